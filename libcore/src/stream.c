/*
 * stream.c - streaming extraction: slices pushed one at a time, the mesh
 * handed to a sink as it is made (isomend_stream_*, isomend.h).
 *
 * The one engine: runs of slices driven through the kernels, scan_slice for
 * slice m and march_layer for layer m - 1 as soon as the samples they read
 * are there, the vertices numbered from the running count.  Its clients:
 * the stream (slices pushed one at a time, the mesh to a sink), the pool's
 * slabs (stream_pool.c), the pieces of isomend-mpi, and isomend_extract()'s
 * runs (slabs.c: the volume read in place, the mesh written in place,
 * stream_direct_*).  The ids, the order and the bytes are the same for all.
 * What a stream keeps:
 *
 *   the window   WINDOW planes of samples, contiguous: the grid's data
 *                points at its first plane, volume slice g.z0.  Scanning
 *                slice m reads samples m - 1 .. m + 2 (normals: central
 *                differences at both ends of the z edges), marching layer
 *                m - 1 reads m - 2 .. m + 1 (the general methods' corners,
 *                gradient's ring, the private vertices' edge points), so
 *                slice m is scanned once slice m + 2 has arrived and the
 *                window needs KEEP + 1 = 5 planes; when it is full the last
 *                KEEP planes move to its start (one plane moved per push on
 *                average with WINDOW = 8).
 *   the worker   as an extraction's (extract.c): the sign ring (SIGN_RING
 *                slices), the id maps of two slices, the row buffers.
 *   staging      one slice's vertices (positions, normals) and one layer's
 *                triangles (ids, origins), as address-space reservations of
 *                their largest possible size (mesh_memory.c): only what the
 *                largest slice and layer use is ever touched.  The kernels
 *                write vertex `id` at vertex_at(ctx.vertex_base, id), the
 *                slice's first id being vertex_base, and keep ids modulo
 *                2^32 in the id maps: a triangle of layer k has ids in
 *                [first of slice k, that + 2^32), which makes them 64-bit
 *                again (to_global).
 *
 * The table methods sweep (PASS_SWEEP: count and write at once); the
 * general methods (methods.h) march each layer twice, counting its
 * cube-private vertices first, so that they are numbered after slice m's
 * vertices.
 */
#include "context.h"
#include "vertices.h"
#include "extract.h"
#include "isomend.h"
#include "tables.h"
#include "methods.h"
#define KERNELS_SSE2 0 /* the span helpers of scan_inline.h, in portable C */
#include "scan_inline.h"
#include "stream.h"

#include <stdlib.h>

enum {
    KEEP = 4,              /* planes kept when the window moves: slices m - 2 .. m + 1 */
    WINDOW = 2 * KEEP,     /* planes of samples in the window                          */
    TRIANGLE_BATCH = 8192, /* triangles converted to 64-bit ids per sink call          */
};

/* A reservation, or when refused a heap block (mapped 0). */
typedef struct staging {
    void *p;
    size_t mapped;
} staging;

struct stream_one {
    ctx c;
    worker w;
    isomend_mesh_sink sink;
    isomend_status failed; /* the first failure, returned from then on */
    int finished;
    size_t plane_bytes;    /* a volume slice's samples */
    char *window;
    double *slice_origins; /* the stream's copy of the volume's, or NULL */
    int64_t pushed;        /* volume slices pushed */
    int64_t next_scan;     /* the next slice (marched grid) to scan */
    /* A piece (isomend_piece_begin): marched slices and layers [own_first,
     * own_end) owned, volume slices [push_first, push_end) pushed; a stream
     * owns all: 0, N2, 0, n2. */
    int64_t own_first, own_end, push_first, push_end;
    int piece;
    uint64_t *keys;  /* a piece's keys of the vertices staged */
    uint32_t *fmap;  /* slice own_end's ids to foreign indices, UINT32_MAX none */
    float *fpos;     /* the foreign vertices' positions */
    uint64_t nforeign;
    /* A box piece (columns or rows restricted): owned marched columns
     * [bx[0], bx[1]) and rows [by[0], by[1]).  A step's staged vertices
     * (ring m % 2, from staged id remap_first) map to local ids, FOREIGN | f,
     * CANDIDATE | c (not owned, in the box's frame: key and position kept in
     * ckeys, cpos until a triangle uses it) or DROPPED. */
    int box;
    int64_t bx[2], by[2];
    uint64_t *remap[2], remap_first[2], remap_count[2];
    uint64_t *ckeys[2];
    float *cpos[2];
    uint64_t delivered;  /* a box's local ids delivered */
    uint64_t *bkeys;     /* the foreign vertices of a triangle batch */
    float *bpos;
    uint64_t first_id;     /* the first vertex id: 0 (tests: stream_set_first_id) */
    uint64_t next_id;      /* the next vertex id */
    uint64_t slice_first[2]; /* first ids of the slices last scanned, ring m % 2 */
    uint64_t triangles;
    uint64_t max_slice_vertices, max_layer_vertices, max_layer_triangles;
    staging pos, nrm, tri, org;
    uint64_t *ids; /* [3 * TRIANGLE_BATCH] */
    /* A run of isomend_extract() (stream_direct_*): the volume read in place,
     * the mesh written straight into `out` (vertex id i at out.pos + 3 i,
     * the run's triangles from out.tri on), no sink; tick asked before each
     * slice past the first. */
    int direct;
    stream_out out;
    stream_tick tick;
    void *tick_user;
    stream_event event;
    void *event_user;
};


