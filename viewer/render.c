/* The renderer: GPU buffers from the glTF scene, per-tree LOD by screen coverage with a
 * dithered cross-fade, instanced draws, sun shadow map, Preetham sky with SH ambient,
 * ground with optional ray-traced grass, scan overlay, stats, headless capture. */
#include "viewer/viewer.h"

#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <math.h>
#ifndef M_PI
#define M_PI 3.14159265358979323846 /* POSIX C11 does not define it */
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>

#include <stb_easy_font.h>
#include <stb_image_write.h>

#include "stages/core/color.h"
#include "stages/core/fileio.h"
#include "viewer/motion.h"
#include "viewer/shaders.h"
#include "viewer/sky.h"

/* The first view's azimuth, degrees from +X towards +Z. */
#define DEFAULT_CAMERA_AZ 45.0

/* The ground-plane direction to the right of the screen for a camera at
 * azimuth az_deg (its eye at +cos az, +sin az from the target, looking back
 * at it). */
static void ground_right(double az_deg, double right[3])
{
    double az = az_deg * M_PI / 180;
    right[0] = sin(az), right[1] = 0, right[2] = -cos(az);
}

/* The shadow map: twice the image's larger side, a power of two from 512 to
 * 2048 (the thesis's 2048 for a window or a 1280 x 720 shot; a 256-pixel
 * batch thumbnail drew and sampled 16 times the texels it could show, most of
 * its software-rendered frame). The shaders read its size (textureSize). */
#define SHADOW_MIN 512
#define SHADOW_MAX 2048
#define LOD_BAND 0.1 /* cross-fade over +-10 % of each MSFT_screencoverage threshold */
#define FOVY_DEG 45.0

/* ---- small matrix helpers (column-major floats, as GL wants) ---- */
typedef struct { float m[16]; } mat4;

static mat4 m4_identity(void)
{
    mat4 r = {{0}};
    r.m[0] = r.m[5] = r.m[10] = r.m[15] = 1;
    return r;
}
static mat4 m4_mul(mat4 a, mat4 b)
{
    mat4 r;
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            float s = 0;
            for (int k = 0; k < 4; k++) s += a.m[k * 4 + row] * b.m[c * 4 + k];
            r.m[c * 4 + row] = s;
        }
    return r;
}
static void v3_sub(const double a[3], const double b[3], double r[3]) { for (int i = 0; i < 3; i++) r[i] = a[i] - b[i]; }
static double v3_dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void v3_cross(const double a[3], const double b[3], double r[3])
{
    r[0] = a[1] * b[2] - a[2] * b[1], r[1] = a[2] * b[0] - a[0] * b[2], r[2] = a[0] * b[1] - a[1] * b[0];
}
static void v3_norm(double a[3])
{
    double l = sqrt(v3_dot(a, a));
    if (l > 0) for (int i = 0; i < 3; i++) a[i] /= l;
}
static mat4 m4_look_at(const double eye[3], const double at[3], const double up_hint[3])
{
    double f[3], s[3], u[3], up[3] = {up_hint[0], up_hint[1], up_hint[2]};
    v3_sub(at, eye, f);
    v3_norm(f);
    v3_cross(f, up, s);
    if (v3_dot(s, s) < 1e-12) {
        up[0] = 1, up[1] = 0, up[2] = 0;
        v3_cross(f, up, s);
    }
    v3_norm(s);
    v3_cross(s, f, u);
    mat4 r = m4_identity();
    r.m[0] = (float)s[0], r.m[4] = (float)s[1], r.m[8] = (float)s[2];
    r.m[1] = (float)u[0], r.m[5] = (float)u[1], r.m[9] = (float)u[2];
    r.m[2] = (float)-f[0], r.m[6] = (float)-f[1], r.m[10] = (float)-f[2];
    r.m[12] = (float)-v3_dot(s, eye), r.m[13] = (float)-v3_dot(u, eye), r.m[14] = (float)v3_dot(f, eye);
    return r;
}
static mat4 m4_perspective(double fovy_deg, double aspect, double n, double f)
{
    double t = 1.0 / tan(fovy_deg * M_PI / 360);
    mat4 r = {{0}};
    r.m[0] = (float)(t / aspect), r.m[5] = (float)t;
    r.m[10] = (float)((f + n) / (n - f)), r.m[11] = -1, r.m[14] = (float)(2 * f * n / (n - f));
    return r;
}
static mat4 m4_ortho(double l, double r_, double b, double t, double n, double f)
{
    mat4 r = m4_identity();
    r.m[0] = (float)(2 / (r_ - l)), r.m[5] = (float)(2 / (t - b)), r.m[10] = (float)(-2 / (f - n));
    r.m[12] = (float)(-(r_ + l) / (r_ - l)), r.m[13] = (float)(-(t + b) / (t - b)), r.m[14] = (float)(-(f + n) / (f - n));
    return r;
}
static mat4 m4_inverse(mat4 a)
{
    /* Gauss-Jordan on doubles; the view-projection is well conditioned. */
    double m[4][8];
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) m[r][c] = a.m[c * 4 + r], m[r][c + 4] = r == c;
    for (int c = 0; c < 4; c++) {
        int p = c;
        for (int r = c + 1; r < 4; r++)
            if (fabs(m[r][c]) > fabs(m[p][c])) p = r;
        for (int k = 0; k < 8; k++) { double t = m[c][k]; m[c][k] = m[p][k]; m[p][k] = t; }
        double d = m[c][c];
        if (fabs(d) < 1e-30) return m4_identity();
        for (int k = 0; k < 8; k++) m[c][k] /= d;
        for (int r = 0; r < 4; r++)
            if (r != c) {
                double f = m[r][c];
                for (int k = 0; k < 8; k++) m[r][k] -= f * m[c][k];
            }
    }
    mat4 r;
    for (int row = 0; row < 4; row++)
        for (int c = 0; c < 4; c++) r.m[c * 4 + row] = (float)m[row][c + 4];
    return r;
}

/* ---- GPU-side scene ---- */
typedef struct {
    GLuint vao, vbo[7], ebo;
    GLsizei count;
    size_t triangles;
    int material; /* into the scene's materials, -1 default */
} gprim;

typedef struct {
    const sy_gltf_scene *scene;
    int scene_index;
    gprim *prims; /* one per scene primitive */
    GLuint *textures; /* one per scene texture */
    GLuint *inst_buf, *inst_tex; /* per draw (0 when not instanced) */
} gscene;

typedef struct {
    int scene, object;               /* which glTF object */
    GLuint branch_tex;
    int n_branches;
    double center[3], radius;        /* LOD0 bounds, asset frame */
    double min_y;
    float trunk_freq;
} gobject;

typedef struct {
    int object;                      /* into gobjects */
    double offset[3];                /* asset -> world translation */
    float phase;                     /* wind time offset */
    float coverage;
    int level;                       /* the level the coverage selects (n_levels: none) */
    int draw_a, draw_b;              /* levels drawn (-1 none) */
    float fade;                      /* weight of draw_a in [0,1] (1: draw_a only) */
} gtree;

typedef struct {
    int object, level;
    float fade, sign;
    int tree;
} gentry;

typedef struct {
    double eye[3], target[3];
    double az, el, dist;
    mat4 view, proj, view_proj;
} camera;

typedef struct {
    double frame_ms, fps;
    size_t triangles, draw_calls;
    int lod_hist[SY_GLTF_MAX_LODS + 1];
} frame_stats;

typedef struct {
    const sy_view_input *in;
    sy_view_options opt;
    int width, height;
    GLuint prog_tree, prog_shadow, prog_sky, prog_ground, prog_points, prog_text, prog_probe;
    gscene *gs;
    size_t n_gs;
    gobject *objs;
    size_t n_objs;
    gtree *trees;
    size_t n_trees;
    gentry *entries;
    size_t n_entries;
    GLuint tree_buf, tree_tex;
    GLuint motion_tex, grass_tex, white_tex;
    sy_motion motion;
    sy_sky sky;
    GLuint shadow_fbo, shadow_depth;
    int shadow_size;
    mat4 shadow_matrix;
    GLuint fbo, fbo_color, fbo_depth;
    GLuint ground_vao, ground_vbo, empty_vao;
    GLuint points_vao, points_vbo[2];
    size_t n_points;
    double points_offset[3];
    GLuint text_vao, text_vbo;
    double scene_min[3], scene_max[3], ground_y;
    sy_gltf_material default_material;
    frame_stats stats;
    char msg[512];
} renderer;

static const char *kVersion = "#version 330 core\n";

static GLuint compile(GLenum type, const char *const *parts, int n, char *msg, size_t size)
{
    GLuint s = glCreateShader(type);
    glShaderSource(s, n, parts, NULL);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[2048] = "";
        glGetShaderInfoLog(s, sizeof log, NULL, log);
        for (char *c = log; *c; c++)
            if (*c == '\n') *c = ' ';
        snprintf(msg, size, "shader did not compile: %.400s", log);
        glDeleteShader(s);
        return 0;
    }
    return s;
}

static GLuint program(const char *const *vs, int nvs, const char *const *fs, int nfs, const char *feedback, char *msg, size_t size)
{
    GLuint v = compile(GL_VERTEX_SHADER, vs, nvs, msg, size);
    if (!v) return 0;
    GLuint f = compile(GL_FRAGMENT_SHADER, fs, nfs, msg, size);
    if (!f) {
        glDeleteShader(v);
        return 0;
    }
    GLuint p = glCreateProgram();
    glAttachShader(p, v);
    glAttachShader(p, f);
    if (feedback) glTransformFeedbackVaryings(p, 1, &feedback, GL_INTERLEAVED_ATTRIBS);
    glLinkProgram(p);
    glDeleteShader(v);
    glDeleteShader(f);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) {
        char log[2048] = "";
        glGetProgramInfoLog(p, sizeof log, NULL, log);
        for (char *c = log; *c; c++)
            if (*c == '\n') *c = ' ';
        snprintf(msg, size, "shader did not link: %.400s", log);
        glDeleteProgram(p);
        return 0;
    }
    return p;
}

static GLint U(GLuint p, const char *name) { return glGetUniformLocation(p, name); }

static int build_programs(renderer *r)
{
    const char *tree_vs[] = {kVersion, "", sy_shader_wind_glsl, sy_shader_tree_vert};
    const char *tree_fs[] = {kVersion, sy_shader_tree_frag};
    const char *shadow_fs[] = {kVersion, sy_shader_shadow_frag};
    const char *probe_fs[] = {kVersion, "out vec4 o; void main() { o = vec4(1.0); }\n"};
    const char *sky_vs[] = {kVersion, sy_shader_sky_vert}, *sky_fs[] = {kVersion, sy_shader_sky_frag};
    const char *gr_vs[] = {kVersion, sy_shader_ground_vert}, *gr_fs[] = {kVersion, sy_shader_ground_frag};
    const char *pt_vs[] = {kVersion, sy_shader_points_vert}, *pt_fs[] = {kVersion, sy_shader_points_frag};
    const char *tx_vs[] = {kVersion, sy_shader_text_vert}, *tx_fs[] = {kVersion, sy_shader_text_frag};
    char *m = r->msg;
    size_t ms = sizeof r->msg;
    if (!(r->prog_tree = program(tree_vs, 4, tree_fs, 2, NULL, m, ms))) return -1;
    if (!(r->prog_shadow = program(tree_vs, 4, shadow_fs, 2, NULL, m, ms))) return -1;
    if (!(r->prog_probe = program(tree_vs, 4, probe_fs, 2, "v_world", m, ms))) return -1;
    if (!(r->prog_sky = program(sky_vs, 2, sky_fs, 2, NULL, m, ms))) return -1;
    if (!(r->prog_ground = program(gr_vs, 2, gr_fs, 2, NULL, m, ms))) return -1;
    if (!(r->prog_points = program(pt_vs, 2, pt_fs, 2, NULL, m, ms))) return -1;
    if (!(r->prog_text = program(tx_vs, 2, tx_fs, 2, NULL, m, ms))) return -1;
    return 0;
}

