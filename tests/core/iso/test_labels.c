/* test_labels.c - the surfaces of label maps (core/iso/labels.h): on every labelling of a cell by
 * up to three labels and thousands by four, on random maps of up to seven labels and on blocks, each label's surface is a
 * closed, consistently oriented 2-manifold (each edge two triangles running opposite ways, each
 * vertex one fan, no triangle of zero area); labels that touch share their boundary (every
 * triangle of A facing B is, turned round, a triangle of B, and their counts agree); the labels'
 * volumes add up to the volume the background's surface encloses, and to the labelled voxels'
 * within the corners marching cubes cuts off; a two-label map is its mask's marching cubes. */
#include "../../../core/iso/labels.h"

#include <stdint.h>

#include "../../unit.h"

static uint64_t rng = 0x9e3779b97f4a7c15ull;
static unsigned draw(unsigned n) /* xorshift64 */
{
    rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
    return (unsigned)(rng >> 33) % n;
}

/* Each vertex's triangles make one fan (a single cycle of its opposite edges). */
static bool vertex_manifold(const struct trimesh *m)
{
    size_t *deg = calloc(m->n_vert + 1, sizeof *deg), *at = calloc(m->n_vert + 2, sizeof *at);
    uint32_t *opp = malloc(sizeof *opp * (6 * m->n_tri + 1));
    bool ok = deg && at && opp;
    for (size_t t = 0; ok && t < m->n_tri; t++)
        for (int c = 0; c < 3; c++)
            deg[m->tri[3 * t + (size_t)c]]++;
    for (size_t v = 0; ok && v < m->n_vert; v++)
        at[v + 1] = at[v] + deg[v], deg[v] = 0;
    for (size_t t = 0; ok && t < m->n_tri; t++)
        for (int c = 0; c < 3; c++) {
            uint32_t v = m->tri[3 * t + (size_t)c];
            size_t k = at[v] + deg[v]++;
            opp[2 * k] = m->tri[3 * t + (size_t)(c + 1) % 3], opp[2 * k + 1] = m->tri[3 * t + (size_t)(c + 2) % 3];
        }
    for (size_t v = 0; ok && v < m->n_vert; v++) {
        size_t n = deg[v], len = 0;
        if (!n)
            continue;
        uint32_t start = opp[2 * at[v]], cur = start;
        do { /* from the edge that starts at cur to where it ends */
            size_t k = 0;
            while (k < n && opp[2 * (at[v] + k)] != cur)
                k++;
            if (k == n)
                break;
            cur = opp[2 * (at[v] + k) + 1];
            len++;
        } while (cur != start && len <= n);
        ok = cur == start && len == n;
    }
    free(deg), free(at), free(opp);
    return ok;
}

struct tri9 {
    float p[9];
};
static int cmp9(const void *a, const void *b) { return memcmp(a, b, sizeof(struct tri9)); }

/* m's triangles (turned round when flip) as points, each from its least corner, sorted. */
static struct tri9 *tri_set(const struct trimesh *m, bool flip)
{
    struct tri9 *s = malloc(sizeof *s * (m->n_tri + 1));
    for (size_t t = 0; s && t < m->n_tri; t++) {
        uint32_t v[3] = {m->tri[3 * t], m->tri[3 * t + (flip ? 2 : 1)], m->tri[3 * t + (flip ? 1 : 2)]};
        int r = 0;
        for (int k = 1; k < 3; k++)
            if (memcmp(m->pos + 3 * v[k], m->pos + 3 * v[r], 3 * sizeof(float)) < 0)
                r = k;
        for (int k = 0; k < 3; k++)
            memcpy(s[t].p + 3 * k, m->pos + 3 * v[(r + k) % 3], 3 * sizeof(float));
    }
    if (s)
        qsort(s, m->n_tri, sizeof *s, cmp9);
    return s;
}

/* Triangles of a found turned round in b. */
static size_t common(const struct trimesh *a, const struct tri9 *bs, size_t nb)
{
    struct tri9 *as = tri_set(a, true);
    size_t n = 0;
    for (size_t t = 0; as && t < a->n_tri; t++)
        n += bsearch(&as[t], bs, nb, sizeof *bs, cmp9) != NULL;
    free(as);
    return n;
}

struct verdict {
    int bad_closed, bad_shared;
    double sum, background, voxels;
    long centres;            /* junctions drawn with a labelled centre: the tests reach them */
};

