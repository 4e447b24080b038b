/* Leaf maps: the multi-dipole model against its closed form, the HL2 basis,
 * a synthetic round trip (albedo, thickness, normals through segmentation,
 * orientation, registration and both thickness paths), the HL2
 * reconstruction error, energy conservation and clean masks on real photos. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/leafmaps/leafmaps.h"
#include "stages/leafmaps/leafmaps_cv.h"

#define PI 3.14159265358979323846

static double srgb(double v)
{
    v = v < 0 ? 0 : v > 1 ? 1 : v;
    return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
}

/* ----------------------------------------------------------- the model */

static void test_dipole_closed_form(void **state)
{
    (void)state;
    /* A = 2.790 (Jensen's F_dr at eta 1.33): rho_d = (A - 1) / (A + 1). */
    double rho = (2.790 - 1) / (2.790 + 1);
    sy_dipole m = sy_dipole_make(0.4, 10.2, 0.07, rho, 3);
    assert_true(fabs(m.sigma_tr - 3.444) < 1e-3);
    assert_true(fabs(m.l - 0.1012) < 1e-4);
    assert_true(fabs(sy_dipole_total(&m, 0.2) - 0.38268) < 0.001 * 0.38268);
    assert_true(fabs(sy_dipole_total(&m, 0.5) - 0.1339) < 0.001 * 0.1339 + 1e-4);
    /* Numeric radial integration of T matches the closed form. */
    for (double d = 0.15; d < 0.6; d += 0.15) {
        double s = 0, dr = 1e-4;
        for (double r = 0.5 * dr; r < 6; r += dr) s += sy_dipole_T(&m, r, d) * 2 * PI * r * dr;
        assert_true(fabs(s / sy_dipole_total(&m, d) - 1) < 1e-3);
    }
    /* Converged in n; monotone; decay tends to sigma_tr. */
    sy_dipole m10 = sy_dipole_make(0.4, 10.2, 0.07, rho, 10);
    assert_true(fabs(sy_dipole_total(&m, 0.2) - sy_dipole_total(&m10, 0.2)) / sy_dipole_total(&m10, 0.2) < 1e-4);
    for (double d = 0.13; d < 1.0; d += 0.01) assert_true(sy_dipole_total(&m, d + 0.01) < sy_dipole_total(&m, d));
    double slope = -(log(sy_dipole_total(&m, 1.001)) - log(sy_dipole_total(&m, 0.999))) / 0.002;
    assert_true(fabs(slope / m.sigma_tr - 1) < 0.01);
    /* Footprint-integrated weights keep the integral where point samples
     * over-count it (d = 0.15 mm, 0.1 mm texels). */
    int R = (int)ceil(sy_dipole_radius(&m, 0.15) / 0.1);
    float *w = malloc((size_t)(2 * R + 1) * (2 * R + 1) * sizeof *w);
    sy_dipole_kernel(&m, 0.15, 0.1, R, w);
    double sum = 0;
    for (int i = 0; i < (2 * R + 1) * (2 * R + 1); i++) {
        assert_true(w[i] >= 0);
        sum += w[i];
    }
    assert_true(fabs(sum / sy_dipole_total(&m, 0.15) - 1) < 0.01);
    /* Energy bound of the kernel for every valid thickness. */
    for (double d = 1.2 * m.l; d < 2; d += 0.05) assert_true(sy_dipole_total(&m, d) > 0 && sy_dipole_total(&m, d) < 1);
    /* Inversion. */
    assert_true(fabs(sy_dipole_invert(&m, sy_dipole_total(&m, 0.3), 0.12, 3) - 0.3) < 1e-6);
    free(w);
}

