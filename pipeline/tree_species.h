/* What `train`, `classify` and `run` share around the classify stage: a scan
 * file to its tree features (ingest, the classification preprocessing,
 * features), the label a simulated scan carries, the feature table file, and
 * where the shipped default model lives. */
#ifndef SYLVA_TREE_SPECIES_H
#define SYLVA_TREE_SPECIES_H

#include <stddef.h>

#include "classify/classify.h"
#include "species/species.h"
#include "stages/core/cloud.h"
#include "stages/core/json.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The shipped default model, classifier.sjb in the species library folder
 * (species/library.h locates it; built by species/train-classifier.sh). */
sy_code sy_default_model_path(char *path, size_t size, sy_error *err);

typedef struct {
    char label[64];       /* species name from the speciesID extra bytes ("" when none) */
    int georeferenced;    /* the file's coordinates place the tree (LAS): positions for voting */
    size_t points_clean;  /* after the classification preprocessing */
    sy_features_info info;
} sy_scan_features_result;

/* Preprocessing for classification: up axis, a voxel thinning (voxel metres:
 * SY_CLASSIFY_VOXEL, as the training scans had), ground classified and
 * removed; no outlier removal (the features are quantile-based voxel
 * statistics) and no normals (the features fit their own). */
#define SY_CLASSIFY_VOXEL 0.02
sy_code sy_classify_preprocess(sy_cloud *c, const char *path, double voxel, sy_error *err);

/* Reads path, preprocesses it and computes the features into f
 * (sy_feature_count() floats). */
sy_code sy_scan_features(const char *path, const sy_features_options *fo, float *f, sy_scan_features_result *r,
                         sy_error *err);

/* The most frequent non-negative speciesID of the cloud (the simulator's
 * per-point label), or -1 when it has none. */
int sy_cloud_majority_species(const sy_cloud *c);

/* Name of the library species with id idx (the scanner's speciesID), or NULL
 * when there is none; buf holds it. */
const char *sy_species_name_at(int idx, char *buf, size_t size);

/* Feature table: a TSV with a header "file<TAB>label<TAB>spacing<TAB>points<TAB>
 * <feature names...>" and one row per tree, so a model can be retrained or
 * benchmarked without recomputing features. */
typedef struct {
    size_t n, d, cap;
    char **file, **label;
    double *spacing;
    size_t *points;
    float *x; /* n x d */
} sy_feature_table;

sy_code sy_feature_table_add(sy_feature_table *t, const char *file, const char *label, double spacing, size_t points,
                             const float *x, size_t d, sy_error *err);
sy_code sy_feature_table_write(const sy_feature_table *t, const char *path, sy_error *err);
sy_code sy_feature_table_read(const char *path, sy_feature_table *t, sy_error *err);
void sy_feature_table_free(sy_feature_table *t);

/* Labels to class indices: the distinct labels sorted by name become the
 * classes (names[] pointers into t, *n_classes of them); y gets n indices. */
sy_code sy_feature_table_classes(const sy_feature_table *t, const char **names, size_t *n_classes, int *y,
                                 sy_error *err);

/* One tree's species from its cleaned cloud: the model (NULL: the default)
 * is loaded, the features computed and the single-tree decision taken (no
 * neighbours, so no voting). name is a library species or "unknown". */
typedef struct {
    sy_species species; /* the answer in library ids: id -1 when unknown; owned (sy_species_guess_free) */
    char name[64];
    char best[64];     /* the argmax class, even when unknown */
    double probability; /* of best */
    double novelty;
    int confident, novel;
    size_t too_few;     /* the cloud's points when fewer than SY_FEATURES_MIN_POINTS: not classified, unknown */
    char ruled_out[64]; /* the classifier's answer the scan's structure ruled out, "" when none (run_tree.c) */
    double crown_base_scan, crown_base_species; /* ... the crown bases over the height that ruled it out */
    double taken_probability; /* ... and the probability of the species taken in its place (0: none) */
    double seconds;
} sy_species_guess;

/* The rule that overrode the classifier (ruled_out and the crown bases
 * behind it, and the taken species' probability) as members of the open
 * JSON object; nothing when none did. */
void sy_species_guess_rule_json(sy_json *j, const sy_species_guess *g);

sy_code sy_classify_cloud(const sy_cloud *tree, const char *model_path, sy_species_guess *out, sy_error *err);
void sy_species_guess_free(sy_species_guess *g);

#ifdef __cplusplus
}
#endif

#endif
