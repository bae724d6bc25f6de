/*
 * cores.h - how many threads a call runs on when it is not told: the cores
 * this process may run on (its affinity mask: taskset, a container's
 * cpuset), not every core the machine has online.
 */
#ifndef ISOMEND_CORES_H
#define ISOMEND_CORES_H

/* The cores this process may run on, at least 1 (isomend_cores()). */
int cores_available(void);

/* `requested` threads when positive, else cores_available(); at most cap. */
int cores_threads(int requested, int cap);

#endif
