/*
 * transform.c - a mesh copied through an affine map (isomend_mesh_copy_transformed)
 *
 * The core extracts on an axis-aligned grid (origin + index * spacing).  A
 * volume whose samples lie on a turned or mirrored grid (a DICOM series with
 * oblique direction cosines, a NRRD with general "space directions") is
 * extracted on its own grid and its mesh is then mapped by the affine map A
 * of that grid to the world: p' = M p + t.
 *
 *   - positions: p' = M p + t, in double, rounded once to float;
 *   - normals: they are gradient directions, which map by the inverse
 *     transpose of M (a normal stays perpendicular to the surface also under
 *     a shear or an anisotropic scale), renormalised;
 *   - winding: triangles are counter-clockwise seen from where the normals
 *     point.  The geometric normal of a triangle, (b - a) x (c - a), maps by
 *     the cofactor matrix det(M) M^-T: when det(M) < 0 (a mirror) it turns
 *     against the mapped gradient normals, so the winding is reversed (two
 *     indices swapped) and the surface stays outward-facing, never inside out.
 *
 * The arrays are the caller's (count-then-fill, like isomend_mesh_copy), so
 * the mesh object itself, its grid box and isomend_mesh_check() stay those
 * of the grid it was extracted on; the topology of the mapped copy is the
 * same (the map is invertible).
 */
#include "isomend.h"

#include <math.h>
#include <string.h>

isomend_status isomend_mesh_copy_transformed(const isomend_mesh *mesh, const double affine[12],
                                             float *positions, float *normals,
                                             uint32_t *triangles, uint8_t *origins)
{
    if (!mesh || !affine)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    for (int i = 0; i < 12; i++)
        if (!isfinite(affine[i]))
            return ISOMEND_ERR_INVALID_ARGUMENT;
    const double *m0 = affine, *m1 = affine + 4, *m2 = affine + 8;
    /* cofactor matrix C (C = det(M) M^-T): C[r][c] */
    const double c[3][3] = {
        {m1[1] * m2[2] - m1[2] * m2[1], m1[2] * m2[0] - m1[0] * m2[2], m1[0] * m2[1] - m1[1] * m2[0]},
        {m2[1] * m0[2] - m2[2] * m0[1], m2[2] * m0[0] - m2[0] * m0[2], m2[0] * m0[1] - m2[1] * m0[0]},
        {m0[1] * m1[2] - m0[2] * m1[1], m0[2] * m1[0] - m0[0] * m1[2], m0[0] * m1[1] - m0[1] * m1[0]}};
    const double det = m0[0] * c[0][0] + m0[1] * c[0][1] + m0[2] * c[0][2];
    if (!(fabs(det) > 0.0) || !isfinite(det))
        return ISOMEND_ERR_INVALID_ARGUMENT; /* singular: no surface survives it */
    /* the normals map by M^-T = C / det; the sign of det is kept so that they
     * keep pointing to the side of lower values */
    const double s = 1.0 / det;
    const size_t nv = isomend_mesh_vertex_count(mesh), nt = isomend_mesh_triangle_count(mesh);
    const float *pos = isomend_mesh_positions(mesh);
    const float *nrm = isomend_mesh_normals(mesh);
    const uint32_t *tri = isomend_mesh_triangles(mesh);
    const uint8_t *org = isomend_mesh_triangle_origins(mesh);
    if ((normals && !nrm) || (origins && !org))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (positions) {
        for (size_t i = 0; i < nv; i++) {
            const double x = pos[3 * i], y = pos[3 * i + 1], z = pos[3 * i + 2];
            positions[3 * i] = (float)(m0[0] * x + m0[1] * y + m0[2] * z + m0[3]);
            positions[3 * i + 1] = (float)(m1[0] * x + m1[1] * y + m1[2] * z + m1[3]);
            positions[3 * i + 2] = (float)(m2[0] * x + m2[1] * y + m2[2] * z + m2[3]);
        }
    }
    if (normals) {
        for (size_t i = 0; i < nv; i++) {
            const double x = nrm[3 * i], y = nrm[3 * i + 1], z = nrm[3 * i + 2];
            double n[3];
            for (int r = 0; r < 3; r++)
                n[r] = s * (c[r][0] * x + c[r][1] * y + c[r][2] * z);
            const double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            const double inv = len > 0.0 ? 1.0 / len : 0.0;
            for (int r = 0; r < 3; r++)
                normals[3 * i + r] = (float)(n[r] * inv);
        }
    }
    if (triangles) {
        if (det > 0.0) {
            memcpy(triangles, tri, sizeof(uint32_t) * 3 * nt);
        } else {
            for (size_t t = 0; t < nt; t++) {
                triangles[3 * t] = tri[3 * t];
                triangles[3 * t + 1] = tri[3 * t + 2];
                triangles[3 * t + 2] = tri[3 * t + 1];
            }
        }
    }
    if (origins)
        memcpy(origins, org, nt);
    return ISOMEND_OK;
}
