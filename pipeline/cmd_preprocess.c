/* sylva preprocess IN -o OUT: up-axis, crop, voxel, outliers, ground, normals. */
#include <math.h>
#include <stdio.h>

#include "pipeline/commands.h"
#include "stages/core/json.h"
#include "stages/ingest/ingest.h"
#include "stages/preprocess/preprocess.h"

static const char *out_path, *up_text;
static double crop_box[6], voxel, sor_std, ground_cell, ground_slope, ground_window, ground_threshold;
static int sor_k, normal_k, no_sor, no_ground, no_normals, remove_ground;

static const sy_opt opts[] = {
    {"-o", OPT_STRING, &out_path, "OUT", "output file; format from extension (.ply .las .xyz .txt)"},
    {"--up", OPT_STRING, &up_text, "AXIS", "input up axis: auto (default), z, y, x, -z, -y, -x"},
    {"--crop", OPT_DOUBLE6, crop_box, "BOX", "keep xmin,ymin,zmin,xmax,ymax,zmax (world, after up)"},
    {"--voxel", OPT_DOUBLE, &voxel, "SIZE", "keep one real point per SIZE m voxel (default 0: off)"},
    {"--sor-k", OPT_INT, &sor_k, "K", "outlier removal neighbours (default 16)"},
    {"--sor-std", OPT_DOUBLE, &sor_std, "S", "outlier threshold in standard deviations (default 2.0)"},
    {"--no-sor", OPT_FLAG, &no_sor, NULL, "skip outlier removal"},
    {"--ground-cell", OPT_DOUBLE, &ground_cell, "M", "ground filter cell size (default 0.5 m)"},
    {"--ground-slope", OPT_DOUBLE, &ground_slope, "S", "terrain slope tolerated, rise/run (default 0.3)"},
    {"--ground-max-window", OPT_DOUBLE, &ground_window, "M", "largest object flattened (default 16 m)"},
    {"--ground-threshold", OPT_DOUBLE, &ground_threshold, "M", "height still counted as ground (default 0.15 m)"},
    {"--remove-ground", OPT_FLAG, &remove_ground, NULL, "drop ground points instead of only classifying them"},
    {"--no-ground", OPT_FLAG, &no_ground, NULL, "skip ground classification"},
    {"--normal-k", OPT_INT, &normal_k, "K", "normal estimation neighbours (default 16)"},
    {"--no-normals", OPT_FLAG, &no_normals, NULL, "skip normal estimation"},
    {NULL, 0, NULL, NULL, NULL},
};
static const sy_cmd_spec spec = {
    "preprocess", "IN -o OUT", "Clean a scan: up-axis, crop, voxel, outliers, ground, normals.",
    "Steps run in that order, each optional. Ground points get class 2 and every point a\n"
    "height_above_ground attribute. The report has one line per step (--json: an object with\n"
    "a \"steps\" array). Exit codes: 0 ok, 1 usage, 2 bad input.",
    opts, 1, 1};

static void set_defaults(void)
{
    sy_preprocess_options d;
    d = sy_preprocess_options_default();
    out_path = NULL;
    up_text = "auto";
    for (int i = 0; i < 6; i++) crop_box[i] = NAN;
    voxel = d.voxel;
    sor_k = d.sor_k, sor_std = d.sor_std;
    ground_cell = d.ground_cell, ground_slope = d.ground_slope;
    ground_window = d.ground_max_window, ground_threshold = d.ground_threshold;
    normal_k = d.normal_k;
    no_sor = no_ground = no_normals = remove_ground = 0;
}

static int build_opts(sy_preprocess_options *o, sy_error *err)
{
    *o = sy_preprocess_options_default();
    if (sy_up_parse(up_text, &o->up))
        return sy_fail(err, SY_EUSAGE, "--up: expected auto, z, y, x, -z, -y or -x, got '%s'", up_text);
    o->crop = !isnan(crop_box[0]);
    for (int i = 0; i < 6; i++) o->crop_box[i] = crop_box[i];
    o->voxel = voxel;
    o->sor = !no_sor, o->sor_k = sor_k, o->sor_std = sor_std;
    o->ground = !no_ground, o->remove_ground = remove_ground;
    o->ground_cell = ground_cell, o->ground_slope = ground_slope;
    o->ground_max_window = ground_window, o->ground_threshold = ground_threshold;
    o->normals = !no_normals, o->normal_k = normal_k;
    return sy_preprocess_options_check(o, err);
}

static void print_report(const sy_preprocess_result *r, const char *in, const char *out, int json)
{
    if (json) {
        sy_json j;
        sy_json_begin(&j, stdout, 0);
        sy_json_object(&j, NULL);
        sy_json_string(&j, "input", in);
        sy_json_string(&j, "output", out);
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
        sy_json_end(&j);
        sy_json_finish(&j);
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
    const char *in[1];
    int n;
    set_defaults();
    int rc = sy_cli_parse(&spec, argc, argv, cli, in, 1, &n);
    if (rc) return rc < 0 ? 0 : rc;
    sy_cli_apply_settings(cli);
    sy_error err = {0};
    if (!out_path) {
        fprintf(stderr, "sylva preprocess: -o OUT is required\n");
        return SY_EUSAGE;
    }
    sy_preprocess_options o;
    if (build_opts(&o, &err)) {
        fprintf(stderr, "sylva preprocess: %s\n", err.msg);
        return SY_EUSAGE;
    }
    sy_cloud c;
    if (sy_read_cloud(in[0], &c, &err)) return sy_cli_report(&err);
    sy_preprocess_result r;
    rc = sy_preprocess(&c, &o, &r, &err);
    if (rc == SY_OK && c.n == 0) rc = sy_fail(&err, SY_EINPUT, "%s: no points left after preprocessing", in[0]);
    if (rc == SY_OK) rc = sy_write_cloud(out_path, &c, &err);
    if (rc == SY_OK) print_report(&r, in[0], out_path, cli->json);
    sy_cloud_free(&c);
    return rc ? sy_cli_report(&err) : 0;
}
