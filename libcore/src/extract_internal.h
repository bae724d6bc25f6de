/*
 * extract_internal.h - what the files of the extraction share (private).
 *
 * The extraction, file by file (extract.c has the overview of the passes):
 *
 *   extract.c          the driver: checks the arguments, describes the grid,
 *                      sets up the context and the workers, takes the one
 *                      pass or the two passes, gathers the statistics;
 *                      isomend_extract() and isomend_extract_recycle()
 *   passes.c           the two passes: chunks of layers on threads, the
 *                      prefix sums between them, the output arrays
 *   one_pass.c         the one pass for one or two threads, its split
 *                      between two threads and the join of a split apart
 *   sign_cache.c       the counting pass's signs kept for the fill pass
 *   vertices.c         the general vertex path (borders, NaN, padding,
 *                      face diagonals), exact per-type gradients
 *   march_general.c    the per-cube hook of methods.h, tetra's diagonals
 *   mesh_memory.c      output and scratch memory: huge pages, address-space
 *                      reservations, recycling an old mesh's pages
 *   cpu_features.c     the CPU probe (once), the choice of kernels
 *   kernels_scalar.c   the kernels (classification, numbering, vertex loops,
 *   kernels_sse2.c     marching), compiled once per CPU target from the
 *   kernels_avx2.c     templates listed in kernels_template.h
 *
 * The kernels are the loops that touch every sample or every cube.  They
 * are written once, in *_template.h headers, and instantiated per target
 * (portable C, SSE2, AVX2) and, inside a target, per voxel type.  Everything
 * else calls them through the table chosen once per extraction
 * (ctx.kernels, see kernels_select() in cpu_features.h).
 */
#ifndef ISOMEND_EXTRACT_INTERNAL_H
#define ISOMEND_EXTRACT_INTERNAL_H

#include "isomend.h"
#include "mesh_internal.h"

#include <math.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

/* ------------------------------------------------------------ the grid */

typedef struct grid {
    const char *data;
    isomend_type type;
    int64_t n[3];  /* the volume's dimensions                      */
    int64_t st[3]; /* byte strides                                  */
    int64_t pad;   /* 0 or 1                                        */
    int64_t z0;    /* the volume slice `data` points at: 0, or in a
                    * stream the first slice of its window (stream.c) */
    int64_t N[3];  /* marched grid: n + 2 pad                      */
    int64_t off[2]; /* the larger grid's marched column and row of this
                     * grid's column and row 0: 0, or for a box piece the
                     * crop's (stream.c); positions use them, nothing else */
    double iso;
    double h[3];   /* spacing                                       */
    double inv2h[3]; /* 1 / (2 spacing), for central differences    */
    int64_t inner_lo[3], inner_hi[3]; /* marched samples with all 6 neighbours in the volume */
    double o[3];   /* world position of marched sample (0, 0, 0)   */
    slice_table slices; /* slices where they are (so NULL: uniform); the
                         * kernels then send every vertex to make_vertex */
    int constant;  /* integer types: -1 none, 0 all out, 1 all in */
    int64_t ithr;  /* integer types: inside iff v >= ithr           */
    float fthr;    /* f32: the smallest float >= iso               */
} grid;

