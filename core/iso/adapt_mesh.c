/* adapt_mesh.c - the mesh a slab's piece of the adaptive hierarchy grows: vertices keyed by the
 * finest edge they lie on (one vertex whichever cells read the edge), placed on the samples' or
 * the field's crossing; crossings the samples do not show; triangles counted against the limit;
 * and a cell's crossings and segments (struct cell). It decides nothing about levels or loops. */
#include "adapt_internal.h"

#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

/* Whether node p is one of the volume's samples (not the pad layer round them). */
static bool real_node(const struct iso_adapt *a, const int p[3])
{
    for (int d = 0; d < 3; d++)
        if (p[d] < a->shift || p[d] >= a->N[d] - a->shift)
            return false;
    return true;
}

/* grad f at node (x, y, z), central differences (one-sided at the border), in world units. */
static void gradient(const struct iso_adapt *a, int x, int y, int z, double g[3])
{
    int p[3] = {x, y, z};
    for (int d = 0; d < 3; d++) {
        int lo[3] = {x, y, z}, hi[3] = {x, y, z};
        lo[d] = p[d] > 0 ? p[d] - 1 : p[d];
        hi[d] = p[d] + 1 < a->N[d] ? p[d] + 1 : p[d];
        g[d] = (Fp(a, hi) - Fp(a, lo)) / ((hi[d] - lo[d]) * a->sp[d]);
    }
}
/* A crossing's key: the finest edge it lies on. */
uint64_t edge_key(const struct iso_adapt *a, const int n[3], int axis)
{
    return (uint64_t)at3(a, n[0], n[1], n[2]) * 3 + (uint64_t)axis;
}

/* The first change of side on the edge of len samples from node n along axis: false when there is
 * none; else n is moved to the finest edge's lower node and v0, v1 get its two values. */
bool first_change(const struct iso_adapt *a, int n[3], int axis, int len, float *v0, float *v1)
{
    float prev = Fp(a, n);
    for (int k = 0; k < len; k++, n[axis]++) {
        int q[3] = {n[0], n[1], n[2]};
        q[axis]++;
        float cur = Fp(a, q);
        if ((prev > a->iso) != (cur > a->iso)) {
            *v0 = prev, *v1 = cur;
            return true;
        }
        prev = cur;
    }
    return false;
}

/* ---- the mesh ---- */

static uint64_t hash64(uint64_t k)
{
    k ^= k >> 33, k *= 0xff51afd7ed558ccdull, k ^= k >> 33, k *= 0xc4ceb9fe1a85ec53ull, k ^= k >> 33;
    return k;
}

/* Vertex v of pc at pos, its normal nrm made unit. */
void set_vertex(struct piece *pc, size_t v, const double pos[3], const double nrm[3])
{
    double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    for (int d = 0; d < 3; d++) {
        pc->m.pos[3 * v + d] = (float)pos[d];
        pc->m.nrm[3 * v + d] = len > 0 ? (float)(nrm[d] / len) : 0.0f;
    }
}

/* A new vertex of piece pc at pos with normal nrm and key: its id, or -1 (no memory, or over
 * the limit). */
long new_vertex(struct piece *pc, const double pos[3], const double nrm[3], uint64_t key)
{
    size_t v = pc->m.n_vert, cap = pc->vcap, kcap = pc->kcap;
    if (v >= ISO_MAX_VERTICES || mem_reserve((void **)&pc->m.pos, &cap, 3 * (v + 1), sizeof(float)) ||
        mem_reserve((void **)&pc->m.nrm, &pc->vcap, 3 * (v + 1), sizeof(float)) ||
        mem_reserve((void **)&pc->vkey, &kcap, v + 1, sizeof(uint64_t))) {
        pc->nomem = true;
        return -1;
    }
    pc->kcap = kcap;
    set_vertex(pc, v, pos, nrm);
    pc->vkey[v] = key;
    return (long)pc->m.n_vert++;
}

/* The slot of key in pc's table into *h (growing the table at half full), *found whether it
 * holds key: false for no memory. */
