/* Plots in a batch: an input that holds several trees (the segment stage's
 * sy_segment_is_plot) is segmented once, in a worker, into one cloud per
 * tree (OUTDIR/plots/ID/ID_tNNN.las) and a plot record (OUTDIR/plots/ID.json,
 * committed last, with the input's content hash); the batch then runs those
 * trees like any single-tree input, placed at their stems. A rerun reads
 * the record instead of segmenting again while the input is unchanged. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "pipeline/batch.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/json_read.h"
#include "stages/core/progress.h"
#include "stages/ingest/ingest.h"
#include "stages/segment/segment.h"

/* What the plot record is keyed on besides the input bytes. */
static uint64_t segment_key(const sy_batch_options *o)
{
    char t[256];
    snprintf(t, sizeof t, "sylva %s segment 1 seed %llu", SYLVA_VERSION, (unsigned long long)o->run.seed);
    return sy_batch_hash(t, strlen(t));
}

static void plot_record_path(char *buf, size_t size, const char *out_dir, const char *id)
{
    snprintf(buf, size, "%s/plots/%s.json", out_dir, id);
}

/* The plot record of in when it is current (same input bytes and key), else NULL. */
static sy_jv *current_record(const sy_batch_input *in, const char *out_dir, uint64_t input_hash, uint64_t key)
{
    char path[8192];
    plot_record_path(path, sizeof path, out_dir, in->id);
    sy_jv *r;
    sy_error e = {0};
    if (access(path, F_OK) || sy_jv_parse_file(path, &r, &e)) return NULL;
    char h[20], k[20];
    snprintf(h, sizeof h, "%016llx", (unsigned long long)input_hash);
    snprintf(k, sizeof k, "%016llx", (unsigned long long)key);
    const char *rh = sy_jv_string(sy_jv_get(r, "input_hash")), *rk = sy_jv_string(sy_jv_get(r, "segment_hash"));
    if (!input_hash || !rh || !rk || strcmp(rh, h) || strcmp(rk, k)) {
        sy_jv_free(r);
        return NULL;
    }
    return r;
}

/* In the worker: read, judge, segment, write the trees and the record. */
static sy_code inspect(const sy_batch_input *in, const char *out_dir, const sy_batch_options *o, sy_error *err)
{
    sy_buffer b;
    sy_code rc = sy_read_file(in->path, &b, err);
    if (rc) return rc;
    uint64_t h = sy_batch_hash(b.data, b.size);
    sy_buffer_free(&b);
    sy_cloud c;
    if ((rc = sy_read_cloud(in->path, &c, err))) return rc;
    sy_segment_options so = sy_segment_options_default();
    so.seed = o->run.seed;
    double t0 = sy_now();
    int plot = sy_segment_is_plot(&c, &so);
    sy_segmentation s;
    memset(&s, 0, sizeof s);
    if (plot && (rc = sy_segment(&c, &so, &s, err))) {
        sy_cloud_free(&c);
        return rc;
    }
    char dir[8192];
    snprintf(dir, sizeof dir, "%s/plots/%s", out_dir, in->id);
    if (plot && mkdir(dir, 0755) && errno != EEXIST) rc = sy_fail(err, SY_EINPUT, "%s: cannot create: %s", dir, strerror(errno));
    size_t n_out = plot ? s.n_trees + 1 : 1;
    sy_staged_output *st = calloc(n_out, sizeof *st);
    if (!rc && !st) rc = sy_fail(err, SY_EINTERNAL, "batch: out of memory");
    for (size_t i = 0; plot && i < s.n_trees && !rc; i++) {
        char p[8400];
        snprintf(p, sizeof p, "%s/%s_t%03zu.las", dir, in->id, i + 1);
        sy_cloud t;
        if ((rc = sy_stage_output(&st[i], p, err))) break;
        if ((rc = sy_segmentation_tree_cloud(&c, &s, i, &t, err))) break;
        rc = sy_write_cloud(st[i].staged, &t, err);
        sy_cloud_free(&t);
    }
    sy_cloud_free(&c);
    char rec[8192];
    plot_record_path(rec, sizeof rec, out_dir, in->id);
    if (!rc) rc = sy_stage_output(&st[n_out - 1], rec, err);
    FILE *fp = rc ? NULL : fopen(st[n_out - 1].staged, "wb");
    if (!rc && !fp) rc = sy_fail(err, SY_EINPUT, "%s: cannot write: %s", rec, strerror(errno));
    if (!rc) {
        char hx[20], kx[20];
        snprintf(hx, sizeof hx, "%016llx", (unsigned long long)h);
        snprintf(kx, sizeof kx, "%016llx", (unsigned long long)segment_key(o));
        sy_json j;
        sy_json_begin(&j, fp, 1);
        sy_json_object(&j, NULL);
        sy_json_string(&j, "id", in->id);
        sy_json_string(&j, "input", in->path);
        sy_json_string(&j, "input_hash", hx);
        sy_json_string(&j, "segment_hash", kx);
        sy_json_string(&j, "kind", plot ? "plot" : "tree");
        if (plot) {
            sy_json_bool(&j, "airborne", s.airborne);
            sy_json_int(&j, "points", (long long)s.n_points);
            sy_json_int(&j, "ground", (long long)s.n_ground);
            sy_json_int(&j, "unassigned", (long long)s.n_unassigned);
            sy_json_array(&j, "trees");
            for (size_t i = 0; i < s.n_trees; i++) {
                const sy_segment_tree *t = &s.trees[i];
                char id[300], file[400];
                snprintf(id, sizeof id, "%s_t%03zu", in->id, i + 1);
                snprintf(file, sizeof file, "plots/%s/%s.las", in->id, id);
                sy_json_object(&j, NULL);
                sy_json_string(&j, "id", id);
                sy_json_string(&j, "file", file);
                sy_json_numbers(&j, "stem", t->stem, 3);
                sy_json_number(&j, "height", t->height);
                if (isfinite(t->dbh)) sy_json_number(&j, "dbh", t->dbh);
                sy_json_number(&j, "crown_width", t->crown_width);
                sy_json_int(&j, "points", (long long)t->n_points);
                sy_json_end(&j);
            }
            sy_json_end(&j);
        }
        sy_json_number(&j, "seconds", sy_now() - t0);
        sy_json_end(&j);
        sy_json_finish(&j);
        int bad = ferror(fp);
        if (fclose(fp) || bad) rc = sy_fail(err, SY_EINPUT, "%s: write failed", rec);
    }
    if (!rc) rc = sy_stage_commit(st, n_out, err);
    else if (st) sy_stage_abort(st, n_out);
    free(st);
    if (plot) sy_segmentation_free(&s);
    return rc;
}

