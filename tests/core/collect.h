/* The collecting sink of the streamed post-processing tests
 * (test_decimate_stream.c, test_clean_stream.c, test_smooth_stream.c): the
 * mesh a step delivers, gathered from the sink's calls, which the streaming
 * check is fed too (so the protocol is checked: ids in order, triangles on
 * delivered and not retired vertices, floors); its stop_at-th call fails (a
 * sink that stops).  And a volume pushed through a stream into a sink; a
 * streamed clean-up's mesh compared with the in-memory one. */
#ifndef ISOMEND_TEST_COLLECT_H
#define ISOMEND_TEST_COLLECT_H

#include "isomend.h"

#include <math.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct collected {
    float *pos, *nrm;
    uint32_t *tri;
    size_t nv, nt, cap_v, cap_t;
    uint64_t floor;
    int normals;      /* normals expected (and none otherwise)          */
    int unit_normals; /* a normal not of length 1 (within 1e-5) fails   */
    int stop_at, calls, retires;
    isomend_check_stream *check;
} collected;

static inline int collect_vertices(void *user, uint64_t first, size_t count, const float *pos,
                                   const float *nrm, const uint64_t *keys)
{
    collected *c = (collected *)user;
    if (++c->calls == c->stop_at)
        return 1;
    if (first != c->nv || keys || (c->normals != (nrm != NULL)))
        return 1;
    if (c->nv + count > c->cap_v) {
        c->cap_v = 2 * (c->nv + count);
        c->pos = (float *)realloc(c->pos, 12 * c->cap_v);
        c->nrm = (float *)realloc(c->nrm, 12 * c->cap_v);
    }
    memcpy(c->pos + 3 * c->nv, pos, 12 * count);
    if (nrm) {
        memcpy(c->nrm + 3 * c->nv, nrm, 12 * count);
        for (size_t i = 0; c->unit_normals && i < count; i++) {
            const float *n = nrm + 3 * i;
            const double len =
                sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
            if (fabs(len - 1.0) > 1e-5)
                return 1;
        }
    }
    c->nv += count;
    return isomend_check_stream_vertices(c->check, first, count, pos) != ISOMEND_OK;
}

static inline int collect_triangles(void *user, size_t count, const uint64_t *ids,
                                    const uint8_t *origins)
{
    collected *c = (collected *)user;
    if (++c->calls == c->stop_at || origins)
        return 1;
    if (c->nt + count > c->cap_t) {
        c->cap_t = 2 * (c->nt + count);
        c->tri = (uint32_t *)realloc(c->tri, 12 * c->cap_t);
    }
    for (size_t i = 0; i < 3 * count; i++) {
        if (ids[i] < c->floor || ids[i] >= c->nv)
            return 1;
        c->tri[3 * c->nt + i] = (uint32_t)ids[i];
    }
    c->nt += count;
    return isomend_check_stream_triangles(c->check, count, ids) != ISOMEND_OK;
}

static inline int collect_retire(void *user, uint64_t floor)
{
    collected *c = (collected *)user;
    if (++c->calls == c->stop_at || floor < c->floor || floor > c->nv)
        return 1;
    c->floor = floor;
    c->retires++;
    return isomend_check_stream_retire(c->check, floor) != ISOMEND_OK;
}

static inline isomend_mesh_sink collected_sink(collected *c)
{
    const isomend_mesh_sink s = {c, collect_vertices, collect_triangles, collect_retire, NULL};
    return s;
}

/* c emptied, normals expected unless o has ISOMEND_FLAG_NO_NORMALS, its
 * streaming check begun for vol and o. */
static inline isomend_status collected_begin(collected *c, const isomend_volume *vol,
                                             const isomend_options *o)
{
    memset(c, 0, sizeof *c);
    c->normals = !(o->flags & ISOMEND_FLAG_NO_NORMALS);
    return isomend_check_stream_begin_volume(vol, o, &c->check);
}

static inline void collected_free(collected *c)
{
    free(c->pos);
    free(c->nrm);
    free(c->tri);
    isomend_check_stream_destroy(c->check);
    memset(c, 0, sizeof *c);
}

/* The same mesh to the byte: positions, triangles, normals if any (an
 * empty mesh has no arrays). */
