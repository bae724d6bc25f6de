/*
 * label_table.c - label names and colours from colour tables and from a
 * 3D Slicer segmentation's header (see label_table.h)
 */
#define _POSIX_C_SOURCE 200809L

#include "label_table.h"

#include "atomic_file.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SET_MSG isomend_fileio_set_msg

void label_table_free(label_table *t)
{
    if (!t) return;
    free(t->entry);
    t->entry = NULL;
    t->count = t->cap = 0;
}

/* The entry of `value`, added (zeroed) when new; NULL without memory. */
static label_entry *entry_for(label_table *t, int64_t value)
{
    for (size_t q = 0; q < t->count; q++)
        if (t->entry[q].value == value) return &t->entry[q];
    if (t->count == t->cap) {
        size_t cap = t->cap ? 2 * t->cap : 64;
        label_entry *e = realloc(t->entry, cap * sizeof *e);
        if (!e) return NULL;
        t->entry = e;
        t->cap = cap;
    }
    label_entry *e = &t->entry[t->count++];
    memset(e, 0, sizeof *e);
    e->value = value;
    return e;
}

const label_entry *label_table_find(const label_table *t, int64_t value)
{
    for (size_t q = 0; t && q < t->count; q++)
        if (t->entry[q].value == value) return &t->entry[q];
    return NULL;
}

void label_table_color(int64_t value, uint8_t rgb[3])
{
    /* 20 distinct colours (Tableau's 20), by the value */
    static const uint8_t palette[20][3] = {
        {31, 119, 180},  {255, 127, 14},  {44, 160, 44},   {214, 39, 40},   {148, 103, 189},
        {140, 86, 75},   {227, 119, 194}, {127, 127, 127}, {188, 189, 34},  {23, 190, 207},
        {174, 199, 232}, {255, 187, 120}, {152, 223, 138}, {255, 152, 150}, {197, 176, 213},
        {196, 156, 148}, {247, 182, 210}, {199, 199, 199}, {219, 219, 141}, {158, 218, 229}};
    const uint64_t k = (uint64_t)value % 20u;
    memcpy(rgb, palette[k], 3);
}

static int parse_i64(const char *s, int64_t *out)
{
    if (!*s) return 0;
    char *end;
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (*end || errno) return 0;
    *out = v;
    return 1;
}

static int parse_f(const char *s, double *out)
{
    if (!*s) return 0;
    char *end;
    double v = strtod(s, &end);
    if (*end || v != v) return 0;
    *out = v;
    return 1;
}

static void set_name(label_entry *e, const char *name)
{
    snprintf(e->name, sizeof e->name, "%s", name);
}

/* One data line of a table (trimmed, not a comment); 0 if malformed. */
static int table_line(label_table *t, char *line)
{
    char *quote = strchr(line, '"');
    if (quote) { /* ITK-SNAP: IDX R G B A VIS MSH "LABEL" */
        char *close = strrchr(line, '"');
        if (close == quote || close[1]) return 0;
        *close = '\0';
        *quote = '\0';
        char *tok[8];
        int n = 0;
        for (char *p = strtok(line, " \t"); p && n < 8; p = strtok(NULL, " \t")) tok[n++] = p;
        int64_t v[7];
        double a;
        if (n != 7 || !parse_i64(tok[0], &v[0]) || !parse_f(tok[4], &a)) return 0;
        for (int c = 1; c < 4; c++)
            if (!parse_i64(tok[c], &v[c]) || v[c] < 0 || v[c] > 255) return 0;
        label_entry *e = entry_for(t, v[0]);
        if (!e) return 0;
        set_name(e, quote + 1);
        for (int c = 0; c < 3; c++) e->rgb[c] = (uint8_t)v[c + 1];
        e->has_color = 1;
        snprintf(t->source, sizeof t->source, "itk-snap");
        return 1;
    }
    /* Slicer, FreeSurfer: INDEX NAME R G B [A] */
    char *tok[7];
    int n = 0;
    for (char *p = strtok(line, " \t"); p && n < 7; p = strtok(NULL, " \t")) tok[n++] = p;
    int64_t v[6];
    if ((n != 5 && n != 6) || !parse_i64(tok[0], &v[0])) return 0;
    for (int c = 2; c < n; c++)
        if (!parse_i64(tok[c], &v[c]) || v[c] < 0 || v[c] > 255) return 0;
    label_entry *e = entry_for(t, v[0]);
    if (!e) return 0;
    set_name(e, tok[1]);
    for (int c = 0; c < 3; c++) e->rgb[c] = (uint8_t)v[c + 2];
    e->has_color = 1;
    snprintf(t->source, sizeof t->source, "slicer/freesurfer");
    return 1;
}

