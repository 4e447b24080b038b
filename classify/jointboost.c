/* JointBoost: multiclass boosting with shared regression stumps (Torralba,
 * Murphy & Freeman 2007, "Sharing visual features for multiclass and multiview
 * object detection", IEEE PAMI 29(5)), the classifier of Pirk 2013 §3.5.1.
 *
 * GentleBoost (Friedman, Hastie & Tibshirani 2000, "Additive logistic
 * regression") per class with targets z = +1 for the sample's class and -1 for
 * the others and weights w = w0 exp(-z H). Each round fits ONE stump
 *     h(x, c) = a [x_f > theta] + b [x_f <= theta]   for c in the shared set S,
 *     h(x, c) = k_c                                   for c not in S,
 * by weighted least squares over all classes. For a split the fitted constants
 * are weighted means (a = sum_S w z over the right side / sum_S w, ...), so the
 * error is sum w z^2 minus sum over the groups of (sum w z)^2 / sum w, and the
 * search maximises that sum. S is found by Torralba's greedy forward search:
 * start empty, add the class that helps most, keep the best set seen along the
 * way (C(C+1)/2 set evaluations per threshold instead of 2^C).
 *
 * Thresholds are midpoints between consecutive distinct values of the feature
 * sorted once before training; with max_thresholds set, at most that many of
 * them, spread evenly by rank. The set search costs C^2 per threshold, so it
 * runs on the greedy_thresholds candidates of each feature whose best
 * single-class split gains most (the sweep that finds them is O(C) each). Features are searched in parallel, each
 * feature's best split is kept, and the winner is taken in feature order (ties
 * to the lower feature): the model is the same for any thread count.
 *
 * Early stopping and calibration: a stratified, seeded share of the samples is
 * held out; training stops when their log loss has not improved for `patience`
 * rounds and is cut back to the best round; the temperature kappa of
 * p_c = exp(kappa H_c) / sum exp(kappa H) is then fitted on the held-out scores
 * (minimum log loss, golden-section search; Guo et al. 2017, "On calibration of
 * modern neural networks", temperature scaling). GentleBoost's H approximates
 * half the log-odds, so kappa = 2 is the uncalibrated default. With `refit`
 * the model is finally retrained on every sample for the best round count. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "classify/classify.h"
#include "stages/core/fileio.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/core/rng.h"

sy_jb_options sy_jb_options_default(void)
{
    sy_jb_options o;
    o.rounds = 600;
    o.max_thresholds = 64;
    o.greedy_thresholds = 8;
    o.validation = 0.2;
    o.patience = 60;
    o.shrinkage = 0.5;
    o.balance = 1;
    o.refit = 1;
    o.seed = 1;
    o.novelty_quantile = 0.995;
    o.novelty_factor = 2.0;
    return o;
}

sy_code sy_jb_options_check(const sy_jb_options *o, sy_error *err)
{
    if (o->rounds < 1 || o->rounds > 100000) return sy_fail(err, SY_EUSAGE, "jointboost: rounds must be in [1, 100000]");
    if (o->max_thresholds < 0) return sy_fail(err, SY_EUSAGE, "jointboost: max_thresholds must be >= 0");
    if (o->greedy_thresholds < 0) return sy_fail(err, SY_EUSAGE, "jointboost: greedy_thresholds must be >= 0");
    if (!(o->validation >= 0 && o->validation < 0.9))
        return sy_fail(err, SY_EUSAGE, "jointboost: validation must be in [0, 0.9)");
    if (o->patience < 1) return sy_fail(err, SY_EUSAGE, "jointboost: patience must be >= 1");
    if (!(o->shrinkage > 0 && o->shrinkage <= 1)) return sy_fail(err, SY_EUSAGE, "jointboost: shrinkage must be in (0, 1]");
    if (!(o->novelty_quantile > 0 && o->novelty_quantile <= 1))
        return sy_fail(err, SY_EUSAGE, "jointboost: novelty_quantile must be in (0, 1]");
    if (!(o->novelty_factor > 0 && o->novelty_factor < 1e6))
        return sy_fail(err, SY_EUSAGE, "jointboost: novelty_factor must be > 0");
    return SY_OK;
}

void sy_jb_model_free(sy_jb_model *m)
{
    if (!m) return;
    for (size_t c = 0; c < m->n_classes; c++) free(m->classes ? m->classes[c] : NULL);
    free(m->classes);
    free(m->feature), free(m->threshold), free(m->a), free(m->b), free(m->mask), free(m->k);
    free(m->nov_center), free(m->nov_scale), free(m->nov_mean), free(m->nov_sd);
    free(m->planar_feature), free(m->planar_lo), free(m->planar_hi), free(m->planar_s);
    memset(m, 0, sizeof *m);
}

void sy_jb_scores(const sy_jb_model *m, const float *x, double *H)
{
    size_t C = m->n_classes;
    for (size_t c = 0; c < C; c++) H[c] = 0;
    for (size_t r = 0; r < m->n_rounds; r++) {
        double v = x[m->feature[r]] > m->threshold[r] ? m->a[r] : m->b[r];
        uint64_t mask = m->mask[r];
        const float *k = m->k + r * C;
        for (size_t c = 0; c < C; c++) H[c] += (mask >> c) & 1 ? v : k[c];
    }
}

static void softmax(const double *H, size_t C, double kappa, double *p)
{
    double mx = -INFINITY;
    for (size_t c = 0; c < C; c++) mx = fmax(mx, kappa * H[c]);
    double s = 0;
    for (size_t c = 0; c < C; c++) s += p[c] = exp(kappa * H[c] - mx);
    for (size_t c = 0; c < C; c++) p[c] /= s;
}

void sy_jb_predict(const sy_jb_model *m, const float *x, double *prob)
{
    double H[SY_JB_MAX_CLASSES];
    sy_jb_scores(m, x, H);
    softmax(H, m->n_classes, m->kappa, prob);
}

/* ------------------------------------------------------------ training */

