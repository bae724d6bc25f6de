/*
 * check.c - the continuity checker (thesis chapter 2.3.2, after Udupa,
 * Srihari & Herman 1982): a triangle mesh is a continuous surface iff every
 * edge is used by exactly two triangles, except edges on the outer faces of
 * the volume, used once.  Beyond that theorem it reports orientation flips
 * (an edge used twice in the same direction), non-manifold vertices (the
 * triangles around a vertex form two or more fans), degenerate triangles,
 * connected components (triangles joined through shared edges) and the Euler
 * characteristic V - E + F.
 *
 * Method.  Every directed triangle edge is filed under its lower vertex in a
 * compressed row table (counting sort, no hashing), each vertex's short list
 * is sorted by the other vertex, and equal neighbours form one undirected
 * edge.  Union-find joins triangles across edges (components) and the
 * endpoints of hole edges (hole loops).  Memory is linear in the mesh.
 *
 * isomend_check() takes this way (check_sorted) only for a mesh whose order
 * is not a sweep; an extracted mesh goes to the streaming checker in its
 * order (check_order.c), which gives the same report faster.
 */
#include "check.h"
#include "check_order.h"
#include "check_rules.h"
#include "mesh_internal.h"
#include "slice_geometry.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct half {
    uint32_t other; /* the higher vertex of the edge                  */
    uint32_t tri;   /* triangle using it                               */
    uint8_t fwd;    /* 1 when the triangle runs lower -> higher        */
} half;

static uint32_t uf_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

static void uf_union(uint32_t *parent, uint32_t a, uint32_t b)
{
    a = uf_find(parent, a);
    b = uf_find(parent, b);
    if (a != b) {
        if (a < b)
            parent[b] = a;
        else
            parent[a] = b;
    }
}

static void sort_halves(half *h, size_t n)
{
    for (size_t i = 1; i < n; i++) { /* lists are short: insertion sort */
        half x = h[i];
        size_t j = i;
        while (j > 0 && h[j - 1].other > x.other) {
            h[j] = h[j - 1];
            j--;
        }
        h[j] = x;
    }
}

/* degenerate_triangle() of triangle t (3 indices into pos). */
static int degenerate_of(const float *pos, const uint32_t *t)
{
    return degenerate_triangle(t[0], t[1], t[2], pos + 3 * (size_t)t[0], pos + 3 * (size_t)t[1],
                               pos + 3 * (size_t)t[2]);
}

/* Number of fans the triangles `tris[0..n)` around vertex v form. */
static uint64_t count_fans(const uint32_t *triangles, uint32_t v, const uint32_t *tris, size_t n,
                           uint32_t *parent, half *scratch)
{
    for (size_t i = 0; i < n; i++)
        parent[i] = (uint32_t)i;
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        const uint32_t *t = triangles + 3 * (size_t)tris[i];
        for (int c = 0; c < 3; c++)
            if (t[c] != v) {
                scratch[m].other = t[c];
                scratch[m].tri = (uint32_t)i;
                m++;
            }
    }
    sort_halves(scratch, m);
    for (size_t i = 1; i < m; i++)
        if (scratch[i].other == scratch[i - 1].other)
            uf_union(parent, scratch[i].tri, scratch[i - 1].tri);
    uint64_t fans = 0;
    for (size_t i = 0; i < n; i++)
        fans += uf_find(parent, (uint32_t)i) == i;
    return fans;
}

uint64_t isomend_check_memory(size_t vertex_count, size_t triangle_count)
{
    const uint64_t nv = vertex_count, nt = triangle_count;
    /* row, vrow, fill, vfill; halves, vtris, tparent; vparent, mark */
    return 4 * sizeof(size_t) * (nv + 1) + (3 * sizeof(half) + 3 * 4 + 4) * nt + 5 * nv;
}

/* Tests only (check.h): isomend_check() always sorts, the reference the
 * streaming checker is compared with. */
static int test_sorted;

void check_set_test_sorted(int on)
{
    test_sorted = on;
}

isomend_status isomend_check(const float *positions, size_t vertex_count,
                             const uint32_t *triangles, size_t triangle_count, const double *box,
                             isomend_check_report *report)
{
    if (!report || (triangle_count && (!positions || !triangles)) || vertex_count > UINT32_MAX ||
        triangle_count > UINT32_MAX / 3)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    memset(report, 0, sizeof(*report));
    for (size_t i = 0; i < 3 * triangle_count; i++)
        if (triangles[i] >= vertex_count)
            return ISOMEND_ERR_INVALID_ARGUMENT;
    if (triangle_count == 0)
        return ISOMEND_OK;
    if (!test_sorted) {
        const isomend_status status =
            check_in_order(positions, vertex_count, triangles, triangle_count, box, report);
        if (status != ISOMEND_ERR_UNSUPPORTED)
            return status;
    }
    return check_sorted(positions, vertex_count, triangles, triangle_count, box, report);
}

