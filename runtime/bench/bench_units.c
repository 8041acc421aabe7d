/* Variants of the rANS unit's decoder, timed on the values of real units: where a value's nanoseconds go, and
 * what a unit of another layout would cost in bytes. A measurement tool: nothing here is part of the format.
 *
 * The input is the chunk units of mcb-rot streams as the Python decoder reads them (their classes and values,
 * written by runtime/tools/dump_units.py). Each variant re-encodes every unit in its own layout (the encoder here,
 * the format's 15-bit tables from src/mcbrot_tables.h), checks that its decoder gives the values back, and is timed
 * (warm caches, thread CPU time, the variants taking turns; ns per value over all units) three ways, which differ
 * in what the branch predictor has learnt:
 *   repeated  each unit alone, REPEATS decodes per timing, the least of ROUNDS timings: the predictor learns the
 *             unit's branches from its repeats (the figures of this tool before the other two modes existed);
 *   random    as the harness's random access meets the units: per clip, 80 draws per unit of one at random, decoded
 *             unless it is the previous draw's (the runtime keeps its last chunk), the least of ROUNDS runs;
 *   once      every unit decoded once a pass, the least of ROUNDS passes: nothing to learn from (a unit decoded
 *             once, as forward playback decodes each chunk and a game sampling many clips meets them).
 * Variants (S: interleaved 32-bit rANS states):
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
 *   v<S>, v<S>s  S = 8 or 16 lanes, every bit in the lanes (the section "Lanes" below has the layout), tokens
 *          alphabet (sign and raw bits as uniform symbols) or signed alphabet (raw bits only); the scalar decoder
 *          (the reference); v<S>x, v<S>sx: the AVX2 decoder of the same units (groups of 8 lanes in a register; the
 *          scalar decoder where the CPU lacks AVX2)
 *   diagnoses (not decoders: their values differ): b2t the token alone (no sign nor raw bits), b2S the signed
 *          symbol alone
 *
 *   PYTHONPATH=. MOCAPBENCH_NATIVE=0 python runtime/tools/dump_units.py units.bin DIR/e1-0.5-*.mcb
 *   cc -O2 -DNDEBUG -std=c11 runtime/bench/bench_units.c -o bench_units
 *   ./bench_units ROUNDS units.bin [VARIANT,...]     (b2 and the variants named; all without a list)
 *
 * Prints, per variant: ns per value and time against b2 in each mode, bytes against b2 (whole units: size varint,
 * rANS data, bits). The AVX2 functions carry their own target attribute: the build line needs no -mavx2, and the
 * scalar variants are compiled as before. */
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

/* ---- Lanes: S = 8 or 16 interleaved states, each value's token, sign and raw bits decoded in its lane ----
 *
 * Value i uses lane i % S; the values of a group (S consecutive values, the last group possibly shorter) are decoded
 * in three phases, each over the group's lanes in ascending order:
 *   1. the token (or the signed alphabet's symbol) from the class's table (15 bits: the format's tables);
 *   2. the top b1 = min(B, 16) bits of the value's bit string, as a uniform symbol (x & (2^b1 - 1), x >> b1);
 *   3. its last b2 = B - b1 bits likewise (only magnitudes of 2^16 and more: none in the units measured);
 * where the bit string is the sign then the raw bits of an escaped magnitude (tokens alphabet: B = [v != 0] + w), or
 * the raw bits alone (signed alphabet: B = w), w = token - 12 raw bits for a token >= 16, else 0. States lie in
 * [2^16, 2^32) between symbols; after each symbol a lane whose state fell below 2^16 reads one 16-bit word (never
 * more: a symbol takes at most 16 bits from a state of at least 2^16), the lanes that read taking consecutive words
 * in lane order. A phase whose symbol has no bits (b = 0) leaves the state as it is, so it reads nothing.
 * The data: the S initial states (u32 little-endian), then the words (u16 little-endian) in reading order; the
 * decoder ends with every state at 2^16 and every word read. No separate bit stream: sign and raw bits cost the same
 * bits as in format 6's bit stream, the flush is S states of 4 bytes (format 6: 2). */
