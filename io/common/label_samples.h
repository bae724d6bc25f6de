/*
 * label_samples.h - a label map's samples as the core's label extraction
 * takes them (io/common, shared by the CLI and the importer)
 *
 * isomend_labels_extract() takes the integer types (and ISOMEND_U32).  A
 * label map may arrive as floats: the importer delivers NIfTI's uint32 (and
 * int64) volumes as f64.  Such a volume is accepted when every sample is a
 * whole number in the 32-bit range, and copied as u32 (no negative sample)
 * or i32; a fraction, a NaN, or values below 0 and above 2^31 - 1 together
 * are refused, naming the first such voxel.
 */
#ifndef ISOMEND_LABEL_SAMPLES_H
#define ISOMEND_LABEL_SAMPLES_H

#include <stddef.h>

#include "isomend.h"

#ifdef __cplusplus
extern "C" {
#endif

/*
 * *out is `in` itself when its type is an integer type (*copy NULL), else
 * an i32/u32 copy of its whole-number float samples (contiguous, same
 * spacing and origin; *copy to free).  0 on success; 1 with one line in msg
 * ("WHAT has the non-integer sample 1.5 at (i, j, k): a label map holds
 * integers", WHAT naming the volume) on refusal or without memory.
 */
int label_samples_integer(const isomend_volume *in, const char *what, isomend_volume *out,
                          void **copy, char *msg, size_t msg_size);

/* The name and colour a label is shown with: the table's name (else
 * "label_N") and the table's colour (else label_table_color()'s palette).
 * `t` may be NULL.  Returns 1 when the table has an entry for the value. */
struct label_table;
int label_describe(const struct label_table *t, int64_t value, char *name, size_t name_size,
                   uint8_t rgb[3]);

#ifdef __cplusplus
}
#endif

#endif
