/*
 * labels.c - label maps (segmentations): every requested label's surface
 * in one pass over the volume (isomend_labels_*; the contract is in
 * isomend.h, the design and its measurements in docs/labels.md).
 *
 * This file is the driver: the arguments checked, the labels present
 * (isomend_labels_present, a histogram for 8- and 16-bit types, a hash
 * table for 32-bit ones), the value -> code map the sweep uses, the slabs
 * (consecutive layers, one a thread, swept by labels_sweep.c), and each
 * label's mesh joined from the slabs' parts: ids offset by the vertices of
 * the earlier slabs, a foreign id (a vertex of the next slab's first slice)
 * by the next slab's offset.  Nothing depends on the number of slabs but
 * the time: every label's mesh is the same byte for byte for any thread
 * count, and is isomend_extract()'s on the label's indicator at level 0.5.
 */
#include "labels_internal.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

struct isomend_labels {
    size_t count;
    int64_t *value;
    uint64_t *voxels;
    isomend_mesh **mesh;
};

/* The size of a label sample, 0 for a type that is not a label type. */
static size_t label_type_size(isomend_type type)
{
    switch ((int)type) {
    case ISOMEND_U8:
    case ISOMEND_I8: return 1;
    case ISOMEND_U16:
    case ISOMEND_I16: return 2;
    case ISOMEND_U32:
    case ISOMEND_I32: return 4;
    default: return 0;
    }
}

/* The smallest value of an 8- or 16-bit type and the number of its values;
 * 0 values for 32-bit types. */
static size_t small_range(isomend_type type, int64_t *min)
{
    switch ((int)type) {
    case ISOMEND_U8: *min = 0; return 256;
    case ISOMEND_I8: *min = -128; return 256;
    case ISOMEND_U16: *min = 0; return 65536;
    case ISOMEND_I16: *min = -32768; return 65536;
    default: *min = 0; return 0;
    }
}

static isomend_status check_volume(const isomend_volume *vol, int pad)
{
    if (!vol || !vol->data || !label_type_size(vol->type))
        return ISOMEND_ERR_INVALID_ARGUMENT;
    const int64_t min = pad ? 1 : 2;
    for (int a = 0; a < 3; a++) {
        if (vol->dims[a] < min || vol->dims[a] > ((int64_t)1 << 31))
            return ISOMEND_ERR_BAD_DIMENSIONS;
        if (!(vol->spacing[a] > 0.0) || !isfinite(vol->spacing[a]))
            return ISOMEND_ERR_BAD_SPACING;
        if (!isfinite(vol->origin[a]))
            return ISOMEND_ERR_INVALID_ARGUMENT;
    }
    return vol->slice_origins ? ISOMEND_ERR_UNSUPPORTED : ISOMEND_OK;
}

static void volume_strides(const isomend_volume *vol, int64_t st[3])
{
    const int64_t size = (int64_t)label_type_size(vol->type);
    if (vol->strides[0] == 0 && vol->strides[1] == 0 && vol->strides[2] == 0) {
        st[0] = size;
        st[1] = size * vol->dims[0];
        st[2] = st[1] * vol->dims[1];
    } else {
        memcpy(st, vol->strides, sizeof(int64_t) * 3);
    }
}

/* ------------------------------------------------------- labels present */

static int64_t sample_at(const isomend_volume *vol, const int64_t st[3], int64_t i, int64_t j,
                         int64_t k)
{
    return load_label(vol->type, (const char *)vol->data + i * st[0] + j * st[1] + k * st[2]);
}

/* A hash table of 32-bit values and their counts (open addressing). */
typedef struct value_set {
    int64_t *value;
    uint64_t *count;
    size_t cap, n;
} value_set;

static int set_add(value_set *s, int64_t v, uint64_t n)
{
    if (2 * (s->n + 1) > s->cap) {
        const size_t cap = s->cap ? 2 * s->cap : 1024;
        int64_t *value = malloc(sizeof(int64_t) * cap);
        uint64_t *count = calloc(cap, sizeof(uint64_t));
        if (!value || !count) {
            free(value);
            free(count);
            return 0;
        }
        for (size_t q = 0; q < s->cap; q++) {
            if (!s->count[q])
                continue;
            size_t h = (size_t)((uint64_t)s->value[q] * 0x9E3779B97F4A7C15ull >> 20) & (cap - 1);
            while (count[h])
                h = (h + 1) & (cap - 1);
            value[h] = s->value[q];
            count[h] = s->count[q];
        }
        free(s->value);
        free(s->count);
        s->value = value;
        s->count = count;
        s->cap = cap;
    }
    size_t h = (size_t)((uint64_t)v * 0x9E3779B97F4A7C15ull >> 20) & (s->cap - 1);
    while (s->count[h] && s->value[h] != v)
        h = (h + 1) & (s->cap - 1);
    if (!s->count[h]) {
        s->value[h] = v;
        s->n++;
    }
    s->count[h] += n;
    return 1;
}

