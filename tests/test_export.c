/* glTF export: a small tree built in code (tapered tube trunk, instanced leaf
 * cards, 3 mesh LODs + an impostor level) exported with meshopt on/off and
 * instancing on/off, checked by the Khronos validator and by reading the GLB
 * back (JSON via the shim, binary data decoded here). */
#include "testutil.h"

#include <math.h>
#include <meshoptimizer.h>
#include <stb_image_write.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "stages/core/fileio.h"
#include "stages/export/export.h"
#include "stages/gltf/gltf_read.h"
#include "glb_read.h"

#define N_LEAVES 50
#define PI 3.14159265358979323846
#define TRUNK_H 2.0f
enum { V_PLAIN, V_MESHOPT, V_BAKED, V_BAKED_MESHOPT, N_VARIANTS };
/* The pipeline's way to a file: export to bytes, then write atomically. */
static sy_code export_file(const char *path, const sy_asset *a, const sy_export_options *opt, size_t *bytes,
                           sy_error *err)
{
    unsigned char *glb = NULL;
    size_t size = 0;
    sy_code rc = sy_export_glb(a, opt, path, &glb, &size, err);
    if (!rc) rc = sy_write_file_atomic(path, glb, size, err);
    if (bytes) *bytes = rc ? 0 : size;
    free(glb);
    return rc;
}

static const char *variant_name[N_VARIANTS] = {"tree.glb", "tree_meshopt.glb", "tree_baked.glb",
                                               "tree_baked_meshopt.glb"};
static const int variant_meshopt[N_VARIANTS] = {0, 1, 0, 1};
static const int variant_instancing[N_VARIANTS] = {1, 1, 0, 0};

static sy_asset tree;
static char out_dir[4096];

/* ------------------------------------------------------------ the asset */

typedef struct {
    unsigned char *data;
    size_t size;
} png_buf;

static void png_sink(void *ctx, void *data, int size)
{
    png_buf *b = ctx;
    unsigned char *grown = realloc(b->data, b->size + (size_t)size);
    assert_non_null(grown);
    memcpy(grown + b->size, data, (size_t)size);
    b->data = grown;
    b->size += (size_t)size;
}

/* An 8x8 PNG with a per-image pattern; comp 3 or 4. */
static int add_png(sy_asset *a, const char *name, int comp, unsigned char seed)
{
    unsigned char px[8 * 8 * 4];
    for (int i = 0; i < 64; i++)
        for (int c = 0; c < comp; c++) px[i * comp + c] = (unsigned char)(seed * (c + 1) + i * 3);
    if (comp == 4)
        for (int i = 0; i < 64; i++) px[i * 4 + 3] = (i % 8 >= 1 && i % 8 <= 3 && i / 8 < 5) ? 255 : 0; /* no symmetry */
    png_buf b = {NULL, 0};
    assert_true(stbi_write_png_to_func(png_sink, &b, 8, 8, comp, px, 8 * comp));
    sy_image img = {b.data, b.size, ""};
    snprintf(img.name, sizeof img.name, "%s", name);
    sy_error err = {0};
    int idx = sy_asset_add_image(a, &img, &err);
    assert_true(idx >= 0);
    return idx;
}

/* A tube of `around` x `along` quads tapering from r0 to r1 over TRUNK_H,
 * with a duplicated seam column for the uv wrap. */
static int add_tube(sy_asset *a, const char *name, int around, int along, int material, int with_tangents)
{
    sy_mesh m;
    memset(&m, 0, sizeof m);
    snprintf(m.name, sizeof m.name, "%s", name);
    size_t cols = (size_t)around + 1, rows = (size_t)along + 1, n = cols * rows;
    m.n_vertices = n;
    m.position = calloc(3 * n, sizeof(float));
    m.normal = calloc(3 * n, sizeof(float));
    m.uv = calloc(2 * n, sizeof(float));
    m.wind_w = calloc(4 * n, sizeof(float));
    m.wind_branch = calloc(n, sizeof(uint16_t));
    if (with_tangents) m.tangent = calloc(4 * n, sizeof(float));
    for (size_t j = 0; j < rows; j++)
        for (size_t k = 0; k < cols; k++) {
            size_t v = j * cols + k;
            double ang = 2 * PI * (double)k / around, t = (double)j / along;
            double r = 0.15 - 0.10 * t;
            m.position[3 * v + 0] = (float)(r * cos(ang));
            m.position[3 * v + 1] = (float)(t * TRUNK_H);
            m.position[3 * v + 2] = (float)(r * sin(ang));
            m.normal[3 * v + 0] = (float)cos(ang);
            m.normal[3 * v + 2] = (float)sin(ang);
            m.uv[2 * v + 0] = (float)k / around;
            m.uv[2 * v + 1] = (float)(2 * t);
            if (with_tangents) {
                m.tangent[4 * v + 0] = (float)-sin(ang);
                m.tangent[4 * v + 2] = (float)cos(ang);
                m.tangent[4 * v + 3] = 1.0f;
            }
            m.wind_w[4 * v + 0] = (float)t;
            m.wind_branch[v] = 0;
        }
    m.n_indices = (size_t)around * along * 6;
    m.indices = calloc(m.n_indices, sizeof(uint32_t));
    size_t q = 0;
    for (size_t j = 0; j < (size_t)along; j++)
        for (size_t k = 0; k < (size_t)around; k++) {
            uint32_t A = (uint32_t)(j * cols + k), B = A + 1, C = A + (uint32_t)cols, D = C + 1;
            uint32_t tri[6] = {A, C, D, A, D, B};
            memcpy(m.indices + q, tri, sizeof tri);
            q += 6;
        }
    m.material = material;
    sy_error err = {0};
    int idx = sy_asset_add_mesh(a, &m, &err);
    assert_true(idx >= 0);
    return idx;
}

static const float leaf_pos[4][3] = {{-0.05f, 0, 0}, {0.05f, 0, 0}, {0.05f, 0.15f, 0}, {-0.05f, 0.15f, 0}};

