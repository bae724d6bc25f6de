/*
 * stream.h - one stream on the calling thread (private; stream.c): the
 * engine under the public isomend_stream_* and isomend_piece_* (stream_api.c
 * chooses it or a pool of them, stream_pool.c, whose workers run it slab by
 * slab).  The arguments are checked by the callers.
 */
#ifndef ISOMEND_STREAM_H
#define ISOMEND_STREAM_H

#include "isomend.h"

typedef struct stream_one stream_one;

/* ISOMEND_OK, or why a stream of desc with opts (NULL: the defaults) would
 * be refused. */
isomend_status stream_one_check(const isomend_volume *desc, const isomend_options *opts);
/* A stream of the whole volume, and a piece of it (isomend_piece_begin). */
isomend_status stream_one_begin(const isomend_volume *desc, const isomend_options *opts,
                                const isomend_mesh_sink *sink, stream_one **out);
isomend_status stream_one_piece_begin(const isomend_volume *desc, const isomend_options *opts,
                                      const isomend_piece *piece, const isomend_mesh_sink *sink,
                                      stream_one **out);
/* isomend_stream_push, _finish and _destroy on one stream. */
isomend_status stream_one_push(stream_one *s, const void *slice);
isomend_status stream_one_finish(stream_one *s, isomend_stats *stats);
void stream_one_destroy(stream_one *s);
/* Tests: the first vertex id, before the first push. */
void stream_one_set_first_id(stream_one *s, uint64_t first);
/* A bound of one stream's memory (`piece`: a piece's, with its keys), 0
 * when refused; *pad the grid's padding. */
uint64_t stream_one_memory(const isomend_volume *desc, const isomend_options *opts, int piece,
                           int64_t *pad);

/* For isomend_extract() (slabs.c) and the pool's slabs (stream_pool.c):
 * runs of marched slices over a volume in memory (or a slab's planes), read
 * in place (its strides), the mesh written straight into the arrays of
 * stream_out instead of going to a sink.  A run [first, end) numbers
 * its vertices from first_id on, vertex id i at out.pos + 3 i (and
 * out.nrm), and writes its triangles from out.tri (and out.org: zero bytes
 * where it writes none, as a fresh reservation is) on, with the ids of the
 * vertices; slice `end`, when it is not the last of the grid, is numbered
 * (on from the run's own) but not computed.
 * tick (may be NULL) is asked before each slice m, first < m < end: 1 goes
 * on, 0 makes m the run's end, < 0 cancels (ISOMEND_ERR_CANCELLED).  event
 * (may be NULL) hears what a sink would have been called with, in ids from
 * first_id: vertices written (at, count), triangles written (at, count),
 * retire (at: the floor), and the vertices numbered in slice `end` (count);
 * non-zero stops the run (ISOMEND_ERR_OUT_OF_MEMORY).  planes (NULL: the
 * volume given to stream_direct_begin) are volume slices z0, z0 + 1, ...,
 * contiguous. */
enum { STREAM_EV_VERTICES, STREAM_EV_TRIANGLES, STREAM_EV_RETIRE, STREAM_EV_NEXT };
typedef int (*stream_event)(void *user, int kind, uint64_t at, uint64_t count);
typedef struct stream_out {
    float *pos, *nrm;
    uint32_t *tri;
    uint8_t *org;
} stream_out;
typedef int (*stream_tick)(void *user, int64_t m);
typedef struct stream_run {
    int64_t first, end;
    uint64_t first_id;
    stream_out out;
    stream_tick tick;
    void *tick_user;
    stream_event event;
    void *event_user;
    const char *planes;
    int64_t z0;
} stream_run;
isomend_status stream_direct_begin(const isomend_volume *vol, const isomend_options *opts,
                                   stream_one **out);
/* One run (statistics as isomend_stream_finish's; *nv, *nt the vertices and
 * triangles it wrote, those of slice `end` not counted). */
isomend_status stream_direct_run(stream_one *s, const stream_run *run, isomend_stats *stats,
                                 uint64_t *nv, uint64_t *nt);
/* The most vertices a slice (and the layer below) and the most triangles a
 * layer can have, for a stream of desc with opts; 0 when refused. */
void stream_run_bounds(const isomend_volume *desc, const isomend_options *opts,
                       uint64_t *slice_vertices, uint64_t *layer_triangles);
/* Counts, without writing, slice k's vertices (the return) and, with
 * `layer`, layer k's triangles (*nt) and cube-private vertices (added to
 * the return); the statistics this adds are cleared by the next run. */
uint64_t stream_direct_count(stream_one *s, int64_t k, int layer, uint64_t *nt);

#endif /* ISOMEND_STREAM_H */
