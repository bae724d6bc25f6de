/*
 * test_mesh_writer.c - the streaming mesh writer (io/common/mesh_writer.h)
 *
 * Invariants:
 *   - a mesh fed in random batches, in the order a streaming extraction
 *     delivers it (slice k's vertices, then layer k - 1's triangles, which
 *     use slices k - 1 and k, then a retire), gives the same file byte for
 *     byte as isomend_write_mesh() of the whole mesh, for PLY, OBJ and STL,
 *     with and without normals, with and without end_vertices() before the
 *     last layer and with and without retire();
 *   - the header has one length whatever the counts, and counts beyond the
 *     formats' 32-bit limits are refused with a message naming the file;
 *   - misuse (an id not yet written, a retired id for STL, vertices after
 *     end_vertices) fails with a message and leaves nothing;
 *   - a write that fails (RLIMIT_FSIZE: the file size limit) or an abort
 *     leaves neither the output nor a temporary or scratch file, and the
 *     scratch files are never visible in the folder;
 *   - with retire(), the STL writer's memory does not grow with the mesh.
 */
#define _POSIX_C_SOURCE 200809L

#include <dirent.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "mesh_io.h"
#include "mesh_writer.h"
#include "testutil.h"

static char dir[512];
static char msg[ISOMEND_FILEIO_MSG_SIZE];

static const char *path_in(const char *name)
{
    return tu_path_in(dir, name);
}

/* Entries of the test folder other than . and .. */
static int count_entries(void)
{
    DIR *d = opendir(dir);
    int n = 0;
    struct dirent *e;
    while (d && (e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) n++;
    if (d) closedir(d);
    return n;
}

static unsigned char *slurp(const char *path, size_t *size)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) return NULL;
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    unsigned char *p = malloc(n > 0 ? (size_t)n : 1);
    *size = p && fread(p, 1, (size_t)n, fp) == (size_t)n ? (size_t)n : 0;
    fclose(fp);
    return p;
}

static uint64_t rng = 88172645463325252ull;
static uint64_t next_u64(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return rng;
}
static size_t below(size_t n) { return n ? (size_t)(next_u64() % n) : 0; }

/* A mesh in "slices": vertices of slice k are [first[k], first[k+1]); the
 * triangles of layer k use slices k and k + 1 and are [tfirst[k], tfirst[k+1]). */
typedef struct test_mesh {
    size_t nv, nt, nslices;
    float *pos, *nrm;
    uint32_t *tri;
    size_t *first, *tfirst;
} test_mesh;

static void make_mesh(test_mesh *m, size_t nslices, size_t per_slice, size_t per_layer)
{
    memset(m, 0, sizeof *m);
    m->nslices = nslices;
    m->first = calloc(nslices + 1, sizeof *m->first);
    m->tfirst = calloc(nslices + 1, sizeof *m->tfirst);
    for (size_t k = 0; k < nslices; k++)
        m->first[k + 1] = m->first[k] + below(per_slice + 1); /* empty slices too */
    m->nv = m->first[nslices];
    m->pos = malloc((3 * m->nv + 1) * sizeof(float));
    m->nrm = malloc((3 * m->nv + 1) * sizeof(float));
    for (size_t i = 0; i < 3 * m->nv; i++) {
        /* values that exercise %.9g: negative, tiny, large, exact integers */
        uint64_t r = next_u64();
        float f = (float)((double)(int64_t)(r % 2000001) / 1000.0 - 1000.0);
        if (r % 17 == 0) f = (float)(r % 7);
        if (r % 23 == 0) f = 1e-30f * (float)(r % 5);
        m->pos[i] = f;
        m->nrm[i] = (float)((double)(next_u64() % 2001) / 1000.0 - 1.0);
    }
    size_t cap = nslices * per_layer + 1;
    m->tri = malloc(3 * cap * sizeof(uint32_t));
    for (size_t k = 0; k + 1 < nslices; k++) {
        m->tfirst[k] = m->nt;
        size_t lo = m->first[k], hi = m->first[k + 2];
        if (hi > lo) {
            size_t n = below(per_layer + 1);
            for (size_t t = 0; t < n; t++) {
                for (int c = 0; c < 3; c++)
                    m->tri[3 * m->nt + (size_t)c] = (uint32_t)(lo + below(hi - lo));
                m->nt++;
            }
        }
    }
    m->tfirst[nslices - 1] = m->tfirst[nslices] = m->nt;
}

