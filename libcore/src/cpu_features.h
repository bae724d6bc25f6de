/*
 * cpu_features.h - the CPU features the kernels use, probed once, and the
 * choice of kernels (private).
 *
 * One probe per process, cached (cpu_features): what the CPU and the
 * operating system support does not change while the library runs.  One
 * selection function (kernels_select) turns the features into the table of
 * kernels an extraction calls; it is called once per extraction.
 *
 * For tests only, cpu_features_set_test_mask() hides features, so that one
 * test binary can run the portable, SSE2 and AVX2 kernels one after the
 * other and compare their meshes byte for byte (tests/core/test_digest.c).
 * It is not part of the library's API (isomend.h) and is not exported by
 * the shared library; the tests link the static one.
 */
#ifndef ISOMEND_CPU_FEATURES_H
#define ISOMEND_CPU_FEATURES_H

struct extract_kernels;

enum {
    CPU_FEATURE_SSE2 = 1u << 0,
    CPU_FEATURE_AVX2 = 1u << 1, /* with the OS saving the 256-bit registers */
    CPU_FEATURES_ALL = CPU_FEATURE_SSE2 | CPU_FEATURE_AVX2
};

/* The features of this CPU the kernels may use (CPU_FEATURE_*), less those
 * hidden by the test mask.  Thread safe. */
unsigned cpu_features(void);

/* Tests only: from now on cpu_features() reports at most `mask`
 * (CPU_FEATURES_ALL to undo).  Extractions already running keep their
 * kernels. */
void cpu_features_set_test_mask(unsigned mask);

/* The kernels for cpu_features(): AVX2, else SSE2, else portable C. */
const struct extract_kernels *kernels_select(void);

/* (The tables it chooses from: kernels.h.) */

#endif /* ISOMEND_CPU_FEATURES_H */
