/*
 * methods_bench.c - the measurements behind the methods table of the README
 * (run by scripts/methods_table.py, which formats them).
 *
 * Per method, on `grids` random n^3 grids (uniform values in [-1, 1], iso 0,
 * padded so the surface is closed; the same grids for every method):
 *   hole_loops, multi_edges, nonmanifold_vertices  summed over the grids,
 *       from isomend_check() (the project's continuity checker);
 *   mismatch_grids  grids whose mesh differs from the trilinear interpolant
 *       in Euler characteristic or components (tests/topology/oracle.h),
 *       or is not a closed 2-manifold;
 *   triangles  summed.
 * Speed: (cube_ns) nanoseconds per surface cube of a smooth 160^3 field (sum
 * of Gaussians) to get the method's triangles from isomend_method_cube()
 * (MC: the table lookup isomend_case_triangles), corners already read, one
 * thread, best of 9; cube_ratio = that over MC's.  extract_ratio: the whole
 * isomend_extract() over MC's, one thread, normals off, best of 9.
 * F1 and F2 (thesis chapter 5.2): triangles, hole loops, edges used 3+
 * times, closed-manifold, topology match.
 *
 * Output: one JSON object per line.
 * Usage: isomend_methods_bench [grids] [n]     (defaults 10000, 4)
 */
#define _POSIX_C_SOURCE 199309L
#include "meshkit.h"
#include "methods.h"
#include "oracle.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define NM 8
static const isomend_method methods[NM] = {
    ISOMEND_METHOD_MC, ISOMEND_METHOD_DURST, ISOMEND_METHOD_DMC, ISOMEND_METHOD_FACIAL,
    ISOMEND_METHOD_GRADIENT, ISOMEND_METHOD_ASYMPTOTIC, ISOMEND_METHOD_TETRA, ISOMEND_METHOD_MC33};

static uint64_t rng = 0x853C49E6748FEA9Bull;
static double urand(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

typedef struct measure {
    long hole_loops, multi_edges, nonmanifold_vertices, mismatch_grids, not_closed;
    long triangles;
} measure;

static int check_mesh(const mk_mesh *m, isomend_check_report *rep)
{
    return isomend_check(m->pos, m->nv, m->tri, m->nt, m->box, rep) == ISOMEND_OK;
}

/* Extracts one grid with one method and measures it against `r`. */
static int measure_grid(const double *v, int nx, int ny, int nz, isomend_method method,
                        const oracle_result *r, measure *out, mk_topo *tp_out,
                        isomend_check_report *rep_out)
{
    mk_mesh mesh;
    if (mk_extract(v, nx, ny, nz, 0.0, method, 1, &mesh) != 0)
        return -1;
    isomend_check_report rep;
    mk_topo tp;
    int closed = mk_analyse(&mesh, &tp);
    if (!check_mesh(&mesh, &rep)) {
        mk_free(&mesh);
        return -1;
    }
    out->hole_loops += (long)rep.hole_loops;
    out->multi_edges += (long)rep.nonmanifold_edges;
    out->nonmanifold_vertices += (long)rep.nonmanifold_vertices;
    out->triangles += (long)mesh.nt;
    out->not_closed += !closed;
    out->mismatch_grids += !(closed && tp.chi == r->chi_s && tp.components == r->b0_s);
    if (tp_out)
        *tp_out = tp;
    if (rep_out)
        *rep_out = rep;
    mk_free(&mesh);
    return 0;
}

static double *smooth_field(int n)
{
    double *v = malloc((size_t)n * n * n * sizeof *v);
    if (!v)
        return NULL;
    double cx[16], cy[16], cz[16], w[16], s[16];
    for (int b = 0; b < 16; b++) {
        cx[b] = urand() * n;
        cy[b] = urand() * n;
        cz[b] = urand() * n;
        w[b] = (b % 3 == 2 ? -1.0 : 1.0) * (0.6 + urand());
        s[b] = n * (0.05 + 0.1 * urand());
    }
    for (int k = 0; k < n; k++)
        for (int j = 0; j < n; j++)
            for (int i = 0; i < n; i++) {
                double f = -0.3;
                for (int b = 0; b < 16; b++) {
                    double d2 = (i - cx[b]) * (i - cx[b]) + (j - cy[b]) * (j - cy[b]) +
                                (k - cz[b]) * (k - cz[b]);
                    f += w[b] * exp(-d2 / (s[b] * s[b]));
                }
                v[(size_t)i + (size_t)n * ((size_t)j + (size_t)n * k)] = f;
            }
    return v;
}

static double time_core(const double *v, int n, isomend_method m)
{
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F64, n, n, n);
    isomend_options o;
    isomend_options_init(&o);
    o.method = m;
    o.threads = 1;
    o.flags = ISOMEND_FLAG_PAD | ISOMEND_FLAG_NO_NORMALS | ISOMEND_FLAG_NO_ORIGINS;
    double best = 1e30;
    for (int rep = 0; rep < 9; rep++) {
        isomend_mesh *mesh = NULL;
        double t0 = now();
        if (isomend_extract(&vol, &o, &mesh, NULL) != ISOMEND_OK)
            return -1;
        double t = now() - t0;
        isomend_mesh_destroy(mesh);
        if (t < best)
            best = t;
    }
    return best;
}

