/* COLMAP reader: the hand-written text model and its binary twin
 * (tests/data/colmap/README.md lists the values), workspace layouts, and
 * malformed models. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "stages/core/fileio.h"
#include "stages/ingest/ingest.h"

static const char *fixture(const char *rel)
{
    static char buf[4][4096];
    static int next;
    char *b = buf[next++ & 3];
    snprintf(b, 4096, "%s/tests/data/colmap/%s", SYLVA_SOURCE_DIR, rel);
    return b;
}

#define assert_near(a, b, tol) near_or_fail((a), (b), (tol), #a, __FILE__, __LINE__)
static void near_or_fail(double a, double b, double tol, const char *what, const char *file, int line)
{
    if (fabs(a - b) <= tol) return;
    print_error("%s = %.17g, want %.17g +- %g\n", what, a, b, tol);
    _fail(file, line);
}

static void assert_input_error(sy_code rc, const sy_error *err, const char *needle1, const char *needle2)
{
    assert_int_equal(rc, SY_EINPUT);
    if (!strstr(err->msg, needle1) || !strstr(err->msg, needle2) || strchr(err->msg, '\n'))
        fail_msg("unexpected message: '%s' (want '%s' and '%s')", err->msg, needle1, needle2);
}

/* The 20 points every faithful reading of the fixture model yields. */
static void check_model_points(const sy_cloud *c)
{
    assert_int_equal(c->n, 20);
    assert_non_null(c->rgb);
    const double *error = sy_cloud_attr(c, "error"), *track = sy_cloud_attr(c, "track_length");
    assert_non_null(error);
    assert_non_null(track);
    double observations = 0;
    for (size_t i = 0; i < 20; i++) {
        double k = (double)(i + 1);
        assert_near(c->origin[0] + c->xyz[3 * i + 0], -2.5 + 0.25 * k, 1e-6);
        assert_near(c->origin[1] + c->xyz[3 * i + 1], 1.0 + 0.125 * k, 1e-6);
        assert_near(c->origin[2] + c->xyz[3 * i + 2], 0.5 * k - 3.0, 1e-6);
        assert_int_equal(c->rgb[3 * i + 0], (12 * (i + 1)) % 256 * 257);
        assert_int_equal(c->rgb[3 * i + 1], (255 - 11 * (i + 1)) * 257);
        assert_int_equal(c->rgb[3 * i + 2], (60 + 5 * (i + 1)) * 257);
        assert_near(error[i], 0.05 * k, 1e-12);
        assert_near(track[i], (i + 1) % 5 == 0 ? 3 : 2, 0);
        observations += track[i];
    }
    assert_near(observations, 44, 0);
}

static void text_and_binary_models_agree(void **state)
{
    (void)state;
    sy_cloud t, b;
    sy_error err = {0};
    assert_int_equal(sy_read_colmap_dir(fixture("text"), &t, &err), SY_OK);
    assert_int_equal(sy_read_colmap_dir(fixture("bin"), &b, &err), SY_OK);
    check_model_points(&t);
    check_model_points(&b);
    assert_string_equal(t.meta.format, "COLMAP");
    assert_string_equal(t.meta.version, "sparse text");
    assert_string_equal(b.meta.version, "sparse binary");
    const char *summary = "2 cameras, 3 images\ncamera models: SIMPLE_PINHOLE x1, OPENCV x1";
    assert_string_equal(t.meta.vlr_summary, summary);
    assert_string_equal(b.meta.vlr_summary, summary);
    /* Identical clouds, bit for bit. */
    assert_memory_equal(t.origin, b.origin, sizeof t.origin);
    assert_memory_equal(t.xyz, b.xyz, 3 * 20 * sizeof(float));
    assert_memory_equal(t.rgb, b.rgb, 3 * 20 * sizeof(uint16_t));
    assert_int_equal(t.n_attrs, b.n_attrs);
    for (size_t a = 0; a < t.n_attrs; a++) {
        assert_string_equal(t.attrs[a].name, b.attrs[a].name);
        assert_memory_equal(t.attrs[a].values, b.attrs[a].values, 20 * sizeof(double));
    }
    sy_cloud_free(&t);
    sy_cloud_free(&b);
}

