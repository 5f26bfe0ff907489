/* test_kept.c - marching cubes kept for seed 002's interactive loop (kept.h: iso_kept_*): the first
 * mesh is iso_extract's byte for byte (ids 0 .. n-1 its order); after each of a run of edits
 * (inside, on the border, over a corner, moving the least sample: whole) and iso changes the kept
 * mesh equals a fresh extraction of the samples triangle for triangle (positions and normals);
 * ids of untouched triangles stay, new ones come from the counter and two kept extractions given
 * the same changes number alike; the change lists what the mesh gained and lost; bad regions and
 * isos are refused. On an analytic field and on the shared CT crop. */
#include "../../../core/iso/kept.h"

#include <stdbool.h>
#include <stdint.h>

#include "../../unit.h"

/* A triangle's corners as 18 floats (x y z nx ny nz each). */
static void corners18(const struct trimesh *m, size_t i, float *c)
{
    for (int k = 0; k < 3; k++) {
        uint32_t v = m->tri[3 * i + k];
        memcpy(c + 6 * k, m->pos + 3 * v, 3 * sizeof(float));
        if (m->nrm)
            memcpy(c + 6 * k + 3, m->nrm + 3 * v, 3 * sizeof(float));
        else
            memset(c + 6 * k + 3, 0, 3 * sizeof(float));
    }
}

static bool same_mesh(const struct trimesh *x, const struct trimesh *y)
{
    size_t differ;
    bool same = !trimesh_differ(x, y, &differ) && differ == 0;
    if (!same)
        fprintf(stderr, "  %zu of %zu triangles differ (against %zu)\n", differ, x->n_tri, y->n_tri);
    return same;
}

/* The kept mesh as the caller sees it, with a mirror of it by id kept from the changes alone (what
 * a client applying the deltas holds): sorted ids and their 18 floats. */
struct mirror {
    uint32_t *id;
    float *c;
    size_t n;
};

static void mirror_free(struct mirror *m)
{
    free(m->id);
    free(m->c);
    memset(m, 0, sizeof *m);
}

/* The mirror of k's mesh as iso_kept_mesh gives it (ids ascending: checked). */
static bool mirror_of(const struct iso_kept *k, struct mirror *m, struct trimesh *mesh)
{
    uint32_t *ids;
    struct sf_err err = {0};
    if (iso_kept_mesh(k, mesh, &ids, &err))
        return false;
    m->n = mesh->n_tri;
    m->id = ids;
    m->c = malloc((m->n ? m->n : 1) * 18 * sizeof *m->c);
    bool ok = true;
    for (size_t i = 0; i < m->n; i++) {
        corners18(mesh, i, m->c + 18 * i);
        ok = ok && (i == 0 || ids[i - 1] < ids[i]);
    }
    return ok;
}

/* The mirror after change ch: the removed ids out (each present), the added in (ids above all). */
static bool mirror_apply(struct mirror *m, const struct iso_change *ch, uint32_t next_before)
{
    bool ok = ch->n_added == 0 || ch->added[0] == next_before;
    size_t w = 0, r = 0;
    for (size_t i = 0; i < m->n; i++) {
        while (r < ch->n_removed && ch->removed[r] < m->id[i])
            r++, ok = false; /* (an id removed that was not there) */
        if (r < ch->n_removed && ch->removed[r] == m->id[i]) {
            r++;
            continue;
        }
        m->id[w] = m->id[i];
        memmove(m->c + 18 * w, m->c + 18 * i, 18 * sizeof *m->c);
        w++;
    }
    ok = ok && r == ch->n_removed;
    m->id = realloc(m->id, (w + ch->n_added + 1) * sizeof *m->id);
    m->c = realloc(m->c, (w + ch->n_added + 1) * 18 * sizeof *m->c);
    for (size_t i = 0; i < ch->n_added; i++) {
        ok = ok && (i == 0 || ch->added[i] == ch->added[i - 1] + 1);
        m->id[w + i] = ch->added[i];
        memcpy(m->c + 18 * (w + i), ch->corners + 18 * i, 18 * sizeof *m->c);
    }
    m->n = w + ch->n_added;
    ok = ok && ch->next_id == next_before + ch->n_added;
    return ok;
}

