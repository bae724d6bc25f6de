/*
 * cli.h - internals of the `isomend` command line (io/cli)
 *
 *   main.c      the commands (extract, check, info, sample)
 *   args.c      the options of every command (shared with isomend-mpi)
 *   cli_util.c  messages, number parsing, timing, the progress bar
 *   source.c    an opened SOURCE (cli_source): which kind it is, the options
 *               checked against it, read slice by slice or loaded, closed;
 *               the kinds' own files:
 *     source_volume.c    raw, NRRD (io/common) and the built-in F1/F2
 *     source_importer.c  image stacks, DICOM, NIfTI through the importer
 *                        (ISOMEND_HAVE_IO)
 *     importer.c         the importer libisomend_io, loaded with dlopen()
 *     source_geometry.c  --slice-positions and where the slices lie
 *     source_summary.c   value range, histogram, suggested iso level
 *     source_report.c    a DICOM series' and a NIfTI volume's facts
 *               (source_internal.h is what these files share)
 *   stream.c    the --max-memory rule, the mesh sink, the streaming extraction
 *   report.c    the Table-2 statistics, the check summary and the JSON object
 *   postprocess.c  clean-up, smoothing, decimation after the extraction
 *
 * Exit codes: 0 success, 1 failure (a file cannot be read or written, the
 * extraction fails, `check` finds a defect), 2 usage error (unknown option,
 * bad number, bad type, unknown or unavailable method).
 */
#ifndef ISOMEND_CLI_H
#define ISOMEND_CLI_H

#include <stdint.h>
#include <stdio.h>

#include "atomic_file.h"
#include "volume_readers.h"
#include "isomend.h"
#include "mesh_writer.h"

#define CLI_EXIT_OK 0
#define CLI_EXIT_FAIL 1
#define CLI_EXIT_USAGE 2

/* ---- cli_util.c ---- */

/* The program name messages start with ("isomend", "isomend-mpi"). */
extern const char *cli_program;

/* From now on cli_error() keeps its first message in buf[0..size) instead of
 * printing (isomend-mpi prints one rank's message); NULL prints again. */
void cli_error_capture(char *buf, size_t size);

/* Prints "isomend: <message>\n" to stderr (after clearing a progress bar). */
void cli_error(const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 1, 2)))
#endif
    ;

/* Strict parsers: the whole text must be the value. Return 1 on success. */
int cli_parse_double(const char *s, double *out);      /* finite */
int cli_parse_int64(const char *s, int64_t *out);
/* "a,b,c" with exactly n finite numbers. */
int cli_parse_doubles(const char *s, double *out, int n);

/* A memory size: bytes ("1048576"), or a number with K, M, G or T (binary
 * units, 1K = 1024; "512M", "4G", "1.5G"; a trailing B or iB is allowed). */
int cli_parse_size(const char *s, uint64_t *out);

/* "812.0 MiB" or "3.35 GiB" into buf (32 bytes are enough); returns buf. */
const char *cli_bytes_text(uint64_t bytes, char *buf, size_t size);

/* The "KEY: N kB" value of a /proc file in KiB ("MemAvailable:" of
 * /proc/meminfo, "VmHWM:" of /proc/self/status); 0 if unknown. */
uint64_t cli_proc_kib(const char *path, const char *key);

/* MemAvailable from /proc/meminfo in bytes, 0 if unknown. */
uint64_t cli_memory_available(void);

double cli_now_ms(void);

/* Progress bar on stderr; inactive unless enabled (stderr a TTY, not --quiet). */
typedef struct cli_progress {
    int enabled;
    int shown;      /* a bar is on screen */
    int last_permille;
    const char *label;
} cli_progress;

void cli_progress_init(cli_progress *p, int enabled);
void cli_progress_update(cli_progress *p, const char *label, double fraction);
void cli_progress_clear(cli_progress *p);
/* isomend_progress_fn / isomend_fileio_progress_fn adapters (user = cli_progress*) */
int cli_progress_extract_cb(void *user, double fraction);
int cli_progress_read_cb(void *user, double fraction);

