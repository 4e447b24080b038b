/* Species materials: bark and leaf-card images decoded with stb_image,
 * filtered through the OpenCV shim (image_cv.h), stored as PNG in the asset.
 * Without images, a deterministic procedural bark and a plain leaf
 * silhouette stand in. */
#include "species/materials.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <stb_image.h>

#include "species/image_cv.h"
#include "species/library.h"
#include "species/material_cache.h"
#include "stages/core/color.h"
#include "stages/leafmaps/leaf_material.h"
#include "stages/leafmaps/leafmaps_cv.h"
#include "stages/core/fileio.h"
#include "stages/core/png.h"
#include "stages/core/texture.h"

#define BARK_NORMAL_STRENGTH 6.0f /* bark photos have shallow luminance relief */
#define LEAF_NORMAL_STRENGTH 2.0f
#define EMISSIVE_SHARE 0.3f       /* leaf glow per unit of translucency (no-transmission engines) */
#define ALPHA_THRESHOLD 40.0f     /* RGB distance from the background, 0..255 */
#define MAX_DECODE_SIDE 16384
#define MAX_INFLATE 1032.0 /* deflate's largest expansion (RFC 1951: 258-byte matches in ~2 bits) */

typedef struct {
    int w, h;
    unsigned char *rgba;
} image;

static void image_free(image *im)
{
    free(im->rgba);
    im->rgba = NULL;
}

/* ------------------------------------------------------------ PNG bytes */

/* Appends an encoded PNG (png malloc'ed, taken over) to the asset as image
 * `name`; its index, or -1 (png freed). */
static int add_encoded(sy_asset *asset, const char *name, unsigned char *png, size_t size, sy_error *err)
{
    sy_image img;
    memset(&img, 0, sizeof img);
    img.png = png;
    img.size = size;
    snprintf(img.name, sizeof img.name, "%s", name);
    int idx = sy_asset_add_image(asset, &img, err);
    if (idx < 0) free(img.png);
    return idx;
}

/* Encodes pixels (comp channels) as PNG and appends it to the asset. */
static int add_png(sy_asset *asset, const char *name, const unsigned char *pixels, int w, int h, int comp,
                   sy_error *err)
{
    unsigned char *png;
    size_t size;
    if (sy_png_encode(pixels, w, h, comp, 8, &png, &size)) {
        sy_fail(err, SY_EINTERNAL, "%s: PNG encoding failed", name);
        return -1;
    }
    return add_encoded(asset, name, png, size, err);
}

/* --------------------------------------------------------- decode/resize */

static int is_pow2_floor(int v)
{
    int p = 1;
    while (p * 2 <= v) p *= 2;
    return p;
}

/* Power-of-two size no larger than max_size, keeping the aspect as close as
 * powers of two allow (nearest in log2 for the short side). */
static void target_size(int w, int h, int max_size, int *tw, int *th)
{
    int longest = w > h ? w : h;
    int lp = is_pow2_floor(longest < max_size ? longest : max_size);
    double short_side = (double)(w < h ? w : h) * lp / longest;
    int sp = 1;
    while (sp * 2 <= lp && fabs(log2(sp * 2.0) - log2(short_side)) < fabs(log2((double)sp) - log2(short_side)))
        sp *= 2;
    *tw = w >= h ? lp : sp;
    *th = w >= h ? sp : lp;
}

/* Loads path as RGBA; *had_alpha tells whether the file carried alpha. */
static sy_code load_rgba(const char *path, image *im, int *had_alpha, sy_error *err)
{
    sy_buffer b;
    sy_code rc = sy_read_file(path, &b, err);
    if (rc) return rc;
    if (b.size > INT_MAX) {
        sy_buffer_free(&b);
        return sy_fail(err, SY_EINPUT, "%s: image file of %zu bytes is too large", path, b.size);
    }
    int w, h, comp;
    if (!stbi_info_from_memory(b.data, (int)b.size, &w, &h, &comp)) {
        sy_buffer_free(&b);
        return sy_fail(err, SY_EINPUT, "%s: cannot read image (%s)", path, stbi_failure_reason());
    }
    if (w <= 0 || h <= 0 || w > MAX_DECODE_SIDE || h > MAX_DECODE_SIDE) {
        sy_buffer_free(&b);
        return sy_fail(err, SY_EINPUT, "%s: image size %dx%d is outside 1..%d", path, w, h, MAX_DECODE_SIDE);
    }
    /* Deflate expands at most ~1032:1, so a header naming more pixels than
     * the bytes can hold lies: refuse it before the decoder allocates them. */
    if ((double)w * h * (comp > 0 ? comp : 4) > MAX_INFLATE * (double)b.size + (1 << 20)) {
        sy_buffer_free(&b);
        return sy_fail(err, SY_EINPUT, "%s: %dx%d pixels cannot come from %zu bytes (a corrupt header)", path, w, h,
                       b.size);
    }
    im->rgba = stbi_load_from_memory(b.data, (int)b.size, &im->w, &im->h, &comp, 4);
    sy_buffer_free(&b);
    if (!im->rgba) return sy_fail(err, SY_EINPUT, "%s: cannot decode image (%s)", path, stbi_failure_reason());
    *had_alpha = comp == 2 || comp == 4;
    return SY_OK;
}

