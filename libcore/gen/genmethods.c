/*
 * genmethods.c - generates libcore/src/methods_tables.inc, the tables of the
 * face-decision methods (facial, gradient, asymptotic), Marching Cubes 33 and
 * the five-tetrahedron decomposition.  Nothing in those tables is typed by
 * hand: everything below is derived from the cube numbering of cube.h.
 *
 * The face-tracing engine.  Given a configuration (bit c = corner c positive)
 * and a decision for every ambiguous face (join the two positive corners
 * through the face, or separate them), each face of the cube carries 0, 1 or
 * 2 segments between the intersection points of its edges.  A segment p->q on
 * a face is directed so that the positive side lies in the direction
 * (q - p) x n, n the face's outward normal; in the neighbouring cube the same
 * face has the opposite normal, so the neighbour uses the segment q->p and
 * the two cubes' surfaces glue into an oriented surface.  Every intersection
 * point lies on two faces and is the head of one segment and the tail of
 * another, so the segments form closed directed polygons.
 *
 * Disks.  Each polygon is filled with a disk: a minimum-length triangulation
 * (dynamic programming over chords) that never uses a chord between two
 * points lying on one common face of the cube.  Such a chord could be chosen
 * by the neighbour too (an edge used four times); any other chord belongs to
 * this cube alone.  When no such triangulation exists the polygon is fanned
 * from the cube's centre vertex (slot METHODS_SLOT_CENTRE).  Triangles keep
 * the polygon's cyclic order, which points the normals towards the negative
 * side: the triangle (e0, e4, e8) cutting off corner 0 is the reference.
 *
 * Tubes (MC33).  The polygons split the cube's surface into regions, each of
 * one sign; the regions and polygons form a tree.  Inside the cube the
 * trilinear interpolant may connect two regions of the same sign X1, X2 that
 * are both adjacent to one region N of the other sign (Chernyaev's tunnels:
 * cases 4.1.2, 6.1.2, 7.4.2, 10.1.2, 12.1.2, 13.5.2 and their inverses).
 * Then the two disks spanning the polygons X1|N and X2|N are replaced by a
 * tube (annulus) joining the polygons, a strip of triangles whose rungs again
 * avoid pairs of points on one face.  For every configuration and face
 * decision the generator lists all such candidate tubes with the corners of
 * X1 and X2, so that the runtime only has to say which regions its interior
 * test finds connected.
 *
 * Tetrahedra.  The cube is cut into five tetrahedra: one central tetrahedron
 * on the four corners whose grid parity (i + j + k of the corner) is even and
 * four corner tetrahedra.  Neighbouring cubes therefore use the same diagonal
 * on their shared face (the one joining the even corners): the decomposition
 * is mirrored between neighbours.  Each tetrahedron is cut as in marching
 * tetrahedra; intersection points on face diagonals use slots 12..17.
 *
 * Every generated entry is checked before it is written: each internal edge
 * is used once in each direction, every boundary edge is one of the face
 * segments in its direction, and no triangle repeats a vertex.
 *
 * Usage: isomend_genmethods OUTPUT.inc
 */
#include "../src/cube.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SLOT_DIAG0 12
#define SLOT_CENTRE 18
#define SLOT_RING0 19 /* 19 + e: halfway between the centre and edge e's point */
#define NSLOTS 31

#define MAX_TRI_POOL 200000
#define MAX_POLY 8
#define MAX_PV 12

static void die(const char *msg, unsigned config, unsigned join)
{
    fprintf(stderr, "genmethods: %s (configuration %u, face decision %#x)\n", msg, config, join);
    exit(1);
}

/* ---------------------------------------------------------- geometry */

static void corner_pos(int c, double p[3])
{
    p[0] = CUBE_CORNER_X(c);
    p[1] = CUBE_CORNER_Y(c);
    p[2] = CUBE_CORNER_Z(c);
}

/* Position of a slot with every intersection at the middle of its edge. */
static void slot_pos(int s, double p[3])
{
    double a[3], b[3];
    if (s < 12) {
        corner_pos(cube_edge_corner[s][0], a);
        corner_pos(cube_edge_corner[s][1], b);
    } else if (s < SLOT_CENTRE) {
        /* Face diagonal: any diagonal of the face has the same midpoint. */
        corner_pos(cube_face_corner[s - SLOT_DIAG0][0], a);
        corner_pos(cube_face_corner[s - SLOT_DIAG0][2], b);
    } else if (s == SLOT_CENTRE) {
        p[0] = p[1] = p[2] = 0.5;
        return;
    } else {
        slot_pos(s - SLOT_RING0, p);
        for (int i = 0; i < 3; i++)
            p[i] = 0.5 * (p[i] + 0.5);
        return;
    }
    for (int i = 0; i < 3; i++)
        p[i] = 0.5 * (a[i] + b[i]);
}

