/* Variants of the rANS unit's decoder, timed on the values of real units: where a value's nanoseconds go, and
 * what a unit of another layout would cost in bytes. A measurement tool: nothing here is part of the format.
 *
 * The input is the chunk units of mcb-rot streams as the Python decoder reads them (their classes and values,
 * written by runtime/tools/dump_units.py). Each variant re-encodes every unit in its own layout (the encoder here,
 * the format's 15-bit tables from src/mcbrot_tables.h), checks that its decoder gives the values back, and is timed
 * unit by unit: warm, REPEATS decodes per timing, the least of ROUNDS timings, the variants taking turns on each
 * unit, thread CPU time; ns per value over all units. Variants (S: interleaved 32-bit rANS states):
 *
 *   b<S>   byte renormalization to [2^23, 2^31), the sign and raw bits after the rANS data read with a branch on
 *          the zero token: b2 is format 6's unit (its bytes must equal the stream's: checked) and the runtime's
 *          `unit_next`, the state of the next value in front (the others move up after each value)
 *   b<S>u  the same, the loop unrolled by S (value i uses state i % S: the states never move)
 *   b<S>f  the sign and raw bits read without a branch from a 64-bit window, advanced by the nonzero test
 *   w<S>   states in [2^16, 2^32), 16-bit renormalization: at most one word a value, read without a branch
 *   w<S>f  both
 *   b<S>s, w<S>s  the sign in the alphabet: symbol 0 the zero token, 2t - 1 token t positive, 2t negative (a
 *          token's frequency split in two; a half of 0 made 1, taken from the row's most frequent symbol); raw
 *          bits only after an escape
 *   diagnoses (not decoders: their values differ): b2t the token alone (no sign nor raw bits), b2S the signed
 *          symbol alone
 *
 *   PYTHONPATH=. MOCAPBENCH_NATIVE=0 python runtime/tools/dump_units.py units.bin DIR/e1-0.5-*.mcb
 *   cc -O2 -DNDEBUG -std=c11 runtime/bench/bench_units.c -o bench_units
 *   ./bench_units ROUNDS units.bin
 *
 * Prints, per variant: ns per value, time against b2, bytes against b2 (whole units: size varint, rANS data,
 * bits). */
#define _POSIX_C_SOURCE 199309L
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../src/mcbrot_tables.h"

#define PRECISION 15
#define MAX_TOKEN (16 + 31 - 5)
#define PAD 16
#define REPEATS 8 /* decodes of a unit per timing (a thread clock read costs about a microsecond) */

#if defined(__GNUC__) || defined(__clang__)
#define ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define ALWAYS_INLINE inline
#endif

static double thread_seconds(void) {
    struct timespec now;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
    return (double)now.tv_sec + 1e-9 * (double)now.tv_nsec;
}

#define SYMBOLS (2 * MCBROT_TOKENS - 1)
static uint16_t sfreq[MCBROT_CLASSES][SYMBOLS], scum[MCBROT_CLASSES][SYMBOLS + 1];
static uint8_t slookup[MCBROT_CLASSES][256];
static uint32_t sentry[MCBROT_CLASSES][256];

/* The signed alphabet: symbol 0 the zero token, 2t - 1 token t positive, 2t token t negative; a token's frequency
 * split in two (the positive half rounded up; a half of 0 made 1, taken from the row's most frequent symbol). */
static void signed_tables(void) {
    for (int k = 0; k < MCBROT_CLASSES; ++k) {
        int32_t f[SYMBOLS];
        f[0] = mcbrot_freq[k][0];
        for (int t = 1; t < MCBROT_TOKENS; ++t) {
            f[2 * t - 1] = (mcbrot_freq[k][t] + 1) >> 1;
            f[2 * t] = mcbrot_freq[k][t] >> 1;
        }
        int top = 0;
        for (int q = 1; q < SYMBOLS; ++q) if (f[q] > f[top]) top = q;
        for (int q = 0; q < SYMBOLS; ++q) if (f[q] == 0) { f[q] = 1; --f[top]; }
        scum[k][0] = 0;
        for (int q = 0; q < SYMBOLS; ++q) { sfreq[k][q] = (uint16_t)f[q]; scum[k][q + 1] = (uint16_t)(scum[k][q] + f[q]); }
        for (int b = 0; b < 256; ++b) {
            int q = 0;
            while (scum[k][q + 1] <= (uint32_t)b << 7) ++q;
            slookup[k][b] = (uint8_t)q;
            sentry[k][b] = scum[k][q] | (uint32_t)sfreq[k][q] << 16;
        }
    }
}

