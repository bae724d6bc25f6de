/*
 * Post-processing that keeps the promise (isomend_mesh_decimate, _smooth,
 * _clean): on padded surfaces of a sphere, a gyroid (genus), random noise
 * (hundreds of components, every ambiguous case) and the thesis's F1/F2, for
 * the hole-free methods:
 *   - every decimated mesh is a closed, oriented 2-manifold (no hole,
 *     non-manifold or misoriented edge, no non-manifold vertex), with the
 *     input's components and Euler characteristic; the target is reached
 *     where the report says so and the triangle count is the target's;
 *     max_error bounds the reported error; the same bytes twice and from a
 *     mesh extracted on 1 or 2 threads;
 *   - unpadded, the border edges and their vertices are kept exactly;
 *   - smoothing keeps the triangles, moves no locked vertex and keeps the
 *     enclosed volume within 0.5 %;
 *   - clean-up removes exactly the components under the size, or all but
 *     the largest, and the checker counts what the report says;
 *   - a mesh large enough for the decimation's regions on threads (2^16
 *     vertices a region): the same bytes on one core as on all, with and
 *     without a maximum error, and closed.
 */
#define _GNU_SOURCE /* sched_setaffinity */
#include "isomend.h"
#include "testutil.h"
#include "volumes.h"

#include <math.h>
#include <sched.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

enum { SPHERE = SHAPE_SPHERE, GYROID = SHAPE_GYROID, NOISE = SHAPE_NOISE, F1 = SHAPE_F1,
       F2 = SHAPE_F2, SHAPES };
static const char *names[SHAPES] = {"sphere", "gyroid", "noise", "F1", "F2"};
static uint64_t rng_state = 0x9e3779b97f4a7c15ull;

static float *make(int shape, int64_t n[3])
{
    if (shape >= F1)
        n[0] = n[1] = n[2] = 4;
    else if (shape == NOISE)
        n[0] = n[1] = n[2] = 14;
    else
        n[0] = 40, n[1] = 36, n[2] = 33;
    return shape_volume(shape, n, 0.35, &rng_state);
}

static int closed_as(const isomend_check_report *r, const isomend_check_report *in, int padded)
{
    return r->hole_edges == 0 && r->nonmanifold_edges == 0 && r->misoriented_edges == 0 &&
           r->nonmanifold_vertices == 0 && (!padded || r->border_edges == 0) &&
           r->components == in->components && r->euler == in->euler;
}

static int same_bytes(const isomend_mesh *a, const isomend_mesh *b)
{
    const size_t nv = isomend_mesh_vertex_count(a), nt = isomend_mesh_triangle_count(a);
    return nv == isomend_mesh_vertex_count(b) && nt == isomend_mesh_triangle_count(b) &&
           !memcmp(isomend_mesh_positions(a), isomend_mesh_positions(b), 12 * nv) &&
           !memcmp(isomend_mesh_triangles(a), isomend_mesh_triangles(b), 12 * nt) &&
           !memcmp(isomend_mesh_normals(a), isomend_mesh_normals(b), 12 * nv);
}

static int decimated;

