/*
 * labels_present.c - the labels a label map holds and their samples
 * (isomend_labels_present, and `--labels all` of isomend_labels_extract):
 * one pass, a histogram for 8- and 16-bit types (a plain loop for the
 * contiguous u8 and u16 volumes), a hash table of values for 32-bit ones fed
 * a run of equal samples at a time (label maps come in runs).
 */
#include "labels_present.h"
#include "labels_volume.h"
#include "labels_job.h"

#include <stdlib.h>
#include <string.h>

static int64_t sample_at(const isomend_volume *vol, const int64_t st[3], int64_t i, int64_t j,
                         int64_t k)
{
    return load_label(vol->type, (const char *)vol->data + i * st[0] + j * st[1] + k * st[2]);
}

/* A hash table of 32-bit values and their counts (open addressing). */
typedef struct value_set {
    int64_t *value;
    uint64_t *count;
    size_t cap, n;
} value_set;

static int set_add(value_set *s, int64_t v, uint64_t n)
{
    if (2 * (s->n + 1) > s->cap) {
        const size_t cap = s->cap ? 2 * s->cap : 1024;
        int64_t *value = malloc(sizeof(int64_t) * cap);
        uint64_t *count = calloc(cap, sizeof(uint64_t));
        if (!value || !count) {
            free(value);
            free(count);
            return 0;
        }
        for (size_t q = 0; q < s->cap; q++) {
            if (!s->count[q])
                continue;
            size_t h = (size_t)((uint64_t)s->value[q] * 0x9E3779B97F4A7C15ull >> 20) & (cap - 1);
            while (count[h])
                h = (h + 1) & (cap - 1);
            value[h] = s->value[q];
            count[h] = s->count[q];
        }
        free(s->value);
        free(s->count);
        s->value = value;
        s->count = count;
        s->cap = cap;
    }
    size_t h = (size_t)((uint64_t)v * 0x9E3779B97F4A7C15ull >> 20) & (s->cap - 1);
    while (s->count[h] && s->value[h] != v)
        h = (h + 1) & (s->cap - 1);
    if (!s->count[h]) {
        s->value[h] = v;
        s->n++;
    }
    s->count[h] += n;
    return 1;
}

/* The labels present, ascending, and their samples: malloc'ed arrays. */
isomend_status label_list_present(const isomend_volume *vol, int64_t **values, uint64_t **voxels,
                                  size_t *count)
{
    int64_t st[3];
    label_strides(vol, st);
    int64_t min;
    const size_t range = label_small_range(vol->type, &min);
    *values = NULL;
    *voxels = NULL;
    *count = 0;
    if (range) {
        uint64_t *hist = calloc(range, sizeof(uint64_t));
        if (!hist)
            return ISOMEND_ERR_OUT_OF_MEMORY;
        const int64_t size = (int64_t)label_type_size(vol->type);
        for (int64_t k = 0; k < vol->dims[2]; k++)
            for (int64_t j = 0; j < vol->dims[1]; j++) {
                const uint8_t *row = (const uint8_t *)vol->data + j * st[1] + k * st[2];
                if (vol->type == ISOMEND_U8 && st[0] == 1) /* the common case, vectorised */
                    for (int64_t i = 0; i < vol->dims[0]; i++)
                        hist[row[i]]++;
                else if (vol->type == ISOMEND_U16 && st[0] == size)
                    for (int64_t i = 0; i < vol->dims[0]; i++) {
                        uint16_t v;
                        memcpy(&v, row + 2 * i, 2);
                        hist[v]++;
                    }
                else
                    for (int64_t i = 0; i < vol->dims[0]; i++)
                        hist[sample_at(vol, st, i, j, k) - min]++;
            }
        size_t n = 0;
        for (size_t v = 0; v < range; v++)
            n += hist[v] != 0;
        *values = malloc(sizeof(int64_t) * (n ? n : 1));
        *voxels = malloc(sizeof(uint64_t) * (n ? n : 1));
        if (!*values || !*voxels) {
            free(hist);
            return ISOMEND_ERR_OUT_OF_MEMORY;
        }
        n = 0;
        for (size_t v = 0; v < range; v++)
            if (hist[v]) {
                (*values)[n] = (int64_t)v + min;
                (*voxels)[n++] = hist[v];
            }
        *count = n;
        free(hist);
        return ISOMEND_OK;
    }
    value_set s = {NULL, NULL, 0, 0};
    isomend_status status = ISOMEND_OK;
    for (int64_t k = 0; k < vol->dims[2] && status == ISOMEND_OK; k++)
        for (int64_t j = 0; j < vol->dims[1] && status == ISOMEND_OK; j++) {
            int64_t run = sample_at(vol, st, 0, j, k);
            uint64_t n = 0;
            for (int64_t i = 0; i < vol->dims[0]; i++) { /* runs: one insertion each */
                const int64_t v = sample_at(vol, st, i, j, k);
                if (v != run) {
                    if (!set_add(&s, run, n))
                        status = ISOMEND_ERR_OUT_OF_MEMORY;
                    run = v;
                    n = 0;
                }
                n++;
            }
            if (status == ISOMEND_OK && !set_add(&s, run, n))
                status = ISOMEND_ERR_OUT_OF_MEMORY;
        }
    if (status == ISOMEND_OK) {
        *values = malloc(sizeof(int64_t) * (s.n ? s.n : 1));
        *voxels = malloc(sizeof(uint64_t) * (s.n ? s.n : 1));
        if (!*values || !*voxels)
            status = ISOMEND_ERR_OUT_OF_MEMORY;
    }
    if (status == ISOMEND_OK) {
        size_t n = 0;
        for (size_t q = 0; q < s.cap; q++)
            if (s.count[q])
                (*values)[n++] = s.value[q];
        qsort(*values, n, sizeof(int64_t), label_cmp_value);
        for (size_t q = 0; q < s.cap; q++)
            if (s.count[q]) {
                const int64_t *at =
                    bsearch(&s.value[q], *values, n, sizeof(int64_t), label_cmp_value);
                (*voxels)[at - *values] = s.count[q];
            }
        *count = n;
    }
    free(s.value);
    free(s.count);
    return status;
}

isomend_status isomend_labels_present(const isomend_volume *vol, int64_t *values, uint64_t *voxels,
                                      size_t capacity, size_t *count)
{
    if (!count)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *count = 0;
    isomend_status status = label_check_volume(vol, 1, 1);
    if (status != ISOMEND_OK)
        return status;
    int64_t *v;
    uint64_t *n;
    size_t have;
    status = label_list_present(vol, &v, &n, &have);
    if (status == ISOMEND_OK) {
        for (size_t q = 0; q < have && q < capacity; q++) {
            if (values)
                values[q] = v[q];
            if (voxels)
                voxels[q] = n[q];
        }
        *count = have;
    }
    free(v);
    free(n);
    return status;
}
