/*
 * source_summary.c - what a source's samples say: value range, NaN count,
 * 16-bin histogram and the suggested iso level
 *
 * The suggested level follows the importer's documented rule (Otsu on a
 * 256-bin histogram of the finite samples; integer types moved to
 * floor(t) + 0.5 so that no sample equals the level); for importer sources
 * the importer computes it itself, and a CT series in Hounsfield units
 * suggests its bone level instead (the named levels: otsu, bone, skin).
 *
 * The summary is computed plane by plane in two passes (range, then
 * histograms), so that a loaded volume (any strides), a source read slice by
 * slice and isomend-mpi's slabs go through the same code and give the same
 * numbers.
 */
#define _POSIX_C_SOURCE 200809L

#include "source_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Histogram bin of d over [mn, mx] (the importer's formula, clamped). */
static int bin_of(double d, double mn, double mx, int bins)
{
    if (!(mx > mn)) return 0;
    int b = (int)((d - mn) / (mx - mn) * bins);
    return b < 0 ? 0 : (b >= bins ? bins - 1 : b);
}

static int is_integer_type(isomend_type t)
{
    return t == ISOMEND_U8 || t == ISOMEND_I8 || t == ISOMEND_U16 || t == ISOMEND_I16 ||
           t == ISOMEND_I32;
}

double cli_sample_value(const void *sample, isomend_type t)
{
    const char *p = sample;
    switch (t) {
    case ISOMEND_U8: { uint8_t x; memcpy(&x, p, 1); return x; }
    case ISOMEND_I8: { int8_t x; memcpy(&x, p, 1); return x; }
    case ISOMEND_U16: { uint16_t x; memcpy(&x, p, 2); return x; }
    case ISOMEND_I16: { int16_t x; memcpy(&x, p, 2); return x; }
    case ISOMEND_I32: { int32_t x; memcpy(&x, p, 4); return x; }
    case ISOMEND_F32: { float x; memcpy(&x, p, 4); return x; }
    case ISOMEND_F64: { double x; memcpy(&x, p, 8); return x; }
    }
    return NAN;
}

void cli_summary_plane(cli_summary_acc *a, int pass, const char *base, int64_t s0, int64_t s1,
                       int64_t nx, int64_t ny)
{
    cli_summary *sum = a->sum;
    for (int64_t j = 0; j < ny; j++)
        for (int64_t i = 0; i < nx; i++) {
            double x = cli_sample_value(base + i * s0 + j * s1, a->type);
            if (pass == 0) {
                sum->samples++;
                if (!isfinite(x)) {
                    sum->nan_samples++;
                    continue;
                }
                a->finite++;
                if (x < a->lo) a->lo = x;
                if (x > a->hi) a->hi = x;
            } else if (isfinite(x)) {
                sum->histogram[bin_of(x, a->lo, a->hi, 16)]++;
                a->fine[bin_of(x, a->lo, a->hi, CLI_OTSU_BINS)]++;
            }
        }
}

void cli_summary_start(cli_summary_acc *a, cli_summary *sum, isomend_type type)
{
    memset(sum, 0, sizeof *sum);
    memset(a, 0, sizeof *a);
    a->sum = sum;
    a->type = type;
    a->lo = INFINITY;
    a->hi = -INFINITY;
}

/* After pass 0: 1 if a histogram pass is needed. */
int cli_summary_range_done(cli_summary_acc *a)
{
    if (a->finite == 0) return 0;
    a->sum->min = a->lo;
    a->sum->max = a->hi;
    a->sum->suggested_iso = a->lo;
    return a->hi > a->lo;
}

void cli_summary_finish(cli_summary_acc *a)
{
    /* Otsu, exactly as the importer does it (io/common) */
    a->sum->suggested_iso = isomend_fileio_otsu(a->fine, CLI_OTSU_BINS, a->lo, a->hi,
                                                is_integer_type(a->type));
    a->sum->has_suggestion = 1;
}

/* A loaded volume, plane by plane (any strides). */
static int summary_of_samples(const isomend_volume *v, cli_summary *sum)
{
    int64_t ts = (int64_t)isomend_type_size(v->type), s0 = v->strides[0], s1 = v->strides[1],
            s2 = v->strides[2];
    if (!s0 && !s1 && !s2) {
        s0 = ts;
        s1 = s0 * v->dims[0];
        s2 = s1 * v->dims[1];
    }
    cli_summary_acc a;
    cli_summary_start(&a, sum, v->type);
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1 && !cli_summary_range_done(&a)) return CLI_EXIT_OK;
        for (int64_t k = 0; k < v->dims[2]; k++)
            cli_summary_plane(&a, pass, (const char *)v->data + k * s2, s0, s1, v->dims[0], v->dims[1]);
    }
    cli_summary_finish(&a);
    return CLI_EXIT_OK;
}

