/*
 * smooth.c - isomend_mesh_smooth(): the windowed sinc filter of Taubin,
 * Zhang and Golub (1996, "Optimal surface smoothing as filter design"), the
 * low-pass filter that VTK's vtkWindowedSincPolyDataFilter and 3D Slicer
 * apply, with the umbrella operator; then each component's volume restored.
 *
 * A marching-cubes surface of voxel data is a staircase; plain Laplacian
 * smoothing removes it and shrinks the surface.  The filter is a polynomial
 * of degree N (the iterations) in the umbrella Laplacian K, sum cj Tj(M) x0
 * with Chebyshev's Tj in M = 1 - K/2 (M x = (x + mean x) / 2; K's
 * frequencies k in [0, 2]), evaluated by Clenshaw's recurrence (from cN
 * down: b_k = c_k x0 + 2 M b_(k+1) - b_(k+2), result c_0 x0 + M b_1 - b_2;
 * VTK runs the forward one, x(j+1) = 2 M xj - x(j-1) with a running sum,
 * which reads and writes one array more a step).  The cj are a sinc (an
 * ideal low pass with pass band
 * 0.1) under a Hamming window, its cut-off shifted (Newton) so that the gain
 * at the pass band is 1, then scaled to sum to 1: a translation passes
 * unchanged (VTK's sum is 0.998 for N = 20, which without its
 * NormalizeCoordinates shrinks a mesh towards the origin).  One step of the
 * recurrence costs one umbrella step, so N iterations cost what N of VTK's
 * do; the steps run in float on coordinates centred on the mesh's box, on a
 * team of threads started once (team.c), every vertex from the previous
 * steps only, so the threads' split changes nothing.
 *
 * What volume is still lost is given back per component: its free vertices
 * move along their normals by one offset, (V0 - V1) / A, A the area those
 * vertices carry (a third of each of their triangles'), at most a quarter of
 * the edge of an equilateral triangle of the component's mean triangle area
 * a pass (an island the filter shrank to almost a point grows back
 * gradually), until every component is within 1e-7 of its volume or of what
 * a float's resolution allows (at most eight passes, each on the vertices
 * of the components still to restore).  Volumes and normals come
 * from each vertex's fan, V = sum over vertices of p . N / 18 with N the
 * vertex's area-weighted normal sum (each triangle's a . (b x c) / 6 counted
 * once from each corner; the edges and cross products in float, four lanes
 * at once, the volumes and areas in double), so that they are gathered on
 * threads and summed in vertex order, in fixed blocks of vertices found and
 * summed at once.  Locked vertices (mesh_free_vertices: the border of an
 * unpadded surface, non-manifold places) never move, and the triangles are
 * the input's, so the surface stays closed and oriented.
 */
#include "arena.h"
#include "mesh_internal.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#define PASS_BAND 0.1
#define RESTORE_PASSES 8

/* The n + 1 Chebyshev coefficients of the windowed sinc filter. */
static void sinc_coefficients(int n, double *c)
{
    const double pi = 3.14159265358979323846, theta = acos(1.0 - 0.5 * PASS_BAND);
    double sigma = 0;
    for (int it = 0; it < 100; it++) {
        double f = 0, df = 0;
        for (int i = 0; i <= n; i++) {
            const double w = 0.54 + 0.46 * cos(i * pi / (n + 1)); /* Hamming */
            if (i == 0) {
                c[0] = w * (theta + sigma) / pi;
                df += w / pi;
            } else {
                c[i] = 2.0 * w * sin(i * (theta + sigma)) / (i * pi);
                df += 2.0 * w * cos(i * (theta + sigma)) / pi * cos(i * theta);
            }
            f += c[i] * cos(i * theta); /* T_i(1 - k_pb / 2) */
        }
        if (n < 2 || fabs(f - 1.0) < 1e-12 || !(df != 0))
            break;
        sigma -= (f - 1.0) / df;
    }
    double sum = 0;
    for (int i = 0; i <= n; i++)
        sum += c[i];
    for (int i = 0; i <= n; i++)
        c[i] /= sum;
}

/* ------------------------------------------------------------ the filter */

/* Each vertex's neighbours in a row of fixed length, so that the filter's
 * inner loop has no branch to mispredict on the varying neighbour count:
 * on a mesh of fewer than NEAR_MIN vertices (its arrays in cache, the loop
 * bound by its instructions) WIDE indices (16-bit below 65 536 vertices:
 * a smaller array to fault in), the rest of the row the zero vertex nv
 * (position 0: adding it changes no sum); on a larger one (bound
 * by memory) NEAR 16-bit offsets from the vertex (vertices come in
 * extraction order, so neighbours lie within about a slice's vertices),
 * the rest of the row masked off: 20 bytes a vertex instead of 32, and
 * rows long enough for nearly every vertex (the gyroid's filter: about
 * 15 % less time on one thread; on the phantom's 32 000 vertices the
 * masks cost 10 %, docs/postprocess.md).  The neighbour count in a byte
 * (0: locked, up to the row's length: the row, DEG_MANY: more neighbours,
 * or one further than an offset reaches, summed from the compressed rows),
 * 1 / count from a table; either way the neighbours are summed in their
 * order, a vertex's padding adding +0, so both rows give the same bytes. */
#define WIDE      8
#define SHORT_MAX ((size_t)UINT16_MAX) /* wide rows in 16 bits up to nv */
#define NEAR      10
#define NEAR_MIN  ((size_t)1 << 17)
#define DEG_MANY 255

