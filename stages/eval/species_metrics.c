/* Species classification: id -> label tables (CSV or truth files), the
 * confusion matrix, accuracy and macro-F1, as text and JSON. */
#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "eval.h"
#include "stages/core/array.h"
#include "stages/core/fileio.h"
#include "stages/core/lines.h"

void sy_label_table_free(sy_label_table *t)
{
    for (size_t i = 0; i < t->n; i++) {
        free(t->id[i]);
        free(t->label[i]);
    }
    free(t->id);
    free(t->label);
    memset(t, 0, sizeof *t);
}

static char *dup_str(const char *s, size_t n)
{
    char *d = malloc(n + 1);
    if (d) {
        memcpy(d, s, n);
        d[n] = 0;
    }
    return d;
}

sy_code sy_label_table_add(sy_label_table *t, const char *id, const char *label, sy_error *err)
{
    size_t n = t->n;
    if ((n & (n - 1)) == 0) {
        size_t cap = n ? 2 * n : 1;
        char **a = realloc(t->id, cap * sizeof *a);
        if (a) t->id = a;
        char **b = realloc(t->label, cap * sizeof *b);
        if (b) t->label = b;
        if (!a || !b) return sy_fail(err, SY_EINTERNAL, "labels: out of memory");
    }
    t->id[n] = dup_str(id, strlen(id));
    t->label[n] = dup_str(label, strlen(label));
    if (!t->id[n] || !t->label[n]) {
        free(t->id[n]);
        free(t->label[n]);
        return sy_fail(err, SY_EINTERNAL, "labels: out of memory");
    }
    t->n = n + 1;
    return SY_OK;
}

/* One CSV field from s[*pos..end): optionally "quoted" with "" escapes;
 * surrounding blanks trimmed. Returns a malloc'd string or NULL (bad quote
 * sets *bad, out of memory leaves it 0). */
static char *csv_field(const char *s, size_t *pos, size_t end, int *bad)
{
    size_t i = *pos;
    while (i < end && (s[i] == ' ' || s[i] == '\t')) i++;
    char *out = NULL;
    if (i < end && s[i] == '"') {
        size_t cap = end - i + 1, n = 0;
        out = malloc(cap);
        if (!out) return NULL;
        for (i++;; i++) {
            if (i >= end) {
                free(out);
                *bad = 1;
                return NULL;
            }
            if (s[i] == '"') {
                if (i + 1 < end && s[i + 1] == '"') out[n++] = s[i++];
                else break;
            } else {
                out[n++] = s[i];
            }
        }
        out[n] = 0;
        i++;
        while (i < end && (s[i] == ' ' || s[i] == '\t')) i++;
        if (i < end && s[i] != ',') {
            free(out);
            *bad = 1;
            return NULL;
        }
    } else {
        size_t start = i;
        while (i < end && s[i] != ',') i++;
        size_t stop = i;
        while (stop > start && (s[stop - 1] == ' ' || s[stop - 1] == '\t')) stop--;
        out = dup_str(s + start, stop - start);
    }
    if (i < end && s[i] == ',') i++;
    *pos = i;
    return out;
}

static int ieq(const char *a, const char *b)
{
    for (; *a && *b; a++, b++)
        if (tolower((unsigned char)*a) != tolower((unsigned char)*b)) return 0;
    return *a == *b;
}

typedef struct {
    const char *id;
    size_t row;
} id_row;

static int cmp_id_then_row(const void *a, const void *b)
{
    const id_row *x = a, *y = b;
    int c = strcmp(x->id, y->id);
    return c ? c : (x->row > y->row) - (x->row < y->row);
}

/* An id that appears twice would be scored twice: refused, naming both rows
 * (their lines when lines is not NULL). */
static sy_code check_unique_ids(const sy_label_table *t, const char *name, const int *lines, sy_error *err)
{
    if (t->n < 2) return SY_OK;
    id_row *r = sy_calloc(t->n, sizeof *r, err, "labels");
    if (!r) return SY_EINTERNAL;
    for (size_t i = 0; i < t->n; i++) r[i] = (id_row){t->id[i], i};
    qsort(r, t->n, sizeof *r, cmp_id_then_row);
    sy_code rc = SY_OK;
    for (size_t i = 1; i < t->n && !rc; i++)
        if (strcmp(r[i].id, r[i - 1].id) == 0) {
            if (lines)
                rc = sy_fail(err, SY_EINPUT, "%s:%d: id '%.64s' appears again (first on line %d)", name,
                             lines[r[i].row], r[i].id, lines[r[i - 1].row]);
            else
                rc = sy_fail(err, SY_EINPUT, "%s: tree_id %.64s appears twice (trees %zu and %zu)", name, r[i].id,
                             r[i - 1].row, r[i].row);
        }
    free(r);
    return rc;
}