typedef struct {
    const float *X;
    size_t n, d, C;
    const uint32_t *order;  /* d x n_train: training sample indices sorted by feature value */
    const uint32_t *cand;   /* d x max candidate split ranks (count in n_cand) */
    const size_t *n_cand;
    size_t max_cand;
    const int *y;
    const double *w;        /* n x C current weights */
    const double *W, *Z;    /* per class totals sum w, sum w z */
    size_t n_train;
    size_t greedy;          /* candidates per feature for the set search (0: all) */
    /* per feature results */
    double *gain;
    float *theta;
    uint64_t *mask;
    double *a, *b;
} search_ctx;

/* Greedy forward selection of the shared set at one split (left sums WL, ZL
 * per class); updates *best and the stump when it finds a better one. */
static void greedy_sets(const search_ctx *s, const double *WL, const double *ZL, const double *base, double *best,
                        uint64_t *best_mask, double *best_a, double *best_b, int *improved)
{
    size_t C = s->C;
    uint64_t S = 0;
    double sWL = 0, sZL = 0, sWR = 0, sZR = 0, sBase = 0;
    for (size_t step = 0; step < C; step++) {
        double step_best = -INFINITY;
        size_t step_c = 0;
        for (size_t c = 0; c < C; c++) {
            if ((S >> c) & 1) continue;
            double wl = sWL + WL[c], zl = sZL + ZL[c];
            double wr = sWR + s->W[c] - WL[c], zr = sZR + s->Z[c] - ZL[c];
            double g = (wl > 0 ? zl * zl / wl : 0) + (wr > 0 ? zr * zr / wr : 0) - (sBase + base[c]);
            if (g > step_best) step_best = g, step_c = c;
        }
        S |= (uint64_t)1 << step_c;
        sWL += WL[step_c], sZL += ZL[step_c];
        sWR += s->W[step_c] - WL[step_c], sZR += s->Z[step_c] - ZL[step_c];
        sBase += base[step_c];
        if (step_best > *best * (1 + 1e-12) + 1e-15) {
            *best = step_best;
            *best_mask = S;
            *best_a = sWR > 0 ? sZR / sWR : 0;
            *best_b = sWL > 0 ? sZL / sWL : 0;
            *improved = 1;
        }
    }
}

