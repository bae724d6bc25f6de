/*
 * decimate_stream.c - the decimation of a streamed mesh, in memory bounded
 * by a chunk of layers: isomend_decimate_stream_*().
 *
 * A client of the sliding window (stream_window.c): each window W = H (the
 * triangles held back from the previous window) + a chunk's triangles is
 * decimated by mesh_decimate_to() (decimate.c), which locks every vertex on
 * a once-used edge: so the cut vertices of W (those with triangles outside
 * it: already final below, or in the next chunk above) neither move nor
 * go, and no collapse reaches across a cut.  The triangles of W's result
 * within RINGS rings of the top plane are held back, every other triangle
 * is final.  Each window is thus a decimation of a piece of the surface
 * whose cut is locked; the pieces fit as they did, and a closed, oriented
 * 2-manifold stays one, components and genus included (decimate.c's link
 * condition, within the piece).
 *
 * Targets.  Each window aims at the running total: ratio of the stream's
 * triangles so far, counting the triangles at the new top plane (which the
 * window cannot touch) as they are, so that the next window, where they are
 * free, reduces them.  A triangle target needs the stream's count (an
 * earlier pass over a spool of it: isomend_decimate_stream_expect()); the
 * running total is then target * (triangles so far) / count, so the last
 * window aims at the target itself.  That gives each stretch of the surface
 * its triangles' share of the target, where the decimation in memory gives
 * it what its costs ask for: a stretch that needs more than its share (a
 * padded cap's rim, a busier part of the surface) can only take it from
 * the triangles still held.  With a band of 3 rings, the last window, a
 * padded volume's top cap and a few rings, had to make up the whole top's
 * shortfall at 2 %: collapses up to 16 x the largest error in memory (and
 * the count missed).  So with a ratio or a target the band also holds, ring
 * by ring, the triangles made within YOUNG_LAYERS layers of the top plane,
 * up to a layer's worth of the chunk's triangles (at 2 % some 50 layers of
 * the decimated surface): the next window decimates them again with its
 * chunk, cheapest first, so the budget moves across the seam
 * (docs/postprocess.md, "Streamed decimation").  Beyond the band's reach a
 * stretch keeps its share: the error follows the surface's busyness there.
 * Not with max_error (the band's carried points would be checked again in
 * every window) nor on chunks of 1 layer (it would double the window).
 *
 * Maximum error.  decimate.c keeps every point a vertex stands for within
 * max_error of the triangles around it.  In a window, a chunk's vertex
 * stands for itself (its stream position); a held vertex for the stream
 * vertices collapsed into it in earlier windows, carried from window to
 * window (an arena of points, the slot's own bytes say where) less those
 * already within max_error of its final triangles (which never change: a
 * final triangle's vertices are final or locked in every later window).
 * So at the start of a window every point carried by a vertex lies within
 * max_error of its triangles in the window, as decimate.c's check assumes,
 * and every stream vertex stays within max_error of the written surface,
 * as in memory.
 *
 * Quadrics.  A held vertex keeps its quadric (decimate_carry, the slot's
 * own bytes): the planes of every stream triangle it stands for, so that
 * the next window costs its collapses as one decimation of the whole mesh
 * would; only the chunk's new triangles add planes.
 *
 * The distance from each stream vertex to the result is measured per chunk,
 * MEASURE_LAYERS layers later, against the surface as it then stands near it
 * (the final triangles of the windows since the one before the chunk's, and
 * the band still held): the held band may still change, so this is a
 * measurement of the surface at that time, which tests compare with the
 * distance to the written mesh.
 */
#include "mesh_internal.h"
#include "stream_window.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The held band: triangles within this many rings (edges) of the top
 * plane's vertices; with a ratio or a target (no max_error, chunks of more
 * than 1 layer), up to MORE_RINGS rings beyond
 * of triangles made within YOUNG_LAYERS layers of the top plane, while
 * those add at most a layer's worth of the chunk's triangles (the budget's
 * band: see "Targets" above). */
