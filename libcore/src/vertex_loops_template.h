/*
 * vertex_loops_template.h - the vertex loops of one voxel type (private; no
 * include guard: kernels_template.h includes it once per type).
 *
 * Before including, define VOXEL and VOXEL_NAME(f) as for
 * classify_template.h.  Defines, for each axis a of the edges (x, y, z):
 *   VOXEL_NAME(row_vertices_a)   numbers and computes the crossings of one
 *                                row in a column range (wide spans);
 *   VOXEL_NAME(list_vertices_a)  computes listed vertices with prefetching
 *                                (narrow spans, vertex_inline.h);
 * and with KERNELS_AVX2 the same four vertices at a time,
 * VOXEL_NAME(row_vertices4_a) and VOXEL_NAME(list_vertices4_a).
 */

/* Sample of type VOXEL at p, as a double. */
static inline double VOXEL_NAME(load)(const char *p)
{
    VOXEL v;
    memcpy(&v, p, sizeof v);
    return (double)v;
}

/* Computes vertex `id` on the edge from (x, j, m) along the axis. */
static ALWAYS_INLINE void VOXEL_NAME(vertex_one)(const vertex_setup *s, const int axis, int64_t x,
                                                 int64_t j, uint64_t id)
{
    const size_t at = vertex_at(s->base, id);
    float *pos = s->P + at, *nrm = s->NR ? s->NR + at : NULL;
    if (s->slice_inner && j >= s->y_lo && j <= s->y_hi && x >= s->x_lo && x <= s->x_hi) {
        const int64_t sx = s->sx, sy = s->sy, sz = s->sz;
        const char *p = s->slice + (x - s->pad) * sx + (j - s->pad) * sy, *q = p + s->sa;
        const double f0 = VOXEL_NAME(load)(p), f1 = VOXEL_NAME(load)(q);
        const double t = (s->iso - f0) / (f1 - f0);
        double n0 = 0, n1 = 0, n2 = 0, len = 1.0;
        if (nrm) {
            const double u = 1.0 - t;
#define LD(ptr) VOXEL_NAME(load)(ptr)
            n0 = -(u * ((axis == 0 ? f1 : LD(p + sx)) - LD(p - sx)) +
                   t * (LD(q + sx) - (axis == 0 ? f0 : LD(q - sx)))) *
                 s->ix;
            n1 = -(u * ((axis == 1 ? f1 : LD(p + sy)) - LD(p - sy)) +
                   t * (LD(q + sy) - (axis == 1 ? f0 : LD(q - sy)))) *
                 s->iy;
            n2 = -(u * ((axis == 2 ? f1 : LD(p + sz)) - LD(p - sz)) +
                   t * (LD(q + sz) - (axis == 2 ? f0 : LD(q - sz)))) *
                 s->iz;
#undef LD
            len = sqrt(n0 * n0 + n1 * n1 + n2 * n2);
        }
        if (t >= 0.0 && t <= 1.0 && len > 0.0 && len < INFINITY) {
            pos[0] = (float)(s->ox + ((double)x + (axis == 0 ? t : 0.0)) * s->hx);
            pos[1] = (float)(s->oy + ((double)j + (axis == 1 ? t : 0.0)) * s->hy);
            pos[2] = axis == 2 ? (float)(s->oz + (s->pz0 + t) * s->hz) : s->fz;
            if (nrm) {
                const double sc = s->sgn / len;
                nrm[0] = (float)(sc * n0);
                nrm[1] = (float)(sc * n1);
                nrm[2] = (float)(sc * n2);
            }
            return;
        }
    }
    make_vertex(s->g, s->flip, x, j, s->m, axis, pos, nrm);
}

/* Numbers and computes the vertices of one row's crossings in [from, to]:
 * the columns where rows a and b differ. */
