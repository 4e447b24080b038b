/* sylva view FILE.glb...: the GL preview. It lives in its own executable, sylva-view, so
 * that sylva itself never links GL: this verb finds it next to the running sylva (or on
 * PATH, or at $SYLVA_VIEW) and hands it the arguments. */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "pipeline/commands.h"

static int executable(const char *p) { return access(p, X_OK) == 0; }

int sy_find_viewer(char *out, size_t size)
{
    const char *env = getenv("SYLVA_VIEW");
    if (env && *env) {
        snprintf(out, size, "%s", env);
        return executable(out);
    }
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n > 0) {
        self[n] = 0;
        char *slash = strrchr(self, '/');
        if (slash) {
            *slash = 0;
            snprintf(out, size, "%s/sylva-view", self);
            if (executable(out)) return 1;
        }
    }
    const char *path = getenv("PATH");
    for (const char *p = path; p && *p;) {
        const char *e = strchr(p, ':');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        snprintf(out, size, "%.*s/sylva-view", (int)len, p);
        if (len && executable(out)) return 1;
        p = e ? e + 1 : p + len;
    }
    return 0;
}

int cmd_view(int argc, char **argv, sy_cli *cli)
{
    (void)cli;
    char viewer[PATH_MAX + 16];
    if (!sy_find_viewer(viewer, sizeof viewer)) {
        fprintf(stderr, "sylva view: no GL preview here: sylva-view is not installed (build it with GLFW, epoxy and EGL)\n");
        return SY_EINPUT;
    }
    char **args = calloc((size_t)argc + 1, sizeof(char *));
    if (!args) return SY_EINTERNAL;
    args[0] = viewer;
    for (int i = 1; i < argc; i++) args[i] = argv[i];
    fflush(NULL);
    execv(viewer, args);
    fprintf(stderr, "sylva view: cannot run %s: %s\n", viewer, strerror(errno));
    free(args);
    return SY_EINPUT;
}
