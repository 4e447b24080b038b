#include "text_scan.h"
#include "textnum.h"

#include <stdlib.h>
#include <string.h>

static int is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

int sy_tok_next(const char **p, const char *e, sy_tok *t)
{
    const char *s = *p;
    while (s < e && is_space(*s)) s++;
    if (s == e) {
        *p = s;
        return 0;
    }
    t->s = s;
    while (s < e && !is_space(*s)) s++;
    t->n = (size_t)(s - t->s);
    *p = s;
    return 1;
}

size_t sy_tok_count(const char *p, const char *e)
{
    sy_tok t;
    size_t n = 0;
    while (sy_tok_next(&p, e, &t)) n++;
    return n;
}

int sy_tok_is(const sy_tok *t, const char *word)
{
    return t->n == strlen(word) && memcmp(t->s, word, t->n) == 0;
}

int sy_tok_u64(const sy_tok *t, uint64_t *v)
{
    if (t->n == 0 || t->n > 20) return 0;
    uint64_t x = 0;
    for (size_t i = 0; i < t->n; i++) {
        if (t->s[i] < '0' || t->s[i] > '9') return 0;
        unsigned d = (unsigned)(t->s[i] - '0');
        if (x > (UINT64_MAX - d) / 10) return 0;
        x = x * 10 + d;
    }
    *v = x;
    return 1;
}

int sy_tok_i64(const sy_tok *t, int64_t *v)
{
    int neg = t->n > 0 && t->s[0] == '-';
    sy_tok digits = {t->s + neg, t->n - (size_t)neg};
    uint64_t u;
    if (!sy_tok_u64(&digits, &u) || u > (uint64_t)INT64_MAX + (uint64_t)neg) return 0;
    *v = neg ? (int64_t)(0 - u) : (int64_t)u;
    return 1;
}

int sy_tok_double(const sy_tok *t, double *v)
{
    /* The same locale-independent parser as the XYZ and PLY readers. */
    const char *end = t->n ? sy_parse_number(t->s, t->s + t->n, v) : NULL;
    return end == t->s + t->n;
}

int sy_tok_shown(const sy_tok *t) { return (int)(t->n < 32 ? t->n : 32); }
