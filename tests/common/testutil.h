/* Assertions for the C tests that stay active in release builds. */
#ifndef ISOMEND_TESTUTIL_H
#define ISOMEND_TESTUTIL_H
#include <stdio.h>
#include <stdlib.h>

static int tu_failures;

#define CHECK(cond)                                                                      \
    do {                                                                                 \
        if (!(cond)) {                                                                   \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);     \
            if (++tu_failures > 20) exit(1);                                             \
        }                                                                                \
    } while (0)

#define CHECK_EQ_INT(a, b)                                                               \
    do {                                                                                 \
        long long tu_a_ = (long long)(a), tu_b_ = (long long)(b);                        \
        if (tu_a_ != tu_b_) {                                                            \
            fprintf(stderr, "%s:%d: CHECK failed: %s == %s (%lld vs %lld)\n", __FILE__,  \
                    __LINE__, #a, #b, tu_a_, tu_b_);                                     \
            if (++tu_failures > 20) exit(1);                                             \
        }                                                                                \
    } while (0)

#define TEST_EXIT()                                                                      \
    do {                                                                                 \
        if (tu_failures) {                                                               \
            fprintf(stderr, "%d check(s) failed\n", tu_failures);                        \
            return 1;                                                                    \
        }                                                                                \
        printf("ok\n");                                                                  \
        return 0;                                                                        \
    } while (0)

/* "dir/name" in one of four rotating buffers (up to four in use at once). */
static inline const char *tu_path_in(const char *dir, const char *name)
{
    static char buf[4][600];
    static int k;
    k = (k + 1) % 4;
    snprintf(buf[k], sizeof buf[k], "%s/%s", dir, name);
    return buf[k];
}

#endif
