#include "progress.h"

#include <stdio.h>
#include <time.h>
#include <unistd.h>

static int g_quiet;

void sy_progress_set_quiet(int quiet) { g_quiet = quiet; }
int sy_progress_quiet(void) { return g_quiet; }

double sy_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

void sy_progress_begin(sy_progress *p, const char *label, size_t total)
{
    p->label = label;
    p->total = total ? total : 1;
    p->last_shown = -1;
    p->tty = isatty(STDERR_FILENO);
    p->quiet = g_quiet;
    p->start = sy_now();
}

void sy_progress_update(sy_progress *p, size_t done)
{
    if (p->quiet) return;
    if (done > p->total) done = p->total;
    int permille = (int)(1000.0 * done / p->total);
    if (p->tty) {
        if (permille / 10 == p->last_shown / 10) return;
        int width = 30, filled = permille * width / 1000;
        fprintf(stderr, "\r%-14s [", p->label);
        for (int i = 0; i < width; i++) fputc(i < filled ? '#' : '.', stderr);
        fprintf(stderr, "] %3d%%", permille / 10);
        fflush(stderr);
    } else {
        if (permille / 100 == p->last_shown / 100 && p->last_shown >= 0) return;
        fprintf(stderr, "%s: %d%%\n", p->label, permille / 10);
    }
    p->last_shown = permille;
}

void sy_progress_end(sy_progress *p)
{
    if (p->quiet) return;
    sy_progress_update(p, p->total);
    if (p->tty) fputc('\n', stderr);
    fprintf(stderr, "%s: done in %.2f s\n", p->label, sy_now() - p->start);
}
