/* test_sharp.c - seed 002's feature points (adapt.h, features=sharp): on FRep solids turned off the
 * grid's axes (a box, a cylinder, a box with a ball subtracted) every point of the true edges and
 * every corner lies on the mesh, which stays a closed 2-manifold at every level; plain marching
 * cubes is far off the same edges (the measure can fail); on sampled data (no field: normals from
 * the samples' differences, blurred across an edge) the features are kept closer than without; the same mesh whatever the order
 * of the slabs. */
#include "../../../core/iso/adapt.h"
#include "../../../core/iso/frep.h"

#include <stdbool.h>
#include <stdlib.h>

#include "../../unit.h"

#define PI 3.14159265358979323846

static struct frep_node nodes[16];
static struct frep tree = {nodes, 0, 0, NULL};
static const double ROT[3] = {20, 30, 10}; /* degrees about x, y, z */

static int add(struct frep_node n)
{
    nodes[tree.n] = n;
    tree.root = tree.n;
    return tree.n++;
}

/* the tree's root turned by ROT */
static void turned(void)
{
    struct frep_node t = {.kind = FREP_TRANSFORM, .a = tree.root};
    frep_transform(&t, (double[3]){1, 1, 1}, ROT, (double[3]){0, 0, 0});
    add(t);
}

/* x = R q for the turn of ROT (R = Rz Ry Rx) */
static void turn(const double q[3], double x[3])
{
    double c[3], s[3], v[3] = {q[0], q[1], q[2]};
    for (int i = 0; i < 3; i++)
        c[i] = cos(ROT[i] * PI / 180), s[i] = sin(ROT[i] * PI / 180);
    double y = c[0] * v[1] - s[0] * v[2], z = s[0] * v[1] + c[0] * v[2];
    v[1] = y, v[2] = z;
    double x0 = c[1] * v[0] + s[1] * v[2];
    z = -s[1] * v[0] + c[1] * v[2];
    v[0] = x0, v[2] = z;
    x[0] = c[2] * v[0] - s[2] * v[1], x[1] = s[2] * v[0] + c[2] * v[1], x[2] = v[2];
}

static double field(const void *ctx, const double p[3], double g[3])
{
    return frep_eval(ctx, p, g);
}

enum { N = 37 }; /* cells of 0.1 over [-1.8, 1.8]: about 1/20 of the solids */
static const double H = 0.1, ORG = -1.8;
static float samples[N * N * N];

static void sample(void)
{
    frep_sample(&tree, (double[3]){ORG, ORG, ORG}, H, N, N, 0, N, samples, NULL, NULL);
}

static bool extract(int levels, bool sharp, bool with_field, struct trimesh *m, struct trimesh_stats *st,
                    struct iso_adapt_stats *as)
{
    struct iso_grid g = {N, N, N, ISO_F32, samples, {H, H, H}, {ORG, ORG, ORG}};
    struct iso_opts o = {.closed = true, .normals = true, .sharp = sharp, .field = with_field ? field : NULL, .field_ctx = with_field ? &tree : NULL};
    struct sf_err err = {0};
    int rc = iso_extract_adaptive(&g, &o, levels, 0.5 * H, NULL, m, as, &err);
    if (!rc)
        rc = trimesh_stats(m, st, &err);
    if (rc)
        fprintf(stderr, "  extraction failed: %s\n", err.message);
    return rc == 0;
}

static bool closed_manifold(const struct trimesh_stats *st)
{
    bool ok = st->boundary_edges == 0 && st->nonmanifold_edges == 0;
    if (!ok)
        fprintf(stderr, "  boundary %ld, non-manifold %ld\n", st->boundary_edges, st->nonmanifold_edges);
    return ok;
}

/* distance from q (the solid's own frame, turned by ROT) to the mesh, in cells */
static double to_mesh(const struct trimesh *m, const double q[3])
{
    double p[3], best = INFINITY;
    turn(q, p);
    for (size_t t = 0; t < m->n_tri; t++) {
        double c[3][3];
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++)
                c[k][d] = m->pos[3 * m->tri[3 * t + k] + d];
        best = fmin(best, trimesh_point_dist(p, c[0], c[1], c[2]));
    }
    return best / H;
}

