/*
 * isomend_io.h - slice-stack importer for isomend (public C API)
 *
 * Opens a volume given as a stack of 2D images (read with OpenImageIO) or as
 * a raw/NRRD file (read with isomend's own readers), validates it completely,
 * and delivers it to the caller: into a caller's buffer, into a
 * library-owned buffer described as an isomend_volume, one slice at a time,
 * or straight to a mesh with isomend_extract().
 *
 * This library is separate from the core (libisomend) so that the core never
 * loads OpenImageIO (~260 shared libraries).  It is C++17 inside; every
 * exported function catches all exceptions and returns a status.
 *
 * Sources (one `isomend_io_open()` call, `paths` / `path_count`):
 *   - a folder:          every image file whose extension is the folder's most
 *                        common image extension, in natural order (s_2 before
 *                        s_10; case-insensitive, digits compared as numbers);
 *   - a glob:            'scan/slice_*.tif' (a path with * ? or [ ), natural
 *                        order of the matches;
 *   - a printf pattern:  'slice_%04d.tif' (a path containing one %d / %0Nd /
 *                        %Nd / %i / %u conversion; "%%" is a literal '%'):
 *                        indices first, first+step, ... (options.first,
 *                        options.count, options.step); count 0 means "until
 *                        the first missing file";
 *   - a list of files:   path_count >= 2; the order given is kept;
 *   - one multi-page TIFF (pages are slices) or one multi-part OpenEXR (parts
 *     are slices) or any other multi-subimage 2D file;
 *   - one raw file (options.raw_dims / raw_type set) or NRRD file (.nrrd /
 *     .nhdr): read by io/common's readers, see isomend_io_options;
 *   - a DICOM series (read with GDCM): a folder holding DICOM files (any
 *     names, found by their content), a DICOMDIR, a list, glob or pattern of
 *     DICOM files, or one multi-frame (enhanced) DICOM file; see "DICOM" below;
 *   - a NIfTI volume (read with libnifti2): one .nii or .nii.gz file, or a
 *     .hdr/.img pair (either name), NIfTI-1, NIfTI-2 or ANALYZE 7.5; see
 *     "NIfTI" below.
 * Every 2D format OpenImageIO reads is accepted.  Tested: TIFF u8, u16, i16
 * (negative values kept), f32, packed 12-bit (restored to its real 0..4095
 * values, not OIIO's scaled 16-bit ones; likewise 1- and 4-bit), tiled TIFF,
 * OpenEXR half and float, PNG.  A TIFF Orientation tag is not applied: pixels
 * are taken as stored (row 0 first).
 *
 * Sample types are kept as stored (no normalisation to 0..1): u8, i8, u16,
 * i16, i32, f32, f64; half becomes f32 and u32 becomes f64 (both exact);
 * --channel luma gives f32 (Rec. 709: 0.2126 R + 0.7152 G + 0.0722 B of the
 * stored values).
 *
 * Axes: x = image column (left to right as displayed), y = image row (top
 * row first: row 0 is y = 0, as stored, no flip), z = slice order (first
 * slice is z = 0).  Sample (x, y, z) is at index x + nx*(y + ny*z) of a
 * contiguous volume.  (column, row, slice) with x right, y down and slices
 * stacked away from the viewer is a right-handed frame, and so is (x, y, z):
 * the mesh is the stack as the user sees it, moved, never mirrored.  Looking
 * at the mesh from its z < 0 side with +y pointing down shows each slice as
 * an image viewer shows it (an "L" stays an "L", never a "J"); in a y-up
 * viewer that is the default view turned 180 degrees about the x axis.
 * tests/io checks this with an asymmetric "L" phantom.
 *
 * Validation (isomend_io_open() opens every slice's header; the reads check
 * every decode): a missing, unreadable or unknown file; truncated or corrupt
 * data (has_error() after every read, and per-scanline decoding so that
 * broken compressed strips are reported); a slice whose size, data window,
 * channel count, sample type or bit depth differs from the first slice's; a
 * 3D image (depth > 1); a multi-page file inside a folder or list; an ImageJ
 * hyperstack with several channels or frames (pages interleave them); a
 * 1-bit TIFF without a BitsPerSample tag (OIIO 2.4.7 returns its packed bits
 * as bytes); an empty folder or a pattern/glob with no match; fewer than two
 * slices; a volume larger than the memory available (refused with its size
 * before anything is allocated).  Every message names the slice file and the
 * reason.
 *
 * A NRRD whose "space directions" point an axis backwards (NIfTI-derived RAS
 * data) is delivered reversed along that axis, with the origin moved to the
 * stored last sample, so that world = origin + index * spacing (spacing > 0)
 * holds for every source: the mesh lands where the samples are, unmirrored,
 * as the isomend command line places it.
 *
 * Spacing: options.spacing if set (all three > 0), else the files' metadata
 * (ImageJ's "spacing=" in ImageDescription for z and its resolution tags as
 * pixels per unit for x/y; else TIFF XResolution / YResolution with
 * ResolutionUnit inch or cm, in mm, except 72 and 96 dpi, the defaults image
 * programs write, which count as unknown; NRRD "spacings"/"space
 * directions"), else 1.  isomend_io_spacing() says where each value came from.
 * Spacings from TIFF resolution tags (which OIIO gives as float) are rounded
 * to 6 significant digits (1/1.3333334f -> 0.75, not 0.74999996).
 *
 * Thread safety: a source handle must be used by one thread at a time;
 * different handles are independent.  Functions that read may start worker
 * threads internally; the progress callback is always called from the
 * calling thread.  A job (isomend_io_job_start) does the work on a thread
 * of its own and calls no callback at all.  There is no global mutable state visible to the caller
 * (OpenImageIO's own global attributes are set once, idempotently).
 *
 * Bindings (ctypes, MeshLab): opaque handle, plain C types, status codes,
 * message retrieval from the handle, caller-sized or library-owned buffers.
 */
