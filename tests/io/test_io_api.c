/*
 * test_io_api.c - the isomend_io C API on the stacks written by gen_stacks.py.
 *
 * Usage: test_io_api DIR [MANIFEST]   (DIR holds the stacks and MANIFEST, by
 *        default manifest.tsv; the portable build reads manifest_portable.tsv)
 *
 *   - every good stack reads back exactly (whole volume, slice by slice, and
 *     loaded), with the right dimensions, type, kind and spacing;
 *   - every bad stack fails with its status and a message naming the file;
 *   - progress is reported from the calling thread and can cancel;
 *   - a job (open + extract on the library's thread) gives the calling
 *     thread's mesh, ends cancelled or complete whenever it is cancelled, and
 *     refuses callbacks;
 *   - the suggested iso (Otsu) separates a bimodal stack, between samples;
 *   - the mesh from a TIFF stack equals the core's mesh of the same volume
 *     read as raw;
 *   - the L phantom is not mirrored: the mesh has the L where the image has it.
 */
#define _POSIX_C_SOURCE 200809L /* nanosleep */
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "isomend.h"
#include "isomend_io.h"
#include "testutil.h"

#define MAX_FIELDS 32

static const char *g_dir;

static char *join(const char *rel) {
    size_t n = strlen(g_dir) + strlen(rel) + 2;
    char *p = malloc(n);
    if (!p) exit(2);
    snprintf(p, n, "%s/%s", g_dir, rel);
    return p;
}

static void *read_file(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "cannot open %s\n", path);
        exit(2);
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    void *buf = malloc(n > 0 ? (size_t)n : 1);
    if (!buf || fread(buf, 1, (size_t)n, f) != (size_t)n) exit(2);
    fclose(f);
    *size = (size_t)n;
    return buf;
}

/* Opens a source given manifest fields; returns the status, *out the handle. */
static isomend_io_status open_case(char **src, int nsrc, int channel, long first, long count,
                                   long step, isomend_io_source **out) {
    isomend_io_options o;
    isomend_io_options_init(&o);
    o.channel = channel;
    o.first = first;
    o.count = count;
    o.step = step;
    char *paths[MAX_FIELDS];
    for (int i = 0; i < nsrc; i++) paths[i] = join(src[i]);
    CHECK_EQ_INT(isomend_io_create(out), ISOMEND_IO_OK);
    isomend_io_status st = isomend_io_open(*out, (const char *const *)paths, (size_t)nsrc, &o);
    for (int i = 0; i < nsrc; i++) free(paths[i]);
    return st;
}

