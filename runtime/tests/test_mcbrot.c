/* Tests of the runtime on streams given on the command line (`make test`: the repository's golden streams; built
 * with ASan and UBSan). Every stream: the right status for what it is (format 6 mcb-rot opens; older mcb-rot
 * formats, other codecs refused); every format 6 stream: every frame decodes to unit quaternions, the sampling
 * modes agree with the frames, and every hostile variant (each truncation, flipped bytes, a context too small,
 * times outside the clip) is refused with a status and a message. A stream `name.mcb` with `name.prior` beside it
 * names a rig of that prior (flags bit 15): it opens with the prior, and is refused without it, with another prior
 * (one byte changed: the fingerprint differs) and with the prior cut short. Prints one line per stream; exit 1 on
 * failure. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mcbrot.h"

static int failures = 0;
#define CHECK(cond, ...)                                                                                           \
    do {                                                                                                           \
        if (!(cond)) {                                                                                             \
            ++failures;                                                                                            \
            printf("FAIL %s:%d: ", __FILE__, __LINE__);                                                            \
            printf(__VA_ARGS__);                                                                                   \
            printf("\n");                                                                                          \
        }                                                                                                          \
    } while (0)

/* The prior of the stream under test (NULL: none). */
static const unsigned char *prior = NULL;
static size_t prior_bytes = 0;

static unsigned char *read_file(const char *path, size_t *n) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *data = malloc((size_t)size + 1);
    *n = fread(data, 1, (size_t)size, f);
    fclose(f);
    return data;
}

static void *open_clip(const unsigned char *data, size_t n, int *status, size_t *size) {
    char message[256];
    *status = mcbrot_context_size_with_prior(data, n, prior, prior_bytes, size, message, sizeof message);
    if (*status) return NULL;
    void *context = aligned_alloc(16, (*size + 15) & ~(size_t)15);
    *status = mcbrot_open_with_prior(context, *size, data, n, prior, prior_bytes);
    if (*status) {
        free(context);
        return NULL;
    }
    return context;
}

static void test_hostile(const unsigned char *data, size_t n) {
    unsigned char *copy = malloc(n);
    size_t size;
    int status;
    for (size_t cut = 0; cut < n; cut += 1 + cut / 64) { /* every truncation is refused */
        memcpy(copy, data, cut);
        void *context = open_clip(copy, cut, &status, &size);
        CHECK(context == NULL && status != MCBROT_OK, "a stream cut at %zu of %zu bytes opened", cut, n);
        free(context);
    }
    for (size_t at = 0; at < n; at += 1 + at / 32) { /* a flipped byte: the CRC (or the header) catches it */
        memcpy(copy, data, n);
        copy[at] ^= 0x5a;
        void *context = open_clip(copy, n, &status, &size);
        CHECK(context == NULL && status != MCBROT_OK, "a stream with byte %zu flipped opened", at);
        free(context);
    }
    free(copy);
}

/* Whole poses (translation tracks): row 0 is the root, the rotations are the frames', a tracked joint's translation
 * changes over the clip while the others keep their offsets, every rounding mode gives its frame, linear lies
 * between, float32 is the float64 pose narrowed. */
