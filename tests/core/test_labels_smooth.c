/*
 * test_labels_smooth.c - isomend_meshes_smooth() and isomend_meshes_decimate()
 * on a label map's meshes.  Smoothing:
 * every label's smoothed mesh keeps its triangles and stays closed,
 * manifold and oriented (isomend_mesh_check: holes, non-manifold and
 * misoriented edges, components, Euler characteristic as before); a vertex
 * that two labels share before is shared after (the same position in both,
 * bit for bit), while smoothing each label alone (isomend_mesh_smooth)
 * parts them (so the test can fail); free vertices move, the staircase
 * goes (the largest move is more than a hundredth of a voxel); each
 * label's volume stays within 1 % (no restoration: the filter alone; not
 * on the checkerboard, a one-voxel pattern that a low pass removes); 0
 * iterations changes nothing; two runs give the same bytes; bad arguments
 * are refused.  Decimation (to 0.3): each label closed with its components
 * and Euler characteristic, every vertex two labels share still a vertex of
 * both (locked), fewer triangles in all; bad arguments refused.
 *
 * Label maps: two touching boxes, three labels meeting along a line, a
 * ball inside a shell (nested), a small two-label checkerboard (every face
 * ambiguous), each padded (closed surfaces).
 */
#include "isomend.h"
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct lmap {
    const char *name;
    int n[3];
    uint8_t *v;
} lmap;

#define AT(l, i, j, k) ((l).v[(i) + (l).n[0] * ((j) + (l).n[1] * (k))])

static lmap make(const char *name, int nx, int ny, int nz)
{
    lmap l = {name, {nx, ny, nz}, calloc((size_t)nx * ny * nz, 1)};
    return l;
}

static lmap touching(void)
{
    lmap l = make("touching", 24, 18, 18);
    for (int k = 3; k < 15; k++)
        for (int j = 3; j < 15; j++)
            for (int i = 2; i < 22; i++)
                AT(l, i, j, k) = i < 11 ? 1 : 2;
    return l;
}

static lmap three(void)
{
    lmap l = make("three", 22, 22, 16);
    for (int k = 2; k < 14; k++)
        for (int j = 2; j < 20; j++)
            for (int i = 2; i < 20; i++)
                AT(l, i, j, k) = i < 11 ? (j < 11 ? 1 : 2) : 3;
    return l;
}

static lmap nested(void)
{
    lmap l = make("nested", 24, 24, 24);
    for (int k = 0; k < 24; k++)
        for (int j = 0; j < 24; j++)
            for (int i = 0; i < 24; i++) {
                const double r = sqrt((i - 11.5) * (i - 11.5) + (j - 11.5) * (j - 11.5) +
                                      (k - 11.5) * (k - 11.5));
                AT(l, i, j, k) = r < 5.2 ? 4 : r < 9.6 ? 9 : 0;
            }
    return l;
}

static lmap checker(void)
{
    lmap l = make("checkerboard", 8, 7, 6);
    for (int k = 0; k < 6; k++)
        for (int j = 0; j < 7; j++)
            for (int i = 0; i < 8; i++)
                AT(l, i, j, k) = (uint8_t)(1 + ((i + j + k) & 1));
    return l;
}

static int same_check(const isomend_check_report *a, const isomend_check_report *b)
{
    return a->hole_edges == b->hole_edges && a->border_edges == b->border_edges && a->nonmanifold_edges == b->nonmanifold_edges &&
           a->misoriented_edges == b->misoriented_edges && a->components == b->components &&
           a->euler == b->euler;
}

/* Pairs (a in mesh p, b in mesh q) of vertices at one position in the input. */
typedef struct shared {
    size_t p, a, q, b;
} shared;

static size_t find_shared(const isomend_mesh *const *m, size_t n, shared *out, size_t cap)
{
    size_t count = 0;
    for (size_t p = 0; p < n; p++)
        for (size_t q = p + 1; q < n; q++) {
            const float *pp = isomend_mesh_positions(m[p]), *qp = isomend_mesh_positions(m[q]);
            for (size_t a = 0; a < isomend_mesh_vertex_count(m[p]); a++)
                for (size_t b = 0; b < isomend_mesh_vertex_count(m[q]); b++)
                    if (memcmp(pp + 3 * a, qp + 3 * b, 12) == 0 && count < cap)
                        out[count++] = (shared){p, a, q, b};
        }
    return count;
}

static int same_position(const isomend_mesh *const *m, const shared *s)
{
    return memcmp(isomend_mesh_positions(m[s->p]) + 3 * s->a,
                  isomend_mesh_positions(m[s->q]) + 3 * s->b, 12) == 0;
}

