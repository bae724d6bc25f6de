/*
 * stream_window.c - the sliding window of the streamed post-processing
 * (stream_window.h), shared by decimate_stream.c and smooth_stream.c.
 *
 * The stream's layers are grouped in chunks of K layers.  When chunk c is
 * complete (K retire() calls), the window W = H (the triangles held back
 * from the previous window) + chunk c's triangles is made one mesh and
 * handed to the client, which processes it as a whole mesh whose cut (its
 * once-used edges: triangles outside it, final below or in chunk c + 1
 * above, whose plane of vertices is the top slice of chunk c) is locked.
 * Then the triangles of the result within `band` rings of the top plane are
 * held back (the next H: there the plane's vertices get their triangles of
 * both sides into one window), with up to `more` rings beyond (of young
 * triangles: hold_band) while those add at most a layer's worth of the
 * chunk's triangles, none for chunks of 1 layer (the next window can still
 * move them: a decimation's budget shifts across the seam), and every other
 * triangle is final.
 *
 *     layers:   0 ............ K ............ 2K ........... 3K
 *     window 0: [ chunk 0      )H0
 *     window 1:             H0 [ chunk 1      )H1
 *     window 2:                            H1 [ chunk 2      ) ...
 *
 * Output.  A vertex is delivered once every triangle around it is final
 * (it never gets a triangle again: only a top plane's vertices get new
 * ones, and they are held), with the area-weighted normal of those
 * triangles; a final triangle once its three vertices are delivered.  Ids
 * count from 0 in the order vertices are first delivered; retire() follows
 * the lowest id a waiting triangle still uses.
 *
 * Vertices are slots in a table keyed by the stream's vertex id (id_table.h):
 * a window's vertices and the held and waiting triangles' (O(chunk) memory);
 * each slot has the client's bytes besides.  The stream's positions are kept
 * from the last top plane on.
 */
#include "stream_window.h"
#include "id_table.h"
#include "mem_tally.h"
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NONE  UINT32_MAX
#define NO_ID UINT64_MAX

typedef struct slot {
    float p[3];       /* its position: the stream's, then where the windows put it */
    uint32_t held;    /* its triangles not yet final (held or in a window) */
    uint32_t pending; /* its triangles not yet delivered (final or not)    */
    uint32_t local;   /* scratch: index in the window's mesh               */
    uint64_t id;      /* the stream's id                                   */
    uint64_t out;     /* the delivered id, NO_ID before                    */
    double n[3];      /* the final triangles' area-weighted normal sum     */
} slot;

/* A growable array of elements of `size` bytes, counted in *tally. */
typedef struct vec {
    void *p;
    size_t n, cap, size;
    mem_tally *tally;
} vec;

static int vec_reserve(vec *v, size_t n)
{
    if (n <= v->cap && v->p)
        return 1; /* (allocated once even for nothing: vec_push never returns NULL on success) */
    size_t cap = v->cap ? v->cap : 256;
    while (cap < n)
        cap *= 2;
    void *p = realloc(v->p, cap * v->size);
    if (!p)
        return 0;
    mem_tally_grow(v->tally, v->p ? (uint64_t)v->cap * v->size : 0, (uint64_t)cap * v->size);
    v->p = p;
    v->cap = cap;
    return 1;
}

static void *vec_push(vec *v, size_t count)
{
    if (!vec_reserve(v, v->n + count))
        return NULL;
    void *at = (char *)v->p + v->n * v->size;
    v->n += count;
    return at;
}

struct stream_window {
    stream_window_client c;
    isomend_mesh_sink out;
    int normals;
    int64_t K;
    isomend_status status;

    /* the stream's side */
    int64_t layers;        /* layers completed (retire calls)     */
    uint64_t next_id;      /* stream vertices delivered           */
    uint64_t floor;        /* the last floor retired              */
    uint64_t *floors;      /* young + 1: the floor after layer l at l % (young + 1) */
    vec raw;               /* floats: positions of ids raw_base.. */
    uint64_t raw_base;
    vec chunk;             /* uint64_t x 3: the chunk's triangles */
    uint64_t triangles_in; /* stream triangles so far             */

