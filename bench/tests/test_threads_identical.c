/*
 * test_threads_identical.c - the spec's point 4: "the mesh is identical,
 * vertex order included, for every thread count; a test proves it at 1, 2
 * and 8".
 *
 * The extraction splits the layers of cubes into chunks whose size depends on
 * the thread count (layers / (8 threads), at least 4), so 1, 2, 3, 8 and 64
 * threads cut the volume at different slices and hand chunks to threads in a
 * different order.  For every method and flag combination below, the mesh
 * (positions, normals, triangles, origins, bit for bit) and the statistics
 * must not change.  The volumes are larger and less regular than the core's
 * random tests: odd sizes so chunks end mid-volume, smooth fields with many
 * mending quads, integer ties at the level, NaNs, a negative-stride view, a
 * volume thinner than one chunk (counted runs), and one above 2^20 samples
 * (the caller's run into reserved arrays, at 2 threads with the counted
 * split or staged runs, at more with staged runs).
 */
#include "isomend.h"
#include "meshcmp.h"
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const int thread_counts[] = {1, 2, 3, 8, 64, 0};
#define NTHREADS ((int)(sizeof(thread_counts) / sizeof(thread_counts[0])))

static uint64_t rng_state = 0x2545F4914F6CDD1Dull;

static double rng_unit(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (double)(rng_state >> 11) / 9007199254740992.0;
}

/* A smooth random field: a sum of random plane waves (noise with a few voxels
 * of feature size, so many ambiguous faces and inverted combinations). */
static float *wave_field(int nx, int ny, int nz, int waves, double freq)
{
    double k[64][3], ph[64];
    for (int w = 0; w < waves; w++) {
        for (int c = 0; c < 3; c++)
            k[w][c] = (2.0 * rng_unit() - 1.0) * freq;
        ph[w] = 6.283185307179586 * rng_unit();
    }
    float *v = malloc(sizeof(float) * (size_t)nx * ny * nz);
    if (!v)
        return NULL;
    for (int z = 0; z < nz; z++)
        for (int y = 0; y < ny; y++)
            for (int x = 0; x < nx; x++) {
                double s = 0.0;
                for (int w = 0; w < waves; w++)
                    s += cos(k[w][0] * x + k[w][1] * y + k[w][2] * z + ph[w]);
                v[((size_t)z * ny + y) * nx + x] = (float)s;
            }
    return v;
}

static int same_stats(const isomend_stats *a, const isomend_stats *b)
{
    return memcmp(a, b, sizeof(*a)) == 0;
}

/*
 * Extracts `vol` at every thread count with each method and flag set, and
 * checks that all results equal the 1-thread one.  Returns the number of
 * mending triangles of DMC at 1 thread, so callers can check the volume
 * exercised the mending.
 */
static uint64_t check_volume_as(const char *name, const isomend_volume *vol, double iso,
                                int light)
{
    static const isomend_method methods[] = {ISOMEND_METHOD_MC, ISOMEND_METHOD_DURST,
                                             ISOMEND_METHOD_DMC};
    static const unsigned flag_sets[] = {0, ISOMEND_FLAG_PAD, ISOMEND_FLAG_NO_NORMALS,
                                         ISOMEND_FLAG_FLIP | ISOMEND_FLAG_PAD,
                                         ISOMEND_FLAG_NO_ORIGINS};
    /* light: the flag sets that change the runs' output (padding and flip, no
     * origins) at 1, 2 and 8 threads */
    static const unsigned light_flags[] = {0, ISOMEND_FLAG_FLIP | ISOMEND_FLAG_PAD,
                                           ISOMEND_FLAG_NO_ORIGINS | ISOMEND_FLAG_NO_NORMALS};
    const unsigned *flags = light ? light_flags : flag_sets;
    const size_t nflags = light ? sizeof(light_flags) / sizeof(light_flags[0])
                                : sizeof(flag_sets) / sizeof(flag_sets[0]);
    uint64_t mended = 0;
    for (size_t m = 0; m < sizeof(methods) / sizeof(methods[0]); m++) {
        for (size_t f = 0; f < nflags; f++) {
            isomend_mesh *ref = NULL;
            isomend_stats ref_stats;
            for (int t = 0; t < NTHREADS; t++) {
                if (light && thread_counts[t] != 1 && thread_counts[t] != 2 &&
                    thread_counts[t] != 8)
                    continue;
                isomend_options o;
                isomend_options_init(&o);
                o.iso = iso;
                o.method = methods[m];
                o.flags = flags[f];
                o.threads = thread_counts[t];
                isomend_mesh *mesh = NULL;
                isomend_stats st;
                isomend_status s = isomend_extract(vol, &o, &mesh, &st);
                CHECK_EQ_INT(s, ISOMEND_OK);
                if (s != ISOMEND_OK)
                    continue;
                if (!ref) {
                    ref = mesh;
                    ref_stats = st;
                    CHECK(isomend_mesh_triangle_count(ref) > 0);
                    if (methods[m] == ISOMEND_METHOD_DMC && flags[f] == 0)
                        mended = st.triangles_by_origin[ISOMEND_ORIGIN_MEND];
                    continue;
                }
                int same = same_mesh(ref, mesh), same_st = same_stats(&ref_stats, &st);
                if (!same || !same_st)
                    fprintf(stderr, "%s: %s flags 0x%x: %d threads differ from 1 (%s)\n", name,
                            isomend_method_name(methods[m]), flags[f], thread_counts[t],
                            !same ? "mesh" : "statistics");
                CHECK(same);
                CHECK(same_st);
                isomend_mesh_destroy(mesh);
            }
            isomend_mesh_destroy(ref);
        }
    }
    return mended;
}