sy_code sy_label_table_parse_csv(const char *name, const char *text, size_t len, sy_label_table *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    size_t lines_cap = 0;
    int *lines = NULL; /* the line of each row, for messages */
    sy_lines L;
    sy_lines_init(&L, text, len);
    const char *lb, *le;
    while (sy_lines_next(&L, &lb, &le)) {
        int line = (int)L.line;
        size_t p = (size_t)(lb - text), end = (size_t)(le - text);
        while (p < end && (text[p] == ' ' || text[p] == '\t')) p++;
        if (p == end || text[p] == '#') continue;
        int bad = 0;
        char *id = csv_field(text, &p, end, &bad);
        char *label = id && p <= end ? csv_field(text, &p, end, &bad) : NULL;
        sy_code rc = SY_OK;
        if (!id || !label) {
            rc = bad ? sy_fail(err, SY_EINPUT, "%s:%d: unterminated or misplaced quote", name, line)
                     : sy_fail(err, SY_EINTERNAL, "%s: out of memory", name);
        } else if (p < end) {
            rc = sy_fail(err, SY_EINPUT, "%s:%d: expected two fields 'id,species', found more", name, line);
        } else if (!*id || !*label) {
            rc = sy_fail(err, SY_EINPUT, "%s:%d: expected 'id,species' with both fields non-empty", name, line);
        } else if (!(out->n == 0 && ieq(id, "id") && (ieq(label, "species") || ieq(label, "label")))) {
            rc = sy_array_reserve(&lines, &lines_cap, out->n + 1, sizeof *lines, 64, err, name);
            if (!rc) lines[out->n] = line;
            if (!rc) rc = sy_label_table_add(out, id, label, err);
        }
        free(id);
        free(label);
        if (rc) {
            free(lines);
            sy_label_table_free(out);
            return rc;
        }
    }
    sy_code rc = out->n ? check_unique_ids(out, name, lines, err) : sy_fail(err, SY_EINPUT, "%s: no 'id,species' rows", name);
    free(lines);
    if (rc) sy_label_table_free(out);
    return rc;
}

sy_code sy_label_table_read_csv(const char *path, sy_label_table *out, sy_error *err)
{
    sy_buffer b;
    memset(out, 0, sizeof *out);
    sy_code rc = sy_read_file(path, &b, err);
    if (rc) return rc;
    rc = sy_label_table_parse_csv(path, (const char *)b.data, b.size, out, err);
    sy_buffer_free(&b);
    return rc;
}

sy_code sy_label_table_from_forest(const sy_forest *f, const char *path, sy_label_table *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    for (size_t i = 0; i < f->n_trees; i++) {
        const sy_eval_tree *t = &f->trees[i];
        if (t->tree_id < 0 || !t->species[0]) {
            sy_label_table_free(out);
            return sy_fail(err, SY_EINPUT, "%s: tree %zu lacks a tree_id or species", path, i);
        }
        char id[32];
        snprintf(id, sizeof id, "%lld", t->tree_id);
        sy_code rc = sy_label_table_add(out, id, t->species, err);
        if (rc) {
            sy_label_table_free(out);
            return rc;
        }
    }
    if (!out->n) return sy_fail(err, SY_EINPUT, "%s: no trees", path);
    sy_code rc = check_unique_ids(out, path, NULL, err);
    if (rc) sy_label_table_free(out);
    return rc;
}

/* ---- confusion ---- */

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* Index of label in the sorted list, or -1. */
static long find_label(char **labels, size_t n, const char *s)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        int c = strcmp(labels[mid], s);
        if (c == 0) return (long)mid;
        if (c < 0) lo = mid + 1;
        else hi = mid;
    }
    return -1;
}

/* Sorted (id, row) pairs of the prediction for lookups by id: id_row. */
static int cmp_id_row(const void *a, const void *b) { return strcmp(((const id_row *)a)->id, ((const id_row *)b)->id); }

void sy_confusion_free(sy_confusion *c)
{
    for (size_t i = 0; i < c->n_classes; i++) free(c->labels[i]);
    free(c->labels);
    free(c->matrix);
    free(c->f1);
    memset(c, 0, sizeof *c);
}

/* Distinct labels of both tables, sorted. */
static sy_code collect_labels(const sy_label_table *truth, const sy_label_table *pred, sy_confusion *c, sy_error *err)
{
    size_t total = truth->n + pred->n;
    char **all = sy_calloc(total + 1, sizeof *all, err, "labels");
    if (!all) return SY_EINTERNAL;
    for (size_t i = 0; i < truth->n; i++) all[i] = truth->label[i];
    for (size_t i = 0; i < pred->n; i++) all[truth->n + i] = pred->label[i];
    qsort(all, total, sizeof *all, cmp_str);
    c->labels = sy_calloc(total + 1, sizeof *c->labels, err, "labels");
    if (!c->labels) {
        free(all);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < total; i++) {
        if (c->n_classes && strcmp(c->labels[c->n_classes - 1], all[i]) == 0) continue;
        if (!(c->labels[c->n_classes] = dup_str(all[i], strlen(all[i])))) {
            free(all);
            return sy_fail(err, SY_EINTERNAL, "labels: out of memory");
        }
        c->n_classes++;
    }
    free(all);
    return SY_OK;
}

