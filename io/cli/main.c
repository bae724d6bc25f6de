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
    "  FILE.nii | FILE.nii.gz | FILE.hdr/.img\n"
    "                           a NIfTI-1/-2 volume (libnifti2), placed by its sform or\n"
    "                           qform in patient coordinates (LPS, mm; --ras for RAS)\n"
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
    "  --threads N              worker threads, 0 = the cores this process may run on\n"
    "                           (default; a streamed, checked extraction leaves one to\n"
    "                           the check)\n"
    "  --pages huge|small       memory pages of the mesh in memory: huge (transparent\n"
    "                           huge pages, the default) or small, which only some\n"
    "                           virtual machines reward (see the README)\n"
    "  --stats                  print the case histogram (thesis Table-2) and where\n"
    "                           the triangles come from (table / mending / Durst)\n"
    "  --json FILE|-            write statistics, check and timings as one JSON object\n"
    "  --quiet                  no progress bar, no summary (errors and --stats still print)\n"
    "  --max-memory SIZE        the memory to stay within (512M, 4G, 1.5G, bytes);\n"
    "                           default: the memory available. The mesh is written as\n"
    "                           it is made (and checked on the way); the volume is read\n"
    "                           slice by slice when it does not fit, and fewer threads\n"
    "                           are used when theirs do not\n"
    "  --in-memory              hold the whole mesh, then check and write it (what the\n"
    "                           steps below do anyway); streamed when it does not fit\n"
    "  --stream                 stream even when the whole mesh would fit (with the\n"
    "                           steps below: their streamed versions)\n"
    "  --slice-positions Z0,Z1,...|@FILE\n"
    "                           the z of every slice (FILE: one a line, # comments),\n"
    "                           strictly increasing, for slices not evenly spaced;\n"
    "                           replaces the z spacing and origin (not for DICOM)\n"
    "After the extraction, each keeping a closed surface closed (in this order):\n"
    "  --min-component N        drop components of fewer than N triangles\n"
    "  --largest K              keep the K largest components\n"
    "  --smooth N               N windowed sinc iterations (VTK's filter), volume kept\n"
    "  --decimate RATIO         keep RATIO of the triangles (0.1: a tenth)\n"
    "  --target-triangles N     keep N triangles\n"
    "  --max-error E            no vertex of the extraction farther than E (world units)\n"
    "                           from the result; alone: decimate as far as that allows\n"
    "--decimate and --target-triangles together keep the larger count; --max-error\n"
    "with either stops where the error would be exceeded.\n"
    "A streamed run (--stream, or a mesh larger than --max-memory) is post-processed\n"
    "as it is made, still closed, by every step; --largest K and --target-triangles N\n"
    "in two passes over a scratch copy of the stream beside MESH (the first counts)\n"
    "  --chunk-layers N         the streamed smoothing's and decimation's chunks of N\n"
    "                           layers (default: from the slice size, fewer under a\n"
    "                           tight --max-memory)\n"
    "Label maps (segmentations; integer samples), every label in one pass:\n"
    "  --labels all|L1,L2,...   one closed surface a label (all: every label but 0);\n"
    "                           -o FOLDER/ writes one file a label (NAME or label_N),\n"
    "                           -o FILE.ply all with a label and colour a face,\n"
    "                           -o FILE.obj a group a label and FILE.mtl's colours\n"
    "                           (with --stream the slices are read one at a time;\n"
    "                           --smooth, --decimate, --target-triangles, --max-error\n"
    "                           on all labels together, the surfaces two labels share\n"
    "                           kept shared; --min-component, --largest a label each)\n"
    "  --format ply|obj|stl     the files of -o FOLDER/ (default ply)\n"
    "  --label-table FILE       names and colours: 3D Slicer .ctbl/.txt, FreeSurfer\n"
    "                           LUT, ITK-SNAP label description (a .seg.nrrd's own\n"
    "                           Segment*_ keys are read without it)\n"
