/*
 * test_digest.c - one line per extraction: its case, vertex and triangle
 * counts and a 64-bit FNV-1a digest of the mesh's bytes (positions, normals,
 * triangles, origins) and of the statistics.
 *
 *   test_digest                    the lines, with the kernels the CPU takes
 *   test_digest --compare-targets  the lines with the kernels of every CPU
 *                                  target the machine runs (AVX2: four
 *                                  vertices at a time; SSE2 scanning; the
 *                                  portable C), which must be identical
 *                                  (core_simd_identical)
 *
 *   test_digest --threads=N --schedule=S
 *                                  the lines at N threads (default 2) with
 *                                  the schedule S (tests/core/schedule.h)
 *
 * Run as it is (two threads: counted runs on these small grids), the lines
 * must be tests/core/digest_expected.txt's, printed by the two passes of
 * 2026-12-05 (core_digest_expected); at 1 thread and with each test schedule
 * (--schedule=anysize, thin, staged, counted: tests/core/schedule.h) they
 * must be the same (core_one_run_identical, core_*_runs_identical).
 *
 * The cases: every sample type; a dense field (many crossings per row: the
 * wide-span path) and a sphere (a few per row: the lists); odd sizes with the
 * surface reaching the border (the general vertex path); NaNs; a view with a
 * negative stride; padding, flipped normals, no normals; MC, Durst and DMC.
 */
#include "isomend.h"
#include "cpu_target.h"
#include "schedule.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int digest_threads = 2; /* --threads=N */

enum { NX = 53, NY = 38, NZ = 41 };

/* The lines printed so far (out_text, out_len bytes). */
static char *out_text;
static size_t out_len, out_cap;

static int out_line(const char *line)
{
    const size_t n = strlen(line);
    if (out_len + n + 1 > out_cap) {
        const size_t cap = 2 * (out_len + n + 1);
        char *t = realloc(out_text, cap);
        if (!t)
            return 0;
        out_text = t;
        out_cap = cap;
    }
    memcpy(out_text + out_len, line, n + 1);
    out_len += n;
    return 1;
}

static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++) {
        h ^= b[i];
        h *= UINT64_C(1099511628211);
    }
    return h;
}

/* A dense field in [-1, 1]: crossings every few samples along every axis. */
static double dense(int x, int y, int z)
{
    return (sin(0.71 * x + 0.2) * cos(0.53 * y) + sin(0.47 * y + 1.1) * cos(0.61 * z) +
            sin(0.66 * z) * cos(0.57 * x + 0.4)) / 3.0;
}

/* A sphere reaching past the volume's +x face: a few crossings per row. */
static double sphere(int x, int y, int z)
{
    const double dx = x - 33.3, dy = y - 18.6, dz = z - 20.2;
    return (19.5 - sqrt(dx * dx + dy * dy + dz * dz)) / 20.0;
}

/* The field f, scaled and stored as `type`; f32/f64 get a few NaNs if asked. */
static void *make_volume(isomend_type type, double (*f)(int, int, int), int nans, double *iso)
{
    const size_t n = (size_t)NX * NY * NZ, size = isomend_type_size(type);
    unsigned char *v = malloc(n * size);
    if (!v)
        return NULL;
    for (int z = 0; z < NZ; z++)
        for (int y = 0; y < NY; y++)
            for (int x = 0; x < NX; x++) {
                const size_t at = ((size_t)z * NY + y) * NX + x;
                const double s = f(x, y, z);
                const int nan_here = nans && (at % 997) == 5;
                switch (type) {
                case ISOMEND_U8: v[at] = (uint8_t)lround(127.5 + 120.0 * s); break;
                case ISOMEND_I8: ((int8_t *)(void *)v)[at] = (int8_t)lround(120.0 * s); break;
                case ISOMEND_U16:
                    ((uint16_t *)(void *)v)[at] = (uint16_t)lround(30000.0 + 20000.0 * s);
                    break;
                case ISOMEND_I16: ((int16_t *)(void *)v)[at] = (int16_t)lround(9000.0 * s); break;
                case ISOMEND_I32:
                    ((int32_t *)(void *)v)[at] = (int32_t)lround(1.0e6 * s);
                    break;
                case ISOMEND_F32:
                    ((float *)(void *)v)[at] = nan_here ? NAN : (float)s;
                    break;
                case ISOMEND_F64: ((double *)(void *)v)[at] = nan_here ? NAN : s; break;
                }
            }
    /* levels between samples and, for integers, equal to many samples */
    switch (type) {
    case ISOMEND_U8: *iso = 127.0; break;
    case ISOMEND_I8: *iso = 0.5; break;
    case ISOMEND_U16: *iso = 30000.0; break;
    case ISOMEND_I16: *iso = 12.0; break;
    case ISOMEND_I32: *iso = 0.0; break;
    default: *iso = 0.0137; break;
    }
    return v;
}

