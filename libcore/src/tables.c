/*
 * tables.c - the generated marching cubes table (mc_tables.inc) and its
 * public read-only accessors.
 */
#include "isomend.h"
#include "tables.h"

#include "mc_tables.inc"

int isomend_case_of(unsigned config)
{
    return config < 256 ? mc_case_of[config] : -1;
}

int isomend_case_triangles(unsigned config, int *edges)
{
    if (config >= 256)
        return -1;
    int n = mc_tri_count[config];
    if (edges)
        for (int i = 0; i < 3 * n; i++)
            edges[i] = mc_tri_edges[config][i];
    return n;
}
