/*
 * test_labels.c - label maps (isomend_labels_*): every label's mesh from
 * the one pass equals isomend_extract()'s on the label's indicator (u8
 * 0/1, iso 0.5, the same method and flags) byte for byte; the same for
 * 1, 2, 3 and 5 threads and for every label type; DMC's and Durst's
 * padded meshes closed (no hole, no once-used edge), DMC's 2-manifold and
 * oriented; touching labels share their boundary's vertex positions; the
 * labels present and the voxel counts; bad arguments refused.
 *
 * Volumes: two touching boxes, a one-voxel checkerboard of two labels (the
 * worst case: every face ambiguous), nested spheres, 200 Voronoi cells,
 * random labels in blocks and as noise, negative and 32-bit values.
 */
#include "isomend.h"
#include "meshcmp.h"
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct lvol {
    int64_t n[3];
    int64_t *v; /* x fastest */
    const char *name;
} lvol;

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static uint64_t rng(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return rng_state;
}

static lvol make(const char *name, int64_t nx, int64_t ny, int64_t nz)
{
    lvol l = {{nx, ny, nz}, calloc((size_t)(nx * ny * nz), sizeof(int64_t)), name};
    return l;
}

#define AT(l, i, j, k) ((l).v[(i) + (l).n[0] * ((j) + (l).n[1] * (k))])

static lvol touching(void)
{
    lvol l = make("touching", 14, 11, 12);
    for (int64_t k = 2; k < 9; k++)
        for (int64_t j = 2; j < 9; j++)
            for (int64_t i = 1; i < 12; i++)
                AT(l, i, j, k) = i < 6 ? 3 : 7;
    AT(l, 6, 5, 5) = 3; /* a bump of 3 into 7 */
    return l;
}

static lvol checkerboard(void)
{
    lvol l = make("checkerboard", 9, 8, 7);
    for (int64_t k = 0; k < 7; k++)
        for (int64_t j = 0; j < 8; j++)
            for (int64_t i = 0; i < 9; i++)
                AT(l, i, j, k) = ((i + j + k) & 1) ? 1 : 2;
    return l;
}

static lvol nested(void)
{
    lvol l = make("nested", 17, 16, 15);
    for (int64_t k = 0; k < 15; k++)
        for (int64_t j = 0; j < 16; j++)
            for (int64_t i = 0; i < 17; i++) {
                const double r =
                    sqrt((i - 8.2) * (i - 8.2) + (j - 7.6) * (j - 7.6) + (k - 7.1) * (k - 7.1));
                AT(l, i, j, k) = r < 3.0 ? 5 : r < 5.2 ? 4 : r < 7.0 ? 1 : 0;
            }
    return l;
}

static lvol voronoi(int cells, int64_t n)
{
    lvol l = make("voronoi", n, n - 2, n + 1);
    double seed[256][3];
    for (int c = 0; c < cells; c++)
        for (int a = 0; a < 3; a++)
            seed[c][a] = (double)(rng() % 10000) / 10000.0 * (double)l.n[a];
    for (int64_t k = 0; k < l.n[2]; k++)
        for (int64_t j = 0; j < l.n[1]; j++)
            for (int64_t i = 0; i < l.n[0]; i++) {
                int best = 0;
                double bd = 1e30;
                for (int c = 0; c < cells; c++) {
                    const double d = (i - seed[c][0]) * (i - seed[c][0]) +
                                     (j - seed[c][1]) * (j - seed[c][1]) +
                                     (k - seed[c][2]) * (k - seed[c][2]);
                    if (d < bd) {
                        bd = d;
                        best = c;
                    }
                }
                AT(l, i, j, k) = best + 1;
            }
    return l;
}

static lvol noise(int labels, int64_t n, int block)
{
    lvol l = make(block > 1 ? "blocks" : "noise", n + 1, n, n - 1);
    for (int64_t k = 0; k < l.n[2]; k++)
        for (int64_t j = 0; j < l.n[1]; j++)
            for (int64_t i = 0; i < l.n[0]; i++) {
                if (block > 1 && (i % block || j % block || k % block)) {
                    AT(l, i, j, k) = AT(l, i - i % block, j - j % block, k - k % block);
                    continue;
                }
                AT(l, i, j, k) = (int64_t)(rng() % (uint64_t)labels);
            }
    return l;
}

