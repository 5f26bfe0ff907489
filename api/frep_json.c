/* frep_json.c - FRep requests with jansson (frep_json.h). */
#include "frep_json.h"
#include "json_in.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define COORD_MAX 1e9 /* mm: any coordinate or length of a request */

struct builder {
    struct frep_request *req;
    struct frep *f;
    int cap;                 /* of f->nodes */
    double alpha;            /* the request's, for operations that give none */
    struct sf_err *err;
};

static int bad(struct builder *b, const char *ptr, const char *fmt, const char *what)
{
    return sf_fail(b->err, SF_EINVAL, ptr, fmt, what);
}

/* Every key of o is one of keys (a NULL-ended list). */
static int only_keys(struct builder *b, json_t *o, const char *ptr, const char *const *keys)
{
    const char *k;
    json_t *v;
    json_object_foreach(o, k, v) {
        bool known = false;
        for (int i = 0; keys[i] && !known; i++)
            known = !strcmp(k, keys[i]);
        if (!known) {
            char p[160];
            snprintf(p, sizeof p, "%s/%s", ptr, k);
            return sf_fail(b->err, SF_EINVAL, p, "unknown member \"%.40s\"", k);
        }
    }
    return 0;
}

/* o[key] as a number in [lo, hi] (open at lo when open_lo): 0, or a 422. Absent: dflt when
 * has_default, else a 422. */
static int num(struct builder *b, json_t *o, const char *ptr, const char *key, double lo, double hi, bool open_lo,
               bool has_default, double dflt, double *out)
{
    char p[160];
    snprintf(p, sizeof p, "%s/%s", ptr, key);
    json_t *v = json_object_get(o, key);
    if (!v) {
        if (has_default) {
            *out = dflt;
            return 0;
        }
        return bad(b, p, "%s is required", key);
    }
    double x = json_number_value(v);
    if (!json_is_number(v) || !isfinite(x))
        return bad(b, p, "%s is a number", key);
    if (x < lo || x > hi || (open_lo && x == lo))
        return sf_fail(b->err, SF_EINVAL, p, "%s is %s %g and at most %g, not %g", key, open_lo ? "over" : "at least",
                       lo, hi, x);
    *out = x;
    return 0;
}

/* o[key] as 3 finite numbers within COORD_MAX (unit length when unit: not zero). */
static int vec3(struct builder *b, json_t *o, const char *ptr, const char *key, bool unit, double out[3])
{
    char p[160];
    snprintf(p, sizeof p, "%s/%s", ptr, key);
    json_t *v = json_object_get(o, key);
    if (!v)
        return bad(b, p, "%s is required", key);
    if (!json_is_array(v) || json_array_size(v) != 3)
        return bad(b, p, "%s is [x, y, z]", key);
    for (int i = 0; i < 3; i++) {
        json_t *c = json_array_get(v, i);
        out[i] = json_number_value(c);
        if (!json_is_number(c) || !isfinite(out[i]) || fabs(out[i]) > COORD_MAX) {
            char q[176];
            snprintf(q, sizeof q, "%s/%d", p, i);
            return sf_fail(b->err, SF_EINVAL, q, "a finite number within %g", COORD_MAX);
        }
    }
    if (unit) {
        double n = sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
        if (!(n > 1e-12))
            return bad(b, p, "%s is a direction: not [0, 0, 0]", key);
        for (int i = 0; i < 3; i++)
            out[i] /= n;
    }
    return 0;
}

/* o[key] as 3 numbers, each over 0 (radii, scales). */
static int positive3(struct builder *b, json_t *o, const char *ptr, const char *key, double out[3])
{
    int rc = vec3(b, o, ptr, key, false, out);
    for (int i = 0; i < 3 && !rc; i++)
        if (!(out[i] > 0)) {
            char p[176];
            snprintf(p, sizeof p, "%s/%s/%d", ptr, key, i);
            rc = sf_fail(b->err, SF_EINVAL, p, "%s are over 0", key);
        }
    return rc;
}

