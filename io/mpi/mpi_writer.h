/*
 * mpi_writer.h - one PLY/OBJ/STL file written by every rank at once (io/mpi)
 *
 * The file is the header, then section 0 of every vertex (PLY records, OBJ
 * "v" lines), then section 1 (OBJ "vn" lines), then every face record, each
 * section the concatenation of the ranks' parts in rank order
 * (mesh_writer.h's record encoders, so the bytes are `isomend extract`'s).
 * Each rank encodes its part into scratch files beside the output, the
 * ranks learn where their bytes go from prefix sums of the sizes
 * (MPI_Exscan), and they write them with MPI_File_write_at_all in rounds of
 * at most 4 MiB per rank.  No rank ever holds another rank's mesh.
 *
 * Every function is collective over `comm` (all ranks call it, also after a
 * local failure, so that no rank waits for ever) and returns the local exit
 * code; the caller agrees on failures afterwards.
 */
#ifndef ISOMEND_MPI_WRITER_H
#define ISOMEND_MPI_WRITER_H

#include <mpi.h>
#include <stdint.h>
#include <stdio.h>

#include "mesh_writer.h"
#include "slab.h"

typedef struct mpi_writer {
    isomend_mesh_format format;
    int normals;
    const char *final_path;     /* for scratch files and messages           */
    FILE *section[3];           /* this rank's encoded bytes                 */
    uint64_t size[3];
    uint64_t size_total;        /* every rank's sections (after mpi_writer_write) */
} mpi_writer;

/*
 * Encodes this rank's piece: vertex ids from `first_id`, foreign corners
 * from `foreign_ids` (global ids of the piece's foreign keys).  Local; the
 * writer is ready for mpi_writer_write afterwards (or closed on failure).
 */
int mpi_writer_encode(mpi_writer *w, const slab_piece *p, uint64_t first_id,
                      const uint64_t *foreign_ids);

/*
 * Writes the header (rank 0; `header` of header_size bytes) and every
 * rank's sections into the open file `fh`.  Collective; `failed` non-zero
 * when this rank has nothing valid to write (it still takes part).
 */
int mpi_writer_write(mpi_writer *w, MPI_Comm comm, MPI_File fh, const unsigned char *header,
                     size_t header_size, int failed);

/* Closes the scratch files.  Local; accepts a closed writer. */
void mpi_writer_close(mpi_writer *w);

#endif /* ISOMEND_MPI_WRITER_H */
