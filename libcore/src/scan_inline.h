/*
 * scan_inline.h - the hot inline helpers of the kernels (private): the
 * 16-column scans of sign bytes and cube configurations, and the algebra of
 * row spans that lets every loop skip the constant parts of a row.
 *
 * Included by the kernel templates only (kernels_template.h), once per
 * target: KERNELS_SSE2 (0 or 1) says whether the scans use SSE2
 * intrinsics or portable 64-bit word arithmetic.  Both give the same
 * results; the test core_simd_identical compares the meshes.
 */
#ifndef ISOMEND_SCAN_INLINE_H
#define ISOMEND_SCAN_INLINE_H

#include "grid.h"

#if !defined(KERNELS_SSE2)
#error "scan_inline.h: define KERNELS_SSE2 (kernels_template.h)"
#endif
#if KERNELS_SSE2
#include <emmintrin.h>
#endif

/* ------------------------------------------------- 16 columns at a time */

/* The last index h < n with s[h] != v, or -1: 16 bytes a step from the end
 * (a row's span ends where a blob's chord does, often far from the end). */
static inline int64_t last_not(const uint8_t *s, int64_t n, uint8_t v)
{
    int64_t h = n;
#if KERNELS_SSE2
    const __m128i vv = _mm_set1_epi8((char)v);
    for (; h >= 16; h -= 16) {
        const __m128i x = _mm_loadu_si128((const __m128i *)(const void *)(s + h - 16));
        const uint32_t m = (uint32_t)_mm_movemask_epi8(_mm_cmpeq_epi8(x, vv)) ^ 0xFFFFu;
        if (m)
            return h - 16 + (31 - __builtin_clz(m));
    }
#endif
    while (h > 0 && s[h - 1] == v)
        h--;
    return h - 1;
}

/*
 * Scanning 16 sign bytes (or cube configurations) per step, so long
 * stretches without a crossing cost a compare.  The reads reach up to 15
 * bytes past the last column scanned: the buffers carry SCAN_PAD bytes of
 * slack.
 */

/* Bit x set when a[x] != b[x], x in 0..15. */
static inline uint32_t diff16(const uint8_t *a, const uint8_t *b)
{
#if KERNELS_SSE2
    const __m128i va = _mm_loadu_si128((const __m128i *)(const void *)a);
    const __m128i vb = _mm_loadu_si128((const __m128i *)(const void *)b);
    return (uint32_t)_mm_movemask_epi8(_mm_cmpeq_epi8(va, vb)) ^ 0xFFFFu;
#else
    const uint64_t m = UINT64_C(0x0101010101010101);
    return (uint32_t)(((load8(a) ^ load8(b)) & m) * UINT64_C(0x0102040810204080) >> 56) |
           (uint32_t)(((load8(a + 8) ^ load8(b + 8)) & m) * UINT64_C(0x0102040810204080) >> 56)
               << 8;
#endif
}

/* Bit x set when cube configuration c[x] is neither 0 nor 255, x in 0..15. */
static inline uint32_t mixed16(const uint8_t *c)
{
#if KERNELS_SSE2
    const __m128i v = _mm_loadu_si128((const __m128i *)(const void *)c);
    const __m128i trivial =
        _mm_or_si128(_mm_cmpeq_epi8(v, _mm_setzero_si128()), _mm_cmpeq_epi8(v, _mm_set1_epi8(-1)));
    return (uint32_t)_mm_movemask_epi8(trivial) ^ 0xFFFFu;
#else
    uint32_t r = 0;
    for (int x = 0; x < 16; x++)
        r |= (uint32_t)(c[x] != 0 && c[x] != 255) << x;
    return r;
#endif
}

/* The configuration of cube i between rows r0, r1 (slice k) and r2, r3
 * (slice k + 1), corners numbered as in cube.h. */
