/*
 * mesh_format.h - the mesh file formats isomend writes and reads (PLY, OBJ,
 * STL), named apart from the whole-mesh functions (mesh_io.h) and the
 * streaming writer (mesh_writer.h), which both use them.
 */
#ifndef ISOMEND_MESH_FORMAT_H
#define ISOMEND_MESH_FORMAT_H

#ifdef __cplusplus
extern "C" {
#endif

typedef enum isomend_mesh_format {
    ISOMEND_MESH_UNKNOWN = 0,
    ISOMEND_MESH_PLY = 1,
    ISOMEND_MESH_OBJ = 2,
    ISOMEND_MESH_STL = 3
} isomend_mesh_format;

/* The format for a path's extension, ISOMEND_MESH_UNKNOWN if none matches
 * (mesh_format.c). */
isomend_mesh_format isomend_mesh_format_of(const char *path);

#ifdef __cplusplus
}
#endif

#endif
