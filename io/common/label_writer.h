/*
 * label_writer.h - several labels' surfaces in one file (io/common)
 *
 *   .ply  binary little endian; vertex x y z [nx ny nz] (float); face
 *         "list uchar uint vertex_indices", the label ("int label", or
 *         "uint label" when no value is negative) and its colour ("uchar
 *         red green blue"): each label's vertices follow the previous
 *         label's, its triangles keep their own vertices.
 *   .obj  "mtllib BASE.mtl", then for each label "o NAME", "g NAME",
 *         "usemtl NAME", its v [vn] and f lines (1-based, global); the .mtl
 *         beside it has one "newmtl NAME" with "Kd R G B" a label.
 * Both go through temporary files renamed at the end (atomic_file.h): a
 * failure leaves neither file.  STL has no groups: not written here.
 */
#ifndef ISOMEND_LABEL_WRITER_H
#define ISOMEND_LABEL_WRITER_H

#include <stddef.h>
#include <stdint.h>

#include "mesh_format.h"

typedef struct label_mesh_part {
    const float *pos, *nrm; /* nrm NULL: no normals */
    size_t nv;
    const uint32_t *tri;
    size_t nt;
    int64_t value;
    const char *name; /* the group and material name (no spaces) */
    uint8_t rgb[3];
} label_mesh_part;

/* The .mtl an .obj names: the same folder and stem. */
void label_mtl_path(const char *obj, char *out, size_t size);

/* Writes parts[0 .. n) to path (PLY or OBJ, by fmt); normals when
 * `normals` (every part then has nrm).  0, or 1 with the message naming the
 * file in msg and nothing left. */
int label_meshes_write(const char *path, isomend_mesh_format fmt, const label_mesh_part *parts,
                       size_t n, int normals, char *msg, size_t msg_size);

#endif
