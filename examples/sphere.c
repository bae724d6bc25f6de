/*
 * sphere.c - the README's C API example: extract a sphere from a float volume
 * with the thesis method, check it, print what it made.
 * Build: cc sphere.c $(pkg-config --cflags --libs isomend) -o sphere
 */
#include <isomend.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

int main(void)
{
    enum { N = 64 };
    float *v = malloc(sizeof(float) * N * N * N);
    if (!v)
        return 1;
    for (int z = 0; z < N; z++) /* x fastest: v[x + N (y + N z)] */
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++)
                v[x + N * (y + N * z)] = 20.0f - sqrtf((float)((x - 31.5) * (x - 31.5) +
                                                               (y - 31.5) * (y - 31.5) +
                                                               (z - 31.5) * (z - 31.5)));

    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F32, N, N, N);
    vol.spacing[2] = 2.0; /* slices 2 mm apart */

    isomend_options opts;
    isomend_options_init(&opts); /* DMC, all cores, normals on */
    opts.iso = 0.0;
    opts.flags = ISOMEND_FLAG_PAD; /* close surfaces at the volume's border */

    isomend_mesh *mesh = NULL;
    isomend_stats stats;
    isomend_status s = isomend_extract(&vol, &opts, &mesh, &stats);
    if (s != ISOMEND_OK) {
        fprintf(stderr, "extract: %s\n", isomend_status_string(s));
        free(v);
        return 1;
    }
    isomend_check_report check;
    isomend_mesh_check(mesh, &check);
    printf("%zu vertices, %zu triangles (%llu mending), %llu hole edges, euler %lld\n",
           isomend_mesh_vertex_count(mesh), isomend_mesh_triangle_count(mesh),
           (unsigned long long)stats.triangles_by_origin[ISOMEND_ORIGIN_MEND],
           (unsigned long long)check.hole_edges, (long long)check.euler);
    const float *p = isomend_mesh_positions(mesh); /* 3 floats per vertex, world units */
    const uint32_t *t = isomend_mesh_triangles(mesh); /* 3 indices per triangle */
    printf("first triangle: (%g %g %g) ...\n", p[3 * t[0]], p[3 * t[0] + 1], p[3 * t[0] + 2]);
    int ok = check.hole_edges == 0 && check.border_edges == 0 && check.euler == 2;
    isomend_mesh_destroy(mesh);
    free(v);
    return ok ? 0 : 1;
}
