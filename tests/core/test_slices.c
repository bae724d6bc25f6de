/*
 * Slices where they are (isomend_volume.slice_origins): random volumes on
 * grids with uneven gaps, jittered and sheared slices, for every method and
 * flag set:
 *   - the triangles (and their origins, and the vertex count) are those of
 *     the same samples on the uniform index grid;
 *   - every vertex on a grid edge is exactly (1 - t) p0 + t p1, t and the
 *     samples' true positions recomputed here in double and rounded once
 *     (the edge of each vertex from a whole-grid piece's keys, whose vertices
 *     must also be the in-memory mesh's, byte for byte);
 *   - on a linear field sampled at the true positions every vertex lies on
 *     the level plane and every normal is the field's gradient direction
 *     (the non-uniform central differences are exact for it);
 *   - the hole-free methods give closed surfaces with padding, and without
 *     it the continuity check finds the border in the sheared faces (no
 *     hole edges);
 *   - a uniform table meshes like origin and spacing (positions within
 *     rounding), and bad tables are refused.
 */
#include "isomend.h"
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng_state = 0x5eed511ce5ull;
static uint32_t rng(void)
{
    rng_state = rng_state * 6364136223846793005ull + 1442695040888963407ull;
    return (uint32_t)(rng_state >> 33);
}
static double urand(void) { return (double)rng() / 4294967296.0; }

/* Slice origins: gaps of 0.4..2.6 spacing, and per kind: 0 jitter of up to
 * 0.3 pixel in x and y, 1 a shear of tan 15 degrees along y, 2 both and a
 * gap of 2.5x (a missing slice). */
static double *make_table(const isomend_volume *vol, int kind)
{
    const int64_t nz = vol->dims[2];
    double *so = malloc(sizeof(double) * 3 * (size_t)nz);
    double z = vol->origin[2];
    for (int64_t k = 0; k < nz; k++) {
        double gap = (0.4 + 2.2 * urand()) * vol->spacing[2];
        if (kind == 2 && k == nz / 2)
            gap = 2.5 * vol->spacing[2];
        if (k > 0)
            z += gap;
        so[3 * k] = vol->origin[0] + (kind != 1 ? (urand() - 0.5) * 0.6 * vol->spacing[0] : 0.0);
        so[3 * k + 1] = vol->origin[1] + (kind != 0 ? 0.2679491924 * (z - vol->origin[2]) : 0.0) +
                        (kind == 2 ? (urand() - 0.5) * 0.6 * vol->spacing[1] : 0.0);
        so[3 * k + 2] = z;
    }
    return so;
}

/* Marched slice m's origin, padding one gap beyond the ends (isomend.h). */
static void origin_of(const isomend_volume *vol, int64_t pad, int64_t m, double o[3])
{
    const double *so = vol->slice_origins;
    const int64_t k = m - pad, n = vol->dims[2];
    for (int a = 0; a < 3; a++) {
        if (k >= 0 && k < n)
            o[a] = so[3 * k + a];
        else if (k < 0)
            o[a] = so[a] - (n > 1 ? so[3 + a] - so[a] : (a == 2 ? vol->spacing[2] : 0.0));
        else
            o[a] = so[3 * (n - 1) + a] +
                   (n > 1 ? so[3 * (n - 1) + a] - so[3 * (n - 2) + a] : (a == 2 ? vol->spacing[2] : 0.0));
    }
}

static double sample(const isomend_volume *vol, int64_t pad, const int64_t p[3])
{
    int64_t q[3];
    for (int a = 0; a < 3; a++) {
        q[a] = p[a] - pad;
        if (q[a] < 0 || q[a] >= vol->dims[a])
            return NAN;
    }
    const double *d = vol->data;
    return d[(q[2] * vol->dims[1] + q[1]) * vol->dims[0] + q[0]];
}