static void decimate_and_check(const isomend_mesh *in, const isomend_check_report *rin,
                               int padded, const isomend_decimate_options *o, const char *what)
{
    isomend_mesh *out = NULL, *again = NULL;
    isomend_decimate_report rep;
    CHECK_EQ_INT(isomend_mesh_decimate(in, o, &out, &rep), ISOMEND_OK);
    CHECK_EQ_INT(isomend_mesh_decimate(in, o, &again, NULL), ISOMEND_OK);
    if (!out || !again)
        goto end;
    decimated++;
    CHECK(same_bytes(out, again));
    isomend_check_report r;
    CHECK_EQ_INT(isomend_mesh_check(out, &r), ISOMEND_OK);
    if (!closed_as(&r, rin, padded)) {
        fprintf(stderr,
                "%s: decimated to %llu triangles: %llu hole, %llu non-manifold, %llu misoriented "
                "edges, %llu non-manifold vertices, %llu border edges; components %llu (was %llu), "
                "euler %lld (was %lld)\n",
                what, (unsigned long long)r.triangles, (unsigned long long)r.hole_edges,
                (unsigned long long)r.nonmanifold_edges, (unsigned long long)r.misoriented_edges,
                (unsigned long long)r.nonmanifold_vertices, (unsigned long long)r.border_edges,
                (unsigned long long)r.components, (unsigned long long)rin->components,
                (long long)r.euler, (long long)rin->euler);
        CHECK(0);
    }
    if (!padded)
        CHECK_EQ_INT(r.border_edges, rin->border_edges);
    CHECK_EQ_INT(rep.triangles_after, isomend_mesh_triangle_count(out));
    CHECK_EQ_INT(rep.triangles_before, isomend_mesh_triangle_count(in));
    if (rep.reached && rep.target_triangles)
        CHECK(rep.triangles_after <= rep.target_triangles &&
              rep.triangles_after + 2 > rep.target_triangles);
    if (o->max_error > 0)
        CHECK(rep.max_error <= o->max_error);
    CHECK(rep.triangles_after <= rep.triangles_before);
    /* every output vertex is finite and inside the grid box (with slack) */
    double box[6];
    isomend_mesh_grid_box(out, box);
    const float *p = isomend_mesh_positions(out);
    for (size_t v = 0; v < 3 * isomend_mesh_vertex_count(out); v++)
        CHECK(isfinite(p[v]) && p[v] >= box[v % 3] - 1.0 && p[v] <= box[3 + v % 3] + 1.0);
end:
    isomend_mesh_destroy(out);
    isomend_mesh_destroy(again);
}

/* The border of an unpadded surface: its once-used edges' vertices stay. */
static void border_kept(const isomend_mesh *in, const char *what)
{
    isomend_decimate_options o;
    isomend_decimate_options_init(&o);
    o.ratio = 0.2;
    isomend_mesh *out = NULL;
    CHECK_EQ_INT(isomend_mesh_decimate(in, &o, &out, NULL), ISOMEND_OK);
    isomend_mesh *sm = NULL;
    CHECK_EQ_INT(isomend_mesh_smooth(in, 10, &sm, NULL), ISOMEND_OK);
    if (!out || !sm)
        return;
    /* the input's vertices on the box's faces: each must be in `out` at the
     * same position (a set compare via sorting would do; n is small) and
     * unmoved in `sm` */
    double box[6];
    isomend_mesh_grid_box(in, box);
    const float *p = isomend_mesh_positions(in), *q = isomend_mesh_positions(out),
                *s = isomend_mesh_positions(sm);
    const size_t nv = isomend_mesh_vertex_count(in), nq = isomend_mesh_vertex_count(out);
    size_t on_border = 0, missing = 0, moved = 0;
    for (size_t v = 0; v < nv; v++) {
        int border = 0;
        for (int a = 0; a < 3; a++)
            border |= p[3 * v + a] == (float)box[a] || p[3 * v + a] == (float)box[3 + a];
        if (!border)
            continue;
        on_border++;
        int found = 0;
        for (size_t w = 0; w < nq && !found; w++)
            found = !memcmp(q + 3 * w, p + 3 * v, 12);
        missing += !found;
        moved += memcmp(s + 3 * v, p + 3 * v, 12) != 0;
    }
    if (!on_border || missing || moved) {
        fprintf(stderr, "%s: %zu border vertices, %zu missing after decimation, %zu moved by smoothing\n",
                what, on_border, missing, moved);
        CHECK(0);
    }
    isomend_mesh_destroy(out);
    isomend_mesh_destroy(sm);
}

static void smooth_and_check(const isomend_mesh *in, const isomend_check_report *rin,
                             int padded, const char *what)
{
    isomend_mesh *out = NULL;
    isomend_smooth_report rep;
    CHECK_EQ_INT(isomend_mesh_smooth(in, 20, &out, &rep), ISOMEND_OK);
    if (!out)
        return;
    CHECK(!memcmp(isomend_mesh_triangles(in), isomend_mesh_triangles(out),
                  12 * isomend_mesh_triangle_count(in)));
    isomend_check_report r;
    CHECK_EQ_INT(isomend_mesh_check(out, &r), ISOMEND_OK);
    CHECK(closed_as(&r, rin, padded));
    if (padded) {
        const double change = fabs(rep.volume_after - rep.volume_before) / fabs(rep.volume_before);
        if (!(change < 0.005)) {
            fprintf(stderr, "%s: smoothing changed the volume by %.4f %% (%g to %g)\n", what, 100 * change, rep.volume_before, rep.volume_after);
            CHECK(0);
        }
        CHECK(rep.max_displacement > 0);
    }
    isomend_mesh_destroy(out);
}

