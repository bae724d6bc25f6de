/*
 * decimate.c - quadric-error edge collapse (Garland & Heckbert 1997) that
 * never opens a hole: isomend_mesh_decimate().
 *
 * Every collapse of an edge (a, b) into one vertex at the point that
 * minimises the sum of the two quadrics is refused unless it keeps the
 * surface what it was:
 *   - the link condition (Dey, Edelsbrunner, Guha & Nekhayev 1999): the
 *     vertices adjacent to both a and b are exactly the two opposite the
 *     edge, and no triangle joins those two with a and with b (a
 *     tetrahedron).  On a closed 2-manifold such a collapse is a
 *     homeomorphism: components, orientation and genus stay, and no
 *     component collapses away (a tetrahedron is the smallest left);
 *   - no triangle around a or b flips (its normal turns by 90 degrees or
 *     more) or becomes degenerate (zero area);
 *   - vertices on once-used edges (the volume's border of an unpadded
 *     surface, or holes of the methods that leave them), on edges used more
 *     than twice or twice the same way, on repeated-index triangles and
 *     where the triangles around a vertex form several fans are locked:
 *     never moved, never removed, so the border stays where it is;
 *   - with a maximum error, every input vertex stays within it of the
 *     triangles around the vertex it was collapsed into (collapse_close),
 *     so within it of the result.  The report's errors are measured at the
 *     end (distance.c).
 * Collapses are taken in passes (the loop in mesh_decimate_to says how),
 * cheapest first, ties in the order of the triangles; in the large passes
 * the candidates inside fixed regions of the mesh go region by region on
 * threads before those on the regions' borders (run_pass says why that is
 * safe).  The result does not depend on the thread count, which only
 * shares out the costing, the regions and the distance measurement.
 *
 * Layout: a corner table (corner c = 3t + k of triangle t; a dead
 * triangle's first corner NONE) and, per pass, each vertex's corners in a
 * compressed row table (fan_first, fan) built as the pass begins; a vertex
 * collapsed into another in the pass lends it its corners (merged), and
 * the corners of triangles that died in the pass are skipped.
 */
#include "arena.h"
#include "mem_tally.h"
#include "mesh_internal.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX

enum { V_LOCKED = 1, V_DEAD = 2 };

/* A collapse may not make a triangle thinner than this shape measure
 * (|n| / sum of squared edges: 0.289 equilateral, 0 degenerate) unless it was
 * thin already (then not below half of what it was): no fans of slivers in
 * flat regions, whose later collapses would all be refused as flips. */
#define MIN_SHAPE 0.03

/* The link condition's neighbours of a, held on the stack up to LINK_CAP
 * (collapse_allowed; the marks beyond). */
#define LINK_CAP 128

/* A candidate collapse of a pass: the edge (a < b) and its cost. */
typedef struct cand {
    float cost;
    uint32_t a, b;
} cand;

typedef struct dec {
    size_t nv, nt, alive;
    double *p;       /* 3 a vertex */
    double *q;       /* 10 a vertex: the quadric's upper triangle */
    uint32_t *tv;    /* 3 a triangle: the corners' vertices */
    uint8_t *tdead;
    uint32_t *fan_first; /* nv + 1: where a vertex's corners start in fan */
    uint32_t *fan;       /* the corners of the live triangles as the pass began, by vertex */
    uint32_t *merged;    /* the vertex collapsed into v in this pass, or NONE */
    uint32_t *live;      /* the live triangles as the pass began, in order */
    uint8_t *border;     /* a vertex with a triangle across a region's border (run_pass) */
    size_t nlive;
    float *cost_of;      /* a corner's edge's cost when last costed (from its a < b side) */
    struct cand *cand, *cand_tmp; /* a pass's candidates: 3 a triangle each */
    uint8_t *vf;     /* V_LOCKED, V_DEAD */
    uint32_t *mark;  /* scratch marks, generation `gen` */
    uint32_t *hist;  /* sort_candidates()' histogram: 65536 */
    uint32_t gen;
    uint64_t *changed;   /* a bit a vertex: moved or removed in this pass */
    uint64_t *changed_before; /* the same for the pass before (the costs to renew) */
    size_t nwords;       /* of each */
    uint32_t pass;
    double max_dist;      /* max_error, or 0: no distance check            */
    const float *orig;    /* the points the vertices stand for: the input's  */
                          /* positions, or decimate_carry.pts               */
    uint32_t *members;    /* the points a vertex stands for: a list         */
    uint32_t *member_next; /* through these (a point each), from members[v] */
    uint32_t *member_last; /* the list's last                              */
    mem_tally mem;         /* its bytes (decimate_carry.peak_bytes)         */
    team *team;            /* the call's threads, started once (NULL: this one) */
} dec;

/* ------------------------------------------------------------- quadrics */

static void quadric_add_plane(double *q, const double n[3], double dd)
{
    q[0] += n[0] * n[0];
    q[1] += n[0] * n[1];
    q[2] += n[0] * n[2];
    q[3] += n[0] * dd;
    q[4] += n[1] * n[1];
    q[5] += n[1] * n[2];
    q[6] += n[1] * dd;
    q[7] += n[2] * n[2];
    q[8] += n[2] * dd;
    q[9] += dd * dd;
}

static double quadric_eval(const double *q, const double v[3])
{
    const double x = v[0], y = v[1], z = v[2];
    return q[0] * x * x + 2 * q[1] * x * y + 2 * q[2] * x * z + 2 * q[3] * x + q[4] * y * y +
           2 * q[5] * y * z + 2 * q[6] * y + q[7] * z * z + 2 * q[8] * z + q[9];
}

/* The planes of triangles from `from` on, summed into their vertices'
 * quadrics, then q_in (if not NULL) added: each vertex's own sum, over its
 * corners in the order of the triangles (as one pass over the triangles
 * would add them), so vertices [lo, hi) on any thread. */
typedef struct quadric_job {
    const struct dec *d;
    size_t from;
    const double *q_in;
} quadric_job;

static void quadric_range(void *arg, size_t lo, size_t hi);

/* The collapse of (a, b): the point minimising qa + qb (or the best of a, b
 * and the midpoint where that is ill-posed or far off the edge); its cost. */
