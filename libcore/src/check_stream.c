/*
 * check_stream.c - the continuity checker on a mesh that streams past
 * (isomend_check_stream_*): the report of isomend_check() (check.c) on the
 * whole mesh, field for field, holding only what the window of live
 * vertices needs.  It is fed what a stream's sink gets: vertices with
 * consecutive 64-bit ids, triangles of delivered ids, and retire(floor),
 * after which no triangle uses an id below floor.
 *
 * What is complete when a vertex v retires:
 *   - the edges filed under v, their lower end (every triangle using such an
 *     edge uses v): each is counted, classified (border, hole, non-manifold,
 *     misoriented) by check.c's rules, its triangles' sets joined;
 *   - v's fan (every triangle around v): the non-manifold vertex test, and
 *     whether v counts at all (referenced by a triangle).
 * The edge's other end is above v, so not retired yet: its position, needed
 * by the border test, is still in the window.
 *
 * Method.  Every triangle appends three half-edge records (lower id, the
 * other's offset from it and the direction, the triangle's set node) and
 * three corner records (the corner's id, the two other corners' offsets)
 * to two pending arrays, and is tested for degeneracy at once (its
 * positions are live).  retire(floor) takes the records of the vertices
 * below floor out of the pending arrays with one counting sort by id
 * (the rest is compacted in place), then walks those vertices in id order
 * as check.c walks its rows.  With retire called once per layer, as a
 * stream does, a record is moved about twice; a caller retiring one id at
 * a time is batched (work is done once the retired vertices are 1/16 of the
 * pending records), so the cost stays linear.
 *
 * Components and hole loops need sets whose members stream past: a
 * union-find whose nodes carry a reference count (the half-edge records or
 * live vertices naming the node, plus the nodes whose parent it is).  A
 * node whose count drops to zero is freed and releases its parent; a root
 * that is freed is a set with no live member left, one that can never grow
 * again: one component (triangle nodes) or one hole loop (vertex nodes,
 * joined by hole edges, made only for vertices on a hole edge).  Path
 * halving moves references from a parent to the grandparent.
 *
 * Memory: positions (16 bytes a live vertex, in a ring indexed by id), the
 * pending records (32 bytes a live triangle corner), the set nodes of live
 * triangles and hole vertices, and scratch of the largest batch retired: all
 * linear in the window, none in the mesh.  Nothing is allocated per
 * triangle; the arrays grow by doubling and are kept for reuse.
 *
 * Sheared and uneven slices (isomend_volume.slice_origins):
 * isomend_check_stream_begin_volume() keeps the marched slices' origins
 * (24 bytes a slice) and moves every vertex into the unsheared frame as
 * sheared_check() (slice_geometry.c) does, with the same arithmetic, so the
 * report is isomend_mesh_check()'s.
 */
#include "isomend.h"

#include "extract_internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX
/* The most live ids at once: offsets between ids of a triangle are kept in
 * 32 bits. */
#define WINDOW_LIMIT ((uint64_t)1 << 31)

typedef struct vslot { /* a live vertex, at ring[id & mask] */
    float p[3];        /* in the frame of the check              */
    uint32_t hole;     /* its hole-loop node, or NONE            */
} vslot;

/* A directed triangle edge, filed under its lower id. */
typedef struct hrec {
    uint64_t lo;
    uint32_t d;   /* (other - lo) << 1 | (1 when it runs lower -> higher) */
    uint32_t tri; /* the triangle's set node                              */
} hrec;

/* A triangle's corner. */
typedef struct crec {
    uint64_t v;
    uint32_t a, b; /* the two other corners minus v (mod 2^32; 0: v itself) */
} crec;

/* A union-find of reference-counted nodes (see the overview). */
typedef struct ufnode {
    uint32_t parent; /* itself at a root; the next free node when free */
    uint32_t ref;
    uint32_t rank;
} ufnode;

typedef struct ufpool {
    ufnode *n;
    uint32_t cap, free_list, used;
    uint64_t finished; /* sets whose root was freed */
} ufpool;

/* Scratch of the per-vertex tests. */
typedef struct pair {
    uint32_t key, idx;
} pair;

