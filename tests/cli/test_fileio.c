/*
 * test_fileio.c - io/common's readers and writers (runs under ASan/UBSan too)
 *
 * Invariants, not golden files:
 *   - every sample type survives NRRD write -> read (raw and gzip), and a
 *     big-endian file reads as the same values as a little-endian one;
 *   - detached headers, byte skip (also -1), line skip, multi-member gzip,
 *     slice-range reads equal the corresponding part of a full read;
 *   - every malformed input gives its status and a message naming the file,
 *     and sizes are checked before allocation;
 *   - meshes written as PLY/OBJ/STL read back with the same connectivity
 *     (STL welded back to the shared vertices), and the readers accept the
 *     variants other tools write (ascii PLY with extra properties, big-endian
 *     PLY, OBJ with v//vn and quads, ascii STL, binary STL starting "solid");
 *   - the slice reader (isomend_fileio_slices_*) delivers, slice by slice,
 *     exactly the volume isomend_fileio_describe() presents (every type, raw
 *     and gzip, every combination of reversed axes) and finds the same gzip
 *     errors; gzip with a reversed z axis is refused by name;
 *   - a failed write leaves neither the file nor a temporary file.
 */
#define _POSIX_C_SOURCE 200809L

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "mesh_io.h"
#include "testutil.h"
#include "volume_readers.h"

static char dir[512];
static char msg[ISOMEND_FILEIO_MSG_SIZE];

static const char *path_in(const char *name)
{
    return tu_path_in(dir, name);
}

static void write_bytes(const char *path, const void *data, size_t n)
{
    FILE *fp = fopen(path, "wb");
    CHECK(fp != NULL);
    if (!fp) return;
    CHECK(fwrite(data, 1, n, fp) == n);
    fclose(fp);
}

static void write_text(const char *path, const char *text)
{
    write_bytes(path, text, strlen(text));
}

/* Files in the test folder whose name contains ".tmp" (left-over temporaries). */
static int count_tmp_files(void)
{
    DIR *d = opendir(dir);
    int n = 0;
    struct dirent *e;
    while (d && (e = readdir(d)))
        if (strstr(e->d_name, ".tmp")) n++;
    if (d) closedir(d);
    return n;
}

static int exists(const char *p)
{
    struct stat st;
    return stat(p, &st) == 0;
}

/* A volume of each type with values that use the type's range. */
static void *make_volume(isomend_type t, const int64_t d[3])
{
    size_t n = (size_t)(d[0] * d[1] * d[2]), ts = isomend_type_size(t);
    unsigned char *p = malloc(n * ts);
    for (size_t i = 0; i < n; i++) {
        double v = (double)((i * 37) % 251) - (t == ISOMEND_U8 || t == ISOMEND_U16 ? 0 : 120);
        switch (t) {
        case ISOMEND_U8: { uint8_t x = (uint8_t)v; memcpy(p + i * ts, &x, ts); break; }
        case ISOMEND_I8: { int8_t x = (int8_t)v; memcpy(p + i * ts, &x, ts); break; }
        case ISOMEND_U16: { uint16_t x = (uint16_t)(v * 250); memcpy(p + i * ts, &x, ts); break; }
        case ISOMEND_I16: { int16_t x = (int16_t)(v * 250); memcpy(p + i * ts, &x, ts); break; }
        case ISOMEND_I32: { int32_t x = (int32_t)(v * 1e6); memcpy(p + i * ts, &x, ts); break; }
        case ISOMEND_F32: { float x = (float)(v / 7.0); memcpy(p + i * ts, &x, ts); break; }
        case ISOMEND_F64: { double x = v / 7.0; memcpy(p + i * ts, &x, ts); break; }
        }
    }
    return p;
}

