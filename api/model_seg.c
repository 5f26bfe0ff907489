/* model_seg.c - stored models as one DICOM Segmentation (seg.h): the grid chosen (a stored CT
 * series', an isosurface's own, or ?spacing over the models' bounds; api/README.md, "DICOM SEG
 * out"), each model's mesh turned into the grid's frame, cut at its slices and the sections
 * rasterised by the even-odd rule (core/geom/raster.h). It reads no store: the daemon hands it the
 * stored series' instances. */
#include "model_json_internal.h"

#include <jansson.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../core/geom/raster.h"
#include "planes.h"
#include "query.h"

/* ?spacing's range (mm): a voxel of a micron or a metre is no structure's */
#define SEG_MIN_SPACING 0.01
#define SEG_MAX_SPACING 100.0

static const char *str_of(json_t *r, const char *key)
{
    const char *v = json_string_value(json_object_get(r, key));
    return v && *v ? v : NULL;
}

static bool doubles_of(json_t *a, double *v, size_t n)
{
    if (json_array_size(a) != n)
        return false;
    for (size_t k = 0; k < n; k++) {
        if (!json_is_number(json_array_get(a, k)))
            return false;
        v[k] = json_number_value(json_array_get(a, k));
    }
    return true;
}

bool model_seg_series(const char *resource, char uid[65])
{
    json_t *r = json_loads(resource, 0, NULL);
    const char *s = json_string_value(json_object_get(json_object_get(r, "referenced_series"), "series_instance_uid"));
    bool found = s && *s && strlen(s) < 65;
    if (found)
        snprintf(uid, 65, "%s", s);
    json_decref(r);
    return found;
}

int model_seg_series_grid(const char *series_uid, const char *study_uid, const char *const *sop_uids,
                          const char *const *metas, int n, struct seg_grid *g, struct sf_err *err)
{
    memset(g, 0, sizeof *g);
    struct plane *pl = calloc((size_t)(n > 0 ? n : 1), sizeof *pl);
    char (*cls)[65] = calloc((size_t)(n > 0 ? n : 1), sizeof *cls), frame[65] = "";
    int rc = !pl || !cls ? sf_fail(err, SF_ENOMEM, "", "out of memory") : 0;
    if (!rc && n < 2)
        rc = sf_fail(err, SF_EINVAL, "?format", "the stored series %.64s has %d instance%s: a CT grid is 2 slices or "
                     "more", series_uid, n, n == 1 ? "" : "s");
    for (int k = 0; !rc && k < n; k++) {
        json_t *m = json_loads(metas[k], 0, NULL);
        const char *c = str_of(m, "sop_class"), *f = str_of(m, "frame_of_reference_uid");
        json_int_t rows = json_integer_value(json_object_get(m, "rows")),
                   cols = json_integer_value(json_object_get(m, "columns")),
                   frames = json_integer_value(json_object_get(m, "frames"));
        struct plane *p = &pl[k];
        if (!c || frames != 1 || rows < 1 || cols < 1 || rows > 65535 || cols > 65535 ||
            !doubles_of(json_object_get(m, "position"), p->pos, 3) ||
            !doubles_of(json_object_get(m, "orientation"), p->orient, 6) ||
            !doubles_of(json_object_get(m, "pixel_spacing"), p->spacing, 2))
            rc = sf_fail(err, SF_EINVAL, "?format", "the stored series %.64s is not a stack of single-frame images "
                         "(its instance %.64s has no plane, or several frames): a SEG's grid is a CT's", series_uid,
                         sop_uids[k]);
        else if (f && frame[0] && strcmp(f, frame))
            rc = sf_fail(err, SF_EINVAL, "?format", "the stored series %.64s has two frames of reference", series_uid);
        if (!rc) {
            p->part = k, p->frame = -1, p->rows = (unsigned)rows, p->cols = (unsigned)cols, p->tag = k;
            snprintf(cls[k], sizeof cls[k], "%s", c);
            if (f && !frame[0])
                snprintf(frame, sizeof frame, "%s", f);
        }
        json_decref(m);
    }
    struct planes_grid pg;
    if (!rc && planes_layout(pl, n, false, SIZE_MAX, &pg, err)) { /* a posted series' rules, said of the stored one */
        char why[sizeof err->message];
        snprintf(why, sizeof why, "%s", err->message);
        int part = 0;
        sscanf(err->pointer, "/parts/%d", &part);
        err->code = 0;
        rc = sf_fail(err, SF_EINVAL, "?format", "the stored series %.64s is not one grid (instance %.64s: %.200s)",
                     series_uid, part >= 0 && part < n ? sop_uids[part] : "?", why);
    }
    if (!rc) {
        g->cols = pg.nx, g->rows = pg.ny, g->n_slices = pg.nz;
        memcpy(g->spacing, pl[0].spacing, sizeof g->spacing);
        memcpy(g->orient, pl[0].orient, sizeof g->orient);
        g->thickness = pg.spacing[2];
        g->pos = malloc(sizeof *g->pos * (size_t)n);
        g->images = calloc((size_t)n, sizeof *g->images);
        if (!g->pos || !g->images)
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        for (int k = 0; !rc && k < n; k++) { /* the k-th along the normal */
            memcpy(g->pos[k], pl[k].pos, sizeof g->pos[k]);
            snprintf(g->images[k].sop_class, sizeof g->images[k].sop_class, "%s", cls[pl[k].tag]);
            snprintf(g->images[k].sop_instance, sizeof g->images[k].sop_instance, "%.64s", sop_uids[pl[k].tag]);
        }
        snprintf(g->series_uid, sizeof g->series_uid, "%.64s", series_uid);
        snprintf(g->study_uid, sizeof g->study_uid, "%.64s", study_uid ? study_uid : "");
        snprintf(g->frame_uid, sizeof g->frame_uid, "%s", frame);
        g->source = "series";
    }
    if (rc)
        seg_grid_free(g);
    free(pl);
    free(cls);
    return rc;
}