static uint32_t token_of(int32_t v) {
    uint32_t a = v < 0 ? 0u - (uint32_t)v : (uint32_t)v;
    if (a < 16) return a;
    uint32_t width = 0;
    while (a >> width) ++width;
    return 16 + width - 5;
}

static size_t varint_bytes(size_t v) {
    size_t n = 1;
    while (v >= 128) v >>= 7, ++n;
    return n;
}

/* The signed alphabet's symbol of a value. */
static uint32_t symbol_of(int32_t v) {
    uint32_t t = token_of(v);
    return t == 0 ? 0 : 2 * t - (v > 0);
}

/* Encode with S states: the rANS data into `data` (returns its length), the bits into `bits` (their byte count in
 * *nbits). word: 0 byte renormalization (L = 2^23), 1 16-bit words (L = 2^16); sgn: the signed alphabet. */

static size_t encode(int S, int word, int sgn, const int32_t *v, const uint8_t *cls, uint32_t n, uint8_t *data, size_t cap,
                     uint8_t *bits, size_t *nbits) {
    size_t at = 0;
    memset(bits, 0, 4 * (size_t)n + PAD);
    for (uint32_t i = 0; i < n; ++i) {
        if (!v[i]) continue;
        uint32_t a = v[i] < 0 ? 0u - (uint32_t)v[i] : (uint32_t)v[i];
        if (!sgn) {
            if (v[i] < 0) bits[at >> 3] |= (uint8_t)(0x80 >> (at & 7));
            ++at;
        }
        if (a >= 16) {
            int width = 0;
            while (a >> (width + 1)) ++width;
            for (int b = width - 1; b >= 0; --b, ++at)
                if ((a >> b) & 1) bits[at >> 3] |= (uint8_t)(0x80 >> (at & 7));
        }
    }
    *nbits = (at + 7) >> 3;
    uint32_t low = word ? 1u << 16 : 1u << 23;
    uint32_t x[8];
    for (int s = 0; s < S; ++s) x[s] = low;
    size_t pos = cap;
    for (uint32_t i = n; i-- > 0;) {
        uint32_t t = sgn ? symbol_of(v[i]) : token_of(v[i]), k = cls[i];
        uint64_t f = sgn ? sfreq[k][t] : mcbrot_freq[k][t], st = x[i % S];
        if (word) {
            uint64_t limit = f << 17;
            while (st >= limit) {
                pos -= 2;
                data[pos] = (uint8_t)st;
                data[pos + 1] = (uint8_t)(st >> 8);
                st >>= 16;
            }
        } else {
            uint64_t limit = f << 16;
            while (st >= limit) {
                data[--pos] = (uint8_t)st;
                st >>= 8;
            }
        }
        x[i % S] = (uint32_t)(((st / f) << PRECISION) + st % f + (sgn ? scum[k][t] : mcbrot_cum[k][t]));
    }
    for (int s = S; s-- > 0;)
        for (int b = 3; b >= 0; --b) data[--pos] = (uint8_t)(x[s] >> (8 * b));
    size_t size = cap - pos;
    memmove(data, data + pos, size);
    return size;
}