/* The plot pool: the jobs, and which inputs' inspection a stop signal
 * ended (left out of this run; the next run inspects them). */
typedef struct {
    sy_batch_jobs jobs;
    unsigned char *stopped; /* per input */
} plot_pool;

static void plot_child(void *ctx, size_t job)
{
    const sy_batch_jobs *p = &((plot_pool *)ctx)->jobs;
    const sy_batch_input *in = &p->in->items[p->todo[job]];
    char log_id[300];
    snprintf(log_id, sizeof log_id, "%s.segment", in->id);
    sy_batch_worker_setup(p->out_dir, log_id, p->threads, 0, p->parent);
    sy_error err = {0};
    sy_code rc = inspect(in, p->out_dir, p->o, &err);
    if (rc) {
        /* The plot fails as one tree, with the error. */
        fprintf(stderr, "sylva batch: %s\n", err.msg);
        sy_error e2 = {0};
        sy_batch_record_failure(in, p->out_dir, p->o, p->hash[p->todo[job]], err.msg, 0, &e2);
    }
    fflush(NULL);
    _exit(rc);
}

static void plot_done(void *ctx, size_t job, int status, int timed_out, int interrupted, double secs)
{
    const sy_batch_jobs *p = &((plot_pool *)ctx)->jobs;
    const sy_batch_input *in = &p->in->items[p->todo[job]];
    if (interrupted) {
        /* Not judged: neither a failure nor a single tree this run (running
         * a plot whole as one tree would leave its output behind). */
        ((plot_pool *)ctx)->stopped[p->todo[job]] = 1;
        return;
    }
    if (!(WIFEXITED(status) && (WEXITSTATUS(status) == 0 || WEXITSTATUS(status) == SY_EINPUT)) || timed_out) {
        char why[256];
        sy_batch_death(status, timed_out, p->o->worker_timeout, why, sizeof why);
        char msg[400];
        snprintf(msg, sizeof msg, "segmenting: %s", why);
        sy_error e2 = {0};
        sy_batch_record_failure(in, p->out_dir, p->o, p->hash[p->todo[job]], msg, secs, &e2);
    }
    if (p->o->json) {
        sy_json j;
        sy_json_begin(&j, stdout, 0);
        sy_json_object(&j, NULL);
        sy_json_string(&j, "event", "inspected");
        sy_json_string(&j, "id", in->id);
        sy_json_number(&j, "seconds", secs);
        sy_json_end(&j);
        sy_json_finish(&j);
        fflush(stdout);
    }
}