/* An axial grid of spacing mm voxels over bounds lo..hi, centred on them (a voxel's centre within
 * half a voxel of each end) */
static int spacing_grid(const double lo[3], const double hi[3], double spacing, int n_seg, struct seg_grid *g,
                        struct sf_err *err)
{
    double count[3];
    for (int a = 0; a < 3; a++)
        count[a] = ceil((hi[a] - lo[a]) / spacing) + 1;
    if (!(count[0] * count[1] * count[2] * n_seg <= (double)SEG_MAX_BITS) || !(count[0] <= 65535 && count[1] <= 65535))
        return sf_fail(err, SF_ELIMIT, "?spacing", "%g mm voxels over the models' bounds (%.0f x %.0f x %.0f mm) make %.0f "
                       "x %.0f x %.0f voxels x %d segments, over the %llu bits of one export", spacing, hi[0] - lo[0],
                       hi[1] - lo[1], hi[2] - lo[2], count[0], count[1], count[2], n_seg,
                       (unsigned long long)SEG_MAX_BITS);
    g->cols = (int)count[0], g->rows = (int)count[1], g->n_slices = (int)count[2];
    g->spacing[0] = g->spacing[1] = g->thickness = spacing;
    const double axial[6] = {1, 0, 0, 0, 1, 0};
    memcpy(g->orient, axial, sizeof axial);
    if (!(g->pos = malloc(sizeof *g->pos * (size_t)g->n_slices)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    double o[3];
    for (int a = 0; a < 3; a++)
        o[a] = (lo[a] + hi[a]) / 2 - (count[a] - 1) * spacing / 2;
    for (int k = 0; k < g->n_slices; k++)
        g->pos[k][0] = o[0], g->pos[k][1] = o[1], g->pos[k][2] = o[2] + k * spacing;
    g->source = "spacing";
    return 0;
}

/* An isosurface model's own grid (its resource's: dims, spacing, origin and, for an oblique
 * series, axes): 1 made, 0 the model has none */
static int own_grid(json_t *r, struct seg_grid *g, struct sf_err *err)
{
    json_t *grid = json_object_get(r, "grid");
    double dims[3], sp[3], o[3], ax[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    if (!doubles_of(json_object_get(grid, "dims"), dims, 3) || !doubles_of(json_object_get(grid, "spacing"), sp, 3) ||
        !doubles_of(json_object_get(grid, "origin"), o, 3) || !(sp[0] > 0 && sp[1] > 0 && sp[2] > 0) ||
        !(dims[0] >= 1 && dims[1] >= 1 && dims[2] >= 1 && dims[0] <= 65535 && dims[1] <= 65535 && dims[2] <= 1e7))
        return 0;
    json_t *axes = json_object_get(grid, "axes");
    if (axes && json_array_size(axes) == 3)
        for (size_t a = 0; a < 3; a++)
            if (!doubles_of(json_array_get(axes, a), ax + 3 * a, 3))
                memcpy(ax + 3 * a, (const double[3]){a == 0, a == 1, a == 2}, sizeof(double[3]));
    g->cols = (int)dims[0], g->rows = (int)dims[1], g->n_slices = (int)dims[2];
    g->spacing[0] = sp[1], g->spacing[1] = sp[0], g->thickness = sp[2]; /* PixelSpacing: rows' first */
    memcpy(g->orient, ax, sizeof g->orient);
    if (!(g->pos = malloc(sizeof *g->pos * (size_t)g->n_slices)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (int k = 0; k < g->n_slices; k++)
        for (int b = 0; b < 3; b++)
            g->pos[k][b] = o[b] + k * sp[2] * ax[6 + b];
    g->source = "model";
    return 1;
}

int model_seg_grid(const char *const *ids, const char *const *resources, int n, const struct seg_grid *series,
                   const char *options, struct seg_grid *g, struct sf_err *err)
{
    memset(g, 0, sizeof *g);
    char v[64], *end = NULL;
    query_option(options, "spacing", v, sizeof v);
    double spacing = v[0] ? strtod(v, &end) : 0.0;
    if (v[0] && (*end || !(spacing >= SEG_MIN_SPACING && spacing <= SEG_MAX_SPACING)))
        return sf_fail(err, SF_EINVAL, "?spacing", "spacing is a SEG's voxel size in mm, %g to %g", SEG_MIN_SPACING,
                       SEG_MAX_SPACING);
    if (n < 1 || n > MODEL_RTSTRUCT_MAX_MODELS)
        return sf_fail(err, SF_EINVAL, "?models", "list 1 to %d model ids, comma-separated", MODEL_RTSTRUCT_MAX_MODELS);
    const char *where = n > 1 ? "?models" : "?format";
    json_t **r = calloc((size_t)n, sizeof *r);
    int rc = r ? 0 : sf_fail(err, SF_ENOMEM, "", "out of memory");
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int k = 0; !rc && k < n; k++) {
        double b[6];
        json_t *bounds = json_object_get(r[k] = json_loads(resources[k], 0, NULL), "bounds");
        if (!r[k])
            rc = sf_fail(err, SF_EINVAL, where, "model %s: its resource is not JSON", ids[k]);
        else if (spacing > 0 && (!doubles_of(json_array_get(bounds, 0), b, 3) || !doubles_of(json_array_get(bounds, 1), b + 3, 3)))
            rc = sf_fail(err, SF_EINVAL, "?spacing", "model %s has no bounds to lay a grid over", ids[k]);
        for (int a = 0; !rc && spacing > 0 && a < 3; a++)
            lo[a] = fmin(lo[a], b[a]), hi[a] = fmax(hi[a], b[3 + a]);
        /* the series' voxels are the models' only when both lie in one frame of reference */
        const char *f = rc || spacing > 0 || !series ? NULL : str_of(r[k], "frame_of_reference_uid");
        if (f && series->frame_uid[0] && strcmp(f, series->frame_uid))
            rc = sf_fail(err, SF_EINVAL, where, "model %s is in frame of reference %.64s, its stored series %.64s in "
                         "%.64s: its voxels would not be the model's", ids[k], f, series->series_uid, series->frame_uid);
    }
    if (!rc && spacing > 0) {
        rc = spacing_grid(lo, hi, spacing, n, g, err);
    } else if (!rc && series) {
        *g = *series;
        g->pos = malloc(sizeof *g->pos * (size_t)g->n_slices);
        g->images = series->images ? malloc(sizeof *g->images * (size_t)g->n_slices) : NULL;
        if (!g->pos || (series->images && !g->images))
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        else
            memcpy(g->pos, series->pos, sizeof *g->pos * (size_t)g->n_slices);
        if (!rc && g->images)
            memcpy(g->images, series->images, sizeof *g->images * (size_t)g->n_slices);
    } else if (!rc) {
        int made = 0;
        for (int k = 0; !made && k < n; k++)
            made = own_grid(r[k], g, err);
        rc = made < 0 ? made : 0;
        char uid[65];
        if (!rc && !made) {
            int k = 0;
            while (k < n - 1 && !model_seg_series(resources[k], uid))
                k++;
            if (model_seg_series(resources[k], uid))
                rc = sf_fail(err, SF_EINVAL, where, "model %s was drawn on series %.64s, which this node has not stored: "
                             "send it to the node (C-STORE) or pull it (POST /series/pull), or give ?spacing=MM for a "
                             "grid of its own", ids[k], uid);
            else
                rc = sf_fail(err, SF_EINVAL, where, "no image grid: the model%s came from no stored series and %s no "
                             "grid of %s own; give ?spacing=MM", n > 1 ? "s" : "", n > 1 ? "have" : "has",
                             n > 1 ? "their" : "its");
        }
    }
    double bits = rc ? 0 : (double)g->cols * g->rows * g->n_slices * n;
    if (!rc && bits > (double)SEG_MAX_BITS)
        rc = sf_fail(err, SF_ELIMIT, where, "%d x %d x %d voxels x %d segments is over the %llu bits of one export",
                     g->cols, g->rows, g->n_slices, n, (unsigned long long)SEG_MAX_BITS);
    else if (!rc && (long)g->n_slices * n > SEG_MAX_FRAMES)
        rc = sf_fail(err, SF_ELIMIT, spacing > 0 ? "?spacing" : where, "%d slices x %d segments could be over the %ld "
                     "frames of one export", g->n_slices, n, SEG_MAX_FRAMES);
    for (int k = 0; r && k < n; k++)
        json_decref(r[k]);
    free(r);
    if (rc)
        seg_grid_free(g);
    return rc;
}

/* Model m as segment `segment`: its mesh in the grid's frame (columns and rows in pixels, the
 * normal in mm from the first slice), cut at each slice its extent reaches, each section's pixels
 * added as a frame where it holds any. */
static int voxelise(const struct model_export *m, int segment, const struct seg_grid *g, struct seg_writer *w,
                    unsigned char *mask, const struct sf_progress *pr, struct sf_err *err)
{
    double tol;
    struct trimesh tm;
    int rc = model_trimesh(m->src, m->len, 0.0, NULL, &tm, &tol, err);
    if (rc)
        return rc;
    const double *r = g->orient, *c = g->orient + 3, *o = g->pos[0];
    const double nrm[3] = {r[1] * c[2] - r[2] * c[1], r[2] * c[0] - r[0] * c[2], r[0] * c[1] - r[1] * c[0]};
    double lo = INFINITY, hi = -INFINITY;
    for (size_t k = 0; k < tm.n_vert; k++) { /* (r/dx, c/dy, n) is right-handed: the mesh still faces out */
        float *p = tm.pos + 3 * k;
        double d[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
        p[0] = (float)((d[0] * r[0] + d[1] * r[1] + d[2] * r[2]) / g->spacing[1]);
        p[1] = (float)((d[0] * c[0] + d[1] * c[1] + d[2] * c[2]) / g->spacing[0]);
        p[2] = (float)(d[0] * nrm[0] + d[1] * nrm[1] + d[2] * nrm[2]);
        lo = fmin(lo, p[2]), hi = fmax(hi, p[2]);
    }
    for (int k = 0; !rc && k < g->n_slices; k++) {
        const double *q = g->pos[k];
        double s = (q[0] - o[0]) * nrm[0] + (q[1] - o[1]) * nrm[1] + (q[2] - o[2]) * nrm[2];
        if (s < lo || s > hi)
            continue;
        struct trimesh_loops l;
        size_t set = 0;
        if ((rc = trimesh_slice(&tm, s, &l, err)))
            break;
        rc = raster_loops(&l, g->cols, g->rows, mask, &set, err);
        trimesh_loops_free(&l);
        if (!rc && set)
            rc = seg_frame(w, segment, k, mask, err);
        if (!rc)
            rc = sf_poll(pr, (double)(k + 1) / g->n_slices, err);
    }
    trimesh_free(&tm);
    return rc;
}

int model_seg_set(const struct model_export *m, int n, const struct seg_grid *g, const struct sf_progress *pr,
                  unsigned char **out, size_t *out_len, struct sf_err *err)
{
    *out = NULL;
    *out_len = 0;
    struct seg_segment *s = calloc((size_t)n, sizeof *s);
    json_t **r = calloc((size_t)n, sizeof *r);
    unsigned char *mask = malloc((size_t)g->cols * (size_t)g->rows);
    int rc = s && r && mask ? 0 : sf_fail(err, SF_ENOMEM, "", "out of memory");
    const char *study = g->study_uid[0] ? g->study_uid : NULL, *frame = g->frame_uid[0] ? g->frame_uid : NULL;
    for (int k = 0; !rc && k < n; k++) {
        if (!(r[k] = json_loads(m[k].resource, 0, NULL)))
            rc = sf_fail(err, SF_EINVAL, "?models", "model %s: its resource is not JSON", m[k].id);
        else
            model_roi_look(r[k], k, &s[k].label, s[k].color, &s[k].type);
        study = study ? study : str_of(r[k], "study_instance_uid");
        frame = frame ? frame : str_of(r[k], "frame_of_reference_uid");
    }
    struct seg_writer *w = NULL;
    if (!rc)
        rc = seg_begin(g, s, n, study, frame, &w, err);
    for (int k = 0; !rc && k < n; k++) {
        struct sf_span span = {pr, (double)k / n, (double)(k + 1) / n};
        const struct sf_progress part = {sf_span_poll, &span};
        if ((rc = voxelise(&m[k], k + 1, g, w, mask, &part, err)) && n > 1 && rc != SF_ECANCEL) {
            char what[sizeof err->message];
            snprintf(what, sizeof what, "%s", err->message);
            snprintf(err->message, sizeof err->message, "model %s: %.280s", m[k].id, what);
        }
    }
    if (!rc) {
        rc = seg_end(w, out, out_len, err);
        w = NULL;
        if (rc == SF_EINVAL) /* every segment empty: the grid is what to change */
            snprintf(err->pointer, sizeof err->pointer, "%s", !strcmp(g->source, "spacing") ? "?spacing" : "?format");
    }
    seg_free(w);
    for (int k = 0; r && k < n; k++)
        json_decref(r[k]);
    free(r);
    free(s);
    free(mask);
    return rc;
}
