/* sylva: tree scans to game-ready glTF. Dispatches to one subcommand per stage. */
#include <stdio.h>
#include <string.h>

#include "pipeline/cli.h"

static void usage(FILE *fp)
{
    fprintf(fp, "usage: sylva COMMAND [options] ARGS   (sylva COMMAND --help for details)\n\ncommands:\n");
    for (const sy_command *c = sy_commands; c->name; c++) fprintf(fp, "  %-12s %s\n", c->name, c->summary);
    fprintf(fp, "\nsylva --version prints the version. Exit codes: 0 ok, 1 usage, 2 bad input, 3 internal.\n");
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        usage(stderr);
        return SY_EUSAGE;
    }
    if (strcmp(argv[1], "--version") == 0 || strcmp(argv[1], "version") == 0) {
        printf("sylva %s\n", SYLVA_VERSION);
        return 0;
    }
    if (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0 || strcmp(argv[1], "help") == 0) {
        usage(stdout);
        return 0;
    }
    for (const sy_command *c = sy_commands; c->name; c++)
        if (strcmp(c->name, argv[1]) == 0) {
            sy_cli cli = {0, 0, 0, 1};
            return c->fn(argc - 1, argv + 1, &cli);
        }
    fprintf(stderr, "sylva: unknown command '%s'\n", argv[1]);
    usage(stderr);
    return SY_EUSAGE;
}
