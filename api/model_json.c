/* model_json.c - contours in, models out: a model request's body by its kind (contours, a scene,
 * a matrix model), the figures of each model of a contour set or an RT Structure Set, and each
 * model made stored in the sink with its source (contour JSON). The other parts of model_json.h:
 * model_scene.c, model_matrix.c, model_mesh.c, model_rtstruct.c, model_patches.c. */
#include "model_json_internal.h"

#include <jansson.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../core/base/clock.h"
#include "formats.h"
#include "json_in.h"
#include "matrix_json.h"
#include "query.h"
#include "rtstruct.h"

/* ?caps=, ?method= and ?parameterisation= (override the body's own); "" when absent. */
static int overrides(const char *options, char caps[16], char method[24], char param[16], struct sf_err *err)
{
    enum model_method m;
    query_option(options, "caps", caps, 16);
    query_option(options, "method", method, 24);
    query_option(options, "parameterisation", param, 16);
    if (param[0] && strcmp(param, "arc-length") && strcmp(param, "polar"))
        return sf_fail(err, SF_EINVAL, "?parameterisation", "parameterisation is arc-length or polar");
    if (caps[0] && strcmp(caps, "flat") && strcmp(caps, "slab") && strcmp(caps, "dome"))
        return sf_fail(err, SF_EINVAL, "?caps", "caps is flat, slab or dome");
    if (method[0] && model_method_parse(method, &m))
        return sf_fail(err, SF_EINVAL, "?method", "method is parabolic, linear-parabolic, coons or bspline");
    return 0;
}

/* Applies the query's overrides to a request's options. */
static void override(struct contour_request *req, const char *caps, const char *method, const char *param)
{
    if (caps[0])
        snprintf(req->caps, sizeof req->caps, "%s", caps);
    if (method[0])
        snprintf(req->method, sizeof req->method, "%s", method);
    if (param[0])
        snprintf(req->param, sizeof req->param, "%s", param);
}

/* Adds figures' "warnings" where the model's curves depart from the polygons (model_departure):
 * what a planning system measures is the polygons, so a user comparing volumes learns why they
 * differ and which figure is theirs. 0 or SF_ENOMEM. */
static int departure_warning(const struct contour_set *cs, enum model_method m, json_t *figures)
{
    struct model_departure d;
    if (model_departure(cs, m, &d))
        return SF_ENOMEM;
    if (fabs(d.rel) <= MODEL_DEPART_WARN)
        return 0;
    const struct contour_slice *w = &cs->s[d.worst];
    char msg[400];
    snprintf(msg, sizeof msg,
             "the surface's contours enclose %.1f %% %s than their polygons, which planning systems measure "
             "(volume.trapezoid is the polygons' volume): the contours have few points for how they turn (the "
             "most: %d points at z %g, %.1f %% %s)",
             100 * fabs(d.rel), d.rel > 0 ? "more" : "less", w->n, w->z, 100 * fabs(d.worst_rel),
             d.worst_rel > 0 ? "more" : "less");
    json_t *list = json_pack("[{s:s, s:s, s:f}]", "code", "curves-depart-from-polygons", "message", msg,
                             "departure", d.rel);
    return list && !json_object_set_new(figures, "warnings", list) ? 0 : SF_ENOMEM;
}

/* The figures of one cleaned contour set as a JSON object (NULL with err set on failure); a model's
 * (unfold: of its surface with the folds undone, as solid_of builds it), or a volume's (model.h). */
