/*
 * source.c - SOURCE to an isomend_volume
 *
 * One function decides what SOURCE is, so that each kind is a few lines:
 *   builtin:f1, builtin:f2   the thesis's test volumes (chapter 5.2), generated
 *   --raw NX,NY,NZ:TYPE      a headerless file (io/common)
 *   *.nrrd, *.nhdr           NRRD (io/common)
 *   anything else            the slice-stack importer isomend_io when this
 *                            build has it (folder, glob, printf pattern, list,
 *                            multi-page file), else a clear error.
 * Raw and NRRD always go through io/common directly, so that the CLI's own
 * behaviour (and the sanitizer build, which has no importer) is the same
 * with and without the importer.
 *
 * The suggested iso level follows the importer's documented rule (Otsu on a
 * 256-bin histogram of the finite samples; integer types moved to
 * floor(t) + 0.5 so that no sample equals the level); for importer sources
 * the importer computes it itself.
 */
#define _POSIX_C_SOURCE 200809L

#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "volume_readers.h"

#ifdef ISOMEND_HAVE_IO
#include <dlfcn.h>
#include <unistd.h>

#include "isomend_io.h"

/*
 * The importer is loaded with dlopen() only when a slice-stack source needs
 * it: linking it would load OpenImageIO's ~260 shared libraries (~0.3-0.7 s)
 * on every start, even for `isomend check` or a NRRD file.  Search order,
 * relative to this executable so that a build tree and an installation never
 * mix: $ISOMEND_IO_LIBRARY; <exe dir>/slices/<file> (the build tree:
 * build/io/isomend next to build/io/slices/); <exe dir>/../<libdir>/<soname>
 * (an installation); then the soname through the normal library search.
 */
static struct io_api {
    void *handle;
    const char *(*status_string)(isomend_io_status);
    isomend_io_status (*create)(isomend_io_source **);
    void (*destroy)(isomend_io_source *);
    const char *(*message)(const isomend_io_source *);
    void (*options_init)(isomend_io_options *);
    isomend_io_status (*open)(isomend_io_source *, const char *const *, size_t,
                              const isomend_io_options *);
    isomend_io_status (*load)(isomend_io_source *, isomend_volume *, double *);
    isomend_io_status (*analyse)(isomend_io_source *, isomend_io_summary *);
    isomend_io_status (*spacing)(const isomend_io_source *, double *, int *);
    const char *(*spacing_source_name)(int);
    const char *(*kind_name)(int);
    int (*source_kind)(const isomend_io_source *);
    const char *(*format)(const isomend_io_source *);
    isomend_io_status (*dims)(const isomend_io_source *, int64_t *);
    isomend_io_status (*type)(const isomend_io_source *, isomend_type *);
    isomend_io_status (*origin)(const isomend_io_source *, double *);
    isomend_io_status (*read_slice)(isomend_io_source *, int64_t, void *, size_t);
    isomend_io_status (*set_series)(isomend_io_source *, const char *);
    isomend_io_status (*set_axes)(isomend_io_source *, int);
    int64_t (*series_count)(const isomend_io_source *);
    isomend_io_status (*series_get)(const isomend_io_source *, int64_t, isomend_io_series *);
    int64_t (*series_chosen)(const isomend_io_source *);
    isomend_io_status (*dicom_info)(const isomend_io_source *, isomend_io_dicom *);
    isomend_io_status (*world_transform)(const isomend_io_source *, double *, int *);
    isomend_io_status (*level_value)(isomend_io_source *, int, double *);
    int (*suggested_level)(const isomend_io_source *);
} io_api;

static int io_load_api(char *why, size_t why_size)
{
    if (io_api.handle) return 1;
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
        h = dlopen(candidates[i], RTLD_NOW | RTLD_LOCAL);
        if (!h && !why[0]) {
            const char *e = dlerror();
            snprintf(why, why_size, "%s", e ? e : candidates[i]);
        }
    }
    if (!h) return 0;
