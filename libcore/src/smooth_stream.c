/*
 * smooth_stream.c - the smoothing of a streamed mesh, in memory bounded by a
 * chunk of layers and a band: isomend_smooth_stream_*().
 *
 * The sliding window of decimate_stream.c.  The stream's layers are grouped
 * in chunks of K layers.  When chunk c is complete, the window W = H (the
 * triangles held back from the previous window) + chunk c's triangles is
 * smoothed by isomend_mesh_smooth() (smooth.c), which locks every vertex on
 * a once-used edge: so the cut vertices of W (those with triangles outside
 * it: final below, or in chunk c + 1 above) do not move.  Then the
 * triangles within BAND = N + 1 rings of the new top plane are held back
 * (the next H), and every other triangle is final, with its vertices where
 * this window put them.  N iterations of the windowed sinc filter are N
 * steps of the umbrella operator, each reaching one ring further: a final
 * vertex, at least BAND rings from the top plane, moved as if the plane were
 * free (but for the volume restoration, one offset per component of the
 * window).
 *
 * Held vertices are smoothed again in the next window from their ORIGINAL
 * positions (the stream's), not twice: a window's mesh takes a vertex at
 * its final position if a final triangle has it (it is on the window's
 * lower cut, locked) and at its original position otherwise.  So each
 * vertex is smoothed once, in the window where its triangles become final,
 * with BAND rings of surface above it and all of its final neighbours
 * below (locked at their final positions).
 *
 * The volume.  isomend_mesh_smooth() restores each component's volume: for
 * a window (an open piece whose cut is locked) the signed volume of its
 * triangles is well defined (the cut does not move), so the window's
 * smoothing keeps it; the held band's share is redone in the next window,
 * so what a stream loses is the difference between a band smoothed with
 * the window below and with the one above (the report measures it: the
 * signed volume of the stream's triangles before and of the result after).
 *
 * Output.  As decimate_stream.c: a vertex is delivered once every triangle
 * around it is final, with the area-weighted normal of those triangles;
 * a final triangle once its three vertices are; ids from 0 in delivery
 * order; one retire() for each of the stream's (the lowest id a waiting
 * triangle uses), so that a streamed decimation after it counts the
 * stream's layers.  The mesh depends on the stream's vertices, triangles
 * and floors, the iterations and K only (not on the stream's threads).
 */
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX
#define NO_ID UINT64_MAX
/* The memory estimate: bytes a stream triangle costs in a window (its ids,
 * the stream's positions, the window's mesh, smooth.c's tables, the result)
 * and stream triangles a marched sample. */
#define BYTES_PER_TRIANGLE 200.0
#define TRIANGLES_PER_SAMPLE 0.25

typedef struct slot {
    float p[3];       /* its position: final once `fixed`               */
    float orig[3];    /* the stream's                                    */
    uint32_t held;    /* its triangles not yet final (held or in a window) */
    uint32_t pending; /* its triangles not yet delivered (final or not)    */
    uint32_t local;   /* scratch: index in the window's mesh               */
    int fixed;        /* a final triangle has it: p is final               */
    uint64_t id;      /* the stream's id                                   */
    uint64_t out;     /* the delivered id, NO_ID before                    */
    double n[3];      /* the final triangles' area-weighted normal sum     */
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

struct isomend_smooth_stream {
    isomend_mesh_sink out;
    int iterations, band;
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
    uint64_t out_next;     /* vertices delivered                          */
    uint64_t out_floor;

    /* delivery scratch */
    vec vpos, vnrm; /* floats x 3: the positions and normals of a batch */
    vec tbuf;  /* uint64_t x 3 */

    double max_d2;
    isomend_smooth_report rep;
};

/* ------------------------------------------------------------------ the slot table */

static size_t hash_of(uint64_t id, size_t cap)
{
    id ^= id >> 33;
    id *= 0xff51afd7ed558ccdULL;
    id ^= id >> 33;
    return (size_t)id & (cap - 1);
}

static int table_grow(isomend_smooth_stream *d)
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

static uint32_t table_find(const isomend_smooth_stream *d, uint64_t id)
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

static void table_remove(isomend_smooth_stream *d, uint64_t id)
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
static uint32_t slot_of(isomend_smooth_stream *d, uint64_t id, const float *p)
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
    memcpy(x->orig, p, sizeof x->orig);
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
static void slot_release(isomend_smooth_stream *d, uint32_t s)
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

static void add_normal(isomend_smooth_stream *d, const uint32_t *t)
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

/* The signed volume under triangle (a, b, c) (smooth.c's, about the origin). */
static double tet(const float *a, const float *b, const float *c)
{
    const double ax = a[0], ay = a[1], az = a[2], bx = b[0], by = b[1], bz = b[2];
    const double cx = c[0], cy = c[1], cz = c[2];
    return (ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)) / 6.0;
}

