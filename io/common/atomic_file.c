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

/*
 * Splits `path` into its folder ("." when it has none) and base name, and
 * formats temporary name number `attempt` in that folder:
 * "FOLDER/.BASE.PID.ATTEMPT.SUFFIX".  Returns 0, or -1 if the path is empty,
 * too long or names a folder (the message then says so).
 */
static int temp_name(const char *path, unsigned attempt, const char *suffix, char *dir,
                     size_t dir_size, char *out, size_t out_size, char *msg, size_t msg_size)
{
    if (!path || !*path) {
        isomend_fileio_set_msg(msg, msg_size, "empty output path");
        return -1;
    }
    size_t len = strlen(path);
    if (len >= ISOMEND_FILEIO_PATH_MAX) {
        isomend_fileio_set_msg(msg, msg_size, "%.200s...: output path too long", path);
        return -1;
    }
    if (path[len - 1] == '/') {
        isomend_fileio_set_msg(msg, msg_size, "%s: output path is a folder, not a file", path);
        return -1;
    }
    const char *slash = strrchr(path, '/');
    const char *base;
    if (slash) {
        size_t dlen = (size_t)(slash - path);
        if (dlen == 0) dlen = 1; /* "/name" */
        if (dlen >= dir_size) dlen = dir_size - 1;
        memcpy(dir, path, dlen);
        dir[dlen] = '\0';
        base = slash + 1;
    } else {
        snprintf(dir, dir_size, ".");
        base = path;
    }
    snprintf(out, out_size, "%s%s.%s.%ld.%u.%s", slash ? dir : "",
             slash ? (strcmp(dir, "/") == 0 ? "" : "/") : "", base, (long)getpid(), attempt, suffix);
    return 0;
}

/* Creates a new file for temporary name `suffix` next to `path` (O_EXCL). */
static int create_temp(const char *path, const char *suffix, int flags, char *tmp_path,
                       size_t tmp_size, char *msg, size_t msg_size)
{
    char dir[ISOMEND_FILEIO_PATH_MAX];
    int err = 0;
    for (unsigned attempt = 0; attempt < 100; attempt++) {
        if (temp_name(path, attempt, suffix, dir, sizeof dir, tmp_path, tmp_size, msg, msg_size))
            return -2;
        int fd = open(tmp_path, flags | O_CREAT | O_EXCL, 0666);
        if (fd >= 0) return fd;
        err = errno;
        if (err != EEXIST) break;
    }
    isomend_fileio_set_msg(msg, msg_size, "%s: cannot create a file in folder '%s': %s", path, dir,
                           strerror(err));
    tmp_path[0] = '\0';
    return -1;
}

isomend_fileio_status isomend_atomic_open(isomend_atomic_file *af, const char *path, char *msg,
                                          size_t msg_size)
{
    memset(af, 0, sizeof *af);
    char dir[ISOMEND_FILEIO_PATH_MAX];
    if (temp_name(path, 0, "tmp", dir, sizeof dir, af->tmp_path, sizeof af->tmp_path, msg,
                  msg_size)) {
        af->tmp_path[0] = '\0';
        return ISOMEND_FILEIO_ERR_INVALID_ARGUMENT;
    }
    struct stat st;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode)) {
        isomend_fileio_set_msg(msg, msg_size, "%s: output path is a folder, not a file", path);
        af->tmp_path[0] = '\0';
        return ISOMEND_FILEIO_ERR_WRITE;
    }
    memcpy(af->final_path, path, strlen(path) + 1);
    int fd = create_temp(path, "tmp", O_WRONLY, af->tmp_path, sizeof af->tmp_path, msg, msg_size);
    if (fd < 0) return ISOMEND_FILEIO_ERR_WRITE;
    af->fp = fdopen(fd, "wb");
    if (!af->fp) {
        int err = errno;
        close(fd);
        unlink(af->tmp_path);
        af->tmp_path[0] = '\0';
        isomend_fileio_set_msg(msg, msg_size, "%s: %s", path, strerror(err));
        return ISOMEND_FILEIO_ERR_WRITE;
    }
    return ISOMEND_FILEIO_OK;
}

isomend_fileio_status isomend_spool_open(const char *near_path, FILE **out, char *msg,
                                         size_t msg_size)
{
    char tmp[ISOMEND_FILEIO_PATH_MAX + 64];
    *out = NULL;
    int fd = create_temp(near_path, "spool", O_RDWR, tmp, sizeof tmp, msg, msg_size);
    if (fd < 0) return fd == -2 ? ISOMEND_FILEIO_ERR_INVALID_ARGUMENT : ISOMEND_FILEIO_ERR_WRITE;
    unlink(tmp); /* anonymous from now on: nothing is left behind, whatever happens */
    *out = fdopen(fd, "w+b");
    if (!*out) {
        int err = errno;
        close(fd);
        isomend_fileio_set_msg(msg, msg_size, "%s: %s", near_path, strerror(err));
        return ISOMEND_FILEIO_ERR_WRITE;
    }
    return ISOMEND_FILEIO_OK;
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
    if (failed) unlink(af->tmp_path);
    af->tmp_path[0] = '\0'; /* renamed or removed: nothing for an abort to remove */
    if (failed) {
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
