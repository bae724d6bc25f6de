/*
 * test_io_positions.c - options.slice_positions for a raw volume and an image
 * stack (isomend_io.h): slices placed where the caller says
 *
 * - an uneven table: isomend_io_slice_origins() is (origin x, origin y, z_k)
 *   for every slice, copied at open (the caller's array may change after),
 *   spacing[2] the mean gap (source "option"), origin z the first position,
 *   isomend_io_geometry_info() the gaps, no tilt, no warning; the volume
 *   isomend_io_load() describes carries the table, and the mesh has the
 *   uniform grid's triangles with every vertex z between two slices' z;
 * - an evenly spaced table (within 1e-6 of the mean gap): no table (NULL),
 *   that spacing and origin;
 * - a wrong count, a repeated or decreasing value, a NaN, an infinity, NULL
 *   with a count: ISOMEND_IO_ERR_INVALID_ARGUMENT naming slice_positions;
 * - without positions: uniform, the gaps are spacing[2];
 * - a job copies the table at start.
 *
 * Usage: test_io_positions DIR   (DIR holds gen_stacks.py's stacks)
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

static const char *g_dir;

/* the 13x9x13 u16 volume of gen_stacks.py's u16_pattern, as raw */
#define NX 13
#define NY 9
#define NZ 13

static isomend_io_status open_raw(const double *z, size_t n, const double *origin,
                                  isomend_io_source **out)
{
    isomend_io_options o;
    isomend_io_options_init(&o);
    o.raw_dims[0] = NX;
    o.raw_dims[1] = NY;
    o.raw_dims[2] = NZ;
    o.raw_type = ISOMEND_U16;
    o.slice_positions = z;
    o.slice_position_count = n;
    if (origin)
        for (int a = 0; a < 3; a++)
            o.origin[a] = origin[a];
    const char *paths[1] = {tu_path_in(g_dir, "u16_pattern_all.expected.raw")};
    CHECK_EQ_INT(isomend_io_create(out), ISOMEND_IO_OK);
    return isomend_io_open(*out, paths, 1, &o);
}

static void refused(const char *what, const double *z, size_t n, const char *words)
{
    isomend_io_source *s = NULL;
    isomend_io_status st = open_raw(z, n, NULL, &s);
    const char *msg = isomend_io_message(s);
    if (st != ISOMEND_IO_ERR_INVALID_ARGUMENT || !strstr(msg, "slice_positions") ||
        !strstr(msg, words)) {
        fprintf(stderr, "%s: status %d \"%s\", expected INVALID_ARGUMENT with \"%s\"\n", what,
                (int)st, msg, words);
        CHECK(0);
    } else {
        printf("ok   %s: %s\n", what, msg);
    }
    CHECK(isomend_io_slice_origins(s) == NULL);
    isomend_io_destroy(s);
}

