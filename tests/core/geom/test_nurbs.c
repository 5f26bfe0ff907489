/* test_nurbs.c - NURBS against closed forms (the exact sphere of revolution), derivatives,
 * knot insertion and Bézier extraction invariance, and every validation error. */
#include "../../../core/geom/nurbs.h"
#include "../../unit.h"

#include <stdlib.h>

/* The unit sphere as a NURBS: the 9-point quadratic circle (u) swept by a 5-point half circle
 * (v), weights the products of the profiles' (1, √2/2, ...). Parameter u in [0,1] covers the
 * circle in 4 arcs, v in [0,1] the meridian from south to north pole in 2 arcs. */
static void make_sphere(struct surface *s, double R)
{
    const double h = sqrt(0.5);
    const double cx[9] = {1, 1, 0, -1, -1, -1, 0, 1, 1}, cy[9] = {0, 1, 1, 1, 0, -1, -1, -1, 0};
    const double cw[9] = {1, h, 1, h, 1, h, 1, h, 1};
    const double mr[5] = {0, 1, 1, 1, 0}, mz[5] = {-1, -1, 0, 1, 1}, mw[5] = {1, h, 1, h, 1};
    const double U[12] = {0, 0, 0, .25, .25, .5, .5, .75, .75, 1, 1, 1}, V[8] = {0, 0, 0, .5, .5, 1, 1, 1};
    nurbs_surface_alloc(s, SURF_NURBS, 2, 2, 9, 5, NULL);
    memcpy(s->knots_u, U, sizeof U);
    memcpy(s->knots_v, V, sizeof V);
    for (int i = 0; i < 9; i++)
        for (int j = 0; j < 5; j++) {
            int k = i * 5 + j;
            s->points[3 * k] = R * cx[i] * mr[j];
            s->points[3 * k + 1] = R * cy[i] * mr[j];
            s->points[3 * k + 2] = R * mz[j];
            s->weights[k] = cw[i] * mw[j];
        }
}

TEST(sphere_points_exact)
{
    struct surface s;
    make_sphere(&s, 2.5);
    CHECK(nurbs_validate(&s, "/objects/0", NULL) == 0);
    for (double u = 0; u <= 1.0; u += 0.03)
        for (double v = 0; v <= 1.0; v += 0.05) {
            vec3 P, Pu, Pv;
            nurbs_eval(&s, u, v, &P, &Pu, &Pv);
            CHECK_NEAR(v3_len(P), 2.5, 1e-13);
            /* the derivatives are tangent: P·Pu = P·Pv = 0 on a sphere */
            CHECK_NEAR(v3_dot(P, Pu), 0, 1e-11);
            CHECK_NEAR(v3_dot(P, Pv), 0, 1e-11);
        }
    /* arc joints are exact circle points: u = 0.25 is +90°, v = 0.5 the equator */
    vec3 P;
    nurbs_eval(&s, 0.25, 0.5, &P, NULL, NULL);
    CHECK_NEAR(P.x, 0, 1e-14);
    CHECK_NEAR(P.y, 2.5, 1e-14);
    CHECK_NEAR(P.z, 0, 1e-14);
    nurbs_surface_free(&s);
}

TEST(derivatives_against_closed_form)
{
    /* central differences, sampled off the knots (the second derivative jumps at the arcs'
     * double knots, where a central difference is only first order) */
    struct surface s;
    make_sphere(&s, 1.0);
    for (double u = 0.013; u < 1; u += 0.07)
        for (double v = 0.02; v < 1; v += 0.09) {
            vec3 Pu, Pv, A, B, C, D;
            const double h = 1e-6;
            nurbs_eval(&s, u, v, NULL, &Pu, &Pv);
            nurbs_eval(&s, u + h, v, &A, NULL, NULL);
            nurbs_eval(&s, u - h, v, &B, NULL, NULL);
            nurbs_eval(&s, u, v + h, &C, NULL, NULL);
            nurbs_eval(&s, u, v - h, &D, NULL, NULL);
            CHECK_NEAR(v3_len(v3_sub(Pu, v3_scale(v3_sub(A, B), 0.5 / h))), 0, 2e-6);
            CHECK_NEAR(v3_len(v3_sub(Pv, v3_scale(v3_sub(C, D), 0.5 / h))), 0, 2e-6);
        }
    nurbs_surface_free(&s);
}

TEST(knot_insertion_keeps_surface)
{
    struct surface s, t;
    make_sphere(&s, 1.0);
    make_sphere(&t, 1.0);
    CHECK(nurbs_insert_knot_u(&t, 0.1) == 0);
    CHECK(nurbs_insert_knot_u(&t, 0.6) == 0);
    CHECK(nurbs_transpose(&t) == 0);
    CHECK(nurbs_insert_knot_u(&t, 0.3) == 0); /* now along the old v */
    CHECK(nurbs_transpose(&t) == 0);
    CHECK(t.n_u == 11 && t.n_v == 6);
    CHECK(nurbs_validate(&t, "", NULL) == 0);
    for (double u = 0; u <= 1.0; u += 0.05)
        for (double v = 0; v <= 1.0; v += 0.05) {
            vec3 P, Q;
            nurbs_eval(&s, u, v, &P, NULL, NULL);
            nurbs_eval(&t, u, v, &Q, NULL, NULL);
            CHECK_NEAR(v3_len(v3_sub(P, Q)), 0, 1e-13);
        }
    nurbs_surface_free(&s);
    nurbs_surface_free(&t);
}

