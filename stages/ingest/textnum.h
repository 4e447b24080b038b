/* Fast decimal number parsing for the text readers (XYZ and ASCII PLY).
 * strtod needs a NUL-terminated string and honours the locale; the readers
 * work on bounded buffers (fuzz inputs are not terminated) and parse millions
 * of numbers, so they use this instead. */
#ifndef SYLVA_TEXTNUM_H
#define SYLVA_TEXTNUM_H

#ifdef __cplusplus
extern "C" {
#endif

/* Parses a number at [p, end): optional sign, digits with an optional '.',
 * optional exponent (e/E, sign, digits); also "nan", "inf" and "infinity"
 * (any case) so callers can report non-finite values as such. Returns the
 * first character after the number, or NULL when no number starts at p. It
 * does not look at what follows: callers check for a delimiter.
 * Results are correctly rounded when the significand has at most 16 digits
 * and the decimal exponent is within 1e±22 (all real scan data), and within
 * a couple of double ulps otherwise. */
const char *sy_parse_number(const char *p, const char *end, double *out);

#ifdef __cplusplus
}
#endif

#endif
