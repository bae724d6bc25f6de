/*
 * labels_volume.h - a label map's samples (private; labels_volume.c).
 */
#ifndef ISOMEND_LABELS_VOLUME_H
#define ISOMEND_LABELS_VOLUME_H

#include "mesh_internal.h"

/* A label type's sample size (0: not a label type); the range of
 * an 8- or 16-bit type (its smallest value, the count; 0 for 32-bit); the
 * volume checked (data needed or not); its byte strides; int64_t order. */
size_t label_type_size(isomend_type type);
size_t label_small_range(isomend_type type, int64_t *min);
isomend_status label_check_volume(const isomend_volume *vol, int pad, int need_data);
void label_strides(const isomend_volume *vol, int64_t st[3]);
int label_cmp_value(const void *a, const void *b);

#endif /* ISOMEND_LABELS_VOLUME_H */
