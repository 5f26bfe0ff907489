/* test_adapt.c - the adaptive hierarchy of core/iso (adapt.h): a closed, consistently oriented
 * 2-manifold at every mix of levels (analytic fields, random fields, the shared CT crop), levels
 * that really mix, the error against an analytic surface, the same mesh twice, max_error 0
 * keeping marching cubes' vertices, and max_error bounding the distance of every marching-cubes
 * vertex to the mesh (the CT crop, smooth random fields with noise). */
#include "../../../core/iso/adapt.h"

#include <stdbool.h>
#include <stdint.h>

#include "../../unit.h"

static bool extract(const struct iso_grid *g, double iso, int levels, double max_error, struct trimesh *m,
                    struct trimesh_stats *st, struct iso_adapt_stats *as)
{
    struct iso_opts o = {.iso = iso, .closed = true, .normals = true};
    struct sf_err err = {0};
    int rc = iso_extract_adaptive(g, &o, levels, max_error, NULL, m, as, &err);
    if (!rc)
        rc = trimesh_stats(m, st, &err);
    if (rc)
        fprintf(stderr, "  extraction failed: %s\n", err.message);
    return rc == 0;
}

static bool closed_manifold(const struct trimesh_stats *st)
{
    bool ok = st->boundary_edges == 0 && st->nonmanifold_edges == 0 && st->degenerate == 0;
    if (!ok)
        fprintf(stderr, "  boundary %ld, non-manifold %ld, degenerate %ld\n", st->boundary_edges, st->nonmanifold_edges,
                st->degenerate);
    return ok;
}

static struct iso_grid grid(int n, const float *v, double h)
{
    return (struct iso_grid){n, n, n, ISO_F32, v, {h, h, h}, {0, 0, 0}};
}

static double rnd(void)
{
    static unsigned long long s = 0x9e3779b97f4a7c15ull;
    s ^= s << 13, s ^= s >> 7, s ^= s << 17;
    return (double)(s >> 11) / 9007199254740992.0;
}

/* a sphere's distance field, a torus's, and a wavy field of many pieces */
enum { N = 41 };
static float field[3][N * N * N];
static void fields(void)
{
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++) {
                double p[3] = {x - 20.3, y - 19.7, z - 20.1}, r = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
                double q = sqrt(p[0] * p[0] + p[1] * p[1]) - 11;
                size_t at = (size_t)x + N * ((size_t)y + N * z);
                field[0][at] = (float)(15 - r);
                field[1][at] = (float)(4.5 - sqrt(q * q + p[2] * p[2]));
                field[2][at] = (float)(sin(x * 0.37) * cos(y * 0.29) + sin(z * 0.41 + x * 0.1) - 0.2);
            }
}

TEST(closed_at_every_mix_of_levels)
{
    fields();
    const double errs[] = {0, 0.05, 0.3, 1, 1e9};
    for (int f = 0; f < 3; f++)
        for (int levels = 2; levels <= ISO_MAX_LEVELS; levels++)
            for (int e = 0; e < 5; e++) {
                struct iso_grid g = grid(N, field[f], 1);
                struct trimesh m;
                struct trimesh_stats st;
                struct iso_adapt_stats as;
                CHECK(extract(&g, 0, levels, errs[e], &m, &st, &as));
                CHECK(closed_manifold(&st));
                CHECK(st.euler % 2 == 0);
                if (f < 2 && errs[e] <= 1) /* (a huge error may close the torus's hole) */
                    CHECK(st.components == 1 && st.euler == (f == 0 ? 2 : 0));
                trimesh_free(&m);
            }
}

TEST(levels_really_mix)
{
    struct iso_grid g = grid(N, field[2], 1);
    struct trimesh m;
    struct trimesh_stats st;
    struct iso_adapt_stats as;
    CHECK(extract(&g, 0, 4, 0.3, &m, &st, &as));
    CHECK(as.cells[1] > 0 && as.cells[2] > 0 && as.cells[3] > 0);
    CHECK(as.max_estimate <= 0.3);
    trimesh_free(&m);
    g = grid(N, field[0], 1); /* the sphere, coarse cells all over: fewer triangles, level by level */
    size_t prev = SIZE_MAX;
    for (int levels = 1; levels <= 4; levels++) {
        CHECK(extract(&g, 0, levels, 1e9, &m, &st, &as));
        CHECK(m.n_tri < prev);
        prev = m.n_tri;
        trimesh_free(&m);
    }
}