static int staging_alloc(staging *st, size_t size)
{
    st->p = reserve_output(size, SIZE_MAX);
    st->mapped = st->p ? huge_round(size) : 0;
    if (!st->p)
        st->p = calloc(1, size ? size : 1);
    return st->p != NULL;
}

static void staging_free(staging *st)
{
    if (st->p)
        release_output(st->p, st->mapped);
    st->p = NULL;
}

/* The largest possible counts: a slice's vertices (an edge or diagonal per
 * id-map plane and sample), a layer's cube-private vertices (one for each
 * private slot of a cube) and triangles (the table's and two for each of a
 * cube's +x, +y, +z faces; the general methods' per cube). */
static void stream_bounds(const ctx *c, uint64_t *slice_vertices, uint64_t *layer_vertices,
                          uint64_t *layer_triangles)
{
    const uint64_t N0 = (uint64_t)c->g.N[0], N1 = (uint64_t)c->g.N[1];
    const uint64_t cubes = (N0 - 1) * (N1 - 1);
    *slice_vertices = (uint64_t)c->id_planes * N0 * N1;
    *layer_vertices = c->general ? (uint64_t)(METHODS_SLOT_COUNT - METHODS_SLOT_CENTRE) * cubes : 0;
    *layer_triangles = (c->general ? (uint64_t)METHODS_MAX_TRI : (uint64_t)MC_MAX_TRI + 6) * cubes;
}

/* The staging sizes in bytes: positions, normals, triangles, origins. */
static void stream_sizes(const ctx *c, uint64_t size[4])
{
    uint64_t sv, lv, lt;
    stream_bounds(c, &sv, &lv, &lt);
    const uint64_t v = sv + lv; /* layer m - 1's private vertices, then slice m's */
    size[0] = 3 * sizeof(float) * v;
    size[1] = c->want_normals ? size[0] : 0;
    size[2] = 3 * sizeof(uint32_t) * lt;
    size[3] = c->want_origins ? lt : 0;
}

static isomend_status stream_init(stream_one *s, const isomend_volume *desc,
                                  const isomend_options *opts, const isomend_mesh_sink *sink)
{
    isomend_options defaults;
    isomend_options_init(&defaults);
    const isomend_options *o = opts ? opts : &defaults;
    if (!desc || !sink || !sink->vertices || !sink->triangles || !sink->retire)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_volume v = *desc;
    memset(v.strides, 0, sizeof v.strides); /* the window is contiguous */
    ctx *c = &s->c;
    isomend_status status = ctx_setup(c, &v, o);
    if (status != ISOMEND_OK)
        return status;
    s->sink = *sink;
    if (c->g.slices.so) { /* the caller's table need not outlive the call */
        const size_t size = 3 * sizeof(double) * (size_t)c->g.slices.n;
        if (!(s->slice_origins = malloc(size)))
            return ISOMEND_ERR_OUT_OF_MEMORY;
        memcpy(s->slice_origins, c->g.slices.so, size);
        c->g.slices.so = s->slice_origins;
    }
    const grid *g = &c->g;
    if ((uint64_t)g->N[0] * (uint64_t)g->N[1] > (uint64_t)SIZE_MAX / 64)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    s->plane_bytes = (size_t)g->n[0] * (size_t)g->n[1] * isomend_type_size(g->type);
    s->window = malloc(WINDOW * s->plane_bytes);
    s->ids = malloc(3 * sizeof(uint64_t) * TRIANGLE_BATCH);
    if (!s->window || !s->ids || !worker_init(&s->w, c))
        return ISOMEND_ERR_OUT_OF_MEMORY;
    s->w.is_main = 1;
    c->g.data = s->window;
    c->g.z0 = 0;
    s->own_first = 0;
    s->own_end = g->N[2];
    s->push_first = 0;
    s->push_end = g->n[2];
    c->pass = PASS_SWEEP; /* signs are classified (and NaNs counted), never cached */
    stream_bounds(c, &s->max_slice_vertices, &s->max_layer_vertices, &s->max_layer_triangles);
    uint64_t size[4];
    stream_sizes(c, size);
    staging *st[4] = {&s->pos, &s->nrm, &s->tri, &s->org};
    for (int q = 0; q < 4; q++)
        if (size[q] && !staging_alloc(st[q], (size_t)size[q]))
            return ISOMEND_ERR_OUT_OF_MEMORY;
    c->pos = s->pos.p;
    c->nrm = s->nrm.p;
    c->tri = s->tri.p;
    c->org = s->org.p; /* zero bytes: ISOMEND_ORIGIN_TABLE, as in place */
    return ISOMEND_OK;
}

static isomend_status bound_setup(ctx *c, const isomend_volume *desc, const isomend_options *opts);

isomend_status stream_one_check(const isomend_volume *desc, const isomend_options *opts)
{
    ctx c;
    return bound_setup(&c, desc, opts);
}

isomend_status stream_one_begin(const isomend_volume *desc, const isomend_options *opts,
                                const isomend_mesh_sink *sink, stream_one **out)
{
    *out = NULL;
    stream_one *s = calloc(1, sizeof(*s));
    if (!s)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    const isomend_status status = stream_init(s, desc, opts, sink);
    if (status != ISOMEND_OK) {
        stream_one_destroy(s);
        return status;
    }
    *out = s;
    return ISOMEND_OK;
}

