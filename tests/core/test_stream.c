/*
 * test_stream.c - the streaming extraction (isomend_stream_*) against
 * isomend_extract() on the same volume: positions, normals, triangles,
 * origins and statistics identical byte for byte, vertex order included, for
 * every method, voxel type and flag, on sphere, gyroid, noise and random
 * volumes of random sizes; the sink's order contract (consecutive ids,
 * triangles of delivered vertices, retire floors kept); ids past 2^32; the
 * memory bound independent of nz; bad input and a sink that stops; pieces
 * (slabs and boxes at random boundaries) stitched by keys to the same mesh.
 *
 *   test_stream          the comparisons and bad input (core_stream)
 *   test_stream --tall   a 64 x 64 x (2^19 + 2) volume, 2^31 + 8192 samples,
 *                        streamed in O(one slice) (core_stream_tall)
 *   test_stream_mri --nrrd FILE
 *                        slabs and boxes of a real volume (core_stream_mri:
 *                        the bundled MRI; built with io/'s NRRD reader)
 */
#include "isomend.h"
#include "stream_pool.h"
#include "testutil.h"
#ifdef ISOMEND_TEST_NRRD
#include "volume_readers.h"
#endif

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* stream.c, internal: the first vertex id of a stream not yet pushed to. */
void stream_set_first_id(isomend_stream *s, uint64_t first);

static uint64_t rng_state = 0x2545F4914F6CDD1Dull;

static uint32_t rng(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (uint32_t)(rng_state >> 11);
}

/* ------------------------------------------------------------------ a sink that keeps all */

typedef struct collect {
    float *pos, *nrm;
    uint64_t *keys;
    size_t nv, vcap;
    uint64_t *tri;
    uint8_t *org;
    size_t nt, tcap;
    uint64_t floor;
    int saw_normals, saw_origins, saw_keys;
    int order_errors;
    long calls, stop_at; /* stop (return 1) at call stop_at; 0: never */
    long calls_after_stop;
    uint64_t id_offset;
    uint64_t *fkeys; /* a piece's foreign keys and positions */
    float *fpos;
    size_t nf;
    uint64_t vertex_bound; /* isomend_stream_vertex_bound(); 0: not checked */
    uint64_t bound_errors; /* calls past it, or kept (>= floor) past twice it */
} collect;

static int count_call(collect *c)
{
    if (c->stop_at && c->calls >= c->stop_at) {
        c->calls_after_stop++;
        return 1;
    }
    return ++c->calls == c->stop_at;
}

static int on_vertices(void *user, uint64_t first, size_t count, const float *pos,
                       const float *nrm, const uint64_t *keys)
{
    collect *c = user;
    if (count_call(c))
        return 1;
    if (first != c->id_offset + c->nv || count == 0)
        c->order_errors++;
    if (c->vertex_bound && (count > c->vertex_bound ||
                            first + count - c->floor > 2 * c->vertex_bound))
        c->bound_errors++;
    if (c->nv + count > c->vcap) {
        c->vcap = 2 * (c->nv + count);
        c->pos = realloc(c->pos, 3 * sizeof(float) * c->vcap);
        c->nrm = realloc(c->nrm, 3 * sizeof(float) * c->vcap);
        c->keys = realloc(c->keys, sizeof(uint64_t) * c->vcap);
        if (!c->pos || !c->nrm || !c->keys)
            abort();
    }
    memcpy(c->pos + 3 * c->nv, pos, 3 * sizeof(float) * count);
    if (nrm) {
        c->saw_normals = 1;
        memcpy(c->nrm + 3 * c->nv, nrm, 3 * sizeof(float) * count);
    }
    if (keys) {
        c->saw_keys = 1;
        memcpy(c->keys + c->nv, keys, sizeof(uint64_t) * count);
    }
    c->nv += count;
    return 0;
}

static int on_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *org)
{
    collect *c = user;
    if (count_call(c))
        return 1;
    if (c->nt + count > c->tcap) {
        c->tcap = 2 * (c->nt + count);
        c->tri = realloc(c->tri, 3 * sizeof(uint64_t) * c->tcap);
        c->org = realloc(c->org, c->tcap);
        if (!c->tri || !c->org)
            abort();
    }
    for (size_t q = 0; q < 3 * count; q++)
        if ((ids[q] & ISOMEND_FOREIGN) ? (ids[q] & ~ISOMEND_FOREIGN) >= c->nf
                                       : ids[q] < c->floor || ids[q] >= c->id_offset + c->nv)
            c->order_errors++;
    memcpy(c->tri + 3 * c->nt, ids, 3 * sizeof(uint64_t) * count);
    if (org) {
        c->saw_origins = 1;
        memcpy(c->org + c->nt, org, count);
    }
    c->nt += count;
    return 0;
}

static int on_retire(void *user, uint64_t floor)
{
    collect *c = user;
    if (count_call(c))
        return 1;
    if (floor < c->floor || floor > c->id_offset + c->nv)
        c->order_errors++;
    c->floor = floor;
    return 0;
}

static int on_foreign(void *user, size_t first, size_t count, const uint64_t *keys,
                      const float *pos)
{
    collect *c = user;
    if (count_call(c))
        return 1;
    if (first != c->nf) /* appended (triangles check f < nf: before them) */
        c->order_errors++;
    c->fkeys = realloc(c->fkeys, sizeof(uint64_t) * (c->nf + count));
    c->fpos = realloc(c->fpos, 3 * sizeof(float) * (c->nf + count));
    if (!c->fkeys || !c->fpos)
        abort();
    memcpy(c->fkeys + c->nf, keys, sizeof(uint64_t) * count);
    memcpy(c->fpos + 3 * c->nf, pos, 3 * sizeof(float) * count);
    c->nf += count;
    return 0;
}

static isomend_mesh_sink sink_of(collect *c)
{
    isomend_mesh_sink s = {c, on_vertices, on_triangles, on_retire, on_foreign};
    return s;
}

static void collect_free(collect *c)
{
    free(c->pos);
    free(c->nrm);
    free(c->keys);
    free(c->tri);
    free(c->org);
    free(c->fkeys);
    free(c->fpos);
    memset(c, 0, sizeof *c);
}

/* ------------------------------------------------------------------ volumes */

enum { SPHERE, GYROID, NOISE, RANDOM_VALUES, SHAPES };
static const char *shape_names[SHAPES] = {"sphere", "gyroid", "noise", "random"};

/* A field of shape `shape` on n[0] x n[1] x n[2] samples, values in about
 * [0, 1], iso 0.5 (NaNs in float types when `nans`). */
static double *make_field(int shape, const int64_t n[3], int nans)
{
    const size_t count = (size_t)(n[0] * n[1] * n[2]);
    double *f = malloc(sizeof(double) * count);
    if (!f)
        abort();
    for (int64_t k = 0; k < n[2]; k++)
        for (int64_t j = 0; j < n[1]; j++)
            for (int64_t i = 0; i < n[0]; i++) {
                const double x = (double)i / (double)n[0], y = (double)j / (double)n[1],
                             z = (double)k / (double)n[2];
                double v = 0.0;
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
                f[(k * n[1] + j) * n[0] + i] = v;
            }
    if (nans)
        for (size_t q = 0; q < count / 23 + 1; q++)
            f[rng() % count] = NAN;
    return f;
}

