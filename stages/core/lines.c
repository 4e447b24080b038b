#include "lines.h"

#include <string.h>

void sy_lines_init(sy_lines *L, const void *data, size_t size)
{
    L->p = (const char *)data;
    L->end = L->p + size;
    L->line = 0;
}

int sy_lines_next(sy_lines *L, const char **b, const char **e)
{
    if (L->p >= L->end) return 0;
    const char *nl = memchr(L->p, '\n', (size_t)(L->end - L->p));
    const char *q = nl ? nl : L->end;
    *b = L->p;
    *e = q > L->p && q[-1] == '\r' ? q - 1 : q;
    L->p = nl ? nl + 1 : L->end;
    L->line++;
    return 1;
}

size_t sy_lines_offset(const sy_lines *L, const void *data) { return (size_t)(L->p - (const char *)data); }

void sy_trim(const char **b, const char **e)
{
    while (*b < *e && (**b == ' ' || **b == '\t')) (*b)++;
    while (*e > *b && ((*e)[-1] == ' ' || (*e)[-1] == '\t')) (*e)--;
}
