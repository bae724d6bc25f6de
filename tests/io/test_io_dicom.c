/*
 * test_io_dicom.c - the DICOM source of isomend_io against gen_dicom.py's series
 *
 * For every good case of manifest.tsv: the source opens as kind "dicom" with
 * the dimensions, type, spacing, origin and world transform that were
 * meant; isomend_io_read() and every isomend_io_read_slice() deliver the
 * expected volume byte for byte (sorted along the normal, rescaled,
 * inverted); for a CT case, the levels.  The slices' geometry: a uniform
 * series has no slice origins (NULL), any other (rounded positions, two
 * spacings, a gantry tilt, a missing slice) exactly the origins gen_dicom.py
 * computed from the values it wrote (1e-9 relative), also in the volume
 * isomend_io_load() describes; the warning where the gaps vary, not
 * elsewhere; the tilt and the long gaps.  For every defect: the status, a
 * message with the expected words that names a file of the series, and no
 * volume.  Then a mesh through the world transform: closed and oriented,
 * at the patient positions A * grid, and outward (positive volume); and
 * meshes of the unevenly placed series: every vertex between two samples'
 * true positions, closed with --pad.
 *
 * Usage: test_io_dicom DIR   (DIR holds manifest.tsv, from gen_dicom.py)
 */
#define _POSIX_C_SOURCE 200809L
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "isomend.h"
#include "isomend_io.h"
#include "testutil.h"

static const char *g_dir;

static char *join(const char *rel)
{
    size_t n = strlen(g_dir) + strlen(rel) + 2;
    char *p = malloc(n);
    snprintf(p, n, "%s/%s", g_dir, rel);
    return p;
}

static void *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    void *b = malloc(n > 0 ? (size_t)n : 1);
    *size = fread(b, 1, (size_t)n, f);
    fclose(f);
    return b;
}

#define MAX_FIELDS 128

static isomend_io_status open_case(char **src, int nsrc, const char *series, int axes,
                                   isomend_io_source **out)
{
    const char *paths[MAX_FIELDS];
    char *owned[MAX_FIELDS];
    for (int i = 0; i < nsrc; i++) paths[i] = owned[i] = join(src[i]);
    isomend_io_source *s = NULL;
    CHECK(isomend_io_create(&s) == ISOMEND_IO_OK);
    if (strcmp(series, "-") != 0) CHECK(isomend_io_set_series(s, series) == ISOMEND_IO_OK);
    CHECK(isomend_io_set_axes(s, axes) == ISOMEND_IO_OK);
    isomend_io_options o;
    isomend_io_options_init(&o);
    o.threads = 2;
    isomend_io_status st = isomend_io_open(s, paths, (size_t)nsrc, &o);
    for (int i = 0; i < nsrc; i++) free(owned[i]);
    *out = s;
    return st;
}

static int close_to(double a, double b, double tol) { return fabs(a - b) <= tol * (1.0 + fabs(b)); }

/* The slice origins of a case (3 a slice), or NULL for "-". */
static double *read_origins(const char *rel, int64_t nz)
{
    if (strcmp(rel, "-") == 0)
        return NULL;
    char *path = join(rel);
    FILE *fp = fopen(path, "r");
    free(path);
    CHECK(fp != NULL);
    if (!fp)
        return NULL;
    double *o = malloc(sizeof(double) * 3 * (size_t)nz);
    for (int64_t i = 0; i < 3 * nz; i++)
        CHECK(fscanf(fp, "%lf", &o[i]) == 1);
    fclose(fp);
    return o;
}

