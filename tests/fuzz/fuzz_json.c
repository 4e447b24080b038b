/* libFuzzer target: the JSON DOM reader over arbitrary bytes, then the same
 * bytes as a truth/skeleton file (eval's forest, and qsm_io's skeleton
 * reader for the only tree and for tree 1, and the .sylva JSON form). All must return a code, never crash,
 * hang or leak; a parsed DOM is walked in full so every node is touched. */
#include <stddef.h>
#include <stdint.h>

#include "stages/core/json_read.h"
#include "stages/qsm/sylva_json.h"
#include "stages/eval/eval.h"
#include "stages/qsm/qsm.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static size_t walk(const sy_jv *v)
{
    size_t n = 1;
    for (size_t i = 0; i < sy_jv_count(v); i++) n += walk(&v->items[i]);
    return n + (v->type == SY_JV_STRING ? v->len : 0);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sy_jv *v;
    sy_error err = {0};
    sy_jv_limits lim = {64, 1 << 20};
    if (sy_jv_parse("fuzz.json", (const char *)data, size, &lim, &v, &err) == SY_OK) {
        volatile size_t n = walk(v);
        (void)n;
        sy_skeleton s;
        sy_clusters cl;
        sy_sylva_meta meta;
        int has_quant;
        if (sy_sylva_json_from_doc("fuzz.json", v, &s, &cl, &meta, &has_quant, &err) == SY_OK) {
            sy_skeleton_free(&s);
            sy_clusters_free(&cl);
        }
        sy_jv_free(v);
    }
    sy_forest f;
    if (sy_forest_parse("fuzz.json", (const char *)data, size, &f, &err) == SY_OK) sy_forest_free(&f);
    for (long tree = -1; tree <= 1; tree += 2) {
        sy_skeleton s;
        if (sy_skeleton_read_json_tree("fuzz.json", data, size, tree, &s, NULL, &err) == SY_OK) sy_skeleton_free(&s);
    }
    return 0;
}