typedef struct row_job {
    const uint32_t *first, *nb;
    const uint8_t *free_v;
    uint32_t *wide;
    uint16_t *wide16;
    int16_t *near;
    uint8_t *deg;
    size_t nv;
} row_job;

static void row_range(void *arg, size_t lo, size_t hi)
{
    const row_job *j = arg;
    uint8_t *deg = j->deg;
    for (size_t v = lo; v < hi; v++) {
        const uint32_t b = j->first[v], n = j->first[v + 1] - b;
        int fits = n <= (j->near ? NEAR : WIDE);
        if (j->near)
            for (uint32_t k = 0; k < NEAR; k++) {
                const int64_t d = k < n ? (int64_t)j->nb[b + k] - (int64_t)v : 0;
                fits &= d >= INT16_MIN && d <= INT16_MAX;
                j->near[NEAR * v + k] = fits ? (int16_t)d : 0;
            }
        else if (j->wide16)
            for (uint32_t k = 0; k < WIDE; k++)
                j->wide16[WIDE * v + k] = (uint16_t)(k < n ? j->nb[b + k] : j->nv);
        else
            for (uint32_t k = 0; k < WIDE; k++)
                j->wide[WIDE * v + k] = k < n ? j->nb[b + k] : (uint32_t)j->nv;
        deg[v] = !j->free_v[v] || !n ? 0 : fits ? (uint8_t)n : DEG_MANY;
    }
}

/* One step of Clenshaw's recurrence for sum c_k T_k(M) x0, M = (I + W) / 2
 * and W the mean of the neighbours (the identity at a locked vertex):
 * out = ck x0 + gs (g + W g) - H, H = h or hs x0 (h NULL), every vertex from
 * the previous steps' arrays only (h may be out: a vertex reads its own
 * before writing it), so the threads' split changes nothing. */
typedef struct filter_job {
    const uint32_t *first, *nb;
    const uint32_t *wide;   /* the rows: WIDE a vertex (in 32 or */
    const uint16_t *wide16; /* 16 bits), or */
    const int16_t *near;    /* NEAR a vertex (the others NULL) */
    const uint8_t *deg;
    const float *inv; /* 1 / d, d < DEG_MANY (DEG_MANY + 1 of them) */
    const float *x0, *g, *h;
    float *out;
    float ck, gs, hs;
} filter_job;

#if defined(__SSE2__)
/* x, y and z of a float4 into p (the fourth float, the next vertex's x,
 * belongs to another range's thread) */
static inline void store3(float *p, __m128 v)
{
    _mm_storel_pi((__m64 *)(void *)p, v);
    _mm_store_ss(p + 2, _mm_movehl_ps(v, v));
}
#endif

/* Vertices lo .. hi - 1.  With SSE2 a vertex's x, y and z go in one register
 * (loaded with the next vertex's x: the arrays have floats after the last
 * vertex, the zero vertex), lane by lane the same operations in the same
 * order as the plain C below, so the same bytes. */
#if defined(__SSE2__)
/* The sum of all n neighbours of compressed row b, in order (+ 0 for a row's
 * padding). */
static inline __m128 sum_all(const float *g, const uint32_t *nb, uint32_t b, uint32_t n, int row)
{
    __m128 sum = _mm_loadu_ps(g + 3 * (size_t)nb[b]);
    for (uint32_t k = 1; k < n; k++)
        sum = _mm_add_ps(sum, _mm_loadu_ps(g + 3 * (size_t)nb[b + k]));
    return n < (uint32_t)row ? _mm_add_ps(sum, _mm_setzero_ps()) : sum;
}

/* A step's constants in registers (the stores to out could alias the
 * job's floats). */
typedef struct step_k {
    __m128 ck, gs, hs;
    const float *h;
    float *out;
} step_k;

static inline step_k step_consts(const filter_job *j)
{
    return (step_k){_mm_set1_ps(j->ck), _mm_set1_ps(j->gs), _mm_set1_ps(j->hs), j->h, j->out};
}

/* out at vertex v from its x0, g, h and W g */
static inline void step_out(const step_k *c, size_t v, __m128 x, __m128 gv, __m128 wg)
{
    const __m128 hv = c->h ? _mm_loadu_ps(c->h + 3 * v) : _mm_mul_ps(c->hs, x);
    store3(c->out + 3 * v,
           _mm_sub_ps(_mm_add_ps(_mm_mul_ps(c->ck, x), _mm_mul_ps(c->gs, _mm_add_ps(gv, wg))), hv));
}

#define FILTER_WIDE(name, T, field)                                                                \
    static void name(const filter_job *j, size_t lo, size_t hi)                                    \
    {                                                                                              \
        const T *restrict row = j->field;                                                          \
        const uint8_t *restrict deg = j->deg;                                                      \
        const float *restrict x0 = j->x0, *g = j->g;                                               \
        const uint32_t *restrict first = j->first, *restrict nb = j->nb;                           \
        const float *restrict inv = j->inv;                                                        \
        const step_k c = step_consts(j);                                                           \
        for (size_t v = lo; v < hi; v++) {                                                         \
            const __m128 x = _mm_loadu_ps(x0 + 3 * v), gv = _mm_loadu_ps(g + 3 * v);               \
            __m128 wg = gv; /* a locked vertex: W's row is the identity */                         \
            const unsigned dv = deg[v];                                                            \
            if (dv && dv <= WIDE) {                                                                \
                const T *r = row + WIDE * v;                                                       \
                __m128 sum = _mm_loadu_ps(g + 3 * (size_t)r[0]);                                   \
                for (int k = 1; k < WIDE; k++)                                                     \
                    sum = _mm_add_ps(sum, _mm_loadu_ps(g + 3 * (size_t)r[k]));                     \
                wg = _mm_mul_ps(sum, _mm_set1_ps(inv[dv]));                                        \
            } else if (dv) {                                                                       \
                const uint32_t b = first[v], n = first[v + 1] - b;                                 \
                wg = _mm_mul_ps(sum_all(g, nb, b, n, WIDE),                                        \
                                _mm_set1_ps(n < DEG_MANY ? inv[n] : 1.0f / (float)n));             \
            }                                                                                      \
            step_out(&c, v, x, gv, wg);                                                            \
        }                                                                                          \
    }
