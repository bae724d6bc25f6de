/*
 * source_geometry.c - where a source's slices lie: --slice-positions and the
 * slices' geometry (gaps, the warning line)
 *
 * --slice-positions gives the z of every slice, for volumes whose slices are
 * not evenly spaced (microscopy with variable steps, re-sliced data).  It is
 * parsed when SOURCE opens (source.c): raw, NRRD and built-in volumes get
 * their slice origins table here, (origin x, origin y, z_k) for slice k;
 * image stacks hand the positions to the importer, which applies the same
 * rule (source_importer.c).  Positions evenly spaced within 1e-6 of their
 * mean gap are a uniform grid: spacing = the mean gap, origin z = the first,
 * no table, so that the mesh is the evenly spaced one byte for byte.  The
 * table lives in cli_source.desc, so that the streamed path, the loaded
 * volume and isomend-mpi's slabs mesh from it.
 *
 * Every source gets a cli_geometry (a DICOM series' from the importer) and
 * its one-line warning: gaps that differ from the median by more than 1 %,
 * or a gap over 1.5x the median (a missing slice?).
 */
#define _POSIX_C_SOURCE 200809L

#include "source_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

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

void cli_geometry_uniform(const isomend_volume *v, cli_geometry *g)
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

int cli_apply_positions(cli_source *s, const double *z, int64_t n)
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
