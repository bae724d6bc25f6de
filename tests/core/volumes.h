/* Test volumes shared by the core tests: the thesis's F1 and F2 (chapter 5.2). */
#ifndef ISOMEND_TEST_VOLUMES_H
#define ISOMEND_TEST_VOLUMES_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

static inline double thesis_f1(double x, double y, double z)
{
    return 4 * y + 4 * (x - z) * (x - z) - 5;
}

static inline double thesis_f2(double x, double y, double z)
{
    return 4 * (y - 1) * (y - 1) + 2 * (x - z) * (x - z) - 2 * (x + z - 3) * (x + z - 3) + 1;
}

/* Samples f at x, y, z in 0..3 into v[x + 4y + 16z]. */
static inline void sample_4cubed(double (*f)(double, double, double), float v[64])
{
    for (int z = 0; z < 4; z++)
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++)
                v[x + 4 * y + 16 * z] = (float)f(x, y, z);
}

/* The surfaces of the post-processing tests (test_postprocess.c,
 * test_decimate_stream.c): a sphere of radius 17.5 in a 40 x 36 x 33 grid, a
 * gyroid sin(sx)cos(sy) + ... of frequency s (genus), noise in [-0.5, 0.5)
 * from the generator *rng (every ambiguous case, hundreds of components),
 * and F1/F2 (on 4^3); n[] x n[1] x n[2] f32 samples, malloc'ed (NULL without
 * memory). */
enum { SHAPE_SPHERE, SHAPE_GYROID, SHAPE_NOISE, SHAPE_F1, SHAPE_F2 };

static inline double shape_urand(uint64_t *rng)
{
    *rng = *rng * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(*rng >> 11) / 9007199254740992.0;
}

static inline float *shape_volume(int shape, const int64_t n[3], double gyroid_s, uint64_t *rng)
{
    float *f = (float *)malloc(sizeof(float) * (size_t)(n[0] * n[1] * n[2]));
    for (int64_t k = 0; f && k < n[2]; k++)
        for (int64_t j = 0; j < n[1]; j++)
            for (int64_t i = 0; i < n[0]; i++) {
                const double x = (double)i, y = (double)j, z = (double)k, s = gyroid_s;
                double v;
                switch (shape) {
                case SHAPE_SPHERE:
                    v = 17.5 - sqrt((x - 19.5) * (x - 19.5) + (y - 17.2) * (y - 17.2) +
                                    (z - 16.1) * (z - 16.1));
                    break;
                case SHAPE_GYROID:
                    v = sin(s * x) * cos(s * y) + sin(s * y) * cos(s * z) + sin(s * z) * cos(s * x);
                    break;
                case SHAPE_NOISE: v = shape_urand(rng) - 0.5; break;
                case SHAPE_F1: v = thesis_f1(x, y, z); break;
                default: v = thesis_f2(x, y, z);
                }
                f[(k * n[1] + j) * n[0] + i] = (float)v;
            }
    return f;
}

#endif