static int run(const char *name, const isomend_volume *vol, double iso, isomend_method method,
               unsigned flags)
{
    isomend_options o;
    isomend_options_init(&o);
    o.iso = iso;
    o.method = method;
    o.flags = flags;
    o.threads = digest_threads;
    isomend_mesh *m = NULL;
    isomend_stats st;
    const isomend_status s = isomend_extract(vol, &o, &m, &st);
    if (s != ISOMEND_OK) {
        fprintf(stderr, "%s: %s\n", name, isomend_status_string(s));
        return 1;
    }
    const size_t nv = isomend_mesh_vertex_count(m), nt = isomend_mesh_triangle_count(m);
    uint64_t h = UINT64_C(14695981039346656037);
    h = fnv(h, isomend_mesh_positions(m), sizeof(float) * 3 * nv);
    if (isomend_mesh_normals(m))
        h = fnv(h, isomend_mesh_normals(m), sizeof(float) * 3 * nv);
    h = fnv(h, isomend_mesh_triangles(m), sizeof(uint32_t) * 3 * nt);
    if (isomend_mesh_triangle_origins(m))
        h = fnv(h, isomend_mesh_triangle_origins(m), nt);
    h = fnv(h, &st, sizeof st); /* the statistics too */
    char line[160];
    snprintf(line, sizeof line, "%-34s %s flags %u: %7zu vertices %7zu triangles %016llx\n",
             name, isomend_method_name(method), flags, nv, nt, (unsigned long long)h);
    isomend_mesh_destroy(m);
    return !out_line(line) || nt == 0; /* every case has a surface */
}

/* Runs every case into out_text; returns non-zero on a failure. */
static int run_all(void)
{
    static const struct {
        const char *name;
        double (*f)(int, int, int);
    } fields[] = {{"dense", dense}, {"sphere", sphere}};
    int failed = 0;
    for (int t = 0; t < ISOMEND_TYPE_COUNT; t++)
        for (int fi = 0; fi < 2; fi++) {
            const isomend_type type = (isomend_type)t;
            const int floats = type == ISOMEND_F32 || type == ISOMEND_F64;
            for (int nans = 0; nans <= floats; nans++) {
                double iso;
                void *data = make_volume(type, fields[fi].f, nans, &iso);
                if (!data)
                    return 1;
                char name[64];
                snprintf(name, sizeof name, "%s %s%s", isomend_type_name(type), fields[fi].name,
                         nans ? " +NaN" : "");
                isomend_volume vol;
                isomend_volume_init(&vol, data, type, NX, NY, NZ);
                failed |= run(name, &vol, iso, ISOMEND_METHOD_DMC, 0);
                if (type == ISOMEND_F32 || type == ISOMEND_U8) {
                    failed |= run(name, &vol, iso, ISOMEND_METHOD_MC, 0);
                    failed |= run(name, &vol, iso, ISOMEND_METHOD_DURST, ISOMEND_FLAG_FLIP);
                    failed |= run(name, &vol, iso, ISOMEND_METHOD_DMC, ISOMEND_FLAG_PAD);
                    failed |= run(name, &vol, iso, ISOMEND_METHOD_DMC, ISOMEND_FLAG_NO_NORMALS);
                    /* the same samples seen through y reversed (negative stride) */
                    isomend_volume rev = vol;
                    const size_t size = isomend_type_size(type);
                    rev.data = (const char *)data + (size_t)(NY - 1) * NX * size;
                    rev.strides[0] = (int64_t)size;
                    rev.strides[1] = -(int64_t)(NX * size);
                    rev.strides[2] = (int64_t)(NX * NY * size);
                    snprintf(name, sizeof name, "%s %s%s y reversed", isomend_type_name(type),
                             fields[fi].name, nans ? " +NaN" : "");
                    failed |= run(name, &rev, iso, ISOMEND_METHOD_DMC, 0);
                }
                free(data);
            }
        }
    return failed;
}

/* The lines of every target the CPU runs, compared with the first's. */
static int compare_targets(void)
{
    char *first = NULL;
    const char *first_name = NULL;
    int targets = 0, failed = 0;
    char names[64] = "";
    for (int t = 0; t < CPU_TARGET_COUNT && !failed; t++) {
        if (cpu_target_use(cpu_targets[t].name) != 1) {
            printf("%s: not on this CPU\n", cpu_targets[t].name);
            continue;
        }
        out_len = 0;
        failed |= run_all();
        if (failed)
            break;
        if (!first) {
            first = malloc(out_len + 1);
            if (!first)
                return 1;
            memcpy(first, out_text, out_len + 1);
            first_name = cpu_targets[t].name;
            fputs(first, stdout);
        } else if (strcmp(first, out_text) != 0) {
            printf("the %s kernels' meshes differ from the %s kernels':\n%s", cpu_targets[t].name,
                   first_name, out_text);
            failed = 1;
        }
        snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s", targets ? ", " : "",
                 cpu_targets[t].name);
        targets++;
    }
    cpu_features_set_test_mask(CPU_FEATURES_ALL);
    if (!failed && first) { /* with one target (no SSE2), "1 targets": nothing compared */
        int lines = 0;
        for (const char *c = first; *c; c++)
            lines += *c == '\n';
        printf("identical: %d meshes on %d targets (%s)\n", lines, targets, names);
    }
    free(first);
    return failed;
}

int main(int argc, char **argv)
{
    int failed;
    if (argc == 2 && strcmp(argv[1], "--compare-targets") == 0) {
        failed = compare_targets();
    } else {
        for (int i = 1; i < argc; i++)
            if (strncmp(argv[i], "--threads=", 10) == 0)
                digest_threads = atoi(argv[i] + 10);
            else if (strncmp(argv[i], "--schedule=", 11) != 0) {
                fprintf(stderr, "usage: %s [--compare-targets | [--threads=N] [--schedule=S]]\n",
                        argv[0]);
                return 2;
            }
        if (schedule_from_args(argc, argv))
            return 2;
        failed = run_all();
        if (out_text)
            fputs(out_text, stdout);
    }
    free(out_text);
    return failed;
}
