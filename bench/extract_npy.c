/*
 * extract_npy.c - times isomend_extract() on a volume saved by numpy (.npy),
 * without Python in the process: the driver for perf and callgrind when
 * profiling the core (see the README, "Profiling the core").
 *
 *   isomend_bench_extract FILE.npy ISO [--threads N] [--repeats N]
 *                         [--method mc|durst|dmc] [--no-normals] [--pad] [--small-pages]
 *                         [--recycle] [--floor | --ab LIB_A.so LIB_B.so]
 *
 * Reads a C-order 3-D array (shape (nz, ny, nx), x fastest) of uint8, int8,
 * uint16, int16, int32, float32 or float64 in little-endian order, then runs
 * the extraction N times and prints one line per run (wall and process CPU
 * time, the latter split into user and system time, triangles, vertices) and
 * the medians.  On a shared machine the CPU time of a 1-thread run is the
 * figure least disturbed by other jobs; the system time is the kernel's share
 * (page faults of the output arrays).  With --recycle, each run after the
 * first hands the previous run's mesh to isomend_extract_recycle() instead
 * of destroying it (not with --ab).
 * With --floor (float32 and uint8 volumes) each run is preceded by the
 * benchmark's memory-read floor (floor.c: the sum of all voxels, same thread
 * count, the median of 3 consecutive sums as in bench.py) and the line shows
 * the ratio of the two; the median ratio closes the output.  Alternating the
 * two in one process keeps a noisy machine's slow phases out of the ratio.
 * With --ab, each run calls isomend_extract() of two builds of the library
 * instead (two libisomend.so, e.g. from a worktree at the commit before a
 * change and from the change, each loaded with dlmopen in a namespace of its
 * own), in alternating order, and the line shows the ratio B / A; the median
 * and quartiles of those per-run ratios close the output, and the last two
 * meshes are compared byte for byte.  Two calls a few milliseconds apart see
 * the same machine, so the ratio holds on a machine whose speed drifts (this
 * is how the core's changes are measured, README "Profiling the core").  Both
 * builds are loaded alike on purpose: alternated with the same code loaded
 * with dlmopen (another libc, another heap), this program's static copy of
 * the library took 1.12-1.20x as long, though each alone takes the same time.
 * The builds must have this header's ABI.
 * Exit status 0 on success, 1 on bad input (with a message naming the file
 * or option), 2 when an extraction fails, 3 when --ab finds the meshes differ.
 */
#define _GNU_SOURCE /* dlmopen; also clock_gettime, posix_memalign, madvise */
#include "isomend.h"

#include <dlfcn.h>

double isomend_bench_sum_f32(const float *data, size_t n, int threads); /* floor.c */
double isomend_bench_sum_u8(const uint8_t *data, size_t n, int threads);

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>
#if defined(__linux__)
#include <sys/mman.h>
#endif