/* The field as samples of `type` (integers scaled to their range), iso for it. */
static void *to_type(const double *f, size_t count, isomend_type type, double *iso)
{
    void *out = malloc(count * isomend_type_size(type) + 1);
    if (!out)
        abort();
    static const double lo[] = {0, -128, 0, -32768, -2147483648.0};
    static const double hi[] = {255, 127, 65535, 32767, 2147483647.0};
    *iso = 0.5;
    if (type <= ISOMEND_I32)
        *iso = lo[type] + 0.5 * (hi[type] - lo[type]);
    for (size_t q = 0; q < count; q++) {
        const double v = f[q];
        double s = type <= ISOMEND_I32 ? (isnan(v) ? 0.0 : lo[type] + v * (hi[type] - lo[type]))
                                       : v;
        if (type <= ISOMEND_I32)
            s = floor(s + 0.5);
        switch (type) {
        case ISOMEND_U8: ((uint8_t *)out)[q] = (uint8_t)s; break;
        case ISOMEND_I8: ((int8_t *)out)[q] = (int8_t)s; break;
        case ISOMEND_U16: ((uint16_t *)out)[q] = (uint16_t)s; break;
        case ISOMEND_I16: ((int16_t *)out)[q] = (int16_t)s; break;
        case ISOMEND_I32: ((int32_t *)out)[q] = (int32_t)s; break;
        case ISOMEND_F32: ((float *)out)[q] = (float)s; break;
        case ISOMEND_F64: ((double *)out)[q] = s; break;
        }
    }
    return out;
}

/* A volume of `shape` and `type` on n samples (NaNs in float types except
 * the sphere) into *vol; returns its samples (free them) and *iso. */
static void *make_volume(int shape, isomend_type type, const int64_t n[3], isomend_volume *vol,
                         double *iso)
{
    const int nans = (type == ISOMEND_F32 || type == ISOMEND_F64) && shape != SPHERE;
    double *f = make_field(shape, n, nans);
    void *data = to_type(f, (size_t)(n[0] * n[1] * n[2]), type, iso);
    free(f);
    isomend_volume_init(vol, data, type, n[0], n[1], n[2]);
    return data;
}

/* Slices where they are (isomend.h): gives the volume a table of slice
 * origins with uneven gaps, jitter of up to 0.3 pixel and a 15 degree shear
 * along y; returns it (free it). */
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
        so[3 * k] = vol->origin[0] + ((double)(rng() % 1000) / 1000.0 - 0.5) * 0.6 * vol->spacing[0];
        so[3 * k + 1] = vol->origin[1] + 0.2679491924 * (z - vol->origin[2]);
        so[3 * k + 2] = z;
    }
    vol->slice_origins = so;
    return so;
}

/* World position of marched sample idx with slice origins (padding slices
 * one gap beyond the ends). */
static void sheared_sample(const isomend_volume *vol, int64_t pad, const int64_t idx[3], double w[3])
{
    const double *so = vol->slice_origins;
    const int64_t n = vol->dims[2], k = idx[2] - pad;
    for (int a = 0; a < 3; a++) {
        const double step = n > 1 ? (k < 0 ? so[3 + a] - so[a] : so[3 * (n - 1) + a] - so[3 * (n - 2) + a])
                                  : (a == 2 ? vol->spacing[2] : 0.0);
        w[a] = k < 0 ? so[a] - step : k >= n ? so[3 * (n - 1) + a] + step : so[3 * k + a];
    }
    w[0] += (double)(idx[0] - pad) * vol->spacing[0];
    w[1] += (double)(idx[1] - pad) * vol->spacing[1];
}

/* ------------------------------------------------------------------ stream == extract */

static int compared;

/* Streams vol with opts (ids from id_offset) and compares with the
 * in-memory extraction. */
static void compare(const isomend_volume *vol, const isomend_options *opts, uint64_t id_offset,
                    const char *what)
{
    isomend_mesh *mesh = NULL;
    isomend_stats es, ss;
    memset(&es, 0, sizeof es);
    memset(&ss, 0xAB, sizeof ss);
    isomend_status st = isomend_extract(vol, opts, &mesh, &es);
    CHECK_EQ_INT(st, ISOMEND_OK);
    if (st != ISOMEND_OK)
        return;
    collect c;
    memset(&c, 0, sizeof c);
    c.id_offset = id_offset;
    c.floor = id_offset;
    c.vertex_bound = isomend_stream_vertex_bound(vol, opts);
    CHECK(c.vertex_bound > 0);
    isomend_mesh_sink sink = sink_of(&c);
    isomend_stream *s = NULL;
    st = isomend_stream_begin(vol, opts, &sink, &s);
    CHECK_EQ_INT(st, ISOMEND_OK);
    if (id_offset)
        stream_set_first_id(s, id_offset);
    const size_t size = isomend_type_size(vol->type);
    const size_t plane = (size_t)(vol->dims[0] * vol->dims[1]) * size;
    char *buf = malloc(plane);
    for (int64_t z = 0; z < vol->dims[2] && st == ISOMEND_OK; z++) {
        memcpy(buf, (const char *)vol->data + (size_t)z * plane, plane);
        st = isomend_stream_push(s, buf);
        memset(buf, 0x5A, plane); /* the stream must have copied it */
        CHECK_EQ_INT(st, ISOMEND_OK);
    }
    free(buf);
    if (st == ISOMEND_OK) {
        st = isomend_stream_finish(s, &ss);
        CHECK_EQ_INT(st, ISOMEND_OK);
    }
    isomend_stream_destroy(s);
    const size_t nv = isomend_mesh_vertex_count(mesh), nt = isomend_mesh_triangle_count(mesh);
    int ok = st == ISOMEND_OK && c.nv == nv && c.nt == nt && c.order_errors == 0 &&
             c.bound_errors == 0 &&
             memcmp(&es, &ss, sizeof es) == 0 &&
             (nv == 0 || memcmp(c.pos, isomend_mesh_positions(mesh), 12 * nv) == 0) &&
             !c.saw_keys;
    const float *mn = isomend_mesh_normals(mesh);
    if (ok && mn && nv)
        ok = c.saw_normals && memcmp(c.nrm, mn, 12 * nv) == 0;
    if (ok && !mn)
        ok = !c.saw_normals;
    const uint8_t *mo = isomend_mesh_triangle_origins(mesh);
    if (ok && mo && nt)
        ok = c.saw_origins && memcmp(c.org, mo, nt) == 0;
    if (ok && !mo)
        ok = !c.saw_origins;
    const uint32_t *mt = isomend_mesh_triangles(mesh);
    for (size_t q = 0; ok && q < 3 * nt; q++)
        ok = c.tri[q] == id_offset + mt[q];
    if (!ok)
        fprintf(stderr, "stream != extract: %s (vertices %zu/%zu, triangles %zu/%zu, order errors %d)\n",
                what, c.nv, nv, c.nt, nt, c.order_errors);
    CHECK(ok);
    compared++;
    collect_free(&c);
    isomend_mesh_destroy(mesh);
}

static void test_all_methods_types(void)
{
    static const unsigned flag_sets[] = {0,
                                         ISOMEND_FLAG_PAD,
                                         ISOMEND_FLAG_NO_NORMALS | ISOMEND_FLAG_NO_ORIGINS,
                                         ISOMEND_FLAG_FLIP | ISOMEND_FLAG_PAD,
                                         ISOMEND_FLAG_NO_NORMALS | ISOMEND_FLAG_PAD};
    for (int shape = 0; shape < SHAPES; shape++)
        for (int t = 0; t < ISOMEND_TYPE_COUNT; t++) {
            const isomend_type type = (isomend_type)t;
            int64_t n[3];
            for (int a = 0; a < 3; a++)
                n[a] = 2 + (int64_t)(rng() % 17);
            if (shape == SPHERE && t == 0) { /* reserved arrays' size (2^20 samples) */
                n[0] = n[1] = 140;
                n[2] = 110;
            }
            double iso;
            isomend_volume vol;
            void *data = make_volume(shape, type, n, &vol, &iso);
            vol.spacing[0] = 0.5;
            vol.spacing[2] = 1.25;
            vol.origin[1] = -3.0;
            double *so = (shape + t) % 2 ? shear_slices(&vol) : NULL;
            for (int m = 0; m < ISOMEND_METHOD_COUNT; m++) {
                if (!isomend_method_available((isomend_method)m))
                    continue;
                for (size_t fl = 0; fl < sizeof flag_sets / sizeof flag_sets[0]; fl++) {
                    if (n[0] == 140 && m >= ISOMEND_METHOD_FACIAL && fl > 1)
                        continue; /* the large case: the general methods twice only */
                    isomend_options o;
                    isomend_options_init(&o);
                    o.iso = iso;
                    o.method = (isomend_method)m;
                    o.flags = flag_sets[fl];
                    o.threads = 1 + (int)(rng() % 3);
                    char what[160];
                    snprintf(what, sizeof what, "%s %s %lldx%lldx%lld%s %s flags %u threads %d",
                             shape_names[shape], isomend_type_name(type), (long long)n[0],
                             (long long)n[1], (long long)n[2], so ? " sheared" : "",
                             isomend_method_name((isomend_method)m), o.flags, o.threads);
                    compare(&vol, &o, 0, what);
                }
            }
            free(so);
            free(data);
        }
}

