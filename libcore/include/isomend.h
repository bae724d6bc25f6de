/*
 * isomend.h - hole-free isosurface extraction from volumes (public API)
 *
 * isomend turns a scalar volume (CT, MRI, microscopy, simulation fields)
 * into an indexed triangle mesh with the marching cubes family of methods:
 *
 *   ISOMEND_METHOD_MC     Lorensen & Cline (1987), with the 256-case table
 *                         generated from the 15 elementary cases by the 24
 *                         cube rotations and inversion.  Leaves holes where
 *                         two cubes disagree on a shared ambiguous face.
 *   ISOMEND_METHOD_DURST  Durst (1988): MC plus a quadrilateral on every
 *                         ambiguous face shared by two cubes.  Closes every
 *                         hole but adds extraneous polygons (edges used 3x).
 *   ISOMEND_METHOD_DMC    The thesis method (after Roll, Haase & von Kienlin
 *                         1995): MC plus a quadrilateral only on ambiguous
 *                         faces shared by an *inverted combination* (exactly
 *                         one of the two cubes has 5+ positive corners),
 *                         which is exactly where MC leaves a hole.  Default.
 *
 * and five methods that decide each ambiguous face (or the cube) so that
 * neighbours agree, with triangles from tables generated for every decision:
 *
 *   ISOMEND_METHOD_FACIAL      joins a face's positive corners when the mean
 *                              of its four samples is >= iso (Wyvill,
 *                              McPheeters & Wyvill 1986);
 *   ISOMEND_METHOD_GRADIENT    ... when the face centre estimated along the
 *                              in-face gradients is >= iso (Wilhelms & Van
 *                              Gelder 1990);
 *   ISOMEND_METHOD_ASYMPTOTIC  ... when the bilinear saddle value is >= iso
 *                              (Nielson & Hamann 1991);
 *   ISOMEND_METHOD_TETRA       five tetrahedra per cube, marched separately
 *                              (Payne & Toga 1990);
 *   ISOMEND_METHOD_MC33        the asymptotic decider on faces and the
 *                              trilinear interpolant's connectivity inside
 *                              the cube (Chernyaev 1995).
 *
 * DMC and these five give hole-free, consistently oriented 2-manifolds
 * (closed with ISOMEND_FLAG_PAD); only MC33 follows the topology of the
 * trilinear interpolant.
 *
 * Conventions (applied identically by every cube, so neighbours agree):
 *   - a sample is *positive* (inside) when  sample >= iso;
 *   - NaN samples and the optional padding layer are *outside*; an edge with
 *     such an endpoint is cut at its midpoint and its vertex normal is the
 *     edge direction (towards the outside endpoint);
 *   - one vertex per intersected grid edge, shared by every cube around it;
 *     the vertex is at  p0 + t (p1 - p0),  t = (iso - f0) / (f1 - f0),
 *     p0 the endpoint with the lower index.  TETRA also cuts the face
 *     diagonals joining a face's corners of even parity (i + j + k even, in
 *     the padded grid with ISOMEND_FLAG_PAD), one vertex each, shared by
 *     the face's two cubes; FACIAL, GRADIENT, ASYMPTOTIC and MC33 may add
 *     vertices private to a cube, at the mean of its edge vertices (and,
 *     for MC33, halfway between that and an edge vertex);
 *   - positions are float32 world coordinates: origin + index * spacing;
 *   - normals are unit vectors from central-difference gradients (one-sided
 *     at the border and next to NaN/padding), interpolated along the edge,
 *     pointing towards *lower* values; ISOMEND_FLAG_FLIP reverses both the
 *     normals and the winding, which always agree with each other;
 *   - triangles are wound counter-clockwise seen from the side the normals
 *     point to.
 *
 * Thread safety: every function is reentrant; a volume may be read by
 * several extractions at once.  A mesh object may be read from several
 * threads but must not be destroyed while being read.  There is no global
 * mutable state.
 *
 * The library never prints, never exits and never aborts on bad input:
 * every function that can fail returns an isomend_status.
 */
#ifndef ISOMEND_H
#define ISOMEND_H

#include <stddef.h>
#include <stdint.h>

#define ISOMEND_VERSION_MAJOR 0
#define ISOMEND_VERSION_MINOR 1
#define ISOMEND_VERSION_PATCH 0
#define ISOMEND_VERSION_STRING "0.1.0"

#if defined(_WIN32)
#  if defined(ISOMEND_BUILDING_SHARED)
#    define ISOMEND_API __declspec(dllexport)
#  elif defined(ISOMEND_USING_SHARED)
#    define ISOMEND_API __declspec(dllimport)
#  else
#    define ISOMEND_API
#  endif
#elif defined(__GNUC__) && __GNUC__ >= 4
#  define ISOMEND_API __attribute__((visibility("default")))
#else
#  define ISOMEND_API
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------ status */

typedef enum isomend_status {
    ISOMEND_OK = 0,
    ISOMEND_ERR_INVALID_ARGUMENT = 1, /* NULL pointer, bad enum, bad flag    */
    ISOMEND_ERR_BAD_DIMENSIONS = 2,   /* a dimension < 2 (< 1 with pad), > 2^31 */
    ISOMEND_ERR_BAD_SPACING = 3,      /* spacing <= 0 or not finite          */
    ISOMEND_ERR_BAD_ISO = 4,          /* iso level NaN or infinite            */
    ISOMEND_ERR_OUT_OF_MEMORY = 5,
    ISOMEND_ERR_TOO_LARGE = 6,        /* more than 2^32-1 vertices            */
    ISOMEND_ERR_CANCELLED = 7,        /* the progress callback asked to stop  */
    ISOMEND_ERR_THREAD = 8,           /* a worker thread could not start      */
    ISOMEND_ERR_UNSUPPORTED = 9,      /* method/option combination not built  */
    ISOMEND_ERR_SINK = 10,            /* a stream's sink returned non-zero    */
    ISOMEND_ERR_SLICE_COUNT = 11      /* a stream got more or fewer slices    */
                                      /* than its volume has                  */
} isomend_status;

/* A static, human-readable description of a status ("out of memory"). */
ISOMEND_API const char *isomend_status_string(isomend_status status);

/* The library's version string, e.g. "0.1.0". */
ISOMEND_API const char *isomend_version(void);

/* The cores this process may run on (its affinity mask: taskset, a
 * container's cpuset; else the machine's online cores), at least 1: the
 * threads that threads = 0 means, in every call that takes a thread count. */
ISOMEND_API int isomend_cores(void);

/* ------------------------------------------------------------ voxel types */

typedef enum isomend_type {
    ISOMEND_U8 = 0,
    ISOMEND_I8 = 1,
    ISOMEND_U16 = 2,
    ISOMEND_I16 = 3,
    ISOMEND_I32 = 4,
    ISOMEND_F32 = 5,
    ISOMEND_F64 = 6
} isomend_type;
#define ISOMEND_TYPE_COUNT 7
/* uint32 samples, for label maps only (isomend_labels_*): not a type of the
 * scalar extraction, whose switches over isomend_type it stays out of. */
#define ISOMEND_U32 ((isomend_type)7)

/* Size in bytes of one sample, 0 for an invalid type (and for ISOMEND_U32,
 * which only isomend_labels_* take). */
ISOMEND_API size_t isomend_type_size(isomend_type type);
/* "u8", "i8", "u16", "i16", "i32", "f32", "f64"; NULL for an invalid type. */
ISOMEND_API const char *isomend_type_name(isomend_type type);
/* Parses a name as above; returns ISOMEND_ERR_INVALID_ARGUMENT if unknown. */
ISOMEND_API isomend_status isomend_type_from_name(const char *name, isomend_type *type);

/* ----------------------------------------------------------------- volume */

/*
 * A volume is read in place, never copied.  Sample (i, j, k) lives at
 *     (const char *)data + i*strides[0] + j*strides[1] + k*strides[2]
 * (strides in bytes, may be negative).  strides all 0 means contiguous with
 * x fastest: strides = {size, size*dims[0], size*dims[0]*dims[1]}.
 * Multi-byte samples are in the machine's byte order.
 * x = index 0 (image column), y = index 1 (image row), z = index 2 (slice).
 */
typedef struct isomend_volume {
    const void *data;
    isomend_type type;
    int64_t dims[3];
    int64_t strides[3];
    double spacing[3]; /* world distance between samples, > 0 */
    double origin[3];  /* world position of sample (0, 0, 0)  */
    /* NULL (a uniform grid), or 3 * dims[2] doubles: the world position of
     * sample (0, 0, k) of each slice k, see "Slices where they are" below */
    const double *slice_origins;
} isomend_volume;

