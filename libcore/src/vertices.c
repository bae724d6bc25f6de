/*
 * vertices.c - the general vertex path: any edge of the marched grid,
 * border, NaN and padding included, and the points between two samples off
 * the grid's edges (tetra's face diagonals).
 *
 * The kernels' vertex loops (vertex_loops_template.h) take interior edges
 * and hand everything else here.  Both compute t = (iso - f0) / (f1 - f0)
 * and the position in the same way, and the normals from the same central
 * differences, so which path a vertex takes changes nothing in the mesh.
 * NaN samples and padding are outside: an edge with such an end is cut at
 * its middle, its gradients one-sided, and where no gradient is left the
 * normal is the edge's direction towards the outside end (isomend.h).
 */
#include "grid.h"
#include "vertices.h"
#include "slice_geometry.h"

/*
 * fast_gradients for samples of one type (a constant where it is inlined):
 * typed loads from p, the edge's lower end, no bounds checks.
 */
static inline __attribute__((always_inline)) void gradients_as(const grid *g,
                                                               const isomend_type type,
                                                               const char *p, int a, double f[2],
                                                               double gr[2][3])
{
#define SAMPLE(ptr) sample_as_double(type, ptr)
    const int64_t sx = g->st[0], sy = g->st[1], sz = g->st[2];
    const char *q = p + g->st[a];
    const double f0 = SAMPLE(p), f1 = SAMPLE(q);
    f[0] = f0;
    f[1] = f1;
    /* along the edge each endpoint is the other's neighbour */
    gr[0][0] = a == 0 ? f1 - SAMPLE(p - sx) : SAMPLE(p + sx) - SAMPLE(p - sx);
    gr[0][1] = a == 1 ? f1 - SAMPLE(p - sy) : SAMPLE(p + sy) - SAMPLE(p - sy);
    gr[0][2] = a == 2 ? f1 - SAMPLE(p - sz) : SAMPLE(p + sz) - SAMPLE(p - sz);
    gr[1][0] = a == 0 ? SAMPLE(q + sx) - f0 : SAMPLE(q + sx) - SAMPLE(q - sx);
    gr[1][1] = a == 1 ? SAMPLE(q + sy) - f0 : SAMPLE(q + sy) - SAMPLE(q - sy);
    gr[1][2] = a == 2 ? SAMPLE(q + sz) - f0 : SAMPLE(q + sz) - SAMPLE(q - sz);
#undef SAMPLE
    for (int c = 0; c < 3; c++) {
        gr[0][c] *= g->inv2h[c];
        gr[1][c] *= g->inv2h[c];
    }
}

/*
 * Fast path for a vertex whose endpoints and their six neighbours are all
 * inside the volume.  Fills the endpoint values and the gradients at both
 * endpoints (NaN samples make them NaN, which the caller detects and
 * handles as at the border); returns 0 when the edge is not interior.
 */
static int fast_gradients(const grid *g, int64_t i, int64_t j, int64_t k, int a, double f[2],
                          double gr[2][3])
{
    /* Both endpoints and their neighbours must lie inside the volume. */
    if (i < g->inner_lo[0] || j < g->inner_lo[1] || k < g->inner_lo[2] ||
        i + (a == 0) > g->inner_hi[0] || j + (a == 1) > g->inner_hi[1] ||
        k + (a == 2) > g->inner_hi[2])
        return 0;
    const char *p =
        g->data + (i - g->pad) * g->st[0] + (j - g->pad) * g->st[1] + (k - g->pad - g->z0) * g->st[2];
    switch (g->type) {
    case ISOMEND_U8: gradients_as(g, ISOMEND_U8, p, a, f, gr); break;
    case ISOMEND_I8: gradients_as(g, ISOMEND_I8, p, a, f, gr); break;
    case ISOMEND_U16: gradients_as(g, ISOMEND_U16, p, a, f, gr); break;
    case ISOMEND_I16: gradients_as(g, ISOMEND_I16, p, a, f, gr); break;
    case ISOMEND_I32: gradients_as(g, ISOMEND_I32, p, a, f, gr); break;
    case ISOMEND_F32: gradients_as(g, ISOMEND_F32, p, a, f, gr); break;
    case ISOMEND_F64: gradients_as(g, ISOMEND_F64, p, a, f, gr); break;
    }
    return 1;
}

void make_vertex(const grid *g, int flip, int64_t i, int64_t j, int64_t k, int a, float *pos,
                 float *nrm)
{
    int64_t p0[3] = {i, j, k}, p1[3] = {i, j, k};
    p1[a]++;
    if (g->slices.so) {
        sheared_vertex(g, flip, p0, p1, pos, nrm);
        return;
    }
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
        if (!have_gradients ||
            !isfinite(len)) { /* near the border, NaN or padding: one-sided differences */
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
void make_vertex_between(const grid *g, int flip, const int64_t p0[3], const int64_t p1[3],
                         float *pos, float *nrm)
{
    if (g->slices.so) {
        sheared_vertex(g, flip, p0, p1, pos, nrm);
        return;
    }
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