#define RINGS 3
#define MORE_RINGS   (STREAM_WINDOW_MAX_RINGS - RINGS)
#define YOUNG_LAYERS 64
/* A chunk's vertices are measured once this many more layers are done (the
 * held band, re-decimated window after window, is final by then: it holds
 * nothing made more than YOUNG_LAYERS below the top plane beyond its 3
 * rings), and at least 2 windows. */
#define MEASURE_LAYERS         (YOUNG_LAYERS + 16)
#define MEASURE_LAYERS_SHALLOW 48 /* the same for a band of 3 rings only */
/* The memory estimate (isomend_decimate_stream_memory(), calibrated against
 * isomend_decimate_stream_peak_bytes(): docs/postprocess.md, "Streamed
 * decimation's memory"), on a surface of TRIANGLES_PER_SAMPLE stream
 * triangles a marched sample (a 256^3 gyroid), whose padded caps have
 * CAP_TRIANGLES_PER_SAMPLE (half the slice inside):
 *   - a window's triangle, BYTES_PER_TRIANGLE: its ids in the chunk, the
 *     stream's positions, its vertices' slots and id table (grown by
 *     doubling and kept), the window's mesh, decimate.c's tables and
 *     candidates, the result (measured: 340 to 441 bytes for K = 1 to 64 on
 *     gyroids and smoothed noise); the window is the chunk, the band and the
 *     deeper band's layer (K + 2 layers), or at a padded end the cap and 2
 *     layers;
 *   - the measurement: the stream's positions of the chunks waiting for it
 *     (MEASURE_BYTES_PER_TRIANGLE: 12 bytes a vertex, one every 2 triangles)
 *     and the final triangles of the windows it measures against
 *     (MEASURE_BYTES_PER_FINAL: 36 bytes each, doubled, and at a measurement
 *     their copy and distance.c's grid), a share of the stream's triangles:
 *     the ratio, or KEPT_UNKNOWN where a max_error or a target decides;
 *   - 1 MiB. */
#define BYTES_PER_TRIANGLE         512.0
#define TRIANGLES_PER_SAMPLE 0.25
#define CAP_TRIANGLES_PER_SAMPLE   1.0
#define MEASURE_BYTES_PER_TRIANGLE 6.0
#define MEASURE_BYTES_PER_FINAL    240.0
#define KEPT_UNKNOWN               0.25

/* A slot's own bytes: a held vertex's quadric, its triangles' planes so far;
 * with max_error the stream vertices it stands for (points of the arena), or
 * itself when it is a chunk's vertex not yet in a window (fresh). */
typedef struct carried {
    double q[10];
    uint32_t pts_first, npts;
    uint32_t fresh;
} carried;

/* Floats x 9 (a triangle's corners), growable. */
typedef struct soup {
    float *p;
    size_t n, cap;
} soup;

/* A chunk's stream vertices (their positions), waiting to be measured. */
typedef struct measured {
    float *p;
    size_t n;
} measured;

struct isomend_decimate_stream {
    stream_window *w;
    double ratio;
    uint64_t target;  /* target_triangles, 0: none                      */
    int counted;      /* the stream's triangle count is known:          */
    uint64_t count;   /* isomend_decimate_stream_expect()               */
    uint64_t goal;    /* then the final target: max(ratio, target)      */
    double max_error; /* 0: none                                        */
    int64_t K;
    double *q_out;      /* the last window's quadrics out (decimate_carry) */
    /* max_error: the held vertices' points (the arena), and the window's
     * points in and out (decimate_carry) until its result is taken */
    float *pts;
    float *wpts;
    uint32_t *wfirst, *pts_out, *pts_out_first;
    uint64_t own_first; /* first id of the chunk's own vertices           */
    /* their bytes, counted in the window's tally (mem_tally.h): q_out; the
     * arena; the window's points in and out */
    uint64_t q_bytes, pts_bytes, wpts_bytes;

    /* measuring */
    int lag;          /* windows before a chunk is measured  */
    measured *pend;   /* lag + 1: chunks not yet measured, oldest first */
    int npend;
    soup *soup;       /* lag + 2: final triangles of the last windows */
    double err_max, err_sum;
    uint64_t err_n;

    isomend_decimate_report rep;
};

