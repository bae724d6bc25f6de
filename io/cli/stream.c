/*
 * stream.c - extraction that does not hold the mesh (nor, when it does not
 * fit, the volume): the memory rule of --max-memory, the mesh sink, and the
 * streaming extraction
 *
 * The paths (README "Volumes larger than memory, and clusters";
 * docs/streaming.md).  By default `isomend extract` streams the mesh: the
 * slices go through the core's stream (on every core but the check's, isomend_stream_*) and
 * the mesh to the writer and the continuity check (check_sink.c) as it is
 * made.  The whole mesh is held only where a step needs it (post-processing,
 * --in-memory, --pages); that path holds
 *   volume   nx * ny * nz * sample size                       (the samples)
 *   mesh     6.25 bytes per marched sample with normals, 4.75 without:
 *            one triangle (12 bytes + 1 origin byte) for every 4 samples
 *            and a vertex (24 or 12 bytes) for every 8, a surface as busy
 *            as a 256^3 gyroid of period 85 samples or a smoothed CT
 *   working  1 bit per sample for the extraction beside the mesh (a staged
 *            run's part is held twice while it is moved, a huge page an
 *            array), the id maps of two slices (3 x 4 bytes per slice
 *            sample each) and 64 MiB (threads, tables, the writer's buffers)
 * and streams when their sum exceeds the limit (--max-memory SIZE, or
 * MemAvailable without it), unless a step cannot work on a stream.  The
 * mesh is the same either way, byte for byte.
 *
 * Streaming holds at most (cli_memory_plan_make())
 *   core     isomend_stream_memory(): the window of samples, signs and id
 *            maps, and one slice's vertices and one layer's triangles at
 *            their largest possible sizes (reserved; only what the mesh uses
 *            is touched, typically a quarter of it), for each thread, and
 *            the slabs in flight of a stream on several threads
 *   source   one slice, twice (an image is decoded, then converted)
 *   writer   CLI_WRITER_BUFFERS MiB of stdio buffers; PLY/OBJ faces wait in
 *            a scratch file on the output's disk, and STL keeps the
 *            positions of at most twice isomend_stream_vertex_bound()
 *   check    the streaming check's window (isomend_check_stream_memory: 80
 *            bytes a slice sample) and its queue (8 layers' calls, 1 to 4 MiB)
 *   steps    the streamed clean-up's live vertices and held components
 *            (isomend_clean_stream_memory), or with --largest its two
 *            passes' (isomend_largest_stream_memory: the live vertices, one
 *            layer's held triangles) and the spool's buffers
 *            (CLI_SPOOL_BUFFERS; the spool itself is on the output's disk:
 *            about 12 (24 with normals) bytes a vertex, 24 a triangle); with
 *            --target-triangles (no --largest) the spool's buffers and the
 *            clean-up its counting pass runs of its own; the smoothing's chunk and band
 *            (isomend_smooth_stream_memory) and the decimation's chunk
 *            (isomend_decimate_stream_memory), the chunk height the one
 *            that fits what is left (--chunk-layers: the one given)
 * When that exceeds the limit, the stream runs on one thread; if it still
 * does, without the check (said so, as the whole-mesh path says when the
 * check's tables do not fit); and a limit below what remains is refused.
 * The volume itself is loaded first only when a level is computed from it
 * (no --iso, or a named level) or it cannot be read slice by slice, and
 * then only if it fits beside the stream.  So a run's peak resident memory
 * is within the limit plus what the program holds before it reads a sample
 * (its code, libraries and their heaps; docs/streaming.md has the figures),
 * whatever the number of slices.
 *
 * cli_stream_extract() is the core's streaming extraction
 * (isomend_stream_begin/push/finish): one slice read at a time into one
 * buffer and pushed, the core keeping a few planes (isomend_stream_memory())
 * and handing the mesh to the sink as the slices complete it, in
 * isomend_extract()'s order and bytes.
 */
#define _POSIX_C_SOURCE 200809L

#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "mesh_writer.h"

#define MIB (1024.0 * 1024.0)
/* The streaming check's window is the core's (isomend_check_stream_memory());
 * the queue of calls waiting for it is the CLI's (check_sink.c): 8 layers of
 * the in-memory rule's surface (a triangle every 4 samples, 24 bytes, and a
 * vertex every 8, 12 bytes: 60 bytes a slice sample), from 1 to 4 MiB
 * (about 150 000 triangles, 8 ms of the check: two layers of a busy 512 x 512
 * surface). */
#define CLI_CHECK_QUEUE_BYTES_PER_SAMPLE 60.0
#define CLI_CHECK_QUEUE_MIB_MIN 1.0
#define CLI_CHECK_QUEUE_MIB_MAX 4.0

/* The check's queue for slices of `plane` samples. */
static double check_queue_bytes(double plane)
{
    const double q = CLI_CHECK_QUEUE_BYTES_PER_SAMPLE * plane;
    return q < CLI_CHECK_QUEUE_MIB_MIN * MIB   ? CLI_CHECK_QUEUE_MIB_MIN * MIB
           : q > CLI_CHECK_QUEUE_MIB_MAX * MIB ? CLI_CHECK_QUEUE_MIB_MAX * MIB
                                               : q;
}

