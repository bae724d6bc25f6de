/*
 * test_io_nifti.c - the NIfTI source of isomend_io (nifti.cpp) through the C API
 *
 * The files are written here byte by byte (a NIfTI-1 header is 348 bytes of
 * plain fields), independently of libnifti and nibabel, in both byte orders:
 * - an int16 volume with an sform (a mirror and a quarter turn), scl_slope 2
 *   and scl_inter -1024: kind "nifti", format "nifti1", dims, type i32,
 *   spacing = pixdim, isomend_io_nifti_info() (also a smaller struct filled
 *   only up to its size), the world transform F A diag(1/spacing) in LPS,
 *   RAS and grid axes, the origin L^-1 F t, options.origin, the values
 *   (stored * 2 - 1024) by isomend_io_read(), every isomend_io_read_slice()
 *   and isomend_io_load(), isomend_io_analyse() streamed (no load) and loaded;
 * - the same file big-endian: the same bytes delivered;
 * - uint32 without scaling: f64, exact;
 * - a job (isomend_io_job_start) gives isomend_io_extract()'s mesh;
 * - refused, with the file named: a truncated file, an RGB24 datatype, a 4D
 *   file with two volumes, slice_positions; RAS axes for a raw source.
 *
 * Usage: test_io_nifti DIR   (a writable folder)
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "isomend.h"
#include "isomend_io.h"
#include "testutil.h"

enum { NX = 8, NY = 7, NZ = 6 };

static const char *g_dir;

typedef struct header {
    int16_t dim[8];
    int16_t datatype, bitpix;
    float pixdim[8];
    float slope, inter;
    int16_t qform_code, sform_code;
    float quatern[6];
    float srow[12];
    char units;
} header;

static void put(unsigned char *b, size_t off, const void *v, size_t size, int big)
{
    for (size_t i = 0; i < size; i++) b[off + i] = ((const unsigned char *)v)[big ? size - 1 - i : i];
}

/* A NIfTI-1 single file (.nii): header, 4 zero bytes, data (n samples of
 * `size` bytes, swapped when big) cut to `keep` bytes of data if keep >= 0. */
static const char *write_nii(const char *name, const header *h, const void *data, size_t n, size_t size,
                             int big, long keep)
{
    unsigned char b[352];
    memset(b, 0, sizeof b);
    int32_t sizeof_hdr = 348;
    float vox_offset = 352.0f;
    put(b, 0, &sizeof_hdr, 4, big);
    for (int i = 0; i < 8; i++) put(b, 40 + 2 * (size_t)i, &h->dim[i], 2, big);
    put(b, 70, &h->datatype, 2, big);
    put(b, 72, &h->bitpix, 2, big);
    for (int i = 0; i < 8; i++) put(b, 76 + 4 * (size_t)i, &h->pixdim[i], 4, big);
    put(b, 108, &vox_offset, 4, big);
    put(b, 112, &h->slope, 4, big);
    put(b, 116, &h->inter, 4, big);
    b[123] = (unsigned char)h->units;
    put(b, 252, &h->qform_code, 2, big);
    put(b, 254, &h->sform_code, 2, big);
    for (int i = 0; i < 6; i++) put(b, 256 + 4 * (size_t)i, &h->quatern[i], 4, big);
    for (int i = 0; i < 12; i++) put(b, 280 + 4 * (size_t)i, &h->srow[i], 4, big);
    memcpy(b + 344, "n+1", 4);
    const char *path = tu_path_in(g_dir, name);
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL);
    if (!f) return path;
    fwrite(b, 1, sizeof b, f);
    size_t total = n * size, limit = keep >= 0 ? (size_t)keep : total;
    for (size_t i = 0; i < n && i * size < limit; i++) {
        unsigned char s[8];
        put(s, 0, (const unsigned char *)data + i * size, size, big);
        fwrite(s, 1, size, f);
    }
    fclose(f);
    return path;
}

static header base_header(int16_t datatype, int16_t bitpix)
{
    header h;
    memset(&h, 0, sizeof h);
    h.dim[0] = 3;
    h.dim[1] = NX;
    h.dim[2] = NY;
    h.dim[3] = NZ;
    for (int i = 4; i < 8; i++) h.dim[i] = 1;
    h.datatype = datatype;
    h.bitpix = bitpix;
    h.pixdim[0] = 1;
    h.pixdim[1] = 0.5f;
    h.pixdim[2] = 0.75f;
    h.pixdim[3] = 2.0f;
    for (int i = 4; i < 8; i++) h.pixdim[i] = 1;
    h.units = 2; /* mm */
    /* sform: i -> -y (mirror), j -> +x, k -> +z; translation (10, -20, 5) */
    const float s[12] = {0, 0.75f, 0, 10, -0.5f, 0, 0, -20, 0, 0, 2.0f, 5};
    memcpy(h.srow, s, sizeof s);
    h.sform_code = 2;
    return h;
}

