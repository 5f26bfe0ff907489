/* test_solve.c - every root finder hits points sampled on Bézier, B-spline and NURBS patches at
 * the expected distance, from map-like seeds (Newton, gradient, steepest) or from nothing
 * (Monte-Carlo); and none reports a root where the ray misses. */
#include "../../../core/geom/nurbs.h"
#include "../../../core/trace/solve.h"
#include "../../unit.h"

#include <stdlib.h>

enum { KIND_BEZIER, KIND_BSPLINE, KIND_NURBS };

/* One patch of each kind: a bumpy bicubic Bézier; a span of a cubic B-spline; an octant of the
 * exact NURBS sphere (radius 2). The patch set keeps the control points alive. */
static void make_patch(int kind, struct patch_set *ps)
{
    struct surface s;
    memset(ps, 0, sizeof *ps);
    if (kind == KIND_BEZIER) {
        nurbs_surface_alloc(&s, SURF_BEZIER, 3, 3, 4, 4, NULL);
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++) {
                double *p = &s.points[3 * (i * 4 + j)];
                p[0] = i, p[1] = j, p[2] = 0.6 * sin(1.3 * i + 0.7 * j);
            }
    } else if (kind == KIND_BSPLINE) {
        nurbs_surface_alloc(&s, SURF_BSPLINE, 3, 3, 5, 5, NULL);
        for (int k = 0; k < 9; k++)
            s.knots_u[k] = s.knots_v[k] = k < 4 ? 0 : (k < 5 ? 0.4 : 1);
        for (int i = 0; i < 5; i++)
            for (int j = 0; j < 5; j++) {
                double *p = &s.points[3 * (i * 5 + j)];
                p[0] = i, p[1] = j, p[2] = 0.4 * cos(0.9 * i - 0.5 * j);
            }
    } else {
        const double h = sqrt(0.5);
        nurbs_surface_alloc(&s, SURF_NURBS, 2, 2, 3, 3, NULL);
        for (int k = 0; k < 6; k++)
            s.knots_u[k] = s.knots_v[k] = k < 3 ? 0 : 1;
        const double cx[3] = {1, 1, 0}, cy[3] = {0, 1, 1}, cw[3] = {1, h, 1};
        const double mr[3] = {1, 1, 0}, mz[3] = {0, 1, 1};
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                int k = i * 3 + j;
                s.points[3 * k] = 2 * cx[i] * mr[j], s.points[3 * k + 1] = 2 * cy[i] * mr[j];
                s.points[3 * k + 2] = 2 * mz[j], s.weights[k] = cw[i] * cw[j];
            }
    }
    nurbs_extract(&s, 0, ps);
    nurbs_patches_fix(ps);
    nurbs_surface_free(&s);
}

typedef bool (*solver)(const struct patch *, const struct dray *, double, double, const struct solve_box *, double,
                       struct solve_hit *);

/* Aims rays at sampled points in [lo, 1-lo]² from 1.5 units off the surface along a tilted
 * normal; seeds are perturbed by 0.02 in each parameter, as a map seed would be. */
static void check_solver(solver fn, double lo, double tol, double t_tol, int *failures)
{
    for (int kind = 0; kind < 3; kind++) {
        struct patch_set ps;
        make_patch(kind, &ps);
        const struct patch *pt = &ps.patches[0];
        const struct solve_box all = {0, 1, 0, 1};
        for (double u = lo; u < 1 - lo + 1e-9; u += 0.1)
            for (double v = lo; v < 1 - lo + 1e-9; v += 0.1) {
                vec3 P, n;
                bezier_eval(pt, u, v, &P, NULL, NULL);
                bezier_normal(pt, u, v, &n);
                vec3 d = v3_norm(v3_add(v3_scale(n, -1.0), v3(0.2, -0.1, 0.05)));
                struct dray r;
                solve_ray_init(&r, v3_mad(P, d, -1.5), d);
                struct solve_hit h;
                bool ok = fn ? fn(pt, &r, u + 0.02, v - 0.02, &all, tol * tol, &h)
                             : solve_montecarlo(pt, &r, 64, &(uint64_t){0x1234567ull + (uint64_t)(u * 1e4)}, tol * tol, &h);
                if (!ok || fabs(h.t - 1.5) > t_tol) {
                    (*failures)++;
                    fprintf(stderr, "  kind %d at (%.2f, %.2f): %s t=%.12g\n", kind, u, v, ok ? "hit" : "no hit", h.t);
                }
            }
        nurbs_patch_set_free(&ps);
    }
}