static double collapse_point(const dec *d, uint32_t a, uint32_t b, double v[3])
{
    double q[10];
    for (int i = 0; i < 10; i++)
        q[i] = d->q[10 * a + i] + d->q[10 * b + i];
    const double *pa = d->p + 3 * a, *pb = d->p + 3 * b;
    double len2 = 0;
    for (int c = 0; c < 3; c++)
        len2 += (pb[c] - pa[c]) * (pb[c] - pa[c]);
    /* A v = -r, A = [q0 q1 q2; q1 q4 q5; q2 q5 q7], r = (q3, q6, q8) */
    const double A00 = q[0], A01 = q[1], A02 = q[2], A11 = q[4], A12 = q[5], A22 = q[7];
    const double c00 = A11 * A22 - A12 * A12, c01 = A02 * A12 - A01 * A22,
                 c02 = A01 * A12 - A02 * A11;
    const double det = A00 * c00 + A01 * c01 + A02 * c02;
    const double tr = A00 + A11 + A22;
    if (fabs(det) > 1e-9 * tr * tr * tr && tr > 0) {
        const double c11 = A00 * A22 - A02 * A02, c12 = A01 * A02 - A00 * A12,
                     c22 = A00 * A11 - A01 * A01;
        const double r0 = -q[3], r1 = -q[6], r2 = -q[8];
        v[0] = (c00 * r0 + c01 * r1 + c02 * r2) / det;
        v[1] = (c01 * r0 + c11 * r1 + c12 * r2) / det;
        v[2] = (c02 * r0 + c12 * r1 + c22 * r2) / det;
        double off = 0;
        for (int c = 0; c < 3; c++) {
            const double m = 0.5 * (pa[c] + pb[c]);
            off += (v[c] - m) * (v[c] - m);
        }
        if (off <= len2 && isfinite(v[0] + v[1] + v[2])) {
            const double e = quadric_eval(q, v);
            return e > 0 ? e : 0;
        }
    }
    /* On the edge: v = a + s (b - a) minimising the quadric, s in [0, 1];
     * where the quadric is flat along the edge (a plane: every point costs
     * the same) the midpoint, so that flat regions keep even triangles. */
    const double e[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
    const double Ae[3] = {A00 * e[0] + A01 * e[1] + A02 * e[2], A01 * e[0] + A11 * e[1] + A12 * e[2],
                          A02 * e[0] + A12 * e[1] + A22 * e[2]};
    const double eAe = e[0] * Ae[0] + e[1] * Ae[1] + e[2] * Ae[2];
    const double grad = Ae[0] * pa[0] + Ae[1] * pa[1] + Ae[2] * pa[2] + e[0] * q[3] + e[1] * q[6] +
                        e[2] * q[8]; /* e . (A a + r) */
    double s = 0.5;
    if (eAe > 1e-12 * tr * len2) {
        s = -grad / eAe;
        s = s < 0 ? 0 : s > 1 ? 1 : s;
    }
    for (int c = 0; c < 3; c++)
        v[c] = pa[c] + s * e[c];
    const double best = quadric_eval(q, v);
    return best > 0 ? best : 0;
}

/* --------------------------------------------------------- adjacency */

/*
 * A vertex's corners: those it had as the pass began (fan, rebuilt each
 * pass: contiguous, unlike lists, so that they cost one or two cache lines)
 * and, if a vertex was collapsed into it in this pass, that vertex's (each
 * vertex changes at most once a pass).  Corners of triangles that died in
 * this pass are skipped.
 */
typedef struct fan_iter {
    const uint32_t *at, *end, *at2, *end2;
} fan_iter;

static inline int is_changed(const uint64_t *bits, uint32_t v) { return (int)(bits[v >> 6] >> (v & 63)) & 1; }
static inline void set_changed(uint64_t *bits, uint32_t v) { bits[v >> 6] |= (uint64_t)1 << (v & 63); }

static inline fan_iter fan_begin(const dec *d, uint32_t x)
{
    fan_iter it = {d->fan + d->fan_first[x], d->fan + d->fan_first[x + 1], NULL, NULL};
    if (is_changed(d->changed, x) && d->merged[x] != NONE) {
        const uint32_t y = d->merged[x];
        it.at2 = d->fan + d->fan_first[y];
        it.end2 = d->fan + d->fan_first[y + 1];
    }
    return it;
}

static inline int fan_next(const dec *d, fan_iter *it, uint32_t *c)
{
    for (;;) {
        while (it->at < it->end) {
            const uint32_t k = *it->at++;
            if (d->tv[k - k % 3] != NONE) { /* not dead (collapse) */
                *c = k;
                return 1;
            }
        }
        if (!it->at2)
            return 0;
        it->at = it->at2;
        it->end = it->end2;
        it->at2 = NULL;
    }
}

/* The live triangles and the fans of a pass (the corners of the live
 * triangles by vertex, each vertex's in the order of the triangles: a
 * counting sort); a new pass's marks. */
static void begin_pass(dec *d)
{
    size_t m = 0;
    for (size_t i = 0; i < d->nlive; i++)
        if (!d->tdead[d->live[i]])
            d->live[m++] = d->live[i];
    d->nlive = m;
    uint32_t *first = d->fan_first, *cursor = d->merged; /* merged: scratch here */
    memset(first, 0, (d->nv + 1) * sizeof(uint32_t));
    for (size_t i = 0; i < m; i++)
        for (int k = 0; k < 3; k++)
            first[d->tv[3 * (size_t)d->live[i] + (size_t)k] + 1]++;
    for (size_t v = 0; v < d->nv; v++) {
        first[v + 1] += first[v];
        cursor[v] = first[v];
    }
    for (size_t i = 0; i < m; i++) {
        const uint32_t t = d->live[i];
        for (uint32_t k = 0; k < 3; k++)
            d->fan[cursor[d->tv[3 * t + k]]++] = 3 * t + k;
    }
    for (size_t v = 0; v < d->nv; v++)
        d->merged[v] = NONE;
    uint64_t *w = d->changed_before; /* this pass's marks start empty */
    d->changed_before = d->changed;
    d->changed = w;
    memset(d->changed, 0, d->nwords * sizeof(uint64_t));
}


static inline uint32_t corner_next(const dec *d, uint32_t c) { return d->tv[c - c % 3 + (c % 3 + 1) % 3]; }
static inline uint32_t corner_prev(const dec *d, uint32_t c) { return d->tv[c - c % 3 + (c % 3 + 2) % 3]; }

static void quadric_range(void *arg, size_t lo, size_t hi)
{
    const quadric_job *j = arg;
    const dec *d = j->d;
    for (size_t v = lo; v < hi; v++) {
        double *q = d->q + 10 * v;
        for (int i = 0; i < 10; i++)
            q[i] = 0;
        for (uint32_t k = d->fan_first[v]; k < d->fan_first[v + 1]; k++) {
            const uint32_t t = d->fan[k] / 3;
            if (t < j->from)
                continue;
            const double *p0 = d->p + 3 * (size_t)d->tv[3 * (size_t)t],
                         *p1 = d->p + 3 * (size_t)d->tv[3 * (size_t)t + 1],
                         *p2 = d->p + 3 * (size_t)d->tv[3 * (size_t)t + 2];
            const double e1[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
            const double e2[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
            double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                           e1[0] * e2[1] - e1[1] * e2[0]};
            const double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            if (!(len > 0) || !isfinite(len))
                continue;
            for (int c = 0; c < 3; c++)
                n[c] /= len;
            const double dd = -(n[0] * p0[0] + n[1] * p0[1] + n[2] * p0[2]);
            quadric_add_plane(q, n, dd);
        }
        if (j->q_in)
            for (int i = 0; i < 10; i++)
                q[i] += j->q_in[10 * v + (size_t)i];
    }
}

/* ------------------------------------------------------------- distance */

/* Whether input vertex u lies within `limit` (squared distance) of a live
 * triangle around x1 or x2 (NONE: none), with a and b moved to v (the
 * triangles with both a and b die with their edge): the first such triangle
 * answers, so that a point near its first triangles costs one distance. */
static int fan_within(const dec *d, uint32_t u, uint32_t x1, uint32_t x2, uint32_t a, uint32_t b,
                      const double *v, double limit)
{
    const double p[3] = {d->orig[3 * (size_t)u], d->orig[3 * (size_t)u + 1],
                         d->orig[3 * (size_t)u + 2]};
    for (int s = 0; s < 2; s++) {
        const uint32_t x = s ? x2 : x1;
        if (x == NONE)
            continue;
        fan_iter it = fan_begin(d, x);
        uint32_t c;
        while (fan_next(d, &it, &c)) {
            const uint32_t t = c / 3;
            const double *q[3];
            int moved = 0;
            for (int k = 0; k < 3; k++) {
                const uint32_t y = d->tv[3 * t + (uint32_t)k];
                const int m = y == a || y == b;
                moved += m;
                q[k] = m ? v : d->p + 3 * (size_t)y;
            }
            if (moved > 1)
                continue;
            if (point_triangle_distance2(p, q[0], q[1], q[2]) <= limit)
                return 1;
        }
    }
    return 0;
}

/* The members of neighbour w, each within `limit` (squared) of w's fan
 * after (a, b) collapses to v. */
static int members_close(const dec *d, uint32_t w, uint32_t a, uint32_t b, const double v[3],
                         double limit)
{
    for (uint32_t u = d->members[w]; u != NONE; u = d->member_next[u])
        if (!fan_within(d, u, w, NONE, a, b, v, limit))
            return 0;
    return 1;
}

/* A new generation of the marks (all unmarked): its value. */
static uint32_t next_generation(dec *d)
{
    if (++d->gen == 0) {
        memset(d->mark, 0, d->nv * sizeof(uint32_t));
        d->gen = 1;
    }
    return d->gen;
}

/* Neighbours held in a list on the stack, up to CLOSE_CAP (the marks beyond:
 * only outside the regions, whose vertices have at most LINK_CAP / 2
 * triangles, so that the regions' threads share no scratch). */
#define CLOSE_CAP LINK_CAP

/* Whether every input vertex stays within max_dist of the triangles around
 * the vertex it stands in for, after (a, b) collapses to v: the members of
 * a and b (to the new fan) and of every neighbour of a or b (whose fans
 * change too), each neighbour once (found in `seen`, or with many corners
 * or merged fans by the marks, generation g). */
static int collapse_close(dec *d, uint32_t a, uint32_t b, const double v[3])
{
    const double limit = d->max_dist * d->max_dist;
    for (int s = 0; s < 2; s++)
        for (uint32_t u = d->members[s ? b : a]; u != NONE; u = d->member_next[u])
            if (!fan_within(d, u, a, b, a, b, v, limit))
                return 0;
    uint32_t seen[CLOSE_CAP];
    size_t nseen = 0;
    const int listed = /* at most CLOSE_CAP corners: no merged fans */
        d->fan_first[a + 1] - d->fan_first[a] + d->fan_first[b + 1] - d->fan_first[b] <= CLOSE_CAP &&
        !(is_changed(d->changed, a) || is_changed(d->changed, b));
    uint32_t g = 0;
    if (!listed) {
        g = next_generation(d);
        d->mark[a] = d->mark[b] = g;
    }
    for (int s = 0; s < 2; s++) {
        fan_iter it = fan_begin(d, s ? b : a);
        uint32_t c;
        while (fan_next(d, &it, &c)) {
            const uint32_t w = corner_next(d, c);
            int again = listed ? w == a || w == b : d->mark[w] == g;
            for (size_t i = 0; listed && i < nseen && !again; i++)
                again = seen[i] == w;
            if (again)
                continue;
            if (listed)
                seen[nseen++] = w;
            else
                d->mark[w] = g;
            if (!members_close(d, w, a, b, v, limit))
                return 0;
        }
    }
    return 1;
}

/* --------------------------------------------------------- one collapse */

/* n = (p1 - p0) x (p2 - p0) of triangle t with vertices moved_a and moved_b
 * at v (if v is not NULL), and *edges the sum of its squared edge lengths. */
static void tri_normal(const dec *d, uint32_t t, uint32_t moved_a, uint32_t moved_b,
                       const double *v, double n[3], double *edges)
{
    const double *p[3];
    for (int k = 0; k < 3; k++) {
        const uint32_t x = d->tv[3 * t + (uint32_t)k];
        p[k] = (x == moved_a || x == moved_b) && v ? v : d->p + 3 * x;
    }
    const double e1[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    const double e2[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    if (edges) {
        const double e3[3] = {p[2][0] - p[1][0], p[2][1] - p[1][1], p[2][2] - p[1][2]};
        *edges = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2] + e2[0] * e2[0] + e2[1] * e2[1] +
                 e2[2] * e2[2] + e3[0] * e3[0] + e3[1] * e3[1] + e3[2] * e3[2];
    }
}


enum { ALLOWED = 0, REFUSED_TOPOLOGY = 1, REFUSED_GEOMETRY = 2 };

/* Whether (a, b) may collapse to v (the checks at the top of this file):
 * ALLOWED or why not.  Uses the marks only where a has more than
 * LINK_CAP / 2 triangles. */
static int collapse_allowed(dec *d, uint32_t a, uint32_t b, const double v[3])
{
    /* link condition: the neighbours common to a and b */
    uint32_t around[LINK_CAP];
    size_t naround = 0;
    int marked = 0; /* too many neighbours for `around`: the marks */
    uint32_t g = 0;
    uint32_t opp[2], nopp = 0;
    fan_iter it = fan_begin(d, a);
    uint32_t c;
    while (fan_next(d, &it, &c)) {
        const uint32_t w = corner_next(d, c), u = corner_prev(d, c);
        if (!marked && naround + 2 > LINK_CAP) {
            g = next_generation(d);
            for (size_t i = 0; i < naround; i++)
                d->mark[around[i]] = g;
            marked = 1;
        }
        if (marked) {
            d->mark[w] = d->mark[u] = g;
        } else {
            around[naround++] = w;
            around[naround++] = u;
        }
        if (w == b)
            opp[nopp < 2 ? nopp : 1] = u, nopp++;
    }
    if (nopp != 1)
        goto topology;
    it = fan_begin(d, b);
    while (fan_next(d, &it, &c))
        if (corner_next(d, c) == a)
            opp[1] = corner_prev(d, c), nopp++;
    if (nopp != 2 || opp[0] == opp[1])
        goto topology;
    int common = 0;
    it = fan_begin(d, b);
    while (fan_next(d, &it, &c)) {
        const uint32_t w = corner_next(d, c); /* each neighbour once as `next` */
        if (w == a)
            continue;
        if (marked) {
            common += d->mark[w] == g;
        } else {
            for (size_t i = 0; i < naround; i++)
                if (around[i] == w) {
                    common++;
                    break;
                }
        }
    }
    if (common != 2)
        goto topology;
    /* no triangle (a, c, d) and (b, c, d) both: a tetrahedron */
    int tet = 0;
    for (int s = 0; s < 2; s++) {
        it = fan_begin(d, s ? b : a);
        while (fan_next(d, &it, &c)) {
            const uint32_t w = corner_next(d, c), u = corner_prev(d, c);
            if ((w == opp[0] && u == opp[1]) || (w == opp[1] && u == opp[0])) {
                tet++;
                break;
            }
        }
    }
    if (tet == 2)
        goto topology;
    /* no flipped or degenerate triangle */
    for (int s = 0; s < 2; s++) {
        it = fan_begin(d, s ? b : a);
        while (fan_next(d, &it, &c)) {
            const uint32_t t = c / 3;
            const uint32_t w = corner_next(d, c), u = corner_prev(d, c);
            if (w == (s ? a : b) || u == (s ? a : b))
                continue; /* dies with the edge */
            double n0[3], n1[3], e0, e1;
            tri_normal(d, t, NONE, NONE, NULL, n0, &e0);
            tri_normal(d, t, a, b, v, n1, &e1);
            const double l1 = n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2];
            const double dot = n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2];
            const double l0 = n0[0] * n0[0] + n0[1] * n0[1] + n0[2] * n0[2];
            /* shape: 2 sqrt(3) |n| / (sum of squared edges), 1 equilateral */
            const double q0 = e0 > 0 ? sqrt(l0) / e0 : 0, q1 = e1 > 0 ? sqrt(l1) / e1 : 0;
            if (!(l1 > 0) || (l0 > 0 && !(dot > 0)) || (q1 < MIN_SHAPE && q1 < 0.5 * q0))
                return REFUSED_GEOMETRY;
        }
    }
    return ALLOWED;
topology:
    return REFUSED_TOPOLOGY;
}

/* Collapses (a, b) into a at v; the caller then marks both as changed in
 * this pass.  Returns the number of triangles that died (two). */
static size_t collapse(dec *d, uint32_t a, uint32_t b, const double v[3])
{
    fan_iter it = fan_begin(d, b);
    uint32_t c;
    size_t died = 0;
    while (fan_next(d, &it, &c)) {
        if (corner_next(d, c) == a || corner_prev(d, c) == a) {
            d->tdead[c / 3] = 1;
            d->tv[c - c % 3] = NONE; /* so the fans see it dead without tdead */
            died++;
        } else {
            d->tv[c] = a;
        }
    }
    d->vf[b] |= V_DEAD;
    d->merged[a] = b; /* b's corners are a's now */
    d->merged[b] = NONE;
    if (d->members) { /* b's members join a's */
        if (d->members[b] != NONE) {
            if (d->members[a] == NONE)
                d->members[a] = d->members[b];
            else
                d->member_next[d->member_last[a]] = d->members[b];
            d->member_last[a] = d->member_last[b];
        }
        d->members[b] = NONE;
    }
    for (int i = 0; i < 10; i++)
        d->q[10 * a + i] += d->q[10 * b + i];
    memcpy(d->p + 3 * a, v, 3 * sizeof(double));
    return died;
}

/* ----------------------------------------------------------- the passes */

/*
 * The collapse loop takes the candidates in the order of their costs, so
 * all over the mesh: it would wait on memory at every step.  What a
 * candidate will read is asked for ahead (its vertices PREFETCH_FAR
 * candidates ahead, its fans' triangles PREFETCH_MID ahead, their vertices
 * PREFETCH_NEAR ahead).  Only a
 * hint: nothing depends on it.
 */
#define PREFETCH_FAR 32
#define PREFETCH_MID 12
#define PREFETCH_NEAR 4
#if defined(__GNUC__)
#define PREFETCH(x) __builtin_prefetch(x)
#else
#define PREFETCH(x) ((void)(x))
#endif

static inline void prefetch_vertices(const dec *d, uint32_t a, uint32_t b)
{
    if (is_changed(d->changed, a) || is_changed(d->changed, b))
        return; /* will be passed over */
    PREFETCH(d->fan_first + a);
    PREFETCH(d->fan_first + b);
    PREFETCH(d->p + 3 * (size_t)a);
    PREFETCH(d->p + 3 * (size_t)b);
    PREFETCH(d->q + 10 * (size_t)a);
    PREFETCH(d->q + 10 * (size_t)a + 9);
    PREFETCH(d->q + 10 * (size_t)b);
    PREFETCH(d->q + 10 * (size_t)b + 9);
}

static inline void prefetch_fans(const dec *d, uint32_t a, uint32_t b)
{
    if (is_changed(d->changed, a) || is_changed(d->changed, b))
        return; /* will be passed over */
    for (int s = 0; s < 2; s++) {
        const uint32_t x = s ? b : a;
        for (uint32_t k = d->fan_first[x]; k < d->fan_first[x + 1]; k++) {
            const uint32_t c = d->fan[k];
            PREFETCH(d->tv + c);
        }
    }
}

static inline void prefetch_neighbours(const dec *d, uint32_t a, uint32_t b)
{
    if (is_changed(d->changed, a) || is_changed(d->changed, b))
        return;
    for (int s = 0; s < 2; s++) {
        const uint32_t x = s ? b : a;
        for (uint32_t k = d->fan_first[x]; k < d->fan_first[x + 1]; k++) {
            const uint32_t w = corner_next(d, d->fan[k]);
            if (w != NONE) /* NONE: a dead triangle's first corner */
                PREFETCH(d->p + 3 * (size_t)w);
        }
    }
}

/*
 * The candidates of a pass: every live edge (once, from its a < b side)
 * whose ends are free, in the order of the triangles, with their costs.
 * The triangles go in blocks of GATHER_BLOCK, on threads: each block's
 * candidates are counted, then filed from the block's offset and costed
 * (a pure function of the mesh), so nothing depends on the threads.
 */
#define GATHER_BLOCK 16384
#define GATHER_AHEAD 8

typedef struct gather_job {
    dec *d; /* writes only cost_of, each block its own triangles' */
    cand *c;
    size_t *first; /* a block's first candidate; its count before the sum */
} gather_job;

static int edge_free(const dec *d, uint32_t a, uint32_t b)
{
    return a < b && !((d->vf[a] | d->vf[b]) & (V_LOCKED | V_DEAD));
}

static void gather_count(void *arg, size_t lo, size_t hi)
{
    const gather_job *j = arg;
    const dec *d = j->d;
    for (size_t blk = lo; blk < hi; blk++) {
        const size_t i1 = (blk + 1) * GATHER_BLOCK < d->nlive ? (blk + 1) * GATHER_BLOCK : d->nlive;
        size_t k = 0;
        for (size_t i = blk * GATHER_BLOCK; i < i1; i++) {
            const size_t t = d->live[i];
            for (int e = 0; e < 3; e++)
                k += (size_t)edge_free(d, d->tv[3 * t + (size_t)e], d->tv[3 * t + (size_t)(e + 1) % 3]);
        }
        j->first[blk + 1] = k;
    }
}

static void gather_cost(void *arg, size_t lo, size_t hi)
{
    const gather_job *j = arg;
    dec *d = j->d;
    for (size_t blk = lo; blk < hi; blk++) {
        const size_t i1 = (blk + 1) * GATHER_BLOCK < d->nlive ? (blk + 1) * GATHER_BLOCK : d->nlive;
        cand *c = j->c + j->first[blk];
        for (size_t i = blk * GATHER_BLOCK; i < i1; i++) {
            const size_t t = d->live[i];
            if (i + GATHER_AHEAD < i1) /* the quadrics a few triangles ahead */
                for (int k = 0; k < 3; k++) {
                    const size_t x = d->tv[3 * (size_t)d->live[i + GATHER_AHEAD] + (size_t)k];
                    PREFETCH(d->q + 10 * x);
                    PREFETCH(d->q + 10 * x + 9);
                }
            for (int e = 0; e < 3; e++) {
                const uint32_t a = d->tv[3 * t + (size_t)e], b = d->tv[3 * t + (size_t)(e + 1) % 3];
                if (!edge_free(d, a, b))
                    continue;
                float *cost = d->cost_of + 3 * t + (size_t)e;
                if (d->pass == 1 || is_changed(d->changed_before, a) || is_changed(d->changed_before, b)) {
                    double v[3];
                    const double e2 = collapse_point(d, a, b, v);
                    *cost = e2 < (double)FLT_MAX ? (float)e2 : FLT_MAX;
                }
                *c++ = (cand){*cost, a, b};
            }
        }
    }
}

/* Gathers and costs the candidates into c (room for 3 a triangle); their
 * count.  0 without memory (then *ok = 0). */
static size_t gather(dec *d, cand *c, int *ok)
{
    const size_t nblocks = (d->nlive + GATHER_BLOCK - 1) / GATHER_BLOCK;
    size_t *first = calloc(nblocks + 1, sizeof(size_t));
    *ok = first != NULL;
    if (!first)
        return 0;
    mem_tally_spike(&d->mem, (nblocks + 1) * sizeof(size_t));
    gather_job job = {d, c, first};
    team_for_from(d->team, nblocks, 1, gather_count, &job);
    for (size_t blk = 0; blk < nblocks; blk++)
        first[blk + 1] += first[blk];
    team_for_from(d->team, nblocks, 1, gather_cost, &job);
    const size_t n = first[nblocks];
    free(first);
    return n;
}

static inline uint32_t cost_bits(const cand *c)
{
    uint32_t k;
    memcpy(&k, &c->cost, 4);
    return k;
}

/*
 * The candidates of a pass that it may take, cheapest first, ties in their
 * order: those up to the cost of the one at `rank` in that order (all if
 * rank >= n); their count, and *limit that cost (FLT_MAX: all).  The
 * costs' bits order as the non-negative floats do: a histogram of their top
 * 16 bits finds the block of costs where `rank` falls, the candidates up to
 * it are kept (in order), and a least significant digit radix sort (three
 * digits of 11 bits, stable) sorts them into c.  tmp has room for n.
 */
static size_t sort_candidates(cand *c, cand *tmp, size_t n, size_t rank, float *limit,
                              uint32_t *hist)
{
    uint32_t top = 0xffffu; /* the kept: top 16 bits up to this */
    if (rank < n) {
        memset(hist, 0, 65536 * sizeof(uint32_t));
        for (size_t i = 0; i < n; i++)
            hist[cost_bits(c + i) >> 16]++;
        size_t below = 0;
        for (top = 0; top < 0xffffu && below + hist[top] <= rank; top++)
            below += hist[top];
    }
    size_t count[3][2049];
    memset(count, 0, sizeof count);
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        const uint32_t k = cost_bits(c + i);
        if ((k >> 16) > top)
            continue;
        tmp[m++] = c[i];
        count[0][(k & 2047) + 1]++;
        count[1][((k >> 11) & 2047) + 1]++;
        count[2][(k >> 22) + 1]++;
    }
    cand *src = tmp, *dst = c;
    for (int digit = 0; digit < 3; digit++) {
        size_t *cnt = count[digit];
        for (int b = 0; b < 2048; b++)
            cnt[b + 1] += cnt[b];
        const int shift = 11 * digit;
        for (size_t i = 0; i < m; i++)
            dst[cnt[(cost_bits(src + i) >> shift) & 2047]++] = src[i];
        cand *t = src;
        src = dst;
        dst = t;
    }
    /* three passes from tmp: the sorted run is in c */
    *limit = rank < n ? c[rank].cost : FLT_MAX;
    while (m > 0 && c[m - 1].cost > *limit)
        m--;
    return m;
}

