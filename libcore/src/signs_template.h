/*
 * signs_template.h - classifying the samples into signs, row by row (private;
 * part of kernels_template.h, included once per target).
 *
 * A row of the marched grid becomes sign bytes (sample >= iso, with a
 * threshold chosen per voxel type so the comparison is exact and the loop
 * vectorises: grid_threshold in extract.c) and its span (row_span).  A
 * worker keeps the sign slices of the layers it marches in a ring of
 * SIGN_RING slots.
 */

#if KERNELS_AVX2
/* The NaN lanes of x. */
static inline uint64_t nans8(__m256 x)
{
    return (uint64_t)__builtin_popcount(
        (unsigned)_mm256_movemask_ps(_mm256_cmp_ps(x, x, _CMP_UNORD_Q)));
}

/*
 * classify_f32 on a contiguous row, written out for AVX2: 32 samples a step,
 * where the compiler's loop masks each comparison twice and counts NaNs lane
 * by lane; NaNs, which are rare, are counted only in the steps that have one
 * (docs/core-internals.md has the instruction counts).
 * Same results: `>=` is an ordered comparison, false for NaN, as in C.
 */
static uint64_t classify_f32_avx2(const float *restrict r, int64_t n, float t, int count_nans,
                                  uint8_t *restrict o)
{
    const __m256 tv = _mm256_set1_ps(t);
    /* packs interleave the four masks' halves; this puts them back in order */
    const __m256i order = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
    const __m256i one = _mm256_set1_epi8(1);
    uint64_t nn = 0;
    int64_t i = 0;
    for (; i + 32 <= n; i += 32) {
        const __m256 x0 = _mm256_loadu_ps(r + i), x1 = _mm256_loadu_ps(r + i + 8);
        const __m256 x2 = _mm256_loadu_ps(r + i + 16), x3 = _mm256_loadu_ps(r + i + 24);
        const __m256i m0 = _mm256_castps_si256(_mm256_cmp_ps(x0, tv, _CMP_GE_OQ));
        const __m256i m1 = _mm256_castps_si256(_mm256_cmp_ps(x1, tv, _CMP_GE_OQ));
        const __m256i m2 = _mm256_castps_si256(_mm256_cmp_ps(x2, tv, _CMP_GE_OQ));
        const __m256i m3 = _mm256_castps_si256(_mm256_cmp_ps(x3, tv, _CMP_GE_OQ));
        const __m256i b =
            _mm256_packs_epi16(_mm256_packs_epi32(m0, m1), _mm256_packs_epi32(m2, m3));
        _mm256_storeu_si256((__m256i *)(void *)(o + i),
                            _mm256_and_si256(_mm256_permutevar8x32_epi32(b, order), one));
        if (count_nans) {
            /* lane l is unordered when x0[l] or x1[l] is NaN: two compares
             * tell whether the 32 samples hold one, four count them */
            const __m256 u = _mm256_or_ps(_mm256_cmp_ps(x0, x1, _CMP_UNORD_Q),
                                          _mm256_cmp_ps(x2, x3, _CMP_UNORD_Q));
            if (!_mm256_testz_ps(u, u))
                nn += nans8(x0) + nans8(x1) + nans8(x2) + nans8(x3);
        }
    }
    for (; i < n; i++) {
        o[i] = (uint8_t)(r[i] >= t);
        nn += (uint64_t)(count_nans && r[i] != r[i]);
    }
    return nn;
}
#endif /* KERNELS_AVX2 */

/* Classifies row (j, k) of the marched grid into s[0..N0-1] and its span;
 * adds its NaNs to *nans unless nans is NULL (then they are not counted). */
static void classify_row(const grid *g, int64_t j, int64_t k, uint8_t *s, row_span *ri,
                         uint64_t *nans)
{
    const int64_t N0 = g->N[0], p = g->pad;
    const int64_t rj = j - p, rk = k - p;
    if (rj < 0 || rj >= g->n[1] || rk < 0 || rk >= g->n[2]) {
        memset(s, 0, (size_t)N0);
        ri->lo = N0;
        ri->hi = -1;
        ri->first = ri->last = 0;
        ri->simple = 0;
        return;
    }
    if (p) {
        s[0] = 0;
        s[N0 - 1] = 0;
    }
    uint8_t *o = s + p;
    const int64_t n = g->n[0], st = g->st[0];
    const char *row = g->data + rj * g->st[1] + (rk - g->z0) * g->st[2];
    uint64_t nn = 0;
    if (g->constant >= 0) {
        memset(o, g->constant, (size_t)n);
    } else {
        switch (g->type) {
        case ISOMEND_U8: classify_u8(row, n, st, (uint8_t)g->ithr, 0, o); break;
        case ISOMEND_I8: classify_i8(row, n, st, (int8_t)g->ithr, 0, o); break;
        case ISOMEND_U16: classify_u16(row, n, st, (uint16_t)g->ithr, 0, o); break;
        case ISOMEND_I16: classify_i16(row, n, st, (int16_t)g->ithr, 0, o); break;
        case ISOMEND_I32: classify_i32(row, n, st, (int32_t)g->ithr, 0, o); break;
        case ISOMEND_F32:
#if KERNELS_AVX2
            if (st == (int64_t)sizeof(float) && (uintptr_t)row % _Alignof(float) == 0) {
                nn = classify_f32_avx2((const float *)(const void *)row, n, g->fthr, nans != NULL,
                                       o);
                break;
            }
#endif
            nn = classify_f32(row, n, st, g->fthr, nans != NULL, o);
            break;
        case ISOMEND_F64: nn = classify_f64(row, n, st, g->iso, nans != NULL, o); break;
        }
    }
    if (nans)
        *nans += nn;
    ri->first = s[0];
    ri->last = s[N0 - 1];
    const uint8_t *d = memchr(s, s[0] ^ 1, (size_t)N0);
    if (!d) {
        ri->lo = N0;
        ri->hi = -1;
        ri->simple = 0;
        return;
    }
    ri->lo = d - s;
    ri->hi = last_not(s, N0, ri->last);
    ri->simple = 0;
    if (ri->first == ri->last) {
        const uint8_t *e = memchr(s + ri->lo, ri->first, (size_t)(N0 - ri->lo));
        ri->simple = e && e - s == ri->hi + 1;
    }
}

/* Slice k's signs and row spans, from the worker's ring: classified when the
 * slot holds another slice. */
static const uint8_t *signs(worker *w, int64_t k, const row_span **spans)
{
    const grid *g = &w->c->g;
    const int r = (int)(k % SIGN_RING);
    if (w->slice_held[r] != k) {
        uint64_t nans = 0;
        for (int64_t j = 0; j < g->N[1]; j++)
            classify_row(g, j, k, w->sign_bytes[r] + j * g->N[0], &w->spans[r][j], &nans);
        w->slice_nans[r] = nans;
        w->slice_held[r] = k;
    }
    *spans = w->spans[r];
    return w->sign_bytes[r];
}
