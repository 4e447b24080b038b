/* Image files of the leaf-maps stage without OpenCV's imgcodecs (which loads
 * ~120 shared libraries, GDAL and DICOM among them, into every sylva
 * process): decoding through stb_image (PNG 8/16-bit, JPEG, BMP, TGA, PNM),
 * PNG encoding through zlib (PNG specification, ISO/IEC 15948:2004).
 * GPL-3.0-or-later. */
#include "stages/leafmaps/leafmaps_cv.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <stb_image.h>
#include <zlib.h>

#include "stages/core/fileio.h"

#define MAX_SIDE 16384
#define MAX_INFLATE 1032.0 /* deflate's largest expansion (RFC 1951) */

int sy_lcv_read(const char *path, float **px, int *w, int *h, int *c, int *depth)
{
    sy_buffer b;
    sy_error err = {0};
    if (sy_read_file(path, &b, &err)) return -1;
    int iw, ih, ic, rc = -1;
    if (b.size == 0 || b.size > INT_MAX || !stbi_info_from_memory(b.data, (int)b.size, &iw, &ih, &ic) || iw <= 0 ||
        ih <= 0 || iw > MAX_SIDE || ih > MAX_SIDE || ic < 1 || ic > 4 ||
        (double)iw * ih * ic * 2 > MAX_INFLATE * (double)b.size + (1 << 20)) {
        sy_buffer_free(&b);
        return -1;
    }
    int is16 = stbi_is_16_bit_from_memory(b.data, (int)b.size);
    void *raw = is16 ? (void *)stbi_load_16_from_memory(b.data, (int)b.size, &iw, &ih, &ic, 0)
                     : (void *)stbi_load_from_memory(b.data, (int)b.size, &iw, &ih, &ic, 0);
    sy_buffer_free(&b);
    if (!raw) return -1;
    int oc = ic == 2 ? 4 : ic; /* grey + alpha: expanded to RGBA */
    size_t n = (size_t)iw * (size_t)ih;
    float *out = malloc(n * (size_t)oc * sizeof *out);
    if (out) {
        float scale = is16 ? 1.0f / 65535.0f : 1.0f / 255.0f;
        const uint16_t *s16 = raw;
        const unsigned char *s8 = raw;
        for (size_t i = 0; i < n; i++) {
            float v[4];
            for (int k = 0; k < ic; k++) v[k] = (float)(is16 ? s16[i * (size_t)ic + (size_t)k] : s8[i * (size_t)ic + (size_t)k]) * scale;
            if (ic == 2) {
                v[3] = v[1];
                v[1] = v[2] = v[0];
            }
            memcpy(out + i * (size_t)oc, v, (size_t)oc * sizeof *out);
        }
        *px = out;
        *w = iw;
        *h = ih;
        *c = oc;
        *depth = is16 ? 16 : 8;
        rc = 0;
    }
    stbi_image_free(raw);
    return rc;
}

/* ------------------------------------------------------------ PNG encoding */

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

/* Filters one row with filter type f into out (1 + stride bytes). bpp: bytes
 * per pixel; prev is NULL for the first row. */
static void filter_row(int f, const unsigned char *row, const unsigned char *prev, size_t stride, int bpp,
                       unsigned char *out)
{
    out[0] = (unsigned char)f;
    for (size_t i = 0; i < stride; i++) {
        int a = i >= (size_t)bpp ? row[i - (size_t)bpp] : 0, b = prev ? prev[i] : 0;
        int c = prev && i >= (size_t)bpp ? prev[i - (size_t)bpp] : 0, x = row[i], p = 0;
        switch (f) {
        case 1: p = a; break;
        case 2: p = b; break;
        case 3: p = (a + b) / 2; break;
        case 4: p = paeth(a, b, c); break;
        default: p = 0;
        }
        out[i + 1] = (unsigned char)(x - p);
    }
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
    unsigned char *raw = malloc(raw_n), *cand = malloc(stride + 1);
    if (!raw || !cand) {
        free(raw), free(cand);
        return -1;
    }
    for (int y = 0; y < h; y++) {
        const unsigned char *row = samples + (size_t)y * stride, *prev = y ? row - stride : NULL;
        unsigned char *dst = raw + (size_t)y * (stride + 1);
        unsigned long best = ULONG_MAX;
        for (int f = 0; f < 5; f++) {
            filter_row(f, row, prev, stride, bpp, cand);
            unsigned long s = 0;
            for (size_t i = 1; i <= stride; i++) s += (unsigned long)abs((int)(signed char)cand[i]);
            if (s < best) {
                best = s;
                memcpy(dst, cand, stride + 1);
            }
        }
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

int sy_lcv_encode_png(const float *px, int w, int h, int c, int bits, unsigned char **png, size_t *size)
{
    if ((c != 1 && c != 3 && c != 4) || w <= 0 || h <= 0 || (bits != 8 && bits != 16)) return -1;
    size_t n = (size_t)w * (size_t)h * (size_t)c, bps = (size_t)bits / 8;
    unsigned char *q = malloc(n * bps);
    if (!q) return -1;
    float maxv = bits == 16 ? 65535.0f : 255.0f;
    for (size_t i = 0; i < n; i++) {
        float v = px[i] * maxv;
        /* Round to nearest, saturate; NaN reads as 0. */
        long s = v > 0 ? (v < maxv ? lrintf(v) : (long)maxv) : 0;
        if (bits == 16) {
            q[2 * i] = (unsigned char)(s >> 8);
            q[2 * i + 1] = (unsigned char)s;
        } else
            q[i] = (unsigned char)s;
    }
    int rc = sy_png_encode(q, w, h, c, bits, png, size);
    free(q);
    return rc;
}
