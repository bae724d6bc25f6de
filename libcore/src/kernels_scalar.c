/*
 * kernels_scalar.c - the kernels in portable C: the 16-column scans on
 * 64-bit words, no intrinsics (the compiler may still vectorise the plain
 * loops for the baseline it targets).  The reference the other targets
 * must equal byte for byte, and the choice on CPUs with neither SSE2 nor
 * AVX2 (kernels_select).
 */
#define KERNELS_SSE2 0
#define KERNELS_AVX2 0
#include "kernels.h"
#include "kernels_template.h"

const extract_kernels *kernels_scalar(void)
{
    return &kernels_table;
}