/* The geometry of an opened case against the manifest's. */
static void check_geometry(isomend_io_source *s, const char *name, int64_t nz, const double *want,
                           int warn, double tilt, int64_t long_gaps, double gap)
{
    isomend_io_geometry g;
    memset(&g, 0, sizeof g);
    g.size = sizeof g;
    CHECK(isomend_io_geometry_info(s, &g) == ISOMEND_IO_OK);
    const double *got = isomend_io_slice_origins(s);
    CHECK_EQ_INT(g.uniform, want == NULL);
    CHECK((got == NULL) == (want == NULL));
    if (got && want) {
        double worst = 0;
        for (int64_t i = 0; i < 3 * nz; i++)
            worst = fmax(worst, fabs(got[i] - want[i]) / fmax(1.0, fabs(want[i])));
        if (worst > 1e-9) {
            fprintf(stderr, "%s: slice origins differ by %.3g (relative)\n", name, worst);
            CHECK(0);
        }
    }
    CHECK(g.warning != NULL);
    if (g.warning && (g.warning[0] != 0) != (warn != 0)) {
        fprintf(stderr, "%s: warning \"%s\", expected %s\n", name, g.warning,
                warn ? "one" : "none");
        CHECK(0);
    }
    if (g.warning && g.warning[0]) {
        printf("  %s: %s\n", name, g.warning);
        CHECK(strchr(g.warning, '\n') == NULL && strstr(g.warning, "slice gaps vary from"));
        CHECK(strstr(g.warning, "meshed at the slices' true positions") != NULL);
    }
    if (fabs(g.tilt_degrees - tilt) > 1e-6) {
        fprintf(stderr, "%s: tilt %.9g degrees, expected %.9g\n", name, g.tilt_degrees, tilt);
        CHECK(0);
    }
    CHECK_EQ_INT(g.long_gaps, long_gaps);
    CHECK(g.gap_min > 0 && g.gap_min <= g.gap_median && g.gap_median <= g.gap_max);
    CHECK(want != NULL ||
          g.max_offset <= 1e-4 * 0.5); /* uniform: within 1e-4 of a pixel (>= 0.5 mm here) */
    CHECK(want == NULL || g.max_offset > 0);
    if (!warn)
        CHECK_EQ_INT(g.uneven_gaps, 0);
    else
        CHECK(g.uneven_gaps > 0);
    if (want == NULL && !close_to(g.gap_median, gap, 1e-6)) {
        fprintf(stderr, "%s: median gap %.9g of a uniform series, spacing %.9g\n", name,
                g.gap_median, gap);
        CHECK(0);
    }
    if (long_gaps > 0 && g.warning) {
        /* names the files on both sides of the longest gap */
        CHECK(strstr(g.warning, "missing slice") != NULL);
        int named = 0;
        for (int64_t k = 0; k + 1 < nz; k++) {
            if (want && want[3 * (k + 1) + 2] - want[3 * k + 2] < g.gap_max * (1 - 1e-9))
                continue;
            const char *a = isomend_io_slice_path(s, k), *b = isomend_io_slice_path(s, k + 1);
            const char *ba = strrchr(a, '/'), *bb = strrchr(b, '/');
            if (strstr(g.warning, ba ? ba + 1 : a) && strstr(g.warning, bb ? bb + 1 : b))
                named = 1;
        }
        CHECK(named);
    }
    /* a smaller struct from an older caller: only its bytes are written */
    isomend_io_geometry small;
    memset(&small, 0x5a, sizeof small);
    small.size = offsetof(isomend_io_geometry, gap_min);
    CHECK(isomend_io_geometry_info(s, &small) == ISOMEND_IO_OK);
    CHECK(((unsigned char *)&small)[offsetof(isomend_io_geometry, gap_min)] == 0x5a);
}

