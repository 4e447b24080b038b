/* Leaf material files (leaf_material.h, docs/leafmaps.md). */
#include "stages/leafmaps/leaf_material.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "stages/core/color.h"
#include "stages/core/fileio.h"
#include "stages/core/lines.h"
#include "stages/leafmaps/leafmaps_cv.h"

#define ATLAS_MAX 2048

void sy_leaf_files_free(sy_leaf_files *f)
{
    for (int i = 0; i < f->n; i++) free(f->data[i]);
    memset(f, 0, sizeof *f);
}

int sy_leaf_material_valid_name(const char *name)
{
    if (!name || !*name || strlen(name) > 40) return 0;
    for (const char *p = name; *p; p++)
        if (!isalnum((unsigned char)*p) && *p != '_' && *p != '-') return 0;
    return 1;
}

static sy_code add_file(sy_leaf_files *f, const char *name, const float *px, int w, int h, int c, int bits,
                        sy_error *err)
{
    if (f->n >= SY_LEAF_MAX_FILES) return sy_fail(err, SY_EINTERNAL, "leaf material: too many files");
    if (sy_lcv_encode_png(px, w, h, c, bits, &f->data[f->n], &f->size[f->n], err)) return sy_error_prefix(err, name);
    snprintf(f->name[f->n], sizeof f->name[0], "%s", name);
    f->n++;
    return SY_OK;
}

static sy_code add_text(sy_leaf_files *f, const char *name, const char *text, sy_error *err)
{
    if (f->n >= SY_LEAF_MAX_FILES) return sy_fail(err, SY_EINTERNAL, "leaf material: too many files");
    size_t n = strlen(text);
    f->data[f->n] = malloc(n + 1);
    if (!f->data[f->n]) return sy_fail(err, SY_EINTERNAL, "leaf material: out of memory");
    memcpy(f->data[f->n], text, n + 1);
    f->size[f->n] = n;
    snprintf(f->name[f->n], sizeof f->name[0], "%s", name);
    f->n++;
    return SY_OK;
}

/* The eight-bit and sixteen-bit images of one leaf into buffers. kind:
 * 0 albedo RGBA (sRGB, alpha = mask), 1 normal (n/2 + 1/2), 2 translucency
 * (sRGB), 3 HL2 (16-bit scale/bias), 4 thickness (16-bit, mm / max). */
static float *image_of(const sy_leaf_maps *m, int kind, int side, double tmax)
{
    size_t n = (size_t)m->w * m->h;
    int c = kind == 0 ? 4 : kind == 4 ? 1 : 3;
    float *o = malloc(n * (size_t)c * sizeof *o);
    if (!o) return NULL;
    for (size_t i = 0; i < n; i++) {
        switch (kind) {
        case 0:
            for (int k = 0; k < 3; k++) o[4 * i + k] = (float)sy_linear_to_srgb(m->albedo[side][3 * i + k]);
            o[4 * i + 3] = m->alpha[i];
            break;
        case 1:
            for (int k = 0; k < 3; k++) o[3 * i + k] = 0.5f * m->normal[side][3 * i + k] + 0.5f;
            break;
        case 2:
            for (int k = 0; k < 3; k++) o[3 * i + k] = (float)sy_linear_to_srgb(m->translucency[side][3 * i + k]);
            break;
        case 3:
            for (int k = 0; k < 3; k++) {
                double v = (m->hl2[side][3 * i + k] - SY_LEAF_HL2_MIN) / (SY_LEAF_HL2_MAX - SY_LEAF_HL2_MIN);
                o[3 * i + k] = (float)(v < 0 ? 0 : v > 1 ? 1 : v);
            }
            break;
        default:
            o[i] = (float)(m->thickness[i] / tmax > 1 ? 1 : m->thickness[i] / tmax);
        }
    }
    return o;
}

static const char *source_name(sy_leaf_source s)
{
    static const char *names[] = {"none", "measured", "model", "copy"};
    return names[s];
}

static const char *base_name(const char *path)
{
    const char *s = strrchr(path, '/');
    return s ? s + 1 : path;
}

