/* mcbrot: native sampler of mcb-rot payload format 6 (see include/mcbrot.h for the API, README.md for the design).
 *
 * The layout read here is written down in mocapbench/codecs/mcb_rot/stream.py (the payload),
 * mocapbench/codecs/mcb_rot/skeleton6.py (the skeleton), mocapbench/entropy/rans6.py (the rANS units) and
 * mocapbench/codecs/container.py (container and CRC); every limit the Python decoder checks is checked here too,
 * before the value is used. Arithmetic is float64 throughout: the outputs equal the Python decoder's up to float
 * rounding (a test compares them on every stream the suite makes).
 */
#include "mcbrot.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "mcbrot_tables.h"

#if defined(__SSE2__) || defined(_M_X64) || (defined(_M_IX86_FP) && _M_IX86_FP >= 2)
#include <emmintrin.h> /* SSE2: part of every x86-64 */
#define MCBROT_SSE2 1
#endif
/* AVX2 + FMA sums where the CPU has them (chosen at open; gcc and clang on x86-64 only, the SSE2 sums elsewhere) */
#if defined(MCBROT_SSE2) && defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && !defined(MCBROT_NO_AVX2)
#include <immintrin.h>
#define MCBROT_AVX2 1
#define TARGET_AVX2 __attribute__((target("avx2,fma")))
#endif

/* ---------------------------------------------------------------------------------------------------------- */
/* limits (as the Python decoder's)                                                                            */

#define MAX_FRAMES 100000000u
#define MAX_JOINTS 4096u
#define MAX_NAME 64u
#define NUM_CLASSES 64
#define NUM_BANDS 12
#define SIDE 64                 /* side values use classes SIDE + class */
#define MAX_TOKEN (16 + 31 - 5) /* magnitudes below 2^31 */
#define RANS_LOW (1u << 23)
#define PRECISION 15
#define MESSAGE_BYTES 200
#define OPEN_MAGIC 0x4d43424fu /* "MCBO" */
#define AXIS_STEP (3.14159265358979323846 / 32768.0)
#define PI 3.14159265358979323846

/* ---------------------------------------------------------------------------------------------------------- */
/* the context                                                                                                 */

typedef struct override_t {
    uint32_t segment, joint;
    double quat[4];
} override_t;

typedef struct ctx_t {
    uint32_t magic;
    uint32_t version;
    size_t bytes_used;
    const uint8_t *payload;
    size_t payload_bytes;
    uint32_t frames, joints, channels, segments, chunks, ends;
    double fps;
    /* settings */
    double eps, bound, multiplier, slope, rounding, root_share, free_angle, power, shell;
    uint32_t segment_frames, chunk_frames;
    int dc_tilt, count_tilt, gap_class, value_class;
    uint32_t num_overrides, num_turned, unit_values, max_length, max_chunk_segments, max_chunk_frames;
                            /* num_turned: joints off their principal axes (after open: those not the identity) */
    uint32_t num_tracks;    /* translation tracks (flags bit 10) */
    uint32_t still;         /* 1: a still root kept apart (flags bit 12): the outputs have joints + 1 joints */
    double still_offset[3], still_position[3]; /* cm */
    double *still_pose;     /* POSE_DOUBLES(joints + 1): the float32 calls' whole pose (a still root only) */
    uint32_t num_scales;    /* scale tracks (flags bit 13) */
    int32_t *scale_of;      /* J: the joint's scale track, or -1 (arrays of 0 bytes without scale tracks) */
    uint32_t *scale_joint;  /* S' */
    double *scale_step, *scale_base, *scale_peak; /* S', S' x 3, S' */
    uint8_t *scale_class;   /* S' x 3: side classes */
    double *scale_factor;   /* J: the most a joint's parent frame stretches a length (product of the peaks above) */
    double *scale_values;   /* max_chunk_frames x S' x 3: the cached chunk's scales */
    /* arrays inside the context */
    int32_t *parents;       /* J */
    double *offsets;        /* (J + E) x 3: the joints', then the end sites' */
    int32_t *end_parents;   /* E */
    int cover_ends;         /* the bound covers the end sites */
    double *base_step;      /* C: multiplier x the channel's relative step */
    double *correction_step; /* J + 1 */
    int32_t *turned;        /* J: index into axes, or -1 */
    uint32_t *turned_joint; /* num_turned: the joint of each axes entry (num_turned: the joints turned) */
    double *axes;           /* T x 9, row-major, columns are the axes */
    override_t *overrides;  /* sorted by (segment, joint) */
    uint32_t *seg_start;    /* S + 1 */
    uint32_t *chunk_first;  /* K + 1: first segment of each chunk */
    uint32_t *chunk_offset; /* K + 1: byte offsets in the payload */
    uint8_t *class_table;   /* C x NUM_BANDS */
    int64_t *dc;            /* S x C */
    uint16_t *counts;       /* S x C */
    /* the cache of one chunk */
    int64_t cached_chunk;
    uint32_t last_segment;  /* the segment of the last frame decoded (a hint: checked before use) */
    uint32_t next_slot, next_correction; /* after a frame of the cached chunk: its end as frame x (J + 1) from the
                             * chunk's first frame, and the first correction at or past it (UINT32_MAX: none kept) */
    int32_t *values;        /* the chunk's coefficients, segment by segment in blocks (LANES), then correction values */
    uint16_t *order;        /* max_chunk_segments x C: each segment's channels by decreasing coefficient count */
    uint32_t *blocks;       /* max_chunk_segments x (C / LANES + 1): where each block of a segment starts in values */
    uint32_t *longest;      /* max_chunk_segments: the most coefficients of a channel in each segment of the chunk */
    uint16_t *rank;         /* C: a channel's place in `order` (while a chunk is decoded) */
    uint16_t *value_at;     /* C: a channel's place in a frame's values (see FRAME_DOUBLES) */
    uint32_t *corr_flat;    /* the chunk's corrections as frame * (J + 1) + slot from its first frame: in `values`,
                             * after the coefficients (a correction's slot and its 3 values take the 4 values the
                             * header's largest unit counts for it) */
    uint32_t num_corrections, corr_values_at;
    /* per segment length tables, in two slots: the longest segments' (most of a clip's) and the last other length
     * used (a clip's shorter segments: before a cut, at its end), so that access alternating between the two never
     * recomputes them */
    uint32_t table_length[2];
    double *cosines;        /* 2 n + 1: cos(pi m / 2n), m = 0..2n (the slot in use; cos is even about 2n) */
    uint8_t *bands;         /* n: band of frequency k */
    double *cosines_slot[2];
    uint8_t *bands_slot[2];
    int32_t *track_of;      /* J: the joint's track, or -1 */
    uint32_t *track_joint;  /* T */
    double *track_step;     /* T, cm */
    double *track_base;     /* T x 3, cm */
    double *track_reach;    /* T, cm: the track's bone length in the budgets */
    uint8_t *track_class;   /* T x 3: side classes */
    double *track_values;   /* max_chunk_frames x T x 3: the cached chunk's translations, cm */
    /* frames synthesised together in sequential playback (see channel_values) */
    uint32_t frame_block;   /* frames per block: FRAME_BLOCK, or 1 where the block's tables would not fit in
                             * MAX_CONTEXT */
    uint32_t block_segment, block_first, block_count; /* the cached block: its frames [first, first + count) */
    uint32_t previous_plus_one; /* the last frame synthesised, plus one (0: none yet) */
    int avx2;               /* the CPU runs AVX2 and FMA */
    double *block_rows;     /* (n + 1) x FRAME_BLOCK: the block's basis rows, frequency by frequency */
    double *block_signal;   /* FRAME_BLOCK x FRAME_DOUBLES(J): the block's frames' values */
    double *scratch;        /* two poses (J x 4 rotations, 3 root, J x 3 steps) for linear sampling, a frame's
                             * values (FRAME_DOUBLES(J)), a row of n + 1 basis values */
    char message[MESSAGE_BYTES];
} ctx_t;

/* ---------------------------------------------------------------------------------------------------------- */
/* messages                                                                                                    */

static int fail(char *message, size_t bytes, int status, const char *format, ...) {
    if (message && bytes) {
        va_list args;
        va_start(args, format);
        vsnprintf(message, bytes, format, args);
        va_end(args);
    }
    return status;
}

MCBROT_API int mcbrot_abi_version(void) { return MCBROT_ABI_VERSION; }

MCBROT_API const char *mcbrot_status_text(int status) {
    switch (status) {
    case MCBROT_OK: return "ok";
    case MCBROT_E_ARGUMENT: return "invalid argument";
    case MCBROT_E_TRUNCATED: return "the stream is truncated";
    case MCBROT_E_CORRUPT: return "the stream is corrupt";
    case MCBROT_E_NOT_MCBROT: return "not an mcb-rot stream";
    case MCBROT_E_FORMAT: return "an mcb-rot payload format this library does not read";
    case MCBROT_E_CONTEXT_SMALL: return "the context is too small";
    case MCBROT_E_TIME: return "the time is NaN or outside the clip";
    case MCBROT_E_NOT_OPEN: return "the context holds no opened clip";
    case MCBROT_E_UNSUPPORTED: return "the stream uses a feature this library does not implement";
    case MCBROT_E_PRIOR: return "the stream names a prior that was not given, another prior, or a malformed one";
    default: return "unknown status";
    }
}

/* ---------------------------------------------------------------------------------------------------------- */
/* byte reader                                                                                                 */

typedef struct reader_t {
    const uint8_t *data;
    size_t pos, end;
    char *message;
    size_t message_bytes;
} reader_t;

#define MSG(r) (r)->message, (r)->message_bytes

static int need(reader_t *r, size_t n, const char *what) {
    if (r->end - r->pos < n)
        return fail(MSG(r), MCBROT_E_TRUNCATED, "mcb-rot: the payload ends inside its %s (byte %zu of %zu)", what,
                    r->pos, r->end);
    return MCBROT_OK;
}

static int read_u8(reader_t *r, uint32_t *out, const char *what) {
    int s = need(r, 1, what);
    if (s) return s;
    *out = r->data[r->pos++];
    return MCBROT_OK;
}

static int read_f32(reader_t *r, double *out, const char *what) {
    int s = need(r, 4, what);
    if (s) return s;
    uint32_t bits = (uint32_t)r->data[r->pos] | (uint32_t)r->data[r->pos + 1] << 8 |
                    (uint32_t)r->data[r->pos + 2] << 16 | (uint32_t)r->data[r->pos + 3] << 24;
    float value;
    memcpy(&value, &bits, 4);
    *out = (double)value;
    r->pos += 4;
    return MCBROT_OK;
}

static int read_varint(reader_t *r, uint64_t *out, const char *what, int max_bytes) {
    uint64_t value = 0;
    for (int i = 0; i < max_bytes; ++i) {
        if (r->pos >= r->end)
            return fail(MSG(r), MCBROT_E_TRUNCATED, "mcb-rot: the payload ends inside its %s", what);
        uint8_t byte = r->data[r->pos++];
        if (i == 9 && byte > 1)
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: %s: a varint exceeds 64 bits", what);
        value |= (uint64_t)(byte & 0x7f) << (7 * i);
        if (!(byte & 0x80)) {
            *out = value;
            return MCBROT_OK;
        }
    }
    return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: %s: a varint longer than %d bytes", what, max_bytes);
}

static int read_count(reader_t *r, uint32_t *out, uint64_t limit, const char *what) {
    uint64_t value;
    int s = read_varint(r, &value, what, 10);
    if (s) return s;
    if (value > limit)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: expected a %s of at most %llu, found %llu", what,
                    (unsigned long long)limit, (unsigned long long)value);
    *out = (uint32_t)value;
    return MCBROT_OK;
}