/* ------------------------------------------------------------------ measuring */

/* The distance from pts to the final triangles of the kept windows. */
static isomend_status measure(isomend_decimate_stream *d, const measured *m)
{
    if (!m->n)
        return ISOMEND_OK;
    size_t nheld;
    const uint32_t *h = stream_window_held(d->w, &nheld); /* the band still held, as it stands */
    size_t nt = nheld;
    for (int j = 0; j < d->lag + 2; j++)
        nt += d->soup[j].n;
    if (!nt)
        return ISOMEND_OK; /* nothing final near them: no surface left */
    float *pos = malloc(nt * 36);
    uint32_t *tri = malloc(nt * 12);
    if (!pos || !tri) {
        free(pos);
        free(tri);
        return stream_window_fail(d->w, ISOMEND_ERR_OUT_OF_MEMORY);
    }
    size_t at = 0;
    for (int j = 0; j < d->lag + 2; j++) {
        if (d->soup[j].n)
            memcpy(pos + 9 * at, d->soup[j].p, d->soup[j].n * 36);
        at += d->soup[j].n;
    }
    for (size_t t = 0; t < nheld; t++, at++)
        for (int k = 0; k < 3; k++)
            memcpy(pos + 9 * at + 3 * k, stream_window_pos(d->w, h[3 * t + (size_t)k]), 12);
    for (size_t i = 0; i < 3 * nt; i++)
        tri[i] = (uint32_t)i;
    double mx = 0, mean = 0;
    uint64_t dist_bytes = 0;
    const int ok = mesh_distances(m->p, m->n, pos, tri, nt, NULL, &mx, &mean, &dist_bytes);
    mem_tally_spike(stream_window_tally(d->w), 48 * (uint64_t)nt + dist_bytes);
    free(pos);
    free(tri);
    if (!ok)
        return stream_window_fail(d->w, ISOMEND_ERR_OUT_OF_MEMORY);
    d->err_max = mx > d->err_max ? mx : d->err_max;
    d->err_sum += mean * (double)m->n;
    d->err_n += m->n;
    return ISOMEND_OK;
}

/* The oldest waiting chunk measured and dropped. */
static isomend_status measure_oldest(isomend_decimate_stream *d)
{
    isomend_status st = measure(d, &d->pend[0]);
    mem_tally_sub(stream_window_tally(d->w), 12 * (uint64_t)d->pend[0].n + 1);
    free(d->pend[0].p);
    memmove(d->pend, d->pend + 1, (size_t)(d->npend - 1) * sizeof d->pend[0]);
    d->npend--;
    d->pend[d->npend].p = NULL;
    d->pend[d->npend].n = 0;
    return st;
}

/* ------------------------------------------------------------------ the window's hooks */

/* The points window w's vertices stand for (max_error): a fresh vertex's
 * own, a held one's from the arena; into carry (d->wpts, d->wfirst).  0
 * without memory. */
static int window_points(isomend_decimate_stream *d, stream_window *sw, const stream_window_mesh *w,
                         decimate_carry *carry)
{
    const size_t nv = w->m->nv;
    size_t total = 0;
    for (size_t v = 0; v < nv; v++) {
        const carried *c = stream_window_data(sw, w->slot[v]);
        total += c->fresh ? 1 : c->npts;
    }
    if (total >= UINT32_MAX)
        return 0;
    d->wfirst = malloc((nv + 1) * sizeof *d->wfirst);
    d->wpts = malloc((total + 1) * 12);
    if (!d->wfirst || !d->wpts)
        return 0;
    d->wpts_bytes = ((uint64_t)nv + 1) * sizeof *d->wfirst + ((uint64_t)total + 1) * 12;
    mem_tally_add(stream_window_tally(sw), d->wpts_bytes);
    uint32_t at = 0;
    for (size_t v = 0; v < nv; v++) {
        const carried *c = stream_window_data(sw, w->slot[v]);
        d->wfirst[v] = at;
        if (c->fresh) { /* a chunk's vertex, at its stream position */
            memcpy(d->wpts + 3 * (size_t)at, w->m->pos + 3 * v, 12);
            at++;
        } else if (c->npts) {
            memcpy(d->wpts + 3 * (size_t)at, d->pts + 3 * (size_t)c->pts_first,
                   12 * (size_t)c->npts);
            at += c->npts;
        }
    }
    d->wfirst[nv] = at;
    carry->pts = d->wpts;
    carry->pts_first = d->wfirst;
    return 1;
}