static int cmp_value(const void *a, const void *b)
{
    const int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

/* The labels present, ascending, and their samples: malloc'ed arrays. */
static isomend_status labels_present(const isomend_volume *vol, int64_t **values, uint64_t **voxels,
                                     size_t *count)
{
    int64_t st[3];
    volume_strides(vol, st);
    int64_t min;
    const size_t range = small_range(vol->type, &min);
    *values = NULL;
    *voxels = NULL;
    *count = 0;
    if (range) {
        uint64_t *hist = calloc(range, sizeof(uint64_t));
        if (!hist)
            return ISOMEND_ERR_OUT_OF_MEMORY;
        const int64_t size = (int64_t)label_type_size(vol->type);
        for (int64_t k = 0; k < vol->dims[2]; k++)
            for (int64_t j = 0; j < vol->dims[1]; j++) {
                const uint8_t *row = (const uint8_t *)vol->data + j * st[1] + k * st[2];
                if (vol->type == ISOMEND_U8 && st[0] == 1) /* the common case, vectorised */
                    for (int64_t i = 0; i < vol->dims[0]; i++)
                        hist[row[i]]++;
                else if (vol->type == ISOMEND_U16 && st[0] == size)
                    for (int64_t i = 0; i < vol->dims[0]; i++) {
                        uint16_t v;
                        memcpy(&v, row + 2 * i, 2);
                        hist[v]++;
                    }
                else
                    for (int64_t i = 0; i < vol->dims[0]; i++)
                        hist[sample_at(vol, st, i, j, k) - min]++;
            }
        size_t n = 0;
        for (size_t v = 0; v < range; v++)
            n += hist[v] != 0;
        *values = malloc(sizeof(int64_t) * (n ? n : 1));
        *voxels = malloc(sizeof(uint64_t) * (n ? n : 1));
        if (!*values || !*voxels) {
            free(hist);
            return ISOMEND_ERR_OUT_OF_MEMORY;
        }
        n = 0;
        for (size_t v = 0; v < range; v++)
            if (hist[v]) {
                (*values)[n] = (int64_t)v + min;
                (*voxels)[n++] = hist[v];
            }
        *count = n;
        free(hist);
        return ISOMEND_OK;
    }
    value_set s = {NULL, NULL, 0, 0};
    isomend_status status = ISOMEND_OK;
    for (int64_t k = 0; k < vol->dims[2] && status == ISOMEND_OK; k++)
        for (int64_t j = 0; j < vol->dims[1] && status == ISOMEND_OK; j++) {
            int64_t run = sample_at(vol, st, 0, j, k);
            uint64_t n = 0;
            for (int64_t i = 0; i < vol->dims[0]; i++) { /* runs: one insertion each */
                const int64_t v = sample_at(vol, st, i, j, k);
                if (v != run) {
                    if (!set_add(&s, run, n))
                        status = ISOMEND_ERR_OUT_OF_MEMORY;
                    run = v;
                    n = 0;
                }
                n++;
            }
            if (status == ISOMEND_OK && !set_add(&s, run, n))
                status = ISOMEND_ERR_OUT_OF_MEMORY;
        }
    if (status == ISOMEND_OK) {
        *values = malloc(sizeof(int64_t) * (s.n ? s.n : 1));
        *voxels = malloc(sizeof(uint64_t) * (s.n ? s.n : 1));
        if (!*values || !*voxels)
            status = ISOMEND_ERR_OUT_OF_MEMORY;
    }
    if (status == ISOMEND_OK) {
        size_t n = 0;
        for (size_t q = 0; q < s.cap; q++)
            if (s.count[q])
                (*values)[n++] = s.value[q];
        qsort(*values, n, sizeof(int64_t), cmp_value);
        for (size_t q = 0; q < s.cap; q++)
            if (s.count[q]) {
                const int64_t *at = bsearch(&s.value[q], *values, n, sizeof(int64_t), cmp_value);
                (*voxels)[at - *values] = s.count[q];
            }
        *count = n;
    }
    free(s.value);
    free(s.count);
    return status;
}

isomend_status isomend_labels_present(const isomend_volume *vol, int64_t *values, uint64_t *voxels,
                                      size_t capacity, size_t *count)
{
    if (!count)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *count = 0;
    isomend_status status = check_volume(vol, 1);
    if (status != ISOMEND_OK)
        return status;
    int64_t *v;
    uint64_t *n;
    size_t have;
    status = labels_present(vol, &v, &n, &have);
    if (status == ISOMEND_OK) {
        for (size_t q = 0; q < have && q < capacity; q++) {
            if (values)
                values[q] = v[q];
            if (voxels)
                voxels[q] = n[q];
        }
        *count = have;
    }
    free(v);
    free(n);
    return status;
}

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

static void free_slab(label_slab *s, size_t count)
{
    free_parts(s->part, count);
    free(s->voxels);
    for (int r = 0; r < LABEL_RING; r++)
        free(s->codes[r]);
    free(s->ids[0]);
    free(s->ids[1]);
}

static int alloc_slab(label_slab *s, label_job *job)
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
    const size_t range = small_range(job->type, &min);
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
    qsort(pairs, job->count, 2 * sizeof(int64_t), cmp_value); /* by value (first) */
    for (uint32_t l = 0; l < job->count; l++) {
        (*sorted)[l] = pairs[2 * l];
        (*sorted_code)[l] = (uint32_t)pairs[2 * l + 1];
    }
    free(pairs);
    job->sorted = *sorted;
    job->sorted_code = *sorted_code;
    return 1;
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
        if (!alloc_slab(&slab[s], job))
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
    if (status == ISOMEND_OK) {
        for (int s = 0; s < nslabs; s++) { /* the scratch arrays, before the join */
            for (int q = 0; q < LABEL_RING; q++) {
                free(slab[s].codes[q]);
                slab[s].codes[q] = NULL;
            }
            for (uint32_t l = 0; l < job->count; l++)
                r->voxels[l] += slab[s].voxels[l];
        }
        isomend_status *st = calloc(job->count ? job->count : 1, sizeof(isomend_status));
        if (!st) {
            status = ISOMEND_ERR_OUT_OF_MEMORY;
        } else {
            join_job jj = {job, slab, nslabs, r->mesh, st};
            parallel_for_from(job->count, 2, join_range, &jj);
            for (uint32_t l = 0; l < job->count && status == ISOMEND_OK; l++)
                status = st[l];
            free(st);
        }
    }
    for (int s = 0; slab && s < nslabs; s++)
        free_slab(&slab[s], job->count);
    free(slab);
    free(tid);
    free(started);
    return status;
}

