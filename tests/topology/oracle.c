/*
 * oracle.c - topology of the trilinear interpolant, independent of meshes.
 *
 * One cell.  Cut the cell by the planes x = s, s in [0, 1].  A slice is a
 * bilinear function g_s on the unit square (y, z) whose four corner values
 * move linearly with s.  Because g_s has no interior extremum, every
 * component of {g_s >= iso} contains a corner and is contractible: adjacent
 * P corners (around the square) are in one component, and when the corners
 * alternate, the two P corners are joined iff the saddle value is >= iso,
 * i.e. iff  a c - b d >= 0  (a, c the P diagonal, values minus iso).  The
 * slice structure changes only at the heights where a corner value crosses
 * iso (linear roots) or the decider a c - b d changes sign (a quadratic in
 * s).  Between two consecutive critical heights the slice components move
 * without changing (a product with an open interval); at a critical height
 * the slice is evaluated with the crossing corner, or the decider, set to
 * exactly zero (the tie rule).  Hence
 *   components: union-find over slice components, a slab component joined
 *               to the component of each bounding slice holding one of its
 *               corners (P is closed, so its corners stay in P there; for Q,
 *               open, the shared corner must be in Q in both);
 *   chi:        chi_c is additive and chi_c(X x open interval) = -chi(X), so
 *               chi(P in cell) = sum over critical slices of their component
 *               counts - sum over slabs of theirs.
 *
 * The grid.  chi(P) = sum over open cells (vertices, open edges, open faces,
 * open cubes) of chi_c(P in the open cell); each open cell's term is the
 * closed cell's chi minus the terms of its boundary cells.  Components of P
 * and Q come from the cells' corner labels by union-find over grid vertices.
 */
#include "oracle.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Cell corner c at (c & 1, (c >> 1) & 1, (c >> 2) & 1). */
static double trilinear(const double v[8], double x, double y, double z)
{
    double c00 = v[0] + x * (v[1] - v[0]), c10 = v[2] + x * (v[3] - v[2]);
    double c01 = v[4] + x * (v[5] - v[4]), c11 = v[6] + x * (v[7] - v[6]);
    double c0 = c00 + y * (c10 - c00), c1 = c01 + y * (c11 - c01);
    return c0 + z * (c1 - c0);
}

static int in_set(double w, int sign)
{
    return sign ? w >= 0 : w < 0;
}

/* Components of a square with values w[4] (minus iso) in cyclic order.
 * comp[k] = 0.. or -1; `saddle_zero` forces the decider to 0. */
static int square_components(const double w[4], int sign, int saddle_zero, int comp[4])
{
    int in[4], n = 0;
    for (int k = 0; k < 4; k++) {
        in[k] = in_set(w[k], sign);
        comp[k] = -1;
    }
    if (in[0] == in[2] && in[1] == in[3] && in[0] != in[1]) {
        /* Decider in terms of P: positive diagonal p, negative q. */
        int p = (w[0] >= 0) == (w[2] >= 0) && w[0] >= 0 ? 0 : 1;
        double dec = saddle_zero ? 0.0 : w[p] * w[p + 2] - w[p + 1] * w[(p + 3) % 4];
        int p_joined = dec >= 0;
        int joined = sign ? p_joined : !p_joined;
        int first = in[0] ? 0 : 1;
        comp[first] = 0;
        comp[first + 2] = joined ? 0 : 1;
        return joined ? 1 : 2;
    }
    int all = 1;
    for (int k = 0; k < 4; k++)
        all &= in[k];
    if (all) {
        for (int k = 0; k < 4; k++)
            comp[k] = 0;
        return 1;
    }
    /* Start just after an outside corner and number the runs. */
    int s0 = 0;
    while (in[s0])
        s0++;
    for (int i = 1; i <= 4; i++) {
        int k = (s0 + i) % 4, prev = (k + 3) % 4;
        if (!in[k])
            continue;
        comp[k] = in[prev] ? comp[prev] : n++;
    }
    return n;
}

static int uf_find(int *parent, int x)
{
    while (parent[x] != x)
        x = parent[x] = parent[parent[x]];
    return x;
}

static void uf_union(int *parent, int a, int b)
{
    a = uf_find(parent, a);
    b = uf_find(parent, b);
    if (a != b)
        parent[a] = b;
}

typedef struct crit {
    double s;
    unsigned what; /* bit k: slice corner k is zero here; bit 4: decider zero */
} crit;

