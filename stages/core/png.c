/* PNG encoding through zlib (PNG specification, ISO/IEC 15948:2004): one
 * encoder for the textures, leaf maps and the impostor. GPL-3.0-or-later. */
#include "stages/core/png.h"

#include <limits.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <zlib.h>

typedef struct {
    unsigned char *p;
    size_t n, cap;
    int failed;
} bytes;

static void put(bytes *b, const void *d, size_t n)
{
    if (b->failed) return;
    if (b->n + n > b->cap) {
        size_t cap = b->cap * 2 + n + 256;
        unsigned char *q = realloc(b->p, cap);
        if (!q) {
            b->failed = 1;
            return;
        }
        b->p = q;
        b->cap = cap;
    }
    memcpy(b->p + b->n, d, n);
    b->n += n;
}

static void put_u32(bytes *b, uint32_t v)
{
    unsigned char x[4] = {(unsigned char)(v >> 24), (unsigned char)(v >> 16), (unsigned char)(v >> 8), (unsigned char)v};
    put(b, x, 4);
}

static void chunk(bytes *b, const char *type, const unsigned char *d, size_t n)
{
    put_u32(b, (uint32_t)n);
    put(b, type, 4);
    if (n) put(b, d, n);
    uLong crc = crc32(0L, (const Bytef *)type, 4);
    if (n) crc = crc32(crc, d, (uInt)n);
    put_u32(b, (uint32_t)crc);
}

static int paeth(int a, int b, int c)
{
    int p = a + b - c, pa = abs(p - a), pb = abs(p - b), pc = abs(p - c);
    return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

/* Filters one row with filter type f into out (1 + stride bytes) and
 * returns the sum of its filtered bytes' absolute values as signed bytes.
 * bpp: bytes per pixel; prev is NULL for the first row (a zero row). One
 * loop per type: a switch per byte made encoding a fifth of a tree's
 * meshing (its impostor). */
static unsigned long filter_row(int f, const unsigned char *row, const unsigned char *prev, size_t stride, int bpp,
                                unsigned char *out)
{
    unsigned char *o = out + 1;
    size_t lead = (size_t)bpp < stride ? (size_t)bpp : stride; /* bytes with no left neighbour */
    out[0] = (unsigned char)f;
    switch (f) {
    case 1:
        memcpy(o, row, lead);
        for (size_t i = lead; i < stride; i++) o[i] = (unsigned char)(row[i] - row[i - (size_t)bpp]);
        break;
    case 2:
        for (size_t i = 0; i < stride; i++) o[i] = (unsigned char)(row[i] - (prev ? prev[i] : 0));
        break;
    case 3:
        for (size_t i = 0; i < lead; i++) o[i] = (unsigned char)(row[i] - (prev ? prev[i] : 0) / 2);
        for (size_t i = lead; i < stride; i++)
            o[i] = (unsigned char)(row[i] - (row[i - (size_t)bpp] + (prev ? prev[i] : 0)) / 2);
        break;
    case 4:
        if (!prev) { /* Paeth of (a, 0, 0) is a: the Sub filter */
            memcpy(o, row, lead);
            for (size_t i = lead; i < stride; i++) o[i] = (unsigned char)(row[i] - row[i - (size_t)bpp]);
            break;
        }
        for (size_t i = 0; i < lead; i++) o[i] = (unsigned char)(row[i] - prev[i]); /* Paeth of (0, b, 0) is b */
        for (size_t i = lead; i < stride; i++)
            o[i] = (unsigned char)(row[i] - paeth(row[i - (size_t)bpp], prev[i], prev[i - (size_t)bpp]));
        break;
    default: memcpy(o, row, stride);
    }
    unsigned long sum = 0;
    for (size_t i = 0; i < stride; i++) sum += (unsigned long)abs((int)(signed char)o[i]);
    return sum;
}

/* PNG of 8- or 16-bit samples (big-endian, as PNG stores them). Filters by
 * the specification's suggested heuristic: per row, the type whose output
 * has the least sum of absolute values as signed bytes. zlib level 3: within
 * a few percent of the best size at a third of the time. */
int sy_png_encode(const unsigned char *samples, int w, int h, int c, int bits, unsigned char **png, size_t *size)
{
    if (w <= 0 || h <= 0 || (c < 1 || c > 4) || (bits != 8 && bits != 16)) return -1;
    int bpp = c * bits / 8;
    size_t stride = (size_t)w * (size_t)bpp, raw_n = (stride + 1) * (size_t)h;
    unsigned char *raw = malloc(raw_n), *cand = malloc(5 * (stride + 1));
    if (!raw || !cand) {
        free(raw), free(cand);
        return -1;
    }
    for (int y = 0; y < h; y++) {
        const unsigned char *row = samples + (size_t)y * stride, *prev = y ? row - stride : NULL;
        unsigned long best = ULONG_MAX;
        int pick = 0;
        for (int f = 0; f < 5; f++) {
            unsigned long s = filter_row(f, row, prev, stride, bpp, cand + (size_t)f * (stride + 1));
            if (s < best) best = s, pick = f; /* the first of equal sums, as before */
        }
        memcpy(raw + (size_t)y * (stride + 1), cand + (size_t)pick * (stride + 1), stride + 1);
    }
    free(cand);
    uLongf zn = compressBound((uLong)raw_n);
    unsigned char *z = malloc(zn);
    int ok = z && compress2(z, &zn, raw, (uLong)raw_n, 3) == Z_OK;
    free(raw);
    bytes b = {0};
    if (ok) {
        static const unsigned char sig[8] = {137, 80, 78, 71, 13, 10, 26, 10};
        static const unsigned char type[5] = {0, 0, 4, 2, 6}; /* by c: grey, grey+alpha, RGB, RGBA */
        unsigned char ihdr[13];
        uint32_t W = (uint32_t)w, H = (uint32_t)h;
        for (int i = 0; i < 4; i++) ihdr[i] = (unsigned char)(W >> (24 - 8 * i)), ihdr[4 + i] = (unsigned char)(H >> (24 - 8 * i));
        ihdr[8] = (unsigned char)bits;
        ihdr[9] = type[c];
        ihdr[10] = ihdr[11] = ihdr[12] = 0;
        put(&b, sig, 8);
        chunk(&b, "IHDR", ihdr, 13);
        chunk(&b, "IDAT", z, zn);
        chunk(&b, "IEND", NULL, 0);
    }
    free(z);
    if (!ok || b.failed) {
        free(b.p);
        return -1;
    }
    *png = b.p;
    *size = b.n;
    return 0;
}