#ifdef ISOMEND_HAVE_IO
    "  --first N --count N --step N   printf-pattern slice range\n"
    "  --channel N|luma         channel of multi-channel images\n"
    "  --series N|UID           DICOM: the series (N as listed by 'isomend info')\n"
    "  --grid-axes              DICOM: keep the series' own axes (rows, columns,\n"
    "                           slices) instead of turning the mesh into patient space;\n"
    "                           NIfTI: the voxel grid (i, j, k times spacing), not mapped\n"
    "  --ras                    NIfTI: the file's RAS axes (FSL, FreeSurfer) instead of\n"
    "                           the patient LPS axes DICOM meshes are in\n"
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
    "                           [--origin X,Y,Z] [--json FILE|-] [--quiet] [--max-memory SIZE]\n"
    "                           [--slice-positions Z0,Z1,...|@FILE]\n"
    "                           [--labels all [--label-table FILE]]\n"
#ifdef ISOMEND_HAVE_IO
    "                           [--first N] [--count N] [--step N] [--channel N|luma]\n"
    "                           [--series N|UID] [--grid-axes] [--ras]\n"
#endif
    "\n"
    "Prints the dimensions, sample type, value range, a coarse histogram, the\n"
    "spacing and where it came from, and the suggested iso level (Otsu).\n"
    "For DICOM also the series (all of them when a folder holds several and\n"
    "--series is not given), modality, values, orientation and, for CT in HU,\n"
    "the bone and skin levels and which one extract uses.\n"
    "For NIfTI also the version, datatype, scaling and the transform used (sform,\n"
    "qform or pixdim) with its matrix.\n"
    "The slices' geometry: evenly spaced or not (gaps: median, smallest,\n"
    "largest; gantry tilt; gaps over 1.5x the median); slices whose gaps differ\n"
    "from the median by more than 1 % get one warning line on stderr.\n"
    "A volume larger than --max-memory (default: the memory available) is read\n"
    "slice by slice, twice, instead of loaded.\n"
    "With --labels all [--label-table FILE]: a label map's labels instead, each\n"
    "with its voxels, name and colour (as extract --labels names them).\n";

static const char *const usage_sample =
    "usage: isomend sample f1|f2 -o FILE.nrrd [--gzip]\n"
    "\n"
    "Writes the thesis's test volume (chapter 5.2), sampled at x, y, z = 0..3, f32:\n"
    "  F1 = 4y + 4(x-z)^2 - 5\n"
    "  F2 = 4(y-1)^2 + 2(x-z)^2 - 2(x+z-3)^2 + 1\n"
    "Extract at --iso 0.  The same volumes are available as SOURCE builtin:f1 / builtin:f2.\n";

static void print_source_line(FILE *fp, const cli_source *s)
{
    const isomend_volume *v = &s->desc;
    fprintf(fp, "%s: %s (%s), %lld x %lld x %lld %s, spacing %g x %g x %g (%s), origin %g, %g, %g\n",
            s->label, s->kind, s->format, (long long)v->dims[0], (long long)v->dims[1],
            (long long)v->dims[2], isomend_type_name(v->type), v->spacing[0], v->spacing[1],
            v->spacing[2], s->spacing_from[0], v->origin[0], v->origin[1], v->origin[2]);
    if (s->oblique)
        fprintf(fp, "  note: the NRRD 'space directions' are not axis aligned; isomend uses their "
                    "lengths as spacing (the mesh is not rotated)\n");
    if (!s->geometry.uniform)
        fprintf(fp, "  slices: not evenly spaced (%s): gaps %g .. %g, median %g%s; meshed at their "
                    "positions\n",
                s->geometry.from, s->geometry.gap_min, s->geometry.gap_max, s->geometry.gap_median,
                s->geometry.tilt_degrees != 0 ? ", tilted" : "");
    if (strcmp(s->kind, "nifti") == 0)
        fprintf(fp, "  axes: %s\n",
                s->grid_axes ? "the volume's own (--grid-axes): x = i, y = j, z = k, not mapped"
                : s->has_world ? "the file's sform/qform, in patient LPS mm (or RAS with --ras)"
                               : "patient LPS mm (or RAS with --ras), the grid axis aligned");
    else if (s->dicom)
        fprintf(fp, "  axes: %s\n",
                s->grid_axes ? "the series' own (--grid-axes): x rows, y columns, z slices, not rotated"
                : s->has_world ? "patient (LPS mm), turned by the series' direction cosines"
                               : "patient (LPS mm): x to the patient's left, y posterior, z head");
}

