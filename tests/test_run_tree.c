/* The run driver is re-entrant: the same scan and options give the same
 * .glb and .sylva bytes on a second call in the same process and on two
 * threads running at once, and a bad call leaves nothing behind. */
#include "testutil.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/run_tree.h"
#include "stages/core/progress.h"

#define SCAN SYLVA_SOURCE_DIR "/samples/palm_tls.las"

static sy_run_tree_options options(void)
{
    sy_run_tree_options o = sy_run_tree_options_default();
    o.species = "palm";
    o.voxel = 0.03;
    o.sylva = 1;
    o.seed = 7;
    o.asset.lods = 2;
    o.asset.impostor_size = 64;
    return o;
}

typedef struct {
    sy_run_tree_result r;
    sy_code rc;
    sy_error err;
} job;

static void *run_job(void *arg)
{
    job *j = arg;
    sy_run_tree_options o = options();
    memset(&j->err, 0, sizeof j->err);
    j->rc = sy_run_tree(SCAN, &o, &j->r, &j->err);
    return NULL;
}

static void assert_same(const sy_run_tree_result *a, const sy_run_tree_result *b)
{
    assert_int_equal(a->glb_size, b->glb_size);
    assert_memory_equal(a->glb, b->glb, a->glb_size);
    assert_int_equal(a->sylva_size, b->sylva_size);
    assert_memory_equal(a->sylva, b->sylva, a->sylva_size);
    assert_int_equal(a->skeleton.nodes, b->skeleton.nodes);
    assert_int_equal(a->skeleton.clusters, b->skeleton.clusters);
}

static void twice_in_one_process_and_on_two_threads(void **state)
{
    (void)state;
    job first, second, t[2];
    run_job(&first);
    if (first.rc) fail_msg("%s", first.err.msg);
    assert_true(first.r.glb_size > 1000);
    assert_memory_equal(first.r.glb, "glTF", 4);
    assert_true(first.r.sylva_size > 20 && first.r.sylva_size < 40000);
    assert_int_equal(first.r.species_id, 5); /* palm: library id 5 */
    assert_true(first.r.skeleton.nodes > 10);
    run_job(&second);
    assert_int_equal(second.rc, SY_OK);
    assert_same(&first.r, &second.r);

    pthread_t th[2];
    for (int i = 0; i < 2; i++) assert_int_equal(pthread_create(&th[i], NULL, run_job, &t[i]), 0);
    for (int i = 0; i < 2; i++) assert_int_equal(pthread_join(th[i], NULL), 0);
    for (int i = 0; i < 2; i++) {
        if (t[i].rc) fail_msg("thread %d: %s", i, t[i].err.msg);
        assert_same(&first.r, &t[i].r);
        sy_run_tree_result_free(&t[i].r);
    }
    sy_run_tree_result_free(&second.r);

    /* A different seed changes the bytes: the comparison above can fail. */
    sy_run_tree_options o = options();
    o.seed = 8;
    sy_run_tree_result other;
    sy_error err = {0};
    assert_int_equal(sy_run_tree(SCAN, &o, &other, &err), SY_OK);
    assert_false(other.sylva_size == first.r.sylva_size &&
                 memcmp(other.sylva, first.r.sylva, other.sylva_size) == 0);
    sy_run_tree_result_free(&other);

    /* Writing: both files, byte for byte what the result holds. */
    const char *glb = tmp_path("tree.glb"), *sylva = tmp_path("tree.sylva");
    assert_int_equal(sy_run_tree_write(&first.r, glb, sylva, &err), SY_OK);
    assert_true(file_exists(glb) && file_exists(sylva));
    sy_run_tree_result_free(&first.r);
}

static void bad_calls_fail_cleanly(void **state)
{
    (void)state;
    sy_run_tree_options o = options();
    sy_run_tree_result r;
    sy_error err = {0};
    o.fs = 2;
    assert_int_equal(sy_run_tree(SCAN, &o, &r, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "fs"));
    assert_null(r.glb);
    o = options();
    o.species = "no_such_tree";
    assert_int_equal(sy_run_tree(SCAN, &o, &r, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "no_such_tree"));
    o = options();
    const char *missing = tmp_path("missing.las");
    assert_int_equal(sy_run_tree(missing, &o, &r, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, missing));
    assert_null(r.glb);
    assert_null(r.sylva);
    /* An unwritable .sylva path leaves no .glb either. */
    assert_int_equal(sy_run_tree(SCAN, &o, &r, &err), SY_OK);
    const char *glb = tmp_path("half.glb");
    assert_int_equal(sy_run_tree_write(&r, glb, tmp_path("no/such/dir/t.sylva"), &err), SY_EINPUT);
    assert_false(file_exists(glb));
    sy_run_tree_result_free(&r);
}

int main(void)
{
    sy_progress_set_quiet(1);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(twice_in_one_process_and_on_two_threads),
        cmocka_unit_test(bad_calls_fail_cleanly),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