/* The window's points that still need carrying (max_error): those of r's
 * vertices with a held triangle that lie farther than max_error from the
 * vertex's final triangles in r, in a new arena; the other points are within
 * it of a triangle that never changes.  0 without memory. */
static int keep_points(isomend_decimate_stream *d, stream_window *sw, const isomend_mesh *r,
                       const uint32_t *slot, const uint8_t *fin)
{
    const size_t rv = r->nv, rt = r->nt;
    uint8_t *held = calloc(rv + 1, 1);
    uint32_t *first = calloc(rv + 2, sizeof *first), *tris = NULL;
    float *arena = malloc(((size_t)d->pts_out_first[rv] + 1) * 12);
    if (!held || !first || !arena)
        goto oom;
    for (size_t t = 0; t < rt; t++)
        if (!fin[t])
            for (int k = 0; k < 3; k++)
                held[r->tri[3 * t + (size_t)k]] = 1;
    /* the final triangles around each vertex with a held one */
    for (size_t t = 0; t < rt; t++)
        for (int k = 0; fin[t] && k < 3; k++)
            first[r->tri[3 * t + (size_t)k] + 1] += held[r->tri[3 * t + (size_t)k]];
    for (size_t v = 0; v < rv; v++)
        first[v + 1] += first[v];
    tris = malloc(((size_t)first[rv] + 1) * sizeof *tris);
    if (!tris)
        goto oom;
    {
        /* the new arena beside the old, with this scratch */
        mem_tally *t = stream_window_tally(sw);
        const uint64_t arena_bytes = ((uint64_t)d->pts_out_first[rv] + 1) * 12;
        mem_tally_add(t, arena_bytes);
        mem_tally_spike(t, rv + 1 + (rv + 2) * sizeof *first +
                               ((uint64_t)first[rv] + 1) * sizeof *tris);
        mem_tally_sub(t, d->pts_bytes);
        d->pts_bytes = arena_bytes;
    }
    for (size_t t = 0; t < rt; t++)
        for (int k = 0; fin[t] && k < 3; k++) {
            const uint32_t v = r->tri[3 * t + (size_t)k];
            if (held[v])
                tris[first[v]++] = (uint32_t)t;
        }
    for (size_t v = rv; v > 0; v--)
        first[v] = first[v - 1];
    first[0] = 0;
    /* the kept points, into the new arena */
    const double limit = d->max_error * d->max_error;
    uint32_t at = 0;
    for (size_t v = 0; v < rv; v++) {
        carried *c = stream_window_data(sw, slot[v]);
        c->fresh = 0;
        c->pts_first = at;
        c->npts = 0;
        if (!held[v])
            continue; /* all its triangles final: its points within max_error of them */
        for (uint32_t i = d->pts_out_first[v]; i < d->pts_out_first[v + 1]; i++) {
            const float *pf = d->wpts + 3 * (size_t)d->pts_out[i];
            const double p[3] = {pf[0], pf[1], pf[2]};
            double best = INFINITY;
            for (uint32_t j = first[v]; j < first[v + 1] && best > limit; j++) {
                double q[3][3];
                for (int k = 0; k < 3; k++)
                    for (int x = 0; x < 3; x++)
                        q[k][x] =
                            r->pos[3 * (size_t)r->tri[3 * (size_t)tris[j] + (size_t)k] + (size_t)x];
                const double e = point_triangle_distance2(p, q[0], q[1], q[2]);
                best = e < best ? e : best;
            }
            if (best > limit) {
                memcpy(arena + 3 * (size_t)at, pf, 12);
                at++;
                c->npts++;
            }
        }
    }
    free(d->pts);
    d->pts = arena;
    free(held);
    free(first);
    free(tris);
    return 1;
oom:
    free(held);
    free(first);
    free(tris);
    free(arena);
    return 0;
}

