/*
 * schedule.h - the C tests' choice of isomend_extract()'s schedule (tests
 * only).
 *
 * isomend_extract() runs the caller's run of slices from the bottom and,
 * on grids of 2^20 samples and more, other threads' staged runs from the top
 * down, moved into place at the end (libcore/src/slabs.c).  A test run with
 * --schedule=anysize takes staged runs at every size, --schedule=thin takes
 * them one layer at a time, --schedule=staged also stops the caller's run
 * after layer 0, so that every other layer is staged and moved, and
 * --schedule=counted takes the counted split of two threads (a dense mesh)
 * at every size and density (extract_set_test_schedule, linked from the
 * static library): one binary
 * reaches every path on the tests' small grids.
 */
#ifndef ISOMEND_TEST_SCHEDULE_H
#define ISOMEND_TEST_SCHEDULE_H

#include "extract.h"

#include <stdio.h>
#include <string.h>

/* Handles a --schedule=NAME argument, if any: returns 0 to go on, 1 to stop
 * with an error (unknown name, message printed). */
static inline int schedule_from_args(int argc, char **argv)
{
    static const struct {
        const char *name;
        extract_schedule schedule;
    } names[] = {{"auto", SCHEDULE_AUTO},
                 {"anysize", SCHEDULE_ANY_SIZE},
                 {"thin", SCHEDULE_THIN},
                 {"staged", SCHEDULE_STAGED},
                 {"counted", SCHEDULE_COUNTED}};
    for (int i = 1; i < argc; i++) {
        if (strncmp(argv[i], "--schedule=", 11) != 0)
            continue;
        int found = 0;
        for (size_t k = 0; k < sizeof names / sizeof names[0]; k++)
            if (strcmp(argv[i] + 11, names[k].name) == 0) {
                extract_set_test_schedule(names[k].schedule);
                found = 1;
            }
        if (!found) {
            fprintf(stderr, "%s: unknown schedule '%s' (auto, anysize, thin, staged, counted)\n",
                    argv[0], argv[i] + 11);
            return 1;
        }
        fprintf(stderr, "schedule: %s\n", argv[i] + 11);
    }
    return 0;
}

#endif /* ISOMEND_TEST_SCHEDULE_H */
