/*
 * passes.c - the two passes: count, allocate, fill.
 *
 * The grid is cut into chunks of consecutive layers (ctx.chunk_layers).
 * Threads take chunks from an atomic counter; everything a chunk writes
 * goes to places fixed in advance, so the mesh is the same, vertex order
 * included, for every thread count.
 *
 *   1. Count (count_layers).  For each slice k, the intersected edges whose
 *      lower end is in it; for each layer, the triangles (mending and Durst
 *      quadrilaterals included), the cube-private vertices of the general
 *      methods and the statistics.  The signs go to the sign cache.
 *   2. Prefix sums give every slice's first vertex and every layer's first
 *      triangle; the output arrays are allocated once, at their exact size.
 *   3. Fill (fill_layers).  Each chunk numbers the edges of its slices from
 *      those firsts, computes their vertices and writes its layers'
 *      triangles.  A chunk's first slice is numbered again (its vertices
 *      belong to the chunk below, which writes them).
 *
 * count_layers and fill_layers are the unit: the layers [k0, k1) of the
 * grid, given the slices k0 .. k1 (and k1 + 1 for the +z neighbours).
 */
#include "context.h"
#include "sign_cache.h"
#include "passes.h"

#include <pthread.h>
#include <stdlib.h>

/* Counting pass over layers [k0, k1): counts into ctx.slice_first,
 * layer_first and layer_private, statistics into the worker's. */
static void count_layers(worker *w, int64_t k0, int64_t k1)
{
    ctx *c = w->c;
    const extract_kernels *kr = c->kernels;
    const int64_t N2 = c->g.N[2];
    for (int64_t k = k0; k < k1; k++) {
        c->slice_first[k] = kr->scan_slice(w, k, PASS_COUNT, 0, 0);
        w->stats.nan_samples += w->slice_nans[k % SIGN_RING];
        if (c->cache_bits)
            cache_store(w, k);
        if (k == N2 - 2) { /* the last slice has no layer of its own */
            c->slice_first[N2 - 1] = kr->scan_slice(w, N2 - 1, PASS_COUNT, 0, 0);
            w->stats.nan_samples += w->slice_nans[(N2 - 1) % SIGN_RING];
            if (c->cache_bits)
                cache_store(w, N2 - 1);
        }
        c->layer_first[k] = kr->march_layer(w, k, PASS_COUNT, 0);
        c->layer_private[k] = w->private_count;
    }
}

/* Fill pass over layers [k0, k1), ids from the prefix sums.  Slice k0 is
 * numbered for the ids of layer k0, its vertices written by the chunk below
 * (or, for slice 0, here); slice k1 is written here only if it is the last. */
static void fill_layers(worker *w, int64_t k0, int64_t k1)
{
    ctx *c = w->c;
    const extract_kernels *kr = c->kernels;
    const int64_t N2 = c->g.N[2];
    kr->scan_slice(w, k0, PASS_FILL, c->slice_first[k0], 1);
    for (int64_t k = k0; k < k1; k++) {
        const int64_t m = k + 1;
        kr->scan_slice(w, m, PASS_FILL, c->slice_first[m], m < k1 || m == N2 - 1);
        kr->march_layer(w, k, PASS_FILL, c->layer_first[k]);
    }
}

/* Runs one chunk of the current pass. */
static void run_chunk(worker *w, int64_t chunk)
{
    const ctx *c = w->c;
    const int64_t N2 = c->g.N[2];
    const int64_t k0 = chunk * c->chunk_layers;
    int64_t k1 = k0 + c->chunk_layers;
    if (k1 > N2 - 1)
        k1 = N2 - 1;
    if (c->pass == PASS_COUNT)
        count_layers(w, k0, k1);
    else
        fill_layers(w, k0, k1);
}

static void run_chunks(worker *w)
{
    ctx *c = w->c;
    for (;;) {
        if (atomic_load(&c->cancel))
            return;
        long long chunk = atomic_fetch_add(&c->next_chunk, 1);
        if (chunk >= c->nchunks)
            return;
        run_chunk(w, chunk);
        long long done = atomic_fetch_add(&c->done_chunks, 1) + 1;
        if (w->is_main && c->progress) {
            double f = (double)done / (double)(2 * c->nchunks);
            if (c->progress(c->progress_user, f))
                atomic_store(&c->cancel, 1);
        }
    }
}

