/* sylva scan SPECIES -o scan.las --truth truth.json: the virtual LiDAR
 * scanner. Grows a tree (or a plot of trees), scans it with a terrestrial,
 * mobile or airborne scanner, and writes the labelled points and the exact
 * truth. Both outputs are atomic, and a failure leaves neither. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "pipeline/commands.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/progress.h"
#include "stages/grow/grow.h"
#include "stages/ingest/ingest.h"
#include "stages/scan/scan.h"

/* One call's arguments: NAN and -1 mean "the scanner kind's default". */
typedef struct {
    const char *out_path, *truth_path, *kind_name, *species_list, *path_text;
    int positions, max_points, returns, trees, subrays, no_leaves, no_terrain, rect_leaves, lawn, neighbours, isolate;
    double forest, clip, step, vstep, density, noise, divergence, plot_size, radius, height, altitude, swath, overlap, speed,
        rotation, line_spacing, separation, max_range, understory, slope, aspect, roughness;
} scan_args;

static scan_args scan_args_default(void)
{
    scan_args v, *a = &v;
    memset(a, 0, sizeof *a);
    a->out_path = a->truth_path = a->kind_name = a->species_list = a->path_text = NULL;
    a->positions = a->max_points = a->returns = a->trees = a->subrays = -1;
    a->neighbours = a->isolate = 0;
    a->forest = 0;
    a->clip = NAN;
    a->no_leaves = a->no_terrain = a->rect_leaves = a->lawn = 0;
    a->step = a->vstep = a->density = a->noise = a->divergence = a->radius = a->height = a->altitude = a->swath =
        a->overlap = a->speed = a->rotation = a->line_spacing = a->separation = a->max_range = a->understory = NAN;
    a->plot_size = a->slope = a->aspect = 0;
    a->roughness = NAN;
    return v;
}

#define SET_D(field, v) \
    if (!isnan(v)) sc->field = v
#define SET_I(field, v) \
    if ((v) >= 0) sc->field = v

static int parse_kind(const char *name, sy_scanner_kind *kind)
{
    if (!name || strcmp(name, "terrestrial") == 0 || strcmp(name, "tls") == 0) *kind = SY_SCANNER_TERRESTRIAL;
    else if (strcmp(name, "mobile") == 0 || strcmp(name, "mls") == 0) *kind = SY_SCANNER_MOBILE;
    else if (strcmp(name, "airborne") == 0 || strcmp(name, "als") == 0) *kind = SY_SCANNER_AIRBORNE;
    else return 0;
    return 1;
}

/* "x,y,x,y,..." into pairs. */
static int parse_path(const char *text, double **out, size_t *n)
{
    size_t cap = 1;
    for (const char *p = text; *p; p++) cap += *p == ',';
    double *v = malloc(cap * sizeof *v);
    if (!v) return 0;
    size_t k = 0;
    const char *p = text;
    for (;;) {
        char *end;
        errno = 0;
        v[k] = strtod(p, &end);
        if (errno || end == p || !isfinite(v[k])) break;
        k++;
        if (*end == '\0') {
            if (k % 2 || k < 4) break;
            *out = v;
            *n = k / 2;
            return 1;
        }
        if (*end != ',') break;
        p = end + 1;
    }
    free(v);
    return 0;
}

static void configure(const scan_args *a, sy_scan_options *sc, const sy_cli *cli)
{
    sc->seed = cli->seed;
    SET_I(positions, a->positions);
    SET_D(radius, a->radius);
    SET_D(height, a->height);
    SET_D(step_deg, a->step);
    SET_D(vstep_deg, a->vstep);
    SET_D(speed, a->speed);
    SET_D(rotation_hz, a->rotation);
    SET_D(line_spacing, a->line_spacing);
    SET_D(density, a->density);
    SET_D(altitude, a->altitude);
    SET_D(swath_deg, a->swath);
    SET_D(overlap, a->overlap);
    SET_D(noise, a->noise);
    SET_D(divergence_mrad, a->divergence);
    SET_I(subrays, a->subrays);
    SET_I(max_returns, a->returns);
    SET_D(separation, a->separation);
    SET_D(max_range, a->max_range);
    if (a->max_points >= 0) sc->max_points = (size_t)a->max_points;
    sc->lawnmower = a->lawn || a->plot_size > 0;
}

/* Splits the comma list in place into o->species. */
static int split_species(char *list, sy_scene_options *o)
{
    for (char *s = list, *e; s && *s; s = e) {
        e = strchr(s, ',');
        if (e) *e++ = '\0';
        if (!*s) continue;
        if (o->n_species == 32) return 0;
        o->species[o->n_species++] = s;
    }
    return o->n_species > 0;
}

