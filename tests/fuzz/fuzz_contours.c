/* fuzz_contours.c - contour JSON: parse and clean; small inputs are also modelled and measured
 * (the volume job's whole path), large ones only parsed, to keep each run short. */
#include "../../api/contour_json.h"
#include "../../api/model_json.h"
#include "fuzz.h"

#define MODEL_MAX_INPUT 4096 /* bytes: inputs up to this size are modelled too */

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct contour_set cs;
    struct contour_request req;
    struct sf_err err = {0};
    if (contour_parse_json((const char *)data, size, &cs, &req, &err) == 0) {
        contour_set_free(&cs);
        char *json = NULL;
        struct sf_err err2 = {0};
        if (size <= MODEL_MAX_INPUT && model_figures((const char *)data, size, "json", "", NULL, &json, &err2) == 0)
            free(json);
    }
    return 0;
}
