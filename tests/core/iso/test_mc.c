/* test_mc.c - the marching cubes of core/iso: closed, consistently oriented 2-manifolds on every
 * cell configuration and ambiguous face, on saddles, checkerboards and ties; the topology and
 * volume of analytic fields; the same mesh whatever the slabs; the CT crop against VTK. */
#include "../../../core/iso/mc.h"

#include <stdint.h>

#include "../../unit.h"

#define PI 3.14159265358979323846

/* Extracts g at iso (closed unless open) and measures it. */
static int run(const struct iso_grid *g, double iso, bool closed, struct trimesh *m, struct trimesh_stats *st)
{
    struct iso_opts o = {.iso = iso, .closed = closed, .normals = true};
    struct sf_err err = {0};
    int rc = iso_extract(g, &o, NULL, m, &err);
    if (!rc)
        rc = trimesh_stats(m, st, &err);
    if (rc)
        fprintf(stderr, "  extraction failed: %s\n", err.message);
    return rc;
}

static bool closed_manifold(const struct trimesh_stats *st)
{
    return st->boundary_edges == 0 && st->nonmanifold_edges == 0 && st->degenerate == 0;
}

static struct iso_grid float_grid(int n, float *v)
{
    return (struct iso_grid){n, n, n, ISO_F32, v, {1, 1, 1}, {0, 0, 0}};
}

static uint64_t rng = 88172645463325252ull;
static double uniform(void) /* xorshift64, in (0, 1) */
{
    rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
    return ((rng >> 11) + 0.5) / 9007199254740992.0;
}

/* Every corner state of one cell, with values drawn many times so that each ambiguous face is
 * decided both ways: closed manifold, positive volume where anything is inside. */
TEST(every_cell_configuration)
{
    int bad = 0, decided[2] = {0, 0};
    for (int c = 0; c < 256; c++)
        for (int draw = 0; draw < 40; draw++) {
            float v[8];
            for (int k = 0; k < 8; k++)
                v[k] = (float)((c >> k & 1 ? 1 : -1) * (0.05 + uniform()));
            struct iso_grid g = float_grid(2, v);
            struct trimesh m;
            struct trimesh_stats st;
            if (run(&g, 0, true, &m, &st) || !closed_manifold(&st) || (c && !(st.volume > 0)) ||
                (c == 0 && m.n_tri != 0) || st.euler % 2) {
                if (bad++ < 5)
                    fprintf(stderr, "  config 0x%02x draw %d: %zu tris, boundary %ld, nonmanifold %ld, degenerate %ld, "
                            "volume %g, euler %ld\n", c, draw, m.n_tri, st.boundary_edges, st.nonmanifold_edges,
                            st.degenerate, st.volume, st.euler);
            }
            /* which way the checkerboard's faces went, to see both are reached */
            if (c == 0x69)
                decided[st.components > 2]++;
            trimesh_free(&m);
        }
    CHECK(bad == 0);
    CHECK(decided[0] > 0 && decided[1] > 0);
}

/* MC33's interior ambiguity: two opposite corners in (no face ambiguous). Where the trilinear
 * interpolant is inside at the cell's centre they are one body through a tube, else two. */
TEST(interior_tunnel)
{
    for (int k = 0; k < 2; k++) {
        float rest = k ? -0.2f : -1.0f; /* centre (2 + 6 rest) / 8: 0.1 inside, or -0.5 outside */
        float v[8] = {1, rest, rest, rest, rest, rest, rest, 1};
        struct iso_grid g = float_grid(2, v);
        struct trimesh m;
        struct trimesh_stats st;
        CHECK(run(&g, 0, true, &m, &st) == 0);
        CHECK(closed_manifold(&st));
        CHECK(st.components == (k ? 1 : 2));
        CHECK(st.euler == (k ? 2 : 4));
        trimesh_free(&m);
    }
}

