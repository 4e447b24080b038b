/* Photogrammetry: a folder of photos -> a point cloud, by driving COLMAP's
 * command-line tools as subprocesses (Schoenberger & Frahm, "Structure-from-
 * Motion Revisited", CVPR 2016): SIFT feature extraction, exhaustive
 * matching and incremental mapping with the GPU off; dense stereo only when
 * the colmap binary was built with CUDA, else the sparse model. The result
 * is brought into Sylva's frame: Z up along the cameras' mean up vector, and
 * metres from a reference distance between two cameras or the known spacing
 * of consecutive cameras. COLMAP's whole log is kept in the workspace. */
#ifndef SYLVA_PHOTOGRAMMETRY_H
#define SYLVA_PHOTOGRAMMETRY_H

#include "../core/cloud.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { SY_PHOTO_LOW = 0, SY_PHOTO_MEDIUM = 1, SY_PHOTO_HIGH = 2 } sy_photo_quality;

typedef struct {
    const char *colmap;       /* the colmap executable ("colmap": found on PATH) */
    const char *workspace;    /* folder for COLMAP's database, models and log (created; required) */
    sy_photo_quality quality; /* image size and feature count COLMAP works at */
    int threads;              /* COLMAP's thread count; 0 = all cores */
    /* 0: match every pair of photos (exhaustive); N > 0: each photo with the
     * N next in name order (a walk around the tree, frames of a video). */
    int sequential_overlap;
    /* Scale, at most one of: the distance in metres between the centres of
     * the cameras that took scale_image_a and scale_image_b ... */
    const char *scale_image_a, *scale_image_b;
    double scale_distance;
    /* ... or the mean distance in metres between consecutive cameras (in
     * image-name order). Neither: COLMAP's arbitrary unit, reported. */
    double camera_spacing;
    double min_registered; /* fraction of the photos that must register (0..1] */
    /* Called between steps and about every second while COLMAP runs. */
    void (*progress)(void *user, const char *step, int step_index, int steps, double seconds);
    void *progress_user;
} sy_photogrammetry_options;

sy_photogrammetry_options sy_photogrammetry_options_default(void);
sy_code sy_photogrammetry_options_check(const sy_photogrammetry_options *o, sy_error *err);

typedef struct {
    sy_cloud cloud;           /* Z up; metres when a scale was given */
    size_t n_images;          /* photos found */
    size_t n_registered;      /* photos COLMAP placed */
    int dense;                /* 1: dense stereo fused points; 0: the sparse model's points */
    int scaled;               /* 1 when scale_* or camera_spacing set the unit */
    double scale;             /* metres per COLMAP unit (1 when not scaled) */
    double up_spread_deg;     /* mean angle of the camera ups from their mean: how level the set was */
    char model_dir[4096];     /* the sparse model used */
    char log_path[4096];      /* COLMAP's output, every step */
    /* Registered cameras in the output frame, sorted by name. */
    size_t n_cameras;
    char (*camera_names)[128];
    double *camera_centres; /* 3 per camera */
} sy_photogrammetry_result;

/* Runs COLMAP over the photos in images_dir. Fails with SY_EINPUT and a
 * message that says why when there are too few photos, COLMAP finds no
 * model (no overlap between views), too few photos register, or a scale
 * reference names an image that did not register; with SY_EINTERNAL when
 * colmap cannot be run. */
sy_code sy_photogrammetry_run(const char *images_dir, const sy_photogrammetry_options *o,
                              sy_photogrammetry_result *out, sy_error *err);
void sy_photogrammetry_result_free(sy_photogrammetry_result *r);

/* The number of photos (.jpg .jpeg .png .tif .tiff .bmp .ppm .pgm, any case)
 * directly in dir; 0 when dir cannot be read. */
size_t sy_photogrammetry_count_images(const char *dir);

#ifdef __cplusplus
}
#endif

#endif