static int add_leaf_card(sy_asset *a, int material)
{
    sy_mesh m;
    memset(&m, 0, sizeof m);
    snprintf(m.name, sizeof m.name, "leaf_card");
    m.n_vertices = 4;
    m.position = malloc(sizeof leaf_pos);
    memcpy(m.position, leaf_pos, sizeof leaf_pos);
    m.normal = calloc(12, sizeof(float));
    m.tangent = calloc(16, sizeof(float));
    m.uv = calloc(8, sizeof(float));
    m.wind_w = calloc(16, sizeof(float));
    m.wind_branch = calloc(4, sizeof(uint16_t));
    static const float uv[8] = {0, 1, 1, 1, 1, 0, 0, 0};
    memcpy(m.uv, uv, sizeof uv);
    for (int v = 0; v < 4; v++) {
        m.normal[3 * v + 2] = 1;
        m.tangent[4 * v + 0] = 1;
        m.tangent[4 * v + 3] = 1;
        m.wind_w[4 * v + 0] = 0.9f;
        m.wind_w[4 * v + 1] = 0.5f;
        m.wind_branch[v] = 1;
    }
    m.n_indices = 6;
    m.indices = malloc(6 * sizeof(uint32_t));
    static const uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
    memcpy(m.indices, idx, sizeof idx);
    m.material = material;
    sy_error err = {0};
    int i = sy_asset_add_mesh(a, &m, &err);
    assert_true(i >= 0);
    return i;
}

/* Two crossed vertical quads: the impostor level (no tangents, no wind). */
static int add_impostor(sy_asset *a, int material)
{
    sy_mesh m;
    memset(&m, 0, sizeof m);
    snprintf(m.name, sizeof m.name, "impostor");
    m.n_vertices = 8;
    m.position = calloc(24, sizeof(float));
    m.normal = calloc(24, sizeof(float));
    m.uv = calloc(16, sizeof(float));
    static const float corner[4][2] = {{-1, 0}, {1, 0}, {1, 1}, {-1, 1}};
    static const float cuv[4][2] = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
    for (int card = 0; card < 2; card++)
        for (int c = 0; c < 4; c++) {
            int v = card * 4 + c;
            m.position[3 * v + (card ? 2 : 0)] = corner[c][0] * 0.8f;
            m.position[3 * v + 1] = corner[c][1] * 2.6f;
            m.normal[3 * v + (card ? 0 : 2)] = 1;
            m.uv[2 * v] = cuv[c][0];
            m.uv[2 * v + 1] = cuv[c][1];
        }
    m.n_indices = 12;
    m.indices = malloc(12 * sizeof(uint32_t));
    static const uint32_t idx[12] = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
    memcpy(m.indices, idx, sizeof idx);
    m.material = material;
    sy_error err = {0};
    int i = sy_asset_add_mesh(a, &m, &err);
    assert_true(i >= 0);
    return i;
}

/* n leaves on a spiral around the crown, rotated about Y, slightly scaled. */
static sy_instances leaves(int mesh, size_t n, float size)
{
    sy_instances in = {mesh, n, calloc(3 * n, sizeof(float)), calloc(4 * n, sizeof(float)),
                       calloc(3 * n, sizeof(float)), NULL, NULL};
    for (size_t i = 0; i < n; i++) {
        double t = (double)i / n, ang = 2.4 * i;
        in.translation[3 * i + 0] = (float)(0.6 * cos(ang));
        in.translation[3 * i + 1] = (float)(1.2 + 0.8 * t);
        in.translation[3 * i + 2] = (float)(0.6 * sin(ang));
        in.rotation[4 * i + 1] = (float)sin(ang / 2);
        in.rotation[4 * i + 3] = (float)cos(ang / 2);
        in.scale[3 * i + 0] = size;
        in.scale[3 * i + 1] = size * (1.0f + 0.2f * (float)(i % 3));
        in.scale[3 * i + 2] = size;
    }
    return in;
}

static void build_tree(sy_asset *a)
{
    memset(a, 0, sizeof *a);
    snprintf(a->name, sizeof a->name, "test_oak");
    sy_error err = {0};
    int bark_c = add_png(a, "bark_color", 3, 40), bark_n = add_png(a, "bark_normal", 3, 128);
    int leaf_c = add_png(a, "leaf_color", 4, 90), leaf_n = add_png(a, "leaf_normal", 3, 130);
    int leaf_t = add_png(a, "leaf_transmission", 4, 60), imp_c = add_png(a, "impostor_color", 4, 20);

    sy_material bark = sy_material_default("bark");
    bark.base_color_image = bark_c;
    bark.normal_image = bark_n;
    sy_material leaf = sy_material_default("leaf");
    leaf.base_color_image = leaf_c;
    leaf.normal_image = leaf_n;
    leaf.alpha_mode = SY_ALPHA_MASK;
    leaf.alpha_cutoff = 0.4f;
    leaf.double_sided = 1;
    leaf.diffuse_transmission = 0.3f;
    leaf.diffuse_transmission_color[0] = 0.6f;
    leaf.diffuse_transmission_color[1] = 0.8f;
    leaf.diffuse_transmission_color[2] = 0.2f;
    leaf.diffuse_transmission_image = leaf_t;
    for (int c = 0; c < 3; c++) leaf.emissive[c] = 0.09f; /* the fallback glow for engines without transmission */
    sy_material imp = sy_material_default("impostor");
    imp.base_color_image = imp_c;
    imp.alpha_mode = SY_ALPHA_MASK;
    imp.double_sided = 1;
    int m_bark = sy_asset_add_material(a, &bark, &err), m_leaf = sy_asset_add_material(a, &leaf, &err);
    int m_imp = sy_asset_add_material(a, &imp, &err);

    int trunk0 = add_tube(a, "trunk_lod0", 32, 64, m_bark, 1);
    int trunk1 = add_tube(a, "trunk_lod1", 12, 16, m_bark, 1);
    int trunk2 = add_tube(a, "trunk_lod2", 6, 4, m_bark, 0); /* tangents generated on export */
    int card = add_leaf_card(a, m_leaf);
    int impostor = add_impostor(a, m_imp);

    const float coverage[4] = {0.5f, 0.2f, 0.05f, 0.01f};
    const size_t n_leaves[3] = {N_LEAVES, 25, 10};
    const int trunks[3] = {trunk0, trunk1, trunk2};
    for (int l = 0; l < 4; l++) {
        sy_lod lod;
        memset(&lod, 0, sizeof lod);
        lod.screen_coverage = coverage[l];
        lod.n_meshes = 1;
        lod.meshes[0] = l < 3 ? trunks[l] : impostor;
        if (l < 3) {
            lod.n_instances = 1;
            lod.instances[0] = leaves(card, n_leaves[l], 1.0f + 0.5f * (float)l);
        }
        assert_true(sy_asset_add_lod(a, &lod, &err) >= 0);
    }
    a->n_wind = 2;
    a->wind = calloc(2, sizeof *a->wind);
    a->wind[0] = (sy_wind_branch){-1, 0, {0, 0, 0}, {0, 1, 0}, 2.0f, 0.4f, 0.1f, 1.6f, 0.9f};
    a->wind[1] = (sy_wind_branch){0, 1, {0, 1.2f, 0}, {0.6f, 0.8f, 0}, 0.9f, 0.7f, 0.2f, 2.7f, 0.4f};
    a->extras_json = strdup("{\"species\":\"Quercus robur\",\"parameters\":{\"seed\":7,\"leaf_area\":0.012}}");
}

