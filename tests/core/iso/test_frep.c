/* test_frep.c - FRep evaluation (core/iso/frep.h): every primitive's value against its closed
 * form, the R-functions' formulas, transforms, gradients against finite differences through a
 * whole tree, gradients on the surface itself, the bounds' soundness, and block-skipping sampling
 * against full evaluation. */
#include "../../../core/iso/frep.h"

#include <stdbool.h>

#include "../../unit.h"

#define PI 3.14159265358979323846

static struct frep_node nodes[64];
static struct frep tree = {nodes, 0, 0, NULL};

static int add(struct frep_node n)
{
    nodes[tree.n] = n;
    tree.root = tree.n;
    return tree.n++;
}

static double at(double x, double y, double z)
{
    double p[3] = {x, y, z};
    return frep_eval(&tree, p, NULL);
}

/* a deterministic stream of numbers in [lo, hi] */
static double rnd(double lo, double hi)
{
    static unsigned long long s = 88172645463325252ull;
    s ^= s << 13, s ^= s >> 7, s ^= s << 17;
    return lo + (hi - lo) * (double)(s >> 11) / 9007199254740992.0;
}

TEST(primitives_are_signed_distances)
{
    tree.n = 0;
    add((struct frep_node){.kind = FREP_SPHERE, .p = {1, 2, 3, 2}});
    CHECK_NEAR(at(1, 2, 3), 2, 1e-12);
    CHECK_NEAR(at(4, 2, 3), -1, 1e-12);
    CHECK_NEAR(at(1, 2, 4.5), 0.5, 1e-12);

    tree.n = 0;
    add((struct frep_node){.kind = FREP_BOX, .p = {-1, -2, -3, 1, 2, 3}});
    CHECK_NEAR(at(0, 0, 0), 1, 1e-12);    /* nearest face x = +-1 */
    CHECK_NEAR(at(0.5, 1.8, 0), 0.2, 1e-12);
    CHECK_NEAR(at(2, 0, 0), -1, 1e-12);
    CHECK_NEAR(at(4, 6, 3), -5, 1e-12);   /* from the edge (1, 2, z): 3-4-5 */

    tree.n = 0; /* axis along +y from (0, 1, 0), radius 2, length 4 */
    add((struct frep_node){.kind = FREP_CYLINDER, .p = {0, 1, 0, 0, 1, 0, 2, 4}});
    CHECK_NEAR(at(0, 3, 0), 2, 1e-12);    /* the axis, mid-height: 2 to the side and to the caps */
    CHECK_NEAR(at(1.5, 3, 0), 0.5, 1e-12);
    CHECK_NEAR(at(0, 6, 1), -1, 1e-12);   /* above the top cap */
    CHECK_NEAR(at(5, 8, 0), -sqrt(9 + 9), 1e-12); /* off the rim */
    CHECK_NEAR(at(0, 1.25, 0.5), 0.25, 1e-12);    /* near the base */

    tree.n = 0; /* base at the origin, radius 1, apex (0, 0, 1): slant at 45 degrees */
    add((struct frep_node){.kind = FREP_CONE, .p = {0, 0, 0, 0, 0, 1, 1, 1}});
    CHECK_NEAR(at(0, 0, 0.5), 0.5 / sqrt(2), 1e-12);
    CHECK_NEAR(at(0, 0, 2), -1, 1e-12);
    CHECK_NEAR(at(0.5, 0, -1), -1, 1e-12);
    CHECK_NEAR(at(0.2, 0, 0.1), 0.1, 1e-12); /* nearer the base than the slant (0.7/sqrt 2) */

    tree.n = 0;
    add((struct frep_node){.kind = FREP_TORUS, .p = {0, 0, 0, 0, 0, 1, 3, 1}});
    CHECK_NEAR(at(3, 0, 0), 1, 1e-12);
    CHECK_NEAR(at(0, 3, 0.5), 0.5, 1e-12);
    CHECK_NEAR(at(0, 0, 0), -2, 1e-12);
    CHECK_NEAR(at(3, 0, 3), -2, 1e-12);

    tree.n = 0; /* the normal points out: inside is below z = 1 */
    add((struct frep_node){.kind = FREP_HALFSPACE, .p = {0, 0, 1, 0, 0, 1}});
    CHECK_NEAR(at(5, 5, -1), 2, 1e-12);
    CHECK_NEAR(at(0, 0, 3), -2, 1e-12);

    tree.n = 0; /* on the axes an ellipsoid's field is the distance along them */
    add((struct frep_node){.kind = FREP_ELLIPSOID, .p = {0, 0, 0, 1, 2, 3}});
    CHECK_NEAR(at(1, 0, 0), 0, 1e-12);
    CHECK_NEAR(at(0, 2, 0), 0, 1e-12);
    CHECK_NEAR(at(0, 0, 3), 0, 1e-12);
    CHECK_NEAR(at(1.5, 0, 0), -0.5, 1e-12);
    CHECK(at(0, 0, 2.9) > 0 && at(0, 0, 3.1) < 0);
}

