/*
 * test_io_labels.c - label maps through the importer's C API (issue 36: the
 * route of the MeshLab filter and the Blender add-on)
 *
 * - isomend_io_labels_extract() on a .seg.nrrd of three touching labels
 *   gives the core's isomend_labels_extract() of the same samples, every
 *   label (count 0) and a list, byte for byte; progress reaches the source's
 *   callback as stage EXTRACT, up to 1.0;
 * - an f64 raw file of whole numbers (as NIfTI uint32 arrives) gives the
 *   same meshes; a fraction is refused naming the file and the voxel;
 * - refused with the source named: a label not in the volume, a volume with
 *   no label but 0; a method labels do not take (the core's text); NULL;
 * - isomend_io_label_names_read(): the .seg.nrrd's Segment*_ keys (name,
 *   colour), a colour table file, none for a raw file (label_N and the
 *   palette, as with no set), a missing table named without the command
 *   line's option.
 *
 * Usage: test_io_labels DIR   (a writable folder)
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "isomend.h"
#include "isomend_io.h"
#include "testutil.h"

enum { NX = 14, NY = 13, NZ = 12 };

static uint8_t g_vol[NZ][NY][NX];

static void make_labels(void)
{
    for (int z = 0; z < NZ; z++)
        for (int y = 0; y < NY; y++)
            for (int x = 0; x < NX; x++) {
                uint8_t l = 0;
                if (z >= 2 && z < 7 && y >= 2 && y < 10 && x >= 2 && x < 7) l = 1;
                else if (z >= 2 && z < 7 && y >= 2 && y < 10 && x >= 7 && x < 12) l = 2;
                else if ((x - 7.2) * (x - 7.2) + (y - 6.1) * (y - 6.1) + (z - 8.6) * (z - 8.6) < 7.5)
                    l = 3;
                g_vol[z][y][x] = l;
            }
}

static int write_file(const char *path, const char *head, const void *data, size_t bytes)
{
    FILE *f = fopen(path, "wb");
    if (!f) return 0;
    int ok = fputs(head, f) >= 0 && fwrite(data, 1, bytes, f) == bytes;
    return fclose(f) == 0 && ok;
}

static isomend_io_source *open_path(const char *path, const isomend_io_options *o)
{
    isomend_io_source *src = NULL;
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    isomend_io_status st = isomend_io_open(src, &path, 1, o);
    CHECK_EQ_INT(st, ISOMEND_IO_OK);
    if (st != ISOMEND_IO_OK) fprintf(stderr, "  open %s: %s\n", path, isomend_io_message(src));
    return src;
}

/* The core's result on g_vol with the given spacing. */
static isomend_labels *reference(const int64_t *labels, size_t count, const double spacing[3])
{
    isomend_volume vol;
    isomend_volume_init(&vol, g_vol, ISOMEND_U8, NX, NY, NZ);
    memcpy(vol.spacing, spacing, sizeof vol.spacing);
    isomend_options opts;
    isomend_options_init(&opts);
    opts.flags = ISOMEND_FLAG_PAD;
    isomend_labels *res = NULL;
    CHECK_EQ_INT(isomend_labels_extract(&vol, labels, count, &opts, &res), ISOMEND_OK);
    return res;
}

static void same_labels(const isomend_labels *a, const isomend_labels *b)
{
    CHECK(a && b);
    if (!a || !b) return;
    CHECK_EQ_INT(isomend_labels_count(a), isomend_labels_count(b));
    for (size_t q = 0; q < isomend_labels_count(a) && q < isomend_labels_count(b); q++) {
        const isomend_mesh *ma = isomend_labels_mesh(a, q), *mb = isomend_labels_mesh(b, q);
        CHECK_EQ_INT(isomend_labels_value(a, q), isomend_labels_value(b, q));
        CHECK_EQ_INT(isomend_labels_voxels(a, q), isomend_labels_voxels(b, q));
        const size_t nv = isomend_mesh_vertex_count(ma), nt = isomend_mesh_triangle_count(ma);
        CHECK(nt > 0);
        CHECK_EQ_INT(isomend_mesh_vertex_count(mb), nv);
        CHECK_EQ_INT(isomend_mesh_triangle_count(mb), nt);
        if (isomend_mesh_vertex_count(mb) != nv || isomend_mesh_triangle_count(mb) != nt) continue;
        CHECK(memcmp(isomend_mesh_positions(ma), isomend_mesh_positions(mb), 12 * nv) == 0);
        CHECK(memcmp(isomend_mesh_normals(ma), isomend_mesh_normals(mb), 12 * nv) == 0);
        CHECK(memcmp(isomend_mesh_triangles(ma), isomend_mesh_triangles(mb), 12 * nt) == 0);
    }
}

