/* Species materials: normal maps from luminance, PNG round trips, the
 * leaf material's alpha mask, double-sidedness and transmission. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <stb_image.h>
#include <stb_image_write.h>

#include "species/image_cv.h"
#include "species/materials.h"

static unsigned char *gray_rgba(int w, int h, int (*value)(int x, int y))
{
    unsigned char *p = malloc((size_t)w * (size_t)h * 4);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            unsigned char *q = p + 4 * ((size_t)y * (size_t)w + (size_t)x);
            q[0] = q[1] = q[2] = (unsigned char)value(x, y);
            q[3] = 255;
        }
    return p;
}

static int flat(int x, int y)
{
    (void)x;
    (void)y;
    return 140;
}
static int ramp_right(int x, int y)
{
    (void)y;
    return 40 + 5 * x;
}
static int ramp_down(int x, int y)
{
    (void)x;
    return 40 + 5 * y;
}

static void flat_image_gives_straight_up_normals(void **state)
{
    (void)state;
    const int w = 24, h = 16;
    unsigned char *img = gray_rgba(w, h, flat), rgb[24 * 16 * 3];
    for (int wrap = 0; wrap <= 1; wrap++) {
        assert_int_equal(sy_cv_normal_map(img, w, h, 5.0f, wrap, rgb, NULL), SY_OK);
        for (int i = 0; i < w * h; i++) {
            /* (0.5, 0.5, 1) within 1/255 */
            assert_true(abs(2 * rgb[3 * i] - 255) <= 2);
            assert_true(abs(2 * rgb[3 * i + 1] - 255) <= 2);
            assert_true(rgb[3 * i + 2] >= 254);
        }
    }
    free(img);
}

static void ramps_tilt_the_normal_downhill(void **state)
{
    (void)state;
    const int w = 32, h = 32;
    unsigned char rgb[32 * 32 * 3];
    /* Slope 5/255 per texel at strength 4: n = (-0.0784, 0, 1) normalized. */
    const double s = 4.0 * 5.0 / 255.0;
    const int tilted = (int)((0.5 - 0.5 * s / sqrt(1 + s * s)) * 255.0 + 0.5);
    assert_true(tilted < 120);
    /* Brighter (higher) to the right: the normal leans left, -X, red < 0.5. */
    unsigned char *img = gray_rgba(w, h, ramp_right);
    assert_int_equal(sy_cv_normal_map(img, w, h, 4.0f, 0, rgb, NULL), SY_OK);
    for (int y = 1; y < h - 1; y++)
        for (int x = 1; x < w - 1; x++) {
            const unsigned char *n = rgb + 3 * (y * w + x);
            assert_true(abs(n[0] - tilted) <= 2);
            assert_true(abs(2 * n[1] - 255) <= 2);
            assert_true(n[2] > 128);
        }
    free(img);
    /* Brighter toward the bottom row, i.e. lower toward the image top:
     * the normal leans up the image, +Y in glTF's convention, green > 0.5. */
    img = gray_rgba(w, h, ramp_down);
    assert_int_equal(sy_cv_normal_map(img, w, h, 4.0f, 0, rgb, NULL), SY_OK);
    for (int y = 1; y < h - 1; y++)
        for (int x = 1; x < w - 1; x++) {
            const unsigned char *n = rgb + 3 * (y * w + x);
            assert_true(abs(n[1] - (255 - tilted)) <= 2);
            assert_true(abs(2 * n[0] - 255) <= 2);
        }
    /* A stronger relief tilts further. */
    unsigned char strong[32 * 32 * 3];
    assert_int_equal(sy_cv_normal_map(img, w, h, 8.0f, 0, strong, NULL), SY_OK);
    assert_true(strong[3 * (16 * w + 16) + 1] > rgb[3 * (16 * w + 16) + 1]);
    free(img);
}

static unsigned char *decode(const sy_image *im, int *w, int *h, int *comp)
{
    unsigned char *p = stbi_load_from_memory(im->png, (int)im->size, w, h, comp, 0);
    assert_non_null(p);
    return p;
}

