/*
 * methods.c - the disambiguation methods beyond the MC table: face
 * decisions by the facial average, the centre-pointing gradient and the
 * asymptotic decider; Marching Cubes 33; the five-tetrahedron decomposition.
 *
 * One table for the face methods and MC33.  libcore/gen/genmethods.c traces,
 * for every configuration and every decision on its ambiguous faces, the
 * face segments into closed polygons, fills each with a disk and lists the
 * tubes (annuli) that may replace two disks; methods_tables.inc holds the
 * result.  A method only has to decide the faces (and, for MC33, whether a
 * tube is present); the triangles always come from the generated table.
 *
 *   facial      joins the positive corners of an ambiguous face when the
 *               average of its four samples is >= iso (Wyvill, McPheeters &
 *               Wyvill 1986).
 *   gradient    estimates the face centre from each corner by a first-order
 *               step along the in-face gradient (central differences in the
 *               face's plane, one-sided at the volume's border) and joins
 *               when the mean of the four estimates is >= iso; the
 *               centre-pointing gradient of Wilhelms & Van Gelder (1990).
 *   asymptotic  joins when the bilinear interpolant's saddle value on the
 *               face is >= iso (Nielson & Hamann 1991): with a, c the
 *               positive diagonal and b, d the negative one (values minus
 *               iso), when a c - b d >= 0; the denominator a + c - b - d is
 *               positive on an ambiguous face.
 *   mc33        the asymptotic decider on faces, and inside the cube the
 *               exact connectivity of the trilinear interpolant (below):
 *               when two regions of one sign on the cube's surface are
 *               connected through the interior, the tube of the table
 *               replaces their two disks (Chernyaev 1995).  The classical
 *               interior test evaluates the interpolant at a few points
 *               derived from the case, which Custodio et al. (2013) and
 *               Vega et al. (2019) showed to be wrong in some subcases
 *               (the plane of the test must contain the body saddle, and
 *               case 13.5 needs the full order of the saddle values); the
 *               sweep below decides the connectivity directly, so it has no
 *               case-specific test to get wrong.
 *   tetra       five tetrahedra per cube, the central one on the corners of
 *               even grid parity, so neighbours agree on the face diagonals
 *               (Payne & Toga 1990); marching tetrahedra in each.  Hole-free
 *               and 2-manifold, not the trilinear topology.
 *
 * Ties, one rule everywhere: a sample equal to iso is positive, and a face or
 * slice saddle whose value equals iso connects the positive corners.  Both
 * are what the interpolant does at the level iso - e for an infinitely small
 * e > 0, so the surface is that of a generic level, and both cubes of a face
 * apply the rule to the same numbers in the same order.  NaN samples (and
 * padding) are outside and infinitely low: a face with a NaN corner never
 * joins its positive corners, and a cube with a NaN or infinite corner gets
 * no tube.  Infinite samples and overflowing products give the same numbers
 * in both cubes of a face, so even they cannot open a hole.
 *
 * The interior sweep.  Cut the cube by planes z = s.  Each slice is a
 * bilinear function on the unit square whose corners move linearly with s;
 * its set {f >= iso} has one component per run of positive corners, or, on
 * an alternating slice, one or two according to the sign of the slice's
 * decider D(s) = f00 f11 - f10 f01 (values minus iso), a quadratic in s.
 * That structure only changes at the roots of the four vertical edges and of
 * D in (0, 1).  Between two such heights the components slide without
 * changing, so the set {f >= iso} inside the cube is the union of the
 * critical slices and of the slabs between them, each slab component joined
 * to the components of its two bounding slices that contain the same
 * corners.  Union-find over those pieces gives the components exactly, up
 * to the rounding of the roots.
 */
#include "methods.h"

#include "cube.h"

#include <math.h>
#include <string.h>

#include "methods_tables.inc"

_Static_assert(METHODS_ENTRY_MAX_TRI <= METHODS_MAX_TRI, "METHODS_MAX_TRI too small");
_Static_assert(METHODS_TETRA_MAX_TRI <= METHODS_MAX_TRI, "METHODS_MAX_TRI too small");

int methods_handles(isomend_method method)
{
    return method == ISOMEND_METHOD_FACIAL || method == ISOMEND_METHOD_GRADIENT ||
           method == ISOMEND_METHOD_ASYMPTOTIC || method == ISOMEND_METHOD_TETRA ||
           method == ISOMEND_METHOD_MC33;
}

int methods_needs_ring(isomend_method method)
{
    return method == ISOMEND_METHOD_GRADIENT;
}

/* ------------------------------------------------------------ the table */