static bool mirror_same(const struct mirror *a, const struct mirror *b)
{
    return a->n == b->n && !memcmp(a->id, b->id, a->n * sizeof *a->id) && !memcmp(a->c, b->c, a->n * 18 * sizeof *a->c);
}

/* k's mesh against a fresh extraction of g at o, and against the mirror the changes made. */
static bool as_fresh(const struct iso_kept *k, const struct iso_grid *g, const struct iso_opts *o, struct mirror *mirror)
{
    struct trimesh fresh, live;
    struct trimesh_stats st;
    struct sf_err err = {0};
    struct mirror now = {0};
    if (iso_extract(g, o, NULL, &fresh, &err))
        return false;
    bool ok = mirror_of(k, &now, &live);
    ok = ok && same_mesh(&live, &fresh);
    ok = ok && trimesh_stats(&live, &st, &err) == 0 && (!o->closed || (st.boundary_edges == 0 && st.nonmanifold_edges == 0));
    if (mirror) {
        bool same = mirror_same(&now, mirror);
        if (!same)
            fprintf(stderr, "  the changes applied do not give the kept mesh\n");
        ok = ok && same;
    }
    mirror_free(&now);
    trimesh_free(&fresh);
    trimesh_free(&live);
    return ok;
}

/* A ball of value in, radius r, in an n^3 block of value out, written at lo into k and vol (nx^3). */
static int edit_ball(struct iso_kept *k, int16_t *vol, const int dims[3], const int lo[3], int n, double r, int16_t in,
                     int16_t out, struct iso_edit *ed, struct iso_change *ch)
{
    int16_t *blk = malloc((size_t)n * n * n * sizeof *blk);
    for (int z = 0; z < n; z++)
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                double d = hypot(hypot(x - n / 2.0 + 0.3, y - n / 2.0 - 0.2), z - n / 2.0 + 0.1);
                int16_t v = d < r ? in : out;
                blk[x + n * (y + n * z)] = v;
                if (lo[0] + x < dims[0] && lo[1] + y < dims[1] && lo[2] + z < dims[2] && lo[0] >= 0 && lo[1] >= 0 &&
                    lo[2] >= 0)
                    vol[(lo[0] + x) + dims[0] * ((lo[1] + y) + (size_t)dims[1] * (lo[2] + z))] = v;
            }
    struct iso_grid bg = {n, n, n, ISO_I16, blk, {1, 1, 1}, {0, 0, 0}};
    struct sf_err err = {0};
    int rc = iso_kept_edit(k, lo, &bg, ed, ch, &err);
    free(blk);
    return rc;
}

#define CT_BYTES (64 * 64 * 64 * 2)
static char *ct_crop(void)
{
    size_t len;
    char *raw = unit_data("volumes", "ct_head_crop64_int16.raw", &len);
    CHECK(raw && len == CT_BYTES);
    return raw && len == CT_BYTES ? raw : (free(raw), NULL);
}

