/*
 * grid.h - the volume as the extraction's loops see it (private): the marched
 * grid (the samples, their type and strides, the padding, the spacing or the
 * slices where they are, the level), a sample read as a double, the sign
 * rows' spans, and 8-byte words read and written in a fixed byte order.
 * Types and inline functions only: the files that use them say so by
 * including this, and it depends on nothing of theirs.
 */
#ifndef ISOMEND_GRID_H
#define ISOMEND_GRID_H

#include "isomend.h"
#include "mesh_internal.h" /* slice_table */

#include <math.h>
#include <stdint.h>
#include <string.h>

typedef struct grid {
    const char *data;
    isomend_type type;
    int64_t n[3];  /* the volume's dimensions                      */
    int64_t st[3]; /* byte strides                                  */
    int64_t pad;   /* 0 or 1                                        */
    int64_t z0;    /* the volume slice `data` points at: 0, or in a
                    * stream the first slice of its window (stream.c) */
    int64_t N[3];  /* marched grid: n + 2 pad                      */
    int64_t off[2]; /* the larger grid's marched column and row of this
                     * grid's column and row 0: 0, or for a box piece the
                     * crop's (stream.c); positions use them, nothing else */
    double iso;
    double h[3];   /* spacing                                       */
    double inv2h[3]; /* 1 / (2 spacing), for central differences    */
    int64_t inner_lo[3], inner_hi[3]; /* marched samples with all 6 neighbours in the volume */
    double o[3];   /* world position of marched sample (0, 0, 0)   */
    slice_table slices; /* slices where they are (so NULL: uniform); the
                         * kernels then send every vertex to make_vertex */
    int constant;  /* integer types: -1 none, 0 all out, 1 all in */
    int64_t ithr;  /* integer types: inside iff v >= ithr           */
    float fthr;    /* f32: the smallest float >= iso               */
} grid;

/* The sample of type `type` at p as a double (exact for every type). */
static inline __attribute__((always_inline)) double sample_as_double(isomend_type type,
                                                                     const char *p)
{
    switch (type) {
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

/* Sample (i, j, k) of the marched grid as a double; NaN for padding. */
static inline double fetch(const grid *g, int64_t i, int64_t j, int64_t k)
{
    i -= g->pad;
    j -= g->pad;
    k -= g->pad;
    if ((uint64_t)i >= (uint64_t)g->n[0] || (uint64_t)j >= (uint64_t)g->n[1] ||
        (uint64_t)k >= (uint64_t)g->n[2])
        return NAN;
    return sample_as_double(g->type,
                            g->data + i * g->st[0] + j * g->st[1] + (k - g->z0) * g->st[2]);
}

/* World-space gradient component along axis a at marched sample p (value
 * f0): central, or one-sided next to the border, NaN and padding (the
 * general vertex path, vertices.c, and slices where they are,
 * slice_geometry.c). */
static inline double gradient_component(const grid *g, const int64_t p[3], int a, double f0)
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
 * Sign rows.  A row of the marched grid is stored as bytes (1 = inside) plus
 * its span: `lo`, the first column whose sign differs from column 0 (N0 when
 * the row is uniform), and `hi`, the last column whose sign differs from the
 * last column (-1 when uniform).  Outside [lo - 1, hi] the row is constant,
 * which is what lets every loop skip the empty parts of a row.  A `simple`
 * row is one run [lo, hi] of the other sign in a constant row (a chord
 * through a blob): rows of cubes between four simple rows are empty inside
 * the runs' overlap too.
 */
typedef struct row_span {
    int64_t lo, hi;
    uint8_t first, last;
    uint8_t simple; /* one run [lo, hi] of the other sign, constant around it */
} row_span;

/* 8 bytes at p as a little-endian word, and back. */
static inline uint64_t load8(const uint8_t *p)
{
    uint64_t v;
    memcpy(&v, p, sizeof v);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    v = __builtin_bswap64(v);
#endif
    return v;
}

static inline void store8(uint8_t *p, uint64_t v)
{
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    v = __builtin_bswap64(v);
#endif
    memcpy(p, &v, sizeof v);
}

#endif /* ISOMEND_GRID_H */
