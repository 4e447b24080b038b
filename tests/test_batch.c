/* The batch runner's inputs and resume keys: folders give their point-cloud
 * files sorted, manifests (CSV with quotes and comments, JSON arrays of
 * names or objects) give files relative to themselves with their species
 * hints, positions and labels, ids are unique, malformed manifests fail
 * with one line naming the place; the options text changes exactly when a
 * tree's outputs would. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "pipeline/batch.h"

static void put(const char *name, const char *text) { assert_int_equal(write_bytes(tmp_path(name), text, strlen(text)), 0); }

static void hash_is_fnv1a(void **state)
{
    (void)state;
    /* FNV-1a 64 reference values. */
    assert_true(sy_batch_hash("", 0) == 0xcbf29ce484222325ull);
    assert_true(sy_batch_hash("a", 1) == 0xaf63dc4c8601ec8cull);
}

static void folders_and_files(void **state)
{
    (void)state;
    const char *dir = tmp_path("scans");
    mkdir(dir, 0755);
    put("scans/b.las", "x");
    put("scans/a.xyz", "x");
    put("scans/notes.md", "x");
    put("scans/.hidden.las", "x");
    mkdir(tmp_path("other"), 0755);
    put("other/a.ply", "x");
    const char *args[] = {tmp_path("scans"), tmp_path("other/a.ply")};
    sy_batch_inputs in;
    sy_error err = {0};
    assert_int_equal(sy_batch_inputs_collect(args, 2, &in, &err), SY_OK);
    assert_int_equal(in.n, 3);
    assert_non_null(strstr(in.items[0].path, "scans/a.xyz"));
    assert_non_null(strstr(in.items[1].path, "scans/b.las"));
    assert_string_equal(in.items[0].id, "a");
    assert_string_equal(in.items[1].id, "b");
    assert_string_equal(in.items[2].id, "a-2"); /* the same name again */
    assert_null(in.items[0].species);
    assert_false(in.items[0].has_position);
    sy_batch_inputs_free(&in);
    const char *missing[] = {tmp_path("nothing-here")};
    assert_int_equal(sy_batch_inputs_collect(missing, 1, &in, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "nothing-here"));
    mkdir(tmp_path("empty"), 0755);
    const char *empty[] = {tmp_path("empty")};
    assert_int_equal(sy_batch_inputs_collect(empty, 1, &in, &err), SY_EINPUT);
}

static void csv_manifest(void **state)
{
    (void)state;
    put("m.csv", "# survey 2026\r\n"
                 "file,species,x,y,z,label\r\n"
                 "trees/t1.las,,1.5,2.5,3,black_oak\r\n"
                 "\"trees/t, two.las\",palm,,,,\r\n"
                 "/abs/t3.laz,\"quaking_aspen\",-4,5,,\r\n"
                 "\n");
    const char *args[] = {tmp_path("m.csv")};
    sy_batch_inputs in;
    sy_error err = {0};
    assert_int_equal(sy_batch_inputs_collect(args, 1, &in, &err), SY_OK);
    assert_int_equal(in.n, 3);
    char want[4096];
    snprintf(want, sizeof want, "%s", tmp_path("trees/t1.las"));
    assert_string_equal(in.items[0].path, want);
    assert_true(in.items[0].has_position);
    assert_true(in.items[0].position[0] == 1.5 && in.items[0].position[1] == 2.5 && in.items[0].position[2] == 3);
    assert_string_equal(in.items[0].label, "black_oak");
    assert_null(in.items[0].species);
    assert_non_null(strstr(in.items[1].path, "trees/t, two.las"));
    assert_string_equal(in.items[1].species, "palm");
    assert_false(in.items[1].has_position);
    assert_string_equal(in.items[1].id, "t__two"); /* ids keep to a safe alphabet */
    assert_string_equal(in.items[2].path, "/abs/t3.laz");
    assert_true(in.items[2].position[0] == -4 && in.items[2].position[2] == 0);
    sy_batch_inputs_free(&in);
    /* Malformed: a position that is not a number, names its line. */
    put("bad.csv", "file,x,y\nt.las,1,north\n");
    const char *bad[] = {tmp_path("bad.csv")};
    assert_int_equal(sy_batch_inputs_collect(bad, 1, &in, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "bad.csv:2"));
    /* A CSV without a file column is a point cloud, not a manifest. */
    put("cloud.csv", "1,2,3\n4,5,6\n");
    const char *cloud[] = {tmp_path("cloud.csv")};
    assert_int_equal(sy_batch_inputs_collect(cloud, 1, &in, &err), SY_OK);
    assert_int_equal(in.n, 1);
    assert_string_equal(in.items[0].id, "cloud");
    sy_batch_inputs_free(&in);
}

