/* iso_json.c - an isosurface's model resource with jansson (iso_json.h). */
#include "iso_json.h"
#include "model_json.h"

#include <jansson.h>
#include <stdio.h>
#include <string.h>

static const char *type_name(enum iso_type t)
{
    return t == ISO_U8 ? "uint8" : t == ISO_I16 ? "int16" : t == ISO_U16 ? "uint16" : "float32";
}

char *iso_model_json(const struct iso_model *m, struct sf_err *err)
{
    char self[64], mesh[96], render[96];
    snprintf(self, sizeof self, "/models/%s", m->id);
    snprintf(mesh, sizeof mesh, "/models/%s/mesh?format=stl", m->id);
    snprintf(render, sizeof render, "/models/%s/render", m->id);
    const struct trimesh_stats *s = m->st;
    const struct iso_grid *g = &m->vol->g;
    json_t *o = json_pack(
        "{s:s, s:s, s:s, s:f, s:b, s:i, s:I, s:I, s:f, s:f, s:I, s:I, s:I, s:I, s:[[f,f,f],[f,f,f]],"
        " s:{s:[i,i,i], s:s, s:[f,f,f], s:[f,f,f]}, s:{s:f, s:f, s:f, s:f}, s:{s:s, s:s, s:s}}",
        "id", m->id, "name", m->name, "source", m->vol->source, "iso", m->vol->iso, "closed", m->vol->closed, "levels", m->vol->levels,
        "triangles", (json_int_t)m->triangles, "vertices", (json_int_t)m->vertices, "volume_mm3", s->volume, "area_mm2",
        s->area, "boundary_edges", (json_int_t)s->boundary_edges, "nonmanifold_edges", (json_int_t)s->nonmanifold_edges,
        "components", (json_int_t)s->components, "euler_characteristic", (json_int_t)s->euler, "bounds",
        s->bounds[0][0], s->bounds[0][1], s->bounds[0][2], s->bounds[1][0], s->bounds[1][1], s->bounds[1][2], "grid",
        "dims", g->nx, g->ny, g->nz, "type", type_name(m->label ? m->vol->map_type : g->type), "spacing", g->spacing[0], g->spacing[1], g->spacing[2],
        "origin", g->origin[0], g->origin[1], g->origin[2], "timings_ms", "read", m->ms[0], "extract", m->ms[2],
        "measure", m->ms[3], "total", m->ms[4], "links", "self", self, "mesh", mesh, "render", render);
    if (o && m->adapt) {
        json_t *cells = json_array();
        for (int l = 1; l <= m->vol->levels; l++)
            json_array_append_new(cells, json_integer(m->adapt->cells[l]));
        json_object_set_new(o, "max_error", json_real(m->vol->max_error));
        json_object_set_new(o, "cells_by_level", cells);
        json_object_set_new(o, "max_error_estimate", json_real(m->adapt->max_estimate));
        json_object_set_new(o, "merge", json_string(m->vol->pieces && m->vol->levels > 1 ? "pieces" : "cells"));
    }
    if (o)
        json_object_set_new(o, "features", json_string(m->vol->sharp ? "sharp" : "none"));
    if (o && m->vol->oblique) /* the grid's row, column and slice directions: a SEG on its grid needs them */
        json_object_set_new(json_object_get(o, "grid"), "axes",
                            json_pack("[[f,f,f],[f,f,f],[f,f,f]]", m->vol->axes[0][0], m->vol->axes[0][1],
                                      m->vol->axes[0][2], m->vol->axes[1][0], m->vol->axes[1][1], m->vol->axes[1][2],
                                      m->vol->axes[2][0], m->vol->axes[2][1], m->vol->axes[2][2]));
    /* a DICOM series' references, as a structure set's models keep theirs: exports reference the
     * study and frame, and a SEG is made on the series' own grid when it is stored */
    if (o && m->vol->frame_uid[0])
        json_object_set_new(o, "frame_of_reference_uid", json_string(m->vol->frame_uid));
    if (o && m->vol->study_uid[0])
        json_object_set_new(o, "study_instance_uid", json_string(m->vol->study_uid));
    if (o && m->vol->series_uid[0])
        json_object_set_new(o, "referenced_series", json_pack("{s:s}", "series_instance_uid", m->vol->series_uid));
    if (o && m->adapt && m->vol->sharp) {
        json_object_set_new(o, "feature_points", json_integer(m->adapt->feature_points));
        json_object_set_new(o, "face_points", json_integer(m->adapt->face_points));
    }
    if (o)
        json_object_set_new(o, "edits", json_integer(m->edits)),
            json_object_set_new(o, "version", json_integer(m->edits + 1)); /* API.md: 1 when made, +1 an edit */
    if (o && m->label) { /* a label map's label: its value, and for labels=all the labels it touches */
        const struct volume_label *l = &m->vol->label_of[m->label - 1];
        json_object_set_new(o, "label", json_integer(l->value));
        json_object_set_new(o, "label_name", json_string(l->name));
    }
    if (o && m->label && m->touch) {
        json_t *near = json_array();
        for (int k = 0; near && k <= m->vol->n_labels; k++)
            if (m->touch[k])
                json_array_append_new(near, json_pack("{s:I, s:s, s:I}", "label",
                                                      (json_int_t)(k ? m->vol->label_of[k - 1].value : 0), "name",
                                                      k ? m->vol->label_of[k - 1].name : "background", "triangles",
                                                      (json_int_t)m->touch[k]));
        json_object_set_new(o, "method", json_string("multi-label"));
        json_object_set_new(o, "neighbours", near);
    }
    if (o && !m->label && !strcmp(m->vol->source, "isosurface")) {
        char edit[96];
        snprintf(edit, sizeof edit, "/models/%s/edit", m->id);
        json_object_set_new(json_object_get(o, "links"), "edit", json_string(edit));
    }
    if (o && m->edit) /* (an edit stored with its whole mesh, measured: the figures are this version's) */
        json_object_set_new(o, "topology_version", json_integer(m->edits + 1));
    if (o && m->edit)
        json_object_set_new(o, "edit",
                            json_pack("{s:s, s:I, s:I, s:I, s:b, s:f}", "region", m->edit->region, "cells_rebuilt",
                                      (json_int_t)m->edit->e.cells_rebuilt, "triangles_removed",
                                      (json_int_t)m->edit->e.triangles_removed, "triangles_added",
                                      (json_int_t)m->edit->e.triangles_added, "whole", m->edit->e.whole, "ms",
                                      m->edit->ms));
    if (o && !strcmp(m->vol->source, "frep"))
        json_object_set_new(json_object_get(o, "timings_ms"), "sample", json_real(m->ms[1]));
    char *text = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12)) : NULL;
    json_decref(o);
    if (!text)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return text;
}