/* The bar that cli_error() clears first (the one in use, or NULL). */
extern cli_progress *cli_active_progress;

/*
 * Ctrl-C / SIGTERM: the handler only sets cli_interrupted; the progress
 * callbacks return it, so reading and extraction stop cleanly (exit 130,
 * nothing written).  A signal during writing takes effect after the output
 * is complete and renamed: a partial file never appears.
 */
#define CLI_EXIT_INTERRUPTED 130
extern volatile int cli_interrupted;
void cli_install_signal_handlers(void);

/* The exit code of an extraction's status, 0 for ISOMEND_OK; else the
 * message printed: "LABEL: interrupted" (130) or "LABEL: WHAT failed: ..." (1). */
int cli_extract_status(isomend_status st, const char *label, const char *what);

/* Writes a JSON string literal (with quotes) for `s`. */
void cli_json_string(FILE *fp, const char *s);

/* ---- the source: source.c and the files it names ---- */

typedef struct cli_source_opts {
    int have_raw;
    int64_t raw_dims[3];
    isomend_type raw_type;
    int raw_big_endian;
    int have_spacing;
    double spacing[3];
    int have_origin;
    double origin[3];
    /* slice-stack options (importer only); have_* = given on the command line */
    int have_first, have_count, have_step, have_channel;
    int64_t first, count, step;
    int channel; /* >= 0, or -2 for luma */
    int threads;
    /* DICOM (importer only) */
    const char *series;     /* --series UID|N, NULL = the only one */
    int grid_axes;          /* --grid-axes: the series' own frame, no rotation */
    int ras;                /* --ras: a NIfTI volume in its RAS axes (not LPS) */
    int list_series;        /* `info`: several series and no choice lists them */
    /* --slice-positions as given ("z0,z1,..." or "@FILE"), NULL = none; parsed
     * by cli_source_open() (the count is only known once SOURCE is open) */
    const char *slice_positions;
    cli_progress *progress;
} cli_source_opts;

/*
 * Where the slices lie (isomend_io_geometry's facts, for every source): a
 * DICOM series' from the importer, a stack's with --slice-positions from the
 * importer too, raw/NRRD/built-in volumes' from --slice-positions or the z
 * spacing.  Gaps are along z, in the volume's units.  `warning` is "" or one
 * line without the source's name: gaps that differ from the median by more
 * than 1 %, or a gap over 1.5x the median (cli_geometry_of_positions()).
 */
typedef struct cli_geometry {
    int uniform;             /* evenly spaced on one line: no slice origins     */
    const char *from;        /* "spacing", "--slice-positions", "dicom"          */
    double gap_median;       /* the upper middle gap; 0 for a single slice      */
    double gap_min, gap_max; /* the smallest and the largest gap                */
    double tilt_degrees;     /* the line through the slices' origins against z  */
    double max_offset;       /* farthest slice origin from the even grid's      */
    int64_t long_gaps;       /* gaps over 1.5x the median                       */
    int64_t uneven_gaps;     /* gaps that differ from the median by over 1 %    */
    char warning[512];
} cli_geometry;

/* source_geometry.c: the geometry of slices at z[0..n) (strictly increasing,
 * x and y shared). */
void cli_geometry_of_positions(const double *z, int64_t n, cli_geometry *g);

/*
 * --slice-positions VALUE -> a malloc'ed array of *count finite, strictly
 * increasing z values: "z0,z1,..." or "@FILE" (one z a line, blank lines and
 * '#' comments allowed).  Returns an exit code; the message names the option
 * or the file (2 for a bad value, 1 for a file that cannot be read).
 */
int cli_parse_slice_positions(const char *value, double **out, int64_t *count);

/* "isomend: warning: LABEL: TEXT" on stderr when g->warning is not empty. */
void cli_print_geometry_warning(const char *label, const cli_geometry *g);
/* `, "geometry": {...}, "warnings": [...]` (the JSON of info and extract; report.c). */
void cli_json_geometry(FILE *fp, const cli_geometry *g);

