/* Preprocessing: turns a raw scan into a clean, Z-up cloud ready for
 * segmentation. Steps, in order, each optional: up-axis normalisation, crop,
 * voxel downsampling, statistical outlier removal, ground classification and
 * normal estimation. Every removal goes through sy_cloud_filter so all
 * per-point attributes stay aligned, and each step reports what it did. */
#ifndef SYLVA_PREPROCESS_H
#define SYLVA_PREPROCESS_H

#include <stddef.h>

#include "../core/cloud.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Up axes as signed axis codes: +-1 = +-x, +-2 = +-y, +-3 = +-z; 0 = detect. */
enum { SY_UP_AUTO = 0, SY_UP_X = 1, SY_UP_Y = 2, SY_UP_Z = 3 };

/* Parses "auto", "z", "+z", "-y", ...; returns 0 and sets *up, or -1. */
int sy_up_parse(const char *text, int *up);
/* "+z", "-y", "auto". */
const char *sy_up_name(int up);

typedef struct {
    int up;                  /* SY_UP_AUTO or a signed axis code */
    int crop;                /* 1: keep only points inside crop_box */
    double crop_box[6];      /* xmin,ymin,zmin,xmax,ymax,zmax, world, after up */
    double voxel;            /* voxel edge in metres, 0 = off */
    int sor;                 /* statistical outlier removal on/off */
    int sor_k;
    double sor_std;
    int keep_top;            /* 1: the crown's top the outlier filter strips is kept (default);
                                0: dropped, only measured (top_z): `sylva run` reconstructs from
                                the filtered points and takes the height to top_z */
    int ground;              /* ground classification on/off */
    double ground_cell;      /* metres */
    double ground_slope;     /* rise over run the terrain may have */
    double ground_max_window;/* metres: the largest object PMF flattens */
    double ground_threshold; /* metres above the ground surface still ground */
    int remove_ground;       /* drop ground points after classifying */
    int normals;             /* normal estimation on/off */
    int normal_k;
} sy_preprocess_options;

sy_preprocess_options sy_preprocess_options_default(void);
/* Checks ranges; SY_EUSAGE with a message naming the option otherwise. */
sy_code sy_preprocess_options_check(const sy_preprocess_options *o, sy_error *err);

typedef struct {
    const char *name;  /* "up", "crop", "voxel", "outliers", "ground", "normals" */
    int ran;           /* 0 when switched off */
    size_t before, after;
    double seconds;
    char detail[240];  /* one human line: what was found or decided */
} sy_preprocess_step;

enum { SY_PREPROCESS_STEPS = 6 };

typedef struct {
    sy_preprocess_step steps[SY_PREPROCESS_STEPS];
    size_t point_count_in, point_count_out;
    int up_axis;         /* the axis the input had as up (signed code) */
    int up_detected;     /* 1 when auto detection chose it */
    size_t ground_points;
    double top_z;        /* world z of the crown's top, taken before the outlier filter (which
                            strips a sparse crown top): the highest point with at least 3 others
                            within 0.5 m, then on up through returns each within 1 m of one below
                            it; NaN: none, or the filter is off */
} sy_preprocess_result;

/* Runs the enabled steps on c in place. */
sy_code sy_preprocess(sy_cloud *c, const sy_preprocess_options *o, sy_preprocess_result *r, sy_error *err);

/* --- the steps, also usable alone --- */

/* Evidence behind an up-axis decision, per unsigned axis x, y, z. */
typedef struct {
    double axis_score[3]; /* fractions: floors at either end + vertical surfaces + vertical stems */
    double sign_score[3]; /* > 0: the + direction is up */
    size_t sample;        /* points analysed */
} sy_up_evidence;

/* `auto` in sy_preprocess keeps the file's +z unless the detected axis scores
 * at least SY_UP_AXIS_MARGIN times z's, or (for -z) the sign evidence is at
 * least SY_UP_SIGN_MARGIN; sy_detect_up itself has no such prior. */
#define SY_UP_AXIS_MARGIN 1.5
#define SY_UP_SIGN_MARGIN 0.03

/* Detects which signed axis of c points up (geometry only); ev may be NULL. */
sy_code sy_detect_up(const sy_cloud *c, int *up, sy_up_evidence *ev, sy_error *err);
/* Rotates c (positions, origin, normals) so that the signed axis up becomes
 * +z, with a proper rotation (right-handed stays right-handed). */
void sy_rotate_to_z_up(sy_cloud *c, int up);

/* Keeps the points whose world position lies inside box (bounds inclusive). */
sy_code sy_crop(sy_cloud *c, const double box[6], sy_error *err);

/* Keeps one real point per voxel of edge size: the one nearest the voxel's
 * centroid (lowest index on ties). Order of the kept points is unchanged. */
sy_code sy_voxel_downsample(sy_cloud *c, double size, sy_error *err);

/* The voxel edge (metres) that leaves at most target occupied voxels, found
 * by bisection in log size to within 0.5%; 0 when c has target points or
 * fewer. O(n) a step, ten steps. */
sy_code sy_voxel_size_for_count(const sy_cloud *c, size_t target, double *size, sy_error *err);
/* The finest voxel edge (metres) the voxel keys allow over c's extent. */
double sy_voxel_finest(const sy_cloud *c);

/* Removes statistical outliers (PCL). */
sy_code sy_remove_outliers(sy_cloud *c, int k, double std_mul, sy_error *err);
/* The same, giving back the crown's top the filter strips: dropped points
 * above every kept one, up to top_z (world z, NaN: none), are kept when
 * chained (c->n flags, may be NULL: the chain to the top, sy_preprocess)
 * or with 3 others within 0.5 m; *given counts them. */
sy_code sy_remove_outliers_keeping_top(sy_cloud *c, int k, double std_mul, double top_z, const uint8_t *chained,
                                       size_t *given, sy_error *err);

/* Classifies ground (class 2, other points keep their class or get 1 =
 * unclassified when the cloud had none) and fills the attribute
 * "height_above_ground"; *n_ground gets the ground count. */
sy_code sy_classify_ground(sy_cloud *c, const sy_preprocess_options *o, size_t *n_ground, sy_error *err);

/* Estimates unit normals from k neighbours on sy_threads() threads, oriented
 * along up plus the horizontal direction away from the vertical line through
 * the cloud's median point: ground normals point up, the normals of a stem
 * on that line point outwards. */
sy_code sy_estimate_normals(sy_cloud *c, int k, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