static double now(clockid_t clock)
{
    struct timespec ts;
    clock_gettime(clock, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* User and system CPU time of the process so far, in seconds. */
static void usage_times(double *user, double *sys)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    *user = (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec;
    *sys = (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

typedef struct npy {
    void *data;
    isomend_type type;
    int64_t shape[3];
} npy;

/* Parses the .npy header (format 1.0/2.0/3.0) and reads the samples. */
static int read_npy(const char *path, npy *out)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "isomend_bench_extract: %s: %s\n", path, strerror(errno));
        return 0;
    }
    unsigned char magic[8];
    char *header = NULL;
    int ok = 0;
    if (fread(magic, 1, 8, f) != 8 || memcmp(magic, "\x93NUMPY", 6) != 0) {
        fprintf(stderr, "isomend_bench_extract: %s: not a .npy file\n", path);
        goto done;
    }
    unsigned long hlen;
    if (magic[6] == 1) {
        unsigned char b[2];
        if (fread(b, 1, 2, f) != 2)
            goto truncated;
        hlen = b[0] | (unsigned long)b[1] << 8;
    } else {
        unsigned char b[4];
        if (fread(b, 1, 4, f) != 4)
            goto truncated;
        hlen = b[0] | (unsigned long)b[1] << 8 | (unsigned long)b[2] << 16 |
               (unsigned long)b[3] << 24;
    }
    if (hlen > 65536) {
        fprintf(stderr, "isomend_bench_extract: %s: header too long\n", path);
        goto done;
    }
    header = calloc(1, hlen + 1);
    if (!header || fread(header, 1, hlen, f) != hlen)
        goto truncated;
    static const struct { const char *descr; isomend_type type; } types[] = {
        {"'|u1'", ISOMEND_U8},  {"'|i1'", ISOMEND_I8},  {"'<u2'", ISOMEND_U16},
        {"'<i2'", ISOMEND_I16}, {"'<i4'", ISOMEND_I32}, {"'<f4'", ISOMEND_F32},
        {"'<f8'", ISOMEND_F64}};
    const char *d = strstr(header, "'descr':");
    int found = 0;
    for (size_t i = 0; d && i < sizeof(types) / sizeof(types[0]); i++)
        if (strncmp(d + 9, types[i].descr, strlen(types[i].descr)) == 0 ||
            strncmp(d + 8, types[i].descr, strlen(types[i].descr)) == 0) {
            out->type = types[i].type;
            found = 1;
        }
    const char *fo = strstr(header, "'fortran_order': False");
    const char *sh = strstr(header, "'shape': (");
    long long s0, s1, s2;
    if (!found || !fo || !sh || sscanf(sh + 10, "%lld, %lld, %lld", &s0, &s1, &s2) != 3 ||
        s0 < 1 || s1 < 1 || s2 < 1) {
        fprintf(stderr, "isomend_bench_extract: %s: need a C-order 3-D array of a little-endian "
                        "integer or float type; header: %s\n", path, header);
        goto done;
    }
    out->shape[0] = s0;
    out->shape[1] = s1;
    out->shape[2] = s2;
    size_t n = (size_t)s0 * (size_t)s1 * (size_t)s2 * isomend_type_size(out->type);
    /* Like numpy, which the benchmark's arrays come from: large arrays on
     * transparent huge pages (numpy madvises arrays of 4 MiB and more).  With
     * 4 KiB pages the samples read around sparse vertices cost TLB misses
     * that the benchmark's runs do not have. */
    out->data = NULL;
    if (n >= ((size_t)4 << 20)) {
        void *p = NULL;
        if (posix_memalign(&p, (size_t)2 << 20, n) == 0) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
            (void)madvise(p, n, MADV_HUGEPAGE);
#endif
            out->data = p;
        }
    } else {
        out->data = malloc(n ? n : 1);
    }
    if (!out->data) {
        fprintf(stderr, "isomend_bench_extract: %s: out of memory\n", path);
        goto done;
    }
    if (fread(out->data, 1, n, f) != n)
        goto truncated;
    ok = 1;
    goto done;
truncated:
    fprintf(stderr, "isomend_bench_extract: %s: truncated file\n", path);
done:
    free(header);
    fclose(f);
    if (!ok) {
        free(out->data);
        out->data = NULL;
    }
    return ok;
}

static int usage(void)
{
    fprintf(stderr, "usage: isomend_bench_extract FILE.npy ISO [--threads N] [--repeats N] "
                    "[--method mc|durst|dmc] [--no-normals] [--pad] [--small-pages] [--recycle] "
                    "[--floor | --ab LIB_A.so LIB_B.so]\n");
    return 1;
}

/* The entry points of a build of the library loaded with dlmopen (--ab). */
typedef struct built_lib {
    isomend_status (*extract)(const isomend_volume *, const isomend_options *, isomend_mesh **,
                              isomend_stats *);
    void (*destroy)(isomend_mesh *);
    size_t (*vertex_count)(const isomend_mesh *);
    size_t (*triangle_count)(const isomend_mesh *);
    const float *(*positions)(const isomend_mesh *);
    const float *(*normals)(const isomend_mesh *);
    const uint32_t *(*triangles)(const isomend_mesh *);
    const uint8_t *(*origins)(const isomend_mesh *);
    const char *(*version)(void);
} built_lib;

/* Loads the build at `path` in a namespace of its own, so that its symbols
 * resolve neither to this program's static copy of the library nor to the
 * other build. */
