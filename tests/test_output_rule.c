/* The output rule (stages/core/fileio.h): temp names within NAME_MAX, stale
 * temps of dead processes removed, links and devices never replaced, an
 * output never the same file as an input, paired outputs committed together. */
#include "testutil.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "stages/core/fileio.h"

/* A fresh directory of its own per test. */
static const char *fresh_dir(const char *name)
{
    static char dir[4096];
    snprintf(dir, sizeof dir, "%s", tmp_path(name));
    mkdir(dir, 0755);
    assert_int_equal(dir_entry_count(dir), 0);
    return dir;
}

/* The file's size, or -1 when it is missing. */
static long long file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (long long)st.st_size : -1;
}

/* A pid that certainly ran and ended: a child we waited for. */
static long dead_pid(void)
{
    pid_t p = fork();
    if (p == 0) _exit(0);
    assert_true(p > 0);
    int status;
    waitpid(p, &status, 0);
    return (long)p;
}

static void long_names_fit_name_max(void **state)
{
    (void)state;
    const char *dir = fresh_dir("long");
    char name[251], path[4400], tmp[4400];
    memset(name, 'a', 246);
    memcpy(name + 246, ".glb", 5); /* 250 bytes: legal, but ".NAME.tmp.PID" would not be */
    snprintf(path, sizeof path, "%s/%s", dir, name);
    assert_int_equal(sy_output_temp_name(path, 4194304, tmp, sizeof tmp), 0);
    const char *base = strrchr(tmp, '/') + 1;
    assert_true(strlen(base) <= NAME_MAX);
    char ext[16];
    assert_string_equal(sy_extension(tmp, ext, sizeof ext), "glb"); /* writers choose formats by it */
    sy_error err = {0};
    assert_int_equal(sy_write_file_atomic(path, "glTF", 4, &err), SY_OK);
    assert_int_equal(file_size(path), 4);
    assert_int_equal(dir_entry_count(dir), 1);
    /* Short names keep their whole name after the prefix. */
    snprintf(path, sizeof path, "%s/tree.las", dir);
    assert_int_equal(sy_output_temp_name(path, 42, tmp, sizeof tmp), 0);
    char tag[9], want[64];
    sy_host_tag(tag);
    snprintf(want, sizeof want, ".tmp.42-%s.tree.las", tag);
    assert_string_equal(strrchr(tmp, '/') + 1, want);
}

static void stale_temps_of_dead_processes_go(void **state)
{
    (void)state;
    const char *dir = fresh_dir("stale");
    char path[4400], dead[4400], live[4400], other[4400];
    snprintf(path, sizeof path, "%s/out.ply", dir);
    assert_int_equal(sy_output_temp_name(path, dead_pid(), dead, sizeof dead), 0);
    assert_int_equal(sy_output_temp_name(path, (long)getppid(), live, sizeof live), 0);
    snprintf(other, sizeof other, "%s/.tmp.%ld.other.ply", dir, dead_pid());
    assert_int_equal(write_bytes(dead, "x", 1), 0);
    assert_int_equal(write_bytes(live, "x", 1), 0);
    assert_int_equal(write_bytes(other, "x", 1), 0);
    sy_error err = {0};
    assert_int_equal(sy_write_file_atomic(path, "ply\n", 4, &err), SY_OK);
    assert_false(file_exists(dead));  /* its process is gone: a kill's leftover */
    assert_true(file_exists(live));   /* a running process may still finish it */
    assert_true(file_exists(other));  /* another output's temp is not ours to judge */
    assert_int_equal(dir_entry_count(dir), 3);
}

/* A Slurm array writes into one folder from several nodes, and a pid names
 * a process on its own host only: another host's temp of a pid that does not
 * run here stays (its node may be writing it); this host's, and one of the
 * earlier tagless form, go. */