static int crit_cmp(const void *a, const void *b)
{
    double x = ((const crit *)a)->s, y = ((const crit *)b)->s;
    return x < y ? -1 : x > y;
}

/* Slice corner k (cyclic in (y, z)) at x = 0 is this cell corner; +1 at x = 1. */
static const int slice_corner0[4] = {0, 2, 6, 4};

int oracle_cell(const double v[8], double iso, int sign, int label[8], long *chi)
{
    double lo[4], hi[4];
    for (int k = 0; k < 4; k++) {
        lo[k] = v[slice_corner0[k]] - iso;
        hi[k] = v[slice_corner0[k] + 1] - iso;
    }
    crit cr[16];
    int nc = 0;
    cr[nc].s = 0;
    cr[nc++].what = 0;
    cr[nc].s = 1;
    cr[nc++].what = 0;
    for (int k = 0; k < 4; k++) {
        double d = hi[k] - lo[k];
        if (d == 0)
            continue;
        double s = -lo[k] / d;
        if (s > 0 && s < 1) {
            cr[nc].s = s;
            cr[nc++].what = 1u << k;
        }
    }
    /* D(s) = w0 w2 - w1 w3 with w_k = lo_k + s (hi_k - lo_k). */
    double d[4];
    for (int k = 0; k < 4; k++)
        d[k] = hi[k] - lo[k];
    double qa = d[0] * d[2] - d[1] * d[3];
    double qb = lo[0] * d[2] + d[0] * lo[2] - lo[1] * d[3] - d[1] * lo[3];
    double qc = lo[0] * lo[2] - lo[1] * lo[3];
    double roots[2];
    int nroot = 0;
    if (qa != 0) {
        double disc = qb * qb - 4 * qa * qc;
        if (disc >= 0) {
            double r = sqrt(disc);
            roots[nroot++] = (-qb - r) / (2 * qa);
            if (r > 0)
                roots[nroot++] = (-qb + r) / (2 * qa);
        }
    } else if (qb != 0) {
        roots[nroot++] = -qc / qb;
    }
    for (int i = 0; i < nroot; i++)
        if (roots[i] > 0 && roots[i] < 1) {
            cr[nc].s = roots[i];
            cr[nc++].what = 16;
        }
    qsort(cr, (size_t)nc, sizeof cr[0], crit_cmp);
    int m = 0;
    for (int i = 0; i < nc; i++) {
        if (m > 0 && cr[i].s == cr[m - 1].s)
            cr[m - 1].what |= cr[i].what;
        else
            cr[m++] = cr[i];
    }
    nc = m;

    /* Pieces 0 .. 2nc-2: even = critical slice, odd = slab. Node 4p + k. */
    int parent[64];
    for (int i = 0; i < 64; i++)
        parent[i] = i;
    long x = 0;
    int prev[4] = {-1, -1, -1, -1};
    const int npiece = 2 * nc - 1;
    for (int p = 0; p < npiece; p++) {
        const int critical = !(p & 1);
        const crit *c = &cr[p / 2];
        double s = critical ? c->s : 0.5 * (c->s + cr[p / 2 + 1].s);
        double w[4];
        for (int k = 0; k < 4; k++) {
            w[k] = s == 0 ? lo[k] : s == 1 ? hi[k] : lo[k] + s * d[k];
            if (critical && (c->what & (1u << k)))
                w[k] = 0;
        }
        int comp[4];
        int n = square_components(w, sign, critical && (c->what & 16), comp);
        x += critical ? n : -n;
        int rep[2] = {-1, -1};
        for (int k = 0; k < 4; k++) {
            if (comp[k] < 0)
                continue;
            int node = 4 * p + k;
            if (rep[comp[k]] < 0)
                rep[comp[k]] = node;
            else
                uf_union(parent, node, rep[comp[k]]);
            if (p > 0 && prev[k] >= 0)
                uf_union(parent, node, 4 * (p - 1) + k);
        }
        memcpy(prev, comp, sizeof prev);
        if (p == 0 || p == npiece - 1)
            for (int k = 0; k < 4; k++)
                label[slice_corner0[k] + (p == 0 ? 0 : 1)] = comp[k] >= 0 ? 4 * p + k : -1;
    }
    int roots_seen[8], nr = 0;
    for (int c = 0; c < 8; c++) {
        if (label[c] < 0)
            continue;
        int r = uf_find(parent, label[c]), j = 0;
        while (j < nr && roots_seen[j] != r)
            j++;
        if (j == nr)
            roots_seen[nr++] = r;
        label[c] = j;
    }
    if (chi)
        *chi = x;
    return nr;
}