static void world(const isomend_volume *vol, int64_t pad, const int64_t p[3], double w[3])
{
    origin_of(vol, pad, p[2], w);
    w[0] += (double)(p[0] - pad) * vol->spacing[0];
    w[1] += (double)(p[1] - pad) * vol->spacing[1];
}

/* ---------------------------------------------------------------- a keyed sink */

typedef struct keep {
    float *pos;
    uint64_t *keys;
    size_t n, cap;
} keep;

static int on_vertices(void *user, uint64_t first, size_t count, const float *pos,
                       const float *nrm, const uint64_t *keys)
{
    (void)first;
    (void)nrm;
    keep *k = user;
    if (k->n + count > k->cap) {
        k->cap = 2 * (k->n + count);
        k->pos = realloc(k->pos, 12 * k->cap);
        k->keys = realloc(k->keys, 8 * k->cap);
    }
    memcpy(k->pos + 3 * k->n, pos, 12 * count);
    memcpy(k->keys + k->n, keys, 8 * count);
    k->n += count;
    return 0;
}
static int on_triangles(void *u, size_t c, const uint64_t *ids, const uint8_t *o)
{
    (void)u, (void)c, (void)ids, (void)o;
    return 0;
}
static int on_retire(void *u, uint64_t f)
{
    (void)u, (void)f;
    return 0;
}

/* Pushes the whole volume through a whole-grid piece (keys for every vertex). */
static int keyed_vertices(const isomend_volume *vol, const isomend_options *o, keep *k)
{
    isomend_piece piece;
    memset(&piece, 0, sizeof piece);
    piece.owned_end = vol->dims[2] + ((o->flags & ISOMEND_FLAG_PAD) ? 2 : 0);
    isomend_mesh_sink sink = {k, on_vertices, on_triangles, on_retire, NULL};
    isomend_stream *s = NULL;
    if (isomend_piece_begin(vol, o, &piece, &sink, &s) != ISOMEND_OK)
        return 0;
    const size_t plane = (size_t)(vol->dims[0] * vol->dims[1]);
    int ok = 1;
    for (int64_t z = 0; z < vol->dims[2] && ok; z++)
        ok = isomend_stream_push(s, (const double *)vol->data + plane * (size_t)z) == ISOMEND_OK;
    ok = ok && isomend_stream_finish(s, NULL) == ISOMEND_OK;
    isomend_stream_destroy(s);
    return ok;
}

/* ---------------------------------------------------------------- the tests */

static const unsigned flag_sets[] = {0, ISOMEND_FLAG_PAD, ISOMEND_FLAG_FLIP,
                                     ISOMEND_FLAG_PAD | ISOMEND_FLAG_NO_NORMALS};
static int exact_vertices, checked_meshes;

