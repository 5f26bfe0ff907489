/* model_json.c - contours in, models out: figures (the CLI, the volume and model jobs), stored models'
 * sources, meshes, patch lists and scene objects made from them, and the volume a closed scene encloses. */
#include "model_json.h"

#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../core/base/clock.h"
#include "../core/geom/enclosed.h"
#include "../core/contour/solid.h"
#include "dicom_stl.h"
#include "json_in.h"
#include "matrix_json.h"
#include "mesh_io.h"
#include "query.h"
#include "rtstruct.h"
#include "scene_io.h"

#define SHELL_GAP_REL 1e-4 /* trimmed surfaces meet where their boundaries come this close, of the bounds' diagonal */

static char *dump(json_t *o, struct sf_err *err)
{
    char *s = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12)) : NULL;
    json_decref(o);
    if (!s)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return s;
}

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

static enum model_caps caps_of(const char *name)
{
    return !strcmp(name, "slab") ? CAPS_SLAB : !strcmp(name, "dome") ? CAPS_DOME : CAPS_FLAT;
}

static struct model_opts opts_of(const struct contour_request *req, const struct sf_progress *pr)
{
    struct model_opts o = {.method = MODEL_PARABOLIC, .polar = !strcmp(req->param, "polar"), .progress = pr};
    model_method_parse(req->method, &o.method);
    return o;
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
    if (!o)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return o;
}

/* What a JSON body is (a contour set, a scene, a matrix model): by the members of its top-level
 * object, never the text anywhere (a structure named "matrix_model" is still a contour set). */

/* A matrix model (matrix_json.h) rather than a contour set. */
static bool matrix_body(const char *buf, size_t len) { return json_has_member(buf, len, "matrix_model"); }

/* The scene format of a body: as named, but an IGES file is one whatever its Content-Type said
 * (curl sends files as forms, and a JSON default would refuse it). */
static enum scene_format scene_body_format(const char *buf, size_t len, const char *format)
{
    enum scene_format f = scene_format_parse(format);
    return (f == SCENE_JSON || f == SCENE_UNKNOWN) && scene_format_sniff(buf, len) == SCENE_IGES ? SCENE_IGES : f;
}

bool model_body_is_scene(const char *buf, size_t len, const char *format)
{
    if (scene_body_format(buf, len, format) == SCENE_IGES)
        return true;
    enum scene_format f = scene_format_parse(format);
    if (f == SCENE_BPT || f == SCENE_VRML || f == SCENE_IGES) /* (by any of its names) */
        return true;
    if (format && *format && strcmp(format, "json"))
        return false;
    return !json_has_member(buf, len, "slices") &&
           (json_has_member(buf, len, "objects") || json_has_member(buf, len, "patches"));
}

/* Trimmed surfaces as a solid: their area over the trimmed domains, and the volume they enclose
 * when their boundaries meet (enclosed_shell), each turned the way its neighbours face. Patches
 * whose edges meet parts of others (a contour model's: its caps' fans against the walls' rows)
 * close the same way (trimmed false: no list of surfaces). */