static int add_node(struct builder *b, const char *ptr, struct frep_node n)
{
    if (b->f->n >= FREP_MAX_NODES)
        return sf_fail(b->err, SF_ELIMIT, ptr, "an FRep tree has at most %d nodes", FREP_MAX_NODES), -1;
    if (b->f->n == b->cap) {
        int cap = b->cap ? 2 * b->cap : 16;
        struct frep_node *nodes = realloc(b->f->nodes, sizeof *nodes * (size_t)cap);
        if (!nodes)
            return sf_fail(b->err, SF_ENOMEM, ptr, "out of memory"), -1;
        b->f->nodes = nodes, b->cap = cap;
    }
    b->f->nodes[b->f->n] = n;
    return b->f->n++;
}

static int node(struct builder *b, json_t *o, const char *ptr, int depth, int *out);

/* The list's nodes combined by kind, as a balanced tree: *out its root. */
static int balanced(struct builder *b, const int *ids, int n, enum frep_kind kind, double alpha, const char *ptr,
                    int *out)
{
    if (n == 1) {
        *out = ids[0];
        return 0;
    }
    int l, r, rc;
    if ((rc = balanced(b, ids, n / 2, kind, alpha, ptr, &l)) || (rc = balanced(b, ids + n / 2, n - n / 2, kind, alpha, ptr, &r)))
        return rc;
    int id = add_node(b, ptr, (struct frep_node){.kind = kind, .a = l, .b = r, .alpha = alpha});
    if (id < 0)
        return b->err->code;
    *out = id;
    return 0;
}

/* {"union" | "intersect" | "subtract" | "blend": [NODE, ...], params} */
static int operation(struct builder *b, json_t *o, const char *ptr, const char *key, json_t *list, int depth, int *out)
{
    static const char *const SET_KEYS[] = {"union", "intersect", "subtract", "alpha", NULL};
    static const char *const BLEND_KEYS[] = {"blend", "alpha", "a0", "a1", "a2", NULL};
    bool blend = !strcmp(key, "blend");
    int rc = only_keys(b, o, ptr, blend ? BLEND_KEYS : SET_KEYS);
    if (rc)
        return rc;
    char p[160];
    snprintf(p, sizeof p, "%s/%s", ptr, key);
    size_t n = json_array_size(list);
    size_t least = !strcmp(key, "union") || !strcmp(key, "intersect") ? 1 : 2;
    if (!json_is_array(list) || n < least || (blend && n != 2))
        return sf_fail(b->err, SF_EINVAL, p, "%s is a list of %s objects", key,
                       blend ? "two" : least == 1 ? "one or more" : "two or more");
    if (n > FREP_MAX_NODES)
        return sf_fail(b->err, SF_ELIMIT, p, "an FRep tree has at most %d nodes", FREP_MAX_NODES);
    double alpha;
    if ((rc = num(b, o, ptr, "alpha", 0, 1, false, true, b->alpha, &alpha)))
        return rc;
    int *ids = malloc(sizeof *ids * n);
    if (!ids)
        return sf_fail(b->err, SF_ENOMEM, p, "out of memory");
    for (size_t i = 0; i < n && !rc; i++) {
        char q[176];
        snprintf(q, sizeof q, "%s/%zu", p, i);
        rc = node(b, json_array_get(list, i), q, depth + 1, &ids[i]);
    }
    if (!rc && !strcmp(key, "subtract")) { /* a minus (b or c or ...) */
        int rest;
        if (!(rc = balanced(b, ids + 1, (int)n - 1, FREP_UNION, alpha, p, &rest))) {
            int id = add_node(b, p, (struct frep_node){.kind = FREP_SUBTRACT, .a = ids[0], .b = rest, .alpha = alpha});
            rc = id < 0 ? b->err->code : 0;
            *out = id;
        }
    } else if (!rc && blend) {
        struct frep_node nd = {.kind = FREP_BLEND, .a = ids[0], .b = ids[1], .alpha = alpha};
        if (!(rc = num(b, o, ptr, "a0", -COORD_MAX, COORD_MAX, false, false, 0, &nd.p[0])) &&
            !(rc = num(b, o, ptr, "a1", 0, COORD_MAX, true, false, 0, &nd.p[1])) &&
            !(rc = num(b, o, ptr, "a2", 0, COORD_MAX, true, false, 0, &nd.p[2]))) {
            int id = add_node(b, p, nd);
            rc = id < 0 ? b->err->code : 0;
            *out = id;
        }
    } else if (!rc) {
        rc = balanced(b, ids, (int)n, !strcmp(key, "union") ? FREP_UNION : FREP_INTERSECT, alpha, p, out);
    }
    free(ids);
    return rc;
}

