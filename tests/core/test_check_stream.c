/*
 * test_check_stream.c - the streaming continuity check (isomend_check_stream_*)
 * against the in-memory one on the same mesh: every field of the report
 * equal, for
 *   - streams (isomend_stream_*) of sphere, gyroid, noise and random
 *     volumes, every method, padded and not, uniform and with sheared,
 *     uneven slices, checked through isomend_check_stream_sink() against
 *     isomend_mesh_check() on isomend_extract()'s mesh;
 *   - the same meshes fed from memory in random batches with random retire
 *     floors (batching and deferred work), against isomend_check();
 *   - hand-made meshes (a non-manifold vertex, flipped faces, degenerate
 *     triangles, several components and hole loops, an edge used 3 times,
 *     two cones on one apex of 300 neighbours)
 *     and random triangle soups on a coarse grid (collinear points, repeated
 *     indices, border edges), against isomend_check().
 * The cases must include each defect (else the test fails); bad input is
 * refused with ISOMEND_ERR_INVALID_ARGUMENT; the check's peak memory stays
 * put when the volume grows from 32 to 256 slices.
 *
 *   test_check_stream          the comparisons (core_check_stream)
 *   test_check_stream --bench [N]
 *                              the speed of both checks on an N^3 gyroid's
 *                              mesh (default 256), printed
 */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include "isomend.h"
#include "check.h"
#include "check_order.h"
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;

static uint32_t rng(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (uint32_t)(rng_state >> 11);
}

/* ------------------------------------------------------------ the reports */

static int compared_streams, compared_fed, compared_hand, compared_soups;
/* how many compared reports had each defect: the test must see them all */
/* sheared meshes whose check in the sheared frame (the grid box) differs:
 * the unsheared frame matters, and the streaming check found it */
static int sheared_frame_matters;
static int seen_border, seen_hole, seen_loops2, seen_nm_edge, seen_mis, seen_nm_vertex,
    seen_degenerate, seen_components2;

static int same_report(const isomend_check_report *a, const isomend_check_report *b,
                       const char *what)
{
    if (memcmp(a, b, sizeof *a) == 0) {
        seen_border += a->border_edges > 0;
        seen_hole += a->hole_edges > 0;
        seen_loops2 += a->hole_loops > 1;
        seen_nm_edge += a->nonmanifold_edges > 0;
        seen_mis += a->misoriented_edges > 0;
        seen_nm_vertex += a->nonmanifold_vertices > 0;
        seen_degenerate += a->degenerate_triangles > 0;
        seen_components2 += a->components > 1;
        return 1;
    }
    fprintf(stderr, "reports differ: %s\n", what);
    const uint64_t *x = (const uint64_t *)(const void *)a, *y = (const uint64_t *)(const void *)b;
    static const char *names[] = {"vertices",
                                  "triangles",
                                  "edges",
                                  "border_edges",
                                  "hole_edges",
                                  "hole_loops",
                                  "nonmanifold_edges",
                                  "misoriented_edges",
                                  "nonmanifold_vertices",
                                  "degenerate_triangles",
                                  "components",
                                  "euler"};
    for (int i = 0; i < 12; i++)
        if (x[i] != y[i])
            fprintf(stderr, "  %s: stream %lld, in memory %lld\n", names[i], (long long)x[i],
                    (long long)y[i]);
    return 0;
}

/* ------------------------------------------------------------ volumes */

enum { SPHERE, GYROID, NOISE, RANDOM_VALUES, SHAPES };
static const char *shape_names[SHAPES] = {"sphere", "gyroid", "noise", "random"};

/* A float volume of `shape` on n samples, values about [0, 1], iso 0.5. */
static float *make_field(int shape, const int64_t n[3])
{
    const size_t count = (size_t)(n[0] * n[1] * n[2]);
    float *f = malloc(sizeof(float) * count);
    if (!f)
        abort();
    for (int64_t k = 0; k < n[2]; k++)
        for (int64_t j = 0; j < n[1]; j++)
            for (int64_t i = 0; i < n[0]; i++) {
                const double x = (double)i / (double)n[0], y = (double)j / (double)n[1],
                             z = (double)k / (double)n[2];
                double v;
                switch (shape) {
                case SPHERE:
                    v = 1.0 - 2.0 * sqrt((x - 0.5) * (x - 0.5) + (y - 0.45) * (y - 0.45) +
                                         (z - 0.55) * (z - 0.55));
                    break;
                case GYROID: {
                    const double s = 2 * 3.14159265358979 * 1.7;
                    v = 0.5 + 0.3 * (sin(s * x) * cos(s * y) + sin(s * y) * cos(s * z) +
                                     sin(s * z) * cos(s * x));
                    break;
                }
                case NOISE: v = (double)(rng() % 1000) / 999.0; break;
                default: v = (double)(rng() % 3) * 0.25 + 0.25; break; /* ties at 0.5 */
                }
                f[(k * n[1] + j) * n[0] + i] = (float)v;
            }
    return f;
}

