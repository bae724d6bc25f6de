/*
 * source.c - an opened SOURCE (cli_source): which kind it is, the options
 * checked against it, its slices one at a time or its samples loaded, closed
 *
 * One function decides what SOURCE is, so that each kind is a few lines:
 *   builtin:f1, builtin:f2   the thesis's test volumes (chapter 5.2), generated
 *   --raw NX,NY,NZ:TYPE      a headerless file (io/common)
 *   *.nrrd, *.nhdr           NRRD (io/common)
 *   anything else            the slice-stack importer isomend_io when this
 *                            build has it (folder, glob, printf pattern, list,
 *                            multi-page file, DICOM, NIfTI), else a clear error.
 * The kinds live in their own files: source_volume.c (raw, NRRD, built-in),
 * source_importer.c (through the importer, which importer.c loads), and
 * --slice-positions with the slices' geometry in source_geometry.c.
 *
 * A source opens in mode CLI_SOURCE_SLICES (nothing read; slices on demand
 * through cli_slices_next, in z order) and may then be loaded
 * (CLI_SOURCE_LOADED: desc.data holds the samples).  The description, the
 * slices' geometry and the DICOM facts stay the same; a caller streams, loads,
 * or both, from the one object.  Every source gets a cli_geometry and its
 * one-line warning, which the caller prints.
 */
#define _POSIX_C_SOURCE 200809L

