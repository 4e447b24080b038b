#include "pipeline/tree_species.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "species/library.h"
#include "stages/core/fileio.h"
#include "stages/core/progress.h"
#include "stages/ingest/ingest.h"
#include "stages/preprocess/preprocess.h"

sy_code sy_classify_preprocess(sy_cloud *c, const char *path, double voxel, sy_error *err)
{
    sy_preprocess_options po = sy_preprocess_options_default();
    po.voxel = voxel;
    po.sor = 0;
    po.remove_ground = 1;
    po.normals = 0;
    sy_preprocess_result pr;
    sy_code rc = sy_preprocess(c, &po, &pr, err);
    if (rc) return rc;
    if (c->n < 32) return sy_fail(err, SY_EINPUT, "%s: %zu points left after removing the ground, too few for a tree", path, c->n);
    return SY_OK;
}

int sy_cloud_majority_species(const sy_cloud *c)
{
    const double *sid = sy_cloud_attr(c, "speciesID");
    if (!sid) return -1;
    size_t count[256] = {0};
    for (size_t i = 0; i < c->n; i++)
        if (sid[i] >= 0 && sid[i] < 256) count[(int)sid[i]]++;
    int best = -1;
    for (int k = 0; k < 256; k++)
        if (count[k] && (best < 0 || count[k] > count[best])) best = k;
    return best;
}

sy_code sy_scan_features(const char *path, const sy_features_options *fo, float *f, sy_scan_features_result *r,
                         sy_error *err)
{
    memset(r, 0, sizeof *r);
    sy_cloud c;
    sy_code rc = sy_read_cloud(path, &c, err);
    if (rc) return rc;
    int sid = sy_cloud_majority_species(&c);
    if (sid >= 0) sy_species_name_at(sid, r->label, sizeof r->label);
    r->georeferenced = strcmp(c.meta.format, "LAS") == 0;
    if ((rc = sy_classify_preprocess(&c, path, SY_CLASSIFY_VOXEL, err))) {
        sy_cloud_free(&c);
        return rc;
    }
    r->points_clean = c.n;
    rc = sy_features_compute(&c, fo, f, &r->info, err);
    if (rc && !strstr(err->msg, path)) {
        sy_error e2 = *err;
        sy_fail(err, rc, "%s: %s", path, e2.msg);
    }
    sy_cloud_free(&c);
    return rc;
}

const char *sy_species_name_at(int idx, char *buf, size_t size)
{
    sy_library lib;
    sy_error err = {0};
    if (idx < 0 || sy_library_load(NULL, &lib, &err)) return NULL;
    const sy_library_entry *e = sy_library_by_id(&lib, idx);
    const char *out = NULL;
    if (e) {
        snprintf(buf, size, "%s", e->name);
        out = buf;
    }
    sy_library_free(&lib);
    return out;
}

sy_code sy_default_model_path(char *path, size_t size, sy_error *err)
{
    char dir[4096];
    sy_code rc = sy_library_locate(dir, sizeof dir, err);
    if (rc) return rc;
    if ((size_t)snprintf(path, size, "%s/classifier.sjb", dir) >= size)
        return sy_fail(err, SY_EINTERNAL, "%s: path too long", dir);
    return SY_OK;
}

/* ------------------------------------------------------------ feature table */

void sy_feature_table_free(sy_feature_table *t)
{
    for (size_t i = 0; i < t->n; i++) free(t->file[i]), free(t->label[i]);
    free(t->file), free(t->label), free(t->spacing), free(t->points), free(t->x);
    memset(t, 0, sizeof *t);
}

sy_code sy_feature_table_add(sy_feature_table *t, const char *file, const char *label, double spacing, size_t points,
                             const float *x, size_t d, sy_error *err)
{
    if (t->n && d != t->d) return sy_fail(err, SY_EINPUT, "feature table: %zu features, the table has %zu", d, t->d);
    t->d = d;
    if (t->n == t->cap) {
        size_t nc = t->cap ? 2 * t->cap : 64;
        char **nf = realloc(t->file, nc * sizeof *nf);
        if (nf) t->file = nf;
        char **nl = realloc(t->label, nc * sizeof *nl);
        if (nl) t->label = nl;
        double *ns = realloc(t->spacing, nc * sizeof *ns);
        if (ns) t->spacing = ns;
        size_t *np = realloc(t->points, nc * sizeof *np);
        if (np) t->points = np;
        float *nx = realloc(t->x, nc * d * sizeof *nx);
        if (nx) t->x = nx;
        if (!nf || !nl || !ns || !np || !nx) return sy_fail(err, SY_EINTERNAL, "feature table: out of memory");
        t->cap = nc;
    }
    t->file[t->n] = strdup(file);
    t->label[t->n] = strdup(label ? label : "");
    if (!t->file[t->n] || !t->label[t->n]) {
        free(t->file[t->n]), free(t->label[t->n]);
        return sy_fail(err, SY_EINTERNAL, "feature table: out of memory");
    }
    t->spacing[t->n] = spacing;
    t->points[t->n] = points;
    memcpy(t->x + t->n * d, x, d * sizeof *x);
    t->n++;
    return SY_OK;
}