static void test_good(char **f, int nf) {
    const char *name = f[1];
    isomend_type want_type;
    CHECK_EQ_INT(isomend_type_from_name(f[2], &want_type), ISOMEND_OK);
    int64_t want[3] = {atol(f[3]), atol(f[4]), atol(f[5])};
    double sp_want[3] = {atof(f[12]), atof(f[13]), atof(f[14])};
    isomend_io_source *src = NULL;
    isomend_io_status st = open_case(f + 16, nf - 16, atoi(f[8]), atol(f[9]), atol(f[10]),
                                     atol(f[11]), &src);
    if (st != ISOMEND_IO_OK) {
        fprintf(stderr, "%s: open failed: %s\n", name, isomend_io_message(src));
        CHECK(0);
        isomend_io_destroy(src);
        return;
    }
    CHECK_EQ_INT(strcmp(isomend_io_message(src), ""), 0);
    int64_t dims[3];
    isomend_type t;
    CHECK_EQ_INT(isomend_io_dims(src, dims), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_type(src, &t), ISOMEND_IO_OK);
    for (int a = 0; a < 3; a++) CHECK_EQ_INT(dims[a], want[a]);
    if (t != want_type) fprintf(stderr, "%s: type %s, want %s\n", name, isomend_type_name(t), f[2]);
    CHECK_EQ_INT(t, want_type);
    if (strcmp(isomend_io_kind_name(isomend_io_source_kind(src)), f[7]) != 0) {
        fprintf(stderr, "%s: kind %s, want %s\n", name,
                isomend_io_kind_name(isomend_io_source_kind(src)), f[7]);
        CHECK(0);
    }
    size_t exp_size;
    char *exp_path = join(f[6]);
    unsigned char *expected = read_file(exp_path, &exp_size);
    free(exp_path);
    uint64_t vb = isomend_io_volume_bytes(src), sb = isomend_io_slice_bytes(src);
    CHECK_EQ_INT(vb, exp_size);
    CHECK_EQ_INT(sb * (uint64_t)dims[2], vb);
    if (vb == exp_size) {
        /* whole volume into a caller's buffer */
        unsigned char *buf = malloc(vb);
        CHECK_EQ_INT(isomend_io_read(src, buf, (size_t)vb), ISOMEND_IO_OK);
        if (memcmp(buf, expected, vb) != 0) {
            size_t i = 0;
            while (buf[i] == expected[i]) i++;
            fprintf(stderr, "%s: volume differs from the expected one at byte %zu\n", name, i);
            CHECK(0);
        }
        /* a too-small buffer is refused */
        CHECK_EQ_INT(isomend_io_read(src, buf, (size_t)vb - 1), ISOMEND_IO_ERR_INVALID_ARGUMENT);
        CHECK(strlen(isomend_io_message(src)) > 0);
        /* one slice at a time */
        memset(buf, 0xAB, vb);
        for (int64_t k = 0; k < dims[2]; k++)
            CHECK_EQ_INT(isomend_io_read_slice(src, k, buf + (size_t)k * sb, (size_t)sb), ISOMEND_IO_OK);
        CHECK(memcmp(buf, expected, vb) == 0);
        CHECK_EQ_INT(isomend_io_read_slice(src, dims[2], buf, (size_t)sb), ISOMEND_IO_ERR_INVALID_ARGUMENT);
        /* loaded into the handle */
        isomend_volume vol;
        double secs = -1;
        CHECK_EQ_INT(isomend_io_load(src, &vol, &secs), ISOMEND_IO_OK);
        CHECK(secs >= 0);
        CHECK(vol.data && memcmp(vol.data, expected, vb) == 0);
        CHECK_EQ_INT(vol.type, want_type);
        for (int a = 0; a < 3; a++) CHECK_EQ_INT(vol.dims[a], want[a]);
        free(buf);
    }
    double sp[3];
    int sps[3];
    CHECK_EQ_INT(isomend_io_spacing(src, sp, sps), ISOMEND_IO_OK);
    if (sp_want[0] > 0) {
        for (int a = 0; a < 3; a++) {
            if (fabs(sp[a] - sp_want[a]) > 1e-6 * sp_want[a]) {
                fprintf(stderr, "%s: spacing[%d] %g, want %g\n", name, a, sp[a], sp_want[a]);
                CHECK(0);
            }
        }
        char srcs[128];
        snprintf(srcs, sizeof srcs, "%s,%s,%s", isomend_io_spacing_source_name(sps[0]),
                 isomend_io_spacing_source_name(sps[1]), isomend_io_spacing_source_name(sps[2]));
        if (strcmp(srcs, f[15]) != 0) {
            fprintf(stderr, "%s: spacing sources %s, want %s\n", name, srcs, f[15]);
            CHECK(0);
        }
    } else {
        for (int a = 0; a < 3; a++) {
            CHECK(sp[a] == 1.0);
            CHECK_EQ_INT(sps[a], ISOMEND_IO_SPACING_DEFAULT);
        }
    }
    /* analysis: streamed (or from the loaded volume), consistent with the data */
    isomend_io_summary sum;
    CHECK_EQ_INT(isomend_io_analyse(src, &sum), ISOMEND_IO_OK);
    uint64_t total = sum.nan_samples;
    for (int b = 0; b < ISOMEND_IO_HISTOGRAM_BINS; b++) total += sum.histogram[b];
    CHECK_EQ_INT(sum.samples, (uint64_t)want[0] * (uint64_t)want[1] * (uint64_t)want[2]);
    CHECK_EQ_INT(total, sum.samples);
    CHECK(sum.min <= sum.suggested_iso && sum.suggested_iso <= sum.max);
    CHECK(isomend_io_slice_path(src, 0) != NULL);
    CHECK(isomend_io_slice_path(src, dims[2]) == NULL);
    CHECK(strlen(isomend_io_format(src)) > 0);
    free(expected);
    isomend_io_destroy(src);
    printf("ok   %-18s %s %lldx%lldx%lld\n", name, f[2], (long long)want[0], (long long)want[1],
           (long long)want[2]);
}

static void test_bad(char **f, int nf) {
    const char *name = f[1];
    int want = atoi(f[2]);
    isomend_io_source *src = NULL;
    isomend_io_status st = open_case(f + 8, nf - 8, atoi(f[4]), atol(f[5]), atol(f[6]), atol(f[7]), &src);
    const char *when = "open";
    if (st == ISOMEND_IO_OK) {
        /* header-level checks passed: the data must fail when loaded */
        isomend_volume vol;
        st = isomend_io_load(src, &vol, NULL);
        when = "load";
    }
    const char *msg = isomend_io_message(src);
    if ((int)st != want || !strstr(msg, f[3])) {
        fprintf(stderr, "%s: %s gave status %d (%s) \"%s\"; want %d with \"%s\"\n", name, when,
                (int)st, isomend_io_status_string(st), msg, want, f[3]);
        CHECK(0);
    } else {
        printf("err  %-18s %s: %s\n", name, when, msg);
    }
    isomend_io_destroy(src);
}

/* ---- progress and cancellation ---- */

struct progress_log {
    pthread_t caller;
    int calls, wrong_thread, out_of_range, stages_seen;
    int cancel_at_stage; /* -1 never */
    double last[4];
    int backwards;
};

