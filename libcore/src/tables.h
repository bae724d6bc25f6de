/*
 * tables.h - internal declarations of the generated marching cubes tables
 * (mc_tables.inc, built by libcore/gen/gentables.c) and small derived facts.
 * Numbering: cube.h.
 */
#ifndef ISOMEND_TABLES_H
#define ISOMEND_TABLES_H

#include "cube.h"

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

#endif /* ISOMEND_TABLES_H */
