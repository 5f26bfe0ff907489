/* fuzz_request.c - a request's query options with its body, as the routes take them: the first
 * line is the query string, the rest the body. Render options with a scene (format sniffed),
 * contour options with contours, mesh and structure set options alone. */
#include "../../api/model_json.h"
#include "../../api/render_request.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *body;
    size_t len;
    char *text = fuzz_request(data, size, &body, &len);
    if (!text)
        return 0;
    struct scene sc;
    enum image_format img;
    struct sf_err err = {0};
    if (render_request_parse(body, len, "", text, NULL, &sc, &img, &err) == 0)
        scene_free(&sc);
    struct sf_err err2 = {0};
    model_validate(body, len, "json", text, &err2);
    const char *format;
    double tol;
    struct sf_err err3 = {0};
    model_mesh_options(text, &format, &tol, &err3);
    struct sf_err err4 = {0};
    model_rtstruct_options(text, &tol, &err4);
    free(text);
    return 0;
}