static const sy_image *image_named(const sy_asset *a, const char *name)
{
    for (size_t i = 0; i < a->n_images; i++)
        if (strcmp(a->images[i].name, name) == 0) return &a->images[i];
    fail_msg("no image %s", name);
    return NULL;
}

static void library_textures_become_materials(void **state)
{
    (void)state;
    sy_material_spec spec = {SYLVA_SPECIES_DIR "/textures/bark.png", SYLVA_SPECIES_DIR "/textures/ash_color.png",
                             0.45f, 128, NULL, 0, NULL, NULL};
    sy_asset asset;
    memset(&asset, 0, sizeof asset);
    sy_error err = {0};
    int bark = -1, leaf = -1;
    assert_int_equal(sy_materials_add(&spec, &asset, &bark, &leaf, &err), SY_OK);
    assert_int_equal(asset.n_materials, 2);
    assert_int_equal(asset.n_images, 4);
    int w, h, comp;
    unsigned char *px = decode(image_named(&asset, "bark_color"), &w, &h, &comp);
    assert_int_equal(w, 128);
    assert_int_equal(h, 128);
    assert_int_equal(comp, 3);
    free(px);
    px = decode(image_named(&asset, "bark_normal"), &w, &h, &comp);
    assert_int_equal(w, 128);
    assert_int_equal(comp, 3);
    /* Bark relief: the normals vary and on average point out of the surface. */
    long blue = 0, red_lo = 255, red_hi = 0;
    for (int i = 0; i < w * h; i++) {
        blue += px[3 * i + 2];
        if (px[3 * i] < red_lo) red_lo = px[3 * i];
        if (px[3 * i] > red_hi) red_hi = px[3 * i];
    }
    assert_true(blue / (w * h) > 200);
    assert_true(red_hi - red_lo > 40);
    free(px);
    px = decode(image_named(&asset, "leaf_color"), &w, &h, &comp);
    assert_int_equal(w, 128);
    assert_int_equal(h, 128);
    assert_int_equal(comp, 4);
    int opaque = 0, clear = 0;
    for (int i = 0; i < w * h; i++) {
        if (px[4 * i + 3] >= 128) opaque++;
        if (px[4 * i + 3] == 0) clear++;
    }
    assert_true(opaque > w * h / 20 && clear > w * h / 5); /* a twig card: both present */
    free(px);

    const sy_material *bm = &asset.materials[bark], *lm = &asset.materials[leaf];
    assert_int_equal(bm->alpha_mode, SY_ALPHA_OPAQUE);
    assert_true(bm->base_color_image >= 0 && bm->normal_image >= 0);
    assert_int_equal(lm->alpha_mode, SY_ALPHA_MASK);
    assert_float_equal(lm->alpha_cutoff, 0.5f, 0);
    assert_true(lm->double_sided);
    assert_float_equal(lm->diffuse_transmission, 0.45f, 1e-6f);
    const float *tc = lm->diffuse_transmission_color;
    assert_float_equal(tc[1], 1.0f, 1e-6f); /* green leaves: green is the largest channel */
    assert_true(tc[0] < 1.0f && tc[2] < 1.0f && tc[2] >= 0.0f);
    assert_true(lm->base_color_image >= 0 && lm->normal_image >= 0);
    assert_string_equal(asset.images[lm->base_color_image].name, "leaf_color");
    /* The fallback for engines without KHR_materials_diffuse_transmission:
     * a glow of 0.3 x the translucency (docs/gltf.md); bark has none. */
    for (int c = 0; c < 3; c++) {
        assert_float_equal(lm->emissive[c], 0.3f * 0.45f, 1e-6f);
        assert_float_equal(bm->emissive[c], 0.0f, 0);
    }
    sy_asset_free(&asset);
}

/* A species' bark colour: the photo recoloured to that mean, its pattern
 * (each texel's brightness over the mean) and its normal map kept. */
