/* Helpers of bench/synthesize/run.sh (issue 11's targets; printed, never
 * asserted):
 *
 *   bench_synthesize decode TREE.sylva [REPS]
 *     CPU time of decode + synthesis and of meshing LOD0 (no impostor, no
 *     export, no materials) on one thread, the median of REPS (default 5)
 *     runs, and the LOD0 triangles (bark + leaf cards x instances). The
 *     species is the file's (library id), as `sylva mesh` takes it; the
 *     L-system library generation is timed apart (per species and seed, it
 *     could be cached).
 *   bench_synthesize look SCAN MESH.obj [MASKS.png]
 *     The silhouette measure of `sylva eval --points SCAN ASSET.glb`
 *     (stages/eval/silhouette.c: the scan preprocessed as `sylva run` does)
 *     for a triangle mesh in Wavefront OBJ (v / f lines, polygons fanned),
 *     world Z up, e.g. AdTree's branch mesh, so that a peer's model is scored
 *     by the same measure as Sylva's asset. MASKS.png: the six views' masks
 *     as `sylva eval --png` draws them.
 *   bench_synthesize returns SCAN
 *     The scan's own returns as the asset (a tetrahedron of 4 mm circumradius
 *     at each, then one of the scan's median spacing), by the same measure: what
 *     an asset that drew every return and nothing else would score.
 *
 *   bench_synthesize lookglb REFERENCE.glb ASSET.glb [MASKS.png]
 *     `sylva eval --points REFERENCE.glb ASSET.glb`'s silhouette figures
 *     alone (the same calls: LOD0 without proxy, the reference sampled every
 *     2 cm), precision and recall with them, without its distance metrics,
 *     which cost minutes on a grown tree. MASKS.png as for look.
 *   bench_synthesize compare SPECIES SEED TREE.sylva
 *     The asset decoded from TREE.sylva (a `sylva run --species SPECIES` of
 *     a simulated scan of that tree) against the true tree (`sylva grow`'s,
 *     same species and seed): total leaf area (sum of card length squared;
 *     both use the species' card, so its shape factor cancels in the ratio)
 *     and the count of branches whose base radius (a branch's first node)
 *     is >= 2 cm, each with the ratio asset / truth.
 *
 * Output: one line of key=value pairs. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "pipeline/tree_synth.h"
#include "stages/gltf/gltf_read.h"
#include "stages/grow/grow.h"
#include "species/library.h"
#include "stages/core/fileio.h"
#include "stages/core/parallel.h"
#include "stages/eval/eval.h"
#include "stages/ingest/ingest.h"
#include "stages/mesh/mesh.h"
#include "stages/preprocess/preprocess.h"

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Branches whose first node (the one whose parent is on another branch, or
 * the root) is at least r thick. */
static size_t thick_branches(const sy_skeleton *s, float r)
{
    size_t n = 0;
    for (size_t i = 0; i < s->n; i++) {
        int32_t p = s->parent[i];
        if ((p < 0 || s->branch[p] != s->branch[i]) && s->radius[i] >= r) n++;
    }
    return n;
}

static double leaf_area(const sy_leaves *l)
{
    double a = 0;
    for (size_t i = 0; i < l->n; i++) a += (double)l->scale[i] * l->scale[i];
    return a;
}

