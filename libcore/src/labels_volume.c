/*
 * labels_volume.c - a label map's samples as the label files read them
 * (private; labels_volume.h): the sample size of a label type, the range of
 * an 8- or 16-bit type, the volume's checks and byte strides, and the order
 * of label values.
 */
#include "labels_volume.h"

#include <string.h>

/* The size of a label sample, 0 for a type that is not a label type. */
size_t label_type_size(isomend_type type)
{
    switch ((int)type) {
    case ISOMEND_U8:
    case ISOMEND_I8: return 1;
    case ISOMEND_U16:
    case ISOMEND_I16: return 2;
    case ISOMEND_U32:
    case ISOMEND_I32: return 4;
    default: return 0;
    }
}

/* The smallest value of an 8- or 16-bit type and the number of its values;
 * 0 values for 32-bit types. */
size_t label_small_range(isomend_type type, int64_t *min)
{
    switch ((int)type) {
    case ISOMEND_U8: *min = 0; return 256;
    case ISOMEND_I8: *min = -128; return 256;
    case ISOMEND_U16: *min = 0; return 65536;
    case ISOMEND_I16: *min = -32768; return 65536;
    default: *min = 0; return 0;
    }
}

isomend_status label_check_volume(const isomend_volume *vol, int pad, int need_data)
{
    if (!vol || (need_data && !vol->data) || !label_type_size(vol->type))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    const isomend_status checked = volume_grid_check(vol, pad);
    if (checked != ISOMEND_OK)
        return checked;
    return vol->slice_origins ? ISOMEND_ERR_UNSUPPORTED : ISOMEND_OK;
}

void label_strides(const isomend_volume *vol, int64_t st[3])
{
    const int64_t size = (int64_t)label_type_size(vol->type);
    if (vol->strides[0] == 0 && vol->strides[1] == 0 && vol->strides[2] == 0) {
        st[0] = size;
        st[1] = size * vol->dims[0];
        st[2] = st[1] * vol->dims[1];
    } else {
        memcpy(st, vol->strides, sizeof(int64_t) * 3);
    }
}

int label_cmp_value(const void *a, const void *b)
{
    const int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}