/* The first mesh is iso_extract's, byte for byte, ids 0 .. n-1. */
static bool first_is_extract(const struct iso_grid *g, const struct iso_opts *o)
{
    struct iso_kept *k;
    struct trimesh fresh, live;
    uint32_t *ids;
    struct sf_err err = {0};
    if (iso_kept_begin(g, o, &k, &err) || iso_extract(g, o, NULL, &fresh, &err) || iso_kept_mesh(k, &live, &ids, &err))
        return false;
    bool ok = live.n_tri == fresh.n_tri && live.n_vert == fresh.n_vert && fresh.n_tri > 0 &&
              !memcmp(live.pos, fresh.pos, 3 * fresh.n_vert * sizeof(float)) &&
              !memcmp(live.tri, fresh.tri, 3 * fresh.n_tri * sizeof(uint32_t)) &&
              (!o->normals || !memcmp(live.nrm, fresh.nrm, 3 * fresh.n_vert * sizeof(float)));
    for (size_t i = 0; i < live.n_tri && ok; i++)
        ok = ids[i] == i;
    ok = ok && iso_kept_bytes(k) > (size_t)g->nx * g->ny * g->nz;
    free(ids);
    trimesh_free(&fresh);
    trimesh_free(&live);
    iso_kept_free(k);
    return ok;
}

TEST(the_first_mesh_is_iso_extracts)
{
    char *raw = ct_crop();
    if (!raw)
        return;
    struct iso_grid g = {64, 64, 64, ISO_I16, raw, {0.9570312, 0.9570312, 1.5}, {-3, 2, 7}};
    for (int closed = 0; closed < 2; closed++)
        for (int normals = 0; normals < 2; normals++) {
            struct iso_opts o = {.iso = 226.5, .closed = closed, .normals = normals};
            CHECK(first_is_extract(&g, &o));
        }
    struct iso_opts o = {.iso = -500, .closed = true, .normals = true};
    CHECK(first_is_extract(&g, &o));
    free(raw);
}

/* A run of edits and iso changes on the CT crop, each checked against a fresh extraction and the
 * mirror of the changes; a second kept extraction given the same run reports the same changes. */
TEST(ct_edits_and_isos_equal_a_fresh_extraction)
{
    char *raw = ct_crop();
    if (!raw)
        return;
    int dims[3] = {64, 64, 64};
    int16_t *vol[2] = {memcpy(malloc(CT_BYTES), raw, CT_BYTES), memcpy(malloc(CT_BYTES), raw, CT_BYTES)};
    struct iso_opts o = {.iso = 226.5, .closed = true, .normals = true};
    struct iso_kept *k[2];
    struct sf_err err = {0};
    struct iso_grid g[2];
    for (int r = 0; r < 2; r++) {
        g[r] = (struct iso_grid){64, 64, 64, ISO_I16, vol[r], {0.9570312, 0.9570312, 1.5}, {0, 0, 0}};
        REQUIRE(iso_kept_begin(&g[r], &o, &k[r], &err) == 0);
    }
    struct mirror m = {0};
    struct trimesh first;
    CHECK(mirror_of(k[0], &m, &first));
    trimesh_free(&first);
    uint32_t next = (uint32_t)m.n;
    const int lo[][3] = {{20, 24, 17}, {0, 0, 0}, {48, 48, 48}, {30, 5, 40}, {21, 25, 18}, {8, 40, 3}, {50, 10, 50}};
    for (int e = 0; e < 7; e++) {
        struct iso_edit ed[2];
        struct iso_change ch[2];
        int n = e == 2 ? 16 : e == 6 ? 14 : 12;
        for (int r = 0; r < 2; r++)
            CHECK(edit_ball(k[r], vol[r], dims, lo[e], n, 4 + e, e & 1 ? -1000 : 1400, e & 1 ? 300 : -100, &ed[r],
                            &ch[r]) == 0);
        CHECK(ed[0].cells_rebuilt > 0 && ed[0].triangles_added > 0 && !ed[0].whole);
        CHECK(ed[0].cells_rebuilt <= (long)(n + 3) * (n + 3) * (n + 3));
        CHECK(ch[0].n_removed == (size_t)ed[0].triangles_removed && ch[0].n_added == (size_t)ed[0].triangles_added);
        CHECK(ch[0].n_added == ch[1].n_added && ch[0].n_removed == ch[1].n_removed &&
              !memcmp(ch[0].removed, ch[1].removed, ch[0].n_removed * sizeof(uint32_t)) &&
              !memcmp(ch[0].added, ch[1].added, ch[0].n_added * sizeof(uint32_t)) &&
              !memcmp(ch[0].corners, ch[1].corners, ch[0].n_added * 18 * sizeof(float)));
        CHECK(mirror_apply(&m, &ch[0], next));
        next = ch[0].next_id;
        CHECK(as_fresh(k[0], &g[0], &o, &m));
        for (int r = 0; r < 2; r++)
            iso_change_free(&ch[r]);
    }
    const double isos[] = {500, 100, 226.5, 1200};
    for (int i = 0; i < 4; i++) {
        struct iso_edit ed;
        struct iso_change ch;
        CHECK(iso_kept_iso(k[0], isos[i], true, &ed, &ch, &err) == 0);
        CHECK(ed.whole && ch.n_removed == m.n);
        CHECK(mirror_apply(&m, &ch, next));
        next = ch.next_id;
        o.iso = isos[i];
        CHECK(as_fresh(k[0], &g[0], &o, &m));
        iso_change_free(&ch);
    }
    /* and an edit at the last iso */
    struct iso_edit ed;
    struct iso_change ch;
    CHECK(edit_ball(k[0], vol[0], dims, (int[3]){30, 30, 30}, 16, 6, 2000, 900, &ed, &ch) == 0);
    CHECK(mirror_apply(&m, &ch, next));
    CHECK(as_fresh(k[0], &g[0], &o, &m));
    iso_change_free(&ch);
    mirror_free(&m);
    for (int r = 0; r < 2; r++) {
        iso_kept_free(k[r]);
        free(vol[r]);
    }
    free(raw);
}