#ifndef ISOMEND_IO_H
#define ISOMEND_IO_H

#include <stddef.h>
#include <stdint.h>

#include "isomend.h"

#if defined(__GNUC__) && __GNUC__ >= 4
#  define ISOMEND_IO_API __attribute__((visibility("default")))
#else
#  define ISOMEND_IO_API
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------------ status */

typedef enum isomend_io_status {
    ISOMEND_IO_OK = 0,
    ISOMEND_IO_ERR_INVALID_ARGUMENT = 1, /* NULL, bad option, call out of order   */
    ISOMEND_IO_ERR_NOT_FOUND = 2,        /* missing file/folder, nothing matched  */
    ISOMEND_IO_ERR_UNREADABLE = 3,       /* cannot open, unknown format           */
    ISOMEND_IO_ERR_CORRUPT = 4,          /* truncated or corrupt data             */
    ISOMEND_IO_ERR_MISMATCH = 5,         /* slice differs from the first slice    */
    ISOMEND_IO_ERR_UNSUPPORTED = 6,      /* 3D image, sample type, channel        */
    ISOMEND_IO_ERR_TOO_FEW_SLICES = 7,   /* fewer than two slices                 */
    ISOMEND_IO_ERR_TOO_LARGE = 8,        /* larger than the memory available      */
    ISOMEND_IO_ERR_OUT_OF_MEMORY = 9,
    ISOMEND_IO_ERR_CANCELLED = 10,       /* the progress callback asked to stop   */
    ISOMEND_IO_ERR_EXTRACT = 11,         /* the core's isomend_extract() failed   */
    ISOMEND_IO_ERR_INTERNAL = 12,        /* unexpected exception (a bug)          */
    ISOMEND_IO_ERR_SERIES = 13           /* DICOM: several series and none chosen,
                                            or the choice names none of them      */
} isomend_io_status;

/* A static description of a status ("corrupt or truncated data"). */
ISOMEND_IO_API const char *isomend_io_status_string(isomend_io_status status);

/* The library's version string (same as the core's, e.g. "0.1.0"). */
ISOMEND_IO_API const char *isomend_io_version(void);

/* The image libraries this build reads slices with and their versions:
 * "OpenImageIO 2.4.7" (every format OpenImageIO reads), or
 * "libtiff 4.5.0, OpenEXR 3.1.5, libpng 1.6.39" for the portable build that
 * reads TIFF, OpenEXR and PNG (the one the Blender add-on carries).  A static
 * string. */
ISOMEND_IO_API const char *isomend_io_image_libraries(void);

/* ------------------------------------------------------------------ options */

/* Progress stages passed to the callback. */
typedef enum isomend_io_stage {
    ISOMEND_IO_STAGE_OPEN = 0,    /* scanning slice headers            */
    ISOMEND_IO_STAGE_READ = 1,    /* decoding slices                   */
    ISOMEND_IO_STAGE_ANALYSE = 2, /* value range, histogram, Otsu      */
    ISOMEND_IO_STAGE_EXTRACT = 3  /* the core's isomend_extract()      */
} isomend_io_stage;

/*
 * Progress: called from the thread that called the isomend_io function, with
 * the stage and a fraction in [0, 1] of that stage, at most ~20 times per
 * second.  Return non-zero to cancel: the call returns ISOMEND_IO_ERR_CANCELLED.
 */
typedef int (*isomend_io_progress_fn)(void *user, int stage, double fraction);

#define ISOMEND_IO_CHANNEL_AUTO (-1) /* the only channel; error if several  */
#define ISOMEND_IO_CHANNEL_LUMA (-2) /* Rec.709 luma of channels 0..2, f32  */

typedef struct isomend_io_options {
    /* printf pattern range: indices first, first+step, ..., count of them;
     * count 0 = until the first missing index.  Defaults 0, 0, 1. */
    int64_t first;
    int64_t count;
    int64_t step;
    /* channel index >= 0, or ISOMEND_IO_CHANNEL_AUTO / ISOMEND_IO_CHANNEL_LUMA */
    int channel;
    /* spacing override: used when all three are > 0 (default all 0) */
    double spacing[3];
    /* world position of sample (0, 0, 0); all three 0 (the default) means
     * the file's own origin (NRRD "space origin"), else 0 */
    double origin[3];
    /* reader threads, 0 = one per core (max 8) */
    int threads;
    /* refuse volumes larger than this many bytes; 0 = MemAvailable from
     * /proc/meminfo (or no limit where unknown) */
    uint64_t memory_limit;
    /* raw source: set raw_dims (all > 0) and raw_type to read a headerless
     * file; raw_header bytes are skipped; raw_big_endian != 0 for big-endian */
    int64_t raw_dims[3];
    isomend_type raw_type;
    uint64_t raw_header;
    int raw_big_endian;
    /* may be NULL */
    isomend_io_progress_fn progress;
    void *progress_user;
    /* slice positions: the z of each slice (slice_position_count = the
     * number of slices, strictly increasing, finite), for a stack or a
     * raw/NRRD volume whose slices are not evenly spaced (microscopy with
     * variable steps, re-sliced data): slice k is meshed at z =
     * slice_positions[k] (a z spacing and origin given or read are then
     * not used).  Positions each within 1e-6 x their mean gap of evenly
     * spaced are taken as that spacing and origin (a uniform grid).
     * Either way the z spacing reported is the mean gap and the origin's z
     * slice_positions[0].  NULL / 0: evenly spaced.  A count that is not
     * the number of slices, a value that is not finite or not greater than
     * the one before: ISOMEND_IO_ERR_INVALID_ARGUMENT naming
     * slice_positions.  Refused for a DICOM series, whose positions are its
     * own.  Copied by isomend_io_open() (and by isomend_io_job_start()). */
    const double *slice_positions;
    size_t slice_position_count;
} isomend_io_options;