static ALWAYS_INLINE uint32_t le32(const uint8_t *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static ALWAYS_INLINE uint64_t be64(const uint8_t *p) {
    uint64_t w;
    memcpy(&w, p, 8);
    return __builtin_bswap64(w);
}

/* The token of state x in class k's table (sgn: the signed alphabet's) and the state after it, before its
 * renormalization: the runtime's `unit_next` (the bucket's first token, its start and frequency in one load; a scan
 * only where the slot lies past that token). */
static ALWAYS_INLINE uint32_t advance(const int sgn, uint32_t k, uint32_t x, uint32_t *token_out) {
    uint32_t slot = x & ((1u << PRECISION) - 1), bucket = slot >> MCBROT_LOOKUP_SHIFT;
    uint32_t entry = sgn ? sentry[k][bucket] : mcbrot_entry[k][bucket];
    uint32_t token = sgn ? slookup[k][bucket] : mcbrot_lookup[k][bucket], start = entry & 0xffff, freq = entry >> 16;
    if (start + freq <= slot) {
        const uint16_t *cum = sgn ? scum[k] : mcbrot_cum[k];
        while (cum[token + 1] <= slot) ++token;
        start = cum[token];
        freq = sgn ? sfreq[k][token] : mcbrot_freq[k][token];
    }
    *token_out = token;
    return freq * (x >> PRECISION) + slot - start;
}

/* An escaped magnitude: its leading 1, then `width` raw bits (MSB first) from bit *bit on, one at a time. */
static ALWAYS_INLINE uint32_t raw_bits(const uint8_t *data, size_t *bit, uint32_t width) {
    uint32_t magnitude = 1;
    for (uint32_t j = 0; j < width; ++j, ++*bit) magnitude = magnitude << 1 | ((data[*bit >> 3] >> (7 - (*bit & 7))) & 1);
    return magnitude;
}

/* The value of a token, its sign and raw bits read with a branch on the zero token (the runtime's): 0, or 4 (the
 * bits end before the value's). */
static ALWAYS_INLINE int signed_value(uint32_t token, const uint8_t *data, size_t *bit, size_t bit_limit,
                                      int32_t *out) {
    if (token == 0) {
        *out = 0;
        return 0;
    }
    size_t b = *bit;
    if (b >= bit_limit) return 4;
    uint32_t negative = (data[b >> 3] >> (7 - (b & 7))) & 1;
    ++b;
    uint32_t magnitude = token;
    if (token >= 16) {
        uint32_t width = token - 16 + 4;
        if (bit_limit - b < width) return 4;
        magnitude = raw_bits(data, &b, width);
    }
    *bit = b;
    *out = (int32_t)((magnitude ^ (0u - negative)) + negative);
    return 0;
}

/* Decode `n` values (S states, layout `word`, sign read `free`); returns 0 or an error code. `data` holds the rANS
 * bytes then the bits, with PAD readable bytes after them. */
static ALWAYS_INLINE int decode(const int S, const int word, const int free, const uint8_t *data, size_t size,
                                size_t limit, const uint8_t *cls, uint32_t n, int32_t *out) {
    /* the states in scalars, not an array: an array of them is kept in memory (a store forwarded to a wider load) */
    uint32_t x0 = le32(data), x1 = le32(data + 4), x2 = S > 2 ? le32(data + 8) : 0, x3 = S > 2 ? le32(data + 12) : 0;
    uint32_t x4 = S > 4 ? le32(data + 16) : 0, x5 = S > 4 ? le32(data + 20) : 0, x6 = S > 4 ? le32(data + 24) : 0;
    uint32_t x7 = S > 4 ? le32(data + 28) : 0;
    size_t pos = 4 * (size_t)S, end = size, bit = end * 8, bit_limit = limit * 8;
    const uint32_t low = word ? 1u << 16 : 1u << 23;
    for (uint32_t i = 0; i < n; ++i) {
        uint32_t k = cls[i];
        uint32_t token, value = advance(free >= 3, k, x0, &token);
        if (word) {
            uint32_t lt = value < low, mask = 0u - lt;
            uint32_t w = (uint32_t)data[pos] | (uint32_t)data[pos + 1] << 8;
            value = value << (16 & mask) | (w & mask);
            pos += 2 * lt;
        } else {
            while (value < low) {
                if (pos >= end) return 1;
                value = value << 8 | data[pos++];
            }
        }
        x0 = x1;
        if (S == 2) {
            x1 = value;
        } else if (S == 4) {
            x1 = x2, x2 = x3, x3 = value;
        } else {
            x1 = x2, x2 = x3, x3 = x4, x4 = x5, x5 = x6, x6 = x7, x7 = value;
        }
        if (free == 4) { /* diagnosis only: the signed symbol, no conversion */
            out[i] = (int32_t)token;
            continue;
        }
        if (free == 3) { /* signed symbols: no sign bit; raw bits after an escape */
            uint32_t sym = token, negative = ~sym & 1; /* symbol 0: magnitude 0 either way */
            token = (sym + 1) >> 1;
            if (token > MAX_TOKEN) return 2;
            uint32_t magnitude = token;
            if (token >= 16) {
                uint32_t width = token - 16 + 4;
                if (bit_limit - bit < width) return 4;
                magnitude = raw_bits(data, &bit, width);
            }
            out[i] = (int32_t)((magnitude ^ (0u - negative)) + negative);
            continue;
        }
        if (token > MAX_TOKEN) return 2;
        if (free == 2) { /* diagnosis only: the token, no sign nor raw bits (values differ) */
            out[i] = (int32_t)token;
        } else if (free) {
            uint32_t nz = token != 0;
            uint64_t w = be64(data + (bit >> 3)) << (bit & 7);
            uint32_t negative = (uint32_t)(w >> 63) & nz;
            bit += nz;
            uint32_t magnitude = token;
            if (token >= 16) {
                uint32_t width = token - 16 + 4;
                magnitude = (1u << width) | (uint32_t)((w << 1) >> (64 - width));
                bit += width;
            }
            if (bit > bit_limit) return 4;
            out[i] = (int32_t)((magnitude ^ (0u - negative)) + negative);
        } else {
            int e = signed_value(token, data, &bit, bit_limit, out + i);
            if (e) return e;
        }
    }
    if (x0 != low || x1 != low || (S > 2 && (x2 != low || x3 != low)) ||
        (S > 4 && (x4 != low || x5 != low || x6 != low || x7 != low)))
        return 3;
    if (pos != end) return 3;
    return 0;
}

/* One value of state *x (byte renormalization, sign with a branch): the step of the unrolled decoders below. */
static ALWAYS_INLINE int step(uint32_t *x, uint32_t k, const uint8_t *data, size_t *pos, size_t end, size_t *bit,
                              size_t bit_limit, int32_t *out) {
    uint32_t token, value = advance(0, k, *x, &token);
    while (value < (1u << 23)) {
        if (*pos >= end) return 1;
        value = value << 8 | data[(*pos)++];
    }
    *x = value;
    if (token > MAX_TOKEN) return 2;
    return signed_value(token, data, bit, bit_limit, out);
}

/* S states, the loop unrolled by S (value i + s uses state s: no rotation of the states). */
static ALWAYS_INLINE int decode_unrolled(const int S, const uint8_t *data, size_t size, size_t limit,
                                         const uint8_t *cls, uint32_t n, int32_t *out) {
    uint32_t x0 = le32(data), x1 = le32(data + 4), x2 = S > 2 ? le32(data + 8) : 0, x3 = S > 2 ? le32(data + 12) : 0;
    size_t pos = 4 * (size_t)S, end = size, bit = end * 8, bit_limit = limit * 8;
    uint32_t i = 0;
    int e = 0;
    for (; i + S <= n; i += S) {
        e |= step(&x0, cls[i], data, &pos, end, &bit, bit_limit, out + i);
        e |= step(&x1, cls[i + 1], data, &pos, end, &bit, bit_limit, out + i + 1);
        if (S > 2) {
            e |= step(&x2, cls[i + 2], data, &pos, end, &bit, bit_limit, out + i + 2);
            e |= step(&x3, cls[i + 3], data, &pos, end, &bit, bit_limit, out + i + 3);
        }
        if (e) return e;
    }
    if (i < n) e |= step(&x0, cls[i], data, &pos, end, &bit, bit_limit, out + i), ++i;
    if (i < n) e |= step(&x1, cls[i], data, &pos, end, &bit, bit_limit, out + i), ++i;
    if (S > 2 && i < n) e |= step(&x2, cls[i], data, &pos, end, &bit, bit_limit, out + i), ++i;
    if (e) return e;
    uint32_t low = 1u << 23;
    if (x0 != low || x1 != low || (S > 2 && (x2 != low || x3 != low)) || pos != end) return 3;
    return 0;
}

/* (S, word renormalization, sign mode: 0 branch, 1 window, 2 token alone, 3 signed alphabet, 4 signed symbol alone,
 * 9 unrolled) */
#define VARIANTS(X)                                                                                                \
    X(2, 0, 0) X(4, 0, 0) X(8, 0, 0) X(2, 0, 9) X(4, 0, 9) X(2, 0, 1) X(4, 0, 1) X(2, 1, 0) X(4, 1, 0) X(2, 1, 1)   \
    X(2, 0, 3) X(2, 1, 3) X(2, 0, 2) X(2, 0, 4)

#define DEFINE(S, W, F) \
    static int decode_##S##_##W##_##F(const uint8_t *d, size_t size, size_t limit, const uint8_t *c, uint32_t n, \
                                      int32_t *o) { \
        return F == 9 ? decode_unrolled(S, d, size, limit, c, n, o) : decode(S, W, F, d, size, limit, c, n, o); }