TEST(random_fields)
{
    enum { R = 17 };
    static float v[R * R * R];
    for (int t = 0; t < 30; t++) {
        for (int k = 0; k < R * R * R; k++)
            v[k] = (float)(rnd() < 0.5 ? rnd() : -rnd());
        if (t % 3 == 1) /* ties: samples equal to iso */
            for (int k = 0; k < R * R * R; k += 7)
                v[k] = 0;
        struct iso_grid g = grid(R, v, 0.5 + t * 0.1);
        for (int levels = 2; levels <= 4; levels++) {
            struct trimesh m;
            struct trimesh_stats st;
            struct iso_adapt_stats as;
            CHECK(extract(&g, 0, levels, t % 2 ? 1e9 : 0.2, &m, &st, &as));
            CHECK(closed_manifold(&st));
            trimesh_free(&m);
        }
    }
}

TEST(within_max_error_of_the_sphere)
{
    /* a sphere of radius 15 sampled with spacing 0.5 mm: every vertex within max_error (plus the
     * full-resolution surface's own error) of it */
    struct iso_grid g = grid(N, field[0], 0.5);
    for (double me = 0.05; me < 0.6; me *= 2) {
        struct trimesh m;
        struct trimesh_stats st;
        struct iso_adapt_stats as;
        CHECK(extract(&g, 0, 3, me, &m, &st, &as));
        double worst = 0;
        for (size_t v = 0; v < m.n_vert; v++) {
            double p[3];
            for (int d = 0; d < 3; d++)
                p[d] = m.pos[3 * v + d] / 0.5 - (d == 0 ? 20.3 : d == 1 ? 19.7 : 20.1);
            double r = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            worst = fmax(worst, fabs(r - 15) * 0.5);
        }
        CHECK(worst <= me + 0.01);
        CHECK(as.cells[2] + as.cells[3] > 0);
        trimesh_free(&m);
    }
}

static int cmp3(const void *p, const void *q)
{
    const float *a = p, *b = q;
    for (int d = 0; d < 3; d++)
        if (a[d] != b[d])
            return a[d] < b[d] ? -1 : 1;
    return 0;
}

TEST(the_same_mesh_twice_and_mc_at_zero_error)
{
    struct iso_grid g = grid(N, field[1], 1);
    struct trimesh a, b, mc;
    struct trimesh_stats sa, sb, smc;
    struct iso_adapt_stats as;
    CHECK(extract(&g, 0, 3, 0.2, &a, &sa, &as));
    CHECK(extract(&g, 0, 3, 0.2, &b, &sb, &as));
    CHECK(a.n_tri == b.n_tri && a.n_vert == b.n_vert);
    CHECK(!memcmp(a.tri, b.tri, 3 * sizeof *a.tri * a.n_tri) && !memcmp(a.pos, b.pos, 3 * sizeof *a.pos * a.n_vert));
    trimesh_free(&a);
    trimesh_free(&b);
    /* at max_error 0 only blocks whose every full-resolution vertex lies on the merged cell's
     * polygon merge: every vertex is marching cubes' own, the volume marching cubes' */
    struct sf_err err = {0};
    struct iso_opts o = {.iso = 0, .closed = true, .normals = true};
    CHECK(extract(&g, 0, 4, 0, &a, &sa, &as));
    CHECK(iso_extract(&g, &o, NULL, &mc, &err) == 0 && trimesh_stats(&mc, &smc, &err) == 0);
    CHECK(a.n_tri <= mc.n_tri && a.n_vert <= mc.n_vert);
    qsort(mc.pos, mc.n_vert, 3 * sizeof *mc.pos, cmp3);
    for (size_t v = 0; v < a.n_vert; v++)
        CHECK(bsearch(a.pos + 3 * v, mc.pos, mc.n_vert, 3 * sizeof *mc.pos, cmp3) != NULL);
    CHECK_NEAR(sa.volume, smc.volume, 1e-3 * smc.volume);
    trimesh_free(&a);
    trimesh_free(&mc);
}