static void uneven_raw(void)
{
    double z[NZ], keep[NZ];
    for (int k = 0; k < NZ; k++)
        z[k] = keep[k] = 5.0 + 0.8 * k + 0.05 * k * k; /* gaps 0.85 .. 1.95 */
    const double origin[3] = {2.0, -3.0, 99.0};        /* z replaced by z[0] */
    isomend_io_source *s = NULL;
    CHECK_EQ_INT(open_raw(z, NZ, origin, &s), ISOMEND_IO_OK);
    for (int k = 0; k < NZ; k++)
        z[k] = -1.0; /* copied at open */
    const double *so = isomend_io_slice_origins(s);
    CHECK(so != NULL);
    if (so)
        for (int k = 0; k < NZ; k++)
            CHECK(so[3 * k] == 2.0 && so[3 * k + 1] == -3.0 && so[3 * k + 2] == keep[k]);
    double sp[3], org[3];
    int from[3];
    CHECK_EQ_INT(isomend_io_spacing(s, sp, from), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_origin(s, org), ISOMEND_IO_OK);
    CHECK(sp[0] == 1.0 && sp[1] == 1.0 &&
          fabs(sp[2] - (keep[NZ - 1] - keep[0]) / (NZ - 1)) < 1e-15);
    CHECK_EQ_INT(from[2], ISOMEND_IO_SPACING_OPTION);
    CHECK(org[0] == 2.0 && org[1] == -3.0 && org[2] == keep[0]);
    isomend_io_geometry g;
    memset(&g, 0, sizeof g);
    g.size = sizeof g;
    CHECK_EQ_INT(isomend_io_geometry_info(s, &g), ISOMEND_IO_OK);
    CHECK_EQ_INT(g.uniform, 0);
    CHECK(fabs(g.gap_min - 0.85) < 1e-12 && fabs(g.gap_max - 1.95) < 1e-12);
    CHECK(fabs(g.gap_median - (keep[7] - keep[6])) < 1e-12); /* the upper middle of 12 gaps */
    CHECK(g.tilt_degrees == 0 && g.max_offset > 0.1 && g.uneven_gaps > 0);
    CHECK(g.warning && g.warning[0] == 0); /* the caller's own positions: no warning */
    /* the volume carries the table; the mesh: the uniform grid's triangles,
     * every vertex between the first and last slice, each on a slice plane or
     * between two neighbouring ones */
    isomend_volume vol;
    memset(&vol, 0x5a, sizeof vol);
    CHECK_EQ_INT(isomend_io_load(s, &vol, NULL), ISOMEND_IO_OK);
    CHECK(vol.slice_origins == so && vol.origin[2] == keep[0]);
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 30000.5;
    isomend_mesh *m = NULL, *flat = NULL;
    CHECK_EQ_INT(isomend_io_extract(s, &o, 0, NULL, &m, NULL), ISOMEND_IO_OK);
    isomend_volume uniform = vol;
    uniform.slice_origins = NULL;
    CHECK_EQ_INT(isomend_extract(&uniform, &o, &flat, NULL), ISOMEND_OK);
    if (m && flat) {
        size_t nv = isomend_mesh_vertex_count(m), nt = isomend_mesh_triangle_count(m);
        CHECK(nt > 10 && isomend_mesh_triangle_count(flat) == nt &&
              isomend_mesh_vertex_count(flat) == nv);
        if (isomend_mesh_triangle_count(flat) == nt)
            CHECK(memcmp(isomend_mesh_triangles(m), isomend_mesh_triangles(flat), nt * 12) == 0);
        const float *p = isomend_mesh_positions(m), *q = isomend_mesh_positions(flat);
        size_t off = 0, moved = 0;
        for (size_t i = 0; i < nv; i++) {
            /* x and y as on the uniform grid; z: the same fraction between the true slices */
            double zu = (q[3 * i + 2] - keep[0]) / sp[2]; /* uniform: slice index + t */
            int k = (int)floor(zu + 1e-5);
            double t = zu - k;
            if (k >= NZ - 1)
                k = NZ - 1, t = 0;
            double want = t < 1e-5 ? keep[k] : keep[k] + t * (keep[k + 1] - keep[k]);
            if (fabs(p[3 * i] - q[3 * i]) > 1e-5 || fabs(p[3 * i + 1] - q[3 * i + 1]) > 1e-5 ||
                fabs(p[3 * i + 2] - want) > 1e-4)
                off++;
            if (fabs(p[3 * i + 2] - q[3 * i + 2]) > 1e-3)
                moved++;
        }
        CHECK_EQ_INT(off, 0);
        CHECK(moved > 0);
        printf("ok   raw with uneven slice positions: %zu vertices, %zu moved by the table\n", nv,
               moved);
    }
    isomend_mesh_destroy(m);
    isomend_mesh_destroy(flat);
    isomend_io_destroy(s);
}

static void even_raw(void)
{
    double z[NZ];
    for (int k = 0; k < NZ; k++)
        z[k] = 7.0 + 2.5 * k + (k == 4 ? 1e-7 : 0.0); /* within 1e-6 x 2.5 */
    isomend_io_source *s = NULL;
    CHECK_EQ_INT(open_raw(z, NZ, NULL, &s), ISOMEND_IO_OK);
    CHECK(isomend_io_slice_origins(s) == NULL);
    double sp[3], org[3];
    CHECK_EQ_INT(isomend_io_spacing(s, sp, NULL), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_origin(s, org), ISOMEND_IO_OK);
    CHECK(fabs(sp[2] - 2.5) < 1e-12 && org[2] == 7.0 && org[0] == 0 && org[1] == 0);
    isomend_io_geometry g;
    memset(&g, 0, sizeof g);
    g.size = sizeof g;
    CHECK_EQ_INT(isomend_io_geometry_info(s, &g), ISOMEND_IO_OK);
    CHECK_EQ_INT(g.uniform, 1);
    CHECK(g.uneven_gaps == 0 && g.long_gaps == 0 && g.warning && !g.warning[0]);
    isomend_volume vol;
    CHECK_EQ_INT(isomend_io_load(s, &vol, NULL), ISOMEND_IO_OK);
    CHECK(vol.slice_origins == NULL && fabs(vol.spacing[2] - 2.5) < 1e-12 && vol.origin[2] == 7.0);
    isomend_io_destroy(s);
    /* 1e-5 x the gap off: a table */
    z[4] = 7.0 + 2.5 * 4 + 2.5e-5;
    CHECK_EQ_INT(open_raw(z, NZ, NULL, &s), ISOMEND_IO_OK);
    CHECK(isomend_io_slice_origins(s) != NULL);
    isomend_io_destroy(s);
    printf("ok   evenly spaced positions: a uniform grid of spacing %g\n", sp[2]);
}