struct isomend_check_stream {
    isomend_status status; /* sticky: the first failure                       */
    int started, finished;
    double box[6], extent;
    double *so; /* sheared frame: marched slice origins (3 a slice), or NULL  */
    int64_t n2;
    uint64_t next, floor, done; /* delivered [.., next); retired below floor;
                                 * processed below done (done <= floor)      */
    vslot *ring;
    uint64_t mask; /* ring capacity - 1 (a power of two)                     */
    hrec *half, *hs;
    crec *corner, *cs;
    size_t nhalf, hcap, hscap, ncorner, ccap, cscap;
    size_t *hoff, *coff; /* per vertex of a batch                            */
    size_t hoffcap, coffcap;
    pair *pairs;
    uint32_t *fan; /* a vertex's fan union-find                            */
    size_t paircap, fancap;
    ufpool tri, hole;
    isomend_check_report r;
    uint64_t bytes, peak;
};

/* ------------------------------------------------------------ memory */

static void account(isomend_check_stream *s, size_t old_bytes, size_t new_bytes)
{
    s->bytes += (uint64_t)new_bytes - (uint64_t)old_bytes;
    if (s->bytes > s->peak)
        s->peak = s->bytes;
}

/* Grows the array whose pointer is at `where` (*cap elements of `size`) to
 * hold `need`, doubling.  The pointer is read and written with memcpy: any
 * object pointer type. */
static int grow(isomend_check_stream *s, void *where, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return 1;
    size_t n = *cap ? *cap : 64;
    while (n < need)
        n *= 2;
    if (n > SIZE_MAX / size)
        return 0;
    void *p;
    memcpy(&p, where, sizeof p);
    void *q = realloc(p, n * size);
    if (!q)
        return 0;
    account(s, *cap * size, n * size);
    memcpy(where, &q, sizeof q);
    *cap = n;
    return 1;
}

/* ------------------------------------------------- the counted union-find */

static isomend_status uf_new(isomend_check_stream *s, ufpool *u, uint32_t ref, uint32_t *out)
{
    if (u->free_list == NONE) {
        if (u->used == u->cap) {
            size_t cap = u->cap;
            if (cap >= NONE / 2)
                return ISOMEND_ERR_TOO_LARGE;
            if (!grow(s, &u->n, &cap, cap + 1, sizeof(ufnode)))
                return ISOMEND_ERR_OUT_OF_MEMORY;
            u->cap = (uint32_t)cap;
        }
        u->free_list = u->used;
        u->n[u->used++].parent = NONE;
    }
    const uint32_t x = u->free_list;
    u->free_list = u->n[x].parent;
    u->n[x].parent = x;
    u->n[x].ref = ref;
    u->n[x].rank = 0;
    *out = x;
    return ISOMEND_OK;
}

static void uf_free(ufpool *u, uint32_t x)
{
    u->n[x].parent = u->free_list;
    u->free_list = x;
}

/* The root of x, halving the path: x's reference moves from its parent to
 * its grandparent, and a parent left with none is freed. */
static uint32_t uf_find(ufpool *u, uint32_t x)
{
    ufnode *n = u->n;
    for (;;) {
        const uint32_t p = n[x].parent;
        if (p == x)
            return x;
        const uint32_t g = n[p].parent;
        if (g == p)
            return p;
        n[x].parent = g;
        n[g].ref++;
        if (--n[p].ref == 0) { /* p was only x's parent: gone, g loses it */
            n[g].ref--;
            uf_free(u, p);
        }
        x = g;
    }
}

static void uf_union(ufpool *u, uint32_t a, uint32_t b)
{
    a = uf_find(u, a);
    b = uf_find(u, b);
    if (a == b)
        return;
    ufnode *n = u->n;
    if (n[a].rank < n[b].rank) {
        const uint32_t t = a;
        a = b;
        b = t;
    }
    n[b].parent = a;
    n[a].ref++;
    if (n[a].rank == n[b].rank)
        n[a].rank++;
}

/* Drops one reference to x; nodes left with none are freed up the tree,
 * and a freed root is a finished set. */