/* The label volume as samples of `type`, values shifted by `offset`. */
static void *as_type(const lvol *l, isomend_type type, int64_t offset)
{
    const size_t n = (size_t)(l->n[0] * l->n[1] * l->n[2]);
    const size_t size = type == ISOMEND_U32 ? 4 : isomend_type_size(type);
    char *p = malloc(n * size);
    for (size_t q = 0; q < n; q++) {
        const int64_t v = l->v[q] + offset;
        switch ((int)type) {
        case ISOMEND_U8: ((uint8_t *)p)[q] = (uint8_t)v; break;
        case ISOMEND_I8: ((int8_t *)p)[q] = (int8_t)v; break;
        case ISOMEND_U16: ((uint16_t *)(void *)p)[q] = (uint16_t)v; break;
        case ISOMEND_I16: ((int16_t *)(void *)p)[q] = (int16_t)v; break;
        case ISOMEND_U32: ((uint32_t *)(void *)p)[q] = (uint32_t)v; break;
        default: ((int32_t *)(void *)p)[q] = (int32_t)v; break;
        }
    }
    return p;
}

/* The meshes of labels of l by isomend_extract() on each indicator. */
static isomend_mesh *indicator_mesh(const lvol *l, int64_t label, const isomend_options *o)
{
    const size_t n = (size_t)(l->n[0] * l->n[1] * l->n[2]);
    uint8_t *ind = malloc(n);
    for (size_t q = 0; q < n; q++)
        ind[q] = l->v[q] == label;
    isomend_volume vol;
    isomend_volume_init(&vol, ind, ISOMEND_U8, l->n[0], l->n[1], l->n[2]);
    vol.spacing[0] = 0.5;
    vol.spacing[1] = 1.25;
    vol.spacing[2] = 2.0;
    vol.origin[0] = -3.0;
    vol.origin[2] = 7.5;
    isomend_options io = *o;
    io.iso = 0.5;
    io.threads = 1;
    isomend_mesh *m = NULL;
    CHECK(isomend_extract(&vol, &io, &m, NULL) == ISOMEND_OK);
    free(ind);
    return m;
}

static void label_volume(isomend_volume *vol, const void *data, isomend_type type, const lvol *l)
{
    isomend_volume_init(vol, data, type, l->n[0], l->n[1], l->n[2]);
    vol->spacing[0] = 0.5;
    vol->spacing[1] = 1.25;
    vol->spacing[2] = 2.0;
    vol->origin[0] = -3.0;
    vol->origin[2] = 7.5;
}

/* A padded DMC mesh: closed, every edge used twice in opposite directions. */
static void check_closed(const isomend_mesh *m, isomend_method method, const char *what)
{
    isomend_check_report r;
    CHECK(isomend_mesh_check(m, &r) == ISOMEND_OK);
    if (r.hole_edges || r.border_edges || r.nonmanifold_edges || r.misoriented_edges ||
        r.degenerate_triangles || r.triangles == 0) {
        fprintf(stderr, "%s: %s not closed: holes %llu border %llu 3+ %llu misoriented %llu\n",
                what, isomend_method_name(method), (unsigned long long)r.hole_edges,
                (unsigned long long)r.border_edges, (unsigned long long)r.nonmanifold_edges,
                (unsigned long long)r.misoriented_edges);
        tu_failures++;
    }
}

static int cmp_f3(const void *a, const void *b)
{
    return memcmp(a, b, 12);
}

/* Touching labels A, B: every midpoint of a grid edge between an A and a B
 * sample is a vertex of both meshes, at the same position. */