static void run_ok(char **f, int nf)
{
    /* ok NAME TYPE NX NY NZ EXP SX SY SZ OX OY OZ A0..A11 SERIES AXES ORIGINS WARN TILT LONG SOURCE... */
    const char *name = f[1];
    int64_t want[3] = {atoll(f[3]), atoll(f[4]), atoll(f[5])};
    double sp[3], org[3], aff[12];
    for (int a = 0; a < 3; a++) sp[a] = atof(f[7 + a]);
    for (int a = 0; a < 3; a++) org[a] = atof(f[10 + a]);
    for (int i = 0; i < 12; i++) aff[i] = atof(f[13 + i]);
    const char *series = f[25];
    int axes = atoi(f[26]);
    double *origins = read_origins(f[27], want[2]);
    int warn = atoi(f[28]);
    double tilt = atof(f[29]);
    int64_t long_gaps = atoll(f[30]);
    isomend_io_source *s;
    isomend_io_status st = open_case(f + 31, nf - 31, series, axes, &s);
    if (st != ISOMEND_IO_OK) {
        fprintf(stderr, "%s: open failed: %s\n", name, isomend_io_message(s));
        CHECK(0);
        isomend_io_destroy(s);
        free(origins);
        return;
    }
    CHECK_EQ_INT(isomend_io_source_kind(s), ISOMEND_IO_KIND_DICOM);
    check_geometry(s, name, want[2], origins, warn, tilt, long_gaps, sp[2]);
    CHECK(strcmp(isomend_io_format(s), "dicom") == 0);
    int64_t dims[3];
    CHECK(isomend_io_dims(s, dims) == ISOMEND_IO_OK);
    for (int a = 0; a < 3; a++) CHECK_EQ_INT(dims[a], want[a]);
    isomend_type t;
    CHECK(isomend_io_type(s, &t) == ISOMEND_IO_OK);
    if (strcmp(isomend_type_name(t), f[2]) != 0) {
        fprintf(stderr, "%s: type %s, expected %s\n", name, isomend_type_name(t), f[2]);
        CHECK(0);
    }
    double got_sp[3], got_org[3], got_aff[12];
    int from[3], identity = -1;
    CHECK(isomend_io_spacing(s, got_sp, from) == ISOMEND_IO_OK);
    CHECK(isomend_io_origin(s, got_org) == ISOMEND_IO_OK);
    CHECK(isomend_io_world_transform(s, got_aff, &identity) == ISOMEND_IO_OK);
    for (int a = 0; a < 3; a++) {
        if (!close_to(got_sp[a], sp[a], 1e-6) || !close_to(got_org[a], org[a], 1e-5)) {
            fprintf(stderr, "%s: axis %d spacing %.9g origin %.9g, expected %.9g %.9g\n", name, a,
                    got_sp[a], got_org[a], sp[a], org[a]);
            CHECK(0);
        }
    }
    CHECK_EQ_INT(from[0], ISOMEND_IO_SPACING_DICOM);
    CHECK_EQ_INT(from[2], ISOMEND_IO_SPACING_POSITIONS);
    int want_identity = 1;
    for (int i = 0; i < 12; i++) {
        if (aff[i] != (i % 5 == 0 ? 1.0 : 0.0)) want_identity = 0;
        if (fabs(got_aff[i] - aff[i]) > 1e-6 * (1 + fabs(aff[i]))) {
            fprintf(stderr, "%s: affine[%d] %.12g, expected %.12g\n", name, i, got_aff[i], aff[i]);
            CHECK(0);
        }
    }
    CHECK_EQ_INT(identity, want_identity);
    isomend_io_dicom info;
    memset(&info, 0, sizeof info);
    info.size = sizeof info;
    CHECK(isomend_io_dicom_info(s, &info) == ISOMEND_IO_OK);
    CHECK_EQ_INT(info.axes, axes);
    CHECK(info.series_uid && info.series_uid[0]);
    CHECK(isomend_io_series_chosen(s) >= 0 && isomend_io_series_chosen(s) < isomend_io_series_count(s));
    /* the volume, byte for byte */
    char *exp_path = join(f[6]);
    size_t exp_size = 0;
    void *exp = slurp(exp_path, &exp_size);
    CHECK(exp != NULL);
    uint64_t vb = isomend_io_volume_bytes(s);
    CHECK_EQ_INT(vb, exp_size);
    void *buf = malloc((size_t)vb);
    CHECK(isomend_io_read(s, buf, (size_t)vb) == ISOMEND_IO_OK);
    if (exp && exp_size == vb && memcmp(buf, exp, (size_t)vb) != 0) {
        fprintf(stderr, "%s: volume differs from %s\n", name, exp_path);
        CHECK(0);
    }
    uint64_t sb = isomend_io_slice_bytes(s);
    void *one = malloc((size_t)sb);
    for (int64_t k = 0; k < dims[2]; k += dims[2] > 6 ? dims[2] / 5 : 1) {
        CHECK(isomend_io_read_slice(s, k, one, (size_t)sb) == ISOMEND_IO_OK);
        if (exp && exp_size == vb) CHECK(memcmp(one, (char *)exp + (size_t)k * sb, (size_t)sb) == 0);
    }
    /* the levels: CT in HU has bone and skin, others refuse them */
    double level = 0;
    isomend_io_status lst = isomend_io_level_value(s, ISOMEND_IO_LEVEL_BONE, &level);
    if (info.hounsfield) {
        CHECK(lst == ISOMEND_IO_OK && level == 300.0);
        CHECK(isomend_io_level_value(s, ISOMEND_IO_LEVEL_SKIN, &level) == ISOMEND_IO_OK && level == -500.0);
        CHECK_EQ_INT(isomend_io_suggested_level(s), ISOMEND_IO_LEVEL_BONE);
        isomend_io_summary sum;
        CHECK(isomend_io_analyse(s, &sum) == ISOMEND_IO_OK && sum.suggested_iso == 300.0);
    } else {
        CHECK(lst == ISOMEND_IO_ERR_UNSUPPORTED && strstr(isomend_io_message(s), "Hounsfield"));
        CHECK_EQ_INT(isomend_io_suggested_level(s), ISOMEND_IO_LEVEL_OTSU);
    }
    CHECK(isomend_io_level_value(s, ISOMEND_IO_LEVEL_OTSU, &level) == ISOMEND_IO_OK);
    /* the volume isomend_io_load() describes carries the slice origins */
    isomend_volume vol;
    memset(&vol, 0x5a, sizeof vol);
    CHECK(isomend_io_load(s, &vol, NULL) == ISOMEND_IO_OK);
    CHECK(vol.slice_origins == isomend_io_slice_origins(s));
    for (int a = 0; a < 3; a++)
        CHECK(close_to(vol.origin[a], org[a], 1e-5) && close_to(vol.spacing[a], sp[a], 1e-6));
    free(origins);
    free(one);
    free(buf);
    free(exp);
    free(exp_path);
    isomend_io_destroy(s);
}