bool slot_of(struct piece *pc, uint64_t key, bool *found, size_t *h_out)
{
    if (pc->used * 2 >= pc->cap) {
        size_t cap = pc->cap ? pc->cap * 2 : 1 << 14;
        uint64_t *keys = malloc(cap * sizeof *keys);
        uint32_t *slot = malloc(cap * sizeof *slot);
        if (!keys || !slot) {
            free(keys), free(slot);
            pc->nomem = true;
            return false;
        }
        memset(keys, 0xff, cap * sizeof *keys);
        for (size_t i = 0; i < pc->cap; i++)
            if (pc->keys[i] != UINT64_MAX) {
                size_t h = hash64(pc->keys[i]) & (cap - 1);
                while (keys[h] != UINT64_MAX)
                    h = (h + 1) & (cap - 1);
                keys[h] = pc->keys[i], slot[h] = pc->slot[i];
            }
        free(pc->keys), free(pc->slot);
        pc->keys = keys, pc->slot = slot, pc->cap = cap;
    }
    size_t h = hash64(key) & (pc->cap - 1);
    while (pc->keys[h] != UINT64_MAX && pc->keys[h] != key)
        h = (h + 1) & (pc->cap - 1);
    *found = pc->keys[h] == key;
    *h_out = h;
    return true;
}

/* Records that key is vertex v of pc (its slot from slot_of). */
void keep_slot(struct piece *pc, size_t h, uint64_t key, long v)
{
    pc->keys[h] = key, pc->slot[h] = (uint32_t)v;
    pc->used++;
}

/* pc's vertex keyed key: its id, or UNKNOWN with *slot where it will go (-1: no memory). */
long known_vertex(struct piece *pc, uint64_t key, size_t *slot)
{
    bool found;
    if (!slot_of(pc, key, &found, slot))
        return -1;
    return found ? (long)pc->slot[*slot] : UNKNOWN;
}

/* A new vertex of pc keyed key (its slot from known_vertex). */
long keyed_vertex(struct piece *pc, uint64_t key, size_t slot, const double pos[3], const double nrm[3])
{
    long v = new_vertex(pc, pos, nrm, key);
    if (v >= 0)
        keep_slot(pc, slot, key, v);
    return v;
}

/* The field minus iso at fraction t of the edge from node n along axis. */
static double on_edge(const struct iso_adapt *a, const int n[3], int axis, double t)
{
    double x[3];
    for (int d = 0; d < 3; d++)
        x[d] = a->org[d] + a->sp[d] * (n[d] + (d == axis ? t : 0));
    return a->field(a->field_ctx, x, NULL) - a->iso;
}

/* Where the field crosses iso on the edge from node n along axis between fractions lo and hi
 * (f0, f1: the field minus iso there, of opposite signs), by regula falsi with the Illinois step. */
static double field_root(const struct iso_adapt *a, const int n[3], int axis, double lo, double hi, double f0, double f1)
{
    double t = lo + (hi - lo) * f0 / (f0 - f1);
    int side = 0;
    for (int it = 0; it < 24 && hi - lo > 1e-9; it++) {
        double f = on_edge(a, n, axis, t);
        if (f == 0 || !isfinite(f))
            break;
        if ((f > 0) == (f0 > 0)) {
            lo = t, f0 = f;
            if (side < 0)
                f1 /= 2;
            side = -1;
        } else {
            hi = t, f1 = f;
            if (side > 0)
                f0 /= 2;
            side = 1;
        }
        t = lo + (hi - lo) * f0 / (f0 - f1);
    }
    return t;
}

/* Makes the vertex keyed key (its slot from known_vertex) at fraction t of the finest edge from
 * node n along axis; its normal from the field's gradient (on_field) or the samples'. */
static long place_vertex(const struct iso_adapt *a, struct piece *pc, const int n[3], int axis, double t, bool on_field,
                         uint64_t key, size_t slot)
{
    double pos[3], g0[3], g1[3], nrm[3];
    int m[3] = {n[0], n[1], n[2]};
    m[axis]++;
    t = edge_fraction(t);
    crossing_at(a, n, axis, t, pos);
    if (on_field) {
        a->field(a->field_ctx, pos, g0);
        for (int d = 0; d < 3; d++)
            nrm[d] = -g0[d]; /* outward: down the gradient */
    } else {
        gradient(a, n[0], n[1], n[2], g0);
        gradient(a, m[0], m[1], m[2], g1);
        for (int d = 0; d < 3; d++)
            nrm[d] = -((1 - t) * g0[d] + t * g1[d]);
    }
    return keyed_vertex(pc, key, slot, pos, nrm);
}

