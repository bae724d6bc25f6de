/*
 * scan_template.h - numbering the intersected edges of a slice and
 * computing their vertices (private; part of kernels_template.h, included
 * once per target).
 *
 * Slice m owns the edges whose lower end is in it: x and y edges in the
 * slice, z edges to slice m + 1.  Ids follow a fixed order, slice, row, axis
 * x/y/z, column, so the mesh does not depend on who numbers the slice or
 * when its vertices are computed.
 */

/* The vertex loops of this extraction's type: four at a time with normals
 * on AVX2. */
static inline const list_vertices_fn *list_loops(const ctx *c)
{
#if KERNELS_AVX2
    if (c->want_normals)
        return list_vertices4[c->g.type];
#endif
    return list_vertices[c->g.type];
}

static inline const row_vertices_fn *row_loops(const ctx *c)
{
#if KERNELS_AVX2
    if (c->want_normals)
        return row_vertices4[c->g.type];
#endif
    return row_vertices[c->g.type];
}

/* Computes and empties the worker's vertex lists of slice m. */
static void flush_vertices(worker *w, int64_t m)
{
    for (int a = 0; a < 3; a++) {
        if (w->pending_count[a])
            list_loops(w->c)[a](w->c, w->pending[a], w->pending_count[a], m);
        w->pending_count[a] = 0;
    }
}

/*
 * Numbers the vertices on the edges along `axis` from row a (row j of slice
 * m) towards row b: one per column i in [from, to] where a[i] != b[i].  With
 * a list, also appends them to it for flush_vertices.  Returns the next id.
 */
static uint64_t number_crossings(const uint8_t *a, const uint8_t *b, int64_t from, int64_t to,
                                 int64_t j, uint32_t *ids, uint64_t id, vertex_item *list,
                                 size_t *count)
{
    size_t n = list ? *count : 0;
    for (int64_t i = from; i <= to; i += 16) {
        uint32_t diff = diff16(a + i, b + i);
        if (to - i < 15)
            diff = first_bits(diff, to - i + 1);
        while (diff) {
            const int64_t x = i + __builtin_ctz(diff);
            diff &= diff - 1;
            ids[x] = (uint32_t)id;
            if (list) {
                list[n].id = (uint32_t)id;
                list[n].x = (int32_t)x;
                list[n].j = (int32_t)j;
                n++;
            }
            id++;
        }
    }
    if (list)
        *count = n;
    return id;
}

/*
 * Numbers (and, if `write`, computes) the crossings of a span: a narrow span
 * (the rim of a blob: a few crossings per row) goes to the lists, to be
 * computed with prefetching; a wide one is computed at once, in row order,
 * which the hardware prefetcher follows.
 */
static inline uint64_t crossings(worker *w, const uint8_t *a, const uint8_t *b, int64_t from,
                                 int64_t to, int64_t j, int64_t m, int axis, uint32_t *ids,
                                 uint64_t id, int write)
{
    if (!write)
        return number_crossings(a, b, from, to, j, ids, id, NULL, NULL);
    if (to - from < LIST_SPAN)
        return number_crossings(a, b, from, to, j, ids, id, w->pending[axis],
                                &w->pending_count[axis]);
    return row_loops(w->c)[axis](w->c, a, b, from, to, j, m, ids, id);
}

/* Number of i in [from, to] with a[i] != b[i]; vectorises.  Out of line:
 * inlined, its vectorised loop costs the counting scan more than the call. */
static __attribute__((noinline)) uint64_t
count_differences(const uint8_t *restrict a, const uint8_t *restrict b, int64_t from, int64_t to)
{
    uint32_t n = 0;
    for (int64_t i = from; i <= to; i++)
        n += (uint32_t)(a[i] != b[i]);
    return n;
}

/*
 * The crossings between rows a and b in the n spans span[0..2n).  Exact spans
 * (between one-run rows: row_spans, pair_spans) are crossings in every column,
 * so they are counted, not scanned.
 */
static uint64_t count_spans(const uint8_t *a, const uint8_t *b, const int64_t *span, int n,
                            int exact)
{
    uint64_t count = 0;
    for (int q = 0; q < n; q++)
        count += exact ? (uint64_t)(span[2 * q + 1] - span[2 * q] + 1)
                       : count_differences(a, b, span[2 * q], span[2 * q + 1]);
    return count;
}

