/* Whitespace tokens over bytes that are not NUL-terminated (a file in
 * memory): what the text parts of the PCD and COLMAP readers share (their
 * lines come from stages/core/lines.h). Every function stays inside
 * [start, end) and never reads a terminator. */
#ifndef SYLVA_TEXT_SCAN_H
#define SYLVA_TEXT_SCAN_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/lines.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    const char *s;
    size_t n;
} sy_tok;

/* Next token of [*p, e) separated by spaces, tabs or CR; 0 when none is left. */
int sy_tok_next(const char **p, const char *e, sy_tok *t);
size_t sy_tok_count(const char *p, const char *e);
int sy_tok_is(const sy_tok *t, const char *word);
/* Whole-token conversions; 0 on any stray character or overflow. */
int sy_tok_u64(const sy_tok *t, uint64_t *v);
int sy_tok_i64(const sy_tok *t, int64_t *v);
int sy_tok_double(const sy_tok *t, double *v);
/* printf precision that shows at most 32 characters of a token in messages. */
int sy_tok_shown(const sy_tok *t);


#ifdef __cplusplus
}
#endif

#endif