#include "source_internal.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* cli_source_open's dispatch; on failure the caller closes s. */
static int open_kind(const char *const *paths, int n, const cli_source_opts *o,
                     const double *positions, int64_t npositions, cli_source *s)
{
    int stack_opts = o->have_first || o->have_count || o->have_step || o->have_channel;
    int rc;
    if (n == 1 && cli_builtin_volume(paths[0], s->builtin)) {
        if (o->have_raw || stack_opts) {
            cli_error("%s: --raw/--first/--count/--step/--channel do not apply to a built-in volume",
                      paths[0]);
            return CLI_EXIT_USAGE;
        }
        rc = cli_volume_open_builtin(o, s);
    } else if (strncmp(paths[0], "builtin:", 8) == 0) {
        cli_error("%s: unknown built-in volume (builtin:f1 or builtin:f2)", paths[0]);
        return CLI_EXIT_USAGE;
    } else if (n == 1 && (o->have_raw || isomend_fileio_is_nrrd_path(paths[0]))) {
        if (stack_opts) {
            cli_error("%s: --first/--count/--step/--channel only apply to slice stacks", paths[0]);
            return CLI_EXIT_USAGE;
        }
        rc = cli_volume_open_file(paths[0], o, s);
    } else {
#ifdef ISOMEND_HAVE_IO
        if (o->have_raw) {
            cli_error("--raw describes one file, got %d sources", n);
            return CLI_EXIT_USAGE;
        }
        rc = cli_importer_open(paths, n, o, positions, npositions, s);
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
        return rc; /* the importer placed the slices itself */
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
    /* raw, NRRD, built-in: evenly spaced, unless --slice-positions says otherwise */
    if (rc == CLI_EXIT_OK) cli_geometry_uniform(&s->desc, &s->geometry);
    if (rc == CLI_EXIT_OK && positions) rc = cli_apply_positions(s, positions, npositions);
    return rc;
}

int cli_source_open(const char *const *paths, int n, const cli_source_opts *o, cli_source *s)
{
    memset(s, 0, sizeof *s);
    s->mode = CLI_SOURCE_SLICES;
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
    int rc = open_kind(paths, n, o, positions, npositions, s);
    free(positions);
    if (rc) {
        cli_source_close(s);
        return rc;
    }
    s->slice_bytes = (uint64_t)s->desc.dims[0] * (uint64_t)s->desc.dims[1] *
                     isomend_type_size(s->desc.type);
    return CLI_EXIT_OK;
}

int cli_source_load(cli_source *s)
{
    if (s->mode == CLI_SOURCE_LOADED) return CLI_EXIT_OK;
    int rc;
#ifdef ISOMEND_HAVE_IO
    if (s->reader == CLI_READER_IMPORTER)
        rc = cli_importer_load(s);
    else
#endif
        rc = cli_volume_load(s);
    if (rc) return rc;
    s->mode = CLI_SOURCE_LOADED; /* the slices still come from the reader, where they were */
    return CLI_EXIT_OK;
}

void cli_source_drop_samples(cli_source *s)
{
    if (!s || !s->owned) return; /* an importer's volume stays with its handle */
    free(s->owned);
    s->owned = NULL;
    /* the opened description again: no data, contiguous slices */
    isomend_volume v = s->desc;
    isomend_volume_init(&s->desc, NULL, v.type, v.dims[0], v.dims[1], v.dims[2]);
    memcpy(s->desc.spacing, v.spacing, sizeof v.spacing);
    memcpy(s->desc.origin, v.origin, sizeof v.origin);
    s->desc.slice_origins = v.slice_origins;
    s->mode = CLI_SOURCE_SLICES;
}

void cli_source_close(cli_source *s)
{
    if (!s) return;
    isomend_fileio_slices_close(s->file_slices);
    free(s->owned);
    free(s->origins_owned);
#ifdef ISOMEND_HAVE_IO
    if (s->io) cli_io.destroy(s->io);
#endif
    memset(s, 0, sizeof *s);
}

/* ------------------------------------------------------------------ slice by slice */

/* Slice s->next of the loaded samples into `buffer`, x fastest, through the
 * volume's strides (a reversed axis runs backwards in memory). */
static void copy_loaded_slice(const cli_source *s, void *buffer)
{
    const isomend_volume *d = &s->desc;
    const size_t size = isomend_type_size(d->type);
    int64_t st[3] = {d->strides[0], d->strides[1], d->strides[2]};
    if (!st[0] && !st[1] && !st[2]) {
        st[0] = (int64_t)size;
        st[1] = st[0] * d->dims[0];
        st[2] = st[1] * d->dims[1];
    }
    const char *plane = (const char *)d->data + s->next * st[2];
    char *out = buffer;
    for (int64_t j = 0; j < d->dims[1]; j++) {
        const char *row = plane + j * st[1];
        if (st[0] == (int64_t)size) {
            memcpy(out, row, size * (size_t)d->dims[0]);
            out += size * (size_t)d->dims[0];
        } else {
            for (int64_t i = 0; i < d->dims[0]; i++, out += size)
                memcpy(out, row + i * st[0], size);
        }
    }
}

int cli_slices_next(cli_source *s, void *buffer)
{
    if (s->next >= s->desc.dims[2]) {
        cli_error("%s: no slice %lld (internal error)", s->label, (long long)s->next);
        return CLI_EXIT_FAIL;
    }
    if (s->mode == CLI_SOURCE_LOADED) { /* from memory, as isomend_extract() reads it */
        copy_loaded_slice(s, buffer);
        s->next++;
        return CLI_EXIT_OK;
    }
    double t0 = cli_now_ms();
    int rc;
#ifdef ISOMEND_HAVE_IO
    if (s->reader == CLI_READER_IMPORTER)
        rc = cli_importer_read_slice(s, buffer);
    else
#endif
        rc = cli_volume_read_slice(s, buffer);
    s->read_ms += cli_now_ms() - t0;
    if (rc == CLI_EXIT_OK) s->next++;
    return rc;
}

int cli_slices_seek(cli_source *s, int64_t k)
{
    if (k < 0 || k > s->desc.dims[2]) {
        cli_error("%s: no slice %lld (internal error)", s->label, (long long)k);
        return CLI_EXIT_FAIL;
    }
    if (s->reader == CLI_READER_FILE) {
        int rc = cli_volume_seek(s, k);
        if (rc) return rc;
    }
    s->next = k;
    return CLI_EXIT_OK;
}

void cli_slices_rewind(cli_source *s)
{
    isomend_fileio_slices_close(s->file_slices); /* the next slice opens it again */
    s->file_slices = NULL;
    s->next = 0;
}

/*
 * The start shared by `extract`, `info` and their --labels forms: prepares the --json output, sets
 * up the progress bar (stderr a terminal and not --quiet) and opens SOURCE
 * (no sample read yet), then prints the slices' geometry warning if any
 * (stderr, even with --quiet: it is about the result).  On failure nothing
 * is left open and the exit code is returned.
 */
int cli_open_source_for(cli_args *a, int quiet, cli_json_out *jo, cli_progress *bar, cli_source *s)
{
    int rc = cli_json_prepare(jo, a->json);
    if (rc) return rc;
    cli_progress_init(bar, !quiet && isatty(STDERR_FILENO));
    cli_active_progress = bar;
    a->src.progress = bar;
    rc = cli_source_open(a->positional, a->npositional, &a->src, s);
    if (rc)
        cli_json_abort(jo);
    else /* uneven gaps, a missing slice: said once, the mesh is still made */
        cli_print_geometry_warning(s->label, &s->geometry);
    return rc;
}