static void test_poses(const char *path, void *context, const mcbrot_clip_info *info, const double *rotations,
                       const double *roots) {
    size_t J = info->num_joints, F = info->num_frames;
    double *rot = malloc(sizeof(double) * 4 * J * F), *moved = malloc(sizeof(double) * 3 * J * F);
    double *offsets = malloc(sizeof(double) * 3 * J), *pose = malloc(sizeof(double) * 7 * J);
    float *narrow = malloc(sizeof(float) * 7 * J);
    uint32_t tracked[4096];
    CHECK(mcbrot_decode_pose_frames(context, 0, (uint32_t)F, rot, moved) == MCBROT_OK, "%s: poses", path);
    CHECK(mcbrot_skeleton(context, NULL, offsets) == MCBROT_OK && mcbrot_tracks(context, tracked) == MCBROT_OK, "tracks");
    CHECK(memcmp(rot, rotations, 32 * J * F) == 0, "%s: the poses' rotations differ from the frames'", path);
    int moves = 0;
    for (size_t f = 0; f < F; ++f) {
        CHECK(memcmp(moved + 3 * J * f, roots + 3 * f, 24) == 0, "%s: row 0 of frame %zu is not the root", path, f);
        for (size_t j = 1; j < J; ++j) {
            int is_tracked = 0;
            for (uint32_t t = 0; t < info->num_tracks; ++t) is_tracked |= tracked[t] == j;
            const double *v = moved + 3 * (J * f + j);
            if (!is_tracked)
                CHECK(memcmp(v, offsets + 3 * j, 24) == 0, "%s: joint %zu without a track moves", path, j);
            else if (f > 0)
                moves |= memcmp(v, v - 3 * J, 24) != 0;
        }
    }
    CHECK(!info->num_tracks || F < 3 || moves, "%s: no tracked joint moves", path);
    for (size_t f = 0; f < F; f += 1 + F / 13) {
        for (int mode = 0; mode < 3; ++mode) {
            CHECK(mcbrot_sample_pose(context, (double)f / info->fps, mode, pose, pose + 4 * J) == MCBROT_OK, "pose");
            CHECK(memcmp(pose + 4 * J, moved + 3 * J * f, 24 * J) == 0, "%s: pose mode %d, frame %zu", path, mode, f);
        }
        if (f + 1 < F) {
            CHECK(mcbrot_sample_pose(context, (f + 0.5) / info->fps, MCBROT_LINEAR, pose, pose + 4 * J) == MCBROT_OK,
                  "linear pose");
            for (size_t i = 0; i < 3 * J; ++i) {
                double a = moved[3 * J * f + i], b = moved[3 * J * (f + 1) + i], v = pose[4 * J + i];
                CHECK(v >= fmin(a, b) - 1e-9 && v <= fmax(a, b) + 1e-9, "%s: a linear translation outside", path);
            }
        }
        CHECK(mcbrot_sample_pose_f32(context, (double)f / info->fps, MCBROT_NEAREST, narrow, narrow + 4 * J) ==
              MCBROT_OK, "f32 pose");
        for (size_t i = 0; i < 3 * J; ++i)
            CHECK(narrow[4 * J + i] == (float)moved[3 * J * f + i], "%s: f32 translation %zu", path, i);
    }
    free(rot);
    free(moved);
    free(offsets);
    free(pose);
    free(narrow);
}

/* A still root kept apart (flags bit 12; streams named *still-root*): the calls give the whole rig, joint 0 the still
 * root (parent -1, the identity rotation and one place on every frame, sampled or decoded, in float64 and float32),
 * joint 1 its child, listed first among the tracked joints. */