/* Samples under the least move the pad: the whole grid is drawn again; so when they go. */
TEST(a_new_least_sample_redraws_every_cell)
{
    char *raw = ct_crop();
    if (!raw)
        return;
    int16_t *vol = memcpy(malloc(CT_BYTES), raw, CT_BYTES), least = INT16_MAX;
    for (size_t i = 0; i < CT_BYTES / 2; i++)
        least = vol[i] < least ? vol[i] : least;
    int dims[3] = {64, 64, 64};
    struct iso_grid g = {64, 64, 64, ISO_I16, vol, {0.9570312, 0.9570312, 1.5}, {0, 0, 0}};
    struct iso_opts o = {.iso = -500, .closed = true, .normals = true};
    struct iso_kept *k;
    struct sf_err err = {0};
    REQUIRE(iso_kept_begin(&g, &o, &k, &err) == 0);
    struct mirror m = {0};
    struct trimesh first;
    CHECK(mirror_of(k, &m, &first));
    trimesh_free(&first);
    struct iso_edit ed;
    struct iso_change ch;
    uint32_t next = (uint32_t)m.n;
    CHECK(edit_ball(k, vol, dims, (int[3]){10, 10, 10}, 8, 3, (int16_t)(least - 500), 0, &ed, &ch) == 0);
    CHECK(ed.whole);
    CHECK(mirror_apply(&m, &ch, next));
    next = ch.next_id;
    iso_change_free(&ch);
    CHECK(as_fresh(k, &g, &o, &m));
    CHECK(edit_ball(k, vol, dims, (int[3]){10, 10, 10}, 8, 3, 0, 0, &ed, &ch) == 0); /* the least gone again */
    CHECK(ed.whole);
    CHECK(mirror_apply(&m, &ch, next));
    iso_change_free(&ch);
    CHECK(as_fresh(k, &g, &o, &m));
    mirror_free(&m);
    iso_kept_free(k);
    free(vol);
    free(raw);
}

/* An analytic field (a torus in floats, not closed, and a sphere in bytes, closed): edits of every
 * size over every place of a small grid, and iso changes, each against a fresh extraction. */
