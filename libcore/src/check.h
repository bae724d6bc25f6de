/*
 * check.h - what check.c gives the others (private): the sorted check,
 * which isomend_check() takes when check_in_order() (check_order.h) refuses
 * the mesh's order, and the tests' switch.  Both ways give the same report,
 * field for field (core_check_stream compares them).
 */
#ifndef ISOMEND_CHECK_H
#define ISOMEND_CHECK_H

#include "isomend.h"

/* isomend_check()'s report by sorting every edge under its lower vertex
 * (check.c): memory linear in the mesh (isomend_check_memory()), any order.
 * The arguments are checked by isomend_check(). */
isomend_status check_sorted(const float *positions, size_t vertex_count,
                            const uint32_t *triangles, size_t triangle_count, const double *box,
                            isomend_check_report *report);

/* Tests only (not exported; tests link the static library): with `on`,
 * isomend_check() takes check_sorted() for every mesh, so that the
 * streaming checker is compared with the sorted one. */
void check_set_test_sorted(int on);

#endif /* ISOMEND_CHECK_H */
