/*
 * mpi_decimate.c - a rank's piece recorded, and rank 0's replay of all of
 * them as one stream (see mpi_decimate.h)
 *
 * The spool: records of three 64-bit words (type, a, b) and a payload:
 *   V  a = first local id, b = count; count x 3 floats (positions)
 *   T  b = count; count x 3 ids (local, or ISOMEND_FOREIGN | f)
 *   R  a = the floor (local)
 *   F  a = first foreign index, b = count; count keys
 * The replay turns rank r's records into the single stream's calls: local
 * id i is base_r + i (base_r: the vertices of the ranks before); the next
 * slab's first slice of vertices (the prefix of its ids whose keys lie in
 * that slice; their positions and keys are sent apart) is delivered where
 * the single stream delivers it, after rank r's last layer's own vertices
 * and before that layer's triangles, and skipped when that rank's own
 * records are replayed; a foreign corner f is the next slab's vertex with
 * the key f had.
 */
#define _POSIX_C_SOURCE 200809L

#include "mpi_decimate.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "atomic_file.h"
#include "mesh_io.h"

enum { REC_V = 1, REC_T = 2, REC_R = 3, REC_F = 4 };
enum { TAG_FIRST = 71, TAG_SPOOL = 72 };
#define BLOCK (4u << 20)

/* ------------------------------------------------------------------ recording */

static int spool_put(dec_spool *s, uint64_t type, uint64_t a, uint64_t b, const void *payload,
                     size_t len)
{
    const uint64_t head[3] = {type, a, b};
    if (fwrite(head, sizeof head, 1, s->fp) != 1 ||
        (len && fwrite(payload, 1, len, s->fp) != len)) {
        cli_error("%s: cannot write a scratch file: %s", s->final_path, strerror(errno));
        return s->failed = 1;
    }
    return 0;
}

static int rec_vertices(void *user, uint64_t first, size_t count, const float *pos,
                        const float *nrm, const uint64_t *keys)
{
    (void)nrm;
    dec_spool *s = user;
    if (first != s->nv || !keys) {
        cli_error("vertices from id %llu, %llu expected (internal error)",
                  (unsigned long long)first, (unsigned long long)s->nv);
        return s->failed = 1;
    }
    /* the first slice's vertices: positions and keys for the rank below */
    size_t v = 0;
    for (; s->in_first && v < count; v++) {
        const uint64_t key = keys[v];
        if (key == ISOMEND_KEY_NONE || (key >> 3) / s->plane != (uint64_t)s->first) {
            s->in_first = 0;
            break;
        }
    }
    if (v) {
        if (s->nfirst + v > s->first_cap) {
            size_t cap = s->first_cap ? 2 * s->first_cap : 4096;
            while (cap < s->nfirst + v)
                cap *= 2;
            uint64_t *k = realloc(s->first_keys, cap * sizeof *k);
            if (k)
                s->first_keys = k;
            float *p = realloc(s->first_pos, cap * 12);
            if (p)
                s->first_pos = p;
            if (!k || !p) {
                cli_error("%s: out of memory", s->final_path);
                return s->failed = 1;
            }
            s->first_cap = cap;
        }
        memcpy(s->first_keys + s->nfirst, keys, v * sizeof *keys);
        memcpy(s->first_pos + 3 * s->nfirst, pos, v * 12);
        s->nfirst += v;
    }
    s->nv += count;
    return spool_put(s, REC_V, first, count, pos, count * 12);
}

static int rec_triangles(void *user, size_t count, const uint64_t *ids, const uint8_t *org)
{
    (void)org;
    dec_spool *s = user;
    s->nt += count;
    return spool_put(s, REC_T, 0, count, ids, count * 24);
}

static int rec_retire(void *user, uint64_t floor)
{
    dec_spool *s = user;
    s->layers++;
    return spool_put(s, REC_R, floor, 0, NULL, 0);
}

static int rec_foreign(void *user, size_t first, size_t count, const uint64_t *keys,
                       const float *pos)
{
    (void)pos;
    dec_spool *s = user;
    return spool_put(s, REC_F, first, count, keys, count * 8);
}