static void check_extraction(const struct surface *s, size_t expect_patches)
{
    struct patch_set ps = {0};
    CHECK(nurbs_extract(s, 0, &ps) == 0);
    nurbs_patches_fix(&ps);
    CHECK(ps.n == expect_patches);
    for (size_t k = 0; k < ps.n; k++) {
        const struct patch *pt = &ps.patches[k];
        CHECK(pt->p == s->deg_u && pt->q == s->deg_v);
        for (double a = 0; a <= 1.0; a += 0.2)
            for (double b = 0; b <= 1.0; b += 0.2) {
                vec3 P, Q;
                bezier_eval(pt, a, b, &P, NULL, NULL);
                nurbs_eval(s, pt->u0 + a * (pt->u1 - pt->u0), pt->v0 + b * (pt->v1 - pt->v0), &Q, NULL, NULL);
                CHECK_NEAR(v3_len(v3_sub(P, Q)), 0, 1e-12);
            }
    }
    nurbs_patch_set_free(&ps);
}

TEST(bezier_extraction_keeps_surface)
{
    struct surface s;
    make_sphere(&s, 3.0);
    check_extraction(&s, 4 * 2);
    nurbs_surface_free(&s);
    /* an unclamped uniform cubic B-spline, 7 x 6 points: 4 x 3 spans */
    struct surface b;
    CHECK(nurbs_surface_alloc(&b, SURF_BSPLINE, 3, 3, 7, 6, NULL) == 0);
    for (int k = 0; k < 11; k++)
        b.knots_u[k] = k;
    for (int k = 0; k < 10; k++)
        b.knots_v[k] = 0.5 * k;
    srand(9);
    for (int k = 0; k < 3 * 42; k++)
        b.points[k] = rand() / (double)RAND_MAX;
    CHECK(nurbs_validate(&b, "", NULL) == 0);
    check_extraction(&b, 4 * 3);
    /* the same net as a NURBS whose weights are all 2: polynomial patches, the same surface */
    struct surface w;
    CHECK(nurbs_surface_alloc(&w, SURF_NURBS, 3, 3, 7, 6, NULL) == 0);
    memcpy(w.knots_u, b.knots_u, sizeof *w.knots_u * 11);
    memcpy(w.knots_v, b.knots_v, sizeof *w.knots_v * 10);
    memcpy(w.points, b.points, sizeof *w.points * 3 * 42);
    for (int k = 0; k < 42; k++)
        w.weights[k] = 2.0;
    check_extraction(&w, 4 * 3);
    nurbs_surface_free(&w);
    nurbs_surface_free(&b);
}

/* One validation failure per rule, with the pointer it must name. */
TEST(validation_errors)
{
    struct surface s;
    struct sf_err e = {0};
    CHECK(nurbs_surface_alloc(&s, SURF_BSPLINE, 0, 3, 5, 5, &e) == SF_EINVAL && strstr(e.pointer, "degree"));
    nurbs_surface_free(&s);
    memset(&e, 0, sizeof e);
    CHECK(nurbs_surface_alloc(&s, SURF_BSPLINE, 3, 3, 3, 5, &e) == SF_EINVAL && strstr(e.pointer, "size"));
    nurbs_surface_free(&s);
    memset(&e, 0, sizeof e);
    CHECK(nurbs_surface_alloc(&s, SURF_BSPLINE, 1, 1, 2000, 2000, &e) == SF_ELIMIT);
    nurbs_surface_free(&s);

    const char *expect[] = {"/objects/2/knots_u/5", "/objects/2/knots_v", "/objects/2/weights/7",
                            "/objects/2/points/3/1", "/objects/2/knots_u/3", "/objects/2/knots_v/0"};
    for (int c = 0; c < 6; c++) {
        make_sphere(&s, 1.0);
        switch (c) {
        case 0: s.knots_u[5] = 0.1; break;                       /* decreasing */
        case 1: for (int k = 0; k < 8; k++) s.knots_v[k] = 0.0; break; /* empty domain */
        case 2: s.weights[7] = -1.0; break;                      /* weight <= 0 */
        case 3: s.points[3 * 3 + 1] = NAN; break;                /* NaN coordinate */
        case 4: s.knots_u[5] = 0.25; s.knots_u[6] = 0.25; break; /* interior knot 3x > degree 2 */
        case 5: s.knots_v[0] = INFINITY; break;                  /* non-finite knot */
        }
        memset(&e, 0, sizeof e);
        int rc = nurbs_validate(&s, "/objects/2", &e);
        CHECK(rc == SF_EINVAL);
        if (strcmp(e.pointer, expect[c]))
            fprintf(stderr, "  case %d: pointer %s, expected %s (%s)\n", c, e.pointer, expect[c], e.message);
        CHECK_STR(e.pointer, expect[c]);
        CHECK(e.message[0] != 0);
        nurbs_surface_free(&s);
    }
}

int main(void)
{
    RUN(sphere_points_exact);
    RUN(derivatives_against_closed_form);
    RUN(knot_insertion_keeps_surface);
    RUN(bezier_extraction_keeps_surface);
    RUN(validation_errors);
    UNIT_END();
}
