/*
 * extract.c - marching cubes, Durst's fix and the thesis's disambiguated
 * marching cubes over a volume read in place.
 *
 * Passes.  The grid is cut into chunks of consecutive cube layers (a layer is
 * the cubes between sample slices k and k+1).  Threads take chunks from an
 * atomic counter; everything a chunk writes goes to places fixed in advance,
 * so the mesh is the same, vertex order included, for every thread count.
 *
 *   1. Count.  For each slice k: the intersected grid edges whose lower end
 *      is in slice k (x and y edges in the slice, z edges to slice k+1); for
 *      each layer: the triangles, including mending/Durst quadrilaterals, and
 *      the statistics (Table-2 histogram, ambiguous faces, inverted
 *      combinations).
 *   2. Prefix sums give every slice's first vertex and every layer's first
 *      triangle; the output arrays are allocated once, at their exact size.
 *   3. Fill.  Each chunk numbers the intersected edges of its slices in a
 *      fixed order (slice, row, axis x/y/z, column), computes those vertices
 *      (position, normal) once, and writes its layers' triangles.
 *
 * One pass.  With one or two threads and a table method (MC, Durst, DMC) on
 * a grid of 2^21 samples or more, the three steps become one sweep
 * (run_one_pass): the slice's edges are numbered from the running count, so
 * the ids and the order are the same, and the output arrays are address-space
 * reservations of the largest mesh the grid can give, trimmed at the end.
 * Each slice is classified once, and its vertices are computed while its
 * samples are still in the caches (the 256^3 sphere: 0.79x the two passes'
 * time).  Two threads split the sweep: the second counts the first layers
 * (the counting pass's scans) up to a layer that halves what is left, then
 * sweeps from there with ids and triangles starting at its counts (split).
 *
 * The counting pass classifies samples row by row into sign bytes (sample
 * >= iso, with a threshold chosen per voxel type so the comparison is exact
 * and the loop vectorises, AVX2 where available) and keeps them, 1 bit a
 * sample, in a sign cache that the fill pass reads instead of the volume.
 * Each row carries its span (where its sign changes) so that rows of cubes
 * whose four sample rows are uniform are skipped, and rows that are one run
 * in a constant background (chords through a blob) are scanned only at the
 * runs' ends.  Crossings and busy cubes are found 16 columns at a time.
 * Only samples around emitted vertices are read as numbers, by per-type,
 * per-axis loops, four vertices at a time on AVX2 (make_vertex is the general
 * path near borders and NaN).
 * Output arrays of 2 MiB and more go on transparent huge pages.
 *
 * Methods of methods.h (facial, gradient, asymptotic, tetra, mc33) replace
 * the table by a per-cube hook: face-diagonal vertices (tetra) are numbered
 * with their slice, cube-private vertices after all the slices' vertices.
 *
 * Mending (thesis chapter 4.2.2).  Each face of the grid is judged once, by
 * the cube for which it is the +x, +y or +z face.  If the face is ambiguous
 * and the neighbour exists, DURST always adds a quadrilateral, DMC only when
 * exactly one of the two cubes is inverted (5+ positive corners).  The table
 * records this cube's two directed segments on the face in loop order
 * p->q, r->s; the neighbour, pairing the points the other way, supplies
 * q->r and s->p, so the hole is the loop p q r s and the quadrilateral
 * (s, r, q, p) uses each of its edges in the opposite direction.  Its
 * diagonal s-q joins points on opposite edges of the face, which no other
 * triangle can contain, so the surface stays a 2-manifold.
 *
 * Padding and NaN.  With ISOMEND_FLAG_PAD the marched grid is the volume
 * plus one layer of samples on every side; padding samples, like NaN
 * samples, are outside, and an edge with such an endpoint is cut at its
 * midpoint.
 */
#define _GNU_SOURCE /* madvise, posix_memalign, mremap */
#include "isomend.h"
#include "methods.h"
#include "tables.h"

#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#if defined(__linux__)
#include <sys/mman.h>
#endif
#if defined(__SSE2__) && !defined(ISOMEND_NO_SIMD)
#include <emmintrin.h>
#endif
/* AVX2 paths, chosen at run time (grid.avx2): four vertices at once (vertex4
 * below) and the float32 classification (classify_f32_avx2). */
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__)) && \
    !defined(ISOMEND_NO_SIMD)
#define ISOMEND_VERTEX4 1
#define ISOMEND_CLASSIFY_AVX2 1
#include <immintrin.h>
#endif

struct isomend_mesh {
    size_t nv, nt;
    float *pos;
    float *nrm;
    uint32_t *tri;
    uint8_t *org;
    double box[6];
    size_t mapped[4]; /* bytes mapped for pos, nrm, tri, org; 0: malloc'ed */
};

/* ------------------------------------------------------------ the grid */

typedef struct grid {
    const char *data;
    isomend_type type;
    int64_t n[3];  /* the volume's dimensions                      */
    int64_t st[3]; /* byte strides                                  */
    int64_t pad;   /* 0 or 1                                        */
    int64_t N[3];  /* marched grid: n + 2 pad                      */
    double iso;
    double h[3];   /* spacing                                       */
    double inv2h[3]; /* 1 / (2 spacing), for central differences    */
    int64_t inner_lo[3], inner_hi[3]; /* marched samples with all 6 neighbours in the volume */
    double o[3];   /* world position of marched sample (0, 0, 0)   */
    int constant;  /* integer types: -1 none, 0 all out, 1 all in */
    int64_t ithr;  /* integer types: inside iff v >= ithr           */
    float fthr;    /* f32: the smallest float >= iso               */
    int avx2;      /* the CPU runs the AVX2 paths                   */
} grid;