/* ------------------------------------------------------------------ the memory rule */

/* What streaming holds with `opts`: the core's bound, one slice read (twice:
 * an image is decoded, then converted), the writer's stdio buffers, for STL
 * the positions it keeps until retire(), and the continuity check's window
 * and queue. */
static double streaming_need(const isomend_volume *v, const isomend_options *opts,
                             isomend_mesh_format format, int check)
{
    const double ts = (double)isomend_type_size(v->type);
    const double core = (double)isomend_stream_memory(v, opts);
    if (core == 0.0) return 1.8e19; /* dims the core refuses: in memory, to say why */
    const double bound = (double)isomend_stream_vertex_bound(v, opts);
    const double plane = (double)v->dims[0] * (double)v->dims[1];
    const double queue = check ? check_queue_bytes(plane) : 0.0;
    double need = core + 2.0 * plane * ts + CLI_WRITER_BUFFERS * MIB + queue +
                  (check ? (double)isomend_check_stream_memory(v, opts) : 0.0);
    if (format == ISOMEND_MESH_STL) need += 2.0 * 12.0 * bound;
    return need;
}

/* The streamed steps' memory beside a stream that holds `streaming`: the
 * clean-up's live vertices and held components, then the smoothing's and the
 * decimation's chunks of the layers that fit what is left (the two share the
 * chunk height; each holds a chunk, the smoothing its band too).  Sets the
 * steps' fields of p. */
static double plan_steps(cli_memory_plan *p, const isomend_volume *v, const isomend_options *opts,
                         const cli_post *post, double streaming)
{
    const int decimate = post && (post->ratio > 0 || post->target || post->max_error > 0);
    const int smooth = post && post->smooth > 0;
    const int clean = post && post->min_component > 0;
    const int largest = post && post->largest > 0;
    const int64_t chunk_layers = post ? post->chunk_layers : 0;
    double need = 0.0;
    p->largest_need = p->clean_need = p->decimate_need = p->smooth_need = 0;
    p->decimate_layers = 0;
    if (!(clean || largest || smooth || decimate) || isomend_stream_memory(v, opts) == 0)
        return 0.0;
    if (largest) { /* it does the clean-up too */
        p->largest_need = isomend_largest_stream_memory(v, opts) + (uint64_t)(CLI_SPOOL_BUFFERS * MIB);
        need += (double)p->largest_need;
    } else if (clean) {
        p->clean_need = isomend_clean_stream_memory(v, opts);
        need += (double)p->clean_need;
    }
    if (post->target && !largest) { /* its spool; pass 1's own clean-up */
        p->largest_need = (uint64_t)(CLI_SPOOL_BUFFERS * MIB) + p->clean_need;
        need += (double)p->largest_need;
    }
    if (smooth || decimate) {
        const double left = p->limit ? (double)p->limit - streaming - need : 0.0;
        /* the smoothing's band counts as that many more layers of a chunk */
        const double band = smooth ? 2.0 * post->smooth + 2.0 : 0.0;
        const double share = (smooth && decimate ? 2.0 : 1.0);
        double fit = left / share;
        if (p->limit && band > 0) {
            const double per_layer = (double)isomend_smooth_stream_memory(v, opts, 0, 2) -
                                     (double)isomend_smooth_stream_memory(v, opts, 0, 1);
            fit -= band * per_layer;
        }
        isomend_decimate_options d; /* what the decimation keeps sets what it measures against */
        isomend_decimate_options_init(&d);
        d.ratio = post->ratio;
        d.target_triangles = post->target;
        d.max_error = post->max_error;
        p->decimate_layers = chunk_layers
                                 ? chunk_layers
                                 : isomend_decimate_stream_layers(v, opts, &d,
                                                                  !p->limit   ? 0
                                                                  : fit > 1.0 ? (uint64_t)fit
                                                                              : 1);
        if (decimate)
            p->decimate_need = isomend_decimate_stream_memory(v, opts, &d, p->decimate_layers);
        if (smooth)
            p->smooth_need = isomend_smooth_stream_memory(v, opts, post->smooth, p->decimate_layers);
        need += (double)p->decimate_need + (double)p->smooth_need;
    }
    return need;
}