static void clean_and_check(const isomend_mesh *in, const char *what)
{
    isomend_check_report rin;
    isomend_mesh_check(in, &rin);
    isomend_mesh *out = NULL;
    isomend_clean_report rep;
    CHECK_EQ_INT(isomend_mesh_clean(in, 30, 0, &out, &rep), ISOMEND_OK);
    if (!out)
        return;
    isomend_check_report r;
    isomend_mesh_check(out, &r);
    CHECK_EQ_INT(rep.components_before, rin.components);
    CHECK_EQ_INT(r.components, rep.components_after);
    CHECK_EQ_INT(rep.triangles_removed, rin.triangles - r.triangles);
    CHECK(r.hole_edges == 0 && r.nonmanifold_edges == 0);
    isomend_mesh_destroy(out);
    CHECK_EQ_INT(isomend_mesh_clean(in, 0, 1, &out, &rep), ISOMEND_OK);
    if (!out)
        return;
    isomend_mesh_check(out, &r);
    CHECK_EQ_INT(r.components, 1);
    CHECK_EQ_INT(rep.components_after, 1);
    if (strcmp(what, "noise") == 0)
        CHECK(rin.components > 10 && r.triangles < rin.triangles);
    isomend_mesh_destroy(out);
}

/* The decimation's regions (several of 2^16 vertices) on threads, and with
 * the process confined to one core (the post-processing's threads follow
 * its cores): the same bytes, with a ratio and with a maximum error. */
static void regions_same_on_one_core(void)
{
    int64_t n[3] = {96, 96, 96};
    float *f = shape_volume(GYROID, n, 0.35, &rng_state);
    isomend_volume vol;
    isomend_volume_init(&vol, f, ISOMEND_F32, n[0], n[1], n[2]);
    isomend_options o;
    isomend_options_init(&o);
    o.flags = ISOMEND_FLAG_PAD;
    isomend_mesh *m = NULL;
    CHECK_EQ_INT(isomend_extract(&vol, &o, &m, NULL), ISOMEND_OK);
    free(f);
    if (!m)
        return;
    CHECK(isomend_mesh_vertex_count(m) >= 3 << 16); /* three regions at least */
    isomend_check_report rin;
    CHECK_EQ_INT(isomend_mesh_check(m, &rin), ISOMEND_OK);
    cpu_set_t all, one;
    CHECK_EQ_INT(sched_getaffinity(0, sizeof all, &all), 0);
    CPU_ZERO(&one);
    for (int c = 0; c < CPU_SETSIZE; c++)
        if (CPU_ISSET(c, &all)) {
            CPU_SET(c, &one);
            break;
        }
    for (int with_error = 0; with_error < 2; with_error++) {
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        if (with_error)
            d.max_error = 0.1;
        else
            d.ratio = 0.1;
        isomend_mesh *a = NULL, *b = NULL;
        CHECK_EQ_INT(isomend_mesh_decimate(m, &d, &a, NULL), ISOMEND_OK);
        CHECK_EQ_INT(sched_setaffinity(0, sizeof one, &one), 0);
        CHECK_EQ_INT(isomend_mesh_decimate(m, &d, &b, NULL), ISOMEND_OK);
        CHECK_EQ_INT(sched_setaffinity(0, sizeof all, &all), 0);
        CHECK(a && b && same_bytes(a, b));
        if (a && b && !same_bytes(a, b))
            fprintf(stderr, "regions (%s): %zu triangles on all cores, %zu on one\n",
                    with_error ? "max_error 0.1" : "ratio 0.1", isomend_mesh_triangle_count(a),
                    isomend_mesh_triangle_count(b));
        isomend_check_report r;
        CHECK(a && isomend_mesh_check(a, &r) == ISOMEND_OK && closed_as(&r, &rin, 1));
        CHECK(a && isomend_mesh_triangle_count(a) < isomend_mesh_triangle_count(m) / 2);
        isomend_mesh_destroy(a);
        isomend_mesh_destroy(b);
        decimated++;
    }
    isomend_mesh_destroy(m);
}

