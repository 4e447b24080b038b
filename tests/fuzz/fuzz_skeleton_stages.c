/* Structured libFuzzer target: a fuzzed skeleton through what `sylva mesh`
 * and `sylva eval` do with one: the PLY skeleton reader (so the skeleton
 * is whatever a file could make), leaf placement, the mesh and export
 * stages (tree asset with LODs and, on bit 2, the impostor), and the
 * skeleton and surface metrics of eval against itself.
 *
 * Layout: byte 0 flags (bit 0 leaves, bit 1 a second LOD, bit 2 impostor,
 * bit 3 meshopt), byte 1 the scale exponent (units of 10^(b % 10 - 4) m),
 * then per node 8 bytes: parent back-step (node i hangs on i - 1 - b % i),
 * x y z as int16, radius code (1 mm * 1.06^b). At most 400 nodes. A case
 * that passes -timeout or -rss_limit_mb is a finding. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/tree_asset.h"
#include "stages/core/asset.h"
#include "stages/core/progress.h"
#include "stages/eval/eval.h"
#include "stages/qsm/leaf_placement.h"
#include "stages/qsm/qsm.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

enum { MAX_NODES = 400 };

static int16_t i16(const uint8_t *p) { return (int16_t)(uint16_t)(p[0] | p[1] << 8); }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2 + 8) return 0;
    sy_progress_set_quiet(1);
    uint8_t flags = data[0];
    double unit = pow(10.0, (double)(data[1] % 10) - 4);
    size_t n = (size - 2) / 8;
    if (n > MAX_NODES) n = MAX_NODES;
    /* An ASCII PLY skeleton, as a file would hold it. */
    size_t cap = 512 + n * 96;
    char *ply = malloc(cap);
    if (!ply) return 0;
    size_t len = (size_t)snprintf(ply, cap,
                                  "ply\nformat ascii 1.0\nelement vertex %zu\nproperty double x\nproperty double y\n"
                                  "property double z\nproperty float radius\nelement edge %zu\n"
                                  "property int vertex1\nproperty int vertex2\nend_header\n",
                                  n, n - 1);
    for (size_t i = 0; i < n; i++) {
        const uint8_t *p = data + 2 + 8 * i;
        len += (size_t)snprintf(ply + len, cap - len, "%.9g %.9g %.9g %.6g\n", i16(p + 1) * unit, i16(p + 3) * unit,
                                i16(p + 5) * unit, 0.001 * pow(1.06, p[7]));
    }
    for (size_t i = 1; i < n; i++) {
        const uint8_t *p = data + 2 + 8 * i;
        len += (size_t)snprintf(ply + len, cap - len, "%zu %zu\n", i - 1 - p[0] % i, i);
    }
    sy_skeleton s;
    sy_error err = {0};
    sy_code rc = sy_skeleton_read_ply_mem("fuzz.ply", (const unsigned char *)ply, len, &s, NULL, &err);
    free(ply);
    if (rc) return 0;
    sy_leaves leaves = {0};
    if (flags & 1) {
        sy_leaf_placement lp = {0};
        lp.per_metre = 4.3;
        lp.size = 0.3f;
        lp.max_reverse_order = 2;
        lp.seed = 1;
        double twigs;
        rc = sy_place_leaves(&s, &lp, &leaves, &twigs, &err);
    }
    if (rc == SY_OK) {
        sy_tree_asset_options o = sy_tree_asset_options_default();
        o.lods = flags & 2 ? 2 : 1;
        o.impostor = (flags >> 2) & 1;
        o.impostor_size = 32;
        o.meshopt = (flags >> 3) & 1;
        o.texture_size = 32;
        sy_asset a;
        sy_tree_asset_report rep;
        if (sy_tree_asset_build(&s, &leaves, NULL, &o, &a, &rep, &err) == SY_OK) sy_asset_free(&a);
    }
    sy_leaves_free(&leaves);
    /* eval: the skeleton against itself, and its nodes against its cones. */
    sy_forest f = {0};
    sy_eval_tree t;
    memset(&t, 0, sizeof t);
    t.tree_id = -1;
    t.species_id = -1;
    t.height = sy_skeleton_height(&s);
    t.dbh = sy_skeleton_dbh(&s);
    t.crown_width = NAN;
    for (int k = 0; k < 3; k++) t.position[k] = s.origin[k] + s.pos[k];
    double *pts = malloc(3 * s.n * sizeof *pts);
    for (size_t i = 0; pts && i < s.n; i++)
        for (int k = 0; k < 3; k++) pts[3 * i + k] = s.origin[k] + s.pos[3 * i + k];
    size_t n_pts = s.n;
    t.skel = s;
    if (sy_forest_add(&f, &t, &err) != SY_OK) {
        sy_skeleton_free(&s);
        free(pts);
        return 0;
    }
    sy_skeleton_metrics sm;
    sy_skeleton_metrics_options mo = sy_skeleton_metrics_options_default();
    sy_skeleton_metrics_compute(&f, &f, &mo, &sm, &err);
    sy_eval_model model = {0, NULL, f};
    sy_surface_metrics su;
    if (pts) sy_surface_metrics_compute(&model, pts, n_pts, 0.02, 0.01, &su, &err);
    free(pts);
    sy_forest_free(&f);
    return 0;
}