static int load_build(const char *path, built_lib *l)
{
    void *h = dlmopen(LM_ID_NEWLM, path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        fprintf(stderr, "isomend_bench_extract: --ab %s: %s\n", path, dlerror());
        return 0;
    }
    void *sym[9];
    static const char *const names[9] = {
        "isomend_extract", "isomend_mesh_destroy", "isomend_mesh_vertex_count",
        "isomend_mesh_triangle_count", "isomend_mesh_positions", "isomend_mesh_normals",
        "isomend_mesh_triangles", "isomend_mesh_triangle_origins", "isomend_version"};
    for (int i = 0; i < 9; i++)
        if (!(sym[i] = dlsym(h, names[i]))) {
            fprintf(stderr, "isomend_bench_extract: --ab %s: no symbol %s\n", path, names[i]);
            return 0;
        }
    /* POSIX: object pointers from dlsym convert to function pointers */
    memcpy(&l->extract, &sym[0], sizeof sym[0]);
    memcpy(&l->destroy, &sym[1], sizeof sym[1]);
    memcpy(&l->vertex_count, &sym[2], sizeof sym[2]);
    memcpy(&l->triangle_count, &sym[3], sizeof sym[3]);
    memcpy(&l->positions, &sym[4], sizeof sym[4]);
    memcpy(&l->normals, &sym[5], sizeof sym[5]);
    memcpy(&l->triangles, &sym[6], sizeof sym[6]);
    memcpy(&l->origins, &sym[7], sizeof sym[7]);
    memcpy(&l->version, &sym[8], sizeof sym[8]);
    return 1;
}

/* Whether mesh m of build l and mesh n of build k are the same byte for byte. */
static int same_mesh(const built_lib *l, const isomend_mesh *m, const built_lib *k,
                     const isomend_mesh *n)
{
    const size_t nv = l->vertex_count(m), nt = l->triangle_count(m);
    if (nv != k->vertex_count(n) || nt != k->triangle_count(n))
        return 0;
    const float *a = l->normals(m), *b = k->normals(n);
    if ((a == NULL) != (b == NULL) || (a && memcmp(a, b, 3 * sizeof(float) * nv)))
        return 0;
    const uint8_t *o = l->origins(m), *p = k->origins(n);
    if ((o == NULL) != (p == NULL) || (o && memcmp(o, p, nt)))
        return 0;
    return !memcmp(l->positions(m), k->positions(n), 3 * sizeof(float) * nv) &&
           !memcmp(l->triangles(m), k->triangles(n), 3 * sizeof(uint32_t) * nt);
}

/* The memory-read floor of the volume: the median of 3 consecutive sums, like
 * bench.py's. */
static double floor_time(const npy *v, int threads)
{
    const size_t samples = (size_t)v->shape[0] * (size_t)v->shape[1] * (size_t)v->shape[2];
    double t[3];
    for (int q = 0; q < 3; q++) {
        const double t0 = now(CLOCK_MONOTONIC);
        volatile double sum = v->type == ISOMEND_F32
            ? isomend_bench_sum_f32(v->data, samples, threads)
            : isomend_bench_sum_u8(v->data, samples, threads);
        (void)sum;
        t[q] = now(CLOCK_MONOTONIC) - t0;
    }
    qsort(t, 3, sizeof(double), cmp_double);
    return t[1];
}

/*
 * --ab: `repeats` runs of build A and build B in alternating order (A first
 * on even runs), after one untimed call of each.  Returns the exit status.
 */
