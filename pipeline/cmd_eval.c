/* sylva eval: one scoring for synthetic and real data (docs/eval.md). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/commands.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/eval/eval.h"
#include "stages/gltf/gltf_read.h"
#include "stages/ingest/ingest.h"
#include "stages/preprocess/preprocess.h"

/* One call's arguments. */
typedef struct {
    const char *truth_path, *points_path, *truth_attr, *pred_attr, *png_path;
    int segmentation_mode, species_mode, closed_flag;
    double coverage_eps, match_distance;
} eval_args;

/* Output: a JSON object of flat keys or aligned "name  value" lines. */
typedef struct {
    int json;
    sy_json j;
} report;

static void put(report *r, const char *key, const char *label, double v, const char *unit)
{
    if (isnan(v)) return;
    if (r->json) sy_json_number(&r->j, key, v);
    else printf("  %-34s %.4f%s\n", label, v, unit);
}

static void put_count(report *r, const char *key, const char *label, size_t v)
{
    if (r->json) sy_json_int(&r->j, key, (long long)v);
    else printf("  %-34s %zu\n", label, v);
}

static void report_begin(report *r, int json, const char *title)
{
    r->json = json;
    if (json) {
        sy_json_begin(&r->j, stdout, 0);
        sy_json_object(&r->j, NULL);
    } else {
        printf("%s\n", title);
    }
}

static void report_end(report *r)
{
    if (!r->json) return;
    sy_json_end(&r->j);
    sy_json_finish(&r->j);
}

static void print_skeleton(report *r, const sy_skeleton_metrics *m)
{
    static const char *order_key[4] = {"recall_order0", "recall_order1", "recall_order2", "recall_order3"};
    static const char *prec_key[4] = {"precision_order0", "precision_order1", "precision_order2", "precision_order3"};
    static const char *rad_key[4] = {"radius_error_order0", "radius_error_order1", "radius_error_order2",
                                     "radius_error_order3"};
    put(r, "truth_length", "truth skeleton length", m->truth_length, " m");
    put(r, "model_length", "model skeleton length", m->model_length, " m");
    put(r, "recall", "recall (length-weighted)", m->recall, "");
    put(r, "precision", "precision (length-weighted)", m->precision, "");
    put(r, "recall_r2cm", "recall, branches r >= 2 cm", m->recall_r2cm, "");
    put(r, "precision_r2cm", "precision, branches r >= 2 cm", m->precision_r2cm, "");
    for (int k = 0; k < SY_EVAL_ORDERS; k++) {
        if (r->json) {
            put(r, order_key[k], "", m->recall_order[k], "");
            put(r, prec_key[k], "", m->precision_order[k], "");
            continue;
        }
        if (isnan(m->recall_order[k]) && isnan(m->precision_order[k])) continue;
        printf("  order %d%-2s recall %.4f  precision %.4f  radius error %.4f\n", k, k == 3 ? "+" : "",
               m->recall_order[k], m->precision_order[k], m->radius_error_order[k]);
    }
    put(r, "radius_error_median", "radius error (median relative)", m->radius_error_median, "");
    if (r->json)
        for (int k = 0; k < SY_EVAL_ORDERS; k++) put(r, rad_key[k], "", m->radius_error_order[k], "");
    put_count(r, "bifurcations_truth", "truth branch points", m->bifurcations_truth);
    put_count(r, "bifurcations_matched", "matched branch points", m->bifurcations_matched);
    put(r, "bifurcation_error_mean", "bifurcation error mean", m->bifurcation_error_mean, " m");
    put(r, "bifurcation_error_median", "bifurcation error median", m->bifurcation_error_median, " m");
    put_count(r, "trees_matched", "trees matched", m->trees_matched);
    put(r, "dbh_error", "DBH error (mean absolute)", m->dbh_error, " m");
    put(r, "height_error", "height error (mean absolute)", m->height_error, " m");
}

static void print_surface(report *r, const sy_surface_metrics *s)
{
    put_count(r, "point_count", "points", s->n_points);
    put(r, "mean_distance", "mean distance point->model", s->mean_distance, " m");
    put(r, "rms_distance", "RMS distance", s->rms_distance, " m");
    put(r, "p95_distance", "95th percentile distance", s->p95_distance, " m");
    put(r, "coverage", "coverage (share within eps)", s->coverage, "");
    put(r, "coverage_eps", "coverage eps", s->coverage_eps, " m");
    put(r, "hausdorff", "Hausdorff point->model", s->hausdorff, " m");
    put(r, "hausdorff_model_to_points", "Hausdorff model->points", s->hausdorff_model_to_points, " m");
}

