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
    /* 9 significant digits always round-trip a float; most need fewer. */
    char buf[32];
    for (int digits = 6; digits <= 9; digits++) {
        snprintf(buf, sizeof buf, "%.*g", digits, (double)value);
        if (strtof(buf, NULL) == value) break;
    }
    fputs(buf, j->fp);
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
