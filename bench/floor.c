/*
 * floor.c - the benchmark's memory-read floor: the time to read every voxel
 * of a volume once, measured by summing them.
 *
 * No isosurface extractor can finish before it has looked at every sample,
 * so "sum all voxels" is the lower bound the benchmark divides by.  numpy's
 * sum is not a fair floor: for float32 it runs a pairwise summation with
 * little unrolling, for uint8 it converts every sample to a wider type
 * first.  These loops keep many independent accumulators (so the FP adds
 * are not one serial dependency chain) and split the volume into one
 * contiguous part per thread, which is how a slab-parallel extractor reads
 * it.  They are called through ctypes by bench.py on the very arrays the
 * extractors get, in the same process.
 *
 * Exact IEEE arithmetic (no -ffast-math): the accumulators are combined in a
 * fixed order, so a result depends only on the thread count.
 */
#define _DEFAULT_SOURCE /* MAP_ANONYMOUS, madvise */
#include <pthread.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <time.h>
#if defined(__linux__)
#include <sys/mman.h>
#endif

#if defined(__GNUC__)
#define FLOOR_API __attribute__((visibility("default")))
#else
#define FLOOR_API
#endif

FLOOR_API double isomend_bench_sum_f32(const float *data, size_t n, int threads);
FLOOR_API double isomend_bench_sum_u8(const uint8_t *data, size_t n, int threads);
FLOOR_API int isomend_bench_floor_max_threads(void);
FLOOR_API int isomend_bench_page_cost(size_t mb, double out[3]);

enum { MAX_THREADS = 64, LANES = 16 };

typedef struct part {
    const void *data;
    size_t n;
    double sum;
} part;

/* 16 independent float accumulators: the compiler keeps them in vector
 * registers, one load and one add per 4 or 8 samples. */
static void *sum_f32_part(void *arg)
{
    part *p = arg;
    const float *d = p->data;
    float acc[LANES] = {0};
    size_t i = 0;
    for (; i + LANES <= p->n; i += LANES)
        for (int l = 0; l < LANES; l++)
            acc[l] += d[i + l];
    double s = 0.0;
    for (; i < p->n; i++)
        s += d[i];
    for (int l = 0; l < LANES; l++)
        s += acc[l];
    p->sum = s;
    return NULL;
}

/* Bytes summed eight at a time inside 64-bit words (SWAR): two masks give
 * four 16-bit lanes each, which hold at most 2 * 255 * 128 < 65536 after
 * 128 words, so lanes are flushed to 64-bit totals every 128 words. */
static void *sum_u8_part(void *arg)
{
    part *p = arg;
    const uint8_t *d = p->data;
    const uint64_t m = 0x00FF00FF00FF00FFull;
    uint64_t total = 0;
    size_t i = 0;
    while (i + 8 * 128 <= p->n) {
        uint64_t lanes[4] = {0, 0, 0, 0};
        for (int w = 0; w < 128; w += 4, i += 32) {
            for (int l = 0; l < 4; l++) {
                uint64_t v;
                memcpy(&v, d + i + 8 * l, sizeof v);
                lanes[l] += (v & m) + ((v >> 8) & m);
            }
        }
        for (int l = 0; l < 4; l++) {
            uint64_t v = lanes[l];
            total += (v & 0xFFFF) + ((v >> 16) & 0xFFFF) + ((v >> 32) & 0xFFFF) + (v >> 48);
        }
    }
    for (; i < p->n; i++)
        total += d[i];
    p->sum = (double)total;
    return NULL;
}

static double run_parts(const void *data, size_t n, size_t size, int threads,
                        void *(*fn)(void *))
{
    if (threads < 1)
        threads = 1;
    if (threads > MAX_THREADS)
        threads = MAX_THREADS;
    if ((size_t)threads > n / 4096 + 1)
        threads = (int)(n / 4096 + 1);
    part parts[MAX_THREADS];
    pthread_t tid[MAX_THREADS];
    int started[MAX_THREADS] = {0};
    const size_t per = (n / (size_t)threads) & ~(size_t)63;
    for (int t = 0; t < threads; t++) {
        size_t from = per * (size_t)t;
        parts[t].data = (const char *)data + from * size;
        parts[t].n = t + 1 == threads ? n - from : per;
        parts[t].sum = 0.0;
    }
    for (int t = 1; t < threads; t++)
        started[t] = pthread_create(&tid[t], NULL, fn, &parts[t]) == 0;
    fn(&parts[0]);
    double s = parts[0].sum;
    for (int t = 1; t < threads; t++) {
        if (started[t])
            pthread_join(tid[t], NULL);
        else
            fn(&parts[t]); /* no thread: do its part here, the sum stays exact */
        s += parts[t].sum;
    }
    return s;
}

double isomend_bench_sum_f32(const float *data, size_t n, int threads)
{
    return run_parts(data, n, sizeof(float), threads, sum_f32_part);
}

double isomend_bench_sum_u8(const uint8_t *data, size_t n, int threads)
{
    return run_parts(data, n, 1, threads, sum_u8_part);
}

int isomend_bench_floor_max_threads(void) { return MAX_THREADS; }

/*
 * The kernel's price for fresh memory, which every extractor pays on its
 * output: milliseconds per MB to fault in (touch one byte of every 4 KiB of)
 * `mb` MB of anonymous memory.  out[0]: 2 MiB pages, the first time in this
 * process; out[1]: 2 MiB pages again (median of 4 rounds, the memory just
 * given back); out[2]: 4 KiB pages again (median of 4).  On a virtual machine
 * whose host takes freed memory back (free page reporting), out[0] can be
 * many times out[1]: the host must find the pages too.  Returns 0, or -1
 * where this cannot be measured.
 */
static double now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

#if defined(__linux__) && defined(MADV_HUGEPAGE) && defined(MADV_NOHUGEPAGE)
static double touch_round(size_t size, int huge_pages)
{
    const size_t huge = (size_t)2 << 20;
    char *p = mmap(NULL, size + huge, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED)
        return -1.0;
    char *q = (char *)(((uintptr_t)p + huge - 1) & ~(uintptr_t)(huge - 1));
    (void)madvise(q, size, huge_pages ? MADV_HUGEPAGE : MADV_NOHUGEPAGE);
    const double t0 = now_ms();
    for (size_t i = 0; i < size; i += 4096)
        ((volatile char *)q)[i] = 1;
    const double ms = now_ms() - t0;
    munmap(p, size + huge);
    return ms / (double)(size >> 20);
}

static double median4(double v[4])
{
    for (int i = 1; i < 4; i++)
        for (int j = i; j > 0 && v[j] < v[j - 1]; j--) {
            const double t = v[j];
            v[j] = v[j - 1];
            v[j - 1] = t;
        }
    return 0.5 * (v[1] + v[2]);
}

int isomend_bench_page_cost(size_t mb, double out[3])
{
    if (mb < 2 || mb > ((size_t)1 << 20))
        return -1;
    const size_t size = mb << 20;
    double v[4];
    out[0] = touch_round(size, 1);
    for (int r = 0; r < 4; r++)
        v[r] = touch_round(size, 1);
    out[1] = median4(v);
    for (int r = 0; r < 4; r++)
        v[r] = touch_round(size, 0);
    out[2] = median4(v);
    return out[0] < 0 || out[1] < 0 || out[2] < 0 ? -1 : 0;
}
#else
int isomend_bench_page_cost(size_t mb, double out[3])
{
    (void)mb;
    out[0] = out[1] = out[2] = -1.0;
    return -1;
}
#endif
