/* bench_ingest [POINTS] [DIR]: reader throughput in points/s for every format
 * on a generated cloud (default 5 M points), with PCL's PLY and PCD readers
 * timed on the same files in the same run. Prints a table and the ratios. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench/ingest/pcl_readers.h"
#include "stages/core/progress.h"
#include "stages/ingest/ingest.h"

/* A deterministic tree-like cloud: points on a noisy cone, 25 m tall. */
static void generate(size_t n, float *xyz)
{
    uint64_t s = 0x9E3779B97F4A7C15ull;
    for (size_t i = 0; i < n; i++) {
        float r[3];
        for (int k = 0; k < 3; k++) {
            s ^= s << 13, s ^= s >> 7, s ^= s << 17;
            r[k] = (float)((s >> 11) * (1.0 / 9007199254740992.0));
        }
        float h = 25.0f * r[0], rad = 4.0f * (1.0f - r[0] / 1.2f) * r[1];
        float a = 6.2831853f * r[2];
        xyz[3 * i] = 500.0f + rad * cosf(a);
        xyz[3 * i + 1] = 800.0f + rad * sinf(a);
        xyz[3 * i + 2] = h;
    }
}

static void put_u16(unsigned char *p, unsigned v) { p[0] = v & 255, p[1] = v >> 8; }
static void put_u32(unsigned char *p, uint32_t v)
{
    for (int k = 0; k < 4; k++) p[k] = (v >> (8 * k)) & 255;
}
static void put_f64(unsigned char *p, double v) { memcpy(p, &v, 8); }

static int write_las(const char *path, const float *xyz, size_t n)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    unsigned char h[227] = {0};
    memcpy(h, "LASF", 4);
    h[24] = 1, h[25] = 2;                       /* LAS 1.2 */
    put_u16(h + 94, 227);                       /* header size */
    put_u32(h + 96, 227);                       /* offset to points */
    h[104] = 0;                                 /* point format 0 */
    put_u16(h + 105, 20);                       /* record length */
    put_u32(h + 107, (uint32_t)n);
    for (int k = 0; k < 3; k++) put_f64(h + 131 + 8 * k, 0.001); /* scale */
    double lo[3] = {1e30, 1e30, 1e30}, hi[3] = {-1e30, -1e30, -1e30};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            if (xyz[3 * i + k] < lo[k]) lo[k] = xyz[3 * i + k];
            if (xyz[3 * i + k] > hi[k]) hi[k] = xyz[3 * i + k];
        }
    for (int k = 0; k < 3; k++) put_f64(h + 179 + 16 * k, hi[k]), put_f64(h + 187 + 16 * k, lo[k]);
    fwrite(h, 1, sizeof h, fp);
    unsigned char rec[20] = {0};
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) put_u32(rec + 4 * k, (uint32_t)(int32_t)(xyz[3 * i + k] * 1000.0f));
        rec[14] = 0x11;
        fwrite(rec, 1, sizeof rec, fp);
    }
    return fclose(fp);
}

static int write_ply(const char *path, const float *xyz, size_t n)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    fprintf(fp, "ply\nformat binary_little_endian 1.0\nelement vertex %zu\n"
                "property float x\nproperty float y\nproperty float z\nend_header\n", n);
    fwrite(xyz, sizeof(float), 3 * n, fp);
    return fclose(fp);
}

static int write_pcd(const char *path, const float *xyz, size_t n)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    fprintf(fp, "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
                "TYPE F F F\nCOUNT 1 1 1\nWIDTH %zu\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %zu\n"
                "DATA binary\n", n, n);
    fwrite(xyz, sizeof(float), 3 * n, fp);
    return fclose(fp);
}

static int write_xyz(const char *path, const float *xyz, size_t n)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    for (size_t i = 0; i < n; i++) fprintf(fp, "%.3f %.3f %.3f\n", xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    return fclose(fp);
}

/* Best of three runs, in seconds; -1 on failure. */
static double time_sylva(const char *path, size_t expect)
{
    double best = -1;
    for (int r = 0; r < 3; r++) {
        sy_cloud c;
        sy_error err = {0};
        double t = sy_now();
        if (sy_read_cloud(path, &c, &err)) {
            fprintf(stderr, "bench_ingest: %s\n", err.msg);
            return -1;
        }
        t = sy_now() - t;
        if (c.n != expect) fprintf(stderr, "bench_ingest: %s: read %zu points, expected %zu\n", path, c.n, expect);
        sy_cloud_free(&c);
        if (best < 0 || t < best) best = t;
    }
    return best;
}

static double time_pcl(long (*load)(const char *), const char *path)
{
    double best = -1;
    for (int r = 0; r < 3; r++) {
        double t = sy_now();
        if (load(path) < 0) return -1;
        t = sy_now() - t;
        if (best < 0 || t < best) best = t;
    }
    return best;
}

int main(int argc, char **argv)
{
    size_t n = argc > 1 ? strtoull(argv[1], NULL, 10) : 5000000;
    const char *dir = argc > 2 ? argv[2] : "/tmp";
    float *xyz = malloc(n * 3 * sizeof(float));
    if (!xyz) return 3;
    generate(n, xyz);
    char las[4096], ply[4096], pcd[4096], txt[4096];
    snprintf(las, sizeof las, "%s/sylva_bench.las", dir);
    snprintf(ply, sizeof ply, "%s/sylva_bench.ply", dir);
    snprintf(pcd, sizeof pcd, "%s/sylva_bench.pcd", dir);
    snprintf(txt, sizeof txt, "%s/sylva_bench.xyz", dir);
    if (write_las(las, xyz, n) || write_ply(ply, xyz, n) || write_pcd(pcd, xyz, n) || write_xyz(txt, xyz, n)) {
        fprintf(stderr, "bench_ingest: cannot write the test files in %s\n", dir);
        return 2;
    }
    free(xyz);
    printf("ingest benchmark: %zu points, best of 3, one thread\n", n);
    printf("%-22s %10s %14s\n", "reader", "seconds", "Mpoints/s");
    struct { const char *name; const char *path; } rows[] = {
        {"sylva LAS (fmt 0)", las}, {"sylva PLY (binary)", ply}, {"sylva PCD (binary)", pcd}, {"sylva XYZ (text)", txt}};
    double t_sylva[4];
    for (int i = 0; i < 4; i++) {
        t_sylva[i] = time_sylva(rows[i].path, n);
        printf("%-22s %10.3f %14.1f\n", rows[i].name, t_sylva[i], t_sylva[i] > 0 ? n / t_sylva[i] / 1e6 : 0);
    }
    double t_ply = time_pcl(bench_pcl_load_ply, ply), t_pcd = time_pcl(bench_pcl_load_pcd, pcd);
    printf("%-22s %10.3f %14.1f\n", "PCL loadPLYFile", t_ply, t_ply > 0 ? n / t_ply / 1e6 : 0);
    printf("%-22s %10.3f %14.1f\n", "PCL loadPCDFile", t_pcd, t_pcd > 0 ? n / t_pcd / 1e6 : 0);
    if (t_sylva[1] > 0 && t_ply > 0) printf("PLY: sylva is %.2fx PCL's speed\n", t_ply / t_sylva[1]);
    if (t_sylva[2] > 0 && t_pcd > 0) printf("PCD: sylva is %.2fx PCL's speed\n", t_pcd / t_sylva[2]);
    remove(las), remove(ply), remove(pcd), remove(txt);
    return 0;
}
