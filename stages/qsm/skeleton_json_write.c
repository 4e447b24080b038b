/* Sylva's skeleton JSON: {"format":"sylva-skeleton","version":1,
 * "origin":[x,y,z],"nodes":[{"id","parent","x","y","z","radius","order",
 * "branch"}...]} with x y z in world coordinates (origin + pos). */
#include <stdio.h>

#include "stages/qsm/qsm.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"

void sy_skeleton_json_members(sy_json *j, FILE *fp, const sy_skeleton *s)
{
    sy_json_numbers(j, "origin", s->origin, 3);
    sy_json_array(j, "nodes");
    for (size_t i = 0; i < s->n; i++) {
        /* One node per line keeps large files diffable without pretty-printing. */
        fputc('\n', fp);
        sy_json_object(j, NULL);
        sy_json_int(j, "id", (long long)i);
        sy_json_int(j, "parent", s->parent[i]);
        sy_json_number(j, "x", s->origin[0] + (double)s->pos[3 * i]);
        sy_json_number(j, "y", s->origin[1] + (double)s->pos[3 * i + 1]);
        sy_json_number(j, "z", s->origin[2] + (double)s->pos[3 * i + 2]);
        sy_json_number(j, "radius", s->radius[i]);
        sy_json_int(j, "order", s->order[i]);
        sy_json_int(j, "branch", s->branch[i]);
        sy_json_end(j);
    }
    sy_json_end(j);
}

sy_code sy_skeleton_json_open(const char *path, const sy_skeleton *s, const char *format, sy_atomic_file *f,
                              sy_json *j, sy_error *err)
{
    sy_code rc = sy_skeleton_validate(s, err);
    if (rc) return rc;
    if ((rc = sy_atomic_open(f, path, err))) return rc;
    sy_json_begin(j, f->fp, 0);
    sy_json_object(j, NULL);
    sy_json_string(j, "format", format);
    sy_json_int(j, "version", 1);
    return SY_OK;
}

sy_code sy_skeleton_write_json(const char *path, const sy_skeleton *s, sy_error *err)
{
    sy_atomic_file f;
    sy_json j;
    sy_code rc = sy_skeleton_json_open(path, s, "sylva-skeleton", &f, &j, err);
    if (rc) return rc;
    sy_skeleton_json_members(&j, f.fp, s);
    sy_json_end(&j);
    sy_json_finish(&j);
    return sy_atomic_commit(&f, err);
}
