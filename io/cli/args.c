/*
 * args.c - the options of every `isomend` command, parsed once for all of
 * them (and for isomend-mpi, which takes `isomend extract`'s options)
 *
 * One table names every option; a command passes the set it allows, so an
 * option that does not apply is a usage error naming the command.  Values
 * are parsed strictly (cli_util.c): "--iso 1O" is an error, never 1.
 */
#define _POSIX_C_SOURCE 200809L

#include "cli.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static const struct {
    const char *name;
    uint64_t id;
    int takes_value;
} options[] = {
    {"-o", OPT_OUTPUT, 1},       {"--output", OPT_OUTPUT, 1}, {"--iso", OPT_ISO, 1},
    {"--method", OPT_METHOD, 1}, {"--raw", OPT_RAW, 1},       {"--spacing", OPT_SPACING, 1},
    {"--origin", OPT_ORIGIN, 1}, {"--pad", OPT_PAD, 0},       {"--no-normals", OPT_NO_NORMALS, 0},
    {"--flip", OPT_FLIP, 0},     {"--stats", OPT_STATS, 0},   {"--json", OPT_JSON, 1},
    {"--quiet", OPT_QUIET, 0},   {"-q", OPT_QUIET, 0},        {"--threads", OPT_THREADS, 1},
    {"--box", OPT_BOX, 1},       {"--first", OPT_FIRST, 1},   {"--count", OPT_COUNT, 1},
    {"--step", OPT_STEP, 1},     {"--channel", OPT_CHANNEL, 1}, {"--gzip", OPT_GZIP, 0},
    {"--help", OPT_HELP, 0},     {"-h", OPT_HELP, 0},         {"--pages", OPT_PAGES, 1},
    {"--max-memory", OPT_MAX_MEMORY, 1}, {"--in-memory", OPT_IN_MEMORY, 0},
    {"--series", OPT_SERIES, 1}, {"--grid-axes", OPT_GRID_AXES, 0}, {"--ras", OPT_RAS, 0},
    {"--slice-positions", OPT_SLICE_POSITIONS, 1},
    {"--decimate", OPT_DECIMATE, 1},   {"--target-triangles", OPT_TARGET_TRIANGLES, 1},
    {"--max-error", OPT_MAX_ERROR, 1}, {"--smooth", OPT_SMOOTH, 1},
    {"--min-component", OPT_MIN_COMPONENT, 1}, {"--largest", OPT_LARGEST, 1},
    {"--stream", OPT_STREAM, 0}, {"--chunk-layers", OPT_CHUNK_LAYERS, 1},
    {"--labels", OPT_LABELS, 1}, {"--label-table", OPT_LABEL_TABLE, 1}, {"--format", OPT_FORMAT, 1},
};

static int parse_raw(const char *v, cli_source_opts *o)
{
    char buf[256];
    if (strlen(v) >= sizeof buf) {
        cli_error("--raw: value too long");
        return 0;
    }
    strcpy(buf, v);
    char *dims = buf, *type = strchr(buf, ':'), *order = NULL;
    if (!type) {
        cli_error("--raw: '%s' lacks ':TYPE' (expected NX,NY,NZ:TYPE[:le|be], e.g. 256,256,128:u16)", v);
        return 0;
    }
    *type++ = '\0';
    order = strchr(type, ':');
    if (order) *order++ = '\0';
    char *p = dims;
    for (int a = 0; a < 3; a++) {
        char *comma = strchr(p, ',');
        if (a < 2 && !comma) {
            cli_error("--raw: '%s' needs three dimensions NX,NY,NZ", v);
            return 0;
        }
        if (a == 2 && comma) {
            cli_error("--raw: '%s' has more than three dimensions", v);
            return 0;
        }
        if (comma) *comma = '\0';
        int64_t d;
        if (!cli_parse_int64(p, &d) || d < 1) {
            cli_error("--raw: dimension '%s' is not a positive integer", p);
            return 0;
        }
        o->raw_dims[a] = d;
        p = comma ? comma + 1 : p;
    }
    if (isomend_type_from_name(type, &o->raw_type) != ISOMEND_OK) {
        cli_error("--raw: unknown sample type '%s' (use u8, i8, u16, i16, i32, f32 or f64)", type);
        return 0;
    }
    o->raw_big_endian = 0;
    if (order) {
        if (strcmp(order, "le") == 0)
            o->raw_big_endian = 0;
        else if (strcmp(order, "be") == 0)
            o->raw_big_endian = 1;
        else {
            cli_error("--raw: byte order '%s' must be le or be", order);
            return 0;
        }
    }
    o->have_raw = 1;
    return 1;
}

