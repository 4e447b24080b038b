/* sylva run SCAN -o tree.glb: the whole reconstruction of one scanned tree:
 * ingest -> preprocess -> skeleton -> clusters -> mesh -> export, with the
 * cluster hulls as a semi-transparent foliage proxy and optionally the
 * compact .sylva file of the same reconstruction. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "pipeline/commands.h"
#include "pipeline/tree_asset.h"
#include "pipeline/tree_species.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/progress.h"
#include "stages/encode/sylva_format.h"
#include "stages/ingest/ingest.h"
#include "stages/preprocess/preprocess.h"
#include "stages/scan/scan.h"
#include "stages/skeleton/skeleton_stage.h"

static const char *out_path, *sylva_path, *species_name, *model_path;
static double beta, gamma_, fs, voxel, wood_share;
static int spread_around;
static const sy_opt opts[] = {
    {"-o", OPT_STRING, &out_path, "OUT.glb", "output glTF binary"},
    {"--sylva", OPT_STRING, &sylva_path, "OUT.sylva", "also write the compact .sylva file of the reconstruction"},
    {"--species", OPT_STRING, &species_name, "NAME",
     "library species: its beta/gamma, bark and leaf materials (default: the classifier's answer)"},
    {"--model", OPT_STRING, &model_path, "MODEL.sjb", "species classifier used without --species (default: the shipped one)"},
    {"--beta", OPT_DOUBLE, &beta, "B", "Dijkstra edge weight |u-v|^B (default: species, else 1)"},
    {"--gamma", OPT_DOUBLE, &gamma_, "G", "allometry exponent (default: species, else 2)"},
    {"--fs", OPT_DOUBLE, &fs, "F", "scan-density factor f_s in (0,1]; smaller gives larger clusters (default 1)"},
    {"--wood-share", OPT_DOUBLE, &wood_share, "W",
     "wood/leaf separation: wood = shortest-path subtrees of >= W of the points (e.g. 0.005; default 0 = off)"},
    {"--voxel", OPT_DOUBLE, &voxel, "SIZE", "thin the scan to one point per SIZE-metre voxel (default off)"},
    {"--spread-around", OPT_FLAG, &spread_around, NULL,
     "judge a level set's spread from the skeleton around its node, not its edge (leaf-off scans)"},
    SY_GLB_OPTIONS,
    {NULL, 0, NULL, NULL, NULL},
};
static const sy_cmd_spec spec = {
    "run", "SCAN -o OUT.glb [--sylva OUT.sylva]",
    "Reconstruct one scanned tree and write it as glTF: branch meshes plus cluster hulls.",
    "Steps: ingest, preprocess (up axis, statistical outliers, ground classified and removed;\n"
    "the defaults of `sylva preprocess`), skeleton and alpha-shape clusters (docs/skeleton.md),\n"
    "mesh (LOD chain, impostor), export. The hulls become one semi-transparent mesh with the\n"
    "material \"foliage_proxy\" in every level. The glb is centred at the tree's base, its world\n"
    "position in asset.extras.origin (as `sylva mesh` does). SCAN must hold one tree. The .sylva species id\n"
    "is the species' index in the library plus one (0: unknown). Without --species the tree is\n"
    "classified first (docs/classify.md) and a confident answer's parameters and materials are used;\n"
    "an unknown tree keeps the defaults.",
    opts, 1, 1};

typedef struct {
    size_t points_in, points_clean;
    sy_species_guess guess; /* filled when the species was classified */
    int classified;
    double t_ingest, t_preprocess, t_skeleton, t_mesh, t_export;
    size_t sylva_bytes;
} run_stats;

static void stage_line(const sy_cli *cli, const char *what, double seconds, const char *detail)
{
    if (!cli->quiet && !cli->json) fprintf(stderr, "sylva run: %-10s %7.3f s  %s\n", what, seconds, detail);
}

