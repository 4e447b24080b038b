/* Library species grown and written as .glb by the pipeline
 * (sy_tree_asset_write), then read back: the per-vertex and per-instance
 * wind attributes against the skeleton they came from (docs/wind.md), with
 * instancing on and off, the Khronos validator on both files, and
 * asset.extras, which must hold every species parameter and the seed. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "glb_read.h"
#include "pipeline/tree_asset.h"
#include "stages/grow/grow.h"

enum { INSTANCED, BAKED };

typedef struct {
    sy_species_params sp;
    sy_skeleton sk;
    sy_leaves lv;
    uint64_t seed;
    char path[2][4200];
    /* Per stem: its branch's first node, Weber-Penn order and depth in the
     * stem hierarchy (split clones are children of the stem they split from,
     * so their depth exceeds their order). */
    int32_t nb;
    int32_t *first, *rank; /* rank: the stem of each branch id */
    int32_t *ride;         /* per stem: the wind entry its vertices carry */
    int *order, *depth;
    /* The wind table holds the stems of levels 0-3, in stem order
     * (docs/wind.md): entry e is stem stem_of[e]. */
    int32_t entries, *stem_of;
} grown;

static void grow_and_write(const char *species, uint64_t seed, grown *g)
{
    memset(g, 0, sizeof *g);
    sy_error err = {0};
    assert_int_equal(sy_species_params_find(species, &g->sp, &err), SY_OK);
    g->seed = seed;
    sy_code rc = sy_grow_tree(&g->sp, seed, &g->sk, &g->lv, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
    for (int v = INSTANCED; v <= BAKED; v++) {
        sy_tree_asset_options o = sy_tree_asset_options_default();
        o.seed = seed;
        o.lods = 3;
        o.impostor_size = 64;
        o.texture_size = 64;
        o.instancing = v == INSTANCED;
        snprintf(g->path[v], sizeof g->path[v], "%s/%s_%s.glb", test_tmpdir(), species, v ? "baked" : "instanced");
        rc = sy_tree_asset_write(g->path[v], &g->sk, &g->lv, &g->sp, &o, NULL, &err);
        if (rc) fprintf(stderr, "%s\n", err.msg);
        assert_int_equal(rc, SY_OK);
    }
    /* The mesher makes one stem per branch in increasing branch id, and
     * wind entry k is stem k; ids the grower skipped have no entry. */
    const sy_skeleton *sk = &g->sk;
    int32_t ids = sy_skeleton_branch_count(sk);
    int32_t *base = malloc((size_t)ids * sizeof *base), *rank = malloc((size_t)ids * sizeof *rank);
    g->first = malloc((size_t)ids * sizeof *g->first);
    g->order = malloc((size_t)ids * sizeof *g->order);
    g->depth = malloc((size_t)ids * sizeof *g->depth);
    assert_true(base && rank && g->first && g->order && g->depth);
    for (int32_t b = 0; b < ids; b++) base[b] = -1;
    for (size_t i = 0; i < sk->n; i++) {
        int32_t p = sk->parent[i], b = sk->branch[i];
        if (p < 0 || sk->branch[p] != b) {
            assert_int_equal(base[b], -1); /* one base per branch */
            base[b] = (int32_t)i;
        }
    }
    g->nb = 0;
    for (int32_t b = 0; b < ids; b++) {
        rank[b] = g->nb;
        if (base[b] >= 0) g->first[g->nb++] = base[b];
    }
    for (int32_t k = 0; k < g->nb; k++) {
        int d = 0;
        for (int32_t n = g->first[k]; sk->parent[n] >= 0; n = base[sk->branch[sk->parent[n]]]) d++;
        g->depth[k] = d;
        g->order[k] = sk->order[g->first[k]];
    }
    /* Stems deeper than level 3 ride rigidly on their level-3 ancestor and
     * carry its entry (docs/wind.md). */
    g->ride = malloc((size_t)g->nb * sizeof *g->ride);
    g->stem_of = malloc((size_t)g->nb * sizeof *g->stem_of);
    int32_t *entry = malloc((size_t)g->nb * sizeof *entry);
    assert_true(g->ride && g->stem_of && entry);
    g->entries = 0;
    for (int32_t k = 0; k < g->nb; k++) {
        entry[k] = g->depth[k] <= 3 ? g->entries : -1;
        if (g->depth[k] <= 3) g->stem_of[g->entries++] = k;
    }
    for (int32_t k = 0; k < g->nb; k++) {
        int32_t a = k;
        while (g->depth[a] > 3) a = rank[sk->branch[sk->parent[g->first[a]]]];
        g->ride[k] = entry[a];
    }
    free(entry);
    g->rank = rank;
    free(base);
}

static void grown_free(grown *g)
{
    sy_species_params_free(&g->sp);
    sy_skeleton_free(&g->sk);
    sy_leaves_free(&g->lv);
    free(g->first), free(g->rank), free(g->ride), free(g->order), free(g->depth), free(g->stem_of);
}

static const float *float_accessor(const sy_gltf_file *f, int acc, size_t n, int components)
{
    assert_true(acc >= 0);
    char p[64], s[16];
    static const char *types[] = {"", "SCALAR", "VEC2", "VEC3", "VEC4"};
    snprintf(p, sizeof p, "/accessors/%d/type", acc);
    assert_string_equal(sy_gltf_string(f, p, s, sizeof s), types[components]);
    assert_int_equal((int)glb_num(f, "/accessors/%d/componentType", acc), 5126);
    size_t count, stride;
    const float *d = (const float *)glb_accessor(f, acc, &count, &stride);
    assert_int_equal(count, n);
    assert_true(stride == 0 || stride == 4 * (size_t)components);
    return d;
}

/* One element's wind (branch index, anchor, level, stiffness) against the
 * table in the file and the skeleton: the anchor is the branch's base (its
 * attachment node on the parent: at most one parent segment from its first
 * node), the level its depth in the stem hierarchy capped at 3, which is its
 * Weber-Penn order when the species makes no split clones. */
static void check_element(const grown *g, const sy_gltf_file *f, int root, unsigned b, const float anchor[3],
                          const float ls[2], int no_clones)
{
    assert_true((int32_t)b < g->entries);
    int32_t k = g->stem_of[b];
    for (int c = 0; c < 3; c++)
        assert_true(anchor[c] == (float)glb_num(f, "/nodes/%d/extras/sylva_wind/anchor/%u", root, 3 * b + (unsigned)c));
    int level = (int)glb_num(f, "/nodes/%d/extras/sylva_wind/level/%u", root, b);
    assert_true(ls[0] == (float)level);
    assert_true(ls[1] == (float)glb_num(f, "/nodes/%d/extras/sylva_wind/stiffness/%u", root, b));
    assert_true(ls[1] >= 0 && ls[1] <= 1);
    assert_int_equal(level, g->depth[k] < 3 ? g->depth[k] : 3);
    if (no_clones) assert_int_equal(level, g->order[k]);
    const sy_skeleton *sk = &g->sk;
    int32_t n = g->first[k], p = sk->parent[n] >= 0 ? sk->parent[n] : n;
    const float *base = sk->pos + 3 * n, *par = sk->pos + 3 * p;
    /* glTF (x, y, z) is Sylva's (x, -z, y). */
    float zup[3] = {anchor[0], -anchor[2], anchor[1]};
    float seg = 0, off = 0;
    for (int c = 0; c < 3; c++) {
        seg += (base[c] - par[c]) * (base[c] - par[c]);
        off += (zup[c] - base[c]) * (zup[c] - base[c]);
    }
    /* The mesher attaches a child where the parent's drawn axis passes
     * nearest its first node (docs/mesh.md), which can lie off the parent's
     * polyline by up to the parent's radius; then slides it along the
     * parent until its ring lands on the tube, clear of its siblings
     * (fit_on_parent, stems.c): off an end by at most R cot 25 degrees plus
     * 1.25 r / sin 25 degrees, past siblings by at most three times that
     * half-length (r as drawn: at least the mesher's minimum radius). */
    float r = fmaxf(sk->radius[n], sy_mesh_options_default().min_radius), slide = 2.2f * sk->radius[p] + 12 * r;
    assert_true(sqrtf(off) <= sqrtf(seg) + sk->radius[p] + slide + 1e-4f);
}

/* Every mesh with _WIND_BRANCH: the two table-free attributes beside it,
 * POSITION's count each, holding its branch's values; returns how many. */
static int check_mesh_wind(const grown *g, const sy_gltf_file *f, int root, int no_clones)
{
    int with_wind = 0;
    for (int m = 0; m < sy_gltf_size(f, "/meshes"); m++) {
        const char *attrs = "/meshes/%d/primitives/0/attributes/%s";
        int wb = (int)glb_num(f, attrs, m, "_WIND_BRANCH");
        if (wb < 0) {
            assert_false(glb_has(f, attrs, m, "_WIND_ANCHOR"));
            continue;
        }
        with_wind++;
        size_t n = (size_t)glb_num(f, "/accessors/%d/count", (int)glb_num(f, attrs, m, "POSITION")), count, stride;
        const unsigned char *br = glb_accessor(f, wb, &count, &stride);
        assert_int_equal(count, n);
        assert_int_equal(stride, 4);
        const float *an = float_accessor(f, (int)glb_num(f, attrs, m, "_WIND_ANCHOR"), n, 3);
        const float *ls = float_accessor(f, (int)glb_num(f, attrs, m, "_WIND_LEVEL_STIFFNESS"), n, 2);
        for (size_t i = 0; i < n; i++) {
            uint16_t b;
            memcpy(&b, br + 4 * i, sizeof b);
            check_element(g, f, root, b, an + 3 * i, ls + 2 * i, no_clones);
        }
    }
    return with_wind;
}

/* Whether some leaf based at translation t (glTF frame) hangs on a branch
 * that carries wind entry b (a split node can carry leaves of two stems). */
static int leaf_on(const grown *g, const float t[3], unsigned b)
{
    const sy_leaves *lv = &g->lv;
    int found = 0;
    for (size_t l = 0; l < lv->n; l++) {
        const float *p = lv->pos + 3 * l;
        if (p[0] == t[0] && p[2] == t[1] && -p[1] == t[2]) found |= (unsigned)g->ride[g->rank[g->sk.branch[lv->node[l]]]] == b;
    }
    return found;
}

/* Instance nodes: the four wind attributes per instance next to TRANSLATION,
 * and each instance follows the branch its leaf hangs on. */
static int check_instance_wind(const grown *g, const sy_gltf_file *f, int root, int no_clones)
{
    int sets = 0;
    for (int node = 0; node < sy_gltf_size(f, "/nodes"); node++) {
        const char *ext = "/nodes/%d/extensions/EXT_mesh_gpu_instancing/attributes/%s";
        int tr = (int)glb_num(f, ext, node, "TRANSLATION");
        if (tr < 0) continue;
        sets++;
        size_t n = (size_t)glb_num(f, "/accessors/%d/count", tr);
        const float *t = float_accessor(f, tr, n, 3);
        const float *br = float_accessor(f, (int)glb_num(f, ext, node, "_WIND_BRANCH"), n, 1);
        const float *w = float_accessor(f, (int)glb_num(f, ext, node, "_WIND_W"), n, 4);
        const float *an = float_accessor(f, (int)glb_num(f, ext, node, "_WIND_ANCHOR"), n, 3);
        const float *ls = float_accessor(f, (int)glb_num(f, ext, node, "_WIND_LEVEL_STIFFNESS"), n, 2);
        size_t moved = 0;
        for (size_t i = 0; i < n; i++) {
            unsigned b = (unsigned)br[i];
            assert_true(br[i] == (float)b);
            check_element(g, f, root, b, an + 3 * i, ls + 2 * i, no_clones);
            /* A leaf whose twig LOD0's budget leaves out hangs on the
             * nearest drawn ancestor instead (docs/mesh.md); the rest sit
             * exactly where grown, on the branch whose wind they follow. */
            moved += !leaf_on(g, t + 3 * i, b);
            for (int k = 0; k < 4; k++) assert_true(w[4 * i + k] >= 0 && w[4 * i + k] <= 1);
        }
        assert_true(moved < n); /* the mesh-quality test checks where the moved ones hang */
    }
    return sets;
}

static void validate(const grown *g)
{
    char module[4200], cmd[10000];
    snprintf(module, sizeof module, "%s/node_modules/gltf-validator/package.json", SYLVA_SOURCE_DIR);
    if (!file_exists(module)) fail_msg("gltf-validator is not installed (%s missing): run scripts/install-deps.sh", module);
    snprintf(cmd, sizeof cmd, "node '%s/tests/gltf_validate.mjs' '%s' '%s'", SYLVA_SOURCE_DIR, g->path[INSTANCED],
             g->path[BAKED]);
    fflush(stdout);
    assert_int_equal(system(cmd), 0);
}

static void check_wind(grown *gp, int no_clones)
{
    grown g = *gp;
    int clones = 0;
    for (int32_t b = 0; b < g.nb; b++) clones += g.depth[b] != g.order[b];
    assert_true(no_clones ? clones == 0 : clones > 0);
    for (int v = INSTANCED; v <= BAKED; v++) {
        sy_gltf_file *f = NULL;
        sy_error err = {0};
        assert_int_equal(sy_gltf_open(g.path[v], &f, &err), SY_OK);
        int root = (int)glb_num(f, "/scenes/0/nodes/0");
        assert_int_equal((int)glb_num(f, "/nodes/%d/extras/sylva_wind/count", root), g.entries);
        int meshes = check_mesh_wind(&g, f, root, no_clones), sets = check_instance_wind(&g, f, root, no_clones);
        /* Bark in each of the 3 mesh levels; leaves as instance sets, or as
         * baked meshes carrying the same attributes per vertex. */
        if (v == INSTANCED) {
            assert_int_equal(meshes, 3);
            assert_int_equal(sets, 3);
        } else {
            assert_int_equal(meshes, 6);
            assert_int_equal(sets, 0);
        }
        sy_gltf_close(f);
    }
    validate(&g);
}

/* asset.extras.parameters written back as a species file (each section's
 * keys as "Key = value") into a memstream; returns the text. */
static char *extras_as_ini(const sy_gltf_file *f, size_t *len, int *keys)
{
    char *ini = NULL;
    FILE *fp = open_memstream(&ini, len);
    assert_non_null(fp);
    const char *params = "/asset/extras/parameters";
    for (int si = 0; si < sy_gltf_size(f, params); si++) {
        char sec[32], sp[96], key[64], vp[160], str[4096];
        sy_gltf_key(f, params, si, sec, sizeof sec);
        fprintf(fp, "[%s]\n", sec);
        snprintf(sp, sizeof sp, "%s/%s", params, sec);
        keys[si] = sy_gltf_size(f, sp);
        for (int ki = 0; ki < keys[si]; ki++) {
            sy_gltf_key(f, sp, ki, key, sizeof key);
            snprintf(vp, sizeof vp, "%s/%s", sp, key);
            if (sy_gltf_size(f, vp) == 3)
                fprintf(fp, "%s = {%.9g, %.9g, %.9g}\n", key, glb_num(f, "%s/0", vp), glb_num(f, "%s/1", vp),
                        glb_num(f, "%s/2", vp));
            else if (sy_gltf_string(f, vp, str, sizeof str)[0])
                fprintf(fp, "%s = %s\n", key, str);
            else
                fprintf(fp, "%s = %.17g\n", key, sy_gltf_number(f, vp, NAN));
        }
    }
    fclose(fp);
    return ini;
}

/* The parameters in the file parse back to the species the tree was grown
 * from (every number bit-identical), and the species plus the seed in the
 * file grow the identical skeleton. Floats are written in their shortest
 * form. */
static void extras_regrow_the_same_tree(void **state)
{
    grown *g = *state;
    sy_gltf_file *f = NULL;
    sy_error err = {0};
    assert_int_equal(sy_gltf_open(g->path[INSTANCED], &f, &err), SY_OK);
    char name[64];
    assert_string_equal(sy_gltf_string(f, "/asset/extras/species", name, sizeof name), g->sp.name);
    assert_true(glb_num(f, "/asset/extras/seed") == (double)g->seed);
    /* Every key of every section: [General] 29 (32 less recLevels, an alias
     * of Levels, and the unset thesis strings Material, MaterialNormal),
     * [ParamLevel0] 17, deeper levels 16 (BaseSplits is a trunk key),
     * [Sylva] 9 (sassafras names both textures and its bark colour; twigs). */
    const int want[6] = {29, 17, 16, 16, 16, 9};
    int keys[6] = {0};
    assert_int_equal(sy_gltf_size(f, "/asset/extras/parameters"), 6);
    size_t len;
    char *ini = extras_as_ini(f, &len, keys);
    for (int k = 0; k < 6; k++) assert_int_equal(keys[k], want[k]);
    char tex[256];
    assert_string_equal(sy_gltf_string(f, "/asset/extras/parameters/Sylva/bark", tex, sizeof tex), "textures/bark.png");
    sy_gltf_close(f);

    sy_species_params sp;
    sy_code rc = sy_species_params_parse(ini, len, "extras.ini", SYLVA_SPECIES_DIR, &sp, &err);
    if (rc) fprintf(stderr, "%s\n%s", err.msg, ini);
    assert_int_equal(rc, SY_OK);
    free(ini);
    assert_string_equal(sp.name, g->sp.name);
    assert_string_equal(sp.bark_texture, g->sp.bark_texture);
    assert_string_equal(sp.leaf_texture, g->sp.leaf_texture);
    /* Numbers: the structs match byte for byte once the strings are set
     * aside (both start from sy_species_params_default' zeroed struct). */
    sy_species_params a = g->sp, b = sp;
    a.name = a.bark_texture = a.leaf_texture = a.material = a.material_normal = NULL;
    b.name = b.bark_texture = b.leaf_texture = b.material = b.material_normal = NULL;
    assert_memory_equal(&a, &b, sizeof a);

    sy_skeleton sk;
    assert_int_equal(sy_grow_tree(&sp, g->seed, &sk, NULL, &err), SY_OK);
    assert_int_equal(sk.n, g->sk.n);
    assert_memory_equal(sk.pos, g->sk.pos, 3 * sk.n * sizeof(float));
    assert_memory_equal(sk.radius, g->sk.radius, sk.n * sizeof(float));
    assert_memory_equal(sk.parent, g->sk.parent, sk.n * sizeof(int32_t));
    sy_skeleton_free(&sk);
    sy_species_params_free(&sp);
}

/* Significant digits of the number text [from, to): no sign, no leading or
 * trailing zeros, no exponent. */
static size_t sig_digits(const char *from, const char *to)
{
    const char *e = from;
    while (e < to && *e != 'e' && *e != 'E') e++;
    while (from < e && (*from == '-' || *from == '0' || *from == '.')) from++;
    while (e > from && (e[-1] == '0' || e[-1] == '.')) e--;
    size_t n = 0;
    for (const char *d = from; d < e; d++) n += *d >= '0' && *d <= '9';
    return n;
}

/* The parameters' numbers in the JSON text: each the shortest decimal of
 * its float (0.05, never 0.05000000074505806). */
static void extras_print_floats_shortest(void **state)
{
    grown *g = *state;
    FILE *fp = fopen(g->path[INSTANCED], "rb");
    assert_non_null(fp);
    unsigned char head[20];
    assert_int_equal(fread(head, 1, 20, fp), 20);
    uint32_t n = (uint32_t)head[12] | (uint32_t)head[13] << 8 | (uint32_t)head[14] << 16 | (uint32_t)head[15] << 24;
    char *text = calloc(n + 1, 1);
    assert_non_null(text);
    assert_int_equal(fread(text, 1, n, fp), n);
    fclose(fp);
    const char *p = strstr(text, "\"parameters\"");
    assert_non_null(p);
    assert_non_null(strstr(p, "\"LobeDepth\":0.05,"));
    /* The parameters object ends at its matching brace (no strings in it
     * hold braces). */
    const char *open = strchr(p, '{'), *close = open;
    for (int depth = 0; *close; close++) {
        depth += *close == '{' ? 1 : *close == '}' ? -1 : 0;
        if (depth == 0) break;
    }
    int numbers = 0;
    for (const char *c = open; c < close; c++) {
        if (!(c[0] == ':' || c[0] == ',' || c[0] == '[') || !(c[1] == '-' || (c[1] >= '0' && c[1] <= '9'))) continue;
        char *end;
        double v = strtod(c + 1, &end);
        char shortest[32];
        for (int digits = 1; digits <= 9; digits++) {
            snprintf(shortest, sizeof shortest, "%.*g", digits, v);
            if ((float)strtod(shortest, NULL) == (float)v) break;
        }
        if (sig_digits(c + 1, end) > sig_digits(shortest, shortest + strlen(shortest)))
            fail_msg("parameter number %.*s is longer than its float's shortest form %s", (int)(end - c - 1), c + 1,
                     shortest);
        numbers++;
    }
    assert_true(numbers >= 29 + 17 + 3 * 16 + 3);
    free(text);
}

static int grow_sassafras(void **state)
{
    static grown g;
    grow_and_write("sassafras", 3, &g);
    *state = &g;
    return 0;
}

static int free_sassafras(void **state)
{
    grown_free(*state);
    return 0;
}

/* Sassafras: four stem levels and no splits, so level = order everywhere. */
static void wind_attributes_follow_the_skeleton(void **state)
{
    check_wind(*state, 1);
}

/* European pine splits its stems: clones sway as children of their stem. */
static void split_clones_sway_as_children(void **state)
{
    (void)state;
    grown g;
    grow_and_write("european_pine", 3, &g);
    /* Its clones reach below level 3: those stems have no entry of their own. */
    assert_true(g.entries < g.nb);
    check_wind(&g, 0);
    grown_free(&g);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(wind_attributes_follow_the_skeleton),
        cmocka_unit_test(split_clones_sway_as_children),
        cmocka_unit_test(extras_regrow_the_same_tree),
        cmocka_unit_test(extras_print_floats_shortest),
    };
    /* One sassafras (the group state) serves every test but the pine's. */
    return cmocka_run_group_tests(tests, grow_sassafras, free_sassafras);
}
