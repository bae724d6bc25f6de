/*
 * mpi_main.c - isomend-mpi: `mpirun -n N isomend-mpi extract SOURCE -o MESH [options]`
 *
 * One mesh from N processes (on one machine or many, sharing the folders of
 * SOURCE and MESH), the same file byte for byte as `isomend extract` writes:
 *
 *   1. every rank parses the options (the command line's own parser, args.c)
 *      and opens SOURCE (raw, NRRD or an image stack: headers only);
 *   2. the marched slices are cut into N slabs (slab.h); without --iso the
 *      suggested level is computed from every rank's slab, the sums reduced;
 *   3. each rank streams its slab: its slices and a halo are read one at a
 *      time and pushed to the core's piece (slab.c), whose vertices are
 *      encoded into scratch files beside MESH as they come and whose
 *      triangles wait there as local ids (STL facets are encoded at once);
 *      a rank holds a few slices, never its mesh (slab_memory());
 *   4. MPI_Exscan of the vertex counts gives each rank its first global id;
 *      each rank sends the (key, id) pairs of its first plane to the rank
 *      below, which maps the keys its last layer refers to, and encodes its
 *      triangles with global ids (mpi_writer_faces);
 *   5. rank 0 creates a temporary file beside MESH; the ranks write their
 *      parts at offsets from prefix sums with MPI_File_write_at_all
 *      (mpi_writer.h); rank 0 renames the file once every rank has
 *      succeeded.
 *
 * Failures: every step ends with agree(): an MPI_Allreduce finds the lowest
 * rank that failed, its message is broadcast and printed once by rank 0
 * ("isomend-mpi: MESSAGE (rank R of N)"), every rank exits with its exit
 * code, and rank 0 removes the temporary file: no output, whatever failed
 * where.  Messages are captured (cli_error_capture), never printed by the
 * other ranks.  Exit codes as `isomend extract`: 0, 1 failure, 2 usage, 130
 * interrupted.
 */
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <signal.h>
#include <inttypes.h>
#include <mpi.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "atomic_file.h"
#include "cli.h"
#include "mesh_writer.h"
#include "mpi_decimate.h"
#include "mpi_writer.h"
#include "slab.h"

static const char *const usage =
    "usage: mpirun -n N isomend-mpi extract SOURCE -o MESH [options]\n"
    "\n"
    "The options and SOURCE kinds of 'isomend extract' (see isomend extract --help).\n"
    "Each of the N ranks reads its own slab of slices and writes its part of MESH\n"
    "(.ply, .obj or .stl) with MPI-IO; the file is the one 'isomend extract' writes.\n"
    "Every method splits between ranks.  The continuity check is not run: use\n"
    "isomend check.\n"
    "\n"
    "--min-component N, --largest K, --smooth N, --decimate RATIO, --target-triangles N,\n"
    "--max-error E [--chunk-layers N]: rank 0 post-processes the ranks' slabs as one\n"
    "stream, checks and writes the mesh: the file 'isomend extract --stream' with the\n"
    "same steps writes, for any number of ranks (--largest, --target-triangles: in two\n"
    "passes over a scratch copy of the stream beside MESH).\n";

static MPI_Comm comm = MPI_COMM_WORLD;
static int rank, ranks;
static char message[ISOMEND_FILEIO_MSG_SIZE + 512];

/* Agreement on failure: returns the exit code of the lowest failing rank
 * (0 when every rank succeeded); rank 0 prints that rank's message. */
static int agree(int rc)
{
    int mine = rc ? rank : ranks, lowest;
    MPI_Allreduce(&mine, &lowest, 1, MPI_INT, MPI_MIN, comm);
    if (lowest == ranks) return CLI_EXIT_OK;
    int code = rc;
    char text[sizeof message];
    memcpy(text, message, sizeof text);
    MPI_Bcast(&code, 1, MPI_INT, lowest, comm);
    MPI_Bcast(text, (int)sizeof text, MPI_CHAR, lowest, comm);
    if (rank == 0) {
        text[sizeof text - 1] = '\0';
        if (ranks > 1)
            fprintf(stderr, "isomend-mpi: %s (rank %d of %d)\n", text[0] ? text : "failed", lowest,
                    ranks);
        else
            fprintf(stderr, "isomend-mpi: %s\n", text[0] ? text : "failed");
    }
    return code ? code : CLI_EXIT_FAIL;
}

