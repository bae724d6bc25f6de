/*
 * check_sink.c - the continuity check of a streamed mesh, as it goes by.
 *
 * A tee in front of the writer's sink: every call goes to the writer and to
 * the core's streaming checker (isomend_check_stream_*, O(slice) memory),
 * whose report is isomend_mesh_check()'s on the whole mesh.  The checker
 * runs on a thread of its own: the tee copies each call's arrays into a
 * queue of blocks (at most the plan's check_queue bytes; the stream waits
 * when it is full) and the thread feeds them to the checker in order, so that checking
 * overlaps reading, extracting and writing instead of adding to them.  A block
 * the thread is done with is kept for the next call it fits (the queued and the
 * kept blocks within the queue's capacity, and one block): freed, a layer's triangles (megabytes) came back from the
 * system on fresh pages at the next call, a page fault every 4 KiB.
 */
#define _POSIX_C_SOURCE 200809L

#include "cli.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>


typedef enum { CALL_VERTICES, CALL_TRIANGLES, CALL_RETIRE } call_kind;

typedef struct call {
    struct call *next;
    call_kind kind;
    uint64_t first; /* vertices: first id; retire: the floor */
    size_t count, bytes;
    size_t room;    /* bytes allocated (>= bytes) */
    /* then the positions (3 floats each) or the triangles (3 ids each) */
} call;

struct cli_checker {
    isomend_check_stream *check;
    cli_sink next;  /* the writer's sink */
    size_t capacity; /* bytes of calls the queue holds at most */
    pthread_t thread;
    int started;
    pthread_mutex_t lock;
    pthread_cond_t more, room;
    call *head, *tail;
    size_t queued;   /* bytes in the queue */
    call *spare;     /* blocks done with, for reuse (their room: spare_bytes) */
    size_t spare_bytes;
    int closed;      /* no more calls */
    isomend_status status; /* the checker's first failure */
    uint64_t peak;   /* isomend_check_stream_peak_bytes() + the queue's peak */
    size_t queue_peak;
};

static void *check_main(void *arg)
{
    cli_checker *k = arg;
    pthread_mutex_lock(&k->lock);
    for (;;) {
        while (!k->head && !k->closed)
            pthread_cond_wait(&k->more, &k->lock);
        call *c = k->head;
        if (!c)
            break;
        k->head = c->next;
        if (!k->head)
            k->tail = NULL;
        pthread_mutex_unlock(&k->lock);
        isomend_status st = ISOMEND_OK;
        if (k->status == ISOMEND_OK) {
            const void *data = c + 1;
            switch (c->kind) {
            case CALL_VERTICES:
                st = isomend_check_stream_vertices(k->check, c->first, c->count, data);
                break;
            case CALL_TRIANGLES:
                st = isomend_check_stream_triangles(k->check, c->count, data);
                break;
            case CALL_RETIRE:
                st = isomend_check_stream_retire(k->check, c->first);
                break;
            }
        }
        pthread_mutex_lock(&k->lock);
        if (st != ISOMEND_OK && k->status == ISOMEND_OK)
            k->status = st;
        k->queued -= c->bytes;
        pthread_cond_signal(&k->room);
        if (k->queued + k->spare_bytes <= k->capacity) { /* at most a block over */
            c->next = k->spare;
            k->spare = c;
            k->spare_bytes += c->room;
            c = NULL;
        }
        if (k->queued + k->spare_bytes > k->queue_peak)
            k->queue_peak = k->queued + k->spare_bytes;
        free(c);
    }
    pthread_mutex_unlock(&k->lock);
    return NULL;
}

/* Queues a call with `size` bytes of data (copied from `data`). */
static int enqueue(cli_checker *k, call_kind kind, uint64_t first, size_t count, const void *data,
                   size_t size)
{
    call *c = NULL;
    pthread_mutex_lock(&k->lock); /* a spare block it fits in */
    for (call **at = &k->spare; *at; at = &(*at)->next)
        if ((*at)->room >= sizeof *c + size) {
            c = *at;
            *at = c->next;
            k->spare_bytes -= c->room;
            break;
        }
    pthread_mutex_unlock(&k->lock);
    if (!c) { /* room for a somewhat larger call next time */
        const size_t room = sizeof *c + size + size / 4;
        c = malloc(room);
        if (!c) {
            cli_error("out of memory (the continuity check's queue)");
            return 1;
        }
        c->room = room;
    }
    c->next = NULL;
    c->kind = kind;
    c->first = first;
    c->count = count;
    c->bytes = sizeof *c + size;
    if (size)
        memcpy(c + 1, data, size);
    pthread_mutex_lock(&k->lock);
    while (k->queued > 0 && k->queued + c->bytes > k->capacity)
        pthread_cond_wait(&k->room, &k->lock);
    k->queued += c->bytes;
    if (k->queued + k->spare_bytes > k->queue_peak)
        k->queue_peak = k->queued + k->spare_bytes;
    if (k->tail)
        k->tail->next = c;
    else
        k->head = c;
    k->tail = c;
    pthread_cond_signal(&k->more);
    pthread_mutex_unlock(&k->lock);
    return 0;
}