/* Random fields, saddles everywhere: closed, consistently oriented, even Euler characteristic. */
TEST(random_fields)
{
    int bad = 0;
    for (int trial = 0; trial < 200; trial++) {
        int n = 3 + trial % 5;
        float *v = malloc(sizeof *v * n * n * n);
        for (int k = 0; k < n * n * n; k++)
            v[k] = (float)(uniform() - 0.5);
        struct iso_grid g = float_grid(n, v);
        struct trimesh m;
        struct trimesh_stats st;
        if (run(&g, 0, true, &m, &st) || !closed_manifold(&st) || st.euler % 2 || !(st.volume > 0))
            bad++;
        trimesh_free(&m);
        free(v);
    }
    CHECK(bad == 0);
}

/* A checkerboard: every face of every cell ambiguous. */
TEST(checkerboard)
{
    enum { N = 9 };
    float v[N * N * N];
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++)
                v[x + N * (y + N * z)] = (x + y + z) % 2 ? 1.0f : -1.0f;
    struct iso_grid g = float_grid(N, v);
    struct trimesh m;
    struct trimesh_stats st;
    CHECK(run(&g, 0, true, &m, &st) == 0);
    CHECK(closed_manifold(&st));
    CHECK(st.volume > 0);
    trimesh_free(&m);
}

/* Integer samples with many equal to the iso value: no zero-area triangle, still closed. */
TEST(ties_at_the_iso_value)
{
    enum { N = 12 };
    int16_t v[N * N * N];
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++)
                v[x + N * (y + N * z)] = (int16_t)((x * 7 + y * 3 + z * 5) % 5); /* 0..4, iso 2 */
    struct iso_grid g = {N, N, N, ISO_I16, v, {1, 1, 1}, {0, 0, 0}};
    struct trimesh m;
    struct trimesh_stats st;
    CHECK(run(&g, 2, true, &m, &st) == 0);
    CHECK(closed_manifold(&st));
    CHECK(m.n_tri > 0);
    trimesh_free(&m);
}

/* samples of f(x, y, z) on an n^3 grid of spacing h centred on the origin */
static float *field(int n, double h, double (*f)(double, double, double), struct iso_grid *g)
{
    float *v = malloc(sizeof *v * (size_t)n * n * n);
    double o = -0.5 * (n - 1) * h;
    for (int z = 0; z < n; z++)
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++)
                v[x + n * (y + n * z)] = (float)f(o + x * h, o + y * h, o + z * h);
    *g = (struct iso_grid){n, n, n, ISO_F32, v, {h, h, h}, {o, o, o}};
    return v;
}

static double sphere(double x, double y, double z) { return 20 - sqrt(x * x + y * y + z * z); }
static double torus(double x, double y, double z)
{
    double q = sqrt(x * x + y * y) - 16;
    return 6 - sqrt(q * q + z * z);
}
static double two_spheres(double x, double y, double z)
{
    double a = 10 - sqrt((x - 13) * (x - 13) + y * y + z * z), b = 10 - sqrt((x + 13) * (x + 13) + y * y + z * z);
    return a > b ? a : b;
}
static double shell(double x, double y, double z) /* a sphere of radius 22 with a cavity of radius 12 */
{
    double r = sqrt(x * x + y * y + z * z);
    return fmin(22 - r, r - 12);
}