/* the worst distance of the points of segment a-b (every cell/8) */
static double segment_worst(const struct trimesh *m, const double a[3], const double b[3])
{
    double len = sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
    int n = (int)ceil(len / (H / 8));
    double worst = 0;
    for (int k = 0; k <= n; k++) {
        double q[3];
        for (int d = 0; d < 3; d++)
            q[d] = a[d] + (b[d] - a[d]) * k / n;
        worst = fmax(worst, to_mesh(m, q));
    }
    return worst;
}

/* The worst distance of the box's twelve edges and of its corners. */
static void box_edges(const struct trimesh *m, const double lo[3], const double hi[3], double *edges, double *corners)
{
    *edges = *corners = 0;
    for (int k = 0; k < 8; k++) {
        double c[3];
        for (int d = 0; d < 3; d++)
            c[d] = k >> d & 1 ? hi[d] : lo[d];
        *corners = fmax(*corners, to_mesh(m, c));
        for (int d = 0; d < 3; d++)
            if (!(k >> d & 1)) {
                double a[3] = {c[0], c[1], c[2]}, b[3] = {c[0], c[1], c[2]};
                a[d] = lo[d], b[d] = hi[d];
                *edges = fmax(*edges, segment_worst(m, a, b));
            }
    }
}

static const double BLO[3] = {-1, -0.7, -0.5}, BHI[3] = {1, 0.7, 0.5};

/* the box less a ball of radius 0.5 centred on its top face, turned, sampled */
static void box_minus_ball(void)
{
    tree.n = 0;
    int box = add((struct frep_node){.kind = FREP_BOX, .p = {BLO[0], BLO[1], BLO[2], BHI[0], BHI[1], BHI[2]}});
    int ball = add((struct frep_node){.kind = FREP_SPHERE, .p = {0.3, 0.1, 0.5, 0.5}});
    add((struct frep_node){.kind = FREP_SUBTRACT, .a = box, .b = ball, .alpha = 0});
    turned();
    sample();
}

TEST(a_turned_box_keeps_its_edges_and_corners)
{
    tree.n = 0;
    add((struct frep_node){.kind = FREP_BOX, .p = {BLO[0], BLO[1], BLO[2], BHI[0], BHI[1], BHI[2]}});
    turned();
    sample();
    size_t tris[4] = {0};
    for (int levels = 1; levels <= 3; levels++) {
        struct trimesh m;
        struct trimesh_stats st;
        struct iso_adapt_stats as;
        CHECK(extract(levels, true, true, &m, &st, &as));
        CHECK(closed_manifold(&st));
        CHECK(st.components == 1 && st.euler == 2);
        CHECK(as.feature_points > 0 && as.face_points > 0);
        double e, c;
        box_edges(&m, BLO, BHI, &e, &c);
        fprintf(stderr, "  levels %d: %zu triangles, edges within %.3f cells, corners %.3f, volume %+.4f %%\n", levels,
                m.n_tri, e, c, 100 * (st.volume / 2.8 - 1));
        tris[levels] = m.n_tri;
        CHECK(e <= 0.1);
        CHECK(c <= 0.2);
        CHECK(fabs(st.volume / 2.8 - 1) < 5e-4);
        trimesh_free(&m);
    }
    CHECK(tris[3] < tris[2] && tris[2] < tris[1]); /* the flat faces merge */
    struct trimesh m; /* the measure fails plain marching cubes */
    struct trimesh_stats st;
    struct iso_adapt_stats as;
    CHECK(extract(1, false, false, &m, &st, &as));
    double e, c;
    box_edges(&m, BLO, BHI, &e, &c);
    CHECK(e > 0.4 && c > 0.4);
    trimesh_free(&m);
}