static isomend_io_source *open_path(const char *path, int axes, const isomend_io_options *o,
                                    isomend_io_status *st)
{
    isomend_io_source *src = NULL;
    isomend_io_create(&src);
    if (axes >= 0) isomend_io_set_axes(src, axes);
    *st = isomend_io_open(src, &path, 1, o);
    return src;
}

/* The refusal of a bad file: status and a message naming it with `words`. */
static void refused(const char *path, isomend_io_status want, const char *words)
{
    isomend_io_status st;
    isomend_io_source *src = open_path(path, -1, NULL, &st);
    const char *m = isomend_io_message(src);
    const char *base = strrchr(path, '/') ? strrchr(path, '/') + 1 : path;
    if (st == ISOMEND_IO_OK) { /* gzip defects show at read */
        int64_t d[3];
        isomend_io_dims(src, d);
        void *buf = malloc(isomend_io_volume_bytes(src));
        st = isomend_io_read(src, buf, isomend_io_volume_bytes(src));
        free(buf);
        m = isomend_io_message(src);
    }
    CHECK_EQ_INT(st, want);
    CHECK(strstr(m, base) != NULL && strstr(m, words) != NULL);
    if (!(strstr(m, base) && strstr(m, words))) fprintf(stderr, "  message: %s (want %s)\n", m, words);
    isomend_io_destroy(src);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: test_io_nifti DIR\n");
        return 2;
    }
    g_dir = argv[1];
    const size_t n = (size_t)NX * NY * NZ;
    int16_t *stored = malloc(n * sizeof *stored);
    int32_t *want = malloc(n * sizeof *want);
    for (size_t i = 0; i < n; i++) {
        size_t x = i % NX, y = i / NX % NY, z = i / (NX * NY);
        double r = sqrt(pow((double)x - 3.6, 2) + pow((double)y - 3.1, 2) + pow((double)z - 2.4, 2));
        stored[i] = (int16_t)(1200 - 300 * r + (int)(i % 5));
        want[i] = stored[i] * 2 - 1024;
    }
    header h = base_header(4 /* INT16 */, 16);
    h.slope = 2.0f;
    h.inter = -1024.0f;
    char le_name[64], be_name[64];
    snprintf(le_name, sizeof le_name, "le.nii");
    snprintf(be_name, sizeof be_name, "be.nii");
    char le[600], be[600];
    snprintf(le, sizeof le, "%s", write_nii(le_name, &h, stored, n, 2, 0, -1));
    snprintf(be, sizeof be, "%s", write_nii(be_name, &h, stored, n, 2, 1, -1));

    /* ---- the scaled, mirrored int16 volume, both byte orders ---- */
    const double F[3] = {-1, -1, 1};
    const double A[12] = {0, 0.75, 0, 10, -0.5, 0, 0, -20, 0, 0, 2, 5};
    const double sp[3] = {0.5, 0.75, 2.0};
    for (int file = 0; file < 2; file++) {
        isomend_io_status st;
        isomend_io_source *src = open_path(file ? be : le, -1, NULL, &st);
        CHECK_EQ_INT(st, ISOMEND_IO_OK);
        if (st) {
            fprintf(stderr, "%s\n", isomend_io_message(src));
            isomend_io_destroy(src);
            continue;
        }
        CHECK_EQ_INT(isomend_io_source_kind(src), ISOMEND_IO_KIND_NIFTI);
        CHECK(strcmp(isomend_io_kind_name(ISOMEND_IO_KIND_NIFTI), "nifti") == 0);
        CHECK(strcmp(isomend_io_format(src), "nifti1") == 0);
        int64_t d[3];
        isomend_io_dims(src, d);
        CHECK(d[0] == NX && d[1] == NY && d[2] == NZ);
        isomend_type t;
        isomend_io_type(src, &t);
        CHECK_EQ_INT(t, ISOMEND_I32);
        double s[3], o[3], W[12];
        int from[3], identity = 1;
        isomend_io_spacing(src, s, from);
        for (int a = 0; a < 3; a++) CHECK(s[a] == sp[a] && from[a] == ISOMEND_IO_SPACING_HEADER);
        isomend_io_nifti info;
        memset(&info, 0, sizeof info);
        info.size = sizeof info;
        CHECK_EQ_INT(isomend_io_nifti_info(src, &info), ISOMEND_IO_OK);
        CHECK(info.version == 1 && !info.two_files && !info.gzip && info.scaled && info.scl_slope == 2 &&
              info.scl_inter == -1024 && info.sform_code == 2 && info.qform_code == 0 &&
              strcmp(info.transform, "sform") == 0 && info.axes == ISOMEND_IO_AXES_PATIENT);
        for (int i = 0; i < 12; i++) CHECK(info.file_affine[i] == A[i]);
        isomend_io_nifti small;
        memset(&small, 0x5a, sizeof small);
        small.size = offsetof(isomend_io_nifti, gzip);
        CHECK_EQ_INT(isomend_io_nifti_info(src, &small), ISOMEND_IO_OK);
        CHECK(small.version == 1 && ((unsigned char *)&small)[offsetof(isomend_io_nifti, gzip)] == 0x5a);
        /* world = L (origin + index * spacing) + t' must be F (A [index, 1]) */
        isomend_io_world_transform(src, W, &identity);
        isomend_io_origin(src, o);
        CHECK(!identity);
        const double idx[2][3] = {{0, 0, 0}, {NX - 1, 2, NZ - 1}};
        for (int c = 0; c < 2; c++)
            for (int r = 0; r < 3; r++) {
                double got = W[4 * r + 3], wantw = A[4 * r + 3];
                for (int a = 0; a < 3; a++) {
                    got += W[4 * r + a] * (o[a] + idx[c][a] * s[a]);
                    wantw += A[4 * r + a] * idx[c][a];
                }
                CHECK(fabs(got - F[r] * wantw) < 1e-9);
            }
        /* the values: read, every slice, load */
        size_t vb = (size_t)isomend_io_volume_bytes(src), sb = (size_t)isomend_io_slice_bytes(src);
        CHECK(vb == n * 4 && sb == (size_t)NX * NY * 4);
        int32_t *got = malloc(vb);
        CHECK_EQ_INT(isomend_io_read(src, got, vb), ISOMEND_IO_OK);
        CHECK(memcmp(got, want, vb) == 0);
        for (int64_t k = 0; k < NZ; k++) {
            CHECK_EQ_INT(isomend_io_read_slice(src, k, got, sb), ISOMEND_IO_OK);
            CHECK(memcmp(got, want + (size_t)k * NX * NY, sb) == 0);
        }
        isomend_io_summary sum; /* streamed: nothing loaded yet */
        CHECK_EQ_INT(isomend_io_analyse(src, &sum), ISOMEND_IO_OK);
        int32_t mn = want[0], mx = want[0];
        for (size_t i = 0; i < n; i++) {
            if (want[i] < mn) mn = want[i];
            if (want[i] > mx) mx = want[i];
        }
        CHECK(sum.min == mn && sum.max == mx && sum.samples == n);
        isomend_volume vol;
        CHECK_EQ_INT(isomend_io_load(src, &vol, NULL), ISOMEND_IO_OK);
        CHECK(vol.type == ISOMEND_I32 && memcmp(vol.data, want, vb) == 0 && vol.spacing[1] == 0.75);
        free(got);
        isomend_io_destroy(src);
    }

    /* ---- RAS and grid axes; options.origin ---- */
    {
        isomend_io_status st;
        double W[12], o[3];
        int identity;
        isomend_io_source *src = open_path(le, ISOMEND_IO_AXES_RAS, NULL, &st);
        CHECK_EQ_INT(st, ISOMEND_IO_OK);
        isomend_io_world_transform(src, W, &identity);
        isomend_io_origin(src, o);
        /* L = A diag(1/sp) = [[0,1,0],[-1,0,0],[0,0,1]]: voxel 0 at (10, -20, 5) */
        CHECK(!identity && W[1] == 1 && W[4] == -1 && W[10] == 1);
        for (int r = 0; r < 3; r++)
            CHECK(fabs(W[4 * r] * o[0] + W[4 * r + 1] * o[1] + W[4 * r + 2] * o[2] + W[4 * r + 3] - A[4 * r + 3]) <
                  1e-12);
        isomend_io_nifti info = {.size = sizeof info};
        isomend_io_nifti_info(src, &info);
        CHECK_EQ_INT(info.axes, ISOMEND_IO_AXES_RAS);
        isomend_io_destroy(src);
        src = open_path(le, ISOMEND_IO_AXES_GRID, NULL, &st);
        CHECK_EQ_INT(st, ISOMEND_IO_OK);
        isomend_io_world_transform(src, W, &identity);
        CHECK(identity);
        isomend_io_destroy(src);
        isomend_io_options opts;
        isomend_io_options_init(&opts);
        opts.origin[0] = 1;
        opts.origin[1] = 2;
        opts.origin[2] = 3;
        src = open_path(le, -1, &opts, &st);
        CHECK_EQ_INT(st, ISOMEND_IO_OK);
        isomend_io_world_transform(src, W, &identity);
        isomend_io_origin(src, o);
        for (int r = 0; r < 3; r++)
            CHECK(fabs(W[4 * r] * o[0] + W[4 * r + 1] * o[1] + W[4 * r + 2] * o[2] + W[4 * r + 3] - (r + 1)) <
                  1e-12);
        isomend_io_destroy(src);
    }

    /* ---- uint32 unscaled: f64, exact ---- */
    {
        uint32_t *u = malloc(n * 4);
        for (size_t i = 0; i < n; i++) u[i] = 4000000000u - (uint32_t)i * 7u;
        header hu = base_header(768 /* UINT32 */, 32);
        const char *path = write_nii("u32.nii", &hu, u, n, 4, 0, -1);
        isomend_io_status st;
        isomend_io_source *src = open_path(path, -1, NULL, &st);
        CHECK_EQ_INT(st, ISOMEND_IO_OK);
        isomend_type t;
        isomend_io_type(src, &t);
        CHECK_EQ_INT(t, ISOMEND_F64);
        double *g = malloc(n * 8);
        CHECK_EQ_INT(isomend_io_read(src, g, n * 8), ISOMEND_IO_OK);
        int same = 1;
        for (size_t i = 0; i < n; i++) same &= g[i] == (double)u[i];
        CHECK(same);
        free(g);
        free(u);
        isomend_io_destroy(src);
    }

    /* ---- a job gives isomend_io_extract()'s mesh ---- */
    {
        isomend_io_status st;
        isomend_io_source *a = open_path(le, -1, NULL, &st);
        isomend_options eo;
        isomend_options_init(&eo);
        eo.iso = 500;
        eo.flags |= ISOMEND_FLAG_PAD;
        isomend_mesh *m1 = NULL, *m2 = NULL;
        CHECK_EQ_INT(isomend_io_extract(a, &eo, 0, NULL, &m1, NULL), ISOMEND_IO_OK);
        isomend_io_source *b = NULL;
        isomend_io_create(&b);
        isomend_io_job *job = NULL;
        const char *p = le;
        CHECK_EQ_INT(isomend_io_job_start(b, &p, 1, NULL, &eo, 0, &job), ISOMEND_IO_OK);
        CHECK_EQ_INT(isomend_io_job_finish(job, NULL, &m2, NULL), ISOMEND_IO_OK);
        CHECK(m1 && m2 && isomend_mesh_vertex_count(m1) > 20 &&
              isomend_mesh_vertex_count(m1) == isomend_mesh_vertex_count(m2) &&
              isomend_mesh_triangle_count(m1) == isomend_mesh_triangle_count(m2));
        CHECK_EQ_INT(isomend_io_source_kind(b), ISOMEND_IO_KIND_NIFTI);
        isomend_mesh_destroy(m1);
        isomend_mesh_destroy(m2);
        isomend_io_destroy(a);
        isomend_io_destroy(b);
    }

    /* ---- refused ---- */
    refused(write_nii("truncated.nii", &h, stored, n, 2, 0, (long)(n * 2 / 2)), ISOMEND_IO_ERR_CORRUPT,
            "truncated");
    header rgb = base_header(128 /* RGB24 */, 24);
    unsigned char *rgbdata = calloc(n, 3);
    refused(write_nii("rgb.nii", &rgb, rgbdata, n, 3, 0, -1), ISOMEND_IO_ERR_UNSUPPORTED, "RGB");
    free(rgbdata);
    header four = h;
    four.dim[0] = 4;
    four.dim[4] = 2;
    int16_t *two = calloc(2 * n, 2);
    refused(write_nii("two_volumes.nii", &four, two, 2 * n, 2, 0, -1), ISOMEND_IO_ERR_UNSUPPORTED, "2 volumes");
    free(two);
    refused(tu_path_in(g_dir, "missing.nii"), ISOMEND_IO_ERR_NOT_FOUND, "not found");
    {
        isomend_io_options opts;
        isomend_io_options_init(&opts);
        double z[NZ] = {0, 1, 2, 3, 4, 5};
        opts.slice_positions = z;
        opts.slice_position_count = NZ;
        isomend_io_status st;
        isomend_io_source *src = open_path(le, -1, &opts, &st);
        CHECK_EQ_INT(st, ISOMEND_IO_ERR_INVALID_ARGUMENT);
        CHECK(strstr(isomend_io_message(src), "slice_positions") != NULL);
        isomend_io_destroy(src);
        /* RAS axes for a raw file: refused */
        isomend_io_options_init(&opts);
        opts.raw_dims[0] = NX * 2;
        opts.raw_dims[1] = NY;
        opts.raw_dims[2] = NZ;
        opts.raw_type = ISOMEND_U8;
        opts.raw_header = 352;
        src = open_path(le, ISOMEND_IO_AXES_RAS, &opts, &st);
        CHECK_EQ_INT(st, ISOMEND_IO_ERR_INVALID_ARGUMENT);
        CHECK(strstr(isomend_io_message(src), "NIfTI") != NULL);
        isomend_io_destroy(src);
    }
    free(stored);
    free(want);
    TEST_EXIT();
}