static double dist(int s, int t)
{
    double a[3], b[3];
    slot_pos(s, a);
    slot_pos(t, b);
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                (a[2] - b[2]) * (a[2] - b[2]));
}

/* Bit mask of the faces an edge lies on. */
static unsigned edge_faces(int e)
{
    unsigned m = 0;
    for (int f = 0; f < 6; f++)
        for (int i = 0; i < 4; i++)
            if (cube_face_edge[f][i] == e)
                m |= 1u << f;
    return m;
}

/* A chord or rung between edge points sharing a face could be chosen by the
 * neighbouring cube as well; forbid it. */
static int chord_allowed(int s, int t)
{
    if (s >= 12 || t >= 12)
        return 1; /* private to the cube */
    return (edge_faces(s) & edge_faces(t)) == 0;
}

static int popcount(unsigned x)
{
    int n = 0;
    for (; x; x &= x - 1)
        n++;
    return n;
}

/* Face f of a configuration is ambiguous when its positive corners are
 * exactly one diagonal. */
static int face_ambiguous(unsigned config, int f)
{
    const unsigned char *q = cube_face_corner[f];
    int s0 = (config >> q[0]) & 1, s1 = (config >> q[1]) & 1, s2 = (config >> q[2]) & 1,
        s3 = (config >> q[3]) & 1;
    return s0 == s2 && s1 == s3 && s0 != s1;
}

static unsigned ambiguous_mask(unsigned config)
{
    unsigned m = 0;
    for (int f = 0; f < 6; f++)
        if (face_ambiguous(config, f))
            m |= 1u << f;
    return m;
}

/* ------------------------------------------------------ face segments */

typedef struct trace {
    int next[12];             /* next[e]: head of the segment leaving e, -1 */
    int npoly;
    int plen[MAX_POLY];
    int poly[MAX_POLY][MAX_PV];
    int poly_of[12];          /* polygon of each intersected edge         */
    int region_of_corner[8];  /* region index of each corner              */
    int nregion;
    unsigned region_corners[8];
    int region_sign[8];
    int poly_region[MAX_POLY][2]; /* positive region, negative region     */
} trace;

/* Adds the directed segment between edge points a, b of face f such that the
 * corner `ref` (of sign `ref_positive`) ends up on its correct side. */
static void add_segment(trace *t, int f, int a, int b, int ref, int ref_positive, unsigned config,
                        unsigned join)
{
    double pa[3], pb[3], pr[3], n[3] = {0, 0, 0}, d[3], cr[3];
    slot_pos(a, pa);
    slot_pos(b, pb);
    corner_pos(ref, pr);
    n[f / 2] = (f & 1) ? 1.0 : -1.0;
    for (int i = 0; i < 3; i++)
        d[i] = pb[i] - pa[i];
    cr[0] = d[1] * n[2] - d[2] * n[1];
    cr[1] = d[2] * n[0] - d[0] * n[2];
    cr[2] = d[0] * n[1] - d[1] * n[0];
    double side = cr[0] * (pr[0] - pa[0]) + cr[1] * (pr[1] - pa[1]) + cr[2] * (pr[2] - pa[2]);
    if (side == 0)
        die("degenerate segment", config, join);
    int from = a, to = b;
    if ((side > 0) != (ref_positive != 0)) {
        from = b;
        to = a;
    }
    if (t->next[from] != -1)
        die("two segments leave one point", config, join);
    t->next[from] = to;
}

static int find(int *parent, int x)
{
    while (parent[x] != x)
        x = parent[x] = parent[parent[x]];
    return x;
}

static void unite(int *parent, int a, int b)
{
    a = find(parent, a);
    b = find(parent, b);
    if (a != b)
        parent[a] = b;
}

/* Traces the polygons of a configuration under the face decisions `join`
 * (bit f set: the positive corners of ambiguous face f are joined). */
