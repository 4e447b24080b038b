/* sylva photogrammetry PHOTOS/ -o cloud.ply: photos -> points through
 * COLMAP (stages/photogrammetry), levelled and scaled, written by extension.
 * Also the photo front end of `sylva run PHOTOS/`. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "pipeline/commands.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/ingest/ingest.h"
#include "stages/photogrammetry/photogrammetry.h"

typedef struct {
    const sy_cli *cli;
    int tty;
    double last_line;
} photo_progress;

static void show_progress(void *user, const char *step, int index, int steps, double seconds)
{
    photo_progress *p = user;
    if (p->cli->quiet || p->cli->json) return;
    if (p->tty) {
        fprintf(stderr, "\rphotogrammetry: [%d/%d] %-18s %6.1f s", index, steps, step, seconds);
        fflush(stderr);
        return;
    }
    /* plain lines: each step's start, then every 10 s */
    if (seconds == 0.0 || seconds - p->last_line >= 10.0) {
        fprintf(stderr, "photogrammetry: [%d/%d] %s %.0f s\n", index, steps, step, seconds);
        p->last_line = seconds;
    }
    if (seconds == 0.0) p->last_line = 0.0;
}

sy_code sy_photo_cli_apply(sy_photo_cli *c, const char *workspace, sy_photogrammetry_options *o, sy_error *err)
{
    *o = sy_photogrammetry_options_default();
    o->workspace = workspace;
    if (c->colmap) o->colmap = c->colmap;
    if (c->quality) {
        if (strcmp(c->quality, "low") == 0) o->quality = SY_PHOTO_LOW;
        else if (strcmp(c->quality, "medium") == 0) o->quality = SY_PHOTO_MEDIUM;
        else if (strcmp(c->quality, "high") == 0) o->quality = SY_PHOTO_HIGH;
        else return sy_fail(err, SY_EUSAGE, "--quality must be low, medium or high, got '%s'", c->quality);
    }
    if (c->min_registered != 0) o->min_registered = c->min_registered;
    o->camera_spacing = c->camera_spacing;
    o->sequential_overlap = c->sequential;
    if (c->scale_ref) {
        /* "A,B,METRES" */
        char *a = c->scale_a, *b = c->scale_b; /* storage in the flags struct: no globals */
        const char *p1 = strchr(c->scale_ref, ','), *p2 = p1 ? strchr(p1 + 1, ',') : NULL;
        if (!p1 || !p2 || (size_t)(p1 - c->scale_ref) >= sizeof c->scale_a || (size_t)(p2 - p1 - 1) >= sizeof c->scale_b)
            return sy_fail(err, SY_EUSAGE, "--scale-ref wants PHOTO_A,PHOTO_B,METRES, got '%s'", c->scale_ref);
        memcpy(a, c->scale_ref, (size_t)(p1 - c->scale_ref));
        a[p1 - c->scale_ref] = 0;
        memcpy(b, p1 + 1, (size_t)(p2 - p1 - 1));
        b[p2 - p1 - 1] = 0;
        char *end;
        o->scale_distance = strtod(p2 + 1, &end);
        if (*end || end == p2 + 1)
            return sy_fail(err, SY_EUSAGE, "--scale-ref: '%s' is not a distance in metres", p2 + 1);
        o->scale_image_a = a;
        o->scale_image_b = b;
    }
    return sy_photogrammetry_options_check(o, err);
}