/* Streams on several threads (stream_pool.c): slabs extracted by workers and
 * handed over in order, tall enough for many slabs; the same bytes as the
 * in-memory mesh for every thread count. */
static int pooled;
static void test_threads(void)
{
    static const unsigned flag_sets[] = {0, ISOMEND_FLAG_PAD,
                                         ISOMEND_FLAG_NO_NORMALS | ISOMEND_FLAG_NO_ORIGINS,
                                         ISOMEND_FLAG_FLIP | ISOMEND_FLAG_PAD};
    for (int round = 0; round < 12; round++) {
        const int shape = round % SHAPES;
        const isomend_type type = (isomend_type)(rng() % ISOMEND_TYPE_COUNT);
        const int64_t n[3] = {3 + (int64_t)(rng() % 30), 3 + (int64_t)(rng() % 30),
                              20 + (int64_t)(rng() % 100)};
        double iso;
        isomend_volume vol;
        void *data = make_volume(shape, type, n, &vol, &iso);
        vol.spacing[2] = 0.75;
        double *so = round % 3 == 1 ? shear_slices(&vol) : NULL;
        for (int m = 0; m < ISOMEND_METHOD_COUNT; m++) {
            if (!isomend_method_available((isomend_method)m))
                continue;
            isomend_options o;
            isomend_options_init(&o);
            o.iso = iso;
            o.method = (isomend_method)m;
            o.flags = flag_sets[(round + m) % 4];
            static const int counts[] = {2, 3, 5};
            o.threads = counts[(round + m) % 3];
            int64_t slab_layers;
            pooled += stream_pool_plan(&vol, &o, &slab_layers) > 1;
            char what[160];
            snprintf(what, sizeof what, "threads %d: %s %s %lldx%lldx%lld%s %s flags %u",
                     o.threads, shape_names[shape], isomend_type_name(type), (long long)n[0],
                     (long long)n[1], (long long)n[2], so ? " sheared" : "",
                     isomend_method_name((isomend_method)m), o.flags);
            compare(&vol, &o, 0, what);
        }
        free(so);
        free(data);
    }
    CHECK(pooled > 60); /* nearly all of them took the pool */
}

/* Ids past 2^32: the stream starts numbering just below it (ids are kept
 * modulo 2^32 in the id maps and made 64-bit again per layer). */
static void test_ids_past_2_32(void)
{
    const int64_t n[3] = {30, 27, 40};
    for (int m = 0; m < ISOMEND_METHOD_COUNT; m++) {
        double *f = make_field(GYROID, n, 0);
        double iso;
        void *data = to_type(f, (size_t)(n[0] * n[1] * n[2]), ISOMEND_F32, &iso);
        free(f);
        isomend_volume vol;
        isomend_volume_init(&vol, data, ISOMEND_F32, n[0], n[1], n[2]);
        isomend_options o;
        isomend_options_init(&o);
        o.iso = iso;
        o.method = (isomend_method)m;
        o.flags = ISOMEND_FLAG_PAD;
        compare(&vol, &o, ((uint64_t)1 << 32) - 3001, "ids past 2^32");
        free(data);
    }
}

/* ------------------------------------------------------------------ pieces */

typedef struct keyed {
    uint64_t key, id;
} keyed;

static int keyed_cmp(const void *a, const void *b)
{
    const uint64_t x = ((const keyed *)a)->key, y = ((const keyed *)b)->key;
    return x < y ? -1 : x > y;
}

/* Whether key's edge (kinds 0..2) holds position p (the other two
 * coordinates are the grid's). */
static int key_on_edge(const isomend_volume *vol, unsigned flags, uint64_t key, const float *p)
{
    const int64_t pad = (flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    const uint64_t N0 = (uint64_t)(vol->dims[0] + 2 * pad), N1 = (uint64_t)(vol->dims[1] + 2 * pad);
    const unsigned kind = (unsigned)(key & 7);
    const uint64_t lin = key >> 3;
    const int64_t idx[3] = {(int64_t)(lin % N0), (int64_t)(lin / N0 % N1), (int64_t)(lin / N0 / N1)};
    if (kind > 5)
        return 0;
    if (vol->slice_origins) { /* in the box of its edge's or face's true corners */
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int c = 0; c < 4; c++) {
            int64_t corner[3] = {idx[0], idx[1], idx[2]};
            if (kind <= 2) {
                if (c > 1)
                    break;
                corner[kind] += c;
            } else {
                const int u = ((int)kind - 3 + 1) % 3, v = ((int)kind - 3 + 2) % 3;
                corner[u] += c & 1;
                corner[v] += c >> 1;
            }
            double w[3];
            sheared_sample(vol, pad, corner, w);
            for (int a = 0; a < 3; a++) {
                lo[a] = w[a] < lo[a] ? w[a] : lo[a];
                hi[a] = w[a] > hi[a] ? w[a] : hi[a];
            }
        }
        for (int a = 0; a < 3; a++) {
            const double tol = 1e-5 * (fabs(lo[a]) + fabs(hi[a]) + 1.0);
            if ((double)p[a] < lo[a] - tol || (double)p[a] > hi[a] + tol)
                return 0;
        }
        return 1;
    }
    for (int a = 0; a < 3; a++) {
        const double lo = vol->origin[a] + (double)(idx[a] - pad) * vol->spacing[a];
        if (kind <= 2 && a != (int)kind && p[a] != (float)lo)
            return 0;
        if (p[a] < (float)lo - 1e-3f * (float)vol->spacing[a] ||
            p[a] > (float)(lo + vol->spacing[a]) + 1e-3f * (float)vol->spacing[a])
            return 0;
    }
    return 1;
}

static int pieces_compared;

/* Extracts vol as np pieces at random boundaries, stitches them by keys and
 * compares with the in-memory mesh. */
