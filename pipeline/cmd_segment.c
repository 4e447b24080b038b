/* sylva segment PLOT -o OUT: a plot into trees (a cloud labelled with treeID,
 * or with --split one file per tree), and the per-tree table. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/commands.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/ingest/ingest.h"
#include "stages/segment/segment.h"

/* The table every --split folder holds; it also marks the folder as ours. */
#define SEGMENT_TABLE "trees.csv"

typedef struct {
    const char *out_path, *method_text, *format;
    int split, stem_points;
    double min_points;
    sy_segment_options o;
} segment_args;

static void tree_file_name(char *buf, size_t size, const sy_segment_tree *t, const char *ext)
{
    snprintf(buf, size, "tree_%04d.%s", (int)t->id, ext);
}

/* The table as CSV text (malloc'd): the same columns the terminal shows. */
static char *table_csv(const sy_segmentation *s, const char *ext)
{
    size_t cap = 128 + (s->n_trees + 1) * 200, len = 0;
    char *t = malloc(cap);
    if (!t) return NULL;
    len += (size_t)snprintf(t + len, cap - len, "id,x,y,z,height,dbh,crown_width,points%s\n", ext ? ",file" : "");
    for (size_t i = 0; i < s->n_trees; i++) {
        const sy_segment_tree *tr = &s->trees[i];
        char dbh[32] = "";
        if (!isnan(tr->dbh)) snprintf(dbh, sizeof dbh, "%.3f", tr->dbh);
        len += (size_t)snprintf(t + len, cap - len, "%d,%.3f,%.3f,%.3f,%.2f,%s,%.2f,%zu", (int)tr->id, tr->stem[0],
                                tr->stem[1], tr->stem[2], tr->height, dbh, tr->crown_width, tr->n_points);
        if (ext) {
            char name[64];
            tree_file_name(name, sizeof name, tr, ext);
            len += (size_t)snprintf(t + len, cap - len, ",%s", name);
        }
        len += (size_t)snprintf(t + len, cap - len, "\n");
    }
    return t;
}

static void print_report(const sy_segmentation *s, const char *in, const char *out, int split, const char *ext,
                         int json)
{
    size_t tree_points = s->n_points - s->n_ground - s->n_unassigned;
    if (json) {
        sy_json j;
        sy_cli_json_open(&j, in, out);
        sy_json_bool(&j, "split", split);
        sy_json_string(&j, "method", s->airborne ? "airborne" : "terrestrial");
        sy_json_int(&j, "point_count", (long long)s->n_points);
        sy_json_int(&j, "tree_count", (long long)s->n_trees);
        sy_json_int(&j, "tree_points", (long long)tree_points);
        sy_json_int(&j, "ground_points", (long long)s->n_ground);
        sy_json_int(&j, "unassigned_points", (long long)s->n_unassigned);
        sy_json_number(&j, "density", s->density);
        if (!s->airborne) sy_json_int(&j, "stem_candidates", (long long)s->n_stem_candidates);
        sy_json_number(&j, "seconds", s->seconds);
        sy_json_array(&j, "trees");
        for (size_t i = 0; i < s->n_trees; i++) {
            const sy_segment_tree *t = &s->trees[i];
            sy_json_object(&j, NULL);
            sy_json_int(&j, "id", t->id);
            sy_json_number(&j, "x", t->stem[0]);
            sy_json_number(&j, "y", t->stem[1]);
            sy_json_number(&j, "z", t->stem[2]);
            sy_json_number(&j, "height", t->height);
            sy_json_number(&j, "dbh", t->dbh);
            sy_json_number(&j, "crown_width", t->crown_width);
            sy_json_int(&j, "points", (long long)t->n_points);
            if (split) {
                char name[64];
                tree_file_name(name, sizeof name, t, ext);
                sy_json_string(&j, "file", name);
            }
            sy_json_end(&j);
        }
        sy_json_end(&j);
        sy_cli_json_close(&j);
        return;
    }
    printf("%s: %zu trees (%s), %zu points: %zu in trees, %zu ground, %zu unassigned\n", in, s->n_trees,
           s->airborne ? "airborne: canopy watershed" : "terrestrial: stems and crowns", s->n_points, tree_points,
           s->n_ground, s->n_unassigned);
    printf("%5s %12s %12s %9s %7s %6s %7s %9s\n", "id", "x", "y", "z", "height", "dbh", "crown", "points");
    for (size_t i = 0; i < s->n_trees; i++) {
        const sy_segment_tree *t = &s->trees[i];
        char dbh[16] = "-";
        if (!isnan(t->dbh)) snprintf(dbh, sizeof dbh, "%.3f", t->dbh);
        printf("%5d %12.2f %12.2f %9.2f %7.2f %6s %7.2f %9zu\n", (int)t->id, t->stem[0], t->stem[1], t->stem[2],
               t->height, dbh, t->crown_width, t->n_points);
    }
    printf("wrote %s%s in %.2f s\n", out, split ? " (one file per tree and " SEGMENT_TABLE ")" : "", s->seconds);
}