typedef struct cli_summary {
    double min, max;
    uint64_t samples, nan_samples;
    uint64_t histogram[16];
    double suggested_iso;
    int has_suggestion; /* 0 when every finite sample is equal (or none is finite) */
} cli_summary;

/*
 * An opened SOURCE: what it is, and its samples in one of two modes.
 *
 *   CLI_SOURCE_SLICES  opened (cli_source_open), no sample read: `desc`
 *                      describes the volume with data NULL, and the slices
 *                      come on demand (cli_slices_next), so memory stays
 *                      O(one slice).  What `extract` streams, what `info`
 *                      analyses when the volume exceeds the memory limit.
 *   CLI_SOURCE_LOADED  the samples in memory (cli_source_load): desc.data.
 *
 * Everything else (kind, where the spacing came from, DICOM, the world map,
 * the slices' geometry) is the same in both modes, and the slices can be read
 * in either.  Slices come in z order, each contiguous, x fastest, machine
 * byte order, oriented as the loaded volume is presented (reversed NRRD axes
 * already turned).  What delivers them (`reader`): raw and NRRD through
 * isomend_fileio_slices_* (source_volume.c), built-ins from their 64 samples
 * (source_volume.c), image stacks, DICOM and NIfTI through the importer's
 * isomend_io_read_slice() (source_importer.c).  Not shared between threads.
 *
 * Use: cli_source_open(); then either cli_stream_extract(s, ...) on the
 * slices, or cli_source_load(s) and isomend_extract(&s->desc, ...);
 * cli_source_summary() and cli_source_level() work in both modes;
 * cli_source_close() in every case.
 */
typedef enum cli_source_mode { CLI_SOURCE_SLICES, CLI_SOURCE_LOADED } cli_source_mode;
typedef enum cli_source_reader {
    CLI_READER_BUILTIN,  /* builtin:f1, builtin:f2                        */
    CLI_READER_FILE,     /* raw and NRRD through io/common                */
    CLI_READER_IMPORTER  /* libisomend_io (dlopen'ed): stacks, DICOM, NIfTI */
} cli_source_reader;

typedef struct cli_source {
    cli_source_mode mode;
    /* dims, type, spacing, origin and slice origins as the extraction uses
     * them; data NULL while read slice by slice, the samples once loaded */
    isomend_volume desc;
    char label[1024];        /* SOURCE as given (first path)                   */
    char kind[16];           /* raw, nrrd, builtin, folder, glob, pattern, ... */
    char format[32];
    const char *spacing_from[3];
    int oblique;             /* NRRD space directions not axis aligned        */
    int dicom;               /* a DICOM series (the importer's kind "dicom")   */
    int series_listed;       /* several series, none chosen: only the list     */
    int grid_axes;           /* --grid-axes was given                          */
    int has_world;           /* the mesh maps to the world by `world`          */
    double world[12];        /* 3x4 row-major (isomend_io_world_transform)     */
    cli_geometry geometry;   /* where the slices lie                           */
    uint64_t slice_bytes;    /* one slice: nx * ny * sample size               */
    double read_ms;          /* time spent reading samples (slices, the load)  */
    cli_progress *progress;
    /* what delivers the samples */
    cli_source_reader reader;
    int64_t next;            /* the slice cli_slices_next() delivers           */
    float builtin[64];       /* CLI_READER_BUILTIN                             */
    isomend_fileio_info info;             /* CLI_READER_FILE                   */
    isomend_fileio_slices *file_slices;   /* its slice reader, opened at the first slice */
    void *io;                /* isomend_io_source* (CLI_READER_IMPORTER); a
                              * volume it loaded belongs to it                 */
    void *owned;             /* samples we loaded (raw, NRRD, built-in)        */
    double *origins_owned;   /* desc.slice_origins when we built them (raw,   */
                             /* NRRD, built-in with --slice-positions)         */
} cli_source;

/* Opens SOURCE (paths[0..n)) in mode CLI_SOURCE_SLICES, reading no sample
 * (an image stack's headers are all checked).  Exit code; on failure the
 * message is printed and nothing needs closing. */