typedef struct progress_log {
    int extract_calls;
    double last;
} progress_log;

static int on_progress(void *user, int stage, double fraction)
{
    progress_log *p = user;
    if (stage == ISOMEND_IO_STAGE_EXTRACT) {
        p->extract_calls++;
        p->last = fraction;
    }
    return 0;
}

/* A refusal: the status, *out NULL and `words` in the message. */
static void refused(isomend_io_source *src, const int64_t *labels, size_t count,
                    const isomend_options *opts, isomend_io_status want, const char *words)
{
    isomend_labels *res = (isomend_labels *)&res; /* not NULL: must be cleared */
    CHECK_EQ_INT(isomend_io_labels_extract(src, labels, count, opts, &res), want);
    CHECK(res == NULL);
    const char *m = isomend_io_message(src);
    CHECK(m && strstr(m, words) != NULL);
    if (!(m && strstr(m, words))) fprintf(stderr, "  message: %s (want %s)\n", m, words);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: test_io_labels DIR\n");
        return 2;
    }
    const char *dir = argv[1];
    make_labels();
    const double sp[3] = {0.5, 0.75, 1.5}, unit[3] = {1, 1, 1};

    /* a .seg.nrrd: every label, then a list, each the core's result */
    char head[1024];
    snprintf(head, sizeof head,
             "NRRD0004\ntype: uint8\ndimension: 3\nsizes: %d %d %d\nspacings: 0.5 0.75 1.5\n"
             "encoding: raw\nSegment0_Name:=Liver\nSegment0_Color:=1 0 0\n"
             "Segment0_LabelValue:=1\nSegment1_Name:=Left kidney\nSegment1_Color:=0 0.5 1\n"
             "Segment1_LabelValue:=2\n\n",
             NX, NY, NZ);
    const char *seg = tu_path_in(dir, "organs.seg.nrrd");
    CHECK(write_file(seg, head, g_vol, sizeof g_vol));
    progress_log log = {0, -1.0};
    isomend_io_options o;
    isomend_io_options_init(&o);
    o.progress = on_progress;
    o.progress_user = &log;
    isomend_io_source *src = open_path(seg, &o);
    isomend_options opts;
    isomend_options_init(&opts);
    opts.flags = ISOMEND_FLAG_PAD;
    isomend_labels *got = NULL, *ref = reference(NULL, 0, sp);
    CHECK_EQ_INT(isomend_io_labels_extract(src, NULL, 0, &opts, &got), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_labels_count(got), 3);
    same_labels(got, ref);
    CHECK(log.extract_calls > 0 && log.last == 1.0);
    isomend_labels_destroy(got);
    isomend_labels_destroy(ref);
    const int64_t two[2] = {3, 1};
    ref = reference(two, 2, sp);
    CHECK_EQ_INT(isomend_io_labels_extract(src, two, 2, &opts, &got), ISOMEND_IO_OK);
    same_labels(got, ref);
    isomend_labels_destroy(got);
    isomend_labels_destroy(ref);

    /* refusals naming the source */
    const int64_t absent[2] = {2, 9};
    refused(src, absent, 2, &opts, ISOMEND_IO_ERR_INVALID_ARGUMENT, "label 9 is not in");
    refused(src, absent, 2, &opts, ISOMEND_IO_ERR_INVALID_ARGUMENT, "organs.seg.nrrd");
    isomend_options mc33 = opts;
    mc33.method = ISOMEND_METHOD_MC33;
    refused(src, NULL, 0, &mc33, ISOMEND_IO_ERR_EXTRACT, "label extraction failed");
    refused(src, NULL, 1, &opts, ISOMEND_IO_ERR_INVALID_ARGUMENT, "labels is NULL");
    CHECK_EQ_INT(isomend_io_labels_extract(src, NULL, 0, &opts, NULL), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_io_labels_extract(NULL, NULL, 0, &opts, &got), ISOMEND_IO_ERR_INVALID_ARGUMENT);

    /* the .seg.nrrd's names and colours; a label it does not name: label_N, the palette */
    isomend_io_label_names *names = NULL;
    CHECK_EQ_INT(isomend_io_label_names_read(src, NULL, &names), ISOMEND_IO_OK);
    CHECK(strcmp(isomend_io_label_names_from(names), "seg.nrrd") == 0);
    char name[64];
    uint8_t rgb[3], palette[3];
    CHECK_EQ_INT(isomend_io_label_name(names, 2, name, sizeof name, rgb), 1);
    CHECK(strcmp(name, "Left kidney") == 0 && rgb[0] == 0 && rgb[1] == 128 && rgb[2] == 255);
    CHECK_EQ_INT(isomend_io_label_name(names, 3, name, sizeof name, rgb), 0);
    CHECK_EQ_INT(isomend_io_label_name(NULL, 3, NULL, 0, palette), 0);
    CHECK(strcmp(name, "label_3") == 0 && memcmp(rgb, palette, 3) == 0);
    CHECK_EQ_INT(isomend_io_label_name(names, 1, name, 4, NULL), 1); /* truncated */
    CHECK(strcmp(name, "Liv") == 0);
    isomend_io_label_names_destroy(names);

    /* a colour table; a missing one named without the CLI's option */
    const char *table = tu_path_in(dir, "organs.txt");
    CHECK(write_file(table, "# FreeSurfer-style\n3 Lesion 10 20 30 0\n", "", 0));
    CHECK_EQ_INT(isomend_io_label_names_read(src, table, &names), ISOMEND_IO_OK);
    CHECK(strcmp(isomend_io_label_names_from(names), "slicer/freesurfer") == 0);
    CHECK_EQ_INT(isomend_io_label_name(names, 3, name, sizeof name, rgb), 1);
    CHECK(strcmp(name, "Lesion") == 0 && rgb[0] == 10 && rgb[1] == 20 && rgb[2] == 30);
    isomend_io_label_names_destroy(names);
    names = (isomend_io_label_names *)&names;
    const char *missing = tu_path_in(dir, "none.ctbl");
    CHECK_EQ_INT(isomend_io_label_names_read(src, missing, &names), ISOMEND_IO_ERR_UNREADABLE);
    CHECK(names == NULL);
    const char *m = isomend_io_message(src);
    CHECK(strncmp(m, missing, strlen(missing)) == 0 && strstr(m, "cannot open"));
    isomend_io_label_names_destroy(NULL);
    CHECK(strcmp(isomend_io_label_names_from(NULL), "") == 0);
    isomend_io_destroy(src);

    /* f64 samples of whole numbers (NIfTI uint32 arrives so): the same meshes */
    static double f[NZ][NY][NX];
    for (size_t i = 0; i < sizeof f / sizeof f[0][0][0]; i++) (&f[0][0][0])[i] = (&g_vol[0][0][0])[i];
    const char *whole = tu_path_in(dir, "whole.raw");
    CHECK(write_file(whole, "", f, sizeof f));
    isomend_io_options_init(&o);
    o.raw_dims[0] = NX, o.raw_dims[1] = NY, o.raw_dims[2] = NZ;
    o.raw_type = ISOMEND_F64;
    src = open_path(whole, &o);
    ref = reference(NULL, 0, unit);
    CHECK_EQ_INT(isomend_io_labels_extract(src, NULL, 0, &opts, &got), ISOMEND_IO_OK);
    same_labels(got, ref);
    isomend_labels_destroy(got);
    isomend_labels_destroy(ref);
    CHECK_EQ_INT(isomend_io_label_names_read(src, NULL, &names), ISOMEND_IO_OK); /* no keys: empty */
    CHECK(strcmp(isomend_io_label_names_from(names), "") == 0);
    CHECK_EQ_INT(isomend_io_label_name(names, 1, name, sizeof name, NULL), 0);
    CHECK(strcmp(name, "label_1") == 0);
    isomend_io_label_names_destroy(names);
    isomend_io_destroy(src);

    /* a fraction; a volume of background only */
    f[4][5][6] = 1.5;
    const char *frac = tu_path_in(dir, "fraction.raw");
    CHECK(write_file(frac, "", f, sizeof f));
    src = open_path(frac, &o);
    refused(src, NULL, 0, &opts, ISOMEND_IO_ERR_UNSUPPORTED,
            "has the non-integer sample 1.5 at (6, 5, 4): a label map holds integers");
    refused(src, NULL, 0, &opts, ISOMEND_IO_ERR_UNSUPPORTED, "fraction.raw");
    isomend_io_destroy(src);
    memset(f, 0, sizeof f);
    const char *empty = tu_path_in(dir, "empty.raw");
    CHECK(write_file(empty, "", f, sizeof f));
    src = open_path(empty, &o);
    refused(src, NULL, 0, &opts, ISOMEND_IO_ERR_INVALID_ARGUMENT, "no label but the background 0");
    isomend_io_destroy(src);
    TEST_EXIT();
}
