/*
 * importer.c - the slice-stack importer libisomend_io, loaded with dlopen()
 *
 * The importer is loaded only when a source needs it (image stacks, DICOM,
 * NIfTI): linking it would load OpenImageIO's ~260 shared libraries
 * (~0.3-0.7 s) on every start, even for `isomend check` or a NRRD file.
 * Search order, relative to this executable so that a build tree and an
 * installation never mix: $ISOMEND_IO_LIBRARY; <exe dir>/slices/<file> (the
 * build tree: build/io/isomend next to build/io/slices/);
 * <exe dir>/../<libdir>/<soname> (an installation); then the soname through
 * the normal library search.  The functions called are listed once,
 * CLI_IO_FUNCTIONS in importer.h.
 *
 * Without the importer (ISOMEND_HAVE_IO undefined) this file is empty.
 */
#define _POSIX_C_SOURCE 200809L

#include "importer.h"
#include "cli.h"

#ifdef ISOMEND_HAVE_IO
#include <dlfcn.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

cli_io_api cli_io;

int cli_io_load_library(char *why, size_t why_size)
{
    if (cli_io.handle) return 1;
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
        /* lazily bound: the importer pulls in OpenImageIO's and GDCM's trees (154 000
         * relocations); binding their functions on first call saves about 20 ms of a
         * run's start (a 2-slice TIFF folder: 0.21 s -> 0.19 s) */
        h = dlopen(candidates[i], RTLD_LAZY | RTLD_LOCAL);
        if (!h && !why[0]) {
            const char *e = dlerror();
            snprintf(why, why_size, "%s", e ? e : candidates[i]);
        }
    }
    if (!h) return 0;
    cli_io_api api;
    memset(&api, 0, sizeof api);
    /* a data pointer to a function pointer by its bytes (ISO C has no cast) */
#define CLI_IO_RESOLVE(name)                                                                       \
    do {                                                                                           \
        void *sym_ = dlsym(h, "isomend_io_" #name);                                                \
        if (!sym_) {                                                                               \
            snprintf(why, why_size, "symbol %s missing", "isomend_io_" #name);                     \
            dlclose(h);                                                                            \
            return 0;                                                                              \
        }                                                                                          \
        memcpy(&api.name, &sym_, sizeof sym_);                                                     \
    } while (0);
    CLI_IO_FUNCTIONS(CLI_IO_RESOLVE)
#undef CLI_IO_RESOLVE
    api.handle = h;
    cli_io = api;
    return 1;
}

int cli_io_failed(isomend_io_source *io, isomend_io_status st, const char *label)
{
    if (st == ISOMEND_IO_ERR_CANCELLED) {
        cli_error("%s: interrupted", label);
        return CLI_EXIT_INTERRUPTED;
    }
    const char *m = cli_io.message(io);
    cli_error("%s", m && *m ? m : cli_io.status_string(st));
    return st == ISOMEND_IO_ERR_INVALID_ARGUMENT ? CLI_EXIT_USAGE : CLI_EXIT_FAIL;
}
#endif
