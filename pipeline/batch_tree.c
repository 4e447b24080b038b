/* One tree of a batch, in its worker process: the run driver, the
 * classification, the metrics (DBH, height, crown width, wood volume), the
 * asset scored against its own points, a headless thumbnail, and every
 * output committed together with the record last (stages/core/fileio.h's
 * staged set), so a kill at any moment leaves the previous set or one
 * without its record, which the next run redoes. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "pipeline/batch.h"
#include "pipeline/commands.h"
#include "pipeline/tree_species.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/progress.h"
#include "stages/core/sort.h"
#include "stages/encode/encode.h"
#include "stages/eval/eval.h"
#include "stages/gltf/gltf_read.h"
#include "stages/ingest/ingest.h"
#include "stages/preprocess/preprocess.h"

static void hex64(uint64_t h, char *buf) { snprintf(buf, 17, "%016llx", (unsigned long long)h); }

static void record_head(sy_json *j, const sy_batch_input *in, const sy_batch_options *o, uint64_t input_hash)
{
    char h[17], ho[17];
    hex64(input_hash, h);
    char *opt = sy_batch_options_text(o, in);
    hex64(opt ? sy_batch_hash(opt, strlen(opt)) : 0, ho);
    free(opt);
    sy_json_string(j, "id", in->id);
    sy_json_string(j, "input", in->path);
    sy_json_string(j, "input_hash", h);
    sy_json_string(j, "options_hash", ho);
}

static void tree_path(char *buf, size_t size, const char *out_dir, const char *id, const char *ext)
{
    snprintf(buf, size, "%s/trees/%s%s", out_dir, id, ext);
}

static void remove_outputs(const char *out_dir, const char *id)
{
    static const char *const ext[] = {".glb", ".sylva", ".png", ".glb.js"};
    char p[8192];
    for (size_t i = 0; i < sizeof ext / sizeof *ext; i++) {
        tree_path(p, sizeof p, out_dir, id, ext[i]);
        unlink(p);
    }
}

sy_code sy_batch_record_failure(const sy_batch_input *in, const char *out_dir, const sy_batch_options *o,
                                uint64_t input_hash, const char *error, double seconds, sy_error *err)
{
    char path[8192];
    tree_path(path, sizeof path, out_dir, in->id, ".json");
    sy_atomic_file f;
    sy_code rc = sy_atomic_open(&f, path, err);
    if (rc) return rc;
    sy_json j;
    sy_json_begin(&j, f.fp, 1);
    sy_json_object(&j, NULL);
    record_head(&j, in, o, input_hash);
    sy_json_string(&j, "status", "failed");
    sy_json_string(&j, "error", error);
    if (in->label) sy_json_string(&j, "label", in->label);
    sy_json_object(&j, "seconds");
    sy_json_number(&j, "total", seconds);
    sy_json_end(&j);
    sy_json_end(&j);
    sy_json_finish(&j);
    rc = sy_atomic_commit(&f, err);
    /* The record says failed: whatever an earlier run made of this id goes. */
    if (!rc) remove_outputs(out_dir, in->id);
    return rc;
}

/* 5-95 % extent along x and y, averaged: the crown width as the silhouette
 * metric measures it (docs/eval.md). */
static double crown_width(const double *pts, size_t n)
{
    if (n < 10) return NAN;
    double *v = malloc(n * sizeof *v);
    if (!v) return NAN;
    double w = 0;
    for (int axis = 0; axis < 2; axis++) {
        for (size_t i = 0; i < n; i++) v[i] = pts[3 * i + axis];
        double hi = sy_select_double(v, n, (size_t)(0.95 * (double)(n - 1)));
        w += hi - sy_select_double(v, n, (size_t)(0.05 * (double)(n - 1)));
    }
    free(v);
    return w / 2;
}

/* Wood volume of the skeleton: each edge a truncated cone (frustum). */
static double skeleton_volume(const sy_skeleton *s)
{
    double v = 0;
    for (size_t i = 0; i < s->n; i++) {
        int32_t p = s->parent[i];
        if (p < 0) continue;
        double dx = s->pos[3 * i] - s->pos[3 * p], dy = s->pos[3 * i + 1] - s->pos[3 * p + 1],
               dz = s->pos[3 * i + 2] - s->pos[3 * p + 2];
        double l = sqrt(dx * dx + dy * dy + dz * dz), r1 = s->radius[p], r2 = s->radius[i];
        v += 3.14159265358979323846 / 3 * l * (r1 * r1 + r1 * r2 + r2 * r2);
    }
    return v;
}