static void run_err(char **f, int nf)
{
    /* err NAME STATUS SUBSTRING SERIES SOURCE... */
    const char *name = f[1];
    int want = atoi(f[2]);
    isomend_io_source *s;
    isomend_io_status st = open_case(f + 5, nf - 5, f[4], 0, &s);
    if (st == ISOMEND_IO_OK) { /* defects in the pixel data show when reading */
        isomend_volume vol;
        st = isomend_io_load(s, &vol, NULL);
    }
    const char *msg = isomend_io_message(s);
    if ((int)st != want || !strstr(msg, f[3]) || !strstr(msg, g_dir)) {
        fprintf(stderr, "%s: status %d (%s), expected %d with \"%s\" naming a file of %s\n", name,
                (int)st, msg, want, f[3], g_dir);
        CHECK(0);
    }
    if (want == ISOMEND_IO_ERR_SERIES) CHECK(isomend_io_series_count(s) >= 2);
    isomend_io_destroy(s);
}

/* A mesh of the oblique CT through the world transform: closed, oriented,
 * outward, at A * (grid position). */
static void mesh_through_transform(void)
{
    char *src[1] = {"ct_oblique"};
    isomend_io_source *s;
    if (open_case(src, 1, "-", 0, &s) != ISOMEND_IO_OK) {
        fprintf(stderr, "ct_oblique: %s\n", isomend_io_message(s));
        CHECK(0);
        isomend_io_destroy(s);
        return;
    }
    isomend_options o;
    isomend_options_init(&o);
    o.flags = ISOMEND_FLAG_PAD;
    isomend_mesh *m = NULL;
    double iso = 0;
    CHECK(isomend_io_extract(s, &o, 1, &iso, &m, NULL) == ISOMEND_IO_OK);
    CHECK(iso == 300.0);
    double A[12];
    int identity = 1;
    CHECK(isomend_io_world_transform(s, A, &identity) == ISOMEND_IO_OK && identity == 0);
    size_t nv = isomend_mesh_vertex_count(m), nt = isomend_mesh_triangle_count(m);
    CHECK(nt > 1000);
    float *p = malloc(sizeof(float) * 3 * nv), *n = malloc(sizeof(float) * 3 * nv);
    uint32_t *tri = malloc(sizeof(uint32_t) * 3 * nt);
    CHECK(isomend_mesh_copy_transformed(m, A, p, n, tri, NULL) == ISOMEND_OK);
    const float *g = isomend_mesh_positions(m);
    double worst = 0;
    for (size_t i = 0; i < nv; i++)
        for (int r = 0; r < 3; r++) {
            double w = A[4 * r] * g[3 * i] + A[4 * r + 1] * g[3 * i + 1] + A[4 * r + 2] * g[3 * i + 2] + A[4 * r + 3];
            worst = fmax(worst, fabs(w - p[3 * i + r]));
        }
    CHECK(worst < 1e-4);
    isomend_check_report rep;
    CHECK(isomend_check(p, nv, tri, nt, NULL, &rep) == ISOMEND_OK);
    CHECK_EQ_INT(rep.hole_edges + rep.border_edges, 0);
    CHECK_EQ_INT(rep.nonmanifold_edges, 0);
    CHECK_EQ_INT(rep.misoriented_edges, 0);
    /* outward: the signed volume of a closed surface wound counter-clockwise
     * from outside is positive (the skull shell: outer minus inner surface) */
    double vol = 0;
    for (size_t t = 0; t < nt; t++) {
        const float *a = p + 3 * tri[3 * t], *b = p + 3 * tri[3 * t + 1], *c = p + 3 * tri[3 * t + 2];
        vol += (a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) - a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0])) / 6.0;
    }
    CHECK(vol > 0);
    free(p);
    free(n);
    free(tri);
    isomend_mesh_destroy(m);
    isomend_io_destroy(s);
}