FILTER_WIDE(filter_wide, uint32_t, wide)
FILTER_WIDE(filter_wide16, uint16_t, wide16)

static void filter_near(const filter_job *j, size_t lo, size_t hi)
{
    const int16_t *restrict row = j->near;
    const uint8_t *restrict deg = j->deg;
    const float *restrict x0 = j->x0, *g = j->g;
    const uint32_t *restrict first = j->first, *restrict nb = j->nb;
    const float *restrict inv = j->inv;
    const step_k c = step_consts(j);
    __m128 mask[NEAR + 1][NEAR]; /* mask[d][k]: whether neighbour k of d counts */
    for (int d = 0; d <= NEAR; d++)
        for (int k = 0; k < NEAR; k++)
            mask[d][k] = _mm_castsi128_ps(_mm_set1_epi32(k < d ? -1 : 0));
    for (size_t v = lo; v < hi; v++) {
        const __m128 x = _mm_loadu_ps(x0 + 3 * v), gv = _mm_loadu_ps(g + 3 * v);
        __m128 wg = gv;
        const unsigned dv = deg[v];
        if (dv && dv <= NEAR) {
            const int16_t *r = row + NEAR * v;
            const float *gb = g + 3 * v;
            __m128 sum = _mm_loadu_ps(gb + 3 * (ptrdiff_t)r[0]);
            for (int k = 1; k < NEAR; k++)
                sum = _mm_add_ps(sum,
                                 _mm_and_ps(_mm_loadu_ps(gb + 3 * (ptrdiff_t)r[k]), mask[dv][k]));
            wg = _mm_mul_ps(sum, _mm_set1_ps(inv[dv]));
        } else if (dv) {
            const uint32_t b = first[v], n = first[v + 1] - b;
            wg = _mm_mul_ps(sum_all(g, nb, b, n, NEAR),
                            _mm_set1_ps(n < DEG_MANY ? inv[n] : 1.0f / (float)n));
        }
        step_out(&c, v, x, gv, wg);
    }
}
#endif

static void filter_range(void *arg, size_t lo, size_t hi)
{
    const filter_job *j = arg;
#if defined(__SSE2__)
    if (j->near)
        filter_near(j, lo, hi);
    else if (j->wide16)
        filter_wide16(j, lo, hi);
    else
        filter_wide(j, lo, hi);
#else
    const uint32_t *restrict first = j->first, *restrict nb = j->nb;
    const uint8_t *restrict deg = j->deg;
    const float *restrict x0 = j->x0, *g = j->g, *h = j->h;
    float *out = j->out;
    const float ck = j->ck, gs = j->gs, hs = j->hs;
    const uint32_t len = j->near ? NEAR : WIDE;
    for (size_t v = lo; v < hi; v++) {
        float wg[3] = {g[3 * v], g[3 * v + 1], g[3 * v + 2]};
        const unsigned dv = deg[v];
        if (dv) {
            const uint32_t b = first[v], n = dv <= len ? dv : first[v + 1] - b;
            float sum[3];
            for (uint32_t k = 0; k < (n > len ? n : len); k++) {
                const size_t u = k >= n      ? v /* padding: + 0 */
                                 : dv > len  ? (size_t)nb[b + k]
                                 : j->near   ? (size_t)((ptrdiff_t)v + j->near[NEAR * v + k])
                                 : j->wide16 ? (size_t)j->wide16[WIDE * v + k]
                                             : (size_t)j->wide[WIDE * v + k];
                for (int d = 0; d < 3; d++) {
                    const float a = k < n ? g[3 * u + (size_t)d] : 0.0f;
                    sum[d] = k ? sum[d] + a : a;
                }
            }
            const float inv = n < DEG_MANY ? j->inv[n] : 1.0f / (float)n;
            for (int d = 0; d < 3; d++)
                wg[d] = sum[d] * inv;
        }
        float o[3];
        for (int d = 0; d < 3; d++) {
            const float x = x0[3 * v + (size_t)d];
            const float hv = h ? h[3 * v + (size_t)d] : hs * x;
            o[d] = (ck * x + gs * (g[3 * v + (size_t)d] + wg[d])) - hv;
        }
        for (int d = 0; d < 3; d++)
            out[3 * v + (size_t)d] = o[d];
    }
#endif
}

/* The windowed sinc filter of `iterations` (>= 1) steps on n vertices
 * whose neighbours are nb[first[v] .. first[v + 1]) (free_v[v] 0: the
 * vertex stays), from the centred positions x0 into out, on team tm; x0,
 * b and out hold 3 n + 4 floats (x0's last 4 zero: the zero vertex), b
 * and deg (n bytes) are scratch, row sinc_row_bytes(n) bytes (NULL: allocated
 * here).  0 without memory. */
size_t sinc_row_bytes(size_t n)
{
    const int near = n >= NEAR_MIN, wide16 = !near && n <= SHORT_MAX;
    return (near ? NEAR * sizeof(int16_t) : WIDE * (wide16 ? 2 : 4)) * (n ? n : 1);
}

