/*
 * test_api.c - the public API's contracts: every bad argument gets its status
 * and no mesh; names round-trip; cancellation from the progress callback;
 * world coordinates from origin and spacing; --flip reverses winding and
 * normals together; isomend_extract_recycle gives isomend_extract's mesh;
 * threads = 0 means the cores the process may run on (its affinity mask).
 */
#define _GNU_SOURCE /* sched_setaffinity, CPU_COUNT */
#include "isomend.h"
#include "schedule.h"
#include "testutil.h"

#include <math.h>
#include <sched.h>
#include <stdlib.h>
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
    CHECK(isomend_mesh_check_memory(NULL) == 0);
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

/* Smoothed pseudo-random field on an n^3 grid: many ambiguous faces, so DMC
 * writes mending quadrilaterals and the origins are not all zero. */
static float *noise_volume(int n, unsigned seed)
{
    float *v = malloc(sizeof(float) * (size_t)n * (size_t)n * (size_t)n);
    CHECK(v != NULL);
    if (!v)
        return NULL;
    for (int z = 0; z < n; z++)
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++)
                v[x + n * (y + n * z)] =
                    (float)(sin(0.37 * x + seed) * cos(0.29 * y - 0.5 * seed) +
                            sin(0.23 * z + 0.11 * x * (seed % 3)) * 0.8 +
                            0.3 * sin(1.7 * x + 2.3 * y + 3.1 * z + seed));
    return v;
}

static int same_mesh(const isomend_mesh *a, const isomend_mesh *b)
{
    const size_t nv = isomend_mesh_vertex_count(a), nt = isomend_mesh_triangle_count(a);
    if (nv != isomend_mesh_vertex_count(b) || nt != isomend_mesh_triangle_count(b))
        return 0;
    if (memcmp(isomend_mesh_positions(a), isomend_mesh_positions(b), 12 * nv) != 0 ||
        memcmp(isomend_mesh_triangles(a), isomend_mesh_triangles(b), 12 * nt) != 0)
        return 0;
    const float *na = isomend_mesh_normals(a), *nb = isomend_mesh_normals(b);
    if (!na != !nb || (na && memcmp(na, nb, 12 * nv) != 0))
        return 0;
    const uint8_t *oa = isomend_mesh_triangle_origins(a), *ob = isomend_mesh_triangle_origins(b);
    return !oa == !ob && (!oa || memcmp(oa, ob, nt) == 0);
}

/*
 * isomend_extract_recycle: the new mesh is isomend_extract()'s byte for byte
 * whatever the recycled mesh held (a larger or smaller one, with or without
 * normals and origins, mended triangles where the new mesh has none), at 1,
 * 2 and 3 threads (the caller's run alone, and with the counted split or
 * staged runs; counted runs on the 96^3 grid); bad arguments destroy the
 * old mesh and leave NULL.
 */