static void points_files_alone(void **state)
{
    (void)state;
    const char *files[] = {"text/points3D.txt", "bin/points3D.bin"};
    for (int i = 0; i < 2; i++) {
        sy_cloud c;
        sy_error err = {0};
        /* Through the dispatch (by name/extension), and straight from memory. */
        assert_int_equal(sy_read_cloud(fixture(files[i]), &c, &err), SY_OK);
        check_model_points(&c);
        assert_null(c.meta.vlr_summary);
        sy_cloud_free(&c);
        sy_buffer buf;
        assert_int_equal(sy_read_file(fixture(files[i]), &buf, &err), SY_OK);
        assert_int_equal(sy_read_colmap_points_mem("p", buf.data, buf.size, i ? 'b' : 't', &c, &err), SY_OK);
        check_model_points(&c);
        sy_cloud_free(&c);
        sy_buffer_free(&buf);
    }
}

/* ---- workspaces built in the temp dir ------------------------------------ */

static const char *mkdirs(const char *rel)
{
    const char *path = tmp_path(rel);
    char cmd[4300];
    snprintf(cmd, sizeof cmd, "mkdir -p '%s'", path);
    assert_int_equal(system(cmd), 0);
    return path;
}

/* Copies fixture files (kind "text" or "bin") into dir, optionally replacing
 * the first occurrence of old by new in the file named target. */
static void copy_model(const char *dir, const char *kind, const char *target, const void *old, size_t old_len,
                       const void *new, size_t new_len)
{
    static const char *stems[] = {"cameras", "images", "points3D"};
    for (int i = 0; i < 3; i++) {
        char name[64], src[4200], dst[4200];
        snprintf(name, sizeof name, "%s.%s", stems[i], strcmp(kind, "bin") ? "txt" : "bin");
        snprintf(src, sizeof src, "%s/%s", fixture(kind), name);
        snprintf(dst, sizeof dst, "%s/%s", dir, name);
        sy_buffer b;
        sy_error err = {0};
        assert_int_equal(sy_read_file(src, &b, &err), SY_OK);
        size_t size = b.size, at = 0;
        if (target && strcmp(target, name) == 0) {
            int found = 0;
            for (size_t k = 0; k + old_len <= b.size && !found; k++)
                if (memcmp(b.data + k, old, old_len) == 0) at = k, found = 1;
            assert_true(found);
            unsigned char *d = malloc(b.size + new_len);
            memcpy(d, b.data, at);
            memcpy(d + at, new, new_len);
            memcpy(d + at + new_len, b.data + at + old_len, b.size - at - old_len);
            size = b.size - old_len + new_len;
            assert_int_equal(write_bytes(dst, d, size), 0);
            free(d);
        } else {
            assert_int_equal(write_bytes(dst, b.data, size), 0);
        }
        sy_buffer_free(&b);
    }
}

static void copy_plain(const char *dir, const char *kind) { copy_model(dir, kind, NULL, NULL, 0, NULL, 0); }

static void workspace_layouts(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    /* ws/sparse/0 (binary), through sy_read_cloud's directory dispatch. */
    copy_plain(mkdirs("ws1/sparse/0"), "bin");
    assert_int_equal(sy_read_cloud(tmp_path("ws1"), &c, &err), SY_OK);
    check_model_points(&c);
    assert_string_equal(c.meta.version, "sparse binary");
    sy_cloud_free(&c);
    /* ws/sparse (text). */
    copy_plain(mkdirs("ws2/sparse"), "text");
    assert_int_equal(sy_read_cloud(tmp_path("ws2"), &c, &err), SY_OK);
    check_model_points(&c);
    assert_string_equal(c.meta.version, "sparse text");
    sy_cloud_free(&c);
    /* Model files directly in the directory, both kinds: binary wins. */
    const char *ws3 = mkdirs("ws3");
    copy_plain(ws3, "text");
    copy_plain(ws3, "bin");
    assert_int_equal(sy_read_cloud(ws3, &c, &err), SY_OK);
    assert_string_equal(c.meta.version, "sparse binary");
    sy_cloud_free(&c);
    /* sparse/0 is preferred over a stray model higher up. */
    copy_plain(mkdirs("ws1"), "text");
    assert_int_equal(sy_read_cloud(tmp_path("ws1"), &c, &err), SY_OK);
    assert_string_equal(c.meta.version, "sparse binary");
    sy_cloud_free(&c);
    /* Neither a model nor a fused cloud. */
    const char *empty = mkdirs("ws_empty");
    assert_input_error(sy_read_cloud(empty, &c, &err), &err, empty, "not a COLMAP workspace");
}

