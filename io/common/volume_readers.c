/*
 * volume_readers.c - raw and NRRD volumes (see volume_readers.h)
 *
 * Why probe, then read: the caller (CLI, importer) wants to refuse a file
 * whose size does not match its description before allocating gigabytes,
 * and the importer wants dimensions and type at "open" time without
 * decoding.  So the probe does every check that needs no sample: header
 * syntax, required fields, exact byte count for raw data, and a plausibility
 * bound for gzip data (a deflate stream expands at most ~1032 times).  The
 * read then only has to detect what cannot be known earlier: a gzip stream
 * that is corrupt, ends early or carries more data than announced.
 *
 * Byte order: samples are stored as the header says ("endian") and swapped
 * to the machine's order while reading; single-byte types ignore it.
 */
#define _POSIX_C_SOURCE 200809L

#include "volume_readers.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <zlib.h>

#include "atomic_file.h"
#include "byte_order.h"

#define SET_MSG isomend_fileio_set_msg
#define CHUNK_BYTES (4u << 20)  /* read/decompress granularity and progress step */
#define GZ_MAX_RATIO 1032u      /* deflate's maximum expansion factor            */
#define GZ_SLACK 4096u

static void swap_bytes(void *data, size_t count, size_t size)
{
    unsigned char *p = data;
    for (size_t i = 0; i < count; i++, p += size) {
        for (size_t a = 0, b = size - 1; a < b; a++, b--) {
            unsigned char t = p[a];
            p[a] = p[b];
            p[b] = t;
        }
    }
}

/* Product of dims times the sample size, 0 on overflow or bad input. */
static uint64_t volume_bytes(const int64_t dims[3], isomend_type type)
{
    uint64_t n = isomend_type_size(type);
    if (n == 0) return 0;
    for (int a = 0; a < 3; a++) {
        if (dims[a] < 1) return 0;
        uint64_t d = (uint64_t)dims[a];
        if (n > UINT64_MAX / d) return 0;
        n *= d;
    }
    return n;
}

uint64_t isomend_fileio_volume_bytes(const isomend_fileio_info *info)
{
    return info ? volume_bytes(info->dims, info->type) : 0;
}

int isomend_fileio_is_nrrd_path(const char *path)
{
    if (!path) return 0;
    size_t n = strlen(path);
    return n >= 5 && (strcasecmp(path + n - 5, ".nrrd") == 0 || strcasecmp(path + n - 5, ".nhdr") == 0);
}