static void test_recycle(void)
{
    const int sizes[3] = {130, 96, 140}; /* 130^3 and 140^3: reserved arrays */
    float *vols[3];
    for (int q = 0; q < 3; q++)
        vols[q] = noise_volume(sizes[q], 7u + (unsigned)q);
    if (!vols[0] || !vols[1] || !vols[2])
        return;
    const double isos[3] = {0.0, 0.4, -0.3};
    const unsigned flags[3] = {0, ISOMEND_FLAG_NO_NORMALS, ISOMEND_FLAG_NO_ORIGINS};
    for (int threads = 1; threads <= 3; threads++) {
        isomend_mesh *kept = NULL;
        for (int step = 0; step < 7; step++) {
            const int q = step % 3;
            isomend_volume vol;
            isomend_volume_init(&vol, vols[q], ISOMEND_F32, sizes[q], sizes[q], sizes[q]);
            isomend_options o;
            isomend_options_init(&o);
            o.threads = threads;
            o.iso = isos[step % 3];
            o.flags = flags[(step / 2) % 3];
            isomend_mesh *fresh = NULL;
            isomend_stats sf, sr;
            CHECK_EQ_INT(isomend_extract(&vol, &o, &fresh, &sf), ISOMEND_OK);
            CHECK_EQ_INT(isomend_extract_recycle(&vol, &o, &kept, &sr), ISOMEND_OK);
            CHECK(kept != NULL && fresh != NULL);
            if (kept && fresh) {
                CHECK(same_mesh(kept, fresh));
                CHECK(memcmp(&sf, &sr, sizeof sf) == 0);
            }
            if (step == 0)
                CHECK(sf.triangles_by_origin[ISOMEND_ORIGIN_MEND] > 0);
            isomend_mesh_destroy(fresh);
        }
        /* Refused arguments: the old mesh is destroyed all the same. */
        isomend_volume bad;
        isomend_volume_init(&bad, vols[0], ISOMEND_F32, 1, sizes[0], sizes[0]);
        CHECK_EQ_INT(isomend_extract_recycle(&bad, NULL, &kept, NULL), ISOMEND_ERR_BAD_DIMENSIONS);
        CHECK(kept == NULL);
        /* A NULL mesh is isomend_extract(). */
        isomend_volume vol;
        isomend_volume_init(&vol, vols[1], ISOMEND_F32, sizes[1], sizes[1], sizes[1]);
        CHECK_EQ_INT(isomend_extract_recycle(&vol, NULL, &kept, NULL), ISOMEND_OK);
        CHECK(kept != NULL);
        isomend_mesh_destroy(kept);
    }
    CHECK_EQ_INT(isomend_extract_recycle(NULL, NULL, NULL, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    for (int q = 0; q < 3; q++)
        free(vols[q]);
}

/*
 * Two threads give one thread's mesh on grids of reserved arrays (2^20
 * samples and more): a dense field (the counted split; with
 * --schedule=staged staged runs, whose moves then span several huge pages
 * and release them as they go) and a sphere (sparse: staged runs).
 */
static void test_split(void)
{
    enum { N = 150 };
    float *dense = noise_volume(N, 3u);
    float *ball = malloc(sizeof(float) * N * N * N);
    CHECK(ball != NULL);
    if (!dense || !ball) {
        free(dense);
        free(ball);
        return;
    }
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++)
                ball[x + N * (y + N * z)] =
                    (float)(55.5 - sqrt((x - 70.2) * (x - 70.2) + (y - 77.9) * (y - 77.9) +
                                        (z - 74.4) * (z - 74.4)));
    const float *vols[2] = {dense, ball};
    for (int q = 0; q < 2; q++) {
        isomend_volume vol;
        isomend_volume_init(&vol, vols[q], ISOMEND_F32, N, N, N);
        isomend_options o;
        isomend_options_init(&o);
        isomend_mesh *m[2] = {NULL, NULL};
        isomend_stats st[2];
        for (int t = 0; t < 2; t++) {
            o.threads = t + 1;
            CHECK_EQ_INT(isomend_extract(&vol, &o, &m[t], &st[t]), ISOMEND_OK);
        }
        if (m[0] && m[1]) {
            CHECK(same_mesh(m[0], m[1]));
            CHECK(memcmp(&st[0], &st[1], sizeof st[0]) == 0);
            CHECK(isomend_mesh_vertex_count(m[0]) > (q ? 30000u : 1000000u));
        }
        isomend_mesh_destroy(m[0]);
        isomend_mesh_destroy(m[1]);
    }
    free(dense);
    free(ball);
}

/* isomend_cores() follows the affinity mask, and threads = 0 means it: a
 * stream's bound (one engine a worker, the slabs in flight) under a mask of
 * one core is that of one thread, under two that of two. */
static void test_cores(void)
{
    cpu_set_t all;
    CHECK_EQ_INT(sched_getaffinity(0, sizeof all, &all), 0);
    CHECK_EQ_INT(isomend_cores(), CPU_COUNT(&all));
    isomend_volume v;
    isomend_volume_init(&v, NULL, ISOMEND_U16, 256, 256, 512);
    isomend_options o0, o1, o2;
    isomend_options_init(&o0);
    o1 = o2 = o0;
    o1.threads = 1;
    o2.threads = 2;
    CHECK(isomend_stream_memory(&v, &o1) < isomend_stream_memory(&v, &o2));
    for (int want = 1; want <= 2 && want <= CPU_COUNT(&all); want++) {
        cpu_set_t some;
        CPU_ZERO(&some);
        int n = 0;
        for (int c = 0; c < CPU_SETSIZE && n < want; c++)
            if (CPU_ISSET(c, &all)) {
                CPU_SET(c, &some);
                n++;
            }
        CHECK_EQ_INT(sched_setaffinity(0, sizeof some, &some), 0);
        CHECK_EQ_INT(isomend_cores(), want);
        CHECK(isomend_stream_memory(&v, &o0) == isomend_stream_memory(&v, want == 1 ? &o1 : &o2));
        CHECK_EQ_INT(sched_setaffinity(0, sizeof all, &all), 0);
    }
}

int main(int argc, char **argv)
{
    if (schedule_from_args(argc, argv))
        return 1;
    test_errors();
    test_names();
    test_progress_and_geometry();
    test_recycle();
    test_split();
    test_cores();
    TEST_EXIT();
}
