/*
 * decimate_stream.c - the decimation of a streamed mesh, in memory bounded
 * by a chunk of layers: isomend_decimate_stream_*().
 *
 * A sliding window.  The stream's layers are grouped in chunks of K layers.
 * When chunk c is complete, the window W = H (the triangles held back from
 * the previous window) + chunk c's triangles is decimated by
 * mesh_decimate_to() (decimate.c), which locks every vertex on a once-used
 * edge: so the cut vertices of W (those with triangles outside it: already
 * final below, or in chunk c + 1 above, whose plane of vertices is the top
 * slice of chunk c) neither move nor go, and no collapse reaches across a
 * cut.  Then the triangles of W's result within RINGS rings of the top
 * plane are held back (the next H: there the plane's vertices get their
 * triangles of both sides into one window and become free), and every
 * other triangle is final.  Each window is thus a decimation of a piece of
 * the surface whose cut is locked; the pieces fit as they did, and a
 * closed, oriented 2-manifold stays one, components and genus included
 * (decimate.c's link condition, within the piece).
 *
 *     layers:   0 ............ K ............ 2K ........... 3K
 *     window 0: [ chunk 0      )H0
 *     window 1:             H0 [ chunk 1      )H1
 *     window 2:                            H1 [ chunk 2      ) ...
 *
 * Targets.  Each window aims at the running total: ratio of the stream's
 * triangles so far, counting the triangles at the new top plane (which the
 * window cannot touch) as they are, so that the next window, where they are
 * free, reduces them.
 *
 * Output.  A vertex is delivered once every triangle around it is final
 * (it never gets a triangle again: only a top plane's vertices get new
 * ones, and they are held), with the area-weighted normal of those
 * triangles; a final triangle once its three vertices are delivered.  Ids
 * count from 0 in the order vertices are first delivered; retire() follows
 * the lowest id a waiting triangle still uses.
 *
 * Quadrics.  A held vertex keeps its quadric (decimate_carry): the planes of
 * every stream triangle it stands for, so that the next window costs its
 * collapses as one decimation of the whole mesh would; only the chunk's new
 * triangles add planes.
 *
 * Vertices are slots in a table keyed by the stream's vertex id: a window's
 * vertices and the held and waiting triangles' (O(chunk) memory).  The
 * distance from each stream vertex to the result is measured per chunk,
 * MEASURE_LAYERS layers later, against the surface as it then stands near it
 * (the final triangles of the windows since the one before the chunk's, and
 * the band still held): the held band may still change, so this is a
 * measurement of the surface at that time, which tests compare with the
 * distance to the written mesh.
 */
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX
#define NO_ID UINT64_MAX
/* The held band: triangles within this many rings (edges) of the top
 * plane's vertices. */
#define RINGS 3
/* A chunk's vertices are measured when this many more windows are done. */
/* A chunk's vertices are measured once this many more layers are done (the
 * held band, re-decimated window after window, is final by then), and at
 * least 2 windows. */
#define MEASURE_LAYERS 48
/* The memory estimate: bytes a stream triangle costs in a window (its ids,
 * the stream's positions, the window's mesh, decimate.c's tables and
 * candidates, the result) and stream triangles a marched sample. */
#define BYTES_PER_TRIANGLE 256.0
#define TRIANGLES_PER_SAMPLE 0.25

typedef struct slot {
    float p[3];
    uint32_t held;    /* its triangles not yet final (held or in a window) */
    uint32_t pending; /* its triangles not yet delivered (final or not)    */
    uint32_t local;   /* scratch: index in the window's mesh               */
    uint64_t id;      /* the stream's id                                   */
    uint64_t out;     /* the delivered id, NO_ID before                    */
    double n[3];      /* the final triangles' area-weighted normal sum     */
    double q[10];     /* a held vertex's quadric: its triangles' planes so far */
} slot;

