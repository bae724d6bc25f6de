/*
 * importer.h - the slice-stack importer libisomend_io as the command line
 * reaches it: loaded with dlopen() only when a source needs it (importer.c),
 * its functions in one table.  Used by the kind of source that reads through
 * it (source_importer.c, via source_internal.h) and by the reports.
 */
#ifndef ISOMEND_CLI_IMPORTER_H
#define ISOMEND_CLI_IMPORTER_H

#ifdef ISOMEND_HAVE_IO
#include "isomend_io.h"

#include <stddef.h>

/*
 * Every function of isomend_io.h the command line calls, listed once: the
 * table's members are declared from it (with the header's own types) and
 * resolved from it with dlsym("isomend_io_" NAME), in this order.
 */
#define CLI_IO_FUNCTIONS(X)                                                                        \
    X(status_string)                                                                               \
    X(create)                                                                                      \
    X(destroy)                                                                                     \
    X(message)                                                                                     \
    X(options_init)                                                                                \
    X(open)                                                                                        \
    X(load)                                                                                        \
    X(analyse)                                                                                     \
    X(spacing)                                                                                     \
    X(spacing_source_name)                                                                         \
    X(kind_name)                                                                                   \
    X(source_kind)                                                                                 \
    X(format)                                                                                      \
    X(dims)                                                                                        \
    X(type)                                                                                        \
    X(origin)                                                                                      \
    X(read_slice)                                                                                  \
    X(set_series)                                                                                  \
    X(set_axes)                                                                                    \
    X(series_count)                                                                                \
    X(series_get)                                                                                  \
    X(series_chosen)                                                                               \
    X(dicom_info)                                                                                  \
    X(nifti_info)                                                                                  \
    X(world_transform)                                                                             \
    X(level_value)                                                                                 \
    X(suggested_level)                                                                             \
    X(geometry_info)                                                                               \
    X(slice_origins)

/* cli_io.NAME is isomend_io_NAME once cli_io_load_library() succeeded. */
typedef struct cli_io_api {
    void *handle;
#define CLI_IO_MEMBER(name) __typeof__(isomend_io_##name) *name;
    CLI_IO_FUNCTIONS(CLI_IO_MEMBER)
#undef CLI_IO_MEMBER
} cli_io_api;
extern cli_io_api cli_io;

/* Loads the importer once; 0 and the reason in why[] when it cannot. */
int cli_io_load_library(char *why, size_t why_size);
/* The importer's message (or the status) printed, naming `label` for an
 * interruption; the exit code (2 for an invalid argument). */
int cli_io_failed(isomend_io_source *io, isomend_io_status st, const char *label);

#endif

#endif /* ISOMEND_CLI_IMPORTER_H */
