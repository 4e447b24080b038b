/* Ground: a sloped plane plus seeded value noise, sampled on a regular grid
 * and triangulated. Rays hit the triangles, and sy_terrain_height evaluates
 * the very same triangles, so trees stand exactly on the surface scanned. */
#include <math.h>

#include "scan.h"
#include "stages/core/rng.h"

#define PI 3.14159265358979323846

static uint64_t mix64(uint64_t z) { return sy_mix64(z); }

/* Lattice value in [-1, 1]. */
static double lattice(uint64_t seed, int64_t ix, int64_t iy, int octave)
{
    uint64_t h = mix64(seed ^ mix64((uint64_t)ix * 0x8CB92BA72F3D8DD7ull ^ mix64((uint64_t)iy + (uint64_t)octave * 131)));
    return (double)(h >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

static double smooth(double t) { return t * t * (3 - 2 * t); }

static double value_noise(uint64_t seed, double x, double y, int octave)
{
    double fx = floor(x), fy = floor(y);
    int64_t ix = (int64_t)fx, iy = (int64_t)fy;
    double tx = smooth(x - fx), ty = smooth(y - fy);
    double a = lattice(seed, ix, iy, octave), b = lattice(seed, ix + 1, iy, octave);
    double c = lattice(seed, ix, iy + 1, octave), d = lattice(seed, ix + 1, iy + 1, octave);
    return (a + (b - a) * tx) * (1 - ty) + (c + (d - c) * tx) * ty;
}

double sy_terrain_field(const sy_terrain *t, double x, double y)
{
    double a = t->aspect_deg * PI / 180;
    double z = t->base + tan(t->slope_deg * PI / 180) * (x * cos(a) + y * sin(a));
    if (t->roughness > 0) {
        double f = t->feature > 0 ? t->feature : 6.0, n = 0, amp = 1, norm = 0;
        for (int o = 0; o < 3; o++) {
            n += amp * value_noise(t->seed, x / f, y / f, o);
            norm += amp;
            amp *= 0.5;
            f *= 0.5;
        }
        z += t->roughness * n / norm;
    }
    return z;
}

static void grid_size(const sy_terrain *t, long *nx, long *ny)
{
    *nx = (long)ceil((t->hi[0] - t->lo[0]) / t->step);
    *ny = (long)ceil((t->hi[1] - t->lo[1]) / t->step);
    if (*nx < 1) *nx = 1;
    if (*ny < 1) *ny = 1;
}

/* Grid vertex (i, j) exactly as stored in the triangles. */
static void vertex(const sy_terrain *t, long i, long j, float v[3])
{
    v[0] = (float)(t->lo[0] + i * t->step);
    v[1] = (float)(t->lo[1] + j * t->step);
    v[2] = (float)sy_terrain_field(t, v[0], v[1]);
}

double sy_terrain_height(const sy_terrain *t, double x, double y)
{
    long nx, ny;
    grid_size(t, &nx, &ny);
    long i = (long)floor((x - t->lo[0]) / t->step), j = (long)floor((y - t->lo[1]) / t->step);
    if (i < 0 || j < 0 || i >= nx || j >= ny) return sy_terrain_field(t, x, y);
    float v00[3], v10[3], v01[3], v11[3];
    vertex(t, i, j, v00);
    vertex(t, i + 1, j, v10);
    vertex(t, i, j + 1, v01);
    vertex(t, i + 1, j + 1, v11);
    double fx = (x - v00[0]) / ((double)v10[0] - v00[0]), fy = (y - v00[1]) / ((double)v01[1] - v00[1]);
    /* Cells split along the v00-v11 diagonal, as in sy_terrain_triangulate. */
    if (fx >= fy) return v00[2] + fx * ((double)v10[2] - v00[2]) + fy * ((double)v11[2] - v10[2]);
    return v00[2] + fy * ((double)v01[2] - v00[2]) + fx * ((double)v11[2] - v01[2]);
}

sy_code sy_terrain_triangulate(const sy_terrain *t, sy_prims *out, sy_error *err)
{
    if (!(t->step > 0) || !(t->hi[0] > t->lo[0]) || !(t->hi[1] > t->lo[1]))
        return sy_fail(err, SY_EINPUT, "terrain: empty extent or step");
    long nx, ny;
    grid_size(t, &nx, &ny);
    if ((double)nx * ny > 4e6) return sy_fail(err, SY_EINPUT, "terrain: %ld x %ld cells is too fine", nx, ny);
    for (long j = 0; j < ny; j++)
        for (long i = 0; i < nx; i++) {
            float v00[3], v10[3], v01[3], v11[3];
            vertex(t, i, j, v00);
            vertex(t, i + 1, j, v10);
            vertex(t, i, j + 1, v01);
            vertex(t, i + 1, j + 1, v11);
            sy_prim a = sy_prim_tri(v00, v10, v11), b = sy_prim_tri(v00, v11, v01);
            if (sy_prims_push(out, &a, err) || sy_prims_push(out, &b, err)) return err->code;
        }
    return SY_OK;
}
