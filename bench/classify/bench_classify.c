/* bench_classify: the species classifier measured (docs/classify.md).
 *
 *   bench_classify [--train TRAIN.tsv] [--unseen UNSEEN.tsv] [--reps N] [--rounds R] [--xgb-reps N] [--model M] [--png FILE]
 *
 * TRAIN.tsv / UNSEEN.tsv are the feature tables species/train-classifier.sh
 * --unseen writes (build/classifier-data/). Prints:
 *   1. Pirk 2013's protocol: per species half train / half test, N random
 *      repetitions (100), mean accuracy (mean of the confusion diagonal, as the
 *      thesis reports it) and the pooled accuracy, the row-normalised confusion
 *      matrix (text, and a PNG), accuracy per scanner type and density band,
 *      expected calibration error; spatial voting on rows-of-one-species and on
 *      random mixed layouts;
 *   2. the same splits with xgboost (boosted trees, its C API) as a baseline;
 *   3. generalisation: trained on half the seeds with the seen settings, tested
 *      on the other seeds (seen settings) and on the unseen settings;
 *   4. the shipped model on the real scans in ../shared/data/real;
 *   5. speed: features + prediction of a 100k-point tree, CPU seconds. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <xgboost/c_api.h>

#include "classify/classify.h"
#include "pipeline/tree_species.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/eval/eval.h"
#include "stages/ingest/ingest.h"

#ifndef SYLVA_DATA_DIR
#define SYLVA_DATA_DIR SYLVA_SPECIES_DIR "/../../shared/data"
#endif

static double cpu_seconds(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + (double)ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6;
}

static uint64_t rng_state;
static uint64_t rnd(void)
{
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* Scanner kind and setting from "species__setting__sSEED.las". */
static int kind_of(const char *file, char *setting, size_t size, int *seed)
{
    const char *b = strrchr(file, '/');
    b = b ? b + 1 : file;
    const char *p = strstr(b, "__");
    setting[0] = 0;
    *seed = -1;
    if (!p) return -1;
    const char *q = strstr(p + 2, "__");
    if (!q) return -1;
    snprintf(setting, size, "%.*s", (int)(q - p - 2), p + 2);
    *seed = atoi(q + 3);
    if (!strncmp(setting, "tls", 3)) return 0;
    if (!strncmp(setting, "mls", 3)) return 1;
    if (!strncmp(setting, "als", 3)) return 2;
    return -1;
}
static const char *const kind_names[3] = {"terrestrial", "mobile", "airborne"};
#define N_BANDS 4
static const double band_edges[N_BANDS - 1] = {0.02, 0.05, 0.15};
static const char *const band_names[N_BANDS] = {"spacing < 2 cm", "2-5 cm", "5-15 cm", ">= 15 cm"};
static int band_of(double spacing)
{
    int b = 0;
    while (b < N_BANDS - 1 && spacing >= band_edges[b]) b++;
    return b;
}

typedef struct {
    size_t n, d, C;
    const float *x;
    const int *y;
    const char **names;
} dataset;

/* Trains on idx_tr, predicts idx_te: probabilities into prob (n_te x C). */
typedef int (*method_fn)(const dataset *ds, const size_t *tr, size_t n_tr, const size_t *te, size_t n_te, double *prob,
                         uint64_t seed);

static int gather(const dataset *ds, const size_t *idx, size_t m, float *X, int *y)
{
    for (size_t k = 0; k < m; k++) {
        memcpy(X + k * ds->d, ds->x + idx[k] * ds->d, ds->d * sizeof *X);
        if (y) y[k] = ds->y[idx[k]];
    }
    return 0;
}

/* 0: the trainer's default (early stopping within 600 rounds). */
static int jb_max_rounds;
/* When set, jb_method writes each test tree's sy_jb_novelty here (n_te). */
static double *jb_novelty_out;

