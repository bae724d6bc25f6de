/*
 * labels.c - label maps (segmentations): every requested label's surface
 * in one pass over the volume (isomend_labels_*; the contract is in
 * isomend.h, the design and its measurements in docs/labels.md).
 *
 * This file is the driver: the arguments checked (the labels present are
 * listed by labels_present.c), the value -> code map the sweep uses, the slabs
 * (consecutive layers, one a thread, swept by labels_sweep.c), and each
 * label's mesh joined from the slabs' parts: ids offset by the vertices of
 * the earlier slabs, a foreign id (a vertex of the next slab's first slice)
 * by the next slab's offset.  Nothing depends on the number of slabs but
 * the time: every label's mesh is the same byte for byte for any thread
 * count, and is isomend_extract()'s on the label's indicator at level 0.5.
 */
#include "cores.h"
#include "labels.h"
#include "labels_present.h"
#include "labels_sweep.h"
#include "labels_volume.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

struct isomend_labels {
    size_t count;
    int64_t *value;
    uint64_t *voxels;
    isomend_mesh **mesh;
};

/* ------------------------------------------------------------ the slabs */

static void *slab_thread(void *p)
{
    label_slab_run(p);
    return NULL;
}

static void free_parts(label_part *part, size_t count)
{
    if (!part)
        return;
    for (size_t l = 0; l < count; l++) {
        free(part[l].pos);
        free(part[l].nrm);
        free(part[l].tri);
        free(part[l].org);
    }
    free(part);
}

void label_slab_free(label_slab *s, size_t count)
{
    free_parts(s->part, count);
    free(s->voxels);
    for (int r = 0; r < LABEL_RING; r++)
        free(s->codes[r]);
    free(s->ids[0]);
    free(s->ids[1]);
    free(s->cols);
}

int label_slab_alloc(label_slab *s, label_job *job)
{
    const size_t plane = (size_t)job->N[0] * (size_t)job->N[1];
    s->job = job;
    s->part = calloc(job->count ? job->count : 1, sizeof(label_part));
    s->voxels = calloc(job->count ? job->count : 1, sizeof(uint64_t));
    int ok = s->part && s->voxels;
    for (int r = 0; r < LABEL_RING; r++)
        ok = (s->codes[r] = malloc(sizeof(uint32_t) * plane)) && ok;
    for (int r = 0; r < 2; r++)
        ok = (s->ids[r] = malloc(sizeof(uint32_t) * 6 * plane)) && ok;
    ok = (s->cols = malloc(sizeof(int64_t) * (size_t)job->N[0])) && ok;
    for (int r = 0; r < LABEL_RING; r++)
        s->held[r] = -1;
    return ok;
}

/* The join of one label's parts into its mesh. */
typedef struct join_job {
    label_job *job;
    label_slab *slab;
    int nslabs;
    isomend_mesh **mesh;
    isomend_status *status;
} join_job;

/* `bytes` for an array that continues *first (a part's array, taken over:
 * realloc moves large blocks by remapping, without a copy), else new. */
static void *take_array(void **first, size_t bytes)
{
    void *p = realloc(*first, bytes ? bytes : 1);
    if (p)
        *first = NULL;
    return p;
}