static void check_shared(const lvol *l, const isomend_volume *vol, const isomend_labels *r,
                         size_t ia, size_t ib, int pad)
{
    const int64_t A = isomend_labels_value(r, ia), B = isomend_labels_value(r, ib);
    const isomend_mesh *ma = isomend_labels_mesh(r, ia), *mb = isomend_labels_mesh(r, ib);
    size_t na = isomend_mesh_vertex_count(ma), nb = isomend_mesh_vertex_count(mb);
    float *pa = malloc(12 * (na + 1)), *pb = malloc(12 * (nb + 1));
    memcpy(pa, isomend_mesh_positions(ma), 12 * na);
    memcpy(pb, isomend_mesh_positions(mb), 12 * nb);
    qsort(pa, na, 12, cmp_f3);
    qsort(pb, nb, 12, cmp_f3);
    size_t shared = 0;
    for (int64_t k = 0; k < l->n[2]; k++)
        for (int64_t j = 0; j < l->n[1]; j++)
            for (int64_t i = 0; i < l->n[0]; i++)
                for (int a = 0; a < 3; a++) {
                    int64_t q[3] = {i, j, k};
                    q[a]++;
                    if (q[a] >= l->n[a])
                        continue;
                    const int64_t u = AT(*l, i, j, k), w = AT(*l, q[0], q[1], q[2]);
                    if (!((u == A && w == B) || (u == B && w == A)))
                        continue;
                    float p[3];
                    for (int c = 0; c < 3; c++) { /* the marched grid's formula */
                        const double o = vol->origin[c] - pad * vol->spacing[c];
                        const double x = (double)((c == 0   ? i
                                                   : c == 1 ? j
                                                            : k) +
                                                  pad) +
                                         (c == a ? 0.5 : 0.0);
                        p[c] = (float)(o + x * vol->spacing[c]);
                    }
                    CHECK(bsearch(p, pa, na, 12, cmp_f3) != NULL);
                    CHECK(bsearch(p, pb, nb, 12, cmp_f3) != NULL);
                    shared++;
                }
    CHECK(shared > 0);
    free(pa);
    free(pb);
}

static int64_t count_value(const lvol *l, int64_t v)
{
    int64_t n = 0;
    for (int64_t q = 0; q < l->n[0] * l->n[1] * l->n[2]; q++)
        n += l->v[q] == v;
    return n;
}

