/*
 * mpi_decimate.h - `isomend-mpi extract --decimate RATIO` (io/mpi)
 *
 * The ranks extract their slabs in parallel as always, but each records its
 * piece's sink calls (vertices, triangles, retire, foreign keys) into a
 * scratch spool beside the output instead of encoding them.  Then rank 0
 * replays the pieces in rank order as the one stream `isomend extract`
 * would have made (global ids by prefix sums, the next slab's first plane
 * delivered where the single stream delivers it, foreign corners mapped by
 * key) into the core's streamed decimation (isomend_decimate_stream_*),
 * whose output goes through the streaming check to one writer, exactly as
 * `isomend extract --stream --decimate RATIO` does: the same bytes for every
 * number of ranks.  Each rank sends its spool to rank 0 in blocks when rank
 * 0 reaches it, so rank 0 holds a window of the decimation and a block, and
 * no rank its mesh.  The decimation itself runs on rank 0, after the
 * parallel extraction.
 */
#ifndef ISOMEND_MPI_DECIMATE_H
#define ISOMEND_MPI_DECIMATE_H

#include <mpi.h>
#include <stdint.h>
#include <stdio.h>

#include "cli.h"

/* A rank's recording of its piece (spool: a scratch file beside the output). */
typedef struct dec_spool {
    FILE *fp;
    const char *final_path;
    uint64_t plane;   /* N0 * N1: a key's slice is (key >> 3) / plane  */
    int64_t first;    /* the slab's first marched slice                */
    uint64_t nv;      /* vertices recorded                             */
    uint64_t nt;      /* triangles recorded                            */
    int64_t layers;   /* retire calls recorded                         */
    int in_first;     /* still in the first slice's vertices           */
    uint64_t nfirst;  /* the first slice's vertices (a prefix of the ids) */
    uint64_t *first_keys;
    float *first_pos;
    size_t first_cap;
    int failed;       /* the message is printed                        */
    int nonempty;     /* the slab has slices (set by the caller)       */
} dec_spool;

/* Opens the spool (final_path: the output, for the scratch file's place). */
int dec_spool_open(dec_spool *s, const char *final_path, uint64_t plane, int64_t first);
void dec_spool_close(dec_spool *s);

/* The core sink that records into the spool (for isomend_piece_begin). */
void dec_spool_sink(dec_spool *s, isomend_mesh_sink *sink);

/*
 * Collective: rank 0 replays every rank's spool (in rank order, with
 * nv[r], nfirst via messages) into `out` (rank 0's sink: the decimation);
 * the other ranks send theirs.  Exit code (each rank's own; the caller
 * agrees).
 */
int dec_replay(MPI_Comm comm, dec_spool *s, const isomend_mesh_sink *out);

#endif /* ISOMEND_MPI_DECIMATE_H */
