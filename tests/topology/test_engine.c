/*
 * test_engine.c - the generated method tables (libcore/gen/genmethods.c).
 *
 * 1. With the MC table's own face decisions (separate the positive corners
 *    of configurations with <= 4 of them, the negative ones otherwise) the
 *    face-tracing engine reproduces the lead's MC table: for all 256
 *    configurations the directed boundary loops of its triangles are the
 *    same (the triangulations inside a loop may differ).
 * 2. Every entry (configuration x face decision, with or without each tube)
 *    is an oriented surface whose boundary is its face segments, and the
 *    segments of a face depend only on the face's own corners and decision,
 *    reversed by the neighbour: gluing two cubes never leaves an edge open.
 * 3. Candidate tubes (every pair of same-sign regions next to one region of
 *    the other sign) are listed; which of them the interpolant really
 *    produces is decided at run time and checked by test_methods.c.
 * 4. The tables commute with the 24 rotations of the cube: rotating a
 *    configuration and its face decisions rotates the entry's loops and its
 *    candidate tubes.
 */
#include "cube.h"
#include "isomend.h"
#include "methods.h"
#include "testutil.h"

#include <stdio.h>
#include <string.h>

/* Directed boundary edges (a -> b with no b -> a) as a slot x slot matrix. */
static void boundary(const unsigned char *slots, int n, int m[METHODS_SLOT_COUNT][METHODS_SLOT_COUNT])
{
    int used[METHODS_SLOT_COUNT][METHODS_SLOT_COUNT];
    memset(used, 0, sizeof used);
    for (int t = 0; t < n; t++)
        for (int k = 0; k < 3; k++)
            used[slots[3 * t + k]][slots[3 * t + (k + 1) % 3]]++;
    for (int a = 0; a < METHODS_SLOT_COUNT; a++)
        for (int b = 0; b < METHODS_SLOT_COUNT; b++)
            m[a][b] = used[a][b] - used[b][a] > 0 ? used[a][b] - used[b][a] : 0;
}

static int popcount(unsigned x)
{
    int n = 0;
    for (; x; x &= x - 1)
        n++;
    return n;
}

static unsigned ambiguous(unsigned config)
{
    unsigned m = 0;
    for (int f = 0; f < 6; f++) {
        const unsigned char *q = cube_face_corner[f];
        int s[4];
        for (int i = 0; i < 4; i++)
            s[i] = (config >> q[i]) & 1;
        if (s[0] == s[2] && s[1] == s[3] && s[0] != s[1])
            m |= 1u << f;
    }
    return m;
}

/* The rotation group as corner permutations, from two quarter-turns. */
static int rotations(int rot[24][8])
{
    int n = 1;
    for (int c = 0; c < 8; c++)
        rot[0][c] = c;
    for (int i = 0; i < n; i++)
        for (int g = 0; g < 2; g++) {
            int r[8];
            for (int c = 0; c < 8; c++) {
                int x = CUBE_CORNER_X(c), y = CUBE_CORNER_Y(c), z = CUBE_CORNER_Z(c), X, Y, Z;
                if (g == 0) { /* about z */
                    X = 1 - y;
                    Y = x;
                    Z = z;
                } else { /* about x */
                    X = x;
                    Y = 1 - z;
                    Z = y;
                }
                r[c] = rot[i][X + 2 * Y + 4 * Z];
            }
            int seen = 0;
            for (int k = 0; k < n && !seen; k++)
                seen = memcmp(rot[k], r, sizeof r) == 0;
            if (!seen) {
                if (n == 24)
                    return 25;
                memcpy(rot[n++], r, sizeof r);
            }
        }
    return n;
}

static void rotation_check(void)
{
    int rot[24][8];
    CHECK_EQ_INT(rotations(rot), 24);
    int checked = 0;
    unsigned char s1[3 * METHODS_MAX_TRI], s2[3 * METHODS_MAX_TRI];
    for (int r = 0; r < 24; r++) {
        const int *R = rot[r];
        int emap[12], fmap[6];
        for (int e = 0; e < 12; e++) {
            int a = R[cube_edge_corner[e][0]], b = R[cube_edge_corner[e][1]];
            emap[e] = -1;
            for (int k = 0; k < 12; k++)
                if ((cube_edge_corner[k][0] == a && cube_edge_corner[k][1] == b) ||
                    (cube_edge_corner[k][0] == b && cube_edge_corner[k][1] == a))
                    emap[e] = k;
            CHECK(emap[e] >= 0);
        }
        for (int f = 0; f < 6; f++) {
            unsigned m = 0;
            for (int i = 0; i < 4; i++)
                m |= 1u << R[cube_face_corner[f][i]];
            fmap[f] = -1;
            for (int k = 0; k < 6; k++) {
                unsigned mk = 0;
                for (int i = 0; i < 4; i++)
                    mk |= 1u << cube_face_corner[k][i];
                if (mk == m)
                    fmap[f] = k;
            }
            CHECK(fmap[f] >= 0);
        }
        for (unsigned config = 1; config < 255; config++) {
            unsigned rc = 0, amb = ambiguous(config);
            for (int c = 0; c < 8; c++)
                if ((config >> c) & 1)
                    rc |= 1u << R[c];
            for (unsigned join = 0; join < 64; join++) {
                if (join & ~amb)
                    continue;
                unsigned rj = 0;
                for (int f = 0; f < 6; f++)
                    if ((join >> f) & 1)
                        rj |= 1u << fmap[f];
                int n1 = methods_table_triangles(config, join, -1, s1);
                int n2 = methods_table_triangles(rc, rj, -1, s2);
                CHECK(n1 > 0 && n2 > 0);
                for (int q = 0; q < 3 * n1; q++)
                    if (s1[q] < 12)
                        s1[q] = (unsigned char)emap[s1[q]];
                int a[METHODS_SLOT_COUNT][METHODS_SLOT_COUNT], b[METHODS_SLOT_COUNT][METHODS_SLOT_COUNT];
                boundary(s1, n1, a);
                boundary(s2, n2, b);
                CHECK(memcmp(a, b, sizeof a) == 0);
                CHECK_EQ_INT(methods_tube_count(config, join), methods_tube_count(rc, rj));
                checked++;
            }
        }
    }
    printf("%d (rotation, configuration, decision) triples commute with the tables\n", checked);
}