static int compare(const char *species, uint64_t seed, const char *path)
{
    sy_error err = {0};
    sy_species_params sp;
    if (sy_species_params_find(species, &sp, &err)) return fprintf(stderr, "%s\n", err.msg), 2;
    sy_skeleton truth;
    sy_leaves tl;
    sy_buffer buf;
    if (sy_grow_tree(&sp, seed, &truth, &tl, &err)) {
        sy_species_params_free(&sp);
        return fprintf(stderr, "%s\n", err.msg), 2;
    }
    int rc = 0;
    sy_decoded_tree dt;
    if (sy_read_file(path, &buf, &err)) rc = 2;
    else {
        if (sy_decoded_tree_build(path, buf.data, buf.size, &sp, 0, &dt, &err)) rc = 2;
        sy_buffer_free(&buf);
    }
    if (rc) fprintf(stderr, "%s\n", err.msg);
    else {
        size_t bt = thick_branches(&truth, 0.02f), ba = thick_branches(&dt.grown, 0.02f);
        size_t bm = thick_branches(&dt.skel, 0.02f);
        double at = leaf_area(&tl), aa = leaf_area(&dt.leaves);
        printf("leaves=%zu leaves_truth=%zu leaf_area=%.2f leaf_area_truth=%.2f leaf_area_ratio=%.3f "
               "branches_r2cm=%zu branches_r2cm_main=%zu branches_r2cm_truth=%zu branches_r2cm_ratio=%.3f\n",
               dt.leaves.n, tl.n, aa, at, at > 0 ? aa / at : 0, ba, bm, bt, bt ? (double)ba / (double)bt : 0);
        sy_decoded_tree_free(&dt);
    }
    sy_skeleton_free(&truth);
    sy_leaves_free(&tl);
    sy_species_params_free(&sp);
    return rc;
}

/* FNV-1a over n bytes, continuing from h. */
static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *b = data;
    for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * 0x100000001B3ull;
    return h;
}

/* A digest of LOD0 (bark positions and triangles, leaf instances' TRS): a
 * change meant to keep the asset's bytes can be checked without an export. */
static uint64_t lod0_digest(const sy_asset *a)
{
    uint64_t h = 0xCBF29CE484222325ull;
    const sy_lod *lod = &a->lods[0];
    for (int k = 0; k < lod->n_meshes; k++) {
        const sy_mesh *m = &a->meshes[lod->meshes[k]];
        h = fnv1a(h, m->position, 3 * m->n_vertices * sizeof *m->position);
        h = fnv1a(h, m->indices, m->n_indices * sizeof *m->indices);
    }
    for (int k = 0; k < lod->n_instances; k++) {
        const sy_instances *in = &lod->instances[k];
        h = fnv1a(h, in->translation, 3 * in->n * sizeof *in->translation);
        h = fnv1a(h, in->rotation, 4 * in->n * sizeof *in->rotation);
        h = fnv1a(h, in->scale, 3 * in->n * sizeof *in->scale);
    }
    return h;
}

