/* sylva: the command-line front. `sylva --version` and `sylva info` run here,
 * linking only the core and the readers; every other command runs in
 * sylva-pipeline (pipeline/main.c), which this front execs with the same
 * arguments, so the pid, the streams and the exit status are that command's.
 * Why: the pipeline links PCL, CGAL, OpenCV (and through them BLAS, LAPACK,
 * TBB, X11: 30 shared libraries), whose loading alone cost 6 ms before a byte
 * was read, four times what reading a 1.5 MB scan costs (issue 12). */
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "pipeline/cli.h"
#include "pipeline/commands.h"

int main(int argc, char **argv)
{
    if (argc >= 2 && (strcmp(argv[1], "--version") == 0 || strcmp(argv[1], "version") == 0)) {
        printf("sylva %s\n", SYLVA_VERSION);
        return 0;
    }
    if (argc >= 2 && strcmp(argv[1], "info") == 0) {
        sy_cli cli = {0, 0, 0, 1};
        return cmd_info(argc - 1, argv + 1, &cli);
    }
    char pipeline[PATH_MAX + 32];
    if (!sy_find_executable("sylva-pipeline", "SYLVA_PIPELINE", pipeline, sizeof pipeline)) {
        fprintf(stderr, "sylva: sylva-pipeline is not installed beside sylva or on PATH\n");
        return SY_EINTERNAL;
    }
    argv[0] = pipeline;
    execv(pipeline, argv);
    fprintf(stderr, "sylva: cannot run %s: %s\n", pipeline, strerror(errno));
    return SY_EINTERNAL;
}