static ALWAYS_INLINE uint64_t VOXEL_NAME(row_vertices_on)(const ctx *c, const uint8_t *a,
                                                          const uint8_t *b, int64_t from,
                                                          int64_t to, int64_t j0, int64_t m,
                                                          uint32_t *ids, uint64_t id,
                                                          const int axis)
{
    vertex_setup s;
    vertex_setup_init(&s, c, m, axis);
    for (int64_t i = from; i <= to; i += 16) {
        uint32_t diff = diff16(a + i, b + i);
        if (to - i < 15)
            diff = first_bits(diff, to - i + 1);
        while (diff) {
            const int64_t col = i + __builtin_ctz(diff);
            diff &= diff - 1;
            VOXEL_NAME(vertex_one)(&s, axis, col, j0, id);
            ids[col] = (uint32_t)id++;
        }
    }
    return id;
}

/* Computes listed vertices, prefetching the samples of the item
 * VERTEX_PREFETCH places ahead when it lies off its predecessor's cache line. */
static ALWAYS_INLINE void VOXEL_NAME(list_vertices_on)(const ctx *c, const vertex_item *it,
                                                       size_t n, int64_t m, const int axis)
{
    vertex_setup s;
    vertex_setup_init(&s, c, m, axis);
    const size_t ahead = s.slice_inner ? VERTEX_PREFETCH : 0; /* 0: no prefetching */
    const int32_t line = 64 / (int32_t)sizeof(VOXEL);         /* samples a cache line */
    /* Step e prefetches item e and computes item e - ahead. */
    for (size_t e = 0; e < n + ahead; e++) {
        if (ahead && e < n)
            prefetch_item(&s, axis, it, e, line);
        if (e >= ahead) {
            const vertex_item *v = &it[e - ahead];
            VOXEL_NAME(vertex_one)(&s, axis, v->x, v->j, v->id);
        }
    }
}

#if KERNELS_AVX2
/*
 * Four samples as doubles, converted in one instruction: integers through
 * 32-bit lanes, floats through single-precision lanes (both exact, as the
 * scalar conversions are).
 */
static inline __m256d VOXEL_NAME(load4)(const char *const p[4], int64_t off)
{
    VOXEL v0, v1, v2, v3;
    memcpy(&v0, p[0] + off, sizeof v0);
    memcpy(&v1, p[1] + off, sizeof v1);
    memcpy(&v2, p[2] + off, sizeof v2);
    memcpy(&v3, p[3] + off, sizeof v3);
    if ((VOXEL)0.5 == 0) /* an integer type */
        return _mm256_cvtepi32_pd(
            _mm_setr_epi32((int32_t)v0, (int32_t)v1, (int32_t)v2, (int32_t)v3));
    if (sizeof(VOXEL) == sizeof(float))
        return _mm256_cvtps_pd(_mm_setr_ps((float)v0, (float)v1, (float)v2, (float)v3));
    return _mm256_setr_pd((double)v0, (double)v1, (double)v2, (double)v3);
}

/* The normal's component along axis `comp` at the four vertices, stride
 * `st` and 1 / (2 spacing) `inv` along it: vertex_one's n0, n1 or n2. */
static ALWAYS_INLINE __m256d VOXEL_NAME(gradient4)(const char *const p[4], const int axis,
                                                   const int comp, int64_t st, int64_t sa,
                                                   double inv, __m256d f0, __m256d f1, __m256d t,
                                                   __m256d u)
{
    const __m256d negz = _mm256_set1_pd(-0.0);
#define LD4(off) VOXEL_NAME(load4)(p, off)
    const __m256d lower =
        axis == comp ? _mm256_sub_pd(f1, LD4(-st)) : _mm256_sub_pd(LD4(st), LD4(-st));
    const __m256d upper =
        axis == comp ? _mm256_sub_pd(LD4(sa + st), f0) : _mm256_sub_pd(LD4(sa + st), LD4(sa - st));
#undef LD4
    return _mm256_mul_pd(
        _mm256_xor_pd(_mm256_add_pd(_mm256_mul_pd(u, lower), _mm256_mul_pd(t, upper)), negz),
        _mm256_set1_pd(inv));
}

/*
 * The four vertices on the edges from (xs[l], js[l], m) along the axis, all
 * interior, into *out; returns 1 when all four are valid (vertex_one's test),
 * else 0 and nothing is to be kept.
 */