void cli_memory_plan_make(const isomend_volume *desc, const isomend_options *opts,
                          isomend_mesh_format format, uint64_t max_memory, int whole_mesh,
                          const cli_post *post, cli_memory_plan *p)
{
    memset(p, 0, sizeof *p);
    const int pad = (opts->flags & ISOMEND_FLAG_PAD) != 0;
    const int normals = !(opts->flags & ISOMEND_FLAG_NO_NORMALS);
    const double ts = (double)isomend_type_size(desc->type);
    double n[3], N[3];
    for (int a = 0; a < 3; a++) {
        n[a] = (double)desc->dims[a];
        N[a] = n[a] + 2.0 * pad;
    }
    const double samples = N[0] * N[1] * N[2], plane = N[0] * N[1];
    double volume = n[0] * n[1] * n[2] * ts;
    double mesh = samples * (normals ? 6.25 : 4.75);
    double working = samples / 8.0 + 24.0 * plane + 64.0 * MIB;
    double in_memory = volume + mesh + working;
    p->limit_given = max_memory != 0;
    p->limit = max_memory ? max_memory : cli_memory_available();
    p->check_queue = (uint64_t)check_queue_bytes(n[0] * n[1]);
    isomend_volume v = *desc;
    v.data = NULL;
    p->check_need = p->check_queue + isomend_check_stream_memory(&v, opts);
    if (opts->threads > 0) {
        p->threads = opts->threads;
    } else {
        /* all cores, as the core counts them, but the check's: its thread is
         * the run's longest, and a pool on every core takes its time (the busy
         * 512^3 TIFF stack on 2 cores: 2.99 s with one extraction thread beside
         * the check, 3.35 s with a pool of two; the pool costs 1.3-1.5x the CPU
         * of one stream, docs/streaming.md).  A run the check skips gets one
         * thread below, as every run under a tight limit. */
        const int cores = isomend_cores(); /* those the process may run on */
        p->threads = cores < 3 ? 1 : cores > 65 ? 64 : cores - 1;
    }
    /* under a tight limit: first one thread, then no check (said so); the
     * streamed steps count in that choice, so a step's minimal chunk is not
     * left without room by a second thread */
    isomend_options all = *opts, one = *opts;
    all.threads = p->threads;
    one.threads = 1;
    double streaming = 0.0;
    for (int step = 0; step < 3; step++) {
        if (step == 1 && p->threads == 1)
            continue;
        const int check = step < 2;
        const isomend_options *o = step == 0 ? &all : &one;
        const double base = streaming_need(&v, o, format, check);
        streaming = base + plan_steps(p, &v, opts, post, base);
        p->check = check;
        if (step > 0)
            p->threads = 1;
        if (!p->limit || streaming <= (double)p->limit)
            break;
    }
    const double cap = 1.8e19;
    p->volume = volume < cap ? (uint64_t)volume : UINT64_MAX;
    p->in_memory = in_memory < cap ? (uint64_t)in_memory : UINT64_MAX;
    p->streaming = streaming < cap ? (uint64_t)streaming : UINT64_MAX;
    p->over_limit = p->limit != 0 && p->in_memory > p->limit;
    /* a volume the core refuses goes the whole-mesh way, which says why */
    const int refused = isomend_stream_memory(&v, opts) == 0;
    p->stream = whole_mesh || refused ? p->over_limit : 1;
}

uint64_t cli_peak_memory(void)
{
    return cli_proc_kib("/proc/self/status", "VmHWM:") * 1024u;
}

uint64_t cli_resident_memory(void)
{
    return cli_proc_kib("/proc/self/status", "VmRSS:") * 1024u;
}

/* ------------------------------------------------------------------ a writer as sink */

static int writer_failed(isomend_mesh_writer *w, isomend_fileio_status st)
{
    if (st == ISOMEND_FILEIO_OK) return 0;
    cli_error("%s", isomend_mesh_writer_message(w));
    return 1;
}

static int sink_vertices(void *user, uint64_t first, size_t count, const float *pos,
                         const float *nrm, const uint64_t *keys)
{
    (void)keys;
    isomend_mesh_writer *w = user;
    if (first != isomend_mesh_writer_vertex_count(w)) {
        cli_error("vertices from id %llu, %llu expected (internal error)",
                  (unsigned long long)first,
                  (unsigned long long)isomend_mesh_writer_vertex_count(w));
        return 1;
    }
    return writer_failed(w, isomend_mesh_writer_vertices(w, count, pos, nrm));
}

static int sink_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    (void)origins;
    return writer_failed(user, isomend_mesh_writer_triangles(user, count, ids));
}

static int sink_retire(void *user, uint64_t floor)
{
    return writer_failed(user, isomend_mesh_writer_retire(user, floor));
}

void cli_sink_for_writer(cli_sink *sink, isomend_mesh_writer *w)
{
    memset(sink, 0, sizeof *sink);
    sink->user = w;
    sink->vertices = sink_vertices;
    sink->triangles = sink_triangles;
    sink->retire = sink_retire;
}

/* ------------------------------------------------------------------ a mapped sink */

/*
 * The affine map of isomend_mesh_copy_transformed() (libcore/src/transform.c),
 * batch by batch, with the same expressions in the same order, so that a
 * streamed DICOM mesh is the in-memory one byte for byte (cli_stream,
 * io_dicom_cli): positions by M p + t in double, rounded once; normals by
 * the cofactor matrix over det(M), renormalised; windings reversed when
 * det(M) < 0.  (A batch form of that function in the core would replace
 * this copy.)
 */