/* A byte count that must fit in what follows it (checked after its own bytes are read). */
static int read_size(reader_t *r, uint32_t *out, const char *what) {
    uint64_t value;
    int s = read_varint(r, &value, what, 10);
    if (s) return s;
    if (value > r->end - r->pos)
        return fail(MSG(r), MCBROT_E_TRUNCATED, "mcb-rot: the %s says %llu bytes, only %zu are left", what,
                    (unsigned long long)value, r->end - r->pos);
    *out = (uint32_t)value;
    return MCBROT_OK;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* CRC32 (zlib's polynomial), four bytes a step with the constant tables of mcbrot_tables.h (slicing by four: a
 * clip's open checks its container's CRC, and a prior's fingerprint, in mcbrot_context_size and again in
 * mcbrot_open; a byte at a time through a 16-entry table was most of an open's time)                          */

static uint32_t crc32_of(const uint8_t *data, size_t n) {
    const uint32_t(*t)[256] = mcbrot_crc32;
    uint32_t crc = 0xffffffffu;
    size_t i = 0;
    for (; i + 4 <= n; i += 4) {
        crc ^= (uint32_t)data[i] | (uint32_t)data[i + 1] << 8 | (uint32_t)data[i + 2] << 16 |
               (uint32_t)data[i + 3] << 24;
        crc = t[3][crc & 0xff] ^ t[2][(crc >> 8) & 0xff] ^ t[1][(crc >> 16) & 0xff] ^ t[0][crc >> 24];
    }
    for (; i < n; ++i) crc = (crc >> 8) ^ t[0][(crc ^ data[i]) & 0xff];
    return crc ^ 0xffffffffu;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* container                                                                                                   */

typedef struct container_t {
    uint32_t frames, joints;
    double fps;
    const uint8_t *payload;
    size_t payload_bytes;
    const uint8_t *prior; /* the prior given beside the stream (NULL: none), for a stream with flags bit 15 */
    size_t prior_bytes;
} container_t;

static uint32_t le32(const uint8_t *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static int read_container(const uint8_t *s, size_t n, container_t *c, char *message, size_t bytes) {
    if (!s) return fail(message, bytes, MCBROT_E_ARGUMENT, "mcb-rot: the stream pointer is NULL");
    if (n < 10)
        return fail(message, bytes, MCBROT_E_TRUNCATED,
                    "mcb-rot: the stream is truncated: expected at least 10 header bytes, found %zu", n);
    if (memcmp(s, "MCB\0", 4) != 0)
        return fail(message, bytes, MCBROT_E_NOT_MCBROT, "mcb-rot: not a mocapbench stream (wrong magic)");
    uint32_t version = s[4];
    if (version != 1 && version != 2)
        return fail(message, bytes, MCBROT_E_FORMAT, "mcb-rot: unknown container version %u (expected 1 or 2)",
                    version);
    uint32_t crc = le32(s + 5);
    const uint8_t *body = s + 9;
    size_t body_bytes = n - 9;
    uint32_t name_length = body[0];
    size_t fields = version == 1 ? 18 : 23;
    size_t fixed = 1 + name_length + fields;
    if (name_length == 0 || name_length > MAX_NAME)
        return fail(message, bytes, MCBROT_E_CORRUPT, "mcb-rot: corrupt header: codec name length %u", name_length);
    if (body_bytes < fixed)
        return fail(message, bytes, MCBROT_E_TRUNCATED, "mcb-rot: the stream is truncated: expected %zu header "
                    "bytes, found %zu", 9 + fixed, n);
    const uint8_t *f = body + 1 + name_length;
    uint32_t frames = le32(f), joints = (uint32_t)f[4] | (uint32_t)f[5] << 8;
    double fps;
    memcpy(&fps, f + 6, 8); /* little-endian hosts (x86-64, arm64) */
    float unit = 1.0f;
    uint8_t axis = '?';
    if (version == 2) {
        memcpy(&unit, f + 14, 4);
        axis = f[18];
    }
    uint32_t payload_length = le32(f + fields - 4);
    if (body_bytes - fixed != payload_length)
        return fail(message, bytes, body_bytes - fixed < payload_length ? MCBROT_E_TRUNCATED : MCBROT_E_CORRUPT,
                    "mcb-rot: the header declares a %u-byte payload, found %zu bytes after the header",
                    payload_length, body_bytes - fixed);
    uint32_t computed = crc32_of(body, body_bytes);
    if (computed != crc)
        return fail(message, bytes, MCBROT_E_CORRUPT,
                    "mcb-rot: the stream is corrupted: CRC32 expected %#010x (from the header), computed %#010x", crc,
                    computed);
    if (name_length != 7 || memcmp(body + 1, "mcb-rot", 7) != 0) {
        char name[MAX_NAME + 1];
        for (uint32_t i = 0; i < name_length; ++i) name[i] = (body[1 + i] >= 32 && body[1 + i] < 127) ? (char)body[1 + i] : '?';
        name[name_length] = 0;
        return fail(message, bytes, MCBROT_E_NOT_MCBROT, "mcb-rot: this is a stream of codec '%s'", name);
    }
    if (frames < 1 || frames > MAX_FRAMES || joints < 1 || joints > MAX_JOINTS || !(fps >= 1e-3 && fps <= 1e5))
        return fail(message, bytes, MCBROT_E_CORRUPT, "mcb-rot: corrupt header: F=%u, J=%u, fps=%g", frames, joints,
                    fps);
    double relative = 1.0 / 8388608.0;
    if (!((double)unit >= 1e-4 * (1 - relative) && (double)unit <= 1e6 * (1 + relative)) ||
        !(axis == 'x' || axis == 'y' || axis == 'z' || axis == '?'))
        return fail(message, bytes, MCBROT_E_CORRUPT, "mcb-rot: corrupt header: source unit %g cm, up axis %d",
                    (double)unit, axis);
    c->frames = frames;
    c->joints = joints;
    c->fps = fps;
    c->payload = body + fixed;
    c->payload_bytes = payload_length;
    return MCBROT_OK;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* the payload header, in two passes: `plan` (no memory: counts and sizes) and `fill` (into the context)        */

typedef struct header_t {
    /* settings */
    double eps, bound, multiplier, slope, rounding, root_share, free_angle, power, shell;
    uint32_t segment_frames, chunk_frames;
    int cover_ends; /* flags bit 11: the bound covers the end sites (virtual children in the budgets) */
    /* skeleton */
    int exponent;
    uint32_t joints, ends;
    size_t parents_at, end_parents_at, offsets_at, offsets_bytes;
    /* positions of the parts */
    size_t cuts_at, overrides_at, axes_at, classes_at, side_at;
    uint32_t num_cuts, num_overrides, num_turned, unit_values;
    uint32_t segments, chunks, max_length, max_chunk_segments;
    int tracks;          /* flags bit 10: translation tracks */
    uint32_t num_tracks;
    size_t tracks_at;
    int still;           /* flags bit 12: a still root kept apart; `joints` are the stream's others */
    int scales;          /* flags bit 13: scale tracks */
    uint32_t num_scales;
    double still_offset[3], still_position[3];
    /* flags bit 15: the skeleton and the still root are rig `rig` of the prior given beside the stream (prior.py);
     * the skeleton's positions above (parents_at, end_parents_at) are then in the prior's bytes, and its offsets
     * are float64 at prior_offsets_at, rounded onto the stream's grid as pack_skeleton_runtime rounds them */
    int prior;
    const uint8_t *prior_data;
    size_t prior_bytes, prior_offsets_at, prior_mean_at;
    int rig_still;      /* the named rig has a still root */
    uint32_t predicted; /* the first segment's means are coded as differences from the rig's (prior.first_means) */
} header_t;

static const double defaults_f32[] = {0.0, 0.0, 0.0, 1.0, 0.45f, 0.05f, 0.017453292519943295f, 0.0};

static int read_settings(reader_t *r, header_t *h) {
    uint32_t format;
    int s = read_u8(r, &format, "format");
    if (s) return s;
    if (format != MCBROT_PAYLOAD_FORMAT)
        return fail(MSG(r), MCBROT_E_FORMAT, "mcb-rot: payload format %u; this runtime reads format %d only (older "
                    "streams: decode them with Python and re-encode)", format, MCBROT_PAYLOAD_FORMAT);
    if ((s = read_f32(r, &h->eps, "eps")) || (s = read_f32(r, &h->bound, "bound"))) return s;
    uint64_t flags;
    if ((s = read_varint(r, &flags, "settings flags", 3))) return s;
    if ((flags >> 14) & ~(uint64_t)2)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: unknown settings flags %#llx", (unsigned long long)flags);
    h->prior = (int)((flags >> 15) & 1);
    h->scales = (int)((flags >> 13) & 1);
    h->still = (int)((flags >> 12) & 1);
    h->cover_ends = (int)((flags >> 11) & 1);
    h->tracks = (int)((flags >> 10) & 1);
    if (flags & 1) {
        if ((s = read_f32(r, &h->multiplier, "multiplier"))) return s;
    } else {
        uint32_t code;
        if ((s = read_u8(r, &code, "multiplier code"))) return s;
        h->multiplier = (double)(float)pow(2.0, ((double)code - 64.0) / 2.0);
    }
    /* defaults: shell 0, segment 128, chunk 128, slope 1, rounding 0.45, root share 0.05, free angle 1 deg, power 0 */
    double shell = 0.0, slope = 1.0, rounding = defaults_f32[4], root_share = defaults_f32[5],
           free_angle = defaults_f32[6], power = 0.0;
    uint64_t segment = 128, chunk = 128;
    for (int bit = 2; bit < 10; ++bit) {
        int set = (int)((flags >> bit) & 1);
        const char *name = "setting";
        double *f32 = NULL;
        uint64_t *var = NULL;
        switch (bit) {
        case 2: f32 = &shell; name = "shell distance"; break;
        case 3: var = &segment; name = "segment frames"; break;
        case 4: var = &chunk; name = "chunk frames"; break;
        case 5: f32 = &slope; name = "slope"; break;
        case 6: f32 = &rounding; name = "rounding"; break;
        case 7: f32 = &root_share; name = "root share"; break;
        case 8: f32 = &free_angle; name = "free angle"; break;
        case 9: f32 = &power; name = "allocation power"; break;
        }
        if (set) {
            if (f32 && (s = read_f32(r, f32, name))) return s;
            if (var && (s = read_varint(r, var, name, 10))) return s;
        } else if (bit == 5 && (flags & 2)) {
            slope = 0.0;
        }
    }
    if (!(h->bound > 0 && h->bound <= 100 && h->eps > 0 && h->eps <= 101 && h->multiplier > 0 &&
          h->multiplier <= 1e6 && slope >= 0 && slope <= 64 && rounding >= 0 && rounding <= 0.5 && root_share > 0 &&
          root_share < 1 && free_angle > 0 && free_angle <= PI && power >= 0 && power <= 64 && segment >= 1 &&
          segment <= 4096 && chunk >= 1 && chunk <= (1u << 20) && shell >= 0 && shell <= 100))
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: settings out of range: eps %g, bound %g, multiplier %g, slope "
                    "%g, rounding %g, root share %g, free angle %g, allocation power %g, segment frames %llu, chunk "
                    "frames %llu, shell distance %g", h->eps, h->bound, h->multiplier, slope, rounding, root_share,
                    free_angle, power, (unsigned long long)segment, (unsigned long long)chunk, shell);
    h->slope = slope;
    h->rounding = rounding;
    h->root_share = root_share;
    h->free_angle = free_angle;
    h->power = power;
    h->shell = shell;
    h->segment_frames = (uint32_t)segment;
    h->chunk_frames = (uint32_t)chunk;
    if (h->scales && (shell > 0 || h->still))
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: scale tracks with a shell distance or a still root kept apart "
                    "(the encoder writes neither)");
    return MCBROT_OK;
}

/* A bit reader over [start, end) bytes, MSB first. */
typedef struct bits_t {
    const uint8_t *data;
    size_t at, limit; /* in bits */
} bits_t;

static int take_bits(bits_t *b, uint32_t n, uint64_t *out) {
    if (b->limit - b->at < n) return -1;
    uint64_t v = 0;
    for (uint32_t i = 0; i < n; ++i, ++b->at) v = v << 1 | ((b->data[b->at >> 3] >> (7 - (b->at & 7))) & 1);
    *out = v;
    return 0;
}

/* The skeleton's offsets blob (skeleton_blob._pack_offsets): checked, and the first `keep` vectors (cm) written to
 * `out` (keep x 3) when it is not NULL (a repeat names an earlier vector, so the joints' need no end site's). */
static int read_offsets(reader_t *r, const uint8_t *blob, size_t n, uint32_t count, double step, double *out,
                        uint32_t keep) {
    if (n == 0 || blob[0] > 62)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: skeleton: expected offsets of at most 62 bits");
    uint32_t width = blob[0];
    bits_t b = {blob + 1, 0, (n - 1) * 8};
    uint32_t index_bits = 0;
    while (count > 1 && ((uint64_t)(count - 1) >> index_bits)) ++index_bits;
    /* pass 1: the repeat flags, to know which vectors are fresh */
    uint64_t v;
    size_t flags_at = b.at;
    uint32_t repeats = 0;
    for (uint32_t i = 1; i < count; ++i) {
        if (take_bits(&b, 1, &v)) goto truncated;
        repeats += (uint32_t)v;
    }
    size_t sources_at = b.at;
    if (b.limit - b.at < (size_t)repeats * index_bits) goto truncated;
    b.at += (size_t)repeats * index_bits;
    uint32_t fresh = count - repeats;
    size_t zero_at = b.at;
    uint32_t nonzero = 0;
    for (uint32_t i = 0; i < 3 * fresh; ++i) {
        if (take_bits(&b, 1, &v)) goto truncated;
        nonzero += (uint32_t)v;
    }
    size_t signs_at = b.at;
    if (b.limit - b.at < nonzero) goto truncated;
    b.at += nonzero;
    size_t magnitudes_at = b.at;
    if ((b.limit - b.at) / (width ? width : 1) < (width ? nonzero : 0)) goto truncated;
    b.at += (size_t)nonzero * width;
    if (b.limit - b.at >= 8)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: skeleton: %zu bytes follow the offsets", (b.limit - b.at) / 8);
    /* pass 2: the values */
    bits_t fl = {b.data, flags_at, sources_at}, src = {b.data, sources_at, zero_at}, zf = {b.data, zero_at, signs_at},
           sg = {b.data, signs_at, magnitudes_at}, mg = {b.data, magnitudes_at, b.at};
    double limit = 1e6 / step + 1;
    for (uint32_t i = 0; i < count; ++i) {
        uint64_t repeated = 0;
        if (i > 0) take_bits(&fl, 1, &repeated);
        if (repeated) {
            uint64_t source = 0;
            take_bits(&src, index_bits, &source);
            if (source >= i)
                return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: skeleton: a repeated offset names a later one");
            /* the source must not be a repeat itself: re-read its flag */
            if (source > 0) {
                bits_t check = {b.data, flags_at + (size_t)(source - 1), sources_at};
                uint64_t again;
                take_bits(&check, 1, &again);
                if (again)
                    return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: skeleton: a repeated offset names a repeated one");
            }
            if (out && i < keep) memcpy(out + 3 * i, out + 3 * source, 3 * sizeof(double));
            continue;
        }
        for (int c = 0; c < 3; ++c) {
            uint64_t present = 0, sign = 0, magnitude = 0;
            take_bits(&zf, 1, &present);
            if (present) {
                take_bits(&sg, 1, &sign);
                take_bits(&mg, width, &magnitude);
            }
            double value = (double)magnitude;
            if (value > limit) return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: skeleton: an offset exceeds 1e6 cm");
            if (out && i < keep) out[3 * i + c] = (sign ? -value : value) * step;
        }
    }
    return MCBROT_OK;
truncated:
    return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: skeleton: the offsets end inside their bits");
}

static int read_small_ints(reader_t *r, uint32_t count, uint32_t limit, const char *what, uint8_t *out) {
    size_t flags_bytes = (count + 7) / 8;
    int s = need(r, flags_bytes, what);
    if (s) return s;
    const uint8_t *flags = r->data + r->pos;
    r->pos += flags_bytes;
    uint32_t nonzero = 0;
    for (uint32_t i = 0; i < count; ++i) nonzero += (flags[i >> 3] >> (7 - (i & 7))) & 1;
    if (out) memset(out, 0, count);
    if (!nonzero) return MCBROT_OK;
    if ((s = need(r, 2, what))) return s;
    uint32_t low = r->data[r->pos], width = r->data[r->pos + 1];
    r->pos += 2;
    if (low < 1 || low >= limit || width > 8)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: %s: expected values below %u, found a low of %u, width %u",
                    what, limit, low, width);
    size_t bytes = ((size_t)nonzero * width + 7) / 8;
    if ((s = need(r, bytes, what))) return s;
    bits_t b = {r->data + r->pos, 0, bytes * 8};
    r->pos += bytes;
    for (uint32_t i = 0; i < count; ++i) {
        if (!((flags[i >> 3] >> (7 - (i & 7))) & 1)) continue;
        uint64_t v = 0;
        take_bits(&b, width, &v);
        if (low + v >= limit)
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: %s: expected values below %u, found %llu", what, limit,
                        (unsigned long long)(low + v));
        if (out) out[i] = (uint8_t)(low + v);
    }
    return MCBROT_OK;
}

/* Segment starts: a grid of segment_frames restarted at every cut (Python's window_lengths). Calls `emit` per
 * segment when `starts` is not NULL; returns the count and the longest. */
static void segment_grid(uint32_t frames, const uint32_t *cuts, uint32_t num_cuts, uint32_t grid, uint32_t *starts,
                         uint32_t *count, uint32_t *longest) {
    uint32_t n = 0, most = 0, begin = 0;
    for (uint32_t i = 0; i <= num_cuts; ++i) {
        uint32_t stop = i < num_cuts ? cuts[i] : frames;
        for (uint32_t at = begin; at < stop; at += grid) {
            uint32_t length = stop - at < grid ? stop - at : grid;
            if (starts) starts[n] = at;
            ++n;
            if (length > most) most = length;
        }
        begin = stop;
    }
    if (starts) starts[n] = frames;
    *count = n;
    *longest = most;
}

/* The tracks header (mocapbench/codecs/mcb_rot/tracks.py, read_tracks): varint T (1..J-1), then per track varint
 * joint (increasing, 1..J-1) | u8 kind (0: translation) | f32 step | 3 x f32 base |
 * f32 reach | 3 x u8 class. Checked; written into the context when `x` is not NULL. */
static int read_tracks_header(reader_t *r, header_t *h, ctx_t *x) {
    int s;
    uint32_t count;
    h->tracks_at = r->pos;
    if ((s = read_count(r, &count, h->joints - 1, "track count"))) return s;
    if (count < 1)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: expected 1..%u tracks, found 0", h->joints - 1);
    uint32_t previous = 0;
    for (uint32_t t = 0; t < count; ++t) {
        uint64_t joint;
        uint32_t kind;
        double step, base[3], reach;
        if ((s = read_varint(r, &joint, "tracked joint", 10))) return s;
        if (!(joint > previous && joint < h->joints))
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: a track's joint must be in 1..%u, after the previous "
                        "track's, found %llu", h->joints - 1, (unsigned long long)joint);
        previous = (uint32_t)joint;
        if ((s = read_u8(r, &kind, "track kind"))) return s;
        if (kind != 0) /* (scale tracks, kind 1, have a section of their own: flag bit 13) */
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: track %u has kind %u (0: translation)", t, kind);
        if ((s = read_f32(r, &step, "track step")) || (s = read_f32(r, &base[0], "track base")) ||
            (s = read_f32(r, &base[1], "track base")) || (s = read_f32(r, &base[2], "track base")) ||
            (s = read_f32(r, &reach, "track reach")) || (s = need(r, 3, "track classes")))
            return s;
        const uint8_t *classes = r->data + r->pos;
        r->pos += 3;
        if (!(step > 0 && step <= 1e6 && fabs(base[0]) <= 1e6 && fabs(base[1]) <= 1e6 && fabs(base[2]) <= 1e6 &&
              reach >= 0 && reach <= 4e6 && classes[0] < SIDE && classes[1] < SIDE && classes[2] < SIDE))
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: track %u: step %g, base (%g, %g, %g), reach %g or a "
                        "class outside the format's range", t, step, base[0], base[1], base[2], reach);
        if (x) {
            x->track_joint[t] = (uint32_t)joint;
            x->track_of[joint] = (int32_t)t;
            x->track_step[t] = step;
            memcpy(x->track_base + 3 * (size_t)t, base, sizeof base);
            x->track_reach[t] = reach;
            memcpy(x->track_class + 3 * (size_t)t, classes, 3);
        }
    }
    h->num_tracks = count;
    return MCBROT_OK;
}

/* The scale tracks header (mocapbench/codecs/mcb_rot/scales.py; read_tracks of kind 1): varint T (1..J), then per
 * track varint joint (increasing, 0..J-1) | u8 kind (1) | f32 step | 3 x f32 base | f32 peak | 3 x u8 class. Checked;
 * written into the context when `x` is not NULL. */
static int read_scales_header(reader_t *r, header_t *h, ctx_t *x) {
    int s;
    uint32_t count;
    if ((s = read_count(r, &count, h->joints, "scale track count"))) return s;
    if (count < 1) return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: expected 1..%u scale tracks, found 0", h->joints);
    uint64_t next = 0;
    for (uint32_t t = 0; t < count; ++t) {
        uint64_t joint;
        uint32_t kind;
        double step, base[3], peak;
        if ((s = read_varint(r, &joint, "scaled joint", 10))) return s;
        if (!(joint >= next && joint < h->joints))
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: a scale track's joint must be in 0..%u, after the previous "
                        "track's, found %llu", h->joints - 1, (unsigned long long)joint);
        next = joint + 1;
        if ((s = read_u8(r, &kind, "track kind"))) return s;
        if (kind != 1) return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: track kind %u is not a scale (1)", kind);
        if ((s = read_f32(r, &step, "track step")) || (s = read_f32(r, &base[0], "track base")) ||
            (s = read_f32(r, &base[1], "track base")) || (s = read_f32(r, &base[2], "track base")) ||
            (s = read_f32(r, &peak, "track peak")) || (s = need(r, 3, "track classes")))
            return s;
        const uint8_t *classes = r->data + r->pos;
        r->pos += 3;
        if (!(step > 0 && step <= 1e6 && fabs(base[0]) <= 1e6 && fabs(base[1]) <= 1e6 && fabs(base[2]) <= 1e6 &&
              peak > 0 && peak <= 4e6 && classes[0] < SIDE && classes[1] < SIDE && classes[2] < SIDE))
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: a scale track's step, base, peak or class is outside the "
                        "format's range");
        if (x) {
            x->scale_joint[t] = (uint32_t)joint;
            x->scale_of[joint] = (int32_t)t;
            x->scale_step[t] = step;
            memcpy(x->scale_base + 3 * (size_t)t, base, sizeof base);
            x->scale_peak[t] = peak;
            memcpy(x->scale_class + 3 * (size_t)t, classes, 3);
        }
    }
    h->num_scales = count;
    return MCBROT_OK;
}

/* Whether bytes [0, n) are UTF-8 as Python's strict decoder takes it: no overlong form, no surrogate, nothing
 * above U+10FFFF, no stray or missing continuation byte. */
static int is_utf8(const uint8_t *p, size_t n) {
    for (size_t i = 0; i < n;) {
        uint8_t b = p[i];
        size_t more;
        uint8_t low = 0x80, high = 0xbf; /* the range of the byte after the lead */
        if (b < 0x80) more = 0;
        else if (b >= 0xc2 && b <= 0xdf) more = 1;
        else if (b >= 0xe0 && b <= 0xef) {
            more = 2;
            if (b == 0xe0) low = 0xa0;
            if (b == 0xed) high = 0x9f;
        } else if (b >= 0xf0 && b <= 0xf4) {
            more = 3;
            if (b == 0xf0) low = 0x90;
            if (b == 0xf4) high = 0x8f;
        } else return 0;
        if (n - i - 1 < more) return 0;
        for (size_t k = 1; k <= more; ++k) {
            uint8_t c = p[i + k];
            if (c < (k == 1 ? low : 0x80) || c > (k == 1 ? high : 0xbf)) return 0;
        }
        i += 1 + more;
    }
    return 1;
}

/* The still root section (mocapbench/codecs/mcb_rot/static_root.py, read_static_root), after the skeleton part:
 * varint n (1..255) + n bytes of UTF-8 name without NUL | u8 channel order (< 6) | 3 x f32 offset cm | 3 x f32
 * position cm, each finite and within 1e6 cm. Checked; the offset and position kept in `h` (the name and the order
 * are not needed to sample). */
static int read_still_root(reader_t *r, header_t *h) {
    int s;
    uint64_t n;
    uint32_t order;
    if ((s = read_varint(r, &n, "length of static root name", 10))) return s;
    if (n > 255)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: expected at most 255 bytes for the static root's name, the "
                    "length field says %llu", (unsigned long long)n);
    if ((s = need(r, (size_t)n, "static root name"))) return s;
    const uint8_t *name = r->data + r->pos;
    if (n < 1 || memchr(name, 0, (size_t)n))
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: the static root's name must be 1..255 bytes without NUL, "
                    "found %llu bytes", (unsigned long long)n);
    if (!is_utf8(name, (size_t)n)) return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: the static root's name is not UTF-8");
    r->pos += (size_t)n;
    if ((s = read_u8(r, &order, "static root channel order"))) return s;
    if (order >= 6)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: the static root's channel order index must be < 6, found %u",
                    order);
    for (int k = 0; k < 3; ++k)
        if ((s = read_f32(r, &h->still_offset[k], "static root offset"))) return s;
    for (int k = 0; k < 3; ++k)
        if ((s = read_f32(r, &h->still_position[k], "static root position"))) return s;
    for (int k = 0; k < 3; ++k)
        if (!(fabs(h->still_offset[k]) <= 1e6 && fabs(h->still_position[k]) <= 1e6))
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: the static root's offset or position is not finite or "
                        "beyond 1e6 cm");
    return MCBROT_OK;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* the prior (flags bit 15, mocapbench/codecs/mcb_rot/prior.py): the rigs of the training clips, given by the     */
/* caller beside a stream that names one of them                                                               */

#define PRIOR_VERSION 1
#define MAX_RIGS 4096u
#define MAX_RIG_NAMES (1u << 20)

static double le64f(const uint8_t *p) {
    uint64_t bits = 0;
    for (int i = 7; i >= 0; --i) bits = bits << 8 | p[i];
    double value;
    memcpy(&value, &bits, 8);
    return value;
}

/* `count` float64 values at the reader, each finite and within 1e6 (cm, or rad for the mean signal): skipped. */
static int skip_f64s(reader_t *r, size_t count, const char *what) {
    int s = need(r, 8 * count, what);
    if (s) return s;
    for (size_t i = 0; i < count; ++i)
        if (!(fabs(le64f(r->data + r->pos + 8 * i)) <= 1e6))
            return fail(MSG(r), MCBROT_E_CORRUPT, "%s: a value is not finite or beyond 1e6", what);
    r->pos += 8 * count;
    return MCBROT_OK;
}

/* The joint names and channel orders of a rig (prior.py, Rig.write): J order bytes (< 6), then the names as a
 * varint length and NUL-separated UTF-8, J of them, nothing after. Not checked: that the names differ (Python's
 * Skeleton refuses a repeated name; the runtime never uses names, and the check would cost J^2). */
static int check_rig_names(reader_t *r, uint32_t joints) {
    uint64_t n;
    int s = read_varint(r, &n, "length of names", 10);
    if (s) return s;
    if (n > MAX_RIG_NAMES)
        return fail(MSG(r), MCBROT_E_CORRUPT, "expected at most %u bytes for names, the length field says %llu",
                    MAX_RIG_NAMES, (unsigned long long)n);
    if ((s = need(r, (size_t)n, "names"))) return s;
    reader_t inner = {r->data + r->pos, 0, (size_t)n, r->message, r->message_bytes};
    r->pos += (size_t)n;
    if ((s = need(&inner, joints, "channel orders"))) return s;
    for (uint32_t j = 0; j < joints; ++j)
        if (inner.data[j] >= 6)
            return fail(MSG(r), MCBROT_E_CORRUPT, "channel order index must be < 6, found %u", inner.data[j]);
    inner.pos = joints;
    uint32_t size;
    if ((s = read_size(&inner, &size, "joint names"))) return s;
    const uint8_t *names = inner.data + inner.pos;
    inner.pos += size;
    if (inner.pos != inner.end)
        return fail(MSG(r), MCBROT_E_CORRUPT, "expected the end of the skeleton, found %zu more bytes",
                    inner.end - inner.pos);
    if (!is_utf8(names, size)) return fail(MSG(r), MCBROT_E_CORRUPT, "the joint names are not UTF-8");
    uint32_t separators = 0;
    for (uint32_t i = 0; i < size; ++i) separators += names[i] == 0;
    if (separators != joints - 1)
        return fail(MSG(r), MCBROT_E_CORRUPT, "the skeleton has %u joints and %u names", joints, separators + 1);
    return MCBROT_OK;
}