/* Fills the defaults described above. */
ISOMEND_IO_API void isomend_io_options_init(isomend_io_options *opts);

/* ------------------------------------------------------------------ source */

/* An opened, validated source.  Create, open, query/read, destroy. */
typedef struct isomend_io_source isomend_io_source;

/* Allocates an empty source (*out NULL on failure). */
ISOMEND_IO_API isomend_io_status isomend_io_create(isomend_io_source **out);

/* Accepts NULL. Frees the loaded volume too. */
ISOMEND_IO_API void isomend_io_destroy(isomend_io_source *src);

/*
 * The message of the last failed call on this handle, naming the file and
 * the reason, e.g. "slice_0003.tif: 256x200 differs from the first slice's
 * 256x256 (scan/slice_0000.tif)".  "" if the last call succeeded.  Owned by
 * the handle, valid until the next call on it.  NULL src gives "".
 */
ISOMEND_IO_API const char *isomend_io_message(const isomend_io_source *src);

/*
 * Resolves the source (see the top of this file), opens every slice's header
 * and checks that all agree.  Reads no pixel data (except for raw/NRRD,
 * whose header is parsed).  `opts` may be NULL for the defaults.  May be
 * called once per handle.
 */
ISOMEND_IO_API isomend_io_status isomend_io_open(isomend_io_source *src, const char *const *paths,
                                                 size_t path_count,
                                                 const isomend_io_options *opts);

/* ---- queries (after a successful open) ---- */

/* dims[0] = columns (x), dims[1] = rows (y), dims[2] = slices (z). */
ISOMEND_IO_API isomend_io_status isomend_io_dims(const isomend_io_source *src, int64_t dims[3]);
/* The sample type delivered (half -> f32, luma -> f32, 12-bit -> u16). */
ISOMEND_IO_API isomend_io_status isomend_io_type(const isomend_io_source *src, isomend_type *type);
/* Bytes of the whole volume (nx*ny*nz*sample size) and of one slice. */
ISOMEND_IO_API uint64_t isomend_io_volume_bytes(const isomend_io_source *src);
ISOMEND_IO_API uint64_t isomend_io_slice_bytes(const isomend_io_source *src);

/* Where a spacing value came from. */
typedef enum isomend_io_spacing_source {
    ISOMEND_IO_SPACING_DEFAULT = 0,  /* nothing known: 1                      */
    ISOMEND_IO_SPACING_OPTION = 1,   /* options.spacing                       */
    ISOMEND_IO_SPACING_TIFF = 2,     /* TIFF XResolution/YResolution          */
    ISOMEND_IO_SPACING_IMAGEJ = 3,   /* ImageJ "spacing=" (z)                 */
    ISOMEND_IO_SPACING_HEADER = 4,   /* NRRD header                           */
    ISOMEND_IO_SPACING_DICOM = 5,    /* DICOM Pixel Spacing (x, y)            */
    ISOMEND_IO_SPACING_POSITIONS = 6 /* DICOM: measured between the slices'
                                        Image Position (Patient) (z)          */
} isomend_io_spacing_source;
/* "default", "option", "tiff", "imagej", "header", "dicom", "positions";
 * NULL if invalid. */
ISOMEND_IO_API const char *isomend_io_spacing_source_name(int source);

/* spacing[3]; `sources` (may be NULL) receives an isomend_io_spacing_source per axis. */
ISOMEND_IO_API isomend_io_status isomend_io_spacing(const isomend_io_source *src, double spacing[3],
                                                    int sources[3]);
ISOMEND_IO_API isomend_io_status isomend_io_origin(const isomend_io_source *src, double origin[3]);

/* The kind of source resolved. */
typedef enum isomend_io_kind {
    ISOMEND_IO_KIND_FOLDER = 0,
    ISOMEND_IO_KIND_GLOB = 1,
    ISOMEND_IO_KIND_PATTERN = 2,
    ISOMEND_IO_KIND_LIST = 3,
    ISOMEND_IO_KIND_MULTIPAGE = 4, /* pages/parts of one file */
    ISOMEND_IO_KIND_RAW = 5,
    ISOMEND_IO_KIND_NRRD = 6,
    ISOMEND_IO_KIND_DICOM = 7,     /* a DICOM series, see "DICOM" below */
    ISOMEND_IO_KIND_NIFTI = 8      /* a NIfTI volume, see "NIfTI" below */
} isomend_io_kind;
/* "folder", "glob", "pattern", "list", "multipage", "raw", "nrrd", "dicom",
 * "nifti"; NULL if invalid. */
ISOMEND_IO_API const char *isomend_io_kind_name(int kind);
ISOMEND_IO_API int isomend_io_source_kind(const isomend_io_source *src); /* -1 before open */

/* The OpenImageIO format name of the first slice ("tiff", "openexr", ...),
 * "raw", "nrrd", "dicom", or for NIfTI "nifti1", "nifti2" or "analyze";
 * "" before open. Owned by the handle. */
ISOMEND_IO_API const char *isomend_io_format(const isomend_io_source *src);

/* Path of slice k (for a multi-page file: the file's path for every k);
 * NULL if k is out of range.  Owned by the handle. */
ISOMEND_IO_API const char *isomend_io_slice_path(const isomend_io_source *src, int64_t k);

/*
 * The slices' geometry.  Every source has one; a DICOM series' comes from
 * its Image Position (Patient) values, others' from options.slice_positions
 * (or the spacing).  A series whose slices are not evenly spaced on one line
 * along the slice normal (uniform 0) is meshed at its slices' true
 * positions: isomend_io_slice_origins() is not NULL, and isomend_io_load()
 * sets isomend_volume.slice_origins to it.  A source without positions is
 * uniform, its gaps all spacing[2], its tilt and offset 0.  The warning is
 * set for DICOM series only (slice_positions are the caller's own).
 */