static void uf_release(ufpool *u, uint32_t x)
{
    ufnode *n = u->n;
    while (--n[x].ref == 0) {
        const uint32_t p = n[x].parent;
        uf_free(u, x);
        if (p == x) {
            u->finished++;
            return;
        }
        x = p;
    }
}

/* ----------------------------------------------- check.c's two tests */

/* check.c's on_box_face(), the same arithmetic (the reports must agree). */
static int on_box_face(const float *p, const float *q, const double *box, double extent)
{
    for (int a = 0; a < 3; a++)
        for (int side = 0; side < 2; side++) {
            double plane = box[3 * side + a];
            double tol = 1e-6 * extent + 4.0 * FLT_EPSILON * fabs(plane);
            if (fabs((double)p[a] - plane) <= tol && fabs((double)q[a] - plane) <= tol)
                return 1;
        }
    return 0;
}

/* check.c's degenerate(): a repeated index or a zero cross product. */
static int degenerate(const float *a, const float *b, const float *c, const uint64_t *t)
{
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2])
        return 1;
    double u[3], v[3];
    for (int i = 0; i < 3; i++) {
        u[i] = (double)b[i] - a[i];
        v[i] = (double)c[i] - a[i];
    }
    double x = u[1] * v[2] - u[2] * v[1], y = u[2] * v[0] - u[0] * v[2],
           z = u[0] * v[1] - u[1] * v[0];
    return x == 0.0 && y == 0.0 && z == 0.0;
}

/* ------------------------------------------------------------ begin */

static isomend_status begin_box(const double box[6], isomend_check_stream **out)
{
    isomend_check_stream *s = calloc(1, sizeof *s);
    if (!s)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    account(s, 0, sizeof *s);
    memcpy(s->box, box, sizeof s->box);
    for (int a = 0; a < 3; a++)
        if (s->box[3 + a] - s->box[a] > s->extent)
            s->extent = s->box[3 + a] - s->box[a];
    s->tri.free_list = s->hole.free_list = NONE;
    *out = s;
    return ISOMEND_OK;
}

isomend_status isomend_check_stream_begin(const double box[6], isomend_check_stream **out)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    if (!box)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    return begin_box(box, out);
}

isomend_status isomend_check_stream_begin_volume(const isomend_volume *desc,
                                                 const isomend_options *opts,
                                                 isomend_check_stream **out)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    if (!desc)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_options defaults;
    isomend_options_init(&defaults);
    isomend_volume v = *desc;
    memset(v.strides, 0, sizeof v.strides);
    ctx c;
    memset(&c, 0, sizeof c);
    isomend_status status = ctx_setup(&c, &v, opts ? opts : &defaults);
    if (status != ISOMEND_OK)
        return status;
    const grid *g = &c.g;
    double box[6];
    for (int a = 0; a < 3; a++) { /* extract.c's grid box */
        box[a] = g->o[a];
        box[3 + a] = g->o[a] + (double)(g->N[a] - 1) * g->h[a];
    }
    double *so = NULL;
    if (g->slices.so) { /* sheared_check()'s frame and box */
        so = malloc(3 * sizeof(double) * (size_t)g->N[2]);
        if (!so)
            return ISOMEND_ERR_OUT_OF_MEMORY;
        for (int64_t m = 0; m < g->N[2]; m++)
            slice_origin(&g->slices, m, so + 3 * m);
        for (int a = 0; a < 2; a++) {
            box[a] = -(double)g->pad * g->h[a];
            box[3 + a] = box[a] + (double)(g->N[a] - 1) * g->h[a];
        }
        box[2] = so[2];
        box[5] = so[3 * (g->N[2] - 1) + 2];
    }
    status = begin_box(box, out);
    if (status != ISOMEND_OK) {
        free(so);
        return status;
    }
    (*out)->so = so;
    (*out)->n2 = g->N[2];
    if (so)
        account(*out, 0, 3 * sizeof(double) * (size_t)g->N[2]);
    return ISOMEND_OK;
}

void isomend_check_stream_destroy(isomend_check_stream *s)
{
    if (!s)
        return;
    free(s->so);
    free(s->ring);
    free(s->half);
    free(s->hs);
    free(s->corner);
    free(s->cs);
    free(s->hoff);
    free(s->coff);
    free(s->pairs);
    free(s->fan);
    free(s->tri.n);
    free(s->hole.n);
    free(s);
}