static void test_hl2_basis(void **state)
{
    (void)state;
    double H[3][3];
    sy_hl2_vectors(H);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = H[i][0] * H[j][0] + H[i][1] * H[j][1] + H[i][2] * H[j][2];
            assert_true(fabs(d - (i == j)) < 1e-12);
        }
    /* Orthonormal on the hemisphere: a 16k-direction quadrature. */
    int n = 16384;
    double *dirs = malloc((size_t)n * 3 * sizeof *dirs), *W = malloc((size_t)n * 3 * sizeof *W);
    sy_hl2_directions(n, 1, dirs);
    double G[3][3] = {{0}};
    for (int m = 0; m < n; m++) {
        assert_true(dirs[3 * m + 2] >= 0);
        assert_true(fabs(dirs[3 * m] * dirs[3 * m] + dirs[3 * m + 1] * dirs[3 * m + 1] + dirs[3 * m + 2] * dirs[3 * m + 2] - 1) < 1e-9);
        double b[3];
        sy_hl2_eval(dirs + 3 * m, b);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) G[i][j] += b[i] * b[j] * 2 * PI / n;
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) assert_true(fabs(G[i][j] - (i == j)) < 1e-3);
    free(dirs), free(W);
    /* 128 directions: the isotropic case (eq 3.22) and any linear function
     * project exactly; projection is idempotent. */
    n = 128;
    dirs = malloc((size_t)n * 3 * sizeof *dirs), W = malloc((size_t)n * 3 * sizeof *W);
    sy_hl2_directions(n, 7, dirs);
    assert_int_equal(sy_hl2_projection(dirs, n, W), 0);
    double h[3] = {0, 0, 0};
    for (int m = 0; m < n; m++)
        for (int i = 0; i < 3; i++) h[i] += W[(size_t)i * n + m] * dirs[3 * m + 2];
    for (int i = 0; i < 3; i++) assert_true(fabs(h[i] - sqrt(2 * PI) / 3) < 1e-9);
    double c[3] = {0.3, -0.2, 0.9};
    for (int i = 0; i < 3; i++) h[i] = 0;
    for (int m = 0; m < n; m++) {
        double f = c[0] * dirs[3 * m] + c[1] * dirs[3 * m + 1] + c[2] * dirs[3 * m + 2];
        for (int i = 0; i < 3; i++) h[i] += W[(size_t)i * n + m] * f;
    }
    for (int m = 0; m < n; m++) {
        double b[3], f = c[0] * dirs[3 * m] + c[1] * dirs[3 * m + 1] + c[2] * dirs[3 * m + 2];
        sy_hl2_eval(dirs + 3 * m, b);
        assert_true(fabs(h[0] * b[0] + h[1] * b[1] + h[2] * b[2] - f) < 1e-9);
    }
    free(dirs), free(W);
}

/* ------------------------------------------------------ the round trip */

typedef struct {
    sy_leaf_synthetic syn;
    sy_leaf_maps maps;
    sy_leafmaps_options o;
} fixture;

static float *to_map_frame(const sy_fimage *im, const sy_leaf_maps *m)
{
    float *out = calloc((size_t)m->w * m->h * im->c, sizeof *out);
    sy_error err;
    assert_int_equal(sy_lcv_warp(im->px, im->w, im->h, im->c, m->photo_from_map, out, m->w, m->h, 1, &err), SY_OK);
    return out;
}