/* The map's surfaces, each label checked; volumes added into v. */
static void check_map(const struct iso_grid *g, int n_labels, struct verdict *v, const char *what)
{
    struct iso_labels l;
    struct sf_err err = {0};
    if (iso_labels_extract(g, n_labels, true, 0, NULL, NULL, &l, &err)) {
        fprintf(stderr, "  %s: %s\n", what, err.message);
        v->bad_closed++;
        return;
    }
    v->centres += l.centres;
    struct trimesh m[9];
    struct tri9 *set[9];
    size_t touch[9][9];
    double vox = g->spacing[0] * g->spacing[1] * g->spacing[2];
    for (size_t i = 0; i < (size_t)g->nx * g->ny * g->nz; i++)
        v->voxels += (g->type == ISO_U8 ? ((const uint8_t *)g->samples)[i] : ((const uint16_t *)g->samples)[i]) ? vox : 0;
    for (int k = 1; k <= n_labels; k++) {
        struct trimesh_stats st;
        iso_labels_mesh(&l, k, touch[k], &m[k], &err);
        set[k] = tri_set(&m[k], false);
        trimesh_stats(&m[k], &st, &err);
        v->sum += st.volume;
        if (m[k].n_tri && (st.boundary_edges || st.nonmanifold_edges || st.degenerate || !vertex_manifold(&m[k]) ||
                           !(st.volume > 0))) {
            if (v->bad_closed++ < 5)
                fprintf(stderr, "  %s, label %d: boundary %ld, nonmanifold %ld, degenerate %ld, fans %d, volume %g\n",
                        what, k, st.boundary_edges, st.nonmanifold_edges, st.degenerate, vertex_manifold(&m[k]),
                        st.volume);
        }
    }
    /* the background's surface: every triangle between it and a label, facing it */
    double bg = 0;
    for (size_t t = 0; t < l.n_tri; t++) {
        if (l.side[2 * t] != 0 && l.side[2 * t + 1] != 0)
            continue;
        const float *a = l.pos + 3 * l.tri[3 * t], *b = l.pos + 3 * l.tri[3 * t + 1], *c = l.pos + 3 * l.tri[3 * t + 2];
        double det = a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) - a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
                     a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
        bg += (l.side[2 * t + 1] == 0 ? det : -det) / 6;
    }
    v->background += bg;
    for (int a = 1; a <= n_labels; a++)
        for (int b = 1; b <= n_labels; b++)
            if (a != b && (common(&m[a], set[b], m[b].n_tri) != touch[a][b] || touch[a][b] != touch[b][a])) {
                if (v->bad_shared++ < 5)
                    fprintf(stderr, "  %s: labels %d and %d: %zu of %zu triangles shared, %zu the other way\n", what, a,
                            b, common(&m[a], set[b], m[b].n_tri), touch[a][b], touch[b][a]);
            }
    for (int k = 1; k <= n_labels; k++)
        trimesh_free(&m[k]), free(set[k]);
    iso_labels_free(&l);
}

/* Every labelling of a 2 x 2 x 2 map by labels 0-2 (3^8), and 2500 of the 4^8 by labels 0-3 (all
 * of them pass too, in a minute): each cell of the padded map meets it. */
TEST(every_cell_of_three_labels)
{
    struct verdict v = {0};
    uint8_t s[8];
    struct iso_grid g = {2, 2, 2, ISO_U8, s, {1, 1, 1}, {0, 0, 0}};
    for (int code = 0; code < 6561 + 2500; code++) {
        int n = 0;
        for (int k = 0, c = code; k < 8; k++, c /= 3)
            s[k] = (uint8_t)(code < 6561 ? (unsigned)c % 3 : draw(4)), n = s[k] > n ? s[k] : n;
        char what[32];
        snprintf(what, sizeof what, "labelling 0x%04x", code);
        check_map(&g, n, &v, what);
    }
    CHECK(v.bad_closed == 0);
    CHECK(v.bad_shared == 0);
    CHECK_NEAR(v.sum, v.background, 1e-6 * v.background);
    CHECK(v.centres > 0);
    fprintf(stderr, "  cells: %ld junctions with a labelled centre\n", v.centres);
}

/* Random maps of up to seven labels, some with runs (so labels form bodies, junction lines and
 * corners), both index types. */
TEST(random_maps)
{
    struct verdict v = {0};
    static uint16_t s16[6 * 5 * 7];
    static uint8_t s8[6 * 5 * 7];
    for (int draw_no = 0; draw_no < 500; draw_no++) {
        int n = 2 + (int)draw(6);
        bool wide = draw_no & 1;
        for (int i = 0; i < 6 * 5 * 7; i++) {
            unsigned lab = (draw_no % 3 == 0 && i > 0 && draw(3)) ? (wide ? s16[i - 1] : s8[i - 1]) : draw((unsigned)n + 1);
            s16[i] = (uint16_t)lab, s8[i] = (uint8_t)lab;
        }
        struct iso_grid g = {6, 5, 7, wide ? ISO_U16 : ISO_U8, wide ? (const void *)s16 : (const void *)s8,
                             {0.5, 1, 2}, {-3, 1, 7}};
        char what[32];
        snprintf(what, sizeof what, "random map %d", draw_no);
        check_map(&g, n, &v, what);
    }
    CHECK(v.bad_closed == 0);
    CHECK(v.bad_shared == 0);
    CHECK_NEAR(v.sum, v.background, 1e-6 * v.background);
    CHECK(v.centres > 0);
    fprintf(stderr, "  random maps: %ld junctions with a labelled centre\n", v.centres);
}

/* Blocks of labels stacked in a box (three meet along lines, four at points): the labels' volumes
 * add up to the labelled voxels', less what marching cubes cuts off at the outer corners and edges. */
