/*
 * mesh_format.c - the format a mesh path names (mesh_format.h), for the
 * whole-mesh functions (mesh_io.c) and the streaming writer (mesh_writer.c)
 * alike.
 */
#define _POSIX_C_SOURCE 200809L

#include "mesh_format.h"

#include <string.h>
#include <strings.h>

isomend_mesh_format isomend_mesh_format_of(const char *path)
{
    if (!path) return ISOMEND_MESH_UNKNOWN;
    const char *dot = strrchr(path, '.');
    const char *slash = strrchr(path, '/');
    if (!dot || (slash && dot < slash)) return ISOMEND_MESH_UNKNOWN;
    if (strcasecmp(dot, ".ply") == 0) return ISOMEND_MESH_PLY;
    if (strcasecmp(dot, ".obj") == 0) return ISOMEND_MESH_OBJ;
    if (strcasecmp(dot, ".stl") == 0) return ISOMEND_MESH_STL;
    return ISOMEND_MESH_UNKNOWN;
}
