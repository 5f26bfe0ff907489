/* scene_json.c - the JSON scene of API.md §Scene into struct scene. Every complaint carries the
 * JSON pointer of the offending value. A bare {"patches": [...]} (the JSON files of shared/data/scenes)
 * is a scene of Bézier objects. Unknown keys are ignored, as most JSON APIs do. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "json_in.h"
#include "scene_io.h"

/* Reads a finite number (integers too). */
static int num(json_t *j, const char *ptr, double *out, struct sf_err *err)
{
    if (!json_is_number(j))
        return sf_fail(err, SF_EINVAL, ptr, "expected a number");
    double v = json_number_value(j);
    if (!isfinite(v))
        return sf_fail(err, SF_EINVAL, ptr, "expected a finite number");
    *out = v;
    return 0;
}

static int integer(json_t *j, const char *ptr, int lo, int hi, int *out, struct sf_err *err)
{
    double v;
    int rc = num(j, ptr, &v, err);
    if (rc)
        return rc;
    if (v != floor(v) || v < lo || v > hi)
        return sf_fail(err, SF_EINVAL, ptr, "expected an integer in %d..%d, got %g", lo, hi, v);
    *out = (int)v;
    return 0;
}

static int vec(json_t *j, const char *ptr, vec3 *out, struct sf_err *err)
{
    if (!json_is_array(j) || json_array_size(j) != 3)
        return sf_fail(err, SF_EINVAL, ptr, "expected an array of 3 numbers");
    double c[3];
    char p[192];
    for (int k = 0; k < 3; k++) {
        snprintf(p, sizeof p, "%s/%d", ptr, k);
        int rc = num(json_array_get(j, (size_t)k), p, &c[k], err);
        if (rc)
            return rc;
    }
    *out = v3(c[0], c[1], c[2]);
    return 0;
}

/* Reads a flat array of exactly n numbers. */
static int numbers(json_t *j, const char *ptr, size_t n, double *out, struct sf_err *err)
{
    if (!json_is_array(j))
        return sf_fail(err, SF_EINVAL, ptr, "expected an array of %zu numbers", n);
    if (json_array_size(j) != n)
        return sf_fail(err, SF_EINVAL, ptr, "expected %zu values, got %zu", n, json_array_size(j));
    char p[192];
    for (size_t k = 0; k < n; k++) {
        snprintf(p, sizeof p, "%s/%zu", ptr, k);
        int rc = num(json_array_get(j, k), p, &out[k], err);
        if (rc)
            return rc;
    }
    return 0;
}

static int material(json_t *j, const char *where, struct material *m, struct sf_err *err)
{
    char p[192];
    json_t *v;
    int rc = 0;
    if (!json_is_object(j)) {
        snprintf(p, sizeof p, "%s/material", where);
        return sf_fail(err, SF_EINVAL, p, "expected an object");
    }
    if ((v = json_object_get(j, "color"))) {
        snprintf(p, sizeof p, "%s/material/color", where);
        if ((rc = vec(v, p, &m->color, err)))
            return rc;
    }
    if ((v = json_object_get(j, "specular"))) {
        snprintf(p, sizeof p, "%s/material/specular", where);
        if ((rc = num(v, p, &m->specular, err)))
            return rc;
    }
    if ((v = json_object_get(j, "shininess"))) {
        snprintf(p, sizeof p, "%s/material/shininess", where);
        if ((rc = num(v, p, &m->shininess, err)))
            return rc;
        if (m->shininess < 0 || m->shininess > 10000)
            return sf_fail(err, SF_EINVAL, p, "shininess must be within 0..10000");
    }
    return 0;
}

/* {"type": "model", "id": ..., "material": ...}: the stored model's patches, from the resolver. */
static int model_object(json_t *j, const char *where, const struct model_resolver *models, struct scene *sc,
                        struct sf_err *err)
{
    char p[400];
    snprintf(p, sizeof p, "%s/id", where);
    json_t *id = json_object_get(j, "id");
    if (!json_is_string(id))
        return sf_fail(err, SF_EINVAL, p, "expected the id of a stored model");
    if (!models || !models->objects)
        return sf_fail(err, SF_EINVAL, p, "stored models are only available through the service");
    struct material mat = scene_default_material();
    json_t *m = json_object_get(j, "material");
    int rc = m ? material(m, where, &mat, err) : 0;
    return rc ? rc : models->objects(models->ctx, json_string_value(id), &mat, where, sc, err);
}