static void window_points_free(isomend_decimate_stream *d)
{
    if (d->w)
        mem_tally_sub(stream_window_tally(d->w), d->wpts_bytes);
    d->wpts_bytes = 0;
    free(d->wpts);
    free(d->wfirst);
    free(d->pts_out);
    free(d->pts_out_first);
    d->wpts = NULL;
    d->wfirst = d->pts_out = d->pts_out_first = NULL;
}

/* Window w decimated to the running total, its vertices' quadrics carried in
 * and out. */
static isomend_status decimate_window(void *user, stream_window *sw, const stream_window_mesh *w,
                                      isomend_mesh **r, uint32_t **kept)
{
    isomend_decimate_stream *d = user;
    /* a new soup for this window's final triangles; the oldest is dropped */
    soup old = d->soup[d->lag + 1];
    memmove(d->soup + 1, d->soup, (size_t)(d->lag + 1) * sizeof d->soup[0]);
    d->soup[0] = old;
    d->soup[0].n = 0;
    mem_tally *tally = stream_window_tally(sw);
    mem_tally_sub(tally, d->q_bytes);
    d->q_bytes = 0;
    free(d->q_out);
    d->q_out = NULL;
    window_points_free(d);

    /* the running total at ratio, the new top plane's triangles as they are */
    uint64_t n_top = 0;
    for (size_t t = 0; t < w->nchunk; t++) {
        int top = 0;
        for (int k = 0; k < 3; k++) {
            const uint64_t id = w->chunk[3 * t + (size_t)k];
            top |= id >= w->top_lo && id < w->top_hi;
        }
        n_top += (uint64_t)top;
    }
    const stream_window_counts n = stream_window_counts_of(sw);
    const size_t nv = w->m->nv, nt = w->m->nt;
    if (d->target && !d->counted)
        return ISOMEND_ERR_INVALID_ARGUMENT; /* a triangle target without the count */
    const double ratio =
        d->counted ? (d->count ? (double)d->goal / (double)d->count : 1.0) : d->ratio;
    const double so_far = (double)(n.triangles_in - n_top);
    const double keep =
        (d->counted ? ceil((double)d->goal * so_far / (double)(d->count ? d->count : 1))
                    : ceil(ratio * so_far)) +
        (double)n_top;
    double target = keep - (double)n.final_triangles;
    const double least = ceil(0.5 * ratio * (double)nt);
    target = target < least ? least : target;
    /* the held vertices' quadrics carry the planes of their earlier triangles
     * (the held ones' included); the chunk's triangles add theirs */
    double *q_in = malloc((10 * nv + 1) * sizeof *q_in);
    if (!q_in)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    mem_tally_add(tally, (10 * (uint64_t)nv + 1) * sizeof *q_in);
    for (size_t v = 0; v < nv; v++)
        memcpy(q_in + 10 * v, ((const carried *)stream_window_data(sw, w->slot[v]))->q,
               10 * sizeof(double));
    decimate_carry carry = {q_in, w->nheld, NULL, NULL, NULL, NULL, NULL, NULL, 0};
    isomend_status st = ISOMEND_OK;
    if (d->max_error > 0 && !window_points(d, sw, w, &carry))
        st = ISOMEND_ERR_OUT_OF_MEMORY;
    if (nt && st == ISOMEND_OK) {
        isomend_decimate_report wr;
        st = mesh_decimate_to(w->m, (uint64_t)target, d->max_error, 0, r, kept, &carry, &wr);
        /* its tables and outputs; the window counts the mesh and kept */
        mem_tally_spike(tally, carry.peak_bytes);
        if (st == ISOMEND_OK) {
            const uint64_t nvo = (*r)->nv;
            d->q_bytes = 80 * (nvo + 1);
            const uint64_t pb =
                carry.pts_out ? 4 * ((uint64_t)carry.pts_first[nv] + 1 + nvo + 1) : 0;
            mem_tally_add(tally, d->q_bytes + pb);
            d->wpts_bytes += pb;
            d->rep.collapses += wr.collapses;
            d->rep.refused_topology += wr.refused_topology;
            d->rep.refused_geometry += wr.refused_geometry;
            d->rep.refused_error += wr.refused_error;
            d->rep.locked_vertices += wr.locked_vertices;
        }
    }
    free(q_in);
    mem_tally_sub(tally, (10 * (uint64_t)nv + 1) * sizeof *q_in);
    d->q_out = carry.q_out;
    d->pts_out = carry.pts_out;
    d->pts_out_first = carry.pts_out_first;
    return st;
}

