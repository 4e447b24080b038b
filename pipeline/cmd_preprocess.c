#include "pipeline/commands.h"
int cmd_preprocess(int argc, char **argv, sy_cli *cli) { (void)argc; (void)argv; (void)cli; return 3; }