static void compare_with_index_grid(const isomend_volume *vol, double iso, const char *what)
{
    isomend_volume index = *vol;
    index.slice_origins = NULL;
    for (int m = 0; m < ISOMEND_METHOD_COUNT; m++)
        for (size_t fl = 0; fl < sizeof flag_sets / sizeof flag_sets[0]; fl++) {
            isomend_options o;
            isomend_options_init(&o);
            o.iso = iso;
            o.method = (isomend_method)m;
            o.flags = flag_sets[fl];
            o.threads = 1 + (int)(rng() % 2);
            isomend_mesh *a = NULL, *b = NULL;
            CHECK_EQ_INT(isomend_extract(vol, &o, &a, NULL), ISOMEND_OK);
            CHECK_EQ_INT(isomend_extract(&index, &o, &b, NULL), ISOMEND_OK);
            if (!a || !b) {
                isomend_mesh_destroy(a);
                isomend_mesh_destroy(b);
                continue;
            }
            const size_t nv = isomend_mesh_vertex_count(a), nt = isomend_mesh_triangle_count(a);
            CHECK_EQ_INT(nv, isomend_mesh_vertex_count(b));
            CHECK_EQ_INT(nt, isomend_mesh_triangle_count(b));
            if (nt && nt == isomend_mesh_triangle_count(b)) {
                if (memcmp(isomend_mesh_triangles(a), isomend_mesh_triangles(b), 12 * nt) ||
                    memcmp(isomend_mesh_triangle_origins(a), isomend_mesh_triangle_origins(b), nt)) {
                    fprintf(stderr, "%s %s flags %u: triangles differ from the index grid's\n",
                            what, isomend_method_name(o.method), o.flags);
                    CHECK(0);
                }
            }
            /* exact positions of the edge vertices, from a piece's keys */
            keep k = {0};
            CHECK(keyed_vertices(vol, &o, &k));
            CHECK_EQ_INT(k.n, nv);
            if (k.n == nv && nv && memcmp(k.pos, isomend_mesh_positions(a), 12 * nv)) {
                fprintf(stderr, "%s: the piece's positions differ from the mesh's\n", what);
                CHECK(0);
            }
            const int64_t pad = (o.flags & ISOMEND_FLAG_PAD) ? 1 : 0;
            const int64_t N0 = vol->dims[0] + 2 * pad, N1 = vol->dims[1] + 2 * pad;
            const float *P = isomend_mesh_positions(a);
            for (size_t v = 0; v < k.n && v < nv; v++) {
                const uint64_t key = k.keys[v];
                if (key == UINT64_MAX || (key & 7) > 2)
                    continue; /* cube-private, tetra's diagonals */
                const unsigned axis = (unsigned)(key & 7);
                const uint64_t lin = key >> 3;
                int64_t p0[3] = {(int64_t)(lin % (uint64_t)N0), (int64_t)(lin / (uint64_t)N0 % (uint64_t)N1),
                                 (int64_t)(lin / (uint64_t)N0 / (uint64_t)N1)};
                int64_t p1[3] = {p0[0], p0[1], p0[2]};
                p1[axis]++;
                const double f0 = sample(vol, pad, p0), f1 = sample(vol, pad, p1);
                const double t = isnan(f0) || isnan(f1) ? 0.5 : (iso - f0) / (f1 - f0);
                double w0[3], w1[3];
                world(vol, pad, p0, w0);
                world(vol, pad, p1, w1);
                for (int c = 0; c < 3; c++) {
                    const float want = (float)((1.0 - t) * w0[c] + t * w1[c]);
                    if (P[3 * v + c] != want) {
                        fprintf(stderr, "%s %s flags %u: vertex %zu coordinate %d is %.9g, not %.9g\n",
                                what, isomend_method_name(o.method), o.flags, v, c,
                                (double)P[3 * v + c], (double)want);
                        CHECK(0);
                        c = 3;
                    }
                }
                exact_vertices++;
            }
            free(k.pos);
            free(k.keys);
            /* hole-free methods: closed with padding, the border found without */
            if (m != ISOMEND_METHOD_MC && m != ISOMEND_METHOD_DURST) {
                isomend_check_report r;
                CHECK_EQ_INT(isomend_mesh_check(a, &r), ISOMEND_OK);
                if (r.hole_edges || r.nonmanifold_edges || r.misoriented_edges ||
                    ((o.flags & ISOMEND_FLAG_PAD) && r.border_edges)) {
                    fprintf(stderr, "%s %s flags %u: %llu hole, %llu border, %llu non-manifold, %llu misoriented edges\n",
                            what, isomend_method_name(o.method), o.flags,
                            (unsigned long long)r.hole_edges, (unsigned long long)r.border_edges,
                            (unsigned long long)r.nonmanifold_edges, (unsigned long long)r.misoriented_edges);
                    CHECK(0);
                }
                isomend_check_report rb;
                CHECK_EQ_INT(isomend_mesh_check(b, &rb), ISOMEND_OK);
                CHECK_EQ_INT(r.border_edges, rb.border_edges);
                CHECK_EQ_INT(r.euler, rb.euler);
                checked_meshes++;
            }
            isomend_mesh_destroy(a);
            isomend_mesh_destroy(b);
        }
}

