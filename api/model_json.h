/* model_json.h - a model's figures as the JSON of API.md's model resource (the fields that exist
 * so far: name, method, caps, slices, patches, volume_mm3, area_mm2, volume {exact, trapezoid,
 * cavalieri, frustum}, bounds, timings_ms). */
#ifndef SURFD_MODEL_JSON_H
#define SURFD_MODEL_JSON_H

#include <stddef.h>

#include "../core/err.h"
#include "contour_json.h"

/* Reads contours (format "json", or "dicom" for an RT Structure Set), builds the model and measures
 * it; *json receives the figures (caller frees): one object for JSON or for a DICOM ?roi=NAME, else
 * {"models": [...]} with one object per ROI. options: "roi=NAME&caps=flat|slab" (DICOM; JSON carries
 * its own). Errors as contour_parse_json and rtstruct_read. */
int model_figures(const char *buf, size_t len, const char *format, const char *options, char **json,
                  struct sf_err *err);
/* What model_figures would refuse, without modelling anything (for request handlers). */
int model_validate(const char *buf, size_t len, const char *format, const char *options, struct sf_err *err);

#endif