static int run_ab(const char *path, const isomend_volume *vol, const isomend_options *o,
                  int repeats, const char *const names[2], const built_lib lib[2])
{
    double *ratio = calloc((size_t)repeats, sizeof(double));
    double *tm[2] = {calloc((size_t)repeats, sizeof(double)),
                     calloc((size_t)repeats, sizeof(double))};
    int rc = ratio && tm[0] && tm[1] ? 0 : 2;
    for (int r = -1; r < repeats && rc == 0; r++) { /* r = -1: the untimed first calls */
        isomend_mesh *mesh[2] = {NULL, NULL};
        double t[2];
        for (int q = 0; q < 2 && rc == 0; q++) {
            const int b = (r & 1) ? 1 - q : q;
            const double t0 = now(CLOCK_MONOTONIC);
            if (lib[b].extract(vol, o, &mesh[b], NULL) != ISOMEND_OK) {
                fprintf(stderr, "isomend_bench_extract: %s: build %c (%s) failed\n", path,
                        'A' + b, names[b]);
                rc = 2;
            }
            t[b] = now(CLOCK_MONOTONIC) - t0;
        }
        if (rc == 0 && r >= 0) {
            tm[0][r] = t[0];
            tm[1][r] = t[1];
            ratio[r] = t[1] / t[0];
            printf("run %d: A %.2f ms, B %.2f ms, B / A %.3f, %zu triangles\n", r, 1e3 * t[0],
                   1e3 * t[1], ratio[r], lib[0].triangle_count(mesh[0]));
            if (r == repeats - 1 && !same_mesh(&lib[0], mesh[0], &lib[1], mesh[1])) {
                fprintf(stderr, "isomend_bench_extract: %s: the meshes of %s and %s differ\n",
                        path, names[0], names[1]);
                rc = 3;
            }
        }
        for (int b = 0; b < 2; b++)
            if (mesh[b])
                lib[b].destroy(mesh[b]); /* each build frees with its own allocator */
    }
    if (rc != 2) {
        qsort(ratio, (size_t)repeats, sizeof(double), cmp_double);
        for (int b = 0; b < 2; b++)
            qsort(tm[b], (size_t)repeats, sizeof(double), cmp_double);
        printf("A %s (%s): median %.2f ms; B %s (%s): median %.2f ms\n", names[0],
               lib[0].version(), 1e3 * tm[0][repeats / 2], names[1], lib[1].version(),
               1e3 * tm[1][repeats / 2]);
        printf("median ratio B / A %.3f, quartiles %.3f..%.3f; meshes %s\n", ratio[repeats / 2],
               ratio[repeats / 4], ratio[(3 * repeats) / 4], rc == 3 ? "DIFFER" : "identical");
    }
    free(ratio);
    free(tm[0]);
    free(tm[1]);
    return rc;
}

