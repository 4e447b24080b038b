/* libFuzzer target: arbitrary bytes through the PLY skeleton (AdTree layout, ascii and binary) reader. A
 * skeleton it returns must validate (the reader's promise). */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "stages/core/skeleton.h"
#include "stages/qsm/qsm.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sy_skeleton s;
    sy_skeleton_read_info info;
    sy_error err = {0};
    if (sy_skeleton_read_ply_mem("fuzz", data, size, &s, &info, &err) == SY_OK) {
        if (sy_skeleton_validate(&s, &err) != SY_OK) abort();
        sy_skeleton_free(&s);
    }
    return 0;
}