static int entry_index(unsigned config, unsigned join)
{
    unsigned amb = methods_ambiguous[config & 255];
    if (join & ~amb)
        return -1;
    unsigned k = 0;
    int bit = 0;
    for (int f = 0; f < 6; f++)
        if (amb & (1u << f))
            k |= ((join >> f) & 1u) << bit++;
    return methods_entry_base[config] + (int)k;
}

int methods_tube_count(unsigned config, unsigned join)
{
    if (config > 255)
        return -1;
    int e = entry_index(config, join);
    return e < 0 ? -1 : methods_entries[e].tube_count;
}

static int copy_tris(const unsigned char (*tri)[3], int n, unsigned char *out)
{
    memcpy(out, tri, (size_t)n * 3);
    return n;
}

int methods_table_triangles(unsigned config, unsigned join, int tube, unsigned char *slots)
{
    if (config > 255)
        return -1;
    int ei = entry_index(config, join);
    if (ei < 0)
        return -1;
    const methods_entry *en = &methods_entries[ei];
    if (tube < -1 || tube >= (int)en->tube_count)
        return -1;
    const methods_tube *tb = tube >= 0 ? &methods_tubes[en->tube_first + tube] : NULL;
    int n = 0;
    for (int p = 0; p < en->poly_count; p++) {
        if (tb && (p == tb->poly_a || p == tb->poly_b))
            continue;
        const methods_poly *po = &methods_polys[en->poly_first + p];
        n += copy_tris(methods_tri_pool + po->tri_first, po->tri_count, slots + 3 * n);
    }
    if (tb)
        n += copy_tris(methods_tri_pool + tb->tri_first, tb->tri_count, slots + 3 * n);
    return n;
}

/* ------------------------------------------------------- face decisions */

static int facial_join(const double *q, double iso)
{
    double avg = ((q[0] + q[1]) + (q[2] + q[3])) * 0.25;
    return avg >= iso; /* false for NaN */
}

/* Sign of the saddle value minus iso: joined when a c - b d >= 0. */
static int asymptotic_join(const double *q, double iso)
{
    double w[4];
    for (int i = 0; i < 4; i++) {
        if (isnan(q[i]))
            return 0;
        w[i] = q[i] - iso;
    }
    double num = w[0] >= 0 ? w[0] * w[2] - w[1] * w[3] : w[1] * w[3] - w[0] * w[2];
    return num >= 0;
}

/* Ring sample at cube-relative coordinates (x, y, z) in -1..2. */
static double ring_at(const double *ring, const int p[3])
{
    return ring[(p[0] + 1) + 4 * (p[1] + 1) + 16 * (p[2] + 1)];
}

static int gradient_join(const double *ring, int f, double iso)
{
    const int a = f / 2, u = a == 0 ? 1 : 0, v = a == 2 ? 1 : 2;
    double est = 0;
    for (int i = 0; i < 4; i++) {
        const int c = cube_face_corner[f][i];
        int p[3] = {CUBE_CORNER_X(c), CUBE_CORNER_Y(c), CUBE_CORNER_Z(c)};
        double val = ring_at(ring, p);
        if (isnan(val))
            return 0;
        double d[2];
        const int axes[2] = {u, v};
        for (int k = 0; k < 2; k++) {
            const int ax = axes[k], inward = p[ax] == 0 ? 1 : -1;
            int pin[3] = {p[0], p[1], p[2]}, pout[3] = {p[0], p[1], p[2]};
            pin[ax] += inward;  /* the other corner of the face: always a sample */
            pout[ax] -= inward; /* outside the cube, in the face's plane */
            double vin = ring_at(ring, pin), vout = ring_at(ring, pout);
            /* derivative towards the face centre */
            d[k] = isnan(vout) ? vin - val : 0.5 * (vin - vout);
        }
        est += val + 0.5 * (d[0] + d[1]);
    }
    est *= 0.25;
    return est >= iso; /* false for NaN */
}

unsigned methods_face_join(isomend_method method, const methods_cube *cube)
{
    unsigned amb = methods_ambiguous[cube->config & 255], join = 0;
    for (int f = 0; f < 6; f++) {
        if (!(amb & (1u << f)))
            continue;
        double q[4];
        for (int i = 0; i < 4; i++)
            q[i] = cube->v[cube_face_corner[f][i]];
        int j = 0;
        switch (method) {
        case ISOMEND_METHOD_FACIAL:
            j = facial_join(q, cube->iso);
            break;
        case ISOMEND_METHOD_GRADIENT:
            j = cube->ring ? gradient_join(cube->ring, f, cube->iso) : facial_join(q, cube->iso);
            break;
        case ISOMEND_METHOD_ASYMPTOTIC:
        case ISOMEND_METHOD_MC33:
            j = asymptotic_join(q, cube->iso);
            break;
        default:
            /* MC's own choice: separate the positives below 5 corners. */
            j = __builtin_popcount(cube->config & 255) >= 5;
            break;
        }
        join |= (unsigned)j << f;
    }
    return join;
}

