/* The JointBoost model file (docs/classify.md): plain text, one record per
 * line, so it diffs and reviews like source; floats are written with nine
 * significant digits, which read back as the same float. The last line holds
 * an FNV-1a 64-bit hash of every byte before it, so a damaged or truncated
 * file is refused rather than predicting nonsense.
 *
 *   sylva-jointboost 3
 *   features <count> <features-version>
 *   classes <count>
 *   class <name>                       (one per class, in index order)
 *   kappa <temperature>
 *   trained <samples> <held-out accuracy or nan>
 *   novelty <threshold> <cap> <trim>   (the joint novelty test, classify/novelty.c)
 *   stat <center> <scale> <mean_0> <sd_0> ... <mean_C-1> <sd_C-1>   (one per feature)
 *   planar <threshold> <count>         (the planar-surface test, novelty.c; 0 0: none)
 *   range <feature> <lo> <hi> <spread> (one per planarity feature)
 *   rounds <count>
 *   stump <feature> <threshold> <a> <b> <mask hex> <k_0> ... <k_C-1>
 *   end <fnv1a64 hex>
 */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "classify/classify.h"
#include "stages/core/fileio.h"
#include "stages/core/hash.h"
#include "stages/core/lines.h"

static uint64_t fnv1a(const char *s, size_t n) { return sy_fnv1a64(SY_FNV1A64_INIT, s, n); }

typedef struct {
    char *buf;
    size_t len, cap;
    int failed;
} strbuf;

static void sb_printf(strbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void sb_printf(strbuf *b, const char *fmt, ...)
{
    if (b->failed) return;
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int k = vsnprintf(b->buf ? b->buf + b->len : NULL, b->buf ? b->cap - b->len : 0, fmt, ap);
        va_end(ap);
        if (k < 0) {
            b->failed = 1;
            return;
        }
        if (b->buf && b->len + (size_t)k < b->cap) {
            b->len += (size_t)k;
            return;
        }
        size_t nc = b->cap ? b->cap * 2 : 4096;
        while (nc < b->len + (size_t)k + 1) nc *= 2;
        char *nb = realloc(b->buf, nc);
        if (!nb) {
            b->failed = 1;
            return;
        }
        b->buf = nb, b->cap = nc;
    }
}

static int valid_name(const char *s)
{
    if (!s || !*s || strlen(s) > 63) return 0;
    for (; *s; s++)
        if (!(isalnum((unsigned char)*s) || *s == '_' || *s == '-' || *s == '.')) return 0;
    return 1;
}

sy_code sy_jb_serialize(const sy_jb_model *m, char **text, size_t *len, sy_error *err)
{
    strbuf b = {0};
    for (size_t c = 0; c < m->n_classes; c++)
        if (!valid_name(m->classes[c]))
            return sy_fail(err, SY_EINPUT, "jointboost: class name \"%s\" must be 1-63 letters, digits, '_', '-' or '.'",
                           m->classes[c]);
    sb_printf(&b, "sylva-jointboost %d\n", SY_JB_FORMAT_VERSION);
    sb_printf(&b, "features %zu %u\n", m->n_features, m->features_version);
    sb_printf(&b, "classes %zu\n", m->n_classes);
    for (size_t c = 0; c < m->n_classes; c++) sb_printf(&b, "class %s\n", m->classes[c]);
    sb_printf(&b, "kappa %.17g\n", m->kappa);
    sb_printf(&b, "trained %zu %.6g\n", m->train_samples, m->holdout_accuracy);
    /* A model without the test (too few trees to calibrate it) writes a zero
     * threshold and neutral statistics: nothing is novel. */
    sb_printf(&b, "novelty %.9g %.9g %.9g\n", m->nov_center ? m->nov_threshold : 0.0, m->nov_center ? m->nov_cap : 25.0,
              m->nov_center ? m->nov_trim : 0.0);
    for (size_t f = 0; f < m->n_features; f++) {
        sb_printf(&b, "stat %.9g %.9g", m->nov_center ? m->nov_center[f] : 0.0f, m->nov_center ? m->nov_scale[f] : 1.0f);
        for (size_t c = 0; c < m->n_classes; c++)
            sb_printf(&b, " %.9g %.9g", m->nov_center ? m->nov_mean[c * m->n_features + f] : 0.0f,
                      m->nov_center ? m->nov_sd[c * m->n_features + f] : 1.0f);
        sb_printf(&b, "\n");
    }
    sb_printf(&b, "planar %.9g %zu\n", m->n_planar ? m->planar_threshold : 0.0, m->n_planar);
    for (size_t k = 0; k < m->n_planar; k++)
        sb_printf(&b, "range %d %.9g %.9g %.9g\n", m->planar_feature[k], m->planar_lo[k], m->planar_hi[k],
                  m->planar_s[k]);
    sb_printf(&b, "rounds %zu\n", m->n_rounds);
    for (size_t r = 0; r < m->n_rounds; r++) {
        sb_printf(&b, "stump %d %.9g %.9g %.9g %llx", m->feature[r], m->threshold[r], m->a[r], m->b[r],
                  (unsigned long long)m->mask[r]);
        for (size_t c = 0; c < m->n_classes; c++) sb_printf(&b, " %.9g", m->k[r * m->n_classes + c]);
        sb_printf(&b, "\n");
    }
    if (!b.failed) {
        uint64_t h = fnv1a(b.buf, b.len);
        sb_printf(&b, "end %016llx\n", (unsigned long long)h);
    }
    if (b.failed) {
        free(b.buf);
        return sy_fail(err, SY_EINTERNAL, "jointboost: out of memory writing the model");
    }
    *text = b.buf;
    *len = b.len;
    return SY_OK;
}