/* Smooth normals for primitives that have none (glTF says flat; smooth reads better for trees). */
static float *make_normals(const sy_gltf_primitive *p)
{
    float *n = calloc(p->n_vertices * 3 + 1, sizeof(float));
    if (!n) return NULL;
    for (size_t t = 0; t + 2 < p->n_indices; t += 3) {
        const float *a = p->position + 3 * p->indices[t], *b = p->position + 3 * p->indices[t + 1], *c = p->position + 3 * p->indices[t + 2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float x[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; k++)
            for (int i = 0; i < 3; i++) n[3 * p->indices[t + k] + i] += x[i];
    }
    for (size_t v = 0; v < p->n_vertices; v++) {
        float *q = n + 3 * v, l = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
        if (l > 0) q[0] /= l, q[1] /= l, q[2] /= l;
        else q[1] = 1;
    }
    return n;
}

static void attrib(GLuint vbo, int loc, int width, const float *data, size_t n)
{
    glBindBuffer(GL_ARRAY_BUFFER, vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(n * (size_t)width * sizeof(float)), data, GL_STATIC_DRAW);
    glEnableVertexAttribArray((GLuint)loc);
    glVertexAttribPointer((GLuint)loc, width, GL_FLOAT, GL_FALSE, 0, NULL);
}
/* The stored alpha of a texel of alpha a (0..255, unrounded) scaled by scale. */
static double scaled_alpha(double a, double scale)
{
    double v = a * scale;
    return v > 255 ? 255 : floor(v + 0.5);
}

/* Share of the n alphas (0..255, stride apart) that, scaled and stored,
 * reach c (the cut-off times 255). */
static double alpha_coverage(const double *alpha, size_t n, size_t stride, double scale, double c)
{
    size_t hit = 0;
    for (size_t i = 0; i < n; i++) hit += scaled_alpha(alpha[i * stride], scale) >= c;
    return n ? (double)hit / (double)n : 0;
}

/* Uploads mip levels 1.. of an 8-bit RGBA alpha-tested texture (level 0
 * bound already) whose alpha keeps level 0's coverage at the cut-off
 * (Castano 2010, "Computing alpha mipmaps"; Unity's "Mip Maps Preserve
 * Coverage"): each level is the 2 x 2 box mean of the one before (colour in
 * linear light when srgb, as GL's own sRGB mips), its alpha scaled by the
 * factor, found by bisection, at which as many texels pass the test as at
 * level 0. The test is the shader's: texel alpha times the material's
 * alpha factor (factor_alpha) against its cut-off (vertex colours, which
 * no Sylva asset carries, are not counted). With plain box means
 * (glGenerateMipmap) a leaf texture of 15 % opaque texels lost every leaf a
 * few levels down: the weeping willow stood bare at 300 pixels tall, its
 * impostor a green crown. Returns 0, or -1 (out of memory, or nothing can
 * pass: the caller generates plain mips). */
static int coverage_mips(const unsigned char *base, int w, int h, int srgb, float cutoff, double factor_alpha,
                         GLenum internal)
{
    if (!(factor_alpha > 0)) return -1;
    const double c = 255.0 * ((double)cutoff / factor_alpha);
    size_t n0 = (size_t)w * (size_t)h;
    double *prev = malloc(n0 * 4 * sizeof *prev), *next = malloc(n0 * 4 * sizeof *next);
    unsigned char *level_px = malloc(n0 * 4);
    if (!prev || !next || !level_px) {
        free(prev), free(next), free(level_px);
        return -1;
    }
    double linear[256]; /* an 8-bit sRGB value in linear light */
    for (int v = 0; v < 256; v++) linear[v] = sy_srgb_to_linear(v / 255.0);
    for (size_t i = 0; i < 4 * n0; i++) prev[i] = i % 4 < 3 && srgb ? linear[base[i]] : base[i];
    const double want = alpha_coverage(prev + 3, n0, 4, 1, c);
    for (int level = 1; w > 1 || h > 1; level++) {
        int nw = w > 1 ? w / 2 : 1, nh = h > 1 ? h / 2 : 1;
        for (int y = 0; y < nh; y++)
            for (int x = 0; x < nw; x++) {
                int x0 = 2 * x < w ? 2 * x : w - 1, x1 = 2 * x + 1 < w ? 2 * x + 1 : x0;
                int y0 = 2 * y < h ? 2 * y : h - 1, y1 = 2 * y + 1 < h ? 2 * y + 1 : y0;
                for (int k = 0; k < 4; k++)
                    next[4 * ((size_t)y * nw + x) + k] = (prev[4 * ((size_t)y0 * w + x0) + k] + prev[4 * ((size_t)y0 * w + x1) + k] +
                                                          prev[4 * ((size_t)y1 * w + x0) + k] + prev[4 * ((size_t)y1 * w + x1) + k]) / 4;
            }
        size_t n = (size_t)nw * (size_t)nh;
        double lo = 0, hi = 1;
        while (hi < 64 && alpha_coverage(next + 3, n, 4, hi, c) < want) hi *= 2;
        for (int it = 0; it < 16; it++) {
            double mid = 0.5 * (lo + hi);
            if (alpha_coverage(next + 3, n, 4, mid, c) < want) lo = mid;
            else hi = mid;
        }
        for (size_t i = 0; i < n; i++) {
            for (int k = 0; k < 3; k++) {
                double v = next[4 * i + k];
                v = srgb ? 255 * sy_linear_to_srgb(v) : v;
                level_px[4 * i + k] = (unsigned char)(v < 0 ? 0 : v > 255 ? 255 : v + 0.5);
            }
            level_px[4 * i + 3] = (unsigned char)scaled_alpha(next[4 * i + 3], hi);
        }
        glTexImage2D(GL_TEXTURE_2D, level, (GLint)internal, nw, nh, 0, GL_RGBA, GL_UNSIGNED_BYTE, level_px);
        double *t = prev;
        prev = next, next = t, w = nw, h = nh; /* the next level averages this one's unscaled alpha */
    }
    free(prev), free(next), free(level_px);
    return 0;
}

static int upload_scene(renderer *r, gscene *g)
{
    const sy_gltf_scene *s = g->scene;
    g->prims = calloc(s->n_primitives + 1, sizeof(gprim));
    g->textures = calloc(s->n_textures + 1, sizeof(GLuint));
    g->inst_buf = calloc(s->n_draws + 1, sizeof(GLuint));
    g->inst_tex = calloc(s->n_draws + 1, sizeof(GLuint));
    if (!g->prims || !g->textures || !g->inst_buf || !g->inst_tex) return -1;
    GLint max_tex = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
    /* Colour textures are sRGB-encoded (glTF 2.0 §3.9.2); data textures (normals, roughness,
     * HL2 coefficients, transmission factors) are linear. */
    char *srgb = calloc(s->n_textures + 1, 1);
    /* Alpha-tested base colours: their cut-off (else -1) and alpha factor. A texture that
     * several materials share takes the first MASK one's; its levels serve the others too. */
    float *cutoff = malloc((s->n_textures + 1) * sizeof *cutoff), *factor_a = malloc((s->n_textures + 1) * sizeof *factor_a);
    if (!srgb || !cutoff || !factor_a) {
        free(srgb), free(cutoff), free(factor_a);
        return -1;
    }
    for (size_t i = 0; i < s->n_textures; i++) cutoff[i] = -1;
    for (size_t i = 0; i < s->n_materials; i++) {
        const sy_gltf_material *m = &s->materials[i];
        if (m->base_color_texture >= 0) srgb[m->base_color_texture] = 1;
        if (m->diffuse_transmission_color_texture >= 0) srgb[m->diffuse_transmission_color_texture] = 1;
        if (m->base_color_texture >= 0 && m->alpha_mode == SY_GLTF_MASK && cutoff[m->base_color_texture] < 0)
            cutoff[m->base_color_texture] = m->alpha_cutoff, factor_a[m->base_color_texture] = m->base_color[3];
    }
    for (size_t i = 0; i < s->n_textures; i++) {
        const sy_gltf_texture *t = &s->textures[i];
        const sy_gltf_image *im = &s->images[t->image];
        if (im->width > max_tex || im->height > max_tex) {
            snprintf(r->msg, sizeof r->msg, "image %d is %dx%d, larger than this GL's %d", t->image, im->width, im->height, max_tex);
            free(srgb), free(cutoff), free(factor_a);
            return -2;
        }
        glGenTextures(1, &g->textures[i]);
        glBindTexture(GL_TEXTURE_2D, g->textures[i]);
        glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
        GLenum internal = srgb[i] ? GL_SRGB8_ALPHA8 : im->bits == 16 ? GL_RGBA16 : GL_RGBA8;
        glTexImage2D(GL_TEXTURE_2D, 0, internal, im->width, im->height, 0, GL_RGBA,
                     im->bits == 16 ? GL_UNSIGNED_SHORT : GL_UNSIGNED_BYTE, im->pixels);
        if (cutoff[i] < 0 || im->bits != 8 ||
            coverage_mips(im->pixels, im->width, im->height, srgb[i], cutoff[i], factor_a[i], internal))
            glGenerateMipmap(GL_TEXTURE_2D);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, t->wrap_s);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, t->wrap_t);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, t->min_filter > 0 ? t->min_filter : GL_LINEAR_MIPMAP_LINEAR);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, t->mag_filter > 0 ? t->mag_filter : GL_LINEAR);
    }
    free(srgb), free(cutoff), free(factor_a);
    for (size_t i = 0; i < s->n_primitives; i++) {
        const sy_gltf_primitive *p = &s->primitives[i];
        gprim *q = &g->prims[i];
        q->material = p->material;
        q->count = (GLsizei)p->n_indices;
        q->triangles = p->n_indices / 3;
        glGenVertexArrays(1, &q->vao);
        glBindVertexArray(q->vao);
        glGenBuffers(7, q->vbo);
        glGenBuffers(1, &q->ebo);
        attrib(q->vbo[0], 0, 3, p->position, p->n_vertices);
        float *normals = p->normal ? NULL : make_normals(p);
        if (!p->normal && !normals) return -1;
        attrib(q->vbo[1], 1, 3, p->normal ? p->normal : normals, p->n_vertices);
        free(normals);
        if (p->tangent) attrib(q->vbo[2], 2, 4, p->tangent, p->n_vertices);
        else glDisableVertexAttribArray(2), glVertexAttrib4f(2, 0, 0, 0, 1);
        if (p->uv) attrib(q->vbo[3], 3, 2, p->uv, p->n_vertices);
        else glDisableVertexAttribArray(3), glVertexAttrib2f(3, 0, 0);
        if (p->color) attrib(q->vbo[4], 4, 4, p->color, p->n_vertices);
        else glDisableVertexAttribArray(4), glVertexAttrib4f(4, 1, 1, 1, 1);
        if (p->wind_w && p->wind_branch) {
            attrib(q->vbo[5], 5, 4, p->wind_w, p->n_vertices);
            attrib(q->vbo[6], 6, 1, p->wind_branch, p->n_vertices);
        } else {
            glDisableVertexAttribArray(5), glVertexAttrib4f(5, 0, 0, 0, 0);
            glDisableVertexAttribArray(6), glVertexAttrib1f(6, 0);
        }
        glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, q->ebo);
        glBufferData(GL_ELEMENT_ARRAY_BUFFER, (GLsizeiptr)(p->n_indices * sizeof(uint32_t)), p->indices, GL_STATIC_DRAW);
        glBindVertexArray(0);
    }
    for (size_t i = 0; i < s->n_draws; i++) {
        const sy_gltf_draw *d = &s->draws[i];
        if (!d->n_instances) continue;
        float *tb = calloc(d->n_instances * 24, sizeof(float));
        if (!tb) return -1;
        for (size_t k = 0; k < d->n_instances; k++) {
            memcpy(tb + k * 24, d->instance_matrix + k * 16, 16 * sizeof(float));
            if (d->inst_wind_w) memcpy(tb + k * 24 + 16, d->inst_wind_w + k * 4, 4 * sizeof(float));
            if (d->inst_wind_branch) tb[k * 24 + 20] = d->inst_wind_branch[k];
        }
        glGenBuffers(1, &g->inst_buf[i]);
        glBindBuffer(GL_TEXTURE_BUFFER, g->inst_buf[i]);
        glBufferData(GL_TEXTURE_BUFFER, (GLsizeiptr)(d->n_instances * 24 * sizeof(float)), tb, GL_STATIC_DRAW);
        free(tb);
        glGenTextures(1, &g->inst_tex[i]);
        glBindTexture(GL_TEXTURE_BUFFER, g->inst_tex[i]);
        glTexBuffer(GL_TEXTURE_BUFFER, GL_RGBA32F, g->inst_buf[i]);
    }
    return 0;
}