TEST(superellipsoid_of_unit_exponents_is_the_ellipsoid)
{
    struct frep_node s = {.kind = FREP_SUPERELLIPSOID, .p = {0.5, 0, 0, 1, 2, 1.5, 1, 1}};
    struct frep_node e = {.kind = FREP_ELLIPSOID, .p = {0.5, 0, 0, 1, 2, 1.5}};
    struct frep ts = {&s, 1, 0, NULL}, te = {&e, 1, 0, NULL};
    for (int k = 0; k < 200; k++) {
        double x[3] = {rnd(-3, 3), rnd(-3, 3), rnd(-3, 3)};
        CHECK_NEAR(frep_eval(&ts, x, NULL), frep_eval(&te, x, NULL), 1e-9);
    }
    /* e -> small: a box's corner is inside; e = 2 on one axis: a bicone's edge */
    s.p[6] = s.p[7] = 0.1;
    double corner[3] = {0.5 + 0.9, 1.8, 1.35};
    CHECK(frep_eval(&ts, corner, NULL) > 0);
    s.p[6] = s.p[7] = 1;
    CHECK(frep_eval(&ts, corner, NULL) < 0);
}

TEST(r_functions)
{
    tree.n = 0; /* two halfspaces: x < 1 (f1 = 1 - x) and y < 2 (f2 = 2 - y) */
    int a = add((struct frep_node){.kind = FREP_HALFSPACE, .p = {1, 0, 0, 1, 0, 0}});
    int b = add((struct frep_node){.kind = FREP_HALFSPACE, .p = {0, 2, 0, 0, 1, 0}});
    const enum frep_kind OPS[] = {FREP_UNION, FREP_INTERSECT, FREP_SUBTRACT};
    for (int o = 0; o < 3; o++)
        for (double alpha = 0; alpha <= 1; alpha += 0.5) {
            tree.n = 2;
            add((struct frep_node){.kind = OPS[o], .a = a, .b = b, .alpha = alpha});
            for (int k = 0; k < 50; k++) {
                double x = rnd(-3, 3), y = rnd(-3, 3), f1 = 1 - x, f2 = 2 - y;
                if (OPS[o] == FREP_SUBTRACT)
                    f2 = -f2;
                double s = sqrt(f1 * f1 + f2 * f2 - 2 * alpha * f1 * f2), sign = OPS[o] == FREP_UNION ? 1 : -1;
                CHECK_NEAR(at(x, y, 0), (f1 + f2 + sign * s) / (1 + alpha), 1e-12);
                if (alpha == 1)
                    CHECK_NEAR(at(x, y, 0), OPS[o] == FREP_UNION ? fmax(f1, f2) : fmin(f1, f2), 1e-12);
            }
        }
    /* blend: the union plus a0 / (1 + (f1/a1)^2 + (f2/a2)^2), most at the join's edge */
    tree.n = 2;
    add((struct frep_node){.kind = FREP_BLEND, .a = a, .b = b, .p = {0.3, 0.5, 0.25}});
    double f1 = 1 - 0.2, f2 = 2 - 1.1;
    CHECK_NEAR(at(0.2, 1.1, 0), f1 + f2 + sqrt(f1 * f1 + f2 * f2) + 0.3 / (1 + f1 * f1 / 0.25 + f2 * f2 / 0.0625), 1e-12);
    CHECK(at(1.05, 2.05, 0) > 0); /* the blend fills the concave corner's outside */
    /* offset */
    tree.n = 0;
    int s = add((struct frep_node){.kind = FREP_SPHERE, .p = {0, 0, 0, 1}});
    add((struct frep_node){.kind = FREP_OFFSET, .a = s, .p = {0.25}});
    CHECK_NEAR(at(1.25, 0, 0), 0, 1e-12);
}