static int on_progress(void *user, int stage, double fraction) {
    struct progress_log *p = user;
    p->calls++;
    if (!pthread_equal(pthread_self(), p->caller)) p->wrong_thread++;
    if (stage < 0 || stage > 3 || !(fraction >= 0 && fraction <= 1)) {
        p->out_of_range++;
        return 0;
    }
    if (fraction < p->last[stage]) p->backwards++;
    p->last[stage] = fraction;
    p->stages_seen |= 1 << stage;
    return stage == p->cancel_at_stage;
}

static isomend_io_source *open_with_progress(const char *rel, struct progress_log *log) {
    isomend_io_options o;
    isomend_io_options_init(&o);
    o.progress = on_progress;
    o.progress_user = log;
    o.threads = 2;
    char *p = join(rel);
    const char *paths[1] = {p};
    isomend_io_source *src = NULL;
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_open(src, paths, 1, &o), ISOMEND_IO_OK);
    free(p);
    return src;
}

static void test_progress(void) {
    struct progress_log log;
    memset(&log, 0, sizeof log);
    log.caller = pthread_self();
    log.cancel_at_stage = -1;
    isomend_io_source *src = open_with_progress("u16_pattern/slice_%04d.tif", &log);
    isomend_volume vol;
    CHECK_EQ_INT(isomend_io_load(src, &vol, NULL), ISOMEND_IO_OK);
    CHECK(log.calls > 0);
    CHECK_EQ_INT(log.wrong_thread, 0);
    CHECK_EQ_INT(log.out_of_range, 0);
    CHECK_EQ_INT(log.backwards, 0);
    CHECK(log.stages_seen & (1 << ISOMEND_IO_STAGE_READ));
    CHECK(log.last[ISOMEND_IO_STAGE_READ] == 1.0);
    /* extraction reports through the same callback when opts->progress is NULL */
    isomend_options eo;
    isomend_options_init(&eo);
    eo.iso = 30000.5;
    isomend_mesh *mesh = NULL;
    double iso_used = 0;
    CHECK_EQ_INT(isomend_io_extract(src, &eo, 0, &iso_used, &mesh, NULL), ISOMEND_IO_OK);
    CHECK(iso_used == 30000.5);
    CHECK(mesh && isomend_mesh_triangle_count(mesh) > 0);
    CHECK(log.stages_seen & (1 << ISOMEND_IO_STAGE_EXTRACT));
    CHECK_EQ_INT(log.wrong_thread, 0);
    isomend_mesh_destroy(mesh);
    isomend_io_destroy(src);

    /* cancel while reading: status CANCELLED, nothing loaded, the handle stays usable */
    memset(&log, 0, sizeof log);
    log.caller = pthread_self();
    log.cancel_at_stage = ISOMEND_IO_STAGE_READ;
    src = open_with_progress("u16_pattern/slice_%04d.tif", &log);
    CHECK_EQ_INT(isomend_io_load(src, &vol, NULL), ISOMEND_IO_ERR_CANCELLED);
    CHECK(strstr(isomend_io_message(src), "cancel") != NULL);
    mesh = (isomend_mesh *)&log; /* must be reset to NULL on failure */
    CHECK_EQ_INT(isomend_io_extract(src, &eo, 0, NULL, &mesh, NULL), ISOMEND_IO_ERR_CANCELLED);
    CHECK(mesh == NULL);
    log.cancel_at_stage = -1;
    CHECK_EQ_INT(isomend_io_load(src, &vol, NULL), ISOMEND_IO_OK);
    CHECK_EQ_INT(log.wrong_thread, 0);
    isomend_io_destroy(src);

    /* cancel while the headers of a long stack are checked by worker threads */
    memset(&log, 0, sizeof log);
    log.caller = pthread_self();
    log.cancel_at_stage = ISOMEND_IO_STAGE_OPEN;
    {
        isomend_io_options o;
        isomend_io_options_init(&o);
        o.progress = on_progress;
        o.progress_user = &log;
        o.threads = 3;
        char *p = join("many_pages/pages.tif");
        const char *paths[1] = {p};
        CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
        CHECK_EQ_INT(isomend_io_open(src, paths, 1, &o), ISOMEND_IO_ERR_CANCELLED);
        CHECK(strstr(isomend_io_message(src), "cancel") != NULL);
        CHECK_EQ_INT(log.wrong_thread, 0);
        isomend_io_destroy(src);
        free(p);
    }

    /* cancel during extraction */
    memset(&log, 0, sizeof log);
    log.caller = pthread_self();
    log.cancel_at_stage = ISOMEND_IO_STAGE_EXTRACT;
    src = open_with_progress("u16_pattern/slice_%04d.tif", &log);
    CHECK_EQ_INT(isomend_io_extract(src, &eo, 0, NULL, &mesh, NULL), ISOMEND_IO_ERR_CANCELLED);
    CHECK(mesh == NULL);
    isomend_io_destroy(src);
    printf("ok   progress from the calling thread, cancellation while reading and extracting\n");
}