/* Is (x, y) at whole samples from origin (ox, oy): along x, along y, or both? */
static int on_grid(double x, double y, double ox, double oy, const double *sp, int both)
{
    const double eps = 2e-4; /* float positions of values below 100 mm */
    double u = (x - ox) / sp[0], v = (y - oy) / sp[1];
    int iu = fabs(u - round(u)) * sp[0] <= eps, iv = fabs(v - round(v)) * sp[1] <= eps;
    return both ? iu && iv : iu || iv;
}

/* A series meshed where its slices are: every vertex lies on a sample edge
 * between two samples' true positions (in a slice's plane on a row or a
 * column, or between slices k and k+1 on the line between the two samples'
 * positions, at whole samples from the interpolated slice origin); the
 * triangles are those of the same samples on the uniform grid; with padding
 * the mesh is closed. */
static void mesh_at_true_positions(const char *name)
{
    char rel[64];
    snprintf(rel, sizeof rel, "%s", name);
    char *src[1] = {rel};
    isomend_io_source *s;
    if (open_case(src, 1, "-", 0, &s) != ISOMEND_IO_OK) {
        fprintf(stderr, "%s: %s\n", name, isomend_io_message(s));
        CHECK(0);
        isomend_io_destroy(s);
        return;
    }
    const double *so = isomend_io_slice_origins(s);
    CHECK(so != NULL);
    isomend_volume vol;
    CHECK(isomend_io_load(s, &vol, NULL) == ISOMEND_IO_OK);
    isomend_options o;
    isomend_options_init(&o);
    isomend_io_summary sum;
    CHECK(isomend_io_analyse(s, &sum) == ISOMEND_IO_OK);
    o.iso = sum.suggested_iso;
    isomend_mesh *m = NULL, *flat = NULL;
    CHECK(isomend_io_extract(s, &o, 0, NULL, &m, NULL) == ISOMEND_IO_OK);
    isomend_volume uniform = vol;
    uniform.slice_origins = NULL;
    CHECK(isomend_extract(&uniform, &o, &flat, NULL) == ISOMEND_OK);
    if (!so || !m || !flat) {
        isomend_mesh_destroy(m);
        isomend_mesh_destroy(flat);
        isomend_io_destroy(s);
        return;
    }
    size_t nv = isomend_mesh_vertex_count(m), nt = isomend_mesh_triangle_count(m);
    CHECK(nt > 100);
    CHECK_EQ_INT(isomend_mesh_vertex_count(flat), nv);
    CHECK_EQ_INT(isomend_mesh_triangle_count(flat), nt);
    if (isomend_mesh_triangle_count(flat) == nt)
        CHECK(memcmp(isomend_mesh_triangles(m), isomend_mesh_triangles(flat), nt * 12) == 0);
    const float *p = isomend_mesh_positions(m);
    const int64_t nz = vol.dims[2];
    size_t bad = 0, moved = 0;
    for (size_t i = 0; i < nv; i++) {
        double x = p[3 * i], y = p[3 * i + 1], z = p[3 * i + 2];
        const float *q = isomend_mesh_positions(flat) + 3 * i;
        if (fabs(q[0] - x) + fabs(q[1] - y) + fabs(q[2] - z) > 1e-3)
            moved++;
        int ok = 0;
        for (int64_t k = 0; k < nz && !ok; k++) {
            const double *a = so + 3 * k;
            if (fabs(z - a[2]) <= 2e-4 && on_grid(x, y, a[0], a[1], vol.spacing, 0))
                ok = 1;
            if (!ok && k + 1 < nz && z > a[2] && z < a[5]) {
                double t = (z - a[2]) / (a[5] - a[2]);
                ok = on_grid(x, y, a[0] + t * (a[3] - a[0]), a[1] + t * (a[4] - a[1]), vol.spacing,
                             1);
            }
        }
        if (!ok && bad++ < 3)
            fprintf(
                stderr,
                "%s: vertex %zu (%.6f %.6f %.6f) is not on an edge between true sample positions\n",
                name, i, x, y, z);
    }
    CHECK_EQ_INT(bad, 0);
    CHECK(moved > 0); /* the table made a difference */
    isomend_mesh_destroy(m);
    isomend_mesh_destroy(flat);
    /* closed with padding */
    o.flags = ISOMEND_FLAG_PAD;
    CHECK(isomend_io_extract(s, &o, 0, NULL, &m, NULL) == ISOMEND_IO_OK);
    isomend_check_report rep;
    CHECK(m && isomend_mesh_check(m, &rep) == ISOMEND_OK);
    if (m) {
        CHECK_EQ_INT(rep.hole_edges + rep.border_edges, 0);
        CHECK_EQ_INT(rep.nonmanifold_edges, 0);
    }
    printf("%-22s meshed at its slices' true positions (%zu vertices, %zu moved)\n", name, nv,
           moved);
    isomend_mesh_destroy(m);
    isomend_io_destroy(s);
}