static void bark_takes_the_species_colour(void **state)
{
    (void)state;
    static const float birch[3] = {226, 222, 212};
    sy_material_spec plain = {SYLVA_SPECIES_DIR "/textures/bark.png", NULL, 0.4f, 64, NULL, 0, NULL, NULL};
    sy_material_spec white = plain;
    white.bark_color = birch;
    sy_asset a, b;
    memset(&a, 0, sizeof a), memset(&b, 0, sizeof b);
    sy_error err = {0};
    int bark, leaf;
    assert_int_equal(sy_materials_add(&plain, &a, &bark, &leaf, &err), SY_OK);
    assert_int_equal(sy_materials_add(&white, &b, &bark, &leaf, &err), SY_OK);
    int w, h, comp, w2, h2, comp2;
    unsigned char *p = decode(image_named(&a, "bark_color"), &w, &h, &comp);
    unsigned char *q = decode(image_named(&b, "bark_color"), &w2, &h2, &comp2);
    assert_int_equal(w * h, w2 * h2);
    double mean[3] = {0, 0, 0}, sp = 0, sq = 0, spp = 0, sqq = 0, spq = 0;
    int n = w * h;
    for (int i = 0; i < n; i++) {
        for (int c = 0; c < 3; c++) mean[c] += q[3 * i + c];
        double lp = 0.2126 * p[3 * i] + 0.7152 * p[3 * i + 1] + 0.0722 * p[3 * i + 2];
        double lq = 0.2126 * q[3 * i] + 0.7152 * q[3 * i + 1] + 0.0722 * q[3 * i + 2];
        sp += lp, sq += lq, spp += lp * lp, sqq += lq * lq, spq += lp * lq;
    }
    /* Bright texels clip at 255, so the mean may fall a little short. */
    for (int c = 0; c < 3; c++) assert_true(fabs(mean[c] / n - birch[c]) < 8);
    double r = (n * spq - sp * sq) / sqrt((n * spp - sp * sp) * (n * sqq - sq * sq));
    assert_true(r > 0.97);
    free(p), free(q);
    const sy_image *na = image_named(&a, "bark_normal"), *nb = image_named(&b, "bark_normal");
    assert_int_equal(na->size, nb->size);
    assert_memory_equal(na->png, nb->png, na->size);
    sy_asset_free(&a), sy_asset_free(&b);
}

static void cards_keep_a_power_of_two_aspect(void **state)
{
    (void)state;
    /* oak_leaf.png is 171 x 256: the long side becomes 128, the short side
     * the nearest power of two to 85.5, 64. */
    sy_material_spec spec = {NULL, SYLVA_SPECIES_DIR "/textures/oak_leaf.png", 0.3f, 128, NULL, 0, NULL, NULL};
    sy_asset asset;
    memset(&asset, 0, sizeof asset);
    sy_error err = {0};
    int bark, leaf;
    assert_int_equal(sy_materials_add(&spec, &asset, &bark, &leaf, &err), SY_OK);
    int w, h, comp;
    unsigned char *px = decode(image_named(&asset, "leaf_normal"), &w, &h, &comp);
    assert_int_equal(w, 64);
    assert_int_equal(h, 128);
    free(px);
    sy_asset_free(&asset);
}

static void procedural_fallbacks_are_deterministic(void **state)
{
    (void)state;
    sy_material_spec spec = {NULL, NULL, 0.4f, 64, NULL, 0, NULL, NULL};
    sy_asset a, b;
    memset(&a, 0, sizeof a);
    memset(&b, 0, sizeof b);
    sy_error err = {0};
    int bark, leaf;
    assert_int_equal(sy_materials_add(&spec, &a, &bark, &leaf, &err), SY_OK);
    assert_int_equal(sy_materials_add(&spec, &b, &bark, &leaf, &err), SY_OK);
    assert_int_equal(a.n_images, 4);
    for (size_t i = 0; i < a.n_images; i++) {
        assert_int_equal(a.images[i].size, b.images[i].size);
        assert_memory_equal(a.images[i].png, b.images[i].png, a.images[i].size);
    }
    int w, h, comp;
    unsigned char *px = decode(image_named(&a, "bark_color"), &w, &h, &comp);
    assert_int_equal(w, 64);
    assert_int_equal(h, 64);
    int lo = 255, hi = 0;
    for (int i = 0; i < w * h; i++) {
        lo = px[3 * i] < lo ? px[3 * i] : lo;
        hi = px[3 * i] > hi ? px[3 * i] : hi;
    }
    assert_true(hi - lo > 20); /* real texture, not a flat fill */
    free(px);
    px = decode(image_named(&a, "leaf_color"), &w, &h, &comp);
    assert_int_equal(comp, 4);
    assert_int_equal(w, 32);
    assert_int_equal(h, 64);
    assert_int_equal(px[3], 0);                         /* corner: outside the blade */
    assert_int_equal(px[4 * (32 * w + 16) + 3], 255);   /* centre: inside */
    free(px);
    assert_int_equal(a.materials[leaf].alpha_mode, SY_ALPHA_MASK);
    assert_float_equal(a.materials[leaf].diffuse_transmission, 0.4f, 1e-6f);
    sy_asset_free(&a);
    sy_asset_free(&b);
}

