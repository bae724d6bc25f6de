/*
 * test_reserve_fallback.c - isomend_extract() on a grid of 2^20 samples or
 * more writes its runs into address-space reservations of the largest mesh
 * the grid allows (hundreds of MB for this volume), and a staged run into
 * its thread's own region, as large (libcore/src/slabs.c).  Where the system
 * refuses them (here an address-space limit, RLIMIT_AS, as `ulimit -v` sets
 * it; strict overcommit does the same), the extraction must still succeed,
 * with the same mesh and statistics: without the regions, the caller's run
 * alone; without the mesh's reservations, counted runs (count, allocate the
 * mesh's size, run).
 *
 * Not under the sanitizers: their shadow memory does not fit an address-space
 * limit.
 */
#define _DEFAULT_SOURCE /* MAP_ANONYMOUS, MAP_NORESERVE */
#include "isomend.h"
#include "meshcmp.h"
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/resource.h>

enum { NX = 131, NY = 127, NZ = 128 }; /* 2 129 536 samples */

static isomend_mesh *extract(const isomend_volume *vol, isomend_method method, int threads,
                             isomend_stats *st, isomend_status *status)
{
    isomend_options o;
    isomend_options_init(&o);
    o.method = method;
    o.threads = threads;
    isomend_mesh *m = NULL;
    *status = isomend_extract(vol, &o, &m, st);
    return m;
}

/* Bytes of address space the process uses now (VmSize). */
static long long vm_size(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    char line[256];
    long long kb = -1;
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "VmSize: %lld kB", &kb) == 1)
            break;
    if (f)
        fclose(f);
    return kb < 0 ? -1 : kb * 1024;
}

int main(void)
{
    /* Two interleaved spheres: closed surfaces with many ambiguous faces. */
    float *v = malloc(sizeof(float) * NX * NY * NZ);
    CHECK(v != NULL);
    if (!v)
        TEST_EXIT();
    for (int z = 0; z < NZ; z++)
        for (int y = 0; y < NY; y++)
            for (int x = 0; x < NX; x++)
                v[((size_t)z * NY + y) * NX + x] =
                    (float)(sin(0.31 * x) * cos(0.27 * y) + sin(0.23 * z) * cos(0.29 * x) +
                            0.4 - sqrt((x - 65.0) * (x - 65.0) + (y - 63.0) * (y - 63.0) +
                                       (z - 64.0) * (z - 64.0)) / 60.0);
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F32, NX, NY, NZ);

    static const isomend_method methods[] = {ISOMEND_METHOD_MC, ISOMEND_METHOD_DMC};
    isomend_mesh *ref[2];
    isomend_stats ref_st[2];
    for (int q = 0; q < 2; q++) {
        isomend_status s;
        ref[q] = extract(&vol, methods[q], 1, &ref_st[q], &s);
        CHECK_EQ_INT(s, ISOMEND_OK);
        CHECK(ref[q] && isomend_mesh_triangle_count(ref[q]) > 10000);
    }

    /* Room for the mesh's arrays at their largest (positions and normals
     * 77 MB each, triangles 250 MB, origins 21 MB), not for a staged
     * thread's region as large: at 2 threads the caller's run goes alone (or
     * the counted split, which needs no region), with the same mesh. */
    const long long now = vm_size();
    CHECK(now > 0);
    struct rlimit mid = {(rlim_t)(now + (640LL << 20)), RLIM_INFINITY};
    CHECK_EQ_INT(setrlimit(RLIMIT_AS, &mid), 0);
    for (int q = 0; q < 2; q++) {
        isomend_status s;
        isomend_mesh *m = extract(&vol, methods[q], 2, NULL, &s);
        CHECK_EQ_INT(s, ISOMEND_OK);
        if (m && ref[q])
            CHECK(same_mesh(ref[q], m));
        isomend_mesh_destroy(m);
    }

    /* Room for counted runs (a few MB of mesh and work arrays), not for the
     * reservations (the triangles' alone are 10 a cube, 250 MB). */
    struct rlimit lim = {(rlim_t)(now + (96LL << 20)), RLIM_INFINITY};
    CHECK_EQ_INT(setrlimit(RLIMIT_AS, &lim), 0);
    void *probe = mmap(NULL, (size_t)256 << 20, PROT_READ | PROT_WRITE,
                       MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    CHECK(probe == MAP_FAILED); /* the limit does refuse a reservation that size */
    if (probe != MAP_FAILED)
        munmap(probe, (size_t)256 << 20);

    for (int q = 0; q < 2; q++) {
        isomend_status s;
        isomend_stats st;
        isomend_mesh *m = extract(&vol, methods[q], 1, &st, &s);
        CHECK_EQ_INT(s, ISOMEND_OK);
        if (m && ref[q]) {
            CHECK(same_mesh(ref[q], m));
            CHECK(memcmp(&st, &ref_st[q], sizeof st) == 0);
        }
        isomend_mesh_destroy(m);
        isomend_mesh_destroy(ref[q]);
    }
    free(v);
    TEST_EXIT();
}
