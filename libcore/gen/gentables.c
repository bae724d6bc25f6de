/*
 * gentables.c - builds isomend's 256-case marching cubes table from the 15
 * elementary cases, as the thesis asks (objective 4: "algorithmic construction
 * of the polygon connectivity table"; chapter 3.1 and Appendix A).
 *
 * The only hand-written data are the 15 elementary triangulations below.
 * Everything else is derived:
 *
 *   1. The rotation group of the cube is generated from two quarter-turns
 *      (about x and about z) by closure under composition: 24 elements.
 *   2. Each elementary case (its positive corners and triangles, <= 4
 *      positive corners) is moved by every rotation; corners and edges are
 *      permuted together, so the winding is kept (rotations are proper).
 *      The orbits cover the 163 configurations with 0..4 positive corners.
 *   3. A configuration with 5..8 positive corners takes the triangles of its
 *      complement (inversion symmetry) with the winding reversed, so normals
 *      still point from positive to negative corners.
 *   4. For every configuration and every ambiguous face, the directed face
 *      segments of its triangles are recorded in loop order (p->q, r->s):
 *      the mending quadrilateral of an inverted combination is (s, r, q, p),
 *      whose edges are the reverse of the hole's (see extract.c).
 *
 * The elementary triangulations separate the positive corners on every
 * ambiguous face (the intersection points are joined around each positive
 * corner).  That makes the thesis's rule exact: two cubes sharing an
 * ambiguous face disagree on it iff exactly one has 5+ positive corners.
 *
 * Usage: isomend_gentables [OUTPUT]   (default: standard output)
 * The output is committed as libcore/src/mc_tables.inc; the ctest
 * "core_tables_regenerate" reruns this program and compares.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../src/cube.h"

/* ------------------------------------------------- hand-written data */

/*
 * The 15 elementary cases of Lorensen & Cline in the thesis's Appendix A
 * (set M, thesis labels 1..8) and their triangulations, as triples of edge
 * numbers (cube.h), wound counter-clockwise seen from the negative side.
 */
typedef struct elementary_case {
    int labels[4];  /* thesis labels of the positive corners, 0-terminated */
    int ntri;
    int tri[4][3];
} elementary_case;

static const elementary_case elementary[15] = {
    /* 0  {}        */ {{0}, 0, {{0}}},
    /* 1  {4}       */ {{4}, 1, {{1, 10, 4}}},
    /* 2  {4,3}     */ {{4, 3}, 2, {{5, 11, 10}, {5, 10, 4}}},
    /* 3  {2,4}     */ {{2, 4}, 2, {{0, 9, 5}, {1, 10, 4}}},
    /* 4  {4,8}     */ {{4, 8}, 2, {{1, 10, 4}, {7, 9, 2}}},
    /* 5  {3,5,6}   */ {{3, 5, 6}, 3, {{5, 7, 6}, {5, 6, 10}, {5, 10, 1}}},
    /* 6  {4,3,8}   */ {{4, 3, 8}, 3, {{7, 9, 2}, {5, 11, 10}, {5, 10, 4}}},
    /* 7  {1,3,8}   */ {{1, 3, 8}, 3, {{4, 8, 0}, {5, 11, 1}, {7, 9, 2}}},
    /* 8  {3,4,5,6} */ {{3, 4, 5, 6}, 2, {{5, 7, 6}, {5, 6, 4}}},
    /* 9  {4,5,6,7} */ {{4, 5, 6, 7}, 4, {{1, 11, 7}, {1, 7, 2}, {1, 2, 8}, {1, 8, 4}}},
    /* 10 {1,4,5,8} */ {{1, 4, 5, 8}, 4, {{1, 10, 8}, {1, 8, 0}, {3, 11, 9}, {3, 9, 2}}},
    /* 11 {4,5,6,8} */ {{4, 5, 6, 8}, 4, {{1, 11, 9}, {1, 9, 2}, {1, 2, 6}, {1, 6, 4}}},
    /* 12 {1,3,5,6} */ {{1, 3, 5, 6}, 4, {{4, 8, 0}, {5, 7, 6}, {5, 6, 10}, {5, 10, 1}}},
    /* 13 {4,5,2,7} */ {{4, 5, 2, 7}, 4, {{0, 9, 5}, {1, 10, 4}, {2, 8, 6}, {3, 11, 7}}},
    /* 14 {3,5,6,7} */ {{3, 5, 6, 7}, 4, {{5, 7, 2}, {5, 2, 8}, {5, 8, 10}, {5, 10, 1}}},
};

/* ------------------------------------------------------- derivation */