TEST(analytic_fields_under_many_edits)
{
    enum { NX = 23, NY = 19, NZ = 21 };
    float *f = malloc(sizeof(float) * NX * NY * NZ);
    for (int z = 0; z < NZ; z++)
        for (int y = 0; y < NY; y++)
            for (int x = 0; x < NX; x++) {
                double X = x - 11.2, Y = y - 9.1, Z = z - 10.3, q = hypot(X, Y) - 6.0;
                f[x + NX * (y + NY * z)] = (float)(3.0 - hypot(q, Z));
            }
    struct iso_grid g = {NX, NY, NZ, ISO_F32, f, {1.0, 0.5, 2.0}, {0.5, 0, -1}};
    for (int closed = 0; closed < 2; closed++) {
        struct iso_opts o = {.iso = 0.25, .closed = closed, .normals = true};
        struct iso_kept *k;
        struct sf_err err = {0};
        REQUIRE(iso_kept_begin(&g, &o, &k, &err) == 0);
        CHECK(as_fresh(k, &g, &o, NULL));
        unsigned seed = 7;
        for (int e = 0; e < 24; e++) {
            int n[3], lo[3], dims[3] = {NX, NY, NZ};
            for (int d = 0; d < 3; d++) {
                seed = seed * 1103515245u + 12345u;
                n[d] = 1 + (int)(seed >> 16) % 7;
                seed = seed * 1103515245u + 12345u;
                lo[d] = (int)(seed >> 16) % (dims[d] - n[d] + 1);
            }
            float *b = malloc(sizeof(float) * n[0] * n[1] * n[2]);
            for (int i = 0; i < n[0] * n[1] * n[2]; i++) {
                seed = seed * 1103515245u + 12345u;
                b[i] = (float)((seed >> 16) % 1000) / 250.0f - 2.0f; /* (-2 .. 2: below the least, now and then) */
            }
            for (int z = 0; z < n[2]; z++)
                for (int y = 0; y < n[1]; y++)
                    for (int x = 0; x < n[0]; x++)
                        f[lo[0] + x + NX * (lo[1] + y + NY * (lo[2] + z))] = b[x + n[0] * (y + n[1] * z)];
            struct iso_grid bg = {n[0], n[1], n[2], ISO_F32, b, {1, 1, 1}, {0, 0, 0}};
            struct iso_edit ed;
            struct iso_change ch;
            CHECK(iso_kept_edit(k, lo, &bg, &ed, &ch, &err) == 0);
            CHECK(as_fresh(k, &g, &o, NULL));
            iso_change_free(&ch);
            free(b);
            if (e % 8 == 7) {
                o.iso = e == 7 ? -0.5 : e == 15 ? 1.25 : 0.25;
                CHECK(iso_kept_iso(k, o.iso, false, &ed, &ch, &err) == 0 && !ch.corners);
                CHECK(as_fresh(k, &g, &o, NULL));
                iso_change_free(&ch);
            }
        }
        iso_kept_free(k);
    }
    free(f);
}

