/*
 * The streamed --largest (isomend_largest_stream_*): the same stream played
 * twice through one sink (pass 1 counts the components, replay() chooses,
 * pass 2 filters), on noise (hundreds of components, ties), a gyroid and a
 * sphere with islands, by DMC, tetra and MC (holes), padded and not, with
 * (min_triangles, keep_largest) of (0, 1), (0, 2), (10, 5), (0, 40) and
 * (2, more than there are):
 *   - the result (collected from the sink, which the streaming check is fed
 *     too, so the protocol is checked) has the triangles of the in-memory
 *     isomend_mesh_clean(mesh, min, keep): the same multiset of triangles by
 *     their corners' positions, the same check report and report counts;
 *   - one retire a layer, as the stream's;
 *   - isomend_largest_stream_kept_triangles(): 0 before replay(), then the
 *     triangles pass 2 passes;
 *   - the same bytes whatever the threads of either pass (1, 2, 3);
 *   - a second pass that is not the first's stream is refused at finish;
 *   - bad arguments are refused and a sink that stops stops the stream.
 */
#include "isomend.h"
#include "collect.h"
#include "testutil.h"
#include "volumes.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 0x9e3779b97f4a7c15ull;

/* Streams vol (pass 1 with threads t1, pass 2 with t2; pass 2 from vol2 if
 * not NULL) through a streamed --largest into c. */