/* "trim": loops in the surface's (u, v) domain, each an array of at least 3 [u, v] points (closed
 * without repeating the first), whose even-odd inside is the surface's region (as an IGES 144's
 * outer loop and holes): o's trim. */
static int trim_loops(json_t *j, const char *where, struct object *o, struct sf_err *err)
{
    char p[400];
    snprintf(p, sizeof p, "%s/trim", where);
    size_t nl = json_array_size(j), total = 0;
    if (!json_is_array(j) || nl == 0)
        return sf_fail(err, SF_EINVAL, p, "expected an array of loops, each an array of [u, v] points");
    for (size_t l = 0; l < nl; l++) {
        json_t *loop = json_array_get(j, l);
        snprintf(p, sizeof p, "%s/trim/%zu", where, l);
        if (!json_is_array(loop) || json_array_size(loop) < 3)
            return sf_fail(err, SF_EINVAL, p, "expected a loop of at least 3 [u, v] points");
        if ((total += json_array_size(loop)) > TRIM_MAX_POINTS)
            return sf_fail(err, SF_ELIMIT, p, "trim loops have more than %u points", TRIM_MAX_POINTS);
    }
    double(*pts)[2] = malloc(sizeof *pts * total), u0, u1, v0, v1;
    size_t *counts = malloc(sizeof *counts * nl), at = 0;
    int rc = !pts || !counts ? sf_fail(err, SF_ENOMEM, where, "out of memory") : 0;
    nurbs_domain(&o->surf, &u0, &u1, &v0, &v1);
    double su = 1e-9 * (u1 - u0), sv = 1e-9 * (v1 - v0);
    for (size_t l = 0; !rc && l < nl; l++) {
        json_t *loop = json_array_get(j, l);
        counts[l] = json_array_size(loop);
        for (size_t k = 0; !rc && k < counts[l]; k++, at++) {
            snprintf(p, sizeof p, "%s/trim/%zu/%zu", where, l, k);
            if (!(rc = numbers(json_array_get(loop, k), p, 2, pts[at], err)) &&
                !(pts[at][0] >= u0 - su && pts[at][0] <= u1 + su && pts[at][1] >= v0 - sv && pts[at][1] <= v1 + sv))
                rc = sf_fail(err, SF_EINVAL, p, "a trim point outside the surface's domain [%g, %g] x [%g, %g]", u0, u1,
                             v0, v1);
        }
    }
    if (!rc && !(o->trim = calloc(1, sizeof *o->trim)))
        rc = sf_fail(err, SF_ENOMEM, where, "out of memory");
    snprintf(p, sizeof p, "%s/trim", where);
    if (!rc && (rc = trim_build(o->trim, (const double(*)[2])pts, counts, (int)nl, p, NULL, err))) { /* (nl < total / 3) */
        free(o->trim);
        o->trim = NULL;
    }
    free(pts), free(counts);
    return rc;
}

