/* Skeleton vs truth skeleton: both are cut into ~1 cm samples along their
 * edges; a truth sample is found when the model's axis passes within
 * max(2 r, 5 cm) of it, a model sample is precise when the truth's axis lies
 * within max(2 r_truth, 5 cm) of it (r_truth at the nearest truth point).
 * Weights are sample lengths, so both are branch-length weighted. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "eval.h"
#include "geometry.h"
#include "stages/core/parallel.h"
#include "stages/core/sort.h"

sy_skeleton_metrics_options sy_skeleton_metrics_options_default(void)
{
    sy_skeleton_metrics_options o = {0.01, 0.05, 2.0, 0.02, 0.25};
    return o;
}

sy_code sy_skeleton_metrics_options_check(const sy_skeleton_metrics_options *o, sy_error *err)
{
    if (!(o->sample_step > 0) || !isfinite(o->sample_step))
        return sy_fail(err, SY_EUSAGE, "skeleton metrics: sample_step %g must be > 0", o->sample_step);
    const struct {
        const char *name;
        double v;
    } at_least_0[] = {{"min_tolerance", o->min_tolerance},
                      {"radius_factor", o->radius_factor},
                      {"thick_radius", o->thick_radius},
                      {"bifurcation_radius", o->bifurcation_radius}};
    for (size_t i = 0; i < sizeof at_least_0 / sizeof *at_least_0; i++)
        if (!(at_least_0[i].v >= 0) || !isfinite(at_least_0[i].v))
            return sy_fail(err, SY_EUSAGE, "skeleton metrics: %s %g must be >= 0", at_least_0[i].name, at_least_0[i].v);
    return SY_OK;
}

/* Every edge of a forest in world coordinates. */
typedef struct {
    size_t n;
    double *a, *b;     /* 3n */
    float *ra, *rb;
    uint8_t *order;
    uint8_t *thick;    /* the edge's stem has base radius >= thick_radius */
    sy_bvh bvh;
} segments;

static void segments_free(segments *s)
{
    free(s->a);
    free(s->b);
    free(s->ra);
    free(s->rb);
    free(s->order);
    free(s->thick);
    sy_bvh_free(&s->bvh);
    memset(s, 0, sizeof *s);
}

static size_t edge_count(const sy_forest *f)
{
    size_t n = 0;
    for (size_t t = 0; t < f->n_trees; t++)
        for (size_t i = 0; i < f->trees[t].skel.n; i++) n += f->trees[t].skel.parent[i] >= 0;
    return n;
}

/* The largest radius on each stem stands for the stem's base radius. */
static float *stem_radii(const sy_skeleton *s, int32_t *n_stems)
{
    int32_t m = sy_skeleton_branch_count(s);
    float *r = calloc(m > 0 ? (size_t)m : 1, sizeof *r);
    if (!r) return NULL;
    for (size_t i = 0; i < s->n; i++)
        if (s->branch[i] >= 0 && s->radius[i] > r[s->branch[i]]) r[s->branch[i]] = s->radius[i];
    *n_stems = m;
    return r;
}

static double segment_prim_distance(const void *ctx, uint32_t i, const double q[3])
{
    const segments *s = ctx;
    return sy_point_segment_distance(q, s->a + 3 * i, s->b + 3 * i, NULL);
}