uint64_t isomend_check_stream_peak_bytes(const isomend_check_stream *s)
{
    return s ? s->peak : 0;
}

static isomend_status fail(isomend_check_stream *s, isomend_status status)
{
    if (s->status == ISOMEND_OK)
        s->status = status;
    return s->status;
}

/* ------------------------------------------------- retiring: the tests */

static void sort_pairs(pair *p, size_t n)
{
    for (size_t i = 1; i < n; i++) { /* short lists: insertion sort */
        pair x = p[i];
        size_t j = i;
        while (j > 0 && p[j - 1].key > x.key) {
            p[j] = p[j - 1];
            j--;
        }
        p[j] = x;
    }
}

static int pair_cmp(const void *a, const void *b)
{
    const uint32_t x = ((const pair *)a)->key, y = ((const pair *)b)->key;
    return x < y ? -1 : x > y;
}

static uint32_t fan_find(uint32_t *parent, uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    return x;
}

/* check.c's count_fans() > 1 on v's corners c[0..n): entries joined by a
 * shared corner other than v. */
static int several_fans(isomend_check_stream *s, const crec *c, size_t n)
{
    pair *p = s->pairs;
    uint32_t *parent = s->fan;
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        parent[i] = (uint32_t)i;
        if (c[i].a) {
            p[m].key = c[i].a;
            p[m++].idx = (uint32_t)i;
        }
        if (c[i].b) {
            p[m].key = c[i].b;
            p[m++].idx = (uint32_t)i;
        }
    }
    if (m > 64)
        qsort(p, m, sizeof *p, pair_cmp);
    else
        sort_pairs(p, m);
    size_t fans = n;
    for (size_t i = 1; i < m; i++)
        if (p[i].key == p[i - 1].key) {
            const uint32_t a = fan_find(parent, p[i].idx), b = fan_find(parent, p[i - 1].idx);
            if (a != b) {
                parent[a < b ? b : a] = a < b ? a : b;
                fans--;
            }
        }
    return fans > 1;
}

static void sort_halves(hrec *h, size_t n)
{
    for (size_t i = 1; i < n; i++) {
        hrec x = h[i];
        size_t j = i;
        while (j > 0 && (h[j - 1].d >> 1) > (x.d >> 1)) {
            h[j] = h[j - 1];
            j--;
        }
        h[j] = x;
    }
}

static int half_cmp(const void *a, const void *b)
{
    const uint32_t x = ((const hrec *)a)->d >> 1, y = ((const hrec *)b)->d >> 1;
    return x < y ? -1 : x > y;
}

/* The hole-loop node of live vertex id, made on first use. */
static isomend_status hole_node(isomend_check_stream *s, uint64_t id, uint32_t *out)
{
    vslot *v = &s->ring[id & s->mask];
    if (v->hole == NONE) {
        isomend_status st = uf_new(s, &s->hole, 1, &v->hole);
        if (st != ISOMEND_OK)
            return st;
    }
    *out = v->hole;
    return ISOMEND_OK;
}

/* Vertex v's edges h[0..n) (filed under it) are complete: check.c's loop
 * over a row. */
static isomend_status vertex_edges(isomend_check_stream *s, uint64_t v, hrec *h, size_t n)
{
    if (n > 64)
        qsort(h, n, sizeof *h, half_cmp);
    else
        sort_halves(h, n);
    isomend_check_report *r = &s->r;
    const float *p = s->ring[v & s->mask].p;
    for (size_t i = 0; i < n;) {
        const uint32_t other = h[i].d >> 1;
        size_t j = i + 1;
        unsigned fwd = h[i].d & 1;
        while (j < n && (h[j].d >> 1) == other) {
            fwd += h[j].d & 1;
            uf_union(&s->tri, h[i].tri, h[j].tri);
            j++;
        }
        const size_t uses = j - i;
        r->edges++;
        if (uses == 1) {
            const uint64_t w = v + other;
            if (on_box_face(p, s->ring[w & s->mask].p, s->box, s->extent)) {
                r->border_edges++;
            } else {
                r->hole_edges++;
                uint32_t a, b;
                isomend_status st = hole_node(s, v, &a);
                if (st == ISOMEND_OK)
                    st = hole_node(s, w, &b);
                if (st != ISOMEND_OK)
                    return st;
                uf_union(&s->hole, a, b);
            }
        } else if (uses == 2) {
            if (fwd != 1)
                r->misoriented_edges++;
        } else {
            r->nonmanifold_edges++;
        }
        i = j;
    }
    for (size_t i = 0; i < n; i++)
        uf_release(&s->tri, h[i].tri);
    return ISOMEND_OK;
}

