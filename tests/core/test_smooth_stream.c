/*
 * The streamed smoothing (isomend_smooth_stream_*) between a stream and a
 * sink, on a sphere, a gyroid (genus) and noise (hundreds of components),
 * by DMC, tetra and MC (holes), padded and not, with N = 1, 4, 10
 * iterations and chunks of 1, 3, 8 layers and the default:
 *   - the result (collected from the sink, which the streaming check is fed
 *     too) is the input's triangles, a closed oriented 2-manifold with the
 *     input's check report (components, Euler characteristic, holes,
 *     borders), and the report's counts are the mesh's;
 *   - the volume changes by less than 0.5 % (2 % on noise, whose specks are
 *     smaller than a band and restored window by window: up to 1.7 % with
 *     chunks of one layer) and the largest displacement is within 1.5 x the
 *     in-memory smoothing's; the streamed vertices lie near the in-memory
 *     smoothing's surface (mean distance under 0.05, largest under 0.5 of a
 *     voxel);
 *   - the same bytes from streams on 1, 2 and 3 threads;
 *   - clean-up, smoothing and decimation in a chain (as the CLI makes it):
 *     closed, with the cleaned mesh's components;
 *   - bad arguments are refused and a sink that stops stops the stream.
 */
#include "isomend.h"
#include "collect.h"
#include "mesh_internal.h" /* mesh_distances */
#include "testutil.h"
#include "volumes.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 0x5851f42d4c957f2dull;

/* Streams vol with o through [a clean-up,] a smoothing [and a decimation]
 * into c. */
static isomend_status stream_smoothed(const isomend_volume *vol, const isomend_options *o, int iters,
                                      int64_t layers, uint64_t min, double ratio, collected *c,
                                      isomend_smooth_report *rep, isomend_check_report *sr)
{
    isomend_status st = collected_begin(c, vol, o);
    if (st != ISOMEND_OK)
        return st;
    const isomend_mesh_sink out = collected_sink(c);
    isomend_mesh_sink to_dec = out, to_smooth, in;
    isomend_decimate_stream *ds = NULL;
    isomend_clean_stream *cs = NULL;
    isomend_smooth_stream *ss = NULL;
    if (ratio > 0) {
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        d.ratio = ratio;
        if ((st = isomend_decimate_stream_begin(vol, o, &d, layers, &out, &ds)) != ISOMEND_OK)
            return st;
        isomend_decimate_stream_sink(ds, &to_dec);
    }
    if ((st = isomend_smooth_stream_begin(vol, o, iters, layers, &to_dec, &ss)) != ISOMEND_OK) {
        isomend_decimate_stream_destroy(ds);
        return st;
    }
    isomend_smooth_stream_sink(ss, &to_smooth);
    in = to_smooth;
    if (min) {
        isomend_clean_stream_begin(min, &to_smooth, &cs);
        isomend_clean_stream_sink(cs, &in);
    }
    st = stream_volume(vol, o, &in);
    isomend_status fs = cs ? isomend_clean_stream_finish(cs, NULL) : ISOMEND_OK;
    const isomend_status f1 = isomend_smooth_stream_finish(ss, rep);
    fs = fs == ISOMEND_OK ? f1 : fs;
    if (ds) {
        const isomend_status f2 = isomend_decimate_stream_finish(ds, NULL);
        fs = fs == ISOMEND_OK ? f2 : fs;
    }
    isomend_clean_stream_destroy(cs);
    isomend_smooth_stream_destroy(ss);
    isomend_decimate_stream_destroy(ds);
    if (st == ISOMEND_OK)
        st = fs;
    if (st == ISOMEND_OK)
        st = isomend_check_stream_finish(c->check, sr);
    return st;
}

