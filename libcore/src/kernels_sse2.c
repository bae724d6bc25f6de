/*
 * kernels_sse2.c - the kernels with SSE2 intrinsics for the 16-column scans,
 * the baseline of x86-64.  Elsewhere (no __SSE2__) the file holds nothing
 * and kernels_sse2() returns NULL.
 */
#include "kernels.h"

#if defined(__SSE2__)
#define KERNELS_SSE2 1
#define KERNELS_AVX2 0
#include "kernels_template.h"

const extract_kernels *kernels_sse2(void)
{
    return &kernels_table;
}
#else
const extract_kernels *kernels_sse2(void)
{
    return NULL;
}
#endif