/* ---- jobs: open + extract on the library's thread, polled ---- */

static int same_meshes(const isomend_mesh *a, const isomend_mesh *b) {
    size_t v = isomend_mesh_vertex_count(a), t = isomend_mesh_triangle_count(a);
    return v == isomend_mesh_vertex_count(b) && t == isomend_mesh_triangle_count(b) &&
           memcmp(isomend_mesh_positions(a), isomend_mesh_positions(b), v * 12) == 0 &&
           memcmp(isomend_mesh_normals(a), isomend_mesh_normals(b), v * 12) == 0 &&
           memcmp(isomend_mesh_triangles(a), isomend_mesh_triangles(b), t * 12) == 0;
}

static int core_progress(void *user, double fraction) {
    (void)user;
    (void)fraction;
    return 0;
}

static void sleep_us(long us) {
    struct timespec ts = {us / 1000000, (us % 1000000) * 1000};
    nanosleep(&ts, NULL);
}

static void test_job(void) {
    char *p = join("u16_pattern/slice_%04d.tif");
    const char *paths[1] = {p};
    isomend_io_options io;
    isomend_io_options_init(&io);
    io.threads = 2;
    isomend_options eo;
    isomend_options_init(&eo);
    eo.flags = ISOMEND_FLAG_PAD;

    /* the reference: the same source through the calling thread */
    isomend_io_source *ref_src = NULL;
    isomend_mesh *ref = NULL;
    double ref_iso = 0;
    CHECK_EQ_INT(isomend_io_create(&ref_src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_open(ref_src, paths, 1, &io), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_extract(ref_src, &eo, 1, &ref_iso, &ref, NULL), ISOMEND_IO_OK);

    /* polled to the end: the same mesh and level; progress in range and forwards */
    isomend_io_source *src = NULL;
    isomend_io_job *job = NULL;
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_job_start(src, paths, 1, &io, &eo, 1, &job), ISOMEND_IO_OK);
    int polls = 0, bad = 0, last_stage = 0;
    for (;;) {
        int stage = -1;
        double fraction = -1;
        int done = isomend_io_job_poll(job, &stage, &fraction);
        polls++;
        if (stage < 0 || stage > 3 || !(fraction >= 0 && fraction <= 1) || stage < last_stage) bad++;
        last_stage = stage;
        if (done) break;
        sleep_us(200);
    }
    CHECK_EQ_INT(bad, 0);
    isomend_mesh *mesh = NULL;
    isomend_stats st;
    double iso = 0;
    CHECK_EQ_INT(isomend_io_job_finish(job, &iso, &mesh, &st), ISOMEND_IO_OK);
    CHECK(iso == ref_iso);
    CHECK(mesh && ref && same_meshes(mesh, ref));
    CHECK(mesh && st.triangles == isomend_mesh_triangle_count(mesh));
    /* afterwards an ordinary source, whose reads call no stale callback */
    int64_t dims[3] = {0, 0, 0};
    CHECK_EQ_INT(isomend_io_dims(src, dims), ISOMEND_IO_OK);
    CHECK(dims[0] == 13 && dims[1] == 9 && dims[2] == 13);
    size_t bytes = (size_t)isomend_io_volume_bytes(src);
    void *buf = malloc(bytes);
    CHECK_EQ_INT(isomend_io_read(src, buf, bytes), ISOMEND_IO_OK);
    free(buf);
    isomend_mesh_destroy(mesh);
    isomend_io_destroy(src);

    /* cancelled at once, at random moments, or never: CANCELLED with no mesh,
     * or the reference mesh; never anything else */
    int cancelled = 0, finished = 0, late = 0;
    for (int k = 0; k < 60; k++) {
        CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
        CHECK_EQ_INT(isomend_io_job_start(src, paths, 1, &io, &eo, 1, &job), ISOMEND_IO_OK);
        if (k % 3 == 1) sleep_us(500L * (k * 7 % 60)); /* 0 to 30 ms */
        if (k % 3 != 2) isomend_io_job_cancel(job);
        mesh = (isomend_mesh *)&k;
        isomend_io_status s = isomend_io_job_finish(job, NULL, &mesh, NULL);
        if (s == ISOMEND_IO_ERR_CANCELLED) {
            cancelled++;
            CHECK(mesh == NULL);
            CHECK(strstr(isomend_io_message(src), "cancel") != NULL);
        } else {
            finished++;
            CHECK_EQ_INT(s, ISOMEND_IO_OK);
            CHECK(mesh && ref && same_meshes(mesh, ref));
            if (k % 3 == 1) late++;
        }
        if (k % 3 == 0) CHECK_EQ_INT(s, ISOMEND_IO_ERR_CANCELLED);
        if (k % 3 == 2) CHECK_EQ_INT(s, ISOMEND_IO_OK);
        isomend_mesh_destroy(mesh);
        isomend_io_destroy(src);
    }
    isomend_mesh_destroy(ref);
    isomend_io_destroy(ref_src);

    /* a handle that a running job has cannot start another job */
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_job_start(src, paths, 1, &io, &eo, 0, &job), ISOMEND_IO_OK);
    {
        isomend_io_job *second = (isomend_io_job *)&bad;
        CHECK_EQ_INT(isomend_io_job_start(src, paths, 1, &io, &eo, 0, &second), ISOMEND_IO_ERR_INVALID_ARGUMENT);
        CHECK(second == NULL);
    }
    CHECK_EQ_INT(isomend_io_job_finish(job, NULL, NULL, NULL), ISOMEND_IO_OK);
    isomend_io_destroy(src);

    /* a cancel while many headers are checked by worker threads */
    {
        char *mp = join("many_pages/pages.tif");
        const char *mpaths[1] = {mp};
        io.threads = 3;
        CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
        CHECK_EQ_INT(isomend_io_job_start(src, mpaths, 1, &io, NULL, 0, &job), ISOMEND_IO_OK);
        isomend_io_job_cancel(job);
        CHECK_EQ_INT(isomend_io_job_finish(job, NULL, NULL, NULL), ISOMEND_IO_ERR_CANCELLED);
        CHECK(strstr(isomend_io_message(src), "cancelled while opening") != NULL);
        CHECK_EQ_INT(isomend_io_source_kind(src), -1);
        isomend_io_destroy(src);
        free(mp);
    }

    /* failures: in the job (the open's status and message), or refused at the start */
    {
        char *missing = join("no_such_stack");
        const char *mpaths[1] = {missing};
        CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
        CHECK_EQ_INT(isomend_io_job_start(src, mpaths, 1, NULL, NULL, 0, &job), ISOMEND_IO_OK);
        mesh = (isomend_mesh *)&bad;
        CHECK_EQ_INT(isomend_io_job_finish(job, NULL, &mesh, NULL), ISOMEND_IO_ERR_NOT_FOUND);
        CHECK(mesh == NULL);
        CHECK(strstr(isomend_io_message(src), "no_such_stack") != NULL);
        /* that handle has been opened (and failed): a job needs a fresh one */
        job = (isomend_io_job *)&bad;
        CHECK_EQ_INT(isomend_io_job_start(src, paths, 1, NULL, NULL, 0, &job), ISOMEND_IO_ERR_INVALID_ARGUMENT);
        CHECK(job == NULL);
        CHECK(strstr(isomend_io_message(src), "not been opened") != NULL);
        isomend_io_destroy(src);
        free(missing);
    }
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    isomend_io_options_init(&io);
    io.progress = on_progress;
    CHECK_EQ_INT(isomend_io_job_start(src, paths, 1, &io, NULL, 0, &job), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK(strstr(isomend_io_message(src), "poll") != NULL);
    eo.progress = core_progress;
    CHECK_EQ_INT(isomend_io_job_start(src, paths, 1, NULL, &eo, 0, &job), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_io_job_start(src, paths, 1, NULL, NULL, 0, NULL), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_io_job_start(NULL, paths, 1, NULL, NULL, 0, &job), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_io_job_finish(NULL, NULL, NULL, NULL), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_io_job_poll(NULL, NULL, NULL), 1);
    isomend_io_job_cancel(NULL);
    isomend_io_destroy(src);
    free(p);
    printf("ok   jobs: polled mesh equals the calling thread's; %d cancelled, %d complete (%d of them "
           "cancelled too late), none else; misuse refused\n", cancelled, finished, late);
}

