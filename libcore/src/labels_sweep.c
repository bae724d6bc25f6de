/*
 * labels_sweep.c - one slab of a label map swept once for every requested
 * label (isomend_labels_extract, labels.c drives the slabs).
 *
 * The surface of label L is the surface isomend_extract() gives for L's
 * indicator (1 where the sample is L, 0 elsewhere) at level 0.5 with the
 * same method and flags, byte for byte, vertex order included; this file
 * makes every label's surface in one pass over the samples:
 *
 *   - samples become codes (labels_job.h), a ring of LABEL_RING code
 *     slices: scanning slice m reads slices m - 1 .. m + 2 (the normals'
 *     central differences), marching layer k reads k .. k + 2 (the +z
 *     neighbour of DMC's mending);
 *   - a grid edge whose two codes differ is cut, at its midpoint (the
 *     indicator's t = (0.5 - f0) / (f1 - f0) is 1/2 either way), and is a
 *     vertex of the lower end's label and of the upper end's label, when
 *     requested: two ids an edge.  Both labels' vertices have the same
 *     position, so touching labels share their boundary's vertices exactly;
 *     each has its own normal, from its own indicator, by make_vertex()'s
 *     formula (vertices.c);
 *   - a cube whose eight codes are not all equal is marched once for each
 *     requested label among its corners, with that label's configuration
 *     (bit c: corner c is the label) and the MC table, then DMC's or
 *     Durst's quadrilaterals on its +x, +y, +z faces against the
 *     neighbour's configuration for the same label (march_template.h's
 *     rule and order).
 *
 * Per label the order is isomend_extract()'s: vertices by slice, row, axis
 * x/y/z, column; triangles by layer, row, column, the table's then the
 * quadrilaterals of +x, +y, +z.  A slab numbers its own slices' vertices
 * from 0 a label; its last layer's cubes refer to the next slab's first
 * slice as LABEL_FOREIGN | f, f counted in that slice's order, which is
 * where the next slab's numbering starts, so labels.c joins the parts with
 * offsets alone and the mesh does not depend on the number of slabs.
 *
 * Ambiguous faces: a face whose label corners lie on one diagonal has its
 * bilinear saddle exactly at 0.5.  The table methods do not evaluate it:
 * the MC table separates the label's corners on such a face when the cube
 * has 4 or fewer of them and joins them when it has 5 or more, and DMC adds
 * the quadrilateral where two cubes disagree (docs/labels.md: why DMC and
 * not the saddle tie rule of the face methods).
 */
#include "labels_sweep.h"
#include "labels_volume.h"

#include "tables.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ codes */

uint32_t label_code(const label_job *job, int64_t value)
{
    if (job->table)
        return job->table[value - job->table_min];
    size_t lo = 0, hi = job->count; /* the first sorted value >= value */
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (job->sorted[mid] < value)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < job->count && job->sorted[lo] == value ? job->sorted_code[lo] : job->count;
}

/* Codes of n samples from p (stride st) into dst; counts the labels'
 * samples when `voxels` is not NULL. */
static void code_row(const label_job *job, const char *p, int64_t st, int64_t n, uint32_t *dst,
                     uint64_t *voxels)
{
    const uint32_t other = job->count;
    if (job->table) {
        const uint32_t *table = job->table - job->table_min;
        switch ((int)job->type) {
        case ISOMEND_U8:
            for (int64_t i = 0; i < n; i++)
                dst[i] = table[*(const uint8_t *)(p + i * st)];
            break;
        case ISOMEND_I8:
            for (int64_t i = 0; i < n; i++)
                dst[i] = table[*(const int8_t *)(p + i * st)];
            break;
        default:
            for (int64_t i = 0; i < n; i++)
                dst[i] = table[load_label(job->type, p + i * st)];
            break;
        }
    } else {
        /* 32-bit labels: a look-up where the value changes (label maps
         * come in runs) */
        int64_t last = 0;
        uint32_t code = label_code(job, 0);
        for (int64_t i = 0; i < n; i++) {
            const int64_t v = load_label(job->type, p + i * st);
            if (v != last) {
                last = v;
                code = label_code(job, v);
            }
            dst[i] = code;
        }
    }
    if (voxels)
        for (int64_t i = 0; i < n; i++)
            if (dst[i] < other)
                voxels[dst[i]]++;
}