/* stat() a data file: NOT_FOUND / UNREADABLE with a message naming `shown`. */
static isomend_fileio_status stat_regular(const char *path, const char *shown, uint64_t *size,
                                          char *msg, size_t msg_size)
{
    struct stat st;
    if (stat(path, &st) != 0) {
        int err = errno;
        SET_MSG(msg, msg_size, "%s: %s", shown, strerror(err));
        return err == ENOENT || err == ENOTDIR ? ISOMEND_FILEIO_ERR_NOT_FOUND
                                               : ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    if (S_ISDIR(st.st_mode)) {
        SET_MSG(msg, msg_size, "%s: is a folder, not a volume file", shown);
        return ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    *size = (uint64_t)st.st_size;
    return ISOMEND_FILEIO_OK;
}

static void dims_text(const int64_t dims[3], isomend_type type, char *out, size_t n)
{
    snprintf(out, n, "%lldx%lldx%lld %s", (long long)dims[0], (long long)dims[1],
             (long long)dims[2], isomend_type_name(type) ? isomend_type_name(type) : "?");
}

/* Checks the data size after the probe filled dims/type/encoding/offset. */
static isomend_fileio_status check_data_size(isomend_fileio_info *info, int64_t byte_skip,
                                             char *msg, size_t msg_size)
{
    char what[128];
    dims_text(info->dims, info->type, what, sizeof what);
    uint64_t need = volume_bytes(info->dims, info->type);
    if (need == 0) {
        SET_MSG(msg, msg_size, "%s: %s is too large to address", info->path, what);
        return ISOMEND_FILEIO_ERR_UNSUPPORTED;
    }
    if ((uint64_t)SIZE_MAX < need) {
        SET_MSG(msg, msg_size, "%s: %s needs %llu bytes, more than this machine can address",
                info->path, what, (unsigned long long)need);
        return ISOMEND_FILEIO_ERR_UNSUPPORTED;
    }
    uint64_t have = info->data_file_bytes;
    if (byte_skip == -1) { /* raw data at the end of the file */
        if (have < info->data_offset + need) {
            SET_MSG(msg, msg_size, "%s: data file has %llu bytes, %s needs %llu", info->data_path,
                    (unsigned long long)have, what, (unsigned long long)need);
            return ISOMEND_FILEIO_ERR_SIZE;
        }
        info->data_offset = have - need;
        return ISOMEND_FILEIO_OK;
    }
    if (have < info->data_offset) {
        SET_MSG(msg, msg_size, "%s: file has %llu bytes, fewer than the %llu to skip",
                info->data_path, (unsigned long long)have, (unsigned long long)info->data_offset);
        return ISOMEND_FILEIO_ERR_SIZE;
    }
    uint64_t avail = have - info->data_offset;
    if (info->encoding == ISOMEND_FILEIO_ENC_RAW) {
        if (avail != need) {
            if (info->data_offset)
                SET_MSG(msg, msg_size, "%s: %llu bytes of data after the first %llu, %s needs %llu",
                        info->data_path, (unsigned long long)avail,
                        (unsigned long long)info->data_offset, what, (unsigned long long)need);
            else
                SET_MSG(msg, msg_size, "%s: file has %llu bytes, %s needs %llu", info->data_path,
                        (unsigned long long)avail, what, (unsigned long long)need);
            return ISOMEND_FILEIO_ERR_SIZE;
        }
    } else {
        if (avail == 0 || (avail < (UINT64_MAX - GZ_SLACK) / GZ_MAX_RATIO &&
                           avail * GZ_MAX_RATIO + GZ_SLACK < need)) {
            SET_MSG(msg, msg_size,
                    "%s: %llu bytes of gzip data cannot hold %s (%llu bytes): truncated?",
                    info->data_path, (unsigned long long)avail, what, (unsigned long long)need);
            return ISOMEND_FILEIO_ERR_SIZE;
        }
    }
    return ISOMEND_FILEIO_OK;
}

static void info_defaults(isomend_fileio_info *info, const char *path)
{
    memset(info, 0, sizeof *info);
    for (int a = 0; a < 3; a++) info->spacing[a] = 1.0;
    snprintf(info->path, sizeof info->path, "%s", path);
}

isomend_fileio_status isomend_fileio_probe_raw(const char *path, const int64_t dims[3],
                                               isomend_type type, int big_endian,
                                               uint64_t header_bytes, isomend_fileio_info *info,
                                               char *msg, size_t msg_size)
{
    if (!path || !dims || !info) {
        SET_MSG(msg, msg_size, "isomend_fileio_probe_raw: NULL argument");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (strlen(path) >= ISOMEND_FILEIO_PATH_MAX) {
        SET_MSG(msg, msg_size, "%.200s...: path too long", path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (isomend_type_size(type) == 0) {
        SET_MSG(msg, msg_size, "%s: invalid sample type", path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    for (int a = 0; a < 3; a++) {
        if (dims[a] < 1) {
            SET_MSG(msg, msg_size, "%s: dimension %d is %lld, must be at least 1", path, a,
                    (long long)dims[a]);
            return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
        }
    }
    info_defaults(info, path);
    memcpy(info->dims, dims, sizeof info->dims);
    info->type = type;
    info->big_endian = big_endian ? 1 : 0;
    info->encoding = ISOMEND_FILEIO_ENC_RAW;
    snprintf(info->data_path, sizeof info->data_path, "%s", path);
    info->data_offset = header_bytes;
    isomend_fileio_status st = stat_regular(path, path, &info->data_file_bytes, msg, msg_size);
    if (st != ISOMEND_FILEIO_OK) return st;
    return check_data_size(info, 0, msg, msg_size);
}

/* ------------------------------------------------------------------ NRRD */

static const struct {
    const char *name;
    isomend_type type;
} nrrd_types[] = {
    {"signed char", ISOMEND_I8}, {"int8", ISOMEND_I8}, {"int8_t", ISOMEND_I8},
    {"uchar", ISOMEND_U8}, {"unsigned char", ISOMEND_U8}, {"uint8", ISOMEND_U8},
    {"uint8_t", ISOMEND_U8},
    {"short", ISOMEND_I16}, {"short int", ISOMEND_I16}, {"signed short", ISOMEND_I16},
    {"signed short int", ISOMEND_I16}, {"int16", ISOMEND_I16}, {"int16_t", ISOMEND_I16},
    {"ushort", ISOMEND_U16}, {"unsigned short", ISOMEND_U16},
    {"unsigned short int", ISOMEND_U16}, {"uint16", ISOMEND_U16}, {"uint16_t", ISOMEND_U16},
    {"int", ISOMEND_I32}, {"signed int", ISOMEND_I32}, {"int32", ISOMEND_I32},
    {"int32_t", ISOMEND_I32},
    {"float", ISOMEND_F32}, {"double", ISOMEND_F64},
};

static char *trim(char *s)
{
    while (*s && isspace((unsigned char)*s)) s++;
    size_t n = strlen(s);
    while (n > 0 && isspace((unsigned char)s[n - 1])) s[--n] = '\0';
    return s;
}

/* Parses exactly `count` whitespace-separated numbers; returns how many were found (max count+1). */
static int parse_numbers(const char *s, double *out, int count)
{
    int n = 0;
    while (*s) {
        while (*s && isspace((unsigned char)*s)) s++;
        if (!*s) break;
        char *end;
        double v = strtod(s, &end);
        if (end == s) return -1;
        if (n < count) out[n] = v;
        n++;
        s = end;
        if (*s && !isspace((unsigned char)*s)) return -1;
    }
    return n;
}

/* Parses "(a,b,c)" at *s; advances *s.  Returns 1, 0 for "none", -1 on error. */
static int parse_vector(const char **s, double v[3])
{
    const char *p = *s;
    while (*p && isspace((unsigned char)*p)) p++;
    if (strncmp(p, "none", 4) == 0) {
        *s = p + 4;
        return 0;
    }
    if (*p != '(') return -1;
    p++;
    for (int i = 0; i < 3; i++) {
        char *end;
        while (*p && isspace((unsigned char)*p)) p++;
        v[i] = strtod(p, &end);
        if (end == p) return -1;
        p = end;
        while (*p && isspace((unsigned char)*p)) p++;
        if (*p != (i < 2 ? ',' : ')')) return -1;
        p++;
    }
    *s = p;
    return 1;
}

/* Reads one header line (without the newline) into buf; 0 at EOF, -1 if too long. */
static int read_line(FILE *fp, char *buf, size_t size)
{
    if (!fgets(buf, (int)size, fp)) return 0;
    size_t n = strlen(buf);
    if (n == size - 1 && buf[n - 1] != '\n' && !feof(fp)) return -1;
    while (n > 0 && (buf[n - 1] == '\n' || buf[n - 1] == '\r')) buf[--n] = '\0';
    return 1;
}

static int parse_int64(const char *s, int64_t *out)
{
    char *end;
    errno = 0;
    long long v = strtoll(s, &end, 10);
    if (end == s || errno) return 0;
    while (*end && isspace((unsigned char)*end)) end++;
    if (*end) return 0;
    *out = v;
    return 1;
}

/* Counts the bytes of the first `lines` lines of `path` from `offset`. */
static isomend_fileio_status skip_lines(const char *path, uint64_t offset, uint64_t lines,
                                        uint64_t *bytes, char *msg, size_t msg_size)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        SET_MSG(msg, msg_size, "%s: %s", path, strerror(errno));
        return ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    if (fseeko(fp, (off_t)offset, SEEK_SET) != 0) {
        fclose(fp);
        SET_MSG(msg, msg_size, "%s: cannot seek to byte %llu", path, (unsigned long long)offset);
        return ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    uint64_t n = 0, seen = 0;
    int c;
    while (seen < lines && (c = getc(fp)) != EOF) {
        n++;
        if (c == '\n') seen++;
    }
    fclose(fp);
    if (seen < lines) {
        SET_MSG(msg, msg_size, "%s: 'line skip: %llu' but the file has only %llu lines", path,
                (unsigned long long)lines, (unsigned long long)seen);
        return ISOMEND_FILEIO_ERR_SIZE;
    }
    *bytes = n;
    return ISOMEND_FILEIO_OK;
}

isomend_fileio_status isomend_fileio_probe_nrrd(const char *path, isomend_fileio_info *info,
                                                char *msg, size_t msg_size)
{
    if (!path || !info) {
        SET_MSG(msg, msg_size, "isomend_fileio_probe_nrrd: NULL argument");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (strlen(path) >= ISOMEND_FILEIO_PATH_MAX) {
        SET_MSG(msg, msg_size, "%.200s...: path too long", path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    info_defaults(info, path);
    info->is_nrrd = 1;
    uint64_t header_file_bytes;
    isomend_fileio_status st = stat_regular(path, path, &header_file_bytes, msg, msg_size);
    if (st != ISOMEND_FILEIO_OK) return st;
    FILE *fp = fopen(path, "rb");
    if (!fp) {
        SET_MSG(msg, msg_size, "%s: %s", path, strerror(errno));
        return ISOMEND_FILEIO_ERR_UNREADABLE;
    }

    char line[4096];
    int lineno = 1, r = read_line(fp, line, sizeof line);
    if (r <= 0 || strncmp(line, "NRRD000", 7) != 0 || !isdigit((unsigned char)line[7])) {
        fclose(fp);
        SET_MSG(msg, msg_size, "%s: not a NRRD file (the first line is not 'NRRD000x')", path);
        return ISOMEND_FILEIO_ERR_FORMAT;
    }
    int have_dim = 0, have_type = 0, have_sizes = 0, have_enc = 0, have_endian = 0;
    int have_spacings = 0, have_dirs = 0, blank_seen = 0;
    int64_t byte_skip = 0, line_skip = 0;
    char data_file[ISOMEND_FILEIO_PATH_MAX] = "";
    st = ISOMEND_FILEIO_OK;

#define HDR_FAIL(code, ...)                                                                        \
    do {                                                                                           \
        char detail_[512];                                                                         \
        snprintf(detail_, sizeof detail_, __VA_ARGS__);                                            \
        SET_MSG(msg, msg_size, "%s: line %d: %s", path, lineno, detail_);                          \
        st = code;                                                                                 \
        goto done;                                                                                 \
    } while (0)

    for (;;) {
        r = read_line(fp, line, sizeof line);
        lineno++;
        if (r < 0) HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "header line longer than %zu bytes", sizeof line);
        if (r == 0) break;
        if (line[0] == '\0') {
            blank_seen = 1;
            break;
        }
        if (line[0] == '#') continue;
        if (strstr(line, ":=")) continue; /* key/value pair: not needed */
        char *sep = strstr(line, ": ");
        if (!sep) {
            /* "field:" with an empty value is malformed too */
            HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "expected 'field: value', got '%.80s'", line);
        }
        *sep = '\0';
        char *field = trim(line), *value = trim(sep + 2);
        for (char *c = field; *c; c++) *c = (char)tolower((unsigned char)*c);

        if (strcmp(field, "dimension") == 0) {
            int64_t d;
            if (!parse_int64(value, &d)) HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "bad dimension '%s'", value);
            if (d != 3)
                HDR_FAIL(ISOMEND_FILEIO_ERR_UNSUPPORTED,
                         "dimension %lld: isomend reads 3D volumes (dimension: 3)", (long long)d);
            have_dim = 1;
        } else if (strcmp(field, "type") == 0) {
            size_t i;
            for (i = 0; i < sizeof nrrd_types / sizeof nrrd_types[0]; i++)
                if (strcasecmp(value, nrrd_types[i].name) == 0) break;
            if (i == sizeof nrrd_types / sizeof nrrd_types[0])
                HDR_FAIL(ISOMEND_FILEIO_ERR_UNSUPPORTED,
                         "unsupported type '%.60s' (supported: int8 uint8 int16 uint16 int32 float double)",
                         value);
            info->type = nrrd_types[i].type;
            have_type = 1;
        } else if (strcmp(field, "sizes") == 0) {
            double v[3];
            int n = parse_numbers(value, v, 3);
            if (n != 3) HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "'sizes' needs 3 integers, got '%.60s'", value);
            for (int a = 0; a < 3; a++) {
                if (!(v[a] >= 1 && v[a] <= 9.0e15) || v[a] != floor(v[a]))
                    HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "bad size '%g' in 'sizes'", v[a]);
                info->dims[a] = (int64_t)v[a];
            }
            have_sizes = 1;
        } else if (strcmp(field, "encoding") == 0) {
            if (strcasecmp(value, "raw") == 0)
                info->encoding = ISOMEND_FILEIO_ENC_RAW;
            else if (strcasecmp(value, "gzip") == 0 || strcasecmp(value, "gz") == 0)
                info->encoding = ISOMEND_FILEIO_ENC_GZIP;
            else
                HDR_FAIL(ISOMEND_FILEIO_ERR_UNSUPPORTED,
                         "unsupported encoding '%.60s' (supported: raw, gzip)", value);
            have_enc = 1;
        } else if (strcmp(field, "endian") == 0) {
            if (strcasecmp(value, "little") == 0)
                info->big_endian = 0;
            else if (strcasecmp(value, "big") == 0)
                info->big_endian = 1;
            else
                HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "bad endian '%.60s' (little or big)", value);
            have_endian = 1;
        } else if (strcmp(field, "spacings") == 0) {
            double v[3];
            if (parse_numbers(value, v, 3) != 3)
                HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "'spacings' needs 3 numbers, got '%.60s'", value);
            for (int a = 0; a < 3; a++) {
                if (isnan(v[a])) continue; /* unknown: keep 1 */
                if (!(v[a] != 0 && isfinite(v[a])))
                    HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "bad spacing '%g'", v[a]);
                info->spacing[a] = fabs(v[a]);
                info->spacing_known = 1;
            }
            have_spacings = 1;
        } else if (strcmp(field, "space directions") == 0) {
            const char *p = value;
            for (int a = 0; a < 3; a++) {
                double v[3];
                int k = parse_vector(&p, v);
                if (k < 0)
                    HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT,
                             "'space directions' needs 3 vectors '(x,y,z)', got '%.80s'", value);
                if (k == 0) continue;
                double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
                if (!(len > 0 && isfinite(len)))
                    HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "zero or non-finite vector in 'space directions'");
                for (int c = 0; c < 3; c++)
                    if (c != a && fabs(v[c]) > 1e-9 * len) info->oblique = 1;
                info->axis_negative[a] = v[a] < 0;
                info->spacing[a] = len;
                info->spacing_known = 1;
            }
            have_dirs = 1;
        } else if (strcmp(field, "space origin") == 0) {
            const char *p = value;
            double v[3];
            if (parse_vector(&p, v) != 1)
                HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "'space origin' needs '(x,y,z)', got '%.80s'", value);
            for (int a = 0; a < 3; a++) {
                if (!isfinite(v[a])) HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "non-finite 'space origin'");
                info->origin[a] = v[a];
            }
            info->origin_known = 1;
        } else if (strcmp(field, "space dimension") == 0) {
            int64_t d;
            if (!parse_int64(value, &d) || d != 3)
                HDR_FAIL(ISOMEND_FILEIO_ERR_UNSUPPORTED, "'space dimension: %.40s': only 3 is supported", value);
        } else if (strcmp(field, "byte skip") == 0) {
            if (!parse_int64(value, &byte_skip) || byte_skip < -1)
                HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "bad byte skip '%.40s'", value);
        } else if (strcmp(field, "line skip") == 0) {
            if (!parse_int64(value, &line_skip) || line_skip < 0)
                HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "bad line skip '%.40s'", value);
        } else if (strcmp(field, "data file") == 0 || strcmp(field, "datafile") == 0) {
            if (strncmp(value, "LIST", 4) == 0 || strchr(value, ' ') || strchr(value, '%'))
                HDR_FAIL(ISOMEND_FILEIO_ERR_UNSUPPORTED,
                         "multi-file data ('data file: %.60s') is not supported", value);
            snprintf(data_file, sizeof data_file, "%s", value);
        }
        /* other fields (kinds, centers, labels, units, content, min/max, space, ...)
         * do not change the samples' meaning for isomend */
    }
    lineno--;
    if (!have_dim) HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "header has no 'dimension' field");
    if (!have_type) HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "header has no 'type' field");
    if (!have_sizes) HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "header has no 'sizes' field");
    if (!have_enc) HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "header has no 'encoding' field");
    if (!have_endian && isomend_type_size(info->type) > 1)
        HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "header has no 'endian' field (needed for type %s)",
                 isomend_type_name(info->type));
    if (have_spacings && have_dirs)
        HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "both 'spacings' and 'space directions' given");
    if (byte_skip == -1 && info->encoding != ISOMEND_FILEIO_ENC_RAW)
        HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT, "'byte skip: -1' is only allowed with raw encoding");

    if (data_file[0]) {
        if (data_file[0] == '/') {
            snprintf(info->data_path, sizeof info->data_path, "%s", data_file);
        } else {
            const char *slash = strrchr(path, '/');
            int dlen = slash ? (int)(slash - path) : 0;
            int n = snprintf(info->data_path, sizeof info->data_path, "%.*s%s%s", dlen, path,
                             slash ? "/" : "", data_file);
            if (n < 0 || (size_t)n >= sizeof info->data_path)
                HDR_FAIL(ISOMEND_FILEIO_ERR_INVALID_ARGUMENT, "data file path too long");
        }
        info->data_offset = 0;
    } else {
        if (!blank_seen)
            HDR_FAIL(ISOMEND_FILEIO_ERR_FORMAT,
                     "header ends without the blank line before the data and has no 'data file'");
        snprintf(info->data_path, sizeof info->data_path, "%s", path);
        off_t pos = ftello(fp);
        if (pos < 0) HDR_FAIL(ISOMEND_FILEIO_ERR_UNREADABLE, "cannot tell the data position");
        info->data_offset = (uint64_t)pos;
    }
    fclose(fp);
    fp = NULL;

    if (data_file[0]) {
        char shown[2 * ISOMEND_FILEIO_PATH_MAX + 32];
        snprintf(shown, sizeof shown, "%s (data file of %s)", info->data_path, path);
        st = stat_regular(info->data_path, shown, &info->data_file_bytes, msg, msg_size);
        if (st != ISOMEND_FILEIO_OK) return st;
    } else {
        info->data_file_bytes = header_file_bytes;
    }
    info->line_skip = (uint64_t)line_skip;
    if (line_skip > 0) {
        uint64_t skipped;
        st = skip_lines(info->data_path, info->data_offset, (uint64_t)line_skip, &skipped, msg,
                        msg_size);
        if (st != ISOMEND_FILEIO_OK) return st;
        info->data_offset += skipped;
    }
    if (byte_skip > 0) info->data_offset += (uint64_t)byte_skip;
    return check_data_size(info, byte_skip, msg, msg_size);