#define MAX_TRI 4

typedef struct entry {
    int set;
    int elementary;
    int ntri;
    int tri[MAX_TRI][3];
    int face_loop[6][4]; /* p, q, r, s per ambiguous face, else -1 */
} entry;

static entry table[256];
static int group[24][8]; /* corner permutations */
static int ngroup;

static void fail(const char *msg)
{
    fprintf(stderr, "gentables: %s\n", msg);
    exit(1);
}

static int corner_at(int x, int y, int z) { return x | (y << 1) | (z << 2); }

/* Quarter-turn about x: (x, y, z) -> (x, 1 - z, y); about z: -> (1 - y, x, z). */
static void quarter_turns(int rx[8], int rz[8])
{
    for (int c = 0; c < 8; c++) {
        int x = CUBE_CORNER_X(c), y = CUBE_CORNER_Y(c), z = CUBE_CORNER_Z(c);
        rx[c] = corner_at(x, 1 - z, y);
        rz[c] = corner_at(1 - y, x, z);
    }
}

static int group_find(const int p[8])
{
    for (int i = 0; i < ngroup; i++)
        if (memcmp(group[i], p, sizeof(group[i])) == 0)
            return i;
    return -1;
}

static void build_group(void)
{
    int gen[2][8];
    quarter_turns(gen[0], gen[1]);
    for (int c = 0; c < 8; c++)
        group[0][c] = c;
    ngroup = 1;
    for (int i = 0; i < ngroup; i++) { /* breadth-first closure */
        for (int g = 0; g < 2; g++) {
            int p[8];
            for (int c = 0; c < 8; c++)
                p[c] = gen[g][group[i][c]];
            if (group_find(p) < 0) {
                if (ngroup == 24)
                    fail("rotation group has more than 24 elements");
                memcpy(group[ngroup++], p, sizeof(p));
            }
        }
    }
    if (ngroup != 24)
        fail("rotation group does not have 24 elements");
}

static int edge_between(int a, int b)
{
    for (int e = 0; e < 12; e++)
        if ((cube_edge_corner[e][0] == a && cube_edge_corner[e][1] == b) ||
            (cube_edge_corner[e][0] == b && cube_edge_corner[e][1] == a))
            return e;
    return -1;
}

static int popcount8(unsigned v)
{
    int n = 0;
    for (; v; v &= v - 1)
        n++;
    return n;
}

static int edge_on_face(int e, int f)
{
    for (int i = 0; i < 4; i++)
        if (cube_face_edge[f][i] == e)
            return 1;
    return 0;
}

static int face_is_ambiguous(unsigned config, int f)
{
    int s[4];
    for (int i = 0; i < 4; i++)
        s[i] = (config >> cube_face_corner[f][i]) & 1;
    return s[0] == s[2] && s[1] == s[3] && s[0] != s[1];
}

/* Records, for each ambiguous face, the directed segments of the triangles. */
static void find_face_loops(entry *en, unsigned config)
{
    for (int f = 0; f < 6; f++) {
        for (int i = 0; i < 4; i++)
            en->face_loop[f][i] = -1;
        if (!face_is_ambiguous(config, f))
            continue;
        int seg[2][2], nseg = 0;
        for (int t = 0; t < en->ntri; t++)
            for (int i = 0; i < 3; i++) {
                int a = en->tri[t][i], b = en->tri[t][(i + 1) % 3];
                if (edge_on_face(a, f) && edge_on_face(b, f)) {
                    if (nseg == 2)
                        fail("more than two segments on an ambiguous face");
                    seg[nseg][0] = a;
                    seg[nseg][1] = b;
                    nseg++;
                }
            }
        if (nseg != 2)
            fail("an ambiguous face without two segments");
        en->face_loop[f][0] = seg[0][0];
        en->face_loop[f][1] = seg[0][1];
        en->face_loop[f][2] = seg[1][0];
        en->face_loop[f][3] = seg[1][1];
    }
}

