/*
 * mpi_writer.c - one mesh file written by every rank at once (see mpi_writer.h)
 */
#define _POSIX_C_SOURCE 200809L

#include "mpi_writer.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "atomic_file.h"
#include "cli.h"

#define ROUND_BYTES (4u << 20)
#define SECTION_BUFFER (256u << 10)
#define FACE_BATCH 65536u

/* ------------------------------------------------------------------ scratch sections */

static int section_open(mpi_writer *w, mpi_section *s)
{
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    s->used = 0;
    s->size = 0;
    s->buf = malloc(SECTION_BUFFER);
    if (!s->buf) {
        cli_error("%s: out of memory", w->final_path);
        return CLI_EXIT_FAIL;
    }
    if (isomend_spool_open(w->final_path, &s->fp, msg, sizeof msg) != ISOMEND_FILEIO_OK) {
        cli_error("%s", msg);
        return CLI_EXIT_FAIL;
    }
    return CLI_EXIT_OK;
}

static void section_close(mpi_section *s)
{
    if (s->fp) fclose(s->fp);
    free(s->buf);
    s->fp = NULL;
    s->buf = NULL;
}

static int section_flush(const mpi_writer *w, mpi_section *s)
{
    if (s->used && fwrite(s->buf, 1, s->used, s->fp) != s->used) {
        cli_error("%s: cannot write a scratch file: %s", w->final_path, strerror(errno));
        return CLI_EXIT_FAIL;
    }
    s->used = 0;
    return CLI_EXIT_OK;
}

static int put(const mpi_writer *w, mpi_section *s, const void *rec, size_t len)
{
    if (s->used + len > SECTION_BUFFER && section_flush(w, s)) return CLI_EXIT_FAIL;
    memcpy(s->buf + s->used, rec, len);
    s->used += len;
    s->size += len;
    return CLI_EXIT_OK;
}

/* Flushed and rewound, for reading back. */
static int section_rewind(const mpi_writer *w, mpi_section *s)
{
    if (section_flush(w, s) || fflush(s->fp) != 0 || fseeko(s->fp, 0, SEEK_SET) != 0) {
        cli_error("%s: cannot write a scratch file: %s", w->final_path, strerror(errno));
        return CLI_EXIT_FAIL;
    }
    return CLI_EXIT_OK;
}

void mpi_writer_close(mpi_writer *w)
{
    for (int s = 0; s < 3; s++) section_close(&w->section[s]);
    section_close(&w->spool);
    free(w->window);
    free(w->foreign);
    w->window = w->foreign = NULL;
    w->window_cap = w->foreign_cap = 0;
}

int mpi_writer_open(mpi_writer *w)
{
    int rc = CLI_EXIT_OK;
    for (int s = 0; s < 3 && !rc; s++) rc = section_open(w, &w->section[s]);
    if (!rc && w->format != ISOMEND_MESH_STL) rc = section_open(w, &w->spool);
    if (rc) mpi_writer_close(w);
    return rc;
}

/* ------------------------------------------------------------------ while streaming */

/* Room for `n` positions (3 floats) in *array of capacity *cap. */
static int room(float **array, size_t *cap, size_t n)
{
    if (n <= *cap) return 1;
    size_t c = *cap ? 2 * *cap : 4096;
    while (c < n) c *= 2;
    float *q = realloc(*array, 3 * sizeof(float) * c);
    if (!q) return 0;
    *array = q;
    *cap = c;
    return 1;
}

int mpi_writer_vertices(mpi_writer *w, size_t count, const float *pos, const float *nrm)
{
    unsigned char rec[ISOMEND_MESH_RECORD_MAX];
    for (size_t v = 0; v < count; v++) {
        const float *n = nrm ? nrm + 3 * v : NULL;
        if (put(w, &w->section[0], rec, isomend_mesh_encode_vertex(w->format, pos + 3 * v, n, rec)) ||
            put(w, &w->section[1], rec, isomend_mesh_encode_normal(w->format, n, rec)))
            return CLI_EXIT_FAIL;
    }
    if (w->format == ISOMEND_MESH_STL) {
        const size_t kept = (size_t)(w->nv - w->window_first);
        if (!room(&w->window, &w->window_cap, kept + count)) {
            cli_error("%s: out of memory", w->final_path);
            return CLI_EXIT_FAIL;
        }
        memcpy(w->window + 3 * kept, pos, 3 * sizeof(float) * count);
    }
    w->nv += count;
    return CLI_EXIT_OK;
}

