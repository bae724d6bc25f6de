/*
 * labels_stream.c - a label map's surfaces from slices pushed one at a time
 * (isomend_labels_stream_*): the volume is never whole in memory, only the
 * ring of LABEL_RING code slices and two slices of edge ids; the meshes are
 * isomend_labels_extract()'s, byte for byte.
 *
 * One slab (labels_sweep.c) owns the whole grid; the stream converts each
 * pushed slice into the ring (marched slice z + pad) and runs every step its
 * slices allow: slice 0's vertices once slices 0 .. 2 are there, then for
 * k = 0, 1, ...: slice k + 1's vertices and layer k's cubes once slices
 * k .. k + 3 are (the last ones at finish, with the padding slice).  A push
 * overwrites the slot of slice m - 4, which no later step reads.  The labels
 * must be listed: a stream cannot know which values it will see (the
 * command line lists them in a first pass over the slices).
 */
#include "labels.h"
#include "labels_present.h"
#include "labels_sweep.h"
#include "labels_volume.h"

#include <stdlib.h>

struct isomend_labels_stream {
    label_setup su;
    label_slab slab;
    int64_t pushed; /* volume slices pushed                         */
    int64_t next_k; /* the next layer to march                      */
    int started;    /* slice 0's vertices numbered                  */
    int finished;
    isomend_status status; /* sticky: the first failure                    */
};

/* Every step the marched slices 0 .. have allow. */
static isomend_status advance(isomend_labels_stream *st, int64_t have)
{
    label_slab *s = &st->slab;
    const int64_t last = st->su.job->N[2] - 1;
    if (!st->started) {
        if (have < (last < 2 ? last : 2))
            return ISOMEND_OK;
        if (!label_scan_slice(s, 0, 0))
            return ISOMEND_ERR_OUT_OF_MEMORY;
        st->started = 1;
    }
    while (st->next_k < last && have >= (st->next_k + 3 < last ? st->next_k + 3 : last)) {
        if (!label_scan_slice(s, st->next_k + 1, 0) || !label_march_layer(s, st->next_k))
            return ISOMEND_ERR_OUT_OF_MEMORY;
        st->next_k++;
    }
    return ISOMEND_OK;
}

isomend_status isomend_labels_stream_begin(const isomend_volume *desc, const int64_t *labels,
                                           size_t count, const isomend_options *opts,
                                           isomend_labels_stream **out)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    if (!labels)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_labels_stream *st = calloc(1, sizeof *st);
    if (!st)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    isomend_status status = label_setup_begin(desc, labels, count, opts, 0, &st->su);
    if (status != ISOMEND_OK) {
        free(st);
        return status;
    }
    st->su.job->data = NULL; /* the slices come from push */
    st->slab.k0 = 0;
    st->slab.k1 = st->su.job->N[2] - 1;
    st->slab.last = 1;
    if (!label_slab_alloc(&st->slab, st->su.job)) {
        isomend_labels_stream_destroy(st);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    *out = st;
    return ISOMEND_OK;
}

isomend_status isomend_labels_stream_push(isomend_labels_stream *st, const void *slice)
{
    if (!st || !slice || st->finished)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (st->status != ISOMEND_OK)
        return st->status;
    const label_job *job = st->su.job;
    if (st->pushed >= job->n[2])
        return st->status = ISOMEND_ERR_SLICE_COUNT;
    const int64_t m = st->pushed++ + job->pad;
    label_fill_codes(&st->slab, m, slice, job->size, job->size * job->n[0]);
    return st->status = advance(st, m);
}

isomend_status isomend_labels_stream_finish(isomend_labels_stream *st, isomend_labels **out)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    if (!st || st->finished)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    st->finished = 1;
    if (st->status != ISOMEND_OK)
        return st->status;
    label_job *job = st->su.job;
    if (st->pushed != job->n[2])
        return st->status = ISOMEND_ERR_SLICE_COUNT;
    /* the padding slice at the end is made when read */
    isomend_status status = advance(st, job->N[2] - 1);
    if (status == ISOMEND_OK)
        status = label_join_all(job, &st->slab, 1, st->su.result);
    if (status == ISOMEND_OK) {
        *out = st->su.result;
        st->su.result = NULL;
    }
    return st->status = status;
}

void isomend_labels_stream_destroy(isomend_labels_stream *st)
{
    if (!st)
        return;
    if (st->su.job)
        label_slab_free(&st->slab, st->su.job->count);
    label_setup_free(&st->su);
    free(st);
}
