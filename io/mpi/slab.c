/*
 * slab.c - one rank's part of the mesh (see slab.h)
 *
 * The core's pieces (isomend_piece_begin, isomend.h): the rank pushes the
 * volume slices isomend_piece_halo() names (its owned marched slices and
 * one more on each side), and the piece hands over the owned vertices with
 * their global keys, the owned triangles with the next slab's vertices as
 * ISOMEND_FOREIGN | f, and the keys and positions of those foreign
 * vertices before the triangles that use them.  Every method splits: the
 * core numbers layer k's cube-private vertices between slice k's and slice
 * k + 1's, so they belong to the slab that owns layer k.
 */
#define _POSIX_C_SOURCE 200809L

#include "slab.h"

#include <stdlib.h>
#include <string.h>

_Static_assert(MPI_WRITER_FOREIGN == ISOMEND_FOREIGN, "one foreign flag");

void slab_split(int64_t nz_marched, int ranks, int rank, int64_t *first, int64_t *end)
{
    *first = nz_marched * rank / ranks;
    *end = nz_marched * (rank + 1) / ranks;
}

void slab_piece_free(slab_piece *p)
{
    free(p->foreign_keys);
    free(p->shared);
    memset(p, 0, sizeof *p);
}

uint64_t slab_memory(const cli_source *s, const isomend_options *opts, isomend_mesh_format format)
{
    isomend_volume v = s->desc;
    v.data = NULL;
    isomend_options one = *opts; /* a rank's piece runs on its own thread */
    one.threads = 1;
    const uint64_t core = isomend_stream_memory(&v, &one);
    const uint64_t vb = isomend_stream_vertex_bound(&v, &one);
    if (!core || !vb) return 0;
    /* per vertex of a slice's bound: the piece's keys (24, isomend.h), the
     * shared pairs (16) and, in the exchange, the pairs sent (16), the pairs
     * received (16), the foreign keys and their global ids (8 + 8) */
    uint64_t per_vertex = 24 + 16 + 16 + 16 + 8 + 8;
    if (format == ISOMEND_MESH_STL) per_vertex += 2 * 12 + 12; /* the window, the foreign */
    if (s->has_world) per_vertex += 24;                        /* the mapped batch */
    return core + vb * per_vertex + 2 * (uint64_t)s->slice_bytes + MPI_WRITER_MEMORY +
           ((uint64_t)CLI_WRITER_BUFFERS << 20);
}

/* Room for n more items of `size` bytes in *array (capacity *cap). */
static int grow(void **array, size_t *cap, size_t used, size_t n, size_t size)
{
    if (used + n <= *cap)
        return 1;
    size_t c = *cap ? 2 * *cap : 1024;
    while (c < used + n)
        c *= 2;
    void *q = realloc(*array, c * size);
    if (!q)
        return 0;
    *array = q;
    *cap = c;
    return 1;
}

/* The sink: the mesh to the writer, the plane tables to the piece. */
typedef struct slab_sink {
    slab_piece *p;
    mpi_writer *w;
    const cli_world *world;
    uint64_t plane;             /* N0 * N1: keys >> 3 / plane is the slice  */
    size_t scap, fcap, mcap, tcap;
    float *mapped;              /* a vertex batch in patient space           */
    uint64_t *swapped;          /* a triangle batch with its windings reversed */
    int failed;                 /* the message is printed                    */
} slab_sink;

static int oom(slab_sink *k)
{
    cli_error("%s: out of memory", k->w->final_path);
    return k->failed = 1;
}

static int sink_vertices(void *user, uint64_t first, size_t count, const float *pos,
                         const float *nrm, const uint64_t *keys)
{
    slab_sink *k = user;
    slab_piece *p = k->p;
    if (first != p->nv || !keys) {
        cli_error("vertices from id %llu, %llu expected (internal error)",
                  (unsigned long long)first, (unsigned long long)p->nv);
        return k->failed = 1;
    }
    for (size_t v = 0; v < count; v++) { /* the first plane's x, y edges and z-face diagonals */
        const uint64_t key = keys[v], kind = key & 7u;
        if (key == ISOMEND_KEY_NONE || (key >> 3) / k->plane != (uint64_t)p->first ||
            !(kind == 0 || kind == 1 || kind == 5))
            continue;
        if (!grow((void **)&p->shared, &k->scap, p->nshared, 1, 2 * sizeof(uint64_t)))
            return oom(k);
        p->shared[2 * p->nshared] = key;
        p->shared[2 * p->nshared + 1] = first + v;
        p->nshared++;
    }
    if (k->world) {
        if (!grow((void **)&k->mapped, &k->mcap, 0, count, 6 * sizeof(float)))
            return oom(k);
        float *mp = k->mapped, *mn = nrm ? k->mapped + 3 * count : NULL;
        memcpy(mp, pos, 3 * sizeof(float) * count);
        if (mn)
            memcpy(mn, nrm, 3 * sizeof(float) * count);
        cli_world_map(k->world, mp, mn, count);
        pos = mp;
        nrm = mn;
    }
    p->nv += count;
    return k->failed = mpi_writer_vertices(k->w, count, pos, nrm) != CLI_EXIT_OK;
}

