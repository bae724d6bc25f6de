/*
 * labels.h - what labels.c gives the label map's stream (private; labels.c):
 * the set-up, the slabs' memory and the meshes joined.
 */
#ifndef ISOMEND_LABELS_H
#define ISOMEND_LABELS_H

#include "labels_job.h"

typedef struct label_setup {
    label_job *job;
    isomend_labels *result; /* values, voxels, meshes (filled at the end)   */
    uint32_t *table, *sorted_code;
    int64_t *sorted;
} label_setup;
/* The checks, the result's labels (labels NULL: every label present but 0,
 * read from vol->data) and the job; vol->data may be NULL unless
 * `need_data` or labels NULL (a stream).  On failure nothing is left. */
isomend_status label_setup_begin(const isomend_volume *vol, const int64_t *labels, size_t count,
                                 const isomend_options *opts, int need_data, label_setup *su);
void label_setup_free(label_setup *su); /* the job and tables, and the result unless taken */
int label_slab_alloc(label_slab *s, label_job *job);
void label_slab_free(label_slab *s, size_t count);
/* The slabs' voxels summed and each label's mesh joined from their parts. */
isomend_status label_join_all(label_job *job, label_slab *slab, int nslabs, isomend_labels *r);

#endif /* ISOMEND_LABELS_H */
