/*
 * mesh_build.c - what the post-processing steps (decimate.c, smooth.c,
 * components.c) share to make a new mesh from an old one: the frame it was
 * extracted in (the grid box and, for a grid with slice origins, the table
 * the check needs), normals from the triangles, which vertices may move, and
 * a loop split over threads (for work whose result does not depend on the
 * split).
 */
#include "cores.h"
#include "mesh_internal.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

isomend_status mesh_copy_frame(isomend_mesh *dst, const isomend_mesh *src)
{
    memcpy(dst->box, src->box, sizeof dst->box);
    dst->h[0] = src->h[0];
    dst->h[1] = src->h[1];
    memcpy(dst->N, src->N, sizeof dst->N);
    dst->slices = src->slices;
    dst->slices.so = NULL;
    if (!src->slices.so)
        return ISOMEND_OK;
    const size_t size = 3 * sizeof(double) * (size_t)src->slices.n;
    if (!(dst->slice_store = malloc(size)))
        return ISOMEND_ERR_OUT_OF_MEMORY;
    memcpy(dst->slice_store, src->slices.so, size);
    dst->slices.so = dst->slice_store;
    return ISOMEND_OK;
}

/*
 * Vertex normals as the area-weighted sums of the triangles' normals (the
 * right-hand normal of the winding, which isomend's normals agree with, with
 * or without ISOMEND_FLAG_FLIP), unit length; a vertex whose triangles have
 * no area keeps the normal in `keep` (if not NULL) or (0, 0, 1).
 */
void mesh_area_normals(isomend_mesh *m, const float *keep)
{
    double *acc = calloc(3 * (m->nv ? m->nv : 1), sizeof(double));
    float *n = m->nrm;
    if (!acc) { /* no memory for the sums: one float pass instead */
        memset(n, 0, 12 * m->nv);
    }
    for (size_t t = 0; t < m->nt; t++) {
        const uint32_t *v = m->tri + 3 * t;
        const float *p0 = m->pos + 3 * (size_t)v[0], *p1 = m->pos + 3 * (size_t)v[1],
                    *p2 = m->pos + 3 * (size_t)v[2];
        const double e1[3] = {(double)p1[0] - p0[0], (double)p1[1] - p0[1], (double)p1[2] - p0[2]};
        const double e2[3] = {(double)p2[0] - p0[0], (double)p2[1] - p0[1], (double)p2[2] - p0[2]};
        const double f[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                             e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++) {
                if (acc)
                    acc[3 * (size_t)v[k] + (size_t)c] += f[c];
                else
                    n[3 * (size_t)v[k] + (size_t)c] += (float)f[c];
            }
    }
    for (size_t v = 0; v < m->nv; v++) {
        double x[3];
        for (int c = 0; c < 3; c++)
            x[c] = acc ? acc[3 * v + (size_t)c] : n[3 * v + (size_t)c];
        const double len = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        for (int c = 0; c < 3; c++)
            n[3 * v + (size_t)c] = len > 0 && isfinite(len) ? (float)(x[c] / len)
                                   : keep              ? keep[3 * v + (size_t)c]
                                                       : (c == 2 ? 1.0f : 0.0f);
    }
    free(acc);
}

/* Whether the n corners of vertex v, given by the other two vertices of
 * each (next[i], prev[i] around its triangle), form one closed fan with
 * every edge used once each way: n >= 3, no repeated vertex in a triangle,
 * and the walk from corner 0 to the first corner whose next is this one's
 * prev visits all n corners once and comes back to corner 0.  The walk
 * alone proves each neighbour once a next and once a prev: of two corners
 * with the same next the walk reaches only the first, so it cannot visit
 * all n; and two corners with the same prev would have the same successor
 * on a cycle through distinct corners.  (Above 64 corners, where the mask
 * ends, each neighbour's uses are compared pairwise first.) */