TEST(a_cylinders_rims_and_a_balls_cut_lie_on_the_mesh)
{
    /* a cylinder of radius 0.6 along z from -0.5 to 0.5: its rims are two circles */
    tree.n = 0;
    add((struct frep_node){.kind = FREP_CYLINDER, .p = {0, 0, -0.5, 0, 0, 1, 0.6, 1}});
    turned();
    sample();
    struct trimesh m;
    struct trimesh_stats st;
    struct iso_adapt_stats as;
    CHECK(extract(1, true, true, &m, &st, &as));
    CHECK(closed_manifold(&st));
    double worst = 0;
    for (int k = 0; k < 240; k++)
        for (int cap = 0; cap < 2; cap++) {
            double q[3] = {0.6 * cos(2 * PI * k / 240), 0.6 * sin(2 * PI * k / 240), cap ? 0.5 : -0.5};
            worst = fmax(worst, to_mesh(&m, q));
        }
    fprintf(stderr, "  cylinder: rims within %.3f cells, volume %+.4f %%\n", worst, 100 * (st.volume / (PI * 0.36) - 1));
    CHECK(worst <= 0.1);
    CHECK(fabs(st.volume / (PI * 0.36) - 1) < 5e-3); /* the side's chords, 6 cells from the axis */
    trimesh_free(&m);

    box_minus_ball(); /* its cut is a circle of radius 0.5 */
    CHECK(extract(1, true, true, &m, &st, &as));
    CHECK(closed_manifold(&st));
    worst = 0;
    for (int k = 0; k < 120; k++) {
        double q[3] = {0.3 + 0.5 * cos(2 * PI * k / 120), 0.1 + 0.5 * sin(2 * PI * k / 120), 0.5};
        worst = fmax(worst, to_mesh(&m, q));
    }
    double e, c, exact = 2.8 - 2 * PI * 0.125 / 3;
    box_edges(&m, BLO, BHI, &e, &c);
    fprintf(stderr, "  box minus ball: cut within %.3f cells, edges %.3f, corners %.3f, volume %+.4f %%\n", worst, e, c,
            100 * (st.volume / exact - 1));
    CHECK(worst <= 0.1 && e <= 0.1 && c <= 0.2);
    CHECK(fabs(st.volume / exact - 1) < 3e-3); /* the ball's chords, 5 cells round */
    trimesh_free(&m);
}

TEST(sampled_data_keeps_features_closer_without_a_field)
{
    /* the turned box as samples only: feature points from the samples' gradients */
    tree.n = 0;
    add((struct frep_node){.kind = FREP_BOX, .p = {BLO[0], BLO[1], BLO[2], BHI[0], BHI[1], BHI[2]}});
    turned();
    sample();
    double mean[2];
    for (int sharp = 0; sharp < 2; sharp++) {
        struct trimesh m;
        struct trimesh_stats st;
        struct iso_adapt_stats as;
        CHECK(extract(1, sharp, false, &m, &st, &as));
        CHECK(closed_manifold(&st));
        double sum = 0;
        int n = 0;
        for (int k = 0; k <= 200; k++) { /* one long edge */
            double q[3] = {-0.9 + 1.8 * k / 200, BLO[1], BLO[2]};
            sum += to_mesh(&m, q), n++;
        }
        mean[sharp] = sum / n;
        trimesh_free(&m);
    }
    fprintf(stderr, "  samples only: mean distance of an edge %.3f cells plain, %.3f sharp\n", mean[0], mean[1]);
    CHECK(mean[1] < 0.8 * mean[0]);
}

