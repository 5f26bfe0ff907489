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
    enum model_caps caps = strcmp(req.caps, "slab") ? CAPS_FLAT : CAPS_SLAB;
    struct model_chain *chains = NULL;
    int n_chains = 0;
    struct contour_slice *view_storage = malloc(sizeof *view_storage * (size_t)cs.n_slices);
    if (!view_storage || (rc = model_chains(&cs, caps, &chains, &n_chains, err))) {
        free(view_storage);
        contour_set_free(&cs);
        return rc ? rc : sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    /* the exact volume straight from the curves, chain by chain: the fast path */
    double t1 = now_ms(), closed = 0.0;
    for (int c = 0; c < n_chains && !rc; c++) {
        struct contour_set v = model_chain_view(&cs, &chains[c], view_storage);
        double vol, ends[2];
        if (v.n_slices >= 2) {
            rc = model_volume_closed(&v, &vol, ends, err);
        } else { /* an island on one slice: its extensions only */
            ends[0] = ends[1] = model_curve_area(&v.s[0]);
            vol = 0.0;
        }
        vol += ends[0] * chains[c].ext[0] + ends[1] * chains[c].ext[1];
        closed += chains[c].hole ? -vol : vol;
    }
    /* the patches: area, bounds, and the divergence theorem over them as a cross-check */
    double t2 = now_ms(), fit_ms = 0.0, quad = 0.0, area = 0.0;
    struct model_measures all = {.lo = {INFINITY, INFINITY, INFINITY}, .hi = {-INFINITY, -INFINITY, -INFINITY}};
    size_t n_patches = 0;
    for (int c = 0; c < n_chains && !rc; c++) {
        struct contour_set v = model_chain_view(&cs, &chains[c], view_storage);
        if (v.n_slices < 2) {
            double a = model_curve_area(&v.s[0]);
            quad += (chains[c].hole ? -a : a) * (chains[c].ext[0] + chains[c].ext[1]);
            area += 2 * a; /* the island's two faces; its rim is left out */
            continue;
        }
        struct patch_set ps = {0};
        double tp = now_ms();
        if ((rc = model_parabolic(&v, &ps, err)))
            break;
        nurbs_patches_fix(&ps);
        fit_ms += now_ms() - tp;
        struct model_measures m;
        model_measure(&ps, CAPS_SLAB, (const double[2]){2 * chains[c].ext[0], 2 * chains[c].ext[1]}, &m);
        quad += chains[c].hole ? -m.volume : m.volume;
        area += m.area;
        n_patches += ps.n;
        for (int d = 0; d < 3; d++)
            all.lo[d] = fmin(all.lo[d], m.lo[d]), all.hi[d] = fmax(all.hi[d], m.hi[d]);
        nurbs_patch_set_free(&ps);
    }
    free(view_storage);
    model_chains_free(chains, n_chains);
    if (rc) {
        contour_set_free(&cs);
        return rc;
    }
    struct contour_baselines b;
    contour_baselines(&cs, &b);
    double t4 = now_ms();
    int n = 0; /* levels */
    for (int k = 0; k < cs.n_slices; k++)
        n += k == 0 || cs.s[k].z != cs.s[k - 1].z;
    const double gap0 = cs.s[cs.n_slices - 1].z > cs.s[0].z ? cs.s[1].z - cs.s[0].z : 0;
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
    (void)gap0;
    json_t *o = json_pack("{s:s, s:s, s:s, s:i, s:i, s:i, s:b, s:I, s:f, s:f, s:{s:f, s:f, s:f, s:f, s:f},"
                          " s:[[f,f,f],[f,f,f]], s:{s:f, s:f, s:f, s:f}}",
                          "name", req.name, "method", req.method, "caps", req.caps, "slices", n, "contours",
                          cs.n_slices, "chains", n_chains, "uneven_spacing", uneven, "patches", (json_int_t)n_patches,
                          "volume_mm3", closed, "area_mm2", area, "volume", "exact", closed, "quadrature", quad,
                          "trapezoid", b.trapezoid, "cavalieri", b.cavalieri, "frustum", b.frustum, "bounds",
                          all.lo[0], all.lo[1], all.lo[2], all.hi[0], all.hi[1], all.hi[2], "timings_ms", "read",
                          t1 - t0, "volume", t2 - t1, "fit", fit_ms, "measure", t4 - t2 - fit_ms);
    *json = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12)) : NULL;
    json_decref(o);
    contour_set_free(&cs);
    return *json ? 0 : sf_fail(err, SF_ENOMEM, "", "out of memory");
}
