/*
 * test_random.c - random volumes (uniform noise of several sizes and shapes,
 * integer data with samples exactly at the iso level, NaNs, with and without
 * padding):
 *   - DMC output is a consistently oriented 2-manifold whose only once-used
 *     edges lie on the volume border (none when padded), with outward
 *     normals (positive signed volume) when closed;
 *   - MC shows holes on the same volumes;
 *   - the mesh is identical, vertex order included, for 1, 2 and 8 threads;
 *   - every voxel type gives the same mesh for the same values; a strided
 *     view gives the same mesh as a contiguous copy.
 */
#include "isomend.h"
#include "cpu_target.h"
#include "schedule.h"
#include "meshcmp.h"
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;

static uint32_t rng(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (uint32_t)(rng_state >> 11);
}

static isomend_mesh *extract(const isomend_volume *vol, double iso, isomend_method m,
                             unsigned flags, int threads, isomend_stats *st)
{
    isomend_options o;
    isomend_options_init(&o);
    o.iso = iso;
    o.method = m;
    o.flags = flags;
    o.threads = threads;
    isomend_mesh *mesh = NULL;
    isomend_status s = isomend_extract(vol, &o, &mesh, st);
    CHECK_EQ_INT(s, ISOMEND_OK);
    return mesh;
}

static double signed_volume(const isomend_mesh *m)
{
    const float *p = isomend_mesh_positions(m);
    const uint32_t *t = isomend_mesh_triangles(m);
    double vol = 0.0;
    for (size_t i = 0; i < isomend_mesh_triangle_count(m); i++) {
        const float *a = p + 3 * t[3 * i], *b = p + 3 * t[3 * i + 1], *c = p + 3 * t[3 * i + 2];
        vol += (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
                a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) / 6.0;
    }
    return vol;
}

/* Vertex normals agree with the winding: summed over each vertex's triangles. */
static int normals_agree(const isomend_mesh *m)
{
    const float *p = isomend_mesh_positions(m), *n = isomend_mesh_normals(m);
    const uint32_t *t = isomend_mesh_triangles(m);
    size_t agree = 0, total = 0;
    for (size_t i = 0; i < isomend_mesh_triangle_count(m); i++) {
        const float *a = p + 3 * t[3 * i], *b = p + 3 * t[3 * i + 1], *c = p + 3 * t[3 * i + 2];
        double u[3], v[3];
        for (int k = 0; k < 3; k++) {
            u[k] = (double)b[k] - a[k];
            v[k] = (double)c[k] - a[k];
        }
        double f[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                       u[0] * v[1] - u[1] * v[0]};
        if (f[0] == 0 && f[1] == 0 && f[2] == 0)
            continue;
        double d = 0;
        for (int q = 0; q < 3; q++)
            for (int k = 0; k < 3; k++)
                d += f[k] * n[3 * t[3 * i + q] + k];
        agree += d > 0;
        total++;
    }
    /* On uniform noise the central-difference gradient is a poor estimate of
     * the facets' orientation (measured: 76-100 % agreement, lowest next to
     * NaNs); the smooth-field test in test_api.c checks directions exactly. */
    if (getenv("ISOMEND_TEST_VERBOSE"))
        fprintf(stderr, "normals agree on %zu of %zu triangles\n", agree, total);
    return total == 0 || agree >= total * 70 / 100;
}