static int jb_method(const dataset *ds, const size_t *tr, size_t n_tr, const size_t *te, size_t n_te, double *prob,
                     uint64_t seed)
{
    float *X = malloc(n_tr * ds->d * sizeof *X);
    int *y = malloc(n_tr * sizeof *y);
    if (!X || !y) return free(X), free(y), 1;
    gather(ds, tr, n_tr, X, y);
    sy_jb_options o = sy_jb_options_default();
    o.seed = seed;
    if (jb_max_rounds > 0) o.rounds = jb_max_rounds;
    sy_jb_model m;
    sy_error err = {0};
    if (sy_jb_train(X, n_tr, ds->d, y, ds->C, ds->names, SY_FEATURES_VERSION, &o, &m, NULL, &err)) {
        fprintf(stderr, "bench_classify: %s\n", err.msg);
        free(X), free(y);
        return 1;
    }
    for (size_t k = 0; k < n_te; k++) {
        sy_jb_predict(&m, ds->x + te[k] * ds->d, prob + k * ds->C);
        if (jb_novelty_out) jb_novelty_out[k] = sy_jb_novelty(&m, ds->x + te[k] * ds->d);
    }
    sy_jb_model_free(&m);
    free(X), free(y);
    return 0;
}

#define XGB_OK(call)                                                                                                   \
    do {                                                                                                               \
        if ((call) != 0) {                                                                                             \
            fprintf(stderr, "bench_classify: xgboost: %s\n", XGBGetLastError());                                      \
            goto fail;                                                                                                 \
        }                                                                                                              \
    } while (0)

/* xgboost multi:softprob: the histogram tree method (64 bins), depth-3 trees,
 * XGB_ROUNDS rounds of eta 0.2, subsampling off, one thread: a common
 * small-data setting, deterministic. The exact method with 200 rounds of eta
 * 0.1 used over 60 CPU s per repetition (13 classes x 286 features). */
#define XGB_ROUNDS 100
static int xgb_method(const dataset *ds, const size_t *tr, size_t n_tr, const size_t *te, size_t n_te, double *prob,
                      uint64_t seed)
{
    float *X = malloc(n_tr * ds->d * sizeof *X), *Xt = malloc(n_te * ds->d * sizeof *Xt);
    float *lab = malloc(n_tr * sizeof *lab);
    int *y = malloc(n_tr * sizeof *y);
    DMatrixHandle dtr = NULL, dte = NULL;
    BoosterHandle bst = NULL;
    int rc = 1;
    if (!X || !Xt || !lab || !y) goto fail;
    gather(ds, tr, n_tr, X, y);
    gather(ds, te, n_te, Xt, NULL);
    for (size_t k = 0; k < n_tr; k++) lab[k] = (float)y[k];
    XGB_OK(XGDMatrixCreateFromMat(X, n_tr, ds->d, NAN, &dtr));
    XGB_OK(XGDMatrixSetFloatInfo(dtr, "label", lab, n_tr));
    XGB_OK(XGDMatrixCreateFromMat(Xt, n_te, ds->d, NAN, &dte));
    XGB_OK(XGBoosterCreate(&dtr, 1, &bst));
    char buf[32];
    snprintf(buf, sizeof buf, "%zu", ds->C);
    XGB_OK(XGBoosterSetParam(bst, "objective", "multi:softprob"));
    XGB_OK(XGBoosterSetParam(bst, "num_class", buf));
    XGB_OK(XGBoosterSetParam(bst, "max_depth", "3"));
    XGB_OK(XGBoosterSetParam(bst, "eta", "0.2"));
    XGB_OK(XGBoosterSetParam(bst, "tree_method", "hist"));
    XGB_OK(XGBoosterSetParam(bst, "max_bin", "64"));
    XGB_OK(XGBoosterSetParam(bst, "nthread", "1"));
    XGB_OK(XGBoosterSetParam(bst, "verbosity", "0"));
    snprintf(buf, sizeof buf, "%llu", (unsigned long long)(seed % 1000000));
    XGB_OK(XGBoosterSetParam(bst, "seed", buf));
    for (int it = 0; it < XGB_ROUNDS; it++) XGB_OK(XGBoosterUpdateOneIter(bst, it, dtr));
    bst_ulong len;
    const float *out;
    XGB_OK(XGBoosterPredict(bst, dte, 0, 0, 0, &len, &out));
    if (len != n_te * ds->C) goto fail;
    for (size_t k = 0; k < len; k++) prob[k] = out[k];
    rc = 0;
fail:
    if (bst) XGBoosterFree(bst);
    if (dtr) XGDMatrixFree(dtr);
    if (dte) XGDMatrixFree(dte);
    free(X), free(Xt), free(lab), free(y);
    return rc;
}

static size_t argmax(const double *p, size_t C)
{
    size_t b = 0;
    for (size_t c = 1; c < C; c++)
        if (p[c] > p[b]) b = c;
    return b;
}

