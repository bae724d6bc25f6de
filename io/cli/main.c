/*
 * main.c - the `isomend` command line
 *
 *   isomend extract SOURCE -o MESH [options]   volume -> hole-free mesh
 *   isomend check MESH [options]               continuity checker on a mesh file
 *   isomend info SOURCE [options]              what a source holds, suggested iso
 *   isomend sample f1|f2 -o FILE.nrrd          the thesis's test volumes as NRRD
 *
 * Design rules (README, CONTRIBUTING.md): every error is one line on stderr naming
 * the file or flag and what is wrong; exit 2 for usage errors, 1 for
 * failures; outputs are written to a temporary file in the target folder and
 * renamed at the end, so a failure never leaves a partial or stale-looking
 * file.  The outputs are checked to be creatable *before* the volume is read,
 * so that a typo in -o costs nothing.  Human-readable text goes to stdout,
 * or to stderr when `--json -` claims stdout for the JSON object.
 */
#define _POSIX_C_SOURCE 200809L

#include <inttypes.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "atomic_file.h"
#include "cli.h"
#include "mesh_io.h"
#include "volume_readers.h"

#ifdef ISOMEND_HAVE_IO
#include "isomend_io.h"
#define HAVE_IO_TEXT "yes"
#else
#define HAVE_IO_TEXT "no"
#endif

/* ------------------------------------------------------------------ usage */

static const char *const usage_main =
    "usage: isomend COMMAND [options]\n"
    "\n"
    "Commands:\n"
    "  extract SOURCE -o MESH   extract a hole-free isosurface (PLY, OBJ or STL)\n"
    "  check MESH               run the continuity checker on a PLY/OBJ/STL mesh\n"
    "  info SOURCE              dimensions, type, value range, histogram, suggested iso\n"
    "  sample f1|f2 -o F.nrrd   write the thesis's test volume F1 or F2 as NRRD\n"
    "\n"
    "Run 'isomend COMMAND --help' for the options of a command.\n"
    "isomend --version prints the version.\n";

static const char *const usage_extract =
    "usage: isomend extract SOURCE -o MESH [options]\n"
    "\n"
    "SOURCE:\n"
    "  FILE.nrrd | FILE.nhdr    NRRD, attached or detached, raw or gzip\n"
    "  FILE --raw NX,NY,NZ:TYPE[:le|be]\n"
    "                           headerless samples, x fastest; TYPE one of\n"
    "                           u8 i8 u16 i16 i32 f32 f64; byte order le (default) or be\n"
    "  builtin:f1 | builtin:f2  the thesis's test functions F1, F2 (4x4x4, iso 0)\n"
#ifdef ISOMEND_HAVE_IO
    "  FOLDER | 'GLOB' | PATTERN%04d.tif | FILE1 FILE2 ... | MULTIPAGE.tif\n"
    "                           image slice stacks (OpenImageIO)\n"
    "  DICOM-FOLDER | DICOMDIR | FILE1.dcm FILE2.dcm ... | MULTIFRAME.dcm\n"
    "                           a DICOM series (GDCM), found by content; the mesh in\n"
    "                           patient coordinates (LPS, mm)\n"
#endif
    "\n"
    "MESH: .ply (binary, with normals), .obj (with normals) or .stl (binary)\n"
    "\n"
    "Options:\n"
    "  -o, --output MESH        output mesh (required)\n"
    "  --iso V                  iso level; default: the source's suggested level\n"
    "                           (Otsu, see 'isomend info'), announced on stderr;\n"
    "                           also otsu, or for CT in HU bone (300, the CT default)\n"
    "                           or skin (-500)\n"
    "  --method NAME            dmc (default), mc, durst (others if built)\n"
    "  --spacing DX,DY,DZ       sample spacing (overrides the file's)\n"
    "  --origin X,Y,Z           world position of sample (0,0,0)\n"
    "  --pad                    surround the volume with an outside layer: closed surfaces\n"
    "  --no-normals             write no vertex normals\n"
    "  --flip                   normals towards higher values, winding reversed\n"
    "  --threads N              worker threads, 0 = all cores (default)\n"
    "  --pages huge|small       memory pages of the mesh in memory: huge (transparent\n"
    "                           huge pages, the default) or small, which only some\n"
    "                           virtual machines reward (see the README)\n"
    "  --stats                  print the case histogram (thesis Table-2) and where\n"
    "                           the triangles come from (table / mending / Durst)\n"
    "  --json FILE|-            write statistics, check and timings as one JSON object\n"
    "  --quiet                  no progress bar, no summary (errors and --stats still print)\n"
#ifdef ISOMEND_HAVE_IO
    "  --first N --count N --step N   printf-pattern slice range\n"
    "  --channel N|luma         channel of multi-channel images\n"
    "  --series N|UID           DICOM: the series (N as listed by 'isomend info')\n"
    "  --grid-axes              DICOM: keep the series' own axes (rows, columns,\n"
    "                           slices) instead of turning the mesh into patient space\n"
