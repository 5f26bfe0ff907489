/* fuzz_scene_json.c - the JSON scene of API.md: parse, then validate and extract every surface's
 * Bézier patches, as a render job does before tracing. */
#include "../../api/scene_io.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct scene sc;
    enum image_format img;
    struct sf_err err = {0};
    if (scene_parse_json((const char *)data, size, NULL, &sc, &img, &err) == 0) {
        struct patch_set ps;
        if (scene_validate(&sc, &err) == 0 && scene_patches(&sc, &ps, &err) == 0)
            nurbs_patch_set_free(&ps);
        scene_free(&sc);
    }
    return 0;
}
