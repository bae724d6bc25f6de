/*
 * largest_stream.c - --largest K (with --min-component N) on a streamed
 * mesh, in two passes over the same stream: isomend_largest_stream_*().
 *
 * Every component's size is needed before anything is written, so the
 * caller plays the stream twice (isomend-mpi's rank 0 and `isomend extract`
 * replay a scratch spool of it).  Both passes run the frontier union-find
 * of stream_components.c, as clean_stream.c does: each live vertex (an id at or above the
 * last retire floor, used by a triangle) points to a component record, a
 * triangle joins its vertices' records (union by size), and a record with
 * no live vertex left after a retire is a closed component.
 *
 * Identity.  A triangle must be passed or dropped in the second pass long
 * before its component closes, while it is only a piece of it (two legs
 * that meet higher up are two pieces until they do).  So pieces get seeds:
 * at each retire, every root that has none (born since the last retire, not
 * joined to an older piece) gets the next seed number, in the order of its
 * first triangle; when two seeded pieces join, the smaller seed stays and
 * the first pass notes parent[larger] = smaller.  A seed's chain of parents
 * ends at its component's smallest seed, the component's key.  Seeds,
 * joins and closes depend on the stream's triangles and floors only, so the
 * second pass assigns every piece the first pass's seed.
 *
 * Pass 1 counts: at each close, a component of at least min_triangles
 * triangles is recorded (its triangles, first triangle, key).  Then
 * isomend_largest_stream_replay() sorts them as isomend_mesh_clean() does
 * (more triangles first; ties: the first triangle first), keeps keep_largest
 * of them (0: all), and turns parent[] into one bit a seed: its component
 * is kept (seeds in increasing order; a parent is always smaller).
 * Pass 2 filters: a triangle whose piece has a seed passes or goes at once
 * by its bit; one whose piece has none yet (born since the last retire) is
 * held until that retire gives it one (or it joins a seeded piece).
 *
 * Output (pass 2) as clean_stream.c's: vertices numbered from 0 in the
 * order a passed triangle first uses them, delivered just before it with
 * the normal they came with; triangles in stream order but for held ones,
 * which pass at the retire that seeds them (in stream order); no origins;
 * one retire() for each of the stream's, the floor the smallest output id
 * of a vertex still live.  The triangles kept are exactly
 * isomend_mesh_clean(mesh, min_triangles, keep_largest)'s, the report's
 * counts its.
 *
 * Memory: the live vertices and records (O(slice)), the triangles of one
 * layer held in pass 2, and per seed 8 bytes in pass 1 (its parent) and one
 * bit in pass 2, per recorded component 24 bytes: a seed is a piece of
 * surface that starts (a z minimum: a component, a leg, a bubble's bottom),
 * a few per component.
 */
#include "stream_components.h"

#include <stdlib.h>
#include <string.h>

#define NO_ID SC_NO_ID
#define BYTES_PER_HELD 40.0 /* a held triangle (pass 2: one layer), sc_memory */

typedef struct lcomp {
    uint64_t triangles, first, seed;
} lcomp;

/* A record's seed: NO_ID none yet; its pass: (pass 2, once seeded) its
 * component is kept. */
struct isomend_largest_stream {
    stream_components f;
    uint64_t min_tri, keep;
    int pass; /* 1 counting, 2 filtering, 3 finished */

    /* seeds */
    uint64_t nseeds;
    uint64_t *parent; /* pass 1 */
    size_t cap_parent;
    uint8_t *bits; /* pass 2: the seed's component is kept */
    lcomp *comps;  /* pass 1: the closed components of min_triangles */
    uint64_t kept_triangles; /* the kept components' (after the replay)  */
    size_t ncomps, cap_comps;
    uint32_t *fresh; /* a retire's roots without a seed */
    size_t cap_fresh;

    /* pass 1's totals, checked against pass 2's */
    uint64_t vertices1, triangles1, seeds1;

    isomend_clean_report rep;
};

/* Two pieces join: the smaller seed stays (pass 1 notes the larger's parent;
 * pass 2 refuses two verdicts for one component). */
static int merge_seeds(void *user, sc_rec *A, const sc_rec *B)
{
    isomend_largest_stream *c = user;
    if (A->seed != NO_ID && B->seed != NO_ID) {
        const uint64_t lo = A->seed < B->seed ? A->seed : B->seed;
        const uint64_t hi = A->seed < B->seed ? B->seed : A->seed;
        if (c->pass == 1)
            c->parent[hi] = lo;
        else if (A->pass != B->pass)
            return 0; /* one component, two verdicts: not the same stream */
        A->seed = lo;
    } else if (B->seed != NO_ID) {
        A->seed = B->seed;
        A->pass = B->pass;
    }
    return 1;
}

/* Pass 1: a closed component of min_triangles is recorded. */
static int close_component(void *user, uint32_t r)
{
    isomend_largest_stream *c = user;
    const sc_rec *R = &c->f.recs[r];
    if (c->pass != 1)
        return 1;
    c->rep.components_before++;
    if (R->triangles >= c->min_tri) {
        if (!sc_grow((void **)&c->comps, &c->cap_comps, c->ncomps + 1, sizeof *c->comps))
            return 0;
        c->comps[c->ncomps++] = (lcomp){R->triangles, R->first, R->seed};
    }
    return 1;
}