/* The records of ids below `floor` in rec[0..n), sorted by id into out
 * (grown to fit), the others compacted in place; off[i] ends up as the end
 * of id base + i's records.  One function per record type. */
#define TAKE_BELOW(name, type, key)                                                                \
    static int name(isomend_check_stream *s, type *rec, size_t *n, type **out, size_t *outcap,     \
                    size_t *off, uint64_t base, uint64_t floor)                                    \
    {                                                                                              \
        const size_t m = (size_t)(floor - base);                                                   \
        memset(off, 0, sizeof(size_t) * (m + 1));                                                  \
        for (size_t i = 0; i < *n; i++)                                                            \
            if (rec[i].key < floor)                                                                \
                off[rec[i].key - base + 1]++;                                                      \
        for (size_t i = 0; i < m; i++)                                                             \
            off[i + 1] += off[i];                                                                  \
        if (!grow(s, out, outcap, off[m], sizeof(type)))                                           \
            return 0;                                                                              \
        type *o = *out;                                                                            \
        size_t kept = 0;                                                                           \
        for (size_t i = 0; i < *n; i++) {                                                          \
            const type r = rec[i];                                                                 \
            if (r.key < floor)                                                                     \
                o[off[r.key - base]++] = r;                                                        \
            else                                                                                   \
                rec[kept++] = r;                                                                   \
        }                                                                                          \
        *n = kept;                                                                                 \
        return 1;                                                                                  \
    }
TAKE_BELOW(take_halves, hrec, lo)
TAKE_BELOW(take_corners, crec, v)
#undef TAKE_BELOW

/* Every vertex below s->floor is tested and forgotten. */
static isomend_status process(isomend_check_stream *s)
{
    const uint64_t base = s->done, floor = s->floor;
    if (floor == base)
        return ISOMEND_OK;
    const size_t m = (size_t)(floor - base);
    if (!grow(s, &s->hoff, &s->hoffcap, m + 1, sizeof(size_t)) ||
        !grow(s, &s->coff, &s->coffcap, m + 1, sizeof(size_t)))
        return ISOMEND_ERR_OUT_OF_MEMORY;
    size_t *hoff = s->hoff, *coff = s->coff;
    if (!take_halves(s, s->half, &s->nhalf, &s->hs, &s->hscap, hoff, base, floor) ||
        !take_corners(s, s->corner, &s->ncorner, &s->cs, &s->cscap, coff, base, floor))
        return ISOMEND_ERR_OUT_OF_MEMORY;
    /* off[i] is now the end of vertex base + i's records */
    isomend_check_report *r = &s->r;
    size_t h0 = 0, c0 = 0;
    for (size_t i = 0; i < m; i++) {
        const uint64_t v = base + i;
        const size_t h1 = hoff[i], c1 = coff[i], nv = c1 - c0;
        if (nv) {
            r->vertices++;
            if (nv > 1) {
                if (!grow(s, &s->pairs, &s->paircap, 2 * nv, sizeof(pair)) ||
                    !grow(s, &s->fan, &s->fancap, nv, sizeof(uint32_t)))
                    return ISOMEND_ERR_OUT_OF_MEMORY;
                r->nonmanifold_vertices += (uint64_t)several_fans(s, s->cs + c0, nv);
            }
        }
        isomend_status st = vertex_edges(s, v, s->hs + h0, h1 - h0);
        if (st != ISOMEND_OK)
            return st;
        vslot *slot = &s->ring[v & s->mask];
        if (slot->hole != NONE) {
            uf_release(&s->hole, slot->hole);
            slot->hole = NONE;
        }
        h0 = h1;
        c0 = c1;
    }
    s->done = floor;
    return ISOMEND_OK;
}

