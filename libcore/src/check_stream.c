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
 *     edge uses v): each is counted and classified (border, hole,
 *     non-manifold, misoriented) by check.c's rules;
 *   - v's fan (every triangle around v): the non-manifold vertex test, and
 *     whether v counts at all (referenced by a triangle).
 * The edge's other end is above v, so not retired yet: its position, needed
 * by the border test, is still in the window.
 *
 * Method: edges are matched as triangles arrive; nothing is sorted.  Every
 * live vertex v has a small table of its neighbours w, keyed by w - v (8
 * entries in v's own slot, compared at once with SSE2; beyond 8, a block
 * of 16 or 32 scanned, larger ones hashed).  At each corner x of a
 * triangle the next and the previous corner are looked up in x's table (added when new), then
 *   - the fan: the two entries are joined in the table's own union-find
 *     (check.c's count_fans() joins x's corners through shared neighbours:
 *     the same pieces; a block of 8 keeps every entry at its root).  x's
 *     count of pieces grows with each new neighbour and each corner whose
 *     other two corners are x itself, and drops with each join of two
 *     pieces: more than one piece at retirement is a non-manifold vertex,
 *     none an unreferenced one;
 *   - the edges: each directed edge counts on its lower end's entry for the
 *     higher one (self-edges under the key 0): triangles using it, how many
 *     run lower -> higher (counting stops at 3: classification needs no
 *     more), and its component;
 *   - the degeneracy test, its positions being live.
 * retire(floor) walks the vertices below floor in id order: each edge in
 * its table (keys >= 0) is classified and its component reference dropped,
 * and the block goes back to a free list.  The work is constant per
 * triangle and per retired neighbour (a high-degree vertex's table is
 * hashed), whatever the order of the triangles or how often retire is
 * called.
 *
 * Components and hole loops need sets whose members stream past: a
 * union-find whose nodes carry a reference count (the live edges or live
 * vertices naming the node, plus the nodes whose parent it is).  A triangle
 * joins the sets of its edges already seen (triangles sharing an edge are
 * one component) and names the result on its new edges; a triangle with no
 * edge seen starts a node.  A node whose count drops to zero is freed and
 * releases its parent; a root that is freed is a set with no live member
 * left, one that can never grow again: one component (edge sets) or one
 * hole loop (vertex nodes, joined by hole edges, made only for vertices on
 * a hole edge).  Path halving moves references from a parent to the
 * grandparent.
 *
 * Memory: the ring of live vertices (168 bytes each, in chunks of 4096 made
 * as ids come and kept for reuse as they retire: position, hole node, a table of 8
 * neighbours), the tables of vertices with more (16 bytes a neighbour,
 * blocks at most twice the size needed, kept on free lists by size for
 * reuse), the set nodes the live edges name and their parents: all linear in the
 * window, none in the mesh.  Nothing is allocated per triangle once the
 * window has been seen; arrays grow by doubling and are kept.  The first 8
 * neighbours live in the slot, not in a block of their own, because the
 * triangles and the retirements reach the slots in about id order, which
 * the caches follow, while blocks taken from free lists are scattered (a
 * block's pointer and the free list's next pointer were two cache misses a
 * vertex): 1.2x standalone, and more beside the threads of a streaming
 * extraction (docs/streaming.md).
 *
 * One object, fed by one thread at a time (any thread: the stream's, or a
 * worker the caller hands batches to); nothing in it is shared.
 *
 * Sheared and uneven slices (isomend_volume.slice_origins):
 * isomend_check_stream_begin_volume() keeps the marched slices' origins
 * (24 bytes a slice) and moves every vertex into the unsheared frame as
 * sheared_check() (check.c) does, with the same arithmetic, so the
 * report is isomend_mesh_check()'s.
 */
#include "isomend.h"

#include "check_rules.h"
#include "context.h"
#include "slice_geometry.h"
#include "extract.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#define NONE UINT32_MAX
/* The most live ids at once: the offset between two live ids fits an
 * int32_t (never INT32_MIN, the key of an empty entry). */