int label_table_read(const char *path, label_table *t, char *msg, size_t msg_size)
{
    FILE *fp = fopen(path, "r");
    if (!fp) {
        SET_MSG(msg, msg_size, "--label-table %s: cannot open: %s", path, strerror(errno));
        return 1;
    }
    char line[1024];
    long lineno = 0;
    int rc = 0;
    while (fgets(line, sizeof line, fp)) {
        lineno++;
        size_t len = strlen(line);
        if (len == sizeof line - 1 && line[len - 1] != '\n') {
            SET_MSG(msg, msg_size, "--label-table %s: line %ld is too long", path, lineno);
            rc = 1;
            break;
        }
        while (len && isspace((unsigned char)line[len - 1])) line[--len] = '\0';
        char *p = line;
        while (isspace((unsigned char)*p)) p++;
        if (!*p || *p == '#') continue;
        if (!table_line(t, p)) {
            SET_MSG(msg, msg_size,
                    "--label-table %s: line %ld is not 'INDEX NAME R G B [A]' (3D Slicer, "
                    "FreeSurfer; colours 0..255) nor ITK-SNAP's 'IDX R G B A VIS MSH \"LABEL\"'",
                    path, lineno);
            rc = 1;
            break;
        }
    }
    if (!rc && ferror(fp)) {
        SET_MSG(msg, msg_size, "--label-table %s: read error: %s", path, strerror(errno));
        rc = 1;
    }
    fclose(fp);
    if (!rc && t->count == 0) {
        SET_MSG(msg, msg_size, "--label-table %s: no label in the file", path);
        rc = 1;
    }
    if (rc) label_table_free(t);
    return rc;
}

/* Segment keys: "SegmentN_Field:=value"; N into *seg, the field's start. */
static const char *segment_key(const char *line, long *seg)
{
    if (strncmp(line, "Segment", 7) != 0 || !isdigit((unsigned char)line[7])) return NULL;
    char *end;
    *seg = strtol(line + 7, &end, 10);
    return *end == '_' ? end + 1 : NULL;
}

int label_table_from_nrrd(const char *path, label_table *t, char *msg, size_t msg_size)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        SET_MSG(msg, msg_size, "%s: cannot open: %s", path, strerror(errno));
        return -1;
    }
    /* the header: text lines up to the first empty one (or the end) */
    typedef struct seg {
        long n;
        char name[LABEL_NAME_MAX];
        double rgb[3];
        int has_color, has_value;
        int64_t value;
    } seg;
    seg *segs = NULL;
    size_t nsegs = 0;
    char line[4096];
    int rc = 0, first = 1;
    while (fgets(line, sizeof line, fp)) {
        size_t len = strlen(line);
        while (len && (line[len - 1] == '\n' || line[len - 1] == '\r')) line[--len] = '\0';
        if (first && strncmp(line, "NRRD", 4) != 0) break; /* not a NRRD header */
        first = 0;
        if (!len) break;
        long n;
        const char *field = segment_key(line, &n);
        const char *sep = strstr(line, ":=");
        if (!field || !sep) continue;
        size_t q = 0;
        while (q < nsegs && segs[q].n != n) q++;
        if (q == nsegs) {
            seg *s = realloc(segs, (nsegs + 1) * sizeof *s);
            if (!s) {
                rc = -1;
                SET_MSG(msg, msg_size, "%s: out of memory", path);
                break;
            }
            segs = s;
            memset(&segs[nsegs], 0, sizeof segs[nsegs]);
            segs[nsegs++].n = n;
        }
        seg *s = &segs[q];
        const char *value = sep + 2;
        const size_t flen = (size_t)(sep - field);
        if (flen == 4 && strncmp(field, "Name", 4) == 0) {
            snprintf(s->name, sizeof s->name, "%s", value);
        } else if (flen == 5 && strncmp(field, "Color", 5) == 0) {
            if (sscanf(value, "%lf %lf %lf", &s->rgb[0], &s->rgb[1], &s->rgb[2]) != 3 ||
                !(s->rgb[0] >= 0 && s->rgb[0] <= 1 && s->rgb[1] >= 0 && s->rgb[1] <= 1 &&
                  s->rgb[2] >= 0 && s->rgb[2] <= 1)) {
                SET_MSG(msg, msg_size, "%s: Segment%ld_Color '%s' is not three fractions 0..1",
                        path, n, value);
                rc = -1;
                break;
            }
            s->has_color = 1;
        } else if (flen == 10 && strncmp(field, "LabelValue", 10) == 0) {
            if (!parse_i64(value, &s->value)) {
                SET_MSG(msg, msg_size, "%s: Segment%ld_LabelValue '%s' is not an integer", path, n,
                        value);
                rc = -1;
                break;
            }
            s->has_value = 1;
        }
    }
    fclose(fp);
    for (size_t q = 0; rc == 0 && q < nsegs; q++) {
        label_entry *e = entry_for(t, segs[q].has_value ? segs[q].value : 1);
        if (!e) {
            SET_MSG(msg, msg_size, "%s: out of memory", path);
            rc = -1;
            break;
        }
        set_name(e, segs[q].name);
        if (segs[q].has_color) {
            for (int c = 0; c < 3; c++) e->rgb[c] = (uint8_t)(segs[q].rgb[c] * 255.0 + 0.5);
            e->has_color = 1;
        }
    }
    free(segs);
    if (rc) {
        label_table_free(t);
        return -1;
    }
    if (t->count) snprintf(t->source, sizeof t->source, "seg.nrrd");
    return t->count ? 1 : 0;
}
