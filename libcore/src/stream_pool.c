/*
 * stream_pool.c - a stream on several threads: slabs of the marched grid
 * extracted by a pool of workers and handed to the sink in order.
 *
 *   push (caller)            workers (threads)               sink (caller)
 *   slice z copied into the  slab s: a run of the engine     slab s's calls replayed
 *   input of each slab whose (stream.c) on its input, read   in order, its ids made
 *   halo holds it (1 or 2:   in place, written in place      global a batch at a time
 *   a slab opened late takes into its slot's arrays, what    (local + base)
 *   them from the one below);  a sink would have heard kept
 *   a slab complete: queued
 *
 * A slab is a run of the engine (stream_direct_run, as isomend_extract()'s
 * staged runs): it numbers its vertices from 0, in isomend_extract()'s
 * order, and its last slice b, the next slab's first, on from its own
 * (numbered, not computed): the next slab numbers the same vertices first,
 * in the same order (the same scan of the same slice), so local id nv + i is
 * the next slab's vertex i, and base(s + 1) = base(s) + nv: the replay adds
 * the base to every id.  Slab s is delivered once it and slab s + 1 are
 * done: its calls (vertices, triangles, retire, as the run heard them)
 * replayed, the next slab's first vertices delivered just before the
 * triangles that use them.  The sink sees isomend_stream_push()'s sequence
 * of ids, triangles and floors, whatever the number of threads: the mesh is
 * the same bytes.
 *
 * Memory: at most `inflight` slabs at a time (threads + 2), each holding
 * its slices (H + 3 planes) and its mesh, and one engine per worker.  A
 * slot's arrays are reserved once at the largest slab's size (address
 * space: only what the slabs write is touched) and kept for the slabs after.
 */
#include "cores.h"
#include "mesh_internal.h"
#include "stream.h"
#include "stream_pool.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

/* Samples a slab should hold at least (its planes' work amortises a piece's
 * set-up) and the layers a slab has at least and at most. */
#define SLAB_SAMPLES ((int64_t)1 << 21)
#define SLAB_MIN 3
#define SLAB_MAX 64
#define TRIANGLE_BATCH 8192 /* triangles made global per sink call (the batch stays in cache) */

typedef enum { EV_VERTICES, EV_TRIANGLES, EV_RETIRE } event_kind;

typedef struct event {
    event_kind kind;
    uint64_t at, count; /* vertices/triangles: first and count; retire: floor in at */
} event;

typedef enum { SLAB_FREE, SLAB_FILLING, SLAB_QUEUED, SLAB_RUNNING, SLAB_DONE } slab_state;

typedef struct slab {
    slab_state state;
    int64_t index, a, b, z_first, z_end; /* owned marched slices, volume slices read */
    char *input;                         /* its volume slices, contiguous [H + 3 planes] */
    isomend_status status;
    isomend_stats stats;
    uint64_t nv, nt, nev, evcap;
    uint64_t nnext;  /* vertices numbered in slice b: the next slab's first */
    float *pos, *nrm;
    uint32_t *tri;   /* local ids, global when replayed */
    uint8_t *org;    /* zero bytes but where written (cleared after the replay) */
    size_t mapped[4]; /* the slot's arrays' reservations (0: heap) */
    event *ev;
    int lead_delivered;            /* the first vertices call went out with the slab below */
} slab;

struct stream_pool {
    isomend_volume desc;   /* with the pool's copy of the slice origins */
    double *slice_origins;
    isomend_options opts;  /* the pieces': one thread, no progress */
    isomend_mesh_sink sink;
    int threads, inflight;
    int64_t H, nslabs, N0, N1, pad;
    size_t plane_bytes;
    slab *slabs;          /* [inflight]: slab s in slabs[s % inflight] */
    pthread_t *workers;
    int started;
    pthread_mutex_t lock;
    pthread_cond_t work, done;
    int64_t *queue;       /* slabs to run, FIFO [inflight] */
    int64_t qhead, qcount;
    int stop;
    int64_t pushed, next_open, next_deliver; /* volume slices pushed; the next slab to open, to hand over */
    uint64_t first_id, next_id, triangles;
    uint64_t *ids; /* [3 * TRIANGLE_BATCH]: a replayed batch's global ids */
    isomend_stats stats;
    isomend_status failed;
};

/* ---------------------------------------------------------------- plan */

