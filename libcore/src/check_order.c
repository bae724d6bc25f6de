/*
 * check_order.c - a whole mesh in memory checked by the streaming checker
 * (check_stream.c) when its order is a sweep: the triangles fed in their
 * order, each vertex delivered before the first triangle that uses it and
 * retired after the last.
 *
 * isomend_extract()'s meshes, the stream's and the files isomend writes are
 * in such an order: a vertex's triangles come within about two slices of
 * each other, so the checker's window holds a few slices' vertices, in the
 * caches, where check_sorted() files every edge of the mesh in tables as
 * large as the mesh and reads them back in vertex order (a 384^3 gyroid, 13.6
 * M triangles: 1.17 s against about 0.5 s, and a tenth of the memory; see
 * docs/core-internals.md).  A mesh in another order (a shuffled or
 * hand-made one) would keep most of its vertices live at once; one pass over
 * the triangles measures that window first, and when it is more than a
 * quarter of the vertices the sorted check is taken instead.
 */
#include "check_order.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Triangles fed to the checker at a time (their ids widened to 64 bits),
 * each batch followed by a retire. */
#define BATCH 2048
#define NEVER UINT32_MAX
/* What the streaming checker holds a live vertex (check_stream.c: a ring
 * slot of 168 bytes in chunks of 4096, its edges' set nodes, the tables of
 * the few vertices with more than 8 neighbours), with room, and what it
 * holds whatever the window (measured: core_check_stream). */
#define CHECK_BYTES_PER_LIVE_VERTEX 256
#define CHECK_FIXED_BYTES (2u << 20)

/* The sweep over the triangles in batches: for each, the vertices to
 * deliver ([*delivered, *hi)) and, after it, the floor below which every
 * vertex has had its last triangle.  last[v] is v's last triangle, NEVER
 * for a vertex no triangle uses. */
typedef struct sweep {
    const uint32_t *tri, *last;
    size_t nt, t, hi, floor;
} sweep;

/* The next batch [s->t, *end): raises s->hi to cover it. */
static size_t sweep_batch(sweep *s)
{
    const size_t end = s->nt - s->t > BATCH ? s->t + BATCH : s->nt;
    size_t hi = s->hi;
    for (size_t q = 3 * s->t; q < 3 * end; q++)
        hi = (size_t)s->tri[q] + 1 > hi ? (size_t)s->tri[q] + 1 : hi;
    s->hi = hi;
    return end;
}

/* After the batch ending at `end`: the floor moved past every delivered
 * vertex whose triangles are all fed. */
static void sweep_retire(sweep *s, size_t end)
{
    s->t = end;
    while (s->floor < s->hi && (s->last[s->floor] == NEVER || s->last[s->floor] < end))
        s->floor++;
}

/* last[v]: v's last triangle (NEVER for none); the most vertices live at
 * once when the triangles are fed in order. */
static size_t order_window(const uint32_t *triangles, size_t nv, size_t nt, uint32_t *last)
{
    memset(last, 0xff, sizeof(uint32_t) * nv); /* NEVER */
    for (size_t q = 0; q < 3 * nt; q++)
        last[triangles[q]] = (uint32_t)(q / 3);
    sweep s = {triangles, last, nt, 0, 0, 0};
    size_t window = 0;
    while (s.t < nt) {
        const size_t end = sweep_batch(&s);
        window = s.hi - s.floor > window ? s.hi - s.floor : window;
        sweep_retire(&s, end);
    }
    return window;
}

static int window_allowed(size_t window, size_t nv)
{
    return window <= (nv / 4 > 65536 ? nv / 4 : 65536);
}

uint64_t check_in_order_memory(const uint32_t *triangles, size_t vertex_count,
                               size_t triangle_count)
{
    uint32_t *last = malloc(sizeof(uint32_t) * (vertex_count ? vertex_count : 1));
    if (!last)
        return 0;
    const size_t window = order_window(triangles, vertex_count, triangle_count, last);
    free(last);
    if (!window_allowed(window, vertex_count))
        return 0;
    return 4 * (uint64_t)vertex_count + (uint64_t)window * CHECK_BYTES_PER_LIVE_VERTEX +
           CHECK_FIXED_BYTES;
}

isomend_status check_in_order(const float *positions, size_t vertex_count,
                              const uint32_t *triangles, size_t triangle_count, const double *box,
                              isomend_check_report *report)
{
    const size_t nv = vertex_count, nt = triangle_count;
    uint32_t *last = malloc(sizeof(uint32_t) * (nv ? nv : 1));
    if (!last)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    if (!window_allowed(order_window(triangles, nv, nt, last), nv)) {
        free(last);
        return ISOMEND_ERR_UNSUPPORTED;
    }

    double bb[6];
    if (box) {
        memcpy(bb, box, sizeof bb);
    } else { /* check_sorted()'s: the vertices that triangles use */
        for (int a = 0; a < 3; a++) {
            bb[a] = INFINITY;
            bb[3 + a] = -INFINITY;
        }
        for (size_t v = 0; v < nv; v++)
            if (last[v] != NEVER)
                for (int a = 0; a < 3; a++) {
                    const double x = positions[3 * v + (size_t)a];
                    bb[a] = x < bb[a] ? x : bb[a];
                    bb[3 + a] = x > bb[3 + a] ? x : bb[3 + a];
                }
    }

    isomend_check_stream *c = NULL;
    uint64_t *ids = malloc(sizeof(uint64_t) * 3 * BATCH); /* not on a host thread's stack */
    isomend_status st = ids ? isomend_check_stream_begin(bb, &c) : ISOMEND_ERR_OUT_OF_MEMORY;
    sweep s = {triangles, last, nt, 0, 0, 0};
    size_t delivered = 0;
    while (st == ISOMEND_OK && s.t < nt) {
        const size_t t0 = s.t, end = sweep_batch(&s);
        if (s.hi > delivered) {
            st = isomend_check_stream_vertices(c, delivered, s.hi - delivered,
                                               positions + 3 * delivered);
            delivered = s.hi;
        }
        for (size_t q = 3 * t0; q < 3 * end; q++)
            ids[q - 3 * t0] = triangles[q];
        if (st == ISOMEND_OK)
            st = isomend_check_stream_triangles(c, end - t0, ids);
        sweep_retire(&s, end);
        if (st == ISOMEND_OK)
            st = isomend_check_stream_retire(c, s.floor);
    }
    if (st == ISOMEND_OK)
        st = isomend_check_stream_finish(c, report);
    isomend_check_stream_destroy(c);
    free(ids);
    free(last);
    return st;
}
