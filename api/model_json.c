/* model_json.c - contours in, model figures out: the one path the CLI and the volume job share. */
#include "model_json.h"

#include <jansson.h>
#include <math.h>
#include <string.h>
#include <time.h>

#include "../core/solid.h"
#include "rtstruct.h"

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

/* name=value from an options string ("roi=PTV&caps=slab"); "" when absent. */
static void option(const char *options, const char *name, char *out, size_t cap)
{
    out[0] = 0;
    size_t n = strlen(name);
    for (const char *p = options ? options : ""; *p;) {
        size_t len = strcspn(p, "&");
        if (len > n && !strncmp(p, name, n) && p[n] == '=')
            snprintf(out, cap, "%.*s", (int)(len - n - 1), p + n + 1);
        p += len + (p[len] == '&');
    }
}

static char *dump(json_t *o, struct sf_err *err)
{
    char *s = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12)) : NULL;
    json_decref(o);
    if (!s)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return s;
}

static enum model_caps caps_of(const char *name)
{
    return !strcmp(name, "slab") ? CAPS_SLAB : !strcmp(name, "dome") ? CAPS_DOME : CAPS_FLAT;
}

/* The figures of one cleaned contour set as a JSON object (NULL with err set on failure). */
static json_t *figures(struct contour_set *cs_in, const struct contour_request *req, double t0, struct sf_err *err)
{
    struct contour_set cs = *cs_in;
    struct solid sd;
    double t1 = now_ms();
    if (solid_build(&cs, caps_of(req->caps), &sd, err))
        return NULL;
    /* the exact volume straight from the curves, tube by tube (the closed form), and the ends as built */
    double t2 = now_ms(), closed = 0.0;
    struct contour_slice *storage = malloc(sizeof *storage * (size_t)cs.n_slices);
    int rc = storage ? 0 : sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (int c = 0; c < sd.n_tubes && !rc; c++) {
        struct contour_set v = model_chain_view(&cs, &sd.chains[c], storage);
        double vol = 0.0, ends[2];
        if (v.n_slices >= 2)
            rc = model_volume_closed(&v, &vol, ends, NULL, err);
        closed += (sd.tubes[c].hole ? -vol : vol) + sd.tubes[c].volume_ends;
    }
    free(storage);
    /* the divergence theorem over every patch as a cross-check, the area and the bounds */
    double t3 = now_ms();
    struct solid_measures all;
    solid_measure(&sd, &all);
    double t4 = now_ms();
    size_t n_patches = sd.set.n;
    int n_chains = sd.n_tubes, dome_fallbacks = sd.dome_fallbacks;
    solid_free(&sd);
    if (rc)
        return NULL;
    struct contour_baselines b;
    contour_baselines(&cs, &b);
    int n = 0; /* levels */
    for (int k = 0; k < cs.n_slices; k++)
        n += k == 0 || cs.s[k].z != cs.s[k - 1].z;
    bool uneven = false; /* any spacing between levels unlike the first one */
    double first_gap = 0.0;
    for (int k = 1; k < cs.n_slices; k++) {
        double g = cs.s[k].z - cs.s[k - 1].z;
        if (g == 0.0)
            continue;
        if (first_gap == 0.0)
            first_gap = g;
        uneven |= fabs(g - first_gap) > 1e-6 * first_gap;
    }
    json_t *o = json_pack("{s:s, s:s, s:s, s:i, s:i, s:i, s:i, s:b, s:I, s:f, s:f, s:{s:f, s:f, s:f, s:f, s:f},"
                          " s:[[f,f,f],[f,f,f]], s:{s:f, s:f, s:f, s:f}}",
                          "name", req->name, "method", req->method, "caps", req->caps, "dome_ends_flat",
                          dome_fallbacks, "slices", n, "contours",
                          cs.n_slices, "chains", n_chains, "uneven_spacing", uneven, "patches", (json_int_t)n_patches,
                          "volume_mm3", closed, "area_mm2", all.area, "volume", "exact", closed, "quadrature", all.volume,
                          "trapezoid", b.trapezoid, "cavalieri", b.cavalieri, "frustum", b.frustum, "bounds",
                          all.lo[0], all.lo[1], all.lo[2], all.hi[0], all.hi[1], all.hi[2], "timings_ms", "read",
                          t1 - t0, "fit", t2 - t1, "volume", t3 - t2, "measure", t4 - t3);
    if (!o)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return o;
}