static sy_code segments_build(const sy_forest *f, double thick_radius, segments *s, sy_error *err)
{
    memset(s, 0, sizeof *s);
    size_t n = edge_count(f), k = 0;
    s->a = sy_calloc(n ? 3 * n : 1, sizeof(double), err, "skeleton edges");
    s->b = sy_calloc(n ? 3 * n : 1, sizeof(double), err, "skeleton edges");
    s->ra = sy_calloc(n ? n : 1, sizeof(float), err, "skeleton edges");
    s->rb = sy_calloc(n ? n : 1, sizeof(float), err, "skeleton edges");
    s->order = sy_calloc(n ? n : 1, 1, err, "skeleton edges");
    s->thick = sy_calloc(n ? n : 1, 1, err, "skeleton edges");
    sy_box *boxes = sy_calloc(n ? n : 1, sizeof *boxes, err, "skeleton edges");
    if (!s->a || !s->b || !s->ra || !s->rb || !s->order || !s->thick || !boxes) {
        free(boxes);
        segments_free(s);
        return SY_EINTERNAL;
    }
    for (size_t t = 0; t < f->n_trees; t++) {
        const sy_skeleton *sk = &f->trees[t].skel;
        int32_t n_stems = 0;
        float *stem_r = stem_radii(sk, &n_stems);
        if (!stem_r) {
            free(boxes);
            segments_free(s);
            return sy_fail(err, SY_EINTERNAL, "skeleton edges: out of memory");
        }
        for (size_t i = 0; i < sk->n; i++) {
            int32_t p = sk->parent[i];
            if (p < 0) continue;
            for (int c = 0; c < 3; c++) {
                s->a[3 * k + c] = sk->origin[c] + sk->pos[3 * p + c];
                s->b[3 * k + c] = sk->origin[c] + sk->pos[3 * i + c];
                boxes[k].lo[c] = fmin(s->a[3 * k + c], s->b[3 * k + c]);
                boxes[k].hi[c] = fmax(s->a[3 * k + c], s->b[3 * k + c]);
            }
            s->ra[k] = sk->radius[p];
            s->rb[k] = sk->radius[i];
            s->order[k] = sk->order[i] < SY_EVAL_ORDERS - 1 ? sk->order[i] : SY_EVAL_ORDERS - 1;
            int32_t br = sk->branch[i];
            s->thick[k] = br >= 0 && br < n_stems && stem_r[br] >= thick_radius;
            k++;
        }
        free(stem_r);
    }
    s->n = n;
    sy_code rc = sy_bvh_build(&s->bvh, boxes, n, err);
    free(boxes);
    if (rc) segments_free(s);
    return rc;
}

#define SKELETON_SAMPLES_FLOOR 1e5
#define SKELETON_SAMPLES_PER_EDGE 256.0
#define SKELETON_SAMPLES_MAX 2e7

/* Samples: k = ceil(len / step) per edge at sub-interval midpoints. */
static size_t samples_on(const segments *s, size_t i, double step)
{
    double d[3];
    for (int c = 0; c < 3; c++) d[c] = s->b[3 * i + c] - s->a[3 * i + c];
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    double k = ceil(len / step);
    return k < 1 ? 1 : k > 1e6 ? 1000000 : (size_t)k;
}

static double edge_length(const segments *s, size_t i)
{
    double d2 = 0;
    for (int c = 0; c < 3; c++) {
        double d = s->b[3 * i + c] - s->a[3 * i + c];
        d2 += d * d;
    }
    return sqrt(d2);
}

/* Per-sample result of matching one skeleton's samples against the other. */
typedef struct {
    const segments *from, *to;
    const sy_skeleton_metrics_options *o;
    const size_t *first; /* first sample index per edge of from */
    int tolerance_from_target; /* precision: tolerance uses the target's radius */
    uint8_t *hit;
    float *rel_radius;   /* recall: |r_to - r_from| / r_from where hit, else NaN */
    uint8_t *cls_order;  /* class of each sample (order, thick) for the breakdowns */
    uint8_t *cls_thick;
    float *weight;
} match_job;