int cli_source_open(const char *const *paths, int n, const cli_source_opts *o, cli_source *s);
/* Reads the samples into memory (mode CLI_SOURCE_LOADED; nothing to do when
 * loaded).  Exit code, the message printed; on failure s stays opened. */
int cli_source_load(cli_source *s);
/* Frees the samples of a loaded raw, NRRD or built-in source once they are
 * used (desc.data becomes NULL, the mode CLI_SOURCE_SLICES; the description
 * stays).  An importer's volume stays until cli_source_close(). */
void cli_source_drop_samples(cli_source *s);
void cli_source_close(cli_source *s); /* accepts NULL and a closed source */

/* Slice s->next into `buffer` (s->slice_bytes), in either mode; exit code,
 * message printed. */
/* Whether the source can be read slice by slice (not: gzip NRRD with a reversed z axis). */
int cli_source_reads_by_slice(const cli_source *s);
int cli_slices_next(cli_source *s, void *buffer);
/* The next call delivers slice 0 again / slice k. */
void cli_slices_rewind(cli_source *s);
int cli_slices_seek(cli_source *s, int64_t k);

/* source_summary.c: value range, 16-bin histogram, Otsu suggestion (the
 * importer's rule): from the samples when loaded, else reading the slices
 * twice (rewound at the end); an importer's source is analysed by the
 * importer. */
int cli_source_summary(cli_source *s, cli_summary *sum);
/* The level named "otsu", "bone" or "skin" (an importer's source: its rule;
 * bone/skin only for CT in HU).  Returns an exit code, the message printed. */
int cli_source_level(cli_source *s, const char *name, double *value);
/* "bone" for a CT DICOM series in HU, else "otsu": what a missing --iso uses. */
const char *cli_source_suggested_level(const cli_source *s);
/* 1 and *level when the source suggests a fixed level rather than Otsu's
 * (a CT series in HU: the bone level, as cli_source_suggested_level says). */
int cli_source_fixed_level(cli_source *s, double *level);

/*
 * The summary's two passes over planes, for callers that see the volume in
 * parts (isomend-mpi: each rank its slab, the sums reduced between passes):
 * start; pass 0 over every plane; range_done() (0: no histogram needed, the
 * summary is complete); pass 1 over every plane; finish().
 */
#define CLI_OTSU_BINS 256
typedef struct cli_summary_acc {
    cli_summary *sum;
    isomend_type type;
    double lo, hi;
    uint64_t finite;
    uint64_t fine[CLI_OTSU_BINS];
} cli_summary_acc;
void cli_summary_start(cli_summary_acc *a, cli_summary *sum, isomend_type type);
void cli_summary_plane(cli_summary_acc *a, int pass, const char *base, int64_t s0, int64_t s1,
                       int64_t nx, int64_t ny);
int cli_summary_range_done(cli_summary_acc *a);
void cli_summary_finish(cli_summary_acc *a);

/* One sample of type t (machine byte order) as a double. */
double cli_sample_value(const void *sample, isomend_type t);

/* source_report.c: what a DICOM series or a NIfTI volume says about itself
 * (text lines for `info`, JSON objects or null); no-ops / null for other
 * sources and without the importer. */
void cli_print_dicom(FILE *fp, cli_source *s);
void cli_json_dicom(FILE *fp, cli_source *s);
void cli_print_nifti(FILE *fp, const cli_source *s);
void cli_json_nifti(FILE *fp, const cli_source *s);
void cli_print_series(FILE *fp, const cli_source *s);
void cli_json_series(FILE *fp, const cli_source *s);

/* source_volume.c: fills the built-in F1/F2 of the thesis (4x4x4 f32, 0..3).
 * Returns 1 if `name` is one. */
int cli_builtin_volume(const char *name, float out[64]);

/* ---- args.c ---- */

