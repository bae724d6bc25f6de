/*
 * slabs.c - isomend_extract(): a volume in memory extracted by runs of
 * slices on threads, each run the one engine of stream.c (read in place,
 * written in place), joined into one mesh in isomend_extract()'s order.
 *
 *   caller (the head)                 other threads (staged runs)
 *   slices 0, 1, 2, ... claimed one   runs of up to 64 layers taken from the
 *   at a time, written straight into  top down, each numbered from 0 in the
 *   the mesh's arrays with the final  thread's own region, its last slice
 *   ids, until it meets the lowest    (the run above's first, in the same
 *   run taken                         order) numbered on from its own
 *                  \                  /
 *                   moves: every staged run, in slice order, after the head's
 *                   part (vertices copied, ids + the run's base: its last
 *                   slice's land on the run above's), on all the threads
 *
 * The two parts meet wherever the threads' speeds make them meet, so a
 * thread on a slower virtual CPU takes a smaller share.  The head writes
 * its part once; a staged run's part is written twice (its region, then the
 * mesh).  On a dense mesh and two threads, the other thread counts instead
 * (the counted split): the head's vertices and triangles, slice by slice
 * from the bottom (a fraction of a run's work), until it has counted up to
 * a slice that halves what is left, and then runs from there to the top,
 * straight into the mesh (docs/core-internals.md, "The one engine").  A run's
 * slices are numbered and computed as the stream numbers them, so the mesh
 * is the same bytes, vertex order included, for any number of threads and
 * any meeting point.
 *
 * The output arrays are address-space reservations of the largest mesh the
 * grid can give (mesh_memory.c), trimmed at the end.  A small grid, or one
 * whose reservations the system refuses, takes counted runs instead
 * (counted_runs.c: counted first, into arrays of the mesh's size).
 */
#define _POSIX_C_SOURCE 200809L /* clock_gettime */
#include "context.h"
#include "cores.h"
#include "extract.h"
#include "methods.h"
#include "slice_geometry.h"
#include "stream.h"
#include "tables.h"
#include "runs_job.h"
#include "counted_runs.h"

#include <pthread.h>
#include <stdlib.h>
#include <time.h>

/* Samples from which the runs go into reservations, other threads taking
 * staged runs (below, counted runs: a thread's start and a region's huge
 * pages cost a small grid more than the work they take, a 64^3 sphere 1.9x
 * the head's time alone), and from which more than one thread takes part
 * (in counted runs, or the counted split of a dense mesh). */
#define STAGED_SAMPLES ((uint64_t)1 << 20)
#define COUNTED_SAMPLES ((uint64_t)1 << 16)
/* Layers of a staged run: a share of what is left, within these. */
#define RUN_MIN 2
#define RUN_MAX 64
/* The head reports progress every PROGRESS_SLICES slices. */
#define PROGRESS_SLICES 16
/* Vertices a sample from which two threads take the counted split, for
 * samples of one byte; times the sample's size (a larger sample: counting
 * reads more). */
#define COUNTED_DENSITY 0.02

static void arrays_release(arrays *a)
{
    void *p[4] = {a->out.pos, a->out.nrm, a->out.tri, a->out.org};
    for (int q = 0; q < 4; q++)
        if (p[q])
            release_output(p[q], a->mapped[q]);
    memset(a, 0, sizeof *a);
}

/* Reserves room for vmax vertices and tmax triangles (normals and origins
 * as the context wants them); 0 when refused (nothing kept). */
static int arrays_reserve(arrays *a, const ctx *c, uint64_t vmax, uint64_t tmax)
{
    memset(a, 0, sizeof *a);
    const size_t size[4] = {sizeof(float) * 3 * (size_t)vmax,
                            c->want_normals ? sizeof(float) * 3 * (size_t)vmax : 0,
                            sizeof(uint32_t) * 3 * (size_t)tmax,
                            c->want_origins ? (size_t)tmax : 0};
    void *p[4] = {NULL, NULL, NULL, NULL};
    for (int q = 0; q < 4; q++) {
        if (!size[q])
            continue;
        /* The origins (a byte a triangle) are often under 2 MiB: huge pages
         * from there on only, or a huge page would hold ~2 MiB of nothing.
         * (The other arrays on small pages below 2 MiB: 1.3x the time of a
         * 64^3 sphere, faults instead of one zeroed huge page.) */
        size_t huge_from = q == 3 ? HUGE_PAGE : 0;
        if (c->small_pages)
            huge_from = SIZE_MAX;
        p[q] = reserve_output(size[q], huge_from);
        if (!p[q]) {
            for (int r = 0; r < q; r++)
                if (p[r])
                    release_output(p[r], a->mapped[r]);
            memset(a, 0, sizeof *a);
            return 0;
        }
        a->mapped[q] = huge_round(size[q]);
    }
    a->out = (stream_out){p[0], p[1], p[2], p[3]};
    return 1;
}

