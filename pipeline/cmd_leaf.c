/* sylva leaf PHOTO... -o DIR: leaf captures to albedo, normal, thickness,
 * translucency and HL2 maps, a leaf material file and an atlas; --species
 * installs them into the species library (docs/leafmaps.md). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "pipeline/commands.h"
#include "species/library.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/cloud.h"
#include "stages/core/color.h"
#include "stages/core/parallel.h"
#include "stages/ingest/ingest.h"
#include "stages/leafmaps/leaf_material.h"
#include "stages/leafmaps/leafmaps.h"
#include "stages/leafmaps/leafmaps_cv.h"

#define MAX_PHOTOS 16

/* One call's command line. */
typedef struct {
    const char *out_dir, *species_name, *library_dir, *back_lit, *flat_field, *height, *abaxial, *abaxial_back_lit,
        *abaxial_flat_field, *abaxial_height, *white, *synthetic_dir;
    double thickness, texel, leaf_length, height_scale, white_reflectance, tint[3];
    int size, no_orient, directions;
} leaf_args;

/* ------------------------------------------------------------- loading */

static sy_code load_photo(const char *path, sy_fimage *im, sy_error *err)
{
    int depth;
    if (access(path, R_OK) != 0) return sy_fail(err, SY_EINPUT, "%s: cannot open (%s)", path, strerror(errno));
    if (sy_lcv_read(path, &im->px, &im->w, &im->h, &im->c, &depth, err)) return err->code;
    if (depth != 8) {
        sy_fimage_free(im);
        return sy_fail(err, SY_EINPUT, "%s: a %d-bit image where an 8-bit sRGB photo is expected", path, depth);
    }
    if (im->c == 1) { /* grey photo: RGB */
        float *rgb = malloc((size_t)im->w * im->h * 3 * sizeof *rgb);
        if (!rgb) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
        for (size_t i = 0; i < (size_t)im->w * im->h; i++) rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = im->px[i];
        free(im->px);
        im->px = rgb;
        im->c = 3;
    }
    for (size_t i = 0; i < (size_t)im->w * im->h; i++)
        for (int c = 0; c < 3; c++) im->px[i * im->c + c] = (float)sy_srgb_to_linear(im->px[i * im->c + c]);
    return SY_OK;
}

/* A displacement scan as a point cloud (PLY, or any format ingest reads):
 * x, y, z in mm times `scale`, x right and y up in the photo, its bounding
 * box's corner (min x, max y) on the photo's top-left pixel, one photo pixel
 * = texel mm. Each pixel keeps the highest point; empty pixels take the
 * mean of their filled neighbours, grown outwards until none is left. */
