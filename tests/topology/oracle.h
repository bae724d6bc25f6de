/*
 * oracle.h - the topology of the trilinear interpolant's isosurface,
 * computed independently of any mesh (tests only).
 *
 * For a grid of finite samples and an iso level, the oracle surrounds the
 * grid with one layer of samples below iso (what ISOMEND_FLAG_PAD does: the
 * surface is closed) and computes, for P = {f >= iso} of the piecewise
 * trilinear interpolant f and its complement Q = {f < iso}:
 *
 *   b0(P), b0(Q)   by union-find over grid vertices: every component of P
 *                  (or Q) inside a cell contains a corner of the cell (f is
 *                  harmonic in a cell: no interior extremum), and the
 *                  components inside one cell are computed exactly by a
 *                  sweep of planes x = s (oracle.c explains it);
 *   chi(P)         by additivity over the open cells of the grid (vertices,
 *                  open edges, open faces, open cubes), each term from the
 *                  exact structure of the closed cell's piece;
 *
 * and from those the closed surface S = boundary of P:
 *   b0(S) = b0(P) + b0(Q) - 1   (components of P and Q form a tree whose
 *                                edges are the components of S),
 *   chi(S) = 2 chi(P),          genus sum = b0(S) - chi(S) / 2,
 *   b1(S) = 2 b0(S) - chi(S).
 *
 * Ties follow isomend's rule: a sample equal to iso is in P, a face or slice
 * saddle with value iso joins the P corners (the level iso - e).
 * Limits: exact for generic values up to the rounding of the sweep's
 * critical heights; tests/topology/test_oracle.c checks it on shapes whose
 * topology is known and against a fine digital sampling.
 */
#ifndef ISOMEND_TEST_ORACLE_H
#define ISOMEND_TEST_ORACLE_H

typedef struct oracle_result {
    long b0_p, b0_q;     /* components of P and of Q (including outside) */
    long chi_p;          /* Euler characteristic of P                    */
    long b0_s, chi_s;    /* the closed surface                           */
    long b1_s;           /* 2 b0 - chi                                   */
} oracle_result;

/* vals: nx*ny*nz finite samples, x fastest.  Returns 0, or -1 on a NaN or
 * out of memory. */
int oracle_topology(const double *vals, int nx, int ny, int nz, double iso, oracle_result *r);

/* One cell with corner values v[8] (cube.h numbering): components of P
 * (sign 1) or Q (sign 0) inside the closed cell, a label per corner (-1 not
 * in the set); returns the count.  *chi (may be NULL) receives chi of
 * P or Q inside the closed cell. */
int oracle_cell(const double v[8], double iso, int sign, int label[8], long *chi);

/* The same for one cell by digital sampling at m+1 points per edge
 * (6-connectivity, cubical complex), for cross-checking oracle_cell. */
int oracle_cell_digital(const double v[8], double iso, int m, int sign, int label[8], long *chi);

/* The whole (padded) grid by digital sampling at m points per cell edge:
 * 6-connected components of the samples in P and in Q, chi of the cubical
 * complex of P.  For cross-checking only: thin necks near saddles whose
 * value is close to iso are lost at any fixed resolution. */
int oracle_topology_digital(const double *vals, int nx, int ny, int nz, double iso, int m,
                            oracle_result *r);

#endif