void stream_one_destroy(stream_one *s)
{
    if (!s)
        return;
    free(s->window);
    free(s->slice_origins);
    free(s->ids);
    free(s->keys);
    free(s->fmap);
    free(s->fpos);
    for (int p = 0; p < 2; p++) {
        free(s->remap[p]);
        free(s->ckeys[p]);
        free(s->cpos[p]);
    }
    free(s->bkeys);
    free(s->bpos);
    free(s->w.block);
    staging_free(&s->pos);
    staging_free(&s->nrm);
    staging_free(&s->tri);
    staging_free(&s->org);
    free(s);
}

void stream_one_set_first_id(stream_one *s, uint64_t first)
{
    if (s->pushed == s->push_first)
        s->first_id = s->next_id = first;
}

/* A sink's answer as a status (and the stream's failure). */
static isomend_status sink_status(stream_one *s, int rc)
{
    return rc ? (s->failed = ISOMEND_ERR_SINK) : ISOMEND_OK;
}

/* Hands the n staged vertices (ids from s->next_id) to the sink, with their
 * keys if `keyed`. */
static isomend_status deliver_vertices(stream_one *s, uint64_t n, int keyed)
{
    if (!n)
        return ISOMEND_OK;
    if (s->direct) { /* written in place */
        if (s->event && s->event(s->event_user, STREAM_EV_VERTICES, s->next_id - s->first_id, n))
            return s->failed = ISOMEND_ERR_OUT_OF_MEMORY;
        s->next_id += n;
        return ISOMEND_OK;
    }
    const ctx *c = &s->c;
    const isomend_status status =
        sink_status(s, s->sink.vertices(s->sink.user, s->next_id, (size_t)n, c->pos,
                                        c->want_normals ? c->nrm : NULL,
                                        keyed ? s->keys : NULL));
    s->next_id += n;
    return status;
}

/* The key of the vertex on grid edge (or face diagonal) `kind` at (i, j, m). */
static uint64_t edge_key(const grid *g, int64_t i, int64_t j, int64_t m, int kind)
{
    return (((uint64_t)m * (uint64_t)g->N[1] + (uint64_t)j) * (uint64_t)g->N[0] + (uint64_t)i) *
               8u +
           (uint64_t)kind;
}

/* Whether tetra's diagonal of face `kind` (x, y, z face: 0, 1, 2) at
 * (i, j, m) is cut: its ends are the face's even corners (scan_diagonals). */
static int diagonal_cut(const uint8_t *a, const uint8_t *b, const uint8_t *d, const uint8_t *e,
                        int64_t i, int even, int kind)
{
    switch (kind) {
    case 0: return even ? a[i] != e[i] : b[i] != d[i];
    case 1: return even ? a[i] != d[i + 1] : a[i + 1] != d[i];
    default: return even ? a[i] != b[i + 1] : a[i + 1] != b[i];
    }
}

/* The position of slice m's in-plane vertex `key` (an x or y edge, a z
 * face's diagonal) by the general vertex path (the same as the vertex
 * loops', vertices.c), which reads slices m - 1 .. m + 1 only: a piece's
 * next slice, whose vertices are not computed. */
static void plane_position(const stream_one *s, uint64_t key, int64_t m, float p[3])
{
    const ctx *c = &s->c;
    const grid *g = &c->g;
    const unsigned kind = (unsigned)(key & 7u);
    const uint64_t lin = key >> 3;
    const int64_t i = (int64_t)(lin % (uint64_t)g->N[0]);
    const int64_t j = (int64_t)(lin / (uint64_t)g->N[0] % (uint64_t)g->N[1]);
    if (kind < 3) {
        make_vertex(g, c->flip, i, j, m, (int)kind, p, NULL);
    } else { /* the z face's diagonal between its even corners, lower sample first */
        const int even = ((i + j + m) & 1) == 0;
        const int64_t lo[3] = {even ? i : i + 1, j, m}, hi[3] = {even ? i + 1 : i, j + 1, m};
        make_vertex_between(g, c->flip, lo, hi, p, NULL);
    }
}

/*
 * A piece's keys of slice m's nv vertices (ids from first) into
 * s->keys[np ..], np = first - s->next_id (the private vertices before
 * them).  For the next piece's slice (`last`), the foreign table instead:
 * the in-plane vertices (x, y edges, z-face diagonals), in id order,
 * delivered through sink.foreign, and s->fmap from ids to their indices.
 */