sy_code sy_leaf_material_encode(const sy_leaf_maps *maps, int n, const char *const *sources,
                                const sy_leafmaps_options *o, sy_leaf_files *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    const sy_leaf_maps *m = &maps[0];
    double tmax = ceil(m->thickness_max * 100 + 1e-9) / 100; /* 0.01 mm steps */
    static const char *names[2][4] = {{"albedo.png", "normal.png", "translucency.png", "hl2_adaxial.png"},
                                      {"albedo_abaxial.png", "normal_abaxial.png", "translucency_abaxial.png",
                                       "hl2_abaxial.png"}};
    sy_code rc = SY_OK;
    for (int s = 0; !rc && s < 2; s++)
        for (int kind = 0; !rc && kind < 4; kind++) {
            float *px = image_of(m, kind, s, tmax);
            if (!px) return sy_fail(err, SY_EINTERNAL, "leaf material: out of memory");
            rc = add_file(out, names[s][kind], px, m->w, m->h, kind == 0 ? 4 : 3, kind == 3 ? 16 : 8, err);
            free(px);
        }
    if (!rc) {
        float *px = image_of(m, 4, 0, tmax);
        rc = px ? add_file(out, "thickness.png", px, m->w, m->h, 1, 16, err)
                : sy_fail(err, SY_EINTERNAL, "leaf material: out of memory");
        free(px);
    }
    /* The atlas: the leaves' albedo, normal and translucency in a grid. */
    int cols = 1;
    while (cols * cols < n) cols++;
    int rows = (n + cols - 1) / cols;
    int cell = m->w;
    while (cell * cols > ATLAS_MAX && cell > 16) cell /= 2;
    int aw = cell * cols, ah = cell * rows;
    static const char *atlas_names[3] = {"atlas.png", "atlas_normal.png", "atlas_translucency.png"};
    static const int atlas_kind[3] = {0, 1, 2}, atlas_c[3] = {4, 3, 3};
    for (int a = 0; !rc && a < 3; a++) {
        int c = atlas_c[a];
        float *at = calloc((size_t)aw * ah * c, sizeof *at), *cellpx = malloc((size_t)cell * cell * c * sizeof *cellpx);
        if (!at || !cellpx) rc = sy_fail(err, SY_EINTERNAL, "atlas: out of memory");
        if (!rc && a == 1)
            for (size_t i = 0; i < (size_t)aw * ah; i++) at[3 * i] = at[3 * i + 1] = 0.5f, at[3 * i + 2] = 1;
        for (int k = 0; !rc && k < n; k++) {
            float *px = image_of(&maps[k], atlas_kind[a], 0, tmax);
            if (!px) rc = sy_fail(err, SY_EINTERNAL, "atlas: out of memory");
            else if ((rc = sy_lcv_resize(px, maps[k].w, maps[k].h, c, cellpx, cell, cell, err)))
                sy_error_prefix(err, "atlas");
            for (int y = 0; !rc && y < cell; y++)
                memcpy(at + (((size_t)(k / cols) * cell + y) * aw + (size_t)(k % cols) * cell) * c,
                       cellpx + (size_t)y * cell * c, (size_t)cell * c * sizeof *at);
            free(px);
        }
        if (!rc) rc = add_file(out, atlas_names[a], at, aw, ah, c, 8, err);
        free(at), free(cellpx);
    }
    if (rc) {
        sy_leaf_files_free(out);
        return rc;
    }
    char *text = malloc(16384 + 256 * (size_t)n);
    if (!text) {
        sy_leaf_files_free(out);
        return sy_fail(err, SY_EINTERNAL, "leaf material: out of memory");
    }
    int len = snprintf(
        text, 16384,
        "; Sylva leaf material, written by `sylva leaf` (docs/leafmaps.md).\n"
        "; Maps share the adaxial texel grid: row 0 is the leaf tip, the petiole is at the bottom centre.\n"
        "[Leaf]\n"
        "format = 1\n"
        "source = %s\n"
        "size = %d\n"
        "texel_mm = %.6g\n"
        "albedo = albedo.png\n"
        "albedo_abaxial = albedo_abaxial.png\n"
        "normal = normal.png\n"
        "normal_abaxial = normal_abaxial.png\n"
        "translucency = translucency.png\n"
        "translucency_abaxial = translucency_abaxial.png\n"
        "thickness = thickness.png\n"
        "hl2_adaxial = hl2_adaxial.png\n"
        "hl2_abaxial = hl2_abaxial.png\n"
        "; thickness.png (16-bit): mm = value / 65535 * thickness_max_mm\n"
        "thickness_max_mm = %.4g\n"
        "thickness_median_mm = %.6g\n"
        "thickness_min_mm = %.6g\n"
        "; hl2_*.png (16-bit RGB = h1 h2 h3): h = hl2_min + value / 65535 * (hl2_max - hl2_min)\n"
        "hl2_min = %g\n"
        "hl2_max = %g\n"
        "; mean L_t^D at normal incidence per unit irradiance, light on that side (physical scale of the HL2 maps)\n"
        "transmit_normal_adaxial = %.6g\n"
        "transmit_normal_abaxial = %.6g\n"
        "sigma_a = %g\nsigma_s = %g\ng = %g\nmultipoles = %d\ndirections = %d\nsectors = %d\n"
        "sigma_tr = %.6g\nextrapolation_mm = %.6g\nkernel_radius_mm = %.4g\nanchor_scale = %.6g\n"
        "energy_clamped = %zu\n"
        "source_albedo_abaxial = %s\nsource_translucency_adaxial = %s\nsource_translucency_abaxial = %s\n"
        "source_height_adaxial = %s\nsource_height_abaxial = %s\nsource_thickness = %s\n"
        "\n[Atlas]\n"
        "albedo = atlas.png\nnormal = atlas_normal.png\ntranslucency = atlas_translucency.png\n"
        "; per leaf: u0 v0 u1 v1 in glTF UV (v down from the image top)\n"
        "leaves = %d\n",
        base_name(sources[0]), m->w, m->texel_mm, tmax, m->thickness_median, m->thickness_min, SY_LEAF_HL2_MIN,
        SY_LEAF_HL2_MAX, m->transmit_normal[0], m->transmit_normal[1], o->sigma_a, o->sigma_s, o->g, o->multipoles,
        o->directions, o->sectors, m->sigma_tr, m->extrapolation_mm, m->kernel_radius_mm, m->anchor_scale,
        m->energy_clamped, source_name(m->src_albedo[1]), source_name(m->src_translucency[0]),
        source_name(m->src_translucency[1]), source_name(m->src_height[0]), source_name(m->src_height[1]),
        source_name(m->src_thickness), n);
    for (int k = 0; k < n; k++)
        len += snprintf(text + len, 256, "leaf%d = %.6g %.6g %.6g %.6g %s\n", k + 1, (double)(k % cols) * cell / aw,
                        (double)(k / cols) * cell / ah, (double)(k % cols + 1) * cell / aw,
                        (double)(k / cols + 1) * cell / ah, base_name(sources[k]));
    sy_code trc = add_text(out, SY_LEAF_MATERIAL_FILE, text, err);
    free(text);
    if (trc) sy_leaf_files_free(out);
    return trc;
}

