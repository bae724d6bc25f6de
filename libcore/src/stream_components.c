/*
 * stream_components.c - the frontier union-find of a streamed mesh's
 * components (stream_components.h), shared by clean_stream.c and
 * largest_stream.c.
 *
 * At each retire(floor), the live vertices are walked once: each points to
 * its root thereafter, those below the floor leave, and every component
 * record not a root of a live vertex is freed (a root that is not: a closed
 * component).  So the records and the slots hold the live vertices, the
 * open components and the vertices of their held triangles.  The records'
 * free list is rebuilt in index order at each retire, so that records are
 * reused alike whatever happened before.  Nothing here depends on how the
 * stream is split into calls.
 */
#include "stream_components.h"

#include <stdlib.h>
#include <string.h>

#define NONE  SC_NONE
#define NO_ID SC_NO_ID

int sc_grow(void **p, size_t *cap, size_t n, size_t size)
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

void sc_init(stream_components *f, const isomend_mesh_sink *out)
{
    f->out = *out;
    f->free_slot = f->free_rec = f->free_held = NONE;
}

/* The memory estimate: bytes a live vertex costs (its slot, table entries,
 * record); vertices and triangles a slice sample (a surface as busy as a
 * 256^3 gyroid: one triangle every 4 samples); live slices (a layer's
 * vertices and the next). */
#define BYTES_PER_VERTEX 96.0
#define TRIANGLES_PER_SAMPLE 0.25
#define VERTICES_PER_SAMPLE 0.125
#define LIVE_SLICES 3.0

uint64_t sc_memory(const isomend_volume *desc, const isomend_options *opts, double held_slices,
                   double bytes_per_held, double fixed)
{
    if (!desc || isomend_stream_memory(desc, opts) == 0)
        return 0;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const int pad = ((opts ? opts : &defaults)->flags & ISOMEND_FLAG_PAD) != 0;
    const double plane = (double)(desc->dims[0] + 2 * pad) * (double)(desc->dims[1] + 2 * pad);
    const double bytes = plane * (LIVE_SLICES * VERTICES_PER_SAMPLE * BYTES_PER_VERTEX +
                                  held_slices * TRIANGLES_PER_SAMPLE * bytes_per_held) +
                         fixed;
    return bytes < 1.8e19 ? (uint64_t)bytes : UINT64_MAX;
}

isomend_status sc_fail(stream_components *f, isomend_status st)
{
    if (f->status == ISOMEND_OK)
        f->status = st;
    return f->status;
}

void sc_restart(stream_components *f)
{
    id_table_clear(&f->ids);
    f->nslots = f->nlive = f->nrecs = f->nheld = 0;
    f->free_slot = f->free_rec = f->free_held = NONE;
    f->next_id = f->floor = f->seq = 0;
}

void sc_free(stream_components *f)
{
    free(f->slots);
    id_table_free(&f->ids);
    free(f->live);
    free(f->recs);
    free(f->held);
    free(f->vpos);
    free(f->vnrm);
    free(f->tbuf);
    free(f->sortbuf);
}

/* ------------------------------------------------------------------ slots */

/* A new slot for stream vertex id (live). */
static uint32_t slot_new(stream_components *f, uint64_t id, const float *p, const float *n)
{
    if (!id_table_reserve(&f->ids))
        return NONE;
    uint32_t s;
    if (f->free_slot != NONE) {
        s = f->free_slot;
        f->free_slot = f->slots[s].comp;
    } else {
        if (!sc_grow((void **)&f->slots, &f->cap_slots, f->nslots + 1, sizeof *f->slots))
            return NONE;
        s = (uint32_t)f->nslots++;
    }
    sc_slot *x = &f->slots[s];
    memcpy(x->p, p, sizeof x->p);
    if (n)
        memcpy(x->n, n, sizeof x->n);
    else
        memset(x->n, 0, sizeof x->n);
    x->id = id;
    x->out = NO_ID;
    x->comp = NONE;
    x->refs = 0;
    id_table_insert(&f->ids, id, s);
    return s;
}

/* Frees slot s if its vertex has retired and no held triangle uses it. */
static void slot_release(stream_components *f, uint32_t s)
{
    sc_slot *x = &f->slots[s];
    if (x->refs || x->id == NO_ID || x->id >= f->floor)
        return;
    id_table_remove(&f->ids, x->id);
    x->id = NO_ID;
    x->comp = f->free_slot;
    f->free_slot = s;
}

isomend_status sc_vertices(stream_components *f, uint64_t first, size_t count, const float *pos,
                           const float *nrm)
{
    if (first != f->next_id)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (first == 0 && count)
        f->normals = nrm != NULL;
    if (!sc_grow((void **)&f->live, &f->cap_live, f->nlive + count, sizeof *f->live))
        return ISOMEND_ERR_OUT_OF_MEMORY;
    for (size_t v = 0; v < count; v++) {
        const uint32_t s = slot_new(f, first + v, pos + 3 * v, nrm ? nrm + 3 * v : NULL);
        if (s == NONE)
            return ISOMEND_ERR_OUT_OF_MEMORY;
        f->live[f->nlive++] = s;
    }
    f->next_id += count;
    return ISOMEND_OK;
}

