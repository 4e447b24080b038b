/* The batch runner's driver: inputs (folders, files, manifests), the
 * resume decision per tree, the worker processes and the progress. The
 * worker's side is batch_tree.c, the batch products batch_report.c. */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <fcntl.h>

#include "pipeline/batch.h"
#include "stages/core/fileio.h"
#include "stages/core/hash.h"
#include "stages/core/json.h"
#include "stages/core/json_read.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"

#if defined(__SANITIZE_ADDRESS__)
#define SY_BATCH_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define SY_BATCH_ASAN 1
#endif
#endif

/* FNV-1a, 64 bit: the record's content and options hashes (a change
 * detector, not a defence against crafted collisions). */
uint64_t sy_batch_hash(const void *data, size_t size)
{
    return sy_fnv1a64(SY_FNV1A64_INIT, data, size);
}

sy_batch_options sy_batch_options_default(void)
{
    sy_batch_options o;
    memset(&o, 0, sizeof o);
    o.resume = 1;
    o.thumbnails = 1;
    o.thumb_size = 256;
    o.eval = 1;
    o.run = sy_run_tree_options_default();
    o.run.sylva = 1;
    o.vote = sy_vote_options_default();
    o.report = 1;
    return o;
}

sy_code sy_batch_options_check(const sy_batch_options *o, sy_error *err)
{
    if (o->workers < 0 || o->workers > 1024) return sy_fail(err, SY_EUSAGE, "workers: %d is not in [0, 1024]", o->workers);
    if (o->threads < 0 || o->threads > 1024) return sy_fail(err, SY_EUSAGE, "threads: %d is not in [0, 1024]", o->threads);
    if (o->thumb_size < 16 || o->thumb_size > 4096)
        return sy_fail(err, SY_EUSAGE, "thumb_size: %d is not in [16, 4096]", o->thumb_size);
    if (!(o->max_memory_gb >= 0) || o->max_memory_gb > 1e6)
        return sy_fail(err, SY_EUSAGE, "max_memory_gb: %g is not a size in GiB", o->max_memory_gb);
    if (!(o->worker_timeout >= 0)) return sy_fail(err, SY_EUSAGE, "worker_timeout: %g is negative", o->worker_timeout);
    if (o->task_count < 0 || (o->task_count && (o->task_index < 0 || o->task_index >= o->task_count)))
        return sy_fail(err, SY_EUSAGE, "task_index: %d is not in [0, %d)", o->task_index, o->task_count);
    sy_code rc = sy_run_tree_options_check(&o->run, err);
    if (rc) return rc;
    return sy_vote_options_check(&o->vote, err);
}

/* Everything that changes a tree's output bytes, as text: the record keeps
 * its hash, and a rerun with other options redoes the tree. */
char *sy_batch_options_text(const sy_batch_options *o, const sy_batch_input *in)
{
    const sy_run_tree_options *r = &o->run;
    const sy_tree_asset_options *a = &r->asset;
    char *buf = malloc(4096);
    if (!buf) return NULL;
    char asset[256];
    snprintf(asset, sizeof asset, "lods %d impostor %d/%d meshopt %d instancing %d texture %d check %d", a->lods,
             a->impostor, a->impostor_size, a->meshopt, a->instancing, a->texture_size, a->check);
    snprintf(buf, 4096,
             "sylva %s batch 1\nspecies=%s\nmodel=%s\nclassify=%d\nbeta=%.17g\ngamma=%.17g\nfs=%.17g\nwood_share=%.17g\n"
             "voxel=%.17g\nspread_around=%d\nkeep_hairpins=%d\nfair_sigma=%.17g\nproxy=%d\nlobe_size=%.17g\nseed=%llu\nasset=%s\nthumbnails=%d\n"
             "thumb_size=%d\neval=%d\nlabel=%s\nposition=%d,%.17g,%.17g,%.17g\n",
             SYLVA_VERSION, in && in->species ? in->species : (r->species ? r->species : ""), r->model ? r->model : "",
             r->classify, r->beta, r->gamma, r->fs, r->wood_share, r->voxel, r->spread_around, r->keep_hairpins,
             r->fair_sigma, r->proxy, r->lobe_size,
             (unsigned long long)r->seed, asset, o->thumbnails, o->thumb_size, o->eval,
             in && in->label ? in->label : "", in ? in->has_position : 0, in && in->has_position ? in->position[0] : 0,
             in && in->has_position ? in->position[1] : 0, in && in->has_position ? in->position[2] : 0);
    return buf;
}

/* ------------------------------------------------------------- inputs */

static char *dupstr(const char *s)
{
    if (!s) return NULL;
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d) memcpy(d, s, n);
    return d;
}

void sy_batch_inputs_free(sy_batch_inputs *in)
{
    for (size_t i = 0; i < in->n; i++) {
        free(in->items[i].path);
        free(in->items[i].id);
        free(in->items[i].species);
        free(in->items[i].label);
    }
    free(in->items);
    memset(in, 0, sizeof *in);
}

