/*
 * The streamed decimation (isomend_decimate_stream_*) between a stream and a
 * sink, on a sphere, a gyroid (genus), random noise (hundreds of components,
 * every ambiguous case), a tall gyroid and the thesis's F1/F2, by the
 * hole-free methods and by MC (holes, which must stay), padded and not, with
 * chunks of 1, 2, 3, 5 layers and the default:
 *   - the result (collected from the sink, which the streaming check is fed
 *     too, so the protocol is checked: ids in order, triangles on delivered
 *     and not retired vertices, floors) is a closed, oriented 2-manifold with
 *     the input's components and Euler characteristic (isomend_check and
 *     the streaming check agree), or keeps the input's border and holes;
 *   - its triangle count is at most 1.25 x the in-memory decimation's at the
 *     same ratio and the report's counts are the mesh's;
 *   - the same bytes from streams on 1, 2 and 3 threads;
 *   - the reported max_error bounds the distance from the extracted mesh's
 *     vertices to the result (measured here, brute force);
 *   - max_error (alone, with a ratio, with a target), on chunks of 1 layer
 *     (the most windows) and the default: every extracted vertex within it
 *     of the result (brute force on chunks of 1 layer), the report's
 *     max_error within it, at least one collapse refused by it, closed as
 *     above, the same bytes on 2 threads (chunks of 1 layer), and no more
 *     than 1.25 x the in-memory decimation's triangles;
 *   - target_triangles with the count given beforehand
 *     (isomend_decimate_stream_expect): the report's target the in-memory
 *     one (the larger of ratio and target), at most 1.25 x the in-memory
 *     decimation's triangles, reached when the mesh has at most that many;
 *     without the count, with another count, a second expect or one after a
 *     triangle: ISOMEND_ERR_INVALID_ARGUMENT;
 *   - bad arguments are refused and a sink that stops stops the stream.
 */
#include "isomend.h"
#include "mesh_internal.h" /* point_triangle_distance2 */
#include "collect.h"
#include "testutil.h"
#include "volumes.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* the tall gyroid: SHAPE_GYROID at frequency 0.5 on 24 x 20 x 90 */
enum { SPHERE = SHAPE_SPHERE, GYROID = SHAPE_GYROID, NOISE = SHAPE_NOISE, F1 = SHAPE_F1,
       F2 = SHAPE_F2, TALL, SHAPES };
static const char *names[SHAPES] = {"sphere", "gyroid", "noise", "F1", "F2", "tall gyroid"};
static uint64_t rng_state = 0x9e3779b97f4a7c15ull;

static float *make(int shape, int64_t n[3])
{
    if (shape == F1 || shape == F2)
        n[0] = n[1] = n[2] = 4;
    else if (shape == NOISE)
        n[0] = 14, n[1] = 12, n[2] = 20;
    else if (shape == TALL)
        n[0] = 24, n[1] = 20, n[2] = 90;
    else
        n[0] = 40, n[1] = 36, n[2] = 33;
    return shape_volume(shape == TALL ? GYROID : shape, n, shape == TALL ? 0.5 : 0.35, &rng_state);
}

#define NO_COUNT UINT64_MAX

/* Streams vol with o through a streamed decimation with d (the stream's
 * triangle count given beforehand unless `count` is NO_COUNT) into c; the
 * status of the first failing call. */
static isomend_status stream_decimated_with(const isomend_volume *vol, const isomend_options *o,
                                            const isomend_decimate_options *d, uint64_t count,
                                            int64_t layers, collected *c,
                                            isomend_decimate_report *rep, isomend_check_report *sr)
{
    isomend_status st = collected_begin(c, vol, o);
    if (st != ISOMEND_OK)
        return st;
    c->unit_normals = 1;
    const isomend_mesh_sink out = collected_sink(c);
    isomend_decimate_stream *ds = NULL;
    st = isomend_decimate_stream_begin(vol, o, d, layers, &out, &ds);
    if (st != ISOMEND_OK)
        return st;
    if (count != NO_COUNT && (st = isomend_decimate_stream_expect(ds, count)) != ISOMEND_OK) {
        isomend_decimate_stream_destroy(ds);
        return st;
    }
    isomend_mesh_sink in;
    isomend_decimate_stream_sink(ds, &in);
    st = stream_volume(vol, o, &in);
    const isomend_status fs = isomend_decimate_stream_finish(ds, rep);
    isomend_decimate_stream_destroy(ds);
    if (st == ISOMEND_OK)
        st = fs;
    if (st == ISOMEND_OK)
        st = isomend_check_stream_finish(c->check, sr);
    return st;
}

