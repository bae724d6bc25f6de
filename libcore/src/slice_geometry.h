/*
 * slice_geometry.h - slices where they are (private; slice_geometry.c).
 */
#ifndef ISOMEND_SLICE_GEOMETRY_H
#define ISOMEND_SLICE_GEOMETRY_H

#include "grid.h"

/* The table's checks; marched slice m's origin (padding one gap beyond the
 * ends); the vertex between marched samples p0 and p1 and its normal from
 * the true positions; the grid's world box; the mesh's copy of the table
 * (unshear_point, the check's frame, is in mesh_internal.h). */
isomend_status slice_origins_validate(const isomend_volume *vol);
void slice_origin(const slice_table *t, int64_t m, double o[3]);
void sheared_vertex(const grid *g, int flip, const int64_t p0[3], const int64_t p1[3], float *pos,
                    float *nrm);
void sheared_box(const grid *g, double box[6]);
isomend_status mesh_keep_slices(isomend_mesh *mesh, const grid *g);

#endif /* ISOMEND_SLICE_GEOMETRY_H */