/* Uneven gaps, jitter in x and a 15 degree shear along y (as test_stream). */
static double *shear_slices(isomend_volume *vol)
{
    const int64_t nz = vol->dims[2];
    double *so = malloc(sizeof(double) * 3 * (size_t)nz);
    if (!so)
        abort();
    double z = vol->origin[2];
    for (int64_t k = 0; k < nz; k++) {
        if (k > 0)
            z += (0.4 + 2.2 * (double)(rng() % 1000) / 1000.0) * vol->spacing[2];
        so[3 * k] =
            vol->origin[0] + ((double)(rng() % 1000) / 1000.0 - 0.5) * 0.6 * vol->spacing[0];
        so[3 * k + 1] = vol->origin[1] + 0.2679491924 * (z - vol->origin[2]);
        so[3 * k + 2] = z;
    }
    vol->slice_origins = so;
    return so;
}

/* ------------------------------------------------------------ feeding */

/* Streams vol through a check (its sink); the report into *rep, the peak
 * bytes into *peak. */
static isomend_status stream_check(const isomend_volume *vol, const isomend_options *o,
                                   isomend_check_report *rep, uint64_t *peak)
{
    isomend_check_stream *c = NULL;
    isomend_status st = isomend_check_stream_begin_volume(vol, o, &c);
    if (st != ISOMEND_OK)
        return st;
    isomend_mesh_sink sink;
    st = isomend_check_stream_sink(c, &sink);
    isomend_stream *s = NULL;
    if (st == ISOMEND_OK)
        st = isomend_stream_begin(vol, o, &sink, &s);
    const size_t plane = (size_t)(vol->dims[0] * vol->dims[1]) * sizeof(float);
    for (int64_t z = 0; st == ISOMEND_OK && z < vol->dims[2]; z++)
        st = isomend_stream_push(s, (const char *)vol->data + (size_t)z * plane);
    if (st == ISOMEND_OK)
        st = isomend_stream_finish(s, NULL);
    isomend_stream_destroy(s);
    const isomend_status cs = isomend_check_stream_finish(c, rep);
    if (peak)
        *peak = isomend_check_stream_peak_bytes(c);
    isomend_check_stream_destroy(c);
    return st != ISOMEND_OK ? st : cs;
}

/*
 * Feeds an in-memory mesh to a check (ids from `offset`) in random batches
 * of up to batch_max triangles, each after the vertices it needs (in random
 * chunks), each followed by a retire at most the lowest id a later triangle
 * uses (sometimes lower, sometimes a few single steps).
 */
static isomend_status feed_mesh(isomend_check_stream *c, const float *pos, size_t nv,
                                const uint32_t *tri, size_t nt, uint64_t offset, size_t batch_max,
                                isomend_check_report *rep)
{
    uint32_t *sufmin = malloc(sizeof(uint32_t) * (nt + 1));
    uint64_t *ids = malloc(sizeof(uint64_t) * 3 * (batch_max + 1));
    if (!sufmin || !ids)
        abort();
    sufmin[nt] = (uint32_t)nv;
    for (size_t t = nt; t-- > 0;) {
        uint32_t m = sufmin[t + 1];
        for (int k = 0; k < 3; k++)
            m = tri[3 * t + k] < m ? tri[3 * t + k] : m;
        sufmin[t] = m;
    }
    isomend_status st = ISOMEND_OK;
    size_t delivered = 0;
    uint64_t floor = offset;
    for (size_t t = 0; st == ISOMEND_OK && t < nt;) {
        const size_t n = 1 + rng() % batch_max, end = t + n < nt ? t + n : nt;
        size_t need = delivered;
        for (size_t q = 3 * t; q < 3 * end; q++)
            need = tri[q] + (size_t)1 > need ? tri[q] + (size_t)1 : need;
        while (st == ISOMEND_OK && delivered < need) {
            size_t chunk = 1 + rng() % (need - delivered + 8);
            chunk = chunk < need - delivered ? chunk : need - delivered;
            st = isomend_check_stream_vertices(c, offset + delivered, chunk, pos + 3 * delivered);
            delivered += chunk;
        }
        for (size_t q = 3 * t; q < 3 * end; q++)
            ids[q - 3 * t] = offset + tri[q];
        if (st == ISOMEND_OK)
            st = isomend_check_stream_triangles(c, end - t, ids);
        t = end;
        uint64_t f = offset + (sufmin[t] < delivered ? sufmin[t] : delivered);
        if (rng() % 4 == 0 && f > floor) /* lower than it could be */
            f = floor + rng() % (f - floor);
        for (int step = 0; st == ISOMEND_OK && step < 3 && floor < f && rng() % 3 == 0; step++)
            st = isomend_check_stream_retire(c, ++floor); /* one at a time */
        if (st == ISOMEND_OK && f >= floor) {
            st = isomend_check_stream_retire(c, f);
            floor = f;
        }
    }
    if (st == ISOMEND_OK && delivered < nv) /* unused vertices at the end */
        st = isomend_check_stream_vertices(c, offset + delivered, nv - delivered,
                                           pos + 3 * delivered);
    free(sufmin);
    free(ids);
    const isomend_status fs = isomend_check_stream_finish(c, rep);
    return st != ISOMEND_OK ? st : fs;
}