int iso_model_grid(const char *resource, struct iso_grid *g, bool *frep, struct sf_err *err)
{
    json_error_t je;
    json_t *o = json_loads(resource, 0, &je);
    const char *source = "", *type = "";
    memset(g, 0, sizeof *g);
    int rc = !o || json_unpack(o, "{s:s, s:{s:[i,i,i], s:s}}", "source", &source, "grid", "dims", &g->nx, &g->ny, &g->nz,
                               "type", &type) ? -1 : 0;
    *frep = !rc && !strcmp(source, "frep");
    if (!rc && json_object_get(o, "label"))
        rc = sf_fail(err, SF_ECONFLICT, "", "a label map's models are not edited (the map is not kept): post the "
                     "edited map again");
    else if (!rc && strcmp(source, "isosurface") && !*frep)
        rc = sf_fail(err, SF_ECONFLICT, "", "%s models are not edited (isosurface models are)", source);
    else if (rc)
        rc = sf_fail(err, SF_ECONFLICT, "", "only isosurface models of samples are edited");
    g->type = !strcmp(type, "uint8") ? ISO_U8 : !strcmp(type, "int16") ? ISO_I16 : !strcmp(type, "uint16") ? ISO_U16 : ISO_F32;
    json_decref(o);
    return rc;
}

