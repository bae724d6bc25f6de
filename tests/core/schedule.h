/*
 * schedule.h - the C tests' choice of isomend_extract()'s schedule (tests
 * only).
 *
 * isomend_extract() takes the one pass for one or two threads on grids of
 * 2^21 samples and more, and its two threads split apart on sparse meshes
 * (libcore/src/one_pass.c).  A test run with --schedule=onepass takes the one
 * pass at every size, --schedule=apart also splits apart whatever the
 * density, --schedule=apartsolo also has the first thread do every move
 * (extract_set_test_schedule, linked from the static library), so that one
 * binary reaches every path on the tests' small grids.
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
                 {"onepass", SCHEDULE_ONE_PASS},
                 {"apart", SCHEDULE_APART},
                 {"apartsolo", SCHEDULE_APART_SOLO}};
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
            fprintf(stderr, "%s: unknown schedule '%s' (auto, onepass, apart, apartsolo)\n",
                    argv[0], argv[i] + 11);
            return 1;
        }
        fprintf(stderr, "schedule: %s\n", argv[i] + 11);
    }
    return 0;
}

#endif /* ISOMEND_TEST_SCHEDULE_H */
