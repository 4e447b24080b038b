/* Grows every species in the library (or those named on the command line)
 * and prints node, branch and leaf counts, height and generation time. */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/progress.h"
#include "stages/grow/grow.h"

static int grow_one(const char *name, uint64_t seed)
{
    sy_species_params sp;
    sy_error err = {0};
    if (sy_species_params_find(name, &sp, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    sy_skeleton sk;
    sy_leaves lv;
    double t0 = sy_now();
    sy_code rc = sy_grow_tree(&sp, seed, &sk, &lv, &err);
    double dt = sy_now() - t0;
    if (rc) {
        fprintf(stderr, "%s\n", err.msg);
        sy_species_params_free(&sp);
        return 1;
    }
    float top = 0, lo[2] = {0, 0}, hi[2] = {0, 0};
    for (size_t i = 0; i < sk.n; i++) {
        const float *p = sk.pos + 3 * i;
        if (p[2] > top) top = p[2];
        for (int k = 0; k < 2; k++) {
            if (p[k] < lo[k]) lo[k] = p[k];
            if (p[k] > hi[k]) hi[k] = p[k];
        }
    }
    int levels[5] = {0};
    for (size_t i = 0; i < sk.n; i++)
        if (i == 0 || sk.branch[i] != sk.branch[sk.parent[i]]) levels[sk.order[i] < 4 ? sk.order[i] : 4]++;
    printf("%-16s seed %3llu  nodes %6zu  branches %5d (%d/%d/%d/%d)  leaves %6zu  height %5.1f m (scale %4.1f)"
           "  crown %4.1f m  base r %.3f m  %6.1f ms\n",
           sp.name, (unsigned long long)seed, sk.n, sy_skeleton_branch_count(&sk), levels[0], levels[1], levels[2],
           levels[3], lv.n, top, sp.scale, (hi[0] - lo[0] + hi[1] - lo[1]) / 2, sk.radius[0], dt * 1e3);
    sy_skeleton_free(&sk);
    sy_leaves_free(&lv);
    sy_species_params_free(&sp);
    return 0;
}

int main(int argc, char **argv)
{
    int seeds = 3, bad = 0;
    if (argc > 1) {
        for (int i = 1; i < argc; i++)
            for (int s = 1; s <= seeds; s++) bad |= grow_one(argv[i], (uint64_t)s);
        return bad;
    }
    DIR *d = opendir(SYLVA_SPECIES_DIR);
    if (!d) return 1;
    char names[64][128];
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)) && n < 64) {
        size_t len = strlen(e->d_name);
        if (len > 4 && strcmp(e->d_name + len - 4, ".ini") == 0)
            snprintf(names[n++], sizeof names[0], "%.*s", (int)(len - 4), e->d_name);
    }
    closedir(d);
    qsort(names, (size_t)n, sizeof names[0], (int (*)(const void *, const void *))strcmp);
    for (int i = 0; i < n; i++)
        for (int s = 1; s <= seeds; s++) bad |= grow_one(names[i], (uint64_t)s);
    return bad;
}
