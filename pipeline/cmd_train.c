/* sylva train SCANS... -o model.sjb: species classifier training. Each scan
 * (one tree) becomes a feature vector (classify/); labels come from a CSV
 * (file -> species name) or from the speciesID extra bytes of simulated scans.
 * Prints the stratified k-fold cross-validated accuracy, then trains the
 * model on every tree and writes it atomically. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "classify/classify.h"
#include "pipeline/commands.h"
#include "pipeline/tree_species.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/core/rng.h"
#include "stages/eval/eval.h"

typedef struct {
    const char **paths;
    float *x;
    sy_scan_features_result *res;
    sy_error *errs;
    sy_code *rcs;
    sy_features_options fo;
    size_t done;
    pthread_mutex_t lock;
    sy_progress *bar;
} feat_job;

static void feat_chunk(void *vctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    feat_job *j = vctx;
    size_t d = sy_feature_count();
    for (size_t i = begin; i < end; i++) {
        j->rcs[i] = sy_scan_features(j->paths[i], &j->fo, j->x + i * d, &j->res[i], &j->errs[i]);
        pthread_mutex_lock(&j->lock);
        sy_progress_update(j->bar, ++j->done);
        pthread_mutex_unlock(&j->lock);
    }
}

static const char *base_name(const char *p)
{
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

static const char *label_for(const sy_label_table *lt, const char *path)
{
    const char *b = base_name(path);
    size_t stem = strcspn(b, ".");
    for (size_t k = 0; k < lt->n; k++)
        if (!strcmp(lt->id[k], path) || !strcmp(lt->id[k], b) || (strlen(lt->id[k]) == stem && !strncmp(lt->id[k], b, stem)))
            return lt->label[k];
    return NULL;
}

/* Features of every scan, in argument order; a failing scan stops training. */
static sy_code scan_all(const char **paths, int n, const sy_label_table *lt, const char *labels_path, int skip_bad,
                        sy_feature_table *t, const sy_cli *cli, sy_error *err)
{
    size_t d = sy_feature_count();
    feat_job j;
    memset(&j, 0, sizeof j);
    j.paths = paths;
    j.fo = sy_features_options_default();
    j.x = sy_calloc((size_t)n * d, sizeof *j.x, err, "train");
    j.res = sy_calloc((size_t)n, sizeof *j.res, err, "train");
    j.errs = sy_calloc((size_t)n, sizeof *j.errs, err, "train");
    j.rcs = sy_calloc((size_t)n, sizeof *j.rcs, err, "train");
    sy_code rc = SY_OK;
    if (!j.x || !j.res || !j.errs || !j.rcs) {
        rc = err->code;
        goto done;
    }
    pthread_mutex_init(&j.lock, NULL);
    sy_progress bar;
    sy_progress_begin(&bar, "features", (size_t)n);
    j.bar = &bar;
    /* One bar for the set: the stages' own bars per scan stay silent. */
    int quiet = sy_progress_quiet();
    sy_progress_set_quiet(1);
    sy_parallel_for((size_t)n, 1, feat_chunk, &j);
    sy_progress_set_quiet(quiet);
    sy_progress_end(&bar);
    pthread_mutex_destroy(&j.lock);
    for (int i = 0; i < n && !rc; i++) {
        if (j.rcs[i] == SY_EINPUT && skip_bad) {
            if (!cli->quiet) fprintf(stderr, "sylva train: skipped %s\n", j.errs[i].msg);
            continue;
        }
        if (j.rcs[i]) {
            *err = j.errs[i];
            rc = j.rcs[i];
            break;
        }
        const char *label = j.res[i].label;
        if (lt) {
            label = label_for(lt, paths[i]);
            if (!label) rc = sy_fail(err, SY_EINPUT, "%s: no line for this file in %s", paths[i], labels_path);
        } else if (!label[0])
            rc = sy_fail(err, SY_EINPUT, "%s: no speciesID attribute to take the label from (use --labels)", paths[i]);
        if (!rc)
            rc = sy_feature_table_add(t, paths[i], label, j.res[i].info.spacing, j.res[i].info.points_in, j.x + (size_t)i * d,
                                      d, err);
    }
done:
    free(j.x), free(j.res), free(j.errs), free(j.rcs);
    return rc;
}


