/* test_mesh_journal.c - a model's mesh as a base and a journal of changes (api/mesh_journal.h),
 * driven by the changes real edits of the shared CT crop make (core/iso/adapt.c): the base with
 * the changes applied is the kept mesh, triangle for triangle and id for id; the delta from any
 * version, applied to that version's mesh by id, gives the current one; a triangle added and taken
 * out again between two versions is in neither list; damaged or out-of-order changes are refused. */
#include "../../api/mesh_io.h"
#include "../../api/mesh_journal.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "../unit.h"

/* A mesh as sorted (id, 9 floats) records: the same mesh by id whatever the order. */
struct rec {
    uint32_t id;
    float p[9];
};
static int cmp_rec(const void *a, const void *b)
{
    const struct rec *x = a, *y = b;
    return x->id < y->id ? -1 : x->id > y->id;
}
static struct rec *records(const struct trimesh *m, const uint32_t *ids)
{
    struct rec *r = malloc((m->n_tri ? m->n_tri : 1) * sizeof *r);
    for (size_t t = 0; t < m->n_tri; t++) {
        r[t].id = ids[t];
        for (int c = 0; c < 9; c++)
            r[t].p[c] = m->pos[3 * m->tri[3 * t + c / 3] + c % 3];
    }
    qsort(r, m->n_tri, sizeof *r, cmp_rec);
    return r;
}

/* A client's mesh by id (what the page keeps): records, applied deltas to. */
struct client {
    struct rec *r;
    size_t n;
    uint32_t version;
};

static uint32_t rd32(const unsigned char *p) { return p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24; }

static bool apply_delta(struct client *c, const char *d, size_t len)
{
    const unsigned char *p = (const unsigned char *)d;
    if (len < 20 || memcmp(p, "SFMD", 4) || rd32(p + 4) != c->version)
        return false;
    uint32_t to = rd32(p + 8), nr = rd32(p + 12), na = rd32(p + 16);
    if (len != 20 + 4 * (size_t)nr + 40 * (size_t)na)
        return false;
    size_t gone = 0;
    for (uint32_t i = 0; i < nr; i++) { /* (marked first, then dropped: the list stays sorted to search) */
        struct rec key = {rd32(p + 20 + 4 * i), {0}}, *hit = bsearch(&key, c->r, c->n, sizeof *c->r, cmp_rec);
        if (!hit || hit->p[0] != hit->p[0])
            return false;
        hit->p[0] = NAN;
    }
    for (size_t k = 0; k < c->n; k++)
        if (c->r[k].p[0] == c->r[k].p[0])
            c->r[gone++] = c->r[k];
    c->n = gone;
    c->r = realloc(c->r, (c->n + na + 1) * sizeof *c->r);
    for (uint32_t i = 0; i < na; i++) {
        const unsigned char *t = p + 20 + 4 * (size_t)nr + 40 * (size_t)i;
        c->r[c->n + i].id = rd32(t);
        memcpy(c->r[c->n + i].p, t + 4, 36);
    }
    c->n += na;
    qsort(c->r, c->n, sizeof *c->r, cmp_rec);
    c->version = to;
    return true;
}

static bool same_records(const struct rec *a, size_t na, const struct rec *b, size_t nb)
{
    return na == nb && !memcmp(a, b, na * sizeof *a);
}

#define CT_BYTES (64 * 64 * 64 * 2)

/* The shared CT crop (NULL, with a failed check, when ../shared/data lacks it). */
static char *ct_crop(void)
{
    size_t len;
    char *raw = unit_data("volumes", "ct_head_crop64_int16.raw", &len);
    CHECK(raw && len == CT_BYTES);
    if (raw && len != CT_BYTES) {
        free(raw);
        raw = NULL;
    }
    return raw;
}

