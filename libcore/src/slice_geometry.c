/*
 * slice_geometry.c - slices where they are: a grid whose slices have their
 * own origins (isomend_volume.slice_origins; isomend.h, "Slices where they
 * are").  The thesis (chapter 2.1) names rectilinear data, whose spacings
 * may be uneven, and leaves it out; scanners write such series (positions
 * rounded to 0.1 mm, a spacing change part-way, a missing slice) and tilt
 * their gantry (each slice shifted along its columns).
 *
 * Marching is the uniform grid's, index for index: the classification, the
 * numbering and the triangles do not depend on where the samples lie.  Only
 * the vertices do, and they are computed here, for every edge (the kernels'
 * vertex loops hand all of them to make_vertex when the grid has slice
 * origins), from the samples' true positions:
 *   - sample (i, j) of marched slice m lies at  O(m) + (i - pad, j - pad, 0) h,
 *     O(m) the slice's origin (the padding slices one gap beyond the ends);
 *   - a vertex between samples at p0 and p1 lies at (1 - t) p0 + t p1;
 *   - the gradient at a sample has its x and y components from the usual
 *     central differences, and its z component from the difference along
 *     the slices, f(m+1) - f(m-1), over the vector d between those two
 *     samples' positions: g . d = f(m+1) - f(m-1), so
 *         gz = (f(m+1) - f(m-1) - gx dx - gy dy) / dz
 *     (one-sided at the border, next to NaN and padding, as elsewhere).
 * The continuity check of such a mesh finds the border in the grid's own
 * faces: unshear_point() undoes a vertex's slice shift (interpolated
 * between the slices around its z), and check.c checks in that unsheared
 * frame.
 */
#include "grid.h"
#include "slice_geometry.h"

#include <stdlib.h>

isomend_status slice_origins_validate(const isomend_volume *vol)
{
    const double *so = vol->slice_origins;
    if (!so)
        return ISOMEND_OK;
    for (int64_t k = 0; k < vol->dims[2]; k++) {
        for (int a = 0; a < 3; a++)
            if (!isfinite(so[3 * k + a]))
                return ISOMEND_ERR_BAD_SPACING;
        if (k > 0 && !(so[3 * k + 2] > so[3 * k - 1]))
            return ISOMEND_ERR_BAD_SPACING;
    }
    return ISOMEND_OK;
}

void slice_origin(const slice_table *t, int64_t m, double o[3])
{
    const int64_t k = m - t->pad, n = t->n;
    const double *so = t->so;
    if (k >= 0 && k < n) {
        for (int a = 0; a < 3; a++)
            o[a] = so[3 * k + a];
        return;
    }
    /* a padding slice: one gap beyond the end (the z spacing with one slice) */
    const double *end = k < 0 ? so : so + 3 * (n - 1);
    const double sign = k < 0 ? -1.0 : 1.0;
    for (int a = 0; a < 3; a++) {
        const double step = n > 1 ? (k < 0 ? so[3 + a] - so[a] : end[a] - end[a - 3])
                                  : (a == 2 ? t->gap : 0.0);
        o[a] = end[a] + sign * step;
    }
}

/* World position of marched sample p. */
static void sample_position(const grid *g, const int64_t p[3], double w[3])
{
    slice_origin(&g->slices, p[2], w);
    w[0] += (double)(p[0] - g->pad) * g->h[0];
    w[1] += (double)(p[1] - g->pad) * g->h[1];
}

/* The world gradient at marched sample p (value f0). */
static void sheared_gradient(const grid *g, const int64_t p[3], double f0, double gr[3])
{
    gr[0] = gradient_component(g, p, 0, f0); /* in-plane: as on a uniform grid */
    gr[1] = gradient_component(g, p, 1, f0);
    gr[2] = 0.0;
    const double fp = fetch(g, p[0], p[1], p[2] + 1), fm = fetch(g, p[0], p[1], p[2] - 1);
    const int vp = !isnan(fp), vm = !isnan(fm);
    if (!vp && !vm)
        return;
    double hi[3], lo[3];
    slice_origin(&g->slices, vp ? p[2] + 1 : p[2], hi);
    slice_origin(&g->slices, vm ? p[2] - 1 : p[2], lo);
    const double df = (vp ? fp : f0) - (vm ? fm : f0);
    gr[2] = (df - gr[0] * (hi[0] - lo[0]) - gr[1] * (hi[1] - lo[1])) / (hi[2] - lo[2]);
}

