/* model_rtstruct.c - a stored model as a DICOM RT Structure Set of one ROI: its mesh cut by planes
 * (a contour model's own slices, an isosurface's grid, or ?spacing apart) into closed planar
 * contours. */
#include "model_json_internal.h"

#include <jansson.h>
#include <math.h>
#include <stdlib.h>

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