/* Walk the prior's bytes (prior.py, Prior.from_bytes and _read_rig), every field checked as Python checks it,
 * and keep rig `index`'s fields in `h` (its skeleton's positions are then in the prior's bytes). The rig count is
 * written to `rigs`. A failure's message is what a stream's would be; the caller names the prior. */
static int walk_prior(reader_t *r, header_t *h, uint64_t index, uint32_t *rigs) {
    uint32_t version, count;
    int s = read_u8(r, &version, "prior version");
    if (s) return s;
    if (version != PRIOR_VERSION)
        return fail(MSG(r), MCBROT_E_CORRUPT, "version %u, this runtime reads %d", version, PRIOR_VERSION);
    uint64_t n;
    if ((s = read_varint(r, &n, "rig count", 10))) return s;
    if (n < 1 || n > MAX_RIGS)
        return fail(MSG(r), MCBROT_E_CORRUPT, "expected 1..%u rigs, found %llu", MAX_RIGS, (unsigned long long)n);
    count = (uint32_t)n;
    for (uint32_t k = 0; k < count; ++k) {
        uint32_t joints, ends, still;
        if ((s = read_count(r, &joints, MAX_JOINTS, "joint count")) ||
            (s = read_count(r, &ends, MAX_JOINTS, "end-site count")))
            return s;
        if (joints < 1) return fail(MSG(r), MCBROT_E_CORRUPT, "rig %u has no joint", k);
        size_t parents_at = r->pos;
        for (uint32_t j = 1; j < joints; ++j) {
            uint64_t step;
            if ((s = read_varint(r, &step, "parents", 10))) return s;
            if (step < 1 || step > j)
                return fail(MSG(r), MCBROT_E_CORRUPT, "rig %u: joint %u names a parent %llu joints before it (1..%u)",
                            k, j, (unsigned long long)step, j);
        }
        size_t end_parents_at = r->pos;
        for (uint32_t e = 0; e < ends; ++e) {
            uint64_t joint;
            if ((s = read_varint(r, &joint, "end-site parents", 10))) return s;
            if (joint >= joints)
                return fail(MSG(r), MCBROT_E_CORRUPT, "rig %u: end site %u names joint %llu of %u", k, e,
                            (unsigned long long)joint, joints);
        }
        size_t offsets_at = r->pos;
        if ((s = skip_f64s(r, 3 * ((size_t)joints + ends), "offsets")) || (s = check_rig_names(r, joints)) ||
            (s = read_u8(r, &still, "still root flag")))
            return s;
        if (still > 1) return fail(MSG(r), MCBROT_E_CORRUPT, "the still root flag must be 0 or 1, found %u", still);
        header_t other; /* a rig not named: its still root checked, not kept */
        if (still && (s = read_still_root(r, k == index ? h : &other))) return s;
        size_t mean_at = r->pos;
        if ((s = skip_f64s(r, 3 + 3 * (size_t)joints, "mean signal"))) return s;
        if (k == index) {
            h->joints = joints;
            h->ends = ends;
            h->parents_at = parents_at;
            h->end_parents_at = end_parents_at;
            h->prior_offsets_at = offsets_at;
            h->prior_mean_at = mean_at;
            h->rig_still = (int)still;
        }
    }
    if (r->pos != r->end)
        return fail(MSG(r), MCBROT_E_CORRUPT, "expected the end of the prior, found %zu more bytes", r->end - r->pos);
    *rigs = count;
    return MCBROT_OK;
}

/* The stream's u32 fingerprint of its prior against the CRC32 of the prior given. (A fuzzing build skips the
 * comparison, so that mutated priors reach the prior's parser.) */
static int check_fingerprint(const container_t *c, reader_t *r) {
    int s = need(r, 4, "prior fingerprint");
    if (s) return s;
    uint32_t fingerprint = le32(r->data + r->pos);
    r->pos += 4;
    if (!c->prior)
        return fail(MSG(r), MCBROT_E_PRIOR, "mcb-rot: the stream was coded against a prior (model %08x) and none was "
                    "given; open it with mcbrot_open_with_prior and that model", fingerprint);
    uint32_t held = crc32_of(c->prior, c->prior_bytes);
#if !defined(FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION)
    if (held != fingerprint)
        return fail(MSG(r), MCBROT_E_PRIOR, "mcb-rot: the stream was coded against prior %08x, the prior given is "
                    "%08x; open it with the model it was coded with", fingerprint, held);
#else
    (void)held;
#endif
    return MCBROT_OK;
}

/* After the grid exponent: the rig index, checked against the prior (walked whole), and the rig's fields. */
static int read_prior_reference(const container_t *c, header_t *h, reader_t *r) {
    uint64_t index;
    int s = read_varint(r, &index, "prior rig index", 10);
    if (s) return s;
    char why[MESSAGE_BYTES];
    reader_t p = {c->prior, 0, c->prior_bytes, why, sizeof why};
    uint32_t rigs = 0;
    if (walk_prior(&p, h, index, &rigs)) {
        const char *text = strncmp(why, "mcb-rot: ", 9) == 0 ? why + 9 : why;
        return fail(MSG(r), MCBROT_E_PRIOR, "mcb-rot: the prior is malformed: %s", text);
    }
    if (index >= rigs)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: the stream names rig %llu of the prior, which holds %u",
                    (unsigned long long)index, rigs);
    if (h->rig_still != h->still)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: the prior's rig and the stream's still-root flag disagree");
    if (h->joints + (uint32_t)h->still != c->joints)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: the skeleton has %u joints%s, the header says %u", h->joints,
                    h->still ? " and a still root" : "", c->joints);
    h->prior_data = c->prior;
    h->prior_bytes = c->prior_bytes;
    return MCBROT_OK;
}

/* Pass 1 over the payload header: every field up to the side unit read and checked, sizes found. The cuts are
 * needed for the segment count: they are read into `cuts` (at most F - 1 values) when not NULL, else only
 * counted. */
static int plan(const container_t *c, header_t *h, reader_t *r, uint32_t *cuts_out) {
    int s;
    memset(h, 0, sizeof *h);
    if ((s = read_settings(r, h))) return s;
    /* skeleton, runtime part (with the prior flag: u32 the prior's fingerprint, then the grid exponent and the rig) */
    if (h->prior && (s = check_fingerprint(c, r))) return s;
    uint64_t zig;
    if ((s = read_varint(r, &zig, "offset grid exponent", 10))) return s;
    int64_t exponent = (int64_t)(zig >> 1) ^ -(int64_t)(zig & 1);
    if (exponent < -40 || exponent > 10)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: skeleton: offset grid exponent %lld outside [-40, 10]",
                    (long long)exponent);
    h->exponent = (int)exponent;
    if (h->prior) {
        if ((s = read_prior_reference(c, h, r))) return s;
    } else {
    if ((s = read_count(r, &h->joints, MAX_JOINTS, "joint count")) || (s = read_count(r, &h->ends, MAX_JOINTS,
                                                                                     "end-site count")))
        return s;
    if (h->joints < 1 || h->joints + (uint32_t)h->still != c->joints)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: the skeleton has %u joints%s, the header says %u", h->joints,
                    h->still ? " and a still root" : "", c->joints);
    h->parents_at = r->pos;
    for (uint32_t j = 1; j < h->joints; ++j) {
        uint64_t step;
        if ((s = read_varint(r, &step, "parents", 10))) return s;
        if (step < 1 || step > j)
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: skeleton: joint %u names a parent %llu joints before "
                        "it (1..%u)", j, (unsigned long long)step, j);
    }
    h->end_parents_at = r->pos;
    for (uint32_t e = 0; e < h->ends; ++e) {
        uint64_t joint;
        if ((s = read_varint(r, &joint, "end-site parents", 10))) return s;
        if (joint >= h->joints)
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: skeleton: end site %u names joint %llu of %u", e,
                        (unsigned long long)joint, h->joints);
    }
    uint32_t blob;
    if ((s = read_size(r, &blob, "offsets size"))) return s;
    h->offsets_at = r->pos;
    h->offsets_bytes = blob;
    if ((s = read_offsets(r, r->data + r->pos, blob, h->joints + h->ends, ldexp(1.0, h->exponent), NULL, 0))) return s;
    r->pos += blob;
    if ((s = read_size(r, &blob, "skeleton names size"))) return s;
    r->pos += blob; /* zstd: names and channel orders, not needed to sample */
    if (h->still && (s = read_still_root(r, h))) return s;
    }
    /* cuts */
    h->cuts_at = r->pos;
    if ((s = read_count(r, &h->num_cuts, c->frames - 1, "cut count"))) return s;
    uint64_t at = 0;
    for (uint32_t i = 0; i < h->num_cuts; ++i) {
        uint64_t gap;
        if ((s = read_varint(r, &gap, "cuts", 10))) return s;
        at += gap;
        if (gap < 1 || at > c->frames - 1)
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: cuts must increase within frames 1..%u", c->frames - 1);
        if (cuts_out) cuts_out[i] = (uint32_t)at;
    }
    /* segments and chunks */
    if (cuts_out || h->num_cuts == 0) {
        segment_grid(c->frames, cuts_out, h->num_cuts, h->segment_frames, NULL, &h->segments, &h->max_length);
    } else { /* count the segments without storing the cuts: re-read the gaps */
        reader_t again = *r;
        again.pos = h->cuts_at;
        uint32_t n;
        read_count(&again, &n, c->frames - 1, "cut count");
        uint64_t begin = 0, total = 0, longest = 0, position = 0;
        for (uint32_t i = 0; i <= n; ++i) {
            uint64_t gap = 0;
            if (i < n) read_varint(&again, &gap, "cuts", 10);
            position += gap;
            uint64_t stop = i < n ? position : c->frames;
            uint64_t length = stop - begin;
            total += (length + h->segment_frames - 1) / h->segment_frames;
            uint64_t most = length < h->segment_frames ? length : h->segment_frames;
            if (most > longest) longest = most;
            begin = stop;
        }
        h->segments = (uint32_t)total;
        h->max_length = (uint32_t)longest;
    }
    /* chunks: group segments until one holds chunk_frames; count and the most segments in one (needs lengths:
     * computed from the grid again, cheaply, in open; here an upper bound from the settings) */
    h->max_chunk_segments = 0;
    /* re-references */
    h->overrides_at = r->pos;
    if ((s = read_count(r, &h->num_overrides, (uint64_t)h->segments * h->joints, "re-reference count"))) return s;
    for (uint32_t i = 0; i < h->num_overrides; ++i) {
        uint64_t segment, joint;
        if ((s = read_varint(r, &segment, "re-referenced segment", 10)) ||
            (s = read_varint(r, &joint, "re-referenced joint", 10)) || (s = need(r, 12, "reference")))
            return s;
        r->pos += 12;
    }
    /* principal axes */
    h->axes_at = r->pos;
    size_t flag_bytes = (h->joints + 7) / 8;
    if ((s = need(r, flag_bytes, "axis flags"))) return s;
    uint32_t flagged = 0;
    for (uint32_t j = 0; j < h->joints; ++j) flagged += (r->data[r->pos + (j >> 3)] >> (7 - (j & 7))) & 1;
    r->pos += flag_bytes;
    if ((s = need(r, (size_t)6 * flagged, "joint axes"))) return s;
    r->pos += (size_t)6 * flagged;
    h->num_turned = flagged;
    /* classes */
    h->classes_at = r->pos;
    uint32_t channels = 3 + 3 * h->joints;
    if ((s = read_small_ints(r, channels, 128, "channel classes", NULL)) ||
        (s = read_small_ints(r, NUM_BANDS - 1, 128, "band classes", NULL)) || (s = need(r, 4, "classes")))
        return s;
    int dc_tilt = (int)r->data[r->pos] - NUM_CLASSES, count_tilt = (int)r->data[r->pos + 1] - NUM_CLASSES;
    int gap = r->data[r->pos + 2], value = r->data[r->pos + 3];
    if (dc_tilt >= NUM_CLASSES || count_tilt >= NUM_CLASSES || gap >= NUM_CLASSES || value >= NUM_CLASSES)
        return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: classes must be < %d", NUM_CLASSES);
    r->pos += 4;
    if (h->tracks && (s = read_tracks_header(r, h, NULL))) return s;
    if (h->scales && (s = read_scales_header(r, h, NULL))) return s;
    uint64_t longest = h->max_length > h->chunk_frames ? h->max_length : h->chunk_frames;
    uint64_t most = longest * (channels + 4 * ((uint64_t)h->joints + 1));
    if ((s = read_count(r, &h->unit_values, most, "largest unit"))) return s;
    if (h->prior) {
        if ((s = read_u8(r, &h->predicted, "first means predicted"))) return s;
        if (h->predicted > 1)
            return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: the first-means flag must be 0 or 1, found %u", h->predicted);
    }
    h->side_at = r->pos;
    return MCBROT_OK;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* rANS units                                                                                                  */

typedef struct unit_t {
    const uint8_t *data;
    size_t pos, end;         /* rANS bytes */
    size_t bit, bit_limit;   /* sign and raw bits, in bits from data */
    uint32_t x[2];           /* x[0]: the state of the next value */
} unit_t;

/* Start a unit at r->pos; `count` values follow. */
static int unit_begin(reader_t *r, unit_t *u, uint32_t count, size_t limit, const char *what) {
    uint64_t size;
    int s = read_varint(r, &size, what, 10);
    if (s) return s;
    if (size > r->end - r->pos)
        return fail(MSG(r), MCBROT_E_TRUNCATED, "mcb-rot: %s: expected %llu rANS bytes, only %zu left", what,
                    (unsigned long long)size, r->end - r->pos);
    u->data = r->data;
    u->pos = r->pos;
    u->end = r->pos + (size_t)size;
    u->bit = u->end * 8;
    u->bit_limit = limit * 8;
    if (count == 0) {
        if (size != 0) return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: %s: rANS bytes for no value", what);
        return MCBROT_OK;
    }
    if (size < 8) return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: %s: the rANS data ends before its values", what);
    u->x[0] = le32(u->data + u->pos);
    u->x[1] = le32(u->data + u->pos + 4);
    u->pos += 8;
    return MCBROT_OK;
}

/* The next value of class `k`; returns 0, or a nonzero code: 1 rANS truncated, 2 token too large, 4 bits
 * truncated. */
#if defined(__GNUC__) || defined(__clang__)
#define ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define ALWAYS_INLINE inline
#endif

#if defined(__GNUC__) || defined(__clang__)
#define LIKELY(c) __builtin_expect(!!(c), 1)
#else
#define LIKELY(c) (c)
#endif

static ALWAYS_INLINE uint64_t be64_at(const uint8_t *p) {
    return (uint64_t)p[0] << 56 | (uint64_t)p[1] << 48 | (uint64_t)p[2] << 40 | (uint64_t)p[3] << 32 |
           (uint64_t)p[4] << 24 | (uint64_t)p[5] << 16 | (uint64_t)p[6] << 8 | p[7];
}

/* The 8 bytes at data + at as a big-endian number; the bytes at or past `limit` read as zeros (a copy to a zeroed
 * local: no read at or past the limit; bytes, not a type-punned load). */
static ALWAYS_INLINE uint64_t bit_window(const uint8_t *data, size_t at, size_t limit) {
    if (LIKELY(at + 8 <= limit)) return be64_at(data + at);
    uint8_t bytes[8] = {0};
    if (at < limit) memcpy(bytes, data + at, limit - at);
    return be64_at(bytes);
}

/* The next value of class `k` (unit_next), `once` a constant: 1 reads the renormalization bytes and the sign and
 * raw bits without a branch on the data, 0 with branches. The same values and codes either way. A chunk that
 * playback reaches is decoded once a pass: its branches have no pattern the predictor learns (a third of the
 * values take a renormalization byte, a fifth to two fifths are zero, at every ε), and without them a chunk's
 * decoding is faster. Random access that keeps returning to a clip's few chunks (as a benchmark does) has the
 * predictor learn their branches: there the branches are faster. Both measured in runtime/README.md ("Design"),
 * where the figures are kept. */
static ALWAYS_INLINE int unit_value(unit_t *u, uint32_t k, int32_t *out, const int once) {
    /* value i uses state i & 1: the state in x[0], the other moves in front of it (no index to keep) */
    uint32_t x = u->x[0];
    uint32_t slot = x & ((1u << PRECISION) - 1);
    /* the bucket's first token, its start and frequency in one load; the token's search goes on only where the
     * slot lies past it (a bucket holding a boundary, rarely hit) */
    uint32_t bucket = slot >> MCBROT_LOOKUP_SHIFT, entry = mcbrot_entry[k][bucket];
    uint32_t token = mcbrot_lookup[k][bucket], start = entry & 0xffff, freq = entry >> 16;
    if (start + freq <= slot) {
        const uint16_t *cum = mcbrot_cum[k];
        while (cum[token + 1] <= slot) ++token;
        start = cum[token];
        freq = mcbrot_freq[k][token];
    }
    uint32_t value = freq * (x >> PRECISION) + slot - start;
    /* once: a state >= 2^23 leaves value >= 2^8, so at most two bytes, both read (where two are left) and shifted
     * in by the count two comparisons give; the loop reads what is left (the unit's last byte, a corrupt stream's
     * states) */
    if (once && LIKELY(u->end - u->pos >= 2)) {
        uint32_t bytes = (value < RANS_LOW) + (value < (RANS_LOW >> 8));
        uint32_t two = (uint32_t)u->data[u->pos] << 8 | u->data[u->pos + 1];
        value = (uint32_t)((uint64_t)value << (8 * bytes)) | (two >> (16 - 8 * bytes));
        u->pos += bytes;
    }
    while (value < RANS_LOW) {
        if (u->pos >= u->end) return 1;
        value = value << 8 | u->data[u->pos++];
    }
    u->x[0] = u->x[1];
    u->x[1] = value;
    if (token > MAX_TOKEN) return 2;
    uint32_t magnitude = token, negative;
    if (once) {
        /* from a 64-bit window at the next bit (big-endian: the next bit its top), the position advanced by the
         * nonzero test; the window's bytes past the unit's limit read as zeros from a local copy (never a read past
         * it), a value whose bits run past it refused as with branches. Widths <= MAX_TOKEN - 12 = 30 and the
         * bit's offset in its byte <= 7: 1 + 30 + 7 bits fit. */
        uint32_t nonzero = token != 0;
        uint64_t window = bit_window(u->data, u->bit >> 3, u->bit_limit >> 3) << (u->bit & 7);
        negative = (uint32_t)(window >> 63) & nonzero;
        size_t bit = u->bit + nonzero;
        if (token >= 16) {
            uint32_t width = token - 16 + 4;
            magnitude = 1u << width | (uint32_t)((window << 1) >> (64 - width));
            bit += width;
        }
        if (bit > u->bit_limit) return 4;
        u->bit = bit;
    } else {
        if (token == 0) {
            *out = 0;
            return 0;
        }
        if (u->bit >= u->bit_limit) return 4;
        negative = (u->data[u->bit >> 3] >> (7 - (u->bit & 7))) & 1;
        ++u->bit;
        if (token >= 16) {
            uint32_t width = token - 16 + 4;
            if (u->bit_limit - u->bit < width) return 4;
            magnitude = 1;
            for (uint32_t i = 0; i < width; ++i, ++u->bit)
                magnitude = magnitude << 1 | ((u->data[u->bit >> 3] >> (7 - (u->bit & 7))) & 1);
        }
    }
    *out = (int32_t)((magnitude ^ (0u - negative)) + negative);
    return 0;
}

/* The next value of class `k`, with branches (the units other than a chunk's coefficients: few values). */
static ALWAYS_INLINE int unit_next(unit_t *u, uint32_t k, int32_t *out) { return unit_value(u, k, out, 0); }

static int unit_error(reader_t *r, int code, const char *what) {
    static const char *const text[] = {"", "the rANS data ends before its values", "a value exceeds 2^31",
                                       "the rANS data does not end where it should (corrupt)",
                                       "the sign and raw bits end before their values"};
    return fail(MSG(r), MCBROT_E_CORRUPT, "mcb-rot: %s: %s", what, text[code]);
}

