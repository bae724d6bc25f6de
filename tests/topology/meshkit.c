/*
 * meshkit.c - reference marching loop for the methods of methods.c, and a
 * combinatorial mesh analysis (edges, Euler characteristic, components,
 * manifold checks).  See meshkit.h.
 */
#include "meshkit.h"

#include "cube.h"
#include "methods.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int via_methods(const double *vals, int nx, int ny, int nz, double iso,
                       isomend_method method, int pad, mk_mesh *out);

int mk_extract_loop(const double *vals, int nx, int ny, int nz, double iso,
                    isomend_method method, int pad, mk_mesh *out)
{
    memset(out, 0, sizeof *out);
    if (method != ISOMEND_METHOD_MC && !methods_handles(method))
        return -1;
    return via_methods(vals, nx, ny, nz, iso, method, pad, out);
}

void mk_free(mk_mesh *m)
{
    if (!m)
        return;
    free(m->pos);
    free(m->tri);
    memset(m, 0, sizeof *m);
}

static int via_core(const double *vals, int nx, int ny, int nz, double iso, isomend_method method,
                    int pad, mk_mesh *out)
{
    isomend_volume vol;
    isomend_volume_init(&vol, vals, ISOMEND_F64, nx, ny, nz);
    isomend_options o;
    isomend_options_init(&o);
    o.iso = iso;
    o.method = method;
    o.threads = 1;
    o.flags = ISOMEND_FLAG_NO_NORMALS | ISOMEND_FLAG_NO_ORIGINS | (pad ? ISOMEND_FLAG_PAD : 0u);
    isomend_mesh *mesh = NULL;
    if (isomend_extract(&vol, &o, &mesh, NULL) != ISOMEND_OK)
        return -1;
    out->nv = isomend_mesh_vertex_count(mesh);
    out->nt = isomend_mesh_triangle_count(mesh);
    out->pos = malloc((out->nv ? out->nv : 1) * 3 * sizeof(float));
    out->tri = malloc((out->nt ? out->nt : 1) * 3 * sizeof(uint32_t));
    if (!out->pos || !out->tri) {
        isomend_mesh_destroy(mesh);
        mk_free(out);
        return -1;
    }
    isomend_mesh_copy(mesh, out->pos, NULL, out->tri, NULL);
    isomend_mesh_grid_box(mesh, out->box);
    isomend_mesh_destroy(mesh);
    return 0;
}

typedef struct builder {
    int X, Y, Z;
    const double *g; /* marched grid, NaN = outside */
    double iso;
    int32_t *edge_vid, *diag_vid, *centre_vid, *ring_vid;
    float *pos;
    size_t nv, cap_v;
    uint32_t *tri;
    size_t nt, cap_t;
} builder;

static size_t lin(const builder *b, int i, int j, int k)
{
    return (size_t)i + (size_t)b->X * ((size_t)j + (size_t)b->Y * (size_t)k);
}

static double at(const builder *b, int i, int j, int k)
{
    if (i < 0 || j < 0 || k < 0 || i >= b->X || j >= b->Y || k >= b->Z)
        return NAN;
    return b->g[lin(b, i, j, k)];
}

static int add_vertex(builder *b, const double p[3])
{
    if (b->nv == b->cap_v) {
        size_t cap = b->cap_v ? 2 * b->cap_v : 256;
        float *np = realloc(b->pos, cap * 3 * sizeof *np);
        if (!np)
            return -1;
        b->pos = np;
        b->cap_v = cap;
    }
    for (int d = 0; d < 3; d++)
        b->pos[3 * b->nv + (size_t)d] = (float)p[d];
    return (int)b->nv++;
}

/* Vertex on the segment between grid points a and b (a before b). */
static void cut_point(const builder *b, const int a[3], const int c[3], double p[3])
{
    double fa = at(b, a[0], a[1], a[2]), fc = at(b, c[0], c[1], c[2]);
    double t = (isnan(fa) || isnan(fc)) ? 0.5 : (b->iso - fa) / (fc - fa);
    for (int d = 0; d < 3; d++)
        p[d] = a[d] + t * (c[d] - a[d]);
}