static void temps_of_other_hosts_stay(void **state)
{
    (void)state;
    const char *dir = fresh_dir("hosts");
    char path[4400], mine[4400], theirs[4400], legacy[4400], tag[9];
    snprintf(path, sizeof path, "%s/tree.glb", dir);
    long dead = dead_pid();
    sy_host_tag(tag);
    assert_int_equal(sy_output_temp_name(path, dead, mine, sizeof mine), 0);
    const char *other_tag = strcmp(tag, "0badc0de") ? "0badc0de" : "0badc0df";
    snprintf(theirs, sizeof theirs, "%s/.tmp.%ld-%s.tree.glb", dir, dead, other_tag);
    snprintf(legacy, sizeof legacy, "%s/.tmp.%ld.tree.glb", dir, dead);
    long pid;
    int here;
    const char *rest;
    assert_true(sy_temp_owner(strrchr(mine, '/') + 6, &pid, &here, &rest) && pid == dead && here);
    assert_string_equal(rest, "tree.glb");
    assert_true(sy_temp_owner(strrchr(theirs, '/') + 6, &pid, &here, &rest) && pid == dead && !here);
    assert_true(sy_temp_owner(strrchr(legacy, '/') + 6, &pid, &here, &rest) && pid == dead && here);
    assert_false(sy_temp_owner("12-xyz.tree.glb", &pid, &here, &rest));
    assert_false(sy_temp_owner("-1.tree.glb", &pid, &here, &rest));
    assert_int_equal(write_bytes(mine, "x", 1), 0);
    assert_int_equal(write_bytes(theirs, "x", 1), 0);
    assert_int_equal(write_bytes(legacy, "x", 1), 0);
    assert_int_equal(sy_output_remove_stale(path), 2);
    assert_false(file_exists(mine));
    assert_false(file_exists(legacy));
    assert_true(file_exists(theirs));
}

/* A killed writer that nobody has reaped yet (an orphan waits for init)
 * still answers kill(pid, 0): its temps are leftovers all the same, while a
 * live writer's stay. (A batch killed and resumed at once met this.) */
static void temps_of_unreaped_killed_writers_go(void **state)
{
    (void)state;
    const char *dir = fresh_dir("zombie");
    pid_t z = fork();
    if (z == 0) _exit(0);
    pid_t live = fork();
    if (live == 0) {
        pause();
        _exit(0);
    }
    assert_true(z > 0 && live > 0);
    /* Wait until z is a zombie (exited, not reaped). */
    siginfo_t si;
    memset(&si, 0, sizeof si);
    assert_int_equal(waitid(P_PID, (id_t)z, &si, WEXITED | WNOWAIT), 0);
    assert_int_equal(kill(z, 0), 0); /* still there for kill() */
    assert_true(sy_process_gone((long)z));
    assert_false(sy_process_gone((long)live));
    assert_false(sy_process_gone((long)getpid()));
    char path[4400], tz[4400], tl[4400];
    snprintf(path, sizeof path, "%s/tree.glb", dir);
    assert_int_equal(sy_output_temp_name(path, (long)z, tz, sizeof tz), 0);
    assert_int_equal(sy_output_temp_name(path, (long)live, tl, sizeof tl), 0);
    assert_int_equal(write_bytes(tz, "x", 1), 0);
    assert_int_equal(write_bytes(tl, "x", 1), 0);
    assert_int_equal(sy_output_remove_stale(path), 1);
    assert_false(file_exists(tz));
    assert_true(file_exists(tl));
    kill(live, SIGKILL);
    int status;
    waitpid(live, &status, 0);
    waitpid(z, &status, 0);
}

