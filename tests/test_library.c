/* The species library: the manifest loads, its ids are the ones scans and
 * .sylva files already carry (the sorted order of the .ini files the LiDAR
 * simulator used before the manifest), every parameter file is listed and
 * exists, and malformed manifests fail with a line number. */
/* realpath() is XSI. */
#define _XOPEN_SOURCE 700

#include "testutil.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "species/library.h"
#include "species/species.h"

static void manifest_keeps_the_legacy_ids(void **state)
{
    (void)state;
    sy_library lib;
    sy_error err = {0};
    if (sy_library_load(SYLVA_SPECIES_DIR, &lib, &err)) fail_msg("%s", err.msg);
    assert_true(lib.n >= 11);
    /* The ids scans, truth files and .sylva files have used so far. */
    static const char *const legacy[] = {"balsam_fir",   "black_oak",     "european_pine", "lombardy_poplar",
                                         "london_plane", "palm",          "quaking_aspen", "sassafras",
                                         "silver_birch", "sugar_maple",   "weeping_willow"};
    for (int i = 0; i < 11; i++) {
        const sy_library_entry *e = sy_library_find(&lib, legacy[i]);
        assert_non_null(e);
        assert_int_equal(e->id, i);
        assert_ptr_equal(sy_library_by_id(&lib, i), e);
    }
    assert_int_equal(sy_library_find(&lib, "quaking_aspen")->kind, SY_SPECIES_BROADLEAF);
    assert_int_equal(sy_library_find(&lib, "balsam_fir")->kind, SY_SPECIES_CONIFER);
    assert_int_equal(sy_library_find(&lib, "palm")->kind, SY_SPECIES_PALM);
    assert_string_equal(sy_library_find(&lib, "quaking_aspen")->scientific_name, "Populus tremuloides");
    assert_null(sy_library_find(&lib, "no_such_tree"));
    assert_null(sy_library_by_id(&lib, 65000));
    /* Every listed file exists and every parameter file loads. */
    for (size_t i = 0; i < lib.n; i++) {
        const sy_library_entry *e = &lib.entries[i];
        for (size_t f = 0; f < e->n_files; f++) {
            char path[8192];
            snprintf(path, sizeof path, "%s/%s", lib.dir, e->files[f]);
            if (!file_exists(path)) fail_msg("%s lists %s, which is missing", e->name, path);
        }
        sy_species_params sp;
        if (sy_library_params(&lib, e, &sp, &err)) fail_msg("%s", err.msg);
        assert_string_equal(sp.name, e->name);
        sy_species_params_free(&sp);
    }
    /* Every .ini of the folder is in the manifest: a new species cannot be forgotten. */
    DIR *d = opendir(SYLVA_SPECIES_DIR);
    assert_non_null(d);
    struct dirent *de;
    while ((de = readdir(d))) {
        size_t len = strlen(de->d_name);
        if (len < 5 || strcmp(de->d_name + len - 4, ".ini") != 0) continue;
        int listed = 0;
        for (size_t i = 0; i < lib.n && !listed; i++) listed = strcmp(lib.entries[i].files[0], de->d_name) == 0;
        if (!listed) fail_msg("%s/%s is not in library.tsv", SYLVA_SPECIES_DIR, de->d_name);
    }
    closedir(d);
    sy_library_free(&lib);
}

static void library_is_found_beside_the_executable(void **state)
{
    (void)state;
    char dir[4096];
    sy_error err = {0};
    if (sy_library_locate(dir, sizeof dir, &err)) fail_msg("%s", err.msg);
    char want[4096];
    assert_non_null(realpath(SYLVA_SPECIES_DIR, want));
    assert_string_equal(dir, want);
    assert_int_equal(sy_library_id("palm"), 5);
    assert_int_equal(sy_library_id("no_such_tree"), -1);
    sy_species_params sp;
    assert_int_equal(sy_species_params_find("sugar_maple", &sp, &err), SY_OK);
    sy_species_params_free(&sp);
    assert_int_equal(sy_species_params_find("no_such_tree", &sp, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "no_such_tree"));
}

