/*
 * dump_mesh.c - test helper: extracts a raw f32 volume and dumps the mesh as
 * raw arrays for the Python peer comparisons.
 * Usage: isomend_dump_mesh IN.raw NX NY NZ ISO METHOD OUT_PREFIX
 * Writes OUT_PREFIX.pos (float32 x,y,z) and OUT_PREFIX.tri (uint32 triples).
 */
#include "isomend.h"

#include <stdio.h>
#include <stdlib.h>

static int write_all(const char *path, const void *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return 0;
    int ok = fwrite(data, 1, size, f) == size;
    return fclose(f) == 0 && ok;
}

int main(int argc, char **argv)
{
    if (argc != 8) {
        fprintf(stderr, "usage: %s IN.raw NX NY NZ ISO METHOD OUT_PREFIX\n", argv[0]);
        return 2;
    }
    long nx = atol(argv[2]), ny = atol(argv[3]), nz = atol(argv[4]);
    size_t n = (size_t)nx * (size_t)ny * (size_t)nz;
    float *v = malloc(n * sizeof(float));
    FILE *f = fopen(argv[1], "rb");
    if (!v || !f || fread(v, sizeof(float), n, f) != n) {
        fprintf(stderr, "%s: cannot read %zu floats\n", argv[1], n);
        return 1;
    }
    fclose(f);
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F32, nx, ny, nz);
    isomend_options o;
    isomend_options_init(&o);
    o.iso = atof(argv[5]);
    if (isomend_method_from_name(argv[6], &o.method) != ISOMEND_OK) {
        fprintf(stderr, "unknown method %s\n", argv[6]);
        return 2;
    }
    isomend_mesh *m = NULL;
    isomend_status s = isomend_extract(&vol, &o, &m, NULL);
    if (s != ISOMEND_OK) {
        fprintf(stderr, "extract: %s\n", isomend_status_string(s));
        return 1;
    }
    char path[4096];
    snprintf(path, sizeof path, "%s.pos", argv[7]);
    int ok = write_all(path, isomend_mesh_positions(m), 12 * isomend_mesh_vertex_count(m));
    snprintf(path, sizeof path, "%s.tri", argv[7]);
    ok = ok && write_all(path, isomend_mesh_triangles(m), 12 * isomend_mesh_triangle_count(m));
    isomend_mesh_destroy(m);
    free(v);
    return ok ? 0 : 1;
}
