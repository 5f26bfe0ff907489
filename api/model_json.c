/* model_json.c - contours in, model figures out: the one path the CLI and the volume job share. */
#include "model_json.h"

#include <jansson.h>
#include <math.h>
#include <string.h>
#include <time.h>

#include "../core/model.h"

static double now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

int model_figures(const char *buf, size_t len, char **json, struct sf_err *err)
{
    *json = NULL;
    struct contour_set cs;
    struct contour_request req;
    double t0 = now_ms();
    int rc = contour_parse_json(buf, len, &cs, &req, err);
    if (rc)
        return rc;
    int n = cs.n_slices;
    const double gaps[2] = {cs.s[1].z - cs.s[0].z, cs.s[n - 1].z - cs.s[n - 2].z};
    bool slab = !strcmp(req.caps, "slab");
    /* the exact volume straight from the curves: the fast path */
    double t1 = now_ms(), closed, ends[2];
    if ((rc = model_volume_closed(&cs, &closed, ends, err))) {
        contour_set_free(&cs);
        return rc;
    }
    if (slab)
        closed += 0.5 * (ends[0] * gaps[0] + ends[1] * gaps[1]);
    /* the patches: area, bounds, and the divergence theorem over them as a cross-check */
    double t2 = now_ms();
    struct patch_set ps = {0};
    if ((rc = model_parabolic(&cs, &ps, err))) {
        contour_set_free(&cs);
        return rc;
    }
    nurbs_patches_fix(&ps);
    double t3 = now_ms();
    struct model_measures m;
    model_measure(&ps, slab ? CAPS_SLAB : CAPS_FLAT, gaps, &m);
    struct contour_baselines b;
    contour_baselines(&cs, &b);
    double t4 = now_ms();
    bool uneven = false;
    for (int k = 1; k + 1 < n; k++)
        uneven |= fabs((cs.s[k + 1].z - cs.s[k].z) - gaps[0]) > 1e-6 * fabs(gaps[0]);
    json_t *o = json_pack("{s:s, s:s, s:s, s:i, s:b, s:I, s:f, s:f, s:{s:f, s:f, s:f, s:f, s:f},"
                          " s:[[f,f,f],[f,f,f]], s:{s:f, s:f, s:f, s:f}}",
                          "name", req.name, "method", req.method, "caps", req.caps, "slices", n, "uneven_spacing",
                          uneven, "patches", (json_int_t)ps.n, "volume_mm3", closed, "area_mm2", m.area, "volume",
                          "exact", closed, "quadrature", m.volume, "trapezoid", b.trapezoid, "cavalieri", b.cavalieri,
                          "frustum", b.frustum, "bounds", m.lo[0], m.lo[1], m.lo[2], m.hi[0], m.hi[1], m.hi[2],
                          "timings_ms", "read", t1 - t0, "volume", t2 - t1, "fit", t3 - t2, "measure", t4 - t3);
    *json = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12)) : NULL;
    json_decref(o);
    nurbs_patch_set_free(&ps);
    contour_set_free(&cs);
    return *json ? 0 : sf_fail(err, SF_ENOMEM, "", "out of memory");
}
