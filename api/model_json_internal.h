/* model_json_internal.h - what the files of model_json.h share (model_json.c, model_scene.c,
 * model_matrix.c, model_mesh.c, model_rtstruct.c, model_patches.c, model_seg.c): small helpers and
 * the functions one file calls in another. Private to those files. Calls go one way: model_json.c ->
 * model_scene.c, model_matrix.c; model_rtstruct.c, model_patches.c -> model_mesh.c; model_seg.c ->
 * model_rtstruct.c, model_mesh.c. */
#ifndef SURFD_MODEL_JSON_INTERNAL_H
#define SURFD_MODEL_JSON_INTERNAL_H

#include <jansson.h>
#include <string.h>

#include "../core/contour/solid.h"
#include "model_json.h"
#include "scene_io.h"

#define SHELL_GAP_REL 1e-4 /* trimmed surfaces meet where their boundaries come this close, of the bounds' diagonal */

/* o as compact JSON (its numbers to 12 digits), o released; NULL with err set when out of memory. */
static inline char *dump(json_t *o, struct sf_err *err)
{
    char *s = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12)) : NULL;
    json_decref(o);
    if (!s)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return s;
}

/* A contour request's caps and options as core's (model.h). */
static inline enum model_caps caps_of(const char *name)
{
    return !strcmp(name, "slab") ? CAPS_SLAB : !strcmp(name, "dome") ? CAPS_DOME : CAPS_FLAT;
}

static inline struct model_opts opts_of(const struct contour_request *req, const struct sf_progress *pr)
{
    struct model_opts o = {.method = MODEL_PARABOLIC, .polar = !strcmp(req->param, "polar"), .progress = pr};
    model_method_parse(req->method, &o.method);
    return o;
}

/* ---- one file's functions that another calls (their comments at their definitions) ---- */

/* model_scene.c */
enum scene_format scene_body_format(const char *buf, size_t len, const char *format);
int scene_figures(const char *buf, size_t len, const char *format, const struct sf_progress *pr, char **json,
                  struct sf_err *err);

/* model_matrix.c */
int matrix_model(const char *buf, size_t len, const struct model_sink *sink, char **json, char location[64],
                 struct sf_err *err);

/* model_rtstruct.c: model k's ROI name, colour and interpreted type (its source's, else chosen) */
void model_roi_look(json_t *r, int k, const char **name, int color[3], const char **type);

/* model_mesh.c */
int solid_of(const char *src, size_t len, const struct sf_progress *pr, struct solid *sd, struct sf_err *err);
int model_trimesh(const char *src, size_t len, double tol, const struct sf_progress *pr, struct trimesh *tm,
                  double *tol_used, struct sf_err *err);

#endif