int mpi_writer_foreign(mpi_writer *w, size_t first, size_t count, const float *pos)
{
    if (w->format != ISOMEND_MESH_STL) return CLI_EXIT_OK;
    if (first != w->nforeign || !room(&w->foreign, &w->foreign_cap, first + count)) {
        cli_error("%s: out of memory", w->final_path);
        return CLI_EXIT_FAIL;
    }
    memcpy(w->foreign + 3 * first, pos, 3 * sizeof(float) * count);
    w->nforeign += count;
    return CLI_EXIT_OK;
}

int mpi_writer_triangles(mpi_writer *w, size_t count, const uint64_t *ids)
{
    w->nt += count;
    if (w->format != ISOMEND_MESH_STL) /* the global ids are not known yet */
        return put(w, &w->spool, ids, 3 * sizeof *ids * count);
    unsigned char rec[ISOMEND_MESH_RECORD_MAX];
    for (size_t t = 0; t < count; t++) {
        const float *corner[3];
        for (int c = 0; c < 3; c++) {
            const uint64_t id = ids[3 * t + (size_t)c];
            if (id & MPI_WRITER_FOREIGN) {
                const uint64_t f = id & ~MPI_WRITER_FOREIGN;
                if (f >= w->nforeign) goto bad;
                corner[c] = w->foreign + 3 * f;
            } else {
                if (id < w->window_first || id >= w->nv) goto bad;
                corner[c] = w->window + 3 * (id - w->window_first);
            }
        }
        if (put(w, &w->section[2], rec,
                isomend_mesh_encode_face(w->format, w->normals, ids + 3 * t, corner, rec)))
            return CLI_EXIT_FAIL;
    }
    return CLI_EXIT_OK;
bad:
    cli_error("%s: a triangle refers to a vertex this rank no longer holds (internal error)",
              w->final_path);
    return CLI_EXIT_FAIL;
}

int mpi_writer_retire(mpi_writer *w, uint64_t floor)
{
    if (w->format != ISOMEND_MESH_STL || floor <= w->window_first) return CLI_EXIT_OK;
    if (floor > w->nv) floor = w->nv;
    const size_t drop = (size_t)(floor - w->window_first), kept = (size_t)(w->nv - floor);
    memmove(w->window, w->window + 3 * drop, 3 * sizeof(float) * kept);
    w->window_first = floor;
    return CLI_EXIT_OK;
}

/* ------------------------------------------------------------------ after the exchange */

int mpi_writer_faces(mpi_writer *w, uint64_t first_id, const uint64_t *foreign_ids)
{
    if (w->format != ISOMEND_MESH_STL) {
        if (section_rewind(w, &w->spool)) return CLI_EXIT_FAIL;
        uint64_t *batch = malloc(3 * sizeof *batch * FACE_BATCH);
        if (!batch) {
            cli_error("%s: out of memory", w->final_path);
            return CLI_EXIT_FAIL;
        }
        unsigned char rec[ISOMEND_MESH_RECORD_MAX];
        int rc = CLI_EXIT_OK;
        for (uint64_t done = 0; done < w->nt && !rc;) {
            const size_t n = w->nt - done < FACE_BATCH ? (size_t)(w->nt - done) : FACE_BATCH;
            if (fread(batch, 3 * sizeof *batch, n, w->spool.fp) != n) {
                cli_error("%s: cannot read back a scratch file: %s", w->final_path,
                          strerror(errno));
                rc = CLI_EXIT_FAIL;
                break;
            }
            for (size_t q = 0; q < 3 * n; q++)
                batch[q] = (batch[q] & MPI_WRITER_FOREIGN)
                               ? foreign_ids[batch[q] & ~MPI_WRITER_FOREIGN]
                               : first_id + batch[q];
            for (size_t t = 0; t < n && !rc; t++)
                rc = put(w, &w->section[2], rec,
                         isomend_mesh_encode_face(w->format, w->normals, batch + 3 * t, NULL, rec));
            done += n;
        }
        free(batch);
        section_close(&w->spool);
        if (rc) return rc;
    }
    for (int s = 0; s < 3; s++)
        if (section_rewind(w, &w->section[s])) return CLI_EXIT_FAIL;
    free(w->window);
    free(w->foreign);
    w->window = w->foreign = NULL;
    w->window_cap = w->foreign_cap = 0;
    return CLI_EXIT_OK;
}