static sy_code resize_to(image *im, int max_size, const char *what, sy_error *err)
{
    int tw, th;
    target_size(im->w, im->h, max_size, &tw, &th);
    if (tw == im->w && th == im->h) return SY_OK;
    unsigned char *dst = malloc((size_t)tw * (size_t)th * 4);
    if (!dst) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", what);
    if (sy_cv_resize_rgba(im->rgba, im->w, im->h, dst, tw, th, err)) {
        free(dst);
        return sy_error_prefix(err, what);
    }
    free(im->rgba);
    im->rgba = dst;
    im->w = tw;
    im->h = th;
    return SY_OK;
}

/* ------------------------------------------------------- procedural art */

static uint32_t hash2(int x, int y, uint32_t seed)
{
    uint32_t h = (uint32_t)x * 0x8DA6B343u ^ (uint32_t)y * 0xD8163841u ^ seed * 0xCB1AB31Fu;
    h ^= h >> 13;
    h *= 0x5BD1E995u;
    return h ^ (h >> 15);
}

/* Periodic value noise: the lattice wraps at (px, py) cells so it tiles. */
static float value_noise(float x, float y, int px, int py, uint32_t seed)
{
    int x0 = (int)floorf(x), y0 = (int)floorf(y);
    float fx = x - (float)x0, fy = y - (float)y0;
    fx = fx * fx * (3 - 2 * fx);
    fy = fy * fy * (3 - 2 * fy);
    float v[4];
    for (int k = 0; k < 4; k++) {
        int cx = ((x0 + (k & 1)) % px + px) % px, cy = ((y0 + (k >> 1)) % py + py) % py;
        v[k] = (float)(hash2(cx, cy, seed) & 0xFFFF) / 65535.0f;
    }
    return (v[0] * (1 - fx) + v[1] * fx) * (1 - fy) + (v[2] * (1 - fx) + v[3] * fx) * fy;
}

/* Bark: vertical furrows (noise stretched along v) over fine grain. */
static sy_code procedural_bark(int size, image *im, sy_error *err)
{
    im->w = im->h = size;
    im->rgba = malloc((size_t)size * (size_t)size * 4);
    if (!im->rgba) return sy_fail(err, SY_EINTERNAL, "bark: out of memory");
    for (int y = 0; y < size; y++)
        for (int x = 0; x < size; x++) {
            float u = (float)x / (float)size, v = (float)y / (float)size;
            float ridges = 0, amp = 0.6f;
            for (int o = 0; o < 4; o++) {
                int cx = 8 << o, cy = 2 << o;
                ridges += amp * value_noise(u * (float)cx, v * (float)cy, cx, cy, 7u + (uint32_t)o);
                amp *= 0.5f;
            }
            float grain = value_noise(u * 64, v * 64, 64, 64, 99u);
            float h = 0.8f * ridges + 0.2f * grain;
            unsigned char *p = im->rgba + 4 * ((size_t)y * (size_t)size + (size_t)x);
            p[0] = (unsigned char)(40 + 90 * h);
            p[1] = (unsigned char)(30 + 70 * h);
            p[2] = (unsigned char)(22 + 48 * h);
            p[3] = 255;
        }
    return SY_OK;
}

/* Leaf: a pointed blade (width sin(pi t)^0.8 along the axis) with a lighter
 * midrib, tip at the top of the image, petiole at the bottom. */