/* Every option; a command allows a set of them. */
enum {
    OPT_OUTPUT = 1u << 0, OPT_ISO = 1u << 1, OPT_METHOD = 1u << 2, OPT_RAW = 1u << 3,
    OPT_SPACING = 1u << 4, OPT_ORIGIN = 1u << 5, OPT_PAD = 1u << 6, OPT_NO_NORMALS = 1u << 7,
    OPT_FLIP = 1u << 8, OPT_STATS = 1u << 9, OPT_JSON = 1u << 10, OPT_QUIET = 1u << 11,
    OPT_THREADS = 1u << 12, OPT_BOX = 1u << 13, OPT_FIRST = 1u << 14, OPT_COUNT = 1u << 15,
    OPT_STEP = 1u << 16, OPT_CHANNEL = 1u << 17, OPT_GZIP = 1u << 18, OPT_HELP = 1u << 19,
    OPT_PAGES = 1u << 20, OPT_MAX_MEMORY = 1u << 21, OPT_SERIES = 1u << 22,
    OPT_GRID_AXES = 1u << 23, OPT_SLICE_POSITIONS = 1u << 24, OPT_DECIMATE = 1u << 25,
    OPT_TARGET_TRIANGLES = 1u << 26, OPT_MAX_ERROR = 1u << 27, OPT_SMOOTH = 1u << 28,
    OPT_MIN_COMPONENT = 1u << 29, OPT_LARGEST = 1u << 30
};
/* past the enum's int range (cli_args.seen is 64-bit) */
#define OPT_RAS (1u << 31)                      /* --ras: NIfTI in the file's RAS axes        */
#define OPT_IN_MEMORY ((uint64_t)1 << 32)       /* --in-memory: the whole mesh, then written */
#define OPT_STREAM ((uint64_t)1 << 33)          /* --stream: streamed even when it would fit */
#define OPT_CHUNK_LAYERS ((uint64_t)1 << 34)    /* --chunk-layers: the streamed decimation's */
#define OPT_LABELS       ((uint64_t)1 << 35)    /* --labels all|L1,L2: a label map's surfaces */
#define OPT_LABEL_TABLE  ((uint64_t)1 << 36)    /* --label-table FILE: names and colours     */
#define OPT_FORMAT       ((uint64_t)1 << 37)    /* --format ply|obj|stl: -o FOLDER/'s files  */
#define OPT_POST \
    (OPT_DECIMATE | OPT_TARGET_TRIANGLES | OPT_MAX_ERROR | OPT_SMOOTH | OPT_MIN_COMPONENT | OPT_LARGEST)

/* The steps after the extraction (postprocess.c); zeros: not asked. */
typedef struct cli_post {
    double ratio;           /* --decimate      */
    uint64_t target;        /* --target-triangles */
    double max_error;       /* --max-error     */
    int smooth;             /* --smooth        */
    uint64_t min_component; /* --min-component */
    uint64_t largest;       /* --largest       */
    int64_t chunk_layers;   /* --chunk-layers (streamed decimation), 0: the default */
} cli_post;

#define CLI_MAX_SOURCES 4096

typedef struct cli_args {
    uint64_t seen;
    const char *output, *json, *method_name;
    const char *positional[CLI_MAX_SOURCES];
    int npositional;
    double iso;
    const char *iso_name; /* --iso otsu|bone|skin */
    isomend_method method;
    enum { CLI_PAGES_HUGE, CLI_PAGES_SMALL } pages; /* --pages */
    double box[6];
    uint64_t max_memory;                    /* --max-memory, 0 = not given */
    const char *labels;                     /* --labels as given               */
    const char *label_table;                /* --label-table FILE              */
    const char *format;                     /* --format: "x.ply" etc., for     */
                                            /* isomend_mesh_format_of()        */
    cli_post post;
    cli_source_opts src;
} cli_args;

/* Parses argv[first..argc) for `command` allowing the options in `allowed`.
 * Returns an exit code (the message is printed). */
int cli_parse_args(int argc, char **argv, int first, const char *command, uint64_t allowed,
                   cli_args *a);

/* The extraction options `extract` takes from its arguments (the iso as
 * a->iso); progress through `bar`, which is also how Ctrl-C cancels. */
void cli_extract_options(const cli_args *a, cli_progress *bar, isomend_options *opts);

