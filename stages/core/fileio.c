#include "fileio.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

int sy_is_directory(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

sy_code sy_read_file(const char *path, sy_buffer *buf, sy_error *err)
{
    buf->data = NULL;
    buf->size = 0;
    struct stat st;
    if (stat(path, &st) != 0)
        return sy_fail(err, SY_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    if (S_ISDIR(st.st_mode)) return sy_fail(err, SY_EINPUT, "%s: is a directory, not a file", path);
    /* Pipes are fine; a device such as /dev/zero would be read until memory runs out. */
    if (!S_ISREG(st.st_mode) && !S_ISFIFO(st.st_mode))
        return sy_fail(err, SY_EINPUT, "%s: not a regular file", path);
    FILE *fp = fopen(path, "rb");
    if (!fp) return sy_fail(err, SY_EINPUT, "%s: cannot open: %s", path, strerror(errno));
    /* Read by growing chunks: st_size is a hint (pipes and /proc report 0). */
    size_t cap = st.st_size > 0 ? (size_t)st.st_size + 1 : 1 << 16, len = 0;
    unsigned char *data = malloc(cap + 1);
    if (!data) {
        fclose(fp);
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory reading %zu bytes", path, cap);
    }
    for (;;) {
        size_t got = fread(data + len, 1, cap - len, fp);
        len += got;
        if (got == 0) break;
        if (len == cap) {
            unsigned char *grown = realloc(data, cap * 2 + 1);
            if (!grown) {
                free(data);
                fclose(fp);
                return sy_fail(err, SY_EINTERNAL, "%s: out of memory reading", path);
            }
            data = grown;
            cap *= 2;
        }
    }
    int bad = ferror(fp);
    fclose(fp);
    if (bad) {
        free(data);
        return sy_fail(err, SY_EINPUT, "%s: read error", path);
    }
    data[len] = 0;
    buf->data = data;
    buf->size = len;
    return SY_OK;
}

void sy_buffer_free(sy_buffer *buf)
{
    free(buf->data);
    buf->data = NULL;
    buf->size = 0;
}

const char *sy_extension(const char *path, char *buf, size_t size)
{
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(slash ? slash : path, '.');
    size_t i = 0;
    if (dot && dot[1])
        for (dot++; *dot && i + 1 < size; dot++) buf[i++] = (char)tolower((unsigned char)*dot);
    buf[i] = '\0';
    return buf;
}

/* ------------------------------------------------------------ the output rule */

static int same_file(const struct stat *a, const struct stat *b)
{
    return a->st_dev == b->st_dev && a->st_ino == b->st_ino;
}

/* 1 when the regular file st is already open as this process's fd. */
static int is_our_fd(const struct stat *st, int fd)
{
    struct stat o;
    return fstat(fd, &o) == 0 && same_file(st, &o);
}

sy_code sy_output_resolve(const char *path, sy_output_target *t, sy_error *err)
{
    memset(t, 0, sizeof *t);
    if (strcmp(path, "-") == 0) {
        strcpy(t->path, "-");
        t->direct = t->is_stdout = 1;
        return SY_OK;
    }
    if (!*path) return sy_fail(err, SY_EUSAGE, "empty output path");
    if (strlen(path) >= sizeof t->path) return sy_fail(err, SY_EUSAGE, "%.64s...: path too long", path);
    struct stat st;
    if (stat(path, &st) == 0) { /* follows links */
        if (S_ISDIR(st.st_mode)) return sy_fail(err, SY_EINPUT, "%s: is a directory, not a file", path);
        if (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) {
            strcpy(t->path, path);
            t->direct = 1;
            return SY_OK;
        }
        if (!S_ISREG(st.st_mode))
            return sy_fail(err, SY_EINPUT, "%s: is a block device or socket; refusing to write to it", path);
        /* /dev/stdout redirected to a file: replacing that file would detach it
         * from the shell's redirection; write through standard output. */
        if (is_our_fd(&st, STDOUT_FILENO) || is_our_fd(&st, STDERR_FILENO)) {
            strcpy(t->path, path);
            t->direct = 1;
            t->is_stdout = is_our_fd(&st, STDOUT_FILENO) ? 1 : 2;
            return SY_OK;
        }
    } else if (errno != ENOENT)
        return sy_fail(err, SY_EINPUT, "%s: cannot write: %s", path, strerror(errno));
    /* Follow links by hand to the final target's name (it may not exist yet):
     * the temp file goes beside the target and the rename replaces it, so the
     * link stays a link. */
    char cur[4096], link[4096];
    strcpy(cur, path);
    for (int hop = 0;; hop++) {
        struct stat ls;
        if (lstat(cur, &ls) != 0 || !S_ISLNK(ls.st_mode)) break;
        if (hop == 40) return sy_fail(err, SY_EINPUT, "%s: too many levels of symbolic links", path);
        ssize_t k = readlink(cur, link, sizeof link - 1);
        if (k < 0) return sy_fail(err, SY_EINPUT, "%s: cannot read link: %s", path, strerror(errno));
        link[k] = '\0';
        const char *slash = strrchr(cur, '/');
        if (link[0] == '/' || !slash) {
            memcpy(cur, link, (size_t)k + 1);
        } else {
            size_t dirlen = (size_t)(slash - cur + 1);
            if (dirlen + (size_t)k >= sizeof cur) return sy_fail(err, SY_EUSAGE, "%s: link target path too long", path);
            memcpy(cur + dirlen, link, (size_t)k + 1);
        }
    }
    strcpy(t->path, cur);
    return SY_OK;
}

/* The name part of a temp name: the target's name, or when the whole would
 * pass NAME_MAX, an 8-digit hash of it, '~' and its tail (the extension
 * survives, and writers choose formats by extension). Independent of the pid
 * (room is kept for 10 digits), so stale temps of any pid match. */
static int temp_part(const char *target, char *part, size_t size, size_t *dirlen)
{
    const char *slash = strrchr(target, '/');
    *dirlen = slash ? (size_t)(slash - target + 1) : 0;
    const char *name = target + *dirlen;
    if (!*name) return -1;
    char dir[4096];
    snprintf(dir, sizeof dir, "%.*s", *dirlen ? (int)*dirlen : 1, *dirlen ? target : ".");
    long name_max = pathconf(dir, _PC_NAME_MAX);
    if (name_max <= 0 || name_max > 4096) name_max = 255;
    const size_t prefix = 25; /* ".tmp." + 10 digits + "-" + 8 (host tag) + "." */
    if ((size_t)name_max <= prefix + 16) return -1;
    size_t budget = (size_t)name_max - prefix, len = strlen(name);
    if (len <= budget) return snprintf(part, size, "%s", name) < (int)size ? 0 : -1;
    uint32_t h = 2166136261u; /* FNV-1a */
    for (const char *c = name; *c; c++) h = (h ^ (unsigned char)*c) * 16777619u;
    const char *tail = name + len - (budget - 9);
    while (*tail && ((unsigned char)*tail & 0xC0) == 0x80) tail++; /* not inside a UTF-8 sequence */
    return snprintf(part, size, "%08x~%s", (unsigned)h, tail) < (int)size ? 0 : -1;
}

void sy_host_tag(char tag[9])
{
    char host[256] = "";
    if (gethostname(host, sizeof host) != 0) host[0] = 0;
    host[sizeof host - 1] = 0;
    uint32_t h = 2166136261u; /* FNV-1a */
    for (const char *c = host; *c; c++) h = (h ^ (unsigned char)*c) * 16777619u;
    snprintf(tag, 9, "%08x", (unsigned)h);
}

int sy_temp_owner(const char *s, long *pid, int *here, const char **rest)
{
    long v = 0;
    int digits = 0;
    while (*s >= '0' && *s <= '9' && digits < 10) v = v * 10 + (*s++ - '0'), digits++;
    if (!digits || v <= 0) return 0;
    *pid = v;
    *here = 1;
    if (*s == '-') {
        char mine[9];
        sy_host_tag(mine);
        for (int i = 0; i < 8; i++)
            if (!isxdigit((unsigned char)s[1 + i])) return 0;
        *here = strncmp(s + 1, mine, 8) == 0;
        s += 9;
    }
    if (*s != '.') return 0;
    if (rest) *rest = s + 1;
    return 1;
}

int sy_output_temp_name(const char *target, long pid, char *buf, size_t size)
{
    char part[4096], tag[9];
    size_t dirlen;
    if (temp_part(target, part, sizeof part, &dirlen)) return -1;
    sy_host_tag(tag);
    int k = snprintf(buf, size, "%.*s.tmp.%ld-%s.%s", (int)dirlen, target, pid, tag, part);
    return k > 0 && (size_t)k < size ? 0 : -1;
}

int sy_process_gone(long pid)
{
    if (pid <= 0) return 0;
    if (kill((pid_t)pid, 0) != 0) return errno == ESRCH;
    /* kill() still finds a process that was killed and has not been reaped
     * yet: a zombie (an orphan waits for init, which may reap late), one
     * whose memory is already gone (exiting: no Vm lines in its status), or
     * one with SIGKILL pending. None of them writes again. */
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%ld/status", pid);
    FILE *fp = fopen(path, "r");
    if (!fp) return 0; /* no /proc: trust kill() */
    int gone = 0, has_mm = 0;
    while (!gone && fgets(line, sizeof line, fp)) {
        if (!strncmp(line, "State:", 6)) {
            const char *c = line + 6;
            while (*c == ' ' || *c == '\t') c++;
            gone = *c == 'Z' || *c == 'X';
        } else if (!strncmp(line, "VmSize:", 7)) has_mm = 1;
        else if (!strncmp(line, "SigPnd:", 7) || !strncmp(line, "ShdPnd:", 7)) {
            unsigned long long mask = strtoull(line + 7, NULL, 16);
            gone = (mask >> (SIGKILL - 1)) & 1;
        }
    }
    fclose(fp);
    return gone || !has_mm;
}

/* 1 when name is ".tmp.<owner>.<part>"; *pid and *here from the owner. */
static int temp_match(const char *name, const char *part, long *pid, int *here)
{
    const char *rest;
    return strncmp(name, ".tmp.", 5) == 0 && sy_temp_owner(name + 5, pid, here, &rest) && strcmp(rest, part) == 0;
}

size_t sy_output_remove_stale(const char *target)
{
    char part[4096], dir[4096], victim[8192];
    size_t dirlen, removed = 0;
    if (temp_part(target, part, sizeof part, &dirlen)) return 0;
    snprintf(dir, sizeof dir, "%.*s", dirlen ? (int)dirlen : 1, dirlen ? target : ".");
    DIR *d = opendir(dir);
    if (!d) return 0;
    long self = (long)getpid();
    for (struct dirent *e; (e = readdir(d));) {
        long pid;
        int here;
        if (!temp_match(e->d_name, part, &pid, &here) || !here || pid == self) continue;
        /* Only a process that no longer runs leaves its temp for good; one of
         * another host (a Slurm node on the same folder) is not judged here. */
        if (!sy_process_gone(pid)) continue;
        snprintf(victim, sizeof victim, "%s%s%s", dir, dirlen ? "" : "/", e->d_name);
        if (unlink(victim) == 0) removed++;
    }
    closedir(d);
    return removed;
}

/* 1 when path's name is one of this process's temp names (a staged output):
 * already private, so written straight through. */
static int is_own_temp(const char *path)
{
    const char *slash = strrchr(path, '/');
    const char *name = slash ? slash + 1 : path;
    char prefix[48], tag[9];
    sy_host_tag(tag);
    int k = snprintf(prefix, sizeof prefix, ".tmp.%ld-%s.", (long)getpid(), tag);
    return strncmp(name, prefix, (size_t)k) == 0 && name[k];
}

/* A new file for writing, refusing to follow a link planted at its name; a
 * leftover of the same name (an earlier process with this pid) is replaced. */
static FILE *create_exclusive(const char *path)
{
    int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0 && errno == EEXIST && unlink(path) == 0) fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) return NULL;
    FILE *fp = fdopen(fd, "wb");
    if (!fp) close(fd);
    return fp;
}