static sy_code add_input(sy_batch_inputs *in, const char *path, const char *species, const char *label,
                         const double *pos, sy_error *err)
{
    if (in->n == in->cap) {
        size_t cap = in->cap ? 2 * in->cap : 16;
        sy_batch_input *p = realloc(in->items, cap * sizeof *p);
        if (!p) return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
        in->items = p;
        in->cap = cap;
    }
    sy_batch_input *t = &in->items[in->n];
    memset(t, 0, sizeof *t);
    t->path = dupstr(path);
    t->species = species && *species ? dupstr(species) : NULL;
    t->label = label && *label ? dupstr(label) : NULL;
    if (pos) {
        t->has_position = 1;
        memcpy(t->position, pos, sizeof t->position);
    }
    in->n++;
    if (!t->path || (species && *species && !t->species) || (label && *label && !t->label))
        return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
    return SY_OK;
}

static int cloud_extension(const char *name)
{
    static const char *const exts[] = {"las", "laz", "ply", "pcd", "xyz", "txt"};
    char ext[16];
    sy_extension(name, ext, sizeof ext);
    for (size_t i = 0; i < sizeof exts / sizeof *exts; i++)
        if (strcmp(ext, exts[i]) == 0) return 1;
    return 0;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

static sy_code add_folder(sy_batch_inputs *in, const char *dir, sy_error *err)
{
    DIR *d = opendir(dir);
    if (!d) return sy_fail(err, SY_EINPUT, "%s: cannot read the folder: %s", dir, strerror(errno));
    char **names = NULL;
    size_t n = 0, cap = 0;
    sy_code rc = SY_OK;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.' || !cloud_extension(e->d_name)) continue;
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            char **p = realloc(names, cap * sizeof *p);
            if (!p) {
                rc = sy_fail(err, SY_EINTERNAL, "batch: out of memory");
                break;
            }
            names = p;
        }
        if (!(names[n] = dupstr(e->d_name))) {
            rc = sy_fail(err, SY_EINTERNAL, "batch: out of memory");
            break;
        }
        n++;
    }
    closedir(d);
    if (!rc && n) qsort(names, n, sizeof *names, cmp_str);
    for (size_t i = 0; i < n && !rc; i++) {
        char path[8192];
        snprintf(path, sizeof path, "%s%s%s", dir, dir[strlen(dir) - 1] == '/' ? "" : "/", names[i]);
        struct stat st;
        if (stat(path, &st) == 0 && S_ISREG(st.st_mode)) rc = add_input(in, path, NULL, NULL, NULL, err);
    }
    for (size_t i = 0; i < n; i++) free(names[i]);
    free(names);
    return rc;
}

/* A manifest's file, relative to the manifest's folder. */
static void manifest_path(const char *manifest, const char *file, char *out, size_t size)
{
    const char *slash = strrchr(manifest, '/');
    if (file[0] == '/' || !slash) snprintf(out, size, "%s", file);
    else snprintf(out, size, "%.*s/%s", (int)(slash - manifest), manifest, file);
}

/* One CSV line split into fields (double quotes, "" inside quotes); the
 * fields point into line, which is modified. Returns the count. */
static int csv_split(char *line, char **field, int max)
{
    int n = 0;
    char *p = line;
    while (n < max) {
        while (*p == ' ' || *p == '\t') p++;
        char *out = p;
        field[n++] = p;
        if (*p == '"') {
            char *r = p + 1;
            for (; *r; r++) {
                if (*r == '"') {
                    if (r[1] == '"') *out++ = '"', r++;
                    else {
                        r++;
                        break;
                    }
                } else *out++ = *r;
            }
            while (*r && *r != ',') r++;
            int more = *r == ',';
            *out = 0;
            if (!more) break;
            p = r + 1;
        } else {
            char *c = strchr(p, ',');
            char *end = c ? c : p + strlen(p);
            while (end > p && (end[-1] == ' ' || end[-1] == '\t' || end[-1] == '\r')) end--;
            int more = c != NULL;
            *end = 0;
            if (!more) break;
            p = c + 1;
        }
    }
    return n;
}

static int csv_manifest_header(const char *text)
{
    /* A manifest's first non-comment line names a "file" column. */
    while (*text == '#') {
        const char *nl = strchr(text, '\n');
        if (!nl) return 0;
        text = nl + 1;
    }
    char line[1024];
    size_t k = 0;
    while (text[k] && text[k] != '\n' && k + 1 < sizeof line) line[k] = text[k], k++;
    line[k] = 0;
    char *f[32];
    int n = csv_split(line, f, 32);
    for (int i = 0; i < n; i++)
        if (strcmp(f[i], "file") == 0 || strcmp(f[i], "path") == 0) return 1;
    return 0;
}

static int parse_double(const char *s, double *v)
{
    char *end;
    errno = 0;
    *v = strtod(s, &end);
    while (*end == ' ' || *end == '\r') end++;
    return end != s && !*end && errno == 0 && isfinite(*v);
}

