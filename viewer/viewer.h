/* The GL preview (`sylva view`, the `sylva-view` executable): options, the loaded scene and
 * the renderer. OpenGL 3.3 core through epoxy; headless through EGL surfaceless Mesa, a
 * window through GLFW. Nothing else in Sylva links GL: `sylva view` runs this executable. */
#ifndef SYLVA_VIEWER_H
#define SYLVA_VIEWER_H

#include <stddef.h>
#include <stdint.h>

#include "stages/gltf/gltf_read.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int width, height;
    int camera_set;                 /* --camera given */
    double cam_az, cam_el, cam_dist; /* degrees, degrees, metres (dist <= 0: frame the scene) */
    int target_set;                 /* --target given */
    double target[3];               /* orbit centre, world (glTF frame) */
    double time;                    /* seconds of wind */
    const char *screenshot;         /* PNG path, headless */
    int frames;                     /* > 0: headless animation */
    double fps;
    const char *out_dir;
    int wind;                       /* on/off */
    double wind_strength;           /* 1 = a fresh breeze */
    double wind_dir_deg;            /* heading the wind blows towards, degrees from +X towards +Z */
    double wind_stop;               /* time at which the wind stops (< 0: never) */
    int static_load;                /* steady push only (tests of the beam) */
    int translucency;
    int lod_override;               /* -1: by screen coverage */
    int grass, ground, shadows, stats, mask, wireframe;
    double sun_az, sun_el, turbidity, ambient, exposure;
    const char *points;
    int show_points;                /* the overlay toggle (key P) */
    int points_beside;
    int copies;                     /* copies of every tree, laid out on the ground */
    double spacing;                 /* metres between trees (<= 0: from their size) */
    int json;
    int bench;                      /* frames to time */
    const char *dump_wind;          /* CSV of rest and swayed vertices (transform feedback) */
    uint64_t seed;
} sy_view_options;

sy_view_options sy_view_options_default(void);

/* A point cloud in the glTF frame of the first tree (positions and colours, 3 floats each). */
typedef struct {
    size_t n;
    float *xyz;
    float *rgb;
} sy_view_points;

typedef struct {
    sy_gltf_scene *scenes;
    size_t n_scenes;
    char **paths;
    sy_view_points points;
} sy_view_input;

/* Renders the input with the options: headless when a screenshot, frames, a bench or a wind
 * dump is asked for, else in a window. Returns the exit status (0, 2 bad input or no GL, 3). */
int sy_view_run(const sy_view_input *in, const sy_view_options *opt);

/* GL context (context.c). */
typedef struct sy_gl_context sy_gl_context;
/* Headless (EGL surfaceless) or windowed (GLFW); NULL and msg set when no OpenGL 3.3 core is
 * available. */
sy_gl_context *sy_gl_open(int headless, int width, int height, const char *title, char *msg, size_t msg_size);
void sy_gl_close(sy_gl_context *c);
/* Window only: */
void *sy_gl_window(sy_gl_context *c); /* the GLFWwindow */

#ifdef __cplusplus
}
#endif

#endif