static json_t *figures(struct contour_set *cs_in, const struct contour_request *req, const struct sf_progress *pr,
                       bool unfold, double t0, struct sf_err *err)
{
    struct contour_set cs = *cs_in;
    struct solid sd;
    struct model_opts mo = opts_of(req, pr);
    mo.unfold = unfold;
    bool curves = mo.method == MODEL_PARABOLIC || mo.method == MODEL_LINEAR_PARABOLIC;
    mo.closed = curves;
    double t1 = sf_now_ms();
    if (solid_build(&cs, mo, caps_of(req->caps), &sd, err))
        return NULL;
    /* the curve methods' exact volume straight from the curves, tube by tube (the closed form, made
     * by solid_build from the curves it fitted), and the ends as built; the grid methods' is the
     * quadrature below (exact for polynomial patches). Timed: fitting the curves and the closed
     * form ("volume": what the volume alone costs), the rest of solid_build ("fit": the patches) */
    double t2 = sf_now_ms(), closed = 0.0, volume_ms = 0.0;
    for (int c = 0; c < sd.n_tubes && curves; c++) {
        const struct tube *tb = &sd.tubes[c];
        closed += (tb->hole ? -tb->side.volume : tb->side.volume) + tb->volume_ends;
        volume_ms += tb->side.ms;
    }
    /* the divergence theorem over every patch as a cross-check, the area and the bounds */
    double t3 = sf_now_ms();
    struct solid_measures all;
    solid_measure(&sd, &all);
    double t4 = sf_now_ms();
    if (!curves)
        closed = all.volume;
    size_t n_patches = sd.set.n;
    int n_chains = sd.n_tubes, dome_fallbacks = sd.dome_fallbacks;
    solid_free(&sd);
    struct contour_baselines b;
    contour_baselines(&cs, &b);
    int n = 0; /* levels */
    for (int k = 0; k < cs.n_slices; k++)
        n += k == 0 || cs.s[k].z != cs.s[k - 1].z;
    bool uneven = false; /* any spacing between levels unlike the first one */
    double first_gap = 0.0;
    for (int k = 1; k < cs.n_slices; k++) {
        double g = cs.s[k].z - cs.s[k - 1].z;
        if (g == 0.0)
            continue;
        if (first_gap == 0.0)
            first_gap = g;
        uneven |= fabs(g - first_gap) > 1e-6 * first_gap;
    }
    json_t *o = json_pack("{s:s, s:s, s:s, s:s, s:i, s:i, s:i, s:i, s:b, s:I, s:f, s:f, s:{s:f, s:f, s:f, s:f, s:f, s:f},"
                          " s:[[f,f,f],[f,f,f]], s:{s:f, s:f, s:f, s:f}}",
                          "name", req->name, "method", req->method, "caps", req->caps, "parameterisation", req->param,
                          "dome_ends_flat",
                          dome_fallbacks, "slices", n, "contours",
                          cs.n_slices, "chains", n_chains, "uneven_spacing", uneven, "patches", (json_int_t)n_patches,
                          "volume_mm3", closed, "area_mm2", all.area, "volume", "exact", closed, "quadrature", all.volume, "grid_10x10", all.volume_grid,
                          "trapezoid", b.trapezoid, "cavalieri", b.cavalieri, "frustum", b.frustum, "bounds",
                          all.lo[0], all.lo[1], all.lo[2], all.hi[0], all.hi[1], all.hi[2], "timings_ms", "read",
                          t1 - t0, "fit", t2 - t1 - volume_ms, "volume", t3 - t2 + volume_ms, "measure", t4 - t3);
    if (!o || departure_warning(&cs, mo.method, o)) {
        json_decref(o);
        sf_fail(err, SF_ENOMEM, "", "out of memory");
        return NULL;
    }
    return o;
}

/* What a JSON body is (a contour set, a scene, a matrix model): by the members of its top-level
 * object, never the text anywhere (a structure named "matrix_model" is still a contour set). */

/* A matrix model (matrix_json.h) rather than a contour set. */
static bool matrix_body(const char *buf, size_t len) { return json_has_member(buf, len, "matrix_model"); }

int model_validate(const char *buf, size_t len, const char *format, const char *options, struct sf_err *err)
{
    if ((!format || !strcmp(format, "json")) && input_refuse_foreign(buf, len, IN_VOLUME, "a route of contours", err))
        return err->code;
    if ((!format || !strcmp(format, "json")) && matrix_body(buf, len)) { /* its shapes, elements and integrity */
        struct matrix_request r;
        int rc = matrix_parse(buf, len, &r, err), bk, bi, bj;
        if (rc)
            return rc;
        uint8_t *vox = malloc((size_t)r.mm.n[0] * r.mm.n[1] * r.mm.n[2]);
        rc = !vox ? sf_fail(err, SF_ENOMEM, "", "out of memory") : matrix_voxels(&r.mm, vox, &bk, &bi, &bj, err);
        if (vox && rc)
            snprintf(err->pointer, sizeof err->pointer, "/matrix_model/M%d/%d/%d", bk, bi, bj);
        free(vox);
        matrix_request_free(&r);
        return rc;
    }
    if (model_body_is_scene(buf, len, format)) {
        struct scene sc;
        enum image_format img;
        int rc = scene_parse(buf, len, scene_body_format(buf, len, format), &sc, &img, err);
        if (!rc)
            scene_free(&sc);
        return rc;
    }
    char roi[128], caps[16], method[24], param[16];
    query_option(options, "roi", roi, sizeof roi);
    int rc = overrides(options, caps, method, param, err);
    if (rc)
        return rc;
    if (!format || strcmp(format, "dicom")) {
        struct contour_set cs;
        struct contour_request req;
        rc = contour_parse_json(buf, len, &cs, &req, err);
        if (!rc)
            contour_set_free(&cs);
        return rc;
    }
    struct rt_roi *rois = NULL;
    int n = 0, found = 0;
    rc = rtstruct_read(buf, len, &rois, &n, err);
    for (int k = 0; k < n && !rc; k++)
        if (roi[0] && rois[k].skipped && !strcmp(roi, rois[k].name))
            rc = sf_fail(err, SF_EINVAL, "?roi", "ROI \"%.60s\" has nothing to model: %s", rois[k].name, rois[k].skipped);
        else if (!rois[k].skipped && (!roi[0] || !strcmp(roi, rois[k].name))) {
            found++;
            rc = contour_json_clean(&rois[k].cs, err);
        }
    rtstruct_free(rois, n);
    if (!rc && !found)
        rc = sf_fail(err, SF_EINVAL, roi[0] ? "?roi" : "/ROIContourSequence",
                     roi[0] ? "no ROI with contours has that name" : "no ROI has closed planar contours");
    return rc;
}

