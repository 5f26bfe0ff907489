/* model_rtstruct.c - stored models as one DICOM RT Structure Set, an ROI each: each mesh cut by
 * planes (a contour model's own slices, an isosurface's grid, or ?spacing apart) into closed planar
 * contours, holes cut into their outer contours (keyhole.h) for readers that fill every contour;
 * what the source structure set said of each ROI (colour, interpreted type, study, frame, images)
 * written back, or chosen here (api/README.md, "RT Structure Sets out"). */
#include "model_json_internal.h"

#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "../core/geom/keyhole.h"
#include "mesh_io.h"
#include "query.h"
#include "rtstruct.h"

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

/* ROI colours for models whose source gave none, by ROI number: ten well-separated hues (Tableau
 * 10), as planning systems cycle a palette */
static const int PALETTE[][3] = {{31, 119, 180}, {255, 127, 14}, {44, 160, 44}, {214, 39, 40}, {148, 103, 189},
                                 {140, 86, 75},  {227, 119, 194}, {127, 127, 127}, {188, 189, 34}, {23, 190, 207}};

/* RTROIInterpretedType from an ROI's name where its source gave none: the body's outline EXTERNAL,
 * target volumes by their usual prefixes, anything else ORGAN */
static const char *type_by_name(const char *name)
{
    static const struct {
        const char *prefix, *type;
    } BY_NAME[] = {{"body", "EXTERNAL"}, {"external", "EXTERNAL"}, {"skin", "EXTERNAL"}, {"outline", "EXTERNAL"},
                   {"ptv", "PTV"},       {"ctv", "CTV"},           {"gtv", "GTV"}};
    for (size_t k = 0; k < sizeof BY_NAME / sizeof *BY_NAME; k++)
        if (!strncasecmp(name, BY_NAME[k].prefix, strlen(BY_NAME[k].prefix)))
            return BY_NAME[k].type;
    return "ORGAN";
}

static const char *str_of(json_t *r, const char *key)
{
    const char *v = json_string_value(json_object_get(r, key));
    return v && *v ? v : NULL;
}

void model_roi_look(json_t *r, int k, const char **name, int color[3], const char **type)
{
    json_t *c = json_object_get(r, "roi_display_color");
    const char *t = str_of(r, "rt_roi_interpreted_type");
    *name = str_of(r, "name") ? str_of(r, "name") : "model";
    *type = t ? t : type_by_name(*name);
    for (int i = 0; i < 3; i++) {
        json_int_t v = json_integer_value(json_array_get(c, (size_t)i));
        color[i] = json_array_size(c) == 3 && v >= 0 && v <= 255 ? (int)v : PALETTE[k % 10][i];
    }
}

int model_rtstruct_check(const char *const *ids, const char *const *resources, int n, struct sf_err *err)
{
    if (n < 1 || n > MODEL_RTSTRUCT_MAX_MODELS)
        return sf_fail(err, SF_EINVAL, "?models", "list 1 to %d model ids, comma-separated", MODEL_RTSTRUCT_MAX_MODELS);
    const char *frame = NULL, *study = NULL;
    int frame_of = -1, study_of = -1, rc = 0;
    json_t **r = calloc((size_t)n, sizeof *r);
    if (!r)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (int k = 0; k < n && !rc; k++) {
        for (int j = 0; j < k && !rc; j++)
            if (!strcmp(ids[j], ids[k]))
                rc = sf_fail(err, SF_EINVAL, "?models", "model %s is listed twice: an ROI each", ids[k]);
        if (!rc && !(r[k] = json_loads(resources[k], 0, NULL)))
            rc = sf_fail(err, SF_EINVAL, "?models", "model %s: its resource is not JSON", ids[k]);
        const char *f = rc ? NULL : str_of(r[k], "frame_of_reference_uid"), *s = rc ? NULL : str_of(r[k], "study_instance_uid");
        /* models without a frame (contours in JSON) take the others'; two frames cannot be one set */
        if (f && frame && strcmp(f, frame))
            rc = sf_fail(err, SF_EINVAL, "?models", "models %s and %s are in different frames of reference (%.64s, %.64s): "
                         "one structure set has one", ids[frame_of], ids[k], frame, f);
        else if (s && study && strcmp(s, study))
            rc = sf_fail(err, SF_EINVAL, "?models", "models %s and %s are of different studies: one structure set belongs "
                         "to one", ids[study_of], ids[k]);
        if (f && !frame)
            frame = f, frame_of = k;
        if (s && !study)
            study = s, study_of = k;
    }
    for (int k = 0; k < n; k++)
        json_decref(r[k]);
    free(r);
    return rc;
}