#define IO_SYM(field, name)                                                                        \
    do {                                                                                           \
        void *sym_ = dlsym(h, name);                                                               \
        if (!sym_) {                                                                               \
            snprintf(why, why_size, "symbol %s missing", name);                                    \
            dlclose(h);                                                                            \
            return 0;                                                                              \
        }                                                                                          \
        memcpy(&io_api.field, &sym_, sizeof sym_);                                                 \
    } while (0)
    IO_SYM(status_string, "isomend_io_status_string");
    IO_SYM(create, "isomend_io_create");
    IO_SYM(destroy, "isomend_io_destroy");
    IO_SYM(message, "isomend_io_message");
    IO_SYM(options_init, "isomend_io_options_init");
    IO_SYM(open, "isomend_io_open");
    IO_SYM(load, "isomend_io_load");
    IO_SYM(analyse, "isomend_io_analyse");
    IO_SYM(spacing, "isomend_io_spacing");
    IO_SYM(spacing_source_name, "isomend_io_spacing_source_name");
    IO_SYM(kind_name, "isomend_io_kind_name");
    IO_SYM(source_kind, "isomend_io_source_kind");
    IO_SYM(format, "isomend_io_format");
    IO_SYM(dims, "isomend_io_dims");
    IO_SYM(type, "isomend_io_type");
    IO_SYM(origin, "isomend_io_origin");
    IO_SYM(read_slice, "isomend_io_read_slice");
    IO_SYM(set_series, "isomend_io_set_series");
    IO_SYM(set_axes, "isomend_io_set_axes");
    IO_SYM(series_count, "isomend_io_series_count");
    IO_SYM(series_get, "isomend_io_series_get");
    IO_SYM(series_chosen, "isomend_io_series_chosen");
    IO_SYM(dicom_info, "isomend_io_dicom_info");
    IO_SYM(world_transform, "isomend_io_world_transform");
    IO_SYM(level_value, "isomend_io_level_value");
    IO_SYM(suggested_level, "isomend_io_suggested_level");
#undef IO_SYM
    io_api.handle = h;
    return 1;
}
#endif

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

uint64_t cli_memory_available(void)
{
    return cli_proc_kib("/proc/meminfo", "MemAvailable:") * 1024u;
}

/* Raw and NRRD: the probe (no sample read). */
static int open_fileio(const char *path, const cli_source_opts *o, cli_slices *s)
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
    s->is_fileio = 1;
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

#ifdef ISOMEND_HAVE_IO
static int io_progress(void *user, int stage, double fraction)
{
    static const char *labels[] = {"open", "read", "analyse", "extract"};
    cli_progress_update(user, stage >= 0 && stage < 4 ? labels[stage] : "io", fraction);
    return cli_interrupted;
}

static int io_failed(isomend_io_source *io, isomend_io_status st, const char *label)
{
    if (st == ISOMEND_IO_ERR_CANCELLED) {
        cli_error("%s: interrupted", label);
        return CLI_EXIT_INTERRUPTED;
    }
    const char *m = io_api.message(io);
    cli_error("%s", m && *m ? m : io_api.status_string(st));
    return st == ISOMEND_IO_ERR_INVALID_ARGUMENT ? CLI_EXIT_USAGE : CLI_EXIT_FAIL;
}

/* Image stacks: the importer resolves the source and checks every header. */
static int open_io(const char *const *paths, int n, const cli_source_opts *o, cli_slices *s)
{
    isomend_io_source *io = NULL;
    char why[512];
    if (!io_load_api(why, sizeof why)) {
        cli_error("%s: slice stacks need the importer library libisomend_io, which could not be "
                  "loaded (%s); set ISOMEND_IO_LIBRARY to its path", paths[0], why);
        return CLI_EXIT_FAIL;
    }
    if (io_api.create(&io) != ISOMEND_IO_OK) {
        cli_error("%s: out of memory", paths[0]);
        return CLI_EXIT_FAIL;
    }
    isomend_io_options opts;
    io_api.options_init(&opts);
    if (o->have_first) opts.first = o->first;
    if (o->have_count) opts.count = o->count;
    if (o->have_step) opts.step = o->step;
    if (o->have_channel) opts.channel = o->channel;
    if (o->have_spacing)
        for (int a = 0; a < 3; a++) opts.spacing[a] = o->spacing[a];
    if (o->have_origin)
        for (int a = 0; a < 3; a++) opts.origin[a] = o->origin[a];
    opts.threads = o->threads;
    opts.progress = io_progress; /* also how Ctrl-C cancels */
    opts.progress_user = o->progress;
    if (o->series) io_api.set_series(io, o->series);
    if (o->grid_axes) io_api.set_axes(io, ISOMEND_IO_AXES_GRID);
    isomend_io_status st = io_api.open(io, paths, (size_t)n, &opts);
    cli_progress_clear(o->progress);
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
    if (st == ISOMEND_IO_OK) st = io_api.dims(io, dims);
    if (st == ISOMEND_IO_OK) st = io_api.type(io, &type);
    if (st == ISOMEND_IO_OK) st = io_api.spacing(io, spacing, from);
    if (st == ISOMEND_IO_OK) st = io_api.origin(io, origin);
    if (st != ISOMEND_IO_OK) {
        int rc = io_failed(io, st, paths[0]);
        io_api.destroy(io);
        return rc;
    }
    s->io = io;
    isomend_volume_init(&s->desc, NULL, type, dims[0], dims[1], dims[2]);
    for (int a = 0; a < 3; a++) {
        s->desc.spacing[a] = spacing[a];
        s->desc.origin[a] = origin[a];
        const char *name = io_api.spacing_source_name(from[a]);
        s->spacing_from[a] = name ? name : "?";
    }
    const char *kind = io_api.kind_name(io_api.source_kind(io));
    snprintf(s->kind, sizeof s->kind, "%s", kind ? kind : "?");
    snprintf(s->format, sizeof s->format, "%s", io_api.format(io));
    s->dicom = io_api.source_kind(io) == ISOMEND_IO_KIND_DICOM;
    s->grid_axes = o->grid_axes;
    int identity = 1;
    if (io_api.world_transform(io, s->world, &identity) == ISOMEND_IO_OK) s->has_world = !identity;
    return CLI_EXIT_OK;
}
#endif

