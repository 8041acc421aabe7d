/* mcbrot: a native sampler of mocapbench `mcb-rot` streams (payload format 6), C99, standard library only.
 *
 * An engine keeps a compressed clip in memory (the whole `.mcb` stream: container header, CRC, payload) and samples
 * the local rotation of every joint (unit quaternions x, y, z, w) and the root translation (cm) at any time.
 *
 *   size_t size;
 *   mcbrot_context_size(stream, stream_bytes, &size, NULL, 0);   // bytes the clip's context needs
 *   void *context = aligned_alloc(16, round_up(size, 16));        // the caller owns it; nothing else is allocated
 *   mcbrot_open(context, size, stream, stream_bytes);             // checks the container, CRC and every count
 *   mcbrot_sample(context, t_seconds, MCBROT_LINEAR, rotations, root);   // rotations: J x 4, root: 3 (double)
 *
 * Every call returns an mcbrot_status; MCBROT_OK is 0. After a failed call on a context, mcbrot_message(context)
 * names what is wrong (e.g. "chunk 3: the rANS data ends before its values"); mcbrot_status_text(status) gives a
 * fixed sentence for any status. A context is read and written by the calls that take it and by nothing else:
 * the library has no global state (reentrant; one context per thread). The stream must stay in memory, unchanged,
 * while its context is used (the context points into it). Nothing is ever read or written outside the stream and
 * the context given.
 *
 * Memory: the context holds the clip's decoded header (per-segment means and coefficient counts: 10 bytes per
 * segment and channel, channels = 3 + 3 J), the tables of the stream, and a cache of one decoded random-access unit
 * (chunk): its entropy decoding is done once while playback stays in it, so forward and backward playback pay it
 * once per chunk and random access once per call that lands in another chunk.
 *
 * Game rigs: a stream may carry translation tracks (joints below the root that move relative to their parent);
 * mcbrot_sample_pose gives every joint's translation with its rotation. A rig whose root never moves (a ground-level
 * root at one place with the identity rotation, the pelvis below it carrying the trajectory) may be coded with that
 * root kept apart: the calls give the whole rig all the same (joint 0 the still root: its rotation the identity,
 * its translation its place; joint 1, the pelvis, a joint with a translation track). A rig may scale joints (scale
 * tracks, settings flag bit 13): mcbrot_sample_scales gives every joint's scale beside the pose.
 *
 * Priors: a stream may name its rig (skeleton and still root) in a prior fit on training clips (settings flag bit
 * 15; the prior's bytes are what mcb-rot's model file holds, mocapbench/codecs/mcb_rot/prior.py) instead of carrying
 * it. Such a stream opens with the *_with_prior calls, given the prior's bytes: the stream's fingerprint must be
 * their CRC32 (else MCBROT_E_PRIOR), the prior is checked whole as Python checks it (a malformed one:
 * MCBROT_E_PRIOR), the rig index must be in it (else MCBROT_E_CORRUPT). Everything the clip needs of the rig is
 * copied into the context at open (its size is the same as for the stream that carries its rig): the prior need
 * not stay in memory after open. A stream without the flag ignores the prior given.
 *
 * ABI: MCBROT_ABI_VERSION changes whenever a function's signature, the meaning of a status or the layout expected
 * of an output changes, or calls or statuses are added; mcbrot_abi_version() returns the library's, to compare with
 * the header's. Version 3 added the *_with_prior calls and MCBROT_E_PRIOR (a caller of version 2 works unchanged;
 * version 2 answered a prior stream MCBROT_E_UNSUPPORTED, version 3 answers MCBROT_E_PRIOR when no prior is given).
 */
#ifndef MCBROT_H
#define MCBROT_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MCBROT_ABI_VERSION 3
/* The newest payload format this library reads. */
#define MCBROT_PAYLOAD_FORMAT 6
/* Alignment the context must have. */
#define MCBROT_CONTEXT_ALIGN 16

