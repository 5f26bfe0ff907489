/* test_edit.c - local rebuilds of the adaptive hierarchy (adapt.h: iso_adapt_keep, iso_adapt_edit):
 * after each of a run of edits (blocks inside, on the border, over a corner, changing the
 * samples' least value) the kept mesh equals a fresh extraction of the edited samples triangle for
 * triangle (positions and normals), at every level count, with and without features; and a region
 * outside the samples is refused. */
#include "../../../core/iso/adapt.h"
#include "../../../core/iso/kept.h"

#include <stdbool.h>
#include <stdint.h>

#include "../../unit.h"

/* The same triangles (positions and normals), whatever the vertex numbering and the order. */
static bool same_mesh(const struct trimesh *x, const struct trimesh *y)
{
    size_t differ;
    bool same = !trimesh_differ(x, y, &differ) && differ == 0;
    if (!same)
        fprintf(stderr, "  %zu of %zu triangles differ (against %zu)\n", differ, x->n_tri, y->n_tri);
    return same;
}

static struct iso_adapt *kept(const struct iso_grid *g, const struct iso_opts *o, int levels, double me)
{
    struct iso_adapt *a;
    struct iso_adapt_stats st;
    struct sf_err err = {0};
    if (iso_adapt_begin(g, o, levels, me, &a, &err))
        return NULL;
    for (int p = 0; p < iso_adapt_phases(a); p++) {
        for (int s = 0; s < iso_adapt_n_slabs(a); s++)
            iso_adapt_run(a, p, s);
        iso_adapt_between(a, p);
    }
    if (iso_adapt_keep(a, &st, &err)) {
        iso_adapt_free(a);
        return NULL;
    }
    return a;
}

/* The kept mesh against a fresh extraction of g's samples (as edited), with the same counts. */
static bool as_fresh(const struct iso_adapt *a, const struct iso_grid *g, const struct iso_opts *o, int levels,
                     double me)
{
    struct trimesh fresh, live;
    struct iso_adapt_stats fs, ls;
    struct trimesh_stats st;
    struct sf_err err = {0};
    struct iso_opts plain = *o;
    plain.keep = false;
    if (iso_extract_adaptive(g, &plain, levels, me, NULL, &fresh, &fs, &err) || iso_adapt_mesh(a, &live, &ls, &err))
        return false;
    bool ok = same_mesh(&live, &fresh) && !memcmp(fs.cells, ls.cells, sizeof fs.cells) &&
              fs.feature_points == ls.feature_points && fs.face_points == ls.face_points &&
              fs.max_estimate == ls.max_estimate;
    ok = ok && trimesh_stats(&live, &st, &err) == 0 && st.boundary_edges == 0 && st.nonmanifold_edges == 0;
    if (!ok)
        fprintf(stderr, "  cells %ld/%ld %ld/%ld, features %ld/%ld, face points %ld/%ld, max %g/%g\n", ls.cells[1],
                fs.cells[1], ls.cells[2], fs.cells[2], ls.feature_points, fs.feature_points, ls.face_points,
                fs.face_points, ls.max_estimate, fs.max_estimate);
    trimesh_free(&fresh);
    trimesh_free(&live);
    return ok;
}

/* A block of n^3 int16 samples at lo written into a's samples and into the copy vol (nx^3): a
 * ball of value in of radius r about the block's centre, value out round it. */
static bool edit_ball_ids(struct iso_adapt *a, int16_t *vol, int nx, const int lo[3], int n, double r, int16_t in,
                          int16_t out, struct iso_edit *ed, struct iso_change *ch)
{
    int16_t *blk = malloc((size_t)n * n * n * sizeof *blk);
    for (int z = 0; z < n; z++)
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                double d = hypot(hypot(x - n / 2.0 + 0.3, y - n / 2.0 - 0.2), z - n / 2.0 + 0.1);
                int16_t v = d < r ? in : out;
                blk[x + n * (y + n * z)] = v;
                if (lo[0] + x < nx && lo[1] + y < nx && lo[2] + z < nx)
                    vol[(lo[0] + x) + nx * ((lo[1] + y) + (size_t)nx * (lo[2] + z))] = v;
            }
    struct iso_grid bg = {n, n, n, ISO_I16, blk, {1, 1, 1}, {0, 0, 0}};
    struct sf_err err = {0};
    int rc = iso_adapt_edit_ids(a, lo, &bg, ed, ch, &err);
    if (rc)
        fprintf(stderr, "  edit: %s\n", err.message);
    free(blk);
    return rc == 0;
}

static bool edit_ball(struct iso_adapt *a, int16_t *vol, int nx, const int lo[3], int n, double r, int16_t in,
                      int16_t out, struct iso_edit *ed)
{
    return edit_ball_ids(a, vol, nx, lo, n, r, in, out, ed, NULL);
}