static int slot_vertex(builder *b, int i, int j, int k, int slot, const int *edge_ids)
{
    const int o[3] = {i, j, k};
    if (slot < 12) {
        int c0 = cube_edge_corner[slot][0], c1 = cube_edge_corner[slot][1];
        int a[3] = {i + CUBE_CORNER_X(c0), j + CUBE_CORNER_Y(c0), k + CUBE_CORNER_Z(c0)};
        int c[3] = {i + CUBE_CORNER_X(c1), j + CUBE_CORNER_Y(c1), k + CUBE_CORNER_Z(c1)};
        size_t key = 3 * lin(b, a[0], a[1], a[2]) + (size_t)(slot / 4);
        if (b->edge_vid[key] < 0) {
            double p[3];
            cut_point(b, a, c, p);
            b->edge_vid[key] = add_vertex(b, p);
        }
        return b->edge_vid[key];
    }
    if (slot < METHODS_SLOT_CENTRE) {
        const int f = slot - METHODS_SLOT_DIAG0, ax = f / 2;
        int fo[3] = {o[0], o[1], o[2]};
        fo[ax] += f & 1;
        size_t key = 3 * lin(b, fo[0], fo[1], fo[2]) + (size_t)ax;
        if (b->diag_vid[key] < 0) {
            /* The diagonal joining the face's corners of even grid parity. */
            int ends[2][3], n = 0;
            for (int q = 0; q < 4; q++) {
                int c = cube_face_corner[f][q];
                int pt[3] = {i + CUBE_CORNER_X(c), j + CUBE_CORNER_Y(c), k + CUBE_CORNER_Z(c)};
                if (((pt[0] + pt[1] + pt[2]) & 1) == 0 && n < 2)
                    memcpy(ends[n++], pt, sizeof pt);
            }
            if (n != 2)
                return -1;
            if (lin(b, ends[0][0], ends[0][1], ends[0][2]) > lin(b, ends[1][0], ends[1][1], ends[1][2])) {
                int tmp[3];
                memcpy(tmp, ends[0], sizeof tmp);
                memcpy(ends[0], ends[1], sizeof tmp);
                memcpy(ends[1], tmp, sizeof tmp);
            }
            double p[3];
            cut_point(b, ends[0], ends[1], p);
            b->diag_vid[key] = add_vertex(b, p);
        }
        return b->diag_vid[key];
    }
    if (slot > METHODS_SLOT_CENTRE) {
        /* Ring slot: halfway between the centre and edge e's point. */
        const int e = slot - METHODS_SLOT_RING0;
        size_t key = 12 * lin(b, i, j, k) + (size_t)e;
        if (b->ring_vid[key] < 0) {
            int cv = slot_vertex(b, i, j, k, METHODS_SLOT_CENTRE, edge_ids);
            if (cv < 0 || edge_ids[e] < 0)
                return -1;
            double p[3];
            for (int d = 0; d < 3; d++)
                p[d] = 0.5 * ((double)b->pos[3 * (size_t)cv + (size_t)d] +
                              (double)b->pos[3 * (size_t)edge_ids[e] + (size_t)d]);
            b->ring_vid[key] = add_vertex(b, p);
        }
        return b->ring_vid[key];
    }
    size_t key = lin(b, i, j, k);
    if (b->centre_vid[key] < 0) {
        double p[3] = {0, 0, 0};
        int n = 0;
        for (int e = 0; e < 12; e++)
            if (edge_ids[e] >= 0) {
                for (int d = 0; d < 3; d++)
                    p[d] += b->pos[3 * (size_t)edge_ids[e] + (size_t)d];
                n++;
            }
        for (int d = 0; d < 3; d++)
            p[d] = n ? p[d] / n : o[d] + 0.5;
        b->centre_vid[key] = add_vertex(b, p);
    }
    return b->centre_vid[key];
}

