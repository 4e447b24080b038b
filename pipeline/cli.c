#include "cli.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "stages/core/fileio.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"

static const sy_opt global_opts[] = {
    {"--json", OPT_FLAG, NULL, NULL, "machine-readable output on stdout"},
    {"--quiet", OPT_FLAG, NULL, NULL, "no progress output"},
    {"--threads", OPT_INT, NULL, "N", "worker threads (default: all cores)"},
    {"--seed", OPT_INT, NULL, "N", "random seed (default 1)"},
    {"--help", OPT_FLAG, NULL, NULL, "this help"},
    {NULL, 0, NULL, NULL, NULL},
};

static void print_opts(const sy_opt *opts)
{
    for (const sy_opt *o = opts; o && o->name; o++) {
        char left[64];
        snprintf(left, sizeof left, "%s%s%s", o->name, o->metavar ? " " : "", o->metavar ? o->metavar : "");
        /* A help text's later lines line up under its first. */
        printf("  %-24s ", left);
        for (const char *h = o->help; *h; h++) {
            putchar(*h);
            if (*h == '\n') printf("%27s", "");
        }
        putchar('\n');
    }
}

static void print_help(const sy_cmd_spec *s)
{
    printf("usage: sylva %s [options] %s\n\n%s\n", s->name, s->usage, s->summary);
    if (s->details) printf("\n%s\n", s->details);
    if (s->opts && s->opts->name) {
        printf("\noptions:\n");
        print_opts(s->opts);
    }
    printf("\ncommon options:\n");
    print_opts(global_opts);
}

static int parse_number(const char *cmd, const char *name, const char *text, int is_int, double *out)
{
    char *end;
    errno = 0;
    double v = is_int ? (double)strtoll(text, &end, 10) : strtod(text, &end);
    /* NaN is never a setting (it would read as "unset" downstream); whole
     * numbers must fit an int, as every integer option is one. */
    if (errno || end == text || *end || isnan(v) || (is_int && !(v >= INT_MIN && v <= INT_MAX))) {
        fprintf(stderr, "sylva %s: %s expects a %s, got '%s'\n", cmd, name, is_int ? "whole number" : "number",
                text);
        return SY_EUSAGE;
    }
    *out = v;
    return SY_OK;
}

/* Reads n comma-separated numbers ("1,2,3"). */
static int parse_list(const char *cmd, const char *name, const char *text, int n, double *out)
{
    const char *p = text;
    for (int i = 0; i < n; i++) {
        char *end;
        errno = 0;
        out[i] = strtod(p, &end);
        if (errno || end == p || isnan(out[i]) || (i + 1 < n ? *end != ',' : *end != '\0')) {
            fprintf(stderr, "sylva %s: %s expects %d comma-separated numbers, got '%s'\n", cmd, name, n, text);
            return SY_EUSAGE;
        }
        p = end + 1;
    }
    return SY_OK;
}

static int is_file_option(const char *name)
{
    static const char *files[] = {"-o", "--sylva", "--png", "--truth", "--points"};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++)
        if (strcmp(name, files[i]) == 0) return 1;
    return 0;
}

static int apply(const char *cmd, const sy_opt *o, const char *value)
{
    double v;
    switch (o->kind) {
    case OPT_FLAG: *(int *)o->target = 1; return SY_OK;
    case OPT_STRING:
        /* A second -o would silently win over the first: refused for the
         * file options (the others may carry a default). */
        if (*(const char **)o->target && is_file_option(o->name)) {
            fprintf(stderr, "sylva %s: %s given twice ('%s' and '%s')\n", cmd, o->name, *(const char **)o->target,
                    value);
            return SY_EUSAGE;
        }
        *(const char **)o->target = value;
        return SY_OK;
    case OPT_INT:
        if (parse_number(cmd, o->name, value, 1, &v)) return SY_EUSAGE;
        *(int *)o->target = (int)v;
        return SY_OK;
    case OPT_DOUBLE:
        if (parse_number(cmd, o->name, value, 0, &v)) return SY_EUSAGE;
        *(double *)o->target = v;
        return SY_OK;
    case OPT_DOUBLE3: return parse_list(cmd, o->name, value, 3, o->target);
    case OPT_DOUBLE6: return parse_list(cmd, o->name, value, 6, o->target);
    }
    return SY_EUSAGE;
}

