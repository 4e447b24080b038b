/* Airborne plots: a canopy height model (the highest normalised return per
 * cell, holes filled from their neighbours, a 3x3 binomial smoothing), tree
 * tops as its local maxima in a circular window whose diameter grows with
 * the height (Popescu & Wynne 2004, "Seeing the trees in the forest",
 * Photogramm. Eng. Remote Sens. 70:589-604), and crowns grown from the tops
 * in order of decreasing height, a marker-controlled watershed with the
 * admission rules of Dalponte & Coomes 2016 (Methods Ecol. Evol.
 * 7:1236-1245): a cell joins a neighbouring crown when it is above the
 * minimum height, above seed_ratio of the crown's top and crown_ratio of
 * the crown's mean height, and within max_crown_radius of the top. Points
 * take the crown of their cell. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "segment_internal.h"

typedef struct {
    size_t nx, ny;
    double cell;
    double *h;
} grid;

static sy_code chm_build(const seg_frame *f, const sy_segment_options *o, grid *g, sy_error *err)
{
    g->cell = o->chm_cell;
    double w = (f->hi[0] - f->lo[0]) / g->cell + 1, hgt = (f->hi[1] - f->lo[1]) / g->cell + 1;
    if (w * hgt > 1e8)
        return sy_fail(err, SY_EINPUT, "segment: a %.0f x %.0f m plot needs more than 1e8 canopy cells of %.3g m",
                       f->hi[0] - f->lo[0], f->hi[1] - f->lo[1], g->cell);
    g->nx = (size_t)w;
    g->ny = (size_t)hgt;
    size_t nc = g->nx * g->ny;
    g->h = sy_calloc(nc, sizeof *g->h, err, "canopy height model");
    double *tmp = sy_calloc(nc, sizeof *tmp, err, "canopy height model");
    if (!g->h || !tmp) {
        free(g->h), free(tmp);
        g->h = NULL;
        return SY_EINTERNAL;
    }
    for (size_t c = 0; c < nc; c++) g->h[c] = -INFINITY;
    for (size_t i = 0; i < f->n; i++) {
        size_t c = (size_t)((f->xyz[3 * i + 1] - f->lo[1]) / g->cell) * g->nx + (size_t)((f->xyz[3 * i] - f->lo[0]) / g->cell);
        double h = f->ground[i] ? 0 : fmax(f->hag[i], 0);
        if (h > g->h[c]) g->h[c] = h;
    }
    /* Holes (cells no return fell in) take the mean of their filled
     * neighbours, a few rings deep; what stays empty is open ground. */
    for (int pass = 0; pass < 4; pass++) {
        int changed = 0;
        memcpy(tmp, g->h, nc * sizeof *tmp);
        for (size_t y = 0; y < g->ny; y++)
            for (size_t x = 0; x < g->nx; x++) {
                if (isfinite(g->h[y * g->nx + x])) continue;
                double s = 0;
                int k = 0;
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++) {
                        long xx = (long)x + dx, yy = (long)y + dy;
                        if (xx < 0 || yy < 0 || xx >= (long)g->nx || yy >= (long)g->ny) continue;
                        double v = g->h[(size_t)yy * g->nx + (size_t)xx];
                        if (isfinite(v)) s += v, k++;
                    }
                if (k) tmp[y * g->nx + x] = s / k, changed = 1;
            }
        memcpy(g->h, tmp, nc * sizeof *tmp);
        if (!changed) break;
    }
    for (size_t c = 0; c < nc; c++)
        if (!isfinite(g->h[c])) g->h[c] = 0;
    /* 3x3 binomial smoothing: single returns poking out of a crown make
     * false maxima otherwise. */
    static const double wgt[3] = {1, 2, 1};
    for (size_t y = 0; y < g->ny; y++)
        for (size_t x = 0; x < g->nx; x++) {
            double s = 0, ws = 0;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    long xx = (long)x + dx, yy = (long)y + dy;
                    if (xx < 0 || yy < 0 || xx >= (long)g->nx || yy >= (long)g->ny) continue;
                    double wv = wgt[dx + 1] * wgt[dy + 1];
                    s += wv * g->h[(size_t)yy * g->nx + (size_t)xx];
                    ws += wv;
                }
            tmp[y * g->nx + x] = s / ws;
        }
    memcpy(g->h, tmp, nc * sizeof *tmp);
    free(tmp);
    return SY_OK;
}

/* Cell a outranks cell b: higher, or as high and earlier (plateaus keep one top). */
static int outranks(const double *h, size_t a, size_t b) { return h[a] > h[b] || (h[a] == h[b] && a < b); }

