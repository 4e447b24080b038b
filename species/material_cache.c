/* The materials cache: what sy_materials_add appends to an asset (its PNG
 * images and its two materials) stored under a key of everything it is made
 * from, so the trees of a species after the first embed the already-encoded
 * PNG bytes instead of decoding, resizing, deriving normal maps and encoding
 * again (a quaking aspen with its leaf maps: 218 ms of a tree's run).
 *
 * The key hashes the spec's numbers and paths, the bytes of every file they
 * name (a leaf material's maps too) and the identity of the running
 * executable (size and modification time), so a rebuilt sylva never reads an
 * older build's entry. A file holds one entry:
 *
 *   "SYMCACHE" | u64 key | u32 sizeof(sy_material) | u32 images
 *   | per image: name[48] u64 size bytes | u32 materials | sy_material...
 *   | i32 bark | i32 leaf
 *
 * with image and material indices relative to the entry's first ones. The
 * file is the machine's own (raw structs), written atomically; anything that
 * does not read back exactly is a miss. */
#include "species/material_cache.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "stages/core/fileio.h"
#include "stages/core/hash.h"
#include "stages/leafmaps/leaf_material.h"

#define MAGIC "SYMCACHE"
/* Entries not used for this long are removed when a new one is written. */
#define STALE_SECONDS (30.0 * 86400.0)

static uint64_t fnv(uint64_t h, const void *data, size_t n) { return sy_fnv1a64(h, data, n); }

static uint64_t fnv_str(uint64_t h, const char *s)
{
    /* The terminator separates one string from the next. */
    return s ? fnv(h, s, strlen(s) + 1) : fnv(h, "", 1);
}

/* The file's bytes; 0 when it cannot be read (the build then fails on it
 * itself, with its own message, and nothing is cached). */
static int fnv_file(uint64_t *h, const char *path)
{
    if (!path) {
        *h = fnv(*h, "-", 1);
        return 1;
    }
    sy_buffer b;
    if (sy_read_file(path, &b, NULL)) return 0;
    uint64_t n = b.size;
    *h = fnv(fnv(*h, &n, sizeof n), b.data, b.size);
    sy_buffer_free(&b);
    return 1;
}

int sy_material_cache_key(const sy_material_spec *spec, int max_size, float translucency, uint64_t *key)
{
    uint64_t h = SY_FNV1A64_INIT;
    h = fnv_str(h, MAGIC SYLVA_VERSION);
    struct stat st;
    if (stat("/proc/self/exe", &st) != 0) return 0;
    int64_t exe[3] = {(int64_t)st.st_size, (int64_t)st.st_mtim.tv_sec, (int64_t)st.st_mtim.tv_nsec};
    h = fnv(h, exe, sizeof exe);
    int32_t ints[2] = {max_size, (int32_t)sizeof(sy_material)};
    float floats[5] = {translucency, spec->leaf_length_m, -1, -1, -1};
    if (spec->bark_color) memcpy(floats + 2, spec->bark_color, 3 * sizeof(float));
    h = fnv(fnv(h, ints, sizeof ints), floats, sizeof floats);
    h = fnv_str(fnv_str(fnv_str(h, spec->bark_image), spec->leaf_image), spec->leaf_maps);
    if (!fnv_file(&h, spec->bark_image) || !fnv_file(&h, spec->leaf_image) || !fnv_file(&h, spec->leaf_maps))
        return 0;
    if (spec->leaf_maps) {
        sy_leaf_material lm;
        if (sy_leaf_material_load(spec->leaf_maps, &lm, NULL)) return 0;
        const char *maps[] = {lm.albedo, lm.normal, lm.translucency, lm.thickness, lm.hl2[0], lm.hl2[1]};
        for (size_t k = 0; k < sizeof maps / sizeof *maps; k++)
            if (!fnv_file(&h, maps[k][0] ? maps[k] : NULL)) return 0;
    }
    *key = h;
    return 1;
}

static void entry_path(const char *dir, uint64_t key, char *buf, size_t size)
{
    snprintf(buf, size, "%s/materials-%016llx.bin", dir, (unsigned long long)key);
}

/* A bounds-checked reader over the entry's bytes. */
typedef struct {
    const unsigned char *p;
    size_t n, at;
    int bad;
} reader;

static const void *take(reader *r, size_t n)
{
    if (r->bad || n > r->n - r->at) {
        r->bad = 1;
        return NULL;
    }
    const void *q = r->p + r->at;
    r->at += n;
    return q;
}

static uint64_t take_u(reader *r, size_t width)
{
    const void *q = take(r, width);
    if (!q) return 0;
    if (width == 8) {
        uint64_t v;
        memcpy(&v, q, 8);
        return v;
    }
    uint32_t v;
    memcpy(&v, q, 4);
    return v;
}

static int rebase(int idx, int base, size_t n)
{
    if (idx < 0) return -1;
    return (size_t)idx < n ? base + idx : -2;
}