/* Triangle t (slots) is final: it waits for delivery, its vertices are
 * where they are now, its geometry counts for their normals and the volume. */
static int make_final(isomend_smooth_stream *d, const uint32_t *t)
{
    uint32_t *w = vec_push(&d->waiting, 1);
    if (!w)
        return 0;
    memcpy(w, t, 3 * sizeof *t);
    for (int k = 0; k < 3; k++) {
        slot *x = &d->slots[t[k]];
        x->pending++;
        x->fixed = 1;
    }
    if (d->normals)
        add_normal(d, t);
    d->rep.volume_after += tet(d->slots[t[0]].p, d->slots[t[1]].p, d->slots[t[2]].p);
    return 1;
}

static isomend_status fail(isomend_smooth_stream *d, isomend_status st)
{
    if (d->status == ISOMEND_OK)
        d->status = st;
    return d->status;
}

/* Delivers every waiting triangle whose vertices are done (no held
 * triangle), their new vertices first, in the order they wait. */
static isomend_status deliver(isomend_smooth_stream *d)
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
                double d2 = 0;
                for (int c = 0; c < 3; c++)
                    d2 += ((double)x->p[c] - x->orig[c]) * ((double)x->p[c] - x->orig[c]);
                d->rep.moved_vertices += d2 > 0;
                d->max_d2 = d2 > d->max_d2 ? d2 : d->max_d2;
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
    const uint64_t floor = low == NO_ID ? d->out_next : low;
    if (floor > d->out_floor)
        d->out_floor = floor;
    return ISOMEND_OK;
}

/* ------------------------------------------------------------------ a window */

/* Rings from the top plane's vertices over the window's mesh m (dist: band
 * or more where farther); lv: its vertices' slots. */
static int rings(const isomend_mesh *m, const uint32_t *lv, const slot *slots, uint64_t top_lo,
                 uint64_t top_hi, uint32_t band, uint32_t *dist)
{
    const size_t nv = m->nv, nt = m->nt;
    uint32_t *first = calloc(nv + 1, sizeof *first), *tris = malloc((3 * nt + 1) * sizeof *tris);
    uint32_t *queue = malloc((nv + 1) * sizeof *queue);
    if (!first || !tris || !queue) {
        free(first);
        free(tris);
        free(queue);
        return 0;
    }
    for (size_t i = 0; i < 3 * nt; i++)
        first[m->tri[i] + 1]++;
    for (size_t v = 0; v < nv; v++)
        first[v + 1] += first[v];
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++)
            tris[first[m->tri[3 * t + (size_t)k]]++] = (uint32_t)t;
    for (size_t v = nv; v > 0; v--)
        first[v] = first[v - 1];
    first[0] = 0;
    size_t head = 0, tail = 0;
    for (size_t v = 0; v < nv; v++) {
        const uint64_t id = slots[lv[v]].id;
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
                const uint32_t w = m->tri[3 * (size_t)tris[i] + (size_t)k];
                if (dist[w] == band) {
                    dist[w] = dist[v] + 1;
                    queue[tail++] = w;
                }
            }
    }
    free(first);
    free(tris);
    free(queue);
    return 1;
}

/* The window: the held triangles and the chunk's, smoothed; the band at the
 * top plane held back, the rest final.  last: no chunk follows. */
