/* sylva decode FILE.sylva [-o OUT]: reads a .sylva file back and summarises
 * it; -o writes what it holds as JSON (the whole file, `sylva encode` takes
 * it back) or the skeleton alone in an interchange format. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "pipeline/commands.h"
#include "stages/core/json.h"
#include "stages/core/fileio.h"
#include "stages/qsm/sylva_json.h"
#include "stages/qsm/qsm.h"


int cmd_decode(int argc, char **argv, sy_cli *cli)
{
    const char *out_path = NULL;
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &out_path, "OUT", "also write it out: .json (everything), or the skeleton as .ply .csv .obj"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "decode", "FILE.sylva [-o OUT]", "Read a .sylva tree file and summarise what it holds.",
        "Prints species, seed, skeleton and cluster counts, hull sizes and the quantisation grid\n"
        "(see docs/sylva-format.md). -o OUT.json writes the whole file as a \"sylva-tree\" JSON\n"
        "(world coordinates; `sylva encode OUT.json -o X.sylva` gives the same file back byte for\n"
        "byte); -o OUT.ply/.csv/.obj writes the skeleton alone (docs/qsm-formats.md).",
        opts, 1, 1};
    const char *in[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, in, 1, &n, SY_CLI_OUT_NONE, &rc)) return rc;
    char ext[16] = "";
    if (out_path) sy_extension(out_path, ext, sizeof ext);
    if (out_path && strcmp(ext, "json") && strcmp(ext, "ply") && strcmp(ext, "csv") && strcmp(ext, "obj")) {
        fprintf(stderr, "sylva decode: %s: unknown output extension (use .json, .ply, .csv or .obj)\n", out_path);
        return SY_EUSAGE;
    }
    if (out_path && (rc = sy_cli_check_outputs(&out_path, 1, in, 1))) return rc;
    sy_skeleton s;
    sy_clusters cl;
    sy_sylva_meta meta;
    sy_error err = {0};
    if (sy_decode_read(in[0], &s, &cl, &meta, &err)) return sy_cli_report(&err);
    if (out_path) {
        rc = strcmp(ext, "json") == 0 ? sy_sylva_json_write(out_path, &s, &cl, &meta, &err)
                                      : sy_skeleton_write(out_path, &s, &err);
        if (rc) {
            sy_skeleton_free(&s);
            sy_clusters_free(&cl);
            return sy_cli_report(&err);
        }
    }
    size_t verts = 0, tris = 0, twigs = 0, kinds[3] = {0, 0, 0};
    for (size_t c = 0; c < cl.n; c++) {
        verts += cl.items[c].n_verts;
        twigs += cl.items[c].n_twigs;
        tris += cl.items[c].n_tris;
        kinds[cl.items[c].hull]++;
    }
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < s.n; i++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], s.origin[k] + s.pos[3 * i + k]);
            hi[k] = fmax(hi[k], s.origin[k] + s.pos[3 * i + k]);
        }
    double step = ldexp(1.0, meta.quant.step_log2);
    if (cli->json) {
        sy_json j;
        sy_json_begin(&j, stdout, 0);
        sy_json_object(&j, NULL);
        sy_json_string(&j, "file", in[0]);
        sy_json_int(&j, "species_id", meta.species_id);
        char seed[32]; /* as a string: a 64-bit seed does not fit a JSON double */
        snprintf(seed, sizeof seed, "%llu", (unsigned long long)meta.seed);
        sy_json_string(&j, "seed", seed);
        sy_json_bool(&j, "leaf_off", (meta.flags & SY_SYLVA_LEAF_OFF) != 0);
        sy_json_int(&j, "nodes", (long long)s.n);
        sy_json_int(&j, "branches", sy_skeleton_branch_count(&s));
        sy_json_number(&j, "skeleton_length", sy_skeleton_length(&s));
        sy_json_number(&j, "root_radius", s.radius[0]);
        sy_json_int(&j, "clusters", (long long)cl.n);
        sy_json_int(&j, "hull_vertices", (long long)verts);
        sy_json_int(&j, "hull_triangles", (long long)tris);
        sy_json_int(&j, "twig_nodes", (long long)twigs);
        sy_json_object(&j, "hulls");
        sy_json_int(&j, "alpha", (long long)kinds[0]);
        sy_json_int(&j, "convex", (long long)kinds[1]);
        sy_json_int(&j, "box", (long long)kinds[2]);
        sy_json_end(&j);
        sy_json_number(&j, "position_step", step);
        sy_json_numbers(&j, "skeleton_min", lo, 3);
        sy_json_numbers(&j, "skeleton_max", hi, 3);
        sy_json_end(&j);
        sy_json_finish(&j);
    } else {
        printf("%s: species %u, seed %llu%s\n", in[0], (unsigned)meta.species_id, (unsigned long long)meta.seed,
               meta.flags & SY_SYLVA_LEAF_OFF ? ", leaf-off" : "");
        printf("  skeleton  %zu nodes, %d branches, %.2f m of axes, root radius %.3f m\n", s.n,
               sy_skeleton_branch_count(&s), sy_skeleton_length(&s), s.radius[0]);
        printf("  clusters  %zu (%zu alpha, %zu convex, %zu box): %zu vertices, %zu triangles, %zu twig nodes\n", cl.n,
               kinds[0], kinds[1], kinds[2], verts, tris, twigs);
        printf("  grid      %.3g m steps\n", step);
    }
    sy_skeleton_free(&s);
    sy_clusters_free(&cl);
    return 0;
}