/*
 * Slices where they are (rectilinear and sheared grids, thesis chapter 2.1).
 * With slice_origins NULL, sample (i, j, k) lies at origin + (i, j, k) *
 * spacing.  Otherwise slice k is the plane z = slice_origins[3k + 2], and its
 * sample (i, j) lies at
 *     (slice_origins[3k] + i * spacing[0], slice_origins[3k + 1] + j * spacing[1],
 *      slice_origins[3k + 2]):
 * the slices' gaps may differ (uneven spacing, a missing slice), and each
 * slice may be shifted in x and y (positions rounded by a scanner, the shear
 * of a gantry tilt).  The z values must increase strictly with k
 * (ISOMEND_ERR_BAD_SPACING otherwise, or for a value that is not finite);
 * origin and spacing[2] are then not used.  Such a grid is marched exactly
 * as a uniform one: the same triangles, the same vertices in the same order,
 * only placed differently.  A vertex between samples at world positions p0
 * and p1 lies at  (1 - t) p0 + t p1  (t as below, computed in double and
 * rounded once), so it stays between its two samples' true positions.
 * Normals are the gradients by central differences over each sample's true
 * neighbours: along x and y as usual, and along the slices the difference
 * f(k+1) - f(k-1) over the vector between those two samples' positions
 * (one-sided at the border, NaN and padding), the gradient being the vector
 * that gives those three directional differences.  With ISOMEND_FLAG_PAD
 * the padding slices lie one gap beyond the first and the last.  The
 * continuity check of such a mesh (isomend_mesh_check) finds the border in
 * the grid's own, sheared, faces.  Vertices take the general path of the
 * kernels (docs/core-internals.md has the cost); a table that is exactly
 * uniform is better given as origin and spacing.
 */

/* Fills a contiguous x-fastest volume description with spacing 1, origin 0
 * and no slice origins. */
ISOMEND_API void isomend_volume_init(isomend_volume *vol, const void *data, isomend_type type,
                                     int64_t nx, int64_t ny, int64_t nz);

/* ---------------------------------------------------------------- methods */

typedef enum isomend_method {
    ISOMEND_METHOD_MC = 0,
    ISOMEND_METHOD_DURST = 1,
    ISOMEND_METHOD_DMC = 2,
    ISOMEND_METHOD_FACIAL = 3,     /* face average (Wyvill et al. 1986)            */
    ISOMEND_METHOD_GRADIENT = 4,   /* centre-pointing gradient (1990)              */
    ISOMEND_METHOD_ASYMPTOTIC = 5, /* asymptotic decider (Nielson & Hamann 1991)   */
    ISOMEND_METHOD_TETRA = 6,      /* 5 mirrored tetrahedra (Payne & Toga 1990)    */
    ISOMEND_METHOD_MC33 = 7        /* Marching Cubes 33 (Chernyaev 1995)           */
} isomend_method;
#define ISOMEND_METHOD_COUNT 8

/* "mc", "durst", "dmc", "facial", "gradient", "asymptotic", "tetra", "mc33". */
ISOMEND_API const char *isomend_method_name(isomend_method method);
ISOMEND_API isomend_status isomend_method_from_name(const char *name, isomend_method *method);
/* 1 if this build implements the method, else 0. */
ISOMEND_API int isomend_method_available(isomend_method method);

/* ---------------------------------------------------------------- options */

enum {
    ISOMEND_FLAG_NO_NORMALS = 1u << 0, /* do not compute normals                */
    ISOMEND_FLAG_FLIP = 1u << 1,       /* normals towards higher values,       */
                                       /* winding reversed to match            */
    ISOMEND_FLAG_PAD = 1u << 2,        /* surround the volume with one layer   */
                                       /* of outside samples: closed surfaces  */
    ISOMEND_FLAG_NO_ORIGINS = 1u << 3, /* do not record triangle origins       */
    ISOMEND_FLAG_SMALL_PAGES = 1u << 4 /* output arrays without huge pages     */
                                       /* (see below)                          */
};
#define ISOMEND_FLAGS_ALL 0x1Fu
/*
 * Pages.  By default the output arrays of 2 MiB and more are offered to the
 * kernel (Linux) for transparent huge pages: fewer page faults and TLB
 * misses.  ISOMEND_FLAG_SMALL_PAGES asks for none in the output arrays.
 * Whether that is faster depends on the machine (on some virtual machines
 * fresh huge pages are expensive; docs/core-internals.md, "Pages", has the
 * measurements): measure before using it.  The mesh is the same either way.
 */

/*
 * Progress: called from the thread that called isomend_extract(), with a
 * fraction in [0, 1], from time to time while it runs (every 16 slices it
 * extracts, after each chunk of layers on a small grid, once its own part
 * is done and about every 100 ms while it then waits for another thread: at
 * least once before the end) and with 1.0 once the mesh is complete.  Return non-zero to cancel: the extraction then returns
 * ISOMEND_ERR_CANCELLED and no mesh.  The return value of the final 1.0 call
 * is ignored.
 */
typedef int (*isomend_progress_fn)(void *user, double fraction);

typedef struct isomend_options {
    double iso;                   /* iso level (finite)                          */
    isomend_method method;        /* default ISOMEND_METHOD_DMC                  */
    unsigned flags;               /* ISOMEND_FLAG_*                              */
    int threads;                  /* 0 = isomend_cores(); at most 64; the mesh     */
                                  /* does not depend on it                       */
    isomend_progress_fn progress; /* may be NULL                                 */
    void *progress_user;
} isomend_options;

/* iso 0, DMC, no flags, all cores, no progress callback. */
ISOMEND_API void isomend_options_init(isomend_options *opts);

/* -------------------------------------------------------------- statistics */

/* Where a triangle comes from. */
typedef enum isomend_origin {
    ISOMEND_ORIGIN_TABLE = 0, /* the 256-case table (or the method's own)       */
    ISOMEND_ORIGIN_DURST = 1, /* Durst's quad on an ambiguous face              */
    ISOMEND_ORIGIN_MEND = 2   /* DMC's quad on an inverted combination          */
} isomend_origin;
#define ISOMEND_ORIGIN_COUNT 3

typedef struct isomend_stats {
    uint64_t cubes;                 /* cubes marched (including padding)         */
    uint64_t case_histogram[15];    /* cubes per elementary case 0..14 (Table-2) */
    uint64_t ambiguous_faces;       /* distinct ambiguous faces shared by 2 cubes */
    uint64_t inverted_combinations; /* ... of those, shared by an inverted combination */
    uint64_t triangles_by_origin[ISOMEND_ORIGIN_COUNT];
    uint64_t nan_samples;           /* NaN samples in the input                  */
    uint64_t vertices;
    uint64_t triangles;
} isomend_stats;

/* ------------------------------------------------------------------- mesh */

/* An extracted mesh; owns its arrays.  Destroy with isomend_mesh_destroy(). */
typedef struct isomend_mesh isomend_mesh;

/*
 * Extracts the isosurface of `vol` at `opts->iso`.
 * On success *out_mesh receives a new mesh (possibly with zero triangles) and
 * `stats` (may be NULL) is filled.  On failure *out_mesh is NULL.
 * `opts` may be NULL for the defaults (which means iso 0).
 */
ISOMEND_API isomend_status isomend_extract(const isomend_volume *vol, const isomend_options *opts,
                                           isomend_mesh **out_mesh, isomend_stats *stats);

/*
 * isomend_extract() for a program that extracts one surface after another:
 * *mesh, if not NULL, is a mesh the caller no longer needs (its arrays must
 * not be used again).  The call destroys it, in every case, and where it can
 * it moves the old mesh's memory into the new mesh first, so that the new
 * arrays are written on memory already in place: no page faults and no
 * zeroing by the kernel for that part (docs/core-internals.md has the
 * measured gain).  The new mesh, the same byte for byte as
 * isomend_extract()'s, is stored in *mesh; NULL on failure.  Memory is
 * reused where the mesh is written into reservations (grids of 2^20 samples
 * or more, Linux); otherwise the old mesh is destroyed before the new one
 * is allocated.
 */
ISOMEND_API isomend_status isomend_extract_recycle(const isomend_volume *vol,
                                                   const isomend_options *opts,
                                                   isomend_mesh **mesh, isomend_stats *stats);

/* Accepts NULL. */
ISOMEND_API void isomend_mesh_destroy(isomend_mesh *mesh);