static void print_report(const scan_args *a, const sy_cli *cli, const sy_scene *scene, const sy_scan_options *sc, const sy_scan_stats *st,
                         double seconds)
{
    size_t tree_pts = st->wood + st->leaf;
    double wood_fraction = tree_pts ? (double)st->wood / tree_pts : 0;
    if (cli->json) {
        sy_json j;
        sy_cli_json_open(&j, NULL, a->out_path);
        sy_json_string(&j, "truth", a->truth_path);
        sy_json_string(&j, "scanner", sy_scanner_kind_name(sc->kind));
        sy_json_int(&j, "seed", (long long)sc->seed);
        sy_json_int(&j, "point_count", (long long)st->points);
        sy_json_int(&j, "pulses", (long long)st->pulses);
        sy_json_int(&j, "stations", st->stations);
        sy_json_int(&j, "trees", (long long)scene->n_trees);
        sy_json_int(&j, "primitives", (long long)scene->prims.n);
        sy_json_int(&j, "wood_points", (long long)st->wood);
        sy_json_int(&j, "leaf_points", (long long)st->leaf);
        sy_json_int(&j, "ground_points", (long long)st->ground);
        sy_json_int(&j, "understory_points", (long long)st->understory);
        sy_json_number(&j, "wood_fraction", wood_fraction);
        sy_json_number(&j, "scan_seconds", st->seconds);
        sy_json_number(&j, "seconds", seconds);
        sy_cli_json_close(&j);
    } else if (!cli->quiet) {
        fprintf(stderr, "wrote %zu points (%zu pulses, %zu trees, wood fraction %.3f) to %s in %.2f s\n", st->points,
                st->pulses, scene->n_trees, wood_fraction, a->out_path, seconds);
    }
}

/* Truth into memory first, so a failure after the scan leaves nothing. */
static sy_code render_truth(const scan_args *a, const sy_scene *scene, const sy_scan_options *sc, int stations, char **buf, size_t *len,
                            sy_error *err)
{
    FILE *fp = open_memstream(buf, len);
    if (!fp) return sy_fail(err, SY_EINTERNAL, "%s: cannot buffer the truth file", a->truth_path);
    sy_write_truth(fp, scene, sc, stations);
    if (fclose(fp)) return sy_fail(err, SY_EINTERNAL, "%s: cannot buffer the truth file", a->truth_path);
    return SY_OK;
}

/* The cloud and its truth, staged and committed together, the truth (which
 * describes the cloud) last: a kill never leaves a truth beside another
 * scan's points. */
static sy_code write_outputs(const scan_args *a, const sy_cloud *cloud, const sy_scene *scene, const sy_scan_options *sc, int stations,
                             sy_error *err)
{
    sy_staged_output out[2];
    size_t n = 0;
    sy_code rc = sy_stage_output(&out[0], a->out_path, err);
    if (!rc) {
        n++;
        rc = sy_write_cloud(out[0].staged, cloud, err);
    }
    if (!rc && a->truth_path) {
        char *truth = NULL;
        size_t truth_len = 0;
        rc = render_truth(a, scene, sc, stations, &truth, &truth_len, err);
        if (!rc && !(rc = sy_stage_output(&out[1], a->truth_path, err))) {
            n++;
            rc = sy_write_file_atomic(out[1].staged, truth, truth_len, err);
        }
        free(truth);
    }
    if (!rc) return sy_stage_commit(out, n, err);
    sy_stage_abort(out, n);
    return rc;
}