/* What a run of candidates did. */
typedef struct tally {
    uint64_t made, refused, topology, geometry, error;
    size_t died;
} tally;

/* Takes candidates c[0 .. n) in order (the rules of the passes) while
 * alive - (triangles that died) > target. */
static void run_candidates(dec *d, const cand *c, size_t n, size_t alive, uint64_t target,
                           tally *t)
{
    for (size_t i = 0; i < n && alive > target; i++) {
        if (i + PREFETCH_FAR < n)
            prefetch_vertices(d, c[i + PREFETCH_FAR].a, c[i + PREFETCH_FAR].b);
        if (i + PREFETCH_MID < n)
            prefetch_fans(d, c[i + PREFETCH_MID].a, c[i + PREFETCH_MID].b);
        if (i + PREFETCH_NEAR < n)
            prefetch_neighbours(d, c[i + PREFETCH_NEAR].a, c[i + PREFETCH_NEAR].b);
        const uint32_t ea = c[i].a, eb = c[i].b;
        if (is_changed(d->changed, ea) || is_changed(d->changed, eb))
            continue;
        double v[3];
        (void)collapse_point(d, ea, eb, v);
        const int why = collapse_allowed(d, ea, eb, v);
        if (why != ALLOWED) {
            t->refused++;
            t->topology += why == REFUSED_TOPOLOGY;
            t->geometry += why == REFUSED_GEOMETRY;
            continue;
        }
        if (d->max_dist > 0 && !collapse_close(d, ea, eb, v)) {
            t->error++;
            t->refused++;
            continue;
        }
        const size_t died = collapse(d, ea, eb, v);
        alive -= died;
        t->died += died;
        set_changed(d->changed, ea);
        set_changed(d->changed, eb);
        t->made++;
    }
}