/* A byte volume edited with blocks of int16 (converted), no normals: corners' normals are 0. */
TEST(bytes_without_normals)
{
    enum { N = 30 };
    uint8_t *v = malloc(N * N * N);
    for (int z = 0; z < N; z++)
        for (int y = 0; y < N; y++)
            for (int x = 0; x < N; x++)
                v[x + N * (y + N * z)] = (uint8_t)(hypot(hypot(x - 14.5, y - 13.7), z - 15.2) < 9 ? 200 : 20);
    struct iso_grid g = {N, N, N, ISO_U8, v, {1, 1, 1}, {0, 0, 0}};
    struct iso_opts o = {.iso = 100.5, .closed = true};
    struct iso_kept *k;
    struct sf_err err = {0};
    REQUIRE(iso_kept_begin(&g, &o, &k, &err) == 0);
    int16_t blk[4 * 4 * 4];
    for (int i = 0; i < 64; i++)
        blk[i] = (int16_t)(i % 3 ? 250 : 10);
    struct iso_grid bg = {4, 4, 4, ISO_I16, blk, {1, 1, 1}, {0, 0, 0}};
    for (int z = 0; z < 4; z++)
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++)
                v[5 + x + N * (6 + y + N * (7 + z))] = (uint8_t)blk[x + 4 * (y + 4 * z)];
    struct iso_edit ed;
    struct iso_change ch;
    CHECK(iso_kept_edit(k, (int[3]){5, 6, 7}, &bg, &ed, &ch, &err) == 0);
    bool zero = true;
    for (size_t i = 0; i < ch.n_added; i++)
        for (int q = 0; q < 3; q++)
            zero = zero && ch.corners[18 * i + 6 * q + 3] == 0 && ch.corners[18 * i + 6 * q + 5] == 0;
    CHECK(zero && ch.n_added > 0);
    iso_change_free(&ch);
    struct trimesh fresh, live;
    uint32_t *ids;
    CHECK(iso_extract(&g, &o, NULL, &fresh, &err) == 0 && iso_kept_mesh(k, &live, &ids, &err) == 0);
    CHECK(live.nrm == NULL && live.n_tri == fresh.n_tri);
    free(ids);
    trimesh_free(&fresh);
    trimesh_free(&live);
    iso_kept_free(k);
    free(v);
}

TEST(bad_regions_and_isos_are_refused)
{
    enum { N = 12 };
    int16_t *v = calloc(N * N * N, sizeof *v);
    for (int i = 0; i < N * N * N; i++)
        v[i] = (int16_t)(i % 7 * 100);
    struct iso_grid g = {N, N, N, ISO_I16, v, {1, 1, 1}, {0, 0, 0}};
    struct iso_opts o = {.iso = 250, .closed = true, .normals = true};
    struct iso_kept *k;
    struct sf_err err = {0};
    REQUIRE(iso_kept_begin(&g, &o, &k, &err) == 0);
    int16_t blk[27] = {0};
    struct iso_grid bg = {3, 3, 3, ISO_I16, blk, {1, 1, 1}, {0, 0, 0}};
    struct iso_edit ed;
    struct iso_change ch;
    CHECK(iso_kept_edit(k, (int[3]){10, 0, 0}, &bg, &ed, &ch, &err) == SF_EINVAL);
    CHECK_STR(err.pointer, "?region");
    CHECK(iso_kept_edit(k, (int[3]){0, -1, 0}, &bg, &ed, &ch, &err) == SF_EINVAL);
    err = (struct sf_err){0}; /* (the first failure is the one kept) */
    CHECK(iso_kept_iso(k, NAN, true, &ed, &ch, &err) == SF_EINVAL);
    CHECK_STR(err.pointer, "?value");
    CHECK(iso_kept_iso(k, 601, true, &ed, &ch, &err) == SF_EINVAL);
    CHECK(iso_kept_iso(k, -1, true, &ed, &ch, &err) == SF_EINVAL);
    err = (struct sf_err){0};
    CHECK(iso_kept_iso(k, 600, true, &ed, &ch, &err) == SF_EINVAL); /* (the greatest: no surface) */
    iso_change_free(&ch);
    CHECK(iso_kept_edit(k, (int[3]){9, 9, 9}, &bg, &ed, &ch, &err) == 0); /* still of use */
    iso_change_free(&ch);
    iso_kept_free(k);
    /* a limit on the triangles */
    o.max_triangles = 10;
    err = (struct sf_err){0};
    CHECK(iso_kept_begin(&g, &o, &k, &err) == SF_ELIMIT);
    free(v);
}

int main(void)
{
    iso_init();
    RUN(the_first_mesh_is_iso_extracts);
    RUN(ct_edits_and_isos_equal_a_fresh_extraction);
    RUN(a_new_least_sample_redraws_every_cell);
    RUN(analytic_fields_under_many_edits);
    RUN(bytes_without_normals);
    RUN(bad_regions_and_isos_are_refused);
    UNIT_END();
}
