/*
 * mesh_writer.h - PLY, OBJ and STL written while the mesh is produced (io/common)
 *
 * One implementation for every mesh isomend writes: the whole-mesh
 * isomend_write_mesh() (mesh_io.h) is a client of this writer, so a mesh
 * gives the same file, byte for byte, whether it was written at once or in
 * batches of any size while a volume larger than memory was being marched.
 *
 *   isomend_mesh_writer_begin(path, format, normals, 0, &w, msg, n);
 *   loop: isomend_mesh_writer_vertices(w, count, positions, normals);
 *         isomend_mesh_writer_triangles(w, count, ids);   (ids < vertices so far)
 *         isomend_mesh_writer_retire(w, floor);           (optional, see below)
 *   isomend_mesh_writer_commit(w, msg, n);  or  isomend_mesh_writer_abort(w);
 *
 * Vertex ids are implicit: the first vertex of a batch has the number of
 * vertices written before it.  Triangle ids are 64-bit, so that a mesh whose
 * ids exceed a format's 32-bit indices fails here, clearly, and never wraps.
 *
 * File layout (the same as the whole-mesh writer always produced, except the
 * header's padding):
 *   .ply  a header of FIXED length for the format and the normals flag: the
 *         third line "comment written by isomend VERSION" is padded with
 *         spaces so that it and the two decimal counts ("element vertex N",
 *         "element face N") always take the same number of bytes; binary
 *         little endian float x y z [nx ny nz] records follow it directly;
 *         faces ("property list uchar uint vertex_indices", 13 bytes each)
 *         go to a scratch file in the target folder and are appended at the
 *         end (or straight to the file after isomend_mesh_writer_end_vertices);
 *         the header is rewritten with the counts at the end.
 *   .obj  a first comment line of fixed length with the counts, "v" lines
 *         directly, "vn" and "f" lines (f a//a b//b c//c, 1-based) to
 *         scratch files, concatenated at the end.
 *   .stl  binary: an 80-byte header, the triangle count at byte 80 (patched
 *         at the end), 50-byte facets written as the triangles come, with
 *         facet normals from the geometry.  The writer keeps the positions a
 *         later facet may use: all of them, unless the producer retires ids.
 * Scratch files are unlinked as soon as they are created (atomic_file.h), and
 * the output goes to a temporary file renamed at commit: a failure, an abort
 * or a killed process never leaves a partial mesh or a scratch file.
 *
 * Limits: PLY and binary STL store 32-bit counts and PLY 32-bit indices, so a
 * mesh has at most 4294967295 (2^32 - 1) vertices (PLY) and triangles (PLY,
 * STL); the call that would exceed it fails with a message naming the file
 * and suggesting OBJ, which has no limit.  (VTK, MeshLab and Blender read
 * PLY counts as signed 32-bit integers: they fail beyond 2^31 - 1 already.)
 *
 * Errors: every call returns a status; after the first failure every call
 * returns it again, and isomend_mesh_writer_message() holds one line naming
 * the file and the reason (e.g. "out/m.ply: write failed: No space left on
 * device").  A writer is used by one thread at a time.
 */
#ifndef ISOMEND_MESH_WRITER_H
#define ISOMEND_MESH_WRITER_H

#include <stddef.h>
#include <stdint.h>

#include "mesh_format.h"
#include "volume_readers.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct isomend_mesh_writer isomend_mesh_writer;

/* The arrays passed to isomend_mesh_writer_vertices() stay valid until commit
 * or abort: STL then reads positions from them instead of keeping a copy. */
#define ISOMEND_MESH_WRITER_BORROW 1u

/*
 * Creates the temporary output next to `path` (nothing else is created until
 * a scratch file is needed).  `format` ISOMEND_MESH_UNKNOWN means "from the
 * extension".  `normals` non-zero: every vertex batch carries normals (PLY
 * and OBJ store them; STL ignores them).  On failure *out is NULL and `msg`
 * names the file.
 */