/* The owner of marched slice k (the rank whose slab holds it). */
static int owner_of(int64_t nz_marched, int64_t k)
{
    for (int r = 0; r < ranks; r++) {
        int64_t f, e;
        slab_split(nz_marched, ranks, r, &f, &e);
        if (k >= f && k < e) return r;
    }
    return -1;
}

/* The suggested iso of the whole volume from every rank's own slices. */
static int suggest_iso(cli_source *s, int64_t k0, int64_t k1, cli_summary *sum)
{
    const int64_t nx = s->desc.dims[0], ny = s->desc.dims[1];
    const int64_t ts = (int64_t)isomend_type_size(s->desc.type);
    double level;
    if (cli_source_fixed_level(s, &level)) { /* a CT series: the bone level, as isomend's */
        memset(sum, 0, sizeof *sum);
        sum->has_suggestion = 1;
        sum->suggested_iso = level;
        return CLI_EXIT_OK;
    }
    char *slice = k1 > k0 ? malloc((size_t)s->slice_bytes) : NULL;
    int rc = k1 > k0 && !slice ? CLI_EXIT_FAIL : CLI_EXIT_OK;
    if (rc) cli_error("%s: out of memory for a slice", s->label);
    cli_summary_acc acc;
    cli_summary_start(&acc, sum, s->desc.type);
    for (int pass = 0; pass < 2; pass++) {
        if (!rc) rc = cli_slices_seek(s, k0 < s->desc.dims[2] ? k0 : 0);
        for (int64_t k = k0; k < k1 && !rc; k++) {
            rc = cli_slices_next(s, slice);
            if (!rc) cli_summary_plane(&acc, pass, slice, ts, ts * nx, nx, ny);
        }
        if ((rc = agree(rc)) != 0) break;
        if (pass == 0) {
            uint64_t n[3] = {sum->samples, sum->nan_samples, acc.finite}, t[3];
            MPI_Allreduce(n, t, 3, MPI_UINT64_T, MPI_SUM, comm);
            sum->samples = t[0];
            sum->nan_samples = t[1];
            acc.finite = t[2];
            double lo = acc.lo, hi = acc.hi;
            MPI_Allreduce(&lo, &acc.lo, 1, MPI_DOUBLE, MPI_MIN, comm);
            MPI_Allreduce(&hi, &acc.hi, 1, MPI_DOUBLE, MPI_MAX, comm);
            if (!cli_summary_range_done(&acc)) break;
        } else {
            uint64_t h[16];
            MPI_Allreduce(sum->histogram, h, 16, MPI_UINT64_T, MPI_SUM, comm);
            memcpy(sum->histogram, h, sizeof h);
            uint64_t *fine = malloc(sizeof acc.fine);
            if (fine) {
                MPI_Allreduce(acc.fine, fine, CLI_OTSU_BINS, MPI_UINT64_T, MPI_SUM, comm);
                memcpy(acc.fine, fine, sizeof acc.fine);
                free(fine);
            } else {
                MPI_Allreduce(MPI_IN_PLACE, acc.fine, CLI_OTSU_BINS, MPI_UINT64_T, MPI_SUM, comm);
            }
            cli_summary_finish(&acc);
        }
    }
    free(slice);
    return rc;
}

/* Sends the first plane's (key, global id) pairs down, maps the foreign keys
 * of the last layer with the pairs from above. */
