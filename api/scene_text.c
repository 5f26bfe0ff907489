/* scene_text.c - the plain-text scene files of shared/data/scenes: Newell's .bpt (a patch count,
 * then per patch "du dv" and (du+1)(dv+1) lines "x y z") and VRML97 NurbsSurface field syntax
 * (uOrder, vOrder, uDimension, vDimension, uKnot, vKnot, controlPoint, weight; several surfaces
 * one after another make one scene). Errors name the line. */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scene_io.h"

struct lexer {
    const char *p, *end;
    int line;
};

static void skip_space(struct lexer *lx)
{
    while (lx->p < lx->end) {
        char c = *lx->p;
        if (c == '#') { /* VRML comment to end of line */
            while (lx->p < lx->end && *lx->p != '\n')
                lx->p++;
        } else if (c == '\n') {
            lx->line++;
            lx->p++;
        } else if (isspace((unsigned char)c) || c == ',') {
            lx->p++;
        } else {
            break;
        }
    }
}

/* Reads a number; false at the end or on a non-number. */
static bool read_number(struct lexer *lx, double *out)
{
    skip_space(lx);
    if (lx->p >= lx->end)
        return false;
    char buf[64];
    size_t n = 0;
    while (lx->p + n < lx->end && n < sizeof buf - 1 && (isdigit((unsigned char)lx->p[n]) || strchr("+-.eE", lx->p[n])))
        n++;
    if (n == 0 || n == sizeof buf - 1)
        return false;
    memcpy(buf, lx->p, n);
    buf[n] = 0;
    char *e;
    errno = 0;
    double v = strtod(buf, &e);
    if (e != buf + n || errno == ERANGE)
        return false;
    lx->p += n;
    *out = v;
    return true;
}

static bool read_int(struct lexer *lx, int lo, int hi, int *out)
{
    double d;
    if (!read_number(lx, &d) || d != floor(d) || d < lo || d > hi)
        return false;
    *out = (int)d;
    return true;
}

int scene_parse_bpt(const char *buf, size_t len, struct scene *sc, struct sf_err *err)
{
    struct lexer lx = {buf, buf + len, 1};
    char where[64];
    int n;
    scene_init(sc);
    if (!read_int(&lx, 1, SCENE_MAX_OBJECTS, &n))
        return sf_fail(err, SF_EFORMAT, "line 1", "a .bpt file starts with its patch count (1..%d)", SCENE_MAX_OBJECTS);
    for (int k = 0; k < n; k++) {
        int p, q, rc;
        snprintf(where, sizeof where, "line %d", lx.line);
        if (!read_int(&lx, 1, PATCH_MAX_DEGREE, &p) || !read_int(&lx, 1, PATCH_MAX_DEGREE, &q)) {
            scene_free(sc);
            return sf_fail(err, SF_EFORMAT, where, "patch %d: expected its degrees \"du dv\" (1..%d)", k,
                           PATCH_MAX_DEGREE);
        }
        struct object *o = scene_add_object(sc);
        if (!o || (rc = nurbs_surface_alloc(&o->surf, SURF_BEZIER, p, q, p + 1, q + 1, err))) {
            scene_free(sc);
            return sf_fail(err, SF_ENOMEM, where, "out of memory");
        }
        for (int i = 0; i < 3 * (p + 1) * (q + 1); i++)
            if (!read_number(&lx, &o->surf.points[i])) {
                snprintf(where, sizeof where, "line %d", lx.line);
                scene_free(sc);
                return sf_fail(err, SF_EFORMAT, where, "patch %d: expected %d coordinates, got %d", k,
                               3 * (p + 1) * (q + 1), i);
            }
    }
    skip_space(&lx);
    if (lx.p != lx.end) {
        snprintf(where, sizeof where, "line %d", lx.line);
        scene_free(sc);
        return sf_fail(err, SF_EFORMAT, where, "unexpected text after %d patches", n);
    }
    return 0;
}

/* ---- VRML97 NurbsSurface ------------------------------------------------------------------ */

static bool read_word(struct lexer *lx, char *w, size_t cap)
{
    skip_space(lx);
    size_t n = 0;
    while (lx->p < lx->end && (isalnum((unsigned char)*lx->p) || *lx->p == '_') && n < cap - 1)
        w[n++] = *lx->p++;
    w[n] = 0;
    return n > 0;
}

static bool expect(struct lexer *lx, char c)
{
    skip_space(lx);
    if (lx->p < lx->end && *lx->p == c) {
        lx->p++;
        return true;
    }
    return false;
}

/* Reads "[ n n n ... ]" into a growing array (capped). */
static int read_array(struct lexer *lx, double **out, size_t *n, size_t cap)
{
    if (!expect(lx, '['))
        return SF_EFORMAT;
    size_t m = 0, room = 64;
    double *a = malloc(sizeof *a * room);
    if (!a)
        return SF_ENOMEM;
    while (!expect(lx, ']')) {
        double v;
        if (m >= cap || !read_number(lx, &v)) {
            free(a);
            return m >= cap ? SF_ELIMIT : SF_EFORMAT;
        }
        if (m == room) {
            double *b = realloc(a, sizeof *a * (room *= 2));
            if (!b) {
                free(a);
                return SF_ENOMEM;
            }
            a = b;
        }
        a[m++] = v;
    }
    free(*out);
    *out = a;
    *n = m;
    return 0;
}

struct vrml_surface {
    int order_u, order_v, dim_u, dim_v;
    double *knot_u, *knot_v, *cp, *w;
    size_t n_ku, n_kv, n_cp, n_w;
};

