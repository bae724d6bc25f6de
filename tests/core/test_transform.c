/*
 * test_transform.c - isomend_mesh_copy_transformed: a mesh through affine maps
 *
 * An off-centre ellipsoid blob (padded: a closed surface) is extracted and
 * copied through a rotation, a mirror (det < 0), a rotation with a mirror, an
 * anisotropic scale with a shear, and a translation.  Every copy must be
 *   - at p' = M p + t (positions),
 *   - a closed, oriented 2-manifold (isomend_check: no hole, border,
 *     non-manifold or misoriented edge), with the original's triangles
 *     (reversed in winding exactly when det M < 0),
 *   - outward: positive signed volume, equal to |det M| times the original's,
 *   - with unit normals that agree with the triangles' winding (each vertex
 *     normal points to the side its triangles face) and point to lower values.
 * A singular or non-finite map is refused.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "isomend.h"
#include "testutil.h"

#define N 24

static double signed_volume(const float *p, const uint32_t *t, size_t nt)
{
    double v = 0;
    for (size_t i = 0; i < nt; i++) {
        const float *a = p + 3 * t[3 * i], *b = p + 3 * t[3 * i + 1], *c = p + 3 * t[3 * i + 2];
        v += ((double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
              (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
              (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) / 6.0;
    }
    return v;
}

static void check_map(const isomend_mesh *m, const double A[12], const char *name)
{
    size_t nv = isomend_mesh_vertex_count(m), nt = isomend_mesh_triangle_count(m);
    float *p = malloc(sizeof(float) * 3 * nv), *n = malloc(sizeof(float) * 3 * nv);
    uint32_t *t = malloc(sizeof(uint32_t) * 3 * nt);
    uint8_t *o = malloc(nt);
    CHECK(isomend_mesh_copy_transformed(m, A, p, n, t, o) == ISOMEND_OK);
    const float *p0 = isomend_mesh_positions(m);
    const uint32_t *t0 = isomend_mesh_triangles(m);
    double det = A[0] * (A[5] * A[10] - A[6] * A[9]) - A[1] * (A[4] * A[10] - A[6] * A[8]) +
                 A[2] * (A[4] * A[9] - A[5] * A[8]);
    double worst = 0;
    for (size_t i = 0; i < nv; i++)
        for (int r = 0; r < 3; r++) {
            double w = A[4 * r] * p0[3 * i] + A[4 * r + 1] * p0[3 * i + 1] + A[4 * r + 2] * p0[3 * i + 2] +
                       A[4 * r + 3];
            worst = fmax(worst, fabs(w - p[3 * i + r]) / (1.0 + fabs(w)));
        }
    CHECK(worst < 1e-6);
    int same = 1, reversed = 1;
    for (size_t i = 0; i < nt; i++) {
        if (t[3 * i] != t0[3 * i] || t[3 * i + 1] != t0[3 * i + 1] || t[3 * i + 2] != t0[3 * i + 2]) same = 0;
        if (t[3 * i] != t0[3 * i] || t[3 * i + 1] != t0[3 * i + 2] || t[3 * i + 2] != t0[3 * i + 1]) reversed = 0;
    }
    CHECK(det > 0 ? same : reversed);
    CHECK(memcmp(o, isomend_mesh_triangle_origins(m), nt) == 0);
    isomend_check_report rep;
    CHECK(isomend_check(p, nv, t, nt, NULL, &rep) == ISOMEND_OK);
    CHECK_EQ_INT(rep.hole_edges + rep.border_edges + rep.nonmanifold_edges + rep.misoriented_edges, 0);
    double v0 = signed_volume(p0, t0, nt), v = signed_volume(p, t, nt);
    CHECK(v0 > 0 && v > 0 && fabs(v - fabs(det) * v0) < 1e-4 * fabs(det) * v0);
    /* normals: unit, and on the side the triangles face */
    double *face = calloc(3 * nv, sizeof(double));
    for (size_t i = 0; i < nt; i++) {
        const float *a = p + 3 * t[3 * i], *b = p + 3 * t[3 * i + 1], *c = p + 3 * t[3 * i + 2];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double g[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; k++)
            for (int r = 0; r < 3; r++) face[3 * t[3 * i + k] + r] += g[r];
    }
    size_t against = 0;
    for (size_t i = 0; i < nv; i++) {
        double len = sqrt(n[3 * i] * n[3 * i] + n[3 * i + 1] * n[3 * i + 1] + n[3 * i + 2] * n[3 * i + 2]);
        CHECK(fabs(len - 1.0) < 1e-5);
        if (n[3 * i] * face[3 * i] + n[3 * i + 1] * face[3 * i + 1] + n[3 * i + 2] * face[3 * i + 2] <= 0) against++;
    }
    if (against) fprintf(stderr, "%s: %zu of %zu normals against their triangles\n", name, against, nv);
    CHECK_EQ_INT(against, 0);
    free(face);
    free(p);
    free(n);
    free(t);
    free(o);
}

int main(void)
{
    static float v[N * N * N];
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++) {
                double dx = (x - 10.3) / 7.0, dy = (y - 12.1) / 5.0, dz = (z - 11.7) / 8.5;
                v[x + N * (y + N * z)] = (float)(1.0 - (dx * dx + dy * dy + dz * dz));
            }
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F32, N, N, N);
    vol.spacing[0] = 0.7;
    vol.spacing[1] = 0.8;
    vol.spacing[2] = 1.25;
    isomend_options o;
    isomend_options_init(&o);
    o.flags = ISOMEND_FLAG_PAD;
    isomend_mesh *m = NULL;
    CHECK(isomend_extract(&vol, &o, &m, NULL) == ISOMEND_OK);
    CHECK(isomend_mesh_triangle_count(m) > 500);
    const double c = cos(0.6), s = sin(0.6);
    const double rot[12] = {c, -s, 0, 5, s, c, 0, -3, 0, 0, 1, 40};
    const double mirror[12] = {-1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    const double rot_mirror[12] = {c, s, 0, 1, s, -c, 0, 2, 0, 0, 1, 3};
    const double shear[12] = {2, 0.5, 0, 0, 0, 0.7, 0, 0, 0.3, 0, 1.5, -1};
    const double feet_first[12] = {-1, 0, 0, 14, 0, 1, 0, 0, 0, 0, -1, 40}; /* det +1 */
    check_map(m, rot, "rotation");
    check_map(m, mirror, "mirror");
    check_map(m, rot_mirror, "rotation with mirror");
    check_map(m, shear, "shear and scale");
    check_map(m, feet_first, "180 degrees about y");
    const double singular[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0};
    double bad[12];
    memcpy(bad, rot, sizeof bad);
    bad[3] = NAN;
    float one[3];
    CHECK(isomend_mesh_copy_transformed(m, singular, NULL, NULL, NULL, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_mesh_copy_transformed(m, bad, NULL, NULL, NULL, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_mesh_copy_transformed(NULL, rot, one, NULL, NULL, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_mesh_copy_transformed(m, NULL, one, NULL, NULL, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_mesh_destroy(m);
    TEST_EXIT();
}