static isomend_status join_label(const join_job *jj, size_t l, isomend_mesh *m)
{
    const label_job *job = jj->job;
    uint64_t nv = 0, nt = 0;
    for (int s = 0; s < jj->nslabs; s++) {
        nv += jj->slab[s].part[l].nv;
        nt += jj->slab[s].part[l].nt;
    }
    if (nv > UINT32_MAX)
        return ISOMEND_ERR_TOO_LARGE;
    m->nv = (size_t)nv;
    m->nt = (size_t)nt;
    /* the first slab's arrays become the mesh's, the others are appended */
    label_part *p0 = &jj->slab[0].part[l];
    m->pos = take_array((void **)&p0->pos, sizeof(float) * 3 * nv);
    m->nrm = job->normals ? take_array((void **)&p0->nrm, sizeof(float) * 3 * nv) : NULL;
    m->tri = take_array((void **)&p0->tri, sizeof(uint32_t) * 3 * nt);
    m->org = job->origins ? take_array((void **)&p0->org, nt) : NULL;
    if (!m->pos || !m->tri || (job->normals && !m->nrm) || (job->origins && !m->org))
        return ISOMEND_ERR_OUT_OF_MEMORY;
    uint64_t base = 0, at_t = 0;
    for (int s = 0; s < jj->nslabs; s++) {
        label_part *p = &jj->slab[s].part[l];
        const uint64_t next = base + p->nv;
        if (s > 0 && p->nv) {
            memcpy(m->pos + 3 * base, p->pos, sizeof(float) * 3 * p->nv);
            if (job->normals)
                memcpy(m->nrm + 3 * base, p->nrm, sizeof(float) * 3 * p->nv);
        }
        uint32_t *out = m->tri + 3 * at_t;
        const uint32_t *in = s > 0 ? p->tri : out;
        for (size_t q = 0; q < 3 * p->nt; q++) {
            const uint32_t id = in[q];
            out[q] = (uint32_t)(id & LABEL_FOREIGN ? next + (id & ~LABEL_FOREIGN) : base + id);
        }
        if (s > 0 && job->origins && p->nt)
            memcpy(m->org + at_t, p->org, p->nt);
        at_t += p->nt;
        base = next;
        /* this part is no longer needed */
        free(p->pos);
        free(p->nrm);
        free(p->tri);
        free(p->org);
        memset(p, 0, sizeof *p);
    }
    m->slices.n = job->n[2];
    m->slices.pad = job->pad;
    m->slices.gap = job->h[2];
    for (int a = 0; a < 3; a++) {
        m->box[a] = job->o[a];
        m->box[3 + a] = job->o[a] + (double)(job->N[a] - 1) * job->h[a];
        m->N[a] = job->N[a];
    }
    m->h[0] = job->h[0];
    m->h[1] = job->h[1];
    return ISOMEND_OK;
}

static void join_range(void *arg, size_t lo, size_t hi)
{
    const join_job *jj = arg;
    for (size_t l = lo; l < hi; l++) {
        isomend_mesh *m = calloc(1, sizeof(isomend_mesh));
        jj->status[l] = m ? join_label(jj, l, m) : ISOMEND_ERR_OUT_OF_MEMORY;
        jj->mesh[l] = m;
    }
}

void isomend_labels_destroy(isomend_labels *r)
{
    if (!r)
        return;
    if (r->mesh)
        for (size_t l = 0; l < r->count; l++)
            isomend_mesh_destroy(r->mesh[l]);
    free(r->mesh);
    free(r->value);
    free(r->voxels);
    free(r);
}

/* The value -> code map of the job: a table for small types, the sorted
 * requested values otherwise.  0 without memory. */
static int build_codes(label_job *job, const int64_t *value, uint32_t **table, int64_t **sorted,
                       uint32_t **sorted_code)
{
    int64_t min;
    const size_t range = label_small_range(job->type, &min);
    if (range) {
        uint32_t *t = malloc(sizeof(uint32_t) * range);
        if (!(*table = t))
            return 0;
        for (size_t q = 0; q < range; q++)
            t[q] = job->count;
        for (uint32_t l = 0; l < job->count; l++)
            if (value[l] >= min && value[l] < min + (int64_t)range)
                t[value[l] - min] = l;
        job->table = t;
        job->table_min = min;
        return 1;
    }
    int64_t *pairs = malloc(sizeof(int64_t) * 2 * (job->count ? job->count : 1));
    *sorted = malloc(sizeof(int64_t) * (job->count ? job->count : 1));
    *sorted_code = malloc(sizeof(uint32_t) * (job->count ? job->count : 1));
    if (!pairs || !*sorted || !*sorted_code) {
        free(pairs);
        return 0;
    }
    for (uint32_t l = 0; l < job->count; l++) {
        pairs[2 * l] = value[l];
        pairs[2 * l + 1] = l;
    }
    qsort(pairs, job->count, 2 * sizeof(int64_t), label_cmp_value); /* by value (first) */
    for (uint32_t l = 0; l < job->count; l++) {
        (*sorted)[l] = pairs[2 * l];
        (*sorted_code)[l] = (uint32_t)pairs[2 * l + 1];
    }
    free(pairs);
    job->sorted = *sorted;
    job->sorted_code = *sorted_code;
    return 1;
}