static int setup(void **state)
{
    (void)state;
    build_tree(&tree);
    snprintf(out_dir, sizeof out_dir, "%s", tmp_path("variants"));
    if (mkdir(out_dir, 0755) != 0) return -1;
    for (int v = 0; v < N_VARIANTS; v++) {
        sy_export_options opt = sy_export_options_default();
        opt.meshopt = variant_meshopt[v];
        opt.instancing = variant_instancing[v];
        char path[4200];
        snprintf(path, sizeof path, "%s/%s", out_dir, variant_name[v]);
        sy_error err = {0};
        size_t bytes = 0;
        if (export_file(path, &tree, &opt, &bytes, &err) != SY_OK) {
            fprintf(stderr, "export %s failed: %s\n", path, err.msg);
            return -1;
        }
        printf("# %-24s %7zu bytes (meshopt=%d instancing=%d)\n", variant_name[v], bytes,
               opt.meshopt, opt.instancing);
    }
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    sy_asset_free(&tree);
    return 0;
}

/* ------------------------------------------------------------ read-back */

static const char *variant_path(int v)
{
    static char path[4200];
    snprintf(path, sizeof path, "%s/%s", out_dir, variant_name[v]);
    return path;
}

static sy_gltf_file *open_variant(int v)
{
    sy_gltf_file *f = NULL;
    sy_error err = {0};
    assert_int_equal(sy_gltf_open(variant_path(v), &f, &err), SY_OK);
    return f;
}

static int string_in_array(const sy_gltf_file *f, const char *array, const char *value)
{
    char p[128], s[128];
    for (int i = 0; i < sy_gltf_size(f, array); i++) {
        snprintf(p, sizeof p, "%s/%d", array, i);
        if (strcmp(sy_gltf_string(f, p, s, sizeof s), value) == 0) return 1;
    }
    return 0;
}

/* Index of the mesh named name, or -1. */
static int mesh_named(const sy_gltf_file *f, const char *name)
{
    char p[64], s[64];
    for (int i = 0; i < sy_gltf_size(f, "/meshes"); i++) {
        snprintf(p, sizeof p, "/meshes/%d/name", i);
        if (strcmp(sy_gltf_string(f, p, s, sizeof s), name) == 0) return i;
    }
    return -1;
}

static int attribute(const sy_gltf_file *f, int mesh, const char *name)
{
    return (int)glb_num(f, "/meshes/%d/primitives/0/attributes/%s", mesh, name);
}

/* Node index of the LOD0 group's child whose name ends with suffix. */
static int lod0_child(const sy_gltf_file *f, const char *suffix)
{
    int root = (int)glb_num(f, "/scenes/0/nodes/0");
    char p[64], s[128];
    for (int c = 0;; c++) {
        snprintf(p, sizeof p, "/nodes/%d/children/%d", root, c);
        if (!sy_gltf_has(f, p)) break;
        int child = (int)sy_gltf_number(f, p, -1);
        snprintf(p, sizeof p, "/nodes/%d/name", child);
        sy_gltf_string(f, p, s, sizeof s);
        size_t ls = strlen(s), lx = strlen(suffix);
        if (ls >= lx && strcmp(s + ls - lx, suffix) == 0) return child;
    }
    return -1;
}

/* ----------------------------------------------------------------- tests */

static void khronos_validator_reports_no_errors_or_warnings(void **state)
{
    (void)state;
    char module[4200];
    snprintf(module, sizeof module, "%s/node_modules/gltf-validator/package.json", SYLVA_SOURCE_DIR);
    if (!file_exists(module))
        fail_msg("gltf-validator is not installed (%s missing): run scripts/install-deps.sh (npm ci)", module);
    char cmd[8192];
    int n = snprintf(cmd, sizeof cmd, "node '%s/tests/gltf_validate.mjs'", SYLVA_SOURCE_DIR);
    for (int v = 0; v < N_VARIANTS; v++) n += snprintf(cmd + n, sizeof cmd - (size_t)n, " '%s'", variant_path(v));
    fflush(stdout);
    int rc = system(cmd);
    assert_int_equal(rc, 0);
}

static void header_generator_and_extras(void **state)
{
    (void)state;
    sy_gltf_file *f = open_variant(V_PLAIN);
    char s[128];
    assert_string_equal(sy_gltf_string(f, "/asset/version", s, sizeof s), "2.0");
    assert_string_equal(sy_gltf_string(f, "/asset/generator", s, sizeof s), "Sylva " SYLVA_VERSION);
    assert_string_equal(sy_gltf_string(f, "/asset/extras/species", s, sizeof s), "Quercus robur");
    assert_int_equal((int)sy_gltf_number(f, "/asset/extras/parameters/seed", 0), 7);
    assert_float_equal(sy_gltf_number(f, "/asset/extras/parameters/leaf_area", 0), 0.012, 1e-12);
    assert_int_equal(sy_gltf_size(f, "/buffers"), 1);
    assert_false(sy_gltf_has(f, "/buffers/0/uri"));
    sy_error lerr = {0};
    if (sy_gltf_tinygltf_check(variant_path(V_PLAIN), &lerr)) fail_msg("tinygltf cannot load: %s", lerr.msg);
    assert_int_equal(sy_gltf_tinygltf_check(variant_path(V_BAKED), &lerr), SY_OK);
    sy_gltf_close(f);
}

static void images_are_png_buffer_views(void **state)
{
    (void)state;
    for (int v = 0; v < N_VARIANTS; v++) {
        sy_gltf_file *f = open_variant(v);
        size_t bin_size;
        const unsigned char *bin = sy_gltf_bin(f, &bin_size);
        assert_int_equal(sy_gltf_size(f, "/images"), 6);
        for (int i = 0; i < 6; i++) {
            char s[64];
            assert_false(glb_has(f, "/images/%d/uri", i));
            char p[64];
            snprintf(p, sizeof p, "/images/%d/mimeType", i);
            assert_string_equal(sy_gltf_string(f, p, s, sizeof s), "image/png");
            int view = (int)glb_num(f, "/images/%d/bufferView", i);
            assert_int_equal((int)glb_num(f, "/bufferViews/%d/buffer", view), 0);
            assert_false(glb_has(f, "/bufferViews/%d/byteStride", view));
            snprintf(p, sizeof p, "/images/%d/name", i);
            sy_gltf_string(f, p, s, sizeof s);
            const sy_image *src = NULL;
            for (size_t k = 0; k < tree.n_images; k++)
                if (strcmp(tree.images[k].name, s) == 0) src = &tree.images[k];
            assert_non_null(src);
            snprintf(p, sizeof p, "/bufferViews/%d/byteOffset", view);
            size_t off = (size_t)sy_gltf_number(f, p, 0), len = (size_t)glb_num(f, "/bufferViews/%d/byteLength", view);
            assert_int_equal(len, src->size);
            assert_true(off + len <= bin_size);
            assert_memory_equal(bin + off, src->png, len);
        }
        sy_gltf_close(f);
    }
}

