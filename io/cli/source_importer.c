/*
 * source_importer.c - the sources read through the importer libisomend_io
 * (importer.c loads it): image stacks (folder, glob, printf pattern, list,
 * multi-page file), DICOM series and NIfTI volumes
 *
 * Opening resolves SOURCE and checks every header (the importer's
 * isomend_io_open), then takes over what the importer says: dims, type,
 * spacing and where it came from, origin, kind, the world map of a DICOM
 * series or a NIfTI volume, and where the slices lie.  --slice-positions of
 * a stack are handed to the importer, which applies the same rule as
 * source_geometry.c (and refuses them for a DICOM series, whose positions are
 * its own).  A volume the importer loads belongs to its handle; slices are
 * read with isomend_io_read_slice(), and the importer analyses a source
 * itself (value range, histogram, suggested level).
 *
 * Without the importer (ISOMEND_HAVE_IO undefined) this file is empty.
 */
#define _POSIX_C_SOURCE 200809L

#include "source_internal.h"

#ifdef ISOMEND_HAVE_IO
#include <string.h>

static int io_progress(void *user, int stage, double fraction)
{
    static const char *labels[] = {"open", "read", "analyse", "extract"};
    cli_progress_update(user, stage >= 0 && stage < 4 ? labels[stage] : "io", fraction);
    return cli_interrupted;
}

int cli_importer_open(const char *const *paths, int n, const cli_source_opts *o,
                      const double *positions, int64_t npositions, cli_source *s)
{
    isomend_io_source *io = NULL;
    char why[512];
    if (!cli_io_load_library(why, sizeof why)) {
        cli_error("%s: slice stacks need the importer library libisomend_io, which could not be "
                  "loaded (%s); set ISOMEND_IO_LIBRARY to its path", paths[0], why);
        return CLI_EXIT_FAIL;
    }
    if (cli_io.create(&io) != ISOMEND_IO_OK) {
        cli_error("%s: out of memory", paths[0]);
        return CLI_EXIT_FAIL;
    }
    isomend_io_options opts;
    cli_io.options_init(&opts);
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
    if (o->series) cli_io.set_series(io, o->series);
    if (o->grid_axes) cli_io.set_axes(io, ISOMEND_IO_AXES_GRID);
    if (o->ras) cli_io.set_axes(io, ISOMEND_IO_AXES_RAS);
    isomend_io_status st = cli_io.open(io, paths, (size_t)n, &opts);
    cli_progress_clear(o->progress);
    s->reader = CLI_READER_IMPORTER;
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
    if (st == ISOMEND_IO_OK) st = cli_io.dims(io, dims);
    if (st == ISOMEND_IO_OK) st = cli_io.type(io, &type);
    if (st == ISOMEND_IO_OK) st = cli_io.spacing(io, spacing, from);
    if (st == ISOMEND_IO_OK) st = cli_io.origin(io, origin);
    if (st != ISOMEND_IO_OK) {
        /* the importer names the parameter by its API name: say the option's */
        const char *m = cli_io.message(io), *api = "slice_positions: ";
        int rc;
        if (positions && m && strncmp(m, api, strlen(api)) == 0) {
            cli_error("--slice-positions: %s", m + strlen(api));
            rc = CLI_EXIT_USAGE;
        } else {
            rc = cli_io_failed(io, st, paths[0]);
        }
        cli_io.destroy(io);
        return rc;
    }
    s->io = io;
    isomend_volume_init(&s->desc, NULL, type, dims[0], dims[1], dims[2]);
    for (int a = 0; a < 3; a++) {
        s->desc.spacing[a] = spacing[a];
        s->desc.origin[a] = origin[a];
        const char *name = cli_io.spacing_source_name(from[a]);
        s->spacing_from[a] = name ? name : "?";
    }
    const char *kind = cli_io.kind_name(cli_io.source_kind(io));
    snprintf(s->kind, sizeof s->kind, "%s", kind ? kind : "?");
    snprintf(s->format, sizeof s->format, "%s", cli_io.format(io));
    s->dicom = cli_io.source_kind(io) == ISOMEND_IO_KIND_DICOM;
    s->grid_axes = o->grid_axes;
    int identity = 1;
    if (cli_io.world_transform(io, s->world, &identity) == ISOMEND_IO_OK) s->has_world = !identity;
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
    st = cli_io.geometry_info(io, &g);
    if (st != ISOMEND_IO_OK) return cli_io_failed(io, st, paths[0]);
    cli_geometry *cg = &s->geometry;
    if (positions) { /* the same rule and words as a raw volume's (the importer's rule) */
        cli_geometry_of_positions(positions, npositions, cg);
        cg->from = "--slice-positions";
        s->desc.slice_origins = cli_io.slice_origins(io);
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
    s->desc.slice_origins = cli_io.slice_origins(io);
    return CLI_EXIT_OK;
}

int cli_importer_load(cli_source *s)
{
    double seconds = 0;
    isomend_volume v;
    memset(&v, 0, sizeof v);
    isomend_io_status st = cli_io.load(s->io, &v, &seconds);
    cli_progress_clear(s->progress);
    if (st != ISOMEND_IO_OK) return cli_io_failed(s->io, st, s->label);
    s->desc = v; /* the samples belong to the handle */
    s->read_ms += seconds * 1e3;
    return CLI_EXIT_OK;
}

int cli_importer_read_slice(cli_source *s, void *buffer)
{
    isomend_io_status st = cli_io.read_slice(s->io, s->next, buffer, (size_t)s->slice_bytes);
    return st == ISOMEND_IO_OK ? CLI_EXIT_OK : cli_io_failed(s->io, st, s->label);
}

int cli_importer_summary(cli_source *s, cli_summary *sum)
{
    isomend_io_summary r;
    isomend_io_status st = cli_io.analyse(s->io, &r);
    if (st != ISOMEND_IO_OK) return cli_io_failed(s->io, st, "analysis");
    sum->min = r.min;
    sum->max = r.max;
    sum->samples = r.samples;
    sum->nan_samples = r.nan_samples;
    for (int b = 0; b < 16; b++) sum->histogram[b] = r.histogram[b];
    sum->suggested_iso = r.suggested_iso;
    sum->has_suggestion = r.max > r.min;
    return CLI_EXIT_OK;
}
#endif
