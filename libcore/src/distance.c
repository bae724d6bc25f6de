/*
 * distance.c - how far points lie from a triangle mesh: the distance from
 * each input vertex to a decimated result (isomend_decimate_report), the
 * one-sided Hausdorff distance that VTK's vtkCellLocator or MeshLab's
 * Hausdorff filter measure.
 *
 * A uniform grid of cells about the mean edge long (at most about 16 a
 * triangle) files each triangle under every cell its bounding box touches
 * (a compressed row table); a point searches rings of cells around its own,
 * outwards, until the ring is farther than the nearest triangle found,
 * passing over cells and triangles' bounding boxes farther than that.
 * Points outside the grid start from the nearest cell.
 */
#include "arena.h"
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Squared distance from p to triangle (a, b, c) (Ericson, "Real-Time Collision
 * Detection", 5.1.5: the closest point by Voronoi regions). */
/* The squared distance from p to the segment (a, b). */
static double point_segment_distance2(const double p[3], const double a[3], const double b[3])
{
    double ab[3], ap[3];
    for (int i = 0; i < 3; i++) {
        ab[i] = b[i] - a[i];
        ap[i] = p[i] - a[i];
    }
    const double len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    double t = len2 > 0 ? (ab[0] * ap[0] + ab[1] * ap[1] + ab[2] * ap[2]) / len2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double d = 0;
    for (int i = 0; i < 3; i++) {
        const double x = ap[i] - t * ab[i];
        d += x * x;
    }
    return d;
}

/* A triangle of (nearly) no area: the nearest of its three edges. */
static double degenerate_distance2(const double p[3], const double a[3], const double b[3],
                                   const double c[3])
{
    const double d0 = point_segment_distance2(p, a, b), d1 = point_segment_distance2(p, b, c),
                 d2 = point_segment_distance2(p, c, a);
    return d0 < d1 ? (d0 < d2 ? d0 : d2) : (d1 < d2 ? d1 : d2);
}

double point_triangle_distance2(const double p[3], const double a[3], const double b[3],
                                const double c[3])
{
    double ab[3], ac[3], ap[3], q[3];
    for (int i = 0; i < 3; i++) {
        ab[i] = b[i] - a[i];
        ac[i] = c[i] - a[i];
        ap[i] = p[i] - a[i];
    }
#define DOT(x, y) ((x)[0] * (y)[0] + (x)[1] * (y)[1] + (x)[2] * (y)[2])
    const double d1 = DOT(ab, ap), d2 = DOT(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        memcpy(q, a, sizeof q);
    } else {
        double bp[3], cp[3];
        for (int i = 0; i < 3; i++) {
            bp[i] = p[i] - b[i];
            cp[i] = p[i] - c[i];
        }
        const double d3 = DOT(ab, bp), d4 = DOT(ac, bp), d5 = DOT(ab, cp), d6 = DOT(ac, cp);
        const double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
        if (d3 >= 0 && d4 <= d3) {
            memcpy(q, b, sizeof q);
        } else if (d6 >= 0 && d5 <= d6) {
            memcpy(q, c, sizeof q);
        } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
            const double v = d1 / (d1 - d3);
            for (int i = 0; i < 3; i++)
                q[i] = a[i] + v * ab[i];
        } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
            const double w = d2 / (d2 - d6);
            for (int i = 0; i < 3; i++)
                q[i] = a[i] + w * ac[i];
        } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
            const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            for (int i = 0; i < 3; i++)
                q[i] = b[i] + w * (c[i] - b[i]);
        } else {
            const double den = 1.0 / (va + vb + vc);
            const double v = vb * den, w = vc * den;
            for (int i = 0; i < 3; i++)
                q[i] = a[i] + ab[i] * v + ac[i] * w;
        }
    }
#undef DOT
    const double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
    const double d = dx * dx + dy * dy + dz * dz;
    /* a zero-area triangle divides 0 by 0 above: its edges instead */
    return isfinite(d) ? d : degenerate_distance2(p, a, b, c);
}


typedef struct cell_grid {
    double lo[3], size;
    int64_t n[3];
    uint32_t *first; /* n0 n1 n2 + 1 */
    uint32_t *tris;
} cell_grid;