TEST(transform_moves_the_object)
{
    tree.n = 0;
    int box = add((struct frep_node){.kind = FREP_BOX, .p = {-1, -0.5, -0.25, 1, 0.5, 0.25}});
    struct frep_node t = {.kind = FREP_TRANSFORM, .a = box};
    const double scale[3] = {2, 1, 3}, rot[3] = {30, -20, 45}, tr[3] = {1, 2, 3};
    frep_transform(&t, scale, rot, tr);
    add(t);
    /* the image of each corner of the box: scaled, rotated about x, y, z in turn, translated */
    for (int c = 0; c < 8; c++) {
        double p[3] = {c & 1 ? 1 : -1, c & 2 ? 0.5 : -0.5, c & 4 ? 0.25 : -0.25};
        for (int i = 0; i < 3; i++)
            p[i] *= scale[i];
        for (int ax = 0; ax < 3; ax++) {
            double a = rot[ax] * PI / 180, u = p[(ax + 1) % 3], v = p[(ax + 2) % 3];
            p[(ax + 1) % 3] = cos(a) * u - sin(a) * v;
            p[(ax + 2) % 3] = sin(a) * u + cos(a) * v;
        }
        CHECK_NEAR(at(p[0] + tr[0], p[1] + tr[1], p[2] + tr[2]), 0, 1e-9);
    }
    CHECK_NEAR(at(1, 2, 3), 0.25 * 1, 1e-9); /* the centre: the child's 0.25, times the least scale */
}

/* the analytic gradient against central differences, where the field is smooth there (the two
 * step sizes agree) */
static int gradient_checks(double lo, double hi)
{
    int checked = 0;
    for (int k = 0; k < 2000; k++) {
        double x[3] = {rnd(lo, hi), rnd(lo, hi), rnd(lo, hi)}, g[3], fd[2][3];
        frep_eval(&tree, x, g);
        for (int s = 0; s < 2; s++)
            for (int i = 0; i < 3; i++) {
                double h = s ? 2e-6 : 1e-6, a[3] = {x[0], x[1], x[2]}, b[3] = {x[0], x[1], x[2]};
                a[i] += h, b[i] -= h;
                fd[s][i] = (frep_eval(&tree, a, NULL) - frep_eval(&tree, b, NULL)) / (2 * h);
            }
        bool smooth = true;
        for (int i = 0; i < 3; i++)
            smooth = smooth && fabs(fd[0][i] - fd[1][i]) < 1e-6;
        if (!smooth)
            continue;
        checked++;
        for (int i = 0; i < 3; i++)
            CHECK_NEAR(g[i], fd[0][i], 1e-5);
    }
    return checked;
}