void sheared_vertex(const grid *g, int flip, const int64_t p0[3], const int64_t p1[3], float *pos,
                    float *nrm)
{
    const double f0 = fetch(g, p0[0], p0[1], p0[2]), f1 = fetch(g, p1[0], p1[1], p1[2]);
    const int valid = !isnan(f0) && !isnan(f1);
    const double t = valid ? (g->iso - f0) / (f1 - f0) : 0.5;
    double w0[3], w1[3];
    sample_position(g, p0, w0);
    sample_position(g, p1, w1);
    for (int c = 0; c < 3; c++)
        pos[c] = (float)((1.0 - t) * w0[c] + t * w1[c]);
    if (!nrm)
        return;
    double n[3] = {0, 0, 0}, len = 0.0;
    if (valid) {
        double g0[3], g1[3];
        sheared_gradient(g, p0, f0, g0);
        sheared_gradient(g, p1, f1, g1);
        for (int c = 0; c < 3; c++)
            n[c] = -((1.0 - t) * g0[c] + t * g1[c]);
        len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    if (!(len > 0.0) || !isfinite(len)) {
        /* the edge's direction, from the inside end towards the outside one */
        const double sign = f0 >= g->iso ? 1.0 : -1.0;
        for (int c = 0; c < 3; c++)
            n[c] = sign * (w1[c] - w0[c]);
        len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    const double scale = (flip ? -1.0 : 1.0) / len;
    for (int c = 0; c < 3; c++)
        nrm[c] = (float)(scale * n[c]);
}

void sheared_box(const grid *g, double box[6])
{
    for (int a = 0; a < 3; a++) {
        box[a] = INFINITY;
        box[3 + a] = -INFINITY;
    }
    for (int64_t m = 0; m < g->N[2]; m++) {
        double o[3];
        slice_origin(&g->slices, m, o);
        for (int a = 0; a < 3; a++) {
            const double lo = a < 2 ? o[a] - (double)g->pad * g->h[a] : o[a];
            const double hi = a < 2 ? lo + (double)(g->N[a] - 1) * g->h[a] : o[a];
            box[a] = lo < box[a] ? lo : box[a];
            box[3 + a] = hi > box[3 + a] ? hi : box[3 + a];
        }
    }
}

isomend_status mesh_keep_slices(isomend_mesh *mesh, const grid *g)
{
    mesh->slices = g->slices;
    mesh->slices.so = NULL;
    mesh->h[0] = g->h[0];
    mesh->h[1] = g->h[1];
    mesh->N[0] = g->N[0];
    mesh->N[1] = g->N[1];
    mesh->N[2] = g->N[2];
    if (!g->slices.so)
        return ISOMEND_OK;
    const size_t size = 3 * sizeof(double) * (size_t)g->slices.n;
    double *copy = malloc(size);
    if (!copy)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    memcpy(copy, g->slices.so, size);
    mesh->slices.so = mesh->slice_store = copy;
    return ISOMEND_OK;
}

void unshear_point(const double *o, int64_t n, const float in[3], float out[3])
{
    /* the shift interpolated between the slices around the point's z */
    const double z = in[2];
    int64_t lo = 0, hi = n - 1;
    while (hi - lo > 1) {
        const int64_t mid = (lo + hi) / 2;
        if (o[3 * mid + 2] <= z)
            lo = mid;
        else
            hi = mid;
    }
    double s = n > 1 ? (z - o[3 * lo + 2]) / (o[3 * hi + 2] - o[3 * lo + 2]) : 0.0;
    s = s < 0.0 ? 0.0 : s > 1.0 ? 1.0 : s;
    for (int a = 0; a < 2; a++) {
        const double shift = (1.0 - s) * o[3 * lo + a] + s * o[3 * hi + a];
        out[a] = (float)((double)in[a] - shift);
    }
    out[2] = in[2];
}
