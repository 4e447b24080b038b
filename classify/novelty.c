/* The joint novelty test of the classifier: is this a tree like the ones the
 * model was trained on at all? JointBoost always answers with some species;
 * a house, a car or a lamp post must come out unknown instead. Per-feature
 * training ranges cannot tell: a house lies inside the range of almost every
 * feature once the training set mixes scanners, densities and stand trees.
 * What gives it away is the combination, so the test measures the joint
 * distance to every species in a standardised feature space.
 *
 *   1. Standardise: z_f = (x_f - median_f) / s_f over all training trees,
 *      s_f the robust spread (interquartile range / 1.349, the standard
 *      deviation where the quartiles coincide, at least 1e-6).
 *   2. Per species c: mean m_cf and standard deviation d_cf of z_f over its
 *      trees, the variance shrunk towards the pooled within-species variance
 *      (Friedman 1989, "Regularized discriminant analysis": with 40 trees and
 *      286 features a species' own variance of a feature is often ~0) and
 *      floored at 0.05 (a twentieth of the training spread).
 *   3. The deviation of x from species c per feature is
 *      e_cf = min(((z_f - m_cf) / d_cf)^2, cap): the squared Mahalanobis term
 *      of a diagonal covariance, capped so one broken feature (a skeleton that
 *      failed on a real scan) adds at most `cap`.
 *   4. D_c(x) = the mean of e_cf over the features after leaving out the
 *      `trim` share of the largest (a trimmed mean); score = min_c D_c.
 *   5. Threshold: `folds`-fold cross-validation over the training trees gives
 *      every tree a score against statistics fitted without it; the threshold
 *      is `factor` times the q-quantile of those scores (docs/classify.md gives
 *      the calibration and what real trees and the house score).
 * Deterministic; cost O(C d log d) per tree. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "classify/classify.h"
#include "stages/core/rng.h"

#define NOV_CAP 25.0  /* one feature adds at most a 5-sigma deviation */
#define NOV_TRIM 0.1  /* the 10% largest deviations are left out */
#define NOV_SHRINK 8.0 /* pseudo-trees of the pooled variance in each species' variance */
#define NOV_SD_FLOOR 0.05