static void compare_pieces(const isomend_volume *vol, const isomend_options *o, int npieces,
                           const char *what)
{
    isomend_mesh *mesh = NULL;
    isomend_stats es, sum;
    CHECK_EQ_INT(isomend_extract(vol, o, &mesh, &es), ISOMEND_OK);
    const int64_t N2 = vol->dims[2] + ((o->flags & ISOMEND_FLAG_PAD) ? 2 : 0);
    if (npieces > N2)
        npieces = (int)N2;
    int64_t cut[8];
    cut[0] = 0;
    cut[npieces] = N2;
    for (int p = 1; p < npieces; p++) { /* distinct, increasing */
        const int64_t lo = cut[p - 1] + 1, hi = N2 - (npieces - p);
        cut[p] = lo + (int64_t)(rng() % (uint64_t)(hi - lo + 1));
    }
    collect c[8];
    memset(c, 0, sizeof c);
    memset(&sum, 0, sizeof sum);
    const size_t plane = (size_t)(vol->dims[0] * vol->dims[1]) * isomend_type_size(vol->type);
    int ok = 1;
    for (int p = 0; p < npieces && ok; p++) {
        isomend_piece piece = {.owned_first = cut[p], .owned_end = cut[p + 1]};
        int64_t first, end;
        CHECK_EQ_INT(isomend_piece_halo(vol, o, &piece, &first, &end), ISOMEND_OK);
        isomend_mesh_sink sink = sink_of(&c[p]);
        isomend_stream *s = NULL;
        ok = isomend_piece_begin(vol, o, &piece, &sink, &s) == ISOMEND_OK;
        for (int64_t z = first; z < end && ok; z++)
            ok = isomend_stream_push(s, (const char *)vol->data + (size_t)z * plane) == ISOMEND_OK;
        isomend_stats ps;
        ok = ok && isomend_stream_finish(s, &ps) == ISOMEND_OK && c[p].order_errors == 0 &&
             c[p].saw_keys == (c[p].nv > 0);
        isomend_stream_destroy(s);
        uint64_t *a = (uint64_t *)(void *)&sum, *b = (uint64_t *)(void *)&ps;
        for (size_t q = 0; q < sizeof sum / sizeof(uint64_t); q++)
            a[q] += b[q];
    }
    /* Stitch: global ids by prefix sums, foreign keys through the next piece's. */
    size_t nv = 0, nt = 0;
    for (int p = 0; p < npieces; p++) {
        nv += c[p].nv;
        nt += c[p].nt;
    }
    ok = ok && nv == isomend_mesh_vertex_count(mesh) && nt == isomend_mesh_triangle_count(mesh) &&
         memcmp(&sum, &es, sizeof es) == 0;
    const float *mp = isomend_mesh_positions(mesh), *mn = isomend_mesh_normals(mesh);
    const uint32_t *mt = isomend_mesh_triangles(mesh);
    const uint8_t *mo = isomend_mesh_triangle_origins(mesh);
    size_t vbase = 0, tbase = 0;
    for (int p = 0; p < npieces && ok; p++) {
        const collect *q = &c[p];
        ok = (!q->nv || memcmp(q->pos, mp + 3 * vbase, 12 * q->nv) == 0) &&
             (!mn || !q->nv || memcmp(q->nrm, mn + 3 * vbase, 12 * q->nv) == 0) &&
             (!mo || !q->nt || memcmp(q->org, mo + tbase, q->nt) == 0);
        for (size_t v = 0; ok && v < q->nv; v++)
            ok = q->keys[v] == ISOMEND_KEY_NONE || key_on_edge(vol, o->flags, q->keys[v], q->pos + 3 * v);
        keyed *next = NULL;
        size_t nnext = 0;
        if (p + 1 < npieces) {
            next = malloc(sizeof(keyed) * (c[p + 1].nv + 1));
            for (size_t v = 0; v < c[p + 1].nv; v++)
                if (c[p + 1].keys[v] != ISOMEND_KEY_NONE) {
                    next[nnext].key = c[p + 1].keys[v];
                    next[nnext++].id = vbase + q->nv + v;
                }
            qsort(next, nnext, sizeof(keyed), keyed_cmp);
        }
        for (size_t t = 0; ok && t < 3 * q->nt; t++) {
            uint64_t id = q->tri[t];
            if (id & ISOMEND_FOREIGN) {
                keyed k = {q->fkeys[id & ~ISOMEND_FOREIGN], 0};
                const keyed *hit = next ? bsearch(&k, next, nnext, sizeof(keyed), keyed_cmp) : NULL;
                ok = hit != NULL;
                id = hit ? hit->id : 0;
                /* the foreign position is the next piece's vertex's */
                ok = ok && memcmp(q->fpos + 3 * (q->tri[t] & ~ISOMEND_FOREIGN), mp + 3 * id,
                                  12) == 0;
            } else {
                id += vbase;
            }
            ok = ok && id == mt[3 * tbase + t];
        }
        free(next);
        vbase += q->nv;
        tbase += q->nt;
    }
    if (!ok)
        fprintf(stderr, "pieces != extract: %s, %d pieces\n", what, npieces);
    CHECK(ok);
    pieces_compared++;
    for (int p = 0; p < npieces; p++)
        collect_free(&c[p]);
    isomend_mesh_destroy(mesh);
}

/* ------------------------------------------------------------------ box pieces */

/* Runs one piece of vol into c; its statistics in *ps. */
static int run_piece(const isomend_volume *vol, const isomend_options *o,
                     const isomend_piece *piece, collect *c, isomend_stats *ps)
{
    int64_t first, end;
    if (isomend_piece_halo(vol, o, piece, &first, &end) != ISOMEND_OK)
        return 0;
    const size_t plane = (size_t)(vol->dims[0] * vol->dims[1]) * isomend_type_size(vol->type);
    isomend_mesh_sink sink = sink_of(c);
    isomend_stream *s = NULL;
    int ok = isomend_piece_begin(vol, o, piece, &sink, &s) == ISOMEND_OK;
    for (int64_t z = first; z < end && ok; z++)
        ok = isomend_stream_push(s, (const char *)vol->data + (size_t)z * plane) == ISOMEND_OK;
    ok = ok && isomend_stream_finish(s, ps) == ISOMEND_OK && c->order_errors == 0;
    isomend_stream_destroy(s);
    return ok;
}

/* n - 1 distinct increasing cuts in (0, N) into cut[1 .. n - 1]; cut[0] = 0, cut[n] = N. */
static void random_cuts(int64_t N, int n, int64_t *cut)
{
    cut[0] = 0;
    cut[n] = N;
    for (int p = 1; p < n; p++) {
        const int64_t lo = cut[p - 1] + 1, hi = N - (n - p);
        cut[p] = lo + (int64_t)(rng() % (uint64_t)(hi - lo + 1));
    }
}

/* A vertex's signature: its position and normal bytes, and its id. */
typedef struct signature {
    float pn[6];
    uint64_t id;
} signature;

static int signature_cmp(const void *a, const void *b)
{
    const int d = memcmp(((const signature *)a)->pn, ((const signature *)b)->pn, sizeof(float) * 6);
    if (d)
        return d;
    const uint64_t x = ((const signature *)a)->id, y = ((const signature *)b)->id;
    return x < y ? -1 : x > y;
}

/* A triangle in global ids, rotated to begin with its smallest, and its origin. */
typedef struct global_triangle {
    uint64_t v[3];
    uint64_t origin;
} global_triangle;

static global_triangle global_of(uint64_t a, uint64_t b, uint64_t c, uint8_t origin)
{
    global_triangle t = {{a, b, c}, origin};
    if (b < a && b < c)
        t = (global_triangle){{b, c, a}, origin};
    else if (c < a && c < b)
        t = (global_triangle){{c, a, b}, origin};
    return t;
}

static int global_cmp(const void *a, const void *b)
{
    const global_triangle *x = a, *y = b;
    for (int q = 0; q < 3; q++)
        if (x->v[q] != y->v[q])
            return x->v[q] < y->v[q] ? -1 : 1;
    return x->origin < y->origin ? -1 : x->origin > y->origin;
}

static int boxes_compared;

/* The flag sets pieces are tried with. */
static const unsigned piece_flags[] = {0, ISOMEND_FLAG_PAD,
                                       ISOMEND_FLAG_NO_NORMALS | ISOMEND_FLAG_FLIP,
                                       ISOMEND_FLAG_PAD | ISOMEND_FLAG_NO_ORIGINS};
enum { PIECE_FLAG_SETS = sizeof piece_flags / sizeof piece_flags[0] };

