/* The runtime alone, for comparing two builds of it on one machine: µs per pose of forward playback and of random
 * access (mcbrot_sample, nearest frame, warm caches, thread CPU time; every forward round before the random ones),
 * each the least over ROUNDS rounds (the figure least disturbed by other processes on a busy machine), then the
 * median over the streams; and a hash of every stream's decoded frames, so that two builds are seen to give the same
 * bits.
 *
 *   cc -O2 -DNDEBUG -msse4.1 -std=c11 -Iruntime/include runtime/bench/bench_decode.c runtime/src/mcbrot.c -lm
 *   ./a.out ROUNDS stream.mcb...
 *
 * Prints: forward_us random_us hash (one line). Two builds: compile each from its own src/ (the tables header
 * beside its mcbrot.c) and run them one after the other, or alternately, on the same streams. */
#define _POSIX_C_SOURCE 199309L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mcbrot.h"

static double thread_seconds(void) {
    struct timespec now;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
    return (double)now.tv_sec + 1e-9 * (double)now.tv_nsec;
}

static int by_value(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static uint64_t fnv(uint64_t h, const void *data, size_t n) {
    const uint8_t *p = data;
    for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
    return h;
}

/* Every allocation of this tool is checked: a failure (or a clip too large to hold) is one line and exit 1. */
static void *allocated(void *pointer, const char *what, const char *path) {
    if (!pointer) {
        fprintf(stderr, "%s: cannot allocate %s\n", path, what);
        exit(1);
    }
    return pointer;
}

int main(int argc, char **argv) {
    int rounds = argc >= 3 ? atoi(argv[1]) : 0, streams = argc - 2;
    if (argc < 3 || rounds < 1) {
        fprintf(stderr, "usage: %s ROUNDS stream.mcb... (ROUNDS >= 1)\n", argv[0]);
        return 2;
    }
    double *forward = allocated(calloc((size_t)streams, sizeof(double)), "the timings", argv[0]);
    double *random = allocated(calloc((size_t)streams, sizeof(double)), "the timings", argv[0]);
    uint64_t hash = 1469598103934665603ull;
    for (int a = 0; a < streams; ++a) {
        FILE *file = fopen(argv[a + 2], "rb");
        if (!file) { fprintf(stderr, "%s: cannot open\n", argv[a + 2]); return 1; }
        long bytes = fseek(file, 0, SEEK_END) == 0 ? ftell(file) : -1;
        if (bytes <= 0 || bytes > (1L << 30) || fseek(file, 0, SEEK_SET) != 0) { fprintf(stderr, "%s: empty, over 1 GiB or not a regular file\n", argv[a + 2]); return 1; }
        uint8_t *stream = allocated(malloc((size_t)bytes), "the stream", argv[a + 2]);
        if (fread(stream, 1, (size_t)bytes, file) != (size_t)bytes) { fprintf(stderr, "%s: short read\n", argv[a + 2]); return 1; }
        fclose(file);
        size_t size;
        char message[256];
        if (mcbrot_context_size(stream, (size_t)bytes, &size, message, sizeof message)) { fprintf(stderr, "%s\n", message); return 1; }
        void *context = allocated(aligned_alloc(MCBROT_CONTEXT_ALIGN, (size + 63) & ~(size_t)63), "the context", argv[a + 2]);
        if (mcbrot_open(context, size, stream, (size_t)bytes)) { fprintf(stderr, "%s\n", mcbrot_message(context)); return 1; }
        mcbrot_clip_info info;
        mcbrot_info(context, &info);
        uint32_t frames = info.num_frames, joints = info.num_joints;
        if (frames == 0) { fprintf(stderr, "%s: a clip of no frames\n", argv[a + 2]); return 1; }
        double *rotations = allocated(malloc(sizeof(double) * 4 * joints * frames), "the decoded frames", argv[a + 2]);
        double *roots = allocated(malloc(sizeof(double) * 3 * frames), "the decoded frames", argv[a + 2]);
        if (mcbrot_decode_frames(context, 0, frames, rotations, roots)) { fprintf(stderr, "%s\n", mcbrot_message(context)); return 1; }
        hash = fnv(fnv(hash, rotations, sizeof(double) * 4 * joints * frames), roots, sizeof(double) * 3 * frames);
        forward[a] = random[a] = 1e30;
        /* every forward round, then every random round: a forward pass timed right after a random one would
         * meet a branch predictor trained by random access's decodes of the same chunks */
        for (int r = 0; r < rounds; ++r) {
            double start = thread_seconds();
            for (uint32_t f = 0; f < frames; ++f) mcbrot_sample(context, f / info.fps, MCBROT_NEAREST, rotations, roots);
            double end = thread_seconds();
            if (end - start < forward[a]) forward[a] = end - start;
        }
        for (int r = 0; r < rounds; ++r) {
            double start = thread_seconds();
            uint64_t state = 0x9e3779b97f4a7c15ull;
            for (uint32_t i = 0; i < frames; ++i) {
                state = state * 6364136223846793005ull + 1442695040888963407ull;
                mcbrot_sample(context, (uint32_t)((state >> 33) % frames) / info.fps, MCBROT_NEAREST, rotations, roots);
            }
            double end = thread_seconds();
            if (end - start < random[a]) random[a] = end - start;
        }
        forward[a] *= 1e6 / frames;
        random[a] *= 1e6 / frames;
        free(rotations);
        free(roots);
        free(context);
        free(stream);
    }
    qsort(forward, (size_t)streams, sizeof(double), by_value);
    qsort(random, (size_t)streams, sizeof(double), by_value);
    printf("%.3f %.3f %016llx\n", forward[streams / 2], random[streams / 2], (unsigned long long)hash);
    return 0;
}