#define LANE_LOW (1u << 16)
#define MAX_LANES 16

/* The AVX2 decoders' tables, per alphabet (0 tokens, 1 signed), class and bucket of 2^7 slots (as the format's
 * lookup): the bucket's first symbol's start and end (start | end << 16), and what follows from that symbol (its
 * token | bit count << 8 | raw bit count w << 16 | negative << 24 | symbol << 25), so that the bits need no arithmetic
 * on the token.
 * 2 x 128 kB for each alphabet, of which a stream touches its classes' rows (1 kB each). */
static uint32_t lane_bounds[2][MCBROT_CLASSES][256], lane_info[2][MCBROT_CLASSES][256];

static uint32_t symbol_info(int sgn, uint32_t symbol) {
    uint32_t t = sgn ? (symbol + 1) >> 1 : symbol, w = t >= 16 ? t - 12 : 0;
    return t | (w + (!sgn && t != 0)) << 8 | w << 16 | (uint32_t)(sgn && t != 0 && !(symbol & 1)) << 24 | symbol << 25;
}

static void lane_tables(void) {
    for (int sgn = 0; sgn < 2; ++sgn)
        for (int k = 0; k < MCBROT_CLASSES; ++k)
            for (int b = 0; b < 256; ++b) {
                uint32_t q = sgn ? slookup[k][b] : mcbrot_lookup[k][b];
                uint32_t start = sgn ? scum[k][q] : mcbrot_cum[k][q], end = sgn ? scum[k][q + 1] : mcbrot_cum[k][q + 1];
                lane_bounds[sgn][k][b] = start | end << 16;
                lane_info[sgn][k][b] = symbol_info(sgn, q);
            }
}

/* A value's token (tokens alphabet) or symbol (signed alphabet), its bit count B and its bit string. */
static void lane_split(int sgn, int32_t v, uint32_t *symbol, uint32_t *count, uint32_t *string) {
    uint32_t t = token_of(v), a = v < 0 ? 0u - (uint32_t)v : (uint32_t)v, w = t >= 16 ? t - 12 : 0;
    uint32_t raw = w ? a & ((1u << w) - 1) : 0;
    *symbol = sgn ? symbol_of(v) : t;
    *count = w + (!sgn && v != 0);
    *string = (!sgn && v < 0 ? 1u << w : 0) | raw;
}

/* Encode one symbol (frequency f, start c, in 2^-P units; a uniform b-bit symbol r is f = 1, c = r, P = b) into
 * state *x, writing its renormalization word (at most one) backwards at *pos. */
static void lane_put(uint32_t *x, uint32_t f, uint32_t c, uint32_t P, uint8_t *data, size_t *pos) {
    uint64_t st = *x;
    if (st >= (uint64_t)f << (32 - P)) {
        *pos -= 2;
        data[*pos] = (uint8_t)st;
        data[*pos + 1] = (uint8_t)(st >> 8);
        st >>= 16;
    }
    *x = (uint32_t)(((st / f) << P) + st % f + c);
}