/* Every check on one volume; returns the triangles of all labels (DMC). */
static void run_volume(const lvol *l, const int64_t *labels, size_t count, int thorough)
{
    static const isomend_method methods[] = {ISOMEND_METHOD_DMC, ISOMEND_METHOD_DURST,
                                             ISOMEND_METHOD_MC};
    static const unsigned flag_sets[] = {ISOMEND_FLAG_PAD, 0, ISOMEND_FLAG_PAD | ISOMEND_FLAG_FLIP,
                                         ISOMEND_FLAG_NO_NORMALS | ISOMEND_FLAG_NO_ORIGINS};
    void *u8 = as_type(l, ISOMEND_U8, 0);
    for (size_t mi = 0; mi < 3; mi++)
        for (size_t fi = 0; fi < 4; fi++) {
            if (!thorough && (mi || fi > 1))
                continue;
            isomend_options o;
            isomend_options_init(&o);
            o.method = methods[mi];
            o.flags = flag_sets[fi];
            o.threads = 1;
            isomend_volume vol;
            label_volume(&vol, u8, ISOMEND_U8, l);
            isomend_labels *r = NULL;
            CHECK(isomend_labels_extract(&vol, labels, count, &o, &r) == ISOMEND_OK);
            if (!r)
                continue;
            const size_t n = isomend_labels_count(r);
            CHECK(labels ? n == count : n > 0);
            for (size_t q = 0; q < n; q++) {
                const int64_t L = isomend_labels_value(r, q);
                const isomend_mesh *m = isomend_labels_mesh(r, q);
                CHECK_EQ_INT(isomend_labels_voxels(r, q), count_value(l, L));
                isomend_mesh *ref = indicator_mesh(l, L, &o);
                if (!same_mesh(m, ref)) {
                    fprintf(stderr,
                            "%s: label %lld (%s, flags %u): %zu/%zu triangles, not "
                            "isomend_extract()'s %zu/%zu\n",
                            l->name, (long long)L, isomend_method_name(o.method), o.flags,
                            isomend_mesh_vertex_count(m), isomend_mesh_triangle_count(m),
                            isomend_mesh_vertex_count(ref), isomend_mesh_triangle_count(ref));
                    tu_failures++;
                }
                isomend_mesh_destroy(ref);
                /* (Durst's quadrilaterals may lie on segments the cubes already
                 * share: edges used once and 3 times, README "The thesis reproduced") */
                if ((o.flags & ISOMEND_FLAG_PAD) && o.method == ISOMEND_METHOD_DMC &&
                    isomend_labels_voxels(r, q))
                    check_closed(m, o.method, l->name);
            }
            /* streamed, a slice at a time: the same bytes */
            {
                int64_t *values = malloc(sizeof(int64_t) * (n + 1));
                for (size_t q = 0; q < n; q++)
                    values[q] = isomend_labels_value(r, q);
                isomend_labels_stream *st = NULL;
                isomend_volume desc = vol;
                desc.data = NULL;
                CHECK(isomend_labels_stream_begin(&desc, values, n, &o, &st) == ISOMEND_OK);
                for (int64_t k = 0; st && k < l->n[2]; k++)
                    CHECK(isomend_labels_stream_push(st, (const uint8_t *)u8 +
                                                             k * l->n[0] * l->n[1]) == ISOMEND_OK);
                isomend_labels *rs = NULL;
                CHECK(isomend_labels_stream_finish(st, &rs) == ISOMEND_OK);
                CHECK(isomend_labels_count(rs) == n);
                for (size_t q = 0; rs && q < n; q++) {
                    CHECK(isomend_labels_voxels(rs, q) == isomend_labels_voxels(r, q));
                    if (!same_mesh(isomend_labels_mesh(rs, q), isomend_labels_mesh(r, q))) {
                        fprintf(stderr, "%s: label %lld streamed differs\n", l->name,
                                (long long)values[q]);
                        tu_failures++;
                    }
                }
                isomend_labels_destroy(rs);
                isomend_labels_stream_destroy(st);
                free(values);
            }
            /* other thread counts: the same bytes */
            for (int t = 2; t <= 5 && (thorough || t == 2); t += t == 3 ? 2 : 1) {
                o.threads = t;
                isomend_labels *r2 = NULL;
                CHECK(isomend_labels_extract(&vol, labels, count, &o, &r2) == ISOMEND_OK);
                CHECK(isomend_labels_count(r2) == n);
                for (size_t q = 0; r2 && q < n; q++)
                    CHECK(same_mesh(isomend_labels_mesh(r, q), isomend_labels_mesh(r2, q)));
                isomend_labels_destroy(r2);
            }
            /* neighbours share their boundary's vertices */
            if (fi == 0 && mi == 0 && n >= 2) {
                for (size_t a = 0; a + 1 < n && a < 4; a++)
                    for (size_t b = a + 1; b < n && b < 5; b++) {
                        const int64_t A = isomend_labels_value(r, a),
                                      B = isomend_labels_value(r, b);
                        int touch = 0; /* only pairs that touch along an edge */
                        for (int64_t q = 0; q + 1 < l->n[0] * l->n[1] * l->n[2] && !touch; q++)
                            touch = (l->v[q] == A && l->v[q + 1] == B && (q + 1) % l->n[0] != 0) ||
                                    (l->v[q] == B && l->v[q + 1] == A && (q + 1) % l->n[0] != 0);
                        if (touch)
                            check_shared(l, &vol, r, a, b, 1);
                    }
            }
            isomend_labels_destroy(r);
        }
    /* every label type gives the same meshes (values shifted where the type
     * needs it: the meshes do not depend on the values) */
    static const isomend_type types[] = {ISOMEND_I8, ISOMEND_U16, ISOMEND_I16, ISOMEND_U32,
                                         ISOMEND_I32};
    int64_t max = 0;
    for (int64_t q = 0; q < l->n[0] * l->n[1] * l->n[2]; q++)
        max = l->v[q] > max ? l->v[q] : max;
    isomend_options o;
    isomend_options_init(&o);
    o.flags = ISOMEND_FLAG_PAD;
    o.threads = 2;
    isomend_volume vol;
    label_volume(&vol, u8, ISOMEND_U8, l);
    isomend_labels *r0 = NULL;
    CHECK(isomend_labels_extract(&vol, labels, count, &o, &r0) == ISOMEND_OK);
    for (size_t ti = 0; ti < sizeof types / sizeof types[0]; ti++) {
        const isomend_type t = types[ti];
        const int64_t offset = t == ISOMEND_I8    ? -100
                               : t == ISOMEND_I16 ? -30000
                               : t == ISOMEND_U32 ? 4000000000ll - max
                               : t == ISOMEND_I32 ? -2000000000ll
                                                  : 1000;
        if (t == ISOMEND_I8 && max > 200)
            continue;
        void *data = as_type(l, t, offset);
        const size_t n = isomend_labels_count(r0);
        int64_t *shifted = malloc(sizeof(int64_t) * (n + 1));
        for (size_t q = 0; q < n; q++)
            shifted[q] = isomend_labels_value(r0, q) + offset;
        label_volume(&vol, data, t, l);
        isomend_labels *r = NULL;
        CHECK(isomend_labels_extract(&vol, shifted, n, &o, &r) == ISOMEND_OK);
        for (size_t q = 0; r && q < n; q++) {
            CHECK(isomend_labels_value(r, q) == shifted[q]);
            CHECK(isomend_labels_voxels(r, q) == isomend_labels_voxels(r0, q));
            if (!same_mesh(isomend_labels_mesh(r, q), isomend_labels_mesh(r0, q))) {
                fprintf(stderr, "%s: type %d label %lld differs from u8\n", l->name, (int)t,
                        (long long)shifted[q]);
                tu_failures++;
            }
        }
        isomend_labels_destroy(r);
        free(shifted);
        free(data);
    }
    isomend_labels_destroy(r0);
    free(u8);
}