isomend_status label_join_all(label_job *job, label_slab *slab, int nslabs, isomend_labels *r)
{
    for (int s = 0; s < nslabs; s++) { /* the scratch arrays, before the join */
        for (int q = 0; q < LABEL_RING; q++) {
            free(slab[s].codes[q]);
            slab[s].codes[q] = NULL;
        }
        for (uint32_t l = 0; l < job->count; l++)
            r->voxels[l] += slab[s].voxels[l];
    }
    isomend_status *st = calloc(job->count ? job->count : 1, sizeof(isomend_status));
    if (!st)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    join_job jj = {job, slab, nslabs, r->mesh, st};
    parallel_for_from(job->count, 2, join_range, &jj);
    isomend_status status = ISOMEND_OK;
    for (uint32_t l = 0; l < job->count && status == ISOMEND_OK; l++)
        status = st[l];
    free(st);
    return status;
}

static isomend_status run_slabs(label_job *job, int nthreads, isomend_labels *r)
{
    const int64_t layers = job->N[2] - 1;
    int nslabs = nthreads;
    if (nslabs > layers / 4)
        nslabs = layers / 4 > 0 ? (int)(layers / 4) : 1;
    label_slab *slab = calloc((size_t)nslabs, sizeof(label_slab));
    pthread_t *tid = calloc((size_t)nslabs, sizeof(pthread_t));
    char *started = calloc((size_t)nslabs, 1);
    isomend_status status = slab && tid && started ? ISOMEND_OK : ISOMEND_ERR_OUT_OF_MEMORY;
    for (int s = 0; s < nslabs && status == ISOMEND_OK; s++) {
        slab[s].k0 = layers * s / nslabs;
        slab[s].k1 = layers * (s + 1) / nslabs;
        slab[s].last = s == nslabs - 1;
        slab[s].reports = s == 0;
        if (!label_slab_alloc(&slab[s], job))
            status = ISOMEND_ERR_OUT_OF_MEMORY;
    }
    if (status == ISOMEND_OK) {
        for (int s = 1; s < nslabs; s++)
            started[s] = pthread_create(&tid[s], NULL, slab_thread, &slab[s]) == 0;
        label_slab_run(&slab[0]);
        for (int s = 1; s < nslabs; s++) {
            if (started[s])
                pthread_join(tid[s], NULL);
            else /* no thread: swept here, the mesh is the same */
                label_slab_run(&slab[s]);
        }
        for (int s = 0; s < nslabs && status == ISOMEND_OK; s++)
            status = slab[s].status;
        /* a slab that stopped because another failed reports cancelled */
        for (int s = 0; s < nslabs; s++)
            if (slab[s].status != ISOMEND_OK && slab[s].status != ISOMEND_ERR_CANCELLED)
                status = slab[s].status;
    }
    if (status == ISOMEND_OK)
        status = label_join_all(job, slab, nslabs, r);
    for (int s = 0; slab && s < nslabs; s++)
        label_slab_free(&slab[s], job->count);
    free(slab);
    free(tid);
    free(started);
    return status;
}

void label_setup_free(label_setup *su)
{
    free(su->table);
    free(su->sorted);
    free(su->sorted_code);
    free(su->job);
    isomend_labels_destroy(su->result);
    memset(su, 0, sizeof *su);
}

