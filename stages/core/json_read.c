#include "json_read.h"

#include <errno.h>
#include <stdio.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"

typedef struct {
    const char *name;
    const unsigned char *s;
    size_t len, pos;
    int line;
    size_t line_start; /* offset of the current line's first byte */
    int max_depth;
    sy_error *err;
    sy_code code; /* set by the first failure */
} parser;

static int column(const parser *p, size_t at) { return (int)(at - p->line_start) + 1; }

static int fail_at(parser *p, size_t at, const char *what)
{
    if (p->code == SY_OK) {
        p->code = SY_EINPUT;
        sy_fail(p->err, SY_EINPUT, "%s:%d:%d: %s", p->name, p->line, column(p, at), what);
    }
    return 0;
}

static int out_of_memory(parser *p)
{
    if (p->code == SY_OK) {
        p->code = SY_EINTERNAL;
        sy_fail(p->err, SY_EINTERNAL, "%s: out of memory parsing JSON", p->name);
    }
    return 0;
}

static void skip_space(parser *p)
{
    while (p->pos < p->len) {
        unsigned char c = p->s[p->pos];
        if (c == '\n') {
            p->pos++;
            p->line++;
            p->line_start = p->pos;
        } else if (c == ' ' || c == '\t' || c == '\r') {
            p->pos++;
        } else {
            break;
        }
    }
}

static int peek(const parser *p) { return p->pos < p->len ? p->s[p->pos] : -1; }

/* A growable byte string for decoding string literals. */
typedef struct {
    char *data;
    size_t len, cap;
} bytes;

static int bytes_put(bytes *b, const void *src, size_t n)
{
    if (b->len + n + 1 > b->cap) {
        size_t cap = b->cap ? b->cap : 32;
        while (cap < b->len + n + 1) cap *= 2;
        char *grown = realloc(b->data, cap);
        if (!grown) return 0;
        b->data = grown;
        b->cap = cap;
    }
    memcpy(b->data + b->len, src, n);
    b->len += n;
    b->data[b->len] = 0;
    return 1;
}

static int put_utf8(bytes *b, uint32_t cp)
{
    unsigned char u[4];
    size_t n;
    if (cp < 0x80) {
        u[0] = (unsigned char)cp;
        n = 1;
    } else if (cp < 0x800) {
        u[0] = (unsigned char)(0xC0 | (cp >> 6));
        u[1] = (unsigned char)(0x80 | (cp & 0x3F));
        n = 2;
    } else if (cp < 0x10000) {
        u[0] = (unsigned char)(0xE0 | (cp >> 12));
        u[1] = (unsigned char)(0x80 | ((cp >> 6) & 0x3F));
        u[2] = (unsigned char)(0x80 | (cp & 0x3F));
        n = 3;
    } else {
        u[0] = (unsigned char)(0xF0 | (cp >> 18));
        u[1] = (unsigned char)(0x80 | ((cp >> 12) & 0x3F));
        u[2] = (unsigned char)(0x80 | ((cp >> 6) & 0x3F));
        u[3] = (unsigned char)(0x80 | (cp & 0x3F));
        n = 4;
    }
    return bytes_put(b, u, n);
}

/* Length of the valid UTF-8 sequence at s[0..avail) (overlongs, surrogates
 * and code points above U+10FFFF rejected), or 0. */
static size_t utf8_length(const unsigned char *s, size_t avail)
{
    unsigned char c = s[0];
    size_t n;
    uint32_t cp, min;
    if (c < 0x80) return 1;
    if ((c & 0xE0) == 0xC0) n = 2, cp = c & 0x1F, min = 0x80;
    else if ((c & 0xF0) == 0xE0) n = 3, cp = c & 0x0F, min = 0x800;
    else if ((c & 0xF8) == 0xF0) n = 4, cp = c & 0x07, min = 0x10000;
    else return 0;
    if (n > avail) return 0;
    for (size_t i = 1; i < n; i++) {
        if ((s[i] & 0xC0) != 0x80) return 0;
        cp = (cp << 6) | (s[i] & 0x3F);
    }
    if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
    return n;
}

