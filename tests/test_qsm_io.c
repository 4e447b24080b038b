/* Skeleton / QSM interchange: rTwig's reference QSM.csv, round trips through
 * every written format, TreeQSM text fixtures, JSON skeleton and truth
 * files, .sylva, malformed inputs. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/grow/grow.h"
#include "stages/qsm/qsm.h"

/* ------------------------------------------------------------ a plain CSV table */

/* An independent reader of numeric CSV tables (header names trimmed), so the
 * tests compare against the file itself, not against the code under test. */
typedef struct {
    int cols;
    char names[32][32];
    size_t rows;
    double *v; /* rows x cols */
} table;

static void table_load(const char *path, table *t)
{
    memset(t, 0, sizeof *t);
    FILE *fp = fopen(path, "r");
    assert_non_null(fp);
    char line[4096];
    size_t cap = 0;
    int header = 1;
    while (fgets(line, sizeof line, fp)) {
        int c = 0;
        for (char *save = NULL, *tok = strtok_r(line, ",\r\n", &save); tok; tok = strtok_r(NULL, ",\r\n", &save)) {
            if (header) {
                while (*tok == ' ') tok++;
                char *end = tok + strlen(tok);
                while (end > tok && end[-1] == ' ') *--end = '\0';
                snprintf(t->names[c], sizeof t->names[c], "%s", tok);
            } else {
                if (t->rows == cap) {
                    cap = cap ? 2 * cap : 1024;
                    t->v = realloc(t->v, cap * 32 * sizeof(double));
                    assert_non_null(t->v);
                }
                t->v[t->rows * 32 + c] = strtod(tok, NULL);
            }
            c++;
        }
        if (header) t->cols = c;
        else {
            assert_int_equal(c, t->cols);
            t->rows++;
        }
        header = 0;
    }
    fclose(fp);
}

static double cell(const table *t, size_t row, const char *name)
{
    for (int c = 0; c < t->cols; c++)
        if (strcmp(t->names[c], name) == 0) return t->v[row * 32 + c];
    fail_msg("no column %s", name);
    return 0;
}

/* ------------------------------------------------------------ helpers */

static const char *qsm_csv(void) { return data_path("real/rtwig/QSM.csv"); }

