/* The confusion matrix as a PNG heatmap: row labels (truth) on the left,
 * column labels (prediction) written upwards on top, counts in the cells,
 * cell shade by the row-normalised share. Text in the 5x7 font of text_raster.c. */
#include <stdlib.h>
#include <string.h>

#include <stb_image_write.h>

#include "eval.h"
#include "eval_internal.h"
#include "stages/core/fileio.h"

#define MARGIN 8

typedef struct {
    int label_w, label_h, cell, w, h;
} layout;

static layout plan(const sy_confusion *c)
{
    layout L;
    int longest = sy_canvas_text_width("truth");
    for (size_t k = 0; k < c->n_classes; k++)
        if (sy_canvas_text_width(c->labels[k]) > longest) longest = sy_canvas_text_width(c->labels[k]);
    size_t biggest = 0;
    for (size_t k = 0; k < c->n_classes * c->n_classes; k++)
        if (c->matrix[k] > biggest) biggest = c->matrix[k];
    char digits[32];
    int nd = snprintf(digits, sizeof digits, "%zu", biggest);
    L.cell = nd * SY_GLYPH_W + 10 > 28 ? nd * SY_GLYPH_W + 10 : 28;
    L.label_w = longest + 2 * MARGIN;
    L.label_h = longest + 2 * MARGIN + SY_GLYPH_H; /* upward labels plus the "predicted" caption */
    L.w = L.label_w + (int)c->n_classes * L.cell + MARGIN;
    L.h = L.label_h + (int)c->n_classes * L.cell + MARGIN;
    return L;
}

void sy_confusion_png_size(const sy_confusion *c, int *width, int *height)
{
    layout L = plan(c);
    *width = L.w;
    *height = L.h;
}

static void write_to_buffer(void *ctx, void *data, int size)
{
    sy_buffer *b = ctx;
    if (size <= 0 || !b->data) return;
    unsigned char *g = realloc(b->data, b->size + (size_t)size + 1);
    if (!g) {
        free(b->data);
        b->data = NULL;
        return;
    }
    memcpy(g + b->size, data, (size_t)size);
    b->data = g;
    b->size += (size_t)size;
}

sy_code sy_confusion_png(const sy_confusion *c, const char *path, sy_error *err)
{
    if (c->n_classes == 0) return sy_fail(err, SY_EINPUT, "%s: empty confusion matrix", path);
    if (c->n_classes > 400) return sy_fail(err, SY_EINPUT, "%s: %zu classes are too many to plot", path, c->n_classes);
    layout L = plan(c);
    sy_canvas cv = {sy_calloc((size_t)L.w * (size_t)L.h, 3, err, "confusion image"), L.w, L.h};
    if (!cv.px) return SY_EINTERNAL;
    memset(cv.px, 255, (size_t)L.w * (size_t)L.h * 3);
    static const unsigned char black[3] = {0, 0, 0}, white[3] = {255, 255, 255}, grey[3] = {150, 150, 150};
    size_t n = c->n_classes;
    sy_canvas_text(&cv, MARGIN, MARGIN, "truth", 0, grey);
    sy_canvas_text(&cv, L.label_w, MARGIN, "predicted", 0, grey);
    for (size_t r = 0; r < n; r++) {
        int y0 = L.label_h + (int)r * L.cell, x0 = L.label_w + (int)r * L.cell;
        sy_canvas_text(&cv, MARGIN, y0 + (L.cell - 7) / 2, c->labels[r], 0, black);
        sy_canvas_text(&cv, x0 + (L.cell - 7) / 2, L.label_h - MARGIN, c->labels[r], 1, black);
        size_t row_sum = 0;
        for (size_t k = 0; k < n; k++) row_sum += c->matrix[r * n + k];
        for (size_t k = 0; k < n; k++) {
            size_t v = c->matrix[r * n + k];
            double share = row_sum ? (double)v / (double)row_sum : 0;
            /* White to deep blue. */
            unsigned char rgb[3] = {(unsigned char)(255 - 247 * share), (unsigned char)(255 - 207 * share),
                                    (unsigned char)(255 - 148 * share)};
            int cx = L.label_w + (int)k * L.cell;
            for (int y = 1; y < L.cell; y++)
                for (int x = 1; x < L.cell; x++) sy_canvas_set(&cv, cx + x, y0 + y, rgb);
            char num[32];
            snprintf(num, sizeof num, "%zu", v);
            sy_canvas_text(&cv, cx + (L.cell - sy_canvas_text_width(num)) / 2 + 1, y0 + (L.cell - 7) / 2, num, 0,
                      share > 0.5 ? white : black);
        }
    }
    sy_buffer png = {malloc(1), 0};
    int ok = png.data && stbi_write_png_to_func(write_to_buffer, &png, L.w, L.h, 3, cv.px, L.w * 3);
    free(cv.px);
    sy_code rc = ok && png.data ? sy_write_file_atomic(path, png.data, png.size, err)
                                : sy_fail(err, SY_EINTERNAL, "%s: PNG encoding failed", path);
    free(png.data);
    return rc;
}
