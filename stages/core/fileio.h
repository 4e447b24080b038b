/* File plumbing shared by readers and writers: whole-file reads that reject
 * directories and unreadable paths with a one-line message, and the one rule
 * every output follows (temp file in the target's directory, renamed on
 * success, so no partial output ever survives; devices and links never
 * replaced; outputs never the same file as an input). */
#ifndef SYLVA_FILEIO_H
#define SYLVA_FILEIO_H

#include <stdio.h>

#include "status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    unsigned char *data; /* NUL-terminated for convenience (data[size] == 0) */
    size_t size;
} sy_buffer;

/* Reads the whole regular file (or pipe). Fails with SY_EINPUT naming path for
 * missing, unreadable, directory or device paths. Empty files read fine (size 0). */
sy_code sy_read_file(const char *path, sy_buffer *buf, sy_error *err);
void sy_buffer_free(sy_buffer *buf);

/* 1 if path exists and is a directory. */
int sy_is_directory(const char *path);

/* Lower-case extension without the dot ("las"), or "" if none. */
const char *sy_extension(const char *path, char *buf, size_t size);

/* ---- The output rule: every file Sylva writes goes through it ----
 *
 * An output path is resolved once, before anything is written:
 * - "-" is standard output, written straight through;
 * - a symlink is followed to its final target, which is replaced; the link
 *   itself is never replaced (a dangling link gets its target created);
 * - a character device or FIFO (also behind a link: /dev/null, /dev/stdout)
 *   is written straight through, never renamed over, and so is a regular file
 *   that already is this process's stdout or stderr (/dev/stdout redirected);
 * - a directory, block device or socket is refused (SY_EINPUT);
 * - anything else (a regular file, or nothing yet) is written to a temp name
 *   in the target's directory, ".tmp.<pid>-<host tag>.<name>" (the name's head shortened
 *   to a hash so the whole stays within NAME_MAX, the extension kept), and
 *   renamed over the target when complete. Temp names of this pattern left
 *   by processes of this host that no longer run are removed on the way. */

typedef struct {
    char path[4096]; /* where the bytes go: the path, or its links' final target */
    int direct;      /* 1: written straight through (see above) */
    int is_stdout;   /* "-" */
} sy_output_target;

/* Resolves path as above; SY_EINPUT naming path when it must be refused. */
sy_code sy_output_resolve(const char *path, sy_output_target *t, sy_error *err);

/* Fails fast, before long work, when path could not or must not be written:
 * refused by the rule above, its directory missing or not writable, or the
 * same file (device and inode) as one of the n_inputs inputs (NULL entries
 * skipped). Leaves nothing behind. */
sy_code sy_output_check(const char *path, const char *const *inputs, size_t n_inputs, sy_error *err);

/* The temp name the rule uses for target in its directory, for process pid:
 * "<dir>/.tmp.<pid>-<host tag>.<name>", within NAME_MAX. 0, or -1 when it
 * cannot fit. */
int sy_output_temp_name(const char *target, long pid, char *buf, size_t size);

/* This host's tag in temp names: 8 hex digits of a hash of its name. A pid
 * names a process on one host only; batches on several Slurm nodes share
 * their output folder, and a node must not take another's live writer for
 * a process that is gone. */
void sy_host_tag(char tag[9]);

/* Parses a temp name's owner field at s, "<pid>-<host tag>." (or "<pid>."
 * of earlier versions, taken as this host's): *pid, *here (1: this host)
 * and *rest (may be NULL) after the '.'. 0 when s is no owner field. */
int sy_temp_owner(const char *s, long *pid, int *here, const char **rest);

/* 1 when process pid no longer runs and will never write again: it does
 * not exist, or it is a zombie, exiting, or has SIGKILL pending (a killed
 * batch's workers linger so until they are reaped). The owner test for
 * ".tmp.<pid>." names. */
int sy_process_gone(long pid);

/* Removes "<dir>/.tmp.<pid>-<host tag>.<name>" files of target whose pid, on
 * this host, no longer runs; returns how many went. */
size_t sy_output_remove_stale(const char *target);

typedef struct {
    FILE *fp;
    int direct;
    int is_stdout;
    char final_path[4096]; /* the resolved target */
    char tmp_path[4096 + 32];
    char shown[4096];      /* the path as given, for messages */
} sy_atomic_file;

/* Opens path for writing under the output rule. */
sy_code sy_atomic_open(sy_atomic_file *f, const char *path, sy_error *err);
/* Flushes, closes and renames over the final path (direct outputs: flushes);
 * removes the temp on failure. */
sy_code sy_atomic_commit(sy_atomic_file *f, sy_error *err);
/* Closes and removes the temp file. Safe to call twice. */
void sy_atomic_abort(sy_atomic_file *f);

/* sy_output_check without inputs. */
sy_code sy_check_writable(const char *path, sy_error *err);

/* Writes size bytes to path atomically. */
sy_code sy_write_file_atomic(const char *path, const void *data, size_t size, sy_error *err);

/* ---- Outputs that belong together (a cloud and its truth, a glb and its
 * .sylva): each is written in full to its staged name (any writer may write
 * it: a path that is this process's temp name is written straight through),
 * then all are renamed together, the last one - the manifest - removed
 * before the first rename and renamed last. A kill at any moment leaves the
 * old set, or a set without its manifest (incomplete, so rerun), never a
 * manifest beside outputs of another run. */
typedef struct {
    char shown[4096];        /* the path as given */
    char final_path[4096];   /* the resolved target */
    char staged[4096 + 32];  /* what the writer writes: the temp name, or the path itself when direct */
    int direct;
} sy_staged_output;

sy_code sy_stage_output(sy_staged_output *s, const char *path, sy_error *err);
/* Commits s[0..n) as described; on failure removes what is still staged. */
sy_code sy_stage_commit(sy_staged_output *s, size_t n, sy_error *err);
/* Removes the staged files. */
void sy_stage_abort(sy_staged_output *s, size_t n);

/* ---- Folder outputs (one file per tree): the folder is written in full
 * under a temp name beside it, "<dir>/.tmp.<pid>.<name>", then swapped in.
 * A folder already at the target is replaced only when it is empty or holds
 * `manifest` (the file the command writes into every folder it makes) and
 * nothing but regular files, so a mistyped -o never empties an unrelated
 * folder; a kill at any moment leaves the old folder or the new one, never a
 * mix (at worst a temp or ".old" folder beside it, swept by the next run). */

/* Checks the target and creates the temp folder; its path goes to tmp. */
sy_code sy_dir_output_begin(const char *target, const char *manifest, char *tmp, size_t size, sy_error *err);
/* Swaps the finished temp folder in (the old one renamed aside, then removed). */
sy_code sy_dir_output_commit(const char *target, const char *tmp, sy_error *err);
/* Removes the temp folder and its files. */
void sy_dir_output_abort(const char *tmp);

#ifdef __cplusplus
}
#endif

#endif