static isomend_status stream_decimated(const isomend_volume *vol, const isomend_options *o,
                                       double ratio, int64_t layers, collected *c,
                                       isomend_decimate_report *rep, isomend_check_report *sr)
{
    isomend_decimate_options d;
    isomend_decimate_options_init(&d);
    d.ratio = ratio;
    return stream_decimated_with(vol, o, &d, NO_COUNT, layers, c, rep, sr);
}

/* The largest distance from the mesh m's vertices to the triangles of c (all
 * of them: the report measures against a subset); every triangle is tried
 * whose bounding box is nearer than the best so far, starting from the
 * previous vertex's nearest (the vertices come slice by slice), until the
 * best is below the largest so far. */
static double brute_distance(const isomend_mesh *m, const collected *c)
{
    const float *p = isomend_mesh_positions(m);
    double *box = malloc((6 * c->nt + 1) * sizeof *box);
    CHECK(box != NULL);
    if (!box)
        return INFINITY;
    for (size_t t = 0; t < c->nt; t++)
        for (int i = 0; i < 3; i++) {
            double lo = INFINITY, hi = -INFINITY;
            for (int k = 0; k < 3; k++) {
                const double x = c->pos[3 * (size_t)c->tri[3 * t + (size_t)k] + (size_t)i];
                lo = x < lo ? x : lo;
                hi = x > hi ? x : hi;
            }
            box[6 * t + (size_t)i] = lo;
            box[6 * t + 3 + (size_t)i] = hi;
        }
    double worst = 0;
    size_t hint = 0;
    for (size_t v = 0; v < isomend_mesh_vertex_count(m); v++) {
        const double q[3] = {p[3 * v], p[3 * v + 1], p[3 * v + 2]};
        double best = INFINITY;
        const size_t start = hint;
        for (size_t j = 0; j < c->nt && best > worst; j++) { /* else it cannot raise the max */
            const size_t t = (j + start) % c->nt;
            double b2 = 0;
            for (int i = 0; i < 3; i++) {
                const double lo = box[6 * t + (size_t)i] - q[i],
                             hi = q[i] - box[6 * t + 3 + (size_t)i];
                const double out = lo > 0 ? lo : hi > 0 ? hi : 0;
                b2 += out * out;
            }
            if (b2 >= best)
                continue;
            double x[3][3];
            for (int k = 0; k < 3; k++)
                for (int i = 0; i < 3; i++)
                    x[k][i] = c->pos[3 * (size_t)c->tri[3 * t + (size_t)k] + (size_t)i];
            const double d2 = point_triangle_distance2(q, x[0], x[1], x[2]);
            if (d2 < best) {
                best = d2;
                hint = t;
            }
        }
        worst = best > worst ? best : worst;
    }
    free(box);
    return sqrt(worst);
}

static int windows;

/* Whether r1 (a streamed decimation's check) keeps the surface of rin (the
 * extraction's): the same defects, border, components and Euler
 * characteristic; else says how. */
static int same_surface(const char *what, const isomend_check_report *r1,
                        const isomend_check_report *rin)
{
    const int ok = r1->nonmanifold_edges == rin->nonmanifold_edges &&
                   r1->misoriented_edges == rin->misoriented_edges &&
                   r1->nonmanifold_vertices == rin->nonmanifold_vertices &&
                   r1->hole_edges == rin->hole_edges && r1->border_edges == rin->border_edges &&
                   r1->degenerate_triangles <= rin->degenerate_triangles &&
                   r1->components == rin->components && r1->euler == rin->euler;
    if (!ok)
        fprintf(stderr,
                "%s: %llu triangles: %llu hole (was %llu), %llu non-manifold, %llu misoriented "
                "edges, %llu non-manifold vertices, %llu border edges (was %llu), %llu "
                "degenerate; components %llu (was %llu), euler %lld (was %lld)\n",
                what, (unsigned long long)r1->triangles, (unsigned long long)r1->hole_edges,
                (unsigned long long)rin->hole_edges, (unsigned long long)r1->nonmanifold_edges,
                (unsigned long long)r1->misoriented_edges,
                (unsigned long long)r1->nonmanifold_vertices, (unsigned long long)r1->border_edges,
                (unsigned long long)rin->border_edges, (unsigned long long)r1->degenerate_triangles,
                (unsigned long long)r1->components, (unsigned long long)rin->components,
                (long long)r1->euler, (long long)rin->euler);
    return ok;
}