/* The grid the sections' points are put on before their holes are joined, and written exactly
 * (rtstruct_write's 15 digits): the channels and corners keyhole_join tests are the ones a reader
 * gets; at the %.9g of before, a mesh's sub-micron slivers moved and a channel crossed them */
#define SECTION_GRID 1e-6 /* mm */
/* consecutive points closer than this are one: a mesh cut through its vertices leaves slivers
 * whose edges, a micron long, channels would have to pass between */
#define SECTION_MERGE 1e-4 /* mm */

/* Puts every point of l on SECTION_GRID, merging points SECTION_MERGE close; loops left with under
 * three points dropped. In place. */
static void snap(struct trimesh_loops *l)
{
    int out = 0, n_out = 0;
    for (int k = 0; k < l->n; k++) {
        int first = out;
        for (int i = l->start[k]; i < l->start[k + 1]; i++) {
            double x = round(l->p[i][0] / SECTION_GRID) * SECTION_GRID, y = round(l->p[i][1] / SECTION_GRID) * SECTION_GRID;
            if (out > first && fabs(x - l->p[out - 1][0]) < SECTION_MERGE && fabs(y - l->p[out - 1][1]) < SECTION_MERGE)
                continue;
            l->p[out][0] = x, l->p[out][1] = y;
            out++;
        }
        while (out - first > 1 && fabs(l->p[out - 1][0] - l->p[first][0]) < SECTION_MERGE &&
               fabs(l->p[out - 1][1] - l->p[first][1]) < SECTION_MERGE)
            out--; /* the closing point */
        if (out - first < 3) {
            out = first;
            continue;
        }
        l->start[n_out++] = first;
    }
    l->start[n_out] = out;
    l->n = n_out;
}