static void scores(sy_confusion *c, size_t real_classes)
{
    size_t n = c->n_classes, diag = 0;
    double f1_sum = 0;
    for (size_t k = 0; k < n; k++) {
        size_t tp = c->matrix[k * n + k], row = 0, col = 0;
        for (size_t j = 0; j < n; j++) row += c->matrix[k * n + j], col += c->matrix[j * n + k];
        diag += tp;
        if (k >= real_classes) {
            c->f1[k] = NAN;
            continue;
        }
        double p = col ? (double)tp / (double)col : 0, r = row ? (double)tp / (double)row : 0;
        c->f1[k] = p + r > 0 ? 2 * p * r / (p + r) : 0;
        f1_sum += c->f1[k];
    }
    c->accuracy = c->n_samples ? (double)diag / (double)c->n_samples : NAN;
    c->macro_f1 = real_classes ? f1_sum / (double)real_classes : NAN;
}

sy_code sy_confusion_build(const sy_label_table *truth, const sy_label_table *pred, sy_confusion *c, sy_error *err)
{
    memset(c, 0, sizeof *c);
    id_row *index = sy_calloc(pred->n + 1, sizeof *index, err, "labels");
    if (!index) return SY_EINTERNAL;
    for (size_t i = 0; i < pred->n; i++) index[i].id = pred->id[i], index[i].row = i;
    qsort(index, pred->n, sizeof *index, cmp_id_row);
    sy_code rc = collect_labels(truth, pred, c, err);
    size_t real = c->n_classes, missing = 0;
    long *pick = rc ? NULL : sy_calloc(truth->n + 1, sizeof *pick, err, "labels");
    if (!rc && !pick) rc = SY_EINTERNAL;
    for (size_t i = 0; !rc && i < truth->n; i++) {
        id_row key = {truth->id[i], 0};
        id_row *hit = bsearch(&key, index, pred->n, sizeof *index, cmp_id_row);
        pick[i] = hit ? find_label(c->labels, real, pred->label[hit->row]) : -1;
        missing += !hit;
    }
    if (!rc && missing) {
        if (!(c->labels[c->n_classes] = dup_str(SY_MISSING_LABEL, strlen(SY_MISSING_LABEL)))) rc = SY_EINTERNAL;
        else c->n_classes++;
    }
    size_t n = c->n_classes;
    if (!rc) {
        c->matrix = sy_calloc(n * n + 1, sizeof *c->matrix, err, "confusion matrix");
        c->f1 = sy_calloc(n + 1, sizeof *c->f1, err, "confusion matrix");
        if (!c->matrix || !c->f1) rc = SY_EINTERNAL;
    }
    if (!rc) {
        for (size_t i = 0; i < truth->n; i++) {
            long row = find_label(c->labels, real, truth->label[i]);
            size_t col = pick[i] >= 0 ? (size_t)pick[i] : n - 1;
            c->matrix[(size_t)row * n + col]++;
        }
        c->n_samples = truth->n;
        c->n_missing = missing;
        scores(c, real);
    }
    free(index);
    free(pick);
    if (rc) sy_confusion_free(c);
    return rc;
}

void sy_confusion_print(const sy_confusion *c, FILE *fp)
{
    size_t n = c->n_classes;
    int w = 12;
    for (size_t k = 0; k < n; k++)
        if ((int)strlen(c->labels[k]) > w) w = (int)strlen(c->labels[k]);
    if (w > 24) w = 24;
    fprintf(fp, "  %-*s", w + 3, "truth \\ pred");
    for (size_t k = 0; k < n; k++) fprintf(fp, " %5zu", k);
    fprintf(fp, "     F1\n");
    for (size_t r = 0; r < n; r++) {
        fprintf(fp, "  %2zu %-*.*s", r, w, w, c->labels[r]);
        for (size_t k = 0; k < n; k++) fprintf(fp, " %5zu", c->matrix[r * n + k]);
        if (isnan(c->f1[r])) fprintf(fp, "\n");
        else fprintf(fp, "  %.3f\n", c->f1[r]);
    }
}

void sy_confusion_json(const sy_confusion *c, sy_json *j)
{
    size_t n = c->n_classes;
    sy_json_array(j, "labels");
    for (size_t k = 0; k < n; k++) sy_json_string(j, NULL, c->labels[k]);
    sy_json_end(j);
    sy_json_array(j, "confusion");
    for (size_t r = 0; r < n; r++) {
        sy_json_array(j, NULL);
        for (size_t k = 0; k < n; k++) sy_json_int(j, NULL, (long long)c->matrix[r * n + k]);
        sy_json_end(j);
    }
    sy_json_end(j);
}