TEST(newton_cramer_hits_sampled_points)
{
    int f = 0;
    check_solver(solve_newton_cramer, 0.05, 1e-12, 1e-10, &f);
    CHECK(f == 0);
}

TEST(gradient_descent_hits_sampled_points)
{
    int f = 0;
    /* linear convergence: the interior, where the patch is well conditioned, to 1e-6 */
    check_solver(solve_gradient, 0.15, 1e-6, 1e-6, &f);
    CHECK(f == 0);
}

TEST(steepest_descent_hits_sampled_points)
{
    int f = 0;
    check_solver(solve_steepest, 0.15, 1e-6, 1e-6, &f);
    CHECK(f == 0);
}

TEST(montecarlo_hits_sampled_points)
{
    int f = 0;
    check_solver(NULL, 0.15, 1e-6, 1e-6, &f);
    CHECK(f == 0);
}

/* A ray that passes beside the patch must not produce a root. */
TEST(no_root_when_the_ray_misses)
{
    solver fns[] = {solve_newton_cramer, solve_gradient, solve_steepest};
    for (int kind = 0; kind < 3; kind++) {
        struct patch_set ps;
        make_patch(kind, &ps);
        const struct solve_box all = {0, 1, 0, 1};
        vec3 lo, hi;
        bezier_bounds(&ps.patches[0], &lo, &hi);
        struct dray r; /* parallel to z, well outside the x-y extent */
        solve_ray_init(&r, v3(hi.x + 1.0, hi.y + 1.0, hi.z + 5), v3(0, 0, -1));
        for (int k = 0; k < 3; k++) {
            struct solve_hit h;
            CHECK(!fns[k](&ps.patches[0], &r, 0.5, 0.5, &all, 1e-16, &h));
        }
        struct solve_hit h;
        CHECK(!solve_montecarlo(&ps.patches[0], &r, 64, &(uint64_t){42}, 1e-16, &h));
        nurbs_patch_set_free(&ps);
    }
}

/* A root outside the accepted box is refused (each BVH leaf owns only its own roots). */
TEST(root_outside_box_refused)
{
    struct patch_set ps;
    make_patch(KIND_BEZIER, &ps);
    vec3 P, n;
    bezier_eval(&ps.patches[0], 0.8, 0.8, &P, NULL, NULL);
    bezier_normal(&ps.patches[0], 0.8, 0.8, &n);
    struct dray r;
    solve_ray_init(&r, v3_mad(P, n, 2.0), v3_scale(n, -1.0));
    struct solve_hit h;
    const struct solve_box low = {0, 0.5, 0, 0.5}, all = {0, 1, 0, 1};
    CHECK(!solve_newton_cramer(&ps.patches[0], &r, 0.45, 0.45, &low, 1e-20, &h));
    CHECK(solve_newton_cramer(&ps.patches[0], &r, 0.45, 0.45, &all, 1e-20, &h));
    CHECK_NEAR(h.u, 0.8, 1e-9);
    CHECK_NEAR(h.v, 0.8, 1e-9);
    nurbs_patch_set_free(&ps);
}

int main(void)
{
    RUN(newton_cramer_hits_sampled_points);
    RUN(gradient_descent_hits_sampled_points);
    RUN(steepest_descent_hits_sampled_points);
    RUN(montecarlo_hits_sampled_points);
    RUN(no_root_when_the_ray_misses);
    RUN(root_outside_box_refused);
    UNIT_END();
}