typedef struct {
    size_t *conf;              /* C x C counts */
    double diag_mean_sum;      /* sum over reps of the mean per-class recall */
    size_t reps;
    size_t kind_n[3], kind_ok[3], band_n[N_BANDS], band_ok[N_BANDS];
    size_t n, ok;
    double ece_conf[10], ece_acc[10];
    size_t ece_n[10];
    size_t vote_rows_ok, vote_mixed_ok, vote_n, confident_n, confident_ok;
    size_t novel_n, novel_of; /* test trees the novelty test called unknown, of those scored */
    double novelty_max;
    double seconds;
} tally;

static void tally_add(tally *t, const dataset *ds, const size_t *te, size_t n_te, const double *prob, const int *kind,
                      const int *band)
{
    size_t C = ds->C;
    size_t per_n[SY_JB_MAX_CLASSES] = {0}, per_ok[SY_JB_MAX_CLASSES] = {0};
    for (size_t k = 0; k < n_te; k++) {
        size_t i = te[k], b = argmax(prob + k * C, C);
        int ok = (int)b == ds->y[i];
        t->conf[(size_t)ds->y[i] * C + b]++;
        per_n[ds->y[i]]++, per_ok[ds->y[i]] += ok;
        t->n++, t->ok += ok;
        if (kind[i] >= 0) t->kind_n[kind[i]]++, t->kind_ok[kind[i]] += ok;
        t->band_n[band[i]]++, t->band_ok[band[i]] += ok;
        double pmax = prob[k * C + b];
        int eb = (int)(pmax * 10);
        eb = eb > 9 ? 9 : eb < 0 ? 0 : eb;
        t->ece_n[eb]++, t->ece_conf[eb] += pmax, t->ece_acc[eb] += ok;
    }
    double s = 0;
    size_t cls = 0;
    for (size_t c = 0; c < C; c++)
        if (per_n[c]) s += (double)per_ok[c] / (double)per_n[c], cls++;
    t->diag_mean_sum += cls ? s / (double)cls : 0;
    t->reps++;
}

static double ece_of(const tally *t)
{
    double e = 0;
    for (int b = 0; b < 10; b++)
        if (t->ece_n[b]) e += fabs(t->ece_acc[b] - t->ece_conf[b]) / (double)t->n;
    return e;
}

/* Voting on two layouts of the test trees: rows (same species side by side,
 * 8 m apart, species rows 60 m apart) and mixed (random positions in a square
 * of 8 m per tree). Counts correct decisions (unknown = wrong). */
static void voting_add(tally *t, const dataset *ds, const size_t *te, size_t n_te, const double *prob)
{
    size_t C = ds->C;
    double *xy = malloc(2 * n_te * sizeof *xy);
    sy_tree_decision *d = malloc(n_te * sizeof *d);
    if (!xy || !d) {
        free(xy), free(d);
        return;
    }
    sy_vote_options vo = sy_vote_options_default();
    sy_error err;
    for (int layout = 0; layout < 2; layout++) {
        size_t col[SY_JB_MAX_CLASSES] = {0};
        double side = 8.0 * sqrt((double)n_te);
        for (size_t k = 0; k < n_te; k++) {
            int c = ds->y[te[k]];
            if (layout == 0) xy[2 * k] = 8.0 * (double)col[c]++, xy[2 * k + 1] = 60.0 * c;
            else xy[2 * k] = side * (double)(rnd() % 100000) / 1e5, xy[2 * k + 1] = side * (double)(rnd() % 100000) / 1e5;
        }
        if (sy_vote(n_te, C, prob, NULL, xy, &vo, d, &err)) continue;
        for (size_t k = 0; k < n_te; k++) {
            int ok = d[k].species == ds->y[te[k]];
            if (layout == 0) t->vote_rows_ok += ok;
            else t->vote_mixed_ok += ok;
            if (layout == 0) {
                t->vote_n++;
                if (d[k].confident) t->confident_n++, t->confident_ok += ok;
            }
        }
    }
    free(xy), free(d);
}

