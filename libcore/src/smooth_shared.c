/*
 * smooth_shared.c - isomend_meshes_smooth(): surfaces that meet, smoothed
 * together, so that they still meet.
 *
 * A label map's surfaces (labels.c) share their vertices where two labels
 * touch: the vertex of a grid edge between labels A and B is in A's mesh and
 * in B's, at the same position (the edge's midpoint).  Smoothing each mesh
 * alone would move such a vertex twice, differently, and open a gap or an
 * overlap between the neighbours.  Here the meshes' vertices are first made
 * one set, a vertex being the same in every mesh where its position is the
 * same (bit for bit: one grid edge, one midpoint); each vertex's neighbours
 * are those it has in any of its meshes (on an interface between two labels
 * the same ring twice, where three labels meet the rings of both sides);
 * and the windowed sinc filter of isomend_mesh_smooth() (smooth.c's
 * sinc_filter()) runs once on that set.  Every mesh then takes its
 * vertices' new positions, so a shared vertex stays shared.  A vertex locked
 * in any of its meshes (mesh_free_vertices(): the border of an unpadded
 * surface, a non-manifold place) stays where it is.
 *
 * No volume is restored: a component's restoring offset along its own
 * normals would move a shared vertex differently for each side.  The filter
 * itself keeps volumes closely (its coefficients sum to 1); each mesh's
 * volume before and after is reported.
 */
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The position's bits, hashed (the key of the vertex set). */
static uint64_t position_hash(const float *p)
{
    uint32_t b[3];
    memcpy(b, p, sizeof b);
    uint64_t h = 1469598103934665603ull;
    for (int d = 0; d < 3; d++) {
        h ^= b[d];
        h *= 1099511628211ull;
        h ^= h >> 29;
    }
    return h;
}

