/*
 * check_order.h - what check_order.c gives the others (private).
 */
#ifndef ISOMEND_CHECK_ORDER_H
#define ISOMEND_CHECK_ORDER_H

#include "isomend.h"

/* isomend_check()'s report by the streaming checker, fed the triangles in
 * their order and each vertex retired after its last triangle (the
 * arguments checked by isomend_check()).  ISOMEND_ERR_UNSUPPORTED (report
 * untouched) when the vertices live at once would exceed a quarter of the
 * mesh's (and 65 536): an order that is not a sweep, where check_sorted()
 * (check.h) is the faster and the smaller. */
isomend_status check_in_order(const float *positions, size_t vertex_count,
                              const uint32_t *triangles, size_t triangle_count, const double *box,
                              isomend_check_report *report);

/* The bytes check_in_order() allocates for these triangles at most (its
 * last-triangle table and the streaming checker's window, measured by one
 * pass over them), or 0 when it would refuse their order. */
uint64_t check_in_order_memory(const uint32_t *triangles, size_t vertex_count,
                               size_t triangle_count);

#endif /* ISOMEND_CHECK_ORDER_H */
