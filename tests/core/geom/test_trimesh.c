/* test_trimesh.c - trimesh_stats' figures against meshes whose answers are known by hand: a
 * tetrahedron (closed, V - E + F = 2, its volume), an open square (four boundary edges), a book of
 * three triangles on one edge and two triangles that run the same way along theirs (each a
 * non-manifold edge), two tetrahedra apart (two components), a vertex no triangle uses (not
 * counted), and a torus of 20 000 triangles (closed, Euler characteristic 0, one component, its
 * volume 2 pi^2 R r^2 within the polygon's error): the large mesh's half-edges take the same path
 * as the CT head's millions. */
#include "../../../core/geom/trimesh.h"

#include <math.h>
#include <stdlib.h>

#include "../../unit.h"

static struct trimesh mesh(const float *pos, size_t nv, const uint32_t *tri, size_t nt)
{
    struct trimesh m = {0};
    m.pos = malloc(3 * nv * sizeof *m.pos);
    m.tri = malloc(3 * nt * sizeof *m.tri);
    for (size_t k = 0; k < 3 * nv; k++)
        m.pos[k] = pos[k];
    for (size_t k = 0; k < 3 * nt; k++)
        m.tri[k] = tri[k];
    m.n_vert = nv, m.n_tri = nt;
    return m;
}

static struct trimesh_stats stats_of(struct trimesh m)
{
    struct trimesh_stats st;
    struct sf_err err = {0};
    CHECK(trimesh_stats(&m, &st, &err) == 0);
    trimesh_free(&m);
    return st;
}

/* The unit tetrahedron's corners, a fifth vertex no triangle uses, and the tetrahedron again
 * moved by 5 in x (vertices 5 .. 8). */
static const float POS[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 9, 9, 9, 5, 0, 0, 6, 0, 0, 5, 1, 0, 5, 0, 1};
static const uint32_t TETRA[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};

TEST(a_tetrahedron_is_closed)
{
    struct trimesh_stats st = stats_of(mesh(POS, 4, TETRA, 4));
    CHECK(st.boundary_edges == 0 && st.nonmanifold_edges == 0);
    CHECK(st.components == 1 && st.euler == 2 && st.degenerate == 0);
    CHECK_NEAR(st.volume, 1.0 / 6, 1e-12);
    CHECK_NEAR(st.area, 1.5 + sqrt(3) / 2, 1e-6);
}

TEST(two_tetrahedra_and_a_vertex_unused)
{
    uint32_t tri[24];
    for (int k = 0; k < 12; k++)
        tri[k] = TETRA[k], tri[12 + k] = TETRA[k] + 5;
    struct trimesh_stats st = stats_of(mesh(POS, 9, tri, 8));
    CHECK(st.boundary_edges == 0 && st.nonmanifold_edges == 0);
    CHECK(st.components == 2 && st.euler == 4); /* (vertex 4 counted in neither) */
    CHECK_NEAR(st.volume, 2.0 / 6, 1e-12);
}

TEST(an_open_square_has_four_boundary_edges)
{
    static const uint32_t tri[] = {0, 1, 2, 1, 4, 2};
    static const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0};
    struct trimesh_stats st = stats_of(mesh(pos, 5, tri, 2));
    CHECK(st.boundary_edges == 4 && st.nonmanifold_edges == 0);
    CHECK(st.components == 1 && st.euler == 1); /* 4 - 5 + 2 (vertex 3 unused) */
}

TEST(a_book_and_a_misoriented_pair_are_not_manifold)
{
    static const uint32_t book[] = {0, 1, 2, 1, 0, 3, 0, 1, 4};
    struct trimesh_stats st = stats_of(mesh(POS, 5, book, 3));
    CHECK(st.nonmanifold_edges == 1 && st.boundary_edges == 6);
    static const uint32_t pair[] = {0, 1, 2, 0, 1, 3};
    st = stats_of(mesh(POS, 4, pair, 2));
    CHECK(st.nonmanifold_edges == 1 && st.boundary_edges == 4);
}

TEST(a_torus_of_twenty_thousand_triangles)
{
    enum { NU = 200, NV = 50 };
    const double R = 3, r = 1;
    float *pos = malloc(3 * NU * NV * sizeof *pos);
    uint32_t *tri = malloc(6 * NU * NV * sizeof *tri);
    for (int i = 0; i < NU; i++)
        for (int j = 0; j < NV; j++) {
            double u = 2 * M_PI * i / NU, v = 2 * M_PI * j / NV;
            float *p = pos + 3 * (i * NV + j);
            p[0] = (float)((R + r * cos(v)) * cos(u)), p[1] = (float)((R + r * cos(v)) * sin(u)), p[2] = (float)(r * sin(v));
            uint32_t a = (uint32_t)(i * NV + j), b = (uint32_t)((i + 1) % NU * NV + j);
            uint32_t c = (uint32_t)((i + 1) % NU * NV + (j + 1) % NV), d = (uint32_t)(i * NV + (j + 1) % NV);
            uint32_t *t = tri + 6 * (i * NV + j);
            t[0] = a, t[1] = b, t[2] = c, t[3] = a, t[4] = c, t[5] = d;
        }
    struct trimesh m = mesh(pos, NU * NV, tri, 2 * NU * NV);
    free(pos);
    free(tri);
    struct trimesh_stats st = stats_of(m);
    CHECK(st.boundary_edges == 0 && st.nonmanifold_edges == 0);
    CHECK(st.components == 1 && st.euler == 0);
    CHECK_NEAR(fabs(st.volume), 2 * M_PI * M_PI * R * r * r, 0.01 * 2 * M_PI * M_PI * R * r * r);
}

int main(void)
{
    RUN(a_tetrahedron_is_closed);
    RUN(two_tetrahedra_and_a_vertex_unused);
    RUN(an_open_square_has_four_boundary_edges);
    RUN(a_book_and_a_misoriented_pair_are_not_manifold);
    RUN(a_torus_of_twenty_thousand_triangles);
    UNIT_END();
}