static void test_still_root(const char *path, void *context, const mcbrot_clip_info *info, const double *rotations,
                            const double *roots) {
    size_t J = info->num_joints, F = info->num_frames;
    int32_t *parents = malloc(sizeof(int32_t) * J);
    uint32_t *tracked = malloc(sizeof(uint32_t) * J);
    double *pose = malloc(sizeof(double) * 7 * J);
    float *narrow = malloc(sizeof(float) * 7 * J);
    CHECK(J >= 2 && info->num_tracks >= 1, "%s: a still root's rig has %zu joints, %u tracks", path, J, info->num_tracks);
    CHECK(mcbrot_skeleton(context, parents, NULL) == MCBROT_OK && mcbrot_tracks(context, tracked) == MCBROT_OK, "rig");
    CHECK(parents[0] == -1 && parents[1] == 0 && tracked[0] == 1, "%s: joint 1 is not the still root's tracked child",
          path);
    for (size_t j = 2; j < J; ++j) CHECK(parents[j] >= 1 && parents[j] < (int32_t)j, "%s: parent of %zu", path, j);
    for (size_t f = 0; f < F; ++f) {
        const double *q = rotations + 4 * J * f;
        CHECK(q[0] == 0.0 && q[1] == 0.0 && q[2] == 0.0 && q[3] == 1.0, "%s: the still root turns at frame %zu", path, f);
        CHECK(memcmp(roots + 3 * f, roots, 24) == 0, "%s: the still root moves at frame %zu", path, f);
    }
    for (int mode = 0; mode < 4; ++mode) {
        double t = info->duration_s * (0.37 + 0.1 * mode);
        CHECK(mcbrot_sample_pose(context, t, mode, pose, pose + 4 * J) == MCBROT_OK, "still pose");
        CHECK(pose[3] == 1.0 && memcmp(pose + 4 * J, roots, 24) == 0, "%s: sampled still root, mode %d", path, mode);
        CHECK(mcbrot_sample(context, t, mode, pose, pose + 4 * J) == MCBROT_OK, "still sample");
        CHECK(pose[3] == 1.0 && memcmp(pose + 4 * J, roots, 24) == 0, "%s: sampled still root, mode %d", path, mode);
        CHECK(mcbrot_sample_pose_f32(context, t, mode, narrow, narrow + 4 * J) == MCBROT_OK, "still f32 pose");
        CHECK(narrow[3] == 1.0f && narrow[4 * J] == (float)roots[0] && narrow[4 * J + 2] == (float)roots[2],
              "%s: float32 still root, mode %d", path, mode);
        CHECK(mcbrot_sample_f32(context, t, mode, narrow, narrow + 4 * J) == MCBROT_OK, "still f32");
        CHECK(narrow[3] == 1.0f && narrow[4 * J + 1] == (float)roots[1], "%s: float32 root, mode %d", path, mode);
    }
    CHECK(mcbrot_sample(context, 0.0, MCBROT_NEAREST, NULL, pose) == MCBROT_E_ARGUMENT, "a NULL output accepted");
    free(parents);
    free(tracked);
    free(pose);
    free(narrow);
}

/* Scale tracks (flags bit 13; streams named *scales*): the scaled joints listed, every frame's scales positive and 1
 * on the other joints, every rounding mode gives its frame's scales, linear lies between; a clip without scale
 * tracks gives 1 everywhere. */
static void test_scales(const char *path, void *context, const mcbrot_clip_info *info) {
    size_t J = info->num_joints, F = info->num_frames;
    uint32_t count = 0, *joints = malloc(sizeof(uint32_t) * J);
    double *all = malloc(sizeof(double) * 3 * J * F), *one = malloc(sizeof(double) * 3 * J);
    int scaled = strstr(path, "scales") != NULL;
    CHECK(mcbrot_scales(context, &count, joints) == MCBROT_OK, "scales");
    CHECK(scaled ? count >= 1 : count == 0, "%s: %u scaled joints", path, count);
    CHECK(mcbrot_decode_scale_frames(context, 0, (uint32_t)F, all) == MCBROT_OK, "%s: scale frames: %s", path,
          mcbrot_message(context));
    int moves = 0;
    for (size_t f = 0; f < F; ++f)
        for (size_t j = 0; j < J; ++j) {
            int listed = 0;
            for (uint32_t t = 0; t < count; ++t) listed |= joints[t] == j;
            for (int k = 0; k < 3; ++k) {
                double v = all[3 * (J * f + j) + k];
                CHECK(listed ? v > 0 : v == 1.0, "%s: joint %zu's scale %g at frame %zu", path, j, v, f);
                moves |= f > 0 && v != all[3 * (J * (f - 1) + j) + k];
            }
        }
    CHECK(!scaled || moves, "%s: no scale changes", path);
    for (size_t f = 0; f < F; f += 1 + F / 7) {
        for (int mode = 0; mode < 3; ++mode) {
            CHECK(mcbrot_sample_scales(context, (double)f / info->fps, mode, one) == MCBROT_OK, "sample scales");
            CHECK(memcmp(one, all + 3 * J * f, 24 * J) == 0, "%s: scales mode %d, frame %zu", path, mode, f);
        }
        if (f + 1 < F) {
            CHECK(mcbrot_sample_scales(context, (f + 0.5) / info->fps, MCBROT_LINEAR, one) == MCBROT_OK, "linear");
            for (size_t i = 0; i < 3 * J; ++i) {
                double a = all[3 * J * f + i], b = all[3 * J * (f + 1) + i];
                CHECK(one[i] >= fmin(a, b) - 1e-12 && one[i] <= fmax(a, b) + 1e-12, "%s: a linear scale outside", path);
            }
        }
    }
    CHECK(mcbrot_sample_scales(context, NAN, MCBROT_LINEAR, one) == MCBROT_E_TIME, "a NaN time for scales");
    CHECK(mcbrot_decode_scale_frames(context, (uint32_t)F, 1, one) == MCBROT_E_ARGUMENT, "scales past the end");
    free(joints);
    free(all);
    free(one);
}

