/* libFuzzer target: COLMAP cameras.txt / cameras.bin through the model
 * reader. The first byte picks the kind (even: text, odd: binary); the rest
 * is the file. images and points3D are fixed and reference nothing, so every
 * input that parses as cameras also runs the model summary. */
#include <stddef.h>
#include <stdint.h>

#include "stages/ingest/ingest.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0) return 0;
    static const char points[] = "1 0.5 1.5 2.5 10 20 30 0.25\n";
    sy_colmap_file cameras = {"fuzz_cameras", data + 1, size - 1, data[0] & 1};
    sy_colmap_file images = {"fuzz_images.txt", (const unsigned char *)"", 0, 0};
    sy_colmap_file pts = {"fuzz_points3D.txt", (const unsigned char *)points, sizeof points - 1, 0};
    sy_cloud c;
    sy_error err;
    if (sy_read_colmap_model_mem(&cameras, &images, &pts, &c, &err) == SY_OK) sy_cloud_free(&c);
    return 0;
}