static void print_json(const char *in, const sy_skeleton_report *r, const sy_tree_asset_report *a,
                       const run_stats *st)
{
    sy_json j;
    sy_json_begin(&j, stdout, 0);
    sy_json_object(&j, NULL);
    sy_json_string(&j, "input", in);
    sy_json_string(&j, "output", out_path);
    if (sylva_path) {
        sy_json_string(&j, "sylva", sylva_path);
        sy_json_int(&j, "sylva_bytes", (long long)st->sylva_bytes);
    }
    if (species_name) sy_json_string(&j, "species", species_name);
    else if (st->classified) {
        sy_json_string(&j, "species", st->guess.name);
        sy_json_object(&j, "classification");
        sy_json_string(&j, "best", st->guess.best);
        sy_json_number(&j, "probability", st->guess.probability);
        sy_json_bool(&j, "confident", st->guess.confident);
        sy_json_number(&j, "novelty", st->guess.novelty);
        sy_json_end(&j);
    }
    sy_json_int(&j, "points_in", (long long)st->points_in);
    sy_json_int(&j, "points_preprocessed", (long long)st->points_clean);
    sy_json_int(&j, "nodes", (long long)r->nodes);
    sy_json_int(&j, "branches", (long long)r->branches);
    sy_json_int(&j, "clusters", (long long)r->clusters);
    sy_json_int(&j, "cluster_points", (long long)r->cluster_points);
    sy_json_number(&j, "dbh", r->dbh);
    sy_json_bool(&j, "dbh_fitted", r->dbh_fitted);
    sy_json_number(&j, "height", r->height);
    sy_json_int(&j, "hull_triangles", (long long)a->hull_triangles);
    sy_tree_asset_report_lods_json(&j, a);
    sy_json_int(&j, "bytes", (long long)a->bytes);
    sy_json_object(&j, "seconds");
    sy_json_number(&j, "ingest", st->t_ingest);
    sy_json_number(&j, "preprocess", st->t_preprocess);
    sy_json_number(&j, "skeleton", r->t_total - r->t_clusters - r->t_hulls);
    sy_json_number(&j, "clusters", r->t_clusters + r->t_hulls);
    sy_json_number(&j, "mesh", st->t_mesh);
    sy_json_number(&j, "export", st->t_export);
    sy_json_end(&j);
    sy_json_end(&j);
    sy_json_finish(&j);
}

static int check_options(void)
{
    if (!out_path) {
        fprintf(stderr, "sylva run: -o OUT.glb is required\n");
        return SY_EUSAGE;
    }
    if ((!isnan(beta) && !(beta > 0)) || (!isnan(gamma_) && !(gamma_ > 0)) || !(fs > 0 && fs <= 1) ||
        !(wood_share >= 0 && wood_share < 1) || !(voxel >= 0) || !isfinite(voxel)) {
        fprintf(stderr, "sylva run: --beta and --gamma must be > 0, --fs in (0,1], --wood-share in [0,1), --voxel >= 0\n");
        return SY_EUSAGE;
    }
    if (sylva_path && strcmp(sylva_path, out_path) == 0) {
        fprintf(stderr, "sylva run: -o and --sylva name the same file\n");
        return SY_EUSAGE;
    }
    sy_tree_asset_options o = sy_tree_asset_options_default();
    return sy_glb_cli_apply("run", &o);
}

/* Ingest and preprocess: a clean, Z-up cloud of the tree alone. */
static sy_code load_clean(const char *in, const sy_cli *cli, sy_cloud *c, run_stats *st, sy_error *err)
{
    double t = sy_now();
    sy_code rc = sy_read_cloud(in, c, err);
    if (rc) return rc;
    st->t_ingest = sy_now() - t;
    st->points_in = c->n;
    char line[160];
    snprintf(line, sizeof line, "%zu points", c->n);
    stage_line(cli, "ingest", st->t_ingest, line);
    t = sy_now();
    sy_preprocess_opts po;
    sy_preprocess_defaults(&po);
    po.voxel = voxel;
    po.remove_ground = 1; /* one tree: the ground would become a skeleton of its own */
    po.normals = 0;       /* the skeleton does not use them */
    sy_preprocess_result pr;
    if ((rc = sy_preprocess(c, &po, &pr, err))) {
        sy_cloud_free(c);
        return rc;
    }
    st->t_preprocess = sy_now() - t;
    st->points_clean = c->n;
    snprintf(line, sizeof line, "%zu points left (up %s, %zu ground removed)", c->n, sy_up_name(pr.up_axis),
             pr.ground_points);
    stage_line(cli, "preprocess", st->t_preprocess, line);
    if (c->n == 0) {
        sy_cloud_free(c);
        return sy_fail(err, SY_EINPUT, "%s: no points left after preprocessing", in);
    }
    return SY_OK;
}

/* Encodes the .sylva image before anything is written, so a failure leaves no file. */
static sy_code encode_sylva(const sy_skeleton *s, const sy_clusters *cl, const char *species, const sy_cli *cli,
                            unsigned char **buf, size_t *size, sy_error *err)
{
    int idx = species ? sy_species_index(species) : -1;
    uint16_t id = (uint16_t)(idx >= 0 && idx < 65535 ? idx + 1 : 0);
    return sy_encode_mem(s, cl, id, cli->seed, NULL, buf, size, err);
}

