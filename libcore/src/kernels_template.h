/*
 * kernels_template.h - the extraction's kernels for one CPU target (private;
 * no include guard: each kernels_<target>.c includes it once).
 *
 * Before including, define
 *   KERNELS_SSE2    1: the 16-column scans use SSE2 intrinsics, 0: portable
 *   KERNELS_AVX2    1: the AVX2 loops (four vertices at a time with normals,
 *                   the float32 classification); the file is compiled for
 *                   AVX2 (kernels_avx2.c) and only called after the CPU
 *                   probe said yes
 * The including file is compiled with -O3 -ffp-contract=off
 * (libcore/CMakeLists.txt): the loops are written to vectorise, and no
 * target may contract into fused multiply-adds, so that every target gives
 * the same mesh bit for bit (core_simd_identical).
 *
 * The parts, in the order of a slice's life: classify_template.h and
 * signs_template.h (samples to signs), scan_template.h (the intersected
 * edges numbered, their vertices computed by vertex_loops_template.h),
 * march_template.h (the cubes' triangles).  Each is a template of static
 * functions and one static table, kernels_table, which the including file
 * returns from its kernels_<target>() (kernels.h).
 */
#include "context.h"
#include "march_general.h" /* method_cube, scan_diagonals: the general methods' hooks */
#include "methods.h"
#include "scan_inline.h"
#include "tables.h"
#include "vertex_inline.h"
#include "vertices.h"      /* make_vertex: the general vertex path */

/* --------------------------------------------------- per voxel type */

#define VOXEL         uint8_t
#define VOXEL_FLOAT   0
#define VOXEL_NAME(f) f##_u8
#include "classify_template.h"
#include "vertex_loops_template.h"
#undef VOXEL
#undef VOXEL_FLOAT
#undef VOXEL_NAME

#define VOXEL         int8_t
#define VOXEL_FLOAT   0
#define VOXEL_NAME(f) f##_i8
#include "classify_template.h"
#include "vertex_loops_template.h"
#undef VOXEL
#undef VOXEL_FLOAT
#undef VOXEL_NAME

#define VOXEL         uint16_t
#define VOXEL_FLOAT   0
#define VOXEL_NAME(f) f##_u16
#include "classify_template.h"
#include "vertex_loops_template.h"
#undef VOXEL
#undef VOXEL_FLOAT
#undef VOXEL_NAME

#define VOXEL         int16_t
#define VOXEL_FLOAT   0
#define VOXEL_NAME(f) f##_i16
#include "classify_template.h"
#include "vertex_loops_template.h"
#undef VOXEL
#undef VOXEL_FLOAT
#undef VOXEL_NAME

#define VOXEL         int32_t
#define VOXEL_FLOAT   0
#define VOXEL_NAME(f) f##_i32
#include "classify_template.h"
#include "vertex_loops_template.h"
#undef VOXEL
#undef VOXEL_FLOAT
#undef VOXEL_NAME

#define VOXEL         float
#define VOXEL_FLOAT   1
#define VOXEL_NAME(f) f##_f32
#include "classify_template.h"
#include "vertex_loops_template.h"
#undef VOXEL
#undef VOXEL_FLOAT
#undef VOXEL_NAME

#define VOXEL         double
#define VOXEL_FLOAT   1
#define VOXEL_NAME(f) f##_f64
#include "classify_template.h"
#include "vertex_loops_template.h"
#undef VOXEL
#undef VOXEL_FLOAT
#undef VOXEL_NAME

/* The vertex loops by [voxel type][axis]. */
typedef uint64_t (*row_vertices_fn)(const ctx *c, const uint8_t *a, const uint8_t *b, int64_t from,
                                    int64_t to, int64_t j0, int64_t m, uint32_t *ids, uint64_t id);
typedef void (*list_vertices_fn)(const ctx *c, const vertex_item *it, size_t n, int64_t m);

static const row_vertices_fn row_vertices[ISOMEND_TYPE_COUNT][3] = {
    {row_vertices_x_u8, row_vertices_y_u8, row_vertices_z_u8},
    {row_vertices_x_i8, row_vertices_y_i8, row_vertices_z_i8},
    {row_vertices_x_u16, row_vertices_y_u16, row_vertices_z_u16},
    {row_vertices_x_i16, row_vertices_y_i16, row_vertices_z_i16},
    {row_vertices_x_i32, row_vertices_y_i32, row_vertices_z_i32},
    {row_vertices_x_f32, row_vertices_y_f32, row_vertices_z_f32},
    {row_vertices_x_f64, row_vertices_y_f64, row_vertices_z_f64},
};
static const list_vertices_fn list_vertices[ISOMEND_TYPE_COUNT][3] = {
    {list_vertices_x_u8, list_vertices_y_u8, list_vertices_z_u8},
    {list_vertices_x_i8, list_vertices_y_i8, list_vertices_z_i8},
    {list_vertices_x_u16, list_vertices_y_u16, list_vertices_z_u16},
    {list_vertices_x_i16, list_vertices_y_i16, list_vertices_z_i16},
    {list_vertices_x_i32, list_vertices_y_i32, list_vertices_z_i32},
    {list_vertices_x_f32, list_vertices_y_f32, list_vertices_z_f32},
    {list_vertices_x_f64, list_vertices_y_f64, list_vertices_z_f64},
};
#if KERNELS_AVX2
static const row_vertices_fn row_vertices4[ISOMEND_TYPE_COUNT][3] = {
    {row_vertices4_x_u8, row_vertices4_y_u8, row_vertices4_z_u8},
    {row_vertices4_x_i8, row_vertices4_y_i8, row_vertices4_z_i8},
    {row_vertices4_x_u16, row_vertices4_y_u16, row_vertices4_z_u16},
    {row_vertices4_x_i16, row_vertices4_y_i16, row_vertices4_z_i16},
    {row_vertices4_x_i32, row_vertices4_y_i32, row_vertices4_z_i32},
    {row_vertices4_x_f32, row_vertices4_y_f32, row_vertices4_z_f32},
    {row_vertices4_x_f64, row_vertices4_y_f64, row_vertices4_z_f64},
};
static const list_vertices_fn list_vertices4[ISOMEND_TYPE_COUNT][3] = {
    {list_vertices4_x_u8, list_vertices4_y_u8, list_vertices4_z_u8},
    {list_vertices4_x_i8, list_vertices4_y_i8, list_vertices4_z_i8},
    {list_vertices4_x_u16, list_vertices4_y_u16, list_vertices4_z_u16},
    {list_vertices4_x_i16, list_vertices4_y_i16, list_vertices4_z_i16},
    {list_vertices4_x_i32, list_vertices4_y_i32, list_vertices4_z_i32},
    {list_vertices4_x_f32, list_vertices4_y_f32, list_vertices4_z_f32},
    {list_vertices4_x_f64, list_vertices4_y_f64, list_vertices4_z_f64},
};
#endif

/* ------------------------------------------------------ per target */

#include "signs_template.h"
#include "scan_template.h"
#include "march_template.h"

/* The table; the including file returns it from kernels_<target>(). */
static const extract_kernels kernels_table = {
#if KERNELS_AVX2
    .name = "avx2",
#elif KERNELS_SSE2
    .name = "sse2",
#else
    .name = "scalar",
#endif
    .signs = signs,
    .scan_slice = scan_slice,
    .march_layer = march_layer,
};
