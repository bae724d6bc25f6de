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
 * A slab streams: its slices are read one at a time and pushed to the
 * core's piece (isomend_piece_begin), whose vertices and triangles go
 * straight to the rank's mpi_writer (local vertex ids 0..nv-1; a corner on
 * the next slab's first plane is MPI_WRITER_FOREIGN | f).  What the rank
 * keeps for the stitching is one plane's worth: `foreign_keys`, the keys of
 * those next-slab vertices, and `shared`, the owned vertices of the slab's
 * first plane that the rank below refers to, as (key, local id) pairs
 * sorted by key.  So a rank's memory does not depend on its slab's length
 * (slab_memory()).
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
#include "mpi_writer.h"

typedef struct slab_piece {
    int64_t first, end;         /* owned marched slices [first, end)                 */
    uint64_t nv, nt;            /* owned vertices and triangles                       */
    size_t nforeign;
    uint64_t *foreign_keys;     /* the next slab's vertices the last layer uses       */
    size_t nshared;
    uint64_t *shared;           /* pairs (key, local id), sorted by key               */
    isomend_stats stats;        /* of the owned slices and layers                     */
} slab_piece;

/* Marched slices [*first, *end) of `rank` among `ranks` for a grid of nz_marched. */
void slab_split(int64_t nz_marched, int ranks, int rank, int64_t *first, int64_t *end);

/*
 * The most memory a rank's extraction holds for the volume `s` (its slices
 * of slice_bytes), whatever its slab: the core piece's bound, a slice read
 * twice, the writer's buffers, and the plane tables above (each at most a
 * slice's vertex bound long), with the STL positions and the patient-space
 * map's batch where they apply.  0 for volumes the core refuses.
 */
uint64_t slab_memory(const cli_source *s, const isomend_options *opts, isomend_mesh_format format);

/*
 * Streams the marched slices [first, end) of the source (reading only them
 * and their halo) into `w` (open), mapped by `world` into patient space
 * when it is not NULL.  Exit code; the message goes through cli_error().
 * On failure the piece is empty.
 */
int slab_extract(cli_source *s, const isomend_options *opts, const cli_world *world,
                 int64_t first, int64_t end, mpi_writer *w, slab_piece *p);

/* The same streaming of marched slices [first, end) into any piece sink
 * (mpi_decimate.c's recorder); *sink_failed: the sink printed why it
 * stopped.  Exit code; *stats the piece's. */
int slab_stream(cli_source *s, const isomend_options *opts, int64_t first, int64_t end,
                const isomend_mesh_sink *sink, const int *sink_failed, isomend_stats *stats);

void slab_piece_free(slab_piece *p);

#endif /* ISOMEND_MPI_SLAB_H */