/* {"offset": {...}} or {"transform": {...}} */
static int unary(struct builder *b, const char *key, json_t *v, const char *p, int depth, int *out)
{
    static const char *const OFFSET_KEYS[] = {"distance", "object", NULL};
    static const char *const TRANSFORM_KEYS[] = {"scale", "rotate_deg", "translate", "object", NULL};
    bool offset = !strcmp(key, "offset");
    if (!json_is_object(v))
        return bad(b, p, "%s is an object", key);
    int rc = only_keys(b, v, p, offset ? OFFSET_KEYS : TRANSFORM_KEYS);
    if (rc)
        return rc;
    struct frep_node nd = {.kind = offset ? FREP_OFFSET : FREP_TRANSFORM};
    if (offset) {
        if ((rc = num(b, v, p, "distance", -COORD_MAX, COORD_MAX, false, false, 0, &nd.p[0])))
            return rc;
    } else {
        double scale[3] = {1, 1, 1}, rot[3] = {0, 0, 0}, tr[3] = {0, 0, 0};
        json_t *s = json_object_get(v, "scale");
        if (json_is_number(s)) {
            if ((rc = num(b, v, p, "scale", 0, 1e6, true, false, 0, &scale[0])))
                return rc;
            scale[1] = scale[2] = scale[0];
        } else if (s && (rc = positive3(b, v, p, "scale", scale))) {
            return rc;
        }
        if ((json_object_get(v, "rotate_deg") && (rc = vec3(b, v, p, "rotate_deg", false, rot))) ||
            (json_object_get(v, "translate") && (rc = vec3(b, v, p, "translate", false, tr))))
            return rc;
        frep_transform(&nd, scale, rot, tr);
    }
    char q[176];
    snprintf(q, sizeof q, "%s/object", p);
    json_t *child = json_object_get(v, "object");
    if (!child)
        return bad(b, q, "%s needs an object", key);
    if ((rc = node(b, child, q, depth + 1, &nd.a)))
        return rc;
    int id = add_node(b, p, nd);
    if (id < 0)
        return b->err->code;
    *out = id;
    return 0;
}

/* {"volume": {"model": ID, "scale": s}}: the model's samples, read by the request's caller. */
static int volume_node(struct builder *b, json_t *v, const char *p, int *out)
{
    static const char *const KEYS[] = {"model", "scale", NULL};
    if (!json_is_object(v))
        return bad(b, p, "%s is an object", "volume");
    int rc = only_keys(b, v, p, KEYS);
    if (rc)
        return rc;
    struct frep_request *r = b->req;
    char q[176];
    snprintf(q, sizeof q, "%s/model", p);
    const char *id = json_string_value(json_object_get(v, "model"));
    size_t n = id ? strlen(id) : 0;
    if (!id || n < 1 || n > 32 || strspn(id, "0123456789abcdef") != n)
        return bad(b, q, "%s is the id of a stored isosurface model (32 hex digits)", "model");
    int k = 0;
    while (k < r->n_refs && strcmp(r->refs[k].model, id))
        k++;
    if (k == FREP_MAX_VOLUMES)
        return sf_fail(b->err, SF_ELIMIT, q, "an FRep tree reads at most %d volumes", FREP_MAX_VOLUMES);
    if (k == r->n_refs) {
        snprintf(r->refs[k].model, sizeof r->refs[k].model, "%s", id);
        snprintf(r->refs[k].pointer, sizeof r->refs[k].pointer, "%s", q);
        r->n_refs++;
    }
    struct frep_node nd = {.kind = FREP_VOLUME, .p = {k, 0, 1}};
    if ((rc = num(b, v, p, "scale", 0, 1e9, true, true, 1, &nd.p[2])))
        return rc;
    int at = add_node(b, p, nd);
    if (at < 0)
        return b->err->code;
    *out = at;
    return 0;
}