static void test_random(void)
{
    for (int round = 0; round < 24; round++) {
        int64_t n[3];
        for (int a = 0; a < 3; a++)
            n[a] = 3 + (int64_t)(rng() % 12);
        const size_t count = (size_t)(n[0] * n[1] * n[2]);
        double *f = malloc(sizeof(double) * count);
        const int blobs = round % 3;
        for (int64_t k = 0; k < n[2]; k++)
            for (int64_t j = 0; j < n[1]; j++)
                for (int64_t i = 0; i < n[0]; i++) {
                    const double x = (double)i / (double)n[0] - 0.5, y = (double)j / (double)n[1] - 0.45,
                                 z = (double)k / (double)n[2] - 0.55;
                    double v = blobs == 0 ? 1.0 - 2.2 * sqrt(x * x + y * y + z * z)
                                          : urand(); /* noise: every ambiguous case */
                    if (blobs == 2)
                        v = (double)(rng() % 3) * 0.25 + 0.25; /* ties at the level */
                    f[(k * n[1] + j) * n[0] + i] = v;
                }
        isomend_volume vol;
        isomend_volume_init(&vol, f, ISOMEND_F64, n[0], n[1], n[2]);
        vol.spacing[0] = 0.7;
        vol.spacing[1] = 0.8;
        vol.spacing[2] = 2.5;
        vol.origin[0] = -12.0;
        vol.origin[1] = 30.5;
        vol.origin[2] = -61.5944;
        double *so = make_table(&vol, round % 3);
        vol.slice_origins = so;
        char what[100];
        snprintf(what, sizeof what, "round %d (%lldx%lldx%lld, table %d)", round, (long long)n[0],
                 (long long)n[1], (long long)n[2], round % 3);
        compare_with_index_grid(&vol, 0.5, what);
        free(so);
        free(f);
    }
}

/* A linear field sampled at the true positions: vertices on the plane,
 * normals along -a (central and one-sided differences are exact for it). */
static void test_linear(void)
{
    const int64_t n[3] = {9, 8, 11};
    const double a[3] = {0.3, -0.5, 0.8}, b = 0.1;
    for (int kind = 0; kind < 3; kind++) {
        isomend_volume vol;
        double *f = malloc(sizeof(double) * 9 * 8 * 11);
        isomend_volume_init(&vol, f, ISOMEND_F64, n[0], n[1], n[2]);
        vol.spacing[0] = 0.9;
        vol.spacing[1] = 0.6;
        vol.spacing[2] = 1.5;
        double *so = make_table(&vol, kind);
        vol.slice_origins = so;
        double lo = INFINITY, hi = -INFINITY;
        for (int64_t k = 0; k < n[2]; k++)
            for (int64_t j = 0; j < n[1]; j++)
                for (int64_t i = 0; i < n[0]; i++) {
                    const int64_t p[3] = {i, j, k};
                    double w[3];
                    world(&vol, 0, p, w);
                    const double v = a[0] * w[0] + a[1] * w[1] + a[2] * w[2] + b;
                    f[(k * n[1] + j) * n[0] + i] = v;
                    lo = v < lo ? v : lo;
                    hi = v > hi ? v : hi;
                }
        for (int level = 1; level < 4; level++) {
            isomend_options o;
            isomend_options_init(&o);
            o.iso = lo + (hi - lo) * level / 4.0;
            isomend_mesh *mesh = NULL;
            CHECK_EQ_INT(isomend_extract(&vol, &o, &mesh, NULL), ISOMEND_OK);
            if (!mesh)
                continue;
            const size_t nv = isomend_mesh_vertex_count(mesh);
            CHECK(nv > 0);
            const float *P = isomend_mesh_positions(mesh), *N = isomend_mesh_normals(mesh);
            const double len = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
            double worst_p = 0, worst_n = 0;
            for (size_t v = 0; v < nv; v++) {
                const double d = fabs(a[0] * P[3 * v] + a[1] * P[3 * v + 1] + a[2] * P[3 * v + 2] +
                                      b - o.iso);
                double e = 0;
                for (int c = 0; c < 3; c++)
                    e += fabs((double)N[3 * v + c] + a[c] / len);
                worst_p = d > worst_p ? d : worst_p;
                worst_n = e > worst_n ? e : worst_n;
            }
            if (worst_p > 1e-4 || worst_n > 1e-5) {
                fprintf(stderr, "linear field, table %d, level %d: off the plane by %g, normals by %g\n",
                        kind, level, worst_p, worst_n);
                CHECK(0);
            }
            isomend_mesh_destroy(mesh);
        }
        free(so);
        free(f);
    }
}

