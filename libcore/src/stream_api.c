/*
 * stream_api.c - the public streams (isomend_stream_*, isomend_piece_begin;
 * the contract is in isomend.h): each argument checked, then one stream on
 * the caller's thread (stream.c) or, where the options allow threads and
 * the volume has slices enough for two slabs, a pool of them (stream_pool.c,
 * whose workers run stream.c's engine slab by slab).  Both hand the sink the
 * same calls, so the choice changes the time, never the mesh.
 */
#include "stream.h"
#include "stream_pool.h"

#include <stdlib.h>

struct isomend_stream {
    stream_pool *pool; /* threads: slabs on workers; NULL: one below */
    stream_one *one;
};

/* Internal (tests): the first vertex id of a stream not yet pushed to. */
void stream_set_first_id(isomend_stream *s, uint64_t first);

static int sink_complete(const isomend_mesh_sink *sink)
{
    return sink && sink->vertices && sink->triangles && sink->retire;
}

isomend_status isomend_stream_begin(const isomend_volume *desc, const isomend_options *opts,
                                    const isomend_mesh_sink *sink, isomend_stream **out)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const isomend_options *o = opts ? opts : &defaults;
    if (!desc || !sink_complete(sink))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_status status = stream_one_check(desc, o);
    if (status != ISOMEND_OK)
        return status;
    isomend_stream *s = calloc(1, sizeof(*s));
    if (!s)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    int64_t slab_layers;
    const int threads = stream_pool_plan(desc, o, &slab_layers);
    if (threads > 1)
        status = stream_pool_begin(desc, o, sink, threads, slab_layers, &s->pool);
    else
        status = stream_one_begin(desc, o, sink, &s->one);
    if (status != ISOMEND_OK) {
        isomend_stream_destroy(s);
        return status;
    }
    *out = s;
    return ISOMEND_OK;
}

isomend_status isomend_piece_begin(const isomend_volume *desc, const isomend_options *opts,
                                   const isomend_piece *piece, const isomend_mesh_sink *sink,
                                   isomend_stream **out)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    isomend_stream *s = calloc(1, sizeof(*s));
    if (!s)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    const isomend_status status = stream_one_piece_begin(desc, opts, piece, sink, &s->one);
    if (status != ISOMEND_OK) {
        free(s);
        return status;
    }
    *out = s;
    return ISOMEND_OK;
}

isomend_status isomend_stream_push(isomend_stream *s, const void *slice)
{
    if (!s || !slice)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    return s->pool ? stream_pool_push(s->pool, slice) : stream_one_push(s->one, slice);
}

isomend_status isomend_stream_finish(isomend_stream *s, isomend_stats *stats)
{
    if (!s)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    return s->pool ? stream_pool_finish(s->pool, stats) : stream_one_finish(s->one, stats);
}

void isomend_stream_destroy(isomend_stream *s)
{
    if (!s)
        return;
    stream_pool_destroy(s->pool);
    stream_one_destroy(s->one);
    free(s);
}

void stream_set_first_id(isomend_stream *s, uint64_t first)
{
    if (s && s->pool)
        stream_pool_set_first_id(s->pool, first);
    else if (s)
        stream_one_set_first_id(s->one, first);
}

uint64_t isomend_stream_memory(const isomend_volume *desc, const isomend_options *opts)
{
    isomend_options defaults;
    isomend_options_init(&defaults);
    const isomend_options *o = opts ? opts : &defaults;
    int64_t pad = 0;
    const int threads = stream_pool_threads(o);
    if (threads > 1) { /* whether a pool runs depends on dims[2]; the bound does not */
        const uint64_t piece = stream_one_memory(desc, opts, 1, &pad);
        return piece ? stream_pool_memory(desc, threads, (int)pad, piece) : 0;
    }
    return stream_one_memory(desc, opts, 0, &pad);
}