/* The encoder: the decoder's operations in reverse (groups, phases and lanes backwards). Returns the data's size. */
static size_t encode_lanes(int S, int sgn, const int32_t *v, const uint8_t *cls, uint32_t n, uint8_t *data, size_t cap) {
    uint32_t x[MAX_LANES];
    for (int s = 0; s < S; ++s) x[s] = LANE_LOW;
    size_t pos = cap;
    for (uint32_t g = (n - 1) / (uint32_t)S * (uint32_t)S;; g -= (uint32_t)S) {
        uint32_t m = n - g < (uint32_t)S ? n - g : (uint32_t)S, sym[MAX_LANES], count[MAX_LANES], str[MAX_LANES];
        for (uint32_t j = 0; j < m; ++j) lane_split(sgn, v[g + j], &sym[j], &count[j], &str[j]);
        for (uint32_t j = m; j-- > 0;) { /* phase 3 */
            uint32_t b1 = count[j] < 16 ? count[j] : 16, b2 = count[j] - b1;
            lane_put(&x[j], 1, str[j] & ((1u << b2) - 1), b2, data, &pos);
        }
        for (uint32_t j = m; j-- > 0;) { /* phase 2 */
            uint32_t b1 = count[j] < 16 ? count[j] : 16, b2 = count[j] - b1;
            lane_put(&x[j], 1, str[j] >> b2, b1, data, &pos);
        }
        for (uint32_t j = m; j-- > 0;) { /* phase 1 */
            uint32_t k = cls[g + j];
            lane_put(&x[j], sgn ? sfreq[k][sym[j]] : mcbrot_freq[k][sym[j]], sgn ? scum[k][sym[j]] : mcbrot_cum[k][sym[j]],
                     PRECISION, data, &pos);
        }
        if (g == 0) break;
    }
    for (int s = S; s-- > 0;)
        for (int b = 3; b >= 0; --b) data[--pos] = (uint8_t)(x[s] >> (8 * b));
    size_t size = cap - pos;
    memmove(data, data + pos, size);
    return size;
}

/* A lane's renormalization (scalar): one word where the state fell below 2^16. 0, or 1 if the data ends. */
static ALWAYS_INLINE int lane_read(uint32_t *x, const uint8_t *data, size_t size, size_t *pos) {
    if (*x >= LANE_LOW) return 0;
    if (*pos + 2 > size) return 1;
    *x = *x << 16 | (uint32_t)data[*pos] | (uint32_t)data[*pos + 1] << 8;
    *pos += 2;
    return 0;
}

/* One group of m <= S values (scalar): the reference decoder of the layout, and the AVX2 decoders' last group. */
static ALWAYS_INLINE int lane_group(const int sgn, uint32_t *x, uint32_t m, const uint8_t *data, size_t size,
                                    size_t *pos, const uint8_t *cls, int32_t *out) {
    uint32_t token[MAX_LANES], negative[MAX_LANES], count[MAX_LANES], str[MAX_LANES];
    int e = 0;
    for (uint32_t j = 0; j < m; ++j) {
        uint32_t t;
        x[j] = advance(sgn, cls[j], x[j], &t);
        e |= lane_read(&x[j], data, size, pos);
        negative[j] = sgn ? ~t & 1 : 0;
        if (sgn) t = (t + 1) >> 1;
        if (t > MAX_TOKEN) return 2;
        token[j] = t;
        count[j] = (t >= 16 ? t - 12 : 0) + (!sgn && t != 0);
    }
    for (uint32_t j = 0; j < m; ++j) {
        uint32_t b1 = count[j] < 16 ? count[j] : 16;
        str[j] = x[j] & ((1u << b1) - 1);
        x[j] >>= b1;
        e |= lane_read(&x[j], data, size, pos);
    }
    for (uint32_t j = 0; j < m; ++j) {
        uint32_t b2 = count[j] < 16 ? 0 : count[j] - 16;
        str[j] = str[j] << b2 | (x[j] & ((1u << b2) - 1));
        x[j] >>= b2;
        e |= lane_read(&x[j], data, size, pos);
    }
    for (uint32_t j = 0; j < m; ++j) {
        uint32_t t = token[j], w = t >= 16 ? t - 12 : 0;
        uint32_t neg = sgn ? negative[j] & (t != 0) : (t != 0) & (str[j] >> w);
        uint32_t magnitude = w ? (1u << w) | (str[j] & ((1u << w) - 1)) : t;
        out[j] = (int32_t)((magnitude ^ (0u - neg)) + neg);
    }
    return e;
}

static ALWAYS_INLINE int lane_finish(int S, const uint32_t *x, size_t pos, size_t size) {
    for (int s = 0; s < S; ++s)
        if (x[s] != LANE_LOW) return 3;
    return pos == size ? 0 : 3;
}