/* Only dense/fused.ply: read through the PLY reader. That reader lands on
 * another branch, so either a COLMAP "fused PLY" cloud or an error naming the
 * PLY file is acceptable here; never a crash or a wrong label. */
static void fused_ply_fallback(void **state)
{
    (void)state;
    const char *dir = mkdirs("ws_dense/dense/0");
    char ply[4200];
    snprintf(ply, sizeof ply, "%s/fused.ply", dir);
    const char *text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                       "property float z\nend_header\n1 2 3\n4 5 6\n";
    assert_int_equal(write_bytes(ply, text, strlen(text)), 0);
    sy_cloud c;
    sy_error err = {0};
    sy_code rc = sy_read_cloud(tmp_path("ws_dense"), &c, &err);
    if (rc == SY_OK) {
        assert_string_equal(c.meta.format, "COLMAP");
        assert_string_equal(c.meta.version, "fused PLY");
        assert_int_equal(c.n, 2);
        sy_cloud_free(&c);
    } else if (!strstr(err.msg, "fused.ply")) {
        fail_msg("error does not name the PLY: %s", err.msg);
    }
}

/* ---- malformed models ------------------------------------------------------ */

static void expect_dir_error(const char *rel, const char *needle1, const char *needle2)
{
    sy_cloud c;
    sy_error err = {0};
    assert_input_error(sy_read_colmap_dir(tmp_path(rel), &c, &err), &err, needle1, needle2);
    assert_null(c.xyz);
}

static void missing_and_truncated_files(void **state)
{
    (void)state;
    const char *dir = mkdirs("bad_missing");
    copy_plain(dir, "text");
    char path[4200];
    snprintf(path, sizeof path, "%s/points3D.txt", dir);
    assert_int_equal(remove(path), 0);
    expect_dir_error("bad_missing", "bad_missing", "lacks points3D.bin or points3D.txt");

    /* points3D.bin cut inside its last point. */
    dir = mkdirs("bad_cut");
    copy_plain(dir, "bin");
    snprintf(path, sizeof path, "%s/points3D.bin", dir);
    sy_buffer b;
    sy_error err = {0};
    assert_int_equal(sy_read_file(path, &b, &err), SY_OK);
    assert_int_equal(write_bytes(path, b.data, b.size - 5), 0);
    expect_dir_error("bad_cut", "points3D.bin", "truncated");

    /* A point count far beyond the bytes present is refused before allocation. */
    unsigned char huge[8] = {0, 0, 0, 0, 0, 1, 0, 0}; /* 2^40 points */
    memcpy(b.data, huge, 8);
    assert_int_equal(write_bytes(path, b.data, b.size), 0);
    expect_dir_error("bad_cut", "points3D.bin", "do not fit");
    sy_buffer_free(&b);

    /* images.bin: count 1, cut right before the NUL ending the first name. */
    dir = mkdirs("bad_images");
    copy_plain(dir, "bin");
    snprintf(path, sizeof path, "%s/images.bin", dir);
    assert_int_equal(sy_read_file(path, &b, &err), SY_OK);
    b.data[0] = 1;
    assert_int_equal(b.data[8 + 64 + strlen("IMG_0001.jpg")], 0);
    assert_int_equal(write_bytes(path, b.data, 8 + 64 + strlen("IMG_0001.jpg")), 0);
    sy_buffer_free(&b);
    expect_dir_error("bad_images", "images.bin", "truncated in image name 0");
}

static void bad_binary_records(void **state)
{
    (void)state;
    /* Camera 1's model id (0, SIMPLE_PINHOLE) follows its 4-byte id. */
    const unsigned char id_and_model[8] = {1, 0, 0, 0, 0, 0, 0, 0};
    const unsigned char bad_model[8] = {1, 0, 0, 0, 42, 0, 0, 0};
    copy_model(mkdirs("bad_model"), "bin", "cameras.bin", id_and_model, 8, bad_model, 8);
    expect_dir_error("bad_model", "cameras.bin", "unknown camera model id 42");
}

