/*
 * clean_stream.c - the clean-up of a streamed mesh (--min-component), in
 * memory bounded by the stream's live vertices: isomend_clean_stream_*().
 *
 * A union-find over the live vertices (stream_components.c).  Each live
 * vertex (an id at or above the last retire floor that a triangle has used)
 * points to a component record; a triangle joins its three vertices'
 * components (union by size).
 * A component's triangles are held back until it has min_triangles of
 * them: then they are passed on (in the order they came), and every
 * triangle that joins the component later passes straight through (so does
 * every component it merges with: their held triangles go first).  A
 * component closes when none of its vertices is live any more (the stream
 * promises no later triangle uses an id below the floor, so nothing can join
 * it): one still held then has fewer than min_triangles triangles and is
 * dropped, with its vertices.  So the triangles kept are exactly
 * isomend_mesh_clean()'s (min_triangles, keep_largest 0) on the whole mesh,
 * and the components, counted as each closes, are its components.
 *
 * The records and the vertex slots hold the live vertices, the held
 * components and the vertices of their held triangles: O(slice) plus the
 * held triangles, each held component fewer than min_triangles.
 *
 * Output.  Vertices are numbered from 0 in the order a passed triangle
 * first uses them (delivered just before it, with the normal they came
 * with); triangles in the order they pass; one retire() for each of the
 * stream's (an output vertex retires when its stream vertex did and no held
 * triangle uses it: held triangles' vertices have no output id yet), so a
 * sink that counts layers by retire() (the streamed smoothing and
 * decimation) still sees the stream's layers.  No triangle origins.  The
 * output depends on the order of the stream's vertices, triangles and
 * retire floors only: not on how they are split into calls, nor on the
 * stream's threads.
 */
#include "stream_components.h"

#include <stdlib.h>
#include <string.h>

/* The memory estimate (sc_memory): a held triangle's bytes, held over the
 * live slices (a component waits until it has min_triangles). */
#define BYTES_PER_HELD 32.0

struct isomend_clean_stream {
    stream_components f; /* a record's pass: min_triangles reached */
    uint64_t min_tri;
    uint64_t triangles_in;
    isomend_clean_report rep;
};

/* A component that joins a passed one passes. */
static int merge_passed(void *user, sc_rec *root, const sc_rec *joined)
{
    (void)user;
    root->pass |= joined->pass;
    return 1;
}

/* A component closes: one still held has fewer than min_triangles and goes. */
static int close_component(void *user, uint32_t r)
{
    isomend_clean_stream *c = user;
    c->rep.components_before++;
    if (c->f.recs[r].pass) {
        c->rep.components_after++;
        return 1;
    }
    return sc_release_held(&c->f, r, 0);
}

/* ------------------------------------------------------------------ the stream's sink */

static int on_vertices(void *user, uint64_t first, size_t count, const float *pos, const float *nrm,
                       const uint64_t *keys)
{
    (void)keys;
    isomend_clean_stream *c = user;
    if (c->f.status != ISOMEND_OK)
        return 1;
    const isomend_status st = sc_vertices(&c->f, first, count, pos, nrm);
    return st != ISOMEND_OK ? (sc_fail(&c->f, st), 1) : 0;
}

static int on_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    (void)origins;
    isomend_clean_stream *c = user;
    if (c->f.status != ISOMEND_OK)
        return 1;
    stream_components *f = &c->f;
    for (size_t t = 0; t < count; t++) {
        uint32_t s[3], root;
        const isomend_status st = sc_triangle(f, ids + 3 * t, s, &root, merge_passed, NULL);
        if (st != ISOMEND_OK)
            return sc_fail(&c->f, st), 1;
        c->triangles_in++;
        int ok;
        if (f->recs[root].pass) {
            ok = sc_release_held(f, root, 1) && sc_emit(f, s);
        } else {
            ok = sc_hold(f, root, s);
            if (ok && f->recs[root].triangles >= c->min_tri) {
                f->recs[root].pass = 1;
                ok = sc_release_held(f, root, 1);
            }
        }
        f->seq++;
        if (!ok)
            return sc_fail(&c->f, ISOMEND_ERR_OUT_OF_MEMORY), 1;
    }
    if (!sc_flush(f))
        return sc_fail(&c->f, ISOMEND_ERR_SINK), 1;
    return 0;
}

/* The live vertices below floor leave, the components without a live
 * vertex close; then (forward) retire() on the output. */
static isomend_status retire_to(isomend_clean_stream *c, uint64_t floor, int forward)
{
    const isomend_status st = sc_retire(&c->f, floor, close_component, c, 1, forward);
    return st != ISOMEND_OK ? sc_fail(&c->f, st) : ISOMEND_OK;
}

static int on_retire(void *user, uint64_t floor)
{
    isomend_clean_stream *c = user;
    if (c->f.status != ISOMEND_OK)
        return 1;
    if (floor < c->f.floor || floor > c->f.next_id)
        return sc_fail(&c->f, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    return retire_to(c, floor, 1) != ISOMEND_OK;
}

/* ------------------------------------------------------------------ the API */

uint64_t isomend_clean_stream_memory(const isomend_volume *desc, const isomend_options *opts)
{
    return sc_memory(desc, opts, 3.0, BYTES_PER_HELD, 1048576.0); /* + 1 MiB */
}

isomend_status isomend_clean_stream_begin(uint64_t min_triangles, const isomend_mesh_sink *out,
                                          isomend_clean_stream **cs)
{
    if (!cs)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *cs = NULL;
    if (!out || !out->vertices || !out->triangles || !out->retire)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_clean_stream *c = calloc(1, sizeof *c);
    if (!c)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    sc_init(&c->f, out);
    c->min_tri = min_triangles;
    *cs = c;
    return ISOMEND_OK;
}

isomend_status isomend_clean_stream_sink(isomend_clean_stream *c, isomend_mesh_sink *sink)
{
    if (!c || !sink)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *sink = (isomend_mesh_sink){c, on_vertices, on_triangles, on_retire, NULL};
    return ISOMEND_OK;
}

isomend_status isomend_clean_stream_finish(isomend_clean_stream *c, isomend_clean_report *report)
{
    if (report)
        memset(report, 0, sizeof *report);
    if (!c)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    /* everything still open closes now (a padded stream's last retire has
     * closed it already); no retire() is passed on for it, so that a step
     * after this one sees the stream's layers (its own finish retires the
     * rest) */
    if (c->f.status == ISOMEND_OK && (c->f.floor < c->f.next_id || c->f.nlive))
        (void)retire_to(c, c->f.next_id, 0);
    if (c->f.status != ISOMEND_OK)
        return c->f.status;
    c->rep.vertices_removed = c->f.next_id - c->f.out_next;
    c->rep.triangles_removed = c->triangles_in - c->f.triangles_out;
    if (report)
        *report = c->rep;
    return ISOMEND_OK;
}

void isomend_clean_stream_destroy(isomend_clean_stream *c)
{
    if (!c)
        return;
    sc_free(&c->f);
    free(c);
}