/* the phases' slabs in reverse order (as threads may take them): the same mesh, byte for byte */
TEST(the_same_mesh_whatever_the_order_of_the_slabs)
{
    struct iso_grid g = grid(N, field[2], 1);
    struct iso_opts o = {.iso = 0, .closed = true, .normals = true};
    struct trimesh fw, bw;
    struct trimesh_stats st;
    struct iso_adapt_stats as;
    struct sf_err err = {0};
    CHECK(extract(&g, 0, 4, 0.3, &fw, &st, &as));
    struct iso_adapt *a;
    CHECK(iso_adapt_begin(&g, &o, 4, 0.3, &a, &err) == 0);
    CHECK(iso_adapt_n_slabs(a) > 2);
    for (int p = 0; p < iso_adapt_phases(a); p++) {
        for (int s = iso_adapt_n_slabs(a) - 1; s >= 0; s--)
            iso_adapt_run(a, p, s);
        iso_adapt_between(a, p);
    }
    CHECK(iso_adapt_end(a, &bw, &as, &err) == 0);
    CHECK(fw.n_tri == bw.n_tri && fw.n_vert == bw.n_vert);
    CHECK(!memcmp(fw.tri, bw.tri, 3 * sizeof *fw.tri * fw.n_tri) && !memcmp(fw.pos, bw.pos, 3 * sizeof *fw.pos * fw.n_vert));
    trimesh_free(&fw);
    trimesh_free(&bw);
}

/* The shared CT crop (64^3 int16) as a grid; its samples (to free), or NULL (a failed check). */
static char *ct_crop(struct iso_grid *g)
{
    size_t len;
    char *raw = unit_data("volumes", "ct_head_crop64_int16.raw", &len);
    CHECK(raw && len == 64 * 64 * 64 * 2);
    if (raw && len != 64 * 64 * 64 * 2) {
        free(raw);
        raw = NULL;
    }
    *g = (struct iso_grid){64, 64, 64, ISO_I16, raw, {0.9570312, 0.9570312, 1.5}, {0, 0, 0}};
    return raw;
}

TEST(ct_crop_at_every_level)
{
    struct iso_grid g;
    char *raw = ct_crop(&g);
    if (!raw)
        return;
    for (int levels = 2; levels <= 4; levels++)
        for (double me = 0.25; me <= 4; me *= 4) {
            struct trimesh m;
            struct trimesh_stats st;
            struct iso_adapt_stats as;
            CHECK(extract(&g, 226.5, levels, me, &m, &st, &as));
            CHECK(closed_manifold(&st));
            CHECK(as.cells[2] > 0);
            trimesh_free(&m);
        }
    free(raw);
}

/* The largest distance from a vertex of mesh from to mesh to (brute force over the triangles whose
 * box, grown by reach, holds the vertex: bucketed in a grid of cells of size reach; a vertex
 * farther than reach from every triangle counts as INFINITY). */
static double farthest(const struct trimesh *from, const struct trimesh *to, double reach)
{
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < to->n_vert; v++)
        for (int d = 0; d < 3; d++)
            lo[d] = fminf(lo[d], to->pos[3 * v + d]), hi[d] = fmaxf(hi[d], to->pos[3 * v + d]);
    int n[3];
    for (int d = 0; d < 3; d++)
        n[d] = (int)((hi[d] - lo[d]) / reach) + 3;
    size_t cells = (size_t)n[0] * n[1] * n[2], *first = calloc(cells + 1, sizeof *first), *list = NULL;
#define CELL(p, d) ((int)(((p) - lo[d]) / reach) + 1)
    for (int pass = 0; pass < 2; pass++) {
        for (size_t t = 0; t < to->n_tri; t++) {
            int c0[3], c1[3];
            for (int d = 0; d < 3; d++) {
                float a = INFINITY, b = -INFINITY;
                for (int k = 0; k < 3; k++)
                    a = fminf(a, to->pos[3 * to->tri[3 * t + k] + d]), b = fmaxf(b, to->pos[3 * to->tri[3 * t + k] + d]);
                c0[d] = CELL(a, d) - 1, c1[d] = CELL(b, d) + 1;
            }
            for (int z = c0[2]; z <= c1[2]; z++)
                for (int y = c0[1]; y <= c1[1]; y++)
                    for (int x = c0[0]; x <= c1[0]; x++) {
                        size_t at = (size_t)x + (size_t)n[0] * ((size_t)y + (size_t)n[1] * z);
                        if (pass == 0)
                            first[at + 1]++;
                        else
                            list[first[at]++] = t;
                    }
        }
        if (pass == 0) {
            for (size_t c = 0; c < cells; c++)
                first[c + 1] += first[c];
            list = malloc((first[cells] + 1) * sizeof *list);
        } else {
            for (size_t c = cells; c > 0; c--) /* (the second pass moved each start to its end) */
                first[c] = first[c - 1];
            first[0] = 0;
        }
    }
    double worst = 0;
    for (size_t v = 0; v < from->n_vert; v++) {
        double p[3], best = INFINITY;
        int c[3];
        for (int d = 0; d < 3; d++) {
            p[d] = from->pos[3 * v + d];
            c[d] = CELL(from->pos[3 * v + d], d);
            c[d] = c[d] < 0 ? 0 : c[d] >= n[d] ? n[d] - 1 : c[d];
        }
        size_t at = (size_t)c[0] + (size_t)n[0] * ((size_t)c[1] + (size_t)n[1] * c[2]);
        for (size_t k = first[at]; k < first[at + 1]; k++) {
            double q[3][3];
            for (int j = 0; j < 3; j++)
                for (int d = 0; d < 3; d++)
                    q[j][d] = to->pos[3 * to->tri[3 * list[k] + j] + d];
            best = fmin(best, trimesh_point_dist(p, q[0], q[1], q[2]));
        }
        worst = fmax(worst, best);
    }