static void expect_bad_n(const char *text, size_t len, const char *what)
{
    sy_library lib;
    sy_error err = {0};
    assert_int_equal(sy_library_parse("lib.tsv", "/x", text, len, &lib, &err), SY_EINPUT);
    if (!strstr(err.msg, what)) fail_msg("'%s' for %s", err.msg, what);
    assert_non_null(strstr(err.msg, "lib.tsv"));
    assert_null(strchr(err.msg, '\n'));
    assert_null(lib.entries);
}

static void expect_bad(const char *text, const char *what) { expect_bad_n(text, strlen(text), what); }

static void malformed_manifests_fail_with_a_line(void **state)
{
    (void)state;
    const char *ok = "# comment\n0\toak\tQuercus robur\tbroadleaf\toak.ini,textures/bark.png\r\n\n7\tfir\tAbies alba\tconifer\tfir.ini";
    sy_library lib;
    sy_error err = {0};
    assert_int_equal(sy_library_parse("lib.tsv", "/x", ok, strlen(ok), &lib, &err), SY_OK);
    assert_int_equal(lib.n, 2);
    assert_int_equal(lib.entries[0].n_files, 2);
    assert_string_equal(lib.entries[0].files[1], "textures/bark.png");
    assert_int_equal(lib.entries[1].id, 7);
    sy_library_free(&lib);
    expect_bad("0\toak\tQuercus\tbroadleaf\n", "5 tab-separated");
    expect_bad("0\toak\tQuercus\tbroadleaf\toak.ini\textra\n", "got 6");
    expect_bad("x\toak\tQuercus\tbroadleaf\toak.ini\n", "lib.tsv:1: id 'x'");
    expect_bad("-1\toak\tQuercus\tbroadleaf\toak.ini\n", "id '-1'");
    expect_bad("0\tOak\tQuercus\tbroadleaf\toak.ini\n", "name 'Oak'");
    expect_bad("0\toak\t\tbroadleaf\toak.ini\n", "scientific");
    expect_bad("0\toak\tQuercus\tshrub\toak.ini\n", "kind 'shrub'");
    expect_bad("0\toak\tQuercus\tbroadleaf\t../oak.ini\n", "inside the library");
    expect_bad("0\toak\tQuercus\tbroadleaf\t/etc/oak.ini\n", "inside the library");
    expect_bad("0\toak\tQuercus\tbroadleaf\toak.png\n", "parameter .ini");
    expect_bad("0\toak\tQuercus\tbroadleaf\toak.ini,,x.png\n", "empty entry");
    expect_bad("0\toak\tQuercus\tbroadleaf\toak.ini\n0\tfir\tAbies\tconifer\tfir.ini\n", "lib.tsv:2: id 0 is already");
    expect_bad("0\toak\tQuercus\tbroadleaf\toak.ini\n1\toak\tQuercus\tbroadleaf\toak.ini\n", "listed twice");
    expect_bad("# nothing\n", "lists no species");
    static const char nul[] = "0\toak\tQu\0ercus\tbroadleaf\toak.ini\n";
    expect_bad_n(nul, sizeof nul - 1, "NUL");
}

static void classifier_result_owns_its_probabilities(void **state)
{
    (void)state;
    sy_species s;
    sy_error err = {0};
    assert_int_equal(sy_species_init(&s, 11, &err), SY_OK);
    assert_int_equal(s.id, -1);
    assert_int_equal(s.n_classes, 11);
    for (size_t k = 0; k < 11; k++) assert_true(s.probabilities[k] == 0.0f);
    assert_false(s.confident);
    sy_species_free(&s);
    assert_null(s.probabilities);
    sy_species_free(&s); /* twice is safe */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(manifest_keeps_the_legacy_ids),
        cmocka_unit_test(library_is_found_beside_the_executable),
        cmocka_unit_test(malformed_manifests_fail_with_a_line),
        cmocka_unit_test(classifier_result_owns_its_probabilities),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