/* A stream that names a prior: refused (MCBROT_E_PRIOR, a message naming the prior) without it, when sized or
 * opened; with another prior (a byte changed: the fingerprint differs); with the prior cut short; with a NULL prior. */
static void test_prior(const char *path, const unsigned char *data, size_t n, size_t size) {
    char message[256];
    size_t none;
    CHECK(mcbrot_context_size(data, n, &none, message, sizeof message) == MCBROT_E_PRIOR && strstr(message, "prior"),
          "%s: sized without its prior: %s", path, message);
    void *context = aligned_alloc(16, size);
    CHECK(mcbrot_open(context, size, data, n) == MCBROT_E_PRIOR && strstr(mcbrot_message(context), "none was given"),
          "%s: opened without its prior", path);
    unsigned char *other = malloc(prior_bytes);
    for (size_t at = 0; at < prior_bytes; at += 1 + at / 4) {
        memcpy(other, prior, prior_bytes);
        other[at] ^= 0x21;
        CHECK(mcbrot_open_with_prior(context, size, data, n, other, prior_bytes) == MCBROT_E_PRIOR &&
                  strstr(mcbrot_message(context), "coded against prior"),
              "%s: opened with another prior (byte %zu changed): %s", path, at, mcbrot_message(context));
    }
    for (size_t cut = 0; cut < prior_bytes; cut += 1 + cut / 8)
        CHECK(mcbrot_open_with_prior(context, size, data, n, prior, cut) == MCBROT_E_PRIOR,
              "%s: opened with its prior cut at %zu bytes", path, cut);
    CHECK(mcbrot_open_with_prior(context, size, data, n, NULL, 5) == MCBROT_E_PRIOR, "%s: a NULL prior", path);
    free(other);
    free(context);
}

