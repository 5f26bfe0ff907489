/* test_bezier.c - Bernstein basis, patch evaluation and derivatives, subdivision, bounds. */
#include "../../../core/geom/bezier.h"
#include "../../../core/geom/nurbs.h"
#include "../../unit.h"

#include <stdlib.h>

/* A bicubic and a biquintic-by-quadratic patch with pseudo-random control points. */
static double (*random_net(int p, int q, unsigned seed, bool rational))[4]
{
    double(*cw)[4] = malloc(sizeof *cw * (size_t)(p + 1) * (q + 1));
    srand(seed);
    for (int k = 0; k < (p + 1) * (q + 1); k++) {
        double w = rational ? 0.5 + rand() / (double)RAND_MAX : 1.0;
        for (int c = 0; c < 3; c++)
            cw[k][c] = (rand() / (double)RAND_MAX * 2 - 1) * w;
        cw[k][3] = w;
    }
    return cw;
}

TEST(basis_partition_of_unity)
{
    for (int n = 1; n <= PATCH_MAX_DEGREE; n++)
        for (double t = 0; t <= 1.0; t += 0.125) {
            double B[PATCH_MAX_DEGREE + 1], dB[PATCH_MAX_DEGREE + 1], s = 0, ds = 0;
            bezier_basis(n, t, B, dB);
            for (int i = 0; i <= n; i++)
                s += B[i], ds += dB[i];
            CHECK_NEAR(s, 1.0, 1e-13);
            CHECK_NEAR(ds, 0.0, 1e-9 * n);
        }
}

TEST(derivatives_match_finite_differences)
{
    const int degs[][2] = {{3, 3}, {5, 2}, {1, 4}};
    for (int r = 0; r < 2; r++)
        for (size_t d = 0; d < 3; d++) {
            struct patch pt = {.p = degs[d][0], .q = degs[d][1], .rational = r,
                               .cw = random_net(degs[d][0], degs[d][1], 7 + (unsigned)d, r), .u1 = 1, .v1 = 1};
            for (double u = 0.1; u < 1; u += 0.2)
                for (double v = 0.15; v < 1; v += 0.2) {
                    vec3 P, Pu, Pv, A, B, C, D;
                    const double h = 1e-6;
                    bezier_eval(&pt, u, v, &P, &Pu, &Pv);
                    bezier_eval(&pt, u + h, v, &A, NULL, NULL);
                    bezier_eval(&pt, u - h, v, &B, NULL, NULL);
                    bezier_eval(&pt, u, v + h, &C, NULL, NULL);
                    bezier_eval(&pt, u, v - h, &D, NULL, NULL);
                    CHECK_NEAR(v3_len(v3_sub(Pu, v3_scale(v3_sub(A, B), 0.5 / h))), 0, 1e-6);
                    CHECK_NEAR(v3_len(v3_sub(Pv, v3_scale(v3_sub(C, D), 0.5 / h))), 0, 1e-6);
                }
            free(pt.cw);
        }
}

/* The bicubic fast path against Cox–de Boor on the same net seen as a clamped B-spline. */
TEST(bicubic_matches_cox_de_boor)
{
    struct patch pt = {.p = 3, .q = 3, .rational = true, .cw = random_net(3, 3, 11, true), .u1 = 1, .v1 = 1};
    struct surface s;
    CHECK(nurbs_surface_alloc(&s, SURF_NURBS, 3, 3, 4, 4, NULL) == 0);
    for (int k = 0; k < 8; k++)
        s.knots_u[k] = s.knots_v[k] = k < 4 ? 0 : 1;
    for (int k = 0; k < 16; k++) {
        for (int c = 0; c < 3; c++)
            s.points[3 * k + c] = pt.cw[k][c] / pt.cw[k][3];
        s.weights[k] = pt.cw[k][3];
    }
    for (double u = 0; u <= 1.0; u += 0.25)
        for (double v = 0; v <= 1.0; v += 0.25) {
            vec3 P, Pu, Pv, Q, Qu, Qv;
            bezier_eval(&pt, u, v, &P, &Pu, &Pv);
            nurbs_eval(&s, u, v, &Q, &Qu, &Qv);
            CHECK_NEAR(v3_len(v3_sub(P, Q)), 0, 1e-13);
            CHECK_NEAR(v3_len(v3_sub(Pu, Qu)), 0, 1e-11);
            CHECK_NEAR(v3_len(v3_sub(Pv, Qv)), 0, 1e-11);
        }
    nurbs_surface_free(&s);
    free(pt.cw);
}

TEST(split_leaves_surface_unchanged)
{
    struct patch pt = {.p = 4, .q = 3, .rational = true, .cw = random_net(4, 3, 3, true), .u1 = 1, .v1 = 1};
    double(*lo)[4] = malloc(sizeof *lo * 20), (*hi)[4] = malloc(sizeof *hi * 20);
    for (int dir = 0; dir < 2; dir++) {
        (dir ? bezier_split_v : bezier_split_u)(&pt, 0.3, lo, hi);
        struct patch a = pt, b = pt;
        a.cw = lo;
        b.cw = hi;
        for (double s = 0; s <= 1.0; s += 0.25)
            for (double t = 0; t <= 1.0; t += 0.25) {
                vec3 P, A, B;
                double us = dir ? t : 0.3 * s, vs = dir ? 0.3 * s : t;
                bezier_eval(&pt, us, vs, &P, NULL, NULL);
                bezier_eval(&a, dir ? t : s, dir ? s : t, &A, NULL, NULL);
                CHECK_NEAR(v3_len(v3_sub(P, A)), 0, 1e-13);
                us = dir ? t : 0.3 + 0.7 * s, vs = dir ? 0.3 + 0.7 * s : t;
                bezier_eval(&pt, us, vs, &P, NULL, NULL);
                bezier_eval(&b, dir ? t : s, dir ? s : t, &B, NULL, NULL);
                CHECK_NEAR(v3_len(v3_sub(P, B)), 0, 1e-13);
            }
    }
    free(lo);
    free(hi);
    free(pt.cw);
}

