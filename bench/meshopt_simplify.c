/*
 * meshopt_simplify.c - postprocess_bench.py's meshoptimizer peer: reads a
 * binary little-endian PLY as isomend writes it (float vertex properties, x
 * y z first; faces of uchar count + uint32 indices, triangles), simplifies
 * it with meshopt_simplify (meshoptimizer 0.18, Debian's
 * libmeshoptimizer-dev) to RATIO of its triangles with
 * meshopt_SimplifyLockBorder, and writes the result as a binary PLY
 * (positions only, unreferenced vertices dropped).  Prints one line:
 * "triangles_before triangles_after ms result_error", ms the time of the
 * meshopt_simplify call alone.  target_error is 1 (the whole mesh extent):
 * the triangle target, not an error bound, stops it, as for the other tools.
 *
 * usage: isomend_bench_meshopt IN.ply OUT.ply RATIO
 */
#define _POSIX_C_SOURCE 200809L
#include <meshoptimizer.h>

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

static int die(const char *what)
{
    fprintf(stderr, "isomend_bench_meshopt: %s\n", what);
    return 1;
}

int main(int argc, char **argv)
{
    if (argc != 4) return die("usage: isomend_bench_meshopt IN.ply OUT.ply RATIO");
    const double ratio = atof(argv[3]);
    FILE *f = fopen(argv[1], "rb");
    if (!f) return die("cannot open the input");
    char line[256];
    size_t nv = 0, nf = 0, nprops = 0;
    int in_vertex = 0;
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "element vertex ", 15) == 0) {
            nv = strtoull(line + 15, NULL, 10);
            in_vertex = 1;
        } else if (strncmp(line, "element face ", 13) == 0) {
            nf = strtoull(line + 13, NULL, 10);
            in_vertex = 0;
        } else if (strncmp(line, "property float ", 15) == 0 && in_vertex) {
            nprops++;
        } else if (strncmp(line, "format ", 7) == 0 &&
                   strncmp(line, "format binary_little_endian", 27) != 0) {
            return die("not a binary little-endian PLY");
        } else if (strcmp(line, "end_header\n") == 0) {
            break;
        }
    }
    if (nprops < 3 || nv == 0 || nf == 0) return die("no vertices, faces or x y z");
    float *vin = malloc(nv * nprops * sizeof(float));
    float *pos = malloc(nv * 3 * sizeof(float));
    unsigned *idx = malloc(nf * 3 * sizeof(unsigned));
    unsigned *dst = malloc(nf * 3 * sizeof(unsigned));
    if (!vin || !pos || !idx || !dst) return die("out of memory");
    if (fread(vin, sizeof(float) * nprops, nv, f) != nv) return die("truncated vertices");
    for (size_t i = 0; i < nv; i++) memcpy(pos + 3 * i, vin + nprops * i, 3 * sizeof(float));
    for (size_t i = 0; i < nf; i++) {
        unsigned char n;
        if (fread(&n, 1, 1, f) != 1 || n != 3) return die("a face is not a triangle");
        if (fread(idx + 3 * i, sizeof(unsigned), 3, f) != 3) return die("truncated faces");
    }
    fclose(f);

    size_t target = (size_t)(ratio * (double)nf + 0.5) * 3;
    float err = 0;
    double t0 = now_ms();
    size_t n = meshopt_simplify(dst, idx, nf * 3, pos, nv, 3 * sizeof(float), target, 1.0f,
                                meshopt_SimplifyLockBorder, &err);
    double ms = now_ms() - t0;

    /* compact: only the vertices the triangles use, in order of first use */
    unsigned *remap = malloc(nv * sizeof(unsigned));
    if (!remap) return die("out of memory");
    memset(remap, 0xff, nv * sizeof(unsigned));
    size_t used = 0;
    for (size_t i = 0; i < n; i++)
        if (remap[dst[i]] == 0xffffffffu) remap[dst[i]] = (unsigned)used++;
    FILE *o = fopen(argv[2], "wb");
    if (!o) return die("cannot create the output");
    fprintf(o, "ply\nformat binary_little_endian 1.0\nelement vertex %zu\nproperty float x\n"
               "property float y\nproperty float z\nelement face %zu\n"
               "property list uchar uint vertex_indices\nend_header\n",
            used, n / 3);
    float *vout = malloc((used ? used : 1) * 3 * sizeof(float));
    if (!vout) return die("out of memory");
    for (size_t v = 0; v < nv; v++)
        if (remap[v] != 0xffffffffu) memcpy(vout + 3 * remap[v], pos + 3 * v, 3 * sizeof(float));
    fwrite(vout, 3 * sizeof(float), used, o);
    for (size_t i = 0; i < n; i += 3) {
        unsigned char three = 3;
        unsigned t[3] = {remap[dst[i]], remap[dst[i + 1]], remap[dst[i + 2]]};
        fwrite(&three, 1, 1, o);
        fwrite(t, sizeof(unsigned), 3, o);
    }
    if (fclose(o) != 0) return die("cannot write the output");
    printf("%zu %zu %.3f %.9g\n", nf, n / 3, ms, (double)err);
    free(vin), free(pos), free(idx), free(dst), free(remap), free(vout);
    return 0;
}
