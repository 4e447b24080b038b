#include "textnum.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>

/* Powers of ten that are exact in double: a significand below 2^53 times or
 * divided by one of them is rounded once, hence correctly (Clinger's fast path). */
static const double exact_pow10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                       1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                       1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

static int is_digit(char c)
{
    return (unsigned)(c - '0') < 10u;
}

static char lower(char c)
{
    return (c >= 'A' && c <= 'Z') ? (char)(c - 'A' + 'a') : c;
}

/* Case-insensitive match of word at p; returns the end of the match or NULL. */
static const char *match_word(const char *p, const char *end, const char *word)
{
    for (; *word; word++, p++)
        if (p >= end || lower(*p) != *word) return NULL;
    return p;
}

static const char *parse_special(const char *p, const char *end, int neg, double *out)
{
    const char *q;
    if ((q = match_word(p, end, "nan"))) {
        *out = neg ? -NAN : NAN;
        return q;
    }
    if ((q = match_word(p, end, "inf"))) {
        const char *longer = match_word(q, end, "inity");
        *out = neg ? -INFINITY : INFINITY;
        return longer ? longer : q;
    }
    return NULL;
}

/* mant * 10^e outside the fast path (more than 2^53 or a large exponent):
 * long double keeps the 64-bit significand and the scale exact enough that
 * the final rounding to double dominates. Rare in scan data. */
static double scale_pow10(uint64_t mant, int e)
{
    long double m = (long double)mant;
    return (double)(e >= 0 ? m * powl(10.0L, (long double)e) : m / powl(10.0L, (long double)-e));
}

const char *sy_parse_number(const char *p, const char *end, double *out)
{
    int neg = 0;
    if (p < end && (*p == '-' || *p == '+')) {
        neg = *p == '-';
        p++;
    }
    uint64_t mant = 0;
    int sig = 0, exp10 = 0, any = 0;
    /* Up to 19 significant digits fit in 64 bits; later ones only shift the
     * exponent (integer part) or are dropped (fraction). */
    for (; p < end && is_digit(*p); p++, any = 1) {
        if (sig < 19) {
            mant = mant * 10 + (uint64_t)(*p - '0');
            sig += mant != 0;
        } else {
            exp10++;
        }
    }
    if (p < end && *p == '.') {
        for (p++; p < end && is_digit(*p); p++, any = 1) {
            if (sig < 19) {
                mant = mant * 10 + (uint64_t)(*p - '0');
                sig += mant != 0;
                exp10--;
            }
        }
    }
    if (!any) return parse_special(p, end, neg, out);
    if (p < end && (*p == 'e' || *p == 'E')) {
        const char *q = p + 1;
        int eneg = 0, e = 0;
        if (q < end && (*q == '-' || *q == '+')) {
            eneg = *q == '-';
            q++;
        }
        if (q < end && is_digit(*q)) {
            for (; q < end && is_digit(*q); q++)
                if (e < 100000) e = e * 10 + (*q - '0');
            exp10 += eneg ? -e : e;
            p = q;
        }
    }
    double v;
    if (mant == 0) v = 0.0;
    else if (mant <= (1ull << 53) && exp10 >= -22 && exp10 <= 22)
        v = exp10 >= 0 ? (double)mant * exact_pow10[exp10] : (double)mant / exact_pow10[-exp10];
    else v = scale_pow10(mant, exp10);
    *out = neg ? -v : v;
    return p;
}