static inline unsigned cube_case(const uint8_t *r0, const uint8_t *r1, const uint8_t *r2,
                                 const uint8_t *r3, int64_t i)
{
    return (unsigned)r0[i] | (unsigned)r0[i + 1] << 1 | (unsigned)r1[i] << 2 |
           (unsigned)r1[i + 1] << 3 | (unsigned)r2[i] << 4 | (unsigned)r2[i + 1] << 5 |
           (unsigned)r3[i] << 6 | (unsigned)r3[i + 1] << 7;
}

/*
 * The configurations of the 16 cubes between rows a, b (slice k) and c, d
 * (slice k + 1) at columns 0..15, stored to out[0..15]; returns the mask of
 * those that are neither 0 nor 255 (bit x: column x).  For narrow spans, where
 * row_cases' setup costs more than the few cubes do.  Sign bytes are 0 or 1,
 * so a 16-bit lane shift by up to 7 moves each byte's bit within its byte.
 */
static inline uint32_t cases16(const uint8_t *a, const uint8_t *b, const uint8_t *c,
                               const uint8_t *d, uint8_t *out)
{
#if KERNELS_SSE2
#define LD16(p) _mm_loadu_si128((const __m128i *)(const void *)(p))
    const __m128i v = _mm_or_si128(
        _mm_or_si128(_mm_or_si128(LD16(a), _mm_slli_epi16(LD16(a + 1), 1)),
                     _mm_or_si128(_mm_slli_epi16(LD16(b), 2), _mm_slli_epi16(LD16(b + 1), 3))),
        _mm_or_si128(_mm_or_si128(_mm_slli_epi16(LD16(c), 4), _mm_slli_epi16(LD16(c + 1), 5)),
                     _mm_or_si128(_mm_slli_epi16(LD16(d), 6), _mm_slli_epi16(LD16(d + 1), 7))));
#undef LD16
    _mm_storeu_si128((__m128i *)(void *)out, v);
    const __m128i trivial =
        _mm_or_si128(_mm_cmpeq_epi8(v, _mm_setzero_si128()), _mm_cmpeq_epi8(v, _mm_set1_epi8(-1)));
    return (uint32_t)_mm_movemask_epi8(trivial) ^ 0xFFFFu;
#else
    uint32_t r = 0;
    for (int x = 0; x < 16; x++) {
        out[x] = (uint8_t)cube_case(a, b, c, d, x);
        r |= (uint32_t)(out[x] != 0 && out[x] != 255) << x;
    }
    return r;
#endif
}

/* Keeps bits 0..n-1 (n < 16). */
static inline uint32_t first_bits(uint32_t mask, int64_t n)
{
    return mask & ((1u << n) - 1u);
}

static inline void prefetch_at(const char *base, int64_t off)
{
    /* Integer arithmetic: the address may lie outside the volume (a prefetch
     * never faults), and pointer arithmetic there would be undefined. */
    __builtin_prefetch((const void *)((uintptr_t)base + (uintptr_t)off));
}

/* ------------------------------------------------------------ row spans */

/* Row r is uniform with sign v (its span is empty). */
static inline int uniform_as(const row_span *r, int64_t N0, uint8_t v)
{
    return r->lo >= N0 && r->first == v;
}

/* Two simple rows with the same outside sign: pair_spans is then exact. */
static inline int simple_pair(const row_span *a, const row_span *b)
{
    return a->simple && b->simple && a->first == b->first;
}

/*
 * The columns where rows a and b may differ, as 0, 1 or 2 ascending
 * intervals in span[0..2n): outside them the rows agree.  Two simple rows with
 * the same outside sign differ exactly on the symmetric difference of their
 * runs, which is what the intervals are then.
 */