static void print_tally(const char *title, const tally *t, const dataset *ds, int with_matrix)
{
    size_t C = ds->C;
    printf("\n%s: %zu repetitions, %.1f CPU s\n", title, t->reps, t->seconds);
    printf("  mean accuracy (mean of the confusion diagonal) %.2f%%   pooled %.2f%% of %zu test trees\n",
           100 * t->diag_mean_sum / (double)t->reps, 100.0 * (double)t->ok / (double)t->n, t->n);
    printf("  expected calibration error (10 bins of the top probability) %.3f\n", ece_of(t));
    for (int k = 0; k < 3; k++)
        if (t->kind_n[k]) printf("  %-12s %6.2f%% (%zu)\n", kind_names[k], 100.0 * t->kind_ok[k] / t->kind_n[k], t->kind_n[k]);
    for (int b = 0; b < N_BANDS; b++)
        if (t->band_n[b]) printf("  %-16s %6.2f%% (%zu)\n", band_names[b], 100.0 * t->band_ok[b] / t->band_n[b], t->band_n[b]);
    if (t->novel_of)
        printf("  novelty test (threshold from the training half's own 5-fold scores): %zu of %zu test trees novel "
               "(%.2f%%, unknown though trees), the highest novelty %.2f of the threshold\n",
               t->novel_n, t->novel_of, 100.0 * t->novel_n / t->novel_of, t->novelty_max);
    if (t->vote_n)
        printf("  decisions with voting (unknown counts as wrong): rows of one species %.2f%%, random mixed %.2f%%; "
               "confident %.1f%% of trees, %.2f%% of those right\n",
               100.0 * t->vote_rows_ok / t->vote_n, 100.0 * t->vote_mixed_ok / t->vote_n,
               100.0 * t->confident_n / t->vote_n, t->confident_n ? 100.0 * t->confident_ok / t->confident_n : 0);
    if (!with_matrix) return;
    printf("  confusion (rows truth, %% of the row):\n  %-16s", "");
    for (size_t c = 0; c < C; c++) printf(" %6.6s", ds->names[c]);
    printf("\n");
    for (size_t r = 0; r < C; r++) {
        size_t row = 0;
        for (size_t c = 0; c < C; c++) row += t->conf[r * C + c];
        printf("  %-16.16s", ds->names[r]);
        for (size_t c = 0; c < C; c++) printf(" %6.1f", row ? 100.0 * t->conf[r * C + c] / row : 0);
        printf("\n");
    }
}

static int run_protocol(const char *title, method_fn fn, const dataset *ds, const int *kind, const int *band, int reps,
                        tally *t, int voting)
{
    size_t C = ds->C;
    t->conf = calloc(C * C, sizeof *t->conf);
    size_t *tr = malloc(ds->n * sizeof *tr), *te = malloc(ds->n * sizeof *te), *idx = malloc(ds->n * sizeof *idx);
    double *prob = malloc(ds->n * C * sizeof *prob), *nov = malloc(ds->n * sizeof *nov);
    if (!t->conf || !tr || !te || !idx || !prob || !nov) return 1;
    jb_novelty_out = fn == jb_method ? nov : NULL;
    double c0 = cpu_seconds();
    sy_progress bar;
    sy_progress_begin(&bar, title, (size_t)reps);
    for (int r = 0; r < reps; r++) {
        rng_state = 0x5eed0000ull + (uint64_t)r; /* the same splits for every method */
        size_t ntr = 0, nte = 0;
        for (size_t c = 0; c < C; c++) {
            size_t m = 0;
            for (size_t i = 0; i < ds->n; i++)
                if (ds->y[i] == (int)c) idx[m++] = i;
            for (size_t i = m; i > 1; i--) {
                size_t j = (size_t)(rnd() % i), tmp = idx[i - 1];
                idx[i - 1] = idx[j], idx[j] = tmp;
            }
            for (size_t i = 0; i < m; i++) {
                if (i < m / 2) tr[ntr++] = idx[i];
                else te[nte++] = idx[i];
            }
        }
        if (fn(ds, tr, ntr, te, nte, prob, (uint64_t)r + 1)) return 1;
        tally_add(t, ds, te, nte, prob, kind, band);
        if (jb_novelty_out)
            for (size_t k = 0; k < nte; k++) {
                t->novel_of++, t->novel_n += nov[k] > 1;
                if (nov[k] > t->novelty_max) t->novelty_max = nov[k];
            }
        if (voting) voting_add(t, ds, te, nte, prob);
        sy_progress_update(&bar, (size_t)r + 1);
    }
    sy_progress_end(&bar);
    t->seconds = cpu_seconds() - c0;
    jb_novelty_out = NULL;
    free(tr), free(te), free(idx), free(prob), free(nov);
    return 0;
}