sy_code sy_jb_save(const sy_jb_model *m, const char *path, sy_error *err)
{
    char *text;
    size_t len;
    sy_code rc = sy_jb_serialize(m, &text, &len, err);
    if (rc) return rc;
    rc = sy_write_file_atomic(path, text, len, err);
    free(text);
    return rc;
}

/* ------------------------------------------------------------ reading */

typedef struct {
    const char *name;
    sy_lines lines;
    int line;
    char cur[65536];
    sy_error *err;
} reader;

/* Next line into r->cur (without the end of line); 0 at the end of the text. */
static int next_line(reader *r)
{
    const char *b, *e;
    if (!sy_lines_next(&r->lines, &b, &e)) return 0;
    size_t n = (size_t)(e - b);
    r->line++;
    if (n >= sizeof r->cur) n = sizeof r->cur - 1; /* too long: the field checks fail on it */
    memcpy(r->cur, b, n);
    r->cur[n] = 0;
    return 1;
}

static sy_code bad(reader *r, const char *what)
{
    return sy_fail(r->err, SY_EINPUT, "%s:%d: %s", r->name, r->line, what);
}

/* Expects the line to start with word followed by a space; returns the rest. */
static const char *expect(reader *r, const char *word)
{
    if (!next_line(r)) {
        r->line++;
        return NULL;
    }
    size_t n = strlen(word);
    if (strncmp(r->cur, word, n) != 0 || r->cur[n] != ' ') return NULL;
    return r->cur + n + 1;
}

static int parse_size(const char **s, size_t *out, size_t max)
{
    char *e;
    errno = 0;
    if (!isdigit((unsigned char)**s)) return 0;
    unsigned long long v = strtoull(*s, &e, 10);
    if (errno || v > max) return 0;
    *out = (size_t)v;
    *s = e;
    return 1;
}

static int parse_float(const char **s, float *out, int allow_inf)
{
    char *e;
    const char *p = *s;
    while (*p == ' ') p++;
    if (!*p) return 0;
    double v = strtod(p, &e);
    if (e == p || isnan(v) || (!allow_inf && !isfinite(v))) return 0;
    if (isfinite(v) && fabs(v) > 3.4e38) return 0;
    *out = (float)v;
    *s = e;
    return 1;
}

static int at_end(const char *s)
{
    while (*s == ' ') s++;
    return *s == 0;
}

