/*
 * stream_pool.h - a stream on several threads (stream_pool.c): the slab
 * pipeline behind isomend_stream_begin() when opts->threads allows more
 * than one.  stream_api.c decides and forwards; nothing else includes this.
 */
#ifndef ISOMEND_STREAM_POOL_H
#define ISOMEND_STREAM_POOL_H

#include "isomend.h"

typedef struct stream_pool stream_pool;

/* The threads of opts (0: the machine's cores, at most 64). */
int stream_pool_threads(const isomend_options *opts);
/* The threads a stream of `desc` with `opts` runs on (1: the plain stream,
 * too few slices for two slabs) and the marched layers of its slabs;
 * `desc` and `opts` already checked. */
int stream_pool_plan(const isomend_volume *desc, const isomend_options *opts, int64_t *slab_layers);

isomend_status stream_pool_begin(const isomend_volume *desc, const isomend_options *opts,
                                 const isomend_mesh_sink *sink, int threads, int64_t slab_layers,
                                 stream_pool **out);
isomend_status stream_pool_push(stream_pool *p, const void *slice);
isomend_status stream_pool_finish(stream_pool *p, isomend_stats *stats);
void stream_pool_destroy(stream_pool *p);
/* Tests: the first vertex id, before the first push. */
void stream_pool_set_first_id(stream_pool *p, uint64_t first);
/* A bound of a pool's memory for any dims[2] (`piece`: one piece's). */
uint64_t stream_pool_memory(const isomend_volume *desc, int threads, int pad, uint64_t piece);

#endif
