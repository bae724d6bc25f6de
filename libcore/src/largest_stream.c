/*
 * largest_stream.c - --largest K (with --min-component N) on a streamed
 * mesh, in two passes over the same stream: isomend_largest_stream_*().
 *
 * Every component's size is needed before anything is written, so the
 * caller plays the stream twice (isomend-mpi's rank 0 and `isomend extract`
 * replay a scratch spool of it).  Both passes run the same frontier
 * union-find as clean_stream.c: each live vertex (an id at or above the
 * last retire floor, used by a triangle) points to a component record, a
 * triangle joins its vertices' records (union by size), and a record with
 * no live vertex left after a retire is a closed component.
 *
 * Identity.  A triangle must be passed or dropped in the second pass long
 * before its component closes, while it is only a piece of it (two legs
 * that meet higher up are two pieces until they do).  So pieces get seeds:
 * at each retire, every root that has none (born since the last retire, not
 * joined to an older piece) gets the next seed number, in the order of its
 * first triangle; when two seeded pieces join, the smaller seed stays and
 * the first pass notes parent[larger] = smaller.  A seed's chain of parents
 * ends at its component's smallest seed, the component's key.  Seeds,
 * joins and closes depend on the stream's triangles and floors only, so the
 * second pass assigns every piece the first pass's seed.
 *
 * Pass 1 counts: at each close, a component of at least min_triangles
 * triangles is recorded (its triangles, first triangle, key).  Then
 * isomend_largest_stream_replay() sorts them as isomend_mesh_clean() does
 * (more triangles first; ties: the first triangle first), keeps keep_largest
 * of them (0: all), and turns parent[] into one bit a seed: its component
 * is kept (seeds in increasing order; a parent is always smaller).
 * Pass 2 filters: a triangle whose piece has a seed passes or goes at once
 * by its bit; one whose piece has none yet (born since the last retire) is
 * held until that retire gives it one (or it joins a seeded piece).
 *
 * Output (pass 2) as clean_stream.c's: vertices numbered from 0 in the
 * order a passed triangle first uses them, delivered just before it with
 * the normal they came with; triangles in stream order but for held ones,
 * which pass at the retire that seeds them (in stream order); no origins;
 * one retire() for each of the stream's, the floor the smallest output id
 * of a vertex still live.  The triangles kept are exactly
 * isomend_mesh_clean(mesh, min_triangles, keep_largest)'s, the report's
 * counts its.
 *
 * Memory: the live vertices and records (O(slice)), the triangles of one
 * layer held in pass 2, and per seed 8 bytes in pass 1 (its parent) and one
 * bit in pass 2, per recorded component 24 bytes: a seed is a piece of
 * surface that starts (a z minimum: a component, a leg, a bubble's bottom),
 * a few per component.
 */
#include "mesh_internal.h"

#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX
#define NO_ID UINT64_MAX
#define BYTES_PER_VERTEX 96.0
#define BYTES_PER_HELD 40.0
#define TRIANGLES_PER_SAMPLE 0.25
#define VERTICES_PER_SAMPLE 0.125
#define LIVE_SLICES 3.0

typedef struct cslot {
    float p[3], n[3];
    uint64_t id;   /* the stream's id (NO_ID: free)               */
    uint64_t out;  /* the delivered id, NO_ID before               */
    uint32_t comp; /* its component record while live (NONE: none) */
    uint32_t refs; /* held triangles that use it                   */
} cslot;

typedef struct lrec {
    uint32_t parent;
    uint32_t head, tail; /* held triangles (pass 2): a list through htri.next */
    uint32_t mark;       /* the retire epoch it was last found live in      */
    uint64_t triangles;  /* triangles so far                                */
    uint64_t first;      /* its first triangle (stream order)               */
    uint64_t seed;       /* NO_ID: none yet                                 */
    int kept;            /* pass 2, once seeded                             */
    int used;
} lrec;

typedef struct htri {
    uint32_t s[3];
    uint32_t next;
    uint64_t seq;
} htri;

typedef struct lcomp {
    uint64_t triangles, first, seed;
} lcomp;

struct isomend_largest_stream {
    isomend_mesh_sink out;
    uint64_t min_tri, keep;
    isomend_status status;
    int pass;    /* 1 counting, 2 filtering, 3 finished */
    int normals; /* the stream delivers normals */

