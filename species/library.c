/* The species library's manifest: locating the folder, reading library.tsv
 * strictly (every field checked, one line per message), and looking species
 * up by name or stable id. */
/* realpath() is XSI. */
#define _XOPEN_SOURCE 700

#include "species/library.h"

#include <ctype.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "species/species.h"
#include "stages/core/fileio.h"
#include "stages/core/array.h"
#include "stages/core/lines.h"

#ifndef SYLVA_LIBRARY_INSTALL_DIR
#define SYLVA_LIBRARY_INSTALL_DIR "/usr/local/share/sylva/species"
#endif

const char *sy_species_kind_name(sy_species_kind kind)
{
    switch (kind) {
    case SY_SPECIES_BROADLEAF: return "broadleaf";
    case SY_SPECIES_CONIFER: return "conifer";
    case SY_SPECIES_PALM: return "palm";
    }
    return "unknown";
}

sy_code sy_species_init(sy_species *s, size_t n_classes, sy_error *err)
{
    memset(s, 0, sizeof *s);
    s->id = -1;
    if (n_classes == 0) return SY_OK;
    s->probabilities = sy_calloc(n_classes, sizeof *s->probabilities, err, "species probabilities");
    if (!s->probabilities) return SY_EINTERNAL;
    s->n_classes = n_classes;
    return SY_OK;
}

void sy_species_free(sy_species *s)
{
    free(s->probabilities);
    s->probabilities = NULL;
    s->n_classes = 0;
}

/* 1 and the canonical path in out when dir holds a regular library.tsv. */
static int holds_manifest(const char *dir, char *out, size_t size)
{
    char manifest[4096 + 16];
    struct stat st;
    if (snprintf(manifest, sizeof manifest, "%s/library.tsv", dir) >= (int)sizeof manifest) return 0;
    if (stat(manifest, &st) != 0 || !S_ISREG(st.st_mode)) return 0;
    char canon[PATH_MAX];
    if (!realpath(dir, canon) || strlen(canon) >= size) return 0;
    memcpy(out, canon, strlen(canon) + 1);
    return 1;
}

sy_code sy_library_locate(char *dir, size_t size, sy_error *err)
{
    char exe[PATH_MAX];
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (len > 0) {
        exe[len] = '\0';
        char *slash = strrchr(exe, '/');
        if (slash) *slash = '\0';
        static const char *const beside[] = {"species", "../species", "../share/sylva/species"};
        for (size_t i = 0; i < sizeof beside / sizeof beside[0]; i++) {
            char cand[PATH_MAX + 32];
            snprintf(cand, sizeof cand, "%s/%s", exe, beside[i]);
            if (holds_manifest(cand, dir, size)) return SY_OK;
        }
    }
    if (holds_manifest(SYLVA_LIBRARY_INSTALL_DIR, dir, size)) return SY_OK;
    const char *env = getenv("SYLVA_LIBRARY");
    if (env && *env && holds_manifest(env, dir, size)) return SY_OK;
    return sy_fail(err, SY_EINPUT,
                   "species library: no library.tsv beside the executable, in %s or in $SYLVA_LIBRARY (%s)",
                   SYLVA_LIBRARY_INSTALL_DIR, env && *env ? env : "unset");
}

void sy_library_free(sy_library *lib)
{
    for (size_t i = 0; i < lib->n; i++) {
        sy_library_entry *e = &lib->entries[i];
        free(e->name);
        free(e->scientific_name);
        for (size_t f = 0; f < e->n_files; f++) free(e->files[f]);
        free(e->files);
    }
    free(lib->entries);
    lib->entries = NULL;
    lib->n = 0;
}

static int valid_name(const char *s)
{
    if (!*s) return 0;
    for (; *s; s++)
        if (!(islower((unsigned char)*s) || isdigit((unsigned char)*s) || *s == '_' || *s == '-')) return 0;
    return 1;
}

/* A file of the library: relative, no "..", printable, no blanks. */
static int valid_file(const char *s)
{
    if (!*s || *s == '/') return 0;
    for (const char *p = s; *p; p++)
        if ((unsigned char)*p <= ' ' || *p == 0x7f) return 0;
    for (const char *p = s; (p = strstr(p, "..")); p += 2)
        if ((p == s || p[-1] == '/') && (p[2] == '/' || p[2] == '\0')) return 0;
    return 1;
}

/* Splits line at tabs (in place) into field[0..max); returns the field
 * count, which may exceed max (the extra fields are not stored). */
static int split_tabs(char *line, char **field, int max)
{
    int n = 1;
    field[0] = line;
    for (char *p = line; *p; p++)
        if (*p == '\t') {
            *p = '\0';
            if (n < max) field[n] = p + 1;
            n++;
        }
    return n;
}

