/* test_trim.c - the trim region's index against brute-force even-odd: a square with a round hole
 * holding a square island, loops running either way round, points on a fine lattice and at
 * random, vertices on the cells' centre lines; boxes classified inside/outside are so at every
 * sample; bad loops refused with the pointer given. */
#include "../../../core/geom/trim.h"

#include <stdbool.h>
#include <stdint.h>

#include "../../unit.h"

/* even-odd over all loops, every segment (the reference) */
static bool brute(const double (*p)[2], const size_t *counts, int n_loops, double u, double v)
{
    bool in = false;
    size_t at = 0;
    for (int l = 0; l < n_loops; at += counts[l], l++)
        for (size_t k = 0; k < counts[l]; k++) {
            const double *a = p[at + k], *b = p[at + (k + 1) % counts[l]];
            if ((a[1] > v) != (b[1] > v) && u < a[0] + (v - a[1]) / (b[1] - a[1]) * (b[0] - a[0]))
                in = !in;
        }
    return in;
}

static uint64_t rng = 88172645463325252ull;
static double uniform(void)
{
    rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
    return (double)(rng >> 11) / 9007199254740992.0;
}

enum { HOLE = 997 };
static double pts[4 + HOLE + 4][2];
static size_t counts[3] = {4, HOLE, 4};

static void shape(void)
{
    const double sq[4][2] = {{0, 0}, {4, 0}, {4, 3}, {0, 3}};       /* outer, counter-clockwise */
    const double isl[4][2] = {{1.8, 1.3}, {1.8, 1.7}, {2.2, 1.7}, {2.2, 1.3}}; /* island, clockwise */
    memcpy(pts, sq, sizeof sq);
    for (int k = 0; k < HOLE; k++) /* the hole, clockwise */
        pts[4 + k][0] = 2 + cos(-2 * M_PI * k / HOLE), pts[4 + k][1] = 1.5 + sin(-2 * M_PI * k / HOLE);
    memcpy(pts[4 + HOLE], isl, sizeof isl);
}

TEST(points_agree_with_brute_force)
{
    shape();
    struct trim t;
    struct sf_err err = {0};
    CHECK(trim_build(&t, (const double(*)[2])pts, counts, 3, "/x", NULL, &err) == 0);
    int wrong = 0, n_in = 0;
    for (int k = 0; k < 200000; k++) {
        double u = -0.5 + 5 * uniform(), v = -0.5 + 4 * uniform();
        bool want = brute((const double(*)[2])pts, counts, 3, u, v);
        wrong += trim_contains(&t, u, v) != want;
        n_in += want;
    }
    /* a lattice through the loop vertices' own coordinates (off the loops' straight edges, where a
     * point may go either way) */
    int lattice = 0;
    for (int i = 1; i < 400; i++)
        for (int j = 1; j < 300; j++) {
            double u = i * 0.01, v = j * 0.01;
            if (i == 180 || i == 220 || j == 130 || j == 170 || (i == 300 && j == 150)) /* (3, 1.5): a hole vertex */
                continue;
            lattice += trim_contains(&t, u, v) != brute((const double(*)[2])pts, counts, 3, u, v);
        }
    fprintf(stderr, "  %d of 200000 inside, %d disagree; %d on the lattice\n", n_in, wrong, lattice);
    CHECK(wrong == 0 && lattice == 0);
    CHECK(n_in > 50000 && n_in < 150000);
    CHECK(trim_contains(&t, 0.5, 0.5) && !trim_contains(&t, 2.5, 1.5) && trim_contains(&t, 2.0, 1.5));
    CHECK(!trim_contains(&t, -1, 1) && !trim_contains(&t, 5, 1));
    trim_free(&t);
}

