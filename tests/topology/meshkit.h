/*
 * meshkit.h - tests only: meshes of small grids by every method, and their
 * combinatorial topology.
 *
 * mk_extract marches a grid of doubles with the public isomend_extract()
 * (one thread, no normals; `pad` sets ISOMEND_FLAG_PAD).  mk_extract_loop
 * uses instead a small independent reference loop over
 * isomend_method_cube() (libcore/src/methods.h) with one vertex per grid
 * edge, face diagonal, cube centre or ring slot, padding with NaN samples:
 * the tests compare the two, so a fault in the extraction's handling of the
 * hook (vertex numbering, private vertices, threads) shows up.
 */
#ifndef ISOMEND_TEST_MESHKIT_H
#define ISOMEND_TEST_MESHKIT_H

#include "isomend.h"

#include <stddef.h>
#include <stdint.h>

typedef struct mk_mesh {
    size_t nv, nt;
    float *pos;     /* 3 per vertex */
    uint32_t *tri;  /* 3 per triangle */
    double box[6];  /* the marched grid's box */
} mk_mesh;

typedef struct mk_topo {
    long v, e, f;                /* referenced vertices, distinct edges, triangles */
    long chi;                    /* v - e + f */
    long components;             /* through shared edges */
    long once_edges;             /* edges used once (border or hole) */
    long multi_edges;            /* edges used 3+ times */
    long misoriented_edges;      /* used twice in the same direction */
    long nonmanifold_vertices;   /* triangles around it form 2+ fans */
    long degenerate;             /* a repeated index */
} mk_topo;

/* 0 on success; -1 on failure (out of memory, bad method). */
int mk_extract(const double *vals, int nx, int ny, int nz, double iso, isomend_method method,
               int pad, mk_mesh *out);
/* Always the reference loop; MC there uses the MC table (for timing the
 * per-cube cost of every method in the same loop). */
int mk_extract_loop(const double *vals, int nx, int ny, int nz, double iso, isomend_method method,
                    int pad, mk_mesh *out);
void mk_free(mk_mesh *m);

/* 1 when the mesh is a closed oriented 2-manifold without degenerate triangles. */
int mk_analyse(const mk_mesh *m, mk_topo *t);

#endif