/*
 * Regions.  The vertices go in regions of REGION_SIZE consecutive indices
 * (the extraction numbers them slab by slab, so a region is a slab of the
 * surface).  A candidate is inside a region when both its vertices and
 * every vertex of their triangles (as the pass began) are in it, and each
 * has at most LINK_CAP / 2 triangles.  Its checks and its collapse read
 * and write only that region's vertices and triangles (the triangles of a
 * vertex change only by collapses of its neighbours, which are then inside
 * the region too; a vertex's triangles only grow when it is collapsed into,
 * after which it waits for the next pass), and whole words of the bitmap.
 * So the regions' candidates can be taken region by region, each region's
 * in its order, on any thread, with the same result; the candidates on the
 * regions' borders follow, in their order.  With a maximum error the check
 * reads farther, the fans of a's and b's neighbours (collapse_close, which
 * then keeps the neighbours in a list on the stack, not in the shared
 * marks): the candidate is inside a region when those fans' vertices are in
 * it too.  A pass goes this way only where it cannot reach the target (each
 * collapse takes two free vertices: at most half the free vertices
 * collapse).
 */
#define REGION_SHIFT 16
#define REGION_SIZE ((size_t)1 << REGION_SHIFT) /* a multiple of 64: whole bitmap words */

/* The vertices with a triangle across a region's border (border[v] = 1)
 * as the pass begins; returns the number of free vertices that have
 * triangles. */