TEST(a_base_and_its_changes_are_the_kept_mesh)
{
    char *raw = ct_crop();
    if (!raw)
        return;
    struct iso_grid g = {64, 64, 64, ISO_I16, raw, {0.9570312, 0.9570312, 1.5}, {0, 0, 0}};
    struct iso_opts o = {.iso = 226.5, .closed = true, .normals = true, .keep = true};
    struct iso_adapt *a;
    struct iso_adapt_stats st;
    struct sf_err err = {0};
    CHECK(iso_adapt_begin(&g, &o, 2, 0.5, &a, &err) == 0);
    for (int p = 0; p < iso_adapt_phases(a); p++) {
        for (int s = 0; s < iso_adapt_n_slabs(a); s++)
            iso_adapt_run(a, p, s);
        iso_adapt_between(a, p);
    }
    CHECK(iso_adapt_keep(a, &st, &err) == 0);
    struct trimesh m;
    uint32_t *ids;
    char *base, *cur;
    size_t base_len, cur_len;
    CHECK(iso_adapt_mesh(a, &m, &st, &err) == 0 && iso_adapt_ids(a, &ids, &err) == 0);
    CHECK(mesh_pack_ids(&m, ids, 1, &base, &base_len, &err) == 0);
    struct client first = {records(&m, ids), m.n_tri, 1};
    trimesh_free(&m);
    free(ids);
    /* six edits, each a change of the journal */
    enum { EDITS = 6 };
    char *chg[EDITS];
    struct mesh_change journal[EDITS];
    for (int e = 0; e < EDITS; e++) {
        int lo[3] = {8 + 6 * e, 22, 12 + 4 * e}, n = e == 3 ? 12 : 8;
        int16_t *blk = malloc((size_t)n * n * n * sizeof *blk);
        for (int i = 0; i < n * n * n; i++)
            blk[i] = (int16_t)(e % 2 ? -900 : 1600);
        if (e == 4) /* the same place as edit 3: what 3 added, 4 takes out again */
            memcpy(lo, (int[3]){8 + 18, 22, 12 + 12}, sizeof lo);
        struct iso_grid bg = {n, n, n, ISO_I16, blk, {1, 1, 1}, {0, 0, 0}};
        struct iso_edit ed;
        struct iso_change ch;
        CHECK(iso_adapt_edit_ids(a, lo, &bg, &ed, &ch, &err) == 0);
        CHECK(mesh_change_encode(&ch, (uint32_t)e + 2, &chg[e], &journal[e].len, &err) == 0);
        CHECK(mesh_change_version(chg[e], journal[e].len) == (uint32_t)e + 2);
        journal[e].data = chg[e];
        iso_change_free(&ch);
        free(blk);
    }
    CHECK(iso_adapt_mesh(a, &m, &st, &err) == 0 && iso_adapt_ids(a, &ids, &err) == 0);
    struct rec *now = records(&m, ids);
    size_t n_now = m.n_tri;
    trimesh_free(&m);
    free(ids);
    /* the base with every change applied: the kept mesh, id for id, with its vertices shared */
    uint64_t version;
    CHECK(mesh_changes_apply(base, base_len, journal, EDITS, &cur, &cur_len, &err) == 0);
    CHECK(mesh_unpack_ids(cur, cur_len, &m, &ids, &version, &err) == 0 && version == EDITS + 1);
    struct rec *got = records(&m, ids);
    CHECK(same_records(got, m.n_tri, now, n_now));
    struct trimesh_stats ts;
    CHECK(trimesh_stats(&m, &ts, &err) == 0 && ts.boundary_edges == 0 && ts.nonmanifold_edges == 0);
    free(got);
    trimesh_free(&m);
    free(ids);
    /* applied in two steps (a base compacted at version 4): the same */
    char *mid, *cur2;
    size_t mid_len, cur2_len;
    CHECK(mesh_changes_apply(base, base_len, journal, 3, &mid, &mid_len, &err) == 0);
    CHECK(mesh_changes_apply(mid, mid_len, journal + 3, EDITS - 3, &cur2, &cur2_len, &err) == 0);
    CHECK(cur2_len == cur_len && !memcmp(cur, cur2, cur_len));
    /* deltas from every version, applied to that version's mesh */
    for (uint32_t from = 0; from <= EDITS; from++) {
        struct client c = {0};
        if (from) { /* that version's mesh: the first, then the deltas of one version each */
            c = (struct client){memcpy(malloc(first.n * sizeof *first.r), first.r, first.n * sizeof *first.r), first.n, 1};
            for (uint32_t v = 1; v < from; v++) {
                char *d;
                size_t dl;
                CHECK(mesh_changes_delta(journal + v - 1, 1, v, v + 1, NULL, 0, &d, &dl, &err) == 0 && apply_delta(&c, d, dl));
                free(d);
            }
        }
        char *d;
        size_t dl;
        if (from == 0) { /* since=0: the base's triangles added, then the rest */
            c = (struct client){NULL, 0, 0};
            c.r = memcpy(malloc(first.n * sizeof *first.r), first.r, first.n * sizeof *first.r), c.n = first.n, c.version = 1;
        }
        CHECK(mesh_changes_delta(journal + (from ? from - 1 : 0), EDITS + 1 - (from ? from : 1), from ? from : 1,
                                 EDITS + 1, NULL, 0, &d, &dl, &err) == 0);
        CHECK(apply_delta(&c, d, dl));
        if (!same_records(c.r, c.n, now, n_now))
            fprintf(stderr, "  from %u: %zu records against %zu\n", from, c.n, n_now);
        CHECK(same_records(c.r, c.n, now, n_now));
        free(d);
        free(c.r);
    }
    /* what the change to version 5 added and the next took out again is in neither list of the
     * delta 4 -> 6 */
    char *d;
    size_t dl;
    CHECK(mesh_changes_delta(journal + 3, 2, 4, 6, NULL, 0, &d, &dl, &err) == 0);
    const unsigned char *c5 = (const unsigned char *)chg[3], *c6 = (const unsigned char *)chg[4];
    const unsigned char *p = (const unsigned char *)d;
    uint32_t nr5 = rd32(c5 + 8), na5 = rd32(c5 + 12), nr6 = rd32(c6 + 8), nr = rd32(p + 12), na = rd32(p + 16);
    size_t again = 0, listed = 0;
    for (uint32_t i = 0; i < na5; i++) {
        uint32_t id = rd32(c5 + 16 + 4 * nr5 + 76 * i);
        bool gone = false;
        for (uint32_t k = 0; k < nr6; k++)
            gone = gone || rd32(c6 + 16 + 4 * k) == id;
        again += gone;
        for (uint32_t k = 0; k < nr && gone; k++)
            listed += rd32(p + 20 + 4 * k) == id;
        for (uint32_t k = 0; k < na && gone; k++)
            listed += rd32(p + 20 + 4 * nr + 40 * k) == id;
    }
    CHECK(again > 0 && listed == 0);
    free(d);
    /* refused: a gap, a change out of order, damage, a change that does not follow the base */
    CHECK(mesh_changes_delta(journal, 2, 1, 4, NULL, 0, &d, &dl, &err) == SF_EFORMAT);
    CHECK(mesh_changes_delta(journal + 1, 2, 1, 3, NULL, 0, &d, &dl, &err) == SF_EFORMAT);
    struct mesh_change cut = {journal[0].data, journal[0].len - 1};
    CHECK(mesh_changes_delta(&cut, 1, 1, 2, NULL, 0, &d, &dl, &err) == SF_EFORMAT);
    CHECK(mesh_changes_apply(cur, cur_len, journal, 1, &d, &dl, &err) == SF_EFORMAT);
    CHECK(mesh_changes_apply(base, base_len, journal + 1, 1, &d, &dl, &err) == SF_EFORMAT);
    for (int e = 0; e < EDITS; e++)
        free(chg[e]);
    free(first.r);
    free(now);
    free(base), free(cur), free(mid), free(cur2);
    iso_adapt_free(a);
    free(raw);
}