static void trace_config(unsigned config, unsigned join, trace *t)
{
    memset(t, 0, sizeof *t);
    for (int e = 0; e < 12; e++) {
        t->next[e] = -1;
        t->poly_of[e] = -1;
    }
    for (int f = 0; f < 6; f++) {
        const unsigned char *q = cube_face_corner[f];
        const unsigned char *fe = cube_face_edge[f];
        int cut[4], ncut = 0;
        for (int i = 0; i < 4; i++)
            if (((config >> q[i]) & 1) != ((config >> q[(i + 1) % 4]) & 1))
                cut[ncut++] = i;
        if (ncut == 2) {
            /* Reference: the corner after the first cut edge. */
            int ref = q[(cut[0] + 1) % 4];
            add_segment(t, f, fe[cut[0]], fe[cut[1]], ref, (config >> ref) & 1, config, join);
        } else if (ncut == 4) {
            /* Ambiguous: isolate either the positive or the negative corners.
             * Corner i of the face lies between face edges i-1 and i. */
            int joined = (join >> f) & 1;
            for (int i = 0; i < 4; i++) {
                int c = q[i];
                int positive = (config >> c) & 1;
                if (positive == joined)
                    continue; /* this corner is not isolated */
                add_segment(t, f, fe[(i + 3) % 4], fe[i], c, positive, config, join);
            }
        } else if (ncut != 0) {
            die("odd number of cut edges", config, join);
        }
    }
    /* Polygons. */
    for (int e = 0; e < 12; e++) {
        if (t->next[e] == -1 || t->poly_of[e] != -1)
            continue;
        if (t->npoly == MAX_POLY)
            die("too many polygons", config, join);
        int p = t->npoly++;
        int x = e;
        do {
            if (t->plen[p] == MAX_PV)
                die("polygon too long", config, join);
            t->poly[p][t->plen[p]++] = x;
            t->poly_of[x] = p;
            x = t->next[x];
            if (x == -1)
                die("open polygon", config, join);
        } while (x != e);
    }
    for (int e = 0; e < 12; e++) {
        int cut = ((config >> cube_edge_corner[e][0]) & 1) != ((config >> cube_edge_corner[e][1]) & 1);
        if (cut != (t->poly_of[e] != -1))
            die("cut edge outside every polygon", config, join);
    }
    /* Regions: corners of one sign connected along cube edges or across a
     * face whose decision connects that sign's diagonal. */
    int parent[8];
    for (int c = 0; c < 8; c++)
        parent[c] = c;
    for (int e = 0; e < 12; e++) {
        int a = cube_edge_corner[e][0], b = cube_edge_corner[e][1];
        if (((config >> a) & 1) == ((config >> b) & 1))
            unite(parent, a, b);
    }
    for (int f = 0; f < 6; f++) {
        if (!face_ambiguous(config, f))
            continue;
        const unsigned char *q = cube_face_corner[f];
        int joined = (join >> f) & 1;
        /* The diagonal of the sign that is joined. */
        int d = (((config >> q[0]) & 1) == (unsigned)joined) ? 0 : 1;
        unite(parent, q[d], q[d + 2]);
    }
    int index[8];
    for (int c = 0; c < 8; c++)
        index[c] = -1;
    for (int c = 0; c < 8; c++) {
        int r = find(parent, c);
        if (index[r] == -1) {
            index[r] = t->nregion;
            t->region_sign[t->nregion] = (config >> c) & 1;
            t->nregion++;
        }
        t->region_of_corner[c] = index[r];
        t->region_corners[index[r]] |= 1u << c;
    }
    for (int p = 0; p < t->npoly; p++) {
        int e = t->poly[p][0];
        int a = cube_edge_corner[e][0], b = cube_edge_corner[e][1];
        int pos = ((config >> a) & 1) ? a : b, neg = pos == a ? b : a;
        t->poly_region[p][0] = t->region_of_corner[pos];
        t->poly_region[p][1] = t->region_of_corner[neg];
        /* Every point of the polygon must border the same two regions. */
        for (int i = 1; i < t->plen[p]; i++) {
            int e2 = t->poly[p][i];
            int a2 = cube_edge_corner[e2][0], b2 = cube_edge_corner[e2][1];
            int pos2 = ((config >> a2) & 1) ? a2 : b2, neg2 = pos2 == a2 ? b2 : a2;
            if (t->region_of_corner[pos2] != t->poly_region[p][0] ||
                t->region_of_corner[neg2] != t->poly_region[p][1])
                die("polygon borders more than two regions", config, join);
        }
    }
    if (t->nregion != t->npoly + 1)
        die("regions and polygons do not form a tree", config, join);
}

/* ------------------------------------------------------- triangulation */

typedef struct tri_list {
    int n;
    unsigned char v[64][3];
} tri_list;

static void push_tri(tri_list *l, int a, int b, int c)
{
    if (l->n == 64)
        die("too many triangles", 0, 0);
    l->v[l->n][0] = (unsigned char)a;
    l->v[l->n][1] = (unsigned char)b;
    l->v[l->n][2] = (unsigned char)c;
    l->n++;
}