/* The vertex on the finest edge from node n along axis, with its two values: found or made. */
long edge_vertex(const struct iso_adapt *a, struct piece *pc, const int n[3], int axis, float v0, float v1)
{
    uint64_t key = edge_key(a, n, axis);
    size_t h;
    long v = known_vertex(pc, key, &h);
    if (v != UNKNOWN)
        return v;
    int m[3] = {n[0], n[1], n[2]};
    m[axis]++;
    double t = ((double)a->iso - v0) / ((double)v1 - v0);
    bool on_field = a->field && real_node(a, n) && real_node(a, m);
    if (on_field)
        t = field_root(a, n, axis, 0, 1, v0 - a->iso, v1 - a->iso);
    return place_vertex(a, pc, n, axis, t, on_field, key, h);
}

/* ---- crossings the samples do not show ----
 * A cell's surface is read from its edges' sign changes, so where an FRep object's sharp edge or
 * corner pokes through a cell edge between two samples of one side (the surface enters and leaves
 * the edge), no sign changes and the cells round that edge see nothing: the feature is cut off
 * there, by up to half a cell, whatever the feature points do (Extended Marching Cubes and Dual
 * Contouring have the same blind spot). With the field at hand the edge can be asked. Along the
 * edge the field is, on each side of a feature, close to linear: the lines through the samples
 * before and after the edge (node - 1, node; node + 1, node + 2) meet where the feature would be.
 * When they meet inside the edge, not far short of iso, the field is asked there (and, where it
 * bends past an edge or corner that grazes the cell edge, at its extreme along the edge, by golden
 * section); if it is on the other side, the edge carries two crossings, found on the field between
 * the ends and that point. Only level-1 cells read them: a block whose fine edges carry any is not merged. Ends
 * further from iso than twice the edge's length are taken to be out of reach (a field whose slope
 * is 2 at most: FRep's distances, their R-functions and transforms). */

bool hidden_pair(const struct iso_adapt *a, const int n[3], int axis, double t[2])
{
    if (!a->field)
        return false;
    int m[3] = {n[0], n[1], n[2]}, p[3] = {n[0], n[1], n[2]}, q[3] = {n[0], n[1], n[2]};
    m[axis]++, p[axis]--, q[axis] += 2;
    double f0 = Fp(a, n) - a->iso, f1 = Fp(a, m) - a->iso;
    if (fabs(f0) > 2 * a->sp[axis] || fabs(f1) > 2 * a->sp[axis]) /* out of reach for a slope of 2 or less */
        return false;
    if (!real_node(a, p) || !real_node(a, q))
        return false;
    double fp = Fp(a, p) - a->iso, fq = Fp(a, q) - a->iso;
    double s = f0 > 0 ? -1 : 1; /* the ends' side below zero */
    double g0 = s * f0, g1 = s * f1, d0 = s * (f0 - fp), d1 = s * (fq - f1);
    if ((g0 > 0) || (g1 > 0) || !(d0 > 0 && d1 < 0))
        return false;
    double ts = (g1 - d1 - g0) / (d0 - d1);
    if (!(ts > 0 && ts < 1) || !(g0 + d0 * ts > -0.5 * fmin(-g0, -g1)))
        return false;
    /* the field's extreme on the edge, by golden section from the lines' meeting point (past an
     * edge or a corner the field bends: a feature grazing the edge is not on the lines) */
    double fs = s * on_edge(a, n, axis, ts), lo = 0, hi = 1;
    if (!(fs > 0)) {
        const double r = 0.6180339887498949;
        double ta = hi - r * (hi - lo), tb = lo + r * (hi - lo);
        double fa = s * on_edge(a, n, axis, ta), fb = s * on_edge(a, n, axis, tb);
        for (int it = 0; it < 30 && !(fa > 0) && !(fb > 0); it++)
            if (fa > fb) {
                hi = tb, tb = ta, fb = fa;
                ta = hi - r * (hi - lo), fa = s * on_edge(a, n, axis, ta);
            } else {
                lo = ta, ta = tb, fa = fb;
                tb = lo + r * (hi - lo), fb = s * on_edge(a, n, axis, tb);
            }
        if (!(fa > 0) && !(fb > 0))
            return false;
        ts = fa > fb ? ta : tb, fs = fmax(fa, fb);
    }
    fs *= s;
    if (!isfinite(fs))
        return false;
    t[0] = field_root(a, n, axis, 0, ts, f0, fs);
    t[1] = field_root(a, n, axis, ts, 1, fs, f1);
    return true;
}

/* Crossing k (0, 1) of a hidden pair at fraction t of the finest edge from n along axis. */
long hidden_vertex(const struct iso_adapt *a, struct piece *pc, const int n[3], int axis, int k, double t)
{
    uint64_t key = edge_key(a, n, axis) | HIDDEN_KEY(k);
    size_t h;
    long v = known_vertex(pc, key, &h);
    return v != UNKNOWN ? v : place_vertex(a, pc, n, axis, t, true, key, h);
}