static int hex4(parser *p, uint32_t *out)
{
    if (p->len - p->pos < 4) return fail_at(p, p->pos, "truncated \\u escape");
    uint32_t v = 0;
    for (int i = 0; i < 4; i++) {
        unsigned char c = p->s[p->pos + (size_t)i];
        int d = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10 : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
        if (d < 0) return fail_at(p, p->pos + (size_t)i, "invalid hex digit in \\u escape");
        v = v << 4 | (uint32_t)d;
    }
    p->pos += 4;
    *out = v;
    return 1;
}

/* \uXXXX (p->pos just after the 'u'), joining surrogate pairs. */
static int unicode_escape(parser *p, bytes *b)
{
    size_t start = p->pos - 2;
    uint32_t cp;
    if (!hex4(p, &cp)) return 0;
    if (cp >= 0xDC00 && cp <= 0xDFFF) return fail_at(p, start, "unpaired low surrogate in \\u escape");
    if (cp >= 0xD800 && cp <= 0xDBFF) {
        uint32_t lo;
        if (p->len - p->pos < 2 || p->s[p->pos] != '\\' || p->s[p->pos + 1] != 'u')
            return fail_at(p, start, "unpaired high surrogate in \\u escape");
        p->pos += 2;
        if (!hex4(p, &lo)) return 0;
        if (lo < 0xDC00 || lo > 0xDFFF) return fail_at(p, start, "unpaired high surrogate in \\u escape");
        cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
    }
    return put_utf8(b, cp) ? 1 : out_of_memory(p);
}

/* A string literal at p->pos (on the opening quote) into *out / *out_len. */
static int parse_string(parser *p, char **out, size_t *out_len)
{
    size_t start = p->pos++;
    bytes b = {0};
    if (!bytes_put(&b, "", 0)) return out_of_memory(p);
    for (;;) {
        if (p->pos >= p->len) {
            free(b.data);
            return fail_at(p, start, "unterminated string");
        }
        /* Copy the run of plain bytes in one go. */
        size_t run = p->pos;
        while (run < p->len && p->s[run] != '"' && p->s[run] != '\\' && p->s[run] >= 0x20 && p->s[run] < 0x80) run++;
        if (run > p->pos && !bytes_put(&b, p->s + p->pos, run - p->pos)) {
            free(b.data);
            return out_of_memory(p);
        }
        p->pos = run;
        if (p->pos >= p->len) continue;
        unsigned char c = p->s[p->pos];
        int ok = 1;
        if (c == '"') {
            p->pos++;
            *out = b.data;
            *out_len = b.len;
            return 1;
        } else if (c < 0x20) {
            ok = fail_at(p, p->pos, c == '\n' ? "unterminated string (newline inside)" : "control character inside string");
        } else if (c >= 0x80) {
            size_t n = utf8_length(p->s + p->pos, p->len - p->pos);
            if (!n) ok = fail_at(p, p->pos, "invalid UTF-8 in string");
            else if (!bytes_put(&b, p->s + p->pos, n)) ok = out_of_memory(p);
            else p->pos += n;
        } else { /* backslash */
            if (p->pos + 1 >= p->len) {
                ok = fail_at(p, start, "unterminated string");
            } else {
                char e = (char)p->s[p->pos + 1], lit = 0;
                p->pos += 2;
                switch (e) {
                case '"': lit = '"'; break;
                case '\\': lit = '\\'; break;
                case '/': lit = '/'; break;
                case 'b': lit = '\b'; break;
                case 'f': lit = '\f'; break;
                case 'n': lit = '\n'; break;
                case 'r': lit = '\r'; break;
                case 't': lit = '\t'; break;
                case 'u': ok = unicode_escape(p, &b); break;
                default: ok = fail_at(p, p->pos - 2, "invalid escape in string");
                }
                if (ok && e != 'u' && !bytes_put(&b, &lit, 1)) ok = out_of_memory(p);
            }
        }
        if (!ok) {
            free(b.data);
            return 0;
        }
    }
}

static int is_digit(int c) { return c >= '0' && c <= '9'; }

