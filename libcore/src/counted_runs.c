/*
 * counted_runs.c - isomend_extract() on a small grid, or where the
 * reservations are refused: runs of the engine (stream.c) at bases counted
 * first, into arrays of the mesh's size (counted_runs.h).
 */
#include "context.h"
#include "extract.h"
#include "runs_job.h"
#include "stream.h"
#include "counted_runs.h"

#include <pthread.h>
#include <stdlib.h>

/* Runs at bases counted first: chunks of layers counted on the threads
 * (slices and layers, as the runs will number them), the exact arrays
 * allocated, the same chunks run from their bases.  Two reads of a small
 * grid, which stays in the caches between them, into arrays from the heap
 * (a reservation's huge pages cost a small mesh more), on every thread. */
typedef struct counted_job {
    plan *p;
    thread_state *ts;
    isomend_mesh *mesh;
    int64_t chunk, nchunks;
    uint64_t *cv, *ct;     /* [nchunks]: counts, then bases */
    int phase;             /* 0: count, 1: run */
    atomic_llong next, done;
    atomic_int started;    /* threads started in the phase: their index - 1 */
} counted_job;

/* Chunk q's layers [*a, *b) and run end (the grid's end for the last). */
static void chunk_range(const counted_job *j, int64_t q, int64_t *a, int64_t *b, int64_t *end)
{
    const int64_t layers = j->p->N2 - 1;
    *a = q * j->chunk;
    *b = *a + j->chunk < layers ? *a + j->chunk : layers;
    *end = *b == layers ? j->p->N2 : *b;
}

static void counted_chunks(counted_job *j, thread_state *t)
{
    plan *p = j->p;
    const ctx *c = p->c;
    for (;;) {
        const long long q = atomic_fetch_add(&j->next, 1);
        if (q >= j->nchunks || atomic_load(&p->cancel) || t->status != ISOMEND_OK)
            return;
        int64_t a, b, end;
        chunk_range(j, q, &a, &b, &end);
        if (j->phase == 0) {
            uint64_t v = 0, tr = 0, n;
            for (int64_t k = a; k < end; k++) {
                v += stream_direct_count(t->s, k, k < b, &n);
                tr += n;
            }
            j->cv[q] = v;
            j->ct[q] = tr;
        } else {
            const isomend_mesh *m = j->mesh;
            const stream_run run = {.first = a,
                                    .end = end,
                                    .first_id = j->cv[q],
                                    .out = {m->pos, m->nrm, m->tri + 3 * j->ct[q],
                                            m->org ? m->org + j->ct[q] : NULL},
                                    .tick = cancel_tick,
                                    .tick_user = t};
            uint64_t nv, nt;
            if (!thread_run(t, &run, &nv, &nt))
                return;
        }
        const long long done = atomic_fetch_add(&j->done, 1) + 1;
        if (t->index == 0 && c->progress &&
            c->progress(c->progress_user,
                        (double)(done + j->phase * j->nchunks) / (double)(2 * j->nchunks)))
            atomic_store(&p->cancel, 1);
    }
}

static void *counted_thread(void *arg)
{
    counted_job *j = arg;
    const int index = atomic_fetch_add(&j->started, 1) + 1; /* 1, 2, ... */
    counted_chunks(j, &j->ts[index]);
    return NULL;
}

/* Runs one phase on the threads (thread 0: this one). */
static void counted_phase(counted_job *j, int nthreads)
{
    pthread_t tid[64];
    int started = 1;
    atomic_store(&j->next, 0);
    atomic_store(&j->done, 0);
    atomic_store(&j->started, 0);
    for (int t = 1; t < nthreads; t++) {
        if (pthread_create(&tid[t], NULL, counted_thread, j) != 0)
            break;
        started = t + 1;
    }
    counted_chunks(j, &j->ts[0]);
    for (int t = 1; t < started; t++)
        pthread_join(tid[t], NULL);
}