/* iso_model_json_edited, or (whole) with the triangles, volume and area given as the new mesh's own. */
static char *edited(const char *prev, const struct iso_model_edit *me, long version, double iso, bool whole,
                    long triangles, double volume, double area, const double ms[3], struct sf_err *err)
{
    json_t *o = json_loads(prev, 0, NULL), *t = json_object_get(o, "timings_ms");
    if (!json_is_object(o)) {
        json_decref(o);
        sf_fail(err, SF_EIO, "", "the model's resource is not JSON");
        return NULL;
    }
    long topo = json_is_integer(json_object_get(o, "topology_version")) ? (long)json_integer_value(json_object_get(o, "topology_version"))
                                                                         : model_version(prev);
    json_object_set_new(o, "version", json_integer(version));
    json_object_set_new(o, "iso", json_real(iso));
    json_object_set_new(o, "edits", json_integer(version - 1));
    json_object_set_new(o, "triangles",
                        json_integer((whole ? 0 : json_integer_value(json_object_get(o, "triangles"))) + triangles));
    json_object_set_new(o, "volume_mm3", json_real((whole ? 0 : json_number_value(json_object_get(o, "volume_mm3"))) + volume));
    json_object_set_new(o, "area_mm2", json_real((whole ? 0 : json_number_value(json_object_get(o, "area_mm2"))) + area));
    json_object_set_new(o, "topology_version", json_integer(topo));
    json_object_set_new(o, "edit",
                        json_pack("{s:s, s:I, s:I, s:I, s:b, s:f}", "region", me->region, "cells_rebuilt",
                                  (json_int_t)me->e.cells_rebuilt, "triangles_removed", (json_int_t)me->e.triangles_removed,
                                  "triangles_added", (json_int_t)me->e.triangles_added, "whole", me->e.whole, "ms", me->ms));
    if (json_is_object(t)) {
        json_object_set_new(t, "extract", json_real(ms[0]));
        json_object_set_new(t, "measure", json_real(ms[1]));
        json_object_set_new(t, "total", json_real(ms[2]));
    }
    char *text = json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12));
    json_decref(o);
    if (!text)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return text;
}

char *iso_model_json_edited(const char *prev, const struct iso_model_edit *me, long version, double iso, long d_triangles,
                            double d_volume, double d_area, const double ms[3], struct sf_err *err)
{
    return edited(prev, me, version, iso, false, d_triangles, d_volume, d_area, ms, err);
}

char *iso_model_json_redrawn(const char *prev, const struct iso_model_edit *me, long version, double iso, long triangles,
                             double volume, double area, const double ms[3], struct sf_err *err)
{
    return edited(prev, me, version, iso, true, triangles, volume, area, ms, err);
}

char *iso_model_json_measured(const char *prev, const struct trimesh_stats *st, size_t vertices, long version,
                              struct sf_err *err)
{
    json_t *o = json_loads(prev, 0, NULL);
    if (!json_is_object(o)) {
        json_decref(o);
        sf_fail(err, SF_EIO, "", "the model's resource is not JSON");
        return NULL;
    }
    json_object_set_new(o, "vertices", json_integer((json_int_t)vertices));
    json_object_set_new(o, "volume_mm3", json_real(st->volume));
    json_object_set_new(o, "area_mm2", json_real(st->area));
    json_object_set_new(o, "boundary_edges", json_integer(st->boundary_edges));
    json_object_set_new(o, "nonmanifold_edges", json_integer(st->nonmanifold_edges));
    json_object_set_new(o, "components", json_integer(st->components));
    json_object_set_new(o, "euler_characteristic", json_integer(st->euler));
    json_object_set_new(o, "bounds", json_pack("[[f,f,f],[f,f,f]]", st->bounds[0][0], st->bounds[0][1], st->bounds[0][2],
                                               st->bounds[1][0], st->bounds[1][1], st->bounds[1][2]));
    json_object_set_new(o, "topology_version", json_integer(version));
    char *text = json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12));
    json_decref(o);
    if (!text)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return text;
}

long iso_model_topology(const char *resource)
{
    json_t *o = json_loads(resource, 0, NULL);
    long n = (long)json_integer_value(json_object_get(o, "topology_version"));
    json_decref(o);
    return n;
}

long iso_model_edits(const char *resource)
{
    json_t *o = json_loads(resource, 0, NULL);
    long n = (long)json_integer_value(json_object_get(o, "edits"));
    json_decref(o);
    return n;
}
