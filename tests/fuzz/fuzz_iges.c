/* fuzz_iges.c - IGES files: parse (entities, trim loops, their index), then extract the patches and
 * measure the trimmed surfaces as /volume does (quadrature over the trim regions, closure along
 * the loops). */
#include "../../core/geom/enclosed.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct scene sc;
    struct sf_err err = {0};
    char *text = fuzz_text(data, size);
    if (text && scene_parse_iges(text, size, &sc, &err) == 0) {
        struct patch_set ps;
        if (scene_patches(&sc, &ps, &err) == 0) {
            struct enclosed e;
            enclosed_measure(&ps, &e);
            nurbs_patch_set_free(&ps);
        }
        struct shell_part *parts = malloc(sizeof *parts * (size_t)sc.n_objects);
        signed char *sign = malloc((size_t)sc.n_objects);
        struct shell sh;
        for (int k = 0; parts && k < sc.n_objects; k++)
            parts[k] = (struct shell_part){&sc.objects[k].surf, sc.objects[k].trim};
        if (parts && sign)
            enclosed_shell(parts, sc.n_objects, 1e-3, NULL, &sh, sign);
        free(parts);
        free(sign);
        scene_free(&sc);
    }
    free(text);
    return 0;
}
