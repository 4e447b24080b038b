/* libFuzzer target: arbitrary bytes through the species CSV reader of
 * `sylva eval --species` (id,species rows, optional header, quotes). */
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <stdlib.h>

#include "stages/eval/eval.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sy_label_table t;
    sy_error err = {0};
    if (sy_label_table_parse_csv("fuzz.csv", (const char *)data, size, &t, &err) == SY_OK) {
        /* Every row the reader keeps has an id and a label. */
        for (size_t i = 0; i < t.n; i++)
            if (!t.id[i] || !t.label[i]) abort();
        sy_label_table_free(&t);
    }
    return 0;
}
