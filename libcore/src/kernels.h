/*
 * kernels.h - the tables of kernels each kernels_<target>.c compiles from
 * kernels_template.h (private): what those files give, and what
 * kernels_select() (cpu_features.c) chooses from.  kernels_sse2() and
 * kernels_avx2() return NULL where their target was not built;
 * kernels_avx2()'s table may only be used when cpu_features() has
 * CPU_FEATURE_AVX2.
 */
#ifndef ISOMEND_KERNELS_H
#define ISOMEND_KERNELS_H

struct extract_kernels;

const struct extract_kernels *kernels_scalar(void);
const struct extract_kernels *kernels_sse2(void);
const struct extract_kernels *kernels_avx2(void);

#endif /* ISOMEND_KERNELS_H */