static void test_roundtrip_all_types(void)
{
    const int64_t d[3] = {5, 4, 3};
    for (int t = 0; t < ISOMEND_TYPE_COUNT; t++) {
        for (int gz = 0; gz < 2; gz++) {
            void *data = make_volume((isomend_type)t, d);
            isomend_volume vol;
            isomend_volume_init(&vol, data, (isomend_type)t, d[0], d[1], d[2]);
            vol.spacing[0] = 0.5;
            vol.spacing[2] = 2.5;
            vol.origin[1] = -7.25;
            const char *p = path_in("rt.nrrd");
            CHECK_EQ_INT(isomend_fileio_write_nrrd(p, &vol, gz, msg, sizeof msg), ISOMEND_FILEIO_OK);
            isomend_fileio_info info;
            CHECK_EQ_INT(isomend_fileio_probe_nrrd(p, &info, msg, sizeof msg), ISOMEND_FILEIO_OK);
            CHECK_EQ_INT(info.type, t);
            CHECK_EQ_INT(info.encoding, gz ? ISOMEND_FILEIO_ENC_GZIP : ISOMEND_FILEIO_ENC_RAW);
            CHECK(info.dims[0] == 5 && info.dims[1] == 4 && info.dims[2] == 3);
            CHECK(info.spacing[0] == 0.5 && info.spacing[1] == 1.0 && info.spacing[2] == 2.5);
            CHECK(info.origin[1] == -7.25 && info.spacing_known && info.origin_known);
            void *back = NULL;
            CHECK_EQ_INT(isomend_fileio_load(&info, &back, NULL, NULL, msg, sizeof msg), ISOMEND_FILEIO_OK);
            size_t bytes = (size_t)isomend_fileio_volume_bytes(&info);
            CHECK_EQ_INT(bytes, 60 * isomend_type_size((isomend_type)t));
            CHECK(back && memcmp(back, data, bytes) == 0);
            /* a slice range equals the same part of the full read */
            size_t slice = bytes / 3;
            unsigned char *part = malloc(slice);
            CHECK_EQ_INT(isomend_fileio_read(&info, 1, 1, part, slice, NULL, NULL, msg, sizeof msg),
                         ISOMEND_FILEIO_OK);
            CHECK(memcmp(part, (unsigned char *)data + slice, slice) == 0);
            free(part);
            free(back);
            free(data);
        }
    }
    CHECK_EQ_INT(count_tmp_files(), 0);
}

