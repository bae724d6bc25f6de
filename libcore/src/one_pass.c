/*
 * one_pass.c - the one pass, for one or two threads and the table methods
 * (MC, Durst, DMC) on grids of ONE_PASS_SAMPLES samples or more
 * (extract.c decides).
 *
 * Slice by slice, a worker numbers and computes the vertices of slice k + 1
 * and then writes layer k's triangles, counting as it goes (PASS_SWEEP):
 * the slice's edges are numbered from the running count, so the ids and the
 * order are those of the two passes.  Each slice is classified once, and its
 * vertices are computed while its samples are still in the caches.  The
 * output arrays are address-space reservations of the largest mesh the grid
 * can give (mesh_memory.c), trimmed at the end.
 *
 * Two threads split the sweep (struct split below): the second counts the
 * first layers up to one that halves what is left and sweeps from there, or,
 * on a sparse mesh, sweeps down from the last slice until the two meet
 * ("split apart"), its part moved into place at the end.
 *
 * The sweep (sweep()) is the unit: the layers [from, to) given the slices
 * they need, numbered from given vertex and triangle counts.
 */
#define _GNU_SOURCE /* clock_gettime, CLOCK_MONOTONIC */
#include "context.h"
#include "one_pass.h"
#include "tables.h"

#include <pthread.h>
#include <stdlib.h>
#include <time.h>

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/*
 * How long after the first thread's sweep the second may end its own and
 * still take a share of the moves (split apart).  Their sweeps meet
 * wherever their speeds make them, so they end within a slice of each other
 * when both threads run.  When the second ends much later, its CPU was taken
 * from it (a virtual CPU running at a fraction of the other's speed; see
 * docs/core-internals.md), and the first thread, on the CPU that runs, does
 * all the moves (always, with the tests' SCHEDULE_APART_SOLO).
 */
#define SPLIT_LATE 0.5e-3

/*
 * The one pass on two threads.  The calling thread sweeps from the first
 * layer, writing as it goes; the second first counts the vertices and
 * triangles of the layers from the first on (the counting pass's scans, a
 * fraction of a sweep's work) until it has counted up to a layer `at` that
 * splits what is left about evenly, then sweeps from `at` to the end, its ids
 * and triangles starting at the counts.  The first thread claims each slice
 * before writing its vertices and stops at `at`: it numbers that slice, for
 * the ids of its last layer, without writing them.  Ids and order are the
 * one thread's.  With no split (a grid too small, the first thread ahead),
 * the first thread sweeps alone.
 *
 * Counting costs the second thread a read of the volume's first part; on a
 * sparse mesh that is most of a sweep's work there, and the split lands at
 * about 2/3.  So when four sampled slices say the mesh is sparse, the second
 * splits apart instead (split_apart): it sweeps down from the last slice at
 * once (sweep_down), claiming each slice as the first thread does, until the
 * two meet, wherever the threads' speeds make them meet.  It numbers its
 * vertices and triangles past any the first can write (the bases), slice
 * after slice and layer after layer as it goes down; when both are done the
 * first thread moves the second's vertices, slice by slice in slice order,
 * to follow its own, while the second moves its triangles, renumbered.
 * Sweeping down, the second thread takes whatever share of the volume its
 * speed allows, so a thread on a slow CPU does not hold up the call.
 */
typedef struct split {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int64_t at;       /* the second thread's first layer (apart: its lowest
                       * slice so far); INT64_MAX while open */
    int64_t claimed;  /* slices [0, claimed) are written by the first thread */
    int finished;     /* the second thread is done (cv)                      */
    atomic_llong done; /* layers the second thread has swept (progress)      */
    uint64_t nv, nt;  /* its totals, when it split                           */
    isomend_status status;
    /* Split apart (split_apart): no counting; the second thread numbers its
     * vertices and triangles from the bases c->apart_vertex_base and
     * c->apart_triangle_base, past any the first can write, slice m's
     * vertices from vstart[m] and layer k's triangles from tstart[k] (both
     * decreasing with m and k), and its part is moved down once the first's
     * counts are known. */
    int apart;
    uint64_t *vstart, *tstart; /* [N2], when the reservation has the room */
    int first_done;          /* the first thread's sweep is over (cv) */
    double first_end;        /* when (CLOCK_MONOTONIC, s)             */
    int solo_join;           /* the first thread moves the triangles too */
    uint64_t nv1, nt1;       /* its vertices and triangles            */
    isomend_status status1;
} split;