/* The sample of type `type` at p as a double (exact for every type). */
static inline __attribute__((always_inline)) double sample_as_double(isomend_type type,
                                                                     const char *p)
{
    switch (type) {
    case ISOMEND_U8: { uint8_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_I8: { int8_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_U16: { uint16_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_I16: { int16_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_I32: { int32_t v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_F32: { float v; memcpy(&v, p, sizeof v); return v; }
    case ISOMEND_F64: { double v; memcpy(&v, p, sizeof v); return v; }
    }
    return NAN;
}

/* Sample (i, j, k) of the marched grid as a double; NaN for padding. */
static inline double fetch(const grid *g, int64_t i, int64_t j, int64_t k)
{
    i -= g->pad;
    j -= g->pad;
    k -= g->pad;
    if ((uint64_t)i >= (uint64_t)g->n[0] || (uint64_t)j >= (uint64_t)g->n[1] ||
        (uint64_t)k >= (uint64_t)g->n[2])
        return NAN;
    return sample_as_double(g->type,
                            g->data + i * g->st[0] + j * g->st[1] + (k - g->z0) * g->st[2]);
}

/*
 * Sign rows.  A row of the marched grid is stored as bytes (1 = inside) plus
 * its span: `lo`, the first column whose sign differs from column 0 (N0 when
 * the row is uniform), and `hi`, the last column whose sign differs from the
 * last column (-1 when uniform).  Outside [lo - 1, hi] the row is constant,
 * which is what lets every loop skip the empty parts of a row.  A `simple`
 * row is one run [lo, hi] of the other sign in a constant row (a chord
 * through a blob): rows of cubes between four simple rows are empty inside
 * the runs' overlap too.
 */
typedef struct row_span {
    int64_t lo, hi;
    uint8_t first, last;
    uint8_t simple; /* one run [lo, hi] of the other sign, constant around it */
} row_span;

/* ---------------------------------------------------------- the passes */

/*
 * What a pass does with a slice or a layer (extract.c has the overview).
 *   PASS_COUNT  counts the intersected edges, the triangles and the
 *               statistics; nothing is written.
 *   PASS_FILL   numbers the edges from the counts' prefix sums, computes
 *               the vertices and writes the triangles.
 *   PASS_SWEEP  the one pass: counts and writes at once, the ids following
 *               the running count.
 * ctx.pass is the pass under way; the sign slices come from the sign cache
 * in PASS_FILL and are classified (counting NaN samples) in the others.
 */
typedef enum pass_kind { PASS_COUNT, PASS_FILL, PASS_SWEEP } pass_kind;

/* Sign slices a worker holds: a layer's three (k, k + 1 and k + 2 for the
 * +z neighbours), and in the one-pass path the next, read ahead. */
enum { SIGN_RING = 4 };

/* Sign and case buffers carry SCAN_PAD bytes of slack for the 16-column
 * scans' reads past a row's last column (scan_inline.h). */
enum { SCAN_PAD = 32 };

/*
 * Vertices numbered but not yet computed (the vertex lists, see
 * vertex_loops_template.h): the edge's lower end, column x and row j; the
 * slice is the list's.
 */
typedef struct vertex_item {
    uint32_t id;
    int32_t x, j;
} vertex_item;

enum {
    VERTEX_LIST = 2048,   /* items the lists hold before they are computed (plus a row) */
    VERTEX_PREFETCH = 6,  /* prefetch distance, in items                               */
    LIST_SPAN = 32,       /* spans narrower than this go to the lists                  */
    NARROW_CUBES = 16,    /* spans of fewer cubes skip row_cases (march_layer)         */
};

struct extract_kernels;
struct split;

/* One extraction: the grid, the options, the counts and the output arrays. */
typedef struct ctx {
    grid g;
    const struct extract_kernels *kernels; /* the loops for this CPU (kernels_select) */
    isomend_method method;
    int flip;
    int want_normals;
    int want_origins;
    int small_pages;       /* ISOMEND_FLAG_SMALL_PAGES: no huge pages asked for */
    int64_t nchunks;
    int64_t chunk_layers;
    uint64_t *slice_first; /* [N2 + 1]: vertex count, then first vertex */
    uint64_t *layer_first; /* [N2]: triangle count, then first triangle */
    uint64_t *layer_private; /* [N2]: cube-private vertices (methods.h), then first */
    int general;           /* a method of methods.h: per-cube hook        */
    int tetra;             /* ... with face-diagonal vertices             */
    int id_planes;         /* id-map planes per slice: 3, or 6 for tetra  */
    /* The cubes march_layer marches: columns [cube_lo[0], cube_hi[0]) and rows
     * [cube_lo[1], cube_hi[1]), all (0, N - 1) but for a box piece.  Their
     * corners, columns and rows [cube_lo, cube_hi], are the samples whose
     * edges scan_slice numbers. */
    int64_t cube_lo[2], cube_hi[2];
    /* The sign cache (sign_cache.c): the counting pass's signs, 1 bit a
     * sample, and the row spans; NULL when it would take too much memory. */
    uint64_t *cache_bits;
    row_span *cache_spans;
    int64_t cache_words;   /* 64-bit words per row */
    float *pos, *nrm;
    uint32_t *tri;
    uint8_t *org;
    /* Vertex id at pos[0] and nrm[0]: 0, or in a stream the first id of the
     * slice (or of the layer's cube-private vertices) being computed, whose
     * vertices are staged from pos[0] on (vertex_at). */
    uint64_t vertex_base;
    /* The first cube-private vertex of the layer marched when layer_private
     * is NULL (a stream). */
    uint64_t private_first;
    atomic_llong next_chunk;
    atomic_llong done_chunks;
    atomic_int cancel;
    pass_kind pass;
    isomend_progress_fn progress;
    void *progress_user;
    struct split *split;   /* the one pass on two threads (one_pass.c)    */
    /* One pass: the arrays have room past these bases for a split apart
     * (one_pass.c), or 0. */
    uint64_t apart_vertex_base, apart_triangle_base;
    isomend_mesh *recycled; /* isomend_extract_recycle's old mesh, until used */
} ctx;

/* A thread of an extraction and its working arrays. */
typedef struct worker {
    ctx *c;
    uint8_t *sign_bytes[SIGN_RING]; /* sign slices, ring indexed by k % SIGN_RING */
    row_span *spans[SIGN_RING];     /* their rows' spans                          */
    uint64_t slice_nans[SIGN_RING]; /* NaN samples of the slice                   */
    int64_t slice_held[SIGN_RING];  /* the slice in the slot, -1 none             */
    /* Vertex ids of the intersected edges whose lower end is in slice k:
     * planes x, y, z (and tetra's three diagonal planes), ring k % 2. */
    uint32_t *edge_ids[2];
    uint8_t *cube_cases;            /* configurations of one row of cubes         */
    vertex_item *pending[3];        /* vertices numbered, not computed, per axis  */
    size_t pending_count[3];
    void *block;                    /* the arrays above, in one scratch_alloc block */
    uint64_t private_count; /* cube-private vertices of the layer (methods.h) */
    uint64_t private_next;  /* next cube-private vertex id (fill pass)       */
    isomend_stats stats;
    int is_main;
} worker;

/* --------------------------------------------------------- the kernels */

/*
 * The loops that touch every sample or cube, one table per CPU target
 * (kernels_template.h).
 *   signs        slice k's sign bytes and row spans in the worker's ring:
 *                classified, or in the fill pass read from the sign cache.
 *   scan_slice   the intersected edges whose lower end is in slice m: with
 *                PASS_COUNT their number; otherwise numbers them from
 *                `first` into the worker's id map and, if `write`, computes
 *                the vertices.  Returns the number of edges.
 *   march_layer  the cubes of layer k (between slices k and k + 1): counts
 *                triangles and statistics (PASS_COUNT), writes the triangles
 *                from index `first` (PASS_FILL), or both (PASS_SWEEP, table
 *                methods).  Returns the number of triangles.
 * A layer needs the id maps of slices k and k + 1, so slice k + 1 is
 * scanned before layer k is marched.
 */
typedef struct extract_kernels {
    const char *name; /* "scalar", "sse2", "avx2" */
    const uint8_t *(*signs)(worker *w, int64_t k, const row_span **spans);
    uint64_t (*scan_slice)(worker *w, int64_t m, pass_kind pass, uint64_t first, int write);
    uint64_t (*march_layer)(worker *w, int64_t k, pass_kind pass, uint64_t first);
} extract_kernels;

/* Where vertex `id` lives in ctx.pos and ctx.nrm (floats): ids are kept
 * modulo 2^32 in the id maps, and a stream stages a slice's vertices from
 * its first id, ctx.vertex_base, on. */
static inline size_t vertex_at(uint64_t base, uint64_t id)
{
    return 3 * (size_t)(uint32_t)(id - base);
}

/* ------------------------------------------------ shared between files */

/* sign_cache.c */
void cache_store(worker *w, int64_t k);
void cache_load(worker *w, int64_t k, int slot);
void cache_alloc(ctx *c);
void cache_free(ctx *c);

/* vertices.c: the vertex on the edge along axis a from marched sample
 * (i, j, k), and the one between two samples p0, p1 not on a grid edge. */
void make_vertex(const grid *g, int flip, int64_t i, int64_t j, int64_t k, int a, float *pos,
                 float *nrm);
void make_vertex_between(const grid *g, int flip, const int64_t p0[3], const int64_t p1[3],
                         float *pos, float *nrm);
/* ... and the gradient's component along axis a at marched sample p (value
 * f0) on a uniform grid (along x and y on any). */
double gradient_component(const grid *g, const int64_t p[3], int a, double f0);

/* slice_geometry.c: slices where they are.  The table's checks; marched
 * slice m's origin (padding one gap beyond the ends); the vertex between
 * marched samples p0 and p1 and its normal from the true positions; the
 * grid's world box; the mesh's copy of the table and its check. */
isomend_status slice_origins_validate(const isomend_volume *vol);
void slice_origin(const slice_table *t, int64_t m, double o[3]);
void sheared_vertex(const grid *g, int flip, const int64_t p0[3], const int64_t p1[3], float *pos,
                    float *nrm);
void sheared_box(const grid *g, double box[6]);
isomend_status mesh_keep_slices(isomend_mesh *mesh, const grid *g);
/* march_general.c */
unsigned method_cube(worker *w, int64_t i, int64_t j, int64_t k, unsigned cfg, pass_kind pass,
                     const uint32_t *const ep[12], const uint32_t *ids0, const uint32_t *ids1,
                     uint32_t *out, uint8_t *org);
uint64_t scan_diagonals(const ctx *c, const uint8_t *s, const uint8_t *t, int64_t j, int64_t m,
                        uint32_t *ids, uint64_t id, int write);

/* extract.c: the context of an extraction (checks, grid, kernels, options;
 * vol->data may be NULL), the workers' arrays, the statistics. */
isomend_status ctx_setup(ctx *c, const isomend_volume *vol, const isomend_options *o);
size_t worker_layout(worker *w, const ctx *c, char *block);
int worker_init(worker *w, ctx *c);
void gather_stats(const ctx *c, const worker *ws, int nw, uint64_t nv, uint64_t nt,
                  isomend_stats *stats);

/* passes.c */
isomend_status run_two_passes(ctx *c, worker *ws, int nw, isomend_mesh **out, uint64_t *nv,
                              uint64_t *nt);

/* one_pass.c: ISOMEND_ERR_UNSUPPORTED (nothing allocated) when the
 * reservations are refused, for the two passes to take over. */
isomend_status run_one_pass(ctx *c, worker *ws, int nw, isomend_mesh **out, uint64_t *nv,
                            uint64_t *nt);

/* 8 bytes at p as a little-endian word, and back. */
static inline uint64_t load8(const uint8_t *p)
{
    uint64_t v;
    memcpy(&v, p, sizeof v);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    v = __builtin_bswap64(v);
#endif
    return v;
}

static inline void store8(uint8_t *p, uint64_t v)
{
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    v = __builtin_bswap64(v);
#endif
    memcpy(p, &v, sizeof v);
}

#endif /* ISOMEND_EXTRACT_INTERNAL_H */
