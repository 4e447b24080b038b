/* Push-pull colour bleeding (texture.h). */
#include "stages/core/texture.h"

#include <stdlib.h>
#include <string.h>

typedef struct {
    int w, h;
    float *v;  /* w x h x c, weighted averages */
    float *wt; /* w x h, covered weight in [0, 1] */
} level;

sy_code sy_texture_bleed(float *px, int w, int h, int stride, int c, const unsigned char *covered, sy_error *err)
{
    if (w < 1 || h < 1 || c < 1 || c > stride) return SY_OK;
    int any = 0;
    for (size_t i = 0; i < (size_t)w * (size_t)h && !any; i++) any = covered[i] != 0;
    if (!any) return SY_OK;
    /* Levels until 1 x 1: at most 64 for any int size. */
    level L[64];
    int n = 0;
    memset(L, 0, sizeof L);
    sy_code rc = SY_OK;
    size_t np = (size_t)w * (size_t)h;
    /* Level 0 is px itself when every channel bleeds; else a copy of the channels that do. */
    int own = stride != c;
    L[0].w = w, L[0].h = h;
    L[0].v = own ? malloc(np * (size_t)c * sizeof *L[0].v) : px;
    L[0].wt = malloc(np * sizeof *L[0].wt);
    if (!L[0].v || !L[0].wt) {
        if (own) free(L[0].v);
        free(L[0].wt);
        return sy_fail(err, SY_EINTERNAL, "texture: out of memory");
    }
    for (size_t i = 0; i < np; i++) {
        L[0].wt[i] = covered[i] ? 1.0f : 0.0f;
        for (int k = 0; k < c && own; k++) L[0].v[i * (size_t)c + (size_t)k] = px[i * (size_t)stride + (size_t)k];
    }
    n = 1;
    /* Pull: each coarser texel is the weighted mean of its (up to) 2 x 2 finer ones. */
    while ((L[n - 1].w > 1 || L[n - 1].h > 1) && n < 64) {
        const level *f = &L[n - 1];
        level *g = &L[n];
        g->w = (f->w + 1) / 2, g->h = (f->h + 1) / 2;
        g->v = calloc((size_t)g->w * (size_t)g->h * (size_t)c, sizeof *g->v);
        g->wt = calloc((size_t)g->w * (size_t)g->h, sizeof *g->wt);
        n++;
        if (!g->v || !g->wt) {
            rc = sy_fail(err, SY_EINTERNAL, "texture: out of memory");
            break;
        }
        for (int y = 0; y < g->h; y++)
            for (int x = 0; x < g->w; x++) {
                size_t o = (size_t)y * (size_t)g->w + (size_t)x;
                float ws = 0;
                for (int dy = 0; dy < 2; dy++)
                    for (int dx = 0; dx < 2; dx++) {
                        int fx = 2 * x + dx, fy = 2 * y + dy;
                        if (fx >= f->w || fy >= f->h) continue;
                        size_t q = (size_t)fy * (size_t)f->w + (size_t)fx;
                        float wq = f->wt[q];
                        if (wq <= 0) continue;
                        for (int k = 0; k < c; k++) g->v[o * (size_t)c + (size_t)k] += wq * f->v[q * (size_t)c + (size_t)k];
                        ws += wq;
                    }
                if (ws > 0)
                    for (int k = 0; k < c; k++) g->v[o * (size_t)c + (size_t)k] /= ws;
                g->wt[o] = ws > 1 ? 1 : ws;
            }
    }
    /* Push: a texel short of full weight blends in its coarser parent. */
    for (int l = n - 2; l >= 0 && !rc; l--) {
        level *f = &L[l];
        const level *g = &L[l + 1];
        for (int y = 0; y < f->h; y++)
            for (int x = 0; x < f->w; x++) {
                size_t q = (size_t)y * (size_t)f->w + (size_t)x, o = (size_t)(y / 2) * (size_t)g->w + (size_t)(x / 2);
                float wq = f->wt[q];
                if (wq >= 1) continue;
                if (l == 0 && covered[q]) continue;
                for (int k = 0; k < c; k++) {
                    float *d = &f->v[q * (size_t)c + (size_t)k];
                    *d = wq * *d + (1 - wq) * g->v[o * (size_t)c + (size_t)k];
                }
                f->wt[q] = 1;
            }
    }
    for (size_t i = 0; i < np && !rc && own; i++)
        if (!covered[i])
            for (int k = 0; k < c; k++) px[i * (size_t)stride + (size_t)k] = L[0].v[i * (size_t)c + (size_t)k];
    for (int l = 0; l < n; l++) {
        if (l || own) free(L[l].v);
        free(L[l].wt);
    }
    return rc;
}

sy_code sy_texture_bleed_u8(unsigned char *px, int w, int h, int stride, int c, const unsigned char *covered,
                            sy_error *err)
{
    if (w < 1 || h < 1 || c < 1 || c > stride) return SY_OK;
    /* The bleeding channels alone, as floats (bled in place), and back into the clear texels. */
    size_t np = (size_t)w * (size_t)h;
    float *f = malloc(np * (size_t)c * sizeof *f);
    if (!f) return sy_fail(err, SY_EINTERNAL, "texture: out of memory");
    for (size_t i = 0; i < np; i++)
        for (int k = 0; k < c; k++) f[i * (size_t)c + (size_t)k] = px[i * (size_t)stride + (size_t)k];
    sy_code rc = sy_texture_bleed(f, w, h, c, c, covered, err);
    for (size_t i = 0; !rc && i < np; i++)
        if (!covered[i])
            for (int k = 0; k < c; k++) {
                float v = f[i * (size_t)c + (size_t)k] + 0.5f;
                px[i * (size_t)stride + (size_t)k] = (unsigned char)(v < 0 ? 0 : v > 255 ? 255 : v);
            }
    free(f);
    return rc;
}
