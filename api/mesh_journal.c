/* mesh_journal.c - a model's mesh as a base and a journal of changes (mesh_journal.h): changes
 * encoded, composed into API.md's delta, and applied to the base. By hand: a few hundred lines of
 * byte layout and an id table, which no library of the project's does. */
#include "mesh_journal.h"

#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "../core/base/mem.h"
#include "mesh_io.h"

static uint32_t le32(const unsigned char *p) { return p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24; }

static void put32(unsigned char *p, uint32_t v)
{
    for (int k = 0; k < 4; k++)
        p[k] = (unsigned char)(v >> (8 * k));
}

/* Change ch's bytes: its header (magic), the ids removed, then each triangle added in each bytes
 * (its id, and with 76 its corners). */
static int encode(const struct iso_change *ch, const char *magic, size_t each, uint32_t version, char **out,
                  size_t *len, struct sf_err *err)
{
    size_t n = 16 + 4 * ch->n_removed + each * ch->n_added;
    unsigned char *b = malloc(n), *p = b;
    if (!b)
        return sf_fail(err, SF_ENOMEM, "", "out of memory writing the mesh change");
    memcpy(p, magic, 4);
    put32(p + 4, version), put32(p + 8, (uint32_t)ch->n_removed), put32(p + 12, (uint32_t)ch->n_added);
    p += 16;
    for (size_t k = 0; k < ch->n_removed; k++, p += 4)
        put32(p, ch->removed[k]);
    for (size_t k = 0; k < ch->n_added; k++, p += each) {
        put32(p, ch->added[k]);
        for (int c = 0; each == 76 && c < 18; c++) {
            uint32_t bits;
            memcpy(&bits, ch->corners + 18 * k + c, 4);
            put32(p + 4 + 4 * c, bits);
        }
    }
    *out = (char *)b, *len = n;
    return 0;
}

int mesh_change_encode(const struct iso_change *ch, uint32_t version, char **out, size_t *len, struct sf_err *err)
{
    return encode(ch, "SFMC", 76, version, out, len, err);
}

int mesh_change_encode_whole(const struct iso_change *ch, uint32_t version, char **out, size_t *len,
                             struct sf_err *err)
{
    return encode(ch, "SFMW", 4, version, out, len, err);
}

/* A change's counts, checked against its length: its bytes a triangle added (76; a whole one's 4),
 * or 0 when it is not one. */
static size_t change_of(const struct mesh_change *c, uint32_t *version, uint32_t *n_removed, uint32_t *n_added)
{
    const unsigned char *p = c->data;
    if (c->len < 16 || (memcmp(p, "SFMC", 4) && memcmp(p, "SFMW", 4)))
        return 0;
    size_t each = p[3] == 'W' ? 4 : 76;
    *version = le32(p + 4), *n_removed = le32(p + 8), *n_added = le32(p + 12);
    return c->len == 16 + 4 * (uint64_t)*n_removed + each * (uint64_t)*n_added ? each : 0;
}

uint32_t mesh_change_version(const void *data, size_t len)
{
    uint32_t v, r, a;
    return change_of(&(struct mesh_change){data, len}, &v, &r, &a) ? v : 0;
}

bool mesh_change_whole(const void *data, size_t len)
{
    uint32_t v, r, a;
    return change_of(&(struct mesh_change){data, len}, &v, &r, &a) == 4;
}

/* ---- an id table: id -> a value, open addressing ---- */

struct ids {
    uint32_t *key;
    size_t *val;
    size_t cap, n;           /* cap a power of two; EMPTY marks a free slot */
};
#define EMPTY SIZE_MAX

static size_t slot(const struct ids *t, uint32_t id)
{
    size_t h = (id * 2654435761u) & (t->cap - 1);
    while (t->val[h] != EMPTY && t->key[h] != id)
        h = (h + 1) & (t->cap - 1);
    return h;
}

static int ids_init(struct ids *t, size_t n)
{
    t->cap = 16;
    while (t->cap < 2 * n + 16)
        t->cap *= 2;
    t->n = 0;
    t->key = malloc(t->cap * sizeof *t->key);
    t->val = malloc(t->cap * sizeof *t->val);
    if (!t->key || !t->val)
        return -1;
    for (size_t k = 0; k < t->cap; k++)
        t->val[k] = EMPTY;
    return 0;
}

