/* Fuzz targets whose reader takes a path: the bytes go to one file per
 * process under $TMPDIR (or /tmp), rewritten for every input. */
#ifndef SYLVA_FUZZ_UTIL_H
#define SYLVA_FUZZ_UTIL_H

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

static inline const char *fuzz_file(const char *ext, const uint8_t *data, size_t size)
{
    static char path[512];
    if (!path[0]) {
        const char *dir = getenv("TMPDIR");
        snprintf(path, sizeof path, "%s/sylva-fuzz-%ld.%s", dir && *dir ? dir : "/tmp", (long)getpid(), ext);
    }
    FILE *fp = fopen(path, "wb");
    if (!fp) abort();
    if (size && fwrite(data, 1, size, fp) != size) abort();
    if (fclose(fp)) abort();
    return path;
}

#endif
