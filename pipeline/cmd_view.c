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

int sy_find_viewer(char *out, size_t size) { return sy_find_executable("sylva-view", "SYLVA_VIEW", out, size); }

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