isomend_status counted_runs(plan *p, int nthreads, isomend_mesh *mesh, uint64_t *nv,
                                   uint64_t *nt, isomend_stats *stats)
{
    ctx *c = p->c;
    const int64_t N2 = c->g.N[2], layers = N2 - 1;
    p->N2 = N2;
    thread_state ts[64];
    memset(ts, 0, sizeof ts);
    counted_job j;
    memset(&j, 0, sizeof j);
    j.p = p;
    j.ts = ts;
    j.mesh = mesh;
    /* chunks: 4 a thread, of 4 layers at least (each counts and runs a slice
     * more than its own) */
    const int64_t want = 4 * (int64_t)nthreads;
    j.chunk = (layers + want - 1) / want;
    if (j.chunk < 4)
        j.chunk = 4;
    j.nchunks = (layers + j.chunk - 1) / j.chunk;
    if (nthreads > j.nchunks)
        nthreads = (int)j.nchunks;
    j.cv = calloc(2 * (size_t)j.nchunks, sizeof(uint64_t));
    isomend_status status = j.cv ? ISOMEND_OK : ISOMEND_ERR_OUT_OF_MEMORY;
    j.ct = j.cv ? j.cv + j.nchunks : NULL;
    int made = 0;
    for (int t = 0; t < nthreads && status == ISOMEND_OK; t++) {
        ts[t].p = p;
        ts[t].index = t;
        status = stream_direct_begin(p->vol, p->opts, &ts[t].s);
        made = t + 1;
    }
    if (status == ISOMEND_OK) {
        counted_phase(&j, nthreads);
        for (int t = 0; t < nthreads; t++)
            if (ts[t].status != ISOMEND_OK)
                status = ts[t].status;
        /* counted: reported once whichever thread took the chunks */
        if (status == ISOMEND_OK && c->progress && c->progress(c->progress_user, 0.5))
            atomic_store(&p->cancel, 1);
    }
    uint64_t v = 0, tr = 0;
    for (int64_t q = 0; q < j.nchunks && status == ISOMEND_OK; q++) { /* the bases */
        const uint64_t cv = j.cv[q], ct = j.ct[q];
        j.cv[q] = v;
        j.ct[q] = tr;
        v += cv;
        tr += ct;
    }
    if (status == ISOMEND_OK && atomic_load(&p->cancel))
        status = ISOMEND_ERR_CANCELLED;
    if (status == ISOMEND_OK && v > UINT32_MAX)
        status = ISOMEND_ERR_TOO_LARGE;
    if (status == ISOMEND_OK) {
        mesh->nv = (size_t)v;
        mesh->nt = (size_t)tr;
        mesh->pos = output_alloc(12 * mesh->nv, c->small_pages);
        mesh->tri = output_alloc(12 * mesh->nt, c->small_pages);
        if (c->want_normals)
            mesh->nrm = output_alloc(12 * mesh->nv, c->small_pages);
        if (c->want_origins && (mesh->org = output_alloc(mesh->nt, c->small_pages)))
            memset(mesh->org, ISOMEND_ORIGIN_TABLE, mesh->nt); /* the runs write the others */
        if (!mesh->pos || !mesh->tri || (c->want_normals && !mesh->nrm) ||
            (c->want_origins && !mesh->org))
            status = ISOMEND_ERR_OUT_OF_MEMORY;
    }
    if (status == ISOMEND_OK) {
        j.phase = 1;
        counted_phase(&j, nthreads);
        for (int t = 0; t < nthreads; t++)
            if (ts[t].status != ISOMEND_OK)
                status = ts[t].status;
        if (status == ISOMEND_OK && atomic_load(&p->cancel))
            status = ISOMEND_ERR_CANCELLED;
    }
    memset(stats, 0, sizeof *stats);
    for (int t = 0; t < made; t++) {
        stats_add(stats, &ts[t].stats);
        stream_one_destroy(ts[t].s);
    }
    free(j.cv);
    *nv = v;
    *nt = tr;
    return status;
}