    uint64_t next_id, floor, seq;
    cslot *slots;
    size_t nslots, cap_slots;
    uint32_t free_slot;
    uint64_t *hkey;
    uint32_t *hval;
    size_t hcap, hcount;
    uint32_t *live;
    size_t nlive, cap_live;

    lrec *recs;
    size_t nrecs, cap_recs;
    uint32_t free_rec;
    uint32_t epoch;

    htri *held;
    size_t nheld, cap_held;
    uint32_t free_held;

    /* seeds */
    uint64_t nseeds;
    uint64_t *parent; /* pass 1 */
    size_t cap_parent;
    uint8_t *bits; /* pass 2: the seed's component is kept */
    lcomp *comps;  /* pass 1: the closed components of min_triangles */
    size_t ncomps, cap_comps;
    uint32_t *fresh; /* a retire's roots without a seed */
    size_t cap_fresh;

    /* pass 1's totals, checked against pass 2's */
    uint64_t vertices1, triangles1, seeds1;

    /* output */
    uint64_t triangles_out;
    uint64_t out_next, out_floor;
    float *vpos, *vnrm;
    size_t nv_buf, cap_vbuf;
    uint64_t *tbuf;
    size_t nt_buf, cap_tbuf;
    htri *sortbuf;
    size_t cap_sort;

    isomend_clean_report rep;
};

static isomend_status fail(isomend_largest_stream *c, isomend_status st)
{
    if (c->status == ISOMEND_OK)
        c->status = st;
    return c->status;
}

static int grow(void **p, size_t *cap, size_t n, size_t size)
{
    if (n <= *cap)
        return 1;
    size_t c = *cap ? *cap : 256;
    while (c < n)
        c *= 2;
    void *q = realloc(*p, c * size);
    if (!q)
        return 0;
    *p = q;
    *cap = c;
    return 1;
}

/* ------------------------------------------------------------------ the slot table */

static size_t hash_of(uint64_t id, size_t cap)
{
    id ^= id >> 33;
    id *= 0xff51afd7ed558ccdULL;
    id ^= id >> 33;
    return (size_t)id & (cap - 1);
}

static int table_grow(isomend_largest_stream *c)
{
    const size_t cap = c->hcap ? 2 * c->hcap : 1024;
    uint64_t *k = malloc(cap * sizeof *k);
    uint32_t *v = malloc(cap * sizeof *v);
    if (!k || !v) {
        free(k);
        free(v);
        return 0;
    }
    for (size_t i = 0; i < cap; i++)
        k[i] = NO_ID;
    for (size_t i = 0; i < c->hcap; i++)
        if (c->hkey[i] != NO_ID) {
            size_t h = hash_of(c->hkey[i], cap);
            while (k[h] != NO_ID)
                h = (h + 1) & (cap - 1);
            k[h] = c->hkey[i];
            v[h] = c->hval[i];
        }
    free(c->hkey);
    free(c->hval);
    c->hkey = k;
    c->hval = v;
    c->hcap = cap;
    return 1;
}

static uint32_t table_find(const isomend_largest_stream *c, uint64_t id)
{
    if (!c->hcap)
        return NONE;
    for (size_t h = hash_of(id, c->hcap);; h = (h + 1) & (c->hcap - 1)) {
        if (c->hkey[h] == id)
            return c->hval[h];
        if (c->hkey[h] == NO_ID)
            return NONE;
    }
}

static void table_remove(isomend_largest_stream *c, uint64_t id)
{
    const size_t mask = c->hcap - 1;
    size_t h = hash_of(id, c->hcap);
    while (c->hkey[h] != id)
        h = (h + 1) & mask;
    for (size_t j = (h + 1) & mask;; j = (j + 1) & mask) { /* backward shift */
        if (c->hkey[j] == NO_ID)
            break;
        const size_t home = hash_of(c->hkey[j], c->hcap);
        if (((j - home) & mask) >= ((j - h) & mask)) {
            c->hkey[h] = c->hkey[j];
            c->hval[h] = c->hval[j];
            h = j;
        }
    }
    c->hkey[h] = NO_ID;
    c->hcount--;
}

