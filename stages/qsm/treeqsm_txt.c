/* TreeQSM's cylinder text export, written by src/tools/save_model_text.m:
 *   v1.1.0 (TreeQSM 2.4, cylinder_<name>.txt): a tab-separated header line
 *     "radius (m) length (m) start_point axis_direction parent extension
 *      branch branch_order position_in_branch mad SurfCov added
 *      UnmodRadius (m)", then 17 columns per cylinder:
 *     radius length start(3) axis(3) parent extension branch BranchOrder
 *     PositionInBranch mad SurfCov added UnmodRadius
 *   v1.0 (TreeQSM 2.3, cyl_data_<name>.txt): no header, 15 columns:
 *     radius length start(3) axis(3) parent extension branch BranchOrder
 *     PositionInBranch added UnmodRadius
 * Values are printed with %g after rounding lengths to 0.1 mm; cylinders
 * and branches count from 1 and parent 0 marks the first stem cylinder. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "qsm_internal.h"
#include "stages/core/array.h"

/* The file rounds coordinates to 0.1 mm, so an end recomputed from start +
 * length * axis misses the next start by a few tenths of a millimetre. */
#define TXT_JOIN_TOL 1e-3

enum { T_RAD, T_LEN, T_SX, T_SY, T_SZ, T_AX, T_AY, T_AZ, T_PARENT, T_EXT, T_BRANCH, T_ORDER, T_PIB };

static int split_blank(const char *b, const char *e, const char **tb, const char **te, int max)
{
    int n = 0;
    while (b < e) {
        while (b < e && (*b == ' ' || *b == '\t' || *b == ',')) b++;
        if (b == e) break;
        if (n == max) return max + 1;
        tb[n] = b;
        while (b < e && *b != ' ' && *b != '\t' && *b != ',') b++;
        te[n++] = b;
    }
    return n;
}

static int is_header(const char *b, const char *e)
{
    return e - b >= 6 && strncmp(b, "radius", 6) == 0;
}

static sy_code parse_cylinder(const char *path, size_t line, size_t row, const char **tb, const char **te,
                              sy_cyl *c, sy_error *err)
{
    double v[13];
    for (int k = 0; k < 13; k++) {
        if (!sy_qsm_parse_number(tb[k], te[k], &v[k]))
            return sy_fail(err, SY_EINPUT, "%s:%zu: malformed number '%.*s' in column %d", path, line,
                           (int)(te[k] - tb[k] > 40 ? 40 : te[k] - tb[k]), tb[k], k + 1);
        if (!isfinite(v[k])) return sy_fail(err, SY_EINPUT, "%s:%zu: column %d is not finite", path, line, k + 1);
    }
    if (v[T_RAD] < 0) return sy_fail(err, SY_EINPUT, "%s:%zu: negative radius %g", path, line, v[T_RAD]);
    if (!((float)v[T_RAD] > 0)) return sy_fail(err, SY_EINPUT, "%s:%zu: radius %g is not positive", path, line, v[T_RAD]);
    if (v[T_LEN] < 0) return sy_fail(err, SY_EINPUT, "%s:%zu: negative length %g", path, line, v[T_LEN]);
    if (v[T_PARENT] < 0 || v[T_PARENT] != floor(v[T_PARENT]) || v[T_PARENT] > 9e15)
        return sy_fail(err, SY_EINPUT, "%s:%zu: parent %g is not a cylinder number", path, line, v[T_PARENT]);
    if (v[T_BRANCH] < 1 || v[T_BRANCH] != floor(v[T_BRANCH]) || v[T_BRANCH] > INT32_MAX)
        return sy_fail(err, SY_EINPUT, "%s:%zu: branch %g is not a branch number", path, line, v[T_BRANCH]);
    if (v[T_ORDER] < 0 || v[T_ORDER] > 255 || v[T_ORDER] != floor(v[T_ORDER]))
        return sy_fail(err, SY_EINPUT, "%s:%zu: branch order %g outside 0..255", path, line, v[T_ORDER]);
    double ax = v[T_AX], ay = v[T_AY], az = v[T_AZ], an = sqrt(ax * ax + ay * ay + az * az);
    if (!(an > 0) && v[T_LEN] > 0)
        return sy_fail(err, SY_EINPUT, "%s:%zu: zero axis direction", path, line);
    memset(c, 0, sizeof *c);
    c->line = line;
    c->id = (long long)row; /* cylinders count from 1 in file order */
    c->parent_id = v[T_PARENT] == 0 ? -1 : (long long)v[T_PARENT];
    double s = an > 0 ? v[T_LEN] / an : 0; /* the rounded axis is renormalised */
    c->start[0] = v[T_SX];
    c->start[1] = v[T_SY];
    c->start[2] = v[T_SZ];
    c->end[0] = v[T_SX] + s * ax;
    c->end[1] = v[T_SY] + s * ay;
    c->end[2] = v[T_SZ] + s * az;
    c->radius = (float)v[T_RAD];
    c->order = (int)v[T_ORDER];
    c->branch = (int32_t)v[T_BRANCH] - 1;
    return SY_OK;
}

sy_code sy_skeleton_read_treeqsm_mem(const char *path, const unsigned char *data, size_t size, sy_skeleton *out,
                                     sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_lines L;
    sy_lines_init(&L, data, size);
    const char *b, *e, *tb[20], *te[20];
    sy_cyl *cyl = NULL;
    size_t n = 0, cap = 0;
    int width = 0; /* 15 or 17 columns, fixed by the header or the first row */
    sy_code rc = SY_OK;
    while (!rc && sy_lines_next(&L, &b, &e)) {
        sy_trim(&b, &e);
        if (b == e) continue;
        if (width == 0 && n == 0 && is_header(b, e)) {
            width = 17;
            continue;
        }
        int nt = split_blank(b, e, tb, te, 19);
        if (width == 0) {
            if (nt != 15 && nt != 17) {
                rc = sy_fail(err, SY_EINPUT, "%s:%zu: %d columns, a TreeQSM cylinder file has 15 or 17", path,
                             L.line, nt);
                break;
            }
            width = nt;
        }
        if (nt != width) {
            rc = sy_fail(err, SY_EINPUT, "%s:%zu: %d columns, expected %d", path, L.line, nt, width);
            break;
        }
        if ((rc = sy_array_reserve(&cyl, &cap, n + 1, sizeof *cyl, 256, err, path))) break;
        rc = parse_cylinder(path, L.line, n + 1, tb, te, &cyl[n], err);
        if (!rc) n++;
    }
    if (!rc) rc = sy_cylinders_to_skeleton(path, cyl, n, TXT_JOIN_TOL, out, info, err);
    if (!rc && info) info->format = SY_SKEL_TREEQSM_TXT;
    free(cyl);
    return rc;
}