static int parse_count_option(const char *flag, const char *v, int64_t min, int64_t *out)
{
    if (!cli_parse_int64(v, out) || *out < min) {
        cli_error("%s: '%s' is not an integer >= %lld", flag, v, (long long)min);
        return 0;
    }
    return 1;
}

/* Parses argv[first..argc) for a command allowing `allowed`.  Returns an exit code. */
int cli_parse_args(int argc, char **argv, int first, const char *command, uint64_t allowed,
                   cli_args *a)
{
    memset(a, 0, sizeof *a);
    a->method = ISOMEND_METHOD_DMC;
    a->src.channel = -1;
    for (int i = first; i < argc; i++) {
        const char *arg = argv[i];
        if (strcmp(arg, "--") == 0) {
            for (i++; i < argc && a->npositional < CLI_MAX_SOURCES; i++)
                a->positional[a->npositional++] = argv[i];
            break;
        }
        if (arg[0] != '-' || arg[1] == '\0') {
            if (a->npositional == CLI_MAX_SOURCES) {
                cli_error("too many arguments (more than %d)", CLI_MAX_SOURCES);
                return CLI_EXIT_USAGE;
            }
            a->positional[a->npositional++] = arg;
            continue;
        }
        char name[64];
        const char *value = NULL, *eq = strchr(arg, '=');
        size_t nlen = eq ? (size_t)(eq - arg) : strlen(arg);
        if (nlen >= sizeof name) nlen = sizeof name - 1;
        memcpy(name, arg, nlen);
        name[nlen] = '\0';
        size_t k;
        for (k = 0; k < sizeof options / sizeof options[0]; k++)
            if (strcmp(options[k].name, name) == 0) break;
        if (k == sizeof options / sizeof options[0] || !(options[k].id & allowed)) {
            cli_error("unknown option '%s' for 'isomend %s' (see isomend %s --help)", name, command,
                      command);
            return CLI_EXIT_USAGE;
        }
        uint64_t id = options[k].id;
        if (options[k].takes_value) {
            if (eq)
                value = eq + 1;
            else if (i + 1 < argc)
                value = argv[++i];
            else {
                cli_error("%s: missing value", name);
                return CLI_EXIT_USAGE;
            }
        } else if (eq) {
            cli_error("%s takes no value", name);
            return CLI_EXIT_USAGE;
        }
        if ((a->seen & id) && id != OPT_QUIET && id != OPT_HELP) {
            cli_error("%s given twice", name);
            return CLI_EXIT_USAGE;
        }
        a->seen |= id;
        switch (id) {
        case OPT_OUTPUT:
            if (!*value) {
                cli_error("%s: empty file name", name);
                return CLI_EXIT_USAGE;
            }
            a->output = value;
            break;
        case OPT_ISO:
            if (strcmp(value, "otsu") == 0 || strcmp(value, "bone") == 0 || strcmp(value, "skin") == 0) {
                a->iso_name = value;
                break;
            }
            if (!cli_parse_double(value, &a->iso)) {
                cli_error("--iso: '%s' is not a finite number (nor otsu, bone, skin)", value);
                return CLI_EXIT_USAGE;
            }
            break;
        case OPT_METHOD:
            a->method_name = value;
            if (isomend_method_from_name(value, &a->method) != ISOMEND_OK) {
                cli_error("--method: unknown method '%s' (use dmc, mc or durst; also facial, "
                          "gradient, asymptotic, tetra, mc33 where built)", value);
                return CLI_EXIT_USAGE;
            }
            if (!isomend_method_available(a->method)) {
                char avail[128] = "";
                for (int m = 0; m < ISOMEND_METHOD_COUNT; m++)
                    if (isomend_method_available((isomend_method)m)) {
                        if (avail[0]) strcat(avail, ", ");
                        strcat(avail, isomend_method_name((isomend_method)m));
                    }
                cli_error("--method: '%s' is not implemented in this build (available: %s)", value,
                          avail);
                return CLI_EXIT_USAGE;
            }
            break;
        case OPT_RAW:
            if (!parse_raw(value, &a->src)) return CLI_EXIT_USAGE;
            break;
        case OPT_SPACING:
            if (!cli_parse_doubles(value, a->src.spacing, 3) || !(a->src.spacing[0] > 0) ||
                !(a->src.spacing[1] > 0) || !(a->src.spacing[2] > 0)) {
                cli_error("--spacing: '%s' is not three positive numbers DX,DY,DZ", value);
                return CLI_EXIT_USAGE;
            }
            a->src.have_spacing = 1;
            break;
        case OPT_ORIGIN:
            if (!cli_parse_doubles(value, a->src.origin, 3)) {
                cli_error("--origin: '%s' is not three numbers X,Y,Z", value);
                return CLI_EXIT_USAGE;
            }
            a->src.have_origin = 1;
            break;
        case OPT_JSON:
            if (!*value) {
                cli_error("--json: empty file name (use - for stdout)");
                return CLI_EXIT_USAGE;
            }
            a->json = value;
            break;
        case OPT_THREADS: {
            int64_t t;
            if (!parse_count_option("--threads", value, 0, &t)) return CLI_EXIT_USAGE;
            if (t > 1024) {
                cli_error("--threads: %lld is more than 1024", (long long)t);
                return CLI_EXIT_USAGE;
            }
            a->src.threads = (int)t;
            break;
        }
        case OPT_BOX:
            if (!cli_parse_doubles(value, a->box, 6) || a->box[0] > a->box[3] ||
                a->box[1] > a->box[4] || a->box[2] > a->box[5]) {
                cli_error("--box: '%s' is not six numbers MINX,MINY,MINZ,MAXX,MAXY,MAXZ with min <= max",
                          value);
                return CLI_EXIT_USAGE;
            }
            break;
        case OPT_FIRST:
            if (!parse_count_option("--first", value, 0, &a->src.first)) return CLI_EXIT_USAGE;
            a->src.have_first = 1;
            break;
        case OPT_COUNT:
            if (!parse_count_option("--count", value, 0, &a->src.count)) return CLI_EXIT_USAGE;
            a->src.have_count = 1;
            break;
        case OPT_STEP:
            if (!parse_count_option("--step", value, 1, &a->src.step)) return CLI_EXIT_USAGE;
            a->src.have_step = 1;
            break;
        case OPT_SERIES:
            if (!*value) {
                cli_error("--series: empty (a number N from 'isomend info' or a Series Instance UID)");
                return CLI_EXIT_USAGE;
            }
            a->src.series = value;
            break;
        case OPT_GRID_AXES:
            a->src.grid_axes = 1;
            break;
        case OPT_RAS:
            a->src.ras = 1;
            break;
        case OPT_SLICE_POSITIONS:
            /* parsed when SOURCE is open: the count must match its slices */
            if (!*value || strcmp(value, "@") == 0) {
                cli_error("--slice-positions: empty (Z0,Z1,... with one z a slice, or @FILE with "
                          "one z a line)");
                return CLI_EXIT_USAGE;
            }
            a->src.slice_positions = value;
            break;
        case OPT_DECIMATE:
            if (!cli_parse_doubles(value, &a->post.ratio, 1) || !(a->post.ratio > 0) ||
                !(a->post.ratio <= 1)) {
                cli_error("--decimate: '%s' is not a fraction of the triangles to keep, in (0, 1] "
                          "(0.1 keeps a tenth)", value);
                return CLI_EXIT_USAGE;
            }
            break;
        case OPT_TARGET_TRIANGLES: {
            int64_t t;
            if (!parse_count_option("--target-triangles", value, 1, &t)) return CLI_EXIT_USAGE;
            a->post.target = (uint64_t)t;
            break;
        }
        case OPT_MAX_ERROR:
            if (!cli_parse_doubles(value, &a->post.max_error, 1) || !(a->post.max_error > 0) ||
                !isfinite(a->post.max_error)) {
                cli_error("--max-error: '%s' is not a positive distance (world units, mm for DICOM)",
                          value);
                return CLI_EXIT_USAGE;
            }
            break;
        case OPT_SMOOTH: {
            int64_t n;
            if (!parse_count_option("--smooth", value, 1, &n)) return CLI_EXIT_USAGE;
            if (n > 10000) {
                cli_error("--smooth: %lld iterations is more than 10000", (long long)n);
                return CLI_EXIT_USAGE;
            }
            a->post.smooth = (int)n;
            break;
        }
        case OPT_CHUNK_LAYERS: {
            int64_t n;
            if (!parse_count_option("--chunk-layers", value, 1, &n)) return CLI_EXIT_USAGE;
            a->post.chunk_layers = n;
            break;
        }
        case OPT_MIN_COMPONENT: {
            int64_t n;
            if (!parse_count_option("--min-component", value, 1, &n)) return CLI_EXIT_USAGE;
            a->post.min_component = (uint64_t)n;
            break;
        }
        case OPT_LARGEST: {
            int64_t n;
            if (!parse_count_option("--largest", value, 1, &n)) return CLI_EXIT_USAGE;
            a->post.largest = (uint64_t)n;
            break;
        }
        case OPT_PAGES:
            if (strcmp(value, "huge") == 0)
                a->pages = CLI_PAGES_HUGE;
            else if (strcmp(value, "small") == 0)
                a->pages = CLI_PAGES_SMALL;
            else {
                cli_error("--pages: '%s' is not huge or small", value);
                return CLI_EXIT_USAGE;
            }
            break;
        case OPT_LABELS:
            if (!*value) {
                cli_error("--labels: empty (all, or L1,L2,...)");
                return CLI_EXIT_USAGE;
            }
            a->labels = value; /* parsed by extract_labels.c */
            break;
        case OPT_LABEL_TABLE: a->label_table = value; break;
        case OPT_FORMAT:
            if (strcmp(value, "ply") && strcmp(value, "obj") && strcmp(value, "stl")) {
                cli_error("--format: '%s' is not ply, obj or stl", value);
                return CLI_EXIT_USAGE;
            }
            a->format = strcmp(value, "ply") == 0   ? "x.ply"
                        : strcmp(value, "obj") == 0 ? "x.obj"
                                                    : "x.stl";
            break;
        case OPT_MAX_MEMORY:
            if (!cli_parse_size(value, &a->max_memory) || a->max_memory == 0) {
                cli_error("--max-memory: '%s' is not a size (bytes, or a number with K, M, G or "
                          "T: 512M, 4G, 1.5G)", value);
                return CLI_EXIT_USAGE;
            }
            break;
        case OPT_CHANNEL: {
            int64_t c;
            if (strcmp(value, "luma") == 0)
                a->src.channel = -2;
            else if (cli_parse_int64(value, &c) && c >= 0 && c < 1024)
                a->src.channel = (int)c;
            else {
                cli_error("--channel: '%s' is not a channel index (0, 1, ...) or 'luma'", value);
                return CLI_EXIT_USAGE;
            }
            a->src.have_channel = 1;
            break;
        }
        default:
            break;
        }
    }
#ifndef ISOMEND_HAVE_IO
    if (a->seen & (OPT_FIRST | OPT_COUNT | OPT_STEP | OPT_CHANNEL | OPT_SERIES | OPT_GRID_AXES | OPT_RAS)) {
        cli_error("--first/--count/--step/--channel/--series/--grid-axes/--ras need the slice-stack importer "
                  "(this isomend was built without it: -DISOMEND_BUILD_IO=ON)");
        return CLI_EXIT_USAGE;
    }
#endif
    return CLI_EXIT_OK;
}

void cli_extract_options(const cli_args *a, cli_progress *bar, isomend_options *opts)
{
    isomend_options_init(opts);
    opts->iso = a->iso;
    opts->method = a->method;
    opts->threads = a->src.threads;
    if (a->seen & OPT_PAD) opts->flags |= ISOMEND_FLAG_PAD;
    if (a->seen & OPT_NO_NORMALS) opts->flags |= ISOMEND_FLAG_NO_NORMALS;
    if (a->seen & OPT_FLIP) opts->flags |= ISOMEND_FLAG_FLIP;
    if (a->pages == CLI_PAGES_SMALL) opts->flags |= ISOMEND_FLAG_SMALL_PAGES;
    opts->progress = cli_progress_extract_cb; /* the bar, and how Ctrl-C cancels */
    opts->progress_user = bar;
}
