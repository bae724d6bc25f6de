/*
 * smooth.c - isomend_mesh_smooth(): Taubin's lambda|mu smoothing (Taubin
 * 1995, "A signal processing approach to fair surface design") with the
 * umbrella operator, then each component's volume restored.
 *
 * A marching-cubes surface of voxel data is a staircase; plain Laplacian
 * smoothing removes it and shrinks the surface.  Taubin alternates a
 * shrinking step (lambda 0.5) and an inflating one (mu -0.53): a low-pass
 * filter with pass band k = 1/lambda + 1/mu = 0.11, which leaves the shape
 * and takes the staircase.  What volume is still lost is given back per
 * component: its free vertices move along their normals by one offset,
 * (V0 - V1) / A, A the area those vertices carry (a third of each of their
 * triangles'), in up to eight passes until every component is within
 * 1e-9 of its volume (each takes the previous one's
 * curvature term) of at most a quarter of the component's mean edge each
 * (an island the filter shrank to almost a point grows back gradually).
 * Locked vertices (mesh_free_vertices: the border of an unpadded surface,
 * non-manifold places) never move, and the triangles are the input's, so
 * the surface stays closed and oriented.
 */
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LAMBDA 0.5
#define MU (-0.53)

/* Enclosed volume of each component (the divergence theorem; the right-hand
 * normals point outwards for isomend's orientation). */
static void component_volumes(const isomend_mesh *m, const double *p, const uint32_t *label,
                              double *vol, int64_t nc)
{
    for (int64_t c = 0; c < nc; c++)
        vol[c] = 0;
    for (size_t t = 0; t < m->nt; t++) {
        const double *a = p + 3 * (size_t)m->tri[3 * t], *b = p + 3 * (size_t)m->tri[3 * t + 1],
                     *c = p + 3 * (size_t)m->tri[3 * t + 2];
        vol[label[m->tri[3 * t]]] += (a[0] * (b[1] * c[2] - b[2] * c[1]) +
                                      a[1] * (b[2] * c[0] - b[0] * c[2]) +
                                      a[2] * (b[0] * c[1] - b[1] * c[0])) /
                                     6.0;
    }
}

/* Area-weighted vertex normals (not unit: |n| = twice the triangles' area
 * around the vertex) into n. */
static void weighted_normals(const isomend_mesh *m, const double *p, double *n)
{
    memset(n, 0, 3 * sizeof(double) * m->nv);
    for (size_t t = 0; t < m->nt; t++) {
        const uint32_t *v = m->tri + 3 * t;
        const double *a = p + 3 * (size_t)v[0], *b = p + 3 * (size_t)v[1], *c = p + 3 * (size_t)v[2];
        const double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        const double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        const double f[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                             e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++)
                n[3 * (size_t)v[k] + (size_t)d] += f[d];
    }
}

/* A step of the smoothing: q from p for every vertex. */
typedef struct smooth_job {
    size_t nv;
    const uint32_t *first, *nb;
    const uint8_t *free_v;
    const double *p;
    double *q;
    double f;
} smooth_job;

/* One step over vertices [lo, hi) of the job: q from p. */
static void step_range(void *arg, size_t lo, size_t hi)
{
    const smooth_job *j = arg;
    const double *p = j->p;
    double *q = j->q;
    for (size_t v = lo; v < hi; v++) {
        const uint32_t b = j->first[v], e = j->first[v + 1];
        if (!j->free_v[v]) {
            q[3 * v] = p[3 * v];
            q[3 * v + 1] = p[3 * v + 1];
            q[3 * v + 2] = p[3 * v + 2];
            continue;
        }
        double sx = 0, sy = 0, sz = 0;
        for (uint32_t x = b; x < e; x++) {
            const double *w = p + 3 * (size_t)j->nb[x];
            sx += w[0];
            sy += w[1];
            sz += w[2];
        }
        const double inv = 1.0 / (double)(e - b);
        q[3 * v] = p[3 * v] + j->f * (sx * inv - p[3 * v]);
        q[3 * v + 1] = p[3 * v + 1] + j->f * (sy * inv - p[3 * v + 1]);
        q[3 * v + 2] = p[3 * v + 2] + j->f * (sz * inv - p[3 * v + 2]);
    }
}