typedef struct isomend_io_geometry {
    size_t size;            /* set by the caller: sizeof(isomend_io_geometry)  */
    int uniform;            /* evenly spaced on one line (no slice origins)     */
    double gap_median;      /* gaps between neighbouring slices along z (the    */
    double gap_min;         /* slice normal), in the volume's units (mm for     */
    double gap_max;         /* DICOM)                                           */
    double tilt_degrees;    /* angle between z and the line from the first      */
                            /* slice's origin to the last's (gantry tilt)        */
    double max_offset;      /* largest distance of a slice's origin from where  */
                            /* an evenly spaced grid would put it               */
    int64_t long_gaps;      /* gaps over 1.5x the median (missing slices?)      */
    int64_t uneven_gaps;    /* gaps that differ from the median by more than 1% */
    const char *warning;    /* "" or one line for the user (uneven gaps, a long */
                            /* gap), without the source's name; owned by the    */
                            /* handle                                           */
} isomend_io_geometry;

/* Fills `out` (its first out->size bytes at most) after a successful open. */
ISOMEND_IO_API isomend_io_status isomend_io_geometry_info(const isomend_io_source *src,
                                                          isomend_io_geometry *out);

/* The slices' origins in the frame of the volume isomend_io_load()
 * describes (isomend_volume.slice_origins: 3 doubles a slice), or NULL for a
 * uniform grid or before open.  Owned by the handle. */
ISOMEND_IO_API const double *isomend_io_slice_origins(const isomend_io_source *src);

/* ---- reading ---- */

/*
 * Reads the whole volume into `buffer` (contiguous, x fastest, machine byte
 * order, isomend_io_volume_bytes() bytes; `buffer_size` must be at least
 * that).  Worker threads decode slices; progress (stage READ) and
 * cancellation run on the calling thread.  No memory check (the caller owns
 * the buffer).  On failure the buffer content is unspecified.
 */
ISOMEND_IO_API isomend_io_status isomend_io_read(isomend_io_source *src, void *buffer,
                                                 size_t buffer_size);

/*
 * Reads slice k (0-based) into `buffer` (isomend_io_slice_bytes() bytes,
 * x fastest): opens, decodes and closes the file, so memory stays flat when
 * marching through a stack larger than memory.  No progress callback.
 */
ISOMEND_IO_API isomend_io_status isomend_io_read_slice(isomend_io_source *src, int64_t k,
                                                       void *buffer, size_t buffer_size);

/*
 * Reads the whole volume into a buffer owned by the handle (after checking
 * that isomend_io_volume_bytes() fits options.memory_limit / the available
 * memory: ISOMEND_IO_ERR_TOO_LARGE with the size in the message otherwise)
 * and describes it in `vol` (data, type, dims, contiguous strides, spacing,
 * origin, and slice_origins: isomend_io_slice_origins()).  Loading twice
 * reuses the buffer.  `vol->data` stays valid until
 * the handle is destroyed.  `seconds` (may be NULL) receives the read time.
 */
ISOMEND_IO_API isomend_io_status isomend_io_load(isomend_io_source *src, isomend_volume *vol,
                                                 double *seconds);

/* ---- analysis ---- */

#define ISOMEND_IO_HISTOGRAM_BINS 16

typedef struct isomend_io_summary {
    double min, max;        /* finite sample range (0, 0 if none is finite)   */
    uint64_t samples;       /* nx*ny*nz                                       */
    uint64_t nan_samples;   /* NaN or infinite samples (not in the histogram) */
    /* coarse histogram: bin b covers [min + b*w, min + (b+1)*w), w =
     * (max-min)/ISOMEND_IO_HISTOGRAM_BINS, the last bin includes max */
    uint64_t histogram[ISOMEND_IO_HISTOGRAM_BINS];
    double suggested_iso;   /* see isomend_io_analyse()                       */
    double read_seconds;    /* time spent reading slices                      */
} isomend_io_summary;

/*
 * Computes the value range, a coarse histogram and the suggested iso level.
 * Uses the loaded volume if isomend_io_load() was called, else streams the
 * slices one at a time (flat memory).
 *
 * Suggested iso rule: for a CT DICOM series in HU, the bone level (see
 * isomend_io_level_value); for every other source Otsu (1979): a 256-bin histogram of the finite samples
 * over [min, max]; t = the upper edge of the bin that maximises the
 * between-class variance w0*w1*(m0 - m1)^2 (when empty bins after it give
 * the same maximum, the edge in the middle of that gap).  For integer types t is then
 * moved to floor(t) + 0.5, so that no sample equals the level.  If all
 * samples are equal the suggestion is that value (no surface exists).
 */
ISOMEND_IO_API isomend_io_status isomend_io_analyse(isomend_io_source *src,
                                                    isomend_io_summary *summary);

/* ------------------------------------------------------------------ DICOM */