isomend_status check_sorted(const float *positions, size_t vertex_count,
                            const uint32_t *triangles, size_t triangle_count, const double *box,
                            isomend_check_report *report)
{
    memset(report, 0, sizeof(*report));
    const size_t nv = vertex_count, nt = triangle_count;
    size_t *row = calloc(nv + 1, sizeof(size_t));     /* halves by lower vertex */
    size_t *vrow = calloc(nv + 1, sizeof(size_t));    /* triangles by vertex    */
    half *halves = malloc(sizeof(half) * 3 * nt);
    uint32_t *vtris = malloc(sizeof(uint32_t) * 3 * nt);
    uint32_t *tparent = malloc(sizeof(uint32_t) * nt);
    uint32_t *vparent = malloc(sizeof(uint32_t) * nv);
    size_t maxdeg = 0;
    isomend_status status = ISOMEND_ERR_OUT_OF_MEMORY;
    uint32_t *lparent = NULL;
    half *scratch = NULL;
    if (!row || !vrow || !halves || !vtris || !tparent || !vparent)
        goto done;

    for (size_t t = 0; t < nt; t++) {
        const uint32_t *v = triangles + 3 * t;
        for (int c = 0; c < 3; c++) {
            uint32_t a = v[c], b = v[(c + 1) % 3];
            row[(a < b ? a : b) + 1]++;
            vrow[a + 1]++;
        }
    }
    for (size_t i = 0; i < nv; i++) {
        row[i + 1] += row[i];
        size_t deg = vrow[i + 1];
        if (deg > maxdeg)
            maxdeg = deg;
        vrow[i + 1] += vrow[i];
        if (deg)
            report->vertices++;
    }
    {
        size_t *fill = malloc(sizeof(size_t) * (nv + 1));
        size_t *vfill = malloc(sizeof(size_t) * (nv + 1));
        if (!fill || !vfill) {
            free(fill);
            free(vfill);
            goto done;
        }
        memcpy(fill, row, sizeof(size_t) * (nv + 1));
        memcpy(vfill, vrow, sizeof(size_t) * (nv + 1));
        for (size_t t = 0; t < nt; t++) {
            const uint32_t *v = triangles + 3 * t;
            for (int c = 0; c < 3; c++) {
                uint32_t a = v[c], b = v[(c + 1) % 3];
                half h;
                h.other = a < b ? b : a;
                h.tri = (uint32_t)t;
                h.fwd = a < b;
                halves[fill[a < b ? a : b]++] = h;
                vtris[vfill[a]++] = (uint32_t)t;
            }
        }
        free(fill);
        free(vfill);
    }

    double bb[6];
    if (box) {
        memcpy(bb, box, sizeof(bb));
    } else {
        for (int a = 0; a < 3; a++) {
            bb[a] = INFINITY;
            bb[3 + a] = -INFINITY;
        }
        for (size_t i = 0; i < nv; i++) {
            if (vrow[i + 1] == vrow[i])
                continue;
            for (int a = 0; a < 3; a++) {
                double x = positions[3 * i + a];
                if (x < bb[a])
                    bb[a] = x;
                if (x > bb[3 + a])
                    bb[3 + a] = x;
            }
        }
    }
    double extent = 0.0;
    for (int a = 0; a < 3; a++)
        if (bb[3 + a] - bb[a] > extent)
            extent = bb[3 + a] - bb[a];

    for (size_t t = 0; t < nt; t++)
        tparent[t] = (uint32_t)t;
    for (size_t i = 0; i < nv; i++)
        vparent[i] = (uint32_t)i;

    for (size_t v = 0; v < nv; v++) {
        half *h = halves + row[v];
        size_t n = row[v + 1] - row[v];
        sort_halves(h, n);
        for (size_t i = 0; i < n;) {
            size_t j = i + 1;
            unsigned fwd = h[i].fwd;
            while (j < n && h[j].other == h[i].other) {
                fwd += h[j].fwd;
                uf_union(tparent, h[i].tri, h[j].tri);
                j++;
            }
            size_t uses = j - i;
            report->edges++;
            if (uses == 1) {
                const float *p = positions + 3 * v, *q = positions + 3 * (size_t)h[i].other;
                if (on_box_face(p, q, bb, extent)) {
                    report->border_edges++;
                } else {
                    report->hole_edges++;
                    uf_union(vparent, (uint32_t)v, h[i].other);
                }
            } else if (uses == 2) {
                if (fwd != 1)
                    report->misoriented_edges++;
            } else {
                report->nonmanifold_edges++;
            }
            i = j;
        }
    }

    /* Hole loops: groups of vertices joined by hole edges, one mark per group. */
    if (report->hole_edges) {
        unsigned char *mark = calloc(nv, 1);
        if (!mark)
            goto done;
        for (size_t v = 0; v < nv; v++) {
            const half *h = halves + row[v];
            size_t n = row[v + 1] - row[v];
            for (size_t i = 0; i < n;) {
                size_t j = i + 1;
                while (j < n && h[j].other == h[i].other)
                    j++;
                if (j - i == 1 && !on_box_face(positions + 3 * v,
                                               positions + 3 * (size_t)h[i].other, bb, extent))
                    mark[uf_find(vparent, (uint32_t)v)] = 1;
                i = j;
            }
        }
        for (size_t v = 0; v < nv; v++)
            report->hole_loops += mark[v];
        free(mark);
    }

    for (size_t t = 0; t < nt; t++) {
        report->components += uf_find(tparent, (uint32_t)t) == t;
        report->degenerate_triangles += (uint64_t)degenerate_of(positions, triangles + 3 * t);
    }

    lparent = malloc(sizeof(uint32_t) * (maxdeg ? maxdeg : 1));
    scratch = malloc(sizeof(half) * 2 * (maxdeg ? maxdeg : 1));
    if (!lparent || !scratch)
        goto done;
    for (size_t v = 0; v < nv; v++) {
        size_t n = vrow[v + 1] - vrow[v];
        if (n > 1 && count_fans(triangles, (uint32_t)v, vtris + vrow[v], n, lparent, scratch) > 1)
            report->nonmanifold_vertices++;
    }

    report->triangles = nt;
    report->euler = (int64_t)report->vertices - (int64_t)report->edges + (int64_t)nt;
    status = ISOMEND_OK;

done:
    free(row);
    free(vrow);
    free(halves);
    free(vtris);
    free(tparent);
    free(vparent);
    free(lparent);
    free(scratch);
    if (status != ISOMEND_OK)
        memset(report, 0, sizeof(*report));
    return status;
}

