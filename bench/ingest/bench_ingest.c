/* bench_ingest [POINTS] [DIR]: reader throughput in points/s for every format
 * and encoding on a generated cloud (default 5 M points), with PCL's PLY and
 * PCD readers timed on the same files in the same run where PCL has one
 * (COLMAP has none). Prints one row per file: sylva's and PCL's points/s and
 * the ratio. */
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

/* "x y z" lines in millimetres after an optional header: XYZ and ASCII PLY. */
static int write_text(const char *path, const char *header, const float *xyz, size_t n)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    fputs(header, fp);
    for (size_t i = 0; i < n; i++) fprintf(fp, "%.3f %.3f %.3f\n", xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    return fclose(fp);
}

static int write_xyz(const char *path, const float *xyz, size_t n) { return write_text(path, "", xyz, n); }

static int write_ply_ascii(const char *path, const float *xyz, size_t n)
{
    char header[256];
    snprintf(header, sizeof header,
             "ply\nformat ascii 1.0\nelement vertex %zu\n"
             "property float x\nproperty float y\nproperty float z\nend_header\n",
             n);
    return write_text(path, header, xyz, n);
}

/* COLMAP points carry a colour, a reprojection error and a track; each point
 * here is seen in two images, as in a sparse SfM model. */
static int write_colmap_txt(const char *path, const float *xyz, size_t n)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    fprintf(fp, "# 3D point list with one line of data per point:\n"
                "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
                "# Number of points: %zu, mean track length: 2\n", n);
    for (size_t i = 0; i < n; i++)
        fprintf(fp, "%zu %.6f %.6f %.6f %u %u %u %.4f %zu %zu %zu %zu\n", i + 1, xyz[3 * i], xyz[3 * i + 1],
                xyz[3 * i + 2], (unsigned)(i % 256), 128u, 64u, 0.5 + 0.001 * (double)(i % 1000), 1 + i % 50, i,
                2 + i % 50, i + 1);
    return fclose(fp);
}

static int write_colmap_bin(const char *path, const float *xyz, size_t n)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    uint64_t count = n;
    fwrite(&count, 8, 1, fp);
    unsigned char rec[8 + 24 + 3 + 8 + 8 + 2 * 8];
    for (size_t i = 0; i < n; i++) {
        uint64_t id = i + 1, track = 2;
        double p[3] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]}, error = 0.5 + 0.001 * (double)(i % 1000);
        uint32_t obs[4] = {(uint32_t)(1 + i % 50), (uint32_t)i, (uint32_t)(2 + i % 50), (uint32_t)(i + 1)};
        unsigned char *q = rec;
        memcpy(q, &id, 8), q += 8;
        memcpy(q, p, 24), q += 24;
        *q++ = (unsigned char)(i % 256), *q++ = 128, *q++ = 64;
        memcpy(q, &error, 8), q += 8;
        memcpy(q, &track, 8), q += 8;
        memcpy(q, obs, 16);
        fwrite(rec, 1, sizeof rec, fp);
    }
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

typedef struct {
    const char *name, *file;
    int (*write)(const char *path, const float *xyz, size_t n);
    long (*pcl_load)(const char *path); /* NULL: PCL has no reader for it */
    char path[4096];
} bench_row;

int main(int argc, char **argv)
{
    size_t n = argc > 1 ? strtoull(argv[1], NULL, 10) : 5000000;
    const char *dir = argc > 2 ? argv[2] : "/tmp";
    float *xyz = malloc(n * 3 * sizeof(float));
    if (!xyz) return 3;
    generate(n, xyz);
    bench_row rows[] = {
        {"LAS (fmt 0)", "sylva_bench.las", write_las, NULL, ""},
        {"PLY (binary)", "sylva_bench.ply", write_ply, bench_pcl_load_ply, ""},
        {"PLY (ascii)", "sylva_bench_ascii.ply", write_ply_ascii, bench_pcl_load_ply, ""},
        {"PCD (binary)", "sylva_bench.pcd", write_pcd, bench_pcl_load_pcd, ""},
        {"PCD (compressed)", "sylva_bench_lzf.pcd", bench_pcl_save_pcd_compressed, bench_pcl_load_pcd, ""},
        {"XYZ (text)", "sylva_bench.xyz", write_xyz, NULL, ""},
        {"COLMAP points3D.txt", "sylva_bench_points3D.txt", write_colmap_txt, NULL, ""},
        {"COLMAP points3D.bin", "sylva_bench_points3D.bin", write_colmap_bin, NULL, ""},
    };
    const size_t n_rows = sizeof rows / sizeof rows[0];
    for (size_t r = 0; r < n_rows; r++) {
        snprintf(rows[r].path, sizeof rows[r].path, "%s/%s", dir, rows[r].file);
        if (rows[r].write(rows[r].path, xyz, n)) {
            fprintf(stderr, "bench_ingest: cannot write %s\n", rows[r].path);
            return 2;
        }
    }
    free(xyz);
    printf("ingest benchmark: %zu points, best of 3, one thread\n", n);
    printf("%-20s %10s %14s %10s %14s %8s\n", "format", "sylva s", "sylva Mpt/s", "PCL s", "PCL Mpt/s", "ratio");
    for (size_t r = 0; r < n_rows; r++) {
        double t = time_sylva(rows[r].path, n);
        printf("%-20s %10.3f %14.1f", rows[r].name, t, t > 0 ? n / t / 1e6 : 0);
        double t_pcl = rows[r].pcl_load ? time_pcl(rows[r].pcl_load, rows[r].path) : -1;
        if (t_pcl > 0 && t > 0) printf(" %10.3f %14.1f %7.2fx\n", t_pcl, n / t_pcl / 1e6, t_pcl / t);
        else printf(" %10s %14s %8s\n", "-", "-", "-");
        remove(rows[r].path);
    }
    printf("ratio: sylva's speed over PCL's (loadPLYFile / loadPCDFile into PointXYZ)\n");
    return 0;
}