static sy_code add_csv_manifest(sy_batch_inputs *in, const char *path, char *text, sy_error *err)
{
    int col_file = -1, col_species = -1, col_label = -1, col_x = -1, col_y = -1, col_z = -1, header = 0;
    int line_no = 0;
    for (char *line = text, *next; line && *line; line = next) {
        line_no++;
        next = strchr(line, '\n');
        if (next) *next++ = 0;
        size_t len = strlen(line);
        if (len && line[len - 1] == '\r') line[--len] = 0;
        if (!len || line[0] == '#') continue;
        char *f[32];
        int n = csv_split(line, f, 32);
        if (!header) {
            for (int i = 0; i < n; i++) {
                if (!strcmp(f[i], "file") || !strcmp(f[i], "path")) col_file = i;
                else if (!strcmp(f[i], "species")) col_species = i;
                else if (!strcmp(f[i], "label")) col_label = i;
                else if (!strcmp(f[i], "x")) col_x = i;
                else if (!strcmp(f[i], "y")) col_y = i;
                else if (!strcmp(f[i], "z")) col_z = i;
            }
            if (col_file < 0) return sy_fail(err, SY_EINPUT, "%s:%d: the header names no \"file\" column", path, line_no);
            if ((col_x < 0) != (col_y < 0))
                return sy_fail(err, SY_EINPUT, "%s:%d: a position needs both \"x\" and \"y\" columns", path, line_no);
            header = 1;
            continue;
        }
        if (col_file >= n || !*f[col_file]) return sy_fail(err, SY_EINPUT, "%s:%d: no file named", path, line_no);
        double pos[3] = {0, 0, 0};
        int have_pos = 0;
        if (col_x >= 0 && col_x < n && col_y < n && *f[col_x]) {
            if (!parse_double(f[col_x], &pos[0]) || !parse_double(f[col_y], &pos[1]) ||
                (col_z >= 0 && col_z < n && *f[col_z] && !parse_double(f[col_z], &pos[2])))
                return sy_fail(err, SY_EINPUT, "%s:%d: the position is not a number", path, line_no);
            have_pos = 1;
        }
        char file[8192];
        manifest_path(path, f[col_file], file, sizeof file);
        sy_code rc = add_input(in, file, col_species >= 0 && col_species < n ? f[col_species] : NULL,
                               col_label >= 0 && col_label < n ? f[col_label] : NULL, have_pos ? pos : NULL, err);
        if (rc) return rc;
    }
    if (!header) return sy_fail(err, SY_EINPUT, "%s: an empty manifest", path);
    return SY_OK;
}

static sy_code add_json_manifest(sy_batch_inputs *in, const char *path, sy_error *err)
{
    sy_jv *root;
    sy_code rc = sy_jv_parse_file(path, &root, err);
    if (rc) return rc;
    const sy_jv *list = root->type == SY_JV_OBJECT ? sy_jv_get(root, "trees") : root;
    if (!list || list->type != SY_JV_ARRAY) {
        sy_jv_free(root);
        return sy_fail(err, SY_EINPUT, "%s: a manifest is an array of trees (or {\"trees\": [...]})", path);
    }
    for (size_t i = 0; i < sy_jv_count(list) && !rc; i++) {
        const sy_jv *t = sy_jv_at(list, i);
        const char *file = t->type == SY_JV_STRING ? t->str : sy_jv_string(sy_jv_get(t, "file"));
        if (!file || !*file) {
            rc = sy_fail(err, SY_EINPUT, "%s:%d:%d: tree %zu names no \"file\"", path, t->line, t->col, i);
            break;
        }
        const char *species = t->type == SY_JV_OBJECT ? sy_jv_string(sy_jv_get(t, "species")) : NULL;
        const char *label = t->type == SY_JV_OBJECT ? sy_jv_string(sy_jv_get(t, "label")) : NULL;
        double pos[3] = {0, 0, 0};
        int have = 0;
        if (t->type == SY_JV_OBJECT) {
            const sy_jv *p = sy_jv_get(t, "position");
            if (p && p->type == SY_JV_ARRAY && (sy_jv_count(p) == 2 || sy_jv_count(p) == 3)) {
                have = 1;
                for (size_t k = 0; k < sy_jv_count(p); k++) have &= sy_jv_number(sy_jv_at(p, k), &pos[k]);
            } else if (sy_jv_get(t, "x") || sy_jv_get(t, "y")) {
                have = sy_jv_number(sy_jv_get(t, "x"), &pos[0]) && sy_jv_number(sy_jv_get(t, "y"), &pos[1]);
                if (have && sy_jv_get(t, "z")) have = sy_jv_number(sy_jv_get(t, "z"), &pos[2]);
            } else if (p) have = 0;
            if ((p || sy_jv_get(t, "x") || sy_jv_get(t, "y")) && !have) {
                rc = sy_fail(err, SY_EINPUT, "%s:%d:%d: tree %zu: the position is not [x, y] or [x, y, z] numbers", path,
                             t->line, t->col, i);
                break;
            }
        }
        char full[8192];
        manifest_path(path, file, full, sizeof full);
        rc = add_input(in, full, species, label, have ? pos : NULL, err);
    }
    sy_jv_free(root);
    return rc;
}