#define WINDOW_LIMIT ((uint64_t)1 << 31)
#define NO_KEY INT32_MIN
/* Neighbour tables: class c holds 8 << c entries; up to SCAN_MAX looked up
 * by comparing keys, larger ones hashed (2 slots an entry). */
#define CLASSES 28
#define SCAN_MAX 32u

/* A neighbour w of vertex v (its key, w - v, is kept apart: lookups read
 * keys only). */
typedef struct nbr {
    uint32_t up;   /* the fan union-find's parent, an index in the table    */
    uint32_t set;  /* edge (v, w), w >= v: its component node, NONE before  */
    uint8_t uses;  /* triangles on the edge, up to 3                        */
    uint8_t fwd;   /* of those, running v -> w                              */
} nbr;

typedef struct vslot { /* a live vertex, at slot(s, id) */
    float p[3];        /* in the frame of the check                        */
    uint32_t hole;     /* its hole-loop node, or NONE                      */
    int32_t *key;      /* its neighbours' keys, w - v: k8, or a block      */
    nbr *e;            /* and entries: e8, or in the same block            */
    uint32_t n;        /* neighbours in the table                          */
    uint32_t fans;     /* pieces of its fan so far; 0: no triangle uses it */
    int32_t k8[8];     /* the table while 8 neighbours fit (most vertices: */
    nbr e8[8];         /* read in id order with the ring, no block to find) */
} vslot;

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

struct isomend_check_stream {
    isomend_status status; /* sticky: the first failure                       */
    int started, finished;
    double box[6], extent;
    double *so; /* sheared frame: marched slice origins (3 a slice), or NULL  */
    int64_t n2;
    uint64_t next, floor; /* delivered [.., next); retired below floor        */
    vslot **chunks;  /* the ring of live vertices in chunks of CHUNK slots:   */
    uint64_t cmask;  /* id's chunk at (id >> CHUNK_BITS) & cmask, NULL when  */
    vslot *spare;    /* none of its ids is live; the retired chunks kept for  */
                     /* reuse (never more than were live at once), the next   */
                     /* one in their first bytes                               */
    void *free_blocks[CLASSES]; /* tables' blocks, by class, for reuse: the
                                 * next free one in their first bytes      */
    ufpool tri, hole; /* components (of edges), hole loops (of vertices)    */
    isomend_check_report r;
    uint64_t bytes, peak;
};

/* ------------------------------------------------------------ memory */

/* The ring of live vertices is cut in chunks of 4096 slots (688 KiB), made
 * as ids arrive and given back as they retire: its memory follows the live
 * window, where one array of a power-of-two capacity held up to twice it
 * (a 512 x 512 busy surface: 75 000 live vertices in 131 072 slots).  The
 * chunks' table is the power of two; slots never move, so a table in its
 * slot (k8) needs no fixing when the ring grows. */
#define CHUNK_BITS 12
#define CHUNK ((uint64_t)1 << CHUNK_BITS)

static inline vslot *slot(const isomend_check_stream *s, uint64_t id)
{
    return s->chunks[(id >> CHUNK_BITS) & s->cmask] + (id & (CHUNK - 1));
}

static void account(isomend_check_stream *s, size_t old_bytes, size_t new_bytes)
{
    s->bytes += (uint64_t)new_bytes - (uint64_t)old_bytes;
    if (s->bytes > s->peak)
        s->peak = s->bytes;
}

/* Grows the array whose pointer is at `where` (*cap elements of `size`) to
 * hold `need`, doubling from about 4 KB.  The pointer is read and written
 * with memcpy: any object pointer type. */
