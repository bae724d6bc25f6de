/*
 * mesh_writer.c - PLY/OBJ/STL written while the mesh is produced (see mesh_writer.h)
 *
 * Why a fixed-length header: the counts are known only at the end, and the
 * vertices must follow the header directly.  Rewriting a header of the same
 * length in place is the only way that needs neither a second copy of the
 * vertex data nor knowledge of the counts in advance.  The padding sits in
 * a comment line, which every PLY reader skips (VTK, MeshLab's vcglib,
 * Blender's importer and ours: the peer tests read the files with them), so
 * the element lines keep the plain "element vertex N" form every reader
 * parses.  OBJ's counts are in a comment too, padded the same way.
 *
 * Why scratch files for the faces: PLY and OBJ put every vertex before the
 * first face, but a streaming extraction finishes triangles of layer k
 * before the vertices of slice k + 2 exist.  The faces wait in a scratch
 * file in the target folder (the same disk as the output; an unlinked file,
 * so it cannot be left behind) and are copied to the end at commit; the
 * whole-mesh writer calls isomend_mesh_writer_end_vertices() before its
 * triangles, so it writes them straight to the file and creates no scratch
 * file.  The bytes are the same either way.
 */
#define _GNU_SOURCE /* copy_file_range */

#include "mesh_writer.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "atomic_file.h"
#include "byte_order.h"

#define SET_MSG isomend_fileio_set_msg
#define STDIO_BUFFER (1u << 20)
#define COPY_CHUNK (1u << 20)

/* ------------------------------------------------------------------ records */

/* Appends the decimal digits of v to p; returns the new end. */
static char *put_uint(char *p, uint64_t v)
{
    char tmp[24];
    int n = 0;
    do {
        tmp[n++] = (char)('0' + v % 10);
        v /= 10;
    } while (v);
    while (n) *p++ = tmp[--n];
    return p;
}

static int digits(uint64_t v)
{
    int n = 1;
    while (v >= 10) {
        v /= 10;
        n++;
    }
    return n;
}

uint64_t isomend_mesh_max_vertices(isomend_mesh_format format)
{
    return format == ISOMEND_MESH_PLY ? UINT32_MAX : UINT64_MAX;
}

uint64_t isomend_mesh_max_triangles(isomend_mesh_format format)
{
    return format == ISOMEND_MESH_PLY || format == ISOMEND_MESH_STL ? UINT32_MAX : UINT64_MAX;
}

/* Digits the counts may take: two 32-bit counts (PLY), two 64-bit ones (OBJ). */
#define PLY_COUNT_DIGITS 20
#define OBJ_COUNT_DIGITS 40

/* Formats the header into out (NULL: only its length); returns its length. */
static size_t format_header(isomend_mesh_format format, int normals, uint64_t nv, uint64_t nt,
                            char *out, size_t out_size)
{
    if (format == ISOMEND_MESH_STL) {
        if (out) {
            memset(out, 0, 84);
            snprintf(out, 80, "binary STL written by isomend %s", isomend_version());
            uint32_t count = (uint32_t)nt;
            put_le32((unsigned char *)out + 80, &count);
        }
        return 84;
    }
    char pad[OBJ_COUNT_DIGITS + 1];
    int width = format == ISOMEND_MESH_PLY ? PLY_COUNT_DIGITS : OBJ_COUNT_DIGITS;
    int n = width - digits(nv) - digits(nt);
    if (n < 0) n = 0;
    memset(pad, ' ', (size_t)n);
    pad[n] = '\0';
    char tmp[1024];
    char *dst = out ? out : tmp;
    size_t size = out ? out_size : sizeof tmp;
    int len;
    if (format == ISOMEND_MESH_PLY)
        len = snprintf(dst, size,
                       "ply\nformat binary_little_endian 1.0\ncomment written by isomend %s%s\n"
                       "element vertex %llu\nproperty float x\nproperty float y\nproperty float z\n"
                       "%selement face %llu\nproperty list uchar uint vertex_indices\nend_header\n",
                       isomend_version(), pad, (unsigned long long)nv,
                       normals ? "property float nx\nproperty float ny\nproperty float nz\n" : "",
                       (unsigned long long)nt);
    else if (format == ISOMEND_MESH_OBJ)
        len = snprintf(dst, size, "# written by isomend %s: %llu vertices, %llu triangles%s\n",
                       isomend_version(), (unsigned long long)nv, (unsigned long long)nt, pad);
    else
        return 0;
    return len > 0 ? (size_t)len : 0;
}