static void bad_tables(void)
{
    double z[NZ + 1];
    for (int k = 0; k <= NZ; k++)
        z[k] = k * 1.5;
    refused("12 positions", z, NZ - 1, "12 positions for 13 slices");
    refused("14 positions", z, NZ + 1, "14 positions for 13 slices");
    z[5] = z[4];
    refused("a repeated position", z, NZ, "slice_positions[5]");
    z[5] = z[4] - 0.1;
    refused("a decreasing position", z, NZ, "not greater than");
    z[5] = NAN;
    refused("NaN", z, NZ, "slice_positions[5] is not finite");
    z[5] = INFINITY;
    refused("infinity", z, NZ, "not finite");
    refused("NULL with a count", NULL, NZ, "NULL");
}

static void plain_sources(void)
{
    /* no positions: uniform, gaps = spacing[2] */
    isomend_io_source *s = NULL;
    CHECK_EQ_INT(open_raw(NULL, 0, NULL, &s), ISOMEND_IO_OK);
    isomend_io_geometry g;
    memset(&g, 0, sizeof g);
    g.size = sizeof g;
    CHECK_EQ_INT(isomend_io_geometry_info(s, &g), ISOMEND_IO_OK);
    CHECK(g.uniform == 1 && g.gap_median == 1.0 && g.gap_min == 1.0 && g.gap_max == 1.0 &&
          g.tilt_degrees == 0 && g.max_offset == 0 && g.warning && !g.warning[0]);
    CHECK(isomend_io_slice_origins(s) == NULL);
    isomend_io_destroy(s);
    /* before open */
    CHECK_EQ_INT(isomend_io_create(&s), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_geometry_info(s, &g), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK(isomend_io_slice_origins(s) == NULL);
    CHECK_EQ_INT(isomend_io_geometry_info(NULL, &g), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK(isomend_io_slice_origins(NULL) == NULL);
    isomend_io_destroy(s);
}

/* An image stack, opened by a job: the table is copied at the job's start. */
static void stack_job(void)
{
    double *z = malloc(sizeof(double) * NZ);
    for (int k = 0; k < NZ; k++)
        z[k] = k < 6 ? k * 1.0 : 5.0 + (k - 5) * 2.0;
    isomend_io_options io;
    isomend_io_options_init(&io);
    io.slice_positions = z;
    io.slice_position_count = NZ;
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 30000.5;
    const char *paths[1] = {tu_path_in(g_dir, "u16_pattern/slice_%04d.tif")};
    isomend_io_source *s = NULL;
    isomend_io_job *job = NULL;
    CHECK_EQ_INT(isomend_io_create(&s), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_job_start(s, paths, 1, &io, &o, 0, &job), ISOMEND_IO_OK);
    for (int k = 0; k < NZ; k++)
        z[k] = -1.0;
    free(z);
    isomend_mesh *m = NULL;
    isomend_io_status st = isomend_io_job_finish(job, NULL, &m, NULL);
    if (st != ISOMEND_IO_OK)
        fprintf(stderr, "stack job: %s\n", isomend_io_message(s));
    CHECK_EQ_INT(st, ISOMEND_IO_OK);
    CHECK(m && isomend_mesh_triangle_count(m) > 10);
    const double *so = isomend_io_slice_origins(s);
    CHECK(so != NULL);
    if (so)
        for (int k = 0; k < NZ; k++)
            CHECK(so[3 * k + 2] == (k < 6 ? k * 1.0 : 5.0 + (k - 5) * 2.0));
    if (m) {
        const float *p = isomend_mesh_positions(m);
        for (size_t i = 0; i < isomend_mesh_vertex_count(m); i++)
            CHECK(p[3 * i + 2] >= 0 && p[3 * i + 2] <= 21);
    }
    printf("ok   a stack's job with slice positions\n");
    isomend_mesh_destroy(m);
    isomend_io_destroy(s);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: test_io_positions DIR\n");
        return 2;
    }
    g_dir = argv[1];
    uneven_raw();
    even_raw();
    bad_tables();
    plain_sources();
    stack_job();
    TEST_EXIT();
}
