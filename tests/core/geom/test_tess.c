/* test_tess.c - tessellations sized per patch: a flat patch beside a curved one sharing an edge
 * gets a coarser grid, and the curved one's extra vertices along that edge lie on the flat one's
 * chords (no crack), which a grid of the patch's own would not be; patches sharing only their end points (two halves of a circle between the
 * same points) are not taken for neighbours. */
#include "../../../core/geom/tess.h"

#include "../../unit.h"

/* A bicubic patch over [x0, x0 + 1] x [0, 1], its control points at height bump inside along u. */
static void make(struct patch *pt, double (*cw)[4], double x0, double bump)
{
    *pt = (struct patch){.p = 3, .q = 3, .rational = false, .cw = cw, .u0 = 0, .u1 = 1, .v0 = 0, .v1 = 1};
    for (int i = 0; i <= 3; i++)
        for (int j = 0; j <= 3; j++) {
            double *c = cw[i * 4 + j];
            c[0] = x0 + i / 3.0, c[1] = j / 3.0, c[2] = (i == 1 || i == 2) ? bump : 0.0, c[3] = 1.0;
        }
}

static double dist_to_chords(const struct tess *t, int patch, double x, vec3 q)
{
    /* the coarse patch's vertices along its side x: the chords between consecutive ones */
    double best = INFINITY;
    vec3 prev = v3(NAN, NAN, NAN);
    for (size_t k = 0; k < t->n_verts; k++) {
        if (t->patch[k] != patch || fabs(t->pos[k][0] - x) > 1e-12)
            continue;
        vec3 p = v3(t->pos[k][0], t->pos[k][1], t->pos[k][2]);
        if (isfinite(prev.x)) {
            vec3 d = v3_sub(p, prev);
            double f = fmin(1, fmax(0, v3_dot(v3_sub(q, prev), d) / v3_dot(d, d)));
            best = fmin(best, v3_len(v3_sub(q, v3_mad(prev, d, f))));
        }
        prev = p;
    }
    return best;
}

TEST(a_milder_neighbour_is_coarser_and_the_shared_edge_has_no_crack)
{
    double cw[2][16][4];
    struct patch pts[2];
    make(&pts[0], cw[0], 0.0, 0.0);
    make(&pts[1], cw[1], 1.0, 0.0); /* its u = 0 side is the first one's u = 1 side */
    /* both bowed a little along v (the shared edge too), the second one much more inside */
    for (int i = 0; i <= 3; i++)
        for (int j = 1; j <= 2; j++)
            cw[0][i * 4 + j][2] = 0.05, cw[1][i * 4 + j][2] = i ? 0.8 : 0.05;
    struct tess t;
    CHECK(tess_build(pts, 2, 1e-3, TESS_MAX_SIDE, &t) == 0);
    size_t n0 = 0, n1 = 0;
    for (size_t k = 0; k < t.n_verts; k++)
        n0 += t.patch[k] == 0, n1 += t.patch[k] == 1;
    fprintf(stderr, "  the mild patch %zu vertices, the curved one %zu\n", n0, n1);
    CHECK(n0 < n1);
    double worst = 0;
    for (size_t k = 0; k < t.n_verts; k++)
        if (t.patch[k] == 1 && fabs(t.pos[k][0] - 1.0) < 1e-12)
            worst = fmax(worst, dist_to_chords(&t, 0, 1.0, v3(t.pos[k][0], t.pos[k][1], t.pos[k][2])));
    double off = 0; /* the same vertices where the curved patch itself has them: off the chords */
    for (size_t k = 0; k < t.n_verts; k++)
        if (t.patch[k] == 1 && fabs(t.pos[k][0] - 1.0) < 1e-12) {
            vec3 P;
            bezier_eval(&pts[1], t.uv[k][0], t.uv[k][1], &P, NULL, NULL);
            off = fmax(off, dist_to_chords(&t, 0, 1.0, P));
        }
    fprintf(stderr, "  on the chords within %.1e; unsnapped they would be %.1e off\n", worst, off);
    CHECK(worst < 1e-12 && off > 1e-5);
    tess_free(&t);
}

TEST(two_halves_of_a_circle_are_not_neighbours)
{
    /* two bilinear-in-v strips whose u = 0 sides join the same two points by different curves */
    double cw[2][16][4];
    struct patch pts[2];
    make(&pts[0], cw[0], 0.0, 0.0);
    make(&pts[1], cw[1], 0.0, 0.0);
    for (int j = 0; j <= 3; j++) { /* side u = 0 of each: bowed up in one, down in the other */
        cw[0][j][2] = (j == 1 || j == 2) ? 0.5 : 0.0;
        cw[1][j][2] = (j == 1 || j == 2) ? -0.5 : 0.0;
    }
    for (int i = 1; i <= 3; i++) /* the second patch is otherwise flat and far: a coarse grid */
        for (int j = 0; j <= 3; j++)
            cw[1][i * 4 + j][0] = -i / 3.0;
    struct tess t;
    CHECK(tess_build(pts, 2, 1e-3, TESS_MAX_SIDE, &t) == 0);
    /* every vertex of both lies on its own patch: none moved onto the other's chords */
    double worst = 0;
    for (size_t k = 0; k < t.n_verts; k++) {
        vec3 P;
        bezier_eval(&pts[t.patch[k]], t.uv[k][0], t.uv[k][1], &P, NULL, NULL);
        if (fabs(t.pos[k][0]) < 1e-12) /* the u = 0 sides */
            worst = fmax(worst, v3_len(v3_sub(P, v3(t.pos[k][0], t.pos[k][1], t.pos[k][2]))));
    }
    CHECK(worst < 1e-6);
    tess_free(&t);
}

int main(void)
{
    RUN(a_milder_neighbour_is_coarser_and_the_shared_edge_has_no_crack);
    RUN(two_halves_of_a_circle_are_not_neighbours);
    UNIT_END();
}