static int write_png(const tally *t, const dataset *ds, const char *path)
{
    sy_confusion c;
    memset(&c, 0, sizeof c);
    size_t C = ds->C;
    c.n_classes = C;
    c.labels = calloc(C, sizeof *c.labels);
    c.matrix = calloc(C * C, sizeof *c.matrix);
    c.f1 = calloc(C, sizeof *c.f1);
    if (!c.labels || !c.matrix || !c.f1) return 1;
    for (size_t k = 0; k < C; k++) c.labels[k] = strdup(ds->names[k]);
    memcpy(c.matrix, t->conf, C * C * sizeof *c.matrix);
    c.n_samples = t->n;
    c.accuracy = (double)t->ok / (double)t->n;
    for (size_t k = 0; k < C; k++) {
        size_t tp = t->conf[k * C + k], row = 0, col = 0;
        for (size_t j = 0; j < C; j++) row += t->conf[k * C + j], col += t->conf[j * C + k];
        c.f1[k] = row + col ? 2.0 * tp / (double)(row + col) : NAN;
    }
    sy_error err;
    int rc = sy_confusion_png(&c, path, &err) ? 1 : 0;
    if (rc) fprintf(stderr, "bench_classify: %s\n", err.msg);
    else printf("  confusion PNG: %s\n", path);
    sy_confusion_free(&c);
    return rc;
}

/* Generalisation: train on the odd seeds (with the training script's even
 * number of settings cycled by seed, half of the settings); test on the even
 * seeds (the other half of the settings, never seen in this training) and on
 * the unseen table (settings no model has seen). */
static void generalisation(const char *name, method_fn fn, const dataset *ds, const int *seed, const dataset *un,
                           const int *un_kind)
{
    size_t *tr = malloc(ds->n * sizeof *tr), *te = malloc(ds->n * sizeof *te), *all = malloc(un->n * sizeof *all);
    double *prob = malloc((ds->n + un->n) * ds->C * sizeof *prob);
    if (!tr || !te || !all || !prob) return;
    size_t ntr = 0, nte = 0;
    for (size_t i = 0; i < ds->n; i++) {
        if (seed[i] % 2) tr[ntr++] = i;
        else te[nte++] = i;
    }
    /* One model, two test sets: train once on ds, predict the seen half, then
     * the unseen table through a merged view. */
    size_t n2 = ds->n + un->n;
    float *x2 = malloc(n2 * ds->d * sizeof *x2);
    int *y2 = malloc(n2 * sizeof *y2);
    size_t *te2 = malloc(n2 * sizeof *te2);
    if (!x2 || !y2 || !te2) return;
    memcpy(x2, ds->x, ds->n * ds->d * sizeof *x2);
    memcpy(x2 + ds->n * ds->d, un->x, un->n * ds->d * sizeof *x2);
    memcpy(y2, ds->y, ds->n * sizeof *y2);
    memcpy(y2 + ds->n, un->y, un->n * sizeof *y2);
    for (size_t k = 0; k < nte; k++) te2[k] = te[k];
    for (size_t k = 0; k < un->n; k++) te2[nte + k] = ds->n + k;
    dataset merged = {n2, ds->d, ds->C, x2, y2, ds->names};
    double c0 = cpu_seconds();
    double *nov = malloc((nte + un->n) * sizeof *nov);
    if (!nov) return;
    jb_novelty_out = fn == jb_method ? nov : NULL;
    if (fn(&merged, tr, ntr, te2, nte + un->n, prob, 7)) return;
    jb_novelty_out = NULL;
    size_t ok_seen = 0, ok_un = 0, kn[3] = {0}, kok[3] = {0};
    for (size_t k = 0; k < nte; k++) ok_seen += (int)argmax(prob + k * ds->C, ds->C) == ds->y[te[k]];
    for (size_t k = 0; k < un->n; k++) {
        int ok = (int)argmax(prob + (nte + k) * ds->C, ds->C) == un->y[k];
        ok_un += ok;
        if (un_kind[k] >= 0) kn[un_kind[k]]++, kok[un_kind[k]] += ok;
    }
    double a = 100.0 * ok_seen / nte, b = 100.0 * ok_un / un->n;
    /* The script cycles an even number of settings by seed, so odd seeds are
     * half of the settings and the even-seed test trees the other half. */
    printf("  %-10s trained on %zu trees (odd seeds = half the settings): the other settings, other seeds %.2f%% (%zu); --unseen settings %.2f%% (%zu); difference %.2f points  [unseen: tls %.1f%%, mls %.1f%%, als %.1f%%] %.1f CPU s\n",
           name, ntr, a, nte, b, un->n, a - b, kn[0] ? 100.0 * kok[0] / kn[0] : NAN, kn[1] ? 100.0 * kok[1] / kn[1] : NAN,
           kn[2] ? 100.0 * kok[2] / kn[2] : NAN, cpu_seconds() - c0);
    if (fn == jb_method) {
        size_t ns = 0, nu = 0;
        double mx = 0;
        for (size_t k = 0; k < nte; k++) ns += nov[k] > 1;
        for (size_t k = 0; k < un->n; k++) nu += nov[nte + k] > 1, mx = fmax(mx, nov[nte + k]);
        printf("  %-10s novelty test: novel (unknown) among the other settings %zu of %zu (%.2f%%), among the --unseen "
               "settings %zu of %zu (%.2f%%; highest %.2f of the threshold)\n",
               name, ns, nte, 100.0 * ns / nte, nu, un->n, 100.0 * nu / un->n, mx);
    }
    free(nov);
    free(tr), free(te), free(all), free(prob), free(x2), free(y2), free(te2);
}