/* Stratified k-fold cross-validation: per class a seeded shuffle dealt round-robin to the folds. */
static sy_code cross_validate(const sy_feature_table *t, const int *y, size_t C, const char *const *names,
                              const sy_jb_options *jo, int k, uint64_t seed, size_t *correct, size_t *per_total,
                              size_t *per_correct, sy_error *err)
{
    size_t n = t->n, d = t->d;
    int *fold = sy_calloc(n, sizeof *fold, err, "train");
    float *X = sy_calloc(n * d, sizeof *X, err, "train");
    int *yy = sy_calloc(n, sizeof *yy, err, "train");
    size_t *idx = sy_calloc(n, sizeof *idx, err, "train");
    sy_code rc = SY_OK;
    if (!fold || !X || !yy || !idx) {
        rc = err->code;
        goto done;
    }
    uint64_t s = seed ^ 0x43726f7373ull;
    for (size_t c = 0; c < C; c++) {
        size_t m = 0;
        for (size_t i = 0; i < n; i++)
            if (y[i] == (int)c) idx[m++] = i;
        for (size_t i = m; i > 1; i--) {
            size_t r = (size_t)(sy_splitmix64(&s) % i), tmp = idx[i - 1];
            idx[i - 1] = idx[r];
            idx[r] = tmp;
        }
        for (size_t i = 0; i < m; i++) fold[idx[i]] = (int)(i % (size_t)k);
    }
    *correct = 0;
    for (size_t c = 0; c < C; c++) per_total[c] = per_correct[c] = 0;
    sy_progress bar;
    sy_progress_begin(&bar, "cross-validation", (size_t)k);
    for (int f = 0; f < k && !rc; f++) {
        size_t m = 0;
        for (size_t i = 0; i < n; i++)
            if (fold[i] != f) memcpy(X + m * d, t->x + i * d, d * sizeof *X), yy[m++] = y[i];
        /* A fold may leave a rare class without training trees: skip it. */
        size_t seen[SY_JB_MAX_CLASSES] = {0};
        for (size_t i = 0; i < m; i++) seen[yy[i]]++;
        int all = 1;
        for (size_t c = 0; c < C; c++) all &= seen[c] > 0;
        if (!all) continue;
        sy_jb_model mdl;
        if ((rc = sy_jb_train(X, m, d, yy, C, names, SY_FEATURES_VERSION, jo, &mdl, NULL, err))) break;
        double p[SY_JB_MAX_CLASSES];
        for (size_t i = 0; i < n; i++) {
            if (fold[i] != f) continue;
            sy_jb_predict(&mdl, t->x + i * d, p);
            size_t b = 0;
            for (size_t c = 1; c < C; c++)
                if (p[c] > p[b]) b = c;
            per_total[y[i]]++;
            if ((int)b == y[i]) (*correct)++, per_correct[y[i]]++;
        }
        sy_jb_model_free(&mdl);
        sy_progress_update(&bar, (size_t)f + 1);
    }
    sy_progress_end(&bar);
done:
    free(fold), free(X), free(yy), free(idx);
    return rc;
}