/* The codes of marched slice m (NULL outside the grid), converted into
 * the ring when not there yet; samples counted when m is the slab's own. */
void label_fill_codes(label_slab *s, int64_t m, const char *slice, int64_t st0, int64_t st1)
{
    const label_job *job = s->job;
    const int64_t N0 = job->N[0], N1 = job->N[1], N2 = job->N[2], pad = job->pad;
    const int slot = (int)(m & (LABEL_RING - 1));
    uint32_t *dst = s->codes[slot];
    s->held[slot] = m;
    const uint32_t PAD = job->count + 1;
    const int own = m >= s->k0 && (s->last || m < s->k1);
    if (pad && (m == 0 || m == N2 - 1)) {
        for (int64_t q = 0; q < N0 * N1; q++)
            dst[q] = PAD;
        return;
    }
    for (int64_t j = 0; j < N1; j++) {
        uint32_t *row = dst + j * N0;
        if (pad && (j == 0 || j == N1 - 1)) {
            for (int64_t i = 0; i < N0; i++)
                row[i] = PAD;
            continue;
        }
        if (pad)
            row[0] = row[N0 - 1] = PAD;
        code_row(job, slice + (j - pad) * st1, st0, job->n[0], row + pad, own ? s->voxels : NULL);
    }
}

/* The codes of marched slice m (NULL outside the grid): a volume's slice is
 * converted into the ring when not there yet; a stream's must have been
 * pushed (labels_stream.c pushes ahead of every use). */
static const uint32_t *codes_of(label_slab *s, int64_t m)
{
    const label_job *job = s->job;
    if (m < 0 || m >= job->N[2])
        return NULL;
    const int slot = (int)(m & (LABEL_RING - 1));
    if (s->held[slot] != m)
        label_fill_codes(s, m, job->data ? job->data + (m - job->pad) * job->st[2] : NULL,
                         job->st[0], job->st[1]);
    return s->codes[slot];
}

/* ------------------------------------------------------------ vertices */

/* The marched slices m - 1 .. m + 2 around a scanned slice m. */
typedef struct near_slices {
    const uint32_t *sl[4];
    int64_t m;
} near_slices;

/* Label code L's indicator at marched sample (x, y, z): 1 or 0; NaN outside
 * the grid and for padding, as fetch() (grid.h). */
static inline double indicator(const label_job *job, const near_slices *ns, int64_t x, int64_t y,
                               int64_t z, uint32_t L)
{
    if ((uint64_t)x >= (uint64_t)job->N[0] || (uint64_t)y >= (uint64_t)job->N[1])
        return NAN;
    const uint32_t *row = ns->sl[z - (ns->m - 1)];
    if (!row)
        return NAN;
    const uint32_t code = row[y * job->N[0] + x];
    if (code == job->count + 1)
        return NAN;
    return code == L ? 1.0 : 0.0;
}

/* gradient_component() (vertices.c) of the indicator. */
static inline double indicator_gradient(const label_job *job, const near_slices *ns,
                                        const int64_t p[3], int a, double f0, uint32_t L)
{
    int64_t q[3] = {p[0], p[1], p[2]}, r[3] = {p[0], p[1], p[2]};
    q[a]++;
    r[a]--;
    const double fp = indicator(job, ns, q[0], q[1], q[2], L);
    const double fm = indicator(job, ns, r[0], r[1], r[2], L);
    const int vp = !isnan(fp), vm = !isnan(fm);
    if (vp && vm)
        return (fp - fm) * job->inv2h[a];
    if (vp)
        return (fp - f0) / job->h[a];
    if (vm)
        return (f0 - fm) / job->h[a];
    return 0.0;
}

/* make_vertex()'s normal from the gradients g0, g1 at the edge's ends
 * (t = 1/2), or 0 when it is no direction (then the caller takes the edge's). */
static int indicator_normal(const label_job *job, const double g0[3], const double g1[3],
                            float *nrm)
{
    const double t = 0.5;
    double n[3];
    for (int c = 0; c < 3; c++)
        n[c] = -((1.0 - t) * g0[c] + t * g1[c]);
    const double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0.0) || !isfinite(len))
        return 0;
    const double scale = (job->flip ? -1.0 : 1.0) / len;
    for (int c = 0; c < 3; c++)
        nrm[c] = (float)(scale * n[c]);
    return 1;
}