/* --------------------------------------------------------------- digital */

int oracle_cell_digital(const double v[8], double iso, int m, int sign, int label[8], long *chi)
{
    const int n = m + 1;
    const size_t total = (size_t)n * n * n;
    unsigned char *in = malloc(total);
    int *parent = malloc(total * sizeof *parent);
    if (!in || !parent) {
        free(in);
        free(parent);
        return -1;
    }
#define ID(i, j, k) ((size_t)(i) + (size_t)n * ((size_t)(j) + (size_t)n * (size_t)(k)))
    for (int k = 0; k < n; k++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                double f = trilinear(v, (double)i / m, (double)j / m, (double)k / m) - iso;
                in[ID(i, j, k)] = (unsigned char)in_set(f, sign);
                parent[ID(i, j, k)] = (int)ID(i, j, k);
            }
    long V = 0, E = 0, F = 0, C = 0;
    for (int k = 0; k < n; k++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                size_t a = ID(i, j, k);
                if (!in[a])
                    continue;
                V++;
                int ex = i + 1 < n && in[ID(i + 1, j, k)], ey = j + 1 < n && in[ID(i, j + 1, k)],
                    ez = k + 1 < n && in[ID(i, j, k + 1)];
                if (ex) {
                    E++;
                    uf_union(parent, (int)a, (int)ID(i + 1, j, k));
                }
                if (ey) {
                    E++;
                    uf_union(parent, (int)a, (int)ID(i, j + 1, k));
                }
                if (ez) {
                    E++;
                    uf_union(parent, (int)a, (int)ID(i, j, k + 1));
                }
                int sxy = ex && ey && in[ID(i + 1, j + 1, k)];
                int sxz = ex && ez && in[ID(i + 1, j, k + 1)];
                int syz = ey && ez && in[ID(i, j + 1, k + 1)];
                F += sxy + sxz + syz;
                if (sxy && sxz && syz && in[ID(i + 1, j + 1, k + 1)])
                    C++;
            }
    int roots[8], nr = 0;
    for (int c = 0; c < 8; c++) {
        size_t a = ID((c & 1) * m, ((c >> 1) & 1) * m, ((c >> 2) & 1) * m);
        if (!in[a]) {
            label[c] = -1;
            continue;
        }
        int r = uf_find(parent, (int)a), j = 0;
        while (j < nr && roots[j] != r)
            j++;
        if (j == nr)
            roots[nr++] = r;
        label[c] = j;
    }
    /* Components not touching a corner would be a bug of the sampling. */
    long comps = 0;
    for (size_t a = 0; a < total; a++)
        if (in[a] && uf_find(parent, (int)a) == (int)a)
            comps++;
#undef ID
    free(in);
    free(parent);
    if (chi)
        *chi = V - E + F - C;
    return comps == nr ? nr : (int)comps + 1000;
}

/* ------------------------------------------------------------------ grid */

