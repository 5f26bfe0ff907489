/* test_keyhole.c - holes joined into their outer loops: what a reader that fills every loop it
 * meets covers (the union of the output loops) is the input's even-odd region, point for point
 * on a lattice and in area; the output loops cross nowhere (their channels only touch); outer
 * loops without holes pass as they are; an island in a hole is a loop of its own; holes in a
 * grid (vertices in line with each hole's rightmost point) and holes given either way round;
 * the test cap refused. */
#include "../../../core/geom/keyhole.h"

#include <stdbool.h>

#include "../../unit.h"

#define MAX_PTS 4096
#define MAX_LOOPS 64

struct shape {
    double p[MAX_PTS][2];
    int start[MAX_LOOPS + 1], n;
};

/* a w x h rectangle at (x, y), counter-clockwise (ccw) or not, with k points a side */
static void rect(struct shape *s, double x, double y, double w, double h, bool ccw, int k)
{
    int at = s->start[s->n];
    double c[4][2] = {{x, y}, {x + w, y}, {x + w, y + h}, {x, y + h}};
    for (int side = 0; side < 4; side++)
        for (int i = 0; i < k; i++) {
            int a = ccw ? side : 3 - side, b = ccw ? (side + 1) % 4 : (3 - side + 3) % 4;
            double t = (double)i / k;
            s->p[at][0] = c[a][0] + t * (c[b][0] - c[a][0]);
            s->p[at][1] = c[a][1] + t * (c[b][1] - c[a][1]);
            at++;
        }
    s->start[++s->n] = at;
}

static struct trimesh_loops loops_of(struct shape *s)
{
    return (struct trimesh_loops){s->p, s->start, s->n};
}

static bool inside(double (*p)[2], int n, double x, double y)
{
    bool in = false;
    for (int i = 0, j = n - 1; i < n; j = i++)
        if ((p[i][1] > y) != (p[j][1] > y) && x < p[j][0] + (y - p[j][1]) / (p[i][1] - p[j][1]) * (p[i][0] - p[j][0]))
            in = !in;
    return in;
}

static double signed_area(double (*p)[2], int n)
{
    double a = 0;
    for (int i = 0, j = n - 1; i < n; j = i++)
        a += p[j][0] * p[i][1] - p[i][0] * p[j][1];
    return a / 2;
}

/* even-odd over every input loop */
static bool even_odd(const struct trimesh_loops *l, double x, double y)
{
    bool in = false;
    for (int k = 0; k < l->n; k++)
        in ^= inside(l->p + l->start[k], l->start[k + 1] - l->start[k], x, y);
    return in;
}

/* filled: inside any output loop */
static bool filled(const struct trimesh_loops *l, double x, double y)
{
    for (int k = 0; k < l->n; k++)
        if (inside(l->p + l->start[k], l->start[k + 1] - l->start[k], x, y))
            return true;
    return false;
}