static int tee_vertices(void *user, uint64_t first, size_t count, const float *pos,
                        const float *nrm, const uint64_t *keys)
{
    cli_checker *k = user;
    if (enqueue(k, CALL_VERTICES, first, count, pos, 3 * sizeof(float) * count))
        return 1;
    return k->next.vertices(k->next.user, first, count, pos, nrm, keys);
}

static int tee_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    cli_checker *k = user;
    if (enqueue(k, CALL_TRIANGLES, 0, count, ids, 3 * sizeof(uint64_t) * count))
        return 1;
    return k->next.triangles(k->next.user, count, ids, origins);
}

static int tee_retire(void *user, uint64_t floor)
{
    cli_checker *k = user;
    if (enqueue(k, CALL_RETIRE, floor, 0, NULL, 0))
        return 1;
    return k->next.retire(k->next.user, floor);
}

int cli_checker_begin(const isomend_volume *desc, const isomend_options *opts, uint64_t queue,
                      const cli_sink *next, cli_checker **out, cli_sink *tee)
{
    *out = NULL;
    cli_checker *k = calloc(1, sizeof *k);
    if (!k) {
        cli_error("out of memory (the continuity check)");
        return 1;
    }
    isomend_volume v = *desc;
    v.data = NULL;
    const isomend_status st = isomend_check_stream_begin_volume(&v, opts, &k->check);
    if (st != ISOMEND_OK) {
        cli_error("the continuity check: %s", isomend_status_string(st));
        free(k);
        return 1;
    }
    k->next = *next;
    k->capacity = (size_t)queue;
    pthread_mutex_init(&k->lock, NULL);
    pthread_cond_init(&k->more, NULL);
    pthread_cond_init(&k->room, NULL);
    if (pthread_create(&k->thread, NULL, check_main, k) != 0) {
        cli_error("cannot start the continuity check's thread");
        cli_checker_destroy(k);
        return 1;
    }
    k->started = 1;
    memset(tee, 0, sizeof *tee);
    tee->user = k;
    tee->vertices = tee_vertices;
    tee->triangles = tee_triangles;
    tee->retire = tee_retire;
    *out = k;
    return 0;
}

/* Waits for the thread to have checked every call queued. */
static void close_queue(cli_checker *k)
{
    if (!k->started)
        return;
    pthread_mutex_lock(&k->lock);
    k->closed = 1;
    pthread_cond_signal(&k->more);
    pthread_mutex_unlock(&k->lock);
    pthread_join(k->thread, NULL);
    k->started = 0;
}

int cli_checker_finish(cli_checker *k, isomend_check_report *report)
{
    close_queue(k);
    isomend_status st = k->status;
    if (st == ISOMEND_OK)
        st = isomend_check_stream_finish(k->check, report);
    if (st != ISOMEND_OK) {
        cli_error("the continuity check: %s", isomend_status_string(st));
        return 1;
    }
    return 0;
}

uint64_t cli_checker_peak_bytes(const cli_checker *k)
{
    return k ? isomend_check_stream_peak_bytes(k->check) + k->queue_peak : 0;
}

void cli_checker_destroy(cli_checker *k)
{
    if (!k)
        return;
    pthread_mutex_lock(&k->lock);
    if (k->status == ISOMEND_OK) /* not finished: the calls still queued are dropped */
        k->status = ISOMEND_ERR_CANCELLED;
    pthread_mutex_unlock(&k->lock);
    close_queue(k);
    while (k->spare) {
        call *c = k->spare;
        k->spare = c->next;
        free(c);
    }
    isomend_check_stream_destroy(k->check);
    pthread_mutex_destroy(&k->lock);
    pthread_cond_destroy(&k->more);
    pthread_cond_destroy(&k->room);
    free(k);
}
