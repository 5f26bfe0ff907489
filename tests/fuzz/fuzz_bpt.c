/* fuzz_bpt.c - Newell's .bpt patch files: parse, then validate and extract the patches. */
#include "../../api/scene_io.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct scene sc;
    struct sf_err err = {0};
    char *text = fuzz_text(data, size);
    if (text && scene_parse_bpt(text, size, &sc, &err) == 0) {
        struct patch_set ps;
        if (scene_patches(&sc, &ps, &err) == 0)
            nurbs_patch_set_free(&ps);
        scene_free(&sc);
    }
    free(text);
    return 0;
}