static sy_code procedural_leaf(int size, image *im, sy_error *err)
{
    im->h = size;
    im->w = size / 2 > 0 ? size / 2 : 1;
    im->rgba = calloc((size_t)im->w * (size_t)im->h, 4);
    if (!im->rgba) return sy_fail(err, SY_EINTERNAL, "leaf: out of memory");
    for (int y = 0; y < im->h; y++)
        for (int x = 0; x < im->w; x++) {
            float t = 1.0f - ((float)y + 0.5f) / (float)im->h; /* 0 at the petiole, 1 at the tip */
            float s = 2.0f * ((float)x + 0.5f) / (float)im->w - 1.0f;
            float half = 0.9f * powf(sinf(3.14159265f * (0.05f + 0.95f * t)), 0.8f);
            unsigned char *p = im->rgba + 4 * ((size_t)y * (size_t)im->w + (size_t)x);
            int petiole = t < 0.08f && fabsf(s) < 0.06f;
            if (fabsf(s) > half && !petiole) continue;
            float rib = fabsf(s) < 0.04f ? 1.0f : 0.0f;
            float shade = 0.85f + 0.15f * (1 - fabsf(s));
            p[0] = (unsigned char)((60 + 50 * rib) * shade);
            p[1] = (unsigned char)((120 + 40 * rib) * shade);
            p[2] = (unsigned char)((40 + 20 * rib) * shade);
            p[3] = 255;
        }
    return SY_OK;
}

/* ------------------------------------------------------------ materials */

static float srgb_to_linear(float c)
{
    return (float)sy_srgb_to_linear(c);
}

/* Mean linear albedo of the opaque texels, scaled so its largest channel is
 * 1: the hue of light passing through the leaf. */
static void leaf_transmission_color(const image *im, float out[3])
{
    double sum[3] = {0, 0, 0};
    size_t n = 0;
    for (size_t i = 0; i < (size_t)im->w * (size_t)im->h; i++) {
        const unsigned char *p = im->rgba + 4 * i;
        if (p[3] < 128) continue;
        for (int c = 0; c < 3; c++) sum[c] += srgb_to_linear((float)p[c] / 255.0f);
        n++;
    }
    float m = 0;
    for (int c = 0; c < 3; c++) {
        out[c] = n ? (float)(sum[c] / (double)n) : 0.0f;
        if (out[c] > m) m = out[c];
    }
    for (int c = 0; c < 3; c++) out[c] = m > 0 ? out[c] / m : 1.0f;
}

/* Luminance of an sRGB texel (Rec. 709 weights on the encoded values). */
static float texel_luma(const unsigned char *p) { return 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2]; }

/* The RGB of im recoloured to mean colour c (sRGB 0..255): each texel is c
 * times its luminance over the image's mean luminance, clamped. */
static void recolor(const image *im, const float c[3], unsigned char *rgb)
{
    size_t n = (size_t)im->w * (size_t)im->h;
    double sum = 0;
    for (size_t i = 0; i < n; i++) sum += texel_luma(im->rgba + 4 * i);
    float mean = n && sum > 0 ? (float)(sum / (double)n) : 1.0f;
    for (size_t i = 0; i < n; i++) {
        float k = texel_luma(im->rgba + 4 * i) / mean;
        for (int ch = 0; ch < 3; ch++) {
            float v = c[ch] * k + 0.5f;
            rgb[3 * i + ch] = (unsigned char)(v < 0 ? 0 : v > 255 ? 255 : v);
        }
    }
}

/* Adds the colour and normal images of im (its RGB recoloured to tint when
 * given, RGB images only); returns 0 or -1 (err set). */
static int add_maps(sy_asset *asset, const char *prefix, const image *im, int rgba, const float *tint, float strength,
                    int wrap, int *color_idx, int *normal_idx, sy_error *err)
{
    size_t n = (size_t)im->w * (size_t)im->h;
    unsigned char *buf = malloc(n * 3);
    if (!buf) {
        sy_fail(err, SY_EINTERNAL, "%s: out of memory", prefix);
        return -1;
    }
    char name[48];
    int rc = 0;
    if (rgba) {
        snprintf(name, sizeof name, "%s_color", prefix);
        *color_idx = add_png(asset, name, im->rgba, im->w, im->h, 4, err);
    } else {
        if (tint) recolor(im, tint, buf);
        else
            for (size_t i = 0; i < n; i++) memcpy(buf + 3 * i, im->rgba + 4 * i, 3);
        snprintf(name, sizeof name, "%s_color", prefix);
        *color_idx = add_png(asset, name, buf, im->w, im->h, 3, err);
    }
    if (*color_idx < 0) rc = -1;
    if (rc == 0 && sy_cv_normal_map(im->rgba, im->w, im->h, strength, wrap, buf, err)) {
        sy_error_prefix(err, prefix);
        rc = -1;
    }
    if (rc == 0) {
        snprintf(name, sizeof name, "%s_normal", prefix);
        *normal_idx = add_png(asset, name, buf, im->w, im->h, 3, err);
        if (*normal_idx < 0) rc = -1;
    }
    free(buf);
    return rc;
}