int main(void)
{
    regions_same_on_one_core();
    static const isomend_method methods[] = {ISOMEND_METHOD_DMC, ISOMEND_METHOD_TETRA,
                                              ISOMEND_METHOD_MC33, ISOMEND_METHOD_ASYMPTOTIC};
    for (int shape = 0; shape < SHAPES; shape++)
        for (size_t mi = 0; mi < sizeof methods / sizeof methods[0]; mi++)
            for (int padded = 1; padded >= 0; padded--) {
                int64_t n[3];
                float *f = make(shape, n);
                isomend_volume vol;
                isomend_volume_init(&vol, f, ISOMEND_F32, n[0], n[1], n[2]);
                vol.spacing[2] = 1.5;
                isomend_options o;
                isomend_options_init(&o);
                o.method = methods[mi];
                o.flags = padded ? ISOMEND_FLAG_PAD : 0;
                isomend_mesh *m1 = NULL, *m2 = NULL;
                o.threads = 1;
                CHECK_EQ_INT(isomend_extract(&vol, &o, &m1, NULL), ISOMEND_OK);
                o.threads = 2;
                CHECK_EQ_INT(isomend_extract(&vol, &o, &m2, NULL), ISOMEND_OK);
                char what[120];
                snprintf(what, sizeof what, "%s %s%s", names[shape],
                         isomend_method_name(methods[mi]), padded ? " padded" : "");
                isomend_check_report rin;
                CHECK_EQ_INT(isomend_mesh_check(m1, &rin), ISOMEND_OK);
                CHECK(rin.hole_edges == 0);
                static const double ratios[] = {0.05, 0.1, 0.3, 0.6};
                for (size_t r = 0; r < 4; r++) {
                    isomend_decimate_options d;
                    isomend_decimate_options_init(&d);
                    d.ratio = ratios[r];
                    decimate_and_check(m1, &rin, padded, &d, what);
                }
                isomend_decimate_options d;
                isomend_decimate_options_init(&d);
                d.target_triangles = isomend_mesh_triangle_count(m1) / 4;
                decimate_and_check(m1, &rin, padded, &d, what);
                d.target_triangles = 0;
                d.max_error = 0.05;
                decimate_and_check(m1, &rin, padded, &d, what);
                /* 1 and 2 threads: the same mesh, the same decimation */
                d.max_error = 0;
                d.ratio = 0.1;
                isomend_mesh *a = NULL, *b = NULL;
                isomend_mesh_decimate(m1, &d, &a, NULL);
                isomend_mesh_decimate(m2, &d, &b, NULL);
                CHECK(a && b && same_bytes(a, b));
                isomend_mesh_destroy(a);
                isomend_mesh_destroy(b);
                if (padded)
                    smooth_and_check(m1, &rin, padded, what);
                else if (shape == SPHERE || shape == GYROID)
                    border_kept(m1, what);
                if (padded && mi == 0)
                    clean_and_check(m1, names[shape]);
                isomend_mesh_destroy(m1);
                isomend_mesh_destroy(m2);
                free(f);
            }
    /* bad arguments */
    {
        int64_t n[3];
        float *f = make(SPHERE, n);
        isomend_volume vol;
        isomend_volume_init(&vol, f, ISOMEND_F32, n[0], n[1], n[2]);
        isomend_mesh *m = NULL, *out = (isomend_mesh *)&vol;
        CHECK_EQ_INT(isomend_extract(&vol, NULL, &m, NULL), ISOMEND_OK);
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        CHECK_EQ_INT(isomend_mesh_decimate(m, &d, &out, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK(out == NULL);
        d.ratio = 1.5;
        CHECK_EQ_INT(isomend_mesh_decimate(m, &d, &out, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        d.ratio = NAN;
        CHECK_EQ_INT(isomend_mesh_decimate(m, &d, &out, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        d.ratio = 0.5;
        d.max_error = -1;
        CHECK_EQ_INT(isomend_mesh_decimate(m, &d, &out, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_mesh_smooth(m, -1, &out, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_mesh_decimate(NULL, &d, &out, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_mesh_clean(NULL, 1, 0, &out, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        isomend_mesh_destroy(m);
        free(f);
    }
    printf("%d decimations checked\n", decimated);
    TEST_EXIT();
}
