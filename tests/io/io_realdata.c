/*
 * io_realdata.c - a real volume (from a Debian package, converted to TIFF
 * slices by scripts/get-test-data.sh) through the isomend_io C API.
 *
 * Usage: io_realdata TIFF_FOLDER RAW TYPE NX NY NZ SX SY SZ
 *
 * Checks: the folder opens as NX x NY x NZ of TYPE with the spacing of the
 * original file (from the slices' ImageJ metadata); the samples equal the raw
 * file's; the mesh at the suggested iso has no hole edges (border edges are
 * allowed) and none at all with padding; the padded mesh equals the core's
 * mesh of the raw volume.  Prints the figures (read time, suggested iso, mesh).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "isomend.h"
#include "isomend_io.h"
#include "testutil.h"

int main(int argc, char **argv) {
    if (argc != 10) {
        fprintf(stderr, "usage: %s TIFF_FOLDER RAW TYPE NX NY NZ SX SY SZ\n", argv[0]);
        return 2;
    }
    isomend_type type;
    if (isomend_type_from_name(argv[3], &type) != ISOMEND_OK) {
        fprintf(stderr, "unknown type %s\n", argv[3]);
        return 2;
    }
    int64_t want[3] = {atol(argv[4]), atol(argv[5]), atol(argv[6])};
    double sp_want[3] = {atof(argv[7]), atof(argv[8]), atof(argv[9])};

    isomend_io_source *src = NULL;
    const char *paths[1] = {argv[1]};
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    isomend_io_status st = isomend_io_open(src, paths, 1, NULL);
    if (st != ISOMEND_IO_OK) {
        fprintf(stderr, "open: %s\n", isomend_io_message(src));
        return 1;
    }
    int64_t dims[3];
    isomend_type t;
    double sp[3];
    int sps[3];
    CHECK_EQ_INT(isomend_io_dims(src, dims), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_type(src, &t), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_spacing(src, sp, sps), ISOMEND_IO_OK);
    for (int a = 0; a < 3; a++) {
        CHECK_EQ_INT(dims[a], want[a]);
        CHECK(sp[a] > sp_want[a] * (1 - 1e-6) && sp[a] < sp_want[a] * (1 + 1e-6));
        CHECK_EQ_INT(sps[a], ISOMEND_IO_SPACING_IMAGEJ);
    }
    CHECK_EQ_INT(t, type);

    isomend_volume vol;
    double secs = 0;
    st = isomend_io_load(src, &vol, &secs);
    if (st != ISOMEND_IO_OK) {
        fprintf(stderr, "load: %s\n", isomend_io_message(src));
        return 1;
    }
    size_t bytes = (size_t)isomend_io_volume_bytes(src);
    FILE *f = fopen(argv[2], "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", argv[2]);
        return 1;
    }
    void *raw = malloc(bytes + 1);
    size_t got = raw ? fread(raw, 1, bytes + 1, f) : 0;
    fclose(f);
    CHECK_EQ_INT(got, bytes);
    CHECK(raw && memcmp(raw, vol.data, bytes) == 0);

    isomend_io_summary sum;
    CHECK_EQ_INT(isomend_io_analyse(src, &sum), ISOMEND_IO_OK);
    CHECK(sum.suggested_iso > sum.min && sum.suggested_iso < sum.max);

    /* at the suggested level: no holes inside the volume (border edges allowed) */
    isomend_options o;
    isomend_options_init(&o);
    isomend_mesh *mesh = NULL;
    double iso = 0;
    isomend_check_report r;
    CHECK_EQ_INT(isomend_io_extract(src, &o, 1, &iso, &mesh, NULL), ISOMEND_IO_OK);
    CHECK(iso == sum.suggested_iso);
    CHECK(mesh && isomend_mesh_triangle_count(mesh) > 1000);
    CHECK_EQ_INT(isomend_mesh_check(mesh, &r), ISOMEND_OK);
    CHECK_EQ_INT(r.hole_edges, 0);
    CHECK_EQ_INT(r.nonmanifold_edges, 0);
    CHECK_EQ_INT(r.misoriented_edges, 0);
    printf("unpadded: %zu triangles, %llu border edges, %llu hole edges\n",
           isomend_mesh_triangle_count(mesh), (unsigned long long)r.border_edges,
           (unsigned long long)r.hole_edges);
    isomend_mesh_destroy(mesh);

    /* padded: closed, and equal to the core's mesh of the raw volume */
    o.flags = ISOMEND_FLAG_PAD;
    CHECK_EQ_INT(isomend_io_extract(src, &o, 1, NULL, &mesh, NULL), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_mesh_check(mesh, &r), ISOMEND_OK);
    CHECK_EQ_INT(r.hole_edges, 0);
    CHECK_EQ_INT(r.border_edges, 0);
    CHECK_EQ_INT(r.nonmanifold_edges, 0);
    isomend_volume rv;
    isomend_volume_init(&rv, raw, type, want[0], want[1], want[2]);
    for (int a = 0; a < 3; a++) rv.spacing[a] = sp[a];
    o.iso = iso;
    isomend_mesh *ref = NULL;
    CHECK_EQ_INT(isomend_extract(&rv, &o, &ref, NULL), ISOMEND_OK);
    if (mesh && ref) {
        size_t nv = isomend_mesh_vertex_count(mesh), nt = isomend_mesh_triangle_count(mesh);
        CHECK_EQ_INT(isomend_mesh_vertex_count(ref), nv);
        CHECK_EQ_INT(isomend_mesh_triangle_count(ref), nt);
        if (isomend_mesh_vertex_count(ref) == nv && isomend_mesh_triangle_count(ref) == nt) {
            CHECK(memcmp(isomend_mesh_positions(ref), isomend_mesh_positions(mesh), nv * 12) == 0);
            CHECK(memcmp(isomend_mesh_triangles(ref), isomend_mesh_triangles(mesh), nt * 12) == 0);
        }
        printf("padded:   %zu vertices, %zu triangles, %llu components, 0 holes, 0 border edges\n", nv,
               nt, (unsigned long long)r.components);
    }
    printf("%s: %lldx%lldx%lld %s, spacing %g,%g,%g (imagej), range %g..%g, suggested iso %g, "
           "read %.1f ms\n",
           argv[1], (long long)dims[0], (long long)dims[1], (long long)dims[2], isomend_type_name(t),
           sp[0], sp[1], sp[2], sum.min, sum.max, iso, secs * 1e3);
    isomend_mesh_destroy(ref);
    isomend_mesh_destroy(mesh);
    isomend_io_destroy(src);
    free(raw);
    TEST_EXIT();
}