/* --chunk-layers is given with no step that has chunks (the smoothing, the
 * decimation): 1 with the message printed, else 0. */
int cli_chunk_layers_unused(const cli_args *a);

/* ---- stream.c ---- */

/* Which memory path `extract` takes (the rule is at the top of stream.c). */
typedef struct cli_memory_plan {
    uint64_t limit;       /* --max-memory, else MemAvailable; 0 = unknown                */
    int limit_given;      /* --max-memory was given                                      */
    uint64_t volume;      /* the samples                                                 */
    uint64_t in_memory;   /* volume + mesh + working set of the whole-mesh path          */
    uint64_t streaming;   /* the most streaming holds (the rule at the top of stream.c)  */
    uint64_t check_queue; /* bytes of calls the streaming check may queue                */
    uint64_t check_need;  /* what the streaming check holds, queue included              */
    int check;            /* the streamed mesh is checked (0: it does not fit the limit)  */
    int threads;          /* the stream's threads: opts', or 1 when several do not fit   */
    int over_limit;       /* in_memory > limit                                           */
    int stream;           /* the mesh streamed: always, but for a whole-mesh run that fits */
    int64_t decimate_layers; /* the chunk height of a streamed smoothing and decimation  */
                             /* (0: neither)                                             */
    uint64_t decimate_need;  /* what the decimation holds (isomend_decimate_stream_memory) */
    uint64_t smooth_need;    /* the smoothing's (isomend_smooth_stream_memory)           */
    uint64_t clean_need;     /* the clean-up's (isomend_clean_stream_memory)             */
    uint64_t largest_need;   /* --largest's: isomend_largest_stream_memory and the spool's */
                             /* buffers (CLI_SPOOL_BUFFERS); --target-triangles': the    */
                             /* spool's buffers and pass 1's clean-up (clean_need)       */
} cli_memory_plan;

/* --largest's spool (stream.c): its stdio buffer, and the replay's record
 * buffer beyond one layer's calls, MiB. */
#define CLI_SPOOL_BUFFERS 2

/* The writer's stdio buffers, MiB (mesh_writer.c: the file and two scratch files). */
#define CLI_WRITER_BUFFERS 3

/* The plan of an extraction; `whole_mesh`: the run needs the mesh in memory
 * (--in-memory, post-processing, --pages), streamed only when it does not fit;
 * `post` (may be NULL): the steps a streamed run does as it goes
 * (--min-component, --smooth, --decimate), smoothing and decimation in
 * chunks of post->chunk_layers layers (0: the core's default, fewer where
 * that does not fit). */
struct cli_post;
void cli_memory_plan_make(const isomend_volume *desc, const isomend_options *opts,
                          isomend_mesh_format format, uint64_t max_memory, int whole_mesh,
                          const struct cli_post *post, cli_memory_plan *p);

/* The process's peak resident memory (VmHWM), bytes; 0 if unknown. */
uint64_t cli_peak_memory(void);

/* The process's resident memory now (VmRSS), bytes; 0 if unknown. */
uint64_t cli_resident_memory(void);

/* Where a streaming extraction puts the mesh: the core's sink (isomend.h);
 * the CLI's sinks print their message before they return non-zero. */
typedef isomend_mesh_sink cli_sink;

/* A sink that writes to `w` (mesh_writer.h). */
void cli_sink_for_writer(cli_sink *sink, isomend_mesh_writer *w);
/* A sink that maps the mesh by an affine 3x4 map (a DICOM series' patient
 * transform, as isomend_mesh_copy_transformed() does) before `next`.
 * cli_world_init returns 0 for a non-finite or singular map. */
typedef struct cli_world {
    double m[12], c[3][3], s;
    int mirror;
    cli_sink next;
    float *buf;
    size_t cap;
} cli_world;
int cli_world_init(cli_world *w, const double affine[12], const cli_sink *next);
void cli_sink_for_world(cli_sink *sink, cli_world *w);
/* The map applied in place to `count` positions (and normals, may be NULL). */
void cli_world_map(const cli_world *w, float *pos, float *nrm, size_t count);
void cli_world_free(cli_world *w); /* accepts NULL */