/* Unique ids: the file name without its extension, "-2", "-3"... for repeats. */
static sy_code assign_ids(sy_batch_inputs *in, sy_error *err)
{
    for (size_t i = 0; i < in->n; i++) {
        const char *base = strrchr(in->items[i].path, '/');
        base = base ? base + 1 : in->items[i].path;
        char id[256];
        snprintf(id, sizeof id, "%s", base);
        char *dot = strrchr(id, '.');
        if (dot && dot != id) *dot = 0;
        /* Ids become file names and HTML: keep them to a safe alphabet. */
        for (char *p = id; *p; p++)
            if (!((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') || *p == '-' ||
                  *p == '_' || *p == '.'))
                *p = '_';
        if (!id[0] || id[0] == '.') id[0] = '_';
        char unique[300];
        snprintf(unique, sizeof unique, "%s", id);
        for (int k = 2;; k++) {
            int clash = 0;
            for (size_t j = 0; j < i && !clash; j++) clash = strcmp(in->items[j].id, unique) == 0;
            if (!clash) break;
            snprintf(unique, sizeof unique, "%s-%d", id, k);
        }
        if (!(in->items[i].id = dupstr(unique))) return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
        in->items[i].origin = i;
    }
    return SY_OK;
}

sy_code sy_batch_inputs_collect(const char *const *args, size_t n, sy_batch_inputs *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_code rc = SY_OK;
    for (size_t i = 0; i < n && !rc; i++) {
        const char *a = args[i];
        struct stat st;
        if (stat(a, &st) != 0) {
            rc = sy_fail(err, SY_EINPUT, "%s: no such file or folder", a);
            break;
        }
        char ext[16];
        sy_extension(a, ext, sizeof ext);
        if (S_ISDIR(st.st_mode)) rc = add_folder(out, a, err);
        else if (strcmp(ext, "json") == 0) rc = add_json_manifest(out, a, err);
        else if (strcmp(ext, "csv") == 0) {
            sy_buffer b;
            if ((rc = sy_read_file(a, &b, err))) break;
            if (csv_manifest_header((const char *)b.data)) rc = add_csv_manifest(out, a, (char *)b.data, err);
            else rc = add_input(out, a, NULL, NULL, NULL, err);
            sy_buffer_free(&b);
        } else rc = add_input(out, a, NULL, NULL, NULL, err);
    }
    if (!rc && !out->n) rc = sy_fail(err, SY_EINPUT, "%s: no point-cloud files in the inputs", n ? args[0] : "batch");
    if (!rc) rc = assign_ids(out, err);
    if (rc) sy_batch_inputs_free(out);
    return rc;
}

/* ------------------------------------------------------------ resume */

typedef enum { JOB_TO_RUN, JOB_SKIP_OK, JOB_SKIP_FAILED } job_state;

/* What the record of in says about it: finished with this input and these options? */
static job_state record_state(const sy_batch_input *in, const char *out_dir, const sy_batch_options *o,
                              uint64_t input_hash)
{
    char path[8192];
    snprintf(path, sizeof path, "%s/trees/%s.json", out_dir, in->id);
    sy_jv *r;
    sy_error e = {0};
    if (access(path, F_OK) != 0 || sy_jv_parse_file(path, &r, &e)) return JOB_TO_RUN;
    char *opt = sy_batch_options_text(o, in);
    char want_in[32], want_opt[32];
    snprintf(want_in, sizeof want_in, "%016llx", (unsigned long long)input_hash);
    snprintf(want_opt, sizeof want_opt, "%016llx", opt ? (unsigned long long)sy_batch_hash(opt, strlen(opt)) : 0ull);
    free(opt);
    const char *hi = sy_jv_string(sy_jv_get(r, "input_hash")), *ho = sy_jv_string(sy_jv_get(r, "options_hash"));
    const char *st = sy_jv_string(sy_jv_get(r, "status"));
    job_state s = JOB_TO_RUN;
    if (hi && ho && st && !strcmp(hi, want_in) && !strcmp(ho, want_opt)) {
        if (!strcmp(st, "ok")) s = JOB_SKIP_OK;
        else if (!strcmp(st, "failed") && !o->retry_failed) s = JOB_SKIP_FAILED;
    }
    sy_jv_free(r);
    return s;
}

static uint64_t file_hash(const char *path, int *ok)
{
    sy_buffer b;
    sy_error e = {0};
    *ok = sy_read_file(path, &b, &e) == SY_OK;
    if (!*ok) return 0;
    uint64_t h = sy_batch_hash(b.data, b.size);
    sy_buffer_free(&b);
    return h;
}

/* ------------------------------------------------------------ workers */

typedef struct {
    pid_t pid;
    size_t job;
    double start;
    int timed_out;
} worker;

static int cores(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n > 0 ? (int)n : 1;
}

static void fmt_duration(double s, char *buf, size_t size)
{
    if (!(s >= 0) || s > 1e7) snprintf(buf, size, "--");
    else if (s < 60) snprintf(buf, size, "%.0fs", s);
    else if (s < 3600) snprintf(buf, size, "%dm%02ds", (int)s / 60, (int)s % 60);
    else snprintf(buf, size, "%dh%02dm", (int)s / 3600, ((int)s % 3600) / 60);
}

typedef struct {
    int tty, quiet, json;
    size_t total, finished, failed;
    double start;
    double work_seconds; /* sum of the finished trees' times (ETA) */
    size_t work_n;
} progress;

static void progress_draw(progress *p, int workers, const char *id, const char *status, double seconds)
{
    double elapsed = sy_now() - p->start;
    double eta = -1;
    if (p->finished && p->finished < p->total) eta = elapsed / (double)p->finished * (double)(p->total - p->finished);
    else if (p->finished == p->total) eta = 0;
    char e1[32], e2[32];
    fmt_duration(elapsed, e1, sizeof e1);
    fmt_duration(eta, e2, sizeof e2);
    if (p->json) {
        if (id) {
            sy_json j;
            sy_json_begin(&j, stdout, 0);
            sy_json_object(&j, NULL);
            sy_json_string(&j, "event", "tree");
            sy_json_string(&j, "id", id);
            sy_json_string(&j, "status", status);
            sy_json_number(&j, "seconds", seconds);
            sy_json_int(&j, "done", (long long)p->finished);
            sy_json_int(&j, "total", (long long)p->total);
            sy_json_number(&j, "eta_seconds", eta);
            sy_json_end(&j);
            sy_json_finish(&j);
            fflush(stdout);
        }
        return;
    }
    if (p->quiet) return;
    if (p->tty) {
        int width = 30, fill = p->total ? (int)(width * p->finished / p->total) : width;
        char bar[64];
        for (int i = 0; i < width; i++) bar[i] = i < fill ? '#' : '.';
        bar[width] = 0;
        fprintf(stderr, "\rsylva batch [%s] %zu/%zu trees, %zu failed, %d worker%s, %s elapsed, ETA %s   ", bar,
                p->finished, p->total, p->failed, workers, workers == 1 ? "" : "s", e1, e2);
        if (p->finished == p->total) fputc('\n', stderr);
    } else if (id) {
        fprintf(stderr, "sylva batch: [%zu/%zu] %s: %s (%.1f s), ETA %s\n", p->finished, p->total, id, status, seconds,
                e2);
    }
    fflush(stderr);
}

void sy_batch_worker_setup(const char *out_dir, const char *id, int threads, double mem_gb, pid_t parent)
{
    /* Die with the batch: a killed batch leaves no worker writing behind it. */
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (getppid() != parent) _exit(SY_EINTERNAL);
    /* The worker's stdout is not the batch's (--json events); its stderr goes to its log. */
    char log[8192];
    snprintf(log, sizeof log, "%s/logs/%s.log", out_dir, id);
    int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd >= 0) {
        dup2(fd, 2);
        close(fd);
    }
    int nul = open("/dev/null", O_WRONLY);
    if (nul >= 0) {
        dup2(nul, 1);
        close(nul);
    }
#ifndef SY_BATCH_ASAN
    if (mem_gb > 0) {
        struct rlimit rl;
        rl.rlim_cur = rl.rlim_max = (rlim_t)(mem_gb * 1073741824.0);
        setrlimit(RLIMIT_AS, &rl);
    }
#else
    (void)mem_gb;
#endif
    sy_set_threads(threads);
    sy_progress_set_quiet(1);
}

