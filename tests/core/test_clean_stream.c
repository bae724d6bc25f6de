/*
 * The streamed clean-up (isomend_clean_stream_*) between a stream and a
 * sink, on noise (hundreds of components, every ambiguous case), a gyroid
 * and a sphere with islands, by DMC, tetra and MC (holes), padded and not,
 * with min_triangles 0, 2, 10, 60 and more than the largest component:
 *   - the result (collected from the sink, which the streaming check is fed
 *     too, so the protocol is checked) has the triangles of the in-memory
 *     isomend_mesh_clean(mesh, min, 0): the same multiset of triangles by
 *     their corners' positions, the same check report (components, Euler
 *     characteristic, holes, borders), the same report counts;
 *   - the same bytes from streams on 1, 2 and 3 threads;
 *   - clean-up then the streamed decimation (a chain, as the CLI makes it)
 *     is still closed with the cleaned mesh's components and Euler
 *     characteristic;
 *   - bad arguments are refused and a sink that stops stops the stream.
 */
#include "collect.h"
#include "isomend.h"
#include "testutil.h"
#include "volumes.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 0x2545f4914f6cdd1dull;

/* Streams vol with o through a streamed clean-up [and decimation] into c. */
static isomend_status stream_cleaned(const isomend_volume *vol, const isomend_options *o,
                                     uint64_t min, double ratio, collected *c,
                                     isomend_clean_report *rep, isomend_check_report *sr,
                                     int *retires_in)
{
    isomend_status st = collected_begin(c, vol, o);
    if (st != ISOMEND_OK)
        return st;
    const isomend_mesh_sink out = collected_sink(c);
    isomend_mesh_sink mid = out, in;
    isomend_decimate_stream *ds = NULL;
    if (ratio > 0) {
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        d.ratio = ratio;
        if ((st = isomend_decimate_stream_begin(vol, o, &d, 2, &out, &ds)) != ISOMEND_OK)
            return st;
        isomend_decimate_stream_sink(ds, &mid);
    }
    isomend_clean_stream *cs = NULL;
    if ((st = isomend_clean_stream_begin(min, &mid, &cs)) != ISOMEND_OK) {
        isomend_decimate_stream_destroy(ds);
        return st;
    }
    isomend_clean_stream_sink(cs, &in);
    st = stream_volume(vol, o, &in);
    isomend_status fs = isomend_clean_stream_finish(cs, rep);
    isomend_clean_stream_destroy(cs);
    if (ds) {
        const isomend_status f2 = isomend_decimate_stream_finish(ds, NULL);
        fs = fs == ISOMEND_OK ? f2 : fs;
        isomend_decimate_stream_destroy(ds);
    }
    if (retires_in)
        *retires_in = c->retires;
    if (st == ISOMEND_OK)
        st = fs;
    if (st == ISOMEND_OK)
        st = isomend_check_stream_finish(c->check, sr);
    return st;
}

