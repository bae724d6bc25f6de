/*
 * cli.h - internals of the `isomend` command line (io/cli)
 *
 *   main.c      the commands (extract, check, info, sample)
 *   args.c      the options of every command (shared with isomend-mpi)
 *   cli_util.c  messages, number parsing, timing, the progress bar
 *   source.c    SOURCE -> isomend_volume: raw, NRRD, built-in F1/F2 and, when
 *               built with the importer (ISOMEND_HAVE_IO), slice stacks;
 *               value range, histogram and suggested iso level
 *   stream.c    the --max-memory rule, the mesh sink, the streaming extraction
 *   report.c    the Table-2 statistics, the check summary and the JSON object
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

/* Writes a JSON string literal (with quotes) for `s`. */
void cli_json_string(FILE *fp, const char *s);

/* ---- source.c ---- */

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
     * by cli_slices_open() (the count is only known once SOURCE is open) */
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

/* The geometry of slices at z[0..n) (strictly increasing, x and y shared). */
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
/* `, "geometry": {...}, "warnings": [...]` (the JSON of info and extract). */
void cli_json_geometry(FILE *fp, const cli_geometry *g);

typedef struct cli_summary {
    double min, max;
    uint64_t samples, nan_samples;
    uint64_t histogram[16];
    double suggested_iso;
    int has_suggestion; /* 0 when every finite sample is equal (or none is finite) */
} cli_summary;

/*
 * An opened SOURCE whose samples have not been read: what it is, and its
 * slices on demand.  `desc` describes the volume (dims, type, spacing and
 * origin as the extraction uses them; data NULL).  Slices come in z order,
 * each contiguous, x fastest, machine byte order, oriented as the whole
 * volume would be presented (reversed NRRD axes already turned), so memory
 * stays O(one slice): raw and NRRD through isomend_fileio_slices_*, image
 * stacks through the importer's isomend_io_read_slice(), built-ins from
 * their 64 samples.
 */
typedef struct cli_slices {
    isomend_volume desc;
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
    double *origins_owned;   /* desc.slice_origins when we built them (raw,    */
                             /* NRRD, built-in with --slice-positions)         */
    char label[1024];        /* SOURCE as given (first path)                   */
    uint64_t slice_bytes;
    int64_t next;            /* the slice the next call delivers               */
    double read_ms;          /* time spent in cli_slices_next()                */
    /* what delivers them: one of */
    int is_builtin;
    float builtin[64];
    int is_fileio;
    isomend_fileio_info info;
    isomend_fileio_slices *reader; /* opened at the first slice */
    void *io;                /* isomend_io_source* (image stacks)             */
    cli_progress *progress;
} cli_slices;

/* Opens SOURCE (paths[0..n)) without reading samples (an image stack's
 * headers are all checked).  Exit code; on failure the message is printed
 * and nothing needs closing. */
int cli_slices_open(const char *const *paths, int n, const cli_source_opts *o, cli_slices *s);
/* Slice s->next into `buffer` (s->slice_bytes); exit code, message printed. */
int cli_slices_next(cli_slices *s, void *buffer);
/* The next call delivers slice 0 again / slice k. */
void cli_slices_rewind(cli_slices *s);
int cli_slices_seek(cli_slices *s, int64_t k);
void cli_slices_close(cli_slices *s);
/* cli_source_summary's numbers, reading the slices (twice) instead of a
 * loaded volume; rewinds at the end. */
int cli_slices_summary(cli_slices *s, cli_summary *sum);
/* 1 and *level when the source suggests a fixed level rather than Otsu's
 * (a CT series in HU: the bone level, as cli_source_suggested_level says). */
int cli_slices_fixed_level(cli_slices *s, double *level);

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

typedef struct cli_source {
    isomend_volume vol;
    void *owned;             /* samples we allocated (raw, NRRD, built-in)   */
    void *io;                /* isomend_io_source* when loaded by the importer */
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
    double *origins_owned;   /* vol.slice_origins when we built them           */
    double read_ms;
    char label[1024];        /* SOURCE as given (first path)                   */
} cli_source;

/* Loads an opened source whole into `src` (s is closed in every case). */
int cli_source_load(cli_slices *s, cli_source *src);
void cli_source_close(cli_source *src);

/* Frees the samples of a raw, NRRD or built-in source once they are used
 * (vol.data becomes NULL; the description stays).  An importer's volume
 * stays until cli_source_close(). */
void cli_source_drop_samples(cli_source *src);
/* Value range, 16-bin histogram, Otsu suggestion (the importer's rule). */
int cli_source_summary(cli_source *src, cli_summary *sum);

/* One sample of type t (machine byte order) as a double. */
double cli_sample_value(const void *sample, isomend_type t);

/* MemAvailable from /proc/meminfo in bytes, 0 if unknown. */
uint64_t cli_memory_available(void);