static inline int collected_same(const collected *a, const collected *b)
{
    if (a->nv != b->nv || a->nt != b->nt)
        return 0;
    return (!a->nv || !memcmp(a->pos, b->pos, 12 * a->nv)) &&
           (!a->nt || !memcmp(a->tri, b->tri, 12 * a->nt)) &&
           (!a->normals || !a->nv || !memcmp(a->nrm, b->nrm, 12 * a->nv));
}

/* vol's slices streamed with o into `in` (isomend_stream_*), finished; the
 * status of the first failing call. */
static inline isomend_status stream_volume(const isomend_volume *vol, const isomend_options *o,
                                           const isomend_mesh_sink *in)
{
    isomend_stream *s = NULL;
    isomend_status st = isomend_stream_begin(vol, o, in, &s);
    const size_t plane = (size_t)(vol->dims[0] * vol->dims[1]);
    for (int64_t k = 0; st == ISOMEND_OK && k < vol->dims[2]; k++)
        st = isomend_stream_push(s, (const float *)vol->data + plane * (size_t)k);
    if (st == ISOMEND_OK)
        st = isomend_stream_finish(s, NULL);
    isomend_stream_destroy(s);
    return st;
}

/* A triangle as its corners' 9 floats, for comparing triangle sets. */
typedef struct tri9 {
    float f[9];
} tri9;

static inline int by_tri9(const void *x, const void *y)
{
    return memcmp(x, y, sizeof(tri9));
}

static inline tri9 *corners(const float *pos, const uint32_t *tri, size_t nt)
{
    tri9 *t = (tri9 *)malloc((nt + 1) * sizeof *t);
    for (size_t i = 0; i < nt; i++)
        for (int k = 0; k < 3; k++)
            memcpy(t[i].f + 3 * k, pos + 3 * (size_t)tri[3 * i + (size_t)k], 12);
    qsort(t, nt, sizeof *t, by_tri9);
    return t;
}

/* Whether a streamed clean-up's (or --largest's) mesh c is the in-memory
 * isomend_mesh_clean()'s `inmem`: its check (by isomend_check in `box`)
 * equals the streaming check's `rs` and the in-memory mesh's, the reports
 * are the same, and so are the counts and the triangles (by their corners).
 * What differs is printed, naming `what`. */
static inline int same_as_clean(const char *what, const collected *c, const double *box,
                                const isomend_check_report *rs, const isomend_mesh *inmem,
                                const isomend_clean_report *rep, const isomend_clean_report *irep)
{
    isomend_check_report ri, r1;
    if (isomend_mesh_check(inmem, &ri) != ISOMEND_OK ||
        isomend_check(c->pos, c->nv, c->tri, c->nt, box, &r1) != ISOMEND_OK) {
        fprintf(stderr, "%s: a check failed\n", what);
        return 0;
    }
    if (memcmp(&r1, rs, sizeof *rs) || memcmp(&r1, &ri, sizeof ri) || memcmp(rep, irep, sizeof *rep)) {
        fprintf(stderr,
                "%s: streamed %llu triangles, %llu components (report %llu of %llu, %llu "
                "removed); in memory %llu, %llu (%llu of %llu, %llu removed)\n",
                what, (unsigned long long)r1.triangles, (unsigned long long)r1.components,
                (unsigned long long)rep->components_after, (unsigned long long)rep->components_before,
                (unsigned long long)rep->triangles_removed, (unsigned long long)ri.triangles,
                (unsigned long long)ri.components, (unsigned long long)irep->components_after,
                (unsigned long long)irep->components_before,
                (unsigned long long)irep->triangles_removed);
        return 0;
    }
    if (c->nt != isomend_mesh_triangle_count(inmem) || c->nv != isomend_mesh_vertex_count(inmem)) {
        fprintf(stderr, "%s: %zu vertices, %zu triangles streamed; %zu, %zu in memory\n", what,
                (size_t)c->nv, (size_t)c->nt, isomend_mesh_vertex_count(inmem),
                isomend_mesh_triangle_count(inmem));
        return 0;
    }
    int same = 1;
    if (c->nt) { /* the same triangles, by their corners */
        tri9 *a = corners(c->pos, c->tri, c->nt);
        tri9 *b = corners(isomend_mesh_positions(inmem), isomend_mesh_triangles(inmem), c->nt);
        same = !memcmp(a, b, c->nt * sizeof *a);
        free(a);
        free(b);
        if (!same)
            fprintf(stderr, "%s: other triangles\n", what);
    }
    return same;
}

#endif