/* options.slice_positions is for stacks and raw volumes: a DICOM series'
 * positions are its own. */
static void positions_refused(void)
{
    char *p = join("ct");
    const char *paths[1] = {p};
    double z[30];
    for (int k = 0; k < 30; k++)
        z[k] = k;
    isomend_io_options o;
    isomend_io_options_init(&o);
    o.slice_positions = z;
    o.slice_position_count = 30;
    isomend_io_source *s = NULL;
    CHECK(isomend_io_create(&s) == ISOMEND_IO_OK);
    CHECK(isomend_io_open(s, paths, 1, &o) == ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(isomend_io_message(s), "slice_positions") &&
          strstr(isomend_io_message(s), "DICOM") && strstr(isomend_io_message(s), p));
    printf("refused: %s\n", isomend_io_message(s));
    isomend_io_destroy(s);
    free(p);
}

/* options.origin moves the slice origins with the origin (one frame);
 * options.spacing replaces the positions by an evenly spaced grid. */
static void options_on_uneven_series(void)
{
    char *src[1] = {"tilt15"};
    isomend_io_source *s;
    CHECK(open_case(src, 1, "-", 0, &s) == ISOMEND_IO_OK);
    int64_t nz = 30;
    double *plain = malloc(sizeof(double) * 3 * (size_t)nz);
    const double *so = isomend_io_slice_origins(s);
    CHECK(so != NULL);
    if (so) memcpy(plain, so, sizeof(double) * 3 * (size_t)nz);
    isomend_io_destroy(s);
    char *p = join("tilt15");
    const char *paths[1] = {p};
    isomend_io_options o;
    isomend_io_options_init(&o);
    o.origin[0] = 1;
    o.origin[1] = 2;
    o.origin[2] = 3;
    CHECK(isomend_io_create(&s) == ISOMEND_IO_OK);
    CHECK(isomend_io_open(s, paths, 1, &o) == ISOMEND_IO_OK);
    so = isomend_io_slice_origins(s);
    CHECK(so != NULL);
    double org[3];
    CHECK(isomend_io_origin(s, org) == ISOMEND_IO_OK && org[0] == 1 && org[1] == 2 && org[2] == 3);
    if (so)
        for (int64_t i = 0; i < 3 * nz; i++) CHECK(fabs(so[i] - (plain[i] - plain[i % 3] + org[i % 3])) < 1e-9);
    isomend_io_destroy(s);
    free(p);
    /* the caller's spacing on a series with a missing slice: even, and the warning says so */
    p = join("missing_slice");
    paths[0] = p;
    isomend_io_options_init(&o);
    o.spacing[0] = o.spacing[1] = 0.5;
    o.spacing[2] = 1.0;
    CHECK(isomend_io_create(&s) == ISOMEND_IO_OK);
    CHECK(isomend_io_open(s, paths, 1, &o) == ISOMEND_IO_OK);
    CHECK(isomend_io_slice_origins(s) == NULL);
    isomend_io_geometry g;
    memset(&g, 0, sizeof g);
    g.size = sizeof g;
    CHECK(isomend_io_geometry_info(s, &g) == ISOMEND_IO_OK);
    CHECK(g.uniform == 1 && g.long_gaps == 1 && strstr(g.warning, "meshed evenly at the spacing given instead"));
    isomend_volume vol;
    CHECK(isomend_io_load(s, &vol, NULL) == ISOMEND_IO_OK);
    CHECK(vol.slice_origins == NULL && vol.spacing[2] == 1.0);
    printf("spacing given: %s\n", g.warning);
    isomend_io_destroy(s);
    free(p);
    free(plain);
}

