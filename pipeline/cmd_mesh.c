/* sylva mesh MODEL -o tree.glb: a skeleton or QSM from any tool (.sylva, .ply,
 * .csv, .json, .obj, TreeQSM text) to the same game-ready asset `sylva grow`
 * makes, optionally dressed with a species' bark, leaf material and leaves. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/commands.h"
#include "pipeline/tree_asset.h"
#include "pipeline/tree_synth.h"
#include "species/library.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/progress.h"
#include "stages/export/export.h"
#include "stages/qsm/leaf_placement.h"
#include "stages/qsm/qsm.h"
#include "stages/qsm/sylva_json.h"

/* Leaf density and size for models that name no species: a common
 * broadleaf (4.3 leaf cards a metre of twig, 0.55 m long on a tree of its
 * 13 m, smaller on smaller trees: sy_leaf_placement_fit_tree), the species of
 * the README's first example. Bark and leaf materials stay the neutral
 * defaults, so the asset claims no species. */
#define DEFAULT_LEAVES "quaking_aspen"

typedef struct {
    const char *model, *format;
    double height, twig_length, leaf_size, seconds_read, seconds_leaves;
    double origin[3];
} mesh_facts;

static void print_report(const sy_cli *cli, const char *out_path, const sy_tree_asset_report *rep, const mesh_facts *f,
                         const sy_species_params *sp)
{
    if (cli->json) {
        sy_json j;
        sy_cli_json_open(&j, f->model, NULL);
        sy_json_string(&j, "format", f->format);
        sy_json_string(&j, "output", out_path);
        if (sp) sy_json_string(&j, "species", sp->name);
        sy_json_int(&j, "seed", (long long)cli->seed);
        sy_json_numbers(&j, "origin", f->origin, 3);
        sy_json_int(&j, "nodes", (long long)rep->nodes);
        sy_json_int(&j, "branches", (long long)rep->branches);
        sy_json_int(&j, "leaves", (long long)rep->leaves);
        sy_json_int(&j, "hull_triangles", (long long)rep->hull_triangles);
        sy_json_number(&j, "twig_length", f->twig_length);
        sy_json_number(&j, "leaf_size", f->leaf_size);
        sy_json_number(&j, "height", f->height);
        sy_json_int(&j, "bytes", (long long)rep->bytes);
        sy_tree_asset_report_lods_json(&j, rep);
        sy_json_number(&j, "seconds_read", f->seconds_read);
        sy_json_number(&j, "seconds_leaves", f->seconds_leaves);
        sy_json_number(&j, "seconds_mesh", rep->seconds_mesh);
        sy_json_number(&j, "seconds_export", rep->seconds_export);
        sy_cli_json_close(&j);
    } else if (!cli->quiet) {
        fprintf(stderr, "read %s (%s) in %.3f s; root %.3f %.3f %.3f moved to the origin\n", f->model, f->format,
                f->seconds_read, f->origin[0], f->origin[1], f->origin[2]);
        if (rep->leaves)
            fprintf(stderr, "placed %zu %s leaves (%.3f m cards) on %.2f m of twig in %.3f s\n", rep->leaves,
                    sp ? sp->name : "default", f->leaf_size, f->twig_length, f->seconds_leaves);
        sy_tree_asset_report_text(rep, out_path);
    }
}

/* A .sylva image with lobes (path's, or the one its sylva-tree JSON encodes
 * to): decode and synthesise as `sylva run` does, with the file's species
 * (or species_name) and seed. Takes buf. */
static int mesh_sylva(const char *path, sy_buffer buf, const char *out_path, const char *species_name, int no_leaves,
                      int proxy, const sy_cli *cli, sy_tree_asset_options *o, mesh_facts *f)
{
    sy_error err = {0};
    sy_species_params sp;
    int have_species = 0;
    sy_code rc = SY_OK;
    uint16_t id = buf.size >= 8 ? (uint16_t)(buf.data[6] | buf.data[7] << 8) : 0;
    if (species_name) {
        rc = sy_species_params_find(species_name, &sp, &err);
        have_species = !rc;
    } else if (id > 0) {
        sy_library lib;
        if (!sy_library_load(NULL, &lib, &err)) {
            const sy_library_entry *e = sy_library_by_id(&lib, id - 1);
            if (e) {
                rc = sy_library_params(&lib, e, &sp, &err);
                have_species = !rc;
            }
            sy_library_free(&lib);
        }
    }
    sy_decoded_tree dt;
    double t0 = sy_now();
    if (!rc) rc = sy_decoded_tree_build(path, buf.data, buf.size, have_species ? &sp : NULL, no_leaves, &dt, &err);
    sy_buffer_free(&buf);
    if (!rc) {
        f->seconds_leaves = sy_now() - t0;
        memcpy(f->origin, dt.skel.origin, sizeof f->origin);
        f->height = sy_skeleton_height(&dt.skel);
        if (!cli->quiet && !cli->json) sy_decoded_tree_report_bare("mesh", &dt);
        o->seed = dt.meta.seed;
        o->keep_leaf_order = 1;
        o->hulls = proxy ? &dt.lobes : NULL;
        o->lean_radius = dt.lean_radius;
        o->source = f->model;
        o->source_format = f->format;
        sy_tree_asset_report rep;
        rc = sy_tree_asset_write(out_path, &dt.grown, dt.leaf_off ? NULL : &dt.leaves, have_species ? &sp : NULL, o,
                                 &rep, &err);
        if (!rc) print_report(cli, out_path, &rep, f, have_species ? &sp : NULL);
        sy_decoded_tree_free(&dt);
    }
    if (have_species) sy_species_params_free(&sp);
    return rc ? sy_cli_report(&err) : 0;
}

