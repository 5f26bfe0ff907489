/* fuzz_contours.c - contour JSON: parse and clean; small inputs are also modelled and measured
 * (the volume job's whole path), meshed (the caps joined where tubes meet: join.c) and their joined
 * planes taken as /patches exports them (solid_join_caps), large ones only parsed, to keep each run
 * short. */
#include "../../api/contour_json.h"
#include "../../api/model_json.h"
#include "../../core/contour/solid.h"
#include "fuzz.h"

#define MODEL_MAX_INPUT 4096 /* bytes: inputs up to this size are modelled too */

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct contour_set cs;
    struct contour_request req;
    struct sf_err err = {0};
    if (contour_parse_json((const char *)data, size, &cs, &req, &err) == 0) {
        struct solid sd;
        if (size <= MODEL_MAX_INPUT && solid_build(&cs, (struct model_opts){.method = MODEL_PARABOLIC, .unfold = true, .closed = true}, CAPS_FLAT, &sd,
                                                   &err) == 0) {
            struct solid_measures sm;
            struct solid_mesh m;
            solid_measure(&sd, &sm);
            if (solid_mesh(&sd, 10 * solid_default_tolerance(&sm), &m) == 0)
                solid_mesh_free(&m);
            bool *skip = malloc(sizeof *skip * (size_t)(sd.n_bands ? sd.n_bands : 1));
            struct cap_regions regions; /* the planes where tubes meet, as /patches exports them */
            if (skip && solid_join_caps(&sd, 10 * solid_default_tolerance(&sm), &regions, skip) == 0)
                solid_cap_regions_free(&regions);
            free(skip);
            solid_free(&sd);
        }
        contour_set_free(&cs);
        char *json = NULL;
        struct sf_err err2 = {0};
        if (size <= MODEL_MAX_INPUT && model_figures((const char *)data, size, "json", "", NULL, &json, &err2) == 0)
            free(json);
    }
    return 0;
}