/* Whether any of the cell of s nodes a side at o's finest edges carries a hidden pair (only
 * when there is a field). */
bool hides_crossings(const struct iso_adapt *a, const int o[3], int s)
{
    if (!a->field)
        return false;
    double t[2], reach = 2 * fmax(a->sp[0], fmax(a->sp[1], a->sp[2]));
    bool near = false;
    for (int z = 0; z <= s && !near; z++) /* (hidden_pair's reach, for the whole cell first) */
        for (int y = 0; y <= s && !near; y++)
            for (int x = 0; x <= s && !near; x++) {
                int p[3] = {o[0] + x, o[1] + y, o[2] + z};
                near = p[0] < a->N[0] && p[1] < a->N[1] && p[2] < a->N[2] && fabs(Fp(a, p) - a->iso) <= reach;
            }
    if (!near)
        return false;
    for (int z = 0; z <= s; z++)
        for (int y = 0; y <= s; y++)
            for (int x = 0; x <= s; x++)
                for (int axis = 0; axis < 3; axis++) {
                    int p[3] = {o[0] + x, o[1] + y, o[2] + z}, q[3] = {p[0], p[1], p[2]};
                    if (++q[axis] > o[axis] + s || q[0] >= a->N[0] || q[1] >= a->N[1] || q[2] >= a->N[2])
                        continue;
                    if ((Fp(a, p) > a->iso) == (Fp(a, q) > a->iso) && hidden_pair(a, p, axis, t))
                        return true;
                }
    return false;
}

/* Triangles a piece adds to the shared count at a time: the count runs ahead of the pieces by at
 * most this each, so a surface stops within ADAPT_SLABS TRI_CHUNK triangles of the limit. */
#define TRI_CHUNK 4096

void add_triangle(struct piece *pc, long p, long q, long r)
{
    if (p < 0 || q < 0 || r < 0)
        return;
    size_t t = pc->m.n_tri;
    if (pc->tri_total && t % TRI_CHUNK == 0 &&
        atomic_fetch_add(pc->tri_total, TRI_CHUNK) + TRI_CHUNK > pc->tri_limit + ADAPT_SLABS * TRI_CHUNK) {
        pc->over = pc->nomem = true;
        return;
    }
    if (mem_reserve((void **)&pc->m.tri, &pc->tcap, 3 * (t + 1), sizeof(uint32_t)) ||
        mem_reserve((void **)&pc->owner, &pc->ocap, t + 1, sizeof(uint32_t))) {
        pc->nomem = true;
        return;
    }
    pc->owner[t] = pc->block;
    pc->m.tri[3 * t] = (uint32_t)p, pc->m.tri[3 * t + 1] = (uint32_t)q, pc->m.tri[3 * t + 2] = (uint32_t)r;
    pc->m.n_tri++;
}

/* ---- one cell ---- */

/* The faces of cell c that the edge from node lo along axis lies on (bits). */
int cell_edge_faces(const struct cell *c, const int lo[3], int axis)
{
    int faces = 0;
    for (int d = 0; d < 3; d++)
        if (d != axis) {
            faces |= lo[d] == c->o[d] ? 1 << (2 * d) : 0;
            faces |= lo[d] == c->o[d] + c->s ? 1 << (2 * d + 1) : 0;
        }
    return faces;
}

/* The crossing on the sub-edge from node p to node q (one axis apart): the finest edge where the
 * values change side, walked from the lower end, and the faces of the cell it lies on. */
long crossing(const struct iso_adapt *a, const struct cell *c, const int p[3], const int q[3], int *faces)
{
    int axis = p[0] != q[0] ? 0 : p[1] != q[1] ? 1 : 2;
    const int *lo = p[axis] < q[axis] ? p : q;
    int n[3] = {lo[0], lo[1], lo[2]};
    float v0, v1;
    *faces = cell_edge_faces(c, lo, axis);
    return first_change(a, n, axis, abs(q[axis] - p[axis]), &v0, &v1) ? edge_vertex(a, c->pc, n, axis, v0, v1) : -1;
}

void add_seg(struct cell *c, long from, int from_faces, long to)
{
    if (c->n < MAX_SEGS) {
        c->from[c->n] = from, c->to[c->n] = to, c->faces[c->n] = from_faces;
        c->n++;
    }
}

