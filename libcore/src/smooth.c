/*
 * smooth.c - isomend_mesh_smooth(): the windowed sinc filter of Taubin,
 * Zhang and Golub (1996, "Optimal surface smoothing as filter design"), the
 * low-pass filter that VTK's vtkWindowedSincPolyDataFilter and 3D Slicer
 * apply, with the umbrella operator; then each component's volume restored.
 *
 * A marching-cubes surface of voxel data is a staircase; plain Laplacian
 * smoothing removes it and shrinks the surface.  The filter is a polynomial
 * of degree N (the iterations) in the umbrella Laplacian K, evaluated with
 * Chebyshev's recurrence in the variable 1 - k/2 (k in [0, 2], K's
 * frequencies): x1 = (x0 + mean x0) / 2, x(j+1) = xj + mean xj - x(j-1),
 * result sum cj xj.  The cj are a sinc (an ideal low pass with pass band
 * 0.1) under a Hamming window, its cut-off shifted (Newton) so that the gain
 * at the pass band is 1, then scaled to sum to 1: a translation passes
 * unchanged (VTK's sum is 0.998 for N = 20, which without its
 * NormalizeCoordinates shrinks a mesh towards the origin).  One step of the
 * recurrence costs one umbrella step, so N iterations cost what N of VTK's
 * do; the steps run in float on coordinates centred on the mesh's box, every
 * vertex from the previous steps only, so the threads' split changes
 * nothing.
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
 * once from each corner), so that they are gathered on threads and summed
 * in vertex order.  Locked vertices (mesh_free_vertices: the border of an
 * unpadded surface, non-manifold places) never move, and the triangles are
 * the input's, so the surface stays closed and oriented.
 */
#include "mesh_internal.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

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

typedef struct filter_job {
    const uint32_t *first, *nb; /* each vertex's neighbours (compressed rows)  */
    const uint8_t *free_v;
    const float *x;             /* x_j, read                                  */
    float *y;                   /* x_(j-1) in, x_(j+1) out (x_1 out at step 0) */
    float *sum;                 /* the result so far                          */
    float c0, c1;               /* step 0: c_0, c_1; later: c_(j+1) in c1     */
    int first_step;
} filter_job;

static void filter_range(void *arg, size_t lo, size_t hi)
{
    const filter_job *j = arg;
    const uint32_t *restrict first = j->first, *restrict nb = j->nb;
    const uint8_t *restrict free_v = j->free_v;
    const float *restrict x = j->x;
    float *restrict y = j->y, *restrict s = j->sum;
    const float c0 = j->c0, c1 = j->c1;
    const int first_step = j->first_step;
    for (size_t v = lo; v < hi; v++) {
        const float *p = x + 3 * v;
        float n0 = p[0], n1 = p[1], n2 = p[2]; /* a locked vertex: K's row is 0 */
        if (free_v[v]) {
            const uint32_t b = first[v], e = first[v + 1];
            float sx = 0, sy = 0, sz = 0;
            for (uint32_t k = b; k < e; k++) {
                const float *w = x + 3 * (size_t)nb[k];
                sx += w[0];
                sy += w[1];
                sz += w[2];
            }
            const float inv = 1.0f / (float)(e - b);
            if (first_step) { /* x1 = (x0 + mean x0) / 2 */
                n0 = 0.5f * (n0 + sx * inv);
                n1 = 0.5f * (n1 + sy * inv);
                n2 = 0.5f * (n2 + sz * inv);
            } else { /* x(j+1) = xj + mean xj - x(j-1) */
                n0 += sx * inv - y[3 * v];
                n1 += sy * inv - y[3 * v + 1];
                n2 += sz * inv - y[3 * v + 2];
            }
        }
        if (first_step) {
            s[3 * v] = c0 * p[0] + c1 * n0;
            s[3 * v + 1] = c0 * p[1] + c1 * n1;
            s[3 * v + 2] = c0 * p[2] + c1 * n2;
        } else {
            s[3 * v] += c1 * n0;
            s[3 * v + 1] += c1 * n1;
            s[3 * v + 2] += c1 * n2;
        }
        y[3 * v] = n0;
        y[3 * v + 1] = n1;
        y[3 * v + 2] = n2;
    }
}

/* Each vertex's area-weighted normal sum N (twice the area of its
 * triangles, right-hand winding; stored in float), its area |N| / 6 and its
 * part of the enclosed volume, p . N / 18, from its fan (the next and prev
 * vertex of each corner), of positions p. */