static void real_scans(const char *model_path)
{
    static const char *const files[] = {"treels/pine.las", "adtree/tree1.xyz", "adtree/tree7.xyz",
                                        "adtree/tree13.xyz", "adtree/tree33.xyz", "adtree/Lille_11.xyz",
                                        "adtree/ahn3_delft.xyz", "adtree/tiny(for_debug).xyz",
                                        "pytlidar/tree_1.las", "rtwig/cloud.txt", "adtree/house.xyz"};
    sy_jb_model m;
    sy_error err = {0};
    if (sy_jb_load(model_path, &m, &err)) {
        printf("\nreal scans: %s\n", err.msg);
        return;
    }
    printf("\nreal scans, shipped model %s (%zu rounds):\n", model_path, m.n_rounds);
    sy_progress_set_quiet(1);
    sy_vote_options vo = sy_vote_options_default();
    size_t d = sy_feature_count();
    float *x = malloc(d * sizeof *x);
    sy_features_options fo = sy_features_options_default();
    for (size_t k = 0; k < sizeof files / sizeof *files && x; k++) {
        char path[1024];
        snprintf(path, sizeof path, "%s/real/%s", SYLVA_DATA_DIR, files[k]);
        sy_scan_features_result r;
        if (sy_scan_features(path, &fo, x, &r, &err)) {
            printf("  %-22s %s\n", files[k], err.msg);
            continue;
        }
        double p[SY_JB_MAX_CLASSES], nov = sy_jb_novelty(&m, x);
        sy_jb_predict(&m, x, p);
        sy_tree_decision dec;
        sy_vote(1, m.n_classes, p, &nov, NULL, &vo, &dec, &err);
        size_t best = (size_t)dec.best, second = best == 0 ? 1 : 0;
        for (size_t c = 0; c < m.n_classes; c++)
            if (c != best && p[c] > p[second]) second = c;
        printf("  %-26s %7zu pts, H %5.1f m: %-15s best %-15s p %.2f, second %-15s p %.2f, h1/h2 %.2f, novelty %.2f\n",
               files[k], r.info.points_in, r.info.height, dec.species >= 0 ? m.classes[dec.species] : "unknown",
               m.classes[dec.best], dec.h1, m.classes[second], p[second], dec.h2 > 0 ? dec.h1 / dec.h2 : INFINITY, nov);
    }
    free(x);
    sy_jb_model_free(&m);
}

/* The shipped model's novelty test on the --unseen table (trees it never saw,
 * scanned with settings it never saw): how many it would call unknown. */
static void shipped_novelty(const char *model_path, const dataset *un)
{
    sy_jb_model m;
    sy_error err = {0};
    if (sy_jb_load(model_path, &m, &err)) return;
    size_t nu = 0;
    double mx = 0;
    for (size_t k = 0; k < un->n; k++) {
        double v = sy_jb_novelty(&m, un->x + k * un->d);
        nu += v > 1, mx = fmax(mx, v);
    }
    printf("  shipped model (threshold %.3f): novel among the --unseen trees %zu of %zu (%.2f%%), highest %.2f of the threshold\n",
           m.nov_threshold, nu, un->n, un->n ? 100.0 * nu / un->n : 0, mx);
    sy_jb_model_free(&m);
}