#undef CELL
    free(first);
    free(list);
    return worst;
}

/* max_error bounds the real distance: every vertex of the full-resolution mesh (marching cubes'
 * own) lies within it of the adaptive mesh, on the CT crop at levels 2 and 3, wherever merged
 * cells meet finer ones (their faces cut at the finer resolution) */
TEST(every_full_resolution_vertex_within_max_error)
{
    struct iso_grid g;
    char *raw = ct_crop(&g);
    if (!raw)
        return;
    struct iso_opts o = {.iso = 226.5, .closed = true, .normals = true};
    struct trimesh mc;
    struct sf_err err = {0};
    CHECK(iso_extract(&g, &o, NULL, &mc, &err) == 0);
    for (int levels = 2; levels <= 3; levels++)
        for (double me = 0.25; me <= 1; me *= 2) {
            struct trimesh m;
            struct trimesh_stats st;
            struct iso_adapt_stats as;
            CHECK(extract(&g, 226.5, levels, me, &m, &st, &as));
            double far = farthest(&mc, &m, 2 * me);
            fprintf(stderr, "  levels %d max_error %.2f: %zu triangles of %zu, farthest vertex %.4f\n", levels, me,
                    m.n_tri, mc.n_tri, far);
            CHECK(far <= me * (1 + 1e-6) + 1e-5); /* (float positions) */
            CHECK(as.cells[2] > 0);
            trimesh_free(&m);
        }
    trimesh_free(&mc);
    free(raw);
    /* and on smooth random fields with noise (many merged cells next to finer ones, paths that
     * cross their chords, faces whose nine nodes decide) */
    enum { R = 33 };
    static float v[R * R * R];
    for (int t = 0; t < 6; t++) {
        double k[4][3], ph[4];
        for (int i = 0; i < 4; i++) {
            for (int d = 0; d < 3; d++)
                k[i][d] = (rnd() - 0.5) * 0.8;
            ph[i] = rnd() * 6.28;
        }
        for (int z = 0; z < R; z++)
            for (int y = 0; y < R; y++)
                for (int x = 0; x < R; x++) {
                    double f = 0.1 * (rnd() - 0.5);
                    for (int i = 0; i < 4; i++)
                        f += sin(k[i][0] * x + k[i][1] * y + k[i][2] * z + ph[i]);
                    v[x + R * (y + R * z)] = (float)f;
                }
        struct iso_grid rg = grid(R, v, 1);
        CHECK(iso_extract(&rg, &(struct iso_opts){.iso = 0, .closed = true, .normals = true}, NULL, &mc, &err) == 0);
        for (int levels = 2; levels <= 3; levels++) {
            struct trimesh m;
            struct trimesh_stats st;
            struct iso_adapt_stats as;
            double me = 0.2 + 0.2 * (t % 3);
            CHECK(extract(&rg, 0, levels, me, &m, &st, &as));
            CHECK(closed_manifold(&st));
            double far = farthest(&mc, &m, 2 * me);
            if (!(far <= me * (1 + 1e-6) + 1e-5))
                fprintf(stderr, "  random field %d, levels %d: farthest vertex %.4f over max_error %.2f\n", t, levels, far, me);
            CHECK(far <= me * (1 + 1e-6) + 1e-5);
            trimesh_free(&m);
        }
        trimesh_free(&mc);
    }
}

int main(void)
{
    iso_init();
    RUN(closed_at_every_mix_of_levels);
    RUN(levels_really_mix);
    RUN(random_fields);
    RUN(within_max_error_of_the_sphere);
    RUN(the_same_mesh_twice_and_mc_at_zero_error);
    RUN(the_same_mesh_whatever_the_order_of_the_slabs);
    RUN(ct_crop_at_every_level);
    RUN(every_full_resolution_vertex_within_max_error);
    UNIT_END();
}
