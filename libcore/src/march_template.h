/*
 * march_template.h - marching the cubes of a layer (private; part of
 * kernels_template.h, included once per target).
 *
 * Layer k is the cubes between sample slices k and k + 1.  A row of cubes
 * is skipped when its four sample rows are uniform and alike, and otherwise
 * marched only over the columns its row spans allow (cube_spans); the busy
 * cubes (configuration neither 0 nor 255) are found 16 columns at a time.
 *
 * Mending (thesis chapter 4.2.2).  Each face of the grid is judged once, by
 * the cube for which it is the +x, +y or +z face.  If the face is ambiguous
 * and the neighbour exists, DURST always adds a quadrilateral, DMC only when
 * exactly one of the two cubes is inverted (5+ positive corners).  The table
 * records this cube's two directed segments on the face in loop order
 * p->q, r->s; the neighbour, pairing the points the other way, supplies
 * q->r and s->p, so the hole is the loop p q r s and the quadrilateral
 * (s, r, q, p) uses each of its edges in the opposite direction.  Its
 * diagonal s-q joins points on opposite edges of the face, which no other
 * triangle can contain, so the surface stays a 2-manifold.
 */

/* Prefetches the id-map lines of the twelve cube edges at column i. */
static inline void prefetch_ids(const uint32_t *const ep[12], int64_t i)
{
    for (int e = 0; e < 12; e++)
        __builtin_prefetch(ep[e] + i);
}

/* Configurations of the cubes [from, to] of a row from its four sample rows. */
static void row_cases(const uint8_t *restrict a, const uint8_t *restrict b,
                      const uint8_t *restrict c, const uint8_t *restrict d, int64_t from,
                      int64_t to, uint8_t *restrict cases)
{
    for (int64_t i = from; i <= to; i++)
        cases[i] = (uint8_t)(a[i] | a[i + 1] << 1 | b[i] << 2 | b[i + 1] << 3 | c[i] << 4 |
                             c[i + 1] << 5 | d[i] << 6 | d[i + 1] << 7);
}

/*
 * Marches layer k (extract_kernels.march_layer).  `general` is c->general
 * and `flip` c->flip, passed so that march_layer can compile the loop with
 * them as constants.  Returns the number of triangles.
 */