static sy_code rasterize_scan(const char *path, double scale, double texel_mm, int w, int h, sy_fimage *im,
                              sy_error *err)
{
    if (!(texel_mm > 0)) return sy_fail(err, SY_EINPUT, "%s: a point-cloud scan needs --texel (photo pixel size)", path);
    sy_cloud c;
    sy_code rc = sy_read_cloud(path, &c, err);
    if (rc) return rc;
    if (c.n < 3) {
        sy_cloud_free(&c);
        return sy_fail(err, SY_EINPUT, "%s: a height scan needs points, it has %zu", path, c.n);
    }
    double xmin = 1e300, ymax = -1e300;
    for (size_t i = 0; i < c.n; i++) {
        double x = (c.origin[0] + c.xyz[3 * i]) * scale, y = (c.origin[1] + c.xyz[3 * i + 1]) * scale;
        if (x < xmin) xmin = x;
        if (y > ymax) ymax = y;
    }
    size_t n = (size_t)w * h;
    if ((rc = sy_fimage_alloc(im, w, h, 1, err))) {
        sy_cloud_free(&c);
        return rc;
    }
    unsigned char *filled = calloc(n, 1);
    if (!filled) rc = sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    size_t hits = 0;
    for (size_t i = 0; !rc && i < c.n; i++) {
        double x = (c.origin[0] + c.xyz[3 * i]) * scale, y = (c.origin[1] + c.xyz[3 * i + 1]) * scale;
        double z = (c.origin[2] + c.xyz[3 * i + 2]) * scale;
        long px = lround((x - xmin) / texel_mm), py = lround((ymax - y) / texel_mm);
        if (px < 0 || py < 0 || px >= w || py >= h) continue;
        size_t q = (size_t)py * w + (size_t)px;
        if (!filled[q] || z > im->px[q]) im->px[q] = (float)z, hits += !filled[q], filled[q] = 1;
    }
    sy_cloud_free(&c);
    if (!rc && hits == 0) rc = sy_fail(err, SY_EINPUT, "%s: no point falls on the photo", path);
    for (int pass = 0; !rc && hits < n && pass < w + h; pass++) {
        unsigned char *next = malloc(n);
        if (!next) {
            rc = sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
            break;
        }
        memcpy(next, filled, n);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                size_t q = (size_t)y * w + x;
                if (filled[q]) continue;
                double sum = 0;
                int k = 0;
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++) {
                        int xx = x + dx, yy = y + dy;
                        if (xx < 0 || yy < 0 || xx >= w || yy >= h || !filled[(size_t)yy * w + xx]) continue;
                        sum += im->px[(size_t)yy * w + xx], k++;
                    }
                if (k) im->px[q] = (float)(sum / k), next[q] = 1, hits++;
            }
        free(filled);
        filled = next;
    }
    free(filled);
    if (rc) sy_fimage_free(im);
    return rc;
}

static sy_code load_height(const char *path, double scale, sy_fimage *im, sy_error *err)
{
    int depth;
    char ext[16];
    sy_extension(path, ext, sizeof ext);
    if (strcmp(ext, "png") != 0) {
        /* A point cloud: rasterised once the photo's size is known. */
        im->w = im->h = 0;
        im->px = NULL;
        im->c = -1;
        return SY_OK;
    }
    if (access(path, R_OK) != 0) return sy_fail(err, SY_EINPUT, "%s: cannot open (%s)", path, strerror(errno));
    if (sy_lcv_read(path, &im->px, &im->w, &im->h, &im->c, &depth, err)) return err->code;
    if (depth != 16 || im->c != 1) {
        sy_fimage_free(im);
        return sy_fail(err, SY_EINPUT, "%s: a height scan must be a 16-bit grey PNG", path);
    }
    for (size_t i = 0; i < (size_t)im->w * im->h; i++) im->px[i] = (float)(im->px[i] * scale);
    return SY_OK;
}

/* -------------------------------------------------- synthetic captures */

static sy_code write_png(const char *dir, const char *name, const float *px, int w, int h, int c, int bits, sy_error *err)
{
    unsigned char *png;
    size_t n;
    if (sy_lcv_encode_png(px, w, h, c, bits, &png, &n, err)) return sy_error_prefix(err, name);
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    sy_code rc = sy_write_file_atomic(path, png, n, err);
    free(png);
    return rc;
}

static float *srgb_copy(const sy_fimage *im)
{
    size_t n = (size_t)im->w * im->h * im->c;
    float *o = malloc(n * sizeof *o);
    if (!o) return NULL;
    for (size_t i = 0; i < n; i++) o[i] = (float)sy_linear_to_srgb(im->px[i]);
    return o;
}