static int exchange_plane(const slab_piece *p, int64_t nz_marched, uint64_t first_id,
                          uint64_t *foreign_ids)
{
    const int owns = p->first < p->end;
    MPI_Request req = MPI_REQUEST_NULL;
    uint64_t *out = NULL;
    int rc = CLI_EXIT_OK;
    if (owns && p->first > 0) {
        out = malloc((2 * p->nshared + 1) * sizeof *out);
        if (!out) {
            cli_error("out of memory");
            rc = CLI_EXIT_FAIL;
        }
        size_t n = out ? p->nshared : 0;
        for (size_t q = 0; q < n; q++) {
            out[2 * q] = p->shared[2 * q];
            out[2 * q + 1] = first_id + p->shared[2 * q + 1];
        }
        MPI_Isend(out, (int)(2 * n), MPI_UINT64_T, owner_of(nz_marched, p->first - 1), 7, comm,
                  &req);
    }
    if (owns && p->end < nz_marched) {
        MPI_Status st;
        int from = owner_of(nz_marched, p->end), count = 0;
        MPI_Probe(from, 7, comm, &st);
        MPI_Get_count(&st, MPI_UINT64_T, &count);
        uint64_t *in = malloc(((size_t)count + 1) * sizeof *in);
        if (!in) { /* still receive, or the sender waits for ever */
            uint64_t dummy;
            MPI_Recv(&dummy, 0, MPI_UINT64_T, from, 7, comm, MPI_STATUS_IGNORE);
            cli_error("out of memory");
            rc = CLI_EXIT_FAIL;
        } else {
            MPI_Recv(in, count, MPI_UINT64_T, from, 7, comm, MPI_STATUS_IGNORE);
            size_t pairs = (size_t)count / 2;
            for (size_t f = 0; f < p->nforeign && rc == CLI_EXIT_OK; f++) {
                size_t lo = 0, hi = pairs;
                while (lo < hi) {
                    size_t mid = lo + (hi - lo) / 2;
                    if (in[2 * mid] < p->foreign_keys[f]) lo = mid + 1;
                    else hi = mid;
                }
                if (lo == pairs || in[2 * lo] != p->foreign_keys[f]) {
                    cli_error("slice %lld: rank %d has no vertex of key %llu that this rank's "
                              "last layer uses (internal error)",
                              (long long)p->end, from, (unsigned long long)p->foreign_keys[f]);
                    rc = CLI_EXIT_FAIL;
                } else {
                    foreign_ids[f] = in[2 * lo + 1];
                }
            }
            free(in);
        }
    }
    MPI_Wait(&req, MPI_STATUS_IGNORE);
    free(out);
    return rc;
}

/* The summary's first lines: the source, the method and level. */
static void print_run(FILE *text, const cli_source *sl, const cli_args *a, int iso_suggested,
                      int pad, int normals)
{
    const isomend_volume *v = &sl->desc;
    fprintf(text, "%s: %s (%s), %lld x %lld x %lld %s, %d rank%s\n", sl->label, sl->kind,
            sl->format, (long long)v->dims[0], (long long)v->dims[1], (long long)v->dims[2],
            isomend_type_name(v->type), ranks, ranks > 1 ? "s" : "");
    fprintf(text, "%s at iso %.9g%s%s%s%s\n", isomend_method_name(a->method), a->iso,
            iso_suggested ? " (suggested)" : "", pad ? ", padded" : "",
            (a->seen & OPT_FLIP) ? ", flipped" : "", normals ? "" : ", no normals");
}

/*
 * The post-processing steps (--min-component N, --largest K, --smooth N,
 * --decimate RATIO, --target-triangles N, --max-error E): every rank records its
 * slab's piece (mpi_decimate.h); rank 0 replays them as one stream into the
 * streamed steps (clean-up or --largest's two passes, smoothing, decimation:
 * cli_outputs, which spools the replay for the second pass of --largest and
 * --target-triangles), the
 * continuity check and one writer, as `isomend extract --stream` with the
 * same steps does (the same bytes), and reports.
 */