static sy_code make_bark(const sy_material_spec *spec, int max_size, sy_asset *asset, int *out, sy_error *err)
{
    image im = {0};
    int had_alpha = 0;
    sy_code rc = spec->bark_image ? load_rgba(spec->bark_image, &im, &had_alpha, err)
                                  : procedural_bark(is_pow2_floor(max_size), &im, err);
    if (rc == SY_OK && spec->bark_image) rc = resize_to(&im, max_size, spec->bark_image, err);
    int color = -1, normal = -1;
    if (rc == SY_OK && add_maps(asset, "bark", &im, 0, spec->bark_color, BARK_NORMAL_STRENGTH, 1, &color, &normal, err))
        rc = err->code;
    image_free(&im);
    if (rc) return rc;
    sy_material m = sy_material_default("bark");
    m.base_color_image = color;
    m.normal_image = normal;
    m.roughness = 0.9f;
    *out = sy_asset_add_material(asset, &m, err);
    return *out < 0 ? SY_EINTERNAL : SY_OK;
}

/* The leaf card's clear texels take the leaf's colours (texture.h): an
 * engine's mip levels average them in, and a card that is mostly clear
 * showed its photo's background colour at a distance. */
static sy_code bleed_clear_texels(image *im, sy_error *err)
{
    size_t n = (size_t)im->w * (size_t)im->h;
    unsigned char *covered = malloc(n ? n : 1);
    if (!covered) return sy_fail(err, SY_EINTERNAL, "leaf: out of memory");
    for (size_t i = 0; i < n; i++) covered[i] = im->rgba[4 * i + 3] >= 128;
    sy_code rc = sy_texture_bleed_u8(im->rgba, im->w, im->h, 4, 3, covered, err);
    free(covered);
    return rc;
}

static sy_code make_leaf(const sy_material_spec *spec, int max_size, float translucency, sy_asset *asset,
                             int *out, sy_error *err)
{
    image im = {0};
    int had_alpha = 1;
    sy_code rc = spec->leaf_image ? load_rgba(spec->leaf_image, &im, &had_alpha, err)
                                  : procedural_leaf(is_pow2_floor(max_size), &im, err);
    if (rc == SY_OK && !had_alpha && sy_cv_alpha_from_background(im.rgba, im.w, im.h, ALPHA_THRESHOLD, err))
        rc = sy_error_prefix(err, spec->leaf_image);
    if (rc == SY_OK && spec->leaf_image) rc = resize_to(&im, max_size, spec->leaf_image, err);
    if (rc == SY_OK) rc = bleed_clear_texels(&im, err);
    int color = -1, normal = -1;
    if (rc == SY_OK && add_maps(asset, "leaf", &im, 1, NULL, LEAF_NORMAL_STRENGTH, 0, &color, &normal, err))
        rc = err->code;
    sy_material m = sy_material_default("leaf");
    if (rc == SY_OK) leaf_transmission_color(&im, m.diffuse_transmission_color);
    image_free(&im);
    if (rc) return rc;
    m.base_color_image = color;
    m.normal_image = normal;
    m.roughness = 0.7f;
    m.alpha_mode = SY_ALPHA_MASK;
    m.alpha_cutoff = 0.5f;
    m.double_sided = 1;
    m.diffuse_transmission = translucency;
    /* Engines without KHR_materials_diffuse_transmission (three.js, most game
     * engines) light a card's side away from the sun with ambient light only,
     * near black under a low sky. A faint glow in the leaf's own colours
     * stands in for the transmitted light there: EMISSIVE_SHARE of the
     * translucency (a fraction that barely brightens a sunlit face). */
    for (int c = 0; c < 3; c++) m.emissive[c] = EMISSIVE_SHARE * translucency;
    *out = sy_asset_add_material(asset, &m, err);
    return *out < 0 ? SY_EINTERNAL : SY_OK;
}

/* ------------------------------------------------- leaf maps (sylva leaf) */

