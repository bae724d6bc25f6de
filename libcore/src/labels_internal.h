/*
 * labels_internal.h - what the label-map extraction's two files share
 * (private): labels.c (the API, the labels' codes, the slabs on threads,
 * the meshes joined from the slabs' parts) and labels_sweep.c (one slab's
 * sweep: samples to codes, vertices, triangles).
 *
 * Codes.  Each sample of the marched grid becomes a uint32 code: the index
 * 0 .. count - 1 of its value among the requested labels, `count` (OTHER)
 * for any other value, `count + 1` (PAD) for the padding layer.  Every
 * decision of the sweep (which edges are cut, each label's cube
 * configuration) compares codes only, so it is the same for every voxel
 * type and needs no look-up after the conversion.
 */
#ifndef ISOMEND_LABELS_INTERNAL_H
#define ISOMEND_LABELS_INTERNAL_H

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

/* labels_sweep.c: the normal table of the job (its h, inv2h, flip set). */
void label_normal_table(label_job *job);
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

/* labels_sweep.c: the job's tables, normal and cut (its inv2h and flip set). */
void label_job_tables(label_job *job);
/* labels_sweep.c: the code of a value (OTHER when not requested). */
uint32_t label_code(const label_job *job, int64_t value);
/* labels_sweep.c: marched slice m's codes into the ring from `slice` (the
 * volume's slice m - pad, strides st0, st1; unused for a padding slice),
 * its samples counted when the slab owns it. */
void label_fill_codes(label_slab *s, int64_t m, const char *slice, int64_t st0, int64_t st1);
/* labels_sweep.c: the vertices of slice m (its codes and those of m - 1 ..
 * m + 2 in the ring), `foreign`: numbered only (the next slab's); the
 * triangles of layer k (codes k .. k + 2, ids of slices k and k + 1).
 * 0 without memory. */
int label_scan_slice(label_slab *s, int64_t m, int foreign);
int label_march_layer(label_slab *s, int64_t k);
/* labels_sweep.c: sweeps the slab (its scratch arrays allocated by the
 * caller); sets and returns s->status. */
isomend_status label_slab_run(label_slab *s);

/* labels.c: a label type's sample size (0: not a label type); the range of
 * an 8- or 16-bit type (its smallest value, the count; 0 for 32-bit); the
 * volume checked (data needed or not); its byte strides; int64_t order. */
size_t label_type_size(isomend_type type);
size_t label_small_range(isomend_type type, int64_t *min);
isomend_status label_check_volume(const isomend_volume *vol, int pad, int need_data);
void label_strides(const isomend_volume *vol, int64_t st[3]);
int label_cmp_value(const void *a, const void *b);

/* labels_present.c: the labels present, ascending, and their samples, as
 * malloc'ed arrays. */
isomend_status label_list_present(const isomend_volume *vol, int64_t **values, uint64_t **voxels,
                                  size_t *count);

/* labels.c: what the in-memory extraction and the stream share. */
typedef struct label_setup {
    label_job *job;
    isomend_labels *result; /* values, voxels, meshes (filled at the end)   */
    uint32_t *table, *sorted_code;
    int64_t *sorted;
} label_setup;
/* The checks, the result's labels (labels NULL: every label present but 0,
 * read from vol->data) and the job; vol->data may be NULL unless
 * `need_data` or labels NULL (a stream).  On failure nothing is left. */
isomend_status label_setup_begin(const isomend_volume *vol, const int64_t *labels, size_t count,
                                 const isomend_options *opts, int need_data, label_setup *su);
void label_setup_free(label_setup *su); /* the job and tables, and the result unless taken */
int label_slab_alloc(label_slab *s, label_job *job);
void label_slab_free(label_slab *s, size_t count);
/* The slabs' voxels summed and each label's mesh joined from their parts. */
isomend_status label_join_all(label_job *job, label_slab *slab, int nslabs, isomend_labels *r);

#endif /* ISOMEND_LABELS_INTERNAL_H */