/*
 * A DICOM source is recognised by content, before any other rule: a file is
 * DICOM when it has the 128-byte preamble and "DICM" (files without the
 * Part 10 header are not recognised).  A folder is a DICOM source when it
 * holds a DICOMDIR or at least one DICOM file; its other files are ignored
 * and counted.  A folder with neither DICOM files nor images at its top
 * level is searched for DICOM files in its subfolders (an export's root).
 *
 * Series: the images are grouped by Series Instance UID and the series are
 * listed in order of Series Number, then UID.  With several series, choose
 * one with isomend_io_set_series() before opening; otherwise the open fails
 * with ISOMEND_IO_ERR_SERIES and a message listing them, and the list stays
 * available through isomend_io_series_count() / isomend_io_series_get().
 * DICOM objects without pixel data (structured reports, presentation
 * states, RT structures, a DICOMDIR inside a folder) are ignored and
 * counted, and so are files that are not DICOM.
 *
 * Geometry: slices are ordered by their Image Position (Patient) along the
 * slice normal n = row x column of Image Orientation (Patient) (never by
 * file name or Instance Number); x = column index (along the row direction
 * cosine), y = row index (along the column direction cosine), z = slice
 * index (along n).  Spacing x, y = Pixel Spacing's second and first values
 * (column spacing, row spacing); z = the distance between the first and
 * last positions along n / (slices - 1), the mean gap.  The mesh is in
 * patient coordinates (DICOM LPS: +x towards the patient's left, +y
 * posterior, +z head; millimetres):
 *     world = P0 + R * (index * spacing),  R = [row | column | n]
 * with P0 the first slice's Image Position (Patient).  Because the slices
 * are sorted along n, R is a rotation (determinant +1): a surface is never
 * mirrored.  The core's grid is axis aligned, so isomend_io_load() describes
 * the volume in the series' own frame, the patient frame turned by R^-1
 * (spacing as above, origin R^-1 P0), and isomend_io_world_transform()
 * gives the map that turns it back (the identity for an axial series whose
 * rows and columns run along +x and +y).  With ISOMEND_IO_AXES_GRID the
 * transform is the identity: the mesh stays in the series' own frame (x
 * along the rows, y along the columns, z along the slices, at R^-1 P0).
 *
 * Slices where they are: each slice k lies at its own origin in that frame,
 * R^-1 P_k = (row . P_k, column . P_k, n . P_k).  A series whose origins are
 * all within 1e-4 of the smaller pixel spacing of the evenly spaced line
 * R^-1 P0 + k * (mean gap) * z is a uniform grid (isomend_io_slice_origins()
 * NULL), described by origin and spacing as above.  Any other series is
 * meshed at its slices' true positions, never resampled:
 * isomend_io_slice_origins() holds the 3 * slices origins and
 * isomend_io_load() passes them as isomend_volume.slice_origins, so each
 * vertex lies between its two samples' true positions.  That covers gaps
 * that vary (positions rounded to 0.1 mm by the scanner, a spacing that
 * changes part-way, a missing slice) and slices shifted in their plane (the
 * shear of a gantry tilt); the world transform stays R.
 * isomend_io_geometry_info() reports the gaps along n (median, min, max),
 * the tilt (the angle between n and the line from the first slice's
 * position to the last's), the largest offset from the even grid, and one
 * warning line when a gap differs from the median by more than 1% or
 * exceeds 1.5x the median (a missing slice?); the mesh is made all the same.
 * When options.spacing is given it replaces the positions' spacing: the
 * series is then an evenly spaced grid of that spacing (no slice origins;
 * the warning, if any, says so).  options.slice_positions is refused
 * (ISOMEND_IO_ERR_INVALID_ARGUMENT): a series' positions are its own.
 *
 * Values: stored values are masked to Bits Stored (sign-extended when Pixel
 * Representation is 1); MONOCHROME1 is inverted (s' = smin + smax - s over
 * the range Bits Stored allows: brighter is higher); then Rescale Slope and
 * Intercept (per frame in enhanced files) are applied, so CT values are
 * Hounsfield units.  The delivered type holds every value the header allows
 * without clipping: the stored type when nothing is rescaled, else the
 * smallest of u8, i16, u16, i32 that holds slope * [smin, smax] + intercept
 * when slope and intercept are integers, else f32 (f64 for 32-bit samples).
 * Transfer syntaxes: every one GDCM 3.0 decodes (implicit and explicit VR,
 * deflate, RLE, JPEG baseline/lossless, JPEG-LS, JPEG 2000); uncompressed
 * and RLE pixel data are taken from GDCM's parse and unpacked by isomend.
 *
 * Validation (every message names the file and the reason): files that do
 * not parse, whose pixel data are truncated or do not decode; images whose
 * size, Bits Allocated / Stored, Pixel Representation, photometric
 * interpretation, Pixel Spacing or Image Orientation (beyond 1e-4) differ
 * from the first image's; colour images; a missing Image Position,
 * Orientation or Pixel Spacing (unless options.spacing is set); two slices
 * at one position along n (closer than a hundredth of the smaller pixel
 * spacing: duplicates, or several echoes / time points in one series);
 * fewer than two slices; several series without a choice.  Only what
 * cannot be a volume is refused: uneven gaps, missing slices and sheared
 * (tilted) stacks are meshed where their slices are (see "Slices where
 * they are" above).
 *
 * Reading: isomend_io_read() decodes files in worker threads (a multi-frame
 * file is decoded once, on one thread); isomend_io_read_slice() of a
 * multi-frame file decodes the whole file.  isomend_io_analyse() of a DICOM
 * source loads the volume first (with the memory check).
 */

/* The axes of a DICOM or NIfTI mesh (isomend_io_set_axes). */
typedef enum isomend_io_axes {
    ISOMEND_IO_AXES_PATIENT = 0, /* patient coordinates, LPS mm (default) */
    ISOMEND_IO_AXES_GRID = 1,    /* the series' (volume's) own frame, no rotation */
    ISOMEND_IO_AXES_RAS = 2      /* NIfTI: the file's RAS mm (FSL, FreeSurfer);
                                    refused by isomend_io_open() for DICOM */
} isomend_io_axes;

/*
 * Chooses the series of a DICOM source before isomend_io_open() (or
 * isomend_io_job_start()): a Series Instance UID, or the 1-based position N
 * in the list as text ("2"; a text of digits only is a position).  NULL or
 * "" = the only series (the default).  Ignored by other sources.
 */
ISOMEND_IO_API isomend_io_status isomend_io_set_series(isomend_io_source *src, const char *series);

/* Chooses the axes (isomend_io_axes) before opening; ignored by sources
 * other than DICOM and NIfTI. */
ISOMEND_IO_API isomend_io_status isomend_io_set_axes(isomend_io_source *src, int axes);

