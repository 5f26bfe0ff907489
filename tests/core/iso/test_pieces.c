/* test_pieces.c - the adaptive hierarchy's merge=pieces mode (core/iso/adapt_pieces.c): on analytic
 * fields (a sphere, a torus, a thin plate, a thin tube, a wavy field of many pieces) and the shared
 * CT crop, every mesh closed, a 2-manifold, of the full-resolution mesh's components and Euler
 * characteristic, within max_error of it both ways measured densely here (points at quarters of
 * every triangle of each mesh against the other's triangles, by this file's own distance), fewer
 * triangles, the same on 1 and 2 threads and in any slab order, and edits equal to a fresh
 * extraction with the ids of kept.h. */
#include "../../../core/iso/adapt.h"
#include "../../../core/iso/kept.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>

#include "../../unit.h"

enum { N = 41 };

static void field_of(int kind, float *f, int n)
{
    for (int z = 0; z < n; z++)
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                double p[3] = {x - 20.3, y - 19.7, z - 20.1}, r = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
                double q = sqrt(p[0] * p[0] + p[1] * p[1]) - 11, v;
                if (kind == 0) /* a sphere of radius 15 */
                    v = 15 - r;
                else if (kind == 1) /* a torus */
                    v = 4.5 - sqrt(q * q + p[2] * p[2]);
                else if (kind == 2) /* a plate 0.7 samples thick, tilted, 30 wide */
                    v = fmin(0.35 - fabs(0.94 * p[2] + 0.34 * p[0]), fmin(15 - fabs(p[0]), 15 - fabs(p[1])));
                else if (kind == 3) /* a tube of radius 0.6 bent round a circle, and a ball it runs into */
                    v = fmax(0.6 - sqrt(q * q + p[2] * p[2]), 6 - sqrt((p[0] - 11) * (p[0] - 11) + p[1] * p[1] + p[2] * p[2]));
                else /* a wavy field of many pieces */
                    v = sin(x * 0.37) * cos(y * 0.29) + sin(z * 0.41 + x * 0.1) - 0.2;
                f[(size_t)x + (size_t)n * ((size_t)y + (size_t)n * z)] = (float)v;
            }
}

static struct iso_grid grid(int n, const float *v, double h)
{
    return (struct iso_grid){n, n, n, ISO_F32, v, {h, h, h}, {0, 0, 0}};
}

static struct iso_opts pieces_opts(double iso)
{
    return (struct iso_opts){.iso = iso, .closed = true, .normals = true, .pieces = true};
}

/* ---- an independent two-way distance ---- */

/* The distance from p to triangle abc: the nearest of its inside (by the plane) and its edges. */
static double seg_dist(const double p[3], const double a[3], const double b[3])
{
    double d[3], w[3], dd = 0, t = 0;
    for (int k = 0; k < 3; k++)
        d[k] = b[k] - a[k], w[k] = p[k] - a[k], dd += d[k] * d[k], t += d[k] * w[k];
    t = dd > 0 ? fmin(1, fmax(0, t / dd)) : 0;
    double s = 0;
    for (int k = 0; k < 3; k++)
        s += (w[k] - t * d[k]) * (w[k] - t * d[k]);
    return sqrt(s);
}

static double tri_dist(const double p[3], const double a[3], const double b[3], const double c[3])
{
    double u[3], v[3], n[3], w[3];
    for (int k = 0; k < 3; k++)
        u[k] = b[k] - a[k], v[k] = c[k] - a[k], w[k] = p[k] - a[k];
    n[0] = u[1] * v[2] - u[2] * v[1], n[1] = u[2] * v[0] - u[0] * v[2], n[2] = u[0] * v[1] - u[1] * v[0];
    double nn = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    if (nn > 0) { /* inside the prism over the triangle: the plane's distance */
        double h = (w[0] * n[0] + w[1] * n[1] + w[2] * n[2]) / nn, q[3];
        for (int k = 0; k < 3; k++)
            q[k] = p[k] - h * n[k];
        double e0[3], e1[3], e2[3], c0[3], c1[3], c2[3];
        bool in = true;
        const double *A[3] = {a, b, c};
        for (int k = 0; k < 3 && in; k++) {
            const double *s = A[k], *t = A[(k + 1) % 3];
            for (int d = 0; d < 3; d++)
                e0[d] = t[d] - s[d], e1[d] = q[d] - s[d];
            c0[0] = e0[1] * e1[2] - e0[2] * e1[1], c0[1] = e0[2] * e1[0] - e0[0] * e1[2], c0[2] = e0[0] * e1[1] - e0[1] * e1[0];
            in = c0[0] * n[0] + c0[1] * n[1] + c0[2] * n[2] >= 0;
        }
        (void)e2, (void)c1, (void)c2;
        if (in)
            return fabs(h) * sqrt(nn);
    }
    return fmin(seg_dist(p, a, b), fmin(seg_dist(p, b, c), seg_dist(p, c, a)));
}