void frep_volume_iso(struct frep_request *r, int k, double iso)
{
    for (int i = 0; i < r->f.n; i++)
        if (r->f.nodes[i].kind == FREP_VOLUME && (int)r->f.nodes[i].p[0] == k)
            r->f.nodes[i].p[1] = iso;
}

static int primitive(struct builder *b, const char *key, json_t *v, const char *p, int *out)
{
    if (!strcmp(key, "volume"))
        return volume_node(b, v, p, out);
    static const struct {
        const char *name;
        enum frep_kind kind;
        const char *keys[5];
    } PRIMS[] = {
        {"sphere", FREP_SPHERE, {"center", "radius"}},
        {"ellipsoid", FREP_ELLIPSOID, {"center", "radii"}},
        {"box", FREP_BOX, {"min", "max"}},
        {"cylinder", FREP_CYLINDER, {"base", "axis", "radius", "length"}},
        {"cone", FREP_CONE, {"base", "axis", "radius", "length"}},
        {"torus", FREP_TORUS, {"center", "axis", "major", "minor"}},
        {"superellipsoid", FREP_SUPERELLIPSOID, {"center", "radii", "e1", "e2"}},
        {"halfspace", FREP_HALFSPACE, {"point", "normal"}},
    };
    size_t k = 0;
    while (k < sizeof PRIMS / sizeof *PRIMS && strcmp(PRIMS[k].name, key))
        k++;
    if (k == sizeof PRIMS / sizeof *PRIMS)
        return sf_fail(b->err, SF_EINVAL, p,
                       "unknown primitive or operation \"%.40s\" (sphere, ellipsoid, box, cylinder, cone, torus, "
                       "superellipsoid, halfspace, volume; union, intersect, subtract, blend, offset, transform)", key);
    if (!json_is_object(v))
        return bad(b, p, "%s is an object", key);
    int rc = only_keys(b, v, p, PRIMS[k].keys);
    if (rc)
        return rc;
    struct frep_node nd = {.kind = PRIMS[k].kind};
    double *q = nd.p;
    const double L = COORD_MAX;
    switch (nd.kind) {
    case FREP_SPHERE:
        rc = vec3(b, v, p, "center", false, q) || num(b, v, p, "radius", 0, L, true, false, 0, q + 3);
        break;
    case FREP_ELLIPSOID:
        rc = vec3(b, v, p, "center", false, q) || positive3(b, v, p, "radii", q + 3);
        break;
    case FREP_BOX:
        if (!(rc = vec3(b, v, p, "min", false, q)) && !(rc = vec3(b, v, p, "max", false, q + 3)))
            for (int i = 0; i < 3 && !rc; i++)
                if (!(q[3 + i] > q[i])) {
                    char r[176];
                    snprintf(r, sizeof r, "%s/max/%d", p, i);
                    rc = sf_fail(b->err, SF_EINVAL, r, "max is over min on every axis");
                }
        break;
    case FREP_CYLINDER:
    case FREP_CONE:
        rc = vec3(b, v, p, "base", false, q) || vec3(b, v, p, "axis", true, q + 3) ||
             num(b, v, p, "radius", 0, L, true, false, 0, q + 6) || num(b, v, p, "length", 0, L, true, false, 0, q + 7);
        break;
    case FREP_TORUS:
        rc = vec3(b, v, p, "center", false, q) || vec3(b, v, p, "axis", true, q + 3) ||
             num(b, v, p, "major", 0, L, true, false, 0, q + 6) || num(b, v, p, "minor", 0, L, true, false, 0, q + 7);
        break;
    case FREP_SUPERELLIPSOID:
        rc = vec3(b, v, p, "center", false, q) || positive3(b, v, p, "radii", q + 3) ||
             num(b, v, p, "e1", 0.05, 10, false, false, 0, q + 6) || num(b, v, p, "e2", 0.05, 10, false, false, 0, q + 7);
        break;
    default: /* halfspace */
        rc = vec3(b, v, p, "point", false, q) || vec3(b, v, p, "normal", true, q + 3);
        break;
    }
    if (rc)
        return b->err->code;
    int id = add_node(b, p, nd);
    if (id < 0)
        return b->err->code;
    *out = id;
    return 0;
}