sy_code seg_chm_watershed(const seg_frame *f, const sy_segment_options *o, int tops_only, seg_top **tops,
                          size_t *n_tops, int32_t *label, sy_error *err)
{
    *tops = NULL;
    *n_tops = 0;
    grid g = {0};
    sy_code rc = chm_build(f, o, &g, err);
    if (rc) return rc;
    size_t nc = g.nx * g.ny, cap = 0, nt = 0;
    seg_top *t = NULL;
    int32_t *cl = sy_calloc(nc, sizeof *cl, err, "crown cells");
    if (!cl) rc = SY_EINTERNAL;
    for (size_t y = 0; y < g.ny && rc == SY_OK; y++)
        for (size_t x = 0; x < g.nx; x++) {
            size_t c = y * g.nx + x;
            double h = g.h[c];
            if (h < o->min_height || h <= 0) continue;
            double ws = fmin(o->window_base + o->window_slope * h, o->window_max);
            double rad = 0.5 * ws / g.cell;
            long r = (long)rad;
            int top = 1;
            for (long dy = -r; dy <= r && top; dy++)
                for (long dx = -r; dx <= r; dx++) {
                    if ((!dx && !dy) || (double)(dx * dx + dy * dy) > rad * rad) continue;
                    long xx = (long)x + dx, yy = (long)y + dy;
                    if (xx < 0 || yy < 0 || xx >= (long)g.nx || yy >= (long)g.ny) continue;
                    if (outranks(g.h, (size_t)yy * g.nx + (size_t)xx, c)) {
                        top = 0;
                        break;
                    }
                }
            if (!top) continue;
            if (nt == cap) {
                cap = cap ? 2 * cap : 256;
                seg_top *nt2 = realloc(t, cap * sizeof *t);
                if (!nt2) {
                    rc = sy_fail(err, SY_EINTERNAL, "segment: out of memory for tree tops");
                    break;
                }
                t = nt2;
            }
            t[nt].x = f->lo[0] + ((double)x + 0.5) * g.cell;
            t[nt].y = f->lo[1] + ((double)y + 0.5) * g.cell;
            t[nt].h = h;
            cl[c] = (int32_t)++nt;
        }
    if (rc || tops_only) {
        free(g.h), free(cl);
        if (rc) free(t);
        else *tops = t, *n_tops = nt;
        return rc;
    }
    /* Crowns: grow from every top at once, the highest cell first. */
    double *sum = sy_calloc(nt + 1, sizeof *sum, err, "crowns");
    size_t *count = sy_calloc(nt + 1, sizeof *count, err, "crowns");
    size_t *top_cell = sy_calloc(nt + 1, sizeof *top_cell, err, "crowns");
    seg_heap heap = {0};
    if (!sum || !count || !top_cell) rc = SY_EINTERNAL;
    for (size_t c = 0; c < nc && rc == SY_OK; c++)
        if (cl[c] > 0) {
            sum[cl[c]] = g.h[c];
            count[cl[c]] = 1;
            top_cell[cl[c]] = c;
            rc = seg_heap_push(&heap, -g.h[c], (uint32_t)c, err);
        }
    double maxr = o->max_crown_radius / g.cell;
    while (rc == SY_OK) {
        double negh;
        uint32_t c;
        if (!seg_heap_pop(&heap, &negh, &c)) break;
        int32_t id = cl[c];
        size_t x = c % g.nx, y = c / g.nx, tc = top_cell[id];
        double th = g.h[tc], tx = (double)(tc % g.nx), ty = (double)(tc / g.nx);
        static const int nbx[4] = {1, -1, 0, 0}, nby[4] = {0, 0, 1, -1};
        for (int k = 0; k < 4; k++) {
            long xx = (long)x + nbx[k], yy = (long)y + nby[k];
            if (xx < 0 || yy < 0 || xx >= (long)g.nx || yy >= (long)g.ny) continue;
            size_t nb = (size_t)yy * g.nx + (size_t)xx;
            if (cl[nb]) continue;
            double h = g.h[nb];
            double ddx = (double)xx - tx, ddy = (double)yy - ty;
            if (h < o->min_height || h > th || h < o->seed_ratio * th || h < o->crown_ratio * sum[id] / (double)count[id] ||
                ddx * ddx + ddy * ddy > maxr * maxr)
                continue;
            cl[nb] = id;
            sum[id] += h;
            count[id]++;
            if ((rc = seg_heap_push(&heap, -h, (uint32_t)nb, err))) break;
        }
    }
    if (rc == SY_OK)
        for (size_t i = 0; i < f->n; i++) {
            if (f->ground[i]) {
                label[i] = 0;
                continue;
            }
            size_t c = (size_t)((f->xyz[3 * i + 1] - f->lo[1]) / g.cell) * g.nx + (size_t)((f->xyz[3 * i] - f->lo[0]) / g.cell);
            label[i] = cl[c] > 0 ? cl[c] : -1;
        }
    free(g.h), free(cl), free(sum), free(count), free(top_cell);
    seg_heap_free(&heap);
    if (rc) free(t);
    else *tops = t, *n_tops = nt;
    return rc;
}
