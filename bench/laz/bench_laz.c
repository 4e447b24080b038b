/* LAZ codec throughput: decode and encode in points per second, on one and
 * two threads, against laz-perf (LASzip's C++ port compiled to WebAssembly,
 * run by node over the same file) and against reading the plain .las.
 *
 * Inputs: a real TLS plot (treels pine_plot, point format 0) tiled ten
 * times over the plane (1.14 M points, LASzip's own coding choices on real
 * data), and the same points as LAS 1.4 point format 7 (layered items, RGB
 * and GPS time). Each figure is the best of 3 runs; CPU seconds (user+sys,
 * all threads) are shown because the machine may be shared.
 * Usage: bench_laz [tiles] (default 10). Run from the repository root so
 * node finds tests/laz_perf_check.mjs. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include "stages/core/cloud.h"
#include "stages/core/fileio.h"
#include "stages/core/parallel.h"
#include "stages/ingest/ingest.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static double cpu(void)
{
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return (double)u.ru_utime.tv_sec + 1e-6 * (double)u.ru_utime.tv_usec + (double)u.ru_stime.tv_sec +
           1e-6 * (double)u.ru_stime.tv_usec;
}

static uint32_t get32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static void set32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}

/* The real plot tiled `tiles` times (x shifted by 40 m each), as format 0
 * or, with to14, format 7 (RGB from intensity, GPS time from the index). */
static unsigned char *tile(const sy_buffer *src, int tiles, int to14, size_t *size, size_t *n_out)
{
    uint32_t off = get32(src->data + 96), n = get32(src->data + 107);
    unsigned rl = src->data[105] | src->data[106] << 8;
    unsigned out_rl = to14 ? 36 : rl;
    size_t n_all = (size_t)n * (size_t)tiles;
    unsigned head = to14 ? 375 : off;
    unsigned char *d = calloc(head + n_all * out_rl, 1);
    if (!d) return NULL;
    memcpy(d, src->data, off < head ? off : head);
    if (to14) {
        d[25] = 4;
        d[94] = 375 & 0xFF;
        d[95] = 375 >> 8;
        set32(d + 96, 375);
        set32(d + 100, 0);
        d[104] = 7;
        set32(d + 107, 0);
        uint64_t c = n_all;
        for (int i = 0; i < 8; i++) d[247 + i] = (unsigned char)(c >> (8 * i));
    } else {
        set32(d + 107, (uint32_t)n_all);
    }
    d[105] = (unsigned char)out_rl;
    d[106] = 0;
    double scale;
    memcpy(&scale, src->data + 131, 8);
    int32_t shift = (int32_t)(40.0 / scale);
    for (int t = 0; t < tiles; t++)
        for (uint32_t i = 0; i < n; i++) {
            const unsigned char *p = src->data + off + (size_t)i * rl;
            unsigned char *q = d + head + ((size_t)t * n + i) * out_rl;
            memcpy(q, p, 14);
            set32(q, get32(p) + (uint32_t)(t * shift));
            if (!to14) {
                memcpy(q + 14, p + 14, rl - 14);
                continue;
            }
            q[14] = (unsigned char)((p[14] & 7) | ((p[14] >> 3) & 7) << 4);
            q[16] = p[15] & 0x1F;
            double gps = 1.0e5 + 2e-6 * (double)((size_t)t * n + i);
            memcpy(q + 22, &gps, 8);
            unsigned v = p[12] | p[13] << 8;
            for (int k = 0; k < 3; k++) {
                q[30 + 2 * k] = (unsigned char)(v >> k);
                q[31 + 2 * k] = (unsigned char)(v >> 8);
            }
        }
    *size = head + n_all * out_rl;
    *n_out = n_all;
    return d;
}

typedef struct {
    double wall, cpu;
} timing;

/* Best of 3. */
#define TIME_BEST(result, expr)                                                                 \
    do {                                                                                        \
        (result).wall = 1e30;                                                                   \
        for (int rep_ = 0; rep_ < 3; rep_++) {                                                  \
            double w0_ = now(), c0_ = cpu();                                                    \
            expr;                                                                               \
            double w_ = now() - w0_, c_ = cpu() - c0_;                                          \
            if (w_ < (result).wall) {                                                           \
                (result).wall = w_;                                                             \
                (result).cpu = c_;                                                              \
            }                                                                                   \
        }                                                                                       \
    } while (0)

