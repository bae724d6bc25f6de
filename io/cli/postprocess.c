/*
 * postprocess.c - `extract`'s steps after the extraction, each a call of
 * the core (isomend.h, "post-processing"): clean-up (--min-component,
 * --largest), smoothing (--smooth) and decimation (--decimate,
 * --target-triangles, --max-error), in that order: islands go before they
 * cost smoothing time, and the smoothed surface is what the decimation's
 * quadrics keep (a streamed run chains the same steps as sinks: stream.c,
 * cli_outputs).  Every step keeps a closed, oriented surface closed; the
 * mesh each one makes replaces the previous.
 */
#include "cli.h"

#include <inttypes.h>
#include <string.h>

int cli_postprocess(isomend_mesh **mesh, const cli_post *p, cli_post_report *r, const char *label)
{
    memset(r, 0, sizeof *r);
    if (p->min_component || p->largest) {
        double t0 = cli_now_ms();
        isomend_mesh *out = NULL;
        isomend_status st = isomend_mesh_clean(*mesh, p->min_component, p->largest, &out, &r->clean);
        if (st != ISOMEND_OK) {
            cli_error("%s: clean-up failed: %s", label, isomend_status_string(st));
            return CLI_EXIT_FAIL;
        }
        isomend_mesh_destroy(*mesh);
        *mesh = out;
        r->clean_ms = cli_now_ms() - t0;
        r->cleaned = 1;
    }
    if (p->smooth) {
        double t0 = cli_now_ms();
        isomend_mesh *out = NULL;
        isomend_status st = isomend_mesh_smooth(*mesh, p->smooth, &out, &r->smooth);
        if (st != ISOMEND_OK) {
            cli_error("%s: smoothing failed: %s", label, isomend_status_string(st));
            return CLI_EXIT_FAIL;
        }
        isomend_mesh_destroy(*mesh);
        *mesh = out;
        r->smooth_ms = cli_now_ms() - t0;
        r->smoothed = 1;
    }
    if (p->ratio > 0 || p->target || p->max_error > 0) {
        double t0 = cli_now_ms();
        isomend_decimate_options d;
        isomend_decimate_options_init(&d);
        d.ratio = p->ratio;
        d.target_triangles = p->target;
        d.max_error = p->max_error;
        isomend_mesh *out = NULL;
        isomend_status st = isomend_mesh_decimate(*mesh, &d, &out, &r->decimate);
        if (st != ISOMEND_OK) {
            cli_error("%s: decimation failed: %s", label, isomend_status_string(st));
            return CLI_EXIT_FAIL;
        }
        isomend_mesh_destroy(*mesh);
        *mesh = out;
        r->decimate_ms = cli_now_ms() - t0;
        r->decimated = 1;
    }
    return CLI_EXIT_OK;
}

void cli_print_post(FILE *fp, const cli_post_report *r)
{
    if (r->cleaned)
        fprintf(fp, "clean-up: %" PRIu64 " of %" PRIu64 " components kept, %" PRIu64
                    " triangles removed%s (%.1f ms)\n",
                r->clean.components_after, r->clean.components_before, r->clean.triangles_removed,
                r->streamed ? ", streamed" : "", r->clean_ms);
    if (r->smoothed) {
        const double v0 = r->smooth.volume_before, v1 = r->smooth.volume_after;
        fprintf(fp, "smoothing: %" PRIu64 " vertices moved, at most %.4g; volume %.6g -> %.6g"
                    " (%+.3f %%)",
                r->smooth.moved_vertices, r->smooth.max_displacement, v0, v1,
                v0 != 0 ? 100.0 * (v1 - v0) / v0 : 0.0);
        if (r->streamed)
            fprintf(fp, ", streamed in chunks of %lld layers", (long long)r->chunk_layers);
        fprintf(fp, " (%.1f ms)\n", r->smooth_ms);
    }
    if (r->decimated) {
        const isomend_decimate_report *d = &r->decimate;
        fprintf(fp, "decimation: %" PRIu64 " -> %" PRIu64 " triangles", d->triangles_before,
                d->triangles_after);
        if (d->target_triangles)
            fprintf(fp, " (target %" PRIu64 "%s)", d->target_triangles,
                    d->reached ? "" : ", not reached: further collapses would break the surface "
                                      "or exceed --max-error");
        fprintf(fp, ", largest error %.4g, %" PRIu64 " locked vertices", d->max_error,
                d->locked_vertices);
        if (r->streamed)
            fprintf(fp, ", streamed in chunks of %lld layers", (long long)r->chunk_layers);
        fprintf(fp, " (%.1f ms)\n", r->decimate_ms);
    }
}

void cli_json_post(FILE *fp, const cli_post_report *r)
{
    fprintf(fp, ", \"postprocess\": {\"clean\": ");
    if (r->cleaned)
        fprintf(fp, "{\"components_before\": %" PRIu64 ", \"components_after\": %" PRIu64
                    ", \"triangles_removed\": %" PRIu64 ", \"vertices_removed\": %" PRIu64
                    ", \"streamed\": %s, \"ms\": %.3f}",
                r->clean.components_before, r->clean.components_after, r->clean.triangles_removed,
                r->clean.vertices_removed, r->streamed ? "true" : "false", r->clean_ms);
    else
        fprintf(fp, "null");
    fprintf(fp, ", \"smooth\": ");
    if (r->smoothed)
        fprintf(fp, "{\"moved_vertices\": %" PRIu64 ", \"max_displacement\": %.9g"
                    ", \"volume_before\": %.17g, \"volume_after\": %.17g, \"streamed\": %s"
                    ", \"chunk_layers\": %lld, \"ms\": %.3f}",
                r->smooth.moved_vertices, r->smooth.max_displacement, r->smooth.volume_before,
                r->smooth.volume_after, r->streamed ? "true" : "false",
                (long long)(r->streamed ? r->chunk_layers : 0), r->smooth_ms);
    else
        fprintf(fp, "null");
    fprintf(fp, ", \"decimate\": ");
    if (r->decimated) {
        const isomend_decimate_report *d = &r->decimate;
        fprintf(fp, "{\"triangles_before\": %" PRIu64 ", \"triangles_after\": %" PRIu64
                    ", \"vertices_before\": %" PRIu64 ", \"vertices_after\": %" PRIu64
                    ", \"target_triangles\": %" PRIu64 ", \"reached\": %s, \"max_error\": %.9g"
                    ", \"mean_error\": %.9g, \"collapses\": %" PRIu64
                    ", \"locked_vertices\": %" PRIu64 ", \"refused_topology\": %" PRIu64
                    ", \"refused_geometry\": %" PRIu64 ", \"refused_error\": %" PRIu64
                    ", \"streamed\": %s, \"chunk_layers\": %lld, \"ms\": %.3f}",
                d->triangles_before, d->triangles_after, d->vertices_before, d->vertices_after,
                d->target_triangles, d->reached ? "true" : "false", d->max_error, d->mean_error,
                d->collapses, d->locked_vertices, d->refused_topology, d->refused_geometry,
                d->refused_error, r->streamed ? "true" : "false", (long long)r->chunk_layers,
                r->decimate_ms);
    } else {
        fprintf(fp, "null");
    }
    fputc('}', fp);
}