int mpi_writer_write(mpi_writer *w, MPI_Comm comm, MPI_File fh, const unsigned char *header,
                     size_t header_size, int failed)
{
    int rank;
    MPI_Comm_rank(comm, &rank);
    uint64_t size[3], before[3] = {0, 0, 0}, total[3];
    for (int s = 0; s < 3; s++) size[s] = failed ? 0 : w->section[s].size;
    MPI_Exscan(size, before, 3, MPI_UINT64_T, MPI_SUM, comm);
    if (rank == 0) before[0] = before[1] = before[2] = 0; /* Exscan leaves rank 0's undefined */
    MPI_Allreduce(size, total, 3, MPI_UINT64_T, MPI_SUM, comm);
    w->size_total = total[0] + total[1] + total[2];
    const uint64_t base[3] = {header_size, header_size + total[0], header_size + total[0] + total[1]};
    /* rounds: every rank takes part in as many as the busiest rank needs */
    uint64_t mine = rank == 0 ? 1 : 0, rounds;
    for (int s = 0; s < 3; s++) mine += (size[s] + ROUND_BYTES - 1) / ROUND_BYTES;
    MPI_Allreduce(&mine, &rounds, 1, MPI_UINT64_T, MPI_MAX, comm);
    unsigned char *buf = malloc(ROUND_BYTES);
    int rc = buf ? CLI_EXIT_OK : CLI_EXIT_FAIL;
    if (!buf) cli_error("%s: out of memory", w->final_path);
    int sec = 0, header_done = rank != 0;
    uint64_t done[3] = {0, 0, 0};
    for (uint64_t r = 0; r < rounds; r++) {
        const void *data = buf;
        int count = 0;
        MPI_Offset at = 0;
        if (rc == CLI_EXIT_OK && !header_done) {
            data = header;
            count = (int)header_size;
            header_done = 1;
        } else if (rc == CLI_EXIT_OK) {
            while (sec < 3 && done[sec] == size[sec]) sec++;
            if (sec < 3) {
                uint64_t left = size[sec] - done[sec];
                size_t n = left < ROUND_BYTES ? (size_t)left : ROUND_BYTES;
                if (fread(buf, 1, n, w->section[sec].fp) != n) {
                    cli_error("%s: cannot read back a scratch file: %s", w->final_path,
                              strerror(errno));
                    rc = CLI_EXIT_FAIL;
                } else {
                    at = (MPI_Offset)(base[sec] + before[sec] + done[sec]);
                    count = (int)n;
                    done[sec] += n;
                }
            }
        }
        if (rc != CLI_EXIT_OK) count = 0;
        MPI_Status st;
        int err = MPI_File_write_at_all(fh, at, data, count, MPI_BYTE, &st);
        int written = count; /* ROMIO leaves the status of an empty write unset */
        if (err == MPI_SUCCESS && count > 0) MPI_Get_count(&st, MPI_BYTE, &written);
        if (rc == CLI_EXIT_OK && (err != MPI_SUCCESS || written != count)) {
            char why[MPI_MAX_ERROR_STRING] = "short write";
            int len = 0;
            if (err != MPI_SUCCESS) MPI_Error_string(err, why, &len);
            cli_error("%s: write failed at byte %lld: %s", w->final_path, (long long)at, why);
            rc = CLI_EXIT_FAIL;
        }
    }
    free(buf);
    return rc;
}