/* The shared CT crop's samples (NULL when missing: a failed check), and its grid over them. */
#define CT_BYTES (64 * 64 * 64 * 2)
static char *ct_crop(void)
{
    size_t len;
    char *raw = unit_data("volumes", "ct_head_crop64_int16.raw", &len);
    CHECK(raw && len == CT_BYTES);
    return raw && len == CT_BYTES ? raw : (free(raw), NULL);
}
static struct iso_grid ct_grid(const int16_t *vol)
{
    return (struct iso_grid){64, 64, 64, ISO_I16, vol, {0.9570312, 0.9570312, 1.5}, {0, 0, 0}};
}

TEST(ct_edits_equal_a_fresh_extraction)
{
    size_t len = CT_BYTES;
    char *raw = ct_crop();
    if (!raw)
        return;
    const int lo[][3] = {{20, 24, 17}, {0, 0, 0}, {48, 48, 48}, {30, 5, 40}, {21, 25, 18}, {8, 40, 3}};
    const double me[] = {0, 0.5, 1.0, 2.0};
    for (int levels = 1; levels <= 4; levels++)
        for (int sharp = 0; sharp < 2; sharp++) {
            if (levels == 1 && !sharp)
                continue; /* (levels 1 without features is marching cubes, mc.c) */
            int16_t *vol = memcpy(malloc(len), raw, len);
            struct iso_grid g = ct_grid(vol);
            struct iso_opts o = {.iso = 226.5, .closed = true, .normals = true, .sharp = sharp, .keep = true};
            struct iso_adapt *a = kept(&g, &o, levels, me[levels - 1]);
            CHECK(a != NULL);
            if (!a) {
                free(vol);
                continue;
            }
            for (int e = 0; e < 6; e++) {
                struct iso_edit ed;
                int n = e == 2 ? 16 : 12; /* (the third runs past no border: 48 + 16 = 64) */
                CHECK(edit_ball(a, vol, 64, lo[e], n, 4 + e, e & 1 ? -1000 : 1400, e & 1 ? 300 : -100, &ed));
                CHECK(ed.cells_rebuilt > 0 && ed.triangles_added > 0 && !ed.whole);
                CHECK(as_fresh(a, &g, &o, levels, me[levels - 1]));
            }
            iso_adapt_free(a);
            free(vol);
        }
    free(raw);
}

/* Samples under the least one there was move the pad (the border counts as outside below it):
 * every cell is drawn again, and the mesh is still the fresh one; so when the least one goes. */
TEST(a_new_least_sample_redraws_every_cell)
{
    char *raw = ct_crop();
    if (!raw)
        return;
    int16_t *vol = memcpy(malloc(CT_BYTES), raw, CT_BYTES), least = INT16_MAX;
    for (size_t i = 0; i < CT_BYTES / 2; i++)
        least = vol[i] < least ? vol[i] : least;
    struct iso_grid g = ct_grid(vol);
    struct iso_opts o = {.iso = -500, .closed = true, .normals = true, .keep = true}; /* (a surface at the border) */
    struct iso_adapt *a = kept(&g, &o, 3, 1.0);
    CHECK(a != NULL);
    struct iso_edit ed;
    struct iso_change ch = {0};
    struct trimesh before;
    struct iso_adapt_stats st;
    CHECK(iso_adapt_mesh(a, &before, &st, &(struct sf_err){0}) == 0);
    CHECK(edit_ball_ids(a, vol, 64, (int[3]){10, 10, 10}, 8, 3, (int16_t)(least - 500), 0, &ed, &ch));
    CHECK(ed.whole);
    CHECK(as_fresh(a, &g, &o, 3, 1.0));
    /* (a whole change: every triangle out, the new ones numbered on from the counter: the daemon
     * stores the new mesh as the model's base, job_edit.c) */
    CHECK(ch.n_removed == before.n_tri && ch.n_added == (size_t)ed.triangles_added &&
          ch.next_id == ch.added[0] + ch.n_added && ch.added[ch.n_added - 1] == ch.next_id - 1);
    trimesh_free(&before);
    iso_change_free(&ch);
    CHECK(edit_ball(a, vol, 64, (int[3]){10, 10, 10}, 8, 3, 0, 0, &ed)); /* the least one gone again */
    CHECK(ed.whole);
    CHECK(as_fresh(a, &g, &o, 3, 1.0));
    iso_adapt_free(a);
    free(vol);
    free(raw);
}

