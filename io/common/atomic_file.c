/*
 * atomic_file.c - temporary file + rename for every output (see atomic_file.h)
 */
#define _POSIX_C_SOURCE 200809L

#include "atomic_file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

void isomend_fileio_set_msg(char *msg, size_t msg_size, const char *fmt, ...)
{
    if (!msg || msg_size == 0) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, msg_size, fmt, ap);
    va_end(ap);
}

isomend_fileio_status isomend_atomic_open(isomend_atomic_file *af, const char *path, char *msg,
                                          size_t msg_size)
{
    memset(af, 0, sizeof *af);
    if (!path || !*path) {
        isomend_fileio_set_msg(msg, msg_size, "empty output path");
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    size_t len = strlen(path);
    if (len >= sizeof af->final_path) {
        isomend_fileio_set_msg(msg, msg_size, "%.200s...: output path too long", path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (path[len - 1] == '/') {
        isomend_fileio_set_msg(msg, msg_size, "%s: output path is a folder, not a file", path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    struct stat st;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) {
        isomend_fileio_set_msg(msg, msg_size, "%s: output path is a folder, not a file", path);
        return ISOMEND_FILEIO_ERR_WRITE;
    }
    memcpy(af->final_path, path, len + 1);

    /* folder part and base name */
    const char *slash = strrchr(path, '/');
    char dir[ISOMEND_FILEIO_PATH_MAX];
    const char *base;
    if (slash) {
        size_t dlen = (size_t)(slash - path);
        if (dlen == 0) dlen = 1; /* "/name" */
        memcpy(dir, path, dlen);
        dir[dlen] = '\0';
        base = slash + 1;
    } else {
        strcpy(dir, ".");
        base = path;
    }

    int err = 0;
    for (unsigned attempt = 0; attempt < 100; attempt++) {
        snprintf(af->tmp_path, sizeof af->tmp_path, "%s%s.%s.%ld.%u.tmp",
                 slash ? dir : "", slash ? (strcmp(dir, "/") == 0 ? "" : "/") : "", base,
                 (long)getpid(), attempt);
        int fd = open(af->tmp_path, O_WRONLY | O_CREAT | O_EXCL, 0666);
        if (fd >= 0) {
            af->fp = fdopen(fd, "wb");
            if (!af->fp) {
                err = errno;
                close(fd);
                unlink(af->tmp_path);
                break;
            }
            return ISOMEND_FILEIO_OK;
        }
        err = errno;
        if (err != EEXIST) break;
    }
    isomend_fileio_set_msg(msg, msg_size, "%s: cannot create a file in folder '%s': %s", path, dir,
                           strerror(err));
    af->tmp_path[0] = '\0';
    return ISOMEND_FILEIO_ERR_WRITE;
}

isomend_fileio_status isomend_atomic_commit(isomend_atomic_file *af, char *msg, size_t msg_size)
{
    int failed = 0, err = 0;
    if (!af->fp) {
        isomend_fileio_set_msg(msg, msg_size, "%s: output is not open", af->final_path);
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    if (fflush(af->fp) != 0 || ferror(af->fp)) {
        failed = 1;
        err = errno;
    }
    if (fclose(af->fp) != 0 && !failed) {
        failed = 1;
        err = errno;
    }
    af->fp = NULL;
    if (!failed && rename(af->tmp_path, af->final_path) != 0) {
        failed = 1;
        err = errno;
    }
    if (failed) {
        unlink(af->tmp_path);
        isomend_fileio_set_msg(msg, msg_size, "%s: write failed: %s", af->final_path,
                               strerror(err ? err : EIO));
        return ISOMEND_FILEIO_ERR_WRITE;
    }
    return ISOMEND_FILEIO_OK;
}

void isomend_atomic_abort(isomend_atomic_file *af)
{
    if (af->fp) {
        fclose(af->fp);
        af->fp = NULL;
    }
    if (af->tmp_path[0]) unlink(af->tmp_path);
    af->tmp_path[0] = '\0';
}