/* The largest distance from the points at quarters (barycentric steps of 1/4) of every triangle of
 * from to the surface of to (reach at most: a point farther than reach from every triangle counts
 * as reach), the triangles of to binned in a grid of cells of side reach by their boxes; a triangle
 * whose box is no nearer than the nearest so far is passed over (it cannot be nearer). */
static double farthest_dense(const struct trimesh *from, const struct trimesh *to, double reach)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, worst = 0;
    for (size_t v = 0; v < to->n_vert; v++)
        for (int d = 0; d < 3; d++)
            lo[d] = fmin(lo[d], to->pos[3 * v + d] - 2 * reach);
    int nb[3];
    double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < to->n_vert; v++)
        for (int d = 0; d < 3; d++)
            hi[d] = fmax(hi[d], to->pos[3 * v + d] + 2 * reach);
    for (int d = 0; d < 3; d++)
        nb[d] = (int)((hi[d] - lo[d]) / reach) + 1;
    size_t nbins = (size_t)nb[0] * nb[1] * nb[2];
    size_t *start = calloc(nbins + 1, sizeof *start), *list = NULL, n_list = 0;
    double(*box)[6] = malloc((to->n_tri + 1) * sizeof *box); /* each triangle's least and greatest x, y, z */
    if (!start || !box) {
        free(start);
        free(box);
        return INFINITY;
    }
    for (int pass = 0; pass < 2; pass++) {
        for (size_t t = 0; t < to->n_tri; t++) {
            int b0[3], b1[3];
            for (int d = 0; d < 3; d++) {
                double mn = INFINITY, mx = -INFINITY;
                for (int k = 0; k < 3; k++)
                    mn = fmin(mn, to->pos[3 * to->tri[3 * t + k] + d]), mx = fmax(mx, to->pos[3 * to->tri[3 * t + k] + d]);
                b0[d] = (int)((mn - reach - lo[d]) / reach), b1[d] = (int)((mx + reach - lo[d]) / reach);
                box[t][d] = mn, box[t][3 + d] = mx;
            }
            for (int z = b0[2]; z <= b1[2]; z++)
                for (int y = b0[1]; y <= b1[1]; y++)
                    for (int x = b0[0]; x <= b1[0]; x++) {
                        size_t at = (size_t)x + (size_t)nb[0] * ((size_t)y + (size_t)nb[1] * z);
                        if (pass == 0)
                            start[at + 1]++;
                        else
                            list[start[at]++] = t;
                    }
        }
        if (pass == 0) {
            for (size_t b = 0; b < nbins; b++)
                start[b + 1] += start[b];
            n_list = start[nbins];
            if (!(list = malloc((n_list + 1) * sizeof *list))) {
                free(start);
                free(box);
                return INFINITY;
            }
        } else {
            for (size_t b = nbins; b > 0; b--)
                start[b] = start[b - 1];
            start[0] = 0;
        }
    }
    for (size_t f = 0; f < from->n_tri; f++)
        for (int a = 0; a <= 4; a++)
            for (int b = 0; a + b <= 4; b++) {
                double p[3];
                int c = 4 - a - b, bin[3];
                for (int d = 0; d < 3; d++) {
                    p[d] = (a * from->pos[3 * from->tri[3 * f] + d] + b * from->pos[3 * from->tri[3 * f + 1] + d] +
                            c * from->pos[3 * from->tri[3 * f + 2] + d]) / 4.0;
                    bin[d] = (int)((p[d] - lo[d]) / reach);
                }
                size_t at = (size_t)bin[0] + (size_t)nb[0] * ((size_t)bin[1] + (size_t)nb[1] * bin[2]);
                double best = reach;
                for (size_t j = start[at]; j < start[at + 1]; j++) {
                    size_t t = list[j];
                    double e = 0;
                    for (int d = 0; d < 3; d++) {
                        double o = fmax(box[t][d] - p[d], p[d] - box[t][3 + d]);
                        e += o > 0 ? o * o : 0;
                    }
                    if (e >= best * best)
                        continue;
                    double A[3], B[3], C[3];
                    for (int d = 0; d < 3; d++)
                        A[d] = to->pos[3 * to->tri[3 * t] + d], B[d] = to->pos[3 * to->tri[3 * t + 1] + d],
                        C[d] = to->pos[3 * to->tri[3 * t + 2] + d];
                    best = fmin(best, tri_dist(p, A, B, C));
                }
                worst = fmax(worst, best);
            }
    free(start);
    free(list);
    free(box);
    return worst;
}