/* The most vertices a slice and the layer below it can have: an edge or
 * diagonal per id-map plane and sample, and the general methods' private
 * slots. */
static uint64_t layer_vertex_bound(const ctx *c)
{
    const uint64_t per_sample =
        (uint64_t)c->id_planes + (c->general ? METHODS_SLOT_COUNT - METHODS_SLOT_CENTRE : 0);
    return per_sample * (uint64_t)c->g.N[0] * (uint64_t)c->g.N[1];
}

/* The largest counts a grid allows: vertices (at most 3 a sample, one slice
 * past 2^32 - 1 before the check), triangles (the table's, and two for each
 * of a cube's +x, +y, +z faces; the general methods' per cube). */
static void grid_bounds(const ctx *c, uint64_t *vmax, uint64_t *tmax)
{
    const grid *g = &c->g;
    const uint64_t N0 = (uint64_t)g->N[0], N1 = (uint64_t)g->N[1], N2 = (uint64_t)g->N[2];
    const uint64_t cubes = (N0 - 1) * (N1 - 1) * (N2 - 1);
    const uint64_t v = layer_vertex_bound(c) * N2;
    const uint64_t cap = (uint64_t)UINT32_MAX + 1 + layer_vertex_bound(c);
    *vmax = v > cap ? cap : v;
    *tmax = (c->general ? (uint64_t)METHODS_MAX_TRI : (uint64_t)MC_MAX_TRI + 6) * cubes;
}

/* ------------------------------------------------------- the schedule */

/* The head's tick: claims slice m unless a staged run has it; progress. */
static int head_tick(void *user, int64_t m)
{
    thread_state *t = user;
    plan *p = t->p;
    pthread_mutex_lock(&p->mu);
    const int mine = m < p->lowest && !(p->head_yield_at && m >= p->head_yield_at);
    if (mine)
        p->claimed = m + 1;
    pthread_mutex_unlock(&p->mu);
    if (!mine)
        return 0;
    const ctx *c = p->c;
    if (atomic_load(&p->cancel))
        return -1;
    if (c->progress && m - p->head_reported >= PROGRESS_SLICES) {
        p->head_reported = m;
        const double done = (double)m + (double)atomic_load(&p->layers_staged);
        if (c->progress(c->progress_user, done / (double)p->N2)) {
            atomic_store(&p->cancel, 1);
            return -1;
        }
    }
    return 1;
}

/* A staged thread: runs taken from the top down until they meet the head. */
static void take_runs(thread_state *t)
{
    plan *p = t->p;
    for (;;) {
        pthread_mutex_lock(&p->mu);
        const int64_t end = p->lowest;
        /* guided: a share of what is left between the head and here, at
         * most H layers, so that runs are long (each reads two slices more
         * than its own) but the last ones short (the head may wait for one) */
        int64_t h = (end - p->claimed) / (2 * p->threads);
        h = h < p->H_min ? p->H_min : h > p->H ? p->H : h;
        int64_t first = end - h;
        if (first < p->claimed)
            first = p->claimed;
        int go = first < end && !atomic_load(&p->cancel) && t->status == ISOMEND_OK;
        if (go && t->v_used + (uint64_t)(end - first + 1) * p->layer_vmax > p->vcap) {
            t->status = ISOMEND_ERR_TOO_LARGE; /* the region is full: the mesh would be */
            atomic_store(&p->cancel, 1);
            go = 0;
        }
        int64_t r = -1;
        if (go) {
            p->lowest = first;
            r = p->nruns++;
            p->runs[r] = (staged){first, end, t->index, t->v_used, 0, t->t_used, 0, 0, 0};
        }
        pthread_mutex_unlock(&p->mu);
        if (!go)
            return;
        staged *run = &p->runs[r]; /* its slot: written by this thread only */
        const stream_out *o = &t->region.out;
        const stream_run sr = {.first = first,
                               .end = end,
                               .out = {o->pos + 3 * t->v_used,
                                       o->nrm ? o->nrm + 3 * t->v_used : NULL,
                                       o->tri + 3 * t->t_used, o->org ? o->org + t->t_used : NULL},
                               .tick = cancel_tick,
                               .tick_user = t};
        if (!thread_run(t, &sr, &run->nv, &run->nt))
            return;
        t->v_used += run->nv;
        t->t_used += run->nt;
        atomic_fetch_add(&p->layers_staged, end - first);
    }
}