static isomend_status slice_keys(stream_one *s, int64_t m, uint64_t first, uint64_t nv,
                                 int last)
{
    const ctx *c = &s->c;
    const grid *g = &c->g;
    worker *w = &s->w;
    const int64_t N0 = g->N[0], N1 = g->N[1], N2 = g->N[2], plane = N0 * N1;
    const row_span *rn = NULL, *ra;
    const uint8_t *t = m + 1 < N2 ? c->kernels->signs(w, m + 1, &rn) : NULL;
    const uint8_t *sg = c->kernels->signs(w, m, &ra);
    const uint32_t *map = w->edge_ids[m % 2];
    uint64_t *keys = s->keys + (first - s->next_id);
    const uint32_t low = (uint32_t)first;
    for (int64_t j = c->cube_lo[1]; j <= c->cube_hi[1] && !c->tetra; j++) {
        /* the x, y and z edges where the rows' spans allow a crossing */
        const uint8_t *a = sg + j * N0, *other[3] = {a + 1, j + 1 < N1 ? a + N0 : NULL,
                                                     t ? t + j * N0 : NULL};
        for (int kind = 0; kind < 3; kind++) {
            if (!other[kind])
                continue;
            int64_t sp[4];
            int n = kind == 0 ? row_spans(&ra[j], N0, sp)
                              : pair_spans(&ra[j], kind == 1 ? &ra[j + 1] : &rn[j], N0, sp);
            n = clip_spans(sp, n, c->cube_lo[0], kind == 0 && c->cube_hi[0] == N0 - 1
                                                      ? N0 - 2
                                                      : c->cube_hi[0]);
            const uint8_t *b = other[kind];
            /* 16 signs a compare (as the scan numbers them, number_crossings): a
             * pool's slabs key two slices each, a sample at a time cost as much
             * as scanning them */
            for (int q = 0; q < n; q++)
                for (int64_t i = sp[2 * q]; i <= sp[2 * q + 1]; i += 16) {
                    uint32_t diff = diff16(a + i, b + i);
                    if (sp[2 * q + 1] - i < 15)
                        diff = first_bits(diff, sp[2 * q + 1] - i + 1);
                    while (diff) {
                        const int64_t x = i + __builtin_ctz(diff);
                        diff &= diff - 1;
                        const uint64_t r = (uint32_t)(map[kind * plane + j * N0 + x] - low);
                        if (r >= nv)
                            return s->failed = ISOMEND_ERR_INVALID_ARGUMENT; /* not reached */
                        keys[r] = edge_key(g, x, j, m, kind);
                    }
                }
        }
    }
    for (int64_t j = c->cube_lo[1]; j <= c->cube_hi[1] && c->tetra; j++) { /* every column */
        const uint8_t *a = sg + j * N0, *b = j + 1 < N1 ? a + N0 : NULL;
        const uint8_t *d = t ? t + j * N0 : NULL, *e = t && b ? d + N0 : NULL;
        for (int64_t i = c->cube_lo[0]; i <= c->cube_hi[0]; i++) {
            const int64_t at = j * N0 + i;
            int cut[6] = {i + 1 < N0 && a[i] != a[i + 1], b && a[i] != b[i], d && a[i] != d[i],
                          0, 0, 0};
            if (c->tetra) {
                const int even = ((i + j + m) & 1) == 0;
                cut[3] = e && diagonal_cut(a, b, d, e, i, even, 0);
                cut[4] = d && i + 1 < N0 && diagonal_cut(a, b, d, e, i, even, 1);
                cut[5] = b && i + 1 < N0 && diagonal_cut(a, b, d, e, i, even, 2);
            }
            for (int kind = 0; kind < 6; kind++) {
                if (!cut[kind])
                    continue;
                const uint64_t r = (uint32_t)(map[kind * plane + at] - low);
                if (r >= nv)
                    return s->failed = ISOMEND_ERR_INVALID_ARGUMENT; /* not reached */
                keys[r] = edge_key(g, i, j, m, kind);
            }
        }
    }
    if (!last)
        return ISOMEND_OK;
    /* In id order, the in-plane vertices: kinds 0, 1 and 5 (z-face diagonal). */
    uint64_t nf = 0;
    for (uint64_t r = 0; r < nv; r++) {
        const unsigned kind = (unsigned)(keys[r] & 7u);
        s->fmap[r] = UINT32_MAX;
        if (kind == 0 || kind == 1 || kind == 5) {
            s->fmap[r] = (uint32_t)nf;
            keys[nf++] = keys[r];
        }
    }
    s->nforeign = nf;
    if (!nf)
        return ISOMEND_OK;
    for (uint64_t f = 0; f < nf; f++)
        plane_position(s, keys[f], m, s->fpos + 3 * f);
    return sink_status(s, s->sink.foreign(s->sink.user, 0, (size_t)nf, keys, s->fpos));
}

/* ------------------------------------------------------------ box pieces */

#define CANDIDATE ((uint64_t)1 << 62)
#define DROPPED UINT64_MAX

/* The NaN samples of the box's part of marched slice m (padding excluded). */
static uint64_t box_nans(const stream_one *s, int64_t m)
{
    const grid *g = &s->c.g;
    if ((g->type != ISOMEND_F32 && g->type != ISOMEND_F64) || m < g->pad || m >= g->n[2] + g->pad)
        return 0;
    const int64_t i0 = s->bx[0] > g->pad ? s->bx[0] : g->pad;
    const int64_t i1 = s->bx[1] < g->n[0] + g->pad ? s->bx[1] : g->n[0] + g->pad;
    const int64_t j0 = s->by[0] > g->pad ? s->by[0] : g->pad;
    const int64_t j1 = s->by[1] < g->n[1] + g->pad ? s->by[1] : g->n[1] + g->pad;
    uint64_t n = 0;
    for (int64_t j = j0; j < j1; j++)
        for (int64_t i = i0; i < i1; i++)
            n += (uint64_t)isnan(fetch(g, i, j, m));
    return n;
}

/*
 * A box's step m: of the np + nv vertices staged (layer m - 1's private
 * ones, slice m's, keyed in s->keys), delivers the owned ones, compacted,
 * and keeps the candidates of the frame; *floor is the local id of the
 * first owned vertex of slice m (all delivered for the next slice).
 */