/* ---- analysis ---- */

static void test_analyse(void) {
    struct progress_log log;
    memset(&log, 0, sizeof log);
    log.caller = pthread_self();
    log.cancel_at_stage = -1;
    isomend_io_source *src = open_with_progress("bimodal", &log);
    isomend_io_summary s;
    CHECK_EQ_INT(isomend_io_analyse(src, &s), ISOMEND_IO_OK); /* streamed: not loaded */
    CHECK(s.min >= 17 && s.min <= 23 && s.max >= 197 && s.max <= 203);
    CHECK(s.suggested_iso > 23 && s.suggested_iso < 197);
    CHECK(s.suggested_iso - floor(s.suggested_iso) == 0.5);
    uint64_t total = 0;
    for (int b = 0; b < ISOMEND_IO_HISTOGRAM_BINS; b++) total += s.histogram[b];
    CHECK_EQ_INT(total, s.samples);
    CHECK_EQ_INT(s.samples, 13 * 9 * 4);
    CHECK_EQ_INT(s.nan_samples, 0);
    CHECK(s.histogram[0] > 0 && s.histogram[ISOMEND_IO_HISTOGRAM_BINS - 1] > 0);
    for (int b = 1; b < ISOMEND_IO_HISTOGRAM_BINS - 1; b++) CHECK_EQ_INT(s.histogram[b], 0);
    CHECK_EQ_INT(log.wrong_thread, 0);
    /* the same numbers from the loaded volume; the range matches the data */
    isomend_volume vol;
    CHECK_EQ_INT(isomend_io_load(src, &vol, NULL), ISOMEND_IO_OK);
    const uint8_t *v = vol.data;
    int mn = 255, mx = 0;
    for (size_t i = 0; i < 13 * 9 * 4; i++) {
        if (v[i] < mn) mn = v[i];
        if (v[i] > mx) mx = v[i];
    }
    CHECK(s.min == mn && s.max == mx);
    /* the one-call extraction with the suggested level says which it used */
    isomend_mesh *mesh = NULL;
    double used = 0;
    CHECK_EQ_INT(isomend_io_extract(src, NULL, 1, &used, &mesh, NULL), ISOMEND_IO_OK);
    CHECK(used == s.suggested_iso);
    isomend_mesh_destroy(mesh);
    isomend_io_destroy(src);
    printf("ok   analyse: range %g..%g, suggested iso %g\n", s.min, s.max, s.suggested_iso);
}