ISOMEND_API size_t isomend_mesh_vertex_count(const isomend_mesh *mesh);
ISOMEND_API size_t isomend_mesh_triangle_count(const isomend_mesh *mesh);
/* 3 floats (x, y, z) per vertex. */
ISOMEND_API const float *isomend_mesh_positions(const isomend_mesh *mesh);
/* 3 floats per vertex, unit length; NULL with ISOMEND_FLAG_NO_NORMALS. */
ISOMEND_API const float *isomend_mesh_normals(const isomend_mesh *mesh);
/* 3 vertex indices per triangle. */
ISOMEND_API const uint32_t *isomend_mesh_triangles(const isomend_mesh *mesh);
/* One isomend_origin per triangle; NULL with ISOMEND_FLAG_NO_ORIGINS. */
ISOMEND_API const uint8_t *isomend_mesh_triangle_origins(const isomend_mesh *mesh);
/*
 * The world-space box of the (padded, if ISOMEND_FLAG_PAD) sample grid the
 * mesh was extracted from: min[3] then max[3].  Once-used edges lying in one
 * of its faces are the volume's legitimate border (see isomend_check).
 */
ISOMEND_API void isomend_mesh_grid_box(const isomend_mesh *mesh, double box[6]);

/*
 * Copies the mesh into caller-owned arrays (count-then-fill, for bindings).
 * Any pointer may be NULL to skip that array.  positions/normals hold
 * 3*vertex_count floats, triangles 3*triangle_count indices, origins
 * triangle_count bytes.
 */
ISOMEND_API isomend_status isomend_mesh_copy(const isomend_mesh *mesh, float *positions,
                                             float *normals, uint32_t *triangles,
                                             uint8_t *origins);

/*
 * isomend_mesh_copy() through an affine map, for a volume whose grid is
 * turned or mirrored in the world (e.g. a DICOM series' direction cosines,
 * see isomend_io_world_transform()).  `affine` is 3x4, row-major:
 *     p'[r] = affine[4r] p[0] + affine[4r+1] p[1] + affine[4r+2] p[2] + affine[4r+3]
 * Positions map by it (in double, rounded once to float); normals by the
 * inverse transpose of its 3x3 part, renormalised (they stay the surface's
 * normals, pointing to lower values); when that part's determinant is
 * negative (a mirror) every triangle's winding is reversed, so triangles stay
 * counter-clockwise seen from where the normals point and the surface is
 * never turned inside out.  Array sizes and NULL as for isomend_mesh_copy().
 * The mesh itself is unchanged (its grid box and isomend_mesh_check() stay
 * those of the grid it was extracted on; the copy has the same topology).
 * ISOMEND_ERR_INVALID_ARGUMENT for a non-finite or singular map.
 */
ISOMEND_API isomend_status isomend_mesh_copy_transformed(const isomend_mesh *mesh,
                                                         const double affine[12],
                                                         float *positions, float *normals,
                                                         uint32_t *triangles, uint8_t *origins);

/* ------------------------------------------------------------- streaming */

/*
 * Streaming extraction: slices pushed one at a time, in z order, and the
 * mesh handed to a sink as it is made.  The stream holds a few slices of
 * samples, signs and vertex ids, and one slice's vertices and one layer's
 * triangles (isomend_stream_memory()), whatever the number of slices.  The
 * mesh is isomend_extract()'s on the same volume and options, byte for byte,
 * vertex order included: the same positions, normals, triangles (as 64-bit
 * ids), origins and statistics (docs/streaming.md, section "The core").
 *
 * The order.  Slice k (of the marched grid: the volume plus the padding
 * layer with ISOMEND_FLAG_PAD) owns the vertices on the grid edges whose
 * lower end is in it (and tetra's face diagonals whose lowest corner is);
 * layer k is the cubes between slices k and k + 1.  The sink receives
 * slice 0's vertices, then for k = 0, 1, ...: layer k's cube-private
 * vertices (mc33, and facial, gradient, asymptotic where needed) and slice
 * k + 1's vertices (one call; two where a threaded stream's slabs meet),
 * layer k's triangles, and retire(first id of
 * slice k + 1).  isomend_extract() numbers its vertices in that order:
 * slice 0, layer 0's private vertices, slice 1, layer 1's, ...
 */

/* A vertex with no key (cube-private), in the keys of a piece's vertices. */
#define ISOMEND_KEY_NONE UINT64_MAX
/* A piece's triangle refers to the next piece's vertex f as
 * ISOMEND_FOREIGN | f (isomend_piece_begin). */
#define ISOMEND_FOREIGN ((uint64_t)1 << 63)

/*
 * Where a stream puts the mesh.  Every callback returns 0 to go on; any
 * other value stops the extraction: the push (or finish) that called it
 * returns ISOMEND_ERR_SINK, and no callback is called again.  Callbacks are
 * called from the thread that calls push or finish; the arrays they get are
 * valid only during the call.
 *   vertices   `count` vertices with ids first_id .. first_id + count - 1
 *              (first_id: the number delivered before), 3 floats each;
 *              normals NULL with ISOMEND_FLAG_NO_NORMALS; keys NULL except
 *              for pieces (one per vertex: the global grid edge or face,
 *              isomend_piece_begin, ISOMEND_KEY_NONE for cube-private ones).
 *   triangles  `count` triangles, 3 vertex ids each, all delivered before;
 *              origins (one isomend_origin each) NULL with
 *              ISOMEND_FLAG_NO_ORIGINS.
 *   retire     no triangle delivered later uses an id below `floor`.
 *   foreign    pieces only (may be NULL for streams): the keys and positions
 *              (3 floats each, as the next piece computes them) of foreign
 *              vertices first .. first + count - 1, before any triangle that
 *              refers to them.
 */
typedef struct isomend_mesh_sink {
    void *user;
    int (*vertices)(void *user, uint64_t first_id, size_t count, const float *positions,
                    const float *normals, const uint64_t *keys);
    int (*triangles)(void *user, size_t count, const uint64_t *ids, const uint8_t *origins);
    int (*retire)(void *user, uint64_t floor);
    int (*foreign)(void *user, size_t first, size_t count, const uint64_t *keys,
                   const float *positions);
} isomend_mesh_sink;

/* A streaming extraction (one caller thread; not to be shared between threads). */
typedef struct isomend_stream isomend_stream;

/*
 * Begins a stream of the volume `desc` (its type, dims, spacing, origin and
 * slice origins, which the stream copies; data and strides are ignored) with
 * `opts` (NULL: the defaults; progress and ISOMEND_FLAG_SMALL_PAGES are
 * ignored: the caller checks for cancellation between pushes).
 * opts->threads (0: all cores) other than 1, on a volume tall enough for two
 * slabs of slices, extracts slabs of slices on that many worker threads while
 * the caller pushes the next slices and the sink takes the finished slabs, in
 * order; the sink is still called only from the thread that calls push or
 * finish, with the same ids, triangles, floors and bytes as on one thread
 * (docs/streaming.md, "Threads").
 * The sink is copied; vertices, triangles and retire must not be NULL.
 * The same checks and statuses as isomend_extract(), except that a stream
 * has no limit of 2^32 vertices (ids are 64-bit): ISOMEND_ERR_TOO_LARGE
 * only when two consecutive slices (and a layer's private vertices) have
 * 2^32 vertices or more.  On failure *out is NULL.
 */
ISOMEND_API isomend_status isomend_stream_begin(const isomend_volume *desc,
                                                const isomend_options *opts,
                                                const isomend_mesh_sink *sink,
                                                isomend_stream **out);

/*
 * Pushes the next volume slice, z = 0, 1, ... dims[2] - 1: dims[0] * dims[1]
 * samples of the stream's type, x fastest, rows of dims[0], machine byte
 * order.  The stream copies what it keeps; the caller may reuse `slice` at
 * once.  Delivers to the sink what the slice completes.  After a failure
 * (a status other than ISOMEND_OK, the sink's included) every later push
 * and finish return that status and call nothing.  More than dims[2] slices:
 * ISOMEND_ERR_SLICE_COUNT.
 */
ISOMEND_API isomend_status isomend_stream_push(isomend_stream *s, const void *slice);

/*
 * Delivers the rest of the mesh once all dims[2] slices are pushed (fewer:
 * ISOMEND_ERR_SLICE_COUNT) and fills `stats` (may be NULL) as
 * isomend_extract() does.  The stream must still be destroyed.
 */
ISOMEND_API isomend_status isomend_stream_finish(isomend_stream *s, isomend_stats *stats);

/* Frees the stream, at any time (a stream not finished delivers nothing
 * more).  Accepts NULL. */
ISOMEND_API void isomend_stream_destroy(isomend_stream *s);