static void free_mesh(test_mesh *m)
{
    free(m->pos);
    free(m->nrm);
    free(m->tri);
    free(m->first);
    free(m->tfirst);
}

/* Feeds vertices [a, b) in random batches. */
static void feed_vertices(isomend_mesh_writer *w, const test_mesh *m, size_t a, size_t b, int normals)
{
    while (a < b) {
        size_t n = 1 + below(b - a);
        CHECK_EQ_INT(isomend_mesh_writer_vertices(w, n, m->pos + 3 * a, normals ? m->nrm + 3 * a : NULL),
                     ISOMEND_FILEIO_OK);
        a += n;
    }
}

static void feed_triangles(isomend_mesh_writer *w, const test_mesh *m, size_t a, size_t b)
{
    while (a < b) {
        size_t n = 1 + below(b - a);
        if (next_u64() & 1) {
            CHECK_EQ_INT(isomend_mesh_writer_triangles_u32(w, n, m->tri + 3 * a), ISOMEND_FILEIO_OK);
        } else {
            uint64_t *ids = malloc(3 * n * sizeof *ids);
            for (size_t i = 0; i < 3 * n; i++) ids[i] = m->tri[3 * a + i];
            CHECK_EQ_INT(isomend_mesh_writer_triangles(w, n, ids), ISOMEND_FILEIO_OK);
            free(ids);
        }
        a += n;
    }
}