TEST(gradients_through_a_tree)
{
    tree.n = 0;
    int prims[8];
    prims[0] = add((struct frep_node){.kind = FREP_SPHERE, .p = {0.2, 0, 0, 1}});
    prims[1] = add((struct frep_node){.kind = FREP_BOX, .p = {-1, -0.8, -0.6, 0.9, 0.7, 0.5}});
    prims[2] = add((struct frep_node){.kind = FREP_CYLINDER, .p = {0, 0, -1.5, 0, 0, 1, 0.4, 3}});
    double ax[3] = {1 / sqrt(3), 1 / sqrt(3), 1 / sqrt(3)};
    prims[3] = add((struct frep_node){.kind = FREP_CONE, .p = {0, 0, 0, ax[0], ax[1], ax[2], 0.7, 1.6}});
    prims[4] = add((struct frep_node){.kind = FREP_TORUS, .p = {0, 0.3, 0, 0, 1, 0, 1.1, 0.25}});
    prims[5] = add((struct frep_node){.kind = FREP_SUPERELLIPSOID, .p = {0, 0, 0.2, 0.8, 1, 1.2, 0.6, 1.6}});
    prims[6] = add((struct frep_node){.kind = FREP_ELLIPSOID, .p = {0.1, 0, 0, 1.2, 0.6, 0.9}});
    prims[7] = add((struct frep_node){.kind = FREP_HALFSPACE, .p = {0, 0, 0.4, ax[0], 0, ax[0] * sqrt(2)}});
    for (int p = 0; p < 8; p++) { /* each alone */
        tree.root = prims[p];
        CHECK(gradient_checks(-2, 2) > 1000);
    }
    int u = add((struct frep_node){.kind = FREP_UNION, .a = prims[1], .b = prims[2], .alpha = 0});
    int sub = add((struct frep_node){.kind = FREP_SUBTRACT, .a = u, .b = prims[0], .alpha = 0.3});
    int bl = add((struct frep_node){.kind = FREP_BLEND, .a = sub, .b = prims[4], .p = {0.2, 0.4, 0.3}});
    int in = add((struct frep_node){.kind = FREP_INTERSECT, .a = bl, .b = prims[7], .alpha = 1});
    int of = add((struct frep_node){.kind = FREP_OFFSET, .a = in, .p = {-0.05}});
    struct frep_node t = {.kind = FREP_TRANSFORM, .a = of};
    frep_transform(&t, (double[3]){1.5, 0.8, 1.2}, (double[3]){15, 30, 60}, (double[3]){0.1, -0.2, 0.3});
    add(t);
    CHECK(gradient_checks(-2, 2) > 1000);
}

TEST(bounds_hold_over_their_ball)
{
    tree.n = 0;
    int a = add((struct frep_node){.kind = FREP_BOX, .p = {-1, -1, -1, 1, 1, 1}});
    int b = add((struct frep_node){.kind = FREP_SPHERE, .p = {1, 1, 1, 0.6}});
    int c = add((struct frep_node){.kind = FREP_SUPERELLIPSOID, .p = {0, 0, 0, 0.5, 0.7, 1.4, 0.4, 1.8}});
    int d = add((struct frep_node){.kind = FREP_SUBTRACT, .a = a, .b = b});
    int e = add((struct frep_node){.kind = FREP_BLEND, .a = d, .b = c, .p = {-0.3, 0.5, 0.5}, .alpha = 0.2});
    struct frep_node t = {.kind = FREP_TRANSFORM, .a = e};
    frep_transform(&t, (double[3]){0.5, 1, 2}, (double[3]){0, 45, 10}, (double[3]){0, 0, 0.5});
    int tr = add(t);
    add((struct frep_node){.kind = FREP_OFFSET, .a = tr, .p = {0.1}});
    for (int k = 0; k < 300; k++) {
        double cen[3] = {rnd(-3, 3), rnd(-3, 3), rnd(-3, 3)}, r = rnd(0, 1), lo, hi;
        frep_bound(&tree, cen, r, &lo, &hi);
        for (int m = 0; m < 50; m++) {
            double dir[3] = {rnd(-1, 1), rnd(-1, 1), rnd(-1, 1)}, n = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
            double s = r * rnd(0, 1) / n, x[3] = {cen[0] + s * dir[0], cen[1] + s * dir[1], cen[2] + s * dir[2]};
            double v = frep_eval(&tree, x, NULL);
            CHECK(v >= lo - 1e-12 && v <= hi + 1e-12);
        }
    }
}

