#include "fileio.h"

#include <ctype.h>
#include <errno.h>
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

sy_code sy_atomic_open(sy_atomic_file *f, const char *path, sy_error *err)
{
    memset(f, 0, sizeof *f);
    if (strlen(path) >= sizeof f->final_path)
        return sy_fail(err, SY_EUSAGE, "%s: path too long", path);
    if (sy_is_directory(path)) return sy_fail(err, SY_EINPUT, "%s: is a directory, not a file", path);
    strcpy(f->final_path, path);
    const char *slash = strrchr(path, '/');
    int dirlen = slash ? (int)(slash - path + 1) : 0;
    snprintf(f->tmp_path, sizeof f->tmp_path, "%.*s.%s.tmp.%ld", dirlen, path,
             slash ? slash + 1 : path, (long)getpid());
    f->fp = fopen(f->tmp_path, "wb");
    if (!f->fp) return sy_fail(err, SY_EINPUT, "%s: cannot write: %s", path, strerror(errno));
    return SY_OK;
}

sy_code sy_atomic_commit(sy_atomic_file *f, sy_error *err)
{
    if (!f->fp) return sy_fail(err, SY_EINTERNAL, "%s: not open", f->final_path);
    int bad = ferror(f->fp) | fflush(f->fp);
    bad |= fclose(f->fp);
    f->fp = NULL;
    if (bad) {
        remove(f->tmp_path);
        return sy_fail(err, SY_EINPUT, "%s: write failed (disk full?)", f->final_path);
    }
    if (rename(f->tmp_path, f->final_path) != 0) {
        int e = errno;
        remove(f->tmp_path);
        return sy_fail(err, SY_EINPUT, "%s: cannot rename into place: %s", f->final_path, strerror(e));
    }
    return SY_OK;
}

void sy_atomic_abort(sy_atomic_file *f)
{
    if (f->fp) {
        fclose(f->fp);
        f->fp = NULL;
        remove(f->tmp_path);
    }
}

sy_code sy_check_writable(const char *path, sy_error *err)
{
    sy_atomic_file f;
    sy_code rc = sy_atomic_open(&f, path, err);
    if (rc == SY_OK) sy_atomic_abort(&f);
    return rc;
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