/* A new slot for stream vertex id (live). */
static uint32_t slot_new(isomend_largest_stream *c, uint64_t id, const float *p, const float *n)
{
    if (2 * (c->hcount + 1) > c->hcap && !table_grow(c))
        return NONE;
    uint32_t s;
    if (c->free_slot != NONE) {
        s = c->free_slot;
        c->free_slot = c->slots[s].comp;
    } else {
        if (!grow((void **)&c->slots, &c->cap_slots, c->nslots + 1, sizeof *c->slots))
            return NONE;
        s = (uint32_t)c->nslots++;
    }
    cslot *x = &c->slots[s];
    memcpy(x->p, p, sizeof x->p);
    if (n)
        memcpy(x->n, n, sizeof x->n);
    else
        memset(x->n, 0, sizeof x->n);
    x->id = id;
    x->out = NO_ID;
    x->comp = NONE;
    x->refs = 0;
    size_t h = hash_of(id, c->hcap);
    while (c->hkey[h] != NO_ID)
        h = (h + 1) & (c->hcap - 1);
    c->hkey[h] = id;
    c->hval[h] = s;
    c->hcount++;
    return s;
}

/* Frees slot s if its vertex has retired and no held triangle uses it. */
static void slot_release(isomend_largest_stream *c, uint32_t s)
{
    cslot *x = &c->slots[s];
    if (x->refs || x->id == NO_ID || x->id >= c->floor)
        return;
    table_remove(c, x->id);
    x->id = NO_ID;
    x->comp = c->free_slot;
    c->free_slot = s;
}

/* ------------------------------------------------------------------ records */

static uint32_t rec_new(isomend_largest_stream *c)
{
    uint32_t r;
    if (c->free_rec != NONE) {
        r = c->free_rec;
        c->free_rec = c->recs[r].parent;
    } else {
        if (!grow((void **)&c->recs, &c->cap_recs, c->nrecs + 1, sizeof *c->recs))
            return NONE;
        r = (uint32_t)c->nrecs++;
    }
    c->recs[r] = (lrec){r, NONE, NONE, 0, 0, NO_ID, NO_ID, 0, 1};
    return r;
}

static uint32_t rec_find(isomend_largest_stream *c, uint32_t r)
{
    uint32_t root = r;
    while (c->recs[root].parent != root)
        root = c->recs[root].parent;
    while (c->recs[r].parent != root) {
        const uint32_t up = c->recs[r].parent;
        c->recs[r].parent = root;
        r = up;
    }
    return root;
}

/* ------------------------------------------------------------------ output (pass 2) */

static int emit(isomend_largest_stream *c, const uint32_t *t)
{
    if (!grow((void **)&c->tbuf, &c->cap_tbuf, 3 * (c->nt_buf + 1), sizeof *c->tbuf))
        return 0;
    for (int k = 0; k < 3; k++) {
        cslot *x = &c->slots[t[k]];
        if (x->out == NO_ID) {
            if (c->nv_buf == c->cap_vbuf) {
                const size_t cap = c->cap_vbuf ? 2 * c->cap_vbuf : 1024;
                float *p = realloc(c->vpos, cap * 12);
                if (p)
                    c->vpos = p;
                float *n = realloc(c->vnrm, cap * 12);
                if (n)
                    c->vnrm = n;
                if (!p || !n)
                    return 0;
                c->cap_vbuf = cap;
            }
            memcpy(c->vpos + 3 * c->nv_buf, x->p, 12);
            memcpy(c->vnrm + 3 * c->nv_buf, x->n, 12);
            c->nv_buf++;
            x->out = c->out_next++;
        }
        c->tbuf[3 * c->nt_buf + (size_t)k] = x->out;
    }
    c->nt_buf++;
    c->triangles_out++;
    return 1;
}

static isomend_status flush_out(isomend_largest_stream *c)
{
    if (c->nv_buf) {
        if (c->out.vertices(c->out.user, c->out_next - c->nv_buf, c->nv_buf, c->vpos,
                            c->normals ? c->vnrm : NULL, NULL))
            return fail(c, ISOMEND_ERR_SINK);
        c->nv_buf = 0;
    }
    if (c->nt_buf) {
        if (c->out.triangles(c->out.user, c->nt_buf, c->tbuf, NULL))
            return fail(c, ISOMEND_ERR_SINK);
        c->nt_buf = 0;
    }
    return ISOMEND_OK;
}