/* labels NULL: every label present but 0, ascending; isomend_labels_present. */
static void check_present(const lvol *l)
{
    static const isomend_type types[] = {ISOMEND_U8, ISOMEND_I16, ISOMEND_U32, ISOMEND_I32};
    for (size_t ti = 0; ti < 4; ti++) {
        const int64_t offset = types[ti] == ISOMEND_I16 ? -7 : types[ti] == ISOMEND_I32 ? -3 : 0;
        void *data = as_type(l, types[ti], offset);
        isomend_volume vol;
        label_volume(&vol, data, types[ti], l);
        size_t n = 0;
        CHECK(isomend_labels_present(&vol, NULL, NULL, 0, &n) == ISOMEND_OK);
        int64_t *values = malloc(sizeof(int64_t) * (n + 1));
        uint64_t *voxels = malloc(sizeof(uint64_t) * (n + 1));
        size_t n2 = 0;
        CHECK(isomend_labels_present(&vol, values, voxels, n, &n2) == ISOMEND_OK);
        CHECK(n2 == n);
        uint64_t total = 0;
        for (size_t q = 0; q < n; q++) {
            CHECK(q == 0 || values[q] > values[q - 1]);
            CHECK_EQ_INT(voxels[q], count_value(l, values[q] - offset));
            total += voxels[q];
        }
        CHECK_EQ_INT(total, l->n[0] * l->n[1] * l->n[2]);
        isomend_labels *r = NULL;
        CHECK(isomend_labels_extract(&vol, NULL, 0, NULL, &r) == ISOMEND_OK);
        size_t q = 0;
        for (size_t p = 0; p < n; p++) {
            if (values[p] == 0)
                continue;
            CHECK(isomend_labels_value(r, q) == values[p]);
            CHECK(isomend_labels_voxels(r, q) == voxels[p]);
            q++;
        }
        CHECK(isomend_labels_count(r) == q);
        isomend_labels_destroy(r);
        free(values);
        free(voxels);
        free(data);
    }
}

static int cancel_at_once(void *user, double f)
{
    (void)f;
    (*(int *)user)++;
    return 1;
}

