/*
 * slab.c - one rank's part of the mesh (see slab.h)
 *
 * PLACEHOLDER until the core's piece API exists (issue 24, docs/streaming.md):
 * the core cannot yet extract a box of a larger grid, so a rank extracts
 * its slab plus a halo as a volume of its own with isomend_extract() and
 * recovers, from the samples, what the piece API will hand over directly:
 *
 *   - which grid edge each vertex lies on: the rank enumerates the
 *     intersected edges of its slices in the core's documented order
 *     (slice, row, [tetra diagonals], x, y, z edges, column) from the signs
 *     sample >= iso (NaN and padding outside), so vertex v of the slab's
 *     mesh is the v-th edge found, and its key follows;
 *   - the z coordinate the whole volume would give: the slab's origin is
 *     shifted by a whole number of slices, and origin + (k + t) * spacing
 *     rounds differently from the shifted sum, so z is computed again with
 *     the core's own formula (x and y are unchanged);
 *   - which layer each triangle belongs to: the lowest slice of its
 *     vertices, except a quadrilateral on a plane (all corners x/y edges of
 *     one slice k), which belongs to layer k - 1 that judged that face;
 *   - the statistics of the owned cubes (the case of each cube, its
 *     ambiguous +x/+y/+z faces and whether the combination is inverted).
 *
 * The halo (marched slices first - 1 .. end + 1, the slab's start rounded
 * down to an even slice so the tetrahedral method's parity is the whole
 * volume's) holds every sample the owned vertices' gradients, the last
 * layer's vertices and DMC's decision on its top face read; the slab's own
 * borders (and its padding, with --pad) fall outside the owned slices.
 * Methods that make cube-private vertices (facial, gradient, asymptotic,
 * mc33) are numbered after all slices by today's core and cannot be split:
 * they run on one rank only (slab_method_splits).  A mismatch between the
 * enumeration and the core is reported as an internal error, never written.
 */
#define _POSIX_C_SOURCE 200809L

#include "slab.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void slab_split(int64_t nz_marched, int ranks, int rank, int64_t *first, int64_t *end)
{
    *first = nz_marched * rank / ranks;
    *end = nz_marched * (rank + 1) / ranks;
}

int slab_method_splits(isomend_method method)
{
    return method == ISOMEND_METHOD_MC || method == ISOMEND_METHOD_DURST ||
           method == ISOMEND_METHOD_DMC || method == ISOMEND_METHOD_TETRA;
}

void slab_piece_free(slab_piece *p)
{
    free(p->pos);
    free(p->nrm);
    free(p->keys);
    free(p->tri);
    free(p->org);
    free(p->foreign_keys);
    free(p->foreign_pos);
    free(p->shared);
    memset(p, 0, sizeof *p);
}

/* The slab as the enumeration sees it: marched coordinates of the slab volume. */
typedef struct slab_ctx {
    const char *data;          /* the slab's samples, contiguous          */
    isomend_type type;
    size_t ts;
    int64_t nx, ny, nb;        /* the slab volume's dimensions            */
    int64_t pad, N0, N1, Ns;   /* marched: N0 x N1 x Ns                   */
    int64_t a;                 /* global marched slice of slab slice 0    */
    double iso;
    uint8_t *sign;             /* Ns planes of N0 x N1 (1 = inside)       */
} slab_ctx;

typedef struct vinfo {
    int32_t s;                 /* slab marched slice */
    int32_t i, j;
    uint8_t kind;              /* 0..2 edges, 3..5 face diagonals */
} vinfo;

/* Sample (i, j, s) of the slab's marched grid; NaN for padding. */
static double sample(const slab_ctx *c, int64_t i, int64_t j, int64_t s)
{
    i -= c->pad;
    j -= c->pad;
    s -= c->pad;
    if (i < 0 || j < 0 || s < 0 || i >= c->nx || j >= c->ny || s >= c->nb) return NAN;
    return cli_sample_value(c->data + ((size_t)((s * c->ny + j) * c->nx + i)) * c->ts, c->type);
}

static int is_plane_kind(int kind) { return kind == 0 || kind == 1 || kind == 5; }

/* Numbers the intersected edges as the core does; returns the count, or
 * -1 when there are more than `cap` (the core found fewer: a mismatch). */