/* Streams `m` into `path` as an extraction would; returns the commit status. */
static isomend_fileio_status stream_mesh(const char *path, const test_mesh *m, int normals,
                                         int end_early, int retire)
{
    isomend_mesh_writer *w;
    isomend_fileio_status st = isomend_mesh_writer_begin(path, ISOMEND_MESH_UNKNOWN, normals, 0, &w,
                                                         msg, sizeof msg);
    CHECK_EQ_INT(st, ISOMEND_FILEIO_OK);
    if (st != ISOMEND_FILEIO_OK) return st;
    for (size_t k = 0; k < m->nslices; k++) {
        feed_vertices(w, m, m->first[k], m->first[k + 1], normals);
        if (k + 1 == m->nslices && end_early == 1) {
            CHECK_EQ_INT(isomend_mesh_writer_end_vertices(w), ISOMEND_FILEIO_OK);
            /* no vertex after the end */
            const float one[3] = {0, 0, 0};
            CHECK_EQ_INT(isomend_mesh_writer_vertices(w, 1, one, one), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
            isomend_mesh_writer_abort(w);
            /* again, properly */
            return stream_mesh(path, m, normals, 2, retire);
        }
        if (k + 1 == m->nslices && end_early == 2)
            CHECK_EQ_INT(isomend_mesh_writer_end_vertices(w), ISOMEND_FILEIO_OK);
        if (k >= 1) {
            feed_triangles(w, m, m->tfirst[k - 1], m->tfirst[k]);
            if (retire) CHECK_EQ_INT(isomend_mesh_writer_retire(w, m->first[k]), ISOMEND_FILEIO_OK);
        }
    }
    return isomend_mesh_writer_commit(w, msg, sizeof msg);
}

static void test_same_bytes(void)
{
    static const char *ext[3] = {"ply", "obj", "stl"};
    for (int round = 0; round < 24; round++) {
        test_mesh m;
        size_t slices = 2 + below(round < 12 ? 6 : 40);
        make_mesh(&m, slices, round % 3 == 0 ? 3 : 300, round % 4 == 0 ? 2 : 500);
        for (int f = 0; f < 3; f++)
            for (int normals = 0; normals < 2; normals++) {
                char whole[64], streamed[64];
                snprintf(whole, sizeof whole, "whole.%s", ext[f]);
                snprintf(streamed, sizeof streamed, "streamed.%s", ext[f]);
                CHECK_EQ_INT(isomend_write_mesh(path_in(whole), ISOMEND_MESH_UNKNOWN, m.pos,
                                                normals ? m.nrm : NULL, m.nv, m.tri, m.nt, msg, sizeof msg),
                             ISOMEND_FILEIO_OK);
                int end_early = (round + normals) % 3 == 1;
                int retire = (round / 2) % 2;
                CHECK_EQ_INT(stream_mesh(path_in(streamed), &m, normals, end_early, retire), ISOMEND_FILEIO_OK);
                size_t na = 0, nb = 0;
                unsigned char *a = slurp(path_in(whole), &na), *b = slurp(path_in(streamed), &nb);
                CHECK(a && b && na == nb && na > 0 && memcmp(a, b, na) == 0);
                if (!(a && b && na == nb && memcmp(a, b, na) == 0))
                    fprintf(stderr, "  round %d %s normals %d: %zu vs %zu bytes\n", round, ext[f], normals, na, nb);
                /* and it reads back as the mesh */
                isomend_read_mesh_result r;
                CHECK_EQ_INT(isomend_read_mesh(path_in(streamed), &r, msg, sizeof msg), ISOMEND_FILEIO_OK);
                if (f != 2) {
                    CHECK_EQ_INT(r.vertex_count, m.nv);
                    CHECK_EQ_INT(r.triangle_count, m.nt);
                    CHECK(m.nt == 0 || memcmp(r.triangles, m.tri, 3 * m.nt * sizeof(uint32_t)) == 0);
                } else {
                    CHECK_EQ_INT(r.stl_facets, m.nt);
                }
                isomend_read_mesh_free(&r);
                free(a);
                free(b);
                unlink(path_in(whole));
                unlink(path_in(streamed));
                CHECK_EQ_INT(count_entries(), 0);
            }
        free_mesh(&m);
    }
}

static void test_header(void)
{
    static const isomend_mesh_format fmts[3] = {ISOMEND_MESH_PLY, ISOMEND_MESH_OBJ, ISOMEND_MESH_STL};
    unsigned char a[1024], b[1024];
    for (int f = 0; f < 3; f++)
        for (int normals = 0; normals < 2; normals++) {
            size_t n = isomend_mesh_header_size(fmts[f], normals);
            CHECK(n > 0 && n < sizeof a);
            uint64_t big = fmts[f] == ISOMEND_MESH_OBJ ? UINT64_MAX : UINT32_MAX;
            CHECK_EQ_INT(isomend_mesh_header(fmts[f], normals, 0, 0, a, "x", msg, sizeof msg), ISOMEND_FILEIO_OK);
            CHECK_EQ_INT(isomend_mesh_header(fmts[f], normals, fmts[f] == ISOMEND_MESH_STL ? UINT64_MAX : big,
                                             big, b, "x", msg, sizeof msg),
                         ISOMEND_FILEIO_OK);
            CHECK(memcmp(a, b, n) != 0);
            if (fmts[f] == ISOMEND_MESH_PLY) {
                /* the exact lines every reader parses */
                char text[1100];
                memcpy(text, b, n);
                text[n] = '\0';
                CHECK(strstr(text, "\nelement vertex 4294967295\n") != NULL);
                CHECK(strstr(text, "\nelement face 4294967295\n") != NULL);
                CHECK(strncmp(text + n - 11, "end_header\n", 11) == 0);
                CHECK(strstr(text, "format binary_little_endian 1.0\n") != NULL);
                CHECK(strstr(text, "property list uchar uint vertex_indices\n") != NULL);
            }
        }
    /* beyond the 32-bit limits */
    CHECK_EQ_INT(isomend_mesh_header(ISOMEND_MESH_PLY, 1, (uint64_t)UINT32_MAX + 1, 0, a, "big.ply", msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(msg, "big.ply") && strstr(msg, "4294967295 vertices") && strstr(msg, ".obj"));
    CHECK_EQ_INT(isomend_mesh_header(ISOMEND_MESH_PLY, 0, 3, (uint64_t)UINT32_MAX + 1, a, "big.ply", msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(msg, "4294967295 triangles") != NULL);
    CHECK_EQ_INT(isomend_mesh_header(ISOMEND_MESH_STL, 0, 0, (uint64_t)UINT32_MAX + 1, a, "big.stl", msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(msg, "big.stl") && strstr(msg, "STL"));
    /* a 64-bit id beyond 2^32 cannot be written as PLY: it was never a vertex of the file */
    isomend_mesh_writer *w;
    CHECK_EQ_INT(isomend_mesh_writer_begin(path_in("ids.ply"), ISOMEND_MESH_UNKNOWN, 0, 0, &w, msg, sizeof msg),
                 ISOMEND_FILEIO_OK);
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint64_t ids[3] = {0, 1, (uint64_t)1 << 32};
    CHECK_EQ_INT(isomend_mesh_writer_vertices(w, 3, p, NULL), ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_triangles(w, 1, ids), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(isomend_mesh_writer_message(w), "ids.ply") && strstr(isomend_mesh_writer_message(w), "4294967296"));
    /* every later call repeats the failure; commit leaves nothing */
    CHECK_EQ_INT(isomend_mesh_writer_vertices(w, 3, p, NULL), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_mesh_writer_commit(w, msg, sizeof msg), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(msg, "ids.ply") != NULL);
    CHECK_EQ_INT(count_entries(), 0);
}

static void test_misuse(void)
{
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t t[3] = {0, 1, 2};
    isomend_mesh_writer *w;
    /* an id beyond what was written */
    CHECK_EQ_INT(isomend_mesh_writer_begin(path_in("m.ply"), ISOMEND_MESH_UNKNOWN, 0, 0, &w, msg, sizeof msg),
                 ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_vertices(w, 2, p, NULL), ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_triangles_u32(w, 1, t), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(isomend_mesh_writer_message(w), "triangle 0 uses vertex 2") != NULL);
    isomend_mesh_writer_abort(w);
    CHECK_EQ_INT(count_entries(), 0);
    /* STL: a retired vertex */
    CHECK_EQ_INT(isomend_mesh_writer_begin(path_in("m.stl"), ISOMEND_MESH_UNKNOWN, 1, 0, &w, msg, sizeof msg),
                 ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_vertices(w, 3, p, p), ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_triangles_u32(w, 1, t), ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_retire(w, 1), ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_retire(w, 9), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    isomend_mesh_writer_abort(w);
    CHECK_EQ_INT(isomend_mesh_writer_begin(path_in("m.stl"), ISOMEND_MESH_UNKNOWN, 0, 0, &w, msg, sizeof msg),
                 ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_vertices(w, 3, p, NULL), ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_retire(w, 1), ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_triangles_u32(w, 1, t), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(isomend_mesh_writer_message(w), "retired") != NULL);
    CHECK_EQ_INT(isomend_mesh_writer_commit(w, msg, sizeof msg), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(count_entries(), 0);
    /* normals promised but not given */
    CHECK_EQ_INT(isomend_mesh_writer_begin(path_in("m.obj"), ISOMEND_MESH_UNKNOWN, 1, 0, &w, msg, sizeof msg),
                 ISOMEND_FILEIO_OK);
    CHECK_EQ_INT(isomend_mesh_writer_vertices(w, 3, p, NULL), ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    isomend_mesh_writer_abort(w);
    /* bad paths and formats: nothing created */
    CHECK_EQ_INT(isomend_mesh_writer_begin(path_in("m.xyz"), ISOMEND_MESH_UNKNOWN, 0, 0, &w, msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_INVALID_ARGUMENT);
    CHECK(w == NULL && strstr(msg, ".xyz") != NULL);
    CHECK_EQ_INT(isomend_mesh_writer_begin(path_in("no/such/m.ply"), ISOMEND_MESH_UNKNOWN, 0, 0, &w, msg, sizeof msg),
                 ISOMEND_FILEIO_ERR_WRITE);
    CHECK(w == NULL && strstr(msg, "m.ply") != NULL);
    isomend_mesh_writer_abort(NULL);
    CHECK_EQ_INT(count_entries(), 0);
}

/* A streamed write that hits the file size limit: nothing may be left. */
static void test_write_failure(void)
{
    struct rlimit old, lim;
    getrlimit(RLIMIT_FSIZE, &old);
    signal(SIGXFSZ, SIG_IGN); /* the write then fails with EFBIG instead of killing us */
    test_mesh m;
    make_mesh(&m, 30, 2000, 3000);
    static const char *names[3] = {"big.ply", "big.obj", "big.stl"};
    for (int f = 0; f < 3; f++) {
        for (int limit_kib = 64; limit_kib <= 2048; limit_kib *= 4) {
            lim = old;
            lim.rlim_cur = (rlim_t)limit_kib * 1024;
            CHECK(setrlimit(RLIMIT_FSIZE, &lim) == 0);
            isomend_mesh_writer *w;
            CHECK_EQ_INT(isomend_mesh_writer_begin(path_in(names[f]), ISOMEND_MESH_UNKNOWN, 1, 0, &w, msg,
                                                   sizeof msg),
                         ISOMEND_FILEIO_OK);
            /* the folder shows the temporary output only, never a scratch file */
            isomend_fileio_status st = ISOMEND_FILEIO_OK;
            for (size_t k = 0; k < m.nslices && st == ISOMEND_FILEIO_OK; k++) {
                st = isomend_mesh_writer_vertices(w, m.first[k + 1] - m.first[k], m.pos + 3 * m.first[k],
                                                  m.nrm + 3 * m.first[k]);
                if (k >= 1 && st == ISOMEND_FILEIO_OK)
                    st = isomend_mesh_writer_triangles_u32(w, m.tfirst[k] - m.tfirst[k - 1],
                                                           m.tri + 3 * m.tfirst[k - 1]);
                CHECK_EQ_INT(count_entries(), 1);
            }
            st = isomend_mesh_writer_commit(w, msg, sizeof msg);
            CHECK_EQ_INT(setrlimit(RLIMIT_FSIZE, &old), 0);
            CHECK_EQ_INT(st, ISOMEND_FILEIO_ERR_WRITE);
            CHECK(strstr(msg, names[f]) && strstr(msg, "write failed"));
            CHECK_EQ_INT(count_entries(), 0);
        }
    }
    free_mesh(&m);
}

static long peak_kib(void)
{
    FILE *fp = fopen("/proc/self/status", "r");
    char line[256];
    long kib = -1;
    while (fp && fgets(line, sizeof line, fp))
        if (sscanf(line, "VmHWM: %ld kB", &kib) == 1) break;
    if (fp) fclose(fp);
    return kib;
}

/* 1M vertices, 2M facets as STL with retire: the kept positions stay a window. */
static void test_stl_memory(void)
{
    enum { SLICES = 1000, PER = 1000 };
    float *pos = malloc(PER * 3 * sizeof(float));
    uint32_t *tri = malloc(2 * PER * 3 * sizeof(uint32_t));
    if (!pos || !tri) {
        CHECK(0);
        return;
    }
    long before = peak_kib();
    isomend_mesh_writer *w;
    CHECK_EQ_INT(isomend_mesh_writer_begin(path_in("window.stl"), ISOMEND_MESH_UNKNOWN, 0, 0, &w, msg, sizeof msg),
                 ISOMEND_FILEIO_OK);
    for (uint32_t k = 0; k < SLICES; k++) {
        for (int i = 0; i < PER; i++) {
            pos[3 * i] = (float)i;
            pos[3 * i + 1] = (float)k;
            pos[3 * i + 2] = (float)(i % 7);
        }
        CHECK_EQ_INT(isomend_mesh_writer_vertices(w, PER, pos, NULL), ISOMEND_FILEIO_OK);
        if (k == 0) continue;
        for (uint32_t i = 0; i + 1 < PER; i++) {
            uint32_t a = (k - 1) * PER + i, b = k * PER + i;
            uint32_t *t = tri + 6 * i;
            t[0] = a, t[1] = a + 1, t[2] = b;
            t[3] = b, t[4] = a + 1, t[5] = b + 1;
        }
        CHECK_EQ_INT(isomend_mesh_writer_triangles_u32(w, 2 * (PER - 1), tri), ISOMEND_FILEIO_OK);
        CHECK_EQ_INT(isomend_mesh_writer_retire(w, (uint64_t)k * PER), ISOMEND_FILEIO_OK);
    }
    CHECK_EQ_INT(isomend_mesh_writer_commit(w, msg, sizeof msg), ISOMEND_FILEIO_OK);
    long grew = peak_kib() - before;
    /* without retire the positions alone would be 11.7 MiB; the stdio buffer is 1 MiB */
    printf("STL of 1M vertices with retire: peak grew %ld KiB\n", grew);
#if defined(__SANITIZE_ADDRESS__)
    (void)grew; /* ASan keeps freed memory in quarantine: no bound to check */
#else
    CHECK(before > 0 && grew < 4096);
#endif
    struct stat st;
    CHECK(stat(path_in("window.stl"), &st) == 0 && st.st_size == 84 + 50 * (off_t)(2 * (PER - 1)) * (SLICES - 1));
    unlink(path_in("window.stl"));
    free(pos);
    free(tri);
}

int main(void)
{
    const char *base = getenv("TMPDIR");
    snprintf(dir, sizeof dir, "%s/isomend_writer_XXXXXX", base && *base ? base : "/tmp");
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_stl_memory(); /* first: the peak must not include the other tests' meshes */
    test_header();
    test_misuse();
    test_same_bytes();
    test_write_failure();
    rmdir(dir);
    TEST_EXIT();
}