/* Branch table texture (see wind.glsl for the layout) with each branch's trajectory. */
static int upload_wind(renderer *r, gobject *o, const sy_gltf_object *src)
{
    o->n_branches = (int)src->n_wind;
    o->trunk_freq = 0.5f;
    if (!src->n_wind) return 0;
    GLint max_tex = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
    if ((GLint)src->n_wind > max_tex) {
        snprintf(r->msg, sizeof r->msg, "wind table of %zu branches exceeds this GL's texture size %d", src->n_wind, max_tex);
        return -2;
    }
    float *t = calloc(src->n_wind * 24, sizeof(float));
    if (!t) return -1;
    /* Per-level amplitude (normalised deflection per unit wind): small branches move most. */
    const float gain[4] = {0.02f, 0.05f, 0.08f, 0.11f};
    for (size_t b = 0; b < src->n_wind; b++) {
        const sy_gltf_wind_branch *w = &src->wind[b];
        float *e = t + b * 24;
        double ax[3] = {w->axis[0], w->axis[1], w->axis[2]};
        v3_norm(ax);
        if (v3_dot(ax, ax) < 0.5) ax[1] = 1;
        /* r, s: any orthonormal completion of t (docs/wind.md); r as horizontal as possible. */
        double up[3] = {0, 1, 0}, rr[3], ss[3];
        v3_cross(up, ax, rr);
        if (v3_dot(rr, rr) < 1e-8) { double x[3] = {1, 0, 0}; v3_cross(x, ax, rr); }
        v3_norm(rr);
        v3_cross(ax, rr, ss);
        v3_norm(ss);
        e[0] = w->anchor[0], e[1] = w->anchor[1], e[2] = w->anchor[2], e[3] = w->length;
        e[4] = (float)ax[0], e[5] = (float)ax[1], e[6] = (float)ax[2], e[7] = w->c2;
        e[8] = (float)rr[0], e[9] = (float)rr[1], e[10] = (float)rr[2], e[11] = w->c4;
        e[12] = (float)ss[0], e[13] = (float)ss[1], e[14] = (float)ss[2], e[15] = (float)w->parent;
        float vel[2], off[2];
        double fh = w->frequency > 0.01 ? w->frequency : 2.55 * pow(w->length > 0.01 ? w->length : 0.01, -0.59);
        sy_motion_trajectory(&r->motion, fh, r->opt.seed, (uint32_t)b, vel, off);
        e[16] = vel[0], e[17] = vel[1], e[18] = off[0], e[19] = off[1];
        int lv = w->level < 0 ? 0 : w->level > 3 ? 3 : w->level;
        e[20] = (float)lv, e[21] = w->stiffness, e[22] = gain[lv] * (1.0f - 0.6f * w->stiffness), e[23] = (float)fh;
        if (w->parent < 0 && b == 0) o->trunk_freq = (float)fh;
    }
    glGenTextures(1, &o->branch_tex);
    glBindTexture(GL_TEXTURE_2D, o->branch_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, 6, (GLsizei)src->n_wind, 0, GL_RGBA, GL_FLOAT, t);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    free(t);
    return 0;
}

static int setup_targets(renderer *r)
{
    GLint max_rb = 0;
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
    if (r->width > max_rb || r->height > max_rb) {
        snprintf(r->msg, sizeof r->msg, "--size %dx%d exceeds this GL's largest framebuffer (%d)", r->width, r->height, max_rb);
        return -2;
    }
    glGenFramebuffers(1, &r->fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo);
    glGenRenderbuffers(1, &r->fbo_color);
    glBindRenderbuffer(GL_RENDERBUFFER, r->fbo_color);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, r->width, r->height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, r->fbo_color);
    glGenRenderbuffers(1, &r->fbo_depth);
    glBindRenderbuffer(GL_RENDERBUFFER, r->fbo_depth);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, r->width, r->height);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, r->fbo_depth);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
        snprintf(r->msg, sizeof r->msg, "could not make a %dx%d framebuffer (out of memory?)", r->width, r->height);
        return -2;
    }
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    return 0;
}

static void setup_shadow(renderer *r)
{
    int side = r->width > r->height ? r->width : r->height;
    r->shadow_size = SHADOW_MIN;
    while (r->shadow_size < 2 * side && r->shadow_size < SHADOW_MAX) r->shadow_size *= 2;
    glGenTextures(1, &r->shadow_depth);
    glBindTexture(GL_TEXTURE_2D, r->shadow_depth);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT24, r->shadow_size, r->shadow_size, 0, GL_DEPTH_COMPONENT, GL_FLOAT,
                 NULL);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_MODE, GL_COMPARE_REF_TO_TEXTURE);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_COMPARE_FUNC, GL_LEQUAL);
    glGenFramebuffers(1, &r->shadow_fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, r->shadow_fbo);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, r->shadow_depth, 0);
    glDrawBuffer(GL_NONE);
    glReadBuffer(GL_NONE);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

static void setup_static_textures(renderer *r)
{
    unsigned char white[4] = {255, 255, 255, 255};
    glGenTextures(1, &r->white_tex);
    glBindTexture(GL_TEXTURE_2D, r->white_tex);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, 1, 1, 0, GL_RGBA, GL_UNSIGNED_BYTE, white);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    int n = r->motion.size;
    glGenTextures(1, &r->motion_tex);
    glBindTexture(GL_TEXTURE_2D_ARRAY, r->motion_tex);
    glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RG32F, n, n, SY_MOTION_LEVELS, 0, GL_RG, GL_FLOAT, r->motion.texels);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, GL_REPEAT);
    const int gw = 256, gh = 128, gl = 4;
    unsigned char *grass = sy_grass_slices(gw, gh, gl, r->opt.seed);
    glGenTextures(1, &r->grass_tex);
    glBindTexture(GL_TEXTURE_2D_ARRAY, r->grass_tex);
    glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGBA8, gw, gh, gl, 0, GL_RGBA, GL_UNSIGNED_BYTE, grass);
    free(grass);
    glGenerateMipmap(GL_TEXTURE_2D_ARRAY);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
}

/* Lays the trees out: every object of every file, `copies` times each, on a square grid
 * (row-major) centred on the origin, spaced by the widest footprint. */
static int layout(renderer *r)
{
    size_t n_obj = 0;
    for (size_t i = 0; i < r->in->n_scenes; i++) n_obj += r->in->scenes[i].n_objects;
    r->objs = calloc(n_obj + 1, sizeof(gobject));
    size_t copies = (size_t)(r->opt.copies > 0 ? r->opt.copies : 1);
    r->n_trees = n_obj * copies;
    r->trees = calloc(r->n_trees + 1, sizeof(gtree));
    r->entries = calloc(2 * r->n_trees + 1, sizeof(gentry));
    if (!r->objs || !r->trees || !r->entries) return -1;
    double widest = 0;
    for (size_t i = 0; i < r->in->n_scenes; i++)
        for (size_t k = 0; k < r->in->scenes[i].n_objects; k++) {
            const sy_gltf_object *o = &r->in->scenes[i].objects[k];
            gobject *g = &r->objs[r->n_objs++];
            g->scene = (int)i, g->object = (int)k;
            double ext = 0;
            for (int c = 0; c < 3; c++) {
                g->center[c] = 0.5 * (o->bounds_min[c] + o->bounds_max[c]);
                double h = 0.5 * (o->bounds_max[c] - o->bounds_min[c]);
                ext += h * h;
            }
            g->radius = sqrt(ext);
            g->min_y = o->bounds_min[1];
            double fx = o->bounds_max[0] - o->bounds_min[0], fz = o->bounds_max[2] - o->bounds_min[2];
            widest = fmax(widest, fmax(fx, fz));
            int rc = upload_wind(r, g, o);
            if (rc) return rc;
        }
    double spacing = r->opt.spacing > 0 ? r->opt.spacing : fmax(widest * 1.15, 0.5);
    size_t cols = (size_t)ceil(sqrt((double)r->n_trees));
    uint64_t s = r->opt.seed * 0x9e3779b97f4a7c15ull + 7;
    for (size_t t = 0; t < r->n_trees; t++) {
        gtree *g = &r->trees[t];
        g->object = (int)(t % n_obj);
        size_t row = t / cols, col = t % cols;
        double rows = ceil((double)r->n_trees / cols);
        /* One tree stays where its file puts it; a grid only when there are several. */
        if (r->n_trees > 1) {
            g->offset[0] = (col - (cols - 1) / 2.0) * spacing - r->objs[g->object].center[0];
            g->offset[2] = (row - (rows - 1) / 2.0) * spacing - r->objs[g->object].center[2];
        }
        s ^= s << 13, s ^= s >> 7, s ^= s << 17;
        g->phase = t == 0 ? 0.0f : (float)((s >> 11) % 100000) * 1e-3f;
    }
    for (int c = 0; c < 3; c++) r->scene_min[c] = HUGE_VAL, r->scene_max[c] = -HUGE_VAL;
    for (size_t t = 0; t < r->n_trees; t++) {
        const gtree *g = &r->trees[t];
        const sy_gltf_object *o = &r->in->scenes[r->objs[g->object].scene].objects[r->objs[g->object].object];
        for (int c = 0; c < 3; c++) {
            r->scene_min[c] = fmin(r->scene_min[c], o->bounds_min[c] + g->offset[c]);
            r->scene_max[c] = fmax(r->scene_max[c], o->bounds_max[c] + g->offset[c]);
        }
    }
    r->ground_y = r->scene_min[1];
    return 0;
}