static int via_methods(const double *vals, int nx, int ny, int nz, double iso,
                       isomend_method method, int pad, mk_mesh *out)
{
    builder b;
    memset(&b, 0, sizeof b);
    const int P = pad ? 1 : 0;
    b.X = nx + 2 * P;
    b.Y = ny + 2 * P;
    b.Z = nz + 2 * P;
    b.iso = iso;
    const size_t N = (size_t)b.X * b.Y * b.Z;
    double *g = malloc(N * sizeof *g);
    b.edge_vid = malloc(3 * N * sizeof(int32_t));
    b.diag_vid = malloc(3 * N * sizeof(int32_t));
    b.centre_vid = malloc(N * sizeof(int32_t));
    b.ring_vid = malloc(12 * N * sizeof(int32_t));
    int rc = -1;
    if (!g || !b.edge_vid || !b.diag_vid || !b.centre_vid || !b.ring_vid)
        goto done;
    for (int k = 0; k < b.Z; k++)
        for (int j = 0; j < b.Y; j++)
            for (int i = 0; i < b.X; i++) {
                int vi = i - P, vj = j - P, vk = k - P;
                g[lin(&b, i, j, k)] = (vi < 0 || vj < 0 || vk < 0 || vi >= nx || vj >= ny || vk >= nz)
                                          ? NAN
                                          : vals[(size_t)vi + (size_t)nx * ((size_t)vj + (size_t)ny * vk)];
            }
    b.g = g;
    memset(b.edge_vid, 0xff, 3 * N * sizeof(int32_t));
    memset(b.diag_vid, 0xff, 3 * N * sizeof(int32_t));
    memset(b.centre_vid, 0xff, N * sizeof(int32_t));
    memset(b.ring_vid, 0xff, 12 * N * sizeof(int32_t));
    double ring[64];
    for (int k = 0; k + 1 < b.Z; k++)
        for (int j = 0; j + 1 < b.Y; j++)
            for (int i = 0; i + 1 < b.X; i++) {
                methods_cube c;
                c.config = 0;
                for (int q = 0; q < 8; q++) {
                    c.v[q] = at(&b, i + CUBE_CORNER_X(q), j + CUBE_CORNER_Y(q), k + CUBE_CORNER_Z(q));
                    if (c.v[q] >= iso)
                        c.config |= 1u << q;
                }
                if (c.config == 0 || c.config == 255)
                    continue;
                c.iso = iso;
                c.parity = (unsigned)(i + j + k) & 1;
                c.ring = NULL;
                if (methods_needs_ring(method)) {
                    for (int z = -1; z <= 2; z++)
                        for (int y = -1; y <= 2; y++)
                            for (int x = -1; x <= 2; x++)
                                ring[(x + 1) + 4 * (y + 1) + 16 * (z + 1)] = at(&b, i + x, j + y, k + z);
                    c.ring = ring;
                }
                unsigned char slots[3 * METHODS_MAX_TRI];
                int n;
                if (method == ISOMEND_METHOD_MC) {
                    int edges[15];
                    n = isomend_case_triangles(c.config, edges);
                    for (int q = 0; q < 3 * n; q++)
                        slots[q] = (unsigned char)edges[q];
                } else {
                    n = isomend_method_cube(method, &c, slots);
                }
                if (n < 0)
                    goto done;
                /* Edge vertices first, so that the centre can average them. */
                int edge_ids[12];
                for (int e = 0; e < 12; e++) {
                    int c0 = cube_edge_corner[e][0], c1 = cube_edge_corner[e][1];
                    edge_ids[e] = ((c.config >> c0) & 1) != ((c.config >> c1) & 1)
                                      ? slot_vertex(&b, i, j, k, e, NULL)
                                      : -1;
                }
                if (b.nt + (size_t)n > b.cap_t) {
                    size_t cap = b.cap_t ? 2 * b.cap_t : 256;
                    while (cap < b.nt + (size_t)n)
                        cap *= 2;
                    uint32_t *nt = realloc(b.tri, cap * 3 * sizeof *nt);
                    if (!nt)
                        goto done;
                    b.tri = nt;
                    b.cap_t = cap;
                }
                for (int t = 0; t < 3 * n; t++) {
                    int vid = slot_vertex(&b, i, j, k, slots[t], edge_ids);
                    if (vid < 0)
                        goto done;
                    b.tri[3 * b.nt + (size_t)t] = (uint32_t)vid;
                }
                b.nt += (size_t)n;
            }
    out->nv = b.nv;
    out->nt = b.nt;
    out->pos = b.pos;
    out->tri = b.tri;
    b.pos = NULL;
    b.tri = NULL;
    for (int d = 0; d < 3; d++) {
        out->box[d] = 0;
        out->box[3 + d] = (d == 0 ? b.X : d == 1 ? b.Y : b.Z) - 1;
    }
    rc = 0;
done:
    free(g);
    free(b.edge_vid);
    free(b.diag_vid);
    free(b.centre_vid);
    free(b.ring_vid);
    free(b.pos);
    free(b.tri);
    return rc;
}

int mk_extract(const double *vals, int nx, int ny, int nz, double iso, isomend_method method,
               int pad, mk_mesh *out)
{
    memset(out, 0, sizeof *out);
    if (isomend_method_available(method))
        return via_core(vals, nx, ny, nz, iso, method, pad, out);
    if (!methods_handles(method))
        return -1;
    return via_methods(vals, nx, ny, nz, iso, method, pad, out);
}

/* ---------------------------------------------------------------- analysis */

typedef struct half {
    uint64_t key; /* min << 32 | max */
    uint32_t tri;
    uint8_t forward; /* stored as min -> max */
} half;

static int half_cmp(const void *a, const void *b)
{
    uint64_t x = ((const half *)a)->key, y = ((const half *)b)->key;
    return x < y ? -1 : x > y;
}