static int one_fan(uint32_t v, const uint32_t *next, const uint32_t *prev, uint32_t n)
{
    if (n < 3)
        return 0;
    for (uint32_t i = 0; i < n; i++)
        if (next[i] == v || prev[i] == v || next[i] == prev[i])
            return 0;
    if (n > 64) {
        for (uint32_t i = 0; i < n; i++)
            for (uint32_t k = i + 1; k < n; k++)
                if (next[i] == next[k] || prev[i] == prev[k])
                    return 0;
        uint32_t i = 0, steps = 0;
        do {
            uint32_t k = 0;
            while (k < n && next[k] != prev[i])
                k++;
            if (k == n)
                return 0; /* a prev that is no next: a once-used edge */
            i = k;
            steps++;
        } while (i != 0 && steps <= n);
        return steps == n;
    }
    uint64_t seen = 1; /* corner 0 */
    uint32_t i = 0;
    for (uint32_t steps = 0; steps < n; steps++) {
        uint32_t k = 0;
        while (k < n && next[k] != prev[i])
            k++;
        if (k == n)
            return 0; /* a prev that is no next: a once-used edge */
        if (k == 0)
            return steps == n - 1; /* back at the start: after all n? */
        if (seen >> k & 1)
            return 0;
        seen |= (uint64_t)1 << k;
        i = k;
    }
    return 0;
}

typedef struct fan_job {
    const uint32_t *first, *next, *prev;
    uint8_t *free_flag;
} fan_job;

static void fan_range(void *arg, size_t lo, size_t hi)
{
    const fan_job *j = arg;
    for (size_t v = lo; v < hi; v++) {
        const uint32_t b = j->first[v];
        j->free_flag[v] = (uint8_t)one_fan((uint32_t)v, j->next + b, j->prev + b, j->first[v + 1] - b);
    }
}

/*
 * The vertices free to move: those whose triangles form one closed fan with
 * every edge used once each way.  Every other vertex of a triangle (on a
 * once-used edge, an edge used three times or twice the same way, a
 * repeated index, two fans) is locked (free[v] = 0).  The corners of each
 * vertex are filed in a compressed row table, in triangle order: first[v] ..
 * first[v + 1] - 1 index next and prev, the other two vertices of each
 * corner's triangle (the one after v and the one before, in the winding),
 * which the caller may keep (all three NULL-able: then freed here).  The
 * fans are tested on threads (the team tm's, or parallel_for()'s if NULL).  Returns 0 without memory.
 */
/* The compressed row table of corners, built in parts (vertex ranges), each
 * by one thread that reads every triangle and files the corners of its own
 * vertices, in triangle order: the same table for any number of parts.
 * Step 0 counts a part's corners into first[v] and sums them; step 1 turns
 * the counts into starts (the part's base: the corners of the parts before),
 * files the corners (first[v] a cursor, ending at the next row's start) and
 * shifts the starts back, all within the part's own vertices. */
typedef struct rows_job {
    const uint32_t *tri;
    size_t nt, nv;
    size_t parts;
    int step;
    uint32_t *first, *next, *prev;
    uint64_t corners[TEAM_MAX_THREADS];
} rows_job;

static void rows_parts(void *arg, size_t p0, size_t p1)
{
    rows_job *j = arg;
    const uint32_t *tri = j->tri;
    uint32_t *first = j->first, *next = j->next, *prev = j->prev;
    for (size_t part = p0; part < p1; part++) {
        const size_t lo = j->nv * part / j->parts, hi = j->nv * (part + 1) / j->parts;
        const uint32_t span = (uint32_t)(hi - lo);
        if (j->step == 0) {
            memset(first + lo, 0, (hi - lo) * sizeof(uint32_t));
            for (size_t c = 0; c < 3 * j->nt; c++)
                if (tri[c] - (uint32_t)lo < span)
                    first[tri[c]]++;
            uint64_t n = 0;
            for (size_t v = lo; v < hi; v++)
                n += first[v];
            j->corners[part] = n;
            continue;
        }
        uint64_t base = 0;
        for (size_t q = 0; q < part; q++)
            base += j->corners[q];
        uint32_t at = (uint32_t)base;
        for (size_t v = lo; v < hi; v++) {
            const uint32_t n = first[v];
            first[v] = at;
            at += n;
        }
        for (size_t t = 0; t < j->nt; t++) {
            const uint32_t a = tri[3 * t], b = tri[3 * t + 1], c = tri[3 * t + 2];
            if (a - (uint32_t)lo < span) {
                const uint32_t x = first[a]++;
                next[x] = b;
                prev[x] = c;
            }
            if (b - (uint32_t)lo < span) {
                const uint32_t x = first[b]++;
                next[x] = c;
                prev[x] = a;
            }
            if (c - (uint32_t)lo < span) {
                const uint32_t x = first[c]++;
                next[x] = a;
                prev[x] = b;
            }
        }
        for (size_t v = hi; v > lo + 1; v--)
            first[v - 1] = first[v - 2];
        if (hi > lo)
            first[lo] = (uint32_t)base;
    }
}