static void build_fixture(fixture *f, int use_scans)
{
    sy_error err = {0};
    f->o = sy_leafmaps_options_default();
    f->o.size = 256;
    f->o.directions = 64;
    assert_int_equal(sy_leaf_synthesize(256, 3, 3.0, &f->o, &f->syn, &err), SY_OK);
    sy_leaf_capture cap;
    memset(&cap, 0, sizeof cap);
    for (int s = 0; s < 2; s++) {
        cap.side[s].reflected = &f->syn.reflected[s];
        cap.side[s].transmitted = &f->syn.transmitted[s];
        cap.side[s].flat_field = &f->syn.flat_field;
        cap.side[s].height = use_scans ? &f->syn.height[s] : NULL;
    }
    memcpy(cap.white_rect, f->syn.white_rect, sizeof cap.white_rect);
    cap.white_reflectance = f->syn.white_reflectance;
    f->o.texel_mm = f->syn.texel_mm;
    /* The calliper: the truth's median thickness. */
    size_t n = (size_t)f->syn.thickness.w * f->syn.thickness.h, k = 0;
    float *v = malloc(n * sizeof *v);
    for (size_t i = 0; i < n; i++)
        if (f->syn.alpha.px[i] >= 0.5f) v[k++] = f->syn.thickness.px[i];
    for (size_t i = 1; i < k; i++)
        for (size_t j = i; j > 0 && v[j - 1] > v[j]; j--) {
            float t = v[j];
            v[j] = v[j - 1], v[j - 1] = t;
        }
    f->o.thickness_mm = v[k / 2];
    free(v);
    int rc = sy_leafmaps_build(&cap, &f->o, &f->maps, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
}

static void free_fixture(fixture *f)
{
    sy_leaf_maps_free(&f->maps);
    sy_leaf_synthetic_free(&f->syn);
}

/* Interior texels: well inside the truth mask (the edge texels mix leaf and background). */
static unsigned char *interior(const sy_leaf_maps *m, const float *alpha_truth)
{
    int w = m->w;
    unsigned char *in = calloc((size_t)w * w, 1);
    for (int y = 2; y < w - 2; y++)
        for (int x = 2; x < w - 2; x++) {
            int ok = 1;
            for (int dy = -2; dy <= 2 && ok; dy++)
                for (int dx = -2; dx <= 2 && ok; dx++) ok = alpha_truth[(size_t)(y + dy) * w + x + dx] > 0.999f;
            in[(size_t)y * w + x] = (unsigned char)ok;
        }
    return in;
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void check_round_trip(fixture *f, int scans)
{
    sy_leaf_maps *m = &f->maps;
    size_t n = (size_t)m->w * m->h;
    float *alpha = to_map_frame(&f->syn.alpha, m);
    unsigned char *in = interior(m, alpha);
    size_t cnt = 0;
    for (size_t i = 0; i < n; i++) cnt += in[i];
    assert_true(cnt > n / 10);
    /* Albedo, both sides, in 8-bit sRGB steps. */
    for (int s = 0; s < 2; s++) {
        float *a = to_map_frame(&f->syn.albedo[s], m);
        double err = 0;
        for (size_t i = 0; i < n; i++)
            if (in[i])
                for (int c = 0; c < 3; c++) err += fabs(srgb(m->albedo[s][3 * i + c]) - srgb(a[3 * i + c])) * 255;
        err /= 3.0 * cnt;
        fprintf(stderr, "round trip (%s): albedo side %d mean error %.3f/255\n", scans ? "scans" : "transmission", s, err);
        assert_true(err <= 2.0);
        free(a);
    }
    /* Thickness. */
    float *d = to_map_frame(&f->syn.thickness, m);
    double rel = 0;
    for (size_t i = 0; i < n; i++)
        if (in[i]) rel += fabs(m->thickness[i] / d[i] - 1);
    rel /= cnt;
    fprintf(stderr, "round trip (%s): thickness mean relative error %.2f %%\n", scans ? "scans" : "transmission",
            100 * rel);
    assert_true(rel <= 0.05);
    free(d);
    /* Normals from the scans, both sides: the truth's heights, warped into
     * the map frame (the abaxial scan lives in the mirrored photo). */
    if (scans) {
        for (int s = 0; s < 2; s++) {
            float *tn = to_map_frame(&f->syn.normal[s], m);
            /* Truth normals are in the photo's tangent frame; the map frame is
             * rotated by the orientation: rotate their tangent part. */
            double ux = m->photo_from_map[0], uy = m->photo_from_map[3];
            double l = hypot(ux, uy);
            ux /= l, uy /= l; /* map +X in photo pixels (y down) */
            double *ang = malloc(cnt * sizeof *ang);
            size_t k = 0;
            for (size_t i = 0; i < n; i++) {
                if (!in[i]) continue;
                double px = tn[3 * i], py = -tn[3 * i + 1]; /* photo pixel axes */
                double tx = px * ux + py * uy, ty = -(-px * uy + py * ux);
                double tz = tn[3 * i + 2], tl = sqrt(tx * tx + ty * ty + tz * tz);
                const float *q = m->normal[s] + 3 * i;
                double dot = (tx * q[0] + ty * q[1] + tz * q[2]) / tl;
                ang[k++] = acos(dot > 1 ? 1 : dot) * 180 / PI;
            }
            qsort(ang, k, sizeof *ang, cmp_d);
            fprintf(stderr, "round trip: normal side %d median angle error %.2f deg\n", s, ang[k / 2]);
            assert_true(ang[k / 2] <= 5.0);
            free(ang), free(tn);
        }
    }
    free(alpha), free(in);
}

/* The scans capture is built once for the round trip and the HL2 checks. */
static fixture scans_fixture;
static int scans_built;

static fixture *scans(void)
{
    if (!scans_built) build_fixture(&scans_fixture, 1), scans_built = 1;
    return &scans_fixture;
}

static void test_round_trip_scans(void **state)
{
    (void)state;
    fixture *f = scans();
    assert_int_equal(f->maps.src_thickness, SY_LEAF_SRC_MEASURED);
    check_round_trip(f, 1);
}

static void test_round_trip_transmission(void **state)
{
    (void)state;
    fixture f;
    build_fixture(&f, 0);
    assert_int_equal(f.maps.src_thickness, SY_LEAF_SRC_MODEL);
    check_round_trip(&f, 0);
    /* Registration found the 3 px shift of the back-lit photos. */
    assert_true(f.maps.registration_shift[0] > 1.0);
    free_fixture(&f);
}

/* HL2 reconstruction against the per-direction convolution, and energy. */
static void test_hl2_reconstruction_energy(void **state)
{
    (void)state;
    fixture *fx = scans();
    sy_leaf_maps *m = &fx->maps;
    size_t n = (size_t)m->w * m->h;
    float *L = malloc(n * sizeof *L);
    sy_error err = {0};
    static const double elev[3] = {PI / 2, PI / 4, PI / 8};
    for (int s = 0; s < 2; s++) {
        double sum = 0;
        size_t cnt = 0;
        for (int e = 0; e < 3; e++)
            for (int a = 0; a < (e ? 8 : 1); a++) {
                double az = 2 * PI * a / 8 + 0.2;
                double w[3] = {cos(elev[e]) * cos(az), cos(elev[e]) * sin(az), sin(elev[e])};
                assert_int_equal(sy_leaf_transmit_direction(m, &fx->o, s, w, L, &err), SY_OK);
                double b[3];
                sy_hl2_eval(w, b);
                for (size_t i = 0; i < n; i++) {
                    if (m->alpha[i] < 0.5f || L[i] < 0.05 * m->transmit_normal[s] * w[2]) continue;
                    const float *h = m->hl2[s] + 3 * i;
                    double rec = m->hl2_scale[s][i] * (h[0] * b[0] + h[1] * b[1] + h[2] * b[2]);
                    sum += fabs(rec / L[i] - 1), cnt++;
                    /* Energy: reflected + transmitted <= incident (per unit
                     * irradiance w_z on the lit side). */
                    assert_true(m->albedo[s][3 * i + 1] + L[i] / w[2] <= 1.0 + 1e-6);
                }
            }
        fprintf(stderr, "HL2 reconstruction, lit side %d: mean relative error %.2f %%\n", s, 100 * sum / cnt);
        assert_true(sum / cnt <= 0.03);
    }
    /* Reflected + transmitted <= 1 for every texel and channel. */
    for (int s = 0; s < 2; s++)
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++) assert_true(m->albedo[1 - s][3 * i + c] + m->translucency[s][3 * i + c] <= 1.0f + 1e-6f);
    free(L);
}

/* --------------------------------------------------------- real photos */

static void check_real_mask(const char *name)
{
    float *px;
    int w, h, c, depth;
    sy_error err = {0};
    assert_int_equal(sy_lcv_read(data_path(name), &px, &w, &h, &c, &depth, &err), SY_OK);
    assert_int_equal(c, 4);
    sy_fimage im = {w, h, 4, px};
    sy_leafmaps_options o = sy_leafmaps_options_default();
    o.size = 256;
    o.directions = 3; /* masks only: the precompute's cost is not under test here */
    o.orient = 0;
    sy_leaf_capture cap;
    memset(&cap, 0, sizeof cap);
    cap.side[0].reflected = &im;
    sy_leaf_maps m;
    assert_int_equal(sy_leafmaps_build(&cap, &o, &m, &err), SY_OK);
    /* The photo's own alpha in the map frame is the truth. */
    sy_fimage a = {w, h, 1, malloc((size_t)w * h * sizeof(float))};
    for (size_t i = 0; i < (size_t)w * h; i++) a.px[i] = px[4 * i + 3];
    float *ta = to_map_frame(&a, &m);
    size_t both = 0, either = 0, extra = 0, inside = 0;
    for (size_t i = 0; i < (size_t)m.w * m.h; i++) {
        int p = m.alpha[i] >= 0.5f, t = ta[i] >= 0.5f;
        both += p && t, either += p || t, inside += p;
        /* Background inside our alpha: texels fully in it where the photo's
         * alpha says background (edge texels mix both after resampling). */
        extra += m.alpha[i] >= 0.9f && ta[i] < 0.1f;
    }
    double iou = (double)both / either;
    fprintf(stderr, "%s: mask IoU %.4f, background inside the alpha %.3f %%\n", name, iou, 100.0 * extra / inside);
    assert_true(iou >= 0.95);
    assert_true(extra <= inside / 1000);
    /* The same photo without alpha, over a uniform background: colour
     * segmentation finds the same leaf. */
    sy_fimage flat = {w, h, 3, malloc((size_t)w * h * 3 * sizeof(float))};
    for (size_t i = 0; i < (size_t)w * h; i++)
        for (int k = 0; k < 3; k++) {
            float al = px[4 * i + 3];
            flat.px[3 * i + k] = al * px[4 * i + k] + (1 - al) * 0.85f;
        }
    cap.side[0].reflected = &flat;
    sy_leaf_maps m2;
    assert_int_equal(sy_leafmaps_build(&cap, &o, &m2, &err), SY_OK);
    float *ta2 = to_map_frame(&a, &m2);
    both = either = 0;
    for (size_t i = 0; i < (size_t)m2.w * m2.h; i++) {
        int p = m2.alpha[i] >= 0.5f, t = ta2[i] >= 0.5f;
        both += p && t, either += p || t;
    }
    fprintf(stderr, "%s without alpha: mask IoU %.4f\n", name, (double)both / either);
    assert_true((double)both / either >= 0.90);
    sy_leaf_maps_free(&m);
    sy_leaf_maps_free(&m2);
    free(ta), free(ta2), free(a.px), free(flat.px), free(px);
}

static void test_real_masks(void **state)
{
    (void)state;
    check_real_mask("real/eztree/oak_leaf.png");
    check_real_mask("real/eztree/aspen_color.png");
    check_real_mask("real/eztree/ash_color.png");
}

/* --tint: the autumn aspen photo made a summer leaf. Over the leaf the
 * albedo's mean is the tint (in linear light, within rounding of the clamp at
 * 0.98), each texel keeps its luminance over the mean (veins and shading
 * stay), the mask is the photo's, and the translucency derived from the
 * albedo's hue turns green with it. A tint outside sRGB is refused. */
static double srgb_lin(double v)
{
    v /= 255;
    return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
}

static float luma(const float *rgb) { return 0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2]; }