static int u64_cmp(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

static uint32_t find_root(uint32_t *p, uint32_t x)
{
    while (p[x] != x)
        x = p[x] = p[p[x]];
    return x;
}

int mk_analyse(const mk_mesh *m, mk_topo *t)
{
    memset(t, 0, sizeof *t);
    t->f = (long)m->nt;
    if (m->nt == 0)
        return 1;
    half *h = malloc(3 * m->nt * sizeof *h);
    uint32_t *tp = malloc(m->nt * sizeof *tp);
    uint8_t *used = calloc(m->nv ? m->nv : 1, 1);
    if (!h || !tp || !used) {
        free(h);
        free(tp);
        free(used);
        t->degenerate = -1;
        return 0;
    }
    for (size_t i = 0; i < m->nt; i++) {
        tp[i] = (uint32_t)i;
        const uint32_t *v = m->tri + 3 * i;
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2])
            t->degenerate++;
        for (int k = 0; k < 3; k++) {
            uint32_t a = v[k], b = v[(k + 1) % 3];
            used[a] = 1;
            half *x = &h[3 * i + (size_t)k];
            x->key = a < b ? ((uint64_t)a << 32 | b) : ((uint64_t)b << 32 | a);
            x->tri = (uint32_t)i;
            x->forward = a < b;
        }
    }
    for (size_t i = 0; i < m->nv; i++)
        t->v += used[i];
    qsort(h, 3 * m->nt, sizeof *h, half_cmp);
    for (size_t i = 0; i < 3 * m->nt;) {
        size_t j = i;
        int fw = 0;
        while (j < 3 * m->nt && h[j].key == h[i].key) {
            fw += h[j].forward;
            if (j > i) {
                uint32_t a = find_root(tp, h[i].tri), b = find_root(tp, h[j].tri);
                if (a != b)
                    tp[a] = b;
            }
            j++;
        }
        size_t n = j - i;
        t->e++;
        if (n == 1)
            t->once_edges++;
        else if (n > 2)
            t->multi_edges++;
        else if (fw != 1)
            t->misoriented_edges++;
        i = j;
    }
    for (size_t i = 0; i < m->nt; i++)
        t->components += find_root(tp, (uint32_t)i) == i;
    t->chi = t->v - t->e + t->f;

    /* Fans: the triangles around a vertex, linked when they share a second
     * vertex (an edge at the vertex); more than one group = non-manifold. */
    {
        size_t nc = 3 * m->nt;
        uint64_t *corner = malloc(nc * sizeof *corner);
        if (!corner) {
            t->degenerate = -1;
        } else {
            for (size_t i = 0; i < m->nt; i++)
                for (int k = 0; k < 3; k++)
                    corner[3 * i + (size_t)k] = (uint64_t)m->tri[3 * i + (size_t)k] << 32 | i;
            qsort(corner, nc, sizeof *corner, u64_cmp);
            for (size_t i = 0; i < nc;) {
                size_t j = i;
                while (j < nc && corner[j] >> 32 == corner[i] >> 32)
                    j++;
                size_t k = j - i;
                if (k <= 64) {
                    int par[64];
                    for (size_t a = 0; a < k; a++)
                        par[a] = (int)a;
                    for (size_t a = 0; a < k; a++)
                        for (size_t b2 = a + 1; b2 < k; b2++) {
                            const uint32_t *ta = m->tri + 3 * (corner[i + a] & 0xffffffffu);
                            const uint32_t *tb = m->tri + 3 * (corner[i + b2] & 0xffffffffu);
                            uint32_t v = (uint32_t)(corner[i] >> 32);
                            int share = 0;
                            for (int x = 0; x < 3; x++)
                                for (int y = 0; y < 3; y++)
                                    share |= ta[x] == tb[y] && ta[x] != v;
                            if (share) {
                                int ra = (int)a, rb = (int)b2;
                                while (par[ra] != ra)
                                    ra = par[ra];
                                while (par[rb] != rb)
                                    rb = par[rb];
                                par[ra] = rb;
                            }
                        }
                    int groups = 0;
                    for (size_t a = 0; a < k; a++)
                        groups += par[a] == (int)a;
                    t->nonmanifold_vertices += groups > 1;
                } else {
                    t->nonmanifold_vertices++;
                }
                i = j;
            }
            free(corner);
        }
    }
    free(h);
    free(tp);
    free(used);
    return t->once_edges == 0 && t->multi_edges == 0 && t->misoriented_edges == 0 &&
           t->nonmanifold_vertices == 0 && t->degenerate == 0;
}