sy_code sy_atomic_open(sy_atomic_file *f, const char *path, sy_error *err)
{
    memset(f, 0, sizeof *f);
    sy_output_target t;
    sy_code rc = sy_output_resolve(path, &t, err);
    if (rc) return rc;
    snprintf(f->shown, sizeof f->shown, "%s", path);
    strcpy(f->final_path, t.path);
    f->direct = t.direct;
    if (t.is_stdout) {
        f->is_stdout = t.is_stdout;
        f->fp = t.is_stdout == 2 ? stderr : stdout;
        return SY_OK;
    }
    if (t.direct) {
        f->fp = fopen(t.path, "wb");
        if (!f->fp) return sy_fail(err, SY_EINPUT, "%s: cannot write: %s", path, strerror(errno));
        return SY_OK;
    }
    if (is_own_temp(t.path)) {
        f->direct = 1;
        strcpy(f->tmp_path, t.path); /* removed on abort */
        f->fp = create_exclusive(t.path);
        if (!f->fp) return sy_fail(err, SY_EINPUT, "%s: cannot write: %s", path, strerror(errno));
        return SY_OK;
    }
    sy_output_remove_stale(t.path);
    if (sy_output_temp_name(t.path, (long)getpid(), f->tmp_path, sizeof f->tmp_path))
        return sy_fail(err, SY_EINPUT, "%s: cannot form a temp name beside it", path);
    f->fp = create_exclusive(f->tmp_path);
    if (!f->fp) return sy_fail(err, SY_EINPUT, "%s: cannot write: %s", path, strerror(errno));
    /* Replacing a file keeps its permission bits. */
    struct stat st;
    if (stat(t.path, &st) == 0 && S_ISREG(st.st_mode)) (void)fchmod(fileno(f->fp), st.st_mode & 07777);
    return SY_OK;
}

