/*
 * test_api.c - the public API's contracts: every bad argument gets its status
 * and no mesh; names round-trip; cancellation from the progress callback;
 * world coordinates from origin and spacing; --flip reverses winding and
 * normals together.
 */
#include "isomend.h"
#include "testutil.h"

#include <math.h>
#include <string.h>

static int progress_calls;
static double last_fraction;

static int count_progress(void *user, double f)
{
    (void)user;
    CHECK(f >= last_fraction && f <= 1.0);
    last_fraction = f;
    progress_calls++;
    return 0;
}

static int cancel_at_once(void *user, double f)
{
    (void)f;
    (*(int *)user)++;
    return 1;
}

static void test_errors(void)
{
    float v[27] = {0};
    v[13] = 1.0f;
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F32, 3, 3, 3);
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 0.5;
    isomend_mesh *m = (isomend_mesh *)&o; /* must be reset to NULL on failure */

    CHECK_EQ_INT(isomend_extract(NULL, &o, &m, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(m == NULL);
    CHECK_EQ_INT(isomend_extract(&vol, &o, NULL, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_volume bad = vol;
    bad.data = NULL;
    CHECK_EQ_INT(isomend_extract(&bad, &o, &m, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    bad = vol;
    bad.type = (isomend_type)42;
    CHECK_EQ_INT(isomend_extract(&bad, &o, &m, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    bad = vol;
    bad.dims[1] = 1;
    CHECK_EQ_INT(isomend_extract(&bad, &o, &m, NULL), ISOMEND_ERR_BAD_DIMENSIONS);
    bad.dims[1] = 0;
    CHECK_EQ_INT(isomend_extract(&bad, &o, &m, NULL), ISOMEND_ERR_BAD_DIMENSIONS);
    bad.dims[1] = -3;
    CHECK_EQ_INT(isomend_extract(&bad, &o, &m, NULL), ISOMEND_ERR_BAD_DIMENSIONS);
    bad = vol;
    bad.spacing[2] = 0.0;
    CHECK_EQ_INT(isomend_extract(&bad, &o, &m, NULL), ISOMEND_ERR_BAD_SPACING);
    bad.spacing[2] = -1.0;
    CHECK_EQ_INT(isomend_extract(&bad, &o, &m, NULL), ISOMEND_ERR_BAD_SPACING);
    bad.spacing[2] = NAN;
    CHECK_EQ_INT(isomend_extract(&bad, &o, &m, NULL), ISOMEND_ERR_BAD_SPACING);
    bad = vol;
    bad.origin[0] = INFINITY;
    CHECK_EQ_INT(isomend_extract(&bad, &o, &m, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_options bo = o;
    bo.iso = NAN;
    CHECK_EQ_INT(isomend_extract(&vol, &bo, &m, NULL), ISOMEND_ERR_BAD_ISO);
    bo.iso = INFINITY;
    CHECK_EQ_INT(isomend_extract(&vol, &bo, &m, NULL), ISOMEND_ERR_BAD_ISO);
    bo = o;
    bo.flags = 1u << 20;
    CHECK_EQ_INT(isomend_extract(&vol, &bo, &m, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    bo = o;
    bo.method = (isomend_method)99;
    CHECK_EQ_INT(isomend_extract(&vol, &bo, &m, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    for (int k = 0; k < ISOMEND_METHOD_COUNT; k++) {
        bo.method = (isomend_method)k;
        isomend_status s = isomend_extract(&vol, &bo, &m, NULL);
        CHECK_EQ_INT(s, isomend_method_available(bo.method) ? ISOMEND_OK
                                                            : ISOMEND_ERR_UNSUPPORTED);
        isomend_mesh_destroy(m);
    }
    /* a 1-sample-thick volume is fine with padding */
    bad = vol;
    bad.dims[2] = 1;
    bo = o;
    bo.flags = ISOMEND_FLAG_PAD;
    CHECK_EQ_INT(isomend_extract(&bad, &bo, &m, NULL), ISOMEND_OK);
    isomend_mesh_destroy(m);

    for (int s = 0; s <= ISOMEND_ERR_UNSUPPORTED; s++)
        CHECK(strlen(isomend_status_string((isomend_status)s)) > 3);
    CHECK(strcmp(isomend_status_string((isomend_status)1234), "unknown status") == 0);
    isomend_check_report r;
    uint32_t tri[3] = {0, 1, 5};
    float pos[9] = {0};
    CHECK_EQ_INT(isomend_check(pos, 3, tri, 1, NULL, &r), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_mesh_check(NULL, &r), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_mesh_destroy(NULL);
}

static void test_names(void)
{
    for (int t = 0; t < ISOMEND_TYPE_COUNT; t++) {
        isomend_type back;
        CHECK_EQ_INT(isomend_type_from_name(isomend_type_name((isomend_type)t), &back), ISOMEND_OK);
        CHECK_EQ_INT(back, t);
    }
    isomend_type tt;
    CHECK_EQ_INT(isomend_type_from_name("float", &tt), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_type_name((isomend_type)9) == NULL);
    CHECK_EQ_INT(isomend_type_size(ISOMEND_F64), 8);
    for (int k = 0; k < ISOMEND_METHOD_COUNT; k++) {
        isomend_method back;
        CHECK_EQ_INT(isomend_method_from_name(isomend_method_name((isomend_method)k), &back),
                     ISOMEND_OK);
        CHECK_EQ_INT(back, k);
    }
    isomend_method mm;
    CHECK_EQ_INT(isomend_method_from_name("MC", &mm), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(strcmp(isomend_version(), ISOMEND_VERSION_STRING) == 0);
}

static void test_progress_and_geometry(void)
{
    enum { N = 40 };
    static float v[N * N * N];
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++) {
                double dx = x - 19.5, dy = y - 19.5, dz = z - 19.5;
                v[x + N * (y + N * z)] = (float)sqrt(dx * dx + dy * dy + dz * dz);
            }
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F32, N, N, N);
    vol.spacing[0] = 0.5;
    vol.spacing[1] = 2.0;
    vol.spacing[2] = 1.25;
    vol.origin[0] = 100.0;
    vol.origin[1] = -7.0;
    vol.origin[2] = 3.0;
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 12.0;
    o.progress = count_progress;
    o.threads = 2;
    isomend_mesh *m = NULL;
    CHECK_EQ_INT(isomend_extract(&vol, &o, &m, NULL), ISOMEND_OK);
    CHECK(progress_calls >= 2 && last_fraction == 1.0);
    /* Distances in world space from the volume's centre: the sphere scaled
     * per axis by the spacing (the field is in index space). */
    const float *p = isomend_mesh_positions(m);
    for (size_t i = 0; i < isomend_mesh_vertex_count(m); i++) {
        double ix = (p[3 * i] - 100.0) / 0.5 - 19.5, iy = (p[3 * i + 1] + 7.0) / 2.0 - 19.5,
               iz = (p[3 * i + 2] - 3.0) / 1.25 - 19.5;
        double r = sqrt(ix * ix + iy * iy + iz * iz);
        CHECK(fabs(r - 12.0) < 0.05);
    }
    /* The box and the outward normals (the field grows outwards, so normals
     * towards lower values point inwards: flip makes them point out). */
    double box[6];
    isomend_mesh_grid_box(m, box);
    CHECK(box[0] == 100.0 && box[3] == 100.0 + 39 * 0.5 && box[4] == -7.0 + 39 * 2.0);

    isomend_options of = o;
    of.flags = ISOMEND_FLAG_FLIP;
    of.progress = NULL;
    isomend_mesh *mf = NULL;
    CHECK_EQ_INT(isomend_extract(&vol, &of, &mf, NULL), ISOMEND_OK);
    CHECK_EQ_INT(isomend_mesh_triangle_count(mf), isomend_mesh_triangle_count(m));
    const uint32_t *ta = isomend_mesh_triangles(m), *tb = isomend_mesh_triangles(mf);
    const float *na = isomend_mesh_normals(m), *nb = isomend_mesh_normals(mf);
    for (size_t i = 0; i < isomend_mesh_triangle_count(m); i++)
        CHECK(ta[3 * i] == tb[3 * i] && ta[3 * i + 1] == tb[3 * i + 2] &&
              ta[3 * i + 2] == tb[3 * i + 1]);
    for (size_t i = 0; i < 3 * isomend_mesh_vertex_count(m); i++)
        CHECK(na[i] == -nb[i]);
    CHECK(memcmp(isomend_mesh_triangle_origins(m), isomend_mesh_triangle_origins(mf),
                 isomend_mesh_triangle_count(m)) == 0);
    /* Default normals point towards lower values: inwards for this field. */
    for (size_t i = 0; i < isomend_mesh_vertex_count(m); i++) {
        double ix = p[3 * i] - (100.0 + 19.5 * 0.5), iy = p[3 * i + 1] - (-7.0 + 19.5 * 2.0),
               iz = p[3 * i + 2] - (3.0 + 19.5 * 1.25);
        CHECK(ix * na[3 * i] + iy * na[3 * i + 1] + iz * na[3 * i + 2] < 0.0);
    }
    /* Copy-out API. */
    size_t nv = isomend_mesh_vertex_count(m), nt = isomend_mesh_triangle_count(m);
    static float cp[3 * 40000], cn[3 * 40000];
    static uint32_t ct[3 * 80000];
    static uint8_t co[80000];
    CHECK(nv <= 40000 && nt <= 80000);
    CHECK_EQ_INT(isomend_mesh_copy(m, cp, cn, ct, co), ISOMEND_OK);
    CHECK(memcmp(cp, p, 12 * nv) == 0 && memcmp(ct, ta, 12 * nt) == 0);
    isomend_mesh_destroy(m);
    isomend_mesh_destroy(mf);

    /* Cancellation: the callback's non-zero return stops the extraction. */
    int calls = 0;
    o.progress = cancel_at_once;
    o.progress_user = &calls;
    m = (isomend_mesh *)&calls;
    CHECK_EQ_INT(isomend_extract(&vol, &o, &m, NULL), ISOMEND_ERR_CANCELLED);
    CHECK(m == NULL && calls >= 1);
}

int main(void)
{
    test_errors();
    test_names();
    test_progress_and_geometry();
    TEST_EXIT();
}