int oracle_topology(const double *vals, int nx, int ny, int nz, double iso, oracle_result *r)
{
    const int X = nx + 2, Y = ny + 2, Z = nz + 2;
    const size_t N = (size_t)X * Y * Z;
    double *g = malloc(N * sizeof *g);
    int *pp = malloc(N * sizeof *pp), *pq = malloc(N * sizeof *pq);
    if (!g || !pp || !pq) {
        free(g);
        free(pp);
        free(pq);
        return -1;
    }
#define G(i, j, k) g[(size_t)(i) + (size_t)X * ((size_t)(j) + (size_t)Y * (size_t)(k))]
#define IDX(i, j, k) ((int)((i) + X * ((j) + Y * (k))))
    int bad = 0;
    for (int k = 0; k < Z; k++)
        for (int j = 0; j < Y; j++)
            for (int i = 0; i < X; i++) {
                double val = iso - 1.0;
                if (i > 0 && j > 0 && k > 0 && i <= nx && j <= ny && k <= nz) {
                    val = vals[(size_t)(i - 1) + (size_t)nx * ((size_t)(j - 1) + (size_t)ny * (k - 1))];
                    if (!isfinite(val))
                        bad = 1;
                }
                G(i, j, k) = val;
                pp[IDX(i, j, k)] = pq[IDX(i, j, k)] = IDX(i, j, k);
            }
    if (bad) {
        free(g);
        free(pp);
        free(pq);
        return -1;
    }
    long chi = 0;
    /* Vertices and open edges. */
    for (int k = 0; k < Z; k++)
        for (int j = 0; j < Y; j++)
            for (int i = 0; i < X; i++) {
                int p = G(i, j, k) >= iso;
                chi += p;
                if (p && i + 1 < X && G(i + 1, j, k) >= iso)
                    chi--;
                if (p && j + 1 < Y && G(i, j + 1, k) >= iso)
                    chi--;
                if (p && k + 1 < Z && G(i, j, k + 1) >= iso)
                    chi--;
            }
    /* Open faces: normal axis a, lower corner (i, j, k). */
    for (int a = 0; a < 3; a++)
        for (int k = 0; k + (a == 2 ? 0 : 1) < Z; k++)
            for (int j = 0; j + (a == 1 ? 0 : 1) < Y; j++)
                for (int i = 0; i + (a == 0 ? 0 : 1) < X; i++) {
                    const int u = a == 0 ? 1 : 0, w = a == 2 ? 1 : 2;
                    double q[4];
                    int o[3] = {i, j, k};
                    for (int c = 0; c < 4; c++) {
                        int pt[3] = {o[0], o[1], o[2]};
                        pt[u] += (c == 1 || c == 2);
                        pt[w] += (c >= 2);
                        q[c] = G(pt[0], pt[1], pt[2]) - iso;
                    }
                    int comp[4];
                    long t = square_components(q, 1, 0, comp);
                    for (int c = 0; c < 4; c++) {
                        t -= q[c] >= 0;
                        if (q[c] >= 0 && q[(c + 1) % 4] >= 0)
                            t += 1; /* minus the open edge's -1 */
                    }
                    chi += t;
                }
    /* Open cubes, and the corner labels. */
    for (int k = 0; k + 1 < Z; k++)
        for (int j = 0; j + 1 < Y; j++)
            for (int i = 0; i + 1 < X; i++) {
                double v[8];
                int id[8];
                for (int c = 0; c < 8; c++) {
                    int ci = i + (c & 1), cj = j + ((c >> 1) & 1), ck = k + ((c >> 2) & 1);
                    v[c] = G(ci, cj, ck);
                    id[c] = IDX(ci, cj, ck);
                }
                int label[8], first[8];
                long cchi;
                oracle_cell(v, iso, 1, label, &cchi);
                for (int c = 0; c < 8; c++)
                    first[c] = -1;
                for (int c = 0; c < 8; c++)
                    if (label[c] >= 0) {
                        if (first[label[c]] < 0)
                            first[label[c]] = id[c];
                        else
                            uf_union(pp, id[c], first[label[c]]);
                    }
                oracle_cell(v, iso, 0, label, NULL);
                for (int c = 0; c < 8; c++)
                    first[c] = -1;
                for (int c = 0; c < 8; c++)
                    if (label[c] >= 0) {
                        if (first[label[c]] < 0)
                            first[label[c]] = id[c];
                        else
                            uf_union(pq, id[c], first[label[c]]);
                    }
                /* chi_c(open cube) = chi(closed) - its 6 open faces - 12
                 * open edges - 8 vertices = chi(closed) - chi(boundary);
                 * chi(P on the cube's surface) by the same additivity. */
                long bnd = 0;
                for (int c = 0; c < 8; c++)
                    bnd += v[c] >= iso;
                static const int edge_c[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                                                  {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};
                for (int e = 0; e < 12; e++)
                    bnd -= v[edge_c[e][0]] >= iso && v[edge_c[e][1]] >= iso;
                static const int face_c[6][4] = {{0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                                 {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 5, 7, 6}};
                for (int f = 0; f < 6; f++) {
                    double q[4];
                    for (int c = 0; c < 4; c++)
                        q[c] = v[face_c[f][c]] - iso;
                    int comp[4];
                    long t = square_components(q, 1, 0, comp);
                    for (int c = 0; c < 4; c++) {
                        t -= q[c] >= 0;
                        if (q[c] >= 0 && q[(c + 1) % 4] >= 0)
                            t += 1;
                    }
                    bnd += t;
                }
                chi += cchi - bnd;
            }
    long b0p = 0, b0q = 0;
    for (int k = 0; k < Z; k++)
        for (int j = 0; j < Y; j++)
            for (int i = 0; i < X; i++) {
                int id = IDX(i, j, k);
                if (G(i, j, k) >= iso)
                    b0p += uf_find(pp, id) == id;
                else
                    b0q += uf_find(pq, id) == id;
            }
#undef G
#undef IDX
    free(g);
    free(pp);
    free(pq);
    r->b0_p = b0p;
    r->b0_q = b0q;
    r->chi_p = chi;
    r->b0_s = b0p + b0q - 1;
    r->chi_s = 2 * chi;
    r->b1_s = 2 * r->b0_s - r->chi_s;
    return 0;
}

/* ------------------------------------------------------- digital, grid */

int oracle_topology_digital(const double *vals, int nx, int ny, int nz, double iso, int m,
                            oracle_result *r)
{
    const int X = nx + 2, Y = ny + 2, Z = nz + 2;
    const int RX = (X - 1) * m + 1, RY = (Y - 1) * m + 1, RZ = (Z - 1) * m + 1;
    const size_t total = (size_t)RX * RY * RZ;
    unsigned char *in = malloc(total);
    int *parent = malloc(total * sizeof *parent);
    if (!in || !parent) {
        free(in);
        free(parent);
        return -1;
    }
#define RID(i, j, k) ((size_t)(i) + (size_t)RX * ((size_t)(j) + (size_t)RY * (size_t)(k)))
    for (int k = 0; k < RZ; k++)
        for (int j = 0; j < RY; j++)
            for (int i = 0; i < RX; i++) {
                int ci = i / m < X - 1 ? i / m : X - 2, cj = j / m < Y - 1 ? j / m : Y - 2,
                    ck = k / m < Z - 1 ? k / m : Z - 2;
                double v[8];
                for (int c = 0; c < 8; c++) {
                    int gi = ci + (c & 1) - 1, gj = cj + ((c >> 1) & 1) - 1, gk = ck + ((c >> 2) & 1) - 1;
                    v[c] = (gi < 0 || gj < 0 || gk < 0 || gi >= nx || gj >= ny || gk >= nz)
                               ? iso - 1.0
                               : vals[(size_t)gi + (size_t)nx * ((size_t)gj + (size_t)ny * (size_t)gk)];
                }
                double f = trilinear(v, (double)(i - ci * m) / m, (double)(j - cj * m) / m,
                                     (double)(k - ck * m) / m);
                in[RID(i, j, k)] = f >= iso;
                parent[RID(i, j, k)] = (int)RID(i, j, k);
            }
    long V = 0, E = 0, F = 0, C = 0;
    for (int k = 0; k < RZ; k++)
        for (int j = 0; j < RY; j++)
            for (int i = 0; i < RX; i++) {
                size_t a = RID(i, j, k);
                int nb[3][3] = {{i + 1, j, k}, {i, j + 1, k}, {i, j, k + 1}};
                int ok[3];
                for (int d = 0; d < 3; d++) {
                    ok[d] = nb[d][0] < RX && nb[d][1] < RY && nb[d][2] < RZ;
                    if (ok[d]) {
                        size_t b = RID(nb[d][0], nb[d][1], nb[d][2]);
                        if (in[a] == in[b])
                            uf_union(parent, (int)a, (int)b);
                        ok[d] = in[a] && in[b];
                    }
                }
                if (!in[a])
                    continue;
                V++;
                E += ok[0] + ok[1] + ok[2];
                int sxy = ok[0] && ok[1] && in[RID(i + 1, j + 1, k)];
                int sxz = ok[0] && ok[2] && in[RID(i + 1, j, k + 1)];
                int syz = ok[1] && ok[2] && in[RID(i, j + 1, k + 1)];
                F += sxy + sxz + syz;
                C += sxy && sxz && syz && in[RID(i + 1, j + 1, k + 1)];
            }
    long b0p = 0, b0q = 0;
    for (size_t a = 0; a < total; a++)
        if (uf_find(parent, (int)a) == (int)a) {
            if (in[a])
                b0p++;
            else
                b0q++;
        }
#undef RID
    free(in);
    free(parent);
    r->b0_p = b0p;
    r->b0_q = b0q;
    r->chi_p = V - E + F - C;
    r->b0_s = b0p + b0q - 1;
    r->chi_s = 2 * r->chi_p;
    r->b1_s = 2 * r->b0_s - r->chi_s;
    return 0;
}