sy_code sy_atomic_commit(sy_atomic_file *f, sy_error *err)
{
    if (!f->fp) return sy_fail(err, SY_EINTERNAL, "%s: not open", f->shown);
    if (f->is_stdout) {
        int bad = fflush(f->fp) | ferror(f->fp);
        f->fp = NULL;
        return bad ? sy_fail(err, SY_EINPUT, "%s: write failed", f->shown) : SY_OK;
    }
    int bad = ferror(f->fp) | fflush(f->fp);
    bad |= fclose(f->fp);
    f->fp = NULL;
    if (bad) {
        if (f->tmp_path[0]) remove(f->tmp_path);
        return sy_fail(err, SY_EINPUT, "%s: write failed (disk full?)", f->shown);
    }
    if (f->direct) return SY_OK;
    if (rename(f->tmp_path, f->final_path) != 0) {
        int e = errno;
        remove(f->tmp_path);
        return sy_fail(err, SY_EINPUT, "%s: cannot rename into place: %s", f->shown, strerror(e));
    }
    return SY_OK;
}

void sy_atomic_abort(sy_atomic_file *f)
{
    if (!f->fp) return;
    if (f->is_stdout) {
        fflush(f->fp); /* what went out is out */
        f->fp = NULL;
        return;
    }
    fclose(f->fp);
    f->fp = NULL;
    if (f->tmp_path[0]) remove(f->tmp_path);
}