static ALWAYS_INLINE int VOXEL_NAME(vertex4)(const vertex_setup *s, const int axis,
                                             const int64_t xs[4], const int64_t js[4],
                                             vertex4_lanes *out)
{
    const int64_t pad = s->pad, sx = s->sx, sy = s->sy, sa = s->sa;
    const char *const p[4] = {
        s->slice + (xs[0] - pad) * sx + (js[0] - pad) * sy,
        s->slice + (xs[1] - pad) * sx + (js[1] - pad) * sy,
        s->slice + (xs[2] - pad) * sx + (js[2] - pad) * sy,
        s->slice + (xs[3] - pad) * sx + (js[3] - pad) * sy,
    };
    const __m256d f0 = VOXEL_NAME(load4)(p, 0), f1 = VOXEL_NAME(load4)(p, sa);
    const __m256d t =
        _mm256_div_pd(_mm256_sub_pd(_mm256_set1_pd(s->iso), f0), _mm256_sub_pd(f1, f0));
    const __m256d u = _mm256_sub_pd(_mm256_set1_pd(1.0), t);
    const __m256d n0 = VOXEL_NAME(gradient4)(p, axis, 0, sx, sa, s->ix, f0, f1, t, u);
    const __m256d n1 = VOXEL_NAME(gradient4)(p, axis, 1, sy, sa, s->iy, f0, f1, t, u);
    const __m256d n2 = VOXEL_NAME(gradient4)(p, axis, 2, s->sz, sa, s->iz, f0, f1, t, u);
    const __m256d len = _mm256_sqrt_pd(_mm256_add_pd(
        _mm256_add_pd(_mm256_mul_pd(n0, n0), _mm256_mul_pd(n1, n1)), _mm256_mul_pd(n2, n2)));
    const __m256d zero = _mm256_setzero_pd();
    const __m256d valid =
        _mm256_and_pd(_mm256_and_pd(_mm256_cmp_pd(t, zero, _CMP_GE_OQ),
                                    _mm256_cmp_pd(t, _mm256_set1_pd(1.0), _CMP_LE_OQ)),
                      _mm256_and_pd(_mm256_cmp_pd(len, zero, _CMP_GT_OQ),
                                    _mm256_cmp_pd(len, _mm256_set1_pd(INFINITY), _CMP_LT_OQ)));
    __m256d xd = _mm256_cvtepi32_pd(_mm_setr_epi32((int)xs[0], (int)xs[1], (int)xs[2], (int)xs[3]));
    __m256d yd = _mm256_cvtepi32_pd(_mm_setr_epi32((int)js[0], (int)js[1], (int)js[2], (int)js[3]));
    if (axis == 0)
        xd = _mm256_add_pd(xd, t);
    if (axis == 1)
        yd = _mm256_add_pd(yd, t);
    out->px = _mm256_cvtpd_ps(
        _mm256_add_pd(_mm256_set1_pd(s->ox), _mm256_mul_pd(xd, _mm256_set1_pd(s->hx))));
    out->py = _mm256_cvtpd_ps(
        _mm256_add_pd(_mm256_set1_pd(s->oy), _mm256_mul_pd(yd, _mm256_set1_pd(s->hy))));
    out->pz =
        axis == 2
            ? _mm256_cvtpd_ps(_mm256_add_pd(
                  _mm256_set1_pd(s->oz),
                  _mm256_mul_pd(_mm256_add_pd(_mm256_set1_pd(s->pz0), t), _mm256_set1_pd(s->hz))))
            : _mm_set1_ps(s->fz);
    const __m256d sc = _mm256_div_pd(_mm256_set1_pd(s->sgn), len);
    out->nx = _mm256_cvtpd_ps(_mm256_mul_pd(sc, n0));
    out->ny = _mm256_cvtpd_ps(_mm256_mul_pd(sc, n1));
    out->nz = _mm256_cvtpd_ps(_mm256_mul_pd(sc, n2));
    return _mm256_movemask_pd(valid) == 0xF;
}

/* row_vertices_on, four crossings at a time: they are grouped in column
 * order; four interior vertices that all come out valid are stored at once,
 * otherwise the four take vertex_one. */