/* The slices' geometry, one line of `info`. */
static void print_geometry(FILE *fp, const cli_geometry *g, int64_t nz)
{
    if (nz < 2) {
        fprintf(fp, "  slices:      one\n");
        return;
    }
    if (g->uniform)
        fprintf(fp, "  slices:      evenly spaced (from: %s), gap %g\n", g->from, g->gap_median);
    else
        fprintf(fp, "  slices:      not evenly spaced (from: %s): gaps median %g, %g .. %g; %lld "
                    "differ from the median by more than 1 %%, %lld longer than 1.5x it; farthest "
                    "%g from an even grid; meshed at their positions\n",
                g->from, g->gap_median, g->gap_min, g->gap_max, (long long)g->uneven_gaps,
                (long long)g->long_gaps, g->max_offset);
    if (g->tilt_degrees != 0)
        fprintf(fp, "  tilt:        %.4g degrees (the slices' origins against the slice normal: "
                    "gantry tilt, meshed sheared)\n", g->tilt_degrees);
}

/* ------------------------------------------------------------------ extract */

/* Refuses a plan whose streaming path does not fit the limit either. */
static int plan_fits(const cli_memory_plan *p, const cli_source *s)
{
    if (!p->stream || p->streaming <= p->limit) return CLI_EXIT_OK;
    char need[32], limit[32];
    cli_error("%s: streaming slices of %lld x %lld needs about %s, more than %s of %s", s->label,
              (long long)s->desc.dims[0], (long long)s->desc.dims[1],
              cli_bytes_text(p->streaming, need, sizeof need),
              p->limit_given ? "--max-memory" : "the memory available (MemAvailable)",
              cli_bytes_text(p->limit, limit, sizeof limit));
    return p->limit_given ? CLI_EXIT_USAGE : CLI_EXIT_FAIL;
}

static void print_plan(FILE *fp, const cli_memory_plan *p)
{
    char need[32], limit[32];
    if (p->stream && p->over_limit)
        fprintf(fp, "streamed: the in-memory path would need about %s, more than %s of %s\n",
                cli_bytes_text(p->in_memory, need, sizeof need),
                p->limit_given ? "--max-memory" : "the memory available",
                cli_bytes_text(p->limit, limit, sizeof limit));
}

static void json_plan(FILE *jf, const cli_memory_plan *p, int volume_loaded)
{
    fprintf(jf, ", \"streamed\": %s, \"volume_loaded\": %s, \"stream_threads\": %d",
            p->stream ? "true" : "false", volume_loaded ? "true" : "false",
            p->stream ? p->threads : 0);
    fprintf(jf, ", \"memory_limit\": %" PRIu64
                ", \"memory_limit_from\": \"%s\", \"memory_estimate\": %" PRIu64
                ", \"memory_streaming\": %" PRIu64 ", \"peak_memory\": %" PRIu64,
            p->limit, p->limit_given ? "option" : "MemAvailable", p->in_memory, p->streaming,
            cli_peak_memory());
}

