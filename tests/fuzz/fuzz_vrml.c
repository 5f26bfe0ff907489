/* fuzz_vrml.c - VRML97 NurbsSurface fragments: parse, then validate and extract the patches. */
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_text_scene(data, size, scene_parse_vrml);
    return 0;
}
