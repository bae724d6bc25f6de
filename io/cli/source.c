/*
 * source.c - SOURCE to an isomend_volume
 *
 * One function decides what SOURCE is, so that each kind is a few lines:
 *   builtin:f1, builtin:f2   the thesis's test volumes (chapter 5.2), generated
 *   --raw NX,NY,NZ:TYPE      a headerless file (io/common)
 *   *.nrrd, *.nhdr           NRRD (io/common)
 *   anything else            the slice-stack importer isomend_io when this
 *                            build has it (folder, glob, printf pattern, list,
 *                            multi-page file), else a clear error.
 * Raw and NRRD always go through io/common directly, so that the CLI's own
 * behaviour (and the sanitizer build, which has no importer) is the same
 * with and without the importer.
 *
 * --slice-positions (slices not evenly spaced) is parsed when SOURCE opens:
 * raw, NRRD and built-in volumes get their slice origins table here (the
 * importer's rule: evenly spaced within 1e-6 of the mean gap is a uniform
 * grid, no table), image stacks hand the positions to the importer.  The
 * table lives in cli_slices.desc (so the streamed path and isomend-mpi's
 * slabs mesh from it) and moves to cli_source.vol with the samples.  Every
 * source gets a cli_geometry (the DICOM series' from the importer) and its
 * one-line warning.
 *
 * The suggested iso level follows the importer's documented rule (Otsu on a
 * 256-bin histogram of the finite samples; integer types moved to
 * floor(t) + 0.5 so that no sample equals the level); for importer sources
 * the importer computes it itself.
 */
#define _POSIX_C_SOURCE 200809L

#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "volume_readers.h"

#ifdef ISOMEND_HAVE_IO
#include <dlfcn.h>
#include <unistd.h>

#include "isomend_io.h"

/*
 * The importer is loaded with dlopen() only when a slice-stack source needs
 * it: linking it would load OpenImageIO's ~260 shared libraries (~0.3-0.7 s)
 * on every start, even for `isomend check` or a NRRD file.  Search order,
 * relative to this executable so that a build tree and an installation never
 * mix: $ISOMEND_IO_LIBRARY; <exe dir>/slices/<file> (the build tree:
 * build/io/isomend next to build/io/slices/); <exe dir>/../<libdir>/<soname>
 * (an installation); then the soname through the normal library search.
 */
static struct io_api {
    void *handle;
    const char *(*status_string)(isomend_io_status);
    isomend_io_status (*create)(isomend_io_source **);
    void (*destroy)(isomend_io_source *);
    const char *(*message)(const isomend_io_source *);
    void (*options_init)(isomend_io_options *);
    isomend_io_status (*open)(isomend_io_source *, const char *const *, size_t,
                              const isomend_io_options *);
    isomend_io_status (*load)(isomend_io_source *, isomend_volume *, double *);
    isomend_io_status (*analyse)(isomend_io_source *, isomend_io_summary *);
    isomend_io_status (*spacing)(const isomend_io_source *, double *, int *);
    const char *(*spacing_source_name)(int);
    const char *(*kind_name)(int);
    int (*source_kind)(const isomend_io_source *);
    const char *(*format)(const isomend_io_source *);
    isomend_io_status (*dims)(const isomend_io_source *, int64_t *);
    isomend_io_status (*type)(const isomend_io_source *, isomend_type *);
    isomend_io_status (*origin)(const isomend_io_source *, double *);
    isomend_io_status (*read_slice)(isomend_io_source *, int64_t, void *, size_t);
    isomend_io_status (*set_series)(isomend_io_source *, const char *);
    isomend_io_status (*set_axes)(isomend_io_source *, int);
    int64_t (*series_count)(const isomend_io_source *);
    isomend_io_status (*series_get)(const isomend_io_source *, int64_t, isomend_io_series *);
    int64_t (*series_chosen)(const isomend_io_source *);
    isomend_io_status (*dicom_info)(const isomend_io_source *, isomend_io_dicom *);
    isomend_io_status (*nifti_info)(const isomend_io_source *, isomend_io_nifti *);
    isomend_io_status (*world_transform)(const isomend_io_source *, double *, int *);
    isomend_io_status (*level_value)(isomend_io_source *, int, double *);
    int (*suggested_level)(const isomend_io_source *);
    isomend_io_status (*geometry_info)(const isomend_io_source *, isomend_io_geometry *);
    const double *(*slice_origins)(const isomend_io_source *);
} io_api;

static int io_load_api(char *why, size_t why_size)
{
    if (io_api.handle) return 1;
    char exe[1024], build_path[1200] = "", install_path[1200] = "";
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n > 0) {
        exe[n] = '\0';
        char *slash = strrchr(exe, '/');
        if (slash) {
            *slash = '\0';
            snprintf(build_path, sizeof build_path, "%s/slices/%s", exe, ISOMEND_IO_FILE_NAME);
            snprintf(install_path, sizeof install_path, "%s/../%s/%s", exe, ISOMEND_IO_LIBDIR,
                     ISOMEND_IO_SONAME);
        }
    }
    const char *candidates[4] = {getenv("ISOMEND_IO_LIBRARY"), build_path, install_path,
                                 ISOMEND_IO_SONAME};
    void *h = NULL;
    why[0] = '\0';
    for (int i = 0; i < 4 && !h; i++) {
        if (i > 0 && i < 3 && candidates[i] && access(candidates[i], F_OK) != 0) continue;
        if (!candidates[i] || !*candidates[i]) continue;
        h = dlopen(candidates[i], RTLD_NOW | RTLD_LOCAL);
        if (!h && !why[0]) {
            const char *e = dlerror();
            snprintf(why, why_size, "%s", e ? e : candidates[i]);
        }
    }
    if (!h) return 0;
#define IO_SYM(field, name)                                                                        \
    do {                                                                                           \
        void *sym_ = dlsym(h, name);                                                               \
        if (!sym_) {                                                                               \
            snprintf(why, why_size, "symbol %s missing", name);                                    \
            dlclose(h);                                                                            \
            return 0;                                                                              \
        }                                                                                          \
        memcpy(&io_api.field, &sym_, sizeof sym_);                                                 \
    } while (0)
    IO_SYM(status_string, "isomend_io_status_string");
    IO_SYM(create, "isomend_io_create");
    IO_SYM(destroy, "isomend_io_destroy");
    IO_SYM(message, "isomend_io_message");
    IO_SYM(options_init, "isomend_io_options_init");
    IO_SYM(open, "isomend_io_open");
    IO_SYM(load, "isomend_io_load");
    IO_SYM(analyse, "isomend_io_analyse");
    IO_SYM(spacing, "isomend_io_spacing");
    IO_SYM(spacing_source_name, "isomend_io_spacing_source_name");
    IO_SYM(kind_name, "isomend_io_kind_name");
    IO_SYM(source_kind, "isomend_io_source_kind");
    IO_SYM(format, "isomend_io_format");
    IO_SYM(dims, "isomend_io_dims");
    IO_SYM(type, "isomend_io_type");
    IO_SYM(origin, "isomend_io_origin");
    IO_SYM(read_slice, "isomend_io_read_slice");
    IO_SYM(set_series, "isomend_io_set_series");
    IO_SYM(set_axes, "isomend_io_set_axes");
    IO_SYM(series_count, "isomend_io_series_count");
    IO_SYM(series_get, "isomend_io_series_get");
    IO_SYM(series_chosen, "isomend_io_series_chosen");
    IO_SYM(dicom_info, "isomend_io_dicom_info");
    IO_SYM(nifti_info, "isomend_io_nifti_info");
    IO_SYM(world_transform, "isomend_io_world_transform");
    IO_SYM(level_value, "isomend_io_level_value");
    IO_SYM(suggested_level, "isomend_io_suggested_level");
    IO_SYM(geometry_info, "isomend_io_geometry_info");
    IO_SYM(slice_origins, "isomend_io_slice_origins");
