/*
 * march_general.c - marching with a method of methods.h (facial, gradient,
 * asymptotic, tetra, mc33): the per-cube hook and tetra's face diagonals.
 *
 * The table methods' loops (march_template.h, scan_template.h) call these
 * for every busy cube and, with tetra, every row.  Cube-private vertices
 * (methods.h slots 18..30) of layer k are numbered after slice k's
 * vertices, before slice k + 1's; face-diagonal vertices with their slice, after its edges'
 * in row order.
 */
#include "context.h"
#include "vertices.h"
#include "march_general.h"
#include "methods.h"

#include "cube.h"

/* Linear-index order of two marched samples: is p before q? */
static int sample_before(const int64_t p[3], const int64_t q[3])
{
    if (p[2] != q[2])
        return p[2] < q[2];
    if (p[1] != q[1])
        return p[1] < q[1];
    return p[0] < q[0];
}

/*
 * The tetrahedral method's face diagonals (methods.h, slots 12..17): each
 * face of the grid has the diagonal joining its two corners of even parity
 * (i + j + k even).  Row j of slice m owns the diagonals of the x faces
 * (x = i, y in [j, j+1], z in [m, m+1]), the y faces (y = j, x in [i, i+1],
 * z in [m, m+1]) and the z faces (z = m, x in [i, i+1], y in [j, j+1]) whose
 * lowest corner is (i, j, m).  Counting (ids NULL) returns id + the
 * number cut; otherwise numbers them in that order and returns the next id.
 */
uint64_t scan_diagonals(const ctx *c, const uint8_t *s, const uint8_t *t, int64_t j, int64_t m,
                        uint32_t *ids, uint64_t id, int write)
{
    const grid *g = &c->g;
    const int64_t N0 = g->N[0], N1 = g->N[1], plane = N0 * N1;
    const uint8_t *a = s + j * N0;
    const uint8_t *b = j + 1 < N1 ? a + N0 : NULL;
    const uint8_t *d = t ? t + j * N0 : NULL;
    const uint8_t *e = t && b ? d + N0 : NULL;
    for (int kind = 0; kind < 3; kind++) {
        if ((kind == 0 && !e) || (kind == 1 && !d) || (kind == 2 && !b))
            continue;
        const int64_t end = kind == 0 ? N0 - 1 : N0 - 2;
        const int64_t last = end < c->cube_hi[0] ? end : c->cube_hi[0];
        for (int64_t i = c->cube_lo[0]; i <= last; i++) {
            const int even = ((i + j + m) & 1) == 0;
            int64_t p[3], q[3];
            uint8_t sp, sq;
            if (kind == 0) { /* x face: (i,j,m)-(i,j+1,m+1) or (i,j+1,m)-(i,j,m+1) */
                p[0] = q[0] = i;
                p[1] = even ? j : j + 1;
                q[1] = even ? j + 1 : j;
                p[2] = m;
                q[2] = m + 1;
                sp = even ? a[i] : b[i];
                sq = even ? e[i] : d[i];
            } else if (kind == 1) { /* y face: (i,j,m)-(i+1,j,m+1) or (i+1,j,m)-(i,j,m+1) */
                p[1] = q[1] = j;
                p[0] = even ? i : i + 1;
                q[0] = even ? i + 1 : i;
                p[2] = m;
                q[2] = m + 1;
                sp = even ? a[i] : a[i + 1];
                sq = even ? d[i + 1] : d[i];
            } else { /* z face: (i,j,m)-(i+1,j+1,m) or (i+1,j,m)-(i,j+1,m) */
                p[2] = q[2] = m;
                p[0] = even ? i : i + 1;
                q[0] = even ? i + 1 : i;
                p[1] = j;
                q[1] = j + 1;
                sp = even ? a[i] : a[i + 1];
                sq = even ? b[i + 1] : b[i];
            }
            if (sp == sq)
                continue;
            if (ids) {
                const int64_t *lo = sample_before(p, q) ? p : q, *hi = lo == p ? q : p;
                if (write)
                    make_vertex_between(g, c->flip, lo, hi, c->pos + vertex_at(c->vertex_base, id),
                                        c->nrm ? c->nrm + vertex_at(c->vertex_base, id) : NULL);
                ids[(3 + kind) * plane + j * N0 + i] = (uint32_t)id;
            }
            id++;
        }
    }
    return id;
}

/*
 * One cube of a method of methods.h: asks the hook for its triangles (vertex
 * slots), counts the cube-private vertices they use (PASS_COUNT) or numbers and
 * computes those and writes the triangles (PASS_FILL; the general methods
 * never sweep).  Private vertices are
 * derived from the cube's own edge points, recomputed here, so a chunk never
 * reads vertices another thread may still be writing.
 */