static int decode(const char *path, int reps)
{
    sy_error err = {0};
    sy_buffer buf;
    if (sy_read_file(path, &buf, &err)) return fprintf(stderr, "%s\n", err.msg), 2;
    sy_species_params sp;
    int have = 0;
    uint16_t id = buf.size >= 8 ? (uint16_t)(buf.data[6] | buf.data[7] << 8) : 0;
    if (id > 0) {
        sy_library lib;
        if (!sy_library_load(NULL, &lib, &err)) {
            const sy_library_entry *e = sy_library_by_id(&lib, id - 1);
            if (e && !sy_library_params(&lib, e, &sp, &err)) have = 1;
            sy_library_free(&lib);
        }
    }
    double *t_synth = calloc((size_t)reps, sizeof *t_synth), *t_mesh = calloc((size_t)reps, sizeof *t_mesh);
    double t_lib = 0;
    size_t bark = 0, cards = 0, leaf_tris = 0, nodes = 0;
    uint64_t digest = 0;
    int rc = 0;
    for (int r = 0; r < reps && !rc; r++) {
        sy_decoded_tree dt;
        double t0 = cpu_now();
        if (sy_decoded_tree_build(path, buf.data, buf.size, have ? &sp : NULL, 0, &dt, &err)) {
            fprintf(stderr, "%s\n", err.msg);
            rc = 2;
            break;
        }
        t_synth[r] = cpu_now() - t0;
        if (r == 0) {
            /* The library step again, alone, in CPU time (dt.seconds_library is wall time). */
            sy_lsystem ls;
            sy_branchlets lib;
            double t1 = cpu_now();
            if (!sy_lsystem_load(dt.lsys, &ls, &err) && !sy_branchlets_generate(&ls, dt.meta.seed, &lib, &err)) {
                t_lib = cpu_now() - t1;
                sy_branchlets_free(&lib);
            }
        }
        t_synth[r] -= t_lib;
        sy_mesh_options mo = sy_mesh_options_default();
        mo.n_lods = 1;
        mo.impostor = 0;
        mo.seed = dt.meta.seed;
        mo.keep_leaf_order = 1;
        mo.lean_radius = dt.lean_radius;
        mo.bark_material = mo.leaf_material = -1;
        if (have) {
            mo.leaf_aspect = sp.leaf_scale_x;
            mo.leaf_shape = sp.leaf_shape;
        }
        sy_asset a;
        memset(&a, 0, sizeof a);
        t0 = cpu_now();
        if (sy_mesh_tree(&dt.grown, &dt.leaves, &mo, &a, &err)) {
            fprintf(stderr, "%s\n", err.msg);
            rc = 2;
        } else {
            t_mesh[r] = cpu_now() - t0;
            const sy_lod *lod = &a.lods[0];
            bark = cards = leaf_tris = 0;
            for (int k = 0; k < lod->n_meshes; k++) bark += a.meshes[lod->meshes[k]].n_indices / 3;
            for (int k = 0; k < lod->n_instances; k++) {
                cards += lod->instances[k].n;
                leaf_tris += lod->instances[k].n * (a.meshes[lod->instances[k].mesh].n_indices / 3);
            }
            nodes = dt.grown.n;
            digest = lod0_digest(&a);
            sy_asset_free(&a);
        }
        sy_decoded_tree_free(&dt);
    }
    if (!rc) {
        double both[64];
        int n = reps < 64 ? reps : 64;
        for (int r = 0; r < n; r++) both[r] = t_synth[r] + t_mesh[r];
        qsort(t_synth, (size_t)reps, sizeof *t_synth, cmp_double);
        qsort(t_mesh, (size_t)reps, sizeof *t_mesh, cmp_double);
        qsort(both, (size_t)n, sizeof *both, cmp_double);
        printf("species=%s nodes=%zu lod0_bark_tris=%zu leaf_instances=%zu lod0_tris=%zu library_ms=%.1f "
               "synth_ms=%.1f mesh_ms=%.1f decode_ms=%.1f digest=%016llx\n",
               have ? sp.name : "default", nodes, bark, cards, bark + leaf_tris, 1000 * t_lib,
               1000 * t_synth[reps / 2], 1000 * t_mesh[reps / 2], 1000 * both[n / 2], (unsigned long long)digest);
    }
    free(t_synth);
    free(t_mesh);
    if (have) sy_species_params_free(&sp);
    sy_buffer_free(&buf);
    return rc;
}

/* OBJ triangles as 9 doubles each (polygons fanned from their first corner;
 * negative indices count back from the last vertex). */
static int read_obj(const char *path, double **tri, size_t *n_tri)
{
    FILE *f = fopen(path, "r");
    if (!f) return fprintf(stderr, "%s: cannot open\n", path), 2;
    size_t nv = 0, cv = 1024, nt = 0, ct = 1024;
    double *v = malloc(3 * cv * sizeof *v), *t = malloc(9 * ct * sizeof *t);
    char line[4096];
    int rc = 0;
    while (!rc && fgets(line, sizeof line, f)) {
        if (line[0] == 'v' && line[1] == ' ') {
            if (nv == cv) v = realloc(v, 3 * (cv *= 2) * sizeof *v);
            if (sscanf(line + 2, "%lf %lf %lf", v + 3 * nv, v + 3 * nv + 1, v + 3 * nv + 2) != 3) rc = 2;
            nv++;
        } else if (line[0] == 'f' && line[1] == ' ') {
            long idx[64];
            int k = 0;
            char *p = line + 2, *e;
            while (k < 64) {
                long i = strtol(p, &e, 10);
                if (e == p) break;
                idx[k++] = i < 0 ? (long)nv + i : i - 1;
                p = e;
                while (*p && *p != ' ' && *p != '\t') p++; /* skip /vt/vn */
            }
            for (int j = 0; j < k; j++)
                if (idx[j] < 0 || (size_t)idx[j] >= nv) rc = 2;
            for (int j = 2; !rc && j < k; j++) {
                if (nt == ct) t = realloc(t, 9 * (ct *= 2) * sizeof *t);
                const long c[3] = {idx[0], idx[j - 1], idx[j]};
                for (int q = 0; q < 3; q++) memcpy(t + 9 * nt + 3 * q, v + 3 * c[q], 3 * sizeof *t);
                nt++;
            }
        }
    }
    fclose(f);
    free(v);
    if (rc || !nt) {
        free(t);
        return fprintf(stderr, "%s: %s\n", path, rc ? "bad vertex or face line" : "no faces"), 2;
    }
    *tri = t;
    *n_tri = nt;
    return 0;
}