static void buffer_views_are_aligned_and_strided(void **state)
{
    (void)state;
    for (int v = 0; v < N_VARIANTS; v++) {
        sy_gltf_file *f = open_variant(v);
        char p[96];
        for (int i = 0; i < sy_gltf_size(f, "/bufferViews"); i++) {
            snprintf(p, sizeof p, "/bufferViews/%d/byteOffset", i);
            assert_int_equal((long)sy_gltf_number(f, p, 0) % 4, 0);
            snprintf(p, sizeof p, "/bufferViews/%d/extensions/EXT_meshopt_compression/byteOffset", i);
            assert_int_equal((long)sy_gltf_number(f, p, 0) % 4, 0);
            if (glb_num(f, "/bufferViews/%d/target", i) == 34962) {
                double stride = glb_num(f, "/bufferViews/%d/byteStride", i);
                assert_true(stride >= 4 && fmod(stride, 4) == 0);
            }
        }
        sy_gltf_close(f);
    }
}

static void materials_samplers_and_transmission(void **state)
{
    (void)state;
    sy_gltf_file *f = open_variant(V_PLAIN);
    char s[64];
    assert_string_equal(sy_gltf_string(f, "/materials/0/name", s, sizeof s), "bark");
    assert_true(sy_gltf_has(f, "/materials/0/pbrMetallicRoughness/baseColorTexture/index"));
    assert_true(sy_gltf_has(f, "/materials/0/normalTexture/index"));
    assert_false(sy_gltf_has(f, "/materials/0/alphaMode"));
    int bark_tex = (int)sy_gltf_number(f, "/materials/0/pbrMetallicRoughness/baseColorTexture/index", -1);
    int bark_sampler = (int)glb_num(f, "/textures/%d/sampler", bark_tex);
    assert_int_equal((int)glb_num(f, "/samplers/%d/wrapS", bark_sampler), 10497); /* REPEAT */
    assert_int_equal((int)glb_num(f, "/samplers/%d/minFilter", bark_sampler), 9987);

    const char *leaf = "/materials/1";
    char p[160];
    snprintf(p, sizeof p, "%s/alphaMode", leaf);
    assert_string_equal(sy_gltf_string(f, p, s, sizeof s), "MASK");
    assert_float_equal(glb_num(f, "%s/alphaCutoff", leaf), 0.4, 1e-6);
    snprintf(p, sizeof p, "%s/doubleSided", leaf);
    assert_true(sy_gltf_has(f, p));
    assert_true(glb_has(f, "%s/normalTexture/index", leaf));
    const char *dt = "/materials/1/extensions/KHR_materials_diffuse_transmission";
    assert_float_equal(glb_num(f, "%s/diffuseTransmissionFactor", dt), 0.3, 1e-6);
    assert_float_equal(glb_num(f, "%s/diffuseTransmissionColorFactor/0", dt), 0.6, 1e-6);
    assert_float_equal(glb_num(f, "%s/diffuseTransmissionColorFactor/1", dt), 0.8, 1e-6);
    assert_float_equal(glb_num(f, "%s/diffuseTransmissionColorFactor/2", dt), 0.2, 1e-6);
    int dtex = (int)glb_num(f, "%s/diffuseTransmissionTexture/index", dt);
    assert_true(dtex >= 0 && dtex < sy_gltf_size(f, "/textures"));
    int leaf_tex = (int)glb_num(f, "%s/pbrMetallicRoughness/baseColorTexture/index", leaf);
    int leaf_sampler = (int)glb_num(f, "/textures/%d/sampler", leaf_tex);
    assert_int_equal((int)glb_num(f, "/samplers/%d/wrapS", leaf_sampler), 33071); /* CLAMP_TO_EDGE */
    assert_int_equal((int)glb_num(f, "/samplers/%d/wrapT", leaf_sampler), 33071);
    assert_int_equal((int)glb_num(f, "/samplers/%d/minFilter", leaf_sampler), 9987);
    assert_true(string_in_array(f, "/extensionsUsed", "KHR_materials_diffuse_transmission"));
    assert_false(string_in_array(f, "/extensionsRequired", "KHR_materials_diffuse_transmission"));
    /* Engines without the extension light the card's shaded side by the
     * emissive fallback, in the leaf's own colours; bark has none. */
    for (int c = 0; c < 3; c++) assert_float_equal(glb_num(f, "%s/emissiveFactor/%d", leaf, c), 0.09, 1e-6);
    assert_int_equal((int)glb_num(f, "%s/emissiveTexture/index", leaf), leaf_tex);
    assert_false(sy_gltf_has(f, "/materials/0/emissiveFactor"));
    /* The impostor has no transmission, so no extension object. */
    assert_false(sy_gltf_has(f, "/materials/2/extensions"));
    sy_gltf_close(f);
}

/* _WIND_ANCHOR (VEC3) and _WIND_LEVEL_STIFFNESS (VEC2), float, n each, hold
 * the wind-table entry of the branch in _WIND_BRANCH at every vertex. */
static void check_wind_branch_values(const sy_gltf_file *f, int v, int anchor, int ls, int branch, size_t n)
{
    char p[64], s[16];
    const int acc[2] = {anchor, ls};
    const char *type[2] = {"VEC3", "VEC2"};
    for (int k = 0; k < 2; k++) {
        assert_true(acc[k] >= 0);
        assert_int_equal((size_t)glb_num(f, "/accessors/%d/count", acc[k]), n);
        assert_int_equal((int)glb_num(f, "/accessors/%d/componentType", acc[k]), 5126);
        snprintf(p, sizeof p, "/accessors/%d/type", acc[k]);
        assert_string_equal(sy_gltf_string(f, p, s, sizeof s), type[k]);
    }
    if (variant_meshopt[v]) return; /* the data is checked on the uncompressed files */
    size_t count, stride;
    const float *an = (const float *)glb_accessor(f, anchor, &count, &stride);
    const float *lv = (const float *)glb_accessor(f, ls, &count, &stride);
    const unsigned char *br = glb_accessor(f, branch, &count, &stride);
    for (size_t i = 0; i < n; i++) {
        uint16_t b;
        memcpy(&b, br + 4 * i, sizeof b);
        assert_true(b < tree.n_wind);
        assert_memory_equal(an + 3 * i, tree.wind[b].anchor, 12);
        assert_true(lv[2 * i] == (float)tree.wind[b].level && lv[2 * i + 1] == tree.wind[b].stiffness);
    }
}