void label_job_tables(label_job *job)
{
    for (unsigned cfg = 0; cfg < 256; cfg++) {
        unsigned cut = 0; /* bit e: the two corners of edge e differ */
        for (int e = 0; e < 12; e++)
            cut |= ((cfg >> cube_edge_corner[e][0] ^ cfg >> cube_edge_corner[e][1]) & 1u) << e;
        job->cut[cfg] = (uint16_t)cut;
    }
    for (int q = 0; q < 729; q++) {
        double g[2][3];
        int r = q;
        for (int e = 1; e >= 0; e--) /* index: d0x d0y d0z d1x d1y d1z, base 3, d0x first */
            for (int c = 2; c >= 0; c--) {
                g[e][c] = (double)(r % 3 - 1) * job->inv2h[c];
                r /= 3;
            }
        job->zero[q] = (uint8_t)!indicator_normal(job, g[0], g[1], job->normal[q]);
    }
}

/*
 * The vertex of label code L on the edge from marched sample (i, j, m)
 * along axis a: make_vertex()'s position and normal for L's indicator at
 * level 0.5 (t = 1/2 for every cut edge, padding ends included).  An edge
 * whose ends have all their neighbours in the volume takes its normal from
 * the job's table (the same numbers: the differences are -1, 0 or 1 times
 * inv2h); the others compute it as gradient_component() does.
 */
static void label_vertex(const label_job *job, const near_slices *ns, int64_t i, int64_t j,
                         int64_t m, int a, uint32_t L, float *pos, float *nrm)
{
    const int64_t p0[3] = {i, j, m};
    int64_t p1[3] = {i, j, m};
    p1[a]++;
    for (int c = 0; c < 3; c++) {
        const double x = (double)p0[c] + (c == a ? 0.5 : 0.0);
        pos[c] = (float)(job->o[c] + x * job->h[c]);
    }
    if (!nrm)
        return;
    int inner = 1;
    for (int c = 0; c < 3; c++)
        inner &= p0[c] >= job->inner_lo[c] && p1[c] <= job->inner_hi[c];
    if (inner) {
        const int64_t N0 = job->N[0];
        int q = 0;
        for (int e = 0; e < 2; e++) {
            const int64_t *p = e ? p1 : p0;
            const uint32_t *mid = ns->sl[p[2] - (ns->m - 1)] + p[1] * N0 + p[0];
            const uint32_t *below = ns->sl[p[2] - ns->m] + p[1] * N0 + p[0];
            const uint32_t *above = ns->sl[p[2] - ns->m + 2] + p[1] * N0 + p[0];
            q = q * 3 + (int)(mid[1] == L) - (int)(mid[-1] == L) + 1;
            q = q * 3 + (int)(mid[N0] == L) - (int)(mid[-N0] == L) + 1;
            q = q * 3 + (int)(*above == L) - (int)(*below == L) + 1;
        }
        if (!job->zero[q]) {
            memcpy(nrm, job->normal[q], sizeof(float) * 3);
            return;
        }
    } else {
        const double f0 = indicator(job, ns, p0[0], p0[1], p0[2], L);
        const double f1 = indicator(job, ns, p1[0], p1[1], p1[2], L);
        if (!isnan(f0) && !isnan(f1)) {
            double g0[3], g1[3];
            for (int c = 0; c < 3; c++) {
                g0[c] = indicator_gradient(job, ns, p0, c, f0, L);
                g1[c] = indicator_gradient(job, ns, p1, c, f1, L);
            }
            if (indicator_normal(job, g0, g1, nrm))
                return;
        }
    }
    /* no direction: the edge's, from the inside end towards the outside */
    const double f0 = indicator(job, ns, p0[0], p0[1], p0[2], L);
    double n[3] = {0.0, 0.0, 0.0};
    n[a] = f0 >= 0.5 ? 1.0 : -1.0; /* NaN: outside */
    const double scale = job->flip ? -1.0 : 1.0;
    for (int c = 0; c < 3; c++)
        nrm[c] = (float)(scale * n[c]);
}

/* Room for one more vertex of a part; 0 without memory. */
static int grow_vertices(label_part *p, int normals)
{
    if (p->nv < p->cap_v)
        return 1;
    const size_t cap = p->cap_v ? 2 * p->cap_v : 256;
    float *pos = realloc(p->pos, sizeof(float) * 3 * cap);
    if (!pos)
        return 0;
    p->pos = pos;
    if (normals) {
        float *nrm = realloc(p->nrm, sizeof(float) * 3 * cap);
        if (!nrm)
            return 0;
        p->nrm = nrm;
    }
    p->cap_v = cap;
    return 1;
}