/* Checks the RFC 8259 number grammar, then converts with strtod. */
static int parse_number(parser *p, double *out)
{
    size_t start = p->pos, i = p->pos;
    if (i < p->len && p->s[i] == '-') i++;
    if (i >= p->len || !is_digit(p->s[i])) return fail_at(p, start, "invalid number");
    if (p->s[i] == '0') i++;
    else
        while (i < p->len && is_digit(p->s[i])) i++;
    if (i < p->len && p->s[i] == '.') {
        i++;
        if (i >= p->len || !is_digit(p->s[i])) return fail_at(p, i, "digit expected after '.' in number");
        while (i < p->len && is_digit(p->s[i])) i++;
    }
    if (i < p->len && (p->s[i] == 'e' || p->s[i] == 'E')) {
        i++;
        if (i < p->len && (p->s[i] == '+' || p->s[i] == '-')) i++;
        if (i >= p->len || !is_digit(p->s[i])) return fail_at(p, i, "digit expected in number exponent");
        while (i < p->len && is_digit(p->s[i])) i++;
    }
    char buf[400];
    if (i - start >= sizeof buf) return fail_at(p, start, "number literal too long");
    memcpy(buf, p->s + start, i - start);
    buf[i - start] = 0;
    errno = 0;
    double v = strtod(buf, NULL);
    if (!isfinite(v)) return fail_at(p, start, "number out of range");
    *out = v;
    p->pos = i;
    return 1;
}

static int parse_value(parser *p, sy_jv *v, int depth);
static void free_contents(sy_jv *v);

/* Makes room for one more element (and key). */
static int grow_items(parser *p, sy_jv *v, size_t *cap, int with_keys)
{
    if (v->len < *cap) return 1;
    size_t ncap = *cap ? *cap * 2 : 4;
    sy_jv *items = realloc(v->items, ncap * sizeof *items);
    if (!items) return out_of_memory(p);
    v->items = items;
    if (with_keys) {
        char **keys = realloc(v->keys, ncap * sizeof *keys);
        if (!keys) return out_of_memory(p);
        v->keys = keys;
    }
    *cap = ncap;
    return 1;
}

/* Elements of an array or members of an object; v->len counts the ones
 * completely parsed, so a failure leaves v freeable. */
static int parse_container(parser *p, sy_jv *v, int depth, int is_object)
{
    size_t cap = 0;
    char close = is_object ? '}' : ']';
    const char *what = is_object ? "object" : "array";
    char msg[64];
    v->type = is_object ? SY_JV_OBJECT : SY_JV_ARRAY;
    if (depth >= p->max_depth) return fail_at(p, p->pos, "nesting too deep");
    p->pos++;
    skip_space(p);
    if (peek(p) == close) {
        p->pos++;
        return 1;
    }
    for (;;) {
        if (!grow_items(p, v, &cap, is_object)) return 0;
        char *key = NULL;
        if (is_object) {
            size_t key_len;
            if (peek(p) != '"') return fail_at(p, p->pos, peek(p) < 0 ? "unexpected end of input in object" : "expected a string key in object");
            if (!parse_string(p, &key, &key_len)) return 0;
            skip_space(p);
            if (peek(p) != ':') {
                free(key);
                return fail_at(p, p->pos, "expected ':' after object key");
            }
            p->pos++;
            skip_space(p);
        }
        if (!parse_value(p, &v->items[v->len], depth + 1)) {
            free(key);
            return 0;
        }
        if (is_object) v->keys[v->len] = key;
        v->len++;
        skip_space(p);
        int c = peek(p);
        if (c == ',') {
            p->pos++;
            skip_space(p);
            continue;
        }
        if (c == close) {
            p->pos++;
            return 1;
        }
        if (c < 0) snprintf(msg, sizeof msg, "unexpected end of input in %s", what);
        else snprintf(msg, sizeof msg, "expected ',' or '%c' in %s", close, what);
        return fail_at(p, p->pos, msg);
    }
}

static int match_word(parser *p, const char *word)
{
    size_t n = strlen(word);
    if (p->len - p->pos < n || memcmp(p->s + p->pos, word, n) != 0) return 0;
    p->pos += n;
    return 1;
}