int sinc_filter(team *tm, size_t n, const uint32_t *first, const uint32_t *nb,
                const uint8_t *free_v, const float *x0, float *b, uint8_t *deg, float *out,
                int iterations, void *row)
{
    const size_t nv = n;
    double *c = malloc(8 * ((size_t)iterations + 1));
    const int near = nv >= NEAR_MIN, wide16 = !near && nv <= SHORT_MAX;
    void *own = row ? NULL : malloc(sinc_row_bytes(nv));
    if (!c || (!row && !own)) {
        free(c);
        free(own);
        return 0;
    }
    if (!row)
        row = own;
    for (int d = 0; d < 4; d++) /* the zero vertex */
        b[3 * nv + (size_t)d] = out[3 * nv + (size_t)d] = 0;
    sinc_coefficients(iterations, c);
    uint32_t *wide = near || wide16 ? NULL : row;
    uint16_t *short_row = wide16 ? row : NULL;
    int16_t *near_row = near ? row : NULL;
    row_job rj = {first, nb, free_v, wide, short_row, near_row, deg, nv};
    team_for(tm, nv, row_range, &rj);
    float inv[DEG_MANY + 1];
    inv[0] = inv[DEG_MANY] = 0;
    for (int d = 1; d < DEG_MANY; d++)
        inv[d] = 1.0f / (float)d;
    /* Clenshaw: b_(N+1) = b_(N+2) = 0, b_k = c_k x0 + 2 M b_(k+1) - b_(k+2)
     * down to k = 1, result c_0 x0 + M b_1 - b_2; b_N = c_N x0 is not
     * stored, and the b_k alternate between two arrays, b_2 in the
     * output's so that the last step writes over it */
    const int N = iterations;
    float *buf[2] = {N % 2 ? out : b, N % 2 ? b : out};
    filter_job job = {first, nb, wide, short_row, near_row, deg, inv, x0, x0, NULL, NULL, 0, 0, 0};
    if (N >= 2) {
        job.ck = (float)c[N - 1]; /* b_(N-1) = c_(N-1) x0 + c_N 2 M x0 */
        job.g = x0;
        job.gs = (float)c[N];
        job.h = NULL;
        job.hs = 0;
        job.out = buf[0];
        team_for(tm, nv, filter_range, &job);
        for (int k = N - 2; k >= 1; k--) {
            const int i = (N - 1 - k) % 2;
            job.ck = (float)c[k];
            job.g = buf[1 - i]; /* b_(k+1) */
            job.gs = 1;
            job.h = k == N - 2 ? NULL : buf[i]; /* b_(k+2), or c_N x0 */
            job.hs = k == N - 2 ? (float)c[N] : 0;
            job.out = buf[i];
            team_for(tm, nv, filter_range, &job);
        }
    }
    job.ck = (float)c[0]; /* c_0 x0 + M b_1 - b_2 */
    job.g = N >= 2 ? buf[(N - 2) % 2] : x0;
    job.gs = N >= 2 ? 0.5f : (float)(0.5 * c[1]);
    job.h = N >= 3 ? buf[(N - 3) % 2] : NULL;
    job.hs = N == 2 ? (float)c[2] : 0;
    job.out = out;
    team_for(tm, nv, filter_range, &job);
    free(c);
    free(own);
    return 1;
}

/* Each vertex's area-weighted normal sum N (twice the area of its
 * triangles, right-hand winding; in float), its area |N| / 6 and its part
 * of the enclosed volume, p . N / 18, from its fan (the next and prev
 * vertex of each corner), of positions p.  In float the fans take a fifth
 * less time than in double (docs/postprocess.md); what they measure moves
 * by about 3e-10 of a volume, below the restoration's 1e-7, and a vertex's
 * normal by up to 2e-5. */
typedef struct fan_job {
    const uint32_t *first, *next, *prev;
    const uint32_t *list; /* the vertices (NULL: all), by index */
    const float *p;
    float *nrm;
    double *vol, *area;
} fan_job;

/* Vertex v's fan: its normal sum into nrm, its volume and area returned.
 * The edges and cross products in float (SSE2: a vertex's x, y, z in one
 * register; the plain C the same operations in the same order), the volume
 * and area in double. */
#if defined(__SSE2__)
static inline __m128 load3(const float *p) /* x, y, z, 0 (no read past z) */
{
    return _mm_movelh_ps(_mm_loadl_pi(_mm_setzero_ps(), (const __m64 *)(const void *)p),
                         _mm_load_ss(p + 2));
}
#endif

