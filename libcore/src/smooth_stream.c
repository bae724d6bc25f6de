/*
 * smooth_stream.c - the smoothing of a streamed mesh, in memory bounded by a
 * chunk of layers and a band: isomend_smooth_stream_*().
 *
 * A client of the sliding window (stream_window.c), as decimate_stream.c:
 * each window W = H (the triangles held back from the previous window) + a
 * chunk's triangles is smoothed by isomend_mesh_smooth() (smooth.c), which
 * locks every vertex on a once-used edge: so the cut vertices of W (those
 * with triangles outside it: final below, or in the next chunk above) do
 * not move.  Then the triangles within BAND = N + 1 rings of the new top
 * plane are held back (the next H), and every other triangle is final, with
 * its vertices where this window put them.  N iterations of the windowed
 * sinc filter are N steps of the umbrella operator, each reaching one ring
 * further: a final vertex, at least BAND rings from the top plane, moved as
 * if the plane were free (but for the volume restoration, one offset per
 * component of the window).
 *
 * Held vertices are smoothed again in the next window from their ORIGINAL
 * positions (the stream's), not twice: a slot moves only when a final
 * triangle has it (then it is on the next window's lower cut, locked), so a
 * window's mesh has every other vertex at the stream's position.  So each
 * vertex is smoothed once, in the window where its triangles become final,
 * with BAND rings of surface above it and all of its final neighbours
 * below (locked at their final positions).
 *
 * The volume.  isomend_mesh_smooth() restores each component's volume: for
 * a window (an open piece whose cut is locked) the signed volume of its
 * triangles is well defined (the cut does not move), so the window's
 * smoothing keeps it; the held band's share is redone in the next window,
 * so what a stream loses is the difference between a band smoothed with
 * the window below and with the one above (the report measures it: the
 * signed volume of the stream's triangles before and of the result after).
 *
 * Output.  The window's: vertices delivered once final, with their final
 * triangles' area-weighted normals; one retire() for each of the stream's
 * (the lowest id a waiting triangle uses), so that a streamed decimation
 * after it counts the stream's layers.  The mesh depends on the stream's
 * vertices, triangles and floors, the iterations and K only (not on the
 * stream's threads).
 */
#include "mesh_internal.h"
#include "stream_window.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The memory estimate: bytes a window's triangle costs (its ids, the
 * stream's positions, its vertices' slots and id table, the window's mesh,
 * smooth.c's tables, the result; measured against
 * isomend_smooth_stream_peak_bytes(): 240 to 300, docs/postprocess.md), stream
 * triangles a marched sample, and a padded end's cap's (half the slice
 * inside), which the first and last windows hold besides the band. */
#define BYTES_PER_TRIANGLE       360.0
#define TRIANGLES_PER_SAMPLE 0.25
#define CAP_TRIANGLES_PER_SAMPLE 1.0

/* A slot's own bytes. */
typedef struct original {
    float orig[3]; /* the stream's position                       */
    int fixed;     /* a final triangle has it: its position is final */
} original;

struct isomend_smooth_stream {
    stream_window *w;
    int iterations;
    double max_d2;
    isomend_smooth_report rep;
};

/* The signed volume under triangle (a, b, c) (smooth.c's, about the origin). */
static double tet(const float *a, const float *b, const float *c)
{
    const double ax = a[0], ay = a[1], az = a[2], bx = b[0], by = b[1], bz = b[2];
    const double cx = c[0], cy = c[1], cz = c[2];
    return (ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)) / 6.0;
}

/* ------------------------------------------------------------------ the window's hooks */

static void keep_original(void *user, void *data, const float *p)
{
    (void)user;
    memcpy(((original *)data)->orig, p, sizeof((original *)data)->orig);
}

/* Window w smoothed (the same vertices and triangles); the chunk's
 * triangles count for the volume before. */
static isomend_status smooth_window(void *user, stream_window *sw, const stream_window_mesh *w,
                                    isomend_mesh **r, uint32_t **kept)
{
    isomend_smooth_stream *d = user;
    for (size_t t = 0; t < w->nchunk; t++) {
        const uint64_t *id = w->chunk + 3 * t;
        d->rep.volume_before += tet(stream_window_raw(sw, id[0]), stream_window_raw(sw, id[1]),
                                    stream_window_raw(sw, id[2]));
    }
    *kept = NULL;
    if (!w->m->nt)
        return ISOMEND_OK;
    uint64_t bytes = 0;
    const isomend_status st = mesh_smooth(w->m, d->iterations, r, NULL, &bytes);
    mem_tally_spike(stream_window_tally(sw), bytes); /* the window counts the result */
    return st;
}

/* The final triangles' vertices take their smoothed positions (a fixed one
 * was locked: the same); the held ones stay at the stream's. */
static void take_result(void *user, stream_window *sw, const isomend_mesh *r, const uint32_t *slot,
                        const uint8_t *fin)
{
    (void)user;
    for (size_t t = 0; t < r->nt; t++)
        for (int k = 0; fin[t] && k < 3; k++) {
            const uint32_t v = r->tri[3 * t + (size_t)k];
            memcpy(stream_window_pos(sw, slot[v]), r->pos + 3 * (size_t)v, 12);
        }
}

