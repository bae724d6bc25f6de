/*
 * vertex_inline.h - what the vertex loops of every voxel type share
 * (private; included by kernels_template.h before vertex_loops_template.h).
 *
 * Vertices.  The samples around a vertex lie in four slices and four rows,
 * which the classification long ago evicted from the caches.  Where a row
 * has many crossings (a wide span) its vertices are computed at once, in row
 * order, and the hardware prefetcher follows the rows.  Where it has a few
 * (narrow spans: the rim of a blob) they are isolated lines the hardware
 * does not foresee, and the loads' latency dominates.  Those crossings are
 * numbered and listed per axis as (id, column, row), and the lists are
 * computed in bulk, each item prefetching the samples of the item
 * VERTEX_PREFETCH places ahead when it lies off its predecessor's cache
 * line.  Ids are fixed at numbering, so the order of computation changes
 * nothing.  (docs/core-internals.md has the measurements behind this.)
 *
 * The computation is specialised per voxel type and axis: typed loads, the
 * interior test done per vertex.  Vertices near the border, next to NaN or
 * padding take the general path (make_vertex, vertices.c); both compute
 * t = (iso - f0) / (f1 - f0) and the position in the same way.
 */
#ifndef ISOMEND_VERTEX_INLINE_H
#define ISOMEND_VERTEX_INLINE_H

#include "context.h"

#define ALWAYS_INLINE inline __attribute__((always_inline))

/* The constants of the vertex loops for slice m and edges along one axis. */
typedef struct vertex_setup {
    const grid *g;
    float *P, *NR; /* positions, normals (NULL without) */
    uint64_t base; /* the id at P[0] (ctx.vertex_base) */
    int flip;
    int64_t sx, sy, sz, sa; /* strides along x, y, z and along the edges' axis */
    int64_t pad, m;
    int slice_inner;                /* slice m (and m + 1 for z edges) is inside the inner box */
    int64_t x_lo, x_hi, y_lo, y_hi; /* the inner box for the edges' lower ends */
    const char *slice; /* the samples of slice m (of the volume, not the padded grid) */
    double iso, ox, hx, oy, hy, oz, hz, pz0;
    float fz;          /* the z coordinate of slice m */
    double ix, iy, iz; /* 1 / (2 spacing) */
    double sgn;        /* -1 with ISOMEND_FLAG_FLIP, else 1 */
} vertex_setup;

static ALWAYS_INLINE void vertex_setup_init(vertex_setup *s, const ctx *c, int64_t m,
                                            const int axis)
{
    const grid *g = &c->g;
    s->g = g;
    s->P = c->pos;
    s->NR = c->nrm;
    s->base = c->vertex_base;
    s->flip = c->flip;
    s->sx = g->st[0];
    s->sy = g->st[1];
    s->sz = g->st[2];
    s->sa = g->st[axis];
    s->pad = g->pad;
    s->m = m;
    /* slices where they are: every vertex takes make_vertex */
    s->slice_inner = !g->slices.so && m >= g->inner_lo[2] && m + (axis == 2) <= g->inner_hi[2];
    s->x_lo = g->inner_lo[0];
    s->x_hi = g->inner_hi[0] - (axis == 0);
    s->y_lo = g->inner_lo[1];
    s->y_hi = g->inner_hi[1] - (axis == 1);
    /* integer arithmetic: with padding, slice m - pad may be -1 */
    s->slice = (const char *)((uintptr_t)g->data + (uintptr_t)((m - g->pad - g->z0) * s->sz));
    s->iso = g->iso;
    s->ox = g->o[0];
    s->hx = g->h[0];
    s->oy = g->o[1];
    s->hy = g->h[1];
    s->oz = g->o[2];
    s->hz = g->h[2];
    s->pz0 = (double)m;
    s->fz = (float)(s->oz + s->pz0 * s->hz);
    s->ix = g->inv2h[0];
    s->iy = g->inv2h[1];
    s->iz = g->inv2h[2];
    s->sgn = c->flip ? -1.0 : 1.0;
}

/*
 * In a list loop: prefetches the samples list item it[e] will read, unless it
 * lies on its predecessor's cache line (`line`: samples a line).
 */
static ALWAYS_INLINE void prefetch_item(const vertex_setup *s, const int axis,
                                        const vertex_item *it, size_t e, int32_t line)
{
    if (e > 0 && it[e].j == it[e - 1].j && it[e].x - it[e - 1].x < line)
        return;
    const int64_t sx = s->sx, sy = s->sy, sz = s->sz;
    const int64_t o = ((int64_t)it[e].x - s->pad) * sx + ((int64_t)it[e].j - s->pad) * sy;
    prefetch_at(s->slice, o);
    prefetch_at(s->slice, o + s->sa);
    if (s->NR) {
        prefetch_at(s->slice, o - sy);
        prefetch_at(s->slice, o + (axis == 1 ? 2 : 1) * sy);
        prefetch_at(s->slice, o - sz);
        prefetch_at(s->slice, o + (axis == 2 ? 2 : 1) * sz);
        if (axis == 1) {
            prefetch_at(s->slice, o + sy - sz);
            prefetch_at(s->slice, o + sy + sz);
        } else if (axis == 2) {
            prefetch_at(s->slice, o + sz - sy);
            prefetch_at(s->slice, o + sz + sy);
        }
    }
}

#if KERNELS_AVX2
/*
 * Four vertices at a time (AVX2, with normals: the arithmetic is then most
 * of a vertex's cost).  The lanes do vertex_one's operations in its order on
 * doubles, with no fused multiply-add, so the mesh is bit for bit the scalar
 * path's (core_simd_identical compares them on every sample type).
 */

/* The results of four vertices: position and normal lanes. */
typedef struct vertex4_lanes {
    __m128 px, py, pz, nx, ny, nz;
} vertex4_lanes;

/* Four (x, y, z) float lanes to four consecutive triples at out[0..11]. */
static inline void store_xyz4(float *out, __m128 x, __m128 y, __m128 z)
{
    __m128 w = _mm_setzero_ps();
    _MM_TRANSPOSE4_PS(x, y, z, w); /* rows: (x_l, y_l, z_l, 0) */
    _mm_storeu_ps(out, x);
    _mm_storeu_ps(out + 3, y); /* each store's fourth float is overwritten */
    _mm_storeu_ps(out + 6, z); /* by the next, and the last is kept out    */
    _mm_storel_pi((__m64 *)(void *)(out + 9), w);
    _mm_store_ss(out + 11, _mm_movehl_ps(w, w));
}

/* Four (x, y, z) float lanes to the triples of vertices v[0..3].id in out.
 * Each lane is stored on its own: the ids of a list are not consecutive, and
 * a 16-byte store could reach another thread's vertex. */
static inline void store_items4(float *out, uint64_t base, const vertex_item *v, __m128 x,
                                __m128 y, __m128 z)
{
    __m128 w = _mm_setzero_ps();
    _MM_TRANSPOSE4_PS(x, y, z, w); /* rows: (x_l, y_l, z_l, 0) */
    const __m128 row[4] = {x, y, z, w};
    for (int l = 0; l < 4; l++) {
        float *o = out + vertex_at(base, v[l].id);
        _mm_storel_pi((__m64 *)(void *)o, row[l]);
        _mm_store_ss(o + 2, _mm_movehl_ps(row[l], row[l]));
    }
}
#endif /* KERNELS_AVX2 */

#endif /* ISOMEND_VERTEX_INLINE_H */