/* Best shared stump for features [begin, end). Pass 1 sweeps the sorted
 * samples once, keeping each candidate split's per-class sums and its best
 * single-class gain; pass 2 runs the greedy set search on the `greedy`
 * candidates with the highest single-class gain (all when greedy is 0). */
static void search_features(void *vctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    search_ctx *s = vctx;
    size_t C = s->C;
    double WL[SY_JB_MAX_CLASSES], ZL[SY_JB_MAX_CLASSES], base[SY_JB_MAX_CLASSES];
    for (size_t c = 0; c < C; c++) base[c] = s->W[c] > 0 ? s->Z[c] * s->Z[c] / s->W[c] : 0;
    double *sums = malloc((s->max_cand ? s->max_cand : 1) * 2 * C * sizeof *sums);
    double *single = malloc((s->max_cand ? s->max_cand : 1) * sizeof *single);
    uint32_t *pick = malloc((s->max_cand ? s->max_cand : 1) * sizeof *pick);
    for (size_t f = begin; f < end; f++) {
        s->gain[f] = 0, s->theta[f] = 0, s->mask[f] = 0, s->a[f] = s->b[f] = 0;
        if (!sums || !single || !pick) continue; /* out of memory: this feature offers nothing */
        const uint32_t *ord = s->order + f * s->n_train;
        const uint32_t *cand = s->cand + f * s->max_cand;
        size_t nc = s->n_cand[f];
        for (size_t c = 0; c < C; c++) WL[c] = ZL[c] = 0;
        size_t at = 0; /* samples [0, at) of ord are on the left */
        for (size_t t = 0; t < nc; t++) {
            size_t upto = cand[t]; /* split after rank upto-1 */
            for (; at < upto; at++) {
                uint32_t i = ord[at];
                const double *wi = s->w + (size_t)i * C;
                for (size_t c = 0; c < C; c++) {
                    WL[c] += wi[c];
                    ZL[c] += (s->y[i] == (int)c) ? wi[c] : -wi[c];
                }
            }
            double g1 = -INFINITY;
            for (size_t c = 0; c < C; c++) {
                double wr = s->W[c] - WL[c], zr = s->Z[c] - ZL[c];
                double g = (WL[c] > 0 ? ZL[c] * ZL[c] / WL[c] : 0) + (wr > 0 ? zr * zr / wr : 0) - base[c];
                if (g > g1) g1 = g;
            }
            memcpy(sums + t * 2 * C, WL, C * sizeof *WL);
            memcpy(sums + t * 2 * C + C, ZL, C * sizeof *ZL);
            single[t] = g1;
        }
        /* The candidates for the set search: the top `greedy` by single-class
         * gain (ties to the lower rank), kept in rank order. */
        size_t np = nc;
        for (size_t t = 0; t < nc; t++) pick[t] = (uint32_t)t;
        if (s->greedy > 0 && nc > s->greedy) {
            /* Partial selection sort: the `greedy` best (gain descending, ties to
             * the lower rank), O(nc greedy), then back into rank order. */
            np = s->greedy;
            for (size_t k = 0; k < np; k++) {
                size_t b = k;
                for (size_t u = k + 1; u < nc; u++)
                    if (single[pick[u]] > single[pick[b]] || (single[pick[u]] == single[pick[b]] && pick[u] < pick[b]))
                        b = u;
                uint32_t t = pick[k];
                pick[k] = pick[b];
                pick[b] = t;
            }
            for (size_t k = 1; k < np; k++)
                for (size_t u = k; u > 0 && pick[u - 1] > pick[u]; u--) {
                    uint32_t t = pick[u];
                    pick[u] = pick[u - 1];
                    pick[u - 1] = t;
                }
        }
        double best = 0, best_a = 0, best_b = 0;
        uint64_t best_mask = 0;
        float best_theta = 0;
        for (size_t k = 0; k < np; k++) {
            size_t t = pick[k];
            int improved = 0;
            greedy_sets(s, sums + t * 2 * C, sums + t * 2 * C + C, base, &best, &best_mask, &best_a, &best_b, &improved);
            if (improved) {
                size_t upto = cand[t];
                float lo = s->X[(size_t)ord[upto - 1] * s->d + f], hi = s->X[(size_t)ord[upto] * s->d + f];
                float th = (float)((double)lo + ((double)hi - lo) / 2);
                if (!(th < hi)) th = lo;
                best_theta = th;
            }
        }
        s->gain[f] = best;
        s->theta[f] = best_theta;
        s->mask[f] = best_mask;
        s->a[f] = best_a;
        s->b[f] = best_b;
    }
    free(sums), free(single), free(pick);
}