/* The ignored objects of the CT folder are counted; the series list. */
static void counts(void)
{
    char *src[1] = {"ct"};
    isomend_io_source *s;
    CHECK(open_case(src, 1, "-", 0, &s) == ISOMEND_IO_OK);
    isomend_io_dicom info;
    memset(&info, 0, sizeof info);
    info.size = sizeof info;
    CHECK(isomend_io_dicom_info(s, &info) == ISOMEND_IO_OK);
    CHECK_EQ_INT(info.non_image, 1);
    CHECK_EQ_INT(info.non_dicom, 1);
    CHECK_EQ_INT(info.files, 30);
    CHECK(strcmp(info.modality, "CT") == 0 && info.hounsfield == 1 && info.rescaled == 1);
    CHECK(info.rescale_intercept == -1024.0 && info.rescale_slope == 1.0);
    /* a smaller struct from an older caller: only its bytes are written */
    isomend_io_series small[2];
    memset(small, 0x5a, sizeof small);
    small[0].size = offsetof(isomend_io_series, modality);
    CHECK(isomend_io_series_get(s, 0, &small[0]) == ISOMEND_IO_OK);
    CHECK(small[0].uid && strcmp(small[0].uid, info.series_uid) == 0);
    CHECK(((unsigned char *)&small[0])[offsetof(isomend_io_series, modality)] == 0x5a);
    isomend_io_destroy(s);
    /* choices are made before the open */
    CHECK(isomend_io_create(&s) == ISOMEND_IO_OK);
    CHECK(isomend_io_set_axes(s, 7) == ISOMEND_IO_ERR_INVALID_ARGUMENT);
    isomend_io_destroy(s);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: test_io_dicom DIR\n");
        return 2;
    }
    g_dir = argv[1];
    char *mpath = join("manifest.tsv");
    FILE *m = fopen(mpath, "r");
    free(mpath);
    if (!m) {
        fprintf(stderr, "%s/manifest.tsv not found (run gen_dicom.py first)\n", g_dir);
        return 1;
    }
    static char line[1 << 16];
    int cases = 0;
    while (fgets(line, sizeof line, m)) {
        line[strcspn(line, "\n")] = 0;
        char *f[MAX_FIELDS];
        int nf = 0;
        for (char *tok = strtok(line, "\t"); tok && nf < MAX_FIELDS; tok = strtok(NULL, "\t")) f[nf++] = tok;
        if (nf < 2) continue;
        int before = tu_failures;
        if (strcmp(f[0], "ok") == 0) run_ok(f, nf);
        else run_err(f, nf);
        printf("%-22s %s\n", f[1], tu_failures == before ? "ok" : "FAILED");
        cases++;
    }
    fclose(m);
    CHECK(cases >= 30);
    counts();
    mesh_through_transform();
    positions_refused();
    options_on_uneven_series();
    mesh_at_true_positions("tilt15");
    mesh_at_true_positions("missing_slice");
    mesh_at_true_positions("rounded");
    mesh_at_true_positions("two_spacings");
    TEST_EXIT();
}