static void match_chunk(void *arg, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    match_job *J = arg;
    const segments *F = J->from, *T = J->to;
    uint32_t prev = UINT32_MAX; /* consecutive samples have nearby answers */
    for (size_t e = begin; e < end; e++) {
        size_t k = samples_on(F, e, J->o->sample_step);
        double w = edge_length(F, e) / (double)k;
        for (size_t j = 0; j < k; j++) {
            size_t idx = J->first[e] + j;
            double u = ((double)j + 0.5) / (double)k, q[3];
            for (int c = 0; c < 3; c++) q[c] = F->a[3 * e + c] + u * (F->b[3 * e + c] - F->a[3 * e + c]);
            double r_from = F->ra[e] + u * (F->rb[e] - F->ra[e]), d, t;
            J->weight[idx] = (float)w;
            J->rel_radius[idx] = NAN;
            if (!J->tolerance_from_target) {
                double tol = fmax(J->o->radius_factor * r_from, J->o->min_tolerance);
                uint32_t hit = sy_bvh_nearest(&T->bvh, q, tol, segment_prim_distance, T, prev, &d);
                if (hit != UINT32_MAX) prev = hit;
                J->hit[idx] = hit != UINT32_MAX;
                J->cls_order[idx] = F->order[e];
                J->cls_thick[idx] = F->thick[e];
                if (hit != UINT32_MAX && r_from > 0) {
                    sy_point_segment_distance(q, T->a + 3 * hit, T->b + 3 * hit, &t);
                    double r_to = T->ra[hit] + t * (T->rb[hit] - T->ra[hit]);
                    J->rel_radius[idx] = (float)(fabs(r_to - r_from) / r_from);
                }
            } else {
                uint32_t hit = sy_bvh_nearest(&T->bvh, q, INFINITY, segment_prim_distance, T, prev, &d);
                J->hit[idx] = 0;
                J->cls_order[idx] = 0;
                J->cls_thick[idx] = 0;
                if (hit == UINT32_MAX) continue;
                prev = hit;
                sy_point_segment_distance(q, T->a + 3 * hit, T->b + 3 * hit, &t);
                double r_to = T->ra[hit] + t * (T->rb[hit] - T->ra[hit]);
                J->hit[idx] = d <= fmax(J->o->radius_factor * r_to, J->o->min_tolerance);
                J->cls_order[idx] = T->order[hit];
                J->cls_thick[idx] = T->thick[hit];
            }
        }
    }
}

/* Median of the non-NaN values among v[i] with keep(i); sorts a copy. */
static double median_where(const float *v, const uint8_t *cls, int want, size_t n)
{
    float *tmp = malloc((n ? n : 1) * sizeof *tmp);
    if (!tmp) return NAN;
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (!isnan(v[i]) && (want < 0 || cls[i] == want)) tmp[m++] = v[i];
    double med = NAN;
    if (m) {
        qsort(tmp, m, sizeof *tmp, sy_cmp_float);
        med = m % 2 ? tmp[m / 2] : 0.5 * ((double)tmp[m / 2 - 1] + tmp[m / 2]);
    }
    free(tmp);
    return med;
}

typedef struct {
    size_t n;
    uint8_t *hit, *cls_order, *cls_thick;
    float *rel_radius, *weight;
} sample_set;

static void sample_set_free(sample_set *s)
{
    free(s->hit);
    free(s->cls_order);
    free(s->cls_thick);
    free(s->rel_radius);
    free(s->weight);
}

/* Samples `from` against `to`. */
static sy_code match_samples(const segments *from, const segments *to, const sy_skeleton_metrics_options *o,
                             int tolerance_from_target, sample_set *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    size_t *first = sy_calloc(from->n + 1, sizeof *first, err, "skeleton samples");
    if (!first) return SY_EINTERNAL;
    for (size_t e = 0; e < from->n; e++) first[e + 1] = first[e] + samples_on(from, e, o->sample_step);
    size_t n = first[from->n];
    out->n = n;
    out->hit = sy_calloc(n ? n : 1, 1, err, "skeleton samples");
    out->cls_order = sy_calloc(n ? n : 1, 1, err, "skeleton samples");
    out->cls_thick = sy_calloc(n ? n : 1, 1, err, "skeleton samples");
    out->rel_radius = sy_calloc(n ? n : 1, sizeof(float), err, "skeleton samples");
    out->weight = sy_calloc(n ? n : 1, sizeof(float), err, "skeleton samples");
    if (!out->hit || !out->cls_order || !out->cls_thick || !out->rel_radius || !out->weight) {
        free(first);
        sample_set_free(out);
        return SY_EINTERNAL;
    }
    match_job J = {from, to, o, first, tolerance_from_target, out->hit, out->rel_radius, out->cls_order, out->cls_thick,
                   out->weight};
    sy_parallel_for(from->n, 256, match_chunk, &J);
    free(first);
    return SY_OK;
}

/* Weighted share of hits among samples of class want (-1: all). */
static double share(const sample_set *s, const uint8_t *cls, int want)
{
    double hit = 0, all = 0;
    for (size_t i = 0; i < s->n; i++) {
        if (want >= 0 && cls[i] != want) continue;
        all += s->weight[i];
        if (s->hit[i]) hit += s->weight[i];
    }
    return all > 0 ? hit / all : NAN;
}

static double total_weight(const sample_set *s)
{
    double w = 0;
    for (size_t i = 0; i < s->n; i++) w += s->weight[i];
    return w;
}

