/* Progress for long work: a redrawn bar on a TTY, a plain line every 10%
 * otherwise, nothing when quiet. Always on stderr so stdout stays parseable. */
#ifndef SYLVA_PROGRESS_H
#define SYLVA_PROGRESS_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    const char *label;
    size_t total;
    int last_shown; /* permille last drawn, -1 before the first */
    int tty;
    int quiet;
    double start;
} sy_progress;

/* Global switch set by the CLI (--quiet, --json). */
void sy_progress_set_quiet(int quiet);

void sy_progress_begin(sy_progress *p, const char *label, size_t total);
void sy_progress_update(sy_progress *p, size_t done);
void sy_progress_end(sy_progress *p);

/* Monotonic seconds. */
double sy_now(void);

#ifdef __cplusplus
}
#endif

#endif