/* Room for `more` triangles; 0 without memory. */
static int grow_triangles(label_part *p, size_t more, int origins)
{
    if (p->nt + more <= p->cap_t)
        return 1;
    size_t cap = p->cap_t ? 2 * p->cap_t : 512;
    while (cap < p->nt + more)
        cap *= 2;
    uint32_t *tri = realloc(p->tri, sizeof(uint32_t) * 3 * cap);
    if (!tri)
        return 0;
    p->tri = tri;
    if (origins) {
        uint8_t *org = realloc(p->org, cap);
        if (!org)
            return 0;
        p->org = org;
    }
    p->cap_t = cap;
    return 1;
}

/* The id of label code L's vertex on an edge of slice m (from (i, j) along
 * a): a new vertex of the slab, or of the next slab when m is its first
 * slice (`foreign`).  UINT32_MAX: no memory or too many vertices. */
static uint32_t new_vertex(label_slab *s, const near_slices *ns, int64_t i, int64_t j, int64_t m,
                           int a, uint32_t L, int foreign)
{
    label_part *p = &s->part[L];
    if (foreign) {
        if (p->foreign >= LABEL_FOREIGN - 1)
            return UINT32_MAX;
        return LABEL_FOREIGN | p->foreign++;
    }
    if (p->nv >= LABEL_FOREIGN - 1 || !grow_vertices(p, s->job->normals))
        return UINT32_MAX;
    label_vertex(s->job, ns, i, j, m, a, L, p->pos + 3 * p->nv,
                 s->job->normals ? p->nrm + 3 * p->nv : NULL);
    return (uint32_t)p->nv++;
}

/* The cut edges between rows x and y ([0, n)): their columns into cols;
 * returns their number.  Sixteen columns are compared at once (the
 * compiler vectorises it) and looked at one by one only when one differs. */
static int64_t cut_columns(const uint32_t *x, const uint32_t *y, int64_t n, int64_t *cols)
{
    int64_t k = 0, i = 0;
    for (; i + 16 <= n; i += 16) {
        uint32_t any = 0;
        for (int q = 0; q < 16; q++)
            any |= x[i + q] ^ y[i + q];
        if (!any)
            continue;
        for (int q = 0; q < 16; q++)
            if (x[i + q] != y[i + q])
                cols[k++] = i + q;
    }
    for (; i < n; i++)
        if (x[i] != y[i])
            cols[k++] = i;
    return k;
}

/*
 * Scans marched slice m: every cut edge whose lower end is in it gets the
 * ids of its two labels' vertices (slot 0: the lower end's label, 1: the
 * upper end's; UINT32_MAX for a label not requested).  `foreign`: the next
 * slab's first slice, numbered only.
 */
int label_scan_slice(label_slab *s, int64_t m, int foreign)
{
    int64_t *cols = s->cols;
    const label_job *job = s->job;
    const int64_t N0 = job->N[0], N1 = job->N[1], N2 = job->N[2], plane = N0 * N1;
    near_slices ns;
    ns.m = m;
    for (int q = 0; q < 4; q++)
        ns.sl[q] = codes_of(s, m - 1 + q);
    const uint32_t *S = ns.sl[1], *T = m + 1 < N2 ? ns.sl[2] : NULL;
    uint32_t *ids = s->ids[m & 1];
    for (int64_t j = 0; j < N1; j++) {
        const uint32_t *a = S + j * N0;
        const uint32_t *other[3] = {a + 1, j + 1 < N1 ? a + N0 : NULL, T ? T + j * N0 : NULL};
        const int64_t len[3] = {N0 - 1, N0, N0};
        for (int axis = 0; axis < 3; axis++) { /* x, y, z edges: isomend_extract's order */
            if (!other[axis])
                continue;
            const int64_t n = cut_columns(a, other[axis], len[axis], cols);
            uint32_t *row_ids = ids + 2 * (axis * plane + j * N0);
            for (int64_t q = 0; q < n; q++) {
                const int64_t i = cols[q];
                const uint32_t ends[2] = {a[i], other[axis][i]};
                for (int e = 0; e < 2; e++) {
                    uint32_t id = UINT32_MAX;
                    if (ends[e] < job->count) {
                        id = new_vertex(s, &ns, i, j, m, axis, ends[e], foreign);
                        if (id == UINT32_MAX)
                            return 0;
                    }
                    row_ids[2 * i + e] = id;
                }
            }
        }
    }
    return 1;
}