    /* the slots */
    slot *slots;
    unsigned char *data; /* c.data_bytes a slot                  */
    size_t nslots, cap_slots;
    uint32_t free_slot;  /* a free list through slot.local       */
    id_table ids;        /* stream id -> slot                    */

    vec held;               /* uint32_t x 3: the held triangles (slots)    */
    vec waiting;            /* uint32_t x 3: final triangles not delivered */
    uint64_t final_count;   /* triangles made final                        */
    uint64_t out_next;      /* vertices delivered                          */
    uint64_t triangles_out; /* triangles delivered                         */
    uint64_t out_floor;

    /* delivery scratch */
    vec vpos, vnrm; /* floats x 3: the positions and normals of a batch */
    vec tbuf;       /* uint64_t x 3                                     */

    mem_tally mem; /* what the window and its client hold (mem_tally.h) */
};

isomend_status stream_window_fail(stream_window *w, isomend_status st)
{
    if (w->status == ISOMEND_OK)
        w->status = st;
    return w->status;
}

isomend_status stream_window_status(const stream_window *w)
{
    return w->status;
}

stream_window_counts stream_window_counts_of(const stream_window *w)
{
    return (stream_window_counts){w->next_id, w->triangles_in, w->final_count, w->out_next,
                                  w->triangles_out};
}

float *stream_window_pos(stream_window *w, uint32_t s)
{
    return w->slots[s].p;
}

void *stream_window_data(stream_window *w, uint32_t s)
{
    return w->data + (size_t)s * w->c.data_bytes;
}

const float *stream_window_raw(const stream_window *w, uint64_t id)
{
    return (const float *)w->raw.p + 3 * (id - w->raw_base);
}

const uint32_t *stream_window_held(const stream_window *w, size_t *count)
{
    *count = w->held.n;
    return w->held.p;
}

mem_tally *stream_window_tally(stream_window *w)
{
    return &w->mem;
}

uint64_t stream_window_peak_bytes(const stream_window *w)
{
    return w->mem.peak;
}

uint64_t stream_window_mesh_bytes(const isomend_mesh *m)
{
    if (!m)
        return 0;
    return sizeof *m + 12 * (uint64_t)m->nv * (m->nrm ? 2 : 1) + 12 * (uint64_t)m->nt +
           (m->org ? (uint64_t)m->nt : 0) + (m->slice_store ? 24 * (uint64_t)m->slices.n : 0);
}

/* The slot of stream vertex id, made at position p if it has none. */
static uint32_t slot_of(stream_window *w, uint64_t id, const float *p)
{
    uint32_t s = id_table_find(&w->ids, id);
    if (s != NONE)
        return s;
    const uint64_t ids_before = (uint64_t)w->ids.cap * 12;
    if (!id_table_reserve(&w->ids))
        return NONE;
    if ((uint64_t)w->ids.cap * 12 != ids_before) /* a new table, filled from the old */
        mem_tally_grow(&w->mem, ids_before, (uint64_t)w->ids.cap * 12);
    if (w->free_slot != NONE) {
        s = w->free_slot;
        w->free_slot = w->slots[s].local;
    } else {
        if (w->nslots == w->cap_slots) {
            const size_t cap = w->cap_slots ? 2 * w->cap_slots : 1024;
            slot *n = realloc(w->slots, cap * sizeof *n);
            if (!n)
                return NONE;
            w->slots = n;
            mem_tally_grow(&w->mem, (uint64_t)w->cap_slots * sizeof *n, (uint64_t)cap * sizeof *n);
            unsigned char *b = realloc(w->data, cap * w->c.data_bytes + 1);
            if (!b)
                return NONE;
            w->data = b;
            mem_tally_grow(&w->mem, w->cap_slots ? (uint64_t)w->cap_slots * w->c.data_bytes + 1 : 0,
                           (uint64_t)cap * w->c.data_bytes + 1);
            w->cap_slots = cap;
        }
        s = (uint32_t)w->nslots++;
    }
    slot *x = &w->slots[s];
    memset(x, 0, sizeof *x);
    memcpy(x->p, p, sizeof x->p);
    x->local = NONE;
    x->id = id;
    x->out = NO_ID;
    memset(stream_window_data(w, s), 0, w->c.data_bytes);
    if (w->c.made)
        w->c.made(w->c.user, stream_window_data(w, s), p);
    id_table_insert(&w->ids, id, s);
    return s;
}

