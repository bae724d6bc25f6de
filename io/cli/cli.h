/*
 * cli.h - internals of the `isomend` command line (io/cli)
 *
 *   main.c      argument parsing and the commands (extract, check, info, sample)
 *   cli_util.c  messages, number parsing, timing, the progress bar
 *   source.c    SOURCE -> isomend_volume: raw, NRRD, built-in F1/F2 and, when
 *               built with the importer (ISOMEND_HAVE_IO), slice stacks;
 *               value range, histogram and suggested iso level
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

#include "isomend.h"

#define CLI_EXIT_OK 0
#define CLI_EXIT_FAIL 1
#define CLI_EXIT_USAGE 2

/* ---- cli_util.c ---- */

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
    int list_series;        /* `info`: several series and no choice lists them */
    cli_progress *progress;
} cli_source_opts;

typedef struct cli_summary {
    double min, max;
    uint64_t samples, nan_samples;
    uint64_t histogram[16];
    double suggested_iso;
    int has_suggestion; /* 0 when every finite sample is equal (or none is finite) */
} cli_summary;

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
    double read_ms;
    char label[1024];        /* SOURCE as given (first path)                   */
} cli_source;

/* Opens and loads SOURCE (paths[0..n)).  Returns an exit code; on failure
 * the message is printed and nothing needs closing. */
int cli_source_open(const char *const *paths, int n, const cli_source_opts *o, cli_source *src);
void cli_source_close(cli_source *src);
/* Value range, 16-bin histogram, Otsu suggestion (the importer's rule). */
int cli_source_summary(cli_source *src, cli_summary *sum);

/* DICOM reporting (source.c; no-ops without the importer). */
void cli_print_dicom(FILE *fp, cli_source *src, const cli_summary *sum);
void cli_json_dicom(FILE *fp, cli_source *src, const cli_summary *sum);
void cli_print_series(FILE *fp, const cli_source *src);
void cli_json_series(FILE *fp, const cli_source *src);
/* The level named "otsu", "bone" or "skin" (an importer's source: its rule;
 * bone/skin only for CT in HU).  Returns an exit code, the message printed. */
int cli_source_level(cli_source *src, const char *name, double *value);
/* "bone" for a CT DICOM series in HU, else "otsu": what a missing --iso uses. */
const char *cli_source_suggested_level(const cli_source *src);

/* Fills the built-in F1/F2 of the thesis (4x4x4 f32, 0..3).  Returns 1 if `name` is one. */
int cli_builtin_volume(const char *name, float out[64]);

/* ---- report.c ---- */

typedef struct cli_timings {
    double read_ms, extract_ms, write_ms;
} cli_timings;

void cli_print_table2(FILE *fp, const isomend_stats *st, isomend_method method);
void cli_print_check(FILE *fp, const char *what, const isomend_check_report *r);
void cli_json_check(FILE *fp, const isomend_check_report *r);
/* 1 when the report shows holes, edges used 3+ times or misoriented edges. */
int cli_check_has_defects(const isomend_check_report *r);

#endif /* ISOMEND_CLI_H */