typedef struct fan_job {
    const uint32_t *first, *next, *prev;
    const uint32_t *list; /* the vertices (NULL: all), by index */
    const float *p;
    float *nrm;
    double *vol, *area;
} fan_job;

static void fan_range(void *arg, size_t lo, size_t hi)
{
    const fan_job *j = arg;
    const uint32_t *restrict first = j->first, *restrict next = j->next, *restrict prev = j->prev;
    const float *restrict p = j->p;
    float *restrict nrm = j->nrm;
    double *restrict vol = j->vol, *restrict area = j->area;
    for (size_t i = lo; i < hi; i++) {
        const size_t v = j->list ? j->list[i] : i;
        const double a0 = p[3 * v], a1 = p[3 * v + 1], a2 = p[3 * v + 2];
        double n0 = 0, n1 = 0, n2 = 0;
        for (uint32_t k = first[v]; k < first[v + 1]; k++) {
            const float *b = p + 3 * (size_t)next[k], *d = p + 3 * (size_t)prev[k];
            const double e0 = b[0] - a0, e1 = b[1] - a1, e2 = b[2] - a2;
            const double f0 = d[0] - a0, f1 = d[1] - a1, f2 = d[2] - a2;
            n0 += e1 * f2 - e2 * f1;
            n1 += e2 * f0 - e0 * f2;
            n2 += e0 * f1 - e1 * f0;
        }
        nrm[3 * v] = (float)n0;
        nrm[3 * v + 1] = (float)n1;
        nrm[3 * v + 2] = (float)n2;
        vol[v] = (a0 * n0 + a1 * n1 + a2 * n2) / 18.0;
        area[v] = sqrt(n0 * n0 + n1 * n1 + n2 * n2) / 6.0;
    }
}

/* The fans of positions p on threads, of the n vertices of j->list (or of
 * all); the volume of each of their components and the area of its free
 * vertices summed anew, in vertex order (so not by the threads). */