/* Finish a unit: both states back at 2^23, every rANS byte read; r->pos moves past the bits. */
static int unit_end(reader_t *r, unit_t *u, uint32_t count, const char *what) {
    if (count && (u->x[0] != RANS_LOW || u->x[1] != RANS_LOW || u->pos != u->end)) return unit_error(r, 3, what);
    r->pos = (u->bit + 7) >> 3;
    return MCBROT_OK;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* layout of the context                                                                                       */

typedef struct layout_t {
    size_t parents, offsets, end_parents, base_step, correction_step, turned, turned_joint, axes, overrides, seg_start, chunk_first,
        chunk_offset, class_table, dc, counts, values, order, blocks, longest, rank, value_at, cosines, block_rows, block_signal,
        bands, track_of, track_joint, track_step, track_base, track_reach, track_class, track_values, scratch,
        still_pose, scale_of, scale_joint, scale_step, scale_base, scale_peak, scale_class, scale_factor, scale_values,
        total;
    uint32_t frame_block;
} layout_t;

static size_t place(size_t *at, size_t bytes) {
    size_t here = (*at + 15) & ~(size_t)15;
    *at = here + bytes;
    return here;
}

/* A segment's channels, by decreasing coefficient count, in blocks of LANES: a block holds its channels'
 * coefficients frequency by frequency (LANES values per frequency, zero where a channel has fewer), up to its first
 * channel's count, so that the synthesis sums LANES channels at once over memory read in order. */
#define LANES 4

/* Doubles of one pose in the scratch area: rotations (4 J), root (3), steps (3 J). */
#define POSE_DOUBLES(J) (7 * (size_t)(J) + 3)

/* A frame's channel values as the exponential maps read them: the root's three (and a zero), then the rotation
 * vectors' x of every joint, their y, their z, each run padded with zeros to a multiple of four joints (AVX2 loads
 * four joints' x, y and z as they are, without a transpose: JOINTS_PADDED). */
#define JOINTS_PADDED(J) (((size_t)(J) + 3) & ~(size_t)3)
#define FRAME_DOUBLES(J) (4 + 3 * JOINTS_PADDED(J))

/* Sequential playback synthesises FRAME_BLOCK frames of a segment at once (the coefficients read once for all of
 * them), unless their tables would take a context that fits in MAX_CONTEXT bytes past it. */
#define FRAME_BLOCK 4
#define MAX_CONTEXT 65536u

static void layout_of(const header_t *h, uint32_t chunks, uint32_t max_chunk_segments, uint32_t max_chunk_frames,
                      layout_t *l) {
    size_t at = sizeof(ctx_t);
    size_t J = h->joints, C = 3 + 3 * J, S = h->segments, n = h->max_length;
    l->parents = place(&at, 4 * J);
    l->offsets = place(&at, 24 * (J + h->ends));
    l->end_parents = place(&at, 4 * (size_t)h->ends + 4);
    l->base_step = place(&at, 8 * C);
    l->correction_step = place(&at, 8 * (J + 1));
    l->turned = place(&at, 4 * J);
    l->turned_joint = place(&at, 4 * (size_t)h->num_turned);
    l->axes = place(&at, 72 * (size_t)h->num_turned);
    l->overrides = place(&at, sizeof(override_t) * (size_t)h->num_overrides);
    l->seg_start = place(&at, 4 * (S + 1));
    l->chunk_first = place(&at, 4 * ((size_t)chunks + 1));
    l->chunk_offset = place(&at, 8 * ((size_t)chunks + 1));
    l->class_table = place(&at, C * NUM_BANDS);
    l->dc = place(&at, 8 * S * C);
    l->counts = place(&at, 2 * S * C);
    /* a block pads its channels to its first's count: (LANES - 1) (first - last count) at most, whose sum over a
     * segment's blocks telescopes to (LANES - 1) (n - 1) (each block's first count is at most the previous block's
     * last); the last block's lanes past C add (n - 1) each */
    size_t B = (C + LANES - 1) / LANES;
    l->values = place(&at, 4 * ((size_t)h->unit_values + (size_t)max_chunk_segments * (LANES - 1 + B * LANES - C) * n));
    l->order = place(&at, 2 * (size_t)max_chunk_segments * B * LANES);
    l->blocks = place(&at, 4 * (size_t)max_chunk_segments * (B + 1));
    l->longest = place(&at, 4 * (size_t)max_chunk_segments);
    l->rank = place(&at, 2 * C);
    l->value_at = place(&at, 2 * C);
    size_t slots = h->segments > 1 ? 2 : 1; /* one segment: one length */
    l->cosines = place(&at, slots * 8 * (2 * n + 1));
    l->bands = place(&at, slots * n);
    size_t T = h->tracks ? h->num_tracks : 0;
    l->track_of = place(&at, 4 * J);
    l->track_joint = place(&at, 4 * T);
    l->track_step = place(&at, 8 * T);
    l->track_base = place(&at, 24 * T);
    l->track_reach = place(&at, 8 * T);
    l->track_class = place(&at, 3 * T);
    l->track_values = place(&at, 24 * T * (T ? max_chunk_frames : 0));
    l->scratch = place(&at, 8 * (2 * POSE_DOUBLES(J) + FRAME_DOUBLES(J) + n + 1));
    l->still_pose = place(&at, h->still ? 8 * POSE_DOUBLES(J + 1) : 0);
    size_t S3 = h->scales ? h->num_scales : 0, JS = S3 ? J : 0;
    l->scale_of = place(&at, 4 * JS);
    l->scale_joint = place(&at, 4 * S3);
    l->scale_step = place(&at, 8 * S3);
    l->scale_base = place(&at, 24 * S3);
    l->scale_peak = place(&at, 8 * S3);
    l->scale_class = place(&at, 3 * S3);
    l->scale_factor = place(&at, 8 * JS);
    l->scale_values = place(&at, 24 * S3 * (S3 ? max_chunk_frames : 0));
    /* the block tables, last: left out (frame_block 1) where they would take the context past MAX_CONTEXT */
    size_t without = (at + 15) & ~(size_t)15;
    l->block_rows = place(&at, 8 * FRAME_BLOCK * (n + 1));
    l->block_signal = place(&at, 8 * FRAME_BLOCK * FRAME_DOUBLES(J));
    l->total = (at + 15) & ~(size_t)15;
    l->frame_block = FRAME_BLOCK;
    if (l->total > MAX_CONTEXT && without <= MAX_CONTEXT) {
        l->total = without;
        l->frame_block = 1;
    }
}

/* Chunk grouping (SegmentLayout): consecutive segments until a chunk holds at least chunk_frames frames. */
static void chunk_grid(const uint32_t *seg_start, uint32_t segments, uint32_t chunk_frames, uint32_t *first,
                       uint32_t *count, uint32_t *most) {
    uint32_t n = 0, held = 0, largest = 0, begin = 0;
    if (first) first[0] = 0;
    for (uint32_t s = 0; s + 1 < segments; ++s) {
        held += seg_start[s + 1] - seg_start[s];
        if (held >= chunk_frames) {
            ++n;
            if (first) first[n] = s + 1;
            if (s + 1 - begin > largest) largest = s + 1 - begin;
            begin = s + 1;
            held = 0;
        }
    }
    ++n;
    if (first) first[n] = segments;
    if (segments - begin > largest) largest = segments - begin;
    *count = n;
    *most = largest;
}

/* The chunk count and the most segments of one chunk, without memory: the grid walked twice. */
static void count_chunks(const container_t *c, const header_t *h, reader_t *r, uint32_t *chunks, uint32_t *most,
                         uint32_t *most_frames) {
    /* walk the segments (from the cuts in the stream) and group them */
    reader_t cr = *r;
    cr.pos = h->cuts_at;
    uint32_t n;
    read_count(&cr, &n, c->frames - 1, "cut count");
    uint64_t begin = 0, position = 0;
    uint32_t groups = 0, largest = 0, in_chunk = 0, held = 0, held_most = 0;
    uint32_t total_segments = 0;
    for (uint32_t i = 0; i <= n; ++i) {
        uint64_t gap = 0;
        if (i < n) read_varint(&cr, &gap, "cuts", 10);
        position += gap;
        uint64_t stop = i < n ? position : c->frames;
        for (uint64_t at = begin; at < stop; at += h->segment_frames) {
            uint32_t length = (uint32_t)(stop - at < h->segment_frames ? stop - at : h->segment_frames);
            ++total_segments;
            ++in_chunk;
            held += length;
            if (held >= h->chunk_frames && total_segments < h->segments) {
                ++groups;
                if (in_chunk > largest) largest = in_chunk;
                if (held > held_most) held_most = held;
                in_chunk = 0;
                held = 0;
            }
        }
        begin = stop;
    }
    ++groups;
    if (in_chunk > largest) largest = in_chunk;
    if (held > held_most) held_most = held;
    *chunks = groups;
    *most = largest;
    *most_frames = held_most;
}

static int size_of(const uint8_t *stream, size_t n, container_t *c, header_t *h, layout_t *l, uint32_t *chunks,
                   uint32_t *most, uint32_t *most_frames, char *message, size_t bytes) {
    int s = c->payload ? MCBROT_OK : read_container(stream, n, c, message, bytes);
    if (s) return s;
    reader_t r = {c->payload, 0, c->payload_bytes, message, bytes};
    if ((s = plan(c, h, &r, NULL))) return s;
    count_chunks(c, h, &r, chunks, most, most_frames);
    layout_of(h, *chunks, *most, *most_frames, l);
    return MCBROT_OK;
}

static int stream_size(const uint8_t *stream, size_t stream_bytes, const uint8_t *prior, size_t prior_bytes,
                       size_t *size, char *message, size_t message_bytes) {
    if (message && message_bytes) message[0] = 0;
    if (!size) return fail(message, message_bytes, MCBROT_E_ARGUMENT, "mcb-rot: `size` is NULL");
    container_t c = {0};
    c.prior = prior;
    c.prior_bytes = prior ? prior_bytes : 0;
    header_t h;
    layout_t l;
    uint32_t chunks, most, most_frames;
    int s = size_of(stream, stream_bytes, &c, &h, &l, &chunks, &most, &most_frames, message, message_bytes);
    if (s) return s;
    *size = l.total;
    return MCBROT_OK;
}

MCBROT_API int mcbrot_context_size(const uint8_t *stream, size_t stream_bytes, size_t *size, char *message,
                                   size_t message_bytes) {
    return stream_size(stream, stream_bytes, NULL, 0, size, message, message_bytes);
}

MCBROT_API int mcbrot_context_size_with_prior(const uint8_t *stream, size_t stream_bytes, const uint8_t *prior,
                                              size_t prior_bytes, size_t *size, char *message, size_t message_bytes) {
    return stream_size(stream, stream_bytes, prior, prior_bytes, size, message, message_bytes);
}

static int payload_container(const uint8_t *payload, size_t bytes, uint32_t frames, uint32_t joints, double fps,
                             container_t *c, char *message, size_t message_bytes) {
    if (!payload || !bytes) return fail(message, message_bytes, MCBROT_E_TRUNCATED, "mcb-rot: the payload is empty");
    if (frames < 1 || frames > MAX_FRAMES || joints < 1 || joints > MAX_JOINTS || !(fps >= 1e-3 && fps <= 1e5))
        return fail(message, message_bytes, MCBROT_E_ARGUMENT, "mcb-rot: F=%u, J=%u, fps=%g out of range", frames,
                    joints, fps);
    c->frames = frames;
    c->joints = joints;
    c->fps = fps;
    c->payload = payload;
    c->payload_bytes = bytes;
    return MCBROT_OK;
}

static int payload_size(const uint8_t *payload, size_t payload_bytes, uint32_t frames, uint32_t joints,
                        double fps, const uint8_t *prior, size_t prior_bytes, size_t *size, char *message,
                        size_t message_bytes) {
    if (message && message_bytes) message[0] = 0;
    if (!size) return fail(message, message_bytes, MCBROT_E_ARGUMENT, "mcb-rot: `size` is NULL");
    container_t c = {0};
    c.prior = prior;
    c.prior_bytes = prior ? prior_bytes : 0;
    header_t h;
    layout_t l;
    uint32_t chunks, most, most_frames;
    int s = payload_container(payload, payload_bytes, frames, joints, fps, &c, message, message_bytes);
    if (s || (s = size_of(NULL, 0, &c, &h, &l, &chunks, &most, &most_frames, message, message_bytes))) return s;
    *size = l.total;
    return MCBROT_OK;
}

MCBROT_API int mcbrot_payload_context_size(const uint8_t *payload, size_t payload_bytes, uint32_t frames,
                                           uint32_t joints, double fps, size_t *size, char *message,
                                           size_t message_bytes) {
    return payload_size(payload, payload_bytes, frames, joints, fps, NULL, 0, size, message, message_bytes);
}

MCBROT_API int mcbrot_payload_context_size_with_prior(const uint8_t *payload, size_t payload_bytes, uint32_t frames,
                                                      uint32_t joints, double fps, const uint8_t *prior,
                                                      size_t prior_bytes, size_t *size, char *message,
                                                      size_t message_bytes) {
    return payload_size(payload, payload_bytes, frames, joints, fps, prior, prior_bytes, size, message,
                        message_bytes);
}

static int open_with(void *context, size_t context_bytes, container_t *c, const uint8_t *stream, size_t stream_bytes);

MCBROT_API int mcbrot_open(void *context, size_t context_bytes, const uint8_t *stream, size_t stream_bytes) {
    container_t c = {0};
    return open_with(context, context_bytes, &c, stream, stream_bytes);
}

MCBROT_API int mcbrot_open_with_prior(void *context, size_t context_bytes, const uint8_t *stream, size_t stream_bytes,
                                      const uint8_t *prior, size_t prior_bytes) {
    container_t c = {0};
    c.prior = prior;
    c.prior_bytes = prior ? prior_bytes : 0;
    return open_with(context, context_bytes, &c, stream, stream_bytes);
}

static int open_payload(void *context, size_t context_bytes, const uint8_t *payload, size_t payload_bytes,
                        uint32_t frames, uint32_t joints, double fps, const uint8_t *prior, size_t prior_bytes) {
    if (!context || (uintptr_t)context % MCBROT_CONTEXT_ALIGN) return MCBROT_E_ARGUMENT;
    if (context_bytes < sizeof(ctx_t)) return MCBROT_E_CONTEXT_SMALL;
    container_t c = {0};
    int s = payload_container(payload, payload_bytes, frames, joints, fps, &c, ((ctx_t *)context)->message,
                              MESSAGE_BYTES);
    if (s) return s;
    c.prior = prior;
    c.prior_bytes = prior ? prior_bytes : 0;
    return open_with(context, context_bytes, &c, NULL, 0);
}

MCBROT_API int mcbrot_open_payload(void *context, size_t context_bytes, const uint8_t *payload, size_t payload_bytes,
                                   uint32_t frames, uint32_t joints, double fps) {
    return open_payload(context, context_bytes, payload, payload_bytes, frames, joints, fps, NULL, 0);
}

MCBROT_API int mcbrot_open_payload_with_prior(void *context, size_t context_bytes, const uint8_t *payload,
                                              size_t payload_bytes, uint32_t frames, uint32_t joints, double fps,
                                              const uint8_t *prior, size_t prior_bytes) {
    return open_payload(context, context_bytes, payload, payload_bytes, frames, joints, fps, prior, prior_bytes);
}

/* ---------------------------------------------------------------------------------------------------------- */
/* budgets (budgets.joint_budgets): angle budgets from the lever arms, without the J x J chain matrix          */

static void budgets(ctx_t *x, double *rotation, double *base, double *dist, double *lever, double *sums,
                    double *reach) {
    uint32_t J = x->joints;
    const int32_t *parent = x->parents;
    /* reach[k]: the distance of k's virtual children (shell vertices; with flags bit 11 its end sites too) */
    int vertices = 0;
    for (uint32_t j = 0; j < J; ++j) reach[j] = x->shell;
    if (x->cover_ends)
        for (uint32_t e = 0; e < x->ends; ++e) {
            const double *o = x->offsets + 3 * ((size_t)J + e);
            double length = sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
            if (x->num_scales) { /* stretched by the joint's frame: its factor and its own peak (scales.py) */
                int32_t k = x->end_parents[e], t = x->scale_of[k];
                length = length * x->scale_factor[k] * (t >= 0 ? x->scale_peak[t] : 1.0);
            }
            if (length > reach[x->end_parents[e]]) reach[x->end_parents[e]] = length;
        }
    for (uint32_t j = 0; j < J; ++j) vertices |= reach[j] > 0;
    dist[0] = 0.0;
    for (uint32_t j = 1; j < J; ++j) { /* a translated joint's bone is its track's reach */
        const double *o = x->offsets + 3 * j;
        double bone = x->track_of[j] >= 0 ? x->track_reach[x->track_of[j]] : sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
        dist[j] = dist[parent[j]] + (x->num_scales ? bone * x->scale_factor[j] : bone);
    }
    /* lever[a] = max over the points a's rotation moves: proper descendants k (chain dist k - dist a) and, with
     * virtual children, those of a (reach a) and of its proper descendants (chain + reach k) */
    for (uint32_t j = 0; j < J; ++j) lever[j] = vertices ? reach[j] : 0.0;
    for (uint32_t k = J; k-- > 1;) {
        for (int32_t a = parent[k]; a >= 0; a = a > 0 ? parent[a] : -1) {
            double chain = dist[k] - dist[a];
            double far = vertices ? chain + reach[k] : chain;
            if (far > lever[a]) lever[a] = far;
        }
    }
    /* worst = max over points of sum over movers a of chain(a, point) / lever[a] */
    double worst = 0.0;
    for (uint32_t k = 0; k < J; ++k) {
        double joint = 0.0, vertex = vertices && lever[k] > 0 ? reach[k] / lever[k] : 0.0;
        for (int32_t a = k > 0 ? parent[k] : -1; a >= 0; a = a > 0 ? parent[a] : -1) {
            if (!(lever[a] > 0)) continue;
            double chain = dist[k] - dist[a];
            joint += chain / lever[a];
            if (vertices) vertex += (chain + reach[k]) / lever[a];
        }
        if (joint > worst) worst = joint;
        if (vertex > worst) worst = vertex;
    }
    double weight = worst > 0 ? x->bound * (1.0 - x->root_share) / worst : 0.0;
    for (uint32_t j = 0; j < J; ++j) rotation[j] = lever[j] > 0 ? weight / lever[j] : x->free_angle;
    if (x->power > 0) {
        for (uint32_t j = 0; j < J; ++j) sums[j] = vertices && reach[j] > 0 ? pow(reach[j], x->power) : 0.0;
        for (uint32_t k = 1; k < J; ++k)
            for (int32_t a = parent[k]; a >= 0; a = a > 0 ? parent[a] : -1) {
                double chain = dist[k] - dist[a];
                sums[a] += pow(chain, x->power);
                if (vertices) sums[a] += pow(chain + reach[k], x->power);
            }
        for (uint32_t j = 0; j < J; ++j)
            base[j] = lever[j] > 0 ? weight / pow(sums[j], 1.0 / x->power) : x->free_angle;
    } else {
        for (uint32_t j = 0; j < J; ++j) base[j] = rotation[j];
    }
}

/* ---------------------------------------------------------------------------------------------------------- */
/* quaternions                                                                                                 */

static void exp_map(double x, double y, double z, double *q) {
    double angle = sqrt(x * x + y * y + z * z);
    double scale = angle < 1e-6 ? 0.5 - angle * angle / 48.0 : sin(0.5 * angle) / angle;
    q[0] = x * scale;
    q[1] = y * scale;
    q[2] = z * scale;
    q[3] = cos(0.5 * angle);
}

/* The decoder's map (stream.assemble computes sin and cos of the half angle from tan(theta / 4); the same
 * values up to float rounding): for half angles up to pi / 2 by their Taylor series in h^2 (11 terms each: the
 * remainder is below 1e-16 there), beyond by libm. sin(h) / theta = 0.5 sin(h) / h. */
static void exp_map_fast(double x, double y, double z, double *q) {
    double squared = x * x + y * y + z * z;
    double h2 = 0.25 * squared; /* (theta / 2)^2 */
    double scale, w;
    if (h2 <= 2.4674011002723395) { /* (pi / 2)^2 */
        double s = 1.0 / 51090942171709440000.0, c;                   /* sin h / h = sum (-h2)^n / (2n + 1)! */
        s = 1.0 / 121645100408832000.0 - h2 * s;
        s = 1.0 / 355687428096000.0 - h2 * s;
        s = 1.0 / 1307674368000.0 - h2 * s;
        s = 1.0 / 6227020800.0 - h2 * s;
        s = 1.0 / 39916800.0 - h2 * s;
        s = 1.0 / 362880.0 - h2 * s;
        s = 1.0 / 5040.0 - h2 * s;
        s = 1.0 / 120.0 - h2 * s;
        s = 1.0 / 6.0 - h2 * s;
        s = 1.0 - h2 * s;
        c = 1.0 / 2432902008176640000.0;                              /* cos h = sum (-h2)^n / (2n)! */
        c = 1.0 / 6402373705728000.0 - h2 * c;
        c = 1.0 / 20922789888000.0 - h2 * c;
        c = 1.0 / 87178291200.0 - h2 * c;
        c = 1.0 / 479001600.0 - h2 * c;
        c = 1.0 / 3628800.0 - h2 * c;
        c = 1.0 / 40320.0 - h2 * c;
        c = 1.0 / 720.0 - h2 * c;
        c = 1.0 / 24.0 - h2 * c;
        c = 0.5 - h2 * c;
        c = 1.0 - h2 * c;
        scale = 0.5 * s;
        w = c;
    } else {
        double angle = sqrt(squared);
        scale = sin(0.5 * angle) / angle;
        w = cos(0.5 * angle);
    }
    q[0] = x * scale;
    q[1] = y * scale;
    q[2] = z * scale;
    q[3] = w;
}

#if defined(MCBROT_AVX2)
/* exp_map_fast of four joints at once (AVX2 + FMA: the same series, fused), their rotation vectors' x, y and z in
 * X, Y, Z; the quaternions (x y z w) out to q[0..16). Returns a mask of the joints past a half turn's series (their
 * quaternions are not written: exp_map_fast maps them). */
static TARGET_AVX2 ALWAYS_INLINE int exp_map_four(__m256d X, __m256d Y, __m256d Z, double *q) {
    __m256d squared = _mm256_fmadd_pd(Z, Z, _mm256_fmadd_pd(Y, Y, _mm256_mul_pd(X, X)));
    __m256d h2 = _mm256_mul_pd(_mm256_set1_pd(0.25), squared);
    int far = _mm256_movemask_pd(_mm256_cmp_pd(h2, _mm256_set1_pd(2.4674011002723395), _CMP_GT_OQ)) |
              _mm256_movemask_pd(_mm256_cmp_pd(h2, h2, _CMP_UNORD_Q));
    /* the series in u = h2 by Estrin's scheme (pairs of terms, then pairs of pairs by u^2, u^4, u^8): a chain of
     * five operations instead of Horner's eleven; sin h / h = sum (-u)^n / (2n + 1)!, cos h = sum (-u)^n / (2n)!,
     * n = 0..10, the same sums up to float rounding) */
    __m256d u = h2, u2 = _mm256_mul_pd(u, u), u4 = _mm256_mul_pd(u2, u2), u8 = _mm256_mul_pd(u4, u4);
#define K(v) _mm256_set1_pd(v)
#define PAIR(a, b) _mm256_fmadd_pd(K(b), u, K(a)) /* a + b u */
    __m256d s = _mm256_fmadd_pd(_mm256_fmadd_pd(PAIR(1.0 / 6227020800.0, -1.0 / 1307674368000.0), u2,
                                                PAIR(1.0 / 362880.0, -1.0 / 39916800.0)), u4,
                                _mm256_fmadd_pd(PAIR(1.0 / 120.0, -1.0 / 5040.0), u2, PAIR(1.0, -1.0 / 6.0)));
    s = _mm256_fmadd_pd(_mm256_fmadd_pd(K(1.0 / 51090942171709440000.0), u2,
                                        PAIR(1.0 / 355687428096000.0, -1.0 / 121645100408832000.0)), u8, s);
    __m256d c = _mm256_fmadd_pd(_mm256_fmadd_pd(PAIR(1.0 / 479001600.0, -1.0 / 87178291200.0), u2,
                                                PAIR(1.0 / 40320.0, -1.0 / 3628800.0)), u4,
                                _mm256_fmadd_pd(PAIR(1.0 / 24.0, -1.0 / 720.0), u2, PAIR(1.0, -0.5)));
    c = _mm256_fmadd_pd(_mm256_fmadd_pd(K(1.0 / 2432902008176640000.0), u2,
                                        PAIR(1.0 / 20922789888000.0, -1.0 / 6402373705728000.0)), u8, c);
#undef PAIR
#undef K
    __m256d scale = _mm256_mul_pd(_mm256_set1_pd(0.5), s);
    X = _mm256_mul_pd(X, scale);
    Y = _mm256_mul_pd(Y, scale);
    Z = _mm256_mul_pd(Z, scale);
    /* transpose: x y z w per joint */
    __m256d t0 = _mm256_unpacklo_pd(X, Y), t1 = _mm256_unpackhi_pd(X, Y);
    __m256d t2 = _mm256_unpacklo_pd(Z, c), t3 = _mm256_unpackhi_pd(Z, c);
    __m256d o0 = _mm256_permute2f128_pd(t0, t2, 0x20), o1 = _mm256_permute2f128_pd(t1, t3, 0x20);
    __m256d o2 = _mm256_permute2f128_pd(t0, t2, 0x31), o3 = _mm256_permute2f128_pd(t1, t3, 0x31);
    if (!(far & 1)) _mm256_storeu_pd(q, o0);
    if (!(far & 2)) _mm256_storeu_pd(q + 4, o1);
    if (!(far & 4)) _mm256_storeu_pd(q + 8, o2);
    if (!(far & 8)) _mm256_storeu_pd(q + 12, o3);
    return far;
}

/* exp_maps with AVX2: four joints at a time, read from the frame's runs of x, y and z as they lie (the last one to
 * three joints through a padded copy of their quaternions: the runs are padded, the output is not). */
static TARGET_AVX2 void exp_maps_avx2(const double *X, const double *Y, const double *Z, uint32_t J, double *q) {
    for (uint32_t j = 0; j < J; j += 4) {
        double tail[16];
        double *out = j + 4 <= J ? q + 4 * j : tail;
        int far = exp_map_four(_mm256_loadu_pd(X + j), _mm256_loadu_pd(Y + j), _mm256_loadu_pd(Z + j), out);
        for (uint32_t k = 0; k < 4 && j + k < J; ++k)
            if (far >> k & 1) exp_map_fast(X[j + k], Y[j + k], Z[j + k], out + 4 * k);
        if (out == tail) /* quaternion by quaternion (a memcpy of a variable size was a call) */
            for (uint32_t k = 0; j + k < J; ++k) _mm256_storeu_pd(q + 4 * (j + k), _mm256_loadu_pd(tail + 4 * k));
    }
}
#endif

/* Every joint's quaternion (q, J x 4) from its rotation vector in a frame's values (`values`, FRAME_DOUBLES:
 * exp_map_fast; four joints at a time with AVX2). */
static void exp_maps(const ctx_t *x, const double *values, double *q) {
    uint32_t J = x->joints;
    size_t P = JOINTS_PADDED(J);
    const double *X = values + 4, *Y = X + P, *Z = Y + P;
#if defined(MCBROT_AVX2)
    if (x->avx2) {
        exp_maps_avx2(X, Y, Z, J, q);
        return;
    }
#endif
    for (uint32_t j = 0; j < J; ++j) exp_map_fast(X[j], Y[j], Z[j], q + 4 * j);
}

static void multiply(const double *a, const double *b, double *out) {
    double x = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1];
    double y = a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0];
    double z = a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3];
    double w = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2];
    out[0] = x;
    out[1] = y;
    out[2] = z;
    out[3] = w;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* open                                                                                                        */

