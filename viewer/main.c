/* sylva-view: the GL preview (`sylva view` runs it). Parses the command line, reads every
 * glb through the project's glTF reader and the scan through ingest, then renders. */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#ifndef M_PI
#define M_PI 3.14159265358979323846 /* POSIX C11 does not define it */
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/fileio.h"
#include "stages/ingest/ingest.h"
#include "viewer/viewer.h"

sy_view_options sy_view_options_default(void)
{
    sy_view_options o;
    memset(&o, 0, sizeof o);
    o.width = 1280, o.height = 720;
    o.fps = 30;
    o.out_dir = NULL;
    o.wind = 1, o.wind_strength = 1.0, o.wind_dir_deg = 0, o.wind_stop = -1;
    o.translucency = 1, o.lod_override = -1;
    o.ground = 1, o.shadows = 1, o.stats = 1;
    o.sun_az = 80, o.sun_el = 45, o.turbidity = 3, o.ambient = 1, o.exposure = 1.0;
    o.copies = 1;
    o.show_points = 1;
    o.seed = 1;
    return o;
}

static const char *kUsage =
    "usage: sylva view FILE.glb|FOLDER... [options]\n"
    "  Interactive preview (a window), or headless through EGL with --screenshot/--frames.\n"
    "  --points SCAN           overlay the scan (any format sylva reads) in the asset's frame\n"
    "  --points-beside         put the scan beside the tree instead of over it\n"
    "  --screenshot OUT.png    render one frame headless and exit\n"
    "  --size WxH              image size (default 1280x720)\n"
    "  --camera AZ,EL[,DIST]   orbit angles in degrees, distance in metres (default: framed)\n"
    "  --target X,Y,Z          orbit centre in metres, glTF frame (default: the scene's centre)\n"
    "  --time T                wind time in seconds (default 0)\n"
    "  --frames N --fps F -o DIR   headless wind animation DIR/frame_NNNN.png\n"
    "  --no-wind  --wind-strength S  --wind-dir DEG  --wind-stop T\n"
    "  --no-translucency  --lod N  --grass  --no-ground  --no-shadows  --no-stats  --wireframe\n"
    "  --mask                  white silhouette on black (tests)\n"
    "  --sun AZ,EL  --turbidity T  --ambient K  --exposure E\n"
    "  --copies N  --spacing M lay out N copies of each tree on the ground\n"
    "  --json                  print camera, per-tree LOD, triangles, draw calls, frame time\n"
    "  --bench N               time N frames (headless)\n"
    "  --dump-wind OUT.csv     rest and swayed vertices of the first tree (transform feedback)\n"
    "  --static-load           wind as a steady push only (tests of the beam)\n"
    "  --seed N\n"
    "Keys: drag orbit, right-drag pan, wheel zoom, WASD/arrows move, PgUp/PgDn, F frame,\n"
    "  X wireframe, L LOD override, Space wind, +/- strength, [ ] direction, T translucency,\n"
    "  P scan overlay, G grass, J/K sun azimuth, U/I sun elevation, H stats, O screenshot, Q quit.\n";

static int bad(const char *what, const char *value)
{
    fprintf(stderr, "sylva view: %s '%s'\n", what, value ? value : "");
    return 2;
}

static int parse_list(const char *s, double *v, int min, int max)
{
    int n = 0;
    const char *p = s;
    while (n < max) {
        char *end;
        errno = 0;
        double x = strtod(p, &end);
        if (end == p || errno || !isfinite(x)) return -1;
        v[n++] = x;
        if (*end == 0) break;
        if (*end != ',') return -1;
        p = end + 1;
    }
    return n >= min && n <= max && (p == s || 1) ? n : -1;
}

