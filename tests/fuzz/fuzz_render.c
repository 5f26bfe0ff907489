/* fuzz_render.c - the tracer on any JSON scene: parsed and validated as a render job does, then
 * prepared and traced small (32 x 24, the map's method: its tessellation, seams and raster, the
 * exact hierarchy for what the map leaves open and for shadow rays). Scenes of more than
 * FUZZ_RENDER_OBJECTS objects are only parsed: each input must take milliseconds. */
#include "../../api/scene_io.h"
#include "../../core/trace/render.h"
#include "fuzz.h"

#define FUZZ_RENDER_OBJECTS 64

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static struct bvh_device *dev;
    if (!dev && !(dev = bvh_device_new(1, NULL)))
        return 0;
    struct scene sc;
    enum image_format img;
    struct sf_err err = {0};
    if (scene_parse_json((const char *)data, size, NULL, &sc, &img, &err))
        return 0;
    if (sc.n_objects <= FUZZ_RENDER_OBJECTS) {
        sc.width = 32, sc.height = 24, sc.samples = 1, sc.method = METHOD_MAP;
        struct frame *fr;
        if (frame_prepare(&sc, dev, &fr, &err) == 0) {
            struct render_stats st = {0};
            frame_band(fr, 0, sc.height, &st);
            frame_free(fr);
        }
    }
    scene_free(&sc);
    return 0;
}