/* Every kept vertex takes its position and quadric from the result. */
static void take_result(void *user, stream_window *sw, const isomend_mesh *r, const uint32_t *slot,
                        const uint8_t *fin)
{
    isomend_decimate_stream *d = user;
    for (size_t v = 0; v < r->nv; v++) {
        memcpy(stream_window_pos(sw, slot[v]), r->pos + 3 * v, 12);
        memcpy(((carried *)stream_window_data(sw, slot[v]))->q, d->q_out + 10 * v,
               10 * sizeof(double));
    }
    if (d->max_error > 0 && !keep_points(d, sw, r, slot, fin))
        (void)stream_window_fail(sw, ISOMEND_ERR_OUT_OF_MEMORY);
    window_points_free(d);
}

/* A slot made for a chunk's vertex stands for itself. */
static void made_slot(void *user, void *data, const float *p)
{
    (void)user;
    (void)p;
    ((carried *)data)->fresh = 1;
}

/* A final triangle counts for the measurement of its window. */
static int count_final(void *user, stream_window *sw, const uint32_t *t)
{
    isomend_decimate_stream *d = user;
    soup *s = &d->soup[0];
    if (s->n == s->cap) {
        const size_t cap = s->cap ? 2 * s->cap : 256;
        float *p = realloc(s->p, cap * 36);
        if (!p)
            return 0;
        mem_tally_grow(stream_window_tally(sw), 36 * (uint64_t)s->cap, 36 * (uint64_t)cap);
        s->p = p;
        s->cap = cap;
    }
    float *f = s->p + 9 * s->n++;
    for (int k = 0; k < 3; k++)
        memcpy(f + 3 * k, stream_window_pos(sw, t[k]), 3 * sizeof(float));
    return 1;
}

/* The chunk's own stream vertices wait to be measured; the oldest chunk is
 * measured once lag windows are done. */
static isomend_status measure_chunk(void *user, stream_window *sw)
{
    isomend_decimate_stream *d = user;
    const uint64_t next_id = stream_window_counts_of(sw).vertices_in;
    measured *pm = &d->pend[d->npend++];
    pm->n = (size_t)(next_id - d->own_first);
    pm->p = malloc(pm->n * 12 + 1);
    if (!pm->p)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    mem_tally_add(stream_window_tally(sw), 12 * (uint64_t)pm->n + 1);
    if (pm->n)
        memcpy(pm->p, stream_window_raw(sw, d->own_first), pm->n * 12);
    d->own_first = next_id;
    if (d->npend > d->lag)
        return measure_oldest(d);
    return ISOMEND_OK;
}

/* ------------------------------------------------------------------ the API */

static int plane_of(const isomend_volume *desc, const isomend_options *opts, double *plane)
{
    if (!desc || isomend_stream_memory(desc, opts) == 0)
        return 0;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const int pad = ((opts ? opts : &defaults)->flags & ISOMEND_FLAG_PAD) != 0;
    *plane = (double)(desc->dims[0] + 2 * pad) * (double)(desc->dims[1] + 2 * pad);
    return 1;
}

/* The share of the stream's triangles the windows keep, for the estimate:
 * the ratio, unless a max_error or a target may keep more. */
static double kept_share(const isomend_decimate_options *dopts)
{
    if (!dopts)
        return 1.0;
    const double r = dopts->ratio > 0 && dopts->ratio <= 1 ? dopts->ratio : 0.0;
    if (dopts->max_error > 0 || dopts->target_triangles || r == 0)
        return r > KEPT_UNKNOWN ? r : KEPT_UNKNOWN;
    return r;
}

