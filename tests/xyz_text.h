/* The tests' own reader for plain "x y z" text files, so the skeleton tests
 * do not depend on the ingest stage. */
#ifndef SYLVA_TEST_XYZ_TEXT_H
#define SYLVA_TEST_XYZ_TEXT_H

#include <stdlib.h>

#include "stages/core/cloud.h"
#include "stages/core/fileio.h"

/* Plain "x y z" lines (CRLF and trailing spaces allowed): the tests' own
 * parser, so they do not depend on the ingest stage. */
static inline int load_xyz(const char *path, sy_cloud *c)
{
    sy_buffer b;
    sy_error err = {0};
    if (sy_read_file(path, &b, &err)) return -1;
    size_t lines = 1;
    for (size_t i = 0; i < b.size; i++) lines += b.data[i] == '\n';
    if (sy_cloud_init(c, lines, &err)) {
        sy_buffer_free(&b);
        return -1;
    }
    size_t n = 0;
    char *p = (char *)b.data;
    while (*p) {
        double x, y, z;
        char *e;
        x = strtod(p, &e);
        if (e != p) {
            p = e;
            y = strtod(p, &e);
            p = e;
            z = strtod(p, &e);
            p = e;
            c->xyz[3 * n] = (float)x;
            c->xyz[3 * n + 1] = (float)y;
            c->xyz[3 * n + 2] = (float)z;
            n++;
        }
        while (*p && *p != '\n') p++;
        if (*p) p++;
    }
    c->n = n;
    sy_buffer_free(&b);
    sy_cloud_rebase(c);
    return 0;
}

#endif