/* ------------------------------------------------------------------ held triangles (pass 2) */

static int by_seq(const void *x, const void *y)
{
    const htri *a = x, *b = y;
    return a->seq < b->seq ? -1 : a->seq > b->seq;
}

/* Frees root r's held triangles: into sortbuf[*n..] when pass, else dropped. */
static int collect_held(isomend_largest_stream *c, uint32_t r, int pass, size_t *n)
{
    size_t count = 0;
    for (uint32_t h = c->recs[r].head; h != NONE; h = c->held[h].next)
        count++;
    if (pass && !grow((void **)&c->sortbuf, &c->cap_sort, *n + count, sizeof *c->sortbuf))
        return 0;
    for (uint32_t h = c->recs[r].head; h != NONE;) {
        const uint32_t next = c->held[h].next;
        if (pass) {
            c->sortbuf[(*n)++] = c->held[h];
        } else {
            for (int k = 0; k < 3; k++) {
                c->slots[c->held[h].s[k]].refs--;
                slot_release(c, c->held[h].s[k]);
            }
        }
        c->held[h].next = c->free_held;
        c->free_held = h;
        h = next;
    }
    c->recs[r].head = c->recs[r].tail = NONE;
    return 1;
}

/* Emits sortbuf[0..n) in stream order. */
static int emit_sorted(isomend_largest_stream *c, size_t n)
{
    qsort(c->sortbuf, n, sizeof *c->sortbuf, by_seq);
    for (size_t i = 0; i < n; i++) {
        if (!emit(c, c->sortbuf[i].s))
            return 0;
        for (int k = 0; k < 3; k++) {
            c->slots[c->sortbuf[i].s[k]].refs--;
            slot_release(c, c->sortbuf[i].s[k]);
        }
    }
    return 1;
}

static int hold(isomend_largest_stream *c, uint32_t r, const uint32_t *t)
{
    uint32_t h;
    if (c->free_held != NONE) {
        h = c->free_held;
        c->free_held = c->held[h].next;
    } else {
        if (!grow((void **)&c->held, &c->cap_held, c->nheld + 1, sizeof *c->held))
            return 0;
        h = (uint32_t)c->nheld++;
    }
    htri *x = &c->held[h];
    memcpy(x->s, t, sizeof x->s);
    x->next = NONE;
    x->seq = c->seq;
    for (int k = 0; k < 3; k++)
        c->slots[t[k]].refs++;
    lrec *R = &c->recs[r];
    if (R->tail == NONE)
        R->head = h;
    else
        c->held[R->tail].next = h;
    R->tail = h;
    return 1;
}

/* Joins roots a and b; returns the root (NONE: the passes disagree). */
static uint32_t join(isomend_largest_stream *c, uint32_t a, uint32_t b)
{
    if (a == b)
        return a;
    lrec *A = &c->recs[a], *B = &c->recs[b];
    if (B->triangles > A->triangles || (B->triangles == A->triangles && b < a)) {
        const uint32_t t = a;
        a = b;
        b = t;
        A = &c->recs[a];
        B = &c->recs[b];
    }
    B->parent = a;
    A->triangles += B->triangles;
    if (B->first < A->first)
        A->first = B->first;
    if (A->seed != NO_ID && B->seed != NO_ID) {
        const uint64_t lo = A->seed < B->seed ? A->seed : B->seed;
        const uint64_t hi = A->seed < B->seed ? B->seed : A->seed;
        if (c->pass == 1)
            c->parent[hi] = lo;
        else if (A->kept != B->kept)
            return NONE; /* one component, two verdicts: not the same stream */
        A->seed = lo;
    } else if (B->seed != NO_ID) {
        A->seed = B->seed;
        A->kept = B->kept;
    }
    if (B->head != NONE) {
        if (A->tail == NONE)
            A->head = B->head;
        else
            c->held[A->tail].next = B->head;
        A->tail = B->tail;
    }
    B->head = B->tail = NONE;
    return a;
}

/* ------------------------------------------------------------------ the stream's sink */

