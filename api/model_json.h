/* model_json.h - a model's figures as the JSON of API.md's model resource (the fields that exist
 * so far: name, method, caps, slices, patches, volume_mm3, area_mm2, volume {exact, trapezoid,
 * cavalieri, frustum}, bounds, timings_ms). */
#ifndef SURFD_MODEL_JSON_H
#define SURFD_MODEL_JSON_H

#include <stddef.h>

#include "../core/err.h"
#include "contour_json.h"

/* Reads contour JSON, builds the model and measures it; *json receives the figures (caller
 * frees). Errors as contour_parse_json. */
int model_figures(const char *buf, size_t len, char **json, struct sf_err *err);

#endif