static const char *signal_name(int sig)
{
    switch (sig) {
    case SIGSEGV: return "segmentation fault";
    case SIGABRT: return "aborted";
    case SIGKILL: return "killed (out of memory, a timeout or by hand)";
    case SIGBUS: return "bus error";
    case SIGFPE: return "arithmetic exception";
    case SIGILL: return "illegal instruction";
    case SIGTERM: return "terminated";
    default: return "signal";
    }
}

static sy_code ensure_dir(const char *path, sy_error *err)
{
    if (mkdir(path, 0755) != 0 && errno != EEXIST)
        return sy_fail(err, SY_EINPUT, "%s: cannot create the folder: %s", path, strerror(errno));
    if (!sy_is_directory(path)) return sy_fail(err, SY_EINPUT, "%s: not a folder", path);
    return SY_OK;
}

sy_code sy_batch_prepare_dir(const char *out_dir, sy_error *err)
{
    char p[8192];
    sy_code rc = ensure_dir(out_dir, err);
    snprintf(p, sizeof p, "%s/trees", out_dir);
    if (!rc) rc = ensure_dir(p, err);
    snprintf(p, sizeof p, "%s/logs", out_dir);
    if (!rc) rc = ensure_dir(p, err);
    return rc;
}

/* Temp files of processes that no longer run (a batch or a worker killed
 * mid-write, or the viewer's own temp beside a worker's): the output rule
 * names them ".tmp.<pid>-<host tag>.<name>"; none of them is an output. */