#undef IO_SYM
    io_api.handle = h;
    return 1;
}
#endif

int cli_builtin_volume(const char *name, float out[64])
{
    int which = strcmp(name, "builtin:f1") == 0 ? 1 : strcmp(name, "builtin:f2") == 0 ? 2 : 0;
    if (!which) return 0;
    for (int z = 0; z < 4; z++)
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++) {
                double v;
                if (which == 1)
                    v = 4.0 * y + 4.0 * (x - z) * (x - z) - 5.0;
                else
                    v = 4.0 * (y - 1) * (y - 1) + 2.0 * (x - z) * (x - z) -
                        2.0 * (x + z - 3) * (x + z - 3) + 1.0;
                out[x + 4 * (y + 4 * z)] = (float)v;
            }
    return 1;
}

/* ------------------------------------------------------------------ slice positions */

/*
 * --slice-positions: the z of every slice, for volumes whose slices are not
 * evenly spaced (microscopy with variable steps, re-sliced data).  Raw, NRRD
 * and built-in volumes get their slice origins table here, (origin x, origin
 * y, z_k) for slice k; image stacks hand the positions to the importer, which
 * applies the same rule.  Positions evenly spaced within 1e-6 of their mean
 * gap are a uniform grid: spacing = the mean gap, origin z = the first, no
 * table, so that the mesh is the evenly spaced one byte for byte.
 */