static isomend_status stream_largest(const isomend_volume *vol, const isomend_volume *vol2,
                                     isomend_options o, int t1, int t2, uint64_t min,
                                     uint64_t keep, collected *c, isomend_clean_report *rep,
                                     isomend_check_report *sr)
{
    isomend_status st = collected_begin(c, vol, &o);
    if (st != ISOMEND_OK)
        return st;
    const isomend_mesh_sink out = collected_sink(c);
    isomend_largest_stream *ls = NULL;
    if ((st = isomend_largest_stream_begin(min, keep, &out, &ls)) != ISOMEND_OK)
        return st;
    isomend_mesh_sink in;
    isomend_largest_stream_sink(ls, &in);
    uint64_t kept = 0; /* what replay() says pass 2 will pass */
    for (int pass = 0; pass < 2 && st == ISOMEND_OK; pass++) {
        const isomend_volume *v = pass && vol2 ? vol2 : vol;
        o.threads = pass ? t2 : t1;
        st = stream_volume(v, &o, &in);
        if (st == ISOMEND_OK && pass == 0) {
            CHECK_EQ_INT(isomend_largest_stream_kept_triangles(ls), 0);
            st = isomend_largest_stream_replay(ls);
            kept = isomend_largest_stream_kept_triangles(ls);
        }
    }
    const isomend_status fs = isomend_largest_stream_finish(ls, rep);
    if (st == ISOMEND_OK && fs == ISOMEND_OK && !vol2)
        CHECK_EQ_INT(kept, c->nt);
    isomend_largest_stream_destroy(ls);
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
    static const uint64_t mins[] = {0, 0, 10, 0, 2}, keeps[] = {1, 2, 5, 40, 1000000};
    int runs = 0;
    for (int shape = 0; shape < SHAPES; shape++)
        for (size_t mi = 0; mi < sizeof methods / sizeof methods[0]; mi++)
            for (int padded = 1; padded >= 0; padded--) {
                if (!padded && shape == ISLANDS)
                    continue;
                int64_t n[3] = {18, 16, 26};
                float *f;
                if (shape == ISLANDS) { /* a sphere and noise specks around it */
                    n[0] = 40, n[1] = 36, n[2] = 33;
                    f = shape_volume(SHAPE_SPHERE, n, 0.35, &rng_state);
                    for (size_t i = 0; i < (size_t)(n[0] * n[1] * n[2]); i++)
                        if (f[i] < -2.0f && shape_urand(&rng_state) < 0.01)
                            f[i] = 1.0f; /* a one-sample island outside */
                } else {
                    if (shape == GYROID)
                        n[0] = 40, n[1] = 36, n[2] = 33;
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
                for (size_t k = 0; k < sizeof keeps / sizeof keeps[0]; k++) {
                    char what[160];
                    snprintf(what, sizeof what, "%s %s%s min %llu keep %llu", names[shape],
                             isomend_method_name(methods[mi]), padded ? " padded" : "",
                             (unsigned long long)mins[k], (unsigned long long)keeps[k]);
                    isomend_mesh *inmem = NULL;
                    isomend_clean_report irep, rep;
                    CHECK_EQ_INT(isomend_mesh_clean(m, mins[k], keeps[k], &inmem, &irep), ISOMEND_OK);
                    isomend_check_report rs;
                    collected c1, c2;
                    CHECK_EQ_INT(stream_largest(&vol, NULL, o, 1, 1, mins[k], keeps[k], &c1, &rep, &rs),
                                 ISOMEND_OK);
                    runs++;
                    CHECK(same_as_clean(what, &c1, box, &rs, inmem, &rep, &irep));
                    /* one retire a layer, as the stream's */
                    CHECK_EQ_INT(c1.retires, n[2] + 2 * padded - 1);
                    if (shape == NOISE && padded && mi == 0)
                        printf("%-20s min %-3llu keep %-7llu: %llu of %llu components, %llu "
                               "triangles removed\n",
                               names[shape], (unsigned long long)mins[k],
                               (unsigned long long)keeps[k],
                               (unsigned long long)rep.components_after,
                               (unsigned long long)rep.components_before,
                               (unsigned long long)rep.triangles_removed);
                    /* other threads in either pass: the same bytes */
                    static const int t1s[] = {2, 3, 1}, t2s[] = {2, 1, 3};
                    for (int t = 0; t < 3; t++) {
                        CHECK_EQ_INT(stream_largest(&vol, NULL, o, t1s[t], t2s[t], mins[k], keeps[k],
                                                    &c2, NULL, &rs),
                                     ISOMEND_OK);
                        if (!collected_same(&c1, &c2)) {
                            fprintf(stderr, "%s: threads %d/%d: another mesh\n", what, t1s[t], t2s[t]);
                            CHECK(0);
                        }
                        collected_free(&c2);
                    }
                    collected_free(&c1);
                    isomend_mesh_destroy(inmem);
                }
                isomend_mesh_destroy(m);
                free(f);
            }
    /* a second pass that is not the first's stream; bad arguments; a sink
     * that stops */
    {
        int64_t n[3] = {18, 16, 26};
        float *f = shape_volume(SHAPE_NOISE, n, 0.35, &rng_state);
        float *g = shape_volume(SHAPE_NOISE, n, 0.35, &rng_state);
        isomend_volume vol, other;
        isomend_volume_init(&vol, f, ISOMEND_F32, n[0], n[1], n[2]);
        isomend_volume_init(&other, g, ISOMEND_F32, n[0], n[1], n[2]);
        isomend_options o;
        isomend_options_init(&o);
        o.flags = ISOMEND_FLAG_PAD;
        collected c;
        isomend_check_report rs;
        CHECK(stream_largest(&vol, &other, o, 1, 1, 0, 3, &c, NULL, &rs) != ISOMEND_OK);
        collected_free(&c);
        memset(&c, 0, sizeof c);
        isomend_mesh_sink out = collected_sink(&c);
        isomend_largest_stream *ls = (isomend_largest_stream *)&c;
        CHECK_EQ_INT(isomend_largest_stream_begin(0, 1, NULL, &ls), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK(ls == NULL);
        out.retire = NULL;
        CHECK_EQ_INT(isomend_largest_stream_begin(0, 1, &out, &ls), ISOMEND_ERR_INVALID_ARGUMENT);
        out.retire = collect_retire;
        CHECK_EQ_INT(isomend_largest_stream_begin(0, 1, &out, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_largest_stream_sink(NULL, &out), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_largest_stream_replay(NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_largest_stream_finish(NULL, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK(isomend_largest_stream_memory(&vol, &o) > 0);
        CHECK_EQ_INT(isomend_largest_stream_memory(NULL, &o), 0);
        isomend_largest_stream_destroy(NULL);
        int stops = 0;
        for (int k = 1; k < 200; k += 5) {
            collected t;
            CHECK_EQ_INT(collected_begin(&t, &vol, &o), ISOMEND_OK);
            t.stop_at = k;
            const isomend_mesh_sink tout = collected_sink(&t);
            isomend_largest_stream *x = NULL;
            CHECK_EQ_INT(isomend_largest_stream_begin(0, 30, &tout, &x), ISOMEND_OK);
            isomend_mesh_sink in;
            isomend_largest_stream_sink(x, &in);
            isomend_status r = ISOMEND_OK;
            o.threads = 2;
            for (int pass = 0; pass < 2 && r == ISOMEND_OK; pass++) {
                r = stream_volume(&vol, &o, &in);
                if (r == ISOMEND_OK && pass == 0)
                    r = isomend_largest_stream_replay(x);
            }
            const isomend_status fr = isomend_largest_stream_finish(x, NULL);
            isomend_largest_stream_destroy(x);
            if (t.calls >= k) {
                stops++;
                CHECK(r != ISOMEND_OK || fr == ISOMEND_ERR_SINK);
            } else {
                CHECK_EQ_INT(r, ISOMEND_OK);
                CHECK_EQ_INT(fr, ISOMEND_OK);
            }
            collected_free(&t);
        }
        CHECK(stops > 3);
        free(f);
        free(g);
    }
    printf("%d streamed --largest runs checked\n", runs);
    TEST_EXIT();
}