static void sweep_temps(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (strncmp(e->d_name, ".tmp.", 5)) continue;
        long pid;
        int here;
        /* Another host's temp (a Slurm node writing into the same folder) is
         * that node's to judge: its pid means nothing here. */
        if (!sy_temp_owner(e->d_name + 5, &pid, &here, NULL) || !here) continue;
        if (!sy_process_gone(pid)) continue;
        char p[8500];
        if (snprintf(p, sizeof p, "%s/%s", dir, e->d_name) < (int)sizeof p) unlink(p);
    }
    closedir(d);
}

void sy_batch_sweep(const char *out_dir)
{
    static const char *const sub[] = {"", "/trees", "/report", "/slurm", "/slurm/done", "/plots"};
    char p[8300];
    for (size_t i = 0; i < sizeof sub / sizeof *sub; i++) {
        snprintf(p, sizeof p, "%s%s", out_dir, sub[i]);
        sweep_temps(p);
    }
    /* A plot's tree clouds: plots/ID/ID_tNNN.las, staged like any output. */
    snprintf(p, sizeof p, "%s/plots", out_dir);
    DIR *d = opendir(p);
    if (!d) return;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.') continue;
        char q[8600];
        if (snprintf(q, sizeof q, "%s/%s", p, e->d_name) < (int)sizeof q && sy_is_directory(q)) sweep_temps(q);
    }
    closedir(d);
}

/* What the worker's record of this attempt (this input and options) says, a
 * failure included; JOB_TO_RUN: it left none. */
static job_state attempt_record(const sy_batch_input *in, const char *out_dir, const sy_batch_options *o, uint64_t h)
{
    sy_batch_options any = *o;
    any.retry_failed = 0;
    return record_state(in, out_dir, &any, h);
}

void sy_batch_death(int status, int timed_out, double timeout, char *why, size_t size)
{
    if (timed_out) snprintf(why, size, "the worker took longer than %g s and was stopped", timeout);
    else if (WIFSIGNALED(status))
        snprintf(why, size, "the worker died: %s (signal %d)", signal_name(WTERMSIG(status)), WTERMSIG(status));
    else snprintf(why, size, "the worker exited with status %d", WEXITSTATUS(status));
}

int sy_batch_stop_signal(int sig) { return sig == SIGINT || sig == SIGTERM || sig == SIGHUP; }

_Noreturn void sy_batch_die_of(int sig)
{
    fflush(NULL);
    sigset_t one;
    sigemptyset(&one);
    sigaddset(&one, sig);
    signal(sig, SIG_DFL);
    sigprocmask(SIG_UNBLOCK, &one, NULL);
    raise(sig);
    _exit(128 + sig);
}

/* Signal sig has come (from sigtimedwait): a stop's first starts no more
 * workers and passes it to those running; a second kills them (a worker
 * stuck in a long step would otherwise hold the stop). */
static void take_signal(int sig, worker *w, int nw, int *stopped_by)
{
    if (!sy_batch_stop_signal(sig)) return;
    int second = *stopped_by != 0;
    if (!second) *stopped_by = sig;
    for (int k = 0; k < nw; k++)
        if (w[k].pid) kill(w[k].pid, second ? SIGKILL : sig);
}

/* The signals already pending, without waiting. */
static void take_pending(const sigset_t *set, worker *w, int nw, int *stopped_by)
{
    struct timespec now = {0, 0};
    int sig;
    while ((sig = sigtimedwait(set, NULL, &now)) > 0) take_signal(sig, w, nw, stopped_by);
}