/* The sweep from layer `from` (vertices numbered from *nv, triangles from
 * *nt) to the last, or, for the first of two threads (`sp`), to sp->at. */
static isomend_status sweep(ctx *c, worker *w, int64_t from, uint64_t *nv, uint64_t *nt,
                            split *sp)
{
    const int64_t N2 = c->g.N[2], layers = N2 - 1;
    const int first = sp && w->is_main;
    const row_span *ri;
    if (from + 2 < N2)
        (void)c->kernels->signs(w, from + 2, &ri); /* read ahead: z edges reach from + 2 */
    uint64_t v = *nv, t = *nt;
    v += c->kernels->scan_slice(w, from, PASS_SWEEP, v, 1);
    w->stats.nan_samples += w->slice_nans[from % SIGN_RING];
    for (int64_t k = from; k < layers; k++) {
        if (v > UINT32_MAX)
            return ISOMEND_ERR_TOO_LARGE;
        const int64_t m = k + 1;
        int last = 0; /* slice m is the second thread's: ids only */
        if (first) {
            pthread_mutex_lock(&sp->mu);
            if (m >= sp->at)
                last = 1;
            else
                sp->claimed = m + 1;
            pthread_mutex_unlock(&sp->mu);
        }
        /* The gradients at slice k + 1's z edges read slice k + 3: classifying
         * it first brings it into the caches. */
        if (k + 3 < N2 && !last)
            (void)c->kernels->signs(w, k + 3, &ri);
        const uint64_t own = v; /* the vertices of the slices before m */
        v += c->kernels->scan_slice(w, m, PASS_SWEEP, v, !last);
        if (!last)
            w->stats.nan_samples += w->slice_nans[m % SIGN_RING];
        t += c->kernels->march_layer(w, k, PASS_SWEEP, t);
        if (last) {
            *nv = own; /* slice m's vertices are the second thread's */
            *nt = t;
            return ISOMEND_OK;
        }
        if (sp && !first) {
            atomic_fetch_add(&sp->done, 1);
            if (atomic_load(&c->cancel))
                return ISOMEND_ERR_CANCELLED;
        }
        if (w->is_main && c->progress && (k % 16 == 15 || k + 1 == layers)) {
            const double swept = (double)(k + 1) + (sp ? (double)atomic_load(&sp->done) : 0.0);
            if (c->progress(c->progress_user, swept / (double)(layers + 1)))
                return ISOMEND_ERR_CANCELLED; /* 1.0 is reported at the end */
        }
    }
    if (v > UINT32_MAX)
        return ISOMEND_ERR_TOO_LARGE;
    *nv = v;
    *nt = t;
    return ISOMEND_OK;
}

/* Vertices a sample below which two threads split apart, for samples of one
 * byte; times the sample's size (see split_apart). */
#define APART_DENSITY 0.02

/*
 * Whether the second of two threads splits the sweep apart rather than
 * counting: when the one pass reserved room for it (run_one_pass: the arrays
 * twice as long, the ids then within 32 bits), it samples four slices'
 * vertices and splits apart when the mesh is sparse (the moves at the end
 * cost little).
 */
static int split_apart(worker *w, const split *sp)
{
    const ctx *c = w->c;
    const grid *g = &c->g;
    if (!sp->vstart)
        return 0;
    const uint64_t N0 = (uint64_t)g->N[0], N1 = (uint64_t)g->N[1], N2 = (uint64_t)g->N[2];
    uint64_t sampled = 0;
    for (uint64_t q = 0; q < 4; q++)
        sampled += c->kernels->scan_slice(w, (int64_t)((2 * q + 1) * N2 / 8), PASS_COUNT, 0, 0);
    const double density = APART_DENSITY * (double)isomend_type_size(g->type);
    return c->schedule >= SCHEDULE_APART || (double)sampled <= density * 4.0 * (double)(N0 * N1);
}

