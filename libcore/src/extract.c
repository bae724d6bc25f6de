/*
 * extract.c - marching cubes, Durst's fix and the thesis's disambiguated
 * marching cubes over a volume: the extraction's set-up, shared by every
 * path (isomend_extract() in slabs.c, the streams in stream.c and
 * stream_pool.c, the pieces).
 *
 * The grid is marched layer by layer (a layer is the cubes between sample
 * slices k and k + 1).  Slice k owns the intersected grid edges whose lower
 * end is in it (x and y edges in the slice, z edges to slice k + 1), one
 * vertex each, numbered in a fixed order (slice, row, axis x/y/z, column),
 * so the mesh is the same, vertex order included, for every thread count
 * and every path.
 *
 * One engine (stream.c) drives the kernels slice by slice: it numbers and
 * computes slice k + 1's vertices and then writes layer k's triangles,
 * counting as it goes, so each slice is classified once and its vertices
 * are computed while its samples are in the caches.  Its clients schedule
 * runs of slices: isomend_extract() (slabs.c: the caller's run from the
 * bottom, other threads' runs from the top, joined in place), the stream
 * (slices pushed one at a time), its pool (stream_pool.c: slabs on
 * threads, handed to the sink in order) and the pieces of isomend-mpi.
 *
 * The kernels (kernels_template.h), chosen once per extraction for the CPU
 * (cpu_features.c): the classification into signs (sample >= iso,
 * exactly, by a per-type threshold: grid_threshold below); the numbering of
 * the edges and their vertices (positions, normals from central
 * differences); the marching of the cubes with the generated table
 * (mc_tables.inc) and the mending quadrilaterals (march_template.h).
 *
 * Methods of methods.h (facial, gradient, asymptotic, tetra, mc33) replace
 * the table by a per-cube hook (march_general.c): each layer is counted
 * first (its cube-private vertices numbered after slice k's vertices,
 * before slice k + 1's), then written.
 *
 * Padding and NaN.  With ISOMEND_FLAG_PAD the marched grid is the volume
 * plus one layer of samples on every side; padding samples, like NaN
 * samples, are outside, and an edge with such an endpoint is cut at its
 * midpoint (vertices.c).
 */
#include "cpu_features.h"
#include "context.h"
#include "slice_geometry.h"
#include "extract.h"
#include "methods.h"

#include <stdlib.h>

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

/* The counts of a part of the grid's cubes added to *to (not the cubes,
 * vertices and triangles). */
void stats_add(isomend_stats *to, const isomend_stats *s)
{
    for (int q = 0; q < 15; q++)
        to->case_histogram[q] += s->case_histogram[q];
    for (int q = 0; q < ISOMEND_ORIGIN_COUNT; q++)
        to->triangles_by_origin[q] += s->triangles_by_origin[q];
    to->ambiguous_faces += s->ambiguous_faces;
    to->inverted_combinations += s->inverted_combinations;
    to->nan_samples += s->nan_samples;
}

/* The workers' statistics and the mesh's counts, into *stats. */
void gather_stats(const ctx *c, const worker *ws, int nw, uint64_t nv, uint64_t nt,
                  isomend_stats *stats)
{
    const grid *g = &c->g;
    memset(stats, 0, sizeof(*stats));
    for (int t = 0; t < nw; t++)
        stats_add(stats, &ws[t].stats);
    stats->cubes = (uint64_t)(g->N[0] - 1) * (uint64_t)(g->N[1] - 1) * (uint64_t)(g->N[2] - 1);
    stats->vertices = nv;
    stats->triangles = nt;
}
