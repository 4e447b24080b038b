/* libFuzzer target: arbitrary bytes through the species .ini parser
 * (Weber-Penn parameters and Sylva's own keys): every value out of range,
 * every malformed line fails with a code, never a crash, hang or leak. */
#include <stddef.h>
#include <stdint.h>

#include "species/params.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sy_species_params sp;
    sy_error err = {0};
    if (sy_species_params_parse((const char *)data, size, "fuzz.ini", "/nonexistent", &sp, &err) == SY_OK)
        sy_species_params_free(&sp);
    return 0;
}