/* ---- mesh from slices == mesh from the raw volume ---- */

static void test_mesh_equals_raw(const char *stack, const char *expected, isomend_type type,
                                 int64_t nx, int64_t ny, int64_t nz, double iso) {
    size_t n;
    char *p = join(expected);
    void *raw = read_file(p, &n);
    free(p);
    isomend_volume vol;
    isomend_volume_init(&vol, raw, type, nx, ny, nz);
    isomend_options o;
    isomend_options_init(&o);
    o.iso = iso;
    o.flags = ISOMEND_FLAG_PAD;
    isomend_mesh *ref = NULL, *mesh = NULL;
    isomend_stats rs, ms;
    CHECK_EQ_INT(isomend_extract(&vol, &o, &ref, &rs), ISOMEND_OK);

    isomend_io_source *src = NULL;
    p = join(stack);
    const char *paths[1] = {p};
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_open(src, paths, 1, NULL), ISOMEND_IO_OK);
    free(p);
    CHECK_EQ_INT(isomend_io_extract(src, &o, 0, NULL, &mesh, &ms), ISOMEND_IO_OK);
    if (ref && mesh) {
        size_t v = isomend_mesh_vertex_count(ref), t = isomend_mesh_triangle_count(ref);
        CHECK(t > 0);
        CHECK_EQ_INT(isomend_mesh_vertex_count(mesh), v);
        CHECK_EQ_INT(isomend_mesh_triangle_count(mesh), t);
        if (isomend_mesh_vertex_count(mesh) == v && isomend_mesh_triangle_count(mesh) == t) {
            CHECK(memcmp(isomend_mesh_positions(ref), isomend_mesh_positions(mesh), v * 12) == 0);
            CHECK(memcmp(isomend_mesh_normals(ref), isomend_mesh_normals(mesh), v * 12) == 0);
            CHECK(memcmp(isomend_mesh_triangles(ref), isomend_mesh_triangles(mesh), t * 12) == 0);
        }
        CHECK_EQ_INT(ms.triangles, rs.triangles);
        isomend_check_report r;
        CHECK_EQ_INT(isomend_mesh_check(mesh, &r), ISOMEND_OK);
        CHECK_EQ_INT(r.hole_edges, 0);
        CHECK_EQ_INT(r.border_edges, 0);
        printf("ok   mesh of %s equals the raw volume's (%zu vertices, %zu triangles)\n", stack, v, t);
    }
    isomend_mesh_destroy(ref);
    isomend_mesh_destroy(mesh);
    isomend_io_destroy(src);
    free(raw);
}

/* ---- the L phantom is not mirrored ---- */