/* An opened, not loaded source seen as a cli_source for the functions below
 * (the importer's handle and the DICOM facts are shared, vol has no data);
 * never closed. */
void cli_source_view(const cli_slices *s, cli_source *view);

/* DICOM reporting (source.c; no-ops without the importer). */
void cli_print_dicom(FILE *fp, cli_source *src, const cli_summary *sum);
void cli_json_dicom(FILE *fp, cli_source *src, const cli_summary *sum);
/* NIfTI reporting: the header's facts and the transform used (text lines;
 * the JSON object or null); no-ops / null for other sources. */
void cli_print_nifti(FILE *fp, const cli_source *src);
void cli_json_nifti(FILE *fp, const cli_source *src);
void cli_print_series(FILE *fp, const cli_source *src);
void cli_json_series(FILE *fp, const cli_source *src);
/* The level named "otsu", "bone" or "skin" (an importer's source: its rule;
 * bone/skin only for CT in HU).  Returns an exit code, the message printed. */
int cli_source_level(cli_source *src, const char *name, double *value);
/* "bone" for a CT DICOM series in HU, else "otsu": what a missing --iso uses. */
const char *cli_source_suggested_level(const cli_source *src);

/* Fills the built-in F1/F2 of the thesis (4x4x4 f32, 0..3).  Returns 1 if `name` is one. */
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
/* --ras: NIfTI in the file's RAS axes (the enum's int range is full) */
#define OPT_RAS (1u << 31)
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
} cli_post;

#define CLI_MAX_SOURCES 4096

typedef struct cli_args {
    unsigned seen;
    const char *output, *json, *method_name;
    const char *positional[CLI_MAX_SOURCES];
    int npositional;
    double iso;
    const char *iso_name; /* --iso otsu|bone|skin */
    isomend_method method;
    enum { CLI_PAGES_HUGE, CLI_PAGES_SMALL } pages; /* --pages */
    double box[6];
    uint64_t max_memory;                    /* --max-memory, 0 = not given */
    cli_post post;
    cli_source_opts src;
} cli_args;

/* Parses argv[first..argc) for `command` allowing the options in `allowed`.
 * Returns an exit code (the message is printed). */
int cli_parse_args(int argc, char **argv, int first, const char *command, unsigned allowed,
                   cli_args *a);

/* The extraction options `extract` takes from its arguments (the iso as
 * a->iso); progress through `bar`, which is also how Ctrl-C cancels. */
void cli_extract_options(const cli_args *a, cli_progress *bar, isomend_options *opts);

/* ---- stream.c ---- */

/* Which memory path `extract` takes (the rule is at the top of stream.c). */
typedef struct cli_memory_plan {
    uint64_t limit;       /* --max-memory, else MemAvailable; 0 = unknown (never stream) */
    int limit_given;      /* --max-memory was given                                      */
    uint64_t volume;      /* bytes of the samples                                        */
    uint64_t in_memory;   /* volume + mesh + working set of the in-memory path           */
    uint64_t streaming;   /* the most streaming holds (the rule at the top of stream.c)  */
    int stream;           /* in_memory > limit                                           */
} cli_memory_plan;

/* The writer's stdio buffers, MiB (mesh_writer.c: the file and two scratch files). */
#define CLI_WRITER_BUFFERS 3

void cli_memory_plan_make(const isomend_volume *desc, const isomend_options *opts,
                          isomend_mesh_format format, uint64_t max_memory, cli_memory_plan *p);

/* The process's peak resident memory (VmHWM), bytes; 0 if unknown. */
uint64_t cli_peak_memory(void);

/* The process's resident memory now (VmRSS), bytes; 0 if unknown. */
uint64_t cli_resident_memory(void);

/*
 * Where a streaming extraction puts the mesh (the sink of docs/streaming.md,
 * until the core declares its own): vertices with consecutive ids from
 * `first` (keys may be NULL), triangles of 64-bit ids of vertices already
 * delivered, and retire(floor): no later triangle uses an id below floor.
 * A callback returns non-zero to stop, after printing the message.
 */
typedef struct cli_sink {
    void *user;
    int (*vertices)(void *user, uint64_t first, size_t count, const float *positions,
                    const float *normals, const uint64_t *keys);
    int (*triangles)(void *user, size_t count, const uint64_t *ids, const uint8_t *origins);
    int (*retire)(void *user, uint64_t floor);
} cli_sink;

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
int cli_stream_extract(cli_slices *s, const isomend_options *opts, const cli_sink *sink,
                       isomend_stats *stats);

/* ---- report.c ---- */

typedef struct cli_timings {
    double read_ms, extract_ms, write_ms;
} cli_timings;

/* ---- postprocess.c ---- */

typedef struct cli_post_report {
    int cleaned, smoothed, decimated;
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
