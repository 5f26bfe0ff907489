/* test_contour_model.c - contours to parabolic surface to volume: the synthetic shapes' exact volumes
 * between their end slices (caps flat), exactness of the quadrature, outward orientation,
 * interpolation of every contour point, baselines, and every rejection with its pointer. */
#include "../../api/contour_json.h"
#include "../../api/model_json.h"
#include "../../api/rtstruct.h"
#include "../../core/base/gauss.h"
#include "../../core/contour/solid.h"
#include "../../core/geom/enclosed.h"
#include "../unit.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* folds undone, as a model's surface */
static const struct model_opts PARABOLIC = {.method = MODEL_PARABOLIC, .unfold = true};

/* The synthetic shapes and their exact volumes between the end slices (from the files). */
static const struct synthetic {
    const char *file;
    double exact;
} SYNTHETIC[] = {{"synthetic_ellipsoid.json", 123841.58240450964}, {"synthetic_bean.json", 66556.32338083329},
                 {"synthetic_torus_branching.json", 84963.33313378324}};

static int model_of(const char *text, size_t len, struct contour_set *cs, struct patch_set *ps, struct sf_err *err)
{
    struct contour_request req;
    memset(ps, 0, sizeof *ps);
    int rc = contour_parse_json(text, len, cs, &req, err);
    if (!rc && !(rc = model_side(cs, PARABOLIC, ps, err)))
        nurbs_patches_fix(ps);
    return rc;
}

static void measure(const struct contour_set *cs, enum model_caps caps, struct solid_measures *m)
{
    struct solid sd;
    memset(m, 0, sizeof *m);
    CHECK(solid_build(cs, PARABOLIC, caps, &sd, NULL) == 0);
    solid_measure(&sd, m);
    solid_free(&sd);
}

/* caps flat: within 0.2 % of the exact solid between the end slices (issue 5's target) */
TEST(synthetic_volumes_within_0_2_percent)
{
    const struct synthetic *cases = SYNTHETIC;
    for (size_t k = 0; k < 2; k++) { /* one contour per slice: the patches' own volume */
        size_t len;
        char *buf = unit_data("contours", cases[k].file, &len);
        CHECK(buf != NULL);
        if (!buf)
            continue;
        struct contour_set cs;
        struct patch_set ps;
        struct sf_err err = {0};
        CHECK(model_of(buf, len, &cs, &ps, &err) == 0);
        struct solid_measures m;
        measure(&cs, CAPS_FLAT, &m);
        double rel = (m.volume - cases[k].exact) / cases[k].exact;
        fprintf(stderr, "  %s: %.3f mm3, %+.4f %% (%zu patches)\n", cases[k].file, m.volume, 100 * rel, ps.n);
        CHECK(fabs(rel) < 0.002);
        struct contour_baselines b;
        contour_baselines(&cs, &b);
        CHECK(fabs(m.volume - cases[k].exact) < fabs(b.trapezoid - cases[k].exact)); /* better than the baseline */
        nurbs_patch_set_free(&ps);
        contour_set_free(&cs);
        free(buf);
    }
}

/* Several contours per slice: the branching torus (1 -> 2 -> 1) within 0.2 % of its exact volume
 * between the end slices, the lung with 77 holes and islands modelled, both through the figures
 * path the CLI and the service use. */
TEST(several_contours_per_slice)
{
    const struct {
        const char *file;
        double exact;
    } cases[] = {{"synthetic_torus_branching.json", 84963.33313378324}, {"dicompyler_lt_lung_multicontour.json", 0}};
    for (int k = 0; k < 2; k++) {
        size_t len;
        char *buf = unit_data("contours", cases[k].file, &len), *json = NULL;
        struct sf_err err = {0};
        CHECK(buf && model_figures(buf, len, "json", "", NULL, &json, &err) == 0);
        if (!json) {
            fprintf(stderr, "  %s: %s at %s\n", cases[k].file, err.message, err.pointer);
            free(buf);
            continue;
        }
        double exact = atof(strstr(json, "\"exact\":") + 8), quad = atof(strstr(json, "\"quadrature\":") + 13);
        int chains = atoi(strstr(json, "\"chains\":") + 9);
        fprintf(stderr, "  %s: %.3f mm3 in %d chains\n", cases[k].file, exact, chains);
        CHECK_NEAR(exact / quad, 1.0, 1e-12);
        if (cases[k].exact > 0)
            CHECK(fabs(exact - cases[k].exact) / cases[k].exact < 0.002);
        else
            CHECK(chains > 10 && exact > 1.5e6 && exact < 2.5e6); /* the lung: about 2 litres */
        free(json);
        free(buf);
    }
}

/* caps dome: within 0.5 % of the exact solids (issue 5's target), closing on its own at both ends. */
TEST(dome_caps_within_0_5_percent_of_the_solid)
{
    const struct {
        const char *file;
        double solid;
    } cases[] = {{"synthetic_ellipsoid.json", 125663.7061435917},
                 {"synthetic_bean.json", 66860.129},
                 {"synthetic_torus_branching.json", 85273.382}};
    for (int k = 0; k < 3; k++) {
        size_t len;
        char *buf = unit_data("contours", cases[k].file, &len), *json = NULL;
        if (!buf) {
            CHECK(buf != NULL);
            continue;
        }
        /* the request's own caps: put "caps": "dome" in front of the file's keys */
        char *req = malloc(len + 32);
        snprintf(req, len + 32, "{\"caps\":\"dome\",%s", strchr(buf, '{') + 1);
        struct sf_err err = {0};
        CHECK(model_figures(req, strlen(req), "json", "", NULL, &json, &err) == 0);
        if (json) {
            double v = atof(strstr(json, "\"volume_mm3\":") + 13);
            fprintf(stderr, "  %s dome: %.3f mm3, %+.4f %%\n", cases[k].file, v, 100 * (v - cases[k].solid) / cases[k].solid);
            CHECK(fabs(v - cases[k].solid) / cases[k].solid < 0.005);
            CHECK(strstr(json, "\"dome_ends_flat\":0") != NULL);
            CHECK(strstr(json, "\"caps\":\"dome\"") != NULL);
        }
        free(json);
        free(req);
        free(buf);
    }
}

/* The distance from (x, y) to the edge v of patch pt (v = 0 or 1): sampled, then narrowed. */
static double edge_distance(const struct patch *pt, double v, double x, double y)
{
    double best = INFINITY, at = 0.0;
    for (int k = 0; k <= 32; k++) {
        vec3 P;
        bezier_eval(pt, k / 32.0, v, &P, NULL, NULL);
        if (hypot(P.x - x, P.y - y) < best)
            best = hypot(P.x - x, P.y - y), at = k / 32.0;
    }
    for (double h = 1 / 64.0; h > 1e-12; h /= 2) /* (the nearest point moves by less each halving) */
        for (int s = -1; s <= 1; s += 2) {
            double u = fmin(1.0, fmax(0.0, at + s * h));
            vec3 P;
            bezier_eval(pt, u, v, &P, NULL, NULL);
            if (hypot(P.x - x, P.y - y) < best)
                best = hypot(P.x - x, P.y - y), at = u;
        }
    return best;
}

/* The surface passes through every contour point (within MODEL_FIT_REL of the contour's extent:
 * the curve redrawn on fewer knots), and faces outward. */