const char *sy_species_leaf_maps(const char *species_name, char *buf, size_t size)
{
    if (!species_name || !sy_leaf_material_valid_name(species_name)) return NULL;
    sy_library lib;
    sy_error err = {0};
    if (sy_library_load(NULL, &lib, &err)) return NULL; /* no library: cards from the species file */
    const sy_library_entry *e = sy_library_find(&lib, species_name);
    const char *rel = e ? sy_library_entry_leaf_maps(e) : NULL;
    if (rel) snprintf(buf, size, "%s/%s", lib.dir, rel);
    sy_library_free(&lib);
    if (!rel) return NULL;
    FILE *f = fopen(buf, "rb");
    if (!f) return NULL;
    fclose(f);
    return buf;
}

/* Reads a map of the leaf material at side x side texels (float, c channels). */
static sy_code read_map(const char *path, int want_c, int want_bits, int side, float **out, sy_error *err)
{
    float *px;
    int w, h, c, depth;
    if (sy_lcv_read(path, &px, &w, &h, &c, &depth, err)) return err->code;
    if (c != want_c || depth != want_bits || w != h || w < 1) {
        free(px);
        return sy_fail(err, SY_EINPUT, "%s: expected a square %d-bit %d-channel leaf map", path, want_bits, want_c);
    }
    if (w == side) {
        *out = px;
        return SY_OK;
    }
    float *r = malloc((size_t)side * side * (size_t)c * sizeof *r);
    sy_code rc = r ? sy_lcv_resize(px, w, h, c, r, side, side, err) : sy_fail(err, SY_EINTERNAL, "out of memory");
    if (rc) {
        free(px), free(r);
        return sy_error_prefix(err, path);
    }
    free(px);
    *out = r;
    return SY_OK;
}

static int add_png16(sy_asset *asset, const char *name, const float *px, int side, int c, int bits, sy_error *err)
{
    unsigned char *png;
    size_t size;
    if (sy_lcv_encode_png(px, side, side, c, bits, &png, &size, err)) {
        sy_error_prefix(err, name);
        return -1;
    }
    return add_encoded(asset, name, png, size, err);
}

static float to_srgb(float v)
{
    return (float)sy_linear_to_srgb(v);
}

/* The leaf of a species with maps from `sylva leaf`. KHR_materials_diffuse_
 * transmission splits the non-specular light: (1 - f) baseColor is
 * reflected and f colour transmitted. With measured albedo a and
 * transmittance t per texel: f = max_c t_c and colour = t / f, so the
 * transmitted light is t exactly. baseColor stays a: viewers without the
 * extension (most engines' importers) show the measured albedo, and those
 * with it reflect (1 - f) a, a little darker, never more than a + t <= 1. */
