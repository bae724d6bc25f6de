/*
 * components.c - connected components of a mesh (triangles joined through
 * shared vertices) and isomend_mesh_clean(), which drops the small ones or
 * keeps the largest: the noise islands of a CT or microscopy surface.
 */
#include "mesh_internal.h"

#include <stdlib.h>
#include <string.h>

static uint32_t find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

int64_t mesh_components(const isomend_mesh *m, uint32_t *label)
{
    for (size_t v = 0; v < m->nv; v++)
        label[v] = (uint32_t)v;
    for (size_t t = 0; t < m->nt; t++) {
        const uint32_t *v = m->tri + 3 * t;
        for (int k = 1; k < 3; k++) {
            uint32_t a = find(label, v[0]), b = find(label, v[k]);
            if (a != b) {
                if (a < b)
                    label[b] = a;
                else
                    label[a] = b;
            }
        }
    }
    /* every vertex to its root (a set's smallest vertex), then the roots
     * numbered in vertex order: component 0 holds vertex 0 */
    for (size_t v = 0; v < m->nv; v++)
        label[v] = find(label, (uint32_t)v);
    int64_t count = 0;
    for (size_t v = 0; v < m->nv; v++)
        label[v] = label[v] == v ? (uint32_t)count++ : label[label[v]];
    return count;
}

typedef struct comp {
    uint64_t triangles;
    uint64_t first; /* its first triangle */
    uint32_t index;
    uint8_t keep;
} comp;

static int by_size(const void *x, const void *y)
{
    const comp *a = x, *b = y;
    if (a->triangles != b->triangles)
        return a->triangles > b->triangles ? -1 : 1;
    return a->first < b->first ? -1 : a->first > b->first;
}

isomend_status isomend_mesh_clean(const isomend_mesh *mesh, uint64_t min_triangles,
                                  uint64_t keep_largest, isomend_mesh **out,
                                  isomend_clean_report *report)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    if (!mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    const size_t nv = mesh->nv ? mesh->nv : 1;
    uint32_t *label = malloc(nv * sizeof(uint32_t)), *remap = malloc(nv * sizeof(uint32_t));
    isomend_mesh *m = calloc(1, sizeof(*m));
    comp *cs = NULL, *order = NULL;
    isomend_status status = ISOMEND_ERR_OUT_OF_MEMORY;
    if (!label || !remap || !m)
        goto fail;
    const int64_t nc = mesh_components(mesh, label);
    cs = calloc((size_t)nc + 1, sizeof(comp));
    order = calloc((size_t)nc + 1, sizeof(comp));
    if (!cs || !order)
        goto fail;
    for (int64_t c = 0; c < nc; c++) {
        cs[c].index = (uint32_t)c;
        cs[c].first = UINT64_MAX;
    }
    for (size_t t = 0; t < mesh->nt; t++) {
        comp *c = &cs[label[mesh->tri[3 * t]]];
        c->triangles++;
        if (c->first == UINT64_MAX)
            c->first = t;
    }
    /* components without triangles (unused vertices) are not components */
    int64_t real = 0;
    for (int64_t c = 0; c < nc; c++)
        if (cs[c].triangles && cs[c].triangles >= min_triangles)
            order[real++] = cs[c];
    qsort(order, (size_t)real, sizeof(comp), by_size);
    if (keep_largest && (uint64_t)real > keep_largest)
        real = (int64_t)keep_largest;
    for (int64_t r = 0; r < real; r++)
        cs[order[r].index].keep = 1;
    size_t kv = 0, kt = 0;
    for (size_t v = 0; v < mesh->nv; v++)
        remap[v] = UINT32_MAX;
    for (size_t t = 0; t < mesh->nt; t++)
        if (cs[label[mesh->tri[3 * t]]].keep) {
            kt++;
            for (int k = 0; k < 3; k++)
                remap[mesh->tri[3 * t + (size_t)k]] = 0;
        }
    for (size_t v = 0; v < mesh->nv; v++)
        if (remap[v] != UINT32_MAX)
            remap[v] = (uint32_t)kv++;
    m->nv = kv;
    m->nt = kt;
    m->pos = malloc(12 * (kv ? kv : 1));
    m->tri = malloc(12 * (kt ? kt : 1));
    m->nrm = mesh->nrm ? malloc(12 * (kv ? kv : 1)) : NULL;
    m->org = mesh->org ? malloc(kt ? kt : 1) : NULL;
    if (!m->pos || !m->tri || (mesh->nrm && !m->nrm) || (mesh->org && !m->org))
        goto fail;
    for (size_t v = 0; v < mesh->nv; v++)
        if (remap[v] != UINT32_MAX) {
            memcpy(m->pos + 3 * (size_t)remap[v], mesh->pos + 3 * v, 12);
            if (m->nrm)
                memcpy(m->nrm + 3 * (size_t)remap[v], mesh->nrm + 3 * v, 12);
        }
    size_t o = 0;
    for (size_t t = 0; t < mesh->nt; t++)
        if (cs[label[mesh->tri[3 * t]]].keep) {
            for (int k = 0; k < 3; k++)
                m->tri[3 * o + (size_t)k] = remap[mesh->tri[3 * t + (size_t)k]];
            if (m->org)
                m->org[o] = mesh->org[t];
            o++;
        }
    if (mesh_copy_frame(m, mesh) != ISOMEND_OK)
        goto fail;
    if (report) {
        int64_t before = 0;
        for (int64_t c = 0; c < nc; c++)
            before += cs[c].triangles > 0;
        report->components_before = (uint64_t)before;
        report->components_after = (uint64_t)real;
        report->triangles_removed = mesh->nt - kt;
        report->vertices_removed = mesh->nv - kv;
    }
    free(label);
    free(remap);
    free(cs);
    free(order);
    *out = m;
    return ISOMEND_OK;
fail:
    free(label);
    free(remap);
    free(cs);
    free(order);
    isomend_mesh_destroy(m);
    return status;
}
