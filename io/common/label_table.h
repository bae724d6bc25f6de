/*
 * label_table.h - the names and colours of a label map's labels (io/common)
 *
 * Where they come from:
 *   - a colour table file (--label-table FILE), one of
 *       3D Slicer's colour table (.ctbl/.txt) and FreeSurfer's LUT
 *       (FreeSurferColorLUT.txt): "INDEX NAME R G B [A]" lines, 0..255;
 *       ITK-SNAP's label description file: "IDX R G B A VIS MSH \"LABEL\""
 *       (A a fraction 0..1);
 *     blank lines and '#' comments allowed in all;
 *   - a 3D Slicer segmentation (.seg.nrrd): its header's key/value pairs
 *     SegmentN_Name, SegmentN_Color ("R G B", fractions 0..1) and
 *     SegmentN_LabelValue (1 when absent, as Slicer writes one segment);
 *   - else "label_N" and a fixed palette (label_table_color).
 */
#ifndef ISOMEND_LABEL_TABLE_H
#define ISOMEND_LABEL_TABLE_H

#include <stddef.h>
#include <stdint.h>

#define LABEL_NAME_MAX 128

#ifdef __cplusplus
extern "C" {
#endif

typedef struct label_entry {
    int64_t value;
    char name[LABEL_NAME_MAX];
    uint8_t rgb[3];
    int has_color;
} label_entry;

typedef struct label_table {
    label_entry *entry;
    size_t count, cap;
    char source[32]; /* "slicer/freesurfer", "itk-snap", "seg.nrrd" */
} label_table;

/* Reads a colour table file into t (empty on entry).  0 on success; else 1
 * with one line naming the file (and the line) in msg, t emptied. */
int label_table_read(const char *path, label_table *t, char *msg, size_t msg_size);

/* The segments of a .seg.nrrd header (attached or detached): 1 when the
 * header holds Segment*_ keys (t filled), 0 when it has none, -1 when the
 * file cannot be read or a segment's keys are malformed (msg says why). */
int label_table_from_nrrd(const char *path, label_table *t, char *msg, size_t msg_size);

/* The entry of a value, NULL if none. */
const label_entry *label_table_find(const label_table *t, int64_t value);

/* The fixed palette's colour of a value (when no table gives one). */
void label_table_color(int64_t value, uint8_t rgb[3]);

void label_table_free(label_table *t);

#ifdef __cplusplus
}
#endif

#endif