TEST(interpolates_points_and_faces_outward)
{
    size_t len;
    char *buf = unit_data("contours", "synthetic_bean.json", &len);
    struct contour_set cs;
    struct patch_set ps;
    REQUIRE(buf && model_of(buf, len, &cs, &ps, NULL) == 0);
    long found = 0, total = 0;
    double worst = 0.0;
    for (int k = 0; k < cs.n_slices; k++) {
        double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
        for (int i = 0; i < cs.s[k].n; i++)
            for (int d = 0; d < 2; d++)
                lo[d] = fmin(lo[d], cs.s[k].p[i][d]), hi[d] = fmax(hi[d], cs.s[k].p[i][d]);
        double tol = MODEL_FIT_REL * fmax(hi[0] - lo[0], hi[1] - lo[1]);
        for (int i = 0; i < cs.s[k].n; i++, total++) {
            double best = INFINITY;
            for (size_t p = 0; p < ps.n; p++) { /* the v = 0 or v = 1 edge of some patch holds it */
                const struct patch *pt = &ps.patches[p];
                double v = fabs(pt->v0 - cs.s[k].z) < 1e-9 ? 0.0 : (fabs(pt->v1 - cs.s[k].z) < 1e-9 ? 1.0 : -1.0);
                if (v >= 0)
                    best = fmin(best, edge_distance(pt, v, cs.s[k].p[i][0], cs.s[k].p[i][1]));
            }
            found += best <= tol;
            worst = fmax(worst, best / tol);
        }
    }
    fprintf(stderr, "  contour points within %.2f of the tolerance of the surface\n", worst);
    CHECK(found == total);
    CHECK(worst > 0.01); /* (redrawn: not through the points exactly) */
    /* outward: at a patch centre the normal points away from the slice's centroid */
    long outward = 0;
    for (size_t p = 0; p < ps.n; p++) {
        vec3 P, Pu, Pv;
        bezier_eval(&ps.patches[p], 0.5, 0.5, &P, &Pu, &Pv);
        vec3 n = v3_cross(Pu, Pv);
        outward += n.x * P.x + n.y * P.y > 0; /* the bean is star-shaped about its axis near x=y=0 */
    }
    CHECK(outward > (long)ps.n * 95 / 100);
    nurbs_patch_set_free(&ps);
    contour_set_free(&cs);
    free(buf);
}

/* The closed form from the curves equals the divergence theorem over the patches to 1e-12; the grid
 * rule of eq. 23 is near (1e-4 on the smooth synthetic shapes, 0.2 % on real ones). */
TEST(closed_form_equals_quadrature)
{
    const char *files[] = {"synthetic_ellipsoid.json", "synthetic_bean.json", "dicompyler_heart.json", "eclipse_ptv.json"};
    for (int f = 0; f < 4; f++) {
        size_t len;
        char *buf = unit_data("contours", files[f], &len);
        struct contour_set cs;
        struct patch_set ps;
        REQUIRE(buf && model_of(buf, len, &cs, &ps, NULL) == 0);
        double v, ends[2];
        CHECK(model_volume_closed(&cs, PARABOLIC, &v, ends, NULL) == 0);
        struct solid_measures m;
        measure(&cs, CAPS_FLAT, &m);
        CHECK_NEAR(v / m.volume, 1.0, 1e-12);
        CHECK(fabs(m.volume_grid / m.volume - 1.0) < (f < 2 ? 1e-4 : 2e-3)); /* the 10 x 10 grid rule, eq. 23 */
        CHECK(m.volume_grid != m.volume);
        CHECK_NEAR(ends[0] / model_curve_area(&cs.s[0]), 1.0, 1e-12);
        CHECK_NEAR(ends[1] / model_curve_area(&cs.s[cs.n_slices - 1]), 1.0, 1e-12);
        nurbs_patch_set_free(&ps);
        contour_set_free(&cs);
        free(buf);
    }
}

/* ROI name of the shared RT Structure Set file into *cs, cleaned; false when it cannot be read. */
static bool roi_set(const char *file, const char *name, struct contour_set *cs)
{
    size_t len;
    char *buf = unit_data("contours", file, &len);
    struct rt_roi *rois = NULL;
    int n = 0;
    bool ok = false;
    if (buf && rtstruct_read(buf, len, &rois, &n, NULL) == 0)
        for (int k = 0; k < n && !ok; k++)
            if (strcmp(rois[k].name, name) == 0 && !rois[k].skipped && contour_clean(&rois[k].cs, NULL, NULL) == 0) {
                *cs = rois[k].cs;
                rois[k].cs = (struct contour_set){0};
                ok = true;
            }
    rtstruct_free(rois, n);
    free(buf);
    return ok;
}

/* Folds undone (model_fold.c curves_unfold): on the lung's chains and the dicompyler BODY's (whose folding
 * pair at z 24.56 is drawn ruled), the closed form from the warped curves equals the
 * divergence theorem over the patches drawn from them, as without the warps, and is the one the
 * solid's tubes carry (fitted once for both); the two surfaces differ only where a band folds, by
 * the pockets a fold holds (the lung: 1.1e-4 of its volume; the heart, which does not fold: to the
 * last bit). */
TEST(unfolded_curves_keep_volume_and_patches_together)
{
    const char *files[] = {"dicompyler_lt_lung_multicontour.json", "dicompyler_heart.json", "BODY"};
    for (int f = 0; f < 3; f++) {
        size_t len = 0;
        char *buf = f < 2 ? unit_data("contours", files[f], &len) : NULL;
        struct contour_set cs;
        struct contour_request req;
        REQUIRE(f < 2 ? buf && contour_parse_json(buf, len, &cs, &req, NULL) == 0
                      : roi_set("dicompyler-core_example_rtss.dcm", files[f], &cs));
        struct model_chain *ch;
        int n_ch;
        REQUIRE(model_chains(&cs, CAPS_FLAT, &ch, &n_ch, NULL) == 0);
        struct contour_slice *storage = malloc(sizeof *storage * (size_t)cs.n_slices);
        double plain = 0.0, unfolded = 0.0;
        struct solid sd; /* whose tubes carry the closed form from the curves their patches came from */
        struct model_opts with_closed = PARABOLIC;
        with_closed.closed = true;
        CHECK(solid_build(&cs, with_closed, CAPS_FLAT, &sd, NULL) == 0 && sd.n_tubes == n_ch);
        for (int c = 0; c < n_ch; c++) {
            struct contour_set v = model_chain_view(&cs, &ch[c], storage);
            if (v.n_slices < 2)
                continue;
            double a, b, ends[2];
            struct model_opts o = PARABOLIC;
            struct patch_set ps = {0};
            CHECK(model_volume_closed(&v, o, &b, ends, NULL) == 0);
            CHECK(sd.tubes[c].side.volume == b);
            o.unfold = false;
            CHECK(model_volume_closed(&v, o, &a, ends, NULL) == 0);
            CHECK(model_side(&v, PARABOLIC, &ps, NULL) == 0);
            nurbs_patches_fix(&ps);
            struct enclosed e;
            CHECK(enclosed_measure(&ps, &e) == 0);
            /* the side's divergence integral: the flat caps add nothing (model.h) */
            CHECK_NEAR(e.volume / b, 1.0, 1e-9);
            plain += ch[c].hole ? -a : a, unfolded += ch[c].hole ? -b : b;
            nurbs_patch_set_free(&ps);
        }
        fprintf(stderr, "  %s: %.6f cm3 as fitted, %.6f unfolded (%+.2e)\n", files[f], plain / 1e3, unfolded / 1e3,
                unfolded / plain - 1.0);
        CHECK(f != 1 ? fabs(unfolded / plain - 1.0) > 1e-6 && fabs(unfolded / plain - 1.0) < 2e-4 : unfolded == plain);
        solid_free(&sd);
        free(storage);
        model_chains_free(ch, n_ch);
        contour_set_free(&cs);
        free(buf);
    }
}

/* The fold check's caps (model_fold.c FOLD_MAX_TESTS, FOLD_MAX_SECTIONS): contours of 4400 points that
 * zigzag 2200 times across the same 10 mm, each tooth leaning back (so no stretch of two is
 * monotone), each level's teeth half a tooth off the one below, so that the sections fold at every
 * tooth. Teeth across x (the check's sweep): every piece's box overlaps every other's along x, past
 * the comparisons' cap; teeth along x: each overlaps its neighbours', the pieces to cut past the
 * sections' cap (both reached: counted in a build that prints them). The model is built, unfolded
 * as far as the caps let it. */
