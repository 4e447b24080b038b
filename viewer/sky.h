/* Daylight for the preview: the Preetham, Shirley & Smits (1999) analytic sky and its
 * projection into second-order spherical harmonics for ambient light (Habel 2009 ch. 5 uses
 * the same sky through SH; here the projection is integrated numerically at start-up and
 * whenever the sun moves, ~1 ms). World frame: Y up. */
#ifndef SYLVA_VIEWER_SKY_H
#define SYLVA_VIEWER_SKY_H

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    float perez[5][3];    /* A..E for (Y, x, y) */
    float zenith[3];      /* Y (kcd/m^2), x, y */
    float perez_sun[3];   /* F(0, theta_s): the normaliser */
    float scale;          /* luminance -> render units */
    float sun_dir[3];     /* unit, towards the sun */
    float sun_color[3];   /* render units */
    float sh[9][3];       /* irradiance/pi in the shader's basis (diffuse albedo * sh = radiance) */
} sy_sky;

/* Sun at azimuth az (degrees from +X towards +Z) and elevation el (degrees above the
 * horizon), turbidity in [1.7, 10] (Preetham's valid range; clamped). */
void sy_sky_make(sy_sky *sky, double az_deg, double el_deg, double turbidity);

/* Sky radiance (render units, linear sRGB) in unit direction d (world, Y up). */
void sy_sky_radiance(const sy_sky *sky, const double d[3], double rgb[3]);

#ifdef __cplusplus
}
#endif

#endif