/* Many edits over one part: the unused vertices are dropped now and then, the mesh stays right. */
TEST(many_edits_over_one_place)
{
    char *raw = ct_crop();
    if (!raw)
        return;
    int16_t *vol = memcpy(malloc(CT_BYTES), raw, CT_BYTES);
    struct iso_grid g = ct_grid(vol);
    struct iso_opts o = {.iso = 226.5, .closed = true, .normals = true, .keep = true};
    struct iso_adapt *a = kept(&g, &o, 2, 0.5);
    CHECK(a != NULL);
    for (int e = 0; e < 24; e++) {
        struct iso_edit ed;
        CHECK(edit_ball(a, vol, 64, (int[3]){4 + e % 5, 6 + e % 3, 4 + e % 7}, 40, 6 + e % 13, 1400, -100, &ed));
        if (e % 6 == 5)
            CHECK(as_fresh(a, &g, &o, 2, 0.5));
    }
    CHECK(as_fresh(a, &g, &o, 2, 0.5));
    iso_adapt_free(a);
    free(vol);
    free(raw);
}

TEST(a_region_outside_is_refused)
{
    static float v[8 * 8 * 8];
    for (int i = 0; i < 8 * 8 * 8; i++)
        v[i] = (float)(i % 7) - 3;
    struct iso_grid g = {8, 8, 8, ISO_F32, v, {1, 1, 1}, {0, 0, 0}};
    struct iso_opts o = {.iso = 0, .closed = true, .normals = true, .keep = true};
    struct iso_adapt *a = kept(&g, &o, 2, 0.5);
    CHECK(a != NULL);
    float blk[27] = {0};
    struct iso_grid bg = {3, 3, 3, ISO_F32, blk, {1, 1, 1}, {0, 0, 0}};
    struct iso_edit ed;
    struct sf_err err = {0};
    CHECK(iso_adapt_edit(a, (int[3]){6, 0, 0}, &bg, &ed, &err) == SF_EINVAL && !strcmp(err.pointer, "?region"));
    CHECK(iso_adapt_edit(a, (int[3]){0, -1, 0}, &bg, &ed, &err) == SF_EINVAL);
    CHECK(iso_adapt_edit(a, (int[3]){5, 5, 5}, &bg, &ed, &err) == 0);
    iso_adapt_free(a);
    /* an extraction not begun to be kept cannot be */
    o.keep = false;
    struct iso_adapt_stats st;
    CHECK(iso_adapt_begin(&g, &o, 2, 0.5, &a, &err) == 0);
    CHECK(iso_adapt_keep(a, &st, &err) == SF_EINVAL);
    iso_adapt_free(a);
}

/* A client's copy of the mesh by triangle id (kept.h), as the mesh deltas keep it: 18 floats
 * each, present or not. */
struct by_id {
    float *t;
    bool *has;
    size_t cap;
};

static void by_id_put(struct by_id *c, uint32_t id, const float *corners)
{
    if (id >= c->cap) {
        size_t cap = 2 * (size_t)id + 16;
        c->t = realloc(c->t, cap * 18 * sizeof *c->t);
        c->has = realloc(c->has, cap * sizeof *c->has);
        memset(c->has + c->cap, 0, (cap - c->cap) * sizeof *c->has);
        c->cap = cap;
    }
    memcpy(c->t + 18 * (size_t)id, corners, 18 * sizeof *c->t);
    c->has[id] = true;
}

/* Whether the kept mesh, id for id, is the client's copy. */
static bool by_id_same(const struct by_id *c, const struct iso_adapt *a)
{
    struct trimesh m;
    struct iso_adapt_stats st;
    struct sf_err err = {0};
    uint32_t *ids = NULL;
    if (iso_adapt_mesh(a, &m, &st, &err) || iso_adapt_ids(a, &ids, &err)) {
        fprintf(stderr, "  the kept mesh: %s\n", err.message);
        return false;
    }
    size_t held = 0, wrong = 0;
    for (size_t i = 0; i < c->cap; i++)
        held += c->has[i];
    for (size_t t = 0; t < m.n_tri; t++) {
        float x[18];
        for (int k = 0; k < 3; k++) {
            memcpy(x + 6 * k, m.pos + 3 * m.tri[3 * t + k], 3 * sizeof(float));
            memcpy(x + 6 * k + 3, m.nrm + 3 * m.tri[3 * t + k], 3 * sizeof(float));
        }
        wrong += ids[t] >= c->cap || !c->has[ids[t]] || memcmp(c->t + 18 * (size_t)ids[t], x, sizeof x);
    }
    bool same = !wrong && held == m.n_tri;
    if (!same)
        fprintf(stderr, "  %zu of %zu triangles differ from the copy by id (%zu held)\n", wrong, m.n_tri, held);
    free(ids);
    trimesh_free(&m);
    return same;
}

/* Ids (kept.h): the first mesh numbered in the fresh extraction's order; each edit's change,
 * applied to a copy by id, gives the kept mesh; an id is never used twice; two hierarchies given
 * the same edits number alike. */