/*
 * Extracts the surface of the slices of `s` (from slice 0) and hands the
 * mesh to `sink`, in the order isomend_extract() numbers it.  Exit code; the
 * message is printed.  `stats` as isomend_extract()'s.
 */
/*
 * The continuity check of a streamed mesh (check_sink.c): a tee in front of
 * `next` that feeds the core's streaming checker on a thread of its own,
 * queueing at most `queue` bytes of calls.  cli_checker_finish waits for it
 * and gives isomend_mesh_check()'s report of the whole mesh.
 */
typedef struct cli_checker cli_checker;
int cli_checker_begin(const isomend_volume *desc, const isomend_options *opts, uint64_t queue,
                      const cli_sink *next, cli_checker **out, cli_sink *tee);
int cli_checker_finish(cli_checker *k, isomend_check_report *report);
uint64_t cli_checker_peak_bytes(const cli_checker *k);
void cli_checker_destroy(cli_checker *k); /* accepts NULL */

/* A sink that times the calls it passes on to `next` (ms: their sum): around
 * a streamed decimation and around what follows it, the difference is the
 * decimation's own time. */
typedef struct cli_timed_sink {
    cli_sink next;
    double ms;
} cli_timed_sink;
void cli_sink_timed(cli_sink *sink, cli_timed_sink *t, const cli_sink *next);

/*
 * Where a streamed mesh goes (isomend extract, isomend-mpi --decimate): with
 * --largest, the stream recorded to a scratch spool beside the output while
 * the components are counted, then replayed through the filter of the kept
 * components (isomend_largest_stream_*, --min-component with it) at
 * cli_outputs_finish(); else the streamed clean-up; then the streamed
 * smoothing, the streamed decimation (ratio > 0, chunks of `layers`), then the continuity
 * check (check_queue > 0: the queue's bytes; it sees the grid's frame), then
 * the patient map (world: a 3x4 affine, or NULL), then the writer of path.
 * `sink` is the head of that chain.  The struct points into itself: it must
 * not move between begin and commit/abort.
 */
typedef struct cli_outputs {
    isomend_mesh_writer *w;
    cli_world world;
    int has_world;
    cli_checker *checker;
    uint64_t check_peak; /* the check's tables and queue at their largest (finish) */
    uint64_t decimate_peak; /* the streamed decimation's bytes at their largest (finish) */
    uint64_t smooth_peak;   /* the streamed smoothing's (finish)                         */
    isomend_clean_stream *clean;
    isomend_largest_stream *largest;
    FILE *spool;            /* --largest, --target-triangles: pass 1's calls, */
                            /* replayed for pass 2                            */
    char *spool_buf;        /* its stdio buffer                               */
    const char *spool_flag; /* the flag that needs it, for messages           */
    const cli_sink *replay; /* pass 2's sink: --largest's filter, or the chain */
    /* --target-triangles: pass 1's own clean-up (--min-component) and count */
    isomend_clean_stream *count_clean;
    uint64_t counted;
    const char *path;       /* the output, for messages                       */
    isomend_smooth_stream *smooth;
    isomend_decimate_stream *decimate;
    int64_t layers;
    /* around each step (in) and around what follows it (out): its own time */
    cli_timed_sink t_in, t_out, c_in, c_out, s_in, s_out;
    cli_sink writer, mapped, tee, dsink, timed_in, timed_out;
    cli_sink csink, ctimed_in, ctimed_out, ssink, stimed_in, stimed_out;
    cli_timed_sink l_in, l_out;
    cli_sink lsink, lrecord, ltimed_out, counter;
    const cli_sink *sink;
} cli_outputs;

/* 0, or 1 with the message printed (label names the source) and nothing left
 * open.  post (may be NULL): the streamed steps, [clean-up] -> [smoothing]
 * -> [decimation] before the check, smoothing and decimation in chunks of
 * `layers` layers. */