/* A "sylva-tree" JSON with lobes (sylva decode -o, edited or not) is the
 * .sylva it encodes to, and is meshed as that file is: read as a skeleton
 * alone it lost its lobes and came out a bare skeleton with default cards
 * (AdTree's tree13: IoU against its scan 0.52 against the .sylva's 0.63).
 * image->data stays NULL for any other JSON, and for a document without
 * lobes (a skeleton, meshed as one). */
static sy_code sylva_tree_image(const char *path, const sy_buffer *file, sy_buffer *image, sy_error *err)
{
    memset(image, 0, sizeof *image);
    sy_jv *doc = NULL;
    sy_code rc = sy_jv_parse(path, (const char *)file->data, file->size, NULL, &doc, err);
    const sy_jv *lobes = rc ? NULL : sy_jv_get(doc, "clusters");
    if (sy_sylva_json_is_tree(doc) && lobes && lobes->type == SY_JV_ARRAY && lobes->len > 0)
        rc = sy_sylva_json_encode(path, doc, &image->data, &image->size, err);
    sy_jv_free(doc);
    return rc;
}

int cmd_mesh(int argc, char **argv, sy_cli *cli)
{
    const char *out_path = NULL, *species_name = NULL;
    int no_leaves = 0, tree_index = -1, proxy = 0;
    double leaf_density = -1;
    sy_glb_args glb = sy_glb_args_default();
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &out_path, "OUT.glb", "output glTF binary"},
        {"--species", OPT_STRING, &species_name, "NAME", "bark, leaf material and leaves of a library species (or an .ini)"},
        {"--no-leaves", OPT_FLAG, &no_leaves, NULL, "no leaf cards (with --species: its materials only); a .sylva lobe with traced twigs keeps them as its wood"},
        {"--leaf-density", OPT_DOUBLE, &leaf_density, "N", "leaves per metre of twig (default: from the species, else " DEFAULT_LEAVES "'s)"},
        {"--tree", OPT_INT, &tree_index, "I", "which tree of a truth file with several (0-based)"},
        {"--proxy", OPT_FLAG, &proxy, NULL, ".sylva: also draw the lobe hulls as the semi-transparent foliage_proxy mesh"},
        SY_GLB_OPTIONS(glb),
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "mesh", "MODEL -o OUT.glb",
        "Mesh a skeleton or QSM (.sylva, .ply, .csv, .json, .obj, TreeQSM .txt) into a glTF tree asset.",
        "Meshing, LODs, impostor and export are those of `sylva grow`. The root is moved to the\n"
        "origin of the glb; its world position is kept in asset.extras.origin. A .sylva is decoded\n"
        "as `sylva run` does: its lobes are filled with the species' branchlets and leaves (the file's\n"
        "species, or --species; its seed), the same tree `run` wrote (a file marked leaf-off gets no cards),\n"
        "and so is its JSON form (sylva decode -o tree.json, edited or not);\n"
        "--proxy adds the hulls. Leaf cards go along the finest branches: --species gives its bark,\n"
        "leaf material and leaf density and size; without it the default bark and plain green cards\n"
        "at " DEFAULT_LEAVES "'s density and size\n"
        "(a model with hulls has its foliage already and gets none). See docs/qsm-formats.md.",
        opts, 1, 1};
    const char *pos[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, pos, 1, &n, SY_CLI_OUT_CHECKED, &rc)) return rc;
    if (tree_index < -1 || (leaf_density != -1 && !(leaf_density >= 0 && leaf_density <= 1e4))) {
        fprintf(stderr, "sylva mesh: --tree must be >= 0 and --leaf-density 0..10000\n");
        return SY_EUSAGE;
    }
    sy_tree_asset_options o = sy_tree_asset_options_default();
    sy_glb_args_apply(&glb, &o);
    o.seed = cli->seed;
    sy_error err = {0};
    if (sy_tree_asset_options_check(&o, &err)) return sy_cli_report(&err);
    mesh_facts f = {pos[0], "", 0, 0, 0, 0, 0, {0, 0, 0}};
    sy_skeleton skel;
    sy_clusters hulls; /* a .sylva's: the same foliage proxy `sylva run` draws */
    sy_skeleton_read_info info;
    double t0 = sy_now();
    /* Read once: a pipe gives its bytes once. */
    sy_buffer file, image = {NULL, 0};
    if (sy_read_file(pos[0], &file, &err)) return sy_cli_report(&err);
    /* A sylva-tree JSON with lobes is its .sylva image, read no further as
     * a skeleton (a --tree past 0 is the reader's to refuse). */
    sy_skel_format format = sy_skeleton_sniff(pos[0], file.data, file.size);
    if (format == SY_SKEL_JSON && tree_index <= 0 && (rc = sylva_tree_image(pos[0], &file, &image, &err))) {
        sy_buffer_free(&file);
        return sy_cli_report(&err);
    }
    if (image.data) {
        sy_buffer_free(&file);
        f.format = sy_skel_format_name(format);
        f.seconds_read = sy_now() - t0;
        return mesh_sylva(pos[0], image, out_path, species_name, no_leaves, proxy, cli, &o, &f);
    }
    if (sy_skeleton_read_model_mem(pos[0], file.data, file.size, tree_index, &skel, &hulls, &info, &err)) {
        sy_buffer_free(&file);
        return sy_cli_report(&err);
    }
    if (skel.n < 2) {
        sy_buffer_free(&file);
        sy_clusters_free(&hulls);
        sy_skeleton_free(&skel);
        sy_fail(&err, SY_EINPUT, "%s: a skeleton of one node has no branch to mesh", pos[0]);
        return sy_cli_report(&err);
    }
    f.seconds_read = sy_now() - t0;
    f.format = sy_skel_format_name(info.format);
    if (info.format == SY_SKEL_SYLVA && hulls.n > 0) {
        sy_clusters_free(&hulls);
        sy_skeleton_free(&skel);
        return mesh_sylva(pos[0], file, out_path, species_name, no_leaves, proxy, cli, &o, &f);
    }
    sy_buffer_free(&file);
    sy_tree_asset_root_to_origin(&skel, &hulls);
    o.hulls = &hulls;
    o.source = f.model;
    o.source_format = f.format;
    memcpy(f.origin, skel.origin, sizeof f.origin);
    f.height = sy_skeleton_height(&skel);
    sy_species_params sp;
    int have_species = 0;
    sy_leaves leaves = {0};
    if (species_name) {
        if ((rc = sy_species_params_find(species_name, &sp, &err))) goto done;
        have_species = 1;
    }
    /* A .sylva marked leaf-off without lobes (`run --leaf-off` of a tree
     * with none) is drawn bare, as run drew it. */
    if (!no_leaves && !info.leaf_off && (have_species || !hulls.n)) {
        sy_species_params leaf_sp;
        if (!have_species && (rc = sy_species_params_find(DEFAULT_LEAVES, &leaf_sp, &err))) goto done;
        sy_leaf_placement lp = sy_leaf_placement_from_species(have_species ? &sp : &leaf_sp, cli->seed);
        sy_leaf_placement_fit_tree(&lp, have_species ? &sp : &leaf_sp, f.height);
        if (!have_species) sy_species_params_free(&leaf_sp);
        if (leaf_density >= 0) lp.per_metre = leaf_density;
        f.leaf_size = lp.size;
        t0 = sy_now();
        rc = sy_place_leaves(&skel, &lp, &leaves, &f.twig_length, &err);
        f.seconds_leaves = sy_now() - t0;
        if (rc) { /* the stage names no file: the model's twigs it is */
            char msg[sizeof err.msg];
            snprintf(msg, sizeof msg, "%s", err.msg);
            sy_fail(&err, rc, "%s: %s", pos[0], msg);
            goto done;
        }
    }
    sy_tree_asset_report rep;
    rc = sy_tree_asset_write(out_path, &skel, &leaves, have_species ? &sp : NULL, &o, &rep, &err);
    if (!rc) print_report(cli, out_path, &rep, &f, have_species ? &sp : NULL);
done:
    sy_leaves_free(&leaves);
    if (have_species) sy_species_params_free(&sp);
    sy_clusters_free(&hulls);
    sy_skeleton_free(&skel);
    return rc ? sy_cli_report(&err) : 0;
}