isomend_status vertex_set_build(const isomend_mesh *const *meshes, size_t count,
                                isomend_mesh **out, size_t pad, vertex_set *set)
{
    memset(set, 0, sizeof(*set));
    if (!out || (count && !meshes))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    for (size_t i = 0; i < count; i++)
        out[i] = NULL;
    for (size_t i = 0; i < count; i++) {
        if (!meshes[i])
            return ISOMEND_ERR_INVALID_ARGUMENT;
        set->total += meshes[i]->nv;
        set->corners += 3 * meshes[i]->nt;
    }
    if (set->total >= UINT32_MAX || set->corners >= UINT32_MAX)
        return ISOMEND_ERR_TOO_LARGE;
    size_t cap = 16;
    while (cap < 2 * set->total)
        cap *= 2;
    const size_t n1 = set->total ? set->total : 1;
    uint32_t *slot = malloc(cap * sizeof(uint32_t)); /* the set's vertices, by hash */
    set->gid = malloc(n1 * sizeof(uint32_t));
    set->base = malloc((count ? count : 1) * sizeof(size_t));
    set->pos = malloc(12 * n1 + sizeof(float) * pad);
    if (!slot || !set->gid || !set->base || !set->pos) {
        free(slot);
        vertex_set_free(set);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    memset(slot, 0xff, cap * sizeof(uint32_t));
    size_t n = 0;
    for (size_t i = 0, at = 0; i < count; i++) { /* a vertex's first occurrence: its position */
        set->base[i] = at;
        const isomend_mesh *m = meshes[i];
        for (size_t v = 0; v < m->nv; v++, at++) {
            const float *p = m->pos + 3 * v;
            size_t h = (size_t)position_hash(p) & (cap - 1);
            while (slot[h] != UINT32_MAX && memcmp(set->pos + 3 * (size_t)slot[h], p, 12) != 0)
                h = (h + 1) & (cap - 1);
            if (slot[h] == UINT32_MAX) {
                slot[h] = (uint32_t)n;
                memcpy(set->pos + 3 * n, p, 12);
                n++;
            }
            set->gid[at] = slot[h];
        }
    }
    set->n = n;
    free(slot);
    return ISOMEND_OK;
}

void vertex_set_free(vertex_set *set)
{
    free(set->gid);
    free(set->base);
    free(set->pos);
    set->gid = NULL;
    set->base = NULL;
    set->pos = NULL;
}

void meshes_destroy(isomend_mesh **out, size_t count)
{
    for (size_t i = 0; i < count; i++) {
        isomend_mesh_destroy(out[i]);
        out[i] = NULL;
    }
}

/* The enclosed volume of a mesh's triangles (signed, double sums). */
double mesh_volume(const float *pos, const uint32_t *tri, size_t nt)
{
    double v = 0;
    for (size_t t = 0; t < nt; t++) {
        const float *a = pos + 3 * (size_t)tri[3 * t], *b = pos + 3 * (size_t)tri[3 * t + 1],
                    *c = pos + 3 * (size_t)tri[3 * t + 2];
        v += (double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) +
             (double)a[1] * ((double)b[2] * c[0] - (double)b[0] * c[2]) +
             (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
    }
    return v / 6.0;
}

static int by_value(const void *x, const void *y)
{
    const uint32_t a = *(const uint32_t *)x, b = *(const uint32_t *)y;
    return (a > b) - (a < b);
}

isomend_status isomend_meshes_smooth(const isomend_mesh *const *meshes, size_t count,
                                     int iterations, isomend_mesh **out,
                                     isomend_smooth_report *reports)
{
    vertex_set set;
    isomend_status status = vertex_set_build(meshes, count, out, 4, &set);
    if (status != ISOMEND_OK)
        return status;
    if (iterations < 0 || iterations > 10000) {
        vertex_set_free(&set);
        return ISOMEND_ERR_INVALID_ARGUMENT;
    }
    status = ISOMEND_ERR_OUT_OF_MEMORY;
    const size_t n1 = set.total ? set.total : 1, corners = set.corners, n = set.n;
    const uint32_t *gid = set.gid;
    const size_t *base = set.base;
    float *x0 = set.pos; /* the set's positions, then centred */
    uint32_t *first = calloc(n1 + 1, sizeof(uint32_t)), *nb = malloc((corners ? corners : 1) * 4);
    uint8_t *free_v = malloc(n1), *deg = malloc(n1), *vfree = malloc(n1);
    float *b = malloc(12 * n1 + 16), *y = malloc(12 * n1 + 16);
    team *tm = NULL;
    if (!first || !nb || !free_v || !deg || !vfree || !b || !y)
        goto done;
    memset(free_v, 1, n1);
    /* each set vertex's neighbours: its meshes' rings, merged */
    for (size_t i = 0; i < count; i++) {
        const isomend_mesh *m = meshes[i];
        for (size_t c = 0; c < 3 * m->nt; c++)
            first[gid[base[i] + m->tri[c]] + 1] += 2;
    }
    for (size_t v = 0; v < n; v++)
        first[v + 1] += first[v];
    uint32_t *at = malloc(n1 * sizeof(uint32_t));
    if (!at)
        goto done;
    memcpy(at, first, n1 * sizeof(uint32_t));
    uint32_t *pairs = malloc((first[n] ? first[n] : 1) * sizeof(uint32_t));
    if (!pairs) {
        free(at);
        goto done;
    }
    for (size_t i = 0; i < count; i++) {
        const isomend_mesh *m = meshes[i];
        const uint32_t *g = gid + base[i];
        for (size_t t = 0; t < m->nt; t++)
            for (int k = 0; k < 3; k++) {
                const uint32_t v = g[m->tri[3 * t + (size_t)k]];
                pairs[at[v]++] = g[m->tri[3 * t + (size_t)(k + 1) % 3]];
                pairs[at[v]++] = g[m->tri[3 * t + (size_t)(k + 2) % 3]];
            }
    }
    free(at);
    /* sorted, each neighbour once; rows packed into nb */
    uint32_t out_at = 0;
    for (size_t v = 0; v < n; v++) {
        const uint32_t lo = first[v], hi = first[v + 1];
        qsort(pairs + lo, hi - lo, sizeof(uint32_t), by_value);
        first[v] = out_at;
        for (uint32_t k = lo; k < hi; k++)
            if (k == lo || pairs[k] != pairs[k - 1])
                nb[out_at++] = pairs[k];
    }
    first[n] = out_at;
    free(pairs);
    /* a vertex locked in one of its meshes stays */
    for (size_t i = 0; i < count; i++) {
        const isomend_mesh *m = meshes[i];
        if (!mesh_free_vertices(m, NULL, vfree, NULL, NULL, NULL))
            goto done;
        for (size_t v = 0; v < m->nv; v++)
            free_v[gid[base[i] + v]] &= vfree[v];
    }
    /* the filter on coordinates centred on the set's box */
    float lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0}, mid[3];
    for (size_t v = 0; v < n; v++)
        for (int d = 0; d < 3; d++) {
            const float x = x0[3 * v + (size_t)d];
            lo[d] = v == 0 || x < lo[d] ? x : lo[d];
            hi[d] = v == 0 || x > hi[d] ? x : hi[d];
        }
    for (int d = 0; d < 3; d++)
        mid[d] = 0.5f * (lo[d] + hi[d]);
    memcpy(y, x0, 12 * n); /* the input's positions, x0 centred in place */
    for (size_t v = 0; v < n; v++)
        for (int d = 0; d < 3; d++)
            x0[3 * v + (size_t)d] -= mid[d];
    for (int d = 0; d < 4; d++)
        x0[3 * n + (size_t)d] = 0;
    tm = team_start(n);
    float *pos = y; /* iterations 0: the input's */
    if (iterations > 0 && n > 0) {
        float *f = malloc(12 * n1 + 16);
        if (!f)
            goto done;
        if (!sinc_filter(tm, n, first, nb, free_v, x0, b, deg, f, iterations, NULL)) {
            free(f);
            goto done;
        }
        for (size_t v = 0; v < n; v++) /* locked vertices exactly where they were */
            if (free_v[v])
                for (int d = 0; d < 3; d++)
                    y[3 * v + (size_t)d] = f[3 * v + (size_t)d] + mid[d];
        free(f);
    }
    /* each mesh takes its vertices' positions */
    for (size_t i = 0; i < count; i++) {
        const isomend_mesh *m = meshes[i];
        isomend_mesh *r = calloc(1, sizeof(*r));
        if (!r)
            goto done;
        out[i] = r;
        r->nv = m->nv;
        r->nt = m->nt;
        r->pos = malloc(12 * (m->nv ? m->nv : 1));
        r->tri = malloc(12 * (m->nt ? m->nt : 1));
        r->nrm = m->nrm ? malloc(12 * (m->nv ? m->nv : 1)) : NULL;
        r->org = m->org ? malloc(m->nt ? m->nt : 1) : NULL;
        if (!r->pos || !r->tri || (m->nrm && !r->nrm) || (m->org && !r->org))
            goto done;
        double worst = 0;
        uint64_t moved = 0;
        for (size_t v = 0; v < m->nv; v++) {
            const uint32_t g = gid[base[i] + v];
            double d2 = 0;
            for (int d = 0; d < 3; d++) {
                r->pos[3 * v + (size_t)d] = pos[3 * (size_t)g + (size_t)d];
                const double e = (double)r->pos[3 * v + (size_t)d] - m->pos[3 * v + (size_t)d];
                d2 += e * e;
            }
            worst = d2 > worst ? d2 : worst;
            moved += free_v[g] && iterations > 0;
        }
        memcpy(r->tri, m->tri, 12 * m->nt);
        if (m->org)
            memcpy(r->org, m->org, m->nt);
        if (r->nrm)
            mesh_area_normals(r, m->nrm);
        if ((status = mesh_copy_frame(r, m)) != ISOMEND_OK)
            goto done;
        status = ISOMEND_ERR_OUT_OF_MEMORY;
        if (reports) {
            reports[i].moved_vertices = moved;
            reports[i].volume_before = mesh_volume(m->pos, m->tri, m->nt);
            reports[i].volume_after = mesh_volume(r->pos, r->tri, r->nt);
            reports[i].max_displacement = sqrt(worst);
        }
    }
    status = ISOMEND_OK;
done:
    if (status != ISOMEND_OK)
        meshes_destroy(out, count);
    team_stop(tm);
    vertex_set_free(&set);
    free(first);
    free(nb);
    free(free_v);
    free(deg);
    free(vfree);
    free(b);
    free(y);
    return status;
}
