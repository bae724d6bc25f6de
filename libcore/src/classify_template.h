/*
 * classify_template.h - the classification loop of one voxel type
 * (private; no include guard: kernels_template.h includes it once per type).
 *
 * Before including, define
 *   VOXEL          the sample type (uint8_t, ..., double)
 *   VOXEL_NAME(f)  f with the type's suffix (f##_u8, ...)
 *   VOXEL_FLOAT    1 for float and double (samples that may be NaN), else 0
 * Defines VOXEL_NAME(classify).
 *
 * Written so the compiler vectorises it, for the target the including file
 * is compiled for: restrict pointers, the threshold in a local, 32-bit
 * counters.  A strided or misaligned row takes the memcpy loop.
 */

/* o[i] = (row's sample i >= t) for i < n, samples st bytes apart; returns
 * the NaN samples among them when count_nans (always on the memcpy loop). */
static uint64_t VOXEL_NAME(classify)(const char *row, int64_t n, int64_t st, VOXEL t,
                                     int count_nans, uint8_t *restrict o)
{
    uint32_t nn = 0;
#if !VOXEL_FLOAT
    count_nans = 0; /* none to count */
#endif
    if (st == (int64_t)sizeof(VOXEL) && (uintptr_t)row % _Alignof(VOXEL) == 0) {
        const VOXEL *restrict r = (const VOXEL *)(const void *)row;
        if (count_nans) {
#if VOXEL_FLOAT
            for (int64_t i = 0; i < n; i++) {
                o[i] = (uint8_t)(r[i] >= t);
                nn += (uint32_t)(r[i] != r[i]);
            }
#endif
        } else {
            for (int64_t i = 0; i < n; i++)
                o[i] = (uint8_t)(r[i] >= t);
        }
    } else {
        for (int64_t i = 0; i < n; i++) {
            VOXEL v;
            memcpy(&v, row + i * st, sizeof v);
            o[i] = (uint8_t)(v >= t);
#if VOXEL_FLOAT
            nn += (uint32_t)(v != v);
#endif
        }
    }
    return nn;
}