TEST(boxes_classified_hold_at_every_sample)
{
    shape();
    struct trim t;
    CHECK(trim_build(&t, (const double(*)[2])pts, counts, 3, "", NULL, NULL) == 0);
    int n[3] = {0}, wrong = 0;
    for (int k = 0; k < 3000; k++) {
        double w = 0.5 * uniform() * uniform(), u0 = -0.3 + 4.6 * uniform(), v0 = -0.3 + 3.6 * uniform();
        enum trim_class c = trim_classify(&t, u0, u0 + w, v0, v0 + w);
        n[c]++;
        if (c == TRIM_CUT)
            continue;
        for (int s = 0; s < 20; s++) {
            double u = u0 + w * uniform(), v = v0 + w * uniform();
            wrong += brute((const double(*)[2])pts, counts, 3, u, v) != (c == TRIM_IN);
        }
    }
    fprintf(stderr, "  out %d, in %d, cut %d; %d samples disagree\n", n[TRIM_OUT], n[TRIM_IN], n[TRIM_CUT], wrong);
    CHECK(wrong == 0);
    CHECK(n[TRIM_OUT] > 100 && n[TRIM_IN] > 100 && n[TRIM_CUT] > 100);
    CHECK(trim_classify(&t, 0.1, 0.2, 0.1, 0.2) == TRIM_IN);
    CHECK(trim_classify(&t, 2.4, 2.5, 1.4, 1.5) == TRIM_OUT); /* in the hole */
    CHECK(trim_classify(&t, 1.0, 3.0, 1.0, 2.0) == TRIM_CUT);
    CHECK(trim_classify(&t, 5.0, 6.0, 1.0, 2.0) == TRIM_OUT);
    trim_free(&t);
}

TEST(box_areas_are_exact_for_the_polylines)
{
    shape();
    struct trim t;
    CHECK(trim_build(&t, (const double(*)[2])pts, counts, 3, "", NULL, NULL) == 0);
    double c[2];
    /* the outer square's edges on the box's own edges, and through it */
    CHECK_NEAR(trim_box_moments(&t, 0, 0.5, 0, 0.5, c), 0.25, 1e-12);
    CHECK_NEAR(c[0], 0.25, 1e-12);
    CHECK_NEAR(trim_box_moments(&t, -1, 0.5, -1, 0.5, c), 0.25, 1e-12);
    CHECK_NEAR(trim_box_moments(&t, 3.5, 4.5, 2.5, 3.5, c), 0.25, 1e-12);
    CHECK_NEAR(c[0], 3.75, 1e-12);
    CHECK_NEAR(c[1], 2.75, 1e-12);
    CHECK_NEAR(trim_box_moments(&t, 2.4, 2.6, 1.4, 1.6, c), 0.0, 1e-12); /* in the hole */
    CHECK_NEAR(trim_box_moments(&t, 1.8, 2.2, 1.3, 1.7, c), 0.16, 1e-12); /* the island exactly */
    /* random boxes against a fine lattice of the brute-force test */
    double worst = 0;
    for (int k = 0; k < 60; k++) {
        double w = 0.05 + 0.5 * uniform(), u0 = -0.3 + 4.3 * uniform(), v0 = -0.3 + 3.3 * uniform();
        double a = trim_box_moments(&t, u0, u0 + w, v0, v0 + w, c);
        enum { M = 100 };
        int in = 0;
        for (int i = 0; i < M; i++)
            for (int j = 0; j < M; j++)
                in += brute((const double(*)[2])pts, counts, 3, u0 + w * (i + 0.5) / M, v0 + w * (j + 0.5) / M);
        worst = fmax(worst, fabs(a - w * w * in / (M * M)) / (w * w));
    }
    fprintf(stderr, "  worst box area off the lattice's by %.2e of the box\n", worst);
    CHECK(worst < 0.02); /* the lattice's own error: a boundary's width of cells */
    trim_free(&t);
}

TEST(bad_loops_are_refused)
{
    struct trim t;
    struct sf_err err = {0};
    const double two[2][2] = {{0, 0}, {1, 1}};
    size_t c2 = 2;
    CHECK(trim_build(&t, two, &c2, 1, "/entities/D7", NULL, &err) == SF_EINVAL);
    CHECK_STR(err.pointer, "/entities/D7");
    const double flat[3][2] = {{0, 0}, {1, 0}, {2, 0}};
    size_t c3 = 3;
    err = (struct sf_err){0};
    CHECK(trim_build(&t, flat, &c3, 1, "", NULL, &err) == SF_EINVAL);
    const double nan3[3][2] = {{0, 0}, {1, NAN}, {2, 1}};
    err = (struct sf_err){0};
    CHECK(trim_build(&t, nan3, &c3, 1, "", NULL, &err) == SF_EINVAL);
    size_t big = TRIM_MAX_POINTS + 1;
    err = (struct sf_err){0};
    CHECK(trim_build(&t, two, &big, 1, "", NULL, &err) == SF_ELIMIT); /* refused before any point is read */
    err = (struct sf_err){0};
    CHECK(trim_build(&t, two, &c2, 0, "", NULL, &err) == SF_EINVAL);
}

int main(void)
{
    RUN(points_agree_with_brute_force);
    RUN(boxes_classified_hold_at_every_sample);
    RUN(box_areas_are_exact_for_the_polylines);
    RUN(bad_loops_are_refused);
    UNIT_END();
}