static int64_t enumerate(const slab_ctx *c, int tetra, vinfo *out, size_t cap)
{
    const int64_t N0 = c->N0, N1 = c->N1, plane = N0 * N1;
    size_t n = 0;
#define EMIT(S, I, J, K)                                                                           \
    do {                                                                                           \
        if (n == cap) return -1;                                                                   \
        out[n].s = (int32_t)(S);                                                                   \
        out[n].i = (int32_t)(I);                                                                   \
        out[n].j = (int32_t)(J);                                                                   \
        out[n].kind = (uint8_t)(K);                                                                \
        n++;                                                                                       \
    } while (0)
    for (int64_t s = 0; s < c->Ns; s++) {
        const uint8_t *S = c->sign + s * plane, *T = s + 1 < c->Ns ? S + plane : NULL;
        for (int64_t j = 0; j < N1; j++) {
            const uint8_t *a = S + j * N0, *b = j + 1 < N1 ? a + N0 : NULL;
            const uint8_t *d = T ? T + j * N0 : NULL, *e = T && b ? d + N0 : NULL;
            if (tetra)
                for (int kind = 0; kind < 3; kind++) {
                    if ((kind == 0 && !e) || (kind == 1 && !d) || (kind == 2 && !b)) continue;
                    const int64_t last = kind == 0 ? N0 - 1 : N0 - 2;
                    for (int64_t i = 0; i <= last; i++) {
                        const int even = ((i + j + s + c->a) & 1) == 0;
                        uint8_t sp, sq;
                        if (kind == 0) {
                            sp = even ? a[i] : b[i];
                            sq = even ? e[i] : d[i];
                        } else if (kind == 1) {
                            sp = even ? a[i] : a[i + 1];
                            sq = even ? d[i + 1] : d[i];
                        } else {
                            sp = even ? a[i] : a[i + 1];
                            sq = even ? b[i + 1] : b[i];
                        }
                        if (sp != sq) EMIT(s, i, j, 3 + kind);
                    }
                }
            for (int64_t i = 0; i + 1 < N0; i++)
                if (a[i] != a[i + 1]) EMIT(s, i, j, 0);
            if (b)
                for (int64_t i = 0; i < N0; i++)
                    if (a[i] != b[i]) EMIT(s, i, j, 1);
            if (d)
                for (int64_t i = 0; i < N0; i++)
                    if (a[i] != d[i]) EMIT(s, i, j, 2);
        }
    }
#undef EMIT
    return (int64_t)n;
}

static uint64_t key_of(const slab_ctx *c, const vinfo *v)
{
    const uint64_t k = (uint64_t)(v->s + c->a);
    return ((k * (uint64_t)c->N1 + (uint64_t)v->j) * (uint64_t)c->N0 + (uint64_t)v->i) * 8u + v->kind;
}

/* The z coordinate of vertex v in the whole volume (the core's formula). */
static float whole_z(const slab_ctx *c, const vinfo *v, double oz, double hz)
{
    const int64_t K = v->s + c->a, i = v->i, j = v->j, s = v->s;
    if (is_plane_kind(v->kind)) return (float)(oz + (double)K * hz);
    double f0, f1;
    const int even = ((i + j + K) & 1) == 0;
    if (v->kind == 2) {
        f0 = sample(c, i, j, s);
        f1 = sample(c, i, j, s + 1);
    } else if (v->kind == 3) { /* x face: the ends at z = K and K + 1 */
        f0 = sample(c, i, even ? j : j + 1, s);
        f1 = sample(c, i, even ? j + 1 : j, s + 1);
    } else {                   /* y face */
        f0 = sample(c, even ? i : i + 1, j, s);
        f1 = sample(c, even ? i + 1 : i, j, s + 1);
    }
    const int valid = !isnan(f0) && !isnan(f1);
    const double t = valid ? (c->iso - f0) / (f1 - f0) : 0.5;
    return (float)(oz + ((double)K + t) * hz);
}

/* Statistics of the owned cubes (layers [l0, l1), global) and NaN samples
 * of the owned volume slices, as the core counts them. */
