/*
 * extract.h - the extraction's set-up, shared by the engine and its
 * clients (private; extract.c).
 */
#ifndef ISOMEND_EXTRACT_H
#define ISOMEND_EXTRACT_H

#include "context.h"

/* The context of an extraction (checks, grid, kernels, options;
 * vol->data may be NULL), the workers' arrays, the statistics. */
isomend_status ctx_setup(ctx *c, const isomend_volume *vol, const isomend_options *o);
size_t worker_layout(worker *w, const ctx *c, char *block);
int worker_init(worker *w, ctx *c);
void gather_stats(const ctx *c, const worker *ws, int nw, uint64_t nv, uint64_t nt,
                  isomend_stats *stats);
void stats_add(isomend_stats *to, const isomend_stats *s);

/* Tests only (not exported; tests link the static library): the schedule
 * the next extractions take (context.h), SCHEDULE_AUTO to choose again.  One
 * library reaches every schedule of slabs.c on the tests' small grids. */
void extract_set_test_schedule(extract_schedule schedule);

#endif /* ISOMEND_EXTRACT_H */