/* qsort has no context argument: a feature is sorted as (value, index) pairs. */
typedef struct {
    float v;
    uint32_t i;
} vi_pair;

static int cmp_vi(const void *a, const void *b)
{
    const vi_pair *x = a, *y = b;
    if (x->v != y->v) return x->v < y->v ? -1 : 1;
    return (x->i > y->i) - (x->i < y->i);
}


static double logloss(const double *H, const int *y, const uint32_t *idx, size_t n, size_t C, double kappa)
{
    double p[SY_JB_MAX_CLASSES], s = 0;
    for (size_t k = 0; k < n; k++) {
        softmax(H + (size_t)idx[k] * C, C, kappa, p);
        s -= log(fmax(p[y[idx[k]]], 1e-12));
    }
    return n ? s / (double)n : NAN;
}

static size_t argmax(const double *v, size_t n)
{
    size_t b = 0;
    for (size_t i = 1; i < n; i++)
        if (v[i] > v[b]) b = i;
    return b;
}

typedef struct {
    size_t cap, n;
    int32_t *feature;
    float *threshold, *a, *b, *k;
    uint64_t *mask;
} stumps;

static void stumps_free(stumps *s)
{
    free(s->feature), free(s->threshold), free(s->a), free(s->b), free(s->k), free(s->mask);
    memset(s, 0, sizeof *s);
}

/* Boosts on the samples train[0..n_train) for at most `rounds` rounds; with
 * held-out samples, stops early and cuts back to the best round (*best_round). */