static int64_t cell_of(const cell_grid *g, double x, int a)
{
    int64_t c = (int64_t)floor((x - g->lo[a]) / g->size);
    return c < 0 ? 0 : c >= g->n[a] ? g->n[a] - 1 : c;
}

/* How far x lies outside cell i along axis a (0 inside), a little less
 * (by a millionth of a cell) so that rounding never skips a cell that holds
 * the nearest point: a cell is searched when this is within the nearest
 * distance found, and a triangle filed under the cell of its nearest point
 * is found there, so skipping the others changes no distance. */
static inline double box_gap(const cell_grid *g, double x, int64_t i, int a)
{
    const double lo = g->lo[a] + (double)i * g->size, hi = lo + g->size;
    const double gap = x < lo ? lo - x : x > hi ? x - hi : 0;
    return gap > 1e-6 * g->size ? gap - 1e-6 * g->size : 0;
}

/* The points of a query, in blocks of DIST_BLOCK: each block's largest
 * distance and sum, so that the result does not depend on how the blocks
 * are shared among threads. */
#define DIST_BLOCK 4096
typedef struct dist_job {
    const cell_grid *g;
    const float *pts;
    const float *corners; /* 9 a triangle: its corners' positions */
    const float *boxes;   /* 6 a filed triangle, in g->tris's order: its bounding box */
    size_t np;
    double *block_max, *block_sum;
} dist_job;

static void dist_blocks(void *arg, size_t lo_block, size_t hi_block)
{
    const dist_job *j = arg;
    const cell_grid g = *j->g;
    const float *pts = j->pts;
    const double slack = 1e-6 * g.size;
    for (size_t b = lo_block; b < hi_block; b++) {
        double worst = 0, sum = 0;
        size_t last = 0; /* the triangle nearest to the previous point: points come
                          * in mesh order, so it is usually near, and its distance
                          * lets the search stop at the point's own cell */
        const size_t end = (b + 1) * DIST_BLOCK < j->np ? (b + 1) * DIST_BLOCK : j->np;
        for (size_t i = b * DIST_BLOCK; i < end; i++) {
            const double p[3] = {pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]};
            int64_t c[3];
            for (int a = 0; a < 3; a++)
                c[a] = cell_of(&g, p[a], a);
            double best;
            {
                const float *f = j->corners + 9 * last;
                double q[3][3];
                for (int m = 0; m < 3; m++)
                    for (int a = 0; a < 3; a++)
                        q[m][a] = f[3 * m + a];
                best = point_triangle_distance2(p, q[0], q[1], q[2]);
            }
            int64_t maxr = g.n[0] > g.n[1] ? g.n[0] : g.n[1];
            maxr = g.n[2] > maxr ? g.n[2] : maxr;
            for (int64_t r = 0; r <= maxr; r++) {
                /* every cell of ring r (the shell of the cube of radius r) */
                for (int64_t z = c[2] - r; z <= c[2] + r; z++) {
                    if (z < 0 || z >= g.n[2])
                        continue;
                    for (int64_t y = c[1] - r; y <= c[1] + r; y++) {
                        if (y < 0 || y >= g.n[1])
                            continue;
                        const int shell = z == c[2] - r || z == c[2] + r || y == c[1] - r || y == c[1] + r;
                        /* the cells of this row and layer lie no nearer than dyz */
                        const double dy = box_gap(&g, p[1], y, 1), dz = box_gap(&g, p[2], z, 2);
                        const double dyz = dy * dy + dz * dz;
                        if (dyz > best)
                            continue;
                        for (int64_t x = c[0] - r; x <= c[0] + r; x += shell ? 1 : 2 * r) {
                            const double dx = x >= 0 && x < g.n[0] ? box_gap(&g, p[0], x, 0) : 0;
                            if (x >= 0 && x < g.n[0] && dyz + dx * dx <= best) {
                                const size_t cell = (size_t)((z * g.n[1] + y) * g.n[0] + x);
                                for (uint32_t k = g.first[cell]; k < g.first[cell + 1]; k++) {
                                    /* no nearer than its bounding box (less the slack) */
                                    const float *bx = j->boxes + 6 * (size_t)k;
                                    double gap2 = 0;
                                    for (int a = 0; a < 3; a++) {
                                        const double lo = bx[a], hi = bx[3 + a];
                                        const double gap = p[a] < lo ? lo - p[a] : p[a] > hi ? p[a] - hi : 0;
                                        if (gap > slack)
                                            gap2 += (gap - slack) * (gap - slack);
                                    }
                                    if (gap2 > best)
                                        continue;
                                    const float *f = j->corners + 9 * (size_t)g.tris[k];
                                    double q[3][3];
                                    for (int m = 0; m < 3; m++)
                                        for (int a = 0; a < 3; a++)
                                            q[m][a] = f[3 * m + a];
                                    const double e = point_triangle_distance2(p, q[0], q[1], q[2]);
                                    if (e < best) {
                                        best = e;
                                        last = g.tris[k];
                                    }
                                }
                            }
                            if (r == 0)
                                break;
                        }
                    }
                }
                /* the cells not searched yet lie beyond the faces of the cube of
                 * rings 0 .. r that have cells beyond them */
                double reach = INFINITY;
                for (int a = 0; a < 3; a++) {
                    if (c[a] - r > 0) {
                        const double dlo = p[a] - (g.lo[a] + (double)(c[a] - r) * g.size);
                        reach = dlo < reach ? dlo : reach;
                    }
                    if (c[a] + r + 1 < g.n[a]) {
                        const double dhi = g.lo[a] + (double)(c[a] + r + 1) * g.size - p[a];
                        reach = dhi < reach ? dhi : reach;
                    }
                }
                if (best < INFINITY && (reach == INFINITY || (reach > 0 && reach * reach >= best)))
                    break;
            }

            const double d = sqrt(best);
            worst = d > worst ? d : worst;
            sum += d;
        }
        j->block_max[b] = worst;
        j->block_sum[b] = sum;
    }
}