static ALWAYS_INLINE uint64_t VOXEL_NAME(row_vertices4_on)(const ctx *c, const uint8_t *a,
                                                           const uint8_t *b, int64_t from,
                                                           int64_t to, int64_t j0, int64_t m,
                                                           uint32_t *ids, uint64_t id,
                                                           const int axis)
{
    vertex_setup s;
    vertex_setup_init(&s, c, m, axis);
    const int row_inner = s.NR && s.slice_inner && j0 >= s.y_lo && j0 <= s.y_hi;
    const int64_t js[4] = {j0, j0, j0, j0};
    int64_t pend[16 + 3]; /* crossings not yet computed, in column order */
    int np = 0;
    for (int64_t i = from; i <= to; i += 16) {
        uint32_t diff = diff16(a + i, b + i);
        if (to - i < 15)
            diff = first_bits(diff, to - i + 1);
        while (diff) {
            pend[np++] = i + __builtin_ctz(diff);
            diff &= diff - 1;
        }
        int g4 = 0;
        for (; np - g4 >= 4; g4 += 4, id += 4) {
            const int64_t *x4 = pend + g4;
            int done = 0;
            if (row_inner && x4[0] >= s.x_lo && x4[3] <= s.x_hi) {
                vertex4_lanes v;
                if (VOXEL_NAME(vertex4)(&s, axis, x4, js, &v)) {
                    store_xyz4(s.P + vertex_at(s.base, id), v.px, v.py, v.pz);
                    store_xyz4(s.NR + vertex_at(s.base, id), v.nx, v.ny, v.nz);
                    done = 1;
                }
            }
            for (int l = 0; l < 4; l++) {
                if (!done)
                    VOXEL_NAME(vertex_one)(&s, axis, x4[l], j0, id + (uint64_t)l);
                ids[x4[l]] = (uint32_t)(id + (uint64_t)l);
            }
        }
        if (g4) {
            for (int r = g4; r < np; r++)
                pend[r - g4] = pend[r];
            np -= g4;
        }
    }
    for (int r = 0; r < np; r++, id++) {
        VOXEL_NAME(vertex_one)(&s, axis, pend[r], j0, id);
        ids[pend[r]] = (uint32_t)id;
    }
    return id;
}

/* list_vertices_on, four consecutive items at a time, with the same
 * prefetching: a group is computed once its last item was prefetched
 * VERTEX_PREFETCH steps before. */
static ALWAYS_INLINE void VOXEL_NAME(list_vertices4_on)(const ctx *c, const vertex_item *it,
                                                        size_t n, int64_t m, const int axis)
{
    vertex_setup s;
    vertex_setup_init(&s, c, m, axis);
    const size_t ahead = s.slice_inner ? VERTEX_PREFETCH : 0;
    const int32_t line = 64 / (int32_t)sizeof(VOXEL);
    size_t done = 0;
    for (size_t e = 0; e < n + ahead + 3; e++) {
        if (ahead && e < n)
            prefetch_item(&s, axis, it, e, line);
        if (e < done + 3 + ahead)
            continue;
        const size_t left = n - done;
        if (left == 0)
            break;
        const vertex_item *v = it + done;
        int ok = 0;
        if (left >= 4 && s.NR && s.slice_inner) {
            const int64_t xs[4] = {v[0].x, v[1].x, v[2].x, v[3].x};
            const int64_t js[4] = {v[0].j, v[1].j, v[2].j, v[3].j};
            int inner = 1;
            for (int l = 0; l < 4; l++)
                inner &= xs[l] >= s.x_lo && xs[l] <= s.x_hi && js[l] >= s.y_lo && js[l] <= s.y_hi;
            vertex4_lanes lanes;
            if (inner && VOXEL_NAME(vertex4)(&s, axis, xs, js, &lanes)) {
                store_items4(s.P, s.base, v, lanes.px, lanes.py, lanes.pz);
                store_items4(s.NR, s.base, v, lanes.nx, lanes.ny, lanes.nz);
                ok = 1;
            }
        }
        const size_t grp = left >= 4 ? 4 : left;
        if (!ok)
            for (size_t l = 0; l < grp; l++)
                VOXEL_NAME(vertex_one)(&s, axis, v[l].x, v[l].j, v[l].id);
        done += grp;
    }
}
#endif /* KERNELS_AVX2 */