static inline void fan_vertex(const fan_job *j, size_t v, double *vol, double *area)
{
    const uint32_t *restrict first = j->first, *restrict next = j->next, *restrict prev = j->prev;
    const float *restrict p = j->p;
    float n[4];
#if defined(__SSE2__)
    const __m128 a = load3(p + 3 * v);
    __m128 sum = _mm_setzero_ps();
    for (uint32_t k = first[v]; k < first[v + 1]; k++) {
        const __m128 e = _mm_sub_ps(load3(p + 3 * (size_t)next[k]), a);
        const __m128 f = _mm_sub_ps(load3(p + 3 * (size_t)prev[k]), a);
        const __m128 e1 = _mm_shuffle_ps(e, e, _MM_SHUFFLE(3, 0, 2, 1)); /* y z x */
        const __m128 f2 = _mm_shuffle_ps(f, f, _MM_SHUFFLE(3, 1, 0, 2)); /* z x y */
        const __m128 e2 = _mm_shuffle_ps(e, e, _MM_SHUFFLE(3, 1, 0, 2));
        const __m128 f1 = _mm_shuffle_ps(f, f, _MM_SHUFFLE(3, 0, 2, 1));
        sum = _mm_add_ps(sum, _mm_sub_ps(_mm_mul_ps(e1, f2), _mm_mul_ps(e2, f1)));
    }
    _mm_storeu_ps(n, sum);
#else
    const float a0 = p[3 * v], a1 = p[3 * v + 1], a2 = p[3 * v + 2];
    n[0] = n[1] = n[2] = 0;
    for (uint32_t k = first[v]; k < first[v + 1]; k++) {
        const float *b = p + 3 * (size_t)next[k], *d = p + 3 * (size_t)prev[k];
        const float e0 = b[0] - a0, e1 = b[1] - a1, e2 = b[2] - a2;
        const float f0 = d[0] - a0, f1 = d[1] - a1, f2 = d[2] - a2;
        n[0] += e1 * f2 - e2 * f1;
        n[1] += e2 * f0 - e0 * f2;
        n[2] += e0 * f1 - e1 * f0;
    }
#endif
    j->nrm[3 * v] = n[0];
    j->nrm[3 * v + 1] = n[1];
    j->nrm[3 * v + 2] = n[2];
    const double n0 = n[0], n1 = n[1], n2 = n[2];
    *vol = ((double)p[3 * v] * n0 + (double)p[3 * v + 1] * n1 + (double)p[3 * v + 2] * n2) / 18.0;
    *area = sqrt(n0 * n0 + n1 * n1 + n2 * n2) / 6.0;
}

static void fan_range(void *arg, size_t lo, size_t hi)
{
    const fan_job *j = arg;
    for (size_t i = lo; i < hi; i++) {
        const size_t v = j->list ? j->list[i] : i;
        fan_vertex(j, v, &j->vol[v], &j->area[v]);
    }
}

/* Per-component sums over the vertices of a fan sweep: each component's
 * volume and the area of its free vertices (and, on the input, the area of
 * all its vertices and its corners: the step limit).  With few components
 * (up to SUM_DENSE) each fixed block of SUM_BLOCK vertices has its fans
 * found and summed at once on the team (no per-vertex arrays, no second
 * pass), a row of sums a block, then the blocks in order; with more, the
 * fans on the team and the sums on this thread in vertex order.  Either way
 * the same bytes for any number of threads. */
#define SUM_BLOCK 4096
#define SUM_DENSE 256
#define SUM_FIELDS 4 /* volume, free area, area, corners */

typedef struct sum_job {
    const fan_job *fan;
    const uint32_t *label, *first;
    const uint8_t *free_v;
    size_t n, nc;
    int fields;
    double *part; /* a block's SUM_FIELDS sums a component */
    uint8_t *seen; /* a block's: whether it holds a vertex of the component */
} sum_job;

static void sum_blocks(void *arg, size_t b0, size_t b1)
{
    const sum_job *j = arg;
    const fan_job *f = j->fan;
    for (size_t b = b0; b < b1; b++) {
        double *part = j->part + b * j->nc * SUM_FIELDS;
        uint8_t *seen = j->seen + b * j->nc;
        memset(part, 0, j->nc * SUM_FIELDS * sizeof(double));
        memset(seen, 0, j->nc);
        const size_t end = (b + 1) * SUM_BLOCK < j->n ? (b + 1) * SUM_BLOCK : j->n;
        for (size_t i = b * SUM_BLOCK; i < end; i++) {
            const size_t v = f->list ? f->list[i] : i;
            const uint32_t k = j->label[v];
            double *s = part + (size_t)k * SUM_FIELDS, vol, area;
            fan_vertex(f, v, &vol, &area);
            seen[k] = 1;
            s[0] += vol;
            s[1] += j->free_v[v] ? area : 0;
            if (j->fields > 2) {
                s[2] += area;
                s[3] += j->first[v + 1] - j->first[v];
            }
        }
    }
}

/* The fans of positions p on the team, of the n vertices of j->list (or of
 * all); the sums of each component they touch found anew (out[f] the f-th
 * sum a component; fields 4 with first, else 2); part and seen room for
 * the blocks' sums (NULL: more components than SUM_DENSE). */
static void fans(team *t, fan_job *j, const float *p, size_t n, const uint32_t *label,
                 const uint8_t *free_v, const uint32_t *first, size_t nc, double *part,
                 uint8_t *seen, double *const out[SUM_FIELDS])
{
    j->p = p;
    const int fields = first ? 4 : 2;
    if (part) {
        const size_t nblocks = (n + SUM_BLOCK - 1) / SUM_BLOCK;
        sum_job sj = {j, label, first, free_v, n, nc, fields, part, seen};
        team_for_from(t, nblocks, 1, sum_blocks, &sj);
        for (size_t k = 0; k < nc; k++) {
            double sum[SUM_FIELDS] = {0, 0, 0, 0};
            int any = 0;
            for (size_t b = 0; b < nblocks; b++)
                if (seen[b * nc + k]) {
                    any = 1;
                    for (int f = 0; f < fields; f++)
                        sum[f] += part[(b * nc + k) * SUM_FIELDS + (size_t)f];
                }
            if (any)
                for (int f = 0; f < fields; f++)
                    out[f][k] = sum[f];
        }
        return;
    }
    team_for(t, n, fan_range, j);
    for (size_t i = 0; i < n; i++) {
        const uint32_t k = label[j->list ? j->list[i] : i];
        for (int f = 0; f < fields; f++)
            out[f][k] = 0;
    }
    for (size_t i = 0; i < n; i++) {
        const size_t v = j->list ? j->list[i] : i;
        const uint32_t k = label[v];
        out[0][k] += j->vol[v];
        out[1][k] += free_v[v] ? j->area[v] : 0;
        if (fields > 2) {
            out[2][k] += j->area[v];
            out[3][k] += first[v + 1] - first[v];
        }
    }
}