/* The silhouette measure of triangles tri (cut: their cut-outs, or NULL)
 * against points pts (weights w, or NULL); with png, the six views' masks
 * drawn there as `sylva eval --png` draws them. Nonzero on failure (err). */
static int silhouettes(const double *tri, size_t nt, const sy_gltf_cutout *cut, const double *pts, const double *w,
                       size_t np, const char *png, sy_silhouette_metrics *m, sy_error *err)
{
    unsigned char *masks = png ? calloc((size_t)SY_SILHOUETTE_VIEWS * SY_SILHOUETTE_RES * SY_SILHOUETTE_RES, 1) : NULL;
    if (png && !masks) return sy_fail(err, SY_EINTERNAL, "out of memory"), 1;
    int rc = sy_silhouette_metrics_compute(tri, nt, cut, pts, w, np, m, masks, err) || (png && sy_silhouette_png(masks, png, err));
    free(masks);
    return rc;
}

static void print_silhouettes(const sy_silhouette_metrics *m)
{
    printf("iou_mean=%.3f iou_min=%.3f precision=%.3f recall=%.3f profile_correlation=%.3f height_error_rel=%+.3f "
           "crown_width_error_rel=%+.3f\n",
           m->iou_mean, m->iou_min, m->precision, m->recall, m->profile_correlation, m->height_error, m->width_error);
}

static int look(const char *scan, const char *obj, const char *png)
{
    sy_error err = {0};
    double *tri;
    size_t nt;
    if (read_obj(obj, &tri, &nt)) return 2;
    sy_cloud c;
    memset(&c, 0, sizeof c);
    if (sy_read_cloud(scan, &c, &err)) {
        free(tri);
        return fprintf(stderr, "%s\n", err.msg), 2;
    }
    sy_preprocess_options po = sy_preprocess_options_default();
    po.remove_ground = 1;
    po.normals = 0;
    sy_preprocess_result pr;
    double *pts = NULL;
    sy_silhouette_metrics m;
    int rc = sy_preprocess(&c, &po, &pr, &err) || !(pts = sy_cloud_world_points(&c, &err)) ||
             silhouettes(tri, nt, NULL, pts, NULL, c.n, png, &m, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg[0] ? err.msg : "out of memory");
    else {
        printf("triangles=%zu ", nt);
        print_silhouettes(&m);
    }
    free(pts);
    free(tri);
    sy_cloud_free(&c);
    return rc ? 2 : 0;
}

/* The scan's own returns as the asset: a regular tetrahedron of
 * circumradius r at each return (preprocessed as `sylva run` does), scored
 * against the scan by the same measure, for r = 4 mm and r = the scan's
 * median spacing (the splat radius). What an asset that drew every return
 * and nothing else would score: the measure's ceiling on that scan. */