static size_t mark_borders(dec *d)
{
    memset(d->border, 0, d->nv);
    for (size_t i = 0; i < d->nlive; i++) {
        const uint32_t *t = d->tv + 3 * (size_t)d->live[i];
        if ((t[0] >> REGION_SHIFT) != (t[1] >> REGION_SHIFT) ||
            (t[0] >> REGION_SHIFT) != (t[2] >> REGION_SHIFT))
            d->border[t[0]] = d->border[t[1]] = d->border[t[2]] = 1;
    }
    size_t nfree = 0;
    for (size_t v = 0; v < d->nv; v++)
        nfree += !(d->vf[v] & (V_LOCKED | V_DEAD)) && d->fan_first[v + 1] > d->fan_first[v];
    return nfree;
}

/* The region (offset by `offset` vertices) that candidate (a, b) is inside,
 * or NONE.  offset 0: as the pass began (border); else as the fans are now
 * (a changed vertex is passed over anyway: NONE). */
/* Whether every vertex of x's triangles (as the fans are now) is in region
 * r (offset by `offset`). */
static int fan_inside(const dec *d, uint32_t x, uint32_t offset, uint32_t r)
{
    fan_iter it = fan_begin(d, x);
    uint32_t c;
    while (fan_next(d, &it, &c)) {
        const uint32_t *tv = d->tv + (c - c % 3);
        for (int k = 0; k < 3; k++)
            if ((uint32_t)(((size_t)tv[k] + offset) >> REGION_SHIFT) != r)
                return 0;
    }
    return 1;
}