/* Every free vertex moved along its normal by its component's offset. */
typedef struct move_job {
    const uint32_t *list; /* the vertices, by index */
    const uint8_t *free_v;
    const uint32_t *label;
    const float *nrm;
    const double *delta;
    float *p;
} move_job;

static void move_range(void *arg, size_t lo, size_t hi)
{
    const move_job *j = arg;
    for (size_t i = lo; i < hi; i++) {
        const size_t v = j->list[i];
        const float *n = j->nrm + 3 * v;
        const double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        if (!j->free_v[v] || !(len > 0))
            continue;
        const double s = j->delta[j->label[v]] / len;
        for (int d = 0; d < 3; d++)
            j->p[3 * v + (size_t)d] = (float)(j->p[3 * v + (size_t)d] + s * n[d]);
    }
}

/* The output's positions from the filter's sum (centred) and its normals
 * from the fans; each vertex's squared displacement into d2. */
typedef struct out_job {
    const isomend_mesh *in;
    const uint8_t *free_v;
    const float *nrm, *mid;
    float *pos, *out_nrm; /* out_nrm NULL: positions only */
    double *d2;
    int smoothed;
} out_job;

static void place_range(void *arg, size_t lo, size_t hi)
{
    const out_job *j = arg;
    for (size_t v = lo; v < hi; v++)
        for (int d = 0; d < 3; d++) {
            float *x = j->pos + 3 * v + (size_t)d;
            *x = j->free_v[v] && j->smoothed ? *x + j->mid[d] : j->in->pos[3 * v + (size_t)d];
        }
}

static void finish_range(void *arg, size_t lo, size_t hi)
{
    const out_job *j = arg;
    for (size_t v = lo; v < hi; v++) {
        double d2 = 0;
        for (int d = 0; d < 3; d++) {
            const double dd = (double)j->pos[3 * v + (size_t)d] - j->in->pos[3 * v + (size_t)d];
            d2 += dd * dd;
        }
        j->d2[v] = d2;
        if (!j->out_nrm)
            continue;
        const float *n = j->nrm + 3 * v;
        const double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
        for (int d = 0; d < 3; d++) /* as mesh_area_normals() makes them */
            j->out_nrm[3 * v + (size_t)d] = len > 0 && isfinite(len) ? (float)(n[d] / len)
                                                                     : j->in->nrm[3 * v + (size_t)d];
    }
}

typedef struct centre_job {
    const float *pos, *mid;
    float *x;
} centre_job;

static void centre_range(void *arg, size_t lo, size_t hi)
{
    const centre_job *j = arg;
    for (size_t i = 3 * lo; i < 3 * hi; i++)
        j->x[i] = j->pos[i] - j->mid[i % 3];
}

/* The box of the positions and the count of free vertices, in BOX_BLOCKS
 * fixed blocks (an empty block's box is its neighbours': no vertex, the
 * first vertex's box). */
#define BOX_BLOCKS 64
typedef struct box_job {
    const float *pos;
    const uint8_t *free_v;
    size_t nv;
    float lo[BOX_BLOCKS][3], hi[BOX_BLOCKS][3];
    uint64_t moved[BOX_BLOCKS];
} box_job;

static void box_range(void *arg, size_t b0, size_t b1)
{
    box_job *j = arg;
    for (size_t b = b0; b < b1; b++) {
        const size_t lo = j->nv * b / BOX_BLOCKS, hi = j->nv * (b + 1) / BOX_BLOCKS;
        const size_t v0 = lo < hi ? lo : 0; /* an empty block: vertex 0 (or none) */
        uint64_t moved = 0;
        for (int d = 0; d < 3; d++)
            j->lo[b][d] = j->hi[b][d] = j->nv ? j->pos[3 * v0 + (size_t)d] : 0;
        for (size_t v = lo; v < hi; v++) {
            for (int d = 0; d < 3; d++) {
                const float x = j->pos[3 * v + (size_t)d];
                j->lo[b][d] = x < j->lo[b][d] ? x : j->lo[b][d];
                j->hi[b][d] = x > j->hi[b][d] ? x : j->hi[b][d];
            }
            moved += j->free_v[v];
        }
        j->moved[b] = moved;
    }
}

typedef struct copy_job {
    const uint32_t *from;
    uint32_t *to;
} copy_job;

static void copy_range(void *arg, size_t lo, size_t hi) /* triangles */
{
    const copy_job *j = arg;
    memcpy(j->to + 3 * lo, j->from + 3 * lo, 12 * (hi - lo));
}

typedef struct comp_job {
    const isomend_mesh *mesh;
    uint32_t *label;
    int64_t count;
} comp_job;

static void *comp_main(void *arg)
{
    comp_job *j = arg;
    j->count = mesh_components(j->mesh, j->label);
    return NULL;
}

/* --------------------------------------------------------------- the step */

isomend_status isomend_mesh_smooth(const isomend_mesh *mesh, int iterations, isomend_mesh **out,
                                   isomend_smooth_report *report)
{
    return mesh_smooth(mesh, iterations, out, report, NULL);
}