TEST(bounds_contain_surface)
{
    struct patch pt = {.p = 3, .q = 3, .rational = true, .cw = random_net(3, 3, 5, true), .u1 = 1, .v1 = 1};
    vec3 lo, hi;
    bezier_bounds(&pt, &lo, &hi);
    for (double u = 0; u <= 1.0; u += 0.05)
        for (double v = 0; v <= 1.0; v += 0.05) {
            vec3 P;
            bezier_eval(&pt, u, v, &P, NULL, NULL);
            CHECK(P.x >= lo.x - 1e-12 && P.y >= lo.y - 1e-12 && P.z >= lo.z - 1e-12);
            CHECK(P.x <= hi.x + 1e-12 && P.y <= hi.y + 1e-12 && P.z <= hi.z + 1e-12);
        }
    free(pt.cw);
}

/* A collapsed edge (all of row u = 0 at one point, as at the teapot's lid top) still has a
 * normal: here the first two rings are level, so the tangent plane at the pole is z = 1. */
TEST(normal_at_collapsed_edge)
{
    double(*cw)[4] = malloc(sizeof *cw * 16);
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double r = i / 3.0, a = j * M_PI / 6;
            cw[4 * i + j][0] = r * cos(a), cw[4 * i + j][1] = r * sin(a), cw[4 * i + j][2] = i <= 1 ? 1.0 : 1 - r * r;
            cw[4 * i + j][3] = 1;
        }
    struct patch pt = {.p = 3, .q = 3, .rational = false, .cw = cw, .u1 = 1, .v1 = 1};
    vec3 n;
    CHECK(bezier_normal(&pt, 0.0, 0.5, &n));
    CHECK_NEAR(fabs(n.z), 1.0, 1e-3);
    free(cw);
}

/* The remainder of a first-order step is within the bound the solvers trust to skip an evaluation:
 * |H(u+du, v+dv) - H - Hu du - Hv dv| <= (A_uu du² + 2 A_uv |du dv| + A_vv dv²) / 2, with
 * A = d2 + |o| d2w per partial, H = xyz·w - o w. */
TEST(second_bounds_hold_taylor_remainder)
{
    const int degs[][2] = {{3, 3}, {5, 2}, {1, 4}, {2, 2}};
    const double o[3] = {0.3, -2.0, 0.5}, olen = sqrt(0.09 + 4.0 + 0.25);
    srand(11);
    for (int r = 0; r < 2; r++)
        for (size_t d = 0; d < 4; d++) {
            struct patch pt = {.p = degs[d][0], .q = degs[d][1], .rational = r,
                               .cw = random_net(degs[d][0], degs[d][1], 3 + (unsigned)d, r)};
            bezier_second_bounds(&pt);
            CHECK(pt.wmin > 0 && (pt.d2[0] > 0) == (pt.p > 1) && pt.d2[1] > 0 && (pt.d2[2] > 0) == (pt.q > 1) &&
                  (r ? pt.d2w[1] > 0 : pt.d2w[1] == 0));
            double worst = 0; /* largest remainder over its bound */
            for (int k = 0; k < 2000; k++) {
                double u = rand() / (double)RAND_MAX, v = rand() / (double)RAND_MAX;
                double du = (rand() / (double)RAND_MAX - u) * 0.5, dv = (rand() / (double)RAND_MAX - v) * 0.5;
                double S[4], Su[4], Sv[4], T[4], e2 = 0;
                bezier_eval_h(&pt, u, v, S, Su, Sv);
                bezier_eval_h(&pt, u + du, v + dv, T, NULL, NULL);
                for (int c = 0; c < 3; c++) {
                    double h = T[c] - o[c] * T[3], lin = S[c] - o[c] * S[3] + (Su[c] - o[c] * Su[3]) * du +
                                                         (Sv[c] - o[c] * Sv[3]) * dv;
                    e2 += (h - lin) * (h - lin);
                }
                double bound = 0.5 * ((pt.d2[0] + olen * pt.d2w[0]) * du * du +
                                      2.0 * (pt.d2[1] + olen * pt.d2w[1]) * fabs(du * dv) +
                                      (pt.d2[2] + olen * pt.d2w[2]) * dv * dv);
                worst = fmax(worst, sqrt(e2) / bound);
            }
            CHECK(worst <= 1.0 + 1e-9);
            CHECK(worst > 0.02); /* and not so loose as to be useless */
            free(pt.cw);
        }
    /* a flat parallelogram has no second derivative at all */
    double flat[4][4] = {{0, 0, 0, 1}, {0, 1, 0, 1}, {1, 0.5, 0, 1}, {1, 1.5, 0, 1}};
    struct patch pl = {.p = 1, .q = 1, .cw = flat};
    bezier_second_bounds(&pl);
    CHECK(pl.d2[0] == 0.0 && pl.d2[1] == 0.0 && pl.d2[2] == 0.0 && pl.d2w[1] == 0.0 && pl.wmin == 1.0);
}

int main(void)
{
    RUN(basis_partition_of_unity);
    RUN(derivatives_match_finite_differences);
    RUN(bicubic_matches_cox_de_boor);
    RUN(split_leaves_surface_unchanged);
    RUN(bounds_contain_surface);
    RUN(normal_at_collapsed_edge);
    RUN(second_bounds_hold_taylor_remainder);
    UNIT_END();
}