static isomend_status box_vertices(stream_one *s, int64_t m, uint64_t np, uint64_t nv,
                                   int last, uint64_t *floor)
{
    ctx *c = &s->c;
    const grid *g = &c->g;
    const int p = (int)(m % 2);
    uint64_t *remap = s->remap[p], *ck = s->ckeys[p], *keys = s->keys;
    float *cp = s->cpos[p], *pos = c->pos, *nrm = c->want_normals ? c->nrm : NULL;
    const uint64_t N0 = (uint64_t)g->N[0], N1 = (uint64_t)g->N[1];
    s->remap_first[p] = s->next_id;
    s->remap_count[p] = np + nv;
    uint64_t out = 0, nc = 0;
    for (uint64_t r = 0; r < np + nv; r++) {
        const uint64_t key = keys[r];
        int own = key == ISOMEND_KEY_NONE, near = 0;
        if (!own) {
            const uint64_t lin = key >> 3;
            const int64_t i = (int64_t)(lin % N0), j = (int64_t)(lin / N0 % N1);
            const unsigned kind = (unsigned)(key & 7u);
            near = i >= s->bx[0] && i <= s->bx[1] && j >= s->by[0] && j <= s->by[1];
            own = near && !last && i < s->bx[1] && j < s->by[1];
            /* the next slice's vertices a layer below uses: x, y edges, z-face diagonals */
            near = near && (!last || kind == 0 || kind == 1 || kind == 5);
        }
        if (own) {
            if (out != r) {
                keys[out] = key;
                memcpy(pos + 3 * out, pos + 3 * r, 3 * sizeof(float));
                if (nrm)
                    memcpy(nrm + 3 * out, nrm + 3 * r, 3 * sizeof(float));
            }
            remap[r] = s->delivered + out++;
        } else if (near) {
            ck[nc] = key;
            if (last)
                plane_position(s, key, m, cp + 3 * nc);
            else
                memcpy(cp + 3 * nc, pos + 3 * r, 3 * sizeof(float));
            remap[r] = CANDIDATE | nc++;
        } else {
            remap[r] = DROPPED;
        }
    }
    *floor = s->delivered + (last ? out : np); /* the private vertices are all owned */
    s->next_id += np + nv;
    isomend_status status = ISOMEND_OK;
    if (out)
        status = sink_status(s, s->sink.vertices(s->sink.user, s->delivered, (size_t)out, pos,
                                                 nrm, keys));
    s->delivered += out;
    return status;
}

/* A box's id of staged vertex `id` (of slice m - 1, layer m - 1 or slice m:
 * the two steps' rings): local, or foreign, a candidate becoming the next
 * foreign vertex (queued in bkeys, bpos from *queued on) at its first use. */
static int box_id(stream_one *s, uint64_t id, int64_t m, uint64_t *out, size_t *queued)
{
    const int now = (int)(m % 2), p = id >= s->remap_first[now] ? now : 1 - now;
    const uint64_t r = id - s->remap_first[p];
    if (id < s->remap_first[p] || r >= s->remap_count[p] || s->remap[p][r] == DROPPED)
        return 0; /* not reached */
    uint64_t *v = &s->remap[p][r];
    if ((*v & (CANDIDATE | ISOMEND_FOREIGN)) == CANDIDATE) {
        const uint64_t cand = *v & ~CANDIDATE;
        s->bkeys[*queued] = s->ckeys[p][cand];
        memcpy(s->bpos + 3 * *queued, s->cpos[p] + 3 * cand, 3 * sizeof(float));
        *v = ISOMEND_FOREIGN | s->nforeign++;
        ++*queued;
    }
    *out = *v;
    return 1;
}

/* Layer m - 1's n staged triangles, their ids made 64-bit from `base` (the
 * first id of slice m - 1: every id of the layer is in [base, base + 2^32));
 * for a piece, ids from `foreign` on (its last layer) are the next piece's;
 * for a box, ids go through box_id(), each batch's new foreign vertices
 * delivered before it.  A run in place (direct) has written them where they
 * stay. */
static isomend_status deliver_triangles(stream_one *s, uint64_t n, uint64_t base,
                                        uint64_t foreign, int64_t m)
{
    const ctx *c = &s->c;
    const uint32_t low = (uint32_t)base;
    if (s->direct) { /* written in place, the ids the run's */
        if (n && s->event && s->event(s->event_user, STREAM_EV_TRIANGLES, s->triangles, n))
            return s->failed = ISOMEND_ERR_OUT_OF_MEMORY;
        s->triangles += n;
        return ISOMEND_OK;
    }
    for (uint64_t done = 0; done < n;) {
        const uint64_t b = n - done < TRIANGLE_BATCH ? n - done : TRIANGLE_BATCH;
        const uint32_t *t = c->tri + 3 * done;
        const uint64_t nf = s->nforeign;
        size_t queued = 0;
        for (uint64_t q = 0; q < 3 * b; q++) {
            const uint64_t id = base + (uint32_t)(t[q] - low);
            if (s->box) {
                if (!box_id(s, id, m, &s->ids[q], &queued))
                    return s->failed = ISOMEND_ERR_INVALID_ARGUMENT;
            } else {
                s->ids[q] = id < foreign ? id : ISOMEND_FOREIGN | s->fmap[id - foreign];
            }
        }
        int rc = queued ? s->sink.foreign(s->sink.user, (size_t)nf, queued, s->bkeys, s->bpos) : 0;
        if (!rc)
            rc = s->sink.triangles(s->sink.user, (size_t)b, s->ids, c->org ? c->org + done : NULL);
        if (rc)
            return sink_status(s, rc);
        done += b;
    }
    if (c->org) /* the next layer's table triangles are zero bytes again */
        memset(c->org, 0, (size_t)n);
    s->triangles += n;
    return ISOMEND_OK;
}

/*
 * Scans slice m (numbering from the running count) and marches layer m - 1,
 * delivering layer m - 1's cube-private vertices (general methods: counted
 * first, from the signs alone, so that slice m is numbered after them), slice
 * m's vertices, then layer m - 1's triangles.
 */