int cli_world_init(cli_world *w, const double affine[12], const cli_sink *next)
{
    memset(w, 0, sizeof *w);
    for (int i = 0; i < 12; i++)
        if (!isfinite(affine[i])) return 0;
    memcpy(w->m, affine, sizeof w->m);
    const double *m0 = w->m, *m1 = w->m + 4, *m2 = w->m + 8;
    const double c[3][3] = {
        {m1[1] * m2[2] - m1[2] * m2[1], m1[2] * m2[0] - m1[0] * m2[2], m1[0] * m2[1] - m1[1] * m2[0]},
        {m2[1] * m0[2] - m2[2] * m0[1], m2[2] * m0[0] - m2[0] * m0[2], m2[0] * m0[1] - m2[1] * m0[0]},
        {m0[1] * m1[2] - m0[2] * m1[1], m0[2] * m1[0] - m0[0] * m1[2], m0[0] * m1[1] - m0[1] * m1[0]}};
    const double det = m0[0] * c[0][0] + m0[1] * c[0][1] + m0[2] * c[0][2];
    if (!(fabs(det) > 0.0) || !isfinite(det)) return 0;
    memcpy(w->c, c, sizeof w->c);
    w->s = 1.0 / det;
    w->mirror = det < 0.0;
    w->next = *next;
    return 1;
}

void cli_world_free(cli_world *w)
{
    if (!w) return;
    free(w->buf);
    w->buf = NULL;
    w->cap = 0;
}

static float *world_room(cli_world *w, size_t floats)
{
    if (floats > w->cap) {
        float *p = realloc(w->buf, floats * sizeof *p);
        if (!p) return NULL;
        w->buf = p;
        w->cap = floats;
    }
    return w->buf;
}

void cli_world_map(const cli_world *w, float *pos, float *nrm, size_t count)
{
    const double *m0 = w->m, *m1 = w->m + 4, *m2 = w->m + 8;
    for (size_t i = 0; i < count; i++) {
        const double x = pos[3 * i], y = pos[3 * i + 1], z = pos[3 * i + 2];
        pos[3 * i] = (float)(m0[0] * x + m0[1] * y + m0[2] * z + m0[3]);
        pos[3 * i + 1] = (float)(m1[0] * x + m1[1] * y + m1[2] * z + m1[3]);
        pos[3 * i + 2] = (float)(m2[0] * x + m2[1] * y + m2[2] * z + m2[3]);
    }
    for (size_t i = 0; nrm && i < count; i++) {
        const double x = nrm[3 * i], y = nrm[3 * i + 1], z = nrm[3 * i + 2];
        double n[3];
        for (int r = 0; r < 3; r++)
            n[r] = w->s * (w->c[r][0] * x + w->c[r][1] * y + w->c[r][2] * z);
        const double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        const double inv = len > 0.0 ? 1.0 / len : 0.0;
        for (int r = 0; r < 3; r++) nrm[3 * i + r] = (float)(n[r] * inv);
    }
}

static int world_vertices(void *user, uint64_t first, size_t count, const float *pos,
                          const float *nrm, const uint64_t *keys)
{
    cli_world *w = user;
    float *out = world_room(w, (nrm ? 6 : 3) * count);
    if (!out && count) {
        cli_error("out of memory placing the mesh in patient space");
        return 1;
    }
    float *onrm = nrm ? out + 3 * count : NULL;
    if (count) memcpy(out, pos, 3 * count * sizeof(float));
    if (onrm && count) memcpy(onrm, nrm, 3 * count * sizeof(float));
    cli_world_map(w, out, onrm, count);
    return w->next.vertices(w->next.user, first, count, out, onrm, keys);
}

static int world_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    cli_world *w = user;
    if (!w->mirror) return w->next.triangles(w->next.user, count, ids, origins);
    uint64_t *swapped = malloc(3 * count * sizeof *swapped + 1);
    if (!swapped) {
        cli_error("out of memory placing the mesh in patient space");
        return 1;
    }
    for (size_t t = 0; t < count; t++) { /* a mirror: the winding reversed */
        swapped[3 * t] = ids[3 * t];
        swapped[3 * t + 1] = ids[3 * t + 2];
        swapped[3 * t + 2] = ids[3 * t + 1];
    }
    int rc = w->next.triangles(w->next.user, count, swapped, origins);
    free(swapped);
    return rc;
}

static int world_retire(void *user, uint64_t floor)
{
    cli_world *w = user;
    return w->next.retire(w->next.user, floor);
}

void cli_sink_for_world(cli_sink *sink, cli_world *w)
{
    memset(sink, 0, sizeof *sink);
    sink->user = w;
    sink->vertices = world_vertices;
    sink->triangles = world_triangles;
    sink->retire = world_retire;
}

/* ------------------------------------------------------------------ a timed sink */

static int timed_vertices(void *user, uint64_t first, size_t count, const float *pos,
                          const float *nrm, const uint64_t *keys)
{
    cli_timed_sink *t = user;
    const double t0 = cli_now_ms();
    const int r = t->next.vertices(t->next.user, first, count, pos, nrm, keys);
    t->ms += cli_now_ms() - t0;
    return r;
}

static int timed_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    cli_timed_sink *t = user;
    const double t0 = cli_now_ms();
    const int r = t->next.triangles(t->next.user, count, ids, origins);
    t->ms += cli_now_ms() - t0;
    return r;
}

static int timed_retire(void *user, uint64_t floor)
{
    cli_timed_sink *t = user;
    const double t0 = cli_now_ms();
    const int r = t->next.retire(t->next.user, floor);
    t->ms += cli_now_ms() - t0;
    return r;
}