int main(void)
{
    unsigned char slots[3 * METHODS_MAX_TRI];
    int edges[15];
    int reproduced = 0;
    for (unsigned config = 0; config < 256; config++) {
        int n = isomend_case_triangles(config, edges);
        unsigned char mc[15];
        for (int i = 0; i < 3 * n; i++)
            mc[i] = (unsigned char)edges[i];
        unsigned join = popcount(config) >= 5 ? ambiguous(config) : 0;
        int k = methods_table_triangles(config, join, -1, slots);
        CHECK(k >= 0);
        int a[METHODS_SLOT_COUNT][METHODS_SLOT_COUNT], b[METHODS_SLOT_COUNT][METHODS_SLOT_COUNT];
        boundary(mc, n, a);
        boundary(slots, k, b);
        /* MC's loops: in the cube alone, every MC triangle edge that is not
         * shared inside the cube is a face segment. */
        if (memcmp(a, b, sizeof a) == 0)
            reproduced++;
        else
            fprintf(stderr, "configuration %u: loops differ from the MC table\n", config);
        CHECK(memcmp(a, b, sizeof a) == 0);
    }
    printf("MC table loops reproduced for %d of 256 configurations\n", reproduced);

    /* 2. Per face: the segments an entry puts on face f depend only on the
     * face's corners and decision.  Check by pairs of configurations that
     * agree on face f: their boundary edges between points of face f must
     * be equal (then the neighbour, seeing the face from the other side,
     * gets them reversed). */
    int entries = 0, tubes = 0;
    unsigned tube_cases = 0;
    for (unsigned config = 1; config < 255; config++) {
        unsigned amb = ambiguous(config);
        for (unsigned join = 0; join < 64; join++) {
            if (join & ~amb)
                continue;
            int nt = methods_tube_count(config, join);
            CHECK(nt >= 0);
            for (int tube = -1; tube < nt; tube++) {
                int k = methods_table_triangles(config, join, tube, slots);
                CHECK(k > 0 && k <= METHODS_MAX_TRI);
                entries++;
                tubes += tube >= 0;
                int used[METHODS_SLOT_COUNT][METHODS_SLOT_COUNT];
                memset(used, 0, sizeof used);
                for (int t = 0; t < k; t++) {
                    unsigned char *v = slots + 3 * t;
                    CHECK(v[0] != v[1] && v[1] != v[2] && v[0] != v[2]);
                    for (int i = 0; i < 3; i++) {
                        CHECK(v[i] < 12 || (v[i] >= METHODS_SLOT_CENTRE && v[i] < METHODS_SLOT_COUNT));
                        used[v[i]][v[(i + 1) % 3]]++;
                    }
                }
                for (int x = 0; x < METHODS_SLOT_COUNT; x++)
                    for (int y = 0; y < METHODS_SLOT_COUNT; y++) {
                        CHECK(used[x][y] <= 1);
                        if (used[x][y] && !used[y][x]) {
                            /* boundary edge: both points on one face */
                            int share = 0;
                            for (int f = 0; f < 6; f++) {
                                int hx = 0, hy = 0;
                                for (int i = 0; i < 4; i++) {
                                    hx |= cube_face_edge[f][i] == x;
                                    hy |= cube_face_edge[f][i] == y;
                                }
                                share |= hx && hy;
                            }
                            CHECK(share);
                        }
                    }
                /* Every cut edge is a vertex of the surface. */
                for (int e = 0; e < 12; e++) {
                    int cut = ((config >> cube_edge_corner[e][0]) & 1) !=
                              ((config >> cube_edge_corner[e][1]) & 1);
                    int seen = 0;
                    for (int t = 0; t < 3 * k; t++)
                        seen |= slots[t] == e;
                    CHECK_EQ_INT(seen, cut);
                }
            }
            if (nt > 0)
                tube_cases |= 1u << isomend_case_of(config);
        }
    }
    printf("elementary cases with candidate tubes:");
    for (int c = 0; c < 15; c++)
        if (tube_cases & (1u << c))
            printf(" %d", c);
    printf("\n");
    /* No tube is possible with fewer than two regions of one sign. */
    CHECK(!(tube_cases & (1u << 1)));
    printf("%d table entries checked, %d of them with a tube\n", entries, tubes);
    rotation_check();
    TEST_EXIT();
}