/* ------------------------------------------------------------------ records */

static uint32_t rec_new(stream_components *f)
{
    uint32_t r;
    if (f->free_rec != NONE) {
        r = f->free_rec;
        f->free_rec = f->recs[r].parent;
    } else {
        if (!sc_grow((void **)&f->recs, &f->cap_recs, f->nrecs + 1, sizeof *f->recs))
            return NONE;
        r = (uint32_t)f->nrecs++;
    }
    f->recs[r] = (sc_rec){r, NONE, NONE, 0, 0, NO_ID, NO_ID, 0, 1};
    return r;
}

static uint32_t rec_find(stream_components *f, uint32_t r)
{
    uint32_t root = r;
    while (f->recs[root].parent != root)
        root = f->recs[root].parent;
    while (f->recs[r].parent != root) {
        const uint32_t up = f->recs[r].parent;
        f->recs[r].parent = root;
        r = up;
    }
    return root;
}

/* Joins roots a and b; returns the root (NONE: merge refused). */
static uint32_t join(stream_components *f, uint32_t a, uint32_t b, sc_merge_fn merge, void *user)
{
    if (a == b)
        return a;
    sc_rec *A = &f->recs[a], *B = &f->recs[b];
    if (B->triangles > A->triangles || (B->triangles == A->triangles && b < a)) {
        const uint32_t t = a;
        a = b;
        b = t;
        A = &f->recs[a];
        B = &f->recs[b];
    }
    B->parent = a;
    A->triangles += B->triangles;
    if (B->first < A->first)
        A->first = B->first;
    if (merge && !merge(user, A, B))
        return NONE;
    if (B->head != NONE) {
        if (A->tail == NONE)
            A->head = B->head;
        else
            f->held[A->tail].next = B->head;
        A->tail = B->tail;
    }
    B->head = B->tail = NONE;
    return a;
}

isomend_status sc_triangle(stream_components *f, const uint64_t *ids, uint32_t s[3], uint32_t *root,
                           sc_merge_fn merge, void *user)
{
    uint32_t to = NONE;
    for (int k = 0; k < 3; k++) {
        const uint64_t id = ids[k];
        s[k] = id >= f->floor && id < f->next_id ? id_table_find(&f->ids, id) : NONE;
        if (s[k] == NONE)
            return ISOMEND_ERR_INVALID_ARGUMENT;
        if (f->slots[s[k]].comp == NONE && (f->slots[s[k]].comp = rec_new(f)) == NONE)
            return ISOMEND_ERR_OUT_OF_MEMORY;
        const uint32_t r = rec_find(f, f->slots[s[k]].comp);
        to = to == NONE ? r : join(f, to, r, merge, user);
        if (to == NONE)
            return ISOMEND_ERR_INVALID_ARGUMENT;
    }
    sc_rec *R = &f->recs[to];
    R->triangles++;
    if (R->first == NO_ID)
        R->first = f->seq;
    *root = to;
    return ISOMEND_OK;
}

/* ------------------------------------------------------------------ output */

int sc_emit(stream_components *f, const uint32_t *t)
{
    if (!sc_grow((void **)&f->tbuf, &f->cap_tbuf, 3 * (f->nt_buf + 1), sizeof *f->tbuf))
        return 0;
    for (int k = 0; k < 3; k++) {
        sc_slot *x = &f->slots[t[k]];
        if (x->out == NO_ID) {
            if (f->nv_buf == f->cap_vbuf) {
                const size_t cap = f->cap_vbuf ? 2 * f->cap_vbuf : 1024;
                float *p = realloc(f->vpos, cap * 12);
                if (p)
                    f->vpos = p;
                float *n = realloc(f->vnrm, cap * 12);
                if (n)
                    f->vnrm = n;
                if (!p || !n)
                    return 0;
                f->cap_vbuf = cap;
            }
            memcpy(f->vpos + 3 * f->nv_buf, x->p, 12);
            memcpy(f->vnrm + 3 * f->nv_buf, x->n, 12);
            f->nv_buf++;
            x->out = f->out_next++;
        }
        f->tbuf[3 * f->nt_buf + (size_t)k] = x->out;
    }
    f->nt_buf++;
    f->triangles_out++;
    return 1;
}

int sc_flush(stream_components *f)
{
    if (f->nv_buf) {
        if (f->out.vertices(f->out.user, f->out_next - f->nv_buf, f->nv_buf, f->vpos,
                            f->normals ? f->vnrm : NULL, NULL))
            return 0;
        f->nv_buf = 0;
    }
    if (f->nt_buf) {
        if (f->out.triangles(f->out.user, f->nt_buf, f->tbuf, NULL))
            return 0;
        f->nt_buf = 0;
    }
    return 1;
}

