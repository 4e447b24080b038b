/* The batch as a Slurm job array: one task per share of the trees (tree k
 * goes to task k mod N), each task the same `sylva batch` with
 * --slurm-task k --slurm-tasks N, so outputs, records and resume are the
 * local run's. The last task to finish merges the report; a resubmission
 * (the same command again) redoes only what is missing. */
#include <dirent.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "pipeline/batch.h"
#include "stages/core/fileio.h"

sy_slurm_options sy_slurm_options_default(void)
{
    sy_slurm_options o;
    memset(&o, 0, sizeof o);
    return o;
}

sy_code sy_slurm_options_check(const sy_slurm_options *o, sy_error *err)
{
    if (o->array_size < 0) return sy_fail(err, SY_EUSAGE, "slurm: array_size %d must be >= 0", o->array_size);
    if (o->cpus < 0) return sy_fail(err, SY_EUSAGE, "slurm: cpus %d must be >= 0", o->cpus);
    const struct {
        const char *name, *v;
    } lines[] = {{"partition", o->partition}, {"time", o->time}, {"mem", o->mem}};
    for (size_t i = 0; i < sizeof lines / sizeof *lines; i++)
        if (lines[i].v && lines[i].v[strcspn(lines[i].v, "\r\n")])
            return sy_fail(err, SY_EUSAGE, "slurm: %s holds a line break", lines[i].name);
    return SY_OK;
}

/* Single-quoted for sh: ' becomes '\''. */
static void sh_quote(FILE *fp, const char *s)
{
    fputc('\'', fp);
    for (; *s; s++) {
        if (*s == '\'') fputs("'\\''", fp);
        else fputc(*s, fp);
    }
    fputc('\'', fp);
}

/* The Slurm flags of `sylva batch` (with their argument counts): the task's
 * command line is the user's without them. */
static int slurm_flag(const char *a)
{
    static const char *const with_arg[] = {"--partition", "--time", "--mem", "--array-size", "--cpus-per-task", "--sbatch",
                                           "--slurm-task", "--slurm-tasks"};
    static const char *const flags[] = {"--slurm", "--no-submit"};
    for (size_t i = 0; i < sizeof with_arg / sizeof *with_arg; i++)
        if (!strcmp(a, with_arg[i])) return 2;
    for (size_t i = 0; i < sizeof flags / sizeof *flags; i++)
        if (!strcmp(a, flags[i])) return 1;
    return 0;
}

static void clear_markers(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char p[8500];
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.') continue;
        if (snprintf(p, sizeof p, "%s/%s", dir, e->d_name) < (int)sizeof p) unlink(p);
    }
    closedir(d);
}