static void leaf_without_alpha_is_cut_from_its_background(void **state)
{
    (void)state;
    const int n = 64;
    unsigned char rgb[64 * 64 * 3];
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++) {
            int in = (x - 32) * (x - 32) + (y - 32) * (y - 32) < 20 * 20;
            unsigned char *p = rgb + 3 * (y * n + x);
            p[0] = in ? 50 : 250;
            p[1] = in ? 140 : 250;
            p[2] = in ? 40 : 245;
        }
    const char *path = tmp_path("leaf_rgb.png");
    assert_int_equal(stbi_write_png(path, n, n, 3, rgb, n * 3) != 0, 1);
    sy_material_spec spec = {NULL, path, 0.5f, 64, NULL, 0, NULL, NULL};
    sy_asset asset;
    memset(&asset, 0, sizeof asset);
    sy_error err = {0};
    int bark, leaf;
    assert_int_equal(sy_materials_add(&spec, &asset, &bark, &leaf, &err), SY_OK);
    int w, h, comp;
    unsigned char *px = decode(image_named(&asset, "leaf_color"), &w, &h, &comp);
    assert_int_equal(comp, 4);
    assert_int_equal(px[4 * (32 * w + 32) + 3], 255);
    assert_int_equal(px[4 * (2 * w + 2) + 3], 0);
    assert_int_equal(px[4 * (32 * w + 60) + 3], 0);
    free(px);
    sy_asset_free(&asset);
}

static void unreadable_images_are_input_errors(void **state)
{
    (void)state;
    sy_material_spec spec = {"/nonexistent/bark.png", NULL, 0.4f, 64, NULL, 0, NULL, NULL};
    sy_asset asset;
    memset(&asset, 0, sizeof asset);
    sy_error err = {0};
    int bark, leaf;
    assert_int_equal(sy_materials_add(&spec, &asset, &bark, &leaf, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "/nonexistent/bark.png"));
    const char *junk = tmp_path("junk.png");
    assert_int_equal(write_bytes(junk, "\x89PNG\r\n\x1a\nnot really", 18), 0);
    spec.bark_image = NULL;
    spec.leaf_image = junk;
    assert_int_equal(sy_materials_add(&spec, &asset, &bark, &leaf, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "junk.png"));
    spec.leaf_image = NULL;
    spec.leaf_translucency = 2;
    assert_int_equal(sy_materials_add(&spec, &asset, &bark, &leaf, &err), SY_EINPUT);
    sy_asset_free(&asset);
}

/* A species' leaf maps from `sylva leaf`: every slot is filled, and the
 * base colour is the measured albedo, and the KHR split conserves energy:
 * (1 - f) baseColor + f colour <= 1. */