/* One series of a DICOM source.  Strings are owned by the handle. */
typedef struct isomend_io_series {
    size_t size;             /* set by the caller: sizeof(isomend_io_series) */
    const char *uid;         /* Series Instance UID                          */
    const char *description; /* Series Description, "" if none               */
    const char *modality;    /* "CT", "MR", ... ("" if none)                 */
    int64_t number;          /* Series Number, -1 if none                    */
    int64_t files;           /* image files (a multi-frame file counts once) */
    int64_t images;          /* 2D images (frames)                           */
    int64_t columns, rows;   /* of its first image                           */
} isomend_io_series;

/*
 * The series found by the last isomend_io_open() of a DICOM source, also
 * after it failed with ISOMEND_IO_ERR_SERIES (0 for other sources).
 * isomend_io_series_get() fills `out` (its first out->size bytes at most:
 * set out->size first); the index is 0-based.  isomend_io_series_chosen()
 * is the index of the series opened, -1 if none.
 */
ISOMEND_IO_API int64_t isomend_io_series_count(const isomend_io_source *src);
ISOMEND_IO_API isomend_io_status isomend_io_series_get(const isomend_io_source *src, int64_t index,
                                                       isomend_io_series *out);
ISOMEND_IO_API int64_t isomend_io_series_chosen(const isomend_io_source *src);

/* What an opened DICOM series holds.  Strings are owned by the handle. */
typedef struct isomend_io_dicom {
    size_t size;                 /* set by the caller: sizeof(isomend_io_dicom)  */
    const char *modality;        /* "CT", "MR", ...                              */
    const char *series_uid;
    const char *description;     /* Series Description                           */
    const char *transfer_syntax; /* of the first file, e.g. "1.2.840.10008.1.2.5" */
    const char *transfer_syntax_name; /* GDCM's name, e.g. "RLE Lossless"        */
    const char *photometric;     /* "MONOCHROME1" or "MONOCHROME2"               */
    int bits_stored;
    int pixel_signed;            /* Pixel Representation 1                       */
    int rescaled;                /* a slope != 1 or an intercept != 0 applies    */
    int hounsfield;              /* CT values in HU: the CT levels apply         */
    double rescale_slope, rescale_intercept; /* the first slice's                */
    double orientation[6];       /* Image Orientation (Patient): row, column     */
    double normal[3];            /* row x column, the slice direction            */
    double position[3];          /* Image Position (Patient) of slice 0          */
    int64_t files;               /* image files of the series                    */
    int64_t multiframe;          /* 1 when the series is one multi-frame file    */
    int64_t non_image;           /* DICOM objects without pixel data, ignored    */
    int64_t non_dicom;           /* files that are not DICOM, ignored            */
    int64_t other_series;        /* image files of the series not chosen         */
    int axes;                    /* isomend_io_axes in use                       */
} isomend_io_dicom;

/* Fills `out` (its first out->size bytes at most) for an opened DICOM
 * source; ISOMEND_IO_ERR_UNSUPPORTED for other sources. */
ISOMEND_IO_API isomend_io_status isomend_io_dicom_info(const isomend_io_source *src,
                                                       isomend_io_dicom *out);

/*
 * The affine map from the core's positions (origin + index * spacing of the
 * volume isomend_io_load() describes) to the source's world frame:
 *     world[r] = affine[4r] x + affine[4r+1] y + affine[4r+2] z + affine[4r+3]
 * (3x4, row-major).  The identity for every source except a DICOM series in
 * patient axes that is not axial along +x, +y, and a NIfTI volume whose
 * transform is more than a scaling and a translation (see "NIfTI").  `identity` (may be NULL)
 * receives 1 when it is exactly the identity.  Apply it with the core's
 * isomend_mesh_copy_transformed(); isomend_io_extract() does not.
 */
ISOMEND_IO_API isomend_io_status isomend_io_world_transform(const isomend_io_source *src,
                                                            double affine[12], int *identity);

/* ------------------------------------------------------------------ NIfTI */

/*
 * A NIfTI source is one path named .nii or .nii.gz, or .hdr / .img (also
 * .gz) whose header libnifti2 reads as NIfTI-1, NIfTI-2 or ANALYZE 7.5 (a
 * Radiance .hdr image is not one); read with Debian's libnifti2 (which
 * handles gzip and byte order).
 *
 * Volume: x = i, y = j, z = k of the file (the voxels as stored, never
 * reordered), spacing = |pixdim| (in mm: xyz_units metres and microns are
 * converted; a zero pixdim takes its axis's length in the affine), the
 * spacing sources "header".  A 4th to 7th dimension of 1 is accepted;
 * several volumes (fMRI, DWI) are refused (ISOMEND_IO_ERR_UNSUPPORTED): mesh
 * one volume, extracted first.  Every dimension must be at least 2.
 *
 * Values: scl_slope / scl_inter are applied when the slope is not 0 (the
 * NIfTI rule for "no scaling") and they are not exactly 1 and 0; the
 * delivered type then holds every scaled value, by the DICOM rule: integer
 * slope and intercept on integer samples give the smallest of u8, i16, u16,
 * i32 that holds slope * [stored range] + intercept (f64 beyond), anything
 * else f32 (f64 for int32, uint32 and float64 samples).  Unscaled samples
 * keep their type: uint8, int8, uint16, int16, int32, float32, float64;
 * uint32 becomes f64 (exact).  Other datatypes (RGB, complex, 64-bit
 * integers, float128, binary) are refused naming the file and the type.
 *
 * World: the sform if sform_code > 0, else the qform if qform_code > 0,
 * else pixdim scaling (NIfTI's "method 1", the ANALYZE case): A (3x4,
 * (i, j, k) -> RAS mm).  The default, ISOMEND_IO_AXES_PATIENT, puts the mesh
 * in the DICOM path's patient coordinates (LPS mm: x = -R, y = -A), so that
 * a NIfTI converted from a DICOM series and the series itself give the same
 * mesh in the same place; ISOMEND_IO_AXES_RAS keeps the file's RAS (what
 * FSL, FreeSurfer and nibabel show); ISOMEND_IO_AXES_GRID leaves the map
 * out.  With F = diag(-1, -1, 1) (LPS) or the identity (RAS) and S =
 * diag(spacing), L = F A S^-1; the volume's origin is L^-1 F t (t the
 * affine's translation, or options.origin, then in the chosen axes) and
 * isomend_io_world_transform() returns [L | F t - L origin] (the
 * translation ~1e-14).  L is a rotation for a qform and may be any
 * invertible map for an sform (a shear, a mirror: det L < 0 for most
 * files, whose i axis points left); the core's
 * isomend_mesh_copy_transformed() reverses the winding of a mirrored copy,
 * so the mesh stays outward.  A singular or non-finite transform is refused
 * (ISOMEND_IO_ERR_CORRUPT).  options.spacing replaces the spacing (L keeps
 * the file's directions); options.slice_positions is refused.
 *
 * Validation (every message names the file): a missing file (or the .img of
 * a .hdr), a header that is not NIfTI/ANALYZE (ISOMEND_IO_ERR_UNREADABLE) or
 * that libnifti cannot read (ISOMEND_IO_ERR_CORRUPT), uncompressed data
 * shorter than the header says (at open), compressed data that end early
 * (at read, ISOMEND_IO_ERR_CORRUPT).
 *
 * Reading: an uncompressed file is read slice by slice (isomend_io_read()
 * reports progress and can be cancelled between slices;
 * isomend_io_read_slice() reads one slice with a seek).  A gzip-compressed
 * file (.nii.gz) is decompressed in one pass by isomend_io_read(); its
 * isomend_io_read_slice(k) decompresses slices 0..k again, so streaming a
 * .nii.gz costs time quadratic in the slices (isomend_io_analyse() loads it
 * once instead, with the memory check).
 */