sy_code sy_batch_pool(size_t n_jobs, int nw, double timeout, void (*child)(void *ctx, size_t job),
                      void (*done)(void *ctx, size_t job, int status, int timed_out, int interrupted, double seconds),
                      void *ctx, sy_error *err)
{
    worker *w = calloc((size_t)(nw > 0 ? nw : 1), sizeof *w);
    if (!w) return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
    /* The stop signals and SIGCHLD are taken with sigtimedwait, not by
     * handlers (no state outside this frame): a stop is seen between two
     * reaps, never in the middle of recording one. A stop signal set to be
     * ignored (nohup, a background job of a script) stays ignored: Linux
     * queues a blocked signal even then. Workers get the mask of before. */
    sigset_t wait_set, before;
    sigemptyset(&wait_set);
    const int stops[3] = {SIGINT, SIGTERM, SIGHUP};
    for (int q = 0; q < 3; q++) {
        struct sigaction sa;
        if (sigaction(stops[q], NULL, &sa) == 0 && sa.sa_handler != SIG_IGN) sigaddset(&wait_set, stops[q]);
    }
    sigaddset(&wait_set, SIGCHLD);
    sigprocmask(SIG_BLOCK, &wait_set, &before);
    size_t next = 0, running = 0;
    int stopped_by = 0;
    sy_code rc = SY_OK;
    fflush(NULL);
    while ((next < n_jobs && !stopped_by) || running) {
        take_pending(&wait_set, w, nw, &stopped_by);
        /* Fill the free slots. */
        for (int k = 0; k < nw && next < n_jobs && !stopped_by; k++) {
            if (w[k].pid) continue;
            size_t j = next++;
            pid_t pid = fork();
            if (pid < 0) {
                rc = sy_fail(err, SY_EINTERNAL, "batch: cannot start a worker: %s", strerror(errno));
                next = n_jobs;
                break;
            }
            if (pid == 0) {
                sigprocmask(SIG_SETMASK, &before, NULL);
                child(ctx, j);
                _exit(SY_EINTERNAL);
            }
            w[k].pid = pid;
            w[k].job = j;
            w[k].start = sy_now();
            w[k].timed_out = 0;
            running++;
        }
        if (!running || rc) break;
        int status;
        pid_t pid = waitpid(-1, &status, WNOHANG);
        if (pid < 0) {
            rc = sy_fail(err, SY_EINTERNAL, "batch: waiting for the workers: %s", strerror(errno));
            break;
        }
        if (pid > 0) {
            int k = 0;
            while (k < nw && w[k].pid != pid) k++;
            if (k == nw) continue;
            w[k].pid = 0;
            running--;
            /* A stop this process has been sent by now counts for this worker too. */
            take_pending(&wait_set, w, nw, &stopped_by);
            /* A worker ended by a stop signal (it may see it before this
             * process does), or unfinished after the stop, did not fail its
             * job: interrupted, 2 when the whole batch is stopping. */
            int ok = WIFEXITED(status) && WEXITSTATUS(status) == 0 && !w[k].timed_out;
            int interrupted = ok ? 0 : stopped_by ? 2 : WIFSIGNALED(status) && sy_batch_stop_signal(WTERMSIG(status)) ? 1 : 0;
            done(ctx, w[k].job, status, w[k].timed_out, interrupted, sy_now() - w[k].start);
            continue;
        }
        if (timeout > 0) {
            double now = sy_now();
            for (int k = 0; k < nw; k++)
                if (w[k].pid && !w[k].timed_out && now - w[k].start > timeout) {
                    kill(w[k].pid, SIGKILL);
                    w[k].timed_out = 1;
                }
        }
        struct timespec ts = {0, timeout > 0 ? 50000000 : 500000000};
        int sig = sigtimedwait(&wait_set, NULL, &ts);
        if (sig > 0) take_signal(sig, w, nw, &stopped_by);
    }
    if (rc) {
        /* A batch-level failure: stop the workers still running. */
        for (int k = 0; k < nw; k++)
            if (w[k].pid) kill(w[k].pid, SIGKILL), waitpid(w[k].pid, NULL, 0);
    }
    free(w);
    sigprocmask(SIG_SETMASK, &before, NULL);
    /* Every worker is reaped and what finished is recorded: now die of the
     * signal as the batch would have without this pool, so a shell or Slurm
     * sees the stop. */
    if (stopped_by) sy_batch_die_of(stopped_by);
    return rc;
}

typedef struct {
    sy_batch_jobs jobs;
    double mem_gb;
    sy_batch_summary *summary;
    progress *p;
    int nw;
} tree_pool;

static void tree_child(void *ctx, size_t job)
{
    tree_pool *t = ctx;
    const sy_batch_jobs *b = &t->jobs;
    const sy_batch_input *in = &b->in->items[b->todo[job]];
    sy_batch_worker_setup(b->out_dir, in->id, b->threads, t->mem_gb, b->parent);
    sy_error err = {0};
    sy_code rc = sy_batch_tree(in, b->out_dir, b->o, &err);
    if (rc) fprintf(stderr, "sylva batch: %s\n", err.msg);
    fflush(NULL);
    _exit(rc);
}

static void tree_done(void *ctx, size_t job, int status, int timed_out, int interrupted, double secs)
{
    tree_pool *t = ctx;
    const sy_batch_jobs *b = &t->jobs;
    size_t j = b->todo[job];
    const sy_batch_input *in = &b->in->items[j];
    const char *st = "ok";
    /* The worker may have committed its record before the signal came. */
    job_state rec = interrupted ? attempt_record(in, b->out_dir, b->o, b->hash[j]) : JOB_TO_RUN;
    if (interrupted && rec == JOB_TO_RUN) {
        /* Not the tree's failure: no record, so the next run makes it. */
        t->summary->interrupted++;
        st = "interrupted";
    } else if (interrupted) {
        if (rec == JOB_SKIP_OK) t->summary->done++;
        else t->summary->failed++, st = "failed";
    } else if (WIFEXITED(status) && WEXITSTATUS(status) == 0 && !timed_out) {
        t->summary->done++;
    } else {
        char why[256];
        sy_batch_death(status, timed_out, b->o->worker_timeout, why, sizeof why);
        /* Bad input is recorded by the worker itself; a death is recorded here. */
        if (attempt_record(in, b->out_dir, b->o, b->hash[j]) == JOB_TO_RUN || WIFSIGNALED(status) || timed_out) {
            sy_error e2 = {0};
            sy_batch_record_failure(in, b->out_dir, b->o, b->hash[j], why, secs, &e2);
        }
        t->summary->failed++;
        st = "failed";
    }
    t->p->finished++;
    t->p->failed = t->summary->failed;
    progress_draw(t->p, t->nw, in->id, st, secs);
}

