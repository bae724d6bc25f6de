/* Test volumes shared by the core tests: the thesis's F1 and F2 (chapter 5.2). */
#ifndef ISOMEND_TEST_VOLUMES_H
#define ISOMEND_TEST_VOLUMES_H

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

#endif