static void test_L_phantom(void) {
    isomend_io_source *src = NULL;
    char *p = join("L_phantom");
    const char *paths[1] = {p};
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_open(src, paths, 1, NULL), ISOMEND_IO_OK);
    free(p);
    isomend_options o;
    isomend_options_init(&o);
    o.iso = 50;
    o.flags = ISOMEND_FLAG_PAD;
    isomend_mesh *mesh = NULL;
    CHECK_EQ_INT(isomend_io_extract(src, &o, 0, NULL, &mesh, NULL), ISOMEND_IO_OK);
    if (!mesh) return;
    const float *pos = isomend_mesh_positions(mesh);
    size_t nv = isomend_mesh_vertex_count(mesh);
    /* The image (column = x, row = y, top row = 0): bar at x 2..3 for y 2..12, foot at
     * y 11..12 reaching x 9, dot at x 8..9, y 2..3 in slice 1 only.  Surfaces lie
     * half a sample outside the filled samples. */
    int foot_right = 0, bar_top = 0, dot = 0, dot_wrong_z = 0, outside = 0;
    for (size_t i = 0; i < nv; i++) {
        float x = pos[3 * i], y = pos[3 * i + 1], z = pos[3 * i + 2];
        if (y > 10.4f && y < 12.6f && x > 8.4f) foot_right++;                /* foot: bottom right */
        if (y < 2.0f && x > 1.4f && x < 3.6f) bar_top++;                     /* bar reaches row 2 */
        if (x > 7.4f && y < 4.6f) {                                          /* the dot */
            dot++;
            if (z > 1.6f) dot_wrong_z++;
        }
        /* nothing at the mirrored places: foot at the top, or bar at the right */
        if ((y < 10.4f && y > 4.6f && x > 4.6f) || (y < 1.4f) || (x > 10.6f) || (y > 13.6f)) outside++;
    }
    CHECK(foot_right > 0);
    CHECK(bar_top > 0);
    CHECK(dot > 0);
    CHECK_EQ_INT(dot_wrong_z, 0);
    CHECK_EQ_INT(outside, 0);
    /* orientation: with outward normals (towards lower values) the enclosed volume is
     * positive; a mirror image would turn it negative */
    const uint32_t *tri = isomend_mesh_triangles(mesh);
    double vol6 = 0;
    for (size_t t = 0; t < isomend_mesh_triangle_count(mesh); t++) {
        const float *a = pos + 3 * tri[3 * t], *b = pos + 3 * tri[3 * t + 1], *c = pos + 3 * tri[3 * t + 2];
        vol6 += (double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
                (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
    }
    /* filled samples: 2 slices of (11*2 + 2*6) + 1 slice of 4 = 72 samples; the surface at
     * iso 50 between 0 and 100 sits half way, so the volume is about 72 */
    CHECK(vol6 / 6 > 40 && vol6 / 6 < 110);
    isomend_check_report r;
    CHECK_EQ_INT(isomend_mesh_check(mesh, &r), ISOMEND_OK);
    CHECK_EQ_INT(r.hole_edges, 0);
    printf("ok   L phantom: foot bottom-right (%d vertices), dot in slice 1 only, volume %.1f\n",
           foot_right, vol6 / 6);
    isomend_mesh_destroy(mesh);
    isomend_io_destroy(src);
}

static void test_misuse(void) {
    isomend_io_source *src = NULL;
    CHECK_EQ_INT(isomend_io_create(NULL), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    int64_t dims[3];
    CHECK_EQ_INT(isomend_io_dims(src, dims), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    isomend_volume vol;
    CHECK_EQ_INT(isomend_io_load(src, &vol, NULL), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK(strlen(isomend_io_message(src)) > 0);
    CHECK_EQ_INT(isomend_io_open(src, NULL, 0, NULL), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    CHECK_EQ_INT(isomend_io_open(src, NULL, 0, NULL), ISOMEND_IO_ERR_INVALID_ARGUMENT); /* once */
    isomend_io_destroy(src);
    isomend_io_destroy(NULL);
    CHECK(strcmp(isomend_io_message(NULL), "") == 0);
    CHECK(isomend_io_kind_name(99) == NULL);
    CHECK(isomend_io_spacing_source_name(-1) == NULL);
    for (int s = 0; s <= ISOMEND_IO_ERR_INTERNAL; s++)
        CHECK(strlen(isomend_io_status_string((isomend_io_status)s)) > 0);
    /* a spacing override must be complete and positive */
    isomend_io_options o;
    isomend_io_options_init(&o);
    o.spacing[0] = 0.5;
    char *p = join("u8_folder");
    const char *paths[1] = {p};
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_open(src, paths, 1, &o), ISOMEND_IO_ERR_INVALID_ARGUMENT);
    isomend_io_destroy(src);
    o.spacing[1] = 0.25;
    o.spacing[2] = 2;
    o.origin[0] = -10;
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_open(src, paths, 1, &o), ISOMEND_IO_OK);
    double sp[3], org[3];
    int sps[3];
    CHECK_EQ_INT(isomend_io_spacing(src, sp, sps), ISOMEND_IO_OK);
    CHECK(sp[0] == 0.5 && sp[1] == 0.25 && sp[2] == 2 && sps[2] == ISOMEND_IO_SPACING_OPTION);
    CHECK_EQ_INT(isomend_io_origin(src, org), ISOMEND_IO_OK);
    CHECK(org[0] == -10 && org[1] == 0);
    CHECK_EQ_INT(isomend_io_load(src, &vol, NULL), ISOMEND_IO_OK);
    CHECK(vol.spacing[2] == 2 && vol.origin[0] == -10);
    isomend_io_destroy(src);
    free(p);
    /* the memory limit: whole volume (load) and streamed slice buffers (analyse) */
    isomend_io_options_init(&o);
    o.memory_limit = 1ull << 30;
    o.threads = 1;
    p = join("too_large/huge.tif");
    paths[0] = p;
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_open(src, paths, 1, &o), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_load(src, &vol, NULL), ISOMEND_IO_ERR_TOO_LARGE);
    CHECK(strstr(isomend_io_message(src), "60000x60000x40") && strstr(isomend_io_message(src), "memory limit"));
    isomend_io_summary sum;
    CHECK_EQ_INT(isomend_io_analyse(src, &sum), ISOMEND_IO_ERR_TOO_LARGE);
    CHECK(strstr(isomend_io_message(src), "slice buffer") != NULL);
    isomend_mesh *mesh = NULL;
    CHECK_EQ_INT(isomend_io_extract(src, NULL, 1, NULL, &mesh, NULL), ISOMEND_IO_ERR_TOO_LARGE);
    CHECK(mesh == NULL);
    isomend_io_destroy(src);
    free(p);
    printf("ok   misuse and options\n");
}

/* ---- a headerless raw file, through io/common's reader ---- */

static void test_raw(void) {
    size_t n;
    char *p = join("u16_pattern_all.expected.raw");
    unsigned char *expected = read_file(p, &n);
    isomend_io_options o;
    isomend_io_options_init(&o);
    o.raw_dims[0] = 13;
    o.raw_dims[1] = 9;
    o.raw_dims[2] = 13;
    o.raw_type = ISOMEND_U16;
    const char *paths[1] = {p};
    isomend_io_source *src = NULL;
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_open(src, paths, 1, &o), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_source_kind(src), ISOMEND_IO_KIND_RAW);
    CHECK_EQ_INT(isomend_io_volume_bytes(src), n);
    unsigned char *buf = malloc(n);
    CHECK_EQ_INT(isomend_io_read(src, buf, n), ISOMEND_IO_OK);
    CHECK(memcmp(buf, expected, n) == 0);
    size_t sb = (size_t)isomend_io_slice_bytes(src);
    CHECK_EQ_INT(isomend_io_read_slice(src, 7, buf, sb), ISOMEND_IO_OK);
    CHECK(memcmp(buf, expected + 7 * sb, sb) == 0);
    isomend_io_summary sum;
    CHECK_EQ_INT(isomend_io_analyse(src, &sum), ISOMEND_IO_OK);
    CHECK_EQ_INT(sum.samples, 13 * 9 * 13);
    isomend_io_destroy(src);
    /* wrong dimensions: the reader's message names the file and the sizes */
    o.raw_dims[2] = 14;
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK(isomend_io_open(src, paths, 1, &o) != ISOMEND_IO_OK);
    CHECK(strstr(isomend_io_message(src), "u16_pattern_all.expected.raw") != NULL);
    printf("ok   raw through io/common: %s\n", isomend_io_message(src));
    isomend_io_destroy(src);
    /* NRRD with backwards x and y: origin moved to the stored last sample */
    char *q = join("nrrd/neg.nrrd");
    paths[0] = q;
    CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
    CHECK_EQ_INT(isomend_io_open(src, paths, 1, NULL), ISOMEND_IO_OK);
    double org[3];
    CHECK_EQ_INT(isomend_io_origin(src, org), ISOMEND_IO_OK);
    CHECK(org[0] == 10 - 12 * 0.5 && org[1] == 20 - 8 * 0.75 && org[2] == 30);
    isomend_volume vol;
    CHECK_EQ_INT(isomend_io_load(src, &vol, NULL), ISOMEND_IO_OK);
    CHECK(vol.origin[0] == 4 && vol.origin[1] == 14 && vol.spacing[0] == 0.5 && vol.spacing[1] == 0.75);
    free(q);
    isomend_io_destroy(src);
    free(buf);
    free(expected);
    free(p);
}

int main(int argc, char **argv) {
    if (argc != 2 && argc != 3) {
        fprintf(stderr, "usage: %s DIR [MANIFEST]\n", argv[0]);
        return 2;
    }
    g_dir = argv[1];
    const char *manifest = argc == 3 ? argv[2] : "manifest.tsv";
    char *mpath = join(manifest);
    FILE *m = fopen(mpath, "r");
    free(mpath);
    if (!m) {
        fprintf(stderr, "%s/%s not found (run gen_stacks.py first)\n", g_dir, manifest);
        return 2;
    }
    printf("image libraries: %s\n", isomend_io_image_libraries());
    char line[8192];
    int cases = 0;
    while (fgets(line, sizeof line, m)) {
        line[strcspn(line, "\n")] = 0;
        char *fields[MAX_FIELDS + 16];
        int nf = 0;
        for (char *tok = strtok(line, "\t"); tok && nf < MAX_FIELDS + 16; tok = strtok(NULL, "\t"))
            fields[nf++] = tok;
        if (nf < 9) continue;
        cases++;
        if (strcmp(fields[0], "ok") == 0 && nf >= 17) test_good(fields, nf);
        else if (strcmp(fields[0], "err") == 0) test_bad(fields, nf);
        else CHECK(0);
    }
    fclose(m);
    CHECK(cases >= 30);
    test_misuse();
    test_raw();
    test_progress();
    test_job();
    test_analyse();
    test_mesh_equals_raw("u16_pattern/slice_%04d.tif", "u16_pattern_all.expected.raw", ISOMEND_U16,
                         13, 9, 13, 30000.5);
    test_mesh_equals_raw("exr_float", "exr_float.expected.raw", ISOMEND_F32, 13, 9, 3, 0.0);
    test_L_phantom();
    TEST_EXIT();
}