static void setup_points(renderer *r)
{
    const sy_view_points *p = &r->in->points;
    r->n_points = p->n;
    if (!p->n) return;
    glGenVertexArrays(1, &r->points_vao);
    glBindVertexArray(r->points_vao);
    glGenBuffers(2, r->points_vbo);
    attrib(r->points_vbo[0], 0, 3, p->xyz, p->n);
    attrib(r->points_vbo[1], 1, 3, p->rgb, p->n);
    glBindVertexArray(0);
    /* Over the first tree, or beside it: one tree width to the right as the
     * first view sees it, at the tree's distance. Along +X, the default
     * 45-degree view had the scan a third of a width nearer the camera, and
     * it looked a tenth larger than the tree it was compared with. */
    const gtree *t0 = &r->trees[0];
    const sy_gltf_object *o = &r->in->scenes[r->objs[t0->object].scene].objects[r->objs[t0->object].object];
    for (int c = 0; c < 3; c++) r->points_offset[c] = t0->offset[c];
    if (r->opt.points_beside) {
        double right[3], w = 1.15 * fmax(o->bounds_max[0] - o->bounds_min[0], o->bounds_max[2] - o->bounds_min[2]) + 0.5;
        ground_right(r->opt.camera_set ? r->opt.cam_az : DEFAULT_CAMERA_AZ, right);
        for (int c = 0; c < 3; c++) r->points_offset[c] += w * right[c];
    }
    for (int c = 0; c < 3; c++) {
        for (size_t i = 0; i < p->n; i++) {
            double v = p->xyz[3 * i + c] + r->points_offset[c];
            r->scene_min[c] = fmin(r->scene_min[c], v);
            r->scene_max[c] = fmax(r->scene_max[c], v);
        }
    }
}

static void setup_ground(renderer *r)
{
    double cx = 0.5 * (r->scene_min[0] + r->scene_max[0]), cz = 0.5 * (r->scene_min[2] + r->scene_max[2]);
    double ext = fmax(r->scene_max[0] - r->scene_min[0], r->scene_max[2] - r->scene_min[2]);
    double h = fmax(ext * 40.0, 400.0);
    float q[12] = {(float)(cx - h), (float)(cz - h), (float)(cx + h), (float)(cz - h), (float)(cx + h), (float)(cz + h),
                   (float)(cx - h), (float)(cz - h), (float)(cx + h), (float)(cz + h), (float)(cx - h), (float)(cz + h)};
    /* Counter-clockwise seen from above. */
    float ccw[12] = {q[0], q[1], q[10], q[11], q[8], q[9], q[0], q[1], q[8], q[9], q[2], q[3]};
    glGenVertexArrays(1, &r->ground_vao);
    glBindVertexArray(r->ground_vao);
    glGenBuffers(1, &r->ground_vbo);
    attrib(r->ground_vbo, 0, 2, ccw, 6);
    glBindVertexArray(0);
    glGenVertexArrays(1, &r->empty_vao);
    glGenVertexArrays(1, &r->text_vao);
    glBindVertexArray(r->text_vao);
    glGenBuffers(1, &r->text_vbo);
    glBindBuffer(GL_ARRAY_BUFFER, r->text_vbo);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 6 * sizeof(float), NULL);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, 6 * sizeof(float), (void *)(2 * sizeof(float)));
    glBindVertexArray(0);
    glGenBuffers(1, &r->tree_buf);
    glGenTextures(1, &r->tree_tex);
}

/* ---- camera ---- */
static void camera_update(renderer *r, camera *c)
{
    double el = c->el * M_PI / 180, az = c->az * M_PI / 180;
    c->eye[0] = c->target[0] + c->dist * cos(el) * cos(az);
    c->eye[1] = c->target[1] + c->dist * sin(el);
    c->eye[2] = c->target[2] + c->dist * cos(el) * sin(az);
    double up[3] = {0, 1, 0};
    c->view = m4_look_at(c->eye, c->target, up);
    double ext = 0;
    for (int k = 0; k < 3; k++) ext = fmax(ext, r->scene_max[k] - r->scene_min[k]);
    double n = fmax(0.01, c->dist * 0.01), f = c->dist * 4 + ext * 8 + 100;
    c->proj = m4_perspective(FOVY_DEG, (double)r->width / r->height, n, f);
    c->view_proj = m4_mul(c->proj, c->view);
}

static void camera_frame(renderer *r, camera *c)
{
    double rad = 0;
    for (int k = 0; k < 3; k++) {
        c->target[k] = 0.5 * (r->scene_min[k] + r->scene_max[k]);
        double h = 0.5 * (r->scene_max[k] - r->scene_min[k]);
        rad += h * h;
    }
    rad = fmax(sqrt(rad), 0.01);
    double aspect = (double)r->width / r->height, half = FOVY_DEG * M_PI / 360;
    double half_min = aspect < 1 ? atan(tan(half) * aspect) : half;
    c->dist = rad / sin(half_min) * 1.02;
}

/* ---- LOD ---- */
static float coverage_of(const renderer *r, const camera *c, const gtree *t)
{
    const gobject *o = &r->objs[t->object];
    double p[3], d[3];
    for (int k = 0; k < 3; k++) p[k] = o->center[k] + t->offset[k];
    v3_sub(p, c->eye, d);
    double dist = sqrt(v3_dot(d, d));
    if (dist <= o->radius) return 1.0f;
    /* The share of the screen height the bounding sphere covers (MSFT_screencoverage). */
    double cov = o->radius / (dist * tan(FOVY_DEG * M_PI / 360));
    return (float)fmin(cov, 1.0);
}

static void choose_lod(const renderer *r, const sy_gltf_object *o, gtree *t)
{
    int n = o->n_levels;
    t->draw_b = -1;
    t->fade = 1;
    if (r->opt.lod_override >= 0) {
        t->level = t->draw_a = r->opt.lod_override < n ? r->opt.lod_override : n - 1;
        return;
    }
    float c[SY_GLTF_MAX_LODS];
    for (int i = 0; i < n; i++) c[i] = o->coverage[i] >= 0 ? o->coverage[i] : (i == 0 ? 0.0f : 0.5f / (float)(1 << (i - 1)));
    if (n == 1 && o->coverage[0] < 0) c[0] = 0;
    int lv = n;
    for (int i = 0; i < n; i++)
        if (t->coverage >= c[i]) { lv = i; break; }
    t->level = lv;
    t->draw_a = lv < n ? lv : -1;
    /* Cross-fade with the neighbour across the nearest threshold inside the band. */
    for (int i = 0; i < n; i++) {
        float lo = c[i] * (1 - (float)LOD_BAND), hi = c[i] * (1 + (float)LOD_BAND);
        if (c[i] > 0 && t->coverage >= lo && t->coverage < hi) {
            float f = (t->coverage - lo) / (hi - lo);
            t->draw_a = i;                         /* finer level, weight f */
            t->draw_b = i + 1 < n ? i + 1 : -1;    /* coarser level (or nothing) */
            t->fade = f;
            break;
        }
    }
}

static int entry_cmp(const void *a, const void *b)
{
    const gentry *x = a, *y = b;
    if (x->object != y->object) return x->object - y->object;
    if (x->level != y->level) return x->level - y->level;
    return x->tree - y->tree;
}

static void build_entries(renderer *r, const camera *c)
{
    r->n_entries = 0;
    memset(r->stats.lod_hist, 0, sizeof r->stats.lod_hist);
    for (size_t i = 0; i < r->n_trees; i++) {
        gtree *t = &r->trees[i];
        const gobject *go = &r->objs[t->object];
        const sy_gltf_object *o = &r->in->scenes[go->scene].objects[go->object];
        t->coverage = coverage_of(r, c, t);
        choose_lod(r, o, t);
        r->stats.lod_hist[t->level < SY_GLTF_MAX_LODS ? t->level : SY_GLTF_MAX_LODS]++;
        if (t->draw_a >= 0) r->entries[r->n_entries++] = (gentry){t->object, t->draw_a, t->fade, 1.0f, (int)i};
        if (t->draw_b >= 0 && t->fade < 1) r->entries[r->n_entries++] = (gentry){t->object, t->draw_b, 1.0f - t->fade, -1.0f, (int)i};
        else if (t->draw_b < 0 && t->fade < 1) { /* fading out to nothing: only the dithered finer level */ }
    }
    qsort(r->entries, r->n_entries, sizeof(gentry), entry_cmp);
    float *buf = malloc((r->n_entries + 1) * 20 * sizeof(float));
    if (!buf) return;
    for (size_t e = 0; e < r->n_entries; e++) {
        const gtree *t = &r->trees[r->entries[e].tree];
        float *m = buf + e * 20;
        memset(m, 0, 20 * sizeof(float));
        m[0] = m[5] = m[10] = m[15] = 1;
        m[12] = (float)t->offset[0], m[13] = (float)t->offset[1], m[14] = (float)t->offset[2];
        m[16] = r->entries[e].fade, m[17] = t->phase, m[18] = r->entries[e].sign;
    }
    glBindBuffer(GL_TEXTURE_BUFFER, r->tree_buf);
    glBufferData(GL_TEXTURE_BUFFER, (GLsizeiptr)((r->n_entries + 1) * 20 * sizeof(float)), buf, GL_STREAM_DRAW);
    glBindTexture(GL_TEXTURE_BUFFER, r->tree_tex);
    glTexBuffer(GL_TEXTURE_BUFFER, GL_RGBA32F, r->tree_buf);
    free(buf);
}

/* ---- drawing ---- */
static double wind_gain(const renderer *r, const gobject *o, double time)
{
    if (!r->opt.wind) return 0;
    double g = r->opt.wind_strength;
    if (r->opt.wind_stop >= 0 && time > r->opt.wind_stop) {
        /* The wind stops: the branches ring down like the damped oscillators they are. */
        double zeta = r->motion.damping[0];
        g *= exp(-(time - r->opt.wind_stop) * 2 * M_PI * zeta * fmax(o->trunk_freq, 0.3));
    }
    return g;
}

static void bind_tex(GLuint prog, const char *name, int unit, GLenum target, GLuint tex)
{
    glActiveTexture(GL_TEXTURE0 + (GLenum)unit);
    glBindTexture(target, tex);
    glUniform1i(U(prog, name), unit);
}