/* Frees slot s once nothing uses it. */
static void slot_release(stream_window *w, uint32_t s)
{
    slot *x = &w->slots[s];
    if (x->held || x->pending || x->id == NO_ID)
        return;
    id_table_remove(&w->ids, x->id);
    x->id = NO_ID;
    x->local = w->free_slot;
    w->free_slot = s;
}

/* ------------------------------------------------------------------ delivery */

static void add_normal(stream_window *w, const uint32_t *t)
{
    const float *a = w->slots[t[0]].p, *b = w->slots[t[1]].p, *c = w->slots[t[2]].p;
    const double e1[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
    const double e2[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
    const double f[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                         e1[0] * e2[1] - e1[1] * e2[0]};
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 3; i++)
            w->slots[t[k]].n[i] += f[i];
}

/* Triangle t (slots) is final: it waits for delivery, its geometry counts
 * for its vertices' normals, then for the client. */
static int make_final(stream_window *w, const uint32_t *t)
{
    uint32_t *q = vec_push(&w->waiting, 1);
    if (!q)
        return 0;
    memcpy(q, t, 3 * sizeof *t);
    for (int k = 0; k < 3; k++)
        w->slots[t[k]].pending++;
    if (w->normals)
        add_normal(w, t);
    w->final_count++;
    return !w->c.final || w->c.final(w->c.user, w, t);
}

/* Delivers every waiting triangle whose vertices are done (no held
 * triangle), their new vertices first, in the order they wait. */
static isomend_status deliver(stream_window *w)
{
    uint32_t *q = w->waiting.p;
    const size_t n = w->waiting.n;
    w->vpos.n = w->vnrm.n = w->tbuf.n = 0;
    size_t keep = 0, nv = 0;
    uint64_t low = NO_ID; /* the lowest delivered id a waiting triangle uses */
    for (size_t i = 0; i < n; i++) {
        const uint32_t *t = q + 3 * i;
        const int ready = !w->slots[t[0]].held && !w->slots[t[1]].held && !w->slots[t[2]].held;
        if (!ready) {
            memmove(q + 3 * keep++, t, 3 * sizeof *t);
            continue;
        }
        uint64_t *ids = vec_push(&w->tbuf, 1);
        if (!ids)
            return stream_window_fail(w, ISOMEND_ERR_OUT_OF_MEMORY);
        for (int k = 0; k < 3; k++) {
            slot *x = &w->slots[t[k]];
            if (x->out == NO_ID) {
                float *v = vec_push(&w->vpos, 1), *nv3 = w->normals ? vec_push(&w->vnrm, 1) : NULL;
                if (!v || (w->normals && !nv3))
                    return stream_window_fail(w, ISOMEND_ERR_OUT_OF_MEMORY);
                memcpy(v, x->p, 3 * sizeof(float));
                const double len = sqrt(x->n[0] * x->n[0] + x->n[1] * x->n[1] + x->n[2] * x->n[2]);
                for (int c = 0; nv3 && c < 3; c++)
                    nv3[c] =
                        len > 0 && isfinite(len) ? (float)(x->n[c] / len) : (c == 2 ? 1.0f : 0.0f);
                x->out = w->out_next + nv++;
                if (w->c.delivered)
                    w->c.delivered(w->c.user, w, t[k]);
            }
            ids[k] = x->out;
        }
        for (int k = 0; k < 3; k++) {
            w->slots[t[k]].pending--;
            slot_release(w, t[k]);
        }
    }
    w->waiting.n = keep;
    for (size_t i = 0; i < 3 * keep; i++) /* after the loop: ids given to later triangles count */
        if (w->slots[q[i]].out < low)
            low = w->slots[q[i]].out;
    if (nv) {
        if (w->out.vertices(w->out.user, w->out_next, nv, w->vpos.p, w->normals ? w->vnrm.p : NULL,
                            NULL))
            return stream_window_fail(w, ISOMEND_ERR_SINK);
        w->out_next += nv;
    }
    if (w->tbuf.n && w->out.triangles(w->out.user, w->tbuf.n, w->tbuf.p, NULL))
        return stream_window_fail(w, ISOMEND_ERR_SINK);
    w->triangles_out += w->tbuf.n;
    const uint64_t floor = low == NO_ID ? w->out_next : low;
    if (floor > w->out_floor) {
        if (!w->c.retire_each && w->out.retire(w->out.user, floor))
            return stream_window_fail(w, ISOMEND_ERR_SINK);
        w->out_floor = floor;
    }
    return ISOMEND_OK;
}

/* ------------------------------------------------------------------ a window */

/* Rings from the top plane's vertices over mesh r, whose vertex v is slot
 * out_slot[v] (dist: band or more where farther). */
static int rings(const isomend_mesh *r, const uint32_t *out_slot, const slot *slots,
                 uint64_t top_lo, uint64_t top_hi, uint32_t band, uint32_t *dist, mem_tally *tally)
{
    const size_t nv = r->nv, nt = r->nt;
    uint32_t *first = calloc(nv + 1, sizeof *first), *tris = malloc((3 * nt + 1) * sizeof *tris);
    uint32_t *queue = malloc((nv + 1) * sizeof *queue);
    mem_tally_spike(tally, (2 * (uint64_t)nv + 2 + 3 * (uint64_t)nt + 1) * sizeof *queue);
    if (!first || !tris || !queue) {
        free(first);
        free(tris);
        free(queue);
        return 0;
    }
    for (size_t i = 0; i < 3 * nt; i++)
        first[r->tri[i] + 1]++;
    for (size_t v = 0; v < nv; v++)
        first[v + 1] += first[v];
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++)
            tris[first[r->tri[3 * t + (size_t)k]]++] = (uint32_t)t;
    for (size_t v = nv; v > 0; v--)
        first[v] = first[v - 1];
    first[0] = 0;
    size_t head = 0, tail = 0;
    for (size_t v = 0; v < nv; v++) {
        const uint64_t id = slots[out_slot[v]].id;
        dist[v] = id >= top_lo && id < top_hi ? 0 : band;
        if (!dist[v])
            queue[tail++] = (uint32_t)v;
    }
    while (head < tail) {
        const uint32_t v = queue[head++];
        if (dist[v] + 1 >= band)
            continue;
        for (uint32_t i = first[v]; i < first[v + 1]; i++)
            for (int k = 0; k < 3; k++) {
                const uint32_t u = r->tri[3 * (size_t)tris[i] + (size_t)k];
                if (dist[u] == band) {
                    dist[u] = dist[v] + 1;
                    queue[tail++] = u;
                }
            }
    }
    free(first);
    free(tris);
    free(queue);
    return 1;
}