/* The loops per axis (0 x, 1 y, 2 z), for the tables of kernels_template.h. */
static uint64_t VOXEL_NAME(row_vertices_x)(const ctx *c, const uint8_t *a, const uint8_t *b,
                                           int64_t from, int64_t to, int64_t j0, int64_t m,
                                           uint32_t *ids, uint64_t id)
{
    return VOXEL_NAME(row_vertices_on)(c, a, b, from, to, j0, m, ids, id, 0);
}
static uint64_t VOXEL_NAME(row_vertices_y)(const ctx *c, const uint8_t *a, const uint8_t *b,
                                           int64_t from, int64_t to, int64_t j0, int64_t m,
                                           uint32_t *ids, uint64_t id)
{
    return VOXEL_NAME(row_vertices_on)(c, a, b, from, to, j0, m, ids, id, 1);
}
static uint64_t VOXEL_NAME(row_vertices_z)(const ctx *c, const uint8_t *a, const uint8_t *b,
                                           int64_t from, int64_t to, int64_t j0, int64_t m,
                                           uint32_t *ids, uint64_t id)
{
    return VOXEL_NAME(row_vertices_on)(c, a, b, from, to, j0, m, ids, id, 2);
}
static void VOXEL_NAME(list_vertices_x)(const ctx *c, const vertex_item *it, size_t n, int64_t m)
{
    VOXEL_NAME(list_vertices_on)(c, it, n, m, 0);
}
static void VOXEL_NAME(list_vertices_y)(const ctx *c, const vertex_item *it, size_t n, int64_t m)
{
    VOXEL_NAME(list_vertices_on)(c, it, n, m, 1);
}
static void VOXEL_NAME(list_vertices_z)(const ctx *c, const vertex_item *it, size_t n, int64_t m)
{
    VOXEL_NAME(list_vertices_on)(c, it, n, m, 2);
}
#if KERNELS_AVX2
static uint64_t VOXEL_NAME(row_vertices4_x)(const ctx *c, const uint8_t *a, const uint8_t *b,
                                            int64_t from, int64_t to, int64_t j0, int64_t m,
                                            uint32_t *ids, uint64_t id)
{
    return VOXEL_NAME(row_vertices4_on)(c, a, b, from, to, j0, m, ids, id, 0);
}
static uint64_t VOXEL_NAME(row_vertices4_y)(const ctx *c, const uint8_t *a, const uint8_t *b,
                                            int64_t from, int64_t to, int64_t j0, int64_t m,
                                            uint32_t *ids, uint64_t id)
{
    return VOXEL_NAME(row_vertices4_on)(c, a, b, from, to, j0, m, ids, id, 1);
}
static uint64_t VOXEL_NAME(row_vertices4_z)(const ctx *c, const uint8_t *a, const uint8_t *b,
                                            int64_t from, int64_t to, int64_t j0, int64_t m,
                                            uint32_t *ids, uint64_t id)
{
    return VOXEL_NAME(row_vertices4_on)(c, a, b, from, to, j0, m, ids, id, 2);
}
static void VOXEL_NAME(list_vertices4_x)(const ctx *c, const vertex_item *it, size_t n, int64_t m)
{
    VOXEL_NAME(list_vertices4_on)(c, it, n, m, 0);
}
static void VOXEL_NAME(list_vertices4_y)(const ctx *c, const vertex_item *it, size_t n, int64_t m)
{
    VOXEL_NAME(list_vertices4_on)(c, it, n, m, 1);
}
static void VOXEL_NAME(list_vertices4_z)(const ctx *c, const vertex_item *it, size_t n, int64_t m)
{
    VOXEL_NAME(list_vertices4_on)(c, it, n, m, 2);
}
#endif /* KERNELS_AVX2 */