/* ---- branch points ---- */

typedef struct {
    size_t n;
    double *p; /* 3n */
} point_set;

static double point_prim_distance(const void *ctx, uint32_t i, const double q[3])
{
    const double *p = ((const point_set *)ctx)->p + 3 * i;
    double d0 = q[0] - p[0], d1 = q[1] - p[1], d2 = q[2] - p[2];
    return sqrt(d0 * d0 + d1 * d1 + d2 * d2);
}

/* Nodes with two or more children. */
static sy_code branch_points(const sy_forest *f, point_set *out, sy_error *err)
{
    size_t total = 0;
    for (size_t t = 0; t < f->n_trees; t++) total += f->trees[t].skel.n;
    out->n = 0;
    out->p = sy_calloc(total ? 3 * total : 1, sizeof(double), err, "branch points");
    if (!out->p) return SY_EINTERNAL;
    for (size_t t = 0; t < f->n_trees; t++) {
        const sy_skeleton *s = &f->trees[t].skel;
        uint32_t *kids = calloc(s->n ? s->n : 1, sizeof *kids);
        if (!kids) return sy_fail(err, SY_EINTERNAL, "branch points: out of memory");
        for (size_t i = 0; i < s->n; i++)
            if (s->parent[i] >= 0) kids[s->parent[i]]++;
        for (size_t i = 0; i < s->n; i++)
            if (kids[i] >= 2) {
                for (int c = 0; c < 3; c++) out->p[3 * out->n + c] = s->origin[c] + s->pos[3 * i + c];
                out->n++;
            }
        free(kids);
    }
    return SY_OK;
}

static sy_code bifurcation_errors(const sy_forest *truth, const sy_forest *model, double radius,
                                  sy_skeleton_metrics *m, sy_error *err)
{
    point_set T = {0}, M = {0};
    sy_bvh bvh = {0};
    sy_box *boxes = NULL;
    double *d = NULL;
    sy_code rc = branch_points(truth, &T, err);
    if (!rc) rc = branch_points(model, &M, err);
    if (!rc && !(boxes = sy_calloc(M.n ? M.n : 1, sizeof *boxes, err, "branch points"))) rc = SY_EINTERNAL;
    if (!rc && !(d = sy_calloc(T.n ? T.n : 1, sizeof *d, err, "branch points"))) rc = SY_EINTERNAL;
    if (!rc) {
        for (size_t i = 0; i < M.n; i++)
            for (int c = 0; c < 3; c++) boxes[i].lo[c] = boxes[i].hi[c] = M.p[3 * i + c];
        rc = sy_bvh_build(&bvh, boxes, M.n, err);
    }
    if (!rc) {
        size_t matched = 0;
        double sum = 0;
        for (size_t i = 0; i < T.n; i++) {
            double dist;
            if (sy_bvh_nearest(&bvh, T.p + 3 * i, radius, point_prim_distance, &M, UINT32_MAX, &dist) == UINT32_MAX) continue;
            d[matched++] = dist;
            sum += dist;
        }
        m->bifurcations_truth = T.n;
        m->bifurcations_matched = matched;
        m->bifurcation_error_mean = matched ? sum / (double)matched : NAN;
        qsort(d, matched, sizeof *d, sy_cmp_double);
        m->bifurcation_error_median = !matched ? NAN : matched % 2 ? d[matched / 2] : 0.5 * (d[matched / 2 - 1] + d[matched / 2]);
    }
    sy_bvh_free(&bvh);
    free(boxes);
    free(d);
    free(T.p);
    free(M.p);
    return rc;
}

/* ---- trees ---- */

/* Pairs each truth tree with a model tree: the only one when both hold one,
 * else the same tree_id, else the nearest trunk base within 1 m
 * horizontally. */