static ALWAYS_INLINE int decode_lanes(const int S, const int sgn, const uint8_t *data, size_t size, const uint8_t *cls,
                                      uint32_t n, int32_t *out) {
    uint32_t x[MAX_LANES];
    if (size < 4 * (size_t)S) return 1;
    for (int s = 0; s < S; ++s) x[s] = le32(data + 4 * s);
    size_t pos = 4 * (size_t)S;
    for (uint32_t g = 0; g < n; g += (uint32_t)S) {
        int e = lane_group(sgn, x, n - g < (uint32_t)S ? n - g : (uint32_t)S, data, size, &pos, cls + g, out + g);
        if (e) return e;
    }
    return lane_finish(S, x, pos, size);
}

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define HAVE_AVX2_LANES 1
#define AVX2 __attribute__((target("avx2,popcnt"), always_inline)) inline

/* For each mask of the lanes that read a word: the index of each reading lane's word among the words read. */
static uint8_t lane_perm[256][8];

static void lane_perm_table(void) {
    for (int mask = 0; mask < 256; ++mask)
        for (int j = 0, c = 0; j < 8; ++j) lane_perm[mask][j] = (uint8_t)((mask >> j) & 1 ? c++ : 0);
}

/* The 8 lanes' renormalization: the lanes below 2^16 take the next words in lane order (a movemask-indexed
 * permutation of the 8 words at *pos: up to 16 bytes read, so the data is padded). */
static AVX2 __m256i avx2_renorm(__m256i x, const uint8_t *data, size_t *pos) {
    __m256i need = _mm256_cmpeq_epi32(_mm256_srli_epi32(x, 16), _mm256_setzero_si256());
    unsigned mask = (unsigned)_mm256_movemask_ps(_mm256_castsi256_ps(need));
    __m256i words = _mm256_cvtepu16_epi32(_mm_loadu_si128((const __m128i *)(data + *pos)));
    __m256i perm = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)lane_perm[mask]));
    __m256i fed = _mm256_or_si256(_mm256_slli_epi32(x, 16), _mm256_permutevar8x32_epi32(words, perm));
    *pos += 2 * (size_t)__builtin_popcount(mask);
    return _mm256_blendv_epi8(x, fed, need);
}

/* Phase 1 of 8 lanes before their renormalization: the symbol of each lane's slot (the bucket's first symbol's
 * bounds and information, eight scalar loads each: two vpgatherdd were 8-10 % slower here, a gather's latency being
 * most of a group's; lanes whose slot lies past that symbol step on through the cumulative table, two 16-bit bounds
 * a vpgatherdd, a few groups in a hundred, their information computed) and the state after it. */