/* Minimum total chord length triangulation of polygon p[0..n-1] (cyclic
 * order kept); returns 0 when every triangulation needs a forbidden chord. */
static int triangulate_disk(const int *p, int n, tri_list *out)
{
    double cost[MAX_PV][MAX_PV];
    int split[MAX_PV][MAX_PV];
    const double INF = 1e30;
    for (int len = 1; len < n; len++)
        for (int i = 0; i + len < n; i++) {
            int j = i + len;
            if (len == 1) {
                cost[i][j] = 0;
                continue;
            }
            /* The side i-j is a chord unless it is the closing side 0-(n-1). */
            int is_chord = !(i == 0 && j == n - 1);
            double w = 0;
            if (is_chord) {
                if (!chord_allowed(p[i], p[j])) {
                    cost[i][j] = INF;
                    continue;
                }
                w = dist(p[i], p[j]);
            }
            double best = INF;
            int bk = -1;
            for (int k = i + 1; k < j; k++) {
                double c = cost[i][k] + cost[k][j];
                if (c < best) {
                    best = c;
                    bk = k;
                }
            }
            cost[i][j] = best >= INF ? INF : best + w;
            split[i][j] = bk;
        }
    if (cost[0][n - 1] >= INF)
        return 0;
    /* Emit with an explicit stack. */
    int stack[2 * MAX_PV][2], sp = 0;
    stack[sp][0] = 0;
    stack[sp][1] = n - 1;
    sp++;
    while (sp) {
        sp--;
        int i = stack[sp][0], j = stack[sp][1];
        if (j - i < 2)
            continue;
        int k = split[i][j];
        push_tri(out, p[i], p[k], p[j]);
        stack[sp][0] = i;
        stack[sp][1] = k;
        sp++;
        stack[sp][0] = k;
        stack[sp][1] = j;
        sp++;
    }
    return 1;
}

static void fill_disk(const int *p, int n, tri_list *out)
{
    if (n == 3) {
        push_tri(out, p[0], p[1], p[2]);
        return;
    }
    if (triangulate_disk(p, n, out))
        return;
    for (int i = 0; i < n; i++)
        push_tri(out, p[i], p[(i + 1) % n], SLOT_CENTRE);
}

/* Strip between polygons a (forward) and b (backward); 0 if impossible. */
static int triangulate_tube(const int *a, int na, const int *b, int nb, tri_list *out)
{
    const double INF = 1e30;
    double best_total = INF;
    int best_s = -1;
    static double cost[MAX_PV + 1][MAX_PV + 1];
    static int move[MAX_PV + 1][MAX_PV + 1];
    int best_move[MAX_PV + 1][MAX_PV + 1];
    for (int s = 0; s < nb; s++) {
        /* rung (i, j): a[i % na] to b[(s - j) mod nb]; from (0,0) to (na, nb). */
        for (int i = 0; i <= na; i++)
            for (int j = 0; j <= nb; j++) {
                int ai = a[i % na], bj = b[((s - j) % nb + nb) % nb];
                if (!chord_allowed(ai, bj) || (i == na && j == 0)) {
                    cost[i][j] = INF;
                    continue;
                }
                double w = dist(ai, bj);
                if (i == 0 && j == 0) {
                    cost[i][j] = w;
                    move[i][j] = -1;
                    continue;
                }
                /* The strip starts with a step along a and ends with a step
                 * along b, and (na, 0) is excluded, so that no rung other
                 * than (0, 0) = (na, nb) can occur twice. */
                double ca = i > 0 && !(i == na && j == nb) ? cost[i - 1][j] : INF;
                double cb = j > 0 && i > 0 ? cost[i][j - 1] : INF;
                if (ca <= cb) {
                    cost[i][j] = ca >= INF ? INF : ca + w;
                    move[i][j] = 0;
                } else {
                    cost[i][j] = cb >= INF ? INF : cb + w;
                    move[i][j] = 1;
                }
            }
        if (cost[na][nb] < best_total) {
            best_total = cost[na][nb];
            best_s = s;
            memcpy(best_move, move, sizeof best_move);
        }
    }
    if (best_s < 0)
        return 0;
    int s = best_s, i = na, j = nb;
    while (i > 0 || j > 0) {
        int bj = b[((s - j) % nb + nb) % nb];
        if (best_move[i][j] == 0) {
            /* advanced along a: triangle (a[i-1], a[i], b_j) */
            push_tri(out, a[(i - 1) % na], a[i % na], bj);
            i--;
        } else {
            /* advanced backwards along b: from b_(j-1) to b_j */
            int bprev = b[((s - (j - 1)) % nb + nb) % nb];
            push_tri(out, bj, bprev, a[i % na]);
            j--;
        }
    }
    return 1;
}