int sy_cli_parse(const sy_cmd_spec *spec, int argc, char **argv, sy_cli *cli, const char **pos,
                 int max, int *n_pos)
{
    *n_pos = 0;
    int only_positional = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (only_positional || a[0] != '-' || a[1] == '\0') {
            if (spec->max_pos >= 0 && *n_pos >= spec->max_pos) {
                fprintf(stderr, "sylva %s: unexpected argument '%s' (see --help)\n", spec->name, a);
                return SY_EUSAGE;
            }
            if (*n_pos >= max) {
                fprintf(stderr, "sylva %s: too many arguments\n", spec->name);
                return SY_EUSAGE;
            }
            pos[(*n_pos)++] = a;
            continue;
        }
        if (strcmp(a, "--") == 0) {
            only_positional = 1;
            continue;
        }
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            print_help(spec);
            return -1;
        }
        if (strcmp(a, "--json") == 0) { cli->json = 1; continue; }
        if (strcmp(a, "--quiet") == 0 || strcmp(a, "-q") == 0) { cli->quiet = 1; continue; }
        if (strcmp(a, "--threads") == 0 || strcmp(a, "--seed") == 0) {
            double v = 0;
            if (i + 1 >= argc) {
                fprintf(stderr, "sylva %s: %s needs a value\n", spec->name, a);
                return SY_EUSAGE;
            }
            if (parse_number(spec->name, a, argv[++i], 1, &v) || v < 0) {
                if (v < 0) fprintf(stderr, "sylva %s: %s must not be negative\n", spec->name, a);
                return SY_EUSAGE;
            }
            if (a[2] == 't') cli->threads = (int)v;
            else cli->seed = (unsigned long long)v;
            continue;
        }
        const sy_opt *match = NULL;
        for (const sy_opt *o = spec->opts; o && o->name; o++)
            if (strcmp(o->name, a) == 0) match = o;
        if (!match) {
            fprintf(stderr, "sylva %s: unknown option '%s' (see --help)\n", spec->name, a);
            return SY_EUSAGE;
        }
        const char *value = NULL;
        if (match->kind != OPT_FLAG) {
            if (i + 1 >= argc) {
                fprintf(stderr, "sylva %s: %s needs a value\n", spec->name, a);
                return SY_EUSAGE;
            }
            value = argv[++i];
        }
        if (apply(spec->name, match, value)) return SY_EUSAGE;
    }
    if (*n_pos < spec->min_pos) {
        fprintf(stderr, "sylva %s: missing argument (usage: sylva %s %s)\n", spec->name, spec->name, spec->usage);
        return SY_EUSAGE;
    }
    return SY_OK;
}

void sy_cli_apply_settings(const sy_cli *cli)
{
    sy_progress_set_quiet(cli->quiet || cli->json);
    sy_set_threads(cli->threads);
}

void sy_cli_json_open(sy_json *j, const char *input, const char *output)
{
    sy_json_begin(j, stdout, 0);
    sy_json_object(j, NULL);
    if (input) sy_json_string(j, "input", input);
    if (output) sy_json_string(j, "output", output);
}

void sy_cli_json_close(sy_json *j)
{
    sy_json_end(j);
    sy_json_finish(j);
}

int sy_cli_report(const sy_error *err)
{
    /* Always one line: a path named in the message may hold a newline. */
    fputs("sylva: ", stderr);
    for (const char *s = err->msg[0] ? err->msg : "failed"; *s; s++)
        fputc((unsigned char)*s < 0x20 || *s == 0x7f ? '?' : *s, stderr);
    fputc('\n', stderr);
    return err->code ? (int)err->code : SY_EINTERNAL;
}

int sy_cli_check_outputs(const char *const *outs, size_t n_out, const char *const *ins, size_t n_in)
{
    sy_error err = {0};
    for (size_t i = 0; i < n_out; i++) {
        if (!outs[i]) continue;
        if (sy_output_check(outs[i], ins, n_in, &err)) return sy_cli_report(&err);
        /* Two outputs naming one file: the second would replace the first. */
        if (sy_output_check(outs[i], outs, i, &err)) {
            sy_fail(&err, SY_EUSAGE, "%s: named for two outputs", outs[i]);
            return sy_cli_report(&err);
        }
    }
    return 0;
}

int sy_cli_begin(const sy_cmd_spec *spec, int argc, char **argv, sy_cli *cli, const char **pos, int max, int *n_pos,
                 sy_cli_out out, int *status)
{
    int rc = sy_cli_parse(spec, argc, argv, cli, pos, max, n_pos);
    if (rc) {
        *status = rc < 0 ? 0 : rc; /* -1: --help was printed */
        return 0;
    }
    sy_cli_apply_settings(cli);
    *status = 0;
    if (out == SY_CLI_OUT_NONE) return 1;
    const sy_opt *o = spec->opts;
    while (o && o->name && strcmp(o->name, "-o") != 0) o++;
    if (!o || !o->name || o->kind != OPT_STRING) {
        fprintf(stderr, "sylva %s: no -o option to check (a bug)\n", spec->name);
        *status = SY_EINTERNAL;
        return 0;
    }
    const char *const *path = o->target;
    if (!*path) {
        fprintf(stderr, "sylva %s: -o %s is required\n", spec->name, o->metavar ? o->metavar : "OUT");
        *status = SY_EUSAGE;
        return 0;
    }
    if (out == SY_CLI_OUT_CHECKED) *status = sy_cli_check_outputs(path, 1, pos, (size_t)*n_pos);
    return *status == 0;
}

int sy_cli_parse_all(const sy_cmd_spec *spec, int argc, char **argv, sy_cli *cli, const char ***pos, int *n_pos)
{
    *n_pos = 0;
    *pos = calloc((size_t)argc + 1, sizeof **pos);
    if (!*pos) return SY_EINTERNAL;
    int rc = sy_cli_parse(spec, argc, argv, cli, *pos, argc, n_pos);
    if (rc) {
        free(*pos);
        *pos = NULL;
    }
    return rc;
}

static int executable(const char *p) { return access(p, X_OK) == 0; }

int sy_find_executable(const char *name, const char *env, char *out, size_t size)
{
    const char *given = env ? getenv(env) : NULL;
    if (given && *given) {
        snprintf(out, size, "%s", given);
        return executable(out);
    }
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    if (n > 0) {
        self[n] = 0;
        char *slash = strrchr(self, '/');
        if (slash) {
            *slash = 0;
            snprintf(out, size, "%s/%s", self, name);
            if (executable(out)) return 1;
        }
    }
    const char *path = getenv("PATH");
    for (const char *p = path; p && *p;) {
        const char *e = strchr(p, ':');
        size_t len = e ? (size_t)(e - p) : strlen(p);
        snprintf(out, size, "%.*s/%s", (int)len, p, name);
        if (len && executable(out)) return 1;
        p = e ? e + 1 : p + len;
    }
    return 0;
}