int cmd_scan(int argc, char **argv, sy_cli *cli)
{
    scan_args args = scan_args_default(), *a = &args;
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &args.out_path, "OUT", "point cloud to write (.las: LAS 1.4 with extra bytes; .ply, .xyz)"},
        {"--truth", OPT_STRING, &args.truth_path, "FILE", "truth JSON (docs/truth-format.md)"},
        {"--scanner", OPT_STRING, &args.kind_name, "KIND", "terrestrial (default), mobile or airborne"},
        {"--positions", OPT_INT, &args.positions, "N", "terrestrial stations on a circle (default 4)"},
        {"--radius", OPT_DOUBLE, &args.radius, "M", "station circle / mobile circle radius (default: scene + 5 m, >= 10)"},
        {"--height", OPT_DOUBLE, &args.height, "M", "instrument height over ground (1.5 terrestrial, 1.8 mobile)"},
        {"--step", OPT_DOUBLE, &args.step, "DEG", "angular step (0.04 terrestrial, 0.25 mobile profiler)"},
        {"--vstep", OPT_DOUBLE, &args.vstep, "DEG", "terrestrial vertical step (default: --step)"},
        {"--speed", OPT_DOUBLE, &args.speed, "M/S", "platform speed (1.2 mobile, 50 airborne)"},
        {"--rotation", OPT_DOUBLE, &args.rotation, "HZ", "mobile profiler rotation rate (default 20)"},
        {"--path", OPT_STRING, &args.path_text, "X,Y,...", "mobile path polyline (default: a circle, or lawnmower in plots)"},
        {"--line-spacing", OPT_DOUBLE, &args.line_spacing, "M", "mobile lawnmower line spacing (default 10)"},
        {"--lawnmower", OPT_FLAG, &args.lawn, NULL, "mobile: lawnmower lines over the area (default in plots)"},
        {"--density", OPT_DOUBLE, &args.density, "PTS_PER_M2", "airborne pulses per m^2 over the area (default 20)"},
        {"--altitude", OPT_DOUBLE, &args.altitude, "M", "airborne flying height above ground (default 80)"},
        {"--swath", OPT_DOUBLE, &args.swath, "DEG", "airborne full scan angle (default 40)"},
        {"--overlap", OPT_DOUBLE, &args.overlap, "F", "airborne strip side overlap 0..0.9 (default 0.2)"},
        {"--noise", OPT_DOUBLE, &args.noise, "M", "range noise sigma (0.005 terrestrial, 0.015 mobile, 0.025 airborne)"},
        {"--divergence", OPT_DOUBLE, &args.divergence, "MRAD", "full beam divergence (0.3; 0.5 airborne; 0: one ray)"},
        {"--subrays", OPT_INT, &args.subrays, "N", "rays per pulse inside the beam, 1..16 (default 5)"},
        {"--returns", OPT_INT, &args.returns, "N", "most returns per pulse, 1..15 (default 4)"},
        {"--separation", OPT_DOUBLE, &args.separation, "M", "least range gap between returns (0.1; 0.5 airborne)"},
        {"--max-range", OPT_DOUBLE, &args.max_range, "M", "maximum range (150; 1500 airborne)"},
        {"--max-points", OPT_INT, &args.max_points, "N", "keep at most N points, spread evenly over the scan"},
        {"--plot", OPT_DOUBLE, &args.plot_size, "SIZE", "scan a SIZE x SIZE m plot of trees instead of one tree"},
        {"--trees", OPT_INT, &args.trees, "N", "trees in the plot (default 5)"},
        {"--species", OPT_STRING, &args.species_list, "LIST", "plot species, comma-separated (default quaking_aspen,black_oak,european_pine)"},
        {"--understory", OPT_DOUBLE, &args.understory, "PER_M2", "shrubs per m^2 (default 0.05 in plots, 0 otherwise)"},
        {"--slope", OPT_DOUBLE, &args.slope, "DEG", "terrain slope (default 0)"},
        {"--aspect", OPT_DOUBLE, &args.aspect, "DEG", "direction the terrain rises towards (default 0: +X)"},
        {"--roughness", OPT_DOUBLE, &args.roughness, "M", "terrain noise amplitude (default 0.05)"},
        {"--forest", OPT_DOUBLE, &args.forest, "F", "forest-grown habit 0..1: raised crown base, narrower crown (default 0)"},
        {"--neighbours", OPT_INT, &args.neighbours, "N", "single tree: N trees of its species around it, crowns touching (default 0)"},
        {"--clip", OPT_DOUBLE, &args.clip, "M", "keep the points within M metres of the (first) tree's stem, as plot segmentation does"},
        {"--isolate", OPT_FLAG, &args.isolate, NULL, "keep the (first) tree's own points and the ground under its crown: a perfect segmentation"},
        {"--no-leaves", OPT_FLAG, &args.no_leaves, NULL, "wood only"},
        {"--no-terrain", OPT_FLAG, &args.no_terrain, NULL, "no ground (and no understory)"},
        {"--rect-leaves", OPT_FLAG, &args.rect_leaves, NULL, "full rectangular leaf cards (default: the inscribed ellipse)"},
        {NULL, 0, NULL, NULL, NULL},
    };

    const sy_cmd_spec spec = {
        "scan", "[SPECIES_FILE_OR_NAME]",
        "Virtual LiDAR: grow a species tree (or a plot) and scan it, writing labelled points and the exact truth.",
        "Each point carries treeID, speciesID, isWood and branchID extra bytes, classification\n"
        "(2 ground, 4 understory, 5 trees), return numbers, intensity and gps_time. The same\n"
        "seed gives the same bytes for any --threads. See docs/scan.md.",
        opts, 0, 1};
    const char *pos[1];
    int n_pos, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, pos, 1, &n_pos, SY_CLI_OUT_REQUIRED, &rc)) return rc;
    sy_scanner_kind kind;
    if (!parse_kind(a->kind_name, &kind)) {
        fprintf(stderr, "sylva scan: --scanner must be terrestrial, mobile or airborne, got '%s'\n", a->kind_name);
        return SY_EUSAGE;
    }
    if (a->plot_size < 0 || (a->plot_size == 0 && n_pos == 0)) {
        fprintf(stderr, "sylva scan: give a species, or --plot SIZE (see --help)\n");
        return SY_EUSAGE;
    }
    /* A scan can take a while: a bad output path must fail before it. */
    const char *outs[2] = {a->out_path, a->truth_path};
    if ((rc = sy_cli_check_outputs(outs, 2, pos, (size_t)n_pos))) return rc;
    double t0 = sy_now();
    sy_scan_options sc;
    sc = sy_scan_options_for(kind);
    configure(a, &sc, cli);
    double *path = NULL;
    if (a->path_text) {
        if (!parse_path(a->path_text, &path, &sc.path_points)) {
            fprintf(stderr, "sylva scan: --path expects at least two x,y pairs, got '%s'\n", a->path_text);
            return SY_EUSAGE;
        }
        sc.path = path;
    }
    sy_scene_options so;
    so = sy_scene_options_default();
    so.seed = cli->seed;
    so.plot_size = a->plot_size;
    if (a->trees >= 0) so.trees = a->trees;
    if (!isnan(a->understory)) so.understory = a->understory;
    so.slope_deg = a->slope;
    so.aspect_deg = a->aspect;
    if (!isnan(a->roughness)) so.roughness = a->roughness;
    so.terrain = !a->no_terrain;
    so.leaves = !a->no_leaves;
    so.elliptic = !a->rect_leaves;
    so.forest = a->forest;
    so.neighbours = a->neighbours;
    sy_error check_err = {0};
    if (sy_scan_options_check(&sc, &check_err)) {
        free(path);
        return sy_cli_report(&check_err);
    }
    if (!isnan(a->clip) && !(a->clip > 0)) {
        fprintf(stderr, "sylva scan: --clip must be a positive radius in metres\n");
        free(path);
        return SY_EUSAGE;
    }
    char *list = strdup(a->species_list ? a->species_list : n_pos ? pos[0] : "quaking_aspen,black_oak,european_pine");
    if (!list || !split_species(list, &so)) {
        fprintf(stderr, "sylva scan: --species needs 1..32 comma-separated names\n");
        free(list);
        free(path);
        return SY_EUSAGE;
    }
    sy_error err = {0};
    if (sy_scene_options_check(&so, &err)) {
        free(list);
        free(path);
        return sy_cli_report(&err);
    }
    /* Every species must load before any progress is printed: a bad name
     * makes exactly one line of output. */
    for (int i = 0; i < so.n_species; i++) {
        sy_species_params sp;
        if (sy_species_params_find(so.species[i], &sp, &err)) {
            free(list);
            free(path);
            return sy_cli_report(&err);
        }
        sy_species_params_free(&sp);
    }
    sy_scene scene;
    if (!cli->quiet && !cli->json) fprintf(stderr, "growing %d tree(s)\n", a->plot_size > 0 ? so.trees : 1 + so.neighbours);
    double reach = (sc.radius > 0 ? sc.radius : 0) + 5;
    rc = sy_scene_build(&scene, &so, reach, &err);
    free(list);
    sy_cloud cloud;
    sy_scan_stats st = {0};
    memset(&cloud, 0, sizeof cloud);
    if (!rc && !cli->quiet && !cli->json)
        fprintf(stderr, "scene: %zu primitives, %zu tree(s); scanning (%s)\n", scene.prims.n, scene.n_trees,
                sy_scanner_kind_name(kind));
    if (!rc) rc = sy_scan(&scene, &sc, &cloud, &st, &err);
    if (!rc && a->isolate && scene.n_trees > 0)
        rc = sy_scan_isolate_tree(&cloud, scene.trees[0].tree_id, scene.trees[0].pos,
                                  0.5 * scene.trees[0].crown_width + 1, &st, &err);
    if (!rc && !isnan(a->clip) && scene.n_trees > 0)
        rc = sy_scan_clip_cylinder(&cloud, scene.trees[0].pos, a->clip, &st, &err);
    if (!rc) rc = write_outputs(a, &cloud, &scene, &sc, st.stations, &err);
    if (!rc) print_report(a, cli, &scene, &sc, &st, sy_now() - t0);
    sy_cloud_free(&cloud);
    sy_scene_free(&scene);
    free(path);
    return rc ? sy_cli_report(&err) : 0;
}