isomend_status isomend_labels_extract(const isomend_volume *vol, const int64_t *labels,
                                      size_t count, const isomend_options *opts,
                                      isomend_labels **out)
{
    if (!out)
        return ISOMEND_ERR_INVALID_ARGUMENT;
    *out = NULL;
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
    isomend_status status = check_volume(vol, pad);
    if (status != ISOMEND_OK)
        return status;
    if (count >= (size_t)LABEL_FOREIGN - 2)
        return ISOMEND_ERR_TOO_LARGE;

    isomend_labels *r = calloc(1, sizeof *r);
    if (!r)
        return ISOMEND_ERR_OUT_OF_MEMORY;
    if (!labels) { /* every label present but 0 */
        uint64_t *n = NULL;
        status = labels_present(vol, &r->value, &n, &r->count);
        free(n);
        if (status != ISOMEND_OK) {
            isomend_labels_destroy(r);
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
        if (!r->value) {
            isomend_labels_destroy(r);
            return ISOMEND_ERR_OUT_OF_MEMORY;
        }
        memcpy(r->value, labels, sizeof(int64_t) * count);
        int64_t *check = malloc(sizeof(int64_t) * (count ? count : 1));
        if (!check) {
            isomend_labels_destroy(r);
            return ISOMEND_ERR_OUT_OF_MEMORY;
        }
        memcpy(check, labels, sizeof(int64_t) * count);
        qsort(check, count, sizeof(int64_t), cmp_value);
        for (size_t l = 1; l < count; l++)
            if (check[l] == check[l - 1])
                status = ISOMEND_ERR_INVALID_ARGUMENT; /* a label twice */
        free(check);
        if (status != ISOMEND_OK) {
            isomend_labels_destroy(r);
            return status;
        }
    }
    r->voxels = calloc(r->count ? r->count : 1, sizeof(uint64_t));
    r->mesh = calloc(r->count ? r->count : 1, sizeof(isomend_mesh *));
    if (!r->voxels || !r->mesh) {
        isomend_labels_destroy(r);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }

    label_job *job = calloc(1, sizeof *job);
    if (!job) {
        isomend_labels_destroy(r);
        return ISOMEND_ERR_OUT_OF_MEMORY;
    }
    job->data = vol->data;
    job->type = vol->type;
    volume_strides(vol, job->st);
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

    uint32_t *table = NULL, *sorted_code = NULL;
    int64_t *sorted = NULL;
    status = build_codes(job, r->value, &table, &sorted, &sorted_code) ? ISOMEND_OK
                                                                       : ISOMEND_ERR_OUT_OF_MEMORY;
    if (status == ISOMEND_OK) {
        long cores = sysconf(_SC_NPROCESSORS_ONLN);
        int nthreads = o->threads > 0 ? o->threads : cores < 1 ? 1 : (int)cores;
        status = run_slabs(job, nthreads > 64 ? 64 : nthreads, r);
    }
    free(table);
    free(sorted);
    free(sorted_code);
    free(job);
    if (status != ISOMEND_OK) {
        isomend_labels_destroy(r);
        return status;
    }
    if (o->progress)
        (void)o->progress(o->progress_user, 1.0);
    *out = r;
    return ISOMEND_OK;
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
