/*
 * context.h - one extraction's context and its workers (private): what a
 * pass does with a layer, the context (the grid, the method, the counts
 * and the output arrays), a worker thread's working arrays, and the table of
 * kernels chosen for the CPU.  Types only; the functions on them are
 * declared by the files that define them:
 *
 *   extract.h          the context's set-up, the workers, the statistics
 *                      (extract.c)
 *   stream.h           the one engine: runs of slices driven through the
 *                      kernels, their mesh to a sink or in place (stream.c);
 *                      isomend_extract() schedules its runs in slabs.c
 *   vertices.h         the general vertex path (borders, NaN, padding,
 *                      face diagonals), exact per-type gradients
 *   march_general.h    the per-cube hook of methods.h, tetra's diagonals
 *   slice_geometry.h   slices where they are (rectilinear and sheared)
 *   cpu_features.h     the CPU probe (once), the choice of kernels
 *   kernels_template.h the kernels (classification, numbering, vertex
 *                      loops, marching), compiled once per CPU target by
 *                      kernels_scalar.c, kernels_sse2.c, kernels_avx2.c
 *
 * The kernels are the loops that touch every sample or every cube.  They
 * are written once, in *_template.h headers, and instantiated per target
 * (portable C, SSE2, AVX2) and, inside a target, per voxel type.  Everything
 * else calls them through the table chosen once per extraction
 * (ctx.kernels, see kernels_select() in cpu_features.h).  extract.c has the
 * overview of the passes.
 */
#ifndef ISOMEND_CONTEXT_H
#define ISOMEND_CONTEXT_H

#include "grid.h"
#include "isomend.h"
#include "mesh_internal.h"

#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

/* ---------------------------------------------------------- the passes */

/*
 * What a kernel does with a slice or a layer (extract.c has the overview).
 *   PASS_COUNT  counts the intersected edges, the triangles and the
 *               statistics; nothing is written (a general method's layer
 *               before it is written; a slice sampled).
 *   PASS_FILL   writes a general method's layer counted before: its
 *               cube-private vertices from ctx.private_first, its triangles.
 *   PASS_SWEEP  counts and writes at once, the ids following the running
 *               count.
 * ctx.pass is PASS_SWEEP: the sign slices are classified (counting NaN
 * samples) as a worker needs them.
 */
typedef enum pass_kind { PASS_COUNT, PASS_FILL, PASS_SWEEP } pass_kind;

/* Sign slices a worker holds: a layer's three (k, k + 1 and k + 2 for the
 * +z neighbours), and the next. */
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

/* The schedule isomend_extract() takes (slabs.c): chosen by the grid
 * (AUTO), or, for tests only (extract_set_test_schedule), staged runs on
 * the other threads at every size (ANY_SIZE), staged runs of one layer
 * (THIN), the caller's run stopping after layer 0, every other layer
 * staged (STAGED), and the counted split of two threads at every size and
 * density (COUNTED). */
typedef enum extract_schedule {
    SCHEDULE_AUTO,
    SCHEDULE_ANY_SIZE,
    SCHEDULE_THIN,
    SCHEDULE_STAGED,
    SCHEDULE_COUNTED
} extract_schedule;

/* One extraction: the grid, the options, the counts and the output arrays. */
typedef struct ctx {
    grid g;
    const struct extract_kernels *kernels; /* the loops for this CPU (kernels_select) */
    isomend_method method;
    int flip;
    int want_normals;
    int want_origins;
    int small_pages;       /* ISOMEND_FLAG_SMALL_PAGES: no huge pages asked for */
    int general;           /* a method of methods.h: per-cube hook        */
    int tetra;             /* ... with face-diagonal vertices             */
    int id_planes;         /* id-map planes per slice: 3, or 6 for tetra  */
    /* The cubes march_layer marches: columns [cube_lo[0], cube_hi[0]) and rows
     * [cube_lo[1], cube_hi[1]), all (0, N - 1) but for a box piece.  Their
     * corners, columns and rows [cube_lo, cube_hi], are the samples whose
     * edges scan_slice numbers. */
    int64_t cube_lo[2], cube_hi[2];
    float *pos, *nrm;
    uint32_t *tri;
    uint8_t *org;
    /* The first id of the slice (or of the layer's cube-private vertices)
     * being computed, whose vertices are written from pos[0] on (vertex_at). */
    uint64_t vertex_base;
    /* The first cube-private vertex of the layer marched (PASS_FILL). */
    uint64_t private_first;
    pass_kind pass;
    isomend_progress_fn progress;
    void *progress_user;
    extract_schedule schedule;
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
    uint64_t private_next;  /* next cube-private vertex id (PASS_FILL)       */
    isomend_stats stats;
    int is_main;
} worker;

/* --------------------------------------------------------- the kernels */

/*
 * The loops that touch every sample or cube, one table per CPU target
 * (kernels_template.h).
 *   signs        slice k's sign bytes and row spans in the worker's ring,
 *                classified when the slot holds another slice.
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
 * modulo 2^32 in the id maps, and the engine writes a slice's vertices from
 * its first id, ctx.vertex_base, on. */
static inline size_t vertex_at(uint64_t base, uint64_t id)
{
    return 3 * (size_t)(uint32_t)(id - base);
}

#endif /* ISOMEND_CONTEXT_H */
