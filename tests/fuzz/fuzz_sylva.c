/* libFuzzer target for the .sylva decoder. The first byte picks the mode:
 * odd feeds the rest as is (exercises the checksum and header checks), even
 * appends a valid checksum first so the structural checks behind it are
 * reached. A decoded tree must re-encode with its own grid and decode again. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "stages/encode/encode.h"

static uint32_t crc32_ref(const unsigned char *p, size_t n)
{
    uint32_t c = 0xffffffffu;
    for (size_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int k = 0; k < 8; k++) c = (c & 1) ? (c >> 1) ^ 0xedb88320u : c >> 1;
    }
    return ~c;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    int seal = !(data[0] & 1);
    data++;
    size--;
    unsigned char *buf = malloc(size + 4);
    if (!buf) return 0;
    memcpy(buf, data, size);
    size_t n = size;
    if (seal) {
        uint32_t c = crc32_ref(buf, size);
        for (int i = 0; i < 4; i++) buf[size + i] = (unsigned char)(c >> (8 * i));
        n += 4;
    }
    sy_skeleton s;
    sy_clusters cl;
    sy_sylva_meta meta;
    sy_error err;
    if (sy_decode_mem("fuzz.sylva", buf, n, &s, &cl, &meta, &err) == SY_OK) {
        if (sy_skeleton_validate(&s, &err) != SY_OK) abort();
        unsigned char *again;
        size_t again_size;
        if (sy_encode_mem(&s, &cl, meta.species_id, meta.seed, &meta.quant, &again, &again_size, &err) != SY_OK)
            abort();
        sy_skeleton s2;
        sy_clusters cl2;
        sy_sylva_meta meta2;
        if (sy_decode_mem("again.sylva", again, again_size, &s2, &cl2, &meta2, &err) != SY_OK) abort();
        if (s2.n != s.n || cl2.n != cl.n) abort();
        free(again);
        sy_skeleton_free(&s2);
        sy_clusters_free(&cl2);
        sy_skeleton_free(&s);
        sy_clusters_free(&cl);
    } else if (err.code != SY_EINPUT || !strstr(err.msg, "fuzz.sylva")) {
        abort();
    }
    free(buf);
    return 0;
}