static void speed(const char *model_path, const char *scan)
{
    sy_cloud c;
    sy_error err = {0};
    sy_progress_set_quiet(1);
    if (sy_read_cloud(scan, &c, &err) || sy_classify_preprocess(&c, scan, SY_CLASSIFY_VOXEL, &err)) {
        printf("\nspeed: %s\n", err.msg);
        return;
    }
    if (c.n > 100000) {
        /* Every k-th point: a 100k-point tree with the same shape. */
        uint8_t *keep = calloc(c.n, 1);
        if (!keep) return;
        for (size_t i = 0; i < 100000; i++) keep[(size_t)((double)i * (double)c.n / 100000.0)] = 1;
        sy_cloud_filter(&c, keep, &err);
        free(keep);
    }
    sy_jb_model m;
    if (sy_jb_load(model_path, &m, &err)) {
        printf("\nspeed: %s\n", err.msg);
        sy_cloud_free(&c);
        return;
    }
    size_t d = sy_feature_count();
    float *x = malloc(d * sizeof *x);
    sy_features_options fo = sy_features_options_default();
    double best = INFINITY, sum = 0;
    int reps = 5;
    sy_set_threads(1);
    for (int r = 0; r < reps && x; r++) {
        double c0 = cpu_seconds();
        double p[SY_JB_MAX_CLASSES];
        sy_features_info info;
        sy_features_compute(&c, &fo, x, &info, &err);
        sy_jb_predict(&m, x, p);
        double s = cpu_seconds() - c0;
        sum += s;
        if (s < best) best = s;
    }
    printf("\nspeed, one thread, %zu points (%s): features + prediction %.3f CPU s (best of %d), mean %.3f; target 0.3 s\n",
           c.n, scan, best, reps, sum / reps);
    free(x);
    sy_jb_model_free(&m);
    sy_cloud_free(&c);
}

static int load(const char *path, sy_feature_table *t, dataset *ds, const char **names, int **y, int **kind,
                int **band, int **seed)
{
    sy_error err = {0};
    if (sy_feature_table_read(path, t, &err)) {
        fprintf(stderr, "bench_classify: %s\n", err.msg);
        return 1;
    }
    *y = calloc(t->n, sizeof **y), *kind = calloc(t->n, sizeof **kind), *band = calloc(t->n, sizeof **band);
    *seed = calloc(t->n, sizeof **seed);
    if (!*y || !*kind || !*band || !*seed) return 1;
    if (names) {
        size_t C;
        if (sy_feature_table_classes(t, names, &C, *y, &err)) {
            fprintf(stderr, "bench_classify: %s\n", err.msg);
            return 1;
        }
        ds->C = C;
        ds->names = names;
    }
    for (size_t i = 0; i < t->n; i++) {
        char setting[64];
        (*kind)[i] = kind_of(t->file[i], setting, sizeof setting, &(*seed)[i]);
        (*band)[i] = band_of(t->spacing[i]);
    }
    ds->n = t->n, ds->d = t->d, ds->x = t->x, ds->y = *y;
    return 0;
}