/* Which triangles of r stay held (fin[t] = 0): those within band rings of
 * the top plane (dist[]: rings from it, to reach), and beyond them, ring by
 * ring up to reach, those whose vertices were all made within `young`
 * layers of the top plane, as long as these add at most a layer's worth of
 * the chunk's triangles (none for chunks of 1 layer).  age: scratch, r's
 * vertices. */
static void hold_band(const stream_window *w, const isomend_mesh *r, const uint32_t *out_slot,
                      const uint32_t *dist, uint32_t reach, size_t nchunk, uint8_t *age,
                      uint8_t *fin)
{
    const uint32_t band = w->c.band, D = w->c.young;
    uint32_t ext = band;
    if (reach > band) {
        /* a vertex is young if made at or above the top plane of D layers ago */
        for (size_t v = 0; v < r->nv; v++) {
            const uint64_t id = w->slots[out_slot[v]].id;
            uint32_t d = 0;
            while (d < D && (int64_t)d < w->layers &&
                   id < w->floors[(uint64_t)(w->layers - (int64_t)d) % (D + 1)])
                d++;
            age[v] = d < D;
        }
        uint64_t hist[STREAM_WINDOW_MAX_RINGS + 1] = {0};
        for (size_t t = 0; t < r->nt; t++) {
            const uint32_t *x = r->tri + 3 * t;
            uint32_t d = reach;
            for (int k = 0; k < 3; k++)
                d = dist[x[k]] < d ? dist[x[k]] : d;
            if (d >= band && d < reach && age[x[0]] && age[x[1]] && age[x[2]])
                hist[d]++;
        }
        /* a layer's worth of the chunk's triangles; nothing where a chunk is
         * one layer (what the tightest memory leaves: it would double it) */
        const uint64_t most = w->K > 1 ? (uint64_t)nchunk / (uint64_t)w->K : 0;
        uint64_t added = 0;
        while (ext < reach && added + hist[ext] <= most)
            added += hist[ext++];
    }
    for (size_t t = 0; t < r->nt; t++) {
        const uint32_t *x = r->tri + 3 * t;
        uint32_t d = UINT32_MAX;
        for (int k = 0; k < 3; k++)
            d = dist[x[k]] < d ? dist[x[k]] : d;
        fin[t] = !(d < band || (d < ext && age[x[0]] && age[x[1]] && age[x[2]]));
    }
}