static void meshes_have_attributes_bounds_and_wind(void **state)
{
    (void)state;
    for (int v = 0; v < N_VARIANTS; v++) {
        sy_gltf_file *f = open_variant(v);
        int with_wind = 0;
        for (int m = 0; m < sy_gltf_size(f, "/meshes"); m++) {
            int pos = attribute(f, m, "POSITION");
            assert_true(pos >= 0);
            assert_int_equal((int)glb_num(f, "/accessors/%d/componentType", pos), 5126);
            assert_true(glb_has(f, "/accessors/%d/min/2", pos) && glb_has(f, "/accessors/%d/max/2", pos));
            assert_true(glb_num(f, "/accessors/%d/min/1", pos) < glb_num(f, "/accessors/%d/max/1", pos));
            size_t n = (size_t)glb_num(f, "/accessors/%d/count", pos);
            assert_true(attribute(f, m, "NORMAL") >= 0 && attribute(f, m, "TEXCOORD_0") >= 0);
            int ww = attribute(f, m, "_WIND_W");
            if (ww >= 0) {
                with_wind++;
                assert_int_equal((size_t)glb_num(f, "/accessors/%d/count", ww), n);
                int wb = attribute(f, m, "_WIND_BRANCH");
                assert_int_equal((size_t)glb_num(f, "/accessors/%d/count", wb), n);
                assert_int_equal((int)glb_num(f, "/accessors/%d/componentType", wb), 5123);
                assert_int_equal((int)glb_num(f, "/bufferViews/%d/byteStride", (int)glb_num(f, "/accessors/%d/bufferView", wb)),
                                 4);
                check_wind_branch_values(f, v, attribute(f, m, "_WIND_ANCHOR"), attribute(f, m, "_WIND_LEVEL_STIFFNESS"),
                                         wb, n);
            }
            int idx = (int)glb_num(f, "/meshes/%d/primitives/0/indices", m);
            assert_int_equal((int)glb_num(f, "/accessors/%d/componentType", idx), n <= 65535 ? 5123 : 5125);
            assert_false(glb_has(f, "/bufferViews/%d/byteStride", (int)glb_num(f, "/accessors/%d/bufferView", idx)));
        }
        /* 3 trunks + the leaf card (one shared mesh, or one baked mesh per level); not the impostor. */
        assert_int_equal(with_wind, variant_instancing[v] ? 4 : 6);
        int imp = mesh_named(f, "impostor");
        assert_true(imp >= 0);
        assert_false(glb_has(f, "/meshes/%d/primitives/0/attributes/TANGENT", imp));
        /* trunk_lod2 came without tangents but has a normal map: generated. */
        assert_true(glb_has(f, "/meshes/%d/primitives/0/attributes/TANGENT", mesh_named(f, "trunk_lod2")));
        sy_gltf_close(f);
    }
}

static void position_bounds_and_generated_tangents_match_data(void **state)
{
    (void)state;
    sy_gltf_file *f = open_variant(V_PLAIN);
    int m = mesh_named(f, "trunk_lod0");
    int pos = attribute(f, m, "POSITION");
    size_t count, stride;
    const float *p = (const float *)glb_accessor(f, pos, &count, &stride);
    assert_int_equal(count, tree.meshes[0].n_vertices);
    assert_int_equal(stride, 12);
    assert_memory_equal(p, tree.meshes[0].position, count * 12);
    for (int c = 0; c < 3; c++) {
        float lo = p[c], hi = p[c];
        for (size_t i = 1; i < count; i++) {
            if (p[3 * i + c] < lo) lo = p[3 * i + c];
            if (p[3 * i + c] > hi) hi = p[3 * i + c];
        }
        assert_true(glb_num(f, "/accessors/%d/min/%d", pos, c) == (double)lo);
        assert_true(glb_num(f, "/accessors/%d/max/%d", pos, c) == (double)hi);
    }
    /* Generated tangents of trunk_lod2 follow +u around the tube, w = +1,
     * the same frame the test writes by hand for trunk_lod0. */
    int m2 = mesh_named(f, "trunk_lod2");
    const float *t = (const float *)glb_accessor(f, attribute(f, m2, "TANGENT"), &count, &stride);
    const sy_mesh *src = &tree.meshes[2];
    assert_int_equal(count, src->n_vertices);
    for (size_t i = 0; i < count; i++) {
        double ang = atan2(src->normal[3 * i + 2], src->normal[3 * i + 0]);
        assert_float_equal(t[4 * i + 0], -sin(ang), 0.05);
        assert_float_equal(t[4 * i + 1], 0.0, 0.05);
        assert_float_equal(t[4 * i + 2], cos(ang), 0.05);
        assert_float_equal(t[4 * i + 3], 1.0, 0);
    }
    sy_gltf_close(f);
}

static void leaves_are_gpu_instances(void **state)
{
    (void)state;
    for (int v = V_PLAIN; v <= V_MESHOPT; v++) {
        sy_gltf_file *f = open_variant(v);
        assert_true(string_in_array(f, "/extensionsUsed", "EXT_mesh_gpu_instancing"));
        assert_true(string_in_array(f, "/extensionsRequired", "EXT_mesh_gpu_instancing"));
        int node = lod0_child(f, "_instances");
        assert_true(node >= 0);
        assert_int_equal((int)glb_num(f, "/nodes/%d/mesh", node), mesh_named(f, "leaf_card"));
        const char *names[3] = {"TRANSLATION", "ROTATION", "SCALE"};
        const char *types[3] = {"VEC3", "VEC4", "VEC3"};
        for (int k = 0; k < 3; k++) {
            int acc = (int)glb_num(f, "/nodes/%d/extensions/EXT_mesh_gpu_instancing/attributes/%s", node, names[k]);
            assert_true(acc >= 0);
            assert_int_equal((int)glb_num(f, "/accessors/%d/count", acc), N_LEAVES);
            assert_int_equal((int)glb_num(f, "/accessors/%d/componentType", acc), 5126);
            char p[64], s[16];
            snprintf(p, sizeof p, "/accessors/%d/type", acc);
            assert_string_equal(sy_gltf_string(f, p, s, sizeof s), types[k]);
            assert_false(glb_has(f, "/bufferViews/%d/target", (int)glb_num(f, "/accessors/%d/bufferView", acc)));
            if (v == V_PLAIN) {
                size_t count, stride;
                const float *d = (const float *)glb_accessor(f, acc, &count, &stride);
                const sy_instances *in = &tree.lods[0].instances[0];
                const float *src = k == 0 ? in->translation : k == 1 ? in->rotation : in->scale;
                assert_memory_equal(d, src, N_LEAVES * (k == 1 ? 16 : 12));
            }
        }
        /* One leaf mesh shared by all three levels' instance nodes. */
        assert_int_equal(sy_gltf_size(f, "/meshes"), 5);
        sy_gltf_close(f);
    }
}