/*
 * The intersected edges whose lower end is in slice m: counted, or, if
 * `number`, numbered from `first` into the worker's id map of slice m and,
 * if `write`, computed.  Returns their number.
 */
static ALWAYS_INLINE uint64_t scan_slice_as(worker *w, int64_t m, const int number, uint64_t first,
                                            int write)
{
    const ctx *c = w->c;
    const grid *g = &c->g;
    const int64_t N0 = g->N[0], N1 = g->N[1], N2 = g->N[2];
    const row_span *ra, *rn = NULL;
    const uint8_t *t = m + 1 < N2 ? signs(w, m + 1, &rn) : NULL;
    const uint8_t *s = signs(w, m, &ra); /* slots m and m + 1 differ */
    uint32_t *mx = NULL, *my = NULL, *mz = NULL;
    if (number) {
        mx = w->edge_ids[m % 2];
        my = mx + N0 * N1;
        mz = mx + 2 * N0 * N1;
    }
    uint64_t id = first, count = 0;
    /* the corners of the cubes marched: all, or a box piece's (stream.c) */
    const int64_t col_lo = c->cube_lo[0], col_hi = c->cube_hi[0];
    const int clip = col_lo > 0 || col_hi < N0 - 1;
    for (int64_t j = c->cube_lo[1]; j <= c->cube_hi[1]; j++) {
        if (c->tetra) { /* rare method: full rows, before the skip below */
            if (number)
                id = scan_diagonals(c, s, t, j, m, mx, id, write);
            else
                count = scan_diagonals(c, s, t, j, m, NULL, count, 0);
        }
        const uint8_t v = ra[j].first;
        if (uniform_as(&ra[j], N0, v) && (j + 1 >= N1 || uniform_as(&ra[j + 1], N0, v)) &&
            (!t || uniform_as(&rn[j], N0, v)))
            continue; /* uniform, like the rows it pairs with: no crossing */
        const uint8_t *a = s + j * N0;
        int64_t xs[4], ys[4], zs[4];
        int nx = row_spans(&ra[j], N0, xs);
        int ny = j + 1 < N1 ? pair_spans(&ra[j], &ra[j + 1], N0, ys) : 0;
        int nz = t ? pair_spans(&ra[j], &rn[j], N0, zs) : 0;
        if (clip) {
            nx = clip_spans(xs, nx, col_lo, col_hi);
            ny = clip_spans(ys, ny, col_lo, col_hi);
            nz = clip_spans(zs, nz, col_lo, col_hi);
        }
        if (!nx && !ny && !nz)
            continue;
        const uint8_t *b = a + N0; /* row j + 1, read only when ny */
        const uint8_t *d = nz ? t + j * N0 : NULL;
        if (!number) {
            count += count_spans(a, a + 1, xs, nx, ra[j].simple);
            count += count_spans(a, b, ys, ny, ny && simple_pair(&ra[j], &ra[j + 1]));
            count += count_spans(a, d, zs, nz, nz && simple_pair(&ra[j], &rn[j]));
            continue;
        }
        /* Vertex order within a row: x edges, then y edges, then z edges. */
        const int64_t at = j * N0;
        if (write && w->pending_count[0] + w->pending_count[1] + w->pending_count[2] > VERTEX_LIST)
            flush_vertices(w, m); /* a row adds at most N0 a list */
        for (int q = 0; q < nx; q++)
            id = crossings(w, a, a + 1, xs[2 * q], xs[2 * q + 1], j, m, 0, mx + at, id, write);
        for (int q = 0; q < ny; q++)
            id = crossings(w, a, b, ys[2 * q], ys[2 * q + 1], j, m, 1, my + at, id, write);
        for (int q = 0; q < nz; q++)
            id = crossings(w, a, d, zs[2 * q], zs[2 * q + 1], j, m, 2, mz + at, id, write);
    }
    if (write)
        flush_vertices(w, m);
    return number ? id - first : count;
}

/* scan_slice_as compiled for counting and for numbering (extract_kernels). */
static uint64_t scan_slice(worker *w, int64_t m, pass_kind pass, uint64_t first, int write)
{
    if (pass == PASS_COUNT)
        return scan_slice_as(w, m, 0, 0, 0);
    return scan_slice_as(w, m, 1, first, write);
}