/* A growable array of elements of `size` bytes. */
typedef struct vec {
    void *p;
    size_t n, cap, size;
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

/* A chunk's stream vertices (their positions), waiting to be measured. */
typedef struct measured {
    float *p;
    size_t n;
} measured;

struct isomend_decimate_stream {
    isomend_mesh_sink out;
    double ratio;
    int normals;
    int64_t K;
    isomend_status status;

    /* the stream's side */
    int64_t layers;           /* layers completed (retire calls)          */
    uint64_t next_id;         /* stream vertices delivered                */
    uint64_t floor;           /* the last floor retired                   */
    vec raw;                  /* floats: positions of ids raw_base..      */
    uint64_t raw_base;
    vec chunk;                /* uint64_t x 3: the chunk's triangles      */
    uint64_t plane_lo, plane_hi; /* the bottom plane's ids (chunk start)  */
    uint64_t own_first;       /* first id of the chunk's own vertices     */
    uint64_t triangles_in;    /* stream triangles so far                  */

    /* the slots */
    slot *slots;
    size_t nslots, cap_slots;
    uint32_t free_slot; /* a free list through slot.local */
    uint64_t *hkey;     /* open addressing: stream id -> slot            */
    uint32_t *hval;
    size_t hcap, hcount;

    vec held;    /* uint32_t x 3: the held triangles (slots)              */
    vec waiting; /* uint32_t x 3: final triangles not delivered           */
    uint64_t final_count;  /* triangles made final                       */
    uint64_t out_next;     /* vertices delivered                          */
    uint64_t out_floor;

    /* measuring */
    int lag;                        /* windows before a chunk is measured  */
    measured *pend;                 /* lag + 1: chunks not yet measured, oldest first */
    int npend;
    vec *soup;                      /* lag + 2, floats x 9: final triangles of the last windows */
    double err_max, err_sum;
    uint64_t err_n;

    /* delivery scratch */
    vec vpos, vnrm; /* floats x 3: the positions and normals of a batch */
    vec tbuf;  /* uint64_t x 3 */

    isomend_decimate_report rep;
};

/* ------------------------------------------------------------------ the slot table */

static size_t hash_of(uint64_t id, size_t cap)
{
    id ^= id >> 33;
    id *= 0xff51afd7ed558ccdULL;
    id ^= id >> 33;
    return (size_t)id & (cap - 1);
}

static int table_grow(isomend_decimate_stream *d)
{
    const size_t cap = d->hcap ? 2 * d->hcap : 1024;
    uint64_t *k = malloc(cap * sizeof *k);
    uint32_t *v = malloc(cap * sizeof *v);
    if (!k || !v) {
        free(k);
        free(v);
        return 0;
    }
    for (size_t i = 0; i < cap; i++)
        k[i] = NO_ID;
    for (size_t i = 0; i < d->hcap; i++)
        if (d->hkey[i] != NO_ID) {
            size_t h = hash_of(d->hkey[i], cap);
            while (k[h] != NO_ID)
                h = (h + 1) & (cap - 1);
            k[h] = d->hkey[i];
            v[h] = d->hval[i];
        }
    free(d->hkey);
    free(d->hval);
    d->hkey = k;
    d->hval = v;
    d->hcap = cap;
    return 1;
}

static uint32_t table_find(const isomend_decimate_stream *d, uint64_t id)
{
    if (!d->hcap)
        return NONE;
    for (size_t h = hash_of(id, d->hcap);; h = (h + 1) & (d->hcap - 1)) {
        if (d->hkey[h] == id)
            return d->hval[h];
        if (d->hkey[h] == NO_ID)
            return NONE;
    }
}

static void table_remove(isomend_decimate_stream *d, uint64_t id)
{
    const size_t mask = d->hcap - 1;
    size_t h = hash_of(id, d->hcap);
    while (d->hkey[h] != id)
        h = (h + 1) & mask;
    /* backward shift: the entries after the hole that may move into it */
    for (size_t j = (h + 1) & mask;; j = (j + 1) & mask) {
        if (d->hkey[j] == NO_ID)
            break;
        const size_t home = hash_of(d->hkey[j], d->hcap);
        /* j's entry may fill h if its home is not in (h, j] cyclically */
        if (((j - home) & mask) >= ((j - h) & mask)) {
            d->hkey[h] = d->hkey[j];
            d->hval[h] = d->hval[j];
            h = j;
        }
    }
    d->hkey[h] = NO_ID;
    d->hcount--;
}

/* The slot of stream vertex id, made at position p if it has none. */
static uint32_t slot_of(isomend_decimate_stream *d, uint64_t id, const float *p)
{
    uint32_t s = table_find(d, id);
    if (s != NONE)
        return s;
    if (2 * (d->hcount + 1) > d->hcap && !table_grow(d))
        return NONE;
    if (d->free_slot != NONE) {
        s = d->free_slot;
        d->free_slot = d->slots[s].local;
    } else {
        if (d->nslots == d->cap_slots) {
            const size_t cap = d->cap_slots ? 2 * d->cap_slots : 1024;
            slot *n = realloc(d->slots, cap * sizeof *n);
            if (!n)
                return NONE;
            d->slots = n;
            d->cap_slots = cap;
        }
        s = (uint32_t)d->nslots++;
    }
    slot *x = &d->slots[s];
    memset(x, 0, sizeof *x);
    memcpy(x->p, p, sizeof x->p);
    x->local = NONE;
    x->id = id;
    x->out = NO_ID;
    size_t h = hash_of(id, d->hcap);
    while (d->hkey[h] != NO_ID)
        h = (h + 1) & (d->hcap - 1);
    d->hkey[h] = id;
    d->hval[h] = s;
    d->hcount++;
    return s;
}

/* Frees slot s once nothing uses it. */
static void slot_release(isomend_decimate_stream *d, uint32_t s)
{
    slot *x = &d->slots[s];
    if (x->held || x->pending || x->id == NO_ID)
        return;
    table_remove(d, x->id);
    x->id = NO_ID;
    x->local = d->free_slot;
    d->free_slot = s;
}

/* ------------------------------------------------------------------ delivery */

static void add_normal(isomend_decimate_stream *d, const uint32_t *t)
{
    const float *a = d->slots[t[0]].p, *b = d->slots[t[1]].p, *c = d->slots[t[2]].p;
    const double e1[3] = {(double)b[0] - a[0], (double)b[1] - a[1], (double)b[2] - a[2]};
    const double e2[3] = {(double)c[0] - a[0], (double)c[1] - a[1], (double)c[2] - a[2]};
    const double f[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                         e1[0] * e2[1] - e1[1] * e2[0]};
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 3; i++)
            d->slots[t[k]].n[i] += f[i];
}

