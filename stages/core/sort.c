#include "sort.h"

#include <math.h>
#include <stddef.h>
#include <stdint.h>

int sy_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int sy_cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

int sy_cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

int sy_cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* Hoare's FIND (1961) with the median of three and a three-way partition
 * (Dijkstra's Dutch flag), so runs of equal values cost nothing extra. */
double sy_select_double(double *v, size_t n, size_t k)
{
    ptrdiff_t lo = 0, hi = (ptrdiff_t)n - 1, kk = (ptrdiff_t)k;
    while (hi - lo >= 16) {
        double a = v[lo], b = v[lo + (hi - lo) / 2], c = v[hi];
        double pivot = a < b ? (b < c ? b : a < c ? c : a) : (a < c ? a : b < c ? c : b);
        ptrdiff_t lt = lo, i = lo, gt = hi;
        while (i <= gt) {
            double x = v[i];
            if (x < pivot) v[i++] = v[lt], v[lt++] = x;
            else if (x > pivot) v[i] = v[gt], v[gt--] = x;
            else i++;
        }
        if (kk < lt) hi = lt - 1;
        else if (kk > gt) lo = gt + 1;
        else return v[kk];
    }
    for (ptrdiff_t i = lo + 1; i <= hi; i++) {
        double x = v[i];
        ptrdiff_t j = i;
        for (; j > lo && v[j - 1] > x; j--) v[j] = v[j - 1];
        v[j] = x;
    }
    return v[kk];
}

double sy_quantile_double(double *v, size_t n, double q)
{
    if (!n) return NAN;
    double x = q * (double)(n - 1);
    size_t i = (size_t)x;
    double f = x - (double)i, a = sy_select_double(v, n, i);
    if (i + 1 >= n) return a;
    double b = v[i + 1];
    for (size_t j = i + 2; j < n; j++)
        if (v[j] < b) b = v[j];
    return a * (1 - f) + b * f;
}