/* One file per tree plus the table, into a temp folder swapped in at the end. */
static sy_code write_split(const sy_cloud *plot, const sy_segmentation *s, const char *dir, const char *ext,
                           sy_error *err)
{
    char tmp[4400], path[4600];
    sy_code rc = sy_dir_output_begin(dir, SEGMENT_TABLE, tmp, sizeof tmp, err);
    if (rc) return rc;
    for (size_t i = 0; i < s->n_trees && rc == SY_OK; i++) {
        sy_cloud tree;
        rc = sy_segmentation_tree_cloud(plot, s, i, &tree, err);
        if (rc) break;
        char name[64];
        tree_file_name(name, sizeof name, &s->trees[i], ext);
        snprintf(path, sizeof path, "%s/%s", tmp, name);
        rc = sy_write_cloud(path, &tree, err);
        sy_cloud_free(&tree);
    }
    if (rc == SY_OK) {
        char *csv = table_csv(s, ext);
        snprintf(path, sizeof path, "%s/%s", tmp, SEGMENT_TABLE);
        rc = csv ? sy_write_file_atomic(path, csv, strlen(csv), err) : sy_fail(err, SY_EINTERNAL, "segment: out of memory");
        free(csv);
    }
    if (rc == SY_OK) return sy_dir_output_commit(dir, tmp, err);
    sy_dir_output_abort(tmp);
    return rc;
}