/* What an opened NIfTI volume holds.  Strings are owned by the handle. */
typedef struct isomend_io_nifti {
    size_t size;               /* set by the caller: sizeof(isomend_io_nifti)    */
    int version;               /* 1 or 2 (NIfTI-1 / -2), 0 for ANALYZE 7.5      */
    int two_files;             /* a .hdr/.img pair                              */
    int gzip;                  /* the data are gzip-compressed                  */
    const char *header_path;   /* the .nii or .hdr                              */
    const char *image_path;    /* the .nii or .img                              */
    const char *datatype;      /* as stored, libnifti's name ("INT16", ...)     */
    int scaled;                /* scl_slope / scl_inter applied                 */
    double scl_slope, scl_inter; /* as in the header                            */
    int sform_code, qform_code;
    const char *transform;     /* the one used: "sform", "qform" or "pixdim"    */
    double file_affine[12];    /* that transform, (i, j, k) -> RAS mm, 3x4
                                  row-major, as in the file (units converted)   */
    int axes;                  /* isomend_io_axes in use                        */
} isomend_io_nifti;

/* Fills `out` (its first out->size bytes at most) for an opened NIfTI
 * source; ISOMEND_IO_ERR_UNSUPPORTED for other sources. */
ISOMEND_IO_API isomend_io_status isomend_io_nifti_info(const isomend_io_source *src,
                                                       isomend_io_nifti *out);

/* Named iso levels. */
typedef enum isomend_io_level {
    ISOMEND_IO_LEVEL_OTSU = 0, /* Otsu's threshold (isomend_io_analyse)    */
    ISOMEND_IO_LEVEL_BONE = 1, /* CT: 300 HU, cortical and trabecular bone */
    ISOMEND_IO_LEVEL_SKIN = 2  /* CT: -500 HU, between air and soft tissue */
} isomend_io_level;
/* "otsu", "bone", "skin"; NULL if invalid. */
ISOMEND_IO_API const char *isomend_io_level_name(int level);

/*
 * The value of a named level.  OTSU analyses the volume (isomend_io_analyse;
 * for a CT series too); BONE and SKIN are fixed Hounsfield values, for a CT
 * series in HU only (ISOMEND_IO_ERR_UNSUPPORTED with a message otherwise).
 * The suggested level (isomend_io_summary.suggested_iso, what
 * isomend_io_extract() uses) is BONE for a CT series in HU and OTSU for
 * every other source; isomend_io_suggested_level() says which (-1 before
 * open).
 */
ISOMEND_IO_API isomend_io_status isomend_io_level_value(isomend_io_source *src, int level,
                                                        double *value);
ISOMEND_IO_API int isomend_io_suggested_level(const isomend_io_source *src);

/* ---- one call from source to mesh ---- */

/*
 * Loads the volume (isomend_io_load) and extracts its isosurface with the
 * core.  If `use_suggested_iso` is non-zero, the iso level is the suggested
 * one (isomend_io_analyse) instead of opts->iso.  `opts` may be NULL for the
 * core's defaults.  If opts->progress is NULL, the extraction reports through
 * the source's progress callback with stage EXTRACT (and can be cancelled
 * there).  `iso_used` (may be NULL) receives the level used; `stats` (may
 * be NULL) the core's statistics.  On failure *out_mesh is NULL; a core
 * failure gives ISOMEND_IO_ERR_EXTRACT and its status text in the message.
 * Destroy the mesh with isomend_mesh_destroy().
 */
ISOMEND_IO_API isomend_io_status isomend_io_extract(isomend_io_source *src,
                                                    const isomend_options *opts,
                                                    int use_suggested_iso, double *iso_used,
                                                    isomend_mesh **out_mesh,
                                                    isomend_stats *stats);

/* ---- label maps (segmentations) ---- */