TEST(fold_check_caps)
{
    enum { LEVELS = 3, TEETH = 2200, POINTS = 2 * TEETH };
    struct contour_slice sl[LEVELS];
    double(*pts)[2] = malloc(sizeof *pts * LEVELS * POINTS);
    REQUIRE(pts);
    for (int across = 0; across < 2; across++) {
        for (int k = 0; k < LEVELS; k++) {
            double(*p)[2] = pts + (size_t)k * POINTS, shift = k % 2 ? 0.05 : 0.0;
            for (int i = 0; i < TEETH; i++) { /* along the zigzag, then straight back beside it */
                int a = across, b = !across;
                p[i][a] = i % 2 ? 10.0 : 0.0, p[i][b] = 0.1 * i + (i % 2 ? 0.3 : 0.0) + shift; /* leaning back */
                p[POINTS - 1 - i][a] = 12.0, p[POINTS - 1 - i][b] = 0.1 * i + shift;
            }
            sl[k] = (struct contour_slice){.z = 3.0 * k, .n = POINTS, .p = p, .src = k, .src_contour = -1};
        }
        struct contour_set cs = {sl, LEVELS};
        struct solid sd;
        CHECK(solid_build(&cs, PARABOLIC, CAPS_FLAT, &sd, NULL) == 0);
        struct solid_measures m;
        solid_measure(&sd, &m);
        CHECK(isfinite(m.volume) && m.volume != 0.0); /* (one way round negative) */
        solid_free(&sd);
    }
    free(pts);
}

/* Gauss–Legendre of 3x4 points (the measures) and of 8x8 are both exact for the bicubic side patches:
 * they must agree. */
TEST(volume_quadrature_is_exact)
{
    size_t len;
    char *buf = unit_data("contours", "synthetic_ellipsoid.json", &len);
    struct contour_set cs;
    struct patch_set ps;
    REQUIRE(buf && model_of(buf, len, &cs, &ps, NULL) == 0);
    double v8 = 0;
    for (size_t p = 0; p < ps.n; p++)
        for (int a = 0; a < 8; a++)
            for (int b = 0; b < 8; b++) {
                vec3 P, Pu, Pv;
                bezier_eval(&ps.patches[p], GL8_X[a], GL8_X[b], &P, &Pu, &Pv);
                v8 += 0.5 * GL8_W[a] * GL8_W[b] * ((Pu.y * Pv.z - Pu.z * Pv.y) * P.x + (Pu.z * Pv.x - Pu.x * Pv.z) * P.y);
            }
    struct solid_measures m;
    measure(&cs, CAPS_FLAT, &m); /* flat caps add nothing to the integral */
    CHECK_NEAR(m.volume / v8, 1.0, 1e-12);
    nurbs_patch_set_free(&ps);
    contour_set_free(&cs);
    free(buf);
}

/* A circle of radius 10 on four slices: the cylinder's volume, up to the polygon's inscription. */
TEST(cylinder_and_baselines)
{
    enum { CAP = 32768 }; /* 4 slices x 64 points x at most 45 characters, and the frame */
    char *text = malloc(CAP);
    size_t n = (size_t)snprintf(text, CAP, "{\"slices\":[");
    for (int k = 0; k < 4; k++) {
        n += (size_t)snprintf(text + n, CAP - n, "%s{\"z\":%d,\"points\":[", k ? "," : "", 5 * k);
        for (int i = 0; i < 64; i++) { /* start point and direction vary: clockwise on odd slices */
            double a = 2 * M_PI * (k % 2 ? -i : i) / 64.0 + k;
            n += (size_t)snprintf(text + n, CAP - n, "%s[%.15g,%.15g]", i ? "," : "", 10 * cos(a), 10 * sin(a));
        }
        n += (size_t)snprintf(text + n, CAP - n, "]}");
    }
    n += (size_t)snprintf(text + n, CAP - n, "]}");
    struct contour_set cs;
    struct patch_set ps;
    CHECK(model_of(text, n, &cs, &ps, NULL) == 0);
    struct solid_measures m;
    measure(&cs, CAPS_FLAT, &m);
    double exact = M_PI * 100 * 15;
    CHECK(fabs(m.volume - exact) / exact < 2e-4); /* the curve through 64 points is nearly the circle */
    CHECK(fabs(model_curve_area(&cs.s[0]) - M_PI * 100) / (M_PI * 100) < 2e-4);
    CHECK(fabs(m.area - (2 * M_PI * 10 * 15 + 2 * M_PI * 100)) / m.area < 2e-4); /* side and two caps */
    CHECK(fabs(m.lo[2]) < 1e-12 && fabs(m.hi[2] - 15) < 1e-12 && fabs(m.hi[0] - 10) < 0.1);
    struct solid_measures slab;
    measure(&cs, CAPS_SLAB, &slab);
    CHECK(fabs(slab.volume - M_PI * 100 * 20) / (M_PI * 100 * 20) < 2e-4); /* half a spacing out at each end */
    CHECK(fabs(slab.area - (2 * M_PI * 10 * 20 + 2 * M_PI * 100)) / slab.area < 2e-4);
    CHECK(fabs(slab.lo[2] + 2.5) < 1e-12 && fabs(slab.hi[2] - 17.5) < 1e-12);
    struct contour_baselines b;
    contour_baselines(&cs, &b);
    double poly = 0.5 * 64 * 100 * sin(2 * M_PI / 64); /* the polygon's area */
    CHECK_NEAR(b.trapezoid, poly * 15, 1e-6);
    CHECK_NEAR(b.frustum, poly * 15, 1e-6);
    CHECK_NEAR(b.cavalieri, poly * 20, 1e-6);
    CHECK(n < CAP);
    nurbs_patch_set_free(&ps);
    contour_set_free(&cs);
    free(text);
}

static int cmp_edge(const void *a, const void *b)
{
    const unsigned *x = a, *y = b;
    return x[0] != y[0] ? (x[0] > y[0]) - (x[0] < y[0]) : (x[1] > y[1]) - (x[1] < y[1]);
}

/* Every directed edge once, and its reverse once: closed and consistently oriented. */
static bool watertight(const struct solid_mesh *m)
{
    size_t n = 3 * m->n_t;
    unsigned(*e)[2] = malloc(sizeof *e * n);
    for (size_t k = 0; k < m->n_t; k++)
        for (int i = 0; i < 3; i++)
            e[3 * k + i][0] = m->t[k][i], e[3 * k + i][1] = m->t[k][(i + 1) % 3];
    qsort(e, n, sizeof *e, cmp_edge);
    bool ok = true;
    for (size_t k = 0; k < n && ok; k++) {
        unsigned key[2] = {e[k][1], e[k][0]};
        ok = (k == 0 || cmp_edge(e[k - 1], e[k])) && bsearch(key, e, n, sizeof *e, cmp_edge);
    }
    free(e);
    return ok;
}

/* Meshes: closed, oriented, and within 0.1 % of the model's volume at the fixed default tolerance, for every kind of end (flat, slab walls, domes), branchings and holes; and at the default tied to the model (solid_mesh_default) within 0.05 % with fewer triangles. */
TEST(meshes_are_closed_and_hold_the_volume)
{
    const struct {
        const char *file;
        enum model_caps caps;
    } cases[] = {{"synthetic_ellipsoid.json", CAPS_DOME}, {"synthetic_bean.json", CAPS_FLAT},
                 {"synthetic_torus_branching.json", CAPS_SLAB}, {"dicompyler_lt_lung_multicontour.json", CAPS_DOME},
                 {"dicompyler_heart.json", CAPS_DOME}};
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        size_t len;
        char *buf = unit_data("contours", cases[k].file, &len);
        struct contour_set cs;
        struct contour_request req;
        struct solid sd;
        struct solid_measures sm;
        struct solid_mesh m;
        REQUIRE(buf && contour_parse_json(buf, len, &cs, &req, NULL) == 0);
        CHECK(solid_build(&cs, PARABOLIC, cases[k].caps, &sd, NULL) == 0);
        solid_measure(&sd, &sm);
        CHECK(solid_mesh(&sd, solid_default_tolerance(&sm), &m) == 0);
        double vm = solid_mesh_volume(&m), rel = (vm - sm.volume) / sm.volume;
        fprintf(stderr, "  %s: %zu triangles, volume %+.4f %% of the model's\n", cases[k].file, m.n_t, 100 * rel);
        CHECK(watertight(&m));
        CHECK(fabs(rel) < 1e-3);
        /* the default tied to the model: as closed, within 0.05 %, and no finer than the fixed one */
        struct solid_mesh d;
        double tol = 0.0;
        CHECK(solid_mesh_default(&sd, &sm, &d, &tol) == 0);
        double rd = solid_mesh_volume(&d) / sm.volume - 1.0;
        fprintf(stderr, "  ... the default: %.3g mm, %zu triangles, volume %+.4f %%\n", tol, d.n_t, 100 * rd);
        CHECK(watertight(&d) && fabs(rd) <= 5e-4 && tol >= solid_default_tolerance(&sm) && d.n_t <= m.n_t);
        solid_mesh_free(&d);
        solid_mesh_free(&m);
        solid_free(&sd);
        contour_set_free(&cs);
        free(buf);
    }
}