static int band_of(uint32_t k, uint32_t length, uint32_t nominal) {
    uint64_t scaled = (uint64_t)k * nominal, square = scaled * scaled, unit = (uint64_t)length * length;
    int band = 1;
    for (int m = 1; m < NUM_BANDS - 1; ++m) band += square >= unit << m;
    return band;
}

static int clip_class(int value) { return value < 0 ? 0 : value > NUM_CLASSES - 1 ? NUM_CLASSES - 1 : value; }

static int open_with(void *context, size_t context_bytes, container_t *given, const uint8_t *stream,
                     size_t stream_bytes) {
    if (!context) return MCBROT_E_ARGUMENT;
    if ((uintptr_t)context % MCBROT_CONTEXT_ALIGN) return MCBROT_E_ARGUMENT;
    if (context_bytes < sizeof(ctx_t)) return MCBROT_E_CONTEXT_SMALL;
    ctx_t *x = (ctx_t *)context;
    memset(x, 0, sizeof *x);
    char *message = x->message;
    container_t c = *given;
    header_t h;
    layout_t l;
    uint32_t chunks, most, most_frames;
    int s = size_of(stream, stream_bytes, &c, &h, &l, &chunks, &most, &most_frames, message, MESSAGE_BYTES);
    if (s) return s;
    if (context_bytes < l.total)
        return fail(message, MESSAGE_BYTES, MCBROT_E_CONTEXT_SMALL, "mcb-rot: the context holds %zu bytes, this "
                    "stream needs %zu (mcbrot_context_size)", context_bytes, l.total);
    uint8_t *base = (uint8_t *)context;
    x->parents = (int32_t *)(base + l.parents);
    x->offsets = (double *)(base + l.offsets);
    x->end_parents = (int32_t *)(base + l.end_parents);
    x->base_step = (double *)(base + l.base_step);
    x->correction_step = (double *)(base + l.correction_step);
    x->turned = (int32_t *)(base + l.turned);
    x->turned_joint = (uint32_t *)(base + l.turned_joint);
    x->axes = (double *)(base + l.axes);
    x->overrides = (override_t *)(base + l.overrides);
    x->seg_start = (uint32_t *)(base + l.seg_start);
    x->chunk_first = (uint32_t *)(base + l.chunk_first);
    x->chunk_offset = (uint32_t *)(base + l.chunk_offset);
    x->class_table = base + l.class_table;
    x->dc = (int64_t *)(base + l.dc);
    x->counts = (uint16_t *)(base + l.counts);
    x->values = (int32_t *)(base + l.values);
    x->order = (uint16_t *)(base + l.order);
    x->blocks = (uint32_t *)(base + l.blocks);
    x->longest = (uint32_t *)(base + l.longest);
    x->rank = (uint16_t *)(base + l.rank);
    x->value_at = (uint16_t *)(base + l.value_at);
    for (uint32_t ch = 0; ch < 3 + 3 * h.joints; ++ch) /* root x y z; joint j's x y z: 4 + j, 4 + Jp + j, 4 + 2 Jp + j */
        x->value_at[ch] = (uint16_t)(ch < 3 ? ch : 4 + (ch - 3) % 3 * JOINTS_PADDED(h.joints) + (ch - 3) / 3);
    for (int slot = 0; slot < (h.segments > 1 ? 2 : 1); ++slot) {
        x->cosines_slot[slot] = (double *)(base + l.cosines) + (size_t)slot * (2 * h.max_length + 1);
        x->bands_slot[slot] = base + l.bands + (size_t)slot * h.max_length;
    }
    x->track_of = (int32_t *)(base + l.track_of);
    x->track_joint = (uint32_t *)(base + l.track_joint);
    x->track_step = (double *)(base + l.track_step);
    x->track_base = (double *)(base + l.track_base);
    x->track_reach = (double *)(base + l.track_reach);
    x->track_class = base + l.track_class;
    x->track_values = (double *)(base + l.track_values);
    x->scratch = (double *)(base + l.scratch);
    x->still_pose = (double *)(base + l.still_pose);
    x->scale_of = (int32_t *)(base + l.scale_of);
    x->scale_joint = (uint32_t *)(base + l.scale_joint);
    x->scale_step = (double *)(base + l.scale_step);
    x->scale_base = (double *)(base + l.scale_base);
    x->scale_peak = (double *)(base + l.scale_peak);
    x->scale_class = base + l.scale_class;
    x->scale_factor = (double *)(base + l.scale_factor);
    x->scale_values = (double *)(base + l.scale_values);
    x->frame_block = l.frame_block;
    x->block_rows = l.frame_block > 1 ? (double *)(base + l.block_rows) : NULL;
    x->block_signal = l.frame_block > 1 ? (double *)(base + l.block_signal) : NULL;
#if defined(MCBROT_AVX2)
    x->avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma");
#endif
    x->bytes_used = l.total;
    x->payload = c.payload;
    x->payload_bytes = c.payload_bytes;
    x->frames = c.frames;
    x->joints = h.joints; /* the stream's (a still root apart: the header's less one) */
    x->channels = 3 + 3 * h.joints;
    x->fps = c.fps;
    x->segments = h.segments;
    x->chunks = chunks;
    x->ends = h.ends;
    x->eps = h.eps;
    x->bound = h.bound;
    x->multiplier = h.multiplier;
    x->slope = h.slope;
    x->rounding = h.rounding;
    x->root_share = h.root_share;
    x->free_angle = h.free_angle;
    x->power = h.power;
    x->shell = h.shell;
    x->cover_ends = h.cover_ends;
    x->segment_frames = h.segment_frames;
    x->chunk_frames = h.chunk_frames;
    x->num_overrides = h.num_overrides;
    x->num_turned = h.num_turned;
    x->unit_values = h.unit_values;
    x->max_length = h.max_length;
    x->max_chunk_segments = most;
    x->max_chunk_frames = most_frames;
    x->num_tracks = h.tracks ? h.num_tracks : 0;
    x->still = (uint32_t)h.still;
    memcpy(x->still_offset, h.still_offset, sizeof x->still_offset);
    memcpy(x->still_position, h.still_position, sizeof x->still_position);
    x->cached_chunk = -1;
    x->table_length[0] = x->table_length[1] = 0;
    uint32_t J = x->joints, C = x->channels, S = x->segments;
    reader_t r = {c.payload, 0, c.payload_bytes, message, MESSAGE_BYTES};
    /* skeleton (the stream's, or the prior's rig: the same fields, checked by plan) */
    reader_t sk = h.prior ? (reader_t){h.prior_data, 0, h.prior_bytes, message, MESSAGE_BYTES} : r;
    sk.pos = h.parents_at;
    x->parents[0] = -1;
    for (uint32_t j = 1; j < J; ++j) {
        uint64_t step;
        read_varint(&sk, &step, "parents", 10);
        x->parents[j] = (int32_t)(j - step);
    }
    for (uint32_t e = 0; e < h.ends; ++e) {
        uint64_t joint;
        read_varint(&sk, &joint, "end-site parents", 10);
        x->end_parents[e] = (int32_t)joint;
    }
    if (h.prior) { /* float64 offsets onto the stream's grid, as pack_skeleton_runtime: np.round (half to even) */
        double step = ldexp(1.0, h.exponent);
        for (size_t i = 0; i < 3 * ((size_t)J + h.ends); ++i)
            x->offsets[i] = (nearbyint(le64f(h.prior_data + h.prior_offsets_at + 8 * i) / step) + 0.0) * step;
    } else {
        read_offsets(&r, r.data + h.offsets_at, h.offsets_bytes, J + h.ends, ldexp(1.0, h.exponent), x->offsets,
                     J + h.ends);
    }
    /* cuts -> segment starts (the cuts go to the segment array's tail first) */
    r.pos = h.cuts_at;
    uint32_t num_cuts;
    read_count(&r, &num_cuts, c.frames - 1, "cut count");
    {
        uint32_t *cuts = x->seg_start + (S + 1) - num_cuts; /* S + 1 >= cuts + 1 */
        uint64_t at = 0;
        for (uint32_t i = 0; i < num_cuts; ++i) {
            uint64_t gap;
            read_varint(&r, &gap, "cuts", 10);
            at += gap;
            cuts[i] = (uint32_t)at;
        }
        /* the grid is written front to back and never reaches a cut it has still to read: every take has a
         * segment, so the segments up to take i end before index S + 1 - cuts + i, where cut i lies */
        uint32_t count, longest;
        segment_grid(c.frames, cuts, num_cuts, h.segment_frames, x->seg_start, &count, &longest);
    }
    chunk_grid(x->seg_start, S, h.chunk_frames, x->chunk_first, &chunks, &most);
    /* re-references (strictly increasing (segment, joint), as the encoder writes them) */
    r.pos = h.overrides_at;
    uint32_t n;
    read_count(&r, &n, (uint64_t)S * J, "re-reference count");
    for (uint32_t i = 0; i < n; ++i) {
        uint64_t segment, joint;
        double v[3];
        read_varint(&r, &segment, "re-referenced segment", 10);
        read_varint(&r, &joint, "re-referenced joint", 10);
        read_f32(&r, &v[0], "reference");
        read_f32(&r, &v[1], "reference");
        read_f32(&r, &v[2], "reference");
        if (segment >= S || joint >= J || !(fabs(v[0]) <= 2 * PI && fabs(v[1]) <= 2 * PI && fabs(v[2]) <= 2 * PI))
            return fail(message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: a re-reference names a segment or joint "
                        "outside the motion");
        if (i > 0 && (segment < x->overrides[i - 1].segment ||
                      (segment == x->overrides[i - 1].segment && joint <= x->overrides[i - 1].joint)))
            return fail(message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: the re-references are not in order");
        x->overrides[i].segment = (uint32_t)segment;
        x->overrides[i].joint = (uint32_t)joint;
        exp_map(v[0], v[1], v[2], x->overrides[i].quat);
    }
    /* principal axes */
    r.pos = h.axes_at;
    {
        const uint8_t *flags = r.data + r.pos;
        r.pos += (J + 7) / 8;
        uint32_t t = 0;
        for (uint32_t j = 0; j < J; ++j) {
            x->turned[j] = -1;
            if (!((flags[j >> 3] >> (7 - (j & 7))) & 1)) continue;
            int16_t code[3];
            for (int k = 0; k < 3; ++k) {
                code[k] = (int16_t)((uint16_t)r.data[r.pos] | (uint16_t)r.data[r.pos + 1] << 8);
                r.pos += 2;
            }
            if (code[0] == 0 && code[1] == 0 && code[2] == 0) continue; /* not turned: identity */
            double q[4];
            exp_map(code[0] * AXIS_STEP, code[1] * AXIS_STEP, code[2] * AXIS_STEP, q);
            double qx = q[0], qy = q[1], qz = q[2], qw = q[3];
            double *m = x->axes + 9 * t;
            m[0] = 1 - 2 * (qy * qy + qz * qz); m[1] = 2 * (qx * qy - qz * qw); m[2] = 2 * (qx * qz + qy * qw);
            m[3] = 2 * (qx * qy + qz * qw); m[4] = 1 - 2 * (qx * qx + qz * qz); m[5] = 2 * (qy * qz - qx * qw);
            m[6] = 2 * (qx * qz - qy * qw); m[7] = 2 * (qy * qz + qx * qw); m[8] = 1 - 2 * (qx * qx + qy * qy);
            x->turned_joint[t] = j;
            x->turned[j] = (int32_t)t++;
        }
        x->num_turned = t;
    }
    /* classes */
    r.pos = h.classes_at;
    uint8_t tilts[NUM_BANDS];
    read_small_ints(&r, C, 128, "channel classes", x->class_table); /* scale + 0, kept in the table's first column */
    read_small_ints(&r, NUM_BANDS - 1, 128, "band classes", tilts + 1);
    int tilt[NUM_BANDS];
    tilt[0] = 0;
    for (int b = 1; b < NUM_BANDS; ++b) tilt[b] = (int)tilts[b] - NUM_CLASSES;
    x->dc_tilt = (int)r.data[r.pos] - NUM_CLASSES;
    x->count_tilt = (int)r.data[r.pos + 1] - NUM_CLASSES;
    x->gap_class = r.data[r.pos + 2];
    x->value_class = r.data[r.pos + 3];
    r.pos += 4;
    for (uint32_t j = 0; j < J; ++j) x->track_of[j] = -1;
    if (h.tracks) read_tracks_header(&r, &h, x);
    x->num_scales = h.scales ? h.num_scales : 0;
    if (x->num_scales) { /* the frame factors (scales.py, frame_factors): products of the peaks above each joint */
        for (uint32_t j = 0; j < J; ++j) x->scale_of[j] = -1;
        read_scales_header(&r, &h, x);
        x->scale_factor[0] = 1.0;
        for (uint32_t j = 1; j < J; ++j) {
            int32_t p = x->parents[j], t = x->scale_of[p];
            x->scale_factor[j] = x->scale_factor[p] * (t >= 0 ? x->scale_peak[t] : 1.0);
        }
    }
    /* the class table (C x bands), built in place from the scales (last channel first: row c's scale sits at
     * index c, row c spans c * 12 .. c * 12 + 11 >= c) */
    for (uint32_t ch = C; ch-- > 0;) {
        int scale = x->class_table[ch];
        for (int b = 0; b < NUM_BANDS; ++b) x->class_table[(size_t)ch * NUM_BANDS + b] = (uint8_t)clip_class(scale + tilt[b]);
        x->class_table[(size_t)ch * NUM_BANDS] = (uint8_t)scale; /* column 0 (the DC band) keeps the raw scale */
    }
    /* budgets -> steps (scratch: the values area, unused until a chunk is decoded, may be small: use the dc area) */
    {
        double *rotation = x->correction_step + 1; /* J values */
        double *base_rad = x->base_step;           /* first J of C */
        double *work = x->scratch; /* dist, lever, sums, reach: 4 J doubles (the scratch holds 10 J + 9) */
        budgets(x, rotation, base_rad, work, work + J, work + 2 * J, work + 3 * J);
        double root_cm = x->bound * x->root_share;
        /* channel steps: root 3 x root_cm, then 3 per joint of base (written back to front over base_rad) */
        for (uint32_t j = J; j-- > 0;) {
            double b = base_rad[j] * x->multiplier;
            x->base_step[3 + 3 * j] = b;
            x->base_step[4 + 3 * j] = b;
            x->base_step[5 + 3 * j] = b;
        }
        /* (writing 3 + 3j.. for j descending never overwrites base_rad[i] for i < j: 3 + 3j > j) */
        x->base_step[0] = x->base_step[1] = x->base_step[2] = root_cm * x->multiplier;
        double scale = 2.0 / sqrt(3.0);
        x->correction_step[0] = root_cm * scale;
        for (uint32_t j = 0; j < J; ++j) rotation[j] *= scale;
    }
    /* the first segment's quantized means predicted from the prior's rig (prior.first_means): its mean signal
     * turned onto the principal axes, times sqrt(segment frames) over the base step, rounded; a value within 1e-6
     * of a rounding boundary makes the stream invalid (the encoder then writes the flag 0) */
    double *predicted = NULL;
    if (h.predicted) {
        predicted = x->scratch; /* C values (the scratch holds more) */
        const uint8_t *mean = h.prior_data + h.prior_mean_at;
        double root_n = sqrt((double)x->segment_frames);
        for (uint32_t ch = 0; ch < C; ++ch) {
            double value;
            if (ch < 3) {
                value = le64f(mean + 8 * ch);
            } else {
                uint32_t j = (ch - 3) / 3, l = (ch - 3) % 3;
                const uint8_t *v = mean + 8 * (3 + 3 * (size_t)j);
                if (x->turned[j] < 0) {
                    value = le64f(v + 8 * l);
                } else { /* axes.to_axes: the sum over the rotation vector's components, in numpy's order */
                    const double *m = x->axes + 9 * (size_t)x->turned[j];
                    value = (le64f(v) * m[l] + le64f(v + 8) * m[3 + l]) + le64f(v + 16) * m[6 + l];
                }
            }
            double scaled = value * root_n / x->base_step[ch];
            if (!(fabs(scaled) < 0x1p40) || fabs(scaled - floor(scaled) - 0.5) < 1e-6)
                return fail(message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: the stream predicts its first "
                            "segment's means where a rounding is too close to call");
            predicted[ch] = floor(scaled + 0.5);
        }
    }
    /* side unit: segment means then significance counts (differences along the segments) */
    r.pos = h.side_at;
    {
        unit_t u;
        uint64_t total = 2 * (uint64_t)S * C;
        const char *what = "segment means and significance counts";
        if ((s = unit_begin(&r, &u, (uint32_t)total, r.end, what))) return s;
        for (uint32_t seg = 0; seg < S; ++seg)
            for (uint32_t ch = 0; ch < C; ++ch) {
                int32_t v;
                int e = unit_next(&u, SIDE + clip_class(x->class_table[(size_t)ch * NUM_BANDS] + x->dc_tilt), &v);
                if (e) return unit_error(&r, e, what);
                size_t i = (size_t)seg * C + ch;
                x->dc[i] = (seg ? x->dc[i - C] : (predicted ? (int64_t)predicted[ch] : 0)) + v;
            }
        for (uint32_t seg = 0; seg < S; ++seg) {
            uint32_t length = x->seg_start[seg + 1] - x->seg_start[seg];
            for (uint32_t ch = 0; ch < C; ++ch) {
                int32_t v;
                int e = unit_next(&u, SIDE + clip_class(x->class_table[(size_t)ch * NUM_BANDS] + x->count_tilt), &v);
                if (e) return unit_error(&r, e, what);
                size_t i = (size_t)seg * C + ch;
                int64_t value = (seg ? (int64_t)x->counts[i - C] : 0) + v;
                if (value < 0 || value > (int64_t)length - 1)
                    return fail(message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: segment %u: significance counts "
                                "outside the segment", seg);
                x->counts[i] = (uint16_t)value;
            }
        }
        if ((s = unit_end(&r, &u, (uint32_t)total, what))) return s;
    }
    /* chunk sizes */
    {
        uint64_t at = 0;
        size_t sizes_at = r.pos;
        for (uint32_t k = 0; k < chunks; ++k) {
            uint64_t size;
            if ((s = read_varint(&r, &size, "chunk size", 10))) return s;
            at += size;
            if (at > c.payload_bytes) break;
        }
        (void)sizes_at;
        if (r.pos + at != c.payload_bytes)
            return fail(message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: the chunks end at byte %llu, the payload "
                        "has %zu", (unsigned long long)(r.pos + at), c.payload_bytes);
        r.pos = sizes_at;
        uint64_t offset = 0;
        for (uint32_t k = 0; k < chunks; ++k) {
            uint64_t size;
            read_varint(&r, &size, "chunk size", 10);
            x->chunk_offset[k] = (uint32_t)offset;
            offset += size;
        }
        for (uint32_t k = 0; k < chunks; ++k) x->chunk_offset[k] += (uint32_t)r.pos;
        x->chunk_offset[chunks] = (uint32_t)c.payload_bytes;
    }
    x->magic = OPEN_MAGIC;
    x->version = MCBROT_PAYLOAD_FORMAT;
    x->message[0] = 0;
    return MCBROT_OK;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* chunks                                                                                                      */

static int check_open(const void *context) {
    if (!context || (uintptr_t)context % MCBROT_CONTEXT_ALIGN) return MCBROT_E_ARGUMENT;
    if (((const ctx_t *)context)->magic != OPEN_MAGIC) return MCBROT_E_NOT_OPEN;
    return MCBROT_OK;
}

static void set_length(ctx_t *x, uint32_t n) {
    int slot = n == x->max_length ? 0 : 1;
    x->cosines = x->cosines_slot[slot];
    x->bands = x->bands_slot[slot];
    if (x->table_length[slot] == n) return;
    for (uint32_t m = 0; m <= 2 * n; ++m) x->cosines[m] = cos(PI * (double)m / (2.0 * n));
    for (uint32_t k = 0; k < n; ++k) {
        x->bands[k] = (uint8_t)(k ? band_of(k, n, x->segment_frames) : 0);
    }
    x->table_length[slot] = n;
}

/* The chunk's translation tracks (tracks.py, Tracks.q_of_values): one unit of second-order differences of q, track
 * by track, axis by axis, frame by frame; two running sums give q, value = base + step q (float64). The sums wrap
 * as numpy's int64 cumsum does (a corrupt stream gives wrong values, never undefined behaviour). */
static int load_tracks(ctx_t *x, reader_t *r, uint32_t k, uint32_t frames) {
    char what[48];
    snprintf(what, sizeof what, "chunk %u tracks", k);
    uint32_t T = x->num_tracks;
    uint64_t total = (uint64_t)T * 3 * frames;
    if (frames > x->max_chunk_frames || total > 0xffffffffu)
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: %s: %u frames in a chunk", what, frames);
    unit_t u;
    int s = unit_begin(r, &u, (uint32_t)total, r->end, what);
    if (s) return s;
    for (uint32_t t = 0; t < T; ++t)
        for (uint32_t axis = 0; axis < 3; ++axis) {
            uint32_t cls = SIDE + x->track_class[3 * t + axis];
            double base = x->track_base[3 * t + axis], step = x->track_step[t];
            uint64_t velocity = 0, q = 0;
            double *out = x->track_values + 3 * (size_t)t + axis;
            for (uint32_t i = 0; i < frames; ++i) {
                int32_t d;
                int e = unit_next(&u, cls, &d);
                if (e) return unit_error(r, e, what);
                velocity += (uint64_t)(int64_t)d;
                q += velocity;
                out[(size_t)i * 3 * T] = base + step * (double)(int64_t)q;
            }
        }
    return unit_end(r, &u, (uint32_t)total, what);
}

/* The chunk's scale tracks (scales.py): one unit as the translation tracks' (load_tracks), every value checked to
 * lie in (0, its track's peak] as Python checks it. */
static int load_scales(ctx_t *x, reader_t *r, uint32_t k, uint32_t frames) {
    char what[48];
    snprintf(what, sizeof what, "chunk %u scales", k);
    uint32_t T = x->num_scales;
    uint64_t total = (uint64_t)T * 3 * frames;
    if (frames > x->max_chunk_frames || total > 0xffffffffu)
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: %s: %u frames in a chunk", what, frames);
    unit_t u;
    int s = unit_begin(r, &u, (uint32_t)total, r->end, what);
    if (s) return s;
    for (uint32_t t = 0; t < T; ++t)
        for (uint32_t axis = 0; axis < 3; ++axis) {
            uint32_t cls = SIDE + x->scale_class[3 * t + axis];
            double base = x->scale_base[3 * t + axis], step = x->scale_step[t], peak = x->scale_peak[t];
            uint64_t velocity = 0, q = 0;
            double *out = x->scale_values + 3 * (size_t)t + axis;
            for (uint32_t i = 0; i < frames; ++i) {
                int32_t d;
                int e = unit_next(&u, cls, &d);
                if (e) return unit_error(r, e, what);
                velocity += (uint64_t)(int64_t)d;
                q += velocity;
                double value = base + step * (double)(int64_t)q;
                if (!(value > 0 && value <= peak))
                    return fail(x->message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: chunk %u: a decoded scale is "
                                "not in (0, its track's peak]", k);
                out[(size_t)i * 3 * T] = value;
            }
        }
    return unit_end(r, &u, (uint32_t)total, what);
}

/* A segment's coefficients, channel by channel, frequency q of a channel at q LANES in its block's lane (unit_value's
 * `once` a constant: two copies of the loop). Returns unit_value's codes. */
static ALWAYS_INLINE int chunk_coefficients(ctx_t *x, unit_t *v, const uint16_t *cnt, const uint32_t *blocks,
                                           const int once) {
    const uint8_t *bands = x->bands;
    for (uint32_t ch = 0; ch < x->channels; ++ch) {
        uint32_t kmax = cnt[ch], rank = x->rank[ch];
        int32_t *slot = x->values + blocks[rank / LANES] + rank % LANES - LANES;
        const uint8_t *row = x->class_table + (size_t)ch * NUM_BANDS;
        for (uint32_t q = 1; q <= kmax; ++q) {
            int e = unit_value(v, row[bands[q]], slot + q * LANES, once);
            if (e) return e;
        }
    }
    return 0;
}

/* Decode chunk `k` into the cache: every coefficient and correction (and the translation tracks' values); `once`:
 * a chunk playback reaches (its coefficients read without branches on the data: unit_value). */
static int load_chunk(ctx_t *x, uint32_t k, int once) {
    if (x->cached_chunk == (int64_t)k) return MCBROT_OK;
    x->cached_chunk = -1;
    x->next_slot = UINT32_MAX;
    char what[48];
    snprintf(what, sizeof what, "chunk %u", k);
    reader_t r = {x->payload, x->chunk_offset[k], x->chunk_offset[k + 1], x->message, MESSAGE_BYTES};
    uint32_t first = x->chunk_first[k], last = x->chunk_first[k + 1], C = x->channels;
    uint32_t frames = x->seg_start[last] - x->seg_start[first], slots = x->joints + 1;
    uint32_t count;
    int s;
    if ((s = read_count(&r, &count, (uint64_t)frames * slots, "correction count"))) return s;
    uint64_t coded = 0;
    for (uint32_t seg = first; seg < last; ++seg)
        for (uint32_t ch = 0; ch < C; ++ch) coded += x->counts[(size_t)seg * C + ch];
    uint64_t total = coded + 4 * (uint64_t)count;
    if (total > x->unit_values)
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: chunk %u: %llu values, the header says at "
                    "most %u", k, (unsigned long long)total, x->unit_values);
    unit_t u;
    if ((s = unit_begin(&r, &u, (uint32_t)total, r.end, what))) return s;
    uint32_t at = 0;
    for (uint32_t seg = first; seg < last; ++seg) {
        uint32_t n = x->seg_start[seg + 1] - x->seg_start[seg], local = seg - first;
        set_length(x, n);
        const uint16_t *cnt = x->counts + (size_t)seg * C;
        uint32_t B = (C + LANES - 1) / LANES;
        uint16_t *order = x->order + (size_t)local * B * LANES;
        uint32_t *blocks = x->blocks + (size_t)local * (B + 1);
        /* channels by decreasing count: a stable counting sort */
        uint32_t most = 0;
        for (uint32_t ch = 0; ch < C; ++ch) most = cnt[ch] > most ? cnt[ch] : most;
        {
            /* most + 1 <= n counters, in the scratch's channel area (the poses there may hold an output) */
            uint32_t *above = (uint32_t *)(x->scratch + 2 * POSE_DOUBLES(x->joints));
            for (uint32_t c = 0; c <= most; ++c) above[c] = 0;
            for (uint32_t ch = 0; ch < C; ++ch) ++above[cnt[ch]];
            for (uint32_t c = most + 1, total = 0; c-- > 0;) { /* first rank of count c */
                uint32_t here = above[c];
                above[c] = total;
                total += here;
            }
            for (uint32_t ch = 0; ch < C; ++ch) {
                uint32_t rank = above[cnt[ch]]++;
                order[rank] = (uint16_t)ch;
                x->rank[ch] = (uint16_t)rank;
            }
            for (uint32_t rank = C; rank < B * LANES; ++rank) order[rank] = 0; /* padding lanes: never written */
        }
        uint32_t start = at;
        for (uint32_t b = 0; b < B; ++b) {
            blocks[b] = start;
            start += LANES * cnt[order[b * LANES]];
        }
        blocks[B] = start;
        memset(x->values + at, 0, 4 * (size_t)(start - at));
        /* the unit in a local whose address never leaves this loop, so that its states stay in registers (a
         * store of a value through int32_t * could otherwise change the unit's fields as far as the compiler
         * knows) */
        unit_t v = u;
        int e = once ? chunk_coefficients(x, &v, cnt, blocks, 1) : chunk_coefficients(x, &v, cnt, blocks, 0);
        if (e) return unit_error(&r, e, what);
        u = v;
        x->longest[local] = most;
        at = start;
    }
    int64_t flat = -1;
    x->corr_flat = (uint32_t *)(x->values + at); /* at + 4 count <= unit_values + padding (checked above) */
    for (uint32_t i = 0; i < count; ++i) {
        int32_t gap;
        int e = unit_next(&u, SIDE + x->gap_class, &gap);
        if (e) return unit_error(&r, e, what);
        if (gap < 0)
            return fail(x->message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: chunk %u: a correction gap is negative", k);
        flat += (int64_t)gap + 1;
        if (flat >= (int64_t)frames * slots)
            return fail(x->message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: chunk %u: corrections run past the "
                        "chunk's end", k);
        x->corr_flat[i] = (uint32_t)flat;
    }
    at += count;
    x->corr_values_at = at;
    for (uint32_t i = 0; i < 3 * count; ++i) {
        int e = unit_next(&u, SIDE + x->value_class, &x->values[at++]);
        if (e) return unit_error(&r, e, what);
    }
    if ((s = unit_end(&r, &u, (uint32_t)total, what))) return s;
    if (x->num_tracks && (s = load_tracks(x, &r, k, frames))) return s;
    if (x->num_scales && (s = load_scales(x, &r, k, frames))) return s;
    if (r.pos != r.end)
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_CORRUPT, "mcb-rot: expected the end of chunk %u, found %zu "
                    "more bytes", k, r.end - r.pos);
    x->num_corrections = count;
    x->cached_chunk = k;
    return MCBROT_OK;
}

static uint32_t upper_bound(const uint32_t *array, uint32_t n, uint32_t value) {
    uint32_t low = 0, high = n;
    while (low < high) {
        uint32_t mid = low + (high - low) / 2;
        if (array[mid] <= value) low = mid + 1;
        else high = mid;
    }
    return low;
}

/* sums[0..LANES) = sum over q = 1..kmax of basis[q] x block[(q - 1) LANES + 0..LANES) (one channel per lane), in
 * increasing q: the order of synthesize_frames, so that a frame synthesised alone or in a block is the same bits. */
static inline void synthesize_block(const int32_t *block, const double *basis, uint32_t kmax, double *sums) {
    const double *b = basis + 1;
#if defined(MCBROT_SSE2)
#define PAIR(p) _mm_cvtepi32_pd(_mm_loadl_epi64((const __m128i *)(p))) /* two int32 -> two doubles */
    __m128d a0 = _mm_setzero_pd(), a1 = _mm_setzero_pd();
    for (uint32_t q = 0; q < kmax; ++q) {
        const int32_t *v = block + LANES * q;
        __m128d c = _mm_set1_pd(b[q]);
        a0 = _mm_add_pd(a0, _mm_mul_pd(c, PAIR(v)));
        a1 = _mm_add_pd(a1, _mm_mul_pd(c, PAIR(v + 2)));
    }
#undef PAIR
    _mm_storeu_pd(sums, a0);
    _mm_storeu_pd(sums + 2, a1);
#else
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    for (uint32_t q = 0; q < kmax; ++q) {
        const int32_t *v = block + LANES * q;
        s0 += b[q] * (double)v[0];
        s1 += b[q] * (double)v[1];
        s2 += b[q] * (double)v[2];
        s3 += b[q] * (double)v[3];
    }
    sums[0] = s0;
    sums[1] = s1;
    sums[2] = s2;
    sums[3] = s3;
#endif
}

#if defined(MCBROT_AVX2)
#define QUAD(p) _mm256_cvtepi32_pd(_mm_loadu_si128((const __m128i *)(p))) /* four int32 -> four doubles */

/* The AVX2 sums of a segment's blocks two at a time, b and b + 1 (k0 >= k1 coefficients each, as the blocks of a
 * segment are sorted; k1 = 0: block b alone), one register per block and frame. The order of each lane's products,
 * the same in synthesize_pair_avx2 (one frame) and synthesize_frames_avx2 (FRAME_BLOCK frames: a frame has the same
 * bits alone or in a block): q < k1 into one accumulator in increasing q; block b's q >= k1 in two, the even and the
 * odd q - k1, added to the first at the end (first + even, then + odd). In the shared range two loads of
 * coefficients and four of the rows feed eight multiply-adds. */
static TARGET_AVX2 ALWAYS_INLINE void synthesize_pair_avx2(const int32_t *p0, const int32_t *p1, uint32_t k0,
                                                          uint32_t k1, const double *basis, __m256d *s0,
                                                          __m256d *s1) {
    const double *b = basis + 1;
    __m256d a = _mm256_setzero_pd(), c = _mm256_setzero_pd(), e = _mm256_setzero_pd();
    uint32_t q = 0;
    for (; q < k1; ++q) {
        __m256d row = _mm256_broadcast_sd(b + q);
        a = _mm256_fmadd_pd(row, QUAD(p0 + LANES * q), a);
        c = _mm256_fmadd_pd(row, QUAD(p1 + LANES * q), c);
    }
    __m256d d = _mm256_setzero_pd();
    for (; q + 2 <= k0; q += 2) {
        d = _mm256_fmadd_pd(_mm256_broadcast_sd(b + q), QUAD(p0 + LANES * q), d);
        e = _mm256_fmadd_pd(_mm256_broadcast_sd(b + q + 1), QUAD(p0 + LANES * q + LANES), e);
    }
    if (q < k0) d = _mm256_fmadd_pd(_mm256_broadcast_sd(b + q), QUAD(p0 + LANES * q), d);
    *s0 = _mm256_add_pd(_mm256_add_pd(a, d), e);
    *s1 = c;
}

static TARGET_AVX2 ALWAYS_INLINE void synthesize_frames_avx2(const int32_t *p0, const int32_t *p1, uint32_t k0,
                                                             uint32_t k1, const double *rows, __m256d *s0,
                                                             __m256d *s1) {
    const double *r = rows + FRAME_BLOCK;
    __m256d a0 = _mm256_setzero_pd(), a1 = _mm256_setzero_pd(), a2 = _mm256_setzero_pd(), a3 = _mm256_setzero_pd();
    __m256d b0 = _mm256_setzero_pd(), b1 = _mm256_setzero_pd(), b2 = _mm256_setzero_pd(), b3 = _mm256_setzero_pd();
    uint32_t q = 0;
    for (; q < k1; ++q) {
        __m256d v = QUAD(p0 + LANES * q), w = QUAD(p1 + LANES * q), c;
        const double *row = r + FRAME_BLOCK * q;
        c = _mm256_broadcast_sd(row);
        a0 = _mm256_fmadd_pd(c, v, a0);
        b0 = _mm256_fmadd_pd(c, w, b0);
        c = _mm256_broadcast_sd(row + 1);
        a1 = _mm256_fmadd_pd(c, v, a1);
        b1 = _mm256_fmadd_pd(c, w, b1);
        c = _mm256_broadcast_sd(row + 2);
        a2 = _mm256_fmadd_pd(c, v, a2);
        b2 = _mm256_fmadd_pd(c, w, b2);
        c = _mm256_broadcast_sd(row + 3);
        a3 = _mm256_fmadd_pd(c, v, a3);
        b3 = _mm256_fmadd_pd(c, w, b3);
    }
    s1[0] = b0;
    s1[1] = b1;
    s1[2] = b2;
    s1[3] = b3;
    /* block b's own frequencies: even and odd q - k1 apart (b0..b3 are free again) */
    __m256d d0 = _mm256_setzero_pd(), d1 = _mm256_setzero_pd(), d2 = _mm256_setzero_pd(), d3 = _mm256_setzero_pd();
    b0 = b1 = b2 = b3 = _mm256_setzero_pd();
    for (; q + 2 <= k0; q += 2) {
        __m256d v = QUAD(p0 + LANES * q), w = QUAD(p0 + LANES * q + LANES);
        const double *c = r + FRAME_BLOCK * q, *n = c + FRAME_BLOCK;
        d0 = _mm256_fmadd_pd(_mm256_broadcast_sd(c), v, d0);
        d1 = _mm256_fmadd_pd(_mm256_broadcast_sd(c + 1), v, d1);
        d2 = _mm256_fmadd_pd(_mm256_broadcast_sd(c + 2), v, d2);
        d3 = _mm256_fmadd_pd(_mm256_broadcast_sd(c + 3), v, d3);
        b0 = _mm256_fmadd_pd(_mm256_broadcast_sd(n), w, b0);
        b1 = _mm256_fmadd_pd(_mm256_broadcast_sd(n + 1), w, b1);
        b2 = _mm256_fmadd_pd(_mm256_broadcast_sd(n + 2), w, b2);
        b3 = _mm256_fmadd_pd(_mm256_broadcast_sd(n + 3), w, b3);
    }
    if (q < k0) {
        __m256d v = QUAD(p0 + LANES * q);
        const double *c = r + FRAME_BLOCK * q;
        d0 = _mm256_fmadd_pd(_mm256_broadcast_sd(c), v, d0);
        d1 = _mm256_fmadd_pd(_mm256_broadcast_sd(c + 1), v, d1);
        d2 = _mm256_fmadd_pd(_mm256_broadcast_sd(c + 2), v, d2);
        d3 = _mm256_fmadd_pd(_mm256_broadcast_sd(c + 3), v, d3);
    }
    s0[0] = _mm256_add_pd(_mm256_add_pd(a0, d0), b0);
    s0[1] = _mm256_add_pd(_mm256_add_pd(a1, d1), b1);
    s0[2] = _mm256_add_pd(_mm256_add_pd(a2, d2), b2);
    s0[3] = _mm256_add_pd(_mm256_add_pd(a3, d3), b3);
}
#undef QUAD

/* A block's four channels' base steps, means (DC x its scale) and places in a frame's values; a padding lane past
 * C (its `order` entry is 0) gets zeros and the root's fourth value, which finish_values clears. The vectors are
 * built in registers (stored lanes read back as one vector would stall on the stores). */
static TARGET_AVX2 ALWAYS_INLINE void lane_constants(const ctx_t *x, const int64_t *dc, const uint16_t *order,
                                                    uint32_t lanes, double dc_scale, __m256d *step, __m256d *mean,
                                                    size_t *at) {
    uint32_t c0 = order[0], c1 = order[1], c2 = order[2], c3 = order[3];
    const double *base = x->base_step;
    *step = _mm256_setr_pd(base[c0], base[c1], base[c2], base[c3]);
    *mean = _mm256_mul_pd(_mm256_setr_pd((double)dc[c0], (double)dc[c1], (double)dc[c2], (double)dc[c3]),
                          _mm256_set1_pd(dc_scale));
    at[0] = x->value_at[c0];
    at[1] = x->value_at[c1];
    at[2] = x->value_at[c2];
    at[3] = x->value_at[c3];
    if (lanes < LANES) {
        double keep[LANES];
        for (uint32_t lane = 0; lane < LANES; ++lane) {
            keep[lane] = lane < lanes ? 1.0 : 0.0;
            if (lane >= lanes) at[lane] = 3;
        }
        __m256d mask = _mm256_loadu_pd(keep);
        *step = _mm256_mul_pd(*step, mask);
        *mean = _mm256_mul_pd(*mean, mask);
    }
}

/* put_values of one frame with AVX2 (base step x (mean + AC scale x sum), the inner product fused), the four lanes
 * stored to their places. */
static TARGET_AVX2 ALWAYS_INLINE void put_four(__m256d sums, __m256d step, __m256d mean, __m256d ac_scale,
                                              const size_t *at, double *out) {
    __m256d v = _mm256_mul_pd(step, _mm256_fmadd_pd(ac_scale, sums, mean));
    __m128d low = _mm256_castpd256_pd128(v), high = _mm256_extractf128_pd(v, 1);
    _mm_storel_pd(out + at[0], low);
    _mm_storeh_pd(out + at[1], low);
    _mm_storel_pd(out + at[2], high);
    _mm_storeh_pd(out + at[3], high);
}

/* Every block of a segment with AVX2, two at a time: frame values (FRAME_DOUBLES) of one frame from its basis row
 * (frames == 1), or of FRAME_BLOCK frames from their rows (out + f stride); finish_values is the caller's. */
static TARGET_AVX2 void segment_values_avx2(const ctx_t *x, const int32_t *values, const uint32_t *blocks,
                                            const uint16_t *order, const int64_t *dc, const double *rows,
                                            uint32_t frames, double ac, double dc_scale, double *out, size_t stride) {
    uint32_t C = x->channels, B = (C + LANES - 1) / LANES;
    __m256d ac_scale = _mm256_set1_pd(ac);
    for (uint32_t b = 0; b < B; b += 2) {
        uint32_t pair = b + 1 < B, k0 = (blocks[b + 1] - blocks[b]) / LANES;
        uint32_t k1 = pair ? (blocks[b + 2] - blocks[b + 1]) / LANES : 0;
        const int32_t *p0 = values + blocks[b], *p1 = values + blocks[b + pair];
        __m256d sums[2 * FRAME_BLOCK];
        if (frames == 1) synthesize_pair_avx2(p0, p1, k0, k1, rows, sums, sums + FRAME_BLOCK);
        else synthesize_frames_avx2(p0, p1, k0, k1, rows, sums, sums + FRAME_BLOCK);
        for (uint32_t k = 0; k <= pair; ++k) {
            uint32_t first = LANES * (b + k), lanes = C - first < LANES ? C - first : LANES;
            __m256d step, mean;
            size_t at[LANES];
            lane_constants(x, dc, order + first, lanes, dc_scale, &step, &mean, at);
            for (uint32_t f = 0; f < frames; ++f)
                put_four(sums[FRAME_BLOCK * k + f], step, mean, ac_scale, at, out + f * stride);
        }
    }
}
#endif

/* sums[f stride + 0..LANES) = sum over q = 1..kmax of rows[FRAME_BLOCK q + f] x block[(q - 1) LANES + 0..LANES),
 * f = 0..FRAME_BLOCK - 1: synthesize_block for four frames, each coefficient read once for all of them. */
static void synthesize_frames(const int32_t *block, const double *rows, uint32_t kmax, double *sums, size_t stride) {
    const double *r = rows + FRAME_BLOCK;
#if defined(MCBROT_SSE2)
#define PAIR(p) _mm_cvtepi32_pd(_mm_loadl_epi64((const __m128i *)(p)))
#define ONE(c, k, lo, hi) (lo = _mm_add_pd(lo, _mm_mul_pd(_mm_set1_pd((c)[k]), v0)), \
                           hi = _mm_add_pd(hi, _mm_mul_pd(_mm_set1_pd((c)[k]), v1)))
    __m128d a0 = _mm_setzero_pd(), a1 = _mm_setzero_pd(), b0 = _mm_setzero_pd(), b1 = _mm_setzero_pd();
    __m128d c0 = _mm_setzero_pd(), c1 = _mm_setzero_pd(), d0 = _mm_setzero_pd(), d1 = _mm_setzero_pd();
    for (uint32_t q = 0; q < kmax; ++q) {
        const int32_t *v = block + LANES * q;
        const double *c = r + FRAME_BLOCK * q;
        __m128d v0 = PAIR(v), v1 = PAIR(v + 2);
        ONE(c, 0, a0, a1);
        ONE(c, 1, b0, b1);
        ONE(c, 2, c0, c1);
        ONE(c, 3, d0, d1);
    }
#undef ONE
#undef PAIR
    _mm_storeu_pd(sums, a0);
    _mm_storeu_pd(sums + 2, a1);
    _mm_storeu_pd(sums + stride, b0);
    _mm_storeu_pd(sums + stride + 2, b1);
    _mm_storeu_pd(sums + 2 * stride, c0);
    _mm_storeu_pd(sums + 2 * stride + 2, c1);
    _mm_storeu_pd(sums + 3 * stride, d0);
    _mm_storeu_pd(sums + 3 * stride + 2, d1);
#else
    for (uint32_t f = 0; f < FRAME_BLOCK; ++f)
        for (uint32_t lane = 0; lane < LANES; ++lane) {
            double sum = 0.0;
            for (uint32_t q = 0; q < kmax; ++q) sum += r[FRAME_BLOCK * q + f] * (double)block[LANES * q + lane];
            sums[f * stride + lane] = sum;
        }
#endif
}