TEST(analytic_fields)
{
    static const struct {
        const char *name;
        double (*f)(double, double, double);
        long components, euler;
        double volume;
    } F[] = {
        {"sphere", sphere, 1, 2, 4.0 / 3 * PI * 20 * 20 * 20},
        {"torus", torus, 1, 0, 2 * PI * PI * 16 * 6 * 6},
        {"two spheres", two_spheres, 2, 4, 2 * 4.0 / 3 * PI * 1000},
        {"sphere with a cavity", shell, 2, 4, 4.0 / 3 * PI * (22 * 22 * 22 - 12 * 12 * 12)},
    };
    for (size_t k = 0; k < sizeof F / sizeof *F; k++) {
        struct iso_grid g;
        float *v = field(64, 0.8, F[k].f, &g);
        struct trimesh m;
        struct trimesh_stats st;
        CHECK(run(&g, 0, true, &m, &st) == 0);
        CHECK(closed_manifold(&st));
        if (st.components != F[k].components || st.euler != F[k].euler ||
            fabs(st.volume / F[k].volume - 1) > 0.01)
            fprintf(stderr, "  %s: components %ld, euler %ld, volume %.1f (exact %.1f)\n", F[k].name, st.components,
                    st.euler, st.volume, F[k].volume);
        CHECK(st.components == F[k].components);
        CHECK(st.euler == F[k].euler);
        CHECK_NEAR(st.volume / F[k].volume, 1, 0.01);
        /* normals from the gradient point outward: away from the sphere's centre */
        if (F[k].f == sphere) {
            double dot = 0;
            for (size_t i = 0; i < m.n_vert; i++)
                dot += m.nrm[3 * i] * m.pos[3 * i] + m.nrm[3 * i + 1] * m.pos[3 * i + 1] + m.nrm[3 * i + 2] * m.pos[3 * i + 2];
            CHECK(dot / m.n_vert > 19);
        }
        trimesh_free(&m);
        free(v);
    }
}

/* The mesh does not depend on how the slabs cut the grid (nor so on the thread count). */
TEST(same_mesh_whatever_the_slabs)
{
    struct iso_grid g;
    float *v = field(40, 1.1, torus, &g);
    struct trimesh m[2];
    for (int k = 0; k < 2; k++) {
        struct iso_job *j;
        struct iso_opts o = {.iso = 0, .closed = true, .normals = true};
        CHECK(iso_begin(&g, &o, k ? 7 : 1, &j, NULL) == 0);
        int n = iso_n_slabs(j);
        for (int s = n - 1; s >= 0; s--) /* any order */
            iso_count(j, s);
        CHECK(iso_layout(j, NULL) == 0);
        for (int s = 0; s < n; s++)
            iso_emit(j, (s * 3) % n == s ? s : n - 1 - s);
        CHECK(iso_end(j, &m[k], NULL) == 0);
    }
    CHECK(m[0].n_tri == m[1].n_tri && m[0].n_vert == m[1].n_vert);
    CHECK(memcmp(m[0].tri, m[1].tri, 3 * sizeof *m[0].tri * m[0].n_tri) == 0);
    CHECK(memcmp(m[0].pos, m[1].pos, 3 * sizeof *m[0].pos * m[0].n_vert) == 0);
    trimesh_free(&m[0]);
    trimesh_free(&m[1]);
    free(v);
}

/* Pass 1 reads the states in the samples' own type (a whole number over iso is over floor(iso)):
 * each integer type's mesh is that of the same values as floats, bit for bit, at isos between
 * samples, on them, and outside the type's range (every sample in: the closed grid's box; none:
 * no surface); rows of 37 samples (16 at a time, then one by one). */
