/* render_request.h - a POST /render request as the daemon stores it (body, body format, query
 * options) into a scene and an output format. The same function validates at submission and
 * rebuilds the scene when a worker (or a restarted daemon) runs the job. */
#ifndef SURFD_RENDER_REQUEST_H
#define SURFD_RENDER_REQUEST_H

#include <stddef.h>

#include "../core/base/err.h"
#include "../core/trace/scene.h"
#include "scene_io.h"

/* Applies a query string of overrides to sc: output=png|exr|tiff, method=, width=, height=,
 * azimuth=, elevation=, shadows=0|1, samples=N, aovs=normal,uv,id, projection=perspective|orthographic, view=+x|-x|+y|-y|+z|-z,
 * view_height=, eye=x,y,z, target=x,y,z (with eye unless the scene has a camera), up=x,y,z, fov=;
 * errors point at "?name". Not validated (scene_validate does that). */
int render_options_apply(const char *options, struct scene *sc, enum image_format *img, struct sf_err *err);

/* format: "json", "bpt", "nurbs" or "" (sniffed). options: as render_options_apply. models
 * resolves stored-model objects (NULL: refused). */
int render_request_parse(const char *body, size_t len, const char *format, const char *options,
                         const struct model_resolver *models, struct scene *sc, enum image_format *img,
                         struct sf_err *err);

#endif
