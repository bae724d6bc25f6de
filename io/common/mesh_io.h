/*
 * mesh_io.h - triangle mesh files for isomend (io/common, library isomend_fileio)
 *
 * Writers (format chosen by the extension, any case):
 *   .ply  binary little endian: vertex float x y z [nx ny nz],
 *         face "property list uchar uint vertex_indices";
 *   .obj  "v x y z", "vn nx ny nz", faces "f a//a b//b c//c" (1-based);
 *   .stl  binary, facet normals from the triangle's geometry (STL cannot
 *         carry vertex normals).
 * Every writer goes through a temporary file in the target folder that is
 * renamed at the end (see atomic_file.h): no partial file is ever visible.
 *
 * Readers (for `isomend check`, so they accept what other tools write):
 *   .ply  ascii, binary_little_endian and binary_big_endian; any element
 *         order, any extra properties (colours, quality, texture lists) and
 *         any scalar types; faces from "vertex_indices" or "vertex_index"
 *         lists; polygons are fan-split into triangles.
 *   .obj  "v", and faces in the forms a, a/b, a/b/c, a//c, with negative
 *         (relative) indices; polygons fan-split; other statements ignored.
 *   .stl  ascii and binary (a binary file whose header starts with "solid"
 *         is recognised by its exact size); vertices are welded by exact
 *         position (-0 and +0 are the same position), since STL stores every
 *         triangle's corners separately.
 * Indices outside the vertex list are errors naming the face.
 *
 * Errors follow volume_readers.h: a status and a one-line message naming
 * the file.  No global state.
 */
#ifndef ISOMEND_MESH_IO_H
#define ISOMEND_MESH_IO_H

#include <stddef.h>
#include <stdint.h>

#include "mesh_format.h"
#include "volume_readers.h"

#ifdef __cplusplus
extern "C" {
#endif

/*
 * Writes a triangle mesh.  `normals` may be NULL (no normals in PLY/OBJ).
 * `format` ISOMEND_MESH_UNKNOWN means "from the extension".
 */
isomend_fileio_status isomend_write_mesh(const char *path, isomend_mesh_format format,
                                         const float *positions, const float *normals,
                                         size_t vertex_count, const uint32_t *triangles,
                                         size_t triangle_count, char *msg, size_t msg_size);

/* A mesh read from a file; release with isomend_read_mesh_free(). */
typedef struct isomend_read_mesh_result {
    float *positions;        /* 3 per vertex                                    */
    uint32_t *triangles;     /* 3 per triangle                                  */
    size_t vertex_count;
    size_t triangle_count;
    uint64_t polygons_split; /* faces with 4+ corners that were fan-split       */
    uint64_t faces_skipped;  /* faces with fewer than 3 corners (ignored)       */
    uint64_t stl_facets;     /* STL: triangles before welding, else 0           */
    isomend_mesh_format format;
    char encoding[24];       /* "ascii", "binary_little_endian", "binary", ... */
} isomend_read_mesh_result;

isomend_fileio_status isomend_read_mesh(const char *path, isomend_read_mesh_result *out,
                                        char *msg, size_t msg_size);

/* Frees the arrays and zeroes the struct; accepts NULL. */
void isomend_read_mesh_free(isomend_read_mesh_result *mesh);

#ifdef __cplusplus
}
#endif

#endif /* ISOMEND_MESH_IO_H */
