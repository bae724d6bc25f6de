/*
 * stream_rate.c - the core's stream at 1 and T threads, A/B in one process.
 *
 *   isomend_bench_stream RAW NX,NY,NZ:TYPE ISO [--threads T] [--rounds R] [--only T]
 *
 * Reads the raw volume (x fastest, machine byte order) into memory once, then
 * streams it once at 1 and at T threads into a sink that folds the whole mesh
 * into a digest (the two must be equal: the mesh does not depend on the
 * threads), then for R rounds at 1 and T threads, alternating which goes
 * first, into a sink that only counts (so that the core is what is timed).  Prints each run's rate (slices/s,
 * Msamples/s), the median per-round ratio T/1 and whether the meshes are the
 * same.  No file is written: this measures the core's pipeline, the CLI's
 * end to end runs are stream_bench.py's.
 */
#define _POSIX_C_SOURCE 200809L
#include "isomend.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct digest {
    uint64_t h, nv, nt;
    int full; /* hash every word (the check run), else only the counts (timed runs) */
} digest;

static uint64_t mix(uint64_t x)
{
    x ^= x >> 31;
    x *= 0x7fb5d329728ea185ull;
    x ^= x >> 27;
    x *= 0x81dadef4bc2dd44dull;
    return x ^ (x >> 33);
}

/* Adds each 32-bit word with its index in its stream: a digest that does not
 * depend on how the sink's calls cut the mesh. */
static void fold(digest *d, const void *p, size_t words, uint64_t first, uint64_t stream)
{
    const uint32_t *w = p;
    uint64_t h = 0;
    for (size_t i = 0; i < words; i++)
        h += mix(((first + i) << 34) ^ (stream << 32) ^ w[i]);
    d->h += h;
}

static int on_vertices(void *u, uint64_t first, size_t count, const float *pos, const float *nrm,
                       const uint64_t *keys)
{
    (void)keys;
    digest *d = u;
    if (first != d->nv)
        return 1;
    if (d->full) {
        fold(d, pos, 3 * count, 3 * first, 0);
        if (nrm)
            fold(d, nrm, 3 * count, 3 * first, 1);
    }
    d->nv += count;
    return 0;
}

static int on_triangles(void *u, size_t count, const uint64_t *ids, const uint8_t *org)
{
    (void)org;
    digest *d = u;
    if (d->full)
        fold(d, ids, 6 * count, 6 * d->nt, 2);
    d->nt += count;
    return 0;
}