/* Moves n origins, where the destination reads as zero bytes (a fresh
 * reservation) as does most of the source (the table's triangles): only the
 * other bytes are written, so that the destination's pages are not all
 * touched. */
static void move_origins(uint8_t *d, const uint8_t *s, uint64_t n)
{
    size_t q = 0;
    for (; q + 8 <= n; q += 8) {
        uint64_t w;
        memcpy(&w, s + q, sizeof w);
        if (w)
            for (size_t b = 0; b < 8; b++)
                if (s[q + b])
                    d[q + b] = s[q + b];
    }
    for (; q < n; q++)
        if (s[q])
            d[q] = s[q];
}

/* Releases the whole pages of a region's array from byte *done up to byte
 * `to` (rounded down): the part its moves have read, as they go, so that
 * the moved part is not held twice. */
static void release_read(void *array, size_t *done, size_t to)
{
    to &= ~(HUGE_PAGE - 1);
    if (array && to > *done) {
        release_pages((char *)array + *done, to - *done);
        *done = to;
    }
}

/* The moves of one region (thread k's staged runs, in its order: the order
 * taken), of its vertices (kind 0) or its triangles and origins (kind 1):
 * each run's part copied to its place in the mesh, the triangles' ids plus
 * the run's base (the ids of its last slice, numbered on from its own
 * vertices, then land on the run above's first). */
static void move_region(plan *p, const thread_state *ts, int k, int kind)
{
    const stream_out *src = &ts[k].region.out, *dst = &p->mesh.out;
    size_t done[2] = {0, 0};
    for (int64_t r = 0; r < p->nruns; r++) {
        const staged *run = &p->runs[r];
        if (run->thread != k)
            continue;
        if (kind == 0) {
            const size_t bytes = 12 * (size_t)run->nv, at = 12 * (size_t)run->v_at;
            memcpy(dst->pos + 3 * run->v_base, src->pos + 3 * run->v_at, bytes);
            release_read(src->pos, &done[0], at + bytes);
            if (src->nrm) {
                memcpy(dst->nrm + 3 * run->v_base, src->nrm + 3 * run->v_at, bytes);
                release_read(src->nrm, &done[1], at + bytes);
            }
            continue;
        }
        const uint32_t *s = src->tri + 3 * run->t_at;
        uint32_t *d = dst->tri + 3 * run->t_base;
        const uint32_t base = (uint32_t)run->v_base;
        for (uint64_t q = 0; q < 3 * run->nt; q++)
            d[q] = s[q] + base;
        release_read(src->tri, &done[0], 12 * (size_t)(run->t_at + run->nt));
        if (src->org)
            move_origins(dst->org + run->t_base, src->org + run->t_at, run->nt);
    }
}

/* The moves, a region's vertices or triangles a task, shared by the
 * threads (tasks 2 (k - 1) + kind for staged thread k). */
static void take_moves(plan *p, const thread_state *ts)
{
    for (;;) {
        const long long task = atomic_fetch_add(&p->next_move, 1);
        if (task >= 2 * (long long)(p->threads - 1))
            return;
        move_region(p, ts, (int)(task / 2) + 1, (int)(task % 2));
    }
}

/* The counted split (thread 1 of two): counts the head's slices and layers
 * from the bottom until it has counted up to a slice s the head has not
 * claimed with about as far for the head to go to it as from it to the top,
 * and runs [s, N2) into the mesh from the counts; none when the head is
 * ahead. */