static void bad_text_lines(void **state)
{
    (void)state;
    static const struct {
        const char *dir, *file, *old, *new, *needle;
    } cases[] = {
        {"t_value", "points3D.txt", "105 -1.25", "105 -1.2x5", "points3D.txt: line 8: bad point id"},
        {"t_track", "points3D.txt", "0.05 2 0 3 1", "0.05 2 0 3", "line 4: track has an odd number"},
        {"t_image", "points3D.txt", "0.05 2 0 3 1", "0.05 9 0 3 1", "line 4: track refers to image 9"},
        {"t_model", "cameras.txt", "SIMPLE_PINHOLE", "FISHEYE9", "cameras.txt: line 4: unknown camera model 'FISHEYE9'"},
        {"t_params", "cameras.txt", "500 320 240", "500 320", "line 4: SIMPLE_PINHOLE takes 3 parameters, found 2"},
        {"t_camera", "images.txt", "0 0 0 1 IMG_0001", "0 0 0 7 IMG_0001", "images.txt: line 5: image 1 uses camera 7"},
        {"t_dup_camera", "cameras.txt", "2 OPENCV", "1 OPENCV", "cameras.txt: duplicate camera id 1"},
        {"t_2d", "images.txt", "80.25 120\n2 ", "80.25 120 7\n2 ", "images.txt: line 6: 43 values"},
        {"t_short", "images.txt", " 1 IMG_0001.jpg", "", "images.txt: line 5: want IMAGE_ID"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        copy_model(mkdirs(cases[i].dir), "text", cases[i].file, cases[i].old, strlen(cases[i].old), cases[i].new,
                   strlen(cases[i].new));
        expect_dir_error(cases[i].dir, cases[i].dir, cases[i].needle);
    }
}

/* A model from memory, as the fuzz targets drive it: cameras listed out of
 * id order (the reader sorts them for lookup) and one camera per image, the
 * layout whose linear lookups once took seconds at 100k cameras. */
static void model_from_memory_with_many_cameras(void **state)
{
    (void)state;
    enum { N = 20000 };
    size_t cap = (size_t)N * 64;
    char *cams = malloc(cap), *imgs = malloc(cap);
    assert_non_null(cams);
    assert_non_null(imgs);
    size_t nc = 0, ni = 0;
    for (int i = N; i >= 1; i--) nc += (size_t)snprintf(cams + nc, cap - nc, "%d PINHOLE 640 480 500 500 320 240\n", i);
    for (int i = 1; i <= N; i++) ni += (size_t)snprintf(imgs + ni, cap - ni, "%d 1 0 0 0 0 0 0 %d im%d.jpg\n\n", i, i, i);
    static const char points[] = "7 1.5 2.5 3.5 10 20 30 0.5 1 0 20000 4\n";
    sy_colmap_file cf = {"cameras.txt", (const unsigned char *)cams, nc, 0};
    sy_colmap_file imf = {"images.txt", (const unsigned char *)imgs, ni, 0};
    sy_colmap_file pf = {"points3D.txt", (const unsigned char *)points, sizeof points - 1, 0};
    sy_cloud c;
    sy_error err = {0};
    if (sy_read_colmap_model_mem(&cf, &imf, &pf, &c, &err)) fail_msg("%s", err.msg);
    assert_int_equal(c.n, 1);
    assert_non_null(strstr(c.meta.vlr_summary, "20000 cameras, 20000 images"));
    assert_near(c.origin[2] + c.xyz[2], 3.5, 1e-6);
    sy_cloud_free(&c);
    /* An image naming a camera the (sorted) list lacks is still caught. */
    ni = (size_t)snprintf(imgs, cap, "5 1 0 0 0 0 0 0 %d im.jpg\n\n", N + 1);
    imf.size = ni;
    assert_input_error(sy_read_colmap_model_mem(&cf, &imf, &pf, &c, &err), &err, "images.txt",
                       "image 5 uses camera 20001");
    free(cams);
    free(imgs);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(text_and_binary_models_agree),
        cmocka_unit_test(points_files_alone),
        cmocka_unit_test(workspace_layouts),
        cmocka_unit_test(fused_ply_fallback),
        cmocka_unit_test(missing_and_truncated_files),
        cmocka_unit_test(bad_binary_records),
        cmocka_unit_test(bad_text_lines),
        cmocka_unit_test(model_from_memory_with_many_cameras),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