#endif
    "\n"
    "Exit status: 0 written, 1 failure, 2 usage error, 130 interrupted (nothing written).\n";

static const char *const usage_check =
    "usage: isomend check MESH [--box MINX,MINY,MINZ,MAXX,MAXY,MAXZ] [--json FILE|-] [--quiet]\n"
    "\n"
    "Runs the continuity checker (every edge used exactly twice, in opposite\n"
    "directions, except once-used edges in a face of the volume's box) on a\n"
    "PLY (ascii/binary), OBJ or STL (ascii/binary, welded by exact position) mesh.\n"
    "The box defaults to the mesh's bounding box.\n"
    "\n"
    "Exit status: 0 continuous, 1 holes, edges used 3+ times, misoriented edges\n"
    "or an unreadable file, 2 usage error.\n";

static const char *const usage_info =
    "usage: isomend info SOURCE [--raw NX,NY,NZ:TYPE[:le|be]] [--spacing DX,DY,DZ]\n"
    "                           [--origin X,Y,Z] [--json FILE|-] [--quiet]\n"
#ifdef ISOMEND_HAVE_IO
    "                           [--first N] [--count N] [--step N] [--channel N|luma]\n"
    "                           [--series N|UID] [--grid-axes]\n"
#endif
    "\n"
    "Prints the dimensions, sample type, value range, a coarse histogram, the\n"
    "spacing and where it came from, and the suggested iso level (Otsu).\n"
    "For DICOM also the series (all of them when a folder holds several and\n"
    "--series is not given), modality, values, orientation and, for CT in HU,\n"
    "the bone and skin levels and which one extract uses.\n";

static const char *const usage_sample =
    "usage: isomend sample f1|f2 -o FILE.nrrd [--gzip]\n"
    "\n"
    "Writes the thesis's test volume (chapter 5.2), sampled at x, y, z = 0..3, f32:\n"
    "  F1 = 4y + 4(x-z)^2 - 5\n"
    "  F2 = 4(y-1)^2 + 2(x-z)^2 - 2(x+z-3)^2 + 1\n"
    "Extract at --iso 0.  The same volumes are available as SOURCE builtin:f1 / builtin:f2.\n";

/* ------------------------------------------------------------------ options */

enum {
    OPT_OUTPUT = 1u << 0, OPT_ISO = 1u << 1, OPT_METHOD = 1u << 2, OPT_RAW = 1u << 3,
    OPT_SPACING = 1u << 4, OPT_ORIGIN = 1u << 5, OPT_PAD = 1u << 6, OPT_NO_NORMALS = 1u << 7,
    OPT_FLIP = 1u << 8, OPT_STATS = 1u << 9, OPT_JSON = 1u << 10, OPT_QUIET = 1u << 11,
    OPT_THREADS = 1u << 12, OPT_BOX = 1u << 13, OPT_FIRST = 1u << 14, OPT_COUNT = 1u << 15,
    OPT_STEP = 1u << 16, OPT_CHANNEL = 1u << 17, OPT_GZIP = 1u << 18, OPT_HELP = 1u << 19,
    OPT_PAGES = 1u << 20, OPT_SERIES = 1u << 21, OPT_GRID_AXES = 1u << 22
};

static const struct {
    const char *name;
    unsigned id;
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
    {"--series", OPT_SERIES, 1}, {"--grid-axes", OPT_GRID_AXES, 0},
};

#define MAX_SOURCES 4096