static int glb_name(const char *n)
{
    size_t l = strlen(n);
    return l > 4 && (strcmp(n + l - 4, ".glb") == 0 || (l > 5 && strcmp(n + l - 5, ".gltf") == 0));
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* Appends a copy of name to the growing list; 0, or 3 when out of memory. */
static int push(char ***list, int *n, size_t *cap, const char *dir, const char *name)
{
    if ((size_t)*n == *cap) {
        size_t c = *cap ? *cap * 2 : 16;
        char **l2 = realloc(*list, c * sizeof(char *));
        if (!l2) return 3;
        *list = l2, *cap = c;
    }
    size_t len = (dir ? strlen(dir) + 1 : 0) + strlen(name) + 1;
    char *p = malloc(len);
    if (!p) return 3;
    if (dir) snprintf(p, len, "%s/%s", dir, name);
    else snprintf(p, len, "%s", name);
    (*list)[(*n)++] = p;
    return 0;
}

/* Files named, with each folder replaced by its glb/gltf files in name order. The list grows
 * in *out / *n_out (the caller frees it, also after a failure). */
static int expand(char **args, int n, char ***out, int *n_out)
{
    size_t cap = 0;
    for (int i = 0; i < n; i++) {
        if (!sy_is_directory(args[i])) {
            if (push(out, n_out, &cap, NULL, args[i])) return 3;
            continue;
        }
        DIR *d = opendir(args[i]);
        if (!d) return bad("cannot read the folder", args[i]);
        struct dirent *e;
        int first = *n_out;
        while ((e = readdir(d)))
            if (e->d_name[0] != '.' && glb_name(e->d_name) && push(out, n_out, &cap, args[i], e->d_name)) {
                closedir(d);
                return 3;
            }
        closedir(d);
        if (*n_out == first) return bad("no .glb files in the folder", args[i]);
        qsort(*out + first, (size_t)(*n_out - first), sizeof(char *), cmp_str);
    }
    return 0;
}

/* The scan in the first asset's glTF frame: world (Z up) minus asset.extras.origin, then
 * (x, y, z) -> (x, z, -y). */
static int load_points(const char *path, const sy_gltf_scene *s, sy_view_points *out)
{
    sy_cloud c;
    sy_error err = {0};
    if (sy_read_cloud(path, &c, &err) != SY_OK) {
        fprintf(stderr, "sylva view: %s\n", err.msg);
        return 2;
    }
    if (c.n == 0) {
        sy_cloud_free(&c);
        fprintf(stderr, "sylva view: %s: the scan has no points\n", path);
        return 2;
    }
    const size_t cap = 4000000; /* every k-th point beyond 4 M: enough to judge by eye */
    size_t step = c.n > cap ? (c.n + cap - 1) / cap : 1, n = (c.n + step - 1) / step;
    out->xyz = malloc(n * 3 * sizeof(float));
    out->rgb = malloc(n * 3 * sizeof(float));
    if (!out->xyz || !out->rgb) {
        sy_cloud_free(&c);
        return 3;
    }
    /* Without asset.extras.origin the asset's origin is the world's (grown trees stand there). */
    double shift[3];
    for (int k = 0; k < 3; k++) shift[k] = c.origin[k] - (s->has_origin ? s->origin[k] : 0.0);
    double zmin = HUGE_VAL, zmax = -HUGE_VAL;
    for (size_t i = 0; i < c.n; i += step) zmin = fmin(zmin, c.xyz[3 * i + 2]), zmax = fmax(zmax, c.xyz[3 * i + 2]);
    size_t k = 0;
    for (size_t i = 0; i < c.n; i += step, k++) {
        double x = c.xyz[3 * i] + shift[0], y = c.xyz[3 * i + 1] + shift[1], z = c.xyz[3 * i + 2] + shift[2];
        out->xyz[3 * k] = (float)x, out->xyz[3 * k + 1] = (float)z, out->xyz[3 * k + 2] = (float)-y;
        if (c.rgb) {
            for (int ch = 0; ch < 3; ch++) out->rgb[3 * k + ch] = c.rgb[3 * i + ch] / 65535.0f;
        } else {
            /* Magenta to orange by height: no tree is either colour. */
            float t = (float)((c.xyz[3 * i + 2] - zmin) / (zmax - zmin + 1e-9));
            out->rgb[3 * k] = 1.0f, out->rgb[3 * k + 1] = 0.15f + 0.55f * t, out->rgb[3 * k + 2] = 0.85f * (1 - t);
        }
    }
    out->n = k;
    sy_cloud_free(&c);
    return 0;
}

int main(int argc, char **argv)
{
    sy_view_options o = sy_view_options_default();
    char **files = calloc((size_t)argc + 1, sizeof(char *));
    int n_files = 0, rc = 0;
    char **paths = NULL;
    int n_paths = 0;
    sy_view_input in = {0};
    if (!files) return 3;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
#define NEXT() (i + 1 < argc ? argv[++i] : (fprintf(stderr, "sylva view: %s needs a value\n", a), exit(1), ""))
        double v[3];
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) { fputs(kUsage, stdout); goto out; }
        else if (!strcmp(a, "--points")) o.points = NEXT();
        else if (!strcmp(a, "--points-beside")) o.points_beside = 1;
        else if (!strcmp(a, "--screenshot")) o.screenshot = NEXT();
        else if (!strcmp(a, "--size")) {
            const char *s = NEXT();
            int w = 0, h = 0;
            char tail;
            if (sscanf(s, "%dx%d%c", &w, &h, &tail) != 2 || w < 16 || h < 16 || w > 16384 || h > 16384)
                { rc = bad("--size must be WxH with each side in 16..16384, not", s); goto out; }
            o.width = w, o.height = h;
        } else if (!strcmp(a, "--camera")) {
            const char *s = NEXT();
            int n = parse_list(s, v, 2, 3);
            if (n < 0 || fabs(v[1]) > 90 || (n == 3 && !(v[2] > 0 && v[2] < 1e6))) { rc = bad("--camera must be AZ,EL[,DIST] (|EL| <= 90, DIST > 0), not", s); goto out; }
            o.camera_set = 1, o.cam_az = v[0], o.cam_el = v[1], o.cam_dist = n == 3 ? v[2] : 0;
        } else if (!strcmp(a, "--target")) {
            const char *s = NEXT();
            if (parse_list(s, v, 3, 3) < 0) { rc = bad("--target must be X,Y,Z (metres, glTF frame), not", s); goto out; }
            o.target_set = 1, o.target[0] = v[0], o.target[1] = v[1], o.target[2] = v[2];
        } else if (!strcmp(a, "--time")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || fabs(v[0]) > 1e6) { rc = bad("--time must be seconds, not", s); goto out; }
            o.time = v[0];
        } else if (!strcmp(a, "--frames")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || v[0] < 1 || v[0] > 100000 || v[0] != floor(v[0])) { rc = bad("--frames must be 1..100000, not", s); goto out; }
            o.frames = (int)v[0];
        } else if (!strcmp(a, "--fps")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || !(v[0] > 0 && v[0] <= 1000)) { rc = bad("--fps must be in (0, 1000], not", s); goto out; }
            o.fps = v[0];
        } else if (!strcmp(a, "-o")) o.out_dir = NEXT();
        else if (!strcmp(a, "--no-wind")) o.wind = 0;
        else if (!strcmp(a, "--wind-strength")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || v[0] < 0 || v[0] > 20) { rc = bad("--wind-strength must be in 0..20, not", s); goto out; }
            o.wind_strength = v[0];
        } else if (!strcmp(a, "--wind-dir")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0) { rc = bad("--wind-dir must be degrees, not", s); goto out; }
            o.wind_dir_deg = v[0];
        } else if (!strcmp(a, "--wind-stop")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || v[0] < 0) { rc = bad("--wind-stop must be seconds >= 0, not", s); goto out; }
            o.wind_stop = v[0];
        } else if (!strcmp(a, "--static-load")) o.static_load = 1;
        else if (!strcmp(a, "--no-translucency")) o.translucency = 0;
        else if (!strcmp(a, "--lod")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || v[0] < 0 || v[0] >= SY_GLTF_MAX_LODS || v[0] != floor(v[0])) { rc = bad("--lod must be a level 0..15, not", s); goto out; }
            o.lod_override = (int)v[0];
        } else if (!strcmp(a, "--grass")) o.grass = 1;
        else if (!strcmp(a, "--no-ground")) o.ground = 0;
        else if (!strcmp(a, "--no-shadows")) o.shadows = 0;
        else if (!strcmp(a, "--no-stats")) o.stats = 0;
        else if (!strcmp(a, "--wireframe")) o.wireframe = 1;
        else if (!strcmp(a, "--mask")) o.mask = 1;
        else if (!strcmp(a, "--sun")) {
            const char *s = NEXT();
            if (parse_list(s, v, 2, 2) < 0 || v[1] < 0 || v[1] > 90) { rc = bad("--sun must be AZ,EL with EL in 0..90, not", s); goto out; }
            o.sun_az = v[0], o.sun_el = v[1];
        } else if (!strcmp(a, "--turbidity")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || v[0] < 1.7 || v[0] > 10) { rc = bad("--turbidity must be in 1.7..10, not", s); goto out; }
            o.turbidity = v[0];
        } else if (!strcmp(a, "--ambient")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || v[0] < 0 || v[0] > 100) { rc = bad("--ambient must be in 0..100, not", s); goto out; }
            o.ambient = v[0];
        } else if (!strcmp(a, "--exposure")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || !(v[0] > 0 && v[0] <= 100)) { rc = bad("--exposure must be in (0, 100], not", s); goto out; }
            o.exposure = v[0];
        } else if (!strcmp(a, "--copies")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || v[0] < 1 || v[0] > 100000 || v[0] != floor(v[0])) { rc = bad("--copies must be 1..100000, not", s); goto out; }
            o.copies = (int)v[0];
        } else if (!strcmp(a, "--spacing")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || !(v[0] > 0 && v[0] < 1e5)) { rc = bad("--spacing must be metres > 0, not", s); goto out; }
            o.spacing = v[0];
        } else if (!strcmp(a, "--json")) o.json = 1;
        else if (!strcmp(a, "--bench")) {
            const char *s = NEXT();
            if (parse_list(s, v, 1, 1) < 0 || v[0] < 1 || v[0] > 100000 || v[0] != floor(v[0])) { rc = bad("--bench must be 1..100000 frames, not", s); goto out; }
            o.bench = (int)v[0];
        } else if (!strcmp(a, "--dump-wind")) o.dump_wind = NEXT();
        else if (!strcmp(a, "--seed")) {
            const char *s = NEXT();
            char *end;
            errno = 0;
            unsigned long long x = strtoull(s, &end, 10);
            if (*s == '-' || end == s || *end || errno) { rc = bad("--seed must be a non-negative integer, not", s); goto out; }
            o.seed = x;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "sylva view: unknown option '%s' (sylva view --help)\n", a);
            rc = 1;
            goto out;
        } else
            files[n_files++] = argv[i];