static sy_code boost(const float *X, size_t d, const int *y, size_t C, const double *w0, const uint32_t *train,
                     size_t n_train, const uint32_t *held, size_t n_held, const sy_jb_options *o, int rounds,
                     size_t n_all, stumps *out, size_t *best_round, double *best_loss, sy_error *err)
{
    sy_code rc = SY_OK;
    memset(out, 0, sizeof *out);
    size_t maxc = o->max_thresholds > 0 ? (size_t)o->max_thresholds : n_train;
    uint32_t *order = sy_calloc(d * n_train, sizeof *order, err, "jointboost");
    uint32_t *cand = sy_calloc(d * (maxc + 1), sizeof *cand, err, "jointboost");
    size_t *n_cand = sy_calloc(d, sizeof *n_cand, err, "jointboost");
    vi_pair *pairs = sy_calloc(n_train, sizeof *pairs, err, "jointboost");
    double *w = sy_calloc(n_all * C, sizeof *w, err, "jointboost");
    double *H = sy_calloc(n_all * C, sizeof *H, err, "jointboost");
    double *gain = sy_calloc(d, sizeof *gain, err, "jointboost"), *fa = sy_calloc(d, sizeof *fa, err, "jointboost"),
           *fb = sy_calloc(d, sizeof *fb, err, "jointboost");
    float *fth = sy_calloc(d, sizeof *fth, err, "jointboost");
    uint64_t *fmask = sy_calloc(d, sizeof *fmask, err, "jointboost");
    uint32_t *distinct = sy_calloc(n_train + 1, sizeof *distinct, err, "jointboost");
    out->cap = (size_t)rounds;
    out->feature = sy_calloc(out->cap, sizeof *out->feature, err, "jointboost");
    out->threshold = sy_calloc(out->cap, sizeof *out->threshold, err, "jointboost");
    out->a = sy_calloc(out->cap, sizeof *out->a, err, "jointboost");
    out->b = sy_calloc(out->cap, sizeof *out->b, err, "jointboost");
    out->mask = sy_calloc(out->cap, sizeof *out->mask, err, "jointboost");
    out->k = sy_calloc(out->cap * C, sizeof *out->k, err, "jointboost");
    if (!order || !cand || !n_cand || !pairs || !w || !H || !gain || !fa || !fb || !fth || !fmask || !distinct ||
        !out->feature || !out->threshold || !out->a || !out->b || !out->mask || !out->k) {
        rc = err->code;
        goto done;
    }
    /* Sort once per feature; candidate splits between distinct values. */
    for (size_t f = 0; f < d; f++) {
        for (size_t k = 0; k < n_train; k++) pairs[k].v = X[(size_t)train[k] * d + f], pairs[k].i = train[k];
        qsort(pairs, n_train, sizeof *pairs, cmp_vi);
        size_t nd = 0;
        for (size_t k = 0; k < n_train; k++) {
            order[f * n_train + k] = pairs[k].i;
            if (k > 0 && pairs[k].v > pairs[k - 1].v) distinct[nd++] = (uint32_t)k;
        }
        size_t take = nd < maxc ? nd : maxc;
        for (size_t t = 0; t < take; t++) {
            size_t pick = nd <= maxc ? t : (size_t)(((double)t + 0.5) * (double)nd / (double)take);
            cand[f * maxc + t] = distinct[pick];
        }
        n_cand[f] = take;
    }
    double W[SY_JB_MAX_CLASSES], Z[SY_JB_MAX_CLASSES];
    *best_round = 0;
    *best_loss = INFINITY;
    size_t since_best = 0;
    for (int r = 0; r < rounds; r++) {
        for (size_t c = 0; c < C; c++) W[c] = Z[c] = 0;
        for (size_t k = 0; k < n_train; k++) {
            uint32_t i = train[k];
            for (size_t c = 0; c < C; c++) {
                double z = y[i] == (int)c ? 1 : -1;
                double wi = w0[i] * exp(-z * H[(size_t)i * C + c]);
                w[(size_t)i * C + c] = wi;
                W[c] += wi;
                Z[c] += z * wi;
            }
        }
        search_ctx sc = {X, n_all, d, C, order, cand, n_cand, maxc, y, w, W, Z, n_train,
                         (size_t)o->greedy_thresholds, gain, fth, fmask, fa, fb};
        sy_parallel_for(d, 8, search_features, &sc);
        size_t bf = 0;
        for (size_t f = 1; f < d; f++)
            if (gain[f] > gain[bf]) bf = f;
        if (!(gain[bf] > 0)) break; /* nothing left to fit */
        size_t rr = out->n++;
        out->feature[rr] = (int32_t)bf;
        out->threshold[rr] = fth[bf];
        out->mask[rr] = fmask[bf];
        out->a[rr] = (float)(o->shrinkage * fa[bf]);
        out->b[rr] = (float)(o->shrinkage * fb[bf]);
        for (size_t c = 0; c < C; c++)
            out->k[rr * C + c] = ((fmask[bf] >> c) & 1) ? 0 : (float)(o->shrinkage * (W[c] > 0 ? Z[c] / W[c] : 0));
        /* Update the scores of every sample, held out or not. */
        for (size_t k = 0; k < n_train + n_held; k++) {
            uint32_t i = k < n_train ? train[k] : held[k - n_train];
            double v = X[(size_t)i * d + bf] > out->threshold[rr] ? out->a[rr] : out->b[rr];
            for (size_t c = 0; c < C; c++) H[(size_t)i * C + c] += ((fmask[bf] >> c) & 1) ? v : out->k[rr * C + c];
        }
        if (n_held) {
            double loss = logloss(H, y, held, n_held, C, 2.0);
            if (loss < *best_loss - 1e-9) {
                *best_loss = loss;
                *best_round = out->n;
                since_best = 0;
            } else if (++since_best >= (size_t)o->patience)
                break;
        } else
            *best_round = out->n;
    }
    if (n_held) out->n = *best_round;
done:
    free(order), free(cand), free(n_cand), free(pairs), free(w), free(H), free(gain), free(fa), free(fb), free(fth);
    free(fmask), free(distinct);
    if (rc) stumps_free(out);
    return rc;
}

static void model_take_stumps(sy_jb_model *m, stumps *s)
{
    m->n_rounds = s->n;
    m->feature = s->feature, m->threshold = s->threshold, m->a = s->a, m->b = s->b, m->mask = s->mask, m->k = s->k;
    memset(s, 0, sizeof *s);
}

