/*
 * tables.h - internal declarations of the generated marching cubes tables
 * (mc_tables.inc, built by libcore/gen/gentables.c) and small derived facts.
 * Numbering: cube.h.
 */
#ifndef ISOMEND_TABLES_H
#define ISOMEND_TABLES_H

#include "cube.h"

#include <stdint.h>

#define MC_MAX_TRI 4

/* Elementary case (0..14) of each configuration. */
extern const unsigned char mc_case_of[256];
/* Triangles per configuration (0..4). */
extern const unsigned char mc_tri_count[256];
/* Edge triples of each configuration's triangles, -1 padded. */
extern const signed char mc_tri_edges[256][3 * MC_MAX_TRI];
/* Bit f set when face f of the configuration is ambiguous. */
extern const unsigned char mc_ambiguous_faces[256];
/* Directed face segments p->q, r->s on each ambiguous face, in loop order. */
extern const signed char mc_face_loop[256][6][4];

/* A configuration is inverted when it has 5 or more positive corners. */
static inline int mc_is_inverted(unsigned config)
{
    unsigned n = 0;
    for (; config; config &= config - 1)
        n++;
    return n >= 5;
}

/* Whether an ambiguous face shared by configurations cfg and nb gets the
 * mending quadrilateral: always for Durst, for DMC when exactly one of the
 * two is inverted (march_template.h, labels_sweep.c). */
static inline int mc_face_mended(int durst, unsigned cfg, unsigned nb)
{
    return durst || mc_is_inverted(cfg) != mc_is_inverted(nb);
}

/* The quadrilateral (s, r, q, p) of a face loop p q r s (mc_face_loop) as
 * the triangles (s, r, q) and (s, q, p) into out[0..6), wound like the
 * table's (reversed with flip). */
static inline void mc_quad_triangles(uint32_t p, uint32_t q, uint32_t r, uint32_t s, int flip,
                                     uint32_t *out)
{
    const uint32_t quad[6] = {s, r, q, s, q, p};
    for (int h = 0; h < 6; h += 3) {
        out[h] = quad[h];
        out[h + 1] = flip ? quad[h + 2] : quad[h + 1];
        out[h + 2] = flip ? quad[h + 1] : quad[h + 2];
    }
}

#endif /* ISOMEND_TABLES_H */