static void count_split(thread_state *t)
{
    plan *p = t->p;
    const int64_t layers = p->N2 - 1;
    uint64_t v = 0, tr = 0;
    int64_t at = -1;
    for (int64_t k = 0; k + 1 < layers && at < 0 && !atomic_load(&p->cancel); k++) {
        uint64_t n;
        v += stream_direct_count(t->s, k, 1, &n);
        tr += n;
        const int64_t s = k + 1;
        pthread_mutex_lock(&p->mu);
        if (s >= p->claimed && 2 * s >= layers + p->claimed && v <= UINT32_MAX)
            p->lowest = at = s;
        pthread_mutex_unlock(&p->mu);
    }
    if (at < 0)
        return;
    const stream_out *o = &p->mesh.out;
    const stream_run sr = {.first = at,
                           .end = p->N2,
                           .first_id = v,
                           .out = {o->pos, o->nrm, o->tri + 3 * tr, o->org ? o->org + tr : NULL},
                           .tick = cancel_tick,
                           .tick_user = t};
    if (!thread_run(t, &sr, &p->counted_nv, &p->counted_nt))
        return;
    p->counted_at = at;
    p->counted_v = v;
    p->counted_t = tr;
    atomic_fetch_add(&p->layers_staged, layers - at);
}

static void *staged_thread(void *arg)
{
    thread_state *t = arg;
    plan *p = t->p;
    if (p->counted)
        count_split(t);
    else
        take_runs(t);
    pthread_mutex_lock(&p->mu);
    p->staging--;
    pthread_cond_broadcast(&p->cv);
    while (!p->moves_ready)
        pthread_cond_wait(&p->cv, &p->mu);
    pthread_mutex_unlock(&p->mu);
    if (p->moves_ready > 0)
        take_moves(p, t - t->index);
    return NULL;
}

/* The layers of a staged run on `threads` threads (0: no staged runs). */
static int64_t run_layers(const ctx *c, int threads)
{
    const grid *g = &c->g;
    const int64_t layers = g->N[2] - 1;
    if (threads < 2 || layers < 2)
        return 0;
    const uint64_t samples = (uint64_t)g->N[0] * (uint64_t)g->N[1] * (uint64_t)g->N[2];
    if (c->schedule == SCHEDULE_THIN || c->schedule == SCHEDULE_STAGED)
        return 1;
    if (samples < STAGED_SAMPLES && c->schedule == SCHEDULE_AUTO)
        return 0;
    int64_t h = RUN_MAX;
    /* a run's ids, its last slice's too, stay within 32 bits */
    const int64_t hmax = (int64_t)(UINT32_MAX / layer_vertex_bound(c)) - 1;
    if (hmax < 1)
        return 0;
    return h < hmax ? h : hmax;
}

/* Whether the mesh is dense (COUNTED_DENSITY) in four slices sampled by s. */
static int dense_mesh(const ctx *c, stream_one *s)
{
    const grid *g = &c->g;
    const int64_t N2 = g->N[2];
    uint64_t sampled = 0, n;
    for (int64_t q = 0; q < 4; q++)
        sampled += stream_direct_count(s, (2 * q + 1) * N2 / 8, 0, &n);
    const double density = COUNTED_DENSITY * (double)isomend_type_size(g->type);
    return (double)sampled > density * 4.0 * (double)(g->N[0] * g->N[1]);
}

/* Whether two threads take the counted split: table methods, two threads
 * (or more, on a grid too small for staged runs: H 0), and a mesh dense in
 * four sampled slices (counted by the head's engine, s). */
static int counted_split(const ctx *c, stream_one *s, int nthreads, int64_t H)
{
    const grid *g = &c->g;
    const int64_t N2 = g->N[2];
    if (nthreads < 2 || c->general || N2 < 8)
        return 0;
    if (c->schedule == SCHEDULE_COUNTED)
        return 1;
    if (c->schedule != SCHEDULE_AUTO || (nthreads > 2 && H > 0) ||
        (uint64_t)g->N[0] * (uint64_t)g->N[1] * (uint64_t)N2 < COUNTED_SAMPLES)
        return 0;
    return dense_mesh(c, s);
}

/*
 * The runs on `nthreads` threads into p->mesh: on success *nv, *nt the
 * mesh's counts and *stats the runs' statistics (cubes, vertices and
 * triangles not set).
 */