/* Truth vs a mesh: the truth's wood surface, sampled, stands in for the
 * points; height from the mesh top when the truth holds one tree. */
static int truth_vs_mesh(const eval_args *a, const sy_forest *truth, const sy_eval_model *model, sy_cli *cli)
{
    sy_error err = {0};
    sy_eval_model wood = {0, NULL, *truth};
    size_t n;
    double *pts = sy_model_surface_samples(&wood, 0.01, &n, &err);
    if (!pts) return sy_cli_report(&err);
    sy_surface_metrics s;
    sy_code rc = sy_surface_metrics_compute(model, pts, n, a->coverage_eps, 0.01, &s, &err);
    free(pts);
    if (rc) return sy_cli_report(&err);
    double height_error = NAN;
    if (truth->n_trees == 1 && isfinite(truth->trees[0].height)) {
        double top = -INFINITY;
        for (size_t m = 0; m < model->n_meshes; m++)
            for (size_t i = 0; i < 3 * model->meshes[m].n; i++) top = fmax(top, model->meshes[m].tri[3 * i + 2]);
        height_error = fabs(top - truth->trees[0].position[2] - truth->trees[0].height);
    }
    report r;
    report_begin(&r, cli->json, "model vs truth wood surface (samples of the truth's cones as points)");
    print_surface(&r, &s);
    put(&r, "height_error", "height error", height_error, " m");
    report_end(&r);
    return 0;
}

static int run_truth(const eval_args *a, const char *model_path, sy_cli *cli)
{
    sy_error err = {0};
    sy_forest truth;
    sy_eval_model model;
    if (sy_forest_read(a->truth_path, &truth, &err)) return sy_cli_report(&err);
    if (sy_eval_load_model(model_path, a->closed_flag, &model, &err)) {
        sy_forest_free(&truth);
        return sy_cli_report(&err);
    }
    int status = 0;
    /* A .sylva model holds a skeleton and hulls: its skeleton is scored. */
    if (model.n_meshes && !model.skeletons.n_trees) {
        status = truth_vs_mesh(a, &truth, &model, cli);
    } else {
        sy_skeleton_metrics m;
        if (sy_skeleton_metrics_compute(&truth, &model.skeletons, NULL, &m, &err)) {
            status = sy_cli_report(&err);
        } else {
            report r;
            report_begin(&r, cli->json, "skeleton vs truth");
            print_skeleton(&r, &m);
            report_end(&r);
        }
    }
    sy_eval_model_free(&model);
    sy_forest_free(&truth);
    return status;
}

/* A reference asset (SCAN given as a .glb, e.g. the true tree's own asset
 * from `sylva grow`) as points: its drawn LOD0 surface (proxy left out,
 * alpha-tested cards where their leaves are) every 2 cm. */
static sy_code glb_points(const char *path, double **pts, double **area, size_t *n, sy_error *err)
{
    double *tri;
    size_t nt;
    sy_gltf_cutout cut;
    sy_code rc = sy_gltf_read_surface(path, &tri, &nt, &cut, err);
    if (rc) return rc;
    if (!(*pts = sy_drawn_surface_points(tri, nt, &cut, 0.02, n, area, err))) rc = SY_EINTERNAL;
    sy_gltf_cutout_free(&cut);
    free(tri);
    return rc;
}

/* The asset's look against the scan: the glb's drawn LOD0 surface
 * (sy_gltf_read_surface), against the scan's above-ground points (the cloud
 * preprocessed as `sylva run` does) or a reference asset's surface. */
static sy_code silhouette(const char *model_path, sy_cloud *c, const double *ref, const double *ref_w, size_t n_ref,
                          sy_silhouette_metrics *m, unsigned char *masks, sy_error *err)
{
    double *tri = NULL;
    size_t k = 0;
    sy_gltf_cutout cut;
    sy_code rc = sy_gltf_read_surface(model_path, &tri, &k, &cut, err);
    if (rc) return rc;
    double *pts = NULL;
    if (!ref) {
        sy_preprocess_options po = sy_preprocess_options_default();
        po.remove_ground = 1;
        po.normals = 0;
        sy_preprocess_result pr;
        rc = sy_preprocess(c, &po, &pr, err);
        pts = rc ? NULL : sy_cloud_world_points(c, err);
        if (!rc && !pts) rc = SY_EINTERNAL;
    }
    if (!rc) rc = sy_silhouette_metrics_compute(tri, k, &cut, ref ? ref : pts, ref_w, ref ? n_ref : c->n, m, masks, err);
    sy_gltf_cutout_free(&cut);
    free(pts);
    free(tri);
    return rc;
}