/* Checks that a cube's triangles form an oriented surface whose boundary is
 * exactly the face segments of `t` (directed), minus nothing. */
static void verify(const trace *t, const tri_list *l, unsigned config, unsigned join)
{
    static int used[NSLOTS][NSLOTS];
    memset(used, 0, sizeof used);
    for (int k = 0; k < l->n; k++) {
        const unsigned char *v = l->v[k];
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2])
            die("degenerate triangle", config, join);
        for (int i = 0; i < 3; i++)
            used[v[i]][v[(i + 1) % 3]]++;
    }
    for (int a = 0; a < NSLOTS; a++)
        for (int b = 0; b < NSLOTS; b++) {
            int seg = a < 12 && t->next[a] == b;
            int rseg = b < 12 && t->next[b] == a;
            if (seg) {
                if (used[a][b] != 1 || used[b][a] != 0)
                    die("face segment not a boundary edge", config, join);
            } else if (!rseg && used[a][b] + used[b][a] > 0) {
                if (used[a][b] != 1 || used[b][a] != 1)
                    die("internal edge not used once in each direction", config, join);
                if (!chord_allowed(a, b))
                    die("chord between points of one face", config, join);
            } else if (rseg && used[a][b]) {
                die("face segment reversed", config, join);
            }
        }
}

/* ---------------------------------------------------------------- output */

typedef struct poly_out {
    int tri_first, tri_count;
} poly_out;

typedef struct tube_out {
    unsigned char corners_a, corners_b; /* corners of the two regions joined */
    unsigned char sign;                 /* 1: positive regions, 0: negative */
    unsigned char poly_a, poly_b;       /* polygons (within the entry) replaced */
    int tri_first, tri_count;
} tube_out;

static unsigned char tri_pool[MAX_TRI_POOL][3];
static int ntri_pool;
static poly_out polys[20000];
static int npolys;
static tube_out tubes[20000];
static int ntubes;

typedef struct entry_out {
    int poly_first, poly_count, tube_first, tube_count, tri_count, centre;
} entry_out;

static entry_out entries[256 * 64];
static int nentries;
static int entry_base[257];
static int infeasible_tubes, ring_tubes;

static int append(const tri_list *l)
{
    int first = ntri_pool;
    if (ntri_pool + l->n > MAX_TRI_POOL)
        die("triangle pool full", 0, 0);
    for (int k = 0; k < l->n; k++)
        memcpy(tri_pool[ntri_pool++], l->v[k], 3);
    return first;
}

static void build_entry(unsigned config, unsigned join, entry_out *en)
{
    trace t;
    trace_config(config, join, &t);
    tri_list all;
    all.n = 0;
    en->poly_first = npolys;
    en->poly_count = t.npoly;
    en->centre = 0;
    tri_list disk[MAX_POLY];
    for (int p = 0; p < t.npoly; p++) {
        disk[p].n = 0;
        fill_disk(t.poly[p], t.plen[p], &disk[p]);
        polys[npolys].tri_first = append(&disk[p]);
        polys[npolys].tri_count = disk[p].n;
        npolys++;
        for (int k = 0; k < disk[p].n; k++) {
            push_tri(&all, disk[p].v[k][0], disk[p].v[k][1], disk[p].v[k][2]);
            if (disk[p].v[k][2] == SLOT_CENTRE)
                en->centre = 1;
        }
    }
    verify(&t, &all, config, join);
    en->tri_count = all.n;

    /* Candidate tubes: regions X1 != X2 of one sign, both adjacent to N. */
    en->tube_first = ntubes;
    for (int p1 = 0; p1 < t.npoly; p1++)
        for (int p2 = p1 + 1; p2 < t.npoly; p2++) {
            int shared_side = -1;
            for (int s = 0; s < 2; s++)
                if (t.poly_region[p1][s] == t.poly_region[p2][s])
                    shared_side = s;
            if (shared_side < 0)
                continue;
            /* N = the shared region; X1, X2 on the other side. */
            int other = 1 - shared_side;
            int x1 = t.poly_region[p1][other], x2 = t.poly_region[p2][other];
            tri_list tube;
            tube.n = 0;
            /* Two polygons sharing a face cannot be joined by rungs that
             * avoid that face; the trilinear interpolant never joins them
             * either (both regions would touch the face's saddle side). */
            if (!triangulate_tube(t.poly[p1], t.plen[p1], t.poly[p2], t.plen[p2], &tube)) {
                /* Every strip needs a rung inside a face: go through a ring
                 * of private vertices, polygon p1 shrunk towards the centre
                 * (slots 19 + e), with two strips. */
                int ring[MAX_PV], rrev[MAX_PV], n1 = t.plen[p1];
                for (int i = 0; i < n1; i++) {
                    ring[i] = SLOT_RING0 + t.poly[p1][i];
                    rrev[i] = SLOT_RING0 + t.poly[p1][n1 - 1 - i];
                }
                tube.n = 0;
                if (!triangulate_tube(t.poly[p1], n1, rrev, n1, &tube) ||
                    !triangulate_tube(ring, n1, t.poly[p2], t.plen[p2], &tube)) {
                    infeasible_tubes++;
                    continue;
                }
                ring_tubes++;
            }
            /* Verify the whole surface with the tube in place of two disks. */
            tri_list whole;
            whole.n = 0;
            for (int p = 0; p < t.npoly; p++)
                if (p != p1 && p != p2)
                    for (int k = 0; k < disk[p].n; k++)
                        push_tri(&whole, disk[p].v[k][0], disk[p].v[k][1], disk[p].v[k][2]);
            for (int k = 0; k < tube.n; k++)
                push_tri(&whole, tube.v[k][0], tube.v[k][1], tube.v[k][2]);
            verify(&t, &whole, config, join);
            tube_out *to = &tubes[ntubes++];
            to->corners_a = (unsigned char)t.region_corners[x1];
            to->corners_b = (unsigned char)t.region_corners[x2];
            to->sign = (unsigned char)t.region_sign[x1];
            to->poly_a = (unsigned char)p1;
            to->poly_b = (unsigned char)p2;
            to->tri_first = append(&tube);
            to->tri_count = tube.n;
        }
    en->tube_count = ntubes - en->tube_first;
}