int main(int argc, char **argv)
{
    if (argc < 3)
        return usage();
    const char *path = argv[1];
    char *end;
    isomend_options o;
    isomend_options_init(&o);
    o.iso = strtod(argv[2], &end);
    if (*end || end == argv[2]) {
        fprintf(stderr, "isomend_bench_extract: ISO %s is not a number\n", argv[2]);
        return 1;
    }
    int repeats = 5, floor = 0, recycle = 0;
    const char *ab[2] = {NULL, NULL};
    for (int i = 3; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--no-normals")) {
            o.flags |= ISOMEND_FLAG_NO_NORMALS;
        } else if (!strcmp(a, "--pad")) {
            o.flags |= ISOMEND_FLAG_PAD;
        } else if (!strcmp(a, "--small-pages")) {
            o.flags |= ISOMEND_FLAG_SMALL_PAGES;
        } else if (!strcmp(a, "--floor")) {
            floor = 1;
        } else if (!strcmp(a, "--recycle")) {
            recycle = 1;
        } else if (!strcmp(a, "--ab") && i + 2 < argc) {
            ab[0] = argv[++i];
            ab[1] = argv[++i];
        } else if ((!strcmp(a, "--threads") || !strcmp(a, "--repeats")) && i + 1 < argc) {
            long v = strtol(argv[++i], &end, 10);
            if (*end || v < (a[2] == 't' ? 0 : 1) || v > 1000) {
                fprintf(stderr, "isomend_bench_extract: %s %s: expected an integer in %d..1000\n",
                        a, argv[i], a[2] == 't' ? 0 : 1);
                return 1;
            }
            if (a[2] == 't')
                o.threads = (int)v;
            else
                repeats = (int)v;
        } else if (!strcmp(a, "--method") && i + 1 < argc) {
            if (isomend_method_from_name(argv[++i], &o.method) != ISOMEND_OK) {
                fprintf(stderr, "isomend_bench_extract: --method %s: unknown method\n", argv[i]);
                return 1;
            }
        } else {
            fprintf(stderr, "isomend_bench_extract: unknown option %s\n", a);
            return usage();
        }
    }
    if (floor && ab[0]) {
        fprintf(stderr, "isomend_bench_extract: --floor and --ab: one ratio at a time\n");
        return 1;
    }
    if (recycle && ab[0]) {
        fprintf(stderr,
                "isomend_bench_extract: --recycle and --ab: the builds would share meshes\n");
        return 1;
    }
    built_lib lib[2];
    memset(lib, 0, sizeof lib);
    if (ab[0] && (!load_build(ab[0], &lib[0]) || !load_build(ab[1], &lib[1])))
        return 1;
    npy v = {0};
    if (!read_npy(path, &v))
        return 1;
    if (floor && v.type != ISOMEND_F32 && v.type != ISOMEND_U8) {
        fprintf(stderr, "isomend_bench_extract: --floor: %s is %s, the floor reads float32 or "
                        "uint8\n", path, isomend_type_name(v.type));
        free(v.data);
        return 1;
    }
    const int floor_threads = o.threads > 0 ? o.threads : (int)sysconf(_SC_NPROCESSORS_ONLN);
    isomend_volume vol;
    isomend_volume_init(&vol, v.data, v.type, v.shape[2], v.shape[1], v.shape[0]);
    if (ab[0]) {
        const int ab_rc = run_ab(path, &vol, &o, repeats, ab, lib);
        free(v.data);
        return ab_rc;
    }
    double *times = calloc((size_t)repeats, sizeof(double));
    double *cpu = calloc((size_t)repeats, sizeof(double));
    double *ratio = calloc((size_t)repeats, sizeof(double));
    int rc = times && cpu && ratio ? 0 : 2;
    isomend_mesh *kept = NULL; /* --recycle: the last run's mesh */
    for (int r = 0; r < repeats && rc == 0; r++) {
        isomend_mesh *mesh = kept;
        kept = NULL;
        isomend_stats st;
        double u0, s0, u1, s1;
        const double floor_s = floor ? floor_time(&v, floor_threads) : 0.0;
        usage_times(&u0, &s0);
        double t0 = now(CLOCK_MONOTONIC), c0 = now(CLOCK_PROCESS_CPUTIME_ID);
        isomend_status s = recycle ? isomend_extract_recycle(&vol, &o, &mesh, &st)
                                   : isomend_extract(&vol, &o, &mesh, &st);
        times[r] = now(CLOCK_MONOTONIC) - t0;
        cpu[r] = now(CLOCK_PROCESS_CPUTIME_ID) - c0;
        usage_times(&u1, &s1);
        if (s != ISOMEND_OK) {
            fprintf(stderr, "isomend_bench_extract: %s: %s\n", path, isomend_status_string(s));
            rc = 2;
            break;
        }
        printf("run %d: %.2f ms (CPU %.2f ms: user %.0f, system %.0f), %llu triangles, "
               "%llu vertices, %llu mended",
               r, 1e3 * times[r], 1e3 * cpu[r], 1e3 * (u1 - u0), 1e3 * (s1 - s0),
               (unsigned long long)st.triangles,
               (unsigned long long)st.vertices,
               (unsigned long long)st.triangles_by_origin[ISOMEND_ORIGIN_MEND]);
        if (floor) {
            ratio[r] = times[r] / floor_s;
            printf("; floor %.2f ms, ratio %.2f", 1e3 * floor_s, ratio[r]);
        }
        printf("\n");
        if (recycle)
            kept = mesh;
        else
            isomend_mesh_destroy(mesh);
    }
    isomend_mesh_destroy(kept);
    if (rc == 0) {
        qsort(times, (size_t)repeats, sizeof(double), cmp_double);
        qsort(cpu, (size_t)repeats, sizeof(double), cmp_double);
        printf("median %.2f ms, min %.2f ms, CPU median %.2f ms (%lld x %lld x %lld %s, "
               "%d threads)\n",
               1e3 * times[repeats / 2], 1e3 * times[0], 1e3 * cpu[repeats / 2],
               (long long)v.shape[2],
               (long long)v.shape[1], (long long)v.shape[0], isomend_type_name(v.type),
               o.threads);
        if (floor) {
            qsort(ratio, (size_t)repeats, sizeof(double), cmp_double);
            printf("median ratio to the floor %.2f (min %.2f)\n", ratio[repeats / 2], ratio[0]);
        }
    }
    free(ratio);
    free(times);
    free(cpu);
    free(v.data);
    return rc;
}
