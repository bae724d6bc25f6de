/*
 * mesh_io.c - PLY/OBJ/STL writers and readers (see mesh_io.h)
 *
 * The readers exist for one purpose: running the continuity checker on a
 * mesh that some other tool (MeshLab, Blender, VTK, an earlier isomend)
 * wrote.  So they read geometry and connectivity only, accept every variant
 * those tools produce, and refuse anything that would make the check wrong
 * (an index out of range, a truncated file) with a message naming the file
 * and the element.
 */
#define _POSIX_C_SOURCE 200809L

#include "mesh_io.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "atomic_file.h"
#include "byte_order.h"
#include "mesh_writer.h"

#define SET_MSG isomend_fileio_set_msg

/* ------------------------------------------------------------------ writers */

/* The whole mesh at once: a client of the streaming writer (mesh_writer.h), so
 * the bytes are the same as a mesh written while it is extracted. */
isomend_fileio_status isomend_write_mesh(const char *path, isomend_mesh_format format,
                                         const float *positions, const float *normals,
                                         size_t vertex_count, const uint32_t *triangles,
                                         size_t triangle_count, char *msg, size_t msg_size)
{
    if (!path) {
        SET_MSG(msg, msg_size, "isomend_write_mesh: NULL path");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if ((vertex_count && !positions) || (triangle_count && !triangles)) {
        SET_MSG(msg, msg_size, "%s: NULL mesh arrays", path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (format == ISOMEND_MESH_UNKNOWN) format = isomend_mesh_format_of(path);
    /* refused before anything is created */
    for (size_t i = 0; i < 3 * triangle_count; i++) {
        if (triangles[i] >= vertex_count) {
            SET_MSG(msg, msg_size, "%s: triangle %zu uses vertex %lu of %zu", path, i / 3,
                    (unsigned long)triangles[i],
                    vertex_count);
            return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
        }
    }
    isomend_mesh_writer *w;
    isomend_fileio_status st = isomend_mesh_writer_begin(path, format, normals != NULL,
                                                         ISOMEND_MESH_WRITER_BORROW, &w, msg,
                                                         msg_size);
    if (st != ISOMEND_FILEIO_OK) return st;
    isomend_mesh_writer_vertices(w, vertex_count, positions, normals);
    isomend_mesh_writer_end_vertices(w);
    isomend_mesh_writer_triangles_u32(w, triangle_count, triangles);
    return isomend_mesh_writer_commit(w, msg, msg_size); /* reports the first failure */
}

/* ------------------------------------------------------------------ growable arrays */

typedef struct vec {
    void *data;
    size_t count, cap, elem;
} vec;

static int vec_push(vec *v, const void *item)
{
    if (v->count == v->cap) {
        size_t cap = v->cap ? v->cap * 2 : 1024;
        if (cap > SIZE_MAX / v->elem) return -1;
        void *p = realloc(v->data, cap * v->elem);
        if (!p) return -1;
        v->data = p;
        v->cap = cap;
    }
    memcpy((char *)v->data + v->count * v->elem, item, v->elem);
    v->count++;
    return 0;
}

typedef struct builder {
    vec pos; /* float[3] */
    vec tri; /* uint32_t[3] */
    uint64_t split, skipped;
} builder;

/* Adds a polygon (fan split from its first corner).  Indices are 0-based. */
static int add_polygon(builder *b, const uint64_t *idx, size_t n)
{
    if (n < 3) {
        b->skipped++;
        return 0;
    }
    if (n > 3) b->split++;
    for (size_t k = 1; k + 1 < n; k++) {
        uint32_t t[3] = {(uint32_t)idx[0], (uint32_t)idx[k], (uint32_t)idx[k + 1]};
        if (vec_push(&b->tri, t)) return -1;
    }
    return 0;
}

static void builder_free(builder *b)
{
    free(b->pos.data);
    free(b->tri.data);
    memset(b, 0, sizeof *b);
}

static isomend_fileio_status builder_finish(builder *b, isomend_read_mesh_result *out,
                                            const char *path, char *msg, size_t msg_size)
{
    size_t nv = b->pos.count;
    const uint32_t *t = b->tri.data;
    for (size_t i = 0; i < 3 * b->tri.count; i++) {
        if (t[i] >= nv) {
            SET_MSG(msg, msg_size, "%s: face %zu uses vertex %lu but there are %zu vertices", path,
                    i / 3, (unsigned long)t[i], nv);
            builder_free(b);
            return ISOMEND_FILEIO_ERR_FORMAT;
        }
    }
    out->positions = b->pos.data;
    out->vertex_count = nv;
    out->triangles = b->tri.data;
    out->triangle_count = b->tri.count;
    out->polygons_split = b->split;
    out->faces_skipped = b->skipped;
    return ISOMEND_FILEIO_OK;
}

/* ------------------------------------------------------------------ PLY */

typedef enum ply_type { PT_NONE, PT_I8, PT_U8, PT_I16, PT_U16, PT_I32, PT_U32, PT_F32, PT_F64 } ply_type;

static ply_type ply_type_of(const char *s)
{
    static const struct {
        const char *name;
        ply_type t;
    } names[] = {{"char", PT_I8},    {"int8", PT_I8},     {"uchar", PT_U8},   {"uint8", PT_U8},
                 {"short", PT_I16},  {"int16", PT_I16},   {"ushort", PT_U16}, {"uint16", PT_U16},
                 {"int", PT_I32},    {"int32", PT_I32},   {"uint", PT_U32},   {"uint32", PT_U32},
                 {"float", PT_F32},  {"float32", PT_F32}, {"double", PT_F64}, {"float64", PT_F64}};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strcmp(s, names[i].name) == 0) return names[i].t;
    return PT_NONE;
}

static size_t ply_size(ply_type t)
{
    switch (t) {
    case PT_I8: case PT_U8: return 1;
    case PT_I16: case PT_U16: return 2;
    case PT_I32: case PT_U32: case PT_F32: return 4;
    case PT_F64: return 8;
    case PT_NONE: return 0;
    }
    return 0;
}

#define PLY_MAX_PROPS 64
#define PLY_MAX_ELEMENTS 16

typedef struct ply_prop {
    char name[64];
    ply_type type;       /* value type                   */
    ply_type count_type; /* PT_NONE for a scalar property */
} ply_prop;

typedef struct ply_element {
    char name[64];
    uint64_t count;
    ply_prop props[PLY_MAX_PROPS];
    int nprops;
} ply_element;

/* The binary body is read through a buffer of its own: one fread() a value
 * cost more than the rest of reading a large mesh (a 340 MB PLY: 1.4 of 2.4
 * s of `isomend check`). */
#define PLY_BUFFER 65536

typedef struct ply_reader {
    FILE *fp;
    int ascii, big;
    const char *path;
    uint64_t token_line; /* ascii: for messages */
    size_t at, len;      /* binary: the unread bytes buf[at, len) */
    unsigned char buf[PLY_BUFFER];
} ply_reader;

/* n <= 8 bytes of the binary body into b; -1 at the end of the file. */
static int ply_read_bytes(ply_reader *r, unsigned char *b, size_t n)
{
    if (r->len - r->at < n) {
        memmove(r->buf, r->buf + r->at, r->len - r->at);
        r->len -= r->at;
        r->at = 0;
        r->len += fread(r->buf + r->len, 1, sizeof r->buf - r->len, r->fp);
        if (r->len < n) return -1;
    }
    memcpy(b, r->buf + r->at, n);
    r->at += n;
    return 0;
}

/* Reads one value; returns 0 on success. */
static int ply_read_value(ply_reader *r, ply_type t, double *out)
{
    if (r->ascii) {
        char tok[64];
        int c, n = 0;
        do {
            c = getc(r->fp);
            if (c == '\n') r->token_line++;
        } while (c != EOF && isspace(c));
        while (c != EOF && !isspace(c) && n < 63) {
            tok[n++] = (char)c;
            c = getc(r->fp);
        }
        if (c == '\n') r->token_line++;
        if (n == 0) return -1;
        tok[n] = '\0';
        char *end;
        *out = strtod(tok, &end);
        return *end ? -1 : 0;
    }
    unsigned char b[8];
    size_t n = ply_size(t);
    if (ply_read_bytes(r, b, n)) return -1;
    if (r->big != machine_is_big_endian())
        for (size_t a = 0, z = n - 1; a < z; a++, z--) {
            unsigned char tmp = b[a];
            b[a] = b[z];
            b[z] = tmp;
        }
    switch (t) {
    case PT_I8: { int8_t v; memcpy(&v, b, 1); *out = v; break; }
    case PT_U8: *out = b[0]; break;
    case PT_I16: { int16_t v; memcpy(&v, b, 2); *out = v; break; }
    case PT_U16: { uint16_t v; memcpy(&v, b, 2); *out = v; break; }
    case PT_I32: { int32_t v; memcpy(&v, b, 4); *out = v; break; }
    case PT_U32: { uint32_t v; memcpy(&v, b, 4); *out = v; break; }
    case PT_F32: { float v; memcpy(&v, b, 4); *out = v; break; }
    case PT_F64: memcpy(out, b, 8); break;
    case PT_NONE: return -1;
    }
    return 0;
}

static isomend_fileio_status read_ply(FILE *fp, const char *path, isomend_read_mesh_result *out,
                                      char *msg, size_t msg_size)
{
    char line[1024];
    ply_element elems[PLY_MAX_ELEMENTS];
    int nelem = 0, lineno = 0, have_format = 0;
    ply_reader r = {.fp = fp, .path = path};
    if (!fgets(line, sizeof line, fp) || strncmp(line, "ply", 3) != 0 ||
        (line[3] != '\n' && line[3] != '\r')) {
        SET_MSG(msg, msg_size, "%s: not a PLY file (the first line is not 'ply')", path);
        return ISOMEND_FILEIO_ERR_FORMAT;
    }
    lineno = 1;
    for (;;) {
        if (!fgets(line, sizeof line, fp)) {
            SET_MSG(msg, msg_size, "%s: PLY header has no 'end_header'", path);
            return ISOMEND_FILEIO_ERR_FORMAT;
        }
        lineno++;
        char *words[8];
        int nw = 0;
        for (char *tok = strtok(line, " \t\r\n"); tok && nw < 8; tok = strtok(NULL, " \t\r\n"))
            words[nw++] = tok;
        if (nw == 0) continue;
        if (strcmp(words[0], "end_header") == 0) break;
        if (strcmp(words[0], "comment") == 0 || strcmp(words[0], "obj_info") == 0) continue;
        if (strcmp(words[0], "format") == 0 && nw >= 2) {
            if (strcmp(words[1], "ascii") == 0)
                r.ascii = 1;
            else if (strcmp(words[1], "binary_little_endian") == 0)
                r.big = 0;
            else if (strcmp(words[1], "binary_big_endian") == 0)
                r.big = 1;
            else {
                SET_MSG(msg, msg_size, "%s: line %d: unknown PLY format '%s'", path, lineno, words[1]);
                return ISOMEND_FILEIO_ERR_FORMAT;
            }
            snprintf(out->encoding, sizeof out->encoding, "%s", words[1]);
            have_format = 1;
        } else if (strcmp(words[0], "element") == 0 && nw >= 3) {
            if (nelem == PLY_MAX_ELEMENTS) {
                SET_MSG(msg, msg_size, "%s: line %d: more than %d elements", path, lineno,
                        PLY_MAX_ELEMENTS);
                return ISOMEND_FILEIO_ERR_UNSUPPORTED;
            }
            ply_element *e = &elems[nelem++];
            memset(e, 0, sizeof *e);
            snprintf(e->name, sizeof e->name, "%s", words[1]);
            char *end;
            errno = 0;
            e->count = strtoull(words[2], &end, 10);
            if (*end || errno || words[2][0] == '-') {
                SET_MSG(msg, msg_size, "%s: line %d: bad element count '%s'", path, lineno, words[2]);
                return ISOMEND_FILEIO_ERR_FORMAT;
            }
        } else if (strcmp(words[0], "property") == 0 && nelem > 0) {
            ply_element *e = &elems[nelem - 1];
            if (e->nprops == PLY_MAX_PROPS) {
                SET_MSG(msg, msg_size, "%s: line %d: too many properties", path, lineno);
                return ISOMEND_FILEIO_ERR_UNSUPPORTED;
            }
            ply_prop *p = &e->props[e->nprops];
            memset(p, 0, sizeof *p);
            if (nw >= 5 && strcmp(words[1], "list") == 0) {
                p->count_type = ply_type_of(words[2]);
                p->type = ply_type_of(words[3]);
                snprintf(p->name, sizeof p->name, "%s", words[4]);
                if (p->count_type == PT_NONE || p->type == PT_NONE || p->count_type == PT_F32 ||
                    p->count_type == PT_F64) {
                    SET_MSG(msg, msg_size, "%s: line %d: bad list types '%s %s'", path, lineno,
                            words[2], words[3]);
                    return ISOMEND_FILEIO_ERR_FORMAT;
                }
            } else if (nw >= 3) {
                p->type = ply_type_of(words[1]);
                snprintf(p->name, sizeof p->name, "%s", words[2]);
                if (p->type == PT_NONE) {
                    SET_MSG(msg, msg_size, "%s: line %d: unknown property type '%s'", path, lineno,
                            words[1]);
                    return ISOMEND_FILEIO_ERR_FORMAT;
                }
            } else {
                SET_MSG(msg, msg_size, "%s: line %d: malformed property", path, lineno);
                return ISOMEND_FILEIO_ERR_FORMAT;
            }
            e->nprops++;
        } else {
            SET_MSG(msg, msg_size, "%s: line %d: unexpected PLY header line '%s'", path, lineno,
                    words[0]);
            return ISOMEND_FILEIO_ERR_FORMAT;
        }
    }
    if (!have_format) {
        SET_MSG(msg, msg_size, "%s: PLY header has no 'format' line", path);
        return ISOMEND_FILEIO_ERR_FORMAT;
    }
    builder b;
    memset(&b, 0, sizeof b);
    b.pos.elem = 3 * sizeof(float);
    b.tri.elem = 3 * sizeof(uint32_t);
    int have_vertex = 0;
    uint64_t *poly = NULL;
    size_t poly_cap = 0;
    isomend_fileio_status st = ISOMEND_FILEIO_OK;
    r.token_line = (uint64_t)lineno + 1;
    for (int ei = 0; ei < nelem && st == ISOMEND_FILEIO_OK; ei++) {
        ply_element *e = &elems[ei];
        int is_vertex = strcmp(e->name, "vertex") == 0;
        int is_face = strcmp(e->name, "face") == 0;
        int px = -1, py = -1, pz = -1, pf = -1;
        for (int p = 0; p < e->nprops; p++) {
            const char *n = e->props[p].name;
            if (is_vertex && e->props[p].count_type == PT_NONE) {
                if (strcmp(n, "x") == 0) px = p;
                if (strcmp(n, "y") == 0) py = p;
                if (strcmp(n, "z") == 0) pz = p;
            }
            if (is_face && e->props[p].count_type != PT_NONE &&
                (strcmp(n, "vertex_indices") == 0 || strcmp(n, "vertex_index") == 0))
                pf = p;
        }
        if (is_vertex) {
            if (px < 0 || py < 0 || pz < 0) {
                SET_MSG(msg, msg_size, "%s: PLY element 'vertex' lacks x, y or z", path);
                st = ISOMEND_FILEIO_ERR_FORMAT;
                break;
            }
            have_vertex = 1;
        }
        if (is_face && pf < 0) {
            SET_MSG(msg, msg_size, "%s: PLY element 'face' has no vertex_indices list", path);
            st = ISOMEND_FILEIO_ERR_FORMAT;
            break;
        }
        for (uint64_t k = 0; k < e->count && st == ISOMEND_FILEIO_OK; k++) {
            float xyz[3] = {0, 0, 0};
            for (int p = 0; p < e->nprops; p++) {
                const ply_prop *pp = &e->props[p];
                double v;
                if (pp->count_type == PT_NONE) {
                    if (ply_read_value(&r, pp->type, &v)) goto truncated;
                    if (p == px) xyz[0] = (float)v;
                    if (p == py) xyz[1] = (float)v;
                    if (p == pz) xyz[2] = (float)v;
                    continue;
                }
                double cnt;
                if (ply_read_value(&r, pp->count_type, &cnt) || cnt < 0 || cnt != floor(cnt) ||
                    cnt > 1e6)
                    goto truncated;
                size_t n = (size_t)cnt;
                if (p == pf && n > poly_cap) {
                    uint64_t *np = realloc(poly, n * sizeof *poly);
                    if (!np) {
                        st = ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
                        SET_MSG(msg, msg_size, "%s: out of memory", path);
                        break;
                    }
                    poly = np;
                    poly_cap = n;
                }
                for (size_t i = 0; i < n; i++) {
                    if (ply_read_value(&r, pp->type, &v)) goto truncated;
                    if (p == pf) {
                        if (!(v >= 0 && v <= 4294967295.0) || v != floor(v)) {
                            SET_MSG(msg, msg_size, "%s: face %llu has a bad vertex index %g", path,
                                    (unsigned long long)k, v);
                            st = ISOMEND_FILEIO_ERR_FORMAT;
                            break;
                        }
                        poly[i] = (uint64_t)v;
                    }
                }
                if (st != ISOMEND_FILEIO_OK) break;
                if (p == pf && add_polygon(&b, poly, n)) {
                    st = ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
                    SET_MSG(msg, msg_size, "%s: out of memory", path);
                    break;
                }
            }
            if (is_vertex && st == ISOMEND_FILEIO_OK && vec_push(&b.pos, xyz)) {
                st = ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
                SET_MSG(msg, msg_size, "%s: out of memory", path);
            }
            continue;
        truncated:
            SET_MSG(msg, msg_size, "%s: PLY data ends or is malformed in element '%s' %llu of %llu",
                    path, e->name, (unsigned long long)k, (unsigned long long)e->count);
            st = ISOMEND_FILEIO_ERR_FORMAT;
        }
    }
    free(poly);
    if (st == ISOMEND_FILEIO_OK && !have_vertex) {
        SET_MSG(msg, msg_size, "%s: PLY file has no 'vertex' element", path);
        st = ISOMEND_FILEIO_ERR_FORMAT;
    }
    if (st != ISOMEND_FILEIO_OK) {
        builder_free(&b);
        return st;
    }
    return builder_finish(&b, out, path, msg, msg_size);
}

/* ------------------------------------------------------------------ OBJ */

/* A face corner's vertex index, as strtoll(s, end, 10) reads it after the
 * spaces: an optional sign and decimal digits; *ok 0 when there are none or
 * the value is beyond a long long.  (strtoll was a sixth of reading a large
 * OBJ: its locale and base handling, per corner.) */
static long long obj_index(char *s, char **end, int *ok)
{
    char *p = s;
    const int neg = *p == '-';
    if (*p == '-' || *p == '+') p++;
    if (*p < '0' || *p > '9') {
        *end = s;
        *ok = 0;
        return 0;
    }
    unsigned long long v = 0;
    int over = 0;
    for (; *p >= '0' && *p <= '9'; p++) {
        const unsigned d = (unsigned)(*p - '0');
        if (v > (ULLONG_MAX - d) / 10) over = 1;
        else v = 10 * v + d;
    }
    *end = p;
    *ok = !over && (v <= (unsigned long long)LLONG_MAX ||
                    (neg && v == (unsigned long long)LLONG_MAX + 1));
    if (!*ok) return 0;
    return neg ? (long long)(0 - v) : (long long)v;
}

static isomend_fileio_status read_obj(FILE *fp, const char *path, isomend_read_mesh_result *out,
                                      char *msg, size_t msg_size)
{
    builder b;
    memset(&b, 0, sizeof b);
    b.pos.elem = 3 * sizeof(float);
    b.tri.elem = 3 * sizeof(uint32_t);
    size_t cap = 1 << 16;
    char *line = malloc(cap);
    uint64_t *poly = NULL;
    size_t poly_cap = 0;
    uint64_t lineno = 0;
    isomend_fileio_status st = ISOMEND_FILEIO_OK;
    if (!line) {
        SET_MSG(msg, msg_size, "%s: out of memory", path);
        return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
    }
    snprintf(out->encoding, sizeof out->encoding, "ascii");
    while (fgets(line, (int)cap, fp)) {
        lineno++;
        size_t len = strlen(line);
        if (len == cap - 1 && line[len - 1] != '\n' && !feof(fp)) {
            SET_MSG(msg, msg_size, "%s: line %llu is longer than %zu bytes", path,
                    (unsigned long long)lineno, cap - 1);
            st = ISOMEND_FILEIO_ERR_UNSUPPORTED;
            break;
        }
        char *p = line;
        while (*p == ' ' || *p == '\t') p++;
        if (p[0] == 'v' && (p[1] == ' ' || p[1] == '\t')) {
            float xyz[3];
            char *s = p + 2, *end;
            for (int c = 0; c < 3; c++) {
                xyz[c] = strtof(s, &end);
                if (end == s) {
                    SET_MSG(msg, msg_size, "%s: line %llu: 'v' needs 3 numbers", path,
                            (unsigned long long)lineno);
                    st = ISOMEND_FILEIO_ERR_FORMAT;
                    break;
                }
                s = end;
            }
            if (st != ISOMEND_FILEIO_OK) break;
            if (vec_push(&b.pos, xyz)) {
                st = ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
                SET_MSG(msg, msg_size, "%s: out of memory", path);
                break;
            }
        } else if (p[0] == 'f' && (p[1] == ' ' || p[1] == '\t')) {
            size_t n = 0;
            char *s = p + 2;
            for (;;) {
                while (*s == ' ' || *s == '\t') s++;
                if (!*s || *s == '\n' || *s == '\r' || *s == '#') break;
                char *end;
                int ok;
                long long v = obj_index(s, &end, &ok);
                if (!ok) {
                    SET_MSG(msg, msg_size, "%s: line %llu: bad face corner '%.20s'", path,
                            (unsigned long long)lineno, s);
                    st = ISOMEND_FILEIO_ERR_FORMAT;
                    break;
                }
                /* skip /vt/vn parts */
                while (*end && !isspace((unsigned char)*end)) end++;
                s = end;
                long long idx = v > 0 ? v - 1 : (long long)b.pos.count + v;
                if (v == 0 || idx < 0 || idx >= (long long)b.pos.count) {
                    SET_MSG(msg, msg_size, "%s: line %llu: face uses vertex %lld but %zu are defined",
                            path, (unsigned long long)lineno, v, b.pos.count);
                    st = ISOMEND_FILEIO_ERR_FORMAT;
                    break;
                }
                if (n == poly_cap) {
                    size_t nc = poly_cap ? 2 * poly_cap : 16;
                    uint64_t *np = realloc(poly, nc * sizeof *poly);
                    if (!np) {
                        st = ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
                        SET_MSG(msg, msg_size, "%s: out of memory", path);
                        break;
                    }
                    poly = np;
                    poly_cap = nc;
                }
                poly[n++] = (uint64_t)idx;
            }
            if (st != ISOMEND_FILEIO_OK) break;
            if (add_polygon(&b, poly, n)) {
                st = ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
                SET_MSG(msg, msg_size, "%s: out of memory", path);
                break;
            }
        }
        /* vt, vn, g, o, s, usemtl, mtllib, l, p, comments: not geometry we check */
    }
    if (st == ISOMEND_FILEIO_OK && ferror(fp)) {
        SET_MSG(msg, msg_size, "%s: read error: %s", path, strerror(errno));
        st = ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    free(line);
    free(poly);
    if (st != ISOMEND_FILEIO_OK) {
        builder_free(&b);
        return st;
    }
    return builder_finish(&b, out, path, msg, msg_size);
}

/* ------------------------------------------------------------------ STL */

/* Open-addressing map from exact float positions to vertex indices. */
typedef struct weld_map {
    uint32_t *slots; /* index + 1, 0 = empty */
    size_t mask;
} weld_map;

static uint64_t hash_pos(const float p[3])
{
    uint32_t bits[3];
    memcpy(bits, p, sizeof bits);
    uint64_t h = 1469598103934665603ull;
    for (int c = 0; c < 3; c++) {
        h ^= bits[c];
        h *= 1099511628211ull;
        h ^= h >> 29;
    }
    return h;
}

/* The map with room for twice its `slots / 2` positions, the positions so far
 * (b's, their indices + 1) filed again; 0 when out of memory. */
static int weld_resize(weld_map *m, size_t slots, const builder *b)
{
    uint32_t *t = calloc(slots, sizeof *t);
    if (!t) return 0;
    const float *pos = (const float *)b->pos.data;
    for (size_t i = 0; i < b->pos.count; i++) {
        size_t h = (size_t)hash_pos(pos + 3 * i) & (slots - 1);
        while (t[h]) h = (h + 1) & (slots - 1);
        t[h] = (uint32_t)(i + 1);
    }
    free(m->slots);
    m->slots = t;
    m->mask = slots - 1;
    return 1;
}

static isomend_fileio_status weld(builder *b, const float *corners, uint64_t count,
                                  const char *path, char *msg, size_t msg_size)
{
    /* sized for a closed mesh's positions (about a sixth of the corners) and
     * doubled whenever it is half full: a table for every corner (2 x count
     * slots) was mostly empty, 512 MB for 13.6 M facets, each lookup a miss */
    weld_map m = {NULL, 0};
    size_t slots = 1024;
    while (slots < count / 3 + 16) slots *= 2;
    if (!weld_resize(&m, slots, b)) {
        SET_MSG(msg, msg_size, "%s: out of memory", path);
        return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
    }
    for (uint64_t t = 0; t < count / 3; t++) {
        uint64_t idx[3];
        for (int c = 0; c < 3; c++) {
            float p[3];
            memcpy(p, corners + 3 * (3 * t + (uint64_t)c), sizeof p);
            for (int a = 0; a < 3; a++)
                if (p[a] == 0.0f) p[a] = 0.0f; /* -0 welds with +0 */
            size_t h = (size_t)hash_pos(p) & m.mask;
            for (;;) {
                uint32_t s = m.slots[h];
                if (s == 0) {
                    const int full = 2 * (b->pos.count + 1) > m.mask;
                    if (b->pos.count >= UINT32_MAX || vec_push(&b->pos, p) ||
                        (full && !weld_resize(&m, 2 * (m.mask + 1), b))) {
                        free(m.slots);
                        SET_MSG(msg, msg_size, "%s: out of memory", path);
                        return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
                    }
                    if (!full) /* (a resize files it with the others) */
                        m.slots[h] = (uint32_t)b->pos.count;
                    idx[c] = b->pos.count - 1;
                    break;
                }
                const float *q = (const float *)b->pos.data + 3 * (size_t)(s - 1);
                if (q[0] == p[0] && q[1] == p[1] && q[2] == p[2]) {
                    idx[c] = s - 1;
                    break;
                }
                h = (h + 1) & m.mask;
            }
        }
        if (add_polygon(b, idx, 3)) {
            free(m.slots);
            SET_MSG(msg, msg_size, "%s: out of memory", path);
            return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
        }
    }
    free(m.slots);
    return ISOMEND_FILEIO_OK;
}

static isomend_fileio_status read_stl(FILE *fp, const char *path, uint64_t file_size,
                                      isomend_read_mesh_result *out, char *msg, size_t msg_size)
{
    unsigned char head[84];
    size_t got = fread(head, 1, sizeof head, fp);
    int binary = 0;
    uint32_t count = 0;
    if (got == 84) {
        memcpy(&count, head + 80, 4);
        if (machine_is_big_endian())
            count = (count >> 24) | ((count >> 8) & 0xff00u) | ((count << 8) & 0xff0000u) | (count << 24);
        binary = file_size == 84 + 50 * (uint64_t)count;
    }
    int starts_solid = got >= 5 && strncmp((const char *)head, "solid", 5) == 0;
    vec corners = {NULL, 0, 0, 3 * sizeof(float)};
    isomend_fileio_status st = ISOMEND_FILEIO_OK;
    if (binary) {
        snprintf(out->encoding, sizeof out->encoding, "binary");
        unsigned char rec[50];
        for (uint32_t t = 0; t < count; t++) {
            if (fread(rec, 1, 50, fp) != 50) {
                SET_MSG(msg, msg_size, "%s: binary STL ends at triangle %lu of %lu", path,
                        (unsigned long)t, (unsigned long)count);
                st = ISOMEND_FILEIO_ERR_FORMAT;
                break;
            }
            for (int v = 0; v < 3 && st == ISOMEND_FILEIO_OK; v++) {
                float p[3];
                for (int c = 0; c < 3; c++) {
                    unsigned char le[4];
                    memcpy(le, rec + 12 + 12 * v + 4 * c, 4);
                    put_le32(le, le); /* swaps on big-endian machines */
                    memcpy(&p[c], le, 4);
                }
                if (vec_push(&corners, p)) {
                    SET_MSG(msg, msg_size, "%s: out of memory", path);
                    st = ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
                }
            }
            if (st != ISOMEND_FILEIO_OK) break;
        }
    } else if (starts_solid) {
        snprintf(out->encoding, sizeof out->encoding, "ascii");
        if (fseek(fp, 0, SEEK_SET) != 0) {
            SET_MSG(msg, msg_size, "%s: cannot seek", path);
            return ISOMEND_FILEIO_ERR_UNREADABLE;
        }
        char tok[128];
        float loop[64][3];
        int in_loop = 0, nloop = 0;
        uint64_t facet = 0;
        while (fscanf(fp, "%127s", tok) == 1) {
            if (strcmp(tok, "outer") == 0) {
                in_loop = 1;
                nloop = 0;
            } else if (strcmp(tok, "vertex") == 0) {
                float p[3];
                if (fscanf(fp, "%f %f %f", &p[0], &p[1], &p[2]) != 3) {
                    SET_MSG(msg, msg_size, "%s: facet %llu: 'vertex' needs 3 numbers", path,
                            (unsigned long long)facet);
                    st = ISOMEND_FILEIO_ERR_FORMAT;
                    break;
                }
                if (!in_loop || nloop == 64) {
                    SET_MSG(msg, msg_size, "%s: facet %llu: 'vertex' outside a loop or too many", path,
                            (unsigned long long)facet);
                    st = ISOMEND_FILEIO_ERR_FORMAT;
                    break;
                }
                memcpy(loop[nloop++], p, sizeof p);
            } else if (strcmp(tok, "endloop") == 0) {
                in_loop = 0;
                if (nloop < 3) out->faces_skipped++;
                for (int k = 1; k + 1 < nloop; k++) {
                    if (vec_push(&corners, loop[0]) || vec_push(&corners, loop[k]) ||
                        vec_push(&corners, loop[k + 1])) {
                        SET_MSG(msg, msg_size, "%s: out of memory", path);
                        st = ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
                        break;
                    }
                }
                if (nloop > 3) out->polygons_split++;
                facet++;
            }
        }
        if (st == ISOMEND_FILEIO_OK && in_loop) {
            SET_MSG(msg, msg_size, "%s: ascii STL ends inside facet %llu", path,
                    (unsigned long long)facet);
            st = ISOMEND_FILEIO_ERR_FORMAT;
        }
        if (st == ISOMEND_FILEIO_OK && facet == 0 && file_size > 200) {
            SET_MSG(msg, msg_size, "%s: no facets found (neither ascii nor binary STL of the right size)",
                    path);
            st = ISOMEND_FILEIO_ERR_FORMAT;
        }
    } else {
        SET_MSG(msg, msg_size,
                "%s: not an STL file (no 'solid' header, and %llu bytes is not 84 + 50 x triangles)",
                path, (unsigned long long)file_size);
        return ISOMEND_FILEIO_ERR_FORMAT;
    }
    if (st != ISOMEND_FILEIO_OK) {
        free(corners.data);
        return st;
    }
    builder b;
    memset(&b, 0, sizeof b);
    b.pos.elem = 3 * sizeof(float);
    b.tri.elem = 3 * sizeof(uint32_t);
    uint64_t split = out->polygons_split, skipped = out->faces_skipped;
    st = weld(&b, corners.data, corners.count, path, msg, msg_size);
    free(corners.data);
    if (st != ISOMEND_FILEIO_OK) {
        builder_free(&b);
        return st;
    }
    out->stl_facets = corners.count / 3;
    st = builder_finish(&b, out, path, msg, msg_size);
    out->polygons_split = split;
    out->faces_skipped = skipped;
    return st;
}

isomend_fileio_status isomend_read_mesh(const char *path, isomend_read_mesh_result *out, char *msg,
                                        size_t msg_size)
{
    if (!path || !out) {
        SET_MSG(msg, msg_size, "isomend_read_mesh: NULL argument");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    memset(out, 0, sizeof *out);
    isomend_mesh_format fmt = isomend_mesh_format_of(path);
    if (fmt == ISOMEND_MESH_UNKNOWN) {
        SET_MSG(msg, msg_size, "%s: unknown mesh format (use .ply, .obj or .stl)", path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    struct stat sb;
    if (stat(path, &sb) != 0) {
        int err = errno;
        SET_MSG(msg, msg_size, "%s: %s", path, strerror(err));
        return err == ENOENT || err == ENOTDIR ? ISOMEND_FILEIO_ERR_NOT_FOUND
                                               : ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    if (S_ISDIR(sb.st_mode)) {
        SET_MSG(msg, msg_size, "%s: is a folder, not a mesh file", path);
        return ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        SET_MSG(msg, msg_size, "%s: %s", path, strerror(errno));
        return ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    out->format = fmt;
    isomend_fileio_status st;
    if (fmt == ISOMEND_MESH_PLY)
        st = read_ply(fp, path, out, msg, msg_size);
    else if (fmt == ISOMEND_MESH_OBJ)
        st = read_obj(fp, path, out, msg, msg_size);
    else
        st = read_stl(fp, path, (uint64_t)sb.st_size, out, msg, msg_size);
    fclose(fp);
    if (st != ISOMEND_FILEIO_OK) isomend_read_mesh_free(out);
    return st;
}

void isomend_read_mesh_free(isomend_read_mesh_result *mesh)
{
    if (!mesh) return;
    free(mesh->positions);
    free(mesh->triangles);
    memset(mesh, 0, sizeof *mesh);
}
