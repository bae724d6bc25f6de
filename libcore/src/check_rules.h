/*
 * check_rules.h - the continuity checker's two geometric rules (private),
 * shared by the whole-mesh check (check.c) and the streaming one
 * (check_stream.c), whose reports must agree field for field.
 */
#ifndef ISOMEND_CHECK_RULES_H
#define ISOMEND_CHECK_RULES_H

#include <float.h>
#include <math.h>
#include <stdint.h>

/* Whether the edge p-q lies in a face plane of `box` (min[3], max[3]), within
 * 1e-6 of the box's extent plus the planes' float rounding: a border edge. */
static inline int on_box_face(const float *p, const float *q, const double *box, double extent)
{
    for (int a = 0; a < 3; a++)
        for (int side = 0; side < 2; side++) {
            double plane = box[3 * side + a];
            double tol = 1e-6 * extent + 4.0 * FLT_EPSILON * fabs(plane);
            if (fabs((double)p[a] - plane) <= tol && fabs((double)q[a] - plane) <= tol)
                return 1;
        }
    return 0;
}

/* Whether the triangle (ids i, j, k; corners a, b, c) is degenerate: a
 * repeated index or a zero cross product. */
static inline int degenerate_triangle(uint64_t i, uint64_t j, uint64_t k, const float *a,
                                      const float *b, const float *c)
{
    if (i == j || j == k || i == k)
        return 1;
    /* (scalars, not arrays: GCC kept the arrays on the stack) */
    const double u0 = (double)b[0] - a[0], u1 = (double)b[1] - a[1], u2 = (double)b[2] - a[2];
    const double v0 = (double)c[0] - a[0], v1 = (double)c[1] - a[1], v2 = (double)c[2] - a[2];
    const double x = u1 * v2 - u2 * v1, y = u2 * v0 - u0 * v2, z = u0 * v1 - u1 * v0;
    return (x == 0.0) & (y == 0.0) & (z == 0.0);
}

#endif /* ISOMEND_CHECK_RULES_H */