static void set_material(renderer *r, GLuint p, const gscene *g, int mi, int shadow)
{
    const sy_gltf_material *m = mi >= 0 ? &g->scene->materials[mi] : &r->default_material;
    glUniform4fv(U(p, "u_base_color"), 1, m->base_color);
    int has = m->base_color_texture >= 0;
    bind_tex(p, "u_base_tex", 0, GL_TEXTURE_2D, has ? g->textures[m->base_color_texture] : r->white_tex);
    glUniform1i(U(p, "u_has_base_tex"), has);
    glUniform1i(U(p, "u_alpha_mode"), (int)m->alpha_mode);
    glUniform1f(U(p, "u_alpha_cutoff"), m->alpha_cutoff);
    if (m->double_sided || shadow) glDisable(GL_CULL_FACE);
    else glEnable(GL_CULL_FACE);
    if (shadow) return;
    struct { const char *name, *flag; int tex; int unit; } maps[] = {
        {"u_normal_tex", "u_has_normal_tex", m->normal_texture, 1}, {"u_mr_tex", "u_has_mr_tex", m->metallic_roughness_texture, 2},
        {"u_dt_tex", "u_has_dt_tex", m->diffuse_transmission_texture, 3},
        {"u_dt_color_tex", "u_has_dt_color_tex", m->diffuse_transmission_color_texture, 4},
        {"u_hl2_adaxial", NULL, m->hl2_adaxial_texture, 5}, {"u_hl2_abaxial", NULL, m->hl2_abaxial_texture, 6}};
    for (size_t i = 0; i < sizeof maps / sizeof maps[0]; i++) {
        bind_tex(p, maps[i].name, maps[i].unit, GL_TEXTURE_2D, maps[i].tex >= 0 ? g->textures[maps[i].tex] : r->white_tex);
        if (maps[i].flag) glUniform1i(U(p, maps[i].flag), maps[i].tex >= 0);
    }
    int hl2 = m->hl2_adaxial_texture >= 0 && m->hl2_abaxial_texture >= 0;
    glUniform1i(U(p, "u_has_hl2"), hl2);
    glUniform1f(U(p, "u_hl2_min"), m->hl2_min);
    glUniform1f(U(p, "u_hl2_max"), m->hl2_max);
    glUniform1f(U(p, "u_normal_scale"), m->normal_scale);
    glUniform1f(U(p, "u_metallic"), m->metallic);
    glUniform1f(U(p, "u_roughness"), m->roughness);
    glUniform3fv(U(p, "u_emissive"), 1, m->emissive);
    glUniform1i(U(p, "u_double_sided"), m->double_sided);
    glUniform1f(U(p, "u_dt_factor"), m->diffuse_transmission);
    glUniform3fv(U(p, "u_dt_color"), 1, m->diffuse_transmission_color);
    if (m->alpha_mode == SY_GLTF_BLEND) {
        glEnable(GL_BLEND);
        glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    } else
        glDisable(GL_BLEND);
}

static void set_wind_uniforms(renderer *r, GLuint p, const gobject *o, double time)
{
    bind_tex(p, "u_branches", 8, GL_TEXTURE_2D, o->branch_tex ? o->branch_tex : r->white_tex);
    bind_tex(p, "u_motion", 9, GL_TEXTURE_2D_ARRAY, r->motion_tex);
    glUniform1i(U(p, "u_n_branches"), o->n_branches);
    glUniform1i(U(p, "u_wind_on"), r->opt.wind && o->n_branches > 0);
    glUniform1f(U(p, "u_time"), (float)time);
    glUniform1f(U(p, "u_wind_gain"), (float)wind_gain(r, o, time));
    glUniform1f(U(p, "u_wind_steady"), 1.2f);
    double a = r->opt.wind_dir_deg * M_PI / 180;
    glUniform3f(U(p, "u_wind_dir"), (float)cos(a), 0.0f, (float)sin(a));
    glUniform1i(U(p, "u_static_load"), r->opt.static_load);
    glUniform1f(U(p, "u_flutter"), o->n_branches > 0 && !r->opt.static_load ? 1.0f : 0.0f);
}

/* The inverse transpose of a node matrix's upper 3x3 (normals), as a uniform. */
static void set_node_normal(GLuint p, const double *w)
{
    double a = w[0], b = w[4], c = w[8], d = w[1], e = w[5], f = w[9], g = w[2], h = w[6], k = w[10];
    double det = a * (e * k - f * h) - b * (d * k - f * g) + c * (d * h - e * g);
    if (fabs(det) < 1e-30) det = 1e-30;
    /* inverse transpose = cofactor matrix / det, stored column-major */
    float m[9] = {(float)((e * k - f * h) / det), (float)(-(b * k - c * h) / det), (float)((b * f - c * e) / det),
                  (float)(-(d * k - f * g) / det), (float)((a * k - c * g) / det), (float)(-(a * f - c * d) / det),
                  (float)((d * h - e * g) / det), (float)(-(a * h - b * g) / det), (float)((a * e - b * d) / det)};
    glUniformMatrix3fv(U(p, "u_node_normal"), 1, GL_FALSE, m);
}

/* Draws every (object, level) group of entries with program p. */
static void draw_trees(renderer *r, GLuint p, const camera *c, const mat4 *view_proj, double time, int shadow, int blend_pass)
{
    glUseProgram(p);
    glUniformMatrix4fv(U(p, "u_view_proj"), 1, GL_FALSE, view_proj->m);
    bind_tex(p, "u_trees", 10, GL_TEXTURE_BUFFER, r->tree_tex);
    for (size_t e0 = 0; e0 < r->n_entries;) {
        size_t e1 = e0;
        while (e1 < r->n_entries && r->entries[e1].object == r->entries[e0].object && r->entries[e1].level == r->entries[e0].level) e1++;
        const gobject *o = &r->objs[r->entries[e0].object];
        const gscene *g = &r->gs[o->scene];
        const sy_gltf_scene *s = g->scene;
        int level = r->entries[e0].level;
        GLsizei copies = (GLsizei)(e1 - e0);
        set_wind_uniforms(r, p, o, time);
        glUniform1i(U(p, "u_tree_base"), (GLint)e0);
        for (size_t di = 0; di < s->n_draws; di++) {
            const sy_gltf_draw *d = &s->draws[di];
            if (d->object != o->object || d->level != level) continue;
            float node[16];
            for (int k = 0; k < 16; k++) node[k] = (float)d->world[k];
            glUniformMatrix4fv(U(p, "u_node"), 1, GL_FALSE, node);
            set_node_normal(p, d->world);
            glUniform1i(U(p, "u_instanced"), d->n_instances > 0);
            glUniform1i(U(p, "u_per_tree"), d->n_instances > 0 ? (GLint)d->n_instances : 1);
            if (d->n_instances) bind_tex(p, "u_inst", 11, GL_TEXTURE_BUFFER, g->inst_tex[di]);
            else bind_tex(p, "u_inst", 11, GL_TEXTURE_BUFFER, r->tree_tex);
            const sy_gltf_mesh *mesh = &s->meshes[d->mesh];
            for (int pi = 0; pi < mesh->n_primitives; pi++) {
                const gprim *q = &g->prims[mesh->first_primitive + pi];
                const sy_gltf_material *m = q->material >= 0 ? &s->materials[q->material] : &r->default_material;
                if (!shadow && (m->alpha_mode == SY_GLTF_BLEND) != blend_pass) continue;
                set_material(r, p, g, q->material, shadow);
                GLsizei n = copies * (GLsizei)(d->n_instances ? d->n_instances : 1);
                glBindVertexArray(q->vao);
                glDrawElementsInstanced(GL_TRIANGLES, q->count, GL_UNSIGNED_INT, NULL, n);
                if (!shadow) {
                    r->stats.triangles += q->triangles * (size_t)n;
                    r->stats.draw_calls++;
                }
            }
        }
        e0 = e1;
    }
    (void)c;
    glBindVertexArray(0);
    glDisable(GL_BLEND);
}

static void shadow_pass(renderer *r, double time)
{
    double center[3], rad = 0;
    for (int k = 0; k < 3; k++) {
        center[k] = 0.5 * (r->scene_min[k] + r->scene_max[k]);
        double h = 0.5 * (r->scene_max[k] - r->scene_min[k]);
        rad += h * h;
    }
    rad = fmax(sqrt(rad), 0.1) * 1.05;
    double eye[3], up[3] = {0, 1, 0};
    for (int k = 0; k < 3; k++) eye[k] = center[k] + r->sky.sun_dir[k] * rad * 2;
    mat4 v = m4_look_at(eye, center, up), pr = m4_ortho(-rad, rad, -rad, rad, rad * 0.5, rad * 3.5);
    mat4 vp = m4_mul(pr, v);
    mat4 bias = m4_identity();
    bias.m[0] = bias.m[5] = bias.m[10] = 0.5f;
    bias.m[12] = bias.m[13] = bias.m[14] = 0.5f;
    r->shadow_matrix = m4_mul(bias, vp);
    glBindFramebuffer(GL_FRAMEBUFFER, r->shadow_fbo);
    glViewport(0, 0, r->shadow_size, r->shadow_size);
    glClear(GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glEnable(GL_POLYGON_OFFSET_FILL);
    glPolygonOffset(1.5f, 2.0f);
    draw_trees(r, r->prog_shadow, NULL, &vp, time, 1, 0);
    glDisable(GL_POLYGON_OFFSET_FILL);
}

static void set_light_uniforms(renderer *r, GLuint p, const camera *c)
{
    float amb[27];
    for (int k = 0; k < 9; k++)
        for (int ch = 0; ch < 3; ch++) amb[k * 3 + ch] = r->sky.sh[k][ch] * (float)r->opt.ambient;
    glUniform3fv(U(p, "u_sh"), 9, amb);
    glUniform3fv(U(p, "u_sun_dir"), 1, r->sky.sun_dir);
    glUniform3fv(U(p, "u_sun_color"), 1, r->sky.sun_color);
    glUniform3f(U(p, "u_eye"), (float)c->eye[0], (float)c->eye[1], (float)c->eye[2]);
    glUniform1f(U(p, "u_exposure"), (float)r->opt.exposure);
    glUniform1i(U(p, "u_shadows"), r->opt.shadows);
    bind_tex(p, "u_shadow_map", 12, GL_TEXTURE_2D, r->shadow_depth);
    glUniformMatrix4fv(U(p, "u_shadow_matrix"), 1, GL_FALSE, r->shadow_matrix.m);
}

static void draw_text(renderer *r, const char *text)
{
    static char quads[160000];
    int nq = stb_easy_font_print(0, 0, (char *)text, NULL, quads, sizeof quads);
    if (nq <= 0) return;
    float *tri = malloc((size_t)nq * 6 * 6 * sizeof(float) + 6 * 6 * sizeof(float));
    if (!tri) return;
    /* A dark panel behind the text, then the glyph quads, all scaled 2x from the top left. */
    float w = (float)stb_easy_font_width((char *)text) * 2 + 16, h = (float)stb_easy_font_height((char *)text) * 2 + 12;
    float panel[6][2] = {{0, 0}, {w, 0}, {w, h}, {0, 0}, {w, h}, {0, h}};
    size_t k = 0;
    for (int i = 0; i < 6; i++) {
        float *v = tri + k++ * 6;
        v[0] = panel[i][0], v[1] = panel[i][1], v[2] = 0, v[3] = 0, v[4] = 0, v[5] = 0.55f;
    }
    static const int order[6] = {0, 1, 2, 0, 2, 3};
    for (int q = 0; q < nq; q++)
        for (int i = 0; i < 6; i++) {
            const float *src = (const float *)(quads + (size_t)(q * 4 + order[i]) * 16);
            float *v = tri + k++ * 6;
            v[0] = src[0] * 2 + 8, v[1] = src[1] * 2 + 6, v[2] = 1, v[3] = 1, v[4] = 0.85f, v[5] = 1;
        }
    glUseProgram(r->prog_text);
    glUniform2f(U(r->prog_text, "u_viewport"), (float)r->width, (float)r->height);
    glBindVertexArray(r->text_vao);
    glBindBuffer(GL_ARRAY_BUFFER, r->text_vbo);
    glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)(k * 6 * sizeof(float)), tri, GL_STREAM_DRAW);
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glDrawArrays(GL_TRIANGLES, 0, (GLsizei)k);
    glDisable(GL_BLEND);
    glBindVertexArray(0);
    free(tri);
}