static sy_code parse_entry(const char *path, size_t line_no, char *line, sy_library_entry *e, sy_error *err)
{
    char *f[5];
    int n = split_tabs(line, f, 5);
    if (n != 5)
        return sy_fail(err, SY_EINPUT, "%s:%zu: expected 5 tab-separated fields (id, name, scientific_name, kind, files), got %d",
                       path, line_no, n);
    char *end;
    long id = strtol(f[0], &end, 10);
    if (end == f[0] || *end || id < 0 || id > 65534 || !isdigit((unsigned char)f[0][0]))
        return sy_fail(err, SY_EINPUT, "%s:%zu: id '%s' is not a whole number in 0..65534", path, line_no, f[0]);
    if (!valid_name(f[1]))
        return sy_fail(err, SY_EINPUT, "%s:%zu: name '%s' must be lower-case letters, digits, '_' or '-'", path,
                       line_no, f[1]);
    if (!*f[2]) return sy_fail(err, SY_EINPUT, "%s:%zu: empty scientific name", path, line_no);
    int kind = -1;
    for (int k = 0; k < 3; k++)
        if (strcmp(f[3], sy_species_kind_name((sy_species_kind)k)) == 0) kind = k;
    if (kind < 0)
        return sy_fail(err, SY_EINPUT, "%s:%zu: kind '%s' is not broadleaf, conifer or palm", path, line_no, f[3]);
    size_t n_files = 1;
    for (const char *p = f[4]; *p; p++) n_files += *p == ',';
    e->id = (int)id;
    e->kind = (sy_species_kind)kind;
    e->name = strdup(f[1]);
    e->scientific_name = strdup(f[2]);
    e->files = calloc(n_files, sizeof *e->files);
    if (!e->name || !e->scientific_name || !e->files) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    char *save = NULL;
    for (char *tok = strtok_r(f[4], ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        if (!valid_file(tok))
            return sy_fail(err, SY_EINPUT, "%s:%zu: file '%s' must be a path inside the library folder", path,
                           line_no, tok);
        if (!(e->files[e->n_files++] = strdup(tok))) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    }
    if (e->n_files != n_files)
        return sy_fail(err, SY_EINPUT, "%s:%zu: empty entry in the file list '%s'", path, line_no, f[4]);
    size_t l0 = strlen(e->files[0]);
    if (l0 < 5 || strcmp(e->files[0] + l0 - 4, ".ini") != 0)
        return sy_fail(err, SY_EINPUT, "%s:%zu: the first file '%s' must be the parameter .ini", path, line_no,
                       e->files[0]);
    return SY_OK;
}

sy_code sy_library_parse(const char *path, const char *dir, const char *text, size_t size, sy_library *lib,
                         sy_error *err)
{
    memset(lib, 0, sizeof *lib);
    snprintf(lib->dir, sizeof lib->dir, "%s", dir ? dir : "");
    size_t cap = 0;
    sy_lines L;
    sy_lines_init(&L, text, size);
    const char *p, *pe;
    sy_code rc = SY_OK;
    while (!rc && sy_lines_next(&L, &p, &pe)) {
        size_t len = (size_t)(pe - p), line_no = L.line;
        if (memchr(p, '\0', len)) {
            rc = sy_fail(err, SY_EINPUT, "%s:%zu: NUL byte", path, line_no);
            break;
        }
        if (len == 0 || p[0] == '#') continue;
        if ((rc = sy_array_reserve(&lib->entries, &cap, lib->n + 1, sizeof *lib->entries, 16, err, path))) break;
        char *line = strndup(p, len);
        if (!line) {
            rc = sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
            break;
        }
        sy_library_entry *e = &lib->entries[lib->n++];
        memset(e, 0, sizeof *e);
        rc = parse_entry(path, line_no, line, e, err);
        free(line);
        for (size_t i = 0; !rc && i + 1 < lib->n; i++) {
            if (lib->entries[i].id == e->id)
                rc = sy_fail(err, SY_EINPUT, "%s:%zu: id %d is already taken by %s", path, line_no, e->id,
                             lib->entries[i].name);
            else if (strcmp(lib->entries[i].name, e->name) == 0)
                rc = sy_fail(err, SY_EINPUT, "%s:%zu: species '%s' is listed twice", path, line_no, e->name);
        }
    }
    if (!rc && lib->n == 0) rc = sy_fail(err, SY_EINPUT, "%s: lists no species", path);
    if (rc) sy_library_free(lib);
    return rc;
}

sy_code sy_library_load(const char *dir, sy_library *lib, sy_error *err)
{
    char found[4096];
    memset(lib, 0, sizeof *lib);
    if (!dir) {
        sy_code rc = sy_library_locate(found, sizeof found, err);
        if (rc) return rc;
        dir = found;
    }
    char path[4096 + 16];
    snprintf(path, sizeof path, "%s/library.tsv", dir);
    sy_buffer buf;
    sy_code rc = sy_read_file(path, &buf, err);
    if (rc) return rc;
    rc = sy_library_parse(path, dir, (const char *)buf.data, buf.size, lib, err);
    sy_buffer_free(&buf);
    return rc;
}

const sy_library_entry *sy_library_find(const sy_library *lib, const char *name)
{
    for (size_t i = 0; name && i < lib->n; i++)
        if (strcmp(lib->entries[i].name, name) == 0) return &lib->entries[i];
    return NULL;
}

const sy_library_entry *sy_library_by_id(const sy_library *lib, int id)
{
    for (size_t i = 0; i < lib->n; i++)
        if (lib->entries[i].id == id) return &lib->entries[i];
    return NULL;
}

int sy_library_id(const char *name)
{
    sy_library lib;
    if (sy_library_load(NULL, &lib, NULL)) return -1;
    const sy_library_entry *e = sy_library_find(&lib, name);
    int id = e ? e->id : -1;
    sy_library_free(&lib);
    return id;
}

sy_code sy_library_params(const sy_library *lib, const sy_library_entry *e, sy_species_params *sp, sy_error *err)
{
    char path[8192];
    snprintf(path, sizeof path, "%s/%s", lib->dir, e->files[0]);
    return sy_species_params_load(path, sp, err);
}

void sy_library_entry_json(const sy_library_entry *e, sy_json *j)
{
    sy_json_object(j, NULL);
    sy_json_int(j, "id", e->id);
    sy_json_string(j, "name", e->name);
    sy_json_string(j, "scientific_name", e->scientific_name);
    sy_json_string(j, "kind", sy_species_kind_name(e->kind));
    sy_json_array(j, "files");
    for (size_t f = 0; f < e->n_files; f++) sy_json_string(j, NULL, e->files[f]);
    sy_json_end(j);
    /* The species' leaf material from `sylva leaf` (docs/leafmaps.md), or null. */
    const char *lm = sy_library_entry_leaf_maps(e);
    if (lm) sy_json_string(j, "leaf_maps", lm);
    else sy_json_null(j, "leaf_maps");
    sy_json_end(j);
}

const char *sy_library_entry_leaf_maps(const sy_library_entry *e)
{
    static const char tail[] = "leaf.material";
    for (size_t f = 1; f < e->n_files; f++) {
        size_t n = strlen(e->files[f]), t = sizeof tail - 1;
        if (n >= t && strcmp(e->files[f] + n - t, tail) == 0 && (n == t || e->files[f][n - t - 1] == '/'))
            return e->files[f];
    }
    return NULL;
}

sy_code sy_library_add_file(const char *dir, const char *name, const char *rel, sy_error *err)
{
    char path[4200];
    snprintf(path, sizeof path, "%.4096s/library.tsv", dir);
    sy_buffer buf;
    sy_code rc = sy_read_file(path, &buf, err);
    if (rc) return rc;
    const char *text = (const char *)buf.data;
    size_t n = buf.size, rl = strlen(rel);
    char *out = malloc(n + rl + 2);
    if (!out) {
        sy_buffer_free(&buf);
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    }
    size_t o = 0, pos = 0;
    int found = 0;
    while (pos < n) {
        size_t end = pos;
        while (end < n && text[end] != '\n') end++;
        size_t len = end - pos;
        /* Fields: id, name, scientific name, kind, files. */
        const char *line = text + pos, *f[5] = {0};
        size_t nf = 0;
        if (len && line[0] != '#') {
            f[nf++] = line;
            for (size_t k = 0; k < len && nf < 5; k++)
                if (line[k] == '\t') f[nf++] = line + k + 1;
        }
        size_t name_len = nf >= 3 ? (size_t)(f[2] - f[1] - 1) : 0;
        int match = nf == 5 && name_len == strlen(name) && memcmp(f[1], name, name_len) == 0;
        memcpy(out + o, line, len);
        o += len;
        if (match) {
            found = 1;
            /* Already listed? Compare each comma-separated file. */
            const char *files = f[4], *stop = line + len;
            while (stop > files && (stop[-1] == '\r' || stop[-1] == ' ')) stop--;
            int listed = 0;
            for (const char *s = files; s < stop;) {
                const char *c = s;
                while (c < stop && *c != ',') c++;
                if ((size_t)(c - s) == rl && memcmp(s, rel, rl) == 0) listed = 1;
                s = c + 1;
            }
            if (!listed) {
                size_t keep = (size_t)(stop - line), tail = len - keep;
                memmove(out + o - tail + rl + 1, out + o - tail, tail);
                out[o - tail] = ',';
                memcpy(out + o - tail + 1, rel, rl);
                o += rl + 1;
            }
        }
        if (end < n) out[o++] = '\n';
        pos = end + 1;
    }
    sy_buffer_free(&buf);
    if (!found) {
        free(out);
        return sy_fail(err, SY_EINPUT, "%s: species '%s' is not in the library", path, name);
    }
    rc = sy_write_file_atomic(path, out, o, err);
    free(out);
    return rc;
}