static void owned_stats(const slab_ctx *c, int64_t l0, int64_t l1, int64_t nz_marched,
                        int64_t first, int64_t end, isomend_stats *st)
{
    const int64_t N0 = c->N0, N1 = c->N1, plane = N0 * N1;
    for (int64_t L = l0; L < l1; L++) {
        const int64_t s = L - c->a;
        const uint8_t *P = c->sign + s * plane;
        for (int64_t j = 0; j + 1 < N1; j++)
            for (int64_t i = 0; i + 1 < N0; i++) {
                unsigned cfg = 0;
                for (unsigned q = 0; q < 8; q++)
                    cfg |= (unsigned)P[((q >> 2) & 1) * plane + (j + ((q >> 1) & 1)) * N0 + i + (q & 1)] << q;
                st->cubes++;
                st->case_histogram[isomend_case_of(cfg)]++;
                for (int axis = 0; axis < 3; axis++) {
                    /* the +axis face: its corners, in pairs across the diagonals */
                    static const unsigned char diag[3][4] = {{1, 7, 3, 5}, {2, 7, 3, 6}, {4, 7, 5, 6}};
                    const unsigned char *f = diag[axis];
                    unsigned b0 = cfg >> f[0] & 1, b1 = cfg >> f[1] & 1, b2 = cfg >> f[2] & 1,
                             b3 = cfg >> f[3] & 1;
                    if (!(b0 == b1 && b2 == b3 && b0 != b2)) continue;
                    if ((axis == 0 && i + 2 >= N0) || (axis == 1 && j + 2 >= N1) ||
                        (axis == 2 && L + 2 >= nz_marched))
                        continue;
                    const int64_t ni = i + (axis == 0), nj = j + (axis == 1), ns = axis == 2;
                    unsigned nb = 0;
                    for (unsigned q = 0; q < 8; q++)
                        nb |= (unsigned)P[(((q >> 2) & 1) + ns) * plane + (nj + ((q >> 1) & 1)) * N0 +
                                          ni + (q & 1)] << q;
                    int inv0 = __builtin_popcount(cfg) >= 5, inv1 = __builtin_popcount(nb) >= 5;
                    st->ambiguous_faces++;
                    st->inverted_combinations += inv0 != inv1;
                }
            }
    }
    if (c->type == ISOMEND_F32 || c->type == ISOMEND_F64)
        for (int64_t K = first; K < end; K++) {
            const int64_t s = K - c->a; /* slab marched slice */
            if (s - c->pad < 0 || s - c->pad >= c->nb) continue; /* padding */
            for (int64_t j = 0; j < c->ny; j++)
                for (int64_t i = 0; i < c->nx; i++)
                    st->nan_samples += isnan(sample(c, i + c->pad, j + c->pad, s));
        }
}

static void *alloc(size_t count, size_t size, int *oom)
{
    void *p = count ? malloc(count * size) : NULL;
    if (count && !p) *oom = 1;
    return p;
}

