/*
 * sign_cache.c - the counting pass's signs kept for the fill pass.
 *
 * The counting pass classifies every sample; the fill pass needs the same
 * signs again.  Reading them back from the cache, 1 bit a sample plus the
 * row spans, spares the fill pass a second read of the volume.  Rows that
 * are uniform or one run (row_span.simple) are told by their span alone and
 * have no bits.
 */
#include "context.h"
#include "sign_cache.h"

#include <stdlib.h>

/* 8 sign bytes (0/1, memory order) -> 8 bits, bit i = byte i. */
static inline uint64_t pack8(uint64_t w)
{
    return (w * UINT64_C(0x0102040810204080)) >> 56;
}

/* 8 bits -> 8 sign bytes (0/1), byte i = bit i, as a little-endian word. */
static inline uint64_t unpack8(uint64_t x)
{
    const uint64_t m = UINT64_C(0x7F7F7F7F7F7F7F7F);
    uint64_t t = (x * UINT64_C(0x0101010101010101)) & UINT64_C(0x8040201008040201);
    return (((((t & m) + m) | t) & ~m) >> 7);
}

/*
 * The cache costs 1 bit a sample plus a span per row: kept only when that is
 * at most 1/16 of the input (float volumes), so that peak memory stays within
 * input + mesh + 10 % even for a small mesh; for 8- and 16-bit samples the
 * fill pass classifies again, which costs little.  Without memory for it,
 * the same: no cache.
 */
void cache_alloc(ctx *c)
{
    const grid *g = &c->g;
    const uint64_t rows = (uint64_t)g->N[1] * (uint64_t)g->N[2];
    const uint64_t words = (uint64_t)(g->N[0] + 63) / 64;
    const uint64_t cache = rows * (8 * words + sizeof(row_span));
    const uint64_t input = (uint64_t)g->n[0] * (uint64_t)g->n[1] * (uint64_t)g->n[2] *
                           (uint64_t)isomend_type_size(g->type);
    if (cache > input / 16 || rows > SIZE_MAX / sizeof(row_span) || rows * words > SIZE_MAX / 8)
        return;
    c->cache_words = (int64_t)words;
    c->cache_bits = scratch_alloc((size_t)(rows * words) * 8);
    c->cache_spans = scratch_alloc((size_t)rows * sizeof(row_span));
    if (!c->cache_bits || !c->cache_spans)
        cache_free(c);
}

void cache_free(ctx *c)
{
    free(c->cache_bits);
    free(c->cache_spans);
    c->cache_bits = NULL;
    c->cache_spans = NULL;
}

/* Saves slice k's signs (held by the worker) in the sign cache. */
void cache_store(worker *w, int64_t k)
{
    const ctx *c = w->c;
    const int64_t N0 = c->g.N[0], N1 = c->g.N[1];
    const int r = (int)(k % SIGN_RING);
    for (int64_t j = 0; j < N1; j++) {
        const row_span *ri = &w->spans[r][j];
        c->cache_spans[k * N1 + j] = *ri;
        if (ri->lo >= N0 || ri->simple)
            continue; /* uniform or one run: the span says it all */
        const uint8_t *s = w->sign_bytes[r] + j * N0;
        uint64_t *b = c->cache_bits + (k * N1 + j) * c->cache_words;
        for (int64_t q = 0; q < c->cache_words; q++) {
            uint64_t word = 0;
            for (int64_t h = 0; h < 8; h++) {
                const int64_t i = 64 * q + 8 * h;
                if (i >= N0)
                    break;
                uint64_t v = N0 - i >= 8 ? load8(s + i) : 0;
                if (N0 - i < 8)
                    for (int64_t x = 0; x < N0 - i; x++)
                        v |= (uint64_t)s[i + x] << (8 * x);
                word |= pack8(v) << (8 * h);
            }
            b[q] = word;
        }
    }
}

/* Refills the worker's ring slot `slot` with slice k from the sign cache. */
void cache_load(worker *w, int64_t k, int slot)
{
    const ctx *c = w->c;
    const int64_t N0 = c->g.N[0], N1 = c->g.N[1];
    for (int64_t j = 0; j < N1; j++) {
        const row_span *ri = &c->cache_spans[k * N1 + j];
        uint8_t *s = w->sign_bytes[slot] + j * N0;
        w->spans[slot][j] = *ri;
        if (ri->lo >= N0) {
            memset(s, ri->first, (size_t)N0);
            continue;
        }
        if (ri->simple) {
            memset(s, ri->first, (size_t)N0);
            memset(s + ri->lo, ri->first ^ 1, (size_t)(ri->hi - ri->lo + 1));
            continue;
        }
        const uint64_t *b = c->cache_bits + (k * N1 + j) * c->cache_words;
        for (int64_t i = 0; i < N0; i += 8) /* writes up to 7 bytes of slack past N0 */
            store8(s + i, unpack8((b[i >> 6] >> (i & 63)) & 0xFF));
    }
}