static uint64_t check_volume(const char *name, const isomend_volume *vol, double iso)
{
    return check_volume_as(name, vol, iso, 0);
}

int main(void)
{
    /* Smooth noise, odd sizes: 83 layers is 10 chunks of 8 at 1 thread,
     * 42 chunks of 2 at 8 threads (clamped to 4), and so on. */
    const int nx = 70, ny = 61, nz = 84;
    const size_t n = (size_t)nx * ny * nz;
    float *f = wave_field(nx, ny, nz, 24, 0.9);
    CHECK(f != NULL);
    if (!f)
        TEST_EXIT();
    isomend_volume vol;
    isomend_volume_init(&vol, f, ISOMEND_F32, nx, ny, nz);
    vol.spacing[0] = 0.5;
    vol.spacing[2] = 1.25;
    vol.origin[1] = -3.0;
    CHECK(check_volume("f32 waves", &vol, 0.1) > 100);

    /* The same samples through a view flipped in z (negative stride). */
    isomend_volume flipped = vol;
    flipped.data = f + (size_t)(nz - 1) * nx * ny;
    flipped.strides[0] = 4;
    flipped.strides[1] = 4 * (int64_t)nx;
    flipped.strides[2] = -4 * (int64_t)nx * ny;
    CHECK(check_volume("f32 waves, z flipped view", &flipped, 0.1) > 100);

    /* NaNs scattered through the volume. */
    float *g = malloc(n * sizeof(float));
    CHECK(g != NULL);
    if (g) {
        memcpy(g, f, n * sizeof(float));
        for (size_t i = 0; i < n; i += 997)
            g[i] = NAN;
        isomend_volume vn = vol;
        vn.data = g;
        check_volume("f32 waves with NaNs", &vn, 0.1);
        free(g);
    }

    /* uint8 quantisation with samples exactly at the level (ties). */
    uint8_t *u = malloc(n);
    CHECK(u != NULL);
    if (u) {
        for (size_t i = 0; i < n; i++) {
            double q = floor(128.0 + 12.0 * f[i]);
            u[i] = (uint8_t)(q < 0 ? 0 : q > 255 ? 255 : q);
        }
        isomend_volume vu;
        isomend_volume_init(&vu, u, ISOMEND_U8, nx, ny, nz);
        CHECK(check_volume("u8 waves, ties at 128", &vu, 128.0) > 0);

        /* Thinner than one chunk: 3 slices, 2 layers, 8 threads ask for more. */
        isomend_volume thin;
        isomend_volume_init(&thin, u, ISOMEND_U8, nx, ny, 3);
        check_volume("u8 waves, 3 slices", &thin, 128.0);
        free(u);
    }
    free(f);

    /* Reserved arrays and staged runs: 131 x 127 x 128 = 2 129 536 samples. */
    const int bx = 131, by = 127, bz = 128;
    float *big = wave_field(bx, by, bz, 8, 0.5);
    CHECK(big != NULL);
    if (big) {
        isomend_volume vb;
        isomend_volume_init(&vb, big, ISOMEND_F32, bx, by, bz);
        CHECK(check_volume_as("f32 waves, 2^21 samples and more", &vb, 0.1, 1) > 100);
        free(big);
    }
    TEST_EXIT();
}