static void vrml_clear(struct vrml_surface *v)
{
    free(v->knot_u);
    free(v->knot_v);
    free(v->cp);
    free(v->w);
    memset(v, 0, sizeof *v);
}

/* Turns one parsed NurbsSurface into a scene object (VRML orders u fastest: transpose). */
static int vrml_emit(struct vrml_surface *v, struct scene *sc, int index, struct sf_err *err)
{
    char where[64];
    snprintf(where, sizeof where, "/objects/%d", index);
    int p = v->order_u - 1, q = v->order_v - 1, nu = v->dim_u, nv = v->dim_v;
    if (p < 1 || q < 1 || nu < 1 || nv < 1)
        return sf_fail(err, SF_EINVAL, where, "surface %d needs uOrder, vOrder >= 2 and its dimensions", index);
    if (v->n_cp != 3 * (size_t)nu * nv)
        return sf_fail(err, SF_EINVAL, where, "surface %d: %zu control point coordinates, expected 3 x %d x %d", index,
                       v->n_cp, nu, nv);
    if (v->n_ku != (size_t)(nu + p + 1) || v->n_kv != (size_t)(nv + q + 1))
        return sf_fail(err, SF_EINVAL, where, "surface %d: knot counts %zu, %zu; expected %d, %d", index, v->n_ku,
                       v->n_kv, nu + p + 1, nv + q + 1);
    bool weighted = v->n_w > 0;
    if (weighted && v->n_w != (size_t)nu * nv)
        return sf_fail(err, SF_EINVAL, where, "surface %d: %zu weights, expected %d", index, v->n_w, nu * nv);
    struct object *o = scene_add_object(sc);
    if (!o)
        return sf_fail(err, SF_ENOMEM, where, "out of memory");
    int rc = nurbs_surface_alloc(&o->surf, weighted ? SURF_NURBS : SURF_BSPLINE, p, q, nu, nv, err);
    if (rc)
        return rc;
    memcpy(o->surf.knots_u, v->knot_u, sizeof(double) * v->n_ku);
    memcpy(o->surf.knots_v, v->knot_v, sizeof(double) * v->n_kv);
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++) {
            size_t src = (size_t)j * nu + i, dst = (size_t)i * nv + j;
            memcpy(&o->surf.points[3 * dst], &v->cp[3 * src], sizeof(double) * 3);
            if (weighted)
                o->surf.weights[dst] = v->w[src];
        }
    return 0;
}

int scene_parse_vrml(const char *buf, size_t len, struct scene *sc, struct sf_err *err)
{
    struct lexer lx = {buf, buf + len, 1};
    struct vrml_surface v = {0};
    char word[48], where[64];
    int rc = 0, n = 0;
    bool open = false; /* a surface has fields that are not emitted yet */
    scene_init(sc);
    for (;;) {
        skip_space(&lx);
        if (lx.p >= lx.end)
            break;
        snprintf(where, sizeof where, "line %d", lx.line);
        if (expect(&lx, '{') || expect(&lx, '}'))
            continue;
        if (!read_word(&lx, word, sizeof word)) {
            rc = sf_fail(err, SF_EFORMAT, where, "unexpected character '%c'", *lx.p);
            goto out;
        }
        /* a new surface begins when a field it already has comes again */
        bool starts = (!strcmp(word, "uOrder") && v.order_u) || !strcmp(word, "NurbsSurface");
        if (starts && open) {
            if ((rc = vrml_emit(&v, sc, n++, err)))
                goto out;
            vrml_clear(&v);
            open = false;
        }
        if (!strcmp(word, "NurbsSurface") || !strcmp(word, "geometry") || !strcmp(word, "ccw") ||
            !strcmp(word, "solid") || !strcmp(word, "TRUE") || !strcmp(word, "FALSE"))
            continue;
        int *iv = !strcmp(word, "uOrder") ? &v.order_u : !strcmp(word, "vOrder") ? &v.order_v
                : !strcmp(word, "uDimension") ? &v.dim_u : !strcmp(word, "vDimension") ? &v.dim_v : NULL;
        if (iv) {
            int lim = iv == &v.order_u || iv == &v.order_v ? PATCH_MAX_DEGREE + 1 : SURF_MAX_POINTS;
            if (!read_int(&lx, 1, lim, iv)) {
                rc = sf_fail(err, SF_EFORMAT, where, "%s needs an integer in 1..%d", word, lim);
                goto out;
            }
            open = true;
            continue;
        }
        double **arr = !strcmp(word, "uKnot") ? &v.knot_u : !strcmp(word, "vKnot") ? &v.knot_v
                     : !strcmp(word, "controlPoint") ? &v.cp : !strcmp(word, "weight") ? &v.w : NULL;
        size_t *cnt = arr == &v.knot_u ? &v.n_ku : arr == &v.knot_v ? &v.n_kv : arr == &v.cp ? &v.n_cp : &v.n_w;
        if (!arr) {
            rc = sf_fail(err, SF_EFORMAT, where, "unknown field \"%s\"", word);
            goto out;
        }
        if ((rc = read_array(&lx, arr, cnt, 3 * (size_t)SURF_MAX_POINTS))) {
            rc = sf_fail(err, rc, where, "%s: expected a list of numbers in [ ]", word);
            goto out;
        }
        open = true;
    }
    if (open)
        rc = vrml_emit(&v, sc, n++, err);
    else if (n == 0)
        rc = sf_fail(err, SF_EFORMAT, "", "no NurbsSurface fields found");
out:
    vrml_clear(&v);
    if (rc)
        scene_free(sc);
    return rc;
}