/* A uniform table is the uniform grid up to rounding; bad tables refused. */
static void test_uniform_and_bad(void)
{
    const int64_t n[3] = {12, 10, 9};
    double f[12 * 10 * 9];
    for (int q = 0; q < 12 * 10 * 9; q++)
        f[q] = urand();
    isomend_volume vol;
    isomend_volume_init(&vol, f, ISOMEND_F64, n[0], n[1], n[2]);
    vol.spacing[2] = 1.25;
    vol.origin[2] = 3.0;
    double so[27];
    for (int k = 0; k < 9; k++) {
        so[3 * k] = so[3 * k + 1] = 0.0;
        so[3 * k + 2] = 3.0 + 1.25 * k;
    }
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 0.5;
    o.flags = ISOMEND_FLAG_PAD;
    isomend_mesh *a = NULL, *b = NULL;
    CHECK_EQ_INT(isomend_extract(&vol, &o, &a, NULL), ISOMEND_OK);
    vol.slice_origins = so;
    CHECK_EQ_INT(isomend_extract(&vol, &o, &b, NULL), ISOMEND_OK);
    if (a && b) {
        CHECK_EQ_INT(isomend_mesh_vertex_count(a), isomend_mesh_vertex_count(b));
        double worst = 0;
        for (size_t q = 0; q < 3 * isomend_mesh_vertex_count(a); q++) {
            const double d = fabs((double)isomend_mesh_positions(a)[q] - isomend_mesh_positions(b)[q]);
            worst = d > worst ? d : worst;
        }
        CHECK(worst < 1e-5);
        double ba[6], bb[6];
        isomend_mesh_grid_box(a, ba);
        isomend_mesh_grid_box(b, bb);
        for (int c = 0; c < 6; c++)
            CHECK(fabs(ba[c] - bb[c]) < 1e-12);
    }
    isomend_mesh_destroy(a);
    isomend_mesh_destroy(b);
    isomend_mesh *m = NULL;
    so[3 * 4 + 2] = so[3 * 3 + 2]; /* two slices at one z */
    CHECK_EQ_INT(isomend_extract(&vol, &o, &m, NULL), ISOMEND_ERR_BAD_SPACING);
    CHECK(m == NULL);
    so[3 * 4 + 2] = so[3 * 3 + 2] - 0.5; /* going back */
    CHECK_EQ_INT(isomend_extract(&vol, &o, &m, NULL), ISOMEND_ERR_BAD_SPACING);
    so[3 * 4 + 2] = 3.0 + 5.0;
    so[3 * 6] = NAN;
    CHECK_EQ_INT(isomend_extract(&vol, &o, &m, NULL), ISOMEND_ERR_BAD_SPACING);
    isomend_stream *s = NULL;
    isomend_mesh_sink sink = {NULL, on_vertices, on_triangles, on_retire, NULL};
    CHECK_EQ_INT(isomend_stream_begin(&vol, &o, &sink, &s), ISOMEND_ERR_BAD_SPACING);
    CHECK(s == NULL);
}

int main(void)
{
    test_random();
    test_linear();
    test_uniform_and_bad();
    printf("%d exact edge vertices, %d meshes checked\n", exact_vertices, checked_meshes);
    CHECK(exact_vertices > 10000);
    TEST_EXIT();
}
