/* Image files of the leaf-maps stage without OpenCV's imgcodecs (which loads
 * ~120 shared libraries, GDAL and DICOM among them, into every sylva
 * process): decoding through stb_image (PNG 8/16-bit, JPEG, BMP, TGA, PNM),
 * PNG encoding through stages/core/png.c.
 * GPL-3.0-or-later. */
#include "stages/leafmaps/leafmaps_cv.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <stb_image.h>

#include "stages/core/fileio.h"
#include "stages/core/png.h"

#define MAX_SIDE 16384
#define MAX_INFLATE 1032.0 /* deflate's largest expansion (RFC 1951) */

sy_code sy_lcv_read(const char *path, float **px, int *w, int *h, int *c, int *depth, sy_error *err)
{
    sy_buffer b;
    if (sy_read_file(path, &b, err)) return err->code;
    int iw, ih, ic;
    if (b.size == 0 || b.size > INT_MAX || !stbi_info_from_memory(b.data, (int)b.size, &iw, &ih, &ic) || iw <= 0 ||
        ih <= 0 || iw > MAX_SIDE || ih > MAX_SIDE || ic < 1 || ic > 4 ||
        (double)iw * ih * ic * 2 > MAX_INFLATE * (double)b.size + (1 << 20)) {
        sy_buffer_free(&b);
        return sy_fail(err, SY_EINPUT, "%s: not an image this build can decode", path);
    }
    int is16 = stbi_is_16_bit_from_memory(b.data, (int)b.size);
    void *raw = is16 ? (void *)stbi_load_16_from_memory(b.data, (int)b.size, &iw, &ih, &ic, 0)
                     : (void *)stbi_load_from_memory(b.data, (int)b.size, &iw, &ih, &ic, 0);
    sy_buffer_free(&b);
    if (!raw) return sy_fail(err, SY_EINPUT, "%s: not an image this build can decode", path);
    int oc = ic == 2 ? 4 : ic; /* grey + alpha: expanded to RGBA */
    size_t n = (size_t)iw * (size_t)ih;
    float *out = sy_calloc(n, (size_t)oc * sizeof *out, err, path);
    sy_code rc = out ? SY_OK : SY_EINTERNAL;
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
    }
    stbi_image_free(raw);
    return rc;
}

sy_code sy_lcv_encode_png(const float *px, int w, int h, int c, int bits, unsigned char **png, size_t *size,
                          sy_error *err)
{
    if ((c != 1 && c != 3 && c != 4) || w <= 0 || h <= 0 || (bits != 8 && bits != 16))
        return sy_fail(err, SY_EINTERNAL, "PNG encoding: %d x %d, %d channels of %d bits is no PNG this encodes", w, h,
                       c, bits);
    size_t n = (size_t)w * (size_t)h * (size_t)c, bps = (size_t)bits / 8;
    unsigned char *q = sy_calloc(n, bps, err, "PNG encoding");
    if (!q) return SY_EINTERNAL;
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
    int bad = sy_png_encode(q, w, h, c, bits, png, size);
    free(q);
    return bad ? sy_fail(err, SY_EINTERNAL, "PNG encoding: out of memory") : SY_OK;
}