static sy_code add_copy(sy_batch_inputs *out, const sy_batch_input *src, const char *path, const char *id,
                        const double *pos, size_t origin, sy_error *err)
{
    if (out->n == out->cap) {
        size_t cap = out->cap ? 2 * out->cap : 64;
        sy_batch_input *p = realloc(out->items, cap * sizeof *p);
        if (!p) return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
        out->items = p;
        out->cap = cap;
    }
    sy_batch_input *t = &out->items[out->n++];
    memset(t, 0, sizeof *t);
    t->path = strdup(path);
    t->id = strdup(id);
    t->species = src->species ? strdup(src->species) : NULL;
    t->label = src->label && !pos ? strdup(src->label) : NULL; /* a plot's label is no tree's */
    t->origin = origin;
    if (pos) t->has_position = 1, t->from_plot = 1, memcpy(t->position, pos, sizeof t->position);
    else if (src->has_position) t->has_position = 1, memcpy(t->position, src->position, sizeof t->position);
    if (!t->path || !t->id) return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
    return SY_OK;
}

sy_code sy_batch_expand(const sy_batch_inputs *in, const char *out_dir, const sy_batch_options *o, int segment_now,
                        sy_batch_inputs *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    size_t n = in->n;
    uint64_t *hash = calloc(n ? n : 1, sizeof *hash);
    size_t *todo = calloc(n ? n : 1, sizeof *todo), n_todo = 0;
    unsigned char *stopped = calloc(n ? n : 1, 1);
    if (!hash || !todo || !stopped) {
        free(hash);
        free(todo);
        free(stopped);
        return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
    }
    uint64_t key = segment_key(o);
    char dir[8192];
    snprintf(dir, sizeof dir, "%s/plots", out_dir);
    if (mkdir(dir, 0755) && errno != EEXIST) {
        free(hash);
        free(todo);
        free(stopped);
        return sy_fail(err, SY_EINPUT, "%s: cannot create: %s", dir, strerror(errno));
    }
    sy_code rc = SY_OK;
    for (size_t i = 0; i < n; i++) {
        int mine = !o->task_count || (int)(in->items[i].origin % (size_t)o->task_count) == o->task_index;
        sy_buffer b;
        sy_error e = {0};
        if (sy_read_file(in->items[i].path, &b, &e)) continue; /* the tree worker records the error */
        hash[i] = sy_batch_hash(b.data, b.size);
        sy_buffer_free(&b);
        sy_jv *r = current_record(&in->items[i], out_dir, hash[i], key);
        if (!r && segment_now && mine) todo[n_todo++] = i;
        sy_jv_free(r);
    }
    if (n_todo) {
        int nw = o->workers ? o->workers : (int)sysconf(_SC_NPROCESSORS_ONLN);
        if (nw < 1) nw = 1;
        if ((size_t)nw > n_todo) nw = (int)n_todo;
        int threads = o->threads ? o->threads : (int)sysconf(_SC_NPROCESSORS_ONLN) / nw;
        if (!o->quiet && !o->json) fprintf(stderr, "sylva batch: looking for plots in %zu input%s\n", n_todo, n_todo == 1 ? "" : "s");
        plot_pool pp = {{in, out_dir, o, todo, hash, threads < 1 ? 1 : threads, getpid()}, stopped};
        rc = sy_batch_pool(n_todo, nw, o->worker_timeout, plot_child, plot_done, &pp, err);
    }
    for (size_t i = 0; i < n && !rc; i++) {
        if (stopped[i]) continue;
        const sy_batch_input *src = &in->items[i];
        sy_jv *r = hash[i] ? current_record(src, out_dir, hash[i], key) : NULL;
        const char *kind = r ? sy_jv_string(sy_jv_get(r, "kind")) : NULL;
        const sy_jv *trees = r ? sy_jv_get(r, "trees") : NULL;
        if (!kind || strcmp(kind, "plot") || !trees || !sy_jv_count(trees)) {
            rc = add_copy(out, src, src->path, src->id, NULL, src->origin, err);
        } else {
            if (!o->quiet && !o->json && segment_now)
                fprintf(stderr, "sylva batch: %s: a plot of %zu trees\n", src->id, sy_jv_count(trees));
            for (size_t k = 0; k < sy_jv_count(trees) && !rc; k++) {
                const sy_jv *t = sy_jv_at(trees, k);
                const char *id = sy_jv_string(sy_jv_get(t, "id")), *file = sy_jv_string(sy_jv_get(t, "file"));
                const sy_jv *stem = sy_jv_get(t, "stem");
                double pos[3] = {0, 0, 0};
                for (size_t q = 0; q < 3 && stem && q < sy_jv_count(stem); q++) sy_jv_number(sy_jv_at(stem, q), &pos[q]);
                if (!id || !file) continue;
                char path[8400];
                snprintf(path, sizeof path, "%s/%s", out_dir, file);
                rc = add_copy(out, src, path, id, pos, src->origin, err);
            }
        }
        sy_jv_free(r);
    }
    free(hash);
    free(todo);
    free(stopped);
    if (rc) sy_batch_inputs_free(out);
    return rc;
}
