/*
 * clean_stream.c - the clean-up of a streamed mesh (--min-component), in
 * memory bounded by the stream's live vertices: isomend_clean_stream_*().
 *
 * A union-find over the live vertices.  Each live vertex (an id at or above
 * the last retire floor that a triangle has used) points to a component
 * record; a triangle joins its three vertices' components (union by size).
 * A component's triangles are held back until it has min_triangles of
 * them: then they are passed on (in the order they came), and every
 * triangle that joins the component later passes straight through (so does
 * every component it merges with: their held triangles go first).  A
 * component closes when none of its vertices is live any more (the stream
 * promises no later triangle uses an id below the floor, so nothing can join
 * it): one still held then has fewer than min_triangles triangles and is
 * dropped, with its vertices.  So the triangles kept are exactly
 * isomend_mesh_clean()'s (min_triangles, keep_largest 0) on the whole mesh,
 * and the components, counted as each closes, are its components.
 *
 * At each retire(floor), the live vertices are walked once: each points to
 * its root thereafter, those below the floor leave, and every component
 * record not a root of a live vertex is freed (a root that is not: a closed
 * component).  So the records and the vertex table hold the live vertices,
 * the held components and the vertices of their held triangles: O(slice)
 * plus the held triangles, each held component fewer than min_triangles.
 *
 * Output.  Vertices are numbered from 0 in the order a passed triangle
 * first uses them (delivered just before it, with the normal they came
 * with); triangles in the order they pass; one retire() for each of the
 * stream's (an output vertex retires when its stream vertex did and no held
 * triangle uses it: held triangles' vertices have no output id yet), so a
 * sink that counts layers by retire() (the streamed smoothing and
 * decimation) still sees the stream's layers.  No triangle origins.  The
 * output depends on the order of the stream's vertices, triangles and
 * retire floors only: not on how they are split into calls, nor on the
 * stream's threads.
 */
#include "mesh_internal.h"

#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX
#define NO_ID UINT64_MAX
/* The memory estimate: bytes a live vertex costs (its slot, table entries,
 * record) and a held triangle; vertices and triangles a slice sample (a
 * surface as busy as a 256^3 gyroid: one triangle every 4 samples); live
 * slices (a layer's vertices and the next). */
#define BYTES_PER_VERTEX 96.0
#define BYTES_PER_HELD 32.0
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

/* A component record: a root (parent == itself) is a component. */
typedef struct crec {
    uint32_t parent;
    uint32_t head, tail; /* its held triangles: a list through htri.next */
    uint32_t mark;       /* the retire epoch it was last found live in  */
    uint64_t triangles;  /* triangles so far (held or passed)           */
    int passed;          /* min_triangles reached: triangles pass        */
    int used;
} crec;

typedef struct htri {
    uint32_t s[3];
    uint32_t next;
    uint64_t seq; /* its place in the stream */
} htri;

struct isomend_clean_stream {
    isomend_mesh_sink out;
    uint64_t min_tri;
    isomend_status status;
    int normals; /* the stream delivers normals */

    uint64_t next_id, floor, seq;
    uint64_t triangles_in, triangles_out;
    /* the slots: a table keyed by the stream's id */
    cslot *slots;
    size_t nslots, cap_slots;
    uint32_t free_slot; /* a free list through slot.comp */
    uint64_t *hkey;
    uint32_t *hval;
    size_t hcap, hcount;
    uint32_t *live; /* slots of ids >= floor, in id order */
    size_t nlive, cap_live;

    crec *recs;
    size_t nrecs, cap_recs;
    uint32_t free_rec; /* through rec.parent */
    uint32_t epoch;

    htri *held;
    size_t nheld, cap_held;
    uint32_t free_held; /* through htri.next */

    /* output */
    uint64_t out_next, out_floor;
    float *vpos, *vnrm;
    size_t nv_buf, cap_vbuf;
    uint64_t *tbuf;
    size_t nt_buf, cap_tbuf;
    htri *sortbuf;
    size_t cap_sort;

    isomend_clean_report rep;
};