void cli_sink_timed(cli_sink *sink, cli_timed_sink *t, const cli_sink *next)
{
    t->next = *next;
    t->ms = 0;
    *sink = (cli_sink){t, timed_vertices, timed_triangles, timed_retire, NULL};
}

/* ------------------------------------------------------------------ the outputs of a stream */

static void outputs_free(cli_outputs *o)
{
    isomend_largest_stream_destroy(o->largest);
    o->largest = NULL;
    if (o->spool) fclose(o->spool); /* unlinked when opened: nothing left behind */
    o->spool = NULL;
    free(o->spool_buf);
    o->spool_buf = NULL;
    isomend_clean_stream_destroy(o->clean);
    isomend_clean_stream_destroy(o->count_clean);
    isomend_smooth_stream_destroy(o->smooth);
    o->clean = o->count_clean = NULL;
    o->smooth = NULL;
    isomend_decimate_stream_destroy(o->decimate);
    cli_checker_destroy(o->checker);
    cli_world_free(o->has_world ? &o->world : NULL);
    o->decimate = NULL;
    o->checker = NULL;
    o->has_world = 0;
}

void cli_outputs_abort(cli_outputs *o)
{
    outputs_free(o);
    if (o->w) isomend_mesh_writer_abort(o->w);
    o->w = NULL;
}

int cli_outputs_commit(cli_outputs *o)
{
    outputs_free(o);
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    const isomend_fileio_status st = isomend_mesh_writer_commit(o->w, msg, sizeof msg);
    o->w = NULL;
    if (st == ISOMEND_FILEIO_OK) return CLI_EXIT_OK;
    cli_error("%s", msg);
    return CLI_EXIT_FAIL;
}

/*
 * The spool of --largest and --target-triangles: the calls pass 1 gets, in
 * records of three 64-bit words (type, a, b) and a payload, replayed for
 * pass 2 (--target-triangles: pass 1 counts the triangles the decimation
 * will get, which its target needs, isomend_decimate_stream_expect()):
 *   V  a = first id, b = count; count x 3 floats (positions)
 *   N  as V, then count x 3 floats (normals)
 *   T  b = count; count x 3 ids
 *   R  a = the floor
 * The file is a scratch file beside the output (isomend_spool_open: unlinked
 * as soon as it exists, so gone however the run ends).
 */
enum { SPOOL_V = 1, SPOOL_N = 2, SPOOL_T = 3, SPOOL_R = 4 };

static int spool_put(cli_outputs *o, uint64_t type, uint64_t a, uint64_t b, const void *p1,
                     size_t n1, const void *p2, size_t n2)
{
    const uint64_t head[3] = {type, a, b};
    if (fwrite(head, sizeof head, 1, o->spool) != 1 ||
        (n1 && fwrite(p1, 1, n1, o->spool) != n1) || (n2 && fwrite(p2, 1, n2, o->spool) != n2)) {
        cli_error("%s: cannot write the %s scratch file: %s", o->path, o->spool_flag,
                  strerror(errno));
        return 1;
    }
    return 0;
}

static int spool_vertices(void *user, uint64_t first, size_t count, const float *pos,
                          const float *nrm, const uint64_t *keys)
{
    cli_outputs *o = user;
    if (spool_put(o, nrm ? SPOOL_N : SPOOL_V, first, count, pos, 12 * count, nrm,
                  nrm ? 12 * count : 0))
        return 1;
    return o->lsink.vertices(o->lsink.user, first, count, pos, nrm, keys);
}

static int spool_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    cli_outputs *o = user;
    if (spool_put(o, SPOOL_T, 0, count, ids, 24 * count, NULL, 0))
        return 1;
    return o->lsink.triangles(o->lsink.user, count, ids, origins);
}

static int spool_retire(void *user, uint64_t floor)
{
    cli_outputs *o = user;
    if (spool_put(o, SPOOL_R, floor, 0, NULL, 0, NULL, 0))
        return 1;
    return o->lsink.retire(o->lsink.user, floor);
}

/* Pass 2: the spool again, through the filter.  0, or 1 with the message
 * printed (the filter's own failures by the caller). */
