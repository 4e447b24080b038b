/* Reading an exported .glb back in tests: numbers at printf-formatted JSON
 * pointers and the raw bytes of uncompressed accessors. Header-only so every
 * test that checks a GLB shares it. */
#ifndef SYLVA_GLB_READ_H
#define SYLVA_GLB_READ_H

#include <stdarg.h>
#include <stdio.h>

#include "stages/gltf/gltf_read.h"
#include "testutil.h"

/* Formats the pointer of a variadic fmt into the char array p. */
#define GLB_POINTER(p, fmt)                  \
    do {                                     \
        va_list ap_;                         \
        va_start(ap_, fmt);                  \
        vsnprintf(p, sizeof p, fmt, ap_);    \
        va_end(ap_);                         \
    } while (0)

/* The number at a formatted pointer, -1 when absent (no count, index or
 * factor the tests read this way is negative). */
static double glb_num(const sy_gltf_file *f, const char *fmt, ...) __attribute__((format(printf, 2, 3), unused));
static double glb_num(const sy_gltf_file *f, const char *fmt, ...)
{
    char p[256];
    GLB_POINTER(p, fmt);
    return sy_gltf_number(f, p, -1);
}

static int glb_has(const sy_gltf_file *f, const char *fmt, ...) __attribute__((format(printf, 2, 3), unused));
static int glb_has(const sy_gltf_file *f, const char *fmt, ...)
{
    char p[256];
    GLB_POINTER(p, fmt);
    return sy_gltf_has(f, p);
}

/* Raw bytes of an accessor stored uncompressed in the BIN chunk; count and
 * byteStride (0 when tightly packed) through the out parameters. */
static const unsigned char *glb_accessor(const sy_gltf_file *f, int acc, size_t *count, size_t *stride)
    __attribute__((unused));
static const unsigned char *glb_accessor(const sy_gltf_file *f, int acc, size_t *count, size_t *stride)
{
    int view = (int)glb_num(f, "/accessors/%d/bufferView", acc);
    assert_int_equal((int)glb_num(f, "/bufferViews/%d/buffer", view), 0);
    char p[64];
    snprintf(p, sizeof p, "/bufferViews/%d/byteOffset", view);
    size_t off = (size_t)sy_gltf_number(f, p, 0);
    size_t len = (size_t)glb_num(f, "/bufferViews/%d/byteLength", view);
    size_t bin_size;
    const unsigned char *bin = sy_gltf_bin(f, &bin_size);
    assert_true(off + len <= bin_size);
    *count = (size_t)glb_num(f, "/accessors/%d/count", acc);
    snprintf(p, sizeof p, "/bufferViews/%d/byteStride", view);
    *stride = (size_t)sy_gltf_number(f, p, 0);
    return bin + off;
}

#endif
