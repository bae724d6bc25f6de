/*
 * arena.c - one block for a post-processing call's working arrays
 * (arena.h).
 *
 * Why: a call of a few milliseconds on a mesh of tens of thousands of
 * vertices spends much of its time in page faults when each array is
 * malloc'ed on its own.  glibc maps or trims large blocks away at free()
 * and the next call faults them in again, 4 KiB at a time; on a virtual
 * machine every such fault is a trap to the host (8-9 us each on this
 * project's machine: 2 MiB faulted page by page took 4.5 ms).  The arena
 * asks for all of it at once: one anonymous mapping, offered for
 * transparent huge pages while it is small enough that the kernel has such
 * pages free (MADV_HUGEPAGE: 2 MiB in 0.3 ms), and populated in one call
 * (MADV_POPULATE_WRITE, Linux 5.14; 1.6 ms for 2 MiB of small pages).  On
 * an older kernel the populate call fails and the pages fault in as they
 * are touched, as before.  Larger arenas stay on small pages: there a
 * kernel that has to compact fragmented memory at each huge-page fault
 * made a 1.5 M-vertex smoothing slower, not faster (docs/postprocess.md).
 */
#define _GNU_SOURCE /* madvise */
#include "arena.h"

#include "mesh_internal.h"

#include <stdint.h>
#include <stdlib.h>
#include <unistd.h>

#if defined(__linux__)
#include <sys/mman.h>
#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23
#endif
#endif

/* Arenas up to this size are offered for huge pages. */
#define ARENA_HUGE_MAX ((size_t)64 << 20)

static size_t page_size(void)
{
#if defined(__linux__)
    const long p = sysconf(_SC_PAGESIZE);
    return p > 0 ? (size_t)p : 4096;
#else
    return 4096;
#endif
}

size_t arena_page_bytes(size_t bytes)
{
    const size_t page = page_size();
    return (bytes ? bytes + page - 1 : page) / page * page;
}

#if defined(ARENA_SEPARATE)
/* Under AddressSanitizer: the same accounting, each array on its own. */
#define ARENA_MAX_ARRAYS 32 /* the arrays an arena holds at most */

int arena_open(arena *a, size_t bytes)
{
    *a = (arena){0};
    a->own = calloc(ARENA_MAX_ARRAYS, sizeof *a->own);
    a->size = a->top = bytes;
    return a->own != NULL;
}

void *arena_take(arena *a, size_t bytes)
{
    const size_t n = arena_bytes(bytes ? bytes : 1);
    if (!a->own || a->nown == ARENA_MAX_ARRAYS || n > a->top - a->used)
        return NULL;
    a->used += n;
    return a->own[a->nown++] = calloc(1, bytes ? bytes : 1);
}

void *arena_take_pages(arena *a, size_t bytes, size_t *mapped)
{
    *mapped = 0;
    const size_t n = arena_page_bytes(bytes);
    if (!a->own || n > a->top - a->used)
        return NULL;
    a->top -= n;
    return calloc(1, bytes ? bytes : 1); /* its new owner frees it */
}

void arena_close(arena *a)
{
    for (size_t i = 0; a->own && i < a->nown; i++)
        free(a->own[i]);
    free(a->own);
    *a = (arena){0};
}

#else

int arena_open(arena *a, size_t bytes)
{
    *a = (arena){0};
    const size_t page = page_size();
    if (bytes > SIZE_MAX / 2)
        return 0;
    bytes = (bytes ? bytes + page - 1 : page) / page * page;
#if defined(__linux__)
    const int huge = bytes >= HUGE_PAGE / 2 && bytes <= ARENA_HUGE_MAX;
    const size_t len = huge ? huge_round(bytes) : bytes;
    char *p = mmap(NULL, len + (huge ? HUGE_PAGE : 0), PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p != MAP_FAILED) {
        if (huge) { /* aligned to a huge page, the rest unmapped */
            const size_t head = (size_t)(-(uintptr_t)p & (HUGE_PAGE - 1));
            if (head)
                munmap(p, head);
            munmap(p + head + len, HUGE_PAGE - head);
            p += head;
#if defined(MADV_HUGEPAGE)
            (void)madvise(p, len, MADV_HUGEPAGE);
#endif
        }
        (void)madvise(p, len, MADV_POPULATE_WRITE);
        a->base = p;
        a->size = a->top = len;
        a->mapped = 1;
        return 1;
    }
#endif
    a->base = calloc(1, bytes);
    a->size = a->top = bytes;
    return a->base != NULL;
}

void *arena_take(arena *a, size_t bytes)
{
    const size_t n = arena_bytes(bytes ? bytes : 1);
    if (!a->base || n > a->top - a->used)
        return NULL;
    void *p = a->base + a->used;
    a->used += n;
    return p;
}

void *arena_take_pages(arena *a, size_t bytes, size_t *mapped)
{
    *mapped = 0;
    if (!a->mapped) /* one calloc'ed block: the array is the new owner's own */
        return calloc(1, bytes ? bytes : 1);
    const size_t n = arena_page_bytes(bytes);
    if (n > a->top - a->used) /* (top stays a page boundary: every n is pages) */
        return NULL;
    a->top -= n;
    *mapped = n;
    return a->base + a->top;
}

void arena_close(arena *a)
{
    if (!a->base)
        return;
#if defined(__linux__)
    if (a->mapped) { /* [top, size) belongs to the pages' new owners */
        if (a->top)
            munmap(a->base, a->top);
        *a = (arena){0};
        return;
    }
#endif
    free(a->base);
    *a = (arena){0};
}

#endif /* ARENA_SEPARATE */