static int cmd_extract(int argc, char **argv)
{
    cli_args a;
    uint64_t allowed = OPT_OUTPUT | OPT_ISO | OPT_METHOD | OPT_RAW | OPT_SPACING | OPT_ORIGIN |
                       OPT_PAD | OPT_NO_NORMALS | OPT_FLIP | OPT_STATS | OPT_JSON | OPT_QUIET |
                       OPT_THREADS | OPT_FIRST | OPT_COUNT | OPT_STEP | OPT_CHANNEL | OPT_HELP |
                       OPT_PAGES | OPT_MAX_MEMORY | OPT_SERIES | OPT_GRID_AXES | OPT_RAS |
                       OPT_SLICE_POSITIONS | OPT_POST | OPT_IN_MEMORY | OPT_STREAM |
                       OPT_CHUNK_LAYERS | OPT_LABELS | OPT_LABEL_TABLE | OPT_FORMAT;
    int rc = cli_parse_args(argc, argv, 2, "extract", allowed, &a);
    if (rc) return rc;
    if (a.seen & OPT_HELP) {
        fputs(usage_extract, stdout);
        return CLI_EXIT_OK;
    }
    if (a.seen & OPT_LABELS) return cli_extract_labels(&a); /* a label map */
    if (a.seen & (OPT_LABEL_TABLE | OPT_FORMAT)) {
        cli_error("%s: only with --labels (a label map's surfaces)",
                  (a.seen & OPT_LABEL_TABLE) ? "--label-table" : "--format");
        return CLI_EXIT_USAGE;
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
    if ((a.seen & OPT_STREAM) && (a.seen & (OPT_IN_MEMORY | OPT_PAGES))) {
        cli_error("--stream: not with %s (the whole mesh in memory)",
                  (a.seen & OPT_IN_MEMORY) ? "--in-memory" : "--pages");
        return CLI_EXIT_USAGE;
    }
    if (cli_chunk_layers_unused(&a)) return CLI_EXIT_USAGE;
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
    cli_json_out jo;
    cli_progress bar;
    cli_source src;
    rc = cli_open_source_for(&a, quiet, &jo, &bar, &src);
    if (rc) return rc;

    isomend_options opts;
    cli_extract_options(&a, &bar, &opts);
    const int small_pages = a.pages == CLI_PAGES_SMALL;
    /* the mesh goes to the file as it is made, checked on the way, unless the
     * run needs it whole: post-processing, --in-memory, --pages (and fits;
     * --stream: never); a streamed --min-component, --smooth, --decimate,
     * --max-error work as the mesh is made, --largest and --target-triangles
     * in two passes over a spool */
    const int whole_mesh =
        !(a.seen & OPT_STREAM) && (a.seen & (OPT_POST | OPT_IN_MEMORY | OPT_PAGES)) != 0;
    cli_memory_plan plan;
    cli_memory_plan_make(&src.desc, &opts, fmt, a.max_memory, whole_mesh, &a.post, &plan);
    rc = plan_fits(&plan, &src);
    if (rc) goto fail_source;

    /* The whole mesh: the volume is loaded, the mesh checked, then written.
     * Streamed: the slices go through the extraction and the mesh to the
     * writer and the continuity check as it is made; the volume is loaded
     * first only when a level is computed from it (no --iso, or a named one)
     * and it fits beside the stream, else read slice by slice as it goes. */
    const int needs_level = a.iso_name || !(a.seen & OPT_ISO);
    const int fits = !plan.limit || plan.volume + plan.streaming <= plan.limit;
    const int load = !plan.stream || ((needs_level || !cli_source_reads_by_slice(&src)) && fits);
    if (load) {
        rc = cli_source_load(&src);
        if (rc) goto fail_source;
    }
    int iso_suggested = 0;
    a.iso = (a.seen & OPT_ISO) ? a.iso : 0;
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
    opts.iso = a.iso;

    isomend_mesh *mesh = NULL;
    isomend_stats stats;
    isomend_check_report check;
    cli_post_report post;
    memset(&post, 0, sizeof post);
    int checked = 0;
    uint64_t check_skipped = 0; /* the check's need, when it did not fit the limit */
    uint64_t check_peak = 0;    /* a streamed check's tables and queue at their largest */
    uint64_t decimate_peak = 0; /* a streamed decimation's bytes at their largest */
    uint64_t smooth_peak = 0;   /* a streamed smoothing's */
    cli_timings tm = {0, 0, 0};
    if (plan.stream) {
        /* the mesh through [the clean-up], [the smoothing], [the decimation], [the check],
         * [the patient map] to the file */
        isomend_options stream_opts = opts;
        stream_opts.threads = plan.threads;
        cli_outputs out;
        if (cli_outputs_begin(&out, a.output, fmt, !(opts.flags & ISOMEND_FLAG_NO_NORMALS),
                              src.has_world ? src.world : NULL, src.label, &src.desc, &stream_opts,
                              plan.check ? plan.check_queue : 0, &a.post,
                              plan.decimate_layers)) {
            rc = CLI_EXIT_FAIL;
            goto fail_source;
        }
        double t0 = cli_now_ms();
        rc = cli_stream_extract(&src, &stream_opts, out.sink, &stats);
        rc = cli_outputs_finish(&out, rc, src.label, &post, &check, &checked);
        check_peak = out.check_peak;
        decimate_peak = out.decimate_peak;
        smooth_peak = out.smooth_peak;
        if (!plan.check) check_skipped = plan.check_need; /* did not fit beside the stream */
        cli_progress_clear(&bar);
        /* the extraction's time includes the writes made meanwhile */
        tm.read_ms = src.read_ms;
        tm.extract_ms = cli_now_ms() - t0 - src.read_ms;
        if (!rc && cli_interrupted) { /* nothing is visible until the commit */
            cli_error("%s: interrupted", src.label);
            rc = CLI_EXIT_INTERRUPTED;
        }
        if (rc) {
            cli_outputs_abort(&out);
            goto fail_source;
        }
        t0 = cli_now_ms();
        rc = cli_outputs_commit(&out);
        if (rc) goto fail_source;
        tm.write_ms = cli_now_ms() - t0;
    } else {
        tm.read_ms = src.read_ms;
        double t0 = cli_now_ms();
        isomend_status st = isomend_extract(&src.desc, &opts, &mesh, &stats);
        cli_progress_clear(&bar);
        tm.extract_ms = cli_now_ms() - t0;
        rc = cli_extract_status(st, src.label, "extraction");
        if (rc) goto fail_source;
        if (cli_interrupted) { /* after the last progress call: still nothing written */
            cli_error("%s: interrupted", src.label);
            rc = CLI_EXIT_INTERRUPTED;
            goto fail_mesh;
        }
        /* the samples are no longer needed; the check runs if it fits the limit */
        cli_source_drop_samples(&src);
        if (a.seen & OPT_POST) {
            rc = cli_postprocess(&mesh, &a.post, &post, src.label);
            if (rc) goto fail_mesh;
        }
        const uint64_t check_need = isomend_mesh_check_memory(mesh);
        checked = !plan.limit || cli_resident_memory() + check_need <= plan.limit;
        if (!checked) check_skipped = check_need;
        st = checked ? isomend_mesh_check(mesh, &check) : ISOMEND_OK;
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
                isomend_mesh_copy_transformed(mesh, src.world, world_pos, world_nrm, world_tri,
                                              NULL) != ISOMEND_OK) {
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
    }

    if (!quiet) {
        print_source_line(text, &src);
        fprintf(text, "%s at iso %.9g%s%s%s%s%s\n", isomend_method_name(a.method), a.iso,
                iso_suggested ? " (suggested)" : "", (a.seen & OPT_PAD) ? ", padded" : "",
                (a.seen & OPT_FLIP) ? ", flipped" : "", (a.seen & OPT_NO_NORMALS) ? ", no normals" : "",
                small_pages ? ", small pages" : "");
        print_plan(text, &plan);
    }
    if (a.seen & OPT_STATS) cli_print_table2(text, &stats, a.method);
    if (!quiet) cli_print_post(text, &post);
    if (!quiet) {
        char need[32], limit[32];
        if (checked)
            cli_print_check(text, a.output, &check);
        else if (check_skipped)
            fprintf(text, "%s: %" PRIu64 " vertices, %" PRIu64 " triangles; the continuity check "
                          "was not run: it needs about %s more, beyond %s of %s (run 'isomend "
                          "check %s')\n",
                    a.output, stats.vertices, stats.triangles,
                    cli_bytes_text(check_skipped, need, sizeof need),
                    plan.limit_given ? "--max-memory" : "the memory available",
                    cli_bytes_text(plan.limit, limit, sizeof limit), a.output);
        fprintf(text, "time: read %.1f ms, extract %.1f ms, write %.1f ms\n", tm.read_ms,
                tm.extract_ms, tm.write_ms);
    }

    FILE *jf = cli_json_stream(&jo);
    if (jf) {
        fprintf(jf, "{\"command\": \"extract\", \"version\": \"%s\", ", isomend_version());
        cli_json_run(jf, src.label, src.kind, a.output, &src.desc, &opts, iso_suggested);
        cli_json_geometry(jf, &src.geometry);
        fprintf(jf, ", \"world_transform\": ");
        if (src.has_world)
            cli_json_doubles(jf, src.world, 12);
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"dicom\": ");
        cli_json_dicom(jf, &src);
        fprintf(jf, ", \"iso_level\": ");
        if (a.iso_name || iso_suggested)
            cli_json_string(jf, a.iso_name ? a.iso_name : cli_source_suggested_level(&src));
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"pages\": \"%s\"", small_pages ? "small" : "huge");
        json_plan(jf, &plan, load);
        cli_json_stats(jf, &stats);
        fprintf(jf, ", \"check\": ");
        if (checked)
            cli_json_check(jf, &check);
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"check_skipped\": %s", checked ? "null" : "\"memory\"");
        /* a streamed check's memory against what the plan counted for it */
        if (check_peak)
            fprintf(jf, ", \"check_memory\": {\"peak\": %" PRIu64 ", \"planned\": %" PRIu64 "}",
                    check_peak, plan.check_need);
        else
            fprintf(jf, ", \"check_memory\": null");
        /* a streamed decimation's memory against what the plan counted for it */
        if (decimate_peak)
            fprintf(jf, ", \"decimate_memory\": {\"peak\": %" PRIu64 ", \"planned\": %" PRIu64 "}",
                    decimate_peak, plan.decimate_need);
        else
            fprintf(jf, ", \"decimate_memory\": null");
        if (smooth_peak)
            fprintf(jf, ", \"smooth_memory\": {\"peak\": %" PRIu64 ", \"planned\": %" PRIu64 "}",
                    smooth_peak, plan.smooth_need);
        else
            fprintf(jf, ", \"smooth_memory\": null");
        cli_json_post(jf, &post);
        fprintf(jf, ", \"timings_ms\": {\"read\": %.3f, \"extract\": %.3f, \"write\": %.3f}}\n",
                tm.read_ms, tm.extract_ms, tm.write_ms);
        rc = cli_json_finish(&jo);
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
    cli_json_abort(&jo);
    cli_source_close(&src);
    return rc;
}

