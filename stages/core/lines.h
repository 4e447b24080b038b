/* Lines over bytes in memory that are not NUL-terminated (a file read
 * whole): the one line reader of every text format the project reads (XYZ,
 * PCD and COLMAP text, the skeleton and TreeQSM formats, the species library
 * and parameter files, the classifier's model, label and species CSVs). A line
 * ends at '\n'; a '\r' just before it (CRLF files) is not part of the line.
 * Nothing is copied and nothing past [data, data + size) is ever read. */
#ifndef SYLVA_CORE_LINES_H
#define SYLVA_CORE_LINES_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    const char *p, *end; /* unread input */
    size_t line;         /* 1-based number of the line last returned */
} sy_lines;

void sy_lines_init(sy_lines *L, const void *data, size_t size);
/* Next line [*b, *e) without its end of line; 0 at the end of the data. */
int sy_lines_next(sy_lines *L, const char **b, const char **e);
/* Bytes consumed so far (the offset of the next line). */
size_t sy_lines_offset(const sy_lines *L, const void *data);
/* Trims ASCII blanks (space, tab) on both sides of [*b, *e). */
void sy_trim(const char **b, const char **e);

#ifdef __cplusplus
}
#endif

#endif