/* Temperature kappa minimising the held-out log loss (golden section on log kappa). */
static double fit_kappa(const sy_jb_model *m, const float *X, const int *y, const uint32_t *held, size_t n_held)
{
    size_t C = m->n_classes, d = m->n_features;
    double *H = malloc(n_held * C * sizeof *H);
    uint32_t *idx = malloc(n_held * sizeof *idx);
    if (!H || !idx) {
        free(H), free(idx);
        return 2.0;
    }
    int *yy = malloc(n_held * sizeof *yy);
    if (!yy) {
        free(H), free(idx);
        return 2.0;
    }
    for (size_t k = 0; k < n_held; k++) {
        sy_jb_scores(m, X + (size_t)held[k] * d, H + k * C);
        idx[k] = (uint32_t)k;
        yy[k] = y[held[k]];
    }
    /* Within a factor 4 of the GentleBoost link (kappa 2): a small held-out
     * set that the model gets all right would otherwise drive kappa to the
     * bound and the probabilities to 0 and 1. */
    double lo = log(0.5), hi = log(8), g = (sqrt(5) - 1) / 2;
    double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
    double f1 = logloss(H, yy, idx, n_held, C, exp(x1)), f2 = logloss(H, yy, idx, n_held, C, exp(x2));
    for (int it = 0; it < 60; it++) {
        if (f1 < f2) {
            hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo);
            f1 = logloss(H, yy, idx, n_held, C, exp(x1));
        } else {
            lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo);
            f2 = logloss(H, yy, idx, n_held, C, exp(x2));
        }
    }
    free(H), free(idx), free(yy);
    return exp((lo + hi) / 2);
}