/* What a viewer draws of the file (sy_gltf_read_surface): the leaf cards'
 * triangles are tested against their texture's alpha (opaque in columns 1-3
 * of rows 0-4 of 8 x 8, asymmetric both ways, so a lookup mirrored in u or
 * v fails; cutoff 0.4), the bark is drawn whole; baked or instanced, the
 * same. The cards' corners carry the exporter's uv. */
static void leaf_cards_are_cut_where_their_texture_is_clear(void **state)
{
    (void)state;
    for (int v = V_PLAIN; v <= V_BAKED; v += V_BAKED - V_PLAIN) {
        char path[4200];
        snprintf(path, sizeof path, "%s/%s", out_dir, variant_name[v]);
        double *tri = NULL;
        size_t nt = 0, leaf_tris = 0, drawn = 0, tested = 0;
        sy_gltf_cutout cut;
        sy_error err = {0};
        assert_int_equal(sy_gltf_read_surface(path, &tri, &nt, &cut, &err), SY_OK);
        assert_non_null(cut.map);
        assert_int_equal(cut.n_maps, 1); /* the leaf material: the impostor is a level of its own, not LOD0 */
        int corner_seen[4] = {0, 0, 0, 0};
        for (size_t t = 0; t < nt; t++) {
            if (cut.map[t] < 0) continue;
            leaf_tris++;
            for (int c = 0; c < 3; c++) {
                float u = cut.uv[6 * t + 2 * c], v = cut.uv[6 * t + 2 * c + 1];
                assert_true((u == 0 || u == 1) && (v == 0 || v == 1));
                corner_seen[(int)u + 2 * (int)v] = 1;
            }
            assert_float_equal(cut.maps[cut.map[t]].cutoff, 0.4, 1e-6);
            for (int i = 0; i <= 20; i++)
                for (int j = 0; i + j <= 20; j++) {
                    double w[3] = {(20.0 - i - j) / 20, i / 20.0, j / 20.0};
                    /* Points off the 1/8 texel lines only (the nearest texel there is exact). */
                    const float *uv = cut.uv + 6 * t;
                    double u = w[0] * uv[0] + w[1] * uv[2] + w[2] * uv[4], v = w[0] * uv[1] + w[1] * uv[3] + w[2] * uv[5];
                    if (fabs(u * 8 - floor(u * 8 + 0.5)) < 1e-3 || fabs(v * 8 - floor(v * 8 + 0.5)) < 1e-3) continue;
                    tested++;
                    drawn += (size_t)sy_gltf_cutout_drawn(&cut, t, w);
                    assert_int_equal(sy_gltf_cutout_drawn(&cut, t, w), u >= 0.125 && u < 0.5 && v < 0.625);
                }
        }
        assert_int_equal(leaf_tris, 2 * N_LEAVES);
        for (int c = 0; c < 4; c++) assert_true(corner_seen[c]);
        /* 15 of the 64 texels pass. */
        assert_true(tested > 0 && fabs((double)drawn / (double)tested - 15.0 / 64) < 0.05);
        /* Bark triangles: drawn whole. */
        assert_true(nt > leaf_tris);
        sy_gltf_cutout_free(&cut);
        free(tri);
    }
}

static void baked_fallback_has_no_instancing(void **state)
{
    (void)state;
    sy_gltf_file *f = open_variant(V_BAKED);
    assert_false(string_in_array(f, "/extensionsUsed", "EXT_mesh_gpu_instancing"));
    assert_false(string_in_array(f, "/extensionsRequired", "EXT_mesh_gpu_instancing"));
    for (int i = 0; i < sy_gltf_size(f, "/nodes"); i++) assert_false(glb_has(f, "/nodes/%d/extensions/EXT_mesh_gpu_instancing", i));
    int node = lod0_child(f, "_instances");
    assert_true(node >= 0);
    int mesh = (int)glb_num(f, "/nodes/%d/mesh", node);
    int pos = attribute(f, mesh, "POSITION");
    size_t count, stride;
    const float *p = (const float *)glb_accessor(f, pos, &count, &stride);
    assert_int_equal(count, 4 * N_LEAVES);
    assert_int_equal((int)glb_num(f, "/accessors/%d/count", (int)glb_num(f, "/meshes/%d/primitives/0/indices", mesh)),
                     6 * N_LEAVES);
    /* Vertex 2 of instance k = T + R (S p), R a rotation about Y by ang. */
    const sy_instances *in = &tree.lods[0].instances[0];
    for (size_t k = 0; k < N_LEAVES; k++) {
        double ang = 2.4 * k, sx = in->scale[3 * k] * leaf_pos[2][0], sy = in->scale[3 * k + 1] * leaf_pos[2][1];
        double x = cos(ang) * sx, z = -sin(ang) * sx;
        assert_float_equal(p[3 * (4 * k + 2) + 0], in->translation[3 * k + 0] + x, 1e-5);
        assert_float_equal(p[3 * (4 * k + 2) + 1], in->translation[3 * k + 1] + sy, 1e-5);
        assert_float_equal(p[3 * (4 * k + 2) + 2], in->translation[3 * k + 2] + z, 1e-5);
    }
    /* Normals rotate with the card: +Z turned about Y. */
    const float *nrm = (const float *)glb_accessor(f, attribute(f, mesh, "NORMAL"), &count, &stride);
    assert_float_equal(nrm[3 * 4 * 7 + 0], sin(2.4 * 7), 1e-5);
    assert_float_equal(nrm[3 * 4 * 7 + 2], cos(2.4 * 7), 1e-5);
    sy_gltf_close(f);
}