static isomend_status fail(isomend_clean_stream *c, isomend_status st)
{
    if (c->status == ISOMEND_OK)
        c->status = st;
    return c->status;
}

/* Grows *p (elements of size bytes) to hold n. */
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

static int table_grow(isomend_clean_stream *c)
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

static uint32_t table_find(const isomend_clean_stream *c, uint64_t id)
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

static void table_remove(isomend_clean_stream *c, uint64_t id)
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
static uint32_t slot_new(isomend_clean_stream *c, uint64_t id, const float *p, const float *n)
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
static void slot_release(isomend_clean_stream *c, uint32_t s)
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

static uint32_t rec_new(isomend_clean_stream *c)
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
    c->recs[r] = (crec){r, NONE, NONE, 0, 0, 0, 1};
    return r;
}

static uint32_t rec_find(isomend_clean_stream *c, uint32_t r)
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

/* ------------------------------------------------------------------ output */

/* Triangle t (slots) passes: its new vertices first. */
static int emit(isomend_clean_stream *c, const uint32_t *t)
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

/* What passed since the last flush, to the sink. */
static isomend_status flush_out(isomend_clean_stream *c)
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

/* ------------------------------------------------------------------ held triangles */

static int by_seq(const void *x, const void *y)
{
    const htri *a = x, *b = y;
    return a->seq < b->seq ? -1 : a->seq > b->seq;
}

/* Frees component r's held triangles, passing them on (in stream order)
 * when pass, else dropping them. */
static int release_held(isomend_clean_stream *c, uint32_t r, int pass)
{
    size_t n = 0;
    for (uint32_t h = c->recs[r].head; h != NONE; h = c->held[h].next)
        n++;
    if (pass && !grow((void **)&c->sortbuf, &c->cap_sort, n, sizeof *c->sortbuf))
        return 0;
    n = 0;
    for (uint32_t h = c->recs[r].head; h != NONE;) {
        const uint32_t next = c->held[h].next;
        if (pass)
            c->sortbuf[n++] = c->held[h];
        else
            for (int k = 0; k < 3; k++) {
                c->slots[c->held[h].s[k]].refs--;
                slot_release(c, c->held[h].s[k]);
            }
        c->held[h].next = c->free_held;
        c->free_held = h;
        h = next;
    }
    c->recs[r].head = c->recs[r].tail = NONE;
    if (!pass)
        return 1;
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

static int hold(isomend_clean_stream *c, uint32_t r, const uint32_t *t)
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
    crec *R = &c->recs[r];
    if (R->tail == NONE)
        R->head = h;
    else
        c->held[R->tail].next = h;
    R->tail = h;
    return 1;
}

/* Joins roots a and b; returns the root. */
static uint32_t join(isomend_clean_stream *c, uint32_t a, uint32_t b)
{
    if (a == b)
        return a;
    crec *A = &c->recs[a], *B = &c->recs[b];
    if (B->triangles > A->triangles || (B->triangles == A->triangles && b < a)) {
        const uint32_t t = a;
        a = b;
        b = t;
        A = &c->recs[a];
        B = &c->recs[b];
    }
    B->parent = a;
    A->triangles += B->triangles;
    A->passed |= B->passed;
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
    isomend_clean_stream *c = user;
    if (c->status != ISOMEND_OK)
        return 1;
    if (first != c->next_id)
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
    isomend_clean_stream *c = user;
    if (c->status != ISOMEND_OK)
        return 1;
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
        }
        crec *R = &c->recs[root];
        R->triangles++;
        c->triangles_in++;
        int ok;
        if (R->passed) {
            ok = release_held(c, root, 1) && emit(c, s);
        } else {
            ok = hold(c, root, s);
            if (ok && c->recs[root].triangles >= c->min_tri) {
                c->recs[root].passed = 1;
                ok = release_held(c, root, 1);
            }
        }
        c->seq++;
        if (!ok)
            return fail(c, ISOMEND_ERR_OUT_OF_MEMORY), 1;
    }
    return flush_out(c) != ISOMEND_OK;
}

/* The retire logic: the live vertices below floor leave, the components
 * without a live vertex close; then (forward) retire() on the output. */