void mesh_free_vertices_into(const isomend_mesh *m, team *tm, uint8_t *free_flag, uint32_t *first,
                             uint32_t *next, uint32_t *prev)
{
    const size_t nv = m->nv, nc = 3 * m->nt;
    rows_job rows = {m->tri, m->nt, nv, 1, 0, first, next, prev, {0}};
    if (nv >= 2 * TEAM_MIN_ITEMS)
        rows.parts = (size_t)team_threads(tm);
    team_for_from(tm, rows.parts, 1, rows_parts, &rows);
    rows.step = 1;
    team_for_from(tm, rows.parts, 1, rows_parts, &rows);
    first[nv] = (uint32_t)nc;
    fan_job job = {first, next, prev, free_flag};
    if (tm)
        team_for(tm, nv, fan_range, &job);
    else
        parallel_for(nv, fan_range, &job);
}

int mesh_free_vertices(const isomend_mesh *m, team *tm, uint8_t *free_flag, uint32_t **first_out,
                       uint32_t **next_out, uint32_t **prev_out)
{
    const size_t nv = m->nv, nc = 3 * m->nt;
    uint32_t *first = malloc((nv + 1) * sizeof(uint32_t)), *next = malloc((nc ? nc : 1) * 4),
             *prev = malloc((nc ? nc : 1) * 4);
    if (!first || !next || !prev) {
        free(first);
        free(next);
        free(prev);
        return 0;
    }
    mesh_free_vertices_into(m, tm, free_flag, first, next, prev);
    if (first_out)
        *first_out = first;
    else
        free(first);
    if (next_out)
        *next_out = next;
    else
        free(next);
    if (prev_out)
        *prev_out = prev;
    else
        free(prev);
    return 1;
}

typedef struct parallel_part {
    void (*fn)(void *, size_t, size_t);
    void *arg;
    size_t lo, hi;
} parallel_part;

static void *parallel_thread(void *p)
{
    const parallel_part *part = p;
    part->fn(part->arg, part->lo, part->hi);
    return NULL;
}

void parallel_for(size_t n, void (*fn)(void *arg, size_t lo, size_t hi), void *arg)
{
    parallel_for_from(n, 32768, fn, arg);
}

void parallel_for_from(size_t n, size_t min_items, void (*fn)(void *arg, size_t lo, size_t hi),
                       void *arg)
{
    int nthreads = 1;
    if (n >= min_items && n >= 2) {
        nthreads = cores_threads(0, 8);
    }
    pthread_t th[8];
    parallel_part parts[8];
    int started = 0;
    for (int t = 1; t < nthreads; t++) {
        parts[t] = (parallel_part){fn, arg, n * (size_t)t / (size_t)nthreads,
                                   n * (size_t)(t + 1) / (size_t)nthreads};
        if (pthread_create(&th[t], NULL, parallel_thread, &parts[t]) != 0)
            break;
        started = t;
    }
    /* this thread: its own part, and the parts of threads that did not start */
    fn(arg, 0, n / (size_t)nthreads);
    if (started + 1 < nthreads)
        fn(arg, n * (size_t)(started + 1) / (size_t)nthreads, n);
    for (int t = 1; t <= started; t++)
        pthread_join(th[t], NULL);
}