static void lod_chain_uses_msft_lod(void **state)
{
    (void)state;
    for (int v = 0; v < N_VARIANTS; v++) {
        sy_gltf_file *f = open_variant(v);
        assert_int_equal(sy_gltf_size(f, "/scenes"), 1);
        assert_int_equal(sy_gltf_size(f, "/scenes/0/nodes"), 1);
        int root = (int)glb_num(f, "/scenes/0/nodes/0");
        int n_nodes = sy_gltf_size(f, "/nodes");
        char p[96];
        snprintf(p, sizeof p, "/nodes/%d/extensions/MSFT_lod/ids", root);
        assert_int_equal(sy_gltf_size(f, p), 3);
        snprintf(p, sizeof p, "/nodes/%d/extras/MSFT_screencoverage", root);
        assert_int_equal(sy_gltf_size(f, p), 4);
        for (int l = 0; l < 4; l++) {
            double c = glb_num(f, "/nodes/%d/extras/MSFT_screencoverage/%d", root, l);
            assert_float_equal(c, tree.lods[l].screen_coverage, 1e-7);
            if (l) assert_true(c < glb_num(f, "/nodes/%d/extras/MSFT_screencoverage/%d", root, l - 1));
        }
        for (int l = 0; l < 3; l++) {
            int id = (int)glb_num(f, "/nodes/%d/extensions/MSFT_lod/ids/%d", root, l);
            assert_true(id >= 0 && id < n_nodes && id != root);
            /* Each level groups its parts: trunk + leaves, or the impostor. */
            snprintf(p, sizeof p, "/nodes/%d/children", id);
            assert_int_equal(sy_gltf_size(f, p), l < 2 ? 2 : 1);
            assert_false(glb_has(f, "/nodes/%d/mesh", id));
        }
        snprintf(p, sizeof p, "/nodes/%d/children", root);
        assert_int_equal(sy_gltf_size(f, p), 2);
        assert_true(string_in_array(f, "/extensionsUsed", "MSFT_lod"));
        assert_false(string_in_array(f, "/extensionsRequired", "MSFT_lod"));
        /* The per-branch wind table rides on the root node. */
        assert_int_equal((int)glb_num(f, "/nodes/%d/extras/sylva_wind/count", root), 2);
        assert_true(glb_has(f, "/nodes/%d/extras/sylva_wind/parent/0", root));
        assert_int_equal((int)glb_num(f, "/nodes/%d/extras/sylva_wind/parent/0", root), -1);
        assert_int_equal((int)glb_num(f, "/nodes/%d/extras/sylva_wind/parent/1", root), 0);
        snprintf(p, sizeof p, "/nodes/%d/extras/sylva_wind/anchor", root);
        assert_int_equal(sy_gltf_size(f, p), 6);
        assert_float_equal(glb_num(f, "/nodes/%d/extras/sylva_wind/anchor/4", root), 1.2, 1e-6);
        assert_float_equal(glb_num(f, "/nodes/%d/extras/sylva_wind/frequency/1", root), 2.7, 1e-6);
        sy_gltf_close(f);
    }
}

static void meshopt_streams_decode_to_the_originals(void **state)
{
    (void)state;
    sy_gltf_file *f = open_variant(V_MESHOPT);
    assert_true(string_in_array(f, "/extensionsRequired", "EXT_meshopt_compression"));
    assert_int_equal(sy_gltf_size(f, "/buffers"), 2);
    assert_false(sy_gltf_has(f, "/buffers/1/uri"));
    assert_true(sy_gltf_has(f, "/buffers/1/extensions/EXT_meshopt_compression/fallback"));
    double fallback_len = sy_gltf_number(f, "/buffers/1/byteLength", 0);
    size_t bin_size;
    const unsigned char *bin = sy_gltf_bin(f, &bin_size);
    int m = mesh_named(f, "trunk_lod0");
    const sy_mesh *src = &tree.meshes[0];

    int views[2] = {(int)glb_num(f, "/accessors/%d/bufferView", attribute(f, m, "POSITION")),
                    (int)glb_num(f, "/accessors/%d/bufferView", (int)glb_num(f, "/meshes/%d/primitives/0/indices", m))};
    for (int k = 0; k < 2; k++) {
        int view = views[k];
        assert_int_equal((int)glb_num(f, "/bufferViews/%d/buffer", view), 1);
        char p[128];
        snprintf(p, sizeof p, "/bufferViews/%d/byteOffset", view);
        assert_true(sy_gltf_number(f, p, 0) + glb_num(f, "/bufferViews/%d/byteLength", view) <= fallback_len);
        snprintf(p, sizeof p, "/bufferViews/%d/extensions/EXT_meshopt_compression", view);
        char q[192], mode[32];
        snprintf(q, sizeof q, "%s/mode", p);
        sy_gltf_string(f, q, mode, sizeof mode);
        assert_int_equal((int)glb_num(f, "%s/buffer", p), 0);
        size_t off = (size_t)glb_num(f, "%s/byteOffset", p), len = (size_t)glb_num(f, "%s/byteLength", p);
        size_t count = (size_t)glb_num(f, "%s/count", p), stride = (size_t)glb_num(f, "%s/byteStride", p);
        assert_true(off + len <= bin_size);
        assert_int_equal(count * stride, (size_t)glb_num(f, "/bufferViews/%d/byteLength", view));
        if (k == 0) {
            assert_string_equal(mode, "ATTRIBUTES");
            assert_int_equal(bin[off], 0xa0);
            assert_int_equal(count, src->n_vertices);
            float *dec = malloc(count * stride);
            assert_int_equal(meshopt_decodeVertexBuffer(dec, count, stride, bin + off, len), 0);
            assert_memory_equal(dec, src->position, count * stride);
            printf("# POSITION of trunk_lod0: %zu -> %zu bytes\n", count * stride, len);
            free(dec);
        } else {
            assert_string_equal(mode, "TRIANGLES");
            assert_int_equal(bin[off], 0xe1);
            assert_int_equal(stride, 2);
            assert_int_equal(count, src->n_indices);
            uint16_t *dec = malloc(count * 2);
            assert_int_equal(meshopt_decodeIndexBuffer(dec, count, 2, bin + off, len), 0);
            for (size_t i = 0; i < count; i++) assert_int_equal(dec[i], src->indices[i]);
            printf("# indices of trunk_lod0: %zu -> %zu bytes\n", count * 2, len);
            free(dec);
        }
    }
    /* Images are never compressed and never point at the fallback buffer. */
    for (int i = 0; i < sy_gltf_size(f, "/images"); i++)
        assert_int_equal((int)glb_num(f, "/bufferViews/%d/buffer", (int)glb_num(f, "/images/%d/bufferView", i)), 0);
    sy_gltf_close(f);

    struct stat a, b;
    assert_int_equal(stat(variant_path(V_PLAIN), &a), 0);
    assert_int_equal(stat(variant_path(V_MESHOPT), &b), 0);
    assert_true(b.st_size < a.st_size);
}

