/* libFuzzer target: the LAS reader over arbitrary bytes must return a code,
 * never crash, hang or allocate from an unchecked header count; and the
 * streaming pass of `sylva info` (sy_las_info_mem) must, where it answers,
 * agree with the whole reader: same acceptance, count and bounds. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "stages/ingest/ingest.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sy_cloud c, meta;
    sy_error err = {0}, ierr = {0};
    sy_code rc = sy_read_las_mem("fuzz.las", data, size, &c, &err);
    if (rc == SY_OK && (c.n == 0 || sy_cloud_check_range(&c, "fuzz.las", &err))) rc = SY_EINPUT;
    size_t n = 0;
    double lo[3], hi[3], flo[3], fhi[3];
    int done = 0;
    sy_code irc = sy_las_info_mem("fuzz.las", data, size, -1, &meta, &n, lo, hi, &done, &ierr);
    if (done) {
        if (rc != SY_OK || n != c.n) abort();
        sy_cloud_bounds(&c, flo, fhi);
        for (int k = 0; k < 3; k++)
            if (lo[k] != flo[k] || hi[k] != fhi[k]) abort();
        sy_cloud_free(&meta);
    } else if (irc != SY_OK && rc == SY_OK) {
        abort(); /* info refused a file the reader takes */
    }
    sy_cloud_free(&c);
    return 0;
}