/* 1 to 4 boxes on each axis, at most one a marched sample. */
static void random_boxes(const isomend_volume *vol, unsigned flags, int nb[3])
{
    const int64_t pad = (flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    for (int a = 0; a < 3; a++) {
        nb[a] = 1 + (int)(rng() % 4);
        if (nb[a] > vol->dims[a] + 2 * pad)
            nb[a] = (int)(vol->dims[a] + 2 * pad);
    }
}

/*
 * Extracts vol as boxes at random boundaries in x, y and z and compares them
 * with the whole grid as one piece (whose keys name every vertex of
 * isomend_extract()'s mesh, compare_pieces): every keyed vertex owned by
 * exactly one box with the same bytes, in the whole's order within a box;
 * the cube-private ones alike by their bytes; every foreign vertex its
 * owner's; the triangles (in global ids, with origins) the same multiset; the
 * statistics summed isomend_extract()'s.
 */
static void compare_boxes(const isomend_volume *vol, const isomend_options *o, const int nb[3],
                          const char *what)
{
    const int64_t pad = (o->flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    const int64_t N[3] = {vol->dims[0] + 2 * pad, vol->dims[1] + 2 * pad, vol->dims[2] + 2 * pad};
    isomend_mesh *mesh = NULL;
    isomend_stats es, ws, sum;
    CHECK_EQ_INT(isomend_extract(vol, o, &mesh, &es), ISOMEND_OK);
    collect w;
    memset(&w, 0, sizeof w);
    const isomend_piece all = {.owned_first = 0, .owned_end = N[2]};
    int ok = run_piece(vol, o, &all, &w, &ws) && w.nv == isomend_mesh_vertex_count(mesh) &&
             (!w.nv || memcmp(w.pos, isomend_mesh_positions(mesh), 12 * w.nv) == 0);
    const int normals = isomend_mesh_normals(mesh) != NULL;
    const int origins = isomend_mesh_triangle_origins(mesh) != NULL;
    /* the whole's keyed vertices by key, its private ones by signature */
    keyed *byk = malloc(sizeof(keyed) * (w.nv + 1));
    signature *bys = malloc(sizeof(signature) * (w.nv + 1));
    uint64_t *rep = malloc(sizeof(uint64_t) * (w.nv + 1));
    uint8_t *seen = calloc(w.nv + 1, 1);
    size_t nk = 0, ns = 0;
    for (size_t v = 0; v < w.nv; v++) {
        rep[v] = v;
        if (w.keys[v] != ISOMEND_KEY_NONE) {
            byk[nk].key = w.keys[v];
            byk[nk++].id = v;
        } else {
            memset(bys[ns].pn, 0, sizeof bys[ns].pn);
            memcpy(bys[ns].pn, w.pos + 3 * v, 12);
            if (normals)
                memcpy(bys[ns].pn + 3, w.nrm + 3 * v, 12);
            bys[ns++].id = v;
        }
    }
    qsort(byk, nk, sizeof(keyed), keyed_cmp);
    qsort(bys, ns, sizeof(signature), signature_cmp);
    for (size_t q = 1; q < ns; q++) /* equal bytes: one representative */
        if (memcmp(bys[q].pn, bys[q - 1].pn, sizeof bys[q].pn) == 0)
            rep[bys[q].id] = rep[bys[q - 1].id];
    global_triangle *whole = malloc(sizeof(global_triangle) * (w.nt + 1));
    for (size_t t = 0; t < w.nt; t++)
        whole[t] = global_of(rep[w.tri[3 * t]], rep[w.tri[3 * t + 1]], rep[w.tri[3 * t + 2]],
                             origins ? w.org[t] : 0);
    global_triangle *parts = malloc(sizeof(global_triangle) * (w.nt + 1));
    size_t nparts = 0, nprivate = 0;

    int64_t cut[3][8];
    for (int a = 0; a < 3; a++)
        random_cuts(N[a], nb[a], cut[a]);
    memset(&sum, 0, sizeof sum);
    int boxes = 0;
    for (int bz = 0; bz < nb[2] && ok; bz++)
        for (int by = 0; by < nb[1] && ok; by++)
            for (int bx = 0; bx < nb[0] && ok; bx++) {
                const isomend_piece piece = {.owned_first = cut[2][bz],
                                             .owned_end = cut[2][bz + 1],
                                             .columns = {cut[0][bx], cut[0][bx + 1]},
                                             .rows = {cut[1][by], cut[1][by + 1]}};
                collect c;
                memset(&c, 0, sizeof c);
                isomend_stats ps;
                ok = run_piece(vol, o, &piece, &c, &ps);
                boxes++;
                uint64_t *a = (uint64_t *)(void *)&sum, *b = (uint64_t *)(void *)&ps;
                for (size_t q = 0; q < sizeof sum / sizeof(uint64_t); q++)
                    a[q] += b[q];
                uint64_t *global = malloc(sizeof(uint64_t) * (c.nv + c.nf + 1));
                uint64_t last = 0;
                int any = 0;
                for (size_t v = 0; ok && v < c.nv; v++) {
                    if (c.keys[v] != ISOMEND_KEY_NONE) {
                        const keyed k = {c.keys[v], 0};
                        const keyed *hit = bsearch(&k, byk, nk, sizeof(keyed), keyed_cmp);
                        ok = hit && !seen[hit->id] && (!any || hit->id > last);
                        if (!ok)
                            break;
                        global[v] = last = hit->id;
                        any = 1;
                        seen[hit->id] = 1;
                    } else {
                        signature sg;
                        memset(&sg, 0, sizeof sg);
                        memcpy(sg.pn, c.pos + 3 * v, 12);
                        if (normals)
                            memcpy(sg.pn + 3, c.nrm + 3 * v, 12);
                        const signature *hit = bsearch(&sg, bys, ns, sizeof(signature), signature_cmp);
                        for (size_t q = 0; !hit && q < ns; q++) /* any id of these bytes */
                            if (memcmp(bys[q].pn, sg.pn, sizeof sg.pn) == 0)
                                hit = &bys[q];
                        ok = hit != NULL;
                        if (!ok)
                            break;
                        global[v] = rep[hit->id];
                        nprivate++;
                    }
                    ok = memcmp(c.pos + 3 * v, w.pos + 3 * global[v], 12) == 0 &&
                         (!normals || memcmp(c.nrm + 3 * v, w.nrm + 3 * global[v], 12) == 0);
                }
                for (size_t f = 0; ok && f < c.nf; f++) { /* the owner's vertex */
                    const keyed k = {c.fkeys[f], 0};
                    const keyed *hit = bsearch(&k, byk, nk, sizeof(keyed), keyed_cmp);
                    ok = hit && memcmp(c.fpos + 3 * f, w.pos + 3 * hit->id, 12) == 0;
                    global[c.nv + f] = hit ? hit->id : 0;
                }
                for (size_t t = 0; ok && t < c.nt; t++) {
                    uint64_t g3[3];
                    for (int q = 0; q < 3; q++) {
                        const uint64_t id = c.tri[3 * t + q];
                        g3[q] = (id & ISOMEND_FOREIGN) ? global[c.nv + (id & ~ISOMEND_FOREIGN)]
                                                       : global[id];
                    }
                    ok = nparts < w.nt;
                    if (ok)
                        parts[nparts++] = global_of(g3[0], g3[1], g3[2], origins ? c.org[t] : 0);
                }
                free(global);
                collect_free(&c);
            }
    size_t nseen = 0;
    for (size_t v = 0; v < w.nv; v++)
        nseen += seen[v];
    ok = ok && nseen == nk && nprivate == ns && nparts == w.nt &&
         memcmp(&sum, &es, sizeof es) == 0 && memcmp(&ws, &es, sizeof es) == 0;
    if (ok) {
        qsort(whole, w.nt, sizeof(global_triangle), global_cmp);
        qsort(parts, nparts, sizeof(global_triangle), global_cmp);
        ok = memcmp(whole, parts, sizeof(global_triangle) * w.nt) == 0;
    }
    if (!ok)
        fprintf(stderr, "boxes != extract: %s, %d x %d x %d boxes\n", what, nb[0], nb[1], nb[2]);
    CHECK(ok);
    boxes_compared += boxes;
    free(byk);
    free(bys);
    free(rep);
    free(seen);
    free(whole);
    free(parts);
    collect_free(&w);
    isomend_mesh_destroy(mesh);
}

/* For every method and flag set of pieces: vol at iso in lo .. lo + span - 1
 * random slabs (compare_pieces) and in random boxes (compare_boxes). */
static void compare_every_split(const isomend_volume *vol, double iso, int lo, int span,
                                const char *name)
{
    for (int m = 0; m < ISOMEND_METHOD_COUNT; m++)
        for (size_t fl = 0; fl < PIECE_FLAG_SETS; fl++) {
            isomend_options o;
            isomend_options_init(&o);
            o.iso = iso;
            o.method = (isomend_method)m;
            o.flags = piece_flags[fl];
            char what[240];
            snprintf(what, sizeof what, "%s, %s, flags %u", name,
                     isomend_method_name((isomend_method)m), o.flags);
            compare_pieces(vol, &o, lo + (int)(rng() % (uint32_t)span), what);
            int nb[3];
            random_boxes(vol, o.flags, nb);
            compare_boxes(vol, &o, nb, what);
        }
}

static void test_pieces(void)
{
    for (int shape = 0; shape < SHAPES; shape++)
        for (int t = 0; t < ISOMEND_TYPE_COUNT; t++) {
            const isomend_type type = (isomend_type)t;
            int64_t n[3];
            for (int a = 0; a < 3; a++)
                n[a] = 2 + (int64_t)(rng() % 15);
            double iso;
            isomend_volume vol;
            void *data = make_volume(shape, type, n, &vol, &iso);
            vol.spacing[1] = 0.75;
            vol.origin[2] = 2.0;
            double *so = (shape + t) % 2 ? shear_slices(&vol) : NULL;
            char what[120];
            snprintf(what, sizeof what, "%s %s %lldx%lldx%lld%s", shape_names[shape],
                     isomend_type_name(type), (long long)n[0], (long long)n[1], (long long)n[2],
                     so ? " sheared" : "");
            compare_every_split(&vol, iso, 1, 5, what);
            free(so);
            free(data);
        }
}

/* ------------------------------------------------------------------ memory, bad input */

static void test_memory_bound(void)
{
    isomend_volume d;
    isomend_volume_init(&d, NULL, ISOMEND_U16, 2048, 2048, 10);
    isomend_options o;
    isomend_options_init(&o);
    const uint64_t small = isomend_stream_memory(&d, &o);
    d.dims[2] = (int64_t)1 << 31;
    const uint64_t tall = isomend_stream_memory(&d, &o);
    CHECK(small > 0);
    CHECK_EQ_INT(small, tall);
    /* at least the window's 8 planes and two slices of id maps */
    CHECK(small >= 8ull * 2048 * 2048 * 2 + 2ull * 12 * 2048 * 2048);
    printf("isomend_stream_memory, 2048 x 2048 u16, DMC: %.1f MiB", (double)small / 1048576.0);
    o.flags = ISOMEND_FLAG_NO_NORMALS | ISOMEND_FLAG_NO_ORIGINS;
    printf("; without normals and origins: %.1f MiB\n",
           (double)isomend_stream_memory(&d, &o) / 1048576.0);
    /* a vertex per x, y and z edge of a slice; tetra: and face diagonal, and its
     * cube-private vertices */
    CHECK_EQ_INT(isomend_stream_vertex_bound(&d, &o), 3ull * 2048 * 2048);
    o.method = ISOMEND_METHOD_TETRA;
    CHECK(isomend_stream_vertex_bound(&d, &o) > 6ull * 2048 * 2048);
    o.method = ISOMEND_METHOD_DMC;
    d.dims[0] = 1; /* refused like isomend_extract() */
    CHECK_EQ_INT(isomend_stream_memory(&d, &o), 0);
    CHECK_EQ_INT(isomend_stream_memory(NULL, &o), 0);
    CHECK_EQ_INT(isomend_stream_vertex_bound(&d, &o), 0);
    CHECK_EQ_INT(isomend_stream_vertex_bound(NULL, &o), 0);
}

/* Streams vol (its data in `data`, `plane` bytes a slice) into a sink that
 * stops at its first call, then at each later one (stride 0) or at calls
 * further apart (stride s: the next stop 1 + stop / s later): ISOMEND_ERR_SINK
 * from that push or finish on,
 * and no callback after it.  Returns the calls of the whole mesh. */
static long check_sink_stops(const isomend_volume *vol, const isomend_options *o,
                             const void *data, size_t plane, long stride)
{
    for (long stop = 1;; stop += stride ? 1 + stop / stride : 1) {
        collect c;
        memset(&c, 0, sizeof c);
        c.stop_at = stop;
        isomend_mesh_sink sink = sink_of(&c);
        isomend_stream *s = NULL;
        CHECK_EQ_INT(isomend_stream_begin(vol, o, &sink, &s), ISOMEND_OK);
        isomend_status st = ISOMEND_OK;
        for (int64_t z = 0; z < vol->dims[2] && st == ISOMEND_OK; z++)
            st = isomend_stream_push(s, (const char *)data + (size_t)z * plane);
        if (st == ISOMEND_OK)
            st = isomend_stream_finish(s, NULL);
        const long calls = c.calls;
        if (calls < stop) { /* fewer calls than stop: the whole mesh went through */
            CHECK_EQ_INT(st, ISOMEND_OK);
            isomend_stream_destroy(s);
            collect_free(&c);
            return calls;
        }
        CHECK_EQ_INT(st, ISOMEND_ERR_SINK);
        CHECK_EQ_INT(isomend_stream_push(s, data), ISOMEND_ERR_SINK);
        CHECK_EQ_INT(isomend_stream_finish(s, NULL), ISOMEND_ERR_SINK);
        CHECK_EQ_INT(c.calls_after_stop, 0);
        isomend_stream_destroy(s);
        collect_free(&c);
    }
}

static void test_bad_input(void)
{
    const int64_t n[3] = {9, 8, 7};
    double *f = make_field(SPHERE, n, 0);
    double iso;
    uint8_t *data = to_type(f, 9 * 8 * 7, ISOMEND_U8, &iso);
    free(f);
    isomend_volume vol;
    isomend_volume_init(&vol, data, ISOMEND_U8, n[0], n[1], n[2]);
    isomend_options o;
    isomend_options_init(&o);
    o.iso = iso;
    collect c;
    memset(&c, 0, sizeof c);
    isomend_mesh_sink sink = sink_of(&c);
    isomend_stream *s = (isomend_stream *)&c; /* must be set to NULL on failure */

    CHECK_EQ_INT(isomend_stream_begin(NULL, &o, &sink, &s), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(s == NULL);
    CHECK_EQ_INT(isomend_stream_begin(&vol, &o, NULL, &s), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_stream_begin(&vol, &o, &sink, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_mesh_sink partial = sink;
    partial.retire = NULL;
    CHECK_EQ_INT(isomend_stream_begin(&vol, &o, &partial, &s), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_volume bad = vol;
    bad.dims[1] = 1;
    CHECK_EQ_INT(isomend_stream_begin(&bad, &o, &sink, &s), ISOMEND_ERR_BAD_DIMENSIONS);
    bad = vol;
    bad.spacing[2] = 0.0;
    CHECK_EQ_INT(isomend_stream_begin(&bad, &o, &sink, &s), ISOMEND_ERR_BAD_SPACING);
    bad = vol;
    bad.type = (isomend_type)99;
    CHECK_EQ_INT(isomend_stream_begin(&bad, &o, &sink, &s), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_options bo = o;
    bo.iso = NAN;
    CHECK_EQ_INT(isomend_stream_begin(&vol, &bo, &sink, &s), ISOMEND_ERR_BAD_ISO);
    bo = o;
    bo.method = (isomend_method)42;
    CHECK_EQ_INT(isomend_stream_begin(&vol, &bo, &sink, &s), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(s == NULL);
    CHECK_EQ_INT(isomend_stream_push(NULL, data), ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_stream_finish(NULL, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_stream_destroy(NULL);

    /* Too few slices at finish, then every call says so. */
    CHECK_EQ_INT(isomend_stream_begin(&vol, &o, &sink, &s), ISOMEND_OK);
    CHECK_EQ_INT(isomend_stream_push(s, NULL), ISOMEND_ERR_INVALID_ARGUMENT);
    for (int z = 0; z < 6; z++)
        CHECK_EQ_INT(isomend_stream_push(s, data + z * 72), ISOMEND_OK);
    CHECK_EQ_INT(isomend_stream_finish(s, NULL), ISOMEND_ERR_SLICE_COUNT);
    CHECK_EQ_INT(isomend_stream_push(s, data + 6 * 72), ISOMEND_ERR_SLICE_COUNT);
    isomend_stream_destroy(s);
    collect_free(&c);
    sink = sink_of(&c);

    /* Too many slices. */
    CHECK_EQ_INT(isomend_stream_begin(&vol, &o, &sink, &s), ISOMEND_OK);
    for (int z = 0; z < 7; z++)
        CHECK_EQ_INT(isomend_stream_push(s, data + z * 72), ISOMEND_OK);
    CHECK_EQ_INT(isomend_stream_push(s, data), ISOMEND_ERR_SLICE_COUNT);
    CHECK_EQ_INT(isomend_stream_finish(s, NULL), ISOMEND_ERR_SLICE_COUNT);
    isomend_stream_destroy(s);
    collect_free(&c);

    /* Destroyed unfinished: nothing more delivered, nothing leaked (ASan). */
    sink = sink_of(&c);
    CHECK_EQ_INT(isomend_stream_begin(&vol, &o, &sink, &s), ISOMEND_OK);
    CHECK_EQ_INT(isomend_stream_push(s, data), ISOMEND_OK);
    isomend_stream_destroy(s);
    collect_free(&c);

    /* Pieces: outside the grid, no foreign callback, the wrong slices. */
    isomend_piece piece = {.owned_first = 0, .owned_end = 3};
    int64_t first = -1, end = -1;
    CHECK_EQ_INT(isomend_piece_halo(&vol, &o, &piece, &first, &end), ISOMEND_OK);
    CHECK(first == 0 && end == 5); /* marched slices -1 .. 4 */
    piece.owned_first = 3;
    piece.owned_end = 7;
    CHECK_EQ_INT(isomend_piece_halo(&vol, &o, &piece, &first, &end), ISOMEND_OK);
    CHECK(first == 2 && end == 7);
    /* (the grid is 9 x 8 x 7: boxes' columns and rows within 9 and 8, not empty) */
    const isomend_piece bad_pieces[] = {
        {.owned_first = -1, .owned_end = 2},
        {.owned_first = 3, .owned_end = 3},
        {.owned_first = 4, .owned_end = 2},
        {.owned_first = 0, .owned_end = 8},
        {.owned_first = 0, .owned_end = 7, .columns = {3, 3}},
        {.owned_first = 0, .owned_end = 7, .columns = {-1, 2}},
        {.owned_first = 0, .owned_end = 7, .columns = {0, 10}},
        {.owned_first = 0, .owned_end = 7, .rows = {5, 4}},
        {.owned_first = 0, .owned_end = 7, .rows = {0, 9}},
    };
    for (size_t q = 0; q < sizeof bad_pieces / sizeof bad_pieces[0]; q++) {
        CHECK_EQ_INT(isomend_piece_halo(&vol, &o, &bad_pieces[q], &first, &end),
                     ISOMEND_ERR_INVALID_ARGUMENT);
        CHECK_EQ_INT(isomend_piece_begin(&vol, &o, &bad_pieces[q], &sink, &s),
                     ISOMEND_ERR_INVALID_ARGUMENT);
    }
    CHECK_EQ_INT(isomend_piece_halo(&vol, &o, NULL, &first, &end), ISOMEND_ERR_INVALID_ARGUMENT);
    piece.owned_first = 0;
    piece.owned_end = 3;
    partial = sink;
    partial.foreign = NULL;
    CHECK_EQ_INT(isomend_piece_begin(&vol, &o, &piece, &partial, &s), ISOMEND_ERR_INVALID_ARGUMENT);
    piece.owned_end = 7; /* the last piece needs no foreign keys */
    CHECK_EQ_INT(isomend_piece_begin(&vol, &o, &piece, &partial, &s), ISOMEND_OK);
    isomend_stream_destroy(s);
    piece.columns[0] = 0; /* ... but a box short of the grid's end in x does */
    piece.columns[1] = 5;
    CHECK_EQ_INT(isomend_piece_begin(&vol, &o, &piece, &partial, &s), ISOMEND_ERR_INVALID_ARGUMENT);
    piece.columns[0] = 5;
    piece.columns[1] = 9;
    CHECK_EQ_INT(isomend_piece_begin(&vol, &o, &piece, &partial, &s), ISOMEND_OK);
    isomend_stream_destroy(s);
    piece.columns[0] = piece.columns[1] = 0;
    piece.owned_first = 3;
    sink = sink_of(&c);
    CHECK_EQ_INT(isomend_piece_begin(&vol, &o, &piece, &sink, &s), ISOMEND_OK);
    for (int z = 2; z < 7; z++)
        CHECK_EQ_INT(isomend_stream_push(s, data + z * 72), ISOMEND_OK);
    CHECK_EQ_INT(isomend_stream_push(s, data), ISOMEND_ERR_SLICE_COUNT);
    isomend_stream_destroy(s);
    collect_free(&c);

    /* A sink that stops at its first, second, ... call: ISOMEND_ERR_SINK from
     * that push or finish on, and no callback after it. */
    const long total_calls = check_sink_stops(&vol, &o, data, 72, 0);
    CHECK(total_calls > 10);
    free(data);

    /* The same on a pool of threads (a volume tall enough for several slabs),
     * and a pool destroyed part way, with slabs queued, running and done. */
    const int64_t tall[3] = {9, 8, 60};
    double tiso;
    isomend_volume tv;
    void *tdata = make_volume(GYROID, ISOMEND_F32, tall, &tv, &tiso);
    isomend_options to;
    isomend_options_init(&to);
    to.iso = tiso;
    to.threads = 2;
    int64_t slab_layers;
    CHECK(stream_pool_plan(&tv, &to, &slab_layers) == 2);
    const size_t tplane = 9 * 8 * sizeof(float);
    const long pool_calls = check_sink_stops(&tv, &to, tdata, tplane, 8);
    CHECK(pool_calls > 20);
    for (int pushed = 0; pushed <= 60; pushed += 7) { /* destroyed after `pushed` slices */
        memset(&c, 0, sizeof c);
        sink = sink_of(&c);
        CHECK_EQ_INT(isomend_stream_begin(&tv, &to, &sink, &s), ISOMEND_OK);
        for (int z = 0; z < pushed; z++)
            CHECK_EQ_INT(isomend_stream_push(s, (const char *)tdata + (size_t)z * tplane),
                         ISOMEND_OK);
        CHECK_EQ_INT(c.order_errors, 0);
        isomend_stream_destroy(s);
        collect_free(&c);
    }
    free(tdata);
}

/* ------------------------------------------------------------------ the tall volume */

/*
 * 64 x 64 x (2^19 + 2) u8 samples, 2^31 + 8192: a tube along z whose radius
 * alternates between two values slice by slice, so that every pair of
 * slices (after the first) adds the same vertices, triangles and cubes per
 * case.  The stream's counts and statistics must equal the extrapolation of
 * two short in-memory extractions (8 and 10 slices), its last vertices lie
 * at the top, and its ids and triangles follow the sink's order.
 */
typedef struct tall_sink {
    uint64_t nv, nt, floor;
    float zmax;
    int errors;
} tall_sink;

static int tall_vertices(void *user, uint64_t first, size_t count, const float *pos,
                         const float *nrm, const uint64_t *keys)
{
    tall_sink *t = user;
    (void)nrm;
    if (first != t->nv || keys)
        t->errors++;
    for (size_t q = 0; q < count; q++)
        if (pos[3 * q + 2] > t->zmax)
            t->zmax = pos[3 * q + 2];
    t->nv += count;
    return 0;
}

static int tall_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *org)
{
    tall_sink *t = user;
    (void)org;
    for (size_t q = 0; q < 3 * count; q++)
        if (ids[q] < t->floor || ids[q] >= t->nv)
            t->errors++;
    t->nt += count;
    return 0;
}

static int tall_retire(void *user, uint64_t floor)
{
    tall_sink *t = user;
    if (floor < t->floor)
        t->errors++;
    t->floor = floor;
    return 0;
}

static void tall_slice(uint8_t *s, int64_t k)
{
    const double r = (k % 2) ? 20.3 : 17.6;
    for (int j = 0; j < 64; j++)
        for (int i = 0; i < 64; i++) {
            const double d = sqrt((i - 31.5) * (i - 31.5) + (j - 30.25) * (j - 30.25));
            s[j * 64 + i] = (uint8_t)(d < r ? 200 - 3 * d : 10 + d);
        }
}

static void short_stats(int64_t nz, const isomend_options *o, isomend_stats *st)
{
    uint8_t *v = malloc((size_t)(64 * 64 * nz));
    for (int64_t k = 0; k < nz; k++)
        tall_slice(v + k * 4096, k);
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_U8, 64, 64, nz);
    isomend_mesh *m = NULL;
    CHECK_EQ_INT(isomend_extract(&vol, o, &m, st), ISOMEND_OK);
    isomend_mesh_destroy(m);
    free(v);
}

static void test_tall(void)
{
    const int64_t nz = ((int64_t)1 << 19) + 2;
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 100.0;
    o.flags = ISOMEND_FLAG_PAD;
    isomend_stats a, b, expect, got;
    short_stats(8, &o, &a);
    short_stats(10, &o, &b);
    const uint64_t periods = (uint64_t)(nz - 8) / 2;
    uint64_t *pa = (uint64_t *)(void *)&a, *pb = (uint64_t *)(void *)&b,
             *pe = (uint64_t *)(void *)&expect;
    for (size_t q = 0; q < sizeof a / sizeof(uint64_t); q++)
        pe[q] = pa[q] + periods * (pb[q] - pa[q]);
    CHECK(expect.cubes > ((uint64_t)1 << 31));

    tall_sink t;
    memset(&t, 0, sizeof t);
    isomend_mesh_sink sink = {&t, tall_vertices, tall_triangles, tall_retire, NULL};
    isomend_volume d;
    isomend_volume_init(&d, NULL, ISOMEND_U8, 64, 64, nz);
    isomend_stream *s = NULL;
    CHECK_EQ_INT(isomend_stream_begin(&d, &o, &sink, &s), ISOMEND_OK);
    uint8_t slice[2][4096];
    tall_slice(slice[0], 0);
    tall_slice(slice[1], 1);
    isomend_status st = ISOMEND_OK;
    for (int64_t k = 0; k < nz && st == ISOMEND_OK; k++)
        st = isomend_stream_push(s, slice[k % 2]);
    CHECK_EQ_INT(st, ISOMEND_OK);
    CHECK_EQ_INT(isomend_stream_finish(s, &got), ISOMEND_OK);
    isomend_stream_destroy(s);
    CHECK_EQ_INT(t.errors, 0);
    CHECK(memcmp(&got, &expect, sizeof got) == 0);
    CHECK_EQ_INT(got.vertices, t.nv);
    CHECK_EQ_INT(got.triangles, t.nt);
    CHECK(t.zmax >= (float)(nz - 1) && t.zmax <= (float)nz); /* the padding's cap at the top */
    printf("tall: %lld slices, %llu cubes, %llu vertices, %llu triangles\n", (long long)nz,
           (unsigned long long)got.cubes, (unsigned long long)t.nv, (unsigned long long)t.nt);
}

#ifdef ISOMEND_TEST_NRRD
/* Slabs and boxes of a real volume (the bundled MRI, read by io/'s NRRD
 * reader), as stored (i16) and as f32, every method and flag set, at three
 * levels. */
static void test_real_volume(const char *path)
{
    isomend_fileio_info info;
    char msg[512];
    void *data = NULL;
    if (isomend_fileio_probe_nrrd(path, &info, msg, sizeof msg) != ISOMEND_FILEIO_OK ||
        isomend_fileio_load(&info, &data, NULL, NULL, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
        fprintf(stderr, "%s\n", msg);
        CHECK(0);
        return;
    }
    const size_t count = (size_t)(info.dims[0] * info.dims[1] * info.dims[2]);
    float *f32 = malloc(sizeof(float) * count);
    CHECK(info.type == ISOMEND_I16 && f32);
    for (size_t q = 0; q < count; q++)
        f32[q] = (float)((const int16_t *)data)[q];
    static const double levels[] = {3000.0, 7000.5, 9500.0};
    for (int as_f32 = 0; as_f32 < 2; as_f32++) {
        isomend_volume vol;
        isomend_volume_init(&vol, as_f32 ? (void *)f32 : data,
                            as_f32 ? ISOMEND_F32 : ISOMEND_I16, info.dims[0], info.dims[1],
                            info.dims[2]);
        for (int a = 0; a < 3; a++) {
            vol.spacing[a] = info.spacing[a];
            vol.origin[a] = info.origin[a];
        }
        for (size_t l = 0; l < sizeof levels / sizeof levels[0]; l++) {
            char what[160];
            snprintf(what, sizeof what, "%s as %s, iso %g", path, as_f32 ? "f32" : "i16",
                     levels[l]);
            compare_every_split(&vol, levels[l], 2, 4, what);
        }
    }
    free(f32);
    free(data);
}
#endif

int main(int argc, char **argv)
{
#ifdef ISOMEND_TEST_NRRD
    if (argc > 2 && strcmp(argv[1], "--nrrd") == 0) {
        test_real_volume(argv[2]);
        printf("%d extractions in pieces, %d box pieces of %s stitched to isomend_extract()'s "
               "mesh\n",
               pieces_compared, boxes_compared, argv[2]);
        TEST_EXIT();
    }
#endif
    if (argc > 1 && strcmp(argv[1], "--tall") == 0) {
        test_tall();
        TEST_EXIT();
    }
    test_memory_bound();
    test_bad_input();
    test_ids_past_2_32();
    test_all_methods_types();
    test_threads();
    printf("%d streams identical to isomend_extract() (%d on a pool of threads)\n", compared,
           pooled);
    test_pieces();
    printf("%d extractions in pieces stitched to isomend_extract()'s mesh\n", pieces_compared);
    printf("%d box pieces stitched to isomend_extract()'s mesh\n", boxes_compared);
    TEST_EXIT();
}
