/* Individual-tree segmentation: instances are the point sets sharing a label
 * (0 and NaN: not a tree); a truth and a predicted instance match when their
 * IoU exceeds 0.5, which makes matches one-to-one. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "eval.h"
#include "geometry.h"
#include "stages/core/sort.h"

static int assigned(double v) { return !isnan(v) && v != 0; }

/* Sorted distinct assigned labels; returns their count. */
static size_t distinct(const double *v, size_t n, double *out)
{
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (assigned(v[i])) out[m++] = v[i];
    qsort(out, m, sizeof *out, sy_cmp_double);
    size_t k = 0;
    for (size_t i = 0; i < m; i++)
        if (k == 0 || out[i] != out[k - 1]) out[k++] = out[i];
    return k;
}

static size_t index_of(const double *sorted, size_t n, double v)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (sorted[mid] < v) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

sy_code sy_segmentation_metrics_labels(const double *truth, const double *pred, size_t n, sy_segmentation_metrics *out,
                                       sy_error *err)
{
    memset(out, 0, sizeof *out);
    out->n_points = n;
    double *tl = sy_calloc(n ? n : 1, sizeof *tl, err, "labels");
    double *pl = sy_calloc(n ? n : 1, sizeof *pl, err, "labels");
    uint64_t *pairs = sy_calloc(n ? n : 1, sizeof *pairs, err, "labels");
    size_t nt = 0, np = 0, *tsize = NULL, *psize = NULL;
    if (tl && pl && pairs) {
        nt = distinct(truth, n, tl);
        np = distinct(pred, n, pl);
        tsize = sy_calloc(nt ? nt : 1, sizeof *tsize, err, "labels");
        psize = sy_calloc(np ? np : 1, sizeof *psize, err, "labels");
    }
    if (!tsize || !psize) {
        free(tl), free(pl), free(pairs), free(tsize), free(psize);
        return SY_EINTERNAL;
    }
    size_t n_pairs = 0;
    for (size_t i = 0; i < n; i++) {
        int has_t = assigned(truth[i]), has_p = assigned(pred[i]);
        size_t ti = has_t ? index_of(tl, nt, truth[i]) : 0, pi = has_p ? index_of(pl, np, pred[i]) : 0;
        if (has_t) tsize[ti]++;
        if (has_p) psize[pi]++;
        if (has_t && has_p) pairs[n_pairs++] = (uint64_t)ti * (uint64_t)np + pi;
    }
    qsort(pairs, n_pairs, sizeof *pairs, sy_cmp_u64);
    double iou_sum = 0;
    /* pieces[ti]: predicted trees mostly inside truth ti; merged[pi]: truth trees mostly inside pi. */
    size_t *pieces = sy_calloc(nt ? nt : 1, sizeof *pieces, err, "labels");
    size_t *merged = sy_calloc(np ? np : 1, sizeof *merged, err, "labels");
    if (!pieces || !merged) {
        free(tl), free(pl), free(pairs), free(tsize), free(psize), free(pieces), free(merged);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < n_pairs;) {
        size_t j = i;
        while (j < n_pairs && pairs[j] == pairs[i]) j++;
        size_t inter = j - i, ti = (size_t)(pairs[i] / np), pi = (size_t)(pairs[i] % np);
        double iou = (double)inter / (double)(tsize[ti] + psize[pi] - inter);
        if (iou > 0.5) {
            out->n_matched++;
            iou_sum += iou;
        }
        if (2 * inter > psize[pi]) pieces[ti]++;
        if (2 * inter > tsize[ti]) merged[pi]++;
        i = j;
    }
    for (size_t t = 0; t < nt; t++) out->n_over_segmented += pieces[t] >= 2;
    for (size_t q = 0; q < np; q++) out->n_under_segmented += merged[q] >= 2;
    free(pieces), free(merged);
    out->n_truth = nt;
    out->n_pred = np;
    out->precision = np ? (double)out->n_matched / (double)np : NAN;
    out->recall = nt ? (double)out->n_matched / (double)nt : NAN;
    out->f1 = nt + np ? 2.0 * (double)out->n_matched / (double)(nt + np) : NAN;
    out->mean_iou = out->n_matched ? iou_sum / (double)out->n_matched : NAN;
    free(tl), free(pl), free(pairs), free(tsize), free(psize);
    return SY_OK;
}