int main(void)
{
    enum { NOISE, GYROID, ISLANDS, SHAPES };
    static const char *names[SHAPES] = {"noise", "gyroid", "sphere with islands"};
    static const isomend_method methods[] = {ISOMEND_METHOD_DMC, ISOMEND_METHOD_TETRA,
                                              ISOMEND_METHOD_MC};
    static const uint64_t mins[] = {0, 2, 10, 60, 1000000};
    int runs = 0;
    for (int shape = 0; shape < SHAPES; shape++)
        for (size_t mi = 0; mi < sizeof methods / sizeof methods[0]; mi++)
            for (int padded = 1; padded >= 0; padded--) {
                if (!padded && shape == ISLANDS)
                    continue;
                int64_t n[3] = {18, 16, 26};
                if (shape == GYROID)
                    n[0] = 40, n[1] = 36, n[2] = 33;
                float *f;
                if (shape == ISLANDS) { /* a sphere and noise specks around it */
                    n[0] = 40, n[1] = 36, n[2] = 33;
                    f = shape_volume(SHAPE_SPHERE, n, 0.35, &rng_state);
                    for (size_t i = 0; i < (size_t)(n[0] * n[1] * n[2]); i++)
                        if (f[i] < -2.0f && shape_urand(&rng_state) < 0.01)
                            f[i] = 1.0f; /* a one-sample island outside */
                } else {
                    f = shape_volume(shape == NOISE ? SHAPE_NOISE : SHAPE_GYROID, n, 0.35,
                                     &rng_state);
                }
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
                double box[6];
                isomend_mesh_grid_box(m, box);
                for (size_t k = 0; k < sizeof mins / sizeof mins[0]; k++) {
                    char what[160];
                    snprintf(what, sizeof what, "%s %s%s min %llu", names[shape],
                             isomend_method_name(methods[mi]), padded ? " padded" : "",
                             (unsigned long long)mins[k]);
                    isomend_mesh *inmem = NULL;
                    isomend_clean_report irep, rep;
                    CHECK_EQ_INT(isomend_mesh_clean(m, mins[k], 0, &inmem, &irep), ISOMEND_OK);
                    isomend_check_report ri, rs, r1;
                    CHECK_EQ_INT(isomend_mesh_check(inmem, &ri), ISOMEND_OK);
                    collected c1, c2;
                    int retires = 0;
                    CHECK_EQ_INT(stream_cleaned(&vol, &o, mins[k], 0, &c1, &rep, &rs, &retires),
                                 ISOMEND_OK);
                    runs++;
                    CHECK(same_as_clean(what, &c1, box, &rs, inmem, &rep, &irep));
                    /* one retire a layer, as the stream's */
                    CHECK_EQ_INT(retires, n[2] + 2 * padded - 1);
                    if (shape == NOISE && padded && mi == 0)
                        printf("%-20s min %-7llu: %llu of %llu components, %llu triangles removed\n",
                               names[shape], (unsigned long long)mins[k],
                               (unsigned long long)rep.components_after,
                               (unsigned long long)rep.components_before,
                               (unsigned long long)rep.triangles_removed);
                    for (int th = 2; th <= 3; th++) {
                        o.threads = th;
                        CHECK_EQ_INT(stream_cleaned(&vol, &o, mins[k], 0, &c2, NULL, &rs, NULL),
                                     ISOMEND_OK);
                        if (!collected_same(&c1, &c2)) {
                            fprintf(stderr, "%s: %d threads: another mesh\n", what, th);
                            CHECK(0);
                        }
                        collected_free(&c2);
                    }
                    o.threads = 1;
                    /* then the streamed decimation: closed, the cleaned mesh's components */
                    if (methods[mi] != ISOMEND_METHOD_MC && padded && mins[k] < 1000) {
                        CHECK_EQ_INT(stream_cleaned(&vol, &o, mins[k], 0.2, &c2, NULL, &rs, NULL),
                                     ISOMEND_OK);
                        CHECK_EQ_INT(isomend_check(c2.pos, c2.nv, c2.tri, c2.nt, box, &r1),
                                     ISOMEND_OK);
                        CHECK_EQ_INT(r1.hole_edges + r1.nonmanifold_edges + r1.misoriented_edges +
                                         r1.nonmanifold_vertices,
                                     0);
                        CHECK_EQ_INT(r1.components, ri.components);
                        CHECK_EQ_INT(r1.euler, ri.euler);
                        collected_free(&c2);
                    }
                    collected_free(&c1);
                    isomend_mesh_destroy(inmem);
                }
                isomend_mesh_destroy(m);
                free(f);
            }
    /* bad arguments and a sink that stops */
    {
        int64_t n[3] = {18, 16, 26};
        float *f = shape_volume(SHAPE_NOISE, n, 0.35, &rng_state);
        isomend_volume vol;
        isomend_volume_init(&vol, f, ISOMEND_F32, n[0], n[1], n[2]);
        isomend_options o;
        isomend_options_init(&o);
        o.flags = ISOMEND_FLAG_PAD;
        collected c;
        memset(&c, 0, sizeof c);
        isomend_mesh_sink out = collected_sink(&c);
        isomend_clean_stream *cs = (isomend_clean_stream *)&c;
        CHECK_EQ_INT(isomend_clean_stream_begin(5, NULL, &cs), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK(cs == NULL);
        out.retire = NULL;
        CHECK_EQ_INT(isomend_clean_stream_begin(5, &out, &cs), ISOMEND_ERR_INVALID_ARGUMENT);
        out.retire = collect_retire;
        CHECK_EQ_INT(isomend_clean_stream_begin(5, &out, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_clean_stream_sink(NULL, &out), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_clean_stream_finish(NULL, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK(isomend_clean_stream_memory(&vol, &o) > 0);
        CHECK_EQ_INT(isomend_clean_stream_memory(NULL, &o), 0);
        isomend_clean_stream_destroy(NULL);
        /* a triangle on an id not delivered, or below the floor: refused */
        {
            CHECK_EQ_INT(isomend_clean_stream_begin(5, &out, &cs), ISOMEND_OK);
            isomend_mesh_sink in;
            isomend_clean_stream_sink(cs, &in);
            const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
            const uint64_t t_bad[3] = {0, 1, 3};
            CHECK_EQ_INT(in.vertices(in.user, 0, 3, p, NULL, NULL), 0);
            CHECK(in.triangles(in.user, 1, t_bad, NULL) != 0);
            CHECK_EQ_INT(isomend_clean_stream_finish(cs, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
            isomend_clean_stream_destroy(cs);
        }
        int stops = 0;
        for (int k = 1; k < 200; k += 5) {
            collected t;
            CHECK_EQ_INT(collected_begin(&t, &vol, &o), ISOMEND_OK);
            t.stop_at = k;
            const isomend_mesh_sink tout = collected_sink(&t);
            isomend_clean_stream *x = NULL;
            CHECK_EQ_INT(isomend_clean_stream_begin(8, &tout, &x), ISOMEND_OK);
            isomend_mesh_sink in;
            isomend_clean_stream_sink(x, &in);
            o.threads = 2;
            const isomend_status r = stream_volume(&vol, &o, &in);
            const isomend_status fr = isomend_clean_stream_finish(x, NULL);
            isomend_clean_stream_destroy(x);
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
    printf("%d streamed clean-ups checked\n", runs);
    TEST_EXIT();
}