/* ---- extraction on 1 or 2 threads, in any slab order ---- */

struct run {
    struct iso_adapt *a;
    int phase, first, step;
};

static void *run_slabs(void *arg)
{
    struct run *r = arg;
    int n = iso_adapt_n_slabs(r->a);
    for (int s = r->first; s < n; s += r->step)
        iso_adapt_run(r->a, r->phase, s);
    return NULL;
}

/* threads 1: slabs in order; -1: in reverse; 2: two threads taking every other slab. */
static bool extract(const struct iso_grid *g, const struct iso_opts *o, int levels, double me, int threads,
                    struct trimesh *m, struct iso_adapt_stats *as)
{
    struct iso_adapt *a;
    struct sf_err err = {0};
    if (iso_adapt_begin(g, o, levels, me, &a, &err)) {
        fprintf(stderr, "  begin: %s\n", err.message);
        return false;
    }
    for (int p = 0; p < iso_adapt_phases(a); p++) {
        int n = iso_adapt_n_slabs(a);
        if (threads == 2) {
            struct run r[2] = {{a, p, 0, 2}, {a, p, 1, 2}};
            pthread_t th;
            if (pthread_create(&th, NULL, run_slabs, &r[1])) {
                iso_adapt_free(a);
                return false;
            }
            run_slabs(&r[0]);
            pthread_join(th, NULL);
        } else {
            for (int s = 0; s < n; s++)
                iso_adapt_run(a, p, threads < 0 ? n - 1 - s : s);
        }
        iso_adapt_between(a, p);
    }
    int rc = iso_adapt_end(a, m, as, &err);
    if (rc)
        fprintf(stderr, "  end: %s\n", err.message);
    return rc == 0;
}

static bool same(const struct trimesh *x, const struct trimesh *y)
{
    return x->n_vert == y->n_vert && x->n_tri == y->n_tri && !memcmp(x->pos, y->pos, 3 * x->n_vert * sizeof *x->pos) &&
           !memcmp(x->tri, y->tri, 3 * x->n_tri * sizeof *x->tri) && !memcmp(x->nrm, y->nrm, 3 * x->n_vert * sizeof *x->nrm);
}

/* One field at levels / max_error against its full-resolution mesh: topology, distances, counts. */
static void check_field(const struct iso_grid *g, double iso, int levels, double me, double *ratio)
{
    struct iso_opts full_o = {.iso = iso, .closed = true, .normals = true};
    struct iso_opts o = pieces_opts(iso);
    struct trimesh full = {0}, m = {0};
    struct trimesh_stats fs, ms;
    struct iso_adapt_stats as;
    struct sf_err err = {0};
    REQUIRE(iso_extract(g, &full_o, NULL, &full, &err) == 0 && trimesh_stats(&full, &fs, &err) == 0);
    REQUIRE(extract(g, &o, levels, me, 1, &m, &as) && trimesh_stats(&m, &ms, &err) == 0);
    CHECK(ms.boundary_edges == 0 && ms.nonmanifold_edges == 0 && ms.degenerate == 0);
    CHECK(ms.components == fs.components);
    CHECK(ms.euler == fs.euler);
    if (ms.components != fs.components || ms.euler != fs.euler || ms.boundary_edges || ms.nonmanifold_edges)
        fprintf(stderr, "  levels %d max_error %g: components %ld / %ld, euler %ld / %ld, boundary %ld, nonmanifold %ld\n",
                levels, me, ms.components, fs.components, ms.euler, fs.euler, ms.boundary_edges, ms.nonmanifold_edges);
    double to_full = farthest_dense(&m, &full, 4 * me + 1), from_full = farthest_dense(&full, &m, 4 * me + 1);
    CHECK(to_full <= me * (1 + 1e-6) + 1e-6);
    CHECK(from_full <= me * (1 + 1e-6) + 1e-6);
    if (to_full > me + 1e-6 || from_full > me + 1e-6)
        fprintf(stderr, "  levels %d max_error %g: %g to full, %g from full\n", levels, me, to_full, from_full);
    CHECK(m.n_tri <= full.n_tri);
    long verts = 0;
    for (int l = 1; l <= ISO_MAX_LEVELS; l++)
        verts += as.cells[l];
    CHECK(verts == (long)m.n_vert);
    *ratio = (double)full.n_tri / (double)(m.n_tri ? m.n_tri : 1);
    trimesh_free(&full);
    trimesh_free(&m);
}