static int on_retire(void *u, uint64_t floor)
{
    (void)u;
    (void)floor;
    return 0;
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static double run(const isomend_volume *vol, double iso, int threads, digest *d, int full)
{
    isomend_options o;
    isomend_options_init(&o);
    o.iso = iso;
    o.threads = threads;
    memset(d, 0, sizeof *d);
    d->h = 1469598103934665603ull;
    d->full = full;
    const isomend_mesh_sink sink = {d, on_vertices, on_triangles, on_retire, NULL};
    isomend_stream *s = NULL;
    const double t0 = now();
    isomend_status st = isomend_stream_begin(vol, &o, &sink, &s);
    const size_t plane = (size_t)(vol->dims[0] * vol->dims[1]) * isomend_type_size(vol->type);
    for (int64_t z = 0; z < vol->dims[2] && st == ISOMEND_OK; z++)
        st = isomend_stream_push(s, (const char *)vol->data + (size_t)z * plane);
    if (st == ISOMEND_OK)
        st = isomend_stream_finish(s, NULL);
    isomend_stream_destroy(s);
    const double t = now() - t0;
    if (st != ISOMEND_OK) {
        fprintf(stderr, "stream (threads %d): %s\n", threads, isomend_status_string(st));
        exit(1);
    }
    return t;
}

static int cmp_double(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int main(int argc, char **argv)
{
    if (argc < 4) {
        fprintf(stderr, "usage: %s RAW NX,NY,NZ:TYPE ISO [--threads T] [--rounds R]\n", argv[0]);
        return 2;
    }
    long long n[3];
    char type_name[16];
    if (sscanf(argv[2], "%lld,%lld,%lld:%15s", &n[0], &n[1], &n[2], type_name) != 4) {
        fprintf(stderr, "%s: dims NX,NY,NZ:TYPE expected\n", argv[2]);
        return 2;
    }
    isomend_type type = ISOMEND_TYPE_COUNT;
    for (int t = 0; t < ISOMEND_TYPE_COUNT; t++)
        if (strcmp(type_name, isomend_type_name((isomend_type)t)) == 0)
            type = (isomend_type)t;
    if (type == ISOMEND_TYPE_COUNT) {
        fprintf(stderr, "%s: unknown type\n", type_name);
        return 2;
    }
    const double iso = atof(argv[3]);
    int threads = 2, rounds = 5, only = 0;
    for (int i = 4; i + 1 < argc; i += 2) {
        if (strcmp(argv[i], "--threads") == 0)
            threads = atoi(argv[i + 1]);
        else if (strcmp(argv[i], "--only") == 0) /* one run at that many threads (profiling) */
            only = atoi(argv[i + 1]);
        else if (strcmp(argv[i], "--rounds") == 0)
            rounds = atoi(argv[i + 1]);
    }
    if (threads < 2 || rounds < 1 || rounds > 99) {
        fprintf(stderr, "--threads 2.. and --rounds 1..99\n");
        return 2;
    }
    const size_t bytes = (size_t)(n[0] * n[1] * n[2]) * isomend_type_size(type);
    void *data = malloc(bytes);
    FILE *f = fopen(argv[1], "rb");
    if (!data || !f || fread(data, 1, bytes, f) != bytes) {
        fprintf(stderr, "%s: cannot read %zu bytes\n", argv[1], bytes);
        return 1;
    }
    fclose(f);
    isomend_volume vol;
    isomend_volume_init(&vol, data, type, n[0], n[1], n[2]);
    if (only > 0) {
        digest d;
        printf("%d thread(s): %.3f s\n", only, run(&vol, iso, only, &d, 0));
        free(data);
        return 0;
    }
    double t1[99], tn[99], ratio[99];
    int same = 1;
    digest d1, dn;
    (void)run(&vol, iso, 1, &d1, 1); /* the meshes, folded whole (not timed) */
    (void)run(&vol, iso, threads, &dn, 1);
    same = memcmp(&d1, &dn, sizeof d1) == 0;
    for (int r = 0; r < rounds; r++) { /* timed: a sink that costs next to nothing */
        if (r % 2) {
            tn[r] = run(&vol, iso, threads, &dn, 0);
            t1[r] = run(&vol, iso, 1, &d1, 0);
        } else {
            t1[r] = run(&vol, iso, 1, &d1, 0);
            tn[r] = run(&vol, iso, threads, &dn, 0);
        }
        same &= memcmp(&d1, &dn, sizeof d1) == 0;
        ratio[r] = t1[r] / tn[r];
    }
    qsort(t1, (size_t)rounds, sizeof(double), cmp_double);
    qsort(tn, (size_t)rounds, sizeof(double), cmp_double);
    qsort(ratio, (size_t)rounds, sizeof(double), cmp_double);
    const double samples = (double)n[0] * (double)n[1] * (double)n[2];
    printf("stream %lldx%lldx%lld %s, %llu vertices, %llu triangles, %d rounds\n", n[0], n[1],
           n[2], type_name, (unsigned long long)d1.nv, (unsigned long long)d1.nt, rounds);
    printf("  1 thread:   median %.3f s (%.0f slices/s, %.0f Msamples/s)\n", t1[rounds / 2],
           (double)n[2] / t1[rounds / 2], samples / t1[rounds / 2] / 1e6);
    printf("  %d threads:  median %.3f s (%.0f slices/s, %.0f Msamples/s)\n", threads,
           tn[rounds / 2], (double)n[2] / tn[rounds / 2], samples / tn[rounds / 2] / 1e6);
    printf("  speed-up (per-round ratio): median %.2f, min %.2f, max %.2f\n", ratio[rounds / 2],
           ratio[0], ratio[rounds - 1]);
    printf("  meshes identical: %s\n", same ? "yes" : "NO");
    free(data);
    return same ? 0 : 1;
}