static int make_synthetic(const leaf_args *a, sy_cli *cli)
{
    sy_error err = {0};
    sy_leafmaps_options o = sy_leafmaps_options_default();
    sy_leaf_synthetic s;
    int n = a->size > 0 ? a->size : 512;
    const char *synthetic_dir = a->synthetic_dir;
    sy_code rc = sy_leaf_synthesize(n, cli->seed, 3.0, &o, &s, &err);
    if (rc) return sy_cli_report(&err);
    if (mkdir(synthetic_dir, 0777) != 0 && errno != EEXIST) {
        sy_leaf_synthetic_free(&s);
        sy_fail(&err, SY_EINPUT, "%s: cannot create folder (%s)", synthetic_dir, strerror(errno));
        return sy_cli_report(&err);
    }
    struct {
        const char *name;
        const sy_fimage *im;
    } photos[] = {{"adaxial.png", &s.reflected[0]},  {"adaxial_back_lit.png", &s.transmitted[0]},
                  {"abaxial.png", &s.reflected[1]},  {"abaxial_back_lit.png", &s.transmitted[1]},
                  {"flat_field.png", &s.flat_field}, {"truth_albedo.png", &s.albedo[0]}};
    for (size_t k = 0; !rc && k < sizeof photos / sizeof *photos; k++) {
        float *p = srgb_copy(photos[k].im);
        rc = p ? write_png(synthetic_dir, photos[k].name, p, n, n, 3, 8, &err) : sy_fail(&err, SY_EINTERNAL, "out of memory");
        free(p);
    }
    /* Scans: 16 bits over 1 mm, offset to mid-range. */
    for (int k = 0; !rc && k < 2; k++) {
        float *p = malloc((size_t)n * n * sizeof *p);
        if (!p) {
            rc = sy_fail(&err, SY_EINTERNAL, "out of memory");
            break;
        }
        for (size_t i = 0; i < (size_t)n * n; i++) p[i] = (float)fmin(1, fmax(0, 0.5 + s.height[k].px[i]));
        rc = write_png(synthetic_dir, k ? "abaxial_height.png" : "adaxial_height.png", p, n, n, 1, 16, &err);
        free(p);
    }
    if (!rc) {
        float *p = malloc((size_t)n * n * sizeof *p);
        for (size_t i = 0; p && i < (size_t)n * n; i++) p[i] = s.thickness.px[i];
        rc = p ? write_png(synthetic_dir, "truth_thickness_mm.png", p, n, n, 1, 16, &err) : SY_EINTERNAL;
        free(p);
    }
    if (!rc && !cli->quiet)
        fprintf(stderr,
                "synthetic capture in %s: texel %.4f mm, white reference %d,%d,%d,%d (reflectance %.2f); scans 1 mm full range\n",
                synthetic_dir, s.texel_mm, s.white_rect[0], s.white_rect[1], s.white_rect[2], s.white_rect[3],
                s.white_reflectance);
    if (!rc && cli->json) {
        sy_json j;
        sy_cli_json_open(&j, NULL, synthetic_dir);
        sy_json_number(&j, "texel_mm", s.texel_mm);
        sy_cli_json_close(&j);
    }
    sy_leaf_synthetic_free(&s);
    return rc ? sy_cli_report(&err) : 0;
}

/* ----------------------------------------------------------------- main */