TEST(the_same_mesh_whatever_the_order_of_the_slabs)
{
    box_minus_ball();
    struct iso_grid g = {N, N, N, ISO_F32, samples, {H, H, H}, {ORG, ORG, ORG}};
    struct iso_opts o = {.closed = true, .normals = true, .sharp = true, .field = field, .field_ctx = &tree};
    struct trimesh m[2];
    for (int run = 0; run < 2; run++) {
        struct iso_adapt *a;
        struct sf_err err = {0};
        CHECK(iso_adapt_begin(&g, &o, 2, 0.05, &a, &err) == 0);
        int n = iso_adapt_n_slabs(a);
        for (int p = 0; p < iso_adapt_phases(a); p++) {
            for (int k = 0; k < n; k++)
                iso_adapt_run(a, p, run ? n - 1 - k : k);
            iso_adapt_between(a, p);
        }
        struct iso_adapt_stats as;
        CHECK(iso_adapt_end(a, &m[run], &as, &err) == 0);
    }
    CHECK(m[0].n_vert == m[1].n_vert && m[0].n_tri == m[1].n_tri);
    CHECK(memcmp(m[0].pos, m[1].pos, 12 * m[0].n_vert) == 0);
    CHECK(memcmp(m[0].tri, m[1].tri, 12 * m[0].n_tri) == 0);
    trimesh_free(&m[0]);
    trimesh_free(&m[1]);
}

/* A solid's edge that grazes a cell edge between two samples of one side gives that edge a hidden
 * pair of crossings (adapt.c); when it only just pokes through, every face square round the edge
 * sees the pair alone, and each square joins it through its own isoline point, else two squares
 * drew one chord between the pair: an edge of four triangles. Box minus cylinder, as found by a
 * sweep of turns and cell sizes (the first at levels 3, the second at levels 1). */
TEST(an_edge_that_only_just_pokes_through_a_cell_edge_stays_manifold)
{
    static const struct {
        double rot[3], move[3], cell, lo[3];
        int n, levels;
    } cases[] = {
        {{20, 30, 11}, {0, 0, 0}, 0.15, {0, -2, -2}, 28, 3},
        {{53.376663315225166, 86.9823262449512, 74.44176436793649},
         {-0.041047550708231545, 0.0808701125823443, -0.09195770029965758}, 0.23, {-2.2, -2.2, -2.2}, 21, 1},
    };
    static float grid[28 * 28 * 28];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        tree.n = 0;
        int box = add((struct frep_node){.kind = FREP_BOX, .p = {0, -1, -1, 1, 1, 5}});
        int hole = add((struct frep_node){.kind = FREP_CYLINDER, .p = {0, 0, -2, 0, 0, 1, 0.5, 4}});
        add((struct frep_node){.kind = FREP_SUBTRACT, .a = box, .b = hole, .alpha = 0});
        struct frep_node t = {.kind = FREP_TRANSFORM, .a = tree.root};
        frep_transform(&t, (double[3]){1, 1, 1}, cases[i].rot, cases[i].move);
        add(t);
        int n = cases[i].n;
        double h = cases[i].cell;
        frep_sample(&tree, cases[i].lo, h, n, n, 0, n, grid, NULL, NULL);
        struct iso_grid g = {n, n, n, ISO_F32, grid, {h, h, h}, {cases[i].lo[0], cases[i].lo[1], cases[i].lo[2]}};
        struct iso_opts o = {.closed = true, .normals = true, .sharp = true, .field = field, .field_ctx = &tree};
        struct trimesh m;
        struct trimesh_stats st;
        struct iso_adapt_stats as;
        struct sf_err err = {0};
        CHECK(iso_extract_adaptive(&g, &o, cases[i].levels, 0.5 * h, NULL, &m, &as, &err) == 0);
        CHECK(trimesh_stats(&m, &st, &err) == 0);
        CHECK(closed_manifold(&st));
        CHECK(st.components == 1);
        trimesh_free(&m);
    }
}

int main(void)
{
    RUN(a_turned_box_keeps_its_edges_and_corners);
    RUN(a_cylinders_rims_and_a_balls_cut_lie_on_the_mesh);
    RUN(sampled_data_keeps_features_closer_without_a_field);
    RUN(the_same_mesh_whatever_the_order_of_the_slabs);
    RUN(an_edge_that_only_just_pokes_through_a_cell_edge_stays_manifold);
    UNIT_END();
}