static isomend_status run_slabs(plan *p, int nthreads, uint64_t *nv, uint64_t *nt,
                                isomend_stats *stats)
{
    ctx *c = p->c;
    const int64_t N2 = c->g.N[2];
    thread_state ts[64];
    memset(ts, 0, sizeof ts);
    p->N2 = N2;
    p->claimed = 1;
    p->lowest = N2;
    p->H = run_layers(c, nthreads);
    p->H_min = p->H < RUN_MIN ? p->H : RUN_MIN;
    p->counted_at = -1;
    isomend_status status = ISOMEND_OK;
    p->layer_vmax = layer_vertex_bound(c);
    int nt_threads = 1;
    for (int t = 0; t < nthreads; t++) {
        ts[t].p = p;
        ts[t].index = t;
        status = stream_direct_begin(p->vol, p->opts, &ts[t].s);
        if (status != ISOMEND_OK)
            break;
        if (t == 0) {
            p->counted = counted_split(c, ts[0].s, nthreads, p->H);
            if (p->counted)
                nthreads = 2;
            else if (!p->H)
                nthreads = 1;
        }
        /* a staged thread's region: what the whole grid may give, address
         * space only; refused, the threads that have one do the staging */
        if (t > 0 && !p->counted && !arrays_reserve(&ts[t].region, c, p->vcap, p->tcap)) {
            stream_one_destroy(ts[t].s);
            ts[t].s = NULL;
            break;
        }
        nt_threads = t + 1;
    }
    if (status != ISOMEND_OK) {
        for (int t = 0; t < nthreads; t++) {
            stream_one_destroy(ts[t].s);
            arrays_release(&ts[t].region);
        }
        return status;
    }
    nthreads = nt_threads;
    p->threads = nthreads;
    pthread_t tid[64];
    int started = 1;
    p->runs = nthreads > 1 ? calloc((size_t)N2, sizeof(staged)) : NULL;
    if (nthreads > 1 && !p->runs)
        nthreads = 1;
    p->staging = nthreads - 1;
    for (int t = 1; t < nthreads; t++) {
        if (pthread_create(&tid[t], NULL, staged_thread, &ts[t]) != 0) {
            pthread_mutex_lock(&p->mu);
            p->staging -= nthreads - t; /* these never start */
            pthread_mutex_unlock(&p->mu);
            break;
        }
        started = t + 1;
    }
    /* tests: the head leaves all but layer 0 to the staged runs */
    p->head_yield_at = c->schedule == SCHEDULE_STAGED && started > 1 ? 1 : 0;

    /* the head, on this thread */
    uint64_t head_nv = 0, head_nt = 0;
    const stream_run head = {
        .first = 0, .end = N2, .out = p->mesh.out, .tick = head_tick, .tick_user = &ts[0]};
    status = stream_direct_run(ts[0].s, &head, &ts[0].stats, &head_nv, &head_nt);
    if (status != ISOMEND_OK)
        atomic_store(&p->cancel, 1);

    /* the staged runs done (progress reported now, whatever the threads'
     * order, then every 100 ms while they run): their bases, in slice order
     * (taken downwards) */
    pthread_mutex_lock(&p->mu);
    for (int first = 1; first || p->staging > 0; first = 0) {
        if (!c->progress || status != ISOMEND_OK) {
            if (p->staging > 0)
                pthread_cond_wait(&p->cv, &p->mu);
            continue;
        }
        if (!first) {
            struct timespec until;
            clock_gettime(CLOCK_REALTIME, &until);
            until.tv_nsec += 100 * 1000 * 1000;
            if (until.tv_nsec >= 1000 * 1000 * 1000) {
                until.tv_sec++;
                until.tv_nsec -= 1000 * 1000 * 1000;
            }
            pthread_cond_timedwait(&p->cv, &p->mu, &until);
        }
        const double done = (double)p->claimed + (double)atomic_load(&p->layers_staged);
        pthread_mutex_unlock(&p->mu);
        if (c->progress(c->progress_user, done / (double)N2)) {
            status = ISOMEND_ERR_CANCELLED;
            atomic_store(&p->cancel, 1);
        }
        pthread_mutex_lock(&p->mu);
    }
    uint64_t v = head_nv, t = head_nt;
    if (status == ISOMEND_OK && p->counted_at >= 0) { /* the counted split's run follows */
        if (p->counted_v != head_nv || p->counted_t != head_nt)
            status = ISOMEND_ERR_INVALID_ARGUMENT; /* not reached: the counts are the head's */
        v += p->counted_nv;
        t += p->counted_nt;
    }
    for (int k = 1; k < started; k++) /* a staged run's failure, not the head's stop */
        if (ts[k].status != ISOMEND_OK && ts[k].status != ISOMEND_ERR_CANCELLED)
            status = ts[k].status;
    for (int k = 1; k < started && status == ISOMEND_OK; k++)
        if (ts[k].status != ISOMEND_OK)
            status = ts[k].status;
    for (int64_t r = p->nruns - 1; r >= 0 && status == ISOMEND_OK; r--) {
        p->runs[r].v_base = v;
        p->runs[r].t_base = t;
        v += p->runs[r].nv;
        t += p->runs[r].nt;
    }
    if (status == ISOMEND_OK && v > UINT32_MAX)
        status = ISOMEND_ERR_TOO_LARGE;
    p->moves_ready = status == ISOMEND_OK ? 1 : -1;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    if (status == ISOMEND_OK)
        take_moves(p, ts);
    for (int k = 1; k < started; k++)
        pthread_join(tid[k], NULL);

    memset(stats, 0, sizeof *stats);
    for (int k = 0; k < nthreads; k++) {
        stats_add(stats, &ts[k].stats);
        stream_one_destroy(ts[k].s);
        arrays_release(&ts[k].region);
    }
    free(p->runs);
    p->runs = NULL;
    if (status == ISOMEND_OK && atomic_load(&p->cancel))
        status = ISOMEND_ERR_CANCELLED;
    *nv = v;
    *nt = t;
    return status;
}