static void large_meshes_use_32_bit_indices(void **state)
{
    (void)state;
    sy_asset a;
    memset(&a, 0, sizeof a);
    sy_error err = {0};
    sy_material bark = sy_material_default("bark");
    sy_asset_add_material(&a, &bark, &err);
    int big = add_tube(&a, "big", 299, 300, 0, 0); /* 300 x 301 = 90300 vertices */
    /* A mesh that does not sway: no wind streams, no wind table. */
    free(a.meshes[big].wind_w);
    free(a.meshes[big].wind_branch);
    a.meshes[big].wind_w = NULL;
    a.meshes[big].wind_branch = NULL;
    sy_lod lod = {0};
    lod.screen_coverage = 1;
    lod.n_meshes = 1;
    lod.meshes[0] = big;
    sy_asset_add_lod(&a, &lod, &err);
    const char *path = tmp_path("big.glb");
    if (export_file(path, &a, NULL, NULL, &err) != SY_OK) fail_msg("%s", err.msg);
    sy_gltf_file *f = NULL;
    assert_int_equal(sy_gltf_open(path, &f, &err), SY_OK);
    int idx = (int)sy_gltf_number(f, "/meshes/0/primitives/0/indices", -1);
    assert_int_equal((int)glb_num(f, "/accessors/%d/componentType", idx), 5125);
    assert_false(sy_gltf_has(f, "/meshes/0/primitives/0/attributes/_WIND_W"));
    assert_false(sy_gltf_has(f, "/meshes/0/primitives/0/attributes/TANGENT")); /* no normal map */
    assert_false(sy_gltf_has(f, "/extensionsUsed"));
    /* One level, no wind: the root carries neither MSFT_lod nor extras. */
    int root = (int)sy_gltf_number(f, "/scenes/0/nodes/0", -1);
    assert_true(glb_has(f, "/nodes/%d/children/0", root));
    assert_false(glb_has(f, "/nodes/%d/extras", root));
    assert_false(glb_has(f, "/nodes/%d/extensions", root));
    sy_gltf_close(f);
    sy_asset_free(&a);
}

/* Exports a broken copy of the tree and checks the one-line failure. */
static void expect_failure(sy_asset *a, const char *name, sy_code code, const char *needle)
{
    const char *path = tmp_path(name);
    int before = dir_entry_count(test_tmpdir());
    sy_error err = {0};
    assert_int_equal(export_file(path, a, NULL, NULL, &err), code);
    if (!strstr(err.msg, needle)) fail_msg("message '%s' lacks '%s'", err.msg, needle);
    assert_non_null(strstr(err.msg, path));
    assert_null(strchr(err.msg, '\n'));
    assert_false(file_exists(path));
    assert_int_equal(dir_entry_count(test_tmpdir()), before);
}

static void invalid_assets_fail_without_output(void **state)
{
    (void)state;
    sy_mesh *trunk = &tree.meshes[0];
    uint32_t saved = trunk->indices[5];
    trunk->indices[5] = (uint32_t)trunk->n_vertices;
    expect_failure(&tree, "bad_index.glb", SY_EINPUT, "out of range");
    trunk->indices[5] = saved;

    float x = trunk->position[7];
    trunk->position[7] = NAN;
    expect_failure(&tree, "nan.glb", SY_EINPUT, "NaN");
    trunk->position[7] = x;

    int mat = tree.meshes[3].material;
    tree.meshes[3].material = 9;
    expect_failure(&tree, "material.glb", SY_EINPUT, "missing material 9");
    tree.meshes[3].material = mat;

    float cov = tree.lods[2].screen_coverage;
    tree.lods[2].screen_coverage = 0.3f;
    expect_failure(&tree, "coverage.glb", SY_EINPUT, "screen coverage");
    tree.lods[2].screen_coverage = cov;

    float qy = tree.lods[0].instances[0].rotation[1];
    tree.lods[0].instances[0].rotation[1] = 2.0f;
    expect_failure(&tree, "quat.glb", SY_EINPUT, "unit quaternion");
    tree.lods[0].instances[0].rotation[1] = qy;

    char *extras = tree.extras_json;
    tree.extras_json = "{\"species\": ";
    expect_failure(&tree, "extras.glb", SY_EINPUT, "extras");
    tree.extras_json = extras;

    uint16_t br = tree.meshes[3].wind_branch[0];
    tree.meshes[3].wind_branch[0] = 5;
    expect_failure(&tree, "wind.glb", SY_EINPUT, "wind branch");
    tree.meshes[3].wind_branch[0] = br;
}

static void unwritable_destinations_fail_cleanly(void **state)
{
    (void)state;
    sy_error err = {0};
    const char *missing = tmp_path("no/such/dir/tree.glb");
    assert_int_equal(export_file(missing, &tree, NULL, NULL, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, missing));
    assert_null(strchr(err.msg, '\n'));

    /* A read-only directory; root ignores permission bits, so as root use
     * /proc, which refuses new files for everyone. */
    char ro_dir[4200], ro_path[4300];
    if (geteuid() == 0) {
        snprintf(ro_dir, sizeof ro_dir, "/proc");
    } else {
        snprintf(ro_dir, sizeof ro_dir, "%s", tmp_path("readonly"));
        assert_int_equal(mkdir(ro_dir, 0555), 0);
    }
    int before = dir_entry_count(ro_dir);
    snprintf(ro_path, sizeof ro_path, "%s/sylva_tree.glb", ro_dir);
    err.msg[0] = 0;
    assert_int_equal(export_file(ro_path, &tree, NULL, NULL, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, ro_path));
    assert_null(strchr(err.msg, '\n'));
    assert_false(file_exists(ro_path));
    if (geteuid() != 0) assert_int_equal(dir_entry_count(ro_dir), before);
    (void)before;
    /* The variant directory holds the four exports and no temp file. */
    assert_int_equal(dir_entry_count(out_dir), N_VARIANTS);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(khronos_validator_reports_no_errors_or_warnings),
        cmocka_unit_test(header_generator_and_extras),
        cmocka_unit_test(images_are_png_buffer_views),
        cmocka_unit_test(buffer_views_are_aligned_and_strided),
        cmocka_unit_test(materials_samplers_and_transmission),
        cmocka_unit_test(meshes_have_attributes_bounds_and_wind),
        cmocka_unit_test(position_bounds_and_generated_tangents_match_data),
        cmocka_unit_test(leaves_are_gpu_instances),
        cmocka_unit_test(baked_fallback_has_no_instancing),
        cmocka_unit_test(leaf_cards_are_cut_where_their_texture_is_clear),
        cmocka_unit_test(lod_chain_uses_msft_lod),
        cmocka_unit_test(meshopt_streams_decode_to_the_originals),
        cmocka_unit_test(large_meshes_use_32_bit_indices),
        cmocka_unit_test(invalid_assets_fail_without_output),
        cmocka_unit_test(unwritable_destinations_fail_cleanly),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