/* One model of a request: its figures (fn may add to them), its cleaned contours and options. */
typedef int (*model_fn)(void *ctx, int k, json_t *fig, const struct contour_set *cs, const struct contour_request *req,
                        struct sf_err *err);

/* Every model the request describes, in order, into *list (one for JSON and for a DICOM ?roi=NAME:
 * *single), and an RT Structure Set's ROIs without contours to model into *skipped ({name,
 * roi_number, reason}); fn (may be NULL: volumes only, their surfaces' folds left as they are) sees
 * each model. */
static int each_model(const char *buf, size_t len, const char *format, const char *options, model_fn fn, void *ctx,
                      const struct sf_progress *pr, json_t **list, json_t **skipped, bool *single, struct sf_err *err)
{
    double t0 = sf_now_ms();
    *list = json_array();
    *skipped = json_array();
    if (!*list || !*skipped)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    int rc = 0;
    char roi[128], caps[16], method[24], param[16];
    query_option(options, "roi", roi, sizeof roi);
    if ((rc = overrides(options, caps, method, param, err)))
        return rc;
    if (!format || strcmp(format, "dicom")) {
        struct contour_set cs;
        struct contour_request req;
        *single = true;
        if ((rc = contour_parse_json(buf, len, &cs, &req, err)))
            return rc;
        override(&req, caps, method, param);
        json_t *o = figures(&cs, &req, pr, fn != NULL, t0, err);
        if (!o)
            rc = err->code ? err->code : SF_ENOMEM;
        else if (json_array_append_new(*list, o) || (fn && (rc = fn(ctx, 0, o, &cs, &req, err))))
            rc = rc ? rc : sf_fail(err, SF_ENOMEM, "", "out of memory");
        contour_set_free(&cs);
        return rc;
    }
    /* an RT Structure Set: every ROI with contours, or the one ?roi names */
    struct contour_request req = {"", "parabolic", "flat", "arc-length"};
    *single = roi[0] != 0;
    override(&req, caps, method, param);
    struct rt_roi *rois = NULL;
    int n = 0;
    if ((rc = rtstruct_read(buf, len, &rois, &n, err)))
        return rc;
    for (int k = 0; k < n && !rc; k++) {
        if (roi[0] && strcmp(roi, rois[k].name))
            continue;
        if (rois[k].skipped) {
            if (roi[0])
                rc = sf_fail(err, SF_EINVAL, "?roi", "ROI \"%.60s\" has nothing to model: %s", rois[k].name,
                             rois[k].skipped);
            else
                json_array_append_new(*skipped, json_pack("{s:s, s:i, s:s}", "name", rois[k].name, "roi_number",
                                                          rois[k].number, "reason", rois[k].skipped));
            continue;
        }
        snprintf(req.name, sizeof req.name, "%s", rois[k].name);
        if ((rc = contour_json_clean(&rois[k].cs, err))) {
            char where[96];
            snprintf(where, sizeof where, "%.95s", err->pointer);
            snprintf(err->pointer, sizeof err->pointer, "/ROIContourSequence(%.40s)%s", rois[k].name, where);
            break;
        }
        json_t *o = figures(&rois[k].cs, &req, pr, fn != NULL, t0, err);
        if (!o) {
            rc = err->code ? err->code : SF_ENOMEM;
            break;
        }
        json_object_set_new(o, "roi_number", json_integer(rois[k].number));
        if (rois[k].frame_uid[0]) /* what an export references (GET /models/{id}/rtstruct) */
            json_object_set_new(o, "frame_of_reference_uid", json_string(rois[k].frame_uid));
        if (rois[k].study_uid[0])
            json_object_set_new(o, "study_instance_uid", json_string(rois[k].study_uid));
        if (rois[k].color[0] >= 0) /* kept to be written back (GET /rtstruct) */
            json_object_set_new(o, "roi_display_color",
                                json_pack("[i, i, i]", rois[k].color[0], rois[k].color[1], rois[k].color[2]));
        if (rois[k].type[0])
            json_object_set_new(o, "rt_roi_interpreted_type", json_string(rois[k].type));
        if (rois[k].n_images > 0 && rois[k].series_uid[0]) {
            json_t *images = json_array();
            for (int i = 0; images && i < rois[k].n_images; i++) {
                const struct rt_image *im = &rois[k].images[i];
                json_array_append_new(images, isnan(im->z) ? json_pack("[s, s]", im->sop_class, im->sop_instance)
                                                           : json_pack("[s, s, f]", im->sop_class, im->sop_instance, im->z));
            }
            json_object_set_new(o, "referenced_series",
                                json_pack("{s:s, s:o*}", "series_instance_uid", rois[k].series_uid, "images", images));
        }
        json_array_append_new(*list, o);
        if (fn)
            rc = fn(ctx, (int)json_array_size(*list) - 1, o, &rois[k].cs, &req, err);
        t0 = sf_now_ms();
    }
    rtstruct_free(rois, n);
    if (!rc && json_array_size(*list) == 0)
        rc = sf_fail(err, SF_EINVAL, roi[0] ? "?roi" : "/ROIContourSequence",
                     roi[0] ? "no ROI with contours has that name" : "no ROI has closed planar contours");
    return rc;
}

