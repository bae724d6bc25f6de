/*
 * labels_present.h - the labels present in a label map (private; labels_present.c).
 */
#ifndef ISOMEND_LABELS_PRESENT_H
#define ISOMEND_LABELS_PRESENT_H

#include "mesh_internal.h"

/* The labels present, ascending, and their samples, as
 * malloc'ed arrays. */
isomend_status label_list_present(const isomend_volume *vol, int64_t **values, uint64_t **voxels,
                                  size_t *count);

#endif /* ISOMEND_LABELS_PRESENT_H */