static int trimmed_figures(const struct scene *sc, const struct patch_set *ps, bool trimmed, double t0, double t1,
                           const struct sf_progress *pr, char **json, struct sf_err *err)
{
    struct enclosed e;
    double *vol = malloc(sizeof *vol * (size_t)sc->n_objects), *area = malloc(sizeof *area * (size_t)sc->n_objects);
    struct shell_part *parts = malloc(sizeof *parts * (size_t)sc->n_objects);
    signed char *sign = malloc((size_t)sc->n_objects);
    struct shell sh;
    int rc = 0;
    if (!vol || !area || !parts || !sign || enclosed_measure_objects(ps, &e, vol, area, sc->n_objects))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    double diag = hypot(hypot(e.hi[0] - e.lo[0], e.hi[1] - e.lo[1]), e.hi[2] - e.lo[2]);
    for (int k = 0; !rc && k < sc->n_objects; k++)
        parts[k] = (struct shell_part){&sc->objects[k].surf, sc->objects[k].trim};
    if (!rc && (rc = enclosed_shell(parts, sc->n_objects, SHELL_GAP_REL * diag, pr, &sh, sign)))
        rc = rc == SF_ECANCEL ? sf_fail(err, rc, "", "cancelled")
             : rc == SF_ELIMIT
                 ? sf_fail(err, rc, "", "the surfaces' boundaries crowd together: matching their points would take "
                           "some %.3g tests, over the limit of %.3g", sh.tests, SHELL_MAX_TESTS)
                 : sf_fail(err, SF_ENOMEM, "", "out of memory");
    char where[32];
    if (!rc && sh.open_samples) {
        scene_object_pointer(sc, sh.open_object, where, sizeof where);
        const char *name = sc->objects[sh.open_object].name;
        rc = sf_fail(err, SF_EINVAL, where, "the surfaces do not bound a closed solid: %zu of %zu boundary points meet no "
                     "other surface within %.3g mm, the first of this surface%s%s%s at (%.4g, %.4g, %.4g) mm; their "
                     "area is %.6g mm²", sh.open_samples, sh.samples, SHELL_GAP_REL * diag, *name ? " (" : "", name,
                     *name ? ")" : "", sh.open_at[0], sh.open_at[1], sh.open_at[2], e.area);
    } else if (!rc && sh.conflicts) {
        rc = sf_fail(err, SF_EINVAL, "", "the surfaces close, but no choice of their sides faces them all the same way "
                     "(%d neighbouring pairs disagree): a one-sided shell", sh.conflicts);
    }
    double v = 0;
    int turned = 0;
    for (int k = 0; !rc && k < sc->n_objects; k++)
        v += sign[k] * vol[k];
    for (int k = 0; !rc && k < sc->n_objects; k++)
        turned += (v < 0 ? -sign[k] : sign[k]) < 0;
    double t2 = sf_now_ms();
    json_t *list = rc ? NULL : json_array();
    for (int k = 0; list && trimmed && k < sc->n_objects; k++) {
        scene_object_pointer(sc, k, where, sizeof where);
        json_array_append_new(list, json_pack("{s:s, s:s, s:f, s:b}", "entity", where, "name", sc->objects[k].name,
                                              "area_mm2", area[k], "turned", (v < 0 ? -sign[k] : sign[k]) < 0));
    }
    if (!rc)
        *json = dump(json_pack("{s:s, s:i, s:o, s:I, s:b, s:s, s:i, s:f, s:f, s:{s:f}, s:I, s:[[f,f,f],[f,f,f]], s:{s:f, "
                               "s:f}}", "kind", trimmed ? "trimmed surfaces" : "patches", "surfaces", sc->n_objects, "surface_figures", list,
                               "patches", (json_int_t)ps->n,
                               "closed", 1, "orientation", turned ? "mixed" : v >= 0 ? "outward" : "inward",
                               "surfaces_turned", turned, "volume_mm3", fabs(v), "area_mm2", e.area, "volume", "exact",
                               fabs(v), "boundary_points", (json_int_t)sh.samples, "bounds", e.lo[0], e.lo[1], e.lo[2],
                               e.hi[0], e.hi[1], e.hi[2], "timings_ms", "read", t1 - t0, "volume", t2 - t1),
                     err);
    free(vol);
    free(area);
    free(parts);
    free(sign);
    return rc ? rc : (*json ? 0 : err->code);
}

