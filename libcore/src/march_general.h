/*
 * march_general.h - the per-cube hook of methods.h and tetra's diagonals (private;
 * march_general.c).
 */
#ifndef ISOMEND_MARCH_GENERAL_H
#define ISOMEND_MARCH_GENERAL_H

#include "context.h"

unsigned method_cube(worker *w, int64_t i, int64_t j, int64_t k, unsigned cfg, pass_kind pass,
                     const uint32_t *const ep[12], const uint32_t *ids0, const uint32_t *ids1,
                     uint32_t *out, uint8_t *org);
uint64_t scan_diagonals(const ctx *c, const uint8_t *s, const uint8_t *t, int64_t j, int64_t m,
                        uint32_t *ids, uint64_t id, int write);

#endif /* ISOMEND_MARCH_GENERAL_H */
