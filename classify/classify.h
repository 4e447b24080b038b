/* Species classification after Pirk 2013 §3.5.1 (Livny et al. 2011, "Texture-lobes
 * for tree modelling"): a feature vector of over 200 numbers per tree from its
 * points and its first skeleton, a JointBoost classifier (Torralba, Murphy &
 * Freeman 2007, "Sharing visual features for multiclass and multiview object
 * detection") giving a probability vector, the confidence rule h1 > 1.5 h2, and
 * spatial voting among neighbouring trees for the unconfident ones.
 *
 * Three parts, each usable alone:
 *   features   sy_features_compute: one segmented, Z-up tree cloud -> floats
 *              (docs/classify.md lists every feature);
 *   JointBoost sy_jb_train / sy_jb_predict / sy_jb_save / sy_jb_load over any
 *              feature matrix (the model file format is in docs/classify.md);
 *   voting     sy_vote over a set of trees with probabilities and positions.
 * Nothing here reads scans or knows the CLI; the model file is this stage's own. */
#ifndef SYLVA_CLASSIFY_H
#define SYLVA_CLASSIFY_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/cloud.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- features */

/* Bumped whenever a feature's definition or the order changes: a model trained
 * on other features refuses to load against this code. */
#define SY_FEATURES_VERSION 2

typedef struct {
    double voxel;      /* first subsampling voxel, metres (0.04); grown by 15% steps
                          until at most max_points voxels remain */
    size_t max_points; /* points the features are computed on (8000) */
    int skeleton;      /* 1: also the skeleton features (-1 when 0) (1) */
    size_t skeleton_points; /* the skeleton's own, finer subsample: at most this many (20000) */
} sy_features_options;

sy_features_options sy_features_options_default(void);
sy_code sy_features_options_check(const sy_features_options *o, sy_error *err);

/* Number of features and the name of feature i ("height_m", "normal_elev_s2_b07")
 * written to name and returned; NULL past the last feature (or out of memory). */
#define SY_FEATURE_NAME_MAX 40
size_t sy_feature_count(void);
/* The fewest points sy_features_compute takes (fewer: SY_EINPUT). */
#define SY_FEATURES_MIN_POINTS 32
const char *sy_feature_name(size_t i, char name[SY_FEATURE_NAME_MAX]);

typedef struct {
    size_t points_in;    /* points of the tree cloud */
    size_t points_used;  /* after subsampling */
    double voxel;        /* the voxel that reached max_points */
    double spacing;      /* median nearest-neighbour spacing of the input, metres */
    double base[3];      /* world position of the trunk base (x, y: trunk axis; z: base) */
    double height;       /* metres, base to the 99.5th percentile of z */
    double seconds;      /* wall time */
} sy_features_info;

/* Computes sy_feature_count() floats into out for one tree (ground removed,
 * Z up, any position and heading). Features that a tree cannot give (no trunk
 * slab, no skeleton) are -1. Fails with SY_EINPUT for fewer than 32 points.
 * Deterministic; uses one thread. info may be NULL. */
sy_code sy_features_compute(const sy_cloud *tree, const sy_features_options *o, float *out,
                            sy_features_info *info, sy_error *err);

/* --------------------------------------------------------------- JointBoost */

#define SY_JB_MAX_CLASSES 64
#define SY_JB_FORMAT_VERSION 3

typedef struct {
    int rounds;           /* most boosting rounds (600) */
    int max_thresholds;   /* candidate thresholds per feature: midpoints between sorted distinct
                             values, at most this many spread evenly by rank; 0 = all (64) */
    int greedy_thresholds; /* per feature, the shared-set search runs on this many candidates: those
                             whose best single-class split gains most; 0 = all (8) */
    double validation;    /* share of each class held out for early stopping and the
                             calibration, 0 = neither (0.2) */
    int patience;         /* stop when the held-out loss has not improved for this many rounds (60) */
    double shrinkage;     /* each stump's output is scaled by this (0.5) */
    int balance;          /* 1: initial weights equalise the classes (1) */
    int refit;            /* 1: after early stopping, retrain on everything for the best
                             round count (1) */
    uint64_t seed;        /* the held-out split */
    /* The joint novelty test (classify/novelty.c, docs/classify.md). */
    double novelty_quantile; /* its threshold: this quantile of the cross-validated
                                training trees' scores ... (0.995) */
    double novelty_factor;   /* ... times this factor (2) */
} sy_jb_options;

sy_jb_options sy_jb_options_default(void);
sy_code sy_jb_options_check(const sy_jb_options *o, sy_error *err);

/* One shared regression stump per round: for the classes in `mask`,
 * h = a if x[feature] > threshold else b; for every other class c, h = k[c]. */
typedef struct {
    size_t n_classes;
    char **classes;         /* species names; the ids are bound when the model is used */
    size_t n_features;
    uint32_t features_version; /* SY_FEATURES_VERSION of the trainer (0: foreign features) */
    size_t n_rounds;
    int32_t *feature;       /* n_rounds */
    float *threshold, *a, *b;
    uint64_t *mask;
    float *k;               /* n_rounds x n_classes */
    double kappa;           /* calibration: p_c = exp(kappa H_c) / sum exp(kappa H) */
    /* The joint novelty test (classify/novelty.c): features standardised by
     * the training median and robust spread, then per class a diagonal
     * Mahalanobis distance; score = min over classes. */
    float *nov_center, *nov_scale; /* n_features */
    float *nov_mean, *nov_sd;      /* n_classes x n_features, standardised units */
    double nov_cap;                /* cap of one feature's squared deviation */
    double nov_trim;               /* share of the largest deviations left out */
    double nov_threshold;          /* scores above it are novel */
    /* The planar-surface test (classify/novelty.c): the planarity features
     * (eigen_P_*) of the trainer's features, their training range and robust
     * spread; a tree beyond the range by more than planar_threshold spreads
     * is no tree (walls and roofs). n_planar 0: no such test. */
    size_t n_planar;
    int32_t *planar_feature;
    float *planar_lo, *planar_hi, *planar_s;
    double planar_threshold;
    /* What training measured, kept in the file for `sylva classify --info`. */
    size_t train_samples;
    double holdout_accuracy; /* NaN without a held-out set */
} sy_jb_model;

