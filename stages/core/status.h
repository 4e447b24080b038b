/* Errors as values: every stage returns an sy_code and fills an sy_error whose
 * message names the input and the problem in one line. */
#ifndef SYLVA_STATUS_H
#define SYLVA_STATUS_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* These are also the process exit codes of `sylva`. */
typedef enum {
    SY_OK = 0,
    SY_EUSAGE = 1,    /* the command line is wrong */
    SY_EINPUT = 2,    /* an input file is missing, unreadable or malformed */
    SY_EINTERNAL = 3  /* out of memory, a library failed, a bug */
} sy_code;

typedef struct {
    sy_code code;
    char msg[1024];
} sy_error;

/* Sets err (if not NULL) to code and a printf-style message; returns code so
 * callers can write `return sy_fail(err, SY_EINPUT, "%s: truncated", path);`. */
sy_code sy_fail(sy_error *err, sy_code code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

void sy_error_clear(sy_error *err);
/* Puts "prefix: " before err's message (a shim's reason gets its caller's
 * file or step in front); keeps and returns err's code. */
sy_code sy_error_prefix(sy_error *err, const char *prefix);

/* Allocation that reports failure through err instead of returning silently;
 * rejects n*size overflow. */
void *sy_calloc(size_t n, size_t size, sy_error *err, const char *what);

#ifdef __cplusplus
}
#endif

#endif
