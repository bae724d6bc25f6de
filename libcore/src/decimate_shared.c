/*
 * decimate_shared.c - isomend_meshes_decimate(): surfaces that meet (a
 * label map's meshes) decimated so that they still meet.
 *
 * Where two labels touch, their meshes hold the same surface: the same
 * vertices (one grid edge's midpoint in both, smooth_shared.c's vertex set)
 * and the same triangles, facing opposite ways.  A collapse there would have
 * to be made in both meshes at once, the same way; isomend_mesh_decimate()
 * run on each mesh alone would make different ones and part the
 * neighbours.  Here every vertex that another mesh holds too is locked
 * (decimate_carry.locked): no edge touching it collapses, so the shared
 * surfaces, and the ring of triangles around them, stay as they are in both
 * meshes, and the rest of each mesh (its surface against the background)
 * is decimated with the options as isomend_mesh_decimate() does it, with
 * every guarantee of that (closed, oriented, components and genus kept).
 * A label that touches others all over (a ball inside another) keeps its
 * triangles.
 */
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

isomend_status isomend_meshes_decimate(const isomend_mesh *const *meshes, size_t count,
                                       const isomend_decimate_options *o, isomend_mesh **out,
                                       isomend_decimate_report *reports)
{
    vertex_set set;
    isomend_status status = vertex_set_build(meshes, count, out, 0, &set);
    if (status != ISOMEND_OK)
        return status;
    if (!o || !(o->ratio >= 0.0 && o->ratio <= 1.0) || !(o->max_error >= 0.0) ||
        !isfinite(o->max_error) || (o->ratio == 0.0 && o->target_triangles == 0 && o->max_error == 0.0)) {
        vertex_set_free(&set);
        return ISOMEND_ERR_INVALID_ARGUMENT;
    }
    status = ISOMEND_ERR_OUT_OF_MEMORY;
    const size_t n1 = set.total ? set.total : 1;
    const uint32_t *gid = set.gid;
    const size_t *base = set.base;
    uint32_t *owners = calloc(n1, sizeof(uint32_t)); /* meshes holding a set vertex */
    uint8_t *locked = malloc(n1);
    if (!owners || !locked)
        goto done;
    for (size_t i = 0; i < count; i++)
        for (size_t v = 0; v < meshes[i]->nv; v++)
            owners[gid[base[i] + v]]++;
    for (size_t i = 0; i < count; i++) {
        const isomend_mesh *m = meshes[i];
        for (size_t v = 0; v < m->nv; v++)
            locked[v] = owners[gid[base[i] + v]] > 1;
        uint64_t target = 0;
        if (o->ratio > 0)
            target = (uint64_t)ceil(o->ratio * (double)m->nt);
        if (o->target_triangles > target)
            target = o->target_triangles;
        decimate_carry carry = {NULL, 0, NULL, NULL, NULL, NULL, NULL, locked, 0};
        status = mesh_decimate_to(m, target, o->max_error, 1, &out[i], NULL, &carry,
                                  reports ? &reports[i] : NULL);
        free(carry.q_out); /* (the quadrics carried out: not wanted here) */
        if (status != ISOMEND_OK)
            goto done;
    }
    status = ISOMEND_OK;
done:
    if (status != ISOMEND_OK)
        meshes_destroy(out, count);
    vertex_set_free(&set);
    free(owners);
    free(locked);
    return status;
}