static isomend_status step(stream_one *s, int64_t m)
{
    ctx *c = &s->c;
    worker *w = &s->w;
    const extract_kernels *kr = c->kernels;
    const int64_t k = m - 1;
    const int layer = m > s->own_first; /* layer m - 1 is this piece's */
    const int last = m == s->own_end;   /* a piece's next slice: ids only */
    uint64_t np = 0, nt = 0;
    if (layer && c->general) {
        nt = kr->march_layer(w, k, PASS_COUNT, 0);
        np = w->private_count;
    }
    c->vertex_base = c->private_first = s->next_id;
    if (s->direct) { /* this step's vertices and triangles where they go */
        c->pos = s->out.pos + 3 * s->next_id;
        c->nrm = s->out.nrm ? s->out.nrm + 3 * s->next_id : NULL;
        c->tri = s->out.tri + 3 * s->triangles;
        c->org = s->out.org ? s->out.org + s->triangles : NULL;
    }
    /* in place, slice m + 2 classified first: the gradients at slice m's z
     * edges read its samples, which this brings into the caches */
    if (s->direct && !last && m + 2 < c->g.N[2]) {
        const row_span *ahead;
        (void)kr->signs(w, m + 2, &ahead);
    }
    const uint64_t first = s->next_id + np;
    const uint64_t nv = kr->scan_slice(w, m, PASS_SWEEP, first, !last);
    if (!last)
        w->stats.nan_samples += s->box ? box_nans(s, m) : w->slice_nans[m % SIGN_RING];
    const uint64_t below = layer ? s->slice_first[(m - 1) % 2] : first;
    s->slice_first[m % 2] = first;
    if (s->direct ? first + nv > (uint64_t)UINT32_MAX + 1 : first + nv - below > UINT32_MAX)
        return s->failed = ISOMEND_ERR_TOO_LARGE; /* the id maps' (a run's ids') 32 bits */
    if (layer && c->general) /* the private vertices and the triangles */
        (void)kr->march_layer(w, k, PASS_FILL, 0);
    isomend_status status = ISOMEND_OK;
    const int keyed = s->piece;
    if (keyed) {
        for (uint64_t q = 0; q < np; q++)
            s->keys[q] = ISOMEND_KEY_NONE;
        status = slice_keys(s, m, first, nv, last && !s->box);
    }
    uint64_t floor = 0;
    if (status == ISOMEND_OK)
        status = s->box ? box_vertices(s, m, np, nv, last, &floor)
                        : deliver_vertices(s, last ? np : np + nv, keyed);
    if (status != ISOMEND_OK || !layer)
        return status;
    if (!c->general)
        nt = kr->march_layer(w, k, PASS_SWEEP, 0);
    status = deliver_triangles(s, nt, below, last ? first : UINT64_MAX, m);
    if (!s->box)
        floor = last ? s->next_id : first;
    if (status == ISOMEND_OK && !s->direct)
        status = sink_status(s, s->sink.retire(s->sink.user, floor));
    else if (status == ISOMEND_OK && s->event &&
             (s->event(s->event_user, STREAM_EV_RETIRE, floor - s->first_id, 0) ||
              (last && s->event(s->event_user, STREAM_EV_NEXT, 0, nv))))
        status = s->failed = ISOMEND_ERR_OUT_OF_MEMORY;
    return status;
}

/* Scans and marches what the samples of marched slices up to `avail` allow. */
static isomend_status advance(stream_one *s, int64_t avail)
{
    const int64_t N2 = s->c.g.N[2];
    /* and a piece's next slice */
    while (s->next_scan < (s->own_end < N2 ? s->own_end + 1 : N2)) {
        const int64_t m = s->next_scan;
        if (s->tick && m > s->own_first && m < s->own_end) {
            const int go = s->tick(s->tick_user, m);
            if (go < 0)
                return s->failed = ISOMEND_ERR_CANCELLED;
            if (go == 0)
                s->own_end = m; /* slice m is the run's last: ids only */
        }
        int64_t need = m + (m == s->own_end ? 1 : 2); /* the next slice: signs of m + 1 */
        if (need > N2 - 1)
            need = N2 - 1;
        if (need > avail)
            break;
        const isomend_status status = step(s, m);
        if (status != ISOMEND_OK)
            return status;
        s->next_scan++;
    }
    return ISOMEND_OK;
}

isomend_status stream_one_push(stream_one *s, const void *slice)
{
    if (s->failed != ISOMEND_OK)
        return s->failed;
    grid *g = &s->c.g;
    const int64_t z = s->pushed;
    if (z >= s->push_end || s->finished)
        return s->failed = ISOMEND_ERR_SLICE_COUNT;
    if (z - g->z0 >= WINDOW) { /* keep the planes still needed, from the lowest */
        int64_t lo = s->next_scan - 2 - g->pad; /* layer next_scan - 1 reads next_scan - 2 */
        if (lo < g->z0)
            lo = g->z0;
        memmove(s->window, s->window + (size_t)(lo - g->z0) * s->plane_bytes,
                (size_t)(z - lo) * s->plane_bytes);
        g->z0 = lo;
    }
    memcpy(s->window + (size_t)(z - g->z0) * s->plane_bytes, slice, s->plane_bytes);
    s->pushed = z + 1;
    return advance(s, z + g->pad);
}