typedef struct {
    size_t rounds_run, rounds_kept;
    double holdout_accuracy, holdout_loss; /* NaN without validation */
    double train_accuracy;
    double kappa;
    double seconds;
} sy_jb_report;

/* Trains on X (n x d, row-major), labels y[i] in [0, n_classes). Names are
 * copied (NULL: "class<i>"). features_version is stored in the model. Every
 * class needs a sample. Deterministic given o->seed; threads over features
 * (sy_threads()), and the result does not depend on the thread count.
 * report may be NULL. */
sy_code sy_jb_train(const float *X, size_t n, size_t d, const int *y, size_t n_classes,
                    const char *const *names, uint32_t features_version, const sy_jb_options *o,
                    sy_jb_model *out, sy_jb_report *report, sy_error *err);
void sy_jb_model_free(sy_jb_model *m);

/* Additive scores H (n_classes) and the calibrated probabilities (n_classes,
 * summing to 1) for one feature vector of m->n_features floats. */
void sy_jb_scores(const sy_jb_model *m, const float *x, double *H);
void sy_jb_predict(const sy_jb_model *m, const float *x, double *prob);
/* The joint novelty score of x: min over the classes of the trimmed mean of
 * the capped squared standardised deviations from the class (a diagonal
 * Mahalanobis distance per feature, averaged). sy_jb_novelty divides it by
 * the calibrated threshold: above 1, x lies farther from every species than
 * the held-out training trees do (a house, not a tree). 0 for a model
 * without the test. */
double sy_jb_novelty_score(const sy_jb_model *m, const float *x);
/* The planar-surface test's score of x: how far, in robust spreads, its
 * planarity lies beyond the training trees' range (0 inside it). */
double sy_jb_planar_score(const sy_jb_model *m, const float *x);
/* Room for n planar-test features in m (n_planar = n; any earlier ones go). */
sy_code sy_jb_planar_alloc(sy_jb_model *m, size_t n, sy_error *err);
/* The larger of the two tests' scores over their thresholds: above 1, x is
 * not a tree like the training trees. 0 for a model without either test. */
double sy_jb_novelty(const sy_jb_model *m, const float *x);
/* Fits the test's statistics on the samples idx[0..n_idx) of X (n x d) into m
 * (m->n_features, m->n_classes set; allocates the arrays). */
sy_code sy_jb_novelty_fit(sy_jb_model *m, const float *X, const int *y, const uint32_t *idx, size_t n_idx,
                          sy_error *err);
/* Fits on all n samples and calibrates both thresholds: `folds`-fold scores
 * of every sample against statistics fitted without its fold (stratified by
 * seed), threshold = factor x the quantile q of those scores. The planar test
 * is made when m->features_version is this build's (the feature names are
 * known). */
sy_code sy_jb_novelty_train(sy_jb_model *m, const float *X, size_t n, const int *y, int folds, double q,
                            double factor, uint64_t seed, sy_error *err);

/* Text model file (docs/classify.md): "sylva-jointboost 1" ... "end <fnv64>".
 * Written atomically; a damaged, truncated or foreign file fails to load with
 * a one-line SY_EINPUT naming the file and the problem. */
sy_code sy_jb_save(const sy_jb_model *m, const char *path, sy_error *err);
sy_code sy_jb_load(const char *path, sy_jb_model *m, sy_error *err);
sy_code sy_jb_parse(const char *name, const char *text, size_t len, sy_jb_model *m, sy_error *err);
/* The file's bytes (malloc'd, NUL-terminated). */
sy_code sy_jb_serialize(const sy_jb_model *m, char **text, size_t *len, sy_error *err);

/* ------------------------------------------------------- decision + voting */

typedef struct {
    double ratio;       /* confident iff h1 > ratio * h2 (1.5, Pirk 2013) */
    double radius;      /* voting radius, metres (25) */
    int voting;         /* 1: unconfident trees with positions take their neighbours' vote (1) */
    double novelty_max; /* sy_jb_novelty above this (1: the model's calibrated
                           threshold): unknown, never confident, never voted (1) */
} sy_vote_options;

sy_vote_options sy_vote_options_default(void);
sy_code sy_vote_options_check(const sy_vote_options *o, sy_error *err);

typedef struct {
    int best;           /* argmax of the probabilities */
    int species;        /* the decision: a class index, or -1 = unknown */
    int confident;      /* h1 > ratio * h2 and not novel */
    int voted;          /* the decision came from the neighbours' vote */
    int novel;          /* outside the training range: never confident */
    int votes;          /* confident neighbours within the radius that voted for `species` */
    double h1, h2;
} sy_tree_decision;

/* Decides every tree of a set: prob is n x n_classes, novelty n values (may be
 * NULL: none novel), xy n world positions (2n, may be NULL: no voting).
 * A confident tree keeps its argmax; an unconfident one takes, among the
 * argmax species of the confident trees within the radius, the one its own
 * probability ranks highest (ties: more votes, then lower index); with no
 * such neighbour it is unknown (-1). */
sy_code sy_vote(size_t n, size_t n_classes, const double *prob, const double *novelty, const double *xy,
                const sy_vote_options *o, sy_tree_decision *out, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