static int spool_replay(cli_outputs *o, const char *label)
{
    const cli_sink *to = o->replay;
    if (fflush(o->spool) != 0 || fseeko(o->spool, 0, SEEK_SET) != 0) {
        cli_error("%s: cannot read back the %s scratch file: %s", o->path, o->spool_flag,
                  strerror(errno));
        return 1;
    }
    unsigned char *buf = NULL;
    size_t cap = 0;
    int rc = 0;
    for (;;) {
        uint64_t head[3];
        const size_t got = fread(head, 1, sizeof head, o->spool);
        if (got == 0 && feof(o->spool))
            break;
        if (cli_interrupted) {
            cli_error("%s: interrupted", label);
            rc = 1;
            break;
        }
        const uint64_t type = head[0], a = head[1], n = head[2];
        const uint64_t len = type == SPOOL_V ? 12 * n : type == SPOOL_N ? 24 * n
                             : type == SPOOL_T ? 24 * n : 0;
        if (got != sizeof head || type < SPOOL_V || type > SPOOL_R || n > (SIZE_MAX >> 5)) {
            cli_error("%s: the %s scratch file is damaged", o->path, o->spool_flag);
            rc = 1;
            break;
        }
        if (len > cap) {
            unsigned char *b = realloc(buf, (size_t)len);
            if (!b) {
                cli_error("%s: out of memory replaying the %s scratch file", label, o->spool_flag);
                rc = 1;
                break;
            }
            buf = b;
            cap = (size_t)len;
        }
        if (len && fread(buf, 1, (size_t)len, o->spool) != len) {
            cli_error("%s: cannot read back the %s scratch file: %s", o->path, o->spool_flag,
                      ferror(o->spool) ? strerror(errno) : "it ends early");
            rc = 1;
            break;
        }
        const float *pos = (const float *)(const void *)buf;
        if (type == SPOOL_V || type == SPOOL_N)
            rc = to->vertices(to->user, a, (size_t)n, pos, type == SPOOL_N ? pos + 3 * n : NULL,
                              NULL);
        else if (type == SPOOL_T)
            rc = to->triangles(to->user, (size_t)n, (const uint64_t *)(const void *)buf, NULL);
        else
            rc = to->retire(to->user, a);
        if (rc) {
            rc = 2; /* the filter or a step after it: its status says why */
            break;
        }
    }
    if (!rc && ferror(o->spool)) {
        cli_error("%s: cannot read back the %s scratch file: %s", o->path, o->spool_flag,
                  strerror(errno));
        rc = 1;
    }
    free(buf);
    return rc;
}

/* The spool opened (o->spool_flag names why) and its recording sink
 * (o->lrecord, which passes pass 1 on to o->lsink); 0, or 1 with the
 * message printed and o aborted. */
static int spool_begin(cli_outputs *o, const char *path)
{
    char smsg[ISOMEND_FILEIO_MSG_SIZE];
    if (isomend_spool_open(path, &o->spool, smsg, sizeof smsg) != ISOMEND_FILEIO_OK) {
        o->spool = NULL;
        cli_error("%s: %s", o->spool_flag, smsg);
        cli_outputs_abort(o);
        return 1;
    }
    o->spool_buf = malloc(1u << 20);
    if (o->spool_buf) setvbuf(o->spool, o->spool_buf, _IOFBF, 1u << 20);
    o->lrecord = (cli_sink){o, spool_vertices, spool_triangles, spool_retire, NULL};
    return 0;
}

/* A streamed clean-up (--min-component min) into `out`, its sink in *in; 0,
 * or 1 with the message printed and o aborted. */
static int clean_begin(cli_outputs *o, const char *label, uint64_t min, const cli_sink *out,
                       isomend_clean_stream **cs, cli_sink *in)
{
    const isomend_status st = isomend_clean_stream_begin(min, out, cs);
    if (st != ISOMEND_OK) {
        cli_error("%s: clean-up failed: %s", label, isomend_status_string(st));
        cli_outputs_abort(o);
        return 1;
    }
    isomend_clean_stream_sink(*cs, in);
    return 0;
}

/* --target-triangles' pass 1 ends here: the triangles counted. */
static int count_vertices(void *user, uint64_t first, size_t count, const float *pos,
                          const float *nrm, const uint64_t *keys)
{
    (void)user, (void)first, (void)count, (void)pos, (void)nrm, (void)keys;
    return 0;
}

static int count_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *origins)
{
    (void)ids, (void)origins;
    ((cli_outputs *)user)->counted += count;
    return 0;
}

static int count_retire(void *user, uint64_t floor)
{
    (void)user, (void)floor;
    return 0;
}