/* The window: the held triangles and the chunk's, processed by the client;
 * the band at the top plane held back, the rest final.  last: no chunk
 * follows. */
static isomend_status run_window(stream_window *w, int last)
{
    const uint64_t top_lo = last ? w->next_id : w->floor, top_hi = w->next_id;
    const size_t nheld = w->held.n, nchunk = w->chunk.n, nt = nheld + nchunk;
    isomend_status st = ISOMEND_OK;
    isomend_mesh *m = calloc(1, sizeof *m), *r = NULL;
    uint32_t *wt = malloc((3 * nt + 1) * sizeof *wt), *lv = malloc((3 * nt + 1) * sizeof *lv);
    uint32_t *kept = NULL, *out_slot = NULL, *dist = NULL;
    uint8_t *fin = NULL, *age = NULL;
    uint64_t scratch = 0; /* the bytes this window counts in w->mem until it ends */
    if (!m || !wt || !lv)
        goto oom;
    scratch = sizeof *m + 2 * (3 * (uint64_t)nt + 1) * sizeof *wt;
    mem_tally_add(&w->mem, scratch);
    /* the window's triangles as slots: the held ones, then the chunk's */
    if (nheld)
        memcpy(wt, w->held.p, 3 * nheld * sizeof *wt);
    const uint64_t *ct = w->chunk.p;
    for (size_t i = 0; i < 3 * nchunk; i++) {
        const uint32_t s = slot_of(w, ct[i], stream_window_raw(w, ct[i]));
        if (s == NONE)
            goto oom;
        w->slots[s].held++;
        wt[3 * nheld + i] = s;
    }
    /* its mesh: vertices in the order of first use */
    size_t nv = 0;
    for (size_t i = 0; i < 3 * nt; i++) {
        slot *x = &w->slots[wt[i]];
        if (x->local == NONE) {
            x->local = (uint32_t)nv;
            lv[nv++] = wt[i];
        }
    }
    m->nv = nv;
    m->nt = nt;
    m->pos = malloc((nv + 1) * 12);
    m->tri = malloc((nt + 1) * 12);
    if (!m->pos || !m->tri)
        goto oom;
    mem_tally_add(&w->mem, 12 * ((uint64_t)nv + 1 + (uint64_t)nt + 1));
    scratch += 12 * ((uint64_t)nv + 1 + (uint64_t)nt + 1);
    for (size_t v = 0; v < nv; v++)
        memcpy(m->pos + 3 * v, w->slots[lv[v]].p, 12);
    for (size_t i = 0; i < 3 * nt; i++)
        m->tri[i] = w->slots[wt[i]].local;
    for (size_t v = 0; v < nv; v++)
        w->slots[lv[v]].local = NONE;
    const stream_window_mesh view = {m, lv, nheld, ct, nchunk, top_lo, top_hi};
    st = w->c.process(w->c.user, w, &view, &r, &kept);
    if (st != ISOMEND_OK)
        goto done;
    {
        /* the result: the client's work counted its peak (a spike) */
        const uint64_t rb = stream_window_mesh_bytes(r) + (kept && r ? 4 * (uint64_t)r->nv : 0);
        mem_tally_add(&w->mem, rb);
        scratch += rb;
    }
    /* the window's triangles are consumed; the result's vertices take their place */
    for (size_t i = 0; i < 3 * nt; i++)
        w->slots[wt[i]].held--;
    w->held.n = 0;
    const size_t rv = r ? r->nv : 0, rt = r ? r->nt : 0;
    out_slot = malloc((rv + 1) * sizeof *out_slot);
    dist = malloc((rv + 1) * sizeof *dist);
    fin = malloc(rt + 1);
    age = malloc(rv + 1);
    if (!out_slot || !dist || !fin || !age)
        goto oom;
    mem_tally_add(&w->mem,
                  2 * ((uint64_t)rv + 1) * sizeof *dist + (uint64_t)rt + 1 + (uint64_t)rv + 1);
    scratch += 2 * ((uint64_t)rv + 1) * sizeof *dist + (uint64_t)rt + 1 + (uint64_t)rv + 1;
    for (size_t v = 0; v < rv; v++)
        out_slot[v] = lv[kept ? kept[v] : v];
    uint32_t reach = w->c.band + (last ? 0 : w->c.more);
    if (reach > STREAM_WINDOW_MAX_RINGS)
        reach = w->c.band > STREAM_WINDOW_MAX_RINGS ? w->c.band : STREAM_WINDOW_MAX_RINGS;
    if (rv && !rings(r, out_slot, w->slots, top_lo, top_hi, reach, dist, &w->mem))
        goto oom;
    if (rt)
        hold_band(w, r, out_slot, dist, reach, nchunk, age, fin);
    if (r)
        w->c.settle(w->c.user, w, r, out_slot, fin);
    for (size_t t = 0; t < rt; t++) {
        uint32_t s[3];
        for (int k = 0; k < 3; k++)
            s[k] = out_slot[r->tri[3 * t + (size_t)k]];
        if (!fin[t]) {
            uint32_t *h = vec_push(&w->held, 1);
            if (!h)
                goto oom;
            memcpy(h, s, sizeof s);
            for (int k = 0; k < 3; k++)
                w->slots[s[k]].held++;
        } else if (!make_final(w, s)) {
            goto oom;
        }
    }
    /* the vertices the client removed */
    for (size_t v = 0; v < nv; v++)
        slot_release(w, lv[v]);
    st = deliver(w);
    if (st != ISOMEND_OK)
        goto done;
    if (w->c.done && (st = w->c.done(w->c.user, w)) != ISOMEND_OK)
        goto done;
    /* the stream's positions below the top plane are no longer needed */
    {
        const size_t drop = (size_t)(top_lo - w->raw_base);
        if (w->raw.n > drop)
            memmove(w->raw.p, (const float *)w->raw.p + 3 * drop, (w->raw.n - drop) * 12);
        w->raw.n -= drop;
        w->raw_base = top_lo;
    }
    w->chunk.n = 0;
    goto done;
oom:
    st = ISOMEND_ERR_OUT_OF_MEMORY;
done:
    mem_tally_sub(&w->mem, scratch);
    isomend_mesh_destroy(m);
    isomend_mesh_destroy(r);
    free(wt);
    free(lv);
    free(kept);
    free(out_slot);
    free(dist);
    free(fin);
    free(age);
    return st == ISOMEND_OK ? ISOMEND_OK : stream_window_fail(w, st);
}