/* laz-perf's decode time (wall and CPU, best of 3), measured inside node. */
static timing laz_perf_time(const unsigned char *laz, size_t size)
{
    const char *tmp = getenv("TMPDIR");
    char path[4096], cmd[8192];
    snprintf(path, sizeof path, "%s/sylva_bench_%d.laz", tmp ? tmp : "/tmp", (int)getpid());
    timing best = {-1, -1};
    FILE *f = fopen(path, "wb");
    if (!f) return best;
    fwrite(laz, 1, size, f);
    fclose(f);
    for (int rep = 0; rep < 3; rep++) {
        snprintf(cmd, sizeof cmd, "node tests/laz_perf_check.mjs --time '%s' 2>/dev/null", path);
        FILE *p = popen(cmd, "r");
        if (!p) break;
        char line[512] = "";
        if (!fgets(line, sizeof line, p)) line[0] = 0;
        pclose(p);
        const char *s = strstr(line, "\"seconds\":"), *c = strstr(line, "\"cpu_seconds\":");
        if (!s || !c) break;
        double v = atof(s + 10);
        if (best.wall < 0 || v < best.wall) best.wall = v, best.cpu = atof(c + 14);
    }
    remove(path);
    return best;
}

static void row(const char *what, size_t n, timing t)
{
    printf("| %-34s | %7.3f | %7.3f | %6.2f | %6.2f |\n", what, t.wall, t.cpu, (double)n / t.wall / 1e6,
           (double)n / t.cpu / 1e6);
}

static int bench(const char *name, const unsigned char *las, size_t size, size_t n)
{
    sy_error err = {0};
    sy_buffer z, back;
    if (sy_laz_compress_mem("bench.las", las, size, &z, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    printf("\n%s: %zu points, LAS %.1f MB, LAZ %.1f MB (%.1f:1)\n\n", name, n, size / 1e6, z.size / 1e6,
           (double)size / (double)z.size);
    printf("| %-34s | wall s  | CPU s   | M pt/s | M pt/CPU-s |\n|---|---|---|---|---|\n", "operation");
    timing t;
    for (int threads = 1; threads <= 2; threads++) {
        sy_set_threads(threads);
        char label[64];
        snprintf(label, sizeof label, "Sylva decode LAZ -> records, %d thr", threads);
        TIME_BEST(t, if (sy_laz_decompress_mem("bench.laz", z.data, z.size, &back, &err) == SY_OK) free(back.data));
        row(label, n, t);
        snprintf(label, sizeof label, "Sylva encode records -> LAZ, %d thr", threads);
        sy_buffer z2;
        TIME_BEST(t, if (sy_laz_compress_mem("bench.las", las, size, &z2, &err) == SY_OK) free(z2.data));
        row(label, n, t);
        snprintf(label, sizeof label, "Sylva read LAZ -> cloud, %d thr", threads);
        sy_cloud c;
        TIME_BEST(t, if (sy_read_las_mem("bench.laz", z.data, z.size, &c, &err) == SY_OK) sy_cloud_free(&c));
        row(label, n, t);
    }
    sy_set_threads(0);
    sy_cloud c;
    TIME_BEST(t, if (sy_read_las_mem("bench.las", las, size, &c, &err) == SY_OK) sy_cloud_free(&c));
    row("Sylva read plain LAS -> cloud", n, t);
    timing lp = laz_perf_time(z.data, z.size);
    if (lp.wall > 0) {
        row("laz-perf 0.0.7 decode (wasm, node)", n, lp);
    } else {
        printf("| laz-perf 0.0.7 decode (wasm, node)  | (node or laz-perf not found) |\n");
    }
    free(z.data);
    return 0;
}

int main(int argc, char **argv)
{
    int tiles = argc > 1 ? atoi(argv[1]) : 10;
    if (tiles < 1) tiles = 1;
    const char *data = getenv("SYLVA_DATA_DIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/real/treels/pine_plot.las", data ? data : "../shared/data");
    sy_buffer src;
    sy_error err = {0};
    if (sy_read_file(path, &src, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 2;
    }
    printf("LAZ codec benchmark (machine possibly shared: compare CPU seconds)\n");
    int rc = 0;
    for (int to14 = 0; to14 <= 1 && rc == 0; to14++) {
        size_t size, n;
        unsigned char *las = tile(&src, tiles, to14, &size, &n);
        if (!las) return 3;
        rc = bench(to14 ? "pine_plot x tiles as LAS 1.4 format 7 (layered POINT14 + RGB14)"
                        : "pine_plot x tiles, format 0 (POINT10)",
                   las, size, n);
        free(las);
    }
    sy_buffer_free(&src);
    return rc;
}