static float *fields[5];

TEST(analytic_topology_and_distance)
{
    /* (each field at one or two of levels / max_error, so that the sanitised run stays short) */
    static const struct { int kind, levels; double me; } runs[] = {{0, 2, 0.5}, {0, 3, 1.0}, {1, 3, 0.5}, {2, 2, 0.5},
                                                                   {3, 3, 1.0}, {4, 4, 0.5}, {4, 2, 0.25}};
    for (size_t k = 0; k < sizeof runs / sizeof runs[0]; k++) {
        struct iso_grid g = grid(N, fields[runs[k].kind], 1.0);
        double ratio = 1;
        check_field(&g, 0, runs[k].levels, runs[k].me, &ratio);
        if (runs[k].kind == 0 && runs[k].levels == 3)
            CHECK(ratio >= 3); /* a smooth sphere merges well */
    }
}

TEST(thin_plate_and_tube_survive)
{
    /* the plate and tube are thinner than a cell: still one closed piece each, of the full mesh's
     * Euler characteristic, at every level, even with a bound that lets everything merge */
    struct iso_opts o = pieces_opts(0);
    for (int kind = 2; kind <= 3; kind++) {
        struct iso_grid g = grid(N, fields[kind], 1.0);
        struct trimesh full = {0};
        struct trimesh_stats fs;
        struct sf_err err = {0};
        struct iso_opts fo = {.iso = 0, .closed = true, .normals = true};
        REQUIRE(iso_extract(&g, &fo, NULL, &full, &err) == 0 && trimesh_stats(&full, &fs, &err) == 0);
        CHECK(fs.components >= 1 && fs.boundary_edges == 0);
        for (int levels = 2; levels <= 4; levels++) {
            struct trimesh m = {0};
            struct trimesh_stats ms;
            struct iso_adapt_stats as;
            REQUIRE(extract(&g, &o, levels, 100, 1, &m, &as) && trimesh_stats(&m, &ms, &err) == 0);
            CHECK(ms.boundary_edges == 0 && ms.nonmanifold_edges == 0 && ms.degenerate == 0);
            CHECK(ms.components == fs.components && ms.euler == fs.euler);
            CHECK(m.n_tri < full.n_tri);
            trimesh_free(&m);
        }
        trimesh_free(&full);
    }
}

TEST(sphere_and_torus_topology)
{
    struct iso_opts o = pieces_opts(0);
    struct sf_err err = {0};
    for (int kind = 0; kind < 2; kind++) {
        struct iso_grid g = grid(N, fields[kind], 0.5);
        struct trimesh m = {0};
        struct trimesh_stats ms;
        struct iso_adapt_stats as;
        REQUIRE(extract(&g, &o, 4, 0.25, 1, &m, &as) && trimesh_stats(&m, &ms, &err) == 0);
        CHECK(ms.components == 1);
        CHECK(ms.euler == (kind == 0 ? 2 : 0));
        CHECK(as.cells[2] > 0 && as.cells[3] > 0); /* the levels really merge */
        trimesh_free(&m);
    }
}