int cmd_train(int argc, char **argv, sy_cli *cli)
{
    const char *out_path = NULL, *labels_path = NULL, *features_in = NULL, *features_out = NULL;
    sy_jb_options jo = sy_jb_options_default();
    int rounds = jo.rounds, thresholds = jo.max_thresholds, patience = jo.patience, folds = 5, skip_bad = 0;
    double validation = jo.validation, shrinkage = jo.shrinkage;
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &out_path, "MODEL.sjb", "model file to write"},
        {"--labels", OPT_STRING, &labels_path, "CSV", "file,species lines (default: the scans' speciesID extra bytes)"},
        {"--features-in", OPT_STRING, &features_in, "TSV", "train on a feature table written by --features-out"},
        {"--features-out", OPT_STRING, &features_out, "TSV", "also write the trees' features (file, label, features)"},
        {"--skip-bad", OPT_FLAG, &skip_bad, NULL, "skip scans too small or odd for a tree (each one reported), instead of failing"},
        {"--folds", OPT_INT, &folds, "K", "cross-validation folds, 0 = none (default 5)"},
        {"--rounds", OPT_INT, &rounds, "N", "most boosting rounds (default 600)"},
        {"--thresholds", OPT_INT, &thresholds, "N", "candidate thresholds per feature, 0 = every distinct value (default 64)"},
        {"--validation", OPT_DOUBLE, &validation, "F", "share held out for early stopping and calibration (default 0.2)"},
        {"--patience", OPT_INT, &patience, "N", "early stopping patience in rounds (default 60)"},
        {"--shrinkage", OPT_DOUBLE, &shrinkage, "F", "stump output scale (default 0.5)"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "train", "[--labels labels.csv] SCANS... -o MODEL.sjb",
        "Train the JointBoost species classifier on labelled tree scans (one tree per file).",
        "Labels: --labels CSV (id,species; the id is the path as given, its file name, or the\n"
        "file name without extension), else the majority speciesID of the points (`sylva scan`).\n"
        "Species are stored by name. The shipped model is rebuilt by species/train-classifier.sh.\n"
        "See docs/classify.md.",
        opts, 0, -1};
    const char **pos;
    int n, rc = sy_cli_parse_all(&spec, argc, argv, cli, &pos, &n);
    if (rc) return rc < 0 ? 0 : rc;
    sy_cli_apply_settings(cli);
    sy_error err = {0};
    sy_feature_table t = {0};
    sy_label_table lt = {0};
    int *y = NULL;
    if (!out_path && !features_out) {
        fprintf(stderr, "sylva train: -o MODEL.sjb (or --features-out) is required\n");
        rc = SY_EUSAGE;
        goto done;
    }
    if (!features_in && n == 0) {
        fprintf(stderr, "sylva train: no scans (give SCANS... or --features-in)\n");
        rc = SY_EUSAGE;
        goto done;
    }
    if (folds < 0 || folds == 1 || folds > 100) {
        fprintf(stderr, "sylva train: --folds must be 0 or 2..100\n");
        rc = SY_EUSAGE;
        goto done;
    }
    jo.rounds = rounds, jo.max_thresholds = thresholds, jo.patience = patience;
    jo.validation = validation, jo.shrinkage = shrinkage, jo.seed = cli->seed;
    if ((rc = sy_jb_options_check(&jo, &err))) goto report;
    if ((out_path && (rc = sy_check_writable(out_path, &err))) ||
        (features_out && (rc = sy_check_writable(features_out, &err))))
        goto report;
    if (labels_path && (rc = sy_label_table_read_csv(labels_path, &lt, &err))) goto report;
    if (features_in && (rc = sy_feature_table_read(features_in, &t, &err))) goto report;
    if (n && (rc = scan_all(pos, n, labels_path ? &lt : NULL, labels_path, skip_bad, &t, cli, &err))) goto report;
    if (features_out && (rc = sy_feature_table_write(&t, features_out, &err))) goto report;
    if (!out_path) goto summary;
    const char *names[SY_JB_MAX_CLASSES];
    size_t C;
    y = calloc(t.n ? t.n : 1, sizeof *y);
    if (!y) {
        rc = sy_fail(&err, SY_EINTERNAL, "out of memory");
        goto report;
    }
    if ((rc = sy_feature_table_classes(&t, names, &C, y, &err))) goto report;
    if (C < 2) {
        rc = sy_fail(&err, SY_EINPUT, "%zu trees of %zu species: training needs at least two species", t.n, C);
        goto report;
    }
    size_t per_total[SY_JB_MAX_CLASSES] = {0}, per_correct[SY_JB_MAX_CLASSES] = {0}, correct = 0, cv_total = 0;
    if (folds >= 2) {
        if ((rc = cross_validate(&t, y, C, names, &jo, folds, cli->seed, &correct, per_total, per_correct, &err)))
            goto report;
        for (size_t c = 0; c < C; c++) cv_total += per_total[c];
    }
    sy_jb_model m;
    sy_jb_report jr;
    if ((rc = sy_jb_train(t.x, t.n, t.d, y, C, names, SY_FEATURES_VERSION, &jo, &m, &jr, &err))) goto report;
    rc = sy_jb_save(&m, out_path, &err);
    sy_jb_model_free(&m);
    if (rc) goto report;
    double cv_acc = cv_total ? (double)correct / (double)cv_total : NAN;
    if (cli->json) {
        sy_json j;
        sy_json_begin(&j, stdout, 0);
        sy_json_object(&j, NULL);
        sy_json_string(&j, "model", out_path);
        sy_json_int(&j, "trees", (long long)t.n);
        sy_json_int(&j, "features", (long long)t.d);
        sy_json_int(&j, "folds", folds);
        sy_json_number(&j, "cv_accuracy", cv_acc);
        sy_json_object(&j, "species");
        for (size_t c = 0; c < C; c++) {
            sy_json_object(&j, names[c]);
            size_t nc = 0;
            for (size_t i = 0; i < t.n; i++) nc += y[i] == (int)c;
            sy_json_int(&j, "trees", (long long)nc);
            sy_json_number(&j, "cv_recall", per_total[c] ? (double)per_correct[c] / (double)per_total[c] : NAN);
            sy_json_end(&j);
        }
        sy_json_end(&j);
        sy_json_int(&j, "rounds", (long long)jr.rounds_kept);
        sy_json_number(&j, "holdout_accuracy", jr.holdout_accuracy);
        sy_json_number(&j, "train_accuracy", jr.train_accuracy);
        sy_json_number(&j, "kappa", jr.kappa);
        sy_json_number(&j, "train_seconds", jr.seconds);
        sy_json_end(&j);
        sy_json_finish(&j);
    } else if (!cli->quiet) {
        printf("trees %zu, species %zu, features %zu\n", t.n, C, t.d);
        for (size_t c = 0; c < C; c++) {
            size_t nc = 0;
            for (size_t i = 0; i < t.n; i++) nc += y[i] == (int)c;
            if (per_total[c])
                printf("  %-20s %4zu trees  cv recall %5.1f%%\n", names[c], nc, 100.0 * per_correct[c] / per_total[c]);
            else printf("  %-20s %4zu trees\n", names[c], nc);
        }
        if (cv_total) printf("cross-validated accuracy (%d folds): %.1f%% (%zu of %zu)\n", folds, 100 * cv_acc, correct, cv_total);
        printf("model: %zu rounds (held-out accuracy %.1f%%, kappa %.3f), %.1f s -> %s\n", jr.rounds_kept,
               100 * jr.holdout_accuracy, jr.kappa, jr.seconds, out_path);
    }
summary:
    if (!out_path && !cli->quiet && !cli->json) printf("wrote the features of %zu trees to %s\n", t.n, features_out);
report:
    if (rc) rc = sy_cli_report(&err);
done:
    free(y);
    sy_feature_table_free(&t);
    sy_label_table_free(&lt);
    free(pos);
    return rc;
}