/* ------------------------------------------------------- the extraction */

/* isomend_extract, recycling *recycled (taken, and set to NULL, once the
 * extraction has begun; the caller destroys it otherwise). */
static isomend_status extract(const isomend_volume *vol, const isomend_options *opts,
                              isomend_mesh **out_mesh, isomend_stats *stats,
                              isomend_mesh **recycled)
{
    if (!out_mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out_mesh = NULL;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const isomend_options *o = opts ? opts : &defaults;
    if (!vol || !vol->data)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    plan *p = calloc(1, sizeof(*p));
    ctx *c = calloc(1, sizeof(*c));
    if (!p || !c) {
        free(p);
        free(c);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    isomend_status status = ctx_setup(c, vol, o);
    isomend_mesh *old = NULL, *mesh = NULL;
    if (status != ISOMEND_OK)
        goto done;
    old = *recycled; /* this call's now: used or destroyed */
    *recycled = NULL;
    p->c = c;
    p->vol = vol;
    p->opts = o;
    atomic_init(&p->next_move, 0);
    atomic_init(&p->layers_staged, 0);
    atomic_init(&p->cancel, 0);
    status = ISOMEND_ERR_THREAD;
    if (pthread_mutex_init(&p->mu, NULL) != 0)
        goto done;
    if (pthread_cond_init(&p->cv, NULL) != 0) {
        pthread_mutex_destroy(&p->mu);
        goto done;
    }
    status = ISOMEND_ERR_OUT_OF_MEMORY;
    if (!(mesh = calloc(1, sizeof(*mesh))))
        goto unlock;

    const grid *g = &c->g;
    uint64_t vmax, tmax, nv = 0, nt = 0;
    grid_bounds(c, &vmax, &tmax);
    p->vcap = vmax; /* a staged thread's region holds as much */
    p->tcap = tmax;
    isomend_stats st;
    int nthreads = cores_threads(o->threads, 64);
    const uint64_t samples = (uint64_t)g->N[0] * (uint64_t)g->N[1] * (uint64_t)g->N[2];
    int small = samples < STAGED_SAMPLES && c->schedule == SCHEDULE_AUTO;
    if (small && nthreads == 1 && samples >= COUNTED_SAMPLES && g->N[2] >= 8) {
        /* one thread: counted runs read the grid twice, which costs a dense
         * mesh more than the reservation's pages (a 64^3 gyroid 1.07x, a
         * sphere 0.89x) */
        stream_one *probe = NULL;
        if (stream_direct_begin(vol, o, &probe) == ISOMEND_OK && dense_mesh(c, probe))
            small = 0;
        stream_one_destroy(probe);
    }
    if (small || vmax > SIZE_MAX / 32 || tmax > SIZE_MAX / 32 ||
        !arrays_reserve(&p->mesh, c, vmax, tmax)) {
        if (samples < COUNTED_SAMPLES) /* a thread's start would cost more */
            nthreads = 1;
        isomend_mesh_destroy(old); /* before the new arrays are allocated */
        old = NULL;
        status = counted_runs(p, nthreads, mesh, &nv, &nt, &st);
    } else {
        /* The recycled mesh's positions, normals and triangles become the
         * start of the new ones.  Not its origins: the runs leave the table's
         * origins as zero bytes and untouched pages cost nothing; zeroing
         * recycled ones would touch what the new mesh may never write. */
        if (old) {
            void **from[3] = {(void **)&old->pos, (void **)&old->nrm, (void **)&old->tri};
            void *into[3] = {p->mesh.out.pos, p->mesh.out.nrm, p->mesh.out.tri};
            for (int q = 0; q < 3; q++) {
                if (!into[q] || !old->mapped[q])
                    continue;
                adopt_output(into[q], p->mesh.mapped[q], *from[q], old->mapped[q]);
                *from[q] = NULL;
                old->mapped[q] = 0;
            }
            isomend_mesh_destroy(old); /* what is left: arrays the new mesh does not have */
            old = NULL;
        }
        mesh->pos = p->mesh.out.pos;
        mesh->nrm = p->mesh.out.nrm;
        mesh->tri = p->mesh.out.tri;
        mesh->org = p->mesh.out.org;
        memcpy(mesh->mapped, p->mesh.mapped, sizeof mesh->mapped); /* the mesh's now */
        status = run_slabs(p, nthreads, &nv, &nt, &st);
        if (status == ISOMEND_OK) {
            mesh->nv = (size_t)nv;
            mesh->nt = (size_t)nt;
            const size_t used[4] = {sizeof(float) * 3 * mesh->nv, sizeof(float) * 3 * mesh->nv,
                                    sizeof(uint32_t) * 3 * mesh->nt, mesh->nt};
            void *arr[4] = {mesh->pos, mesh->nrm, mesh->tri, mesh->org};
            for (int q = 0; q < 4; q++)
                if (arr[q])
                    mesh->mapped[q] = trim_output(arr[q], mesh->mapped[q], used[q]);
        }
    }
    if (status != ISOMEND_OK)
        goto unlock;

    for (int a = 0; a < 3; a++) {
        mesh->box[a] = g->o[a];
        mesh->box[3 + a] = g->o[a] + (double)(g->N[a] - 1) * g->h[a];
    }
    if (g->slices.so)
        sheared_box(g, mesh->box);
    status = mesh_keep_slices(mesh, g);
    if (status != ISOMEND_OK)
        goto unlock;
    if (c->progress)
        (void)c->progress(c->progress_user, 1.0);
    if (stats) {
        *stats = st;
        stats->cubes =
            (uint64_t)(g->N[0] - 1) * (uint64_t)(g->N[1] - 1) * (uint64_t)(g->N[2] - 1);
        stats->vertices = nv;
        stats->triangles = nt;
    }
    *out_mesh = mesh;
    mesh = NULL;

unlock:
    pthread_cond_destroy(&p->cv);
    pthread_mutex_destroy(&p->mu);
done:
    isomend_mesh_destroy(mesh);
    isomend_mesh_destroy(old);
    free(c);
    free(p);
    return status;
}

isomend_status isomend_extract(const isomend_volume *vol, const isomend_options *opts,
                               isomend_mesh **out_mesh, isomend_stats *stats)
{
    isomend_mesh *none = NULL;
    return extract(vol, opts, out_mesh, stats, &none);
}

isomend_status isomend_extract_recycle(const isomend_volume *vol, const isomend_options *opts,
                                       isomend_mesh **mesh, isomend_stats *stats)
{
    if (!mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_mesh *old = *mesh;
    const isomend_status status = extract(vol, opts, mesh, stats, &old);
    isomend_mesh_destroy(old); /* not taken: the arguments were refused */
    return status;
}