static int is_gltf(const char *path)
{
    char ext[16];
    sy_extension(path, ext, sizeof ext);
    return strcmp(ext, "glb") == 0 || strcmp(ext, "gltf") == 0;
}

static int run_points(const eval_args *a, const char *model_path, sy_cli *cli)
{
    sy_error err = {0};
    sy_cloud c;
    memset(&c, 0, sizeof c);
    sy_eval_model model;
    double *ref = NULL, *ref_w = NULL;
    size_t n_ref = 0;
    if (is_gltf(a->points_path) ? glb_points(a->points_path, &ref, &ref_w, &n_ref, &err)
                                : sy_read_cloud(a->points_path, &c, &err))
        return sy_cli_report(&err);
    if (sy_eval_load_model(model_path, a->closed_flag, &model, &err)) {
        sy_cloud_free(&c);
        free(ref), free(ref_w);
        return sy_cli_report(&err);
    }
    double *pts = ref ? ref : sy_cloud_world_points(&c, &err);
    sy_surface_metrics s;
    sy_code rc = pts ? sy_surface_metrics_compute(&model, pts, ref ? n_ref : c.n, a->coverage_eps, 0.01, &s, &err)
                     : SY_EINTERNAL;
    if (!ref) free(pts);
    sy_eval_model_free(&model);
    sy_silhouette_metrics sm;
    int look = !rc && is_gltf(model_path);
    unsigned char *masks = NULL;
    if (look && a->png_path &&
        !(masks = sy_calloc(SY_SILHOUETTE_VIEWS * SY_SILHOUETTE_RES, SY_SILHOUETTE_RES, &err, "silhouette masks")))
        rc = SY_EINTERNAL;
    if (look && !rc) rc = silhouette(model_path, &c, ref, ref_w, n_ref, &sm, masks, &err);
    if (masks && !rc) rc = sy_silhouette_png(masks, a->png_path, &err);
    free(masks);
    sy_cloud_free(&c);
    free(ref), free(ref_w);
    if (rc) return sy_cli_report(&err);
    report r;
    report_begin(&r, cli->json, "model vs points");
    print_surface(&r, &s);
    if (look) {
        static const char *key[6] = {"iou_az0", "iou_az45", "iou_az90", "iou_az135", "iou_top", "iou_oblique30"};
        static const char *label[6] = {"silhouette IoU, azimuth 0", "silhouette IoU, azimuth 45",
                                       "silhouette IoU, azimuth 90", "silhouette IoU, azimuth 135",
                                       "silhouette IoU, top", "silhouette IoU, 30 deg oblique"};
        for (int v = 0; v < 6; v++) put(&r, key[v], label[v], sm.iou[v], "");
        put(&r, "iou_mean", "silhouette IoU, mean of 6", sm.iou_mean, "");
        put(&r, "iou_min", "silhouette IoU, minimum", sm.iou_min, "");
        put(&r, "silhouette_precision", "silhouette precision (asset pixels the scan holds)", sm.precision, "");
        put(&r, "silhouette_recall", "silhouette recall (scan pixels the asset covers)", sm.recall, "");
        put(&r, "profile_correlation", "vertical profile correlation", sm.profile_correlation, "");
        if (r.json) {
            put(&r, "profile_z0", "", sm.profile_z0, "");
            put(&r, "profile_dz", "", sm.profile_dz, "");
            sy_json_numbers(&r.j, "profile_scan", sm.profile_scan, SY_SILHOUETTE_BINS);
            sy_json_numbers(&r.j, "profile_model", sm.profile_model, SY_SILHOUETTE_BINS);
        }
        put(&r, "scan_height", "scan height (above ground)", sm.scan_height, " m");
        put(&r, "model_height", "asset height", sm.model_height, " m");
        put(&r, "height_error_rel", "height error (relative, signed)", sm.height_error, "");
        put(&r, "scan_crown_width", "scan crown width (5-95%)", sm.scan_width, " m");
        put(&r, "model_crown_width", "asset crown width (5-95%)", sm.model_width, " m");
        put(&r, "crown_width_error_rel", "crown width error (relative, signed)", sm.width_error, "");
        put(&r, "splat_radius", "splat radius (scan median spacing)", sm.splat_radius, " m");
    }
    report_end(&r);
    return 0;
}