static void leaf_maps_become_the_leaf_material(void **state)
{
    (void)state;
    const char *lm = SYLVA_SPECIES_DIR "/leafmaps/quaking_aspen/leaf.material";
    sy_material_spec spec = {NULL, NULL, -1.0f, 128, lm, 0.3f, NULL, NULL};
    sy_asset asset;
    memset(&asset, 0, sizeof asset);
    sy_error err = {0};
    int bark = -1, leaf = -1;
    assert_int_equal(sy_materials_add(&spec, &asset, &bark, &leaf, &err), SY_OK);
    const sy_material *m = &asset.materials[leaf];
    assert_true(m->base_color_image >= 0 && m->normal_image >= 0 && m->diffuse_transmission_image >= 0);
    assert_true(m->thickness_image >= 0 && m->thickness_factor > 0);
    assert_true(m->hl2_image[0] >= 0 && m->hl2_image[1] >= 0);
    assert_true(m->double_sided && m->alpha_mode == SY_ALPHA_MASK);
    int w, h, c, w2, h2, c2, w3, h3, c3;
    const sy_image *bi = &asset.images[m->base_color_image], *ti = &asset.images[m->diffuse_transmission_image];
    unsigned char *base = stbi_load_from_memory(bi->png, (int)bi->size, &w, &h, &c, 4);
    unsigned char *tr = stbi_load_from_memory(ti->png, (int)ti->size, &w2, &h2, &c2, 4);
    unsigned char *alb = stbi_load(SYLVA_SPECIES_DIR "/leafmaps/quaking_aspen/albedo.png", &w3, &h3, &c3, 4);
    assert_non_null(base);
    assert_non_null(tr);
    assert_non_null(alb);
    assert_int_equal(w, 128);
    assert_int_equal(w2, 128);
    /* Compare against the albedo reduced to 128 by sampling 4x4 blocks' mean is
     * what the resize does; compare block means in linear light. */
    int f = w3 / w;
    double err_sum = 0;
    size_t n = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const unsigned char *b = base + 4 * ((size_t)y * w + x), *t = tr + 4 * ((size_t)y * w + x);
            if (b[3] < 250) continue;
            double fac = t[3] / 255.0, want = 0;
            int full = 1;
            for (int dy = 0; dy < f; dy++)
                for (int dx = 0; dx < f; dx++) {
                    const unsigned char *a = alb + 4 * ((size_t)(y * f + dy) * w3 + x * f + dx);
                    full &= a[3] == 255;
                    double v = a[1] / 255.0;
                    want += v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
                }
            if (!full) continue;
            want /= f * f;
            double bv = b[1] / 255.0, got = bv <= 0.04045 ? bv / 12.92 : pow((bv + 0.055) / 1.055, 2.4);
            double cv = t[1] / 255.0, col = cv <= 0.04045 ? cv / 12.92 : pow((cv + 0.055) / 1.055, 2.4);
            assert_true((1 - fac) * got + fac * col <= 1.0 + 1e-6);
            err_sum += fabs(got - want);
            n++;
        }
    assert_true(n > 100);
    assert_true(err_sum / n < 0.01);
    stbi_image_free(base), stbi_image_free(tr), stbi_image_free(alb);
    sy_asset_free(&asset);
}

/* The materials cache: the second build of the same spec reads the first's
 * entry and gives the same images byte for byte and the same materials; an
 * entry cut short is a miss, never a wrong asset. */
static void assets_equal(const sy_asset *a, const sy_asset *b)
{
    assert_int_equal(a->n_images, b->n_images);
    assert_int_equal(a->n_materials, b->n_materials);
    for (size_t i = 0; i < a->n_images; i++) {
        assert_string_equal(a->images[i].name, b->images[i].name);
        assert_int_equal(a->images[i].size, b->images[i].size);
        assert_memory_equal(a->images[i].png, b->images[i].png, a->images[i].size);
    }
    for (size_t m = 0; m < a->n_materials; m++) {
        const sy_material *x = &a->materials[m], *y = &b->materials[m];
        assert_string_equal(x->name, y->name);
        assert_int_equal(x->base_color_image, y->base_color_image);
        assert_int_equal(x->normal_image, y->normal_image);
        assert_int_equal(x->diffuse_transmission_image, y->diffuse_transmission_image);
        assert_int_equal(x->thickness_image, y->thickness_image);
        assert_int_equal(x->hl2_image[0], y->hl2_image[0]);
        assert_int_equal(x->hl2_image[1], y->hl2_image[1]);
        assert_memory_equal(x->base_color, y->base_color, sizeof x->base_color);
        assert_memory_equal(x->diffuse_transmission_color, y->diffuse_transmission_color,
                            sizeof x->diffuse_transmission_color);
        assert_true(x->diffuse_transmission == y->diffuse_transmission && x->thickness_factor == y->thickness_factor);
        assert_true(x->alpha_mode == y->alpha_mode && x->double_sided == y->double_sided);
    }
}