#undef HDR_FAIL
done:
    if (fp) fclose(fp);
    return st;
}

/* ------------------------------------------------------------------ reading */

/*
 * One incremental decoder serves every read: isomend_fileio_read() (a range
 * of slices, with progress) and the slice reader (one slice per call, in
 * order, for volumes larger than memory).  Raw data is read where it lies;
 * gzip data is inflated from the start of the stream, so a later range costs
 * the decompression of everything before it, and the end of the stream is
 * checked only when the last slice has been produced.
 */
typedef struct decoder {
    const isomend_fileio_info *info;
    FILE *fp;
    int gzip;
    z_stream z;
    int z_ready;
    unsigned char *in, *scratch;
    int input_eof;
    int ended;              /* gzip: the last member ended with no input left */
    uint64_t produced;      /* bytes decoded so far (raw: the offset in the data) */
    /* progress of the current isomend_fileio_read() (NULL: none) */
    isomend_fileio_progress_fn progress;
    void *progress_user;
    uint64_t done, total, next_report;
    char *msg;
    size_t msg_size;
} decoder;

enum { GZ_IN_SIZE = 1 << 18, GZ_SCRATCH = 1 << 16 };

static isomend_fileio_status decoder_open(decoder *d, const isomend_fileio_info *info, char *msg,
                                          size_t msg_size)
{
    memset(d, 0, sizeof *d);
    d->info = info;
    d->msg = msg;
    d->msg_size = msg_size;
    d->gzip = info->encoding == ISOMEND_FILEIO_ENC_GZIP;
    d->fp = fopen(info->data_path, "rb");
    if (!d->fp) {
        int err = errno;
        SET_MSG(msg, msg_size, "%s: %s", info->data_path, strerror(err));
        return err == ENOENT ? ISOMEND_FILEIO_ERR_NOT_FOUND : ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    if (fseeko(d->fp, (off_t)info->data_offset, SEEK_SET) != 0) {
        SET_MSG(msg, msg_size, "%s: cannot seek to byte %llu", info->data_path,
                (unsigned long long)info->data_offset);
        return ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    if (!d->gzip) return ISOMEND_FILEIO_OK;
    d->in = malloc(GZ_IN_SIZE);
    d->scratch = malloc(GZ_SCRATCH);
    if (!d->in || !d->scratch || inflateInit2(&d->z, 15 + 32) != Z_OK) {
        SET_MSG(msg, msg_size, "%s: out of memory for the decompressor", info->path);
        return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
    }
    d->z_ready = 1;
    return ISOMEND_FILEIO_OK;
}

static void decoder_close(decoder *d)
{
    if (d->z_ready) inflateEnd(&d->z);
    free(d->in);
    free(d->scratch);
    if (d->fp) fclose(d->fp);
    memset(d, 0, sizeof *d);
}

/* Progress for `advance` more useful bytes; 1 if the caller cancels. */
static int report(decoder *d, uint64_t advance)
{
    d->done += advance;
    if (d->progress && (d->done >= d->next_report || d->done == d->total)) {
        d->next_report = d->done + CHUNK_BYTES;
        if (d->progress(d->progress_user, d->total ? (double)d->done / (double)d->total : 1.0))
            return 1;
    }
    return 0;
}

static isomend_fileio_status cancelled(decoder *d)
{
    SET_MSG(d->msg, d->msg_size, "%s: reading cancelled", d->info->path);
    return ISOMEND_FILEIO_ERR_CANCELLED;
}

/* Raw: `bytes` from data byte `at` into `out`. */
static isomend_fileio_status raw_read(decoder *d, uint64_t at, unsigned char *out, uint64_t bytes)
{
    const isomend_fileio_info *info = d->info;
    if (at != d->produced && fseeko(d->fp, (off_t)(info->data_offset + at), SEEK_SET) != 0) {
        SET_MSG(d->msg, d->msg_size, "%s: cannot seek to byte %llu", info->data_path,
                (unsigned long long)(info->data_offset + at));
        return ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    d->produced = at;
    uint64_t pos = 0;
    while (pos < bytes) {
        size_t want = (size_t)(bytes - pos < CHUNK_BYTES ? bytes - pos : CHUNK_BYTES);
        size_t got = fread(out + pos, 1, want, d->fp);
        pos += got;
        d->produced += got;
        if (got < want) {
            if (ferror(d->fp))
                SET_MSG(d->msg, d->msg_size, "%s: read error: %s", info->data_path, strerror(errno));
            else
                SET_MSG(d->msg, d->msg_size,
                        "%s: file ended after %llu of %llu data bytes (truncated?)",
                        info->data_path, (unsigned long long)d->produced,
                        (unsigned long long)volume_bytes(info->dims, info->type));
            return ferror(d->fp) ? ISOMEND_FILEIO_ERR_UNREADABLE : ISOMEND_FILEIO_ERR_SIZE;
        }
        if (report(d, got)) return cancelled(d);
    }
    return ISOMEND_FILEIO_OK;
}

static isomend_fileio_status gz_refill(decoder *d)
{
    if (d->z.avail_in != 0 || d->input_eof) return ISOMEND_FILEIO_OK;
    size_t got = fread(d->in, 1, GZ_IN_SIZE, d->fp);
    if (ferror(d->fp)) {
        SET_MSG(d->msg, d->msg_size, "%s: read error: %s", d->info->data_path, strerror(errno));
        return ISOMEND_FILEIO_ERR_UNREADABLE;
    }
    if (got < GZ_IN_SIZE) d->input_eof = 1;
    d->z.next_in = d->in;
    d->z.avail_in = (uInt)got;
    return ISOMEND_FILEIO_OK;
}

static isomend_fileio_status gz_truncated(decoder *d)
{
    SET_MSG(d->msg, d->msg_size, "%s: gzip data ends after %llu of %llu bytes (truncated?)",
            d->info->path, (unsigned long long)d->produced,
            (unsigned long long)volume_bytes(d->info->dims, d->info->type));
    return ISOMEND_FILEIO_ERR_SIZE;
}

/*
 * Gzip: the next `bytes` of the stream into `out`, or discarded when `out`
 * is NULL.  With `probe` set, `bytes` is ignored: the stream must end here
 * (more members may follow, but none may hold data).
 */
static isomend_fileio_status gz_inflate(decoder *d, unsigned char *out, uint64_t bytes, int probe)
{
    z_stream *z = &d->z;
    unsigned char probe_byte;
    for (;;) {
        if (probe) {
            if (d->ended) return ISOMEND_FILEIO_OK;
            z->next_out = &probe_byte;
            z->avail_out = 1;
        } else {
            if (bytes == 0) return ISOMEND_FILEIO_OK;
            if (d->ended) return gz_truncated(d);
            z->next_out = out ? out : d->scratch;
            uint64_t cap = out ? CHUNK_BYTES : GZ_SCRATCH;
            z->avail_out = (uInt)(bytes < cap ? bytes : cap);
        }
        isomend_fileio_status st = gz_refill(d);
        if (st != ISOMEND_FILEIO_OK) return st;
        uInt before = z->avail_out;
        int zr = inflate(z, Z_NO_FLUSH);
        uint64_t made = before - z->avail_out;
        if (probe && made > 0) {
            SET_MSG(d->msg, d->msg_size,
                    "%s: gzip data holds more than the %llu bytes the header describes",
                    d->info->path, (unsigned long long)volume_bytes(d->info->dims, d->info->type));
            return ISOMEND_FILEIO_ERR_SIZE;
        }
        d->produced += made;
        if (!probe) {
            bytes -= made;
            if (out) {
                out += made;
                if (made && report(d, made)) return cancelled(d);
            }
        }
        if (zr == Z_STREAM_END) {
            /* another gzip member may follow (concatenated gzip) */
            st = gz_refill(d);
            if (st != ISOMEND_FILEIO_OK) return st;
            if (z->avail_in == 0) {
                d->ended = 1;
                continue;
            }
            if (inflateReset(z) != Z_OK) {
                SET_MSG(d->msg, d->msg_size, "%s: corrupt gzip data", d->info->path);
                return ISOMEND_FILEIO_ERR_CORRUPT;
            }
            continue;
        }
        if (zr == Z_OK) continue;
        if (zr == Z_BUF_ERROR && z->avail_in == 0 && d->input_eof) return gz_truncated(d);
        if (zr == Z_BUF_ERROR) continue;
        if (zr == Z_MEM_ERROR) {
            SET_MSG(d->msg, d->msg_size, "%s: out of memory in the decompressor", d->info->path);
            return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
        }
        SET_MSG(d->msg, d->msg_size, "%s: corrupt gzip data after %llu bytes: %s", d->info->path,
                (unsigned long long)d->produced, z->msg ? z->msg : "inflate failed");
        return ISOMEND_FILEIO_ERR_CORRUPT;
    }
}

/* The data bytes [at, at + bytes) into `out`; gzip can only go forward. */
static isomend_fileio_status decode(decoder *d, uint64_t at, unsigned char *out, uint64_t bytes)
{
    if (!d->gzip) return raw_read(d, at, out, bytes);
    if (at < d->produced) { /* never asked for by the callers in this file */
        SET_MSG(d->msg, d->msg_size, "%s: gzip data cannot be read backwards", d->info->path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    isomend_fileio_status st = gz_inflate(d, NULL, at - d->produced, 0);
    if (st == ISOMEND_FILEIO_OK) st = gz_inflate(d, out, bytes, 0);
    /* the last byte of the volume: the stream must end there */
    if (st == ISOMEND_FILEIO_OK && d->produced == volume_bytes(d->info->dims, d->info->type))
        st = gz_inflate(d, NULL, 0, 1);
    return st;
}

static uint64_t slice_bytes_of(const isomend_fileio_info *info)
{
    return (uint64_t)info->dims[0] * (uint64_t)info->dims[1] * isomend_type_size(info->type);
}

isomend_fileio_status isomend_fileio_read(const isomend_fileio_info *info, int64_t first_slice,
                                          int64_t slice_count, void *buffer, size_t buffer_size,
                                          isomend_fileio_progress_fn progress, void *progress_user,
                                          char *msg, size_t msg_size)
{
    if (!info || !buffer) {
        SET_MSG(msg, msg_size, "isomend_fileio_read: NULL argument");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    size_t tsize = isomend_type_size(info->type);
    if (tsize == 0 || volume_bytes(info->dims, info->type) == 0) {
        SET_MSG(msg, msg_size, "%s: invalid volume description", info->path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (first_slice < 0 || slice_count < 1 || first_slice > info->dims[2] ||
        slice_count > info->dims[2] - first_slice) {
        SET_MSG(msg, msg_size, "%s: slices %lld..%lld out of range 0..%lld", info->path,
                (long long)first_slice, (long long)(first_slice + slice_count - 1),
                (long long)(info->dims[2] - 1));
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    uint64_t slice_bytes = slice_bytes_of(info);
    uint64_t bytes = slice_bytes * (uint64_t)slice_count;
    if (buffer_size < bytes) {
        SET_MSG(msg, msg_size, "%s: buffer of %zu bytes, %llu needed", info->path, buffer_size,
                (unsigned long long)bytes);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    decoder d;
    isomend_fileio_status st = decoder_open(&d, info, msg, msg_size);
    if (st == ISOMEND_FILEIO_OK) {
        d.progress = progress;
        d.progress_user = progress_user;
        d.total = bytes;
        st = decode(&d, slice_bytes * (uint64_t)first_slice, buffer, bytes);
    }
    decoder_close(&d);
    if (st == ISOMEND_FILEIO_OK && tsize > 1 && info->big_endian != machine_is_big_endian())
        swap_bytes(buffer, (size_t)(bytes / tsize), tsize);
    return st;
}

/* ------------------------------------------------------------------ slice by slice */

struct isomend_fileio_slices {
    isomend_fileio_info info;
    decoder d;
    int64_t next;          /* the next slice delivered                           */
    uint64_t slice_bytes;
    int reverse[3];        /* the axes describe() presents reversed              */
    unsigned char *row;    /* one row, for reversing y                           */
};

isomend_fileio_status isomend_fileio_slices_open(const isomend_fileio_info *info,
                                                 isomend_fileio_slices **out, char *msg,
                                                 size_t msg_size)
{
    if (!info || !out) {
        SET_MSG(msg, msg_size, "isomend_fileio_slices_open: NULL argument");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    *out = NULL;
    if (volume_bytes(info->dims, info->type) == 0) {
        SET_MSG(msg, msg_size, "%s: invalid volume description", info->path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    isomend_fileio_slices *s = calloc(1, sizeof *s);
    if (!s) {
        SET_MSG(msg, msg_size, "%s: out of memory", info->path);
        return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
    }
    s->info = *info;
    s->slice_bytes = slice_bytes_of(info);
    for (int a = 0; a < 3; a++)
        s->reverse[a] = info->axis_negative[a] && !info->oblique && info->dims[a] > 1;
    if (s->reverse[2] && info->encoding == ISOMEND_FILEIO_ENC_GZIP) {
        SET_MSG(msg, msg_size,
                "%s: gzip data whose 'space directions' reverse the z axis cannot be read slice "
                "by slice (its last slice comes first and gzip only reads forwards): "
                "re-encode it as raw, or give it the memory to be read whole",
                info->path);
        free(s);
        return ISOMEND_FILEIO_ERR_UNSUPPORTED;
    }
    if (s->reverse[1] && !(s->row = malloc((size_t)(info->dims[0] * (int64_t)isomend_type_size(info->type))))) {
        SET_MSG(msg, msg_size, "%s: out of memory", info->path);
        free(s);
        return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
    }
    isomend_fileio_status st = decoder_open(&s->d, &s->info, msg, msg_size);
    if (st != ISOMEND_FILEIO_OK) {
        isomend_fileio_slices_close(s);
        return st;
    }
    *out = s;
    return ISOMEND_FILEIO_OK;
}

uint64_t isomend_fileio_slices_bytes(const isomend_fileio_slices *s)
{
    return s ? s->slice_bytes : 0;
}

static void reverse_items(unsigned char *p, size_t count, size_t size, unsigned char *tmp)
{
    for (size_t a = 0, b = count - 1; a < b; a++, b--) {
        memcpy(tmp, p + a * size, size);
        memcpy(p + a * size, p + b * size, size);
        memcpy(p + b * size, tmp, size);
    }
}

isomend_fileio_status isomend_fileio_slices_next(isomend_fileio_slices *s, void *buffer,
                                                 size_t buffer_size, char *msg, size_t msg_size)
{
    if (!s || !buffer) {
        SET_MSG(msg, msg_size, "isomend_fileio_slices_next: NULL argument");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    const isomend_fileio_info *info = &s->info;
    if (s->next >= info->dims[2]) {
        SET_MSG(msg, msg_size, "%s: all %lld slices were read", info->path, (long long)info->dims[2]);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (buffer_size < s->slice_bytes) {
        SET_MSG(msg, msg_size, "%s: buffer of %zu bytes, a slice needs %llu", info->path,
                buffer_size, (unsigned long long)s->slice_bytes);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    int64_t stored = s->reverse[2] ? info->dims[2] - 1 - s->next : s->next;
    s->d.msg = msg;
    s->d.msg_size = msg_size;
    isomend_fileio_status st = decode(&s->d, s->slice_bytes * (uint64_t)stored, buffer,
                                      s->slice_bytes);
    if (st != ISOMEND_FILEIO_OK) return st;
    size_t tsize = isomend_type_size(info->type);
    size_t nx = (size_t)info->dims[0], ny = (size_t)info->dims[1];
    if (tsize > 1 && info->big_endian != machine_is_big_endian())
        swap_bytes(buffer, nx * ny, tsize);
    unsigned char *p = buffer, tmp[8];
    if (s->reverse[0])
        for (size_t j = 0; j < ny; j++) reverse_items(p + j * nx * tsize, nx, tsize, tmp);
    if (s->reverse[1]) reverse_items(p, ny, nx * tsize, s->row);
    s->next++;
    return ISOMEND_FILEIO_OK;
}

isomend_fileio_status isomend_fileio_slices_seek(isomend_fileio_slices *s, int64_t slice,
                                                 char *msg, size_t msg_size)
{
    if (!s || slice < 0 || slice > s->info.dims[2]) {
        SET_MSG(msg, msg_size, "isomend_fileio_slices_seek: slice out of range");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (s->d.gzip && slice < s->next) { /* gzip only goes forwards: from the start again */
        decoder_close(&s->d);
        isomend_fileio_status st = decoder_open(&s->d, &s->info, msg, msg_size);
        if (st != ISOMEND_FILEIO_OK) return st;
    }
    s->next = slice;
    return ISOMEND_FILEIO_OK;
}

void isomend_fileio_slices_close(isomend_fileio_slices *s)
{
    if (!s) return;
    decoder_close(&s->d);
    free(s->row);
    free(s);
}

isomend_fileio_status isomend_fileio_load(const isomend_fileio_info *info, void **out_data,
                                          isomend_fileio_progress_fn progress,
                                          void *progress_user, char *msg, size_t msg_size)
{
    if (!out_data) {
        SET_MSG(msg, msg_size, "isomend_fileio_load: NULL argument");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    *out_data = NULL;
    if (!info) {
        SET_MSG(msg, msg_size, "isomend_fileio_load: NULL argument");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    uint64_t bytes = volume_bytes(info->dims, info->type);
    if (bytes == 0 || bytes > (uint64_t)SIZE_MAX) {
        SET_MSG(msg, msg_size, "%s: invalid or unaddressable volume size", info->path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    void *data = malloc((size_t)bytes);
    if (!data) {
        char what[128];
        dims_text(info->dims, info->type, what, sizeof what);
        SET_MSG(msg, msg_size, "%s: cannot allocate %llu bytes (%.1f MiB) for %s", info->path,
                (unsigned long long)bytes, (double)bytes / 1048576.0, what);
        return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
    }
    isomend_fileio_status st = isomend_fileio_read(info, 0, info->dims[2], data, (size_t)bytes,
                                                   progress, progress_user, msg, msg_size);
    if (st != ISOMEND_FILEIO_OK) {
        free(data);
        return st;
    }
    *out_data = data;
    return ISOMEND_FILEIO_OK;
}

void isomend_fileio_describe(const isomend_fileio_info *info, const void *data,
                             isomend_volume *vol)
{
    isomend_volume_init(vol, data, info->type, info->dims[0], info->dims[1], info->dims[2]);
    vol->strides[0] = (int64_t)isomend_type_size(info->type);
    vol->strides[1] = vol->strides[0] * info->dims[0];
    vol->strides[2] = vol->strides[1] * info->dims[1];
    for (int a = 0; a < 3; a++) {
        vol->spacing[a] = info->spacing[a];
        vol->origin[a] = info->origin[a];
        if (info->axis_negative[a] && !info->oblique && info->dims[a] > 1) {
            int64_t last = info->dims[a] - 1;
            vol->data = (const char *)vol->data + last * vol->strides[a];
            vol->strides[a] = -vol->strides[a];
            vol->origin[a] -= (double)last * info->spacing[a];
        }
    }
}

/* ------------------------------------------------------------------ writing */

static const char *nrrd_type_name(isomend_type t)
{
    switch (t) {
    case ISOMEND_U8: return "uint8";
    case ISOMEND_I8: return "int8";
    case ISOMEND_U16: return "uint16";
    case ISOMEND_I16: return "int16";
    case ISOMEND_I32: return "int32";
    case ISOMEND_F32: return "float";
    case ISOMEND_F64: return "double";
    }
    return NULL;
}

isomend_fileio_status isomend_fileio_write_nrrd(const char *path, const isomend_volume *vol,
                                                int gzip, char *msg, size_t msg_size)
{
    if (!path || !vol || !vol->data || !nrrd_type_name(vol->type)) {
        SET_MSG(msg, msg_size, "%s: invalid volume to write", path ? path : "(null)");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    for (int a = 0; a < 3; a++) {
        if (vol->dims[a] < 1) {
            SET_MSG(msg, msg_size, "%s: invalid dimension %lld", path, (long long)vol->dims[a]);
            return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
        }
    }
    size_t tsize = isomend_type_size(vol->type);
    int64_t strides[3] = {vol->strides[0], vol->strides[1], vol->strides[2]};
    if (!strides[0] && !strides[1] && !strides[2]) {
        strides[0] = (int64_t)tsize;
        strides[1] = strides[0] * vol->dims[0];
        strides[2] = strides[1] * vol->dims[1];
    }
    size_t row_bytes = (size_t)vol->dims[0] * tsize;
    unsigned char *row = malloc(row_bytes), *zbuf = NULL;
    if (!row) {
        SET_MSG(msg, msg_size, "%s: out of memory", path);
        return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
    }
    isomend_atomic_file af;
    isomend_fileio_status st = isomend_atomic_open(&af, path, msg, msg_size);
    if (st != ISOMEND_FILEIO_OK) {
        free(row);
        return st;
    }
    fprintf(af.fp,
            "NRRD0004\n# written by isomend %s\ntype: %s\ndimension: 3\nsizes: %lld %lld %lld\n"
            "space dimension: 3\nspace directions: (%.17g,0,0) (0,%.17g,0) (0,0,%.17g)\n"
            "space origin: (%.17g,%.17g,%.17g)\nendian: little\nencoding: %s\n\n",
            isomend_version(), nrrd_type_name(vol->type), (long long)vol->dims[0],
            (long long)vol->dims[1], (long long)vol->dims[2], vol->spacing[0], vol->spacing[1],
            vol->spacing[2], vol->origin[0], vol->origin[1], vol->origin[2],
            gzip ? "gzip" : "raw");
    z_stream z;
    memset(&z, 0, sizeof z);
    enum { ZBUF = 1 << 16 };
    if (gzip) {
        zbuf = malloc(ZBUF);
        if (!zbuf || deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
            free(zbuf);
            free(row);
            isomend_atomic_abort(&af);
            SET_MSG(msg, msg_size, "%s: out of memory for the compressor", path);
            return ISOMEND_FILEIO_ERR_OUT_OF_MEMORY;
        }
    }
    int swap = machine_is_big_endian() && tsize > 1;
    int failed = 0;
    for (int64_t k = 0; k < vol->dims[2] && !failed; k++) {
        for (int64_t j = 0; j < vol->dims[1] && !failed; j++) {
            const char *src = (const char *)vol->data + j * strides[1] + k * strides[2];
            for (int64_t i = 0; i < vol->dims[0]; i++)
                memcpy(row + (size_t)i * tsize, src + i * strides[0], tsize);
            if (swap) swap_bytes(row, (size_t)vol->dims[0], tsize);
            int last = (k == vol->dims[2] - 1 && j == vol->dims[1] - 1);
            if (!gzip) {
                if (fwrite(row, 1, row_bytes, af.fp) != row_bytes) failed = 1;
                continue;
            }
            z.next_in = row;
            z.avail_in = (uInt)row_bytes;
            int zr;
            do {
                z.next_out = zbuf;
                z.avail_out = ZBUF;
                zr = deflate(&z, last ? Z_FINISH : Z_NO_FLUSH);
                size_t have = ZBUF - z.avail_out;
                if (zr == Z_STREAM_ERROR || fwrite(zbuf, 1, have, af.fp) != have) {
                    failed = 1;
                    break;
                }
            } while (z.avail_out == 0 || (last && zr != Z_STREAM_END));
        }
    }
    if (gzip) deflateEnd(&z);
    free(zbuf);
    free(row);
    if (failed) {
        int err = errno;
        isomend_atomic_abort(&af);
        SET_MSG(msg, msg_size, "%s: write failed: %s", path, strerror(err ? err : EIO));
        return ISOMEND_FILEIO_ERR_WRITE;
    }
    return isomend_atomic_commit(&af, msg, msg_size);
}

double isomend_fileio_otsu(const uint64_t *hist, int bins, double min, double max, int integer)
{
    if (!(max > min) || bins < 2)
        return min;
    const double w = (max - min) / bins;
    double total = 0, total_mass = 0;
    for (int b = 0; b < bins; b++) {
        total += (double)hist[b];
        total_mass += (double)hist[b] * (min + (b + 0.5) * w);
    }
    double w0 = 0, m0 = 0, best = -1;
    int best_first = 0, best_last = 0;
    for (int b = 0; b < bins - 1; b++) {
        w0 += (double)hist[b];
        m0 += (double)hist[b] * (min + (b + 0.5) * w);
        double w1 = total - w0;
        if (w0 <= 0 || w1 <= 0)
            continue;
        double d = m0 / w0 - (total_mass - m0) / w1;
        double between = w0 * w1 * d * d;
        if (between > best * (1 + 1e-12)) {
            best = between;
            best_first = best_last = b;
        } else if (between >= best * (1 - 1e-12) && hist[b] == 0 && best_last == b - 1) {
            best_last = b;
        }
    }
    double t = min + ((best_first + best_last) / 2.0 + 1) * w;
    return integer ? floor(t) + 0.5 : t;
}
