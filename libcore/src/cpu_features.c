/*
 * cpu_features.c - the CPU probe, run once and cached, and the one function
 * that chooses the kernels (cpu_features.h).
 *
 * The cache is the library's only static state besides the test mask: a
 * word written once with what the CPU supports, which every thread would
 * compute alike, so racing first calls are harmless.  Atomics make the
 * accesses well defined.
 */
#include "cpu_features.h"
#include "kernels.h"

#include "context.h"

#include <stdatomic.h>

/* CPU_FEATURE_* | PROBED once probed; 0 before. */
enum { PROBED = 1u << 31 };
static atomic_uint probed_features;
static atomic_uint test_mask = CPU_FEATURES_ALL;

static unsigned probe(void)
{
    unsigned f = 0;
#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__))
    /* GCC's and Clang's probe: CPUID, and for AVX2 also XGETBV (the operating
     * system saves the YMM registers). */
    __builtin_cpu_init();
    if (__builtin_cpu_supports("sse2"))
        f |= CPU_FEATURE_SSE2;
    if (__builtin_cpu_supports("avx2"))
        f |= CPU_FEATURE_AVX2;
#endif
    return f;
}

unsigned cpu_features(void)
{
    unsigned f = atomic_load_explicit(&probed_features, memory_order_relaxed);
    if (!f) {
        f = probe() | PROBED;
        atomic_store_explicit(&probed_features, f, memory_order_relaxed);
    }
    return f & atomic_load_explicit(&test_mask, memory_order_relaxed) & CPU_FEATURES_ALL;
}

void cpu_features_set_test_mask(unsigned mask)
{
    atomic_store_explicit(&test_mask, mask, memory_order_relaxed);
}

const extract_kernels *kernels_select(void)
{
    const unsigned f = cpu_features();
    const extract_kernels *k = NULL;
    if (f & CPU_FEATURE_AVX2)
        k = kernels_avx2();
    if (!k && (f & CPU_FEATURE_SSE2))
        k = kernels_sse2();
    return k ? k : kernels_scalar();
}
