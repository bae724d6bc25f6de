/*
 * atomic_file.h - output files that appear complete or not at all (internal)
 *
 * Every file isomend writes goes to a temporary file in the target folder
 * (".NAME.PID.N.tmp", created with O_EXCL and mode 0666 minus the umask, so
 * the final file gets the permissions a plain fopen would give) and is
 * renamed over the target only after every byte was written and the stream
 * closed without error.  rename() within one folder is atomic on POSIX, so
 * a reader never sees a partial mesh, and a failure leaves nothing behind.
 * Scratch files (isomend_spool_open) are unlinked as soon as they exist.
 */
#ifndef ISOMEND_ATOMIC_FILE_H
#define ISOMEND_ATOMIC_FILE_H

#include <stdio.h>

#include "fileio_status.h"

typedef struct isomend_atomic_file {
    FILE *fp;
    char final_path[ISOMEND_FILEIO_PATH_MAX];
    char tmp_path[ISOMEND_FILEIO_PATH_MAX + 64];
} isomend_atomic_file;

/* Creates the temporary file; on failure nothing exists and msg names `path`. */
isomend_fileio_status isomend_atomic_open(isomend_atomic_file *af, const char *path, char *msg,
                                          size_t msg_size);

/* Flushes, closes and renames; on failure removes the temporary file. */
isomend_fileio_status isomend_atomic_commit(isomend_atomic_file *af, char *msg, size_t msg_size);

/* Closes and removes the temporary file (after a write error). Accepts a closed file. */
void isomend_atomic_abort(isomend_atomic_file *af);

/*
 * A scratch file for data that is appended to an output at the end (the
 * faces of a PLY written while extracting): created in the folder of
 * `near_path` (where the output goes, so it uses that disk, not /tmp) as
 * ".NAME.PID.N.spool", opened read/write, and unlinked at once, so that it
 * vanishes when closed or when the process dies, whatever happens.
 */
isomend_fileio_status isomend_spool_open(const char *near_path, FILE **out, char *msg,
                                         size_t msg_size);

/* Formats "PATH: reason" style messages into msg (no-op when msg is NULL). */
void isomend_fileio_set_msg(char *msg, size_t msg_size, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

#endif /* ISOMEND_ATOMIC_FILE_H */