/* Client c (at some version) and the current mesh cur: c's version at to and its records cur's. */
static bool delta_brings(struct client *c, const struct mesh_change *ch, size_t n, uint32_t to, const char *cur,
                         size_t cur_len)
{
    char *d = NULL;
    size_t dl;
    struct sf_err err = {0};
    struct trimesh m;
    uint32_t *ids;
    uint64_t v;
    bool ok = mesh_changes_delta(ch, n, c->version, to, cur, cur_len, &d, &dl, &err) == 0 && apply_delta(c, d, dl) &&
              mesh_unpack_ids(cur, cur_len, &m, &ids, &v, &err) == 0;
    if (ok) {
        struct rec *r = records(&m, ids);
        ok = same_records(c->r, c->n, r, m.n_tri);
        free(r), free(ids), trimesh_free(&m);
    }
    free(d);
    return ok;
}

/* Marching cubes kept (levels 1): an edit (v2), a new iso (v3: a whole change, stored with its
 * base), an edit (v4). A delta across the whole change adds every triangle of the current mesh and
 * takes out every one the client holds; without the current mesh, or with one of another version,
 * it is refused, and a whole change is not applied to an older base. */
TEST(a_whole_change_is_composed_with_the_current_mesh)
{
    char *raw = ct_crop();
    if (!raw)
        return;
    struct iso_grid g = {64, 64, 64, ISO_I16, raw, {0.9570312, 0.9570312, 1.5}, {0, 0, 0}};
    struct iso_opts o = {.iso = 226.5, .closed = true, .normals = true};
    struct iso_kept *k;
    struct sf_err err = {0};
    REQUIRE(iso_kept_begin(&g, &o, &k, &err) == 0);
    struct trimesh m;
    uint32_t *ids;
    char *base1, *base3, *cur, *chg[3];
    size_t base1_len, base3_len, cur_len, chg_len[3];
    CHECK(iso_kept_mesh(k, &m, &ids, &err) == 0 && mesh_pack_ids(&m, ids, 1, &base1, &base1_len, &err) == 0);
    struct client c1 = {records(&m, ids), m.n_tri, 1}, c2;
    trimesh_free(&m), free(ids);
    int16_t blk[8 * 8 * 8];
    for (int i = 0; i < 8 * 8 * 8; i++)
        blk[i] = 1600;
    struct iso_grid bg = {8, 8, 8, ISO_I16, blk, {1, 1, 1}, {0, 0, 0}};
    struct iso_edit ed;
    struct iso_change ch;
    CHECK(iso_kept_edit(k, (int[3]){20, 24, 17}, &bg, &ed, &ch, &err) == 0 && !ed.whole);
    CHECK(mesh_change_encode(&ch, 2, &chg[0], &chg_len[0], &err) == 0);
    iso_change_free(&ch);
    CHECK(iso_kept_iso(k, 500, false, &ed, &ch, &err) == 0 && ed.whole);
    CHECK(mesh_change_encode_whole(&ch, 3, &chg[1], &chg_len[1], &err) == 0);
    CHECK(mesh_change_whole(chg[1], chg_len[1]) && !mesh_change_whole(chg[0], chg_len[0]) &&
          mesh_change_version(chg[1], chg_len[1]) == 3);
    iso_change_free(&ch);
    CHECK(iso_kept_mesh(k, &m, &ids, &err) == 0 && mesh_pack_ids(&m, ids, 3, &base3, &base3_len, &err) == 0);
    trimesh_free(&m), free(ids);
    CHECK(iso_kept_edit(k, (int[3]){30, 8, 40}, &bg, &ed, &ch, &err) == 0 && !ed.whole);
    CHECK(mesh_change_encode(&ch, 4, &chg[2], &chg_len[2], &err) == 0);
    iso_change_free(&ch);
    struct mesh_change journal[3] = {{chg[0], chg_len[0]}, {chg[1], chg_len[1]}, {chg[2], chg_len[2]}};
    CHECK(mesh_changes_apply(base3, base3_len, journal + 2, 1, &cur, &cur_len, &err) == 0);
    /* the client at version 2 first: v1 and the change to 2 */
    c2 = (struct client){memcpy(malloc(c1.n * sizeof *c1.r), c1.r, c1.n * sizeof *c1.r), c1.n, 1};
    char *d = NULL;
    size_t dl;
    CHECK(mesh_changes_delta(journal, 1, 1, 2, NULL, 0, &d, &dl, &err) == 0 && apply_delta(&c2, d, dl));
    free(d);
    /* a slider's step: the whole change alone (composed without the id table), then on from it */
    struct client c3 = {memcpy(malloc(c2.n * sizeof *c2.r), c2.r, c2.n * sizeof *c2.r), c2.n, 2};
    CHECK(delta_brings(&c3, journal + 1, 1, 3, base3, base3_len) && c3.version == 3);
    CHECK(delta_brings(&c3, journal + 2, 1, 4, cur, cur_len) && c3.version == 4);
    CHECK(mesh_changes_delta(journal + 1, 1, 2, 3, cur, cur_len, &d, &dl, &err) == SF_EFORMAT);
    free(c3.r);
    CHECK(delta_brings(&c1, journal, 3, 4, cur, cur_len) && c1.version == 4);
    CHECK(delta_brings(&c2, journal + 1, 2, 4, cur, cur_len) && c2.version == 4);
    CHECK(mesh_changes_delta(journal, 3, 1, 4, NULL, 0, &d, &dl, &err) == SF_EFORMAT);
    CHECK(mesh_changes_delta(journal, 3, 1, 4, base3, base3_len, &d, &dl, &err) == SF_EFORMAT);
    CHECK(mesh_changes_apply(base1, base1_len, journal, 2, &d, &dl, &err) == SF_EFORMAT);
    for (int i = 0; i < 3; i++)
        free(chg[i]);
    free(c1.r), free(c2.r);
    free(base1), free(base3), free(cur);
    iso_kept_free(k);
    free(raw);
}

int main(void)
{
    iso_init();
    RUN(a_base_and_its_changes_are_the_kept_mesh);
    RUN(a_whole_change_is_composed_with_the_current_mesh);
    UNIT_END();
}
