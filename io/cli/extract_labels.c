/*
 * extract_labels.c - `isomend extract SOURCE --labels all|L1,L2,...`: the
 * surfaces of a label map's labels, all in one pass of the core
 * (isomend_labels_extract), each checked, written as one file a label
 * (-o FOLDER/) or all in one PLY (per-face label and colour) or OBJ (a
 * group and a material a label, colours in the .mtl beside it).
 *
 * Names and colours: --label-table FILE, else a .seg.nrrd's Segment*_ keys,
 * else label_N and a fixed palette (io/common/label_table.h).  Samples:
 * integer types; a float volume whose samples are all whole numbers (the
 * importer's NIfTI uint32 arrives as f64) is copied as u32 or i32, any
 * other is refused.  Nothing is written before every label is extracted and
 * checked; the files of a folder are written to a temporary folder inside
 * it and renamed at the end, so a failure leaves none of them.
 */
#define _POSIX_C_SOURCE 200809L

#include "cli.h"

#include "label_samples.h"
#include "label_table.h"
#include "label_writer.h"
#include "mesh_io.h"

#include <dirent.h>
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* --labels VALUE: "all" (*count 0, *values NULL) or distinct integers. */
static int parse_labels(const char *value, int64_t **values, size_t *count)
{
    *values = NULL;
    *count = 0;
    if (strcmp(value, "all") == 0) return CLI_EXIT_OK;
    size_t n = 1;
    for (const char *p = value; *p; p++) n += *p == ',';
    int64_t *v = malloc(n * sizeof *v);
    char *copy = strdup(value);
    if (!v || !copy) {
        free(v);
        free(copy);
        cli_error("--labels: out of memory");
        return CLI_EXIT_FAIL;
    }
    size_t k = 0;
    char *save = NULL;
    for (char *tok = strtok_r(copy, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        if (!cli_parse_int64(tok, &v[k])) {
            cli_error("--labels: '%s' is not an integer label (use all, or L1,L2,...)", tok);
            free(v);
            free(copy);
            return CLI_EXIT_USAGE;
        }
        for (size_t q = 0; q < k; q++)
            if (v[q] == v[k]) {
                cli_error("--labels: label %" PRId64 " is listed twice", v[k]);
                free(v);
                free(copy);
                return CLI_EXIT_USAGE;
            }
        k++;
    }
    free(copy);
    if (k != n) { /* an empty item: "1,,2" or a trailing comma */
        cli_error("--labels: '%s' has an empty item (use all, or L1,L2,...)", value);
        free(v);
        return CLI_EXIT_USAGE;
    }
    *values = v;
    *count = k;
    return CLI_EXIT_OK;
}

/* A file-name-safe copy of a label's name: letters, digits, '.', '-', '_'. */
static void safe_name(const char *in, char *out, size_t size)
{
    size_t k = 0;
    for (; *in && k + 1 < size; in++)
        out[k++] = (char)((*in >= 'a' && *in <= 'z') || (*in >= 'A' && *in <= 'Z') ||
                                  (*in >= '0' && *in <= '9') || *in == '-' || *in == '.'
                              ? *in
                              : '_');
    out[k] = '\0';
    if (k == 0 || out[0] == '.') out[0] = '_';
}

/* The label volume of a loaded source: its own samples, or an i32/u32 copy of
 * whole-number float samples (*copy, to free; io/common's
 * label_samples_integer(), which the importer uses too).  Exit code, message
 * printed. */
static int label_samples(const cli_source *s, isomend_volume *vol, void **copy)
{
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    if (!label_samples_integer(&s->desc, s->label, vol, copy, msg, sizeof msg)) return CLI_EXIT_OK;
    cli_error("--labels: %s", msg);
    return CLI_EXIT_FAIL;
}

/* A label's file-safe name and colour: from the table, else label_N and the
 * palette (label_describe(), the hosts' rule too). */
static void name_and_color(const label_table *t, int64_t value, char *name, size_t size,
                           uint8_t rgb[3])
{
    char shown[LABEL_NAME_MAX];
    label_describe(t, value, shown, sizeof shown, rgb);
    safe_name(shown, name, size);
}

/* Everything of one label the outputs need. */
typedef struct label_out {
    int64_t value;
    char name[LABEL_NAME_MAX + 16]; /* safe, unique */
    uint8_t rgb[3];
    const isomend_mesh *mesh;
    float *world_pos, *world_nrm; /* the mesh placed in the world, or NULL */
    uint32_t *world_tri;
    isomend_check_report check;
    char file[ISOMEND_FILEIO_PATH_MAX];
} label_out;

static const float *out_pos(const label_out *l)
{
    return l->world_pos ? l->world_pos : isomend_mesh_positions(l->mesh);
}
static const float *out_nrm(const label_out *l)
{
    return l->world_pos ? l->world_nrm : isomend_mesh_normals(l->mesh);
}
static const uint32_t *out_tri(const label_out *l)
{
    return l->world_pos ? l->world_tri : isomend_mesh_triangles(l->mesh);
}

/* Removes a folder of ours and what is in it (flat). */
static void remove_folder(const char *dir)
{
    DIR *d = opendir(dir);
    if (d) {
        struct dirent *e;
        char path[ISOMEND_FILEIO_PATH_MAX + 300];
        while ((e = readdir(d))) {
            if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            unlink(path);
        }
        closedir(d);
    }
    rmdir(dir);
}

/* One file a label into folder `dir` (created when missing): written into a
 * temporary folder inside it, renamed when all are written. */
static int write_folder(const char *dir, isomend_mesh_format fmt, label_out *l, size_t n)
{
    const char *ext = fmt == ISOMEND_MESH_OBJ ? "obj" : fmt == ISOMEND_MESH_STL ? "stl" : "ply";
    struct stat sb;
    int created = 0;
    if (stat(dir, &sb) != 0) {
        if (mkdir(dir, 0777) != 0) {
            cli_error("-o %s: cannot create the folder: %s", dir, strerror(errno));
            return CLI_EXIT_FAIL;
        }
        created = 1;
    } else if (!S_ISDIR(sb.st_mode)) {
        cli_error("-o %s: not a folder", dir);
        return CLI_EXIT_FAIL;
    }
    char tmp[ISOMEND_FILEIO_PATH_MAX];
    snprintf(tmp, sizeof tmp, "%s/.isomend-labels.%ld.tmp", dir, (long)getpid());
    if (mkdir(tmp, 0777) != 0) {
        cli_error("-o %s: cannot create a folder in it: %s", dir, strerror(errno));
        if (created) rmdir(dir);
        return CLI_EXIT_FAIL;
    }
    char msg[ISOMEND_FILEIO_MSG_SIZE], path[ISOMEND_FILEIO_PATH_MAX + 200];
    int rc = CLI_EXIT_OK;
    for (size_t q = 0; q < n && !rc; q++) {
        snprintf(path, sizeof path, "%s/%s.%s", tmp, l[q].name, ext);
        snprintf(l[q].file, sizeof l[q].file, "%s/%s.%s", dir, l[q].name, ext);
        if (isomend_write_mesh(path, fmt, out_pos(&l[q]), out_nrm(&l[q]),
                               isomend_mesh_vertex_count(l[q].mesh), out_tri(&l[q]),
                               isomend_mesh_triangle_count(l[q].mesh), msg,
                               sizeof msg) != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            rc = CLI_EXIT_FAIL;
        }
        if (cli_interrupted) rc = CLI_EXIT_INTERRUPTED;
    }
    for (size_t q = 0; q < n && !rc; q++) {
        snprintf(path, sizeof path, "%s/%s.%s", tmp, l[q].name, ext);
        if (rename(path, l[q].file) != 0) {
            cli_error("%s: cannot rename into place: %s", l[q].file, strerror(errno));
            for (size_t r = 0; r < q; r++) unlink(l[r].file); /* all or none */
            rc = CLI_EXIT_FAIL;
        }
    }
    remove_folder(tmp);
    if (rc && created) rmdir(dir);
    return rc;
}

static int cmp_i64(const void *a, const void *b)
{
    const int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

/* The labels present but 0, from a pass over the slices (rewound after). */
static int list_labels(cli_source *s, void *buf, int64_t **values, size_t *count)
{
    int64_t *v = NULL;
    size_t n = 0, cap = 0, got = 0;
    int64_t slice_values[256];
    isomend_volume one;
    isomend_volume_init(&one, buf, s->desc.type, s->desc.dims[0], s->desc.dims[1], 1);
    for (int64_t k = 0; k < s->desc.dims[2]; k++) {
        int rc = cli_slices_next(s, buf);
        if (rc) {
            free(v);
            return rc;
        }
        int64_t *sv = slice_values;
        isomend_labels_present(&one, NULL, NULL, 0, &got);
        if (got > 256 && !(sv = malloc(sizeof(int64_t) * got))) {
            free(v);
            cli_error("%s: out of memory listing the labels", s->label);
            return CLI_EXIT_FAIL;
        }
        isomend_labels_present(&one, sv, NULL, got, &got);
        if (n + got > cap) {
            cap = 2 * (n + got);
            int64_t *w = realloc(v, sizeof(int64_t) * cap);
            if (!w) {
                free(v);
                if (sv != slice_values) free(sv);
                cli_error("%s: out of memory listing the labels", s->label);
                return CLI_EXIT_FAIL;
            }
            v = w;
        }
        for (size_t q = 0; q < got; q++)
            if (sv[q] != 0) v[n++] = sv[q];
        if (sv != slice_values) free(sv);
        qsort(v, n, sizeof(int64_t), cmp_i64); /* unique, so n stays small */
        size_t u = 0;
        for (size_t q = 0; q < n; q++)
            if (!u || v[u - 1] != v[q]) v[u++] = v[q];
        n = u;
    }
    cli_slices_rewind(s);
    *values = v;
    *count = n;
    return CLI_EXIT_OK;
}

/* --stream: the slices read one at a time into the core's label stream; with
 * --labels all the labels are listed by a first pass over the slices.  An
 * exit code for a read failure (printed); else *st is the core's status. */
static int stream_labels(cli_source *s, int64_t **want, size_t *nwant, const isomend_options *opts,
                         isomend_labels **res, isomend_status *st)
{
    void *buf = malloc(s->slice_bytes ? s->slice_bytes : 1);
    if (!buf) {
        cli_error("%s: out of memory for a slice", s->label);
        return CLI_EXIT_FAIL;
    }
    int rc = CLI_EXIT_OK;
    if (!*want) {
        rc = list_labels(s, buf, want, nwant);
        if (rc) {
            free(buf);
            return rc;
        }
    }
    isomend_labels_stream *ls = NULL;
    static const int64_t none = 0; /* no label at all: an empty list, refused later */
    *st = isomend_labels_stream_begin(&s->desc, *want ? *want : &none, *nwant, opts, &ls);
    for (int64_t k = 0; *st == ISOMEND_OK && k < s->desc.dims[2]; k++) {
        rc = cli_slices_next(s, buf);
        if (rc) break;
        if (cli_interrupted) {
            *st = ISOMEND_ERR_CANCELLED;
            break;
        }
        *st = isomend_labels_stream_push(ls, buf);
        if (opts->progress)
            (void)opts->progress(opts->progress_user, (double)(k + 1) / (double)s->desc.dims[2]);
    }
    if (!rc && *st == ISOMEND_OK) *st = isomend_labels_stream_finish(ls, res);
    isomend_labels_stream_destroy(ls);
    free(buf);
    return rc;
}

/* The options that do not apply to a label map: the first one given. */
static const char *refused_option(uint64_t seen)
{
    static const struct {
        uint64_t id;
        const char *name;
    } refused[] = {
        {OPT_ISO, "--iso (a label's surface is at 0.5 of its indicator)"},
        {OPT_STATS, "--stats"},
        {OPT_IN_MEMORY, "--in-memory"},
        {OPT_CHUNK_LAYERS, "--chunk-layers"},
        {OPT_PAGES, "--pages"},
        {OPT_SLICE_POSITIONS, "--slice-positions"},
    };
    for (size_t q = 0; q < sizeof refused / sizeof refused[0]; q++)
        if (seen & refused[q].id) return refused[q].name;
    return NULL;
}

/* 1 when files can be made in folder `out` (existing, or its parent); else 0
 * with the message printed. */
static int folder_creatable(const char *out)
{
    char dir[ISOMEND_FILEIO_PATH_MAX];
    snprintf(dir, sizeof dir, "%s", out);
    size_t len = strlen(dir);
    while (len > 1 && dir[len - 1] == '/') dir[--len] = '\0';
    struct stat sb;
    if (stat(dir, &sb) == 0) {
        if (access(dir, W_OK | X_OK) == 0) return 1;
        cli_error("-o %s: cannot create files in this folder: %s", out, strerror(errno));
        return 0;
    }
    char *slash = strrchr(dir, '/');
    if (slash == dir)
        slash[1] = '\0';
    else if (slash)
        *slash = '\0';
    else
        snprintf(dir, sizeof dir, ".");
    if (stat(dir, &sb) == 0 && S_ISDIR(sb.st_mode) && access(dir, W_OK | X_OK) == 0) return 1;
    cli_error("-o %s: cannot create the folder in '%s': %s", out, dir,
              errno ? strerror(errno) : "not a writable folder");
    return 0;
}

/* The steps of `p` on the n labels' meshes cur[] (replaced by the results,
 * which owned[] holds): clean-up a label at a time, smoothing and decimation
 * all together (isomend_meshes_smooth, isomend_meshes_decimate); each
 * label's report in r[].  An exit code, the message printed. */
static int label_steps(const cli_post *p, size_t n, const isomend_mesh **cur, isomend_mesh **owned,
                       cli_post_report *r)
{
    isomend_mesh **next = calloc(n ? n : 1, sizeof *next);
    isomend_smooth_report *sr = calloc(n ? n : 1, sizeof *sr);
    isomend_decimate_report *dr = calloc(n ? n : 1, sizeof *dr);
    int rc = CLI_EXIT_OK;
    isomend_status st = ISOMEND_OK;
    const char *step = NULL;
    if (!next || !sr || !dr) {
        cli_error("--labels: out of memory for the steps");
        rc = CLI_EXIT_FAIL;
        goto done;
    }
    for (int k = 0; k < 3 && !rc; k++) {
        double t0 = cli_now_ms();
        if (k == 0 && (p->min_component || p->largest)) {
            step = p->largest ? "--largest" : "--min-component";
            for (size_t q = 0; q < n && st == ISOMEND_OK; q++)
                st = isomend_mesh_clean(cur[q], p->min_component, p->largest, &next[q], &r[q].clean);
        } else if (k == 1 && p->smooth > 0) {
            step = "--smooth";
            st = isomend_meshes_smooth(cur, n, p->smooth, next, sr);
        } else if (k == 2 && (p->ratio > 0 || p->target || p->max_error > 0)) {
            step = p->ratio > 0 ? "--decimate" : p->target ? "--target-triangles" : "--max-error";
            isomend_decimate_options d;
            isomend_decimate_options_init(&d);
            d.ratio = p->ratio;
            d.target_triangles = p->target;
            d.max_error = p->max_error;
            st = isomend_meshes_decimate(cur, n, &d, next, dr);
        } else {
            continue;
        }
        const double ms = cli_now_ms() - t0;
        if (st != ISOMEND_OK) {
            cli_error("--labels: %s: %s", step, isomend_status_string(st));
            rc = CLI_EXIT_FAIL;
            for (size_t q = 0; q < n; q++) {
                isomend_mesh_destroy(next[q]);
                next[q] = NULL;
            }
            break;
        }
        for (size_t q = 0; q < n; q++) {
            isomend_mesh_destroy(owned[q]);
            owned[q] = next[q];
            cur[q] = next[q];
            next[q] = NULL;
            if (k == 0) {
                r[q].cleaned = 1;
                r[q].clean_ms = ms;
            } else if (k == 1) {
                r[q].smoothed = 1;
                r[q].smooth = sr[q];
                r[q].smooth_ms = ms;
            } else {
                r[q].decimated = 1;
                r[q].decimate = dr[q];
                r[q].decimate_ms = ms;
            }
        }
    }
done:
    free(next);
    free(sr);
    free(dr);
    return rc;
}

/* 1 when -o names a folder: a trailing '/' or an existing folder. */
static int output_is_folder(const char *out)
{
    struct stat sb;
    const size_t len = strlen(out);
    return (len && out[len - 1] == '/') || (stat(out, &sb) == 0 && S_ISDIR(sb.st_mode));
}

int cli_extract_labels(cli_args *a)
{
    const char *bad = refused_option(a->seen);
    if (bad) {
        cli_error("--labels: %s does not apply to a label map", bad);
        return CLI_EXIT_USAGE;
    }
    if (a->method != ISOMEND_METHOD_DMC && a->method != ISOMEND_METHOD_MC &&
        a->method != ISOMEND_METHOD_DURST) {
        cli_error("--method %s: a label map takes dmc (the default), mc or durst",
                  isomend_method_name(a->method));
        return CLI_EXIT_USAGE;
    }
    if (a->npositional == 0) {
        cli_error("extract: missing SOURCE (see isomend extract --help)");
        return CLI_EXIT_USAGE;
    }
    if (!a->output) {
        cli_error("extract: missing -o MESH or -o FOLDER/ (one file a label)");
        return CLI_EXIT_USAGE;
    }
    const int folder = output_is_folder(a->output);
    isomend_mesh_format fmt;
    if (folder) {
        fmt = a->format ? isomend_mesh_format_of(a->format) : ISOMEND_MESH_PLY;
    } else {
        if (a->format) {
            cli_error("--format: only with -o FOLDER/ (a file's format is its extension)");
            return CLI_EXIT_USAGE;
        }
        fmt = isomend_mesh_format_of(a->output);
        if (fmt == ISOMEND_MESH_STL) {
            cli_error("-o %s: STL holds one surface and no labels: use -o FOLDER/ --format stl "
                      "(one STL a label), or .ply / .obj (every label in one file)",
                      a->output);
            return CLI_EXIT_USAGE;
        }
        if (fmt == ISOMEND_MESH_UNKNOWN) {
            cli_error("-o %s: unknown mesh format (use .ply or .obj, or FOLDER/ for one file a "
                      "label)",
                      a->output);
            return CLI_EXIT_USAGE;
        }
    }
    if (a->json && strcmp(a->json, a->output) == 0) {
        cli_error("--json %s: same file as -o", a->json);
        return CLI_EXIT_USAGE;
    }
    int64_t *want = NULL;
    size_t nwant = 0;
    int rc = parse_labels(a->labels, &want, &nwant);
    if (rc) return rc;

    label_table table = {NULL, 0, 0, ""};
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    const char *names_from = NULL;
    if (a->label_table) {
        if (label_table_read(a->label_table, &table, msg, sizeof msg)) {
            cli_error("%s", msg);
            free(want);
            return CLI_EXIT_FAIL;
        }
        names_from = "--label-table";
    }
    /* the outputs must be creatable before any work is done: a file's temporary
     * file, or a writable folder (or its writable parent, when it is to be made) */
    int creatable = 1;
    if (!folder) {
        isomend_atomic_file probe;
        creatable = isomend_atomic_open(&probe, a->output, msg, sizeof msg) == ISOMEND_FILEIO_OK;
        if (creatable)
            isomend_atomic_abort(&probe);
        else
            cli_error("%s", msg);
    } else if (!folder_creatable(a->output)) {
        creatable = 0;
    }
    if (!creatable) {
        label_table_free(&table);
        free(want);
        return CLI_EXIT_FAIL;
    }

    const int quiet = (a->seen & OPT_QUIET) != 0;
    const int json_stdout = a->json && strcmp(a->json, "-") == 0;
    FILE *text = json_stdout ? stderr : stdout;
    cli_json_out jo;
    cli_progress bar;
    cli_source src;
    isomend_labels *res = NULL;
    label_out *lo = NULL;
    const isomend_mesh **cur = NULL; /* each label's mesh after the steps so far */
    isomend_mesh **owned = NULL;     /* ... those the steps made */
    cli_post_report *pr = NULL;      /* each label's steps */
    int post = 0;
    void *copy = NULL;
    size_t n = 0;
    rc = cli_open_source_for(a, quiet, &jo, &bar, &src);
    if (rc) {
        label_table_free(&table);
        free(want);
        return rc;
    }
    /* --stream, or a map that would take more than half the memory (--max-memory,
     * else the memory available): read a slice at a time (the meshes, the
     * same either way, stay in memory) */
    const uint64_t limit = a->max_memory ? a->max_memory : cli_memory_available();
    const uint64_t volume_bytes = src.slice_bytes * (uint64_t)src.desc.dims[2];
    const int integers = src.desc.type != ISOMEND_F32 && src.desc.type != ISOMEND_F64;
    const int stream = (a->seen & OPT_STREAM) != 0 || (integers && limit && volume_bytes > limit / 2);
    isomend_volume vol = src.desc;
    if (stream) {
        if (vol.type == ISOMEND_F32 || vol.type == ISOMEND_F64) {
            cli_error("--labels --stream: %s has %s samples; without --stream the volume is read "
                      "whole and taken as a label map if they are all whole numbers",
                      src.label, isomend_type_name(vol.type));
            rc = CLI_EXIT_FAIL;
            goto done;
        }
    } else {
        rc = cli_source_load(&src);
        if (!rc) rc = label_samples(&src, &vol, &copy);
        if (rc) goto done;
    }
    if (!names_from && strcmp(src.kind, "nrrd") == 0) {
        const int got = label_table_from_nrrd(a->positional[0], &table, msg, sizeof msg);
        if (got < 0) {
            cli_error("%s", msg);
            rc = CLI_EXIT_FAIL;
            goto done;
        }
        if (got) names_from = "seg.nrrd";
    }

    isomend_options opts;
    cli_extract_options(a, &bar, &opts);
    double t0 = cli_now_ms();
    isomend_status st;
    if (stream) {
        rc = stream_labels(&src, &want, &nwant, &opts, &res, &st);
        if (rc) goto done;
    } else {
        st = isomend_labels_extract(&vol, want, nwant, &opts, &res);
    }
    cli_progress_clear(&bar);
    const double extract_ms = cli_now_ms() - t0;
    rc = cli_extract_status(st == ISOMEND_OK && cli_interrupted ? ISOMEND_ERR_CANCELLED : st,
                            src.label, "label extraction");
    if (rc) goto done;
    n = isomend_labels_count(res);
    if (n == 0) {
        cli_error("--labels all: %s has no label but the background 0", src.label);
        rc = CLI_EXIT_FAIL;
        goto done;
    }
    for (size_t q = 0; q < n; q++)
        if (isomend_labels_voxels(res, q) == 0) {
            cli_error("--labels: label %" PRId64 " is not in %s", isomend_labels_value(res, q),
                      src.label);
            rc = CLI_EXIT_FAIL;
            goto done;
        }

    /* the steps: clean-up a label at a time (dropping a label's islands
     * leaves its neighbours' surfaces closed), smoothing and decimation of
     * all the labels together, so that where two labels touch their surfaces
     * still meet */
    cur = calloc(n, sizeof *cur);
    owned = calloc(n, sizeof *owned);
    pr = calloc(n, sizeof *pr);
    if (!cur || !owned || !pr) {
        cli_error("%s: out of memory", src.label);
        rc = CLI_EXIT_FAIL;
        goto done;
    }
    for (size_t q = 0; q < n; q++)
        cur[q] = isomend_labels_mesh(res, q);
    rc = label_steps(&a->post, n, cur, owned, pr);
    if (rc) goto done;
    post = pr[0].cleaned || pr[0].smoothed || pr[0].decimated;

    /* names, colours, checks, the world map */
    lo = calloc(n, sizeof *lo);
    if (!lo) {
        cli_error("%s: out of memory", src.label);
        rc = CLI_EXIT_FAIL;
        goto done;
    }
    t0 = cli_now_ms();
    for (size_t q = 0; q < n && !rc; q++) {
        label_out *l = &lo[q];
        l->value = isomend_labels_value(res, q);
        l->mesh = cur[q];
        char base[LABEL_NAME_MAX];
        name_and_color(&table, l->value, base, sizeof base, l->rgb);
        snprintf(l->name, sizeof l->name, "%s", base);
        for (size_t r = 0, k = 2; r < q; r++) /* unique: name_2, name_3, ... */
            if (strcmp(lo[r].name, l->name) == 0) {
                snprintf(l->name, sizeof l->name, "%s_%zu", base, k++);
                r = (size_t)-1;
            }
        if (isomend_mesh_check(l->mesh, &l->check) != ISOMEND_OK) {
            cli_error("%s: continuity check of label %" PRId64 " failed", src.label, l->value);
            rc = CLI_EXIT_FAIL;
            break;
        }
        const size_t nv = isomend_mesh_vertex_count(l->mesh),
                     nt = isomend_mesh_triangle_count(l->mesh);
        if (src.has_world && nt) {
            const int normals = isomend_mesh_normals(l->mesh) != NULL;
            l->world_pos = malloc(sizeof(float) * 3 * nv);
            l->world_nrm = normals ? malloc(sizeof(float) * 3 * nv) : NULL;
            l->world_tri = malloc(sizeof(uint32_t) * 3 * nt);
            if (!l->world_pos || !l->world_tri || (normals && !l->world_nrm) ||
                isomend_mesh_copy_transformed(l->mesh, src.world, l->world_pos, l->world_nrm,
                                              l->world_tri, NULL) != ISOMEND_OK) {
                cli_error("%s: out of memory placing the labels in patient space", src.label);
                rc = CLI_EXIT_FAIL;
            }
        }
    }
    const double check_ms = cli_now_ms() - t0;
    if (rc) goto done;

    t0 = cli_now_ms();
    if (folder) {
        char dir[ISOMEND_FILEIO_PATH_MAX];
        snprintf(dir, sizeof dir, "%s", a->output);
        size_t len = strlen(dir);
        while (len > 1 && dir[len - 1] == '/') dir[--len] = '\0';
        rc = write_folder(dir, fmt, lo, n);
    } else {
        label_mesh_part *parts = calloc(n, sizeof *parts);
        if (!parts) {
            cli_error("%s: out of memory", a->output);
            rc = CLI_EXIT_FAIL;
            goto done;
        }
        const int normals = !(opts.flags & ISOMEND_FLAG_NO_NORMALS);
        for (size_t q = 0; q < n; q++) {
            parts[q].pos = out_pos(&lo[q]);
            parts[q].nrm = out_nrm(&lo[q]);
            parts[q].nv = isomend_mesh_vertex_count(lo[q].mesh);
            parts[q].tri = out_tri(&lo[q]);
            parts[q].nt = isomend_mesh_triangle_count(lo[q].mesh);
            parts[q].value = lo[q].value;
            parts[q].name = lo[q].name;
            memcpy(parts[q].rgb, lo[q].rgb, 3);
            snprintf(lo[q].file, sizeof lo[q].file, "%s", a->output);
        }
        if (label_meshes_write(a->output, fmt, parts, n, normals, msg, sizeof msg)) {
            cli_error("%s", msg);
            rc = CLI_EXIT_FAIL;
        }
        free(parts);
    }
    const double write_ms = cli_now_ms() - t0;
    if (rc) goto done;

    if (!quiet) {
        fprintf(
            text, "%s: %" PRId64 " x %" PRId64 " x %" PRId64 " %s label map, %zu label%s, %s%s\n",
            src.label, vol.dims[0], vol.dims[1], vol.dims[2],
            vol.type == ISOMEND_U32 ? "u32" : isomend_type_name(vol.type), n, n == 1 ? "" : "s",
            isomend_method_name(opts.method), (opts.flags & ISOMEND_FLAG_PAD) ? ", padded" : "");
        for (size_t q = 0; q < n; q++)
            fprintf(text,
                    "  %" PRId64 " %s: %" PRIu64 " voxels, %zu triangles, %" PRIu64
                    " component%s, %s -> %s\n",
                    lo[q].value, lo[q].name, isomend_labels_voxels(res, q),
                    isomend_mesh_triangle_count(lo[q].mesh), lo[q].check.components,
                    lo[q].check.components == 1 ? "" : "s",
                    cli_check_has_defects(&lo[q].check) ? "NOT continuous"
                    : lo[q].check.border_edges          ? "continuous, open at the border"
                                                        : "closed",
                    lo[q].file);
        for (size_t q = 0; post && q < n; q++) {
            fprintf(text, "  %" PRId64 " %s:\n", lo[q].value, lo[q].name);
            cli_print_post(text, &pr[q]);
        }
        fprintf(text, "time: read %.1f ms, extract %.1f ms, check %.1f ms, write %.1f ms\n",
                src.read_ms, extract_ms, check_ms, write_ms);
    }
    FILE *jf = cli_json_stream(&jo);
    if (jf) {
        fprintf(jf,
                "{\"command\": \"extract\", \"version\": \"%s\", \"source\": ", isomend_version());
        cli_json_string(jf, src.label);
        fprintf(jf, ", \"source_kind\": ");
        cli_json_string(jf, src.kind);
        fprintf(jf, ", \"output\": ");
        cli_json_string(jf, a->output);
        fprintf(jf, ", \"dims\": ");
        cli_json_dims(jf, vol.dims);
        fprintf(jf,
                ", \"type\": \"%s\", \"method\": \"%s\", \"pad\": %s, \"streamed\": %s, "
                "\"names_from\": ",
                vol.type == ISOMEND_U32 ? "u32" : isomend_type_name(vol.type),
                isomend_method_name(opts.method),
                (opts.flags & ISOMEND_FLAG_PAD) ? "true" : "false", stream ? "true" : "false");
        if (names_from)
            cli_json_string(jf, names_from);
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"labels\": [");
        for (size_t q = 0; q < n; q++) {
            fprintf(jf, "%s{\"value\": %" PRId64 ", \"name\": ", q ? ", " : "", lo[q].value);
            cli_json_string(jf, lo[q].name);
            fprintf(jf,
                    ", \"color\": [%u, %u, %u], \"voxels\": %" PRIu64
                    ", \"vertices\": %zu, \"triangles\": %zu, \"components\": %" PRIu64
                    ", \"file\": ",
                    lo[q].rgb[0], lo[q].rgb[1], lo[q].rgb[2], isomend_labels_voxels(res, q),
                    isomend_mesh_vertex_count(lo[q].mesh), isomend_mesh_triangle_count(lo[q].mesh),
                    lo[q].check.components);
            cli_json_string(jf, lo[q].file);
            uint64_t by[ISOMEND_ORIGIN_COUNT] = {0, 0, 0};
            const uint8_t *org = isomend_mesh_triangle_origins(lo[q].mesh);
            for (size_t t = 0; org && t < isomend_mesh_triangle_count(lo[q].mesh); t++)
                by[org[t] < ISOMEND_ORIGIN_COUNT ? org[t] : 0]++;
            fprintf(jf,
                    ", \"triangles_by_origin\": {\"table\": %" PRIu64 ", \"durst\": %" PRIu64
                    ", \"mend\": %" PRIu64 "}",
                    by[ISOMEND_ORIGIN_TABLE], by[ISOMEND_ORIGIN_DURST], by[ISOMEND_ORIGIN_MEND]);
            if (post)
                cli_json_post(jf, &pr[q]);
            fprintf(jf, ", \"check\": ");
            cli_json_check(jf, &lo[q].check);
            fprintf(jf, "}");
        }
        fprintf(jf,
                "], \"timings_ms\": {\"read\": %.3f, \"extract\": %.3f, \"check\": %.3f, "
                "\"write\": %.3f}}\n",
                src.read_ms, extract_ms, check_ms, write_ms);
        rc = cli_json_finish(&jo);
        if (rc) { /* the JSON was asked for: a run without it is a failure */
            for (size_t q = 0; q < n; q++) unlink(lo[q].file);
            if (!folder && fmt == ISOMEND_MESH_OBJ) {
                char mtl[ISOMEND_FILEIO_PATH_MAX];
                label_mtl_path(a->output, mtl, sizeof mtl);
                unlink(mtl);
            }
        }
    }

done:
    if (rc) cli_json_abort(&jo);
    for (size_t q = 0; lo && q < n; q++) {
        free(lo[q].world_pos);
        free(lo[q].world_nrm);
        free(lo[q].world_tri);
    }
    free(lo);
    for (size_t q = 0; owned && q < n; q++)
        isomend_mesh_destroy(owned[q]);
    free(owned);
    free(cur);
    free(pr);
    isomend_labels_destroy(res);
    free(copy);
    label_table_free(&table);
    free(want);
    cli_source_close(&src);
    return rc;
}

int cli_info_labels(cli_args *a)
{
    if (strcmp(a->labels, "all") != 0) {
        cli_error("--labels: info lists every label: use --labels all");
        return CLI_EXIT_USAGE;
    }
    label_table table = {NULL, 0, 0, ""};
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    if (a->label_table && label_table_read(a->label_table, &table, msg, sizeof msg)) {
        cli_error("%s", msg);
        return CLI_EXIT_FAIL;
    }
    const int quiet = (a->seen & OPT_QUIET) != 0;
    cli_json_out jo;
    cli_progress bar;
    cli_source src;
    int rc = cli_open_source_for(a, quiet, &jo, &bar, &src);
    if (rc) {
        label_table_free(&table);
        return rc;
    }
    void *copy = NULL;
    int64_t *values = NULL;
    uint64_t *voxels = NULL;
    size_t n = 0;
    isomend_volume vol;
    rc = cli_source_load(&src);
    if (!rc) rc = label_samples(&src, &vol, &copy);
    cli_progress_clear(&bar);
    if (!rc && !a->label_table && strcmp(src.kind, "nrrd") == 0 &&
        label_table_from_nrrd(a->positional[0], &table, msg, sizeof msg) < 0) {
        cli_error("%s", msg);
        rc = CLI_EXIT_FAIL;
    }
    if (!rc) {
        isomend_labels_present(&vol, NULL, NULL, 0, &n);
        values = malloc(sizeof(int64_t) * (n ? n : 1));
        voxels = malloc(sizeof(uint64_t) * (n ? n : 1));
        if (!values || !voxels) {
            cli_error("%s: out of memory listing the labels", src.label);
            rc = CLI_EXIT_FAIL;
        } else {
            isomend_labels_present(&vol, values, voxels, n, &n);
        }
    }
    FILE *text = jo.to_stdout ? stderr : stdout;
    FILE *jf = rc ? NULL : cli_json_stream(&jo);
    if (!rc && !quiet)
        fprintf(text, "%s: %zu label values (0 is the background unless listed)\n", src.label, n);
    if (jf) {
        fprintf(jf, "{\"command\": \"info\", \"version\": \"%s\", \"source\": ", isomend_version());
        cli_json_string(jf, src.label);
        fprintf(jf, ", \"labels\": [");
    }
    for (size_t q = 0; !rc && q < n; q++) {
        char name[LABEL_NAME_MAX];
        uint8_t rgb[3];
        name_and_color(&table, values[q], name, sizeof name, rgb);
        if (!quiet)
            fprintf(text, "  %" PRId64 " %s: %" PRIu64 " voxels, colour %u %u %u\n", values[q],
                    name, voxels[q], rgb[0], rgb[1], rgb[2]);
        if (jf) {
            fprintf(jf, "%s{\"value\": %" PRId64 ", \"name\": ", q ? ", " : "", values[q]);
            cli_json_string(jf, name);
            fprintf(jf, ", \"color\": [%u, %u, %u], \"voxels\": %" PRIu64 "}", rgb[0], rgb[1],
                    rgb[2], voxels[q]);
        }
    }
    if (jf) fprintf(jf, "]}\n");
    if (rc)
        cli_json_abort(&jo);
    else
        rc = cli_json_finish(&jo);
    free(values);
    free(voxels);
    free(copy);
    label_table_free(&table);
    cli_source_close(&src);
    return rc;
}
