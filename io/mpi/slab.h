/*
 * slab.h - one rank's part of the mesh for isomend-mpi (io/mpi)
 *
 * The marched grid (the volume plus the padding layer with --pad) is cut
 * into slabs of consecutive slices, one per rank (slab_split).  The rule
 * (docs/streaming.md): the rank that owns marched slice k owns slice k's
 * vertices (x and y edges in slice k, z edges from k to k + 1, the tetra
 * diagonals of the faces whose lowest corner is in slice k) and layer k's
 * triangles (the cubes between slices k and k + 1), so the mending quads on
 * a shared plane belong to the rank below and the plane's vertices to the
 * rank above.  Concatenating the ranks' vertices and triangles in rank order
 * gives exactly `isomend extract`'s arrays.
 *
 * A piece holds the owned vertices (local ids 0..nv-1, each with its global
 * key) and the owned triangles; a triangle corner on the next slab's first
 * plane is SLAB_FOREIGN | f, f indexing `foreign_keys` (and `foreign_pos`,
 * for STL).  `shared` lists the owned vertices of the slab's first plane
 * that the rank below refers to: (key, local id), sorted by key.
 *
 * Keys: key = ((k * N1 + j) * N0 + i) * 8 + kind in the global marched grid,
 * (i, j, k) the lower end of the edge (the lowest corner of a face), kind
 * 0/1/2 the x/y/z edge, 3/4/5 the diagonal of the x/y/z face (tetra).
 */
#ifndef ISOMEND_MPI_SLAB_H
#define ISOMEND_MPI_SLAB_H

#include <stddef.h>
#include <stdint.h>

#include "cli.h"

#define SLAB_FOREIGN (UINT64_C(1) << 63)

typedef struct slab_piece {
    int64_t first, end;         /* owned marched slices [first, end)                 */
    size_t nv;
    float *pos, *nrm;           /* 3 floats per owned vertex; nrm NULL without normals */
    uint64_t *keys;             /* NULL when one rank owns everything                 */
    size_t nt;
    uint64_t *tri;              /* 3 ids per owned triangle                           */
    uint8_t *org;               /* one isomend_origin per triangle                    */
    size_t nforeign;
    uint64_t *foreign_keys;
    float *foreign_pos;
    size_t nshared;
    uint64_t *shared;           /* pairs (key, local id), sorted by key               */
    isomend_stats stats;        /* of the owned slices and layers                     */
} slab_piece;

/* Marched slices [*first, *end) of `rank` among `ranks` for a grid of nz_marched. */
void slab_split(int64_t nz_marched, int ranks, int rank, int64_t *first, int64_t *end);

/*
 * Extracts the owned part of the marched slices [first, end) of the source
 * (reading only them and their halo).  Exit code; the message goes through
 * cli_error().  On failure the piece is empty.
 */
int slab_extract(cli_slices *s, const isomend_options *opts, int64_t first, int64_t end,
                 slab_piece *p);

void slab_piece_free(slab_piece *p);

#endif /* ISOMEND_MPI_SLAB_H */