static void links_stay_links(void **state)
{
    (void)state;
    const char *dir = fresh_dir("links");
    char target[4400], link[4400], dangling[4400], missing[4400];
    snprintf(target, sizeof target, "%s/real.bin", dir);
    snprintf(link, sizeof link, "%s/link.bin", dir);
    snprintf(dangling, sizeof dangling, "%s/dangling.bin", dir);
    snprintf(missing, sizeof missing, "%s/made.bin", dir);
    assert_int_equal(write_bytes(target, "old", 3), 0);
    assert_int_equal(symlink("real.bin", link), 0);
    struct stat st;
    assert_int_equal(lstat(link, &st), 0);
    assert_true(S_ISLNK(st.st_mode));
    sy_error err = {0};
    assert_int_equal(sy_write_file_atomic(link, "newer", 5, &err), SY_OK);
    assert_int_equal(lstat(link, &st), 0);
    assert_true(S_ISLNK(st.st_mode)); /* the link was written through, not replaced */
    assert_int_equal(file_size(target), 5);
    /* A dangling link gets its target made. */
    assert_int_equal(symlink("made.bin", dangling), 0);
    assert_int_equal(sy_write_file_atomic(dangling, "ab", 2, &err), SY_OK);
    assert_int_equal(lstat(dangling, &st), 0);
    assert_true(S_ISLNK(st.st_mode));
    assert_int_equal(file_size(missing), 2);
    assert_int_equal(dir_entry_count(dir), 4);
}

static void devices_are_written_through(void **state)
{
    (void)state;
    sy_error err = {0};
    sy_output_target t;
    assert_int_equal(sy_output_resolve("/dev/null", &t, &err), SY_OK);
    assert_true(t.direct);
    assert_int_equal(sy_write_file_atomic("/dev/null", "bytes", 5, &err), SY_OK);
    struct stat st;
    assert_int_equal(stat("/dev/null", &st), 0);
    assert_true(S_ISCHR(st.st_mode)); /* still the device */
    assert_int_equal(sy_output_check("/dev/null", NULL, 0, &err), SY_OK);
    /* A FIFO: the bytes arrive at the reader. */
    const char *dir = fresh_dir("fifo");
    char fifo[4400];
    snprintf(fifo, sizeof fifo, "%s/pipe", dir);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    int rd = open(fifo, O_RDONLY | O_NONBLOCK);
    assert_true(rd >= 0);
    assert_int_equal(sy_write_file_atomic(fifo, "through", 7, &err), SY_OK);
    char got[16] = {0};
    assert_int_equal(read(rd, got, sizeof got), 7);
    assert_string_equal(got, "through");
    close(rd);
    assert_int_equal(stat(fifo, &st), 0);
    assert_true(S_ISFIFO(st.st_mode));
    assert_int_equal(dir_entry_count(dir), 1);
    /* "-" is standard output. */
    assert_int_equal(sy_output_resolve("-", &t, &err), SY_OK);
    assert_true(t.is_stdout);
    /* A directory is refused, naming it. */
    assert_int_equal(sy_output_check(dir, NULL, 0, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, dir));
    assert_non_null(strstr(err.msg, "directory"));
}

static void output_is_never_an_input(void **state)
{
    (void)state;
    const char *dir = fresh_dir("same");
    char in[4400], hard[4400], via_link[4400], other[4400];
    snprintf(in, sizeof in, "%s/raw.xyz", dir);
    snprintf(hard, sizeof hard, "%s/hard.xyz", dir);
    snprintf(via_link, sizeof via_link, "%s/soft.xyz", dir);
    snprintf(other, sizeof other, "%s/out.xyz", dir);
    assert_int_equal(write_bytes(in, "1 2 3\n", 6), 0);
    assert_int_equal(link(in, hard), 0);
    assert_int_equal(symlink(in, via_link), 0);
    const char *inputs[2] = {NULL, in};
    sy_error err = {0};
    const char *same[3] = {in, hard, via_link};
    for (int i = 0; i < 3; i++) {
        assert_int_equal(sy_output_check(same[i], inputs, 2, &err), SY_EINPUT);
        assert_non_null(strstr(err.msg, same[i]));
        assert_non_null(strstr(err.msg, "input"));
    }
    assert_int_equal(sy_output_check(other, inputs, 2, &err), SY_OK);
    assert_false(file_exists(other)); /* the check leaves nothing */
    assert_int_equal(file_size(in), 6);
    assert_int_equal(dir_entry_count(dir), 3);
}