/*
 * An upper bound, in bytes, of the memory a stream of `desc` with `opts`
 * holds (isomend_stream_begin()'s arguments; 0 for invalid ones): the slices
 * of samples, signs and vertex ids it keeps and, at their largest possible
 * sizes, one slice's vertices and one layer's triangles; with threads, that
 * for each worker, and the slabs in flight (threads + 2: their slices and
 * meshes, a mesh estimated as 7 bytes a sample).  It depends on dims[0],
 * dims[1], the type and the options, not on dims[2].  The largest
 * sizes are reserved as address space and only the part a mesh uses is
 * touched, so the resident memory is usually well below it
 * (docs/streaming.md has the formula and figures).
 */
ISOMEND_API uint64_t isomend_stream_memory(const isomend_volume *desc,
                                           const isomend_options *opts);

/*
 * The most vertices one call of sink.vertices gets from such a stream (a
 * slice's, and the cube-private ones of the layer below it; 0 for invalid
 * arguments).  A sink that keeps positions until retire() (an STL writer)
 * keeps at most twice as many, whatever the threads.
 */
ISOMEND_API uint64_t isomend_stream_vertex_bound(const isomend_volume *desc,
                                                 const isomend_options *opts);

/*
 * Pieces: a stream restricted to a slab of the marched grid, for extracting
 * one volume in several processes (isomend-mpi) whose meshes are stitched by
 * keys into isomend_extract()'s mesh.
 *
 * Ownership: the piece that owns marched slice k owns slice k's vertices
 * and layer k's triangles and cube-private vertices, so a piece [a, b)
 * delivers exactly the run of isomend_extract()'s vertex ids from slice a's
 * first to slice b's first, and its triangles in order.  The mending and
 * Durst quadrilaterals on the plane z = b belong to the piece below (its
 * layer b - 1 judges that face), the plane's vertices to the piece above.
 *
 * A piece numbers its vertices from 0 (local ids) and gives every vertex on
 * a grid edge or face diagonal its key in the global marched grid:
 *     key = ((k * N1 + j) * N0 + i) * 8 + kind
 * (i, j, k) the edge's lower end or the face's lowest corner, kind 0/1/2 an
 * x/y/z edge, 3/4/5 tetra's diagonal of an x/y/z face; ISOMEND_KEY_NONE
 * for cube-private vertices.  Its last layer's triangles refer to the next
 * piece's vertices of slice b (x and y edges and z-face diagonals in it) as
 * ISOMEND_FOREIGN | f, f indexing the keys (and positions, for writers such
 * as STL's that need them) delivered through sink.foreign (required unless
 * b == N2) before those triangles.
 */
typedef struct isomend_piece {
    int64_t owned_first, owned_end; /* marched slices [owned_first, owned_end), */
                                    /* 0 <= first < end <= N2 (dims[2] + 2 pad) */
    int64_t columns[2], rows[2];    /* a box: marched columns [columns[0],
                                     * columns[1]) and rows [rows[0], rows[1]);
                                     * {0, 0} (zeros): all of them */
} isomend_piece;

/*
 * Box pieces.  A piece whose columns or rows are not all of the grid's owns
 * the marched samples of its box [columns) x [rows) x [owned_first,
 * owned_end), and with them, as above, the vertices whose edge's lower end
 * (or diagonal's lowest corner) is one of them and the cubes whose lowest
 * corner is, with their triangles, cube-private vertices and the mending and
 * Durst quadrilaterals of their +x, +y and +z faces.  Boxes that partition
 * the grid's samples partition isomend_extract()'s mesh.  A box delivers its
 * vertices in isomend_extract()'s order restricted to the box, numbered from
 * 0, and refers to every vertex it uses but does not own (on its +x, +y or
 * +z side) as ISOMEND_FOREIGN | f, f numbering them in the order of first
 * use; sink.foreign (required unless the box reaches the grid's end on
 * all three axes) is called before the triangles that use them, with
 * first = the number of foreign vertices delivered before.  It is pushed
 * the same whole volume slices as a slab (isomend_piece_halo()) and
 * classifies them whole; numbering, vertices and marching are the box's.
 */

/*
 * The volume slices a piece reads, [*first, *end): marched slices
 * owned_first - 1 .. owned_end + 1 (the gradients' neighbours, the z edges
 * into slice owned_end, the +z neighbours of the last layer's cubes),
 * clamped to the volume.  ISOMEND_ERR_INVALID_ARGUMENT for a piece outside
 * the grid, else isomend_stream_begin()'s checks.
 */
ISOMEND_API isomend_status isomend_piece_halo(const isomend_volume *desc,
                                              const isomend_options *opts,
                                              const isomend_piece *piece, int64_t *first,
                                              int64_t *end);

/*
 * Begins a piece: a stream (isomend_stream_push/finish/destroy) to which
 * exactly the volume slices of isomend_piece_halo() are pushed, in order,
 * starting with *first.  Vertices come with keys (above).  The statistics
 * at finish are the piece's: its layers' cubes, cases, faces and triangles,
 * the NaN samples of its slices, its own vertices; summed over the pieces
 * of a grid they are isomend_extract()'s.  The memory is
 * isomend_stream_memory() plus 24 bytes per vertex of a slice's bound (a
 * box: 80 bytes, and 480 KiB).  ISOMEND_ERR_INVALID_ARGUMENT for columns or rows outside
 * the grid or empty (but {0, 0}).
 */
ISOMEND_API isomend_status isomend_piece_begin(const isomend_volume *desc,
                                               const isomend_options *opts,
                                               const isomend_piece *piece,
                                               const isomend_mesh_sink *sink,
                                               isomend_stream **out);

/* ---------------------------------------------------------- continuity check */

/*
 * The continuity checker (thesis chapter 2.3.2, after Udupa et al. 1982):
 * a mesh is a continuous surface iff every edge is used by exactly two
 * triangles, except edges on the volume's outer faces, used once.
 */
typedef struct isomend_check_report {
    uint64_t vertices;             /* vertices referenced by triangles           */
    uint64_t triangles;
    uint64_t edges;                /* distinct undirected edges                  */
    uint64_t border_edges;         /* used once, lying in a face of the box      */
    uint64_t hole_edges;           /* used once, elsewhere: holes                */
    uint64_t hole_loops;           /* connected groups of hole edges             */
    uint64_t nonmanifold_edges;    /* used 3+ times: extraneous pieces           */
    uint64_t misoriented_edges;    /* used twice in the same direction           */
    uint64_t nonmanifold_vertices; /* triangles around it form 2+ fans           */
    uint64_t degenerate_triangles; /* repeated index or zero area                */
    uint64_t components;           /* connected components (through edges)       */
    int64_t euler;                 /* V - E + F                                  */
} isomend_check_report;

/*
 * Checks a triangle mesh.  `box` (min[3], max[3]) is the volume's box: a
 * once-used edge whose two endpoints lie in the same face plane of the box
 * (within 1e-6 of the box size) is a border edge, any other is a hole edge.
 * `box` NULL means the mesh's own bounding box.  Returns
 * ISOMEND_ERR_INVALID_ARGUMENT for an index >= vertex_count.
 */
ISOMEND_API isomend_status isomend_check(const float *positions, size_t vertex_count,
                                         const uint32_t *triangles, size_t triangle_count,
                                         const double *box, isomend_check_report *report);

/*
 * The bytes isomend_check() allocates for a mesh of these counts (its edge
 * tables, linear in the mesh), besides 28 bytes per triangle around the
 * busiest vertex: for a caller deciding whether the check fits its memory.
 */
ISOMEND_API uint64_t isomend_check_memory(size_t vertex_count, size_t triangle_count);

/*
 * The bytes isomend_mesh_check() allocates for this mesh at most.  A mesh in
 * the order of a sweep (isomend_extract()'s, the stream's, the files isomend
 * writes) is checked holding a window of a few slices' vertices, much less
 * than isomend_check_memory(); one pass over the triangles tells which.
 * 0 for NULL.
 */
ISOMEND_API uint64_t isomend_mesh_check_memory(const isomend_mesh *mesh);

/* Runs isomend_check on an extracted mesh with its grid box. */
ISOMEND_API isomend_status isomend_mesh_check(const isomend_mesh *mesh,
                                              isomend_check_report *report);

/*
 * The streaming continuity check: isomend_check()'s report on a mesh that
 * is never whole in memory, fed what a stream's sink gets (vertices,
 * triangles, retire; see isomend_mesh_sink).  The report is isomend_check()'s
 * on the whole mesh, field for field, with the box given at begin.  It
 * forgets a vertex once it is retired and holds memory linear in the window
 * of live vertices (about 200 bytes a live vertex), not in the mesh
 * (isomend_check_stream_peak_bytes()).  It works as triangles arrive and
 * as vertices retire (no sorting, no batching): constant work a triangle.
 * One object fed by one thread at a time: it may run on a worker thread
 * other than the one that made it or that runs the stream (the caller
 * passing batches on in order), but calls on one check must not overlap.
 * After a failure every later call but destroy returns that status.
 */
