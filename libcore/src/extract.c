/*
 * extract.c - marching cubes, Durst's fix and the thesis's disambiguated
 * marching cubes over a volume read in place: the driver.
 *
 * The grid is marched layer by layer (a layer is the cubes between sample
 * slices k and k + 1).  Slice k owns the intersected grid edges whose lower
 * end is in it (x and y edges in the slice, z edges to slice k + 1), one
 * vertex each, numbered in a fixed order (slice, row, axis x/y/z, column),
 * so the mesh is the same, vertex order included, for every thread count
 * and every path below.
 *
 * Two paths (context.h lists the files):
 *   - the two passes (passes.c): count every slice and layer on all
 *     threads, take prefix sums, allocate the output arrays at their exact
 *     size, fill;
 *   - the one pass (one_pass.c), for one or two threads and the table
 *     methods (MC, Durst, DMC) on grids of ONE_PASS_SAMPLES samples
 *     or more: count and fill in one sweep into address-space reservations,
 *     each slice classified once and its vertices computed while its
 *     samples are in the caches; two threads split the sweep.
 *
 * Both call the same kernels (kernels_template.h), chosen once per
 * extraction for the CPU (cpu_features.c): the classification into signs
 * (sample >= iso, exactly, by a per-type threshold: grid_threshold below),
 * kept 1 bit a sample in a sign cache between the two passes; the numbering
 * of the edges and their vertices (positions, normals from central
 * differences); the marching of the cubes with the generated table
 * (mc_tables.inc) and the mending quadrilaterals (march_template.h).
 *
 * Methods of methods.h (facial, gradient, asymptotic, tetra, mc33) replace
 * the table by a per-cube hook (march_general.c) and always take the two
 * passes: face-diagonal vertices (tetra) are numbered with their slice,
 * layer k's cube-private vertices after slice k's vertices (before slice
 * k + 1's: where a stream delivers them, stream.c).
 *
 * Padding and NaN.  With ISOMEND_FLAG_PAD the marched grid is the volume
 * plus one layer of samples on every side; padding samples, like NaN
 * samples, are outside, and an edge with such an endpoint is cut at its
 * midpoint (vertices.c).
 */
#define _GNU_SOURCE /* _SC_NPROCESSORS_ONLN */
#include "cpu_features.h"
#include "context.h"
#include "sign_cache.h"
#include "slice_geometry.h"
#include "extract.h"
#include "passes.h"
#include "one_pass.h"
#include "methods.h"

#include <stdlib.h>
#include <unistd.h>

/* The smallest grid (samples) for the one-pass path.  Below it the two
 * passes are as fast or faster: the volume stays in the caches between them,
 * and their small arrays come from the heap, where the one-pass reservations
 * cost a huge page each (docs/core-internals.md).  Tests take the one pass
 * at every size (extract_set_test_schedule). */
#define ONE_PASS_SAMPLES (1 << 21)

static extract_schedule test_schedule; /* tests only */

void extract_set_test_schedule(extract_schedule schedule)
{
    test_schedule = schedule;
}

/* Sets the exact per-type threshold: inside iff sample >= iso. */
static void grid_threshold(grid *g)
{
    static const double lo[] = {0, -128, 0, -32768, -2147483648.0};
    static const double hi[] = {255, 127, 65535, 32767, 2147483647.0};
    g->constant = -1;
    if (g->type == ISOMEND_F32) {
        float f = (float)g->iso;
        if ((double)f < g->iso)
            f = nextafterf(f, INFINITY);
        g->fthr = f;
    } else if (g->type != ISOMEND_F64) {
        double t = ceil(g->iso);
        if (t > hi[g->type])
            g->constant = 0;
        else if (t <= lo[g->type])
            g->constant = 1;
        else
            g->ithr = (int64_t)t;
    }
}