/* Triangle t (slots) is final: it waits for delivery, its geometry counts
 * for its vertices' normals and for the measurement of its window. */
static int make_final(isomend_decimate_stream *d, const uint32_t *t, vec *soup)
{
    uint32_t *w = vec_push(&d->waiting, 1);
    float *f = vec_push(soup, 1);
    if (!w || !f)
        return 0;
    memcpy(w, t, 3 * sizeof *t);
    for (int k = 0; k < 3; k++) {
        d->slots[t[k]].pending++;
        memcpy(f + 3 * k, d->slots[t[k]].p, 3 * sizeof(float));
    }
    if (d->normals)
        add_normal(d, t);
    d->final_count++;
    return 1;
}

static isomend_status fail(isomend_decimate_stream *d, isomend_status st)
{
    if (d->status == ISOMEND_OK)
        d->status = st;
    return d->status;
}

/* Delivers every waiting triangle whose vertices are done (no held
 * triangle), their new vertices first, in the order they wait. */
static isomend_status deliver(isomend_decimate_stream *d)
{
    uint32_t *w = d->waiting.p;
    const size_t n = d->waiting.n;
    d->vpos.n = d->vnrm.n = d->tbuf.n = 0;
    size_t keep = 0, nv = 0;
    uint64_t low = NO_ID; /* the lowest delivered id a waiting triangle uses */
    for (size_t i = 0; i < n; i++) {
        const uint32_t *t = w + 3 * i;
        const int ready = !d->slots[t[0]].held && !d->slots[t[1]].held && !d->slots[t[2]].held;
        if (!ready) {
            memmove(w + 3 * keep++, t, 3 * sizeof *t);
            continue;
        }
        uint64_t *ids = vec_push(&d->tbuf, 1);
        if (!ids)
            return fail(d, ISOMEND_ERR_OUT_OF_MEMORY);
        for (int k = 0; k < 3; k++) {
            slot *x = &d->slots[t[k]];
            if (x->out == NO_ID) {
                float *v = vec_push(&d->vpos, 1), *nv3 = d->normals ? vec_push(&d->vnrm, 1) : NULL;
                if (!v || (d->normals && !nv3))
                    return fail(d, ISOMEND_ERR_OUT_OF_MEMORY);
                memcpy(v, x->p, 3 * sizeof(float));
                const double len = sqrt(x->n[0] * x->n[0] + x->n[1] * x->n[1] + x->n[2] * x->n[2]);
                for (int c = 0; nv3 && c < 3; c++)
                    nv3[c] = len > 0 && isfinite(len) ? (float)(x->n[c] / len)
                                                      : (c == 2 ? 1.0f : 0.0f);
                x->out = d->out_next + nv++;
            }
            ids[k] = x->out;
        }
        for (int k = 0; k < 3; k++) {
            d->slots[t[k]].pending--;
            slot_release(d, t[k]);
        }
    }
    d->waiting.n = keep;
    for (size_t i = 0; i < 3 * keep; i++) /* after the loop: ids given to later triangles count */
        if (d->slots[w[i]].out < low)
            low = d->slots[w[i]].out;
    if (nv) {
        if (d->out.vertices(d->out.user, d->out_next, nv, d->vpos.p,
                            d->normals ? d->vnrm.p : NULL, NULL))
            return fail(d, ISOMEND_ERR_SINK);
        d->out_next += nv;
    }
    if (d->tbuf.n && d->out.triangles(d->out.user, d->tbuf.n, d->tbuf.p, NULL))
        return fail(d, ISOMEND_ERR_SINK);
    d->rep.triangles_after += d->tbuf.n;
    const uint64_t floor = low == NO_ID ? d->out_next : low;
    if (floor > d->out_floor) {
        if (d->out.retire(d->out.user, floor))
            return fail(d, ISOMEND_ERR_SINK);
        d->out_floor = floor;
    }
    return ISOMEND_OK;
}