static int node(struct builder *b, json_t *o, const char *ptr, int depth, int *out)
{
    if (depth > FREP_MAX_DEPTH)
        return sf_fail(b->err, SF_ELIMIT, ptr, "an FRep tree is at most %d levels deep", FREP_MAX_DEPTH);
    if (!json_is_object(o) || !json_object_size(o))
        return bad(b, ptr, "%s", "an FRep object is {\"primitive or operation\": ...}");
    static const char *const OPS[] = {"union", "intersect", "subtract", "blend"};
    for (int k = 0; k < 4; k++) {
        json_t *list = json_object_get(o, OPS[k]);
        if (list)
            return operation(b, o, ptr, OPS[k], list, depth, out);
    }
    if (json_object_size(o) != 1)
        return bad(b, ptr, "%s", "an FRep object has one member: its primitive or operation");
    const char *key = json_object_iter_key(json_object_iter(o));
    json_t *v = json_object_iter_value(json_object_iter(o));
    char p[160];
    snprintf(p, sizeof p, "%s/%s", ptr, key);
    if (!strcmp(key, "offset") || !strcmp(key, "transform"))
        return unary(b, key, v, p, depth, out);
    return primitive(b, key, v, p, out);
}

int frep_parse(const char *buf, size_t len, struct frep_request *r, struct sf_err *err)
{
    memset(r, 0, sizeof *r);
    json_t *root;
    int rc = json_read(buf, len, &root, err);
    if (rc)
        return rc;
    struct builder b = {r, &r->f, 0, 0, err};
    r->f.volumes = r->vols;
    static const char *const KEYS[] = {"name", "bounds", "cell", "alpha", "frep", NULL};
    if (!json_is_object(root)) {
        rc = sf_fail(err, SF_EINVAL, "", "an FRep request is a JSON object with \"frep\", \"bounds\" and \"cell\"");
        goto out;
    }
    if ((rc = only_keys(&b, root, "", KEYS)))
        goto out;
    json_t *name = json_object_get(root, "name");
    if (name && !json_is_string(name)) {
        rc = sf_fail(err, SF_EINVAL, "/name", "name is a string");
        goto out;
    }
    snprintf(r->name, sizeof r->name, "%s", name ? json_string_value(name) : "");
    json_t *bounds = json_object_get(root, "bounds");
    if (!json_is_array(bounds) || json_array_size(bounds) != 2) {
        rc = sf_fail(err, SF_EINVAL, "/bounds", "bounds are [[x0, y0, z0], [x1, y1, z1]]");
        goto out;
    }
    json_t *pair = json_pack("{s:O, s:O}", "0", json_array_get(bounds, 0), "1", json_array_get(bounds, 1));
    rc = !pair ? sf_fail(err, SF_ENOMEM, "", "out of memory")
               : vec3(&b, pair, "/bounds", "0", false, r->lo) || vec3(&b, pair, "/bounds", "1", false, r->hi);
    json_decref(pair);
    if (rc) {
        rc = err->code;
        goto out;
    }
    if ((rc = num(&b, root, "", "cell", 0, COORD_MAX, true, false, 0, &r->cell)) ||
        (rc = num(&b, root, "", "alpha", 0, 1, false, true, 0, &b.alpha)))
        goto out;
    double samples = 1;
    for (int a = 0; a < 3; a++) {
        if (!(r->hi[a] > r->lo[a])) {
            char p[16];
            snprintf(p, sizeof p, "/bounds/1/%d", a);
            rc = sf_fail(err, SF_EINVAL, p, "the bounds' second corner is above the first on every axis");
            goto out;
        }
        double n = ceil((r->hi[a] - r->lo[a]) / r->cell - 1e-9) + 1;
        samples *= n;
        r->dims[a] = n > FREP_MAX_SAMPLES ? (int)FREP_MAX_SAMPLES : (int)n;
    }
    if (samples > FREP_MAX_SAMPLES) {
        rc = sf_fail(err, SF_ELIMIT, "/cell", "cell %g makes a grid of %.0f samples: at most %u", r->cell, samples,
                     FREP_MAX_SAMPLES);
        goto out;
    }
    json_t *tree = json_object_get(root, "frep");
    if (!tree) {
        rc = sf_fail(err, SF_EINVAL, "/frep", "frep (the object) is required");
        goto out;
    }
    rc = node(&b, tree, "/frep", 1, &r->f.root);
out:
    json_decref(root);
    if (rc)
        frep_request_free(r);
    return rc;
}