/* Outer shells (connected by shared vertices, positive volume) and cavities (negative) of a mesh. */
static size_t find(size_t *up, size_t x)
{
    while (up[x] != x)
        x = up[x] = up[up[x]];
    return x;
}

static void shells(const struct solid_mesh *m, int *outer, int *cavities)
{
    size_t *up = malloc(sizeof *up * m->n_v);
    double *vol = calloc(m->n_v, sizeof *vol);
    for (size_t v = 0; v < m->n_v; v++)
        up[v] = v;
    for (size_t t = 0; t < m->n_t; t++)
        for (int i = 1; i < 3; i++) {
            size_t a = find(up, m->t[t][0]), b = find(up, m->t[t][i]);
            up[a > b ? a : b] = a < b ? a : b;
        }
    for (size_t t = 0; t < m->n_t; t++) {
        const double *a = m->v[m->t[t][0]], *b = m->v[m->t[t][1]], *c = m->v[m->t[t][2]];
        vol[find(up, m->t[t][0])] += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                                     a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    *outer = *cavities = 0;
    for (size_t v = 0; v < m->n_v; v++)
        if (up[v] == v && vol[v] != 0)
            *(vol[v] > 0 ? outer : cavities) += 1;
    free(up), free(vol);
}

static void sub3(const double *a, const double *b, double *o) { o[0] = a[0] - b[0], o[1] = a[1] - b[1], o[2] = a[2] - b[2]; }

static void cross(const double *a, const double *b, double *o)
{
    o[0] = a[1] * b[2] - a[2] * b[1], o[1] = a[2] * b[0] - a[0] * b[2], o[2] = a[0] * b[1] - a[1] * b[0];
}

/* Whether point x of triangle t's plane lies strictly inside t (by more than eps of its size). */
static bool strictly_in(const double *t[3], const double *x, const double *n, double eps)
{
    for (int i = 0; i < 3; i++) {
        double e[3], w[3], c[3];
        sub3(t[(i + 1) % 3], t[i], e), sub3(x, t[i], w), cross(e, w, c);
        if (dot3(c, n) <= eps * dot3(n, n))
            return false;
    }
    return true;
}

/* Whether triangles p and q (no vertex shared) cut each other: an edge of one through the inside of
 * the other, or, coplanar, a vertex of one inside the other or their edges crossing. */
static bool tris_cut(const double *p[3], const double *q[3])
{
    for (int side = 0; side < 2; side++) {
        const double **a = side ? q : p, **b = side ? p : q;
        double e1[3], e2[3], n[3], d[3];
        sub3(b[1], b[0], e1), sub3(b[2], b[0], e2), cross(e1, e2, n);
        double nn = sqrt(dot3(n, n)), size = sqrt(dot3(e1, e1)) + sqrt(dot3(e2, e2));
        if (!(nn > 0))
            continue;
        for (int i = 0; i < 3; i++) {
            double w[3];
            sub3(a[i], b[0], w);
            d[i] = dot3(w, n) / nn;
        }
        double eps = 1e-9 * size;
        if (fabs(d[0]) <= eps && fabs(d[1]) <= eps && fabs(d[2]) <= eps) { /* coplanar */
            for (int i = 0; i < 3; i++)
                if (strictly_in(b, a[i], n, 1e-6))
                    return true;
            for (int i = 0; i < 3; i++) /* edges crossing: both ends of each on opposite sides of the other */
                for (int k = 0; k < 3; k++) {
                    double u[3], v1[3], v2[3], c1[3], c2[3], w[3], x1[3], x2[3], c3[3], c4[3];
                    sub3(a[(i + 1) % 3], a[i], u), sub3(b[k], a[i], v1), sub3(b[(k + 1) % 3], a[i], v2);
                    cross(u, v1, c1), cross(u, v2, c2);
                    sub3(b[(k + 1) % 3], b[k], w), sub3(a[i], b[k], x1), sub3(a[(i + 1) % 3], b[k], x2);
                    cross(w, x1, c3), cross(w, x2, c4);
                    double s = 1e-6 * size * size * nn;
                    if (dot3(c1, n) * dot3(c2, n) < -s * s && dot3(c3, n) * dot3(c4, n) < -s * s)
                        return true;
                }
            return false;
        }
        for (int i = 0; i < 3; i++) {
            int j = (i + 1) % 3;
            if (!((d[i] > eps && d[j] < -eps) || (d[i] < -eps && d[j] > eps)))
                continue;
            double t = d[i] / (d[i] - d[j]), x[3];
            for (int c = 0; c < 3; c++)
                x[c] = a[i][c] + t * (a[j][c] - a[i][c]);
            if (strictly_in(b, x, n, 1e-6))
                return true;
        }
    }
    return false;
}

struct near_tri {
    double lo[3], hi[3]; /* (axes turned: the sweep's first) */
    size_t t;
};

static int by_lo0(const void *a, const void *b)
{
    double x = ((const struct near_tri *)a)->lo[0], y = ((const struct near_tri *)b)->lo[0];
    return (x > y) - (x < y);
}

/* Whether z is a plane where tubes end and begin: half way between levels, or an end level. */
static bool cap_plane(const struct contour_set *cs, double z)
{
    bool on = z == cs->s[0].z || z == cs->s[cs->n_slices - 1].z;
    for (int k = 0; k + 1 < cs->n_slices && !on; k++)
        on = fabs(z - 0.5 * (cs->s[k].z + cs->s[k + 1].z)) < 1e-9;
    return on;
}

/* Pairs of triangles that cut each other, by a sweep along the axis where the triangles' boxes
 * overlap least (every pair whose boxes meet is tried once, whichever the axis): those where one
 * lies in a plane where tubes end and begin (a cap's), returned, and the others (a side folding on
 * itself, a cavity cutting the outer surface) into *others. */
static int cutting_pairs(const struct solid_mesh *m, const struct contour_set *cs, int *others)
{
    size_t n = m->n_t;
    struct near_tri *nt = malloc(sizeof *nt * n);
    double ext[3] = {0, 0, 0}, lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t t = 0; t < n; t++) {
        struct near_tri x = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}, t};
        for (int i = 0; i < 3; i++)
            for (int c = 0; c < 3; c++)
                x.lo[c] = fmin(x.lo[c], m->v[m->t[t][i]][c]), x.hi[c] = fmax(x.hi[c], m->v[m->t[t][i]][c]);
        for (int c = 0; c < 3; c++)
            ext[c] += x.hi[c] - x.lo[c], lo[c] = fmin(lo[c], x.lo[c]), hi[c] = fmax(hi[c], x.hi[c]);
        nt[t] = x;
    }
    int ax = 0; /* the boxes' mean extent the least part of the mesh's */
    for (int c = 1; c < 3; c++)
        if (ext[c] * (hi[ax] - lo[ax]) < ext[ax] * (hi[c] - lo[c]))
            ax = c;
    for (size_t t = 0; ax && t < n; t++) { /* the sweep's axis first, the z of a cap's plane kept below */
        double l = nt[t].lo[0], h = nt[t].hi[0];
        nt[t].lo[0] = nt[t].lo[ax], nt[t].hi[0] = nt[t].hi[ax], nt[t].lo[ax] = l, nt[t].hi[ax] = h;
    }
    const int z = ax == 2 ? 0 : 2;
    qsort(nt, n, sizeof *nt, by_lo0);
    int pairs = 0;
    *others = 0;
    for (size_t a = 0; a < n; a++)
        for (size_t b = a + 1; b < n && nt[b].lo[0] <= nt[a].hi[0]; b++) {
            if (nt[b].lo[1] > nt[a].hi[1] || nt[a].lo[1] > nt[b].hi[1] || nt[b].lo[2] > nt[a].hi[2] ||
                nt[a].lo[2] > nt[b].hi[2])
                continue;
            const unsigned *ta = m->t[nt[a].t], *tb = m->t[nt[b].t];
            bool shared = false;
            for (int i = 0; i < 3; i++)
                for (int k = 0; k < 3; k++)
                    shared |= ta[i] == tb[k];
            const double *p[3] = {m->v[ta[0]], m->v[ta[1]], m->v[ta[2]]}, *q[3] = {m->v[tb[0]], m->v[tb[1]], m->v[tb[2]]};
            if (!shared && tris_cut(p, q))
                ++*((nt[a].lo[z] == nt[a].hi[z] && cap_plane(cs, nt[a].lo[z])) ||
                            (nt[b].lo[z] == nt[b].hi[z] && cap_plane(cs, nt[b].lo[z]))
                        ? &pairs
                        : others);
        }
    free(nt);
    return pairs;
}