static void test_tint(void **state)
{
    (void)state;
    float *px;
    int w, h, c, depth;
    sy_error err = {0};
    assert_int_equal(sy_lcv_read(data_path("real/eztree/aspen_color.png"), &px, &w, &h, &c, &depth, &err), SY_OK);
    sy_fimage im = {w, h, c, px};
    sy_leafmaps_options o = sy_leafmaps_options_default();
    o.size = 128;
    o.directions = 3;
    sy_leaf_capture cap;
    memset(&cap, 0, sizeof cap);
    cap.side[0].reflected = &im;
    sy_leaf_maps plain, tinted;
    assert_int_equal(sy_leafmaps_build(&cap, &o, &plain, &err), SY_OK);
    const double tint[3] = {96, 128, 52};
    memcpy(o.tint, tint, sizeof tint);
    assert_int_equal(sy_leafmaps_options_check(&o, &err), SY_OK);
    assert_int_equal(sy_leafmaps_build(&cap, &o, &tinted, &err), SY_OK);
    size_t n = (size_t)plain.w * plain.h, k = 0;
    double mean[3] = {0, 0, 0}, luma_p = 0, luma_t = 0, tr_plain[3] = {0, 0, 0}, tr_tint[3] = {0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        assert_true(plain.alpha[i] == tinted.alpha[i]);
        if (plain.alpha[i] < 0.5f) continue;
        k++;
        for (int ch = 0; ch < 3; ch++) {
            mean[ch] += tinted.albedo[0][3 * i + ch];
            tr_plain[ch] += plain.translucency[0][3 * i + ch], tr_tint[ch] += tinted.translucency[0][3 * i + ch];
        }
        luma_p += luma(plain.albedo[0] + 3 * i), luma_t += luma(tinted.albedo[0] + 3 * i);
    }
    assert_true(k > 1000);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(mean[ch] / (double)k - srgb_lin(tint[ch])) < 0.01);
    /* Luminance over the mean, texel by texel. */
    double worst = 0;
    for (size_t i = 0; i < n; i++) {
        if (plain.alpha[i] < 0.5f) continue;
        double a = luma(plain.albedo[0] + 3 * i) / (luma_p / (double)k);
        double b = luma(tinted.albedo[0] + 3 * i) / (luma_t / (double)k);
        if (luma(tinted.albedo[0] + 3 * i) < 0.97f && fabs(a - b) > worst) worst = fabs(a - b);
    }
    assert_true(worst < 1e-3);
    /* The photo is yellow (red over green), the tinted leaf green, and its
     * light through the leaf too. */
    assert_true(tr_plain[0] > tr_plain[1]);
    assert_true(tr_tint[1] > 1.2 * tr_tint[0] && tr_tint[1] > 1.2 * tr_tint[2]);
    o.tint[1] = 300;
    assert_int_equal(sy_leafmaps_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "tint"));
    sy_leaf_maps_free(&plain);
    sy_leaf_maps_free(&tinted);
    free(px);
}