int cli_slices_open(const char *const *paths, int n, const cli_source_opts *o, cli_slices *s)
{
    memset(s, 0, sizeof *s);
    snprintf(s->label, sizeof s->label, "%s", paths[0]);
    s->progress = o->progress;
    int stack_opts = o->have_first || o->have_count || o->have_step || o->have_channel;
    if ((o->series || o->grid_axes) &&
        ((n == 1 && (o->have_raw || isomend_fileio_is_nrrd_path(paths[0]))) ||
         strncmp(paths[0], "builtin:", 8) == 0)) {
        cli_error("%s: --series and --grid-axes apply to DICOM series only", paths[0]);
        return CLI_EXIT_USAGE;
    }
    int rc;
    if (n == 1 && cli_builtin_volume(paths[0], s->builtin)) {
        if (o->have_raw || stack_opts) {
            cli_error("%s: --raw/--first/--count/--step/--channel do not apply to a built-in volume",
                      paths[0]);
            return CLI_EXIT_USAGE;
        }
        s->is_builtin = 1;
        isomend_volume_init(&s->desc, NULL, ISOMEND_F32, 4, 4, 4);
        snprintf(s->kind, sizeof s->kind, "builtin");
        snprintf(s->format, sizeof s->format, "generated");
        for (int a = 0; a < 3; a++) s->spacing_from[a] = "default";
        apply_overrides(o, &s->desc, s->spacing_from);
        rc = CLI_EXIT_OK;
    } else if (strncmp(paths[0], "builtin:", 8) == 0) {
        cli_error("%s: unknown built-in volume (builtin:f1 or builtin:f2)", paths[0]);
        return CLI_EXIT_USAGE;
    } else if (n == 1 && (o->have_raw || isomend_fileio_is_nrrd_path(paths[0]))) {
        if (stack_opts) {
            cli_error("%s: --first/--count/--step/--channel only apply to slice stacks", paths[0]);
            return CLI_EXIT_USAGE;
        }
        rc = open_fileio(paths[0], o, s);
    } else {
#ifdef ISOMEND_HAVE_IO
        if (o->have_raw) {
            cli_error("--raw describes one file, got %d sources", n);
            return CLI_EXIT_USAGE;
        }
        rc = open_io(paths, n, o, s);
        if (rc == CLI_EXIT_OK && !s->dicom && (o->series || o->grid_axes)) {
            cli_error("%s: --series and --grid-axes apply to DICOM series only (this is a %s "
                      "source)", paths[0], s->kind);
            cli_slices_close(s);
            return CLI_EXIT_USAGE;
        }
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
    if (rc) return rc;
    s->slice_bytes = (uint64_t)s->desc.dims[0] * (uint64_t)s->desc.dims[1] *
                     isomend_type_size(s->desc.type);
    return CLI_EXIT_OK;
}

int cli_slices_next(cli_slices *s, void *buffer)
{
    if (s->next >= s->desc.dims[2]) {
        cli_error("%s: no slice %lld (internal error)", s->label, (long long)s->next);
        return CLI_EXIT_FAIL;
    }
    double t0 = cli_now_ms();
    int rc = CLI_EXIT_OK;
    if (s->is_builtin) {
        memcpy(buffer, s->builtin + 16 * s->next, 16 * sizeof(float));
    } else if (s->is_fileio) {
        char msg[ISOMEND_FILEIO_MSG_SIZE];
        isomend_fileio_status st = ISOMEND_FILEIO_OK;
        if (!s->reader) st = isomend_fileio_slices_open(&s->info, &s->reader, msg, sizeof msg);
        if (st == ISOMEND_FILEIO_OK)
            st = isomend_fileio_slices_next(s->reader, buffer, (size_t)s->slice_bytes, msg,
                                            sizeof msg);
        if (st != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            rc = CLI_EXIT_FAIL;
        }
    } else {
#ifdef ISOMEND_HAVE_IO
        isomend_io_status st = io_api.read_slice(s->io, s->next, buffer, (size_t)s->slice_bytes);
        if (st != ISOMEND_IO_OK) rc = io_failed(s->io, st, s->label);
#endif
    }
    s->read_ms += cli_now_ms() - t0;
    if (rc == CLI_EXIT_OK) s->next++;
    return rc;
}

int cli_slices_seek(cli_slices *s, int64_t k)
{
    if (k < 0 || k > s->desc.dims[2]) {
        cli_error("%s: no slice %lld (internal error)", s->label, (long long)k);
        return CLI_EXIT_FAIL;
    }
    if (s->reader) {
        char msg[ISOMEND_FILEIO_MSG_SIZE];
        if (isomend_fileio_slices_seek(s->reader, k, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            return CLI_EXIT_FAIL;
        }
    } else if (s->is_fileio && k > 0) {
        char msg[ISOMEND_FILEIO_MSG_SIZE];
        if (isomend_fileio_slices_open(&s->info, &s->reader, msg, sizeof msg) !=
                ISOMEND_FILEIO_OK ||
            isomend_fileio_slices_seek(s->reader, k, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            return CLI_EXIT_FAIL;
        }
    }
    s->next = k;
    return CLI_EXIT_OK;
}

void cli_slices_rewind(cli_slices *s)
{
    isomend_fileio_slices_close(s->reader); /* the next slice opens it again */
    s->reader = NULL;
    s->next = 0;
}

void cli_slices_close(cli_slices *s)
{
    if (!s) return;
    isomend_fileio_slices_close(s->reader);
#ifdef ISOMEND_HAVE_IO
    if (s->io) io_api.destroy(s->io);
#endif
    memset(s, 0, sizeof *s);
}

int cli_source_load(cli_slices *s, cli_source *src)
{
    memset(src, 0, sizeof *src);
    snprintf(src->label, sizeof src->label, "%s", s->label);
    snprintf(src->kind, sizeof src->kind, "%s", s->kind);
    snprintf(src->format, sizeof src->format, "%s", s->format);
    for (int a = 0; a < 3; a++) src->spacing_from[a] = s->spacing_from[a];
    src->oblique = s->oblique;
    src->dicom = s->dicom;
    src->series_listed = s->series_listed;
    src->grid_axes = s->grid_axes;
    src->has_world = s->has_world;
    memcpy(src->world, s->world, sizeof src->world);
    int rc = CLI_EXIT_OK;
    if (s->is_builtin) {
        src->owned = malloc(sizeof s->builtin);
        if (!src->owned) {
            cli_error("%s: out of memory", s->label);
            rc = CLI_EXIT_FAIL;
        } else {
            memcpy(src->owned, s->builtin, sizeof s->builtin);
            src->vol = s->desc;
            src->vol.data = src->owned;
        }
    } else if (s->is_fileio) {
        /* refuse before allocating: Linux overcommits, so a too large malloc
         * would "succeed" and the kernel would kill us half-way through */
        uint64_t need = isomend_fileio_volume_bytes(&s->info), avail = cli_memory_available();
        char msg[ISOMEND_FILEIO_MSG_SIZE];
        if (avail && need > avail) {
            cli_error("%s: the volume needs %.1f MiB, only %.1f MiB of memory is available",
                      s->label, (double)need / 1048576.0, (double)avail / 1048576.0);
            rc = CLI_EXIT_FAIL;
        } else {
            double t0 = cli_now_ms();
            isomend_fileio_status st = isomend_fileio_load(&s->info, &src->owned,
                                                           cli_progress_read_cb, s->progress, msg,
                                                           sizeof msg);
            cli_progress_clear(s->progress);
            if (st == ISOMEND_FILEIO_ERR_CANCELLED) {
                cli_error("%s: interrupted", s->label);
                rc = CLI_EXIT_INTERRUPTED;
            } else if (st != ISOMEND_FILEIO_OK) {
                cli_error("%s", msg);
                rc = CLI_EXIT_FAIL;
            } else {
                src->read_ms = cli_now_ms() - t0;
                isomend_fileio_describe(&s->info, src->owned, &src->vol);
                for (int a = 0; a < 3; a++) { /* the overrides, as opened */
                    src->vol.spacing[a] = s->desc.spacing[a];
                    src->vol.origin[a] = s->desc.origin[a];
                }
            }
        }
    } else {
#ifdef ISOMEND_HAVE_IO
        double seconds = 0;
        isomend_io_status st = io_api.load(s->io, &src->vol, &seconds);
        cli_progress_clear(s->progress);
        if (st != ISOMEND_IO_OK) {
            rc = io_failed(s->io, st, s->label);
        } else {
            src->io = s->io; /* the loaded volume belongs to the handle */
            s->io = NULL;
            src->read_ms = seconds * 1e3;
        }
#endif
    }
    cli_slices_close(s);
    if (rc) cli_source_close(src);
    return rc;
}

int cli_source_open(const char *const *paths, int n, const cli_source_opts *o, cli_source *src)
{
    cli_slices s;
    memset(src, 0, sizeof *src);
    int rc = cli_slices_open(paths, n, o, &s);
    if (rc) return rc;
    return cli_source_load(&s, src);
}

void cli_source_drop_samples(cli_source *src)
{
    if (!src || !src->owned) return; /* an importer's volume stays with its handle */
    free(src->owned);
    src->owned = NULL;
    src->vol.data = NULL;
}

void cli_source_close(cli_source *src)
{
    if (!src) return;
    free(src->owned);
#ifdef ISOMEND_HAVE_IO
    if (src->io) io_api.destroy(src->io);
#endif
    memset(src, 0, sizeof *src);
}

/* ------------------------------------------------------------------ analysis */

/* Histogram bin of d over [mn, mx] (the importer's formula, clamped). */
static int bin_of(double d, double mn, double mx, int bins)
{
    if (!(mx > mn)) return 0;
    int b = (int)((d - mn) / (mx - mn) * bins);
    return b < 0 ? 0 : (b >= bins ? bins - 1 : b);
}

static int is_integer_type(isomend_type t)
{
    return t == ISOMEND_U8 || t == ISOMEND_I8 || t == ISOMEND_U16 || t == ISOMEND_I16 ||
           t == ISOMEND_I32;
}

double cli_sample_value(const void *sample, isomend_type t)
{
    const char *p = sample;
    switch (t) {
    case ISOMEND_U8: { uint8_t x; memcpy(&x, p, 1); return x; }
    case ISOMEND_I8: { int8_t x; memcpy(&x, p, 1); return x; }
    case ISOMEND_U16: { uint16_t x; memcpy(&x, p, 2); return x; }
    case ISOMEND_I16: { int16_t x; memcpy(&x, p, 2); return x; }
    case ISOMEND_I32: { int32_t x; memcpy(&x, p, 4); return x; }
    case ISOMEND_F32: { float x; memcpy(&x, p, 4); return x; }
    case ISOMEND_F64: { double x; memcpy(&x, p, 8); return x; }
    }
    return NAN;
}

/*
 * The summary is computed plane by plane in two passes (range, then
 * histograms), so that a loaded volume (any strides) and a source read slice
 * by slice go through the same code and give the same numbers.
 */
typedef cli_summary_acc summary_acc; /* short names inside this file */
#define OTSU_BINS CLI_OTSU_BINS

void cli_summary_plane(summary_acc *a, int pass, const char *base, int64_t s0, int64_t s1,
                          int64_t nx, int64_t ny)
{
    cli_summary *sum = a->sum;
    for (int64_t j = 0; j < ny; j++)
        for (int64_t i = 0; i < nx; i++) {
            double x = cli_sample_value(base + i * s0 + j * s1, a->type);
            if (pass == 0) {
                sum->samples++;
                if (!isfinite(x)) {
                    sum->nan_samples++;
                    continue;
                }
                a->finite++;
                if (x < a->lo) a->lo = x;
                if (x > a->hi) a->hi = x;
            } else if (isfinite(x)) {
                sum->histogram[bin_of(x, a->lo, a->hi, 16)]++;
                a->fine[bin_of(x, a->lo, a->hi, OTSU_BINS)]++;
            }
        }
}

void cli_summary_start(summary_acc *a, cli_summary *sum, isomend_type type)
{
    memset(sum, 0, sizeof *sum);
    memset(a, 0, sizeof *a);
    a->sum = sum;
    a->type = type;
    a->lo = INFINITY;
    a->hi = -INFINITY;
}

/* After pass 0: 1 if a histogram pass is needed. */
int cli_summary_range_done(summary_acc *a)
{
    if (a->finite == 0) return 0;
    a->sum->min = a->lo;
    a->sum->max = a->hi;
    a->sum->suggested_iso = a->lo;
    return a->hi > a->lo;
}

void cli_summary_finish(summary_acc *a)
{
    /* Otsu, exactly as the importer does it (io/common) */
    a->sum->suggested_iso = isomend_fileio_otsu(a->fine, OTSU_BINS, a->lo, a->hi,
                                                is_integer_type(a->type));
    a->sum->has_suggestion = 1;
}

#ifdef ISOMEND_HAVE_IO
static int io_summary(void *io, cli_summary *sum)
{
    isomend_io_summary s;
    isomend_io_status st = io_api.analyse(io, &s);
    if (st != ISOMEND_IO_OK) return io_failed(io, st, "analysis");
    sum->min = s.min;
    sum->max = s.max;
    sum->samples = s.samples;
    sum->nan_samples = s.nan_samples;
    for (int b = 0; b < 16; b++) sum->histogram[b] = s.histogram[b];
    sum->suggested_iso = s.suggested_iso;
    sum->has_suggestion = s.max > s.min;
    return CLI_EXIT_OK;
}
#endif

int cli_source_summary(cli_source *src, cli_summary *sum)
{
    memset(sum, 0, sizeof *sum);
#ifdef ISOMEND_HAVE_IO
    if (src->io) return io_summary(src->io, sum);
#endif
    const isomend_volume *v = &src->vol;
    int64_t ts = (int64_t)isomend_type_size(v->type), s0 = v->strides[0], s1 = v->strides[1],
            s2 = v->strides[2];
    if (!s0 && !s1 && !s2) {
        s0 = ts;
        s1 = s0 * v->dims[0];
        s2 = s1 * v->dims[1];
    }
    summary_acc a;
    cli_summary_start(&a, sum, v->type);
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1 && !cli_summary_range_done(&a)) return CLI_EXIT_OK;
        for (int64_t k = 0; k < v->dims[2]; k++)
            cli_summary_plane(&a, pass, (const char *)v->data + k * s2, s0, s1, v->dims[0], v->dims[1]);
    }
    cli_summary_finish(&a);
    return CLI_EXIT_OK;
}

int cli_slices_summary(cli_slices *s, cli_summary *sum)
{
    memset(sum, 0, sizeof *sum);
#ifdef ISOMEND_HAVE_IO
    if (s->io) { /* the importer streams the slices itself when nothing is loaded */
        int rc = io_summary(s->io, sum);
        cli_progress_clear(s->progress);
        return rc;
    }
#endif
    char *slice = malloc((size_t)s->slice_bytes);
    if (!slice) {
        cli_error("%s: out of memory for a slice of %llu bytes", s->label,
                  (unsigned long long)s->slice_bytes);
        return CLI_EXIT_FAIL;
    }
    const int64_t nx = s->desc.dims[0], ny = s->desc.dims[1], nz = s->desc.dims[2];
    const int64_t ts = (int64_t)isomend_type_size(s->desc.type);
    summary_acc a;
    cli_summary_start(&a, sum, s->desc.type);
    int rc = CLI_EXIT_OK;
    for (int pass = 0; pass < 2 && rc == CLI_EXIT_OK; pass++) {
        if (pass == 1 && !cli_summary_range_done(&a)) break;
        cli_slices_rewind(s);
        for (int64_t k = 0; k < nz && rc == CLI_EXIT_OK; k++) {
            if (cli_interrupted) {
                cli_error("%s: interrupted", s->label);
                rc = CLI_EXIT_INTERRUPTED;
                break;
            }
            rc = cli_slices_next(s, slice);
            if (rc == CLI_EXIT_OK) cli_summary_plane(&a, pass, slice, ts, ts * nx, nx, ny);
            cli_progress_update(s->progress, "analyse", (double)(pass * nz + k + 1) / (double)(2 * nz));
        }
        if (pass == 1 && rc == CLI_EXIT_OK) cli_summary_finish(&a);
    }
    cli_progress_clear(s->progress);
    cli_slices_rewind(s);
    free(slice);
    return rc;
}

/* ------------------------------------------------------------------ DICOM */

#ifdef ISOMEND_HAVE_IO
/* `, "key": "value"` (or without the comma for the first member) */
static void json_text_member(FILE *fp, int first, const char *key, const char *value)
{
    fprintf(fp, "%s\"%s\": ", first ? "" : ", ", key);
    cli_json_string(fp, value);
}

static int dicom_of(const cli_source *src, isomend_io_dicom *d)
{
    memset(d, 0, sizeof *d);
    d->size = sizeof *d;
    return src->io && src->dicom && !src->series_listed &&
           io_api.dicom_info((const isomend_io_source *)src->io, d) == ISOMEND_IO_OK;
}
#endif

const char *cli_source_suggested_level(const cli_source *src)
{
#ifdef ISOMEND_HAVE_IO
    if (src->io && !src->series_listed &&
        io_api.suggested_level((const isomend_io_source *)src->io) == ISOMEND_IO_LEVEL_BONE)
        return "bone";
#else
    (void)src;
#endif
    return "otsu";
}

int cli_source_level(cli_source *src, const char *name, double *value)
{
    int level = strcmp(name, "bone") == 0 ? 1 : strcmp(name, "skin") == 0 ? 2 : 0;
#ifdef ISOMEND_HAVE_IO
    if (src->io) {
        if (io_api.level_value((isomend_io_source *)src->io, level, value) != ISOMEND_IO_OK) {
            cli_error("--iso %s: %s", name, io_api.message((isomend_io_source *)src->io));
            return CLI_EXIT_USAGE;
        }
        return CLI_EXIT_OK;
    }
#endif
    if (level != 0) {
        cli_error("--iso %s: the %s level is for CT DICOM series in Hounsfield units; %s is a %s "
                  "source (give the level as a number)", name, name, src->label, src->kind);
        return CLI_EXIT_USAGE;
    }
    cli_summary sum;
    int rc = cli_source_summary(src, &sum);
    if (rc) return rc;
    *value = sum.suggested_iso;
    return CLI_EXIT_OK;
}

void cli_print_series(FILE *fp, const cli_source *src)
{
#ifdef ISOMEND_HAVE_IO
    if (!src->io) return;
    const isomend_io_source *io = (const isomend_io_source *)src->io;
    int64_t n = io_api.series_count(io), chosen = io_api.series_chosen(io);
    if (n < 2 && !src->series_listed) return;
    fprintf(fp, "  series:      %lld%s\n", (long long)n,
            src->series_listed ? "; choose one with --series N or --series UID" : "");
    for (int64_t i = 0; i < n; i++) {
        isomend_io_series e;
        memset(&e, 0, sizeof e);
        e.size = sizeof e;
        if (io_api.series_get(io, i, &e) != ISOMEND_IO_OK) continue;
        fprintf(fp, "  %s %3lld: %-4s \"%s\"", i == chosen ? "*" : " ", (long long)(i + 1),
                e.modality[0] ? e.modality : "?", e.description);
        if (e.number >= 0) fprintf(fp, ", series number %lld", (long long)e.number);
        fprintf(fp, ", %lld x %lld, %lld images in %lld files, UID %s\n", (long long)e.columns,
                (long long)e.rows, (long long)e.images, (long long)e.files, e.uid);
    }
#else
    (void)fp;
    (void)src;
#endif
}

void cli_json_series(FILE *fp, const cli_source *src)
{
    fprintf(fp, "[");
#ifdef ISOMEND_HAVE_IO
    if (src->io) {
        const isomend_io_source *io = (const isomend_io_source *)src->io;
        int64_t n = io_api.series_count(io);
        for (int64_t i = 0; i < n; i++) {
            isomend_io_series e;
            memset(&e, 0, sizeof e);
            e.size = sizeof e;
            if (io_api.series_get(io, i, &e) != ISOMEND_IO_OK) continue;
            fprintf(fp, "%s{\"index\": %lld", i ? ", " : "", (long long)(i + 1));
            json_text_member(fp, 0, "uid", e.uid);
            json_text_member(fp, 0, "description", e.description);
            json_text_member(fp, 0, "modality", e.modality);
            fprintf(fp, ", \"number\": %lld, \"files\": %lld, \"images\": %lld, \"columns\": %lld, "
                        "\"rows\": %lld}",
                    (long long)e.number, (long long)e.files, (long long)e.images,
                    (long long)e.columns, (long long)e.rows);
        }
    }
#else
    (void)src;
#endif
    fprintf(fp, "]");
}

void cli_print_dicom(FILE *fp, cli_source *src, const cli_summary *sum)
{
#ifdef ISOMEND_HAVE_IO
    isomend_io_dicom d;
    if (!dicom_of(src, &d)) return;
    fprintf(fp, "  dicom:       %s \"%s\", %lld file%s%s, %s\n", d.modality[0] ? d.modality : "?",
            d.description, (long long)d.files, d.files == 1 ? "" : "s",
            d.multiframe ? " (multi-frame)" : "", d.transfer_syntax_name);
    fprintf(fp, "  ignored:     %lld DICOM object%s without pixel data, %lld file%s not DICOM, "
                "%lld file%s of other series\n",
            (long long)d.non_image, d.non_image == 1 ? "" : "s", (long long)d.non_dicom,
            d.non_dicom == 1 ? "" : "s", (long long)d.other_series, d.other_series == 1 ? "" : "s");
    cli_print_series(fp, src);
    fprintf(fp, "  values:      %d-bit %s %s", d.bits_stored, d.pixel_signed ? "signed" : "unsigned",
            d.photometric);
    if (strcmp(d.photometric, "MONOCHROME1") == 0) fprintf(fp, " (inverted: brighter is higher)");
    if (d.rescaled)
        fprintf(fp, ", rescaled: slope %g, intercept %g%s", d.rescale_slope, d.rescale_intercept,
                d.hounsfield ? " (HU)" : "");
    fputc('\n', fp);
    fprintf(fp, "  orientation: row %g, %g, %g; column %g, %g, %g; normal %g, %g, %g\n",
            d.orientation[0], d.orientation[1], d.orientation[2], d.orientation[3],
            d.orientation[4], d.orientation[5], d.normal[0], d.normal[1], d.normal[2]);
    fprintf(fp, "  position:    %g, %g, %g (slice 0, patient LPS mm)\n", d.position[0],
            d.position[1], d.position[2]);
    if (d.axes == ISOMEND_IO_AXES_GRID)
        fprintf(fp, "  axes:        grid (--grid-axes): x along the rows, y along the columns, z along "
                    "the slices, not rotated into patient space\n");
    else if (src->has_world)
        fprintf(fp, "  axes:        patient (LPS mm): the mesh is turned by the direction cosines "
                    "(world = position + R * index * spacing)\n");
    else
        fprintf(fp, "  axes:        patient (LPS mm): x to the patient's left, y posterior, z head\n");
    double otsu = 0;
    (void)sum;
    if (d.hounsfield &&
        io_api.level_value((isomend_io_source *)src->io, ISOMEND_IO_LEVEL_OTSU, &otsu) == ISOMEND_IO_OK)
        fprintf(fp, "  levels (HU): bone 300, skin -500, Otsu %.9g; extract uses bone unless --iso "
                    "skin|otsu|VALUE\n", otsu);
#else
    (void)fp;
    (void)src;
    (void)sum;
#endif
}

void cli_json_dicom(FILE *fp, cli_source *src, const cli_summary *sum)
{
#ifdef ISOMEND_HAVE_IO
    (void)sum;
    isomend_io_dicom d;
    if (!dicom_of(src, &d)) {
        fprintf(fp, "null");
        return;
    }
    fputc('{', fp);
    json_text_member(fp, 1, "modality", d.modality);
    json_text_member(fp, 0, "series_uid", d.series_uid);
    json_text_member(fp, 0, "description", d.description);
    json_text_member(fp, 0, "transfer_syntax", d.transfer_syntax);
    json_text_member(fp, 0, "photometric", d.photometric);
    fprintf(fp, ", \"bits_stored\": %d, \"signed\": %s, \"rescaled\": %s, \"rescale_slope\": %.17g, "
                "\"rescale_intercept\": %.17g, \"hounsfield\": %s",
            d.bits_stored, d.pixel_signed ? "true" : "false", d.rescaled ? "true" : "false",
            d.rescale_slope, d.rescale_intercept, d.hounsfield ? "true" : "false");
    fprintf(fp, ", \"orientation\": [%.17g, %.17g, %.17g, %.17g, %.17g, %.17g]", d.orientation[0],
            d.orientation[1], d.orientation[2], d.orientation[3], d.orientation[4], d.orientation[5]);
    fprintf(fp, ", \"normal\": [%.17g, %.17g, %.17g], \"position\": [%.17g, %.17g, %.17g]",
            d.normal[0], d.normal[1], d.normal[2], d.position[0], d.position[1], d.position[2]);
    double otsu = 0;
    if (d.hounsfield &&
        io_api.level_value((isomend_io_source *)src->io, ISOMEND_IO_LEVEL_OTSU, &otsu) == ISOMEND_IO_OK)
        fprintf(fp, ", \"levels\": {\"bone\": 300, \"skin\": -500, \"otsu\": %.17g, \"extract\": \"bone\"}",
                otsu);
    else
        fprintf(fp, ", \"levels\": null");
    fprintf(fp, ", \"files\": %lld, \"multiframe\": %s, \"non_image\": %lld, \"non_dicom\": %lld, "
                "\"other_series\": %lld, \"axes\": \"%s\", \"series\": ",
            (long long)d.files, d.multiframe ? "true" : "false", (long long)d.non_image,
            (long long)d.non_dicom, (long long)d.other_series,
            d.axes == ISOMEND_IO_AXES_GRID ? "grid" : "patient");
    cli_json_series(fp, src);
    fprintf(fp, "}");
#else
    (void)src;
    (void)sum;
    fprintf(fp, "null");
#endif
}

void cli_source_view(const cli_slices *s, cli_source *view)
{
    memset(view, 0, sizeof *view);
    view->vol = s->desc;
    view->io = s->io;
    snprintf(view->kind, sizeof view->kind, "%s", s->kind);
    snprintf(view->format, sizeof view->format, "%s", s->format);
    for (int a = 0; a < 3; a++) view->spacing_from[a] = s->spacing_from[a];
    view->oblique = s->oblique;
    view->dicom = s->dicom;
    view->series_listed = s->series_listed;
    view->grid_axes = s->grid_axes;
    view->has_world = s->has_world;
    memcpy(view->world, s->world, sizeof view->world);
    view->read_ms = s->read_ms;
    snprintf(view->label, sizeof view->label, "%s", s->label);
}