/* ------------------------------------------------------------------ held triangles */

static int by_seq(const void *x, const void *y)
{
    const sc_held *a = x, *b = y;
    return a->seq < b->seq ? -1 : a->seq > b->seq;
}

int sc_hold(stream_components *f, uint32_t r, const uint32_t *t)
{
    uint32_t h;
    if (f->free_held != NONE) {
        h = f->free_held;
        f->free_held = f->held[h].next;
    } else {
        if (!sc_grow((void **)&f->held, &f->cap_held, f->nheld + 1, sizeof *f->held))
            return 0;
        h = (uint32_t)f->nheld++;
    }
    sc_held *x = &f->held[h];
    memcpy(x->s, t, sizeof x->s);
    x->next = NONE;
    x->seq = f->seq;
    for (int k = 0; k < 3; k++)
        f->slots[t[k]].refs++;
    sc_rec *R = &f->recs[r];
    if (R->tail == NONE)
        R->head = h;
    else
        f->held[R->tail].next = h;
    R->tail = h;
    return 1;
}

int sc_collect_held(stream_components *f, uint32_t r, int pass, size_t *n)
{
    size_t count = 0;
    for (uint32_t h = f->recs[r].head; h != NONE; h = f->held[h].next)
        count++;
    if (pass && !sc_grow((void **)&f->sortbuf, &f->cap_sort, *n + count, sizeof *f->sortbuf))
        return 0;
    for (uint32_t h = f->recs[r].head; h != NONE;) {
        const uint32_t next = f->held[h].next;
        if (pass) {
            f->sortbuf[(*n)++] = f->held[h];
        } else {
            for (int k = 0; k < 3; k++) {
                f->slots[f->held[h].s[k]].refs--;
                slot_release(f, f->held[h].s[k]);
            }
        }
        f->held[h].next = f->free_held;
        f->free_held = h;
        h = next;
    }
    f->recs[r].head = f->recs[r].tail = NONE;
    return 1;
}

int sc_emit_sorted(stream_components *f, size_t n)
{
    qsort(f->sortbuf, n, sizeof *f->sortbuf, by_seq);
    for (size_t i = 0; i < n; i++) {
        if (!sc_emit(f, f->sortbuf[i].s))
            return 0;
        for (int k = 0; k < 3; k++) {
            f->slots[f->sortbuf[i].s[k]].refs--;
            slot_release(f, f->sortbuf[i].s[k]);
        }
    }
    return 1;
}

int sc_release_held(stream_components *f, uint32_t r, int pass)
{
    size_t n = 0;
    return sc_collect_held(f, r, pass, &n) && (!pass || sc_emit_sorted(f, n));
}

/* ------------------------------------------------------------------ retires */

isomend_status sc_retire(stream_components *f, uint64_t floor, sc_close_fn on_close, void *user,
                         int output, int forward)
{
    f->floor = floor;
    f->epoch++;
    size_t keep = 0;
    uint64_t low = NO_ID;
    for (size_t i = 0; i < f->nlive; i++) {
        const uint32_t s = f->live[i];
        sc_slot *x = &f->slots[s];
        if (x->id >= floor) {
            if (x->comp != NONE) {
                x->comp = rec_find(f, x->comp);
                f->recs[x->comp].mark = f->epoch;
            }
            if (x->out < low)
                low = x->out;
            f->live[keep++] = s;
        } else {
            x->comp = NONE;
            slot_release(f, s);
        }
    }
    f->nlive = keep;
    /* every record not a live vertex's root goes; a root among them closed */
    for (size_t r = 0; r < f->nrecs; r++) {
        const sc_rec *R = &f->recs[r];
        if (!R->used || (R->parent == r && R->mark == f->epoch))
            continue;
        if (R->parent == r && !on_close(user, (uint32_t)r))
            return ISOMEND_ERR_OUT_OF_MEMORY;
        f->recs[r].used = 0;
    }
    /* the free list in index order (rebuilt from scratch) */
    f->free_rec = NONE;
    for (size_t r = f->nrecs; r-- > 0;)
        if (!f->recs[r].used) {
            f->recs[r].parent = f->free_rec;
            f->free_rec = (uint32_t)r;
        }
    if (!output)
        return ISOMEND_OK;
    if (!sc_flush(f))
        return ISOMEND_ERR_SINK;
    uint64_t out_floor = low == NO_ID ? f->out_next : low;
    if (out_floor < f->out_floor)
        out_floor = f->out_floor;
    f->out_floor = out_floor;
    if (forward && f->out.retire(f->out.user, out_floor))
        return ISOMEND_ERR_SINK;
    return ISOMEND_OK;
}