int sy_material_cache_load(const char *dir, uint64_t key, sy_asset *asset, int *bark, int *leaf)
{
    char path[4096];
    entry_path(dir, key, path, sizeof path);
    sy_buffer b;
    if (sy_read_file(path, &b, NULL)) return 0;
    reader r = {b.data, b.size, 0, 0};
    const void *magic = take(&r, 8);
    int ok = magic && memcmp(magic, MAGIC, 8) == 0 && take_u(&r, 8) == key &&
             take_u(&r, 4) == sizeof(sy_material);
    size_t n_img = ok ? take_u(&r, 4) : 0;
    /* Everything is read and checked before the asset changes. */
    sy_image *img = ok ? calloc(n_img ? n_img : 1, sizeof *img) : NULL;
    ok = ok && img;
    for (size_t i = 0; ok && i < n_img; i++) {
        const char *name = take(&r, sizeof img[i].name);
        size_t size = take_u(&r, 8);
        const void *png = take(&r, size);
        if (!name || !png || !size || name[sizeof img[i].name - 1]) {
            ok = 0;
            break;
        }
        memcpy(img[i].name, name, sizeof img[i].name);
        img[i].size = size;
        img[i].png = malloc(size);
        if (!img[i].png) ok = 0;
        else memcpy(img[i].png, png, size);
    }
    size_t n_mat = ok ? take_u(&r, 4) : 0;
    const sy_material *mats = ok ? take(&r, n_mat * sizeof *mats) : NULL;
    int32_t rel[2] = {(int32_t)take_u(&r, 4), (int32_t)take_u(&r, 4)};
    ok = ok && mats && n_mat && !r.bad && r.at == r.n && rel[0] >= 0 && (size_t)rel[0] < n_mat && rel[1] >= 0 &&
         (size_t)rel[1] < n_mat;
    size_t img0 = asset->n_images, mat0 = asset->n_materials, added = 0;
    for (size_t i = 0; ok && i < n_img; i++, added++)
        if (sy_asset_add_image(asset, &img[i], NULL) < 0) ok = 0;
    for (size_t m = 0; ok && m < n_mat; m++) {
        sy_material mt;
        memcpy(&mt, (const unsigned char *)mats + m * sizeof mt, sizeof mt);
        int *slots[] = {&mt.base_color_image, &mt.normal_image, &mt.diffuse_transmission_image,
                        &mt.thickness_image, &mt.hl2_image[0], &mt.hl2_image[1]};
        for (size_t k = 0; k < sizeof slots / sizeof *slots; k++)
            if ((*slots[k] = rebase(*slots[k], (int)img0, n_img)) == -2) ok = 0;
        if (ok && sy_asset_add_material(asset, &mt, NULL) < 0) ok = 0;
    }
    if (ok) {
        *bark = (int)mat0 + rel[0];
        *leaf = (int)mat0 + rel[1];
    } else {
        /* A damaged entry: take back what was added, and go the slow way. */
        while (asset->n_images > img0) free(asset->images[--asset->n_images].png);
        asset->n_materials = mat0;
        for (size_t i = added; i < n_img; i++) free(img ? img[i].png : NULL);
    }
    free(img);
    sy_buffer_free(&b);
    if (ok) utimensat(AT_FDCWD, path, NULL, 0); /* used now: not stale */
    return ok;
}

static int put(FILE *f, const void *p, size_t n) { return fwrite(p, 1, n, f) == n; }

/* Removes entries of dir not used for STALE_SECONDS (builds come and go). */
static void prune(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return;
    time_t now = time(NULL);
    struct dirent *e;
    while ((e = readdir(d))) {
        if (strncmp(e->d_name, "materials-", 10) != 0) continue;
        char p[4400];
        struct stat st;
        if (snprintf(p, sizeof p, "%s/%s", dir, e->d_name) >= (int)sizeof p || stat(p, &st) != 0) continue;
        if (difftime(now, st.st_mtime) > STALE_SECONDS) remove(p);
    }
    closedir(d);
}

void sy_material_cache_store(const char *dir, uint64_t key, const sy_asset *asset, size_t img0, size_t mat0,
                             int bark, int leaf)
{
    if (mkdir(dir, 0755) != 0 && errno != EEXIST) return;
    char path[4096];
    entry_path(dir, key, path, sizeof path);
    sy_atomic_file af;
    if (sy_atomic_open(&af, path, NULL)) return;
    FILE *f = af.fp;
    uint64_t k = key;
    uint32_t sz = sizeof(sy_material), n_img = (uint32_t)(asset->n_images - img0),
             n_mat = (uint32_t)(asset->n_materials - mat0);
    int ok = put(f, MAGIC, 8) && put(f, &k, 8) && put(f, &sz, 4) && put(f, &n_img, 4);
    for (size_t i = img0; ok && i < asset->n_images; i++) {
        uint64_t size = asset->images[i].size;
        ok = put(f, asset->images[i].name, sizeof asset->images[i].name) && put(f, &size, 8) &&
             put(f, asset->images[i].png, asset->images[i].size);
    }
    ok = ok && put(f, &n_mat, 4);
    for (size_t m = mat0; ok && m < asset->n_materials; m++) {
        sy_material mt = asset->materials[m];
        int *slots[] = {&mt.base_color_image, &mt.normal_image, &mt.diffuse_transmission_image,
                        &mt.thickness_image, &mt.hl2_image[0], &mt.hl2_image[1]};
        for (size_t s = 0; s < sizeof slots / sizeof *slots; s++)
            if (*slots[s] >= 0) *slots[s] -= (int)img0;
        ok = put(f, &mt, sizeof mt);
    }
    int32_t rel[2] = {bark - (int)mat0, leaf - (int)mat0};
    ok = ok && put(f, rel, sizeof rel);
    if (!ok) {
        sy_atomic_abort(&af);
        return;
    }
    if (sy_atomic_commit(&af, NULL) == SY_OK) prune(dir);
}