/* A source read slice by slice: every slice twice, rewound at the end. */
static int summary_of_slices(cli_source *s, cli_summary *sum)
{
    char *slice = malloc((size_t)s->slice_bytes);
    if (!slice) {
        cli_error("%s: out of memory for a slice of %llu bytes", s->label,
                  (unsigned long long)s->slice_bytes);
        return CLI_EXIT_FAIL;
    }
    const int64_t nx = s->desc.dims[0], ny = s->desc.dims[1], nz = s->desc.dims[2];
    const int64_t ts = (int64_t)isomend_type_size(s->desc.type);
    cli_summary_acc a;
    cli_summary_start(&a, sum, s->desc.type);
    int rc = CLI_EXIT_OK;
    for (int pass = 0; pass < 2 && rc == CLI_EXIT_OK; pass++) {
        if (pass == 1 && !cli_summary_range_done(&a)) break;
        cli_slices_rewind(s);
        for (int64_t k = 0; k < nz && rc == CLI_EXIT_OK; k++) {
            if (cli_interrupted) {
                cli_error("%s: interrupted", s->label);
                rc = CLI_EXIT_INTERRUPTED;
                break;
            }
            rc = cli_slices_next(s, slice);
            if (rc == CLI_EXIT_OK) cli_summary_plane(&a, pass, slice, ts, ts * nx, nx, ny);
            cli_progress_update(s->progress, "analyse", (double)(pass * nz + k + 1) / (double)(2 * nz));
        }
        if (pass == 1 && rc == CLI_EXIT_OK) cli_summary_finish(&a);
    }
    cli_progress_clear(s->progress);
    cli_slices_rewind(s);
    free(slice);
    return rc;
}

int cli_source_summary(cli_source *s, cli_summary *sum)
{
    memset(sum, 0, sizeof *sum);
#ifdef ISOMEND_HAVE_IO
    if (s->io) {
        int rc = cli_importer_summary(s, sum);
        /* streaming the slices, the importer showed its bar; a loaded
         * volume's analysis leaves the bar to the caller */
        if (s->mode == CLI_SOURCE_SLICES) cli_progress_clear(s->progress);
        return rc;
    }
#endif
    return s->mode == CLI_SOURCE_LOADED ? summary_of_samples(&s->desc, sum)
                                        : summary_of_slices(s, sum);
}

/* ------------------------------------------------------------------ named levels */

const char *cli_source_suggested_level(const cli_source *s)
{
#ifdef ISOMEND_HAVE_IO
    if (s->io && !s->series_listed &&
        cli_io.suggested_level((const isomend_io_source *)s->io) == ISOMEND_IO_LEVEL_BONE)
        return "bone";
#else
    (void)s;
#endif
    return "otsu";
}

int cli_source_level(cli_source *s, const char *name, double *value)
{
    const int bone = strcmp(name, "bone") == 0, skin = strcmp(name, "skin") == 0;
#ifdef ISOMEND_HAVE_IO
    if (s->io) {
        int level = bone ? ISOMEND_IO_LEVEL_BONE : skin ? ISOMEND_IO_LEVEL_SKIN : ISOMEND_IO_LEVEL_OTSU;
        if (cli_io.level_value((isomend_io_source *)s->io, level, value) != ISOMEND_IO_OK) {
            cli_error("--iso %s: %s", name, cli_io.message((isomend_io_source *)s->io));
            return CLI_EXIT_USAGE;
        }
        return CLI_EXIT_OK;
    }
#endif
    if (bone || skin) {
        cli_error("--iso %s: the %s level is for CT DICOM series in Hounsfield units; %s is a %s "
                  "source (give the level as a number)", name, name, s->label, s->kind);
        return CLI_EXIT_USAGE;
    }
    cli_summary sum;
    int rc = cli_source_summary(s, &sum);
    if (rc) return rc;
    *value = sum.suggested_iso;
    return CLI_EXIT_OK;
}

int cli_source_fixed_level(cli_source *s, double *level)
{
#ifdef ISOMEND_HAVE_IO
    if (s->io && cli_io.suggested_level((const isomend_io_source *)s->io) == ISOMEND_IO_LEVEL_BONE &&
        cli_io.level_value((isomend_io_source *)s->io, ISOMEND_IO_LEVEL_BONE, level) == ISOMEND_IO_OK)
        return 1;
#else
    (void)s;
    (void)level;
#endif
    return 0;
}