static inline int pair_spans(const row_span *a, const row_span *b, int64_t N0, int64_t span[4])
{
    if (simple_pair(a, b)) {
        int n = 0;
        int64_t iv[4];
        if (a->lo <= b->hi && b->lo <= a->hi) { /* overlapping runs */
            iv[0] = a->lo < b->lo ? a->lo : b->lo;
            iv[1] = (a->lo > b->lo ? a->lo : b->lo) - 1;
            iv[2] = (a->hi < b->hi ? a->hi : b->hi) + 1;
            iv[3] = a->hi > b->hi ? a->hi : b->hi;
        } else { /* disjoint runs: both, in column order */
            const row_span *l = a->lo < b->lo ? a : b, *r = l == a ? b : a;
            iv[0] = l->lo;
            iv[1] = l->hi;
            iv[2] = r->lo;
            iv[3] = r->hi;
        }
        for (int q = 0; q < 4; q += 2)
            if (iv[q] <= iv[q + 1]) {
                span[2 * n] = iv[q];
                span[2 * n + 1] = iv[q + 1];
                n++;
            }
        return n;
    }
    int64_t f = 0, t = N0 - 1;
    if (a->first == b->first)
        f = a->lo < b->lo ? a->lo : b->lo;
    if (a->last == b->last)
        t = a->hi > b->hi ? a->hi : b->hi;
    span[0] = f;
    span[1] = t;
    return f <= t;
}

/*
 * The columns i where row a's sample i differs from sample i + 1 may lie
 * (x edges), as intervals like pair_spans: a simple row crosses exactly at
 * lo - 1 and hi.
 */
/* The n spans [span[2q], span[2q + 1]] cut to [lo, hi], the empty ones
 * dropped; returns how many are left. */
static inline int clip_spans(int64_t *span, int n, int64_t lo, int64_t hi)
{
    int k = 0;
    for (int q = 0; q < n; q++) {
        const int64_t a = span[2 * q] > lo ? span[2 * q] : lo;
        const int64_t b = span[2 * q + 1] < hi ? span[2 * q + 1] : hi;
        if (a <= b) {
            span[2 * k] = a;
            span[2 * k + 1] = b;
            k++;
        }
    }
    return k;
}

static inline int row_spans(const row_span *a, int64_t N0, int64_t span[4])
{
    if (a->lo >= N0)
        return 0;
    if (a->simple) {
        span[0] = span[1] = a->lo - 1;
        span[2] = span[3] = a->hi;
        return 2;
    }
    span[0] = a->lo - 1;
    span[1] = a->hi;
    return 1;
}

/*
 * The columns of cubes of a row (between four sample rows) that can hold a
 * non-empty cube: one interval, or two when the four rows are simple with the
 * same outside sign (the cubes inside all four runs are then empty too).
 * Fills span[0..2n) with n intervals and returns n (0, 1 or 2).
 */
static inline int cube_spans(const row_span *r[4], int64_t N0, int64_t span[4])
{
    int same_first = 1, same_last = 1, simple = 1;
    int64_t lo = N0, hi = -1, lo_max = -1, hi_min = N0;
    for (int q = 0; q < 4; q++) {
        same_first &= r[q]->first == r[0]->first;
        same_last &= r[q]->last == r[0]->last;
        simple &= r[q]->simple;
        if (r[q]->lo < lo)
            lo = r[q]->lo;
        if (r[q]->hi > hi)
            hi = r[q]->hi;
        if (r[q]->lo > lo_max)
            lo_max = r[q]->lo;
        if (r[q]->hi < hi_min)
            hi_min = r[q]->hi;
    }
    const int64_t from = same_first ? (lo > 0 ? lo - 1 : 0) : 0;
    const int64_t to = same_last ? (hi < N0 - 2 ? hi : N0 - 2) : N0 - 2;
    if (from > to)
        return 0;
    if (simple && same_first && lo_max <= hi_min - 1) {
        /* cubes in [lo_max, hi_min - 1] have all 8 corners inside the runs */
        span[0] = from;
        span[1] = lo_max - 1;
        span[2] = hi_min;
        span[3] = to;
        return 2;
    }
    span[0] = from;
    span[1] = to;
    return 1;
}

#endif /* ISOMEND_SCAN_INLINE_H */