static void fans(fan_job *j, const float *p, size_t n, const uint32_t *label,
                 const uint8_t *free_v, double *vol, double *area)
{
    j->p = p;
    parallel_for(n, fan_range, j);
    for (size_t i = 0; i < n; i++) {
        const size_t v = j->list ? j->list[i] : i;
        vol[label[v]] = area[label[v]] = 0;
    }
    for (size_t i = 0; i < n; i++) {
        const size_t v = j->list ? j->list[i] : i;
        vol[label[v]] += j->vol[v];
        area[label[v]] += free_v[v] ? j->area[v] : 0;
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
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    if (!mesh || iterations < 0 || iterations > 10000)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    const size_t nv = mesh->nv, nv1 = nv ? nv : 1;
    isomend_status status = ISOMEND_ERR_OUT_OF_MEMORY;
    /* the working arrays on small pages: huge ones (scratch_alloc) fault
     * faster, but on a machine whose free memory is fragmented the kernel
     * compacts it at the fault, which made a 1.5 M-vertex smoothing take
     * 190 ms or 400-560 ms by turns (malloc: 250-285 ms, steadily) */
    uint8_t *free_v = malloc(nv1);
    uint32_t *first = NULL, *next = NULL, *prev = NULL, *label = malloc(nv1 * sizeof(uint32_t));
    float *xa = malloc(12 * nv1), *xb = malloc(12 * nv1), *nrm = malloc(12 * nv1);
    double *vv = malloc(8 * nv1), *va = malloc(8 * nv1);
    double *c = malloc(8 * ((size_t)iterations + 1));
    double *v0 = NULL, *v1 = NULL, *area = NULL, *edge = NULL, *delta = NULL;
    isomend_mesh *m = calloc(1, sizeof(*m));
    if (!free_v || !label || !xa || !xb || !nrm || !vv || !va || !c || !m)
        goto done;
    /* the components (serial) on a thread of their own while the fans are
     * filed (serial too, then tested on threads) */
    comp_job cjob = {mesh, label, 0};
    pthread_t comp_thread;
    const int comp_started = nv >= 32768 && pthread_create(&comp_thread, NULL, comp_main, &cjob) == 0;
    if (!comp_started)
        comp_main(&cjob);
    const int fans_ok = mesh_free_vertices(mesh, free_v, &first, &next, &prev);
    if (comp_started)
        pthread_join(comp_thread, NULL);
    if (!fans_ok)
        goto done;
    const int64_t nc = cjob.count;
    const size_t nc1 = (size_t)nc + 1;
    v0 = malloc(nc1 * sizeof(double));
    v1 = malloc(nc1 * sizeof(double));
    area = malloc(nc1 * sizeof(double));
    edge = calloc(nc1, sizeof(double));
    delta = calloc(nc1, sizeof(double));
    m->nv = nv;
    m->nt = mesh->nt;
    m->pos = malloc(12 * nv1);
    m->tri = malloc(12 * (mesh->nt ? mesh->nt : 1));
    m->nrm = mesh->nrm ? malloc(12 * nv1) : NULL;
    if (!v0 || !v1 || !area || !edge || !delta || !m->pos || !m->tri || (mesh->nrm && !m->nrm))
        goto done;

    /* the input's volumes, and each component's mean triangle area: a
     * quarter of the edge of an equilateral triangle of that area is the
     * largest step the volume restoration takes at once */
    fan_job fj = {first, next, prev, NULL, NULL, nrm, vv, va};
    for (int64_t k = 0; k < nc; k++)
        v0[k] = area[k] = 0; /* every component has a vertex: all set */
    fans(&fj, mesh->pos, nv, label, free_v, v0, area);
    for (size_t v = 0; v < nv; v++) {
        edge[label[v]] += va[v]; /* a third of each triangle's area, each corner */
        delta[label[v]] += first[v + 1] - first[v]; /* three a triangle */
    }
    for (int64_t k = 0; k < nc; k++)
        edge[k] = delta[k] > 0 ? 0.25 * sqrt(4.0 * (3.0 * edge[k] / delta[k]) / sqrt(3.0)) : 0;
    /* the filter, on coordinates centred on the box of the vertices (found
     * in fixed blocks, so the same for any threads) */
    box_job bj = {mesh->pos, free_v, nv, {{0}}, {{0}}, {0}};
    parallel_for_from(BOX_BLOCKS, 2, box_range, &bj);
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
        parallel_for(nv, centre_range, &cj);
        sinc_coefficients(iterations, c);
        filter_job job = {first, next, free_v, xa, xb, m->pos, (float)c[0], (float)c[1], 1};
        parallel_for(nv, filter_range, &job); /* x1 into xb */
        for (int it = 1; it < iterations; it++) {
            job.x = it % 2 ? xb : xa; /* x_it */
            job.y = it % 2 ? xa : xb; /* x_(it-1), becomes x_(it+1) */
            job.c1 = (float)c[it + 1];
            job.first_step = 0;
            parallel_for(nv, filter_range, &job);
        }
    }
    /* back to the mesh's coordinates; locked vertices exactly where they were */
    out_job oj = {mesh, free_v, nrm, mid, m->pos, NULL, vv, iterations > 0};
    parallel_for(nv, place_range, &oj);

    /* the volume back, per component, along the normals: a few passes, each
     * step at most a quarter of the mean edge (a small island that the
     * filter shrank to almost a point grows back over several) */
    fans(&fj, m->pos, nv, label, free_v, v1, area);
    /* the passes move the vertices of the components not yet restored,
     * listed in todo (in xa: the filter is done with it) */
    uint32_t *todo = (uint32_t *)xa;
    size_t ntodo = nv;
    for (size_t v = 0; v < nv; v++)
        todo[v] = (uint32_t)v;
    for (int pass = 0; pass < RESTORE_PASSES && iterations > 0 && ntodo > 0; pass++) {
        int restored = 1; /* every component within float precision: done */
        for (size_t i = 0; i < ntodo; i++) {
            const uint32_t k = label[todo[i]];
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
        parallel_for(ntodo, move_range, &mj);
        fj.list = todo;
        fans(&fj, m->pos, ntodo, label, free_v, v1, area);
    }
    /* the normals of what the passes did not move: from fans1, current */
    if (m->nrm && iterations == 0)
        memcpy(m->nrm, mesh->nrm, 12 * nv);
    oj.out_nrm = iterations > 0 ? m->nrm : NULL;
    parallel_for(nv, finish_range, &oj);
    memcpy(m->tri, mesh->tri, 12 * mesh->nt);
    if (mesh_copy_frame(m, mesh) != ISOMEND_OK)
        goto done;
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
    isomend_mesh_destroy(m);
    free(free_v);
    free(first);
    free(next);
    free(prev);
    free(label);
    free(xa);
    free(xb);
    free(nrm);
    free(vv);
    free(va);
    free(c);
    free(v0);
    free(v1);
    free(area);
    free(edge);
    free(delta);
    return status;
}