TEST(blocks)
{
    enum { N = 24 };
    static uint8_t s[N * N * N];
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++) {
                bool in = x >= 2 && x < N - 2 && y >= 2 && y < N - 2 && z >= 2 && z < N - 2;
                s[x + N * (y + N * z)] = (uint8_t)(in ? 1 + (x >= N / 2) + 2 * (y >= N / 2) + 4 * (z > 15) : 0);
            }
    struct iso_grid g = {N, N, N, ISO_U8, s, {1, 1, 1}, {0, 0, 0}};
    struct verdict v = {0};
    check_map(&g, 8, &v, "blocks");
    CHECK(v.bad_closed == 0);
    CHECK(v.bad_shared == 0);
    CHECK_NEAR(v.sum, v.background, 1e-9 * v.background);
    /* a box of 20^3 voxels: 8000, less its 12 edges' chamfers (1/8 a unit length) and corners */
    CHECK(v.sum < v.voxels && v.sum > v.voxels * 0.985);
    fprintf(stderr, "  blocks: labels' volumes %.3f, voxels %.0f\n", v.sum, v.voxels);
}

/* A map of one label is that label's mask: the same vertices as marching cubes at 0.5 and, where
 * the fans agree, the same volume (a loop of more than three points is fanned from its own point
 * in each, which moves the volume a little where the loop is not flat). */
TEST(one_label_is_its_mask)
{
    enum { N = 12 };
    static uint8_t s[N * N * N];
    double r2 = 4.3 * 4.3;
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++)
                s[x + N * (y + N * z)] = (x - 5.5) * (x - 5.5) + (y - 5.2) * (y - 5.2) + (z - 5.7) * (z - 5.7) < r2;
    struct iso_grid g = {N, N, N, ISO_U8, s, {1, 1, 1}, {0, 0, 0}};
    struct iso_labels l;
    struct trimesh m, mc;
    struct trimesh_stats st, st_mc;
    struct sf_err err = {0};
    struct iso_opts o = {.iso = 0.5, .closed = true};
    iso_init();
    REQUIRE(iso_labels_extract(&g, 1, true, 0, NULL, NULL, &l, &err) == 0);
    REQUIRE(iso_labels_mesh(&l, 1, NULL, &m, &err) == 0);
    REQUIRE(iso_extract(&g, &o, NULL, &mc, &err) == 0);
    trimesh_stats(&m, &st, &err);
    trimesh_stats(&mc, &st_mc, &err);
    CHECK(m.n_vert == mc.n_vert);
    CHECK(m.n_tri == mc.n_tri);
    CHECK_NEAR(st.volume, st_mc.volume, 1e-2 * st_mc.volume);
    CHECK(st.euler == st_mc.euler);
    fprintf(stderr, "  one label: %zu triangles, volume %.3f; its mask's marching cubes %zu, %.3f\n", m.n_tri,
            st.volume, mc.n_tri, st_mc.volume);
    trimesh_free(&m), trimesh_free(&mc);
    iso_labels_free(&l);
}

/* Limits and bad grids: a sample over n_labels, a float grid, too many triangles, cancel. */
static bool stop_now(void *ctx, double done)
{
    (void)ctx, (void)done;
    return true;
}

TEST(refusals)
{
    uint8_t s[27] = {0, 1, 2, 3, 2, 1, 0, 1, 2, 3, 3, 3, 1, 1, 1, 2, 2, 2, 0, 0, 0, 1, 2, 3, 1, 2, 3};
    struct iso_grid g = {3, 3, 3, ISO_U8, s, {1, 1, 1}, {0, 0, 0}};
    struct iso_labels l;
    struct sf_err err = {0};
    CHECK(iso_labels_extract(&g, 2, true, 0, NULL, NULL, &l, &err) == SF_EINVAL && l.n_tri == 0);
    struct iso_grid f = g;
    f.type = ISO_F32;
    CHECK(iso_labels_extract(&f, 3, true, 0, NULL, NULL, &l, &err) == SF_EINVAL);
    memset(&err, 0, sizeof err);
    CHECK(iso_labels_extract(&g, 3, true, 10, "the test's limit", NULL, &l, &err) == SF_ELIMIT &&
          strstr(err.message, "the test's limit"));
    const struct sf_progress stop = {stop_now, NULL};
    CHECK(iso_labels_extract(&g, 3, true, 0, NULL, &stop, &l, &err) == SF_ECANCEL);
    REQUIRE(iso_labels_extract(&g, 3, false, 0, NULL, NULL, &l, &err) == 0); /* open: surfaces stop at the border */
    struct trimesh m;
    struct trimesh_stats st;
    REQUIRE(iso_labels_mesh(&l, 1, NULL, &m, &err) == 0);
    trimesh_stats(&m, &st, &err);
    CHECK(st.boundary_edges > 0 && st.nonmanifold_edges == 0);
    trimesh_free(&m);
    CHECK(iso_labels_mesh(&l, 4, NULL, &m, &err) == SF_EINVAL);
    iso_labels_free(&l);
}

int main(void)
{
    RUN(every_cell_of_three_labels);
    RUN(random_maps);
    RUN(blocks);
    RUN(one_label_is_its_mask);
    RUN(refusals);
    UNIT_END();
}
