/* sylva skeleton SCAN -o tree.sylva: one segmented tree scan to its skeleton,
 * clusters and hulls, written as a compact .sylva file, or the skeleton alone
 * in an interchange format (.ply .csv .json .obj, stages/qsm/qsm.h). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "pipeline/commands.h"
#include "pipeline/run_tree.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/encode/encode.h"
#include "stages/ingest/ingest.h"
#include "stages/preprocess/preprocess.h"
#include "stages/qsm/qsm.h"
#include "stages/skeleton/skeleton.h"

static void print_report(const sy_cli *cli, const char *in, const char *out, const sy_skeleton_report *r,
                         const sy_hull_report *h, size_t bytes)
{
    if (cli->json) {
        sy_json j;
        sy_cli_json_open(&j, in, out);
        sy_json_int(&j, "bytes", (long long)bytes);
        sy_json_int(&j, "points", (long long)r->points);
        sy_json_number(&j, "spacing", r->spacing);
        sy_json_number(&j, "bin_width", r->bin_width);
        sy_json_int(&j, "graph_edges", (long long)r->graph_edges);
        sy_json_int(&j, "components", (long long)r->components);
        sy_json_int(&j, "nodes", (long long)r->nodes);
        sy_json_int(&j, "branches", (long long)r->branches);
        sy_json_int(&j, "clusters", (long long)r->clusters);
        sy_json_number(&j, "lobe_size", r->lobe_size);
        sy_json_int(&j, "skeleton_points", (long long)r->skeleton_points);
        sy_json_int(&j, "cluster_points", (long long)r->cluster_points);
        sy_json_object(&j, "hulls");
        sy_json_int(&j, "alpha", (long long)h->alpha);
        sy_json_int(&j, "convex", (long long)h->convex);
        sy_json_int(&j, "box", (long long)h->box);
        sy_json_end(&j);
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
        if (r->crown_regrown) sy_json_number(&j, "crown_base", r->crown_base);
        sy_json_number(&j, "height", r->height);
        sy_json_object(&j, "seconds");
        sy_json_number(&j, "graph", r->t_graph);
        sy_json_number(&j, "dijkstra", r->t_dijkstra);
        sy_json_number(&j, "level_sets", r->t_levels);
        sy_json_number(&j, "radii", r->t_radii);
        sy_json_number(&j, "clusters", r->t_clusters);
        sy_json_number(&j, "hulls", h->seconds);
        sy_json_number(&j, "total", r->t_total + h->seconds);
        sy_json_end(&j);
        sy_cli_json_close(&j);
        return;
    }
    printf("%s -> %s (%zu bytes)\n", in, out, bytes);
    printf("  points     %zu (spacing %.4f m, level sets %.4f m, %zu graph components bridged)\n", r->points,
           r->spacing, r->bin_width, r->components);
    printf("  skeleton   %zu nodes, %zu branches, %zu points\n", r->nodes, r->branches, r->skeleton_points);
    printf("  clusters   %zu (%zu alpha shapes, %zu convex, %zu boxes), %zu points\n", r->clusters, h->alpha,
           h->convex, h->box, r->cluster_points);
    printf("  DBH        %.3f m (%s), height %.2f m\n", r->dbh, r->dbh_fitted ? "circle fit" : "fallback estimate",
           r->height);
    if (r->hairpins)
        printf("  hairpins   %zu chains that came down another limb turned to grow up from the wood below\n",
               r->hairpins);
    if (r->stem_rebuilt)
        printf("  stem       rebuilt on the crown's axis (the trunk chain strayed %.2f m from it, crown radius %.2f m)\n",
               r->stem_excursion, r->crown_radius);
    if (r->stem_unseen)
        printf("  stem       unseen: the lowest return stands %.2f m over the ground; a trunk drawn from the ground%s\n",
               r->crown_gap, r->stem_fork > 0 ? "" : " to the crown's top");
    if ((r->stem_rebuilt || r->stem_unseen) && r->stem_fork > 0)
        printf("  stem       ends at %.2f m, where the domed crown's widest part ends (dome %.2f): the limbs spread from there\n",
               r->stem_fork, r->crown_dome);
    if (r->crown_regrown)
        printf("  crown      regrown above the trunk's %.2f m (the trunk chain meandered %.2f x its reach through a "
               "foliage crown, fill %.2f)\n",
               r->crown_base, r->trunk_meander, r->crown_fill);
    printf("  time       %.3f s (graph %.3f, dijkstra %.3f, level sets %.3f, radii %.3f, clusters %.3f, hulls %.3f)\n",
           r->t_total + h->seconds, r->t_graph, r->t_dijkstra, r->t_levels, r->t_radii, r->t_clusters, h->seconds);
}

typedef struct {
    const char *out_path;
    double voxel;
    int species, no_clusters, max_points, keep_hairpins;
    sy_skeleton_options o;
    sy_hull_options hull;
} skeleton_args;

int cmd_skeleton(int argc, char **argv, sy_cli *cli)
{
    skeleton_args a = {NULL, 0, 0, 0, SY_POINT_BUDGET, 0, sy_skeleton_options_default(), sy_hull_options_default()};
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &a.out_path, "OUT", "output: .sylva (skeleton + hulls), or the skeleton as .ply .csv .json .obj"},
        {"--beta", OPT_DOUBLE, &a.o.beta, "B", "Dijkstra edge weight |u-v|^B (default 1)"},
        {"--gamma", OPT_DOUBLE, &a.o.gamma, "G", "allometry: d^G additive over children (default 2)"},
        {"--fs", OPT_DOUBLE, &a.o.fs, "F", "scan-density factor f_s in (0,1]; smaller gives larger clusters (default 1)"},
        {"--wood-share", OPT_DOUBLE, &a.o.wood_share, "W",
         "wood/leaf separation: wood = shortest-path subtrees of >= W of the points (e.g. 0.005; default 0 = off)"},
        {"--voxel", OPT_DOUBLE, &a.voxel, "SIZE", "thin the scan to one point per SIZE-metre voxel first (default off)"},
        {"--max-points", OPT_INT, &a.max_points, "N",
         "voxel-thin denser scans to at most N points before the graph (default 300000; 0: never)"},
        {"--spacing", OPT_DOUBLE, &a.o.spacing, "S", "point spacing in metres (default: median nearest-neighbour distance)"},
        {"--k", OPT_INT, &a.o.k, "K", "neighbours per point in the graph (default 12)"},
        {"--bin", OPT_DOUBLE, &a.o.bin_factor, "F", "level-set width in point spacings (default 4)"},
        {"--alpha-scale", OPT_DOUBLE, &a.hull.alpha_scale, "A", "alpha = A * alpha_min, CGAL squared radii (default 5)"},
        {"--min-cluster", OPT_INT, &a.o.min_cluster_points, "N", "smallest cluster in points (default 24)"},
        {"--species", OPT_INT, &a.species, "ID", "species id stored in the file (default 0: unknown)"},
        {"--spread-around", OPT_FLAG, &a.o.spread_around, NULL,
         "judge a level set's spread from the skeleton around its node, not its edge (leaf-off scans)"},
        {"--keep-hairpins", OPT_FLAG, &a.keep_hairpins, NULL,
         "leave chains that climb one limb and come down another as they are (default: turn them to grow up "
         "from the wood below)"},
        {"--fair-limbs", OPT_DOUBLE, &a.o.fair_sigma, "S",
         "smooth each limb along its length over S times its radius (default 4; 0: off)"},
        {"--return-cap", OPT_DOUBLE, &a.o.return_cap, "F",
         "no limb thicker than F times the median distance of its returns (default 2; 0: off)"},
        {"--no-clusters", OPT_FLAG, &a.no_clusters, NULL, "keep every point on the skeleton"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "skeleton", "SCAN -o OUT.{sylva,ply,csv,json,obj}",
        "Reconstruct one tree: skeleton, clusters and alpha-shape hulls, stored as a compact .sylva file.",
        "SCAN must hold one segmented tree, Z up, in metres (see `sylva preprocess`). The report\n"
        "gives nodes, branches, clusters, DBH, height and the time of each step. See docs/skeleton.md.\n"
        "OUT's extension picks the format: .sylva keeps the cluster hulls; .ply (AdTree), .csv\n"
        "(SimpleForest/rTwig cylinders), .json (sylva-skeleton), .obj hold the whole skeleton (no\n"
        "clusters: every point stays on it) in the scan's own world coordinates (docs/qsm-formats.md).",
        opts, 1, 1};
    const char *in[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, in, 1, &n, SY_CLI_OUT_CHECKED, &rc)) return rc;
    char ext[16];
    sy_extension(a.out_path, ext, sizeof ext);
    int sylva_file = strcmp(ext, "sylva") == 0;
    if (!sylva_file && strcmp(ext, "ply") && strcmp(ext, "csv") && strcmp(ext, "json") && strcmp(ext, "obj")) {
        fprintf(stderr, "sylva skeleton: %s: unknown output extension (use .sylva, .ply, .csv, .json or .obj)\n",
                a.out_path);
        return SY_EUSAGE;
    }
    if (a.species < 0 || a.species > 65535 || !(a.voxel >= 0) || !isfinite(a.voxel) || a.max_points < 0) {
        fprintf(stderr, "sylva skeleton: --species must be in 0..65535, --voxel and --max-points >= 0\n");
        return SY_EUSAGE;
    }
    /* Interchange formats hold no hulls: clustering would drop the fine
     * branches the hulls stand for (rTwig: recall 0.16 instead of 0.97). */
    a.o.clusters = !a.no_clusters && sylva_file;
    a.o.unfold_hairpins = !a.keep_hairpins;
    sy_error err = {0};
    if (sy_reconstruct_check(&a.o, &err) || sy_hull_options_check(&a.hull, &err)) return sy_cli_report(&err);
    sy_cloud c;
    if (sy_read_cloud(in[0], &c, &err)) return sy_cli_report(&err);
    sy_skeleton s;
    sy_clusters cl;
    sy_skeleton_report r;
    /* The preprocess stage's voxel filter, as `sylva run --voxel` uses. */
    rc = a.voxel > 0 ? sy_voxel_downsample(&c, a.voxel, &err) : SY_OK;
    sy_hull_report h = {0};
    sy_tree_checks checks;
    if (!rc)
        rc = sy_reconstruct_tree_checked(&c, in[0], &a.o, a.hull.alpha_scale, (size_t)a.max_points, &s, &cl, &r, &h,
                                         &checks, &err);
    if (!rc && !cli->quiet && !cli->json && checks.thinning_voxel > 0)
        fprintf(stderr, "sylva skeleton: thinned %zu -> %zu points (%.4f m voxels, --max-points %d)\n",
                checks.points_before_thinning, checks.points_after_thinning, checks.thinning_voxel, a.max_points);
    if (!rc && !cli->quiet && !cli->json && checks.attempts > 1)
        fprintf(stderr, "sylva skeleton: the first skeleton failed the checks; passed after retrying with %s\n",
                checks.retried);
    if (rc) {
        sy_cloud_free(&c);
        /* Name the scan: the stage's messages name only the step. */
        if (rc == SY_EINPUT && !strstr(err.msg, in[0])) {
            sy_error e2 = err;
            sy_fail(&err, rc, "%s: %s", in[0], e2.msg);
        }
        return sy_cli_report(&err);
    }
    unsigned char *bytes = NULL;
    size_t size = 0;
    if (sylva_file) {
        rc = sy_encode_mem(&s, &cl, (uint16_t)a.species, cli->seed, NULL, &bytes, &size, &err);
        if (!rc) rc = sy_write_file_atomic(a.out_path, bytes, size, &err);
    } else {
        rc = sy_skeleton_write(a.out_path, &s, &err);
        struct stat st;
        if (!rc && stat(a.out_path, &st) == 0) size = (size_t)st.st_size;
    }
    if (!rc) print_report(cli, in[0], a.out_path, &r, &h, size);
    free(bytes);
    sy_clusters_free(&cl);
    sy_skeleton_free(&s);
    sy_cloud_free(&c);
    return rc ? sy_cli_report(&err) : 0;
}