isomend_status stream_one_finish(stream_one *s, isomend_stats *stats)
{
    if (s->failed != ISOMEND_OK)
        return s->failed;
    const grid *g = &s->c.g;
    if (s->pushed != s->push_end)
        return s->failed = ISOMEND_ERR_SLICE_COUNT;
    const isomend_status status = advance(s, g->N[2] - 1);
    if (status != ISOMEND_OK)
        return status;
    s->finished = 1;
    if (stats) {
        const ctx *c = &s->c;
        gather_stats(c, &s->w, 1, s->box ? s->delivered : s->next_id - s->first_id,
                     s->triangles, stats);
        const int64_t layers = (s->own_end < g->N[2] ? s->own_end : g->N[2] - 1) - s->own_first;
        stats->cubes = (uint64_t)(c->cube_hi[0] - c->cube_lo[0]) *
                       (uint64_t)(c->cube_hi[1] - c->cube_lo[1]) * (uint64_t)layers;
    }
    return ISOMEND_OK;
}

/* The context of a stream of `desc` with `opts` (NULL: the defaults), for
 * the bounds and the halo: ISOMEND_OK or why a stream would be refused. */
static isomend_status bound_setup(ctx *c, const isomend_volume *desc, const isomend_options *opts)
{
    isomend_options defaults;
    isomend_options_init(&defaults);
    if (!desc)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    isomend_volume v = *desc;
    memset(v.strides, 0, sizeof v.strides);
    memset(c, 0, sizeof *c);
    return ctx_setup(c, &v, opts ? opts : &defaults);
}

uint64_t isomend_stream_vertex_bound(const isomend_volume *desc, const isomend_options *opts)
{
    ctx c;
    if (bound_setup(&c, desc, opts) != ISOMEND_OK)
        return 0;
    uint64_t sv, lv, lt;
    stream_bounds(&c, &sv, &lv, &lt);
    return sv + lv;
}

/* ------------------------------------------------------------------ pieces */

/* The volume slices [*first, *end) a piece reads: marched slices
 * owned_first - 1 .. owned_end + 1, clamped to the volume. */
static isomend_status piece_range(const grid *g, const isomend_piece *piece, int64_t *first,
                                  int64_t *end)
{
    if (!piece || piece->owned_first < 0 || piece->owned_first >= piece->owned_end ||
        piece->owned_end > g->N[2])
        return ISOMEND_ERR_INVALID_ARGUMENT;
    const int64_t *range[2] = {piece->columns, piece->rows};
    for (int a = 0; a < 2; a++)
        if (!(range[a][0] == 0 && range[a][1] == 0) &&
            (range[a][0] < 0 || range[a][0] >= range[a][1] || range[a][1] > g->N[a]))
            return ISOMEND_ERR_INVALID_ARGUMENT;
    int64_t lo = piece->owned_first - 1 - g->pad, hi = piece->owned_end + 2 - g->pad;
    *first = lo < 0 ? 0 : lo;
    *end = hi > g->n[2] ? g->n[2] : hi;
    return ISOMEND_OK;
}

isomend_status isomend_piece_halo(const isomend_volume *desc, const isomend_options *opts,
                                  const isomend_piece *piece, int64_t *first, int64_t *end)
{
    if (!first || !end)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    ctx c;
    const isomend_status status = bound_setup(&c, desc, opts);
    if (status != ISOMEND_OK)
        return status;
    return piece_range(&c.g, piece, first, end);
}

isomend_status stream_one_piece_begin(const isomend_volume *desc, const isomend_options *opts,
                                     const isomend_piece *piece, const isomend_mesh_sink *sink,
                                     stream_one **out)
{
    *out = NULL;
    stream_one *s = calloc(1, sizeof(*s));
    if (!s)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    isomend_status status = stream_init(s, desc, opts, sink);
    const grid *g = &s->c.g;
    if (status == ISOMEND_OK)
        status = piece_range(g, piece, &s->push_first, &s->push_end);
    if (status == ISOMEND_OK) {
        ctx *c = &s->c;
        const int64_t *range[2] = {piece->columns, piece->rows};
        int64_t *own[2] = {s->bx, s->by};
        for (int a = 0; a < 2; a++) {
            const int all = range[a][0] == 0 && (range[a][1] == 0 || range[a][1] == g->N[a]);
            own[a][0] = all ? 0 : range[a][0];
            own[a][1] = all ? g->N[a] : range[a][1];
            s->box |= !all;
            c->cube_lo[a] = own[a][0]; /* (the +x/+y frame is their corners') */
            c->cube_hi[a] = own[a][1] < g->N[a] - 1 ? own[a][1] : g->N[a] - 1;
        }
        const int at_end = piece->owned_end == g->N[2] && s->bx[1] == g->N[0] &&
                           s->by[1] == g->N[1];
        if (!at_end && !sink->foreign)
            status = ISOMEND_ERR_INVALID_ARGUMENT;
    }
    if (status == ISOMEND_OK) {
        s->piece = 1;
        s->own_first = s->next_scan = piece->owned_first;
        s->own_end = piece->owned_end;
        s->pushed = s->c.g.z0 = s->push_first;
        const uint64_t cap = s->max_slice_vertices + s->max_layer_vertices;
        s->keys = malloc(sizeof(uint64_t) * (size_t)cap);
        s->fmap = malloc(sizeof(uint32_t) * (size_t)s->max_slice_vertices);
        s->fpos = malloc(3 * sizeof(float) * (size_t)s->max_slice_vertices);
        if (!s->keys || !s->fmap || !s->fpos)
            status = ISOMEND_ERR_OUT_OF_MEMORY;
        for (int p = 0; p < 2 && s->box && status == ISOMEND_OK; p++) {
            s->remap[p] = malloc(sizeof(uint64_t) * (size_t)cap);
            s->ckeys[p] = malloc(sizeof(uint64_t) * (size_t)cap);
            s->cpos[p] = malloc(3 * sizeof(float) * (size_t)cap);
            if (!s->remap[p] || !s->ckeys[p] || !s->cpos[p])
                status = ISOMEND_ERR_OUT_OF_MEMORY;
        }
        if (s->box && status == ISOMEND_OK) {
            s->bkeys = malloc(3 * sizeof(uint64_t) * TRIANGLE_BATCH);
            s->bpos = malloc(9 * sizeof(float) * TRIANGLE_BATCH);
            if (!s->bkeys || !s->bpos)
                status = ISOMEND_ERR_OUT_OF_MEMORY;
        }
    }
    if (status != ISOMEND_OK) {
        stream_one_destroy(s);
        return status;
    }
    *out = s;
    return ISOMEND_OK;
}