static int run_segmentation(const eval_args *a, const char *t_path, const char *p_path, sy_cli *cli)
{
    sy_error err = {0};
    sy_cloud t, p;
    if (sy_read_cloud(t_path, &t, &err)) return sy_cli_report(&err);
    if (sy_read_cloud(p_path, &p, &err)) {
        sy_cloud_free(&t);
        return sy_cli_report(&err);
    }
    sy_segmentation_metrics m;
    sy_code rc = sy_segmentation_metrics_clouds(&t, t_path, a->truth_attr, &p, p_path, a->pred_attr, a->match_distance, &m, &err);
    sy_cloud_free(&t);
    sy_cloud_free(&p);
    if (rc) return sy_cli_report(&err);
    report r;
    report_begin(&r, cli->json, "segmentation (instances matched at IoU > 0.5)");
    put_count(&r, "point_count", "points compared", m.n_points);
    put_count(&r, "unmatched_points", "truth points unmatched", m.n_unmatched_points);
    put_count(&r, "truth_instances", "truth instances", m.n_truth);
    put_count(&r, "pred_instances", "predicted instances", m.n_pred);
    put_count(&r, "matched_instances", "matched instances", m.n_matched);
    put(&r, "instance_precision", "instance precision", m.precision, "");
    put(&r, "instance_recall", "instance recall", m.recall, "");
    put(&r, "f1", "F1", m.f1, "");
    put(&r, "mean_iou", "mean IoU of matches", m.mean_iou, "");
    put_count(&r, "over_segmented", "truth trees cut into pieces", m.n_over_segmented);
    put_count(&r, "under_segmented", "predicted trees merging several", m.n_under_segmented);
    report_end(&r);
    return 0;
}

/* A label table from a CSV, or from a truth JSON's trees. */
static sy_code read_labels(const char *path, sy_label_table *t, sy_error *err)
{
    char ext[16];
    sy_extension(path, ext, sizeof ext);
    if (strcmp(ext, "json") != 0) return sy_label_table_read_csv(path, t, err);
    sy_forest f;
    sy_code rc = sy_forest_read(path, &f, err);
    if (rc) return rc;
    rc = sy_label_table_from_forest(&f, path, t, err);
    sy_forest_free(&f);
    return rc;
}

static int run_species(const eval_args *a, const char *t_path, const char *p_path, sy_cli *cli)
{
    sy_error err = {0};
    sy_label_table t, p;
    if (read_labels(t_path, &t, &err)) return sy_cli_report(&err);
    if (read_labels(p_path, &p, &err)) {
        sy_label_table_free(&t);
        return sy_cli_report(&err);
    }
    sy_confusion c;
    sy_code rc = sy_confusion_build(&t, &p, &c, &err);
    sy_label_table_free(&t);
    sy_label_table_free(&p);
    if (rc) return sy_cli_report(&err);
    if (a->png_path && (rc = sy_confusion_png(&c, a->png_path, &err))) {
        sy_confusion_free(&c);
        return sy_cli_report(&err);
    }
    report r;
    report_begin(&r, cli->json, "species classification");
    put_count(&r, "sample_count", "trees scored", c.n_samples);
    put_count(&r, "missing_count", "trees without a prediction", c.n_missing);
    put(&r, "accuracy", "accuracy", c.accuracy, "");
    put(&r, "macro_f1", "macro-F1", c.macro_f1, "");
    if (r.json) sy_confusion_json(&c, &r.j);
    else sy_confusion_print(&c, stdout);
    report_end(&r);
    sy_confusion_free(&c);
    return 0;
}

