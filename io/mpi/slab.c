/*
 * slab.c - one rank's part of the mesh (see slab.h)
 *
 * The core's pieces (isomend_piece_begin, isomend.h): the rank pushes the
 * volume slices isomend_piece_halo() names (its owned marched slices and
 * one more on each side), and the piece hands over the owned vertices with
 * their global keys, the owned triangles with the next slab's vertices as
 * ISOMEND_FOREIGN | f, and the keys and positions of those foreign
 * vertices.  Every method splits: the core numbers layer k's cube-private
 * vertices between slice k's and slice k + 1's, so they belong to the slab
 * that owns layer k.
 */
#define _POSIX_C_SOURCE 200809L

#include "slab.h"

#include <stdlib.h>
#include <string.h>

void slab_split(int64_t nz_marched, int ranks, int rank, int64_t *first, int64_t *end)
{
    *first = nz_marched * rank / ranks;
    *end = nz_marched * (rank + 1) / ranks;
}

void slab_piece_free(slab_piece *p)
{
    free(p->pos);
    free(p->nrm);
    free(p->keys);
    free(p->tri);
    free(p->org);
    free(p->foreign_keys);
    free(p->foreign_pos);
    free(p->shared);
    memset(p, 0, sizeof *p);
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

/* The sink filling a slab_piece. */
typedef struct piece_fill {
    slab_piece *p;
    size_t vcap, tcap, fcap;
    int oom;
} piece_fill;

static int fill_vertices(void *user, uint64_t first, size_t count, const float *pos,
                         const float *nrm, const uint64_t *keys)
{
    piece_fill *f = user;
    slab_piece *p = f->p;
    size_t cap = f->vcap;
    if (first != p->nv || !grow((void **)&p->pos, &cap, p->nv, count, 3 * sizeof(float)) ||
        (nrm && !grow((void **)&p->nrm, &(size_t){f->vcap}, p->nv, count, 3 * sizeof(float))) ||
        !grow((void **)&p->keys, &(size_t){f->vcap}, p->nv, count, sizeof(uint64_t))) {
        f->oom = 1;
        return 1;
    }
    f->vcap = cap;
    memcpy(p->pos + 3 * p->nv, pos, 3 * sizeof(float) * count);
    if (nrm)
        memcpy(p->nrm + 3 * p->nv, nrm, 3 * sizeof(float) * count);
    memcpy(p->keys + p->nv, keys, sizeof(uint64_t) * count);
    p->nv += count;
    return 0;
}

static int fill_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *org)
{
    piece_fill *f = user;
    slab_piece *p = f->p;
    size_t cap = f->tcap;
    if (!grow((void **)&p->tri, &cap, p->nt, count, 3 * sizeof(uint64_t)) ||
        (org && !grow((void **)&p->org, &(size_t){f->tcap}, p->nt, count, 1))) {
        f->oom = 1;
        return 1;
    }
    f->tcap = cap;
    memcpy(p->tri + 3 * p->nt, ids, 3 * sizeof(uint64_t) * count);
    if (org)
        memcpy(p->org + p->nt, org, count);
    p->nt += count;
    return 0;
}

static int fill_retire(void *user, uint64_t floor)
{
    (void)user;
    (void)floor;
    return 0;
}

static int fill_foreign(void *user, size_t first, size_t count, const uint64_t *keys,
                        const float *pos)
{
    piece_fill *f = user;
    slab_piece *p = f->p;
    size_t cap = f->fcap;
    if (first != p->nforeign ||
        !grow((void **)&p->foreign_keys, &cap, p->nforeign, count, sizeof(uint64_t)) ||
        !grow((void **)&p->foreign_pos, &(size_t){f->fcap}, p->nforeign, count,
              3 * sizeof(float))) {
        f->oom = 1;
        return 1;
    }
    f->fcap = cap;
    memcpy(p->foreign_keys + p->nforeign, keys, sizeof(uint64_t) * count);
    memcpy(p->foreign_pos + 3 * p->nforeign, pos, 3 * sizeof(float) * count);
    p->nforeign += count;
    return 0;
}

static int compare_pairs(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

int slab_extract(cli_slices *src, const isomend_options *opts, int64_t first, int64_t end,
                 slab_piece *p)
{
    memset(p, 0, sizeof *p);
    p->first = first;
    p->end = end;
    if (first >= end)
        return CLI_EXIT_OK;
    const isomend_volume *d = &src->desc;
    const isomend_piece piece = {first, end};
    int64_t a = 0, b = 0;
    isomend_status st = isomend_piece_halo(d, opts, &piece, &a, &b);
    piece_fill fill = {p, 0, 0, 0, 0};
    const isomend_mesh_sink sink = {&fill, fill_vertices, fill_triangles, fill_retire,
                                    fill_foreign};
    isomend_stream *stream = NULL;
    if (st == ISOMEND_OK)
        st = isomend_piece_begin(d, opts, &piece, &sink, &stream);
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
        st = isomend_stream_finish(stream, &p->stats);
    isomend_stream_destroy(stream);
    free(slice);
    if (!rc && st != ISOMEND_OK) {
        if (fill.oom)
            cli_error("%s: out of memory", src->label);
        else
            cli_error("%s: extraction of marched slices %lld..%lld failed: %s", src->label,
                      (long long)first, (long long)end - 1, isomend_status_string(st));
        rc = CLI_EXIT_FAIL;
    }
    if (!rc) { /* the owned in-plane vertices of the first slice, for the slab below */
        const uint64_t N0 = (uint64_t)(d->dims[0] + ((opts->flags & ISOMEND_FLAG_PAD) ? 2 : 0));
        const uint64_t N1 = (uint64_t)(d->dims[1] + ((opts->flags & ISOMEND_FLAG_PAD) ? 2 : 0));
        p->shared = malloc(2 * sizeof(uint64_t) * (p->nv + 1));
        if (!p->shared) {
            cli_error("%s: out of memory", src->label);
            rc = CLI_EXIT_FAIL;
        }
        for (size_t v = 0; !rc && v < p->nv; v++) {
            const uint64_t key = p->keys[v], kind = key & 7u;
            if (key == ISOMEND_KEY_NONE || (key >> 3) / (N0 * N1) != (uint64_t)first ||
                !(kind == 0 || kind == 1 || kind == 5))
                continue;
            p->shared[2 * p->nshared] = key;
            p->shared[2 * p->nshared + 1] = v;
            p->nshared++;
        }
        if (!rc)
            qsort(p->shared, p->nshared, 2 * sizeof(uint64_t), compare_pairs);
    }
    if (rc)
        slab_piece_free(p);
    return rc;
}