typedef struct isomend_check_stream isomend_check_stream;

/* Begins a check with the volume's box (min[3], max[3]; required: the
 * mesh's own box is known only at its end), as isomend_check()'s `box`.
 * On failure *out is NULL. */
ISOMEND_API isomend_status isomend_check_stream_begin(const double box[6],
                                                      isomend_check_stream **out);

/*
 * Begins the check of the mesh a stream of `desc` with `opts` delivers
 * (isomend_stream_begin()'s arguments and checks; data and strides are
 * ignored): its report is isomend_mesh_check()'s on isomend_extract()'s
 * mesh of that volume, the grid box included and, with slice origins, the
 * unsheared frame (the table is copied: 24 bytes a slice).
 */
ISOMEND_API isomend_status isomend_check_stream_begin_volume(const isomend_volume *desc,
                                                             const isomend_options *opts,
                                                             isomend_check_stream **out);

/*
 * Vertices first_id .. first_id + count - 1, 3 floats each (copied).  The
 * first call starts the numbering at any first_id (at least a floor retired
 * before it); each later one must start where the previous ended.  Gaps or
 * overlaps: ISOMEND_ERR_INVALID_ARGUMENT.  ISOMEND_ERR_TOO_LARGE when 2^31
 * or more ids would be live (delivered, not retired) at once.
 */
ISOMEND_API isomend_status isomend_check_stream_vertices(isomend_check_stream *s, uint64_t first_id,
                                                         size_t count, const float *positions);

/* `count` triangles, 3 ids each, every one delivered and not retired
 * (ISOMEND_ERR_INVALID_ARGUMENT otherwise, the foreign ids of pieces
 * included; the call then counts none of them). */
ISOMEND_API isomend_status isomend_check_stream_triangles(isomend_check_stream *s, size_t count,
                                                          const uint64_t *ids);

/* No later triangle uses an id below floor: those vertices are tested and
 * forgotten.  floor below an earlier one or above the ids delivered:
 * ISOMEND_ERR_INVALID_ARGUMENT. */
ISOMEND_API isomend_status isomend_check_stream_retire(isomend_check_stream *s, uint64_t floor);

/* Retires every vertex and fills the report (zeros on failure).  Once only;
 * later calls but destroy and peak_bytes return ISOMEND_ERR_INVALID_ARGUMENT. */
ISOMEND_API isomend_status isomend_check_stream_finish(isomend_check_stream *s,
                                                       isomend_check_report *report);

/* Accepts NULL. */
ISOMEND_API void isomend_check_stream_destroy(isomend_check_stream *s);

/* The most bytes the check has held so far (its arrays grow by doubling and
 * are kept), 0 for NULL. */
ISOMEND_API uint64_t isomend_check_stream_peak_bytes(const isomend_check_stream *s);

/* What the check of a stream of desc with opts (isomend_check_stream_begin_volume())
 * holds at most, on a surface as busy as a 256^3 gyroid (a vertex every 8
 * marched samples): 80 bytes a marched slice sample for the live window, two
 * chunks of its ring (1.3 MiB) and, with slice origins, 24 bytes a slice
 * (docs/streaming.md).  Not the queue a caller keeps in front of it.  0 for
 * invalid arguments. */
ISOMEND_API uint64_t isomend_check_stream_memory(const isomend_volume *desc,
                                                 const isomend_options *opts);

/*
 * Fills *sink with callbacks that feed the check (vertices, triangles,
 * retire; foreign NULL: not for pieces), for isomend_stream_begin() or for
 * a sink that passes what it gets on.  A callback returns non-zero when
 * the check fails; isomend_check_stream_finish() then says why.  The sink
 * is valid as long as the check.
 */
ISOMEND_API isomend_status isomend_check_stream_sink(isomend_check_stream *s,
                                                     isomend_mesh_sink *sink);

/* --------------------------------------------------------- post-processing */

/*
 * Steps on an extracted mesh that keep its promise: a closed, oriented
 * 2-manifold stays one, with the same components (but those clean-up drops
 * on purpose), orientation and Euler characteristic; vertices on once-used
 * edges (the volume's border of an unpadded surface, the holes of MC), on
 * edges used more than twice or twice the same way, and where a vertex's
 * triangles form several fans are locked: never moved, never removed.  Each
 * step makes a new mesh (the input is unchanged; destroy both).  Large
 * meshes share the work of a step (the decimation's costing, each smoothing
 * step) among the machine's cores, in ways that change nothing: the result
 * is the same bytes for any number of cores.  The new
 * mesh keeps the input's grid box and frame (isomend_mesh_check works as on
 * the input) and has no triangle origins; its normals, if the input had
 * any, are the triangles' area-weighted normals (decimation, smoothing) or
 * the input's (clean-up).
 */

/* Decimation targets: the larger triangle count of ratio * triangles and
 * target_triangles is kept; max_error (world units, 0: none) keeps every
 * input vertex within that distance of the triangles around the vertex it
 * is collapsed into (so within it of the result).  At least one of the
 * three must be set. */
typedef struct isomend_decimate_options {
    double ratio;              /* fraction of the triangles to keep, [0, 1]; 0: unused */
    uint64_t target_triangles; /* triangles to keep; 0: unused                      */
    double max_error;          /* >= 0, world units; 0: no limit                    */
} isomend_decimate_options;

/* All zero: no target (set at least one). */
ISOMEND_API void isomend_decimate_options_init(isomend_decimate_options *opts);

typedef struct isomend_decimate_report {
    uint64_t triangles_before, triangles_after;
    uint64_t vertices_before, vertices_after;
    uint64_t target_triangles; /* what the options asked (0: none, max_error only) */
    int reached;               /* 1: the target was reached; 0: stopped short,    */
                               /* every further collapse would break the surface */
                               /* or exceed max_error                            */
    double max_error;          /* the largest and the mean distance from the      */
    double mean_error;         /* input's vertices to the result (measured)      */
    uint64_t collapses;
    uint64_t locked_vertices;  /* border and non-manifold: kept as they are      */
    uint64_t refused_topology; /* collapses refused by the link condition        */
    uint64_t refused_geometry; /* ... by a flipped, degenerate or too thin       */
                               /* triangle                                       */
    uint64_t refused_error;    /* ... by max_error                               */
} isomend_decimate_report;

/*
 * Quadric-error edge collapse (Garland & Heckbert 1997) that refuses every
 * collapse breaking the surface: the link condition, flipped or degenerate
 * triangles, locked vertices (above), and with max_error the collapses
 * costlier than it.  A collapsed edge's vertex goes where it minimises the
 * sum of squared distances to the planes of the input triangles it stands
 * for.  When the target cannot be reached the mesh is decimated as far as
 * it can and report->reached is 0.  ISOMEND_ERR_INVALID_ARGUMENT for no
 * target or a ratio outside [0, 1].  report may be NULL.
 */
ISOMEND_API isomend_status isomend_mesh_decimate(const isomend_mesh *mesh,
                                                 const isomend_decimate_options *opts,
                                                 isomend_mesh **out,
                                                 isomend_decimate_report *report);

typedef struct isomend_smooth_report {
    uint64_t moved_vertices;  /* vertices free to move (not locked)              */
    double volume_before;     /* enclosed volume (closed surfaces; signed, as   */
    double volume_after;      /* the normals point outwards from lower values)  */
    double max_displacement;  /* the largest distance a vertex moved             */
} isomend_smooth_report;

/*
 * The windowed sinc filter of Taubin, Zhang and Golub (1996), the one VTK's
 * vtkWindowedSincPolyDataFilter and 3D Slicer apply: a low pass (pass band
 * 0.1, Hamming window) of degree `iterations` in the umbrella operator, each
 * iteration one umbrella step; it removes the voxel staircase without the
 * shrinking of plain Laplacian smoothing.  Then each component's volume is
 * restored by moving its free vertices along their normals by one offset
 * (the volume change over its area), so the enclosed volume is kept.  Only
 * vertices move, locked ones never: the triangles are the input's.  The
 * result does not depend on the threads.  iterations 0 copies the mesh.
 * ISOMEND_ERR_INVALID_ARGUMENT for iterations < 0 or > 10000.
 */