static double orient(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Whether two edges of the output cross properly (each one's ends strictly either side). */
static bool any_crossing(const struct trimesh_loops *l)
{
    int n = l->start[l->n];
    for (int a = 0; a < l->n; a++)
        for (int i = l->start[a]; i < l->start[a + 1]; i++) {
            int i1 = i + 1 < l->start[a + 1] ? i + 1 : l->start[a];
            for (int b = 0; b < l->n; b++)
                for (int j = l->start[b]; j < l->start[b + 1]; j++) {
                    int j1 = j + 1 < l->start[b + 1] ? j + 1 : l->start[b];
                    const double *p = l->p[i], *q = l->p[i1], *r = l->p[j], *s = l->p[j1];
                    if (orient(p, q, r) * orient(p, q, s) < 0 && orient(r, s, p) * orient(r, s, q) < 0)
                        return true;
                }
        }
    (void)n;
    return false;
}

/* The output covers the input's even-odd region: at lattice points off every line of the shapes,
 * and in area (the sum of the loops' areas, none overlapping). */
static void check_covers(const struct trimesh_loops *in, const struct trimesh_loops *out, double expect_area)
{
    int wrong = 0;
    for (double x = -0.93; x < 41; x += 0.217)
        for (double y = -0.87; y < 41; y += 0.231)
            wrong += even_odd(in, x, y) != filled(out, x, y);
    CHECK(wrong == 0);
    double a = 0;
    for (int k = 0; k < out->n; k++) {
        double ak = signed_area(out->p + out->start[k], out->start[k + 1] - out->start[k]);
        CHECK(ak > 0); /* outer loops counter-clockwise, holes inside them */
        a += ak;
    }
    CHECK_NEAR(a, expect_area, 1e-9 * expect_area);
    CHECK(!any_crossing(out));
}

static struct shape s;

static void one_hole(bool hole_ccw)
{
    s.n = 0, s.start[0] = 0;
    rect(&s, 0, 0, 10, 10, true, 5);
    rect(&s, 3, 3, 4, 4, hole_ccw, 3); /* given either way round: nesting decides */
    struct trimesh_loops in = loops_of(&s), out;
    int apart = -1;
    REQUIRE(keyhole_join(&in, KEYHOLE_MAX_TESTS, &out, &apart, NULL) == 0);
    CHECK(out.n == 1 && apart == 0);
    CHECK(out.start[1] == 20 + 12 + 2); /* the outer, the hole, and the channel's two ends again */
    check_covers(&in, &out, 100 - 16);
    trimesh_loops_free(&out);
}

TEST(one_hole) { one_hole(false); }
TEST(hole_either_way) { one_hole(true); }

/* 16 holes in a grid, one holding an island: every hole's rightmost point in line with others'
 * vertices, the island joined as an outer loop of its own */
TEST(grid_of_holes)
{
    s.n = 0, s.start[0] = 0;
    rect(&s, 0, 0, 40, 40, true, 8);
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            rect(&s, 2 + 10 * i, 2 + 10 * j, 6, 6, false, 2);
    rect(&s, 14, 14, 2, 2, true, 1); /* in the hole at (12, 12) */
    struct trimesh_loops in = loops_of(&s), out;
    int apart = -1;
    REQUIRE(keyhole_join(&in, KEYHOLE_MAX_TESTS, &out, &apart, NULL) == 0);
    CHECK(out.n == 2 && apart == 0);
    check_covers(&in, &out, 1600 - 16 * 36 + 4);
    trimesh_loops_free(&out);
}

/* outer loops without holes, side by side: as they are */
TEST(no_holes)
{
    s.n = 0, s.start[0] = 0;
    rect(&s, 0, 0, 10, 10, true, 1);
    rect(&s, 20, 0, 10, 10, false, 1); /* clockwise: turned */
    struct trimesh_loops in = loops_of(&s), out;
    REQUIRE(keyhole_join(&in, KEYHOLE_MAX_TESTS, &out, NULL, NULL) == 0);
    CHECK(out.n == 2 && out.start[1] == 4 && out.start[2] == 8);
    check_covers(&in, &out, 200);
    trimesh_loops_free(&out);
}

/* a hole touching its outer loop at a point: a channel of no length */
TEST(touching_hole)
{
    static const double tri[3][2] = {{10, 5}, {6, 4}, {6, 6}}; /* its rightmost point on the outer's side */
    /* the outer with (10, 5) as a vertex */
    struct shape t = {.n = 0};
    t.start[0] = 0;
    static const double sq[5][2] = {{0, 0}, {10, 0}, {10, 5}, {10, 10}, {0, 10}};
    for (int i = 0; i < 5; i++)
        t.p[i][0] = sq[i][0], t.p[i][1] = sq[i][1];
    for (int i = 0; i < 3; i++)
        t.p[5 + i][0] = tri[i][0], t.p[5 + i][1] = tri[i][1];
    t.start[1] = 5, t.start[2] = 8, t.n = 2;
    struct trimesh_loops in = loops_of(&t), out;
    REQUIRE(keyhole_join(&in, KEYHOLE_MAX_TESTS, &out, NULL, NULL) == 0);
    CHECK(out.n == 1);
    check_covers(&in, &out, 100 - 4);
    trimesh_loops_free(&out);
}

/* the cap: refused, nothing left allocated */
TEST(cap)
{
    s.n = 0, s.start[0] = 0;
    rect(&s, 0, 0, 40, 40, true, 8);
    for (int i = 0; i < 4; i++)
        rect(&s, 2 + 10 * i, 2, 6, 6, false, 2);
    struct trimesh_loops in = loops_of(&s), out;
    struct sf_err err = {0};
    CHECK(keyhole_join(&in, 50, &out, NULL, &err) == SF_ELIMIT);
    CHECK(err.code == SF_ELIMIT && strstr(err.message, "50 tests"));
    CHECK(out.n == 0 && out.p == NULL && out.start == NULL);
    CHECK(keyhole_join(&in, 100000, &out, NULL, NULL) == 0);
    trimesh_loops_free(&out);
}

int main(void)
{
    RUN(one_hole);
    RUN(hole_either_way);
    RUN(grid_of_holes);
    RUN(no_holes);
    RUN(touching_hole);
    RUN(cap);
    UNIT_END();
}