static AVX2 __m256i avx2_symbol(const int sgn, __m256i x, const uint8_t *cls, __m256i *info) {
    const __m256i low15 = _mm256_set1_epi32((1 << PRECISION) - 1), low16 = _mm256_set1_epi32(0xffff);
    __m256i k = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)cls));
    __m256i slot = _mm256_and_si256(x, low15);
    __m256i idx = _mm256_add_epi32(_mm256_slli_epi32(k, 8), _mm256_srli_epi32(slot, MCBROT_LOOKUP_SHIFT));
    uint32_t at[8];
    _mm256_storeu_si256((__m256i *)at, idx);
    const uint32_t *bt = &lane_bounds[sgn][0][0], *it = &lane_info[sgn][0][0];
    __m256i bounds = _mm256_setr_epi32((int)bt[at[0]], (int)bt[at[1]], (int)bt[at[2]], (int)bt[at[3]], (int)bt[at[4]],
                                       (int)bt[at[5]], (int)bt[at[6]], (int)bt[at[7]]);
    *info = _mm256_setr_epi32((int)it[at[0]], (int)it[at[1]], (int)it[at[2]], (int)it[at[3]], (int)it[at[4]],
                              (int)it[at[5]], (int)it[at[6]], (int)it[at[7]]);
    __m256i start = _mm256_and_si256(bounds, low16), end = _mm256_srli_epi32(bounds, 16);
    __m256i within = _mm256_cmpgt_epi32(end, slot);
    if (__builtin_expect(_mm256_movemask_ps(_mm256_castsi256_ps(within)) != 0xff, 0)) {
        const int row = sgn ? SYMBOLS + 1 : MCBROT_TOKENS + 1;
        const __m256i base = _mm256_mullo_epi32(k, _mm256_set1_epi32(row)), one = _mm256_set1_epi32(1);
        __m256i sym = _mm256_srli_epi32(*info, 25), twelve = _mm256_set1_epi32(12);
        do {
            sym = _mm256_add_epi32(sym, _mm256_andnot_si256(within, one));
            __m256i pair = _mm256_i32gather_epi32((const int *)(sgn ? &scum[0][0] : &mcbrot_cum[0][0]),
                                                  _mm256_add_epi32(base, sym), 2);
            start = _mm256_and_si256(pair, low16);
            end = _mm256_srli_epi32(pair, 16);
            within = _mm256_cmpgt_epi32(end, slot);
        } while (_mm256_movemask_ps(_mm256_castsi256_ps(within)) != 0xff);
        __m256i t = sgn ? _mm256_srli_epi32(_mm256_add_epi32(sym, one), 1) : sym;
        __m256i w = _mm256_and_si256(_mm256_cmpgt_epi32(t, _mm256_set1_epi32(15)), _mm256_sub_epi32(t, twelve));
        __m256i nz = _mm256_min_epu32(t, one);
        __m256i count = sgn ? w : _mm256_add_epi32(w, nz);
        __m256i negative = sgn ? _mm256_andnot_si256(sym, nz) : _mm256_setzero_si256();
        *info = _mm256_or_si256(_mm256_or_si256(_mm256_or_si256(t, _mm256_slli_epi32(count, 8)), _mm256_slli_epi32(sym, 25)),
                                _mm256_or_si256(_mm256_slli_epi32(w, 16), _mm256_slli_epi32(negative, 24)));
    }
    __m256i freq = _mm256_sub_epi32(end, start);
    return _mm256_add_epi32(_mm256_mullo_epi32(freq, _mm256_srli_epi32(x, PRECISION)), _mm256_sub_epi32(slot, start));
}

/* A uniform symbol of b (<= 16) bits per lane: its bits, and the state after it (before its renormalization). */
static AVX2 __m256i avx2_bits(__m256i x, __m256i b, __m256i *bits) {
    __m256i mask = _mm256_sub_epi32(_mm256_sllv_epi32(_mm256_set1_epi32(1), b), _mm256_set1_epi32(1));
    *bits = _mm256_and_si256(x, mask);
    return _mm256_srlv_epi32(x, b);
}

/* The values from the symbols' information and bit strings (the sign heads the string of a nonzero token in the
 * tokens alphabet: the string has w + 1 bits). */
static AVX2 __m256i avx2_values(const int sgn, __m256i info, __m256i str) {
    const __m256i one = _mm256_set1_epi32(1);
    __m256i t = _mm256_and_si256(info, _mm256_set1_epi32(0xff)), w = _mm256_srli_epi32(_mm256_slli_epi32(info, 8), 24);
    __m256i top = _mm256_sllv_epi32(one, w);
    __m256i magnitude = _mm256_blendv_epi8(t, _mm256_or_si256(top, _mm256_and_si256(str, _mm256_sub_epi32(top, one))),
                                           _mm256_cmpgt_epi32(w, _mm256_setzero_si256()));
    __m256i negative = sgn ? _mm256_and_si256(_mm256_srli_epi32(info, 24), one) : _mm256_srlv_epi32(str, w);
    return _mm256_add_epi32(_mm256_xor_si256(magnitude, _mm256_sub_epi32(_mm256_setzero_si256(), negative)), negative);
}