/* One case of branchings_are_one_surface: cs's solid with caps meshed at the default tolerance. */
static void one_surface(const char *what, const struct contour_set *cs, enum model_caps caps, int outer_want,
                        int cavities_want, int folds_max)
{
    struct solid sd;
    struct solid_measures sm;
    struct solid_mesh m;
    double tol;
    CHECK(solid_build(cs, PARABOLIC, caps, &sd, NULL) == 0);
    solid_measure(&sd, &sm);
    CHECK(solid_mesh_default(&sd, &sm, &m, &tol) == 0);
    int outer, cavities, folds, cut = cutting_pairs(&m, cs, &folds);
    shells(&m, &outer, &cavities);
    double rel = solid_mesh_volume(&m) / sm.volume - 1.0;
    fprintf(stderr, "  %s (caps %d): %d chains, %d outer shell(s), %d cavities, %d pairs cutting a cap plane's triangles "
            "(%d elsewhere), volume %+.4f %%\n", what, (int)caps, sd.n_tubes, outer, cavities, cut, folds, 100 * rel);
    CHECK(outer == outer_want && cavities == cavities_want && cut == 0 && folds <= folds_max);
    /* the volume within solid_mesh_default's target, or at its floor tolerance within what that allows
     * (a thin ROI: the dicompyler Borders, 2 levels 3 mm apart, misses by 5.1e-4 at 0.004 mm) */
    CHECK(watertight(&m) &&
          (fabs(rel) <= 5e-4 || (tol <= solid_default_tolerance(&sm) && fabs(rel * sm.volume) <= tol * sm.area)));
    solid_mesh_free(&m);
    solid_free(&sd);
}

/* Issue 18: where chains branch, merge or hold islands, the caps that meet in a plane are one surface:
 * every shared contour file's and RT Structure Set ROI's mesh is one outer shell for each body (the
 * lung's holes that end inside it are cavities), closed, with no triangle of a cap plane cut by
 * another, and the volume held. Without the join the torus is 4 shells with 9210 such pairs, the
 * lung 14 with 3829. Elsewhere, no triangles cut each other but 7 pairs of the lung's (446 before
 * hole_reach and curve_align: holes' ends poking out of the body where it moves in between levels,
 * 247; the side folding between unlike contours whose starts lined up badly, 114 at z -106; 29 before
 * the folds were unfolded, model_fold.c curves_unfold: slits at z -107.44 and -104.44, a bay becoming a
 * hole at -77.44, a notch at 39.56): the 7 at z 41.8-42.6, where the bay of z 39.56 closes (its sides
 * meet, 1 um apart at z 42.34, and cross there). The dicompyler BODY is 12 bodies (the torso, a piece
 * of the right arm at z -122..-97 that never meets it, 10 skin markers of one or two levels); its
 * neck to a marker at z 24.56-27.56 folded (50 pairs) until such a pair was drawn ruled, and the
 * spike to one at 81.56-84.56 (4 pairs, a loop within neighbouring pieces) until the fold check
 * compared those. */
TEST(branchings_are_one_surface)
{
    const struct {
        const char *file;
        enum model_caps caps;
        int cavities, folds;
    } cases[] = {{"synthetic_torus_branching.json", CAPS_FLAT, 0, 0}, {"synthetic_torus_branching.json", CAPS_SLAB, 0, 0},
                 {"synthetic_torus_branching.json", CAPS_DOME, 0, 0}, {"dicompyler_lt_lung_multicontour.json", CAPS_FLAT, 40, 7},
                 {"dicompyler_heart.json", CAPS_FLAT, 0, 0},          {"dicompyler_tumor_bed.json", CAPS_FLAT, 0, 0},
                 {"eclipse_ptv.json", CAPS_FLAT, 0, 0},               {"eclipse_body.json", CAPS_FLAT, 0, 0},
                 {"eclipse_bladder.json", CAPS_FLAT, 0, 0},           {"eclipse_rectum.json", CAPS_FLAT, 0, 0},
                 {"eclipse_femoral_head_lt.json", CAPS_FLAT, 0, 0},   {"synthetic_bean.json", CAPS_FLAT, 0, 0}};
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        size_t len;
        char *buf = unit_data("contours", cases[k].file, &len);
        struct contour_set cs;
        struct contour_request req;
        REQUIRE(buf && contour_parse_json(buf, len, &cs, &req, NULL) == 0);
        if (!buf)
            continue;
        one_surface(cases[k].file, &cs, cases[k].caps, 1, cases[k].cavities, cases[k].folds);
        contour_set_free(&cs);
        free(buf);
    }
    /* every ROI of the shared RT Structure Sets (those without contours are skipped) */
    const char *rs[] = {"dicompyler-core_example_rtss.dcm", "slicerrt_EclipseProstatePhantom_RS.dcm"};
    int rois_seen = 0;
    for (int f = 0; f < 2; f++) {
        size_t len;
        char *buf = unit_data("contours", rs[f], &len);
        struct rt_roi *rois = NULL;
        int n = 0;
        REQUIRE(buf && rtstruct_read(buf, len, &rois, &n, NULL) == 0);
        for (int k = 0; k < n; k++) {
            if (rois[k].skipped)
                continue;
            bool body = f == 0 && strcmp(rois[k].name, "BODY") == 0, lung = strcmp(rois[k].name, "Lt Lung") == 0;
            char what[200];
            snprintf(what, sizeof what, "%s %s", rs[f], rois[k].name);
            CHECK(contour_clean(&rois[k].cs, NULL, NULL) == 0);
            one_surface(what, &rois[k].cs, CAPS_FLAT, body ? 12 : 1, lung ? 40 : 0, lung ? 7 : 0);
            rois_seen++;
        }
        rtstruct_free(rois, n);
        free(buf);
    }
    CHECK(rois_seen == 15);
}

/* The four methods of METHODS.md §2 on the synthetic shapes with flat caps (the exact volume between
 * the end slices is in the files): the interpolating ones within 0.2 %, linear-parabolic (which
 * smooths) within 5 %; every method's solid closes into a watertight mesh; the grid methods' end rows
 * lie on the contours' curves at the grid's columns (one-tube shapes). */
TEST(the_four_methods)
{
    const struct synthetic *cases = SYNTHETIC;
    const enum model_method methods[] = {MODEL_PARABOLIC, MODEL_LINEAR_PARABOLIC, MODEL_COONS, MODEL_BSPLINE};
    for (size_t k = 0; k < 3; k++) {
        size_t len;
        char *buf = unit_data("contours", cases[k].file, &len);
        struct contour_set cs;
        struct contour_request req;
        REQUIRE(buf && contour_parse_json(buf, len, &cs, &req, NULL) == 0);
        struct solid ref;
        CHECK(solid_build(&cs, PARABOLIC, CAPS_FLAT, &ref, NULL) == 0);
        for (int m = 0; m < 4; m++) {
            struct solid sd;
            struct solid_measures sm;
            struct solid_mesh mesh;
            CHECK(solid_build(&cs, (struct model_opts){.method = methods[m], .unfold = true}, CAPS_FLAT, &sd, NULL) == 0);
            solid_measure(&sd, &sm);
            double rel = (sm.volume - cases[k].exact) / cases[k].exact;
            fprintf(stderr, "  %-30s %-16s %12.3f mm3 %+8.4f %% (%zu patches)\n", cases[k].file,
                    model_method_name(methods[m]), sm.volume, 100 * rel, sd.set.n);
            CHECK(fabs(rel) < (methods[m] == MODEL_LINEAR_PARABOLIC ? 0.05 : 0.002));
            CHECK(solid_mesh(&sd, solid_default_tolerance(&sm), &mesh) == 0);
            CHECK(watertight(&mesh));
            solid_mesh_free(&mesh);
            if ((methods[m] == MODEL_COONS || methods[m] == MODEL_BSPLINE) && sd.n_tubes == 1) {
                /* the side's first band, row 0, at the columns k/N, N = most points */
                int N = 8, side = sd.tubes[0].first + 1, ref_side = ref.tubes[0].first + 1; /* after the cap */
                for (int j = 0; j < cs.n_slices; j++)
                    N = cs.s[j].n > N ? cs.s[j].n : N;
                double worst = 0.0;
                for (int c = 0; c < N; c++) {
                    vec3 a = solid_point(&sd, side, (double)c / N, 0.0), b = solid_point(&ref, ref_side, (double)c / N, 0.0);
                    worst = fmax(worst, v3_len(v3_sub(a, b)));
                }
                CHECK(worst < 1e-9);
            }
            solid_free(&sd);
        }
        solid_free(&ref);
        contour_set_free(&cs);
        free(buf);
    }
}

