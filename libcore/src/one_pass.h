/*
 * one_pass.h - the one pass (private; one_pass.c).
 */
#ifndef ISOMEND_ONE_PASS_H
#define ISOMEND_ONE_PASS_H

#include "context.h"

/* ISOMEND_ERR_UNSUPPORTED (nothing allocated) when the reservations are
 * refused, for the two passes to take over. */
isomend_status run_one_pass(ctx *c, worker *ws, int nw, isomend_mesh **out, uint64_t *nv,
                            uint64_t *nt);

#endif /* ISOMEND_ONE_PASS_H */