static isomend_status run_window(isomend_smooth_stream *d, int last)
{
    const uint64_t top_lo = last ? d->next_id : d->floor, top_hi = d->next_id;
    const size_t nheld = d->held.n, nchunk = d->chunk.n, nt = nheld + nchunk;
    isomend_status st = ISOMEND_OK;
    isomend_mesh *m = calloc(1, sizeof *m), *r = NULL;
    uint32_t *wt = malloc((3 * nt + 1) * sizeof *wt), *lv = malloc((3 * nt + 1) * sizeof *lv);
    uint32_t *dist = NULL;
    uint8_t *fin = NULL;
    if (!m || !wt || !lv)
        goto oom;
    /* the window's triangles as slots: the held ones, then the chunk's */
    if (nheld)
        memcpy(wt, d->held.p, 3 * nheld * sizeof *wt);
    const uint64_t *ct = d->chunk.p;
    for (size_t t = 0; t < nchunk; t++) {
        const float *q[3];
        for (int k = 0; k < 3; k++) {
            const uint64_t id = ct[3 * t + (size_t)k];
            q[k] = (const float *)d->raw.p + 3 * (id - d->raw_base);
            const uint32_t s = slot_of(d, id, q[k]);
            if (s == NONE)
                goto oom;
            d->slots[s].held++;
            wt[3 * (nheld + t) + (size_t)k] = s;
        }
        d->rep.volume_before += tet(q[0], q[1], q[2]);
    }
    /* its mesh: vertices in the order of first use, at their final
     * positions where a final triangle has them (the lower cut), else at
     * the stream's */
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
    dist = malloc((nv + 1) * sizeof *dist);
    fin = malloc(nt + 1);
    if (!m->pos || !m->tri || !dist || !fin)
        goto oom;
    for (size_t v = 0; v < nv; v++) {
        const slot *x = &d->slots[lv[v]];
        memcpy(m->pos + 3 * v, x->fixed ? x->p : x->orig, 12);
    }
    for (size_t i = 0; i < 3 * nt; i++)
        m->tri[i] = d->slots[wt[i]].local;
    for (size_t v = 0; v < nv; v++)
        d->slots[lv[v]].local = NONE;
    if (nt) {
        st = isomend_mesh_smooth(m, d->iterations, &r, NULL);
        if (st != ISOMEND_OK)
            goto done;
    }
    /* the window's triangles are consumed */
    for (size_t i = 0; i < 3 * nt; i++)
        d->slots[wt[i]].held--;
    d->held.n = 0;
    if (nv && !rings(m, lv, d->slots, top_lo, top_hi, (uint32_t)d->band, dist))
        goto oom;
    /* the final triangles' vertices take their smoothed positions (a fixed
     * one was locked: the same), then the band is held and the rest final */
    for (size_t t = 0; t < nt; t++) {
        fin[t] = 1;
        for (int k = 0; k < 3; k++)
            fin[t] &= dist[m->tri[3 * t + (size_t)k]] >= (uint32_t)d->band;
        for (int k = 0; fin[t] && k < 3; k++) {
            const uint32_t v = m->tri[3 * t + (size_t)k];
            memcpy(d->slots[lv[v]].p, r->pos + 3 * (size_t)v, 12);
        }
    }
    for (size_t t = 0; t < nt; t++) {
        const uint32_t *s = wt + 3 * t;
        if (!fin[t]) {
            uint32_t *h = vec_push(&d->held, 1);
            if (!h)
                goto oom;
            memcpy(h, s, 3 * sizeof *s);
            for (int k = 0; k < 3; k++)
                d->slots[s[k]].held++;
        } else if (!make_final(d, s)) {
            goto oom;
        }
    }
    for (size_t v = 0; v < nv; v++)
        slot_release(d, lv[v]);
    st = deliver(d);
    if (st != ISOMEND_OK)
        goto done;
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
    isomend_mesh_destroy(m);
    isomend_mesh_destroy(r);
    free(wt);
    free(lv);
    free(dist);
    free(fin);
    return st == ISOMEND_OK ? ISOMEND_OK : fail(d, st);
}

/* ------------------------------------------------------------------ the stream's sink */

