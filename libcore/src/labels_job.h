/*
 * labels_job.h - the label-map extraction's types (private): a label's part
 * of a slab, the job (the volume, the labels' codes, the tables), a slab,
 * and a label sample read.  Types and inline functions only; the functions
 * are declared by the files that define them: labels.h (labels.c: the API,
 * the slabs on threads, the meshes joined from the slabs' parts, what the
 * stream shares), labels_sweep.h (one slab's sweep: samples to codes,
 * vertices, triangles), labels_present.h (the labels present),
 * labels_volume.h (a label map's samples: sizes, checks, strides).
 *
 * Codes.  Each sample of the marched grid becomes a uint32 code: the index
 * 0 .. count - 1 of its value among the requested labels, `count` (OTHER)
 * for any other value, `count + 1` (PAD) for the padding layer.  Every
 * decision of the sweep (which edges are cut, each label's cube
 * configuration) compares codes only, so it is the same for every voxel
 * type and needs no look-up after the conversion.
 */
#ifndef ISOMEND_LABELS_JOB_H
#define ISOMEND_LABELS_JOB_H

#include "mesh_internal.h"

#include <stdatomic.h>
#include <string.h>

/* A slab's triangle refers to vertex f of the next slab's first slice as
 * LABEL_FOREIGN | f (that slice belongs to the next slab). */
#define LABEL_FOREIGN 0x80000000u

/* One label's part of one slab: its vertices (ids local to the slab, in the
 * order of the whole mesh) and triangles. */
typedef struct label_part {
    float *pos, *nrm;
    uint32_t *tri;
    uint8_t *org;
    size_t nv, nt, cap_v, cap_t;
    uint32_t foreign; /* vertices of the next slab's first slice numbered here */
} label_part;

/* What every slab reads: the volume, the marched grid, the codes, the options. */
typedef struct label_job {
    const char *data;
    isomend_type type;
    int64_t size;       /* bytes a sample                               */
    int64_t st[3];      /* byte strides of the volume                   */
    int64_t n[3], N[3]; /* volume and marched grid (N = n + 2 pad)      */
    int64_t pad;        /* 0 or 1                                       */
    double o[3], h[3], inv2h[3];
    uint32_t count; /* requested labels: codes 0 .. count - 1       */
    /* value -> code: a table for 8- and 16-bit types (value - table_min), a
     * sorted list of the requested values for 32-bit ones */
    const uint32_t *table;
    int64_t table_min;
    const int64_t *sorted;
    const uint32_t *sorted_code;
    int method; /* ISOMEND_METHOD_MC, _DURST or _DMC            */
    int flip, normals, origins;
    int64_t inner_lo[3], inner_hi[3]; /* marched samples with 6 neighbours in the volume */
    /* The normal of an interior vertex by the indicator's six central
     * differences at its two ends (each -1, 0 or 1; d0x d0y d0z d1x d1y d1z
     * in base 3), computed once by make_vertex()'s formula; zero[]: no
     * direction (the edge's is taken). */
    float normal[729][3];
    uint8_t zero[729];
    uint16_t cut[256]; /* the cube edges a configuration cuts (bit e) */
    atomic_int cancel; /* a slab failed, or progress asked to stop     */
    isomend_progress_fn progress;
    void *progress_user;
} label_job;

#define LABEL_RING 4

/* One slab of layers, swept by one thread. */
typedef struct label_slab {
    label_job *job;
    int64_t k0, k1;   /* layers [k0, k1); slices [k0, k1) are its own, */
    int last;         /* and [k0, N2) for the last slab               */
    int reports;      /* this slab calls the progress callback        */
    label_part *part; /* job->count                                   */
    uint64_t *voxels; /* job->count: samples of each label in its slices */
    uint32_t *codes[LABEL_RING];
    int64_t held[LABEL_RING]; /* the slice each code slot holds, -1: none     */
    uint32_t *ids[2];         /* per slice: 3 axes x N0 N1 edges x 2 ids       */
    int64_t *cols;            /* N0: the cut edges' columns of a row           */
    isomend_status status;
} label_slab;

/* The label sample of `type` at p (machine byte order); 0 for a type that
 * is not a label type. */
static inline int64_t load_label(isomend_type type, const char *p)
{
#define LOAD_AS(T)                                                                                 \
    {                                                                                              \
        T v;                                                                                       \
        memcpy(&v, p, sizeof v);                                                                   \
        return v;                                                                                  \
    }
    switch ((int)type) {
    case ISOMEND_U8: return *(const uint8_t *)p;
    case ISOMEND_I8: return *(const int8_t *)p;
    case ISOMEND_U16: LOAD_AS(uint16_t)
    case ISOMEND_I16: LOAD_AS(int16_t)
    case ISOMEND_U32: LOAD_AS(uint32_t)
    case ISOMEND_I32: LOAD_AS(int32_t)
    default: return 0;
    }
#undef LOAD_AS
}

#endif /* ISOMEND_LABELS_JOB_H */