static void test_stream(const char *path, const unsigned char *data, size_t n) {
    size_t size;
    int status;
    void *context = open_clip(data, n, &status, &size);
    int is_rot = n > 17 && data[9] == 7 && memcmp(data + 10, "mcb-rot", 7) == 0;
    size_t header = 9 + 1 + data[9] + 23;
    int format = is_rot && n > header ? data[header] : -1;
    if (!is_rot) {
        CHECK(status == MCBROT_E_NOT_MCBROT, "%s: another codec's stream gave status %d", path, status);
        printf("ok %s: another codec's stream refused\n", path);
        free(context);
        return;
    }
    if (format != MCBROT_PAYLOAD_FORMAT) {
        CHECK(status == MCBROT_E_FORMAT, "%s: format %d gave status %d", path, format, status);
        printf("ok %s: payload format %d refused\n", path, format);
        free(context);
        return;
    }
    CHECK(status == MCBROT_OK, "%s: status %d (%s)", path, status, context ? mcbrot_message(context) : "");
    if (!context) return;
    mcbrot_clip_info info;
    CHECK(mcbrot_info(context, &info) == MCBROT_OK, "info");
    size_t J = info.num_joints, F = info.num_frames;
    double *rotations = malloc(sizeof(double) * 4 * J * F), *roots = malloc(sizeof(double) * 3 * F);
    CHECK(mcbrot_decode_frames(context, 0, (uint32_t)F, rotations, roots) == MCBROT_OK, "%s: decode: %s", path,
          mcbrot_message(context));
    for (size_t i = 0; i < J * F; ++i) {
        double *q = rotations + 4 * i;
        double norm = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
        CHECK(fabs(norm - 1.0) < 1e-9, "%s: quaternion %zu has norm %g", path, i, norm);
        if (fabs(norm - 1.0) >= 1e-9) break;
    }
    /* sampling: nearest / floor / ceil at frame times give the frames; linear halfway lies between */
    double pose[4 * 256 + 3], root[3];
    for (size_t f = 0; f < F && J <= 256; f += 1 + F / 17) {
        double t = (double)f / info.fps;
        for (int mode = 0; mode < 3; ++mode) {
            CHECK(mcbrot_sample(context, t, mode, pose, root) == MCBROT_OK, "sample");
            CHECK(memcmp(pose, rotations + 4 * J * f, 32 * J) == 0 && memcmp(root, roots + 3 * f, 24) == 0,
                  "%s: sample mode %d at frame %zu differs from the frame", path, mode, f);
        }
        if (f + 1 < F) {
            CHECK(mcbrot_sample(context, (f + 0.5) / info.fps, MCBROT_LINEAR, pose, root) == MCBROT_OK, "linear");
            double low = fmin(roots[3 * f], roots[3 * f + 3]), high = fmax(roots[3 * f], roots[3 * f + 3]);
            CHECK(root[0] >= low - 1e-9 && root[0] <= high + 1e-9, "%s: linear root outside its frames", path);
        }
    }
    float f32[4 * 64 + 3];
    if (J <= 64) CHECK(mcbrot_sample_f32(context, 0.0, MCBROT_NEAREST, f32, f32 + 4 * J) == MCBROT_OK, "f32");
    test_poses(path, context, &info, rotations, roots);
    if (strstr(path, "still-root")) test_still_root(path, context, &info, rotations, roots);
    test_scales(path, context, &info);
    /* bad calls */
    CHECK(mcbrot_sample(context, NAN, MCBROT_NEAREST, pose, root) == MCBROT_E_TIME, "NaN time accepted");
    CHECK(mcbrot_sample(context, -1e-9, MCBROT_NEAREST, pose, root) == MCBROT_E_TIME, "negative time accepted");
    CHECK(mcbrot_sample(context, info.duration_s * 1.001 + 1e-6, MCBROT_FLOOR, pose, root) == MCBROT_E_TIME,
          "a time past the end accepted");
    CHECK(strlen(mcbrot_message(context)) > 10, "no message for a bad time");
    CHECK(mcbrot_decode_frames(context, (uint32_t)F, 1, pose, root) == MCBROT_E_ARGUMENT, "a frame past the end");
    void *small = aligned_alloc(16, size);
    CHECK(mcbrot_open_with_prior(small, size - 16, data, n, prior, prior_bytes) == MCBROT_E_CONTEXT_SMALL,
          "a small context accepted");
    CHECK(strstr(mcbrot_message(small), "needs") != NULL, "the message says what it needs");
    CHECK(mcbrot_sample(small, 0.0, MCBROT_NEAREST, pose, root) == MCBROT_E_NOT_OPEN, "a failed open samples");
    free(small);
    test_hostile(data, n);
    if (prior) test_prior(path, data, n, size);
    printf("ok %s: %zu frames, %zu joints, %u tracks, context %zu bytes (+ %zu stream)\n", path, F, J, info.num_tracks,
           info.context_bytes, n);
    free(rotations);
    free(roots);
    free(context);
}

int main(int argc, char **argv) {
    CHECK(mcbrot_abi_version() == MCBROT_ABI_VERSION, "ABI");
    for (int i = 1; i < argc; ++i) {
        size_t n;
        unsigned char *data = read_file(argv[i], &n);
        CHECK(data != NULL, "cannot read %s", argv[i]);
        char beside[4096];
        size_t length = strlen(argv[i]);
        unsigned char *model = NULL;
        if (length > 4 && length < sizeof beside && strcmp(argv[i] + length - 4, ".mcb") == 0) {
            memcpy(beside, argv[i], length - 4);
            memcpy(beside + length - 4, ".prior", 7);
            model = read_file(beside, &prior_bytes);
        }
        prior = model;
        if (data) test_stream(argv[i], data, n);
        free(data);
        free(model);
        prior = NULL;
        prior_bytes = 0;
    }
    printf("%d failure(s)\n", failures);
    return failures ? 1 : 0;
}