static uint32_t region_of(const dec *d, uint32_t a, uint32_t b, uint32_t offset)
{
    if (d->fan_first[a + 1] - d->fan_first[a] > LINK_CAP / 2 ||
        d->fan_first[b + 1] - d->fan_first[b] > LINK_CAP / 2)
        return NONE;
    const uint32_t r = (uint32_t)(((size_t)a + offset) >> REGION_SHIFT);
    if (r != (uint32_t)(((size_t)b + offset) >> REGION_SHIFT))
        return NONE;
    if (offset == 0) {
        if (d->border[a] || d->border[b])
            return NONE;
        if (d->max_dist > 0) /* collapse_close reads the neighbours' fans too */
            for (int s = 0; s < 2; s++)
                for (uint32_t k = d->fan_first[s ? b : a]; k < d->fan_first[(s ? b : a) + 1]; k++) {
                    const uint32_t w = corner_next(d, d->fan[k]); /* live: the pass begins */
                    if (w == NONE || d->border[w])
                        return NONE;
                }
        return r;
    }
    if (is_changed(d->changed, a) || is_changed(d->changed, b))
        return NONE;
    if (!fan_inside(d, a, offset, r) || !fan_inside(d, b, offset, r))
        return NONE;
    for (int s = 0; s < 2 && d->max_dist > 0; s++) { /* and the neighbours' fans */
        fan_iter it = fan_begin(d, s ? b : a);
        uint32_t c;
        while (fan_next(d, &it, &c))
            if (!fan_inside(d, corner_next(d, c), offset, r))
                return NONE;
    }
    return r;
}

typedef struct region_job {
    dec *d;
    const cand *c;         /* the regions' candidates, region by region */
    const size_t *first;   /* nregions + 1 */
    tally *t;              /* a region's */
} region_job;

static void region_range(void *arg, size_t lo, size_t hi)
{
    const region_job *j = arg;
    for (size_t r = lo; r < hi; r++)
        run_candidates(j->d, j->c + j->first[r], j->first[r + 1] - j->first[r], SIZE_MAX, 0,
                       &j->t[r]);
}

static void tally_add(tally *t, const tally *u)
{
    t->made += u->made;
    t->refused += u->refused;
    t->topology += u->topology;
    t->geometry += u->geometry;
    t->error += u->error;
    t->died += u->died;
}

/* Takes the candidates c[0 .. n) inside the regions offset by `offset`
 * (region_of), region by region on threads, into t; the others stay in c,
 * in order: returns their count, or SIZE_MAX without memory.  tmp: room
 * for n. */
static size_t run_regions(dec *d, cand *c, cand *tmp, size_t n, uint32_t offset, tally *t)
{
    const size_t nregions = ((d->nv + offset) >> REGION_SHIFT) + 1;
    size_t *first = calloc(nregions + 1, sizeof(size_t));
    tally *rt = calloc(nregions, sizeof(tally));
    uint32_t *key = malloc((n ? n : 1) * sizeof(uint32_t));
    if (!first || !rt || !key) {
        free(first);
        free(rt);
        free(key);
        return SIZE_MAX;
    }
    mem_tally_spike(&d->mem, (nregions + 1) * sizeof(size_t) + nregions * sizeof(tally) +
                                 (n ? n : 1) * sizeof(uint32_t));
    for (size_t i = 0; i < n; i++) {
        key[i] = region_of(d, c[i].a, c[i].b, offset);
        if (key[i] != NONE)
            first[key[i] + 1]++;
    }
    for (size_t r = 0; r < nregions; r++)
        first[r + 1] += first[r];
    size_t rest = 0;
    for (size_t i = 0; i < n; i++) { /* stable: each region's in order, the rest too */
        if (key[i] != NONE)
            tmp[first[key[i]]++] = c[i];
        else
            c[rest++] = c[i];
    }
    free(key);
    for (size_t r = nregions; r > 0; r--) /* back to each region's start */
        first[r] = first[r - 1];
    first[0] = 0;
    region_job job = {d, tmp, first, rt};
    team_for_from(d->team, nregions, 1, region_range, &job);
    tally sum = {0, 0, 0, 0, 0, 0};
    for (size_t r = 0; r < nregions; r++)
        tally_add(&sum, &rt[r]);
    free(first);
    free(rt);
    d->alive -= sum.died;
    tally_add(t, &sum);
    return rest;
}

/* Takes the pass's candidates c[0 .. n) (sorted) into t: where the pass
 * may run so, those inside the regions on threads, then those inside the
 * regions shifted by half a region (the borders of the first, judged after
 * them), then the rest in order; else all in order.  tmp: room for n.  0
 * without memory. */
static int run_pass(dec *d, cand *c, cand *tmp, size_t n, size_t nfree, uint64_t target, tally *t)
{
    const size_t most = n < nfree / 2 ? n : nfree / 2; /* collapses a pass can make */
    if ((d->nv >> REGION_SHIFT) >= 1 && d->alive > target &&
        2 * most < d->alive - target) {
        n = run_regions(d, c, tmp, n, 0, t);
        if (n != SIZE_MAX)
            n = run_regions(d, c, tmp, n, (uint32_t)(REGION_SIZE / 2), t);
        if (n == SIZE_MAX)
            return 0;
    }
    tally b = {0, 0, 0, 0, 0, 0};
    run_candidates(d, c, n, d->alive, target, &b);
    d->alive -= b.died;
    tally_add(t, &b);
    return 1;
}

/* ---------------------------------------------------------- the output */

/* The live triangles and the vertices they use, in the input's order;
 * kept (if not NULL) gets each output vertex's input index. */