isomend_status isomend_mesh_smooth(const isomend_mesh *mesh, int iterations, isomend_mesh **out,
                                   isomend_smooth_report *report)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    if (!mesh || iterations < 0 || iterations > 10000)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    const size_t nv = mesh->nv ? mesh->nv : 1;
    isomend_status status = ISOMEND_ERR_OUT_OF_MEMORY;
    uint8_t *free_v = malloc(nv);
    uint32_t *first = NULL, *corners = NULL, *label = malloc(nv * sizeof(uint32_t));
    double *p = calloc(3 * nv, sizeof(double)), *q = calloc(3 * nv, sizeof(double));
    double *v0 = NULL, *v1 = NULL, *area = NULL;
    isomend_mesh *m = calloc(1, sizeof(*m));
    if (!free_v || !label || !p || !q || !m ||
        !mesh_free_vertices(mesh, free_v, &first, &corners))
        goto done;
    const int64_t nc = mesh_components(mesh, label);
    v0 = malloc(((size_t)nc + 1) * sizeof(double));
    v1 = malloc(((size_t)nc + 1) * sizeof(double));
    area = malloc(((size_t)nc + 1) * sizeof(double));
    if (!v0 || !v1 || !area)
        goto done;
    for (size_t i = 0; i < 3 * mesh->nv; i++)
        p[i] = mesh->pos[i];
    component_volumes(mesh, p, label, v0, nc);
    uint64_t moved = 0;
    for (size_t v = 0; v < mesh->nv; v++)
        moved += free_v[v];
    /* each corner's entry becomes the neighbour it leads to: around a free
     * vertex every neighbour is the `next` of exactly one corner */
    for (size_t x = 0; x < 3 * mesh->nt; x++) {
        const uint32_t c = corners[x];
        corners[x] = mesh->tri[c - c % 3 + (c % 3 + 1) % 3];
    }
    /* lambda, mu, lambda, mu ...: q = p + f (mean of the neighbours - p),
     * every vertex from the previous step's positions only, so the threads'
     * split changes nothing */
    smooth_job job = {mesh->nv, first, corners, free_v, p, q, 0};
    for (int it = 0; it < 2 * iterations; it++) {
        job.f = it % 2 ? MU : LAMBDA;
        job.p = p;
        job.q = q;
        parallel_for(mesh->nv, step_range, &job);
        double *t = p;
        p = q;
        q = t;
    }
    /* each component's mean edge length (of the input): the largest step the
     * volume restoration takes at once */
    double *edge = calloc((size_t)nc + 1, sizeof(double)), *edges = calloc((size_t)nc + 1, sizeof(double));
    if (!edge || !edges) {
        free(edge);
        free(edges);
        goto done;
    }
    for (size_t t = 0; t < mesh->nt; t++)
        for (int k = 0; k < 3; k++) {
            const float *a = mesh->pos + 3 * (size_t)mesh->tri[3 * t + (size_t)k],
                        *b = mesh->pos + 3 * (size_t)mesh->tri[3 * t + (size_t)(k + 1) % 3];
            const double dx = (double)a[0] - b[0], dy = (double)a[1] - b[1], dz = (double)a[2] - b[2];
            edge[label[mesh->tri[3 * t]]] += sqrt(dx * dx + dy * dy + dz * dz);
            edges[label[mesh->tri[3 * t]]] += 1;
        }
    for (int64_t c = 0; c < nc; c++)
        edge[c] = edges[c] > 0 ? edge[c] / edges[c] : 0;
    free(edges);
    /* the volume back, per component, along the normals: a few passes, each
     * step at most a quarter of the mean edge (a small island that the
     * filter shrank to almost a point grows back over several) */
    for (int pass = 0; pass < 8 && iterations > 0; pass++) {
        component_volumes(mesh, p, label, v1, nc);
        int restored = 1; /* every component within 1e-9 of its volume: done */
        for (int64_t c = 0; c < nc && restored; c++)
            restored = fabs(v1[c] - v0[c]) <= 1e-9 * fabs(v0[c]);
        if (restored)
            break;
        weighted_normals(mesh, p, q);
        for (int64_t c = 0; c < nc; c++)
            area[c] = 0;
        for (size_t v = 0; v < mesh->nv; v++)
            if (free_v[v]) {
                const double *n = q + 3 * v;
                area[label[v]] += sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) / 6.0;
            }
        for (size_t v = 0; v < mesh->nv; v++) {
            const double *n = q + 3 * v;
            const double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            const double a = area[label[v]];
            if (!free_v[v] || !(len > 0) || !(a > 0))
                continue;
            const double limit = 0.25 * edge[label[v]];
            double delta = (v0[label[v]] - v1[label[v]]) / a;
            delta = delta > limit ? limit : delta < -limit ? -limit : delta;
            for (int d = 0; d < 3; d++)
                p[3 * v + (size_t)d] += delta * n[d] / len;
        }
    }
    free(edge);
    m->nv = mesh->nv;
    m->nt = mesh->nt;
    m->pos = malloc(12 * nv);
    m->tri = malloc(12 * (mesh->nt ? mesh->nt : 1));
    m->nrm = mesh->nrm ? malloc(12 * nv) : NULL;
    if (!m->pos || !m->tri || (mesh->nrm && !m->nrm))
        goto done;
    double worst = 0;
    for (size_t v = 0; v < mesh->nv; v++) {
        double d2 = 0;
        for (int d = 0; d < 3; d++) {
            m->pos[3 * v + (size_t)d] = (float)p[3 * v + (size_t)d];
            const double dd = p[3 * v + (size_t)d] - mesh->pos[3 * v + (size_t)d];
            d2 += dd * dd;
        }
        worst = d2 > worst ? d2 : worst;
    }
    memcpy(m->tri, mesh->tri, 12 * mesh->nt);
    if (m->nrm)
        mesh_area_normals(m, mesh->nrm);
    if (mesh_copy_frame(m, mesh) != ISOMEND_OK)
        goto done;
    if (report) {
        for (size_t i = 0; i < 3 * mesh->nv; i++)
            p[i] = m->pos[i];
        component_volumes(mesh, p, label, v1, nc);
        report->moved_vertices = moved;
        report->volume_before = report->volume_after = 0;
        for (int64_t c = 0; c < nc; c++) {
            report->volume_before += v0[c];
            report->volume_after += v1[c];
        }
        report->max_displacement = sqrt(worst);
    }
    *out = m;
    m = NULL;
    status = ISOMEND_OK;
done:
    isomend_mesh_destroy(m);
    free(free_v);
    free(first);
    free(corners);
    free(label);
    free(p);
    free(q);
    free(v0);
    free(v1);
    free(area);
    return status;
}