/* Tetrahedra of the five-tetrahedron decomposition for a cube whose corner 0
 * has grid parity `parity`: the central one on the corners of even grid
 * parity, then one per odd corner with its three neighbours. */
static void tetrahedra(int parity, int tets[5][4])
{
    int even[4], ne = 0, odd[4], no = 0;
    for (int c = 0; c < 8; c++) {
        int p = (popcount((unsigned)c) + parity) & 1;
        if (p == 0)
            even[ne++] = c;
        else
            odd[no++] = c;
    }
    memcpy(tets[0], even, sizeof even);
    for (int k = 0; k < 4; k++) {
        tets[k + 1][0] = odd[k];
        int n = 1;
        for (int i = 0; i < 4; i++)
            if (popcount((unsigned)(odd[k] ^ even[i])) == 1)
                tets[k + 1][n++] = even[i];
        if (n != 4)
            die("bad tetrahedron", (unsigned)parity, 0);
    }
}

/* Slot of the segment between two corners: a cube edge or a face diagonal. */
static int pair_slot(int a, int b)
{
    for (int e = 0; e < 12; e++)
        if ((cube_edge_corner[e][0] == a && cube_edge_corner[e][1] == b) ||
            (cube_edge_corner[e][0] == b && cube_edge_corner[e][1] == a))
            return e;
    for (int f = 0; f < 6; f++) {
        const unsigned char *q = cube_face_corner[f];
        if ((q[0] == a && q[2] == b) || (q[0] == b && q[2] == a) || (q[1] == a && q[3] == b) ||
            (q[1] == b && q[3] == a))
            return SLOT_DIAG0 + f;
    }
    die("body diagonal in a tetrahedron", (unsigned)a, (unsigned)b);
    return -1;
}

/* Adds triangle a b c oriented so its normal points away from `pos`. */
static void push_oriented(tri_list *l, int a, int b, int c, const double pos[3], const double neg[3])
{
    double pa[3], pb[3], pc[3], u[3], v[3], n[3];
    slot_pos(a, pa);
    slot_pos(b, pb);
    slot_pos(c, pc);
    for (int i = 0; i < 3; i++) {
        u[i] = pb[i] - pa[i];
        v[i] = pc[i] - pa[i];
    }
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
    double d = n[0] * (neg[0] - pos[0]) + n[1] * (neg[1] - pos[1]) + n[2] * (neg[2] - pos[2]);
    if (d == 0)
        die("flat tetrahedron triangle", 0, 0);
    if (d > 0)
        push_tri(l, a, b, c);
    else
        push_tri(l, a, c, b);
}