int cmd_eval(int argc, char **argv, sy_cli *cli)
{
    eval_args args = {NULL, NULL, "treeID", "treeID", NULL, 0, 0, 0, 0.02, 0.01}, *a = &args;
    const sy_opt opts[] = {
        {"--truth", OPT_STRING, &args.truth_path, "TRUTH.json", "score MODEL against a truth (or skeleton) JSON"},
        {"--points", OPT_STRING, &args.points_path, "SCAN", "score MODEL against the scan it was built from"},
        {"--segmentation", OPT_FLAG, &args.segmentation_mode, NULL, "score PRED_CLOUD's tree labels against TRUTH_CLOUD's"},
        {"--species", OPT_FLAG, &args.species_mode, NULL, "score species predictions (CSV id,species or truth JSON)"},
        {"--truth-attr", OPT_STRING, &args.truth_attr, "NAME", "truth labels: extra-bytes attribute or LAS field, e.g. classification (default treeID)"},
        {"--pred-attr", OPT_STRING, &args.pred_attr, "NAME", "predicted labels: extra-bytes attribute or LAS field (default treeID)"},
        {"--png", OPT_STRING, &args.png_path, "FILE", "species: the confusion matrix as a PNG heatmap; points: the six silhouette views"},
        {"--closed", OPT_FLAG, &args.closed_flag, NULL, "treat the model's meshes as closed hulls (inside = distance 0)"},
        {"--coverage", OPT_DOUBLE, &args.coverage_eps, "METRES", "coverage distance (default 0.02)"},
        {"--match-distance", OPT_DOUBLE, &args.match_distance, "METRES", "segmentation: nearest-point match radius when the clouds differ (default 0.01)"},
        {NULL, 0, NULL, NULL, NULL},
    };

    const sy_cmd_spec spec = {
        "eval", "(--truth T MODEL | --points SCAN MODEL | --segmentation TRUTH PRED | --species TRUTH PRED)",
        "Score reconstructions the same way for synthetic and real data.",
        "  --truth T MODEL        skeleton recall/precision (by order, thick branches), radius,\n"
        "                         bifurcation, DBH and height errors; MODEL is a truth or skeleton\n"
        "                         JSON or a .sylva file. A .glb MODEL is scored by distances to the\n"
        "                         truth wood surface.\n"
        "  --points SCAN MODEL    point->model mean/RMS/95th percentile, coverage, Hausdorff both ways\n"
        "                         (MODEL: .glb/.gltf triangles, a skeleton JSON as truncated cones,\n"
        "                         or a .sylva file: cones plus its cluster hulls, inside = distance 0).\n"
    "                         A .glb MODEL also gets its look against the scan's above-ground points:\n"
    "                         silhouette IoU of 6 views (mean, minimum), vertical profile correlation,\n"
    "                         relative height and crown-width errors (LOD0, foliage proxy left out).\n"
    "                         SCAN may be a .glb too (a reference asset, e.g. `sylva grow`'s true tree:\n"
    "                         its LOD0 surface sampled every 2 cm). --png FILE draws the six views'\n"
    "                         masks (scan only red, asset only blue, both grey); --json adds the two\n"
    "                         vertical profiles (profile_scan: points, profile_model: area in m^2).\n"
        "  --segmentation T P     instance precision/recall/F1 at IoU > 0.5 (labels 0/NaN: no tree),\n"
        "                         over-/under-segmentation counts (sylva segment's output as P).\n"
        "  --species T P          accuracy, macro-F1 and the confusion matrix.\n"
        "--json prints flat keys (only those that apply); exit 2 on bad input.",
        opts, 1, 2};
    const char *pos[2];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, pos, 2, &n, SY_CLI_OUT_NONE, &rc)) return rc;
    int modes = (a->truth_path != NULL) + (a->points_path != NULL) + a->segmentation_mode + a->species_mode;
    if (modes != 1) {
        fprintf(stderr, "sylva eval: choose exactly one of --truth, --points, --segmentation, --species\n");
        return SY_EUSAGE;
    }
    int want = a->segmentation_mode || a->species_mode ? 2 : 1;
    if (n != want) {
        fprintf(stderr, "sylva eval: expected %d file argument%s, got %d (see --help)\n", want, want == 1 ? "" : "s", n);
        return SY_EUSAGE;
    }
    if (!(a->coverage_eps >= 0) || !(a->match_distance >= 0)) {
        fprintf(stderr, "sylva eval: --coverage and --match-distance must be >= 0\n");
        return SY_EUSAGE;
    }
    if (a->png_path && !a->species_mode && !(a->points_path && n == 1 && is_gltf(pos[0]))) {
        fprintf(stderr, "sylva eval: --png applies to --species, and to --points with a .glb/.gltf MODEL\n");
        return SY_EUSAGE;
    }
    const char *ins[4] = {pos[0], n > 1 ? pos[1] : NULL, a->truth_path, a->points_path};
    if (a->png_path && (rc = sy_cli_check_outputs(&a->png_path, 1, ins, 4))) return rc;
    if (a->truth_path) return run_truth(a, pos[0], cli);
    if (a->points_path) return run_points(a, pos[0], cli);
    if (a->segmentation_mode) return run_segmentation(a, pos[0], pos[1], cli);
    return run_species(a, pos[0], pos[1], cli);
}