/* ------------------------------------------------------------ cubes */

/* Label code L's configuration of the cube at column i of rows p, q (lower
 * slice) and r, t (upper slice). */
static inline unsigned config_of(const uint32_t *p, const uint32_t *q, const uint32_t *r,
                                 const uint32_t *t, int64_t i, uint32_t L)
{
    return (unsigned)(p[i] == L) | (unsigned)(p[i + 1] == L) << 1 | (unsigned)(q[i] == L) << 2 |
           (unsigned)(q[i + 1] == L) << 3 | (unsigned)(r[i] == L) << 4 |
           (unsigned)(r[i + 1] == L) << 5 | (unsigned)(t[i] == L) << 6 |
           (unsigned)(t[i + 1] == L) << 7;
}

/* What the cubes of a row share: its rows of codes and its edges' ids. */
typedef struct cube_row {
    const uint32_t *a, *b, *c, *d; /* rows j, j + 1 of slice k; of slice k + 1 */
    const uint32_t *e;             /* row j of slice k + 2 (NULL: none)        */
    int64_t j, k;
    const uint32_t *edge[12]; /* per cube edge: its id pair at column 0   */
} cube_row;

/* Marches label code L in the cube at column i (configuration cfg). */
static int march_label(label_slab *s, const cube_row *cr, int64_t i, const uint32_t v[8],
                       uint32_t L, unsigned cfg)
{
    const label_job *job = s->job;
    label_part *p = &s->part[L];
    const int quads = job->method != ISOMEND_METHOD_MC;
    const int durst = job->method == ISOMEND_METHOD_DURST;
    const unsigned nt = mc_tri_count[cfg];
    if (!grow_triangles(p, nt + 6, job->origins))
        return 0;
        /* the ids of the cut edges only (a few of the twelve): the id maps are
     * large, and each look-up may miss the cache */
#define EDGE_ID(e) cr->edge[e][2 * i + (v[cube_edge_corner[e][0]] == L ? 0 : 1)]
    uint32_t id[12];
    for (unsigned cut = job->cut[cfg]; cut; cut &= cut - 1) {
        const int e = __builtin_ctz(cut);
        id[e] = EDGE_ID(e);
    }
#undef EDGE_ID
    uint32_t *out = p->tri + 3 * p->nt;
    const signed char *te = mc_tri_edges[cfg];
    for (unsigned q = 0; q < nt; q++, te += 3) {
        out[0] = id[te[0]];
        out[1] = job->flip ? id[te[2]] : id[te[1]];
        out[2] = job->flip ? id[te[1]] : id[te[2]];
        out += 3;
    }
    if (job->origins)
        memset(p->org + p->nt, ISOMEND_ORIGIN_TABLE, nt);
    p->nt += nt;
    const unsigned amb = mc_ambiguous_faces[cfg] & 0x2A; /* +x, +y, +z */
    if (!quads || !amb)
        return 1;
    const int64_t N0 = job->N[0], N1 = job->N[1];
    for (int axis = 0; axis < 3; axis++) {
        const int f = 2 * axis + 1;
        if (!(amb & (1u << f)))
            continue;
        unsigned nb;
        if (axis == 0) {
            if (i + 2 >= N0)
                continue;
            nb = config_of(cr->a, cr->b, cr->c, cr->d, i + 1, L);
        } else if (axis == 1) {
            if (cr->j + 2 >= N1)
                continue;
            nb = config_of(cr->b, cr->b + N0, cr->d, cr->d + N0, i, L);
        } else {
            if (!cr->e)
                continue;
            nb = config_of(cr->c, cr->d, cr->e, cr->e + N0, i, L);
        }
        if (!mc_face_mended(durst, cfg, nb))
            continue;
        const signed char *l = mc_face_loop[cfg][f];
        mc_quad_triangles(id[l[0]], id[l[1]], id[l[2]], id[l[3]], job->flip, p->tri + 3 * p->nt);
        if (job->origins)
            memset(p->org + p->nt, durst ? ISOMEND_ORIGIN_DURST : ISOMEND_ORIGIN_MEND, 2);
        p->nt += 2;
    }
    return 1;
}