unsigned method_cube(worker *w, int64_t i, int64_t j, int64_t k, unsigned cfg, pass_kind pass,
                     const uint32_t *const ep[12], const uint32_t *ids0, const uint32_t *ids1,
                     uint32_t *out, uint8_t *org)
{
    const ctx *c = w->c;
    const grid *g = &c->g;
    methods_cube cube;
    double ring[64];
    for (int q = 0; q < 8; q++)
        cube.v[q] = fetch(g, i + CUBE_CORNER_X(q), j + CUBE_CORNER_Y(q), k + CUBE_CORNER_Z(q));
    cube.iso = g->iso;
    cube.config = cfg;
    cube.parity = (unsigned)((i + j + k) & 1);
    cube.ring = NULL;
    if (methods_needs_ring(c->method)) {
        for (int z = -1; z <= 2; z++)
            for (int y = -1; y <= 2; y++)
                for (int x = -1; x <= 2; x++)
                    ring[(x + 1) + 4 * (y + 1) + 16 * (z + 1)] = fetch(g, i + x, j + y, k + z);
        cube.ring = ring;
    }
    unsigned char slots[3 * METHODS_MAX_TRI];
    int n = isomend_method_cube(c->method, &cube, slots);
    if (n <= 0)
        return 0;
    uint32_t used = 0; /* private slots, bit s - METHODS_SLOT_CENTRE */
    for (int q = 0; q < 3 * n; q++)
        if (slots[q] >= METHODS_SLOT_CENTRE)
            used |= 1u << (slots[q] - METHODS_SLOT_CENTRE);
    if (pass == PASS_COUNT) {
        w->private_count += (uint64_t)__builtin_popcount(used);
        return (unsigned)n;
    }
    uint32_t ids[METHODS_SLOT_COUNT];
    const int64_t N0 = g->N[0], plane = N0 * g->N[1], at = j * N0 + i;
    for (int q = 0; q < 3 * n; q++) {
        const int sl = slots[q];
        if (sl < 12)
            ids[sl] = ep[sl][i];
        else if (sl < METHODS_SLOT_CENTRE) {
            const int f = sl - METHODS_SLOT_DIAG0;
            static const int diag_plane[6] = {3, 3, 4, 4, 5, 5};
            const int64_t off[6] = {at, at + 1, at, at + N0, at, at};
            ids[sl] = (f == 5 ? ids1 : ids0)[diag_plane[f] * plane + off[f]];
        }
    }
    if (used) {
        /* The cube's edge points, the centre (their mean) and the ring points. */
        float ep_pos[12][3], ep_nrm[12][3], centre[3] = {0, 0, 0}, cn[3] = {0, 0, 0};
        int cut = 0;
        for (int e = 0; e < 12; e++) {
            const int c0 = cube_edge_corner[e][0], c1 = cube_edge_corner[e][1];
            if (((cfg >> c0) & 1) == ((cfg >> c1) & 1))
                continue;
            make_vertex(g, c->flip, i + CUBE_CORNER_X(c0), j + CUBE_CORNER_Y(c0),
                        k + CUBE_CORNER_Z(c0), e / 4, ep_pos[e], c->nrm ? ep_nrm[e] : NULL);
            for (int a = 0; a < 3; a++) {
                centre[a] += ep_pos[e][a];
                cn[a] += c->nrm ? ep_nrm[e][a] : 0.0f;
            }
            cut++;
        }
        for (int a = 0; a < 3; a++)
            centre[a] /= (float)(cut ? cut : 1);
        for (int b = 0; b < METHODS_SLOT_COUNT - METHODS_SLOT_CENTRE; b++) {
            if (!(used & (1u << b)))
                continue;
            const uint64_t id = w->private_next++;
            ids[METHODS_SLOT_CENTRE + b] = (uint32_t)id;
            const size_t vi = vertex_at(c->vertex_base, id);
            float *pos = c->pos + vi, *nrm = c->nrm ? c->nrm + vi : NULL;
            double nn[3];
            for (int a = 0; a < 3; a++) {
                if (b == 0) {
                    pos[a] = centre[a];
                    nn[a] = cn[a];
                } else {
                    pos[a] = 0.5f * (centre[a] + ep_pos[b - 1][a]);
                    nn[a] = (double)cn[a] / (cut ? cut : 1) + (double)ep_nrm[b - 1][a];
                }
            }
            if (nrm) {
                double len = sqrt(nn[0] * nn[0] + nn[1] * nn[1] + nn[2] * nn[2]);
                for (int a = 0; a < 3; a++)
                    nrm[a] = len > 0.0 ? (float)(nn[a] / len) : (a == 2 ? 1.0f : 0.0f);
            }
        }
    }
    for (int t = 0; t < n; t++) {
        out[3 * t] = ids[slots[3 * t]];
        out[3 * t + 1] = ids[slots[3 * t + (c->flip ? 2 : 1)]];
        out[3 * t + 2] = ids[slots[3 * t + (c->flip ? 1 : 2)]];
        if (org)
            org[t] = ISOMEND_ORIGIN_TABLE;
    }
    return (unsigned)n;
}