ISOMEND_API isomend_status isomend_mesh_smooth(const isomend_mesh *mesh, int iterations,
                                               isomend_mesh **out, isomend_smooth_report *report);

/*
 * Surfaces that meet, smoothed together so that they still meet: a label
 * map's meshes (isomend_labels_mesh()), whose vertices where two labels
 * touch are one grid edge's midpoint in both.  The meshes' vertices are made
 * one set (a vertex is the same in every mesh where its position is the
 * same, bit for bit), each vertex's neighbours those it has in any of its
 * meshes, and isomend_mesh_smooth()'s filter runs once on that set: a
 * shared vertex moves once and stays shared.  A vertex locked in one of its
 * meshes stays.  No volume is restored (an offset along one side's normals
 * would part the sides): reports[i] (may be NULL; `count` of them) gives
 * mesh i's volume before and after, its moved vertices and the largest
 * move.  out[0 .. count - 1] receive new meshes (the inputs' triangles),
 * all NULL on failure.  The result does not depend on the threads.
 * ISOMEND_ERR_INVALID_ARGUMENT for iterations < 0 or > 10000 or a NULL
 * mesh; ISOMEND_ERR_TOO_LARGE from 2^32 - 1 vertices or corners in all.
 */
ISOMEND_API isomend_status isomend_meshes_smooth(const isomend_mesh *const *meshes, size_t count,
                                                 int iterations, isomend_mesh **out,
                                                 isomend_smooth_report *reports);

/*
 * Surfaces that meet (a label map's meshes, as isomend_meshes_smooth()
 * takes them) decimated so that they still meet: every vertex that another
 * of the meshes holds too (the same position) is locked, so no edge touching
 * it collapses; the surfaces two meshes share, and the ring of triangles
 * around them, stay as they are in both, and the rest of each mesh is
 * decimated with `opts` as isomend_mesh_decimate() does (ratio and
 * target_triangles a mesh; every guarantee of it).  A mesh that touches the
 * others all over keeps its triangles.  out[0 .. count - 1] receive new
 * meshes, all NULL on failure; reports[i] (may be NULL) mesh i's.
 */
ISOMEND_API isomend_status isomend_meshes_decimate(const isomend_mesh *const *meshes, size_t count,
                                                   const isomend_decimate_options *opts,
                                                   isomend_mesh **out,
                                                   isomend_decimate_report *reports);

typedef struct isomend_clean_report {
    uint64_t components_before, components_after; /* through shared vertices */
    uint64_t triangles_removed, vertices_removed;
} isomend_clean_report;

/*
 * Drops the connected components (triangles joined through shared vertices)
 * of fewer than min_triangles triangles, then keeps the keep_largest largest
 * of the rest (0: all; ties: the one whose first triangle comes first).
 * Vertices and triangles keep their order, normals and origins.
 */
ISOMEND_API isomend_status isomend_mesh_clean(const isomend_mesh *mesh, uint64_t min_triangles,
                                              uint64_t keep_largest, isomend_mesh **out,
                                              isomend_clean_report *report);

/*
 * Streamed decimation: isomend_mesh_decimate()'s collapses on a mesh that is
 * never whole in memory, between a stream (isomend_stream_begin(), any
 * thread count) and a sink (a writer, the streaming check).  The stream's
 * layers are cut into chunks of `chunk_layers` layers (0: the default,
 * isomend_decimate_stream_layers()).  As each chunk completes, it is
 * decimated together with the band held back from the previous one (a
 * window), with the vertices the window shares with the rest (below: final
 * triangles; above: the next chunk) locked; the triangles within a few rings
 * of the new top plane (with a ratio or a target and no max_error, on chunks
 * of more than one layer, up to a layer's worth more of the surface below
 * it, so that the next window can move the budget across the seam) are held
 * back for the next window, where that plane is free, and the rest is final.
 * Every window is a decimation of a piece of the surface whose cut is
 * locked, so the pieces still fit: a closed, oriented 2-manifold stays one,
 * with its components and Euler characteristic; held vertices keep their
 * quadrics from window to window (docs/postprocess.md, "Streamed").
 *
 * The output: vertices numbered from 0 in the order they are first used,
 * each delivered once every triangle around it is final (its normal, unless
 * ISOMEND_FLAG_NO_NORMALS, the area-weighted normal of those triangles),
 * triangles in a fixed order, retire() as vertices are done.  The mesh
 * depends on the volume, the options, the decimation's options and
 * chunk_layers only: not on the stream's threads.  Targets as
 * isomend_mesh_decimate()'s: each window keeps what keeps the running total
 * at ratio of the triangles so far; target_triangles needs the stream's
 * triangle count beforehand (isomend_decimate_stream_expect(), from an
 * earlier pass over a spool of the stream), the running total is then
 * max(ratio * count, target_triangles) * (triangles so far) / count;
 * max_error keeps every stream vertex within it of the result, as in
 * memory: a held vertex carries the stream vertices it stands for (those
 * not yet within max_error of its final triangles) into the next window.
 * Memory: a chunk's triangles and the bands', isomend_decimate_stream_memory().
 */
typedef struct isomend_decimate_stream isomend_decimate_stream;

/* The default chunk height for a volume (about 2^22 marched samples a
 * chunk, 4 to 64 layers), or if that is less the most layers whose
 * isomend_decimate_stream_memory() fits max_bytes (0: no limit), at least
 * 1; 0 for invalid arguments.  dopts as for the memory. */
ISOMEND_API int64_t isomend_decimate_stream_layers(const isomend_volume *desc,
                                                   const isomend_options *opts,
                                                   const isomend_decimate_options *dopts,
                                                   uint64_t max_bytes);

/*
 * An estimate of the most the decimation holds with chunks of chunk_layers
 * layers (0: the default), isomend_decimate_stream_peak_bytes() at its
 * largest, on a surface as busy as a 256^3 gyroid (one triangle every 4
 * marched samples; a padded end's cap one every sample): a window of the
 * chunk and its bands (about 512 bytes a triangle: slots, id table, the
 * window's mesh, the decimation's tables) and what the distances are
 * measured against (a share of the triangles of about 80 layers: the
 * ratio's, or a quarter where max_error or target_triangles decide, all of
 * them for dopts NULL), and 1 MiB.  A busier surface holds more in
 * proportion to its triangles (docs/postprocess.md).  0 for invalid
 * arguments.
 */
ISOMEND_API uint64_t isomend_decimate_stream_memory(const isomend_volume *desc,
                                                    const isomend_options *opts,
                                                    const isomend_decimate_options *dopts,
                                                    int64_t chunk_layers);

/* Begins a streamed decimation of what a stream of desc with opts delivers
 * (their checks as isomend_stream_begin()), passing the result to `out`
 * (copied; vertices, triangles and retire required).  On failure *ds is
 * NULL. */
ISOMEND_API isomend_status isomend_decimate_stream_begin(const isomend_volume *desc,
                                                         const isomend_options *opts,
                                                         const isomend_decimate_options *dopts,
                                                         int64_t chunk_layers,
                                                         const isomend_mesh_sink *out,
                                                         isomend_decimate_stream **ds);

/* The sink to give isomend_stream_begin() (vertices, triangles, retire;
 * foreign NULL).  A callback returns non-zero when the decimation or the
 * out sink failed (isomend_decimate_stream_finish() then says which). */
ISOMEND_API isomend_status isomend_decimate_stream_sink(isomend_decimate_stream *ds,
                                                        isomend_mesh_sink *sink);

/* Before the stream's first triangle: the number of triangles the stream
 * will deliver (known from an earlier pass over the same stream), which a
 * target_triangles needs (without it the first window fails with
 * ISOMEND_ERR_INVALID_ARGUMENT); the target is then
 * max(ceil(ratio * triangles), target_triangles), as in memory.  A
 * stream of another count makes isomend_decimate_stream_finish() return
 * ISOMEND_ERR_INVALID_ARGUMENT.  ISOMEND_ERR_INVALID_ARGUMENT when called
 * twice or after a triangle. */
ISOMEND_API isomend_status isomend_decimate_stream_expect(isomend_decimate_stream *ds,
                                                          uint64_t triangles);

/* After the stream's finish: decimates and delivers the rest and fills the
 * report (report may be NULL): counts before and after, the target (ratio *
 * triangles, or the expected count's target above; 0 for max_error alone),
 * reached, collapses, and the distances from the
 * stream's vertices to the result, each measured a few chunks after its own
 * against the surface near it as it then stands (docs/postprocess.md).
 * ISOMEND_ERR_SINK when `out` stopped it. */
ISOMEND_API isomend_status isomend_decimate_stream_finish(isomend_decimate_stream *ds,
                                                          isomend_decimate_report *report);