static size_t cache_entries(const char *dir, char *one, size_t size)
{
    char cmd[4200];
    snprintf(cmd, sizeof cmd, "ls '%s' 2>/dev/null", dir);
    FILE *p = popen(cmd, "r");
    size_t n = 0;
    char line[512];
    while (p && fgets(line, sizeof line, p)) {
        line[strcspn(line, "\n")] = 0;
        if (one && !n) snprintf(one, size, "%s/%s", dir, line);
        n++;
    }
    if (p) pclose(p);
    return n;
}

static void cache_gives_the_same_materials(void **state)
{
    (void)state;
    const char *dir = tmp_path("material_cache");
    char cmd[8800];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
    const char *lm = SYLVA_SPECIES_DIR "/leafmaps/quaking_aspen/leaf.material";
    sy_material_spec plain = {SYLVA_SPECIES_DIR "/textures/bark.png", NULL, -1.0f, 64, lm, 0.3f, NULL, NULL};
    sy_material_spec cached = plain;
    cached.cache_dir = dir;
    sy_error err = {0};
    sy_asset ref, miss, hit, cut;
    int b0, l0, b1, l1, b2, l2, b3, l3;
    memset(&ref, 0, sizeof ref), memset(&miss, 0, sizeof miss), memset(&hit, 0, sizeof hit);
    memset(&cut, 0, sizeof cut);
    /* An asset that already holds an image: indices are rebased on it. */
    sy_image first = {NULL, 0, "first"};
    first.png = malloc(4), first.size = 4;
    memcpy(first.png, "abcd", 4);
    assert_true(sy_asset_add_image(&hit, &first, &err) == 0);
    assert_int_equal(sy_materials_add(&plain, &ref, &b0, &l0, &err), SY_OK);
    assert_int_equal(sy_materials_add(&cached, &miss, &b1, &l1, &err), SY_OK);
    char entry[4400];
    assert_int_equal(cache_entries(dir, entry, sizeof entry), 1);
    assert_int_equal(sy_materials_add(&cached, &hit, &b2, &l2, &err), SY_OK);
    assets_equal(&ref, &miss);
    assert_int_equal(b1, b0), assert_int_equal(l1, l0);
    assert_int_equal(b2, b0), assert_int_equal(l2, l0);
    assert_int_equal(hit.n_images, ref.n_images + 1);
    for (size_t i = 0; i < ref.n_images; i++)
        assert_memory_equal(ref.images[i].png, hit.images[i + 1].png, ref.images[i].size);
    assert_int_equal(hit.materials[l2].base_color_image, ref.materials[l0].base_color_image + 1);
    assert_int_equal(hit.materials[l2].hl2_image[1], ref.materials[l0].hl2_image[1] + 1);
    /* A damaged entry (cut in half): made again, the same, and stored again. */
    snprintf(cmd, sizeof cmd, "truncate -s %%50 '%s'", entry);
    assert_int_equal(system(cmd), 0);
    assert_int_equal(sy_materials_add(&cached, &cut, &b3, &l3, &err), SY_OK);
    assets_equal(&ref, &cut);
    sy_asset again;
    memset(&again, 0, sizeof again);
    assert_int_equal(sy_materials_add(&cached, &again, &b3, &l3, &err), SY_OK);
    assets_equal(&ref, &again);
    sy_asset_free(&ref), sy_asset_free(&miss), sy_asset_free(&hit), sy_asset_free(&cut), sy_asset_free(&again);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(leaf_maps_become_the_leaf_material),
        cmocka_unit_test(flat_image_gives_straight_up_normals),
        cmocka_unit_test(ramps_tilt_the_normal_downhill),
        cmocka_unit_test(library_textures_become_materials),
        cmocka_unit_test(bark_takes_the_species_colour),
        cmocka_unit_test(cards_keep_a_power_of_two_aspect),
        cmocka_unit_test(procedural_fallbacks_are_deterministic),
        cmocka_unit_test(leaf_without_alpha_is_cut_from_its_background),
        cmocka_unit_test(unreadable_images_are_input_errors),
        cmocka_unit_test(cache_gives_the_same_materials),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