int main(int argc, char **argv)
{
    const char *train = SYLVA_SPECIES_DIR "/../build/classifier-data/train.tsv";
    const char *unseen = SYLVA_SPECIES_DIR "/../build/classifier-data/unseen.tsv";
    char def_model[4200] = "";
    sy_error merr = {0};
    if (sy_default_model_path(def_model, sizeof def_model, &merr)) fprintf(stderr, "bench_classify: %s\n", merr.msg);
    const char *model = def_model, *png = "confusion.png";
    const char *speed_scan = NULL;
    int reps = 100, xgb_reps = 0, skip_xgb = 0, only_speed = 0;
    setvbuf(stdout, NULL, _IOLBF, 0); /* sections appear as they finish */
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--train") && i + 1 < argc) train = argv[++i];
        else if (!strcmp(argv[i], "--unseen") && i + 1 < argc) unseen = argv[++i];
        else if (!strcmp(argv[i], "--model") && i + 1 < argc) model = argv[++i];
        else if (!strcmp(argv[i], "--png") && i + 1 < argc) png = argv[++i];
        else if (!strcmp(argv[i], "--reps") && i + 1 < argc) reps = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--speed-scan") && i + 1 < argc) speed_scan = argv[++i];
        else if (!strcmp(argv[i], "--no-xgboost")) skip_xgb = 1;
        else if (!strcmp(argv[i], "--only-speed")) only_speed = 1;
        else if (!strcmp(argv[i], "--rounds") && i + 1 < argc) jb_max_rounds = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--xgb-reps") && i + 1 < argc) xgb_reps = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: bench_classify [--train T.tsv] [--unseen U.tsv] [--model M] [--png F] [--reps N] [--rounds R] [--xgb-reps N] [--speed-scan SCAN [--only-speed]] [--no-xgboost]\n");
            return 1;
        }
    }
    if (reps < 1) reps = 1;
    if (only_speed && speed_scan) {
        speed(model, speed_scan);
        return 0;
    }
    sy_feature_table t = {0}, tu = {0};
    dataset ds = {0}, du = {0};
    const char *names[SY_JB_MAX_CLASSES];
    int *y, *kind, *band, *seed, *uy = NULL, *ukind = NULL, *uband = NULL, *useed = NULL;
    if (load(train, &t, &ds, names, &y, &kind, &band, &seed)) return 2;
    size_t per[SY_JB_MAX_CLASSES] = {0}, kinds[3] = {0};
    for (size_t i = 0; i < ds.n; i++) {
        per[ds.y[i]]++;
        if (kind[i] >= 0) kinds[kind[i]]++;
    }
    size_t minper = ds.n;
    for (size_t c = 0; c < ds.C; c++) minper = per[c] < minper ? per[c] : minper;
    printf("bench_classify: %zu trees, %zu species (>= %zu each), %zu features; terrestrial %zu, mobile %zu, airborne %zu\n",
           ds.n, ds.C, minper, ds.d, kinds[0], kinds[1], kinds[2]);
    printf("(CPU seconds; the machine is shared, so wall time runs longer)\n");
    if (jb_max_rounds > 0) printf("JointBoost in the repetitions: at most %d rounds (the shipped model: early stopping within 600)\n", jb_max_rounds);

    tally tj = {0}, tx = {0};
    if (run_protocol("jointboost", jb_method, &ds, kind, band, reps, &tj, 1)) return 3;
    print_tally("JointBoost, half/half per species", &tj, &ds, 1);
    write_png(&tj, &ds, png);
    if (!skip_xgb) {
        /* The same splits: repetition r of both methods uses seed r. */
        if (run_protocol("xgboost", xgb_method, &ds, kind, band, xgb_reps > 0 && xgb_reps < reps ? xgb_reps : reps, &tx, 0))
            return 3;
        print_tally("xgboost baseline (multi:softprob, hist 64 bins, depth 3, 100 x eta 0.2, 1 thread), same splits", &tx, &ds, 1);
    }
    /* Unseen settings: labels bound to the training classes by name. */
    sy_error err = {0};
    if (sy_feature_table_read(unseen, &tu, &err) == SY_OK) {
        uy = calloc(tu.n, sizeof *uy), ukind = calloc(tu.n, sizeof *ukind), uband = calloc(tu.n, sizeof *uband);
        useed = calloc(tu.n, sizeof *useed);
        size_t keep = 0;
        for (size_t i = 0; i < tu.n; i++) {
            int c = -1;
            for (size_t k = 0; k < ds.C; k++)
                if (!strcmp(names[k], tu.label[i])) c = (int)k;
            if (c < 0) continue;
            char setting[64];
            memmove(tu.x + keep * tu.d, tu.x + i * tu.d, tu.d * sizeof *tu.x);
            uy[keep] = c;
            ukind[keep] = kind_of(tu.file[i], setting, sizeof setting, &useed[keep]);
            keep++;
        }
        du.n = keep, du.d = tu.d, du.C = ds.C, du.x = tu.x, du.y = uy, du.names = names;
        printf("\ngeneralisation to unseen scanner settings (%zu trees):\n", du.n);
        generalisation("jointboost", jb_method, &ds, seed, &du, ukind);
        if (!skip_xgb) generalisation("xgboost", xgb_method, &ds, seed, &du, ukind);
        shipped_novelty(model, &du);
    } else
        printf("\ngeneralisation: %s (run species/train-classifier.sh --unseen)\n", err.msg);
    real_scans(model);
    if (!speed_scan) {
        /* The densest training scan stands in for a 100k-point tree. */
        size_t best = 0;
        for (size_t i = 0; i < t.n; i++)
            if (t.points[i] > t.points[best]) best = i;
        speed_scan = t.file[best];
    }
    speed(model, speed_scan);
    free(y), free(kind), free(band), free(seed), free(uy), free(ukind), free(uband), free(useed);
    free(tj.conf), free(tx.conf);
    sy_feature_table_free(&t);
    sy_feature_table_free(&tu);
    return 0;
}