#if defined(_WIN32)
#define MCBROT_API __declspec(dllexport)
#else
#define MCBROT_API __attribute__((visibility("default")))
#endif

typedef enum mcbrot_status {
    MCBROT_OK = 0,
    MCBROT_E_ARGUMENT = 1,       /* a null pointer, a misaligned context, a frame range outside the clip */
    MCBROT_E_TRUNCATED = 2,      /* the stream ends before a field it declares */
    MCBROT_E_CORRUPT = 3,        /* a field out of range, a CRC mismatch, an entropy unit that does not decode */
    MCBROT_E_NOT_MCBROT = 4,     /* not a mocapbench stream, or another codec's stream */
    MCBROT_E_FORMAT = 5,         /* an mcb-rot payload format this library does not read (older or newer) */
    MCBROT_E_CONTEXT_SMALL = 6,  /* the context is smaller than mcbrot_context_size says */
    MCBROT_E_TIME = 7,           /* t is NaN or outside [0, duration] */
    MCBROT_E_NOT_OPEN = 8,       /* the context holds no opened clip */
    MCBROT_E_UNSUPPORTED = 9,    /* a feature of the stream this version does not implement */
    MCBROT_E_PRIOR = 10          /* the stream names a prior (flags bit 15) and none was given, another one (its
                                  * fingerprint differs) or a malformed one */
} mcbrot_status;

/* How a time between frames is rounded. A time within a millionth of a frame of a frame is that frame. */
typedef enum mcbrot_rounding {
    MCBROT_NEAREST = 0,  /* the nearest frame (halfway: the later one) */
    MCBROT_FLOOR = 1,    /* the frame at or before t */
    MCBROT_CEIL = 2,     /* the frame at or after t */
    MCBROT_LINEAR = 3    /* between the two: translations lerp, rotations nlerp on the shorter arc */
} mcbrot_rounding;

typedef struct mcbrot_clip_info {
    uint32_t num_frames;
    uint32_t num_joints;
    double fps;
    double duration_s;      /* (num_frames - 1) / fps */
    double eps_cm;          /* the stream's L-inf bound on joint positions */
    uint32_t payload_format;
    uint32_t num_segments;
    uint32_t num_chunks;    /* random-access units */
    size_t context_bytes;   /* what this clip's context uses */
    uint32_t num_tracks;    /* joints below the root with a translation track (game rigs; 0 for a rigid skeleton) */
} mcbrot_clip_info;

MCBROT_API int mcbrot_abi_version(void);
MCBROT_API const char *mcbrot_status_text(int status);

/* Bytes of context the stream needs (checks the container and the payload header up to the entropy-coded part).
 * On failure a message is written to `message` (NUL-terminated, at most message_bytes) when it is not NULL. */
MCBROT_API int mcbrot_context_size(const uint8_t *stream, size_t stream_bytes, size_t *size, char *message,
                                   size_t message_bytes);

/* Open the stream into `context` (MCBROT_CONTEXT_ALIGN-aligned, `context_bytes` long): checks the container, the
 * CRC and every count, decodes the segment means and counts. Fails with MCBROT_E_CONTEXT_SMALL when it is too
 * small (mcbrot_message then says how much is needed, if the context holds at least 256 bytes). */
MCBROT_API int mcbrot_open(void *context, size_t context_bytes, const uint8_t *stream, size_t stream_bytes);

/* The same for a bare payload (what follows the container header: for streams kept in another container), with
 * the frame count, joint count and frame rate the container would have given. */
MCBROT_API int mcbrot_payload_context_size(const uint8_t *payload, size_t payload_bytes, uint32_t frames,
                                           uint32_t joints, double fps, size_t *size, char *message,
                                           size_t message_bytes);
MCBROT_API int mcbrot_open_payload(void *context, size_t context_bytes, const uint8_t *payload, size_t payload_bytes,
                                   uint32_t frames, uint32_t joints, double fps);

