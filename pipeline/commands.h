/* Entry points of the subcommands, one file each (pipeline/cmd_<name>.c). */
#ifndef SYLVA_COMMANDS_H
#define SYLVA_COMMANDS_H

#include "pipeline/cli.h"
#include "stages/photogrammetry/photogrammetry.h"

#ifdef __cplusplus
extern "C" {
#endif

int cmd_info(int argc, char **argv, sy_cli *cli);
int cmd_convert(int argc, char **argv, sy_cli *cli);
int cmd_preprocess(int argc, char **argv, sy_cli *cli);
int cmd_segment(int argc, char **argv, sy_cli *cli);
int cmd_grow(int argc, char **argv, sy_cli *cli);
int cmd_scan(int argc, char **argv, sy_cli *cli);
int cmd_eval(int argc, char **argv, sy_cli *cli);
int cmd_skeleton(int argc, char **argv, sy_cli *cli);
int cmd_mesh(int argc, char **argv, sy_cli *cli);
int cmd_run(int argc, char **argv, sy_cli *cli);
int cmd_batch(int argc, char **argv, sy_cli *cli);
int cmd_train(int argc, char **argv, sy_cli *cli);
int cmd_classify(int argc, char **argv, sy_cli *cli);
int cmd_encode(int argc, char **argv, sy_cli *cli);
int cmd_decode(int argc, char **argv, sy_cli *cli);
int cmd_leaf(int argc, char **argv, sy_cli *cli);
int cmd_library(int argc, char **argv, sy_cli *cli);
int cmd_photogrammetry(int argc, char **argv, sy_cli *cli);

/* Photo input, shared by `photogrammetry` and `run PHOTOS/`: the flags and
 * the call that turns a folder of photos into a levelled, scaled cloud. */
typedef struct {
    const char *workspace, *scale_ref, *quality, *colmap;
    double camera_spacing, min_registered;
    int sequential;
    char scale_a[256], scale_b[256], workspace_path[4096]; /* filled by the calls below */
} sy_photo_cli;
#define SY_PHOTO_OPTIONS(p)                                                                                          \
    {"--workspace", OPT_STRING, &(p).workspace, "DIR", "COLMAP workspace: database, models, colmap.log (default OUT.colmap)"}, \
        {"--scale-ref", OPT_STRING, &(p).scale_ref, "A,B,M", "photos A and B were taken M metres apart (sets the scale)"}, \
        {"--camera-spacing", OPT_DOUBLE, &(p).camera_spacing, "M",                                                     \
         "mean distance between consecutive photos in metres (sets the scale)"},                                     \
        {"--quality", OPT_STRING, &(p).quality, "Q", "low, medium (default) or high: image size and features COLMAP uses"}, \
        {"--colmap", OPT_STRING, &(p).colmap, "PATH", "the colmap executable (default: colmap on PATH)"},            \
        {"--sequential", OPT_INT, &(p).sequential, "N",                                                              \
         "match each photo with the N next in name order only (a walk around; default: all pairs)"},                \
    {                                                                                                                \
        "--min-registered", OPT_DOUBLE, &(p).min_registered, "F",                                                    \
            "fail unless this fraction of the photos registers (default 0.5)"                                        \
    }
/* Fills photogrammetry options from the flags (workspace given). */
sy_code sy_photo_cli_apply(sy_photo_cli *c, const char *workspace, sy_photogrammetry_options *o, sy_error *err);
/* Runs photogrammetry on dir with the workspace from --workspace or
 * "<out_path_hint>.colmap", reporting progress and the outcome on stderr. */
sy_code sy_photos_to_cloud(const char *dir, const char *out_path_hint, sy_photo_cli *c, const sy_cli *cli,
                           sy_photogrammetry_result *r, sy_error *err);
int cmd_view(int argc, char **argv, sy_cli *cli);
/* The sylva-view executable: $SYLVA_VIEW when set, else the one beside this
 * sylva, else the first on PATH; 1 when found (view and batch run it). */
int sy_find_viewer(char *out, size_t size);

#ifdef __cplusplus
}
#endif

#endif