static int compare_pairs(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

int slab_extract(cli_slices *src, const isomend_options *opts, int64_t first, int64_t end,
                 slab_piece *p)
{
    memset(p, 0, sizeof *p);
    p->first = first;
    p->end = end;
    if (first >= end) return CLI_EXIT_OK;
    const isomend_volume *d = &src->desc;
    const int64_t pad = (opts->flags & ISOMEND_FLAG_PAD) ? 1 : 0;
    const int64_t nz = d->dims[2], NZ = nz + 2 * pad;
    const int whole = first == 0 && end == NZ;
    /* volume slices [a, b]: the slab and its halo, a even in marched terms */
    int64_t a = whole ? 0 : first - 1 - pad, b = whole ? nz - 1 : end + 1 - pad;
    if (a < 0) a = 0;
    a -= a & 1;
    if (b > nz - 1) b = nz - 1;
    const int64_t nb = b - a + 1;
    const size_t ts = isomend_type_size(d->type);
    char *data = malloc((size_t)(src->slice_bytes * (uint64_t)nb));
    if (!data) {
        cli_error("%s: out of memory for slices %lld..%lld", src->label, (long long)a, (long long)b);
        return CLI_EXIT_FAIL;
    }
    int rc = cli_slices_seek(src, a);
    for (int64_t k = 0; k < nb && !rc; k++) {
        if (cli_interrupted) {
            cli_error("%s: interrupted", src->label);
            rc = CLI_EXIT_INTERRUPTED;
        } else {
            rc = cli_slices_next(src, data + src->slice_bytes * (uint64_t)k);
        }
    }
    if (rc) {
        free(data);
        return rc;
    }
    isomend_volume vol = *d;
    vol.data = data;
    vol.dims[2] = nb;
    vol.strides[0] = vol.strides[1] = vol.strides[2] = 0;
    vol.origin[2] = d->origin[2] + (double)a * d->spacing[2];
    isomend_mesh *mesh = NULL;
    isomend_stats st;
    isomend_status est = isomend_extract(&vol, opts, &mesh, &st);
    if (est != ISOMEND_OK) {
        free(data);
        if (est == ISOMEND_ERR_CANCELLED) {
            cli_error("%s: interrupted", src->label);
            return CLI_EXIT_INTERRUPTED;
        }
        cli_error("%s: extraction of slices %lld..%lld failed: %s", src->label, (long long)a,
                  (long long)b, isomend_status_string(est));
        return CLI_EXIT_FAIL;
    }
    const size_t nv = isomend_mesh_vertex_count(mesh), nt = isomend_mesh_triangle_count(mesh);
    const float *mpos = isomend_mesh_positions(mesh), *mnrm = isomend_mesh_normals(mesh);
    const uint32_t *mtri = isomend_mesh_triangles(mesh);
    const uint8_t *morg = isomend_mesh_triangle_origins(mesh);
    int oom = 0;
    if (whole) { /* one rank: the mesh as it is */
        p->nv = nv;
        p->nt = nt;
        p->pos = alloc(3 * nv, sizeof(float), &oom);
        p->nrm = mnrm ? alloc(3 * nv, sizeof(float), &oom) : NULL;
        p->tri = alloc(3 * nt, sizeof(uint64_t), &oom);
        p->org = morg ? alloc(nt, 1, &oom) : NULL;
        if (!oom) {
            if (nv) memcpy(p->pos, mpos, 3 * nv * sizeof(float));
            if (p->nrm && nv) memcpy(p->nrm, mnrm, 3 * nv * sizeof(float));
            for (size_t q = 0; q < 3 * nt; q++) p->tri[q] = mtri[q];
            if (p->org && nt) memcpy(p->org, morg, nt);
            p->stats = st;
        }
        isomend_mesh_destroy(mesh);
        free(data);
        if (oom) {
            slab_piece_free(p);
            cli_error("%s: out of memory", src->label);
            return CLI_EXIT_FAIL;
        }
        return CLI_EXIT_OK;
    }

    slab_ctx c;
    memset(&c, 0, sizeof c);
    c.data = data;
    c.type = d->type;
    c.ts = ts;
    c.nx = d->dims[0];
    c.ny = d->dims[1];
    c.nb = nb;
    c.pad = pad;
    c.N0 = c.nx + 2 * pad;
    c.N1 = c.ny + 2 * pad;
    c.Ns = nb + 2 * pad;
    c.a = a; /* slab marched slice s is global marched slice s + a */
    c.iso = opts->iso;
    const int64_t plane = c.N0 * c.N1;
    c.sign = alloc((size_t)(plane * c.Ns), 1, &oom);
    vinfo *vi = alloc(nv + 1, sizeof *vi, &oom);
    if (oom) {
        free(c.sign);
        free(vi);
        isomend_mesh_destroy(mesh);
        free(data);
        cli_error("%s: out of memory", src->label);
        return CLI_EXIT_FAIL;
    }
    for (int64_t s = 0; s < c.Ns; s++)
        for (int64_t j = 0; j < c.N1; j++)
            for (int64_t i = 0; i < c.N0; i++)
                c.sign[s * plane + j * c.N0 + i] = sample(&c, i, j, s) >= c.iso; /* NaN: outside */
    const int tetra = opts->method == ISOMEND_METHOD_TETRA;
    int64_t found = enumerate(&c, tetra, vi, nv);
    rc = CLI_EXIT_OK;
    if (found != (int64_t)nv) {
        cli_error("%s: slices %lld..%lld: the slab has %zu vertices but %lld intersected edges "
                  "(internal error of the slab placeholder)",
                  src->label, (long long)a, (long long)b, nv, (long long)found);
        rc = CLI_EXIT_FAIL;
        goto done;
    }
    /* owned vertices: slab slices [first - a, end - a), then the next plane */
    size_t lo = 0, hi, next_end;
    while (lo < nv && vi[lo].s < first - a) lo++;
    hi = lo;
    while (hi < nv && vi[hi].s < end - a) hi++;
    next_end = hi;
    while (next_end < nv && vi[next_end].s == end - a) next_end++;
    /* owned triangles: layers [first, min(end, NZ - 1)), in order */
    const int64_t l1 = end < NZ - 1 ? end : NZ - 1;
    size_t t0 = nt, t1 = nt;
    int64_t prev = -1;
    for (size_t t = 0; t < nt; t++) {
        const vinfo *v0 = &vi[mtri[3 * t]], *v1 = &vi[mtri[3 * t + 1]], *v2 = &vi[mtri[3 * t + 2]];
        int64_t m = v0->s < v1->s ? v0->s : v1->s;
        if (v2->s < m) m = v2->s;
        if (v0->s == v1->s && v1->s == v2->s && is_plane_kind(v0->kind) &&
            is_plane_kind(v1->kind) && is_plane_kind(v2->kind))
            m--; /* a quadrilateral on plane m + 1, judged by layer m */
        const int64_t layer = m + a;
        if (layer < prev) {
            cli_error("%s: slices %lld..%lld: triangles out of layer order (internal error of the "
                      "slab placeholder)", src->label, (long long)a, (long long)b);
            rc = CLI_EXIT_FAIL;
            goto done;
        }
        prev = layer;
        if (layer >= first && t0 == nt) t0 = t;
        if (layer >= l1 && t1 == nt) {
            t1 = t;
            break;
        }
    }
    if (t0 > t1) t0 = t1;
    const double oz = d->origin[2] - (double)pad * d->spacing[2], hz = d->spacing[2];
    p->nv = hi - lo;
    p->nt = t1 - t0;
    p->pos = alloc(3 * p->nv, sizeof(float), &oom);
    p->nrm = mnrm ? alloc(3 * p->nv, sizeof(float), &oom) : NULL;
    p->keys = alloc(p->nv, sizeof(uint64_t), &oom);
    p->tri = alloc(3 * p->nt, sizeof(uint64_t), &oom);
    p->org = morg ? alloc(p->nt, 1, &oom) : NULL;
    size_t nnext = next_end - hi;
    int64_t *foreign_of = alloc(nnext, sizeof(int64_t), &oom);
    p->foreign_keys = alloc(nnext, sizeof(uint64_t), &oom);
    p->foreign_pos = alloc(3 * nnext, sizeof(float), &oom);
    p->shared = alloc(2 * p->nv, sizeof(uint64_t), &oom);
    if (oom) {
        free(foreign_of);
        cli_error("%s: out of memory", src->label);
        rc = CLI_EXIT_FAIL;
        goto done;
    }
    for (size_t v = lo; v < hi; v++) {
        float *q = p->pos + 3 * (v - lo);
        memcpy(q, mpos + 3 * v, 3 * sizeof(float));
        q[2] = whole_z(&c, &vi[v], oz, hz);
        if (p->nrm) memcpy(p->nrm + 3 * (v - lo), mnrm + 3 * v, 3 * sizeof(float));
        p->keys[v - lo] = key_of(&c, &vi[v]);
        if (vi[v].s == first - a && is_plane_kind(vi[v].kind)) {
            p->shared[2 * p->nshared] = p->keys[v - lo];
            p->shared[2 * p->nshared + 1] = v - lo;
            p->nshared++;
        }
    }
    qsort(p->shared, p->nshared, 2 * sizeof(uint64_t), compare_pairs);
    for (size_t q = 0; q < nnext; q++) foreign_of[q] = -1;
    for (size_t t = t0; t < t1; t++) {
        for (int k = 0; k < 3; k++) {
            const size_t id = mtri[3 * t + (size_t)k];
            uint64_t out;
            if (id >= lo && id < hi) {
                out = id - lo;
            } else if (id >= hi && id < next_end && is_plane_kind(vi[id].kind)) {
                if (foreign_of[id - hi] < 0) {
                    const size_t f = p->nforeign++;
                    foreign_of[id - hi] = (int64_t)f;
                    p->foreign_keys[f] = key_of(&c, &vi[id]);
                    memcpy(p->foreign_pos + 3 * f, mpos + 3 * id, 3 * sizeof(float));
                    p->foreign_pos[3 * f + 2] = whole_z(&c, &vi[id], oz, hz);
                }
                out = SLAB_FOREIGN | (uint64_t)foreign_of[id - hi];
            } else {
                cli_error("%s: slices %lld..%lld: a triangle of layer %lld uses a vertex of slice "
                          "%lld (internal error of the slab placeholder)",
                          src->label, (long long)a, (long long)b, (long long)first,
                          (long long)(vi[id].s + a));
                free(foreign_of);
                rc = CLI_EXIT_FAIL;
                goto done;
            }
            p->tri[3 * (t - t0) + (size_t)k] = out;
        }
        if (p->org) p->org[t - t0] = morg[t];
    }
    free(foreign_of);
    /* statistics of what this rank owns */
    p->stats.vertices = p->nv;
    p->stats.triangles = p->nt;
    for (size_t t = 0; t < p->nt; t++)
        if (p->org) p->stats.triangles_by_origin[p->org[t]]++;
    if (!p->org) p->stats.triangles_by_origin[ISOMEND_ORIGIN_TABLE] = p->nt;
    owned_stats(&c, first, l1, NZ, first, end, &p->stats);
done:
    free(c.sign);
    free(vi);
    isomend_mesh_destroy(mesh);
    free(data);
    if (rc) slab_piece_free(p);
    return rc;
}
