/*
 * test_small_pages.c - ISOMEND_FLAG_SMALL_PAGES: the same mesh (vertex order,
 * normals, statistics) as the default at 1, 2 and 3 threads (the caller's
 * run alone, and with the counted split or staged runs beside it), and
 * output arrays without a transparent huge page: every mapping the arrays lie
 * in shows AnonHugePages 0 in /proc/self/smaps, wherever the kernel's policy
 * leaves that to the program ("madvise", or "always": the reserved arrays
 * are marked MADV_NOHUGEPAGE).  Without the flag the default's huge pages are printed,
 * not required: whether the kernel has one free is not the library's to say.
 */
#define _DEFAULT_SOURCE
#include "isomend.h"
#include "meshcmp.h"
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { N = 130 }; /* 2 197 000 samples: reserved arrays (2^20 samples and more) */

/* kB of transparent huge pages in the mapping that holds address p; -1 when
 * /proc/self/smaps cannot tell. */
static long huge_kb_at(const void *p)
{
    FILE *f = fopen("/proc/self/smaps", "r");
    if (!f)
        return -1;
    char line[512];
    int inside = 0;
    long kb = -1;
    const uintptr_t a = (uintptr_t)p;
    while (fgets(line, sizeof line, f)) {
        unsigned long lo, hi;
        if (sscanf(line, "%lx-%lx ", &lo, &hi) == 2 && strchr(line, '-') < strchr(line, ' ')) {
            inside = a >= lo && a < hi;
            continue;
        }
        if (inside && sscanf(line, "AnonHugePages: %ld kB", &kb) == 1)
            break;
    }
    fclose(f);
    return kb;
}

/* The kernel's transparent huge page policy: 'a'lways, 'm'advise, 'n'ever, '?'. */
static char thp_policy(void)
{
    FILE *f = fopen("/sys/kernel/mm/transparent_hugepage/enabled", "r");
    char buf[128] = "";
    if (f) {
        if (!fgets(buf, sizeof buf, f))
            buf[0] = '\0';
        fclose(f);
    }
    const char *b = strchr(buf, '[');
    return b ? b[1] : '?';
}

static isomend_mesh *extract(const isomend_volume *vol, int threads, unsigned flags,
                             isomend_stats *st)
{
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 0.0;
    o.threads = threads;
    o.flags = flags;
    isomend_mesh *m = NULL;
    CHECK_EQ_INT(isomend_extract(vol, &o, &m, st), ISOMEND_OK);
    return m;
}

int main(void)
{
    /* A gyroid: a dense surface, so that every output array passes 2 MiB. */
    float *v = malloc(sizeof(float) * N * N * N);
    CHECK(v != NULL);
    if (!v)
        TEST_EXIT();
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++) {
                const double s = 0.35;
                v[((size_t)z * N + y) * N + x] =
                    (float)(sin(s * x) * cos(s * y) + sin(s * y) * cos(s * z) +
                            sin(s * z) * cos(s * x));
            }
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F32, N, N, N);
    const char policy = thp_policy();

    for (int threads = 1; threads <= 3; threads++) {
        isomend_stats s0, s1;
        isomend_mesh *def = extract(&vol, threads, 0, &s0);
        isomend_mesh *small = extract(&vol, threads, ISOMEND_FLAG_SMALL_PAGES, &s1);
        if (!def || !small) {
            isomend_mesh_destroy(def);
            isomend_mesh_destroy(small);
            continue;
        }
        CHECK(isomend_mesh_triangle_count(small) > 300000); /* 3.6 MB of triangles */
        CHECK(same_mesh(def, small));
        CHECK(memcmp(&s0, &s1, sizeof s0) == 0);
        const void *arrays[3] = {isomend_mesh_positions(small), isomend_mesh_normals(small),
                                 isomend_mesh_triangles(small)};
        const void *darrays[3] = {isomend_mesh_positions(def), isomend_mesh_normals(def),
                                  isomend_mesh_triangles(def)};
        /* reserved arrays, marked MADV_NOHUGEPAGE: small under any policy */
        const int must_be_small = policy == 'm' || policy == 'n' || policy == 'a';
        for (int q = 0; q < 3; q++) {
            const long kb = huge_kb_at(arrays[q]);
            printf("%d thread(s), array %d: small pages %ld kB huge, default %ld kB huge (policy %c)\n",
                   threads, q, kb, huge_kb_at(darrays[q]), policy);
            CHECK(kb >= 0);
            if (must_be_small)
                CHECK(kb == 0);
        }
        isomend_mesh_destroy(def);
        isomend_mesh_destroy(small);
    }
    free(v);
    TEST_EXIT();
}
