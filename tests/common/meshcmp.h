/* Mesh equality for the core tests: the same vertices (positions, normals),
 * triangles and triangle origins, bit for bit and in the same order. */
#ifndef ISOMEND_TEST_MESHCMP_H
#define ISOMEND_TEST_MESHCMP_H
#include "isomend.h"

#include <stdint.h>
#include <string.h>

static inline int same_mesh(const isomend_mesh *a, const isomend_mesh *b)
{
    size_t nv = isomend_mesh_vertex_count(a), nt = isomend_mesh_triangle_count(a);
    if (nv != isomend_mesh_vertex_count(b) || nt != isomend_mesh_triangle_count(b))
        return 0;
    if (memcmp(isomend_mesh_positions(a), isomend_mesh_positions(b), 12 * nv) ||
        memcmp(isomend_mesh_triangles(a), isomend_mesh_triangles(b), 12 * nt))
        return 0;
    const float *na = isomend_mesh_normals(a), *nb = isomend_mesh_normals(b);
    if ((na == NULL) != (nb == NULL) || (na && memcmp(na, nb, 12 * nv)))
        return 0;
    const uint8_t *oa = isomend_mesh_triangle_origins(a), *ob = isomend_mesh_triangle_origins(b);
    if ((oa == NULL) != (ob == NULL) || (oa && memcmp(oa, ob, nt)))
        return 0;
    return 1;
}

#endif
