/*
 * runs_job.h - isomend_extract()'s runs (private): the reserved arrays, a
 * staged run, a thread and the plan the threads share (slabs.c: the runs on
 * threads into reservations; counted_runs.c: counted first, into arrays of
 * the mesh's size).  Types and inline functions only.
 */
#ifndef ISOMEND_RUNS_JOB_H
#define ISOMEND_RUNS_JOB_H

#include "context.h"
#include "extract.h"
#include "stream.h"

#include <pthread.h>
#include <stdatomic.h>

/* Arrays of the largest mesh (or a region's part of it), reserved. */
typedef struct arrays {
    stream_out out;
    size_t mapped[4];
} arrays;

typedef struct staged {
    int64_t first, end;   /* its slices and layers [first, end) */
    int thread;           /* whose region holds it                 */
    uint64_t v_at, nv;    /* its vertices in the region, and count */
    uint64_t t_at, nt;    /* its triangles                         */
    uint64_t v_base, t_base; /* where they go in the mesh (moves)  */
} staged;

typedef struct plan plan;

typedef struct thread_state {
    plan *p;
    int index;            /* 0: the caller, the head */
    stream_one *s;
    arrays region;        /* a staged thread's runs, one after another */
    uint64_t v_used, t_used;
    isomend_stats stats;  /* summed over its runs */
    isomend_status status;
} thread_state;

struct plan {
    ctx *c;
    const isomend_volume *vol;
    const isomend_options *opts;
    arrays mesh;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int64_t N2;
    int64_t claimed;      /* the head wrote slices [0, claimed)            */
    int64_t lowest;       /* the lowest slice a staged run took; N2: none  */
    int64_t H, H_min;     /* a staged run's layers, at most and at least   */
    int threads;          /* taking part                                   */
    uint64_t vcap, tcap;  /* the grid's largest mesh: the reservations' room */
    uint64_t layer_vmax;  /* the most vertices a layer (and its slice) has */
    staged *runs;         /* [N2], in the order taken (downwards)          */
    int64_t nruns;
    int staging;          /* threads still taking runs                     */
    int moves_ready;      /* the bases are known (cv)                      */
    atomic_llong next_move;
    atomic_llong layers_staged; /* progress */
    atomic_int cancel;
    int64_t head_reported;
    int head_yield_at;    /* tests (SCHEDULE_STAGED): the head stops at 1 */
    int counted;          /* thread 1 counts, then runs to the top          */
    int64_t counted_at;   /* where its run begins (-1: none)                */
    uint64_t counted_v, counted_t, counted_nv, counted_nt;
};

/* A run's tick that only cancels (the caller's runs report progress). */
static inline int cancel_tick(void *user, int64_t m)
{
    (void)m;
    const thread_state *t = user;
    return atomic_load(&t->p->cancel) ? -1 : 1;
}

/* One run on thread t (its engine): 1 with its statistics added to the
 * thread's, 0 with the failure in t->status and the other threads told to
 * stop. */
static inline int thread_run(thread_state *t, const stream_run *run, uint64_t *nv, uint64_t *nt)
{
    isomend_stats st;
    t->status = stream_direct_run(t->s, run, &st, nv, nt);
    if (t->status != ISOMEND_OK) {
        atomic_store(&t->p->cancel, 1);
        return 0;
    }
    stats_add(&t->stats, &st);
    return 1;
}

#endif /* ISOMEND_RUNS_JOB_H */