static void tetra_config(int parity, unsigned config, tri_list *out)
{
    int tets[5][4];
    tetrahedra(parity, tets);
    out->n = 0;
    for (int k = 0; k < 5; k++) {
        int in[4], nin = 0, ou[4], nou = 0;
        double pc[3] = {0, 0, 0}, nc[3] = {0, 0, 0}, p[3];
        for (int i = 0; i < 4; i++) {
            int c = tets[k][i];
            corner_pos(c, p);
            if ((config >> c) & 1) {
                in[nin++] = c;
                for (int d = 0; d < 3; d++)
                    pc[d] += p[d];
            } else {
                ou[nou++] = c;
                for (int d = 0; d < 3; d++)
                    nc[d] += p[d];
            }
        }
        if (nin == 0 || nou == 0)
            continue;
        for (int d = 0; d < 3; d++) {
            pc[d] /= nin;
            nc[d] /= nou;
        }
        if (nin == 1)
            push_oriented(out, pair_slot(in[0], ou[0]), pair_slot(in[0], ou[1]),
                          pair_slot(in[0], ou[2]), pc, nc);
        else if (nou == 1)
            push_oriented(out, pair_slot(ou[0], in[0]), pair_slot(ou[0], in[1]),
                          pair_slot(ou[0], in[2]), pc, nc);
        else {
            /* Quad p0n0 p0n1 p1n1 p1n0, split by the diagonal p0n0-p1n1,
             * which joins opposite edges of the tetrahedron. */
            int q0 = pair_slot(in[0], ou[0]), q1 = pair_slot(in[0], ou[1]),
                q2 = pair_slot(in[1], ou[1]), q3 = pair_slot(in[1], ou[0]);
            push_oriented(out, q0, q1, q2, pc, nc);
            push_oriented(out, q0, q2, q3, pc, nc);
        }
    }
}

