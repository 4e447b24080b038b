/* File plumbing shared by readers and writers: whole-file reads that reject
 * directories and unreadable paths with a one-line message, and atomic writes
 * (temp file in the same directory, renamed on success) so no partial output
 * ever survives. */
#ifndef SYLVA_FILEIO_H
#define SYLVA_FILEIO_H

#include <stdio.h>

#include "status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    unsigned char *data; /* NUL-terminated for convenience (data[size] == 0) */
    size_t size;
} sy_buffer;

/* Reads the whole regular file (or pipe). Fails with SY_EINPUT naming path for
 * missing, unreadable, directory or device paths. Empty files read fine (size 0). */
sy_code sy_read_file(const char *path, sy_buffer *buf, sy_error *err);
void sy_buffer_free(sy_buffer *buf);

/* 1 if path exists and is a directory. */
int sy_is_directory(const char *path);

/* Lower-case extension without the dot ("las"), or "" if none. */
const char *sy_extension(const char *path, char *buf, size_t size);

typedef struct {
    FILE *fp;
    char final_path[4096];
    char tmp_path[4096 + 32];
} sy_atomic_file;

/* Opens "<dir>/.<name>.tmp.<pid>" for writing. */
sy_code sy_atomic_open(sy_atomic_file *f, const char *path, sy_error *err);
/* Flushes, closes and renames over the final path; removes the temp on failure. */
sy_code sy_atomic_commit(sy_atomic_file *f, sy_error *err);
/* Closes and removes the temp file. Safe to call twice. */
void sy_atomic_abort(sy_atomic_file *f);

/* Fails fast, before long work, when path could not be written later: its
 * directory is missing or not writable, or path is a directory. Creates and
 * removes the temp file the atomic writer would use; leaves nothing behind. */
sy_code sy_check_writable(const char *path, sy_error *err);

/* Writes size bytes to path atomically. */
sy_code sy_write_file_atomic(const char *path, const void *data, size_t size, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