sy_code sy_feature_table_write(const sy_feature_table *t, const char *path, sy_error *err)
{
    sy_atomic_file af;
    sy_code rc = sy_atomic_open(&af, path, err);
    if (rc) return rc;
    fprintf(af.fp, "file\tlabel\tspacing\tpoints");
    for (size_t j = 0; j < t->d; j++) {
        char name[SY_FEATURE_NAME_MAX];
        fprintf(af.fp, "\t%s", sy_feature_name(j, name) ? name : "feature");
    }
    fprintf(af.fp, "\n");
    for (size_t i = 0; i < t->n; i++) {
        fprintf(af.fp, "%s\t%s\t%.6g\t%zu", t->file[i], t->label[i][0] ? t->label[i] : "-", t->spacing[i], t->points[i]);
        for (size_t j = 0; j < t->d; j++) fprintf(af.fp, "\t%.9g", t->x[i * t->d + j]);
        fprintf(af.fp, "\n");
    }
    return sy_atomic_commit(&af, err);
}

sy_code sy_feature_table_read(const char *path, sy_feature_table *t, sy_error *err)
{
    memset(t, 0, sizeof *t);
    sy_buffer b;
    sy_code rc = sy_read_file(path, &b, err);
    if (rc) return rc;
    char *text = (char *)b.data, *save = NULL;
    int line = 0;
    size_t d = 0;
    float *row = NULL;
    for (char *ln = strtok_r(text, "\n", &save); ln; ln = strtok_r(NULL, "\n", &save)) {
        line++;
        size_t L = strlen(ln);
        if (L && ln[L - 1] == '\r') ln[--L] = 0;
        if (line == 1) {
            if (strncmp(ln, "file\tlabel\tspacing\tpoints\t", 26) != 0) {
                rc = sy_fail(err, SY_EINPUT, "%s:1: not a feature table (header \"file label spacing points ...\")", path);
                break;
            }
            for (char *p = ln; *p; p++) d += *p == '\t';
            d -= 3;
            if (d != sy_feature_count()) {
                rc = sy_fail(err, SY_EINPUT, "%s:1: %zu features, this build computes %zu", path, d, sy_feature_count());
                break;
            }
            row = malloc(d * sizeof *row);
            if (!row) {
                rc = sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
                break;
            }
            continue;
        }
        char *f[4], *p = ln;
        int k;
        for (k = 0; k < 4; k++) {
            f[k] = p;
            p = strchr(p, '\t');
            if (!p) break;
            *p++ = 0;
        }
        if (k < 4) {
            rc = sy_fail(err, SY_EINPUT, "%s:%d: fewer than 4 + %zu columns", path, line, d);
            break;
        }
        size_t j = 0;
        for (; j < d && *p; j++) {
            char *e;
            double v = strtod(p, &e);
            if (e == p || (*e != '\t' && *e) || !isfinite(v)) break;
            row[j] = (float)v;
            p = *e ? e + 1 : e;
        }
        char *e;
        double sp = strtod(f[2], &e);
        long long pts = strtoll(f[3], NULL, 10);
        if (j != d || *p) {
            rc = sy_fail(err, SY_EINPUT, "%s:%d: expected %zu finite feature values", path, line, d);
            break;
        }
        if ((rc = sy_feature_table_add(t, f[0], strcmp(f[1], "-") ? f[1] : "", sp, pts > 0 ? (size_t)pts : 0, row, d, err)))
            break;
    }
    if (!rc && line == 0) rc = sy_fail(err, SY_EINPUT, "%s: empty feature table", path);
    free(row);
    sy_buffer_free(&b);
    if (rc) sy_feature_table_free(t);
    return rc;
}

static int cmp_cstr(const void *a, const void *b) { return strcmp(*(const char *const *)a, *(const char *const *)b); }