/* One object of "objects" (or of a bare "patches" list, where type defaults to bezier). */
static int object(json_t *j, const char *where, const struct model_resolver *models, struct scene *sc,
                  struct sf_err *err)
{
    char p[400];
    if (!json_is_object(j))
        return sf_fail(err, SF_EINVAL, where, "expected an object");
    const char *type = "bezier";
    json_t *t = json_object_get(j, "type");
    if (t) {
        snprintf(p, sizeof p, "%s/type", where);
        if (!json_is_string(t))
            return sf_fail(err, SF_EINVAL, p, "expected a string");
        type = json_string_value(t);
    }
    enum surf_kind kind;
    if (!strcmp(type, "bezier"))
        kind = SURF_BEZIER;
    else if (!strcmp(type, "bspline"))
        kind = SURF_BSPLINE;
    else if (!strcmp(type, "nurbs"))
        kind = SURF_NURBS;
    else {
        snprintf(p, sizeof p, "%s/type", where);
        if (!strcmp(type, "model"))
            return model_object(j, where, models, sc, err);
        return sf_fail(err, SF_EINVAL, p, "unknown object type \"%s\" (bezier, bspline, nurbs, model)", type);
    }
    json_t *deg = json_object_get(j, "degree");
    int d[2], n[2], rc;
    snprintf(p, sizeof p, "%s/degree", where);
    if (!json_is_array(deg) || json_array_size(deg) != 2)
        return sf_fail(err, SF_EINVAL, p, "expected [degree_u, degree_v]");
    for (int k = 0; k < 2; k++) {
        snprintf(p, sizeof p, "%s/degree/%d", where, k);
        if ((rc = integer(json_array_get(deg, (size_t)k), p, 1, PATCH_MAX_DEGREE, &d[k], err)))
            return rc;
    }
    if (kind == SURF_BEZIER) {
        n[0] = d[0] + 1;
        n[1] = d[1] + 1;
    } else {
        json_t *size = json_object_get(j, "size");
        snprintf(p, sizeof p, "%s/size", where);
        if (!json_is_array(size) || json_array_size(size) != 2)
            return sf_fail(err, SF_EINVAL, p, "expected [points_u, points_v]");
        for (int k = 0; k < 2; k++) {
            snprintf(p, sizeof p, "%s/size/%d", where, k);
            if ((rc = integer(json_array_get(size, (size_t)k), p, d[k] + 1, SURF_MAX_POINTS, &n[k], err)))
                return rc;
        }
    }
    struct object *o = scene_add_object(sc);
    if (!o)
        return sf_fail(err, sc->n_objects >= SCENE_MAX_OBJECTS ? SF_ELIMIT : SF_ENOMEM, where,
                       "too many objects (limit %d) or out of memory", SCENE_MAX_OBJECTS);
    struct sf_err local = {0};
    if ((rc = nurbs_surface_alloc(&o->surf, kind, d[0], d[1], n[0], n[1], &local))) {
        snprintf(p, sizeof p, "%s/%s", where, local.pointer);
        return sf_fail(err, rc, p, "%s", local.message);
    }
    size_t np = (size_t)n[0] * n[1];
    json_t *pts = json_object_get(j, "points");
    snprintf(p, sizeof p, "%s/points", where);
    if (!json_is_array(pts))
        return sf_fail(err, SF_EINVAL, p, "expected an array of [x, y, z] points");
    if (json_array_size(pts) != np)
        return sf_fail(err, SF_EINVAL, p, "expected %zu points for degree [%d, %d] and size [%d, %d], got %zu", np,
                       d[0], d[1], n[0], n[1], json_array_size(pts));
    for (size_t k = 0; k < np; k++) {
        vec3 v;
        snprintf(p, sizeof p, "%s/points/%zu", where, k);
        if ((rc = vec(json_array_get(pts, k), p, &v, err)))
            return rc;
        o->surf.points[3 * k] = v.x, o->surf.points[3 * k + 1] = v.y, o->surf.points[3 * k + 2] = v.z;
    }
    if (kind != SURF_BEZIER) {
        snprintf(p, sizeof p, "%s/knots_u", where);
        if ((rc = numbers(json_object_get(j, "knots_u"), p, (size_t)(n[0] + d[0] + 1), o->surf.knots_u, err)))
            return rc;
        snprintf(p, sizeof p, "%s/knots_v", where);
        if ((rc = numbers(json_object_get(j, "knots_v"), p, (size_t)(n[1] + d[1] + 1), o->surf.knots_v, err)))
            return rc;
    }
    if (kind == SURF_NURBS) {
        snprintf(p, sizeof p, "%s/weights", where);
        if ((rc = numbers(json_object_get(j, "weights"), p, np, o->surf.weights, err)))
            return rc;
    }
    json_t *tr = json_object_get(j, "trim");
    if (tr && (rc = trim_loops(tr, where, o, err)))
        return rc;
    json_t *m = json_object_get(j, "material");
    return m ? material(m, where, &o->mat, err) : 0;
}

static int image(json_t *j, struct scene *sc, enum image_format *img, struct sf_err *err)
{
    json_t *v;
    int rc;
    if (!json_is_object(j))
        return sf_fail(err, SF_EINVAL, "/image", "expected an object");
    if ((v = json_object_get(j, "width")) && (rc = integer(v, "/image/width", 1, SCENE_MAX_SIDE, &sc->width, err)))
        return rc;
    if ((v = json_object_get(j, "height")) && (rc = integer(v, "/image/height", 1, SCENE_MAX_SIDE, &sc->height, err)))
        return rc;
    if ((v = json_object_get(j, "background")) && (rc = vec(v, "/image/background", &sc->background, err)))
        return rc;
    sc->background_opaque |= v != NULL;
    if ((v = json_object_get(j, "samples")) &&
        (rc = integer(v, "/image/samples", 1, SCENE_MAX_SAMPLES, &sc->samples, err)))
        return rc;
    if ((v = json_object_get(j, "format")) && (!json_is_string(v) || image_format_parse(json_string_value(v), img)))
        return sf_fail(err, SF_EINVAL, "/image/format", "format must be \"png\", \"exr\" or \"tiff\"");
    if ((v = json_object_get(j, "aovs"))) {
        if (!json_is_array(v))
            return sf_fail(err, SF_EINVAL, "/image/aovs", "expected an array of \"normal\", \"uv\", \"id\"");
        for (size_t k = 0; k < json_array_size(v); k++) {
            const char *s = json_string_value(json_array_get(v, k));
            char p[64];
            snprintf(p, sizeof p, "/image/aovs/%zu", k);
            unsigned aov = s ? scene_aov_parse(s, strlen(s)) : 0;
            if (!aov)
                return sf_fail(err, SF_EINVAL, p, "unknown AOV (normal, uv, id)");
            sc->aovs |= aov;
        }
    }
    return 0;
}