/* Every label of map l, padded (DMC): the result, its meshes in in[] (at
 * most 8), their count in *n; NULL on failure (recorded). */
static isomend_labels *extract_padded(lmap l, const isomend_mesh **in, size_t *n)
{
    isomend_volume vol;
    isomend_volume_init(&vol, l.v, ISOMEND_U8, l.n[0], l.n[1], l.n[2]);
    isomend_options o;
    isomend_options_init(&o);
    o.flags |= ISOMEND_FLAG_PAD;
    isomend_labels *r = NULL;
    CHECK(isomend_labels_extract(&vol, NULL, 0, &o, &r) == ISOMEND_OK);
    if (!r)
        return NULL;
    *n = isomend_labels_count(r);
    CHECK(*n >= 2 && *n <= 8);
    for (size_t q = 0; q < *n && q < 8; q++)
        in[q] = isomend_labels_mesh(r, q);
    return r;
}

static void run(lmap l, int iterations)
{
    const isomend_mesh *in[8];
    size_t n = 0;
    isomend_labels *r = extract_padded(l, in, &n);
    if (!r)
        return;
    isomend_mesh *out[8] = {0}, *again[8] = {0}, *alone[8] = {0};
    isomend_smooth_report rep[8];
    enum { CAP = 200000 };
    shared *sh = malloc(CAP * sizeof(shared));
    const size_t nsh = find_shared(in, n, sh, CAP);
    CHECK(nsh > 0);

    CHECK(isomend_meshes_smooth(in, n, iterations, out, rep) == ISOMEND_OK);
    CHECK(isomend_meshes_smooth(in, n, iterations, again, NULL) == ISOMEND_OK);
    for (size_t q = 0; q < n; q++) {
        if (!out[q] || !again[q])
            goto next;
        CHECK(isomend_mesh_smooth(in[q], iterations, &alone[q], NULL) == ISOMEND_OK);
        const size_t nv = isomend_mesh_vertex_count(in[q]), nt = isomend_mesh_triangle_count(in[q]);
        CHECK_EQ_INT(isomend_mesh_vertex_count(out[q]), nv);
        CHECK_EQ_INT(isomend_mesh_triangle_count(out[q]), nt);
        CHECK(memcmp(isomend_mesh_triangles(out[q]), isomend_mesh_triangles(in[q]), 12 * nt) == 0);
        CHECK(memcmp(isomend_mesh_positions(out[q]), isomend_mesh_positions(again[q]), 12 * nv) == 0);
        isomend_check_report c0, c1;
        CHECK(isomend_mesh_check(in[q], &c0) == ISOMEND_OK);
        CHECK(isomend_mesh_check(out[q], &c1) == ISOMEND_OK);
        CHECK(c1.hole_edges == 0 && c1.border_edges == 0 && c1.nonmanifold_edges == 0 && c1.misoriented_edges == 0);
        CHECK(same_check(&c0, &c1));
        const double dv = fabs(rep[q].volume_after - rep[q].volume_before) / fabs(rep[q].volume_before);
        printf("%s label %lld, %d iterations: %zu vertices, moved %llu, largest move %.3f, "
               "volume %.1f -> %.1f (%+.3f %%)\n",
               l.name, (long long)isomend_labels_value(r, q), iterations, nv,
               (unsigned long long)rep[q].moved_vertices, rep[q].max_displacement,
               rep[q].volume_before, rep[q].volume_after,
               100 * (rep[q].volume_after - rep[q].volume_before) / rep[q].volume_before);
        if (iterations == 0) {
            CHECK(memcmp(isomend_mesh_positions(out[q]), isomend_mesh_positions(in[q]), 12 * nv) == 0);
        } else {
            CHECK(rep[q].moved_vertices > 0);
            CHECK(rep[q].max_displacement > 0.01);
            if (strcmp(l.name, "checkerboard") != 0) /* a one-voxel pattern: the filter's stop band */
                CHECK(dv < 0.01);
        }
    }
    /* shared before, shared after; alone, parted */
    size_t parted = 0;
    for (size_t s = 0; s < nsh; s++) {
        CHECK(same_position((const isomend_mesh *const *)out, &sh[s]));
        parted += alone[sh[s].p] && alone[sh[s].q] && !same_position((const isomend_mesh *const *)alone, &sh[s]);
    }
    if (iterations > 0)
        CHECK(parted > 0);
    printf("%s: %zu shared vertices, all shared after; %zu parted when each label is smoothed alone\n",
           l.name, nsh, parted);
next:
    for (size_t q = 0; q < n; q++) {
        isomend_mesh_destroy(out[q]);
        isomend_mesh_destroy(again[q]);
        isomend_mesh_destroy(alone[q]);
    }
    free(sh);
    isomend_labels_destroy(r);
}