/* The tree's base in world coordinates: the mean x, y of its lowest half
 * metre and the lowest z (LAS files are georeferenced; voting uses it). */
static void cloud_base(const sy_cloud *c, double out[3])
{
    float zmin = INFINITY;
    for (size_t i = 0; i < c->n; i++)
        if (c->xyz[3 * i + 2] < zmin) zmin = c->xyz[3 * i + 2];
    double sx = 0, sy = 0;
    size_t k = 0;
    for (size_t i = 0; i < c->n; i++)
        if (c->xyz[3 * i + 2] < zmin + 0.5f) sx += c->xyz[3 * i], sy += c->xyz[3 * i + 1], k++;
    out[0] = c->origin[0] + (k ? sx / (double)k : 0);
    out[1] = c->origin[1] + (k ? sy / (double)k : 0);
    out[2] = c->origin[2] + zmin;
}

static const char b64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

/* The glb as a classic script the report loads on demand: a page opened
 * from file:// may run scripts beside it but not fetch files. */
static sy_code write_glb_js(const char *path, const char *id, const unsigned char *d, size_t n, sy_error *err)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return sy_fail(err, SY_EINPUT, "%s: cannot write: %s", path, strerror(errno));
    fprintf(fp, "sylvaTree(\"%s\", \"", id);
    char q[4];
    for (size_t i = 0; i < n; i += 3) {
        unsigned v = (unsigned)d[i] << 16 | (i + 1 < n ? (unsigned)d[i + 1] << 8 : 0) | (i + 2 < n ? d[i + 2] : 0);
        q[0] = b64[v >> 18 & 63];
        q[1] = b64[v >> 12 & 63];
        q[2] = i + 1 < n ? b64[v >> 6 & 63] : '=';
        q[3] = i + 2 < n ? b64[v & 63] : '=';
        fwrite(q, 1, 4, fp);
    }
    fprintf(fp, "\");\n");
    int bad = ferror(fp);
    if (fclose(fp) || bad) return sy_fail(err, SY_EINPUT, "%s: write failed", path);
    return SY_OK;
}

/* The viewer's headless shot of the glb, as a subprocess (sylva itself
 * never links GL). Returns 1 with png written, or 0 with why filled. */
static int thumbnail(const sy_batch_options *o, const char *glb, const char *png, const char *log, char *why,
                     size_t why_size)
{
    char viewer[4096];
    if (o->viewer) snprintf(viewer, sizeof viewer, "%s", o->viewer);
    if (o->viewer ? access(viewer, X_OK) != 0 : !sy_find_viewer(viewer, sizeof viewer)) {
        snprintf(why, why_size, "no thumbnail: sylva-view is not installed (built with GLFW, epoxy and EGL)");
        return 0;
    }
    char size[64];
    snprintf(size, sizeof size, "%dx%d", o->thumb_size, o->thumb_size);
    fflush(NULL);
    pid_t worker = getpid();
    pid_t pid = fork();
    if (pid < 0) {
        snprintf(why, why_size, "no thumbnail: cannot start sylva-view: %s", strerror(errno));
        return 0;
    }
    if (pid == 0) {
        prctl(PR_SET_PDEATHSIG, SIGKILL); /* the viewer dies with its worker too */
        if (getppid() != worker) _exit(127); /* the worker died before prctl: no orphan writes behind it */
        int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) dup2(fd, 2), dup2(fd, 1), close(fd);
        char *args[] = {viewer, (char *)glb, "--screenshot", (char *)png, "--size", size, "--no-stats", NULL};
        execv(viewer, args);
        _exit(127);
    }
    int status = 0;
    double t0 = sy_now();
    for (;;) {
        pid_t r = waitpid(pid, &status, WNOHANG);
        if (r == pid) break;
        if (r < 0 && errno != EINTR) break;
        if (sy_now() - t0 > 600) {
            kill(pid, SIGKILL);
            waitpid(pid, &status, 0);
            snprintf(why, why_size, "no thumbnail: sylva-view took longer than 600 s");
            return 0;
        }
        struct timespec ts = {0, 20000000};
        nanosleep(&ts, NULL);
    }
    if (WIFEXITED(status) && WEXITSTATUS(status) == 0 && access(png, R_OK) == 0) return 1;
    /* The viewer was stopped with the batch (Ctrl-C, scancel), which stops
     * this worker too, before its record: the tree is not finished. */
    if (WIFSIGNALED(status) && sy_batch_stop_signal(WTERMSIG(status))) sy_batch_die_of(WTERMSIG(status));
    /* The viewer's last line says why. */
    char last[512] = "";
    FILE *fp = fopen(log, "r");
    if (fp) {
        char line[512];
        while (fgets(line, sizeof line, fp))
            if (line[0] != '\n') snprintf(last, sizeof last, "%s", line);
        fclose(fp);
    }
    size_t l = strlen(last);
    while (l && (last[l - 1] == '\n' || last[l - 1] == '\r')) last[--l] = 0;
    if (WIFSIGNALED(status)) snprintf(why, why_size, "no thumbnail: sylva-view died (signal %d)", WTERMSIG(status));
    else snprintf(why, why_size, "no thumbnail: sylva-view failed (exit %d)%s%s", WEXITSTATUS(status), l ? ": " : "", last);
    return 0;
}

