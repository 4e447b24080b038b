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
/* Little-endian stores for building binary files by hand. */
void put_le16(unsigned char *p, unsigned v);
void put_le32(unsigned char *p, uint32_t v);
void put_le64(unsigned char *p, uint64_t v);
void put_lef64(unsigned char *p, double d);
void put_lef32(unsigned char *p, float f);
/* Number of entries in a directory (excluding . and ..). */
int dir_entry_count(const char *dir);

#endif