/* Sample (i, j, k) of the marched grid as a double; NaN for padding. */
static double fetch(const grid *g, int64_t i, int64_t j, int64_t k)
{
    i -= g->pad;
    j -= g->pad;
    k -= g->pad;
    if ((uint64_t)i >= (uint64_t)g->n[0] || (uint64_t)j >= (uint64_t)g->n[1] ||
        (uint64_t)k >= (uint64_t)g->n[2])
        return NAN;
    const char *p = g->data + i * g->st[0] + j * g->st[1] + k * g->st[2];
    switch (g->type) {
    case ISOMEND_U8: { uint8_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_I8: { int8_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_U16: { uint16_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_I16: { int16_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_I32: { int32_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_F32: { float v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_F64: { double v; memcpy(&v, p, sizeof v); return v; }
    }
    return NAN;
}

/*
 * Sign rows.  A row of the marched grid is stored as bytes (1 = inside) plus
 * its span: `lo`, the first column whose sign differs from column 0 (N0 when
 * the row is uniform), and `hi`, the last column whose sign differs from the
 * last column (-1 when uniform).  Outside [lo - 1, hi] the row is constant,
 * which is what lets every loop below skip the empty parts of a row.  A
 * `simple` row is one run [lo, hi] of the other sign in a constant row (a
 * chord through a blob): rows of cubes between four simple rows are empty
 * inside the runs' overlap too.
 */
typedef struct rowinfo {
    int64_t lo, hi;
    uint8_t first, last;
    uint8_t simple; /* one run [lo, hi] of the other sign, constant around it */
} rowinfo;

/*
 * The classification loops, one per voxel type, written so the compiler
 * vectorises them: restrict pointers, the threshold in a local, 32-bit
 * counters.  A strided or misaligned row takes the memcpy loop.
 */
/*
 * On x86-64 the hot loops are also compiled for AVX2 and picked at load time
 * (GCC function multiversioning); the baseline build stays SSE2.
 */
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && defined(__linux__)
#define ISOMEND_HOT_LOOP __attribute__((target_clones("avx2", "default")))
#else
#define ISOMEND_HOT_LOOP
#endif

#define DEFINE_CLASSIFY(NAME, T)                                                       \
    ISOMEND_HOT_LOOP static uint64_t NAME(const char *row, int64_t n, int64_t st, T t, int count_nans,  \
                         uint8_t *restrict o)                                          \
    {                                                                                  \
        uint32_t nn = 0;                                                               \
        if (st == (int64_t)sizeof(T) && (uintptr_t)row % _Alignof(T) == 0) {           \
            const T *restrict r = (const T *)(const void *)row;                        \
            if (count_nans) {                                                          \
                for (int64_t i = 0; i < n; i++) {                                      \
                    o[i] = (uint8_t)(r[i] >= t);                                       \
                    nn += (uint32_t)(r[i] != r[i]);                                    \
                }                                                                      \
            } else {                                                                   \
                for (int64_t i = 0; i < n; i++)                                        \
                    o[i] = (uint8_t)(r[i] >= t);                                       \
            }                                                                          \
        } else {                                                                       \
            for (int64_t i = 0; i < n; i++) {                                          \
                T v;                                                                   \
                memcpy(&v, row + i * st, sizeof v);                                    \
                o[i] = (uint8_t)(v >= t);                                              \
                nn += (uint32_t)(v != v);                                              \
            }                                                                          \
        }                                                                              \
        return nn;                                                                     \
    }
DEFINE_CLASSIFY(classify_u8, uint8_t)
DEFINE_CLASSIFY(classify_i8, int8_t)
DEFINE_CLASSIFY(classify_u16, uint16_t)
DEFINE_CLASSIFY(classify_i16, int16_t)
DEFINE_CLASSIFY(classify_i32, int32_t)
DEFINE_CLASSIFY(classify_f32, float)
DEFINE_CLASSIFY(classify_f64, double)

#if ISOMEND_CLASSIFY_AVX2
/* The NaN lanes of x. */
__attribute__((target("avx2"))) static inline uint64_t nans8(__m256 x)
{
    return (uint64_t)__builtin_popcount((unsigned)_mm256_movemask_ps(_mm256_cmp_ps(x, x, _CMP_UNORD_Q)));
}

/*
 * classify_f32 on a contiguous row, written out for AVX2: 32 samples a step
 * in about 20 instructions (4 more to look for NaNs) where the compiler's
 * loop took about 40 (it masked each comparison twice and counted NaNs lane
 * by lane); NaNs, which are rare, are counted only in the steps that have
 * one.  Same results: `>=` is an ordered comparison, false for NaN, as in C.
 * The 256^3 float32 sphere: classification 24 -> 17 M instructions, the
 * extraction 115 -> 108 M; time 0.98-0.99x (0.93-0.96x at 512^3), as the
 * loop mostly waits on memory.  Looking for NaNs with two compares instead
 * of four: 108 -> 106 M, time 0.92-1.01x.
 */
__attribute__((target("avx2"))) static uint64_t classify_f32_avx2(const float *restrict r,
                                                                   int64_t n, float t,
                                                                   int count_nans,
                                                                   uint8_t *restrict o)
{
    const __m256 tv = _mm256_set1_ps(t);
    /* packs interleave the four masks' halves; this puts them back in order */
    const __m256i order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
    const __m256i one = _mm256_set1_epi8(1);
    uint64_t nn = 0;
    int64_t i = 0;
    for (; i + 32 <= n; i += 32) {
        const __m256 x0 = _mm256_loadu_ps(r + i), x1 = _mm256_loadu_ps(r + i + 8);
        const __m256 x2 = _mm256_loadu_ps(r + i + 16), x3 = _mm256_loadu_ps(r + i + 24);
        const __m256i m0 = _mm256_castps_si256(_mm256_cmp_ps(x0, tv, _CMP_GE_OQ));
        const __m256i m1 = _mm256_castps_si256(_mm256_cmp_ps(x1, tv, _CMP_GE_OQ));
        const __m256i m2 = _mm256_castps_si256(_mm256_cmp_ps(x2, tv, _CMP_GE_OQ));
        const __m256i m3 = _mm256_castps_si256(_mm256_cmp_ps(x3, tv, _CMP_GE_OQ));
        const __m256i b = _mm256_packs_epi16(_mm256_packs_epi32(m0, m1), _mm256_packs_epi32(m2, m3));
        _mm256_storeu_si256((__m256i *)(void *)(o + i),
                            _mm256_and_si256(_mm256_permutevar8x32_epi32(b, order), one));
        if (count_nans) {
            /* lane l is unordered when x0[l] or x1[l] is NaN: two compares
             * tell whether the 32 samples hold one, four count them */
            const __m256 u = _mm256_or_ps(_mm256_cmp_ps(x0, x1, _CMP_UNORD_Q),
                                          _mm256_cmp_ps(x2, x3, _CMP_UNORD_Q));
            if (!_mm256_testz_ps(u, u))
                nn += nans8(x0) + nans8(x1) + nans8(x2) + nans8(x3);
        }
    }
    for (; i < n; i++) {
        o[i] = (uint8_t)(r[i] >= t);
        nn += (uint64_t)(count_nans && r[i] != r[i]);
    }
    return nn;
}
#endif

/* The last index h < n with s[h] != v, or -1: 16 bytes a step from the end
 * (a row's span ends where a blob's chord does, often far from the end). */
static inline int64_t last_not(const uint8_t *s, int64_t n, uint8_t v)
{
    int64_t h = n;
#if defined(__SSE2__) && !defined(ISOMEND_NO_SIMD)
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

/* Classifies row (j, k) of the marched grid into s[0..N0-1]; adds its NaNs to
 * *nans unless nans is NULL (then they are not counted). */
static void classify_row(const grid *g, int64_t j, int64_t k, uint8_t *s, rowinfo *ri,
                         uint64_t *nans)
{
    const int64_t N0 = g->N[0], p = g->pad;
    const int64_t rj = j - p, rk = k - p;
    if (rj < 0 || rj >= g->n[1] || rk < 0 || rk >= g->n[2]) {
        memset(s, 0, (size_t)N0);
        ri->lo = N0;
        ri->hi = -1;
        ri->first = ri->last = 0;
        ri->simple = 0;
        return;
    }
    if (p) {
        s[0] = 0;
        s[N0 - 1] = 0;
    }
    uint8_t *o = s + p;
    const int64_t n = g->n[0], st = g->st[0];
    const char *row = g->data + rj * g->st[1] + rk * g->st[2];
    uint64_t nn = 0;
    if (g->constant >= 0) {
        memset(o, g->constant, (size_t)n);
    } else {
        switch (g->type) {
        case ISOMEND_U8: classify_u8(row, n, st, (uint8_t)g->ithr, 0, o); break;
        case ISOMEND_I8: classify_i8(row, n, st, (int8_t)g->ithr, 0, o); break;
        case ISOMEND_U16: classify_u16(row, n, st, (uint16_t)g->ithr, 0, o); break;
        case ISOMEND_I16: classify_i16(row, n, st, (int16_t)g->ithr, 0, o); break;
        case ISOMEND_I32: classify_i32(row, n, st, (int32_t)g->ithr, 0, o); break;
        case ISOMEND_F32:
#if ISOMEND_CLASSIFY_AVX2
            if (g->avx2 && st == (int64_t)sizeof(float) && (uintptr_t)row % _Alignof(float) == 0) {
                nn = classify_f32_avx2((const float *)(const void *)row, n, g->fthr,
                                       nans != NULL, o);
                break;
            }
#endif
            nn = classify_f32(row, n, st, g->fthr, nans != NULL, o);
            break;
        case ISOMEND_F64: nn = classify_f64(row, n, st, g->iso, nans != NULL, o); break;
        }
    }
    if (nans)
        *nans += nn;
    ri->first = s[0];
    ri->last = s[N0 - 1];
    const uint8_t *d = memchr(s, s[0] ^ 1, (size_t)N0);
    if (!d) {
        ri->lo = N0;
        ri->hi = -1;
        ri->simple = 0;
        return;
    }
    ri->lo = d - s;
    ri->hi = last_not(s, N0, ri->last);
    ri->simple = 0;
    if (ri->first == ri->last) {
        const uint8_t *e = memchr(s + ri->lo, ri->first, (size_t)(N0 - ri->lo));
        ri->simple = e && e - s == ri->hi + 1;
    }
}

/* Row r is uniform with sign v (its span is empty). */
static inline int uniform_as(const rowinfo *r, int64_t N0, uint8_t v)
{
    return r->lo >= N0 && r->first == v;
}

/* Two simple rows with the same outside sign: pair_spans is then exact. */
static inline int simple_pair(const rowinfo *a, const rowinfo *b)
{
    return a->simple && b->simple && a->first == b->first;
}

/*
 * The columns where rows a and b may differ, as 0, 1 or 2 ascending
 * intervals in span[0..2n): outside them the rows agree.  Two simple rows with
 * the same outside sign differ exactly on the symmetric difference of their
 * runs, which is what the intervals are then.
 */
static inline int pair_spans(const rowinfo *a, const rowinfo *b, int64_t N0, int64_t span[4])
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
            const rowinfo *l = a->lo < b->lo ? a : b, *r = l == a ? b : a;
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
static inline int row_spans(const rowinfo *a, int64_t N0, int64_t span[4])
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

/* Sets the exact per-type threshold: inside iff sample >= iso. */
static void grid_threshold(grid *g)
{
    static const double lo[] = {0, -128, 0, -32768, -2147483648.0};
    static const double hi[] = {255, 127, 65535, 32767, 2147483647.0};
    g->constant = -1;
    if (g->type == ISOMEND_F32) {
        float f = (float)g->iso;
        if ((double)f < g->iso)
            f = nextafterf(f, INFINITY);
        g->fthr = f;
    } else if (g->type != ISOMEND_F64) {
        double t = ceil(g->iso);
        if (t > hi[g->type])
            g->constant = 0;
        else if (t <= lo[g->type])
            g->constant = 1;
        else
            g->ithr = (int64_t)t;
    }
}

/* ------------------------------------------------------------- vertices */

/* World-space gradient component along axis a at marched sample (i, j, k). */
static double gradient_component(const grid *g, const int64_t p[3], int a, double f0)
{
    int64_t q[3] = {p[0], p[1], p[2]}, r[3] = {p[0], p[1], p[2]};
    q[a]++;
    r[a]--;
    double fp = fetch(g, q[0], q[1], q[2]);
    double fm = fetch(g, r[0], r[1], r[2]);
    int vp = !isnan(fp), vm = !isnan(fm);
    if (vp && vm)
        return (fp - fm) * g->inv2h[a];
    if (vp)
        return (fp - f0) / g->h[a];
    if (vm)
        return (f0 - fm) / g->h[a];
    return 0.0;
}

/*
 * Fast path for a vertex whose endpoints and their six neighbours are all
 * inside the volume: typed loads, no bounds checks.  Fills the endpoint
 * values and the gradients at both endpoints (NaN samples make them NaN,
 * which the caller detects and hands to the general path).
 */
#define DEFINE_FAST_GRADIENTS(NAME, T)                                                 \
    static inline double NAME##_load(const char *p)                                    \
    {                                                                                  \
        T v;                                                                           \
        memcpy(&v, p, sizeof v);                                                       \
        return (double)v;                                                              \
    }                                                                                  \
    static void NAME(const grid *g, const char *p, int a, double f[2], double gr[2][3]) \
    {                                                                                  \
        const int64_t sx = g->st[0], sy = g->st[1], sz = g->st[2];                     \
        const char *q = p + g->st[a];                                                  \
        const double f0 = NAME##_load(p), f1 = NAME##_load(q);                         \
        f[0] = f0;                                                                     \
        f[1] = f1;                                                                     \
        /* along the edge each endpoint is the other's neighbour */                    \
        gr[0][0] = a == 0 ? f1 - NAME##_load(p - sx) : NAME##_load(p + sx) - NAME##_load(p - sx); \
        gr[0][1] = a == 1 ? f1 - NAME##_load(p - sy) : NAME##_load(p + sy) - NAME##_load(p - sy); \
        gr[0][2] = a == 2 ? f1 - NAME##_load(p - sz) : NAME##_load(p + sz) - NAME##_load(p - sz); \
        gr[1][0] = a == 0 ? NAME##_load(q + sx) - f0 : NAME##_load(q + sx) - NAME##_load(q - sx); \
        gr[1][1] = a == 1 ? NAME##_load(q + sy) - f0 : NAME##_load(q + sy) - NAME##_load(q - sy); \
        gr[1][2] = a == 2 ? NAME##_load(q + sz) - f0 : NAME##_load(q + sz) - NAME##_load(q - sz); \
        for (int c = 0; c < 3; c++) {                                                  \
            gr[0][c] *= g->inv2h[c];                                                   \
            gr[1][c] *= g->inv2h[c];                                                   \
        }                                                                              \
    }
DEFINE_FAST_GRADIENTS(fast_gradients_u8, uint8_t)
DEFINE_FAST_GRADIENTS(fast_gradients_i8, int8_t)
DEFINE_FAST_GRADIENTS(fast_gradients_u16, uint16_t)
DEFINE_FAST_GRADIENTS(fast_gradients_i16, int16_t)
DEFINE_FAST_GRADIENTS(fast_gradients_i32, int32_t)
DEFINE_FAST_GRADIENTS(fast_gradients_f32, float)
DEFINE_FAST_GRADIENTS(fast_gradients_f64, double)

static int fast_gradients(const grid *g, int64_t i, int64_t j, int64_t k, int a, double f[2],
                          double gr[2][3])
{
    /* Both endpoints and their neighbours must lie inside the volume. */
    if (i < g->inner_lo[0] || j < g->inner_lo[1] || k < g->inner_lo[2] ||
        i + (a == 0) > g->inner_hi[0] || j + (a == 1) > g->inner_hi[1] ||
        k + (a == 2) > g->inner_hi[2])
        return 0;
    const char *p = g->data + (i - g->pad) * g->st[0] + (j - g->pad) * g->st[1] +
                    (k - g->pad) * g->st[2];
    switch (g->type) {
    case ISOMEND_U8: fast_gradients_u8(g, p, a, f, gr); break;
    case ISOMEND_I8: fast_gradients_i8(g, p, a, f, gr); break;
    case ISOMEND_U16: fast_gradients_u16(g, p, a, f, gr); break;
    case ISOMEND_I16: fast_gradients_i16(g, p, a, f, gr); break;
    case ISOMEND_I32: fast_gradients_i32(g, p, a, f, gr); break;
    case ISOMEND_F32: fast_gradients_f32(g, p, a, f, gr); break;
    case ISOMEND_F64: fast_gradients_f64(g, p, a, f, gr); break;
    }
    return 1;
}

/* Computes the vertex on the edge along axis a from marched sample (i, j, k). */
static void make_vertex(const grid *g, int flip, int64_t i, int64_t j, int64_t k, int a,
                        float *pos, float *nrm)
{
    int64_t p0[3] = {i, j, k}, p1[3] = {i, j, k};
    p1[a]++;
    double f[2] = {0.0, 0.0}, gr[2][3];
    int have_gradients = 0;
    if (nrm && fast_gradients(g, i, j, k, a, f, gr)) {
        have_gradients = 1;
    } else {
        f[0] = fetch(g, p0[0], p0[1], p0[2]);
        f[1] = fetch(g, p1[0], p1[1], p1[2]);
    }
    const int valid = !isnan(f[0]) && !isnan(f[1]);
    const int inside0 = f[0] >= g->iso; /* NaN: outside */
    const double t = valid ? (g->iso - f[0]) / (f[1] - f[0]) : 0.5;
    for (int c = 0; c < 3; c++) {
        double x = (double)p0[c] + (c == a ? t : 0.0);
        pos[c] = (float)(g->o[c] + x * g->h[c]);
    }
    if (!nrm)
        return;
    double n[3] = {0, 0, 0}, len = 0.0;
    if (valid) {
        if (have_gradients) {
            for (int c = 0; c < 3; c++)
                n[c] = -((1.0 - t) * gr[0][c] + t * gr[1][c]);
            len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        }
        if (!have_gradients || !isfinite(len)) { /* near the border, NaN or padding: one-sided differences */
            for (int c = 0; c < 3; c++) {
                double g0 = gradient_component(g, p0, c, f[0]);
                double g1 = gradient_component(g, p1, c, f[1]);
                n[c] = -((1.0 - t) * g0 + t * g1);
            }
            len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        }
    }
    if (!(len > 0.0) || !isfinite(len)) {
        /* Edge direction, from the inside endpoint towards the outside one. */
        n[0] = n[1] = n[2] = 0.0;
        n[a] = inside0 ? 1.0 : -1.0;
        len = 1.0;
    }
    const double scale = (flip ? -1.0 : 1.0) / len;
    for (int c = 0; c < 3; c++)
        nrm[c] = (float)(scale * n[c]);
}

/*
 * The vertex between two marched samples p0 and p1 that are not necessarily
 * on a grid edge (the face diagonals of the tetrahedral method), by the
 * general path: p0 + t (p1 - p0), NaN/padding ends cut at the middle.
 */
static void make_vertex_between(const grid *g, int flip, const int64_t p0[3], const int64_t p1[3],
                                float *pos, float *nrm)
{
    const double f0 = fetch(g, p0[0], p0[1], p0[2]), f1 = fetch(g, p1[0], p1[1], p1[2]);
    const int valid = !isnan(f0) && !isnan(f1);
    const double t = valid ? (g->iso - f0) / (f1 - f0) : 0.5;
    for (int c = 0; c < 3; c++)
        pos[c] = (float)(g->o[c] + ((double)p0[c] + t * (double)(p1[c] - p0[c])) * g->h[c]);
    if (!nrm)
        return;
    double n[3] = {0, 0, 0}, len = 0.0;
    if (valid) {
        for (int c = 0; c < 3; c++)
            n[c] = -((1.0 - t) * gradient_component(g, p0, c, f0) +
                     t * gradient_component(g, p1, c, f1));
        len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    if (!(len > 0.0) || !isfinite(len)) {
        const double sign = f0 >= g->iso ? 1.0 : -1.0; /* towards the outside end */
        for (int c = 0; c < 3; c++)
            n[c] = sign * (double)(p1[c] - p0[c]) * g->h[c];
        len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    const double scale = (flip ? -1.0 : 1.0) / len;
    for (int c = 0; c < 3; c++)
        nrm[c] = (float)(scale * n[c]);
}

/* ------------------------------------------------------- the extraction */

/* The transparent huge page of x86-64 (and of arm64 with 4 KiB pages). */
#define HUGE_PAGE ((size_t)2 << 20)

/* size rounded up to whole huge pages. */
static size_t huge_round(size_t size)
{
    return (size + HUGE_PAGE - 1) & ~(HUGE_PAGE - 1);
}

typedef struct ctx {
    grid g;
    isomend_method method;
    int flip;
    int want_normals;
    int want_origins;
    int small_pages;       /* ISOMEND_FLAG_SMALL_PAGES: no huge pages asked for */
    int vertex4;           /* vertices four at a time (AVX2, with normals)  */
    int64_t nchunks;
    int64_t chunk_layers;
    uint64_t *slice_first; /* [N2 + 1]: vertex count, then first vertex */
    uint64_t *layer_first; /* [N2]: triangle count, then first triangle */
    uint64_t *layer_private; /* [N2]: cube-private vertices (methods.h), then first */
    int general;           /* a method of methods.h: per-cube hook        */
    int tetra;             /* ... with face-diagonal vertices             */
    int planes;            /* id-map planes per slice: 3, or 6 for tetra  */
    uint64_t *bits;        /* sign cache: the counting pass's signs, 1 bit a */
    rowinfo *rows;         /*   sample, and row spans; NULL when too large   */
    int64_t words;         /*   64-bit words per row                          */
    float *pos, *nrm;
    uint32_t *tri;
    uint8_t *org;
    atomic_llong next_chunk;
    atomic_llong done_chunks;
    atomic_int cancel;
    int pass;
    isomend_progress_fn progress;
    void *progress_user;
    struct split *split;   /* the one pass on two threads (run_one_pass)    */
    uint64_t apart_v, apart_t; /* one pass: the arrays have room past these for
                                * a split apart (split_apart), or 0          */
    isomend_mesh *recycled; /* isomend_extract_recycle's old mesh, until used */
} ctx;

/* Sign slices a worker holds: a layer's three (k, k + 1 and k + 2 for the
 * +z neighbours), and in the one-pass path the next, read ahead. */
enum { SIGN_RING = 4 };

typedef struct worker {
    ctx *c;
    uint8_t *sg[SIGN_RING]; /* sign slices, ring indexed by k % SIGN_RING */
    rowinfo *ri[SIGN_RING]; /* their rows' spans                          */
    uint64_t nan[SIGN_RING]; /* NaN samples of the slice                  */
    int64_t sk[SIGN_RING];  /* slice held, -1 none                        */
    uint32_t *map[2]; /* vertex ids of edges x, y, z; ring k % 2 */
    uint8_t *cases;   /* configurations of one row of cubes */
    struct vitem *vl[3]; /* fill pass: vertices numbered, not yet computed, per axis */
    void *block;      /* the arrays above, in one scratch_alloc block */
    size_t vn[3];
    uint64_t private_count; /* cube-private vertices of the layer (methods.h) */
    uint64_t private_next;  /* next cube-private vertex id (fill pass)       */
    isomend_stats stats;
    int is_main;
} worker;

/* 8 sign bytes (0/1, memory order) -> 8 bits, bit i = byte i. */
static inline uint64_t pack8(uint64_t w)
{
    return (w * UINT64_C(0x0102040810204080)) >> 56;
}

/* 8 bits -> 8 sign bytes (0/1), byte i = bit i, as a little-endian word. */
static inline uint64_t unpack8(uint64_t x)
{
    const uint64_t m = UINT64_C(0x7F7F7F7F7F7F7F7F);
    uint64_t t = (x * UINT64_C(0x0101010101010101)) & UINT64_C(0x8040201008040201);
    return (((((t & m) + m) | t) & ~m) >> 7);
}

static inline void store8(uint8_t *p, uint64_t v)
{
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    v = __builtin_bswap64(v);
#endif
    memcpy(p, &v, sizeof v);
}

static inline uint64_t load8(const uint8_t *p);

/* Saves slice k's signs (held by the worker) in the sign cache. */
static void cache_store(worker *w, int64_t k)
{
    const ctx *c = w->c;
    const int64_t N0 = c->g.N[0], N1 = c->g.N[1];
    const int r = (int)(k % SIGN_RING);
    for (int64_t j = 0; j < N1; j++) {
        const rowinfo *ri = &w->ri[r][j];
        c->rows[k * N1 + j] = *ri;
        if (ri->lo >= N0 || ri->simple)
            continue; /* uniform or one run: the span says it all */
        const uint8_t *s = w->sg[r] + j * N0;
        uint64_t *b = c->bits + (k * N1 + j) * c->words;
        for (int64_t q = 0; q < c->words; q++) {
            uint64_t word = 0;
            for (int64_t h = 0; h < 8; h++) {
                const int64_t i = 64 * q + 8 * h;
                if (i >= N0)
                    break;
                uint64_t v = N0 - i >= 8 ? load8(s + i) : 0;
                if (N0 - i < 8)
                    for (int64_t x = 0; x < N0 - i; x++)
                        v |= (uint64_t)s[i + x] << (8 * x);
                word |= pack8(v) << (8 * h);
            }
            b[q] = word;
        }
    }
}

/* Refills slice k from the sign cache. */
static void cache_load(worker *w, int64_t k, int r)
{
    const ctx *c = w->c;
    const int64_t N0 = c->g.N[0], N1 = c->g.N[1];
    for (int64_t j = 0; j < N1; j++) {
        const rowinfo *ri = &c->rows[k * N1 + j];
        uint8_t *s = w->sg[r] + j * N0;
        w->ri[r][j] = *ri;
        if (ri->lo >= N0) {
            memset(s, ri->first, (size_t)N0);
            continue;
        }
        if (ri->simple) {
            memset(s, ri->first, (size_t)N0);
            memset(s + ri->lo, ri->first ^ 1, (size_t)(ri->hi - ri->lo + 1));
            continue;
        }
        const uint64_t *b = c->bits + (k * N1 + j) * c->words;
        for (int64_t i = 0; i < N0; i += 8) /* writes up to 7 bytes of slack past N0 */
            store8(s + i, unpack8((b[i >> 6] >> (i & 63)) & 0xFF));
    }
}

static const uint8_t *signs(worker *w, int64_t k, const rowinfo **ri)
{
    const grid *g = &w->c->g;
    int r = (int)(k % SIGN_RING);
    if (w->sk[r] != k) {
        if (w->c->pass == 2 && w->c->bits) {
            cache_load(w, k, r);
        } else {
            uint64_t nans = 0;
            for (int64_t j = 0; j < g->N[1]; j++)
                classify_row(g, j, k, w->sg[r] + j * g->N[0], &w->ri[r][j],
                             w->c->pass == 1 ? &nans : NULL);
            w->nan[r] = nans;
        }
        w->sk[r] = k;
    }
    *ri = w->ri[r];
    return w->sg[r];
}

/*
 * Scanning 16 sign bytes (or cube configurations) per step (SSE2, or two
 * 64-bit words), so long stretches without a crossing cost a compare.  Buffers
 * carry SCAN_PAD bytes of slack for the reads past a row's last column.
 */
#define SCAN_PAD 32

static inline uint64_t load8(const uint8_t *p)
{
    uint64_t v;
    memcpy(&v, p, sizeof v);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    v = __builtin_bswap64(v);
#endif
    return v;
}

/* Bit x set when a[x] != b[x], x in 0..15. */
static inline uint32_t diff16(const uint8_t *a, const uint8_t *b)
{
#if defined(__SSE2__) && !defined(ISOMEND_NO_SIMD)
    const __m128i va = _mm_loadu_si128((const __m128i *)(const void *)a);
    const __m128i vb = _mm_loadu_si128((const __m128i *)(const void *)b);
    return (uint32_t)_mm_movemask_epi8(_mm_cmpeq_epi8(va, vb)) ^ 0xFFFFu;
#else
    const uint64_t m = UINT64_C(0x0101010101010101);
    return (uint32_t)(((load8(a) ^ load8(b)) & m) * UINT64_C(0x0102040810204080) >> 56) |
           (uint32_t)(((load8(a + 8) ^ load8(b + 8)) & m) * UINT64_C(0x0102040810204080) >> 56) << 8;
#endif
}

/* Bit x set when cube configuration c[x] is neither 0 nor 255, x in 0..15. */
static inline uint32_t mixed16(const uint8_t *c)
{
#if defined(__SSE2__) && !defined(ISOMEND_NO_SIMD)
    const __m128i v = _mm_loadu_si128((const __m128i *)(const void *)c);
    const __m128i trivial = _mm_or_si128(_mm_cmpeq_epi8(v, _mm_setzero_si128()),
                                         _mm_cmpeq_epi8(v, _mm_set1_epi8(-1)));
    return (uint32_t)_mm_movemask_epi8(trivial) ^ 0xFFFFu;
#else
    uint32_t r = 0;
    for (int x = 0; x < 16; x++)
        r |= (uint32_t)(c[x] != 0 && c[x] != 255) << x;
    return r;
#endif
}

/* The configuration of cube i between rows r0, r1 (slice k) and r2, r3 (slice k + 1). */
#define CUBE_CASE(r0, r1, r2, r3, i)                                                   \
    ((unsigned)(r0)[i] | (unsigned)(r0)[(i) + 1] << 1 | (unsigned)(r1)[i] << 2 |       \
     (unsigned)(r1)[(i) + 1] << 3 | (unsigned)(r2)[i] << 4 | (unsigned)(r2)[(i) + 1] << 5 | \
     (unsigned)(r3)[i] << 6 | (unsigned)(r3)[(i) + 1] << 7)

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
#if defined(__SSE2__) && !defined(ISOMEND_NO_SIMD)
#define LD16(p) _mm_loadu_si128((const __m128i *)(const void *)(p))
    const __m128i v = _mm_or_si128(
        _mm_or_si128(_mm_or_si128(LD16(a), _mm_slli_epi16(LD16(a + 1), 1)),
                     _mm_or_si128(_mm_slli_epi16(LD16(b), 2), _mm_slli_epi16(LD16(b + 1), 3))),
        _mm_or_si128(_mm_or_si128(_mm_slli_epi16(LD16(c), 4), _mm_slli_epi16(LD16(c + 1), 5)),
                     _mm_or_si128(_mm_slli_epi16(LD16(d), 6), _mm_slli_epi16(LD16(d + 1), 7))));
#undef LD16
    _mm_storeu_si128((__m128i *)(void *)out, v);
    const __m128i trivial = _mm_or_si128(_mm_cmpeq_epi8(v, _mm_setzero_si128()),
                                         _mm_cmpeq_epi8(v, _mm_set1_epi8(-1)));
    return (uint32_t)_mm_movemask_epi8(trivial) ^ 0xFFFFu;
#else
    uint32_t r = 0;
    for (int x = 0; x < 16; x++) {
        out[x] = (uint8_t)CUBE_CASE(a, b, c, d, x);
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


/*
 * Vertices.  The samples around a vertex lie in four slices and four rows,
 * which the volume pass long ago evicted from the caches.  Where a row has
 * many crossings (a wide span) its vertices are computed at once, in row
 * order, and the hardware prefetcher follows the rows.  Where it has a few
 * (narrow spans: the rim of a blob) they are isolated lines the hardware
 * does not foresee: on the 256^3 sphere 60 % of the vertex time was one
 * load's latency.  Those crossings are numbered and listed per axis as
 * (id, column, row), and the lists are computed in bulk, each item
 * prefetching the samples of the item VERTEX_PREFETCH places ahead when it
 * lies off its predecessor's cache line.  Ids are fixed at numbering, so the
 * order of computation changes nothing.
 *
 * The computation is specialised per voxel type and axis: typed loads, the
 * interior test done per vertex.  Vertices near the border, next to NaN or
 * padding take the general path (make_vertex); both compute
 * t = (iso - f0) / (f1 - f0) and the position in the same way.
 */
typedef struct vitem {
    uint32_t id;
    int32_t x, j; /* the edge's lower end: column and row; the slice is the list's */
} vitem;

enum {
    VERTEX_LIST = 2048,   /* items the lists hold before they are computed (plus a row) */
    VERTEX_PREFETCH = 6,  /* prefetch distance, in items (4-8 measured alike)          */
    LIST_SPAN = 32,       /* spans narrower than this go to the lists                  */
    NARROW_CUBES = 16,    /* spans of fewer cubes skip row_cases (march_layer)         */
};

static inline void prefetch_at(const char *base, int64_t off)
{
    /* Integer arithmetic: the address may lie outside the volume (a prefetch
     * never faults), and pointer arithmetic there would be undefined. */
    __builtin_prefetch((const void *)((uintptr_t)base + (uintptr_t)off));
}

/* Constants of the vertex loops below, for slice m and edges along AXIS. */
#define VERTEX_SETUP(AXIS)                                                             \
    enum { axis = AXIS };                                                              \
    const grid *g = &c->g;                                                             \
    float *const P = c->pos, *const NR = c->nrm;                                       \
    const int flip = c->flip;                                                          \
    const int64_t sx = g->st[0], sy = g->st[1], sz = g->st[2], sa = g->st[axis];       \
    const int64_t pad = g->pad;                                                        \
    const int slice_inner = m >= g->inner_lo[2] && m + (axis == 2) <= g->inner_hi[2];  \
    const int64_t x_lo = g->inner_lo[0], x_hi = g->inner_hi[0] - (axis == 0);          \
    const int64_t y_lo = g->inner_lo[1], y_hi = g->inner_hi[1] - (axis == 1);          \
    /* integer arithmetic: with padding, slice m - pad may be -1 */                   \
    const char *slice = (const char *)((uintptr_t)g->data + (uintptr_t)((m - pad) * sz)); \
    const double iso = g->iso, ox = g->o[0], hx = g->h[0];                             \
    const double oy = g->o[1], hy = g->h[1], oz = g->o[2], hz = g->h[2];               \
    const double pz0 = (double)m;                                                      \
    const float fz = (float)(oz + pz0 * hz);                                           \
    const double ix = g->inv2h[0], iy = g->inv2h[1], iz = g->inv2h[2];                 \
    const double sgn = flip ? -1.0 : 1.0

/* Computes vertex `id` on the edge from (x, j, m) along the axis. */
#define VERTEX_ONE(LD, X, J, ID)                                                       \
    do {                                                                               \
        const int64_t x = (X), j = (J);                                                \
        float *pos = P + 3 * (ID), *nrm = NR ? NR + 3 * (ID) : NULL;                   \
        if (slice_inner && j >= y_lo && j <= y_hi && x >= x_lo && x <= x_hi) {         \
            const char *p = slice + (x - pad) * sx + (j - pad) * sy, *q = p + sa;      \
            const double f0 = LD(p), f1 = LD(q);                                       \
            const double t = (iso - f0) / (f1 - f0);                                   \
            double n0 = 0, n1 = 0, n2 = 0, len = 1.0;                                  \
            if (nrm) {                                                                 \
                const double u = 1.0 - t;                                              \
                n0 = -(u * ((axis == 0 ? f1 : LD(p + sx)) - LD(p - sx)) +              \
                       t * (LD(q + sx) - (axis == 0 ? f0 : LD(q - sx)))) * ix;         \
                n1 = -(u * ((axis == 1 ? f1 : LD(p + sy)) - LD(p - sy)) +              \
                       t * (LD(q + sy) - (axis == 1 ? f0 : LD(q - sy)))) * iy;         \
                n2 = -(u * ((axis == 2 ? f1 : LD(p + sz)) - LD(p - sz)) +              \
                       t * (LD(q + sz) - (axis == 2 ? f0 : LD(q - sz)))) * iz;         \
                len = sqrt(n0 * n0 + n1 * n1 + n2 * n2);                               \
            }                                                                          \
            if (t >= 0.0 && t <= 1.0 && len > 0.0 && len < INFINITY) {                 \
                pos[0] = (float)(ox + ((double)x + (axis == 0 ? t : 0.0)) * hx);       \
                pos[1] = (float)(oy + ((double)j + (axis == 1 ? t : 0.0)) * hy);       \
                pos[2] = axis == 2 ? (float)(oz + (pz0 + t) * hz) : fz;                \
                if (nrm) {                                                             \
                    const double sc = sgn / len;                                       \
                    nrm[0] = (float)(sc * n0);                                         \
                    nrm[1] = (float)(sc * n1);                                         \
                    nrm[2] = (float)(sc * n2);                                         \
                }                                                                      \
                break;                                                                 \
            }                                                                          \
        }                                                                              \
        make_vertex(g, flip, x, j, m, axis, pos, nrm);                                 \
    } while (0)

/* Numbers and computes the vertices of one row's crossings in [from, to]. */
#define DEFINE_ROW_VERTICES(NAME, LD, AXIS)                                            \
    static uint64_t NAME(const ctx *c, const uint8_t *a, const uint8_t *b, int64_t from, \
                         int64_t to, int64_t j0, int64_t m, uint32_t *ids, uint64_t id) \
    {                                                                                  \
        VERTEX_SETUP(AXIS);                                                            \
        for (int64_t i = from; i <= to; i += 16) {                                     \
            uint32_t diff = diff16(a + i, b + i);                                      \
            if (to - i < 15)                                                           \
                diff = first_bits(diff, to - i + 1);                                   \
            while (diff) {                                                             \
                const int64_t col = i + __builtin_ctz(diff);                           \
                diff &= diff - 1;                                                      \
                VERTEX_ONE(LD, col, j0, id);                                           \
                ids[col] = (uint32_t)id++;                                             \
            }                                                                          \
        }                                                                              \
        return id;                                                                     \
    }

/*
 * In a vertex loop: prefetches the samples list item it[e] will read, unless
 * it lies on its predecessor's cache line (`line`: samples a line).
 */
#define PREFETCH_ITEM(it, e)                                                           \
    do {                                                                               \
        if ((e) > 0 && (it)[e].j == (it)[(e) - 1].j && (it)[e].x - (it)[(e) - 1].x < line) \
            break;                                                                     \
        const int64_t o = ((int64_t)(it)[e].x - pad) * sx + ((int64_t)(it)[e].j - pad) * sy; \
        prefetch_at(slice, o);                                                         \
        prefetch_at(slice, o + sa);                                                    \
        if (NR) {                                                                      \
            prefetch_at(slice, o - sy);                                                \
            prefetch_at(slice, o + (axis == 1 ? 2 : 1) * sy);                          \
            prefetch_at(slice, o - sz);                                                \
            prefetch_at(slice, o + (axis == 2 ? 2 : 1) * sz);                          \
            if (axis == 1) {                                                           \
                prefetch_at(slice, o + sy - sz);                                       \
                prefetch_at(slice, o + sy + sz);                                       \
            } else if (axis == 2) {                                                    \
                prefetch_at(slice, o + sz - sy);                                       \
                prefetch_at(slice, o + sz + sy);                                       \
            }                                                                          \
        }                                                                              \
    } while (0)

/*
 * Computes listed vertices, prefetching the samples of the item
 * VERTEX_PREFETCH places ahead when it lies off its predecessor's cache line.
 */
#define DEFINE_LIST_VERTICES(NAME, LD, T, AXIS)                                        \
    static void NAME(const ctx *c, const vitem *it, size_t n, int64_t m)               \
    {                                                                                  \
        VERTEX_SETUP(AXIS);                                                            \
        const size_t ahead = slice_inner ? VERTEX_PREFETCH : 0; /* 0: no prefetching */ \
        const int32_t line = 64 / (int32_t)sizeof(T); /* samples a cache line */       \
        /* Step e prefetches item e and computes item e - ahead. */                    \
        for (size_t e = 0; e < n + ahead; e++) {                                       \
            if (ahead && e < n)                                                        \
                PREFETCH_ITEM(it, e);                                                  \
            if (e >= ahead) {                                                          \
                const vitem *v = &it[e - ahead];                                       \
                VERTEX_ONE(LD, v->x, v->j, v->id);                                     \
            }                                                                          \
        }                                                                              \
    }
#define DEFINE_LIST_LOAD(NAME, T)                                                      \
    static inline double NAME##_ld(const char *p)                                      \
    {                                                                                  \
        T v;                                                                           \
        memcpy(&v, p, sizeof v);                                                       \
        return (double)v;                                                              \
    }                                                                                  \
    DEFINE_LIST_VERTICES(NAME##_l0, NAME##_ld, T, 0)                                   \
    DEFINE_LIST_VERTICES(NAME##_l1, NAME##_ld, T, 1)                                   \
    DEFINE_LIST_VERTICES(NAME##_l2, NAME##_ld, T, 2)                                   \
    DEFINE_ROW_VERTICES(NAME##_r0, NAME##_ld, 0)                                       \
    DEFINE_ROW_VERTICES(NAME##_r1, NAME##_ld, 1)                                       \
    DEFINE_ROW_VERTICES(NAME##_r2, NAME##_ld, 2)
DEFINE_LIST_LOAD(list_vertices_u8, uint8_t)
DEFINE_LIST_LOAD(list_vertices_i8, int8_t)
DEFINE_LIST_LOAD(list_vertices_u16, uint16_t)
DEFINE_LIST_LOAD(list_vertices_i16, int16_t)
DEFINE_LIST_LOAD(list_vertices_i32, int32_t)
DEFINE_LIST_LOAD(list_vertices_f32, float)
DEFINE_LIST_LOAD(list_vertices_f64, double)

#if ISOMEND_VERTEX4
/*
 * Four vertices at a time, on machines with AVX2, when normals are wanted
 * (the arithmetic is then most of a vertex's cost: 171 instructions a vertex
 * on the gyroid 256^3 for the scalar path, 112 this way).  The lanes do
 * VERTEX_ONE's operations in its order on doubles, with no fused
 * multiply-add, so the mesh is bit for bit the scalar path's (the test
 * core_simd_identical compares them on every sample type).  Four interior
 * vertices that all come out valid are stored at once; otherwise the four
 * take VERTEX_ONE.  Rows of a wide span group their crossings in column order,
 * lists group consecutive items.
 */

/* Four (x, y, z) float lanes to four consecutive triples at out[0..11]. */
__attribute__((target("avx2"))) static inline void store_xyz4(float *out, __m128 x, __m128 y,
                                                              __m128 z)
{
    __m128 w = _mm_setzero_ps();
    _MM_TRANSPOSE4_PS(x, y, z, w); /* rows: (x_l, y_l, z_l, 0) */
    _mm_storeu_ps(out, x);
    _mm_storeu_ps(out + 3, y); /* each store's fourth float is overwritten */
    _mm_storeu_ps(out + 6, z); /* by the next, and the last is kept out    */
    _mm_storel_pi((__m64 *)(void *)(out + 9), w);
    _mm_store_ss(out + 11, _mm_movehl_ps(w, w));
}

/*
 * Four samples of type T as doubles, converted in one instruction: integers
 * through 32-bit lanes, floats through single-precision lanes (both exact,
 * as the scalar conversions are).
 */
#define DEFINE_LD4(NAME, T)                                                            \
    __attribute__((target("avx2"))) static inline __m256d NAME(                        \
        const char *p0, const char *p1, const char *p2, const char *p3)                \
    {                                                                                  \
        T v0, v1, v2, v3;                                                              \
        memcpy(&v0, p0, sizeof v0);                                                    \
        memcpy(&v1, p1, sizeof v1);                                                    \
        memcpy(&v2, p2, sizeof v2);                                                    \
        memcpy(&v3, p3, sizeof v3);                                                    \
        if ((T)0.5 == 0) /* an integer type */                                         \
            return _mm256_cvtepi32_pd(                                                 \
                _mm_setr_epi32((int32_t)v0, (int32_t)v1, (int32_t)v2, (int32_t)v3));   \
        if (sizeof(T) == sizeof(float))                                                \
            return _mm256_cvtps_pd(_mm_setr_ps((float)v0, (float)v1, (float)v2, (float)v3)); \
        return _mm256_setr_pd((double)v0, (double)v1, (double)v2, (double)v3);         \
    }

/* Sample at byte offset `off` from each lane's lower endpoint, as doubles. */
#define LD4(LD, off) LD(p0 + (off), p1 + (off), p2 + (off), p3 + (off))

/* Gradient component along axis C at the four vertices: VERTEX_ONE's n_C. */
#define GRADIENT4(LD, C, S, INV)                                                       \
    _mm256_mul_pd(                                                                     \
        _mm256_xor_pd(                                                                 \
            _mm256_add_pd(                                                             \
                _mm256_mul_pd(u, axis == (C) ? _mm256_sub_pd(f1, LD4(LD, -(S)))        \
                                             : _mm256_sub_pd(LD4(LD, S), LD4(LD, -(S)))), \
                _mm256_mul_pd(t, axis == (C) ? _mm256_sub_pd(LD4(LD, sa + (S)), f0)    \
                                             : _mm256_sub_pd(LD4(LD, sa + (S)),        \
                                                             LD4(LD, sa - (S))))),     \
            negz),                                                                     \
        _mm256_set1_pd(INV))

/*
 * The four vertices on the edges from (xs[l], js[l], m) along the axis, all
 * interior: position (px, py, pz) and normal (nx, ny, nz) lanes; vertex4_ok
 * is set when all four are valid (VERTEX_ONE's test), else nothing is kept.
 */
#define VERTEX4(LD, xs, js)                                                            \
    const char *p0 = slice + ((xs)[0] - pad) * sx + ((js)[0] - pad) * sy;              \
    const char *p1 = slice + ((xs)[1] - pad) * sx + ((js)[1] - pad) * sy;              \
    const char *p2 = slice + ((xs)[2] - pad) * sx + ((js)[2] - pad) * sy;              \
    const char *p3 = slice + ((xs)[3] - pad) * sx + ((js)[3] - pad) * sy;              \
    const __m256d negz = _mm256_set1_pd(-0.0);                                         \
    const __m256d f0 = LD4(LD, 0), f1 = LD4(LD, sa);                                   \
    const __m256d t = _mm256_div_pd(_mm256_sub_pd(_mm256_set1_pd(iso), f0),            \
                                    _mm256_sub_pd(f1, f0));                            \
    const __m256d u = _mm256_sub_pd(_mm256_set1_pd(1.0), t);                           \
    const __m256d n0 = GRADIENT4(LD, 0, sx, ix);                                       \
    const __m256d n1 = GRADIENT4(LD, 1, sy, iy);                                       \
    const __m256d n2 = GRADIENT4(LD, 2, sz, iz);                                       \
    const __m256d len = _mm256_sqrt_pd(_mm256_add_pd(                                  \
        _mm256_add_pd(_mm256_mul_pd(n0, n0), _mm256_mul_pd(n1, n1)), _mm256_mul_pd(n2, n2))); \
    const __m256d zero = _mm256_setzero_pd();                                          \
    const __m256d valid = _mm256_and_pd(                                               \
        _mm256_and_pd(_mm256_cmp_pd(t, zero, _CMP_GE_OQ),                              \
                      _mm256_cmp_pd(t, _mm256_set1_pd(1.0), _CMP_LE_OQ)),              \
        _mm256_and_pd(_mm256_cmp_pd(len, zero, _CMP_GT_OQ),                            \
                      _mm256_cmp_pd(len, _mm256_set1_pd(INFINITY), _CMP_LT_OQ)));      \
    const int vertex4_ok = _mm256_movemask_pd(valid) == 0xF;                           \
    __m256d xd = _mm256_cvtepi32_pd(                                                   \
        _mm_setr_epi32((int)(xs)[0], (int)(xs)[1], (int)(xs)[2], (int)(xs)[3]));       \
    __m256d yd = _mm256_cvtepi32_pd(                                                   \
        _mm_setr_epi32((int)(js)[0], (int)(js)[1], (int)(js)[2], (int)(js)[3]));       \
    if (axis == 0)                                                                     \
        xd = _mm256_add_pd(xd, t);                                                     \
    if (axis == 1)                                                                     \
        yd = _mm256_add_pd(yd, t);                                                     \
    const __m128 px = _mm256_cvtpd_ps(                                                 \
        _mm256_add_pd(_mm256_set1_pd(ox), _mm256_mul_pd(xd, _mm256_set1_pd(hx))));     \
    const __m128 py = _mm256_cvtpd_ps(                                                 \
        _mm256_add_pd(_mm256_set1_pd(oy), _mm256_mul_pd(yd, _mm256_set1_pd(hy))));     \
    const __m128 pz =                                                                  \
        axis == 2 ? _mm256_cvtpd_ps(_mm256_add_pd(                                     \
                        _mm256_set1_pd(oz),                                            \
                        _mm256_mul_pd(_mm256_add_pd(_mm256_set1_pd(pz0), t), _mm256_set1_pd(hz)))) \
                  : _mm_set1_ps(fz);                                                   \
    const __m256d sc = _mm256_div_pd(_mm256_set1_pd(sgn), len);                        \
    const __m128 nx = _mm256_cvtpd_ps(_mm256_mul_pd(sc, n0));                          \
    const __m128 ny = _mm256_cvtpd_ps(_mm256_mul_pd(sc, n1));                          \
    const __m128 nz = _mm256_cvtpd_ps(_mm256_mul_pd(sc, n2))

/* The wide-span rows (DEFINE_ROW_VERTICES), four crossings at a time. */
#define DEFINE_ROW_VERTICES4(NAME, LD, LDV, AXIS)                                      \
    __attribute__((target("avx2"))) static uint64_t NAME(                              \
        const ctx *c, const uint8_t *a, const uint8_t *b, int64_t from, int64_t to,    \
        int64_t j0, int64_t m, uint32_t *ids, uint64_t id)                             \
    {                                                                                  \
        VERTEX_SETUP(AXIS);                                                            \
        const int row_inner = NR && slice_inner && j0 >= y_lo && j0 <= y_hi;           \
        const int64_t js[4] = {j0, j0, j0, j0};                                        \
        int64_t pend[16 + 3]; /* crossings not yet computed, in column order */        \
        int np = 0;                                                                    \
        for (int64_t i = from; i <= to; i += 16) {                                     \
            uint32_t diff = diff16(a + i, b + i);                                      \
            if (to - i < 15)                                                           \
                diff = first_bits(diff, to - i + 1);                                   \
            while (diff) {                                                             \
                pend[np++] = i + __builtin_ctz(diff);                                  \
                diff &= diff - 1;                                                      \
            }                                                                          \
            int g4 = 0;                                                                \
            for (; np - g4 >= 4; g4 += 4, id += 4) {                                   \
                const int64_t *x4 = pend + g4;                                         \
                int done = 0;                                                          \
                if (row_inner && x4[0] >= x_lo && x4[3] <= x_hi) {                     \
                    VERTEX4(LDV, x4, js);                                              \
                    if (vertex4_ok) {                                                  \
                        store_xyz4(P + 3 * id, px, py, pz);                            \
                        store_xyz4(NR + 3 * id, nx, ny, nz);                           \
                        done = 1;                                                      \
                    }                                                                  \
                }                                                                      \
                for (int l = 0; l < 4; l++) {                                          \
                    if (!done)                                                         \
                        VERTEX_ONE(LD, x4[l], j0, id + (uint64_t)l);                   \
                    ids[x4[l]] = (uint32_t)(id + (uint64_t)l);                         \
                }                                                                      \
            }                                                                          \
            if (g4) {                                                                  \
                for (int r = g4; r < np; r++)                                          \
                    pend[r - g4] = pend[r];                                            \
                np -= g4;                                                              \
            }                                                                          \
        }                                                                              \
        for (int r = 0; r < np; r++, id++) {                                           \
            VERTEX_ONE(LD, pend[r], j0, id);                                           \
            ids[pend[r]] = (uint32_t)id;                                               \
        }                                                                              \
        return id;                                                                     \
    }

/* Four (x, y, z) float lanes to the triples of vertices v[0..3].id in out. */
__attribute__((target("avx2"))) static inline void store_items4(float *out, const vitem *v,
                                                                __m128 x, __m128 y, __m128 z)
{
    __m128 w = _mm_setzero_ps();
    _MM_TRANSPOSE4_PS(x, y, z, w); /* rows: (x_l, y_l, z_l, 0) */
    const __m128 row[4] = {x, y, z, w};
    for (int l = 0; l < 4; l++) {
        float *o = out + 3 * (uint64_t)v[l].id;
        _mm_storel_pi((__m64 *)(void *)o, row[l]);
        _mm_store_ss(o + 2, _mm_movehl_ps(row[l], row[l]));
    }
}

/*
 * The lists (DEFINE_LIST_VERTICES), four items at a time, with the same
 * prefetching: a group is computed once its last item was prefetched
 * VERTEX_PREFETCH steps before.  Ids are not consecutive here: each lane is
 * stored on its own (a 16-byte store could reach another thread's vertex).
 */
#define DEFINE_LIST_VERTICES4(NAME, LD, LDV, T, AXIS)                                  \
    __attribute__((target("avx2"))) static void NAME(const ctx *c, const vitem *it, size_t n, \
                                                     int64_t m)                        \
    {                                                                                  \
        VERTEX_SETUP(AXIS);                                                            \
        const size_t ahead = slice_inner ? VERTEX_PREFETCH : 0;                        \
        const int32_t line = 64 / (int32_t)sizeof(T);                                  \
        size_t done = 0;                                                               \
        for (size_t e = 0; e < n + ahead + 3; e++) {                                   \
            if (ahead && e < n)                                                        \
                PREFETCH_ITEM(it, e);                                                  \
            if (e < done + 3 + ahead)                                                  \
                continue;                                                              \
            const size_t left = n - done;                                              \
            if (left == 0)                                                             \
                break;                                                                 \
            const vitem *v = it + done;                                                \
            int ok = 0;                                                                \
            if (left >= 4 && NR && slice_inner) {                                      \
                const int64_t xs[4] = {v[0].x, v[1].x, v[2].x, v[3].x};                \
                const int64_t js[4] = {v[0].j, v[1].j, v[2].j, v[3].j};                \
                int inner = 1;                                                         \
                for (int l = 0; l < 4; l++)                                            \
                    inner &= xs[l] >= x_lo && xs[l] <= x_hi && js[l] >= y_lo && js[l] <= y_hi; \
                if (inner) {                                                           \
                    VERTEX4(LDV, xs, js);                                              \
                    if (vertex4_ok) {                                                  \
                        store_items4(P, v, px, py, pz);                                \
                        store_items4(NR, v, nx, ny, nz);                               \
                        ok = 1;                                                        \
                    }                                                                  \
                }                                                                      \
            }                                                                          \
            const size_t grp = left >= 4 ? 4 : left;                                   \
            if (!ok)                                                                   \
                for (size_t l = 0; l < grp; l++)                                       \
                    VERTEX_ONE(LD, v[l].x, v[l].j, v[l].id);                           \
            done += grp;                                                               \
        }                                                                              \
    }
#define DEFINE_VERTICES4_TYPE(NAME, T)                                                 \
    DEFINE_LD4(NAME##_ld4, T)                                                          \
    DEFINE_ROW_VERTICES4(NAME##_v0, NAME##_ld, NAME##_ld4, 0)                          \
    DEFINE_ROW_VERTICES4(NAME##_v1, NAME##_ld, NAME##_ld4, 1)                          \
    DEFINE_ROW_VERTICES4(NAME##_v2, NAME##_ld, NAME##_ld4, 2)                          \
    DEFINE_LIST_VERTICES4(NAME##_w0, NAME##_ld, NAME##_ld4, T, 0)                      \
    DEFINE_LIST_VERTICES4(NAME##_w1, NAME##_ld, NAME##_ld4, T, 1)                      \
    DEFINE_LIST_VERTICES4(NAME##_w2, NAME##_ld, NAME##_ld4, T, 2)
DEFINE_VERTICES4_TYPE(list_vertices_u8, uint8_t)
DEFINE_VERTICES4_TYPE(list_vertices_i8, int8_t)
DEFINE_VERTICES4_TYPE(list_vertices_u16, uint16_t)
DEFINE_VERTICES4_TYPE(list_vertices_i16, int16_t)
DEFINE_VERTICES4_TYPE(list_vertices_i32, int32_t)
DEFINE_VERTICES4_TYPE(list_vertices_f32, float)
DEFINE_VERTICES4_TYPE(list_vertices_f64, double)
#endif /* ISOMEND_VERTEX4 */

/* [type][axis]: the vertex loops named list_vertices_<type>_<kind><axis>. */
#define VERTEX_LOOPS(K)                                                                \
    {                                                                                  \
        {list_vertices_u8_##K##0, list_vertices_u8_##K##1, list_vertices_u8_##K##2},   \
        {list_vertices_i8_##K##0, list_vertices_i8_##K##1, list_vertices_i8_##K##2},   \
        {list_vertices_u16_##K##0, list_vertices_u16_##K##1, list_vertices_u16_##K##2}, \
        {list_vertices_i16_##K##0, list_vertices_i16_##K##1, list_vertices_i16_##K##2}, \
        {list_vertices_i32_##K##0, list_vertices_i32_##K##1, list_vertices_i32_##K##2}, \
        {list_vertices_f32_##K##0, list_vertices_f32_##K##1, list_vertices_f32_##K##2}, \
        {list_vertices_f64_##K##0, list_vertices_f64_##K##1, list_vertices_f64_##K##2}, \
    }
typedef void (*list_vertices_fn)(const ctx *, const vitem *, size_t, int64_t);
typedef uint64_t (*row_vertices_fn)(const ctx *, const uint8_t *, const uint8_t *, int64_t,
                                    int64_t, int64_t, int64_t, uint32_t *, uint64_t);
static const list_vertices_fn list_vertices[ISOMEND_TYPE_COUNT][3] = VERTEX_LOOPS(l);
static const row_vertices_fn row_vertices[ISOMEND_TYPE_COUNT][3] = VERTEX_LOOPS(r);
#if ISOMEND_VERTEX4
static const list_vertices_fn list_vertices4[ISOMEND_TYPE_COUNT][3] = VERTEX_LOOPS(w);
static const row_vertices_fn row_vertices4[ISOMEND_TYPE_COUNT][3] = VERTEX_LOOPS(v);
#endif

/* The vertex loops of this extraction's type: four at a time where c says so. */
static inline const list_vertices_fn *list_loops(const ctx *c)
{
#if ISOMEND_VERTEX4
    if (c->vertex4)
        return list_vertices4[c->g.type];
#endif
    return list_vertices[c->g.type];
}

static inline const row_vertices_fn *row_loops(const ctx *c)
{
#if ISOMEND_VERTEX4
    if (c->vertex4)
        return row_vertices4[c->g.type];
#endif
    return row_vertices[c->g.type];
}

/* Computes and empties the worker's vertex lists of slice m. */
static void flush_vertices(worker *w, int64_t m)
{
    for (int a = 0; a < 3; a++) {
        if (w->vn[a])
            list_loops(w->c)[a](w->c, w->vl[a], w->vn[a], m);
        w->vn[a] = 0;
    }
}

/*
 * Numbers the vertices on the edges along `axis` from row a (row j of slice
 * m) towards row b: one per column i in [from, to] where a[i] != b[i].  With
 * a list, also appends them to it for flush_vertices.  Returns the next id.
 */
static uint64_t number_crossings(const uint8_t *a, const uint8_t *b, int64_t from, int64_t to,
                                 int64_t j, uint32_t *ids, uint64_t id, vitem *list,
                                 size_t *count)
{
    size_t n = list ? *count : 0;
    for (int64_t i = from; i <= to; i += 16) {
        uint32_t diff = diff16(a + i, b + i);
        if (to - i < 15)
            diff = first_bits(diff, to - i + 1);
        while (diff) {
            const int64_t x = i + __builtin_ctz(diff);
            diff &= diff - 1;
            ids[x] = (uint32_t)id;
            if (list) {
                list[n].id = (uint32_t)id;
                list[n].x = (int32_t)x;
                list[n].j = (int32_t)j;
                n++;
            }
            id++;
        }
    }
    if (list)
        *count = n;
    return id;
}

/*
 * Numbers (and, if `write`, computes) the crossings of a span: a narrow span
 * (the rim of a blob: a few crossings per row) goes to the lists, to be
 * computed with prefetching; a wide one is computed at once, in row order,
 * which the hardware prefetcher follows.
 */
static inline uint64_t crossings(worker *w, const uint8_t *a, const uint8_t *b, int64_t from,
                                 int64_t to, int64_t j, int64_t m, int axis, uint32_t *ids,
                                 uint64_t id, int write)
{
    if (!write)
        return number_crossings(a, b, from, to, j, ids, id, NULL, NULL);
    if (to - from < LIST_SPAN)
        return number_crossings(a, b, from, to, j, ids, id, w->vl[axis], &w->vn[axis]);
    return row_loops(w->c)[axis](w->c, a, b, from, to, j, m, ids, id);
}

/* Number of i in [from, to] with a[i] != b[i]; vectorises. */
ISOMEND_HOT_LOOP static uint64_t count_differences(const uint8_t *restrict a, const uint8_t *restrict b,
                                  int64_t from, int64_t to)
{
    uint32_t n = 0;
    for (int64_t i = from; i <= to; i++)
        n += (uint32_t)(a[i] != b[i]);
    return n;
}

/*
 * The crossings between rows a and b in the n spans span[0..2n).  Exact spans
 * (between one-run rows: row_spans, pair_spans) are crossings in every column,
 * so they are counted, not scanned.
 */
static uint64_t count_spans(const uint8_t *a, const uint8_t *b, const int64_t *span, int n,
                            int exact)
{
    uint64_t count = 0;
    for (int q = 0; q < n; q++)
        count += exact ? (uint64_t)(span[2 * q + 1] - span[2 * q] + 1)
                       : count_differences(a, b, span[2 * q], span[2 * q + 1]);
    return count;
}

/* Configurations of the cubes [from, to] of a row from its four sample rows. */
ISOMEND_HOT_LOOP static void row_cases(const uint8_t *restrict a, const uint8_t *restrict b,
                      const uint8_t *restrict c, const uint8_t *restrict d, int64_t from,
                      int64_t to, uint8_t *restrict cases)
{
    for (int64_t i = from; i <= to; i++)
        cases[i] = (uint8_t)(a[i] | a[i + 1] << 1 | b[i] << 2 | b[i + 1] << 3 | c[i] << 4 |
                             c[i + 1] << 5 | d[i] << 6 | d[i + 1] << 7);
}

/* Linear-index order of two marched samples: is p before q? */
static int sample_before(const int64_t p[3], const int64_t q[3])
{
    if (p[2] != q[2])
        return p[2] < q[2];
    if (p[1] != q[1])
        return p[1] < q[1];
    return p[0] < q[0];
}

/*
 * The tetrahedral method's face diagonals (methods.h, slots 12..17): each
 * face of the grid has the diagonal joining its two corners of even parity
 * (i + j + k even).  Row j of slice m owns the diagonals of the x faces
 * (x = i, y in [j, j+1], z in [m, m+1]), the y faces (y = j, x in [i, i+1],
 * z in [m, m+1]) and the z faces (z = m, x in [i, i+1], y in [j, j+1]) whose
 * lowest corner is (i, j, m).  In counting mode (ids NULL) returns id + the
 * number cut; otherwise numbers them in that order and returns the next id.
 */
static uint64_t scan_diagonals(const ctx *c, const uint8_t *s, const uint8_t *t, int64_t j,
                               int64_t m, uint32_t *ids, uint64_t id, int write)
{
    const grid *g = &c->g;
    const int64_t N0 = g->N[0], N1 = g->N[1], plane = N0 * N1;
    const uint8_t *a = s + j * N0;
    const uint8_t *b = j + 1 < N1 ? a + N0 : NULL;
    const uint8_t *d = t ? t + j * N0 : NULL;
    const uint8_t *e = t && b ? d + N0 : NULL;
    for (int kind = 0; kind < 3; kind++) {
        if ((kind == 0 && !e) || (kind == 1 && !d) || (kind == 2 && !b))
            continue;
        const int64_t last = kind == 0 ? N0 - 1 : N0 - 2;
        for (int64_t i = 0; i <= last; i++) {
            const int even = ((i + j + m) & 1) == 0;
            int64_t p[3], q[3];
            uint8_t sp, sq;
            if (kind == 0) { /* x face: (i,j,m)-(i,j+1,m+1) or (i,j+1,m)-(i,j,m+1) */
                p[0] = q[0] = i;
                p[1] = even ? j : j + 1;
                q[1] = even ? j + 1 : j;
                p[2] = m;
                q[2] = m + 1;
                sp = even ? a[i] : b[i];
                sq = even ? e[i] : d[i];
            } else if (kind == 1) { /* y face: (i,j,m)-(i+1,j,m+1) or (i+1,j,m)-(i,j,m+1) */
                p[1] = q[1] = j;
                p[0] = even ? i : i + 1;
                q[0] = even ? i + 1 : i;
                p[2] = m;
                q[2] = m + 1;
                sp = even ? a[i] : a[i + 1];
                sq = even ? d[i + 1] : d[i];
            } else { /* z face: (i,j,m)-(i+1,j+1,m) or (i+1,j,m)-(i,j+1,m) */
                p[2] = q[2] = m;
                p[0] = even ? i : i + 1;
                q[0] = even ? i + 1 : i;
                p[1] = j;
                q[1] = j + 1;
                sp = even ? a[i] : a[i + 1];
                sq = even ? b[i + 1] : b[i];
            }
            if (sp == sq)
                continue;
            if (ids) {
                const int64_t *lo = sample_before(p, q) ? p : q, *hi = lo == p ? q : p;
                if (write)
                    make_vertex_between(g, c->flip, lo, hi, c->pos + 3 * id,
                                        c->nrm ? c->nrm + 3 * id : NULL);
                ids[(3 + kind) * plane + j * N0 + i] = (uint32_t)id;
            }
            id++;
        }
    }
    return id;
}

/*
 * Numbers the intersected edges whose lower end is in slice m.  mode 0
 * counts them; mode 1 fills the id map (ids from `first`) and, if `write`,
 * the vertices.  Returns the count.
 */
static uint64_t scan_slice(worker *w, int64_t m, int mode, uint64_t first, int write)
{
    const ctx *c = w->c;
    const grid *g = &c->g;
    const int64_t N0 = g->N[0], N1 = g->N[1], N2 = g->N[2];
    const rowinfo *ra, *rn = NULL;
    const uint8_t *t = m + 1 < N2 ? signs(w, m + 1, &rn) : NULL;
    const uint8_t *s = signs(w, m, &ra); /* slots m and m + 1 differ */
    uint32_t *mx = NULL, *my = NULL, *mz = NULL;
    if (mode) {
        mx = w->map[m % 2];
        my = mx + N0 * N1;
        mz = mx + 2 * N0 * N1;
    }
    uint64_t id = first, count = 0;
    for (int64_t j = 0; j < N1; j++) {
        if (c->tetra) { /* rare method: full rows, before the skip below */
            if (mode)
                id = scan_diagonals(c, s, t, j, m, mx, id, write);
            else
                count = scan_diagonals(c, s, t, j, m, NULL, count, 0);
        }
        const uint8_t v = ra[j].first;
        if (uniform_as(&ra[j], N0, v) && (j + 1 >= N1 || uniform_as(&ra[j + 1], N0, v)) &&
            (!t || uniform_as(&rn[j], N0, v)))
            continue; /* uniform, like the rows it pairs with: no crossing */
        const uint8_t *a = s + j * N0;
        int64_t xs[4], ys[4], zs[4];
        const int nx = row_spans(&ra[j], N0, xs);
        const int ny = j + 1 < N1 ? pair_spans(&ra[j], &ra[j + 1], N0, ys) : 0;
        const int nz = t ? pair_spans(&ra[j], &rn[j], N0, zs) : 0;
        if (!nx && !ny && !nz)
            continue;
        const uint8_t *b = a + N0; /* row j + 1, read only when ny */
        const uint8_t *d = nz ? t + j * N0 : NULL;
        if (!mode) {
            count += count_spans(a, a + 1, xs, nx, ra[j].simple);
            count += count_spans(a, b, ys, ny, ny && simple_pair(&ra[j], &ra[j + 1]));
            count += count_spans(a, d, zs, nz, nz && simple_pair(&ra[j], &rn[j]));
            continue;
        }
        /* Vertex order within a row: x edges, then y edges, then z edges. */
        const int64_t at = j * N0;
        if (write && w->vn[0] + w->vn[1] + w->vn[2] > VERTEX_LIST)
            flush_vertices(w, m); /* a row adds at most N0 a list */
        for (int q = 0; q < nx; q++)
            id = crossings(w, a, a + 1, xs[2 * q], xs[2 * q + 1], j, m, 0, mx + at, id, write);
        for (int q = 0; q < ny; q++)
            id = crossings(w, a, b, ys[2 * q], ys[2 * q + 1], j, m, 1, my + at, id, write);
        for (int q = 0; q < nz; q++)
            id = crossings(w, a, d, zs[2 * q], zs[2 * q + 1], j, m, 2, mz + at, id, write);
    }
    if (write)
        flush_vertices(w, m);
    return mode ? id - first : count;
}

/* Prefetches the id-map lines of the twelve cube edges at column i. */
static inline void prefetch_ids(const uint32_t *const ep[12], int64_t i)
{
    for (int e = 0; e < 12; e++)
        __builtin_prefetch(ep[e] + i);
}

/*
 * The columns of cubes of a row (between four sample rows) that can hold a
 * non-empty cube: one interval, or two when the four rows are simple with the
 * same outside sign (the cubes inside all four runs are then empty too).
 * Fills span[0..2n) with n intervals and returns n (0, 1 or 2).
 */
static inline int cube_spans(const rowinfo *r[4], int64_t N0, int64_t span[4])
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

/*
 * One cube of a method of methods.h: asks the hook for its triangles (vertex
 * slots), counts the cube-private vertices they use (mode 0) or numbers and
 * computes those and writes the triangles (mode 1).  Private vertices are
 * derived from the cube's own edge points, recomputed here, so a chunk never
 * reads vertices another thread may still be writing.
 */
static unsigned method_cube(worker *w, int64_t i, int64_t j, int64_t k, unsigned cfg, int mode,
                            const uint32_t *const ep[12], const uint32_t *mk0,
                            const uint32_t *mk1, uint32_t *out, uint8_t *org)
{
    const ctx *c = w->c;
    const grid *g = &c->g;
    methods_cube cube;
    double ring[64];
    for (int q = 0; q < 8; q++)
        cube.v[q] = fetch(g, i + CUBE_CORNER_X(q), j + CUBE_CORNER_Y(q), k + CUBE_CORNER_Z(q));
    cube.iso = g->iso;
    cube.config = cfg;
    cube.parity = (unsigned)((i + j + k) & 1);
    cube.ring = NULL;
    if (methods_needs_ring(c->method)) {
        for (int z = -1; z <= 2; z++)
            for (int y = -1; y <= 2; y++)
                for (int x = -1; x <= 2; x++)
                    ring[(x + 1) + 4 * (y + 1) + 16 * (z + 1)] = fetch(g, i + x, j + y, k + z);
        cube.ring = ring;
    }
    unsigned char slots[3 * METHODS_MAX_TRI];
    int n = isomend_method_cube(c->method, &cube, slots);
    if (n <= 0)
        return 0;
    uint32_t used = 0; /* private slots, bit s - METHODS_SLOT_CENTRE */
    for (int q = 0; q < 3 * n; q++)
        if (slots[q] >= METHODS_SLOT_CENTRE)
            used |= 1u << (slots[q] - METHODS_SLOT_CENTRE);
    if (!mode) {
        w->private_count += (uint64_t)__builtin_popcount(used);
        return (unsigned)n;
    }
    uint32_t ids[METHODS_SLOT_COUNT];
    const int64_t N0 = g->N[0], plane = N0 * g->N[1], at = j * N0 + i;
    for (int q = 0; q < 3 * n; q++) {
        const int sl = slots[q];
        if (sl < 12)
            ids[sl] = ep[sl][i];
        else if (sl < METHODS_SLOT_CENTRE) {
            const int f = sl - METHODS_SLOT_DIAG0;
            static const int diag_plane[6] = {3, 3, 4, 4, 5, 5};
            const int64_t off[6] = {at, at + 1, at, at + N0, at, at};
            ids[sl] = (f == 5 ? mk1 : mk0)[diag_plane[f] * plane + off[f]];
        }
    }
    if (used) {
        /* The cube's edge points, the centre (their mean) and the ring points. */
        float ep_pos[12][3], ep_nrm[12][3], centre[3] = {0, 0, 0}, cn[3] = {0, 0, 0};
        int cut = 0;
        for (int e = 0; e < 12; e++) {
            const int c0 = cube_edge_corner[e][0], c1 = cube_edge_corner[e][1];
            if (((cfg >> c0) & 1) == ((cfg >> c1) & 1))
                continue;
            make_vertex(g, c->flip, i + CUBE_CORNER_X(c0), j + CUBE_CORNER_Y(c0),
                        k + CUBE_CORNER_Z(c0), e / 4, ep_pos[e], c->nrm ? ep_nrm[e] : NULL);
            for (int a = 0; a < 3; a++) {
                centre[a] += ep_pos[e][a];
                cn[a] += c->nrm ? ep_nrm[e][a] : 0.0f;
            }
            cut++;
        }
        for (int a = 0; a < 3; a++)
            centre[a] /= (float)(cut ? cut : 1);
        for (int b = 0; b < METHODS_SLOT_COUNT - METHODS_SLOT_CENTRE; b++) {
            if (!(used & (1u << b)))
                continue;
            const uint64_t id = w->private_next++;
            ids[METHODS_SLOT_CENTRE + b] = (uint32_t)id;
            float *pos = c->pos + 3 * id, *nrm = c->nrm ? c->nrm + 3 * id : NULL;
            double nn[3];
            for (int a = 0; a < 3; a++) {
                if (b == 0) {
                    pos[a] = centre[a];
                    nn[a] = cn[a];
                } else {
                    pos[a] = 0.5f * (centre[a] + ep_pos[b - 1][a]);
                    nn[a] = (double)cn[a] / (cut ? cut : 1) + (double)ep_nrm[b - 1][a];
                }
            }
            if (nrm) {
                double len = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
                for (int a = 0; a < 3; a++)
                    nrm[a] = len > 0.0 ? (float)(nn[a] / len) : (a == 2 ? 1.0f : 0.0f);
            }
        }
    }
    for (int t = 0; t < n; t++) {
        out[3 * t] = ids[slots[3 * t]];
        out[3 * t + 1] = ids[slots[3 * t + (c->flip ? 2 : 1)]];
        out[3 * t + 2] = ids[slots[3 * t + (c->flip ? 1 : 2)]];
        if (org)
            org[t] = ISOMEND_ORIGIN_TABLE;
    }
    return (unsigned)n;
}

/*
 * Marches layer k.  mode 0 counts triangles and statistics; mode 1 writes
 * the triangles from index `first`; mode 2 (the one-pass path, table methods)
 * does both.  `general` is c->general and `flip` c->flip, passed so that
 * march_layer can compile the loop with them as constants.  Returns the
 * number of triangles.
 */
static inline __attribute__((always_inline)) uint64_t
march_layer_as(worker *w, int64_t k, int mode, int general, int flip, uint64_t first)
{
    ctx *c = w->c;
    const grid *g = &c->g;
    const int64_t N0 = g->N[0], N1 = g->N[1], N2 = g->N[2];
    const rowinfo *r0, *r1, *r2 = NULL;
    const uint8_t *S2 = k + 2 < N2 ? signs(w, k + 2, &r2) : NULL;
    const uint8_t *S1 = signs(w, k + 1, &r1);
    const uint8_t *S0 = signs(w, k, &r0);
    const int quads = c->method == ISOMEND_METHOD_DMC || c->method == ISOMEND_METHOD_DURST;
    /* Locals, not c->...: the byte stores to the origins may alias the context,
     * which would make the compiler reload these for every triangle. */
    const int durst = c->method == ISOMEND_METHOD_DURST;
    const uint8_t quad_origin = durst ? ISOMEND_ORIGIN_DURST : ISOMEND_ORIGIN_MEND;
    isomend_stats *st = &w->stats;
    const uint32_t *mk0 = NULL, *mk1 = NULL;
    const int count = mode != 1, write = mode != 0;
    if (write) {
        mk0 = w->map[k % 2];
        mk1 = w->map[(k + 1) % 2];
    }
    const int64_t plane = N0 * N1;
    uint64_t ntri = 0, busy = 0;
    uint32_t *out = write ? c->tri + 3 * first : NULL;
    uint8_t *org = write && c->org ? c->org + first : NULL;
    /* The table's triangles' origins at once when the layer's count is known;
     * in the one pass (mode 2) the origins are a fresh reservation, whose zero
     * bytes already say ISOMEND_ORIGIN_TABLE.  The quadrilaterals' are written
     * by index (the general methods write theirs as they go). */
    _Static_assert(ISOMEND_ORIGIN_TABLE == 0, "mode 2 leaves table origins as zero bytes");
    if (org && !general && !count)
        memset(org, ISOMEND_ORIGIN_TABLE, (size_t)(c->layer_first[k + 1] - first));
    const uint32_t *const out_first = out;
    uint8_t *cases = w->cases;
    uint64_t cfg_count[256]; /* counting pass: cubes per configuration */
    uint64_t general_tri = 0;
    if (count)
        memset(cfg_count, 0, sizeof cfg_count);
    w->private_count = 0;
    if (write && general)
        w->private_next = c->slice_first[N2] + c->layer_private[k];

    for (int64_t j = 0; j + 1 < N1; j++) {
        const uint8_t v = r0[j].first;
        if (uniform_as(&r0[j], N0, v) && uniform_as(&r0[j + 1], N0, v) &&
            uniform_as(&r1[j], N0, v) && uniform_as(&r1[j + 1], N0, v))
            continue; /* four uniform rows of one sign (most rows, around a blob) */
        const rowinfo *rows[4] = {&r0[j], &r0[j + 1], &r1[j], &r1[j + 1]};
        int64_t span[4];
        const int nspans = cube_spans(rows, N0, span);
        if (!nspans)
            continue;
        const uint8_t *a = S0 + j * N0, *b = a + N0, *cc = S1 + j * N0, *d = cc + N0;
        const uint32_t *ep[12] = {NULL};
        if (write) {
            const int64_t o = j * N0;
            ep[0] = mk0 + o;                      /* x edges */
            ep[1] = mk0 + o + N0;
            ep[2] = mk1 + o;
            ep[3] = mk1 + o + N0;
            ep[4] = mk0 + plane + o;              /* y edges */
            ep[5] = mk0 + plane + o + 1;
            ep[6] = mk1 + plane + o;
            ep[7] = mk1 + plane + o + 1;
            ep[8] = mk0 + 2 * plane + o;          /* z edges */
            ep[9] = mk0 + 2 * plane + o + 1;
            ep[10] = mk0 + 2 * plane + o + N0;
            ep[11] = mk0 + 2 * plane + o + N0 + 1;
        }
        for (int sp = 0; sp < nspans; sp++) {
        const int64_t i0 = span[2 * sp], i1 = span[2 * sp + 1];
        if (i0 > i1)
            continue;
        /* A narrow span (the rim of a blob) builds its configurations 16 at a
         * time as it goes; cases[] then holds columns word..word + 15 only. */
        const int narrow = i1 - i0 < NARROW_CUBES;
        /* The fill pass reads the twelve edges' ids; their map lines were
         * written a slice ago and, on a large grid, the vertices computed
         * since have pushed them out of the near caches. */
        if (write)
            prefetch_ids(ep, i0);
        if (!narrow)
            row_cases(a, b, cc, d, i0, i1, cases);
        for (int64_t word = i0; word <= i1; word += 16) {
          uint32_t mixed = narrow ? cases16(a + word, b + word, cc + word, d + word, cases + word)
                                  : mixed16(cases + word);
          const int64_t known = narrow ? word + 15 : i1; /* cases[] holds up to here */
          if (i1 - word < 15)
              mixed = first_bits(mixed, i1 - word + 1);
          if (write && word + 16 <= i1) /* the next 16 cubes' id lines */
              prefetch_ids(ep, word + 16);
          while (mixed) {
            const int64_t i = word + __builtin_ctz(mixed);
            mixed &= mixed - 1;
            const unsigned cfg = cases[i];
            busy++;
            unsigned nt;
            if (general) {
                nt = method_cube(w, i, j, k, cfg, mode, ep, mk0, mk1, out, org);
                if (write) {
                    out += 3 * nt;
                    if (org)
                        org += nt;
                }
            } else {
                nt = write ? isomend_mc_tri_count[cfg] : 0; /* else counted per layer */
            }
            if (count) {
                cfg_count[cfg]++; /* folded into the statistics once per layer */
                if (general)
                    general_tri += nt;
            }
            if (write && !general) {
                const signed char *te = isomend_mc_tri_edges[cfg];
                for (unsigned q = 0; q < nt; q++, te += 3) {
                    uint32_t v0 = ep[te[0]][i], v1 = ep[te[1]][i], v2 = ep[te[2]][i];
                    out[0] = v0;
                    out[1] = flip ? v2 : v1;
                    out[2] = flip ? v1 : v2;
                    out += 3;
                }
            }
            ntri += nt;

            const unsigned amb = isomend_mc_ambiguous_faces[cfg] & 0x2A; /* +x, +y, +z */
            if (!amb)
                continue;
            for (int axis = 0; axis < 3; axis++) {
                const int f = 2 * axis + 1;
                if (!(amb & (1u << f)))
                    continue;
                unsigned nb;
                if (axis == 0) {
                    if (i + 2 >= N0)
                        continue;
                    nb = i + 1 <= known ? cases[i + 1] : CUBE_CASE(a, b, cc, d, i + 1);
                } else if (axis == 1) {
                    if (j + 2 >= N1)
                        continue;
                    nb = CUBE_CASE(b, b + N0, d, d + N0, i);
                } else {
                    if (!S2)
                        continue;
                    const uint8_t *e2 = S2 + j * N0;
                    nb = CUBE_CASE(cc, d, e2, e2 + N0, i);
                }
                const int inverted = mc_is_inverted(cfg) != mc_is_inverted(nb);
                if (count) {
                    st->ambiguous_faces++;
                    st->inverted_combinations += (uint64_t)inverted;
                }
                if (!quads || !(inverted || durst))
                    continue;
                if (count)
                    st->triangles_by_origin[quad_origin] += 2;
                if (write) {
                    const signed char *l = isomend_mc_face_loop[cfg][f];
                    const uint32_t p = ep[l[0]][i], q = ep[l[1]][i], r = ep[l[2]][i],
                                   s = ep[l[3]][i];
                    /* The quadrilateral (s, r, q, p): triangles (s, r, q) and (s, q, p). */
                    const uint32_t quad[6] = {s, r, q, s, q, p};
                    for (int h = 0; h < 6; h += 3) {
                        out[0] = quad[h];
                        out[1] = flip ? quad[h + 2] : quad[h + 1];
                        out[2] = flip ? quad[h + 1] : quad[h + 2];
                        if (org)
                            org[(out - out_first) / 3] = quad_origin;
                        out += 3;
                    }
                }
                ntri += 2;
            }
          }
        }
        }
    }
    if (count) {
        uint64_t table_tri = 0;
        for (int q = 1; q < 255; q++) {
            st->case_histogram[isomend_mc_case_of[q]] += cfg_count[q];
            table_tri += cfg_count[q] * isomend_mc_tri_count[q];
        }
        st->case_histogram[0] += (uint64_t)(N0 - 1) * (uint64_t)(N1 - 1) - busy;
        st->triangles_by_origin[ISOMEND_ORIGIN_TABLE] += general ? general_tri : table_tri;
        if (!general && !write)
            ntri += table_tri;
    }
    return ntri;
}

/* march_layer_as compiled for each pass and kind of method, and for the fill
 * pass of the table methods for each winding (per-cube tests fold away). */
static uint64_t march_layer(worker *w, int64_t k, int mode, uint64_t first)
{
    const ctx *c = w->c;
    if (c->general)
        return mode ? march_layer_as(w, k, 1, 1, c->flip, first)
                    : march_layer_as(w, k, 0, 1, 0, first);
    if (!mode)
        return march_layer_as(w, k, 0, 0, 0, first);
    if (mode == 2)
        return c->flip ? march_layer_as(w, k, 2, 0, 1, first)
                       : march_layer_as(w, k, 2, 0, 0, first);
    return c->flip ? march_layer_as(w, k, 1, 0, 1, first) : march_layer_as(w, k, 1, 0, 0, first);
}

/* Runs one chunk of the current pass. */
static void run_chunk(worker *w, int64_t chunk)
{
    ctx *c = w->c;
    const int64_t N2 = c->g.N[2];
    const int64_t k0 = chunk * c->chunk_layers;
    int64_t k1 = k0 + c->chunk_layers;
    if (k1 > N2 - 1)
        k1 = N2 - 1;
    if (c->pass == 1) {
        for (int64_t k = k0; k < k1; k++) {
            c->slice_first[k] = scan_slice(w, k, 0, 0, 0);
            w->stats.nan_samples += w->nan[k % SIGN_RING];
            if (c->bits)
                cache_store(w, k);
            if (k == N2 - 2) {
                c->slice_first[N2 - 1] = scan_slice(w, N2 - 1, 0, 0, 0);
                w->stats.nan_samples += w->nan[(N2 - 1) % SIGN_RING];
                if (c->bits)
                    cache_store(w, N2 - 1);
            }
            c->layer_first[k] = march_layer(w, k, 0, 0);
            c->layer_private[k] = w->private_count;
        }
    } else {
        scan_slice(w, k0, 1, c->slice_first[k0], 1);
        for (int64_t k = k0; k < k1; k++) {
            const int64_t m = k + 1;
            scan_slice(w, m, 1, c->slice_first[m], m < k1 || m == N2 - 1);
            march_layer(w, k, 1, c->layer_first[k]);
        }
    }
}

static void run_chunks(worker *w)
{
    ctx *c = w->c;
    for (;;) {
        if (atomic_load(&c->cancel))
            return;
        long long chunk = atomic_fetch_add(&c->next_chunk, 1);
        if (chunk >= c->nchunks)
            return;
        run_chunk(w, chunk);
        long long done = atomic_fetch_add(&c->done_chunks, 1) + 1;
        if (w->is_main && c->progress) {
            double f = (double)done / (double)(2 * c->nchunks);
            if (c->progress(c->progress_user, f))
                atomic_store(&c->cancel, 1);
        }
    }
}

static void *worker_thread(void *arg)
{
    run_chunks((worker *)arg);
    return NULL;
}

/* Runs the current pass on `nw` workers (worker 0 is this thread). */
static isomend_status run_pass(ctx *c, worker *ws, int nw)
{
    pthread_t tid[64];
    int started = 0;
    isomend_status status = ISOMEND_OK;
    atomic_store(&c->next_chunk, 0);
    for (int t = 1; t < nw; t++) {
        if (pthread_create(&tid[t], NULL, worker_thread, &ws[t]) != 0) {
            status = ISOMEND_ERR_THREAD;
            atomic_store(&c->cancel, 1);
            break;
        }
        started = t;
    }
    if (status == ISOMEND_OK)
        run_chunks(&ws[0]);
    for (int t = 1; t <= started; t++)
        pthread_join(tid[t], NULL);
    if (status == ISOMEND_OK && atomic_load(&c->cancel))
        status = ISOMEND_ERR_CANCELLED;
    return status;
}

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/*
 * How long after the first thread's sweep the second may end its own and
 * still take a share of the moves (split apart).  Their sweeps meet
 * wherever their speeds make them, so they end within a slice of each other
 * when both threads run.  When the second ends much later, its CPU was taken
 * from it, and the first thread, on the CPU that runs, does all the moves.
 * On this project's virtual machine, in phases of minutes, one of the two
 * vCPUs ran a thread at a fraction of the other's speed: on the 256^3
 * sphere at 2 threads its thread swept about 45 slices while the other swept
 * 210, ended 2.6-6.4 ms after it and then took about 4 ms to move a few
 * hundred KB of triangles, the whole call 19 ms against 8 otherwise.  Negative: the first
 * thread always does the moves (a test build's).
 */
#ifndef ISOMEND_SPLIT_LATE
#define ISOMEND_SPLIT_LATE 0.5e-3
#endif

/*
 * The one pass on two threads.  The calling thread sweeps from the first
 * layer, writing as it goes; the second first counts the vertices and
 * triangles of the layers from the first on (the counting pass's scans, a
 * fraction of a sweep's work) until it has counted up to a layer `at` that
 * splits what is left about evenly, then sweeps from `at` to the end, its ids
 * and triangles starting at the counts.  The first thread claims each slice
 * before writing its vertices and stops at `at`: it numbers that slice, for
 * the ids of its last layer, without writing them.  Ids and order are the
 * one thread's.  With no split (a grid too small, the first thread ahead),
 * the first thread sweeps alone.
 *
 * Counting costs the second thread a read of the volume's first part; on a
 * sparse mesh that is most of a sweep's work there, and the split lands at
 * about 2/3.  So when four sampled slices say the mesh is sparse, the second
 * splits apart instead (split_apart): it sweeps down from the last slice at
 * once (sweep_down), claiming each slice as the first thread does, until the
 * two meet, wherever the threads' speeds make them meet.  It numbers its
 * vertices and triangles past any the first can write (the bases), slice
 * after slice and layer after layer as it goes down; when both are done the
 * first thread moves the second's vertices, slice by slice in slice order,
 * to follow its own, while the second moves its triangles, renumbered.
 * 512^3 float sphere at 2 threads: 0.80-0.83x the counting split's time
 * when the second thread swept up from the middle; sweeping down, it takes
 * whatever share of the volume its speed allows, where traces had shown it
 * 2-12 ms late on the 512^3 sphere's 40-ms halves.
 */
typedef struct split {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int64_t at;       /* the second thread's first layer (apart: its lowest
                       * slice so far); INT64_MAX while open */
    int64_t claimed;  /* slices [0, claimed) are written by the first thread */
    int finished;     /* the second thread is done (cv)                      */
    atomic_llong done; /* layers the second thread has swept (progress)      */
    uint64_t nv, nt;  /* its totals, when it split                           */
    isomend_status status;
    /* Split apart (split_apart): no counting; the second thread numbers its
     * vertices and triangles from the bases c->apart_v and c->apart_t, past
     * any the first can write, slice m's vertices from vstart[m] and layer
     * k's triangles from tstart[k] (both decreasing with m and k), and its
     * part is moved down once the first's counts are known. */
    int apart;
    uint64_t *vstart, *tstart; /* [N2], when the reservation has the room */
    int first_done;          /* the first thread's sweep is over (cv) */
    double first_end;        /* when (CLOCK_MONOTONIC, s)             */
    int solo_join;           /* the first thread moves the triangles too */
    uint64_t nv1, nt1;       /* its vertices and triangles            */
    isomend_status status1;
} split;

/* The sweep from layer `from` (vertices numbered from *nv, triangles from
 * *nt) to the last, or, for the first of two threads (`sp`), to sp->at. */
static isomend_status sweep(ctx *c, worker *w, int64_t from, uint64_t *nv, uint64_t *nt,
                            split *sp)
{
    const int64_t N2 = c->g.N[2], layers = N2 - 1;
    const int first = sp && w->is_main;
    const rowinfo *ri;
    if (from + 2 < N2)
        (void)signs(w, from + 2, &ri); /* read ahead: the z edges reach slice from + 2 */
    uint64_t v = *nv, t = *nt;
    v += scan_slice(w, from, 1, v, 1);
    w->stats.nan_samples += w->nan[from % SIGN_RING];
    for (int64_t k = from; k < layers; k++) {
        if (v > UINT32_MAX)
            return ISOMEND_ERR_TOO_LARGE;
        const int64_t m = k + 1;
        int last = 0; /* slice m is the second thread's: ids only */
        if (first) {
            pthread_mutex_lock(&sp->mu);
            if (m >= sp->at)
                last = 1;
            else
                sp->claimed = m + 1;
            pthread_mutex_unlock(&sp->mu);
        }
        /* The gradients at slice k + 1's z edges read slice k + 3: classifying
         * it first brings it into the caches. */
        if (k + 3 < N2 && !last)
            (void)signs(w, k + 3, &ri);
        const uint64_t own = v; /* the vertices of the slices before m */
        v += scan_slice(w, m, 1, v, !last);
        if (!last)
            w->stats.nan_samples += w->nan[m % SIGN_RING];
        t += march_layer(w, k, 2, t);
        if (last) {
            *nv = own; /* slice m's vertices are the second thread's */
            *nt = t;
            return ISOMEND_OK;
        }
        if (sp && !first) {
            atomic_fetch_add(&sp->done, 1);
            if (atomic_load(&c->cancel))
                return ISOMEND_ERR_CANCELLED;
        }
        if (w->is_main && c->progress && (k % 16 == 15 || k + 1 == layers)) {
            const double swept = (double)(k + 1) + (sp ? (double)atomic_load(&sp->done) : 0.0);
            if (c->progress(c->progress_user, swept / (double)(layers + 1)))
                return ISOMEND_ERR_CANCELLED; /* 1.0 is reported at the end */
        }
    }
    if (v > UINT32_MAX)
        return ISOMEND_ERR_TOO_LARGE;
    *nv = v;
    *nt = t;
    return ISOMEND_OK;
}

/* Vertices a sample below which two threads split apart, for samples of one
 * byte; times the sample's size (see split_apart). */
#ifndef ISOMEND_APART_DENSITY
#define ISOMEND_APART_DENSITY 0.02
#endif

/*
 * Whether the second of two threads splits the sweep apart rather than
 * counting: when the one pass reserved room for it (one_pass: the arrays
 * twice as long, the ids then within 32 bits), it samples four slices'
 * vertices and splits apart when the mesh is sparse (the moves at the end
 * cost little).
 */
static int split_apart(worker *w, const split *sp)
{
    const ctx *c = w->c;
    const grid *g = &c->g;
    if (!sp->vstart)
        return 0;
    const uint64_t N0 = (uint64_t)g->N[0], N1 = (uint64_t)g->N[1], N2 = (uint64_t)g->N[2];
    uint64_t sampled = 0;
    for (uint64_t q = 0; q < 4; q++)
        sampled += scan_slice(w, (int64_t)((2 * q + 1) * N2 / 8), 0, 0, 0);
    const double density = ISOMEND_APART_DENSITY * (double)isomend_type_size(g->type);
    return (double)sampled <= density * 4.0 * (double)(N0 * N1);
}

/*
 * The second thread's sweep when apart: down from the last slice, claiming
 * each slice m (sp->at = m) unless the first thread has it, numbering slice
 * m's vertices from *nv and writing layer m's triangles from *nt.  The
 * classification reads slice m - 1 ahead: the gradients at slice m's z edges
 * read it, and of the four ring slots the one it takes holds m + 3, which
 * nothing needs any more.
 */
static isomend_status sweep_down(ctx *c, worker *w, split *sp, uint64_t *nv, uint64_t *nt)
{
    const int64_t N2 = c->g.N[2];
    const rowinfo *ri;
    uint64_t v = *nv, t = *nt;
    isomend_status status = ISOMEND_OK;
    for (int64_t m = N2 - 1; m >= 1; m--) {
        pthread_mutex_lock(&sp->mu);
        const int mine = m >= sp->claimed;
        if (mine)
            sp->at = m;
        pthread_mutex_unlock(&sp->mu);
        if (!mine)
            break;
        (void)signs(w, m - 1, &ri);
        sp->vstart[m] = v;
        v += scan_slice(w, m, 1, v, 1);
        w->stats.nan_samples += w->nan[m % SIGN_RING];
        if (m + 1 < N2) {
            sp->tstart[m] = t;
            t += march_layer(w, m, 2, t);
            atomic_fetch_add(&sp->done, 1);
        }
        if (v > UINT32_MAX) {
            status = ISOMEND_ERR_TOO_LARGE;
            break;
        }
        if (atomic_load(&c->cancel)) {
            status = ISOMEND_ERR_CANCELLED;
            break;
        }
    }
    *nv = v;
    *nt = t;
    return status;
}

/* Source bytes a move reads between releases of the source's pages. */
#define MOVE_CHUNK (4 * HUGE_PAGE)

/*
 * The moves of a split apart, from the second thread's part (from the bases
 * on, blocks in descending slice or layer order) to their places after the
 * first thread's part.  As the blocks are read, from the highest address
 * down, the source's huge pages above the block being read are released,
 * 8 MiB or more at a time, so that the array does not hold the whole moved
 * part twice (maximum RSS of the 512^3 sphere at 2 threads: 613 -> 602 MB
 * when this was first done; 584 MB counting.  The rest of the difference is
 * the second part's own partly used last pages).
 */
static void move_origins(uint8_t *org, uint64_t to, uint64_t from, uint64_t n);

typedef struct release {
    char *array;
    size_t top; /* bytes from here on were read and released, or never used */
} release;

/* Releases the source's whole pages from byte `from` up, when they come to
 * MOVE_CHUNK or this is the last block.  Not the page holding `from`: below
 * the bases it may hold the end of the moved part. */
static void release_above(release *r, size_t from, int last)
{
#if defined(__linux__) && defined(MADV_DONTNEED)
    const size_t at = huge_round(from);
    if (at < r->top && (last || r->top - at >= MOVE_CHUNK)) {
        (void)madvise(r->array + at, r->top - at, MADV_DONTNEED);
        r->top = at;
    }
#else
    (void)r;
    (void)from;
    (void)last;
#endif
}

/* Items in block b of a split apart's part, whose blocks b, b - 1, ..., lo
 * follow one another from start[b] on, the last (lo) ending at `end`. */
static inline uint64_t block_size(const uint64_t *start, int64_t b, int64_t lo, uint64_t end)
{
    return (b > lo ? start[b - 1] : end) - start[b];
}

/*
 * Moves the vertex blocks of slices [at, N2) (items of `size` bytes, block m
 * from item vstart[m], the last ending at `end`) to item `to` on, in slice
 * order.
 */
static void move_vertex_blocks(void *array, size_t size, uint64_t to, const uint64_t *vstart,
                               int64_t at, int64_t N2, uint64_t end)
{
    if (!array || at >= N2)
        return;
    char *a = array;
    release r = {a, huge_round(size * end)};
    for (int64_t m = at; m < N2; m++) {
        const uint64_t n = block_size(vstart, m, at, end);
        memcpy(a + size * to, a + size * vstart[m], size * n);
        to += n;
        release_above(&r, size * vstart[m], m + 1 == N2);
    }
}

/*
 * Moves the triangle blocks of layers [at, N2 - 1) (layer k's from triangle
 * tstart[k], the last ending at `end`) to triangle `to` on, in layer order,
 * renumbering their vertices for the moves of move_vertex_blocks (to `nv1`
 * on), and their origins' non-zero bytes.  Layer k's triangles use vertices
 * of slices k and k + 1, whose blocks are told apart by vstart[k] >
 * vstart[k + 1].
 */
static void move_triangle_blocks(uint32_t *tri, uint8_t *org, uint64_t to, const uint64_t *tstart,
                                 uint64_t tend, const uint64_t *vstart, uint64_t vend,
                                 uint64_t nv1, int64_t at, int64_t N2)
{
    if (at >= N2 - 1)
        return;
    release r = {(char *)tri, huge_round(3 * sizeof(uint32_t) * tend)};
    uint64_t first_k = nv1; /* final id of slice k's first vertex */
    for (int64_t k = at; k < N2 - 1; k++) {
        const uint64_t n = block_size(tstart, k, at, tend);
        const uint64_t first_k1 = first_k + block_size(vstart, k, at, vend);
        /* mod 2^32: the ids move down */
        const uint32_t add_k = (uint32_t)(first_k - vstart[k]);
        const uint32_t add_k1 = (uint32_t)(first_k1 - vstart[k + 1]);
        const uint32_t split_id = (uint32_t)vstart[k];
        const uint32_t *s = tri + 3 * tstart[k];
        uint32_t *d = tri + 3 * to;
        for (uint64_t q = 0; q < 3 * n; q++)
            d[q] = s[q] + (s[q] >= split_id ? add_k : add_k1);
        move_origins(org, to, tstart[k], n);
        to += n;
        first_k = first_k1;
        release_above(&r, 3 * sizeof(uint32_t) * tstart[k], k + 2 == N2);
    }
}

/*
 * Moves n triangles' origins from `from` down to `to`, apart (the source lies
 * past the bases), where the destination reads as zero bytes (a fresh
 * reservation: recycling leaves the origins out) as does most of the source
 * (the table's triangles): only the other bytes are written, so that the
 * pages of the destination, often the first 2 MiB (on 4 KiB pages), are not
 * all faulted in (the 256^3 sphere: 45 pages, 1-4 ms).
 */
static void move_origins(uint8_t *org, uint64_t to, uint64_t from, uint64_t n)
{
    if (!org || !n)
        return;
    const uint8_t *s = org + from;
    uint8_t *d = org + to;
    size_t q = 0;
    for (; q + 8 <= n; q += 8) {
        uint64_t w;
        memcpy(&w, s + q, sizeof w);
        if (w)
            for (size_t b = 0; b < 8; b++)
                if (s[q + b])
                    d[q + b] = s[q + b];
    }
    for (; q < n; q++)
        if (s[q])
            d[q] = s[q];
}

/* A split apart's triangle moves, once both threads' sweeps are over (their
 * counts and sp->at no longer change). */
static void move_second_triangles(const ctx *c, const split *sp)
{
    move_triangle_blocks(c->tri, c->org, sp->nt1, sp->tstart, sp->nt, sp->vstart, sp->nv,
                         sp->nv1, sp->at, c->g.N[2]);
}

/* The second of two threads: counts and splits, or splits apart; sweeps the
 * rest (see split). */
static void *second_sweep(void *arg)
{
    worker *w = arg;
    ctx *c = w->c;
    split *sp = c->split;
    const int64_t layers = c->g.N[2] - 1;
    const isomend_stats kept = w->stats; /* counting adds to them: not this thread's */
    uint64_t v = 0, t = 0;
    int64_t at = -1;
    const int apart = split_apart(w, sp);
    if (apart) { /* no counting: down from the last slice, from the bases */
        pthread_mutex_lock(&sp->mu);
        sp->apart = 1;
        pthread_mutex_unlock(&sp->mu);
        v = c->apart_v;
        t = c->apart_t;
    }
    for (int64_t k = 0; k + 1 < layers && at < 0 && !apart && !atomic_load(&c->cancel); k++) {
        v += scan_slice(w, k, 0, 0, 0);
        t += march_layer(w, k, 0, 0);
        /* Counted: slices and layers [0, k + 1).  Split there when the first
         * thread has not claimed slice k + 1 and has about as far to go to it
         * as this one from it to the end. */
        const int64_t s = k + 1;
        pthread_mutex_lock(&sp->mu);
        if (s >= sp->claimed && 2 * s >= layers + sp->claimed)
            sp->at = at = s;
        pthread_mutex_unlock(&sp->mu);
    }
    w->stats = kept;
    isomend_status status = ISOMEND_OK;
    if (apart)
        status = sweep_down(c, w, sp, &v, &t);
    else if (at >= 0)
        status = v > UINT32_MAX ? ISOMEND_ERR_TOO_LARGE : sweep(c, w, at, &v, &t, sp);
    pthread_mutex_lock(&sp->mu);
    sp->nv = v;
    sp->nt = t;
    sp->status = status;
    /* Apart: this thread moves the triangles (and origins) down once the
     * first thread's counts are known, while the first moves the vertices;
     * unless the first has waited long for this one, whose CPU is then
     * likely the slower (ISOMEND_SPLIT_LATE). */
    sp->solo_join = sp->apart && (ISOMEND_SPLIT_LATE < 0 ||
                                  (sp->first_done &&
                                   now_seconds() - sp->first_end > ISOMEND_SPLIT_LATE));
    sp->finished = 1;
    pthread_cond_broadcast(&sp->cv);
    if (!sp->apart || sp->solo_join) {
        pthread_mutex_unlock(&sp->mu);
        return NULL;
    }
    while (!sp->first_done)
        pthread_cond_wait(&sp->cv, &sp->mu);
    const int join = status == ISOMEND_OK && sp->status1 == ISOMEND_OK && sp->at != INT64_MAX;
    pthread_mutex_unlock(&sp->mu);
    if (join)
        move_second_triangles(c, sp);
    return NULL;
}

/*
 * One pass (table methods, one or two threads).  Slice by slice, a worker
 * numbers and computes the vertices of slice k + 1 and then writes layer k's
 * triangles, counting as it goes, so each slice is classified once and the
 * samples around its vertices are read while the classification has them in
 * the caches.  Ids and order are those of the two passes.  The output arrays
 * are reservations of their largest possible size (reserve_output), so
 * nothing needs to be known in advance; the untouched part costs no memory
 * and is trimmed at the end.
 */
static isomend_status run_one_pass(ctx *c, worker *ws, int nw, uint64_t *nv, uint64_t *nt)
{
    uint64_t v = 0, t = 0;
    if (nw < 2) {
        isomend_status status = sweep(c, &ws[0], 0, &v, &t, NULL);
        *nv = v;
        *nt = t;
        return status;
    }
    split sp;
    memset(&sp, 0, sizeof sp);
    sp.at = INT64_MAX;
    sp.claimed = 1; /* slice 0 */
    atomic_init(&sp.done, 0);
    if (pthread_mutex_init(&sp.mu, NULL) != 0)
        return ISOMEND_ERR_THREAD;
    if (pthread_cond_init(&sp.cv, NULL) != 0) {
        pthread_mutex_destroy(&sp.mu);
        return ISOMEND_ERR_THREAD;
    }
    if (c->apart_v) {
        const size_t N2 = (size_t)c->g.N[2];
        sp.vstart = calloc(2 * N2, sizeof(uint64_t)); /* NULL: no split apart */
        sp.tstart = sp.vstart ? sp.vstart + N2 : NULL;
    }
    c->split = &sp;
    pthread_t tid;
    const int started = pthread_create(&tid, NULL, second_sweep, &ws[1]) == 0;
    if (!started)
        sp.finished = 1; /* no second thread: sp.at stays open, the first sweeps alone */
    isomend_status status = sweep(c, &ws[0], 0, &v, &t, &sp);
    if (status != ISOMEND_OK)
        atomic_store(&c->cancel, 1);
    const double end = now_seconds();
    pthread_mutex_lock(&sp.mu);
    sp.first_done = 1;
    sp.first_end = end;
    sp.nv1 = v;
    sp.nt1 = t;
    sp.status1 = status;
    pthread_cond_broadcast(&sp.cv);
    pthread_mutex_unlock(&sp.mu);
    /* Wait for the second thread, reporting progress once now (the first
     * thread reports every 16 of its own layers, and the second may have
     * swept nearly all) and then every 100 ms. */
    const int64_t layers = c->g.N[2] - 1;
    pthread_mutex_lock(&sp.mu);
    for (int waited = 0;; waited = 1) {
        if (waited) {
            if (sp.finished)
                break;
            if (!c->progress) {
                pthread_cond_wait(&sp.cv, &sp.mu);
                continue;
            }
            struct timespec until;
            clock_gettime(CLOCK_REALTIME, &until);
            until.tv_nsec += 100 * 1000 * 1000;
            if (until.tv_nsec >= 1000 * 1000 * 1000) {
                until.tv_sec++;
                until.tv_nsec -= 1000 * 1000 * 1000;
            }
            pthread_cond_timedwait(&sp.cv, &sp.mu, &until);
            if (sp.finished)
                break;
        }
        if (!c->progress || status != ISOMEND_OK)
            continue;
        const double swept = (double)(sp.at < layers ? sp.at : layers) +
                             (double)atomic_load(&sp.done);
        pthread_mutex_unlock(&sp.mu);
        if (c->progress(c->progress_user, swept / (double)(layers + 1))) {
            status = ISOMEND_ERR_CANCELLED;
            atomic_store(&c->cancel, 1);
        }
        pthread_mutex_lock(&sp.mu);
    }
    const int split_made = sp.at != INT64_MAX;
    pthread_mutex_unlock(&sp.mu);
    if (status == ISOMEND_OK && split_made) {
        status = sp.status;
        if (sp.apart) {
            /* the vertices here, the triangles on the second thread */
            const uint64_t nv2 = sp.nv - c->apart_v, nt2 = sp.nt - c->apart_t;
            if (status == ISOMEND_OK) {
                move_vertex_blocks(c->pos, 3 * sizeof(float), v, sp.vstart, sp.at, c->g.N[2],
                                   sp.nv);
                move_vertex_blocks(c->nrm, 3 * sizeof(float), v, sp.vstart, sp.at, c->g.N[2],
                                   sp.nv);
                if (sp.solo_join)
                    move_second_triangles(c, &sp);
            }
            v += nv2;
            t += nt2;
        } else {
            v = sp.nv;
            t = sp.nt;
        }
    }
    if (started)
        pthread_join(tid, NULL);
    c->split = NULL;
    free(sp.vstart);
    pthread_cond_destroy(&sp.cv);
    pthread_mutex_destroy(&sp.mu);
    *nv = v;
    *nt = t;
    return status;
}

static void worker_free(worker *w)
{
    free(w->block);
}

static void *scratch_alloc(size_t size);

/* The next part of a worker's block: `size` bytes at *at, which moves on to
 * the next cache line. */
static char *carve(char *block, size_t *at, size_t size)
{
    char *p = block ? block + *at : NULL;
    *at += (size + 63) & ~(size_t)63;
    return p;
}

/* The worker's arrays, in one block (scratch_alloc); with block NULL, only
 * their total size. */
static size_t worker_layout(worker *w, const ctx *c, char *block)
{
    const int64_t N0 = c->g.N[0], N1 = c->g.N[1];
    size_t at = 0;
    for (int r = 0; r < SIGN_RING; r++) {
        w->sg[r] = (uint8_t *)carve(block, &at, (size_t)(N0 * N1) + SCAN_PAD);
        w->ri[r] = (rowinfo *)(void *)carve(block, &at, sizeof(rowinfo) * (size_t)N1);
    }
    w->cases = (uint8_t *)carve(block, &at, (size_t)N0 + SCAN_PAD);
    for (int a = 0; a < 3; a++)
        w->vl[a] = (vitem *)(void *)carve(block, &at,
                                          sizeof(vitem) * ((size_t)VERTEX_LIST + (size_t)N0));
    for (int r = 0; r < 2; r++)
        w->map[r] = (uint32_t *)(void *)carve(
            block, &at, sizeof(uint32_t) * (size_t)c->planes * (size_t)(N0 * N1));
    return at;
}

static int worker_init(worker *w, ctx *c)
{
    memset(w, 0, sizeof(*w));
    w->c = c;
    for (int r = 0; r < SIGN_RING; r++)
        w->sk[r] = -1;
    w->block = scratch_alloc(worker_layout(w, c, NULL));
    if (!w->block)
        return 0;
    (void)worker_layout(w, c, w->block);
    memset(w->cases, 0, (size_t)c->g.N[0] + SCAN_PAD); /* read past a row's end */
    return 1;
}

/*
 * Output arrays of 2 MiB and more are aligned to 2 MiB and offered to the
 * kernel for transparent huge pages: a large mesh otherwise spends a third
 * of its time in page faults (measured on 256^3 noise, 14.8 M triangles:
 * 90 000 faults per extraction).  Released with free() like any allocation.
 * With ISOMEND_FLAG_SMALL_PAGES they are plain allocations.
 */
static void *output_alloc(size_t size, int small_pages)
{
    if (size < HUGE_PAGE || small_pages)
        return malloc(size ? size : 1);
    void *p = NULL;
    if (posix_memalign(&p, HUGE_PAGE, size) != 0)
        return NULL;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    (void)madvise(p, huge_round(size), MADV_HUGEPAGE);
#endif
    return p;
}

/*
 * Working arrays of 1 MiB and more (a worker's sign slices and id maps, the
 * sign cache): rounded up to whole 2 MiB pages, aligned to them and offered
 * for transparent huge pages.  malloc would hand these back to the kernel at
 * free() (glibc maps them on their own or trims its heap) and take them again
 * the next call on 4 KiB pages: 600 page faults a call for the second worker
 * of a 256^3 volume, 1 300 for the 512^3 sphere, and on a virtual machine
 * whose every small-page fault is a trap to the host (3.8 ms/MB measured
 * here) that was a tenth of the 256^3 sphere's time at 2 threads.  Released
 * with free().
 */
static void *scratch_alloc(size_t size)
{
    if (size < HUGE_PAGE / 2)
        return malloc(size ? size : 1);
    if (size > SIZE_MAX - HUGE_PAGE)
        return NULL;
    return output_alloc(huge_round(size), 0);
}

/*
 * The one-pass path's output arrays: an anonymous mapping of `size` bytes
 * (the array's largest possible size) that reserves address space, not
 * memory (MAP_NORESERVE), aligned to 2 MiB and offered for transparent huge
 * pages from byte `huge_from` (a multiple of 2 MiB) on, or never (SIZE_MAX:
 * ISOMEND_FLAG_SMALL_PAGES).  NULL when the system
 * refuses (strict overcommit, an address-space limit): the caller then takes
 * the two passes.  The mapping is huge_round(size) bytes long.
 */
static void *reserve_output(size_t size, size_t huge_from)
{
#if defined(__linux__) && defined(MAP_NORESERVE)
    if (size > SIZE_MAX / 2 - 2 * HUGE_PAGE)
        return NULL;
    size = huge_round(size);
    char *p = mmap(NULL, size + HUGE_PAGE, PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (p == MAP_FAILED)
        return NULL;
    const size_t head = (size_t)(-(uintptr_t)p & (HUGE_PAGE - 1));
    if (head)
        munmap(p, head);
    munmap(p + head + size, HUGE_PAGE - head);
#if defined(MADV_HUGEPAGE) && defined(MADV_NOHUGEPAGE)
    if (huge_from == SIZE_MAX) /* small pages, even where the kernel's policy is "always" */
        (void)madvise(p + head, size, MADV_NOHUGEPAGE);
    else if (huge_from < size)
        (void)madvise(p + head + huge_from, size - huge_from, MADV_HUGEPAGE);
#endif
    return p + head;
#else
    (void)size;
    (void)huge_from;
    return NULL;
#endif
}

/* Unmaps the part of a reservation of `size` bytes past its first `used`
 * bytes (rounded up to a page: the last huge page is split, and the mesh
 * then holds no more than it uses); returns the length kept mapped. */
static size_t trim_output(void *p, size_t size, size_t used)
{
#if defined(__linux__) && defined(MAP_NORESERVE)
    const size_t page = (size_t)sysconf(_SC_PAGESIZE);
    used = used ? (used + page - 1) / page * page : page;
    if (used < size)
        munmap((char *)p + used, size - used);
    return used < size ? used : size;
#else
    (void)p;
    (void)used;
    return size;
#endif
}

/* Frees an output array: unmaps a reservation (`mapped` bytes kept), or free(). */
static void release_output(void *p, size_t mapped)
{
#if defined(__linux__) && defined(MAP_NORESERVE)
    if (mapped) {
        munmap(p, mapped);
        return;
    }
#endif
    (void)mapped;
    free(p);
}

/*
 * Recycling (isomend_extract_recycle): moves the whole 2 MiB pages at the
 * start of an old mesh's array, a reservation of `mapped` bytes at `old`, to
 * the start of the new reservation p of `size` bytes (both 2 MiB aligned), so
 * that the new mesh writes on pages already faulted in and zeroed once: no
 * page fault, no zeroing by the kernel, and on a virtual machine nothing to
 * get back from the host.  The old array's last, partly used page was split
 * into 4 KiB pages when it was trimmed: it is unmapped with the rest, since
 * it would make the new array fault 4 KiB pages where a 2 MiB one belongs.
 */
static void adopt_output(void *p, size_t size, void *old, size_t mapped)
{
#if defined(__linux__) && defined(MREMAP_FIXED)
    size_t keep = mapped & ~(HUGE_PAGE - 1);
    if (keep > size)
        keep = size;
    if (keep && mremap(old, keep, keep, MREMAP_MAYMOVE | MREMAP_FIXED, p) == MAP_FAILED)
        keep = 0;
    if (mapped > keep)
        munmap((char *)old + keep, mapped - keep);
#else
    (void)p;
    (void)size;
    release_output(old, mapped);
#endif
}

/* The smallest grid (samples) for the one-pass path.  Below it the two
 * passes are as fast or faster: the volume stays in the caches between them,
 * and their small arrays come from the heap, where the one-pass reservations
 * cost a huge page each (sphere in one pass: 32^3 1.9x, 64^3 1.3x, 100^3
 * 1.0x, 128^3 0.92x the two passes' time; split between two threads at
 * 128^3: sphere and gyroid 1.01x, noise 0.88x).  Tests build the library
 * with 1. */
#ifndef ISOMEND_ONE_PASS_SAMPLES
#define ISOMEND_ONE_PASS_SAMPLES (1 << 21)
#endif

/*
 * The one-pass path: reserves the output arrays and runs run_one_pass.
 * ISOMEND_ERR_UNSUPPORTED (nothing allocated) when the reservations are
 * refused, for the two passes to take over.
 */
static isomend_status one_pass(ctx *c, worker *ws, int nw, isomend_mesh **out, uint64_t *nv,
                               uint64_t *nt)
{
    const grid *g = &c->g;
    const uint64_t N0 = (uint64_t)g->N[0], N1 = (uint64_t)g->N[1], N2 = (uint64_t)g->N[2];
    /* Edges of a slice whose lower end is in it: at most 3 a sample; one
     * slice may pass 2^32 - 1 vertices before the check. */
    uint64_t vmax = 3 * N0 * N1 * N2;
    const uint64_t vcap = (uint64_t)UINT32_MAX + 1 + 3 * N0 * N1;
    if (vmax > vcap)
        vmax = vcap;
    /* Triangles: the table's, and two for each of the cube's +x, +y, +z faces. */
    const uint64_t tmax = (MC_MAX_TRI + 6) * (N0 - 1) * (N1 - 1) * (N2 - 1);
    if (vmax > SIZE_MAX / 32 || tmax > SIZE_MAX / 32)
        return ISOMEND_ERR_UNSUPPORTED;
    /* Two threads may split apart (split_apart): room for the second's part
     * past the bases vmax and tmax, which no count can reach, with its ids
     * still within 32 bits.  Address space only (reserve_output); when it is
     * refused, the arrays are reserved again without the room. */
    int room = nw == 2 && N2 >= 8 && vmax == 3 * N0 * N1 * N2 &&
               2 * vmax <= (uint64_t)UINT32_MAX + 1;
    isomend_mesh *mesh = calloc(1, sizeof(*mesh));
    if (!mesh)
        return ISOMEND_ERR_OUT_OF_MEMORY;
reserve:
    c->apart_v = room ? vmax : 0;
    c->apart_t = room ? tmax : 0;
    const uint64_t vres = room ? 2 * vmax : vmax, tres = room ? 2 * tmax : tmax;
    const size_t size[4] = {sizeof(float) * 3 * (size_t)vres,
                            c->want_normals ? sizeof(float) * 3 * (size_t)vres : 0,
                            sizeof(uint32_t) * 3 * (size_t)tres,
                            c->want_origins ? (size_t)tres : 0};
    void *p[4] = {NULL, NULL, NULL, NULL};
    for (int q = 0; q < 4; q++) {
        if (!size[q])
            continue;
        /* The origins (a byte a triangle) are often under 2 MiB: huge pages
         * from there on only, or a huge page would hold ~2 MiB of nothing. */
        size_t huge_from = q == 3 ? HUGE_PAGE : 0;
        if (c->small_pages)
            huge_from = SIZE_MAX;
        p[q] = reserve_output(size[q], huge_from);
        if (!p[q]) {
            for (int r = 0; r < q; r++)
                release_output(p[r], mesh->mapped[r]);
            if (room) {
                room = 0;
                memset(mesh->mapped, 0, sizeof mesh->mapped);
                goto reserve;
            }
            free(mesh);
            return ISOMEND_ERR_UNSUPPORTED;
        }
        mesh->mapped[q] = huge_round(size[q]);
    }
    /* The recycled mesh's positions, normals and triangles become the start of
     * the new ones.  Not its origins: the one pass leaves the table's origins
     * as zero bytes and untouched pages cost nothing; zeroing recycled ones
     * touches what the new mesh may never write (the 256^3 sphere, without
     * mending: 1.03x isomend_extract's time that way, 0.95x without). */
    if (c->recycled) {
        isomend_mesh *old = c->recycled;
        void **arrays[3] = {(void **)&old->pos, (void **)&old->nrm, (void **)&old->tri};
        for (int q = 0; q < 3; q++) {
            if (!p[q] || !old->mapped[q])
                continue;
            adopt_output(p[q], mesh->mapped[q], *arrays[q], old->mapped[q]);
            *arrays[q] = NULL;
            old->mapped[q] = 0;
        }
        isomend_mesh_destroy(old); /* what is left: arrays the new mesh does not have */
        c->recycled = NULL;
    }
    mesh->pos = c->pos = p[0];
    mesh->nrm = c->nrm = p[1];
    mesh->tri = c->tri = p[2];
    mesh->org = c->org = p[3];
    *out = mesh; /* destroyed by the caller on error */
    c->pass = 1; /* signs() counts NaN samples */
    isomend_status status = run_one_pass(c, ws, nw, nv, nt);
    if (status != ISOMEND_OK)
        return status;
    mesh->nv = (size_t)*nv;
    mesh->nt = (size_t)*nt;
    const size_t used[4] = {sizeof(float) * 3 * mesh->nv, sizeof(float) * 3 * mesh->nv,
                            sizeof(uint32_t) * 3 * mesh->nt, mesh->nt};
    for (int q = 0; q < 4; q++)
        if (p[q])
            mesh->mapped[q] = trim_output(p[q], mesh->mapped[q], used[q]);
    return ISOMEND_OK;
}

static int default_threads(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : n > 64 ? 64 : (int)n;
}

static isomend_status validate(const isomend_volume *vol, const isomend_options *o)
{
    if (!vol || !vol->data || isomend_type_size(vol->type) == 0)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if ((unsigned)o->method >= ISOMEND_METHOD_COUNT || (o->flags & ~ISOMEND_FLAGS_ALL))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (!isomend_method_available(o->method))
        return ISOMEND_ERR_UNSUPPORTED;
    const int64_t min = (o->flags & ISOMEND_FLAG_PAD) ? 1 : 2;
    for (int a = 0; a < 3; a++) {
        if (vol->dims[a] < min || vol->dims[a] > ((int64_t)1 << 31))
            return ISOMEND_ERR_BAD_DIMENSIONS;
        if (!(vol->spacing[a] > 0.0) || !isfinite(vol->spacing[a]))
            return ISOMEND_ERR_BAD_SPACING;
        if (!isfinite(vol->origin[a]))
            return ISOMEND_ERR_INVALID_ARGUMENT;
    }
    if (!isfinite(o->iso))
        return ISOMEND_ERR_BAD_ISO;
    return ISOMEND_OK;
}

/* isomend_extract, recycling *recycled (taken, and set to NULL, once the
 * extraction has begun; the caller destroys it otherwise). */
static isomend_status extract(const isomend_volume *vol, const isomend_options *opts,
                              isomend_mesh **out_mesh, isomend_stats *stats,
                              isomend_mesh **recycled)
{
    if (!out_mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out_mesh = NULL;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const isomend_options *o = opts ? opts : &defaults;
    isomend_status status = validate(vol, o);
    if (status != ISOMEND_OK)
        return status;

    ctx *c = calloc(1, sizeof(*c));
    if (!c)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    c->recycled = *recycled; /* this call's now: used or destroyed */
    *recycled = NULL;
    grid *g = &c->g;
    const size_t size = isomend_type_size(vol->type);
    g->data = vol->data;
    g->type = vol->type;
    g->pad = (o->flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    g->iso = o->iso;
    for (int a = 0; a < 3; a++) {
        g->n[a] = vol->dims[a];
        g->N[a] = vol->dims[a] + 2 * g->pad;
        g->h[a] = vol->spacing[a];
        g->inv2h[a] = 0.5 / vol->spacing[a];
        g->inner_lo[a] = g->pad + 1;
        g->inner_hi[a] = g->pad + vol->dims[a] - 2;
        g->o[a] = vol->origin[a] - (double)g->pad * vol->spacing[a];
    }
    if (vol->strides[0] == 0 && vol->strides[1] == 0 && vol->strides[2] == 0) {
        g->st[0] = (int64_t)size;
        g->st[1] = g->st[0] * g->n[0];
        g->st[2] = g->st[1] * g->n[1];
    } else {
        for (int a = 0; a < 3; a++)
            g->st[a] = vol->strides[a];
    }
    grid_threshold(g);
#if ISOMEND_VERTEX4 || ISOMEND_CLASSIFY_AVX2
    g->avx2 = __builtin_cpu_supports("avx2");
#endif
    c->method = o->method;
    c->general = methods_handles(o->method);
    c->tetra = o->method == ISOMEND_METHOD_TETRA;
    c->planes = c->tetra ? 6 : 3;
    c->flip = (o->flags & ISOMEND_FLAG_FLIP) != 0;
    c->want_normals = !(o->flags & ISOMEND_FLAG_NO_NORMALS);
    c->want_origins = !(o->flags & ISOMEND_FLAG_NO_ORIGINS);
    c->small_pages = (o->flags & ISOMEND_FLAG_SMALL_PAGES) != 0;
#if ISOMEND_VERTEX4
    c->vertex4 = c->want_normals && g->avx2;
#endif
    c->progress = o->progress;
    c->progress_user = o->progress_user;

    const int64_t N0 = g->N[0], N1 = g->N[1], N2 = g->N[2];
    const int64_t layers = N2 - 1;
    int nthreads = o->threads > 0 ? (o->threads > 64 ? 64 : o->threads) : default_threads();
    /* Chunks: enough to balance threads (4 a thread), large enough that the 2
     * slices a chunk classifies again at its start are a small overhead
     * (8 a thread measured 5-15 % slower at 2 threads on 256^3 volumes). */
    const int64_t want = 4 * (int64_t)nthreads;
    int64_t chunk = (layers + want - 1) / want; /* rounded up: chunks of equal size, the
                                                 * last one barely smaller (255 layers on
                                                 * 2 threads: 8 of 32, not 8 of 31 and 1 of 7) */
    if (chunk < 4)
        chunk = 4;
    c->chunk_layers = chunk;
    c->nchunks = (layers + chunk - 1) / chunk;
    if (nthreads > c->nchunks)
        nthreads = (int)c->nchunks;

    isomend_mesh *mesh = NULL;
    worker *ws = calloc((size_t)nthreads, sizeof(*ws));
    c->slice_first = calloc((size_t)N2 + 1, sizeof(uint64_t));
    c->layer_first = calloc((size_t)N2, sizeof(uint64_t));
    c->layer_private = calloc((size_t)N2, sizeof(uint64_t));
    status = ISOMEND_ERR_OUT_OF_MEMORY;
    if (!ws || !c->slice_first || !c->layer_first || !c->layer_private ||
        (uint64_t)N0 * (uint64_t)N1 > (uint64_t)SIZE_MAX / 16)
        goto done;
    for (int t = 0; t < nthreads; t++)
        if (!worker_init(&ws[t], c)) {
            nthreads = t + 1; /* free what was allocated */
            goto done;
        }
    ws[0].is_main = 1;

    uint64_t nv = 0, nt = 0;
    if (nthreads <= 2 && !c->general &&
        (uint64_t)N0 * (uint64_t)N1 * (uint64_t)N2 >= ISOMEND_ONE_PASS_SAMPLES) {
        status = one_pass(c, ws, nthreads, &mesh, &nv, &nt);
        if (status != ISOMEND_ERR_UNSUPPORTED) {
            if (status != ISOMEND_OK)
                goto done;
            goto finish;
        }
    }

    /* The sign cache spares the fill pass a second read of the volume.  It
     * costs 1 bit a sample plus a span per row: kept only when that is at most
     * 1/16 of the input (float volumes), so that peak memory stays within
     * input + mesh + 10 % even for a small mesh; for 8- and 16-bit samples the
     * fill pass classifies again, which costs little. */
    {
        const uint64_t rows = (uint64_t)N1 * (uint64_t)N2;
        const uint64_t words = (uint64_t)(N0 + 63) / 64;
        const uint64_t cache = rows * (8 * words + sizeof(rowinfo));
        const uint64_t input =
            (uint64_t)g->n[0] * (uint64_t)g->n[1] * (uint64_t)g->n[2] * (uint64_t)size;
        if (cache <= input / 16 && rows <= SIZE_MAX / sizeof(rowinfo) &&
            rows * words <= SIZE_MAX / 8) {
            c->words = (int64_t)words;
            c->bits = scratch_alloc((size_t)(rows * words) * 8);
            c->rows = scratch_alloc((size_t)rows * sizeof(rowinfo));
            if (!c->bits || !c->rows) {
                free(c->bits);
                free(c->rows);
                c->bits = NULL;
                c->rows = NULL;
            }
        }
    }

    c->pass = 1;
    status = run_pass(c, ws, nthreads);
    if (status != ISOMEND_OK)
        goto done;

    /* Prefix sums: first vertex of each slice, first triangle of each layer. */
    for (int64_t k = 0; k < N2; k++) {
        uint64_t n = c->slice_first[k];
        c->slice_first[k] = nv;
        nv += n;
    }
    c->slice_first[N2] = nv; /* cube-private vertices follow the slices' */
    for (int64_t k = 0; k < layers; k++) {
        uint64_t n = c->layer_private[k];
        c->layer_private[k] = nv - c->slice_first[N2];
        nv += n;
    }
    for (int64_t k = 0; k < layers; k++) {
        uint64_t n = c->layer_first[k];
        c->layer_first[k] = nt;
        nt += n;
    }
    c->layer_first[layers] = nt;
    if (nv > UINT32_MAX) {
        status = ISOMEND_ERR_TOO_LARGE;
        goto done;
    }

    isomend_mesh_destroy(c->recycled); /* the two passes' arrays are allocated, not reserved */
    c->recycled = NULL;
    status = ISOMEND_ERR_OUT_OF_MEMORY;
    mesh = calloc(1, sizeof(*mesh));
    if (!mesh)
        goto done;
    mesh->nv = (size_t)nv;
    mesh->nt = (size_t)nt;
    mesh->pos = output_alloc(sizeof(float) * 3 * nv, c->small_pages);
    mesh->tri = output_alloc(sizeof(uint32_t) * 3 * nt, c->small_pages);
    if (c->want_normals)
        mesh->nrm = output_alloc(sizeof(float) * 3 * nv, c->small_pages);
    if (c->want_origins)
        mesh->org = output_alloc(nt, c->small_pages);
    if (!mesh->pos || !mesh->tri || (c->want_normals && !mesh->nrm) ||
        (c->want_origins && !mesh->org))
        goto done;
    c->pos = mesh->pos;
    c->nrm = mesh->nrm;
    c->tri = mesh->tri;
    c->org = mesh->org;

    c->pass = 2;
    for (int t = 0; t < nthreads; t++)
        for (int r = 0; r < SIGN_RING; r++)
            ws[t].sk[r] = -1; /* keep buffers, forget contents */
    status = run_pass(c, ws, nthreads);
    if (status != ISOMEND_OK)
        goto done;

finish:
    for (int a = 0; a < 3; a++) {
        mesh->box[a] = g->o[a];
        mesh->box[3 + a] = g->o[a] + (double)(g->N[a] - 1) * g->h[a];
    }
    if (c->progress)
        (void)c->progress(c->progress_user, 1.0);
    if (stats) {
        memset(stats, 0, sizeof(*stats));
        for (int t = 0; t < nthreads; t++) {
            const isomend_stats *s = &ws[t].stats;
            for (int q = 0; q < 15; q++)
                stats->case_histogram[q] += s->case_histogram[q];
            for (int q = 0; q < ISOMEND_ORIGIN_COUNT; q++)
                stats->triangles_by_origin[q] += s->triangles_by_origin[q];
            stats->ambiguous_faces += s->ambiguous_faces;
            stats->inverted_combinations += s->inverted_combinations;
            stats->nan_samples += s->nan_samples;
        }
        stats->cubes = (uint64_t)(N0 - 1) * (uint64_t)(N1 - 1) * (uint64_t)layers;
        stats->vertices = nv;
        stats->triangles = nt;
    }
    *out_mesh = mesh;
    mesh = NULL;
    status = ISOMEND_OK;

done:
    isomend_mesh_destroy(mesh);
    isomend_mesh_destroy(c->recycled);
    if (ws)
        for (int t = 0; t < nthreads; t++)
            worker_free(&ws[t]);
    free(ws);
    free(c->slice_first);
    free(c->layer_first);
    free(c->layer_private);
    free(c->bits);
    free(c->rows);
    free(c);
    return status;
}

/* ------------------------------------------------------------ accessors */

isomend_status isomend_extract(const isomend_volume *vol, const isomend_options *opts,
                               isomend_mesh **out_mesh, isomend_stats *stats)
{
    isomend_mesh *none = NULL;
    return extract(vol, opts, out_mesh, stats, &none);
}

isomend_status isomend_extract_recycle(const isomend_volume *vol, const isomend_options *opts,
                                       isomend_mesh **mesh, isomend_stats *stats)
{
    if (!mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_mesh *old = *mesh;
    const isomend_status status = extract(vol, opts, mesh, stats, &old);
    isomend_mesh_destroy(old); /* not taken: the arguments were refused */
    return status;
}

void isomend_mesh_destroy(isomend_mesh *mesh)
{
    if (!mesh)
        return;
    release_output(mesh->pos, mesh->mapped[0]);
    release_output(mesh->nrm, mesh->mapped[1]);
    release_output(mesh->tri, mesh->mapped[2]);
    release_output(mesh->org, mesh->mapped[3]);
    free(mesh);
}

size_t isomend_mesh_vertex_count(const isomend_mesh *mesh) { return mesh ? mesh->nv : 0; }
size_t isomend_mesh_triangle_count(const isomend_mesh *mesh) { return mesh ? mesh->nt : 0; }
const float *isomend_mesh_positions(const isomend_mesh *mesh) { return mesh ? mesh->pos : NULL; }
const float *isomend_mesh_normals(const isomend_mesh *mesh) { return mesh ? mesh->nrm : NULL; }
const uint32_t *isomend_mesh_triangles(const isomend_mesh *mesh) { return mesh ? mesh->tri : NULL; }
const uint8_t *isomend_mesh_triangle_origins(const isomend_mesh *mesh)
{
    return mesh ? mesh->org : NULL;
}

void isomend_mesh_grid_box(const isomend_mesh *mesh, double box[6])
{
    if (!mesh || !box)
        return;
    memcpy(box, mesh->box, sizeof(mesh->box));
}

isomend_status isomend_mesh_copy(const isomend_mesh *mesh, float *positions, float *normals,
                                 uint32_t *triangles, uint8_t *origins)
{
    if (!mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if ((normals && !mesh->nrm) || (origins && !mesh->org))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (positions)
        memcpy(positions, mesh->pos, sizeof(float) * 3 * mesh->nv);
    if (normals)
        memcpy(normals, mesh->nrm, sizeof(float) * 3 * mesh->nv);
    if (triangles)
        memcpy(triangles, mesh->tri, sizeof(uint32_t) * 3 * mesh->nt);
    if (origins)
        memcpy(origins, mesh->org, mesh->nt);
    return ISOMEND_OK;
}

isomend_status isomend_mesh_check(const isomend_mesh *mesh, isomend_check_report *report)
{
    if (!mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    return isomend_check(mesh->pos, mesh->nv, mesh->tri, mesh->nt, mesh->box, report);
}