static int grow(isomend_check_stream *s, void *where, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return 1;
    size_t n = *cap ? *cap : size < 4096 ? 4096 / size : 1;
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

/* Joins the sets of roots a and b; the root of the union. */
static uint32_t uf_link(ufpool *u, uint32_t a, uint32_t b)
{
    if (a == b)
        return a;
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
    return a;
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

/* ------------------------------------------------- neighbour tables */

/* The class of a table holding n >= 1 neighbours (one grows when full). */
static uint32_t class_of(uint32_t n)
{
    uint32_t cls = 0;
    while ((8u << cls) < n)
        cls++;
    return cls;
}

/* Bytes of a class cls block: keys, entries, then for hashed classes the
 * hash (2 slots an entry: entry index + 1, 0 when empty). */
static size_t block_bytes(uint32_t cls)
{
    const size_t cap = (size_t)8 << cls;
    return (sizeof(int32_t) + sizeof(nbr)) * cap + (cap > SCAN_MAX ? 2 * sizeof(uint32_t) * cap : 0);
}

static uint32_t *hash_of(const vslot *v, uint32_t cls)
{
    return (uint32_t *)(void *)(v->e + ((size_t)8 << cls));
}

/* The first hash slot of key in a class cls table (16 << cls slots). */
static uint32_t hash_slot(int32_t key, uint32_t cls)
{
    return ((uint32_t)key * 0x9E3779B1u) >> (32 - (cls + 4));
}

/* Gives v's table back to its class's free list. */
static void table_free(isomend_check_stream *s, vslot *v)
{
    if (v->key == v->k8)
        return;
    void **head = &s->free_blocks[class_of(v->n)];
    memcpy(v->key, head, sizeof *head);
    *head = v->key;
    v->key = v->k8;
    v->e = v->e8;
}

/* Makes v's (full or missing) table twice as large, from a free block or a
 * new one; 0 when out of memory. */
static int table_grow(isomend_check_stream *s, vslot *v)
{
    const uint32_t cls = class_of(v->n) + 1; /* class 0 is the slot's own k8 */
    if (cls >= CLASSES)
        return 0;
    void *blk = s->free_blocks[cls];
    if (blk) {
        memcpy(&s->free_blocks[cls], blk, sizeof blk);
    } else {
        blk = malloc(block_bytes(cls));
        if (!blk)
            return 0;
        account(s, 0, block_bytes(cls));
    }
    const size_t cap = (size_t)8 << cls;
    int32_t *key = blk;
    nbr *e = (nbr *)(void *)(key + cap);
    memcpy(key, v->key, sizeof(int32_t) * v->n);
    memcpy(e, v->e, sizeof(nbr) * v->n);
    table_free(s, v);
    v->key = key;
    v->e = e;
    if (cap > SCAN_MAX) {
        uint32_t *hash = hash_of(v, cls);
        memset(hash, 0, 2 * sizeof(uint32_t) * cap);
        for (uint32_t i = 0; i < v->n; i++) {
            uint32_t h = hash_slot(key[i], cls);
            while (hash[h])
                h = (h + 1) & (uint32_t)(2 * cap - 1);
            hash[h] = i + 1;
        }
    }
    return 1;
}

/* Adds neighbour key to v's table, which has room: a piece of v's fan of
 * its own (the self-edge's key 0 is no neighbour).  Its index. */
static uint32_t table_add(vslot *v, int32_t key)
{
    const uint32_t at = v->n++;
    v->key[at] = key;
    v->e[at].up = at;
    v->e[at].set = NONE;
    v->e[at].uses = v->e[at].fwd = 0;
    v->fans += key != 0;
    return at;
}

/* neighbour() beyond a table of 8 with room. */
static uint32_t neighbour_slow(isomend_check_stream *s, vslot *v, int32_t key)
{
    if (v->n > 8) {
        const uint32_t cls = class_of(v->n), cap = 8u << cls;
        if (cap <= SCAN_MAX) {
            for (uint32_t i = 0; i < v->n; i++)
                if (v->key[i] == key)
                    return i;
        } else {
            const uint32_t *hash = hash_of(v, cls);
            for (uint32_t h = hash_slot(key, cls); hash[h]; h = (h + 1) & (2 * cap - 1))
                if (v->key[hash[h] - 1] == key)
                    return hash[h] - 1;
        }
    }
    if (v->n == 8u << class_of(v->n) && !table_grow(s, v))
        return NONE;
    const uint32_t at = table_add(v, key), cls = class_of(v->n);
    if (8u << cls > SCAN_MAX) {
        uint32_t *hash = hash_of(v, cls);
        uint32_t h = hash_slot(key, cls);
        while (hash[h])
            h = (h + 1) & ((16u << cls) - 1);
        hash[h] = at + 1;
    }
    return at;
}

/* Bit i set when k[i] == key, i < 8. */
static inline uint32_t match8(const int32_t *k, int32_t key)
{
#if defined(__SSE2__)
    const __m128i x = _mm_set1_epi32(key);
    const __m128i lo = _mm_cmpeq_epi32(_mm_loadu_si128((const __m128i *)(const void *)k), x);
    const __m128i hi = _mm_cmpeq_epi32(_mm_loadu_si128((const __m128i *)(const void *)(k + 4)), x);
    return (uint32_t)_mm_movemask_ps(_mm_castsi128_ps(lo)) |
           (uint32_t)_mm_movemask_ps(_mm_castsi128_ps(hi)) << 4;
#else
    uint32_t hit = 0;
    for (uint32_t i = 0; i < 8; i++)
        hit |= (uint32_t)(k[i] == key) << i;
    return hit;
#endif
}

/* The index of neighbour key (w - v) in v's table, added when new; NONE
 * when out of memory.  Most tables are the slot's 8 entries, compared at once
 * (NO_KEY past the end). */
static inline uint32_t neighbour(isomend_check_stream *s, vslot *v, int32_t key)
{
    if (v->n - 1u < 8u) {
        const uint32_t hit = match8(v->key, key);
        if (hit)
            return (uint32_t)__builtin_ctz(hit);
        if (v->n < 8)
            return table_add(v, key);
    }
    return neighbour_slow(s, v, key);
}

static uint32_t fan_find(nbr *e, uint32_t x)
{
    while (e[x].up != x) {
        e[x].up = e[e[x].up].up;
        x = e[x].up;
    }
    return x;
}

/* Neighbours a and b of v are in one piece of its fan (a corner joins
 * them).  A table of 8 keeps every entry's `up` at its root (the join
 * renames a piece: no search); larger tables halve paths. */
static void fan_join(vslot *v, uint32_t a, uint32_t b)
{
    nbr *e = v->e;
    if (v->n <= 8) {
        a = e[a].up;
        b = e[b].up;
    } else {
        a = fan_find(e, a);
        b = fan_find(e, b);
    }
    if (a == b)
        return;
    const uint32_t keep = a < b ? a : b, gone = a < b ? b : a;
    if (v->n <= 8)
        for (uint32_t i = 0; i < v->n; i++)
            e[i].up = e[i].up == gone ? keep : e[i].up;
    else
        e[gone].up = keep;
    v->fans--;
}

/* A triangle's corner at v, the next corner at key ky from v and the
 * previous one at kz: their entries in v's table into *ny, *nz (NONE when
 * kz is 0: that edge is the previous corner's self-edge), the corner's
 * join in v's fan.  0 when out of memory.  With two neighbours and a block
 * of 8, the two keys are looked up in one pass. */
static inline int corner(isomend_check_stream *s, vslot *v, int32_t ky, int32_t kz, uint32_t *ny,
                         uint32_t *nz)
{
    if (ky && kz) {
        uint32_t a, b;
        if (v->n - 1u < 6u) { /* room for both */
            const uint32_t hy = match8(v->key, ky), hz = match8(v->key, kz);
            a = hy ? (uint32_t)__builtin_ctz(hy) : table_add(v, ky);
            b = hz ? (uint32_t)__builtin_ctz(hz) : ky == kz ? a : table_add(v, kz);
        } else {
            a = neighbour(s, v, ky);
            b = neighbour(s, v, kz);
        }
        *ny = a;
        *nz = b;
        if (a == NONE || b == NONE)
            return 0;
        fan_join(v, a, b);
        return 1;
    }
    *ny = neighbour(s, v, ky); /* ky == 0: the self-edge */
    *nz = kz ? neighbour(s, v, kz) : NONE;
    if (!ky && !kz)
        v->fans++; /* a corner with no neighbour: a piece of its own */
    return *ny != NONE && (!kz || *nz != NONE);
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

/* The marched grid of a stream of desc with opts (its samples' strides
 * aside), in c. */
static isomend_status grid_of(const isomend_volume *desc, const isomend_options *opts, ctx *c)
{
    isomend_options defaults;
    isomend_options_init(&defaults);
    isomend_volume v = *desc;
    memset(v.strides, 0, sizeof v.strides);
    memset(c, 0, sizeof *c);
    return ctx_setup(c, &v, opts ? opts : &defaults);
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
    ctx c;
    isomend_status status = grid_of(desc, opts, &c);
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
    if (s->started)
        for (uint64_t id = s->floor; id < s->next; id++)
            table_free(s, slot(s, id));
    for (int c = 0; c < CLASSES; c++)
        while (s->free_blocks[c]) {
            void *blk = s->free_blocks[c];
            memcpy(&s->free_blocks[c], blk, sizeof blk);
            free(blk);
        }
    for (uint64_t c = 0; s->chunks && c <= s->cmask; c++)
        free(s->chunks[c]);
    free(s->chunks);
    while (s->spare) {
        vslot *next;
        memcpy(&next, s->spare, sizeof next);
        free(s->spare);
        s->spare = next;
    }
    free(s->tri.n);
    free(s->hole.n);
    free(s);
}

uint64_t isomend_check_stream_peak_bytes(const isomend_check_stream *s)
{
    return s ? s->peak : 0;
}

/* The live window on the in-memory rule's surface of a vertex every 8
 * marched samples (docs/streaming.md): measured 59 bytes a slice sample on a
 * 384^3 gyroid with a vertex every 8.3 samples, 57 on a busy 512 x 512
 * surface with one every 7 (check_memory in the CLI's JSON, required within
 * this by cli_stream_memory); 80 leaves room for busier surfaces. */
#define CHECK_BYTES_PER_SAMPLE 80.0

uint64_t isomend_check_stream_memory(const isomend_volume *desc, const isomend_options *opts)
{
    ctx c;
    if (!desc || grid_of(desc, opts, &c) != ISOMEND_OK)
        return 0;
    const grid *g = &c.g;
    /* the window; the ring's last chunk and a spare beside it; the
     * slices' origins (begin_volume) and the object */
    const double bytes = CHECK_BYTES_PER_SAMPLE * (double)g->N[0] * (double)g->N[1] +
                         2.0 * (double)(sizeof(vslot) * CHUNK) +
                         (g->slices.so ? 24.0 * (double)g->N[2] : 0.0) +
                         (double)sizeof(isomend_check_stream);
    return bytes < 1.8e19 ? (uint64_t)bytes : UINT64_MAX;
}

static isomend_status fail(isomend_check_stream *s, isomend_status status)
{
    if (s->status == ISOMEND_OK)
        s->status = status;
    return s->status;
}

/* ------------------------------------------------- retiring: the tests */

/* The hole-loop node of live vertex id, made on first use. */
static isomend_status hole_node(isomend_check_stream *s, uint64_t id, uint32_t *out)
{
    vslot *v = slot(s, id);
    if (v->hole == NONE) {
        isomend_status st = uf_new(s, &s->hole, 1, &v->hole);
        if (st != ISOMEND_OK)
            return st;
    }
    *out = v->hole;
    return ISOMEND_OK;
}

/* Vertex id retires: its fan and the edges filed under it are complete
 * (check.c's loop over a row, and count_fans()). */
static isomend_status retire_vertex(isomend_check_stream *s, uint64_t id)
{
    isomend_check_report *r = &s->r;
    vslot *v = slot(s, id);
    r->vertices += v->fans > 0;
    r->nonmanifold_vertices += v->fans > 1;
    const int32_t *key = v->key;
    const nbr *e = v->e;
    for (uint32_t i = 0; i < v->n; i++) {
        if (key[i] < 0) /* filed under the lower neighbour */
            continue;
        r->edges++;
        if (e[i].uses == 1) {
            const uint64_t w = id + (uint32_t)key[i];
            if (on_box_face(v->p, slot(s, w)->p, s->box, s->extent)) {
                r->border_edges++;
            } else {
                r->hole_edges++;
                uint32_t a, b;
                isomend_status st = hole_node(s, id, &a);
                if (st == ISOMEND_OK)
                    st = hole_node(s, w, &b);
                if (st != ISOMEND_OK)
                    return st;
                uf_link(&s->hole, uf_find(&s->hole, a), uf_find(&s->hole, b));
            }
        } else if (e[i].uses == 2) {
            r->misoriented_edges += e[i].fwd != 1;
        } else {
            r->nonmanifold_edges++;
        }
        uf_release(&s->tri, e[i].set);
    }
    table_free(s, v);
    v->n = v->fans = 0;
    if (v->hole != NONE) {
        uf_release(&s->hole, v->hole);
        v->hole = NONE;
    }
    return ISOMEND_OK;
}

/* ------------------------------------------------------------ feeding */

/* Makes the ring hold ids [s->floor, end): the chunks' table wide enough
 * (grown to the next power of two, the chunks re-placed), a chunk for every
 * chunk of ids from s->next's to end's. */
static isomend_status ring_fit(isomend_check_stream *s, uint64_t end)
{
    if (end == s->next)
        return ISOMEND_OK;
    const uint64_t lo = s->floor >> CHUNK_BITS, hi = (end - 1) >> CHUNK_BITS;
    if (!s->chunks || hi - lo > s->cmask) {
        uint64_t n = s->chunks ? 2 * (s->cmask + 1) : 8;
        while (n <= hi - lo)
            n *= 2;
        vslot **t = calloc((size_t)n, sizeof *t);
        if (!t)
            return ISOMEND_ERR_OUT_OF_MEMORY;
        if (s->chunks && s->next > s->floor)
            for (uint64_t c = lo; c <= (s->next - 1) >> CHUNK_BITS; c++)
                t[c & (n - 1)] = s->chunks[c & s->cmask];
        account(s, s->chunks ? sizeof *t * (size_t)(s->cmask + 1) : 0, sizeof *t * (size_t)n);
        free(s->chunks);
        s->chunks = t;
        s->cmask = n - 1;
    }
    /* the chunks of ids [next, end) that hold no live id yet */
    const uint64_t first = s->next > s->floor ? ((s->next - 1) >> CHUNK_BITS) + 1 : s->next >> CHUNK_BITS;
    for (uint64_t c = first; c <= hi; c++) {
        vslot *chunk = s->spare;
        if (chunk)
            memcpy(&s->spare, chunk, sizeof s->spare);
        if (!chunk) {
            if (!(chunk = malloc(sizeof(vslot) * (size_t)CHUNK)))
                return ISOMEND_ERR_OUT_OF_MEMORY;
            account(s, 0, sizeof(vslot) * (size_t)CHUNK);
        }
        s->chunks[c & s->cmask] = chunk;
    }
    return ISOMEND_OK;
}

/* The chunks whose ids all retired below `floor` (from the old floor) given
 * back to the spares: freed and taken again, a chunk's 688 KiB would fault in
 * anew (glibc gives such blocks back to the system), 168 page faults each. */
static void ring_release(isomend_check_stream *s, uint64_t old_floor, uint64_t floor)
{
    if (!s->chunks)
        return;
    const uint64_t hi = floor >> CHUNK_BITS; /* chunk of floor: still live (or next) */
    const uint64_t end = s->next > floor ? hi : (s->next + CHUNK - 1) >> CHUNK_BITS;
    for (uint64_t c = old_floor >> CHUNK_BITS; c < end; c++) {
        vslot **at = &s->chunks[c & s->cmask];
        if (!*at)
            continue;
        memcpy(*at, &s->spare, sizeof s->spare);
        s->spare = *at;
        *at = NULL;
    }
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
        s->next = s->floor = first_id;
    }
    if (first_id != s->next || count > UINT64_MAX - first_id)
        return fail(s, ISOMEND_ERR_INVALID_ARGUMENT);
    const uint64_t end = first_id + count;
    if (end - s->floor >= WINDOW_LIMIT)
        return fail(s, ISOMEND_ERR_TOO_LARGE);
    isomend_status st = ring_fit(s, end);
    if (st != ISOMEND_OK)
        return fail(s, st);
    for (size_t i = 0; i < count; i++) {
        vslot *v = slot(s, first_id + i);
        if (s->so)
            unshear_point(s->so, s->n2, positions + 3 * i, v->p);
        else
            memcpy(v->p, positions + 3 * i, sizeof v->p);
        v->hole = NONE;
        v->key = v->k8;
        v->e = v->e8;
        for (int k = 0; k < 8; k++) /* match8() reads all 8 keys */
            v->k8[k] = NO_KEY;
        v->n = v->fans = 0;
    }
    s->next = end;
    return ISOMEND_OK;
}

/* to - from, both live ids. */
static int32_t offset(uint64_t to, uint64_t from)
{
    return to >= from ? (int32_t)(to - from) : -(int32_t)(from - to);
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
    for (size_t t = 0; t < count; t++) {
        const uint64_t *id = ids + 3 * t;
        vslot *v[3];
        uint32_t nx[3], pv[3]; /* corner k's entries for the next, previous corner */
        for (int k = 0; k < 3; k++)
            v[k] = slot(s, id[k]);
        for (int k = 0; k < 3; k++) {
            const uint64_t x = id[k], y = id[k == 2 ? 0 : k + 1], z = id[k == 0 ? 2 : k - 1];
            if (!corner(s, v[k], offset(y, x), offset(z, x), &nx[k], &pv[k]))
                return fail(s, ISOMEND_ERR_OUT_OF_MEMORY);
        }
        /* edge k runs id[k] -> id[k + 1]: counted on the lower end's entry */
        nbr *e[3];
        uint32_t root = NONE;
        for (int k = 0; k < 3; k++) {
            const int k1 = k == 2 ? 0 : k + 1;
            const unsigned fwd = id[k] < id[k1], lower = id[k] <= id[k1];
            e[k] = (lower ? v[k] : v[k1])->e + (lower ? nx[k] : pv[k1]);
            const unsigned more = e[k]->uses < 3;
            e[k]->uses = (uint8_t)(e[k]->uses + more);
            e[k]->fwd = (uint8_t)(e[k]->fwd + (fwd & more));
            if (e[k]->set != NONE) { /* an edge seen before: join its set */
                const uint32_t r = uf_find(&s->tri, e[k]->set);
                root = root == NONE ? r : uf_link(&s->tri, root, r);
            }
        }
        for (int k = 0; k < 3; k++)
            if (e[k]->set == NONE) { /* a new edge (maybe twice in e): names the set */
                if (root == NONE) {
                    isomend_status st = uf_new(s, &s->tri, 0, &root);
                    if (st != ISOMEND_OK)
                        return fail(s, st);
                }
                e[k]->set = root;
                s->tri.n[root].ref++;
            }
        s->r.degenerate_triangles +=
            (uint64_t)degenerate_triangle(id[0], id[1], id[2], v[0]->p, v[1]->p, v[2]->p);
        s->r.triangles++;
    }
    return ISOMEND_OK;
}

/* Every vertex below floor, not yet retired, is tested and forgotten. */
static isomend_status retire_to(isomend_check_stream *s, uint64_t floor)
{
    const uint64_t old_floor = s->floor;
    for (; s->floor < floor; s->floor++) {
        isomend_status st = retire_vertex(s, s->floor);
        if (st != ISOMEND_OK)
            return st;
    }
    ring_release(s, old_floor, floor);
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
    isomend_status st = retire_to(s, floor);
    return st == ISOMEND_OK ? ISOMEND_OK : fail(s, st);
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
    isomend_status st = retire_to(s, s->next);
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