sy_code sy_photos_to_cloud(const char *dir, const char *out_path_hint, sy_photo_cli *c, const sy_cli *cli,
                           sy_photogrammetry_result *r, sy_error *err)
{
    if (c->workspace) snprintf(c->workspace_path, sizeof c->workspace_path, "%s", c->workspace);
    else snprintf(c->workspace_path, sizeof c->workspace_path, "%.4080s.colmap", out_path_hint);
    sy_photogrammetry_options o;
    sy_code rc = sy_photo_cli_apply(c, c->workspace_path, &o, err);
    if (rc) return rc;
    o.threads = cli->threads;
    photo_progress p = {cli, isatty(2), 0};
    o.progress = show_progress;
    o.progress_user = &p;
    rc = sy_photogrammetry_run(dir, &o, r, err);
    if (p.tty && !cli->quiet && !cli->json) fprintf(stderr, "\n");
    if (rc) return rc;
    if (!cli->quiet && !cli->json) {
        fprintf(stderr, "photogrammetry: %zu of %zu photos registered, %zu points (%s)\n", r->n_registered,
                r->n_images, r->cloud.n,
                r->dense ? "dense stereo" : "sparse model: this colmap has no CUDA for dense stereo");
        if (r->scaled) fprintf(stderr, "photogrammetry: scale %.6g m per COLMAP unit\n", r->scale);
        else fprintf(stderr, "photogrammetry: no scale reference: units are COLMAP's, not metres\n");
        fprintf(stderr, "photogrammetry: COLMAP log %s\n", r->log_path);
    }
    return SY_OK;
}

int cmd_photogrammetry(int argc, char **argv, sy_cli *cli)
{
    const char *out_path = NULL;
    sy_photo_cli photo;
    memset(&photo, 0, sizeof photo);
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &out_path, "OUT", "point cloud to write (.ply .las .laz .xyz)"},
        SY_PHOTO_OPTIONS(photo),
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "photogrammetry", "PHOTOS/ -o OUT [--scale-ref A,B,METRES | --camera-spacing METRES]",
        "Reconstruct a point cloud from photos with COLMAP (feature extraction, matching, mapping).",
        "Runs Debian's `colmap` as a subprocess with the GPU off; dense stereo only where colmap has\n"
        "CUDA, else the sparse model's points (the output says which). The cloud is levelled (Z along\n"
        "the cameras' mean up vector) and scaled to metres by --scale-ref (two photo names and the\n"
        "distance between the cameras that took them) or --camera-spacing (mean distance between\n"
        "consecutive photos, in name order); without either the unit is COLMAP's. COLMAP's database,\n"
        "models and log (colmap.log) stay in the workspace, OUT.colmap/ by default.",
        opts, 1, 1};
    const char *in[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, in, 1, &n, SY_CLI_OUT_REQUIRED, &rc)) return rc;
    sy_error err = {0};
    if (!sy_is_directory(in[0])) {
        sy_fail(&err, SY_EINPUT, "%s: not a folder of photos", in[0]);
        return sy_cli_report(&err);
    }
    if ((rc = sy_check_writable(out_path, &err))) return sy_cli_report(&err);
    sy_photogrammetry_result r;
    if ((rc = sy_photos_to_cloud(in[0], out_path, &photo, cli, &r, &err))) return sy_cli_report(&err);
    rc = sy_write_cloud(out_path, &r.cloud, &err);
    if (rc == SY_OK && cli->json) {
        sy_json j;
        sy_cli_json_open(&j, in[0], out_path);
        sy_json_int(&j, "images", (long long)r.n_images);
        sy_json_int(&j, "registered", (long long)r.n_registered);
        sy_json_int(&j, "point_count", (long long)r.cloud.n);
        sy_json_string(&j, "points_from", r.dense ? "dense" : "sparse");
        sy_json_bool(&j, "scaled", r.scaled);
        sy_json_number(&j, "scale", r.scale);
        sy_json_number(&j, "camera_up_spread_deg", r.up_spread_deg);
        sy_json_string(&j, "model", r.model_dir);
        sy_json_string(&j, "log", r.log_path);
        sy_cli_json_close(&j);
    } else if (rc == SY_OK && !cli->quiet) {
        fprintf(stderr, "wrote %zu points to %s\n", r.cloud.n, out_path);
    }
    sy_photogrammetry_result_free(&r);
    return rc ? sy_cli_report(&err) : 0;
}