static void ids_free(struct ids *t)
{
    free(t->key);
    free(t->val);
}

/* Deleting from linear probing: the slots after it moved back where their probe allows. */
static void ids_remove(struct ids *t, size_t h)
{
    t->val[h] = EMPTY;
    t->n--;
    for (size_t j = (h + 1) & (t->cap - 1); t->val[j] != EMPTY; j = (j + 1) & (t->cap - 1)) {
        size_t want = (t->key[j] * 2654435761u) & (t->cap - 1);
        /* j's entry may fill the hole at h unless its home lies cyclically in (h, j] */
        if ((j > h && (want <= h || want > j)) || (j < h && want <= h && want > j)) {
            t->key[h] = t->key[j], t->val[h] = t->val[j];
            t->val[j] = EMPTY;
            h = j;
        }
    }
}

/* ---- deltas ---- */

/* Triangle t of packed mesh v as a delta's added record at p: its id, then its corners' places (40
 * bytes). 0, or -1: a corner past its vertices. */
static int put_added(unsigned char *p, const struct mesh_packed *v, size_t t)
{
    put32(p, mesh_packed_id(v, t));
    for (int c = 0; c < 3; c++) {
        uint32_t i = mesh_packed_corner(v, t, c), bits[3];
        if (i >= v->n_vert)
            return -1;
        memcpy(bits, v->pos + 12 * (size_t)i, 12);
        for (int d = 0; d < 3; d++)
            put32(p + 4 + 12 * c + 4 * d, bits[d]);
    }
    return 0;
}

/* The current mesh (packed with ids, of version to) seen in place; SF_EFORMAT when it is not. */
static int mesh_of(const char *mesh, size_t mesh_len, uint32_t to, struct mesh_packed *v, struct sf_err *err)
{
    if (!mesh)
        return sf_fail(err, SF_EFORMAT, "", "a whole change is composed with the current mesh");
    int rc = mesh_packed_view(mesh, mesh_len, v, err);
    return rc ? rc : v->version != to ? sf_fail(err, SF_EFORMAT, "", "the mesh is not of the version its changes make") : 0;
}

/* The triangles added of a delta, from the current mesh (packed with ids, of version to): every
 * one, each in table added (what the changes leave). 0 or SF_EFORMAT. */
static int added_from_mesh(const char *mesh, size_t mesh_len, uint32_t to, struct ids *added, unsigned char **p,
                           struct sf_err *err)
{
    struct mesh_packed v;
    int rc = mesh_of(mesh, mesh_len, to, &v, err);
    if (!rc && v.n_tri != added->n)
        rc = sf_fail(err, SF_EFORMAT, "", "the mesh is not of the version its changes make");
    for (size_t t = 0; t < v.n_tri && !rc; t++, *p += 40) {
        uint32_t id = mesh_packed_id(&v, t);
        if (added->val[slot(added, id)] == EMPTY)
            rc = sf_fail(err, SF_EFORMAT, "", "the mesh holds triangle %u, which its changes do not add", id);
        else if (put_added(*p, &v, t))
            rc = sf_fail(err, SF_EFORMAT, "", "a packed mesh with a vertex index out of range");
    }
    return rc;
}

/* The delta of one whole change (an iso change: every triangle out, the mesh's in, numbered as the
 * change lists them), without the id table: 1 when it is not that case (the caller composes it),
 * else 0 or an error. Read from the packed mesh in place: a slider's step on the CT head some 15-40
 * ms, not 250 (the table) or 40-100 (the mesh unpacked first). */