sy_code sy_output_check(const char *path, const char *const *inputs, size_t n_inputs, sy_error *err)
{
    sy_output_target t;
    sy_code rc = sy_output_resolve(path, &t, err);
    if (rc) return rc;
    struct stat out;
    if (!t.is_stdout && stat(t.path, &out) == 0)
        for (size_t i = 0; i < n_inputs; i++) {
            struct stat in;
            if (inputs[i] && stat(inputs[i], &in) == 0 && same_file(&in, &out))
                return sy_fail(err, SY_EINPUT, "%s: is the input %s itself; refusing to overwrite it", path,
                               inputs[i]);
        }
    if (t.is_stdout) return SY_OK;
    if (t.direct) return access(t.path, W_OK) == 0 ? SY_OK
                                                   : sy_fail(err, SY_EINPUT, "%s: cannot write: %s", path, strerror(errno));
    sy_atomic_file f;
    rc = sy_atomic_open(&f, path, err);
    if (rc == SY_OK) sy_atomic_abort(&f);
    return rc;
}

sy_code sy_check_writable(const char *path, sy_error *err)
{
    return sy_output_check(path, NULL, 0, err);
}

sy_code sy_write_file_atomic(const char *path, const void *data, size_t size, sy_error *err)
{
    sy_atomic_file f;
    sy_code rc = sy_atomic_open(&f, path, err);
    if (rc) return rc;
    if (size && fwrite(data, 1, size, f.fp) != size) {
        sy_atomic_abort(&f);
        return sy_fail(err, SY_EINPUT, "%s: write failed", path);
    }
    return sy_atomic_commit(&f, err);
}

