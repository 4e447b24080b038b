/* sylva preprocess IN -o OUT: up-axis, crop, voxel, outliers, ground, normals. */
#include <math.h>
#include <stdio.h>

#include "pipeline/commands.h"
#include "stages/core/json.h"
#include "stages/ingest/ingest.h"
#include "stages/preprocess/preprocess.h"

/* One call's arguments: the stage's options plus what only the CLI has. */
typedef struct {
    const char *out_path, *up_text;
    double crop_box[6];
    int no_sor, no_ground, no_normals;
    sy_preprocess_options o;
} preprocess_args;

/* The CLI-only arguments into a->o, then the stage's check. */
static int build_opts(preprocess_args *a, sy_error *err)
{
    if (sy_up_parse(a->up_text, &a->o.up))
        return sy_fail(err, SY_EUSAGE, "--up: expected auto, z, y, x, -z, -y or -x, got '%s'", a->up_text);
    a->o.crop = !isnan(a->crop_box[0]);
    for (int i = 0; i < 6; i++) a->o.crop_box[i] = a->crop_box[i];
    a->o.sor = !a->no_sor;
    a->o.ground = !a->no_ground;
    a->o.normals = !a->no_normals;
    return sy_preprocess_options_check(&a->o, err);
}

static void print_report(const sy_preprocess_result *r, const char *in, const char *out, int json)
{
    if (json) {
        sy_json j;
        sy_cli_json_open(&j, in, out);
        sy_json_int(&j, "point_count_in", (long long)r->point_count_in);
        sy_json_int(&j, "point_count_out", (long long)r->point_count_out);
        sy_json_string(&j, "up_axis", sy_up_name(r->up_axis));
        sy_json_bool(&j, "up_detected", r->up_detected);
        sy_json_int(&j, "ground_points", (long long)r->ground_points);
        sy_json_array(&j, "steps");
        for (int i = 0; i < SY_PREPROCESS_STEPS; i++) {
            const sy_preprocess_step *s = &r->steps[i];
            sy_json_object(&j, NULL);
            sy_json_string(&j, "name", s->name);
            sy_json_bool(&j, "ran", s->ran);
            sy_json_int(&j, "before", (long long)s->before);
            sy_json_int(&j, "after", (long long)s->after);
            sy_json_int(&j, "removed", (long long)(s->before - s->after));
            sy_json_number(&j, "seconds", s->seconds);
            sy_json_string(&j, "detail", s->detail);
            sy_json_end(&j);
        }
        sy_json_end(&j);
        sy_cli_json_close(&j);
        return;
    }
    for (int i = 0; i < SY_PREPROCESS_STEPS; i++) {
        const sy_preprocess_step *s = &r->steps[i];
        if (!s->ran) printf("%-9s skipped\n", s->name);
        else
            printf("%-9s %zu -> %zu points (-%zu) in %.3f s%s%s\n", s->name, s->before, s->after, s->before - s->after,
                   s->seconds, s->detail[0] ? ": " : "", s->detail);
    }
    printf("wrote %zu of %zu points to %s (input up %s)\n", r->point_count_out, r->point_count_in, out,
           sy_up_name(r->up_axis));
}

int cmd_preprocess(int argc, char **argv, sy_cli *cli)
{
    preprocess_args a = {NULL, "auto", {NAN, NAN, NAN, NAN, NAN, NAN}, 0, 0, 0, sy_preprocess_options_default()};
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &a.out_path, "OUT", "output file; format from extension (.ply .las .xyz .txt)"},
        {"--up", OPT_STRING, &a.up_text, "AXIS", "input up axis: auto (default), z, y, x, -z, -y, -x"},
        {"--crop", OPT_DOUBLE6, a.crop_box, "BOX", "keep xmin,ymin,zmin,xmax,ymax,zmax (world, after up)"},
        {"--voxel", OPT_DOUBLE, &a.o.voxel, "SIZE", "keep one real point per SIZE m voxel (default 0: off)"},
        {"--sor-k", OPT_INT, &a.o.sor_k, "K", "outlier removal neighbours (default 16)"},
        {"--sor-std", OPT_DOUBLE, &a.o.sor_std, "S", "outlier threshold in standard deviations (default 2.0)"},
        {"--no-sor", OPT_FLAG, &a.no_sor, NULL, "skip outlier removal"},
        {"--ground-cell", OPT_DOUBLE, &a.o.ground_cell, "M", "ground filter cell size (default 0.5 m)"},
        {"--ground-slope", OPT_DOUBLE, &a.o.ground_slope, "S", "terrain slope tolerated, rise/run (default 0.3)"},
        {"--ground-max-window", OPT_DOUBLE, &a.o.ground_max_window, "M", "largest object flattened (default 16 m)"},
        {"--ground-threshold", OPT_DOUBLE, &a.o.ground_threshold, "M", "height still counted as ground (default 0.15 m)"},
        {"--remove-ground", OPT_FLAG, &a.o.remove_ground, NULL, "drop ground points instead of only classifying them"},
        {"--no-ground", OPT_FLAG, &a.no_ground, NULL, "skip ground classification"},
        {"--normal-k", OPT_INT, &a.o.normal_k, "K", "normal estimation neighbours (default 16)"},
        {"--no-normals", OPT_FLAG, &a.no_normals, NULL, "skip normal estimation"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "preprocess", "IN -o OUT", "Clean a scan: up-axis, crop, voxel, outliers, ground, normals.",
        "Steps run in that order, each optional. Ground points get class 2 and every point a\n"
        "height_above_ground attribute. The report has one line per step (--json: an object with\n"
        "a \"steps\" array). Exit codes: 0 ok, 1 usage, 2 bad input.",
        opts, 1, 1};
    const char *in[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, in, 1, &n, SY_CLI_OUT_CHECKED, &rc)) return rc;
    sy_error err = {0};
    if (build_opts(&a, &err)) {
        fprintf(stderr, "sylva preprocess: %s\n", err.msg);
        return SY_EUSAGE;
    }
    sy_cloud c;
    if (sy_read_cloud(in[0], &c, &err)) return sy_cli_report(&err);
    sy_preprocess_result r;
    rc = sy_preprocess(&c, &a.o, &r, &err);
    if (rc == SY_OK && c.n == 0) rc = sy_fail(&err, SY_EINPUT, "%s: no points left after preprocessing", in[0]);
    if (rc == SY_OK) rc = sy_write_cloud(a.out_path, &c, &err);
    if (rc == SY_OK) print_report(&r, in[0], a.out_path, cli->json);
    sy_cloud_free(&c);
    return rc ? sy_cli_report(&err) : 0;
}