static int on_vertices(void *user, uint64_t first, size_t count, const float *pos,
                       const float *nrm, const uint64_t *keys)
{
    (void)keys;
    isomend_largest_stream *c = user;
    if (c->status != ISOMEND_OK)
        return 1;
    if (c->pass > 2 || first != c->next_id)
        return fail(c, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    if (first == 0 && count)
        c->normals = nrm != NULL;
    if (!grow((void **)&c->live, &c->cap_live, c->nlive + count, sizeof *c->live))
        return fail(c, ISOMEND_ERR_OUT_OF_MEMORY), 1;
    for (size_t v = 0; v < count; v++) {
        const uint32_t s = slot_new(c, first + v, pos + 3 * v, nrm ? nrm + 3 * v : NULL);
        if (s == NONE)
            return fail(c, ISOMEND_ERR_OUT_OF_MEMORY), 1;
        c->live[c->nlive++] = s;
    }
    c->next_id += count;
    return 0;
}

static int on_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    (void)origins;
    isomend_largest_stream *c = user;
    if (c->status != ISOMEND_OK)
        return 1;
    if (c->pass > 2)
        return fail(c, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    for (size_t t = 0; t < count; t++) {
        uint32_t s[3], root = NONE;
        for (int k = 0; k < 3; k++) {
            const uint64_t id = ids[3 * t + (size_t)k];
            s[k] = id >= c->floor && id < c->next_id ? table_find(c, id) : NONE;
            if (s[k] == NONE)
                return fail(c, ISOMEND_ERR_INVALID_ARGUMENT), 1;
            if (c->slots[s[k]].comp == NONE && (c->slots[s[k]].comp = rec_new(c)) == NONE)
                return fail(c, ISOMEND_ERR_OUT_OF_MEMORY), 1;
            const uint32_t r = rec_find(c, c->slots[s[k]].comp);
            root = root == NONE ? r : join(c, root, r);
            if (root == NONE)
                return fail(c, ISOMEND_ERR_INVALID_ARGUMENT), 1;
        }
        lrec *R = &c->recs[root];
        R->triangles++;
        if (R->first == NO_ID)
            R->first = c->seq;
        int ok = 1;
        if (c->pass == 2) {
            if (R->seed == NO_ID) {
                ok = hold(c, root, s);
            } else {
                size_t n = 0;
                const int kept = R->kept;
                ok = collect_held(c, root, kept, &n) && (!kept || (emit_sorted(c, n) && emit(c, s)));
            }
        }
        c->seq++;
        if (!ok)
            return fail(c, ISOMEND_ERR_OUT_OF_MEMORY), 1;
    }
    return c->pass == 2 && flush_out(c) != ISOMEND_OK;
}


/* The roots without a seed get the next ones, in the order of their first
 * triangle; in pass 2 their held triangles pass or go by their bits. */
static isomend_status seed_fresh(isomend_largest_stream *c)
{
    size_t nf = 0;
    for (size_t r = 0; r < c->nrecs; r++) {
        const lrec *R = &c->recs[r];
        if (R->used && R->parent == r && R->seed == NO_ID && R->triangles) {
            if (!grow((void **)&c->fresh, &c->cap_fresh, nf + 1, sizeof *c->fresh))
                return fail(c, ISOMEND_ERR_OUT_OF_MEMORY);
            c->fresh[nf++] = (uint32_t)r;
        }
    }
    /* few: an insertion sort by first triangle */
    for (size_t i = 1; i < nf; i++) {
        const uint32_t x = c->fresh[i];
        size_t j = i;
        for (; j > 0 && c->recs[c->fresh[j - 1]].first > c->recs[x].first; j--)
            c->fresh[j] = c->fresh[j - 1];
        c->fresh[j] = x;
    }
    size_t n = 0;
    for (size_t i = 0; i < nf; i++) {
        lrec *R = &c->recs[c->fresh[i]];
        R->seed = c->nseeds++;
        if (c->pass == 1) {
            if (!grow((void **)&c->parent, &c->cap_parent, (size_t)c->nseeds, sizeof *c->parent))
                return fail(c, ISOMEND_ERR_OUT_OF_MEMORY);
            c->parent[R->seed] = R->seed;
        } else {
            if (R->seed >= c->seeds1)
                return fail(c, ISOMEND_ERR_INVALID_ARGUMENT);
            R->kept = (c->bits[R->seed >> 3] >> (R->seed & 7)) & 1;
            if (!collect_held(c, c->fresh[i], R->kept, &n))
                return fail(c, ISOMEND_ERR_OUT_OF_MEMORY);
        }
    }
    if (n && !emit_sorted(c, n))
        return fail(c, ISOMEND_ERR_OUT_OF_MEMORY);
    return ISOMEND_OK;
}

/* The live vertices below floor leave, the components without a live
 * vertex close; then (forward, pass 2) retire() on the output. */
static isomend_status retire_to(isomend_largest_stream *c, uint64_t floor, int forward)
{
    if (seed_fresh(c) != ISOMEND_OK)
        return c->status;
    c->floor = floor;
    c->epoch++;
    size_t keep = 0;
    uint64_t low = NO_ID;
    for (size_t i = 0; i < c->nlive; i++) {
        const uint32_t s = c->live[i];
        cslot *x = &c->slots[s];
        if (x->id >= floor) {
            if (x->comp != NONE) {
                x->comp = rec_find(c, x->comp);
                c->recs[x->comp].mark = c->epoch;
            }
            if (x->out < low)
                low = x->out;
            c->live[keep++] = s;
        } else {
            x->comp = NONE;
            slot_release(c, s);
        }
    }
    c->nlive = keep;
    for (size_t r = 0; r < c->nrecs; r++) {
        lrec *R = &c->recs[r];
        if (!R->used || (R->parent == r && R->mark == c->epoch))
            continue;
        if (R->parent == r && c->pass == 1) {
            c->rep.components_before++;
            if (R->triangles >= c->min_tri) {
                if (!grow((void **)&c->comps, &c->cap_comps, c->ncomps + 1, sizeof *c->comps))
                    return fail(c, ISOMEND_ERR_OUT_OF_MEMORY);
                c->comps[c->ncomps++] = (lcomp){R->triangles, R->first, R->seed};
            }
        }
        R->used = 0;
    }
    c->free_rec = NONE;
    for (size_t r = c->nrecs; r-- > 0;)
        if (!c->recs[r].used) {
            c->recs[r].parent = c->free_rec;
            c->free_rec = (uint32_t)r;
        }
    if (c->pass != 2)
        return ISOMEND_OK;
    if (flush_out(c) != ISOMEND_OK)
        return c->status;
    uint64_t out_floor = low == NO_ID ? c->out_next : low;
    if (out_floor < c->out_floor)
        out_floor = c->out_floor;
    c->out_floor = out_floor;
    if (forward && c->out.retire(c->out.user, out_floor))
        return fail(c, ISOMEND_ERR_SINK);
    return ISOMEND_OK;
}

static int on_retire(void *user, uint64_t floor)
{
    isomend_largest_stream *c = user;
    if (c->status != ISOMEND_OK)
        return 1;
    if (c->pass > 2 || floor < c->floor || floor > c->next_id)
        return fail(c, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    return retire_to(c, floor, 1) != ISOMEND_OK;
}

/* ------------------------------------------------------------------ the API */

static int by_size(const void *x, const void *y)
{
    const lcomp *a = x, *b = y;
    if (a->triangles != b->triangles)
        return a->triangles > b->triangles ? -1 : 1;
    return a->first < b->first ? -1 : a->first > b->first;
}

uint64_t isomend_largest_stream_memory(const isomend_volume *desc, const isomend_options *opts)
{
    if (!desc || isomend_stream_memory(desc, opts) == 0)
        return 0;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const int pad = ((opts ? opts : &defaults)->flags & ISOMEND_FLAG_PAD) != 0;
    const double plane = (double)(desc->dims[0] + 2 * pad) * (double)(desc->dims[1] + 2 * pad);
    const double bytes = plane * (LIVE_SLICES * VERTICES_PER_SAMPLE * BYTES_PER_VERTEX +
                                  TRIANGLES_PER_SAMPLE * BYTES_PER_HELD) +
                         4194304.0;
    return bytes < 1.8e19 ? (uint64_t)bytes : UINT64_MAX;
}

isomend_status isomend_largest_stream_begin(uint64_t min_triangles, uint64_t keep_largest,
                                            const isomend_mesh_sink *out,
                                            isomend_largest_stream **ls)
{
    if (!ls)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *ls = NULL;
    if (!out || !out->vertices || !out->triangles || !out->retire)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_largest_stream *c = calloc(1, sizeof *c);
    if (!c)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    c->out = *out;
    c->min_tri = min_triangles;
    c->keep = keep_largest;
    c->pass = 1;
    c->free_slot = c->free_rec = c->free_held = NONE;
    *ls = c;
    return ISOMEND_OK;
}

isomend_status isomend_largest_stream_sink(isomend_largest_stream *c, isomend_mesh_sink *sink)
{
    if (!c || !sink)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *sink = (isomend_mesh_sink){c, on_vertices, on_triangles, on_retire, NULL};
    return ISOMEND_OK;
}

/* Closes what is still open and forgets the frontier. */
static void close_all(isomend_largest_stream *c)
{
    if (c->status == ISOMEND_OK && (c->floor < c->next_id || c->nlive))
        (void)retire_to(c, c->next_id, 0);
    else if (c->status == ISOMEND_OK)
        (void)seed_fresh(c);
}

isomend_status isomend_largest_stream_replay(isomend_largest_stream *c)
{
    if (!c)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (c->status == ISOMEND_OK && c->pass != 1)
        fail(c, ISOMEND_ERR_INVALID_ARGUMENT);
    close_all(c);
    if (c->status != ISOMEND_OK)
        return c->status;
    /* the kept components, isomend_mesh_clean()'s order */
    qsort(c->comps, c->ncomps, sizeof *c->comps, by_size);
    size_t kept = c->ncomps;
    if (c->keep && kept > c->keep)
        kept = (size_t)c->keep;
    c->rep.components_after = kept;
    c->bits = calloc((size_t)(c->nseeds / 8 + 1), 1);
    if (!c->bits)
        return fail(c, ISOMEND_ERR_OUT_OF_MEMORY);
    for (size_t i = 0; i < kept; i++)
        c->bits[c->comps[i].seed >> 3] |= (uint8_t)(1u << (c->comps[i].seed & 7));
    for (uint64_t s = 0; s < c->nseeds; s++) /* a parent is smaller: done already */
        if (c->parent[s] != s && (c->bits[c->parent[s] >> 3] >> (c->parent[s] & 7)) & 1)
            c->bits[s >> 3] |= (uint8_t)(1u << (s & 7));
    free(c->parent);
    free(c->comps);
    c->parent = NULL;
    c->comps = NULL;
    c->cap_parent = c->ncomps = c->cap_comps = 0;
    c->vertices1 = c->next_id;
    c->triangles1 = c->seq;
    c->seeds1 = c->nseeds;
    /* the frontier from scratch */
    for (size_t i = 0; i < c->hcap; i++)
        c->hkey[i] = NO_ID;
    c->hcount = 0;
    c->nslots = c->nlive = c->nrecs = c->nheld = 0;
    c->free_slot = c->free_rec = c->free_held = NONE;
    c->next_id = c->floor = c->seq = c->nseeds = 0;
    c->pass = 2;
    return ISOMEND_OK;
}

isomend_status isomend_largest_stream_finish(isomend_largest_stream *c,
                                             isomend_clean_report *report)
{
    if (report)
        memset(report, 0, sizeof *report);
    if (!c)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (c->status == ISOMEND_OK && c->pass != 2)
        fail(c, ISOMEND_ERR_INVALID_ARGUMENT);
    close_all(c);
    if (c->status == ISOMEND_OK && flush_out(c) != ISOMEND_OK)
        return c->status;
    /* the second stream must have been the first one again */
    if (c->status == ISOMEND_OK &&
        (c->next_id != c->vertices1 || c->seq != c->triangles1 || c->nseeds != c->seeds1))
        fail(c, ISOMEND_ERR_INVALID_ARGUMENT);
    if (c->status != ISOMEND_OK)
        return c->status;
    c->pass = 3;
    c->rep.vertices_removed = c->vertices1 - c->out_next;
    c->rep.triangles_removed = c->triangles1 - c->triangles_out;
    if (report)
        *report = c->rep;
    return ISOMEND_OK;
}

void isomend_largest_stream_destroy(isomend_largest_stream *c)
{
    if (!c)
        return;
    free(c->slots);
    free(c->hkey);
    free(c->hval);
    free(c->live);
    free(c->recs);
    free(c->held);
    free(c->parent);
    free(c->bits);
    free(c->comps);
    free(c->fresh);
    free(c->vpos);
    free(c->vnrm);
    free(c->tbuf);
    free(c->sortbuf);
    free(c);
}