TEST(every_sample_type_as_floats)
{
    enum { NX = 37, NY = 23, NZ = 19, N = NX * NY * NZ };
    static const enum iso_type types[3] = {ISO_U8, ISO_I16, ISO_U16};
    static const double lo[3] = {0, -32768, 0}, hi[3] = {255, 32767, 65535};
    float *f = malloc(N * sizeof *f);
    void *raw = malloc(N * sizeof(uint16_t));
    REQUIRE(f && raw);
    for (int t = 0; t < 3; t++) {
        for (int i = 0; i < N; i++) { /* a wave through the type's whole range, ends included */
            int x = i % NX, y = i / NX % NY, z = i / (NX * NY);
            double w = 0.5 + 0.5 * sin(0.45 * x + 0.3 * y) * cos(0.35 * z - 0.2 * x);
            double v = round(lo[t] + (hi[t] - lo[t]) * w);
            f[i] = (float)v;
            if (types[t] == ISO_U8)
                ((uint8_t *)raw)[i] = (uint8_t)v;
            else if (types[t] == ISO_I16)
                ((int16_t *)raw)[i] = (int16_t)v;
            else
                ((uint16_t *)raw)[i] = (uint16_t)v;
        }
        double mid = round((lo[t] + hi[t]) / 2);
        const double isos[6] = {mid + 0.5, mid, lo[t] + 1, lo[t] - 7.5, hi[t], hi[t] + 3};
        for (int k = 0; k < 6; k++) {
            struct iso_grid gi = {NX, NY, NZ, types[t], raw, {1, 0.5, 2}, {3, 0, -1}};
            struct iso_grid gf = {NX, NY, NZ, ISO_F32, f, {1, 0.5, 2}, {3, 0, -1}};
            struct iso_opts o = {.iso = isos[k], .closed = true, .normals = true};
            struct trimesh a, b;
            CHECK(iso_extract(&gi, &o, NULL, &a, NULL) == 0 && iso_extract(&gf, &o, NULL, &b, NULL) == 0);
            bool same = a.n_tri == b.n_tri && a.n_vert == b.n_vert &&
                        !memcmp(a.tri, b.tri, 3 * sizeof *a.tri * a.n_tri) &&
                        !memcmp(a.pos, b.pos, 3 * sizeof *a.pos * a.n_vert) &&
                        !memcmp(a.nrm, b.nrm, 3 * sizeof *a.nrm * a.n_vert);
            if (!same)
                fprintf(stderr, "  type %d iso %g: %zu / %zu triangles as floats\n", (int)types[t], isos[k], a.n_tri, b.n_tri);
            CHECK(same);
            CHECK(k <= 3 ? a.n_tri > 0 : a.n_tri == 0);
            trimesh_free(&a);
            trimesh_free(&b);
        }
    }
    free(f);
    free(raw);
}

/* closed=false leaves the surface open where it meets the border */
TEST(open_at_the_border)
{
    struct iso_grid g;
    float *v = field(20, 1.6, sphere, &g); /* half-width 15.2 < radius 20 < the corners at 26: cut by every face */
    struct trimesh m;
    struct trimesh_stats st;
    CHECK(run(&g, 0, false, &m, &st) == 0);
    if (!(st.boundary_edges > 0 && st.nonmanifold_edges == 0))
        fprintf(stderr, "  open: boundary %ld, nonmanifold %ld\n", st.boundary_edges, st.nonmanifold_edges);
    CHECK(st.boundary_edges > 0 && st.nonmanifold_edges == 0);
    trimesh_free(&m);
    CHECK(run(&g, 0, true, &m, &st) == 0);
    CHECK(closed_manifold(&st));
    trimesh_free(&m);
    free(v);
}

/* The shared CT crop at iso 226.5, padded: VTK's Flying Edges gives 34 996 triangles and
 * 57 560.5 mm^3 (../shared/data/volumes/README.md). */
TEST(ct_crop_against_vtk)
{
    size_t len;
    char *raw = unit_data("volumes", "ct_head_crop64_int16.raw", &len);
    CHECK(raw != NULL);
    if (!raw)
        return;
    CHECK(len == 64 * 64 * 64 * 2);
    struct iso_grid g = {64, 64, 64, ISO_I16, raw, {0.9570312, 0.9570312, 1.5}, {0, 0, 0}};
    struct trimesh m;
    struct trimesh_stats st;
    CHECK(run(&g, 226.5, true, &m, &st) == 0);
    CHECK(closed_manifold(&st));
    fprintf(stderr, "  CT crop: %zu triangles (VTK 34996), %.1f mm^3 (VTK 57560.5), %.1f mm^2 (VTK 16555.5)\n",
            m.n_tri, st.volume, st.area);
    CHECK(fabs((double)m.n_tri / 34996 - 1) < 0.02);
    CHECK(fabs(st.volume / 57560.5 - 1) < 0.002);
    trimesh_free(&m);
    free(raw);
}

int main(void)
{
    iso_init();
    RUN(every_cell_configuration);
    RUN(interior_tunnel);
    RUN(random_fields);
    RUN(checkerboard);
    RUN(ties_at_the_iso_value);
    RUN(analytic_fields);
    RUN(same_mesh_whatever_the_slabs);
    RUN(every_sample_type_as_floats);
    RUN(open_at_the_border);
    RUN(ct_crop_against_vtk);
    UNIT_END();
}