/*
 * Loads the volume (isomend_io_load) and extracts the surfaces of its labels
 * with the core's isomend_labels_extract(): labels[0 .. count - 1], or with
 * count 0 every label present but 0, ascending.  Options, progress (stage
 * EXTRACT through the source's callback when opts->progress is NULL) and
 * cancellation as for isomend_io_extract(); opts->iso is ignored.  The
 * meshes are in the grid's frame, as isomend_io_extract()'s: place them with
 * isomend_io_world_transform().  Refused, with a message naming the source:
 * float samples that are not all whole numbers (a NIfTI uint32 map arrives
 * as f64 and is taken as u32 or i32), slices not evenly spaced
 * (ISOMEND_IO_ERR_UNSUPPORTED); a listed label that is not in the volume, a
 * volume with no label but 0 (ISOMEND_IO_ERR_INVALID_ARGUMENT); what the core
 * refuses (a method other than dmc, mc, durst; a label listed twice) is
 * ISOMEND_IO_ERR_EXTRACT with the core's text.  On success *out holds the
 * core's result: destroy it with isomend_labels_destroy().
 */
ISOMEND_IO_API isomend_io_status isomend_io_labels_extract(isomend_io_source *src,
                                                           const int64_t *labels, size_t count,
                                                           const isomend_options *opts,
                                                           isomend_labels **out);

/*
 * Label names and colours (io/common/label_table.h, as `isomend extract
 * --labels` takes them).  `path` non-NULL: a colour table file (3D Slicer
 * .ctbl/.txt, FreeSurfer's LUT, ITK-SNAP's label description); `src` then
 * only receives the message and need not be open.  `path` NULL: the opened
 * source's own names, a 3D Slicer .seg.nrrd's Segment*_Name/_Color/
 * _LabelValue keys (an empty set for any other source).  Failures
 * (unreadable or malformed table, malformed keys) leave *out NULL and the
 * message in isomend_io_message(src).
 */
typedef struct isomend_io_label_names isomend_io_label_names;
ISOMEND_IO_API isomend_io_status isomend_io_label_names_read(isomend_io_source *src,
                                                             const char *path,
                                                             isomend_io_label_names **out);
/* Where the names come from: "slicer/freesurfer", "itk-snap", "seg.nrrd",
 * or "" for an empty set (and for NULL). */
ISOMEND_IO_API const char *isomend_io_label_names_from(const isomend_io_label_names *names);
/* The name (truncated to name_size - 1 bytes) and colour a label is shown
 * with: the set's, else "label_N" and a fixed 20-colour palette by value.
 * `names` may be NULL; name or rgb may be NULL.  1 when the set has the value. */
ISOMEND_IO_API int isomend_io_label_name(const isomend_io_label_names *names, int64_t value,
                                         char *name, size_t name_size, uint8_t rgb[3]);
/* Accepts NULL. */
ISOMEND_IO_API void isomend_io_label_names_destroy(isomend_io_label_names *names);

/* ---- the same, on a thread of the library's own ---- */

/*
 * A job runs isomend_io_open() then isomend_io_extract() on a thread the
 * library starts, for a host whose interface keeps running meanwhile but whose
 * own code must not run on other threads (Blender: "Python threads are not
 * supported").  Nothing of the caller's runs on the job's thread: there is no
 * callback; the caller polls the progress and may ask the job to stop.
 *
 *   isomend_io_job_start(src, paths, n, &io_opts, &opts, 0, &job);
 *   while (!isomend_io_job_poll(job, &stage, &fraction))   // e.g. on a UI timer
 *       if (user_pressed_esc) isomend_io_job_cancel(job);
 *   status = isomend_io_job_finish(job, &iso, &mesh, &stats);
 *
 * `src` is a handle from isomend_io_create() that has not been opened; the
 * job uses it until isomend_io_job_finish() returns, and the caller must not
 * touch it before then (a second job on it is refused, with no message).  Afterwards it is an ordinary source: the queries
 * work, isomend_io_message() holds the failure's message, and
 * isomend_io_load() describes the loaded volume without reading it again.
 * `paths` and both option structs are copied; `opts` may be NULL for the
 * core's defaults; `use_suggested_iso` is isomend_io_extract()'s.  The
 * progress callbacks of both structs must be NULL (ISOMEND_IO_ERR_INVALID_ARGUMENT
 * otherwise).  A job that was started is always ended with
 * isomend_io_job_finish(), which frees it.
 */
typedef struct isomend_io_job isomend_io_job;

ISOMEND_IO_API isomend_io_status isomend_io_job_start(isomend_io_source *src,
                                                      const char *const *paths, size_t path_count,
                                                      const isomend_io_options *io_opts,
                                                      const isomend_options *opts,
                                                      int use_suggested_iso,
                                                      isomend_io_job **out_job);

/* Does not block.  Returns 1 once the job's thread has ended, else 0;
 * `stage` (an isomend_io_stage) and `fraction` (0..1 of that stage; either
 * pointer may be NULL) receive the last progress the job reported. */
ISOMEND_IO_API int isomend_io_job_poll(const isomend_io_job *job, int *stage, double *fraction);

/* Does not block.  The job stops at its next progress point (at most ~50 ms
 * apart) and ends with ISOMEND_IO_ERR_CANCELLED, unless it had already ended. */
ISOMEND_IO_API void isomend_io_job_cancel(isomend_io_job *job);

/* Waits for the job's thread (cancel first not to wait for the rest of the
 * work), frees the job and returns its status: isomend_io_open()'s if the
 * open failed, else isomend_io_extract()'s.  `iso_used`, `out_mesh` and
 * `stats` are as for isomend_io_extract() and may be NULL (the mesh is then
 * destroyed).  NULL job: ISOMEND_IO_ERR_INVALID_ARGUMENT. */
ISOMEND_IO_API isomend_io_status isomend_io_job_finish(isomend_io_job *job, double *iso_used,
                                                       isomend_mesh **out_mesh,
                                                       isomend_stats *stats);

#ifdef __cplusplus
}
#endif

#endif /* ISOMEND_IO_H */