/* ------------------------------------------------------------------ check */

static int cmd_check(int argc, char **argv)
{
    cli_args a;
    int rc = cli_parse_args(argc, argv, 2, "check", OPT_BOX | OPT_JSON | OPT_QUIET | OPT_HELP, &a);
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
    cli_json_out jo;
    rc = cli_json_prepare(&jo, a.json);
    if (rc) return rc;
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    isomend_read_mesh_result m;
    if (isomend_read_mesh(path, &m, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        cli_json_abort(&jo);
        return CLI_EXIT_FAIL;
    }
    isomend_check_report r;
    isomend_status st = isomend_check(m.positions, m.vertex_count, m.triangles, m.triangle_count,
                                      (a.seen & OPT_BOX) ? a.box : NULL, &r);
    if (st != ISOMEND_OK) {
        cli_error("%s: check failed: %s", path, isomend_status_string(st));
        isomend_read_mesh_free(&m);
        cli_json_abort(&jo);
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
    FILE *jf = cli_json_stream(&jo);
    if (jf) {
        fprintf(jf, "{\"command\": \"check\", \"version\": \"%s\", \"mesh\": ", isomend_version());
        cli_json_string(jf, path);
        fprintf(jf, ", \"box\": ");
        if (a.seen & OPT_BOX)
            cli_json_doubles(jf, a.box, 6);
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"polygons_split\": %" PRIu64 ", \"stl_facets\": %" PRIu64 ", \"check\": ",
                m.polygons_split, m.stl_facets);
        cli_json_check(jf, &r);
        fprintf(jf, "}\n");
    }
    isomend_read_mesh_free(&m);
    rc = cli_json_finish(&jo);
    if (rc) return rc;
    return cli_check_has_defects(&r) ? CLI_EXIT_FAIL : CLI_EXIT_OK;
}

/* ------------------------------------------------------------------ info */

static int cmd_info(int argc, char **argv)
{
    cli_args a;
    uint64_t allowed = OPT_RAW | OPT_SPACING | OPT_ORIGIN | OPT_JSON | OPT_QUIET | OPT_FIRST |
                       OPT_COUNT | OPT_STEP | OPT_CHANNEL | OPT_HELP | OPT_MAX_MEMORY | OPT_SERIES |
                       OPT_GRID_AXES | OPT_RAS | OPT_SLICE_POSITIONS | OPT_LABELS | OPT_LABEL_TABLE;
    int rc = cli_parse_args(argc, argv, 2, "info", allowed, &a);
    if (rc) return rc;
    if (a.seen & OPT_HELP) {
        fputs(usage_info, stdout);
        return CLI_EXIT_OK;
    }
    if (a.npositional == 0) {
        cli_error("info: missing SOURCE (see isomend info --help)");
        return CLI_EXIT_USAGE;
    }
    if (a.seen & OPT_LABELS) return cli_info_labels(&a); /* a label map's labels */
    if (a.seen & OPT_LABEL_TABLE) {
        cli_error("--label-table: only with --labels all");
        return CLI_EXIT_USAGE;
    }
    int quiet = (a.seen & OPT_QUIET) != 0;
    cli_json_out jo;
    cli_progress bar;
    cli_source src;
    a.src.list_series = 1;
    rc = cli_open_source_for(&a, quiet, &jo, &bar, &src);
    if (rc) return rc;
    if (src.series_listed) {
        /* several series, none chosen: the list is the answer */
        cli_progress_clear(&bar);
        FILE *text = jo.to_stdout ? stderr : stdout;
        if (!quiet) {
            fprintf(text, "%s: dicom, several series\n", src.label);
            cli_print_series(text, &src);
        }
        FILE *jf = cli_json_stream(&jo);
        if (jf) {
            fprintf(jf, "{\"command\": \"info\", \"version\": \"%s\", \"source\": ", isomend_version());
            cli_json_string(jf, src.label);
            fprintf(jf, ", \"kind\": \"dicom\", \"series\": ");
            cli_json_series(jf, &src);
            fprintf(jf, ", \"series_chosen\": null}\n");
        }
        cli_source_close(&src);
        return cli_json_finish(&jo);
    }
    /* a volume larger than the limit is analysed slice by slice (read twice) */
    uint64_t limit = a.max_memory ? a.max_memory : cli_memory_available();
    int streamed = limit && src.slice_bytes * (uint64_t)src.desc.dims[2] > limit;
    cli_summary sum;
    rc = streamed ? CLI_EXIT_OK : cli_source_load(&src);
    if (!rc) rc = cli_source_summary(&src, &sum);
    cli_progress_clear(&bar);
    if (rc) {
        cli_json_abort(&jo);
        cli_source_close(&src);
        return rc;
    }
    const isomend_volume *v = &src.desc;
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
        print_geometry(text, &src.geometry, v->dims[2]);
        cli_print_dicom(text, &src);
        cli_print_nifti(text, &src);
        if (sum.has_suggestion && strcmp(cli_source_suggested_level(&src), "bone") == 0)
            fprintf(text, "  suggested iso: %.9g (the bone level, HU)\n", sum.suggested_iso);
        else if (sum.has_suggestion)
            fprintf(text, "  suggested iso: %.9g (Otsu threshold)\n", sum.suggested_iso);
        else
            fprintf(text, "  suggested iso: none (all finite samples are equal: no surface)\n");
        fprintf(text, "  read time:   %.1f ms%s\n", src.read_ms,
                streamed ? " (read slice by slice, twice: larger than the memory limit)" : "");
    }
    FILE *jf = cli_json_stream(&jo);
    if (jf) {
        fprintf(jf, "{\"command\": \"info\", \"version\": \"%s\", \"source\": ", isomend_version());
        cli_json_string(jf, src.label);
        fprintf(jf, ", \"kind\": ");
        cli_json_string(jf, src.kind);
        fprintf(jf, ", \"format\": ");
        cli_json_string(jf, src.format);
        fprintf(jf, ", \"dims\": ");
        cli_json_dims(jf, v->dims);
        fprintf(jf, ", \"type\": \"%s\", \"min\": %.17g, \"max\": %.17g, \"samples\": %" PRIu64
                    ", \"nan_samples\": %" PRIu64 ", \"histogram\": [",
                isomend_type_name(v->type), sum.min, sum.max, sum.samples, sum.nan_samples);
        for (int b = 0; b < 16; b++) fprintf(jf, "%s%" PRIu64, b ? ", " : "", sum.histogram[b]);
        fprintf(jf, "], \"spacing\": ");
        cli_json_doubles(jf, v->spacing, 3);
        fprintf(jf, ", \"spacing_from\": [\"%s\", \"%s\", \"%s\"], \"origin\": ",
                src.spacing_from[0], src.spacing_from[1], src.spacing_from[2]);
        cli_json_doubles(jf, v->origin, 3);
        fprintf(jf, ", \"suggested_iso\": ");
        if (sum.has_suggestion)
            fprintf(jf, "%.17g", sum.suggested_iso);
        else
            fprintf(jf, "null");
        fprintf(jf, ", \"streamed\": %s, \"peak_memory\": %" PRIu64, streamed ? "true" : "false",
                cli_peak_memory());
        fprintf(jf, ", \"suggested_level\": \"%s\", \"world_transform\": ",
                cli_source_suggested_level(&src));
        if (src.has_world)
            cli_json_doubles(jf, src.world, 12);
        else
            fprintf(jf, "null");
        cli_json_geometry(jf, &src.geometry);
        /* where each slice's sample (0, 0) is meshed, in the volume's frame
         * (before world_transform): null for an evenly spaced grid */
        fprintf(jf, ", \"slice_origins\": ");
        if (v->slice_origins) {
            fputc('[', jf);
            for (int64_t k = 0; k < v->dims[2]; k++) {
                fputs(k ? ", " : "", jf);
                cli_json_doubles(jf, v->slice_origins + 3 * k, 3);
            }
            fputc(']', jf);
        } else {
            fprintf(jf, "null");
        }
        fprintf(jf, ", \"dicom\": ");
        cli_json_dicom(jf, &src);
        fprintf(jf, ", \"nifti\": ");
        cli_json_nifti(jf, &src);
        fprintf(jf, ", \"timings_ms\": {\"read\": %.3f}}\n", src.read_ms);
    }
    cli_source_close(&src);
    return cli_json_finish(&jo);
}

/* ------------------------------------------------------------------ sample */

static int cmd_sample(int argc, char **argv)
{
    cli_args a;
    int rc = cli_parse_args(argc, argv, 2, "sample", OPT_OUTPUT | OPT_GZIP | OPT_QUIET | OPT_HELP, &a);
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