TEST(edits_report_their_changes_by_stable_ids)
{
    char *raw = ct_crop();
    if (!raw)
        return;
    int16_t *vol = memcpy(malloc(CT_BYTES), raw, CT_BYTES), *vol2 = memcpy(malloc(CT_BYTES), raw, CT_BYTES);
    struct iso_grid g = ct_grid(vol), g2 = ct_grid(vol2);
    struct iso_opts o = {.iso = 226.5, .closed = true, .normals = true, .keep = true}, plain = o;
    plain.keep = false;
    struct iso_adapt *a = kept(&g, &o, 3, 1.0), *b = kept(&g2, &o, 3, 1.0);
    struct trimesh fresh, m;
    struct iso_adapt_stats st;
    struct sf_err err = {0};
    uint32_t *ids = NULL;
    CHECK(a && b && iso_extract_adaptive(&g, &plain, 3, 1.0, NULL, &fresh, &st, &err) == 0);
    CHECK(iso_adapt_mesh(a, &m, &st, &err) == 0 && iso_adapt_ids(a, &ids, &err) == 0);
    bool in_order = m.n_tri == fresh.n_tri;
    struct by_id c = {0};
    for (size_t t = 0; t < m.n_tri && in_order; t++) {
        float x[18];
        for (int k = 0; k < 3; k++) {
            memcpy(x + 6 * k, m.pos + 3 * m.tri[3 * t + k], 3 * sizeof(float));
            memcpy(x + 6 * k + 3, m.nrm + 3 * m.tri[3 * t + k], 3 * sizeof(float));
            in_order = in_order && !memcmp(x + 6 * k, fresh.pos + 3 * fresh.tri[3 * t + k], 3 * sizeof(float));
        }
        in_order = in_order && ids[t] == t;
        by_id_put(&c, ids[t], x);
    }
    CHECK(in_order);
    free(ids);
    trimesh_free(&m);
    trimesh_free(&fresh);
    uint32_t next = (uint32_t)c.cap;
    for (size_t i = 0; i < c.cap; i++)
        next = c.has[i] ? (uint32_t)i + 1 : next;
    for (int e = 0; e < 8 && a && b; e++) {
        int lo[3] = {6 + 5 * e, 20 + (e % 3) * 4, 10 + 3 * e}, n = 10;
        int16_t *blk = malloc((size_t)n * n * n * sizeof *blk);
        for (int i = 0; i < n * n * n; i++) {
            blk[i] = (int16_t)(e & 1 ? -800 : 1500 - 30 * (i % 17));
            vol[lo[0] + i % n + 64 * (lo[1] + i / n % n + 64 * (lo[2] + i / (n * n)))] = blk[i];
        }
        struct iso_grid bg = {n, n, n, ISO_I16, blk, {1, 1, 1}, {0, 0, 0}};
        struct iso_edit ed, ed2;
        struct iso_change ch, ch2;
        CHECK(iso_adapt_edit_ids(a, lo, &bg, &ed, &ch, &err) == 0 && iso_adapt_edit_ids(b, lo, &bg, &ed2, &ch2, &err) == 0);
        CHECK(ch.n_removed == (size_t)ed.triangles_removed && ch.n_added == (size_t)ed.triangles_added && ch.n_added > 0);
        bool ok = true;
        for (size_t k = 0; k < ch.n_removed; k++) {
            ok = ok && ch.removed[k] < c.cap && c.has[ch.removed[k]];
            if (ch.removed[k] < c.cap)
                c.has[ch.removed[k]] = false;
        }
        for (size_t k = 0; k < ch.n_added; k++) {
            ok = ok && ch.added[k] >= next; /* (never one used before) */
            next = ch.added[k] + 1;
            by_id_put(&c, ch.added[k], ch.corners + 18 * k);
        }
        CHECK(ok && ch.next_id == next);
        CHECK(by_id_same(&c, a));
        CHECK(ch.n_added == ch2.n_added && ch.n_removed == ch2.n_removed && ch.next_id == ch2.next_id &&
              !memcmp(ch.added, ch2.added, ch.n_added * sizeof *ch.added) &&
              !memcmp(ch.corners, ch2.corners, ch.n_added * 18 * sizeof *ch.corners));
        iso_change_free(&ch);
        iso_change_free(&ch2);
        free(blk);
    }
    CHECK(as_fresh(a, &g, &o, 3, 1.0));
    free(c.t);
    free(c.has);
    iso_adapt_free(a);
    iso_adapt_free(b);
    free(vol);
    free(vol2);
    free(raw);
}

int main(void)
{
    iso_init();
    RUN(ct_edits_equal_a_fresh_extraction);
    RUN(a_new_least_sample_redraws_every_cell);
    RUN(many_edits_over_one_place);
    RUN(a_region_outside_is_refused);
    RUN(edits_report_their_changes_by_stable_ids);
    UNIT_END();
}