int cmd_segment(int argc, char **argv, sy_cli *cli)
{
    segment_args a = {NULL, "auto", "las", 0, 30, -1, sy_segment_options_default()};
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &a.out_path, "OUT", "labelled cloud (.las .laz .ply .xyz), or with --split a folder"},
        {"--split", OPT_FLAG, &a.split, NULL, "write one file per tree into the folder OUT, plus " SEGMENT_TABLE},
        {"--format", OPT_STRING, &a.format, "EXT", "--split: file format of the trees, las (default), laz, ply or xyz"},
        {"--method", OPT_STRING, &a.method_text, "M", "auto (default), terrestrial (stems + crowns) or airborne (canopy watershed)"},
        {"--breast-height", OPT_DOUBLE, &a.o.breast_height, "M", "stem search height above ground (default 1.3)"},
        {"--slice", OPT_DOUBLE, &a.o.slice, "M", "thickness of the stem search band (default 0.6)"},
        {"--min-radius", OPT_DOUBLE, &a.o.stem_min_radius, "M", "smallest stem radius (default 0.025)"},
        {"--max-radius", OPT_DOUBLE, &a.o.stem_max_radius, "M", "largest stem radius (default 1.0)"},
        {"--circle-tolerance", OPT_DOUBLE, &a.o.circle_tolerance, "M", "stem circle inlier band (default 0.025)"},
        {"--stem-points", OPT_INT, &a.stem_points, "N", "points a stem circle needs (default 30)"},
        {"--voxel", OPT_DOUBLE, &a.o.voxel, "M", "crown graph voxel size (default 0.15)"},
        {"--gap-penalty", OPT_DOUBLE, &a.o.gap_penalty, "P", "crown paths: edge cost grows as length^(1+P) (default 1)"},
        {"--chm-cell", OPT_DOUBLE, &a.o.chm_cell, "M", "airborne: canopy height model cell (default 0.5)"},
        {"--min-height", OPT_DOUBLE, &a.o.min_height, "M", "airborne: lowest tree top and crown edge (default 2)"},
        {"--window", OPT_DOUBLE, &a.o.window_base, "M", "airborne: tree-top window diameter at height 0 (default 3)"},
        {"--window-slope", OPT_DOUBLE, &a.o.window_slope, "F", "airborne: window growth per metre of height (default 0.15)"},
        {"--max-crown", OPT_DOUBLE, &a.o.max_crown_radius, "M", "airborne: largest crown radius (default 8)"},
        {"--min-points", OPT_DOUBLE, &a.min_points, "N", "trees with fewer points become unassigned (default 20)"},
        {"--ground-cell", OPT_DOUBLE, &a.o.ground_cell, "M", "ground filter cell (default 0.5)"},
        {"--ground-threshold", OPT_DOUBLE, &a.o.ground_threshold, "M", "height still counted as ground (default 0.15)"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "segment", "PLOT -o OUT", "Split a plot scan into trees: stem positions, heights, DBH, one cloud per tree.",
        "Ground and normalised heights come from the preprocess stage's ground filter. Terrestrial\n"
        "scans: stems are circles fitted at breast height, crowns follow the shortest voxel-graph\n"
        "path to a stem. Airborne scans: tree tops are local maxima of the canopy height model and\n"
        "crowns its watershed. auto looks for stems (above 10 points per m^2) and falls back to the\n"
        "canopy when none shows.\n"
        "OUT gets every point with a treeID extra-bytes attribute (1..N trees, 0 ground or\n"
        "unassigned); --split writes OUT/tree_0001.las ... and OUT/" SEGMENT_TABLE " instead. The table\n"
        "(id, x, y, ground z, height, DBH, crown width, points) is printed, or with --json an object\n"
        "with the point accounting and a \"trees\" array. Exit codes: 0 ok, 1 usage, 2 bad input.",
        opts, 1, 1};
    const char *in[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, in, 1, &n, SY_CLI_OUT_REQUIRED, &rc)) return rc;
    if (sy_segment_method_parse(a.method_text, &a.o.method)) {
        fprintf(stderr, "sylva segment: --method: expected auto, terrestrial or airborne, got '%s'\n", a.method_text);
        return SY_EUSAGE;
    }
    if (strcmp(a.format, "las") && strcmp(a.format, "laz") && strcmp(a.format, "ply") && strcmp(a.format, "xyz")) {
        fprintf(stderr, "sylva segment: --format: expected las, laz, ply or xyz, got '%s'\n", a.format);
        return SY_EUSAGE;
    }
    if (a.min_points >= 0) {
        if (a.min_points > 1e12 || a.min_points != floor(a.min_points)) {
            fprintf(stderr, "sylva segment: --min-points: expected a whole number of points\n");
            return SY_EUSAGE;
        }
        a.o.min_points = (size_t)a.min_points;
    } else if (a.min_points != -1) {
        fprintf(stderr, "sylva segment: --min-points: expected a whole number of points\n");
        return SY_EUSAGE;
    }
    if (a.stem_points < 5) {
        fprintf(stderr, "sylva segment: --stem-points: expected at least 5\n");
        return SY_EUSAGE;
    }
    a.o.stem_min_points = (size_t)a.stem_points;
    a.o.seed = cli->seed;
    sy_error err = {0};
    if (sy_segment_options_check(&a.o, &err)) {
        fprintf(stderr, "sylva %s\n", err.msg);
        return SY_EUSAGE;
    }
    if (!a.split && (rc = sy_cli_check_outputs(&a.out_path, 1, in, 1))) return rc;
    sy_cloud c;
    if (sy_read_cloud(in[0], &c, &err)) return sy_cli_report(&err);
    sy_segmentation s;
    rc = sy_segment(&c, &a.o, &s, &err);
    if (rc) {
        sy_cloud_free(&c);
        if (err.msg[0] && !strstr(err.msg, in[0])) {
            fprintf(stderr, "sylva: %s: %s\n", in[0], err.msg);
            return err.code;
        }
        return sy_cli_report(&err);
    }
    if (a.split) rc = write_split(&c, &s, a.out_path, a.format, &err);
    else {
        rc = sy_segmentation_label(&c, &s, &err);
        if (rc == SY_OK) rc = sy_write_cloud(a.out_path, &c, &err);
    }
    if (rc == SY_OK) print_report(&s, in[0], a.out_path, a.split, a.format, cli->json);
    sy_segmentation_free(&s);
    sy_cloud_free(&c);
    return rc ? sy_cli_report(&err) : 0;
}
