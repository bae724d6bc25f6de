/*
 * label_writer.c - several labels' surfaces in one PLY or OBJ file (see
 * label_writer.h)
 */
#define _POSIX_C_SOURCE 200809L

#include "label_writer.h"

#include "atomic_file.h"
#include "byte_order.h"
#include "isomend.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define SET_MSG isomend_fileio_set_msg

static int write_ply(FILE *fp, const label_mesh_part *parts, size_t n, int normals)
{
    uint64_t nv = 0, nt = 0;
    int negative = 0;
    for (size_t p = 0; p < n; p++) {
        nv += parts[p].nv;
        nt += parts[p].nt;
        negative |= parts[p].value < 0;
    }
    if (nv > UINT32_MAX || nt > UINT32_MAX) return -1;
    fprintf(fp,
            "ply\nformat binary_little_endian 1.0\ncomment written by isomend %s: %zu labels\n"
            "element vertex %" PRIu64 "\nproperty float x\nproperty float y\nproperty float z\n",
            isomend_version(), n, nv);
    if (normals) fprintf(fp, "property float nx\nproperty float ny\nproperty float nz\n");
    fprintf(fp,
            "element face %" PRIu64 "\nproperty list uchar uint vertex_indices\n"
            "property %s label\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
            "end_header\n",
            nt, negative ? "int" : "uint");
    unsigned char rec[24];
    for (size_t p = 0; p < n; p++)
        for (size_t v = 0; v < parts[p].nv; v++) {
            for (int c = 0; c < 3; c++) put_le32(rec + 4 * c, parts[p].pos + 3 * v + c);
            if (normals)
                for (int c = 0; c < 3; c++) put_le32(rec + 12 + 4 * c, parts[p].nrm + 3 * v + c);
            if (fwrite(rec, normals ? 24 : 12, 1, fp) != 1) return 0;
        }
    uint64_t base = 0;
    for (size_t p = 0; p < n; p++) {
        const int32_t label32 = (int32_t)parts[p].value;
        const uint32_t ulabel = (uint32_t)parts[p].value;
        for (size_t t = 0; t < parts[p].nt; t++) {
            unsigned char f[20];
            f[0] = 3;
            for (int c = 0; c < 3; c++) {
                const uint32_t id = (uint32_t)(base + parts[p].tri[3 * t + c]);
                put_le32(f + 1 + 4 * c, &id);
            }
            if (negative)
                put_le32(f + 13, &label32);
            else
                put_le32(f + 13, &ulabel);
            memcpy(f + 17, parts[p].rgb, 3);
            if (fwrite(f, 20, 1, fp) != 1) return 0;
        }
        base += parts[p].nv;
    }
    return 1;
}

void label_mtl_path(const char *obj, char *out, size_t size)
{
    snprintf(out, size, "%s", obj);
    char *dot = strrchr(out, '.');
    char *slash = strrchr(out, '/');
    if (dot && (!slash || dot > slash)) *dot = '\0';
    strncat(out, ".mtl", size - strlen(out) - 1);
}

static int write_obj(FILE *fp, FILE *mtl, const char *mtl_name, const label_mesh_part *parts,
                     size_t n, int normals)
{
    fprintf(fp, "# written by isomend %s: %zu labels\nmtllib %s\n", isomend_version(), n, mtl_name);
    fprintf(mtl, "# written by isomend %s\n", isomend_version());
    uint64_t base = 1;
    for (size_t p = 0; p < n; p++) {
        const label_mesh_part *q = &parts[p];
        fprintf(fp, "o %s\ng %s\nusemtl %s\n", q->name, q->name, q->name);
        fprintf(mtl, "newmtl %s\nKd %.6f %.6f %.6f\n", q->name, q->rgb[0] / 255.0,
                q->rgb[1] / 255.0, q->rgb[2] / 255.0);
        for (size_t v = 0; v < q->nv; v++)
            fprintf(fp, "v %.9g %.9g %.9g\n", q->pos[3 * v], q->pos[3 * v + 1], q->pos[3 * v + 2]);
        if (normals)
            for (size_t v = 0; v < q->nv; v++)
                fprintf(fp, "vn %.9g %.9g %.9g\n", q->nrm[3 * v], q->nrm[3 * v + 1],
                        q->nrm[3 * v + 2]);
        for (size_t t = 0; t < q->nt; t++) {
            const uint64_t a = base + q->tri[3 * t], b = base + q->tri[3 * t + 1],
                           c = base + q->tri[3 * t + 2];
            if (normals)
                fprintf(fp,
                        "f %" PRIu64 "//%" PRIu64 " %" PRIu64 "//%" PRIu64 " %" PRIu64 "//%" PRIu64
                        "\n",
                        a, a, b, b, c, c);
            else
                fprintf(fp, "f %" PRIu64 " %" PRIu64 " %" PRIu64 "\n", a, b, c);
        }
        base += q->nv;
    }
    return !ferror(fp) && !ferror(mtl);
}

int label_meshes_write(const char *path, isomend_mesh_format fmt, const label_mesh_part *parts,
                       size_t n, int normals, char *msg, size_t msg_size)
{
    isomend_atomic_file af, am;
    if (isomend_atomic_open(&af, path, msg, msg_size) != ISOMEND_FILEIO_OK) return 1;
    if (fmt == ISOMEND_MESH_PLY) {
        const int ok = write_ply(af.fp, parts, n, normals);
        if (ok <= 0) {
            if (ok < 0)
                SET_MSG(msg, msg_size,
                        "%s: more than 2^32 - 1 vertices or triangles (use -o "
                        "FOLDER/ for one file a label)",
                        path);
            else
                SET_MSG(msg, msg_size, "%s: write failed: %s", path, strerror(errno));
            isomend_atomic_abort(&af);
            return 1;
        }
        return isomend_atomic_commit(&af, msg, msg_size) != ISOMEND_FILEIO_OK;
    }
    char mpath[ISOMEND_FILEIO_PATH_MAX];
    label_mtl_path(path, mpath, sizeof mpath);
    if (isomend_atomic_open(&am, mpath, msg, msg_size) != ISOMEND_FILEIO_OK) {
        isomend_atomic_abort(&af);
        return 1;
    }
    const char *slash = strrchr(mpath, '/');
    if (!write_obj(af.fp, am.fp, slash ? slash + 1 : mpath, parts, n, normals)) {
        SET_MSG(msg, msg_size, "%s: write failed: %s", path, strerror(errno));
        isomend_atomic_abort(&af);
        isomend_atomic_abort(&am);
        return 1;
    }
    if (isomend_atomic_commit(&am, msg, msg_size) != ISOMEND_FILEIO_OK) {
        isomend_atomic_abort(&af);
        return 1;
    }
    if (isomend_atomic_commit(&af, msg, msg_size) != ISOMEND_FILEIO_OK) {
        unlink(mpath); /* the pair or nothing */
        return 1;
    }
    return 0;
}