sy_code sy_feature_table_classes(const sy_feature_table *t, const char **names, size_t *n_classes, int *y, sy_error *err)
{
    size_t C = 0;
    for (size_t i = 0; i < t->n; i++) {
        if (!t->label[i][0]) return sy_fail(err, SY_EINPUT, "%s: no species label", t->file[i]);
        size_t c = 0;
        while (c < C && strcmp(names[c], t->label[i])) c++;
        if (c == C) {
            if (C == SY_JB_MAX_CLASSES) return sy_fail(err, SY_EINPUT, "more than %d species", SY_JB_MAX_CLASSES);
            names[C++] = t->label[i];
        }
    }
    qsort(names, C, sizeof *names, cmp_cstr);
    for (size_t i = 0; i < t->n; i++)
        for (size_t c = 0; c < C; c++)
            if (strcmp(names[c], t->label[i]) == 0) y[i] = (int)c;
    *n_classes = C;
    return SY_OK;
}

sy_code sy_classify_cloud(const sy_cloud *tree, const char *model_path, sy_species_guess *out, sy_error *err)
{
    double t0 = sy_now();
    memset(out, 0, sizeof *out);
    /* A tree of a few airborne returns (a plot's smallest) is too small to
     * classify, not bad input: it stays unknown and is reconstructed with
     * the default parameters, as a tree of no confident species is. */
    if (tree->n < SY_FEATURES_MIN_POINTS) {
        out->too_few = tree->n;
        snprintf(out->name, sizeof out->name, "unknown");
        snprintf(out->best, sizeof out->best, "unknown");
        sy_code r0 = sy_species_init(&out->species, 0, err);
        out->seconds = sy_now() - t0;
        return r0;
    }
    char def[4200];
    const char *mp = model_path;
    sy_code rc;
    if (!mp) {
        if ((rc = sy_default_model_path(def, sizeof def, err))) return rc;
        mp = def;
    }
    sy_jb_model m;
    rc = sy_jb_load(mp, &m, err);
    if (rc) return rc;
    size_t d = sy_feature_count();
    if (m.n_features != d || m.features_version != SY_FEATURES_VERSION) {
        sy_jb_model_free(&m);
        return sy_fail(err, SY_EINPUT, "%s: trained on %zu features of version %u, this build computes %zu of version %d (retrain it)",
                       mp, m.n_features, m.features_version, d, SY_FEATURES_VERSION);
    }
    float *x = sy_calloc(d, sizeof *x, err, "classify");
    if (!x) {
        sy_jb_model_free(&m);
        return err->code;
    }
    sy_features_options fo = sy_features_options_default();
    if (!(rc = sy_features_compute(tree, &fo, x, NULL, err))) {
        double p[SY_JB_MAX_CLASSES];
        sy_jb_predict(&m, x, p);
        sy_vote_options vo = sy_vote_options_default();
        out->novelty = sy_jb_novelty(&m, x);
        sy_tree_decision dec;
        if (!(rc = sy_vote(1, m.n_classes, p, &out->novelty, NULL, &vo, &dec, err))) {
            snprintf(out->best, sizeof out->best, "%s", m.classes[dec.best]);
            out->probability = dec.h1;
            out->confident = dec.confident;
            out->novel = dec.novel;
            /* A class the library no longer has cannot give parameters. */
            int id = dec.species >= 0 ? sy_library_id(m.classes[dec.species]) : -1;
            snprintf(out->name, sizeof out->name, "%s", id >= 0 ? m.classes[dec.species] : "unknown");
            /* The answer in library ids: classes bound by name. */
            int max_id = -1;
            for (size_t c = 0; c < m.n_classes; c++) {
                int k = sy_library_id(m.classes[c]);
                if (k > max_id) max_id = k;
            }
            if (!(rc = sy_species_init(&out->species, max_id >= 0 ? (size_t)max_id + 1 : 0, err))) {
                for (size_t c = 0; c < m.n_classes; c++) {
                    int k = sy_library_id(m.classes[c]);
                    if (k >= 0) out->species.probabilities[k] = (float)p[c];
                }
                out->species.id = id;
                if (id >= 0) snprintf(out->species.name, sizeof out->species.name, "%s", out->name);
                out->species.confident = dec.confident && id >= 0;
            }
        }
    }
    free(x);
    sy_jb_model_free(&m);
    out->seconds = sy_now() - t0;
    if (rc) sy_species_guess_free(out);
    return rc;
}

void sy_species_guess_free(sy_species_guess *g) { sy_species_free(&g->species); }

void sy_species_guess_rule_json(sy_json *j, const sy_species_guess *g)
{
    if (!g->ruled_out[0]) return;
    sy_json_string(j, "ruled_out", g->ruled_out);
    sy_json_number(j, "crown_base_scan", g->crown_base_scan);
    sy_json_number(j, "crown_base_species", g->crown_base_species);
    sy_json_number(j, "taken_probability", g->taken_probability);
}