/* A scene's patches as a solid (POST /volume): the volume they enclose, when they close. */
static int scene_figures(const char *buf, size_t len, const char *format, const struct sf_progress *pr, char **json,
                         struct sf_err *err)
{
    double t0 = sf_now_ms();
    struct scene sc;
    enum image_format img;
    /* an IGES part's loops, and the matching of their points, stop at a cancel */
    struct sf_span reading = {pr, 0, 0.5}, closing = {pr, 0.5, 1};
    const struct sf_progress read_pr = {sf_span_poll, &reading}, close_pr = {sf_span_poll, &closing};
    const struct model_resolver polled = {.progress = pr ? &read_pr : NULL};
    int rc = scene_parse_models(buf, len, scene_body_format(buf, len, format), &polled, &sc, &img, err);
    if (rc)
        return rc;
    struct patch_set ps;
    struct enclosed e;
    double t1 = sf_now_ms();
    if ((rc = scene_patches(&sc, &ps, err))) {
        scene_free(&sc);
        return rc;
    }
    bool trimmed = false;
    for (int k = 0; k < sc.n_objects; k++)
        trimmed |= sc.objects[k].trim != NULL;
    if (!trimmed && enclosed_measure(&ps, &e))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    else if (trimmed || e.open_edges) { /* trimmed, or edges meeting parts of others: closed along the boundaries */
        rc = trimmed_figures(&sc, &ps, trimmed, t0, t1, pr ? &close_pr : NULL, json, err);
        nurbs_patch_set_free(&ps);
        scene_free(&sc);
        return rc;
    } else if (e.flipped_edges) {
        char where[32];
        snprintf(where, sizeof where, "/objects/%d", e.open_object);
        rc = sf_fail(err, SF_EINVAL, where, "neighbouring patches face opposite ways across %zu edges (this object has one)",
                     e.flipped_edges / 2);
    }
    double t2 = sf_now_ms(), v = fabs(e.volume);
    if (!rc)
        *json = dump(json_pack("{s:s, s:I, s:b, s:s, s:f, s:f, s:{s:f}, s:[[f,f,f],[f,f,f]], s:{s:f, s:f}}", "kind",
                               "patches", "patches", (json_int_t)ps.n, "closed", 1, "orientation",
                               e.volume >= 0 ? "outward" : "inward", "volume_mm3", v, "area_mm2", e.area, "volume",
                               "exact", v, "bounds", e.lo[0], e.lo[1], e.lo[2], e.hi[0], e.hi[1], e.hi[2],
                               "timings_ms", "read", t1 - t0, "volume", t2 - t1),
                     err);
    nurbs_patch_set_free(&ps);
    scene_free(&sc);
    return rc ? rc : (*json ? 0 : err->code);
}

/* A matrix model's mesh and resource (id "" when it is not stored: POST /volume), and with a sink
 * the model stored as its packed mesh. */
static int matrix_model(const char *buf, size_t len, const struct model_sink *sink, char **json, char location[64],
                        struct sf_err *err)
{
    double t0 = sf_now_ms();
    struct matrix_request r;
    int rc = matrix_parse(buf, len, &r, err);
    if (rc)
        return rc;
    struct trimesh m;
    struct matrix_stats st;
    struct trimesh_stats ts;
    char id[40] = "", *packed = NULL;
    size_t packed_len = 0;
    double mesh_ms = 0;
    if (!(rc = matrix_build(&r, &m, &st, &mesh_ms, err)))
        rc = trimesh_stats(&m, &ts, err);
    double t1 = sf_now_ms();
    if (!rc && sink && sink->id)
        sink->id(sink->ctx, 0, id);
    if (!rc && !(*json = matrix_model_json(id, &r, &m, &ts, &st, mesh_ms, t1 - t0, sf_now_ms() - t0, err)))
        rc = err->code;
    if (!rc && sink && !(rc = mesh_pack(&m, &packed, &packed_len, err)) &&
        sink->put(sink->ctx, id, r.name, packed, packed_len, *json))
        rc = sf_fail(err, SF_EIO, "", "the store could not keep the model");
    if (location)
        snprintf(location, 64, "/models/%s", id);
    free(packed);
    trimesh_free(&m);
    matrix_request_free(&r);
    return rc;
}

