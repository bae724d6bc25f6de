/*
 * sign_cache.h - the counting pass's signs kept for the fill pass (private;
 * sign_cache.c): 1 bit a sample and the row spans, where memory allows.
 */
#ifndef ISOMEND_SIGN_CACHE_H
#define ISOMEND_SIGN_CACHE_H

#include "context.h"

void cache_store(worker *w, int64_t k);
void cache_load(worker *w, int64_t k, int slot);
void cache_alloc(ctx *c);
void cache_free(ctx *c);

#endif /* ISOMEND_SIGN_CACHE_H */
