/* sylva run SCAN -o tree.glb: the whole reconstruction of one scanned tree:
 * ingest -> preprocess -> skeleton -> lobes -> .sylva image -> decode ->
 * synthesis (species branchlets fill the lobes) -> mesh -> export,
 * optionally writing the .sylva image and keeping the hulls as a proxy. */
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
    sy_cli_json_open(&j, in, a->out_path);
    if (a->sylva_path) {
        sy_json_string(&j, "sylva", a->sylva_path);
        sy_json_int(&j, "sylva_bytes", (long long)res->sylva_size);
    }
    if (a->run.species) sy_json_string(&j, "species", a->run.species);
    else if (res->classified) {
        const sy_species_guess *g = &res->guess;
        sy_json_string(&j, "species", g->name);
        sy_json_object(&j, "classification");
        sy_json_string(&j, "best", g->best);
        sy_json_number(&j, "probability", g->probability);
        sy_json_bool(&j, "confident", g->confident);
        sy_json_number(&j, "novelty", g->novelty);
        sy_species_guess_rule_json(&j, g);
        sy_json_end(&j);
    }
    sy_json_int(&j, "points_in", (long long)res->points_in);
    sy_json_int(&j, "points_preprocessed", (long long)res->points_clean);
    sy_json_int(&j, "points_reconstructed", (long long)res->checks.points_after_thinning);
    sy_json_number(&j, "thinning_voxel", res->checks.thinning_voxel);
    sy_json_int(&j, "attempts", res->checks.attempts);
    sy_json_int(&j, "nodes", (long long)r->nodes);
    sy_json_int(&j, "branches", (long long)r->branches);
    sy_json_int(&j, "clusters", (long long)r->clusters);
    sy_json_number(&j, "lobe_size", r->lobe_size);
    sy_json_int(&j, "cluster_points", (long long)r->cluster_points);
    sy_json_int(&j, "twig_nodes", (long long)res->hulls.twig_nodes);
    sy_json_number(&j, "twig_voxel", res->hulls.twig_voxel);
    sy_json_number(&j, "dbh", r->dbh);
    sy_json_bool(&j, "dbh_fitted", r->dbh_fitted);
    sy_json_int(&j, "hairpins", (long long)r->hairpins);
    sy_json_int(&j, "radii_capped", (long long)r->radii_capped);
    sy_json_int(&j, "limb_kinks", (long long)r->limb_kinks);
    sy_json_number(&j, "limb_turn_max", r->limb_turn_max);
    sy_json_bool(&j, "stem_rebuilt", r->stem_rebuilt);
    sy_json_bool(&j, "stem_unseen", r->stem_unseen);
    if (r->stem_unseen) sy_json_number(&j, "crown_gap", r->crown_gap);
    sy_json_number(&j, "stem_excursion", r->stem_excursion);
    sy_json_number(&j, "stem_fork", r->stem_fork);
    sy_json_bool(&j, "crown_regrown", r->crown_regrown);
    sy_json_number(&j, "trunk_meander", r->trunk_meander);
    sy_json_number(&j, "crown_fill", r->crown_fill);
    sy_json_number(&j, "roof_gap", r->roof_gap);
    sy_json_number(&j, "roof_gap_species", r->roof_gap_species);
    sy_json_bool(&j, "roofed", r->roofed);
    if (r->crown_regrown) sy_json_number(&j, "crown_base", r->crown_base);
    sy_json_number(&j, "height", r->height);
    sy_json_int(&j, "hull_triangles", (long long)res->asset.hull_triangles);
    sy_json_int(&j, "lod0_bark_triangles", (long long)(res->asset.bark_triangles[0] - res->asset.hull_triangles));
    sy_json_int(&j, "lod0_leaf_instances", (long long)res->asset.leaf_cards[0]);
    sy_json_int(&j, "patches", (long long)res->synth.patches);
    sy_json_int(&j, "leaves", (long long)res->synth.leaves);
    sy_json_int(&j, "hidden_limb_nodes", (long long)res->synth.scaffold_nodes);
    sy_json_int(&j, "bare_nodes_pruned", (long long)res->synth.nodes_pruned);
    sy_json_bool(&j, "leaf_off", res->leaf_off);
    if (!isnan(res->returns_on_wood)) sy_json_number(&j, "returns_on_wood", res->returns_on_wood);
    sy_json_number(&j, "leaf_size", res->synth.leaf_size);
    sy_json_int(&j, "lobes_bare", (long long)res->synth.lobes_bare);
    sy_json_number(&j, "lobe_coverage", res->synth.coverage);
    sy_json_number(&j, "lobe_fill", res->synth.fill);
    sy_json_number(&j, "leaves_in_hull",
                   res->synth.leaves ? (double)res->synth.leaves_in_hull / (double)res->synth.leaves : 0);
    sy_tree_asset_report_lods_json(&j, &res->asset);
    sy_json_int(&j, "bytes", (long long)res->asset.bytes);
    sy_json_object(&j, "seconds");
    sy_json_number(&j, "ingest", res->t_ingest);
    sy_json_number(&j, "preprocess", res->t_preprocess);
    sy_json_number(&j, "skeleton", r->t_total - r->t_clusters);
    sy_json_number(&j, "clusters", r->t_clusters + res->hulls.seconds);
    sy_json_number(&j, "synthesize", res->t_synth);
    sy_json_number(&j, "mesh", res->asset.seconds_mesh);
    sy_json_number(&j, "export", res->asset.seconds_export);
    sy_json_end(&j);
    sy_cli_json_close(&j);
}