/* Parses one value into *v (zeroed here); on failure v holds nothing. */
static int parse_value(parser *p, sy_jv *v, int depth)
{
    memset(v, 0, sizeof *v);
    v->line = p->line;
    v->col = column(p, p->pos);
    int c = peek(p), ok;
    if (c == '{' || c == '[') {
        ok = parse_container(p, v, depth, c == '{');
    } else if (c == '"') {
        v->type = SY_JV_STRING;
        ok = parse_string(p, &v->str, &v->len);
    } else if (c == '-' || is_digit(c)) {
        v->type = SY_JV_NUMBER;
        ok = parse_number(p, &v->number);
    } else if (match_word(p, "true")) {
        v->type = SY_JV_BOOL;
        v->boolean = 1;
        ok = 1;
    } else if (match_word(p, "false")) {
        v->type = SY_JV_BOOL;
        ok = 1;
    } else if (match_word(p, "null")) {
        ok = 1;
    } else {
        ok = fail_at(p, p->pos, c < 0 ? "unexpected end of input, a value was expected" : "unexpected character, a value was expected");
    }
    if (!ok) {
        free_contents(v);
        memset(v, 0, sizeof *v);
    }
    return ok;
}

static void free_contents(sy_jv *v)
{
    if (v->type == SY_JV_ARRAY || v->type == SY_JV_OBJECT) {
        for (size_t i = 0; i < v->len; i++) {
            free_contents(&v->items[i]);
            if (v->keys) free(v->keys[i]);
        }
    }
    free(v->items);
    free(v->keys);
    free(v->str);
}

void sy_jv_free(sy_jv *v)
{
    if (!v) return;
    free_contents(v);
    free(v);
}

sy_code sy_jv_parse(const char *name, const char *text, size_t len, const sy_jv_limits *limits, sy_jv **out,
                    sy_error *err)
{
    *out = NULL;
    parser p = {name ? name : "JSON", (const unsigned char *)text, len, 0, 1, 0, 256, err, SY_OK};
    size_t max_size = (size_t)1 << 30;
    if (limits && limits->max_depth > 0) p.max_depth = limits->max_depth;
    if (limits && limits->max_size > 0) max_size = limits->max_size;
    if (len > max_size) return sy_fail(err, SY_EINPUT, "%s: JSON input of %zu bytes exceeds the %zu byte limit", p.name, len, max_size);
    /* A UTF-8 byte order mark is tolerated, as many editors write one. */
    if (len >= 3 && memcmp(text, "\xEF\xBB\xBF", 3) == 0) p.pos = p.line_start = 3;
    sy_jv *root = calloc(1, sizeof *root);
    if (!root) return sy_fail(err, SY_EINTERNAL, "%s: out of memory parsing JSON", p.name);
    skip_space(&p);
    if (!parse_value(&p, root, 0)) {
        free(root);
        return p.code;
    }
    skip_space(&p);
    if (p.pos < p.len) {
        fail_at(&p, p.pos, "unexpected data after the JSON value");
        sy_jv_free(root);
        return p.code;
    }
    *out = root;
    return SY_OK;
}

sy_code sy_jv_parse_file(const char *path, sy_jv **out, sy_error *err)
{
    sy_buffer b;
    *out = NULL;
    sy_code rc = sy_read_file(path, &b, err);
    if (rc) return rc;
    rc = sy_jv_parse(path, (const char *)b.data, b.size, NULL, out, err);
    sy_buffer_free(&b);
    return rc;
}

const sy_jv *sy_jv_get(const sy_jv *obj, const char *key)
{
    if (!obj || obj->type != SY_JV_OBJECT || !key) return NULL;
    for (size_t i = 0; i < obj->len; i++)
        if (strcmp(obj->keys[i], key) == 0) return &obj->items[i];
    return NULL;
}

const sy_jv *sy_jv_at(const sy_jv *arr, size_t i)
{
    if (!arr || arr->type != SY_JV_ARRAY || i >= arr->len) return NULL;
    return &arr->items[i];
}

size_t sy_jv_count(const sy_jv *v)
{
    return v && (v->type == SY_JV_ARRAY || v->type == SY_JV_OBJECT) ? v->len : 0;
}

int sy_jv_number(const sy_jv *v, double *out)
{
    if (!v || v->type != SY_JV_NUMBER) return 0;
    *out = v->number;
    return 1;
}

const char *sy_jv_string(const sy_jv *v) { return v && v->type == SY_JV_STRING ? v->str : NULL; }

const char *sy_jv_type_name(sy_jv_type t)
{
    switch (t) {
    case SY_JV_NULL: return "null";
    case SY_JV_BOOL: return "boolean";
    case SY_JV_NUMBER: return "number";
    case SY_JV_STRING: return "string";
    case SY_JV_ARRAY: return "array";
    case SY_JV_OBJECT: return "object";
    }
    return "value";
}