/* The surface cubes of a field (configuration not 0 or 255), with their
 * corner values and, for the gradient method, their 4x4x4 rings. */
typedef struct cube_list {
    methods_cube *c;
    double *rings;
    size_t n;
} cube_list;

static int collect_cubes(const double *v, int n, cube_list *l)
{
    size_t cap = 1024;
    l->n = 0;
    l->c = malloc(cap * sizeof *l->c);
    l->rings = malloc(cap * 64 * sizeof *l->rings);
    if (!l->c || !l->rings)
        return -1;
    for (int k = 0; k + 1 < n; k++)
        for (int j = 0; j + 1 < n; j++)
            for (int i = 0; i + 1 < n; i++) {
                methods_cube c;
                c.config = 0;
                for (int q = 0; q < 8; q++) {
                    c.v[q] = v[(size_t)(i + (q & 1)) +
                               (size_t)n * ((size_t)(j + ((q >> 1) & 1)) + (size_t)n * (size_t)(k + (q >> 2)))];
                    c.config |= (unsigned)(c.v[q] >= 0.0) << q;
                }
                if (c.config == 0 || c.config == 255)
                    continue;
                if (l->n == cap) {
                    cap *= 2;
                    methods_cube *nc = realloc(l->c, cap * sizeof *nc);
                    double *nr = realloc(l->rings, cap * 64 * sizeof *nr);
                    if (nc)
                        l->c = nc;
                    if (nr)
                        l->rings = nr;
                    if (!nc || !nr)
                        return -1;
                }
                double *ring = l->rings + 64 * l->n;
                for (int z = -1; z <= 2; z++)
                    for (int y = -1; y <= 2; y++)
                        for (int x = -1; x <= 2; x++) {
                            int a = i + x, b = j + y, d = k + z;
                            ring[(x + 1) + 4 * (y + 1) + 16 * (z + 1)] =
                                (a < 0 || b < 0 || d < 0 || a >= n || b >= n || d >= n)
                                    ? NAN
                                    : v[(size_t)a + (size_t)n * ((size_t)b + (size_t)n * (size_t)d)];
                        }
                c.iso = 0.0;
                c.parity = (unsigned)(i + j + k) & 1;
                c.ring = NULL;
                l->c[l->n++] = c;
            }
    return 0;
}

/* Seconds per surface cube to get a method's triangles (MC: the table),
 * one thread, best of 9 passes over the list. */
static double time_cubes(const cube_list *l, isomend_method m)
{
    double best = 1e30;
    long sink = 0;
    unsigned char slots[3 * METHODS_MAX_TRI];
    int edges[15];
    for (int rep = 0; rep < 9; rep++) {
        double t0 = now();
        for (size_t i = 0; i < l->n; i++) {
            if (m == ISOMEND_METHOD_MC) {
                sink += isomend_case_triangles(l->c[i].config, edges);
            } else {
                methods_cube c = l->c[i];
                if (methods_needs_ring(m))
                    c.ring = l->rings + 64 * i;
                sink += isomend_method_cube(m, &c, slots);
            }
        }
        double t = now() - t0;
        if (t < best)
            best = t;
    }
    return sink > 0 ? best / (double)l->n : -1;
}

