/* contour_json.c - contour requests with jansson. Only what is built is accepted (method parabolic,
 * caps flat or slab); the rest answers 422 naming the field. */
#include "contour_json.h"
#include "json_in.h"

#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int points(json_t *a, const char *ptr, struct contour_slice *s, struct sf_err *err)
{
    if (!json_is_array(a))
        return sf_fail(err, SF_EINVAL, ptr, "expected an array of [x, y] points");
    size_t n = json_array_size(a);
    if (n > CONTOUR_MAX_POINTS)
        return sf_fail(err, SF_ELIMIT, ptr, "more than %d points", CONTOUR_MAX_POINTS);
    s->p = malloc(sizeof *s->p * (n ? n : 1));
    if (!s->p)
        return sf_fail(err, SF_ENOMEM, ptr, "out of memory");
    s->n = (int)n;
    for (size_t i = 0; i < n; i++) {
        json_t *q = json_array_get(a, i);
        char p[96];
        snprintf(p, sizeof p, "%s/%zu", ptr, i);
        if (!json_is_array(q) || json_array_size(q) < 2 || json_array_size(q) > 3 || !json_is_number(json_array_get(q, 0)) ||
            !json_is_number(json_array_get(q, 1)))
            return sf_fail(err, SF_EINVAL, p, "expected [x, y]");
        s->p[i][0] = json_number_value(json_array_get(q, 0));
        s->p[i][1] = json_number_value(json_array_get(q, 1));
    }
    return 0;
}

static int option(json_t *root, const char *key, const char *dflt, const char *const *allowed, char *out, size_t cap,
                  struct sf_err *err)
{
    json_t *v = json_object_get(root, key);
    char ptr[32];
    snprintf(ptr, sizeof ptr, "/%s", key);
    const char *s = v ? json_string_value(v) : dflt;
    if (!s)
        return sf_fail(err, SF_EINVAL, ptr, "expected a string");
    for (int k = 0; allowed[k]; k++)
        if (!strcmp(s, allowed[k])) {
            snprintf(out, cap, "%s", s);
            return 0;
        }
    char list[128] = "";
    for (int k = 0; allowed[k]; k++)
        snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", k ? ", " : "", allowed[k]);
    return sf_fail(err, SF_EINVAL, ptr, "\"%.40s\" is not one of %s", s, list);
}