#undef NEXT
    }
    if (n_files == 0) {
        fputs(kUsage, stderr);
        rc = 1;
        goto out;
    }
    if (o.frames > 0 && !o.out_dir) {
        fprintf(stderr, "sylva view: --frames needs -o DIR\n");
        rc = 1;
        goto out;
    }
    if ((rc = expand(files, n_files, &paths, &n_paths)) != 0) goto out;
    in.scenes = calloc((size_t)n_paths + 1, sizeof(sy_gltf_scene));
    in.paths = paths;
    if (!in.scenes) { rc = 3; goto out; }
    for (int i = 0; i < n_paths; i++) {
        sy_error err = {0};
        sy_code r = sy_gltf_read_scene(paths[i], &in.scenes[i], &err);
        if (r != SY_OK) {
            fprintf(stderr, "sylva view: %s\n", err.msg);
            rc = r;
            goto out;
        }
        in.n_scenes++;
    }
    if (o.points && (rc = load_points(o.points, &in.scenes[0], &in.points)) != 0) goto out;
    rc = sy_view_run(&in, &o);
out:
    for (size_t i = 0; i < in.n_scenes; i++) sy_gltf_scene_free(&in.scenes[i]);
    for (int i = 0; i < n_paths; i++) free(paths[i]);
    free(paths);
    free(in.scenes);
    free(in.points.xyz);
    free(in.points.rgb);
    free(files);
    return rc;
}
