#include "json.h"

#include <math.h>
#include <stdlib.h>

void sy_json_begin(sy_json *j, FILE *fp, int pretty)
{
    j->fp = fp;
    j->depth = 0;
    j->need_comma[0] = 0;
    j->pretty = pretty;
}

static void indent(sy_json *j)
{
    if (!j->pretty) return;
    fputc('\n', j->fp);
    for (int i = 0; i < j->depth; i++) fputs("  ", j->fp);
}

static void put_string(FILE *fp, const char *s)
{
    fputc('"', fp);
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') fprintf(fp, "\\%c", c);
        else if (c == '\n') fputs("\\n", fp);
        else if (c == '\t') fputs("\\t", fp);
        else if (c < 0x20) fprintf(fp, "\\u%04x", c);
        else fputc(c, fp);
    }
    fputc('"', fp);
}

static void prefix(sy_json *j, const char *key)
{
    if (j->depth > 0) {
        if (j->need_comma[j->depth]) fputc(',', j->fp);
        j->need_comma[j->depth] = 1;
        indent(j);
    }
    if (key) {
        put_string(j->fp, key);
        fputs(j->pretty ? ": " : ":", j->fp);
    }
}

static void open(sy_json *j, const char *key, char c)
{
    prefix(j, key);
    fputc(c, j->fp);
    if (j->depth < 31) j->depth++;
    j->need_comma[j->depth] = 0;
    j->closer[j->depth] = c == '[' ? ']' : '}';
}

void sy_json_object(sy_json *j, const char *key) { open(j, key, '{'); }
void sy_json_array(sy_json *j, const char *key) { open(j, key, '['); }

void sy_json_end(sy_json *j)
{
    if (j->depth == 0) return;
    int had = j->need_comma[j->depth];
    char closer = j->closer[j->depth];
    j->depth--;
    if (had) indent(j);
    fputc(closer, j->fp);
}

void sy_json_string(sy_json *j, const char *key, const char *value)
{
    prefix(j, key);
    if (value) put_string(j->fp, value);
    else fputs("null", j->fp);
}

/* The shortest of %.15g..%.17g that reads back to the same double: 0.24 stays
 * "0.24" instead of "0.23999999999999999", and nothing is lost. */
static void put_number(FILE *fp, double value)
{
    char buf[40];
    for (int digits = 15; digits <= 17; digits++) {
        snprintf(buf, sizeof buf, "%.*g", digits, value);
        if (strtod(buf, NULL) == value) break;
    }
    fputs(buf, fp);
}

void sy_json_number(sy_json *j, const char *key, double value)
{
    prefix(j, key);
    if (isfinite(value)) put_number(j->fp, value);
    else fputs("null", j->fp);
}

void sy_json_int(sy_json *j, const char *key, long long value)
{
    prefix(j, key);
    fprintf(j->fp, "%lld", value);
}

void sy_json_uint(sy_json *j, const char *key, unsigned long long value)
{
    prefix(j, key);
    fprintf(j->fp, "%llu", value);
}

void sy_json_float(sy_json *j, const char *key, float value)
{
    prefix(j, key);
    if (!isfinite(value)) {
        fputs("null", j->fp);
        return;
    }
    char buf[32];
    sy_format_float(buf, sizeof buf, value);
    fputs(buf, j->fp);
}

void sy_format_float(char *buf, size_t size, float v)
{
    /* 9 significant digits always round-trip a float; most need fewer. */
    for (int digits = 6; digits <= 9; digits++) {
        snprintf(buf, size, "%.*g", digits, (double)v);
        if (strtof(buf, NULL) == v) return;
    }
}

double sy_float_shortest(float v)
{
    if (!isfinite(v) || v == 0) return (double)v;
    /* Powers of ten a double holds exactly. */
    static const double p10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                   1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
    double a = fabs((double)v);
    int e = (int)floor(log10(a));
    for (int digits = 6; digits <= 9; digits++) {
        int k = digits - 1 - e; /* a x 10^k has `digits` digits before the point */
        double r;
        if (k >= 0 && k <= 22) r = nearbyint(a * p10[k]) / p10[k];
        else if (k < 0 && -k <= 22) r = nearbyint(a / p10[-k]) * p10[-k];
        else break;
        if ((float)r == (float)a) return v < 0 ? -r : r;
    }
    char buf[32];
    sy_format_float(buf, sizeof buf, v);
    return strtod(buf, NULL);
}

void sy_json_bool(sy_json *j, const char *key, int value)
{
    prefix(j, key);
    fputs(value ? "true" : "false", j->fp);
}

void sy_json_null(sy_json *j, const char *key)
{
    prefix(j, key);
    fputs("null", j->fp);
}

void sy_json_numbers(sy_json *j, const char *key, const double *v, int n)
{
    prefix(j, key);
    fputc('[', j->fp);
    for (int i = 0; i < n; i++) {
        if (i) fputc(',', j->fp);
        if (isfinite(v[i])) put_number(j->fp, v[i]);
        else fputs("null", j->fp);
    }
    fputc(']', j->fp);
}

void sy_json_finish(sy_json *j) { fputc('\n', j->fp); }
