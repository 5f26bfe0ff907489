/* render_request.h - a POST /render request as the daemon stores it (body, body format, query
 * options) into a scene and an output format. The same function validates at submission and
 * rebuilds the scene when a worker (or a restarted daemon) runs the job. */
#ifndef SURFD_RENDER_REQUEST_H
#define SURFD_RENDER_REQUEST_H

#include <stddef.h>

#include "../core/base/err.h"
#include "../core/trace/scene.h"
#include "scene_io.h"

/* format: "json", "bpt", "nurbs" or "" (sniffed). options: a query string of overrides
 * (output=png|exr|tiff, method=, width=, height=, azimuth=, elevation=, shadows=0|1); errors in
 * them point at "?name". models resolves stored-model objects (NULL: refused). */
int render_request_parse(const char *body, size_t len, const char *format, const char *options,
                         const struct model_resolver *models, struct scene *sc, enum image_format *img,
                         struct sf_err *err);

/* Media type to scene format: application/json, model/x-bpt, model/vrml; text/plain,
 * application/octet-stream and application/x-www-form-urlencoded (curl -d) are sniffed.
 * Returns NULL for a type surfd does not read (415). */
const char *render_format_from_type(const char *content_type);

#endif
