/*
 * source_internal.h - what the files of an opened SOURCE share (source.c,
 * source_volume.c, source_importer.c, source_geometry.c,
 * source_summary.c, source_report.c); the rest of the command line sees only
 * cli.h.
 *
 * source.c decides which kind SOURCE is and calls the kind's file to open
 * it, load it and read its slices; those files fill a cli_source and never
 * print anything but the messages of their failures.
 */
#ifndef ISOMEND_CLI_SOURCE_INTERNAL_H
#define ISOMEND_CLI_SOURCE_INTERNAL_H

#include "cli.h"

/* ---- source_geometry.c ---- */

/* A uniform grid's geometry: every gap the z spacing. */
void cli_geometry_uniform(const isomend_volume *v, cli_geometry *g);
/* Raw, NRRD, built-in: --slice-positions z[0..n) become the grid's (checked
 * against its slices): spacing and origin z, or a slice origins table. */
int cli_apply_positions(cli_source *s, const double *z, int64_t n);

/* ---- source_volume.c: raw, NRRD, built-in ---- */

/* s->builtin holds the samples already (cli_builtin_volume). */
int cli_volume_open_builtin(const cli_source_opts *o, cli_source *s);
/* Raw (o->have_raw) or NRRD: the probe, no sample read. */
int cli_volume_open_file(const char *path, const cli_source_opts *o, cli_source *s);
int cli_volume_load(cli_source *s);
int cli_volume_read_slice(cli_source *s, void *buffer); /* slice s->next */
int cli_volume_seek(cli_source *s, int64_t k);

#ifdef ISOMEND_HAVE_IO
#include "importer.h"

/* ---- source_importer.c: image stacks, DICOM, NIfTI ---- */

int cli_importer_open(const char *const *paths, int n, const cli_source_opts *o,
                      const double *positions, int64_t npositions, cli_source *s);
int cli_importer_load(cli_source *s);
int cli_importer_read_slice(cli_source *s, void *buffer); /* slice s->next */
/* The importer's analysis (it streams the slices itself when nothing is loaded). */
int cli_importer_summary(cli_source *s, cli_summary *sum);
#endif

#endif /* ISOMEND_CLI_SOURCE_INTERNAL_H */