/* R registers of 8 lanes (S = 8R); groups of S values in AVX2, the last short group by lane_group. */
static AVX2 int decode_lanes_avx2(const int R, const int sgn, const uint8_t *data, size_t size, const uint8_t *cls,
                                  uint32_t n, int32_t *out) {
    const uint32_t S = 8 * (uint32_t)R;
    if (size < 4 * (size_t)S) return 1;
    __m256i x[2], info[2], count[2], r1[2], r2[2], bad = _mm256_setzero_si256();
    for (int r = 0; r < R; ++r) x[r] = _mm256_loadu_si256((const __m256i *)(data + 32 * r));
    size_t pos = 4 * (size_t)S;
    const __m256i sixteen = _mm256_set1_epi32(16), low8 = _mm256_set1_epi32(0xff);
    uint32_t g = 0;
    for (; g + S <= n; g += S) {
        for (int r = 0; r < R; ++r) x[r] = avx2_symbol(sgn, x[r], cls + g + 8 * r, &info[r]);
        for (int r = 0; r < R; ++r) x[r] = avx2_renorm(x[r], data, &pos);
        __m256i some = _mm256_setzero_si256();
        for (int r = 0; r < R; ++r) {
            bad = _mm256_max_epu8(bad, info[r]);
            count[r] = _mm256_and_si256(_mm256_srli_epi32(info[r], 8), low8);
            some = _mm256_or_si256(some, count[r]);
            r1[r] = _mm256_setzero_si256();
        }
        /* the signed alphabet: most groups have no raw bits (a branch); the tokens': nearly every group has signs */
        if (!sgn || !_mm256_testz_si256(some, some)) {
            for (int r = 0; r < R; ++r) x[r] = avx2_bits(x[r], _mm256_min_epu32(count[r], sixteen), &r1[r]);
            for (int r = 0; r < R; ++r) x[r] = avx2_renorm(x[r], data, &pos);
        }
        __m256i more = _mm256_cmpgt_epi32(count[0], sixteen);
        if (R > 1) more = _mm256_or_si256(more, _mm256_cmpgt_epi32(count[1], sixteen));
        if (__builtin_expect(_mm256_movemask_ps(_mm256_castsi256_ps(more)) != 0, 0)) {
            for (int r = 0; r < R; ++r) {
                __m256i b2 = _mm256_min_epu32(_mm256_subs_epu16(count[r], sixteen), sixteen);
                x[r] = avx2_bits(x[r], b2, &r2[r]);
                r1[r] = _mm256_or_si256(_mm256_sllv_epi32(r1[r], b2), r2[r]);
            }
            for (int r = 0; r < R; ++r) x[r] = avx2_renorm(x[r], data, &pos);
        }
        for (int r = 0; r < R; ++r)
            _mm256_storeu_si256((__m256i *)(out + g + 8 * r), avx2_values(sgn, info[r], r1[r]));
        if (pos > size) return 1;
    }
    /* the largest token of each lane (bytes' maximum: the token is the information's low byte) */
    if (_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_and_si256(bad, low8), _mm256_set1_epi32(MAX_TOKEN)))))
        return 2;
    uint32_t lanes[MAX_LANES];
    for (int r = 0; r < R; ++r) _mm256_storeu_si256((__m256i *)(lanes + 8 * r), x[r]);
    if (g < n) {
        int e = lane_group(sgn, lanes, n - g, data, size, &pos, cls + g, out + g);
        if (e) return e;
    }
    return lane_finish((int)S, lanes, pos, size);
}
#endif

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

/* The lanes' decoders: v<S> tokens alphabet, v<S>s signed alphabet; the scalar reference, and x: AVX2 (the
 * scalar reference where the CPU lacks AVX2). */
#define LANE_VARIANTS(X) X(8, 0) X(8, 3) X(16, 0) X(16, 3)
#define DEFINE_LANES(S, F) \
    static int lanes_##S##_##F(const uint8_t *d, size_t size, size_t limit, const uint8_t *c, uint32_t n, int32_t *o) { \
        return decode_lanes(S, F == 3, d, size, c, n, o); }
LANE_VARIANTS(DEFINE_LANES)
#ifdef HAVE_AVX2_LANES
static int have_avx2;
#define DEFINE_LANES_AVX2(S, F) \
    __attribute__((target("avx2,popcnt"))) static int lanes_avx2_##S##_##F(const uint8_t *d, size_t size, size_t limit, \
                                                                         const uint8_t *c, uint32_t n, int32_t *o) { \
        return have_avx2 ? decode_lanes_avx2(S / 8, F == 3, d, size, c, n, o) : decode_lanes(S, F == 3, d, size, c, n, o); }
