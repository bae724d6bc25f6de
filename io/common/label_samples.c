/*
 * label_samples.c - a label map's samples as the core takes them, and the
 * name and colour a label is shown with (see label_samples.h)
 */
#include "label_samples.h"

#include "label_table.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int label_samples_integer(const isomend_volume *in, const char *what, isomend_volume *out,
                          void **copy, char *msg, size_t msg_size)
{
    *out = *in;
    *copy = NULL;
    if (in->type != ISOMEND_F32 && in->type != ISOMEND_F64) return 0;
    const int64_t nx = in->dims[0], ny = in->dims[1], nz = in->dims[2];
    const size_t n = (size_t)(nx * ny * nz);
    const int64_t ts = (int64_t)isomend_type_size(in->type);
    const int64_t st[3] = {in->strides[0] ? in->strides[0] : ts,
                           in->strides[1] ? in->strides[1] : ts * nx,
                           in->strides[2] ? in->strides[2] : ts * nx * ny};
    int negative = 0;
    for (int pass = 0; pass < 2; pass++) {
        size_t q = 0;
        for (int64_t k = 0; k < nz; k++)
            for (int64_t j = 0; j < ny; j++)
                for (int64_t i = 0; i < nx; i++, q++) {
                    const char *p = (const char *)in->data + i * st[0] + j * st[1] + k * st[2];
                    double v;
                    if (in->type == ISOMEND_F32) {
                        float f;
                        memcpy(&f, p, sizeof f);
                        v = f;
                    } else {
                        memcpy(&v, p, sizeof v);
                    }
                    if (pass == 0) {
                        if (!(v == floor(v)) || v < -2147483648.0 || v > 4294967295.0) {
                            snprintf(msg, msg_size,
                                     "%s has %s sample %.9g at (%" PRId64 ", %" PRId64
                                     ", %" PRId64 "): a label map holds integers",
                                     what, isnan(v) ? "a NaN" : "the non-integer", v, i, j, k);
                            return 1;
                        }
                        negative |= v < 0;
                        continue;
                    }
                    if (negative) {
                        if (v > 2147483647.0) {
                            snprintf(msg, msg_size,
                                     "%s has labels below 0 and above 2^31 - 1, which no 32-bit "
                                     "integer type holds",
                                     what);
                            free(*copy);
                            *copy = NULL;
                            return 1;
                        }
                        ((int32_t *)*copy)[q] = (int32_t)v;
                    } else {
                        ((uint32_t *)*copy)[q] = (uint32_t)v;
                    }
                }
        if (pass == 0 && !(*copy = malloc(4 * (n ? n : 1)))) {
            snprintf(msg, msg_size, "%s: out of memory copying the labels", what);
            return 1;
        }
    }
    isomend_volume_init(out, *copy, negative ? ISOMEND_I32 : ISOMEND_U32, nx, ny, nz);
    memcpy(out->spacing, in->spacing, sizeof out->spacing);
    memcpy(out->origin, in->origin, sizeof out->origin);
    return 0;
}

int label_describe(const label_table *t, int64_t value, char *name, size_t name_size,
                   uint8_t rgb[3])
{
    const label_entry *e = t ? label_table_find(t, value) : NULL;
    if (e && e->name[0])
        snprintf(name, name_size, "%s", e->name);
    else
        snprintf(name, name_size, "label_%" PRId64, value);
    if (e && e->has_color)
        memcpy(rgb, e->rgb, 3);
    else
        label_table_color(value, rgb);
    return e != NULL;
}