int cmd_leaf(int argc, char **argv, sy_cli *cli)
{
    leaf_args a = {0};
    a.thickness = a.texel = a.leaf_length = -1;
    a.height_scale = 1, a.white_reflectance = 0.9;
    a.size = a.directions = -1;
    a.tint[0] = a.tint[1] = a.tint[2] = -1;
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &a.out_dir, "DIR", "output folder for the maps and leaf.material"},
        {"--species", OPT_STRING, &a.species_name, "NAME", "install the maps into the species library as NAME's leaf"},
        {"--library", OPT_STRING, &a.library_dir, "DIR", "species library folder (default: the one sylva finds)"},
        {"--back-lit", OPT_STRING, &a.back_lit, "IMG", "back-lit photo of the adaxial side (light behind the leaf)"},
        {"--flat-field", OPT_STRING, &a.flat_field, "IMG", "the back light alone, same exposure"},
        {"--height", OPT_STRING, &a.height, "SCAN", "displacement scan of the adaxial side (16-bit grey PNG, or PLY in mm)"},
        {"--abaxial", OPT_STRING, &a.abaxial, "IMG", "front-lit photo of the abaxial side (leaf turned over)"},
        {"--abaxial-back-lit", OPT_STRING, &a.abaxial_back_lit, "IMG", "back-lit photo of the abaxial side"},
        {"--abaxial-flat-field", OPT_STRING, &a.abaxial_flat_field, "IMG", "flat field of the abaxial back-lit photo"},
        {"--abaxial-height", OPT_STRING, &a.abaxial_height, "SCAN", "displacement scan of the abaxial side"},
        {"--height-scale", OPT_DOUBLE, &a.height_scale, "MM", "mm of a PNG scan's full 16-bit range, or per PLY unit (default 1)"},
        {"--white", OPT_STRING, &a.white, "X,Y,W,H", "grey/white reference rectangle in the adaxial photo (pixels)"},
        {"--white-reflectance", OPT_DOUBLE, &a.white_reflectance, "R", "reflectance of that reference (default 0.9)"},
        {"--thickness", OPT_DOUBLE, &a.thickness, "MM", "measured leaf thickness, the thickness map's anchor (default 0.2)"},
        {"--texel", OPT_DOUBLE, &a.texel, "MM", "size of one photo pixel on the leaf (default: from --leaf-length)"},
        {"--leaf-length", OPT_DOUBLE, &a.leaf_length, "MM", "leaf length along its axis when --texel is not given (default 80)"},
        {"--size", OPT_INT, &a.size, "N", "maps are N x N texels, a power of two (default 1024)"},
        {"--directions", OPT_INT, &a.directions, "N", "light directions of the HL2 projection (default 128)"},
        {"--no-orient", OPT_FLAG, &a.no_orient, NULL, "keep the photo's orientation (default: petiole down, axis vertical)"},
        {"--tint", OPT_DOUBLE3, a.tint, "R,G,B",
         "recolour the front-lit photos to this mean leaf colour (sRGB 0-255), each texel keeping its luminance (an autumn photo made summer)"},
        {"--synthetic-capture", OPT_STRING, &a.synthetic_dir, "DIR",
         "write a synthetic capture set (photos, scans, truth) of --size pixels and stop"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "leaf", "PHOTO... (-o DIR | --species NAME)",
        "Leaf maps from photos: albedo, normal, thickness, translucency and Half-Life 2 translucency maps.",
        "PHOTO is a front-lit photo of the leaf's adaxial side (or a plain photo of a leaf or twig card\n"
        "on a uniform or transparent background); the optional captures of the thesis setup refine it.\n"
        "Further PHOTOs are more leaves of the species for the atlas. Photos are 8-bit sRGB, scans 16-bit.\n"
        "Writes albedo.png, normal.png, thickness.png, translucency.png, hl2_adaxial.png, ... and\n"
        "leaf.material (docs/leafmaps.md); --species NAME installs them as NAME's leaf.",
        opts, 0, MAX_PHOTOS};
    const char *pos[MAX_PHOTOS];
    int n_pos, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, pos, MAX_PHOTOS, &n_pos, SY_CLI_OUT_NONE, &rc)) return rc;
    const char *out_dir = a.out_dir, *species_name = a.species_name, *library_dir = a.library_dir, *white = a.white;
    double thickness = a.thickness, texel = a.texel, leaf_length = a.leaf_length, height_scale = a.height_scale;
    int size = a.size, directions = a.directions;
    const char *extra_path[7] = {a.back_lit, a.flat_field, a.height, a.abaxial, a.abaxial_back_lit, a.abaxial_flat_field,
                                 a.abaxial_height};
    if (a.synthetic_dir) return make_synthetic(&a, cli);
    if (n_pos < 1 || (!out_dir && !species_name)) {
        fprintf(stderr, "sylva leaf: give at least one PHOTO and -o DIR or --species NAME\n");
        return SY_EUSAGE;
    }
    sy_leafmaps_options o = sy_leafmaps_options_default();
    if (thickness >= 0) o.thickness_mm = thickness;
    if (texel >= 0) o.texel_mm = texel;
    if (leaf_length >= 0) o.leaf_length_mm = leaf_length;
    if (size >= 0) o.size = size;
    if (directions >= 0) o.directions = directions;
    o.orient = !a.no_orient;
    if (a.tint[0] >= 0 || a.tint[1] >= 0 || a.tint[2] >= 0) memcpy(o.tint, a.tint, sizeof o.tint);
    o.seed = cli->seed;
    o.progress = !cli->quiet && !cli->json;
    sy_error err = {0};
    if (!(height_scale > 0 && height_scale < 1000)) {
        fprintf(stderr, "sylva leaf: --height-scale %g is outside (0, 1000) mm\n", height_scale);
        return SY_EUSAGE;
    }
    if (sy_leafmaps_options_check(&o, &err)) {
        fprintf(stderr, "sylva leaf: %s\n", err.msg);
        return SY_EUSAGE;
    }
    sy_leaf_capture cap;
    memset(&cap, 0, sizeof cap);
    cap.white_reflectance = a.white_reflectance;
    if (white && (sscanf(white, "%d,%d,%d,%d", &cap.white_rect[0], &cap.white_rect[1], &cap.white_rect[2],
                         &cap.white_rect[3]) != 4 ||
                  cap.white_rect[2] <= 0 || cap.white_rect[3] <= 0)) {
        fprintf(stderr, "sylva leaf: --white wants X,Y,W,H in pixels, not '%s'\n", white);
        return SY_EUSAGE;
    }
    /* Library: the species must exist before anything is computed. */
    char library[4096] = "";
    if (species_name) {
        if (!sy_leaf_material_valid_name(species_name)) {
            fprintf(stderr, "sylva leaf: --species '%s' is not a species name (letters, digits, _ and -)\n", species_name);
            return SY_EUSAGE;
        }
        sy_library lib;
        if (sy_library_load(library_dir, &lib, &err)) return sy_cli_report(&err);
        snprintf(library, sizeof library, "%s", lib.dir);
        int known = sy_library_find(&lib, species_name) != NULL;
        sy_library_free(&lib);
        if (!known) {
            sy_fail(&err, SY_EINPUT, "%s: no such species in the library (%s/library.tsv)", species_name, library);
            return sy_cli_report(&err);
        }
    }
    sy_fimage photos[MAX_PHOTOS] = {{0}};
    sy_fimage extra[7] = {{0}}; /* back-lit, flat, height, abaxial, abaxial back-lit, abaxial flat, abaxial height */
    for (int k = 0; !rc && k < n_pos; k++) rc = load_photo(pos[k], &photos[k], &err);
    for (int k = 0; !rc && k < 7; k++) {
        if (!extra_path[k]) continue;
        rc = (k == 2 || k == 6) ? load_height(extra_path[k], height_scale, &extra[k], &err)
                                : load_photo(extra_path[k], &extra[k], &err);
    }
    for (int k = 2; !rc && k <= 6; k += 4)
        if (extra_path[k] && extra[k].c == -1)
            rc = rasterize_scan(extra_path[k], height_scale, texel > 0 ? texel : 0, photos[0].w, photos[0].h, &extra[k],
                                &err);
    sy_leaf_maps maps[MAX_PHOTOS];
    memset(maps, 0, sizeof maps);
    int built = 0;
    for (int k = 0; !rc && k < n_pos; k++) {
        memset(&cap.side, 0, sizeof cap.side);
        cap.side[0].reflected = &photos[k];
        if (k == 0) {
            cap.side[0].transmitted = extra[0].px ? &extra[0] : NULL;
            cap.side[0].flat_field = extra[1].px ? &extra[1] : NULL;
            cap.side[0].height = extra[2].px ? &extra[2] : NULL;
            cap.side[1].reflected = extra[3].px ? &extra[3] : NULL;
            cap.side[1].transmitted = extra[4].px ? &extra[4] : NULL;
            /* One back light: the adaxial flat field serves both sides. */
            cap.side[1].flat_field = !extra[4].px ? NULL : extra[5].px ? &extra[5] : extra[1].px ? &extra[1] : NULL;
            cap.side[1].height = extra[6].px ? &extra[6] : NULL;
        }
        int white_rect[4];
        memcpy(white_rect, cap.white_rect, sizeof white_rect);
        if (k > 0) memset(cap.white_rect, 0, sizeof cap.white_rect); /* the reference is in the first photo */
        if (o.progress) fprintf(stderr, "leaf %d/%d: %s\n", k + 1, n_pos, pos[k]);
        rc = sy_leafmaps_build(&cap, &o, &maps[k], &err);
        memcpy(cap.white_rect, white_rect, sizeof white_rect);
        if (rc) {
            sy_error named;
            sy_fail(&named, rc, "%s: %s", pos[k], err.msg);
            err = named;
        } else built++;
    }
    sy_leaf_files files;
    memset(&files, 0, sizeof files);
    if (!rc) rc = sy_leaf_material_encode(maps, built, pos, &o, &files, &err);
    char dest[4300];
    if (!rc && out_dir) rc = sy_leaf_files_write(&files, out_dir, &err);
    if (!rc && species_name) {
        snprintf(dest, sizeof dest, "%s/leafmaps/%s", library, species_name);
        rc = sy_leaf_files_install(&files, library, species_name, &err);
        /* The manifest lists the material among the species' files. */
        char rel[128];
        snprintf(rel, sizeof rel, "leafmaps/%s/%s", species_name, SY_LEAF_MATERIAL_FILE);
        if (!rc) rc = sy_library_add_file(library, species_name, rel, &err);
    }
    if (!rc) {
        const sy_leaf_maps *m = &maps[0];
        if (cli->json) {
            sy_json j;
            sy_cli_json_open(&j, NULL, out_dir);
            if (species_name) sy_json_string(&j, "species", species_name), sy_json_string(&j, "installed", dest);
            sy_json_int(&j, "leaves", built);
            sy_json_int(&j, "size", m->w);
            sy_json_number(&j, "texel_mm", m->texel_mm);
            sy_json_number(&j, "thickness_median_mm", m->thickness_median);
            sy_json_number(&j, "thickness_min_mm", m->thickness_min);
            sy_json_number(&j, "thickness_max_mm", m->thickness_max);
            sy_json_number(&j, "transmit_normal_adaxial", m->transmit_normal[0]);
            sy_json_number(&j, "transmit_normal_abaxial", m->transmit_normal[1]);
            sy_json_number(&j, "kernel_radius_mm", m->kernel_radius_mm);
            sy_json_int(&j, "energy_clamped", (long long)m->energy_clamped);
            sy_json_number(&j, "seconds", m->seconds[5]);
            sy_json_number(&j, "cpu_seconds", m->cpu_seconds);
            sy_cli_json_close(&j);
        } else if (!cli->quiet) {
            fprintf(stderr, "leaf maps: %d leaf(s), %dx%d texels of %.4f mm, thickness %.3f mm median (%.3f..%.3f)\n",
                    built, m->w, m->h, m->texel_mm, m->thickness_median, m->thickness_min, m->thickness_max);
            fprintf(stderr, "  written to %s%s%s in %.1f s (%.1f s CPU)\n", out_dir ? out_dir : "",
                    out_dir && species_name ? " and " : "", species_name ? dest : "", m->seconds[5], m->cpu_seconds);
        }
    }
    sy_leaf_files_free(&files);
    for (int k = 0; k < MAX_PHOTOS; k++) sy_leaf_maps_free(&maps[k]), sy_fimage_free(&photos[k]);
    for (int k = 0; k < 7; k++) sy_fimage_free(&extra[k]);
    return rc ? sy_cli_report(&err) : 0;
}