/* ------------------------------------------------------------------ the stream's sink */

static int on_vertices(void *user, uint64_t first, size_t count, const float *pos, const float *nrm,
                       const uint64_t *keys)
{
    (void)keys;
    isomend_largest_stream *c = user;
    if (c->f.status != ISOMEND_OK)
        return 1;
    if (c->pass > 2)
        return sc_fail(&c->f, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    const isomend_status st = sc_vertices(&c->f, first, count, pos, nrm);
    return st != ISOMEND_OK ? (sc_fail(&c->f, st), 1) : 0;
}

static int on_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    (void)origins;
    isomend_largest_stream *c = user;
    if (c->f.status != ISOMEND_OK)
        return 1;
    if (c->pass > 2)
        return sc_fail(&c->f, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    stream_components *f = &c->f;
    for (size_t t = 0; t < count; t++) {
        uint32_t s[3], root;
        const isomend_status st = sc_triangle(f, ids + 3 * t, s, &root, merge_seeds, c);
        if (st != ISOMEND_OK)
            return sc_fail(&c->f, st), 1;
        int ok = 1;
        if (c->pass == 2) {
            if (f->recs[root].seed == NO_ID) {
                ok = sc_hold(f, root, s);
            } else {
                const int kept = f->recs[root].pass;
                ok = sc_release_held(f, root, kept) && (!kept || sc_emit(f, s));
            }
        }
        f->seq++;
        if (!ok)
            return sc_fail(&c->f, ISOMEND_ERR_OUT_OF_MEMORY), 1;
    }
    if (c->pass == 2 && !sc_flush(f))
        return sc_fail(&c->f, ISOMEND_ERR_SINK), 1;
    return 0;
}

/* The roots without a seed get the next ones, in the order of their first
 * triangle; in pass 2 their held triangles pass or go by their bits. */
static isomend_status seed_fresh(isomend_largest_stream *c)
{
    stream_components *f = &c->f;
    size_t nf = 0;
    for (size_t r = 0; r < f->nrecs; r++) {
        const sc_rec *R = &f->recs[r];
        if (R->used && R->parent == r && R->seed == NO_ID && R->triangles) {
            if (!sc_grow((void **)&c->fresh, &c->cap_fresh, nf + 1, sizeof *c->fresh))
                return sc_fail(&c->f, ISOMEND_ERR_OUT_OF_MEMORY);
            c->fresh[nf++] = (uint32_t)r;
        }
    }
    /* few: an insertion sort by first triangle */
    for (size_t i = 1; i < nf; i++) {
        const uint32_t x = c->fresh[i];
        size_t j = i;
        for (; j > 0 && f->recs[c->fresh[j - 1]].first > f->recs[x].first; j--)
            c->fresh[j] = c->fresh[j - 1];
        c->fresh[j] = x;
    }
    size_t n = 0;
    for (size_t i = 0; i < nf; i++) {
        sc_rec *R = &f->recs[c->fresh[i]];
        R->seed = c->nseeds++;
        if (c->pass == 1) {
            if (!sc_grow((void **)&c->parent, &c->cap_parent, (size_t)c->nseeds, sizeof *c->parent))
                return sc_fail(&c->f, ISOMEND_ERR_OUT_OF_MEMORY);
            c->parent[R->seed] = R->seed;
        } else {
            if (R->seed >= c->seeds1)
                return sc_fail(&c->f, ISOMEND_ERR_INVALID_ARGUMENT);
            R->pass = (c->bits[R->seed >> 3] >> (R->seed & 7)) & 1;
            if (!sc_collect_held(f, c->fresh[i], R->pass, &n))
                return sc_fail(&c->f, ISOMEND_ERR_OUT_OF_MEMORY);
        }
    }
    if (n && !sc_emit_sorted(f, n))
        return sc_fail(&c->f, ISOMEND_ERR_OUT_OF_MEMORY);
    return ISOMEND_OK;
}

/* The fresh roots seeded, the live vertices below floor leave, the
 * components without a live vertex close; then (forward, pass 2) retire()
 * on the output. */
static isomend_status retire_to(isomend_largest_stream *c, uint64_t floor, int forward)
{
    if (seed_fresh(c) != ISOMEND_OK)
        return c->f.status;
    const isomend_status st = sc_retire(&c->f, floor, close_component, c, c->pass == 2, forward);
    return st != ISOMEND_OK ? sc_fail(&c->f, st) : ISOMEND_OK;
}

static int on_retire(void *user, uint64_t floor)
{
    isomend_largest_stream *c = user;
    if (c->f.status != ISOMEND_OK)
        return 1;
    if (c->pass > 2 || floor < c->f.floor || floor > c->f.next_id)
        return sc_fail(&c->f, ISOMEND_ERR_INVALID_ARGUMENT), 1;
    return retire_to(c, floor, 1) != ISOMEND_OK;
}

/* ------------------------------------------------------------------ the API */

static int by_size(const void *x, const void *y)
{
    const lcomp *a = x, *b = y;
    if (a->triangles != b->triangles)
        return a->triangles > b->triangles ? -1 : 1;
    return a->first < b->first ? -1 : a->first > b->first;
}

uint64_t isomend_largest_stream_memory(const isomend_volume *desc, const isomend_options *opts)
{
    return sc_memory(desc, opts, 1.0, BYTES_PER_HELD, 4194304.0);
}

isomend_status isomend_largest_stream_begin(uint64_t min_triangles, uint64_t keep_largest,
                                            const isomend_mesh_sink *out,
                                            isomend_largest_stream **ls)
{
    if (!ls)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *ls = NULL;
    if (!out || !out->vertices || !out->triangles || !out->retire)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_largest_stream *c = calloc(1, sizeof *c);
    if (!c)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    sc_init(&c->f, out);
    c->min_tri = min_triangles;
    c->keep = keep_largest;
    c->pass = 1;
    *ls = c;
    return ISOMEND_OK;
}

isomend_status isomend_largest_stream_sink(isomend_largest_stream *c, isomend_mesh_sink *sink)
{
    if (!c || !sink)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *sink = (isomend_mesh_sink){c, on_vertices, on_triangles, on_retire, NULL};
    return ISOMEND_OK;
}

/* Closes what is still open and forgets the frontier. */
static void close_all(isomend_largest_stream *c)
{
    if (c->f.status == ISOMEND_OK && (c->f.floor < c->f.next_id || c->f.nlive))
        (void)retire_to(c, c->f.next_id, 0);
    else if (c->f.status == ISOMEND_OK)
        (void)seed_fresh(c);
}

isomend_status isomend_largest_stream_replay(isomend_largest_stream *c)
{
    if (!c)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (c->f.status == ISOMEND_OK && c->pass != 1)
        sc_fail(&c->f, ISOMEND_ERR_INVALID_ARGUMENT);
    close_all(c);
    if (c->f.status != ISOMEND_OK)
        return c->f.status;
    /* the kept components, isomend_mesh_clean()'s order */
    qsort(c->comps, c->ncomps, sizeof *c->comps, by_size);
    size_t kept = c->ncomps;
    if (c->keep && kept > c->keep)
        kept = (size_t)c->keep;
    c->rep.components_after = kept;
    c->bits = calloc((size_t)(c->nseeds / 8 + 1), 1);
    if (!c->bits)
        return sc_fail(&c->f, ISOMEND_ERR_OUT_OF_MEMORY);
    for (size_t i = 0; i < kept; i++) {
        c->bits[c->comps[i].seed >> 3] |= (uint8_t)(1u << (c->comps[i].seed & 7));
        c->kept_triangles += c->comps[i].triangles;
    }
    for (uint64_t s = 0; s < c->nseeds; s++) /* a parent is smaller: done already */
        if (c->parent[s] != s && (c->bits[c->parent[s] >> 3] >> (c->parent[s] & 7)) & 1)
            c->bits[s >> 3] |= (uint8_t)(1u << (s & 7));
    free(c->parent);
    free(c->comps);
    c->parent = NULL;
    c->comps = NULL;
    c->cap_parent = c->ncomps = c->cap_comps = 0;
    c->vertices1 = c->f.next_id;
    c->triangles1 = c->f.seq;
    c->seeds1 = c->nseeds;
    /* the frontier from scratch */
    sc_restart(&c->f);
    c->nseeds = 0;
    c->pass = 2;
    return ISOMEND_OK;
}

uint64_t isomend_largest_stream_kept_triangles(const isomend_largest_stream *c)
{
    return c && c->pass >= 2 ? c->kept_triangles : 0;
}

isomend_status isomend_largest_stream_finish(isomend_largest_stream *c,
                                             isomend_clean_report *report)
{
    if (report)
        memset(report, 0, sizeof *report);
    if (!c)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (c->f.status == ISOMEND_OK && c->pass != 2)
        sc_fail(&c->f, ISOMEND_ERR_INVALID_ARGUMENT);
    close_all(c);
    if (c->f.status == ISOMEND_OK && !sc_flush(&c->f))
        return sc_fail(&c->f, ISOMEND_ERR_SINK);
    /* the second stream must have been the first one again */
    if (c->f.status == ISOMEND_OK &&
        (c->f.next_id != c->vertices1 || c->f.seq != c->triangles1 || c->nseeds != c->seeds1))
        sc_fail(&c->f, ISOMEND_ERR_INVALID_ARGUMENT);
    if (c->f.status != ISOMEND_OK)
        return c->f.status;
    c->pass = 3;
    c->rep.vertices_removed = c->vertices1 - c->f.out_next;
    c->rep.triangles_removed = c->triangles1 - c->f.triangles_out;
    if (report)
        *report = c->rep;
    return ISOMEND_OK;
}

void isomend_largest_stream_destroy(isomend_largest_stream *c)
{
    if (!c)
        return;
    sc_free(&c->f);
    free(c->parent);
    free(c->bits);
    free(c->comps);
    free(c->fresh);
    free(c);
}