static void pairs_commit_together(void **state)
{
    (void)state;
    const char *dir = fresh_dir("pair");
    char a[4400], m[4400];
    snprintf(a, sizeof a, "%s/cloud.las", dir);
    snprintf(m, sizeof m, "%s/truth.json", dir);
    assert_int_equal(write_bytes(a, "old-cloud", 9), 0);
    assert_int_equal(write_bytes(m, "old-truth", 9), 0);
    sy_staged_output s[2];
    sy_error err = {0};
    assert_int_equal(sy_stage_output(&s[0], a, &err), SY_OK);
    assert_int_equal(sy_stage_output(&s[1], m, &err), SY_OK);
    char ext[16];
    assert_string_equal(sy_extension(s[0].staged, ext, sizeof ext), "las");
    /* Any writer writes a staged name straight through: no third name. */
    assert_int_equal(sy_write_file_atomic(s[0].staged, "new-cloud!", 10, &err), SY_OK);
    assert_int_equal(sy_write_file_atomic(s[1].staged, "new-truth!", 10, &err), SY_OK);
    assert_int_equal(dir_entry_count(dir), 4);
    assert_int_equal(file_size(a), 9); /* nothing visible changed yet */
    assert_int_equal(sy_stage_commit(s, 2, &err), SY_OK);
    assert_int_equal(file_size(a), 10);
    assert_int_equal(file_size(m), 10);
    assert_int_equal(dir_entry_count(dir), 2);
    /* Abandoned: nothing staged survives, the committed pair stands. */
    assert_int_equal(sy_stage_output(&s[0], a, &err), SY_OK);
    assert_int_equal(sy_stage_output(&s[1], m, &err), SY_OK);
    assert_int_equal(write_bytes(s[0].staged, "x", 1), 0);
    sy_stage_abort(s, 2);
    assert_int_equal(dir_entry_count(dir), 2);
    /* A rename that fails part-way leaves no manifest beside a new cloud. */
    assert_int_equal(sy_stage_output(&s[0], a, &err), SY_OK);
    assert_int_equal(sy_stage_output(&s[1], m, &err), SY_OK);
    assert_int_equal(write_bytes(s[1].staged, "t", 1), 0); /* the cloud was never written */
    assert_int_equal(sy_stage_commit(s, 2, &err), SY_EINPUT);
    assert_false(file_exists(m));
    assert_int_equal(file_size(a), 10);
    assert_int_equal(dir_entry_count(dir), 1);
}

/* A writer killed mid-file leaves only its temp, which the next run removes. */
static void killed_writer_leaves_no_output(void **state)
{
    (void)state;
    const char *dir = fresh_dir("kill");
    char out[4400];
    snprintf(out, sizeof out, "%s/tree.glb", dir);
    int go[2];
    assert_int_equal(pipe(go), 0);
    pid_t p = fork();
    if (p == 0) {
        sy_atomic_file f;
        sy_error err;
        if (sy_atomic_open(&f, out, &err)) _exit(1);
        fputs("half", f.fp);
        fflush(f.fp);
        (void)!write(go[1], "w", 1);
        pause();
        _exit(0);
    }
    char c;
    assert_int_equal(read(go[0], &c, 1), 1);
    kill(p, SIGKILL);
    int status;
    waitpid(p, &status, 0);
    close(go[0]);
    close(go[1]);
    assert_false(file_exists(out));
    assert_int_equal(dir_entry_count(dir), 1); /* the temp */
    sy_error err = {0};
    assert_int_equal(sy_write_file_atomic(out, "whole", 5, &err), SY_OK);
    assert_int_equal(dir_entry_count(dir), 1);
    assert_int_equal(file_size(out), 5);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(long_names_fit_name_max),    cmocka_unit_test(stale_temps_of_dead_processes_go),
        cmocka_unit_test(links_stay_links),           cmocka_unit_test(devices_are_written_through),
        cmocka_unit_test(output_is_never_an_input),   cmocka_unit_test(pairs_commit_together),
        cmocka_unit_test(killed_writer_leaves_no_output), cmocka_unit_test(temps_of_unreaped_killed_writers_go),
        cmocka_unit_test(temps_of_other_hosts_stay),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