static ALWAYS_INLINE uint64_t march_layer_as(worker *w, int64_t k, const pass_kind pass,
                                             const int general, const int flip, uint64_t first)
{
    ctx *c = w->c;
    const grid *g = &c->g;
    const int64_t N0 = g->N[0], N1 = g->N[1], N2 = g->N[2];
    const row_span *r0, *r1, *r2 = NULL;
    const uint8_t *S2 = k + 2 < N2 ? signs(w, k + 2, &r2) : NULL;
    const uint8_t *S1 = signs(w, k + 1, &r1);
    const uint8_t *S0 = signs(w, k, &r0);
    const int quads = c->method == ISOMEND_METHOD_DMC || c->method == ISOMEND_METHOD_DURST;
    /* Locals, not c->...: the byte stores to the origins may alias the context,
     * which would make the compiler reload these for every triangle. */
    const int durst = c->method == ISOMEND_METHOD_DURST;
    const uint8_t quad_origin = durst ? ISOMEND_ORIGIN_DURST : ISOMEND_ORIGIN_MEND;
    isomend_stats *st = &w->stats;
    const uint32_t *ids0 = NULL, *ids1 = NULL;
    const int count = pass != PASS_FILL, write = pass != PASS_COUNT;
    if (write) {
        ids0 = w->edge_ids[k % 2];
        ids1 = w->edge_ids[(k + 1) % 2];
    }
    const int64_t plane = N0 * N1;
    uint64_t ntri = 0, busy = 0;
    uint32_t *out = write ? c->tri + 3 * first : NULL;
    uint8_t *org = write && c->org ? c->org + first : NULL;
    /* The table's triangles' origins are left as they are: zero bytes (a
     * fresh reservation, or the stream's cleared staging) already say
     * ISOMEND_ORIGIN_TABLE.  The quadrilaterals' are written by index (the
     * general methods write theirs as they go). */
    _Static_assert(ISOMEND_ORIGIN_TABLE == 0, "the sweep leaves table origins as zero bytes");
    const uint32_t *const out_first = out;
    uint8_t *cases = w->cube_cases;
    uint64_t cfg_count[256]; /* counting: cubes per configuration */
    uint64_t general_tri = 0;
    if (count)
        memset(cfg_count, 0, sizeof cfg_count);
    w->private_count = 0;
    if (write && general)
        w->private_next = c->private_first;

    /* the cubes marched: all, or a box piece's (stream.c) */
    const int64_t col_lo = c->cube_lo[0], col_hi = c->cube_hi[0] - 1;
    for (int64_t j = c->cube_lo[1]; j < c->cube_hi[1]; j++) {
        const uint8_t v = r0[j].first;
        if (uniform_as(&r0[j], N0, v) && uniform_as(&r0[j + 1], N0, v) &&
            uniform_as(&r1[j], N0, v) && uniform_as(&r1[j + 1], N0, v))
            continue; /* four uniform rows of one sign (most rows, around a blob) */
        const row_span *rows[4] = {&r0[j], &r0[j + 1], &r1[j], &r1[j + 1]};
        int64_t span[4];
        const int nspans = cube_spans(rows, N0, span);
        if (!nspans)
            continue;
        const uint8_t *a = S0 + j * N0, *b = a + N0, *cc = S1 + j * N0, *d = cc + N0;
        const uint32_t *ep[12] = {NULL};
        if (write) {
            const int64_t o = j * N0;
            ep[0] = ids0 + o; /* x edges */
            ep[1] = ids0 + o + N0;
            ep[2] = ids1 + o;
            ep[3] = ids1 + o + N0;
            ep[4] = ids0 + plane + o; /* y edges */
            ep[5] = ids0 + plane + o + 1;
            ep[6] = ids1 + plane + o;
            ep[7] = ids1 + plane + o + 1;
            ep[8] = ids0 + 2 * plane + o; /* z edges */
            ep[9] = ids0 + 2 * plane + o + 1;
            ep[10] = ids0 + 2 * plane + o + N0;
            ep[11] = ids0 + 2 * plane + o + N0 + 1;
        }
        for (int sp = 0; sp < nspans; sp++) {
            const int64_t i0 = span[2 * sp] > col_lo ? span[2 * sp] : col_lo;
            const int64_t i1 = span[2 * sp + 1] < col_hi ? span[2 * sp + 1] : col_hi;
            if (i0 > i1)
                continue;
            /* A narrow span (the rim of a blob) builds its configurations 16 at a
             * time as it goes; cases[] then holds columns word..word + 15 only. */
            const int narrow = i1 - i0 < NARROW_CUBES;
            /* Writing reads the twelve edges' ids; their map lines were
             * written a slice ago and, on a large grid, the vertices computed
             * since have pushed them out of the near caches. */
            if (write)
                prefetch_ids(ep, i0);
            if (!narrow)
                row_cases(a, b, cc, d, i0, i1, cases);
            for (int64_t word = i0; word <= i1; word += 16) {
                uint32_t mixed =
                    narrow ? cases16(a + word, b + word, cc + word, d + word, cases + word)
                           : mixed16(cases + word);
                const int64_t known = narrow ? word + 15 : i1; /* cases[] holds up to here */
                if (i1 - word < 15)
                    mixed = first_bits(mixed, i1 - word + 1);
                if (write && word + 16 <= i1) /* the next 16 cubes' id lines */
                    prefetch_ids(ep, word + 16);
                while (mixed) {
                    const int64_t i = word + __builtin_ctz(mixed);
                    mixed &= mixed - 1;
                    const unsigned cfg = cases[i];
                    busy++;
                    unsigned nt;
                    if (general) {
                        nt = method_cube(w, i, j, k, cfg, pass, ep, ids0, ids1, out, org);
                        if (write) {
                            out += 3 * nt;
                            if (org)
                                org += nt;
                        }
                    } else {
                        nt = write ? mc_tri_count[cfg] : 0; /* else counted per layer */
                    }
                    if (count) {
                        cfg_count[cfg]++; /* folded into the statistics once per layer */
                        if (general)
                            general_tri += nt;
                    }
                    if (write && !general) {
                        const signed char *te = mc_tri_edges[cfg];
                        for (unsigned q = 0; q < nt; q++, te += 3) {
                            uint32_t v0 = ep[te[0]][i], v1 = ep[te[1]][i], v2 = ep[te[2]][i];
                            out[0] = v0;
                            out[1] = flip ? v2 : v1;
                            out[2] = flip ? v1 : v2;
                            out += 3;
                        }
                    }
                    ntri += nt;

                    const unsigned amb = mc_ambiguous_faces[cfg] & 0x2A; /* +x, +y, +z */
                    if (!amb)
                        continue;
                    for (int axis = 0; axis < 3; axis++) {
                        const int f = 2 * axis + 1;
                        if (!(amb & (1u << f)))
                            continue;
                        unsigned nb;
                        if (axis == 0) {
                            if (i + 2 >= N0)
                                continue;
                            nb = i + 1 <= known ? cases[i + 1] : cube_case(a, b, cc, d, i + 1);
                        } else if (axis == 1) {
                            if (j + 2 >= N1)
                                continue;
                            nb = cube_case(b, b + N0, d, d + N0, i);
                        } else {
                            if (!S2)
                                continue;
                            const uint8_t *e2 = S2 + j * N0;
                            nb = cube_case(cc, d, e2, e2 + N0, i);
                        }
                        const int inverted = mc_is_inverted(cfg) != mc_is_inverted(nb);
                        if (count) {
                            st->ambiguous_faces++;
                            st->inverted_combinations += (uint64_t)inverted;
                        }
                        if (!quads || !mc_face_mended(durst, cfg, nb))
                            continue;
                        if (count)
                            st->triangles_by_origin[quad_origin] += 2;
                        if (write) {
                            const signed char *l = mc_face_loop[cfg][f];
                            mc_quad_triangles(ep[l[0]][i], ep[l[1]][i], ep[l[2]][i], ep[l[3]][i],
                                              flip, out);
                            if (org)
                                org[(out - out_first) / 3] = org[(out - out_first) / 3 + 1] =
                                    quad_origin;
                            out += 6;
                        }
                        ntri += 2;
                    }
                }
            }
        }
    }
    if (count) {
        uint64_t table_tri = 0;
        for (int q = 1; q < 255; q++) {
            st->case_histogram[mc_case_of[q]] += cfg_count[q];
            table_tri += cfg_count[q] * mc_tri_count[q];
        }
        st->case_histogram[0] += (uint64_t)(c->cube_hi[0] - c->cube_lo[0]) *
                                     (uint64_t)(c->cube_hi[1] - c->cube_lo[1]) -
                                 busy;
        st->triangles_by_origin[ISOMEND_ORIGIN_TABLE] += general ? general_tri : table_tri;
        if (!general && !write)
            ntri += table_tri;
    }
    return ntri;
}

/* march_layer_as compiled for each pass and kind of method, and for the
 * writing passes for each winding (per-cube tests fold away).  The general
 * methods count a layer and then write it (PASS_FILL); the table methods
 * count and write at once (PASS_SWEEP), or only count. */
static uint64_t march_layer(worker *w, int64_t k, pass_kind pass, uint64_t first)
{
    const ctx *c = w->c;
    if (c->general)
        return pass != PASS_COUNT ? march_layer_as(w, k, PASS_FILL, 1, c->flip, first)
                                  : march_layer_as(w, k, PASS_COUNT, 1, 0, first);
    if (pass == PASS_COUNT)
        return march_layer_as(w, k, PASS_COUNT, 0, 0, first);
    return c->flip ? march_layer_as(w, k, PASS_SWEEP, 0, 1, first)
                   : march_layer_as(w, k, PASS_SWEEP, 0, 0, first);
}