/* The marched grid of a volume (checked by validate). */
static void grid_init(grid *g, const isomend_volume *vol, const isomend_options *o)
{
    const size_t size = isomend_type_size(vol->type);
    g->data = vol->data;
    g->type = vol->type;
    g->pad = (o->flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    g->iso = o->iso;
    for (int a = 0; a < 3; a++) {
        g->n[a] = vol->dims[a];
        g->N[a] = vol->dims[a] + 2 * g->pad;
        g->h[a] = vol->spacing[a];
        g->inv2h[a] = 0.5 / vol->spacing[a];
        g->inner_lo[a] = g->pad + 1;
        g->inner_hi[a] = g->pad + vol->dims[a] - 2;
        g->o[a] = vol->origin[a] - (double)g->pad * vol->spacing[a];
    }
    g->slices.so = vol->slice_origins;
    g->slices.n = vol->dims[2];
    g->slices.pad = g->pad;
    g->slices.gap = vol->spacing[2];
    if (vol->strides[0] == 0 && vol->strides[1] == 0 && vol->strides[2] == 0) {
        g->st[0] = (int64_t)size;
        g->st[1] = g->st[0] * g->n[0];
        g->st[2] = g->st[1] * g->n[1];
    } else {
        for (int a = 0; a < 3; a++)
            g->st[a] = vol->strides[a];
    }
    grid_threshold(g);
}

static int default_threads(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : n > 64 ? 64 : (int)n;
}

isomend_status volume_grid_check(const isomend_volume *vol, int pad)
{
    const int64_t min = pad ? 1 : 2;
    for (int a = 0; a < 3; a++) {
        if (vol->dims[a] < min || vol->dims[a] > ((int64_t)1 << 31))
            return ISOMEND_ERR_BAD_DIMENSIONS;
        if (!(vol->spacing[a] > 0.0) || !isfinite(vol->spacing[a]))
            return ISOMEND_ERR_BAD_SPACING;
        if (!isfinite(vol->origin[a]))
            return ISOMEND_ERR_INVALID_ARGUMENT;
    }
    return ISOMEND_OK;
}

static isomend_status validate(const isomend_volume *vol, const isomend_options *o)
{
    if (!vol || isomend_type_size(vol->type) == 0)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if ((unsigned)o->method >= ISOMEND_METHOD_COUNT || (o->flags & ~ISOMEND_FLAGS_ALL))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (!isomend_method_available(o->method))
        return ISOMEND_ERR_UNSUPPORTED;
    const isomend_status checked = volume_grid_check(vol, (o->flags & ISOMEND_FLAG_PAD) != 0);
    if (checked != ISOMEND_OK)
        return checked;
    if (!isfinite(o->iso))
        return ISOMEND_ERR_BAD_ISO;
    return slice_origins_validate(vol);
}

/* The context of an extraction of `vol` with options `o`: the checks, the
 * grid, the kernels and the options (vol->data may be NULL: a stream sets
 * c->g.data to its window). */
isomend_status ctx_setup(ctx *c, const isomend_volume *vol, const isomend_options *o)
{
    isomend_status status = validate(vol, o);
    if (status != ISOMEND_OK)
        return status;
    grid *g = &c->g;
    grid_init(g, vol, o);
    c->kernels = kernels_select();
    c->method = o->method;
    c->general = methods_handles(o->method);
    c->tetra = o->method == ISOMEND_METHOD_TETRA;
    c->id_planes = c->tetra ? 6 : 3;
    for (int a = 0; a < 2; a++) {
        c->cube_lo[a] = 0;
        c->cube_hi[a] = g->N[a] - 1;
    }
    c->flip = (o->flags & ISOMEND_FLAG_FLIP) != 0;
    c->want_normals = !(o->flags & ISOMEND_FLAG_NO_NORMALS);
    c->want_origins = !(o->flags & ISOMEND_FLAG_NO_ORIGINS);
    c->small_pages = (o->flags & ISOMEND_FLAG_SMALL_PAGES) != 0;
    c->progress = o->progress;
    c->progress_user = o->progress_user;
    c->schedule = test_schedule;
    return ISOMEND_OK;
}

/* ---------------------------------------------------------- the workers */

/* The next part of a worker's block: `size` bytes at *at, which moves on to
 * the next cache line. */
static char *carve(char *block, size_t *at, size_t size)
{
    char *p = block ? block + *at : NULL;
    *at += (size + 63) & ~(size_t)63;
    return p;
}

/* The worker's arrays, in one block (scratch_alloc); with block NULL, only
 * their total size. */
size_t worker_layout(worker *w, const ctx *c, char *block)
{
    const int64_t N0 = c->g.N[0], N1 = c->g.N[1];
    size_t at = 0;
    for (int r = 0; r < SIGN_RING; r++) {
        w->sign_bytes[r] = (uint8_t *)carve(block, &at, (size_t)(N0 * N1) + SCAN_PAD);
        w->spans[r] = (row_span *)(void *)carve(block, &at, sizeof(row_span) * (size_t)N1);
    }
    w->cube_cases = (uint8_t *)carve(block, &at, (size_t)N0 + SCAN_PAD);
    for (int a = 0; a < 3; a++)
        w->pending[a] = (vertex_item *)(void *)carve(
            block, &at, sizeof(vertex_item) * ((size_t)VERTEX_LIST + (size_t)N0));
    for (int r = 0; r < 2; r++)
        w->edge_ids[r] = (uint32_t *)(void *)carve(
            block, &at, sizeof(uint32_t) * (size_t)c->id_planes * (size_t)(N0 * N1));
    return at;
}

int worker_init(worker *w, ctx *c)
{
    memset(w, 0, sizeof(*w));
    w->c = c;
    for (int r = 0; r < SIGN_RING; r++)
        w->slice_held[r] = -1;
    w->block = scratch_alloc(worker_layout(w, c, NULL));
    if (!w->block)
        return 0;
    (void)worker_layout(w, c, w->block);
    memset(w->cube_cases, 0, (size_t)c->g.N[0] + SCAN_PAD); /* read past a row's end */
    return 1;
}

/* The workers' statistics and the mesh's counts, into *stats. */
void gather_stats(const ctx *c, const worker *ws, int nw, uint64_t nv, uint64_t nt,
                  isomend_stats *stats)
{
    const grid *g = &c->g;
    memset(stats, 0, sizeof(*stats));
    for (int t = 0; t < nw; t++) {
        const isomend_stats *s = &ws[t].stats;
        for (int q = 0; q < 15; q++)
            stats->case_histogram[q] += s->case_histogram[q];
        for (int q = 0; q < ISOMEND_ORIGIN_COUNT; q++)
            stats->triangles_by_origin[q] += s->triangles_by_origin[q];
        stats->ambiguous_faces += s->ambiguous_faces;
        stats->inverted_combinations += s->inverted_combinations;
        stats->nan_samples += s->nan_samples;
    }
    stats->cubes = (uint64_t)(g->N[0] - 1) * (uint64_t)(g->N[1] - 1) * (uint64_t)(g->N[2] - 1);
    stats->vertices = nv;
    stats->triangles = nt;
}

/* ------------------------------------------------------- the extraction */

/* isomend_extract, recycling *recycled (taken, and set to NULL, once the
 * extraction has begun; the caller destroys it otherwise). */
static isomend_status extract(const isomend_volume *vol, const isomend_options *opts,
                              isomend_mesh **out_mesh, isomend_stats *stats,
                              isomend_mesh **recycled)
{
    if (!out_mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out_mesh = NULL;
    isomend_options defaults;
    isomend_options_init(&defaults);
    const isomend_options *o = opts ? opts : &defaults;
    if (!vol || !vol->data)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    ctx *c = calloc(1, sizeof(*c));
    if (!c)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    isomend_status status = ctx_setup(c, vol, o);
    if (status != ISOMEND_OK) {
        free(c);
        return status;
    }
    c->recycled = *recycled; /* this call's now: used or destroyed */
    *recycled = NULL;
    grid *g = &c->g;

    const int64_t N0 = g->N[0], N1 = g->N[1], N2 = g->N[2];
    const int64_t layers = N2 - 1;
    int nthreads = o->threads > 0 ? (o->threads > 64 ? 64 : o->threads) : default_threads();
    /* Chunks: enough to balance threads (4 a thread), large enough that the 2
     * slices a chunk classifies again at its start are a small overhead. */
    const int64_t want = 4 * (int64_t)nthreads;
    int64_t chunk = (layers + want - 1) / want; /* rounded up: chunks of equal size, the
                                                 * last one barely smaller (255 layers on
                                                 * 2 threads: 8 of 32, not 8 of 31 and 1 of 7) */
    if (chunk < 4)
        chunk = 4;
    c->chunk_layers = chunk;
    c->nchunks = (layers + chunk - 1) / chunk;
    if (nthreads > c->nchunks)
        nthreads = (int)c->nchunks;

    isomend_mesh *mesh = NULL;
    worker *ws = calloc((size_t)nthreads, sizeof(*ws));
    c->slice_first = calloc((size_t)N2 + 1, sizeof(uint64_t));
    c->layer_first = calloc((size_t)N2, sizeof(uint64_t));
    c->layer_private = calloc((size_t)N2, sizeof(uint64_t));
    status = ISOMEND_ERR_OUT_OF_MEMORY;
    if (!ws || !c->slice_first || !c->layer_first || !c->layer_private ||
        (uint64_t)N0 * (uint64_t)N1 > (uint64_t)SIZE_MAX / 16)
        goto done;
    for (int t = 0; t < nthreads; t++)
        if (!worker_init(&ws[t], c)) {
            nthreads = t + 1; /* free what was allocated */
            goto done;
        }
    ws[0].is_main = 1;

    uint64_t nv = 0, nt = 0;
    status = ISOMEND_ERR_UNSUPPORTED;
    if (nthreads <= 2 && !c->general &&
        ((uint64_t)N0 * (uint64_t)N1 * (uint64_t)N2 >= ONE_PASS_SAMPLES ||
         c->schedule != SCHEDULE_AUTO))
        status = run_one_pass(c, ws, nthreads, &mesh, &nv, &nt);
    if (status == ISOMEND_ERR_UNSUPPORTED) /* not taken, or refused its reservations */
        status = run_two_passes(c, ws, nthreads, &mesh, &nv, &nt);
    if (status != ISOMEND_OK)
        goto done;

    for (int a = 0; a < 3; a++) {
        mesh->box[a] = g->o[a];
        mesh->box[3 + a] = g->o[a] + (double)(g->N[a] - 1) * g->h[a];
    }
    if (g->slices.so)
        sheared_box(g, mesh->box);
    status = mesh_keep_slices(mesh, g);
    if (status != ISOMEND_OK)
        goto done;
    if (c->progress)
        (void)c->progress(c->progress_user, 1.0);
    if (stats)
        gather_stats(c, ws, nthreads, nv, nt, stats);
    *out_mesh = mesh;
    mesh = NULL;

done:
    isomend_mesh_destroy(mesh);
    isomend_mesh_destroy(c->recycled);
    if (ws)
        for (int t = 0; t < nthreads; t++)
            free(ws[t].block);
    free(ws);
    free(c->slice_first);
    free(c->layer_first);
    free(c->layer_private);
    cache_free(c);
    free(c);
    return status;
}

isomend_status isomend_extract(const isomend_volume *vol, const isomend_options *opts,
                               isomend_mesh **out_mesh, isomend_stats *stats)
{
    isomend_mesh *none = NULL;
    return extract(vol, opts, out_mesh, stats, &none);
}

isomend_status isomend_extract_recycle(const isomend_volume *vol, const isomend_options *opts,
                                       isomend_mesh **mesh, isomend_stats *stats)
{
    if (!mesh)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_mesh *old = *mesh;
    const isomend_status status = extract(vol, opts, mesh, stats, &old);
    isomend_mesh_destroy(old); /* not taken: the arguments were refused */
    return status;
}