static int cmp_f(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static int cmp_d(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void novelty_arrays_free(sy_jb_model *m)
{
    free(m->nov_center), free(m->nov_scale), free(m->nov_mean), free(m->nov_sd);
    m->nov_center = m->nov_scale = m->nov_mean = m->nov_sd = NULL;
}

sy_code sy_jb_novelty_fit(sy_jb_model *m, const float *X, const int *y, const uint32_t *idx, size_t n_idx,
                          sy_error *err)
{
    size_t d = m->n_features, C = m->n_classes;
    novelty_arrays_free(m);
    m->nov_center = sy_calloc(d, sizeof *m->nov_center, err, "novelty");
    m->nov_scale = sy_calloc(d, sizeof *m->nov_scale, err, "novelty");
    m->nov_mean = sy_calloc(C * d, sizeof *m->nov_mean, err, "novelty");
    m->nov_sd = sy_calloc(C * d, sizeof *m->nov_sd, err, "novelty");
    float *v = sy_calloc(n_idx ? n_idx : 1, sizeof *v, err, "novelty");
    double *s1 = sy_calloc(C, sizeof *s1, err, "novelty"), *s2 = sy_calloc(C, sizeof *s2, err, "novelty");
    size_t *cnt = sy_calloc(C, sizeof *cnt, err, "novelty");
    if (!m->nov_center || !m->nov_scale || !m->nov_mean || !m->nov_sd || !v || !s1 || !s2 || !cnt) {
        novelty_arrays_free(m);
        free(v), free(s1), free(s2), free(cnt);
        return err->code;
    }
    m->nov_cap = NOV_CAP;
    m->nov_trim = NOV_TRIM;
    for (size_t k = 0; k < n_idx; k++) cnt[y[idx[k]]]++;
    for (size_t f = 0; f < d; f++) {
        for (size_t k = 0; k < n_idx; k++) v[k] = X[(size_t)idx[k] * d + f];
        qsort(v, n_idx, sizeof *v, cmp_f);
        double med = 0, scale = 0;
        if (n_idx) {
            med = 0.5 * ((double)v[(n_idx - 1) / 2] + v[n_idx / 2]);
            scale = ((double)v[(3 * (n_idx - 1)) / 4] - v[(n_idx - 1) / 4]) / 1.349;
            if (!(scale > 0)) {
                double s = 0, ss = 0;
                for (size_t k = 0; k < n_idx; k++) s += v[k], ss += (double)v[k] * v[k];
                double mu = s / (double)n_idx;
                scale = sqrt(fmax(0, ss / (double)n_idx - mu * mu));
            }
        }
        if (!(scale > 1e-6)) scale = 1e-6;
        m->nov_center[f] = (float)med, m->nov_scale[f] = (float)scale;
        for (size_t c = 0; c < C; c++) s1[c] = s2[c] = 0;
        for (size_t k = 0; k < n_idx; k++) {
            double z = ((double)X[(size_t)idx[k] * d + f] - med) / scale;
            s1[y[idx[k]]] += z, s2[y[idx[k]]] += z * z;
        }
        double pooled = 0;
        size_t pooled_n = 0;
        for (size_t c = 0; c < C; c++)
            if (cnt[c]) {
                double mu = s1[c] / (double)cnt[c];
                pooled += fmax(0, s2[c] - (double)cnt[c] * mu * mu), pooled_n += cnt[c];
            }
        pooled = pooled_n ? pooled / (double)pooled_n : 1;
        for (size_t c = 0; c < C; c++) {
            double mu = cnt[c] ? s1[c] / (double)cnt[c] : 0;
            double var = cnt[c] ? fmax(0, s2[c] / (double)cnt[c] - mu * mu) : pooled;
            var = ((double)cnt[c] * var + NOV_SHRINK * pooled) / ((double)cnt[c] + NOV_SHRINK);
            m->nov_mean[c * d + f] = (float)mu;
            m->nov_sd[c * d + f] = (float)fmax(NOV_SD_FLOOR, sqrt(var));
        }
    }
    free(v), free(s1), free(s2), free(cnt);
    return SY_OK;
}

double sy_jb_novelty_score(const sy_jb_model *m, const float *x)
{
    size_t d = m->n_features, C = m->n_classes;
    if (!m->nov_center || d == 0) return 0;
    double *e = malloc(d * sizeof *e);
    if (!e) return 0;
    size_t keep = d - (size_t)floor(m->nov_trim * (double)d);
    if (keep < 1) keep = 1;
    double best = INFINITY;
    for (size_t c = 0; c < C; c++) {
        const float *mu = m->nov_mean + c * d, *sd = m->nov_sd + c * d;
        for (size_t f = 0; f < d; f++) {
            double z = ((double)x[f] - m->nov_center[f]) / m->nov_scale[f];
            double t = (z - mu[f]) / sd[f];
            double v = t * t;
            e[f] = isfinite(v) && v < m->nov_cap ? v : m->nov_cap;
        }
        qsort(e, d, sizeof *e, cmp_d);
        double s = 0;
        for (size_t f = 0; f < keep; f++) s += e[f];
        s /= (double)keep;
        if (s < best) best = s;
    }
    free(e);
    return best;
}

double sy_jb_novelty(const sy_jb_model *m, const float *x)
{
    if (!m->nov_center || !(m->nov_threshold > 0)) return 0;
    return sy_jb_novelty_score(m, x) / m->nov_threshold;
}

sy_code sy_jb_novelty_train(sy_jb_model *m, const float *X, size_t n, const int *y, int folds, double q,
                            double factor, uint64_t seed, sy_error *err)
{
    uint32_t *perm = sy_calloc(n ? n : 1, sizeof *perm, err, "novelty");
    uint32_t *fit = sy_calloc(n ? n : 1, sizeof *fit, err, "novelty");
    int *fold = sy_calloc(n ? n : 1, sizeof *fold, err, "novelty");
    double *score = sy_calloc(n ? n : 1, sizeof *score, err, "novelty");
    sy_code rc = SY_OK;
    if (!perm || !fit || !fold || !score) {
        rc = err->code;
        goto done;
    }
    m->nov_threshold = 0;
    if (folds >= 2 && n >= (size_t)folds) {
        /* Stratified folds: per species a seeded shuffle dealt round-robin. */
        uint64_t rs = seed ^ 0x4E6F76656C747921ull;
        sy_permutation(perm, n, &rs);
        size_t dealt[SY_JB_MAX_CLASSES] = {0};
        for (size_t k = 0; k < n; k++) fold[perm[k]] = (int)(dealt[y[perm[k]]]++ % (size_t)folds);
        sy_jb_model tmp = *m;
        tmp.nov_center = tmp.nov_scale = tmp.nov_mean = tmp.nov_sd = NULL;
        for (int f = 0; f < folds; f++) {
            size_t nf = 0;
            for (size_t i = 0; i < n; i++)
                if (fold[i] != f) fit[nf++] = (uint32_t)i;
            if ((rc = sy_jb_novelty_fit(&tmp, X, y, fit, nf, err))) goto done;
            for (size_t i = 0; i < n; i++)
                if (fold[i] == f) score[i] = sy_jb_novelty_score(&tmp, X + i * m->n_features);
        }
        novelty_arrays_free(&tmp);
        qsort(score, n, sizeof *score, cmp_d);
        double pos = q * (double)(n - 1);
        size_t i = (size_t)pos;
        double t = pos - (double)i;
        double qs = i + 1 < n ? score[i] * (1 - t) + score[i + 1] * t : score[n - 1];
        m->nov_threshold = factor * qs;
    }
    for (size_t i = 0; i < n; i++) fit[i] = (uint32_t)i;
    rc = sy_jb_novelty_fit(m, X, y, fit, n, err);
done:
    free(perm), free(fit), free(fold), free(score);
    return rc;
}
