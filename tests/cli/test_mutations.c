/*
 * test_mutations.c - the file readers on thousands of corrupted inputs
 *
 * A deterministic mutation fuzzer (fixed seed, so a failure reproduces):
 * valid NRRD (raw and gzip), PLY (ascii, binary LE/BE), OBJ and STL (ascii,
 * binary) files get bit flips, random bytes, digits changed, chunks removed
 * or repeated, and truncations; each result is read.  What must hold:
 *   - no crash, no sanitizer report (the ASan/UBSan build runs this test);
 *   - the status is one of the documented ones; a failure has a message
 *     naming the file; a failure leaves *out NULL / the mesh empty;
 *   - a successful mesh read has every index below its vertex count, and a
 *     successful volume read fills exactly the bytes the header describes.
 * Regression for: ascii PLY tokens longer than the token buffer, list counts
 * that are negative or fractional, "sizes" with huge values under gzip.
 */
#define _POSIX_C_SOURCE 200809L

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zlib.h>

#include "mesh_io.h"
#include "testutil.h"
#include "volume_readers.h"

static uint64_t rng = 0x9E3779B97F4A7C15ull;

static uint32_t next_u32(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (uint32_t)(rng >> 16);
}

typedef struct buf {
    unsigned char *p;
    size_t n;
} buf;

static buf mutate(const buf *in)
{
    buf b;
    b.n = in->n;
    b.p = malloc(in->n + 64);
    memcpy(b.p, in->p, in->n);
    int edits = 1 + (int)(next_u32() % 4);
    for (int e = 0; e < edits && b.n > 0; e++) {
        size_t at = next_u32() % b.n;
        switch (next_u32() % 7) {
        case 0: b.p[at] ^= (unsigned char)(1u << (next_u32() % 8)); break;
        case 1: b.p[at] = (unsigned char)next_u32(); break;
        case 2: b.p[at] = (unsigned char)"0123456789-.9e \n"[next_u32() % 16]; break;
        case 3: b.n = at; break; /* truncate */
        case 4: { /* remove a chunk */
            size_t len = 1 + next_u32() % 16;
            if (at + len > b.n) len = b.n - at;
            memmove(b.p + at, b.p + at + len, b.n - at - len);
            b.n -= len;
            break;
        }
        case 5: { /* repeat a chunk (up to 32 bytes; the buffer has 64 spare) */
            size_t len = 1 + next_u32() % 16;
            if (at + len > b.n) len = b.n - at;
            if (b.n + len <= in->n + 64) {
                memmove(b.p + at + len, b.p + at, b.n - at);
                b.n += len;
            }
            break;
        }
        default: /* a large number where a digit was */
            if (b.p[at] >= '0' && b.p[at] <= '9') b.p[at] = '9';
            break;
        }
    }
    return b;
}

static char dir[512], path_nrrd[600], path_mesh[3][600];
static char msg[ISOMEND_FILEIO_MSG_SIZE];

static void save(const char *path, const buf *b)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) {
        CHECK(0);
        return;
    }
    if (b->n) CHECK(fwrite(b->p, 1, b->n, fp) == b->n);
    fclose(fp);
}

static buf file_bytes(const char *path)
{
    buf b = {NULL, 0};
    FILE *fp = fopen(path, "rb");
    if (!fp) return b;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    b.p = malloc((size_t)n + 1);
    b.n = fread(b.p, 1, (size_t)n, fp);
    fclose(fp);
    return b;
}

static void read_volume(const char *path)
{
    isomend_fileio_info info;
    msg[0] = '\0';
    isomend_fileio_status st = isomend_fileio_probe_nrrd(path, &info, msg, sizeof msg);
    void *data = (void *)&info; /* must become NULL on failure */
    if (st == ISOMEND_FILEIO_OK) {
        uint64_t bytes = isomend_fileio_volume_bytes(&info);
        CHECK(bytes > 0);
        if (bytes > (64u << 20)) return; /* plausible but too large for a test: skip */
        msg[0] = '\0';
        st = isomend_fileio_load(&info, &data, NULL, NULL, msg, sizeof msg);
        if (st == ISOMEND_FILEIO_OK) {
            CHECK(data != NULL);
            /* touch every byte: ASan reports a short allocation */
            volatile unsigned char sum = 0;
            for (uint64_t i = 0; i < bytes; i++) sum ^= ((unsigned char *)data)[i];
            (void)sum;
            free(data);
            return;
        }
        CHECK(data == NULL);
    }
    CHECK(st > ISOMEND_FILEIO_OK && st <= ISOMEND_FILEIO_ERR_CANCELLED);
    CHECK(strstr(msg, dir) != NULL); /* names the file */
}