sy_code sy_jb_parse(const char *name, const char *text, size_t len, sy_jb_model *m, sy_error *err)
{
    memset(m, 0, sizeof *m);
    reader r = {name, {0}, 0, {0}, err};
    sy_lines_init(&r.lines, text, len);
    const char *s;
    if (!next_line(&r) || strncmp(r.cur, "sylva-jointboost ", 17) != 0)
        return sy_fail(err, SY_EINPUT, "%s: not a Sylva JointBoost model (no \"sylva-jointboost\" header)", name);
    size_t ver;
    s = r.cur + 17;
    if (!parse_size(&s, &ver, 1000000) || !at_end(s)) return bad(&r, "malformed format version");
    if (ver != SY_JB_FORMAT_VERSION)
        return sy_fail(err, SY_EINPUT, "%s: model format version %zu, this build reads version %d", name, ver,
                       SY_JB_FORMAT_VERSION);
    /* The hash first: a damaged file fails as damaged, not at a random field. */
    {
        const char *last = NULL;
        for (const char *p = text; p < text + len;) {
            const char *nl = memchr(p, '\n', (size_t)(text + len - p));
            if (!nl) break;
            if ((size_t)(text + len - p) > 4 && strncmp(p, "end ", 4) == 0) last = p;
            p = nl + 1;
        }
        if (!last) return sy_fail(err, SY_EINPUT, "%s: truncated model (no \"end\" line)", name);
        char *e;
        unsigned long long h = strtoull(last + 4, &e, 16);
        if (e != last + 20 || *e != '\n' || (size_t)(e + 1 - text) != len)
            return sy_fail(err, SY_EINPUT, "%s: malformed or misplaced \"end\" line", name);
        if (h != fnv1a(text, (size_t)(last - text)))
            return sy_fail(err, SY_EINPUT, "%s: model is damaged (checksum mismatch)", name);
    }
    size_t nf, fv, nc;
    if (!(s = expect(&r, "features")) || !parse_size(&s, &nf, 1000000) || nf == 0 || *s++ != ' ' ||
        !parse_size(&s, &fv, 0xffffffffu) || !at_end(s))
        return bad(&r, "expected \"features <count> <version>\"");
    if (!(s = expect(&r, "classes")) || !parse_size(&s, &nc, SY_JB_MAX_CLASSES) || nc < 2 || !at_end(s))
        return bad(&r, "expected \"classes <count>\" with 2..64 classes");
    m->n_features = nf;
    m->features_version = (uint32_t)fv;
    m->classes = sy_calloc(nc, sizeof *m->classes, err, "model");
    if (!m->classes) return err->code;
    m->n_classes = nc;
    for (size_t c = 0; c < nc; c++) {
        if (!(s = expect(&r, "class")) || !valid_name(s)) {
            sy_jb_model_free(m);
            return bad(&r, "expected \"class <name>\"");
        }
        for (size_t c2 = 0; c2 < c; c2++)
            if (strcmp(m->classes[c2], s) == 0) {
                sy_jb_model_free(m);
                return bad(&r, "class named twice");
            }
        if (!(m->classes[c] = strdup(s))) {
            sy_jb_model_free(m);
            return sy_fail(err, SY_EINTERNAL, "%s: out of memory", name);
        }
    }
    if (!(s = expect(&r, "kappa"))) goto malformed_kappa;
    {
        char *e;
        m->kappa = strtod(s, &e);
        if (e == s || !at_end(e) || !(m->kappa > 0 && m->kappa < 1e6)) goto malformed_kappa;
    }
    if (!(s = expect(&r, "trained")) || !parse_size(&s, &m->train_samples, SIZE_MAX)) {
        sy_jb_model_free(m);
        return bad(&r, "expected \"trained <samples> <accuracy>\"");
    }
    m->holdout_accuracy = strtod(s, NULL);
    {
        float th, cap, trim;
        if (!(s = expect(&r, "novelty")) || !parse_float(&s, &th, 0) || !parse_float(&s, &cap, 0) ||
            !parse_float(&s, &trim, 0) || !at_end(s) || th < 0 || !(cap > 0) || trim < 0 || trim >= 1) {
            sy_jb_model_free(m);
            return bad(&r, "expected \"novelty <threshold> <cap> <trim>\" with threshold >= 0, cap > 0, 0 <= trim < 1");
        }
        m->nov_threshold = th, m->nov_cap = cap, m->nov_trim = trim;
    }
    m->nov_center = sy_calloc(nf, sizeof *m->nov_center, err, "model");
    m->nov_scale = sy_calloc(nf, sizeof *m->nov_scale, err, "model");
    m->nov_mean = sy_calloc(nf * nc, sizeof *m->nov_mean, err, "model");
    m->nov_sd = sy_calloc(nf * nc, sizeof *m->nov_sd, err, "model");
    if (!m->nov_center || !m->nov_scale || !m->nov_mean || !m->nov_sd) {
        sy_jb_model_free(m);
        return err->code;
    }
    for (size_t f = 0; f < nf; f++) {
        int ok = (s = expect(&r, "stat")) && parse_float(&s, &m->nov_center[f], 0) &&
                 parse_float(&s, &m->nov_scale[f], 0) && m->nov_scale[f] > 0;
        for (size_t c = 0; ok && c < nc; c++)
            ok = parse_float(&s, &m->nov_mean[c * nf + f], 0) && parse_float(&s, &m->nov_sd[c * nf + f], 0) &&
                 m->nov_sd[c * nf + f] > 0;
        if (!ok || !at_end(s)) {
            sy_jb_model_free(m);
            return bad(&r, "expected \"stat <center> <scale> <mean> <sd> ...\" (one mean and sd per class, scale and sd > 0)");
        }
    }
    {
        float th;
        size_t np;
        if (!(s = expect(&r, "planar")) || !parse_float(&s, &th, 0) || *s++ != ' ' || !parse_size(&s, &np, nf) ||
            !at_end(s) ||
            th < 0 || (np && !(th > 0))) {
            sy_jb_model_free(m);
            return bad(&r, "expected \"planar <threshold> <count>\" (threshold > 0 with a count, at most one per feature)");
        }
        m->planar_threshold = th;
        if (sy_jb_planar_alloc(m, np, err)) {
            sy_jb_model_free(m);
            return err->code;
        }
        for (size_t k = 0; k < np; k++) {
            size_t f;
            int ok = (s = expect(&r, "range")) && parse_size(&s, &f, nf - 1) && parse_float(&s, &m->planar_lo[k], 0) &&
                     parse_float(&s, &m->planar_hi[k], 0) && parse_float(&s, &m->planar_s[k], 0) && at_end(s) &&
                     m->planar_lo[k] <= m->planar_hi[k] && m->planar_s[k] > 0;
            if (!ok) {
                sy_jb_model_free(m);
                return bad(&r, "expected \"range <feature> <lo> <hi> <spread>\" (a feature index, lo <= hi, spread > 0)");
            }
            m->planar_feature[k] = (int32_t)f;
        }
    }
    size_t nr;
    if (!(s = expect(&r, "rounds")) || !parse_size(&s, &nr, 1000000) || !at_end(s)) {
        sy_jb_model_free(m);
        return bad(&r, "expected \"rounds <count>\"");
    }
    m->n_rounds = nr;
    size_t alloc = nr ? nr : 1;
    m->feature = sy_calloc(alloc, sizeof *m->feature, err, "model");
    m->threshold = sy_calloc(alloc, sizeof *m->threshold, err, "model");
    m->a = sy_calloc(alloc, sizeof *m->a, err, "model");
    m->b = sy_calloc(alloc, sizeof *m->b, err, "model");
    m->mask = sy_calloc(alloc, sizeof *m->mask, err, "model");
    m->k = sy_calloc(alloc * nc, sizeof *m->k, err, "model");
    if (!m->feature || !m->threshold || !m->a || !m->b || !m->mask || !m->k) {
        sy_jb_model_free(m);
        return err->code;
    }
    for (size_t i = 0; i < nr; i++) {
        size_t f;
        char *e;
        if (!(s = expect(&r, "stump")) || !parse_size(&s, &f, nf - 1) || !parse_float(&s, &m->threshold[i], 0) ||
            !parse_float(&s, &m->a[i], 0) || !parse_float(&s, &m->b[i], 0))
            goto bad_stump;
        while (*s == ' ') s++;
        if (!isxdigit((unsigned char)*s)) goto bad_stump;
        errno = 0;
        unsigned long long mask = strtoull(s, &e, 16);
        if (errno || (nc < 64 && (mask >> nc)) || mask == 0) goto bad_stump;
        s = e;
        m->feature[i] = (int32_t)f;
        m->mask[i] = mask;
        for (size_t c = 0; c < nc; c++)
            if (!parse_float(&s, &m->k[i * nc + c], 0)) goto bad_stump;
        if (!at_end(s)) goto bad_stump;
    }
    if (!next_line(&r) || strncmp(r.cur, "end ", 4) != 0) {
        sy_jb_model_free(m);
        return bad(&r, "expected the \"end\" line after the stumps");
    }
    return SY_OK;
bad_stump:
    sy_jb_model_free(m);
    return bad(&r, "malformed stump (feature, threshold, a, b, class mask, one constant per class)");
malformed_kappa:
    sy_jb_model_free(m);
    return bad(&r, "expected \"kappa <temperature>\" with 0 < kappa < 1e6");
}

sy_code sy_jb_load(const char *path, sy_jb_model *m, sy_error *err)
{
    sy_buffer b;
    sy_code rc = sy_read_file(path, &b, err);
    if (rc) return rc;
    rc = sy_jb_parse(path, (const char *)b.data, b.size, m, err);
    sy_buffer_free(&b);
    return rc;
}