static sy_code reconstruct_and_write(const char *in, const sy_cli *cli, const sy_species *sp, run_stats *st,
                                     sy_skeleton_report *r, sy_tree_asset_report *a, sy_error *err)
{
    sy_cloud c;
    sy_code rc = load_clean(in, cli, &c, st, err);
    if (rc) return rc;
    /* No species given: the classifier names one from the cleaned tree. */
    sy_species guessed;
    int have_guess = 0;
    if (!sp) {
        if ((rc = sy_classify_cloud(&c, model_path, &st->guess, err))) {
            sy_cloud_free(&c);
            return rc;
        }
        st->classified = 1;
        char line[200];
        snprintf(line, sizeof line, "%s (%s; best %s p %.2f)", st->guess.name,
                 st->guess.confident ? "confident" : st->guess.novel ? "unlike the training trees" : "not confident",
                 st->guess.best, st->guess.probability);
        stage_line(cli, "species", st->guess.seconds, line);
        if (strcmp(st->guess.name, "unknown") != 0) {
            if ((rc = sy_species_find(st->guess.name, &guessed, err))) {
                sy_cloud_free(&c);
                return rc;
            }
            sp = &guessed;
            have_guess = 1;
        }
    }
    const char *sp_name = species_name ? species_name : have_guess ? st->guess.name : NULL;
    sy_skeleton_options so;
    sy_skeleton_options_default(&so);
    if (sp) so.beta = sp->beta, so.gamma = sp->gamma;
    if (!isnan(beta)) so.beta = beta;
    if (!isnan(gamma_)) so.gamma = gamma_;
    so.fs = fs;
    so.wood_share = wood_share;
    so.spread_around = spread_around;
    sy_skeleton s;
    sy_clusters cl;
    rc = sy_reconstruct_skeleton(&c, &so, &s, &cl, r, err);
    sy_cloud_free(&c);
    if (rc) {
        if (have_guess) sy_species_free(&guessed);
        if (rc == SY_EINPUT && !strstr(err->msg, in)) {
            sy_error e2 = *err;
            sy_fail(err, rc, "%s: %s", in, e2.msg);
        }
        return rc;
    }
    char line[200];
    snprintf(line, sizeof line, "%zu nodes, %zu branches, DBH %.3f m, height %.2f m", r->nodes, r->branches, r->dbh,
             r->height);
    stage_line(cli, "skeleton", r->t_total - r->t_clusters - r->t_hulls, line);
    snprintf(line, sizeof line, "%zu clusters (%zu alpha, %zu convex, %zu box), %zu points", r->clusters,
             r->hulls_alpha, r->hulls_convex, r->hulls_box, r->cluster_points);
    stage_line(cli, "clusters", r->t_clusters + r->t_hulls, line);

    unsigned char *sylva = NULL;
    size_t sylva_size = 0;
    if (sylva_path) rc = encode_sylva(&s, &cl, sp_name, cli, &sylva, &sylva_size, err);
    if (!rc) {
        sy_tree_asset_options o = sy_tree_asset_options_default();
        sy_glb_cli_apply("run", &o); /* checked in check_options */
        o.seed = cli->seed;
        o.hulls = &cl;
        o.source = in;
        o.source_format = "scan";
        /* After encoding: the .sylva keeps the scan's own frame. */
        sy_tree_asset_root_to_origin(&s, &cl);
        rc = sy_tree_asset_write(out_path, &s, NULL, sp, &o, a, err);
    }
    if (!rc) {
        st->t_mesh = a->seconds_mesh;
        st->t_export = a->seconds_export;
        snprintf(line, sizeof line, "%zu levels, LOD0 %zu triangles (%zu of them hulls)", a->lods, a->triangles[0],
                 a->hull_triangles);
        stage_line(cli, "mesh", st->t_mesh, line);
        snprintf(line, sizeof line, "%s, %zu bytes", out_path, a->bytes);
        stage_line(cli, "export", st->t_export, line);
    }
    if (!rc && sylva_path) {
        rc = sy_write_file_atomic(sylva_path, sylva, sylva_size, err);
        if (rc) unlink(out_path); /* both outputs or none */
        st->sylva_bytes = sylva_size;
        if (!rc) {
            snprintf(line, sizeof line, "%s, %zu bytes", sylva_path, sylva_size);
            stage_line(cli, "sylva", 0, line);
        }
    }
    free(sylva);
    sy_clusters_free(&cl);
    sy_skeleton_free(&s);
    if (have_guess) sy_species_free(&guessed);
    return rc;
}

int cmd_run(int argc, char **argv, sy_cli *cli)
{
    const char *in[1];
    int n;
    out_path = sylva_path = species_name = model_path = NULL;
    beta = gamma_ = NAN;
    fs = 1;
    wood_share = 0;
    spread_around = 0;
    voxel = 0;
    sy_glb_cli_reset();
    int rc = sy_cli_parse(&spec, argc, argv, cli, in, 1, &n);
    if (rc) return rc < 0 ? 0 : rc;
    if ((rc = check_options())) return rc;
    sy_error err = {0};
    sy_species sp;
    if (species_name && sy_species_find(species_name, &sp, &err)) return sy_cli_report(&err);
    run_stats st;
    memset(&st, 0, sizeof st);
    sy_skeleton_report r;
    sy_tree_asset_report a;
    memset(&a, 0, sizeof a);
    rc = reconstruct_and_write(in[0], cli, species_name ? &sp : NULL, &st, &r, &a, &err);
    if (species_name) sy_species_free(&sp);
    if (rc) return sy_cli_report(&err);
    if (cli->json) print_json(in[0], &r, &a, &st);
    else if (!cli->quiet)
        fprintf(stderr, "sylva run: wrote %s%s%s\n", out_path, sylva_path ? " and " : "", sylva_path ? sylva_path : "");
    return 0;
}