static int camera(json_t *j, struct scene *sc, struct sf_err *err)
{
    json_t *v;
    int rc;
    if (!json_is_object(j))
        return sf_fail(err, SF_EINVAL, "/camera", "expected an object");
    json_t *eye = json_object_get(j, "eye"), *target = json_object_get(j, "target");
    if (eye || target) {
        if (!eye || !target)
            return sf_fail(err, SF_EINVAL, eye ? "/camera/target" : "/camera/eye", "eye and target come together");
        if ((rc = vec(eye, "/camera/eye", &sc->eye, err)) || (rc = vec(target, "/camera/target", &sc->target, err)))
            return rc;
        sc->has_camera = true;
    }
    if ((v = json_object_get(j, "up")) && (rc = vec(v, "/camera/up", &sc->up, err)))
        return rc;
    if ((v = json_object_get(j, "fov_deg")) && (rc = num(v, "/camera/fov_deg", &sc->fov_deg, err)))
        return rc;
    if ((v = json_object_get(j, "azimuth")) && (rc = num(v, "/camera/azimuth", &sc->azimuth_deg, err)))
        return rc;
    if ((v = json_object_get(j, "elevation")) && (rc = num(v, "/camera/elevation", &sc->elevation_deg, err)))
        return rc;
    if ((v = json_object_get(j, "projection"))) {
        const char *s = json_string_value(v);
        if (!s || (strcmp(s, "perspective") && strcmp(s, "orthographic")))
            return sf_fail(err, SF_EINVAL, "/camera/projection", "projection is \"perspective\" or \"orthographic\"");
        sc->ortho = s[0] == 'o';
    }
    if ((v = json_object_get(j, "view"))) {
        const char *s = json_string_value(v);
        if (!s || scene_view_parse(s, &sc->view))
            return sf_fail(err, SF_EINVAL, "/camera/view", "view is \"+x\", \"-x\", \"+y\", \"-y\", \"+z\" or \"-z\"");
        if (sc->has_camera)
            return sf_fail(err, SF_EINVAL, "/camera/view", "a view along an axis or an eye and target, not both");
    }
    if ((v = json_object_get(j, "view_height")) && (rc = num(v, "/camera/view_height", &sc->view_height, err)))
        return rc;
    if (json_object_get(j, "view_height") && !(sc->view_height > 0.0))
        return sf_fail(err, SF_EINVAL, "/camera/view_height", "view_height must be positive");
    return 0;
}

static int lights(json_t *j, struct scene *sc, struct sf_err *err)
{
    if (!json_is_array(j))
        return sf_fail(err, SF_EINVAL, "/lights", "expected an array of lights");
    size_t n = json_array_size(j);
    if (n > SCENE_MAX_LIGHTS)
        return sf_fail(err, SF_ELIMIT, "/lights", "at most %d lights", SCENE_MAX_LIGHTS);
    if (n == 0)
        return 0;
    sc->lights = calloc(n, sizeof *sc->lights);
    if (!sc->lights)
        return sf_fail(err, SF_ENOMEM, "/lights", "out of memory");
    sc->n_lights = (int)n;
    for (size_t k = 0; k < n; k++) {
        json_t *l = json_array_get(j, k), *v;
        struct light *L = &sc->lights[k];
        char p[64];
        int rc;
        snprintf(p, sizeof p, "/lights/%zu", k);
        if (!json_is_object(l))
            return sf_fail(err, SF_EINVAL, p, "expected an object");
        const char *type = json_string_value(json_object_get(l, "type"));
        L->point = type && !strcmp(type, "point");
        if (type && !L->point && strcmp(type, "directional")) {
            snprintf(p, sizeof p, "/lights/%zu/type", k);
            return sf_fail(err, SF_EINVAL, p, "light type is \"directional\" or \"point\"");
        }
        const char *key = L->point ? "position" : "direction";
        snprintf(p, sizeof p, "/lights/%zu/%s", k, key);
        if ((rc = vec(json_object_get(l, key), p, &L->v, err)))
            return rc;
        L->color = v3(1, 1, 1);
        snprintf(p, sizeof p, "/lights/%zu/color", k);
        if ((v = json_object_get(l, "color")) && (rc = vec(v, p, &L->color, err)))
            return rc;
    }
    return 0;
}