/* The answer: the one object, or {"models": [...], "skipped": [...]}. */
static char *answer(json_t *list, json_t *skipped, bool single, struct sf_err *err)
{
    return dump(single ? json_incref(json_array_get(list, 0)) : json_pack("{s:O, s:O}", "models", list, "skipped", skipped),
                err);
}

int model_figures(const char *buf, size_t len, const char *format, const char *options,
                  const struct sf_progress *pr, char **json, struct sf_err *err)
{
    if ((!format || !strcmp(format, "json")) && matrix_body(buf, len))
        return matrix_model(buf, len, NULL, json, NULL, err);
    if (model_body_is_scene(buf, len, format)) {
        *json = NULL;
        return scene_figures(buf, len, format, pr, json, err);
    }
    json_t *list = NULL, *skipped = NULL;
    bool single;
    int rc = each_model(buf, len, format, options, NULL, NULL, pr, &list, &skipped, &single, err);
    *json = rc ? NULL : answer(list, skipped, single, err);
    json_decref(list);
    json_decref(skipped);
    return rc ? rc : (*json ? 0 : err->code);
}

struct create_ctx {
    const struct model_sink *sink;
    char first[40];
};

static int store_one(void *arg, int k, json_t *fig, const struct contour_set *cs, const struct contour_request *req,
                     struct sf_err *err)
{
    struct create_ctx *c = arg;
    char id[40] = "", self[64], mesh[96], patches[80], render[80];
    if (c->sink->id) {
        c->sink->id(c->sink->ctx, k, id);
        snprintf(self, sizeof self, "/models/%s", id);
        snprintf(mesh, sizeof mesh, "%s/mesh?format=stl", self);
        snprintf(patches, sizeof patches, "%s/patches", self);
        snprintf(render, sizeof render, "%s/render", self);
        json_object_set_new(fig, "id", json_string(id));
        json_object_set_new(fig, "links", json_pack("{s:s, s:s, s:s, s:s}", "self", self, "mesh", mesh, "patches",
                                                    patches, "render", render));
        json_object_set_new(fig, "version", json_integer(1)); /* a contour model is not edited: always 1 */
    }
    if (k == 0)
        snprintf(c->first, sizeof c->first, "%s", id);
    char *source = contour_json_write(cs, req), *resource = json_dumps(fig, JSON_COMPACT | JSON_REAL_PRECISION(12));
    int rc = !source || !resource ? sf_fail(err, SF_ENOMEM, "", "out of memory")
             : c->sink->put(c->sink->ctx, id, req->name, source, strlen(source), resource)
                 ? sf_fail(err, SF_EIO, "", "the store could not keep the model")
                 : 0;
    free(source);
    free(resource);
    return rc;
}

int model_create(const char *buf, size_t len, const char *format, const char *options, const struct model_sink *sink,
                 const struct sf_progress *pr, char **json, char location[64], struct sf_err *err)
{
    if ((!format || !strcmp(format, "json")) && matrix_body(buf, len))
        return matrix_model(buf, len, sink, json, location, err);
    struct create_ctx c = {sink, ""};
    json_t *list = NULL, *skipped = NULL;
    bool single;
    int rc = each_model(buf, len, format, options, store_one, &c, pr, &list, &skipped, &single, err);
    *json = rc ? NULL : answer(list, skipped, single, err);
    json_decref(list);
    json_decref(skipped);
    snprintf(location, 64, "/models/%s", c.first);
    return rc ? rc : (*json ? 0 : err->code);
}