/* ------------------------------------------------------ interior sweep */

typedef struct dsu {
    int parent[64];
} dsu;

static int dsu_find(dsu *d, int x)
{
    while (d->parent[x] != x)
        x = d->parent[x] = d->parent[d->parent[x]];
    return x;
}

static void dsu_union(dsu *d, int a, int b)
{
    a = dsu_find(d, a);
    b = dsu_find(d, b);
    if (a != b)
        d->parent[a] = b;
}

/* Slice corners in cyclic order (x, y) = 00, 10, 11, 01 as cube corners of
 * the bottom face; the top corner is +4. */
static const int slice_corner[4] = {0, 1, 3, 2};

static int inside(double x, int strict)
{
    return strict ? x > 0 : x >= 0;
}

/* Components of one slice with (signed) corner values x[4]; `dzero` forces
 * the decider to 0.  comp[k] = local component 0/1 or -1; returns count. */
static int slice_components(const double x[4], int dzero, int strict, int comp[4])
{
    int in[4], n = 0;
    for (int k = 0; k < 4; k++) {
        in[k] = inside(x[k], strict);
        comp[k] = -1;
    }
    if (in[0] == in[2] && in[1] == in[3] && in[0] != in[1]) {
        int d0 = in[0] ? 0 : 1; /* the inside diagonal */
        double num = dzero ? 0.0 : x[d0] * x[d0 + 2] - x[d0 + 1] * x[(d0 + 3) % 4];
        if (inside(num, strict)) {
            comp[d0] = comp[d0 + 2] = 0;
            return 1;
        }
        comp[d0] = 0;
        comp[d0 + 2] = 1;
        return 2;
    }
    /* Runs of inside corners around the cycle. */
    int start = -1;
    for (int k = 0; k < 4; k++)
        if (!in[k]) {
            start = k;
            break;
        }
    if (start < 0) {
        for (int k = 0; k < 4; k++)
            comp[k] = 0;
        return 1;
    }
    for (int i = 1; i <= 4; i++) {
        int k = (start + i) % 4;
        if (!in[k])
            continue;
        int prev = (k + 3) % 4;
        comp[k] = in[prev] && comp[prev] >= 0 ? comp[prev] : n++;
    }
    return n;
}

static void add_root(double *z, int *nz, double r)
{
    if (r > 0 && r < 1)
        z[(*nz)++] = r;
}

