/* libFuzzer target of the runtime (built with ASan and UBSan: `make -C runtime fuzz`).
 *
 * Input: one mode byte, then a whole `.mcb` stream. Mode bit 0 clear: the stream goes through mcbrot_open (container,
 * CRC, payload). Mode bit 0 set: its payload goes through mcbrot_open_payload with the frame count, joint count and
 * frame rate its header names (folded into 1..4096 frames and 1..512 joints), skipping the CRC, so that mutations
 * reach the payload parser and the entropy decoder instead of stopping at the checksum. An opened clip is then
 * sampled with bounded work (at most three chunks decoded): its first two frames, two times taken from the input's
 * last bytes with the rounding modes they name (one of them as a whole pose in float32: rotations and translation
 * tracks), every joint's scale, and calls that must fail (a frame past the end, NaN and negative times). Contexts above 4 MiB are not
 * allocated (an engine checks mcbrot_context_size against its budget the same way); the clamps keep an execution
 * cheap, so that a campaign reaches millions of inputs.
 *
 * Mode bit 1 set: a prior (flags bit 15, mocapbench/codecs/mcb_rot/prior.py) comes first: u16 little-endian length
 * n, n bytes of prior (cut to what the input holds), then the stream, opened with that prior. The fuzzer is built
 * with FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION, under which the runtime skips the comparison of the stream's
 * fingerprint with the prior's CRC32, so that mutations of the prior and of the stream reach the prior's parser and
 * the rig it gives (the C tests check the comparison).
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "mcbrot.h"

#define MAX_CONTEXT (4u << 20)

static uint32_t le32(const uint8_t *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void exercise(void *context, const uint8_t *data, size_t size) {
    mcbrot_clip_info info;
    if (mcbrot_info(context, &info) != MCBROT_OK) abort();
    size_t joints = info.num_joints;
    double *rotations = malloc(sizeof(double) * (4 * joints * 2 + 6 + 3 * joints));
    double *roots = rotations + 4 * joints * 2;
    float *narrow = malloc(sizeof(float) * 7 * joints);
    if (!rotations || !narrow) abort();
    uint32_t count = info.num_frames < 2 ? info.num_frames : 2;
    (void)mcbrot_decode_frames(context, 0, count, rotations, roots);
    (void)mcbrot_decode_frames(context, info.num_frames, 1, rotations, roots); /* outside: an error */
    uint32_t bits = size >= 8 ? (uint32_t)data[size - 1] | (uint32_t)data[size - 2] << 8 | (uint32_t)data[size - 3] << 16 |
                                    (uint32_t)data[size - 4] << 24
                              : 0x12345678u;
    double t = info.duration_s * (double)(bits & 0x7fff) / 32767.0;
    (void)mcbrot_sample(context, t, (int)(bits >> 15) & 3, rotations, roots);
    t = info.duration_s * (double)((bits >> 17) & 0x7fff) / 32767.0;
    (void)mcbrot_sample_pose_f32(context, t, (int)(bits >> 30), narrow, narrow + 4 * joints);
    (void)mcbrot_sample_scales(context, t, (int)(bits >> 15) & 3, roots + 6); /* (scale tracks, flag bit 13) */
    if (info.num_frames > 1) { /* playback: frames one after another, forward then backward, from a frame the input
                                  * picks (the blocks of four frames in either direction, the last frame's segment
                                  * and chunk taken again, segment and chunk edges crossed) */
        uint32_t last = info.num_frames - 1, first = (bits >> 3) % info.num_frames;
        for (uint32_t k = 0; k < 6 && first + k <= last; ++k)
            (void)mcbrot_sample(context, info.duration_s * (double)(first + k) / (double)last, MCBROT_NEAREST,
                                rotations, roots);
        for (uint32_t k = 0; k < 6 && k <= first; ++k)
            (void)mcbrot_sample_pose(context, info.duration_s * (double)(first - k) / (double)last, MCBROT_NEAREST,
                                     rotations, roots + 6); /* translations: J x 3 */
    }
    (void)mcbrot_sample(context, -1.0, MCBROT_LINEAR, rotations, roots);
    (void)mcbrot_sample(context, NAN, MCBROT_NEAREST, rotations, roots);
    free(narrow);
    free(rotations);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1) return 0;
    int payload_mode = data[0] & 1;
    const uint8_t *stream = data + 1;
    size_t bytes = size - 1;
    const uint8_t *prior = NULL;
    size_t prior_bytes = 0;
    if (data[0] & 2) {
        if (bytes < 2) return 0;
        prior_bytes = (size_t)stream[0] | (size_t)stream[1] << 8;
        if (prior_bytes > bytes - 2) prior_bytes = bytes - 2;
        prior = stream + 2;
        stream += 2 + prior_bytes;
        bytes -= 2 + prior_bytes;
    }
    size_t context_bytes = 0;
    char message[256];
    if (!payload_mode) {
        if (mcbrot_context_size_with_prior(stream, bytes, prior, prior_bytes, &context_bytes, message,
                                           sizeof message) != MCBROT_OK)
            return 0;
        if (context_bytes > MAX_CONTEXT) return 0;
        void *context = aligned_alloc(MCBROT_CONTEXT_ALIGN, (context_bytes + 15) & ~(size_t)15);
        if (!context) return 0;
        if (mcbrot_open_with_prior(context, context_bytes, stream, bytes, prior, prior_bytes) == MCBROT_OK)
            exercise(context, data, size);
        /* a context one byte short must be refused */
        if (context_bytes > 256 &&
            mcbrot_open_with_prior(context, context_bytes - 16, stream, bytes, prior, prior_bytes) !=
                MCBROT_E_CONTEXT_SMALL)
            abort();
        free(context);
        return 0;
    }
    /* payload mode: find the payload after the container header without checking the CRC */
    if (bytes < 10 || memcmp(stream, "MCB\0", 4) != 0) return 0;
    uint32_t version = stream[4], name = stream[9];
    size_t fields = version == 1 ? 18 : 23, fixed = 10 + name + fields;
    if (bytes < fixed) return 0;
    const uint8_t *f = stream + 10 + name;
    uint32_t frames = le32(f), joints = (uint32_t)f[4] | (uint32_t)f[5] << 8;
    if (frames < 1 || frames > 4096) frames = frames % 4096 + 1;
    if (joints < 1 || joints > 512) joints = joints % 512 + 1;
    double fps = 120.0;
    const uint8_t *payload = stream + fixed;
    size_t payload_bytes = bytes - fixed;
    if (mcbrot_payload_context_size_with_prior(payload, payload_bytes, frames, joints, fps, prior, prior_bytes,
                                               &context_bytes, message, sizeof message) != MCBROT_OK)
        return 0;
    if (context_bytes > MAX_CONTEXT) return 0;
    void *context = aligned_alloc(MCBROT_CONTEXT_ALIGN, (context_bytes + 15) & ~(size_t)15);
    if (!context) return 0;
    if (mcbrot_open_payload_with_prior(context, context_bytes, payload, payload_bytes, frames, joints, fps, prior,
                                       prior_bytes) == MCBROT_OK)
        exercise(context, data, size);
    free(context);
    return 0;
}