TEST(sampling_skips_only_what_the_mesh_does_not_read)
{
    tree.n = 0;
    int a = add((struct frep_node){.kind = FREP_TORUS, .p = {0, 0, 0, 0, 0, 1, 1, 0.3}});
    int b = add((struct frep_node){.kind = FREP_CYLINDER, .p = {0, 0, -1, 0, 0, 1, 0.2, 2}});
    add((struct frep_node){.kind = FREP_UNION, .a = a, .b = b});
    enum { N = 61 };
    static float got[N * N * N];
    double org[3] = {-1.5, -1.5, -1.5}, h = 3.0 / (N - 1);
    frep_sample(&tree, org, h, N, N, 0, 30, got, NULL, NULL);  /* in two slabs */
    frep_sample(&tree, org, h, N, N, 30, N, got, NULL, NULL);
    int skipped = 0;
    for (int k = 0; k < N; k++)
        for (int j = 0; j < N; j++)
            for (int i = 0; i < N; i++) {
                double x[3] = {org[0] + i * h, org[1] + j * h, org[2] + k * h};
                float want = (float)frep_eval(&tree, x, NULL), v = got[((size_t)k * N + j) * N + i];
                CHECK((v > 0) == (want > 0));
                /* within two samples of a sign change the value is the field's own */
                bool near = false;
                for (int dk = -2; dk <= 2 && !near; dk++)
                    for (int dj = -2; dj <= 2 && !near; dj++)
                        for (int di = -2; di <= 2 && !near; di++) {
                            double y[3] = {x[0] + di * h, x[1] + dj * h, x[2] + dk * h};
                            near = (frep_eval(&tree, y, NULL) > 0) != (want > 0);
                        }
                if (near)
                    CHECK(v == want);
                skipped += v != want;
            }
    CHECK(skipped > N * N * N / 2); /* the blocks far from the surface were skipped */
}

/* On the surface (and a rounding error off it) a solid of revolution's gradient is its face's
 * normal, not the direction of an offset of 1e-16 (which is noise): the normals of sharp features
 * are read there. */
TEST(gradients_on_the_surface_are_the_faces_normals)
{
    tree.n = 0; /* axis along +z from the origin, radius 0.6, length 1 */
    add((struct frep_node){.kind = FREP_CYLINDER, .p = {0, 0, 0, 0, 0, 1, 0.6, 1}});
    const double pts[][3] = {{0.6, 0, 0.3}, {0.6 + 1e-16, 0, 0.3}, {0.3, 0.2, 0}, {0.3, 0.2, -1e-17}, {0.1, -0.2, 1}},
                 want[][3] = {{-1, 0, 0}, {-1, 0, 0}, {0, 0, 1}, {0, 0, 1}, {0, 0, -1}};
    for (int k = 0; k < 5; k++) {
        double g[3], f = frep_eval(&tree, pts[k], g);
        CHECK_NEAR(f, 0, 1e-15);
        for (int d = 0; d < 3; d++)
            CHECK_NEAR(g[d], want[k][d], 1e-12);
    }
    tree.n = 0; /* the cone's slant, at 45 degrees: the inward normal (-1, 0, -1) / sqrt 2 at (0.5, 0, 0.5) */
    add((struct frep_node){.kind = FREP_CONE, .p = {0, 0, 0, 0, 0, 1, 1, 1}});
    double g[3];
    frep_eval(&tree, (double[3]){0.5, 0, 0.5}, g);
    CHECK_NEAR(g[0], -sqrt(0.5), 1e-12);
    CHECK_NEAR(g[2], -sqrt(0.5), 1e-12);
}

/* A volume primitive: trilinear, so exact on a field linear in each axis (values and gradient), the
 * samples themselves at the nodes, scale (v - iso), flat and outside beyond the grid; its bounds
 * hold; in an R-function it mixes with a distance. */