static void write_banner(FILE *f)
{
    fprintf(f,
            "/*\n"
            " * methods_tables.inc - GENERATED by libcore/gen/genmethods.c, DO NOT EDIT.\n"
            " *\n"
            " * Tables of the face-decision methods, Marching Cubes 33 and the\n"
            " * five-tetrahedron decomposition, traced from the cube numbering of\n"
            " * cube.h.  Layout and meaning: methods.h; how they are built: the\n"
            " * comment at the top of genmethods.c.\n"
            " */\n\n");
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: %s OUTPUT.inc\n", argv[0]);
        return 2;
    }
    int max_entry_tri = 0, centre_entries = 0, max_polys = 0, max_tubes = 0;
    for (unsigned config = 0; config < 256; config++) {
        entry_base[config] = nentries;
        unsigned amb = ambiguous_mask(config);
        int nb = popcount(amb);
        for (unsigned k = 0; k < (1u << nb); k++) {
            /* Deposit the bits of k into the ambiguous faces, low face first. */
            unsigned join = 0;
            int bit = 0;
            for (int f = 0; f < 6; f++)
                if (amb & (1u << f))
                    join |= ((k >> bit++) & 1) << f;
            entry_out *en = &entries[nentries++];
            build_entry(config, join, en);
            if (en->tri_count > max_entry_tri)
                max_entry_tri = en->tri_count;
            for (int tb = 0; tb < en->tube_count; tb++) {
                const tube_out *to = &tubes[en->tube_first + tb];
                int n = en->tri_count - polys[en->poly_first + to->poly_a].tri_count -
                        polys[en->poly_first + to->poly_b].tri_count + to->tri_count;
                if (n > max_entry_tri)
                    max_entry_tri = n;
            }
            centre_entries += en->centre;
            if (en->poly_count > max_polys)
                max_polys = en->poly_count;
            if (en->tube_count > max_tubes)
                max_tubes = en->tube_count;
        }
    }
    entry_base[256] = nentries;

    tri_list tetra[2][256];
    int max_tetra = 0;
    for (int parity = 0; parity < 2; parity++)
        for (unsigned config = 0; config < 256; config++) {
            tetra_config(parity, config, &tetra[parity][config]);
            if (tetra[parity][config].n > max_tetra)
                max_tetra = tetra[parity][config].n;
        }

    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp", argv[1]);
    FILE *f = fopen(tmp, "w");
    if (!f) {
        perror(tmp);
        return 1;
    }
    write_banner(f);
    fprintf(f, "/* %d face-decision entries, %d polygons, %d candidate tubes (%d through a\n"
               " * ring of private vertices; %d pairs of polygons have none), %d triangles;\n"
               " * %d entries fan a polygon from the centre vertex. */\n",
            nentries, npolys, ntubes, ring_tubes, infeasible_tubes, ntri_pool, centre_entries);
    fprintf(f, "#define METHODS_ENTRY_COUNT %d\n", nentries);
    fprintf(f, "#define METHODS_ENTRY_MAX_TRI %d\n", max_entry_tri);
    fprintf(f, "#define METHODS_ENTRY_MAX_POLY %d\n", max_polys);
    fprintf(f, "#define METHODS_ENTRY_MAX_TUBES %d\n", max_tubes);
    fprintf(f, "#define METHODS_TETRA_MAX_TRI %d\n\n", max_tetra);

    fprintf(f, "/* First entry of each configuration; entry base[c] + k holds face decision\n"
               " * k, the bits of k deposited into the ambiguous faces, lowest face first. */\n");
    fprintf(f, "static const unsigned short methods_entry_base[257] = {");
    for (int c = 0; c <= 256; c++)
        fprintf(f, "%s%5d,", c % 12 ? " " : "\n    ", entry_base[c]);
    fprintf(f, "\n};\n\n");

    fprintf(f, "/* Ambiguous faces of each configuration (bit f). */\n");
    fprintf(f, "static const unsigned char methods_ambiguous[256] = {");
    for (unsigned c = 0; c < 256; c++)
        fprintf(f, "%s0x%02x,", c % 12 ? " " : "\n    ", ambiguous_mask(c));
    fprintf(f, "\n};\n\n");

    fprintf(f, "/* Entries: first polygon, polygons, first tube, tubes, triangles. */\n");
    fprintf(f, "static const methods_entry methods_entries[%d] = {\n", nentries);
    for (int i = 0; i < nentries; i++)
        fprintf(f, "    {%d, %d, %d, %d, %d},\n", entries[i].poly_first, entries[i].poly_count,
                entries[i].tube_first, entries[i].tube_count, entries[i].tri_count);
    fprintf(f, "};\n\n");

    fprintf(f, "/* Polygons: first triangle, triangles (their disk). */\n");
    fprintf(f, "static const methods_poly methods_polys[%d] = {", npolys);
    for (int i = 0; i < npolys; i++)
        fprintf(f, "%s{%d, %d},", i % 6 ? " " : "\n    ", polys[i].tri_first, polys[i].tri_count);
    fprintf(f, "\n};\n\n");

    fprintf(f, "/* Candidate tubes: corners of region A, of region B, their sign,\n"
               " * the two polygons replaced, first triangle, triangles. */\n");
    fprintf(f, "static const methods_tube methods_tubes[%d] = {\n", ntubes);
    for (int i = 0; i < ntubes; i++)
        fprintf(f, "    {0x%02x, 0x%02x, %d, %d, %d, %d, %d},\n", tubes[i].corners_a,
                tubes[i].corners_b, tubes[i].sign, tubes[i].poly_a, tubes[i].poly_b,
                tubes[i].tri_first, tubes[i].tri_count);
    fprintf(f, "};\n\n");

    fprintf(f, "/* Triangle pool: three vertex slots each. */\n");
    fprintf(f, "static const unsigned char methods_tri_pool[%d][3] = {", ntri_pool);
    for (int i = 0; i < ntri_pool; i++)
        fprintf(f, "%s{%d, %d, %d},", i % 6 ? " " : "\n    ", tri_pool[i][0], tri_pool[i][1],
                tri_pool[i][2]);
    fprintf(f, "\n};\n\n");

    fprintf(f, "/* Five tetrahedra: triangle counts and triangles per parity, configuration. */\n");
    fprintf(f, "static const unsigned char methods_tetra_count[2][256] = {\n");
    for (int p = 0; p < 2; p++) {
        fprintf(f, "    {");
        for (int c = 0; c < 256; c++)
            fprintf(f, "%s%d,", c % 16 ? " " : "\n        ", tetra[p][c].n);
        fprintf(f, "\n    },\n");
    }
    fprintf(f, "};\n\n");
    fprintf(f, "static const unsigned char methods_tetra_tri[2][256][%d][3] = {\n", max_tetra);
    for (int p = 0; p < 2; p++) {
        fprintf(f, "    {\n");
        for (int c = 0; c < 256; c++) {
            fprintf(f, "        {");
            if (tetra[p][c].n == 0)
                fprintf(f, "{0, 0, 0}");
            for (int k = 0; k < tetra[p][c].n; k++)
                fprintf(f, "{%d, %d, %d}, ", tetra[p][c].v[k][0], tetra[p][c].v[k][1],
                        tetra[p][c].v[k][2]);
            fprintf(f, "},\n");
        }
        fprintf(f, "    },\n");
    }
    fprintf(f, "};\n");
    if (fclose(f) != 0 || rename(tmp, argv[1]) != 0) {
        perror(argv[1]);
        remove(tmp);
        return 1;
    }
    return 0;
}