static void *worker_thread(void *arg)
{
    run_chunks((worker *)arg);
    return NULL;
}

/* Runs the current pass on `nw` workers (worker 0 is this thread). */
static isomend_status run_pass(ctx *c, worker *ws, int nw)
{
    pthread_t tid[64];
    int started = 0;
    isomend_status status = ISOMEND_OK;
    atomic_store(&c->next_chunk, 0);
    for (int t = 1; t < nw; t++) {
        if (pthread_create(&tid[t], NULL, worker_thread, &ws[t]) != 0) {
            status = ISOMEND_ERR_THREAD;
            atomic_store(&c->cancel, 1);
            break;
        }
        started = t;
    }
    if (status == ISOMEND_OK)
        run_chunks(&ws[0]);
    for (int t = 1; t <= started; t++)
        pthread_join(tid[t], NULL);
    if (status == ISOMEND_OK && atomic_load(&c->cancel))
        status = ISOMEND_ERR_CANCELLED;
    return status;
}

/*
 * The two passes on `nw` workers: on success *out is the mesh and *nv, *nt
 * its counts.  On failure *out is whatever mesh was allocated, for the
 * caller to destroy.
 */
isomend_status run_two_passes(ctx *c, worker *ws, int nw, isomend_mesh **out, uint64_t *nv,
                              uint64_t *nt)
{
    const int64_t N2 = c->g.N[2], layers = N2 - 1;
    cache_alloc(c);
    c->pass = PASS_COUNT;
    isomend_status status = run_pass(c, ws, nw);
    if (status != ISOMEND_OK)
        return status;

    /* Prefix sums: first vertex of each slice, first triangle of each layer.
     * Layer k's cube-private vertices (methods.h) follow slice k's, so that
     * slices and layers [a, b) own one run of ids: a stream delivers them
     * there, a piece of the grid owns them with its layers (stream.c). */
    uint64_t v = 0, t = 0;
    for (int64_t k = 0; k < N2; k++) {
        uint64_t n = c->slice_first[k];
        c->slice_first[k] = v;
        v += n;
        if (k < layers) {
            n = c->layer_private[k];
            c->layer_private[k] = v;
            v += n;
        }
    }
    c->slice_first[N2] = v;
    for (int64_t k = 0; k < layers; k++) {
        uint64_t n = c->layer_first[k];
        c->layer_first[k] = t;
        t += n;
    }
    c->layer_first[layers] = t;
    if (v > UINT32_MAX)
        return ISOMEND_ERR_TOO_LARGE;

    isomend_mesh_destroy(c->recycled); /* the two passes' arrays are allocated, not reserved */
    c->recycled = NULL;
    isomend_mesh *mesh = calloc(1, sizeof(*mesh));
    if (!mesh)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    *out = mesh;
    mesh->nv = (size_t)v;
    mesh->nt = (size_t)t;
    mesh->pos = output_alloc(sizeof(float) * 3 * v, c->small_pages);
    mesh->tri = output_alloc(sizeof(uint32_t) * 3 * t, c->small_pages);
    if (c->want_normals)
        mesh->nrm = output_alloc(sizeof(float) * 3 * v, c->small_pages);
    if (c->want_origins)
        mesh->org = output_alloc(t, c->small_pages);
    if (!mesh->pos || !mesh->tri || (c->want_normals && !mesh->nrm) ||
        (c->want_origins && !mesh->org))
        return ISOMEND_ERR_OUT_OF_MEMORY;
    c->pos = mesh->pos;
    c->nrm = mesh->nrm;
    c->tri = mesh->tri;
    c->org = mesh->org;

    c->pass = PASS_FILL;
    for (int w = 0; w < nw; w++)
        for (int r = 0; r < SIGN_RING; r++)
            ws[w].slice_held[r] = -1; /* keep buffers, forget contents */
    status = run_pass(c, ws, nw);
    if (status != ISOMEND_OK)
        return status;
    *nv = v;
    *nt = t;
    return ISOMEND_OK;
}
