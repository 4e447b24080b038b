/* OpenGL 3.3 core contexts: EGL surfaceless (Mesa) for headless work, GLFW for a window. */
#include "viewer/viewer.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <stdio.h>
#include <stdlib.h>

struct sy_gl_context {
    int headless;
    EGLDisplay display;
    EGLContext context;
    GLFWwindow *window;
};

static sy_gl_context *open_egl(char *msg, size_t size)
{
    if (!epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_MESA_platform_surfaceless") &&
        !epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_EXT_platform_base")) {
        snprintf(msg, size, "no EGL surfaceless platform (Mesa's libegl-mesa0)");
        return NULL;
    }
    EGLDisplay d = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL);
    EGLint major = 0, minor = 0;
    if (d == EGL_NO_DISPLAY || !eglInitialize(d, &major, &minor)) {
        snprintf(msg, size, "EGL surfaceless display did not initialise (0x%x)", (unsigned)eglGetError());
        return NULL;
    }
    /* Surfaceless rendering needs no config (EGL_KHR_no_config_context); otherwise any
     * config that renders desktop GL. */
    const EGLint cfg_attr[] = {EGL_SURFACE_TYPE, 0, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLConfig cfg = (EGLConfig)0;
    EGLint n = 0;
    if (!eglBindAPI(EGL_OPENGL_API)) {
        eglTerminate(d);
        snprintf(msg, size, "EGL cannot render desktop OpenGL");
        return NULL;
    }
    if (!epoxy_has_egl_extension(d, "EGL_KHR_no_config_context") && (!eglChooseConfig(d, cfg_attr, &cfg, 1, &n) || n < 1)) {
        eglTerminate(d);
        snprintf(msg, size, "EGL has no desktop OpenGL config");
        return NULL;
    }
    const EGLint ctx_attr[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 3, EGL_CONTEXT_OPENGL_PROFILE_MASK,
                               EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    EGLContext ctx = eglCreateContext(d, cfg, EGL_NO_CONTEXT, ctx_attr);
    if (ctx == EGL_NO_CONTEXT || !eglMakeCurrent(d, EGL_NO_SURFACE, EGL_NO_SURFACE, ctx)) {
        eglTerminate(d);
        snprintf(msg, size, "EGL could not make an OpenGL 3.3 core context current (0x%x)", (unsigned)eglGetError());
        return NULL;
    }
    sy_gl_context *c = calloc(1, sizeof *c);
    if (!c) {
        eglDestroyContext(d, ctx);
        eglTerminate(d);
        snprintf(msg, size, "out of memory");
        return NULL;
    }
    c->headless = 1, c->display = d, c->context = ctx;
    return c;
}

static sy_gl_context *open_glfw(int w, int h, const char *title, char *msg, size_t size)
{
    if (!glfwInit()) {
        snprintf(msg, size, "no display for a window (GLFW could not initialise; use --screenshot for headless)");
        return NULL;
    }
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    GLFWwindow *win = glfwCreateWindow(w, h, title, NULL, NULL);
    if (!win) {
        glfwTerminate();
        snprintf(msg, size, "GLFW could not open an OpenGL 3.3 core window");
        return NULL;
    }
    glfwMakeContextCurrent(win);
    glfwSwapInterval(1);
    sy_gl_context *c = calloc(1, sizeof *c);
    if (!c) {
        glfwDestroyWindow(win);
        glfwTerminate();
        snprintf(msg, size, "out of memory");
        return NULL;
    }
    c->window = win;
    return c;
}

sy_gl_context *sy_gl_open(int headless, int width, int height, const char *title, char *msg, size_t size)
{
    sy_gl_context *c = headless ? open_egl(msg, size) : open_glfw(width, height, title, msg, size);
    if (!c) return NULL;
    if (epoxy_gl_version() < 33) {
        snprintf(msg, size, "OpenGL %d.%d found, 3.3 core needed", epoxy_gl_version() / 10, epoxy_gl_version() % 10);
        sy_gl_close(c);
        return NULL;
    }
    return c;
}

void sy_gl_close(sy_gl_context *c)
{
    if (!c) return;
    if (c->headless) {
        eglMakeCurrent(c->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
        eglDestroyContext(c->display, c->context);
        /* No eglTerminate: the process ends next, and terminating unloads Mesa's driver with
         * allocations it never frees, which LeakSanitizer then reports against whatever library
         * later occupies those addresses. */
    } else {
        glfwDestroyWindow(c->window);
        glfwTerminate();
    }
    free(c);
}

void *sy_gl_window(sy_gl_context *c) { return c ? c->window : NULL; }