/* ------------------------------------------------------------ paired outputs */

sy_code sy_stage_output(sy_staged_output *s, const char *path, sy_error *err)
{
    memset(s, 0, sizeof *s);
    sy_output_target t;
    sy_code rc = sy_output_resolve(path, &t, err);
    if (rc) return rc;
    snprintf(s->shown, sizeof s->shown, "%s", path);
    strcpy(s->final_path, t.path);
    if (t.direct) {
        s->direct = 1;
        strcpy(s->staged, path);
        return SY_OK;
    }
    sy_output_remove_stale(t.path);
    if (sy_output_temp_name(t.path, (long)getpid(), s->staged, sizeof s->staged))
        return sy_fail(err, SY_EINPUT, "%s: cannot form a temp name beside it", path);
    unlink(s->staged); /* an earlier process with this pid */
    return SY_OK;
}

void sy_stage_abort(sy_staged_output *s, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!s[i].direct && s[i].staged[0]) unlink(s[i].staged);
}

sy_code sy_stage_commit(sy_staged_output *s, size_t n, sy_error *err)
{
    if (n == 0) return SY_OK;
    /* The manifest goes first, so no old one ever stands beside new outputs. */
    sy_staged_output *manifest = &s[n - 1];
    if (!manifest->direct && unlink(manifest->final_path) != 0 && errno != ENOENT) {
        int e = errno;
        sy_stage_abort(s, n);
        return sy_fail(err, SY_EINPUT, "%s: cannot replace: %s", manifest->shown, strerror(e));
    }
    for (size_t i = 0; i < n; i++) {
        if (s[i].direct) continue;
        if (rename(s[i].staged, s[i].final_path) != 0) {
            int e = errno;
            sy_stage_abort(s + i, n - i);
            return sy_fail(err, SY_EINPUT, "%s: cannot rename into place: %s", s[i].shown, strerror(e));
        }
        s[i].staged[0] = '\0';
    }
    return SY_OK;
}

/* ---- Folder outputs ---- */

/* Removes a folder of regular files; 0, or -1 when it holds anything else. */
static int remove_flat_folder(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return errno == ENOENT ? 0 : -1;
    struct dirent *e;
    char path[8192];
    int rc = 0;
    while ((e = readdir(d)) != NULL) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        struct stat st;
        if (lstat(path, &st) != 0 || !S_ISREG(st.st_mode) || unlink(path) != 0) rc = -1;
    }
    closedir(d);
    if (rc == 0 && rmdir(dir) != 0) rc = -1;
    return rc;
}

/* 1 when dir may be replaced: empty, or holding manifest and regular files only. */
static int replaceable_folder(const char *dir, const char *manifest)
{
    DIR *d = opendir(dir);
    if (!d) return 0;
    struct dirent *e;
    char path[8192];
    int entries = 0, has_manifest = 0, only_files = 1;
    while ((e = readdir(d)) != NULL) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        entries++;
        if (manifest && !strcmp(e->d_name, manifest)) has_manifest = 1;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        struct stat st;
        if (lstat(path, &st) != 0 || !S_ISREG(st.st_mode)) only_files = 0;
    }
    closedir(d);
    return entries == 0 || (has_manifest && only_files);
}