static int one_whole(const struct mesh_change *ch, uint32_t from, uint32_t to, const char *mesh, size_t mesh_len,
                     char **out, size_t *len, struct sf_err *err)
{
    const unsigned char *c = ch->data;
    uint32_t nr = le32(c + 8), na = le32(c + 12);
    struct mesh_packed v;
    int rc = mesh_of(mesh, mesh_len, to, &v, err);
    if (rc)
        return rc;
    const unsigned char *q = c + 16 + 4 * (size_t)nr;
    bool same = v.n_tri == na;
    for (size_t t = 0; t < v.n_tri && same; t++)
        same = mesh_packed_id(&v, t) == le32(q + 4 * t);
    if (!same)
        return 1;
    unsigned char *b = malloc(20 + 4 * (size_t)nr + 40 * (size_t)na), *p = b;
    if (!b)
        return sf_fail(err, SF_ENOMEM, "", "out of memory writing the mesh delta");
    memcpy(p, "SFMD", 4);
    put32(p + 4, from), put32(p + 8, to), put32(p + 12, nr), put32(p + 16, na);
    memcpy(p + 20, c + 16, 4 * (size_t)nr); /* (both little-endian u32) */
    p += 20 + 4 * (size_t)nr;
    for (size_t t = 0; t < v.n_tri; t++, p += 40)
        if (put_added(p, &v, t)) {
            free(b);
            return sf_fail(err, SF_EFORMAT, "", "a packed mesh with a vertex index out of range");
        }
    *out = (char *)b, *len = (size_t)(p - b);
    return 0;
}

int mesh_changes_delta(const struct mesh_change *ch, size_t n, uint32_t from, uint32_t to, const char *mesh,
                       size_t mesh_len, char **out, size_t *len, struct sf_err *err)
{
    uint32_t v1, r1, a1;
    if (n == 1 && mesh && change_of(&ch[0], &v1, &r1, &a1) == 4 && v1 == from + 1 && to == v1) {
        int rc = one_whole(&ch[0], from, to, mesh, mesh_len, out, len, err);
        if (rc != 1)
            return rc;
    }
    size_t total_added = 0, total_removed = 0;
    bool whole = false;
    for (size_t k = 0; k < n; k++) {
        uint32_t v, r, a;
        size_t each = change_of(&ch[k], &v, &r, &a);
        if (!each || v != from + 1 + k)
            return sf_fail(err, SF_EFORMAT, "", "the model's stored changes are damaged or out of order");
        total_added += a, total_removed += r, whole |= each == 4;
    }
    if (from + n != to)
        return sf_fail(err, SF_EFORMAT, "", "the model's stored changes stop at version %u, not %u", from + (uint32_t)n, to);
    /* added: id -> where its triangle is (change k, index i: k << 32 | i); removed: ids of triangles
     * older than from */
    struct ids added;
    uint32_t *removed = malloc((total_removed ? total_removed : 1) * sizeof *removed);
    size_t n_removed = 0;
    int rc = ids_init(&added, total_added) || !removed ? -1 : 0;
    for (size_t k = 0; k < n && !rc; k++) {
        const unsigned char *p = ch[k].data;
        uint32_t nr = le32(p + 8), na = le32(p + 12);
        size_t each = p[3] == 'W' ? 4 : 76;
        for (uint32_t i = 0; i < nr; i++) {
            uint32_t id = le32(p + 16 + 4 * i);
            size_t h = slot(&added, id);
            if (added.val[h] != EMPTY)
                ids_remove(&added, h);
            else
                removed[n_removed++] = id;
        }
        const unsigned char *q = p + 16 + 4 * (size_t)nr;
        for (uint32_t i = 0; i < na; i++) {
            uint32_t id = le32(q + each * i);
            size_t h = slot(&added, id);
            added.n += added.val[h] == EMPTY;
            added.key[h] = id, added.val[h] = (size_t)k << 32 | i;
        }
    }
    unsigned char *b = rc ? NULL : malloc(20 + 4 * n_removed + 40 * added.n), *p = b;
    if (!b) {
        ids_free(&added);
        free(removed);
        return sf_fail(err, SF_ENOMEM, "", "out of memory writing the mesh delta");
    }
    memcpy(p, "SFMD", 4);
    put32(p + 4, from), put32(p + 8, to), put32(p + 12, (uint32_t)n_removed), put32(p + 16, (uint32_t)added.n);
    p += 20;
    for (size_t k = 0; k < n_removed; k++, p += 4)
        put32(p, removed[k]);
    if (whole) /* (every triangle now was added since from: the mesh's) */
        rc = added_from_mesh(mesh, mesh_len, to, &added, &p, err);
    /* the triangles added, in the order the changes added them (their ids rise) */
    for (size_t k = 0; k < n && !whole; k++) {
        const unsigned char *c = ch[k].data;
        uint32_t nr = le32(c + 8), na = le32(c + 12);
        const unsigned char *q = c + 16 + 4 * (size_t)nr;
        for (uint32_t i = 0; i < na; i++) {
            const unsigned char *t = q + 76 * (size_t)i;
            size_t h = slot(&added, le32(t));
            if (added.val[h] != ((size_t)k << 32 | i))
                continue; /* taken out again, or added again later */
            memcpy(p, t, 4);
            for (int corner = 0; corner < 3; corner++)
                memcpy(p + 4 + 12 * corner, t + 4 + 24 * corner, 12);
            p += 40;
        }
    }
    if (rc)
        free(b);
    else
        *out = (char *)b, *len = (size_t)(p - b);
    ids_free(&added);
    free(removed);
    return rc;
}

