/*
 * labels_sweep.h - one slab's sweep (private; labels_sweep.c).
 */
#ifndef ISOMEND_LABELS_SWEEP_H
#define ISOMEND_LABELS_SWEEP_H

#include "labels_job.h"

/* the normal table of the job (its h, inv2h, flip set). */
void label_normal_table(label_job *job);
/* the job's tables, normal and cut (its inv2h and flip set). */
void label_job_tables(label_job *job);
/* the code of a value (OTHER when not requested). */
uint32_t label_code(const label_job *job, int64_t value);
/* marched slice m's codes into the ring from `slice` (the
 * volume's slice m - pad, strides st0, st1; unused for a padding slice),
 * its samples counted when the slab owns it. */
void label_fill_codes(label_slab *s, int64_t m, const char *slice, int64_t st0, int64_t st1);
/* the vertices of slice m (its codes and those of m - 1 ..
 * m + 2 in the ring), `foreign`: numbered only (the next slab's); the
 * triangles of layer k (codes k .. k + 2, ids of slices k and k + 1).
 * 0 without memory. */
int label_scan_slice(label_slab *s, int64_t m, int foreign);
int label_march_layer(label_slab *s, int64_t k);
/* sweeps the slab (its scratch arrays allocated by the
 * caller); sets and returns s->status. */
isomend_status label_slab_run(label_slab *s);

#endif /* ISOMEND_LABELS_SWEEP_H */
