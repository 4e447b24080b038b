#include "testutil.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char *rotating(void)
{
    static char bufs[8][4096];
    static int next;
    return bufs[next++ & 7];
}

const char *data_path(const char *rel)
{
    char *b = rotating();
    snprintf(b, 4096, "%s/%s", SYLVA_DATA_DIR, rel);
    return b;
}

const char *test_tmpdir(void)
{
    static char dir[4096];
    if (!dir[0]) {
        const char *base = getenv("TMPDIR");
        snprintf(dir, sizeof dir, "%s/sylva-test-XXXXXX", base && *base ? base : "/tmp");
        if (!mkdtemp(dir)) {
            perror("mkdtemp");
            exit(1);
        }
    }
    return dir;
}

const char *tmp_path(const char *name)
{
    char *b = rotating();
    if (snprintf(b, 4096, "%s/%s", test_tmpdir(), name) >= 4096) {
        fprintf(stderr, "tmp_path: %s too long\n", name);
        exit(1);
    }
    return b;
}

int write_bytes(const char *path, const void *data, size_t size)
{
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    size_t w = fwrite(data, 1, size, fp);
    return (fclose(fp) == 0 && w == size) ? 0 : -1;
}

int file_exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

int dir_entry_count(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) n++;
    closedir(d);
    return n;
}
