/*
 * source_volume.c - the sources the command line reads itself: raw and NRRD
 * files (io/common) and the built-in F1/F2 of the thesis
 *
 * Raw and NRRD always go through io/common directly, never through the
 * importer, so that the CLI's own behaviour (and the sanitizer build, which
 * has no importer) is the same with and without the importer.  Opening
 * probes the file (no sample read) and describes the volume as
 * isomend_fileio_describe() will present it once loaded: a reversed NRRD axis
 * starts at its last sample.  --spacing and --origin override the file's.
 * Loading refuses a volume larger than the memory available before
 * allocating it; slices are read through isomend_fileio_slices_*, opened at
 * the first slice.
 */
#define _POSIX_C_SOURCE 200809L

#include "source_internal.h"

#include <stdlib.h>
#include <string.h>

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

/* --spacing and --origin over what the source says. */
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

int cli_volume_open_builtin(const cli_source_opts *o, cli_source *s)
{
    s->reader = CLI_READER_BUILTIN;
    isomend_volume_init(&s->desc, NULL, ISOMEND_F32, 4, 4, 4);
    snprintf(s->kind, sizeof s->kind, "builtin");
    snprintf(s->format, sizeof s->format, "generated");
    for (int a = 0; a < 3; a++) s->spacing_from[a] = "default";
    apply_overrides(o, &s->desc, s->spacing_from);
    return CLI_EXIT_OK;
}

int cli_volume_open_file(const char *path, const cli_source_opts *o, cli_source *s)
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
    s->reader = CLI_READER_FILE;
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

/* The samples into s->owned, described in s->desc. */
int cli_volume_load(cli_source *s)
{
    if (s->reader == CLI_READER_BUILTIN) {
        s->owned = malloc(sizeof s->builtin);
        if (!s->owned) {
            cli_error("%s: out of memory", s->label);
            return CLI_EXIT_FAIL;
        }
        memcpy(s->owned, s->builtin, sizeof s->builtin);
        s->desc.data = s->owned;
        return CLI_EXIT_OK;
    }
    /* refuse before allocating: Linux overcommits, so a too large malloc
     * would "succeed" and the kernel would kill us half-way through */
    uint64_t need = isomend_fileio_volume_bytes(&s->info), avail = cli_memory_available();
    if (avail && need > avail) {
        cli_error("%s: the volume needs %.1f MiB, only %.1f MiB of memory is available", s->label,
                  (double)need / 1048576.0, (double)avail / 1048576.0);
        return CLI_EXIT_FAIL;
    }
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    double t0 = cli_now_ms();
    isomend_fileio_status st = isomend_fileio_load(&s->info, &s->owned, cli_progress_read_cb,
                                                   s->progress, msg, sizeof msg);
    cli_progress_clear(s->progress);
    if (st == ISOMEND_FILEIO_ERR_CANCELLED) {
        cli_error("%s: interrupted", s->label);
        return CLI_EXIT_INTERRUPTED;
    }
    if (st != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        return CLI_EXIT_FAIL;
    }
    s->read_ms += cli_now_ms() - t0;
    isomend_volume v;
    isomend_fileio_describe(&s->info, s->owned, &v);
    for (int a = 0; a < 3; a++) { /* the overrides, as opened */
        v.spacing[a] = s->desc.spacing[a];
        v.origin[a] = s->desc.origin[a];
    }
    v.slice_origins = s->desc.slice_origins; /* --slice-positions */
    s->desc = v;
    return CLI_EXIT_OK;
}

int cli_source_reads_by_slice(const cli_source *s)
{
    /* gzip read backwards (a reversed z axis) is the one thing a file cannot do */
    return !(s->reader == CLI_READER_FILE && s->info.encoding == ISOMEND_FILEIO_ENC_GZIP &&
             s->info.axis_negative[2] && !s->info.oblique && s->info.dims[2] > 1);
}

int cli_volume_read_slice(cli_source *s, void *buffer)
{
    if (s->reader == CLI_READER_BUILTIN) {
        memcpy(buffer, s->builtin + 16 * s->next, 16 * sizeof(float));
        return CLI_EXIT_OK;
    }
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    isomend_fileio_status st = ISOMEND_FILEIO_OK;
    if (!s->file_slices)
        st = isomend_fileio_slices_open(&s->info, &s->file_slices, msg, sizeof msg);
    if (st == ISOMEND_FILEIO_OK)
        st = isomend_fileio_slices_next(s->file_slices, buffer, (size_t)s->slice_bytes, msg,
                                        sizeof msg);
    if (st != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        return CLI_EXIT_FAIL;
    }
    return CLI_EXIT_OK;
}

int cli_volume_seek(cli_source *s, int64_t k)
{
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    if (s->file_slices) {
        if (isomend_fileio_slices_seek(s->file_slices, k, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            return CLI_EXIT_FAIL;
        }
    } else if (s->reader == CLI_READER_FILE && k > 0) {
        if (isomend_fileio_slices_open(&s->info, &s->file_slices, msg, sizeof msg) !=
                ISOMEND_FILEIO_OK ||
            isomend_fileio_slices_seek(s->file_slices, k, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            return CLI_EXIT_FAIL;
        }
    }
    return CLI_EXIT_OK;
}