/* Row `into[stride q]`, q = 1..longest, of frame i of an n-frame segment: (1 + slope q / n) cos(pi (2 i + 1) q / 2n)
 * (the cosine table of length n in use). */
static void basis_row(const ctx_t *x, uint32_t n, uint32_t i, uint32_t longest, double *into, uint32_t stride) {
    uint32_t period = 4 * n, step = 2 * i + 1, m = 0;
    double slope = x->slope / (double)n;
    for (uint32_t q = 1; q <= longest; ++q) {
        m += step;
        if (m >= period) m -= period;
        uint32_t far = 0u - (uint32_t)(m > 2 * n); /* cos is even about 2 n: folded without a branch */
        into[(size_t)stride * q] = (1.0 + slope * (double)q) * x->cosines[(m & ~far) | ((period - m) & far)];
    }
}

/* basis_row of frames i .. i + FRAME_BLOCK - 1 into rows[FRAME_BLOCK q + k] (frames past the segment's end get
 * the formula's values: their sums are dropped); the same products as basis_row, the ramp shared. */
static void basis_rows(const ctx_t *x, uint32_t n, uint32_t i, uint32_t longest, double *rows) {
    uint32_t period = 4 * n, m0 = 0, m1 = 0, m2 = 0, m3 = 0, s0 = (2 * i + 1) % period, s1 = (2 * i + 3) % period,
             s2 = (2 * i + 5) % period, s3 = (2 * i + 7) % period;
    double slope = x->slope / (double)n;
    const double *cosines = x->cosines;
#define FOLD(m) ((m) & ~(0u - (uint32_t)((m) > 2 * n))) | ((period - (m)) & (0u - (uint32_t)((m) > 2 * n)))
#define STEP(m, s) (m += s, m -= period & (0u - (uint32_t)(m >= period)))
    for (uint32_t q = 1; q <= longest; ++q) {
        double ramp = 1.0 + slope * (double)q, *r = rows + FRAME_BLOCK * (size_t)q;
        STEP(m0, s0);
        STEP(m1, s1);
        STEP(m2, s2);
        STEP(m3, s3);
        r[0] = ramp * cosines[FOLD(m0)];
        r[1] = ramp * cosines[FOLD(m1)];
        r[2] = ramp * cosines[FOLD(m2)];
        r[3] = ramp * cosines[FOLD(m3)];
    }
#undef STEP
#undef FOLD
}