TEST(same_on_any_threads)
{
    struct iso_opts o = pieces_opts(0);
    for (int kind = 4; kind < 5; kind++) {
        struct iso_grid g = grid(N, fields[kind], 1.0);
        struct trimesh m1 = {0}, m2 = {0}, mr = {0};
        struct iso_adapt_stats a1, a2, ar;
        REQUIRE(extract(&g, &o, 3, 0.5, 1, &m1, &a1));
        REQUIRE(extract(&g, &o, 3, 0.5, 2, &m2, &a2));
        REQUIRE(extract(&g, &o, 3, 0.5, -1, &mr, &ar));
        CHECK(same(&m1, &m2));
        CHECK(same(&m1, &mr));
        CHECK(!memcmp(a1.cells, a2.cells, sizeof a1.cells));
        trimesh_free(&m1), trimesh_free(&m2), trimesh_free(&mr);
    }
}

TEST(edit_equals_fresh)
{
    /* edits of a pieces model draw it whole again: the same mesh as a fresh extraction, every old
     * id out, the new ones numbered on */
    enum { M = 33 };
    float *f = malloc(sizeof(float) * M * M * M);
    REQUIRE(f);
    field_of(0, f, M);
    struct iso_grid g = grid(M, f, 1.0);
    struct iso_opts o = pieces_opts(0);
    o.keep = true;
    struct iso_adapt *a;
    struct iso_adapt_stats st;
    struct sf_err err = {0};
    REQUIRE(iso_adapt_begin(&g, &o, 3, 0.5, &a, &err) == 0);
    for (int p = 0; p < iso_adapt_phases(a); p++) {
        for (int s = 0; s < iso_adapt_n_slabs(a); s++)
            iso_adapt_run(a, p, s);
        iso_adapt_between(a, p);
    }
    REQUIRE(iso_adapt_keep(a, &st, &err) == 0);
    struct trimesh before = {0};
    REQUIRE(iso_adapt_mesh(a, &before, &st, &err) == 0);
    uint32_t first = iso_adapt_next_id(a);
    CHECK(first == before.n_tri);
    for (int e = 0; e < 3; e++) {
        float blk[6 * 6 * 6];
        for (int k = 0; k < 216; k++)
            blk[k] = e == 1 ? -5.0f : 5.0f;
        int lo[3] = {3 + 7 * e, 14, 14};
        struct iso_grid bg = {6, 6, 6, ISO_F32, blk, {1, 1, 1}, {0, 0, 0}};
        for (int z = 0; z < 6; z++)
            for (int y = 0; y < 6; y++)
                for (int x = 0; x < 6; x++)
                    f[(size_t)(lo[0] + x) + (size_t)M * ((size_t)(lo[1] + y) + (size_t)M * (size_t)(lo[2] + z))] = blk[0];
        struct iso_edit ed;
        struct iso_change ch;
        uint32_t next = iso_adapt_next_id(a);
        struct trimesh old = {0};
        REQUIRE(iso_adapt_mesh(a, &old, &st, &err) == 0);
        REQUIRE(iso_adapt_edit_ids(a, lo, &bg, &ed, &ch, &err) == 0);
        struct trimesh live = {0}, fresh = {0};
        struct iso_adapt_stats ls, fs;
        struct iso_opts plain = pieces_opts(0);
        REQUIRE(iso_adapt_mesh(a, &live, &ls, &err) == 0);
        REQUIRE(iso_extract_adaptive(&g, &plain, 3, 0.5, NULL, &fresh, &fs, &err) == 0);
        size_t differ = 1;
        CHECK(trimesh_differ(&live, &fresh, &differ) == 0 && differ == 0);
        CHECK(!memcmp(ls.cells, fs.cells, sizeof ls.cells));
        CHECK(ed.whole);
        CHECK(ch.n_removed == old.n_tri && ch.n_added == live.n_tri);
        CHECK(ch.n_added == 0 || ch.added[0] == next);
        CHECK(ch.next_id == next + live.n_tri && iso_adapt_next_id(a) == ch.next_id);
        uint32_t *ids = NULL;
        REQUIRE(iso_adapt_ids(a, &ids, &err) == 0);
        CHECK(live.n_tri == 0 || (ids[0] == next && ids[live.n_tri - 1] == next + live.n_tri - 1));
        free(ids);
        iso_change_free(&ch);
        trimesh_free(&old), trimesh_free(&live), trimesh_free(&fresh);
    }
    float *samples = NULL;
    REQUIRE(iso_adapt_samples(a, &samples, &err) == 0);
    CHECK(!memcmp(samples, f, sizeof(float) * M * M * M));
    free(samples);
    trimesh_free(&before);
    iso_adapt_free(a);
    free(f);
}

