/*
 * vertices.h - the general vertex path (private; vertices.c).
 */
#ifndef ISOMEND_VERTICES_H
#define ISOMEND_VERTICES_H

#include "grid.h"

/* The vertex on the edge along axis a from marched sample (i, j, k), and the
 * one between two samples p0, p1 not on a grid edge. */
void make_vertex(const grid *g, int flip, int64_t i, int64_t j, int64_t k, int a, float *pos,
                 float *nrm);
void make_vertex_between(const grid *g, int flip, const int64_t p0[3], const int64_t p1[3],
                         float *pos, float *nrm);

#endif /* ISOMEND_VERTICES_H */