static void step_line(void *ctx, const char *step, double seconds, const char *detail)
{
    (void)ctx;
    fprintf(stderr, "sylva run: %-10s %7.3f s  %s\n", step, seconds, detail);
}

int cmd_run(int argc, char **argv, sy_cli *cli)
{
    run_args a = {NULL, NULL, sy_run_tree_options_default(), sy_glb_args_default()};
    sy_photo_cli photo;
    memset(&photo, 0, sizeof photo);
    int no_classify = 0, max_points = SY_POINT_BUDGET, leaf_off = 0, leaves = 0;
    const char *roof = "auto";
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &a.out_path, "OUT.glb", "output glTF binary"},
        {"--sylva", OPT_STRING, &a.sylva_path, "OUT.sylva", "also write the compact .sylva file of the reconstruction"},
        {"--species", OPT_STRING, &a.run.species, "NAME",
         "library species: its beta/gamma, branchlets, bark and leaf materials (default: the classifier's answer,\n"
         "else default.lsys and plain materials)"},
        {"--proxy", OPT_FLAG, &a.run.proxy, NULL, "also draw the lobe hulls as a semi-transparent foliage_proxy mesh"},
        {"--leaf-off", OPT_FLAG, &leaf_off, NULL,
         "a leaf-off scan (bare branches): lobes with traced twigs keep them as their wood, no leaf cards (default:\n"
         "so when at least 80 % of the returns lie within a scan spacing of that wood, traced at 1.5 spacings or coarser)"},
        {"--leaves", OPT_FLAG, &leaves, NULL, "leaf cards whatever the scan (a leaf-off scan dressed in leaves)"},
        {"--roof", OPT_STRING, &roof, "auto|on|off",
         "lobes reach up to the crown's roof, the top the stations saw through the lower crown (default auto:\n"
         "a terrestrial scan whose top stands 1.5 times, and 3 % of its height, further under its roof than its\n"
         "species' own crown)"},
        {"--lobe-size", OPT_DOUBLE, &a.run.lobe_size, "F",
         "largest lobe as a share of the tree's extent, in [0,1]; 0: one cluster per cut (default 0.1, a crown\n"
         "of fronds 1; cut again larger, up to 7.5x and at most 1, where the .sylva cannot hold that many lobes)"},
        {"--model", OPT_STRING, &a.run.model, "MODEL.sjb", "species classifier used without --species (default: the shipped one)"},
        {"--no-classify", OPT_FLAG, &no_classify, NULL, "without --species, keep the default parameters and materials"},
        {"--beta", OPT_DOUBLE, &a.run.beta, "B", "Dijkstra edge weight |u-v|^B (default: species, else 1)"},
        {"--gamma", OPT_DOUBLE, &a.run.gamma, "G", "allometry exponent (default: species, else 2)"},
        {"--fs", OPT_DOUBLE, &a.run.fs, "F", "scan-density factor f_s in (0,1]; smaller gives larger clusters (default 1)"},
        {"--wood-share", OPT_DOUBLE, &a.run.wood_share, "W",
         "wood/leaf separation: wood = shortest-path subtrees of >= W of the points (e.g. 0.005; default 0 = off)"},
        {"--max-points", OPT_INT, &max_points, "N",
         "voxel-thin denser scans to at most N points after preprocessing (default 300000; 0: never)"},
        {"--voxel", OPT_DOUBLE, &a.run.voxel, "SIZE", "thin the scan to one point per SIZE-metre voxel (default off)"},
        {"--spread-around", OPT_FLAG, &a.run.spread_around, NULL,
         "judge a level set's spread from the skeleton around its node, not its edge (leaf-off scans)"},
        {"--keep-hairpins", OPT_FLAG, &a.run.keep_hairpins, NULL,
         "leave chains that climb one limb and come down another as they are (default: turn them to grow up "
         "from the wood below)"},
        {"--fair-limbs", OPT_DOUBLE, &a.run.fair_sigma, "S",
         "smooth each limb along its length over S times its radius (default 4; 0: off)"},
        {"--return-cap", OPT_DOUBLE, &a.run.return_cap, "F",
         "no limb thicker than F times the median distance of its returns (default 2; 0: off)"},
        SY_GLB_OPTIONS(a.glb),
        SY_PHOTO_OPTIONS(photo),
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "run", "SCAN|PHOTOS/ -o OUT.glb [--sylva OUT.sylva]",
        "Reconstruct one scanned tree and write it as glTF: bark mesh, leaf instances, LODs, impostor.",
    "Steps: ingest, preprocess (up axis, statistical outliers, ground classified and removed;\n"
    "the defaults of `sylva preprocess`), skeleton and alpha-shape lobes (docs/skeleton.md),\n"
    "the compact .sylva image, then from that image (so `sylva mesh OUT.sylva` makes the same\n"
    "tree) synthesis: the species' L-system branchlets fill each lobe (docs/synthesize.md); mesh\n"
    "(one bark mesh, leaf instances whose stored order drives the LOD chain, impostor), export.\n"
    "--proxy adds the hulls as one semi-transparent \"foliage_proxy\" mesh. The glb is centred at the tree's base, its world\n"
    "position in asset.extras.origin (as `sylva mesh` does). SCAN must hold one tree. The .sylva species id\n"
    "is the species' library id plus one (0: unknown). Without --species the tree is classified\n"
    "first (docs/classify.md): a confident answer's parameters, branchlets and materials are used, an\n"
    "unknown tree keeps the defaults. A folder of photos is turned into points first, as\n"
    "`sylva photogrammetry` does (give --scale-ref or --camera-spacing for metres).",
        opts, 1, 1};
    const char *in[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, in, 1, &n, SY_CLI_OUT_REQUIRED, &rc)) return rc;
    if (a.sylva_path && strcmp(a.sylva_path, a.out_path) == 0) {
        fprintf(stderr, "sylva run: -o and --sylva name the same file\n");
        return SY_EUSAGE;
    }
    const char *outs[2] = {a.out_path, a.sylva_path};
    if ((rc = sy_cli_check_outputs(outs, 2, in, 1))) return rc;
    sy_glb_args_apply(&a.glb, &a.run.asset);
    a.run.sylva = a.sylva_path != NULL;
    a.run.classify = !no_classify;
    if (max_points < 0) {
        fprintf(stderr, "sylva run: --max-points must be >= 0\n");
        return SY_EUSAGE;
    }
    a.run.max_points = (size_t)max_points;
    if (leaf_off && leaves) {
        fprintf(stderr, "sylva run: --leaf-off and --leaves contradict each other\n");
        return SY_EUSAGE;
    }
    a.run.leaf_off = leaf_off ? 1 : leaves ? -1 : 0;
    if (strcmp(roof, "auto") && strcmp(roof, "on") && strcmp(roof, "off")) {
        fprintf(stderr, "sylva run: --roof must be auto, on or off, not '%s'\n", roof);
        return SY_EUSAGE;
    }
    a.run.roof = !strcmp(roof, "on") ? 1 : !strcmp(roof, "off") ? 0 : -1;
    a.run.seed = cli->seed;
    if (!cli->quiet && !cli->json) a.run.on_step = step_line;
    sy_error err = {0};
    if (sy_run_tree_options_check(&a.run, &err)) return sy_cli_report(&err);
    sy_run_tree_result res;
    if (sy_is_directory(in[0]) && sy_photogrammetry_count_images(in[0]) >= 3) {
        /* photos, not a scan: COLMAP first, then the tree from its points */
        sy_photogrammetry_result pr;
        if (sy_photos_to_cloud(in[0], a.out_path, &photo, cli, &pr, &err)) return sy_cli_report(&err);
        sy_cloud cloud = pr.cloud;
        memset(&pr.cloud, 0, sizeof pr.cloud);
        sy_photogrammetry_result_free(&pr);
        rc = sy_run_tree_cloud(&cloud, in[0], &a.run, &res, &err);
    } else {
        rc = sy_run_tree(in[0], &a.run, &res, &err);
    }
    if (rc || sy_run_tree_write(&res, a.out_path, a.sylva_path, &err)) {
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
