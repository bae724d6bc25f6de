/*
 * team.h - a team of threads kept for the length of one post-processing
 * call, so that a step made of many short loops (the smoothing's N filter
 * steps, its fans and restoration passes) pays for starting threads once
 * instead of once a loop: parallel_for() starts and joins its threads at
 * every call (tens of microseconds each on a virtual machine), which on a
 * mesh of 30 000 vertices costs more than the loop.
 *
 * team_for(t, n, fn, arg) splits [0, n) into the team's ranges exactly as
 * parallel_for() does (thread k gets n * k / T .. n * (k + 1) / T), runs
 * them (the caller takes range 0) and returns when all are done; a loop of
 * fewer than TEAM_MIN_ITEMS items a thread runs on the caller's thread
 * alone.  What a loop computes must not depend on how it is split (each item
 * written by one range, as in every parallel_for() client).  The workers
 * spin for a moment between loops and then sleep on a condition variable.
 * A team that could not start (no memory, no threads) runs everything on the
 * caller's thread: team_start() never fails, team_stop(NULL) is allowed.
 */
#ifndef ISOMEND_TEAM_H
#define ISOMEND_TEAM_H

#include <stddef.h>

#define TEAM_MIN_ITEMS 2048 /* the items a thread gets at least */
#define TEAM_MAX_THREADS 8

typedef struct team team;

/* A team for loops of up to about n items: as many threads as cores (cores.h; at
 * most 8), fewer where n gives them less than TEAM_MIN_ITEMS each; NULL
 * (run serially) for one thread or when threads cannot start. */
team *team_start(size_t n);
void team_for(team *t, size_t n, void (*fn)(void *arg, size_t lo, size_t hi), void *arg);
/* The same split among threads from min_items items each on (items that
 * are blocks of work). */
void team_for_from(team *t, size_t n, size_t min_items, void (*fn)(void *arg, size_t lo, size_t hi),
                   void *arg);
/* The threads of team t (1 for NULL). */
int team_threads(const team *t);
void team_stop(team *t);

#endif