int mesh_distances(const float *pts, size_t np, const float *pos, const uint32_t *tri, size_t nt,
                   team *tm, double *max_out, double *mean_out, uint64_t *bytes)
{
    *max_out = *mean_out = 0;
    if (bytes)
        *bytes = 0;
    if (!np || !nt)
        return 1;
    cell_grid g;
    g.tris = NULL;
    double hi[3];
    for (int a = 0; a < 3; a++) {
        g.lo[a] = INFINITY;
        hi[a] = -INFINITY;
    }
    double edges = 0;
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            const float *p = pos + 3 * (size_t)tri[3 * t + (size_t)k],
                        *q = pos + 3 * (size_t)tri[3 * t + (size_t)(k + 1) % 3];
            for (int a = 0; a < 3; a++) {
                g.lo[a] = p[a] < g.lo[a] ? p[a] : g.lo[a];
                hi[a] = p[a] > hi[a] ? p[a] : hi[a];
            }
            const double dx = (double)p[0] - q[0], dy = (double)p[1] - q[1], dz = (double)p[2] - q[2];
            edges += sqrt(dx * dx + dy * dy + dz * dz);
        }
    g.size = edges / (3.0 * (double)nt);
    double extent = 0;
    for (int a = 0; a < 3; a++)
        extent = hi[a] - g.lo[a] > extent ? hi[a] - g.lo[a] : extent;
    if (!(g.size > 0) || !isfinite(g.size))
        g.size = extent > 0 ? extent : 1.0;
    /* at most about 16 cells a triangle */
    for (;;) {
        uint64_t cells = 1;
        for (int a = 0; a < 3; a++) {
            g.n[a] = (int64_t)((hi[a] - g.lo[a]) / g.size) + 1;
            cells *= (uint64_t)g.n[a];
        }
        if (cells <= 16 * (uint64_t)nt + 64)
            break;
        g.size *= 1.5;
    }
    const size_t ncell = (size_t)(g.n[0] * g.n[1] * g.n[2]);
    /* the arrays in two arenas (arena.c: faulted in at once, zero): the
     * cells' counts, then what their sum sizes */
    arena cells_ar, ar = {0};
    if (!arena_open(&cells_ar, arena_bytes((ncell + 1) * sizeof(uint32_t))))
        return 0;
    g.first = arena_take(&cells_ar, (ncell + 1) * sizeof(uint32_t));
    /* two passes: count, then file */
    uint64_t total = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (size_t t = 0; t < nt; t++) {
            int64_t c0[3], c1[3];
            for (int a = 0; a < 3; a++) {
                double mn = INFINITY, mx = -INFINITY;
                for (int k = 0; k < 3; k++) {
                    const double x = pos[3 * (size_t)tri[3 * t + (size_t)k] + (size_t)a];
                    mn = x < mn ? x : mn;
                    mx = x > mx ? x : mx;
                }
                c0[a] = cell_of(&g, mn, a);
                c1[a] = cell_of(&g, mx, a);
            }
            for (int64_t z = c0[2]; z <= c1[2]; z++)
                for (int64_t y = c0[1]; y <= c1[1]; y++)
                    for (int64_t x = c0[0]; x <= c1[0]; x++) {
                        const size_t cell = (size_t)((z * g.n[1] + y) * g.n[0] + x);
                        if (pass == 0)
                            g.first[cell + 1]++;
                        else
                            g.tris[g.first[cell]++] = (uint32_t)t;
                    }
        }
        if (pass == 0) {
            for (size_t c = 0; c < ncell; c++)
                g.first[c + 1] += g.first[c];
            total = g.first[ncell];
            const size_t nblocks = (np + DIST_BLOCK - 1) / DIST_BLOCK, t1 = total ? total : 1;
            if (!arena_open(&ar, arena_bytes(t1 * sizeof(uint32_t)) +
                                     arena_bytes(2 * (nblocks ? nblocks : 1) * sizeof(double)) +
                                     arena_bytes(9 * (nt ? nt : 1) * sizeof(float)) +
                                     arena_bytes(6 * t1 * sizeof(float)))) {
                arena_close(&cells_ar);
                return 0;
            }
            g.tris = arena_take(&ar, t1 * sizeof(uint32_t));
        } else {
            for (size_t c = ncell; c > 0; c--)
                g.first[c] = g.first[c - 1];
            g.first[0] = 0;
        }
    }
    /* the points in blocks, on threads; the blocks' results summed in order */
    const size_t nblocks = (np + DIST_BLOCK - 1) / DIST_BLOCK;
    double *bmax = arena_take(&ar, 2 * (nblocks ? nblocks : 1) * sizeof(double));
    float *corners = arena_take(&ar, 9 * (nt ? nt : 1) * sizeof(float));
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++)
            memcpy(corners + 9 * t + 3 * k, pos + 3 * (size_t)tri[3 * t + (size_t)k], 3 * sizeof(float));
    /* each filing's bounding box, where the search reads it: a cell's
     * triangles' boxes side by side */
    float *boxes = arena_take(&ar, 6 * (total ? total : 1) * sizeof(float));
    for (uint64_t k = 0; k < total; k++) {
        const float *f = corners + 9 * (size_t)g.tris[k];
        float *bx = boxes + 6 * k;
        for (int a = 0; a < 3; a++) {
            const float x = f[a], y = f[3 + a], z = f[6 + a];
            bx[a] = x < y ? (x < z ? x : z) : (y < z ? y : z);
            bx[3 + a] = x > y ? (x > z ? x : z) : (y > z ? y : z);
        }
    }
    if (bytes) /* its grid, the blocks' results, the corners and the boxes, at once */
        *bytes = ((uint64_t)ncell + 1 + (total ? total : 1)) * sizeof(uint32_t) +
                 2 * (uint64_t)nblocks * sizeof(double) + 9 * (uint64_t)nt * sizeof(float) +
                 6 * (uint64_t)(total ? total : 1) * sizeof(float);
    dist_job job = {&g, pts, corners, boxes, np, bmax, bmax + nblocks};
    team *own = tm || nblocks < 2 ? NULL : team_start(np); /* threads from 2 blocks (8192 points) on */
    team_for_from(tm ? tm : own, nblocks, 1, dist_blocks, &job);
    team_stop(own);
    double worst = 0, sum = 0;
    for (size_t b = 0; b < nblocks; b++) {
        worst = bmax[b] > worst ? bmax[b] : worst;
        sum += bmax[nblocks + b];
    }
    arena_close(&ar);
    arena_close(&cells_ar);
    *max_out = worst;
    *mean_out = sum / (double)np;
    return 1;
}