/* ------------------------------------------------------------ feeding */

/* Makes the ring hold ids [s->done, end). */
static isomend_status ring_fit(isomend_check_stream *s, uint64_t end)
{
    const uint64_t need = end - s->done;
    if (s->ring && need <= s->mask + 1)
        return ISOMEND_OK;
    uint64_t cap = s->ring ? 2 * (s->mask + 1) : 1024;
    while (cap < need)
        cap *= 2;
    if (cap > SIZE_MAX / sizeof(vslot))
        return ISOMEND_ERR_TOO_LARGE;
    vslot *ring = malloc(sizeof(vslot) * (size_t)cap);
    if (!ring)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    for (uint64_t id = s->done; id < s->next; id++)
        ring[id & (cap - 1)] = s->ring[id & s->mask];
    account(s, s->ring ? sizeof(vslot) * (size_t)(s->mask + 1) : 0, sizeof(vslot) * (size_t)cap);
    free(s->ring);
    s->ring = ring;
    s->mask = cap - 1;
    return ISOMEND_OK;
}

/* sheared_check()'s move into the unsheared frame, the same arithmetic. */
static void unshear(const isomend_check_stream *s, const float *in, float *p)
{
    const double *o = s->so;
    const int64_t N2 = s->n2;
    const double z = in[2];
    int64_t lo = 0, hi = N2 - 1;
    while (hi - lo > 1) {
        const int64_t mid = (lo + hi) / 2;
        if (o[3 * mid + 2] <= z)
            lo = mid;
        else
            hi = mid;
    }
    double t = N2 > 1 ? (z - o[3 * lo + 2]) / (o[3 * hi + 2] - o[3 * lo + 2]) : 0.0;
    t = t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
    for (int a = 0; a < 2; a++) {
        const double shift = (1.0 - t) * o[3 * lo + a] + t * o[3 * hi + a];
        p[a] = (float)((double)in[a] - shift);
    }
    p[2] = in[2];
}

isomend_status isomend_check_stream_vertices(isomend_check_stream *s, uint64_t first_id,
                                             size_t count, const float *positions)
{
    if (!s)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (s->status != ISOMEND_OK)
        return s->status;
    if (s->finished || (count && !positions))
        return fail(s, ISOMEND_ERR_INVALID_ARGUMENT);
    if (!s->started) { /* the first call starts the numbering */
        if (first_id < s->floor)
            return fail(s, ISOMEND_ERR_INVALID_ARGUMENT);
        s->started = 1;
        s->next = s->floor = s->done = first_id;
    }
    if (first_id != s->next || count > UINT64_MAX - first_id)
        return fail(s, ISOMEND_ERR_INVALID_ARGUMENT);
    const uint64_t end = first_id + count;
    if (end - s->floor >= WINDOW_LIMIT)
        return fail(s, ISOMEND_ERR_TOO_LARGE);
    if (s->done < s->floor && s->ring && end - s->done > s->mask + 1) {
        isomend_status st = process(s); /* rather than growing the ring */
        if (st != ISOMEND_OK)
            return fail(s, st);
    }
    isomend_status st = ring_fit(s, end);
    if (st != ISOMEND_OK)
        return fail(s, st);
    for (size_t i = 0; i < count; i++) {
        vslot *v = &s->ring[(first_id + i) & s->mask];
        if (s->so)
            unshear(s, positions + 3 * i, v->p);
        else
            memcpy(v->p, positions + 3 * i, sizeof v->p);
        v->hole = NONE;
    }
    s->next = end;
    return ISOMEND_OK;
}