VARIANTS(DEFINE)

typedef int (*decoder_t)(const uint8_t *, size_t, size_t, const uint8_t *, uint32_t, int32_t *);
#define ENTRY(S, W, F) {S, W, F, decode_##S##_##W##_##F},
static const struct { int S, word, free; decoder_t fn; } variants[] = {VARIANTS(ENTRY)};
#define NV (sizeof variants / sizeof variants[0])

typedef struct {
    uint32_t n, python_bytes;
    uint8_t *cls;
    int32_t *val;
    uint8_t *enc[NV];      /* rANS data then bits then PAD */
    size_t size[NV], bytes[NV];
} unit_rec;

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s ROUNDS units.bin\n", argv[0]);
        return 2;
    }
    int rounds = atoi(argv[1]);
    signed_tables();
    FILE *f = fopen(argv[2], "rb");
    if (!f) { fprintf(stderr, "%s: cannot open\n", argv[2]); return 1; }
    size_t cap = 1024, count = 0;
    unit_rec *u = malloc(cap * sizeof *u);
    uint32_t head[2];
    while (fread(head, 4, 2, f) == 2) {
        if (count == cap) u = realloc(u, (cap *= 2) * sizeof *u);
        unit_rec *r = &u[count++];
        memset(r, 0, sizeof *r);
        r->n = head[0];
        r->python_bytes = head[1];
        r->cls = malloc(r->n + 1);
        r->val = malloc(4 * (size_t)r->n + 4);
        if (fread(r->cls, 1, r->n, f) != r->n || fread(r->val, 4, r->n, f) != r->n) { fprintf(stderr, "short\n"); return 1; }
    }
    fclose(f);
    uint64_t values = 0, python = 0, mismatch = 0;
    int32_t *out = malloc(4 * 70000);
    for (size_t i = 0; i < count; ++i) {
        unit_rec *r = &u[i];
        values += r->n;
        python += r->python_bytes;
        size_t room = 8 * (size_t)r->n + 64;
        uint8_t *data = malloc(room), *bits = malloc(4 * (size_t)r->n + PAD);
        for (size_t v = 0; v < NV; ++v) {
            size_t nbits;
            size_t size = r->n ? encode(variants[v].S, variants[v].word, variants[v].free >= 3 && variants[v].free < 9, r->val, r->cls, r->n, data, room, bits, &nbits) : 0;
            if (!r->n) nbits = 0;
            r->enc[v] = calloc(size + nbits + PAD, 1);
            memcpy(r->enc[v], data, size);
            memcpy(r->enc[v] + size, bits, nbits);
            r->size[v] = size;
            r->bytes[v] = varint_bytes(size) + size + nbits;
            if (r->n) {
                int e = variants[v].fn(r->enc[v], size, size + nbits, r->cls, r->n, out);
                if (e || ((variants[v].free < 2 || variants[v].free == 3 || variants[v].free == 9) && memcmp(out, r->val, 4 * (size_t)r->n))) {
                    fprintf(stderr, "variant %zu unit %zu: error %d or other values\n", v, i, e);
                    return 1;
                }
            }
        }
        if (r->bytes[0] != r->python_bytes) ++mismatch;
        free(data);
        free(bits);
    }
    double best[NV] = {0};
    for (size_t i = 0; i < count; ++i) {
        unit_rec *r = &u[i];
        if (!r->n) continue;
        double least[NV];
        for (size_t v = 0; v < NV; ++v) least[v] = 1e30;
        for (int round = 0; round < rounds; ++round)
            for (size_t v = 0; v < NV; ++v) {
                size_t limit = r->bytes[v] - varint_bytes(r->size[v]);
                int e = 0;
                double t0 = thread_seconds();
                for (int rep = 0; rep < REPEATS; ++rep)
                    e |= variants[v].fn(r->enc[v], r->size[v], limit, r->cls, r->n, out);
                double t1 = (thread_seconds() - t0) / REPEATS;
                if (e) return 1;
                if (t1 < least[v]) least[v] = t1;
            }
        for (size_t v = 0; v < NV; ++v) best[v] += least[v];
    }
    uint64_t b0 = 0;
    for (size_t i = 0; i < count; ++i) b0 += u[i].bytes[0];
    printf("%zu units, %llu values (%.0f a unit), b2 bytes %llu = python's %llu (%llu units differ)\n", count,
           (unsigned long long)values, (double)values / (double)count, (unsigned long long)b0,
           (unsigned long long)python, (unsigned long long)mismatch);
    for (size_t v = 0; v < NV; ++v) {
        uint64_t bytes = 0;
        for (size_t i = 0; i < count; ++i) bytes += u[i].bytes[v];
        printf("%c%d%s  %6.3f ns/value  %.3fx  bytes %+lld (%+.2f%%)\n", variants[v].word ? 'w' : 'b', variants[v].S,
               variants[v].free == 9 ? "u" : variants[v].free == 4 ? "S" : variants[v].free == 3 ? "s" : variants[v].free == 2 ? "t" : variants[v].free ? "f" : " ", 1e9 * best[v] / (double)values, best[v] / best[0],
               (long long)bytes - (long long)b0, 100.0 * ((double)bytes - (double)b0) / (double)b0);
    }
    return 0;
}