static sy_code make_leaf_from_maps(const sy_material_spec *spec, int max_size, sy_asset *asset, int *out, sy_error *err)
{
    sy_leaf_material lm;
    sy_code rc = sy_leaf_material_load(spec->leaf_maps, &lm, err);
    if (rc) return rc;
    int side = lm.size > 0 ? lm.size : 1024;
    while (side > max_size && side > 1) side /= 2;
    float *alb = NULL, *nrm = NULL, *tr = NULL, *th = NULL, *hl[2] = {NULL, NULL};
    if (!rc) rc = read_map(lm.albedo, 4, 8, side, &alb, err);
    if (!rc) rc = read_map(lm.normal, 3, 8, side, &nrm, err);
    if (!rc && lm.translucency[0]) rc = read_map(lm.translucency, 3, 8, side, &tr, err);
    if (!rc && lm.thickness[0]) rc = read_map(lm.thickness, 1, 16, side, &th, err);
    for (int s = 0; !rc && s < 2; s++)
        if (lm.hl2[s][0]) rc = read_map(lm.hl2[s], 3, 16, side, &hl[s], err);
    size_t n = (size_t)side * side;
    float *base = rc ? NULL : malloc(n * 4 * sizeof *base), *trans = rc ? NULL : malloc(n * 4 * sizeof *trans);
    unsigned char *covered = rc ? NULL : malloc(n);
    if (!rc && (!base || !trans || !covered)) rc = sy_fail(err, SY_EINTERNAL, "leaf maps: out of memory");
    for (size_t i = 0; !rc && i < n; i++) {
        float a[3], t[3] = {0, 0, 0}, f = 0;
        for (int c = 0; c < 3; c++) {
            a[c] = srgb_to_linear(alb[4 * i + c]);
            if (tr) t[c] = srgb_to_linear(tr[3 * i + c]);
            if (t[c] > f) f = t[c];
        }
        if (f > 0.95f) f = 0.95f;
        for (int c = 0; c < 3; c++) {
            base[4 * i + c] = to_srgb(a[c]);
            trans[4 * i + c] = to_srgb(f > 1e-4f ? t[c] / f : 1.0f);
        }
        base[4 * i + 3] = alb[4 * i + 3];
        trans[4 * i + 3] = f;
        covered[i] = alb[4 * i + 3] >= 0.5f;
    }
    /* Every map's clear texels take the leaf's values (bleed_clear_texels). */
    if (!rc) rc = sy_texture_bleed(base, side, side, 4, 3, covered, err);
    if (!rc) rc = sy_texture_bleed(trans, side, side, 4, 4, covered, err);
    if (!rc) rc = sy_texture_bleed(nrm, side, side, 3, 3, covered, err);
    if (!rc && th) rc = sy_texture_bleed(th, side, side, 1, 1, covered, err);
    for (int s = 0; !rc && s < 2; s++)
        if (hl[s]) rc = sy_texture_bleed(hl[s], side, side, 3, 3, covered, err);
    sy_material m = sy_material_default("leaf");
    if (!rc && ((m.base_color_image = add_png16(asset, "leaf_color", base, side, 4, 8, err)) < 0 ||
                (m.normal_image = add_png16(asset, "leaf_normal", nrm, side, 3, 8, err)) < 0))
        rc = err->code;
    if (!rc && tr && (m.diffuse_transmission_image = add_png16(asset, "leaf_transmission", trans, side, 4, 8, err)) < 0)
        rc = err->code;
    if (!rc && th && (m.thickness_image = add_png16(asset, "leaf_thickness", th, side, 1, 8, err)) < 0) rc = err->code;
    static const char *hl_names[2] = {"leaf_hl2_adaxial", "leaf_hl2_abaxial"};
    for (int s = 0; !rc && s < 2; s++)
        if (hl[s] && (m.hl2_image[s] = add_png16(asset, hl_names[s], hl[s], side, 3, 16, err)) < 0) rc = err->code;
    free(alb), free(nrm), free(tr), free(th), free(hl[0]), free(hl[1]), free(base), free(trans), free(covered);
    if (rc) return rc;
    m.roughness = 0.7f;
    m.alpha_mode = SY_ALPHA_MASK;
    m.alpha_cutoff = 0.5f;
    m.double_sided = 1;
    if (m.diffuse_transmission_image >= 0) {
        m.diffuse_transmission = 1.0f; /* the texture's alpha carries the factor */
        for (int c = 0; c < 3; c++) m.diffuse_transmission_color[c] = 1.0f;
    }
    float card = spec->leaf_length_m > 0 ? spec->leaf_length_m : 0.1f;
    if (m.thickness_image >= 0) m.thickness_factor = (float)(lm.thickness_max_mm / 1000.0 / card);
    m.hl2_min = (float)SY_LEAF_HL2_MIN;
    m.hl2_max = (float)SY_LEAF_HL2_MAX;
    m.hl2_transmit[0] = (float)lm.transmit_normal[0];
    m.hl2_transmit[1] = (float)lm.transmit_normal[1];
    *out = sy_asset_add_material(asset, &m, err);
    return *out < 0 ? SY_EINTERNAL : SY_OK;
}

sy_code sy_materials_add(const sy_material_spec *spec, sy_asset *asset, int *bark_material, int *leaf_material,
                             sy_error *err)
{
    int max_size = spec->max_size > 0 ? spec->max_size : 512;
    if (max_size > 8192) max_size = 8192;
    float translucency = spec->leaf_translucency < 0 ? 0.4f : spec->leaf_translucency; /* negative: default */
    if (!(translucency <= 1))
        return sy_fail(err, SY_EINPUT, "leaf translucency %g is outside [0, 1]", translucency);
    uint64_t key = 0;
    int cached = spec->cache_dir && sy_material_cache_key(spec, max_size, translucency, &key);
    if (cached && sy_material_cache_load(spec->cache_dir, key, asset, bark_material, leaf_material)) return SY_OK;
    size_t img0 = asset->n_images, mat0 = asset->n_materials;
    sy_code rc = make_bark(spec, max_size, asset, bark_material, err);
    if (rc) return rc;
    rc = spec->leaf_maps ? make_leaf_from_maps(spec, max_size, asset, leaf_material, err)
                         : make_leaf(spec, max_size, translucency, asset, leaf_material, err);
    if (!rc && cached) sy_material_cache_store(spec->cache_dir, key, asset, img0, mat0, *bark_material, *leaf_material);
    return rc;
}