static void check_dmc(const isomend_volume *vol, double iso, unsigned flags, int expect_closed)
{
    isomend_stats st;
    isomend_mesh *m1 = extract(vol, iso, ISOMEND_METHOD_DMC, flags, 1, &st);
    isomend_mesh *m2 = extract(vol, iso, ISOMEND_METHOD_DMC, flags, 2, NULL);
    isomend_mesh *m8 = extract(vol, iso, ISOMEND_METHOD_DMC, flags, 8, NULL);
    if (!m1 || !m2 || !m8)
        return;
    CHECK(same_mesh(m1, m2));
    CHECK(same_mesh(m1, m8));
    isomend_check_report r;
    CHECK_EQ_INT(isomend_mesh_check(m1, &r), ISOMEND_OK);
    CHECK_EQ_INT(r.hole_edges, 0);
    CHECK_EQ_INT(r.nonmanifold_edges, 0);
    CHECK_EQ_INT(r.misoriented_edges, 0);
    CHECK_EQ_INT(r.nonmanifold_vertices, 0);
    CHECK_EQ_INT(st.triangles_by_origin[ISOMEND_ORIGIN_MEND], 2 * st.inverted_combinations);
    CHECK_EQ_INT(st.triangles, isomend_mesh_triangle_count(m1));
    if (expect_closed) {
        CHECK_EQ_INT(r.border_edges, 0);
        if (isomend_mesh_triangle_count(m1))
            CHECK(signed_volume(m1) > 0.0);
    }
    if (!(flags & ISOMEND_FLAG_NO_NORMALS)) {
        CHECK(normals_agree(m1));
        const float *n = isomend_mesh_normals(m1);
        for (size_t i = 0; i < isomend_mesh_vertex_count(m1); i++) {
            double len = sqrt((double)n[3 * i] * n[3 * i] + (double)n[3 * i + 1] * n[3 * i + 1] +
                              (double)n[3 * i + 2] * n[3 * i + 2]);
            CHECK(fabs(len - 1.0) < 1e-5);
        }
    }
    /* MC on the same volume: holes exactly where DMC mended. */
    isomend_mesh *mc = extract(vol, iso, ISOMEND_METHOD_MC, flags, 1, NULL);
    if (mc) {
        isomend_check_report rm;
        CHECK_EQ_INT(isomend_mesh_check(mc, &rm), ISOMEND_OK);
        /* Every once-used edge MC has beyond DMC's is one of the 4 of a hole.
         * (Whether such an edge counts as hole or border is decided by
         * geometry: with samples exactly at the level next to the border a
         * hole edge can lie in the border plane, so compare the sums there.) */
        CHECK_EQ_INT(rm.hole_edges + rm.border_edges,
                     r.hole_edges + r.border_edges + 4 * st.inverted_combinations);
        if (flags & ISOMEND_FLAG_PAD)
            CHECK_EQ_INT(rm.hole_edges, 4 * st.inverted_combinations);
        CHECK_EQ_INT(rm.nonmanifold_edges, 0);
        CHECK_EQ_INT(isomend_mesh_triangle_count(mc) + 2 * st.inverted_combinations,
                     isomend_mesh_triangle_count(m1));
    }
    isomend_mesh_destroy(mc);
    isomend_mesh_destroy(m1);
    isomend_mesh_destroy(m2);
    isomend_mesh_destroy(m8);
}

/*
 * The methods beyond the thesis (facial, gradient, asymptotic, tetra, mc33)
 * through the extraction API: closed (padded), oriented 2-manifolds, the same
 * mesh for every thread count.  Their topology against the trilinear
 * interpolant is verified in tests/topology.
 */
static void check_methods(const isomend_volume *vol, double iso, unsigned flags, int closed)
{
    for (int m = ISOMEND_METHOD_FACIAL; m < ISOMEND_METHOD_COUNT; m++) {
        if (!isomend_method_available((isomend_method)m))
            continue;
        isomend_stats st;
        isomend_mesh *a = extract(vol, iso, (isomend_method)m, flags, 1, &st);
        isomend_mesh *b = extract(vol, iso, (isomend_method)m, flags, 3, NULL);
        if (!a || !b)
            continue;
        CHECK(same_mesh(a, b));
        isomend_check_report r;
        CHECK_EQ_INT(isomend_mesh_check(a, &r), ISOMEND_OK);
        CHECK_EQ_INT(r.hole_edges, 0);
        CHECK_EQ_INT(r.nonmanifold_edges, 0);
        CHECK_EQ_INT(r.misoriented_edges, 0);
        CHECK_EQ_INT(r.nonmanifold_vertices, 0);
        CHECK_EQ_INT(st.vertices, isomend_mesh_vertex_count(a));
        if (closed) {
            CHECK_EQ_INT(r.border_edges, 0);
            if (isomend_mesh_triangle_count(a))
                CHECK(signed_volume(a) > 0.0);
        }
        const float *p = isomend_mesh_positions(a);
        for (size_t i = 0; i < 3 * isomend_mesh_vertex_count(a); i++)
            CHECK(isfinite(p[i]));
        isomend_mesh_destroy(a);
        isomend_mesh_destroy(b);
    }
}