/* The same for a stream (or a bare payload) that names a rig of a prior (settings flag bit 15): `prior` holds the
 * prior's bytes (`prior_bytes` long), read during the call only. With prior NULL these are the calls above. */
MCBROT_API int mcbrot_context_size_with_prior(const uint8_t *stream, size_t stream_bytes, const uint8_t *prior,
                                              size_t prior_bytes, size_t *size, char *message, size_t message_bytes);
MCBROT_API int mcbrot_open_with_prior(void *context, size_t context_bytes, const uint8_t *stream, size_t stream_bytes,
                                      const uint8_t *prior, size_t prior_bytes);
MCBROT_API int mcbrot_payload_context_size_with_prior(const uint8_t *payload, size_t payload_bytes, uint32_t frames,
                                                      uint32_t joints, double fps, const uint8_t *prior,
                                                      size_t prior_bytes, size_t *size, char *message,
                                                      size_t message_bytes);
MCBROT_API int mcbrot_open_payload_with_prior(void *context, size_t context_bytes, const uint8_t *payload,
                                              size_t payload_bytes, uint32_t frames, uint32_t joints, double fps,
                                              const uint8_t *prior, size_t prior_bytes);

MCBROT_API int mcbrot_info(const void *context, mcbrot_clip_info *info);

/* The message of the last failed call on this context ("" after a success). */
MCBROT_API const char *mcbrot_message(const void *context);

/* The skeleton: parents (J, -1 for the root) and bone offsets (J x 3, cm) in the parent's frame. Either may be NULL. */
MCBROT_API int mcbrot_skeleton(const void *context, int32_t *parents, double *offsets);

/* The pose at time t (seconds from the first frame): rotations (J x 4: x, y, z, w, unit), root (3, cm). */
MCBROT_API int mcbrot_sample(void *context, double t, int rounding, double *rotations, double *root);

/* Frames [start, start + count): rotations (count x J x 4), roots (count x 3); either output may be NULL. */
MCBROT_API int mcbrot_decode_frames(void *context, uint32_t start, uint32_t count, double *rotations, double *roots);

/* As mcbrot_sample, in float32 (what an engine's pose buffer usually holds). */
MCBROT_API int mcbrot_sample_f32(void *context, double t, int rounding, float *rotations, float *root);

/* The whole local pose at time t: rotations (J x 4) and translations (J x 3, cm): row 0 the root's translation,
 * row j the joint's translation from its parent: its track's value on a game rig's translated joint (linear
 * rounding: lerped), its skeleton offset otherwise. */
MCBROT_API int mcbrot_sample_pose(void *context, double t, int rounding, double *rotations, double *translations);
MCBROT_API int mcbrot_sample_pose_f32(void *context, double t, int rounding, float *rotations, float *translations);

/* Frames [start, start + count) as whole poses: rotations (count x J x 4), translations (count x J x 3) as
 * mcbrot_sample_pose's; either output may be NULL. */
MCBROT_API int mcbrot_decode_pose_frames(void *context, uint32_t start, uint32_t count, double *rotations,
                                         double *translations);

/* The joints with a translation track (mcbrot_clip_info.num_tracks of them, increasing). */
MCBROT_API int mcbrot_tracks(const void *context, uint32_t *joints);

/* Scale tracks (settings flag bit 13: a joint's frame scaled, local = T R S, so a joint's scale stretches the steps
 * to its children and its end sites, not the joint itself): the scaled joints (count, increasing; either may be NULL),
 * every joint's scale at time t (J x 3, 1 where it has none; linear rounding lerps) and on frames [start, start +
 * count) (count x J x 3). A clip without scale tracks gives 1 everywhere. */
MCBROT_API int mcbrot_scales(const void *context, uint32_t *count, uint32_t *joints);
MCBROT_API int mcbrot_sample_scales(void *context, double t, int rounding, double *scales);
MCBROT_API int mcbrot_decode_scale_frames(void *context, uint32_t start, uint32_t count, double *scales);

#ifdef __cplusplus
}
#endif

#endif /* MCBROT_H */