static int run_decimated(const cli_args *a, cli_source *sl, const isomend_options *opts,
                         isomend_mesh_format fmt, int64_t first, int64_t end, int iso_suggested,
                         cli_json_out *jo, double t_start, FILE *text)
{
    const int quiet = (a->seen & OPT_QUIET) != 0;
    const int64_t pad = (opts->flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    const uint64_t plane =
        (uint64_t)(sl->desc.dims[0] + 2 * pad) * (uint64_t)(sl->desc.dims[1] + 2 * pad);
    double t0 = MPI_Wtime();
    dec_spool sp;
    isomend_stats stats;
    memset(&stats, 0, sizeof stats);
    int rc = dec_spool_open(&sp, a->output, plane, first);
    sp.nonempty = first < end;
    if (!rc) {
        isomend_mesh_sink rec;
        dec_spool_sink(&sp, &rec);
        rc = slab_stream(sl, opts, first, end, &rec, &sp.failed, &stats);
    }
    const double extract_s = MPI_Wtime() - t0;
    if ((rc = agree(rc)) != 0) {
        dec_spool_close(&sp);
        return rc;
    }
    /* rank 0: decimation -> check -> (patient space) -> writer, as isomend extract's stream */
    t0 = MPI_Wtime();
    cli_outputs out;
    memset(&out, 0, sizeof out);
    cli_post_report post;
    memset(&post, 0, sizeof post);
    isomend_check_report check;
    memset(&check, 0, sizeof check);
    int checked = 0;
    const int normals = !(opts->flags & ISOMEND_FLAG_NO_NORMALS);
    if (rank == 0) {
        cli_memory_plan plan;
        cli_memory_plan_make(&sl->desc, opts, fmt, a->max_memory, 0, &a->post, &plan);
        if (cli_outputs_begin(&out, a->output, fmt, normals, sl->has_world ? sl->world : NULL,
                              sl->label, &sl->desc, opts, plan.check_queue, &a->post,
                              plan.decimate_layers))
            rc = CLI_EXIT_FAIL;
    }
    /* the replay is collective: every rank takes part, also after a failure */
    int failed0 = rc;
    MPI_Bcast(&failed0, 1, MPI_INT, 0, comm);
    if (!failed0)
        rc = dec_replay(comm, &sp, rank == 0 ? out.sink : NULL);
    dec_spool_close(&sp);
    if (rank == 0 && !failed0) {
        rc = cli_outputs_finish(&out, rc, sl->label, &post, &check, &checked);
        if (!rc && cli_interrupted) {
            cli_error("%s: interrupted", sl->label);
            rc = CLI_EXIT_INTERRUPTED;
        }
        if (rc)
            cli_outputs_abort(&out);
        else
            rc = cli_outputs_commit(&out);
    }
    post.decimate_ms = (MPI_Wtime() - t0) * 1e3; /* the replay, decimation, check and write */
    if ((rc = agree(rc)) != 0)
        return rc;

    isomend_stats total;
    MPI_Reduce(&stats, &total, (int)(sizeof total / sizeof(uint64_t)), MPI_UINT64_T, MPI_SUM, 0,
               comm);
    uint64_t peak = cli_peak_memory(), peak_max = 0;
    MPI_Reduce(&peak, &peak_max, 1, MPI_UINT64_T, MPI_MAX, 0, comm);
    double times[2] = {sl->read_ms, extract_s * 1e3 - sl->read_ms}, tmax[2];
    MPI_Reduce(times, tmax, 2, MPI_DOUBLE, MPI_MAX, 0, comm);
    if (rank == 0) {
        const isomend_volume *v = &sl->desc;
        if (!quiet) {
            print_run(text, sl, a, iso_suggested, pad != 0, normals);
        }
        if (a->seen & OPT_STATS) cli_print_table2(text, &total, a->method);
        if (!quiet) {
            cli_print_post(text, &post);
            cli_print_check(text, a->output, &check);
            fprintf(text, "time: read %.1f ms, extract %.1f ms (slowest rank), post-process and write "
                          "%.1f ms (rank 0), total %.1f ms; peak memory %.1f MiB (largest rank)\n",
                    tmax[0], tmax[1], post.decimate_ms, (MPI_Wtime() - t_start) * 1e3,
                    (double)peak_max / 1048576.0);
        }
        FILE *jf = cli_json_stream(jo);
        if (jf) {
            fprintf(jf, "{\"command\": \"extract\", \"program\": \"isomend-mpi\", \"version\": "
                        "\"%s\", \"ranks\": %d, ", isomend_version(), ranks);
            cli_json_run(jf, sl->label, sl->kind, a->output, v, opts, iso_suggested);
            cli_json_geometry(jf, &sl->geometry);
            fprintf(jf, ", \"peak_memory\": %" PRIu64, peak_max);
            cli_json_stats(jf, &total);
            cli_json_post(jf, &post);
            fprintf(jf, ", \"check\": ");
            cli_json_check(jf, &check);
            fprintf(jf, ", \"timings_ms\": {\"read\": %.3f, \"extract\": %.3f, \"write\": %.3f}}\n",
                    tmax[0], tmax[1], post.decimate_ms);
        }
        rc = cli_json_finish(jo);
        if (rc) unlink(a->output); /* the JSON was asked for: no mesh without it */
    }
    MPI_Bcast(&rc, 1, MPI_INT, 0, comm);
    return rc;
}

static int run(int argc, char **argv)
{
    if (argc < 2 || (strcmp(argv[1], "extract") != 0 && strcmp(argv[1], "--help") != 0 &&
                     strcmp(argv[1], "-h") != 0)) {
        if (rank == 0) fputs(usage, stderr);
        return CLI_EXIT_USAGE;
    }
    if (strcmp(argv[1], "extract") != 0) {
        if (rank == 0) fputs(usage, stdout);
        return CLI_EXIT_OK;
    }
    cli_args a;
    uint64_t allowed = OPT_OUTPUT | OPT_ISO | OPT_METHOD | OPT_RAW | OPT_SPACING | OPT_ORIGIN |
                       OPT_PAD | OPT_NO_NORMALS | OPT_FLIP | OPT_STATS | OPT_JSON | OPT_QUIET |
                       OPT_THREADS | OPT_FIRST | OPT_COUNT | OPT_STEP | OPT_CHANNEL | OPT_HELP |
                       OPT_PAGES | OPT_MAX_MEMORY | OPT_SLICE_POSITIONS | OPT_DECIMATE |
                       OPT_SMOOTH | OPT_MIN_COMPONENT | OPT_LARGEST | OPT_CHUNK_LAYERS |
                       OPT_TARGET_TRIANGLES | OPT_MAX_ERROR;
    int rc = cli_parse_args(argc, argv, 2, "extract", allowed, &a);
    if (!rc && (a.seen & OPT_HELP)) {
        if (rank == 0) fputs(usage, stdout);
        return CLI_EXIT_OK;
    }
    isomend_mesh_format fmt = ISOMEND_MESH_UNKNOWN;
    if (!rc && a.npositional == 0) {
        cli_error("extract: missing SOURCE");
        rc = CLI_EXIT_USAGE;
    } else if (!rc && !a.output) {
        cli_error("extract: missing -o MESH (.ply, .obj or .stl)");
        rc = CLI_EXIT_USAGE;
    } else if (!rc && (fmt = isomend_mesh_format_of(a.output)) == ISOMEND_MESH_UNKNOWN) {
        cli_error("-o %s: unknown mesh format (use .ply, .obj or .stl)", a.output);
        rc = CLI_EXIT_USAGE;
    } else if (!rc && a.json && strcmp(a.json, a.output) == 0) {
        cli_error("--json %s: same file as -o", a.json);
        rc = CLI_EXIT_USAGE;
    } else if (!rc && cli_chunk_layers_unused(&a)) {
        rc = CLI_EXIT_USAGE;
    }
    if ((rc = agree(rc)) != 0) return rc;
    const int quiet = (a.seen & OPT_QUIET) != 0;
    FILE *text = a.json && strcmp(a.json, "-") == 0 ? stderr : stdout;

    /* the outputs must be creatable before any work is done (rank 0: one file system) */
    cli_json_out jo;
    memset(&jo, 0, sizeof jo);
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    if (rank == 0) {
        isomend_atomic_file probe;
        if (isomend_atomic_open(&probe, a.output, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            rc = CLI_EXIT_FAIL;
        } else {
            isomend_atomic_abort(&probe);
            rc = cli_json_prepare(&jo, a.json);
        }
    }
    if ((rc = agree(rc)) != 0) {
        cli_json_abort(&jo);
        return rc;
    }
    double t_start = MPI_Wtime();
    cli_progress bar;
    cli_progress_init(&bar, 0);
    a.src.progress = &bar;
    cli_source sl;
    memset(&sl, 0, sizeof sl);
    /* every rank reads --slice-positions itself: the same table, the same desc */
    rc = cli_source_open(a.positional, a.npositional, &a.src, &sl);
    if ((rc = agree(rc)) != 0) goto fail;
    if (rank == 0) cli_print_geometry_warning(sl.label, &sl.geometry);

    isomend_options opts;
    cli_extract_options(&a, &bar, &opts); /* no bar on screen: how Ctrl-C cancels */
    const int64_t pad = (opts.flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    const int64_t NZ = sl.desc.dims[2] + 2 * pad;
    int64_t first, end;
    slab_split(NZ, ranks, rank, &first, &end);
    if (a.max_memory) { /* per rank: a slab streams, so the bound is one of a few slices */
        const uint64_t need = slab_memory(&sl, &opts, fmt);
        if (need && need > a.max_memory) {
            char have[32], lim[32];
            cli_error("--max-memory %s: a rank needs up to %s for slices of %lld x %lld %s "
                      "(the stream's bound, a slice read twice, the writer's buffers)",
                      cli_bytes_text(a.max_memory, lim, sizeof lim),
                      cli_bytes_text(need, have, sizeof have), (long long)sl.desc.dims[0],
                      (long long)sl.desc.dims[1], isomend_type_name(sl.desc.type));
            rc = CLI_EXIT_USAGE;
        }
    }
    if ((rc = agree(rc)) != 0) goto fail;

    int iso_suggested = 0;
    if (!(a.seen & OPT_ISO)) {
        cli_summary sum;
        int64_t k0 = first - pad, k1 = end - pad;
        if (k0 < 0) k0 = 0;
        if (k1 > sl.desc.dims[2]) k1 = sl.desc.dims[2];
        if (k1 < k0) k1 = k0;
        if ((rc = suggest_iso(&sl, k0, k1, &sum)) != 0) goto fail;
        if (!sum.has_suggestion) {
            cli_error("--iso is required: %s has no suggested level (all finite samples equal %g)",
                      sl.label, sum.min);
            rc = agree(CLI_EXIT_USAGE);
            goto fail;
        }
        a.iso = sum.suggested_iso;
        iso_suggested = 1;
        double bone;
        if (rank == 0 && !quiet && cli_source_fixed_level(&sl, &bone))
            fprintf(stderr, "isomend-mpi: no --iso given: using %.9g HU, the bone level of the CT "
                            "series %s (see 'isomend info')\n", a.iso, sl.label);
        else if (rank == 0 && !quiet)
            fprintf(stderr, "isomend-mpi: no --iso given: using %.9g, the suggested level of %s "
                            "(Otsu, see 'isomend info')\n", a.iso, sl.label);
    }
    opts.iso = a.iso;
    if (a.seen & OPT_POST) {
        rc = run_decimated(&a, &sl, &opts, fmt, first, end, iso_suggested, &jo, t_start, text);
        if (rc) cli_json_abort(&jo);
        cli_source_close(&sl);
        return rc;
    }

    /* the mesh goes to this rank's scratch files beside MESH as the slab streams */
    double t0 = MPI_Wtime();
    slab_piece piece;
    memset(&piece, 0, sizeof piece);
    uint64_t *foreign_ids = NULL;
    mpi_writer w;
    memset(&w, 0, sizeof w);
    w.format = fmt;
    w.normals = !(opts.flags & ISOMEND_FLAG_NO_NORMALS);
    w.final_path = a.output;
    cli_world world;
    const cli_world *mapping = NULL;
    if (sl.has_world) { /* a DICOM series in patient space, as isomend extract maps it */
        cli_sink none;
        memset(&none, 0, sizeof none);
        if (!cli_world_init(&world, sl.world, &none)) {
            cli_error("%s: the series' patient transform is not invertible", sl.label);
            rc = CLI_EXIT_FAIL;
        }
        mapping = &world;
    }
    if (!rc) rc = mpi_writer_open(&w);
    if (!rc) rc = slab_extract(&sl, &opts, mapping, first, end, &w, &piece);
    double extract_s = MPI_Wtime() - t0;
    if ((rc = agree(rc)) != 0) goto fail_piece;

    /* global ids: prefix sum of the vertex counts */
    uint64_t nv = piece.nv, first_id = 0, totals[2], counts[2] = {piece.nv, piece.nt};
    MPI_Exscan(&nv, &first_id, 1, MPI_UINT64_T, MPI_SUM, comm);
    if (rank == 0) first_id = 0;
    MPI_Allreduce(counts, totals, 2, MPI_UINT64_T, MPI_SUM, comm);
    const int normals = !(opts.flags & ISOMEND_FLAG_NO_NORMALS);
    size_t header_size = isomend_mesh_header_size(fmt, normals);
    unsigned char header[1024];
    if (isomend_mesh_header(fmt, normals, totals[0], totals[1], header, a.output, msg,
                            sizeof msg) != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        rc = CLI_EXIT_FAIL;
    }
    foreign_ids = malloc((piece.nforeign + 1) * sizeof *foreign_ids);
    if (!foreign_ids) {
        cli_error("out of memory");
        rc = CLI_EXIT_FAIL;
    }
    if ((rc = agree(rc)) != 0) goto fail_piece;
    rc = exchange_plane(&piece, NZ, first_id, foreign_ids);
    if (!rc) rc = mpi_writer_faces(&w, first_id, foreign_ids); /* PLY/OBJ: the global ids */
    if ((rc = agree(rc)) != 0) goto fail_piece;

    /* the temporary file, named by rank 0, opened by all */
    char tmp[ISOMEND_FILEIO_PATH_MAX + 64] = "";
    if (rank == 0) {
        isomend_atomic_file af;
        if (isomend_atomic_open(&af, a.output, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            rc = CLI_EXIT_FAIL;
        } else {
            snprintf(tmp, sizeof tmp, "%s", af.tmp_path);
            fclose(af.fp); /* the name stays reserved: MPI-IO writes it */
        }
    }
    MPI_Bcast(tmp, (int)sizeof tmp, MPI_CHAR, 0, comm);
    if ((rc = agree(rc)) != 0) goto fail_piece;
    t0 = MPI_Wtime();
    MPI_File fh;
    int err = MPI_File_open(comm, tmp, MPI_MODE_WRONLY, MPI_INFO_NULL, &fh);
    if (err != MPI_SUCCESS) {
        char why[MPI_MAX_ERROR_STRING];
        int len = 0;
        MPI_Error_string(err, why, &len);
        cli_error("%s: cannot open the temporary file %s: %s", a.output, tmp, why);
        rc = CLI_EXIT_FAIL;
    }
    if ((rc = agree(rc)) != 0) goto fail_file;
    rc = mpi_writer_write(&w, comm, fh, header, header_size, 0);
    mpi_writer_close(&w);
    if (MPI_File_close(&fh) != MPI_SUCCESS && !rc) {
        cli_error("%s: closing the file failed", a.output);
        rc = CLI_EXIT_FAIL;
    }
    if (!rc && cli_interrupted) {
        cli_error("%s: interrupted", sl.label);
        rc = CLI_EXIT_INTERRUPTED;
    }
    if ((rc = agree(rc)) != 0) goto fail_file;
    /* a second line of defence against an MPI-IO layer that loses a write */
    if (rank == 0) {
        struct stat sb;
        uint64_t want = header_size + w.size_total;
        if (stat(tmp, &sb) != 0 || (uint64_t)sb.st_size != want) {
            cli_error("%s: the written file has %lld bytes, %llu expected (a write was lost)",
                      a.output, (long long)sb.st_size, (unsigned long long)want);
            rc = CLI_EXIT_FAIL;
        }
    }
    if ((rc = agree(rc)) != 0) goto fail_file;
    if (rank == 0 && rename(tmp, a.output) != 0) {
        cli_error("%s: cannot rename %s: %s", a.output, tmp, strerror(errno));
        rc = CLI_EXIT_FAIL;
    }
    if ((rc = agree(rc)) != 0) goto fail_file;
    double write_s = MPI_Wtime() - t0;

    /* the report: sums of the pieces' statistics, the largest peak and times */
    isomend_stats stats;
    MPI_Reduce(&piece.stats, &stats, (int)(sizeof stats / sizeof(uint64_t)), MPI_UINT64_T, MPI_SUM,
               0, comm);
    uint64_t peak = cli_peak_memory(), peak_max = 0;
    MPI_Reduce(&peak, &peak_max, 1, MPI_UINT64_T, MPI_MAX, 0, comm);
    double times[2] = {sl.read_ms, extract_s * 1e3 - sl.read_ms}, tmax[2];
    MPI_Reduce(times, tmax, 2, MPI_DOUBLE, MPI_MAX, 0, comm);
    if (rank == 0) {
        const isomend_volume *v = &sl.desc;
        if (!quiet) {
            print_run(text, &sl, &a, iso_suggested, pad != 0, normals);
        }
        if (a.seen & OPT_STATS) cli_print_table2(text, &stats, a.method);
        if (!quiet) {
            fprintf(text, "%s: %" PRIu64 " vertices, %" PRIu64 " triangles (run 'isomend check %s' "
                          "for the continuity check)\n", a.output, totals[0], totals[1], a.output);
            fprintf(text, "time: read %.1f ms, extract %.1f ms, write %.1f ms, total %.1f ms "
                          "(slowest rank); peak memory %.1f MiB (largest rank)\n",
                    tmax[0], tmax[1], write_s * 1e3, (MPI_Wtime() - t_start) * 1e3,
                    (double)peak_max / 1048576.0);
        }
        FILE *jf = cli_json_stream(&jo);
        if (jf) {
            fprintf(jf, "{\"command\": \"extract\", \"program\": \"isomend-mpi\", \"version\": "
                        "\"%s\", \"ranks\": %d, ", isomend_version(), ranks);
            cli_json_run(jf, sl.label, sl.kind, a.output, v, &opts, iso_suggested);
            cli_json_geometry(jf, &sl.geometry);
            fprintf(jf, ", \"peak_memory\": %" PRIu64, peak_max);
            stats.vertices = totals[0];
            stats.triangles = totals[1];
            cli_json_stats(jf, &stats);
            fprintf(jf, ", \"check\": null");
            fprintf(jf, ", \"timings_ms\": {\"read\": %.3f, \"extract\": %.3f, \"write\": %.3f}}\n",
                    tmax[0], tmax[1], write_s * 1e3);
        }
        rc = cli_json_finish(&jo);
        if (rc) unlink(a.output); /* the JSON was asked for: no mesh without it */
    }
    MPI_Bcast(&rc, 1, MPI_INT, 0, comm);
    free(foreign_ids);
    slab_piece_free(&piece);
    cli_source_close(&sl);
    return rc;

fail_file:
    if (rank == 0 && tmp[0]) unlink(tmp);
fail_piece:
    mpi_writer_close(&w);
    free(foreign_ids);
    slab_piece_free(&piece);
fail:
    cli_json_abort(&jo);
    cli_source_close(&sl);
    return rc;
}

int main(int argc, char **argv)
{
    cli_install_signal_handlers(); /* before MPI_Init: its handlers come on top */
#ifdef OMPI_MAJOR_VERSION
    /* Open MPI 4.1's default MPI-IO layer (OMPIO, fcoll vulcan) prints a failed
     * write ("fbtl_pwritev failed") and still returns MPI_SUCCESS from
     * MPI_File_write_at_all: a full disk would give a truncated mesh.  ROMIO
     * reports it.  A user's own choice (OMPI_MCA_io) is kept. */
    setenv("OMPI_MCA_io", OMPI_MAJOR_VERSION >= 5 ? "romio341" : "romio321", 0);
#endif
    MPI_Init(&argc, &argv);
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &ranks);
    cli_program = "isomend-mpi";
    cli_error_capture(message, sizeof message);
    int rc = run(argc, argv);
    /* nobody exits before rank 0 has printed the message and removed the
     * temporary file: mpirun stops the other ranks when one exits non-zero */
    MPI_Barrier(comm);
    MPI_Finalize();
    return rc;
}