/* Model m's sections into its ROI: contours (each hole cut into its outer one), the count in *n. */
static int model_sections(const struct model_export *m, double spacing, const struct sf_progress *pr,
                          struct rt_contour **out, int *n_out, struct sf_err *err)
{
    double tol, *z = NULL;
    struct trimesh tm;
    int rc = model_trimesh(m->src, m->len, 0.0, pr, &tm, &tol, err);
    if (rc)
        return rc;
    int n_z = 0, n_c = 0, cap = 0;
    struct rt_contour *c = NULL;
    rc = section_planes(m->src, m->len, m->resource, spacing, &tm, &z, &n_z, err);
    for (int k = 0; !rc && k < n_z; k++) {
        struct trimesh_loops cut, l;
        if ((rc = trimesh_slice(&tm, z[k], &cut, err)))
            break;
        snap(&cut);
        rc = keyhole_join(&cut, KEYHOLE_MAX_TESTS, &l, NULL, err);
        trimesh_loops_free(&cut);
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
    if (!rc && n_c == 0)
        rc = sf_fail(err, SF_EINVAL, "?spacing", "no section of the model: its planes miss it");
    free(z);
    trimesh_free(&tm);
    *out = c;
    *n_out = n_c;
    return rc;
}

/* The referenced series' images of a resource ("referenced_series"), or none (0). */
static int series_images(json_t *r, const char **series, struct rt_image **images, struct sf_err *err)
{
    json_t *rs = json_object_get(r, "referenced_series"), *list = json_object_get(rs, "images");
    *series = json_string_value(json_object_get(rs, "series_instance_uid"));
    *images = NULL;
    size_t n = json_array_size(list);
    if (!*series || !n || n > RTSTRUCT_MAX_IMAGES)
        return 0;
    if (!(*images = calloc(n, sizeof **images)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    int m = 0;
    for (size_t k = 0; k < n; k++) {
        json_t *im = json_array_get(list, k);
        const char *cls = json_string_value(json_array_get(im, 0)), *inst = json_string_value(json_array_get(im, 1));
        json_t *z = json_array_get(im, 2);
        if (!cls || !inst)
            continue;
        snprintf((*images)[m].sop_class, sizeof (*images)[m].sop_class, "%s", cls);
        snprintf((*images)[m].sop_instance, sizeof (*images)[m].sop_instance, "%s", inst);
        (*images)[m++].z = json_is_number(z) ? json_number_value(z) : NAN;
    }
    return m;
}

int model_rtstruct_set(const struct model_export *m, int n, const char *options, const struct sf_progress *pr,
                       unsigned char **out, size_t *out_len, struct sf_err *err)
{
    *out = NULL;
    double spacing;
    int rc = model_rtstruct_options(options, &spacing, err);
    const char **ids = calloc((size_t)n + 1, sizeof *ids), **resources = calloc((size_t)n + 1, sizeof *resources);
    json_t **r = calloc((size_t)n + 1, sizeof *r);
    struct rt_export_roi *roi = calloc((size_t)n + 1, sizeof *roi);
    struct rt_image *images = NULL;
    if (!rc && (!ids || !resources || !r || !roi))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (int k = 0; !rc && k < n; k++)
        ids[k] = m[k].id, resources[k] = m[k].resource;
    if (!rc)
        rc = model_rtstruct_check(ids, resources, n, err);
    struct rt_export e = {"surfd", NULL, NULL, NULL, NULL, 0, roi, n};
    for (int k = 0; !rc && k < n; k++) {
        if (!(r[k] = json_loads(m[k].resource, 0, NULL))) {
            rc = sf_fail(err, SF_EINVAL, "?models", "model %s: its resource is not JSON", m[k].id);
            break;
        }
        if ((rc = model_sections(&m[k], spacing, pr, (struct rt_contour **)&roi[k].c, &roi[k].n, err))) {
            if (n > 1) { /* which model, where several are listed */
                char what[sizeof err->message];
                snprintf(what, sizeof what, "%s", err->message);
                snprintf(err->message, sizeof err->message, "model %s: %.280s", m[k].id, what);
            }
            break;
        }
        roi[k].number = k + 1;
        model_roi_look(r[k], k, &roi[k].name, roi[k].color, &roi[k].type);
        e.study_uid = e.study_uid ? e.study_uid : str_of(r[k], "study_instance_uid");
        e.frame_uid = e.frame_uid ? e.frame_uid : str_of(r[k], "frame_of_reference_uid");
        if (!images) { /* the first model's series: models of one frame were drawn on one series */
            int got = series_images(r[k], &e.series_uid, &images, err);
            if (got < 0) {
                rc = got;
                break;
            }
            e.images = images, e.n_images = got;
        }
    }
    if (!rc)
        rc = rtstruct_write(&e, out, out_len, err);
    for (int k = 0; roi && k < n; k++) {
        for (int i = 0; i < roi[k].n; i++)
            free(roi[k].c[i].p);
        free((void *)roi[k].c);
        if (r)
            json_decref(r[k]);
    }
    free(images);
    free(roi);
    free(r);
    free(ids);
    free(resources);
    return rc;
}

int model_rtstruct(const char *src, size_t len, const char *resource, const char *options,
                   const struct sf_progress *pr, unsigned char **out, size_t *out_len, struct sf_err *err)
{
    struct model_export m = {"", src, len, resource};
    return model_rtstruct_set(&m, 1, options, pr, out, out_len, err);
}