/*
 * The second thread's sweep when apart: down from the last slice, claiming
 * each slice m (sp->at = m) unless the first thread has it, numbering slice
 * m's vertices from *nv and writing layer m's triangles from *nt.  The
 * classification reads slice m - 1 ahead: the gradients at slice m's z edges
 * read it, and of the four ring slots the one it takes holds m + 3, which
 * nothing needs any more.
 */
static isomend_status sweep_down(ctx *c, worker *w, split *sp, uint64_t *nv, uint64_t *nt)
{
    const int64_t N2 = c->g.N[2];
    const row_span *ri;
    uint64_t v = *nv, t = *nt;
    isomend_status status = ISOMEND_OK;
    for (int64_t m = N2 - 1; m >= 1; m--) {
        pthread_mutex_lock(&sp->mu);
        const int mine = m >= sp->claimed;
        if (mine)
            sp->at = m;
        pthread_mutex_unlock(&sp->mu);
        if (!mine)
            break;
        (void)c->kernels->signs(w, m - 1, &ri);
        sp->vstart[m] = v;
        v += c->kernels->scan_slice(w, m, PASS_SWEEP, v, 1);
        w->stats.nan_samples += w->slice_nans[m % SIGN_RING];
        if (m + 1 < N2) {
            sp->tstart[m] = t;
            t += c->kernels->march_layer(w, m, PASS_SWEEP, t);
            atomic_fetch_add(&sp->done, 1);
        }
        if (v > UINT32_MAX) {
            status = ISOMEND_ERR_TOO_LARGE;
            break;
        }
        if (atomic_load(&c->cancel)) {
            status = ISOMEND_ERR_CANCELLED;
            break;
        }
    }
    *nv = v;
    *nt = t;
    return status;
}

/* Source bytes a move reads between releases of the source's pages. */
#define MOVE_CHUNK (4 * HUGE_PAGE)

/*
 * The moves of a split apart, from the second thread's part (from the bases
 * on, blocks in descending slice or layer order) to their places after the
 * first thread's part.  As the blocks are read, from the highest address
 * down, the source's huge pages above the block being read are released,
 * 8 MiB or more at a time, so that the array does not hold the whole moved
 * part twice.
 */
static void move_origins(uint8_t *org, uint64_t to, uint64_t from, uint64_t n);

typedef struct release {
    char *array;
    size_t top; /* bytes from here on were read and released, or never used */
} release;

/* Releases the source's whole pages from byte `from` up, when they come to
 * MOVE_CHUNK or this is the last block.  Not the page holding `from`: below
 * the bases it may hold the end of the moved part. */
static void release_above(release *r, size_t from, int last)
{
    const size_t at = huge_round(from);
    if (at < r->top && (last || r->top - at >= MOVE_CHUNK)) {
        release_pages(r->array + at, r->top - at);
        r->top = at;
    }
}

/* Items in block b of a split apart's part, whose blocks b, b - 1, ..., lo
 * follow one another from start[b] on, the last (lo) ending at `end`. */
static inline uint64_t block_size(const uint64_t *start, int64_t b, int64_t lo, uint64_t end)
{
    return (b > lo ? start[b - 1] : end) - start[b];
}

/*
 * Moves the vertex blocks of slices [at, N2) (items of `size` bytes, block m
 * from item vstart[m], the last ending at `end`) to item `to` on, in slice
 * order.
 */
static void move_vertex_blocks(void *array, size_t size, uint64_t to, const uint64_t *vstart,
                               int64_t at, int64_t N2, uint64_t end)
{
    if (!array || at >= N2)
        return;
    char *a = array;
    release r = {a, huge_round(size * end)};
    for (int64_t m = at; m < N2; m++) {
        const uint64_t n = block_size(vstart, m, at, end);
        memcpy(a + size * to, a + size * vstart[m], size * n);
        to += n;
        release_above(&r, size * vstart[m], m + 1 == N2);
    }
}