int main(void)
{
    enum { SPHERE, GYROID, NOISE, SHAPES };
    static const char *names[SHAPES] = {"sphere", "gyroid", "noise"};
    static const isomend_method methods[] = {ISOMEND_METHOD_DMC, ISOMEND_METHOD_TETRA,
                                              ISOMEND_METHOD_MC};
    static const int iter_set[] = {1, 4, 10};
    static const int64_t layer_set[] = {1, 3, 8, 0};
    int runs = 0;
    double worst_dv = 0;
    for (int shape = 0; shape < SHAPES; shape++)
        for (size_t mi = 0; mi < sizeof methods / sizeof methods[0]; mi++)
            for (int padded = 1; padded >= 0; padded--) {
                const int holes = methods[mi] == ISOMEND_METHOD_MC;
                if ((holes || !padded) && shape == SPHERE)
                    continue;
                int64_t n[3] = {40, 36, 33};
                if (shape == NOISE)
                    n[0] = 18, n[1] = 16, n[2] = 26;
                float *f = shape_volume(shape == SPHERE ? SHAPE_SPHERE
                                        : shape == GYROID ? SHAPE_GYROID
                                                          : SHAPE_NOISE,
                                        n, 0.35, &rng_state);
                isomend_volume vol;
                isomend_volume_init(&vol, f, ISOMEND_F32, n[0], n[1], n[2]);
                vol.spacing[2] = 1.25;
                isomend_options o;
                isomend_options_init(&o);
                o.method = methods[mi];
                o.flags = padded ? ISOMEND_FLAG_PAD : 0;
                o.threads = 1;
                isomend_mesh *m = NULL;
                CHECK_EQ_INT(isomend_extract(&vol, &o, &m, NULL), ISOMEND_OK);
                isomend_check_report rin;
                CHECK_EQ_INT(isomend_mesh_check(m, &rin), ISOMEND_OK);
                double box[6];
                isomend_mesh_grid_box(m, box);
                for (size_t ii = 0; ii < sizeof iter_set / sizeof iter_set[0]; ii++) {
                    isomend_mesh *inmem = NULL;
                    isomend_smooth_report irep;
                    CHECK_EQ_INT(isomend_mesh_smooth(m, iter_set[ii], &inmem, &irep), ISOMEND_OK);
                    for (size_t li = 0; li < sizeof layer_set / sizeof layer_set[0]; li++) {
                        const int dmc = methods[mi] == ISOMEND_METHOD_DMC;
                        if (!dmc && layer_set[li] != 3)
                            continue;
                        char what[160];
                        snprintf(what, sizeof what, "%s %s%s N %d, %lld layers", names[shape],
                                 isomend_method_name(methods[mi]), padded ? " padded" : "",
                                 iter_set[ii], (long long)layer_set[li]);
                        collected c1, c2;
                        isomend_smooth_report rep;
                        isomend_check_report sr, r1;
                        CHECK_EQ_INT(stream_smoothed(&vol, &o, iter_set[ii], layer_set[li], 0, 0,
                                                     &c1, &rep, &sr),
                                     ISOMEND_OK);
                        runs++;
                        CHECK_EQ_INT(isomend_check(c1.pos, c1.nv, c1.tri, c1.nt, box, &r1),
                                     ISOMEND_OK);
                        CHECK(!memcmp(&r1, &sr, sizeof sr));
                        /* the input's surface: its report, but for degenerate triangles */
                        r1.degenerate_triangles = rin.degenerate_triangles;
                        if (memcmp(&r1, &rin, sizeof rin)) {
                            fprintf(stderr, "%s: %llu holes (was %llu), %llu non-manifold edges, "
                                            "components %llu (was %llu), euler %lld (was %lld)\n",
                                    what, (unsigned long long)r1.hole_edges,
                                    (unsigned long long)rin.hole_edges,
                                    (unsigned long long)r1.nonmanifold_edges,
                                    (unsigned long long)r1.components,
                                    (unsigned long long)rin.components, (long long)r1.euler,
                                    (long long)rin.euler);
                            CHECK(0);
                        }
                        CHECK_EQ_INT(c1.nt, isomend_mesh_triangle_count(m));
                        CHECK_EQ_INT(c1.nv, isomend_mesh_vertex_count(m));
                        /* the volume: the same before (other sums' order), kept after */
                        const double v0 = rep.volume_before, v1 = rep.volume_after;
                        CHECK(fabs(v0 - irep.volume_before) <= 1e-6 * fabs(v0) + 1e-6);
                        const double dv = fabs(v1 - v0) / fabs(v0);
                        if (!holes && padded && shape != NOISE && dv > worst_dv)
                            worst_dv = dv;
                        if (!holes && padded && dv > (shape == NOISE ? 0.02 : 0.005)) {
                            fprintf(stderr, "%s: volume %.6g -> %.6g (%+.3f %%), in memory %.6g\n",
                                    what, v0, v1, 100 * (v1 - v0) / v0, irep.volume_after);
                            CHECK(0);
                        }
                        if (!(rep.max_displacement <= 1.5 * irep.max_displacement + 1e-6)) {
                            fprintf(stderr, "%s: moved up to %g, in memory %g\n", what,
                                    rep.max_displacement, irep.max_displacement);
                            CHECK(0);
                        }
                        /* near the in-memory smoothing's surface */
                        double dmax = 0, dmean = 0;
                        CHECK(mesh_distances(c1.pos, c1.nv, isomend_mesh_positions(inmem),
                                             isomend_mesh_triangles(inmem),
                                             isomend_mesh_triangle_count(inmem), NULL, &dmax,
                                             &dmean, NULL));
                        if (!(dmean < 0.05 && dmax < 0.5)) {
                            fprintf(stderr, "%s: from the in-memory smoothing: mean %g, max %g\n",
                                    what, dmean, dmax);
                            CHECK(0);
                        }
                        if (dmc && padded && layer_set[li] == 3)
                            printf("%-7s N %2d: volume %+.4f %% (in memory %+.4f %%), moved "
                                   "%llu (%llu), at most %.3f (%.3f); from in memory: mean %.4f, "
                                   "max %.3f\n",
                                   names[shape], iter_set[ii], 100 * (v1 - v0) / v0,
                                   100 * (irep.volume_after - irep.volume_before) / irep.volume_before,
                                   (unsigned long long)rep.moved_vertices,
                                   (unsigned long long)irep.moved_vertices, rep.max_displacement,
                                   irep.max_displacement, dmean, dmax);
                        for (int th = 2; th <= 3; th++) {
                            o.threads = th;
                            CHECK_EQ_INT(stream_smoothed(&vol, &o, iter_set[ii], layer_set[li], 0,
                                                         0, &c2, NULL, &sr),
                                         ISOMEND_OK);
                            if (!collected_same(&c1, &c2)) {
                                fprintf(stderr, "%s: %d threads: another mesh\n", what, th);
                                CHECK(0);
                            }
                            collected_free(&c2);
                        }
                        o.threads = 1;
                        /* the chain: clean-up, smoothing, decimation */
                        if (!holes && padded && li == 1) {
                            isomend_mesh *cl = NULL;
                            isomend_check_report rc;
                            CHECK_EQ_INT(isomend_mesh_clean(m, 20, 0, &cl, NULL), ISOMEND_OK);
                            CHECK_EQ_INT(isomend_mesh_check(cl, &rc), ISOMEND_OK);
                            CHECK_EQ_INT(stream_smoothed(&vol, &o, iter_set[ii], layer_set[li], 20,
                                                         0.25, &c2, NULL, &sr),
                                         ISOMEND_OK);
                            CHECK_EQ_INT(isomend_check(c2.pos, c2.nv, c2.tri, c2.nt, box, &r1),
                                         ISOMEND_OK);
                            CHECK_EQ_INT(r1.hole_edges + r1.nonmanifold_edges +
                                             r1.misoriented_edges + r1.nonmanifold_vertices,
                                         0);
                            CHECK_EQ_INT(r1.components, rc.components);
                            CHECK_EQ_INT(r1.euler, rc.euler);
                            CHECK((double)c2.nt <= 0.3 * (double)rc.triangles + 8);
                            collected_free(&c2);
                            isomend_mesh_destroy(cl);
                        }
                        collected_free(&c1);
                    }
                    isomend_mesh_destroy(inmem);
                }
                isomend_mesh_destroy(m);
                free(f);
            }
    /* bad arguments and a sink that stops */
    {
        int64_t n[3] = {24, 20, 40};
        float *f = shape_volume(SHAPE_GYROID, n, 0.5, &rng_state);
        isomend_volume vol;
        isomend_volume_init(&vol, f, ISOMEND_F32, n[0], n[1], n[2]);
        isomend_options o;
        isomend_options_init(&o);
        o.flags = ISOMEND_FLAG_PAD;
        collected c;
        memset(&c, 0, sizeof c);
        const isomend_mesh_sink out = collected_sink(&c);
        isomend_smooth_stream *ss = (isomend_smooth_stream *)&c;
        CHECK_EQ_INT(isomend_smooth_stream_begin(&vol, &o, -1, 0, &out, &ss),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK(ss == NULL);
        CHECK_EQ_INT(isomend_smooth_stream_begin(&vol, &o, 10001, 0, &out, &ss),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_smooth_stream_begin(&vol, &o, 3, -1, &out, &ss),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_smooth_stream_begin(NULL, &o, 3, 0, &out, &ss),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_smooth_stream_begin(&vol, &o, 3, 0, NULL, &ss),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK(isomend_smooth_stream_memory(&vol, &o, 10, 8) >
              isomend_smooth_stream_memory(&vol, &o, 2, 8));
        CHECK_EQ_INT(isomend_smooth_stream_memory(&vol, &o, -1, 8), 0);
        CHECK_EQ_INT(isomend_smooth_stream_finish(NULL, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        isomend_smooth_stream_destroy(NULL);
        int stops = 0;
        for (int k = 1; k < 200; k += 7) {
            collected t;
            CHECK_EQ_INT(collected_begin(&t, &vol, &o), ISOMEND_OK);
            t.stop_at = k;
            const isomend_mesh_sink tout = collected_sink(&t);
            isomend_smooth_stream *x = NULL;
            CHECK_EQ_INT(isomend_smooth_stream_begin(&vol, &o, 2, 3, &tout, &x), ISOMEND_OK);
            isomend_mesh_sink in;
            isomend_smooth_stream_sink(x, &in);
            o.threads = 2;
            const isomend_status r = stream_volume(&vol, &o, &in);
            const isomend_status fr = isomend_smooth_stream_finish(x, NULL);
            isomend_smooth_stream_destroy(x);
            if (t.calls >= k) {
                stops++;
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
    printf("%d streamed smoothings checked; the largest volume change (closed sphere and "
           "gyroid) %.4f %%\n", runs, 100 * worst_dv);
    TEST_EXIT();
}