TEST(a_sampled_volume_in_a_tree)
{
    enum { NX = 5, NY = 4, NZ = 3 };
    static float v[NX * NY * NZ];
    for (int z = 0; z < NZ; z++)
        for (int y = 0; y < NY; y++)
            for (int x = 0; x < NX; x++) /* f = 2x - 3y + 0.5z + xy (bilinear: trilinear reproduces it) */
                v[x + NX * (y + NY * z)] = (float)(2 * x - 3 * y + 0.5 * z + x * y);
    struct frep_volume vol = {{NX, NY, NZ}, {10, 20, 30}, {0.5, 2, 4}, v, -9, 14, -20};
    struct frep_volume vols[1] = {vol};
    tree = (struct frep){nodes, 0, 0, vols};
    add((struct frep_node){.kind = FREP_VOLUME, .p = {0, 1.5, 3}});
    for (int k = 0; k < 200; k++) {
        double gx = rnd(0, NX - 1), gy = rnd(0, NY - 1), gz = rnd(0, NZ - 1);
        double p[3] = {10 + 0.5 * gx, 20 + 2 * gy, 30 + 4 * gz}, g[3];
        double f = frep_eval(&tree, p, g), want = 3 * (2 * gx - 3 * gy + 0.5 * gz + gx * gy - 1.5);
        CHECK_NEAR(f, want, 1e-5);
        CHECK_NEAR(g[0], 3 * (2 + gy) / 0.5, 1e-4);
        CHECK_NEAR(g[1], 3 * (-3 + gx) / 2, 1e-4);
        CHECK_NEAR(g[2], 3 * 0.5 / 4, 1e-4);
        double lo, hi;
        frep_bound(&tree, p, 1, &lo, &hi);
        CHECK(lo <= f && f <= hi);
    }
    CHECK_NEAR(at(10 + 0.5 * 4, 20 + 2 * 3, 30 + 4 * 2), 3 * (v[4 + NX * (3 + NY * 2)] - 1.5), 1e-9); /* the last node */
    double g[3];
    CHECK_NEAR(frep_eval(&tree, (double[3]){9.9, 21, 31}, g), 3 * (-20 - 1.5), 1e-12);
    CHECK(g[0] == 0 && g[1] == 0 && g[2] == 0);
    CHECK_NEAR(at(11, 20, 38.1), 3 * (-20 - 1.5), 1e-12);
    int vn = tree.root; /* subtracted from a ball: R0 of the two, inside only where both say so */
    int ball = add((struct frep_node){.kind = FREP_SPHERE, .p = {11, 23, 34, 2}});
    add((struct frep_node){.kind = FREP_INTERSECT, .a = ball, .b = vn, .alpha = 1});
    double p[3] = {11, 23, 34};
    CHECK_NEAR(frep_eval(&tree, p, NULL), fmin(2, 3 * (2 * 2 - 3 * 1.5 + 0.5 + 3 - 1.5)), 1e-5);
    struct frep_volume none = {{NX, NY, NZ}, {10, 20, 30}, {0.5, 2, 4}, NULL, 0, 0, 0}; /* no samples given: flat */
    vols[0] = none;
    CHECK_NEAR(frep_eval(&tree, p, NULL), fmin(2, 3 * (0 - 1.5)), 1e-12);
    tree.volumes = NULL;
}

int main(void)
{
    RUN(primitives_are_signed_distances);
    RUN(superellipsoid_of_unit_exponents_is_the_ellipsoid);
    RUN(r_functions);
    RUN(transform_moves_the_object);
    RUN(gradients_through_a_tree);
    RUN(bounds_hold_over_their_ball);
    RUN(sampling_skips_only_what_the_mesh_does_not_read);
    RUN(gradients_on_the_surface_are_the_faces_normals);
    RUN(a_sampled_volume_in_a_tree);
    UNIT_END();
}