/* Decimated together: each label closed with its topology, every vertex
 * two labels share still in both (locked), fewer triangles in all. */
static void run_decimate(lmap l, double ratio)
{
    const isomend_mesh *in[8];
    size_t n = 0;
    isomend_labels *r = extract_padded(l, in, &n);
    if (!r)
        return;
    isomend_mesh *out[8] = {0};
    isomend_decimate_report rep[8];
    enum { CAP = 200000 };
    shared *sh = malloc(CAP * sizeof(shared));
    const size_t nsh = find_shared(in, n, sh, CAP);
    isomend_decimate_options d;
    isomend_decimate_options_init(&d);
    d.ratio = ratio;
    CHECK(isomend_meshes_decimate(in, n, &d, out, rep) == ISOMEND_OK);
    size_t before = 0, after = 0;
    for (size_t q = 0; q < n; q++) {
        if (!out[q])
            goto next;
        isomend_check_report c0, c1;
        CHECK(isomend_mesh_check(in[q], &c0) == ISOMEND_OK);
        CHECK(isomend_mesh_check(out[q], &c1) == ISOMEND_OK);
        CHECK(c1.hole_edges == 0 && c1.border_edges == 0 && c1.nonmanifold_edges == 0 &&
              c1.misoriented_edges == 0);
        CHECK(same_check(&c0, &c1));
        before += isomend_mesh_triangle_count(in[q]);
        after += isomend_mesh_triangle_count(out[q]);
        CHECK_EQ_INT(rep[q].triangles_after, isomend_mesh_triangle_count(out[q]));
    }
    /* every shared position still a vertex of both meshes */
    size_t lost = 0;
    for (size_t s = 0; s < nsh; s++) {
        const float *p = isomend_mesh_positions(in[sh[s].p]) + 3 * sh[s].a;
        for (int side = 0; side < 2; side++) {
            const isomend_mesh *m = out[side ? sh[s].q : sh[s].p];
            size_t v = 0;
            while (v < isomend_mesh_vertex_count(m) && memcmp(isomend_mesh_positions(m) + 3 * v, p, 12))
                v++;
            lost += v == isomend_mesh_vertex_count(m);
        }
    }
    CHECK_EQ_INT(lost, 0);
    CHECK(after < before);
    printf("%s decimated to %.2f together: %zu -> %zu triangles, %zu shared vertices kept in both\n",
           l.name, ratio, before, after, nsh);
next:
    for (size_t q = 0; q < n; q++)
        isomend_mesh_destroy(out[q]);
    free(sh);
    isomend_labels_destroy(r);
}

int main(void)
{
    lmap maps[] = {touching(), three(), nested(), checker()};
    for (size_t i = 0; i < sizeof maps / sizeof maps[0]; i++) {
        run(maps[i], 0);
        run(maps[i], 5);
        run(maps[i], 20);
        if (strcmp(maps[i].name, "checkerboard") != 0) /* (all shared: nothing to decimate) */
            run_decimate(maps[i], 0.3);
        free(maps[i].v);
    }
    /* refused */
    isomend_mesh *out[1] = {0};
    const isomend_mesh *none[1] = {NULL};
    CHECK(isomend_meshes_smooth(none, 1, 5, out, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(out[0] == NULL);
    CHECK(isomend_meshes_smooth(NULL, 1, 5, out, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_meshes_smooth(none, 0, -1, out, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_meshes_smooth(none, 0, 10001, out, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_meshes_smooth(none, 0, 5, NULL, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_meshes_smooth(none, 0, 5, out, NULL) == ISOMEND_OK);
    isomend_decimate_options d;
    isomend_decimate_options_init(&d);
    CHECK(isomend_meshes_decimate(none, 0, &d, out, NULL) == ISOMEND_ERR_INVALID_ARGUMENT); /* no target */
    d.ratio = 0.5;
    CHECK(isomend_meshes_decimate(none, 1, &d, out, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_meshes_decimate(none, 0, NULL, out, NULL) == ISOMEND_ERR_INVALID_ARGUMENT);
    CHECK(isomend_meshes_decimate(none, 0, &d, out, NULL) == ISOMEND_OK);
    TEST_EXIT();
}
