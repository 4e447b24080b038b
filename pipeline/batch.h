/* The batch runner: many scans in, a folder of trees and a report out
 * (docs/batch.md). The pipeline owns files and order, so this is where
 * inputs are found (folders, files, CSV/JSON manifests), where the work is
 * spread over worker processes (one tree per forked worker, so a crashing
 * tree never stops the batch), where each tree's outputs are committed
 * atomically beside a record of its input's content hash and the options
 * (resume: a rerun skips what is finished and redoes what changed), and
 * where the batch-wide products are made: spatial voting, index.json, the
 * foresters' CSV and report.html. The Slurm bridge (batch_slurm.c) runs the
 * same jobs as a job array.
 *
 * Layout of OUTDIR:
 *   trees/ID.glb, ID.sylva, ID.png (thumbnail), ID.glb.js (the glb for the
 *        report's 3D preview), ID.json (the record, committed last)
 *   index.json, trees.csv, report.html, report/ (three.js bundle)
 *   slurm/ (job script and task logs, with --slurm) */
#ifndef SYLVA_BATCH_H
#define SYLVA_BATCH_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "classify/classify.h"
#include "pipeline/run_tree.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One tree's input: a file, with what a manifest may say about it. */
typedef struct {
    char *path;        /* the scan file (malloc'd) */
    char *id;          /* the tree id: the file's name without extension, made unique in input order */
    char *species;     /* species hint (a library name), or NULL: classify */
    char *label;       /* the true species for the confusion matrix, or NULL */
    int has_position;  /* position given by the manifest (or a plot's stem) */
    double position[3];
    size_t origin;     /* index of the argument-level input it came from (a plot's trees share it) */
    int from_plot;     /* a tree segmented out of a plot: position is its stem */
} sy_batch_input;

typedef struct {
    size_t n, cap;
    sy_batch_input *items;
} sy_batch_inputs;

/* Expands each argument: a folder gives its point-cloud files (las laz ply
 * pcd xyz txt; sorted by name, not recursive), a .json file or a .csv whose
 * header names a "file" column is a manifest (columns/keys: file, species,
 * x, y, z, label; relative paths are relative to the manifest), anything
 * else is one scan. Ids are unique: a repeated file name gets "-2", "-3"...
 * in input order. A missing path or a malformed manifest fails with one
 * SY_EINPUT line naming it. */
sy_code sy_batch_inputs_collect(const char *const *args, size_t n, sy_batch_inputs *out, sy_error *err);
void sy_batch_inputs_free(sy_batch_inputs *in);

typedef struct {
    int workers;        /* worker processes; 0: one per core */
    int threads;        /* threads inside a worker; 0: cores / workers, at least 1 */
    int resume;         /* 1: keep finished trees whose input and options are unchanged (1) */
    int retry_failed;   /* 1: redo trees recorded as failed even when nothing changed (0) */
    int thumbnails;     /* 1: a headless sylva-view shot per tree (1) */
    int thumb_size;     /* its side in pixels (256) */
    const char *viewer; /* the sylva-view executable; NULL: found beside sylva, $SYLVA_VIEW, PATH */
    int eval;           /* 1: score each asset against its own points (1) */
    double max_memory_gb; /* per worker address-space cap in GiB; 0: physical memory / workers */
    double worker_timeout; /* seconds one tree may take before its worker is killed; 0: none */
    sy_run_tree_options run; /* species/classify/seed...; on_step is not used */
    sy_vote_options vote;    /* spatial voting across the batch */
    int json;           /* --json events on stdout */
    int quiet;          /* no progress */
    /* Slurm task: process only jobs k with k % task_count == task_index (task_count 0: all). */
    int task_index, task_count;
    int report;         /* 1: write index.json, trees.csv and report.html at the end (1) */
} sy_batch_options;

sy_batch_options sy_batch_options_default(void);
sy_code sy_batch_options_check(const sy_batch_options *o, sy_error *err);

typedef struct {
    size_t trees, done, skipped, failed; /* jobs; finished now; kept from before; failed (now or before) */
    size_t interrupted;                  /* workers a stop signal ended: no record, to do next run */
    double seconds;
} sy_batch_summary;

/* Runs the batch into out_dir (created if missing). Failures of single
 * trees are recorded, never returned; the return is an error only for the
 * batch itself (out_dir unusable, out of memory). */
sy_code sy_batch_run(const sy_batch_inputs *in, const char *out_dir, const sy_batch_options *o,
                     sy_batch_summary *summary, sy_error *err);

/* The batch products from the records in out_dir/trees for the given
 * inputs (all records when in is NULL): voting, index.json, trees.csv,
 * report.html and its three.js bundle. Deterministic: the same records
 * give the same bytes (timings are in the records, so they are too). */
sy_code sy_batch_report(const sy_batch_inputs *in, const char *out_dir, const sy_batch_options *o,
                        sy_error *err);

/* Plots (batch_plots.c): each input of this task whose plot record is
 * missing or stale is judged (sy_segment_is_plot) and, when it holds
 * several trees, segmented in a worker into out_dir/plots/ID/ID_tNNN.las
 * and out_dir/plots/ID.json (segment_now 0: records only, nothing run).
 * out gets every input, each plot replaced by its trees (placed at their
 * stems, the plot's species hint kept, origin the plot's). */