/* A keyhole (the outline runs in along a cut to an inner hole, round it and back out, as planning
 * systems export) is two loops: an outer contour and a hole, as if the slice had been given so. */
TEST(keyholes_split_into_outer_and_hole)
{
    const char *keyhole = "[[0,0],[10,0],[10,10],[0,10],[0,5],[4,5],[4,6],[6,6],[6,4],[4,4],[4,5],[0,5]]";
    char text[1024];
    snprintf(text, sizeof text,
             "{\"slices\":[{\"z\":0,\"points\":%s},{\"z\":1,\"points\":%s},{\"z\":2,\"contours\":"
             "[{\"points\":[[0,0],[10,0],[10,10],[0,10]]},{\"points\":[[4,4],[6,4],[6,6],[4,6]]}]}]}",
             keyhole, keyhole);
    struct contour_set cs;
    struct contour_request req;
    CHECK(contour_parse_json(text, strlen(text), &cs, &req, NULL) == 0);
    CHECK(cs.n_slices == 6);
    int holes = 0;
    for (int k = 0; k < cs.n_slices; k++) {
        holes += cs.s[k].hole;
        CHECK(cs.s[k].n == 4 || cs.s[k].n == 5); /* the cut is gone; its ends stay, on the edges */
        CHECK_NEAR(fabs(contour_area(&cs.s[k])), cs.s[k].hole ? 4.0 : 100.0, 1e-12);
    }
    CHECK(holes == 3);
    struct contour_baselines b;
    contour_baselines(&cs, &b);
    CHECK_NEAR(b.trapezoid, 2 * 96.0, 1e-9);
    struct solid sd;
    CHECK(solid_build(&cs, PARABOLIC, CAPS_FLAT, &sd, NULL) == 0);
    CHECK(sd.n_tubes == 2 && (sd.tubes[0].hole != sd.tubes[1].hole));
    solid_free(&sd);
    contour_set_free(&cs);
}

/* A square of side n from (x, y), a point every unit, counter-clockwise, as JSON. */
static int square_json(char *out, size_t cap, int x, int y, int n)
{
    int len = snprintf(out, cap, "[");
    for (int k = 0; k < 4 * n; k++) {
        int s = k / n, t = k % n, px = s == 0 ? t : s == 1 ? n : s == 2 ? n - t : 0, py = s == 0 ? 0 : s == 1 ? t : s == 2 ? n : n - t;
        len += snprintf(out + len, cap - (size_t)len, "%s[%d,%d]", k ? "," : "", x + px, y + py);
    }
    return len + snprintf(out + len, cap - (size_t)len, "]");
}

/* A hole's end stops where it would leave the body (hole_reach, solid.c): a 4 x 4 hole on level 1
 * of a body that grows from 10 x 10 (level 0) to 20 x 20 (levels 1, 2). Half way down the body's
 * side is at 16.25 (the parabola through 10, 20, 20), short of the hole's far side at 17, so the
 * end reaches down to z 0.6 (8 tenths of the half spacing: 17.2 there, 16.74 at 0.55), and up the
 * whole half spacing: the solid is the body's less the hole's section times 0.4 + 0.5, and its mesh
 * is closed with no triangles cutting each other (a whole half spacing down, they do). */
TEST(a_hole_stops_inside_the_body)
{
    static char small[1024], big[2048], hole[1024], text[8192];
    square_json(small, sizeof small, 0, 0, 10);
    square_json(big, sizeof big, 0, 0, 20);
    square_json(hole, sizeof hole, 13, 13, 4);
    double v[2], area = 0.0;
    for (int with = 0; with < 2; with++) {
        snprintf(text, sizeof text,
                 "{\"slices\":[{\"z\":0,\"points\":%s},{\"z\":1,\"contours\":[{\"points\":%s}%s%s%s]},"
                 "{\"z\":2,\"points\":%s}]}",
                 small, big, with ? ",{\"points\":" : "", with ? hole : "", with ? "}" : "", big);
        struct contour_set cs;
        struct contour_request req;
        struct solid sd;
        struct solid_measures sm;
        struct solid_mesh m;
        REQUIRE(contour_parse_json(text, strlen(text), &cs, &req, NULL) == 0);
        REQUIRE(solid_build(&cs, PARABOLIC, CAPS_FLAT, &sd, NULL) == 0);
        solid_measure(&sd, &sm);
        v[with] = sm.volume;
        for (int k = 0; k < sd.n_tubes && with; k++)
            if (sd.tubes[k].hole) {
                area = model_curve_area(&cs.s[sd.chains[k].idx[0]]);
                CHECK_NEAR(sd.chains[k].ext[0], 0.4, 1e-12);
                CHECK_NEAR(sd.chains[k].ext[1], 0.5, 1e-12);
            }
        CHECK(solid_mesh(&sd, solid_default_tolerance(&sm), &m) == 0);
        int outer, cavities, others, cut = cutting_pairs(&m, &cs, &others);
        shells(&m, &outer, &cavities);
        CHECK(watertight(&m) && outer == 1 && cavities == with && cut == 0 && others == 0);
        solid_mesh_free(&m);
        solid_free(&sd);
        contour_set_free(&cs);
    }
    fprintf(stderr, "  hole section %.6f, volumes %.6f %.6f\n", area, v[0], v[1]);
    CHECK_NEAR(area, 16.0, 1e-9); /* (its corners kept: the curve is the polygon, issue 47) */
    CHECK_NEAR(v[1], v[0] - 0.9 * area, 1e-9 * v[0]);
}

/* Seed 004's polar parameterisation: within 0.2 % on the synthetic shapes too, and a different
 * surface from the arc-length one; a C shape (centroid outside) keeps arc length and still models. */
TEST(polar_parameterisation)
{
    const struct synthetic *cases = SYNTHETIC;
    for (size_t k = 0; k < 3; k++) {
        size_t len;
        char *buf = unit_data("contours", cases[k].file, &len);
        struct contour_set cs;
        struct contour_request req;
        REQUIRE(buf && contour_parse_json(buf, len, &cs, &req, NULL) == 0);
        struct solid_measures arc, polar;
        measure(&cs, CAPS_FLAT, &arc);
        struct solid sd;
        CHECK(solid_build(&cs, (struct model_opts){.method = MODEL_PARABOLIC, .polar = true, .unfold = true}, CAPS_FLAT, &sd, NULL) == 0);
        solid_measure(&sd, &polar);
        solid_free(&sd);
        double rel = (polar.volume - cases[k].exact) / cases[k].exact;
        fprintf(stderr, "  %s polar: %+.4f %% (arc length %+.4f %%)\n", cases[k].file, 100 * rel,
                100 * (arc.volume - cases[k].exact) / cases[k].exact);
        CHECK(fabs(rel) < 0.002 && polar.volume != arc.volume);
        contour_set_free(&cs);
        free(buf);
    }
    const char *c_shape = "{\"parameterisation\":\"polar\",\"slices\":[{\"z\":0,\"points\":[[0,0],[10,0],[10,2],[2,2],"
                          "[2,8],[10,8],[10,10],[0,10]]},{\"z\":2,\"points\":[[0,0],[10,0],[10,2],[2,2],[2,8],[10,8],"
                          "[10,10],[0,10]]}]}";
    char *json = NULL;
    CHECK(model_figures(c_shape, strlen(c_shape), "json", "", NULL, &json, NULL) == 0);
    CHECK(json && strstr(json, "\"parameterisation\":\"polar\""));
    free(json);
}