static void tree_errors(const sy_forest *truth, const sy_forest *model, sy_skeleton_metrics *m)
{
    double dbh_sum = 0, h_sum = 0;
    size_t dbh_n = 0, h_n = 0, matched = 0;
    m->trees_truth = truth->n_trees;
    for (size_t i = 0; i < truth->n_trees; i++) {
        const sy_eval_tree *t = &truth->trees[i], *best = NULL;
        if (truth->n_trees == 1 && model->n_trees == 1) best = &model->trees[0];
        for (size_t j = 0; !best && j < model->n_trees; j++)
            if (t->tree_id >= 0 && model->trees[j].tree_id == t->tree_id) best = &model->trees[j];
        double best_d = 1.0;
        for (size_t j = 0; !best && j < model->n_trees; j++) {
            const sy_eval_tree *c = &model->trees[j];
            double d = hypot(c->position[0] - t->position[0], c->position[1] - t->position[1]);
            if (d <= best_d) best_d = d, best = c;
        }
        if (!best) continue;
        matched++;
        if (isfinite(t->dbh) && isfinite(best->dbh)) dbh_sum += fabs(best->dbh - t->dbh), dbh_n++;
        if (isfinite(t->height) && isfinite(best->height)) h_sum += fabs(best->height - t->height), h_n++;
    }
    m->trees_matched = matched;
    m->dbh_error = dbh_n ? dbh_sum / (double)dbh_n : NAN;
    m->height_error = h_n ? h_sum / (double)h_n : NAN;
}

sy_code sy_skeleton_metrics_compute(const sy_forest *truth, const sy_forest *model, const sy_skeleton_metrics_options *opts,
                                    sy_skeleton_metrics *out, sy_error *err)
{
    sy_skeleton_metrics_options o = opts ? *opts : sy_skeleton_metrics_options_default();
    memset(out, 0, sizeof *out);
    sy_code checked = sy_skeleton_metrics_options_check(&o, err);
    if (checked) return checked;
    segments T, M;
    sy_code rc = segments_build(truth, o.thick_radius, &T, err);
    if (rc) return rc;
    if ((rc = segments_build(model, o.thick_radius, &M, err))) {
        segments_free(&T);
        return rc;
    }
    /* The cost follows the skeletons' size, never their extent: the step
     * widens so that each direction takes at most SKELETON_SAMPLES_FLOOR
     * samples (1 km of axes at 1 cm: any real tree, which spans at most
     * SY_SKELETON_MAX_SPAN) or SKELETON_SAMPLES_PER_EDGE per edge, whichever
     * is more, and never more than SKELETON_SAMPLES_MAX. A 20-node skeleton
     * with 300 m edges took 6e5 samples a direction before. */
    double len_t = 0, len_m = 0;
    for (size_t i = 0; i < T.n; i++) len_t += edge_length(&T, i);
    for (size_t i = 0; i < M.n; i++) len_m += edge_length(&M, i);
    double max_len = fmax(len_t, len_m);
    double budget = fmin(fmax(SKELETON_SAMPLES_FLOOR, SKELETON_SAMPLES_PER_EDGE * (double)(T.n > M.n ? T.n : M.n)),
                         SKELETON_SAMPLES_MAX);
    if (max_len / o.sample_step > budget) o.sample_step = max_len / budget;
    sample_set R, P;
    rc = match_samples(&T, &M, &o, 0, &R, err);
    if (!rc && (rc = match_samples(&M, &T, &o, 1, &P, err))) sample_set_free(&R);
    if (!rc) {
        out->truth_length = len_t;
        out->model_length = len_m;
        out->sample_step = o.sample_step;
        out->n_samples = R.n + P.n;
        out->recall = share(&R, R.cls_order, -1);
        out->precision = share(&P, P.cls_order, -1);
        out->recall_r2cm = share(&R, R.cls_thick, 1);
        out->precision_r2cm = share(&P, P.cls_thick, 1);
        for (int k = 0; k < SY_EVAL_ORDERS; k++) {
            out->recall_order[k] = share(&R, R.cls_order, k);
            out->precision_order[k] = share(&P, P.cls_order, k);
            out->radius_error_order[k] = median_where(R.rel_radius, R.cls_order, k, R.n);
        }
        out->radius_error_median = median_where(R.rel_radius, NULL, -1, R.n);
        if (total_weight(&R) <= 0) out->recall = NAN;
        if (total_weight(&P) <= 0) out->precision = NAN;
        sample_set_free(&R);
        sample_set_free(&P);
        rc = bifurcation_errors(truth, model, o.bifurcation_radius, out, err);
        tree_errors(truth, model, out);
    }
    segments_free(&T);
    segments_free(&M);
    return rc;
}