/* Feeds a mesh with box `box` and compares with isomend_check(). */
static void compare_fed(const float *pos, size_t nv, const uint32_t *tri, size_t nt,
                        const double box[6], size_t batch_max, const char *what, int *counter)
{
    isomend_check_report want, got;
    CHECK_EQ_INT(isomend_check(pos, nv, tri, nt, box, &want), ISOMEND_OK);
    isomend_check_stream *c = NULL;
    CHECK_EQ_INT(isomend_check_stream_begin(box, &c), ISOMEND_OK);
    const uint64_t offset = rng() % 2 ? 0 : ((uint64_t)1 << 32) + rng() % 1000;
    const isomend_status st = feed_mesh(c, pos, nv, tri, nt, offset, batch_max, &got);
    CHECK_EQ_INT(st, ISOMEND_OK);
    isomend_check_stream_destroy(c);
    if (st == ISOMEND_OK)
        CHECK(same_report(&got, &want, what));
    (*counter)++;
}

/* ------------------------------------------------------------ volumes */

static void test_volumes(void)
{
    for (int shape = 0; shape < SHAPES; shape++)
        for (int rep = 0; rep < 4; rep++) {
            int64_t n[3];
            for (int a = 0; a < 3; a++)
                n[a] = 3 + (int64_t)(rng() % 22);
            if (rep == 0 && shape == GYROID) {
                n[0] = n[1] = 48;
                n[2] = 40;
            }
            float *data = make_field(shape, n);
            isomend_volume vol;
            isomend_volume_init(&vol, data, ISOMEND_F32, n[0], n[1], n[2]);
            vol.spacing[0] = 0.5;
            vol.spacing[2] = 1.25;
            vol.origin[1] = -3.0;
            vol.origin[2] = 7.5;
            double *so = rep % 2 ? shear_slices(&vol) : NULL;
            for (int m = 0; m < ISOMEND_METHOD_COUNT; m++) {
                if (!isomend_method_available((isomend_method)m))
                    continue;
                for (int pad = 0; pad < 2; pad++) {
                    isomend_options o;
                    isomend_options_init(&o);
                    o.iso = 0.5;
                    o.method = (isomend_method)m;
                    o.flags = ISOMEND_FLAG_NO_NORMALS | (pad ? ISOMEND_FLAG_PAD : 0u) |
                              (rng() % 2 ? ISOMEND_FLAG_FLIP : 0u);
                    o.threads = 1;
                    char what[160];
                    snprintf(what, sizeof what, "%s %lldx%lldx%lld%s %s flags %u",
                             shape_names[shape], (long long)n[0], (long long)n[1], (long long)n[2],
                             so ? " sheared" : "", isomend_method_name(o.method), o.flags);
                    isomend_mesh *mesh = NULL;
                    CHECK_EQ_INT(isomend_extract(&vol, &o, &mesh, NULL), ISOMEND_OK);
                    isomend_check_report want, got;
                    CHECK_EQ_INT(isomend_mesh_check(mesh, &want), ISOMEND_OK);
                    CHECK_EQ_INT(stream_check(&vol, &o, &got, NULL), ISOMEND_OK);
                    CHECK(same_report(&got, &want, what));
                    compared_streams++;
                    if (so) {
                        double box[6];
                        isomend_check_report plain;
                        isomend_mesh_grid_box(mesh, box);
                        CHECK_EQ_INT(isomend_check(isomend_mesh_positions(mesh),
                                                   isomend_mesh_vertex_count(mesh),
                                                   isomend_mesh_triangles(mesh),
                                                   isomend_mesh_triangle_count(mesh), box, &plain),
                                     ISOMEND_OK);
                        sheared_frame_matters += memcmp(&plain, &want, sizeof plain) != 0;
                    } else { /* the same mesh from memory, in random batches */
                        double box[6];
                        isomend_mesh_grid_box(mesh, box);
                        compare_fed(isomend_mesh_positions(mesh), isomend_mesh_vertex_count(mesh),
                                    isomend_mesh_triangles(mesh), isomend_mesh_triangle_count(mesh),
                                    box, 1 + rng() % 300, what, &compared_fed);
                    }
                    isomend_mesh_destroy(mesh);
                }
            }
            free(so);
            free(data);
        }
}

/* ------------------------------------------------------------ hand-made */

/* A closed tetrahedron on vertices v0..v3 (outward), into t. */
static size_t tetra(uint32_t *t, uint32_t v0)
{
    static const uint32_t f[12] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};
    for (int i = 0; i < 12; i++)
        t[i] = v0 + f[i];
    return 4;
}