/*
 * Moves the triangle blocks of layers [at, N2 - 1) (layer k's from triangle
 * tstart[k], the last ending at `end`) to triangle `to` on, in layer order,
 * renumbering their vertices for the moves of move_vertex_blocks (to `nv1`
 * on), and their origins' non-zero bytes.  Layer k's triangles use vertices
 * of slices k and k + 1, whose blocks are told apart by vstart[k] >
 * vstart[k + 1].
 */
static void move_triangle_blocks(uint32_t *tri, uint8_t *org, uint64_t to, const uint64_t *tstart,
                                 uint64_t tend, const uint64_t *vstart, uint64_t vend,
                                 uint64_t nv1, int64_t at, int64_t N2)
{
    if (at >= N2 - 1)
        return;
    release r = {(char *)tri, huge_round(3 * sizeof(uint32_t) * tend)};
    uint64_t first_k = nv1; /* final id of slice k's first vertex */
    for (int64_t k = at; k < N2 - 1; k++) {
        const uint64_t n = block_size(tstart, k, at, tend);
        const uint64_t first_k1 = first_k + block_size(vstart, k, at, vend);
        /* mod 2^32: the ids move down */
        const uint32_t add_k = (uint32_t)(first_k - vstart[k]);
        const uint32_t add_k1 = (uint32_t)(first_k1 - vstart[k + 1]);
        const uint32_t split_id = (uint32_t)vstart[k];
        const uint32_t *s = tri + 3 * tstart[k];
        uint32_t *d = tri + 3 * to;
        for (uint64_t q = 0; q < 3 * n; q++)
            d[q] = s[q] + (s[q] >= split_id ? add_k : add_k1);
        move_origins(org, to, tstart[k], n);
        to += n;
        first_k = first_k1;
        release_above(&r, 3 * sizeof(uint32_t) * tstart[k], k + 2 == N2);
    }
}

/*
 * Moves n triangles' origins from `from` down to `to`, apart (the source lies
 * past the bases), where the destination reads as zero bytes (a fresh
 * reservation: recycling leaves the origins out) as does most of the source
 * (the table's triangles): only the other bytes are written, so that the
 * pages of the destination, often the first 2 MiB (on 4 KiB pages), are not
 * all faulted in.
 */