isomend_status mesh_smooth(const isomend_mesh *mesh, int iterations, isomend_mesh **out,
                           isomend_smooth_report *report, uint64_t *bytes)
{
    if (bytes)
        *bytes = 0;
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    if (!mesh || iterations < 0 || iterations > 10000)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    const size_t nv = mesh->nv, nv1 = nv ? nv : 1;
    isomend_status status = ISOMEND_ERR_OUT_OF_MEMORY;
    /* the working arrays and the output's in one arena (arena.c): faulted
     * in at once, not a page at a time; the output's normals and triangles
     * are working arrays first (xb, prev), done with by then */
    const size_t nc3 = 3 * (mesh->nt ? mesh->nt : 1);
    arena ar;
    const size_t need = arena_bytes(nv1) + arena_bytes(4 * nv1) + arena_bytes(12 * nv1 + 16) +
                        (mesh->nrm ? arena_page_bytes(12 * nv1 + 16) : arena_bytes(12 * nv1 + 16)) +
                        arena_bytes(12 * nv1) + 2 * arena_bytes(8 * nv1) +
                        arena_bytes(4 * (nv1 + 1)) + arena_bytes(4 * nc3) + arena_page_bytes(4 * nc3) +
                        arena_page_bytes(12 * nv1 + 16) +
                        (iterations > 0 ? arena_bytes(sinc_row_bytes(nv)) : 0);
    isomend_mesh *m = calloc(1, sizeof(*m));
    if (!m || !arena_open(&ar, need)) {
        free(m);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    /* the output's arrays in m at once, so that a failure hands them back with m */
    m->pos = arena_take_pages(&ar, 12 * nv1 + 16, &m->mapped[0]); /* + 16: the filter's zero vertex */
    uint32_t *prev = m->tri = arena_take_pages(&ar, 4 * nc3, &m->mapped[2]);
    float *xb = mesh->nrm ? (m->nrm = arena_take_pages(&ar, 12 * nv1 + 16, &m->mapped[1]))
                          : arena_take(&ar, 12 * nv1 + 16);
    uint8_t *free_v = arena_take(&ar, nv1);
    uint32_t *label = arena_take(&ar, nv1 * sizeof(uint32_t));
    uint32_t *first = arena_take(&ar, 4 * (nv1 + 1)), *next = arena_take(&ar, 4 * nc3);
    float *xa = arena_take(&ar, 12 * nv1 + 16), *nrm = arena_take(&ar, 12 * nv1);
    double *vv = arena_take(&ar, 8 * nv1), *va = arena_take(&ar, 8 * nv1);
    void *row = iterations > 0 ? arena_take(&ar, sinc_row_bytes(nv)) : NULL;
    double *v0 = NULL, *v1 = NULL, *area = NULL, *edge = NULL, *delta = NULL, *part = NULL;
    uint8_t *seen = NULL;
    team *tm = NULL;
    if (!m->pos || !xb || !prev || !free_v || !label || !first || !next || !xa || !nrm || !vv ||
        !va || (iterations > 0 && !row))
        goto done;
    for (int d = 0; d < 4; d++) /* the zero vertex nv (and its fourth float) */
        xa[3 * nv + (size_t)d] = xb[3 * nv + (size_t)d] = 0;
    /* the loops on one team of threads, started once (a loop under
     * TEAM_MIN_ITEMS a thread runs on this one) */
    tm = team_start(nv);
    /* the components (serial) on a thread of their own while the fans are
     * filed (serial too, then tested on the team) */
    comp_job cjob = {mesh, label, 0};
    pthread_t comp_thread;
    const int comp_started = nv >= 8192 && pthread_create(&comp_thread, NULL, comp_main, &cjob) == 0;
    if (!comp_started)
        comp_main(&cjob);
    mesh_free_vertices_into(mesh, tm, free_v, first, next, prev);
    if (comp_started)
        pthread_join(comp_thread, NULL);
    const int64_t nc = cjob.count;
    const size_t nc1 = (size_t)nc + 1;
    v0 = malloc(nc1 * sizeof(double));
    v1 = malloc(nc1 * sizeof(double));
    area = malloc(nc1 * sizeof(double));
    edge = calloc(nc1, sizeof(double));
    delta = calloc(nc1, sizeof(double));
    m->nv = nv;
    m->nt = mesh->nt;
    if (!v0 || !v1 || !area || !edge || !delta)
        goto done;
    for (int d = 0; d < 4; d++)
        m->pos[3 * nv + (size_t)d] = 0;

    /* the input's volumes, and each component's mean triangle area: a
     * quarter of the edge of an equilateral triangle of that area is the
     * largest step the volume restoration takes at once */
    fan_job fj = {first, next, prev, NULL, NULL, nrm, vv, va};
    if (nc <= SUM_DENSE) {
        const size_t nblocks = (nv + SUM_BLOCK - 1) / SUM_BLOCK;
        part = malloc(nblocks * (size_t)nc * SUM_FIELDS * sizeof(double) + 1);
        seen = malloc(nblocks * (size_t)nc + 1);
        if (!part || !seen)
            goto done;
    }
    double *const sums0[SUM_FIELDS] = {v0, area, edge, delta}, *const sums1[SUM_FIELDS] = {v1, area};
    fans(tm, &fj, mesh->pos, nv, label, free_v, first, (size_t)nc, part, seen, sums0);
    for (int64_t k = 0; k < nc; k++)
        edge[k] = delta[k] > 0 ? 0.25 * sqrt(4.0 * (3.0 * edge[k] / delta[k]) / sqrt(3.0)) : 0;
    /* the filter, on coordinates centred on the box of the vertices (found
     * in fixed blocks, so the same for any threads) */
    box_job bj = {mesh->pos, free_v, nv, {{0}}, {{0}}, {0}};
    team_for_from(tm, BOX_BLOCKS, 2, box_range, &bj);
    float lo[3], hi[3], mid[3];
    uint64_t moved = 0;
    for (int b = 0; b < BOX_BLOCKS; b++) {
        for (int d = 0; d < 3; d++) {
            lo[d] = b == 0 || bj.lo[b][d] < lo[d] ? bj.lo[b][d] : lo[d];
            hi[d] = b == 0 || bj.hi[b][d] > hi[d] ? bj.hi[b][d] : hi[d];
        }
        moved += bj.moved[b];
    }
    double ulp = 0; /* the resolution of the positions' floats */
    for (int d = 0; d < 3; d++) {
        mid[d] = 0.5f * (lo[d] + hi[d]);
        ulp = fmax(ulp, 2.0 * FLT_EPSILON * fmax(fabs(lo[d]), fabs(hi[d])));
    }
    if (iterations > 0) {
        centre_job cj = {mesh->pos, mid, xa};
        team_for(tm, nv, centre_range, &cj);
        /* the neighbour counts in nrm while the filter runs (the fans write
         * it before and after) */
        if (!sinc_filter(tm, nv, first, next, free_v, xa, xb, (uint8_t *)nrm, m->pos, iterations,
                         row))
            goto done;
    }
    /* (the filter is done with its scratch xb: m->nrm from here on) */
    /* back to the mesh's coordinates; locked vertices exactly where they were */
    out_job oj = {mesh, free_v, nrm, mid, m->pos, NULL, vv, iterations > 0};
    team_for(tm, nv, place_range, &oj);

    /* the volume back, per component, along the normals: a few passes, each
     * step at most a quarter of the mean edge (a small island that the
     * filter shrank to almost a point grows back over several) */
    fans(tm, &fj, m->pos, nv, label, free_v, NULL, (size_t)nc, part, seen, sums1);
    /* the passes move the vertices of the components not yet restored,
     * listed in todo (in xa: the filter is done with it) */
    uint32_t *todo = (uint32_t *)xa;
    size_t ntodo = nv;
    for (size_t v = 0; v < nv; v++)
        todo[v] = (uint32_t)v;
    for (int pass = 0; pass < RESTORE_PASSES && iterations > 0 && ntodo > 0; pass++) {
        int restored = 1; /* every component within float precision: done */
        for (int64_t k = 0; k < nc; k++) { /* (one restored before stays so) */
            /* within 1e-7 of its volume, or of what a move of a float's
             * resolution over its free area can change (a small island) */
            const int done_k = !(area[k] > 0) ||
                               fabs(v1[k] - v0[k]) <= 1e-7 * fabs(v0[k]) + area[k] * ulp;
            const double limit = edge[k], dk = done_k ? 0 : (v0[k] - v1[k]) / area[k];
            delta[k] = dk > limit ? limit : dk < -limit ? -limit : dk;
            restored &= done_k;
        }
        if (restored)
            break;
        size_t n = 0;
        for (size_t i = 0; i < ntodo; i++)
            if (delta[label[todo[i]]] != 0)
                todo[n++] = todo[i];
        ntodo = n;
        move_job mj = {todo, free_v, label, nrm, delta, m->pos};
        team_for(tm, ntodo, move_range, &mj);
        fj.list = todo;
        fans(tm, &fj, m->pos, ntodo, label, free_v, NULL, (size_t)nc, part, seen, sums1);
    }
    /* the normals of what the passes did not move: from fans1, current */
    if (m->nrm && iterations == 0)
        memcpy(m->nrm, mesh->nrm, 12 * nv);
    oj.out_nrm = iterations > 0 ? m->nrm : NULL;
    team_for(tm, nv, finish_range, &oj);
    /* m->tri: the fans are done with prev */
    copy_job tj = {mesh->tri, m->tri};
    team_for(tm, mesh->nt, copy_range, &tj);
    if (mesh_copy_frame(m, mesh) != ISOMEND_OK)
        goto done;
    if (bytes) { /* everything above is held at once (the filter's rows with it) */
        const uint64_t n1 = nv1, c3 = 3 * (uint64_t)(mesh->nt ? mesh->nt : 1);
        *bytes =
            n1 * (1 + 4 + 12 + 16) + 3 * (12 * n1 + 16) + sizeof *m + 4 * (n1 + 1) + 8 * c3 +
            5 * 8 * (uint64_t)nc1 +
            (nc <= SUM_DENSE ? ((nv + SUM_BLOCK - 1) / SUM_BLOCK) * (uint64_t)nc *
                                       (SUM_FIELDS * sizeof(double) + 1) +
                                   2
                             : 0) +
            (iterations > 0 ? 8 * ((uint64_t)iterations + 1) + sinc_row_bytes(nv) : 0) +
            (m->slice_store ? 24 * (uint64_t)m->slices.n : 0);
    }
    if (report) {
        double worst = 0;
        for (size_t v = 0; v < nv; v++)
            worst = vv[v] > worst ? vv[v] : worst;
        report->moved_vertices = moved;
        report->volume_before = report->volume_after = 0;
        for (int64_t k = 0; k < nc; k++) {
            report->volume_before += v0[k];
            report->volume_after += v1[k];
        }
        report->max_displacement = sqrt(worst);
    }
    *out = m;
    m = NULL;
    status = ISOMEND_OK;
done:
    team_stop(tm);
    isomend_mesh_destroy(m); /* on failure: the output's arrays back */
    arena_close(&ar);
    free(v0);
    free(v1);
    free(area);
    free(edge);
    free(delta);
    free(part);
    free(seen);
    return status;
}