void frep_request_free(struct frep_request *r)
{
    for (int k = 0; k < FREP_MAX_VOLUMES; k++)
        free(r->vol_samples[k]), r->vol_samples[k] = NULL;
    free(r->f.nodes);
    r->f.nodes = NULL;
    r->f.n = 0;
}

char *frep_combine(const char *request, size_t len, const char *edit, size_t elen, struct sf_err *err)
{
    static const char *const KEYS[] = {"op", "object", "alpha", NULL};
    json_t *req = NULL, *ed = NULL;
    char *out = NULL;
    if (json_read(edit, elen, &ed, err))
        return NULL;
    struct builder b = {NULL, NULL, 0, 0, err};
    const char *op = json_string_value(json_object_get(ed, "op"));
    json_t *object = json_object_get(ed, "object"), *alpha = json_object_get(ed, "alpha");
    if (!json_is_object(ed))
        sf_fail(err, SF_EINVAL, "", "an FRep model's edit is {\"op\": \"union|intersect|subtract\", \"object\": {...}}");
    else if (only_keys(&b, ed, "", KEYS))
        ;
    else if (!op || (strcmp(op, "union") && strcmp(op, "intersect") && strcmp(op, "subtract")))
        sf_fail(err, SF_EINVAL, "/op", "op is union, intersect or subtract");
    else if (!object)
        sf_fail(err, SF_EINVAL, "/object", "object (the FRep object to combine) is required");
    else if (alpha && (!json_is_number(alpha) || !(json_number_value(alpha) >= 0 && json_number_value(alpha) <= 1)))
        sf_fail(err, SF_EINVAL, "/alpha", "alpha is a number from 0 to 1");
    else if (json_read(request, len, &req, err) || !json_is_object(req))
        sf_fail(err, SF_EINVAL, "", "the model's FRep request could not be read back");
    else {
        json_t *node = json_pack("{s:[O,O]}", op, json_object_get(req, "frep"), object);
        if (node && alpha)
            json_object_set(node, "alpha", alpha);
        json_object_set_new(req, "frep", node);
        out = json_dumps(req, JSON_COMPACT | JSON_REAL_PRECISION(17));
        struct frep_request r;
        char inner[32];
        snprintf(inner, sizeof inner, "/frep/%s/1", op);
        if (!out) {
            sf_fail(err, SF_ENOMEM, "", "out of memory");
        } else if (frep_parse(out, strlen(out), &r, err)) { /* the object's pointer, as the edit names it */
            char p[sizeof err->pointer];
            size_t n = strlen(inner);
            snprintf(p, sizeof p, "/object%s", !strncmp(err->pointer, inner, n) ? err->pointer + n : "");
            snprintf(err->pointer, sizeof err->pointer, "%s", p);
            free(out);
            out = NULL;
        } else {
            frep_request_free(&r);
        }
    }
    json_decref(req);
    json_decref(ed);
    return out;
}