/* The layers of a slab of `plane` samples, before the spread. */
static int64_t slab_height(int64_t plane)
{
    const int64_t h = SLAB_SAMPLES / (plane > 0 ? plane : 1);
    return h < SLAB_MIN ? SLAB_MIN : h > SLAB_MAX ? SLAB_MAX : h;
}

int stream_pool_threads(const isomend_options *opts)
{
    return cores_threads(opts ? opts->threads : 0, 64);
}

int stream_pool_plan(const isomend_volume *desc, const isomend_options *opts, int64_t *slab_layers)
{
    const int threads = stream_pool_threads(opts);
    const int pad = opts && (opts->flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    const int64_t N2 = desc->dims[2] + 2 * pad;
    int64_t h = slab_height((desc->dims[0] + 2 * pad) * (desc->dims[1] + 2 * pad));
    /* sixteen slabs a thread, if it can: the slots (threads + 2 slabs) are
     * written on fresh memory, costly on a virtual machine; with four slabs
     * a thread half the slabs paid for it */
    const int64_t spread = N2 / (16 * (int64_t)threads);
    if (h > spread)
        h = spread < SLAB_MIN ? SLAB_MIN : spread;
    *slab_layers = h;
    if (threads < 2 || N2 - 1 < 2 * h) /* fewer than two slabs: the plain stream */
        return 1;
    return threads;
}

uint64_t stream_pool_memory(const isomend_volume *desc, int threads, int pad, uint64_t piece)
{
    /* the tallest slab the plan makes for these slices, whatever dims[2] */
    const uint64_t H = (uint64_t)slab_height((desc->dims[0] + 2 * pad) * (desc->dims[1] + 2 * pad));
    const uint64_t inflight = (uint64_t)threads + 2;
    const uint64_t samples = (uint64_t)desc->dims[0] * (uint64_t)desc->dims[1];
    const uint64_t plane = samples * isomend_type_size(desc->type);
    /* a slab's mesh, as busy as the in-memory rule's surface: a vertex (24
     * bytes) every 8 samples, a triangle (13 bytes) every 4, 7 bytes a sample */
    const uint64_t mesh = samples * H * 7;
    /* and the partly used huge page a slot's arrays of 2 MiB and more end in
     * (output_alloc, reserve_output): less than one for each array, and less than the
     * array (the input; positions, normals, triangles and origins) */
    const uint64_t input = (H + 3) * plane, huge = HUGE_PAGE;
    const uint64_t ends = (input < huge ? input : huge) + (mesh < 4 * huge ? mesh : 4 * huge);
    return sizeof(stream_pool) + (uint64_t)threads * piece + inflight * (input + mesh + ends);
}

/* ----------------------------------------------------------- growth */

static int grow(void **p, uint64_t *cap, uint64_t need, size_t elem)
{
    if (need <= *cap)
        return 1;
    uint64_t c = *cap ? *cap : 1024;
    while (c < need)
        c *= 2;
    void *q = realloc(*p, (size_t)c * elem);
    if (!q)
        return 0;
    *p = q;
    *cap = c;
    return 1;
}

/* ------------------------------------------------- a slab's own sink */

static int add_event(slab *s, event_kind kind, uint64_t at, uint64_t count)
{
    if (kind == EV_TRIANGLES && s->nev && s->ev[s->nev - 1].kind == EV_TRIANGLES) {
        s->ev[s->nev - 1].count += count; /* a layer's batches: one event */
        return 0;
    }
    if (!grow((void **)&s->ev, &s->evcap, s->nev + 1, sizeof(event)))
        return 1;
    s->ev[s->nev++] = (event){kind, at, count};
    return 0;
}

/* What the slab's run would have told a sink (stream_event). */
static int slab_event(void *user, int kind, uint64_t at, uint64_t count)
{
    slab *s = user;
    switch (kind) {
    case STREAM_EV_VERTICES:
        s->nv = at + count;
        return add_event(s, EV_VERTICES, at, count);
    case STREAM_EV_TRIANGLES:
        s->nt = at + count;
        return add_event(s, EV_TRIANGLES, at, count);
    case STREAM_EV_RETIRE:
        return add_event(s, EV_RETIRE, at, 0);
    default:
        s->nnext = count;
        return 0;
    }
}

/* ------------------------------------------------------------ workers */

/* Extracts slab s: a run of the worker's engine (made at its first slab and
 * reused after) on the slab's planes, into the slot's arrays. */
static void run_slab(stream_pool *p, slab *s, stream_one **engine)
{
    isomend_status st = ISOMEND_OK;
    if (!*engine)
        st = stream_direct_begin(&p->desc, &p->opts, engine);
    if (st == ISOMEND_OK) {
        const stream_run run = {.first = s->a,
                                .end = s->b,
                                .out = {s->pos, s->nrm, s->tri, s->org},
                                .event = slab_event,
                                .event_user = s,
                                .planes = s->input,
                                .z0 = s->z_first};
        uint64_t nv, nt;
        st = stream_direct_run(*engine, &run, &s->stats, &nv, &nt);
    }
    pthread_mutex_lock(&p->lock);
    s->status = st;
    s->state = SLAB_DONE;
    pthread_cond_broadcast(&p->done);
    pthread_mutex_unlock(&p->lock);
}

static void *worker_main(void *arg)
{
    stream_pool *p = arg;
    stream_one *engine = NULL;
    pthread_mutex_lock(&p->lock);
    for (;;) {
        while (!p->stop && p->qcount == 0)
            pthread_cond_wait(&p->work, &p->lock);
        if (p->stop)
            break;
        const int64_t index = p->queue[p->qhead];
        p->qhead = (p->qhead + 1) % p->inflight;
        p->qcount--;
        slab *s = &p->slabs[index % p->inflight];
        s->state = SLAB_RUNNING;
        pthread_mutex_unlock(&p->lock);
        run_slab(p, s, &engine);
        pthread_mutex_lock(&p->lock);
    }
    pthread_mutex_unlock(&p->lock);
    stream_one_destroy(engine);
    return NULL;
}

/* --------------------------------------------------------------- delivery */

static isomend_status fail(stream_pool *p, isomend_status st)
{
    if (p->failed == ISOMEND_OK)
        p->failed = st;
    return p->failed;
}

/* Hands the next slab's first vertices call, its first slice's n vertices,
 * to the sink (ids from base). */
static isomend_status deliver_lead(stream_pool *p, slab *next, uint64_t base, uint64_t n)
{
    const event *e = &next->ev[0];
    if (next->nev == 0 || e->kind != EV_VERTICES || e->at != 0 || e->count != n)
        return fail(p, ISOMEND_ERR_INVALID_ARGUMENT); /* not reached */
    next->lead_delivered = 1;
    return p->sink.vertices(p->sink.user, base, (size_t)n, next->pos,
                            next->nrm ? next->nrm : NULL, NULL)
               ? fail(p, ISOMEND_ERR_SINK)
               : ISOMEND_OK;
}

/* Replays slab s's calls (next: slab s + 1, done, or NULL for the last). */
static isomend_status deliver(stream_pool *p, slab *s, slab *next)
{
    if (s->status != ISOMEND_OK)
        return fail(p, s->status);
    const uint64_t base = p->next_id, next_base = base + s->nv;
    /* the last layer's triangles (before the last retire) use the next
     * slab's first vertices, if its first slice has any */
    uint64_t lead_at = UINT64_MAX;
    if (s->nnext) {
        if (!next || next->status != ISOMEND_OK)
            return fail(p, next ? next->status : ISOMEND_ERR_INVALID_ARGUMENT);
        if (s->nev >= 2 && s->ev[s->nev - 1].kind == EV_RETIRE &&
            s->ev[s->nev - 2].kind == EV_TRIANGLES)
            lead_at = s->nev - 2;
    }
    isomend_status st = ISOMEND_OK;
    for (uint64_t q = s->lead_delivered ? 1 : 0; q < s->nev && st == ISOMEND_OK; q++) {
        const event *e = &s->ev[q];
        switch (e->kind) {
        case EV_VERTICES:
            if (p->sink.vertices(p->sink.user, base + e->at, (size_t)e->count,
                                 s->pos + 3 * e->at, s->nrm ? s->nrm + 3 * e->at : NULL, NULL))
                st = fail(p, ISOMEND_ERR_SINK);
            break;
        case EV_TRIANGLES:
            if (q == lead_at) {
                st = deliver_lead(p, next, next_base, s->nnext);
                if (st != ISOMEND_OK)
                    break;
            }
            /* the ids made global a batch at a time: local + base (the last
             * slice's, numbered on from the slab's own, land on the next
             * slab's first vertices) */
            for (uint64_t done = 0; done < e->count && st == ISOMEND_OK;) {
                const uint64_t b = e->count - done < TRIANGLE_BATCH ? e->count - done
                                                                    : TRIANGLE_BATCH;
                const uint32_t *t = s->tri + 3 * (e->at + done);
                uint64_t *ids = p->ids;
                for (uint64_t k = 0; k < 3 * b; k++)
                    ids[k] = base + t[k];
                if (p->sink.triangles(p->sink.user, (size_t)b, ids,
                                      s->org ? s->org + e->at + done : NULL))
                    st = fail(p, ISOMEND_ERR_SINK);
                done += b;
            }
            break;
        case EV_RETIRE:
            if (p->sink.retire(p->sink.user, base + e->at))
                st = fail(p, ISOMEND_ERR_SINK);
            break;
        }
    }
    if (st != ISOMEND_OK)
        return st;
    if (s->org) /* the slot's next slab writes only its quadrilaterals' origins */
        memset(s->org, 0, (size_t)s->nt);
    p->next_id = next_base;
    p->triangles += s->nt;
    uint64_t *sum = (uint64_t *)(void *)&p->stats;
    const uint64_t *add = (const uint64_t *)(const void *)&s->stats;
    for (size_t k = 0; k < sizeof(isomend_stats) / sizeof(uint64_t); k++)
        sum[k] += add[k];
    return ISOMEND_OK;
}

/* The slab in slot of index s, if it holds slab s and is done. */
static slab *done_slab(stream_pool *p, int64_t s)
{
    slab *x = &p->slabs[s % p->inflight];
    return x->index == s && x->state == SLAB_DONE ? x : NULL;
}

/* Delivers the slabs that can go (with `wait`, until slab `until` has gone,
 * waiting for the workers).  The lock is not held. */
static isomend_status deliver_ready(stream_pool *p, int64_t until)
{
    while (p->next_deliver < p->nslabs && p->failed == ISOMEND_OK) {
        const int64_t s = p->next_deliver;
        pthread_mutex_lock(&p->lock);
        slab *x, *next = NULL;
        for (;;) {
            x = done_slab(p, s);
            next = s + 1 < p->nslabs ? done_slab(p, s + 1) : NULL;
            const int ready = x && (x->status != ISOMEND_OK || s + 1 == p->nslabs || next);
            if (ready || s > until)
                break;
            pthread_cond_wait(&p->done, &p->lock);
        }
        pthread_mutex_unlock(&p->lock);
        if (!x || (x->status == ISOMEND_OK && s + 1 < p->nslabs && !next))
            break; /* not ready, and not waited for */
        const isomend_status st = deliver(p, x, next);
        if (st != ISOMEND_OK)
            return st;
        pthread_mutex_lock(&p->lock);
        x->state = SLAB_FREE;
        x->index = -1;
        pthread_mutex_unlock(&p->lock);
        p->next_deliver++;
    }
    return p->failed;
}

/* ------------------------------------------------------------------ API */

isomend_status stream_pool_begin(const isomend_volume *desc, const isomend_options *opts,
                                 const isomend_mesh_sink *sink, int threads, int64_t slab_layers,
                                 stream_pool **out)
{
    *out = NULL;
    stream_pool *p = calloc(1, sizeof *p);
    if (!p)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    p->desc = *desc;
    p->desc.data = NULL;
    memset(p->desc.strides, 0, sizeof p->desc.strides);
    p->opts = *opts;
    p->opts.threads = 1;
    p->opts.progress = NULL;
    p->opts.progress_user = NULL;
    p->sink = *sink;
    p->threads = threads;
    p->inflight = threads + 2;
    p->H = slab_layers;
    p->pad = (opts->flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    p->N0 = desc->dims[0] + 2 * p->pad;
    p->N1 = desc->dims[1] + 2 * p->pad;
    const int64_t N2 = desc->dims[2] + 2 * p->pad;
    p->nslabs = (N2 - 1 + p->H - 1) / p->H; /* slabs own layers 0 .. N2 - 2; the last also slice N2 - 1 */
    p->plane_bytes = (size_t)desc->dims[0] * (size_t)desc->dims[1] * isomend_type_size(desc->type);
    isomend_status st = ISOMEND_OK;
    if (desc->slice_origins) {
        const size_t size = 3 * sizeof(double) * (size_t)desc->dims[2];
        if ((p->slice_origins = malloc(size)))
            memcpy(p->slice_origins, desc->slice_origins, size);
        p->desc.slice_origins = p->slice_origins;
    }
    p->slabs = calloc((size_t)p->inflight, sizeof(slab));
    p->queue = calloc((size_t)p->inflight, sizeof(int64_t));
    p->workers = calloc((size_t)threads, sizeof(pthread_t));
    p->ids = malloc(3 * sizeof(uint64_t) * TRIANGLE_BATCH);
    if (!p->slabs || !p->queue || !p->workers || !p->ids ||
        (desc->slice_origins && !p->slice_origins))
        st = ISOMEND_ERR_OUT_OF_MEMORY;
    /* a slot's arrays: the largest slab's mesh (H layers, H + 1 slices) */
    uint64_t sv, lt;
    stream_run_bounds(&p->desc, &p->opts, &sv, &lt);
    const int small = (opts->flags & ISOMEND_FLAG_SMALL_PAGES) != 0;
    const uint64_t vmax = sv * (uint64_t)(p->H + 1), tmax = lt * (uint64_t)p->H;
    const int normals = !(opts->flags & ISOMEND_FLAG_NO_NORMALS);
    const int origins = !(opts->flags & ISOMEND_FLAG_NO_ORIGINS);
    if (!sv || vmax > SIZE_MAX / 32 || tmax > SIZE_MAX / 32)
        st = ISOMEND_ERR_OUT_OF_MEMORY;
    for (int k = 0; k < p->inflight && st == ISOMEND_OK; k++) {
        slab *x = &p->slabs[k];
        x->index = -1;
        if (!(x->input = output_alloc(p->plane_bytes * (size_t)(p->H + 3), small)))
            st = ISOMEND_ERR_OUT_OF_MEMORY;
        const size_t size[4] = {12 * (size_t)vmax, normals ? 12 * (size_t)vmax : 0,
                                12 * (size_t)tmax, origins ? (size_t)tmax : 0};
        void **arr[4] = {(void **)&x->pos, (void **)&x->nrm, (void **)&x->tri, (void **)&x->org};
        for (int q = 0; q < 4 && st == ISOMEND_OK; q++) {
            if (!size[q])
                continue;
            /* reserved (the origins on huge pages from 2 MiB on), or when
             * refused from the heap, zeroed (the origins must be) */
            *arr[q] = reserve_output(size[q], small ? SIZE_MAX : q == 3 ? HUGE_PAGE : 0);
            x->mapped[q] = *arr[q] ? huge_round(size[q]) : 0;
            if (!*arr[q] && !(*arr[q] = calloc(1, size[q])))
                st = ISOMEND_ERR_OUT_OF_MEMORY;
        }
    }
    if (st == ISOMEND_OK) {
        pthread_mutex_init(&p->lock, NULL);
        pthread_cond_init(&p->work, NULL);
        pthread_cond_init(&p->done, NULL);
        p->started = -1; /* the lock and conditions exist */
        for (int t = 0; t < threads && st == ISOMEND_OK; t++) {
            if (pthread_create(&p->workers[t], NULL, worker_main, p) != 0)
                st = ISOMEND_ERR_OUT_OF_MEMORY;
            else
                p->started = t + 1;
        }
    }
    if (st != ISOMEND_OK) {
        stream_pool_destroy(p);
        return st;
    }
    *out = p;
    return ISOMEND_OK;
}

void stream_pool_set_first_id(stream_pool *p, uint64_t first)
{
    if (p && p->pushed == 0)
        p->first_id = p->next_id = first;
}

/* Slab s's owned marched slices [a, b) and the volume slices it reads [first, end). */
static void slab_range(const stream_pool *p, int64_t s, int64_t *a, int64_t *b, int64_t *first,
                       int64_t *end)
{
    const int64_t N2 = p->desc.dims[2] + 2 * p->pad;
    *a = s * p->H;
    *b = *a + p->H < N2 - 1 ? *a + p->H : N2;
    const int64_t lo = *a - 1 - p->pad, hi = *b + 2 - p->pad;
    *first = lo < 0 ? 0 : lo;
    *end = hi > p->desc.dims[2] ? p->desc.dims[2] : hi;
}

/* Opens slab s in its slot (which must be free: the caller delivered). */
static void open_slab(stream_pool *p, int64_t s)
{
    slab *x = &p->slabs[s % p->inflight];
    x->state = SLAB_FILLING;
    x->index = s;
    slab_range(p, s, &x->a, &x->b, &x->z_first, &x->z_end);
    x->status = ISOMEND_OK;
    memset(&x->stats, 0, sizeof x->stats);
    x->nv = x->nt = x->nev = x->nnext = 0;
    x->lead_delivered = 0;
}

isomend_status stream_pool_push(stream_pool *p, const void *slice)
{
    if (p->failed != ISOMEND_OK)
        return p->failed;
    const int64_t z = p->pushed;
    if (z >= p->desc.dims[2])
        return fail(p, ISOMEND_ERR_SLICE_COUNT);
    /* the slabs whose halo holds z */
    int64_t s0 = (z + p->pad - 2) / p->H - 1;
    if (s0 < 0)
        s0 = 0;
    while (p->next_open < p->nslabs) {
        const int64_t s = p->next_open, lo = s * p->H - 1 - p->pad;
        if (z < (lo < 0 ? 0 : lo))
            break;
        /* Its slot's previous slab must have gone to the sink, which waits for
         * the slab after that one.  While slab s - 1 still holds z, slab s
         * waits for its slot instead of the caller: s - 1 is completed and
         * queued first (waiting here, the workers idled for a replay and the
         * last slices of s - 1 at each slab), and s takes the slices it
         * shares with s - 1 from s - 1's input when it opens (s - 1 stays in
         * its slot until s is done). */
        const slab *prev = s > 0 ? &p->slabs[(s - 1) % p->inflight] : NULL;
        int64_t a, b, first, end;
        slab_range(p, s, &a, &b, &first, &end);
        const int must = !prev || z >= prev->z_end || z == end - 1;
        if (p->slabs[s % p->inflight].index != -1) {
            if (!must)
                break;
            const isomend_status st = deliver_ready(p, s - p->inflight);
            if (st != ISOMEND_OK)
                return st;
            if (p->slabs[s % p->inflight].index != -1)
                return fail(p, ISOMEND_ERR_INVALID_ARGUMENT); /* not reached */
        }
        open_slab(p, s);
        p->next_open++;
        slab *x = &p->slabs[s % p->inflight];
        for (int64_t k = x->z_first; k < z; k++) /* the slices pushed while it waited */
            memcpy(x->input + (size_t)(k - x->z_first) * p->plane_bytes,
                   prev->input + (size_t)(k - prev->z_first) * p->plane_bytes, p->plane_bytes);
    }
    int64_t attach[4];
    int na = 0;
    for (int64_t s = s0; s < p->next_open && na < 4; s++) {
        const slab *x = &p->slabs[s % p->inflight];
        if (x->index == s && z >= x->z_first && z < x->z_end)
            attach[na++] = s; /* open and filling: queued only at its last slice */
    }
    pthread_mutex_lock(&p->lock); /* (open slabs are the caller's until queued) */
    for (int k = 0; k < na; k++) {
        slab *x = &p->slabs[attach[k] % p->inflight];
        memcpy(x->input + (size_t)(z - x->z_first) * p->plane_bytes, slice, p->plane_bytes);
        if (z == x->z_end - 1) {
            x->state = SLAB_QUEUED;
            p->queue[(p->qhead + p->qcount) % p->inflight] = x->index;
            p->qcount++;
            pthread_cond_signal(&p->work);
        }
    }
    pthread_mutex_unlock(&p->lock);
    p->pushed = z + 1;
    return deliver_ready(p, -1); /* what is ready, without waiting */
}

isomend_status stream_pool_finish(stream_pool *p, isomend_stats *stats)
{
    if (p->failed != ISOMEND_OK)
        return p->failed;
    if (p->pushed != p->desc.dims[2])
        return fail(p, ISOMEND_ERR_SLICE_COUNT);
    const isomend_status st = deliver_ready(p, p->nslabs);
    if (st != ISOMEND_OK)
        return st;
    if (stats) {
        *stats = p->stats;
        stats->vertices = p->next_id - p->first_id;
        stats->triangles = p->triangles;
    }
    return ISOMEND_OK;
}

void stream_pool_destroy(stream_pool *p)
{
    if (!p)
        return;
    if (p->started) {
        pthread_mutex_lock(&p->lock);
        p->stop = 1;
        pthread_cond_broadcast(&p->work);
        pthread_mutex_unlock(&p->lock);
        for (int t = 0; t < p->started; t++)
            pthread_join(p->workers[t], NULL);
        pthread_mutex_destroy(&p->lock);
        pthread_cond_destroy(&p->work);
        pthread_cond_destroy(&p->done);
    }
    for (int k = 0; p->slabs && k < p->inflight; k++) {
        slab *x = &p->slabs[k];
        free(x->input);
        void *arr[4] = {x->pos, x->nrm, x->tri, x->org};
        for (int q = 0; q < 4; q++)
            if (arr[q])
                release_output(arr[q], x->mapped[q]);
        free(x->ev);
    }
    free(p->slabs);
    free(p->queue);
    free(p->workers);
    free(p->ids);
    free(p->slice_origins);
    free(p);
}
