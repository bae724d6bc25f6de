/*
 * mpi_writer.h - one PLY/OBJ/STL file written by every rank at once (io/mpi)
 *
 * The file is the header, then section 0 of every vertex (PLY records, OBJ
 * "v" lines), then section 1 (OBJ "vn" lines), then every face record, each
 * section the concatenation of the ranks' parts in rank order
 * (mesh_writer.h's record encoders, so the bytes are `isomend extract`'s).
 *
 * A rank encodes its part while its slab streams (slab.c), into scratch
 * files beside the output: vertex records as the vertices come; STL facets
 * as the triangles come (the writer keeps the positions a later facet may
 * use, from the last retire() floor on, and the next slab's vertices that
 * the last layer uses); PLY and OBJ triangles as raw local ids (24 bytes
 * each), encoded into section 2 once the global ids are known
 * (mpi_writer_faces()).  Then the ranks learn where their bytes go from
 * prefix sums of the sizes (MPI_Exscan) and write them with
 * MPI_File_write_at_all in rounds of at most 4 MiB per rank.  No rank ever
 * holds its own mesh, let alone another rank's: the memory is
 * MPI_WRITER_MEMORY plus, for STL, the positions of two slices' vertices.
 *
 * The functions but mpi_writer_write() are local and print their failure
 * through cli_error(); mpi_writer_write() is collective over `comm` (every
 * rank calls it, also after a local failure, so that no rank waits for
 * ever).  All return an exit code; the caller agrees on failures afterwards.
 */
#ifndef ISOMEND_MPI_WRITER_H
#define ISOMEND_MPI_WRITER_H

#include <mpi.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "mesh_writer.h"

/* A triangle corner on the next slab's first plane: MPI_WRITER_FOREIGN | f. */
#define MPI_WRITER_FOREIGN (UINT64_C(1) << 63)

/* The writer's own buffers: four scratch buffers, the faces pass's batch
 * and the write rounds' buffer (stdio's buffers of the scratch files are
 * small next to them). */
#define MPI_WRITER_MEMORY (4u * (256u << 10) + 3u * 8u * 65536u + (4u << 20))

typedef struct mpi_section {
    FILE *fp;
    unsigned char *buf;
    size_t used;
    uint64_t size;              /* bytes put, buffered ones included           */
} mpi_section;

typedef struct mpi_writer {
    isomend_mesh_format format;
    int normals;
    const char *final_path;     /* for scratch files and messages             */
    mpi_section section[3];     /* this rank's encoded bytes                   */
    mpi_section spool;          /* PLY/OBJ: raw triangle ids until mpi_writer_faces() */
    uint64_t nv, nt;            /* vertices and triangles put so far           */
    float *window;              /* STL: positions of local ids [window_first, nv) */
    uint64_t window_first;
    size_t window_cap;          /* in vertices                                 */
    float *foreign;             /* STL: positions of the foreign vertices      */
    size_t nforeign, foreign_cap;
    uint64_t size_total;        /* every rank's sections (after mpi_writer_write) */
} mpi_writer;

/* Opens the scratch files beside w->final_path (format, normals and
 * final_path set by the caller, the rest zero). */
int mpi_writer_open(mpi_writer *w);

/* Encodes `count` vertices (local ids from w->nv on); nrm NULL without normals. */
int mpi_writer_vertices(mpi_writer *w, size_t count, const float *pos, const float *nrm);

/* The positions of foreign vertices [first, first + count) (kept for STL only). */
int mpi_writer_foreign(mpi_writer *w, size_t first, size_t count, const float *pos);

/* Puts `count` triangles: local ids, or MPI_WRITER_FOREIGN | f. */
int mpi_writer_triangles(mpi_writer *w, size_t count, const uint64_t *ids);

/* No later triangle uses a local id below `floor` (STL forgets those positions). */
int mpi_writer_retire(mpi_writer *w, uint64_t floor);

/* PLY/OBJ: encodes the spooled triangles with global ids, local id i as
 * first_id + i and foreign vertex f as foreign_ids[f].  Then flushes every
 * section: the writer is ready for mpi_writer_write(). */
int mpi_writer_faces(mpi_writer *w, uint64_t first_id, const uint64_t *foreign_ids);

/*
 * Writes the header (rank 0; `header` of header_size bytes) and every
 * rank's sections into the open file `fh`.  Collective; `failed` non-zero
 * when this rank has nothing valid to write (it still takes part).
 */
int mpi_writer_write(mpi_writer *w, MPI_Comm comm, MPI_File fh, const unsigned char *header,
                     size_t header_size, int failed);

/* Closes the scratch files and frees the buffers.  Local; accepts a closed writer. */
void mpi_writer_close(mpi_writer *w);

#endif /* ISOMEND_MPI_WRITER_H */
