/*
 * mesh_memory.c - the memory of the output arrays and of the workers'
 * scratch arrays.
 *
 * Huge pages.  Arrays of 2 MiB and more are aligned to 2 MiB and offered to
 * the kernel for transparent huge pages (madvise): a large mesh otherwise
 * spends much of its time in page faults, one per 4 KiB.
 * ISOMEND_FLAG_SMALL_PAGES asks for none.
 *
 * Reservations.  isomend_extract()'s runs (slabs.c) do not know the mesh's
 * size in advance: they write into address-space reservations of the
 * largest mesh the grid can give (MAP_NORESERVE: untouched pages cost
 * nothing), trimmed at the end, and a staged run into its thread's own.
 *
 * Recycling.  isomend_extract_recycle() moves an old mesh's pages into the
 * new reservations, so the new mesh is written on memory already faulted in
 * and zeroed.
 *
 * Everything here is released with release_output() (free() for what was
 * malloc'ed, munmap for reservations); docs/core-internals.md has the
 * measurements behind the choices.
 */
#define _GNU_SOURCE /* madvise, posix_memalign, mremap */
#include "mesh_internal.h"

#include <stdlib.h>
#include <unistd.h>

#if defined(__linux__)
#include <sys/mman.h>
#endif

/*
 * Output arrays of 2 MiB and more are aligned to 2 MiB and offered to the
 * kernel for transparent huge pages (a large mesh otherwise spends a good
 * part of its time in page faults).  Released with free() like any
 * allocation.  With ISOMEND_FLAG_SMALL_PAGES they are plain allocations.
 */
void *output_alloc(size_t size, int small_pages)
{
    if (size < HUGE_PAGE || small_pages)
        return malloc(size ? size : 1);
    void *p = NULL;
    if (posix_memalign(&p, HUGE_PAGE, size) != 0)
        return NULL;
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    (void)madvise(p, huge_round(size), MADV_HUGEPAGE);
#endif
    return p;
}

/*
 * Working arrays of 1 MiB and more (a worker's sign slices and id maps):
 * rounded up to whole 2 MiB pages, aligned to them and offered
 * for transparent huge pages.  malloc would hand these back to the kernel at
 * free() (glibc maps them on their own or trims its heap) and take them again
 * the next call on 4 KiB pages, a page fault each (costly on a virtual
 * machine whose every small-page fault is a trap to the host).  Released
 * with free().
 */
void *scratch_alloc(size_t size)
{
    if (size < HUGE_PAGE / 2)
        return malloc(size ? size : 1);
    if (size > SIZE_MAX - HUGE_PAGE)
        return NULL;
    return output_alloc(huge_round(size), 0);
}

/*
 * Reserved output arrays (slabs.c): an anonymous mapping of `size` bytes
 * (the array's largest possible size) that reserves address space, not
 * memory (MAP_NORESERVE), aligned to 2 MiB and offered for transparent huge
 * pages from byte `huge_from` (a multiple of 2 MiB) on, or never (SIZE_MAX:
 * ISOMEND_FLAG_SMALL_PAGES).  NULL when the system
 * refuses (strict overcommit, an address-space limit): the caller then
 * counts first and allocates the mesh's size.  The mapping is
 * huge_round(size) bytes long.
 */
void *reserve_output(size_t size, size_t huge_from)
{
#if defined(__linux__) && defined(MAP_NORESERVE)
    if (size > SIZE_MAX / 2 - 2 * HUGE_PAGE)
        return NULL;
    size = huge_round(size);
    char *p = mmap(NULL, size + HUGE_PAGE, PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (p == MAP_FAILED)
        return NULL;
    const size_t head = (size_t)(-(uintptr_t)p & (HUGE_PAGE - 1));
    if (head)
        munmap(p, head);
    munmap(p + head + size, HUGE_PAGE - head);
#if defined(MADV_HUGEPAGE) && defined(MADV_NOHUGEPAGE)
    if (huge_from == SIZE_MAX) /* small pages, even where the kernel's policy is "always" */
        (void)madvise(p + head, size, MADV_NOHUGEPAGE);
    else if (huge_from < size)
        (void)madvise(p + head + huge_from, size - huge_from, MADV_HUGEPAGE);
#endif
    return p + head;
#else
    (void)size;
    (void)huge_from;
    return NULL;
#endif
}

/* Unmaps the part of a reservation of `size` bytes past its first `used`
 * bytes (rounded up to a page: the last huge page is split, and the mesh
 * then holds no more than it uses); returns the length kept mapped. */
size_t trim_output(void *p, size_t size, size_t used)
{
#if defined(__linux__) && defined(MAP_NORESERVE)
    const size_t page = (size_t)sysconf(_SC_PAGESIZE);
    used = used ? (used + page - 1) / page * page : page;
    if (used < size)
        munmap((char *)p + used, size - used);
    return used < size ? used : size;
#else
    (void)p;
    (void)used;
    return size;
#endif
}

/* Frees an output array: unmaps a reservation (`mapped` bytes kept), or free(). */
void release_output(void *p, size_t mapped)
{
#if defined(__linux__) && defined(MAP_NORESERVE)
    if (mapped) {
        munmap(p, mapped);
        return;
    }
#endif
    (void)mapped;
    free(p);
}

/*
 * Recycling (isomend_extract_recycle): moves the whole 2 MiB pages at the
 * start of an old mesh's array, a reservation of `mapped` bytes at `old`, to
 * the start of the new reservation p of `size` bytes (both 2 MiB aligned), so
 * that the new mesh writes on pages already faulted in and zeroed once: no
 * page fault, no zeroing by the kernel, and on a virtual machine nothing to
 * get back from the host.  The old array's last, partly used page was split
 * into 4 KiB pages when it was trimmed: it is unmapped with the rest, since
 * it would make the new array fault 4 KiB pages where a 2 MiB one belongs.
 */
void adopt_output(void *p, size_t size, void *old, size_t mapped)
{
#if defined(__linux__) && defined(MREMAP_FIXED)
    size_t keep = mapped & ~(HUGE_PAGE - 1);
    if (keep > size)
        keep = size;
    if (keep && mremap(old, keep, keep, MREMAP_MAYMOVE | MREMAP_FIXED, p) == MAP_FAILED)
        keep = 0;
    if (mapped > keep)
        munmap((char *)old + keep, mapped - keep);
#else
    (void)p;
    (void)size;
    release_output(old, mapped);
#endif
}

/* Gives the whole pages of [p, p + size) back to the system (their contents
 * are lost; reading them again gives zeros). */
void release_pages(void *p, size_t size)
{
#if defined(__linux__) && defined(MADV_DONTNEED)
    (void)madvise(p, size, MADV_DONTNEED);
#else
    (void)p;
    (void)size;
#endif
}
