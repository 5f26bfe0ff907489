/* test_slice.c - sections of closed meshes by planes z = const (trimesh_slice): a cube's one square,
 * counter-clockwise; a marching-cubes ball cut through its vertices' own planes (where edge keys
 * alone would break the loops) and between them, one closed loop of the circle's area each. */
#include "../../../core/geom/trimesh.h"
#include "../../../core/iso/mc.h"

#include <stdbool.h>

#include "../../unit.h"

static double loop_area(const struct trimesh_loops *l, int k)
{
    double a = 0.0;
    for (int i = l->start[k]; i < l->start[k + 1]; i++) {
        int j = i + 1 < l->start[k + 1] ? i + 1 : l->start[k];
        a += l->p[i][0] * l->p[j][1] - l->p[j][0] * l->p[i][1];
    }
    return a / 2;
}

TEST(a_cube_gives_one_counter_clockwise_square)
{
    float pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
    uint32_t tri[] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
    struct trimesh m = {pos, NULL, tri, 8, 12};
    struct trimesh_loops l;
    struct sf_err err = {0};
    CHECK(trimesh_slice(&m, 0.5, &l, &err) == 0);
    CHECK(l.n == 1 && l.start[1] == 8); /* the side faces' diagonals cross it too: collinear points */
    if (l.n == 1)
        CHECK_NEAR(loop_area(&l, 0), 1.0, 1e-12);
    trimesh_loops_free(&l);
    CHECK(trimesh_slice(&m, 2.0, &l, &err) == 0 && l.n == 0);
    trimesh_loops_free(&l);
}

TEST(a_ball_cut_through_its_vertices_and_between)
{
    enum { N = 40 };
    static float s[N * N * N];
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++)
                s[x + N * (y + N * z)] = 30.0f - (float)sqrt((x - 19.5) * (x - 19.5) + (y - 19.5) * (y - 19.5) + (z - 19.5) * (z - 19.5));
    struct iso_grid g = {N, N, N, ISO_F32, s, {1, 1, 1}, {0, 0, 0}};
    struct iso_opts o = {.iso = 15.0, .closed = true};
    struct trimesh m;
    struct sf_err err = {0};
    int rc = iso_extract(&g, &o, NULL, &m, &err);
    if (rc)
        fprintf(stderr, "  %s\n", err.message);
    CHECK(rc == 0);
    for (int k = 0; k < 2; k++) {
        double z = 19.5 + (k ? 0.0 : 0.5); /* 20.0: a sample plane, through vertices; 19.5: between */
        double want = M_PI * (225.0 - (z - 19.5) * (z - 19.5));
        struct trimesh_loops l;
        CHECK(trimesh_slice(&m, z, &l, &err) == 0);
        fprintf(stderr, "  z %.1f: %d loops, %d points, area %.2f (circle %.2f)\n", z, l.n, l.n ? l.start[l.n] : 0,
                l.n ? loop_area(&l, 0) : 0.0, want);
        CHECK(l.n == 1);
        if (l.n == 1)
            CHECK(fabs(loop_area(&l, 0) / want - 1) < 0.02);
        trimesh_loops_free(&l);
    }
    trimesh_free(&m);
}

int main(void)
{
    iso_init();
    RUN(a_cube_gives_one_counter_clockwise_square);
    RUN(a_ball_cut_through_its_vertices_and_between);
    UNIT_END();
}