/* ------------------------------------------------------------------ measuring */

/* The distance from pts to the final triangles of the kept windows. */
static isomend_status measure(isomend_decimate_stream *d, const measured *m)
{
    if (!m->n)
        return ISOMEND_OK;
    size_t nt = d->held.n;
    for (int j = 0; j < d->lag + 2; j++)
        nt += d->soup[j].n;
    if (!nt)
        return ISOMEND_OK; /* nothing final near them: no surface left */
    float *pos = malloc(nt * 36);
    uint32_t *tri = malloc(nt * 12);
    if (!pos || !tri) {
        free(pos);
        free(tri);
        return fail(d, ISOMEND_ERR_OUT_OF_MEMORY);
    }
    size_t at = 0;
    for (int j = 0; j < d->lag + 2; j++) {
        if (d->soup[j].n)
            memcpy(pos + 9 * at, d->soup[j].p, d->soup[j].n * 36);
        at += d->soup[j].n;
    }
    const uint32_t *h = d->held.p; /* the band still held, as it stands */
    for (size_t t = 0; t < d->held.n; t++, at++)
        for (int k = 0; k < 3; k++)
            memcpy(pos + 9 * at + 3 * k, d->slots[h[3 * t + (size_t)k]].p, 12);
    for (size_t i = 0; i < 3 * nt; i++)
        tri[i] = (uint32_t)i;
    double mx = 0, mean = 0;
    const int ok = mesh_distances(m->p, m->n, pos, tri, nt, &mx, &mean);
    free(pos);
    free(tri);
    if (!ok)
        return fail(d, ISOMEND_ERR_OUT_OF_MEMORY);
    d->err_max = mx > d->err_max ? mx : d->err_max;
    d->err_sum += mean * (double)m->n;
    d->err_n += m->n;
    return ISOMEND_OK;
}

