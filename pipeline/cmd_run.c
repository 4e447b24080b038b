/* sylva run SCAN -o tree.glb: the whole reconstruction of one scanned tree:
 * ingest -> preprocess -> skeleton -> clusters -> mesh -> export, with the
 * cluster hulls as a semi-transparent foliage proxy and optionally the
 * compact .sylva file of the same reconstruction. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/commands.h"
#include "pipeline/run_tree.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"

typedef struct {
    const char *out_path, *sylva_path;
    sy_run_tree_options run;
    sy_glb_args glb;
} run_args;

static void print_json(const char *in, const run_args *a, const sy_run_tree_result *res)
{
    const sy_skeleton_report *r = &res->skeleton;
    sy_json j;
    sy_json_begin(&j, stdout, 0);
    sy_json_object(&j, NULL);
    sy_json_string(&j, "input", in);
    sy_json_string(&j, "output", a->out_path);
    if (a->sylva_path) {
        sy_json_string(&j, "sylva", a->sylva_path);
        sy_json_int(&j, "sylva_bytes", (long long)res->sylva_size);
    }
    if (a->run.species) sy_json_string(&j, "species", a->run.species);
    sy_json_int(&j, "points_in", (long long)res->points_in);
    sy_json_int(&j, "points_preprocessed", (long long)res->points_clean);
    sy_json_int(&j, "nodes", (long long)r->nodes);
    sy_json_int(&j, "branches", (long long)r->branches);
    sy_json_int(&j, "clusters", (long long)r->clusters);
    sy_json_int(&j, "cluster_points", (long long)r->cluster_points);
    sy_json_number(&j, "dbh", r->dbh);
    sy_json_bool(&j, "dbh_fitted", r->dbh_fitted);
    sy_json_number(&j, "height", r->height);
    sy_json_int(&j, "hull_triangles", (long long)res->asset.hull_triangles);
    sy_tree_asset_report_lods_json(&j, &res->asset);
    sy_json_int(&j, "bytes", (long long)res->asset.bytes);
    sy_json_object(&j, "seconds");
    sy_json_number(&j, "ingest", res->t_ingest);
    sy_json_number(&j, "preprocess", res->t_preprocess);
    sy_json_number(&j, "skeleton", r->t_total - r->t_clusters);
    sy_json_number(&j, "clusters", r->t_clusters + res->hulls.seconds);
    sy_json_number(&j, "mesh", res->asset.seconds_mesh);
    sy_json_number(&j, "export", res->asset.seconds_export);
    sy_json_end(&j);
    sy_json_end(&j);
    sy_json_finish(&j);
}

static void step_line(void *ctx, const char *step, double seconds, const char *detail)
{
    (void)ctx;
    fprintf(stderr, "sylva run: %-10s %7.3f s  %s\n", step, seconds, detail);
}

int cmd_run(int argc, char **argv, sy_cli *cli)
{
    run_args a = {NULL, NULL, sy_run_tree_options_default(), sy_glb_args_default()};
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &a.out_path, "OUT.glb", "output glTF binary"},
        {"--sylva", OPT_STRING, &a.sylva_path, "OUT.sylva", "also write the compact .sylva file of the reconstruction"},
        {"--species", OPT_STRING, &a.run.species, "NAME", "library species: its beta/gamma, bark and leaf materials"},
        {"--beta", OPT_DOUBLE, &a.run.beta, "B", "Dijkstra edge weight |u-v|^B (default: species, else 1)"},
        {"--gamma", OPT_DOUBLE, &a.run.gamma, "G", "allometry exponent (default: species, else 2)"},
        {"--fs", OPT_DOUBLE, &a.run.fs, "F", "scan-density factor f_s in (0,1]; smaller gives larger clusters (default 1)"},
        {"--wood-share", OPT_DOUBLE, &a.run.wood_share, "W",
         "wood/leaf separation: wood = shortest-path subtrees of >= W of the points (e.g. 0.005; default 0 = off)"},
        {"--voxel", OPT_DOUBLE, &a.run.voxel, "SIZE", "thin the scan to one point per SIZE-metre voxel (default off)"},
        {"--spread-around", OPT_FLAG, &a.run.spread_around, NULL,
         "judge a level set's spread from the skeleton around its node, not its edge (leaf-off scans)"},
        SY_GLB_OPTIONS(a.glb),
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "run", "SCAN -o OUT.glb [--sylva OUT.sylva]",
        "Reconstruct one scanned tree and write it as glTF: branch meshes plus cluster hulls.",
    "Steps: ingest, preprocess (up axis, statistical outliers, ground classified and removed;\n"
    "the defaults of `sylva preprocess`), skeleton and alpha-shape clusters (docs/skeleton.md),\n"
    "mesh (LOD chain, impostor), export. The hulls become one semi-transparent mesh with the\n"
    "material \"foliage_proxy\" in every level. The glb is centred at the tree's base, its world\n"
    "position in asset.extras.origin (as `sylva mesh` does). SCAN must hold one tree. The .sylva species id\n"
    "is the species' index in the library plus one (0: unknown).",
        opts, 1, 1};
    const char *in[1];
    int n;
    int rc = sy_cli_parse(&spec, argc, argv, cli, in, 1, &n);
    if (rc) return rc < 0 ? 0 : rc;
    sy_cli_apply_settings(cli);
    if (!a.out_path) {
        fprintf(stderr, "sylva run: -o OUT.glb is required\n");
        return SY_EUSAGE;
    }
    if (a.sylva_path && strcmp(a.sylva_path, a.out_path) == 0) {
        fprintf(stderr, "sylva run: -o and --sylva name the same file\n");
        return SY_EUSAGE;
    }
    sy_glb_args_apply(&a.glb, &a.run.asset);
    a.run.sylva = a.sylva_path != NULL;
    a.run.seed = cli->seed;
    if (!cli->quiet && !cli->json) a.run.on_step = step_line;
    sy_error err = {0};
    if (sy_run_tree_options_check(&a.run, &err)) return sy_cli_report(&err);
    sy_run_tree_result res;
    if (sy_run_tree(in[0], &a.run, &res, &err) || sy_run_tree_write(&res, a.out_path, a.sylva_path, &err)) {
        sy_run_tree_result_free(&res);
        return sy_cli_report(&err);
    }
    if (cli->json) print_json(in[0], &a, &res);
    else if (!cli->quiet)
        fprintf(stderr, "sylva run: wrote %s%s%s\n", a.out_path, a.sylva_path ? " and " : "",
                a.sylva_path ? a.sylva_path : "");
    sy_run_tree_result_free(&res);
    return 0;
}