static void test_noise_shapes(void)
{
    static const int shapes[][3] = {{2, 2, 2}, {3, 5, 7}, {17, 9, 4}, {16, 16, 16},
                                    {1, 6, 6},  {40, 3, 11}, {33, 31, 29}};
    long total_inverted = 0;
    for (size_t s = 0; s < sizeof(shapes) / sizeof(shapes[0]); s++) {
        const int nx = shapes[s][0], ny = shapes[s][1], nz = shapes[s][2];
        const size_t n = (size_t)nx * ny * nz;
        float *v = malloc(n * sizeof(float));
        /* (k + 0.5) / 1000: no sample equals the level 0.5.  With ties a vertex
         * can sit on a border sample, and the checker's geometric border test
         * then counts a hole edge lying in the border plane as border; ties
         * are tested with integer data below. */
        for (size_t i = 0; i < n; i++)
            v[i] = ((float)(rng() % 1000) + 0.5f) / 1000.0f;
        isomend_volume vol;
        isomend_volume_init(&vol, v, ISOMEND_F32, nx, ny, nz);
        const int can_unpadded = nx >= 2 && ny >= 2 && nz >= 2;
        if (can_unpadded)
            check_dmc(&vol, 0.5, 0, 0);
        check_dmc(&vol, 0.5, ISOMEND_FLAG_PAD, 1);
        check_dmc(&vol, 0.5, ISOMEND_FLAG_PAD | ISOMEND_FLAG_NO_NORMALS, 1);
        check_methods(&vol, 0.5, ISOMEND_FLAG_PAD, 1);
        if (can_unpadded)
            check_methods(&vol, 0.5, 0, 0);
        isomend_stats st;
        isomend_mesh *m = extract(&vol, 0.5, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, 0, &st);
        total_inverted += (long)st.inverted_combinations;
        isomend_mesh_destroy(m);
        free(v);
    }
    CHECK(total_inverted > 100); /* the noise really exercises the mending */
}

/* Integer data in 0..3 with iso 1 and 2: many samples exactly at the level. */
static void test_ties_and_types(void)
{
    const int nx = 13, ny = 11, nz = 9;
    const size_t n = (size_t)nx * ny * nz;
    uint8_t *u8 = malloc(n);
    int8_t *i8 = malloc(n);
    uint16_t *u16 = malloc(2 * n);
    int16_t *i16 = malloc(2 * n);
    int32_t *i32 = malloc(4 * n);
    float *f32 = malloc(4 * n);
    double *f64 = malloc(8 * n);
    for (size_t i = 0; i < n; i++) {
        int x = (int)(rng() % 4);
        u8[i] = (uint8_t)x;
        i8[i] = (int8_t)x;
        u16[i] = (uint16_t)x;
        i16[i] = (int16_t)x;
        i32[i] = x;
        f32[i] = (float)x;
        f64[i] = x;
    }
    const void *data[7] = {u8, i8, u16, i16, i32, f32, f64};
    for (int iso = 1; iso <= 3; iso++) {
        isomend_volume ref;
        isomend_volume_init(&ref, f64, ISOMEND_F64, nx, ny, nz);
        check_dmc(&ref, iso, ISOMEND_FLAG_PAD, 1);
        check_dmc(&ref, iso, 0, 0);
        check_methods(&ref, iso, ISOMEND_FLAG_PAD, 1);
        isomend_mesh *want = extract(&ref, iso, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, 1, NULL);
        for (int t = 0; t < 6; t++) {
            isomend_volume vol;
            isomend_volume_init(&vol, data[t], (isomend_type)t, nx, ny, nz);
            isomend_mesh *got = extract(&vol, iso, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, 1, NULL);
            CHECK(got && want && same_mesh(got, want));
            isomend_mesh_destroy(got);
        }
        /* Non-integer level between samples agrees across types too. */
        isomend_mesh_destroy(want);
    }
    /* Levels beyond the type's range: nothing inside, or everything inside. */
    isomend_volume vol;
    isomend_volume_init(&vol, u8, ISOMEND_U8, nx, ny, nz);
    isomend_mesh *m = extract(&vol, 300.0, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, 1, NULL);
    CHECK(m && isomend_mesh_triangle_count(m) == 0);
    isomend_mesh_destroy(m);
    m = extract(&vol, -5.0, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, 1, NULL);
    CHECK(m && isomend_mesh_triangle_count(m) > 0); /* the padded box */
    if (m) {
        isomend_check_report r;
        isomend_mesh_check(m, &r);
        CHECK_EQ_INT(r.components, 1);
        CHECK_EQ_INT(r.euler, 2);
        CHECK_EQ_INT(r.border_edges, 0);
    }
    isomend_mesh_destroy(m);
    free(u8);
    free(i8);
    free(u16);
    free(i16);
    free(i32);
    free(f32);
    free(f64);
}