/* The oldest waiting chunk measured and dropped. */
static isomend_status measure_oldest(isomend_decimate_stream *d)
{
    isomend_status st = measure(d, &d->pend[0]);
    free(d->pend[0].p);
    memmove(d->pend, d->pend + 1, (size_t)(d->npend - 1) * sizeof d->pend[0]);
    d->npend--;
    d->pend[d->npend].p = NULL;
    d->pend[d->npend].n = 0;
    return st;
}

/* ------------------------------------------------------------------ a window */

/* Rings from the top plane's vertices over mesh r (dist: RINGS or more where
 * farther). */
static int rings(const isomend_mesh *r, const uint32_t *out_slot, const slot *slots,
                 uint64_t top_lo, uint64_t top_hi, uint8_t *dist)
{
    const size_t nv = r->nv, nt = r->nt;
    uint32_t *first = calloc(nv + 1, sizeof *first), *tris = malloc((3 * nt + 1) * sizeof *tris);
    uint32_t *queue = malloc((nv + 1) * sizeof *queue);
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
        dist[v] = id >= top_lo && id < top_hi ? 0 : RINGS;
        if (!dist[v])
            queue[tail++] = (uint32_t)v;
    }
    while (head < tail) {
        const uint32_t v = queue[head++];
        if (dist[v] + 1 >= RINGS)
            continue;
        for (uint32_t i = first[v]; i < first[v + 1]; i++)
            for (int k = 0; k < 3; k++) {
                const uint32_t w = r->tri[3 * (size_t)tris[i] + (size_t)k];
                if (dist[w] == RINGS) {
                    dist[w] = (uint8_t)(dist[v] + 1);
                    queue[tail++] = w;
                }
            }
    }
    free(first);
    free(tris);
    free(queue);
    return 1;
}

/* The window: the held triangles and the chunk's, decimated; the band at the
 * top plane held back, the rest final.  last: no chunk follows. */