sy_code sy_slurm_submit(const sy_batch_inputs *in, const char *out_dir, const char *sylva_exe, int argc,
                        char **argv, const sy_slurm_options *so, char *job_id, size_t job_id_size, sy_error *err)
{
    sy_code rc = sy_slurm_options_check(so, err);
    if (rc) return rc;
    if ((rc = sy_batch_prepare_dir(out_dir, err))) return rc;
    char abs_out[4096], cwd[4096], dir[8192], done[8300], script[8300];
    if (!getcwd(cwd, sizeof cwd)) return sy_fail(err, SY_EINTERNAL, "batch: getcwd: %s", strerror(errno));
    /* The tasks start in cwd (the script cds there), so out_dir as given works; the log path must be absolute. */
    if (out_dir[0] == '/') snprintf(abs_out, sizeof abs_out, "%s", out_dir);
    else if (snprintf(abs_out, sizeof abs_out, "%s/%s", cwd, out_dir) >= (int)sizeof abs_out)
        return sy_fail(err, SY_EINPUT, "%s: path too long", out_dir);
    snprintf(dir, sizeof dir, "%s/slurm", abs_out);
    snprintf(done, sizeof done, "%s/done", dir);
    if ((mkdir(dir, 0755) && errno != EEXIST) || (mkdir(done, 0755) && errno != EEXIST))
        return sy_fail(err, SY_EINPUT, "%s: cannot create the folder: %s", dir, strerror(errno));
    /* A new submission: the markers of the last one do not count. */
    clear_markers(done);
    int tasks = so->array_size ? so->array_size : (int)(in->n < 100 ? in->n : 100);
    if (tasks < 1) tasks = 1;
    if ((size_t)tasks > in->n) tasks = (int)in->n;
    snprintf(script, sizeof script, "%s/batch.sbatch", dir);
    sy_atomic_file f;
    if ((rc = sy_atomic_open(&f, script, err))) return rc;
    FILE *fp = f.fp;
    fprintf(fp, "#!/bin/sh\n# Written by sylva batch --slurm: %zu trees in %d array tasks (docs/batch.md).\n", in->n, tasks);
    fprintf(fp, "#SBATCH --job-name=sylva-batch\n#SBATCH --array=0-%d\n#SBATCH --output=%s/task-%%A_%%a.log\n", tasks - 1,
            dir);
    fprintf(fp, "#SBATCH --cpus-per-task=%d\n", so->cpus > 0 ? so->cpus : 1);
    if (so->partition) fprintf(fp, "#SBATCH --partition=%s\n", so->partition);
    if (so->time) fprintf(fp, "#SBATCH --time=%s\n", so->time);
    if (so->mem) fprintf(fp, "#SBATCH --mem=%s\n", so->mem);
    fprintf(fp, "cd ");
    sh_quote(fp, cwd);
    fprintf(fp, " || exit 1\nexec ");
    sh_quote(fp, sylva_exe);
    fprintf(fp, " batch");
    for (int i = 0; i < argc; i++) {
        int k = slurm_flag(argv[i]);
        if (k) {
            i += k - 1;
            continue;
        }
        fputc(' ', fp);
        sh_quote(fp, argv[i]);
    }
    fprintf(fp, " --slurm-task \"$SLURM_ARRAY_TASK_ID\" --slurm-tasks %d\n", tasks);
    if ((rc = sy_atomic_commit(&f, err))) return rc;
    chmod(script, 0755);
    if (so->no_submit) {
        snprintf(job_id, job_id_size, "(not submitted)");
        return SY_OK;
    }
    /* sbatch --parsable prints "JOBID[;CLUSTER]". */
    int pfd[2];
    if (pipe(pfd)) return sy_fail(err, SY_EINTERNAL, "batch: pipe: %s", strerror(errno));
    fflush(NULL);
    pid_t pid = fork();
    if (pid < 0) return sy_fail(err, SY_EINTERNAL, "batch: fork: %s", strerror(errno));
    if (pid == 0) {
        close(pfd[0]);
        dup2(pfd[1], 1);
        close(pfd[1]);
        const char *sb = so->sbatch ? so->sbatch : "sbatch";
        execlp(sb, sb, "--parsable", script, (char *)NULL);
        fprintf(stderr, "sylva batch: cannot run %s: %s\n", sb, strerror(errno));
        _exit(127);
    }
    close(pfd[1]);
    char out[256] = "";
    size_t len = 0;
    ssize_t r;
    while ((r = read(pfd[0], out + len, sizeof out - 1 - len)) > 0) len += (size_t)r;
    out[len] = 0;
    close(pfd[0]);
    int status;
    waitpid(pid, &status, 0);
    if (!WIFEXITED(status) || WEXITSTATUS(status))
        return sy_fail(err, SY_EINPUT, "%s: sbatch refused the job (exit %d)", script, WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    char *semi = strpbrk(out, ";\n");
    if (semi) *semi = 0;
    snprintf(job_id, job_id_size, "%s", out);
    return SY_OK;
}

sy_code sy_slurm_task_done(const sy_batch_inputs *in, const char *out_dir, const sy_batch_options *o, sy_error *err)
{
    char done[8300], marker[8400];
    snprintf(done, sizeof done, "%s/slurm/done", out_dir);
    char slurm[8300];
    snprintf(slurm, sizeof slurm, "%s/slurm", out_dir);
    mkdir(slurm, 0755);
    if (mkdir(done, 0755) && errno != EEXIST)
        return sy_fail(err, SY_EINPUT, "%s: cannot create the folder: %s", done, strerror(errno));
    snprintf(marker, sizeof marker, "%s/task-%d-of-%d", done, o->task_index, o->task_count);
    sy_code rc = sy_write_file_atomic(marker, "done\n", 5, err);
    if (rc) return rc;
    for (int k = 0; k < o->task_count; k++) {
        snprintf(marker, sizeof marker, "%s/task-%d-of-%d", done, k, o->task_count);
        if (access(marker, F_OK)) return SY_OK; /* not the last: another task merges */
    }
    /* The last task: the report of the whole batch (every plot's trees from its record). */
    sy_batch_inputs ex;
    if ((rc = sy_batch_expand(in, out_dir, o, 0, &ex, err))) return rc;
    rc = sy_batch_report(&ex, out_dir, o, err);
    sy_batch_inputs_free(&ex);
    return rc;
}