/* The most bytes the decimation has held at once so far, counted as it
 * allocates (its window, held band, chunk, id table, quadrics, points,
 * measurement and each window's decimation; not malloc's own overhead): what
 * isomend_decimate_stream_memory() estimates.  Any time before destroy; 0
 * for NULL. */
ISOMEND_API uint64_t isomend_decimate_stream_peak_bytes(const isomend_decimate_stream *ds);

/* Accepts NULL. */
ISOMEND_API void isomend_decimate_stream_destroy(isomend_decimate_stream *ds);

/*
 * Streamed clean-up: isomend_mesh_clean()'s --min-component on a mesh that
 * is never whole in memory, between a stream (isomend_stream_begin(), any
 * thread count, or another streamed step) and a sink.  A union-find over the
 * stream's live vertices: a component's triangles are held back until it
 * has min_triangles of them (then they pass, and every triangle that joins
 * it later passes at once) or until it closes (no live vertex left, by the
 * stream's retire floors: then it is dropped).  The triangles kept are
 * exactly isomend_mesh_clean(mesh, min_triangles, 0)'s, and the report's
 * components, triangles and vertices removed are its (docs/postprocess.md,
 * "Streamed").  keep_largest needs every component's size before anything
 * is written: isomend_largest_stream_*, two passes.
 *
 * The output: vertices numbered from 0 in the order a passed triangle first
 * uses them (with the normals they came with), triangles in the order they
 * pass (a held component's in stream order when it reaches min_triangles),
 * no origins, and one retire() for each of the input's, so that a streamed
 * smoothing or decimation after it still counts the stream's layers.  It
 * depends on the stream's vertices, triangles and floors only (not on the
 * threads).  Memory: the live vertices and the held components' triangles
 * (each fewer than min_triangles), isomend_clean_stream_memory().
 */
typedef struct isomend_clean_stream isomend_clean_stream;

/* An estimate of what it holds on a stream of desc with opts (a surface as
 * busy as a 256^3 gyroid), 0 for invalid arguments. */
ISOMEND_API uint64_t isomend_clean_stream_memory(const isomend_volume *desc,
                                                 const isomend_options *opts);

/* Begins a streamed clean-up passing its result to `out` (copied; vertices,
 * triangles and retire required).  min_triangles 0 or 1 keeps everything. */
ISOMEND_API isomend_status isomend_clean_stream_begin(uint64_t min_triangles,
                                                      const isomend_mesh_sink *out,
                                                      isomend_clean_stream **cs);

/* The sink to give the stream (vertices, triangles, retire; foreign NULL).
 * A callback returns non-zero when the clean-up or `out` failed. */
ISOMEND_API isomend_status isomend_clean_stream_sink(isomend_clean_stream *cs,
                                                     isomend_mesh_sink *sink);

/* After the stream's finish: closes what is still open (a stream's last
 * retire has closed everything already) and fills the report (may be
 * NULL).  ISOMEND_ERR_SINK when `out` stopped it; ISOMEND_ERR_INVALID_ARGUMENT
 * when the stream broke the sink's rules. */
ISOMEND_API isomend_status isomend_clean_stream_finish(isomend_clean_stream *cs,
                                                       isomend_clean_report *report);

/* Accepts NULL. */
ISOMEND_API void isomend_clean_stream_destroy(isomend_clean_stream *cs);

/*
 * Streamed --largest: isomend_mesh_clean(mesh, min_triangles, keep_largest)
 * on a mesh that is never whole in memory.  Every component's size is
 * needed before a triangle is written, so the caller plays the same stream
 * through the sink twice (a scratch spool of it, replayed): pass 1 counts
 * each component's triangles by a frontier union-find (clean_stream's);
 * isomend_largest_stream_replay() then keeps the keep_largest largest
 * components of at least min_triangles triangles (0: all of those; ties:
 * the component whose first triangle comes first, as isomend_mesh_clean());
 * pass 2 runs the same union-find again and passes only the triangles of
 * kept components to `out`.  A piece of a component gets a seed at the
 * retire after it starts, the same in both passes, and pass 1 notes which
 * seeds join: so pass 2 knows a piece's component long before it closes,
 * holding at most the triangles of one layer (docs/postprocess.md,
 * "Streamed --largest").  The triangles kept and the report are exactly
 * isomend_mesh_clean()'s.
 *
 * The output (pass 2) as isomend_clean_stream_*'s: vertices numbered from 0
 * in the order a passed triangle first uses them (the normals they came
 * with), triangles in stream order but for those held within a layer (they
 * pass at its retire), no origins, one retire() for each of the stream's.
 * It depends on the stream's vertices, triangles and floors only.  Memory:
 * the live vertices, one layer's held triangles
 * (isomend_largest_stream_memory()) and, growing with the surface's pieces,
 * 8 bytes a seed in pass 1 (1 bit in pass 2) and 24 bytes a component of
 * min_triangles or more.
 */
typedef struct isomend_largest_stream isomend_largest_stream;

/* An estimate of what it holds on a stream of desc with opts (a surface as
 * busy as a 256^3 gyroid), 0 for invalid arguments. */
ISOMEND_API uint64_t isomend_largest_stream_memory(const isomend_volume *desc,
                                                   const isomend_options *opts);

/* Begins pass 1; `out` (copied; vertices, triangles and retire required)
 * gets pass 2's result. */
ISOMEND_API isomend_status isomend_largest_stream_begin(uint64_t min_triangles,
                                                        uint64_t keep_largest,
                                                        const isomend_mesh_sink *out,
                                                        isomend_largest_stream **ls);

/* The sink to give the stream in both passes (vertices, triangles, retire;
 * foreign NULL).  A callback returns non-zero when the step or `out` failed. */
ISOMEND_API isomend_status isomend_largest_stream_sink(isomend_largest_stream *ls,
                                                       isomend_mesh_sink *sink);

/* After pass 1's stream ended: closes what is open, chooses the kept
 * components and starts pass 2 (the same stream again, from id 0). */
ISOMEND_API isomend_status isomend_largest_stream_replay(isomend_largest_stream *ls);

/* After isomend_largest_stream_replay(): the triangles pass 2 will pass
 * (the kept components'), so that a step after it knows its input's size
 * beforehand (isomend_decimate_stream_expect()); 0 before the replay. */
ISOMEND_API uint64_t isomend_largest_stream_kept_triangles(const isomend_largest_stream *ls);

/* After pass 2's stream ended: delivers the rest, fills the report (may be
 * NULL).  ISOMEND_ERR_SINK when `out` stopped it; ISOMEND_ERR_INVALID_ARGUMENT
 * when a stream broke the sink's rules, or pass 2's stream was not pass 1's. */
ISOMEND_API isomend_status isomend_largest_stream_finish(isomend_largest_stream *ls,
                                                         isomend_clean_report *report);

/* Accepts NULL. */
ISOMEND_API void isomend_largest_stream_destroy(isomend_largest_stream *ls);

/*
 * Streamed smoothing: isomend_mesh_smooth()'s windowed sinc on a mesh
 * that is never whole in memory, between a stream (or a streamed clean-up)
 * and a sink (a writer, the streaming check, a streamed decimation).  The
 * layers are cut into chunks of chunk_layers (0: the default,
 * isomend_decimate_stream_layers()); as each completes, it is smoothed with
 * the band held back from the previous one by isomend_mesh_smooth(), whose
 * locks keep the window's cut in place; the triangles within N + 1 rings
 * of the new top plane (N the iterations: N umbrella steps reach that far) are
 * held back and smoothed again, from the stream's positions, in the next
 * window; the rest is final.  Only vertices move, cut vertices never: a
 * closed, oriented 2-manifold stays one, with its components and Euler
 * characteristic.  Each window restores its components' signed volume, so
 * the volume is kept but for the bands (docs/postprocess.md, "Streamed").
 *
 * The output as isomend_decimate_stream_*'s: vertices numbered from 0 in
 * the order they are delivered (once every triangle around them is final,
 * with those triangles' area-weighted normal unless
 * ISOMEND_FLAG_NO_NORMALS), the stream's triangles, no origins, one
 * retire() for each of the input's.  It depends on the volume, the options,
 * the iterations and chunk_layers only (not on the stream's threads).  The
 * report: vertices moved, the largest displacement, and the signed volume
 * of the stream's triangles before and of the result's after.
 */
typedef struct isomend_smooth_stream isomend_smooth_stream;

/* An estimate of what it holds, isomend_smooth_stream_peak_bytes() at its
 * largest: a chunk and a band of N + 2 layers (at a padded end the cap and
 * the band) of a surface as busy as a 256^3 gyroid, about 360 bytes a
 * triangle (docs/postprocess.md); 0 for invalid arguments. */