isomend_status isomend_check_stream_triangles(isomend_check_stream *s, size_t count,
                                              const uint64_t *ids)
{
    if (!s)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (s->status != ISOMEND_OK)
        return s->status;
    if (s->finished || (count && !ids) || count > SIZE_MAX / 3)
        return fail(s, ISOMEND_ERR_INVALID_ARGUMENT);
    const uint64_t lo = s->floor, hi = s->next;
    for (size_t i = 0; i < 3 * count; i++)
        if (ids[i] < lo || ids[i] >= hi) /* retired, not delivered, or foreign */
            return fail(s, ISOMEND_ERR_INVALID_ARGUMENT);
    if (!grow(s, &s->half, &s->hcap, s->nhalf + 3 * count, sizeof(hrec)) ||
        !grow(s, &s->corner, &s->ccap, s->ncorner + 3 * count, sizeof(crec)))
        return fail(s, ISOMEND_ERR_OUT_OF_MEMORY);
    hrec *h = s->half + s->nhalf;
    crec *c = s->corner + s->ncorner;
    const vslot *ring = s->ring;
    const uint64_t mask = s->mask;
    for (size_t t = 0; t < count; t++) {
        const uint64_t *v = ids + 3 * t;
        uint32_t node;
        isomend_status st = uf_new(s, &s->tri, 3, &node);
        if (st != ISOMEND_OK)
            return fail(s, st);
        for (int k = 0; k < 3; k++) {
            const uint64_t a = v[k], b = v[(k + 1) % 3], x = v[(k + 2) % 3];
            h->lo = a < b ? a : b;
            h->d = (uint32_t)((a < b ? b - a : a - b) << 1) | (a < b);
            h->tri = node;
            h++;
            c->v = a;
            c->a = (uint32_t)(b - a);
            c->b = (uint32_t)(x - a);
            c++;
        }
        s->r.degenerate_triangles +=
            (uint64_t)degenerate(ring[v[0] & mask].p, ring[v[1] & mask].p, ring[v[2] & mask].p, v);
    }
    s->nhalf += 3 * count;
    s->ncorner += 3 * count;
    s->r.triangles += count;
    return ISOMEND_OK;
}

isomend_status isomend_check_stream_retire(isomend_check_stream *s, uint64_t floor)
{
    if (!s)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (s->status != ISOMEND_OK)
        return s->status;
    if (s->finished || floor < s->floor || (s->started && floor > s->next))
        return fail(s, ISOMEND_ERR_INVALID_ARGUMENT);
    if (!s->started) { /* nothing delivered: the first id is at least floor */
        s->floor = floor;
        return ISOMEND_OK;
    }
    s->floor = floor;
    /* Batched: the work of a batch is linear in the pending records. */
    if ((floor - s->done) * 16 >= (uint64_t)(s->nhalf + s->ncorner)) {
        isomend_status st = process(s);
        if (st != ISOMEND_OK)
            return fail(s, st);
    }
    return ISOMEND_OK;
}

isomend_status isomend_check_stream_finish(isomend_check_stream *s, isomend_check_report *report)
{
    if (!s || !report)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    memset(report, 0, sizeof *report);
    if (s->status != ISOMEND_OK)
        return s->status;
    if (s->finished)
        return fail(s, ISOMEND_ERR_INVALID_ARGUMENT);
    s->floor = s->next;
    isomend_status st = process(s);
    if (st != ISOMEND_OK)
        return fail(s, st);
    s->finished = 1;
    isomend_check_report *r = &s->r;
    r->components = s->tri.finished;
    r->hole_loops = s->hole.finished;
    r->euler = (int64_t)r->vertices - (int64_t)r->edges + (int64_t)r->triangles;
    *report = *r;
    return ISOMEND_OK;
}

/* ------------------------------------------------------------ as a sink */

static int sink_vertices(void *user, uint64_t first_id, size_t count, const float *positions,
                         const float *normals, const uint64_t *keys)
{
    (void)normals;
    (void)keys;
    return isomend_check_stream_vertices(user, first_id, count, positions) != ISOMEND_OK;
}

static int sink_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    (void)origins;
    return isomend_check_stream_triangles(user, count, ids) != ISOMEND_OK;
}

static int sink_retire(void *user, uint64_t floor)
{
    return isomend_check_stream_retire(user, floor) != ISOMEND_OK;
}

isomend_status isomend_check_stream_sink(isomend_check_stream *s, isomend_mesh_sink *sink)
{
    if (!s || !sink)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    memset(sink, 0, sizeof *sink);
    sink->user = s;
    sink->vertices = sink_vertices;
    sink->triangles = sink_triangles;
    sink->retire = sink_retire;
    return ISOMEND_OK;
}
