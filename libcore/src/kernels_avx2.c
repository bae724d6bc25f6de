/*
 * kernels_avx2.c - the kernels compiled for AVX2: the SSE2 scans, the plain
 * loops vectorised 32 bytes wide, the float32 classification and four
 * vertices at a time written with AVX2 intrinsics.  Every function here is
 * compiled with the target attribute (the pragma below, so the build needs
 * no -mavx2), and is only reached through the table that kernels_select()
 * hands out once the CPU probe (cpu_features.c) has found AVX2.  On other
 * compilers or CPUs, kernels_avx2() returns NULL.
 *
 * AVX2 brings no fused multiply-add (that is FMA, a separate target), and
 * the file is compiled with -ffp-contract=off in any case: the arithmetic is
 * the other targets', operation for operation.
 */
#include "kernels.h"
#include "context.h"
#include "methods.h"
#include "tables.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>

#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2")
#endif

#define KERNELS_SSE2 1
#define KERNELS_AVX2 1
#include "kernels_template.h"

#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

/* Outside the target: the caller may run it before it knows the CPU. */
const extract_kernels *kernels_avx2(void)
{
    return &kernels_table;
}

#else
const extract_kernels *kernels_avx2(void)
{
    return NULL;
}
#endif