static int sink_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *org)
{
    (void)org;
    slab_sink *k = user;
    if (k->world && k->world->mirror) { /* a mirror: the winding reversed */
        if (!grow((void **)&k->swapped, &k->tcap, 0, count, 3 * sizeof(uint64_t)))
            return oom(k);
        for (size_t t = 0; t < count; t++) {
            k->swapped[3 * t] = ids[3 * t];
            k->swapped[3 * t + 1] = ids[3 * t + 2];
            k->swapped[3 * t + 2] = ids[3 * t + 1];
        }
        ids = k->swapped;
    }
    k->p->nt += count;
    return k->failed = mpi_writer_triangles(k->w, count, ids) != CLI_EXIT_OK;
}

static int sink_retire(void *user, uint64_t floor)
{
    slab_sink *k = user;
    return k->failed = mpi_writer_retire(k->w, floor) != CLI_EXIT_OK;
}

static int sink_foreign(void *user, size_t first, size_t count, const uint64_t *keys,
                        const float *pos)
{
    slab_sink *k = user;
    slab_piece *p = k->p;
    if (first != p->nforeign ||
        !grow((void **)&p->foreign_keys, &k->fcap, p->nforeign, count, sizeof(uint64_t)))
        return oom(k);
    memcpy(p->foreign_keys + p->nforeign, keys, sizeof(uint64_t) * count);
    p->nforeign += count;
    if (k->world) {
        if (!grow((void **)&k->mapped, &k->mcap, 0, count, 6 * sizeof(float)))
            return oom(k);
        memcpy(k->mapped, pos, 3 * sizeof(float) * count);
        cli_world_map(k->world, k->mapped, NULL, count);
        pos = k->mapped;
    }
    return k->failed = mpi_writer_foreign(k->w, first, count, pos) != CLI_EXIT_OK;
}

static int compare_pairs(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

int slab_stream(cli_source *src, const isomend_options *opts, int64_t first, int64_t end,
                const isomend_mesh_sink *sink, const int *sink_failed, isomend_stats *stats)
{
    memset(stats, 0, sizeof *stats);
    if (first >= end)
        return CLI_EXIT_OK;
    const isomend_volume *d = &src->desc;
    const isomend_piece piece = {.owned_first = first, .owned_end = end};
    int64_t a = 0, b = 0;
    isomend_status st = isomend_piece_halo(d, opts, &piece, &a, &b);
    isomend_stream *stream = NULL;
    if (st == ISOMEND_OK)
        st = isomend_piece_begin(d, opts, &piece, sink, &stream);
    char *slice = st == ISOMEND_OK ? malloc(src->slice_bytes ? (size_t)src->slice_bytes : 1) : NULL;
    int rc = CLI_EXIT_OK;
    if (st == ISOMEND_OK && !slice) {
        cli_error("%s: out of memory for a slice", src->label);
        rc = CLI_EXIT_FAIL;
    }
    if (st == ISOMEND_OK && !rc)
        rc = cli_slices_seek(src, a);
    for (int64_t k = a; st == ISOMEND_OK && !rc && k < b; k++) {
        if (cli_interrupted) {
            cli_error("%s: interrupted", src->label);
            rc = CLI_EXIT_INTERRUPTED;
            break;
        }
        rc = cli_slices_next(src, slice);
        if (!rc)
            st = isomend_stream_push(stream, slice);
    }
    if (st == ISOMEND_OK && !rc)
        st = isomend_stream_finish(stream, stats);
    isomend_stream_destroy(stream);
    free(slice);
    if (!rc && st != ISOMEND_OK) {
        if (!(st == ISOMEND_ERR_SINK && *sink_failed)) /* else the sink said why */
            cli_error("%s: extraction of marched slices %lld..%lld failed: %s", src->label,
                      (long long)first, (long long)end - 1, isomend_status_string(st));
        rc = CLI_EXIT_FAIL;
    }
    return rc;
}

int slab_extract(cli_source *src, const isomend_options *opts, const cli_world *world,
                 int64_t first, int64_t end, mpi_writer *w, slab_piece *p)
{
    memset(p, 0, sizeof *p);
    p->first = first;
    p->end = end;
    if (first >= end)
        return CLI_EXIT_OK;
    const isomend_volume *d = &src->desc;
    const int pad = (opts->flags & ISOMEND_FLAG_PAD) != 0;
    slab_sink fill;
    memset(&fill, 0, sizeof fill);
    fill.p = p;
    fill.w = w;
    fill.world = world;
    fill.plane = (uint64_t)(d->dims[0] + 2 * pad) * (uint64_t)(d->dims[1] + 2 * pad);
    const isomend_mesh_sink sink = {&fill, sink_vertices, sink_triangles, sink_retire,
                                    sink_foreign};
    int rc = slab_stream(src, opts, first, end, &sink, &fill.failed, &p->stats);
    free(fill.mapped);
    free(fill.swapped);
    if (!rc) /* the pairs come in id order; the rank below looks keys up */
        qsort(p->shared, p->nshared, 2 * sizeof(uint64_t), compare_pairs);
    if (rc)
        slab_piece_free(p);
    return rc;
}
