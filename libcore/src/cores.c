/*
 * cores.c - the cores a call may use (cores.h), and isomend_cores().
 *
 * sysconf(_SC_NPROCESSORS_ONLN) counts the machine's cores; a process
 * started under taskset or in a container with a cpuset may run on fewer,
 * and threads beyond them only take turns.  The affinity mask says how many
 * it has; where it cannot be read, the machine's count.
 */
#define _GNU_SOURCE /* sched_getaffinity, CPU_COUNT */
#include "cores.h"

#include "isomend.h"

#include <sched.h>
#include <unistd.h>

int cores_available(void)
{
#if defined(__linux__)
    cpu_set_t set;
    if (sched_getaffinity(0, sizeof(set), &set) == 0) {
        const int n = CPU_COUNT(&set);
        if (n >= 1)
            return n;
    }
#endif
    const long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : n > 4096 ? 4096 : (int)n;
}

int cores_threads(int requested, int cap)
{
    const int n = requested > 0 ? requested : cores_available();
    return n > cap ? cap : n;
}

int isomend_cores(void) { return cores_available(); }