int contour_parse_json(const char *buf, size_t len, struct contour_set *cs, struct contour_request *req,
                       struct sf_err *err)
{
    memset(cs, 0, sizeof *cs);
    memset(req, 0, sizeof *req);
    json_t *root;
    int rc = json_read(buf, len, &root, err);
    if (rc)
        return rc;
    static const char *const METHODS[] = {"parabolic", "linear-parabolic", "coons", "bspline", NULL},
                             *const CAPS[] = {"flat", "slab", "dome", NULL}, *const PARAMS[] = {"arc-length", "polar", NULL};
    rc = 0;
    json_t *slices = json_object_get(root, "slices");
    if (!json_is_object(root)) {
        rc = sf_fail(err, SF_EINVAL, "", "contours are a JSON object with \"slices\"");
        goto out;
    }
    const char *name = json_string_value(json_object_get(root, "name"));
    snprintf(req->name, sizeof req->name, "%s", name ? name : "");
    if ((rc = option(root, "method", "parabolic", METHODS, req->method, sizeof req->method, err)) ||
        (rc = option(root, "caps", "flat", CAPS, req->caps, sizeof req->caps, err)) ||
        (rc = option(root, "parameterisation", "arc-length", PARAMS, req->param, sizeof req->param, err)))
        goto out;
    if (!json_is_array(slices) || json_array_size(slices) < 2) {
        rc = sf_fail(err, SF_EINVAL, "/slices", "expected an array of at least 2 slices");
        goto out;
    }
    size_t n = json_array_size(slices);
    if (n > CONTOUR_MAX_SLICES) {
        rc = sf_fail(err, SF_ELIMIT, "/slices", "more than %d slices", CONTOUR_MAX_SLICES);
        goto out;
    }
    size_t total = 0; /* contours in all */
    for (size_t k = 0; k < n; k++) {
        json_t *list = json_object_get(json_array_get(slices, k), "contours");
        total += json_is_array(list) ? json_array_size(list) : 1;
    }
    if (total > CONTOUR_MAX_SLICES) {
        rc = sf_fail(err, SF_ELIMIT, "/slices", "more than %d contours", CONTOUR_MAX_SLICES);
        goto out;
    }
    cs->s = calloc(total ? total : 1, sizeof *cs->s);
    if (!cs->s) {
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        goto out;
    }
    for (size_t k = 0; k < n && !rc; k++) {
        json_t *s = json_array_get(slices, k), *z = json_object_get(s, "z");
        char ptr[80];
        snprintf(ptr, sizeof ptr, "/slices/%zu/z", k);
        if (!json_is_object(s) || !json_is_number(z)) {
            rc = sf_fail(err, SF_EINVAL, ptr, "expected a number");
            break;
        }
        json_t *pts = json_object_get(s, "points"), *list = json_object_get(s, "contours");
        if (pts || !list) { /* the single-contour form */
            struct contour_slice *c = &cs->s[cs->n_slices++];
            c->src = (int)k;
            c->src_contour = -1;
            c->z = json_number_value(z);
            snprintf(ptr, sizeof ptr, "/slices/%zu/points", k);
            rc = points(pts, ptr, c, err);
            continue;
        }
        snprintf(ptr, sizeof ptr, "/slices/%zu/contours", k);
        if (!json_is_array(list) || json_array_size(list) == 0) {
            rc = sf_fail(err, SF_EINVAL, ptr, "expected a non-empty array of {\"points\": [...]}");
            break;
        }
        for (size_t i = 0; i < json_array_size(list) && !rc; i++) {
            struct contour_slice *c = &cs->s[cs->n_slices++];
            c->src = (int)k;
            c->src_contour = (int)i;
            c->z = json_number_value(z);
            snprintf(ptr, sizeof ptr, "/slices/%zu/contours/%zu/points", k, i);
            rc = points(json_object_get(json_array_get(list, i), "points"), ptr, c, err);
        }
    }
    if (!rc)
        rc = contour_json_clean(cs, err);
out:
    json_decref(root);
    if (rc)
        contour_set_free(cs);
    return rc;
}

int contour_json_clean(struct contour_set *cs, struct sf_err *err)
{
    struct contour_fault f;
    bool fresh = err && !err->code; /* (the first failure recorded wins: its pointer too) */
    int rc = contour_clean(cs, &f, err);
    if (!rc || !fresh)
        return rc;
    if (f.slice < 0)
        snprintf(err->pointer, sizeof err->pointer, "/slices");
    else if (f.z)
        snprintf(err->pointer, sizeof err->pointer, "/slices/%d/z", f.slice);
    else if (f.contour < 0)
        snprintf(err->pointer, sizeof err->pointer, "/slices/%d/points", f.slice);
    else
        snprintf(err->pointer, sizeof err->pointer, "/slices/%d/contours/%d/points", f.slice, f.contour);
    if (f.slice >= 0 && !f.z && f.point >= 0)
        snprintf(err->pointer + strlen(err->pointer), sizeof err->pointer - strlen(err->pointer), "/%d", f.point);
    return rc;
}

char *contour_json_write(const struct contour_set *cs, const struct contour_request *req)
{
    json_t *slices = json_array(), *root = json_pack("{s:s, s:s, s:s, s:s, s:o}", "name", req->name, "method",
                                                     req->method, "caps", req->caps, "parameterisation", req->param,
                                                     "slices", slices);
    json_t *level = NULL;
    for (int k = 0; root && k < cs->n_slices; k++) {
        const struct contour_slice *c = &cs->s[k];
        if (k == 0 || c->z != cs->s[k - 1].z) {
            level = json_pack("{s:f, s:[]}", "z", c->z, "contours");
            json_array_append_new(slices, level);
        }
        json_t *pts = json_array();
        for (int i = 0; i < c->n; i++)
            json_array_append_new(pts, json_pack("[f,f]", c->p[i][0], c->p[i][1]));
        json_array_append_new(json_object_get(level, "contours"), json_pack("{s:o}", "points", pts));
    }
    char *out = root ? json_dumps(root, JSON_COMPACT | JSON_REAL_PRECISION(17)) : NULL;
    json_decref(root);
    return out;
}