/* A final triangle fixes its vertices and counts for the volume after. */
static int count_final(void *user, stream_window *sw, const uint32_t *t)
{
    isomend_smooth_stream *d = user;
    for (int k = 0; k < 3; k++)
        ((original *)stream_window_data(sw, t[k]))->fixed = 1;
    d->rep.volume_after +=
        tet(stream_window_pos(sw, t[0]), stream_window_pos(sw, t[1]), stream_window_pos(sw, t[2]));
    return 1;
}

/* A delivered vertex's displacement from the stream's position. */
static void count_moved(void *user, stream_window *sw, uint32_t s)
{
    isomend_smooth_stream *d = user;
    const float *p = stream_window_pos(sw, s);
    const float *o = ((const original *)stream_window_data(sw, s))->orig;
    double d2 = 0;
    for (int c = 0; c < 3; c++)
        d2 += ((double)p[c] - o[c]) * ((double)p[c] - o[c]);
    d->rep.moved_vertices += d2 > 0;
    d->max_d2 = d2 > d->max_d2 ? d2 : d->max_d2;
}

/* ------------------------------------------------------------------ the API */

uint64_t isomend_smooth_stream_memory(const isomend_volume *desc, const isomend_options *opts,
                                      int iterations, int64_t chunk_layers)
{
    if (!desc || isomend_stream_memory(desc, opts) == 0 || iterations < 0 || iterations > 10000 ||
        chunk_layers < 0)
        return 0;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const int pad = ((opts ? opts : &defaults)->flags & ISOMEND_FLAG_PAD) != 0;
    const double plane = (double)(desc->dims[0] + 2 * pad) * (double)(desc->dims[1] + 2 * pad);
    if (chunk_layers == 0)
        chunk_layers = isomend_decimate_stream_layers(desc, opts, NULL, 0);
    /* a chunk and the band (a ring is at most a layer deep, about), or at a
     * padded end the cap and the band */
    const double T = plane * TRIANGLES_PER_SAMPLE, band = (double)iterations + 2.0;
    double window = ((double)chunk_layers + band) * T;
    if (pad && CAP_TRIANGLES_PER_SAMPLE * plane + band * T > window)
        window = CAP_TRIANGLES_PER_SAMPLE * plane + band * T;
    const double bytes = window * BYTES_PER_TRIANGLE + 1048576.0;
    return bytes < 1.8e19 ? (uint64_t)bytes : UINT64_MAX;
}

isomend_status isomend_smooth_stream_begin(const isomend_volume *desc, const isomend_options *opts,
                                           int iterations, int64_t chunk_layers,
                                           const isomend_mesh_sink *out,
                                           isomend_smooth_stream **ss)
{
    if (!ss)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *ss = NULL;
    if (!out || !out->vertices || !out->triangles || !out->retire || chunk_layers < 0 ||
        iterations < 0 || iterations > 10000 || !desc || isomend_stream_memory(desc, opts) == 0)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_smooth_stream *d = calloc(1, sizeof *d);
    if (!d)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    isomend_options defaults;
    isomend_options_init(&defaults);
    d->iterations = iterations;
    const stream_window_client client = {.user = d,
                                         .data_bytes = sizeof(original),
                                         .band = (uint32_t)iterations + 1,
                                         .retire_each = 1,
                                         .strict_floor = 1,
                                         .made = keep_original,
                                         .process = smooth_window,
                                         .settle = take_result,
                                         .final = count_final,
                                         .delivered = count_moved};
    const int normals = !((opts ? opts : &defaults)->flags & ISOMEND_FLAG_NO_NORMALS);
    const int64_t K =
        chunk_layers ? chunk_layers : isomend_decimate_stream_layers(desc, opts, NULL, 0);
    if (stream_window_begin(&client, out, normals, K, &d->w) != ISOMEND_OK) {
        free(d);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    mem_tally_add(stream_window_tally(d->w), sizeof *d);
    *ss = d;
    return ISOMEND_OK;
}

isomend_status isomend_smooth_stream_sink(isomend_smooth_stream *d, isomend_mesh_sink *sink)
{
    if (!d || !sink)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    stream_window_sink(d->w, sink);
    return ISOMEND_OK;
}

isomend_status isomend_smooth_stream_finish(isomend_smooth_stream *d,
                                            isomend_smooth_report *report)
{
    if (report)
        memset(report, 0, sizeof *report);
    if (!d)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    /* the last window; no retire() is passed on for it (a step after this
     * one finishes the rest itself) */
    (void)stream_window_finish(d->w, 0);
    const isomend_status st = stream_window_close(d->w);
    if (st != ISOMEND_OK)
        return st;
    d->rep.max_displacement = sqrt(d->max_d2);
    if (report)
        *report = d->rep;
    return ISOMEND_OK;
}

uint64_t isomend_smooth_stream_peak_bytes(const isomend_smooth_stream *d)
{
    return d ? stream_window_peak_bytes(d->w) : 0;
}

void isomend_smooth_stream_destroy(isomend_smooth_stream *d)
{
    if (!d)
        return;
    stream_window_destroy(d->w);
    free(d);
}
