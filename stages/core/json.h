/* A small streaming JSON writer for `--json` output and truth/report files.
 * It tracks commas and nesting so callers only name keys and values. */
#ifndef SYLVA_JSON_H
#define SYLVA_JSON_H

#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    FILE *fp;
    int depth;
    int need_comma[32];
    char closer[32]; /* ']' or '}' per open level */
    int pretty;
} sy_json;

void sy_json_begin(sy_json *j, FILE *fp, int pretty);
void sy_json_object(sy_json *j, const char *key); /* key NULL inside arrays / at top */
void sy_json_array(sy_json *j, const char *key);
void sy_json_end(sy_json *j);                     /* closes the innermost object/array */
void sy_json_string(sy_json *j, const char *key, const char *value);
void sy_json_number(sy_json *j, const char *key, double value); /* NaN/Inf become null */
/* A float as the shortest decimal that reads back as the same float: 0.05,
 * not 0.05000000074505806. NaN/Inf become null. */
void sy_json_float(sy_json *j, const char *key, float value);
/* The shortest "%.Ng" text (N = 6..9) of v that reads back as the same float
 * ("0.8", not "0.800000011920929"): how every writer prints a float. */
void sy_format_float(char *buf, size_t size, float v);
/* The same decimal as a double (strtod of sy_format_float's text), found by
 * arithmetic instead of printing and parsing: a glTF writer that stores
 * doubles and prints the shortest double gets the float's short text. The
 * scaled value is rounded in double arithmetic, so a digit lying within an
 * ulp of a tie can round the other way; the result still reads back as v.
 * Finite v; NaN and Inf come back as they are. */
double sy_float_shortest(float v);
void sy_json_int(sy_json *j, const char *key, long long value);
void sy_json_uint(sy_json *j, const char *key, unsigned long long value);
void sy_json_bool(sy_json *j, const char *key, int value);
void sy_json_null(sy_json *j, const char *key);
void sy_json_numbers(sy_json *j, const char *key, const double *v, int n);
void sy_json_finish(sy_json *j); /* trailing newline */

#ifdef __cplusplus
}
#endif

#endif
