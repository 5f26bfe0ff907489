/* model_mesh.c - a stored model as triangles (an isosurface's or matrix model's own mesh, a contour
 * model's solid meshed at a tolerance) and as a mesh file (STL, PLY, OBJ, VTK, DICOM Encapsulated
 * STL); a stored contour model's solid (solid_of) for the other exports. */
#include "model_json_internal.h"

#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "dicom_stl.h"
#include "mesh_io.h"
#include "query.h"

/* ---- what is made from a stored model ---------------------------------------------------------- */

int solid_of(const char *src, size_t len, const struct sf_progress *pr, struct solid *sd, struct sf_err *err)
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
    /* seg: a DICOM Segmentation, made by model_seg_set (the daemon reads the stored series it needs);
     * delta: the whole mesh in API.md's delta layout */
    static const char *const FORMATS[] = {"stl", "ply", "obj", "vtp", "vtk", "dicom-stl", "seg", "delta"};
    char f[16], t[64], *end = NULL;
    query_option(options, "format", f, sizeof f);
    query_option(options, "tolerance", t, sizeof t);
    *format = NULL;
    for (size_t k = 0; k < sizeof FORMATS / sizeof *FORMATS; k++)
        if (!strcmp(f[0] ? f : "stl", FORMATS[k]))
            *format = FORMATS[k];
    if (!*format)
        return sf_fail(err, SF_EINVAL, "?format", "format is stl, ply, obj, vtp, vtk, dicom-stl, seg or delta");
    *tol = t[0] ? strtod(t, &end) : 0.0;
    if ((t[0] && *end) || !(*tol >= 0) || *tol > 1e6)
        return sf_fail(err, SF_EINVAL, "?tolerance", "tolerance is a distance in mm, > 0 (or 0 for the default)");
    return 0;
}

int model_mesh_key(const char *options, long edits, char *key, size_t cap, struct sf_err *err)
{
    const char *format;
    double tol;
    char since[24];
    int rc = model_mesh_options(options, &format, &tol, err);
    query_option(options, "since", since, sizeof since);
    if (!rc && !strcmp(format, "delta") && atol(since) > 0) /* (a delta from a version to the model's) */
        snprintf(key, cap, "delta since %ld e%ld", atol(since), edits);
    else if (!rc)
        tol > 0 ? snprintf(key, cap, "%s %.17g e%ld", format, tol, edits) : snprintf(key, cap, "%s default e%ld", format, edits);
    return rc;
}

/* A stored model as triangles: an isosurface's own mesh, or a contour model's at tol (0: the
 * default tied to it, solid_mesh_default); *tol_used the tolerance (0 for a mesh model). */
int model_trimesh(const char *src, size_t len, double tol, const struct sf_progress *pr, struct trimesh *tm,
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
    struct solid_mesh m;
    rc = tol > 0 ? solid_mesh(&sd, tol, &m) : solid_mesh_default(&sd, &sm, &m, &dflt);
    *tol_used = tol > 0 ? tol : dflt;
    solid_free(&sd);
    if (rc == SF_ECANCEL)
        return sf_fail(err, rc, "", "cancelled");
    if (rc == SF_ELIMIT)
        return sf_fail(err, rc, "?tolerance", "at %g mm the mesh would have over %u triangles; the default is %.3g mm",
                       tol > 0 ? tol : dflt, SOLID_MESH_MAX_TRIANGLES, dflt);
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

long model_version(const char *resource)
{
    json_t *o = resource ? json_loads(resource, 0, NULL) : NULL;
    json_t *v = json_object_get(o, "version");
    long n = json_is_integer(v) ? (long)json_integer_value(v) : 1 + (long)json_integer_value(json_object_get(o, "edits"));
    json_decref(o);
    return n;
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
    if (!strcmp(format, "seg"))
        return sf_fail(err, SF_EINVAL, "?format", "a DICOM SEG is made by the service on an image grid "
                       "(GET /models/{id}/mesh?format=seg), not offline");
    *mime = mesh_mime(format);
    struct trimesh tm;
    bool dicom = !strcmp(format, "dicom-stl"); /* STL in a DICOM Encapsulated STL object */
    uint32_t *ids = NULL; /* a mesh model's triangle ids (stable across its versions), for the delta */
    bool delta = !strcmp(format, "delta");
    rc = delta && mesh_is_packed(src, len) ? mesh_unpack_ids(src, len, &tm, &ids, NULL, err)
                                           : model_trimesh(src, len, tol, pr, &tm, tol_used, err);
    if (!rc)
        rc = !delta ? mesh_encode(&tm, dicom ? "stl" : format, out, out_len, err)
                    : mesh_delta_encode(&tm, 0, (uint32_t)model_version(resource), NULL, 0, ids, tm.n_tri, NULL, out,
                                        out_len, err);
    trimesh_free(&tm);
    free(ids);
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

