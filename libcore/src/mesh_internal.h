/*
 * mesh_internal.h - the mesh object and what the steps on a mesh share
 * (private): the extraction makes meshes (grid.h includes this),
 * the checks and the post-processing (check_stream.c, decimate.c, smooth.c,
 * components.c, distance.c, mesh_build.c) work on them and need nothing of
 * the extraction's grid, context or kernels.
 */
#ifndef ISOMEND_MESH_INTERNAL_H
#define ISOMEND_MESH_INTERNAL_H

#include "isomend.h"
#include "team.h"

#include <stddef.h>
#include <stdint.h>

/* ------------------------------------------------------- slice origins */

/* The slices' own origins (isomend_volume.slice_origins, slice_geometry.c):
 * so NULL for a uniform grid. */
typedef struct slice_table {
    const double *so; /* 3 doubles a volume slice, or NULL                 */
    int64_t n;        /* the volume's slices                               */
    int64_t pad;      /* 0 or 1: marched slice m is volume slice m - pad  */
    double gap;       /* the padding's gap when the volume has one slice   */
} slice_table;

/* extract.c: a volume's grid checked as every extraction checks it (the
 * label maps too): at least 2 samples a side (1 with padding), at most 2^31;
 * spacing > 0 and finite; origin finite.  ISOMEND_OK or the status. */
isomend_status volume_grid_check(const isomend_volume *vol, int pad);

/* ------------------------------------------------------------- the mesh */

struct isomend_mesh {
    size_t nv, nt;
    float *pos;
    float *nrm;
    uint32_t *tri;
    uint8_t *org;
    double box[6];
    size_t mapped[4]; /* bytes mapped for pos, nrm, tri, org; 0: malloc'ed */
    slice_table slices; /* the grid's, for the check; so: slice_store  */
    double *slice_store;
    double h[2];        /* in-plane spacing and marched grid, likewise     */
    int64_t N[3];
};

/* slice_geometry.c: a point moved into the unsheared frame of a sheared
 * grid (o: the n marched slices' origins), where check.c checks. */
void unshear_point(const double *o, int64_t n, const float in[3], float out[3]);

/* mesh_build.c: a post-processed mesh's frame (box, slice table) copied from
 * the mesh it comes from; vertex normals from the triangles. */
isomend_status mesh_copy_frame(isomend_mesh *dst, const isomend_mesh *src);
void mesh_area_normals(isomend_mesh *m, const float *keep);
int mesh_free_vertices(const isomend_mesh *m, team *tm, uint8_t *free_flag, uint32_t **first,
                       uint32_t **next, uint32_t **prev);
/* The same into the caller's arrays: first nv + 1, next and prev 3 nt each. */
void mesh_free_vertices_into(const isomend_mesh *m, team *tm, uint8_t *free_flag, uint32_t *first,
                             uint32_t *next, uint32_t *prev);
/* smooth.c: isomend_mesh_smooth(), and in *bytes (if not NULL) the most it
 * held at once beyond the input, its output included. */
isomend_status mesh_smooth(const isomend_mesh *mesh, int iterations, isomend_mesh **out,
                           isomend_smooth_report *report, uint64_t *bytes);
/* smooth.c: the windowed sinc filter of `iterations` (>= 1) steps on n
 * vertices whose neighbours are nb[first[v] .. first[v + 1]) (free_v[v] 0:
 * the vertex stays), from the centred positions x0 into out, on team tm
 * (NULL: this thread); x0, b and out hold 3 n + 4 floats (x0's last 4
 * zero), b and deg (n bytes) scratch, and row sinc_row_bytes(n) bytes (NULL:
 * allocated here).  0 without memory. */
int sinc_filter(team *tm, size_t n, const uint32_t *first, const uint32_t *nb,
                const uint8_t *free_v, const float *x0, float *b, uint8_t *deg, float *out,
                int iterations, void *row);
size_t sinc_row_bytes(size_t n);
/* smooth_shared.c: meshes that meet (a label map's), their vertices one set
 * (a vertex the same in every mesh where its position is the same, bit for
 * bit).  vertex_set_build() checks the arguments of isomend_meshes_*()
 * (out[] cleared; INVALID_ARGUMENT for NULL out, meshes or mesh,
 * TOO_LARGE from 2^32 vertices or corners in all), then fills the set:
 * gid[base[i] + v] is vertex v of mesh i's set vertex, pos (3 floats a set
 * vertex, `pad` floats more) the first occurrence's position.
 * meshes_destroy() clears out[] on a failure; mesh_volume() is a mesh's
 * enclosed volume (signed). */
