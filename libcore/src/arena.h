/*
 * arena.h - the working memory of one post-processing call in one block,
 * zeroed and faulted in at once (arena.c).
 *
 * A call that knows its arrays' sizes up front sums them (arena_bytes()
 * for each), opens the arena once and takes the arrays from it in any
 * order.  Arrays taken with arena_take_pages() are whole pages from the
 * arena's top down, which can become an output mesh's (release_output()
 * unmaps them on their own); arena_close() releases the rest.
 */
#ifndef ISOMEND_ARENA_H
#define ISOMEND_ARENA_H

#include <stddef.h>

#define ARENA_ALIGN 64 /* a cache line */

/* Under AddressSanitizer every array is an allocation of its own, so that
 * the sanitizer suite still sees an overrun of any of them. */
#if defined(__SANITIZE_ADDRESS__)
#define ARENA_SEPARATE 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define ARENA_SEPARATE 1
#endif
#endif

typedef struct arena {
    void **own; /* ARENA_SEPARATE: the arrays, freed by arena_close() */
    size_t nown;
    char *base;
    size_t size; /* bytes mapped (or allocated)                          */
    size_t used; /* taken from the bottom by arena_take()                */
    size_t top;  /* [top, size) given away by arena_take_pages()         */
    int mapped;  /* 1: an anonymous mapping; 0: one calloc'ed block      */
} arena;

/* The room an array of `bytes` takes with arena_take(). */
static inline size_t arena_bytes(size_t bytes)
{
    return (bytes + ARENA_ALIGN - 1) & ~(size_t)(ARENA_ALIGN - 1);
}

/* The room an array of `bytes` takes with arena_take_pages(). */
size_t arena_page_bytes(size_t bytes);

/* Opens an arena of `bytes` (the sum of the arrays' arena_bytes() and
 * arena_page_bytes()), every byte zero.  0 without memory. */
int arena_open(arena *a, size_t bytes);

/* An array of `bytes` (ARENA_ALIGN-aligned); NULL when the arena is too
 * small for it (a sum that left it out). */
void *arena_take(arena *a, size_t bytes);

/* An array of `bytes` on pages of its own, which the arena gives away:
 * *mapped receives the length its new owner passes to release_output()
 * (0: free() it, when the arena is not a mapping).  NULL as arena_take(). */
void *arena_take_pages(arena *a, size_t bytes, size_t *mapped);

/* Releases everything not given away. */
void arena_close(arena *a);

#endif /* ISOMEND_ARENA_H */