int cli_outputs_begin(cli_outputs *o, const char *path, isomend_mesh_format fmt, int normals,
                      const double *world, const char *label, const isomend_volume *desc,
                      const isomend_options *opts, uint64_t check_queue,
                      const struct cli_post *post, int64_t layers);

/* After the stream (rc its exit code): ends the steps (into post: their
 * reports, streamed, chunk_layers, their own times) and the check
 * (*checked: it ran to its report); frees all but the writer.  Returns rc,
 * or the failure of any. */
struct cli_post_report; /* postprocess.c */
int cli_outputs_finish(cli_outputs *o, int rc, const char *label, struct cli_post_report *post,
                       isomend_check_report *check, int *checked);

/* The file made visible (an exit code; the message printed), or dropped. */
int cli_outputs_commit(cli_outputs *o);
void cli_outputs_abort(cli_outputs *o);

int cli_stream_extract(cli_source *s, const isomend_options *opts, const cli_sink *sink,
                       isomend_stats *stats);

/* ---- extract_labels.c ---- */

/* `extract SOURCE --labels ...` (a label map's surfaces): an exit code, the
 * message printed. */
int cli_extract_labels(cli_args *a);
/* `info SOURCE --labels all`: the labels present, their voxels, names and colours. */
int cli_info_labels(cli_args *a);

/* ---- report.c ---- */

typedef struct cli_timings {
    double read_ms, extract_ms, write_ms;
} cli_timings;

/* ---- postprocess.c ---- */

typedef struct cli_post_report {
    int cleaned, smoothed, decimated;
    int streamed;         /* the steps ran on the stream, smoothing and decimation in chunks of: */
    int64_t chunk_layers;
    isomend_clean_report clean;
    isomend_smooth_report smooth;
    isomend_decimate_report decimate;
    double clean_ms, smooth_ms, decimate_ms;
} cli_post_report;

/* Runs the steps `p` asks for on *mesh (replaced by the result); an exit
 * code, the message printed naming `label`. */
int cli_postprocess(isomend_mesh **mesh, const cli_post *p, cli_post_report *r, const char *label);

void cli_print_post(FILE *fp, const cli_post_report *r);
void cli_json_post(FILE *fp, const cli_post_report *r);

void cli_print_table2(FILE *fp, const isomend_stats *st, isomend_method method);
void cli_print_check(FILE *fp, const char *what, const isomend_check_report *r);
void cli_json_check(FILE *fp, const isomend_check_report *r);
/* A JSON destination: stdout ("-") or an atomic file opened early. */
typedef struct cli_json_out {
    int to_stdout;
    int open;
    isomend_atomic_file af;
} cli_json_out;

/* Opens the --json destination early (NULL path: none); exit code. */
int cli_json_prepare(cli_json_out *j, const char *path);
/* The stream to print the object to, NULL when no JSON was asked for. */
FILE *cli_json_stream(cli_json_out *j);
/* The start of `extract` and `info` (source.c): the --json output prepared,
 * the progress bar set up (stderr a terminal, not quiet), SOURCE opened (no
 * sample read) and the slices' geometry warning printed.  Exit code; on
 * failure nothing is left open. */
int cli_open_source_for(cli_args *a, int quiet, cli_json_out *jo, cli_progress *bar, cli_source *s);
/* Completes it (renames the file); exit code. */
int cli_json_finish(cli_json_out *j);
void cli_json_abort(cli_json_out *j);
void cli_json_doubles(FILE *fp, const double *v, int n);
void cli_json_dims(FILE *fp, const int64_t *d);

/* The parts of `extract`'s JSON object that isomend and isomend-mpi share:
 * from "source" to "normals" (after the opening brace and the program's own
 * fields), and the statistics from "vertices" to "nan_samples". */
void cli_json_run(FILE *jf, const char *source, const char *kind, const char *output,
                  const isomend_volume *v, const isomend_options *opts, int iso_suggested);
void cli_json_stats(FILE *jf, const isomend_stats *st);

/* 1 when the report shows holes, edges used 3+ times or misoriented edges. */
int cli_check_has_defects(const isomend_check_report *r);

#endif /* ISOMEND_CLI_H */
