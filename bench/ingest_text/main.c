/* Parse throughput of the text and PLY readers on generated 1 M-point files
 * (written to $TMPDIR and removed afterwards), and the fast number parser
 * against strtod on the same bytes. Usage: bench_ingest_text [points]. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "stages/core/cloud.h"
#include "stages/core/fileio.h"
#include "stages/ingest/ingest.h"
#include "stages/ingest/textnum.h"

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* A survey-positioned cloud shaped like a tree scan: rgb, intensity, an id. */
static int make_cloud(sy_cloud *c, size_t n)
{
    sy_error err = {0};
    if (sy_cloud_init(c, n, &err) || sy_cloud_add_rgb(c, &err) || sy_cloud_add_intensity(c, &err)) return -1;
    double *id = sy_cloud_add_attr(c, "treeID", &err);
    if (!id) return -1;
    c->origin[0] = 1176136.0;
    c->origin[1] = 5000100.0;
    c->origin[2] = 3.0;
    srand(1);
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) c->xyz[3 * i + k] = (float)(20.0 * rand() / RAND_MAX);
        for (int k = 0; k < 3; k++) c->rgb[3 * i + k] = (uint16_t)((rand() % 256) * 257);
        c->intensity[i] = (uint16_t)(rand() % 4096);
        id[i] = (double)(i % 50);
    }
    return 0;
}

typedef sy_code (*reader)(const char *, const unsigned char *, size_t, sy_cloud *, sy_error *);

/* Best of three runs over the file already in memory. */
static void time_reader(const char *label, const char *path, reader read)
{
    sy_buffer b;
    sy_error err = {0};
    if (sy_read_file(path, &b, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return;
    }
    double best = 1e9;
    size_t n = 0;
    for (int run = 0; run < 3; run++) {
        sy_cloud c;
        double t0 = now();
        if (read(path, b.data, b.size, &c, &err)) {
            fprintf(stderr, "%s\n", err.msg);
            break;
        }
        double dt = now() - t0;
        n = c.n;
        sy_cloud_free(&c);
        if (dt < best) best = dt;
    }
    printf("%-34s %9zu points %7.1f MB  %7.1f ms  %6.2f M points/s  %6.0f MB/s\n", label, n, b.size / 1e6,
           best * 1e3, n / best / 1e6, b.size / best / 1e6);
    sy_buffer_free(&b);
}

/* Every number in the file through sy_parse_number and through strtod. */
static void time_number_parsers(const char *path)
{
    sy_buffer b;
    sy_error err = {0};
    if (sy_read_file(path, &b, &err)) return;
    const char *end = (const char *)b.data + b.size;
    double sum_fast = 0, sum_strtod = 0, t0 = now();
    size_t count = 0;
    for (const char *p = (const char *)b.data; p < end;) {
        double v;
        const char *q = sy_parse_number(p, end, &v);
        if (q) sum_fast += v, count++, p = q;
        else p++;
    }
    double t_fast = now() - t0;
    t0 = now();
    for (const char *p = (const char *)b.data; p < end;) {
        char *q;
        double v = strtod(p, &q);
        if (q != p) sum_strtod += v, p = q;
        else p++;
    }
    double t_strtod = now() - t0;
    printf("numbers in %s: %zu, sy_parse_number %.1f ms, strtod %.1f ms (sums differ by %.3g)\n",
           strrchr(path, '/') + 1, count, t_fast * 1e3, t_strtod * 1e3, fabs(sum_fast - sum_strtod));
    sy_buffer_free(&b);
}

int main(int argc, char **argv)
{
    size_t n = argc > 1 ? (size_t)atoll(argv[1]) : 1000000;
    const char *tmp = getenv("TMPDIR");
    char dir[512], ply[600], xyz[600], xyz3[600];
    snprintf(dir, sizeof dir, "%s/sylva-bench-XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(dir)) return 1;
    snprintf(ply, sizeof ply, "%s/cloud.ply", dir);
    snprintf(xyz, sizeof xyz, "%s/cloud.xyz", dir);
    snprintf(xyz3, sizeof xyz3, "%s/plain.xyz", dir);

    sy_cloud c;
    sy_error err = {0};
    if (make_cloud(&c, n)) return 1;
    double t0 = now();
    if (sy_write_ply(ply, &c, &err)) return fprintf(stderr, "%s\n", err.msg), 1;
    double t_ply = now() - t0;
    t0 = now();
    if (sy_write_xyz(xyz, &c, &err)) return fprintf(stderr, "%s\n", err.msg), 1;
    double t_xyz = now() - t0;
    printf("write %zu points: binary PLY %.0f ms, XYZ %.0f ms\n", n, t_ply * 1e3, t_xyz * 1e3);
    /* Plain "x y z" with millimetres, like the AdTree files. */
    FILE *fp = fopen(xyz3, "w");
    if (!fp) return 1;
    for (size_t i = 0; i < n; i++)
        fprintf(fp, "%.3f %.3f %.3f \n", c.xyz[3 * i] - 10.0, c.xyz[3 * i + 1] + 5.0, c.xyz[3 * i + 2]);
    fclose(fp);
    sy_cloud_free(&c);

    time_reader("binary PLY (xyz double, rgb, i, id)", ply, sy_read_ply_mem);
    time_reader("XYZ survey (x y z r g b i id)", xyz, sy_read_xyz_mem);
    time_reader("XYZ plain (x y z, 3 decimals)", xyz3, sy_read_xyz_mem);
    time_number_parsers(xyz3);
    remove(ply);
    remove(xyz);
    remove(xyz3);
    rmdir(dir);
    return 0;
}
