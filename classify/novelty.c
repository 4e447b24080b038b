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
 *
 * The planar-surface test beside it: at 0.3 and 0.6 m a tree's points are
 * linear (limbs) or scattered (foliage), a wall's or a roof's planar. The
 * joint distance dilutes that in 286 features (the AdTree house scored 0.4 of
 * the threshold, like a real airborne tree), but the house's mean planarity
 * at 0.6 m is 0.66 where no training tree passes 0.50 and the real trees lie
 * at 0.13-0.33. So per planarity feature (eigen_P_*): the training range and
 * robust spread; the score is the largest excess beyond a range in spreads,
 * its threshold calibrated by the same folds (held-out trees' excess, q and
 * factor as above).
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

double sy_jb_planar_score(const sy_jb_model *m, const float *x)
{
    double best = 0;
    for (size_t k = 0; k < m->n_planar; k++) {
        double v = x[m->planar_feature[k]], s = m->planar_s[k];
        if (v < 0) continue; /* -1: not measured (too few points in that part of the tree) */
        double e = fmax((v - m->planar_hi[k]) / s, (m->planar_lo[k] - v) / s);
        if (!isfinite(v)) e = INFINITY;
        if (e > best) best = e;
    }
    return best;
}

double sy_jb_novelty(const sy_jb_model *m, const float *x)
{
    double joint = m->nov_center && m->nov_threshold > 0 ? sy_jb_novelty_score(m, x) / m->nov_threshold : 0;
    double planar = m->n_planar && m->planar_threshold > 0 ? sy_jb_planar_score(m, x) / m->planar_threshold : 0;
    return fmax(joint, planar);
}

static void planar_free(sy_jb_model *m)
{
    free(m->planar_feature), free(m->planar_lo), free(m->planar_hi), free(m->planar_s);
    m->planar_feature = NULL, m->planar_lo = m->planar_hi = m->planar_s = NULL;
    m->n_planar = 0;
}

/* The planarity features of this build's feature vector. */
static size_t planar_features(const sy_jb_model *m, int32_t *out)
{
    size_t k = 0;
    if (m->features_version != SY_FEATURES_VERSION || m->n_features != sy_feature_count()) return 0;
    for (size_t f = 0; f < m->n_features; f++) {
        char name[SY_FEATURE_NAME_MAX];
        if (strncmp(sy_feature_name(f, name), "eigen_P_", 8) == 0) {
            if (out) out[k] = (int32_t)f;
            k++;
        }
    }
    return k;
}

/* Range and robust spread of the planar features over idx[0..n_idx), of the
 * measured values (planarity lies in [0, 1]; -1 is "not measured"). A feature
 * no training tree measured spans [0, 1]: it flags nothing. */
static sy_code planar_fit(sy_jb_model *m, const float *X, const uint32_t *idx, size_t n_idx, sy_error *err)
{
    size_t d = m->n_features, np = m->n_planar;
    float *v = sy_calloc(n_idx ? n_idx : 1, sizeof *v, err, "novelty");
    if (!v) return err->code;
    for (size_t k = 0; k < np; k++) {
        size_t nm = 0;
        for (size_t i = 0; i < n_idx; i++) {
            float x = X[(size_t)idx[i] * d + (size_t)m->planar_feature[k]];
            if (x >= 0) v[nm++] = x;
        }
        qsort(v, nm, sizeof *v, cmp_f);
        double s = nm ? ((double)v[(3 * (nm - 1)) / 4] - v[(nm - 1) / 4]) / 1.349 : 0;
        m->planar_lo[k] = nm ? v[0] : 0, m->planar_hi[k] = nm ? v[nm - 1] : 1;
        m->planar_s[k] = (float)(s > 1e-6 ? s : 1e-6);
    }
    free(v);
    return SY_OK;
}

sy_code sy_jb_planar_alloc(sy_jb_model *m, size_t n, sy_error *err)
{
    planar_free(m);
    if (!n) return SY_OK;
    m->planar_feature = sy_calloc(n, sizeof *m->planar_feature, err, "novelty");
    m->planar_lo = sy_calloc(n, sizeof *m->planar_lo, err, "novelty");
    m->planar_hi = sy_calloc(n, sizeof *m->planar_hi, err, "novelty");
    m->planar_s = sy_calloc(n, sizeof *m->planar_s, err, "novelty");
    if (!m->planar_feature || !m->planar_lo || !m->planar_hi || !m->planar_s) {
        planar_free(m);
        return err->code;
    }
    m->n_planar = n;
    return SY_OK;
}

