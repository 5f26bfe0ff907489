/* series_json.c - series resources with jansson (series_json.h). */
#include "series_json.h"

#include "job_json.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static json_t *doubles(const double *v, int n)
{
    json_t *a = json_array();
    for (int k = 0; a && k < n; k++)
        json_array_append_new(a, json_real(v[k]));
    return a;
}

char *instance_meta(const struct dicom_instance *in)
{
    json_t *o = json_pack("{s:s, s:I, s:I, s:I}", "sop_class", in->sop_class, "rows", (json_int_t)in->rows, "columns",
                          (json_int_t)in->columns, "frames", (json_int_t)in->frames);
    if (o && in->frame_uid[0])
        json_object_set_new(o, "frame_of_reference_uid", json_string(in->frame_uid));
    if (o && in->has_plane) {
        json_object_set_new(o, "pixel_spacing", doubles(in->spacing, 2));
        json_object_set_new(o, "position", doubles(in->position, 3));
        json_object_set_new(o, "orientation", doubles(in->orientation, 6));
    }
    char *s = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    return s;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static bool read_doubles(json_t *o, const char *key, double *v, size_t n)
{
    json_t *a = json_object_get(o, key);
    if (!json_is_array(a) || json_array_size(a) != n)
        return false;
    for (size_t k = 0; k < n; k++)
        v[k] = json_number_value(json_array_get(a, k));
    return true;
}

/* The series' geometry from its instances': an image series (slices of one size and orientation)
 * its dims (columns, rows, slices: frames summed) and spacing (PixelSpacing's, and the median
 * distance between slice positions along the normal); what is not common to every instance is
 * left out. */
static void geometry(json_t *o, const struct series_view *v)
{
    long rows = -1, cols = -1, slices = 0;
    double orient[6] = {0}, ps[2] = {0};
    bool same = true, planes = v->n_metas > 0;
    const char *frame = NULL;
    double *along = malloc(sizeof *along * (size_t)(v->n_metas ? v->n_metas : 1));
    json_t *classes = json_array();
    for (int k = 0; k < v->n_metas && along; k++) {
        json_t *m = json_loads(v->metas[k], 0, NULL);
        if (!m)
            continue;
        long r = (long)json_integer_value(json_object_get(m, "rows")),
             c = (long)json_integer_value(json_object_get(m, "columns"));
        slices += (long)json_integer_value(json_object_get(m, "frames"));
        same = same && (rows < 0 || (r == rows && c == cols));
        rows = r, cols = c;
        const char *cls = json_string_value(json_object_get(m, "sop_class"));
        bool listed = false;
        for (size_t i = 0; cls && i < json_array_size(classes); i++)
            listed = listed || !strcmp(json_string_value(json_array_get(classes, i)), cls);
        if (cls && !listed)
            json_array_append_new(classes, json_string(cls));
        const char *f = json_string_value(json_object_get(m, "frame_of_reference_uid"));
        if (f && !frame)
            frame = strdup(f);
        double o6[6], pos[3], sp[2];
        if (read_doubles(m, "orientation", o6, 6) && read_doubles(m, "position", pos, 3) &&
            read_doubles(m, "pixel_spacing", sp, 2)) {
            if (k == 0)
                memcpy(orient, o6, sizeof o6), memcpy(ps, sp, sizeof sp);
            for (int i = 0; i < 6; i++)
                planes = planes && fabs(o6[i] - orient[i]) < 1e-4;
            double n[3] = {o6[1] * o6[5] - o6[2] * o6[4], o6[2] * o6[3] - o6[0] * o6[5], o6[0] * o6[4] - o6[1] * o6[3]};
            along[k] = n[0] * pos[0] + n[1] * pos[1] + n[2] * pos[2];
        } else {
            planes = false;
        }
        json_decref(m);
    }
    json_object_set_new(o, "sop_classes", classes);
    if (frame)
        json_object_set_new(o, "frame_of_reference_uid", json_string(frame));
    free((void *)frame);
    if (same && rows > 0 && cols > 0) {
        json_t *dims = json_array();
        json_array_append_new(dims, json_integer(cols));
        json_array_append_new(dims, json_integer(rows));
        json_array_append_new(dims, json_integer(slices));
        json_object_set_new(o, "dims", dims);
    }
    if (same && planes && along && v->n_metas >= 2 && slices == v->n_metas) { /* single-frame slices */
        qsort(along, (size_t)v->n_metas, sizeof *along, cmp_double);
        for (int k = 0; k + 1 < v->n_metas; k++)
            along[k] = along[k + 1] - along[k];
        qsort(along, (size_t)(v->n_metas - 1), sizeof *along, cmp_double);
        double sp[3] = {ps[1], ps[0], along[(v->n_metas - 1) / 2]}; /* PixelSpacing is rows' then columns' */
        json_object_set_new(o, "spacing", doubles(sp, 3));
        json_object_set_new(o, "orientation", doubles(orient, 6));
    }
    free(along);
}

char *series_json(const struct series_view *v)
{
    char self[96];
    snprintf(self, sizeof self, "/series/%s", v->uid);
    json_t *o = json_pack("{s:s, s:s, s:s, s:I, s:I, s:s, s:o, s:o, s:b, s:{s:s}}", "uid", v->uid, "study_uid",
                          v->study_uid, "modality", v->modality, "instances", (json_int_t)v->instances, "bytes",
                          (json_int_t)v->bytes, "source", v->source, "first_received", job_stamp(v->first),
                          "last_received", job_stamp(v->last), "complete", v->complete, "links", "self", self);
    if (o && v->metas)
        geometry(o, v);
    if (o && v->job && v->job[0]) {
        char job[64];
        snprintf(job, sizeof job, "/jobs/%s", v->job);
        json_object_set_new(json_object_get(o, "links"), "job", json_string(job));
    }
    char *s = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    return s;
}
