/* LAS reader/writer throughput: builds synthetic clouds (1 M and 5 M points,
 * format 6 with a treeID extra-bytes field and format 7 with RGB), writes
 * them to $TMPDIR with sy_write_las, then times sy_read_las_mem over the
 * in-memory file (parse only) and sy_read_cloud (disk + parse). Files are
 * removed afterwards. Usage: bench_las [million_points...] (default 1 5). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "stages/core/cloud.h"
#include "stages/core/fileio.h"
#include "stages/ingest/ingest.h"

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int make_cloud(sy_cloud *c, size_t n, int rgb)
{
    sy_error err = {0};
    if (sy_cloud_init(c, n, &err) || sy_cloud_add_intensity(c, &err) || sy_cloud_add_returns(c, &err) ||
        sy_cloud_add_classification(c, &err) || sy_cloud_add_gps_time(c, &err) || (rgb && sy_cloud_add_rgb(c, &err)))
        return -1;
    double *tree = sy_cloud_add_attr(c, "treeID", &err);
    if (!tree) return -1;
    c->origin[0] = 481260.0;
    c->origin[1] = 3812921.0;
    unsigned s = 12345;
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) {
            s = s * 1103515245u + 12345u;
            c->xyz[3 * i + k] = (float)((s >> 8) % 1000000) * (k == 2 ? 0.00004f : 0.0001f);
        }
        c->intensity[i] = (uint16_t)(s >> 3);
        c->return_number[i] = (uint8_t)(1 + i % 3);
        c->num_returns[i] = 3;
        c->classification[i] = (uint8_t)(i % 5 ? 5 : 2);
        c->gps_time[i] = 1.0e5 + 1e-4 * (double)i;
        if (rgb)
            for (int k = 0; k < 3; k++) c->rgb[3 * i + k] = (uint16_t)(s >> (k + 2));
        tree[i] = (double)(i / 5000);
    }
    return 0;
}

static int bench(size_t n, int rgb)
{
    sy_cloud c;
    sy_error err = {0};
    if (make_cloud(&c, n, rgb)) {
        fprintf(stderr, "out of memory building %zu points\n", n);
        return 1;
    }
    const char *tmp = getenv("TMPDIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/bench_las_%d_%zu.las", tmp && *tmp ? tmp : "/tmp", (int)getpid(), n);
    double t0 = now();
    if (sy_write_las(path, &c, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double t_write = now() - t0;
    sy_cloud_free(&c);
    sy_buffer b;
    if (sy_read_file(path, &b, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double best = 1e30, total = 0;
    const int reps = 5;
    for (int r = 0; r < reps; r++) {
        t0 = now();
        if (sy_read_las_mem(path, b.data, b.size, &c, &err)) {
            fprintf(stderr, "%s\n", err.msg);
            return 1;
        }
        double t = now() - t0;
        sy_cloud_free(&c);
        total += t;
        if (t < best) best = t;
    }
    t0 = now();
    if (sy_read_cloud(path, &c, &err)) return 1;
    double t_full = now() - t0;
    sy_cloud_free(&c);
    printf("format %d, %5.1f M points, %6.1f MB: parse best %6.1f ms (mean %6.1f ms, %5.1f Mpts/s), "
           "read_cloud %6.1f ms, write %6.1f ms\n",
           rgb ? 7 : 6, (double)n / 1e6, (double)b.size / 1e6, best * 1e3, total / reps * 1e3,
           (double)n / best / 1e6, t_full * 1e3, t_write * 1e3);
    sy_buffer_free(&b);
    unlink(path);
    return 0;
}

int main(int argc, char **argv)
{
    double millions[8] = {1, 5};
    int count = 2;
    if (argc > 1) {
        count = 0;
        for (int i = 1; i < argc && count < 8; i++) millions[count++] = atof(argv[i]);
    }
    for (int i = 0; i < count; i++)
        for (int rgb = 0; rgb <= 1; rgb++)
            if (bench((size_t)(millions[i] * 1e6), rgb)) return 1;
    return 0;
}