static isomend_status run_window(isomend_decimate_stream *d, int last)
{
    const uint64_t top_lo = last ? d->next_id : d->floor, top_hi = d->next_id;
    /* a new soup for this window's final triangles; the oldest is dropped */
    vec old = d->soup[d->lag + 1];
    memmove(d->soup + 1, d->soup, (size_t)(d->lag + 1) * sizeof d->soup[0]);
    d->soup[0] = old;
    d->soup[0].n = 0;

    const size_t nheld = d->held.n, nchunk = d->chunk.n, nt = nheld + nchunk;
    isomend_status st = ISOMEND_OK;
    isomend_mesh *m = calloc(1, sizeof *m), *r = NULL;
    uint32_t *wt = malloc((3 * nt + 1) * sizeof *wt), *lv = malloc((3 * nt + 1) * sizeof *lv);
    uint32_t *kept = NULL, *out_slot = NULL;
    uint8_t *dist = NULL;
    double *q_in = NULL;
    decimate_carry carry = {NULL, 0, NULL};
    if (!m || !wt || !lv)
        goto oom;
    /* the window's triangles as slots: the held ones, then the chunk's */
    if (nheld)
        memcpy(wt, d->held.p, 3 * nheld * sizeof *wt);
    const uint64_t *ct = d->chunk.p;
    uint64_t n_top = 0;
    for (size_t t = 0; t < nchunk; t++) {
        int top = 0;
        for (int k = 0; k < 3; k++) {
            const uint64_t id = ct[3 * t + (size_t)k];
            const float *p = (const float *)d->raw.p + 3 * (id - d->raw_base);
            const uint32_t s = slot_of(d, id, p);
            if (s == NONE)
                goto oom;
            d->slots[s].held++;
            wt[3 * (nheld + t) + (size_t)k] = s;
            top |= id >= top_lo && id < top_hi;
        }
        n_top += (uint64_t)top;
    }
    /* its mesh: vertices in the order of first use */
    size_t nv = 0;
    for (size_t i = 0; i < 3 * nt; i++) {
        slot *x = &d->slots[wt[i]];
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
    for (size_t v = 0; v < nv; v++)
        memcpy(m->pos + 3 * v, d->slots[lv[v]].p, 12);
    for (size_t i = 0; i < 3 * nt; i++)
        m->tri[i] = d->slots[wt[i]].local;
    for (size_t v = 0; v < nv; v++)
        d->slots[lv[v]].local = NONE;
    /* the running total at ratio, the new top plane's triangles as they are */
    const double keep = ceil(d->ratio * (double)(d->triangles_in - n_top)) + (double)n_top;
    double target = keep - (double)d->final_count;
    const double least = ceil(0.5 * d->ratio * (double)nt);
    target = target < least ? least : target;
    isomend_decimate_report wr;
    /* the held vertices' quadrics carry the planes of their earlier triangles
     * (the held ones' included); the chunk's triangles add theirs */
    q_in = malloc((10 * nv + 1) * sizeof *q_in);
    carry.q_in = q_in;
    carry.planes_from = nheld;
    if (!q_in)
        goto oom;
    for (size_t v = 0; v < nv; v++)
        memcpy(q_in + 10 * v, d->slots[lv[v]].q, sizeof d->slots[0].q);
    if (nt) {
        st = mesh_decimate_to(m, (uint64_t)target, 0.0, 0, &r, &kept, &carry, &wr);
        free(q_in);
        q_in = NULL;
        if (st != ISOMEND_OK)
            goto done;
        d->rep.collapses += wr.collapses;
        d->rep.refused_topology += wr.refused_topology;
        d->rep.refused_geometry += wr.refused_geometry;
        d->rep.locked_vertices += wr.locked_vertices;
    }
    /* the window's triangles are consumed; its kept vertices take their place */
    for (size_t i = 0; i < 3 * nt; i++)
        d->slots[wt[i]].held--;
    d->held.n = 0;
    const size_t rv = r ? r->nv : 0, rt = r ? r->nt : 0;
    out_slot = malloc((rv + 1) * sizeof *out_slot);
    dist = malloc(rv + 1);
    if (!out_slot || !dist)
        goto oom;
    for (size_t v = 0; v < rv; v++) {
        out_slot[v] = lv[kept[v]];
        memcpy(d->slots[out_slot[v]].p, r->pos + 3 * v, 12);
        memcpy(d->slots[out_slot[v]].q, carry.q_out + 10 * v, sizeof d->slots[0].q);
    }
    if (rv && !rings(r, out_slot, d->slots, top_lo, top_hi, dist))
        goto oom;
    for (size_t t = 0; t < rt; t++) {
        uint32_t s[3];
        int near = 0;
        for (int k = 0; k < 3; k++) {
            const uint32_t v = r->tri[3 * t + (size_t)k];
            s[k] = out_slot[v];
            near |= dist[v] < RINGS;
        }
        if (near) {
            uint32_t *h = vec_push(&d->held, 1);
            if (!h)
                goto oom;
            memcpy(h, s, sizeof s);
            for (int k = 0; k < 3; k++)
                d->slots[s[k]].held++;
        } else if (!make_final(d, s, &d->soup[0])) {
            goto oom;
        }
    }
    /* the vertices the collapses removed */
    for (size_t v = 0; v < nv; v++)
        slot_release(d, lv[v]);
    st = deliver(d);
    if (st != ISOMEND_OK)
        goto done;
    /* the chunk's own stream vertices wait to be measured */
    {
        measured *pm = &d->pend[d->npend++];
        pm->n = (size_t)(d->next_id - d->own_first);
        pm->p = malloc(pm->n * 12 + 1);
        if (!pm->p)
            goto oom;
        if (pm->n)
            memcpy(pm->p, (const float *)d->raw.p + 3 * (d->own_first - d->raw_base), pm->n * 12);
        d->own_first = d->next_id;
        if (d->npend > d->lag && (st = measure_oldest(d)) != ISOMEND_OK)
            goto done;
    }
    /* the stream's positions below the top plane are no longer needed */
    {
        const size_t drop = (size_t)(top_lo - d->raw_base);
        if (d->raw.n > drop)
            memmove(d->raw.p, (const float *)d->raw.p + 3 * drop, (d->raw.n - drop) * 12);
        d->raw.n -= drop;
        d->raw_base = top_lo;
    }
    d->chunk.n = 0;
    goto done;
oom:
    st = ISOMEND_ERR_OUT_OF_MEMORY;
done:
    free(q_in);
    free(carry.q_out);
    isomend_mesh_destroy(m);
    isomend_mesh_destroy(r);
    free(wt);
    free(lv);
    free(kept);
    free(out_slot);
    free(dist);
    return st == ISOMEND_OK ? ISOMEND_OK : fail(d, st);
}

/* ------------------------------------------------------------------ the stream's sink */

static int on_vertices(void *user, uint64_t first, size_t count, const float *pos,
                       const float *nrm, const uint64_t *keys)
{
    (void)nrm;
    (void)keys;
    isomend_decimate_stream *d = user;
    if (d->status != ISOMEND_OK)
        return 1;
    if (first != d->next_id)
        return fail(d, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    float *p = vec_push(&d->raw, count);
    if (!p)
        return fail(d, ISOMEND_ERR_OUT_OF_MEMORY), 1;
    if (count)
        memcpy(p, pos, count * 12);
    d->next_id += count;
    return 0;
}

static int on_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    (void)origins;
    isomend_decimate_stream *d = user;
    if (d->status != ISOMEND_OK)
        return 1;
    for (size_t i = 0; i < 3 * count; i++)
        if (ids[i] < d->raw_base || ids[i] >= d->next_id)
            return fail(d, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    uint64_t *t = vec_push(&d->chunk, count);
    if (!t)
        return fail(d, ISOMEND_ERR_OUT_OF_MEMORY), 1;
    if (count)
        memcpy(t, ids, count * 24);
    d->triangles_in += count;
    return 0;
}

static int on_retire(void *user, uint64_t floor)
{
    isomend_decimate_stream *d = user;
    if (d->status != ISOMEND_OK)
        return 1;
    if (floor < d->floor || floor > d->next_id)
        return fail(d, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    d->floor = floor;
    if (++d->layers % d->K == 0 && run_window(d, 0) != ISOMEND_OK)
        return 1;
    return 0;
}

/* ------------------------------------------------------------------ the API */

static int plane_of(const isomend_volume *desc, const isomend_options *opts, double *plane)
{
    if (!desc || isomend_stream_memory(desc, opts) == 0)
        return 0;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const int pad = ((opts ? opts : &defaults)->flags & ISOMEND_FLAG_PAD) != 0;
    *plane = (double)(desc->dims[0] + 2 * pad) * (double)(desc->dims[1] + 2 * pad);
    return 1;
}

int64_t isomend_decimate_stream_layers(const isomend_volume *desc, const isomend_options *opts,
                                       uint64_t max_bytes)
{
    double plane;
    if (!plane_of(desc, opts, &plane))
        return 0;
    double k = floor(4194304.0 / plane);
    k = k < 4 ? 4 : k > 64 ? 64 : k;
    if (max_bytes) {
        const double fit = floor((double)max_bytes / (plane * TRIANGLES_PER_SAMPLE * BYTES_PER_TRIANGLE)) - 1;
        k = fit < k ? fit : k;
        k = k < 1 ? 1 : k;
    }
    return (int64_t)k;
}

uint64_t isomend_decimate_stream_memory(const isomend_volume *desc, const isomend_options *opts,
                                        int64_t chunk_layers)
{
    double plane;
    if (!plane_of(desc, opts, &plane) || chunk_layers < 0)
        return 0;
    if (chunk_layers == 0)
        chunk_layers = isomend_decimate_stream_layers(desc, opts, 0);
    const double bytes =
        ((double)chunk_layers + 1) * plane * TRIANGLES_PER_SAMPLE * BYTES_PER_TRIANGLE + 1048576.0;
    return bytes < 1.8e19 ? (uint64_t)bytes : UINT64_MAX;
}

isomend_status isomend_decimate_stream_begin(const isomend_volume *desc,
                                             const isomend_options *opts,
                                             const isomend_decimate_options *dopts,
                                             int64_t chunk_layers, const isomend_mesh_sink *out,
                                             isomend_decimate_stream **ds)
{
    if (!ds)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *ds = NULL;
    double plane;
    if (!dopts || !out || !out->vertices || !out->triangles || !out->retire || chunk_layers < 0 ||
        !(dopts->ratio > 0.0 && dopts->ratio <= 1.0) || dopts->target_triangles ||
        dopts->max_error != 0.0)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (!plane_of(desc, opts, &plane))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_decimate_stream *d = calloc(1, sizeof *d);
    if (!d)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    isomend_options defaults;
    isomend_options_init(&defaults);
    d->out = *out;
    d->ratio = dopts->ratio;
    d->normals = !((opts ? opts : &defaults)->flags & ISOMEND_FLAG_NO_NORMALS);
    d->K = chunk_layers ? chunk_layers : isomend_decimate_stream_layers(desc, opts, 0);
    d->free_slot = NONE;
    d->raw.size = 12;
    d->chunk.size = 24;
    d->held.size = d->waiting.size = 12;
    d->vpos.size = d->vnrm.size = 12;
    d->tbuf.size = 24;
    d->lag = (int)((MEASURE_LAYERS + d->K - 1) / d->K);
    d->lag = d->lag < 2 ? 2 : d->lag;
    d->pend = calloc((size_t)d->lag + 1, sizeof *d->pend);
    d->soup = calloc((size_t)d->lag + 2, sizeof *d->soup);
    if (!d->pend || !d->soup) {
        isomend_decimate_stream_destroy(d);
        *ds = NULL;
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    for (int j = 0; j < d->lag + 2; j++)
        d->soup[j].size = 36;
    *ds = d;
    return ISOMEND_OK;
}

isomend_status isomend_decimate_stream_sink(isomend_decimate_stream *d, isomend_mesh_sink *sink)
{
    if (!d || !sink)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *sink = (isomend_mesh_sink){d, on_vertices, on_triangles, on_retire, NULL};
    return ISOMEND_OK;
}

isomend_status isomend_decimate_stream_finish(isomend_decimate_stream *d,
                                              isomend_decimate_report *report)
{
    if (report)
        memset(report, 0, sizeof *report);
    if (!d)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (d->status == ISOMEND_OK && (d->chunk.n || d->held.n || d->own_first < d->next_id))
        (void)run_window(d, 1);
    while (d->status == ISOMEND_OK && d->npend)
        (void)measure_oldest(d);
    if (d->status == ISOMEND_OK && d->waiting.n)
        (void)fail(d, ISOMEND_ERR_INVALID_ARGUMENT); /* not reached: nothing is held */
    if (d->status == ISOMEND_OK && d->out_next > d->out_floor &&
        d->out.retire(d->out.user, d->out_next))
        (void)fail(d, ISOMEND_ERR_SINK);
    if (d->status != ISOMEND_OK)
        return d->status;
    isomend_decimate_report *r = &d->rep;
    r->triangles_before = d->triangles_in;
    r->vertices_before = d->next_id;
    r->vertices_after = d->out_next;
    r->target_triangles = (uint64_t)ceil(d->ratio * (double)d->triangles_in);
    r->reached = r->triangles_after <= r->target_triangles;
    r->max_error = d->err_max;
    r->mean_error = d->err_n ? d->err_sum / (double)d->err_n : 0.0;
    if (report)
        *report = *r;
    return ISOMEND_OK;
}

void isomend_decimate_stream_destroy(isomend_decimate_stream *d)
{
    if (!d)
        return;
    free(d->raw.p);
    free(d->chunk.p);
    free(d->slots);
    free(d->hkey);
    free(d->hval);
    free(d->held.p);
    free(d->waiting.p);
    for (int j = 0; d->pend && j < d->lag + 1; j++)
        free(d->pend[j].p);
    for (int j = 0; d->soup && j < d->lag + 2; j++)
        free(d->soup[j].p);
    free(d->pend);
    free(d->soup);
    free(d->vpos.p);
    free(d->vnrm.p);
    free(d->tbuf.p);
    free(d);
}