TEST(rejections)
{
    const struct {
        const char *json;
        int code;
        const char *pointer;
    } cases[] = {
        {"{\"slices\": [", SF_EFORMAT, NULL},
        {"{\"slices\":[{\"z\":0,\"points\":[[0,0],[1,0],[0,1]]}]}", SF_EINVAL, "/slices"},
        {"{\"slices\":[{\"z\":0,\"points\":[[0,0],[1,0],[1,0],[0,0]]},{\"z\":1,\"points\":[[0,0],[1,0],[0,1]]}]}", SF_EINVAL, "/slices/0/points"},
        {"{\"slices\":[{\"z\":0,\"points\":[[0,0],[1,1],[1,0],[0,1]]},{\"z\":1,\"points\":[[0,0],[1,0],[0,1]]}]}", SF_EINVAL, "/slices/0/points"},
        {"{\"slices\":[{\"z\":0,\"points\":[[0,0],[2,0],[0,2]]},{\"z\":0,\"points\":[[1,-1],[1,3],[-1,1]]}]}", SF_EINVAL, "/slices/1/points"},
        {"{\"slices\":[{\"z\":0,\"contours\":[{\"points\":[[0,0],[2,0],[0,2]]},{\"points\":[[1,-1],[1,3],[-1,1]]}]},{\"z\":1,\"points\":[[0,0],[1,0],[0,1]]}]}", SF_EINVAL, "/slices/0/contours/1/points"},
        {"{\"slices\":[{\"z\":0,\"contours\":[]},{\"z\":1,\"points\":[[0,0],[1,0],[0,1]]}]}", SF_EINVAL, "/slices/0/contours"},
        {"{\"slices\":[{\"z\":\"a\",\"points\":[[0,0],[1,0],[0,1]]},{\"z\":1,\"points\":[[0,0],[1,0],[0,1]]}]}", SF_EINVAL, "/slices/0/z"},
        {"{\"slices\":[{\"z\":0,\"points\":[[0,0],[1,\"x\"],[0,1]]},{\"z\":1,\"points\":[[0,0],[1,0],[0,1]]}]}", SF_EINVAL, "/slices/0/points/1"},
        {"{\"method\":\"nurbs\",\"slices\":[]}", SF_EINVAL, "/method"},
        {"{\"caps\":\"hemisphere\",\"slices\":[]}", SF_EINVAL, "/caps"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        struct contour_set cs;
        struct contour_request req;
        struct sf_err err = {0};
        int rc = contour_parse_json(cases[k].json, strlen(cases[k].json), &cs, &req, &err);
        bool ok = rc == cases[k].code && (!cases[k].pointer || !strcmp(err.pointer, cases[k].pointer)) && err.message[0];
        if (!ok)
            fprintf(stderr, "  case %zu: rc %d pointer %s (%s)\n", k, rc, err.pointer, err.message);
        CHECK(ok);
        if (!rc)
            contour_set_free(&cs);
    }
}

/* The patches a chain would make are bounded before any is built (MODEL_MAX_PATCHES: 40 levels of
 * 13 000 points would make about 4 M), refused with the pointer /slices. */
TEST(patch_cap)
{
    enum { LEVELS = 40, POINTS = 13000 };
    struct contour_slice sl[LEVELS];
    double(*pts)[2] = malloc(sizeof *pts * POINTS);
    REQUIRE(pts);
    for (int i = 0; i < POINTS; i++)
        pts[i][0] = 10 * cos(2 * M_PI * i / POINTS), pts[i][1] = 10 * sin(2 * M_PI * i / POINTS);
    for (int k = 0; k < LEVELS; k++)
        sl[k] = (struct contour_slice){.z = k, .n = POINTS, .p = pts, .src = k, .src_contour = -1};
    struct contour_set cs = {sl, LEVELS};
    struct patch_set ps = {0};
    struct sf_err err = {0};
    CHECK(model_side(&cs, PARABOLIC, &ps, &err) == SF_ELIMIT && !strcmp(err.pointer, "/slices"));
    CHECK(ps.n == 0);
    nurbs_patch_set_free(&ps);
    free(pts);
}

/* Curves redrawn on fewer knots: a circle's prism with far fewer patches than points, its volume
 * the closed form's; a zigzag star, which would take more knots than twice its points, keeps its
 * own curve (a patch a point and level pair, as before the knots were redrawn). */
TEST(fewer_knots)
{
    enum { POINTS = 400 };
    double(*pts)[2] = malloc(sizeof *pts * POINTS), (*zig)[2] = malloc(sizeof *zig * POINTS);
    REQUIRE(pts && zig);
    for (int i = 0; i < POINTS; i++) {
        pts[i][0] = 10 * cos(2 * M_PI * i / POINTS), pts[i][1] = 10 * sin(2 * M_PI * i / POINTS);
        double r = i % 2 ? 10.5 : 10; /* a zigzag */
        zig[i][0] = r * cos(2 * M_PI * i / POINTS), zig[i][1] = r * sin(2 * M_PI * i / POINTS);
    }
    for (int c = 0; c < 2; c++) {
        struct contour_slice sl[3];
        for (int k = 0; k < 3; k++)
            sl[k] = (struct contour_slice){.z = k, .n = POINTS, .p = c ? zig : pts, .src = k, .src_contour = -1};
        struct contour_set cs = {sl, 3};
        struct patch_set ps = {0};
        double v, ends[2];
        CHECK(model_side(&cs, PARABOLIC, &ps, NULL) == 0);
        CHECK(model_volume_closed(&cs, PARABOLIC, &v, ends, NULL) == 0);
        double exact = 2 * ends[0]; /* a prism: the end area times the height */
        fprintf(stderr, "  %s: %zu patches of %d points a level, volume %+.2e of the prism's\n", c ? "zigzag" : "circle",
                ps.n, POINTS, v / exact - 1);
        CHECK(fabs(v / exact - 1) < 1e-9);
        CHECK(c || fabs(ends[0] / (M_PI * 100) - 1) < 1e-4); /* (the curve through 400 points of it) */
        CHECK(c ? ps.n == 2 * POINTS : ps.n < POINTS / 4);
        nurbs_patch_set_free(&ps);
    }
    free(pts);
    free(zig);
}

/* ---- sparse polygons (issue 47: 2) ---- */

/* The distance from (x, y) to the polygon's edges. */
static double polygon_distance(const double (*p)[2], int n, double x, double y)
{
    double best = INFINITY;
    for (int i = 0; i < n; i++) {
        const double *a = p[i], *b = p[(i + 1) % n];
        double ex = b[0] - a[0], ey = b[1] - a[1], t = ((x - a[0]) * ex + (y - a[1]) * ey) / (ex * ex + ey * ey);
        t = fmin(1.0, fmax(0.0, t));
        best = fmin(best, hypot(a[0] + t * ex - x, a[1] + t * ey - y));
    }
    return best;
}

/* A contour JSON of ten levels 3 mm apart, each the polygon p. */
static char *prism_json(const double (*p)[2], int n)
{
    size_t cap = 256 + 10 * (size_t)n * 64, len = 0;
    char *buf = malloc(cap);
    len += (size_t)snprintf(buf + len, cap - len, "{\"name\": \"prism\", \"caps\": \"flat\", \"slices\": [");
    for (int k = 0; k < 10; k++) {
        len += (size_t)snprintf(buf + len, cap - len, "%s{\"z\": %d, \"points\": [", k ? ", " : "", 3 * k);
        for (int i = 0; i < n; i++)
            len += (size_t)snprintf(buf + len, cap - len, "%s[%.17g, %.17g]", i ? ", " : "", p[i][0], p[i][1]);
        len += (size_t)snprintf(buf + len, cap - len, "]}");
    }
    snprintf(buf + len, cap - len, "]}");
    return buf;
}

/* What planning systems draw with 4 to 6 points a slice (a box, a couch, an L, a pentagon; edges
 * with a point midway) is modelled as drawn: the volume the prism's (it was +37 % for the square,
 * +43 % for the L), the side surface on the polygon (no corner rounded off, no bulge), and the figures
 * without warnings. */
TEST(sparse_polygons_are_their_prisms)
{
    static const double square[][2] = {{0, 0}, {50, 0}, {50, 50}, {0, 50}};
    static const double ell[][2] = {{0, 0}, {60, 0}, {60, 20}, {20, 20}, {20, 50}, {0, 50}};
    static const double couch[][2] = {{-200, -150}, {0, -150}, {200, -150}, {200, 150}, {0, 150}, {-200, 150}};
    double pent[5][2];
    for (int i = 0; i < 5; i++)
        pent[i][0] = 30 * cos(2 * M_PI * i / 5), pent[i][1] = 30 * sin(2 * M_PI * i / 5);
    const struct {
        const char *name;
        const double (*p)[2];
        int n;
    } cases[] = {{"square", square, 4}, {"L", ell, 6}, {"couch", couch, 6}, {"pentagon", (const double(*)[2])pent, 5}};
    for (size_t c = 0; c < sizeof cases / sizeof *cases; c++) {
        char *buf = prism_json(cases[c].p, cases[c].n), *json = NULL;
        struct contour_set cs;
        struct patch_set ps;
        struct sf_err err = {0};
        REQUIRE(model_of(buf, strlen(buf), &cs, &ps, &err) == 0);
        double area = fabs(contour_area(&cs.s[0])), off = 0.0, v = 0.0, ends[2];
        for (size_t q = 0; q < ps.n; q++) /* the side on the polygon: at 11 x 3 points of every patch */
            for (int a = 0; a <= 10; a++)
                for (int b = 0; b <= 2; b++) {
                    vec3 P;
                    bezier_eval(&ps.patches[q], a / 10.0, b / 2.0, &P, NULL, NULL);
                    off = fmax(off, polygon_distance(cases[c].p, cases[c].n, P.x, P.y));
                }
        CHECK(model_volume_closed(&cs, PARABOLIC, &v, ends, NULL) == 0);
        CHECK(model_figures(buf, strlen(buf), "json", "", NULL, &json, &err) == 0);
        fprintf(stderr, "  %s: %.6f of the prism, %zu patches at most %.1e mm off the polygon\n", cases[c].name,
                v / (27 * area), ps.n, off);
        CHECK(fabs(v / (27 * area) - 1) < 1e-9);
        CHECK(off < 1e-9 * 400);
        CHECK(json && !strstr(json, "\"warnings\""));
        free(json);
        nurbs_patch_set_free(&ps);
        contour_set_free(&cs);
        free(buf);
    }
}

/* A "D" (a half circle of 32 points closed by its diameter): the diameter straight and its ends
 * corners, the arc the circle's (the curve through its points, as before: the volume within 1e-4 of
 * the half disc's prism); a point where the contour turns sharply is where its two sides meet (C0:
 * the side surface's tangents either side of it differ), and a sparse polygon whose turns are short
 * of corners (an octagon stretched and uneven) stays within BULGE_REL (0.1) of each edge's length of
 * that edge's line, its figures warning that the curves enclose more than the polygons. */
TEST(corners_runs_and_bulges)
{
    double d[33][2], oct[8][2];
    for (int i = 0; i <= 32; i++) /* from (20, 0) round to (-20, 0) */
        d[i][0] = 20 * cos(M_PI * i / 32), d[i][1] = 20 * sin(M_PI * i / 32);
    char *buf = prism_json((const double(*)[2])d, 33), *json = NULL;
    struct contour_set cs;
    struct patch_set ps;
    double v, ends[2];
    REQUIRE(model_of(buf, strlen(buf), &cs, &ps, NULL) == 0);
    CHECK(model_volume_closed(&cs, PARABOLIC, &v, ends, NULL) == 0);
    double below = 0.0, kink = 0.0; /* the side's lowest y (the diameter: 0), the turn of its tangents at (20, 0) */
    for (size_t q = 0; q < ps.n; q++)
        for (int a = 0; a <= 10; a++) {
            vec3 P, Pu;
            bezier_eval(&ps.patches[q], a / 10.0, 0.5, &P, &Pu, NULL);
            below = fmin(below, P.y);
            if (hypot(P.x - 20, P.y) < 1e-9 && (a == 0 || a == 10)) /* a patch's end at the corner */
                kink = fmax(kink, fabs(atan2(Pu.y, Pu.x)) * 180 / M_PI);
        }
    fprintf(stderr, "  D: %.6f of the half disc's prism, lowest y %.1e, tangents at its corner %.1f degrees apart\n",
            v / (27 * M_PI * 200), below, kink);
    CHECK(fabs(v / (27 * M_PI * 200) - 1) < 1e-4);
    CHECK(below > -1e-9);
    CHECK(kink > 80); /* (the arc leaves upward, the diameter runs along -x: 90 degrees) */
    nurbs_patch_set_free(&ps);
    contour_set_free(&cs);
    free(buf);
    for (int i = 0; i < 8; i++) {
        double a = 2 * M_PI * i / 8 + (i % 2 ? 0.1 : -0.05);
        oct[i][0] = 40 * cos(a), oct[i][1] = 25 * sin(a);
    }
    buf = prism_json((const double(*)[2])oct, 8);
    REQUIRE(model_of(buf, strlen(buf), &cs, &ps, NULL) == 0);
    double worst = 0.0; /* the side's distance from each edge's line over that edge's length */
    for (size_t q = 0; q < ps.n; q++)
        for (int a = 0; a <= 20; a++) {
            vec3 P;
            bezier_eval(&ps.patches[q], a / 20.0, 0.0, &P, NULL, NULL);
            double best = INFINITY;
            for (int i = 0; i < 8; i++) { /* the edge whose span the point lies across */
                const double *p0 = oct[i], *p1 = oct[(i + 1) % 8];
                double ex = p1[0] - p0[0], ey = p1[1] - p0[1], l = hypot(ex, ey);
                double t = ((P.x - p0[0]) * ex + (P.y - p0[1]) * ey) / (l * l);
                if (t >= -1e-9 && t <= 1 + 1e-9)
                    best = fmin(best, fabs((P.x - p0[0]) * ey - (P.y - p0[1]) * ex) / (l * l));
            }
            worst = fmax(worst, best);
        }
    struct sf_err err = {0};
    CHECK(model_figures(buf, strlen(buf), "json", "", NULL, &json, &err) == 0);
    fprintf(stderr, "  uneven octagon: at most %.4f of an edge's length off its line\n", worst);
    CHECK(worst <= 0.1 + 1e-9 && worst > 0.02);
    CHECK(json && strstr(json, "\"code\":\"curves-depart-from-polygons\""));
    free(json);
    nurbs_patch_set_free(&ps);
    contour_set_free(&cs);
    free(buf);
    size_t len; /* dense contours: no warning */
    buf = unit_data("contours", "synthetic_bean.json", &len);
    CHECK(buf && model_figures(buf, len, "json", "", NULL, &json, &err) == 0);
    CHECK(json && !strstr(json, "\"warnings\""));
    free(json);
    free(buf);
}

int main(void)
{
    RUN(synthetic_volumes_within_0_2_percent);
    RUN(several_contours_per_slice);
    RUN(dome_caps_within_0_5_percent_of_the_solid);
    RUN(interpolates_points_and_faces_outward);
    RUN(volume_quadrature_is_exact);
    RUN(closed_form_equals_quadrature);
    RUN(unfolded_curves_keep_volume_and_patches_together);
    RUN(fold_check_caps);
    RUN(cylinder_and_baselines);
    RUN(meshes_are_closed_and_hold_the_volume);
    RUN(branchings_are_one_surface);
    RUN(the_four_methods);
    RUN(keyholes_split_into_outer_and_hole);
    RUN(a_hole_stops_inside_the_body);
    RUN(polar_parameterisation);
    RUN(rejections);
    RUN(patch_cap);
    RUN(fewer_knots);
    RUN(sparse_polygons_are_their_prisms);
    RUN(corners_runs_and_bulges);
    UNIT_END();
}