int cli_outputs_begin(cli_outputs *o, const char *path, isomend_mesh_format fmt, int normals,
                      const double *world, const char *label, const isomend_volume *desc,
                      const isomend_options *opts, uint64_t check_queue, const cli_post *post,
                      int64_t layers)
{
    const int decimate = post && (post->ratio > 0 || post->target || post->max_error > 0);
    memset(o, 0, sizeof *o);
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    if (isomend_mesh_writer_begin(path, fmt, normals, 0, &o->w, msg, sizeof msg) !=
        ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        o->w = NULL;
        return 1;
    }
    cli_sink_for_writer(&o->writer, o->w);
    o->sink = &o->writer;
    if (world) { /* a DICOM series in patient space: mapped as it goes */
        if (!cli_world_init(&o->world, world, &o->writer)) {
            cli_error("%s: the series' patient transform is not invertible", label);
            cli_outputs_abort(o);
            return 1;
        }
        o->has_world = 1;
        cli_sink_for_world(&o->mapped, &o->world);
        o->sink = &o->mapped;
    }
    if (check_queue) {
        if (cli_checker_begin(desc, opts, check_queue, o->sink, &o->checker, &o->tee)) {
            cli_outputs_abort(o);
            return 1;
        }
        o->sink = &o->tee;
    }
    if (decimate) {
        cli_sink_timed(&o->timed_out, &o->t_out, o->sink);
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        d.ratio = post->ratio;
        d.target_triangles = post->target;
        d.max_error = post->max_error;
        const isomend_status st =
            isomend_decimate_stream_begin(desc, opts, &d, layers, &o->timed_out, &o->decimate);
        if (st != ISOMEND_OK) {
            cli_error("%s: decimation failed: %s", label, isomend_status_string(st));
            cli_outputs_abort(o);
            return 1;
        }
        o->layers = layers;
        isomend_decimate_stream_sink(o->decimate, &o->dsink);
        cli_sink_timed(&o->timed_in, &o->t_in, &o->dsink);
        o->sink = &o->timed_in;
    }
    if (post && post->smooth > 0) {
        cli_sink_timed(&o->stimed_out, &o->s_out, o->sink);
        const isomend_status st = isomend_smooth_stream_begin(desc, opts, post->smooth, layers,
                                                              &o->stimed_out, &o->smooth);
        if (st != ISOMEND_OK) {
            cli_error("%s: smoothing failed: %s", label, isomend_status_string(st));
            cli_outputs_abort(o);
            return 1;
        }
        o->layers = layers;
        isomend_smooth_stream_sink(o->smooth, &o->ssink);
        cli_sink_timed(&o->stimed_in, &o->s_in, &o->ssink);
        o->sink = &o->stimed_in;
    }
    o->path = path;
    if (post && post->largest > 0) { /* --min-component with it */
        o->spool_flag = "--largest";
        cli_sink_timed(&o->ltimed_out, &o->l_out, o->sink);
        const isomend_status st = isomend_largest_stream_begin(
            post->min_component, post->largest, &o->ltimed_out, &o->largest);
        if (st != ISOMEND_OK) {
            cli_error("%s: clean-up failed: %s", label, isomend_status_string(st));
            cli_outputs_abort(o);
            return 1;
        }
        isomend_largest_stream_sink(o->largest, &o->lsink);
        o->replay = &o->lsink; /* the same filter in both passes */
        if (spool_begin(o, path)) return 1;
        cli_sink_timed(&o->ctimed_in, &o->l_in, &o->lrecord);
        o->sink = &o->ctimed_in;
    } else if (post && post->min_component > 0) {
        cli_sink_timed(&o->ctimed_out, &o->c_out, o->sink);
        if (clean_begin(o, label, post->min_component, &o->ctimed_out, &o->clean, &o->csink))
            return 1;
        cli_sink_timed(&o->ctimed_in, &o->c_in, &o->csink);
        o->sink = &o->ctimed_in;
    }
    if (post && post->target && !post->largest) {
        /* --target-triangles: pass 1 counts what the decimation will get (the
         * stream's triangles, or those a clean-up of its own passes); pass 2
         * replays the spool into the chain above, which the stream never fed */
        o->spool_flag = "--target-triangles";
        o->replay = o->sink;
        o->counter = (cli_sink){o, count_vertices, count_triangles, count_retire, NULL};
        o->lsink = o->counter;
        if (post->min_component > 0 &&
            clean_begin(o, label, post->min_component, &o->counter, &o->count_clean, &o->lsink))
            return 1;
        if (spool_begin(o, path)) return 1;
        o->sink = &o->lrecord;
    }
    return 0;
}

