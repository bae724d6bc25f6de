/*
 * counted_runs.h - runs at bases counted first (private; counted_runs.c).
 */
#ifndef ISOMEND_COUNTED_RUNS_H
#define ISOMEND_COUNTED_RUNS_H

#include "runs_job.h"

/* The mesh of p's volume on `nthreads` threads: chunks of layers counted,
 * the arrays allocated at the mesh's size into *mesh, the chunks run from
 * their bases.  On success *nv, *nt the counts and *stats the runs'
 * statistics (cubes, vertices and triangles not set). */
isomend_status counted_runs(plan *p, int nthreads, isomend_mesh *mesh, uint64_t *nv,
                            uint64_t *nt, isomend_stats *stats);

#endif /* ISOMEND_COUNTED_RUNS_H */