uint64_t isomend_mesh_check_memory(const isomend_mesh *mesh)
{
    if (!mesh)
        return 0;
    uint64_t bytes = check_in_order_memory(mesh->tri, mesh->nv, mesh->nt);
    if (bytes == 0)
        bytes = isomend_check_memory(mesh->nv, mesh->nt);
    if (mesh->slices.so) /* sheared_check's moved positions and slice origins */
        bytes += 12 * (uint64_t)mesh->nv + 24 * (uint64_t)mesh->N[2];
    return bytes;
}

/* The check of a mesh on a sheared grid (slice_geometry.c), in its unsheared
 * frame: each vertex moved by its slice shift, the box of the grid's own
 * faces. */
static isomend_status sheared_check(const isomend_mesh *mesh, isomend_check_report *report)
{
    const slice_table *t = &mesh->slices;
    const int64_t N2 = mesh->N[2];
    double *o = malloc(3 * sizeof(double) * (size_t)N2);
    float *p = malloc(3 * sizeof(float) * (mesh->nv ? mesh->nv : 1));
    if (!o || !p) {
        free(o);
        free(p);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    for (int64_t m = 0; m < N2; m++)
        slice_origin(t, m, o + 3 * m);
    for (size_t v = 0; v < mesh->nv; v++)
        unshear_point(o, N2, mesh->pos + 3 * v, p + 3 * v);
    double box[6];
    for (int a = 0; a < 2; a++) {
        box[a] = -(double)t->pad * mesh->h[a];
        box[3 + a] = box[a] + (double)(mesh->N[a] - 1) * mesh->h[a];
    }
    box[2] = o[2];
    box[5] = o[3 * (N2 - 1) + 2];
    free(o);
    const isomend_status status = isomend_check(p, mesh->nv, mesh->tri, mesh->nt, box, report);
    free(p);
    return status;
}

isomend_status isomend_mesh_check(const isomend_mesh *mesh, isomend_check_report *report)
{
    if (!mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (mesh->slices.so)
        return sheared_check(mesh, report);
    return isomend_check(mesh->pos, mesh->nv, mesh->tri, mesh->nt, mesh->box, report);
}