/* One stream's (or piece's) memory, without a pool. */
static uint64_t single_memory(const ctx *c, int piece)
{
    worker w;
    uint64_t size[4];
    stream_sizes(c, size);
    const uint64_t plane = (uint64_t)c->g.n[0] * (uint64_t)c->g.n[1] * isomend_type_size(c->g.type);
    uint64_t total = sizeof(stream_one) + WINDOW * plane + worker_layout(&w, c, NULL) +
                     3 * sizeof(uint64_t) * TRIANGLE_BATCH;
    for (int q = 0; q < 4; q++)
        total += huge_round((size_t)size[q]);
    if (piece) { /* keys, the foreign map and positions */
        uint64_t sv, lv, lt;
        stream_bounds(c, &sv, &lv, &lt);
        total += 8 * (sv + lv) + 16 * sv;
    }
    return total;
}

/* A new run on the same stream: counters and the worker's slices and
 * statistics cleared, its memory kept. */
static void run_reset(stream_one *s)
{
    s->slice_first[0] = s->slice_first[1] = 0;
    s->triangles = s->nforeign = 0;
    worker *w = &s->w;
    for (int r = 0; r < SIGN_RING; r++)
        w->slice_held[r] = -1;
    memset(&w->stats, 0, sizeof w->stats);
    memset(w->pending_count, 0, sizeof w->pending_count);
    w->private_count = w->private_next = 0;
}

uint64_t stream_one_memory(const isomend_volume *desc, const isomend_options *opts, int piece,
                           int64_t *pad)
{
    ctx c;
    if (bound_setup(&c, desc, opts) != ISOMEND_OK)
        return 0;
    *pad = c.g.pad;
    return single_memory(&c, piece);
}

/* ------------------------------------------- isomend_extract()'s runs */

isomend_status stream_direct_begin(const isomend_volume *vol, const isomend_options *opts,
                                   stream_one **out)
{
    *out = NULL;
    stream_one *s = calloc(1, sizeof(*s));
    if (!s)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    ctx *c = &s->c;
    isomend_status status = ctx_setup(c, vol, opts); /* the volume's own strides */
    if (status == ISOMEND_OK && !worker_init(&s->w, c))
        status = ISOMEND_ERR_OUT_OF_MEMORY;
    if (status != ISOMEND_OK) {
        stream_one_destroy(s);
        return status;
    }
    s->w.is_main = 1;
    s->direct = 1;
    c->g.z0 = 0; /* read in place: c->g.data is the volume's */
    c->pass = PASS_SWEEP;
    s->push_first = 0;
    s->push_end = c->g.n[2];
    *out = s;
    return ISOMEND_OK;
}

isomend_status stream_direct_run(stream_one *s, const stream_run *run, isomend_stats *stats,
                                 uint64_t *nv, uint64_t *nt)
{
    s->own_first = s->next_scan = run->first;
    s->own_end = run->end;
    s->pushed = s->push_end;
    s->failed = ISOMEND_OK;
    s->finished = 0;
    s->first_id = s->next_id = run->first_id;
    s->out = run->out;
    s->tick = run->tick;
    s->tick_user = run->tick_user;
    s->event = run->event;
    s->event_user = run->event_user;
    if (run->planes) { /* a slab's planes, read in place */
        s->c.g.data = run->planes;
        s->c.g.z0 = run->z0;
    }
    run_reset(s);
    const isomend_status status = stream_one_finish(s, stats);
    *nv = s->next_id - s->first_id;
    *nt = s->triangles;
    return status;
}

uint64_t stream_direct_count(stream_one *s, int64_t k, int layer, uint64_t *nt)
{
    worker *w = &s->w;
    uint64_t nv = s->c.kernels->scan_slice(w, k, PASS_COUNT, 0, 0);
    *nt = 0;
    if (layer) {
        *nt = s->c.kernels->march_layer(w, k, PASS_COUNT, 0);
        nv += w->private_count;
    }
    return nv;
}

void stream_run_bounds(const isomend_volume *desc, const isomend_options *opts,
                       uint64_t *slice_vertices, uint64_t *layer_triangles)
{
    ctx c;
    *slice_vertices = *layer_triangles = 0;
    if (bound_setup(&c, desc, opts) != ISOMEND_OK)
        return;
    uint64_t sv, lv, lt;
    stream_bounds(&c, &sv, &lv, &lt);
    *slice_vertices = sv + lv;
    *layer_triangles = lt;
}
