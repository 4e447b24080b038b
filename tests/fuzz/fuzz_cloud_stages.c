/* Structured libFuzzer target: a fuzzed cloud through preprocess (up axis,
 * crop, voxel, outliers, ground, normals) and the skeleton stage (graph,
 * level sets, radii) and the clusters stage's cut, as `sylva run` chains them.
 *
 * Layout: byte 0 switches steps (bit 0 voxel, 1 outliers, 2 ground,
 * 3 normals, 4 skeleton, 5 clusters), byte 1 is the scale exponent (units
 * of 10^(b % 12 - 5) m, so 1e-5 m to 1e6 m and past the span bound), then
 * points as three little-endian int16 each (at most 3000). A case that
 * passes the time or memory budget (-timeout, -rss_limit_mb) is a finding:
 * every step must stay bounded by the point count, never by the extent. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "stages/clusters/clusters.h"
#include "stages/core/cloud.h"
#include "stages/core/progress.h"
#include "stages/preprocess/preprocess.h"
#include "stages/skeleton/skeleton.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

enum { MAX_POINTS = 3000 };

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2 + 6) return 0;
    sy_progress_set_quiet(1);
    uint8_t flags = data[0];
    double unit = pow(10.0, (double)(data[1] % 12) - 5);
    size_t n = (size - 2) / 6;
    if (n > MAX_POINTS) n = MAX_POINTS;
    sy_cloud c;
    sy_error err = {0};
    if (sy_cloud_init(&c, n, &err)) return 0;
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            const uint8_t *p = data + 2 + 6 * i + 2 * k;
            c.xyz[3 * i + k] = (float)((int16_t)(uint16_t)(p[0] | p[1] << 8) * unit);
        }
    /* What every reader's caller gets: the range check of sy_read_cloud. */
    if (sy_cloud_check_range(&c, "fuzz", &err) == SY_OK) {
        sy_preprocess_options o = sy_preprocess_options_default();
        o.voxel = flags & 1 ? 0.05 : 0;
        o.sor = (flags >> 1) & 1;
        o.ground = (flags >> 2) & 1;
        o.normals = (flags >> 3) & 1;
        o.sor_k = o.normal_k = 8;
        sy_preprocess_result r;
        sy_code rc = sy_preprocess_options_check(&o, &err);
        if (rc == SY_OK) rc = sy_preprocess(&c, &o, &r, &err);
        if (rc == SY_OK && (flags & 16) && c.n >= 2) {
            sy_skeleton_options so = sy_skeleton_options_default();
            sy_cut_options co = sy_cut_options_default();
            co.clusters = (flags >> 5) & 1;
            sy_full_skeleton full;
            sy_skeleton s;
            sy_clusters cl;
            sy_skeleton_report rep;
            if (sy_reconstruct_skeleton(&c, &so, &full, &rep, &err) == SY_OK) {
                if (sy_clusters_extract(&full, c.xyz, &co, &s, &cl, NULL, &err) == SY_OK) {
                    if (sy_skeleton_validate(&s, &err) != SY_OK) abort();
                    sy_skeleton_free(&s);
                    sy_clusters_free(&cl);
                }
                sy_full_skeleton_free(&full);
            }
        }
    }
    sy_cloud_free(&c);
    return 0;
}