/* The estimate for K layers a chunk (the memory estimate's terms above). */
static double estimate(double plane, int pad, const isomend_decimate_options *dopts, int64_t K)
{
    const double T = plane * TRIANGLES_PER_SAMPLE, k = (double)K;
    double window = (k + 2.0) * T;
    if (pad && CAP_TRIANGLES_PER_SAMPLE * plane + 2.0 * T > window)
        window = CAP_TRIANGLES_PER_SAMPLE * plane + 2.0 * T;
    /* the deeper band (isomend_decimate_stream_begin) measures later */
    const int deep =
        K > 1 &&
        (!dopts || ((dopts->ratio > 0 || dopts->target_triangles) && dopts->max_error == 0));
    double lag = ceil((double)(deep ? MEASURE_LAYERS : MEASURE_LAYERS_SHALLOW) / k);
    lag = lag < 2 ? 2 : lag;
    const double measure = T * k *
                           (MEASURE_BYTES_PER_TRIANGLE * lag +
                            kept_share(dopts) * MEASURE_BYTES_PER_FINAL * (lag + 2.0));
    return window * BYTES_PER_TRIANGLE + measure + 1048576.0;
}

static int pad_of(const isomend_options *opts)
{
    return opts && (opts->flags & ISOMEND_FLAG_PAD) != 0;
}

int64_t isomend_decimate_stream_layers(const isomend_volume *desc, const isomend_options *opts,
                                       const isomend_decimate_options *dopts, uint64_t max_bytes)
{
    double plane;
    if (!plane_of(desc, opts, &plane))
        return 0;
    double k = floor(4194304.0 / plane);
    k = k < 4 ? 4 : k > 64 ? 64 : k;
    if (max_bytes) {
        /* the most layers whose estimate fits (it grows with K): 1 at least */
        int64_t fit = 1;
        while ((double)fit < k &&
               estimate(plane, pad_of(opts), dopts, fit + 1) <= (double)max_bytes)
            fit++;
        k = (double)fit;
    }
    return (int64_t)k;
}

uint64_t isomend_decimate_stream_memory(const isomend_volume *desc, const isomend_options *opts,
                                        const isomend_decimate_options *dopts, int64_t chunk_layers)
{
    double plane;
    if (!plane_of(desc, opts, &plane) || chunk_layers < 0)
        return 0;
    if (chunk_layers == 0)
        chunk_layers = isomend_decimate_stream_layers(desc, opts, dopts, 0);
    const double bytes = estimate(plane, pad_of(opts), dopts, chunk_layers);
    return bytes < 1.8e19 ? (uint64_t)bytes : UINT64_MAX;
}