#else
#define DEFINE_LANES_AVX2(S, F) \
    static int lanes_avx2_##S##_##F(const uint8_t *d, size_t size, size_t limit, const uint8_t *c, uint32_t n, \
                                    int32_t *o) { return decode_lanes(S, F == 3, d, size, c, n, o); }
#endif
LANE_VARIANTS(DEFINE_LANES_AVX2)

typedef int (*decoder_t)(const uint8_t *, size_t, size_t, const uint8_t *, uint32_t, int32_t *);
/* word: 0 byte renormalization, 1 16-bit words, 2 lanes (simd: 1 the AVX2 decoder) */
#define ENTRY(S, W, F) {S, W, F, 0, decode_##S##_##W##_##F},
#define ENTRY_LANES(S, F) {S, 2, F, 0, lanes_##S##_##F}, {S, 2, F, 1, lanes_avx2_##S##_##F},
static const struct { int S, word, free, simd; decoder_t fn; } variants[] = {VARIANTS(ENTRY) LANE_VARIANTS(ENTRY_LANES)};
#define NV (sizeof variants / sizeof variants[0])

/* A variant's name, as printed and as chosen on the command line. */
static const char *variant_name(size_t v, char *buf) {
    int f = variants[v].free;
    if (variants[v].word == 2) {
        sprintf(buf, "v%d%s%s", variants[v].S, f == 3 ? "s" : "", variants[v].simd ? "x" : "");
        return buf;
    }
    sprintf(buf, "%c%d%s", variants[v].word ? 'w' : 'b', variants[v].S,
            f == 9 ? "u" : f == 4 ? "S" : f == 3 ? "s" : f == 2 ? "t" : f ? "f" : "");
    return buf;
}

typedef struct {
    uint32_t n, python_bytes, clip; /* clip: the index of the stream it comes from (0 if the dump has no marks) */
    uint8_t *cls;
    int32_t *val;
    uint8_t *enc[NV];      /* rANS data then bits then PAD */
    size_t size[NV], bytes[NV];
} unit_rec;