isomend_status label_setup_begin(const isomend_volume *vol, const int64_t *labels, size_t count,
                                 const isomend_options *opts, int need_data, label_setup *su)
{
    memset(su, 0, sizeof *su);
    isomend_options defaults;
    isomend_options_init(&defaults);
    const isomend_options *o = opts ? opts : &defaults;
    if ((unsigned)o->method >= ISOMEND_METHOD_COUNT || (o->flags & ~ISOMEND_FLAGS_ALL) ||
        (count && !labels))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    if (o->method != ISOMEND_METHOD_MC && o->method != ISOMEND_METHOD_DURST &&
        o->method != ISOMEND_METHOD_DMC)
        return ISOMEND_ERR_UNSUPPORTED;
    const int pad = (o->flags & ISOMEND_FLAG_PAD) != 0;
    isomend_status status = label_check_volume(vol, pad, need_data || !labels);
    if (status != ISOMEND_OK)
        return status;
    if (count >= (size_t)LABEL_FOREIGN - 2)
        return ISOMEND_ERR_TOO_LARGE;

    isomend_labels *r = su->result = calloc(1, sizeof *r);
    if (!r)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    if (!labels) { /* every label present but 0 */
        uint64_t *n = NULL;
        status = label_list_present(vol, &r->value, &n, &r->count);
        free(n);
        if (status != ISOMEND_OK) {
            label_setup_free(su);
            return status;
        }
        size_t keep = 0;
        for (size_t l = 0; l < r->count; l++)
            if (r->value[l] != 0)
                r->value[keep++] = r->value[l];
        r->count = keep;
    } else {
        r->count = count;
        r->value = malloc(sizeof(int64_t) * (count ? count : 1));
        int64_t *check = malloc(sizeof(int64_t) * (count ? count : 1));
        if (!r->value || !check) {
            free(check);
            label_setup_free(su);
            return ISOMEND_ERR_OUT_OF_MEMORY;
        }
        memcpy(r->value, labels, sizeof(int64_t) * count);
        memcpy(check, labels, sizeof(int64_t) * count);
        qsort(check, count, sizeof(int64_t), label_cmp_value);
        for (size_t l = 1; l < count; l++)
            if (check[l] == check[l - 1])
                status = ISOMEND_ERR_INVALID_ARGUMENT; /* a label twice */
        free(check);
        if (status != ISOMEND_OK) {
            label_setup_free(su);
            return status;
        }
    }
    r->voxels = calloc(r->count ? r->count : 1, sizeof(uint64_t));
    r->mesh = calloc(r->count ? r->count : 1, sizeof(isomend_mesh *));
    label_job *job = su->job = calloc(1, sizeof *job);
    if (!r->voxels || !r->mesh || !job) {
        label_setup_free(su);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    job->data = vol->data;
    job->type = vol->type;
    job->size = (int64_t)label_type_size(vol->type);
    label_strides(vol, job->st);
    job->pad = pad;
    for (int a = 0; a < 3; a++) {
        job->n[a] = vol->dims[a];
        job->N[a] = vol->dims[a] + 2 * pad;
        job->h[a] = vol->spacing[a];
        job->inv2h[a] = 0.5 / vol->spacing[a];
        job->o[a] = vol->origin[a] - (double)pad * vol->spacing[a];
        job->inner_lo[a] = pad + 1;
        job->inner_hi[a] = pad + vol->dims[a] - 2;
    }
    job->count = (uint32_t)r->count;
    job->method = o->method;
    job->flip = (o->flags & ISOMEND_FLAG_FLIP) != 0;
    job->normals = !(o->flags & ISOMEND_FLAG_NO_NORMALS);
    job->origins = !(o->flags & ISOMEND_FLAG_NO_ORIGINS);
    label_job_tables(job);
    atomic_init(&job->cancel, 0);
    job->progress = o->progress;
    job->progress_user = o->progress_user;
    if (!build_codes(job, r->value, &su->table, &su->sorted, &su->sorted_code)) {
        label_setup_free(su);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    return ISOMEND_OK;
}

isomend_status isomend_labels_extract(const isomend_volume *vol, const int64_t *labels,
                                      size_t count, const isomend_options *opts,
                                      isomend_labels **out)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
    label_setup su;
    isomend_status status = label_setup_begin(vol, labels, count, opts, 1, &su);
    if (status != ISOMEND_OK)
        return status;
    const int threads = opts ? opts->threads : 0;
    status = run_slabs(su.job, cores_threads(threads, 64), su.result);
    if (status == ISOMEND_OK) {
        if (opts && opts->progress)
            (void)opts->progress(opts->progress_user, 1.0);
        *out = su.result;
        su.result = NULL;
    }
    label_setup_free(&su);
    return status;
}

size_t isomend_labels_count(const isomend_labels *r)
{
    return r ? r->count : 0;
}

int64_t isomend_labels_value(const isomend_labels *r, size_t index)
{
    return r && index < r->count ? r->value[index] : 0;
}

uint64_t isomend_labels_voxels(const isomend_labels *r, size_t index)
{
    return r && index < r->count ? r->voxels[index] : 0;
}

const isomend_mesh *isomend_labels_mesh(const isomend_labels *r, size_t index)
{
    return r && index < r->count ? r->mesh[index] : NULL;
}

isomend_mesh *isomend_labels_take_mesh(isomend_labels *r, size_t index)
{
    if (!r || index >= r->count)
        return NULL;
    isomend_mesh *m = r->mesh[index];
    r->mesh[index] = NULL;
    return m;
}