static isomend_status build_output(const dec *d, const isomend_mesh *in, isomend_mesh **out,
                                   uint32_t **kept)
{
    uint32_t *remap = malloc((d->nv ? d->nv : 1) * sizeof(uint32_t));
    isomend_mesh *m = calloc(1, sizeof(*m));
    if (!remap || !m) {
        free(remap);
        free(m);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    for (size_t v = 0; v < d->nv; v++)
        remap[v] = NONE;
    size_t nv = 0, nt = 0;
    for (size_t t = 0; t < d->nt; t++)
        if (!d->tdead[t]) {
            nt++;
            for (int k = 0; k < 3; k++) {
                const uint32_t x = d->tv[3 * t + (size_t)k];
                if (remap[x] == NONE)
                    remap[x] = 0; /* used; numbered below in the input's order */
            }
        }
    for (size_t v = 0; v < d->nv; v++)
        if (remap[v] != NONE)
            remap[v] = (uint32_t)nv++;
    if (kept) {
        *kept = malloc((nv ? nv : 1) * sizeof(uint32_t));
        if (!*kept) {
            free(remap);
            free(m);
            return ISOMEND_ERR_OUT_OF_MEMORY;
        }
        for (size_t v = 0; v < d->nv; v++)
            if (remap[v] != NONE)
                (*kept)[remap[v]] = (uint32_t)v;
    }
    m->nv = nv;
    m->nt = nt;
    m->pos = malloc(12 * (nv ? nv : 1));
    m->tri = malloc(12 * (nt ? nt : 1));
    m->nrm = in->nrm ? calloc(3 * (nv ? nv : 1), sizeof(float)) : NULL;
    if (!m->pos || !m->tri || (in->nrm && !m->nrm)) {
        free(remap);
        isomend_mesh_destroy(m);
        if (kept) {
            free(*kept);
            *kept = NULL;
        }
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    for (size_t v = 0; v < d->nv; v++)
        if (remap[v] != NONE)
            for (int c = 0; c < 3; c++)
                m->pos[3 * (size_t)remap[v] + (size_t)c] = (float)d->p[3 * v + (size_t)c];
    size_t o = 0;
    for (size_t t = 0; t < d->nt; t++)
        if (!d->tdead[t])
            for (int k = 0; k < 3; k++)
                m->tri[o++] = remap[d->tv[3 * t + (size_t)k]];
    free(remap);
    if (m->nrm)
        mesh_area_normals(m, NULL);
    if (mesh_copy_frame(m, in) != ISOMEND_OK) {
        isomend_mesh_destroy(m);
        if (kept) {
            free(*kept);
            *kept = NULL;
        }
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    *out = m;
    return ISOMEND_OK;
}

/* The kept vertices' quadrics (and with points, the points each stands
 * for), in output order (build_output numbers the used vertices in input
 * order); 0 without memory (nothing left allocated). */
static int carry_out(const dec *d, decimate_carry *carry, int with_pts, size_t nv_out)
{
    uint8_t *used = calloc(d->nv + 1, 1);
    carry->q_out = malloc(10 * sizeof(double) * (nv_out + 1));
    if (with_pts) {
        carry->pts_out = malloc((carry->pts_first[d->nv] + 1) * sizeof(uint32_t));
        carry->pts_out_first = malloc((nv_out + 1) * sizeof(uint32_t));
    }
    if (!used || !carry->q_out || (with_pts && (!carry->pts_out || !carry->pts_out_first))) {
        free(used);
        free(carry->q_out);
        free(carry->pts_out);
        free(carry->pts_out_first);
        carry->q_out = NULL;
        carry->pts_out = carry->pts_out_first = NULL;
        return 0;
    }
    for (size_t t = 0; t < d->nt; t++)
        if (!d->tdead[t])
            for (int k = 0; k < 3; k++)
                used[d->tv[3 * t + (size_t)k]] = 1;
    size_t o = 0;
    uint32_t at = 0;
    for (size_t v = 0; v < d->nv; v++) {
        if (!used[v])
            continue;
        memcpy(carry->q_out + 10 * o, d->q + 10 * v, 10 * sizeof(double));
        if (with_pts) {
            carry->pts_out_first[o] = at;
            for (uint32_t u = d->members[v]; u != NONE; u = d->member_next[u])
                carry->pts_out[at++] = u;
        }
        o++;
    }
    if (with_pts)
        carry->pts_out_first[o] = at;
    free(used);
    return 1;
}

/* --------------------------------------------------------------- the API */

void isomend_decimate_options_init(isomend_decimate_options *o)
{
    if (o)
        memset(o, 0, sizeof *o);
}

isomend_status isomend_mesh_decimate(const isomend_mesh *mesh, const isomend_decimate_options *o,
                                     isomend_mesh **out, isomend_decimate_report *report)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    if (!mesh || !o || !(o->ratio >= 0.0 && o->ratio <= 1.0) || !(o->max_error >= 0.0) ||
        !isfinite(o->max_error) || (o->ratio == 0.0 && o->target_triangles == 0 && o->max_error == 0.0))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    uint64_t target = 0;
    if (o->ratio > 0)
        target = (uint64_t)ceil(o->ratio * (double)mesh->nt);
    if (o->target_triangles > target)
        target = o->target_triangles;
    return mesh_decimate_to(mesh, target, o->max_error, 1, out, NULL, NULL, report);
}

isomend_status mesh_decimate_to(const isomend_mesh *mesh, uint64_t target, double max_error,
                                int measure, isomend_mesh **out, uint32_t **kept,
                                decimate_carry *carry, isomend_decimate_report *report)
{
    *out = NULL;
    if (carry)
        carry->q_out = NULL, carry->pts_out = carry->pts_out_first = NULL;
    if (kept)
        *kept = NULL;
    isomend_decimate_report rep;
    memset(&rep, 0, sizeof rep);
    dec d;
    memset(&d, 0, sizeof d);
    d.nv = mesh->nv;
    d.nt = mesh->nt;
    d.alive = mesh->nt;
    if (d.nt > (size_t)UINT32_MAX / 3 || d.nv >= (size_t)UINT32_MAX)
        return ISOMEND_ERR_TOO_LARGE;
    rep.triangles_before = d.nt;
    rep.vertices_before = d.nv;
    rep.target_triangles = target;
    const int carried_pts = carry && carry->pts && max_error > 0;
    const size_t npts = carried_pts ? carry->pts_first[d.nv] : d.nv;
    if (npts >= (size_t)UINT32_MAX)
        return ISOMEND_ERR_TOO_LARGE;

    const size_t nv = d.nv ? d.nv : 1, nc = 3 * (d.nt ? d.nt : 1), nt1 = d.nt ? d.nt : 1;
    d.nwords = (nv + 63) / 64;
    /* the working arrays in one arena (arena.c): faulted in at once, zero */
    arena ar;
    const size_t bytes_needed =
        arena_bytes(3 * sizeof(double) * nv) + arena_bytes(10 * sizeof(double) * nv) +
        arena_bytes(nc * sizeof(uint32_t)) + arena_bytes(nt1) + arena_bytes(nv * sizeof(uint32_t)) +
        arena_bytes((nv + 1) * sizeof(uint32_t)) + arena_bytes(nc * sizeof(uint32_t)) +
        2 * arena_bytes(nc * sizeof(cand)) + arena_bytes(nv) +
        2 * arena_bytes(d.nwords * sizeof(uint64_t)) + arena_bytes(nt1 * sizeof(uint32_t)) +
        arena_bytes(nv) + arena_bytes(nc * sizeof(float)) + arena_bytes(nv * sizeof(uint32_t)) +
        arena_bytes(65536 * sizeof(uint32_t)) +
        (max_error > 0 ? 2 * arena_bytes(nv * sizeof(uint32_t)) +
                             arena_bytes((npts ? npts : 1) * sizeof(uint32_t))
                       : 0);
    if (!arena_open(&ar, bytes_needed)) {
        if (report)
            *report = rep;
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    d.p = arena_take(&ar, 3 * sizeof(double) * nv);
    d.q = arena_take(&ar, 10 * sizeof(double) * nv); /* quadric_range sets every vertex's */
    d.tv = arena_take(&ar, nc * sizeof(uint32_t));
    d.tdead = arena_take(&ar, nt1);
    d.merged = arena_take(&ar, nv * sizeof(uint32_t));
    d.fan_first = arena_take(&ar, (nv + 1) * sizeof(uint32_t));
    d.fan = arena_take(&ar, nc * sizeof(uint32_t));
    d.cand = arena_take(&ar, nc * sizeof(cand));
    d.cand_tmp = arena_take(&ar, nc * sizeof(cand));
    d.vf = arena_take(&ar, nv);
    d.changed = arena_take(&ar, d.nwords * sizeof(uint64_t));
    d.changed_before = arena_take(&ar, d.nwords * sizeof(uint64_t));
    d.live = arena_take(&ar, nt1 * sizeof(uint32_t));
    d.border = arena_take(&ar, nv);
    d.cost_of = arena_take(&ar, nc * sizeof(float));
    d.mark = arena_take(&ar, nv * sizeof(uint32_t));
    d.hist = arena_take(&ar, 65536 * sizeof(uint32_t));
    if (max_error > 0) { /* only the distance check needs the members */
        d.members = arena_take(&ar, nv * sizeof(uint32_t));
        d.member_next = arena_take(&ar, (npts ? npts : 1) * sizeof(uint32_t));
        d.member_last = arena_take(&ar, nv * sizeof(uint32_t));
    }
    mem_tally_add(&d.mem, bytes_needed);
    d.orig = carried_pts ? carry->pts : mesh->pos;
    d.max_dist = max_error;
    isomend_status status = ISOMEND_ERR_OUT_OF_MEMORY;
    if (!d.p || !d.q || !d.tv || !d.tdead || !d.merged || !d.fan_first || !d.fan || !d.cand ||
        !d.cand_tmp || !d.vf || !d.changed || !d.changed_before || !d.live || !d.border ||
        !d.cost_of || !d.mark || !d.hist ||
        (max_error > 0 && (!d.members || !d.member_next || !d.member_last)))
        goto done;
    if (d.members && !carried_pts)
        for (size_t v = 0; v < d.nv; v++) {
            d.members[v] = d.member_last[v] = (uint32_t)v;
            d.member_next[v] = NONE;
        }
    if (d.members && carried_pts) /* vertex v's points, in order */
        for (size_t v = 0; v < d.nv; v++) {
            const uint32_t lo = carry->pts_first[v], hi = carry->pts_first[v + 1];
            d.members[v] = lo < hi ? lo : NONE;
            d.member_last[v] = lo < hi ? hi - 1 : NONE;
            for (uint32_t u = lo; u < hi; u++)
                d.member_next[u] = u + 1 < hi ? u + 1 : NONE;
        }
    for (size_t i = 0; i < 3 * d.nv; i++)
        d.p[i] = mesh->pos[i];
    memcpy(d.tv, mesh->tri, 3 * d.nt * sizeof(uint32_t));
    for (size_t t = 0; t < d.nt; t++)
        d.live[t] = (uint32_t)t;
    d.nlive = d.nt;
    begin_pass(&d); /* the first pass's fans */
    mem_tally_spike(&d.mem, (d.nv + 1) * sizeof(uint32_t) + 2 * nc * 4); /* its fans */
    if (4 * ((size_t)d.nv + 1) <= nc * sizeof(cand)) /* the candidates' arrays: scratch yet */
        mesh_free_vertices_into(mesh, NULL, d.vf, (uint32_t *)d.cand, (uint32_t *)d.cand_tmp,
                                (uint32_t *)d.cand_tmp + nc);
    else if (!mesh_free_vertices(mesh, NULL, d.vf, NULL, NULL, NULL))
        goto done;
    for (size_t v = 0; v < d.nv; v++) {
        d.vf[v] = d.vf[v] && !(carry && carry->locked && carry->locked[v])
                      ? 0
                      : V_LOCKED; /* unused vertices are locked too, and those asked */
        rep.locked_vertices += d.vf[v] && d.fan_first[v + 1] > d.fan_first[v];
    }
    /* the threads, started once for the call's loops (a thread's start cost
     * 0.3 ms on a virtual machine: a small mesh's decimation started 16) */
    d.team = team_start(d.nt);
    quadric_job qj = {&d, carry ? carry->planes_from : 0, carry ? carry->q_in : NULL};
    team_for(d.team, d.nv, quadric_range, &qj);
    /*
     * Passes.  Each gathers the live edges, costs them (on threads: a pure
     * function of the mesh), sorts them, and collapses them cheapest first,
     * each vertex at most once a pass (a vertex that changed waits for the
     * next pass, where its edges are costed again), up to the cost at the
     * rank of twice the collapses still needed plus the candidates the pass
     * before refused (so that a pass does not spend expensive edges while
     * cheaper ones are yet to appear, nor stall on cheap edges that keep
     * being refused).  A pass without a
     * collapse under that limit is run again without it; one without any
     * ends the decimation short of the target.
     */
    int unlimited = 0;
    size_t refused = 0; /* in the pass before */
    for (uint32_t pass = 1; d.alive > target; pass++) {
        d.pass = pass;
        if (pass > 1)
            begin_pass(&d);
        int ok;
        const size_t n_all = gather(&d, d.cand, &ok);
        if (!ok)
            goto done;
        const size_t need = (d.alive - target + 1) / 2;
        float limit;
        const size_t rank = unlimited || 2 * need + refused >= n_all ? n_all : 2 * need + refused;
        const size_t n = sort_candidates(d.cand, d.cand_tmp, n_all, rank, &limit, d.hist);
        const size_t nfree = mark_borders(&d);
        tally t = {0, 0, 0, 0, 0, 0};
        if (!run_pass(&d, d.cand, d.cand_tmp, n, nfree, target, &t))
            goto done;
        const uint64_t made = t.made;
        refused = t.refused;
        rep.refused_topology += t.topology;
        rep.refused_geometry += t.geometry;
        rep.refused_error += t.error;
        rep.collapses += made;
        if (made == 0) {
            if (unlimited || limit == FLT_MAX)
                break;
            unlimited = 1;
        } else {
            unlimited = 0;
        }
    }
    rep.reached = d.alive <= target;
    status = build_output(&d, mesh, out, kept);
    if (status == ISOMEND_OK) { /* the output, and the renumbering it was made with */
        const uint64_t ob = 12 * (uint64_t)((*out)->nv ? (*out)->nv : 1) * ((*out)->nrm ? 2 : 1) +
                            12 * (uint64_t)((*out)->nt ? (*out)->nt : 1) + sizeof **out +
                            (kept ? 4 * (uint64_t)((*out)->nv ? (*out)->nv : 1) : 0);
        mem_tally_spike(&d.mem, ob + nv * sizeof(uint32_t));
        mem_tally_add(&d.mem, ob + ((*out)->slice_store ? 24 * (uint64_t)(*out)->slices.n : 0));
    }
    if (status == ISOMEND_OK && carry) { /* the carried quadrics and points */
        const uint64_t nvo = (*out)->nv;
        const uint64_t cb =
            80 * (nvo + 1) +
            (carried_pts ? 4 * ((uint64_t)carry->pts_first[d.nv] + 1 + nvo + 1) : 0);
        mem_tally_spike(&d.mem, cb + d.nv + 1);
        mem_tally_add(&d.mem, cb);
    }
    if (carry)
        carry->peak_bytes = d.mem.peak;
    if (status == ISOMEND_OK && carry && !carry_out(&d, carry, carried_pts, (*out)->nv)) {
        isomend_mesh_destroy(*out);
        *out = NULL;
        if (kept) {
            free(*kept);
            *kept = NULL;
        }
        status = ISOMEND_ERR_OUT_OF_MEMORY;
    }
    if (status == ISOMEND_OK) {
        rep.triangles_after = (*out)->nt;
        rep.vertices_after = (*out)->nv;
        /* how far the input's vertices lie from the result */
        if (measure && !mesh_distances(mesh->pos, mesh->nv, (*out)->pos, (*out)->tri, (*out)->nt,
                                       d.team, &rep.max_error, &rep.mean_error, NULL)) {
            isomend_mesh_destroy(*out);
            *out = NULL;
            if (kept) {
                free(*kept);
                *kept = NULL;
            }
            status = ISOMEND_ERR_OUT_OF_MEMORY;
        }
    }
done:
    team_stop(d.team);
    arena_close(&ar);
    if (report)
        *report = rep;
    return status;
}