typedef struct args {
    unsigned seen;
    const char *output, *json, *method_name;
    const char *positional[MAX_SOURCES];
    int npositional;
    double iso;
    const char *iso_name; /* --iso otsu|bone|skin */
    isomend_method method;
    enum { PAGES_HUGE, PAGES_SMALL } pages; /* --pages */
    double box[6];
    cli_source_opts src;
} args;

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
static int parse_args(int argc, char **argv, int first, const char *command, unsigned allowed,
                      args *a)
{
    memset(a, 0, sizeof *a);
    a->method = ISOMEND_METHOD_DMC;
    a->src.channel = -1;
    for (int i = first; i < argc; i++) {
        const char *arg = argv[i];
        if (strcmp(arg, "--") == 0) {
            for (i++; i < argc && a->npositional < MAX_SOURCES; i++)
                a->positional[a->npositional++] = argv[i];
            break;
        }
        if (arg[0] != '-' || arg[1] == '\0') {
            if (a->npositional == MAX_SOURCES) {
                cli_error("too many arguments (more than %d)", MAX_SOURCES);
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
        unsigned id = options[k].id;
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
        case OPT_PAGES:
            if (strcmp(value, "huge") == 0)
                a->pages = PAGES_HUGE;
            else if (strcmp(value, "small") == 0)
                a->pages = PAGES_SMALL;
            else {
                cli_error("--pages: '%s' is not huge or small", value);
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
    if (a->seen & (OPT_FIRST | OPT_COUNT | OPT_STEP | OPT_CHANNEL | OPT_SERIES | OPT_GRID_AXES)) {
        cli_error("--first/--count/--step/--channel/--series/--grid-axes need the slice-stack importer "
                  "(this isomend was built without it: -DISOMEND_BUILD_IO=ON)");
        return CLI_EXIT_USAGE;
    }
#endif
    return CLI_EXIT_OK;
}

/* ------------------------------------------------------------------ output helpers */

/* A JSON destination: stdout ("-") or an atomic file opened early. */
typedef struct json_out {
    int to_stdout;
    int open;
    isomend_atomic_file af;
} json_out;

static int json_prepare(json_out *j, const char *path)
{
    memset(j, 0, sizeof *j);
    if (!path) return CLI_EXIT_OK;
    if (strcmp(path, "-") == 0) {
        j->to_stdout = 1;
        return CLI_EXIT_OK;
    }
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    if (isomend_atomic_open(&j->af, path, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
        cli_error("--json %s", msg);
        return CLI_EXIT_FAIL;
    }
    j->open = 1;
    return CLI_EXIT_OK;
}

static FILE *json_stream(json_out *j)
{
    return j->to_stdout ? stdout : j->open ? j->af.fp : NULL;
}

static int json_finish(json_out *j)
{
    if (j->to_stdout) return fflush(stdout) == 0 ? CLI_EXIT_OK : CLI_EXIT_FAIL;
    if (!j->open) return CLI_EXIT_OK;
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    j->open = 0;
    if (isomend_atomic_commit(&j->af, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
        cli_error("--json %s", msg);
        return CLI_EXIT_FAIL;
    }
    return CLI_EXIT_OK;
}

static void json_abort(json_out *j)
{
    if (j->open) isomend_atomic_abort(&j->af);
    j->open = 0;
}

static void json_doubles(FILE *fp, const double *v, int n)
{
    fputc('[', fp);
    for (int i = 0; i < n; i++) fprintf(fp, "%s%.17g", i ? ", " : "", v[i]);
    fputc(']', fp);
}

static void json_dims(FILE *fp, const int64_t *d)
{
    fprintf(fp, "[%lld, %lld, %lld]", (long long)d[0], (long long)d[1], (long long)d[2]);
}

static void print_source_line(FILE *fp, const cli_source *s)
{
    const isomend_volume *v = &s->vol;
    fprintf(fp, "%s: %s (%s), %lld x %lld x %lld %s, spacing %g x %g x %g (%s), origin %g, %g, %g\n",
            s->label, s->kind, s->format, (long long)v->dims[0], (long long)v->dims[1],
            (long long)v->dims[2], isomend_type_name(v->type), v->spacing[0], v->spacing[1],
            v->spacing[2], s->spacing_from[0], v->origin[0], v->origin[1], v->origin[2]);
    if (s->oblique)
        fprintf(fp, "  note: the NRRD 'space directions' are not axis aligned; isomend uses their "
                    "lengths as spacing (the mesh is not rotated)\n");
    if (s->dicom)
        fprintf(fp, "  axes: %s\n",
                s->grid_axes ? "the series' own (--grid-axes): x rows, y columns, z slices, not rotated"
                : s->has_world ? "patient (LPS mm), turned by the series' direction cosines"
                               : "patient (LPS mm): x to the patient's left, y posterior, z head");
}

/* ------------------------------------------------------------------ extract */

/*
 * The start shared by `extract` and `info`: prepares the --json output, sets
 * up the progress bar (stderr a terminal and not --quiet) and opens SOURCE.
 * On failure nothing is left open and the exit code is returned.
 */
static int open_source_for(args *a, int quiet, json_out *jo, cli_progress *bar, cli_source *src)
{
    int rc = json_prepare(jo, a->json);
    if (rc) return rc;
    cli_progress_init(bar, !quiet && isatty(STDERR_FILENO));
    cli_active_progress = bar;
    a->src.progress = bar;
    rc = cli_source_open(a->positional, a->npositional, &a->src, src);
    if (rc) json_abort(jo);
    return rc;
}

static int cmd_extract(int argc, char **argv)
{
    args a;
    unsigned allowed = OPT_OUTPUT | OPT_ISO | OPT_METHOD | OPT_RAW | OPT_SPACING | OPT_ORIGIN |
                       OPT_PAD | OPT_NO_NORMALS | OPT_FLIP | OPT_STATS | OPT_JSON | OPT_QUIET |
                       OPT_THREADS | OPT_FIRST | OPT_COUNT | OPT_STEP | OPT_CHANNEL | OPT_HELP |
                       OPT_PAGES | OPT_SERIES | OPT_GRID_AXES;
    int rc = parse_args(argc, argv, 2, "extract", allowed, &a);
    if (rc) return rc;
    if (a.seen & OPT_HELP) {
        fputs(usage_extract, stdout);
        return CLI_EXIT_OK;
    }
    if (a.npositional == 0) {
        cli_error("extract: missing SOURCE (see isomend extract --help)");
        return CLI_EXIT_USAGE;
    }
    if (!a.output) {
        cli_error("extract: missing -o MESH (.ply, .obj or .stl)");
        return CLI_EXIT_USAGE;
    }
    isomend_mesh_format fmt = isomend_mesh_format_of(a.output);
    if (fmt == ISOMEND_MESH_UNKNOWN) {
        cli_error("-o %s: unknown mesh format (use .ply, .obj or .stl)", a.output);
        return CLI_EXIT_USAGE;
    }
    if (a.json && strcmp(a.json, a.output) == 0) {
        cli_error("--json %s: same file as -o", a.json);
        return CLI_EXIT_USAGE;
    }
    int quiet = (a.seen & OPT_QUIET) != 0;
    int json_stdout = a.json && strcmp(a.json, "-") == 0;
    FILE *text = json_stdout ? stderr : stdout;

    /* the outputs must be creatable before any work is done */
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    isomend_atomic_file probe;
    if (isomend_atomic_open(&probe, a.output, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        return CLI_EXIT_FAIL;
    }
    isomend_atomic_abort(&probe);
    json_out jo;
    cli_progress bar;
    cli_source src;
    rc = open_source_for(&a, quiet, &jo, &bar, &src);
    if (rc) return rc;
    int iso_suggested = 0;
    if (a.iso_name) {
        rc = cli_source_level(&src, a.iso_name, &a.iso);
        if (rc) goto fail_source;
    } else if (!(a.seen & OPT_ISO)) {
        cli_summary sum;
        rc = cli_source_summary(&src, &sum);
        if (rc) goto fail_source;
        if (!sum.has_suggestion) {
            cli_error("--iso is required: %s has no suggested level (all finite samples equal %g)",
                      src.label, sum.min);
            rc = CLI_EXIT_USAGE;
            goto fail_source;
        }
        a.iso = sum.suggested_iso;
        iso_suggested = 1;
        if (!quiet && strcmp(cli_source_suggested_level(&src), "bone") == 0)
            fprintf(stderr, "isomend: no --iso given: using %.9g HU, the bone level of the CT series "
                            "%s (--iso skin or --iso otsu for the others, see 'isomend info')\n",
                    a.iso, src.label);
        else if (!quiet)
            fprintf(stderr, "isomend: no --iso given: using %.9g, the suggested level of %s "
                            "(Otsu, see 'isomend info')\n",
                    a.iso, src.label);
    }

    isomend_options opts;
    isomend_options_init(&opts);
    opts.iso = a.iso;
    opts.method = a.method;
    opts.threads = a.src.threads;
    if (a.seen & OPT_PAD) opts.flags |= ISOMEND_FLAG_PAD;
    if (a.seen & OPT_NO_NORMALS) opts.flags |= ISOMEND_FLAG_NO_NORMALS;
    if (a.seen & OPT_FLIP) opts.flags |= ISOMEND_FLAG_FLIP;
    const int small_pages = a.pages == PAGES_SMALL;
    if (small_pages) opts.flags |= ISOMEND_FLAG_SMALL_PAGES;
    opts.progress = cli_progress_extract_cb; /* the bar, and how Ctrl-C cancels */
    opts.progress_user = &bar;
    isomend_mesh *mesh = NULL;
    isomend_stats stats;
    double t0 = cli_now_ms();
    isomend_status st = isomend_extract(&src.vol, &opts, &mesh, &stats);
    cli_progress_clear(&bar);
    cli_timings tm = {src.read_ms, cli_now_ms() - t0, 0};
    if (st == ISOMEND_ERR_CANCELLED) {
        cli_error("%s: interrupted", src.label);
        rc = CLI_EXIT_INTERRUPTED;
        goto fail_source;
    }
    if (st != ISOMEND_OK) {
        cli_error("%s: extraction failed: %s", src.label, isomend_status_string(st));
        rc = CLI_EXIT_FAIL;
        goto fail_source;
    }
    isomend_check_report check;
    if (cli_interrupted) { /* after the last progress call: still nothing written */
        cli_error("%s: interrupted", src.label);
        rc = CLI_EXIT_INTERRUPTED;
        goto fail_mesh;
    }
    st = isomend_mesh_check(mesh, &check);
    if (st != ISOMEND_OK) {
        cli_error("%s: continuity check failed: %s", a.output, isomend_status_string(st));
        rc = CLI_EXIT_FAIL;
        goto fail_mesh;
    }
    t0 = cli_now_ms();
    /* A DICOM series in patient space: the mesh, checked on its own grid
     * above (the map keeps its topology), is written through the map. */
    const size_t nv = isomend_mesh_vertex_count(mesh), nt = isomend_mesh_triangle_count(mesh);
    const float *out_pos = isomend_mesh_positions(mesh), *out_nrm = isomend_mesh_normals(mesh);
    const uint32_t *out_tri = isomend_mesh_triangles(mesh);
    float *world_pos = NULL, *world_nrm = NULL;
    uint32_t *world_tri = NULL;
    if (src.has_world && nt) {
        world_pos = malloc(sizeof(float) * 3 * nv);
        world_nrm = out_nrm ? malloc(sizeof(float) * 3 * nv) : NULL;
        world_tri = malloc(sizeof(uint32_t) * 3 * nt);
        if (!world_pos || !world_tri || (out_nrm && !world_nrm) ||
            isomend_mesh_copy_transformed(mesh, src.world, world_pos, world_nrm, world_tri, NULL) !=
                ISOMEND_OK) {
            cli_error("%s: out of memory placing the mesh in patient space", a.output);
            free(world_pos);
            free(world_nrm);
            free(world_tri);
            rc = CLI_EXIT_FAIL;
            goto fail_mesh;
        }
        out_pos = world_pos;
        out_nrm = world_nrm;
        out_tri = world_tri;
    }
    int wrc = isomend_write_mesh(a.output, fmt, out_pos, out_nrm, nv, out_tri, nt, msg, sizeof msg);
    free(world_pos);
    free(world_nrm);
    free(world_tri);
    if (wrc != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        rc = CLI_EXIT_FAIL;
        goto fail_mesh;
    }
    tm.write_ms = cli_now_ms() - t0;

    if (!quiet) {
        print_source_line(text, &src);
        fprintf(text, "%s at iso %.9g%s%s%s%s%s\n", isomend_method_name(a.method), a.iso,
                iso_suggested ? " (suggested)" : "", (a.seen & OPT_PAD) ? ", padded" : "",
                (a.seen & OPT_FLIP) ? ", flipped" : "", (a.seen & OPT_NO_NORMALS) ? ", no normals" : "",
                small_pages ? ", small pages" : "");
    }
    if (a.seen & OPT_STATS) cli_print_table2(text, &stats, a.method);
    if (!quiet) {
        cli_print_check(text, a.output, &check);
        fprintf(text, "time: read %.1f ms, extract %.1f ms, write %.1f ms\n", tm.read_ms,
                tm.extract_ms, tm.write_ms);
    }

    FILE *jf = json_stream(&jo);
    if (jf) {
        const isomend_volume *v = &src.vol;
        fprintf(jf, "{\"command\": \"extract\", \"version\": \"%s\", \"source\": ", isomend_version());
        cli_json_string(jf, src.label);
        fprintf(jf, ", \"source_kind\": ");
        cli_json_string(jf, src.kind);
        fprintf(jf, ", \"output\": ");
        cli_json_string(jf, a.output);
        fprintf(jf, ", \"dims\": ");
        json_dims(jf, v->dims);
        fprintf(jf, ", \"type\": \"%s\", \"spacing\": ", isomend_type_name(v->type));
        json_doubles(jf, v->spacing, 3);
        fprintf(jf, ", \"origin\": ");
        json_doubles(jf, v->origin, 3);
        fprintf(jf, ", \"world_transform\": ");
        if (src.has_world)
            json_doubles(jf, src.world, 12);
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"dicom\": ");
        cli_json_dicom(jf, &src, NULL);
        fprintf(jf, ", \"method\": \"%s\", \"iso\": %.17g, \"iso_suggested\": %s",
                isomend_method_name(a.method), a.iso, iso_suggested ? "true" : "false");
        fprintf(jf, ", \"iso_level\": ");
        if (a.iso_name || iso_suggested)
            cli_json_string(jf, a.iso_name ? a.iso_name : cli_source_suggested_level(&src));
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"pad\": %s, \"flip\": %s, \"normals\": %s, \"pages\": \"%s\"",
                (a.seen & OPT_PAD) ? "true" : "false", (a.seen & OPT_FLIP) ? "true" : "false",
                (a.seen & OPT_NO_NORMALS) ? "false" : "true", small_pages ? "small" : "huge");
        fprintf(jf, ", \"vertices\": %" PRIu64 ", \"triangles\": %" PRIu64, stats.vertices,
                stats.triangles);
        fprintf(jf, ", \"triangles_by_origin\": {\"table\": %" PRIu64 ", \"durst\": %" PRIu64
                    ", \"mend\": %" PRIu64 "}",
                stats.triangles_by_origin[ISOMEND_ORIGIN_TABLE],
                stats.triangles_by_origin[ISOMEND_ORIGIN_DURST],
                stats.triangles_by_origin[ISOMEND_ORIGIN_MEND]);
        fprintf(jf, ", \"cubes\": %" PRIu64 ", \"case_histogram\": [", stats.cubes);
        for (int c = 0; c < 15; c++)
            fprintf(jf, "%s%" PRIu64, c ? ", " : "", stats.case_histogram[c]);
        fprintf(jf, "], \"ambiguous_faces\": %" PRIu64 ", \"inverted_combinations\": %" PRIu64
                    ", \"nan_samples\": %" PRIu64 ", \"check\": ",
                stats.ambiguous_faces, stats.inverted_combinations, stats.nan_samples);
        cli_json_check(jf, &check);
        fprintf(jf, ", \"timings_ms\": {\"read\": %.3f, \"extract\": %.3f, \"write\": %.3f}}\n",
                tm.read_ms, tm.extract_ms, tm.write_ms);
        rc = json_finish(&jo);
        if (rc) {
            /* the JSON was asked for: a run without it is a failure, leave no mesh */
            unlink(a.output);
            goto fail_mesh;
        }
    }
    isomend_mesh_destroy(mesh);
    cli_source_close(&src);
    return CLI_EXIT_OK;

fail_mesh:
    isomend_mesh_destroy(mesh);
fail_source:
    json_abort(&jo);
    cli_source_close(&src);
    return rc;
}

/* ------------------------------------------------------------------ check */

static int cmd_check(int argc, char **argv)
{
    args a;
    int rc = parse_args(argc, argv, 2, "check", OPT_BOX | OPT_JSON | OPT_QUIET | OPT_HELP, &a);
    if (rc) return rc;
    if (a.seen & OPT_HELP) {
        fputs(usage_check, stdout);
        return CLI_EXIT_OK;
    }
    if (a.npositional != 1) {
        if (a.npositional)
            cli_error("check: one MESH expected, got %d", a.npositional);
        else
            cli_error("check: missing MESH (see isomend check --help)");
        return CLI_EXIT_USAGE;
    }
    const char *path = a.positional[0];
    if (isomend_mesh_format_of(path) == ISOMEND_MESH_UNKNOWN) {
        cli_error("%s: unknown mesh format (use .ply, .obj or .stl)", path);
        return CLI_EXIT_USAGE;
    }
    json_out jo;
    rc = json_prepare(&jo, a.json);
    if (rc) return rc;
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    isomend_read_mesh_result m;
    if (isomend_read_mesh(path, &m, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        json_abort(&jo);
        return CLI_EXIT_FAIL;
    }
    isomend_check_report r;
    isomend_status st = isomend_check(m.positions, m.vertex_count, m.triangles, m.triangle_count,
                                      (a.seen & OPT_BOX) ? a.box : NULL, &r);
    if (st != ISOMEND_OK) {
        cli_error("%s: check failed: %s", path, isomend_status_string(st));
        isomend_read_mesh_free(&m);
        json_abort(&jo);
        return CLI_EXIT_FAIL;
    }
    int quiet = (a.seen & OPT_QUIET) != 0;
    FILE *text = jo.to_stdout ? stderr : stdout;
    if (!quiet) {
        cli_print_check(text, path, &r);
        if (m.polygons_split || m.faces_skipped || m.stl_facets)
            fprintf(text, "  read: %s %s", m.format == ISOMEND_MESH_PLY   ? "PLY"
                                           : m.format == ISOMEND_MESH_OBJ ? "OBJ"
                                                                          : "STL",
                    m.encoding);
        if (m.stl_facets)
            fprintf(text, ", %" PRIu64 " facets welded into %zu vertices", m.stl_facets,
                    m.vertex_count);
        if (m.polygons_split) fprintf(text, ", %" PRIu64 " polygons fan-split", m.polygons_split);
        if (m.faces_skipped)
            fprintf(text, ", %" PRIu64 " faces with < 3 corners ignored", m.faces_skipped);
        if (m.polygons_split || m.faces_skipped || m.stl_facets) fputc('\n', text);
    }
    FILE *jf = json_stream(&jo);
    if (jf) {
        fprintf(jf, "{\"command\": \"check\", \"version\": \"%s\", \"mesh\": ", isomend_version());
        cli_json_string(jf, path);
        fprintf(jf, ", \"box\": ");
        if (a.seen & OPT_BOX)
            json_doubles(jf, a.box, 6);
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"polygons_split\": %" PRIu64 ", \"stl_facets\": %" PRIu64 ", \"check\": ",
                m.polygons_split, m.stl_facets);
        cli_json_check(jf, &r);
        fprintf(jf, "}\n");
    }
    isomend_read_mesh_free(&m);
    rc = json_finish(&jo);
    if (rc) return rc;
    return cli_check_has_defects(&r) ? CLI_EXIT_FAIL : CLI_EXIT_OK;
}

/* ------------------------------------------------------------------ info */

static int cmd_info(int argc, char **argv)
{
    args a;
    unsigned allowed = OPT_RAW | OPT_SPACING | OPT_ORIGIN | OPT_JSON | OPT_QUIET | OPT_FIRST |
                       OPT_COUNT | OPT_STEP | OPT_CHANNEL | OPT_HELP | OPT_SERIES | OPT_GRID_AXES;
    int rc = parse_args(argc, argv, 2, "info", allowed, &a);
    if (rc) return rc;
    if (a.seen & OPT_HELP) {
        fputs(usage_info, stdout);
        return CLI_EXIT_OK;
    }
    if (a.npositional == 0) {
        cli_error("info: missing SOURCE (see isomend info --help)");
        return CLI_EXIT_USAGE;
    }
    int quiet = (a.seen & OPT_QUIET) != 0;
    json_out jo;
    cli_progress bar;
    cli_source src;
    a.src.list_series = 1;
    rc = open_source_for(&a, quiet, &jo, &bar, &src);
    if (rc) return rc;
    if (src.series_listed) {
        /* several series, none chosen: the list is the answer */
        cli_progress_clear(&bar);
        FILE *text = jo.to_stdout ? stderr : stdout;
        if (!quiet) {
            fprintf(text, "%s: dicom, several series\n", src.label);
            cli_print_series(text, &src);
        }
        FILE *jf = json_stream(&jo);
        if (jf) {
            fprintf(jf, "{\"command\": \"info\", \"version\": \"%s\", \"source\": ", isomend_version());
            cli_json_string(jf, src.label);
            fprintf(jf, ", \"kind\": \"dicom\", \"series\": ");
            cli_json_series(jf, &src);
            fprintf(jf, ", \"series_chosen\": null}\n");
        }
        cli_source_close(&src);
        return json_finish(&jo);
    }
    cli_summary sum;
    rc = cli_source_summary(&src, &sum);
    cli_progress_clear(&bar);
    if (rc) {
        json_abort(&jo);
        cli_source_close(&src);
        return rc;
    }
    const isomend_volume *v = &src.vol;
    FILE *text = jo.to_stdout ? stderr : stdout;
    if (!quiet) {
        fprintf(text, "%s: %s (%s)\n", src.label, src.kind, src.format);
        fprintf(text, "  dimensions:  %lld x %lld x %lld (x columns, y rows, z slices)\n",
                (long long)v->dims[0], (long long)v->dims[1], (long long)v->dims[2]);
        fprintf(text, "  sample type: %s\n", isomend_type_name(v->type));
        fprintf(text, "  value range: %.9g .. %.9g (%" PRIu64 " samples, %" PRIu64 " NaN/infinite)\n",
                sum.min, sum.max, sum.samples, sum.nan_samples);
        fprintf(text, "  histogram (16 bins):\n");
        uint64_t peak = 1;
        for (int b = 0; b < 16; b++)
            if (sum.histogram[b] > peak) peak = sum.histogram[b];
        double w = (sum.max - sum.min) / 16.0;
        for (int b = 0; b < 16; b++) {
            int len = (int)(40.0 * (double)sum.histogram[b] / (double)peak + 0.5);
            fprintf(text, "    %12.6g .. %-12.6g %12" PRIu64 " %.*s\n", sum.min + b * w,
                    sum.min + (b + 1) * w, sum.histogram[b], len,
                    "########################################");
        }
        fprintf(text, "  spacing:     %g x %g x %g (from: %s, %s, %s)\n", v->spacing[0],
                v->spacing[1], v->spacing[2], src.spacing_from[0], src.spacing_from[1],
                src.spacing_from[2]);
        fprintf(text, "  origin:      %g, %g, %g\n", v->origin[0], v->origin[1], v->origin[2]);
        cli_print_dicom(text, &src, &sum);
        if (sum.has_suggestion && strcmp(cli_source_suggested_level(&src), "bone") == 0)
            fprintf(text, "  suggested iso: %.9g (the bone level, HU)\n", sum.suggested_iso);
        else if (sum.has_suggestion)
            fprintf(text, "  suggested iso: %.9g (Otsu threshold)\n", sum.suggested_iso);
        else
            fprintf(text, "  suggested iso: none (all finite samples are equal: no surface)\n");
        fprintf(text, "  read time:   %.1f ms\n", src.read_ms);
    }
    FILE *jf = json_stream(&jo);
    if (jf) {
        fprintf(jf, "{\"command\": \"info\", \"version\": \"%s\", \"source\": ", isomend_version());
        cli_json_string(jf, src.label);
        fprintf(jf, ", \"kind\": ");
        cli_json_string(jf, src.kind);
        fprintf(jf, ", \"format\": ");
        cli_json_string(jf, src.format);
        fprintf(jf, ", \"dims\": ");
        json_dims(jf, v->dims);
        fprintf(jf, ", \"type\": \"%s\", \"min\": %.17g, \"max\": %.17g, \"samples\": %" PRIu64
                    ", \"nan_samples\": %" PRIu64 ", \"histogram\": [",
                isomend_type_name(v->type), sum.min, sum.max, sum.samples, sum.nan_samples);
        for (int b = 0; b < 16; b++) fprintf(jf, "%s%" PRIu64, b ? ", " : "", sum.histogram[b]);
        fprintf(jf, "], \"spacing\": ");
        json_doubles(jf, v->spacing, 3);
        fprintf(jf, ", \"spacing_from\": [\"%s\", \"%s\", \"%s\"], \"origin\": ",
                src.spacing_from[0], src.spacing_from[1], src.spacing_from[2]);
        json_doubles(jf, v->origin, 3);
        fprintf(jf, ", \"suggested_iso\": ");
        if (sum.has_suggestion)
            fprintf(jf, "%.17g", sum.suggested_iso);
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"suggested_level\": \"%s\", \"world_transform\": ", cli_source_suggested_level(&src));
        if (src.has_world)
            json_doubles(jf, src.world, 12);
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"dicom\": ");
        cli_json_dicom(jf, &src, &sum);
        fprintf(jf, ", \"timings_ms\": {\"read\": %.3f}}\n", src.read_ms);
    }
    cli_source_close(&src);
    return json_finish(&jo);
}

/* ------------------------------------------------------------------ sample */

static int cmd_sample(int argc, char **argv)
{
    args a;
    int rc = parse_args(argc, argv, 2, "sample", OPT_OUTPUT | OPT_GZIP | OPT_QUIET | OPT_HELP, &a);
    if (rc) return rc;
    if (a.seen & OPT_HELP) {
        fputs(usage_sample, stdout);
        return CLI_EXIT_OK;
    }
    if (a.npositional != 1) {
        cli_error("sample: expected one name, f1 or f2 (see isomend sample --help)");
        return CLI_EXIT_USAGE;
    }
    char name[32];
    snprintf(name, sizeof name, "builtin:%.20s", a.positional[0]);
    float f[64];
    if (!cli_builtin_volume(name, f)) {
        cli_error("sample: unknown volume '%s' (f1 or f2)", a.positional[0]);
        return CLI_EXIT_USAGE;
    }
    if (!a.output) {
        cli_error("sample: missing -o FILE.nrrd");
        return CLI_EXIT_USAGE;
    }
    size_t n = strlen(a.output);
    if (n < 5 || strcmp(a.output + n - 5, ".nrrd") != 0) {
        cli_error("-o %s: sample volumes are written as NRRD: use a .nrrd name", a.output);
        return CLI_EXIT_USAGE;
    }
    isomend_volume vol;
    isomend_volume_init(&vol, f, ISOMEND_F32, 4, 4, 4);
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    if (isomend_fileio_write_nrrd(a.output, &vol, (a.seen & OPT_GZIP) != 0, msg, sizeof msg) !=
        ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        return CLI_EXIT_FAIL;
    }
    if (!(a.seen & OPT_QUIET))
        printf("%s: %s, 4 x 4 x 4 f32, extract with --iso 0\n", a.output, a.positional[0]);
    return CLI_EXIT_OK;
}

/* ------------------------------------------------------------------ main */

int main(int argc, char **argv)
{
    if (argc < 2) {
        fputs(usage_main, stderr);
        return CLI_EXIT_USAGE;
    }
    const char *cmd = argv[1];
    if (strcmp(cmd, "--help") == 0 || strcmp(cmd, "-h") == 0 || strcmp(cmd, "help") == 0) {
        fputs(usage_main, stdout);
        return CLI_EXIT_OK;
    }
    if (strcmp(cmd, "--version") == 0 || strcmp(cmd, "version") == 0) {
        printf("isomend %s (methods:", isomend_version());
        for (int m = 0; m < ISOMEND_METHOD_COUNT; m++)
            if (isomend_method_available((isomend_method)m))
                printf(" %s", isomend_method_name((isomend_method)m));
        printf("; slice-stack importer: %s)\n", HAVE_IO_TEXT);
        return CLI_EXIT_OK;
    }
    cli_install_signal_handlers();
    if (strcmp(cmd, "extract") == 0) return cmd_extract(argc, argv);
    if (strcmp(cmd, "check") == 0) return cmd_check(argc, argv);
    if (strcmp(cmd, "info") == 0) return cmd_info(argc, argv);
    if (strcmp(cmd, "sample") == 0) return cmd_sample(argc, argv);
    cli_error("unknown command '%s' (extract, check, info, sample; see isomend --help)", cmd);
    return CLI_EXIT_USAGE;
}