/* ------------------------------------------------------------------ the stream's sink */

static int on_vertices(void *user, uint64_t first, size_t count, const float *pos, const float *nrm,
                       const uint64_t *keys)
{
    (void)nrm;
    (void)keys;
    stream_window *w = user;
    if (w->status != ISOMEND_OK)
        return 1;
    if (first != w->next_id)
        return stream_window_fail(w, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    float *p = vec_push(&w->raw, count);
    if (!p)
        return stream_window_fail(w, ISOMEND_ERR_OUT_OF_MEMORY), 1;
    if (count)
        memcpy(p, pos, count * 12);
    w->next_id += count;
    return 0;
}

static int on_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    (void)origins;
    stream_window *w = user;
    if (w->status != ISOMEND_OK)
        return 1;
    for (size_t i = 0; i < 3 * count; i++)
        if (ids[i] < w->raw_base || ids[i] >= w->next_id ||
            (w->c.strict_floor && ids[i] < w->floor))
            return stream_window_fail(w, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    uint64_t *t = vec_push(&w->chunk, count);
    if (!t)
        return stream_window_fail(w, ISOMEND_ERR_OUT_OF_MEMORY), 1;
    if (count)
        memcpy(t, ids, count * 24);
    w->triangles_in += count;
    return 0;
}

static int on_retire(void *user, uint64_t floor)
{
    stream_window *w = user;
    if (w->status != ISOMEND_OK)
        return 1;
    if (floor < w->floor || floor > w->next_id)
        return stream_window_fail(w, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    w->floor = floor;
    if (w->floors)
        w->floors[(uint64_t)(w->layers + 1) % (w->c.young + 1)] = floor;
    if (++w->layers % w->K == 0 && run_window(w, 0) != ISOMEND_OK)
        return 1;
    if (w->c.retire_each && w->out.retire(w->out.user, w->out_floor))
        return stream_window_fail(w, ISOMEND_ERR_SINK), 1;
    return 0;
}

/* ------------------------------------------------------------------ the window's life */

isomend_status stream_window_begin(const stream_window_client *client, const isomend_mesh_sink *out,
                                   int normals, int64_t K, stream_window **sw)
{
    *sw = NULL;
    stream_window *w = calloc(1, sizeof *w);
    if (!w)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    w->c = *client;
    w->out = *out;
    w->normals = normals;
    w->K = K;
    w->free_slot = NONE;
    if (client->more && !(w->floors = calloc((size_t)client->young + 1, sizeof *w->floors))) {
        free(w);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    w->raw.size = 12;
    w->chunk.size = 24;
    w->held.size = w->waiting.size = 12;
    w->vpos.size = w->vnrm.size = 12;
    w->tbuf.size = 24;
    vec *const all[] = {&w->raw, &w->chunk, &w->held, &w->waiting, &w->vpos, &w->vnrm, &w->tbuf};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++)
        all[i]->tally = &w->mem;
    mem_tally_add(&w->mem, sizeof *w + (w->floors ? ((uint64_t)client->young + 1) * 8 : 0));
    *sw = w;
    return ISOMEND_OK;
}

void stream_window_sink(stream_window *w, isomend_mesh_sink *sink)
{
    *sink = (isomend_mesh_sink){w, on_vertices, on_triangles, on_retire, NULL};
}

isomend_status stream_window_finish(stream_window *w, int force)
{
    if (w->status == ISOMEND_OK && (w->chunk.n || w->held.n || force))
        (void)run_window(w, 1);
    return w->status;
}

isomend_status stream_window_close(stream_window *w)
{
    if (w->status == ISOMEND_OK && w->waiting.n)
        (void)stream_window_fail(w,
                                 ISOMEND_ERR_INVALID_ARGUMENT); /* not reached: nothing is held */
    if (w->status == ISOMEND_OK && !w->c.retire_each && w->out_next > w->out_floor &&
        w->out.retire(w->out.user, w->out_next))
        (void)stream_window_fail(w, ISOMEND_ERR_SINK);
    return w->status;
}

void stream_window_destroy(stream_window *w)
{
    if (!w)
        return;
    free(w->raw.p);
    free(w->chunk.p);
    free(w->floors);
    free(w->slots);
    free(w->data);
    id_table_free(&w->ids);
    free(w->held.p);
    free(w->waiting.p);
    free(w->vpos.p);
    free(w->vnrm.p);
    free(w->tbuf.p);
    free(w);
}