static void json_manifest(void **state)
{
    (void)state;
    put("m.json", "{\"trees\": [\"a.las\", {\"file\": \"b.las\", \"species\": \"palm\", \"position\": [1, 2]},"
                  " {\"file\": \"c.las\", \"x\": 3, \"y\": 4, \"z\": 5, \"label\": \"palm\"}]}");
    const char *args[] = {tmp_path("m.json")};
    sy_batch_inputs in;
    sy_error err = {0};
    assert_int_equal(sy_batch_inputs_collect(args, 1, &in, &err), SY_OK);
    assert_int_equal(in.n, 3);
    assert_false(in.items[0].has_position);
    assert_string_equal(in.items[1].species, "palm");
    assert_true(in.items[1].has_position && in.items[1].position[1] == 2 && in.items[1].position[2] == 0);
    assert_true(in.items[2].position[2] == 5);
    assert_string_equal(in.items[2].label, "palm");
    sy_batch_inputs_free(&in);
    put("bad.json", "[{\"file\": \"a.las\", \"position\": [1, \"x\"]}]");
    const char *bad[] = {tmp_path("bad.json")};
    assert_int_equal(sy_batch_inputs_collect(bad, 1, &in, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "bad.json:1:2"));
    put("nofile.json", "[{\"species\": \"palm\"}]");
    const char *nofile[] = {tmp_path("nofile.json")};
    assert_int_equal(sy_batch_inputs_collect(nofile, 1, &in, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "names no \"file\""));
    put("obj.json", "{\"file\": \"a.las\"}");
    const char *obj[] = {tmp_path("obj.json")};
    assert_int_equal(sy_batch_inputs_collect(obj, 1, &in, &err), SY_EINPUT);
}

static uint64_t opt_hash(const sy_batch_options *o, const sy_batch_input *in)
{
    char *t = sy_batch_options_text(o, in);
    assert_non_null(t);
    uint64_t h = sy_batch_hash(t, strlen(t));
    free(t);
    return h;
}

static void options_text_tracks_outputs(void **state)
{
    (void)state;
    sy_batch_options o = sy_batch_options_default();
    sy_batch_input in = {"a.las", "a", NULL, NULL, 0, {0, 0, 0}, 0, 0};
    uint64_t h0 = opt_hash(&o, &in);
    /* What never changes a tree's bytes: workers, voting, progress. */
    sy_batch_options p = o;
    p.workers = 7;
    p.vote.ratio = 3;
    p.quiet = 1;
    p.json = 1;
    assert_true(opt_hash(&p, &in) == h0);
    /* What does: the seed, a species hint, asset options, thumbnails. */
    p = o;
    p.run.seed = 2;
    assert_true(opt_hash(&p, &in) != h0);
    sy_batch_input hinted = in;
    hinted.species = "palm";
    assert_true(opt_hash(&o, &hinted) != h0);
    p = o;
    p.run.asset.lods = o.run.asset.lods + 1;
    assert_true(opt_hash(&p, &in) != h0);
    p = o;
    p.thumbnails = 0;
    assert_true(opt_hash(&p, &in) != h0);
    sy_error err = {0};
    assert_int_equal(sy_batch_options_check(&o, &err), SY_OK);
    p = o;
    p.thumb_size = 2;
    assert_int_equal(sy_batch_options_check(&p, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "thumb_size"));
    p = o;
    p.task_count = 2;
    p.task_index = 2;
    assert_int_equal(sy_batch_options_check(&p, &err), SY_EUSAGE);
}

/* Out-of-range Slurm options are errors naming the field; a line break would
 * end its #SBATCH line and start a command of the script. */
static void slurm_options_are_checked(void **state)
{
    (void)state;
    sy_error err = {0};
    sy_slurm_options d = sy_slurm_options_default(), o;
    d.partition = "short";
    d.time = "01:00:00";
    d.mem = "4G";
    assert_int_equal(sy_slurm_options_check(&d, &err), SY_OK);
    o = d;
    o.array_size = -1;
    assert_int_equal(sy_slurm_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "array_size"));
    o = d;
    o.cpus = -2;
    assert_int_equal(sy_slurm_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "cpus"));
    o = d;
    o.partition = "short\nrm -rf x";
    assert_int_equal(sy_slurm_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "partition"));
    o = d;
    o.time = "1:00\r";
    assert_int_equal(sy_slurm_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "time"));
    o = d;
    o.mem = "4G\n";
    assert_int_equal(sy_slurm_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "mem"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(hash_is_fnv1a),
        cmocka_unit_test(folders_and_files),
        cmocka_unit_test(csv_manifest),
        cmocka_unit_test(json_manifest),
        cmocka_unit_test(options_text_tracks_outputs),
        cmocka_unit_test(slurm_options_are_checked),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