static void stats_text(const renderer *r, char *buf, size_t size)
{
    size_t n = (size_t)snprintf(buf, size, "%.1f fps  %.2f ms\n%zu triangles  %zu draw calls\n", r->stats.fps, r->stats.frame_ms,
                                r->stats.triangles, r->stats.draw_calls);
    if (r->n_trees <= 8) {
        for (size_t i = 0; i < r->n_trees && n < size; i++) {
            const gtree *t = &r->trees[i];
            const gobject *go = &r->objs[t->object];
            const sy_gltf_object *o = &r->in->scenes[go->scene].objects[go->object];
            if (t->level < o->n_levels)
                n += (size_t)snprintf(buf + n, size - n, "%s: LOD%d  cover %.3f%s\n", o->name, t->level, t->coverage, t->fade < 1 ? " (fading)" : "");
            else
                n += (size_t)snprintf(buf + n, size - n, "%s: hidden  cover %.3f\n", o->name, t->coverage);
        }
    } else {
        n += (size_t)snprintf(buf + n, size - n, "%zu trees:", r->n_trees);
        for (int l = 0; l <= SY_GLTF_MAX_LODS && n < size; l++)
            if (r->stats.lod_hist[l]) n += (size_t)snprintf(buf + n, size - n, l < SY_GLTF_MAX_LODS ? " LOD%d x%d" : " hidden x%d", l, r->stats.lod_hist[l]);
        if (n < size) n += (size_t)snprintf(buf + n, size - n, "\n");
    }
    if (n < size)
        snprintf(buf + n, size - n, "wind %s %.2f @%.0f deg  translucency %s%s", r->opt.wind ? "on" : "off", r->opt.wind_strength,
                 r->opt.wind_dir_deg, r->opt.translucency ? "on" : "off", r->opt.lod_override >= 0 ? "  LOD locked" : "");
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void render_frame(renderer *r, camera *c, double time, GLuint target)
{
    r->stats.triangles = r->stats.draw_calls = 0;
    camera_update(r, c);
    build_entries(r, c);
    if (r->opt.shadows && !r->opt.mask) shadow_pass(r, time);
    glBindFramebuffer(GL_FRAMEBUFFER, target);
    glViewport(0, 0, r->width, r->height);
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LEQUAL);
    if (!r->opt.mask) {
        glDisable(GL_DEPTH_TEST);
        glUseProgram(r->prog_sky);
        GLuint p = r->prog_sky;
        mat4 inv = m4_inverse(c->view_proj);
        glUniformMatrix4fv(U(p, "u_inv_view_proj"), 1, GL_FALSE, inv.m);
        glUniform3f(U(p, "u_eye"), (float)c->eye[0], (float)c->eye[1], (float)c->eye[2]);
        glUniform3fv(U(p, "u_sun_dir"), 1, r->sky.sun_dir);
        glUniform3fv(U(p, "u_perez"), 5, &r->sky.perez[0][0]);
        glUniform3fv(U(p, "u_zenith"), 1, r->sky.zenith);
        glUniform3fv(U(p, "u_perez_sun"), 1, r->sky.perez_sun);
        glUniform1f(U(p, "u_sky_scale"), r->sky.scale);
        glUniform3fv(U(p, "u_sun_color"), 1, r->sky.sun_color);
        glUniform1f(U(p, "u_exposure"), (float)r->opt.exposure);
        glBindVertexArray(r->empty_vao);
        glDrawArrays(GL_TRIANGLES, 0, 3);
        glEnable(GL_DEPTH_TEST);
        if (r->opt.ground) {
            p = r->prog_ground;
            glUseProgram(p);
            glUniformMatrix4fv(U(p, "u_view_proj"), 1, GL_FALSE, c->view_proj.m);
            double gh = fmax(0.05, fmin(0.35, (r->scene_max[1] - r->scene_min[1]) * 0.04));
            glUniform1f(U(p, "u_y"), (float)(r->ground_y + (r->opt.grass ? gh : 0)));
            glUniform1f(U(p, "u_ground_y"), (float)r->ground_y);
            glUniform1i(U(p, "u_grass"), r->opt.grass);
            glUniform1f(U(p, "u_grass_height"), (float)gh);
            glUniform1f(U(p, "u_grass_spacing"), (float)(gh * 0.35));
            glUniform1i(U(p, "u_steps"), 8);
            glUniform1f(U(p, "u_time"), (float)time);
            double a = r->opt.wind_dir_deg * M_PI / 180;
            glUniform3f(U(p, "u_wind_dir"), (float)cos(a), 0.0f, (float)sin(a));
            glUniform1f(U(p, "u_wind_gain"), r->opt.wind ? (float)r->opt.wind_strength : 0.0f);
            bind_tex(p, "u_grass_tex", 13, GL_TEXTURE_2D_ARRAY, r->grass_tex);
            set_light_uniforms(r, p, c);
            glDisable(GL_CULL_FACE);
            glBindVertexArray(r->ground_vao);
            glDrawArrays(GL_TRIANGLES, 0, 6);
            r->stats.draw_calls++;
            r->stats.triangles += 2;
        }
    }
    GLuint p = r->prog_tree;
    glUseProgram(p);
    set_light_uniforms(r, p, c);
    glUniform1i(U(p, "u_translucency"), r->opt.translucency);
    glUniform1i(U(p, "u_mask"), r->opt.mask);
    glUniform1i(U(p, "u_wireframe"), r->opt.wireframe);
    if (r->opt.wireframe) glPolygonMode(GL_FRONT_AND_BACK, GL_LINE);
    draw_trees(r, p, c, &c->view_proj, time, 0, 0);
    glDepthMask(GL_FALSE);
    draw_trees(r, p, c, &c->view_proj, time, 0, 1);
    glDepthMask(GL_TRUE);
    glPolygonMode(GL_FRONT_AND_BACK, GL_FILL);
    glDisable(GL_CULL_FACE);
    if (r->n_points && r->opt.show_points && !r->opt.mask) {
        p = r->prog_points;
        glUseProgram(p);
        glUniformMatrix4fv(U(p, "u_view_proj"), 1, GL_FALSE, c->view_proj.m);
        mat4 m = m4_identity();
        m.m[12] = (float)r->points_offset[0], m.m[13] = (float)r->points_offset[1], m.m[14] = (float)r->points_offset[2];
        glUniformMatrix4fv(U(p, "u_model"), 1, GL_FALSE, m.m);
        glUniform1f(U(p, "u_point_size"), r->height >= 1000 ? 3.0f : 2.0f);
        glEnable(GL_PROGRAM_POINT_SIZE);
        glBindVertexArray(r->points_vao);
        glDrawArrays(GL_POINTS, 0, (GLsizei)r->n_points);
        r->stats.draw_calls++;
        glBindVertexArray(0);
    }
    if (r->opt.stats && !r->opt.mask) {
        char text[4096];
        stats_text(r, text, sizeof text);
        draw_text(r, text);
    }
}

/* ---- output ---- */
typedef struct { unsigned char *data; size_t size, cap; } membuf;
static void png_sink(void *ctx, void *data, int size)
{
    membuf *b = ctx;
    if (!b->data || size < 0) return;
    if (b->size + (size_t)size > b->cap) {
        size_t cap = (b->cap + (size_t)size) * 2;
        unsigned char *d = realloc(b->data, cap);
        if (!d) { free(b->data); b->data = NULL; return; }
        b->data = d, b->cap = cap;
    }
    memcpy(b->data + b->size, data, (size_t)size);
    b->size += (size_t)size;
}

static int save_png(renderer *r, GLuint fbo, const char *path)
{
    size_t stride = (size_t)r->width * 4;
    unsigned char *px = malloc(stride * (size_t)r->height);
    if (!px) {
        snprintf(r->msg, sizeof r->msg, "out of memory");
        return 3;
    }
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadPixels(0, 0, r->width, r->height, GL_RGBA, GL_UNSIGNED_BYTE, px);
    /* GL's rows run bottom-up. */
    unsigned char *row = malloc(stride);
    for (int y = 0; row && y < r->height / 2; y++) {
        memcpy(row, px + (size_t)y * stride, stride);
        memcpy(px + (size_t)y * stride, px + (size_t)(r->height - 1 - y) * stride, stride);
        memcpy(px + (size_t)(r->height - 1 - y) * stride, row, stride);
    }
    free(row);
    for (size_t i = 0; i < stride * (size_t)r->height; i += 4) px[i + 3] = 255;
    membuf b = {malloc(1 << 16), 0, 1 << 16};
    int ok = b.data && stbi_write_png_to_func(png_sink, &b, r->width, r->height, 4, px, (int)stride) && b.data;
    free(px);
    if (!ok) {
        free(b.data);
        snprintf(r->msg, sizeof r->msg, "%s: PNG encoding failed", path);
        return 3;
    }
    sy_error err = {0};
    sy_code rc = sy_write_file_atomic(path, b.data, b.size, &err);
    free(b.data);
    if (rc != SY_OK) {
        snprintf(r->msg, sizeof r->msg, "%.500s", err.msg);
        return 2;
    }
    return 0;
}

/* Transform feedback of the bark vertex shader: rest and swayed positions of every vertex of
 * the first tree's LOD0 non-instanced meshes, as CSV. */