sy_code sy_leaf_files_write(const sy_leaf_files *f, const char *dir, sy_error *err)
{
    if (mkdir(dir, 0777) != 0 && errno != EEXIST)
        return sy_fail(err, SY_EINPUT, "%s: cannot create folder (%s)", dir, strerror(errno));
    if (!sy_is_directory(dir)) return sy_fail(err, SY_EINPUT, "%s: not a folder", dir);
    char path[4400];
    for (int i = 0; i < f->n; i++) {
        snprintf(path, sizeof path, "%.4300s/%s", dir, f->name[i]);
        sy_code rc = sy_write_file_atomic(path, f->data[i], f->size[i], err);
        if (rc) return rc;
    }
    return SY_OK;
}

static void remove_flat_dir(const char *dir, const sy_leaf_files *names_hint)
{
    (void)names_hint;
    static const char *known[] = {"albedo.png", "albedo_abaxial.png", "normal.png", "normal_abaxial.png",
                                  "translucency.png", "translucency_abaxial.png", "hl2_adaxial.png", "hl2_abaxial.png",
                                  "thickness.png", "atlas.png", "atlas_normal.png", "atlas_translucency.png",
                                  SY_LEAF_MATERIAL_FILE};
    char path[4400];
    for (size_t i = 0; i < sizeof known / sizeof *known; i++) {
        snprintf(path, sizeof path, "%.4300s/%s", dir, known[i]);
        unlink(path);
    }
    rmdir(dir);
}

sy_code sy_leaf_files_install(const sy_leaf_files *f, const char *library, const char *name, sy_error *err)
{
    char base[4200], tmp[4300], old[4300], final[4300];
    snprintf(base, sizeof base, "%s/leafmaps", library);
    if (mkdir(base, 0777) != 0 && errno != EEXIST)
        return sy_fail(err, SY_EINPUT, "%s: cannot create folder (%s)", base, strerror(errno));
    snprintf(tmp, sizeof tmp, "%s/.%s.tmp.%ld", base, name, (long)getpid());
    snprintf(old, sizeof old, "%s/.%s.old.%ld", base, name, (long)getpid());
    snprintf(final, sizeof final, "%s/%s", base, name);
    remove_flat_dir(tmp, f);
    sy_code rc = sy_leaf_files_write(f, tmp, err);
    if (rc) {
        remove_flat_dir(tmp, f);
        return rc;
    }
    int had = sy_is_directory(final);
    if (had && rename(final, old) != 0) {
        remove_flat_dir(tmp, f);
        return sy_fail(err, SY_EINPUT, "%s: cannot replace (%s)", final, strerror(errno));
    }
    if (rename(tmp, final) != 0) {
        int e = errno;
        if (had) rename(old, final);
        remove_flat_dir(tmp, f);
        return sy_fail(err, SY_EINPUT, "%s: cannot install (%s)", final, strerror(e));
    }
    if (had) remove_flat_dir(old, f);
    return SY_OK;
}