int dec_spool_open(dec_spool *s, const char *final_path, uint64_t plane, int64_t first)
{
    memset(s, 0, sizeof *s);
    s->final_path = final_path;
    s->plane = plane;
    s->first = first;
    s->in_first = 1;
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    if (isomend_spool_open(final_path, &s->fp, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        return CLI_EXIT_FAIL;
    }
    return CLI_EXIT_OK;
}

void dec_spool_close(dec_spool *s)
{
    if (s->fp)
        fclose(s->fp);
    free(s->first_keys);
    free(s->first_pos);
    memset(s, 0, sizeof *s);
}

void dec_spool_sink(dec_spool *s, isomend_mesh_sink *sink)
{
    *sink = (isomend_mesh_sink){s, rec_vertices, rec_triangles, rec_retire, rec_foreign};
}

/* ------------------------------------------------------------------ reading a spool */

/* Rank 0 reads rank r's records: its own spool, or the blocks rank r sends. */
typedef struct reader {
    MPI_Comm comm;
    int from; /* -1: the local file */
    FILE *fp;
    unsigned char *buf;
    size_t len, pos, cap;
    int eof;
} reader;

static int reader_fill(reader *r)
{
    if (r->pos) { /* what is left to the front */
        memmove(r->buf, r->buf + r->pos, r->len - r->pos);
        r->len -= r->pos;
        r->pos = 0;
    }
    if (r->len + BLOCK > r->cap) {
        size_t cap = r->cap ? 2 * r->cap : 2 * BLOCK;
        while (cap < r->len + BLOCK)
            cap *= 2;
        unsigned char *b = realloc(r->buf, cap);
        if (!b)
            return 0;
        r->buf = b;
        r->cap = cap;
    }
    if (r->from < 0) {
        const size_t n = fread(r->buf + r->len, 1, BLOCK, r->fp);
        r->len += n;
        r->eof = n < BLOCK;
        return !ferror(r->fp);
    }
    MPI_Status st;
    int n = 0;
    MPI_Probe(r->from, TAG_SPOOL, r->comm, &st);
    MPI_Get_count(&st, MPI_BYTE, &n);
    MPI_Recv(r->buf + r->len, n, MPI_BYTE, r->from, TAG_SPOOL, r->comm, MPI_STATUS_IGNORE);
    r->len += (size_t)n;
    r->eof = n == 0;
    return 1;
}

/* n bytes at r->buf + r->pos, or 0 (the spool ended or a read failed). */
static int reader_need(reader *r, size_t n)
{
    while (r->len - r->pos < n) {
        if (r->eof || !reader_fill(r))
            return 0;
    }
    return 1;
}

/* Drains what rank r still sends (after a failure on rank 0). */
static void reader_drain(reader *r)
{
    while (r->from >= 0 && !r->eof) {
        r->pos = r->len;
        if (!reader_fill(r))
            break;
    }
}

/* ------------------------------------------------------------------ sending */

static int send_spool(MPI_Comm comm, dec_spool *s)
{
    /* the first slice, then the spool in blocks, then an empty block */
    const uint64_t n = s->nfirst;
    MPI_Send(s->first_keys, (int)(8 * n), MPI_BYTE, 0, TAG_FIRST, comm);
    MPI_Send(s->first_pos, (int)(12 * n), MPI_BYTE, 0, TAG_FIRST, comm);
    int rc = CLI_EXIT_OK;
    unsigned char *buf = malloc(BLOCK);
    if (!buf || fflush(s->fp) != 0 || fseeko(s->fp, 0, SEEK_SET) != 0) {
        cli_error("%s: cannot read back a scratch file: %s", s->final_path, strerror(errno));
        rc = CLI_EXIT_FAIL;
    }
    for (size_t got; !rc && (got = fread(buf, 1, BLOCK, s->fp)) > 0;)
        MPI_Send(buf, (int)got, MPI_BYTE, 0, TAG_SPOOL, comm);
    if (!rc && ferror(s->fp)) {
        cli_error("%s: cannot read back a scratch file: %s", s->final_path, strerror(errno));
        rc = CLI_EXIT_FAIL;
    }
    MPI_Send(NULL, 0, MPI_BYTE, 0, TAG_SPOOL, comm);
    free(buf);
    return rc;
}

/* ------------------------------------------------------------------ the replay */

static int compare_pairs(const void *a, const void *b)
{
    const uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* The next slab's first slice: its positions, and (key, index) sorted. */
typedef struct plane {
    uint64_t n;
    uint64_t *pairs;
    float *pos;
} plane;

static int plane_receive(MPI_Comm comm, int from, uint64_t n, plane *p)
{
    p->n = n;
    uint64_t *keys = malloc(8 * n + 8);
    p->pairs = malloc(16 * n + 16);
    p->pos = malloc(12 * n + 12);
    if (keys && p->pairs && p->pos) {
        MPI_Recv(keys, (int)(8 * n), MPI_BYTE, from, TAG_FIRST, comm, MPI_STATUS_IGNORE);
        MPI_Recv(p->pos, (int)(12 * n), MPI_BYTE, from, TAG_FIRST, comm, MPI_STATUS_IGNORE);
        for (uint64_t i = 0; i < n; i++) {
            p->pairs[2 * i] = keys[i];
            p->pairs[2 * i + 1] = i;
        }
        qsort(p->pairs, n, 16, compare_pairs);
    }
    free(keys);
    return p->pairs && p->pos;
}

static void plane_free(plane *p)
{
    free(p->pairs);
    free(p->pos);
    memset(p, 0, sizeof *p);
}

static int64_t plane_find(const plane *p, uint64_t key)
{
    uint64_t lo = 0, hi = p->n;
    while (lo < hi) {
        const uint64_t mid = lo + (hi - lo) / 2;
        if (p->pairs[2 * mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < p->n && p->pairs[2 * lo] == key ? (int64_t)p->pairs[2 * lo + 1] : -1;
}

/* Rank r's records into `out`: an exit code (rank 0 prints the message). */
static int replay_rank(reader *rd, const isomend_mesh_sink *out, uint64_t base, uint64_t skip,
                       int64_t layers, const plane *next, uint64_t next_base, const char *label)
{
    uint64_t *fkeys = NULL, *ids = NULL;
    size_t nf = 0, fcap = 0, icap = 0;
    int64_t retires = 0;
    int inserted = next == NULL, rc = CLI_EXIT_OK;
    for (;;) {
        if (!reader_need(rd, 24)) {
            if (rd->len != rd->pos || retires != layers) {
                cli_error("%s: a rank's records end early (internal error)", label);
                rc = CLI_EXIT_FAIL;
            }
            break;
        }
        uint64_t head[3];
        memcpy(head, rd->buf + rd->pos, 24);
        rd->pos += 24;
        const uint64_t type = head[0], a = head[1], n = head[2];
        const size_t len = type == REC_V ? 12 * n : type == REC_T ? 24 * n : type == REC_F ? 8 * n : 0;
        if (!reader_need(rd, len)) {
            cli_error("%s: a rank's records end early (internal error)", label);
            rc = CLI_EXIT_FAIL;
            break;
        }
        const unsigned char *payload = rd->buf + rd->pos;
        rd->pos += len;
        if ((type == REC_T || type == REC_R) && !inserted && retires == layers - 1) {
            /* the single stream's next slice: the next slab's first plane */
            if (next->n && out->vertices(out->user, next_base, next->n, next->pos, NULL, NULL)) {
                rc = CLI_EXIT_FAIL;
                break;
            }
            inserted = 1;
        }
        if (type == REC_V) {
            const uint64_t lo = a > skip ? a : skip;
            if (lo < a + n &&
                out->vertices(out->user, base + lo, a + n - lo,
                              (const float *)(const void *)payload + 3 * (lo - a), NULL, NULL)) {
                rc = CLI_EXIT_FAIL;
                break;
            }
        } else if (type == REC_T) {
            if (3 * n > icap) {
                icap = 3 * n;
                uint64_t *q = realloc(ids, icap * sizeof *q);
                if (!q) {
                    cli_error("%s: out of memory", label);
                    rc = CLI_EXIT_FAIL;
                    break;
                }
                ids = q;
            }
            memcpy(ids, payload, 24 * n);
            for (uint64_t i = 0; i < 3 * n && !rc; i++) {
                if (!(ids[i] & ISOMEND_FOREIGN)) {
                    ids[i] += base;
                    continue;
                }
                const uint64_t f = ids[i] & ~ISOMEND_FOREIGN;
                const int64_t j = next && f < nf ? plane_find(next, fkeys[f]) : -1;
                if (j < 0) {
                    cli_error("%s: a foreign vertex without its key in the next slab (internal "
                              "error)", label);
                    rc = CLI_EXIT_FAIL;
                }
                ids[i] = next_base + (uint64_t)j;
            }
            if (rc || out->triangles(out->user, (size_t)n, ids, NULL)) {
                rc = CLI_EXIT_FAIL;
                break;
            }
        } else if (type == REC_R) {
            retires++;
            if (out->retire(out->user, base + a)) {
                rc = CLI_EXIT_FAIL;
                break;
            }
        } else if (type == REC_F) {
            if (a != nf || nf + n > SIZE_MAX / 8) {
                cli_error("%s: foreign vertices out of order (internal error)", label);
                rc = CLI_EXIT_FAIL;
                break;
            }
            if (nf + n > fcap) {
                fcap = 2 * (nf + n);
                uint64_t *q = realloc(fkeys, fcap * sizeof *q);
                if (!q) {
                    cli_error("%s: out of memory", label);
                    rc = CLI_EXIT_FAIL;
                    break;
                }
                fkeys = q;
            }
            memcpy(fkeys + nf, payload, 8 * n);
            nf += n;
        } else {
            cli_error("%s: a damaged record in a rank's scratch file", label);
            rc = CLI_EXIT_FAIL;
            break;
        }
    }
    free(fkeys);
    free(ids);
    return rc;
}

int dec_replay(MPI_Comm comm, dec_spool *s, const isomend_mesh_sink *out)
{
    int rank = 0, ranks = 1;
    MPI_Comm_rank(comm, &rank);
    MPI_Comm_size(comm, &ranks);
    /* every rank's vertices, first slice, layers and whether its slab has
     * slices (the last slab may own one slice and no layer) */
    const uint64_t mine[4] = {s->nv, s->nfirst, (uint64_t)s->layers, s->nonempty ? 1u : 0u};
    uint64_t *all = malloc(4 * sizeof(uint64_t) * (size_t)ranks);
    if (!all) {
        cli_error("out of memory");
        MPI_Abort(comm, 1); /* the others would wait for ever */
        return CLI_EXIT_FAIL;
    }
    MPI_Allgather(mine, 4, MPI_UINT64_T, all, 4, MPI_UINT64_T, comm);
#define NV(r) all[4 * (size_t)(r)]
#define NFIRST(r) all[4 * (size_t)(r) + 1]
#define LAYERS(r) all[4 * (size_t)(r) + 2]
#define NONEMPTY(r) all[4 * (size_t)(r) + 3]
    int rc = CLI_EXIT_OK;
    if (rank != 0) {
        if (NONEMPTY(rank))
            rc = send_spool(comm, s);
        free(all);
        return rc;
    }
    if (fflush(s->fp) != 0 || fseeko(s->fp, 0, SEEK_SET) != 0) {
        cli_error("%s: cannot read back a scratch file: %s", s->final_path, strerror(errno));
        rc = CLI_EXIT_FAIL;
    }
    uint64_t base = 0;
    int started = 0;
    plane next;
    memset(&next, 0, sizeof next);
    for (int r = 0; r < ranks; r++) {
        if (!NONEMPTY(r))
            continue; /* no records, nothing sent */
        if (!started && r != 0) { /* the first slab's own first plane: not needed */
            plane none;
            memset(&none, 0, sizeof none);
            if (!plane_receive(comm, r, NFIRST(r), &none) && !rc) {
                cli_error("%s: out of memory", s->final_path);
                rc = CLI_EXIT_FAIL;
            }
            plane_free(&none);
        }
        int nr = r + 1;
        while (nr < ranks && !NONEMPTY(nr))
            nr++;
        plane_free(&next); /* this slab's own first plane, the previous one's next */
        if (nr < ranks && !plane_receive(comm, nr, NFIRST(nr), &next) && !rc) {
            cli_error("%s: out of memory", s->final_path);
            rc = CLI_EXIT_FAIL;
        }
        reader rd;
        memset(&rd, 0, sizeof rd);
        rd.comm = comm;
        rd.from = r == 0 ? -1 : r;
        rd.fp = s->fp;
        const uint64_t skip = started ? NFIRST(r) : 0;
        if (!rc)
            rc = replay_rank(&rd, out, base, skip, (int64_t)LAYERS(r), nr < ranks ? &next : NULL,
                             base + NV(r), s->final_path);
        reader_drain(&rd);
        free(rd.buf);
        started = 1;
        base += NV(r);
    }
#undef NV
#undef NFIRST
#undef LAYERS
#undef NONEMPTY
    plane_free(&next);
    free(all);
    return rc;
}