static int compare_doubles(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

void cli_geometry_of_positions(const double *z, int64_t n, cli_geometry *g)
{
    /* the importer's rule (io/slices/src/geometry.cpp, measure_slices): the
     * median is the upper middle gap; uniform when no slice is farther than
     * 1e-6 of the mean gap from the evenly spaced grid through the first and
     * the last */
    memset(g, 0, sizeof *g);
    g->uniform = 1;
    g->from = "spacing";
    if (n < 2) return;
    const int64_t ng = n - 1;
    const double mean = (z[n - 1] - z[0]) / (double)ng;
    double *gaps = malloc((size_t)ng * sizeof *gaps);
    if (!gaps) { /* out of memory for a sorted copy: only the median is missed */
        g->gap_median = mean;
    } else {
        for (int64_t k = 0; k < ng; k++) gaps[k] = z[k + 1] - z[k];
        qsort(gaps, (size_t)ng, sizeof *gaps, compare_doubles);
        g->gap_median = gaps[ng / 2];
        free(gaps);
    }
    g->gap_min = INFINITY;
    g->gap_max = -INFINITY;
    int64_t longest = -1;
    for (int64_t k = 0; k < ng; k++) {
        const double gap = z[k + 1] - z[k];
        if (gap < g->gap_min) g->gap_min = gap;
        if (gap > g->gap_max) g->gap_max = gap;
        if (fabs(gap - g->gap_median) > 0.01 * g->gap_median) g->uneven_gaps++;
        if (gap > 1.5 * g->gap_median) {
            g->long_gaps++;
            if (longest < 0 || gap > z[longest + 1] - z[longest]) longest = k;
        }
    }
    for (int64_t k = 0; k < n; k++) {
        const double off = fabs(z[k] - (z[0] + (double)k * mean));
        if (off > g->max_offset) g->max_offset = off;
    }
    g->uniform = g->max_offset <= 1e-6 * mean;
    if (!g->uneven_gaps && !g->long_gaps) return;
    int len = snprintf(g->warning, sizeof g->warning,
                       "slice gaps vary from %.4g to %.4g (median %.4g): meshed at the slices' "
                       "positions", g->gap_min, g->gap_max, g->gap_median);
    if (longest >= 0 && len > 0 && (size_t)len < sizeof g->warning) {
        const double ratio = g->gap_max / g->gap_median;
        if (g->long_gaps == 1)
            snprintf(g->warning + len, sizeof g->warning - (size_t)len,
                     "; a gap of %.4g between slice %lld and %lld is %.4gx the median: a missing "
                     "slice?", g->gap_max, (long long)longest, (long long)longest + 1, ratio);
        else
            snprintf(g->warning + len, sizeof g->warning - (size_t)len,
                     "; %lld gaps over 1.5x the median, the longest %.4g between slice %lld and "
                     "%lld (%.4gx): missing slices?", (long long)g->long_gaps, g->gap_max,
                     (long long)longest, (long long)longest + 1, ratio);
    }
}

/* A uniform grid's geometry: every gap the z spacing. */
static void geometry_uniform(const isomend_volume *v, cli_geometry *g)
{
    memset(g, 0, sizeof *g);
    g->uniform = 1;
    g->from = "spacing";
    if (v->dims[2] > 1) g->gap_median = g->gap_min = g->gap_max = v->spacing[2];
}

/* One value of --slice-positions, `where` naming it for the message. */
static int position_value(char *text, const char *where, double *z)
{
    while (*text == ' ' || *text == '\t' || *text == '\r') text++;
    size_t n = strlen(text);
    while (n && (text[n - 1] == ' ' || text[n - 1] == '\t' || text[n - 1] == '\r'))
        text[--n] = '\0';
    char *end = NULL;
    double v = strtod(text, &end);
    if (!*text || end == text || *end) {
        cli_error("--slice-positions: %s: '%s' is not a number", where, text);
        return 0;
    }
    if (!isfinite(v)) {
        cli_error("--slice-positions: %s: '%s' is not a finite number", where, text);
        return 0;
    }
    *z = v;
    return 1;
}

/* Appends z to *out (capacity *cap). */
static int push_position(double **out, int64_t *count, int64_t *cap, double z)
{
    if (*count == *cap) {
        int64_t c = *cap ? 2 * *cap : 256;
        double *p = realloc(*out, (size_t)c * sizeof *p);
        if (!p) {
            cli_error("--slice-positions: out of memory");
            return 0;
        }
        *out = p;
        *cap = c;
    }
    (*out)[(*count)++] = z;
    return 1;
}

int cli_parse_slice_positions(const char *value, double **out, int64_t *count)
{
    *out = NULL;
    *count = 0;
    int64_t cap = 0, *lines = NULL, lcap = 0, lcount = 0; /* a file's line of each value */
    char where[1200];
    int rc = CLI_EXIT_OK;
    const char *file = value[0] == '@' ? value + 1 : NULL;
    if (file) {
        FILE *fp = fopen(file, "r");
        if (!fp) {
            cli_error("--slice-positions: cannot read %s: %s", file, strerror(errno));
            return CLI_EXIT_FAIL;
        }
        char *line = NULL;
        size_t size = 0;
        int64_t number = 0;
        while (rc == CLI_EXIT_OK && getline(&line, &size, fp) >= 0) {
            number++;
            line[strcspn(line, "#\n")] = '\0';
            if (line[strspn(line, " \t\r")] == '\0') continue; /* blank or a comment */
            double z;
            snprintf(where, sizeof where, "%s:%lld", file, (long long)number);
            if (!position_value(line, where, &z)) {
                rc = CLI_EXIT_USAGE;
            } else if (!push_position(out, count, &cap, z)) {
                rc = CLI_EXIT_FAIL;
            } else if (lcount == lcap) {
                lcap = lcap ? 2 * lcap : 256;
                int64_t *p = realloc(lines, (size_t)lcap * sizeof *p);
                if (!p) {
                    cli_error("--slice-positions: out of memory");
                    rc = CLI_EXIT_FAIL;
                } else {
                    lines = p;
                }
            }
            if (rc == CLI_EXIT_OK) lines[lcount++] = number;
        }
        if (rc == CLI_EXIT_OK && ferror(fp)) {
            cli_error("--slice-positions: cannot read %s: %s", file, strerror(errno));
            rc = CLI_EXIT_FAIL;
        }
        free(line);
        fclose(fp);
        if (rc == CLI_EXIT_OK && *count == 0) {
            cli_error("--slice-positions: %s holds no positions (one z a line)", file);
            rc = CLI_EXIT_USAGE;
        }
    } else {
        char *copy = strdup(value);
        if (!copy) {
            cli_error("--slice-positions: out of memory");
            return CLI_EXIT_FAIL;
        }
        char *item = copy;
        for (int64_t k = 0; rc == CLI_EXIT_OK; k++) {
            char *comma = strchr(item, ',');
            if (comma) *comma = '\0';
            double z;
            snprintf(where, sizeof where, "value %lld", (long long)k + 1);
            if (!position_value(item, where, &z))
                rc = CLI_EXIT_USAGE;
            else if (!push_position(out, count, &cap, z))
                rc = CLI_EXIT_FAIL;
            if (!comma) break;
            item = comma + 1;
        }
        free(copy);
    }
    for (int64_t k = 1; rc == CLI_EXIT_OK && k < *count; k++) {
        if ((*out)[k] > (*out)[k - 1]) continue;
        if (file)
            snprintf(where, sizeof where, "%s:%lld", file, (long long)lines[k]);
        else
            snprintf(where, sizeof where, "value %lld", (long long)k + 1);
        cli_error("--slice-positions: %s: z %.17g of slice %lld is not above z %.17g of slice "
                  "%lld (the positions must increase strictly, one a slice)",
                  where, (*out)[k], (long long)k, (*out)[k - 1], (long long)k - 1);
        rc = CLI_EXIT_USAGE;
    }
    free(lines);
    if (rc) {
        free(*out);
        *out = NULL;
        *count = 0;
    }
    return rc;
}

/* Raw, NRRD, built-in: the positions become the grid's (checked against its slices). */
static int apply_positions(cli_slices *s, const double *z, int64_t n)
{
    if (n != s->desc.dims[2]) {
        cli_error("--slice-positions: %lld position%s for the %lld slice%s of %s", (long long)n,
                  n == 1 ? "" : "s", (long long)s->desc.dims[2], s->desc.dims[2] == 1 ? "" : "s",
                  s->label);
        return CLI_EXIT_USAGE;
    }
    cli_geometry_of_positions(z, n, &s->geometry);
    s->geometry.from = "--slice-positions";
    /* the first position and the mean gap: the grid itself when uniform, the
     * figures reported otherwise (the core then reads only the table) */
    s->desc.origin[2] = z[0];
    if (n > 1) s->desc.spacing[2] = (z[n - 1] - z[0]) / (double)(n - 1);
    s->spacing_from[2] = "positions";
    if (s->geometry.uniform) return CLI_EXIT_OK;
    double *t = malloc((size_t)n * 3 * sizeof *t);
    if (!t) {
        cli_error("%s: out of memory for %lld slice origins", s->label, (long long)n);
        return CLI_EXIT_FAIL;
    }
    for (int64_t k = 0; k < n; k++) {
        t[3 * k] = s->desc.origin[0];
        t[3 * k + 1] = s->desc.origin[1];
        t[3 * k + 2] = z[k];
    }
    s->origins_owned = t;
    s->desc.slice_origins = t;
    return CLI_EXIT_OK;
}

void cli_print_geometry_warning(const char *label, const cli_geometry *g)
{
    if (g->warning[0]) {
        cli_progress_clear(cli_active_progress);
        fprintf(stderr, "%s: warning: %s: %s\n", cli_program, label, g->warning);
    }
}

static void apply_overrides(const cli_source_opts *o, isomend_volume *v, const char **from)
{
    for (int a = 0; a < 3; a++) {
        if (o->have_spacing) {
            v->spacing[a] = o->spacing[a];
            from[a] = "option";
        }
        if (o->have_origin) v->origin[a] = o->origin[a];
    }
}

uint64_t cli_memory_available(void)
{
    return cli_proc_kib("/proc/meminfo", "MemAvailable:") * 1024u;
}

/* Raw and NRRD: the probe (no sample read). */
static int open_fileio(const char *path, const cli_source_opts *o, cli_slices *s)
{
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    isomend_fileio_status st;
    if (o->have_raw) {
        st = isomend_fileio_probe_raw(path, o->raw_dims, o->raw_type, o->raw_big_endian, 0,
                                      &s->info, msg, sizeof msg);
        snprintf(s->kind, sizeof s->kind, "raw");
    } else {
        st = isomend_fileio_probe_nrrd(path, &s->info, msg, sizeof msg);
        snprintf(s->kind, sizeof s->kind, "nrrd");
    }
    if (st != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        return CLI_EXIT_FAIL;
    }
    s->is_fileio = 1;
    snprintf(s->format, sizeof s->format, "%s",
             s->info.encoding == ISOMEND_FILEIO_ENC_GZIP ? "gzip" : "raw");
    /* what isomend_fileio_describe() will present: a reversed axis starts at its last sample */
    const isomend_fileio_info *in = &s->info;
    isomend_volume_init(&s->desc, NULL, in->type, in->dims[0], in->dims[1], in->dims[2]);
    for (int a = 0; a < 3; a++) {
        s->desc.spacing[a] = in->spacing[a];
        s->desc.origin[a] = in->origin[a];
        if (in->axis_negative[a] && !in->oblique && in->dims[a] > 1)
            s->desc.origin[a] -= (double)(in->dims[a] - 1) * in->spacing[a];
    }
    for (int a = 0; a < 3; a++) s->spacing_from[a] = s->info.spacing_known ? "header" : "default";
    s->oblique = s->info.oblique;
    apply_overrides(o, &s->desc, s->spacing_from);
    return CLI_EXIT_OK;
}

#ifdef ISOMEND_HAVE_IO
static int io_progress(void *user, int stage, double fraction)
{
    static const char *labels[] = {"open", "read", "analyse", "extract"};
    cli_progress_update(user, stage >= 0 && stage < 4 ? labels[stage] : "io", fraction);
    return cli_interrupted;
}

static int io_failed(isomend_io_source *io, isomend_io_status st, const char *label)
{
    if (st == ISOMEND_IO_ERR_CANCELLED) {
        cli_error("%s: interrupted", label);
        return CLI_EXIT_INTERRUPTED;
    }
    const char *m = io_api.message(io);
    cli_error("%s", m && *m ? m : io_api.status_string(st));
    return st == ISOMEND_IO_ERR_INVALID_ARGUMENT ? CLI_EXIT_USAGE : CLI_EXIT_FAIL;
}

/* Image stacks: the importer resolves the source and checks every header. */
static int open_io(const char *const *paths, int n, const cli_source_opts *o,
                   const double *positions, int64_t npositions, cli_slices *s)
{
    isomend_io_source *io = NULL;
    char why[512];
    if (!io_load_api(why, sizeof why)) {
        cli_error("%s: slice stacks need the importer library libisomend_io, which could not be "
                  "loaded (%s); set ISOMEND_IO_LIBRARY to its path", paths[0], why);
        return CLI_EXIT_FAIL;
    }
    if (io_api.create(&io) != ISOMEND_IO_OK) {
        cli_error("%s: out of memory", paths[0]);
        return CLI_EXIT_FAIL;
    }
    isomend_io_options opts;
    io_api.options_init(&opts);
    if (o->have_first) opts.first = o->first;
    if (o->have_count) opts.count = o->count;
    if (o->have_step) opts.step = o->step;
    if (o->have_channel) opts.channel = o->channel;
    if (o->have_spacing)
        for (int a = 0; a < 3; a++) opts.spacing[a] = o->spacing[a];
    if (o->have_origin)
        for (int a = 0; a < 3; a++) opts.origin[a] = o->origin[a];
    opts.threads = o->threads;
    opts.slice_positions = positions; /* copied by open */
    opts.slice_position_count = (size_t)npositions;
    opts.progress = io_progress; /* also how Ctrl-C cancels */
    opts.progress_user = o->progress;
    if (o->series) io_api.set_series(io, o->series);
    if (o->grid_axes) io_api.set_axes(io, ISOMEND_IO_AXES_GRID);
    if (o->ras) io_api.set_axes(io, ISOMEND_IO_AXES_RAS);
    isomend_io_status st = io_api.open(io, paths, (size_t)n, &opts);
    cli_progress_clear(o->progress);
    if (st == ISOMEND_IO_ERR_SERIES && o->list_series && !o->series) {
        /* `info` on a folder of several series: the list is the answer */
        s->io = io;
        s->dicom = 1;
        s->series_listed = 1;
        snprintf(s->kind, sizeof s->kind, "dicom");
        snprintf(s->format, sizeof s->format, "dicom");
        return CLI_EXIT_OK;
    }
    int64_t dims[3];
    isomend_type type = ISOMEND_U8;
    double spacing[3], origin[3];
    int from[3] = {0, 0, 0};
    if (st == ISOMEND_IO_OK) st = io_api.dims(io, dims);
    if (st == ISOMEND_IO_OK) st = io_api.type(io, &type);
    if (st == ISOMEND_IO_OK) st = io_api.spacing(io, spacing, from);
    if (st == ISOMEND_IO_OK) st = io_api.origin(io, origin);
    if (st != ISOMEND_IO_OK) {
        /* the importer names the parameter by its API name: say the option's */
        const char *m = io_api.message(io), *api = "slice_positions: ";
        int rc;
        if (positions && m && strncmp(m, api, strlen(api)) == 0) {
            cli_error("--slice-positions: %s", m + strlen(api));
            rc = CLI_EXIT_USAGE;
        } else {
            rc = io_failed(io, st, paths[0]);
        }
        io_api.destroy(io);
        return rc;
    }
    s->io = io;
    isomend_volume_init(&s->desc, NULL, type, dims[0], dims[1], dims[2]);
    for (int a = 0; a < 3; a++) {
        s->desc.spacing[a] = spacing[a];
        s->desc.origin[a] = origin[a];
        const char *name = io_api.spacing_source_name(from[a]);
        s->spacing_from[a] = name ? name : "?";
    }
    const char *kind = io_api.kind_name(io_api.source_kind(io));
    snprintf(s->kind, sizeof s->kind, "%s", kind ? kind : "?");
    snprintf(s->format, sizeof s->format, "%s", io_api.format(io));
    s->dicom = io_api.source_kind(io) == ISOMEND_IO_KIND_DICOM;
    s->grid_axes = o->grid_axes;
    int identity = 1;
    if (io_api.world_transform(io, s->world, &identity) == ISOMEND_IO_OK) s->has_world = !identity;
    if (positions && s->dicom) { /* the importer refuses them; never mesh a series elsewhere */
        cli_error("%s: --slice-positions does not apply to a DICOM series (its slices' positions "
                  "are its own, from Image Position (Patient))", paths[0]);
        return CLI_EXIT_USAGE; /* the caller closes s */
    }
    if (positions && dims[2] != npositions) { /* the importer checks it too */
        cli_error("--slice-positions: %lld position%s for the %lld slice%s of %s",
                  (long long)npositions, npositions == 1 ? "" : "s", (long long)dims[2],
                  dims[2] == 1 ? "" : "s", paths[0]);
        return CLI_EXIT_USAGE;
    }
    /* where the slices lie: the series' positions, the stack's --slice-positions */
    isomend_io_geometry g;
    memset(&g, 0, sizeof g);
    g.size = sizeof g;
    st = io_api.geometry_info(io, &g);
    if (st != ISOMEND_IO_OK) return io_failed(io, st, paths[0]);
    cli_geometry *cg = &s->geometry;
    if (positions) { /* the same rule and words as a raw volume's (the importer's rule) */
        cli_geometry_of_positions(positions, npositions, cg);
        cg->from = "--slice-positions";
        s->desc.slice_origins = io_api.slice_origins(io);
        if (cg->uniform != (s->desc.slice_origins == NULL)) {
            cli_error("%s: the importer and isomend disagree on whether the slice positions are "
                      "evenly spaced (internal error)", paths[0]);
            return CLI_EXIT_FAIL;
        }
        s->spacing_from[2] = "positions";
        return CLI_EXIT_OK;
    }
    cg->uniform = g.uniform != 0;
    cg->from = s->dicom ? "dicom" : "spacing";
    cg->gap_median = g.gap_median;
    cg->gap_min = g.gap_min;
    cg->gap_max = g.gap_max;
    cg->tilt_degrees = g.tilt_degrees;
    cg->max_offset = g.max_offset;
    cg->long_gaps = g.long_gaps;
    cg->uneven_gaps = g.uneven_gaps;
    snprintf(cg->warning, sizeof cg->warning, "%s", g.warning ? g.warning : "");
    /* the streamed path and isomend-mpi mesh from this description (the
     * table belongs to the handle; isomend_io_load() sets the same) */
    s->desc.slice_origins = io_api.slice_origins(io);
    return CLI_EXIT_OK;
}
#endif

static int opened(const char *const *paths, int n, const cli_source_opts *o,
                  const double *positions, int64_t npositions, cli_slices *s);

int cli_slices_open(const char *const *paths, int n, const cli_source_opts *o, cli_slices *s)
{
    memset(s, 0, sizeof *s);
    snprintf(s->label, sizeof s->label, "%s", paths[0]);
    s->progress = o->progress;
    if ((o->series || o->grid_axes || o->ras) &&
        ((n == 1 && (o->have_raw || isomend_fileio_is_nrrd_path(paths[0]))) ||
         strncmp(paths[0], "builtin:", 8) == 0)) {
        cli_error("%s: --series, --grid-axes and --ras apply to DICOM series and NIfTI volumes only",
                  paths[0]);
        return CLI_EXIT_USAGE;
    }
    if (o->ras && o->grid_axes) {
        cli_error("--ras and --grid-axes exclude each other (RAS is a world frame, the grid axes "
                  "none)");
        return CLI_EXIT_USAGE;
    }
    double *positions = NULL;
    int64_t npositions = 0;
    if (o->slice_positions) {
        int prc = cli_parse_slice_positions(o->slice_positions, &positions, &npositions);
        if (prc) return prc;
    }
    int rc = opened(paths, n, o, positions, npositions, s);
    free(positions);
    if (rc) {
        cli_slices_close(s);
        return rc;
    }
    s->slice_bytes = (uint64_t)s->desc.dims[0] * (uint64_t)s->desc.dims[1] *
                     isomend_type_size(s->desc.type);
    return CLI_EXIT_OK;
}

/* cli_slices_open's dispatch; on failure the caller closes s. */
static int opened(const char *const *paths, int n, const cli_source_opts *o,
                  const double *positions, int64_t npositions, cli_slices *s)
{
    int stack_opts = o->have_first || o->have_count || o->have_step || o->have_channel;
    int rc;
    if (n == 1 && cli_builtin_volume(paths[0], s->builtin)) {
        if (o->have_raw || stack_opts) {
            cli_error("%s: --raw/--first/--count/--step/--channel do not apply to a built-in volume",
                      paths[0]);
            return CLI_EXIT_USAGE;
        }
        s->is_builtin = 1;
        isomend_volume_init(&s->desc, NULL, ISOMEND_F32, 4, 4, 4);
        snprintf(s->kind, sizeof s->kind, "builtin");
        snprintf(s->format, sizeof s->format, "generated");
        for (int a = 0; a < 3; a++) s->spacing_from[a] = "default";
        apply_overrides(o, &s->desc, s->spacing_from);
        geometry_uniform(&s->desc, &s->geometry);
        rc = positions ? apply_positions(s, positions, npositions) : CLI_EXIT_OK;
    } else if (strncmp(paths[0], "builtin:", 8) == 0) {
        cli_error("%s: unknown built-in volume (builtin:f1 or builtin:f2)", paths[0]);
        return CLI_EXIT_USAGE;
    } else if (n == 1 && (o->have_raw || isomend_fileio_is_nrrd_path(paths[0]))) {
        if (stack_opts) {
            cli_error("%s: --first/--count/--step/--channel only apply to slice stacks", paths[0]);
            return CLI_EXIT_USAGE;
        }
        rc = open_fileio(paths[0], o, s);
        if (rc == CLI_EXIT_OK) geometry_uniform(&s->desc, &s->geometry);
        if (rc == CLI_EXIT_OK && positions) rc = apply_positions(s, positions, npositions);
    } else {
#ifdef ISOMEND_HAVE_IO
        if (o->have_raw) {
            cli_error("--raw describes one file, got %d sources", n);
            return CLI_EXIT_USAGE;
        }
        rc = open_io(paths, n, o, positions, npositions, s);
        int nifti = rc == CLI_EXIT_OK && strcmp(s->kind, "nifti") == 0;
        if (rc == CLI_EXIT_OK && !nifti && !s->dicom && o->ras) {
            cli_error("%s: --ras applies to NIfTI volumes only (this is a %s source)", paths[0],
                      s->kind);
            return CLI_EXIT_USAGE;
        }
        if (rc == CLI_EXIT_OK && nifti && o->series) {
            cli_error("%s: --series applies to DICOM series only (this is a NIfTI volume)", paths[0]);
            return CLI_EXIT_USAGE;
        }
        if (rc == CLI_EXIT_OK && !s->dicom && !nifti && (o->series || o->grid_axes)) {
            cli_error("%s: --series and --grid-axes apply to DICOM series only (this is a %s "
                      "source)", paths[0], s->kind);
            return CLI_EXIT_USAGE;
        }
#else
        if (n > 1) {
            cli_error("%s: one SOURCE expected, got %d (file lists need the slice-stack importer, "
                      "built with -DISOMEND_BUILD_IO=ON)", paths[0], n);
            return CLI_EXIT_USAGE;
        }
        cli_error("%s: not a NRRD file (.nrrd/.nhdr) and no --raw NX,NY,NZ:TYPE given; image "
                  "stacks need the slice-stack importer (build with -DISOMEND_BUILD_IO=ON)",
                  paths[0]);
        return CLI_EXIT_USAGE;
#endif
    }
    return rc;
}

int cli_slices_next(cli_slices *s, void *buffer)
{
    if (s->next >= s->desc.dims[2]) {
        cli_error("%s: no slice %lld (internal error)", s->label, (long long)s->next);
        return CLI_EXIT_FAIL;
    }
    double t0 = cli_now_ms();
    int rc = CLI_EXIT_OK;
    if (s->is_builtin) {
        memcpy(buffer, s->builtin + 16 * s->next, 16 * sizeof(float));
    } else if (s->is_fileio) {
        char msg[ISOMEND_FILEIO_MSG_SIZE];
        isomend_fileio_status st = ISOMEND_FILEIO_OK;
        if (!s->reader) st = isomend_fileio_slices_open(&s->info, &s->reader, msg, sizeof msg);
        if (st == ISOMEND_FILEIO_OK)
            st = isomend_fileio_slices_next(s->reader, buffer, (size_t)s->slice_bytes, msg,
                                            sizeof msg);
        if (st != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            rc = CLI_EXIT_FAIL;
        }
    } else {
#ifdef ISOMEND_HAVE_IO
        isomend_io_status st = io_api.read_slice(s->io, s->next, buffer, (size_t)s->slice_bytes);
        if (st != ISOMEND_IO_OK) rc = io_failed(s->io, st, s->label);
#endif
    }
    s->read_ms += cli_now_ms() - t0;
    if (rc == CLI_EXIT_OK) s->next++;
    return rc;
}

int cli_slices_seek(cli_slices *s, int64_t k)
{
    if (k < 0 || k > s->desc.dims[2]) {
        cli_error("%s: no slice %lld (internal error)", s->label, (long long)k);
        return CLI_EXIT_FAIL;
    }
    if (s->reader) {
        char msg[ISOMEND_FILEIO_MSG_SIZE];
        if (isomend_fileio_slices_seek(s->reader, k, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            return CLI_EXIT_FAIL;
        }
    } else if (s->is_fileio && k > 0) {
        char msg[ISOMEND_FILEIO_MSG_SIZE];
        if (isomend_fileio_slices_open(&s->info, &s->reader, msg, sizeof msg) !=
                ISOMEND_FILEIO_OK ||
            isomend_fileio_slices_seek(s->reader, k, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            return CLI_EXIT_FAIL;
        }
    }
    s->next = k;
    return CLI_EXIT_OK;
}

void cli_slices_rewind(cli_slices *s)
{
    isomend_fileio_slices_close(s->reader); /* the next slice opens it again */
    s->reader = NULL;
    s->next = 0;
}

void cli_slices_close(cli_slices *s)
{
    if (!s) return;
    isomend_fileio_slices_close(s->reader);
    free(s->origins_owned);
#ifdef ISOMEND_HAVE_IO
    if (s->io) io_api.destroy(s->io);
#endif
    memset(s, 0, sizeof *s);
}

int cli_source_load(cli_slices *s, cli_source *src)
{
    memset(src, 0, sizeof *src);
    snprintf(src->label, sizeof src->label, "%s", s->label);
    snprintf(src->kind, sizeof src->kind, "%s", s->kind);
    snprintf(src->format, sizeof src->format, "%s", s->format);
    for (int a = 0; a < 3; a++) src->spacing_from[a] = s->spacing_from[a];
    src->oblique = s->oblique;
    src->dicom = s->dicom;
    src->series_listed = s->series_listed;
    src->grid_axes = s->grid_axes;
    src->has_world = s->has_world;
    memcpy(src->world, s->world, sizeof src->world);
    src->geometry = s->geometry;
    src->origins_owned = s->origins_owned; /* the slice origins we built go along */
    s->origins_owned = NULL;
    int rc = CLI_EXIT_OK;
    if (s->is_builtin) {
        src->owned = malloc(sizeof s->builtin);
        if (!src->owned) {
            cli_error("%s: out of memory", s->label);
            rc = CLI_EXIT_FAIL;
        } else {
            memcpy(src->owned, s->builtin, sizeof s->builtin);
            src->vol = s->desc;
            src->vol.data = src->owned;
        }
    } else if (s->is_fileio) {
        /* refuse before allocating: Linux overcommits, so a too large malloc
         * would "succeed" and the kernel would kill us half-way through */
        uint64_t need = isomend_fileio_volume_bytes(&s->info), avail = cli_memory_available();
        char msg[ISOMEND_FILEIO_MSG_SIZE];
        if (avail && need > avail) {
            cli_error("%s: the volume needs %.1f MiB, only %.1f MiB of memory is available",
                      s->label, (double)need / 1048576.0, (double)avail / 1048576.0);
            rc = CLI_EXIT_FAIL;
        } else {
            double t0 = cli_now_ms();
            isomend_fileio_status st = isomend_fileio_load(&s->info, &src->owned,
                                                           cli_progress_read_cb, s->progress, msg,
                                                           sizeof msg);
            cli_progress_clear(s->progress);
            if (st == ISOMEND_FILEIO_ERR_CANCELLED) {
                cli_error("%s: interrupted", s->label);
                rc = CLI_EXIT_INTERRUPTED;
            } else if (st != ISOMEND_FILEIO_OK) {
                cli_error("%s", msg);
                rc = CLI_EXIT_FAIL;
            } else {
                src->read_ms = cli_now_ms() - t0;
                isomend_fileio_describe(&s->info, src->owned, &src->vol);
                for (int a = 0; a < 3; a++) { /* the overrides, as opened */
                    src->vol.spacing[a] = s->desc.spacing[a];
                    src->vol.origin[a] = s->desc.origin[a];
                }
                src->vol.slice_origins = s->desc.slice_origins; /* --slice-positions */
            }
        }
    } else {
#ifdef ISOMEND_HAVE_IO
        double seconds = 0;
        isomend_io_status st = io_api.load(s->io, &src->vol, &seconds);
        cli_progress_clear(s->progress);
        if (st != ISOMEND_IO_OK) {
            rc = io_failed(s->io, st, s->label);
        } else {
            src->io = s->io; /* the loaded volume belongs to the handle */
            s->io = NULL;
            src->read_ms = seconds * 1e3;
        }
#endif
    }
    cli_slices_close(s);
    if (rc) cli_source_close(src);
    return rc;
}

void cli_source_drop_samples(cli_source *src)
{
    if (!src || !src->owned) return; /* an importer's volume stays with its handle */
    free(src->owned);
    src->owned = NULL;
    src->vol.data = NULL;
}

void cli_source_close(cli_source *src)
{
    if (!src) return;
    free(src->owned);
    free(src->origins_owned);
#ifdef ISOMEND_HAVE_IO
    if (src->io) io_api.destroy(src->io);
#endif
    memset(src, 0, sizeof *src);
}

/* ------------------------------------------------------------------ analysis */

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

/*
 * The summary is computed plane by plane in two passes (range, then
 * histograms), so that a loaded volume (any strides) and a source read slice
 * by slice go through the same code and give the same numbers.
 */
typedef cli_summary_acc summary_acc; /* short names inside this file */
#define OTSU_BINS CLI_OTSU_BINS

void cli_summary_plane(summary_acc *a, int pass, const char *base, int64_t s0, int64_t s1,
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
                a->fine[bin_of(x, a->lo, a->hi, OTSU_BINS)]++;
            }
        }
}

void cli_summary_start(summary_acc *a, cli_summary *sum, isomend_type type)
{
    memset(sum, 0, sizeof *sum);
    memset(a, 0, sizeof *a);
    a->sum = sum;
    a->type = type;
    a->lo = INFINITY;
    a->hi = -INFINITY;
}

/* After pass 0: 1 if a histogram pass is needed. */
int cli_summary_range_done(summary_acc *a)
{
    if (a->finite == 0) return 0;
    a->sum->min = a->lo;
    a->sum->max = a->hi;
    a->sum->suggested_iso = a->lo;
    return a->hi > a->lo;
}

void cli_summary_finish(summary_acc *a)
{
    /* Otsu, exactly as the importer does it (io/common) */
    a->sum->suggested_iso = isomend_fileio_otsu(a->fine, OTSU_BINS, a->lo, a->hi,
                                                is_integer_type(a->type));
    a->sum->has_suggestion = 1;
}

#ifdef ISOMEND_HAVE_IO
static int io_summary(void *io, cli_summary *sum)
{
    isomend_io_summary s;
    isomend_io_status st = io_api.analyse(io, &s);
    if (st != ISOMEND_IO_OK) return io_failed(io, st, "analysis");
    sum->min = s.min;
    sum->max = s.max;
    sum->samples = s.samples;
    sum->nan_samples = s.nan_samples;
    for (int b = 0; b < 16; b++) sum->histogram[b] = s.histogram[b];
    sum->suggested_iso = s.suggested_iso;
    sum->has_suggestion = s.max > s.min;
    return CLI_EXIT_OK;
}
#endif

int cli_source_summary(cli_source *src, cli_summary *sum)
{
    memset(sum, 0, sizeof *sum);
#ifdef ISOMEND_HAVE_IO
    if (src->io) return io_summary(src->io, sum);
#endif
    const isomend_volume *v = &src->vol;
    int64_t ts = (int64_t)isomend_type_size(v->type), s0 = v->strides[0], s1 = v->strides[1],
            s2 = v->strides[2];
    if (!s0 && !s1 && !s2) {
        s0 = ts;
        s1 = s0 * v->dims[0];
        s2 = s1 * v->dims[1];
    }
    summary_acc a;
    cli_summary_start(&a, sum, v->type);
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1 && !cli_summary_range_done(&a)) return CLI_EXIT_OK;
        for (int64_t k = 0; k < v->dims[2]; k++)
            cli_summary_plane(&a, pass, (const char *)v->data + k * s2, s0, s1, v->dims[0], v->dims[1]);
    }
    cli_summary_finish(&a);
    return CLI_EXIT_OK;
}

