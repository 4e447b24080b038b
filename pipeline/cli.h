/* The `sylva` command line: global options, a declarative option table per
 * subcommand, generated --help, and the subcommand registry. */
#ifndef SYLVA_CLI_H
#define SYLVA_CLI_H

#include "stages/core/json.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Options every subcommand accepts. */
typedef struct {
    int json;     /* --json: machine-readable stdout */
    int quiet;    /* --quiet: no progress */
    int threads;  /* --threads N (0: all cores) */
    unsigned long long seed; /* --seed N */
} sy_cli;

typedef enum { OPT_FLAG, OPT_INT, OPT_DOUBLE, OPT_STRING, OPT_DOUBLE3, OPT_DOUBLE6 } sy_opt_kind;

typedef struct {
    const char *name;    /* "--voxel" */
    sy_opt_kind kind;
    void *target;        /* int*, double*, const char** or double[3]/[6] */
    const char *metavar; /* "SIZE" (NULL for flags) */
    const char *help;
} sy_opt;

typedef struct {
    const char *name;
    const char *usage;    /* "FILE..." */
    const char *summary;  /* one line */
    const char *details;  /* more lines for --help, may be NULL */
    const sy_opt *opts;   /* terminated by {NULL} */
    int min_pos, max_pos; /* positional argument counts (-1: unbounded) */
} sy_cmd_spec;

/* Parses argv (argv[0] is the subcommand name) into cli and the option
 * targets of spec (which point into the command's per-call argument struct:
 * no option lives in file-scope storage). Positional arguments land in
 * pos (capacity max). Sets no global state. Returns SY_OK, SY_EUSAGE (message already printed), or
 * -1 when --help was printed (exit 0). */
int sy_cli_parse(const sy_cmd_spec *spec, int argc, char **argv, sy_cli *cli, const char **pos,
                 int max, int *n_pos);

/* sy_cli_parse for commands that take any number of positional arguments:
 * *pos is allocated with room for all of them (the caller frees it). On any
 * non-zero return *pos is NULL and the return is as sy_cli_parse's, with
 * SY_EINTERNAL when out of memory. */
int sy_cli_parse_all(const sy_cmd_spec *spec, int argc, char **argv, sy_cli *cli, const char ***pos, int *n_pos);

/* What a command's opening asks of its -o (the "-o" entry of its option
 * table: target and metavar). */
typedef enum {
    SY_CLI_OUT_NONE,     /* nothing: -o is optional, or the command checks more first */
    SY_CLI_OUT_REQUIRED, /* -o must be given ("sylva NAME: -o META is required", exit 1) */
    SY_CLI_OUT_CHECKED   /* ... and obey the output rule against the positional arguments */
} sy_cli_out;

/* The opening every command makes, so that a command reads: begin (parse,
 * check), call, report. In this order: sy_cli_parse into spec's option
 * targets and pos; sy_cli_apply_settings; then what `out` asks of -o
 * (SY_CLI_OUT_CHECKED: sy_cli_check_outputs on it and the *n_pos inputs).
 * Returns 1 to go on; 0 when the command is over: *status is then its exit
 * status (0 after --help; otherwise the usage or output error, printed). */
int sy_cli_begin(const sy_cmd_spec *spec, int argc, char **argv, sy_cli *cli, const char **pos, int max, int *n_pos,
                 sy_cli_out out, int *status);

/* The two process-wide settings a command makes once, after parsing:
 * sy_set_threads(--threads) and sy_progress_set_quiet(--quiet or --json).
 * They change speed and stderr, never output bytes. */
void sy_cli_apply_settings(const sy_cli *cli);

/* The output rule for a verb, before any work (stages/core/fileio.h): each
 * of the n_out outputs (NULL entries skipped) must be writable, no device or
 * directory it must not replace, no input (n_in paths) and no other output.
 * Prints one line and returns its exit code (2), or 0. */
int sy_cli_check_outputs(const char *const *outs, size_t n_out, const char *const *ins, size_t n_in);

/* A command's --json report on stdout: one object that opens with "input"
 * and "output" (each left out when NULL), the command's own fields after
 * them; sy_cli_json_close ends the object and the line. */
void sy_cli_json_open(sy_json *j, const char *input, const char *output);
void sy_cli_json_close(sy_json *j);

/* Another of Sylva's executables (sylva-pipeline, sylva-view): $env when
 * set and non-empty, else the one beside the running executable, else the
 * first `name` on PATH. Writes its path to out; 1 when it is executable. */
int sy_find_executable(const char *name, const char *env, char *out, size_t size);

/* Prints "sylva: <msg>" on stderr and returns err->code (the exit status). */
int sy_cli_report(const sy_error *err);

typedef int (*sy_cmd_fn)(int argc, char **argv, sy_cli *cli);
typedef struct {
    const char *name;
    const char *summary;
    sy_cmd_fn fn;
} sy_command;

/* The registry, defined in pipeline/commands.c. */
extern const sy_command sy_commands[];

#ifdef __cplusplus
}
#endif

#endif