static int returns(const char *scan)
{
    sy_error err = {0};
    sy_cloud c;
    memset(&c, 0, sizeof c);
    if (sy_read_cloud(scan, &c, &err)) return fprintf(stderr, "%s\n", err.msg), 2;
    sy_preprocess_options po = sy_preprocess_options_default();
    po.remove_ground = 1;
    po.normals = 0;
    sy_preprocess_result pr;
    double *pts = NULL, *tri = NULL;
    int rc = sy_preprocess(&c, &po, &pr, &err) || !(pts = sy_cloud_world_points(&c, &err)) ||
             !(tri = malloc(c.n * 4 * 9 * sizeof *tri));
    static const int face[4][3] = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
    static const double corner[4][3] = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
    double r = 0.004;
    for (int pass = 0; pass < 2 && !rc; pass++) {
        for (size_t i = 0; i < c.n; i++)
            for (int f = 0; f < 4; f++)
                for (int v = 0; v < 3; v++)
                    for (int k = 0; k < 3; k++)
                        tri[9 * (4 * i + (size_t)f) + 3 * (size_t)v + (size_t)k] =
                            pts[3 * i + (size_t)k] + r / sqrt(3.0) * corner[face[f][v]][k];
        sy_silhouette_metrics m;
        rc = sy_silhouette_metrics_compute(tri, 4 * c.n, NULL, pts, NULL, c.n, &m, NULL, &err);
        if (rc) break;
        printf("%sradius=%.4f iou_mean=%.3f iou_min=%.3f precision=%.3f recall=%.3f", pass ? " " : "", r, m.iou_mean,
               m.iou_min, m.precision, m.recall);
        r = m.splat_radius;
    }
    if (rc) fprintf(stderr, "%s\n", err.msg[0] ? err.msg : "out of memory");
    else printf("\n");
    free(tri);
    free(pts);
    sy_cloud_free(&c);
    return rc ? 2 : 0;
}

/* The reference asset's drawn surface every 2 cm against the asset's (as
 * `sylva eval --points REF.glb ASSET.glb`). */
static int lookglb(const char *ref, const char *asset, const char *png)
{
    sy_error err = {0};
    double *rt = NULL, *at = NULL, *pts = NULL, *pts_w = NULL;
    size_t nr = 0, na = 0, np = 0;
    sy_gltf_cutout rc_cut = {0}, ac_cut = {0};
    sy_silhouette_metrics sm;
    int rc = sy_gltf_read_surface(ref, &rt, &nr, &rc_cut, &err) || sy_gltf_read_surface(asset, &at, &na, &ac_cut, &err) ||
             !(pts = sy_drawn_surface_points(rt, nr, &rc_cut, 0.02, &np, &pts_w, &err)) ||
             silhouettes(at, na, &ac_cut, pts, pts_w, np, png, &sm, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg[0] ? err.msg : "out of memory");
    else print_silhouettes(&sm);
    sy_gltf_cutout_free(&rc_cut);
    sy_gltf_cutout_free(&ac_cut);
    free(pts);
    free(pts_w);
    free(rt);
    free(at);
    return rc ? 2 : 0;
}

int main(int argc, char **argv)
{
    sy_set_threads(1);
    if (argc >= 3 && strcmp(argv[1], "decode") == 0) return decode(argv[2], argc > 3 ? atoi(argv[3]) > 0 ? atoi(argv[3]) : 5 : 5);
    if ((argc == 4 || argc == 5) && strcmp(argv[1], "look") == 0) return look(argv[2], argv[3], argc == 5 ? argv[4] : NULL);
    if ((argc == 4 || argc == 5) && strcmp(argv[1], "lookglb") == 0) return lookglb(argv[2], argv[3], argc == 5 ? argv[4] : NULL);
    if (argc == 3 && strcmp(argv[1], "returns") == 0) return returns(argv[2]);
    if (argc == 5 && strcmp(argv[1], "compare") == 0) return compare(argv[2], strtoull(argv[3], NULL, 10), argv[4]);
    fprintf(stderr, "usage: bench_synthesize decode TREE.sylva [REPS] | look SCAN MESH.obj [PNG] | returns SCAN | lookglb REF.glb ASSET.glb [PNG] | compare SPECIES SEED TREE.sylva\n");
    return 2;
}