/*
 * max_error and target_triangles on the stream against the in-memory
 * decimation with the same options: mesh m of vol (its check rin).
 */
static void targets(const isomend_volume *vol, isomend_options *o, const isomend_mesh *m,
                    const isomend_check_report *rin, const char *name, int closed)
{
    static const int64_t layer_sets[] = {1, 0};
    const uint64_t nt = isomend_mesh_triangle_count(m);
    /* options: max_error alone, with a ratio, a target alone, a target with a
     * smaller ratio, a target with max_error */
    const double E = 0.35;
    const struct {
        double ratio, max_error;
        uint64_t target;
    } cases[] = {
        {0, E, 0}, {0.1, E, 0}, {0, 0, nt / 8 + 1}, {0.05, 0, nt / 6}, {0, 2 * E, nt / 12}};
    for (size_t ci = 0; ci < sizeof cases / sizeof cases[0]; ci++) {
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        d.ratio = cases[ci].ratio;
        d.max_error = cases[ci].max_error;
        d.target_triangles = cases[ci].target;
        isomend_mesh *inmem = NULL;
        isomend_decimate_report irep;
        CHECK_EQ_INT(isomend_mesh_decimate(m, &d, &inmem, &irep), ISOMEND_OK);
        for (size_t li = 0; li < sizeof layer_sets / sizeof layer_sets[0]; li++) {
            char what[320];
            snprintf(what, sizeof what, "%.160s ratio %g max_error %g target %llu, %lld layers",
                     name, d.ratio, d.max_error, (unsigned long long)d.target_triangles,
                     (long long)layer_sets[li]);
            collected c1, c2;
            isomend_decimate_report rep;
            isomend_check_report sr, r1, sr2;
            o->threads = 1;
            CHECK_EQ_INT(stream_decimated_with(vol, o, &d, d.target_triangles ? nt : NO_COUNT,
                                               layer_sets[li], &c1, &rep, &sr),
                         ISOMEND_OK);
            double box[6];
            isomend_mesh_grid_box(m, box);
            CHECK_EQ_INT(isomend_check(c1.pos, c1.nv, c1.tri, c1.nt, box, &r1), ISOMEND_OK);
            CHECK(!memcmp(&r1, &sr, sizeof sr));
            CHECK(same_surface(what, &r1, rin));
            windows++;
            CHECK_EQ_INT(rep.triangles_after, c1.nt);
            CHECK_EQ_INT(rep.target_triangles, irep.target_triangles);
            CHECK_EQ_INT(rep.reached, c1.nt <= rep.target_triangles);
            if (closed && (double)c1.nt > 1.25 * (double)irep.triangles_after + 8) {
                fprintf(stderr, "%s: %zu triangles streamed, %llu in memory\n", what, c1.nt,
                        (unsigned long long)irep.triangles_after);
                CHECK(0);
            }
            if (d.max_error >
                0) { /* every stream vertex within it: brute force on 1-layer chunks */
                const double e = layer_sets[li] == 1 ? brute_distance(m, &c1) : rep.max_error;
                if (!(e <= d.max_error * (1 + 1e-5)) ||
                    !(rep.max_error <= d.max_error * (1 + 1e-5)) ||
                    !(e <= rep.max_error * (1 + 1e-3) + 1e-4) || !(rep.refused_error > 0)) {
                    fprintf(stderr, "%s: distance %g, reported %g, %llu refused by the error\n",
                            what, e, rep.max_error, (unsigned long long)rep.refused_error);
                    CHECK(0);
                }
            }
            if (layer_sets[li] == 1)
                printf("%-12s ratio %.2f max_error %.2f target %6llu: %6zu triangles streamed "
                       "(largest error %.4f), %6llu in memory (%.4f)\n",
                       name, d.ratio, d.max_error, (unsigned long long)d.target_triangles, c1.nt,
                       rep.max_error, (unsigned long long)irep.triangles_after, irep.max_error);
            if (layer_sets[li] != 1) {
                collected_free(&c1);
                continue;
            }
            /* the same bytes on 2 threads (chunks of 1 layer) */
            o->threads = 2;
            CHECK_EQ_INT(stream_decimated_with(vol, o, &d, d.target_triangles ? nt : NO_COUNT,
                                               layer_sets[li], &c2, NULL, &sr2),
                         ISOMEND_OK);
            if (!collected_same(&c1, &c2)) {
                fprintf(stderr, "%s: 2 threads: another mesh\n", what);
                CHECK(0);
            }
            o->threads = 1;
            collected_free(&c2);
            collected_free(&c1);
        }
        isomend_mesh_destroy(inmem);
    }
}

