/* sylva batch INPUTS... -o OUTDIR: many scans to a folder of trees and a
 * report, on every core, resumable; --slurm runs it as a job array,
 * --collect merges the report (docs/batch.md). */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "pipeline/batch.h"
#include "pipeline/commands.h"
#include "stages/core/json.h"

int cmd_batch(int argc, char **argv, sy_cli *cli)
{
    const char *out_dir = NULL;
    sy_batch_options o = sy_batch_options_default();
    sy_slurm_options so = sy_slurm_options_default();
    sy_glb_args glb = sy_glb_args_default();
    int no_resume = 0, no_thumbs = 0, no_eval = 0, no_classify = 0, no_voting = 0, collect = 0, slurm = 0;
    int task = -1, tasks = 0;
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &out_dir, "OUTDIR", "output folder (created; a rerun resumes it)"},
        {"--workers", OPT_INT, &o.workers, "N", "worker processes, one tree each (default: one per core)"},
        {"--no-resume", OPT_FLAG, &no_resume, NULL, "redo every tree, even those finished with the same input and options"},
        {"--retry-failed", OPT_FLAG, &o.retry_failed, NULL, "redo trees recorded as failed (default: kept as failed)"},
        {"--species", OPT_STRING, &o.run.species, "NAME", "one library species for every tree (default: manifest, else classify)"},
        {"--model", OPT_STRING, &o.run.model, "MODEL.sjb", "species classifier (default: the shipped one)"},
        {"--no-classify", OPT_FLAG, &no_classify, NULL, "without a species, keep the default parameters"},
        {"--radius", OPT_DOUBLE, &o.vote.radius, "M", "spatial voting radius in metres (default 25)"},
        {"--ratio", OPT_DOUBLE, &o.vote.ratio, "R", "confident iff h1 > R * h2 (default 1.5)"},
        {"--no-voting", OPT_FLAG, &no_voting, NULL, "no spatial voting across the batch"},
        {"--no-thumbnails", OPT_FLAG, &no_thumbs, NULL, "no sylva-view shot per tree"},
        {"--thumb-size", OPT_INT, &o.thumb_size, "PX", "thumbnail side (default 256)"},
        {"--viewer", OPT_STRING, &o.viewer, "PATH", "the sylva-view executable (default: beside sylva, $SYLVA_VIEW, PATH)"},
        {"--no-eval", OPT_FLAG, &no_eval, NULL, "do not score each asset against its own points"},
        {"--max-memory", OPT_DOUBLE, &o.max_memory_gb, "GB", "address-space cap per worker (default: memory / workers)"},
        {"--timeout", OPT_DOUBLE, &o.worker_timeout, "S", "stop a tree's worker after S seconds (default: none)"},
        {"--beta", OPT_DOUBLE, &o.run.beta, "B", "Dijkstra edge weight (default: species, else 1)"},
        {"--gamma", OPT_DOUBLE, &o.run.gamma, "G", "allometry exponent (default: species, else 2)"},
        {"--voxel", OPT_DOUBLE, &o.run.voxel, "SIZE", "thin each scan to one point per SIZE-metre voxel first"},
        SY_GLB_OPTIONS(glb),
        {"--collect", OPT_FLAG, &collect, NULL, "only merge the records in OUTDIR into index.json, trees.csv, report.html"},
        {"--slurm", OPT_FLAG, &slurm, NULL, "write OUTDIR/slurm/batch.sbatch (a job array) and submit it with sbatch"},
        {"--partition", OPT_STRING, &so.partition, "P", "Slurm partition (default: the cluster's)"},
        {"--time", OPT_STRING, &so.time, "T", "Slurm time limit per task (HH:MM:SS)"},
        {"--mem", OPT_STRING, &so.mem, "M", "Slurm memory per task (e.g. 8G)"},
        {"--array-size", OPT_INT, &so.array_size, "N", "array tasks (default: trees, at most 100)"},
        {"--cpus-per-task", OPT_INT, &so.cpus, "N", "Slurm cpus per task; its workers (default 1)"},
        {"--sbatch", OPT_STRING, &so.sbatch, "PATH", "the sbatch executable (default: on PATH)"},
        {"--no-submit", OPT_FLAG, &so.no_submit, NULL, "with --slurm: write the script, do not submit it"},
        {"--slurm-task", OPT_INT, &task, "K", "(set by the job script) this array task's index"},
        {"--slurm-tasks", OPT_INT, &tasks, "N", "(set by the job script) the array's size"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "batch", "INPUTS... -o OUTDIR",
        "Reconstruct every tree of folders, files or manifests: per tree .glb, .sylva, species, metrics,\n"
        "scores and a thumbnail; per batch index.json, trees.csv and report.html.",
        "INPUTS: folders (their .las .laz .ply .pcd .xyz .txt files), scan files, or manifests: a .csv\n"
        "whose header names a file column (and optionally species, x, y, z, label) or a .json array of\n"
        "{\"file\", \"species\", \"position\": [x, y, z], \"label\"}. Each tree runs in its own worker process\n"
        "(a crash fails that tree only) and its outputs are committed together with a record of the\n"
        "input's content hash and the options: a rerun skips finished trees, redoes changed ones, and a\n"
        "batch killed at any moment resumes where it was. Unconfident species take the vote of confident\n"
        "neighbours within --radius (positions from the manifest or LAS coordinates). Progress: a bar on\n"
        "a TTY, a line per tree otherwise, JSON events with --json. --slurm runs the same batch as a Slurm\n"
        "job array (the last task merges the report; run the command again to resubmit what is missing).",
        opts, 0, -1};
    const char **pos;
    int n;
    int rc = sy_cli_parse_all(&spec, argc, argv, cli, &pos, &n);
    if (rc) return rc < 0 ? 0 : rc;
    sy_cli_apply_settings(cli);
    if (!out_dir) {
        fprintf(stderr, "sylva batch: -o OUTDIR is required\n");
        free(pos);
        return SY_EUSAGE;
    }
    if (!n && !collect) {
        fprintf(stderr, "sylva batch: no inputs (folders, files or a manifest)\n");
        free(pos);
        return SY_EUSAGE;
    }
    if ((task >= 0) != (tasks > 0)) {
        fprintf(stderr, "sylva batch: --slurm-task and --slurm-tasks go together\n");
        free(pos);
        return SY_EUSAGE;
    }
    o.resume = !no_resume;
    o.thumbnails = !no_thumbs;
    o.eval = !no_eval;
    o.run.classify = !no_classify;
    o.vote.voting = !no_voting;
    o.run.seed = cli->seed;
    o.json = cli->json;
    o.quiet = cli->quiet;
    o.threads = cli->threads;
    sy_glb_args_apply(&glb, &o.run.asset);
    if (tasks) {
        o.task_index = task;
        o.task_count = tasks;
        if (!o.workers) {
            const char *c = getenv("SLURM_CPUS_PER_TASK");
            o.workers = c && atoi(c) > 0 ? atoi(c) : 1;
        }
    }
    sy_error err = {0};
    if (sy_batch_options_check(&o, &err) || sy_slurm_options_check(&so, &err)) {
        free(pos);
        return sy_cli_report(&err);
    }
    sy_batch_inputs in;
    memset(&in, 0, sizeof in);
    if (n && sy_batch_inputs_collect(pos, (size_t)n, &in, &err)) {
        free(pos);
        return sy_cli_report(&err);
    }
    free(pos);
    if (collect) {
        sy_batch_inputs ex;
        memset(&ex, 0, sizeof ex);
        rc = n ? sy_batch_expand(&in, out_dir, &o, 0, &ex, &err) : SY_OK;
        if (!rc) rc = sy_batch_report(n ? &ex : NULL, out_dir, &o, &err);
        sy_batch_inputs_free(&ex);
        sy_batch_inputs_free(&in);
        if (rc) return sy_cli_report(&err);
        if (!cli->quiet && !cli->json) fprintf(stderr, "sylva batch: wrote %s/index.json, trees.csv and report.html\n", out_dir);
        return 0;
    }
    if (slurm) {
        char exe[PATH_MAX];
        ssize_t l = readlink("/proc/self/exe", exe, sizeof exe - 1);
        if (l <= 0) {
            sy_batch_inputs_free(&in);
            fprintf(stderr, "sylva batch: cannot find this sylva executable for the job script\n");
            return SY_EINTERNAL;
        }
        exe[l] = 0;
        char job[128];
        rc = sy_slurm_submit(&in, out_dir, exe, argc - 1, argv + 1, &so, job, sizeof job, &err);
        sy_batch_inputs_free(&in);
        if (rc) return sy_cli_report(&err);
        if (cli->json) {
            sy_json j;
            sy_cli_json_open(&j, NULL, NULL);
            sy_json_string(&j, "event", "submitted");
            sy_json_string(&j, "job", job);
            sy_cli_json_close(&j);
        } else if (!cli->quiet) {
            fprintf(stderr, "sylva batch: %s/slurm/batch.sbatch %s%s\n", out_dir, so.no_submit ? "written, " : "submitted as job ",
                    job);
        }
        return 0;
    }
    sy_batch_summary s;
    rc = sy_batch_run(&in, out_dir, &o, &s, &err);
    sy_batch_inputs_free(&in);
    if (rc) return sy_cli_report(&err);
    if (cli->json) {
        sy_json j;
        sy_cli_json_open(&j, NULL, NULL);
        sy_json_string(&j, "event", "done");
        sy_json_int(&j, "trees", (long long)s.trees);
        sy_json_int(&j, "made", (long long)s.done);
        sy_json_int(&j, "kept", (long long)s.skipped);
        sy_json_int(&j, "failed", (long long)s.failed);
        sy_json_int(&j, "interrupted", (long long)s.interrupted);
        sy_json_number(&j, "seconds", s.seconds);
        sy_cli_json_close(&j);
    } else if (!cli->quiet) {
        fprintf(stderr, "sylva batch: %zu trees: %zu made, %zu kept, %zu failed in %.1f s; %s/report.html\n", s.trees, s.done,
                s.skipped, s.failed, s.seconds, out_dir);
        if (s.interrupted)
            fprintf(stderr, "sylva batch: %zu tree%s interrupted by a signal to %s worker, not recorded: run the same command again\n",
                    s.interrupted, s.interrupted == 1 ? "" : "s", s.interrupted == 1 ? "its" : "their");
    }
    return 0;
}