static sy_code planar_alloc(sy_jb_model *m, sy_error *err)
{
    sy_code rc = sy_jb_planar_alloc(m, planar_features(m, NULL), err);
    if (!rc && m->n_planar) planar_features(m, m->planar_feature);
    return rc;
}

/* The q-quantile of v[0..n) (sorted here), linear between neighbours. */
static double quantile_of(double *v, size_t n, double q)
{
    qsort(v, n, sizeof *v, cmp_d);
    double pos = q * (double)(n - 1);
    size_t i = (size_t)pos;
    double t = pos - (double)i;
    return i + 1 < n ? v[i] * (1 - t) + v[i + 1] * t : v[n - 1];
}

sy_code sy_jb_novelty_train(sy_jb_model *m, const float *X, size_t n, const int *y, int folds, double q,
                            double factor, uint64_t seed, sy_error *err)
{
    uint32_t *perm = sy_calloc(n ? n : 1, sizeof *perm, err, "novelty");
    uint32_t *fit = sy_calloc(n ? n : 1, sizeof *fit, err, "novelty");
    int *fold = sy_calloc(n ? n : 1, sizeof *fold, err, "novelty");
    double *score = sy_calloc(n ? n : 1, sizeof *score, err, "novelty");
    double *pscore = sy_calloc(n ? n : 1, sizeof *pscore, err, "novelty");
    sy_code rc = SY_OK;
    if (!perm || !fit || !fold || !score || !pscore) {
        rc = err->code;
        goto done;
    }
    m->nov_threshold = 0;
    m->planar_threshold = 0;
    if ((rc = planar_alloc(m, err))) goto done;
    if (folds >= 2 && n >= (size_t)folds) {
        /* Stratified folds: per species a seeded shuffle dealt round-robin. */
        uint64_t rs = seed ^ 0x4E6F76656C747921ull;
        sy_permutation(perm, n, &rs);
        size_t dealt[SY_JB_MAX_CLASSES] = {0};
        for (size_t k = 0; k < n; k++) fold[perm[k]] = (int)(dealt[y[perm[k]]]++ % (size_t)folds);
        /* The folds' statistics go to a copy; the planar arrays are the
         * model's own (the ranges are refitted on everything below). */
        sy_jb_model tmp = *m;
        tmp.nov_center = tmp.nov_scale = tmp.nov_mean = tmp.nov_sd = NULL;
        for (int f = 0; f < folds; f++) {
            size_t nf = 0;
            for (size_t i = 0; i < n; i++)
                if (fold[i] != f) fit[nf++] = (uint32_t)i;
            if ((rc = sy_jb_novelty_fit(&tmp, X, y, fit, nf, err)) || (rc = planar_fit(m, X, fit, nf, err))) {
                novelty_arrays_free(&tmp);
                goto done;
            }
            for (size_t i = 0; i < n; i++)
                if (fold[i] == f) {
                    score[i] = sy_jb_novelty_score(&tmp, X + i * m->n_features);
                    pscore[i] = sy_jb_planar_score(m, X + i * m->n_features);
                }
        }
        novelty_arrays_free(&tmp);
        m->nov_threshold = factor * quantile_of(score, n, q);
        /* Held-out trees inside every fold's ranges score 0: a zero quantile
         * still leaves the test a margin of one spread. */
        m->planar_threshold = m->n_planar ? factor * fmax(quantile_of(pscore, n, q), 0.5) : 0;
    }
    for (size_t i = 0; i < n; i++) fit[i] = (uint32_t)i;
    rc = sy_jb_novelty_fit(m, X, y, fit, n, err);
    if (!rc && m->n_planar) rc = planar_fit(m, X, fit, n, err);
    if (!rc && !(m->planar_threshold > 0)) planar_free(m);
done:
    if (rc) planar_free(m);
    free(perm), free(fit), free(fold), free(score), free(pscore);
    return rc;
}
