/*
 * team.c - the threads of one post-processing call (team.h).
 *
 * The caller publishes a loop (function, argument, count) and bumps the
 * generation; each worker, waiting for a generation it has not run, runs its
 * range and counts itself off; the caller runs range 0 and waits for the
 * count to reach zero.  Waits spin on the atomics for SPIN rounds (the next
 * loop of a smoothing comes within microseconds) and then sleep on a
 * condition variable under the team's mutex; whoever changes what a sleeper
 * waits for takes the mutex to signal, so no wake-up is lost.
 */
#include "team.h"

#include "cores.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>

#define SPIN 256 /* rounds of spinning before sleeping (pause: 10-140 cycles) */

struct team {
    int threads; /* the caller included */
    pthread_t th[TEAM_MAX_THREADS];
    pthread_mutex_t mu;
    pthread_cond_t work, done;
    atomic_uint gen;     /* the loop published last                     */
    atomic_int pending;  /* workers still running it                    */
    int quit;            /* read by the workers after a new generation  */
    void (*fn)(void *, size_t, size_t);
    void *arg;
    size_t n;
    int split; /* the threads the current loop is split among */
};

typedef struct worker {
    team *t;
    int index;
} worker;

static inline void relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

static void *worker_main(void *p)
{
    const worker *w = p;
    team *t = w->t;
    const int k = w->index;
    unsigned seen = 0;
    for (;;) {
        unsigned g = atomic_load_explicit(&t->gen, memory_order_acquire);
        for (int s = 0; g == seen && s < SPIN; s++) {
            relax();
            g = atomic_load_explicit(&t->gen, memory_order_acquire);
        }
        if (g == seen) {
            pthread_mutex_lock(&t->mu);
            while ((g = atomic_load_explicit(&t->gen, memory_order_acquire)) == seen)
                pthread_cond_wait(&t->work, &t->mu);
            pthread_mutex_unlock(&t->mu);
        }
        seen = g;
        if (t->quit)
            break;
        if (k < t->split) {
            const size_t n = t->n, parts = (size_t)t->split;
            t->fn(t->arg, n * (size_t)k / parts, n * ((size_t)k + 1) / parts);
        }
        if (atomic_fetch_sub_explicit(&t->pending, 1, memory_order_acq_rel) == 1) {
            pthread_mutex_lock(&t->mu);
            pthread_cond_signal(&t->done);
            pthread_mutex_unlock(&t->mu);
        }
    }
    free(p);
    return NULL;
}

/* Publish the current loop (or quit) to the workers. */
static void publish(team *t)
{
    atomic_store_explicit(&t->pending, t->threads - 1, memory_order_relaxed);
    atomic_fetch_add_explicit(&t->gen, 1, memory_order_release);
    pthread_mutex_lock(&t->mu);
    pthread_cond_broadcast(&t->work);
    pthread_mutex_unlock(&t->mu);
}

static void wait_workers(team *t)
{
    for (int s = 0; s < SPIN; s++) {
        if (atomic_load_explicit(&t->pending, memory_order_acquire) == 0)
            return;
        relax();
    }
    pthread_mutex_lock(&t->mu);
    while (atomic_load_explicit(&t->pending, memory_order_acquire) != 0)
        pthread_cond_wait(&t->done, &t->mu);
    pthread_mutex_unlock(&t->mu);
}

team *team_start(size_t n)
{
    size_t threads = (size_t)cores_threads(0, TEAM_MAX_THREADS);
    if (n / TEAM_MIN_ITEMS < threads)
        threads = n / TEAM_MIN_ITEMS;
    if (threads < 2)
        return NULL;
    team *t = calloc(1, sizeof(*t));
    if (!t)
        return NULL;
    if (pthread_mutex_init(&t->mu, NULL) != 0) {
        free(t);
        return NULL;
    }
    if (pthread_cond_init(&t->work, NULL) != 0) {
        pthread_mutex_destroy(&t->mu);
        free(t);
        return NULL;
    }
    if (pthread_cond_init(&t->done, NULL) != 0) {
        pthread_cond_destroy(&t->work);
        pthread_mutex_destroy(&t->mu);
        free(t);
        return NULL;
    }
    atomic_init(&t->gen, 0);
    atomic_init(&t->pending, 0);
    t->threads = 1;
    for (size_t k = 1; k < threads; k++) {
        worker *w = malloc(sizeof(*w));
        if (!w)
            break;
        *w = (worker){t, (int)k};
        if (pthread_create(&t->th[k], NULL, worker_main, w) != 0) {
            free(w);
            break;
        }
        t->threads++;
    }
    if (t->threads < 2) {
        team_stop(t);
        return NULL;
    }
    return t;
}

void team_for(team *t, size_t n, void (*fn)(void *arg, size_t lo, size_t hi), void *arg)
{
    team_for_from(t, n, TEAM_MIN_ITEMS, fn, arg);
}

void team_for_from(team *t, size_t n, size_t min_items, void (*fn)(void *arg, size_t lo, size_t hi),
                   void *arg)
{
    size_t split = t ? (size_t)t->threads : 1;
    if (min_items < 1)
        min_items = 1;
    if (n / min_items < split)
        split = n / min_items;
    if (split < 2) {
        if (n)
            fn(arg, 0, n);
        return;
    }
    t->fn = fn;
    t->arg = arg;
    t->n = n;
    t->split = (int)split;
    publish(t);
    fn(arg, 0, n / split);
    wait_workers(t);
}

int team_threads(const team *t)
{
    return t ? t->threads : 1;
}

void team_stop(team *t)
{
    if (!t)
        return;
    if (t->threads > 1) {
        t->quit = 1;
        publish(t);
        for (int k = 1; k < t->threads; k++)
            pthread_join(t->th[k], NULL);
    }
    pthread_cond_destroy(&t->work);
    pthread_cond_destroy(&t->done);
    pthread_mutex_destroy(&t->mu);
    free(t);
}