typedef struct {
    int ok;
    sy_surface_metrics s;
    sy_silhouette_metrics sm;
} tree_eval;

/* The asset against the scan's above-ground points (as `sylva eval --points`). */
static sy_code score(const char *glb, const double *pts, size_t n, tree_eval *e, sy_error *err)
{
    double *tri;
    size_t k;
    sy_gltf_cutout cut;
    sy_code rc = sy_gltf_read_surface(glb, &tri, &k, &cut, err);
    if (rc) return rc;
    sy_eval_model m = {0};
    rc = sy_eval_model_add_mesh(&m, tri, k, 0, err);
    if (!rc) rc = sy_surface_metrics_compute(&m, pts, n, 0.02, 0.05, &e->s, err);
    if (!rc) rc = sy_silhouette_metrics_compute(tri, k, &cut, pts, NULL, n, &e->sm, NULL, err);
    sy_eval_model_free(&m);
    sy_gltf_cutout_free(&cut);
    free(tri);
    e->ok = rc == SY_OK;
    return rc;
}

static void num_or_null(sy_json *j, const char *key, double v)
{
    if (isfinite(v)) sy_json_number(j, key, v);
    else sy_json_null(j, key);
}

sy_code sy_batch_tree(const sy_batch_input *in, const char *out_dir, const sy_batch_options *o, sy_error *err)
{
    double t0 = sy_now();
    struct rusage ru0;
    getrusage(RUSAGE_SELF, &ru0);
    uint64_t h = 0;
    sy_buffer bytes;
    sy_code rc = sy_read_file(in->path, &bytes, err);
    if (!rc) {
        h = sy_batch_hash(bytes.data, bytes.size);
        sy_buffer_free(&bytes);
    }
    sy_cloud c, copy;
    memset(&c, 0, sizeof c);
    memset(&copy, 0, sizeof copy);
    if (!rc) rc = sy_read_cloud(in->path, &c, err);
    char ext[16];
    sy_extension(in->path, ext, sizeof ext);
    int georef = !strcmp(ext, "las") || !strcmp(ext, "laz");
    double position[3] = {NAN, NAN, NAN};
    const char *pos_source = NULL;
    char label_buf[64];
    const char *label = in->label;
    if (!rc) {
        if (in->has_position) memcpy(position, in->position, sizeof position), pos_source = in->from_plot ? "stem" : "manifest";
        else if (georef) cloud_base(&c, position), pos_source = "las";
        if (!label) label = sy_species_name_at(sy_cloud_majority_species(&c), label_buf, sizeof label_buf);
        rc = sy_cloud_copy(&copy, &c, err);
    }
    sy_run_tree_options run = o->run;
    run.on_step = NULL;
    run.sylva = 1;
    if (in->species) run.species = in->species;
    sy_run_tree_result res;
    memset(&res, 0, sizeof res);
    if (!rc) rc = sy_run_tree_cloud(&c, in->path, &run, &res, err);
    else sy_cloud_free(&c);
    if (rc) {
        sy_cloud_free(&copy);
        sy_error e2 = {0};
        sy_batch_record_failure(in, out_dir, o, h, err->msg, sy_now() - t0, &e2);
        return rc;
    }
    /* Stage the outputs; the record is the last of the set. */
    enum { S_GLB, S_SYLVA, S_JS, S_PNG, S_JSON, S_N };
    static const char *const exts[S_N] = {".glb", ".sylva", ".glb.js", ".png", ".json"};
    sy_staged_output st[S_N];
    size_t order[S_N], n_st = 0;
    for (int k = 0; k < S_N && !rc; k++) {
        char p[8192];
        tree_path(p, sizeof p, out_dir, in->id, exts[k]);
        rc = sy_stage_output(&st[k], p, err);
    }
    double t_write = sy_now();
    if (!rc) rc = sy_run_tree_write(&res, st[S_GLB].staged, st[S_SYLVA].staged, err);
    if (!rc) rc = write_glb_js(st[S_JS].staged, in->id, res.glb, res.glb_size, err);
    t_write = sy_now() - t_write;
    /* Metrics and scores from the preprocessed copy (ground removed, as eval does). */
    double volume = NAN, crown = NAN;
    tree_eval ev;
    memset(&ev, 0, sizeof ev);
    char eval_error[1100] = "";
    double t_eval = sy_now();
    if (!rc) {
        sy_skeleton sk;
        sy_clusters cl;
        sy_sylva_meta meta;
        memset(&sk, 0, sizeof sk);
        memset(&cl, 0, sizeof cl);
        sy_error e2 = {0};
        if (!sy_decode_mem(in->path, res.sylva, res.sylva_size, &sk, &cl, &meta, &e2)) {
            volume = skeleton_volume(&sk);
            sy_skeleton_free(&sk);
            sy_clusters_free(&cl);
        }
        sy_preprocess_options po = sy_preprocess_options_default();
        po.remove_ground = 1;
        po.normals = 0;
        sy_preprocess_result pr;
        double *pts = NULL;
        if (!sy_preprocess(&copy, &po, &pr, &e2)) pts = sy_cloud_world_points(&copy, &e2);
        if (pts) {
            crown = crown_width(pts, copy.n);
            if (o->eval && score(st[S_GLB].staged, pts, copy.n, &ev, &e2))
                snprintf(eval_error, sizeof eval_error, "%s", e2.msg);
        } else snprintf(eval_error, sizeof eval_error, "%s", e2.msg);
        free(pts);
    }
    sy_cloud_free(&copy);
    t_eval = sy_now() - t_eval;
    char why[1024] = "";
    int thumb = 0;
    double t_thumb = sy_now();
    if (!rc && o->thumbnails) {
        char log[8192];
        snprintf(log, sizeof log, "%s/logs/%s.view.log", out_dir, in->id);
        thumb = thumbnail(o, st[S_GLB].staged, st[S_PNG].staged, log, why, sizeof why);
    } else if (!o->thumbnails) snprintf(why, sizeof why, "no thumbnail: turned off (--no-thumbnails)");
    t_thumb = sy_now() - t_thumb;
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    /* The record. */
    FILE *fp = rc ? NULL : fopen(st[S_JSON].staged, "wb");
    if (!rc && !fp) rc = sy_fail(err, SY_EINPUT, "%s: cannot write: %s", st[S_JSON].staged, strerror(errno));
    if (!rc) {
        const sy_skeleton_report *sk = &res.skeleton;
        sy_json j;
        sy_json_begin(&j, fp, 1);
        sy_json_object(&j, NULL);
        record_head(&j, in, o, h);
        sy_json_string(&j, "status", "ok");
        if (label) sy_json_string(&j, "label", label);
        if (pos_source) {
            sy_json_numbers(&j, "position", position, 3);
            sy_json_string(&j, "position_source", pos_source);
        }
        sy_json_object(&j, "classification");
        if (in->species || o->run.species) {
            sy_json_string(&j, "species", run.species);
            sy_json_string(&j, "source", in->species ? "manifest" : "option");
        } else if (res.classified) {
            const sy_species_guess *g = &res.guess;
            sy_json_string(&j, "species", g->name);
            sy_json_string(&j, "source", "classifier");
            sy_json_string(&j, "best", g->best);
            sy_json_number(&j, "probability", g->probability);
            sy_json_bool(&j, "confident", g->confident);
            sy_json_bool(&j, "novel", g->novel);
            sy_json_number(&j, "novelty", g->novelty);
            sy_species_guess_rule_json(&j, g); /* a ruled-out species' probability below is 0 */
            double pv[256];
            size_t nc = g->species.n_classes < 256 ? g->species.n_classes : 256;
            for (size_t k = 0; k < nc; k++) pv[k] = g->species.probabilities[k];
            sy_json_numbers(&j, "probabilities", pv, (int)nc);
        } else {
            sy_json_string(&j, "species", "unknown");
            sy_json_string(&j, "source", "none");
        }
        sy_json_end(&j);
        sy_json_object(&j, "metrics");
        num_or_null(&j, "dbh", sk->dbh);
        sy_json_bool(&j, "dbh_fitted", sk->dbh_fitted);
        num_or_null(&j, "height", sk->height);
        num_or_null(&j, "crown_width", crown);
        num_or_null(&j, "volume", volume);
        sy_json_int(&j, "points_in", (long long)res.points_in);
        sy_json_int(&j, "points_clean", (long long)res.points_clean);
        sy_json_int(&j, "nodes", (long long)sk->nodes);
        sy_json_int(&j, "branches", (long long)sk->branches);
        sy_json_int(&j, "clusters", (long long)sk->clusters);
        sy_json_number(&j, "lobe_size", sk->lobe_size);
        sy_json_int(&j, "leaves", (long long)res.synth.leaves);
        sy_json_bool(&j, "leaf_off", res.leaf_off);
        num_or_null(&j, "returns_on_wood", res.returns_on_wood);
        sy_json_int(&j, "glb_bytes", (long long)res.glb_size);
        sy_json_int(&j, "sylva_bytes", (long long)res.sylva_size);
        sy_json_end(&j);
        if (ev.ok) {
            sy_json_object(&j, "eval");
            sy_json_number(&j, "mean_distance", ev.s.mean_distance);
            sy_json_number(&j, "rms_distance", ev.s.rms_distance);
            sy_json_number(&j, "p95_distance", ev.s.p95_distance);
            sy_json_number(&j, "coverage", ev.s.coverage);
            sy_json_number(&j, "hausdorff", ev.s.hausdorff);
            sy_json_number(&j, "iou_mean", ev.sm.iou_mean);
            sy_json_number(&j, "iou_min", ev.sm.iou_min);
            sy_json_number(&j, "silhouette_precision", ev.sm.precision);
            sy_json_number(&j, "silhouette_recall", ev.sm.recall);
            sy_json_number(&j, "profile_correlation", ev.sm.profile_correlation);
            sy_json_number(&j, "height_error_rel", ev.sm.height_error);
            sy_json_number(&j, "crown_width_error_rel", ev.sm.width_error);
            sy_json_end(&j);
        } else if (o->eval && eval_error[0]) sy_json_string(&j, "eval_error", eval_error);
        if (thumb) sy_json_bool(&j, "thumbnail", 1);
        else sy_json_string(&j, "thumbnail_error", why);
        sy_json_object(&j, "seconds");
        sy_json_number(&j, "ingest", res.t_ingest);
        sy_json_number(&j, "preprocess", res.t_preprocess);
        sy_json_number(&j, "skeleton", sk->t_total - sk->t_clusters);
        sy_json_number(&j, "clusters", sk->t_clusters + res.hulls.seconds);
        sy_json_number(&j, "classify", res.classified ? res.guess.seconds : 0);
        sy_json_number(&j, "synthesize", res.t_synth);
        sy_json_number(&j, "mesh", res.asset.seconds_mesh);
        sy_json_number(&j, "export", res.asset.seconds_export);
        sy_json_number(&j, "write", t_write);
        sy_json_number(&j, "eval", t_eval);
        sy_json_number(&j, "thumbnail", t_thumb);
        sy_json_number(&j, "total", sy_now() - t0);
        sy_json_number(&j, "cpu", (double)(ru.ru_utime.tv_sec - ru0.ru_utime.tv_sec + ru.ru_stime.tv_sec - ru0.ru_stime.tv_sec) +
                                      (double)(ru.ru_utime.tv_usec - ru0.ru_utime.tv_usec + ru.ru_stime.tv_usec - ru0.ru_stime.tv_usec) / 1e6);
        sy_json_end(&j);
        sy_json_int(&j, "peak_rss_kb", ru.ru_maxrss);
        sy_json_end(&j);
        sy_json_finish(&j);
        int bad = ferror(fp);
        if (fclose(fp) || bad) rc = sy_fail(err, SY_EINPUT, "%s: write failed", st[S_JSON].staged);
    }
    sy_run_tree_result_free(&res);
    if (rc) {
        sy_stage_abort(st, S_N);
        sy_error e2 = {0};
        sy_batch_record_failure(in, out_dir, o, h, err->msg, sy_now() - t0, &e2);
        return rc;
    }
    for (int k = 0; k < S_N; k++)
        if (k != S_PNG || thumb) order[n_st++] = (size_t)k;
    sy_staged_output commit[S_N];
    for (size_t k = 0; k < n_st; k++) commit[k] = st[order[k]];
    if (!thumb) sy_stage_abort(&st[S_PNG], 1);
    rc = sy_stage_commit(commit, n_st, err);
    if (!rc && !thumb) {
        char p[8192];
        tree_path(p, sizeof p, out_dir, in->id, ".png");
        unlink(p); /* an older run's picture is not this tree's */
    }
    return rc;
}