static void test_hand_made(void)
{
    const double box[6] = {-10, -10, -10, 10, 10, 10};
    static const float tet[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    float pos[300];
    uint32_t tri[300];
    isomend_check_report want;

    /* Two tetrahedra sharing one vertex: a non-manifold vertex, 2 components. */
    memcpy(pos, tet, sizeof tet);
    for (int i = 0; i < 12; i++)
        pos[12 + i] = -tet[i];
    size_t nt = tetra(tri, 0);
    nt += tetra(tri + 3 * nt, 3);
    CHECK_EQ_INT(isomend_check(pos, 7, tri, nt, box, &want), ISOMEND_OK);
    CHECK_EQ_INT(want.nonmanifold_vertices, 1);
    CHECK_EQ_INT(want.components, 2);
    compare_fed(pos, 7, tri, nt, box, 1, "two tetrahedra at a vertex", &compared_hand);
    compare_fed(pos, 7, tri, nt, box, 8, "two tetrahedra at a vertex", &compared_hand);

    /* A tetrahedron with one face flipped: 3 misoriented edges. */
    nt = tetra(tri, 0);
    const uint32_t x = tri[1];
    tri[1] = tri[2];
    tri[2] = x;
    CHECK_EQ_INT(isomend_check(tet, 4, tri, nt, box, &want), ISOMEND_OK);
    CHECK_EQ_INT(want.misoriented_edges, 3);
    compare_fed(tet, 4, tri, nt, box, 2, "flipped face", &compared_hand);

    /* Degenerate triangles: a repeated index, three repeated, collinear. */
    static const float line[12] = {0, 0, 0, 1, 1, 1, 2, 2, 2, 3, 0, 1};
    const uint32_t deg[] = {0, 0, 3, 1, 1, 1, 0, 1, 2, 0, 3, 1, 3, 2, 2};
    CHECK_EQ_INT(isomend_check(line, 4, deg, 5, box, &want), ISOMEND_OK);
    CHECK_EQ_INT(want.degenerate_triangles, 4);
    compare_fed(line, 4, deg, 5, box, 1, "degenerate", &compared_hand);
    compare_fed(line, 4, deg, 5, box, 5, "degenerate", &compared_hand);

    /* Three open quads (two triangles each), apart: 3 hole loops, 3
     * components; one lies in the box's face (border edges). */
    size_t nv = 0;
    nt = 0;
    for (int q = 0; q < 3; q++) {
        const float z = q == 2 ? 10.0f : (float)q;
        const float quad[12] = {0, 0, z, 1, 0, z, 1, 1, z, 0, 1, z};
        memcpy(pos + 3 * nv, quad, sizeof quad);
        const uint32_t qt[6] = {0, 1, 2, 0, 2, 3};
        for (int i = 0; i < 6; i++)
            tri[3 * nt + i] = (uint32_t)nv + qt[i];
        nv += 4;
        nt += 2;
    }
    CHECK_EQ_INT(isomend_check(pos, nv, tri, nt, box, &want), ISOMEND_OK);
    CHECK_EQ_INT(want.hole_loops, 2);
    CHECK_EQ_INT(want.border_edges, 4);
    CHECK_EQ_INT(want.components, 3);
    compare_fed(pos, nv, tri, nt, box, 1, "open quads", &compared_hand);
    compare_fed(pos, nv, tri, nt, box, 3, "open quads", &compared_hand);

    /* Three triangles on one edge (a book): a non-manifold edge. */
    static const float book[15] = {0, 0, 0, 0, 0, 1, 1, 0, 0, 0, 1, 0, -1, -1, 0};
    const uint32_t bt[9] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    CHECK_EQ_INT(isomend_check(book, 5, bt, 3, box, &want), ISOMEND_OK);
    CHECK_EQ_INT(want.nonmanifold_edges, 1);
    compare_fed(book, 5, bt, 3, box, 1, "book", &compared_hand);

    /* Two cones of 150 triangles on one apex (ids 0 and 1: the apex in the
     * middle of the ids, one cone flipped): the apex's table is hashed, its
     * fan in 2 pieces; then one open cone alone. */
    {
        enum { RIM = 150 };
        float cone[3 * (2 * RIM + 1)];
        uint32_t ct[3 * 2 * RIM];
        size_t cv = 0, cn = 0;
        for (int c = 0; c < 2; c++)
            for (int i = 0; i < RIM; i++) {
                const double a = 2.0 * 3.14159265358979 * i / RIM;
                cone[3 * cv] = (float)(3.0 * cos(a));
                cone[3 * cv + 1] = (float)(3.0 * sin(a));
                cone[3 * cv + 2] = c ? 2.0f : -2.0f;
                cv++;
                if (c == 0 && i == RIM / 2) { /* the apex */
                    cone[3 * cv] = cone[3 * cv + 1] = cone[3 * cv + 2] = 0.0f;
                    cv++;
                }
            }
        const uint32_t apex = RIM / 2 + 1;
        for (int c = 0; c < 2; c++)
            for (uint32_t i = 0; i < RIM; i++) {
                uint32_t r0 = (uint32_t)c * RIM + i, r1 = (uint32_t)c * RIM + (i + 1) % RIM;
                r0 += r0 >= apex;
                r1 += r1 >= apex;
                ct[3 * cn] = apex;
                ct[3 * cn + 1] = c ? r1 : r0;
                ct[3 * cn + 2] = c ? r0 : r1;
                cn++;
            }
        CHECK_EQ_INT(isomend_check(cone, cv, ct, cn, box, &want), ISOMEND_OK);
        CHECK_EQ_INT(want.nonmanifold_vertices, 1);
        CHECK_EQ_INT(want.hole_loops, 2);
        compare_fed(cone, cv, ct, cn, box, 7, "two cones on one apex", &compared_hand);
        compare_fed(cone, cv, ct, cn, box, 300, "two cones on one apex", &compared_hand);
        compare_fed(cone, cv, ct, RIM, box, 40, "one cone", &compared_hand);
    }

    /* No triangles; vertices only. */
    compare_fed(tet, 4, tri, 0, box, 1, "no triangles", &compared_hand);
}

/* Random soups: a sliding window of ids, positions on a 5^3 grid in the
 * box [0, 4]^3 (collinear and coincident points, border edges), repeated
 * indices, repeated and reversed triangles. */
static void test_soups(void)
{
    const double box[6] = {0, 0, 0, 4, 4, 4};
    for (int rep = 0; rep < 300; rep++) {
        const size_t nv = 3 + rng() % 400, nt = rng() % 600;
        const uint32_t window = 3 + rng() % 30;
        float *pos = malloc(sizeof(float) * 3 * nv);
        uint32_t *tri = malloc(sizeof(uint32_t) * 3 * (nt + 1));
        if (!pos || !tri)
            abort();
        for (size_t i = 0; i < 3 * nv; i++)
            pos[i] = (float)(rng() % 5) * (rng() % 8 ? 1.0f : 0.999f);
        for (size_t t = 0; t < nt; t++) {
            const size_t base = t * (nv - 1) / (nt ? nt : 1);
            for (int k = 0; k < 3; k++) {
                size_t v = base + rng() % window;
                tri[3 * t + k] = (uint32_t)(v < nv ? v : nv - 1);
            }
            if (t && rng() % 5 == 0) { /* the previous triangle again, maybe reversed */
                tri[3 * t] = tri[3 * t - 3];
                tri[3 * t + 1] = tri[3 * t - (rng() % 2 ? 2 : 1)];
                tri[3 * t + 2] = tri[3 * t - (tri[3 * t + 1] == tri[3 * t - 2] ? 1 : 2)];
            }
        }
        char what[64];
        snprintf(what, sizeof what, "soup %d (%zu vertices, %zu triangles)", rep, nv, nt);
        compare_fed(pos, nv, tri, nt, box, 1 + rng() % 40, what, &compared_soups);
        free(pos);
        free(tri);
    }
}

/* ------------------------------------------------------------ bad input */

static void test_bad_input(void)
{
    const double box[6] = {0, 0, 0, 1, 1, 1};
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    isomend_check_stream *c = NULL;
    isomend_check_report r;
    CHECK_EQ_INT(isomend_check_stream_begin(NULL, &c), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(c == NULL);
    CHECK_EQ_INT(isomend_check_stream_begin(box, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_check_stream_begin_volume(NULL, NULL, &c), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_volume bad;
    isomend_volume_init(&bad, NULL, ISOMEND_F32, 1, 4, 4);
    CHECK_EQ_INT(isomend_check_stream_begin_volume(&bad, NULL, &c), ISOMEND_ERR_BAD_DIMENSIONS);
    CHECK(c == NULL);
    CHECK_EQ_INT(isomend_check_stream_vertices(NULL, 0, 0, p), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_check_stream_triangles(NULL, 0, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_check_stream_retire(NULL, 0), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_check_stream_finish(NULL, &r), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_check_stream_peak_bytes(NULL), 0);
    isomend_check_stream_destroy(NULL);

    /* Each defect on a fresh check; the status then sticks. */
    for (int defect = 0; defect < 10; defect++) {
        CHECK_EQ_INT(isomend_check_stream_begin(box, &c), ISOMEND_OK);
        uint64_t t[3] = {5, 6, 7};
        isomend_status st = isomend_check_stream_vertices(c, 5, 3, p);
        CHECK_EQ_INT(st, ISOMEND_OK);
        switch (defect) {
        case 0: st = isomend_check_stream_vertices(c, 9, 1, p); break; /* a gap */
        case 1: st = isomend_check_stream_vertices(c, 7, 1, p); break; /* overlap */
        case 2:
            t[2] = 8;
            st = isomend_check_stream_triangles(c, 1, t);
            break; /* undelivered */
        case 3:
            t[0] = 4;
            st = isomend_check_stream_triangles(c, 1, t);
            break; /* never there */
        case 4:
            (void)isomend_check_stream_retire(c, 6);
            st = isomend_check_stream_triangles(c, 1, t); /* 5 retired */
            break;
        case 5: st = isomend_check_stream_retire(c, 9); break; /* beyond delivered */
        case 6:
            (void)isomend_check_stream_retire(c, 7);
            st = isomend_check_stream_retire(c, 6); /* backwards */
            break;
        case 7:
            t[1] = ISOMEND_FOREIGN | 6;
            st = isomend_check_stream_triangles(c, 1, t);
            break;
        case 8: st = isomend_check_stream_vertices(c, 8, 2, NULL); break;
        default:
            CHECK_EQ_INT(isomend_check_stream_finish(c, &r), ISOMEND_OK);
            st = isomend_check_stream_finish(c, &r); /* twice */
            break;
        }
        CHECK_EQ_INT(st, ISOMEND_ERR_INVALID_ARGUMENT);
        t[0] = 5, t[1] = 6, t[2] = 7;
        CHECK_EQ_INT(isomend_check_stream_triangles(c, 1, t), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_check_stream_finish(c, &r), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(r.triangles, 0);
        isomend_check_stream_destroy(c);
    }

    /* A first call after a retire must start at or above its floor. */
    CHECK_EQ_INT(isomend_check_stream_begin(box, &c), ISOMEND_OK);
    CHECK_EQ_INT(isomend_check_stream_retire(c, 10), ISOMEND_OK);
    CHECK_EQ_INT(isomend_check_stream_vertices(c, 9, 3, p), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_check_stream_destroy(c);
    CHECK_EQ_INT(isomend_check_stream_begin(box, &c), ISOMEND_OK);
    CHECK_EQ_INT(isomend_check_stream_retire(c, 10), ISOMEND_OK);
    CHECK_EQ_INT(isomend_check_stream_vertices(c, 10, 3, p), ISOMEND_OK);
    const uint64_t t[3] = {10, 11, 12};
    CHECK_EQ_INT(isomend_check_stream_triangles(c, 1, t), ISOMEND_OK);
    CHECK_EQ_INT(isomend_check_stream_finish(c, &r), ISOMEND_OK);
    CHECK_EQ_INT(r.triangles, 1);
    CHECK_EQ_INT(r.border_edges, 3); /* the triangle lies in the face z = 0 */
    isomend_check_stream_destroy(c);

    /* A check that fails stops the stream feeding it: ISOMEND_ERR_SINK. */
    static float vol_data[4 * 4 * 4];
    for (int i = 0; i < 64; i++)
        vol_data[i] = (float)(i % 3);
    isomend_volume vol;
    isomend_volume_init(&vol, vol_data, ISOMEND_F32, 4, 4, 4);
    CHECK_EQ_INT(isomend_check_stream_begin(box, &c), ISOMEND_OK);
    CHECK_EQ_INT(isomend_check_stream_vertices(c, 0, 1, p), ISOMEND_OK); /* ids taken */
    isomend_mesh_sink sink;
    CHECK_EQ_INT(isomend_check_stream_sink(c, &sink), ISOMEND_OK);
    CHECK_EQ_INT(isomend_check_stream_sink(NULL, &sink), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_stream *s = NULL;
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 0.5;
    CHECK_EQ_INT(isomend_stream_begin(&vol, &o, &sink, &s), ISOMEND_OK);
    isomend_status st = ISOMEND_OK;
    for (int z = 0; z < 4 && st == ISOMEND_OK; z++)
        st = isomend_stream_push(s, vol_data + 16 * z);
    if (st == ISOMEND_OK)
        st = isomend_stream_finish(s, NULL);
    CHECK_EQ_INT(st, ISOMEND_ERR_SINK);
    isomend_stream_destroy(s);
    CHECK_EQ_INT(isomend_check_stream_finish(c, &r), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_check_stream_destroy(c);
}

/* ------------------------------------------------------------ memory */

static void test_memory(void)
{
    uint64_t peak[2] = {0, 0};
    size_t nv = 0, nt = 0;
    for (int run = 0; run < 2; run++) {
        const int64_t n[3] = {64, 64, run ? 256 : 32};
        float *data = make_field(GYROID, (const int64_t[3]){64, 64, 32});
        float *tall = malloc(sizeof(float) * (size_t)(n[0] * n[1] * n[2]));
        if (!tall)
            abort();
        for (int64_t k = 0; k < n[2]; k++) /* the same 32 slices, repeated */
            memcpy(tall + k * 64 * 64, data + (k % 32) * 64 * 64, sizeof(float) * 64 * 64);
        free(data);
        isomend_volume vol;
        isomend_volume_init(&vol, tall, ISOMEND_F32, n[0], n[1], n[2]);
        isomend_options o;
        isomend_options_init(&o);
        o.iso = 0.5;
        o.flags = ISOMEND_FLAG_PAD | ISOMEND_FLAG_NO_NORMALS;
        isomend_mesh *mesh = NULL;
        CHECK_EQ_INT(isomend_extract(&vol, &o, &mesh, NULL), ISOMEND_OK);
        isomend_check_report want, got;
        CHECK_EQ_INT(isomend_mesh_check(mesh, &want), ISOMEND_OK);
        CHECK_EQ_INT(stream_check(&vol, &o, &got, &peak[run]), ISOMEND_OK);
        CHECK(same_report(&got, &want, "memory"));
        compared_streams++;
        nv = isomend_mesh_vertex_count(mesh);
        nt = isomend_mesh_triangle_count(mesh);
        isomend_mesh_destroy(mesh);
        free(tall);
    }
    const uint64_t whole = isomend_check_memory(nv, nt);
    printf("peak memory of the streaming check on a 64x64 gyroid: %llu bytes at 32 slices, "
           "%llu at 256 (%zu triangles; isomend_check: %llu bytes)\n",
           (unsigned long long)peak[0], (unsigned long long)peak[1], nt, (unsigned long long)whole);
    CHECK(peak[0] > 0);
    CHECK(peak[1] <= 2 * peak[0]);
    CHECK(peak[1] * 8 < whole);
}

/* ------------------------------------------------------------ speed */

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* The padded surface of a gyroid of n samples (*data: its samples, to free). */
static isomend_mesh *gyroid_mesh(const int64_t n[3], float **data)
{
    *data = make_field(GYROID, n);
    isomend_volume vol;
    isomend_volume_init(&vol, *data, ISOMEND_F32, n[0], n[1], n[2]);
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 0.5;
    o.flags = ISOMEND_FLAG_PAD | ISOMEND_FLAG_NO_NORMALS;
    isomend_mesh *mesh = NULL;
    CHECK_EQ_INT(isomend_extract(&vol, &o, &mesh, NULL), ISOMEND_OK);
    return mesh;
}

/* Both checks on an n^3 gyroid's mesh; the streaming one fed as a stream
 * feeds it (a layer's triangles, then retire), from memory. */
static void bench(int64_t size)
{
    const int64_t n[3] = {size, size, size};
    float *data;
    isomend_mesh *mesh = gyroid_mesh(n, &data);
    const size_t nv = isomend_mesh_vertex_count(mesh), nt = isomend_mesh_triangle_count(mesh);
    const float *pos = isomend_mesh_positions(mesh);
    const uint32_t *tri = isomend_mesh_triangles(mesh);
    /* layers: triangle t's layer ends where the lowest id a later one uses
     * passes a new slice; approximated by batches of nt / N triangles */
    uint64_t *ids = malloc(sizeof(uint64_t) * 3 * nt);
    uint32_t *sufmin = malloc(sizeof(uint32_t) * (nt + 1));
    if (!ids || !sufmin)
        abort();
    for (size_t q = 0; q < 3 * nt; q++)
        ids[q] = tri[q];
    sufmin[nt] = (uint32_t)nv;
    for (size_t t = nt; t-- > 0;) {
        uint32_t m = sufmin[t + 1];
        for (int k = 0; k < 3; k++)
            m = tri[3 * t + k] < m ? tri[3 * t + k] : m;
        sufmin[t] = m;
    }
    for (int round = 0; round < 3; round++) {
        isomend_check_report want, got;
        double t0 = now();
        CHECK_EQ_INT(isomend_mesh_check(mesh, &want), ISOMEND_OK);
        const double t_mem = now() - t0;
        t0 = now();
        isomend_check_stream *c = NULL;
        double box[6];
        isomend_mesh_grid_box(mesh, box);
        CHECK_EQ_INT(isomend_check_stream_begin(box, &c), ISOMEND_OK);
        const size_t batch = nt / (size_t)(size + 1) + 1;
        size_t delivered = 0;
        for (size_t t = 0; t < nt; t += batch) {
            const size_t end = t + batch < nt ? t + batch : nt;
            size_t need = delivered;
            for (size_t q = 3 * t; q < 3 * end; q++)
                need = tri[q] + (size_t)1 > need ? tri[q] + (size_t)1 : need;
            CHECK_EQ_INT(
                isomend_check_stream_vertices(c, delivered, need - delivered, pos + 3 * delivered),
                ISOMEND_OK);
            delivered = need;
            CHECK_EQ_INT(isomend_check_stream_triangles(c, end - t, ids + 3 * t), ISOMEND_OK);
            const uint64_t f = sufmin[end] < delivered ? sufmin[end] : delivered;
            CHECK_EQ_INT(isomend_check_stream_retire(c, f), ISOMEND_OK);
        }
        CHECK_EQ_INT(isomend_check_stream_finish(c, &got), ISOMEND_OK);
        const double t_stream = now() - t0;
        CHECK(same_report(&got, &want, "bench"));
        printf("%lld^3 gyroid, %zu triangles: isomend_mesh_check %.3f s (%.1f M triangles/s, "
               "at most %llu bytes; sorted: %llu), streaming %.3f s (%.1f M triangles/s, peak "
               "%llu bytes)\n",
               (long long)size, nt, t_mem, (double)nt / t_mem * 1e-6,
               (unsigned long long)isomend_mesh_check_memory(mesh),
               (unsigned long long)isomend_check_memory(nv, nt), t_stream,
               (double)nt / t_stream * 1e-6,
               (unsigned long long)isomend_check_stream_peak_bytes(c));
        isomend_check_stream_destroy(c);
    }
    free(ids);
    free(sufmin);
    isomend_mesh_destroy(mesh);
    free(data);
}

/* ------------------------------------------------------------ the route */

/* isomend_check() takes the streaming checker in the mesh's order
 * (check_in_order) when the order is a sweep: the same report as the
 * sorted check, on extracted meshes (taken) and on the same meshes shuffled
 * (triangles permuted, each one's corners rotated, vertices renumbered:
 * taken below 65 536 vertices with the whole mesh live, refused above a
 * quarter of a larger mesh's vertices). */
static void test_route(void)
{
    int taken = 0, shuffled = 0, refused = 0;
    for (int size = 0; size < 3; size++) {
        const int64_t side = size == 0 ? 24 : size == 1 ? 56 : 120;
        const int64_t n[3] = {side, side + 3, side - 2};
        float *data;
        isomend_mesh *mesh = gyroid_mesh(n, &data);
        const float *pos = isomend_mesh_positions(mesh);
        const uint32_t *tri = isomend_mesh_triangles(mesh);
        const size_t nv = isomend_mesh_vertex_count(mesh), nt = isomend_mesh_triangle_count(mesh);
        isomend_check_report sorted, in_order, routed;
        CHECK_EQ_INT(check_sorted(pos, nv, tri, nt, NULL, &sorted), ISOMEND_OK);
        CHECK_EQ_INT(check_in_order(pos, nv, tri, nt, NULL, &in_order), ISOMEND_OK);
        CHECK_EQ_INT(isomend_check(pos, nv, tri, nt, NULL, &routed), ISOMEND_OK);
        CHECK(same_report(&in_order, &sorted, "in order"));
        { /* the memory it says it needs bounds what a stream fed in batches holds */
            double box[6];
            isomend_mesh_grid_box(mesh, box);
            isomend_check_stream *c = NULL;
            isomend_check_report fed;
            CHECK_EQ_INT(isomend_check_stream_begin(box, &c), ISOMEND_OK);
            CHECK_EQ_INT(feed_mesh(c, pos, nv, tri, nt, 0, 2048, &fed), ISOMEND_OK);
            const uint64_t peak = isomend_check_stream_peak_bytes(c) + 4 * (uint64_t)nv;
            const uint64_t said = isomend_mesh_check_memory(mesh);
            printf("route: %zu vertices, check memory %llu bytes said, %llu held fed in batches, "
                   "%llu sorted\n", nv, (unsigned long long)said, (unsigned long long)peak,
                   (unsigned long long)isomend_check_memory(nv, nt));
            CHECK(said >= peak);
            if (nv > 100000) /* beyond the checker's fixed chunks: a fraction of sorting's */
                CHECK(said < isomend_check_memory(nv, nt) / 2);
            isomend_check_stream_destroy(c);
        }
        CHECK(same_report(&routed, &sorted, "routed"));
        CHECK(sorted.triangles == nt && sorted.hole_edges == 0 && sorted.components > 0);
        taken++;

        /* shuffled */
        uint32_t *perm = malloc(sizeof(uint32_t) * nv), *order = malloc(sizeof(uint32_t) * nt);
        uint32_t *st = malloc(sizeof(uint32_t) * 3 * nt);
        float *sp = malloc(sizeof(float) * 3 * nv);
        if (!perm || !order || !st || !sp)
            abort();
        for (size_t i = 0; i < nv; i++)
            perm[i] = (uint32_t)i;
        for (size_t i = 0; i < nt; i++)
            order[i] = (uint32_t)i;
        for (size_t i = nv; i > 1; i--) {
            const size_t j = rng() % i;
            const uint32_t x = perm[i - 1];
            perm[i - 1] = perm[j];
            perm[j] = x;
        }
        for (size_t i = nt; i > 1; i--) {
            const size_t j = ((size_t)rng() << 16 ^ rng()) % i;
            const uint32_t x = order[i - 1];
            order[i - 1] = order[j];
            order[j] = x;
        }
        for (size_t v = 0; v < nv; v++)
            memcpy(sp + 3 * (size_t)perm[v], pos + 3 * v, sizeof(float) * 3);
        for (size_t t = 0; t < nt; t++) {
            const uint32_t *a = tri + 3 * (size_t)order[t];
            const int r = (int)(rng() % 3);
            for (int k = 0; k < 3; k++)
                st[3 * t + (size_t)k] = perm[a[(k + r) % 3]];
        }
        isomend_check_report s_sorted, s_in_order, s_routed;
        CHECK_EQ_INT(check_sorted(sp, nv, st, nt, NULL, &s_sorted), ISOMEND_OK);
        CHECK_EQ_INT(isomend_check(sp, nv, st, nt, NULL, &s_routed), ISOMEND_OK);
        CHECK(same_report(&s_sorted, &sorted, "shuffled, sorted"));
        CHECK(same_report(&s_routed, &sorted, "shuffled, routed"));
        const isomend_status st_order = check_in_order(sp, nv, st, nt, NULL, &s_in_order);
        if (nv <= 65536) {
            CHECK_EQ_INT(st_order, ISOMEND_OK);
            if (st_order == ISOMEND_OK)
                CHECK(same_report(&s_in_order, &sorted, "shuffled, in order"));
            shuffled++;
        } else {
            CHECK_EQ_INT(st_order, ISOMEND_ERR_UNSUPPORTED);
            refused++;
        }
        free(perm);
        free(order);
        free(st);
        free(sp);
        isomend_mesh_destroy(mesh);
        free(data);
    }
    printf("route: %d extracted meshes checked in their order, %d shuffled ones too, %d "
           "shuffled ones sorted\n", taken, shuffled, refused);
    CHECK(taken == 3 && shuffled >= 1 && refused >= 1);
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--bench") == 0) {
        bench(argc > 2 ? atoll(argv[2]) : 256);
        TEST_EXIT();
    }
    test_route();
    check_set_test_sorted(1); /* the reference below: the sorted check */
    test_bad_input();
    test_hand_made();
    test_soups();
    test_volumes();
    test_memory();
    printf("reports equal: %d streams against isomend_mesh_check, %d meshes fed in random "
           "batches, %d hand-made meshes, %d soups against isomend_check\n",
           compared_streams, compared_fed, compared_hand, compared_soups);
    printf("cases with border edges %d, hole edges %d, 2+ hole loops %d, non-manifold edges %d, "
           "misoriented edges %d, non-manifold vertices %d, degenerate triangles %d, 2+ "
           "components %d\n",
           seen_border, seen_hole, seen_loops2, seen_nm_edge, seen_mis, seen_nm_vertex,
           seen_degenerate, seen_components2);
    printf("%d sheared meshes whose report in the sheared frame differs\n", sheared_frame_matters);
    CHECK(sheared_frame_matters > 0);
    CHECK(seen_border > 0 && seen_hole > 0 && seen_loops2 > 0 && seen_nm_edge > 0 && seen_mis > 0 &&
          seen_nm_vertex > 0 && seen_degenerate > 0 && seen_components2 > 0);
    TEST_EXIT();
}
