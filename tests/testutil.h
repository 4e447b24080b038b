/* Helpers shared by the cmocka tests: paths into ../shared/data, temp dirs. */
#ifndef SYLVA_TESTUTIL_H
#define SYLVA_TESTUTIL_H

#include <setjmp.h> /* cmocka needs these before its header */
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

/* "<SYLVA_DATA_DIR>/<rel>" in a static buffer (one of 8 rotating). */
const char *data_path(const char *rel);
/* A fresh empty directory under $TMPDIR for this test run. */
const char *test_tmpdir(void);
/* "<tmpdir>/<name>" in a rotating static buffer. */
const char *tmp_path(const char *name);
/* Writes bytes to a file; returns 0 on success. */
int write_bytes(const char *path, const void *data, size_t size);
int file_exists(const char *path);
/* Number of entries in a directory (excluding . and ..). */
int dir_entry_count(const char *dir);

#endif