ISOMEND_API uint64_t isomend_smooth_stream_memory(const isomend_volume *desc,
                                                  const isomend_options *opts, int iterations,
                                                  int64_t chunk_layers);

/* Begins a streamed smoothing of N = iterations (0 .. 10000) of what a
 * stream of desc with opts delivers, passing the result to `out` (copied;
 * vertices, triangles and retire required).  On failure *ss is NULL. */
ISOMEND_API isomend_status isomend_smooth_stream_begin(const isomend_volume *desc,
                                                       const isomend_options *opts, int iterations,
                                                       int64_t chunk_layers,
                                                       const isomend_mesh_sink *out,
                                                       isomend_smooth_stream **ss);

/* The sink to give the stream (vertices, triangles, retire; foreign NULL). */
ISOMEND_API isomend_status isomend_smooth_stream_sink(isomend_smooth_stream *ss,
                                                      isomend_mesh_sink *sink);

/* After the stream's finish: smooths and delivers the rest, fills the
 * report (may be NULL).  ISOMEND_ERR_SINK when `out` stopped it. */
ISOMEND_API isomend_status isomend_smooth_stream_finish(isomend_smooth_stream *ss,
                                                        isomend_smooth_report *report);

/* The most bytes the smoothing has held at once so far, counted as it
 * allocates (its window, held band, chunk, id table and each window's
 * smoothing; not malloc's own overhead): what isomend_smooth_stream_memory()
 * estimates.  Any time before destroy; 0 for NULL. */
ISOMEND_API uint64_t isomend_smooth_stream_peak_bytes(const isomend_smooth_stream *ss);

/* Accepts NULL. */
ISOMEND_API void isomend_smooth_stream_destroy(isomend_smooth_stream *ss);

/* ------------------------------------------------------------- label maps */

/*
 * Label maps (segmentations: TotalSegmentator, 3D Slicer, FreeSurfer): an
 * integer volume whose samples are label values.  The surface of label L is
 * the surface of its indicator (1 where the sample is L, 0 elsewhere) at
 * level 0.5: exactly isomend_extract()'s mesh of that indicator (as a u8
 * volume, iso 0.5) with the same method and flags, byte for byte, vertex
 * order, normals and origins included.  Every vertex is the midpoint of a
 * grid edge whose two samples differ, so where two labels touch, their
 * surfaces have the same vertex positions on the shared boundary.  Each
 * label's normals come from its own indicator (pointing out of the label,
 * into the label with ISOMEND_FLAG_FLIP).
 *
 * All the labels are extracted in one pass over the volume, not one a label:
 * a cube whose eight samples are not all equal is marched once for each
 * requested label among its corners.  The meshes do not depend on the
 * thread count (slabs of slices, one a thread).
 *
 * Types: ISOMEND_U8, _I8, _U16, _I16, _U32, _I32 (ISOMEND_ERR_INVALID_ARGUMENT
 * for the float types).  Methods: ISOMEND_METHOD_DMC (the default; each
 * label's surface a closed oriented 2-manifold with ISOMEND_FLAG_PAD),
 * _DURST and _MC; the others ISOMEND_ERR_UNSUPPORTED.  Ambiguous faces: on a
 * label's indicator every ambiguous face has its saddle exactly at 0.5; the
 * table methods do not test it: the MC table separates the label's corners
 * on such a face in a cube with at most 4 of them and joins them in a cube
 * with 5 or more, and DMC adds its quadrilateral where two cubes disagree
 * (docs/labels.md: why this and not the face methods' tie rule, under which
 * two labels on a checkerboard would both be joined and cross).  Options:
 * iso is ignored; the flags as for isomend_extract() (SMALL_PAGES changes
 * nothing: the meshes are malloc'ed); slice origins: ISOMEND_ERR_UNSUPPORTED.
 * Progress as for isomend_extract() (every 16 slices of the first slab).
 */
typedef struct isomend_labels isomend_labels;

/*
 * The labels present in `vol` (any label type), ascending, and their sample
 * counts: *count receives how many there are; the first `capacity` go to
 * `values` and `voxels` (either may be NULL).  One pass over the volume.
 */
ISOMEND_API isomend_status isomend_labels_present(const isomend_volume *vol, int64_t *values,
                                                  uint64_t *voxels, size_t capacity, size_t *count);

/*
 * The surfaces of `labels[0 .. count - 1]` (distinct values, in that order;
 * a label absent from the volume gets an empty mesh and 0 voxels), or with
 * labels NULL of every label present but 0 (the background), ascending.
 * `opts` NULL: the defaults.  On success *out receives the result (destroy
 * with isomend_labels_destroy()); on failure NULL.  A value twice:
 * ISOMEND_ERR_INVALID_ARGUMENT.
 */
ISOMEND_API isomend_status isomend_labels_extract(const isomend_volume *vol, const int64_t *labels,
                                                  size_t count, const isomend_options *opts,
                                                  isomend_labels **out);

/* The number of labels of a result, each one's value, its samples in the
 * volume, and its mesh (owned by the result: valid until
 * isomend_labels_destroy(); isomend_mesh_check() and the accessors work on
 * it, never isomend_mesh_destroy()).  Out of range: 0 / NULL. */
ISOMEND_API size_t isomend_labels_count(const isomend_labels *result);
ISOMEND_API int64_t isomend_labels_value(const isomend_labels *result, size_t index);
ISOMEND_API uint64_t isomend_labels_voxels(const isomend_labels *result, size_t index);
ISOMEND_API const isomend_mesh *isomend_labels_mesh(const isomend_labels *result, size_t index);

/* Hands the mesh of label `index` over to the caller (destroy it with
 * isomend_mesh_destroy()); the result keeps its value and voxels and has no
 * mesh for it any more (isomend_labels_mesh() then returns NULL).  NULL when
 * out of range or already taken.  For bindings that own each mesh. */
ISOMEND_API isomend_mesh *isomend_labels_take_mesh(isomend_labels *result, size_t index);

/* Accepts NULL. */
ISOMEND_API void isomend_labels_destroy(isomend_labels *result);

/*
 * A label map streamed: slices pushed one at a time, in z order (each
 * contiguous, x fastest, desc->type, desc->dims[0] x dims[1] samples; the
 * data and strides of `desc` are not used), the surfaces made as the slices
 * arrive, and the result isomend_labels_extract()'s, byte for byte, at
 * finish.  The stream holds 4 slices of codes (4 bytes a sample) and 2 of
 * edge ids (24 bytes a sample) besides the meshes; one thread (opts->threads
 * is not used), no progress calls.  `labels` must be given (a stream cannot
 * list the labels present: isomend_labels_present() on the slices does).
 * Too many slices, or too few at finish: ISOMEND_ERR_SLICE_COUNT (sticky).
 */
typedef struct isomend_labels_stream isomend_labels_stream;

ISOMEND_API isomend_status isomend_labels_stream_begin(const isomend_volume *desc,
                                                       const int64_t *labels, size_t count,
                                                       const isomend_options *opts,
                                                       isomend_labels_stream **out);
ISOMEND_API isomend_status isomend_labels_stream_push(isomend_labels_stream *s, const void *slice);
/* Once: the result into *out (NULL on failure). */
ISOMEND_API isomend_status isomend_labels_stream_finish(isomend_labels_stream *s,
                                                        isomend_labels **out);
/* Accepts NULL. */
ISOMEND_API void isomend_labels_stream_destroy(isomend_labels_stream *s);

/* ------------------------------------------------------------ case tables */

/*
 * Read-only access to the generated tables (for tests, tools and teaching).
 * Cube corner c (0..7) sits at (c & 1, (c >> 1) & 1, (c >> 2) & 1); bit c of
 * a configuration is set when corner c is positive.  Edge e (0..11) runs
 * along axis e / 4 (x, y, z) from its lower corner; for k = e % 4, the
 * lower-numbered of the two other axes is at k & 1, the other at k >> 1
 * (edge 5 joins corners 1 and 3).  libcore/src/cube.h draws the cube and
 * lists the faces.
 */
/* Elementary case 0..14 of a configuration 0..255 (-1 for an invalid one). */
ISOMEND_API int isomend_case_of(unsigned config);
/* Number of triangles of the MC table for a configuration; fills up to
 * 3*5 edge indices (0..11) into `edges` if not NULL. */
ISOMEND_API int isomend_case_triangles(unsigned config, int *edges);

#ifdef __cplusplus
}
#endif

#endif /* ISOMEND_H */