static int on_vertices(void *user, uint64_t first, size_t count, const float *pos,
                       const float *nrm, const uint64_t *keys)
{
    (void)nrm;
    (void)keys;
    isomend_smooth_stream *d = user;
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
    isomend_smooth_stream *d = user;
    if (d->status != ISOMEND_OK)
        return 1;
    for (size_t i = 0; i < 3 * count; i++)
        if (ids[i] < d->raw_base || ids[i] >= d->next_id || ids[i] < d->floor)
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
    isomend_smooth_stream *d = user;
    if (d->status != ISOMEND_OK)
        return 1;
    if (floor < d->floor || floor > d->next_id)
        return fail(d, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    d->floor = floor;
    if (++d->layers % d->K == 0 && run_window(d, 0) != ISOMEND_OK)
        return 1;
    if (d->out.retire(d->out.user, d->out_floor))
        return fail(d, ISOMEND_ERR_SINK), 1;
    return 0;
}

/* ------------------------------------------------------------------ the API */

uint64_t isomend_smooth_stream_memory(const isomend_volume *desc, const isomend_options *opts,
                                      int iterations, int64_t chunk_layers)
{
    if (!desc || isomend_stream_memory(desc, opts) == 0 || iterations < 0 || iterations > 10000 ||
        chunk_layers < 0)
        return 0;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const int pad = ((opts ? opts : &defaults)->flags & ISOMEND_FLAG_PAD) != 0;
    const double plane = (double)(desc->dims[0] + 2 * pad) * (double)(desc->dims[1] + 2 * pad);
    if (chunk_layers == 0)
        chunk_layers = isomend_decimate_stream_layers(desc, opts, 0);
    /* a chunk and the band (a ring is at most a layer deep, about) */
    const double layers = (double)chunk_layers + (double)iterations + 2.0;
    const double bytes = layers * plane * TRIANGLES_PER_SAMPLE * BYTES_PER_TRIANGLE + 1048576.0;
    return bytes < 1.8e19 ? (uint64_t)bytes : UINT64_MAX;
}

isomend_status isomend_smooth_stream_begin(const isomend_volume *desc, const isomend_options *opts,
                                           int iterations, int64_t chunk_layers,
                                           const isomend_mesh_sink *out,
                                           isomend_smooth_stream **ss)
{
    if (!ss)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *ss = NULL;
    if (!out || !out->vertices || !out->triangles || !out->retire || chunk_layers < 0 ||
        iterations < 0 || iterations > 10000 || !desc || isomend_stream_memory(desc, opts) == 0)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_smooth_stream *d = calloc(1, sizeof *d);
    if (!d)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    isomend_options defaults;
    isomend_options_init(&defaults);
    d->out = *out;
    d->iterations = iterations;
    d->band = iterations + 1;
    d->normals = !((opts ? opts : &defaults)->flags & ISOMEND_FLAG_NO_NORMALS);
    d->K = chunk_layers ? chunk_layers : isomend_decimate_stream_layers(desc, opts, 0);
    d->free_slot = NONE;
    d->raw.size = 12;
    d->chunk.size = 24;
    d->held.size = d->waiting.size = 12;
    d->vpos.size = d->vnrm.size = 12;
    d->tbuf.size = 24;
    *ss = d;
    return ISOMEND_OK;
}

isomend_status isomend_smooth_stream_sink(isomend_smooth_stream *d, isomend_mesh_sink *sink)
{
    if (!d || !sink)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *sink = (isomend_mesh_sink){d, on_vertices, on_triangles, on_retire, NULL};
    return ISOMEND_OK;
}

isomend_status isomend_smooth_stream_finish(isomend_smooth_stream *d,
                                            isomend_smooth_report *report)
{
    if (report)
        memset(report, 0, sizeof *report);
    if (!d)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    /* the last window; no retire() is passed on for it (a step after this
     * one finishes the rest itself) */
    if (d->status == ISOMEND_OK && (d->chunk.n || d->held.n))
        (void)run_window(d, 1);
    if (d->status == ISOMEND_OK && d->waiting.n)
        (void)fail(d, ISOMEND_ERR_INVALID_ARGUMENT); /* not reached: nothing is held */
    if (d->status != ISOMEND_OK)
        return d->status;
    d->rep.max_displacement = sqrt(d->max_d2);
    if (report)
        *report = d->rep;
    return ISOMEND_OK;
}

void isomend_smooth_stream_destroy(isomend_smooth_stream *d)
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
    free(d->vpos.p);
    free(d->vnrm.p);
    free(d->tbuf.p);
    free(d);
}
