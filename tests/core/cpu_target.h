/*
 * cpu_target.h - the C tests' choice of the core's CPU target (tests only).
 *
 * The core compiles its kernels once per target (portable C, SSE2, AVX2)
 * and takes the best one the CPU has (libcore/src/cpu_features.c).  A test
 * run with --cpu=scalar, --cpu=sse2 or --cpu=avx2 hides the features above
 * that target (cpu_features_set_test_mask, linked from the static library),
 * so one binary tests every target the machine can run.
 */
#ifndef ISOMEND_TEST_CPU_TARGET_H
#define ISOMEND_TEST_CPU_TARGET_H

#include "cpu_features.h"
#include "context.h"

#include <stdio.h>
#include <string.h>

/* The targets, fastest first, and the feature mask that selects each. */
static const struct {
    const char *name;
    unsigned mask;
} cpu_targets[] = {
    {"avx2", CPU_FEATURES_ALL},
    {"sse2", CPU_FEATURE_SSE2},
    {"scalar", 0},
};
enum { CPU_TARGET_COUNT = sizeof cpu_targets / sizeof cpu_targets[0] };

/* The kernels the next extraction takes. */
static inline const char *cpu_target_selected(void)
{
    return kernels_select()->name;
}

/* Selects target `name`; returns 1 if the extraction then runs its kernels,
 * 0 if this machine lacks it (a lower target runs), -1 for an unknown name. */
static inline int cpu_target_use(const char *name)
{
    for (int t = 0; t < CPU_TARGET_COUNT; t++)
        if (strcmp(name, cpu_targets[t].name) == 0) {
            cpu_features_set_test_mask(cpu_targets[t].mask);
            return strcmp(cpu_target_selected(), name) == 0;
        }
    return -1;
}

/* Handles a --cpu=TARGET argument, if any: returns 0 to go on, 1 to stop
 * with an error (unknown target, message printed). */
static inline int cpu_target_from_args(int argc, char **argv)
{
    for (int i = 1; i < argc; i++) {
        if (strncmp(argv[i], "--cpu=", 6) != 0)
            continue;
        const int r = cpu_target_use(argv[i] + 6);
        if (r < 0) {
            fprintf(stderr, "%s: unknown CPU target '%s' (avx2, sse2, scalar)\n", argv[0],
                    argv[i] + 6);
            return 1;
        }
        printf("kernels: %s%s\n", cpu_target_selected(),
               r ? "" : " (the CPU lacks the target asked for)");
    }
    return 0;
}

#endif /* ISOMEND_TEST_CPU_TARGET_H */
