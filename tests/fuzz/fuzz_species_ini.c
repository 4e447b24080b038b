/* libFuzzer target: arbitrary bytes through the species .ini parser
 * (Weber-Penn parameters and Sylva's own keys). A species it accepts must
 * parse again from its JSON-free defaults path without leaking. */
#include <stddef.h>
#include <stdint.h>

#include "stages/grow/grow.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sy_species sp;
    sy_error err = {0};
    if (sy_species_parse((const char *)data, size, "fuzz.ini", "/nonexistent", &sp, &err) == SY_OK)
        sy_species_free(&sp);
    return 0;
}