static int render_opts(json_t *j, struct scene *sc, struct sf_err *err)
{
    json_t *v;
    int rc;
    if (!json_is_object(j))
        return sf_fail(err, SF_EINVAL, "/render", "expected an object");
    if ((v = json_object_get(j, "method")) &&
        (!json_is_string(v) || scene_method_parse(json_string_value(v), &sc->method)))
        return sf_fail(err, SF_EINVAL, "/render/method", "method is auto, map, bvh, mesh or montecarlo");
    if ((v = json_object_get(j, "tolerance")) && (rc = num(v, "/render/tolerance", &sc->tolerance, err)))
        return rc;
    if ((v = json_object_get(j, "mesh_tolerance")) && (rc = num(v, "/render/mesh_tolerance", &sc->mesh_tolerance, err)))
        return rc;
    if ((v = json_object_get(j, "shadows"))) {
        if (!json_is_boolean(v))
            return sf_fail(err, SF_EINVAL, "/render/shadows", "expected true or false");
        sc->shadows = json_is_true(v);
    }
    return 0;
}

int scene_parse_json(const char *buf, size_t len, const struct model_resolver *models, struct scene *sc,
                     enum image_format *img, struct sf_err *err)
{
    scene_init(sc);
    *img = IMG_PNG;
    json_t *root;
    struct json_split sp; /* (a scene's bulk is its objects: read one at a time) */
    int rc = json_read_split(buf, len, (const char *const[]){"objects", "patches", NULL}, SCENE_MAX_OBJECTS, &root,
                             &sp, err);
    if (rc)
        return rc;
    json_t *v;
    if (!json_is_object(root)) {
        rc = sf_fail(err, SF_EINVAL, "", "a scene is a JSON object");
        goto out;
    }
    if ((v = json_object_get(root, "image")) && (rc = image(v, sc, img, err)))
        goto out;
    if ((v = json_object_get(root, "camera")) && (rc = camera(v, sc, err)))
        goto out;
    if ((v = json_object_get(root, "lights")) && (rc = lights(v, sc, err)))
        goto out;
    if ((v = json_object_get(root, "render")) && (rc = render_opts(v, sc, err)))
        goto out;
    const char *key = json_object_get(root, "objects") ? "objects" : "patches";
    json_t *objs = json_object_get(root, key);
    bool held = sp.held && !strcmp(sp.key, key);
    size_t n = held ? sp.n : json_array_size(objs);
    if (!json_is_array(objs) || n == 0) {
        rc = sf_fail(err, SF_EINVAL, "/objects", "a scene needs a non-empty \"objects\" array");
        goto out;
    }
    if (n > SCENE_MAX_OBJECTS) {
        rc = sf_fail(err, SF_ELIMIT, "/objects", "at most %d objects", SCENE_MAX_OBJECTS);
        goto out;
    }
    for (size_t k = 0; k < n && !rc; k++) {
        char where[64];
        snprintf(where, sizeof where, "/%s/%zu", key, k);
        json_t *o = held ? NULL : json_array_get(objs, k);
        if (held && (rc = json_read_element(&sp, k, &o, err)))
            break;
        rc = object(o, where, models, sc, err);
        if (held)
            json_decref(o);
    }
out:
    json_split_free(&sp);
    json_decref(root);
    if (rc)
        scene_free(sc);
    return rc;
}

int image_format_parse(const char *name, enum image_format *f)
{
    if (!name)
        return SF_EINVAL;
    if (!strcmp(name, "png"))
        *f = IMG_PNG;
    else if (!strcmp(name, "exr"))
        *f = IMG_EXR;
    else if (!strcmp(name, "tiff") || !strcmp(name, "tif"))
        *f = IMG_TIFF;
    else
        return SF_EINVAL;
    return 0;
}

const char *image_format_mime(enum image_format f)
{
    return f == IMG_EXR ? "image/x-exr" : f == IMG_TIFF ? "image/tiff" : "image/png";
}