isomend_status isomend_decimate_stream_begin(const isomend_volume *desc,
                                             const isomend_options *opts,
                                             const isomend_decimate_options *dopts,
                                             int64_t chunk_layers, const isomend_mesh_sink *out,
                                             isomend_decimate_stream **ds)
{
    if (!ds)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *ds = NULL;
    double plane;
    if (!dopts || !out || !out->vertices || !out->triangles || !out->retire || chunk_layers < 0 ||
        !(dopts->ratio >= 0.0 && dopts->ratio <= 1.0) || !(dopts->max_error >= 0.0) ||
        !isfinite(dopts->max_error) ||
        (dopts->ratio == 0.0 && dopts->target_triangles == 0 && dopts->max_error == 0.0))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (!plane_of(desc, opts, &plane))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_decimate_stream *d = calloc(1, sizeof *d);
    if (!d)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    isomend_options defaults;
    isomend_options_init(&defaults);
    d->ratio = dopts->ratio;
    d->target = dopts->target_triangles;
    d->max_error = dopts->max_error;
    d->K = chunk_layers ? chunk_layers : isomend_decimate_stream_layers(desc, opts, dopts, 0);
    /* the deeper band: for a ratio or a target, not on chunks of 1 layer, not
     * with max_error (its carried points made a window's checks 3 to 7 x
     * slower: docs/postprocess.md) */
    const int deep = (d->ratio > 0 || d->target) && d->K > 1 && d->max_error == 0;
    d->lag = (int)(((deep ? MEASURE_LAYERS : MEASURE_LAYERS_SHALLOW) + d->K - 1) / d->K);
    d->lag = d->lag < 2 ? 2 : d->lag;
    d->pend = calloc((size_t)d->lag + 1, sizeof *d->pend);
    d->soup = calloc((size_t)d->lag + 2, sizeof *d->soup);
    const stream_window_client client = {.user = d,
                                         .data_bytes = sizeof(carried),
                                         .band = RINGS,
                                         .more = deep ? MORE_RINGS : 0,
                                         .young = YOUNG_LAYERS,
                                         .made = made_slot,
                                         .process = decimate_window,
                                         .settle = take_result,
                                         .final = count_final,
                                         .done = measure_chunk};
    const int normals = !((opts ? opts : &defaults)->flags & ISOMEND_FLAG_NO_NORMALS);
    if (!d->pend || !d->soup ||
        stream_window_begin(&client, out, normals, d->K, &d->w) != ISOMEND_OK) {
        isomend_decimate_stream_destroy(d);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    mem_tally_add(stream_window_tally(d->w), sizeof *d + ((uint64_t)d->lag + 1) * sizeof *d->pend +
                                                 ((uint64_t)d->lag + 2) * sizeof *d->soup);
    *ds = d;
    return ISOMEND_OK;
}

isomend_status isomend_decimate_stream_sink(isomend_decimate_stream *d, isomend_mesh_sink *sink)
{
    if (!d || !sink)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    stream_window_sink(d->w, sink);
    return ISOMEND_OK;
}

isomend_status isomend_decimate_stream_expect(isomend_decimate_stream *d, uint64_t triangles)
{
    if (!d || d->counted || stream_window_counts_of(d->w).triangles_in != 0)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    d->counted = 1;
    d->count = triangles;
    const double by_ratio = ceil(d->ratio * (double)triangles);
    d->goal = by_ratio > (double)d->target ? (uint64_t)by_ratio : d->target;
    return ISOMEND_OK;
}

isomend_status isomend_decimate_stream_finish(isomend_decimate_stream *d,
                                              isomend_decimate_report *report)
{
    if (report)
        memset(report, 0, sizeof *report);
    if (!d)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    /* a last window also for stream vertices still to be measured */
    const uint64_t next_id = stream_window_counts_of(d->w).vertices_in;
    (void)stream_window_finish(d->w, d->own_first < next_id);
    while (stream_window_status(d->w) == ISOMEND_OK && d->npend)
        (void)measure_oldest(d);
    isomend_status st = stream_window_close(d->w);
    const stream_window_counts n = stream_window_counts_of(d->w);
    if (st == ISOMEND_OK && d->counted && n.triangles_in != d->count) /* not the stream expected */
        st = stream_window_fail(d->w, ISOMEND_ERR_INVALID_ARGUMENT);
    if (st != ISOMEND_OK)
        return st;
    isomend_decimate_report *r = &d->rep;
    r->triangles_before = n.triangles_in;
    r->triangles_after = n.triangles_out;
    r->vertices_before = n.vertices_in;
    r->vertices_after = n.vertices_out;
    r->target_triangles = d->counted ? d->goal : (uint64_t)ceil(d->ratio * (double)n.triangles_in);
    r->reached = r->triangles_after <= r->target_triangles;
    r->max_error = d->err_max;
    r->mean_error = d->err_n ? d->err_sum / (double)d->err_n : 0.0;
    if (report)
        *report = *r;
    return ISOMEND_OK;
}

uint64_t isomend_decimate_stream_peak_bytes(const isomend_decimate_stream *d)
{
    return d ? stream_window_peak_bytes(d->w) : 0;
}

void isomend_decimate_stream_destroy(isomend_decimate_stream *d)
{
    if (!d)
        return;
    free(d->q_out);
    free(d->pts);
    window_points_free(d);
    stream_window_destroy(d->w);
    for (int j = 0; d->pend && j < d->lag + 1; j++)
        free(d->pend[j].p);
    for (int j = 0; d->soup && j < d->lag + 2; j++)
        free(d->soup[j].p);
    free(d->pend);
    free(d->soup);
    free(d);
}