/* ---- the current mesh ---- */

/* A vertex table keyed by position and normal (6 floats' bits). */
struct verts {
    size_t *slot, cap;
    size_t pcap, ncap;       /* of the mesh's positions and normals, in floats */
};

static size_t vhash(const float *pn)
{
    uint64_t h = 1469598103934665603ull;
    const unsigned char *b = (const unsigned char *)pn;
    for (int k = 0; k < 24; k++)
        h = (h ^ b[k]) * 1099511628211ull;
    return (size_t)h;
}

/* The vertex of position and normal pn (6 floats) in m, added when new. -1: no memory. */
static long vertex_of(struct verts *vt, struct trimesh *m, const float *pn)
{
    size_t h = vhash(pn) & (vt->cap - 1);
    for (; vt->slot[h] != EMPTY; h = (h + 1) & (vt->cap - 1)) {
        size_t v = vt->slot[h];
        if (!memcmp(m->pos + 3 * v, pn, 12) && (!m->nrm || !memcmp(m->nrm + 3 * v, pn + 3, 12)))
            return (long)v;
    }
    size_t v = m->n_vert;
    if (mem_reserve((void **)&m->pos, &vt->pcap, 3 * (v + 1), sizeof *m->pos) ||
        (m->nrm && mem_reserve((void **)&m->nrm, &vt->ncap, 3 * (v + 1), sizeof *m->nrm)))
        return -1;
    if (m->nrm)
        memcpy(m->nrm + 3 * v, pn + 3, 12);
    memcpy(m->pos + 3 * v, pn, 12);
    m->n_vert++;
    vt->slot[h] = v;
    return (long)v;
}