static void test_big_endian_and_detached(void)
{
    /* u16 big endian, detached, with a byte skip and a line skip */
    const uint16_t values[8] = {1, 2, 300, 4000, 5, 60000, 7, 8};
    unsigned char be[8 * 2];
    for (int i = 0; i < 8; i++) {
        be[2 * i] = (unsigned char)(values[i] >> 8);
        be[2 * i + 1] = (unsigned char)(values[i] & 0xff);
    }
    unsigned char file[7 + 3 + 16];
    memcpy(file, "line 1\n", 7);
    memcpy(file + 7, "XYZ", 3); /* byte skip 3 after one skipped line */
    memcpy(file + 10, be, 16);
    write_bytes(path_in("be.raw"), file, sizeof file);
    write_text(path_in("be.nhdr"),
               "NRRD0005\n# comment\ntype: unsigned short\ndimension: 3\nsizes: 2 2 2\n"
               "spacings: 1 nan 3\nendian: big\nencoding: raw\nline skip: 1\nbyte skip: 3\n"
               "key:=value\ndata file: be.raw\n");
    isomend_fileio_info info;
    CHECK_EQ_INT(isomend_fileio_probe_nrrd(path_in("be.nhdr"), &info, msg, sizeof msg), ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(info.data_offset, 10);
    CHECK(info.spacing[1] == 1.0 && info.spacing[2] == 3.0);
    uint16_t got[8];
    CHECK_EQ_INT(isomend_fileio_read(&info, 0, 2, got, sizeof got, NULL, NULL, msg, sizeof msg),
                 ISOMEND_FILEIO_OK);
    CHECK(memcmp(got, values, sizeof got) == 0);

    /* byte skip -1: the data is the end of the file */
    write_text(path_in("tail.nhdr"),
               "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 2 2 2\nendian: big\nencoding: raw\n"
               "byte skip: -1\ndata file: be.raw\n");
    CHECK_EQ_INT(isomend_fileio_probe_nrrd(path_in("tail.nhdr"), &info, msg, sizeof msg), ISOMEND_FILEIO_OK);
    memset(got, 0, sizeof got);
    CHECK_EQ_INT(isomend_fileio_read(&info, 0, 2, got, sizeof got, NULL, NULL, msg, sizeof msg),
                 ISOMEND_FILEIO_OK);
    CHECK(memcmp(got, values, sizeof got) == 0);

    /* raw probe with a header and big endian */
    int64_t d[3] = {2, 2, 2};
    CHECK_EQ_INT(isomend_fileio_probe_raw(path_in("be.raw"), d, ISOMEND_U16, 1, 10, &info, msg, sizeof msg),
                 ISOMEND_FILEIO_OK);
    void *data = NULL;
    CHECK_EQ_INT(isomend_fileio_load(&info, &data, NULL, NULL, msg, sizeof msg), ISOMEND_FILEIO_OK);
    CHECK(data && memcmp(data, values, sizeof values) == 0);
    free(data);
}

static void test_negative_direction(void)
{
    /* x axis pointing to -x: the described volume runs the other way */
    const uint8_t v[8] = {0, 1, 2, 3, 4, 5, 6, 7};
    char hdr[512];
    int n = snprintf(hdr, sizeof hdr,
                     "NRRD0004\ntype: uint8\ndimension: 3\nspace: RAS\nsizes: 2 2 2\n"
                     "space directions: (-2,0,0) (0,2,0) (0,0,2)\nspace origin: (10,0,0)\n"
                     "encoding: raw\n\n");
    unsigned char file[600];
    memcpy(file, hdr, (size_t)n);
    memcpy(file + n, v, 8);
    write_bytes(path_in("neg.nrrd"), file, (size_t)n + 8);
    isomend_fileio_info info;
    CHECK_EQ_INT(isomend_fileio_probe_nrrd(path_in("neg.nrrd"), &info, msg, sizeof msg), ISOMEND_FILEIO_OK);
    CHECK(info.axis_negative[0] && !info.axis_negative[1] && !info.oblique);
    void *data = NULL;
    CHECK_EQ_INT(isomend_fileio_load(&info, &data, NULL, NULL, msg, sizeof msg), ISOMEND_FILEIO_OK);
    isomend_volume vol;
    isomend_fileio_describe(&info, data, &vol);
    CHECK(vol.origin[0] == 8.0 && vol.spacing[0] == 2.0 && vol.strides[0] == -1);
    /* sample (0,0,0) of the description is file sample (1,0,0), at world x = 8 */
    CHECK_EQ_INT(*(const uint8_t *)vol.data, 1);
    free(data);
}

/*
 * Reads a volume with the slice reader into one contiguous buffer; compares
 * it sample by sample with isomend_fileio_describe() of a whole load.
 */
static isomend_fileio_status read_by_slices(const isomend_fileio_info *info, void **out)
{
    *out = NULL;
    isomend_fileio_slices *s;
    isomend_fileio_status st = isomend_fileio_slices_open(info, &s, msg, sizeof msg);
    if (st != ISOMEND_FILEIO_OK) return st;
    size_t sb = (size_t)isomend_fileio_slices_bytes(s);
    unsigned char *all = malloc(sb * (size_t)info->dims[2] + 1);
    for (int64_t k = 0; k < info->dims[2] && st == ISOMEND_FILEIO_OK; k++)
        st = isomend_fileio_slices_next(s, all + sb * (size_t)k, sb, msg, sizeof msg);
    if (st == ISOMEND_FILEIO_OK) /* one slice too many */
        CHECK_EQ_INT(isomend_fileio_slices_next(s, all, sb, msg, sizeof msg), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    isomend_fileio_slices_close(s);
    if (st != ISOMEND_FILEIO_OK) {
        free(all);
        return st;
    }
    *out = all;
    return ISOMEND_FILEIO_OK;
}

static int same_as_described(const isomend_fileio_info *info, const void *whole, const void *slices)
{
    isomend_volume vol;
    isomend_fileio_describe(info, whole, &vol);
    size_t ts = isomend_type_size(info->type);
    const unsigned char *q = slices;
    for (int64_t k = 0; k < info->dims[2]; k++)
        for (int64_t j = 0; j < info->dims[1]; j++)
            for (int64_t i = 0; i < info->dims[0]; i++, q += ts) {
                const char *p = (const char *)vol.data + i * vol.strides[0] + j * vol.strides[1] +
                                k * vol.strides[2];
                if (memcmp(p, q, ts) != 0) return 0;
            }
    return 1;
}

static void expect_probe_error(const char *name, const char *header_text, isomend_fileio_status want,
                               const char *substring)
{
    write_text(path_in(name), header_text);
    isomend_fileio_info info;
    isomend_fileio_status st = isomend_fileio_probe_nrrd(path_in(name), &info, msg, sizeof msg);
    if (st != want || !strstr(msg, name) || !strstr(msg, substring))
        fprintf(stderr, "%s: status %d (want %d), message '%s' (want '%s')\n", name, st, want, msg,
                substring);
    CHECK_EQ_INT(st, want);
    CHECK(strstr(msg, name) != NULL);
    CHECK(strstr(msg, substring) != NULL);
}

static void test_header_errors(void)
{
    expect_probe_error("magic.nrrd", "P5\n2 2\n255\n", ISOMEND_FILEIO_ERR_FORMAT, "not a NRRD");
    expect_probe_error("dim.nrrd", "NRRD0004\ntype: float\ndimension: 2\n", ISOMEND_FILEIO_ERR_UNSUPPORTED,
                       "dimension 2");
    expect_probe_error("type.nrrd", "NRRD0004\ntype: uint64\n", ISOMEND_FILEIO_ERR_UNSUPPORTED, "uint64");
    expect_probe_error("enc.nrrd", "NRRD0004\nencoding: bzip2\n", ISOMEND_FILEIO_ERR_UNSUPPORTED, "bzip2");
    expect_probe_error("sizes.nrrd", "NRRD0004\nsizes: 2 2\n", ISOMEND_FILEIO_ERR_FORMAT, "sizes");
    expect_probe_error("nosizes.nrrd", "NRRD0004\ntype: float\ndimension: 3\nencoding: raw\nendian: little\n\n",
                       ISOMEND_FILEIO_ERR_FORMAT, "no 'sizes'");
    expect_probe_error("endian.nrrd",
                       "NRRD0004\ntype: float\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n\nabcd",
                       ISOMEND_FILEIO_ERR_FORMAT, "endian");
    expect_probe_error("short.nrrd",
                       "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\nabcdefg",
                       ISOMEND_FILEIO_ERR_SIZE, "needs 8");
    expect_probe_error("long.nrrd",
                       "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\nabcdefghi",
                       ISOMEND_FILEIO_ERR_SIZE, "needs 8");
    expect_probe_error("nodata.nhdr",
                       "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                       "data file: missing.raw\n",
                       ISOMEND_FILEIO_ERR_NOT_FOUND, "missing.raw");
    expect_probe_error("list.nhdr",
                       "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                       "data file: LIST\n",
                       ISOMEND_FILEIO_ERR_UNSUPPORTED, "multi-file");
    expect_probe_error("gzsmall.nrrd",
                       "NRRD0004\ntype: float\ndimension: 3\nsizes: 1000 1000 1000\nendian: little\n"
                       "encoding: gzip\n\nxx",
                       ISOMEND_FILEIO_ERR_SIZE, "cannot hold");
    expect_probe_error("noblank.nrrd", "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n",
                       ISOMEND_FILEIO_ERR_FORMAT, "blank line");
    isomend_fileio_info info;
    CHECK_EQ_INT(isomend_fileio_probe_nrrd(path_in("absent.nrrd"), &info, msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_NOT_FOUND);
    CHECK(strstr(msg, "absent.nrrd") != NULL);
    CHECK_EQ_INT(isomend_fileio_probe_nrrd(dir, &info, msg, sizeof msg), ISOMEND_FILEIO_ERR_UNREADABLE);
    CHECK(strstr(msg, "folder") != NULL);

    /* raw size checks, before any allocation */
    int64_t d[3] = {10, 10, 10};
    unsigned char buf[1001];
    memset(buf, 1, sizeof buf);
    write_bytes(path_in("v999.raw"), buf, 999);
    CHECK_EQ_INT(isomend_fileio_probe_raw(path_in("v999.raw"), d, ISOMEND_U8, 0, 0, &info, msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_SIZE);
    CHECK(strstr(msg, "999") && strstr(msg, "needs 1000") && strstr(msg, "v999.raw"));
    int64_t huge[3] = {1 << 30, 1 << 30, 1 << 30};
    CHECK(isomend_fileio_probe_raw(path_in("v999.raw"), huge, ISOMEND_F64, 0, 0, &info, msg, sizeof msg) !=
          ISOMEND_FILEIO_OK);
    int64_t zero[3] = {10, 0, 10};
    CHECK_EQ_INT(isomend_fileio_probe_raw(path_in("v999.raw"), zero, ISOMEND_U8, 0, 0, &info, msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
}

static size_t gzip_bytes(const void *in, size_t n, unsigned char *out, size_t cap)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY);
    z.next_in = (unsigned char *)(uintptr_t)in;
    z.avail_in = (uInt)n;
    z.next_out = out;
    z.avail_out = (uInt)cap;
    deflate(&z, Z_FINISH);
    size_t total = z.total_out;
    deflateEnd(&z);
    return total;
}

static void gzip_case(const char *name, const unsigned char *payload, size_t payload_n, int mutate,
                      isomend_fileio_status want, const char *substring)
{
    const char *hdr = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 10 10 10\nencoding: gzip\n\n";
    unsigned char file[8192];
    size_t h = strlen(hdr);
    memcpy(file, hdr, h);
    size_t z = gzip_bytes(payload, payload_n, file + h, sizeof file - h);
    if (mutate == 1) z -= 12;                          /* cut the end off      */
    if (mutate == 2) file[h + z / 2] ^= 0x55;          /* flip bits mid-stream */
    if (mutate == 3) z += gzip_bytes(payload, 500, file + h + z, sizeof file - h - z); /* 2 members */
    write_bytes(path_in(name), file, h + z);
    isomend_fileio_info info;
    isomend_fileio_status st = isomend_fileio_probe_nrrd(path_in(name), &info, msg, sizeof msg);
    void *data = NULL;
    if (st == ISOMEND_FILEIO_OK) st = isomend_fileio_load(&info, &data, NULL, NULL, msg, sizeof msg);
    if (st != want) fprintf(stderr, "%s: status %d, want %d: %s\n", name, st, want, msg);
    CHECK_EQ_INT(st, want);
    /* the slice reader finds the same, in the slice where it is */
    void *sl = NULL;
    isomend_fileio_status st2 = isomend_fileio_probe_nrrd(path_in(name), &info, msg, sizeof msg);
    if (st2 == ISOMEND_FILEIO_OK) st2 = read_by_slices(&info, &sl);
    CHECK_EQ_INT(st2, want);
    CHECK(want != ISOMEND_FILEIO_OK ? sl == NULL && strstr(msg, substring) != NULL
                                    : data && sl && memcmp(sl, data, 1000) == 0);
    free(sl);
    if (want != ISOMEND_FILEIO_OK) {
        CHECK(data == NULL);
        CHECK(strstr(msg, name) && strstr(msg, substring));
    } else if (mutate == 3) {
        CHECK(data && memcmp(data, payload, 500) == 0 && memcmp((char *)data + 500, payload, 500) == 0);
    } else {
        CHECK(data && memcmp(data, payload, 1000) == 0);
    }
    free(data);
}

static int machine_big(void)
{
    const uint16_t one = 1;
    unsigned char first;
    memcpy(&first, &one, 1);
    return first == 0;
}

/* Every type, raw and gzip, every combination of reversed axes: the slice
 * reader delivers exactly the volume that describe() presents. */
static void test_slice_reader(void)
{
    const int64_t d[3] = {5, 4, 6};
    for (int t = 0; t < ISOMEND_TYPE_COUNT; t++)
        for (int gz = 0; gz < 2; gz++)
            for (int neg = 0; neg < 8; neg++) {
                void *data = make_volume((isomend_type)t, d);
                size_t bytes = 120 * isomend_type_size((isomend_type)t);
                static const char *names[7] = {"uint8", "int8", "uint16", "int16", "int32", "float", "double"};
                char hdr[512];
                int n = snprintf(hdr, sizeof hdr,
                                 "NRRD0004\ntype: %s\ndimension: 3\nsizes: 5 4 6\nendian: %s\n"
                                 "space directions: (%d,0,0) (0,%d,0) (0,0,%d)\nencoding: %s\n\n",
                                 names[t], machine_big() ? "big" : "little", neg & 1 ? -1 : 1,
                                 neg & 2 ? -2 : 2, neg & 4 ? -3 : 3, gz ? "gzip" : "raw");
                unsigned char *file = malloc((size_t)n + 2 * bytes + 64);
                memcpy(file, hdr, (size_t)n);
                size_t z = gz ? gzip_bytes(data, bytes, file + n, 2 * bytes + 64) : bytes;
                if (!gz) memcpy(file + n, data, bytes);
                write_bytes(path_in("sl.nrrd"), file, (size_t)n + z);
                free(file);
                isomend_fileio_info info;
                CHECK_EQ_INT(isomend_fileio_probe_nrrd(path_in("sl.nrrd"), &info, msg, sizeof msg), ISOMEND_FILEIO_OK);
                void *whole = NULL, *sl = NULL;
                CHECK_EQ_INT(isomend_fileio_load(&info, &whole, NULL, NULL, msg, sizeof msg), ISOMEND_FILEIO_OK);
                isomend_fileio_status st = read_by_slices(&info, &sl);
                if (gz && (neg & 4)) {
                    /* the first slice is the end of the stream: refused, by name */
                    CHECK_EQ_INT(st, ISOMEND_FILEIO_ERR_UNSUPPORTED);
                    CHECK(strstr(msg, "sl.nrrd") && strstr(msg, "reverse the z axis"));
                } else {
                    CHECK_EQ_INT(st, ISOMEND_FILEIO_OK);
                    CHECK(whole && sl && same_as_described(&info, whole, sl));
                    /* seeking forwards and back (gzip: from the start again) */
                    isomend_fileio_slices *r;
                    CHECK_EQ_INT(isomend_fileio_slices_open(&info, &r, msg, sizeof msg), ISOMEND_FILEIO_OK);
                    size_t sb = (size_t)isomend_fileio_slices_bytes(r);
                    unsigned char one[5 * 4 * 8];
                    static const int order[4] = {4, 1, 5, 0};
                    for (int q = 0; q < 4 && sl; q++) {
                        CHECK_EQ_INT(isomend_fileio_slices_seek(r, order[q], msg, sizeof msg), ISOMEND_FILEIO_OK);
                        CHECK_EQ_INT(isomend_fileio_slices_next(r, one, sizeof one, msg, sizeof msg), ISOMEND_FILEIO_OK);
                        CHECK(memcmp(one, (unsigned char *)sl + sb * (size_t)order[q], sb) == 0);
                    }
                    isomend_fileio_slices_close(r);
                }
                free(whole);
                free(sl);
                free(data);
            }
}

static void test_gzip_errors(void)
{
    unsigned char payload[1200];
    for (int i = 0; i < 1200; i++) payload[i] = (unsigned char)((i * 7919) % 256);
    gzip_case("gz_ok.nrrd", payload, 1000, 0, ISOMEND_FILEIO_OK, "");
    gzip_case("gz_members.nrrd", payload, 500, 3, ISOMEND_FILEIO_OK, "");
    gzip_case("gz_short.nrrd", payload, 999, 0, ISOMEND_FILEIO_ERR_SIZE, "ends after 999");
    gzip_case("gz_extra.nrrd", payload, 1200, 0, ISOMEND_FILEIO_ERR_SIZE, "more than");
    gzip_case("gz_cut.nrrd", payload, 1000, 1, ISOMEND_FILEIO_ERR_SIZE, "truncated");
    gzip_case("gz_corrupt.nrrd", payload, 1000, 2, ISOMEND_FILEIO_ERR_CORRUPT, "corrupt");
}

/* ------------------------------------------------------------------ meshes */

/* A closed octahedron: 6 vertices, 8 triangles, outward winding. */
static const float octa_pos[18] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
static const uint32_t octa_tri[24] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4,
                                      2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};

static void expect_octahedron(const char *name, const isomend_read_mesh_result *m)
{
    CHECK_EQ_INT(m->vertex_count, 6);
    CHECK_EQ_INT(m->triangle_count, 8);
    isomend_check_report r;
    CHECK_EQ_INT(isomend_check(m->positions, m->vertex_count, m->triangles, m->triangle_count, NULL, &r),
                 ISOMEND_OK);
    if (r.hole_edges || r.nonmanifold_edges || r.misoriented_edges || r.euler != 2)
        fprintf(stderr, "%s: holes %llu, nonmanifold %llu, misoriented %llu, euler %lld\n", name,
                (unsigned long long)r.hole_edges, (unsigned long long)r.nonmanifold_edges,
                (unsigned long long)r.misoriented_edges, (long long)r.euler);
    CHECK(r.hole_edges == 0 && r.nonmanifold_edges == 0 && r.misoriented_edges == 0);
    CHECK_EQ_INT(r.euler, 2);
    CHECK_EQ_INT(r.edges, 12);
}

static void test_mesh_roundtrip(void)
{
    const char *names[] = {"octa.ply", "octa.obj", "octa.stl", "OCTA.PLY"};
    float normals[18];
    memcpy(normals, octa_pos, sizeof normals);
    for (int i = 0; i < 4; i++) {
        for (int with_normals = 0; with_normals < 2; with_normals++) {
            const char *p = path_in(names[i]);
            CHECK_EQ_INT(isomend_write_mesh(p, ISOMEND_MESH_UNKNOWN, octa_pos, with_normals ? normals : NULL,
                                            6, octa_tri, 8, msg, sizeof msg),
                         ISOMEND_FILEIO_OK);
            isomend_read_mesh_result m;
            CHECK_EQ_INT(isomend_read_mesh(p, &m, msg, sizeof msg), ISOMEND_FILEIO_OK);
            expect_octahedron(names[i], &m);
            if (i != 2) {
                CHECK(memcmp(m.positions, octa_pos, sizeof octa_pos) == 0);
                CHECK(memcmp(m.triangles, octa_tri, sizeof octa_tri) == 0);
            } else {
                CHECK_EQ_INT(m.stl_facets, 8);
            }
            isomend_read_mesh_free(&m);
        }
    }
    /* the PLY writer's exact header */
    FILE *fp = fopen(path_in("octa.ply"), "rb");
    char head[400] = "";
    if (fp) {
        size_t n = fread(head, 1, sizeof head - 1, fp);
        head[n] = '\0';
        fclose(fp);
    }
    CHECK(strstr(head, "format binary_little_endian 1.0\n") != NULL);
    CHECK(strstr(head, "property float nx\n") != NULL);
    CHECK(strstr(head, "property list uchar uint vertex_indices\n") != NULL);
    /* binary STL size = 84 + 50 per triangle */
    struct stat st;
    CHECK(stat(path_in("octa.stl"), &st) == 0 && st.st_size == 84 + 50 * 8);
    CHECK_EQ_INT(count_tmp_files(), 0);
}

static void test_foreign_meshes(void)
{
    isomend_read_mesh_result m;
    /* ascii PLY, extra properties, a quad split into two triangles, element after faces */
    write_text(path_in("a.ply"),
               "ply\nformat ascii 1.0\ncomment from another tool\nobj_info x\n"
               "element vertex 6\nproperty double x\nproperty double y\nproperty double z\n"
               "property uchar red\nproperty list uchar float texcoords\n"
               "element face 7\nproperty uchar flags\nproperty list uchar int vertex_index\n"
               "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
               "1 0 0 255 2 0.5 0.5\n-1 0 0 0 0\n0 1 0 1 0\n0 -1 0 1 1 0.1\n0 0 1 3 0\n0 0 -1 4 0\n"
               "0 4 0 2 4 1\n0 3 1 3 4\n0 3 3 0 4\n"
               "0 3 2 0 5\n0 3 1 2 5\n0 3 3 1 5\n0 3 0 3 5\n"
               "0 1\n");
    /* the quad "0 2 4 1" fan-splits into (0 2 4) and (0 4 1) */
    CHECK_EQ_INT(isomend_read_mesh(path_in("a.ply"), &m, msg, sizeof msg), ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(m.vertex_count, 6);
    CHECK_EQ_INT(m.triangle_count, 8);
    CHECK_EQ_INT(m.polygons_split, 1);
    CHECK(m.positions[3] == -1.0f && m.triangles[3] == 0 && m.triangles[4] == 4 && m.triangles[5] == 1);
    isomend_read_mesh_free(&m);

    /* big-endian binary PLY with an int16 extra property and uint8 count, int indices */
    {
        unsigned char buf[2048];
        const char *hdr = "ply\nformat binary_big_endian 1.0\nelement vertex 6\nproperty float x\n"
                          "property short quality\nproperty float y\nproperty float z\n"
                          "element face 8\nproperty list uchar int vertex_indices\nend_header\n";
        size_t n = strlen(hdr);
        memcpy(buf, hdr, n);
        for (int v = 0; v < 6; v++) {
            float xyz[3] = {octa_pos[3 * v], octa_pos[3 * v + 1], octa_pos[3 * v + 2]};
            for (int c = 0; c < 3; c++) {
                uint32_t bits;
                memcpy(&bits, &xyz[c], 4);
                for (int b = 3; b >= 0; b--) buf[n++] = (unsigned char)(bits >> (8 * b));
                if (c == 0) {
                    buf[n++] = 0x12;
                    buf[n++] = 0x34;
                }
            }
        }
        for (int t = 0; t < 8; t++) {
            buf[n++] = 3;
            for (int c = 0; c < 3; c++) {
                uint32_t i = octa_tri[3 * t + c];
                for (int b = 3; b >= 0; b--) buf[n++] = (unsigned char)(i >> (8 * b));
            }
        }
        write_bytes(path_in("be.ply"), buf, n);
        CHECK_EQ_INT(isomend_read_mesh(path_in("be.ply"), &m, msg, sizeof msg), ISOMEND_FILEIO_OK);
        expect_octahedron("be.ply", &m);
        CHECK(memcmp(m.positions, octa_pos, sizeof octa_pos) == 0);
        isomend_read_mesh_free(&m);
        /* truncated: the last face is incomplete */
        write_bytes(path_in("cut.ply"), buf, n - 3);
        CHECK_EQ_INT(isomend_read_mesh(path_in("cut.ply"), &m, msg, sizeof msg), ISOMEND_FILEIO_ERR_FORMAT);
        CHECK(strstr(msg, "cut.ply") && strstr(msg, "face"));
    }

    /* OBJ: v//vn, v/vt/vn, negative indices, comments, a quad face */
    write_text(path_in("q.obj"),
               "# cube-ish test\nmtllib x.mtl\no thing\nv 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\n"
               "v 0 0 1\nv 0 0 -1\nvn 0 0 1\nvt 0 0\ns off\n"
               "f 1//1 3//1 5//1\nf 3/1/1 2/1/1 5/1/1\nf 2 4 5\nf -3 -6 -2\n"
               "f 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6 # tail comment\n");
    CHECK_EQ_INT(isomend_read_mesh(path_in("q.obj"), &m, msg, sizeof msg), ISOMEND_FILEIO_OK);
    expect_octahedron("q.obj", &m);
    isomend_read_mesh_free(&m);
    write_text(path_in("bad.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    CHECK_EQ_INT(isomend_read_mesh(path_in("bad.obj"), &m, msg, sizeof msg), ISOMEND_FILEIO_ERR_FORMAT);
    CHECK(strstr(msg, "bad.obj") && strstr(msg, "line 4"));

    /* ascii STL with -0.0 that must weld with 0 */
    {
        char text[4096] = "solid octa\n";
        for (int t = 0; t < 8; t++) {
            strcat(text, "  facet normal 0 0 0\n    outer loop\n");
            for (int c = 0; c < 3; c++) {
                char line[128];
                const float *p = octa_pos + 3 * octa_tri[3 * t + c];
                snprintf(line, sizeof line, "      vertex %s%g %g %g\n",
                         (t % 2 && p[0] == 0) ? "-" : "", p[0], p[1], p[2]);
                strcat(text, line);
            }
            strcat(text, "    endloop\n  endfacet\n");
        }
        strcat(text, "endsolid octa\n");
        write_text(path_in("a.stl"), text);
        CHECK_EQ_INT(isomend_read_mesh(path_in("a.stl"), &m, msg, sizeof msg), ISOMEND_FILEIO_OK);
        expect_octahedron("a.stl", &m);
        CHECK(strcmp(m.encoding, "ascii") == 0);
        isomend_read_mesh_free(&m);
    }
    /* binary STL whose header starts with "solid" */
    {
        CHECK_EQ_INT(isomend_write_mesh(path_in("b.stl"), ISOMEND_MESH_STL, octa_pos, NULL, 6, octa_tri, 8,
                                        msg, sizeof msg),
                     ISOMEND_FILEIO_OK);
        FILE *fp = fopen(path_in("b.stl"), "r+b");
        if (fp) {
            fwrite("solid trap", 1, 10, fp);
            fclose(fp);
        }
        CHECK_EQ_INT(isomend_read_mesh(path_in("b.stl"), &m, msg, sizeof msg), ISOMEND_FILEIO_OK);
        expect_octahedron("b.stl", &m);
        CHECK(strcmp(m.encoding, "binary") == 0);
        isomend_read_mesh_free(&m);
    }
    write_text(path_in("junk.stl"), "this is not an stl file at all, just text\n");
    CHECK_EQ_INT(isomend_read_mesh(path_in("junk.stl"), &m, msg, sizeof msg), ISOMEND_FILEIO_ERR_FORMAT);
    CHECK(strstr(msg, "junk.stl") != NULL);
    CHECK_EQ_INT(isomend_read_mesh(path_in("none.ply"), &m, msg, sizeof msg), ISOMEND_FILEIO_ERR_NOT_FOUND);
    CHECK_EQ_INT(isomend_read_mesh(path_in("x.off"), &m, msg, sizeof msg), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
}

static void test_failed_writes_leave_nothing(void)
{
    const char *p = path_in("no/such/folder/m.ply");
    CHECK_EQ_INT(isomend_write_mesh(p, ISOMEND_MESH_UNKNOWN, octa_pos, NULL, 6, octa_tri, 8, msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_WRITE);
    CHECK(strstr(msg, "m.ply") != NULL);
    /* an index out of range is refused before anything is created */
    const uint32_t bad[3] = {0, 1, 6};
    CHECK_EQ_INT(isomend_write_mesh(path_in("bad.ply"), ISOMEND_MESH_UNKNOWN, octa_pos, NULL, 6, bad, 1, msg,
                                    sizeof msg),
                 ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(!exists(path_in("bad.ply")));
    CHECK_EQ_INT(isomend_write_mesh(path_in("m.xyz"), ISOMEND_MESH_UNKNOWN, octa_pos, NULL, 6, octa_tri, 8, msg,
                                    sizeof msg),
                 ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(msg, ".xyz") != NULL && !exists(path_in("m.xyz")));
    /* the output path is a folder */
    CHECK_EQ_INT(isomend_write_mesh(dir, ISOMEND_MESH_PLY, octa_pos, NULL, 6, octa_tri, 8, msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_WRITE);
    CHECK_EQ_INT(count_tmp_files(), 0);
}

int main(void)
{
    const char *base = getenv("TMPDIR");
    snprintf(dir, sizeof dir, "%s/isomend_fileio_XXXXXX", base && *base ? base : "/tmp");
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_roundtrip_all_types();
    test_big_endian_and_detached();
    test_negative_direction();
    test_slice_reader();
    test_header_errors();
    test_gzip_errors();
    test_mesh_roundtrip();
    test_foreign_meshes();
    test_failed_writes_leave_nothing();
    if (!tu_failures) {
        char cmd[600];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
        if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
    } else {
        fprintf(stderr, "files kept in %s\n", dir);
    }
    TEST_EXIT();
}