int main(void)
{
    static const isomend_method methods[] = {ISOMEND_METHOD_DMC, ISOMEND_METHOD_TETRA,
                                              ISOMEND_METHOD_MC33, ISOMEND_METHOD_ASYMPTOTIC,
                                              ISOMEND_METHOD_MC};
    static const int64_t layer_sets[] = {1, 2, 3, 5, 0};
    for (int shape = 0; shape < SHAPES; shape++)
        for (size_t mi = 0; mi < sizeof methods / sizeof methods[0]; mi++)
            for (int padded = 1; padded >= 0; padded--) {
                const int holes = methods[mi] == ISOMEND_METHOD_MC;
                if ((holes || !padded) && shape != GYROID && shape != NOISE)
                    continue;
                int64_t n[3];
                float *f = make(shape, n);
                isomend_volume vol;
                isomend_volume_init(&vol, f, ISOMEND_F32, n[0], n[1], n[2]);
                vol.spacing[2] = 1.5;
                isomend_options o;
                isomend_options_init(&o);
                o.method = methods[mi];
                o.flags = padded ? ISOMEND_FLAG_PAD : 0;
                o.threads = 1;
                isomend_mesh *m = NULL;
                CHECK_EQ_INT(isomend_extract(&vol, &o, &m, NULL), ISOMEND_OK);
                isomend_check_report rin;
                CHECK_EQ_INT(isomend_mesh_check(m, &rin), ISOMEND_OK);
                char what[160];
                for (int r = 0; r < 2; r++) {
                    const double ratio = r ? 0.3 : 0.1;
                    isomend_decimate_options d;
                    isomend_decimate_options_init(&d);
                    d.ratio = ratio;
                    isomend_mesh *inmem = NULL;
                    isomend_decimate_report irep;
                    CHECK_EQ_INT(isomend_mesh_decimate(m, &d, &inmem, &irep), ISOMEND_OK);
                    for (size_t li = 0; li < sizeof layer_sets / sizeof layer_sets[0]; li++) {
                        const int dmc = methods[mi] == ISOMEND_METHOD_DMC;
                        if (!dmc && (r == 1 || (layer_sets[li] != 2 && layer_sets[li] != 0)))
                            continue; /* the other methods: one ratio, two chunk heights */
                        snprintf(what, sizeof what, "%s %s%s ratio %g, %lld layers", names[shape],
                                 isomend_method_name(methods[mi]), padded ? " padded" : "", ratio,
                                 (long long)layer_sets[li]);
                        collected c1, c2;
                        isomend_decimate_report rep;
                        isomend_check_report sr, r1;
                        o.threads = 1;
                        CHECK_EQ_INT(stream_decimated(&vol, &o, ratio, layer_sets[li], &c1, &rep, &sr),
                                     ISOMEND_OK);
                        double box[6];
                        isomend_mesh_grid_box(m, box);
                        CHECK_EQ_INT(isomend_check(c1.pos, c1.nv, c1.tri, c1.nt, box, &r1), ISOMEND_OK);
                        CHECK(!memcmp(&r1, &sr, sizeof sr));
                        windows++;
                        CHECK(same_surface(what, &r1, &rin));
                        CHECK_EQ_INT(rep.triangles_after, c1.nt);
                        CHECK_EQ_INT(rep.vertices_after, c1.nv);
                        CHECK_EQ_INT(rep.triangles_before, isomend_mesh_triangle_count(m));
                        CHECK_EQ_INT(rep.vertices_before, isomend_mesh_vertex_count(m));
                        if (!holes && padded && (double)c1.nt > 1.25 * (double)irep.triangles_after + 8) {
                            fprintf(stderr, "%s: %zu triangles streamed, %llu in memory\n", what,
                                    c1.nt, (unsigned long long)irep.triangles_after);
                            CHECK(0);
                        }
                        if (shape == SPHERE && layer_sets[li] == 3) {
                            const double e = brute_distance(m, &c1);
                            if (!(e <= rep.max_error * (1 + 1e-3) + 1e-4)) {
                                fprintf(stderr, "%s: distance %g, reported %g\n", what, e, rep.max_error);
                                CHECK(0);
                            }
                        }
                        if (dmc && padded && r == 0 && layer_sets[li] == 0)
                            printf("%-12s ratio %.1f: %6zu triangles streamed (mean distance %.4f), "
                                   "%6llu in memory (%.4f)\n",
                                   names[shape], ratio, c1.nt, rep.mean_error,
                                   (unsigned long long)irep.triangles_after, irep.mean_error);
                        /* the same bytes on 2 and 3 threads */
                        for (int th = 2; th <= (dmc ? 3 : 2); th++) {
                            o.threads = th;
                            isomend_check_report sr2;
                            CHECK_EQ_INT(stream_decimated(&vol, &o, ratio, layer_sets[li], &c2, NULL, &sr2),
                                         ISOMEND_OK);
                            if (!collected_same(&c1, &c2)) {
                                fprintf(stderr, "%s: %d threads: another mesh\n", what, th);
                                CHECK(0);
                            }
                            collected_free(&c2);
                        }
                        o.threads = 1;
                        collected_free(&c1);
                    }
                    isomend_mesh_destroy(inmem);
                }
                /* max_error and targets: DMC padded (closed), MC unpadded (holes, a border) */
                if ((methods[mi] == ISOMEND_METHOD_DMC && padded && shape != F1 && shape != F2) ||
                    (methods[mi] == ISOMEND_METHOD_MC && !padded && shape == GYROID)) {
                    snprintf(what, sizeof what, "%s %s%s", names[shape],
                             isomend_method_name(methods[mi]), padded ? " padded" : "");
                    targets(&vol, &o, m, &rin, what, padded && methods[mi] != ISOMEND_METHOD_MC);
                }
                isomend_mesh_destroy(m);
                free(f);
            }
    /* bad arguments and a sink that stops */
    {
        int64_t n[3];
        float *f = make(TALL, n);
        isomend_volume vol;
        isomend_volume_init(&vol, f, ISOMEND_F32, n[0], n[1], n[2]);
        isomend_options o;
        isomend_options_init(&o);
        o.flags = ISOMEND_FLAG_PAD;
        collected c;
        memset(&c, 0, sizeof c);
        const isomend_mesh_sink out = collected_sink(&c);
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        isomend_decimate_stream *ds = (isomend_decimate_stream *)&c;
        CHECK_EQ_INT(isomend_decimate_stream_begin(&vol, &o, &d, 0, &out, &ds),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK(ds == NULL);
        d.max_error = -1;
        CHECK_EQ_INT(isomend_decimate_stream_begin(&vol, &o, &d, 0, &out, &ds),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        d.max_error = INFINITY;
        CHECK_EQ_INT(isomend_decimate_stream_begin(&vol, &o, &d, 0, &out, &ds),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        d.max_error = NAN;
        CHECK_EQ_INT(isomend_decimate_stream_begin(&vol, &o, &d, 0, &out, &ds),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        d.max_error = 0;
        d.ratio = -0.5;
        CHECK_EQ_INT(isomend_decimate_stream_begin(&vol, &o, &d, 0, &out, &ds),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        /* a triangle target: the count beforehand, once, before any triangle,
         * and the stream must have it */
        d.ratio = 0;
        d.target_triangles = 10;
        CHECK_EQ_INT(isomend_decimate_stream_expect(NULL, 5), ISOMEND_ERR_INVALID_ARGUMENT);
        for (int k = 0; k < 4; k++) {
            collected t;
            CHECK_EQ_INT(collected_begin(&t, &vol, &o), ISOMEND_OK);
            const isomend_mesh_sink tout = collected_sink(&t);
            isomend_decimate_stream *x = NULL;
            isomend_mesh_sink in;
            CHECK_EQ_INT(isomend_decimate_stream_begin(&vol, &o, &d, 2, &tout, &x), ISOMEND_OK);
            isomend_decimate_stream_sink(x, &in);
            uint64_t count = 0;
            if (k == 1 || k == 2) { /* the count of another volume's stream; twice */
                CHECK_EQ_INT(isomend_decimate_stream_expect(x, 7), ISOMEND_OK);
                if (k == 2)
                    CHECK_EQ_INT(isomend_decimate_stream_expect(x, 7),
                                 ISOMEND_ERR_INVALID_ARGUMENT);
            } else if (k == 3) { /* after a triangle */
                const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
                const uint64_t ids[3] = {0, 1, 2};
                CHECK_EQ_INT(in.vertices(in.user, 0, 3, p, NULL, NULL), 0);
                CHECK_EQ_INT(in.triangles(in.user, 1, ids, NULL), 0);
                CHECK_EQ_INT(isomend_decimate_stream_expect(x, 1), ISOMEND_ERR_INVALID_ARGUMENT);
                count = 1;
            }
            if (k != 3)
                (void)stream_volume(&vol, &o, &in);
            (void)count;
            CHECK_EQ_INT(isomend_decimate_stream_finish(x, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
            isomend_decimate_stream_destroy(x);
            collected_free(&t);
        }
        d.target_triangles = 0;
        d.ratio = 1.5;
        CHECK_EQ_INT(isomend_decimate_stream_begin(&vol, &o, &d, 0, &out, &ds),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        d.ratio = 0.1;
        CHECK_EQ_INT(isomend_decimate_stream_begin(&vol, &o, &d, -1, &out, &ds),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_decimate_stream_begin(NULL, &o, &d, 0, &out, &ds),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK(isomend_decimate_stream_layers(&vol, &o, NULL, 0) >= 4);
        CHECK_EQ_INT(isomend_decimate_stream_layers(NULL, &o, NULL, 0), 0);
        CHECK(isomend_decimate_stream_layers(&vol, &o, NULL, 1) == 1);
        CHECK(isomend_decimate_stream_memory(&vol, &o, NULL, 8) >
              isomend_decimate_stream_memory(&vol, &o, NULL, 2));
        isomend_decimate_stream_destroy(NULL);
        /* the out sink stops at its k-th call: the stream stops with ISOMEND_ERR_SINK */
        int stops = 0;
        for (int k = 1; k < 400; k += 7) {
            isomend_decimate_report rep;
            collected t;
            CHECK_EQ_INT(collected_begin(&t, &vol, &o), ISOMEND_OK);
            t.unit_normals = 1;
            t.stop_at = k;
            const isomend_mesh_sink tout = collected_sink(&t);
            isomend_decimate_stream *x = NULL;
            CHECK_EQ_INT(isomend_decimate_stream_begin(&vol, &o, &d, 2, &tout, &x), ISOMEND_OK);
            isomend_mesh_sink in;
            isomend_decimate_stream_sink(x, &in);
            o.threads = 2;
            const isomend_status r = stream_volume(&vol, &o, &in);
            const isomend_status fr = isomend_decimate_stream_finish(x, &rep);
            isomend_decimate_stream_destroy(x);
            if (t.calls >= k) {
                stops++;
                CHECK(r == ISOMEND_ERR_SINK || fr == ISOMEND_ERR_SINK);
                CHECK_EQ_INT(fr, ISOMEND_ERR_SINK);
            } else {
                CHECK_EQ_INT(r, ISOMEND_OK);
                CHECK_EQ_INT(fr, ISOMEND_OK);
            }
            collected_free(&t);
        }
        CHECK(stops > 3);
        free(f);
    }
    printf("%d streamed decimations checked\n", windows);
    TEST_EXIT();
}