int cli_slices_summary(cli_slices *s, cli_summary *sum)
{
    memset(sum, 0, sizeof *sum);
#ifdef ISOMEND_HAVE_IO
    if (s->io) { /* the importer streams the slices itself when nothing is loaded */
        int rc = io_summary(s->io, sum);
        cli_progress_clear(s->progress);
        return rc;
    }
#endif
    char *slice = malloc((size_t)s->slice_bytes);
    if (!slice) {
        cli_error("%s: out of memory for a slice of %llu bytes", s->label,
                  (unsigned long long)s->slice_bytes);
        return CLI_EXIT_FAIL;
    }
    const int64_t nx = s->desc.dims[0], ny = s->desc.dims[1], nz = s->desc.dims[2];
    const int64_t ts = (int64_t)isomend_type_size(s->desc.type);
    summary_acc a;
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

int cli_slices_fixed_level(cli_slices *s, double *level)
{
#ifdef ISOMEND_HAVE_IO
    if (s->io && io_api.suggested_level((const isomend_io_source *)s->io) == ISOMEND_IO_LEVEL_BONE &&
        io_api.level_value((isomend_io_source *)s->io, ISOMEND_IO_LEVEL_BONE, level) == ISOMEND_IO_OK)
        return 1;
#else
    (void)s;
    (void)level;
#endif
    return 0;
}

/* ------------------------------------------------------------------ DICOM */

#ifdef ISOMEND_HAVE_IO
/* `, "key": "value"` (or without the comma for the first member) */
static void json_text_member(FILE *fp, int first, const char *key, const char *value)
{
    fprintf(fp, "%s\"%s\": ", first ? "" : ", ", key);
    cli_json_string(fp, value);
}

static int dicom_of(const cli_source *src, isomend_io_dicom *d)
{
    memset(d, 0, sizeof *d);
    d->size = sizeof *d;
    return src->io && src->dicom && !src->series_listed &&
           io_api.dicom_info((const isomend_io_source *)src->io, d) == ISOMEND_IO_OK;
}
#endif

#ifdef ISOMEND_HAVE_IO
/* The importer's named levels of a CT series, indexed by isomend_io_level. */
static int levels_of(cli_source *src, double lv[3])
{
    for (int l = ISOMEND_IO_LEVEL_OTSU; l <= ISOMEND_IO_LEVEL_SKIN; l++)
        if (io_api.level_value((isomend_io_source *)src->io, l, &lv[l]) != ISOMEND_IO_OK)
            return 0;
    return 1;
}
#endif

const char *cli_source_suggested_level(const cli_source *src)
{
#ifdef ISOMEND_HAVE_IO
    if (src->io && !src->series_listed &&
        io_api.suggested_level((const isomend_io_source *)src->io) == ISOMEND_IO_LEVEL_BONE)
        return "bone";
#else
    (void)src;
#endif
    return "otsu";
}

int cli_source_level(cli_source *src, const char *name, double *value)
{
    int level = strcmp(name, "bone") == 0   ? ISOMEND_IO_LEVEL_BONE
                : strcmp(name, "skin") == 0 ? ISOMEND_IO_LEVEL_SKIN
                                            : ISOMEND_IO_LEVEL_OTSU;
#ifdef ISOMEND_HAVE_IO
    if (src->io) {
        if (io_api.level_value((isomend_io_source *)src->io, level, value) != ISOMEND_IO_OK) {
            cli_error("--iso %s: %s", name, io_api.message((isomend_io_source *)src->io));
            return CLI_EXIT_USAGE;
        }
        return CLI_EXIT_OK;
    }
#endif
    if (level != ISOMEND_IO_LEVEL_OTSU) {
        cli_error("--iso %s: the %s level is for CT DICOM series in Hounsfield units; %s is a %s "
                  "source (give the level as a number)", name, name, src->label, src->kind);
        return CLI_EXIT_USAGE;
    }
    cli_summary sum;
    int rc = cli_source_summary(src, &sum);
    if (rc) return rc;
    *value = sum.suggested_iso;
    return CLI_EXIT_OK;
}

void cli_print_series(FILE *fp, const cli_source *src)
{
#ifdef ISOMEND_HAVE_IO
    if (!src->io) return;
    const isomend_io_source *io = (const isomend_io_source *)src->io;
    int64_t n = io_api.series_count(io), chosen = io_api.series_chosen(io);
    if (n < 2 && !src->series_listed) return;
    fprintf(fp, "  series:      %lld%s\n", (long long)n,
            src->series_listed ? "; choose one with --series N or --series UID" : "");
    for (int64_t i = 0; i < n; i++) {
        isomend_io_series e;
        memset(&e, 0, sizeof e);
        e.size = sizeof e;
        if (io_api.series_get(io, i, &e) != ISOMEND_IO_OK) continue;
        fprintf(fp, "  %s %3lld: %-4s \"%s\"", i == chosen ? "*" : " ", (long long)(i + 1),
                e.modality[0] ? e.modality : "?", e.description);
        if (e.number >= 0) fprintf(fp, ", series number %lld", (long long)e.number);
        fprintf(fp, ", %lld x %lld, %lld images in %lld files, UID %s\n", (long long)e.columns,
                (long long)e.rows, (long long)e.images, (long long)e.files, e.uid);
    }
#else
    (void)fp;
    (void)src;
#endif
}

void cli_json_series(FILE *fp, const cli_source *src)
{
    fprintf(fp, "[");
#ifdef ISOMEND_HAVE_IO
    if (src->io) {
        const isomend_io_source *io = (const isomend_io_source *)src->io;
        int64_t n = io_api.series_count(io);
        for (int64_t i = 0; i < n; i++) {
            isomend_io_series e;
            memset(&e, 0, sizeof e);
            e.size = sizeof e;
            if (io_api.series_get(io, i, &e) != ISOMEND_IO_OK) continue;
            fprintf(fp, "%s{\"index\": %lld", i ? ", " : "", (long long)(i + 1));
            json_text_member(fp, 0, "uid", e.uid);
            json_text_member(fp, 0, "description", e.description);
            json_text_member(fp, 0, "modality", e.modality);
            fprintf(fp, ", \"number\": %lld, \"files\": %lld, \"images\": %lld, \"columns\": %lld, "
                        "\"rows\": %lld}",
                    (long long)e.number, (long long)e.files, (long long)e.images,
                    (long long)e.columns, (long long)e.rows);
        }
    }
#else
    (void)src;
#endif
    fprintf(fp, "]");
}

void cli_print_dicom(FILE *fp, cli_source *src, const cli_summary *sum)
{
#ifdef ISOMEND_HAVE_IO
    isomend_io_dicom d;
    if (!dicom_of(src, &d)) return;
    fprintf(fp, "  dicom:       %s \"%s\", %lld file%s%s, %s\n", d.modality[0] ? d.modality : "?",
            d.description, (long long)d.files, d.files == 1 ? "" : "s",
            d.multiframe ? " (multi-frame)" : "", d.transfer_syntax_name);
    fprintf(fp, "  ignored:     %lld DICOM object%s without pixel data, %lld file%s not DICOM, "
                "%lld file%s of other series\n",
            (long long)d.non_image, d.non_image == 1 ? "" : "s", (long long)d.non_dicom,
            d.non_dicom == 1 ? "" : "s", (long long)d.other_series, d.other_series == 1 ? "" : "s");
    cli_print_series(fp, src);
    fprintf(fp, "  values:      %d-bit %s %s", d.bits_stored, d.pixel_signed ? "signed" : "unsigned",
            d.photometric);
    if (strcmp(d.photometric, "MONOCHROME1") == 0) fprintf(fp, " (inverted: brighter is higher)");
    if (d.rescaled)
        fprintf(fp, ", rescaled: slope %g, intercept %g%s", d.rescale_slope, d.rescale_intercept,
                d.hounsfield ? " (HU)" : "");
    fputc('\n', fp);
    fprintf(fp, "  orientation: row %g, %g, %g; column %g, %g, %g; normal %g, %g, %g\n",
            d.orientation[0], d.orientation[1], d.orientation[2], d.orientation[3],
            d.orientation[4], d.orientation[5], d.normal[0], d.normal[1], d.normal[2]);
    fprintf(fp, "  position:    %g, %g, %g (slice 0, patient LPS mm)\n", d.position[0],
            d.position[1], d.position[2]);
    if (d.axes == ISOMEND_IO_AXES_GRID)
        fprintf(fp, "  axes:        grid (--grid-axes): x along the rows, y along the columns, z along "
                    "the slices, not rotated into patient space\n");
    else if (src->has_world)
        fprintf(fp, "  axes:        patient (LPS mm): the mesh is turned by the direction cosines "
                    "(world = position + R * index * spacing)\n");
    else
        fprintf(fp, "  axes:        patient (LPS mm): x to the patient's left, y posterior, z head\n");
    double lv[3];
    (void)sum;
    if (d.hounsfield && levels_of(src, lv))
        fprintf(fp, "  levels (HU): bone %.9g, skin %.9g, Otsu %.9g; extract uses bone unless --iso "
                    "skin|otsu|VALUE\n", lv[ISOMEND_IO_LEVEL_BONE], lv[ISOMEND_IO_LEVEL_SKIN],
                lv[ISOMEND_IO_LEVEL_OTSU]);
#else
    (void)fp;
    (void)src;
    (void)sum;
#endif
}

void cli_json_dicom(FILE *fp, cli_source *src, const cli_summary *sum)
{
#ifdef ISOMEND_HAVE_IO
    (void)sum;
    isomend_io_dicom d;
    if (!dicom_of(src, &d)) {
        fprintf(fp, "null");
        return;
    }
    fputc('{', fp);
    json_text_member(fp, 1, "modality", d.modality);
    json_text_member(fp, 0, "series_uid", d.series_uid);
    json_text_member(fp, 0, "description", d.description);
    json_text_member(fp, 0, "transfer_syntax", d.transfer_syntax);
    json_text_member(fp, 0, "photometric", d.photometric);
    fprintf(fp, ", \"bits_stored\": %d, \"signed\": %s, \"rescaled\": %s, \"rescale_slope\": %.17g, "
                "\"rescale_intercept\": %.17g, \"hounsfield\": %s",
            d.bits_stored, d.pixel_signed ? "true" : "false", d.rescaled ? "true" : "false",
            d.rescale_slope, d.rescale_intercept, d.hounsfield ? "true" : "false");
    fprintf(fp, ", \"orientation\": [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g]", d.orientation[0],
            d.orientation[1], d.orientation[2], d.orientation[3], d.orientation[4], d.orientation[5]);
    fprintf(fp, ", \"normal\": [%.17g, %.17g, %.17g], \"position\": [%.17g, %.17g, %.17g]",
            d.normal[0], d.normal[1], d.normal[2], d.position[0], d.position[1], d.position[2]);
    double lv[3];
    if (d.hounsfield && levels_of(src, lv))
        fprintf(fp, ", \"levels\": {\"bone\": %.17g, \"skin\": %.17g, \"otsu\": %.17g, "
                    "\"extract\": \"bone\"}",
                lv[ISOMEND_IO_LEVEL_BONE], lv[ISOMEND_IO_LEVEL_SKIN], lv[ISOMEND_IO_LEVEL_OTSU]);
    else
        fprintf(fp, ", \"levels\": null");
    fprintf(fp, ", \"files\": %lld, \"multiframe\": %s, \"non_image\": %lld, \"non_dicom\": %lld, "
                "\"other_series\": %lld, \"axes\": \"%s\", \"series\": ",
            (long long)d.files, d.multiframe ? "true" : "false", (long long)d.non_image,
            (long long)d.non_dicom, (long long)d.other_series,
            d.axes == ISOMEND_IO_AXES_GRID ? "grid" : "patient");
    cli_json_series(fp, src);
    fprintf(fp, "}");
#else
    (void)src;
    (void)sum;
    fprintf(fp, "null");
#endif
}

/* ------------------------------------------------------------------ NIfTI */

#ifdef ISOMEND_HAVE_IO
static int nifti_of(const cli_source *src, isomend_io_nifti *n)
{
    memset(n, 0, sizeof *n);
    n->size = sizeof *n;
    return src->io && strcmp(src->kind, "nifti") == 0 &&
           io_api.nifti_info((const isomend_io_source *)src->io, n) == ISOMEND_IO_OK;
}

static const char *nifti_axes_name(int axes)
{
    return axes == ISOMEND_IO_AXES_GRID ? "grid" : axes == ISOMEND_IO_AXES_RAS ? "ras" : "patient";
}
#endif

void cli_print_nifti(FILE *fp, const cli_source *src)
{
#ifdef ISOMEND_HAVE_IO
    isomend_io_nifti n;
    if (!nifti_of(src, &n)) return;
    if (n.version)
        fprintf(fp, "  nifti:       NIfTI-%d%s%s, datatype %s\n", n.version,
                n.two_files ? " (.hdr/.img pair)" : "", n.gzip ? ", gzip" : "", n.datatype);
    else
        fprintf(fp, "  nifti:       ANALYZE 7.5 (.hdr/.img pair)%s, datatype %s\n",
                n.gzip ? ", gzip" : "", n.datatype);
    if (n.scaled)
        fprintf(fp, "  values:      scaled: scl_slope %g, scl_inter %g\n", n.scl_slope, n.scl_inter);
    fprintf(fp, "  transform:   %s (sform_code %d, qform_code %d), (i, j, k) -> RAS mm:\n",
            n.transform, n.sform_code, n.qform_code);
    for (int r = 0; r < 3; r++)
        fprintf(fp, "               %12.6g %12.6g %12.6g %12.6g\n", n.file_affine[4 * r],
                n.file_affine[4 * r + 1], n.file_affine[4 * r + 2], n.file_affine[4 * r + 3]);
    if (n.axes == ISOMEND_IO_AXES_GRID)
        fprintf(fp, "  axes:        grid (--grid-axes): x = i, y = j, z = k, not mapped to the world\n");
    else if (n.axes == ISOMEND_IO_AXES_RAS)
        fprintf(fp, "  axes:        RAS mm (--ras): x right, y anterior, z superior, as FSL/FreeSurfer\n");
    else
        fprintf(fp, "  axes:        patient (LPS mm, as DICOM): x to the patient's left, y posterior, "
                    "z head (--ras for RAS)\n");
#else
    (void)fp;
    (void)src;
#endif
}

void cli_json_nifti(FILE *fp, const cli_source *src)
{
#ifdef ISOMEND_HAVE_IO
    isomend_io_nifti n;
    if (!nifti_of(src, &n)) {
        fprintf(fp, "null");
        return;
    }
    fprintf(fp, "{\"version\": %d, \"two_files\": %s, \"gzip\": %s", n.version,
            n.two_files ? "true" : "false", n.gzip ? "true" : "false");
    json_text_member(fp, 0, "header_path", n.header_path);
    json_text_member(fp, 0, "image_path", n.image_path);
    json_text_member(fp, 0, "datatype", n.datatype);
    fprintf(fp, ", \"scaled\": %s, \"scl_slope\": %.17g, \"scl_inter\": %.17g, \"sform_code\": %d, "
                "\"qform_code\": %d",
            n.scaled ? "true" : "false", n.scl_slope, n.scl_inter, n.sform_code, n.qform_code);
    json_text_member(fp, 0, "transform", n.transform);
    fprintf(fp, ", \"file_affine\": ");
    cli_json_doubles(fp, n.file_affine, 12);
    json_text_member(fp, 0, "axes", nifti_axes_name(n.axes));
    fputc('}', fp);
#else
    (void)src;
    fprintf(fp, "null");
#endif
}

void cli_source_view(const cli_slices *s, cli_source *view)
{
    memset(view, 0, sizeof *view);
    view->vol = s->desc;
    view->io = s->io;
    snprintf(view->kind, sizeof view->kind, "%s", s->kind);
    snprintf(view->format, sizeof view->format, "%s", s->format);
    for (int a = 0; a < 3; a++) view->spacing_from[a] = s->spacing_from[a];
    view->oblique = s->oblique;
    view->dicom = s->dicom;
    view->series_listed = s->series_listed;
    view->grid_axes = s->grid_axes;
    view->has_world = s->has_world;
    memcpy(view->world, s->world, sizeof view->world);
    view->geometry = s->geometry; /* the slice origins stay with s */
    view->read_ms = s->read_ms;
    snprintf(view->label, sizeof view->label, "%s", s->label);
}