int mesh_changes_apply(const char *base, size_t base_len, const struct mesh_change *ch, size_t n, char **out,
                       size_t *len, struct sf_err *err)
{
    struct trimesh m;
    uint32_t *ids;
    uint64_t version;
    int rc = mesh_unpack_ids(base, base_len, &m, &ids, &version, err);
    if (rc)
        return rc;
    size_t added_total = 0;
    for (size_t k = 0; k < n && !rc; k++) {
        uint32_t v, r, a;
        if (change_of(&ch[k], &v, &r, &a) != 76 || v != version + 1 + k)
            rc = sf_fail(err, SF_EFORMAT, "", "the model's stored changes are damaged or do not follow its mesh");
        added_total += a;
    }
    /* the table of ids (-> triangle), of vertices (welding the corners added) */
    size_t nt = m.n_tri + added_total, tcap = 3 * m.n_tri;
    struct ids t = {0};
    struct verts vt = {.pcap = 3 * m.n_vert, .ncap = 3 * m.n_vert};
    bool *dead = NULL;
    if (!rc) {
        vt.cap = 16;
        while (vt.cap < 2 * (m.n_vert + 3 * added_total) + 16)
            vt.cap *= 2;
        vt.slot = malloc(vt.cap * sizeof *vt.slot);
        dead = calloc(nt ? nt : 1, sizeof *dead);
        if (ids_init(&t, nt) || !vt.slot || !dead || mem_reserve((void **)&m.tri, &tcap, 3 * nt, sizeof *m.tri) ||
            mem_reserve((void **)&ids, &(size_t){m.n_tri}, nt, sizeof *ids))
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory applying the model's changes");
    }
    if (!rc) {
        for (size_t k = 0; k < vt.cap; k++)
            vt.slot[k] = EMPTY;
        for (size_t v = 0; v < m.n_vert; v++) {
            float pn[6] = {0};
            memcpy(pn, m.pos + 3 * v, 12);
            if (m.nrm)
                memcpy(pn + 3, m.nrm + 3 * v, 12);
            size_t h = vhash(pn) & (vt.cap - 1);
            while (vt.slot[h] != EMPTY)
                h = (h + 1) & (vt.cap - 1);
            vt.slot[h] = v;
        }
        for (size_t i = 0; i < m.n_tri; i++) {
            size_t h = slot(&t, ids[i]);
            t.n += t.val[h] == EMPTY;
            t.key[h] = ids[i], t.val[h] = i;
        }
    }
    for (size_t k = 0; k < n && !rc; k++) {
        const unsigned char *p = ch[k].data;
        uint32_t nr = le32(p + 8), na = le32(p + 12);
        for (uint32_t i = 0; i < nr && !rc; i++) {
            size_t h = slot(&t, le32(p + 16 + 4 * i));
            if (t.val[h] == EMPTY)
                rc = sf_fail(err, SF_EFORMAT, "", "a stored change takes out triangle %u, which the mesh does not have",
                             le32(p + 16 + 4 * i));
            else
                dead[t.val[h]] = true, ids_remove(&t, h);
        }
        const unsigned char *q = p + 16 + 4 * (size_t)nr;
        for (uint32_t i = 0; i < na && !rc; i++) {
            const unsigned char *c = q + 76 * (size_t)i;
            size_t at = m.n_tri;
            for (int corner = 0; corner < 3 && !rc; corner++) {
                float pn[6];
                memcpy(pn, c + 4 + 24 * corner, 24);
                long v = vertex_of(&vt, &m, pn);
                if (v < 0)
                    rc = sf_fail(err, SF_ENOMEM, "", "out of memory applying the model's changes");
                m.tri[3 * at + corner] = (uint32_t)v;
            }
            size_t h = slot(&t, le32(c));
            t.n += t.val[h] == EMPTY;
            t.key[h] = le32(c), t.val[h] = at;
            ids[at] = le32(c);
            m.n_tri++;
        }
    }
    uint32_t *vmap = rc ? NULL : malloc((m.n_vert ? m.n_vert : 1) * sizeof *vmap);
    if (!rc && !vmap)
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory applying the model's changes");
    if (!rc) { /* the live triangles, in order, and the vertices they use */
        size_t w = 0, nv = 0;
        for (size_t v = 0; v < m.n_vert; v++)
            vmap[v] = UINT32_MAX;
        for (size_t i = 0; i < m.n_tri; i++)
            if (!dead[i]) {
                for (int c = 0; c < 3; c++) {
                    uint32_t v = m.tri[3 * i + c];
                    if (vmap[v] == UINT32_MAX)
                        vmap[v] = 0; /* (numbered below, in the vertices' order) */
                }
                memmove(m.tri + 3 * w, m.tri + 3 * i, 3 * sizeof *m.tri);
                ids[w++] = ids[i];
            }
        m.n_tri = w;
        for (size_t v = 0; v < m.n_vert; v++)
            if (vmap[v] != UINT32_MAX) {
                memmove(m.pos + 3 * nv, m.pos + 3 * v, 12);
                if (m.nrm)
                    memmove(m.nrm + 3 * nv, m.nrm + 3 * v, 12);
                vmap[v] = (uint32_t)nv++;
            }
        m.n_vert = nv;
        for (size_t k = 0; k < 3 * w; k++)
            m.tri[k] = vmap[m.tri[k]];
        rc = mesh_pack_ids(&m, ids, version + n, out, len, err);
    }
    free(vmap);
    ids_free(&t);
    free(vt.slot);
    free(dead);
    free(ids);
    trimesh_free(&m);
    return rc;
}