static void read_mesh(const char *path)
{
    isomend_read_mesh_result m;
    msg[0] = '\0';
    isomend_fileio_status st = isomend_read_mesh(path, &m, msg, sizeof msg);
    if (st == ISOMEND_FILEIO_OK) {
        for (size_t i = 0; i < 3 * m.triangle_count; i++) CHECK(m.triangles[i] < m.vertex_count);
        volatile float s = 0;
        for (size_t i = 0; i < 3 * m.vertex_count; i++) s += m.positions[i];
        (void)s;
        isomend_read_mesh_free(&m);
        return;
    }
    CHECK(m.positions == NULL && m.triangles == NULL && m.vertex_count == 0);
    CHECK(st > ISOMEND_FILEIO_OK && st <= ISOMEND_FILEIO_ERR_CANCELLED);
    CHECK(strstr(msg, dir) != NULL);
}

int main(int argc, char **argv)
{
    int rounds = argc > 1 ? atoi(argv[1]) : 400;
    const char *base = getenv("TMPDIR");
    snprintf(dir, sizeof dir, "%s/isomend_mut_XXXXXX", base && *base ? base : "/tmp");
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    /* seeds: written by our own writers, plus hand-written ascii variants */
    float vol[5 * 4 * 3];
    for (int i = 0; i < 60; i++) vol[i] = (float)((i * 7) % 11) - 5.0f;
    isomend_volume v;
    isomend_volume_init(&v, vol, ISOMEND_F32, 5, 4, 3);
    char seeds_nrrd[2][600];
    for (int gz = 0; gz < 2; gz++) {
        snprintf(seeds_nrrd[gz], sizeof seeds_nrrd[gz], "%s/seed%d.nrrd", dir, gz);
        CHECK_EQ_INT(isomend_fileio_write_nrrd(seeds_nrrd[gz], &v, gz, msg, sizeof msg), ISOMEND_FILEIO_OK);
    }
    const float pos[18] = {1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1, 0, 0, -1};
    const uint32_t tri[24] = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
    const char *exts[3] = {"ply", "obj", "stl"};
    buf seeds_mesh[6];
    int nseeds = 0;
    for (int k = 0; k < 3; k++) {
        char p[600];
        snprintf(p, sizeof p, "%s/seed.%s", dir, exts[k]);
        CHECK_EQ_INT(isomend_write_mesh(p, ISOMEND_MESH_UNKNOWN, pos, pos, 6, tri, 8, msg, sizeof msg),
                     ISOMEND_FILEIO_OK);
        seeds_mesh[nseeds++] = file_bytes(p);
        snprintf(path_mesh[k], sizeof path_mesh[k], "%s/m.%s", dir, exts[k]);
    }
    const char *ascii_ply =
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
        "property list uchar float extra\nelement face 2\nproperty list uchar int vertex_indices\n"
        "end_header\n0 0 0 1 0.5\n1 0 0 0\n1 1 0 2 1 2\n0 1 0 0\n4 0 1 2 3\n3 0 2 3\n";
    const char *ascii_stl = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                            "vertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
    const char *be_ply = "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n"
                         "property float y\nproperty float z\nelement face 1\n"
                         "property list uchar uint vertex_indices\nend_header\n";
    seeds_mesh[nseeds].n = strlen(ascii_ply);
    seeds_mesh[nseeds].p = (unsigned char *)strdup(ascii_ply);
    nseeds++;
    seeds_mesh[nseeds].n = strlen(ascii_stl);
    seeds_mesh[nseeds].p = (unsigned char *)strdup(ascii_stl);
    nseeds++;
    {
        size_t h = strlen(be_ply);
        unsigned char *p = calloc(h + 36 + 13, 1);
        memcpy(p, be_ply, h);
        p[h + 4] = 0x3f; /* x of vertex 0 = 0.5 */
        p[h + 36] = 3;
        p[h + 36 + 8] = 1;
        p[h + 36 + 12] = 2;
        seeds_mesh[nseeds].n = h + 36 + 13;
        seeds_mesh[nseeds].p = p;
        nseeds++;
    }
    const int mesh_kind[6] = {0, 1, 2, 0, 2, 0}; /* which extension each seed uses */

    buf nrrd_seed[2] = {file_bytes(seeds_nrrd[0]), file_bytes(seeds_nrrd[1])};
    snprintf(path_nrrd, sizeof path_nrrd, "%s/m.nrrd", dir);
    for (int r = 0; r < rounds; r++) {
        for (int gz = 0; gz < 2; gz++) {
            buf b = mutate(&nrrd_seed[gz]);
            save(path_nrrd, &b);
            read_volume(path_nrrd);
            free(b.p);
        }
        for (int s = 0; s < nseeds; s++) {
            buf b = mutate(&seeds_mesh[s]);
            save(path_mesh[mesh_kind[s]], &b);
            read_mesh(path_mesh[mesh_kind[s]]);
            free(b.p);
        }
        if (tu_failures) {
            fprintf(stderr, "round %d: failing inputs kept in %s\n", r, dir);
            break;
        }
    }
    for (int s = 0; s < nseeds; s++) free(seeds_mesh[s].p);
    free(nrrd_seed[0].p);
    free(nrrd_seed[1].p);
    if (!tu_failures) {
        char cmd[700];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
        if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", dir);
    }
    TEST_EXIT();
}