/* The labels: an extra-bytes attribute or a standard field (classification, ...). */
static sy_code need_attr(const sy_cloud *c, const char *path, const char *attr, double **out, sy_error *err)
{
    sy_code rc = sy_cloud_scalar(c, attr, out, err);
    if (rc || *out) return rc;
    char names[512];
    sy_cloud_attribute_names(c, names, sizeof names);
    return sy_fail(err, SY_EINPUT, "%s: no attribute '%s' (has: %s)", path, attr, names);
}

static int same_points(const sy_cloud *a, const sy_cloud *b)
{
    if (a->n != b->n) return 0;
    for (size_t i = 0; i < a->n; i++)
        for (int k = 0; k < 3; k++)
            if (fabs((a->origin[k] + a->xyz[3 * i + k]) - (b->origin[k] + b->xyz[3 * i + k])) > 1e-4) return 0;
    return 1;
}

static double point_distance(const void *ctx, uint32_t i, const double q[3])
{
    const double *p = (const double *)ctx + 3 * (size_t)i;
    double a = q[0] - p[0], b = q[1] - p[1], c = q[2] - p[2];
    return sqrt(a * a + b * b + c * c);
}

/* Each truth point takes the label of the nearest prediction point within
 * match_dist, else 0; counts the unmatched. */
static sy_code transfer_labels(const sy_cloud *truth, const sy_cloud *pred, const double *plab, double match_dist,
                               double *out, size_t *unmatched, sy_error *err)
{
    double *pp = sy_cloud_world_points(pred, err), *tp = sy_cloud_world_points(truth, err);
    sy_box *boxes = sy_calloc(pred->n ? pred->n : 1, sizeof *boxes, err, "points");
    sy_bvh bvh;
    sy_code rc = pp && tp && boxes ? SY_OK : SY_EINTERNAL;
    if (!rc) {
        for (size_t i = 0; i < pred->n; i++)
            for (int k = 0; k < 3; k++) boxes[i].lo[k] = boxes[i].hi[k] = pp[3 * i + k];
        rc = sy_bvh_build(&bvh, boxes, pred->n, err);
    }
    if (!rc) {
        *unmatched = 0;
        uint32_t prev = UINT32_MAX;
        for (size_t i = 0; i < truth->n; i++) {
            double d;
            uint32_t j = sy_bvh_nearest(&bvh, tp + 3 * i, match_dist, point_distance, pp, prev, &d);
            if (j != UINT32_MAX) prev = j;
            out[i] = j == UINT32_MAX ? 0 : plab[j];
            *unmatched += j == UINT32_MAX;
        }
        sy_bvh_free(&bvh);
    }
    free(pp), free(tp), free(boxes);
    return rc;
}

sy_code sy_segmentation_metrics_clouds(const sy_cloud *truth, const char *truth_path, const char *truth_attr,
                                       const sy_cloud *pred, const char *pred_path, const char *pred_attr,
                                       double match_dist, sy_segmentation_metrics *out, sy_error *err)
{
    double *tlab = NULL, *plab = NULL, *moved = NULL;
    sy_code rc = need_attr(truth, truth_path, truth_attr, &tlab, err);
    if (!rc) rc = need_attr(pred, pred_path, pred_attr, &plab, err);
    if (!rc && same_points(truth, pred)) rc = sy_segmentation_metrics_labels(tlab, plab, truth->n, out, err);
    else if (!rc) {
        moved = sy_calloc(truth->n ? truth->n : 1, sizeof *moved, err, "labels");
        size_t unmatched = 0;
        rc = moved ? transfer_labels(truth, pred, plab, match_dist, moved, &unmatched, err) : SY_EINTERNAL;
        if (!rc) rc = sy_segmentation_metrics_labels(tlab, moved, truth->n, out, err);
        out->n_unmatched_points = unmatched;
    }
    free(tlab), free(plab), free(moved);
    return rc;
}
