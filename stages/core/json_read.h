/* A small JSON reader (RFC 8259) building a DOM: objects, arrays, strings
 * (escapes including \uXXXX surrogate pairs, decoded to UTF-8), numbers,
 * true/false/null. Input must be valid UTF-8. Nesting depth and input size
 * are limited; errors name the source, line and column in one line:
 *   "truth.json:12:7: expected ',' or '}' in object".
 * The writer side is json.h (sy_json_*); reader names use sy_jv_. */
#ifndef SYLVA_JSON_READ_H
#define SYLVA_JSON_READ_H

#include <stddef.h>

#include "status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { SY_JV_NULL, SY_JV_BOOL, SY_JV_NUMBER, SY_JV_STRING, SY_JV_ARRAY, SY_JV_OBJECT } sy_jv_type;

typedef struct sy_jv sy_jv;
struct sy_jv {
    sy_jv_type type;
    int line, col;   /* where the value starts (1-based), for messages */
    int boolean;     /* SY_JV_BOOL */
    double number;   /* SY_JV_NUMBER, always finite */
    char *str;       /* SY_JV_STRING: NUL-terminated UTF-8 (may contain \u0000) */
    size_t len;      /* SY_JV_STRING: bytes; ARRAY/OBJECT: element count */
    sy_jv *items;    /* ARRAY elements / OBJECT values */
    char **keys;     /* OBJECT keys, parallel to items */
};

typedef struct {
    int max_depth;   /* nesting of arrays/objects; 0 -> 256 */
    size_t max_size; /* input bytes; 0 -> 1 GiB */
} sy_jv_limits;

/* Parses text[0..len) (no NUL needed). name labels error messages. On
 * success *out owns the tree (sy_jv_free); on failure *out is NULL and err
 * says where (SY_EINPUT) or SY_EINTERNAL for out of memory. */
sy_code sy_jv_parse(const char *name, const char *text, size_t len, const sy_jv_limits *limits, sy_jv **out,
                    sy_error *err);
/* Reads and parses a whole file with default limits. */
sy_code sy_jv_parse_file(const char *path, sy_jv **out, sy_error *err);
void sy_jv_free(sy_jv *v);

/* Lookups return NULL when v is NULL, of another type, or lacks the entry,
 * so chains like sy_jv_get(sy_jv_at(a, 0), "x") need no checks between.
 * Objects: the first member with that key. */
const sy_jv *sy_jv_get(const sy_jv *obj, const char *key);
const sy_jv *sy_jv_at(const sy_jv *arr, size_t i);
/* Element count of an array or object; 0 otherwise. */
size_t sy_jv_count(const sy_jv *v);
/* 1 and *out set when v is a number; 0 otherwise. */
int sy_jv_number(const sy_jv *v, double *out);
/* The string or NULL. */
const char *sy_jv_string(const sy_jv *v);
/* "object", "array", ... for messages. */
const char *sy_jv_type_name(sy_jv_type t);

#ifdef __cplusplus
}
#endif

#endif