typedef struct vertex_set {
    size_t total, corners, n; /* the meshes' vertices and corners; the set's vertices */
    uint32_t *gid;
    size_t *base;
    float *pos;
} vertex_set;
isomend_status vertex_set_build(const isomend_mesh *const *meshes, size_t count,
                                isomend_mesh **out, size_t pad, vertex_set *set);
void vertex_set_free(vertex_set *set);
void meshes_destroy(isomend_mesh **out, size_t count);
double mesh_volume(const float *pos, const uint32_t *tri, size_t nt);
/* fn(arg, lo, hi) over [0, n) in ranges on up to 8 threads (one below 32768
 * items, or where threads cannot start); returns when all are done. */
void parallel_for(size_t n, void (*fn)(void *arg, size_t lo, size_t hi), void *arg);
/* The same with threads from min_items items on (items that are blocks). */
void parallel_for_from(size_t n, size_t min_items, void (*fn)(void *arg, size_t lo, size_t hi),
                       void *arg);

/* decimate.c: isomend_mesh_decimate() to `target` triangles (0: as far as
 * the surface allows) with max_error (0: none); the report's distances only
 * if `measure`; kept (if not NULL) gets each output vertex's input index
 * (malloc'ed, the output's vertex count; locked vertices keep their
 * position). */
typedef struct decimate_carry {
    const double *q_in;  /* 10 an input vertex, added to its quadric (NULL: none)    */
    size_t planes_from;  /* only triangles from this one on add their planes         */
    double *q_out;       /* out: 10 an output vertex, malloc'ed (the caller frees)  */
    /* max_error: the points an input vertex stands for, which the check keeps
     * within max_error (NULL: each vertex stands for itself, at mesh->pos) */
    const float *pts;          /* 3 floats a point                                  */
    const uint32_t *pts_first; /* nv + 1: vertex v's are [pts_first[v], pts_first[v + 1]) */
    uint32_t *pts_out;         /* out (with pts): the points of the output vertices, */
    uint32_t *pts_out_first;   /* by vertex (nv_out + 1 of these); malloc'ed        */
    const uint8_t *locked;     /* nv: non-zero for a vertex that stays (NULL: none) */
    uint64_t peak_bytes;       /* out: the most bytes it held at once beyond the input,
                                * its outputs included (*out, kept, q_out, pts_out)  */
} decimate_carry;
/* carry (may be NULL): quadrics carried in and out, for a decimation in
 * pieces whose earlier triangles' planes are already in their vertices'
 * quadrics (decimate_stream.c); with max_error and pts, the points each
 * vertex stands for carried in and out (the stream's vertices a held vertex
 * was collapsed from, which must stay within max_error of its triangles). */
isomend_status mesh_decimate_to(const isomend_mesh *mesh, uint64_t target, double max_error,
                                int measure, isomend_mesh **out, uint32_t **kept,
                                decimate_carry *carry, isomend_decimate_report *report);

/* distance.c: the squared distance from p to triangle (a, b, c); the largest
 * and mean distance from np points to a triangle mesh, on the threads of tm
 * (NULL: a team of its own; 0 without memory; *bytes, if not NULL: the most
 * it allocated at once). */
double point_triangle_distance2(const double p[3], const double a[3], const double b[3],
                                const double c[3]);
int mesh_distances(const float *pts, size_t np, const float *pos, const uint32_t *tri, size_t nt,
                   team *tm, double *max_out, double *mean_out, uint64_t *bytes);

/* components.c: each vertex's component (triangles joined through shared
 * vertices), numbered in vertex order; returns their count (isolated
 * vertices count as components of their own). */
int64_t mesh_components(const isomend_mesh *m, uint32_t *label);

/* mesh_memory.c */
#define HUGE_PAGE ((size_t)2 << 20) /* the transparent huge page of x86-64 (and of
                                     * arm64 with 4 KiB pages) */
static inline size_t huge_round(size_t size) /* up to whole huge pages */
{
    return (size + HUGE_PAGE - 1) & ~(HUGE_PAGE - 1);
}
void *output_alloc(size_t size, int small_pages);
void *scratch_alloc(size_t size);
void *reserve_output(size_t size, size_t huge_from);
size_t trim_output(void *p, size_t size, size_t used);
void release_output(void *p, size_t mapped);
void release_pages(void *p, size_t size);
void adopt_output(void *p, size_t size, void *old, size_t mapped);

#endif /* ISOMEND_MESH_INTERNAL_H */