int main(int argc, char **argv)
{
    long grids = argc > 1 ? atol(argv[1]) : 10000;
    int n = argc > 2 ? atoi(argv[2]) : 4;
    if (grids < 1 || n < 2 || n > 64) {
        fprintf(stderr, "usage: %s [grids >= 1] [n in 2..64]\n", argv[0]);
        return 2;
    }
    measure ms[NM];
    memset(ms, 0, sizeof ms);
    double *v = malloc((size_t)n * n * n * sizeof *v);
    if (!v)
        return 1;
    for (long g = 0; g < grids; g++) {
        for (int i = 0; i < n * n * n; i++)
            v[i] = 2 * urand() - 1;
        oracle_result r;
        if (oracle_topology(v, n, n, n, 0.0, &r) != 0)
            return 1;
        for (int k = 0; k < NM; k++)
            if (measure_grid(v, n, n, n, methods[k], &r, &ms[k], NULL, NULL) != 0) {
                fprintf(stderr, "methods_bench: extraction with %s failed\n",
                        isomend_method_name(methods[k]));
                return 1;
            }
    }
    free(v);

    const int sn = 160;
    double *field = smooth_field(sn);
    if (!field)
        return 1;
    cube_list cl;
    if (collect_cubes(field, sn, &cl) != 0)
        return 1;
    double cube_mc = time_cubes(&cl, ISOMEND_METHOD_MC);
    double core_mc = time_core(field, sn, ISOMEND_METHOD_MC);
    for (int k = 0; k < NM; k++) {
        const int per_cube = methods[k] != ISOMEND_METHOD_DURST && methods[k] != ISOMEND_METHOD_DMC;
        char cube_ns[32] = "null", cube_ratio[32] = "null", extract_ratio[32] = "null";
        if (per_cube) {
            double cube_t = methods[k] == ISOMEND_METHOD_MC ? cube_mc : time_cubes(&cl, methods[k]);
            snprintf(cube_ns, sizeof cube_ns, "%.1f", 1e9 * cube_t);
            snprintf(cube_ratio, sizeof cube_ratio, "%.2f", cube_t / cube_mc);
        }
        if (isomend_method_available(methods[k]))
            snprintf(extract_ratio, sizeof extract_ratio, "%.2f",
                     (methods[k] == ISOMEND_METHOD_MC ? core_mc : time_core(field, sn, methods[k])) /
                         core_mc);
        printf("{\"kind\": \"random\", \"method\": \"%s\", \"grids\": %ld, \"n\": %d, "
               "\"hole_loops\": %ld, \"multi_edges\": %ld, \"nonmanifold_vertices\": %ld, "
               "\"not_closed_manifold\": %ld, \"mismatch_grids\": %ld, \"triangles\": %ld, "
               "\"cube_ns\": %s, \"cube_ratio\": %s, \"extract_ratio\": %s}\n",
               isomend_method_name(methods[k]), grids, n, ms[k].hole_loops, ms[k].multi_edges,
               ms[k].nonmanifold_vertices, ms[k].not_closed, ms[k].mismatch_grids, ms[k].triangles,
               cube_ns, cube_ratio, extract_ratio);
    }
    printf("{\"kind\": \"speed_reference\", \"n\": %d, \"surface_cubes\": %zu, "
           "\"mc_cube_ns\": %.2f, \"extract_mc_seconds\": %.4f}\n",
           sn, cl.n, 1e9 * cube_mc, core_mc);
    free(cl.c);
    free(cl.rings);
    free(field);

    /* F1 and F2. */
    double f[2][64];
    for (int z = 0; z < 4; z++)
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++) {
                f[0][x + 4 * (y + 4 * z)] = 4.0 * y + 4.0 * (x - z) * (x - z) - 5;
                f[1][x + 4 * (y + 4 * z)] =
                    4.0 * (y - 1) * (y - 1) + 2.0 * (x - z) * (x - z) - 2.0 * (x + z - 3) * (x + z - 3) + 1;
            }
    for (int fi = 0; fi < 2; fi++) {
        oracle_result r;
        oracle_topology(f[fi], 4, 4, 4, 0.0, &r);
        for (int k = 0; k < NM; k++) {
            measure one;
            memset(&one, 0, sizeof one);
            mk_topo tp;
            isomend_check_report rep;
            if (measure_grid(f[fi], 4, 4, 4, methods[k], &r, &one, &tp, &rep) != 0)
                return 1;
            printf("{\"kind\": \"F%d\", \"method\": \"%s\", \"triangles\": %ld, \"hole_loops\": %ld, "
                   "\"multi_edges\": %ld, \"closed_manifold\": %d, \"topology_match\": %d, "
                   "\"chi\": %ld, \"components\": %ld, \"oracle_chi\": %ld, \"oracle_components\": %ld}\n",
                   fi + 1, isomend_method_name(methods[k]), one.triangles, one.hole_loops,
                   one.multi_edges, !one.not_closed, !one.mismatch_grids, tp.chi, tp.components,
                   r.chi_s, r.b0_s);
        }
    }
    return 0;
}