size_t isomend_mesh_header_size(isomend_mesh_format format, int normals)
{
    return format_header(format, normals, 0, 0, NULL, 0);
}

static int check_counts(isomend_mesh_format format, uint64_t nv, uint64_t nt, const char *path,
                        char *msg, size_t msg_size)
{
    const char *name = format == ISOMEND_MESH_PLY ? "a PLY file" : "a binary STL file";
    if (nv > isomend_mesh_max_vertices(format)) {
        SET_MSG(msg, msg_size,
                "%s: the mesh has more than %llu vertices, the most %s can index (write .obj)",
                path, (unsigned long long)isomend_mesh_max_vertices(format), name);
        return -1;
    }
    if (nt > isomend_mesh_max_triangles(format)) {
        SET_MSG(msg, msg_size,
                "%s: the mesh has more than %llu triangles, the most %s can count (write .obj)",
                path, (unsigned long long)isomend_mesh_max_triangles(format), name);
        return -1;
    }
    return 0;
}

isomend_fileio_status isomend_mesh_header(isomend_mesh_format format, int normals,
                                          uint64_t vertex_count, uint64_t triangle_count,
                                          unsigned char *out, const char *path, char *msg,
                                          size_t msg_size)
{
    if (!out || isomend_mesh_header_size(format, normals) == 0) {
        SET_MSG(msg, msg_size, "%s: unknown mesh format", path ? path : "(null)");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (check_counts(format, vertex_count, triangle_count, path ? path : "(null)", msg, msg_size))
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    size_t size = isomend_mesh_header_size(format, normals);
    char tmp[1024];
    size_t n = format_header(format, normals, vertex_count, triangle_count, tmp, sizeof tmp);
    if (n != size) { /* cannot happen within the limits checked above */
        SET_MSG(msg, msg_size, "%s: header of %zu bytes instead of %zu", path, n, size);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    memcpy(out, tmp, size);
    return ISOMEND_FILEIO_OK;
}

/* OBJ is text: positions with 9 significant digits (float32 round-trips). */
static size_t obj_line(char kind, const float *v, unsigned char *out)
{
    int n = snprintf((char *)out, ISOMEND_MESH_RECORD_MAX, "%s %.9g %.9g %.9g\n",
                     kind == 'v' ? "v" : "vn", v[0], v[1], v[2]);
    return n > 0 ? (size_t)n : 0;
}

size_t isomend_mesh_encode_vertex(isomend_mesh_format format, const float *pos, const float *nrm,
                                  unsigned char *out)
{
    if (format == ISOMEND_MESH_PLY) {
        for (int c = 0; c < 3; c++) put_le32(out + 4 * c, &pos[c]);
        if (!nrm) return 12;
        for (int c = 0; c < 3; c++) put_le32(out + 12 + 4 * c, &nrm[c]);
        return 24;
    }
    if (format == ISOMEND_MESH_OBJ) return obj_line('v', pos, out);
    return 0;
}

size_t isomend_mesh_encode_normal(isomend_mesh_format format, const float *nrm,
                                  unsigned char *out)
{
    return format == ISOMEND_MESH_OBJ && nrm ? obj_line('n', nrm, out) : 0;
}

static size_t stl_facet(const float *const p[3], unsigned char *rec)
{
    double e1[3], e2[3], n[3];
    for (int c = 0; c < 3; c++) {
        e1[c] = (double)p[1][c] - p[0][c];
        e2[c] = (double)p[2][c] - p[0][c];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int c = 0; c < 3; c++) {
        float f = len > 0 ? (float)(n[c] / len) : 0.0f;
        put_le32(rec + 4 * c, &f);
    }
    for (int v = 0; v < 3; v++)
        for (int c = 0; c < 3; c++) put_le32(rec + 12 + 12 * v + 4 * c, &p[v][c]);
    rec[48] = rec[49] = 0;
    return 50;
}

size_t isomend_mesh_encode_face(isomend_mesh_format format, int normals, const uint64_t ids[3],
                                const float *const corner[3], unsigned char *out)
{
    if (format == ISOMEND_MESH_PLY) {
        out[0] = 3;
        for (int c = 0; c < 3; c++) {
            uint32_t v = (uint32_t)ids[c];
            put_le32(out + 1 + 4 * c, &v);
        }
        return 13;
    }
    if (format == ISOMEND_MESH_OBJ) {
        /* indices formatted by hand: printf costs ~3x more on million-face meshes */
        char *p = (char *)out;
        *p++ = 'f';
        for (int c = 0; c < 3; c++) {
            *p++ = ' ';
            p = put_uint(p, ids[c] + 1);
            if (normals) {
                *p++ = '/';
                *p++ = '/';
                p = put_uint(p, ids[c] + 1);
            }
        }
        *p++ = '\n';
        return (size_t)(p - (char *)out);
    }
    if (format == ISOMEND_MESH_STL) return stl_facet(corner, out);
    return 0;
}

/* ------------------------------------------------------------------ the writer */

/* Positions of a vertex batch that STL facets may still need. */
typedef struct pos_segment {
    uint64_t first;
    size_t count;
    const float *pos;
    float *owned; /* == pos when copied, NULL when borrowed */
} pos_segment;

struct isomend_mesh_writer {
    isomend_mesh_format format;
    int normals;
    unsigned flags;
    isomend_atomic_file af;  /* the output: header, then vertices, then faces  */
    FILE *spool_normals;     /* OBJ "vn" lines until the end                     */
    FILE *spool_faces;       /* faces that came before the last vertex           */
    int vertices_ended;      /* faces now go straight to af.fp                   */
    uint64_t nv, nt, floor;
    size_t header_size;
    pos_segment *segs;
    size_t nsegs, segs_cap;
    char *bufs[3];           /* stdio buffers of af.fp and the scratch files     */
    isomend_fileio_status status;
    char msg[ISOMEND_FILEIO_MSG_SIZE];
};

static isomend_fileio_status fail(isomend_mesh_writer *w, isomend_fileio_status st,
                                  const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

static isomend_fileio_status fail(isomend_mesh_writer *w, isomend_fileio_status st,
                                  const char *fmt, ...)
{
    if (w->status != ISOMEND_FILEIO_OK) return w->status; /* the first failure is kept */
    char detail[ISOMEND_FILEIO_MSG_SIZE - ISOMEND_FILEIO_PATH_MAX - 8];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(detail, sizeof detail, fmt, ap);
    va_end(ap);
    SET_MSG(w->msg, sizeof w->msg, "%s: %s", w->af.final_path, detail);
    w->status = st;
    return st;
}

static isomend_fileio_status write_failed(isomend_mesh_writer *w)
{
    int err = errno;
    return fail(w, ISOMEND_FILEIO_ERR_WRITE, "write failed: %s", strerror(err ? err : EIO));
}

static void buffer(isomend_mesh_writer *w, FILE *fp, int slot)
{
    w->bufs[slot] = malloc(STDIO_BUFFER);
    if (w->bufs[slot]) setvbuf(fp, w->bufs[slot], _IOFBF, STDIO_BUFFER);
}

static FILE *spool(isomend_mesh_writer *w, FILE **fp, int slot)
{
    if (*fp) return *fp;
    char m[ISOMEND_FILEIO_MSG_SIZE];
    if (isomend_spool_open(w->af.final_path, fp, m, sizeof m) != ISOMEND_FILEIO_OK) {
        if (w->status == ISOMEND_FILEIO_OK) {
            snprintf(w->msg, sizeof w->msg, "%s", m);
            w->status = ISOMEND_FILEIO_ERR_WRITE;
        }
        return NULL;
    }
    buffer(w, *fp, slot);
    return *fp;
}

isomend_fileio_status isomend_mesh_writer_begin(const char *path, isomend_mesh_format format,
                                                int normals, unsigned flags,
                                                isomend_mesh_writer **out, char *msg,
                                                size_t msg_size)
{
    if (!out) {
        SET_MSG(msg, msg_size, "isomend_mesh_writer_begin: NULL argument");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    *out = NULL;
    if (!path) {
        SET_MSG(msg, msg_size, "isomend_mesh_writer_begin: NULL path");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (format == ISOMEND_MESH_UNKNOWN) format = isomend_mesh_format_of(path);
    if (isomend_mesh_header_size(format, normals) == 0) {
        const char *dot = strrchr(path, '.');
        const char *slash = strrchr(path, '/');
        SET_MSG(msg, msg_size, "%s: unknown mesh format '%s' (use .ply, .obj or .stl)", path,
                dot && (!slash || dot > slash) ? dot : "(no extension)");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    isomend_mesh_writer *w = calloc(1, sizeof *w);
    if (!w) {
        SET_MSG(msg, msg_size, "%s: out of memory", path);
        return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
    }
    w->format = format;
    w->normals = normals ? 1 : 0;
    w->flags = flags;
    isomend_fileio_status st = isomend_atomic_open(&w->af, path, msg, msg_size);
    if (st != ISOMEND_FILEIO_OK) {
        free(w);
        return st;
    }
    buffer(w, w->af.fp, 0);
    w->header_size = isomend_mesh_header_size(format, w->normals);
    unsigned char head[1024];
    if (isomend_mesh_header(format, w->normals, 0, 0, head, path, msg, msg_size) !=
            ISOMEND_FILEIO_OK ||
        fwrite(head, 1, w->header_size, w->af.fp) != w->header_size) {
        write_failed(w);
        SET_MSG(msg, msg_size, "%s", w->msg);
        isomend_mesh_writer_abort(w);
        return ISOMEND_FILEIO_ERR_WRITE;
    }
    *out = w;
    return ISOMEND_FILEIO_OK;
}

static isomend_fileio_status keep_positions(isomend_mesh_writer *w, size_t count, const float *pos)
{
    if (w->nsegs == w->segs_cap) {
        size_t cap = w->segs_cap ? 2 * w->segs_cap : 16;
        pos_segment *s = realloc(w->segs, cap * sizeof *s);
        if (!s) return fail(w, ISOMEND_FILEIO_ERR_OUT_OF_MEMORY, "out of memory");
        w->segs = s;
        w->segs_cap = cap;
    }
    pos_segment *s = &w->segs[w->nsegs];
    s->first = w->nv;
    s->count = count;
    s->owned = NULL;
    s->pos = pos;
    if (!(w->flags & ISOMEND_MESH_WRITER_BORROW)) {
        if (count > SIZE_MAX / (3 * sizeof(float)) ||
            !(s->owned = malloc(count * 3 * sizeof(float))))
            return fail(w, ISOMEND_FILEIO_ERR_OUT_OF_MEMORY, "out of memory for %zu positions",
                        count);
        memcpy(s->owned, pos, count * 3 * sizeof(float));
        s->pos = s->owned;
    }
    w->nsegs++;
    return ISOMEND_FILEIO_OK;
}

/* Records encoded into a block and written a block at a time: one fwrite()
 * for a few thousand records instead of one each (the stream's writer
 * spent more time in fwrite()'s locking and copying than in encoding). */
typedef struct record_block {
    size_t used;
    unsigned char bytes[16384];
} record_block;

static int block_flush(record_block *b, FILE *fp)
{
    const size_t n = b->used;
    b->used = 0;
    return n == 0 || fwrite(b->bytes, 1, n, fp) == n;
}

/* Room for one more record, the block written first if need be. */
static int block_room(record_block *b, FILE *fp)
{
    return b->used + ISOMEND_MESH_RECORD_MAX <= sizeof b->bytes || block_flush(b, fp);
}

isomend_fileio_status isomend_mesh_writer_vertices(isomend_mesh_writer *w, size_t count,
                                                   const float *positions, const float *normals)
{
    if (!w) return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    if (w->status != ISOMEND_FILEIO_OK) return w->status;
    if (count == 0) return ISOMEND_FILEIO_OK;
    if (!positions || (w->normals && !normals))
        return fail(w, ISOMEND_FILEIO_ERR_INVALID_ARGUMENT, "vertices without %s",
                    positions ? "normals" : "positions");
    if (w->vertices_ended)
        return fail(w, ISOMEND_FILEIO_ERR_INVALID_ARGUMENT, "vertices after the last vertex");
    if ((uint64_t)count > isomend_mesh_max_vertices(w->format) - w->nv) {
        check_counts(w->format, UINT64_MAX, 0, w->af.final_path, w->msg, sizeof w->msg);
        w->status = ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
        return w->status;
    }
    const float *nrm = w->normals ? normals : NULL;
    if (w->format == ISOMEND_MESH_STL) {
        isomend_fileio_status st = keep_positions(w, count, positions);
        if (st != ISOMEND_FILEIO_OK) return st;
    } else {
        FILE *fp = w->af.fp, *fn = NULL;
        if (w->format == ISOMEND_MESH_OBJ && nrm && !(fn = spool(w, &w->spool_normals, 1)))
            return w->status;
        record_block b, bn;
        b.used = bn.used = 0;
        for (size_t v = 0; v < count; v++) {
            const float *n = nrm ? nrm + 3 * v : NULL;
            if (!block_room(&b, fp)) return write_failed(w);
            b.used += isomend_mesh_encode_vertex(w->format, positions + 3 * v, n, b.bytes + b.used);
            if (fn) {
                if (!block_room(&bn, fn)) return write_failed(w);
                bn.used += isomend_mesh_encode_normal(w->format, n, bn.bytes + bn.used);
            }
        }
        if (!block_flush(&b, fp) || (fn && !block_flush(&bn, fn))) return write_failed(w);
    }
    w->nv += count;
    return ISOMEND_FILEIO_OK;
}

/* The kept position of vertex `id` (STL), NULL if none. */
static const float *position_of(const isomend_mesh_writer *w, uint64_t id)
{
    size_t lo = 0, hi = w->nsegs;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        const pos_segment *s = &w->segs[mid];
        if (id < s->first)
            hi = mid;
        else if (id - s->first >= s->count)
            lo = mid + 1;
        else
            return s->pos + 3 * (id - s->first);
    }
    return NULL;
}

static isomend_fileio_status put_triangles(isomend_mesh_writer *w, size_t count,
                                           const uint64_t *ids64, const uint32_t *ids32)
{
    if (!w) return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    if (w->status != ISOMEND_FILEIO_OK) return w->status;
    if (count == 0) return ISOMEND_FILEIO_OK;
    if (!ids64 && !ids32) return fail(w, ISOMEND_FILEIO_ERR_INVALID_ARGUMENT, "NULL triangles");
    if ((uint64_t)count > isomend_mesh_max_triangles(w->format) - w->nt) {
        check_counts(w->format, 0, UINT64_MAX, w->af.final_path, w->msg, sizeof w->msg);
        w->status = ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
        return w->status;
    }
    FILE *fp = w->af.fp;
    if (!w->vertices_ended && w->format != ISOMEND_MESH_STL &&
        !(fp = spool(w, &w->spool_faces, 2)))
        return w->status;
    record_block b;
    b.used = 0;
    for (size_t t = 0; t < count; t++) {
        uint64_t id[3];
        const float *corner[3] = {NULL, NULL, NULL};
        for (int c = 0; c < 3; c++) {
            id[c] = ids64 ? ids64[3 * t + (size_t)c] : ids32[3 * t + (size_t)c];
            if (id[c] >= w->nv || id[c] < w->floor)
                return fail(w, ISOMEND_FILEIO_ERR_INVALID_ARGUMENT,
                            "triangle %llu uses vertex %llu, %s %llu", (unsigned long long)(w->nt + t),
                            (unsigned long long)id[c],
                            id[c] >= w->nv ? "but the vertices written are" : "retired below",
                            (unsigned long long)(id[c] >= w->nv ? w->nv : w->floor));
            if (w->format == ISOMEND_MESH_STL && !(corner[c] = position_of(w, id[c])))
                return fail(w, ISOMEND_FILEIO_ERR_INVALID_ARGUMENT,
                            "triangle %llu uses vertex %llu, whose position is no longer kept",
                            (unsigned long long)(w->nt + t), (unsigned long long)id[c]);
        }
        if (!block_room(&b, fp)) return write_failed(w);
        b.used += isomend_mesh_encode_face(w->format, w->normals, id, corner, b.bytes + b.used);
    }
    if (!block_flush(&b, fp)) return write_failed(w);
    w->nt += count;
    return ISOMEND_FILEIO_OK;
}

isomend_fileio_status isomend_mesh_writer_triangles(isomend_mesh_writer *w, size_t count,
                                                    const uint64_t *ids)
{
    return put_triangles(w, count, ids, NULL);
}

isomend_fileio_status isomend_mesh_writer_triangles_u32(isomend_mesh_writer *w, size_t count,
                                                        const uint32_t *ids)
{
    return put_triangles(w, count, NULL, ids);
}

isomend_fileio_status isomend_mesh_writer_retire(isomend_mesh_writer *w, uint64_t floor)
{
    if (!w) return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    if (w->status != ISOMEND_FILEIO_OK) return w->status;
    if (floor > w->nv)
        return fail(w, ISOMEND_FILEIO_ERR_INVALID_ARGUMENT, "retire %llu beyond the %llu vertices",
                    (unsigned long long)floor, (unsigned long long)w->nv);
    if (floor <= w->floor) return ISOMEND_FILEIO_OK;
    w->floor = floor;
    size_t drop = 0;
    while (drop < w->nsegs && w->segs[drop].first + w->segs[drop].count <= floor) {
        free(w->segs[drop].owned);
        drop++;
    }
    if (drop) {
        memmove(w->segs, w->segs + drop, (w->nsegs - drop) * sizeof *w->segs);
        w->nsegs -= drop;
    }
    return ISOMEND_FILEIO_OK;
}

/* Appends all of `from` (at its start) to `to` with copy_file_range(2), the
 * kernel copying between the page caches (or sharing blocks where the file
 * system can).  0: done; 1: not possible here (nothing copied: copy through
 * stdio); -1: failed (errno says why). */
static int copy_in_kernel(FILE *from, FILE *to)
{
#ifdef __linux__
    if (fflush(to) != 0)
        return -1;
    const int in = fileno(from), out = fileno(to);
    struct stat sb;
    if (fstat(in, &sb) != 0)
        return 1;
    loff_t at = 0;
    while (at < sb.st_size) {
        const ssize_t n = copy_file_range(in, &at, out, NULL, (size_t)(sb.st_size - at), 0);
        if (n <= 0) {
            if (at == 0 && (n == 0 || errno == ENOSYS || errno == EXDEV || errno == EINVAL ||
                            errno == EOPNOTSUPP))
                return 1;
            if (n == 0)
                errno = EIO;
            return -1;
        }
    }
    /* stdio's idea of the output's position follows the descriptor's */
    return fseeko(to, 0, SEEK_END) == 0 ? 0 : -1;
#else
    (void)from;
    (void)to;
    return 1;
#endif
}

/* Appends the scratch file's bytes to the output, then closes it. */
static isomend_fileio_status append_spool(isomend_mesh_writer *w, FILE **sp)
{
    FILE *s = *sp;
    if (!s) return ISOMEND_FILEIO_OK;
    isomend_fileio_status st = ISOMEND_FILEIO_OK;
    int copied;
    char *chunk = malloc(COPY_CHUNK);
    if (!chunk) {
        st = fail(w, ISOMEND_FILEIO_ERR_OUT_OF_MEMORY, "out of memory");
    } else if (fflush(s) != 0 || ferror(s) || fseeko(s, 0, SEEK_SET) != 0) {
        st = write_failed(w);
    } else if ((copied = copy_in_kernel(s, w->af.fp)) <= 0) {
        if (copied < 0) /* else copied by the kernel, not through this process */
            st = write_failed(w);
    } else {
        size_t got;
        while ((got = fread(chunk, 1, COPY_CHUNK, s)) > 0)
            if (fwrite(chunk, 1, got, w->af.fp) != got) {
                st = write_failed(w);
                break;
            }
        if (st == ISOMEND_FILEIO_OK && ferror(s))
            st = fail(w, ISOMEND_FILEIO_ERR_WRITE, "cannot read back a scratch file: %s",
                      strerror(errno));
    }
    free(chunk);
    fclose(s);
    *sp = NULL;
    return st;
}

isomend_fileio_status isomend_mesh_writer_end_vertices(isomend_mesh_writer *w)
{
    if (!w) return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    if (w->status != ISOMEND_FILEIO_OK || w->vertices_ended) return w->status;
    isomend_fileio_status st = append_spool(w, &w->spool_normals);
    if (st == ISOMEND_FILEIO_OK) st = append_spool(w, &w->spool_faces);
    if (st == ISOMEND_FILEIO_OK) w->vertices_ended = 1;
    return st;
}

static void writer_free(isomend_mesh_writer *w)
{
    if (w->spool_normals) fclose(w->spool_normals);
    if (w->spool_faces) fclose(w->spool_faces);
    for (size_t s = 0; s < w->nsegs; s++) free(w->segs[s].owned);
    free(w->segs);
    isomend_atomic_abort(&w->af); /* no-op after a commit */
    for (int b = 0; b < 3; b++) free(w->bufs[b]);
    free(w);
}

isomend_fileio_status isomend_mesh_writer_commit(isomend_mesh_writer *w, char *msg,
                                                 size_t msg_size)
{
    if (!w) {
        SET_MSG(msg, msg_size, "isomend_mesh_writer_commit: NULL writer");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    isomend_fileio_status st = isomend_mesh_writer_end_vertices(w);
    unsigned char head[1024];
    if (st == ISOMEND_FILEIO_OK)
        st = isomend_mesh_header(w->format, w->normals, w->nv, w->nt, head, w->af.final_path,
                                 w->msg, sizeof w->msg);
    if (st == ISOMEND_FILEIO_OK &&
        (fflush(w->af.fp) != 0 || fseeko(w->af.fp, 0, SEEK_SET) != 0 ||
         fwrite(head, 1, w->header_size, w->af.fp) != w->header_size))
        st = write_failed(w);
    if (st == ISOMEND_FILEIO_OK) {
        st = isomend_atomic_commit(&w->af, w->msg, sizeof w->msg);
        w->status = st;
    }
    if (st != ISOMEND_FILEIO_OK) SET_MSG(msg, msg_size, "%s", w->msg);
    writer_free(w);
    return st;
}

void isomend_mesh_writer_abort(isomend_mesh_writer *w)
{
    if (w) writer_free(w);
}

const char *isomend_mesh_writer_message(const isomend_mesh_writer *w)
{
    return w ? w->msg : "";
}

uint64_t isomend_mesh_writer_vertex_count(const isomend_mesh_writer *w)
{
    return w ? w->nv : 0;
}
