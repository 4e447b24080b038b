#include "status.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

sy_code sy_fail(sy_error *err, sy_code code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
        err->code = code;
    }
    return code;
}

void sy_error_clear(sy_error *err)
{
    if (err) {
        err->code = SY_OK;
        err->msg[0] = '\0';
    }
}

sy_code sy_error_prefix(sy_error *err, const char *prefix)
{
    char reason[sizeof err->msg];
    memcpy(reason, err->msg, sizeof reason);
    reason[sizeof reason - 1] = '\0';
    size_t n = strlen(prefix);
    if (n > sizeof err->msg - 3) n = sizeof err->msg - 3;
    memcpy(err->msg, prefix, n);
    memcpy(err->msg + n, ": ", 2);
    size_t room = sizeof err->msg - n - 3, len = strlen(reason);
    if (len > room) len = room;
    memcpy(err->msg + n + 2, reason, len);
    err->msg[n + 2 + len] = '\0';
    return err->code;
}

void *sy_calloc(size_t n, size_t size, sy_error *err, const char *what)
{
    if (n == 0 || size == 0) n = size = 1;
    if (n > SIZE_MAX / size) {
        sy_fail(err, SY_EINTERNAL, "%s: %zu elements of %zu bytes overflow", what, n, size);
        return NULL;
    }
    void *p = calloc(n, size);
    if (!p) sy_fail(err, SY_EINTERNAL, "%s: out of memory (%zu bytes)", what, n * size);
    return p;
}