int model_validate(const char *buf, size_t len, const char *format, const char *options, struct sf_err *err)
{
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
            rc = contour_clean(&rois[k].cs, err);
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
        if ((rc = contour_clean(&rois[k].cs, err))) {
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

/* ---- what is made from a stored model ---------------------------------------------------------- */

static int solid_of(const char *src, size_t len, const struct sf_progress *pr, struct solid *sd, struct sf_err *err)
{
    struct contour_set cs;
    struct contour_request req;
    int rc = contour_parse_json(src, len, &cs, &req, err);
    if (rc)
        return rc;
    struct model_opts o = opts_of(&req, pr);
    o.unfold = true; /* a surface: its folds undone (model.h) */
    rc = solid_build(&cs, o, caps_of(req.caps), sd, err);
    contour_set_free(&cs);
    return rc;
}

int model_mesh_options(const char *options, const char **format, double *tol, struct sf_err *err)
{
    static const char *const FORMATS[] = {"stl", "ply", "obj", "vtp", "vtk", "dicom-stl"};
    char f[16], t[64], *end = NULL;
    query_option(options, "format", f, sizeof f);
    query_option(options, "tolerance", t, sizeof t);
    *format = NULL;
    for (size_t k = 0; k < sizeof FORMATS / sizeof *FORMATS; k++)
        if (!strcmp(f[0] ? f : "stl", FORMATS[k]))
            *format = FORMATS[k];
    if (!*format)
        return sf_fail(err, SF_EINVAL, "?format", "format is stl, ply, obj, vtp, vtk or dicom-stl");
    *tol = t[0] ? strtod(t, &end) : 0.0;
    if ((t[0] && *end) || !(*tol >= 0) || *tol > 1e6)
        return sf_fail(err, SF_EINVAL, "?tolerance", "tolerance is a distance in mm, > 0 (or 0 for the default)");
    return 0;
}

int model_mesh_key(const char *options, long edits, char *key, size_t cap, struct sf_err *err)
{
    const char *format;
    double tol;
    int rc = model_mesh_options(options, &format, &tol, err);
    if (!rc)
        tol > 0 ? snprintf(key, cap, "%s %.17g e%ld", format, tol, edits) : snprintf(key, cap, "%s default e%ld", format, edits);
    return rc;
}

/* A stored model as triangles: an isosurface's own mesh, or a contour model's at tol (0: the
 * default tied to it, solid_mesh_default); *tol_used the tolerance (0 for a mesh model). */
static int model_trimesh(const char *src, size_t len, double tol, const struct sf_progress *pr, struct trimesh *tm,
                         double *tol_used, struct sf_err *err)
{
    memset(tm, 0, sizeof *tm);
    *tol_used = 0.0;
    if (mesh_is_packed(src, len)) /* an isosurface or a matrix model: the mesh itself */
        return mesh_unpack(src, len, tm, err);
    struct solid sd;
    int rc = solid_of(src, len, pr, &sd, err);
    if (rc)
        return rc;
    struct solid_measures sm;
    solid_measure(&sd, &sm);
    double dflt = solid_default_tolerance(&sm);
    struct mesh m;
    rc = tol > 0 ? solid_mesh(&sd, tol, &m) : solid_mesh_default(&sd, &sm, &m, &dflt);
    *tol_used = tol > 0 ? tol : dflt;
    solid_free(&sd);
    if (rc == SF_ECANCEL)
        return sf_fail(err, rc, "", "cancelled");
    if (rc == SF_ELIMIT)
        return sf_fail(err, rc, "?tolerance", "at %g mm the mesh would have over %u triangles; the default is %.3g mm",
                       tol > 0 ? tol : dflt, MESH_MAX_TRIANGLES, dflt);
    if (rc)
        return sf_fail(err, SF_ENOMEM, "", "out of memory meshing the model");
    *tm = (struct trimesh){malloc(12 * (m.n_v ? m.n_v : 1)), NULL, malloc(12 * (m.n_t ? m.n_t : 1)), m.n_v, m.n_t};
    if (tm->pos && tm->tri) { /* the formats' own precision */
        for (size_t k = 0; k < 3 * m.n_v; k++)
            tm->pos[k] = (float)m.v[k / 3][k % 3];
        for (size_t k = 0; k < 3 * m.n_t; k++)
            tm->tri[k] = m.t[k / 3][k % 3];
    } else {
        trimesh_free(tm);
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory writing the mesh");
    }
    solid_mesh_free(&m);
    return rc;
}

int model_mesh(const char *src, size_t len, const char *resource, const char *options, const struct sf_progress *pr,
               char **out, size_t *out_len, const char **mime, double *tol_used, struct sf_err *err)
{
    const char *format;
    double tol;
    *out = NULL;
    *tol_used = 0.0;
    int rc = model_mesh_options(options, &format, &tol, err);
    if (rc)
        return rc;
    *mime = mesh_mime(format);
    struct trimesh tm;
    bool dicom = !strcmp(format, "dicom-stl"); /* STL in a DICOM Encapsulated STL object */
    if (!(rc = model_trimesh(src, len, tol, pr, &tm, tol_used, err)))
        rc = mesh_encode(&tm, dicom ? "stl" : format, out, out_len, err);
    trimesh_free(&tm);
    if (!rc && dicom) {
        json_t *r = resource ? json_loads(resource, 0, NULL) : NULL;
        unsigned char *d = NULL;
        rc = dicom_stl_wrap(*out, *out_len, json_string_value(json_object_get(r, "name")),
                            json_string_value(json_object_get(r, "study_instance_uid")),
                            json_string_value(json_object_get(r, "frame_of_reference_uid")), &d, out_len, err);
        json_decref(r);
        free(*out);
        *out = (char *)d;
    }
    return rc;
}

int model_rtstruct_options(const char *options, double *spacing, struct sf_err *err)
{
    char v[64], *end = NULL;
    query_option(options, "spacing", v, sizeof v);
    *spacing = v[0] ? strtod(v, &end) : 0.0;
    if ((v[0] && (*end || !(*spacing > 0))) || !(*spacing >= 0) || *spacing > 1000)
        return sf_fail(err, SF_EINVAL, "?spacing", "spacing is the distance of the sections in mm, (0, 1000]");
    return 0;
}

/* The planes an export cuts: ?spacing apart from the first slice of a contour model (or the mesh's
 * lowest point), else a contour model's own slices, else an isosurface's grid spacing; spaced
 * planes get the mesh's lowest and highest points too (its ends), and planes on them are moved in
 * by 1e-6 of its height (a flat cap lies in them). */
static int section_planes(const char *src, size_t len, const char *resource, double spacing, const struct trimesh *tm,
                          double **z, int *n, struct sf_err *err)
{
    double lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < tm->n_vert; k++)
        lo = fmin(lo, tm->pos[3 * k + 2]), hi = fmax(hi, tm->pos[3 * k + 2]);
    double first = lo;
    *z = NULL;
    *n = 0;
    int rc = 0;
    if (!mesh_is_packed(src, len)) {
        struct contour_set cs;
        struct contour_request req;
        if ((rc = contour_parse_json(src, len, &cs, &req, err)))
            return rc;
        if (!spacing && !(*z = malloc(sizeof **z * (size_t)(cs.n_slices + 1))))
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        for (int k = 0; !rc && k < cs.n_slices; k++) {
            if (spacing) {
                first = k == 0 ? cs.s[k].z : fmin(first, cs.s[k].z);
            } else if (*n == 0 || cs.s[k].z != (*z)[*n - 1]) { /* several contours of a slice: one plane */
                (*z)[(*n)++] = cs.s[k].z;
            }
        }
        contour_set_free(&cs);
    } else if (!spacing) { /* an isosurface of samples: its grid's slices */
        json_t *r = json_loads(resource, 0, NULL);
        double sz = 0.0, oz = 0.0;
        if (!r || json_unpack(r, "{s:{s:[F,F,F], s:[F,F,F]}}", "grid", "spacing", &sz, &sz, &sz, "origin", &oz, &oz, &oz) ||
            !(sz > 0)) {
            json_decref(r);
            return sf_fail(err, SF_EINVAL, "?spacing", "this model has no slices of its own: give ?spacing in mm");
        }
        json_decref(r);
        spacing = sz, first = oz;
    }
    if (!rc && spacing) {
        /* the planes first + k spacing, k from k0 to k1, counted by an integer: a double k stops
         * advancing past 2^53 (a grid whose origin is 1e24 mm away), and the planes would not end */
        double k0 = ceil((lo - first) / spacing - 1e-9), k1 = floor((hi - first) / spacing + 1e-9), count = k1 - k0 + 1;
        if (!(count <= CONTOUR_MAX_SLICES))
            return sf_fail(err, SF_ELIMIT, "?spacing", "%g mm gives over %d sections", spacing, CONTOUR_MAX_SLICES);
        int n_k = count > 0 ? (int)count : 0;
        if (!(*z = malloc(sizeof **z * (size_t)(n_k + 2))))
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        if (!n_k || first + k0 * spacing - lo > 1e-3 * spacing) /* the lowest point: the structure's end */
            (*z)[(*n)++] = lo;
        for (int i = 0; i < n_k; i++)
            (*z)[(*n)++] = first + (k0 + i) * spacing;
        if (!n_k || hi - (first + k1 * spacing) > 1e-3 * spacing)
            (*z)[(*n)++] = hi;
    }
    double eps = 1e-6 * (hi - lo);
    for (int k = 0; !rc && k < *n; k++)
        (*z)[k] = fmin(fmax((*z)[k], lo + eps), hi - eps);
    return rc;
}

int model_rtstruct(const char *src, size_t len, const char *resource, const char *options,
                   const struct sf_progress *pr, unsigned char **out, size_t *out_len, struct sf_err *err)
{
    *out = NULL;
    double spacing, tol;
    struct trimesh tm;
    int rc = model_rtstruct_options(options, &spacing, err);
    if (rc || (rc = model_trimesh(src, len, 0.0, pr, &tm, &tol, err)))
        return rc;
    double *z = NULL;
    int n_z = 0, n_c = 0, cap = 0;
    struct rt_contour *c = NULL;
    rc = section_planes(src, len, resource, spacing, &tm, &z, &n_z, err);
    for (int k = 0; !rc && k < n_z; k++) {
        struct trimesh_loops l;
        if ((rc = trimesh_slice(&tm, z[k], &l, err)))
            break;
        for (int i = 0; !rc && i < l.n; i++) {
            int np = l.start[i + 1] - l.start[i];
            if (n_c == cap) {
                struct rt_contour *g = realloc(c, sizeof *c * (size_t)(cap = cap ? 2 * cap : 64));
                if (!g) {
                    rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
                    break;
                }
                c = g;
            }
            if (!(c[n_c].p = malloc(sizeof *c[n_c].p * (size_t)np))) {
                rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
                break;
            }
            c[n_c].n = np;
            for (int j = 0; j < np; j++)
                c[n_c].p[j][0] = l.p[l.start[i] + j][0], c[n_c].p[j][1] = l.p[l.start[i] + j][1], c[n_c].p[j][2] = z[k];
            n_c++;
        }
        trimesh_loops_free(&l);
    }
    json_t *r = rc ? NULL : json_loads(resource, 0, NULL);
    if (!rc && !r)
        rc = sf_fail(err, SF_EINVAL, "", "the model's resource is not JSON");
    if (!rc && n_c == 0)
        rc = sf_fail(err, SF_EINVAL, "?spacing", "no section of the model: its planes miss it");
    if (!rc) {
        json_t *num = json_object_get(r, "roi_number");
        const char *name = json_string_value(json_object_get(r, "name"));
        struct rt_export e = {"surfd", name && *name ? name : "model", num ? (int)json_integer_value(num) : 1,
                              json_string_value(json_object_get(r, "study_instance_uid")),
                              json_string_value(json_object_get(r, "frame_of_reference_uid")), c, n_c};
        rc = rtstruct_write(&e, out, out_len, err);
    }
    json_decref(r);
    for (int k = 0; k < n_c; k++)
        free(c[k].p);
    free(c);
    free(z);
    trimesh_free(&tm);
    return rc;
}

/* A region of a plane (solid.h) as a bilinear patch over its loops' box, a little larger, facing up
 * (u along x) or down (u along y), trimmed by the loops in (u, v). */
static json_t *plane_region_json(const struct cap_region *r)
{
    double lo[2], size[2];
    for (int d = 0; d < 2; d++) {
        double m = 0.01 * (r->hi[d] - r->lo[d]);
        lo[d] = r->lo[d] - m, size[d] = r->hi[d] - r->lo[d] + 2 * m;
    }
    int a = r->up ? 0 : 1; /* the axis u runs along */
    json_t *pts = json_array(), *loops = json_array();
    for (int i = 0; i < 2; i++)
        for (int j = 0; j < 2; j++) {
            double p[2];
            p[a] = lo[a] + i * size[a], p[1 - a] = lo[1 - a] + j * size[1 - a];
            json_array_append_new(pts, json_pack("[f,f,f]", p[0], p[1], r->z));
        }
    double(*pt)[2] = r->pt;
    for (int l = 0; l < r->n_loops; pt += r->counts[l], l++) {
        json_t *loop = json_array();
        for (size_t k = 0; k < r->counts[l]; k++)
            json_array_append_new(loop, json_pack("[f,f]", (pt[k][a] - lo[a]) / size[a], (pt[k][1 - a] - lo[1 - a]) / size[1 - a]));
        json_array_append_new(loops, loop);
    }
    return json_pack("{s:s, s:[i,i], s:o, s:o}", "type", "bezier", "degree", 1, 1, "points", pts, "trim", loops);
}

int model_patches_json(const char *src, size_t len, char **json, struct sf_err *err)
{
    struct solid sd;
    *json = NULL;
    if (mesh_is_packed(src, len))
        return sf_fail(err, SF_EINVAL, "", "this model is a triangle mesh: it has no patches (GET its /mesh)");
    int rc = solid_of(src, len, NULL, &sd, err);
    if (rc)
        return rc;
    /* where tubes end and begin in one plane, the plane's part of the surface for their overlapping
     * caps, within a fifth of the tolerance POST /volume matches boundaries by */
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t k = 0; k < sd.set.n_pool; k++)
        for (int d = 0; d < 3; d++) {
            double x = sd.set.pool[k][d] / sd.set.pool[k][3];
            lo[d] = fmin(lo[d], x), hi[d] = fmax(hi[d], x);
        }
    struct cap_regions joined;
    bool *skip = malloc(sizeof *skip * (size_t)(sd.n_bands ? sd.n_bands : 1));
    double diag = sd.set.n_pool ? sqrt(pow(hi[0] - lo[0], 2) + pow(hi[1] - lo[1], 2) + pow(hi[2] - lo[2], 2)) : 0.0;
    if (!skip || solid_join_caps(&sd, 0.2 * SHELL_GAP_REL * diag, &joined, skip)) {
        free(skip);
        solid_free(&sd);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    json_t *objs = json_array();
    for (int b = 0; objs && b < sd.n_bands; b++) {
        if (skip[b]) /* (a cap the plane's part of the surface replaces) */
            continue;
        for (size_t k = sd.bands[b].first; k < sd.bands[b].first + sd.bands[b].n; k++) {
            const struct patch *pt = &sd.set.patches[k];
            json_t *pts = json_array(), *w = pt->rational ? json_array() : NULL;
            for (int i = 0; i <= pt->p; i++)
                for (int j = 0; j <= pt->q; j++) {
                    vec3 P = bezier_point(pt, i, j);
                    json_array_append_new(pts, json_pack("[f,f,f]", P.x, P.y, P.z));
                    if (w)
                        json_array_append_new(w, json_real(pt->cw[i * (pt->q + 1) + j][3]));
                }
            json_t *o = json_pack("{s:s, s:[i,i], s:o}", "type", w ? "nurbs" : "bezier", "degree", pt->p, pt->q, "points", pts);
            if (w) { /* one span: clamped knots of the Bézier degree */
                json_t *ku = json_array(), *kv = json_array();
                for (int i = 0; i < 2 * (pt->p + 1); i++)
                    json_array_append_new(ku, json_real(i > pt->p));
                for (int j = 0; j < 2 * (pt->q + 1); j++)
                    json_array_append_new(kv, json_real(j > pt->q));
                json_object_set_new(o, "size", json_pack("[i,i]", pt->p + 1, pt->q + 1));
                json_object_set_new(o, "knots_u", ku);
                json_object_set_new(o, "knots_v", kv);
                json_object_set_new(o, "weights", w);
            }
            json_array_append_new(objs, o);
        }
    }
    for (int k = 0; objs && k < joined.n; k++) /* each a plane patch over its loops' box, trimmed by them */
        json_array_append_new(objs, plane_region_json(&joined.r[k]));
    solid_cap_regions_free(&joined);
    free(skip);
    solid_free(&sd);
    *json = dump(objs ? json_pack("{s:o}", "objects", objs) : NULL, err);
    return *json ? 0 : err->code;
}

int model_scene_objects(const char *src, size_t len, struct scene *sc, const struct material *mat, const char *where,
                        struct sf_err *err)
{
    if (mesh_is_packed(src, len)) { /* an isosurface: its triangles beside the patches */
        struct scene_mesh *sm = scene_add_mesh(sc);
        if (!sm)
            return sf_fail(err, SF_ELIMIT, where, "too many objects");
        sm->mat = *mat;
        return mesh_unpack(src, len, &sm->m, err);
    }
    struct solid sd = {0};
    int rc = solid_of(src, len, NULL, &sd, err);
    for (size_t k = 0; !rc && k < sd.set.n; k++) {
        const struct patch *pt = &sd.set.patches[k];
        struct object *o = scene_add_object(sc);
        if (!o) {
            rc = sf_fail(err, sc->n_objects >= SCENE_MAX_OBJECTS ? SF_ELIMIT : SF_ENOMEM, where,
                         "the scene's objects and the model's %zu patches are over %d", sd.set.n, SCENE_MAX_OBJECTS);
            break;
        }
        o->mat = *mat;
        if ((rc = nurbs_surface_alloc(&o->surf, pt->rational ? SURF_NURBS : SURF_BEZIER, pt->p, pt->q, pt->p + 1,
                                      pt->q + 1, err)))
            break;
        for (int i = 0; i <= pt->p; i++)
            for (int j = 0; j <= pt->q; j++) {
                int c = i * (pt->q + 1) + j;
                vec3 P = bezier_point(pt, i, j);
                o->surf.points[3 * c] = P.x, o->surf.points[3 * c + 1] = P.y, o->surf.points[3 * c + 2] = P.z;
                if (pt->rational)
                    o->surf.weights[c] = pt->cw[c][3];
            }
        if (pt->rational) {
            for (int i = 0; i < 2 * (pt->p + 1); i++)
                o->surf.knots_u[i] = i > pt->p;
            for (int j = 0; j < 2 * (pt->q + 1); j++)
                o->surf.knots_v[j] = j > pt->q;
        }
    }
    solid_free(&sd);
    return rc;
}
