/* Entry points of the subcommands, one file each (pipeline/cmd_<name>.c). */
#ifndef SYLVA_COMMANDS_H
#define SYLVA_COMMANDS_H

#include "pipeline/cli.h"

#ifdef __cplusplus
extern "C" {
#endif

int cmd_info(int argc, char **argv, sy_cli *cli);
int cmd_convert(int argc, char **argv, sy_cli *cli);
int cmd_preprocess(int argc, char **argv, sy_cli *cli);
int cmd_grow(int argc, char **argv, sy_cli *cli);
int cmd_scan(int argc, char **argv, sy_cli *cli);
int cmd_eval(int argc, char **argv, sy_cli *cli);
int cmd_skeleton(int argc, char **argv, sy_cli *cli);
int cmd_mesh(int argc, char **argv, sy_cli *cli);
int cmd_run(int argc, char **argv, sy_cli *cli);
int cmd_encode(int argc, char **argv, sy_cli *cli);
int cmd_decode(int argc, char **argv, sy_cli *cli);
int cmd_library(int argc, char **argv, sy_cli *cli);

#ifdef __cplusplus
}
#endif

#endif