static int dump_wind(renderer *r, const char *path, double time)
{
    FILE *fp = NULL;
    sy_atomic_file af;
    sy_error err = {0};
    if (sy_atomic_open(&af, path, &err) != SY_OK) {
        snprintf(r->msg, sizeof r->msg, "%.500s", err.msg);
        return 2;
    }
    fp = af.fp;
    fprintf(fp, "draw,vertex,branch,w0,w1,w2,w3,rest_x,rest_y,rest_z,x,y,z\n");
    const gobject *o = &r->objs[r->trees[0].object];
    const gscene *g = &r->gs[o->scene];
    const sy_gltf_scene *s = g->scene;
    r->n_entries = 1;
    r->entries[0] = (gentry){r->trees[0].object, 0, 1.0f, 1.0f, 0};
    float tb[20] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 1, 0};
    glBindBuffer(GL_TEXTURE_BUFFER, r->tree_buf);
    glBufferData(GL_TEXTURE_BUFFER, sizeof tb, tb, GL_STREAM_DRAW);
    glBindTexture(GL_TEXTURE_BUFFER, r->tree_tex);
    glTexBuffer(GL_TEXTURE_BUFFER, GL_RGBA32F, r->tree_buf);
    GLuint p = r->prog_probe;
    glUseProgram(p);
    mat4 id = m4_identity();
    glUniformMatrix4fv(U(p, "u_view_proj"), 1, GL_FALSE, id.m);
    bind_tex(p, "u_trees", 10, GL_TEXTURE_BUFFER, r->tree_tex);
    bind_tex(p, "u_inst", 11, GL_TEXTURE_BUFFER, r->tree_tex);
    glUniform1i(U(p, "u_tree_base"), 0);
    glUniform1i(U(p, "u_instanced"), 0);
    glUniform1i(U(p, "u_per_tree"), 1);
    glBindFramebuffer(GL_FRAMEBUFFER, r->fbo); /* surfaceless EGL has no default framebuffer */
    glEnable(GL_RASTERIZER_DISCARD);
    for (size_t di = 0; di < s->n_draws; di++) {
        const sy_gltf_draw *d = &s->draws[di];
        if (d->object != o->object || d->level != 0 || d->n_instances) continue;
        float node[16];
        for (int k = 0; k < 16; k++) node[k] = (float)d->world[k];
        glUniformMatrix4fv(U(p, "u_node"), 1, GL_FALSE, node);
        set_node_normal(p, d->world);
        const sy_gltf_mesh *mesh = &s->meshes[d->mesh];
        for (int pi = 0; pi < mesh->n_primitives; pi++) {
            const sy_gltf_primitive *sp = &s->primitives[mesh->first_primitive + pi];
            const gprim *q = &g->prims[mesh->first_primitive + pi];
            size_t n = sp->n_vertices;
            float *out[2] = {malloc(n * 3 * sizeof(float) + 4), malloc(n * 3 * sizeof(float) + 4)};
            GLuint tf;
            glGenBuffers(1, &tf);
            glBindBuffer(GL_TRANSFORM_FEEDBACK_BUFFER, tf);
            glBufferData(GL_TRANSFORM_FEEDBACK_BUFFER, (GLsizeiptr)(n * 3 * sizeof(float)), NULL, GL_STREAM_READ);
            glBindBufferBase(GL_TRANSFORM_FEEDBACK_BUFFER, 0, tf);
            for (int pass = 0; pass < 2; pass++) {
                sy_view_options keep = r->opt;
                if (pass == 0) r->opt.wind = 0;
                set_wind_uniforms(r, p, o, time);
                r->opt = keep;
                glBindVertexArray(q->vao);
                glBeginTransformFeedback(GL_POINTS);
                glDrawArrays(GL_POINTS, 0, (GLsizei)n);
                glEndTransformFeedback();
                glGetBufferSubData(GL_TRANSFORM_FEEDBACK_BUFFER, 0, (GLsizeiptr)(n * 3 * sizeof(float)), out[pass]);

            }
            glDeleteBuffers(1, &tf);
            for (size_t v = 0; v < n && out[0] && out[1]; v++) {
                const float *w = sp->wind_w ? sp->wind_w + 4 * v : NULL;
                fprintf(fp, "%zu,%zu,%d,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g,%.7g\n", di, v,
                        sp->wind_branch ? (int)sp->wind_branch[v] : -1, w ? w[0] : 0, w ? w[1] : 0, w ? w[2] : 0, w ? w[3] : 0,
                        out[0][3 * v], out[0][3 * v + 1], out[0][3 * v + 2], out[1][3 * v], out[1][3 * v + 1], out[1][3 * v + 2]);
            }
            free(out[0]), free(out[1]);
        }
    }
    glDisable(GL_RASTERIZER_DISCARD);
    glBindVertexArray(0);
    if (sy_atomic_commit(&af, &err) != SY_OK) {
        snprintf(r->msg, sizeof r->msg, "%.500s", err.msg);
        return 2;
    }
    return 0;
}

static void print_json(renderer *r, const camera *c, double frame_ms, double cpu_ms, int frames)
{
    printf("{\"width\": %d, \"height\": %d, \"fovy_deg\": %.1f, \"eye\": [%.6f, %.6f, %.6f], \"target\": [%.6f, %.6f, %.6f],\n",
           r->width, r->height, FOVY_DEG, c->eye[0], c->eye[1], c->eye[2], c->target[0], c->target[1], c->target[2]);
    printf(" \"camera\": [%.4f, %.4f, %.6f], \"near\": %.6f,\n", c->az, c->el, c->dist, fmax(0.01, c->dist * 0.01));
    printf(" \"sun_dir\": [%.6f, %.6f, %.6f], \"sun_color\": [%.6f, %.6f, %.6f], \"exposure\": %.6f,\n", r->sky.sun_dir[0],
           r->sky.sun_dir[1], r->sky.sun_dir[2], r->sky.sun_color[0], r->sky.sun_color[1], r->sky.sun_color[2], r->opt.exposure);
    printf(" \"triangles\": %zu, \"draw_calls\": %zu, \"frames\": %d, \"frame_ms\": %.3f, \"cpu_ms_per_frame\": %.3f,\n",
           r->stats.triangles, r->stats.draw_calls, frames, frame_ms, cpu_ms);
    size_t lod0 = 0;
    for (size_t i = 0; i < r->n_trees; i++) {
        const gobject *go = &r->objs[r->trees[i].object];
        lod0 += r->in->scenes[go->scene].objects[go->object].n_triangles[0];
    }
    size_t hl2 = 0, transmitting = 0;
    for (size_t i = 0; i < r->n_gs; i++)
        for (size_t k = 0; k < r->gs[i].scene->n_materials; k++) {
            const sy_gltf_material *m = &r->gs[i].scene->materials[k];
            hl2 += m->hl2_adaxial_texture >= 0 && m->hl2_abaxial_texture >= 0;
            transmitting += m->diffuse_transmission > 0;
        }
    printf(" \"lod0_triangles\": %zu, \"renderer\": \"%s\", \"hl2_materials\": %zu, \"transmitting_materials\": %zu,\n", lod0,
           (const char *)glGetString(GL_RENDERER), hl2, transmitting);
    if (r->n_points) {
        /* The overlay's bounds as drawn (glTF frame of the scene), for checking the frame change. */
        double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
        const sy_view_points *p = &r->in->points;
        for (size_t i = 0; i < p->n; i++)
            for (int k = 0; k < 3; k++) {
                double v = p->xyz[3 * i + k] + r->points_offset[k];
                lo[k] = fmin(lo[k], v), hi[k] = fmax(hi[k], v);
            }
        printf(" \"points\": %zu, \"points_min\": [%.5f, %.5f, %.5f], \"points_max\": [%.5f, %.5f, %.5f],\n", p->n, lo[0], lo[1], lo[2],
               hi[0], hi[1], hi[2]);
    }
    printf(" \"trees\": [");
    for (size_t i = 0; i < r->n_trees; i++) {
        const gtree *t = &r->trees[i];
        const gobject *go = &r->objs[t->object];
        const sy_gltf_object *o = &r->in->scenes[go->scene].objects[go->object];
        printf("%s\n  {\"name\": \"%s\", \"levels\": %d, \"coverage\": %.5f, \"lod\": %d, \"fade\": %.4f, \"drawn\": [%d, %d], \"thresholds\": [",
               i ? "," : "", o->name, o->n_levels, t->coverage, t->level, t->fade, t->draw_a, t->draw_b);
        for (int l = 0; l < o->n_levels; l++) printf("%s%.5f", l ? ", " : "", o->coverage[l]);
        printf("], \"level_triangles\": [");
        for (int l = 0; l < o->n_levels; l++) printf("%s%zu", l ? ", " : "", o->n_triangles[l]);
        printf("], \"bounds_min\": [%.6f, %.6f, %.6f], \"bounds_max\": [%.6f, %.6f, %.6f]}", o->bounds_min[0] + t->offset[0],
               o->bounds_min[1] + t->offset[1], o->bounds_min[2] + t->offset[2], o->bounds_max[0] + t->offset[0],
               o->bounds_max[1] + t->offset[1], o->bounds_max[2] + t->offset[2]);
    }
    printf("]}\n");
}

static double cpu_seconds(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) * 1e-6;
}

/* ---- interactive ---- */
typedef struct {
    renderer *r;
    camera *c;
    double last_x, last_y;
    int drag; /* 1 orbit, 2 pan */
    int shots;
    int want_shot;
} ui_state;

static void on_key(GLFWwindow *w, int key, int sc, int action, int mods)
{
    (void)sc, (void)mods;
    ui_state *u = glfwGetWindowUserPointer(w);
    if (action == GLFW_RELEASE) return;
    sy_view_options *o = &u->r->opt;
    switch (key) {
    case GLFW_KEY_ESCAPE: case GLFW_KEY_Q: glfwSetWindowShouldClose(w, 1); break;
    case GLFW_KEY_F: camera_frame(u->r, u->c); break;
    case GLFW_KEY_X: o->wireframe = !o->wireframe; break;
    case GLFW_KEY_L: {
        int maxl = 0;
        for (size_t i = 0; i < u->r->in->n_scenes; i++)
            for (size_t k = 0; k < u->r->in->scenes[i].n_objects; k++) maxl = maxl > u->r->in->scenes[i].objects[k].n_levels ? maxl : u->r->in->scenes[i].objects[k].n_levels;
        o->lod_override = o->lod_override + 1 >= maxl ? -1 : o->lod_override + 1;
        break;
    }
    case GLFW_KEY_SPACE: o->wind = !o->wind; break;
    case GLFW_KEY_EQUAL: case GLFW_KEY_KP_ADD: o->wind_strength *= 1.25; break;
    case GLFW_KEY_MINUS: case GLFW_KEY_KP_SUBTRACT: o->wind_strength /= 1.25; break;
    case GLFW_KEY_LEFT_BRACKET: o->wind_dir_deg -= 15; break;
    case GLFW_KEY_RIGHT_BRACKET: o->wind_dir_deg += 15; break;
    case GLFW_KEY_T: o->translucency = !o->translucency; break;
    case GLFW_KEY_P: o->show_points = !o->show_points; break;
    case GLFW_KEY_G: o->grass = !o->grass; break;
    case GLFW_KEY_H: o->stats = !o->stats; break;
    case GLFW_KEY_J: case GLFW_KEY_K: case GLFW_KEY_U: case GLFW_KEY_I:
        if (key == GLFW_KEY_J) o->sun_az -= 10;
        if (key == GLFW_KEY_K) o->sun_az += 10;
        if (key == GLFW_KEY_U) o->sun_el = fmax(1, o->sun_el - 5);
        if (key == GLFW_KEY_I) o->sun_el = fmin(90, o->sun_el + 5);
        sy_sky_make(&u->r->sky, o->sun_az, o->sun_el, o->turbidity);
        break;
    case GLFW_KEY_O: case GLFW_KEY_F12: u->want_shot = 1; break;
    default: break;
    }
}