/* ------------------------------------------------------------- reading */

sy_code sy_leaf_material_load(const char *path, sy_leaf_material *m, sy_error *err)
{
    memset(m, 0, sizeof *m);
    sy_buffer buf;
    sy_code rc = sy_read_file(path, &buf, err);
    if (rc) return rc;
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash) *slash = 0;
    else snprintf(dir, sizeof dir, ".");
    int in_leaf = 0, line_no = 0, have_format = 0;
    char *text = (char *)buf.data;
    sy_lines L;
    sy_lines_init(&L, text, buf.size);
    const char *lb, *le;
    while (!rc && sy_lines_next(&L, &lb, &le)) {
        char line[1024];
        size_t len = (size_t)(le - lb) < sizeof line - 1 ? (size_t)(le - lb) : sizeof line - 1;
        memcpy(line, lb, len);
        line[len] = 0;
        line_no++;
        char *s = line;
        while (isspace((unsigned char)*s)) s++;
        if (!*s || *s == ';' || *s == '#') continue;
        if (*s == '[') {
            in_leaf = strncmp(s, "[Leaf]", 6) == 0;
            continue;
        }
        if (!in_leaf) continue;
        char *eq = strchr(s, '=');
        if (!eq) {
            rc = sy_fail(err, SY_EINPUT, "%s:%d: expected key = value", path, line_no);
            break;
        }
        *eq = 0;
        char *key = s, *val = eq + 1;
        for (char *e = key + strlen(key); e > key && isspace((unsigned char)e[-1]);) *--e = 0;
        while (isspace((unsigned char)*val)) val++;
        for (char *e = val + strlen(val); e > val && isspace((unsigned char)e[-1]);) *--e = 0;
        char *file = NULL;
        if (!strcmp(key, "albedo")) file = m->albedo;
        else if (!strcmp(key, "normal")) file = m->normal;
        else if (!strcmp(key, "thickness")) file = m->thickness;
        else if (!strcmp(key, "translucency")) file = m->translucency;
        else if (!strcmp(key, "hl2_adaxial")) file = m->hl2[0];
        else if (!strcmp(key, "hl2_abaxial")) file = m->hl2[1];
        if (file) {
            if (strchr(val, '/') || !*val) rc = sy_fail(err, SY_EINPUT, "%s:%d: '%s' must be a file name beside it", path, line_no, val);
            else snprintf(file, 4096, "%.2000s/%.2000s", dir, val);
            continue;
        }
        char *endp;
        double v = strtod(val, &endp);
        int numeric = endp != val && *endp == 0 && isfinite(v);
        if (!strcmp(key, "format")) {
            if (!numeric || v != 1) rc = sy_fail(err, SY_EINPUT, "%s:%d: unknown format '%s'", path, line_no, val);
            have_format = 1;
        } else if (!strcmp(key, "texel_mm") || !strcmp(key, "thickness_max_mm") || !strcmp(key, "size") ||
                   !strcmp(key, "transmit_normal_adaxial") || !strcmp(key, "transmit_normal_abaxial")) {
            if (!numeric || v < 0) rc = sy_fail(err, SY_EINPUT, "%s:%d: %s '%s' is not a number >= 0", path, line_no, key, val);
            else if (!strcmp(key, "texel_mm")) m->texel_mm = v;
            else if (!strcmp(key, "thickness_max_mm")) m->thickness_max_mm = v;
            else if (!strcmp(key, "size")) m->size = (int)v;
            else if (!strcmp(key, "transmit_normal_adaxial")) m->transmit_normal[0] = v;
            else m->transmit_normal[1] = v;
        }
    }
    sy_buffer_free(&buf);
    if (!rc && !have_format) rc = sy_fail(err, SY_EINPUT, "%s: not a leaf material (no [Leaf] format = 1)", path);
    if (!rc && (!m->albedo[0] || !m->normal[0]))
        rc = sy_fail(err, SY_EINPUT, "%s: names no albedo or normal map", path);
    return rc;
}