static isomend_status retire_to(isomend_clean_stream *c, uint64_t floor, int forward)
{
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
    /* every record not a live vertex's root goes; a root among them closed */
    for (size_t r = 0; r < c->nrecs; r++) {
        crec *R = &c->recs[r];
        if (!R->used || (R->parent == r && R->mark == c->epoch))
            continue;
        if (R->parent == r) {
            c->rep.components_before++;
            if (R->passed)
                c->rep.components_after++;
            else if (!release_held(c, (uint32_t)r, 0))
                return fail(c, ISOMEND_ERR_OUT_OF_MEMORY);
        }
        R->used = 0;
    }
    /* the free list in index order, so that records are reused alike
     * whatever happened before (it is rebuilt from scratch) */
    c->free_rec = NONE;
    for (size_t r = c->nrecs; r-- > 0;)
        if (!c->recs[r].used) {
            c->recs[r].parent = c->free_rec;
            c->free_rec = (uint32_t)r;
        }
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
    isomend_clean_stream *c = user;
    if (c->status != ISOMEND_OK)
        return 1;
    if (floor < c->floor || floor > c->next_id)
        return fail(c, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    return retire_to(c, floor, 1) != ISOMEND_OK;
}

/* ------------------------------------------------------------------ the API */

uint64_t isomend_clean_stream_memory(const isomend_volume *desc, const isomend_options *opts)
{
    if (!desc || isomend_stream_memory(desc, opts) == 0)
        return 0;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const int pad = ((opts ? opts : &defaults)->flags & ISOMEND_FLAG_PAD) != 0;
    const double plane = (double)(desc->dims[0] + 2 * pad) * (double)(desc->dims[1] + 2 * pad);
    const double bytes = plane * (LIVE_SLICES * VERTICES_PER_SAMPLE * BYTES_PER_VERTEX +
                                  LIVE_SLICES * TRIANGLES_PER_SAMPLE * BYTES_PER_HELD) +
                         1048576.0;
    return bytes < 1.8e19 ? (uint64_t)bytes : UINT64_MAX;
}

isomend_status isomend_clean_stream_begin(uint64_t min_triangles, const isomend_mesh_sink *out,
                                          isomend_clean_stream **cs)
{
    if (!cs)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *cs = NULL;
    if (!out || !out->vertices || !out->triangles || !out->retire)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_clean_stream *c = calloc(1, sizeof *c);
    if (!c)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    c->out = *out;
    c->min_tri = min_triangles;
    c->free_slot = c->free_rec = c->free_held = NONE;
    *cs = c;
    return ISOMEND_OK;
}

isomend_status isomend_clean_stream_sink(isomend_clean_stream *c, isomend_mesh_sink *sink)
{
    if (!c || !sink)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *sink = (isomend_mesh_sink){c, on_vertices, on_triangles, on_retire, NULL};
    return ISOMEND_OK;
}

isomend_status isomend_clean_stream_finish(isomend_clean_stream *c, isomend_clean_report *report)
{
    if (report)
        memset(report, 0, sizeof *report);
    if (!c)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    /* everything still open closes now (a padded stream's last retire has
     * closed it already); no retire() is passed on for it, so that a step
     * after this one sees the stream's layers (its own finish retires the
     * rest) */
    if (c->status == ISOMEND_OK && (c->floor < c->next_id || c->nlive))
        (void)retire_to(c, c->next_id, 0);
    if (c->status != ISOMEND_OK)
        return c->status;
    c->rep.vertices_removed = c->next_id - c->out_next;
    c->rep.triangles_removed = c->triangles_in - c->triangles_out;
    if (report)
        *report = c->rep;
    return ISOMEND_OK;
}

void isomend_clean_stream_destroy(isomend_clean_stream *c)
{
    if (!c)
        return;
    free(c->slots);
    free(c->hkey);
    free(c->hval);
    free(c->live);
    free(c->recs);
    free(c->held);
    free(c->vpos);
    free(c->vnrm);
    free(c->tbuf);
    free(c->sortbuf);
    free(c);
}