/* NaN samples: counted, outside, no NaN in the mesh.  Rows of 20 samples take
 * the classification's scalar loop; rows of 75, its 32-sample steps too. */
static void test_nan_volume(int nx, int ny, int nz)
{
    const size_t n = (size_t)nx * ny * nz;
    float *v = malloc(n * sizeof(float));
    size_t nans = 0;
    for (size_t i = 0; i < n; i++) {
        v[i] = (float)(rng() % 1000) / 1000.0f;
        if (rng() % 10 == 0) {
            v[i] = NAN;
            nans++;
        }
    }
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F32, nx, ny, nz);
    check_dmc(&vol, 0.3, ISOMEND_FLAG_PAD, 1);
    check_dmc(&vol, 0.3, 0, 0);
    check_methods(&vol, 0.3, ISOMEND_FLAG_PAD, 1);
    isomend_stats st;
    isomend_mesh *m = extract(&vol, 0.3, ISOMEND_METHOD_DMC, 0, 2, &st);
    CHECK_EQ_INT(st.nan_samples, nans);
    const float *p = isomend_mesh_positions(m), *nr = isomend_mesh_normals(m);
    for (size_t i = 0; m && i < 3 * isomend_mesh_vertex_count(m); i++)
        CHECK(isfinite(p[i]) && isfinite(nr[i]));
    isomend_mesh_destroy(m);
    free(v);
}

static void test_nan(void)
{
    test_nan_volume(20, 18, 16);
    test_nan_volume(75, 9, 7);
}

/* A strided view (every other sample of a bigger array, reversed in z). */
static void test_strides(void)
{
    const int nx = 9, ny = 8, nz = 7;
    float *big = malloc(sizeof(float) * 2 * nx * ny * nz);
    float *copy = malloc(sizeof(float) * nx * ny * nz);
    for (int i = 0; i < 2 * nx * ny * nz; i++)
        big[i] = (float)(rng() % 1000) / 1000.0f;
    for (int z = 0; z < nz; z++)
        for (int y = 0; y < ny; y++)
            for (int x = 0; x < nx; x++)
                copy[x + nx * (y + ny * z)] = big[2 * x + 2 * nx * (y + ny * (nz - 1 - z))];
    isomend_volume view, flat;
    isomend_volume_init(&flat, copy, ISOMEND_F32, nx, ny, nz);
    view = flat;
    view.data = big + 2 * nx * ny * (nz - 1);
    view.strides[0] = 2 * (int64_t)sizeof(float);
    view.strides[1] = 2 * nx * (int64_t)sizeof(float);
    view.strides[2] = -2 * nx * ny * (int64_t)sizeof(float);
    isomend_mesh *a = extract(&flat, 0.5, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, 2, NULL);
    isomend_mesh *b = extract(&view, 0.5, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD, 2, NULL);
    CHECK(a && b && same_mesh(a, b));
    isomend_mesh_destroy(a);
    isomend_mesh_destroy(b);
    free(big);
    free(copy);
}

int main(int argc, char **argv)
{
    if (cpu_target_from_args(argc, argv) || schedule_from_args(argc, argv))
        return 1;
    test_noise_shapes();
    test_ties_and_types();
    test_nan();
    test_strides();
    TEST_EXIT();
}