/* Marches the cube at column i for every requested label among its corners. */
static int march_cube(label_slab *s, const cube_row *cr, int64_t i)
{
    const uint32_t v[8] = {cr->a[i], cr->a[i + 1], cr->b[i], cr->b[i + 1],
                           cr->c[i], cr->c[i + 1], cr->d[i], cr->d[i + 1]};
    unsigned seen = 0;
    for (int c = 0; c < 8; c++) {
        if (seen & (1u << c))
            continue;
        const uint32_t L = v[c];
        unsigned cfg = 0;
        for (int q = c; q < 8; q++)
            cfg |= (unsigned)(v[q] == L) << q;
        seen |= cfg;
        if (cfg == 255)
            return 1; /* one code: no surface */
        if (L < s->job->count && !march_label(s, cr, i, v, L, cfg))
            return 0;
    }
    return 1;
}

/* Marches layer k (the cubes between marched slices k and k + 1). */
int label_march_layer(label_slab *s, int64_t k)
{
    const label_job *job = s->job;
    const int64_t N0 = job->N[0], N1 = job->N[1], N2 = job->N[2], plane = N0 * N1;
    const uint32_t *S0 = codes_of(s, k), *S1 = codes_of(s, k + 1);
    const uint32_t *S2 = k + 2 < N2 ? codes_of(s, k + 2) : NULL;
    const uint32_t *ids0 = s->ids[k & 1], *ids1 = s->ids[(k + 1) & 1];
    cube_row cr;
    cr.k = k;
    for (int64_t j = 0; j + 1 < N1; j++) {
        cr.j = j;
        cr.a = S0 + j * N0;
        cr.b = cr.a + N0;
        cr.c = S1 + j * N0;
        cr.d = cr.c + N0;
        cr.e = S2 ? S2 + j * N0 : NULL;
        for (int e = 0; e < 12; e++) {
            const int corner = cube_edge_corner[e][0], axis = e / 4;
            const uint32_t *base = CUBE_CORNER_Z(corner) ? ids1 : ids0;
            cr.edge[e] = base + 2 * (axis * plane + (j + CUBE_CORNER_Y(corner)) * N0 +
                                     CUBE_CORNER_X(corner));
        }
        const uint32_t *a = cr.a, *b = cr.b, *c = cr.c, *d = cr.d;
        const int64_t cubes = N0 - 1;
        for (int64_t i0 = 0; i0 < cubes; i0 += 16) {
            const int64_t i1 = i0 + 16 < cubes ? i0 + 16 : cubes;
            uint32_t any = 0;
            for (int64_t i = i0; i < i1; i++) {
                const uint32_t x = a[i];
                any |= (a[i + 1] ^ x) | (b[i] ^ x) | (b[i + 1] ^ x) | (c[i] ^ x) | (c[i + 1] ^ x) |
                       (d[i] ^ x) | (d[i + 1] ^ x);
            }
            if (!any)
                continue;
            for (int64_t i = i0; i < i1; i++)
                if (!march_cube(s, &cr, i))
                    return 0;
        }
    }
    return 1;
}

/* ------------------------------------------------------------ the slab */

isomend_status label_slab_run(label_slab *s)
{
    label_job *job = s->job;
    for (int r = 0; r < LABEL_RING; r++)
        s->held[r] = -1;
    s->status = ISOMEND_OK;
    if (!label_scan_slice(s, s->k0, 0))
        s->status = ISOMEND_ERR_OUT_OF_MEMORY;
    for (int64_t k = s->k0; k < s->k1 && s->status == ISOMEND_OK; k++) {
        if (atomic_load_explicit(&job->cancel, memory_order_relaxed)) {
            s->status = ISOMEND_ERR_CANCELLED;
            break;
        }
        /* slice k + 1 is the next slab's first slice at the end of a slab */
        if (!label_scan_slice(s, k + 1, k + 1 == s->k1 && !s->last) || !label_march_layer(s, k)) {
            s->status = ISOMEND_ERR_OUT_OF_MEMORY;
            break;
        }
        if (s->reports && job->progress && ((k - s->k0) & 15) == 15 &&
            job->progress(job->progress_user, (double)(k - s->k0 + 1) / (double)(s->k1 - s->k0)))
            s->status = ISOMEND_ERR_CANCELLED;
    }
    if (s->status != ISOMEND_OK)
        atomic_store(&job->cancel, 1);
    return s->status;
}