static void move_origins(uint8_t *org, uint64_t to, uint64_t from, uint64_t n)
{
    if (!org || !n)
        return;
    const uint8_t *s = org + from;
    uint8_t *d = org + to;
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

/* A split apart's triangle moves, once both threads' sweeps are over (their
 * counts and sp->at no longer change). */
static void move_second_triangles(const ctx *c, const split *sp)
{
    move_triangle_blocks(c->tri, c->org, sp->nt1, sp->tstart, sp->nt, sp->vstart, sp->nv,
                         sp->nv1, sp->at, c->g.N[2]);
}

/* The second of two threads: counts and splits, or splits apart; sweeps the
 * rest (see split). */
static void *second_sweep(void *arg)
{
    worker *w = arg;
    ctx *c = w->c;
    split *sp = c->split;
    const int64_t layers = c->g.N[2] - 1;
    const isomend_stats kept = w->stats; /* counting adds to them: not this thread's */
    uint64_t v = 0, t = 0;
    int64_t at = -1;
    const int apart = split_apart(w, sp);
    if (apart) { /* no counting: down from the last slice, from the bases */
        pthread_mutex_lock(&sp->mu);
        sp->apart = 1;
        pthread_mutex_unlock(&sp->mu);
        v = c->apart_vertex_base;
        t = c->apart_triangle_base;
    }
    for (int64_t k = 0; k + 1 < layers && at < 0 && !apart && !atomic_load(&c->cancel); k++) {
        v += c->kernels->scan_slice(w, k, PASS_COUNT, 0, 0);
        t += c->kernels->march_layer(w, k, PASS_COUNT, 0);
        /* Counted: slices and layers [0, k + 1).  Split there when the first
         * thread has not claimed slice k + 1 and has about as far to go to it
         * as this one from it to the end. */
        const int64_t s = k + 1;
        pthread_mutex_lock(&sp->mu);
        if (s >= sp->claimed && 2 * s >= layers + sp->claimed)
            sp->at = at = s;
        pthread_mutex_unlock(&sp->mu);
    }
    w->stats = kept;
    isomend_status status = ISOMEND_OK;
    if (apart)
        status = sweep_down(c, w, sp, &v, &t);
    else if (at >= 0)
        status = v > UINT32_MAX ? ISOMEND_ERR_TOO_LARGE : sweep(c, w, at, &v, &t, sp);
    pthread_mutex_lock(&sp->mu);
    sp->nv = v;
    sp->nt = t;
    sp->status = status;
    /* Apart: this thread moves the triangles (and origins) down once the
     * first thread's counts are known, while the first moves the vertices;
     * unless the first has waited long for this one, whose CPU is then
     * likely the slower (SPLIT_LATE). */
    sp->solo_join = sp->apart && (c->schedule == SCHEDULE_APART_SOLO ||
                                  (sp->first_done && now_seconds() - sp->first_end > SPLIT_LATE));
    sp->finished = 1;
    pthread_cond_broadcast(&sp->cv);
    if (!sp->apart || sp->solo_join) {
        pthread_mutex_unlock(&sp->mu);
        return NULL;
    }
    while (!sp->first_done)
        pthread_cond_wait(&sp->cv, &sp->mu);
    const int join = status == ISOMEND_OK && sp->status1 == ISOMEND_OK && sp->at != INT64_MAX;
    pthread_mutex_unlock(&sp->mu);
    if (join)
        move_second_triangles(c, sp);
    return NULL;
}

/*
 * One pass (table methods, one or two threads).  Slice by slice, a worker
 * numbers and computes the vertices of slice k + 1 and then writes layer k's
 * triangles, counting as it goes, so each slice is classified once and the
 * samples around its vertices are read while the classification has them in
 * the caches.  Ids and order are those of the two passes.  The output arrays
 * are reservations of their largest possible size (reserve_output), so
 * nothing needs to be known in advance; the untouched part costs no memory
 * and is trimmed at the end.
 */
static isomend_status sweep_on_threads(ctx *c, worker *ws, int nw, uint64_t *nv, uint64_t *nt)
{
    uint64_t v = 0, t = 0;
    if (nw < 2) {
        isomend_status status = sweep(c, &ws[0], 0, &v, &t, NULL);
        *nv = v;
        *nt = t;
        return status;
    }
    split sp;
    memset(&sp, 0, sizeof sp);
    sp.at = INT64_MAX;
    sp.claimed = 1; /* slice 0 */
    atomic_init(&sp.done, 0);
    if (pthread_mutex_init(&sp.mu, NULL) != 0)
        return ISOMEND_ERR_THREAD;
    if (pthread_cond_init(&sp.cv, NULL) != 0) {
        pthread_mutex_destroy(&sp.mu);
        return ISOMEND_ERR_THREAD;
    }
    if (c->apart_vertex_base) {
        const size_t N2 = (size_t)c->g.N[2];
        sp.vstart = calloc(2 * N2, sizeof(uint64_t)); /* NULL: no split apart */
        sp.tstart = sp.vstart ? sp.vstart + N2 : NULL;
    }
    c->split = &sp;
    pthread_t tid;
    const int started = pthread_create(&tid, NULL, second_sweep, &ws[1]) == 0;
    if (!started)
        sp.finished = 1; /* no second thread: sp.at stays open, the first sweeps alone */
    isomend_status status = sweep(c, &ws[0], 0, &v, &t, &sp);
    if (status != ISOMEND_OK)
        atomic_store(&c->cancel, 1);
    const double end = now_seconds();
    pthread_mutex_lock(&sp.mu);
    sp.first_done = 1;
    sp.first_end = end;
    sp.nv1 = v;
    sp.nt1 = t;
    sp.status1 = status;
    pthread_cond_broadcast(&sp.cv);
    pthread_mutex_unlock(&sp.mu);
    /* Wait for the second thread, reporting progress once now (the first
     * thread reports every 16 of its own layers, and the second may have
     * swept nearly all) and then every 100 ms. */
    const int64_t layers = c->g.N[2] - 1;
    pthread_mutex_lock(&sp.mu);
    for (int waited = 0;; waited = 1) {
        if (waited) {
            if (sp.finished)
                break;
            if (!c->progress) {
                pthread_cond_wait(&sp.cv, &sp.mu);
                continue;
            }
            struct timespec until;
            clock_gettime(CLOCK_REALTIME, &until);
            until.tv_nsec += 100 * 1000 * 1000;
            if (until.tv_nsec >= 1000 * 1000 * 1000) {
                until.tv_sec++;
                until.tv_nsec -= 1000 * 1000 * 1000;
            }
            pthread_cond_timedwait(&sp.cv, &sp.mu, &until);
            if (sp.finished)
                break;
        }
        if (!c->progress || status != ISOMEND_OK)
            continue;
        const double swept = (double)(sp.at < layers ? sp.at : layers) +
                             (double)atomic_load(&sp.done);
        pthread_mutex_unlock(&sp.mu);
        if (c->progress(c->progress_user, swept / (double)(layers + 1))) {
            status = ISOMEND_ERR_CANCELLED;
            atomic_store(&c->cancel, 1);
        }
        pthread_mutex_lock(&sp.mu);
    }
    const int split_made = sp.at != INT64_MAX;
    pthread_mutex_unlock(&sp.mu);
    if (status == ISOMEND_OK && split_made) {
        status = sp.status;
        if (sp.apart) {
            /* the vertices here, the triangles on the second thread */
            const uint64_t nv2 = sp.nv - c->apart_vertex_base;
            const uint64_t nt2 = sp.nt - c->apart_triangle_base;
            if (status == ISOMEND_OK) {
                move_vertex_blocks(c->pos, 3 * sizeof(float), v, sp.vstart, sp.at, c->g.N[2],
                                   sp.nv);
                move_vertex_blocks(c->nrm, 3 * sizeof(float), v, sp.vstart, sp.at, c->g.N[2],
                                   sp.nv);
                if (sp.solo_join)
                    move_second_triangles(c, &sp);
            }
            v += nv2;
            t += nt2;
        } else {
            v = sp.nv;
            t = sp.nt;
        }
    }
    if (started)
        pthread_join(tid, NULL);
    c->split = NULL;
    free(sp.vstart);
    pthread_cond_destroy(&sp.cv);
    pthread_mutex_destroy(&sp.mu);
    *nv = v;
    *nt = t;
    return status;
}

/*
 * The one-pass path: reserves the output arrays and sweeps
 * (sweep_on_threads).  ISOMEND_ERR_UNSUPPORTED (nothing allocated) when the
 * reservations are refused, for the two passes to take over.
 */
isomend_status run_one_pass(ctx *c, worker *ws, int nw, isomend_mesh **out, uint64_t *nv,
                            uint64_t *nt)
{
    const grid *g = &c->g;
    const uint64_t N0 = (uint64_t)g->N[0], N1 = (uint64_t)g->N[1], N2 = (uint64_t)g->N[2];
    /* Edges of a slice whose lower end is in it: at most 3 a sample; one
     * slice may pass 2^32 - 1 vertices before the check. */
    uint64_t vmax = 3 * N0 * N1 * N2;
    const uint64_t vcap = (uint64_t)UINT32_MAX + 1 + 3 * N0 * N1;
    if (vmax > vcap)
        vmax = vcap;
    /* Triangles: the table's, and two for each of the cube's +x, +y, +z faces. */
    const uint64_t tmax = (MC_MAX_TRI + 6) * (N0 - 1) * (N1 - 1) * (N2 - 1);
    if (vmax > SIZE_MAX / 32 || tmax > SIZE_MAX / 32)
        return ISOMEND_ERR_UNSUPPORTED;
    /* Two threads may split apart (split_apart): room for the second's part
     * past the bases vmax and tmax, which no count can reach, with its ids
     * still within 32 bits.  Address space only (reserve_output); when it is
     * refused, the arrays are reserved again without the room. */
    int room = nw == 2 && N2 >= 8 && vmax == 3 * N0 * N1 * N2 &&
               2 * vmax <= (uint64_t)UINT32_MAX + 1;
    isomend_mesh *mesh = calloc(1, sizeof(*mesh));
    if (!mesh)
        return ISOMEND_ERR_OUT_OF_MEMORY;
reserve:
    c->apart_vertex_base = room ? vmax : 0;
    c->apart_triangle_base = room ? tmax : 0;
    const uint64_t vres = room ? 2 * vmax : vmax, tres = room ? 2 * tmax : tmax;
    const size_t size[4] = {sizeof(float) * 3 * (size_t)vres,
                            c->want_normals ? sizeof(float) * 3 * (size_t)vres : 0,
                            sizeof(uint32_t) * 3 * (size_t)tres,
                            c->want_origins ? (size_t)tres : 0};
    void *p[4] = {NULL, NULL, NULL, NULL};
    for (int q = 0; q < 4; q++) {
        if (!size[q])
            continue;
        /* The origins (a byte a triangle) are often under 2 MiB: huge pages
         * from there on only, or a huge page would hold ~2 MiB of nothing. */
        size_t huge_from = q == 3 ? HUGE_PAGE : 0;
        if (c->small_pages)
            huge_from = SIZE_MAX;
        p[q] = reserve_output(size[q], huge_from);
        if (!p[q]) {
            for (int r = 0; r < q; r++)
                release_output(p[r], mesh->mapped[r]);
            if (room) {
                room = 0;
                memset(mesh->mapped, 0, sizeof mesh->mapped);
                goto reserve;
            }
            free(mesh);
            return ISOMEND_ERR_UNSUPPORTED;
        }
        mesh->mapped[q] = huge_round(size[q]);
    }
    /* The recycled mesh's positions, normals and triangles become the start of
     * the new ones.  Not its origins: the one pass leaves the table's origins
     * as zero bytes and untouched pages cost nothing; zeroing recycled ones
     * would touch what the new mesh may never write. */
    if (c->recycled) {
        isomend_mesh *old = c->recycled;
        void **arrays[3] = {(void **)&old->pos, (void **)&old->nrm, (void **)&old->tri};
        for (int q = 0; q < 3; q++) {
            if (!p[q] || !old->mapped[q])
                continue;
            adopt_output(p[q], mesh->mapped[q], *arrays[q], old->mapped[q]);
            *arrays[q] = NULL;
            old->mapped[q] = 0;
        }
        isomend_mesh_destroy(old); /* what is left: arrays the new mesh does not have */
        c->recycled = NULL;
    }
    mesh->pos = c->pos = p[0];
    mesh->nrm = c->nrm = p[1];
    mesh->tri = c->tri = p[2];
    mesh->org = c->org = p[3];
    *out = mesh; /* destroyed by the caller on error */
    c->pass = PASS_SWEEP;
    isomend_status status = sweep_on_threads(c, ws, nw, nv, nt);
    if (status != ISOMEND_OK)
        return status;
    mesh->nv = (size_t)*nv;
    mesh->nt = (size_t)*nt;
    const size_t used[4] = {sizeof(float) * 3 * mesh->nv, sizeof(float) * 3 * mesh->nv,
                            sizeof(uint32_t) * 3 * mesh->nt, mesh->nt};
    for (int q = 0; q < 4; q++)
        if (p[q])
            mesh->mapped[q] = trim_output(p[q], mesh->mapped[q], used[q]);
    return ISOMEND_OK;
}
