/* libFuzzer target: COLMAP images.txt / images.bin through the model reader.
 * The first byte picks the kind (even: text, odd: binary); the rest is the
 * file. cameras defines cameras 1 and 2 and points3D's track names images 1
 * and 2, so the image -> camera and track -> image checks both run. */
#include <stddef.h>
#include <stdint.h>

#include "stages/ingest/ingest.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0) return 0;
    static const char cams[] = "1 SIMPLE_PINHOLE 640 480 500 320 240\n"
                               "2 PINHOLE 1024 768 800 810 512 384\n";
    static const char points[] = "1 0.5 1.5 2.5 10 20 30 0.25 1 0 2 3\n";
    sy_colmap_file cameras = {"fuzz_cameras.txt", (const unsigned char *)cams, sizeof cams - 1, 0};
    sy_colmap_file images = {"fuzz_images", data + 1, size - 1, data[0] & 1};
    sy_colmap_file pts = {"fuzz_points3D.txt", (const unsigned char *)points, sizeof points - 1, 0};
    sy_cloud c;
    sy_error err;
    if (sy_read_colmap_model_mem(&cameras, &images, &pts, &c, &err) == SY_OK) sy_cloud_free(&c);
    return 0;
}
