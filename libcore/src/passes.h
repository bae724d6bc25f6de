/*
 * passes.h - the two passes (private; passes.c).
 */
#ifndef ISOMEND_PASSES_H
#define ISOMEND_PASSES_H

#include "context.h"

isomend_status run_two_passes(ctx *c, worker *ws, int nw, isomend_mesh **out, uint64_t *nv,
                              uint64_t *nt);

#endif /* ISOMEND_PASSES_H */