sy_code sy_batch_run(const sy_batch_inputs *all, const char *out_dir, const sy_batch_options *o,
                     sy_batch_summary *summary, sy_error *err)
{
    memset(summary, 0, sizeof *summary);
    double t0 = sy_now();
    sy_code rc = sy_batch_prepare_dir(out_dir, err);
    if (rc) return rc;
    sy_batch_sweep(out_dir);
    /* Plots become their trees first. */
    sy_batch_inputs expanded;
    if ((rc = sy_batch_expand(all, out_dir, o, 1, &expanded, err))) return rc;
    const sy_batch_inputs *in = &expanded;
    size_t n = in->n;
    size_t *todo = calloc(n ? n : 1, sizeof *todo);
    uint64_t *hash = calloc(n ? n : 1, sizeof *hash);
    if (!todo || !hash) {
        free(todo);
        free(hash);
        sy_batch_inputs_free(&expanded);
        return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
    }
    /* Trees not run again (finished before, or failed when their input was
     * inspected) still get their one "tree" event after "start". */
    size_t *kept = calloc(n ? n : 1, sizeof *kept);
    unsigned char *kept_failed = calloc(n ? n : 1, 1);
    size_t n_kept = 0;
    if (!kept || !kept_failed) {
        free(kept);
        free(kept_failed);
        free(todo);
        free(hash);
        sy_batch_inputs_free(&expanded);
        return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
    }
    size_t n_todo = 0, mine = 0;
    for (size_t i = 0; i < n; i++) {
        if (o->task_count && (int)(in->items[i].origin % (size_t)o->task_count) != o->task_index) continue;
        mine++;
        int ok;
        hash[i] = file_hash(in->items[i].path, &ok);
        job_state s = o->resume && ok ? record_state(&in->items[i], out_dir, o, hash[i]) : JOB_TO_RUN;
        if (s == JOB_SKIP_OK) summary->skipped++;
        else if (s == JOB_SKIP_FAILED) summary->skipped++, summary->failed++;
        else todo[n_todo++] = i;
        if (s != JOB_TO_RUN) kept[n_kept] = i, kept_failed[n_kept++] = s == JOB_SKIP_FAILED;
    }
    summary->trees = mine;
    int nw = o->workers ? o->workers : cores();
    if ((size_t)nw > n_todo) nw = n_todo ? (int)n_todo : 1;
    int threads = o->threads ? o->threads : cores() / nw;
    if (threads < 1) threads = 1;
    double mem_gb = o->max_memory_gb;
    if (mem_gb == 0) {
        long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
        if (pages > 0 && page > 0) mem_gb = (double)pages * (double)page / 1073741824.0 / nw;
        if (mem_gb < 2) mem_gb = 2;
    }
    progress p = {isatty(2), o->quiet, o->json, mine, summary->skipped, summary->failed, sy_now(), 0, 0};
    if (o->json) {
        sy_json j;
        sy_json_begin(&j, stdout, 0);
        sy_json_object(&j, NULL);
        sy_json_string(&j, "event", "start");
        sy_json_int(&j, "trees", (long long)mine);
        sy_json_int(&j, "to_do", (long long)n_todo);
        sy_json_int(&j, "kept", (long long)summary->skipped);
        sy_json_int(&j, "workers", nw);
        sy_json_int(&j, "threads_per_worker", threads);
        sy_json_end(&j);
        sy_json_finish(&j);
        for (size_t k = 0; k < n_kept; k++) {
            sy_json_begin(&j, stdout, 0);
            sy_json_object(&j, NULL);
            sy_json_string(&j, "event", "tree");
            sy_json_string(&j, "id", in->items[kept[k]].id);
            sy_json_string(&j, "status", kept_failed[k] ? "failed" : "kept");
            sy_json_end(&j);
            sy_json_finish(&j);
        }
        fflush(stdout);
    } else if (!o->quiet) {
        fprintf(stderr, "sylva batch: %zu tree%s, %zu kept from before, %zu to do on %d worker%s x %d thread%s\n", mine,
                mine == 1 ? "" : "s", summary->skipped, n_todo, nw, nw == 1 ? "" : "s", threads, threads == 1 ? "" : "s");
    }
    tree_pool tp = {{in, out_dir, o, todo, hash, threads, getpid()}, mem_gb, summary, &p, nw};
    rc = sy_batch_pool(n_todo, nw, o->worker_timeout, tree_child, tree_done, &tp, err);
    if (!n_todo) progress_draw(&p, nw, NULL, NULL, 0);
    free(kept);
    free(kept_failed);
    free(todo);
    free(hash);
    summary->seconds = sy_now() - t0;
    /* Again at the end: a killed batch's workers may still have been
     * exiting when the sweep at the start looked at their temps. (Not in a
     * Slurm task: other tasks may be writing into out_dir right now.) */
    if (!o->task_count) sy_batch_sweep(out_dir);
    if (!rc && o->report && !o->task_count) rc = sy_batch_report(in, out_dir, o, err);
    else if (!rc && o->task_count) rc = sy_slurm_task_done(all, out_dir, o, err);
    sy_batch_inputs_free(&expanded);
    return rc;
}