/* target as its folder ("." when none) and its last name, trailing slashes dropped. */
static int split_target(const char *target, char *dir, size_t dsize, char *name, size_t nsize)
{
    size_t len = strlen(target);
    while (len > 1 && target[len - 1] == '/') len--;
    size_t cut = len;
    while (cut > 0 && target[cut - 1] != '/') cut--;
    if (len == cut || len - cut >= nsize || cut >= dsize) return -1;
    memcpy(name, target + cut, len - cut);
    name[len - cut] = 0;
    if (cut == 0) snprintf(dir, dsize, ".");
    else if (cut == 1) snprintf(dir, dsize, "/");
    else {
        memcpy(dir, target, cut - 1);
        dir[cut - 1] = 0;
    }
    return 0;
}

/* "<dir>/.<tag>.<pid>-<host tag>.<name>" */
static int folder_sibling(const char *target, const char *tag, long pid, char *buf, size_t size)
{
    char dir[4096], name[256], host[9];
    if (split_target(target, dir, sizeof dir, name, sizeof name)) return -1;
    sy_host_tag(host);
    int n = snprintf(buf, size, "%s/.%s.%ld-%s.%s", dir, tag, pid, host, name);
    return n > 0 && (size_t)n < size ? 0 : -1;
}

/* Temp and aside folders of this target left by processes that are gone. */
static void sweep_folder_siblings(const char *target)
{
    char dir[4096], name[256];
    if (split_target(target, dir, sizeof dir, name, sizeof name)) return;
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        static const char *tags[2] = {".tmp.", ".old."};
        for (int t = 0; t < 2; t++) {
            size_t tl = strlen(tags[t]);
            if (strncmp(e->d_name, tags[t], tl) != 0) continue;
            long pid;
            int here;
            const char *rest;
            if (!sy_temp_owner(e->d_name + tl, &pid, &here, &rest) || strcmp(rest, name) != 0) continue;
            if (!here || !sy_process_gone(pid)) continue;
            char path[8600];
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            if (sy_is_directory(path)) remove_flat_folder(path);
        }
    }
    closedir(d);
}

sy_code sy_dir_output_begin(const char *target, const char *manifest, char *tmp, size_t size, sy_error *err)
{
    struct stat st;
    if (lstat(target, &st) == 0) {
        if (!S_ISDIR(st.st_mode)) return sy_fail(err, SY_EINPUT, "%s: exists and is not a folder", target);
        if (!replaceable_folder(target, manifest))
            return sy_fail(err, SY_EINPUT, "%s: folder is not empty and was not written by this command (no %s)", target,
                           manifest ? manifest : "manifest");
    }
    if (folder_sibling(target, "tmp", (long)getpid(), tmp, size))
        return sy_fail(err, SY_EINPUT, "%s: path too long", target);
    sweep_folder_siblings(target);
    remove_flat_folder(tmp);
    if (mkdir(tmp, 0777) != 0) return sy_fail(err, SY_EINPUT, "%s: cannot create a folder beside it: %s", target, strerror(errno));
    return SY_OK;
}

sy_code sy_dir_output_commit(const char *target, const char *tmp, sy_error *err)
{
    char old[4200];
    if (folder_sibling(target, "old", (long)getpid(), old, sizeof old)) {
        sy_dir_output_abort(tmp);
        return sy_fail(err, SY_EINPUT, "%s: path too long", target);
    }
    int had = sy_is_directory(target);
    if (had && rename(target, old) != 0) {
        int e = errno;
        sy_dir_output_abort(tmp);
        return sy_fail(err, SY_EINPUT, "%s: cannot replace: %s", target, strerror(e));
    }
    if (rename(tmp, target) != 0) {
        int e = errno;
        if (had) rename(old, target);
        sy_dir_output_abort(tmp);
        return sy_fail(err, SY_EINPUT, "%s: cannot create: %s", target, strerror(e));
    }
    if (had) remove_flat_folder(old);
    return SY_OK;
}

void sy_dir_output_abort(const char *tmp) { remove_flat_folder(tmp); }