#if defined(MCBROT_AVX2)
/* The basis rows with AVX2 + FMA, frame by frame in a lane: cos(q theta), theta = pi (2 i + 1) / 2n, by turning
 * (cos, sin)(q theta) by theta, q = 1, 2, ... (theta's cosine and sine from the table; the turn's rounding grows
 * about linearly with q: under 1e-13 at q = 1000, far below what a row's product with a coefficient keeps), then
 * times the ramp. basis_row_avx2 (one frame) does each lane's operations in the same order: a frame's row has the
 * same bits alone or in a block. Departure from the numpy decoder, which takes each cosine from the library. */
static TARGET_AVX2 void turn_start(const ctx_t *x, uint32_t n, uint32_t i, double *c, double *s) {
    uint32_t m = 2 * i + 1;
    if (m > 2 * n) m = 2 * n; /* a frame past the segment's end (dropped): any finite row */
    *c = x->cosines[m];
    *s = x->cosines[m > n ? m - n : n - m]; /* sin(pi m / 2n) = cos(pi (n - m) / 2n) */
}

static TARGET_AVX2 void basis_row_avx2(const ctx_t *x, uint32_t n, uint32_t i, uint32_t longest, double *into) {
    double slope = x->slope / (double)n, C, S;
    turn_start(x, n, i, &C, &S);
    double c = C, s = S;
    for (uint32_t q = 1; q <= longest; ++q) {
        into[q] = fma(slope, (double)q, 1.0) * c;
        double t = s * S, u = c * S;
        c = fma(c, C, -t);
        s = fma(s, C, u);
    }
}

static TARGET_AVX2 void basis_rows_avx2(const ctx_t *x, uint32_t n, uint32_t i, uint32_t longest, double *rows) {
    double slope = x->slope / (double)n, c4[4], s4[4];
    for (int k = 0; k < 4; ++k) turn_start(x, n, i + k, c4 + k, s4 + k);
    __m256d C = _mm256_loadu_pd(c4), S = _mm256_loadu_pd(s4), c = C, s = S;
    for (uint32_t q = 1; q <= longest; ++q) {
        _mm256_storeu_pd(rows + FRAME_BLOCK * (size_t)q, _mm256_mul_pd(_mm256_set1_pd(fma(slope, (double)q, 1.0)), c));
        __m256d t = _mm256_mul_pd(s, S), u = _mm256_mul_pd(c, S);
        c = _mm256_fmsub_pd(c, C, t);
        s = _mm256_fmadd_pd(s, C, u);
    }
}
#endif

/* A block's channels (order[0..lanes)) in `count` frames from their AC sums (sums[LANES f + lane]): base step x
 * (DC + AC), each at its place in its frame's values (out + f stride + value_at). */
static ALWAYS_INLINE void put_values(const ctx_t *x, const int64_t *dc, const uint16_t *order, uint32_t lanes, const double *sums,
                       uint32_t count, double ac_scale, double dc_scale, double *out, size_t stride) {
    for (uint32_t lane = 0; lane < lanes; ++lane) {
        uint32_t ch = order[lane];
        double step = x->base_step[ch], mean = (double)dc[ch] * dc_scale;
        double *at = out + x->value_at[ch];
        for (uint32_t f = 0; f < count; ++f) at[f * stride] = step * (mean + ac_scale * sums[LANES * f + lane]);
    }
}

/* The rest of `count` frames' values once every channel is put: the rotation vectors of the joints with principal
 * axes turned back off them, zeros in the padding (the root's fourth value, the joints past J). */
static ALWAYS_INLINE void finish_values(const ctx_t *x, uint32_t count, double *out, size_t stride) {
    uint32_t J = x->joints;
    size_t P = JOINTS_PADDED(J);
    for (uint32_t f = 0; f < count; ++f) {
        double *v = out + f * stride, *X = v + 4, *Y = X + P, *Z = Y + P;
        v[3] = 0.0;
        /* the padding (P - J < 4 joints) written one by one: as a loop the compiler made it three calls of
         * memset per frame */
        if (J < P) {
            X[J] = Y[J] = Z[J] = 0.0;
            if (J + 1 < P) {
                X[J + 1] = Y[J + 1] = Z[J + 1] = 0.0;
                if (J + 2 < P) X[J + 2] = Y[J + 2] = Z[J + 2] = 0.0;
            }
        }
        for (uint32_t t = 0; t < x->num_turned; ++t) {
            uint32_t j = x->turned_joint[t];
            const double *a = x->axes + 9 * (size_t)t;
            double v0 = X[j], v1 = Y[j], v2 = Z[j];
            X[j] = a[0] * v0 + a[1] * v1 + a[2] * v2;
            Y[j] = a[3] * v0 + a[4] * v1 + a[5] * v2;
            Z[j] = a[6] * v0 + a[7] * v1 + a[8] * v2;
        }
    }
}

/* The values (FRAME_DOUBLES) of frame f in segment `seg` of the cached chunk `chunk` (eq. of the inverse DCT: every
 * channel's sum at frame i, LANES channels at a time, their counts decreasing, each block's sums put at once into
 * the frame's values: the root, then the rotation vectors, turned off their principal axes). Playback that moves
 * one frame forward or backward synthesises FRAME_BLOCK frames of the segment ahead at once, in the direction of
 * play, and keeps their values (block_signal): the values depend on the stream and the frame alone, so the block
 * stays valid whichever chunk is cached later. Any other access synthesises the frame alone. */