int cli_outputs_finish(cli_outputs *o, int rc, const char *label, struct cli_post_report *post,
                       isomend_check_report *check, int *checked)
{
    *checked = 0;
    /* each step's finish delivers its rest to the next, so in the chain's
     * order; each one's time: its calls and finish, less those of the sinks
     * after it */
    if (o->largest) { /* pass 2: the spool through the filter */
        const double t0 = cli_now_ms();
        int replay = rc ? 0 : -1;
        isomend_status st = rc ? ISOMEND_OK : isomend_largest_stream_replay(o->largest);
        if (!rc && st == ISOMEND_OK && o->decimate) /* pass 2 feeds it: its input's count */
            st = isomend_decimate_stream_expect(o->decimate,
                                                isomend_largest_stream_kept_triangles(o->largest));
        if (!rc && st == ISOMEND_OK)
            replay = spool_replay(o, label);
        if (replay == 1) {
            rc = CLI_EXIT_FAIL;
        } else if (!rc) {
            const isomend_status fs = isomend_largest_stream_finish(o->largest, &post->clean);
            if (st == ISOMEND_OK)
                st = fs;
            if (st != ISOMEND_OK) {
                if (st != ISOMEND_ERR_SINK)
                    cli_error("%s: --largest failed: %s", label, isomend_status_string(st));
                rc = CLI_EXIT_FAIL;
            }
        }
        post->cleaned = !rc;
        post->streamed = 1;
        /* both passes, less the steps after it (pass 1 calls none) */
        post->clean_ms = o->l_in.ms + (cli_now_ms() - t0) - o->l_out.ms;
        if (o->spool) fclose(o->spool);
        o->spool = NULL;
    }
    int replayed = 0;              /* --target-triangles: the chain stopped the replay (2) */
    if (!o->largest && o->spool) { /* --target-triangles: pass 2, the spool into the chain */
        isomend_status st = ISOMEND_OK;
        if (!rc && o->count_clean) st = isomend_clean_stream_finish(o->count_clean, NULL);
        if (!rc && st == ISOMEND_OK) st = isomend_decimate_stream_expect(o->decimate, o->counted);
        if (!rc && st != ISOMEND_OK) {
            cli_error("%s: --target-triangles failed: %s", label, isomend_status_string(st));
            rc = CLI_EXIT_FAIL;
        }
        if (!rc && (replayed = spool_replay(o, label)) == 1) rc = CLI_EXIT_FAIL;
        fclose(o->spool);
        o->spool = NULL;
    }
    if (o->clean) {
        const double t0 = cli_now_ms();
        const isomend_status st = isomend_clean_stream_finish(o->clean, &post->clean);
        if (!rc && st != ISOMEND_OK) {
            if (st != ISOMEND_ERR_SINK)
                cli_error("%s: clean-up failed: %s", label, isomend_status_string(st));
            rc = CLI_EXIT_FAIL;
        }
        post->cleaned = !rc;
        post->streamed = 1;
        post->clean_ms = o->c_in.ms + (cli_now_ms() - t0) - o->c_out.ms;
    }
    if (o->smooth) {
        const double t0 = cli_now_ms();
        const isomend_status st = isomend_smooth_stream_finish(o->smooth, &post->smooth);
        o->smooth_peak = isomend_smooth_stream_peak_bytes(o->smooth);
        if (!rc && st != ISOMEND_OK) {
            if (st != ISOMEND_ERR_SINK)
                cli_error("%s: smoothing failed: %s", label, isomend_status_string(st));
            rc = CLI_EXIT_FAIL;
        }
        post->smoothed = !rc;
        post->streamed = 1;
        post->chunk_layers = o->layers;
        post->smooth_ms = o->s_in.ms + (cli_now_ms() - t0) - o->s_out.ms;
    }
    if (o->decimate) {
        const double d0 = cli_now_ms();
        const isomend_status st = isomend_decimate_stream_finish(o->decimate, &post->decimate);
        o->decimate_peak = isomend_decimate_stream_peak_bytes(o->decimate);
        if (!rc && st != ISOMEND_OK) {
            if (st != ISOMEND_ERR_SINK) /* else the sink said why */
                cli_error("%s: decimation failed: %s", label, isomend_status_string(st));
            rc = CLI_EXIT_FAIL;
        }
        post->decimated = !rc;
        post->streamed = 1;
        post->chunk_layers = o->layers;
        /* its own time: its calls, less those of the sinks after it */
        post->decimate_ms = o->t_in.ms + (cli_now_ms() - d0) - o->t_out.ms;
    }
    if (!rc && replayed) { /* a step stopped the replay and none said why (not reached) */
        cli_error("%s: --target-triangles: the replay stopped", label);
        rc = CLI_EXIT_FAIL;
    }
    if (!rc && o->checker) {
        rc = cli_checker_finish(o->checker, check) ? CLI_EXIT_FAIL : CLI_EXIT_OK;
        *checked = !rc;
        o->check_peak = cli_checker_peak_bytes(o->checker);
    }
    outputs_free(o);
    return rc;
}

/* ------------------------------------------------------------------ extraction */

int cli_stream_extract(cli_source *s, const isomend_options *opts, const cli_sink *sink,
                       isomend_stats *stats)
{
    /* The core's stream (isomend_stream_*): one slice in this buffer at a
     * time, the mesh handed to the sink as the slices complete it. */
    isomend_mesh_sink core = *sink;
    core.foreign = NULL; /* a stream, not a piece */
    char *slice = malloc(s->slice_bytes ? (size_t)s->slice_bytes : 1);
    if (!slice) {
        cli_error("%s: cannot allocate %.1f MiB for a slice", s->label,
                  (double)s->slice_bytes / MIB);
        return CLI_EXIT_FAIL;
    }
    isomend_stream *st = NULL;
    isomend_status status = isomend_stream_begin(&s->desc, opts, &core, &st);
    int rc = CLI_EXIT_OK;
    if (status == ISOMEND_OK)
        cli_slices_rewind(s);
    for (int64_t k = 0; status == ISOMEND_OK && k < s->desc.dims[2]; k++) {
        if (cli_interrupted) {
            cli_error("%s: interrupted", s->label);
            rc = CLI_EXIT_INTERRUPTED;
            break;
        }
        rc = cli_slices_next(s, slice);
        if (rc)
            break;
        status = isomend_stream_push(st, slice);
        cli_progress_update(s->progress, "extract", (double)(k + 1) / (double)s->desc.dims[2]);
    }
    if (!rc && status == ISOMEND_OK)
        status = isomend_stream_finish(st, stats);
    isomend_stream_destroy(st);
    free(slice);
    cli_progress_clear(s->progress);
    if (rc)
        return rc;
    if (status == ISOMEND_ERR_SINK) /* the sink printed its message */
        return CLI_EXIT_FAIL;
    if (status != ISOMEND_OK) {
        cli_error("%s: extraction failed: %s", s->label, isomend_status_string(status));
        return CLI_EXIT_FAIL;
    }
    return CLI_EXIT_OK;
}