sy_code sy_batch_expand(const sy_batch_inputs *in, const char *out_dir, const sy_batch_options *o, int segment_now,
                        sy_batch_inputs *out, sy_error *err);

/* The options as the record stores them: a canonical text of everything
 * that changes a tree's outputs (caller frees), and its hash. */
char *sy_batch_options_text(const sy_batch_options *o, const sy_batch_input *in);
uint64_t sy_batch_hash(const void *data, size_t size);

/* Creates out_dir and its trees/ and logs/ folders. */
sy_code sy_batch_prepare_dir(const char *out_dir, sy_error *err);

/* Removes the temp files (".tmp.<pid>-<host tag>.*") that this host's processes no longer running
 * left in out_dir and its folders: what a kill mid-write leaves. */
void sy_batch_sweep(const char *out_dir);

/* The worker pool: runs child(ctx, j) for j in [0, n_jobs) in forked
 * processes, nw at once (child must _exit), and done(ctx, j, wait status,
 * timed_out, interrupted, seconds) in the parent as each ends; workers
 * running past timeout seconds (0: none) are killed. A stop signal
 * (SIGINT, SIGTERM, SIGHUP; not one set to be ignored, as under nohup)
 * starts no more workers, is passed to those running (a second one kills
 * them), and once they are reaped this process dies of it. A worker that did
 * not finish is `interrupted` (its job neither done nor failed) when a stop
 * signal ended it (1) or the batch is stopping (2). Fails only for the pool
 * itself. */
sy_code sy_batch_pool(size_t n_jobs, int nw, double timeout, void (*child)(void *ctx, size_t job),
                      void (*done)(void *ctx, size_t job, int status, int timed_out, int interrupted, double seconds),
                      void *ctx, sy_error *err);
/* What the tree pool and the plot pool both hand their workers: job j runs
 * in->items[todo[j]] (its input's hash in hash[todo[j]]) into out_dir with
 * o, on `threads` threads, and dies with `parent`. */
typedef struct {
    const sy_batch_inputs *in;
    const char *out_dir;
    const sy_batch_options *o;
    const size_t *todo;
    const uint64_t *hash;
    int threads;
    pid_t parent;
} sy_batch_jobs;
/* In a forked worker: dies with the parent, stdout to /dev/null, stderr to
 * out_dir/logs/ID.log, the memory cap, threads, quiet progress. */
void sy_batch_worker_setup(const char *out_dir, const char *id, int threads, double mem_gb, pid_t parent);
/* A stop asked of the whole batch: Ctrl-C (the terminal signals the process
 * group), scancel (Slurm signals every process of the step), a hang-up. */
int sy_batch_stop_signal(int sig);
/* Dies of sig as with its default action (unblocked, even if blocked);
 * never returns. */
_Noreturn void sy_batch_die_of(int sig);
/* One line saying how a worker ended (a wait status). */
void sy_batch_death(int status, int timed_out, double timeout, char *why, size_t size);

/* ---- the worker side (batch_tree.c) ---- */

/* Makes one tree's outputs in out_dir/trees and commits them with the
 * record last; a failure is committed as a record with status "failed".
 * Runs in the forked worker. Returns the tree's status code. */
sy_code sy_batch_tree(const sy_batch_input *in, const char *out_dir, const sy_batch_options *o, sy_error *err);

/* Writes a failed record for a tree whose worker died (signal, timeout). */
sy_code sy_batch_record_failure(const sy_batch_input *in, const char *out_dir, const sy_batch_options *o,
                                uint64_t input_hash, const char *error, double seconds, sy_error *err);

/* ---- Slurm (batch_slurm.c) ---- */

typedef struct {
    const char *partition; /* NULL: the cluster's default */
    const char *time;      /* "HH:MM:SS" per task (NULL: the partition's) */
    const char *mem;       /* per task, sbatch syntax ("4G"; NULL: the partition's) */
    int array_size;        /* tasks (0: min(trees, 100)) */
    int cpus;              /* cpus per task (0: 1; workers inside a task follow SLURM_CPUS_PER_TASK) */
    const char *sbatch;    /* the sbatch executable (NULL: sbatch on PATH) */
    int no_submit;         /* 1: write the script only */
} sy_slurm_options;

sy_slurm_options sy_slurm_options_default(void);
/* SY_EUSAGE naming the field: negative array_size or cpus, or a line break
 * in partition, time or mem (each becomes one #SBATCH line of the script). */
sy_code sy_slurm_options_check(const sy_slurm_options *o, sy_error *err);

/* Writes out_dir/slurm/batch.sbatch (a job array whose task k runs
 * `sylva batch ARGS --slurm-task k --slurm-tasks N`, argv being this
 * command's own arguments minus the Slurm ones) and submits it with sbatch
 * (job id into job_id). The last task to finish merges the report. */
sy_code sy_slurm_submit(const sy_batch_inputs *in, const char *out_dir, const char *sylva_exe, int argc,
                        char **argv, const sy_slurm_options *so, char *job_id, size_t job_id_size, sy_error *err);

/* After a task: marks it done and, when every task of this submission is,
 * merges the report (the last task). */
sy_code sy_slurm_task_done(const sy_batch_inputs *in, const char *out_dir, const sy_batch_options *o,
                           sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
