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

static char tmpdir_path[4096];

/* Removes path and, when it is a folder, everything under it (links are
 * removed, never followed). */
static void remove_tree(const char *path)
{
    struct stat st;
    if (lstat(path, &st) != 0) return;
    if (S_ISDIR(st.st_mode)) {
        DIR *d = opendir(path);
        if (d) {
            struct dirent *e;
            char child[4096];
            while ((e = readdir(d)))
                if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..") &&
                    snprintf(child, sizeof child, "%s/%s", path, e->d_name) < (int)sizeof child)
                    remove_tree(child);
            closedir(d);
        }
        rmdir(path);
    } else {
        unlink(path);
    }
}

/* Each test process's folder goes when it exits (SYLVA_KEEP_TEST_TMP=1 keeps
 * it for a look): a suite run used to leave 18 folders in /tmp. */
static void remove_tmpdir(void)
{
    const char *keep = getenv("SYLVA_KEEP_TEST_TMP");
    if (keep && *keep && strcmp(keep, "0")) {
        fprintf(stderr, "test files kept in %s\n", tmpdir_path);
        return;
    }
    remove_tree(tmpdir_path);
}

const char *test_tmpdir(void)
{
    if (!tmpdir_path[0]) {
        const char *base = getenv("TMPDIR");
        snprintf(tmpdir_path, sizeof tmpdir_path, "%s/sylva-test-XXXXXX", base && *base ? base : "/tmp");
        if (!mkdtemp(tmpdir_path)) {
            perror("mkdtemp");
            exit(1);
        }
        atexit(remove_tmpdir);
    }
    return tmpdir_path;
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

void put_le16(unsigned char *p, unsigned v)
{
    p[0] = (unsigned char)v;
    p[1] = (unsigned char)(v >> 8);
}

void put_le32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}

void put_le64(unsigned char *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(v >> (8 * i));
}

void put_lef64(unsigned char *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, 8);
    put_le64(p, u);
}

void put_lef32(unsigned char *p, float f)
{
    uint32_t u;
    memcpy(&u, &f, 4);
    put_le32(p, u);
}
