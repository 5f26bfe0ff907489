/* fuzz_bpt.c - Newell's .bpt patch files: parse, then validate and extract the patches. */
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_text_scene(data, size, scene_parse_bpt);
    return 0;
}