TEST(options_refused)
{
    struct iso_opts o = pieces_opts(0);
    o.sharp = true;
    struct iso_grid g = grid(N, fields[0], 1.0);
    struct iso_adapt *a = NULL;
    struct sf_err err = {0};
    CHECK(iso_adapt_begin(&g, &o, 3, 0.5, &a, &err) == SF_EINVAL && a == NULL);
    CHECK_STR(err.pointer, "?merge");
}

TEST(open_empty_and_without_normals)
{
    /* closed=false: a sphere the grid's border cuts is open; its border stays as it was (merges
     * never move a vertex on it), its topology too */
    enum { M = 25 };
    float *f = malloc(sizeof(float) * M * M * M);
    REQUIRE(f);
    for (int z = 0; z < M; z++)
        for (int y = 0; y < M; y++)
            for (int x = 0; x < M; x++)
                f[x + M * (y + M * z)] = (float)(14 - sqrt((x - 12.2) * (x - 12.2) + (y - 11.7) * (y - 11.7) + (z - 3.1) * (z - 3.1)));
    struct iso_grid g = grid(M, f, 1.0);
    struct iso_opts fo = {.iso = 0, .closed = false, .normals = true}, o = fo;
    o.pieces = true;
    struct trimesh full = {0}, m = {0};
    struct trimesh_stats fs, ms;
    struct iso_adapt_stats as;
    struct sf_err err = {0};
    REQUIRE(iso_extract(&g, &fo, NULL, &full, &err) == 0 && trimesh_stats(&full, &fs, &err) == 0);
    REQUIRE(extract(&g, &o, 3, 0.5, 1, &m, &as) && trimesh_stats(&m, &ms, &err) == 0);
    CHECK(fs.boundary_edges > 0);
    CHECK(ms.boundary_edges == fs.boundary_edges && ms.nonmanifold_edges == 0 && ms.degenerate == 0);
    CHECK(ms.components == fs.components && ms.euler == fs.euler);
    CHECK(m.n_tri < full.n_tri);
    CHECK(farthest_dense(&m, &full, 3) <= 0.5 + 1e-6 && farthest_dense(&full, &m, 3) <= 0.5 + 1e-6);
    trimesh_free(&m);
    /* without normals asked for (the fit takes the triangles'), and with no surface at all */
    o.closed = true, o.normals = false;
    REQUIRE(extract(&g, &o, 2, 0.5, 1, &m, &as) && trimesh_stats(&m, &ms, &err) == 0);
    CHECK(ms.boundary_edges == 0 && ms.nonmanifold_edges == 0 && m.n_tri > 0);
    trimesh_free(&m);
    o.iso = 100;
    REQUIRE(extract(&g, &o, 4, 0.5, 2, &m, &as));
    CHECK(m.n_tri == 0 && m.n_vert == 0);
    trimesh_free(&m);
    trimesh_free(&full);
    free(f);
}

/* The shared CT crop (64^3 of the head, as test_adapt reads it) at levels 3, 1 mm: topology and
 * distances. */
TEST(ct_crop)
{
    size_t len;
    char *raw = unit_data("volumes", "ct_head_crop64_int16.raw", &len);
    REQUIRE(raw && len == 64 * 64 * 64 * 2);
    struct iso_grid g = {64, 64, 64, ISO_I16, raw, {0.9570312, 0.9570312, 1.5}, {0, 0, 0}};
    double ratio = 1;
    check_field(&g, 226.5, 3, 1.0, &ratio);
    CHECK(ratio >= 3);
    free(raw);
}

int main(void)
{
    iso_init();
    for (int k = 0; k < 5; k++) {
        fields[k] = malloc(sizeof(float) * N * N * N);
        if (!fields[k])
            return 1;
        field_of(k, fields[k], N);
    }
    RUN(options_refused);
    RUN(sphere_and_torus_topology);
    RUN(thin_plate_and_tube_survive);
    RUN(same_on_any_threads);
    RUN(edit_equals_fresh);
    RUN(open_empty_and_without_normals);
    RUN(analytic_topology_and_distance);
    RUN(ct_crop);
    for (int k = 0; k < 5; k++)
        free(fields[k]);
    UNIT_END();
}