int main(int argc, char **argv) {
    if (argc != 3 && argc != 4) {
        fprintf(stderr, "usage: %s ROUNDS units.bin [VARIANT,...]\n", argv[0]);
        return 2;
    }
    int rounds = atoi(argv[1]);
    signed_tables();
    lane_tables();
#ifdef HAVE_AVX2_LANES
    lane_perm_table();
    have_avx2 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
#else
    const int have_avx2 = 0;
#endif
    if (!have_avx2) fprintf(stderr, "no AVX2 here: the v*x variants run the scalar decoder\n");
    /* the variants timed: b2 (the reference of the ratios) and those named, else all */
    int run[NV];
    char name[16];
    for (size_t v = 0; v < NV; ++v) {
        run[v] = argc == 3 || v == 0;
        for (const char *p = argc == 4 ? argv[3] : ""; *p; p += strcspn(p, ","), p += *p == ',') {
            size_t len = strcspn(p, ",");
            if (len == strlen(variant_name(v, name)) && !strncmp(p, name, len)) run[v] = 1;
        }
    }
    FILE *f = fopen(argv[2], "rb");
    if (!f) { fprintf(stderr, "%s: cannot open\n", argv[2]); return 1; }
    size_t cap = 1024, count = 0;
    unit_rec *u = malloc(cap * sizeof *u);
    uint32_t head[2], clip = 0;
    while (fread(head, 4, 2, f) == 2) {
        if (head[0] == 0xFFFFFFFFu) { /* a stream's mark */
            clip = head[1];
            continue;
        }
        if (count == cap) u = realloc(u, (cap *= 2) * sizeof *u);
        unit_rec *r = &u[count++];
        memset(r, 0, sizeof *r);
        r->clip = clip;
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
            size_t size = 0;
            nbits = 0;
            if (r->n && variants[v].word == 2)
                size = encode_lanes(variants[v].S, variants[v].free == 3, r->val, r->cls, r->n, data, room);
            else if (r->n)
                size = encode(variants[v].S, variants[v].word, variants[v].free >= 3 && variants[v].free < 9, r->val,
                              r->cls, r->n, data, room, bits, &nbits);
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
                if (!run[v]) continue;
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
    /* Each unit decoded once a pass, every unit in turn: the branch predictor cannot learn a unit's branches from
     * its repeats (a random pose decodes its unit once); the least of ROUNDS passes, the variants taking turns. */
    double pass[NV];
    for (size_t v = 0; v < NV; ++v) pass[v] = 1e30;
    for (int round = 0; round < rounds; ++round)
        for (size_t v = 0; v < NV; ++v) {
            if (!run[v]) continue;
            int e = 0;
            double t0 = thread_seconds();
            for (size_t i = 0; i < count; ++i)
                if (u[i].n)
                    e |= variants[v].fn(u[i].enc[v], u[i].size[v], u[i].bytes[v] - varint_bytes(u[i].size[v]),
                                        u[i].cls, u[i].n, out);
            double t1 = thread_seconds() - t0;
            if (e) return 1;
            if (t1 < pass[v]) pass[v] = t1;
        }
    /* Random access as the harness meets it: per clip, 80 draws per unit of a unit at random (a pose's chunk), the
     * unit decoded unless it is the previous draw's (the runtime keeps its last chunk); the branch predictor sees
     * the clip's few units again and again in a random order. The least of ROUNDS runs over all clips. */
    double drawn[NV];
    uint64_t drawn_values = 0;
    for (size_t v = 0; v < NV; ++v) drawn[v] = 1e30;
    for (int round = 0; round < rounds; ++round)
        for (size_t v = 0; v < NV; ++v) {
            if (!run[v]) continue;
            int e = 0;
            uint64_t decoded = 0;
            double t = 0;
            for (size_t first = 0, last; first < count; first = last) {
                for (last = first; last < count && u[last].clip == u[first].clip;) ++last;
                size_t units = last - first, previous = units;
                uint64_t state = 0x9e3779b97f4a7c15ull;
                double t0 = thread_seconds();
                for (size_t d = 0; d < 80 * units; ++d) {
                    state = state * 6364136223846793005ull + 1442695040888963407ull;
                    size_t i = first + (size_t)((state >> 33) % units);
                    if (i == previous || !u[i].n) continue;
                    previous = i;
                    decoded += u[i].n;
                    e |= variants[v].fn(u[i].enc[v], u[i].size[v], u[i].bytes[v] - varint_bytes(u[i].size[v]),
                                        u[i].cls, u[i].n, out);
                }
                t += thread_seconds() - t0;
            }
            if (e) return 1;
            if (t < drawn[v]) drawn[v] = t;
            drawn_values = decoded;
        }
    uint64_t b0 = 0;
    for (size_t i = 0; i < count; ++i) b0 += u[i].bytes[0];
    printf("%zu units, %llu values (%.0f a unit), b2 bytes %llu = python's %llu (%llu units differ)\n", count,
           (unsigned long long)values, (double)values / (double)count, (unsigned long long)b0,
           (unsigned long long)python, (unsigned long long)mismatch);
    for (size_t v = 0; v < NV; ++v) {
        if (!run[v]) continue;
        uint64_t bytes = 0;
        for (size_t i = 0; i < count; ++i) bytes += u[i].bytes[v];
        printf("%-5s  repeated %6.3f ns/value %.3fx  random %6.3f %.3fx  once %6.3f %.3fx  bytes %+lld (%+.2f%%)\n",
               variant_name(v, name), 1e9 * best[v] / (double)values, best[v] / best[0],
               1e9 * drawn[v] / (double)drawn_values, drawn[v] / drawn[0], 1e9 * pass[v] / (double)values,
               pass[v] / pass[0], (long long)bytes - (long long)b0, 100.0 * ((double)bytes - (double)b0) / (double)b0);
    }
    return 0;
}
