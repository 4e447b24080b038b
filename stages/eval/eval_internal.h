/* Shared within the eval stage; not part of its API. */
#ifndef SYLVA_EVAL_INTERNAL_H
#define SYLVA_EVAL_INTERNAL_H

/* An RGB canvas, rows top down (text_raster.c). */
typedef struct {
    unsigned char *px;
    int w, h;
} sy_canvas;

#define SY_GLYPH_W 6 /* 5 columns + 1 spacing */
#define SY_GLYPH_H 8
#define SY_TEXT_MAX 24 /* characters drawn of a text */

/* One pixel; outside the canvas nothing. */
void sy_canvas_set(sy_canvas *c, int x, int y, const unsigned char rgb[3]);
/* Text in the 5x7 font with its top-left at (x, y); upward (rotated 90
 * degrees counter-clockwise, reading bottom to top) when up is set, then
 * (x, y) is its bottom-left. */
void sy_canvas_text(sy_canvas *c, int x, int y, const char *s, int up, const unsigned char rgb[3]);
int sy_canvas_text_width(const char *s);

#endif
