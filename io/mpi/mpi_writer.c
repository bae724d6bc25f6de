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

void mpi_writer_close(mpi_writer *w)
{
    for (int s = 0; s < 3; s++) {
        if (w->section[s]) fclose(w->section[s]);
        w->section[s] = NULL;
    }
}

static int put(mpi_writer *w, int s, const unsigned char *rec, size_t len)
{
    if (!len) return 0;
    if (fwrite(rec, 1, len, w->section[s]) != len) {
        cli_error("%s: cannot write a scratch file: %s", w->final_path, strerror(errno));
        return -1;
    }
    w->size[s] += len;
    return 0;
}

int mpi_writer_encode(mpi_writer *w, const slab_piece *p, uint64_t first_id,
                      const uint64_t *foreign_ids)
{
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    for (int s = 0; s < 3; s++) {
        w->size[s] = 0;
        if (isomend_spool_open(w->final_path, &w->section[s], msg, sizeof msg) !=
            ISOMEND_FILEIO_OK) {
            cli_error("%s", msg);
            mpi_writer_close(w);
            return CLI_EXIT_FAIL;
        }
    }
    unsigned char rec[ISOMEND_MESH_RECORD_MAX];
    const float *nrm = w->normals ? p->nrm : NULL;
    for (size_t v = 0; v < p->nv; v++) {
        const float *n = nrm ? nrm + 3 * v : NULL;
        if (put(w, 0, rec, isomend_mesh_encode_vertex(w->format, p->pos + 3 * v, n, rec)) ||
            put(w, 1, rec, isomend_mesh_encode_normal(w->format, n, rec))) {
            mpi_writer_close(w);
            return CLI_EXIT_FAIL;
        }
    }
    for (size_t t = 0; t < p->nt; t++) {
        uint64_t ids[3];
        const float *corner[3];
        for (int c = 0; c < 3; c++) {
            uint64_t id = p->tri[3 * t + (size_t)c];
            if (id & SLAB_FOREIGN) {
                size_t f = (size_t)(id & ~SLAB_FOREIGN);
                ids[c] = foreign_ids[f];
                corner[c] = p->foreign_pos + 3 * f;
            } else {
                ids[c] = first_id + id;
                corner[c] = p->pos + 3 * id;
            }
        }
        if (put(w, 2, rec, isomend_mesh_encode_face(w->format, w->normals, ids, corner, rec))) {
            mpi_writer_close(w);
            return CLI_EXIT_FAIL;
        }
    }
    for (int s = 0; s < 3; s++)
        if (fflush(w->section[s]) != 0 || fseeko(w->section[s], 0, SEEK_SET) != 0) {
            cli_error("%s: cannot write a scratch file: %s", w->final_path, strerror(errno));
            mpi_writer_close(w);
            return CLI_EXIT_FAIL;
        }
    return CLI_EXIT_OK;
}

int mpi_writer_write(mpi_writer *w, MPI_Comm comm, MPI_File fh, const unsigned char *header,
                     size_t header_size, int failed)
{
    int rank;
    MPI_Comm_rank(comm, &rank);
    uint64_t size[3], before[3] = {0, 0, 0}, total[3];
    for (int s = 0; s < 3; s++) size[s] = failed ? 0 : w->size[s];
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
                if (fread(buf, 1, n, w->section[sec]) != n) {
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