int model_validate(const char *buf, size_t len, const char *format, const char *options, struct sf_err *err)
{
    if (!format || strcmp(format, "dicom")) {
        struct contour_set cs;
        struct contour_request req;
        int rc = contour_parse_json(buf, len, &cs, &req, err);
        if (!rc)
            contour_set_free(&cs);
        return rc;
    }
    char roi[128], caps[16];
    option(options, "roi", roi, sizeof roi);
    option(options, "caps", caps, sizeof caps);
    if (caps[0] && strcmp(caps, "flat") && strcmp(caps, "slab") && strcmp(caps, "dome"))
        return sf_fail(err, SF_EINVAL, "?caps", "caps is flat, slab or dome");
    struct rt_roi *rois = NULL;
    int n = 0, rc = rtstruct_read(buf, len, &rois, &n, err), found = 0;
    for (int k = 0; k < n && !rc; k++)
        if (!roi[0] || !strcmp(roi, rois[k].name)) {
            found++;
            rc = contour_clean(&rois[k].cs, err);
        }
    rtstruct_free(rois, n);
    if (!rc && !found)
        rc = sf_fail(err, SF_EINVAL, roi[0] ? "?roi" : "/ROIContourSequence",
                     roi[0] ? "no ROI with contours has that name" : "no ROI has closed planar contours");
    return rc;
}

int model_figures(const char *buf, size_t len, const char *format, const char *options, char **json, struct sf_err *err)
{
    *json = NULL;
    double t0 = now_ms();
    if (!format || strcmp(format, "dicom")) {
        struct contour_set cs;
        struct contour_request req;
        int rc = contour_parse_json(buf, len, &cs, &req, err);
        if (rc)
            return rc;
        *json = dump(figures(&cs, &req, t0, err), err);
        contour_set_free(&cs);
        return *json ? 0 : err->code;
    }
    /* an RT Structure Set: every ROI with contours, or the one ?roi names */
    struct contour_request req = {"", "parabolic", "flat"};
    char roi[128], caps[16];
    option(options, "roi", roi, sizeof roi);
    option(options, "caps", caps, sizeof caps);
    if (caps[0] && strcmp(caps, "flat") && strcmp(caps, "slab") && strcmp(caps, "dome"))
        return sf_fail(err, SF_EINVAL, "?caps", "caps is flat, slab or dome");
    if (caps[0])
        snprintf(req.caps, sizeof req.caps, "%s", caps);
    struct rt_roi *rois = NULL;
    int n = 0, rc = rtstruct_read(buf, len, &rois, &n, err);
    if (rc)
        return rc;
    json_t *list = json_array(), *one = NULL;
    for (int k = 0; k < n && !rc; k++) {
        if (roi[0] && strcmp(roi, rois[k].name))
            continue;
        snprintf(req.name, sizeof req.name, "%s", rois[k].name);
        if ((rc = contour_clean(&rois[k].cs, err))) {
            char where[96];
            snprintf(where, sizeof where, "%.95s", err->pointer);
            snprintf(err->pointer, sizeof err->pointer, "/ROIContourSequence(%.40s)%s", rois[k].name, where);
            break;
        }
        json_t *o = figures(&rois[k].cs, &req, t0, err);
        if (!o) {
            rc = err->code ? err->code : SF_ENOMEM;
            break;
        }
        json_object_set_new(o, "roi_number", json_integer(rois[k].number));
        json_array_append_new(list, o);
        t0 = now_ms();
    }
    rtstruct_free(rois, n);
    if (!rc && json_array_size(list) == 0)
        rc = sf_fail(err, SF_EINVAL, roi[0] ? "?roi" : "/ROIContourSequence",
                     roi[0] ? "no ROI with contours has that name" : "no ROI has closed planar contours");
    if (!rc && roi[0])
        one = json_incref(json_array_get(list, 0));
    if (!rc)
        *json = dump(one ? one : json_pack("{s:O}", "models", list), err);
    json_decref(list);
    return rc ? rc : (*json ? 0 : err->code);
}
