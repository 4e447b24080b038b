/* sylva grow SPECIES -o tree.glb: a Weber-Penn tree of a library species as a
 * game-ready asset. */
#include <stdio.h>
#include <string.h>

#include "pipeline/commands.h"
#include "pipeline/tree_asset.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/progress.h"

int cmd_grow(int argc, char **argv, sy_cli *cli)
{
    const char *out_path = NULL, *species_name = NULL;
    sy_glb_args glb = sy_glb_args_default();
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &out_path, "OUT.glb", "output glTF binary"},
        {"--species", OPT_STRING, &species_name, "NAME", "a species of the library (species/library.tsv) instead of a file"},
        SY_GLB_OPTIONS(glb),
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "grow", "[SPECIES_FILE] -o OUT.glb",
        "Grow a procedural tree (Weber & Penn) from a species parameter file and write it as glTF.",
        "SPECIES_FILE is a tree-type .ini (docs/species.md); --species NAME picks one of the\n"
        "library's species instead. The same species and --seed give a byte-identical file.",
        opts, 0, 1};
    const char *pos[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, pos, 1, &n, SY_CLI_OUT_NONE, &rc)) return rc;
    if (!out_path || (n == 0) == (species_name == NULL)) {
        fprintf(stderr, "sylva grow: give one species (a file or --species NAME) and -o OUT.glb\n");
        return SY_EUSAGE;
    }
    if ((rc = sy_cli_check_outputs(&out_path, 1, pos, (size_t)n))) return rc;
    sy_tree_asset_options o = sy_tree_asset_options_default();
    sy_glb_args_apply(&glb, &o);
    sy_error err = {0};
    if (sy_tree_asset_options_check(&o, &err)) return sy_cli_report(&err);
    sy_species_params sp;
    rc = n ? sy_species_params_load(pos[0], &sp, &err) : sy_species_params_find(species_name, &sp, &err);
    if (rc) return sy_cli_report(&err);
    sy_skeleton skel;
    sy_leaves leaves = {0};
    double t0 = sy_now();
    rc = sy_grow_tree(&sp, cli->seed, &skel, &leaves, &err);
    double grow_s = sy_now() - t0;
    if (rc && n) { /* grow names the species; name the file it came from too */
        sy_error named;
        sy_fail(&named, rc, "%s: %s", pos[0], err.msg);
        err = named;
    }
    sy_tree_asset_report rep;
    if (rc == SY_OK) {
        o.seed = cli->seed;
        rc = sy_tree_asset_write(out_path, &skel, &leaves, &sp, &o, &rep, &err);
    }
    if (rc == SY_OK) {
        if (cli->json) {
            sy_json j;
            sy_cli_json_open(&j, NULL, out_path);
            sy_json_string(&j, "species", sp.name);
            sy_json_int(&j, "seed", (long long)cli->seed);
            sy_json_int(&j, "nodes", (long long)rep.nodes);
            sy_json_int(&j, "branches", (long long)rep.branches);
            sy_json_int(&j, "leaves", (long long)rep.leaves);
            sy_json_number(&j, "height", sy_skeleton_height(&skel));
            sy_json_int(&j, "bytes", (long long)rep.bytes);
            sy_tree_asset_report_lods_json(&j, &rep);
            sy_json_number(&j, "seconds_grow", grow_s);
            sy_json_number(&j, "seconds_mesh", rep.seconds_mesh);
            sy_json_number(&j, "seconds_export", rep.seconds_export);
            sy_cli_json_close(&j);
        } else if (!cli->quiet) {
            fprintf(stderr, "grew %s (seed %llu) in %.3f s\n", sp.name, (unsigned long long)cli->seed, grow_s);
            sy_tree_asset_report_text(&rep, out_path);
        }
    }
    sy_skeleton_free(&skel);
    sy_leaves_free(&leaves);
    sy_species_params_free(&sp);
    return rc ? sy_cli_report(&err) : 0;
}
