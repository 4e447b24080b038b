/* Meshes a generated ~2,000-branch, ~20,000-leaf tree and prints the time of
 * each step and the triangles of every LOD level. */
#include <stdio.h>
#include <time.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/progress.h"
#include "stages/export/export.h"
#include "stages/mesh/mesh.h"
#include "stages/mesh/mesh_internal.h"
#include "tests/tree_gen.h"

/* CPU time of this process: the development machine is shared, so wall
 * time measures the neighbours; the bench is single-threaded. */
static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
static double ms_since(double t0) { return (cpu_now() - t0) * 1000.0; }

int main(void)
{
    sy_skeleton s;
    sy_leaves lv;
    sy_error err = {0};
    double t0 = cpu_now();
    if (tg_tree(2024, 3, 24, 3, 15.0f, &s, &lv) != 0) {
        fprintf(stderr, "generator failed\n");
        return 1;
    }
    printf("tree: %d branches, %zu nodes, %zu leaves (generated in %.1f ms)\n", sy_skeleton_branch_count(&s), s.n,
           lv.n, ms_since(t0));
    sy_mesh_options o = sy_mesh_options_default();

    /* Steps measured separately through the stage's internals. */
    sy_stems st;
    t0 = cpu_now();
    if (sy_stems_build(&s, &o, &st, &err) != SY_OK) return 1;
    printf("stems (chains, curves, frames, junction trim): %8.1f ms\n", ms_since(t0));
    sy_asset scratch;
    memset(&scratch, 0, sizeof scratch);
    t0 = cpu_now();
    if (sy_wind_build(&st, &scratch, &err) != SY_OK) return 1;
    printf("wind table:                                    %8.1f ms\n", ms_since(t0));
    uint8_t *keep = malloc(st.n);
    memset(keep, 1, st.n);
    sy_lod_params lp = {0, 1, keep, 1};
    sy_mesh m;
    t0 = cpu_now();
    if (sy_bark_mesh(&st, &lp, 0, &m, &err) != SY_OK) return 1;
    printf("LOD0 bark mesh:                                %8.1f ms\n", ms_since(t0));
    sy_mesh_free(&m);
    free(keep);
    sy_asset_free(&scratch);
    sy_stems_free(&st);

    /* The whole stage, without and with the impostor. */
    for (int imp = 0; imp <= 1; imp++) {
        sy_asset a;
        memset(&a, 0, sizeof a);
        o.impostor = imp;
        t0 = cpu_now();
        if (sy_mesh_tree(&s, &lv, &o, &a, &err) != SY_OK) {
            fprintf(stderr, "%s\n", err.msg);
            return 1;
        }
        double mesh_ms = ms_since(t0);
        printf("sy_mesh_tree %s impostor:                  %8.1f ms\n", imp ? "with   " : "without", mesh_ms);
        if (imp) {
            for (size_t k = 0; k < a.n_lods; k++) {
                const sy_lod *l = &a.lods[k];
                size_t bark = 0, leaves = 0, cards = 0, verts = 0;
                for (int i = 0; i < l->n_meshes; i++) {
                    bark += a.meshes[l->meshes[i]].n_indices / 3;
                    verts += a.meshes[l->meshes[i]].n_vertices;
                }
                for (int i = 0; i < l->n_instances; i++) {
                    cards += l->instances[i].n;
                    leaves += l->instances[i].n * (a.meshes[l->instances[i].mesh].n_indices / 3);
                }
                printf("LOD %zu (coverage %.4f): %7zu bark triangles (%7zu vertices), %6zu leaf cards = %7zu leaf "
                       "triangles, total %7zu\n",
                       k, l->screen_coverage, bark, verts, cards, leaves, bark + leaves);
            }
            printf("impostor PNG: %zu bytes\n", a.n_images ? a.images[a.n_images - 1].size : 0);
            /* The target covers meshing + export together, one core. */
            for (int mo = 0; mo < 2; mo++) {
                sy_export_options eo = sy_export_options_default();
                eo.meshopt = mo;
                double te = cpu_now();
                unsigned char *glb = NULL;
                size_t glb_size = 0;
                if (sy_export_glb(&a, &eo, "bench.glb", &glb, &glb_size, &err)) {
                    fprintf(stderr, "%s\n", err.msg);
                    return 3;
                }
                double export_ms = (cpu_now() - te) * 1e3;
                printf("export %-8s %8.1f ms, %9zu bytes; mesh + export %.1f ms (CPU; target < 500 ms)\n",
                       mo ? "meshopt" : "plain", export_ms, glb_size, mesh_ms + export_ms);
                free(glb);
            }
        }
        sy_asset_free(&a);
    }
    sy_leaves_free(&lv);
    sy_skeleton_free(&s);
    return 0;
}