isomend_fileio_status isomend_mesh_writer_begin(const char *path, isomend_mesh_format format,
                                                int normals, unsigned flags,
                                                isomend_mesh_writer **out, char *msg,
                                                size_t msg_size);

/* Appends `count` vertices: 3 floats each in `positions`, and in `normals`
 * when the writer was begun with normals (ignored otherwise). */
isomend_fileio_status isomend_mesh_writer_vertices(isomend_mesh_writer *w, size_t count,
                                                   const float *positions, const float *normals);

/* Appends `count` triangles, 3 vertex ids each, every id < the vertices so
 * far and >= the last retire floor.  The _u32 form takes 32-bit ids. */
isomend_fileio_status isomend_mesh_writer_triangles(isomend_mesh_writer *w, size_t count,
                                                    const uint64_t *ids);
isomend_fileio_status isomend_mesh_writer_triangles_u32(isomend_mesh_writer *w, size_t count,
                                                        const uint32_t *ids);

/* A promise that no later triangle uses an id below `floor`: STL forgets the
 * positions below it (memory stays O(a few slices) while streaming). */
isomend_fileio_status isomend_mesh_writer_retire(isomend_mesh_writer *w, uint64_t floor);

/* No more vertices: the scratch data is appended now and later triangles go
 * straight to the file (no scratch file at all when no triangle came before).
 * Optional; commit does it. */
isomend_fileio_status isomend_mesh_writer_end_vertices(isomend_mesh_writer *w);

/* Completes the file (scratch data appended, counts written), renames it
 * over `path` and frees the writer, in every case.  On failure nothing is
 * left and `msg` (may be NULL) receives the message. */
isomend_fileio_status isomend_mesh_writer_commit(isomend_mesh_writer *w, char *msg,
                                                 size_t msg_size);

/* Removes everything and frees the writer.  Accepts NULL. */
void isomend_mesh_writer_abort(isomend_mesh_writer *w);

/* The message of the first failure ("" if none).  Owned by the writer. */
const char *isomend_mesh_writer_message(const isomend_mesh_writer *w);

uint64_t isomend_mesh_writer_vertex_count(const isomend_mesh_writer *w);

/* ---- the records, for writers that place bytes themselves (isomend-mpi) ----
 *
 * A file is: the header, then section 0 of every vertex, then section 1 of
 * every vertex, then the face record of every triangle, with nothing between.
 */

/* Largest record any encoder below produces, in bytes. */
#define ISOMEND_MESH_RECORD_MAX 192

/* The header's length: fixed for a format and normals flag (0 for an unknown format). */
size_t isomend_mesh_header_size(isomend_mesh_format format, int normals);

/* The most vertices / triangles a format can hold (UINT64_MAX for no limit). */
uint64_t isomend_mesh_max_vertices(isomend_mesh_format format);
uint64_t isomend_mesh_max_triangles(isomend_mesh_format format);

/*
 * Formats the header for the final counts into `out` (header_size bytes).
 * Fails with ISOMEND_FILEIO_ERR_INVALID_ARGUMENT (message naming `path`)
 * when the counts exceed the format's limits.
 */
isomend_fileio_status isomend_mesh_header(isomend_mesh_format format, int normals,
                                          uint64_t vertex_count, uint64_t triangle_count,
                                          unsigned char *out, const char *path, char *msg,
                                          size_t msg_size);

/* Section 0 / section 1 bytes of one vertex (nrm NULL without normals);
 * return the length written to `out`, possibly 0. */
size_t isomend_mesh_encode_vertex(isomend_mesh_format format, const float *pos, const float *nrm,
                                  unsigned char *out);
size_t isomend_mesh_encode_normal(isomend_mesh_format format, const float *nrm,
                                  unsigned char *out);

/* The face record of one triangle: `ids` (0-based) for PLY/OBJ, the corner
 * positions `corner` for STL (may be NULL for the others). */
size_t isomend_mesh_encode_face(isomend_mesh_format format, int normals, const uint64_t ids[3],
                                const float *const corner[3], unsigned char *out);

#ifdef __cplusplus
}
#endif

#endif /* ISOMEND_MESH_WRITER_H */
