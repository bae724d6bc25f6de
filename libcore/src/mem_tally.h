/*
 * mem_tally.h - the bytes a streamed step holds, counted as it allocates
 * (private): what it holds now and the most it has held at once.  The
 * streamed post-processing (stream_window.c and its clients) adds each
 * array's size when it allocates or grows it and takes it off when it frees
 * it; a growing array counts its old and new blocks together (realloc may
 * copy), and work that allocates and frees within one call (a window's
 * decimation, its scratch) counts once as a spike above what is held.  The
 * bytes are those asked of malloc (not its headers or rounding), so that the
 * streams can report their peak (isomend_decimate_stream_peak_bytes()) and
 * their memory estimates be measured against it (docs/postprocess.md).
 * Types and inline functions only.
 */
#ifndef ISOMEND_MEM_TALLY_H
#define ISOMEND_MEM_TALLY_H

#include <stdint.h>

typedef struct mem_tally {
    uint64_t now;  /* held now              */
    uint64_t peak; /* the most held at once */
} mem_tally;

/* bytes more are held. */
static inline void mem_tally_add(mem_tally *t, uint64_t bytes)
{
    t->now += bytes;
    if (t->now > t->peak)
        t->peak = t->now;
}

/* bytes fewer are held. */
static inline void mem_tally_sub(mem_tally *t, uint64_t bytes)
{
    t->now = bytes < t->now ? t->now - bytes : 0;
}

/* bytes held for a while above what is held now, then freed. */
static inline void mem_tally_spike(mem_tally *t, uint64_t bytes)
{
    if (t->now + bytes > t->peak)
        t->peak = t->now + bytes;
}

/* An array grown from old_bytes to new_bytes: both at once, then the new. */
static inline void mem_tally_grow(mem_tally *t, uint64_t old_bytes, uint64_t new_bytes)
{
    mem_tally_add(t, new_bytes);
    mem_tally_sub(t, old_bytes);
}

#endif