static void build_table(void)
{
    for (int k = 0; k < 15; k++) {
        const elementary_case *ec = &elementary[k];
        unsigned config = 0;
        for (int i = 0; i < 4 && ec->labels[i]; i++)
            config |= 1u << cube_thesis_label_corner[ec->labels[i]];
        for (int g = 0; g < ngroup; g++) {
            unsigned rc = 0;
            for (int c = 0; c < 8; c++)
                if ((config >> c) & 1)
                    rc |= 1u << group[g][c];
            entry *en = &table[rc];
            if (en->set) {
                if (en->elementary != k)
                    fail("two elementary cases share a rotation orbit");
                continue;
            }
            en->set = 1;
            en->elementary = k;
            en->ntri = ec->ntri;
            for (int t = 0; t < ec->ntri; t++)
                for (int i = 0; i < 3; i++) {
                    int e = ec->tri[t][i];
                    int a = group[g][cube_edge_corner[e][0]];
                    int b = group[g][cube_edge_corner[e][1]];
                    en->tri[t][i] = edge_between(a, b);
                }
        }
    }
    for (unsigned c = 0; c < 256; c++) {
        if (popcount8(c) <= 4) {
            if (!table[c].set)
                fail("a configuration with <= 4 positive corners is in no orbit");
            continue;
        }
        const entry *src = &table[255 - c];
        entry *en = &table[c];
        en->set = 1;
        en->elementary = src->elementary;
        en->ntri = src->ntri;
        for (int t = 0; t < src->ntri; t++) { /* inversion: reverse the winding */
            en->tri[t][0] = src->tri[t][0];
            en->tri[t][1] = src->tri[t][2];
            en->tri[t][2] = src->tri[t][1];
        }
    }
    for (unsigned c = 0; c < 256; c++)
        find_face_loops(&table[c], c);
}

/* ----------------------------------------------------------- output */

static void emit(FILE *out)
{
    fprintf(out, "/*\n * mc_tables.inc - GENERATED by libcore/gen/gentables.c, DO NOT EDIT.\n"
                 " *\n"
                 " * The marching cubes table of isomend, derived from the 15 elementary\n"
                 " * triangulations by the 24 cube rotations and inversion.  Numbering of\n"
                 " * corners, edges and faces: libcore/src/cube.h; declarations: tables.h.\n"
                 " */\n\n");

    fprintf(out, "/* Elementary case (0..14) of each configuration. */\n");
    fprintf(out, "const unsigned char mc_case_of[256] = {");
    for (int c = 0; c < 256; c++)
        fprintf(out, "%s%2d,", c % 16 ? " " : "\n    ", table[c].elementary);
    fprintf(out, "\n};\n\n");

    fprintf(out, "/* Number of triangles of each configuration. */\n");
    fprintf(out, "const unsigned char mc_tri_count[256] = {");
    for (int c = 0; c < 256; c++)
        fprintf(out, "%s%d,", c % 16 ? " " : "\n    ", table[c].ntri);
    fprintf(out, "\n};\n\n");

    fprintf(out, "/* Triangles of each configuration as edge triples, -1 padded. */\n");
    fprintf(out, "const signed char mc_tri_edges[256][%d] = {\n", 3 * MAX_TRI);
    for (int c = 0; c < 256; c++) {
        fprintf(out, "    {");
        for (int i = 0; i < 3 * MAX_TRI; i++) {
            int v = i / 3 < table[c].ntri ? table[c].tri[i / 3][i % 3] : -1;
            fprintf(out, "%s%d", i ? "," : "", v);
        }
        fprintf(out, "}, /* 0x%02x case %d */\n", c, table[c].elementary);
    }
    fprintf(out, "};\n\n");

    fprintf(out, "/* Ambiguous faces of each configuration, bit f for face f. */\n");
    fprintf(out, "const unsigned char mc_ambiguous_faces[256] = {");
    for (int c = 0; c < 256; c++) {
        int m = 0;
        for (int f = 0; f < 6; f++)
            m |= face_is_ambiguous((unsigned)c, f) << f;
        fprintf(out, "%s0x%02x,", c % 12 ? " " : "\n    ", m);
    }
    fprintf(out, "\n};\n\n");

    fprintf(out, "/*\n * Directed face segments p->q, r->s of each configuration on each\n"
                 " * ambiguous face (edge numbers, in loop order), -1 elsewhere.\n */\n");
    fprintf(out, "const signed char mc_face_loop[256][6][4] = {\n");
    for (int c = 0; c < 256; c++) {
        fprintf(out, "    {");
        for (int f = 0; f < 6; f++) {
            const int *l = table[c].face_loop[f];
            fprintf(out, "%s{%d,%d,%d,%d}", f ? "," : "", l[0], l[1], l[2], l[3]);
        }
        fprintf(out, "},\n");
    }
    fprintf(out, "};\n");
}

int main(int argc, char **argv)
{
    build_group();
    build_table();
    FILE *out = stdout;
    if (argc > 1) {
        out = fopen(argv[1], "w");
        if (!out) {
            perror(argv[1]);
            return 1;
        }
    }
    emit(out);
    if (out != stdout && fclose(out) != 0) {
        perror(argv[1]);
        return 1;
    }
    return 0;
}