static void check_errors(void)
{
    lvol l = checkerboard();
    void *u8 = as_type(&l, ISOMEND_U8, 0);
    isomend_volume vol;
    label_volume(&vol, u8, ISOMEND_U8, &l);
    isomend_labels *r = (isomend_labels *)&l;
    const int64_t one[2] = {1, 1};
    CHECK(isomend_labels_extract(&vol, one, 2, NULL, &r) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(r == NULL);
    CHECK(isomend_labels_extract(&vol, NULL, 1, NULL, &r) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_labels_extract(&vol, one, 1, NULL, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_labels_extract(NULL, one, 1, NULL, &r) == ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_options o;
    isomend_options_init(&o);
    o.method = ISOMEND_METHOD_MC33;
    CHECK(isomend_labels_extract(&vol, one, 1, &o, &r) == ISOMEND_ERR_UNSUPPORTED);
    o.method = ISOMEND_METHOD_FACIAL;
    CHECK(isomend_labels_extract(&vol, one, 1, &o, &r) == ISOMEND_ERR_UNSUPPORTED);
    o.method = (isomend_method)99;
    CHECK(isomend_labels_extract(&vol, one, 1, &o, &r) == ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_options_init(&o);
    o.flags = 0x100;
    CHECK(isomend_labels_extract(&vol, one, 1, &o, &r) == ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_volume bad = vol;
    bad.type = ISOMEND_F32;
    CHECK(isomend_labels_extract(&bad, one, 1, NULL, &r) == ISOMEND_ERR_INVALID_ARGUMENT);
    size_t n = 7;
    CHECK(isomend_labels_present(&bad, NULL, NULL, 0, &n) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(n == 0);
    bad = vol;
    bad.dims[2] = 1;
    CHECK(isomend_labels_extract(&bad, one, 1, NULL, &r) == ISOMEND_ERR_BAD_DIMENSIONS);
    isomend_options_init(&o);
    o.flags = ISOMEND_FLAG_PAD; /* one slice is a volume with padding */
    CHECK(isomend_labels_extract(&bad, one, 1, &o, &r) == ISOMEND_OK);
    CHECK(isomend_mesh_triangle_count(isomend_labels_mesh(r, 0)) > 0);
    isomend_labels_destroy(r);
    bad = vol;
    bad.spacing[1] = 0.0;
    CHECK(isomend_labels_extract(&bad, one, 1, NULL, &r) == ISOMEND_ERR_BAD_SPACING);
    bad = vol;
    double so[3 * 7] = {0};
    for (int k = 0; k < 7; k++)
        so[3 * k + 2] = k;
    bad.slice_origins = so;
    CHECK(isomend_labels_extract(&bad, one, 1, NULL, &r) == ISOMEND_ERR_UNSUPPORTED);
    /* a label absent: an empty mesh */
    const int64_t absent[2] = {2, 77};
    CHECK(isomend_labels_extract(&vol, absent, 2, NULL, &r) == ISOMEND_OK);
    CHECK(isomend_labels_voxels(r, 1) == 0 && isomend_labels_mesh(r, 1) &&
          isomend_mesh_triangle_count(isomend_labels_mesh(r, 1)) == 0);
    CHECK(isomend_mesh_triangle_count(isomend_labels_mesh(r, 0)) > 0);
    CHECK(isomend_labels_mesh(r, 2) == NULL && isomend_labels_value(r, 2) == 0);
    /* a mesh handed over outlives the result (ASan: no double free, no leak) */
    isomend_mesh *taken = isomend_labels_take_mesh(r, 0);
    CHECK(taken && isomend_labels_mesh(r, 0) == NULL && isomend_labels_take_mesh(r, 0) == NULL);
    CHECK(isomend_labels_take_mesh(r, 2) == NULL && isomend_labels_take_mesh(NULL, 0) == NULL);
    CHECK(isomend_labels_voxels(r, 0) > 0 && isomend_labels_value(r, 0) == 2);
    const size_t taken_nt = isomend_mesh_triangle_count(taken);
    isomend_labels_destroy(r);
    CHECK(isomend_mesh_triangle_count(taken) == taken_nt && taken_nt > 0);
    isomend_mesh_destroy(taken);
    isomend_labels_destroy(NULL);
    CHECK(isomend_labels_count(NULL) == 0);
    /* streams: labels required, the slice count kept */
    isomend_labels_stream *st = NULL;
    isomend_volume desc = vol;
    desc.data = NULL;
    CHECK(isomend_labels_stream_begin(&desc, NULL, 0, NULL, &st) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(st == NULL);
    desc.type = ISOMEND_F64;
    CHECK(isomend_labels_stream_begin(&desc, one, 1, NULL, &st) == ISOMEND_ERR_INVALID_ARGUMENT);
    desc.type = ISOMEND_U8;
    CHECK(isomend_labels_stream_begin(&desc, one, 1, NULL, &st) == ISOMEND_OK);
    for (int k = 0; k < 7; k++)
        CHECK(isomend_labels_stream_push(st, (const uint8_t *)u8 + k * 72) == ISOMEND_OK);
    CHECK(isomend_labels_stream_push(st, u8) == ISOMEND_ERR_SLICE_COUNT);
    CHECK(isomend_labels_stream_push(st, u8) == ISOMEND_ERR_SLICE_COUNT); /* sticky */
    CHECK(isomend_labels_stream_finish(st, &r) == ISOMEND_ERR_SLICE_COUNT && r == NULL);
    CHECK(isomend_labels_stream_finish(st, &r) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_labels_stream_push(st, u8) == ISOMEND_ERR_INVALID_ARGUMENT);
    isomend_labels_stream_destroy(st);
    CHECK(isomend_labels_stream_begin(&desc, one, 1, NULL, &st) == ISOMEND_OK);
    CHECK(isomend_labels_stream_push(st, u8) == ISOMEND_OK);
    CHECK(isomend_labels_stream_finish(st, &r) == ISOMEND_ERR_SLICE_COUNT && r == NULL);
    isomend_labels_stream_destroy(st);
    isomend_labels_stream_destroy(NULL);
    /* progress: cancelled at the first call (after 16 slices) */
    lvol big = voronoi(12, 20);
    void *b8 = as_type(&big, ISOMEND_U8, 0);
    label_volume(&vol, b8, ISOMEND_U8, &big);
    int calls = 0;
    isomend_options_init(&o);
    o.threads = 1;
    o.progress = cancel_at_once;
    o.progress_user = &calls;
    r = (isomend_labels *)&l;
    CHECK(isomend_labels_extract(&vol, NULL, 0, &o, &r) == ISOMEND_ERR_CANCELLED);
    CHECK(r == NULL && calls == 1);
    /* a negative stride (x reversed): the reversed volume's meshes */
    lvol rev = make("reversed", big.n[0], big.n[1], big.n[2]);
    for (int64_t k = 0; k < big.n[2]; k++)
        for (int64_t j = 0; j < big.n[1]; j++)
            for (int64_t i = 0; i < big.n[0]; i++)
                AT(rev, i, j, k) = AT(big, big.n[0] - 1 - i, j, k);
    label_volume(&vol, (uint8_t *)b8 + big.n[0] - 1, ISOMEND_U8, &big);
    vol.strides[0] = -1;
    vol.strides[1] = big.n[0];
    vol.strides[2] = big.n[0] * big.n[1];
    isomend_options_init(&o);
    o.flags = ISOMEND_FLAG_PAD;
    CHECK(isomend_labels_extract(&vol, NULL, 0, &o, &r) == ISOMEND_OK);
    for (size_t q = 0; r && q < isomend_labels_count(r); q++) {
        isomend_mesh *ref = indicator_mesh(&rev, isomend_labels_value(r, q), &o);
        CHECK(same_mesh(isomend_labels_mesh(r, q), ref));
        isomend_mesh_destroy(ref);
    }
    isomend_labels_destroy(r);
    free(rev.v);
    free(b8);
    free(big.v);
    free(u8);
    free(l.v);
}

int main(void)
{
    lvol t = touching(), c = checkerboard(), ne = nested();
    const int64_t tl[2] = {7, 3}, cl[2] = {1, 2}, nl[4] = {1, 4, 5, 0};
    run_volume(&t, tl, 2, 1);
    run_volume(&c, cl, 2, 1);
    run_volume(&ne, nl, 4, 1);
    run_volume(&ne, NULL, 0, 0);
    lvol v = voronoi(200, 30);
    run_volume(&v, NULL, 0, 0);
    lvol bl = noise(9, 16, 2), no = noise(5, 11, 1);
    run_volume(&bl, NULL, 0, 1);
    run_volume(&no, NULL, 0, 1);
    lvol thin = make("thin", 9, 8, 2); /* two slices: one layer, or three with padding */
    for (int64_t q = 0; q < 9 * 8 * 2; q++)
        thin.v[q] = (int64_t)(rng() % 3);
    run_volume(&thin, NULL, 0, 1);
    free(thin.v);
    check_present(&v);
    check_present(&no);
    check_errors();
    free(t.v);
    free(c.v);
    free(ne.v);
    free(v.v);
    free(bl.v);
    free(no.v);
    TEST_EXIT();
}
