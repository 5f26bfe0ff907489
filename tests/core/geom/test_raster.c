/* test_raster.c - loops to a pixel mask: every pixel centre set exactly when a point-in-polygon
 * test by the even-odd rule says it is inside (a square, a square with a hole, a triangle, a
 * disc against its area, two loops sharing an edge), loops half off the grid clipped, an empty
 * mask for loops off it, and the crossings' cap refused before anything is allocated. */
#include "../../../core/geom/raster.h"

#include <stdbool.h>

#include "../../unit.h"

#define MAX_PTS 4096
#define MAX_LOOPS 16

struct shape {
    double p[MAX_PTS][2];
    int start[MAX_LOOPS + 1], n;
};

static void poly(struct shape *s, const double (*v)[2], int n)
{
    int at = s->start[s->n];
    for (int i = 0; i < n; i++)
        s->p[at + i][0] = v[i][0], s->p[at + i][1] = v[i][1];
    s->start[++s->n] = at + n;
}

static void disc(struct shape *s, double cx, double cy, double r, int n)
{
    int at = s->start[s->n];
    for (int i = 0; i < n; i++)
        s->p[at + i][0] = cx + r * cos(2 * M_PI * i / n), s->p[at + i][1] = cy + r * sin(2 * M_PI * i / n);
    s->start[++s->n] = at + n;
}

/* the even-odd rule by a ray to +x, half-open in y as the fill is */
static bool inside(const struct shape *s, double x, double y)
{
    bool in = false;
    for (int k = 0; k < s->n; k++)
        for (int i = s->start[k], j = s->start[k + 1] - 1; i < s->start[k + 1]; j = i++) {
            const double *a = s->p[i], *b = s->p[j];
            if ((a[1] <= y) != (b[1] <= y) && x >= a[0] + (y - a[1]) / (b[1] - a[1]) * (b[0] - a[0]))
                in = !in;
        }
    return in;
}

/* the mask against inside() at every centre; returns the pixels set */
static size_t check_mask(struct shape *s, int cols, int rows)
{
    static unsigned char mask[256 * 256];
    struct trimesh_loops l = {s->p, s->start, s->n};
    size_t set = 99, wrong = 0, counted = 0;
    struct sf_err err = {0};
    CHECK(raster_loops(&l, cols, rows, mask, &set, &err) == 0);
    for (int j = 0; j < rows; j++)
        for (int i = 0; i < cols; i++) {
            counted += mask[j * cols + i];
            wrong += mask[j * cols + i] != inside(s, i, j);
        }
    CHECK(wrong == 0);
    CHECK(set == counted);
    return set;
}

TEST(square)
{
    static struct shape s;
    s.n = 0, s.start[0] = 0;
    const double v[][2] = {{2.5, 3.5}, {10.5, 3.5}, {10.5, 8.5}, {2.5, 8.5}};
    poly(&s, v, 4);
    CHECK(check_mask(&s, 16, 16) == 8 * 5); /* i 3..10, j 4..8 */
}

TEST(square_with_hole)
{
    static struct shape s;
    s.n = 0, s.start[0] = 0;
    const double o[][2] = {{0.5, 0.5}, {20.5, 0.5}, {20.5, 20.5}, {0.5, 20.5}};
    const double h[][2] = {{5.5, 5.5}, {5.5, 15.5}, {15.5, 15.5}, {15.5, 5.5}}; /* clockwise */
    poly(&s, o, 4);
    poly(&s, h, 4);
    CHECK(check_mask(&s, 32, 32) == 20 * 20 - 10 * 10);
}

TEST(triangle_and_shared_edge)
{
    static struct shape s;
    s.n = 0, s.start[0] = 0;
    const double a[][2] = {{1.2, 1.7}, {30.3, 4.1}, {12.9, 28.6}};
    poly(&s, a, 3);
    check_mask(&s, 32, 32);
    /* two squares side by side on whole coordinates: centres on the shared edge set once, the
     * outer edges' left and lower sides in, right and upper out */
    s.n = 0, s.start[0] = 0;
    const double l[][2] = {{2, 2}, {6, 2}, {6, 6}, {2, 6}}, r[][2] = {{6, 2}, {10, 2}, {10, 6}, {6, 6}};
    poly(&s, l, 4);
    poly(&s, r, 4);
    CHECK(check_mask(&s, 16, 16) == 8 * 4); /* i 2..9, j 2..5 */
}

TEST(disc_area)
{
    static struct shape s;
    s.n = 0, s.start[0] = 0;
    disc(&s, 100.3, 120.6, 80, 720);
    double set = (double)check_mask(&s, 256, 256);
    CHECK_NEAR(set, M_PI * 80 * 80, 0.005 * M_PI * 80 * 80); /* pixel counting: within 0.5 % at r = 80 px */
}

TEST(clipped_and_off)
{
    static struct shape s;
    s.n = 0, s.start[0] = 0;
    disc(&s, 0, 0, 10.5, 200); /* a quarter on the grid */
    check_mask(&s, 16, 16);
    s.n = 0, s.start[0] = 0;
    disc(&s, -50, 70, 10, 64);
    CHECK(check_mask(&s, 16, 16) == 0);
}

TEST(cap)
{
    /* a zigzag whose every edge spans every row: 4096 edges x 8192 rows = 2^25 crossings, twice the cap */
    static struct shape s;
    s.n = 0, s.start[0] = 0;
    for (int i = 0; i < MAX_PTS; i++)
        s.p[i][0] = i * 0.01, s.p[i][1] = i % 2 ? 5000 : -5000;
    s.start[++s.n] = MAX_PTS;
    struct trimesh_loops l = {s.p, s.start, s.n};
    unsigned char *mask = malloc(4 * 8192);
    struct sf_err err = {0};
    REQUIRE(mask);
    CHECK(raster_loops(&l, 4, 8192, mask, NULL, &err) == SF_ELIMIT);
    CHECK(err.code == SF_ELIMIT && strstr(err.message, "crosses"));
    CHECK(raster_loops(&l, 4, 1024, mask, NULL, NULL) == 0); /* 4096 x 1024 = 2^22: under it */
    free(mask);
}

int main(void)
{
    RUN(square);
    RUN(square_with_hole);
    RUN(triangle_and_shared_edge);
    RUN(disc_area);
    RUN(clipped_and_off);
    RUN(cap);
    UNIT_END();
}