sy_code sy_jb_train(const float *X, size_t n, size_t d, const int *y, size_t C, const char *const *names,
                    uint32_t features_version, const sy_jb_options *o, sy_jb_model *out, sy_jb_report *report,
                    sy_error *err)
{
    double t0 = sy_now();
    memset(out, 0, sizeof *out);
    sy_code rc = sy_jb_options_check(o, err);
    if (rc) return rc;
    if (C < 2 || C > SY_JB_MAX_CLASSES)
        return sy_fail(err, SY_EINPUT, "jointboost: %zu classes, 2..%d are supported", C, SY_JB_MAX_CLASSES);
    if (n < 2 || d < 1 || n > UINT32_MAX) return sy_fail(err, SY_EINPUT, "jointboost: %zu samples of %zu features", n, d);
    size_t per[SY_JB_MAX_CLASSES] = {0};
    for (size_t i = 0; i < n; i++) {
        if (y[i] < 0 || (size_t)y[i] >= C) return sy_fail(err, SY_EINPUT, "jointboost: sample %zu has label %d", i, y[i]);
        per[y[i]]++;
    }
    for (size_t c = 0; c < C; c++)
        if (!per[c])
            return sy_fail(err, SY_EINPUT, "jointboost: class %s has no sample", names ? names[c] : "(unnamed)");
    for (size_t i = 0; i < n * d; i++)
        if (!isfinite(X[i])) return sy_fail(err, SY_EINPUT, "jointboost: feature %zu of sample %zu is not finite", i % d, i / d);
    double *w0 = sy_calloc(n, sizeof *w0, err, "jointboost");
    uint32_t *perm = sy_calloc(n, sizeof *perm, err, "jointboost");
    uint32_t *train = sy_calloc(n, sizeof *train, err, "jointboost"), *held = sy_calloc(n, sizeof *held, err, "jointboost");
    out->classes = sy_calloc(C, sizeof *out->classes, err, "jointboost");
    stumps st = {0};
    if (!w0 || !perm || !train || !held || !out->classes) {
        rc = err->code;
        goto fail;
    }
    out->n_classes = C;
    out->n_features = d;
    out->features_version = features_version;
    out->train_samples = n;
    for (size_t c = 0; c < C; c++) {
        char buf[32];
        snprintf(buf, sizeof buf, "class%zu", c);
        out->classes[c] = strdup(names && names[c] ? names[c] : buf);
        if (!out->classes[c]) {
            rc = sy_fail(err, SY_EINTERNAL, "jointboost: out of memory");
            goto fail;
        }
    }
    for (size_t i = 0; i < n; i++) w0[i] = o->balance ? (double)n / ((double)C * (double)per[y[i]]) : 1.0;
    /* Stratified held-out split: per class, a seeded shuffle, the first share held out. */
    size_t n_train = 0, n_held = 0;
    uint64_t rs = o->seed ^ 0x4A6F696E74426F6Full;
    sy_permutation(perm, n, &rs);
    size_t taken[SY_JB_MAX_CLASSES] = {0};
    for (size_t k = 0; k < n; k++) {
        uint32_t i = perm[k];
        size_t want = (size_t)floor(o->validation * (double)per[y[i]]);
        if (per[y[i]] - want < 1) want = per[y[i]] - 1;
        if (taken[y[i]] < want) held[n_held++] = i, taken[y[i]]++;
        else train[n_train++] = i;
    }
    /* Keep sample order stable: sort both lists by index. */
    for (int pass = 0; pass < 2; pass++) {
        uint32_t *v = pass ? held : train;
        size_t m = pass ? n_held : n_train;
        vi_pair *tmp = malloc((m ? m : 1) * sizeof *tmp);
        if (!tmp) {
            rc = sy_fail(err, SY_EINTERNAL, "jointboost: out of memory");
            goto fail;
        }
        for (size_t k = 0; k < m; k++) tmp[k].v = 0, tmp[k].i = v[k];
        qsort(tmp, m, sizeof *tmp, cmp_vi);
        for (size_t k = 0; k < m; k++) v[k] = tmp[k].i;
        free(tmp);
    }
    size_t best_round = 0;
    double best_loss = NAN;
    if ((rc = boost(X, d, y, C, w0, train, n_train, held, n_held, o, o->rounds, n, &st, &best_round, &best_loss, err)))
        goto fail;
    size_t rounds_run = st.n;
    model_take_stumps(out, &st);
    out->kappa = 2.0;
    double hold_acc = NAN;
    if (n_held) {
        out->kappa = fit_kappa(out, X, y, held, n_held);
        size_t ok = 0;
        double H[SY_JB_MAX_CLASSES];
        for (size_t k = 0; k < n_held; k++) {
            sy_jb_scores(out, X + (size_t)held[k] * d, H);
            ok += argmax(H, C) == (size_t)y[held[k]];
        }
        hold_acc = (double)ok / (double)n_held;
        if (o->refit && best_round > 0) {
            for (size_t i = 0; i < n; i++) train[i] = (uint32_t)i;
            size_t br2;
            double bl2;
            if ((rc = boost(X, d, y, C, w0, train, n, NULL, 0, o, (int)best_round, n, &st, &br2, &bl2, err))) goto fail;
            free(out->feature), free(out->threshold), free(out->a), free(out->b), free(out->mask), free(out->k);
            model_take_stumps(out, &st);
        }
    }
    out->holdout_accuracy = hold_acc;
    /* The novelty test: statistics of every tree, threshold from 5-fold scores. */
    if ((rc = sy_jb_novelty_train(out, X, n, y, 5, o->novelty_quantile, o->novelty_factor, o->seed, err))) goto fail;
    if (report) {
        size_t ok = 0;
        double H[SY_JB_MAX_CLASSES];
        for (size_t i = 0; i < n; i++) {
            sy_jb_scores(out, X + i * d, H);
            ok += argmax(H, C) == (size_t)y[i];
        }
        report->rounds_run = rounds_run;
        report->rounds_kept = out->n_rounds;
        report->holdout_accuracy = hold_acc;
        report->holdout_loss = n_held ? best_loss : NAN;
        report->train_accuracy = (double)ok / (double)n;
        report->kappa = out->kappa;
        report->seconds = sy_now() - t0;
    }
    free(w0), free(perm), free(train), free(held);
    return SY_OK;
fail:
    stumps_free(&st);
    free(w0), free(perm), free(train), free(held);
    sy_jb_model_free(out);
    return rc;
}