static void test_bad_captures(void **state)
{
    (void)state;
    sy_leafmaps_options o = sy_leafmaps_options_default();
    o.size = 64;
    sy_leaf_capture cap;
    memset(&cap, 0, sizeof cap);
    sy_leaf_maps m;
    sy_error err = {0};
    assert_int_equal(sy_leafmaps_build(&cap, &o, &m, &err), SY_EINPUT);
    float one[3] = {0.5f, 0.5f, 0.5f};
    sy_fimage tiny = {1, 1, 3, one};
    cap.side[0].reflected = &tiny;
    assert_int_equal(sy_leafmaps_build(&cap, &o, &m, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "1x1"));
    sy_fimage bg;
    assert_int_equal(sy_fimage_alloc(&bg, 64, 64, 3, &err), SY_OK);
    for (size_t i = 0; i < 64 * 64 * 3; i++) bg.px[i] = 0.4f;
    cap.side[0].reflected = &bg;
    assert_int_equal(sy_leafmaps_build(&cap, &o, &m, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "background"));
    sy_fimage other;
    assert_int_equal(sy_fimage_alloc(&other, 32, 64, 3, &err), SY_OK);
    cap.side[0].transmitted = &other;
    assert_int_equal(sy_leafmaps_build(&cap, &o, &m, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "does not match"));
    o.thickness_mm = 0.05;
    assert_int_equal(sy_leafmaps_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "thickness_mm"));
    sy_fimage_free(&bg), sy_fimage_free(&other);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_dipole_closed_form),
        cmocka_unit_test(test_hl2_basis),
        cmocka_unit_test(test_round_trip_scans),
        cmocka_unit_test(test_round_trip_transmission),
        cmocka_unit_test(test_hl2_reconstruction_energy),
        cmocka_unit_test(test_real_masks),
        cmocka_unit_test(test_tint),
        cmocka_unit_test(test_bad_captures),
    };
    int failed = cmocka_run_group_tests(tests, NULL, NULL);
    if (scans_built) free_fixture(&scans_fixture);
    return failed;
}
