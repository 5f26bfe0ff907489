/* model_patches.c - a stored model's patches: as a scene's JSON (GET /models/{id}/patches, with the
 * plane regions of caps that overlap), and as objects appended to a scene being parsed (a scene's
 * {"type": "model"} objects, through the service's model_resolver). */
#include "model_json_internal.h"

#include <jansson.h>
#include <math.h>
#include <stdlib.h>

#include "mesh_io.h"

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
