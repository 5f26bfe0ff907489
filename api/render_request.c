/* render_request.c - query options and media types of POST /render. */
#include "render_request.h"

#include "query.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

static int num_opt(const char *name, const char *v, double lo, double hi, double *out, struct sf_err *err)
{
    char *end, ptr[48];
    double d = strtod(v, &end);
    snprintf(ptr, sizeof ptr, "?%s", name);
    if (end == v || *end || !isfinite(d) || d < lo || d > hi)
        return sf_fail(err, SF_EINVAL, ptr, "%s must be a number in [%g, %g], not \"%s\"", name, lo, hi, v);
    *out = d;
    return 0;
}

/* Applies one option. */
enum { SEEN_EYE = 1, SEEN_TARGET = 2 };

static int apply(const char *name, const char *v, struct scene *sc, enum image_format *img, unsigned *seen,
                 struct sf_err *err)
{
    double d;
    int rc = 0;
    if (!strcmp(name, "format"))
        return 0; /* the body's format, handled by the caller */
    if (!strcmp(name, "output")) {
        if (image_format_parse(v, img))
            return sf_fail(err, SF_EINVAL, "?output", "output is png, exr or tiff, not \"%s\"", v);
    } else if (!strcmp(name, "method")) {
        if (scene_method_parse(v, &sc->method))
            return sf_fail(err, SF_EINVAL, "?method", "method is auto, map, bvh, mesh or montecarlo");
    } else if (!strcmp(name, "samples")) {
        if (!(rc = num_opt(name, v, 1, SCENE_MAX_SAMPLES, &d, err)))
            sc->samples = (int)d;
        if (!rc && d != (int)d)
            rc = sf_fail(err, SF_EINVAL, "?samples", "samples is a whole number of rays a pixel, 1..%d", SCENE_MAX_SAMPLES);
    } else if (!strcmp(name, "width") || !strcmp(name, "height")) {
        if (!(rc = num_opt(name, v, 1, SCENE_MAX_SIDE, &d, err)))
            *(name[0] == 'w' ? &sc->width : &sc->height) = (int)d;
    } else if (!strcmp(name, "azimuth")) {
        rc = num_opt(name, v, -3600, 3600, &sc->azimuth_deg, err);
    } else if (!strcmp(name, "elevation")) {
        rc = num_opt(name, v, -89.9, 89.9, &sc->elevation_deg, err);
    } else if (!strcmp(name, "projection")) {
        if (strcmp(v, "perspective") && strcmp(v, "orthographic"))
            return sf_fail(err, SF_EINVAL, "?projection", "projection is perspective or orthographic, not \"%.40s\"", v);
        sc->ortho = v[0] == 'o';
    } else if (!strcmp(name, "view")) {
        if (scene_view_parse(v[0] == ' ' ? v + 1 : v, &sc->view)) /* a '+' left unescaped reads as a space */
            return sf_fail(err, SF_EINVAL, "?view", "view is +x, -x, +y, -y, +z or -z, not \"%.40s\"", v);
        sc->has_camera = false; /* the query's view replaces the body's camera */
    } else if (!strcmp(name, "view_height")) {
        rc = num_opt(name, v, 1e-9, SURF_MAX_COORD, &sc->view_height, err);
    } else if (!strcmp(name, "fov")) {
        rc = num_opt(name, v, 0.01, 178.99, &sc->fov_deg, err);
    } else if (!strcmp(name, "eye") || !strcmp(name, "target") || !strcmp(name, "up")) {
        vec3 *to = name[0] == 'e' ? &sc->eye : name[0] == 't' ? &sc->target : &sc->up;
        double a[3];
        char ptr[16], *end = NULL;
        snprintf(ptr, sizeof ptr, "?%s", name);
        const char *q = v;
        for (int k = 0; k < 3; k++, q = end + 1) {
            a[k] = strtod(q, &end);
            if (end == q || !isfinite(a[k]) || fabs(a[k]) > SURF_MAX_COORD || *end != (k < 2 ? ',' : '\0'))
                return sf_fail(err, SF_EINVAL, ptr, "%s is x,y,z (three numbers within ±%g), not \"%.60s\"", name,
                               SURF_MAX_COORD, v);
        }
        *to = v3(a[0], a[1], a[2]);
        if (name[0] != 'u') {
            *seen |= name[0] == 'e' ? SEEN_EYE : SEEN_TARGET;
            sc->has_camera = true; /* checked below: eye and target come together */
            sc->view = VIEW_NONE;
        }
    } else if (!strcmp(name, "aovs")) { /* normal,uv,id: EXR (and TIFF) layers besides colour and depth */
        for (const char *p = v; *p; p += strcspn(p, ","), p += *p == ',') {
            unsigned aov = scene_aov_parse(p, strcspn(p, ","));
            if (!aov)
                return sf_fail(err, SF_EINVAL, "?aovs", "aovs is a list of normal, uv and id, not \"%.40s\"", v);
            sc->aovs |= aov;
        }
    } else if (!strcmp(name, "shadows")) {
        if (!(rc = num_opt(name, v, 0, 1, &d, err)))
            sc->shadows = d != 0;
    } else {
        char ptr[64];
        snprintf(ptr, sizeof ptr, "?%.40s", name);
        return sf_fail(err, SF_EINVAL, ptr, "unknown option \"%.40s\"", name);
    }
    return rc;
}

int render_options_apply(const char *options, struct scene *sc, enum image_format *img, struct sf_err *err)
{
    /* options: name=value&...; values are plain (the daemon decodes %-escapes before storing) */
    const char *p = options ? options : "";
    const bool body_camera = sc->has_camera;
    unsigned seen = 0;
    int rc = 0;
    while (*p && !rc) {
        char name[48] = "", value[128] = "";
        size_t n = strcspn(p, "=&");
        snprintf(name, sizeof name, "%.*s", (int)(n < sizeof name ? n : sizeof name - 1), p);
        p += n;
        if (*p == '=') {
            p++;
            size_t m = strcspn(p, "&");
            snprintf(value, sizeof value, "%.*s", (int)(m < sizeof value ? m : sizeof value - 1), p);
            p += m;
        }
        if (*p == '&')
            p++;
        if (name[0])
            rc = apply(name, value, sc, img, &seen, err);
    }
    if (!rc && !body_camera && !(seen & SEEN_EYE) != !(seen & SEEN_TARGET))
        rc = sf_fail(err, SF_EINVAL, seen & SEEN_EYE ? "?target" : "?eye", "eye and target come together");
    return rc;
}

int render_request_parse(const char *body, size_t len, const char *format, const char *options,
                         const struct model_resolver *models, struct scene *sc, enum image_format *img,
                         struct sf_err *err)
{
    enum scene_format fmt = scene_format_parse(format);
    if ((int)fmt < 0)
        return sf_fail(err, SF_EFORMAT, "?format", "format is json, bpt, nurbs or iges, not \"%s\"", format);
    int rc = scene_parse_models(body, len, fmt, models, sc, img, err);
    if (rc)
        return rc;
    rc = render_options_apply(options, sc, img, err);
    if (!rc)
        rc = scene_validate(sc, err);
    char where[32];
    for (int k = 0; !rc && k < sc->n_objects; k++) {
        snprintf(where, sizeof where, "/objects/%d", k);
        rc = nurbs_validate(&sc->objects[k].surf, where, err);
    }
    if (rc)
        scene_free(sc);
    return rc;
}