int methods_cube_components(const double v[8], double iso, int sign, int label[8])
{
    const int strict = !sign;
    const double s = sign ? 1.0 : -1.0;
    double b[4], d[4];
    for (int k = 0; k < 4; k++) {
        b[k] = s * (v[slice_corner[k]] - iso);
        d[k] = s * (v[slice_corner[k] + 4] - iso) - b[k];
    }
    /* Critical heights: 0, 1, edge roots, decider roots. */
    double z[8];
    int kind[8]; /* bit k: edge k crosses here; bit 4: decider root */
    int nz = 0;
    double zr[8];
    int nr;
    z[nz] = 0;
    kind[nz++] = 0;
    for (int k = 0; k < 4; k++) {
        nr = 0;
        if (d[k] != 0)
            add_root(zr, &nr, -b[k] / d[k]);
        if (nr) {
            z[nz] = zr[0];
            kind[nz++] = 1 << k;
        }
    }
    {
        const double A = d[0] * d[2] - d[1] * d[3];
        const double B = b[0] * d[2] + d[0] * b[2] - b[1] * d[3] - d[1] * b[3];
        const double C = b[0] * b[2] - b[1] * b[3];
        nr = 0;
        if (A == 0) {
            if (B != 0)
                add_root(zr, &nr, -C / B);
        } else {
            double disc = B * B - 4 * A * C;
            if (disc >= 0) {
                double sq = sqrt(disc);
                double q = -0.5 * (B + (B >= 0 ? sq : -sq));
                if (q != 0) {
                    add_root(zr, &nr, q / A);
                    add_root(zr, &nr, C / q);
                } else {
                    add_root(zr, &nr, 0.0);
                }
            }
        }
        for (int i = 0; i < nr; i++) {
            z[nz] = zr[i];
            kind[nz++] = 16;
        }
    }
    z[nz] = 1;
    kind[nz++] = 0;
    /* Sort by height, merging equal heights. */
    for (int i = 1; i < nz; i++)
        for (int j = i; j > 0 && z[j] < z[j - 1]; j--) {
            double tz = z[j];
            z[j] = z[j - 1];
            z[j - 1] = tz;
            int tk = kind[j];
            kind[j] = kind[j - 1];
            kind[j - 1] = tk;
        }
    int m = 0;
    for (int i = 0; i < nz; i++) {
        if (m && z[i] == z[m - 1]) {
            kind[m - 1] |= kind[i];
            continue;
        }
        z[m] = z[i];
        kind[m++] = kind[i];
    }
    nz = m;

    /* Pieces: slice i (critical) has nodes 4*(2i) + k, the slab above it
     * 4*(2i+1) + k, indexed by corner k; nodes of one component are united. */
    dsu u;
    for (int i = 0; i < 64; i++)
        u.parent[i] = i;
    int prev_comp[4] = {-1, -1, -1, -1};
    for (int i = 0; i < 2 * nz - 1; i++) {
        const int critical = (i % 2) == 0;
        const int c = i / 2;
        double h = critical ? z[c] : 0.5 * (z[c] + z[c + 1]);
        double x[4];
        for (int k = 0; k < 4; k++) {
            x[k] = b[k] + h * d[k];
            if (critical && (kind[c] & (1 << k)))
                x[k] = 0;
        }
        if (critical && c == 0)
            for (int k = 0; k < 4; k++)
                x[k] = b[k];
        if (critical && c == nz - 1)
            for (int k = 0; k < 4; k++)
                x[k] = b[k] + d[k];
        int comp[4];
        slice_components(x, critical && (kind[c] & 16), strict, comp);
        int first[2] = {-1, -1};
        for (int k = 0; k < 4; k++) {
            if (comp[k] < 0)
                continue;
            int node = 4 * i + k;
            if (first[comp[k]] < 0)
                first[comp[k]] = node;
            else
                dsu_union(&u, node, first[comp[k]]);
            /* Same corner inside in the previous piece: they touch. */
            if (i > 0 && prev_comp[k] >= 0)
                dsu_union(&u, node, 4 * (i - 1) + k);
        }
        memcpy(prev_comp, comp, sizeof comp);
        if (i == 0)
            for (int k = 0; k < 4; k++)
                label[slice_corner[k]] = comp[k] >= 0 ? 4 * i + k : -1;
        if (i == 2 * nz - 2)
            for (int k = 0; k < 4; k++)
                label[slice_corner[k] + 4] = comp[k] >= 0 ? 4 * i + k : -1;
    }
    int roots[8], nroots = 0;
    for (int c = 0; c < 8; c++) {
        if (label[c] < 0)
            continue;
        int r = dsu_find(&u, label[c]), j;
        for (j = 0; j < nroots; j++)
            if (roots[j] == r)
                break;
        if (j == nroots)
            roots[nroots++] = r;
        label[c] = j;
    }
    return nroots;
}

/* ------------------------------------------------------------- per cube */

static int any_nonfinite(const double *v)
{
    for (int c = 0; c < 8; c++)
        if (!isfinite(v[c]))
            return 1;
    return 0;
}

static int lowest_corner(unsigned mask)
{
    return mask ? __builtin_ctz(mask) : -1;
}

int isomend_method_cube(isomend_method method, const methods_cube *cube, unsigned char *slots)
{
    const unsigned config = cube->config & 255;
    if (!methods_handles(method))
        return -1;
    if (config == 0 || config == 255)
        return 0;
    if (method == ISOMEND_METHOD_TETRA) {
        const int p = (int)(cube->parity & 1);
        const int n = methods_tetra_count[p][config];
        memcpy(slots, methods_tetra_tri[p][config], (size_t)n * 3);
        return n;
    }
    unsigned join = methods_face_join(method, cube);
    int tube = -1;
    if (method == ISOMEND_METHOD_MC33) {
        const methods_entry *en = &methods_entries[entry_index(config, join)];
        if (en->tube_count && !any_nonfinite(cube->v) && isfinite(cube->iso)) {
            int label[2][8], have[2] = {0, 0};
            for (int t = 0; t < en->tube_count && tube < 0; t++) {
                const methods_tube *tb = &methods_tubes[en->tube_first + t];
                const int sgn = tb->sign;
                if (!have[sgn]) {
                    methods_cube_components(cube->v, cube->iso, sgn, label[sgn]);
                    have[sgn] = 1;
                }
                const int a = lowest_corner(tb->corners_a), b = lowest_corner(tb->corners_b);
                if (label[sgn][a] >= 0 && label[sgn][a] == label[sgn][b])
                    tube = t;
            }
        }
    }
    return methods_table_triangles(config, join, tube, slots);
}
