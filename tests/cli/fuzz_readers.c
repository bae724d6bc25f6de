/*
 * fuzz_readers.c - libFuzzer target for the NRRD, PLY, OBJ and STL readers
 *
 * The first input byte picks the reader, the rest is the file.  The readers
 * take paths (they stat, seek and reopen detached data), so each input is
 * written to a file in a private temporary folder.  Build with
 *   cmake -S . -B build-fuzz -DCMAKE_C_COMPILER=clang -DISOMEND_FUZZ=ON \
 *         -DISOMEND_BUILD_IO=OFF -DISOMEND_BUILD_MESHLAB=OFF -DISOMEND_BUILD_BLENDER=OFF
 *   cmake --build build-fuzz --target fuzz_readers
 *   build-fuzz/tests/cli/fuzz_readers -max_total_time=60 -max_len=4096
 * Without libFuzzer (ISOMEND_FUZZ_STANDALONE) the same file builds a program
 * that runs the inputs given on its command line: a regression runner for
 * crashes found by the fuzzer.
 */
#define _POSIX_C_SOURCE 200809L

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "mesh_io.h"
#include "volume_readers.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static char dir[256];

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (!dir[0]) {
        snprintf(dir, sizeof dir, "/tmp/isomend_fuzz_%ld", (long)getpid());
        char cmd[300];
        snprintf(cmd, sizeof cmd, "mkdir -p '%s'", dir);
        if (system(cmd) != 0) abort();
    }
    if (size < 1) return 0;
    static const char *const names[4] = {"in.nrrd", "in.ply", "in.obj", "in.stl"};
    int kind = data[0] % 4;
    char path[400];
    snprintf(path, sizeof path, "%s/%s", dir, names[kind]);
    FILE *fp = fopen(path, "wb");
    if (!fp) abort();
    if (size > 1 && fwrite(data + 1, 1, size - 1, fp) != size - 1) abort();
    fclose(fp);
    char msg[ISOMEND_FILEIO_MSG_SIZE];
    if (kind == 0) {
        isomend_fileio_info info;
        if (isomend_fileio_probe_nrrd(path, &info, msg, sizeof msg) == ISOMEND_FILEIO_OK &&
            isomend_fileio_volume_bytes(&info) <= (16u << 20)) {
            void *vol = NULL;
            if (isomend_fileio_load(&info, &vol, NULL, NULL, msg, sizeof msg) == ISOMEND_FILEIO_OK) {
                isomend_volume v;
                isomend_fileio_describe(&info, vol, &v);
                free(vol);
            }
        }
    } else {
        isomend_read_mesh_result m;
        if (isomend_read_mesh(path, &m, msg, sizeof msg) == ISOMEND_FILEIO_OK) {
            for (size_t i = 0; i < 3 * m.triangle_count; i++)
                if (m.triangles[i] >= m.vertex_count) abort();
            isomend_read_mesh_free(&m);
        }
    }
    return 0;
}

#ifdef ISOMEND_FUZZ_STANDALONE
int main(int argc, char **argv)
{
    for (int i = 1; i < argc; i++) {
        FILE *fp = fopen(argv[i], "rb");
        if (!fp) {
            perror(argv[i]);
            return 1;
        }
        static uint8_t buf[1 << 20];
        size_t n = fread(buf, 1, sizeof buf, fp);
        fclose(fp);
        LLVMFuzzerTestOneInput(buf, n);
    }
    printf("ran %d input(s)\n", argc - 1);
    return 0;
}
#endif