static void read_ok(const char *path, sy_skeleton *s, sy_skeleton_read_info *info)
{
    sy_error err = {0};
    sy_code rc = sy_skeleton_read_ex(path, s, info, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
}

static void write_ok(const char *path, const sy_skeleton *s)
{
    sy_error err = {0};
    sy_code rc = sy_skeleton_write(path, s, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
}

static double world(const sy_skeleton *s, size_t i, int k) { return s->origin[k] + (double)s->pos[3 * i + k]; }

/* Same topology, radii, orders and branch ids exactly; world positions
 * within 1e-6 of the coordinate magnitude. Returns the largest position
 * error in metres. */
static double assert_same_skeleton(const sy_skeleton *a, const sy_skeleton *b)
{
    assert_int_equal(a->n, b->n);
    double worst = 0;
    for (size_t i = 0; i < a->n; i++) {
        assert_int_equal(a->parent[i], b->parent[i]);
        assert_int_equal(a->order[i], b->order[i]);
        assert_int_equal(a->branch[i], b->branch[i]);
        assert_true(a->radius[i] == b->radius[i]);
        for (int k = 0; k < 3; k++) {
            double wa = world(a, i, k), wb = world(b, i, k), d = fabs(wa - wb);
            if (d > worst) worst = d;
            assert_true(d <= 1e-6 * fmax(1.0, fabs(wa)));
        }
    }
    return worst;
}

static void grow_aspen(sy_skeleton *s)
{
    sy_species_params sp;
    sy_error err = {0};
    assert_int_equal(sy_species_params_find("quaking_aspen", &sp, &err), SY_OK);
    assert_int_equal(sy_grow_tree(&sp, 7, s, NULL, &err), SY_OK);
    sy_species_params_free(&sp);
}

static size_t zero_length_edges(const sy_skeleton *s)
{
    size_t z = 0;
    for (size_t i = 0; i < s->n; i++) {
        int32_t p = s->parent[i];
        if (p >= 0 && s->pos[3 * i] == s->pos[3 * p] && s->pos[3 * i + 1] == s->pos[3 * p + 1] &&
            s->pos[3 * i + 2] == s->pos[3 * p + 2])
            z++;
    }
    return z;
}

/* ------------------------------------------------------------ QSM.csv */

static void reads_rtwig_reference(void **state)
{
    (void)state;
    table t;
    table_load(qsm_csv(), &t);
    sy_skeleton s;
    sy_skeleton_read_info info;
    read_ok(qsm_csv(), &s, &info);
    assert_int_equal(info.format, SY_SKEL_CSV);
    assert_int_equal(info.records, t.rows);
    assert_int_equal(info.input_roots, 1);
    assert_int_equal(info.virtual_root, 0);
    assert_int_equal(info.gap_nodes, 0);
    /* One node per cylinder end plus the stem base. */
    assert_int_equal(s.n, t.rows + 1);
    double sum = 0, max_order = 0;
    for (size_t r = 0; r < t.rows; r++) {
        sum += cell(&t, r, "length");
        max_order = fmax(max_order, cell(&t, r, "branchOrder"));
    }
    double len = sy_skeleton_length(&s);
    assert_true(fabs(len - sum) <= 1e-4 * sum);
    int max_node_order = 0;
    for (size_t i = 0; i < s.n; i++) max_node_order = s.order[i] > max_node_order ? s.order[i] : max_node_order;
    assert_int_equal(max_node_order, (int)max_order);
    /* The base: the root and the first cylinder's end carry row 0's radius. */
    assert_true(s.radius[0] == (float)cell(&t, 0, "radius"));
    assert_true(s.radius[1] == (float)cell(&t, 0, "radius"));
    assert_true(s.radius[2] == (float)cell(&t, 1, "radius"));
    assert_true(fabs(world(&s, 0, 2) - cell(&t, 0, "startZ")) < 1e-5);
    /* rTwig's derived columns follow from the topology alone. */
    int32_t *rbo = calloc(s.n, sizeof *rbo);
    double *growth = calloc(s.n, sizeof *growth);
    sy_error err = {0};
    assert_int_equal(sy_skeleton_reverse_order(&s, rbo, &err), SY_OK);
    assert_int_equal(sy_skeleton_growth_length(&s, growth, &err), SY_OK);
    for (size_t r = 0; r < t.rows; r++) {
        assert_int_equal(rbo[r + 1], (int)cell(&t, r, "reverseBranchOrder"));
        assert_true(fabs(growth[r + 1] - cell(&t, r, "growthLength")) < 2e-4);
    }
    printf("QSM.csv: %zu cylinders -> %zu nodes, length %.6f m (column sum %.6f), max order %d\n", t.rows, s.n,
           len, sum, max_node_order);
    free(rbo);
    free(growth);
    free(t.v);
    sy_skeleton_free(&s);
}

static void csv_writer_reproduces_reference(void **state)
{
    (void)state;
    table a, b;
    table_load(qsm_csv(), &a);
    sy_skeleton s;
    read_ok(qsm_csv(), &s, NULL);
    const char *out = tmp_path("qsm_again.csv");
    write_ok(out, &s);
    table_load(out, &b);
    assert_int_equal(b.cols, 17);
    assert_int_equal(a.rows, b.rows);
    static const char *exact[] = {"ID", "parentID", "branchOrder", "segmentID", "parentSegmentID",
                                  "reverseBranchOrder"};
    static const char *coords[] = {"startX", "startY", "startZ", "endX", "endY", "endZ"};
    double worst = 0;
    for (size_t r = 0; r < a.rows; r++) {
        for (size_t k = 0; k < sizeof exact / sizeof *exact; k++)
            assert_true(cell(&a, r, exact[k]) == cell(&b, r, exact[k]));
        for (size_t k = 0; k < 6; k++) {
            double d = fabs(cell(&a, r, coords[k]) - cell(&b, r, coords[k]));
            worst = fmax(worst, d);
            assert_true(d <= 1e-6 * fmax(1.0, fabs(cell(&a, r, coords[k]))));
        }
        assert_true((float)cell(&a, r, "radius") == (float)cell(&b, r, "radius"));
        assert_true(fabs(cell(&a, r, "length") - cell(&b, r, "length")) < 2e-6);
        assert_true(fabs(cell(&a, r, "growthLength") - cell(&b, r, "growthLength")) < 2e-4);
    }
    /* branchID groups the same cylinders (its numbering is Sylva's). */
    for (size_t r = 0; r < a.rows; r++)
        for (size_t q = r + 1; q < a.rows; q += 37)
            assert_int_equal(cell(&a, r, "branchID") == cell(&a, q, "branchID"),
                             cell(&b, r, "branchID") == cell(&b, q, "branchID"));
    printf("QSM.csv rewritten: %zu rows, max coordinate change %.3g m\n", b.rows, worst);
    free(a.v);
    free(b.v);
    sy_skeleton_free(&s);
}

/* ------------------------------------------------------------ round trips */

static void round_trip_all(const sy_skeleton *s, const char *tag)
{
    static const char *exts[] = {"ply", "csv", "obj", "json"};
    for (size_t k = 0; k < 4; k++) {
        char name[64];
        snprintf(name, sizeof name, "%s.%s", tag, exts[k]);
        const char *path = tmp_path(name);
        write_ok(path, s);
        sy_skeleton back;
        sy_skeleton_read_info info;
        read_ok(path, &back, &info);
        assert_int_equal(info.derived_structure, 0);
        double worst = assert_same_skeleton(s, &back);
        if (strcmp(exts[k], "json") == 0) {
            /* The file names its float origin: same origin, and the same
             * floats wherever 17-digit world coordinates can carry them (all
             * of them at origin 0; within 1e-9 m of the float at UTM size). */
            assert_int_equal(info.origin_from_file, 1);
            for (int a = 0; a < 3; a++) assert_true(back.origin[a] == s->origin[a]);
            for (size_t i = 0; i < 3 * s->n; i++) {
                double d = fabs((double)back.pos[i] - (double)s->pos[i]);
                if (s->origin[0] == 0 && s->origin[1] == 0 && s->origin[2] == 0) assert_true(d == 0);
                else assert_true(d <= fmax(1e-9, 1e-7 * fabs(s->pos[i])));
            }
        }
        printf("%s -> %s -> sylva: %zu nodes, max position error %.3g m\n", tag, exts[k], back.n, worst);
        sy_skeleton_free(&back);
    }
}

static void round_trips_grown_tree(void **state)
{
    (void)state;
    sy_skeleton s;
    grow_aspen(&s);
    /* Split clones may start where their parent node sits; make sure some
     * zero-length edges are present, one of them at the root. */
    sy_error err = {0};
    int32_t nb = sy_skeleton_branch_count(&s);
    assert_true(sy_skeleton_add(&s, s.pos + 3 * 10, s.radius[10], 10, s.order[10] + 1, nb, &err) >= 0);
    assert_true(sy_skeleton_add(&s, s.pos, s.radius[0] * 0.5f, 0, 0, nb + 1, &err) >= 0);
    assert_int_equal(sy_skeleton_validate(&s, &err), SY_OK);
    printf("quaking_aspen seed 7: %zu nodes, %zu zero-length edges, %d branches\n", s.n, zero_length_edges(&s),
           sy_skeleton_branch_count(&s));
    round_trip_all(&s, "aspen");
    /* Far from the world origin the PLY switches to double coordinates. */
    s.origin[0] = 412345.25;
    s.origin[1] = 5712345.5;
    s.origin[2] = 253.0;
    round_trip_all(&s, "aspen_utm");
    sy_skeleton_free(&s);
}

static void round_trips_rtwig_skeleton(void **state)
{
    (void)state;
    sy_skeleton s;
    read_ok(qsm_csv(), &s, NULL);
    round_trip_all(&s, "rtwig");
    sy_skeleton_free(&s);
}

static char *slurp(const char *path, size_t *size)
{
    FILE *fp = fopen(path, "rb");
    assert_non_null(fp);
    fseek(fp, 0, SEEK_END);
    long n = ftell(fp);
    fseek(fp, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    assert_non_null(buf);
    assert_int_equal(fread(buf, 1, (size_t)n, fp), (size_t)n);
    buf[n] = '\0';
    fclose(fp);
    *size = (size_t)n;
    return buf;
}

static void json_writer_layout(void **state)
{
    (void)state;
    sy_skeleton s;
    read_ok(qsm_csv(), &s, NULL);
    const char *path = tmp_path("rtwig.json");
    write_ok(path, &s);
    size_t size;
    char *text = slurp(path, &size);
    assert_non_null(strstr(text, "{\"format\":\"sylva-skeleton\",\"version\":1,\"origin\":["));
    size_t ids = 0;
    for (const char *p = text; (p = strstr(p, "\"id\":")); p++) ids++;
    assert_int_equal(ids, s.n);
    /* The first node carries world coordinates and the root's parent. */
    const char *first = strstr(text, "{\"id\":0,\"parent\":-1,\"x\":");
    assert_non_null(first);
    double x = strtod(first + strlen("{\"id\":0,\"parent\":-1,\"x\":"), NULL);
    assert_true(fabs(x - 0.760564) < 1e-6);
    assert_int_equal(text[size - 1], '\n');
    free(text);
    sy_skeleton_free(&s);
}

/* ------------------------------------------------------------ TreeQSM text */

static void check_fixture(const sy_skeleton *s, const sy_skeleton_read_info *info)
{
    assert_int_equal(info->format, SY_SKEL_TREEQSM_TXT);
    assert_int_equal(info->records, 6);
    assert_int_equal(info->gap_nodes, 1);
    assert_int_equal(s->n, 8);
    assert_true(fabs(sy_skeleton_length(s) - 4.25) < 1e-5);
    assert_int_equal(sy_skeleton_branch_count(s), 3);
    /* Node 0 is the stem base; cylinder k's end is the next node but one
     * past the gap node that cylinder 4 brings. */
    assert_true(fabs(world(s, 0, 2) - 100.0) < 1e-5);
    assert_true(s->radius[0] == 0.2f);
    int order1 = 0;
    for (size_t i = 0; i < s->n; i++) order1 += s->order[i] == 1;
    assert_int_equal(order1, 4); /* cylinders 4, 5, 6 and the gap node */
    /* The gap node sits at cylinder 4's start and hangs from cylinder 1's end. */
    int found = 0;
    for (size_t i = 0; i < s->n; i++)
        if (fabs(world(s, i, 2) - 101.5) < 1e-5 && fabs(world(s, i, 0) - 10.0) < 1e-5) {
            found = 1;
            assert_true(fabs(world(s, s->parent[i], 2) - 101.0) < 1e-5);
            assert_true(s->radius[i] == 0.05f);
        }
    assert_true(found);
}

static void reads_treeqsm_text(void **state)
{
    (void)state;
    char path[4096];
    sy_skeleton a, b;
    sy_skeleton_read_info ia, ib;
    snprintf(path, sizeof path, "%s/data/qsm/cylinder_fixture.txt", SYLVA_TEST_DIR);
    read_ok(path, &a, &ia);
    check_fixture(&a, &ia);
    snprintf(path, sizeof path, "%s/data/qsm/cyl_data_fixture.txt", SYLVA_TEST_DIR);
    read_ok(path, &b, &ib);
    check_fixture(&b, &ib);
    assert_same_skeleton(&a, &b);
    sy_skeleton_free(&a);
    sy_skeleton_free(&b);
}

/* ------------------------------------------------------------ foreign graphs */

static void reads_adtree_style_ascii_ply(void **state)
{
    (void)state;
    /* Easy3D's layout without Sylva's extras, root not first: orders and
     * branches are derived and the lowest vertex becomes node 0. */
    const char *ply = "ply\nformat ascii 1.0\ncomment Saved by Easy3D\nelement vertex 5\n"
                      "property float x\nproperty float y\nproperty float z\nproperty float radius\n"
                      "element edge 4\nproperty list uint32 int vertex_indices\nend_header\n"
                      "0 0 1 0.1\n0 0 0 0.12\n0 0 2 0.08\n0.5 0 1.5 0.03\n0 0 3 0.05\n"
                      "2 1 0\n2 0 2\n2 2 4\n2 2 3\n";
    const char *path = tmp_path("adtree.ply");
    assert_int_equal(write_bytes(path, ply, strlen(ply)), 0);
    sy_skeleton s;
    sy_skeleton_read_info info;
    read_ok(path, &s, &info);
    assert_int_equal(info.derived_structure, 1);
    assert_int_equal(s.n, 5);
    assert_int_equal(s.parent[0], -1);
    assert_true(world(&s, 0, 2) == 0.0);
    assert_true(s.radius[0] == 0.12f);
    /* The side twig (0.5, 0, 1.5) is order 1 on its own branch. */
    int side = -1;
    for (size_t i = 0; i < s.n; i++)
        if (world(&s, i, 0) > 0.4) side = (int)i;
    assert_true(side >= 0);
    assert_int_equal(s.order[side], 1);
    assert_int_not_equal(s.branch[side], s.branch[0]);
    assert_int_equal(sy_skeleton_branch_count(&s), 2);
    sy_skeleton_free(&s);
}

/* ------------------------------------------------------------ malformed */

static void fails_with(const char *name, const char *text, const char *where, const char *needle)
{
    const char *path = tmp_path(name);
    assert_int_equal(write_bytes(path, text, strlen(text)), 0);
    sy_skeleton s;
    sy_error err = {0};
    assert_int_equal(sy_skeleton_read(path, &s, &err), SY_EINPUT);
    char want[4200];
    snprintf(want, sizeof want, "%s%s", path, where);
    if (!strstr(err.msg, want) || !strstr(err.msg, needle)) fprintf(stderr, "message: %s\n", err.msg);
    assert_non_null(strstr(err.msg, want));
    assert_non_null(strstr(err.msg, needle));
    assert_null(strchr(err.msg, '\n'));
    assert_int_equal(s.n, 0);
}

#define HDR "ID,parentID,startX,startY,startZ,endX,endY,endZ,radius,branchOrder,segmentID\n"

static void malformed_inputs_name_file_and_line(void **state)
{
    (void)state;
    fails_with("num.csv", HDR "0,-1,0,0,0,0,0,1,0.1,0,0\n1,0,0,0,1,0,0,x2,0.1,0,0\n", ":3:", "malformed number");
    fails_with("col.csv", "ID,parentID,startX,startY,startZ,endX,endY,endZ\n0,-1,0,0,0,0,0,1\n", ":1:",
               "missing column radius");
    fails_with("par.csv", HDR "0,-1,0,0,0,0,0,1,0.1,0,0\n1,7,0,0,1,0,0,2,0.1,0,0\n", ":3:", "parent ID 7 not found");
    fails_with("cyc.csv", HDR "0,-1,0,0,0,0,0,1,0.1,0,0\n1,2,0,0,1,0,0,2,0.1,0,0\n2,1,0,0,2,0,0,3,0.1,0,0\n", ":",
               "cycle");
    fails_with("neg.csv", HDR "0,-1,0,0,0,0,0,1,0.1,0,0\n1,0,0,0,1,0,0,2,-0.1,0,0\n", ":3:", "negative radius");
    fails_with("nan.csv", HDR "0,-1,0,0,0,0,0,1,0.1,0,0\n1,0,0,0,1,0,NaN,2,0.1,0,0\n", ":3:", "not finite");
    fails_with("dup.csv", HDR "0,-1,0,0,0,0,0,1,0.1,0,0\n0,-1,0,0,1,0,0,2,0.1,0,0\n", ":3:", "duplicate cylinder ID 0");
    fails_with("short.csv", HDR "0,-1,0,0,0,0,0,1,0.1,0\n", ":2:", "10 fields");
    fails_with("cols.txt", "0.2\t1\t10\t20\t100\t0\t0\t1\t0\t2\t1\t0\t1\t0\t0.2\n0.1\t1\n", ":2:", "columns");
    fails_with("rad.txt", "-0.2\t1\t10\t20\t100\t0\t0\t1\t0\t2\t1\t0\t1\t0\t0.2\n", ":1:", "negative radius");
    fails_with("norad.obj", "v 0 0 0\n# radius 0.1\nv 0 0 1\nl 1 2\n", ":3:", "no '# radius'");
    fails_with("loop.obj", "v 0 0 0\n# radius 0.1\nv 0 0 1\n# radius 0.1\nv 0 1 1\n# radius 0.1\nl 1 2 3 1\n",
               ":7:", "closes a cycle");
    fails_with("far.obj", "v 0 0 0\n# radius 0.1\nv 0 0 1\n# radius 0.1\nl 1 5\n", ":5:", "beyond");
    fails_with("trunc.ply",
               "ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\nproperty float y\n"
               "property float z\nproperty float radius\nelement edge 99\nproperty list uint32 int vertex_indices\n"
               "end_header\n\x01\x02",
               ": element vertex", "more than the file holds");
    fails_with("bad.ply",
               "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
               "property float radius\nelement edge 1\nproperty list uchar int vertex_indices\nend_header\n"
               "0 0 0 0.1\n0 0 1 oops\n2 0 1\n",
               ":12", "truncated or malformed vertex data");
    fails_with("empty.csv", "", ":", "empty file");
}


/* ------------------------------------------------------------ JSON in */

static void reads_truth_layout_and_picks_trees(void **state)
{
    (void)state;
    const char *node0 = "{\"id\":0,\"parent\":-1,\"x\":500000.5,\"y\":4100000.25,\"z\":12,\"radius\":0.15,"
                        "\"order\":0,\"branch\":0}";
    char one[1024], two[2048];
    snprintf(one, sizeof one,
             "{\"format\":\"sylva-truth\",\"version\":1,\"trees\":[{\"tree_id\":1,\"nodes\":[%s,"
             "{\"id\":1,\"parent\":0,\"x\":500000.5,\"y\":4100000.25,\"z\":15,\"radius\":0.05,\"order\":0,"
             "\"branch\":0}]}]}",
             node0);
    snprintf(two, sizeof two,
             "{\"format\":\"sylva-truth\",\"version\":1,\"trees\":[{\"nodes\":[%s]},{\"nodes\":["
             "{\"parent\":-1,\"x\":10,\"y\":20,\"z\":1,\"radius\":0.2},{\"parent\":0,\"x\":10,\"y\":20,\"z\":4,"
             "\"radius\":0.1},{\"parent\":1,\"x\":10,\"y\":20,\"z\":6,\"radius\":0.05},"
             "{\"parent\":1,\"x\":11,\"y\":20,\"z\":5,\"radius\":0.02}]}]}",
             node0);
    const char *p1 = tmp_path("truth_one.json"), *p2 = tmp_path("truth_two.json");
    assert_int_equal(write_bytes(p1, one, strlen(one)), 0);
    assert_int_equal(write_bytes(p2, two, strlen(two)), 0);
    sy_skeleton s;
    sy_skeleton_read_info info;
    sy_error err = {0};
    read_ok(p1, &s, &info);
    assert_int_equal(info.format, SY_SKEL_JSON);
    assert_int_equal(s.n, 2);
    /* No origin in a truth file: floor() of the root, positions exact. */
    assert_true(s.origin[0] == 500000 && s.origin[1] == 4100000 && s.origin[2] == 12);
    assert_true(s.pos[0] == 0.5f && s.pos[1] == 0.25f && s.pos[5] == 3.0f);
    assert_true(s.radius[1] == 0.05f);
    sy_skeleton_free(&s);
    /* Several trees: refused without an index, the message naming the file and the count. */
    assert_int_equal(sy_skeleton_read(p2, &s, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, p2));
    assert_non_null(strstr(err.msg, "holds 2 trees"));
    assert_int_equal(s.n, 0);
    assert_int_equal(sy_skeleton_read_tree(p2, 1, &s, &info, &err), SY_OK);
    assert_int_equal(s.n, 4);
    assert_int_equal(info.derived_structure, 1); /* no order/branch in tree 1 */
    assert_int_equal(s.order[2], 0);             /* the longer child continues the stem */
    assert_int_equal(s.order[3], 1);
    assert_true(s.branch[3] != s.branch[2]);
    sy_skeleton_free(&s);
    assert_int_equal(sy_skeleton_read_tree(p2, 2, &s, &info, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "tree 2 asked for"));
    /* Other formats hold one tree. */
    assert_int_equal(sy_skeleton_read_tree(qsm_csv(), 1, &s, &info, &err), SY_EINPUT);
    assert_int_equal(sy_skeleton_read_tree(qsm_csv(), 0, &s, &info, &err), SY_OK);
    assert_int_equal(s.n, 1150);
    sy_skeleton_free(&s);
}

static void malformed_json_names_file_and_place(void **state)
{
    (void)state;
    fails_with("j_syntax.json", "{\"nodes\":[{\"parent\":-1,]}", ":1:", "");
    fails_with("j_empty.json", "{\"nodes\":[]}", ":1:", "'nodes' is empty");
    fails_with("j_z.json", "{\"nodes\":[{\"parent\":-1,\"x\":0,\"y\":0,\"radius\":1}]}", ":1:", "'z' is missing");
    fails_with("j_r.json", "{\"nodes\":[{\"parent\":-1,\"x\":0,\"y\":0,\"z\":0,\"radius\":0}]}", ":1:",
               "'radius' must be a number > 0");
    fails_with("j_par.json", "{\"nodes\":[\n{\"parent\":-1,\"x\":0,\"y\":0,\"z\":0,\"radius\":1},\n"
                             "{\"parent\":1.5,\"x\":0,\"y\":0,\"z\":1,\"radius\":1}]}",
               ":3:", "node 1: 'parent' must be -1 or");
    fails_with("j_roots.json", "{\"nodes\":[{\"parent\":-1,\"x\":0,\"y\":0,\"z\":0,\"radius\":1},"
                               "{\"parent\":-1,\"x\":0,\"y\":0,\"z\":1,\"radius\":1}]}",
               ":1:", "2 root nodes");
    fails_with("j_cycle.json", "{\"nodes\":[{\"parent\":-1,\"x\":0,\"y\":0,\"z\":0,\"radius\":1},\n"
                               "{\"parent\":2,\"x\":0,\"y\":0,\"z\":1,\"radius\":1},\n"
                               "{\"parent\":1,\"x\":0,\"y\":0,\"z\":2,\"radius\":1}]}",
               ":", "cycle");
    fails_with("j_id.json", "{\"nodes\":[{\"id\":4,\"parent\":-1,\"x\":0,\"y\":0,\"z\":0,\"radius\":1}]}", ":1:",
               "'id' must equal");
    fails_with("j_fmt.json", "{\"format\":\"other\",\"nodes\":[]}", ":1:", "'format' must be");
    fails_with("j_ver.json", "{\"version\":2,\"nodes\":[]}", ":1:", "only version 1");
    fails_with("j_none.json", "{\"foo\":1}", ":1:", "neither 'trees'");
    fails_with("j_origin.json", "{\"origin\":[1,2],\"nodes\":[]}", ":1:", "'origin' must be [x, y, z]");
    fails_with("j_trees.json", "{\"trees\":[]}", ":1:", "'trees' is empty");
}

static void sylva_file_round_trip(void **state)
{
    (void)state;
    sy_skeleton s, back;
    sy_skeleton_read_info info;
    read_ok(qsm_csv(), &s, NULL);
    const char *path = tmp_path("rtwig.sylva");
    write_ok(path, &s);
    read_ok(path, &back, &info);
    assert_int_equal(info.format, SY_SKEL_SYLVA);
    assert_int_equal(back.n, s.n);
    /* Quantised: 16-bit positions over a ~4 m tree (step 2^-14 m), log radii. */
    double len_a = sy_skeleton_length(&s), len_b = sy_skeleton_length(&back);
    assert_true(fabs(len_a - len_b) < 1e-3 * len_a);
    assert_true(fabs(back.origin[2] + back.pos[2] - (s.origin[2] + s.pos[2])) < 1e-4);
    sy_skeleton_free(&back);
    sy_skeleton_free(&s);
}

static void writer_rejects_unknown_extension_and_keeps_no_partial_file(void **state)
{
    (void)state;
    sy_skeleton s;
    read_ok(qsm_csv(), &s, NULL);
    sy_error err = {0};
    const char *path = tmp_path("tree.xyz");
    assert_int_equal(sy_skeleton_write(path, &s, &err), SY_EUSAGE);
    assert_false(file_exists(path));
    /* An invalid skeleton (two roots) is refused before any file appears. */
    s.parent[5] = -1;
    path = tmp_path("broken.ply");
    assert_int_equal(sy_skeleton_write(path, &s, &err), SY_EINPUT);
    assert_false(file_exists(path));
    sy_skeleton_free(&s);
}

static void sniffs_content_before_extension(void **state)
{
    (void)state;
    const unsigned char csv[] = " ID, parentID, startX\n0,-1,0\n";
    const unsigned char obj[] = "# c\nv 0 0 0\n";
    const unsigned char ply[] = "ply\nformat ascii 1.0\n";
    const unsigned char txt[] = "0.2\t1\t10\t20\t100\t0\t0\t1\t0\t2\t1\t0\t1\t0\t0.2\n";
    assert_int_equal(sy_skeleton_sniff("a.txt", csv, sizeof csv - 1), SY_SKEL_CSV);
    assert_int_equal(sy_skeleton_sniff("a.dat", obj, sizeof obj - 1), SY_SKEL_OBJ);
    assert_int_equal(sy_skeleton_sniff("a.obj", ply, sizeof ply - 1), SY_SKEL_PLY);
    assert_int_equal(sy_skeleton_sniff("a.csv", txt, sizeof txt - 1), SY_SKEL_TREEQSM_TXT);
    assert_int_equal(sy_skeleton_sniff("a.json", (const unsigned char *)"", 0), SY_SKEL_JSON);
    assert_int_equal(sy_skeleton_sniff("a.bin", (const unsigned char *)"\x01\x02", 2), SY_SKEL_UNKNOWN);
    assert_int_equal(sy_skeleton_sniff("a.ply", (const unsigned char *)"SYLV\x01", 5), SY_SKEL_SYLVA);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(reads_rtwig_reference),
        cmocka_unit_test(csv_writer_reproduces_reference),
        cmocka_unit_test(round_trips_grown_tree),
        cmocka_unit_test(round_trips_rtwig_skeleton),
        cmocka_unit_test(json_writer_layout),
        cmocka_unit_test(reads_treeqsm_text),
        cmocka_unit_test(reads_adtree_style_ascii_ply),
        cmocka_unit_test(malformed_inputs_name_file_and_line),
        cmocka_unit_test(reads_truth_layout_and_picks_trees),
        cmocka_unit_test(malformed_json_names_file_and_place),
        cmocka_unit_test(sylva_file_round_trip),
        cmocka_unit_test(writer_rejects_unknown_extension_and_keeps_no_partial_file),
        cmocka_unit_test(sniffs_content_before_extension),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