static void on_button(GLFWwindow *w, int button, int action, int mods)
{
    (void)mods;
    ui_state *u = glfwGetWindowUserPointer(w);
    if (action == GLFW_PRESS) {
        glfwGetCursorPos(w, &u->last_x, &u->last_y);
        u->drag = button == GLFW_MOUSE_BUTTON_LEFT ? 1 : 2;
    } else
        u->drag = 0;
}

static void on_cursor(GLFWwindow *w, double x, double y)
{
    ui_state *u = glfwGetWindowUserPointer(w);
    double dx = x - u->last_x, dy = y - u->last_y;
    u->last_x = x, u->last_y = y;
    camera *c = u->c;
    if (u->drag == 1) {
        c->az += dx * 0.3;
        c->el = fmax(-89, fmin(89, c->el + dy * 0.3));
    } else if (u->drag == 2) {
        /* The scene follows the pointer (the right vector pointed left:
         * it moved against it). */
        double right[3], k = c->dist * 0.0015;
        ground_right(c->az, right);
        for (int i = 0; i < 3; i++) c->target[i] -= right[i] * dx * k;
        c->target[1] += dy * k;
    }
}

static void on_scroll(GLFWwindow *w, double dx, double dy)
{
    (void)dx;
    ui_state *u = glfwGetWindowUserPointer(w);
    u->c->dist *= pow(0.9, dy);
}

static void on_resize(GLFWwindow *w, int width, int height)
{
    ui_state *u = glfwGetWindowUserPointer(w);
    if (width > 0 && height > 0) u->r->width = width, u->r->height = height;
}

static int interactive(renderer *r, camera *c, void *window)
{
    GLFWwindow *w = window;
    ui_state u = {r, c, 0, 0, 0, 0, 0};
    glfwSetWindowUserPointer(w, &u);
    glfwSetKeyCallback(w, on_key);
    glfwSetMouseButtonCallback(w, on_button);
    glfwSetCursorPosCallback(w, on_cursor);
    glfwSetScrollCallback(w, on_scroll);
    glfwSetFramebufferSizeCallback(w, on_resize);
    glfwGetFramebufferSize(w, &r->width, &r->height);
    double start = now_s(), last = start, acc = 0;
    int count = 0;
    while (!glfwWindowShouldClose(w)) {
        double t0 = now_s(), dt = t0 - last;
        last = t0;
        /* WASD / arrows move the orbit centre in the view's ground plane; PgUp/PgDn up and down. */
        double az = c->az * M_PI / 180, step = c->dist * 0.6 * dt;
        double fwd[3] = {-cos(az), 0, -sin(az)}, right[3];
        ground_right(c->az, right); /* D and the right arrow to the right (they went left) */
        int kf = glfwGetKey(w, GLFW_KEY_W) || glfwGetKey(w, GLFW_KEY_UP), kb = glfwGetKey(w, GLFW_KEY_S) || glfwGetKey(w, GLFW_KEY_DOWN);
        int kl = glfwGetKey(w, GLFW_KEY_A) || glfwGetKey(w, GLFW_KEY_LEFT), kr = glfwGetKey(w, GLFW_KEY_D) || glfwGetKey(w, GLFW_KEY_RIGHT);
        for (int i = 0; i < 3; i++) c->target[i] += step * ((kf - kb) * fwd[i] + (kr - kl) * right[i]);
        c->target[1] += step * (glfwGetKey(w, GLFW_KEY_PAGE_UP) - glfwGetKey(w, GLFW_KEY_PAGE_DOWN));
        render_frame(r, c, t0 - start + r->opt.time, 0);
        glfwSwapBuffers(w);
        if (u.want_shot) {
            char name[64];
            snprintf(name, sizeof name, "sylva-view-%03d.png", u.shots++);
            glReadBuffer(GL_BACK);
            if (save_png(r, 0, name) == 0) fprintf(stderr, "sylva view: wrote %s\n", name);
            u.want_shot = 0;
        }
        glfwPollEvents();
        acc += now_s() - t0;
        if (++count == 20 || acc > 0.5) { /* 20 frames or half a second, whichever comes first */
            r->stats.frame_ms = acc / count * 1000;
            r->stats.fps = 1000 / r->stats.frame_ms;
            acc = 0, count = 0;
        }
    }
    return 0;
}

/* ---- entry ---- */
static void release(renderer *r)
{
    for (size_t i = 0; i < r->n_gs; i++) {
        gscene *g = &r->gs[i];
        if (g->prims)
            for (size_t k = 0; k < g->scene->n_primitives; k++) {
                glDeleteVertexArrays(1, &g->prims[k].vao);
                glDeleteBuffers(7, g->prims[k].vbo);
                glDeleteBuffers(1, &g->prims[k].ebo);
            }
        if (g->textures) glDeleteTextures((GLsizei)g->scene->n_textures, g->textures);
        free(g->prims), free(g->textures), free(g->inst_buf), free(g->inst_tex);
    }
    free(r->gs), free(r->objs), free(r->trees), free(r->entries);
    sy_motion_free(&r->motion);
}

int sy_view_run(const sy_view_input *in, const sy_view_options *opt)
{
    int headless = opt->screenshot || opt->frames > 0 || opt->bench > 0 || opt->dump_wind || opt->json;
    char msg[512];
    sy_gl_context *ctx = sy_gl_open(headless, opt->width, opt->height, "sylva view", msg, sizeof msg);
    if (!ctx) {
        fprintf(stderr, "sylva view: no OpenGL: %s\n", msg);
        return 2;
    }
    renderer *r = calloc(1, sizeof *r);
    int rc = 3;
    if (!r) goto out;
    r->in = in;
    r->opt = *opt;
    r->width = opt->width, r->height = opt->height;
    r->default_material = (sy_gltf_material){.base_color = {1, 1, 1, 1}, .metallic = 1, .roughness = 1, .base_color_texture = -1,
                                             .metallic_roughness_texture = -1, .normal_texture = -1, .normal_scale = 1,
                                             .alpha_cutoff = 0.5f, .diffuse_transmission_texture = -1,
                                             .diffuse_transmission_color_texture = -1, .hl2_adaxial_texture = -1,
                                             .hl2_abaxial_texture = -1, .hl2_min = -1, .hl2_max = 3};
    /* The glTF default material is metallic 1; a preview of untextured scans reads better dielectric. */
    r->default_material.metallic = 0;
    r->default_material.roughness = 0.8f;
    if (sy_motion_make(&r->motion, 256, 2.0, opt->seed) != 0) { snprintf(r->msg, sizeof r->msg, "out of memory"); goto fail; }
    sy_sky_make(&r->sky, opt->sun_az, opt->sun_el, opt->turbidity);
    if (build_programs(r) != 0) goto fail;
    r->n_gs = in->n_scenes;
    r->gs = calloc(in->n_scenes + 1, sizeof(gscene));
    if (!r->gs) goto fail;
    for (size_t i = 0; i < in->n_scenes; i++) {
        r->gs[i].scene = &in->scenes[i];
        r->gs[i].scene_index = (int)i;
        int u = upload_scene(r, &r->gs[i]);
        if (u) {
            if (u == -2) {
                char m2[600];
                snprintf(m2, sizeof m2, "%s: %s", in->paths[i], r->msg);
                snprintf(r->msg, sizeof r->msg, "%.500s", m2);
                rc = 2;
            }
            goto fail;
        }
    }
    int lr = layout(r);
    if (lr) { rc = lr == -2 ? 2 : 3; goto fail; }
    setup_static_textures(r);
    setup_shadow(r);
    setup_points(r);
    setup_ground(r);
    if (headless) {
        int tr = setup_targets(r);
        if (tr) { rc = 2; goto fail; }
    }
    camera cam = {0};
    camera_frame(r, &cam);
    cam.az = DEFAULT_CAMERA_AZ, cam.el = 12;
    if (opt->camera_set) {
        cam.az = opt->cam_az, cam.el = opt->cam_el;
        if (opt->cam_dist > 0) cam.dist = opt->cam_dist;
    }
    if (opt->target_set) memcpy(cam.target, opt->target, sizeof cam.target);
    if (opt->dump_wind) {
        rc = dump_wind(r, opt->dump_wind, opt->time);
        if (rc) goto fail;
        goto done;
    }
    if (!headless) {
        rc = interactive(r, &cam, sy_gl_window(ctx));
        goto done;
    }
    int frames = 0;
    double wall = 0, cpu0 = cpu_seconds();
    if (opt->bench > 0) {
        /* Timed frames: each one finished (glFinish) before the clock stops. */
        render_frame(r, &cam, opt->time, r->fbo);
        glFinish();
        cpu0 = cpu_seconds();
        double t0 = now_s();
        for (int f = 0; f < opt->bench; f++) {
            render_frame(r, &cam, opt->time + f / 30.0, r->fbo);
            glFinish();
        }
        wall = now_s() - t0;
        frames = opt->bench;
    }
    if (opt->frames > 0) {
        mkdir(opt->out_dir, 0777);
        if (!sy_is_directory(opt->out_dir)) {
            snprintf(r->msg, sizeof r->msg, "%s: cannot create the output folder", opt->out_dir);
            rc = 2;
            goto fail;
        }
        double t0 = now_s();
        for (int f = 0; f < opt->frames; f++) {
            double t = opt->time + f / opt->fps;
            render_frame(r, &cam, t, r->fbo);
            if (frames == 0 && f > 0) {
                r->stats.frame_ms = (now_s() - t0) / f * 1000;
                r->stats.fps = 1000 / r->stats.frame_ms;
            }
            char path[4096];
            snprintf(path, sizeof path, "%s/frame_%04d.png", opt->out_dir, f);
            if ((rc = save_png(r, r->fbo, path)) != 0) goto fail;
        }
        if (!frames) { wall = now_s() - t0; frames = opt->frames; }
    }
    if (opt->screenshot || frames == 0) {
        double t0 = now_s();
        if (frames) {
            r->stats.frame_ms = wall / frames * 1000;
            r->stats.fps = 1000 / r->stats.frame_ms;
        } else {
            /* One frame to measure, one to show its figures. */
            render_frame(r, &cam, opt->time, r->fbo);
            glFinish();
            wall = now_s() - t0;
            frames = 1;
            r->stats.frame_ms = wall * 1000;
            r->stats.fps = 1 / wall;
        }
        render_frame(r, &cam, opt->time, r->fbo);
        if (opt->screenshot && (rc = save_png(r, r->fbo, opt->screenshot)) != 0) goto fail;
    }
    if (opt->json) print_json(r, &cam, wall / frames * 1000, (cpu_seconds() - cpu0) / frames * 1000, frames);
    else if (opt->bench > 0)
        printf("%zu trees  %d frames  %.2f ms/frame  (cpu %.2f ms/frame)  %zu triangles  %zu draw calls  %s\n", r->n_trees, frames,
               wall / frames * 1000, (cpu_seconds() - cpu0) / frames * 1000, r->stats.triangles, r->stats.draw_calls,
               (const char *)glGetString(GL_RENDERER));
done:
    rc = 0;
    release(r);
    free(r);
    sy_gl_close(ctx);
    return rc;
fail:
    if (r && r->msg[0]) fprintf(stderr, "sylva view: %s\n", r->msg);
    if (r) release(r);
    free(r);
out:
    sy_gl_close(ctx);
    return rc;
}