static const double *channel_values(ctx_t *x, uint32_t seg, uint32_t chunk, uint32_t f) {
    uint32_t C = x->channels, J = x->joints, n = x->seg_start[seg + 1] - x->seg_start[seg];
    uint32_t i = f - x->seg_start[seg], had = x->previous_plus_one, previous = had - 1u;
    x->previous_plus_one = f + 1;
    size_t stride = FRAME_DOUBLES(J);
    if (x->block_count && x->block_segment == seg && i - x->block_first < x->block_count)
        return x->block_signal + (size_t)(i - x->block_first) * stride;
    set_length(x, n);
    uint32_t B = (C + LANES - 1) / LANES, local = seg - x->chunk_first[chunk];
    const uint16_t *order = x->order + (size_t)local * B * LANES;
    const uint32_t *blocks = x->blocks + (size_t)local * (B + 1);
    uint32_t longest = x->longest[local];
    double ac_scale = sqrt(2.0 / (double)n), dc_scale = 1.0 / sqrt((double)x->segment_frames);
    const int64_t *dc = x->dc + (size_t)seg * C;
    double sums[FRAME_BLOCK * LANES]; /* a block's sums, frame by frame */
    uint32_t first = i, count = 1;
    if (x->frame_block > 1 && had && previous + 1 == f) {
        count = n - i < FRAME_BLOCK ? n - i : FRAME_BLOCK;
    } else if (x->frame_block > 1 && had && previous == f + 1) {
        first = i + 1 >= FRAME_BLOCK ? i + 1 - FRAME_BLOCK : 0;
        count = i + 1 - first;
    }
    if (count == 1) {
        double *signal = x->scratch + 2 * POSE_DOUBLES(J), *row = signal + stride; /* n + 1 */
#if defined(MCBROT_AVX2)
        if (x->avx2) basis_row_avx2(x, n, i, longest, row);
        else
#endif
            basis_row(x, n, i, longest, row, 1);
#if defined(MCBROT_AVX2)
        if (x->avx2) segment_values_avx2(x, x->values, blocks, order, dc, row, 1, ac_scale, dc_scale, signal, stride);
        else
#endif
            for (uint32_t b = 0; b < B; ++b) {
                uint32_t kmax = (blocks[b + 1] - blocks[b]) / LANES;
                synthesize_block(x->values + blocks[b], row, kmax, sums);
                put_values(x, dc, order + LANES * b, C - LANES * b < LANES ? C - LANES * b : LANES, sums, 1, ac_scale,
                           dc_scale, signal, stride);
            }
        finish_values(x, 1, signal, stride);
        return signal;
    }
    /* a block: frames past `count` are synthesised and dropped */
    double *rows = x->block_rows, *out = x->block_signal;
#if defined(MCBROT_AVX2)
    if (x->avx2) basis_rows_avx2(x, n, first, longest, rows);
    else
#endif
        basis_rows(x, n, first, longest, rows);
#if defined(MCBROT_AVX2)
    if (x->avx2) segment_values_avx2(x, x->values, blocks, order, dc, rows, FRAME_BLOCK, ac_scale, dc_scale, out, stride);
    else
#endif
        for (uint32_t b = 0; b < B; ++b) {
            uint32_t kmax = (blocks[b + 1] - blocks[b]) / LANES;
            synthesize_frames(x->values + blocks[b], rows, kmax, sums, LANES);
            put_values(x, dc, order + LANES * b, C - LANES * b < LANES ? C - LANES * b : LANES, sums, FRAME_BLOCK,
                       ac_scale, dc_scale, out, stride);
        }
    finish_values(x, FRAME_BLOCK, out, stride); /* every frame of the block (a constant count: unrolled) */
    x->block_segment = seg;
    x->block_first = first;
    x->block_count = count;
    return out + (size_t)(i - first) * stride;
}

/* The pose of frame f: rotations (J x 4), root (3); with `steps` (J x 3, row 0 untouched) every other joint's
 * translation from its parent: its track's value, else its skeleton offset. */
static int decode_frame(ctx_t *x, uint32_t f, double *rotations, double *root, double *steps) {
    uint32_t seg = x->last_segment, chunk;
    if (!(seg < x->segments && x->seg_start[seg] <= f && f < x->seg_start[seg + 1])) /* playback stays in a segment */
        seg = x->last_segment = upper_bound(x->seg_start, x->segments + 1, f) - 1;
    if (x->cached_chunk >= 0 && x->chunk_first[x->cached_chunk] <= seg && seg < x->chunk_first[x->cached_chunk + 1])
        chunk = (uint32_t)x->cached_chunk;
    else
        chunk = upper_bound(x->chunk_first, x->chunks + 1, seg) - 1;
    /* playback: this frame next to the previous one (channel_values keeps it) */
    uint32_t previous = x->previous_plus_one - 1u;
    int s = load_chunk(x, chunk, x->previous_plus_one && (previous + 1 == f || previous == f + 1));
    if (s) return s;
    uint32_t J = x->joints;
    const double *values = channel_values(x, seg, chunk, f);
    root[0] = values[0];
    root[1] = values[1];
    root[2] = values[2];
    exp_maps(x, values, rotations);
    /* re-references of this segment (sorted: binary search for its first) */
    if (x->num_overrides) {
        uint32_t low = 0, high = x->num_overrides;
        while (low < high) {
            uint32_t mid = low + (high - low) / 2;
            if (x->overrides[mid].segment < seg) low = mid + 1;
            else high = mid;
        }
        for (uint32_t o = low; o < x->num_overrides && x->overrides[o].segment == seg; ++o) {
            double *q = rotations + 4 * x->overrides[o].joint;
            double out[4];
            multiply(x->overrides[o].quat, q, out);
            memcpy(q, out, sizeof out);
        }
    }
    if (steps && J > 1) {
        /* a clip without translation tracks (most): the skeleton's offsets in one block; else joint by joint, the
         * context's arrays in locals (a store through `steps` could change them as far as the compiler knows) */
        uint32_t T = x->num_tracks;
        const double *offsets = x->offsets;
        if (!T) {
            memcpy(steps + 3, offsets + 3, 3 * sizeof(double) * (J - 1));
        } else {
            const double *values = x->track_values + (size_t)(f - x->seg_start[x->chunk_first[chunk]]) * 3 * T;
            const int32_t *track_of = x->track_of;
            for (uint32_t j = 1; j < J; ++j) {
                int32_t t = track_of[j];
                memcpy(steps + 3 * j, t >= 0 ? values + 3 * t : offsets + 3 * j, 3 * sizeof(double));
            }
        }
    }
    /* corrections of this frame */
    if (x->num_corrections) {
        uint32_t slots = J + 1;
        uint32_t local = f - x->seg_start[x->chunk_first[chunk]];
        uint32_t first = local * slots, last = first + slots;
        uint32_t low = 0, high = x->num_corrections, c;
        if (x->next_slot == first) { /* the frame after the last one decoded: its first correction is known */
            low = x->next_correction;
        } else {
            while (low < high) {
                uint32_t mid = low + (high - low) / 2;
                if (x->corr_flat[mid] < first) low = mid + 1;
                else high = mid;
            }
        }
        for (c = low; c < x->num_corrections && x->corr_flat[c] < last; ++c) {
            uint32_t slot = x->corr_flat[c] - first;
            const int32_t *v = x->values + x->corr_values_at + 3 * (size_t)c;
            double step = x->correction_step[slot];
            if (slot == 0) {
                root[0] += v[0] * step;
                root[1] += v[1] * step;
                root[2] += v[2] * step;
            } else {
                double turn[4], out[4];
                exp_map(v[0] * step, v[1] * step, v[2] * step, turn);
                double *q = rotations + 4 * (slot - 1);
                multiply(q, turn, out);
                memcpy(q, out, sizeof out);
            }
        }
        x->next_slot = last;
        x->next_correction = c;
    }
    return MCBROT_OK;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* the public calls                                                                                            */

MCBROT_API int mcbrot_info(const void *context, mcbrot_clip_info *info) {
    int s = check_open(context);
    if (s) return s;
    if (!info) return MCBROT_E_ARGUMENT;
    const ctx_t *x = (const ctx_t *)context;
    info->num_frames = x->frames;
    info->num_joints = x->joints + x->still;
    info->fps = x->fps;
    info->duration_s = (double)(x->frames - 1) / x->fps;
    info->eps_cm = x->eps;
    info->payload_format = x->version;
    info->num_segments = x->segments;
    info->num_chunks = x->chunks;
    info->context_bytes = x->bytes_used;
    info->num_tracks = x->num_tracks + x->still; /* a still root's child moves: its translation is a track */
    return MCBROT_OK;
}

MCBROT_API const char *mcbrot_message(const void *context) {
    if (!context || (uintptr_t)context % MCBROT_CONTEXT_ALIGN) return "mcb-rot: no context";
    return ((const ctx_t *)context)->message;
}

MCBROT_API int mcbrot_skeleton(const void *context, int32_t *parents, double *offsets) {
    int s = check_open(context);
    if (s) return s;
    const ctx_t *x = (const ctx_t *)context;
    uint32_t still = x->still;
    if (parents) {
        parents[0] = -1;
        for (uint32_t j = 0; j < x->joints; ++j) parents[j + still] = x->parents[j] + (int32_t)still;
        if (still) parents[1] = 0;
    }
    if (offsets) {
        if (still) memcpy(offsets, x->still_offset, 24);
        memcpy(offsets + 3 * still, x->offsets, 24 * (size_t)x->joints);
    }
    return MCBROT_OK;
}

/* A still root kept apart (flags bit 12) in front of a pose whose other joints are written one joint further in:
 * joint 0's rotation (the identity) and translation (its position), joint 1's translation from it (the stream's
 * root less that position). Either output may be NULL. */
static void put_still(const ctx_t *x, double *rotations, double *translations) {
    if (rotations) {
        rotations[0] = rotations[1] = rotations[2] = 0.0;
        rotations[3] = 1.0;
    }
    if (translations)
        for (int k = 0; k < 3; ++k) {
            translations[3 + k] -= x->still_position[k];
            translations[k] = x->still_position[k];
        }
}

/* Frames [start, start + count): rotations (count x J x 4), roots (count x 3) and/or translations (count x J x 3,
 * row 0 the root's); any output may be NULL. */
static int decode_range(ctx_t *x, uint32_t start, uint32_t count, double *rotations, double *roots,
                        double *translations) {
    x->message[0] = 0;
    if (start > x->frames || count > x->frames - start)
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_ARGUMENT, "mcb-rot: frames %u..%llu outside the clip's %u",
                    start, (unsigned long long)start + count, x->frames);
    size_t J = x->joints, W = J + x->still; /* W: the outputs' joints (a still root's in front) */
    double *pose = x->scratch, *moved = pose + 4 * J; /* J x 3: the root, then the steps */
    for (uint32_t f = 0; f < count; ++f) {
        int s = decode_frame(x, start + f, pose, moved, translations ? moved : NULL);
        if (s) return s;
        if (rotations) memcpy(rotations + 4 * (W * f + x->still), pose, 32 * J);
        if (roots) memcpy(roots + 3 * (size_t)f, x->still ? x->still_position : moved, 24);
        if (translations) memcpy(translations + 3 * (W * f + x->still), moved, 24 * J);
        if (x->still) put_still(x, rotations ? rotations + 4 * W * f : NULL, translations ? translations + 3 * W * f : NULL);
    }
    return MCBROT_OK;
}

MCBROT_API int mcbrot_decode_frames(void *context, uint32_t start, uint32_t count, double *rotations, double *roots) {
    int s = check_open(context);
    if (s) return s;
    return decode_range((ctx_t *)context, start, count, rotations, roots, NULL);
}

MCBROT_API int mcbrot_decode_pose_frames(void *context, uint32_t start, uint32_t count, double *rotations,
                                         double *translations) {
    int s = check_open(context);
    if (s) return s;
    return decode_range((ctx_t *)context, start, count, rotations, NULL, translations);
}

/* The pose at t into rotations (J x 4), root (3) and, when not NULL, steps (J x 3, rows 1..J-1). */
static int sample_into(ctx_t *x, double t, int rounding, double *rotations, double *root, double *steps) {
    x->message[0] = 0;
    if (!rotations || !root || rounding < MCBROT_NEAREST || rounding > MCBROT_LINEAR)
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_ARGUMENT, "mcb-rot: NULL output or unknown rounding %d",
                    rounding);
    double duration = (double)(x->frames - 1) / x->fps;
    if (!(t >= 0.0 && t <= duration))
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_TIME, "mcb-rot: t = %g s outside the clip [0, %g s]", t,
                    duration);
    double position = t * x->fps;
    double last = (double)(x->frames - 1);
    if (position > last) position = last;
    /* a time within a millionth of a frame of a frame is that frame (t = f / fps does not multiply back to f
     * exactly: ceil would step to the next frame) */
    double whole = floor(position + 0.5);
    if (fabs(position - whole) <= 1e-6) position = whole;
    double low = floor(position);
    uint32_t f0 = (uint32_t)low;
    switch (rounding) {
    case MCBROT_NEAREST: {
        double near = floor(position + 0.5);
        return decode_frame(x, (uint32_t)(near > last ? last : near), rotations, root, steps);
    }
    case MCBROT_FLOOR: return decode_frame(x, f0, rotations, root, steps);
    case MCBROT_CEIL: return decode_frame(x, (uint32_t)ceil(position), rotations, root, steps);
    default: break;
    }
    double alpha = position - low;
    if (alpha == 0.0 || f0 + 1 >= x->frames) return decode_frame(x, f0, rotations, root, steps);
    size_t J = x->joints;
    double *second = x->scratch + POSE_DOUBLES(J), *second_root = second + 4 * J, *second_steps = second_root;
    int s;
    if ((s = decode_frame(x, f0, rotations, root, steps)) ||
        (s = decode_frame(x, f0 + 1, second, second_root, steps ? second_steps : NULL)))
        return s;
    for (int k = 0; k < 3; ++k) root[k] += alpha * (second_root[k] - root[k]);
    if (steps && x->num_tracks)
        for (uint32_t t = 0; t < x->num_tracks; ++t) {
            size_t j = x->track_joint[t];
            for (int k = 0; k < 3; ++k) steps[3 * j + k] += alpha * (second_steps[3 * j + k] - steps[3 * j + k]);
        }
    for (size_t j = 0; j < J; ++j) {
        double *a = rotations + 4 * j, *b = second + 4 * j;
        double dot = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
        double sign = dot < 0 ? -1.0 : 1.0, norm = 0.0;
        for (int k = 0; k < 4; ++k) {
            a[k] += alpha * (sign * b[k] - a[k]);
            norm += a[k] * a[k];
        }
        norm = 1.0 / sqrt(norm);
        for (int k = 0; k < 4; ++k) a[k] *= norm;
    }
    return MCBROT_OK;
}

/* sample_into for the outputs' joints: a still root kept apart (flags bit 12) is put in front of the stream's. */
static int sample_rig(ctx_t *x, double t, int rounding, double *rotations, double *root, double *steps) {
    if (!x->still) return sample_into(x, t, rounding, rotations, root, steps);
    if (!rotations || !root) return sample_into(x, t, rounding, NULL, NULL, NULL); /* the NULL output's message */
    double inner_root[3]; /* without steps: the stream's root, which the outputs do not hold */
    int s = sample_into(x, t, rounding, rotations + 4, steps ? steps + 3 : inner_root, steps ? steps + 3 : NULL);
    if (s) return s;
    put_still(x, rotations, steps);
    if (root != steps) memcpy(root, x->still_position, 24);
    return MCBROT_OK;
}

MCBROT_API int mcbrot_sample(void *context, double t, int rounding, double *rotations, double *root) {
    int s = check_open(context);
    if (s) return s;
    return sample_rig((ctx_t *)context, t, rounding, rotations, root, NULL);
}

MCBROT_API int mcbrot_sample_pose(void *context, double t, int rounding, double *rotations, double *translations) {
    int s = check_open(context);
    if (s) return s;
    return sample_rig((ctx_t *)context, t, rounding, rotations, translations, translations);
}

/* float32 variants: sampled into the context's first pose, then narrowed. */
static int sample_f32(void *context, double t, int rounding, float *rotations, float *root, float *translations) {
    int s = check_open(context);
    if (s) return s;
    ctx_t *x = (ctx_t *)context;
    if (!rotations || (!root && !translations))
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_ARGUMENT, "mcb-rot: NULL output");
    size_t J = x->joints + x->still;
    double *pose = x->still ? x->still_pose : x->scratch, *moved = pose + 4 * J;
    if ((s = sample_rig(x, t, rounding, pose, moved, translations ? moved : NULL))) return s;
    for (size_t i = 0; i < 4 * J; ++i) rotations[i] = (float)pose[i];
    if (root)
        for (int k = 0; k < 3; ++k) root[k] = (float)moved[k];
    if (translations)
        for (size_t i = 0; i < 3 * J; ++i) translations[i] = (float)moved[i];
    return MCBROT_OK;
}

MCBROT_API int mcbrot_sample_f32(void *context, double t, int rounding, float *rotations, float *root) {
    return sample_f32(context, t, rounding, rotations, root, NULL);
}

MCBROT_API int mcbrot_sample_pose_f32(void *context, double t, int rounding, float *rotations, float *translations) {
    return sample_f32(context, t, rounding, rotations, NULL, translations);
}

MCBROT_API int mcbrot_tracks(const void *context, uint32_t *joints) {
    int s = check_open(context);
    if (s) return s;
    const ctx_t *x = (const ctx_t *)context;
    if (joints && x->still) joints[0] = 1; /* a still root's child: its translation moves */
    if (joints)
        for (uint32_t t = 0; t < x->num_tracks; ++t) joints[t + x->still] = x->track_joint[t] + x->still;
    return MCBROT_OK;
}

/* ---------------------------------------------------------------------------------------------------------- */
/* scale tracks (flags bit 13)                                                                                 */

/* Every joint's scale at frame f (W x 3, W the outputs' joints): its track's value, 1 where it has none (a still
 * root kept apart has no scale tracks: the stream refuses both). */
static int frame_scales(ctx_t *x, uint32_t f, double *out) {
    uint32_t seg = upper_bound(x->seg_start, x->segments + 1, f) - 1;
    uint32_t chunk = upper_bound(x->chunk_first, x->chunks + 1, seg) - 1;
    int s = load_chunk(x, chunk, 0);
    if (s) return s;
    size_t W = x->joints + x->still, T = x->num_scales;
    for (size_t i = 0; i < 3 * W; ++i) out[i] = 1.0;
    if (T) {
        const double *values = x->scale_values + (size_t)(f - x->seg_start[x->chunk_first[chunk]]) * 3 * T;
        for (size_t t = 0; t < T; ++t) memcpy(out + 3 * (size_t)x->scale_joint[t], values + 3 * t, 24);
    }
    return MCBROT_OK;
}

MCBROT_API int mcbrot_scales(const void *context, uint32_t *count, uint32_t *joints) {
    int s = check_open(context);
    if (s) return s;
    const ctx_t *x = (const ctx_t *)context;
    if (count) *count = x->num_scales;
    if (joints && x->num_scales) memcpy(joints, x->scale_joint, 4 * (size_t)x->num_scales);
    return MCBROT_OK;
}

MCBROT_API int mcbrot_decode_scale_frames(void *context, uint32_t start, uint32_t count, double *scales) {
    int s = check_open(context);
    if (s) return s;
    ctx_t *x = (ctx_t *)context;
    x->message[0] = 0;
    if (!scales || start > x->frames || count > x->frames - start)
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_ARGUMENT, "mcb-rot: NULL output or frames %u..%llu outside "
                    "the clip's %u", start, (unsigned long long)start + count, x->frames);
    for (uint32_t f = 0; f < count; ++f)
        if ((s = frame_scales(x, start + f, scales + 3 * ((size_t)x->joints + x->still) * f))) return s;
    return MCBROT_OK;
}

MCBROT_API int mcbrot_sample_scales(void *context, double t, int rounding, double *scales) {
    int s = check_open(context);
    if (s) return s;
    ctx_t *x = (ctx_t *)context;
    x->message[0] = 0;
    if (!scales || rounding < MCBROT_NEAREST || rounding > MCBROT_LINEAR)
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_ARGUMENT, "mcb-rot: NULL output or unknown rounding %d",
                    rounding);
    double duration = (double)(x->frames - 1) / x->fps;
    if (!(t >= 0.0 && t <= duration))
        return fail(x->message, MESSAGE_BYTES, MCBROT_E_TIME, "mcb-rot: t = %g s outside the clip [0, %g s]", t,
                    duration);
    double position = t * x->fps, last = (double)(x->frames - 1); /* the frames as sample_into picks them */
    if (position > last) position = last;
    double whole = floor(position + 0.5);
    if (fabs(position - whole) <= 1e-6) position = whole;
    double low = floor(position), alpha = position - low;
    uint32_t f0 = (uint32_t)low;
    if (rounding == MCBROT_NEAREST) return frame_scales(x, (uint32_t)(whole > last ? last : whole), scales);
    if (rounding == MCBROT_CEIL) return frame_scales(x, (uint32_t)ceil(position), scales);
    if (rounding == MCBROT_FLOOR || alpha == 0.0 || f0 + 1 >= x->frames) return frame_scales(x, f0, scales);
    size_t W = x->joints + x->still;
    double *second = x->scratch; /* W x 3 <= the scratch's first pose, 7 J + 3 */
    if ((s = frame_scales(x, f0, scales)) || (s = frame_scales(x, f0 + 1, second))) return s;
    for (size_t i = 0; i < 3 * W; ++i) scales[i] += alpha * (second[i] - scales[i]);
    return MCBROT_OK;
}
