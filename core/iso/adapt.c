/* adapt.c - the adaptive hierarchy with crack-free joins (adapt.h). The grid is copied as floats
 * with its pad layer (closed=true), as mc.c sees it; nodes and cells are addressed by their
 * integer coordinates in that grid. */
#include "adapt.h"
#include "cube.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

/* One slab's share of the mesh (the cells phase runs slab by slab, on any threads): vertices keyed
 * by the finest edge they lie on, merged across slabs at the end. */
struct piece {
    uint64_t *keys;
    uint32_t *slot;
    size_t cap, used;
    uint64_t *vkey;                    /* each vertex's key (UINT64_MAX: a fan's centre) */
    struct trimesh m;
    size_t vcap, tcap, kcap;
    bool nomem;
    long cells[ISO_MAX_LEVELS + 1];
};

#define ADAPT_SLABS 16 /* fixed, so that the mesh does not depend on the number of threads */

struct iso_adapt {
    int N[3], shift;
    float iso;
    double org[3], sp[3], max_err;
    int L, n_slabs;
    struct iso_grid g;                 /* the samples, copied into F by the first phase */
    float pad;
    float *F;                          /* the virtual grid, x fastest */
    int nb[ISO_MAX_LEVELS + 1][3];     /* blocks per axis at each level */
    uint8_t *M[ISO_MAX_LEVELS + 1];    /* [l][block]: covered by a cell of level >= l (l >= 2) */
    uint8_t *lev2;                     /* each level-2 block's cell level (1: cut into level-1 cells) */
    uint8_t *mixed[ISO_MAX_LEVELS + 1]; /* [l][block]: its samples are on both sides of iso (l >= 2;
                                         * level 2: or the grid's end cuts it) */
    double slab_max[ADAPT_SLABS];      /* the largest error a merge accepted, by slab */
    struct piece pieces[ADAPT_SLABS];
};

static size_t at3(const struct iso_adapt *a, int x, int y, int z) { return (size_t)x + (size_t)a->N[0] * ((size_t)y + (size_t)a->N[1] * z); }
static float F(const struct iso_adapt *a, int x, int y, int z) { return a->F[at3(a, x, y, z)]; }

static size_t block(const struct iso_adapt *a, int l, int bx, int by, int bz)
{
    return (size_t)bx + (size_t)a->nb[l][0] * ((size_t)by + (size_t)a->nb[l][1] * bz);
}

static float Fp(const struct iso_adapt *a, const int p[3]) { return F(a, p[0], p[1], p[2]); }

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

/* ---- the hierarchy ---- */

/* Distance from p to triangle abc. */
static double tri_dist(const double p[3], const double a[3], const double b[3], const double c[3])
{
    double ab[3], ac[3], ap[3], q[3];
    for (int d = 0; d < 3; d++)
        ab[d] = b[d] - a[d], ac[d] = c[d] - a[d], ap[d] = p[d] - a[d];
#define DOT(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double d1 = DOT(ab, ap), d2 = DOT(ac, ap), v, w;
    double bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]}, cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    double d3 = DOT(ab, bp), d4 = DOT(ac, bp), d5 = DOT(ab, cp), d6 = DOT(ac, cp);
    double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    if (d1 <= 0 && d2 <= 0)
        v = 0, w = 0;
    else if (d3 >= 0 && d4 <= d3)
        v = 1, w = 0;
    else if (vc <= 0 && d1 >= 0 && d3 <= 0)
        v = d1 / (d1 - d3), w = 0;
    else if (d6 >= 0 && d5 <= d6)
        v = 0, w = 1;
    else if (vb <= 0 && d2 >= 0 && d6 <= 0)
        v = 0, w = d2 / (d2 - d6);
    else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6)), v = 1 - w;
    else {
        double den = 1 / (va + vb + vc);
        v = vb * den, w = vc * den;
    }
    for (int d = 0; d < 3; d++)
        q[d] = a[d] + v * ab[d] + w * ac[d] - p[d];
    return sqrt(DOT(q, q));
#undef DOT
}

/* The error estimate of block b of level l, merged into one cell: that cell's surface is a
 * polygon through the samples' own crossings on its twelve edges (each edge must cross at most
 * once: else INFINITY, a feature finer than the cell), so its vertices lie on the full-resolution
 * surface, and what is measured is the distance from every full-resolution vertex in the block
 * (the crossings of its fine edges) to that polygon: INFINITY when the cell would have none. 0
 * when the block's samples are all on one side (mixed false). */
static double block_error(const struct iso_adapt *a, int l, const int b[3], bool mixed)
{
    int s = 1 << (l - 1), o[3] = {b[0] * s, b[1] * s, b[2] * s};
    if (!mixed) /* no crossing in the block: nothing to draw either way */
        return 0;
    double iso = a->iso, c[8], ep[8][8][3]; /* the crossing on the edge between corners i < j, in mm */
    bool st[8];
    for (int k = 0; k < 8; k++) {
        c[k] = F(a, o[0] + (k & 1) * s, o[1] + (k >> 1 & 1) * s, o[2] + (k >> 2 & 1) * s) - iso;
        st[k] = c[k] > 0;
    }
    for (int i = 0; i < 8; i++)
        for (int axis = 0; axis < 3; axis++) {
            int j = i | 1 << axis;
            if (j == i)
                continue;
            int p[3] = {o[0] + (i & 1) * s, o[1] + (i >> 1 & 1) * s, o[2] + (i >> 2 & 1) * s}, changes = 0;
            double prev = c[i];
            for (int t = 1; t <= s; t++) {
                int q[3] = {p[0], p[1], p[2]};
                q[axis] += t;
                double cur = F(a, q[0], q[1], q[2]) - iso;
                if ((prev > 0) != (cur > 0)) {
                    if (++changes > 1)
                        return INFINITY;
                    double f = prev / (prev - cur);
                    for (int d = 0; d < 3; d++)
                        ep[i][j][d] = a->org[d] + a->sp[d] * (q[d] - (d == axis ? 1 - f : 0));
                }
                prev = cur;
            }
        }
    /* the merged cell's polygon: faces' segments between corner-edge crossings, chained, fanned */
    int next[8][8], tri_n = 0;
    double tris[16][3][3];
    memset(next, -1, sizeof next);
    for (int f = 0; f < 6; f++) {
        int axis = f >> 1, u = axis == 0 ? 1 : 0, w = axis == 2 ? 1 : 2, cross[4], entry[4], n = 0;
        double g[4];
        for (int q = 0; q < 4; q++) {
            int cc = iso_face_ccw[f][q], dd = iso_face_ccw[f][(q + 1) % 4];
            g[(cc >> u & 1) + 2 * (cc >> w & 1)] = c[cc];
            if (st[cc] != st[dd]) {
                cross[n] = (cc < dd ? cc : dd) * 8 + (cc < dd ? dd : cc);
                entry[n++] = st[dd];
            }
        }
        if (n == 2) {
            int e = entry[0] ? 0 : 1;
            next[cross[e] / 8][cross[e] % 8] = cross[1 - e];
        } else if (n == 4) {
            int r = entry[0] ? 0 : 1, e1 = cross[r], x1 = cross[(r + 1) % 4], e2 = cross[(r + 2) % 4], x2 = cross[(r + 3) % 4];
            double det = g[0] * g[3] - g[1] * g[2];
            bool joined = g[0] > 0 ? det > 0 : det < 0;
            next[(joined ? e2 : e1) / 8][(joined ? e2 : e1) % 8] = x1;
            next[(joined ? e1 : e2) / 8][(joined ? e1 : e2) % 8] = x2;
        }
    }
    for (int i = 0; i < 8; i++)
        for (int j = i + 1; j < 8; j++) {
            if (next[i][j] < 0)
                continue;
            int loop[12], n = 0;
            for (int e = i * 8 + j; e >= 0 && n < 12;) {
                loop[n++] = e;
                int nx = next[e / 8][e % 8];
                next[e / 8][e % 8] = -1;
                e = nx;
            }
            for (int k = 1; k + 1 < n && tri_n < 16; k++, tri_n++)
                for (int d = 0; d < 3; d++) {
                    tris[tri_n][0][d] = ep[loop[0] / 8][loop[0] % 8][d];
                    tris[tri_n][1][d] = ep[loop[k] / 8][loop[k] % 8][d];
                    tris[tri_n][2][d] = ep[loop[k + 1] / 8][loop[k + 1] % 8][d];
                }
        }
    double worst = 0;
    for (int z = 0; z <= s; z++)
        for (int y = 0; y <= s; y++)
            for (int x = 0; x <= s; x++)
                for (int axis = 0; axis < 3; axis++) {
                    int p[3] = {o[0] + x, o[1] + y, o[2] + z}, q[3] = {p[0], p[1], p[2]};
                    if (++q[axis] > o[axis] + s)
                        continue;
                    double f0 = F(a, p[0], p[1], p[2]) - iso, f1 = F(a, q[0], q[1], q[2]) - iso;
                    if ((f0 > 0) == (f1 > 0))
                        continue;
                    double t = f0 / (f0 - f1), v[3], e = tri_n ? INFINITY : INFINITY;
                    for (int d = 0; d < 3; d++)
                        v[d] = a->org[d] + a->sp[d] * (p[d] + (d == axis ? t : 0));
                    for (int k = 0; k < tri_n; k++)
                        e = fmin(e, tri_dist(v, tris[k][0], tris[k][1], tris[k][2]));
                    worst = fmax(worst, e);
                    if (worst > a->max_err)
                        return worst;
                }
    return worst;
}

/* Whether every block of level l that touches block b of level l+1 is covered at l. */
static bool ring_covered(const struct iso_adapt *a, int l, const int b[3])
{
    for (int z = 2 * b[2] - 1; z <= 2 * b[2] + 2; z++)
        for (int y = 2 * b[1] - 1; y <= 2 * b[1] + 2; y++)
            for (int x = 2 * b[0] - 1; x <= 2 * b[0] + 2; x++) {
                if (x < 0 || y < 0 || z < 0 || x >= a->nb[l][0] || y >= a->nb[l][1] || z >= a->nb[l][2])
                    continue;
                if (!a->M[l][block(a, l, x, y, z)])
                    return false;
            }
    return true;
}

/* Blocks of level l in layers [z0, z1) of slab s: mixed, merged or not (level l-1 done). */
static void mask_slab(struct iso_adapt *a, int l, int z0, int z1, int slab)
{
    int s = 1 << (l - 1), b[3];
    for (b[2] = z0; b[2] < z1; b[2]++)
        for (b[1] = 0; b[1] < a->nb[l][1]; b[1]++)
            for (b[0] = 0; b[0] < a->nb[l][0]; b[0]++) {
                bool inside = true, ok = true, mixed = false;
                for (int d = 0; d < 3; d++)
                    inside = inside && (b[d] + 1) * s <= a->N[d] - 1;
                if (l > 2) { /* its children merged, and every block of l-1 round it */
                    for (int k = 0; k < 8 && ok && inside; k++)
                        ok = a->M[l - 1][block(a, l - 1, 2 * b[0] + (k & 1), 2 * b[1] + (k >> 1 & 1),
                                               2 * b[2] + (k >> 2 & 1))];
                    ok = ok && inside && ring_covered(a, l - 1, b);
                }
                if (l == 2) { /* the block's 27 samples */
                    bool in = false, out = false;
                    for (int z = 0; z <= 2; z++)
                        for (int y = 0; y <= 2; y++)
                            for (int x = 0; x <= 2; x++) {
                                int p[3] = {2 * b[0] + x, 2 * b[1] + y, 2 * b[2] + z};
                                if (p[0] >= a->N[0] || p[1] >= a->N[1] || p[2] >= a->N[2])
                                    continue;
                                bool v = F(a, p[0], p[1], p[2]) > a->iso;
                                in |= v, out |= !v;
                            }
                    mixed = !inside || (in && out); /* a block the grid's end cuts: level-1 cells */
                } else { /* any child's */
                    for (int k = 0; k < 8 && !mixed; k++) {
                        int c[3] = {2 * b[0] + (k & 1), 2 * b[1] + (k >> 1 & 1), 2 * b[2] + (k >> 2 & 1)};
                        if (c[0] < a->nb[l - 1][0] && c[1] < a->nb[l - 1][1] && c[2] < a->nb[l - 1][2])
                            mixed = a->mixed[l - 1][block(a, l - 1, c[0], c[1], c[2])];
                    }
                }
                a->mixed[l][block(a, l, b[0], b[1], b[2])] = mixed;
                double e = ok && inside ? block_error(a, l, b, mixed) : INFINITY;
                if (e <= a->max_err) {
                    a->M[l][block(a, l, b[0], b[1], b[2])] = 1;
                    a->slab_max[slab] = fmax(a->slab_max[slab], e);
                }
            }
}

/* Each level-2 block's cell level, once every level's blocks are known. */
static void cell_levels(struct iso_adapt *a)
{
    int b[3];
    for (b[2] = 0; b[2] < a->nb[2][2]; b[2]++)
        for (b[1] = 0; b[1] < a->nb[2][1]; b[1]++)
            for (b[0] = 0; b[0] < a->nb[2][0]; b[0]++) {
                int lev = 1;
                for (int l = a->L; l >= 2 && lev == 1; l--)
                    if (a->M[l][block(a, l, b[0] >> (l - 2), b[1] >> (l - 2), b[2] >> (l - 2))])
                        lev = l;
                a->lev2[block(a, 2, b[0], b[1], b[2])] = (uint8_t)lev;
            }
}

/* ---- the mesh ---- */

static uint64_t hash64(uint64_t k)
{
    k ^= k >> 33, k *= 0xff51afd7ed558ccdull, k ^= k >> 33, k *= 0xc4ceb9fe1a85ec53ull, k ^= k >> 33;
    return k;
}

/* A new vertex of piece pc at pos with normal nrm and key: its id, or -1 (no memory, or over
 * the limit). */
static long new_vertex(struct piece *pc, const double pos[3], const double nrm[3], uint64_t key)
{
    size_t v = pc->m.n_vert, cap = pc->vcap, kcap = pc->kcap;
    if (v >= ISO_MAX_VERTICES || mem_reserve((void **)&pc->m.pos, &cap, 3 * (v + 1), sizeof(float)) ||
        mem_reserve((void **)&pc->m.nrm, &pc->vcap, 3 * (v + 1), sizeof(float)) ||
        mem_reserve((void **)&pc->vkey, &kcap, v + 1, sizeof(uint64_t))) {
        pc->nomem = true;
        return -1;
    }
    pc->kcap = kcap;
    double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    for (int d = 0; d < 3; d++) {
        pc->m.pos[3 * v + d] = (float)pos[d];
        pc->m.nrm[3 * v + d] = len > 0 ? (float)(nrm[d] / len) : 0.0f;
    }
    pc->vkey[v] = key;
    return (long)pc->m.n_vert++;
}

/* The slot of key in pc's table into *h (growing the table at half full), *found whether it
 * holds key: false for no memory. */
static bool slot_of(struct piece *pc, uint64_t key, bool *found, size_t *h_out)
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
static void keep_slot(struct piece *pc, size_t h, uint64_t key, long v)
{
    pc->keys[h] = key, pc->slot[h] = (uint32_t)v;
    pc->used++;
}

/* The vertex on the finest edge from node n along axis, with its two values: found or made. */
static long edge_vertex(const struct iso_adapt *a, struct piece *pc, const int n[3], int axis, float v0, float v1)
{
    uint64_t key = (uint64_t)at3(a, n[0], n[1], n[2]) * 3 + (uint64_t)axis;
    bool found;
    size_t h;
    if (!slot_of(pc, key, &found, &h))
        return -1;
    if (found)
        return pc->slot[h];
    double t = ((double)a->iso - v0) / ((double)v1 - v0);
    t = t < ISO_EDGE_MARGIN ? ISO_EDGE_MARGIN : t > 1 - ISO_EDGE_MARGIN ? 1 - ISO_EDGE_MARGIN : t;
    double pos[3], g0[3], g1[3], nrm[3];
    int m[3] = {n[0], n[1], n[2]};
    m[axis]++;
    gradient(a, n[0], n[1], n[2], g0);
    gradient(a, m[0], m[1], m[2], g1);
    for (int d = 0; d < 3; d++) {
        pos[d] = a->org[d] + a->sp[d] * (n[d] + (d == axis ? t : 0));
        nrm[d] = -((1 - t) * g0[d] + t * g1[d]); /* outward: down the gradient */
    }
    long v = new_vertex(pc, pos, nrm, key);
    if (v >= 0)
        keep_slot(pc, h, key, v);
    return v;
}

static void add_triangle(struct piece *pc, long p, long q, long r)
{
    if (p < 0 || q < 0 || r < 0)
        return;
    size_t t = pc->m.n_tri;
    if (mem_reserve((void **)&pc->m.tri, &pc->tcap, 3 * (t + 1), sizeof(uint32_t))) {
        pc->nomem = true;
        return;
    }
    pc->m.tri[3 * t] = (uint32_t)p, pc->m.tri[3 * t + 1] = (uint32_t)q, pc->m.tri[3 * t + 2] = (uint32_t)r;
    pc->m.n_tri++;
}

/* ---- one cell ---- */

#define MAX_SEGS 96

struct cell {
    struct piece *pc;        /* where its triangles go */
    int o[3], s;
    int n;                   /* segments */
    long from[MAX_SEGS], to[MAX_SEGS];
    int faces[MAX_SEGS];     /* of from[]: the cell faces its edge lies on (bits) */
};

/* The crossing on the sub-edge from node p to node q (one axis apart): the finest edge where the
 * values change side, walked from the lower end, and the faces of the cell it lies on. */
static long crossing(const struct iso_adapt *a, const struct cell *c, const int p[3], const int q[3], int *faces)
{
    int axis = p[0] != q[0] ? 0 : p[1] != q[1] ? 1 : 2;
    const int *lo = p[axis] < q[axis] ? p : q;
    int m = abs(q[axis] - p[axis]), n[3] = {lo[0], lo[1], lo[2]};
    float prev = Fp(a, n);
    long v = -1;
    for (int k = 1; k <= m; k++) {
        int n1[3] = {n[0], n[1], n[2]};
        n1[axis]++;
        float cur = Fp(a, n1);
        if ((prev > a->iso) != (cur > a->iso)) {
            v = edge_vertex(a, c->pc, n, axis, prev, cur);
            break;
        }
        prev = cur;
        n[axis]++;
    }
    *faces = 0;
    for (int d = 0; d < 3; d++)
        if (d != axis) {
            *faces |= lo[d] == c->o[d] ? 1 << (2 * d) : 0;
            *faces |= lo[d] == c->o[d] + c->s ? 1 << (2 * d + 1) : 0;
        }
    return v;
}

static void add_seg(struct cell *c, long from, int from_faces, long to)
{
    if (c->n < MAX_SEGS) {
        c->from[c->n] = from, c->to[c->n] = to, c->faces[c->n] = from_faces;
        c->n++;
    }
}

/* The segments of face f cut k x k: per sub-square as mc.c's faces (entry to exit, walking it
 * counter-clockwise; an ambiguous one by the asymptotic decider over its values in x, y, z order). */
static void face_segments(const struct iso_adapt *a, struct cell *c, int f, int k)
{
    int axis = f >> 1, side = f & 1, h = c->s / k;
    int u = axis == 0 ? 1 : 0, w = axis == 2 ? 1 : 2;
    for (int j = 0; j < k; j++)
        for (int i = 0; i < k; i++) {
            int p[4][3];
            float v[4];
            double g[4];
            for (int q = 0; q < 4; q++) {
                int cc = iso_face_ccw[f][q], b[3] = {cc & 1, cc >> 1 & 1, cc >> 2 & 1};
                p[q][axis] = c->o[axis] + side * c->s;
                p[q][u] = c->o[u] + (i + b[u]) * h;
                p[q][w] = c->o[w] + (j + b[w]) * h;
                v[q] = Fp(a, p[q]);
                g[b[u] + 2 * b[w]] = (double)v[q] - a->iso;
            }
            long cross[4];
            int faces[4], entry[4], n = 0;
            for (int q = 0; q < 4; q++) {
                bool sa = v[q] > a->iso, sb = v[(q + 1) % 4] > a->iso;
                if (sa != sb) {
                    cross[n] = crossing(a, c, p[q], p[(q + 1) % 4], &faces[n]);
                    entry[n++] = sb;
                }
            }
            if (n == 2) {
                int e = entry[0] ? 0 : 1;
                add_seg(c, cross[e], faces[e], cross[1 - e]);
            } else if (n == 4) {
                int r = entry[0] ? 0 : 1;
                int e1 = r, x1 = (r + 1) % 4, e2 = (r + 2) % 4, x2 = (r + 3) % 4;
                double det = g[0] * g[3] - g[1] * g[2];
                if (g[0] > 0 ? det > 0 : det < 0) { /* inside corners joined: the segments cut off the outside ones */
                    add_seg(c, cross[e2], faces[e2], cross[x1]);
                    add_seg(c, cross[e1], faces[e1], cross[x2]);
                } else {
                    add_seg(c, cross[e1], faces[e1], cross[x1]);
                    add_seg(c, cross[e2], faces[e2], cross[x2]);
                }
            }
        }
}

/* The cell's loops, each fanned from a vertex none of whose diagonals joins two vertices of one
 * face, else from a vertex at its centre. */
static void fan_loops(struct cell *c)
{
    bool used[MAX_SEGS] = {false};
    for (int s0 = 0; s0 < c->n; s0++) {
        if (used[s0])
            continue;
        long loop[MAX_SEGS];
        int faces[MAX_SEGS], n = 0;
        for (int s = s0; s >= 0 && !used[s] && n < MAX_SEGS;) {
            used[s] = true;
            loop[n] = c->from[s], faces[n++] = c->faces[s];
            int next = -1;
            for (int t = 0; t < c->n && next < 0; t++)
                if (!used[t] && c->from[t] == c->to[s])
                    next = t;
            s = next;
        }
        if (n < 3)
            continue;
        int apex = -1;
        for (int p = 0; p < n && apex < 0; p++) {
            bool ok = true;
            for (int k = 2; k + 1 < n && ok; k++)
                ok = !(faces[p] & faces[(p + k) % n]);
            if (ok)
                apex = p;
        }
        if (apex >= 0) {
            for (int k = 1; k + 1 < n; k++)
                add_triangle(c->pc, loop[apex], loop[(apex + k) % n], loop[(apex + k + 1) % n]);
            continue;
        }
        double pos[3] = {0, 0, 0}, nrm[3] = {0, 0, 0};
        for (int k = 0; k < n; k++)
            for (int d = 0; d < 3; d++) {
                if (loop[k] < 0)
                    continue;
                pos[d] += c->pc->m.pos[3 * loop[k] + d] / n;
                nrm[d] += c->pc->m.nrm[3 * loop[k] + d];
            }
        long centre = new_vertex(c->pc, pos, nrm, UINT64_MAX);
        for (int k = 0; k < n; k++)
            add_triangle(c->pc, centre, loop[k], loop[(k + 1) % n]);
    }
}

/* Cell of level l at o: its faces cut where the neighbour across is finer. */
static void polygonise(const struct iso_adapt *a, struct piece *pc, const int o[3], int l)
{
    int s = 1 << (l - 1), in = 0;
    for (int k = 0; k < 8; k++) {
        int p[3] = {o[0] + (k & 1) * s, o[1] + (k >> 1 & 1) * s, o[2] + (k >> 2 & 1) * s};
        in += Fp(a, p) > a->iso;
    }
    bool mixed = in > 0 && in < 8;
    int ks[6];
    for (int f = 0; f < 6; f++) {
        ks[f] = 1;
        if (l >= 2) {
            int axis = f >> 1, b[3] = {o[0] >> (l - 1), o[1] >> (l - 1), o[2] >> (l - 1)};
            b[axis] += f & 1 ? 1 : -1;
            if (b[axis] >= 0 && b[axis] < a->nb[l][axis] && !a->M[l][block(a, l, b[0], b[1], b[2])])
                ks[f] = 2;
        }
        if ((in == 0 || in == 8) && ks[f] == 2) { /* a face cut in four reads its centre too */
            int axis = f >> 1, p[3] = {o[0] + s / 2, o[1] + s / 2, o[2] + s / 2};
            p[axis] = o[axis] + (f & 1) * s;
            mixed = mixed || (Fp(a, p) > a->iso) != (in == 8);
        }
    }
    if (!mixed)
        return;
    struct cell c;
    c.pc = pc;
    memcpy(c.o, o, sizeof c.o);
    c.s = s;
    c.n = 0;
    pc->cells[l]++;
    for (int f = 0; f < 6; f++)
        face_segments(a, &c, f, ks[f]);
    fan_loops(&c);
}

/* The cells of level-2 block b (its own level-1 cells, or the cell it starts). */
static void block_cells(const struct iso_adapt *a, struct piece *pc, const int b[3])
{
    size_t at = block(a, 2, b[0], b[1], b[2]);
    int lam = a->lev2[at];
    if (lam >= 2) {
        int m = (1 << (lam - 2)) - 1;
        if (!(b[0] & m) && !(b[1] & m) && !(b[2] & m))
            polygonise(a, pc, (int[3]){2 * b[0], 2 * b[1], 2 * b[2]}, lam);
        return;
    }
    if (!a->mixed[2][at]) /* level-1 cells where the samples change side */
        return;
    for (int k = 0; k < 8; k++) {
        int o[3] = {2 * b[0] + (k & 1), 2 * b[1] + (k >> 1 & 1), 2 * b[2] + (k >> 2 & 1)};
        if (o[0] + 1 < a->N[0] && o[1] + 1 < a->N[1] && o[2] + 1 < a->N[2])
            polygonise(a, pc, o, 1);
    }
}

static void piece_free(struct piece *pc)
{
    free(pc->keys);
    free(pc->slot);
    free(pc->vkey);
    trimesh_free(&pc->m);
}

void iso_adapt_free(struct iso_adapt *a)
{
    if (!a)
        return;
    free(a->F);
    for (int l = 0; l <= ISO_MAX_LEVELS; l++)
        free(a->M[l]), free(a->mixed[l]);
    free(a->lev2);
    for (int k = 0; k < ADAPT_SLABS; k++)
        piece_free(&a->pieces[k]);
    free(a);
}

int iso_adapt_begin(const struct iso_grid *g, const struct iso_opts *o, int levels, double max_error,
                    struct iso_adapt **out, struct sf_err *err)
{
    *out = NULL;
    if (levels < 1 || levels > ISO_MAX_LEVELS)
        return sf_fail(err, SF_EINVAL, "?levels", "levels is 1 to %d", ISO_MAX_LEVELS);
    if (!(max_error >= 0) || !isfinite(max_error))
        return sf_fail(err, SF_EINVAL, "?max_error", "max_error is a finite length, 0 or more");
    if (g->nx < 2 || g->ny < 2 || g->nz < 2)
        return sf_fail(err, SF_EINVAL, "?dims", "a volume has at least 2 samples on every axis");
    if (!isfinite(o->iso))
        return sf_fail(err, SF_EINVAL, "?iso", "iso is a finite number");
    if ((double)g->nx * g->ny * g->nz > ISO_ADAPT_MAX_SAMPLES)
        return sf_fail(err, SF_ELIMIT, "?levels", "levels over 1 take volumes of at most %u samples",
                       ISO_ADAPT_MAX_SAMPLES);
    struct iso_adapt *a = calloc(1, sizeof *a);
    if (!a)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    a->shift = o->closed ? 1 : 0;
    a->iso = (float)o->iso;
    a->max_err = levels == 1 ? -1 : max_error; /* levels 1: nothing merges */
    a->L = levels < 2 ? 2 : levels;
    int nn[3] = {g->nx, g->ny, g->nz};
    for (int d = 0; d < 3; d++) {
        a->N[d] = nn[d] + 2 * a->shift;
        a->sp[d] = g->spacing[d];
        a->org[d] = g->origin[d] - a->shift * g->spacing[d];
    }
    size_t n = (size_t)a->N[0] * a->N[1] * a->N[2];
    a->g = *g;
    a->pad = o->closed ? (float)fmin(o->iso - 1, iso_grid_min(g)) : 0;
    if (!(a->F = malloc(n * sizeof *a->F))) {
        iso_adapt_free(a);
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the volume's %zu samples", n);
    }
    for (int l = 2; l <= a->L; l++) {
        int s = 1 << (l - 1);
        for (int d = 0; d < 3; d++)
            a->nb[l][d] = (a->N[d] - 1 + s - 1) / s;
        size_t nb = (size_t)a->nb[l][0] * a->nb[l][1] * a->nb[l][2];
        if (!(a->M[l] = calloc(nb ? nb : 1, 1)) || !(a->mixed[l] = calloc(nb ? nb : 1, 1))) {
            iso_adapt_free(a);
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        }
    }
    size_t n2 = (size_t)a->nb[2][0] * a->nb[2][1] * a->nb[2][2];
    if (!(a->lev2 = malloc(n2 ? n2 : 1))) {
        iso_adapt_free(a);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    a->n_slabs = a->nb[2][2] < ADAPT_SLABS ? a->nb[2][2] : ADAPT_SLABS;
    *out = a;
    return 0;
}

int iso_adapt_phases(const struct iso_adapt *a) { return a->L + 1; }

/* Phase 0: planes [z0, z1) of the virtual grid from the samples (the pad layer round them). */
static void load_slab(struct iso_adapt *a, int z0, int z1)
{
    for (int z = z0; z < z1; z++)
        for (int y = 0; y < a->N[1]; y++) {
            float *row = a->F + at3(a, 0, y, z);
            int ry = y - a->shift, rz = z - a->shift;
            if (ry < 0 || ry >= a->g.ny || rz < 0 || rz >= a->g.nz) {
                for (int x = 0; x < a->N[0]; x++)
                    row[x] = a->pad;
                continue;
            }
            iso_grid_row(&a->g, ry, rz, row + a->shift);
            if (a->shift)
                row[0] = row[a->N[0] - 1] = a->pad;
        }
}
int iso_adapt_n_slabs(const struct iso_adapt *a) { return a->n_slabs; }

void iso_adapt_run(struct iso_adapt *a, int phase, int slab)
{
    if (phase == 0) {
        load_slab(a, (int)((long)a->N[2] * slab / a->n_slabs), (int)((long)a->N[2] * (slab + 1) / a->n_slabs));
        return;
    }
    phase--;
    int l = phase + 2 <= a->L ? phase + 2 : 2, nz = a->nb[l][2];
    int z0 = (int)((long)nz * slab / a->n_slabs), z1 = (int)((long)nz * (slab + 1) / a->n_slabs);
    if (phase + 2 <= a->L) {
        mask_slab(a, l, z0, z1, slab);
        return;
    }
    int b[3];
    for (b[2] = z0; b[2] < z1 && !a->pieces[slab].nomem; b[2]++)
        for (b[1] = 0; b[1] < a->nb[2][1]; b[1]++)
            for (b[0] = 0; b[0] < a->nb[2][0]; b[0]++)
                block_cells(a, &a->pieces[slab], b);
}

void iso_adapt_between(struct iso_adapt *a, int phase)
{
    if (phase == a->L - 1) /* the last level's blocks are known */
        cell_levels(a);
}

int iso_adapt_end(struct iso_adapt *a, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    struct piece all = {0};
    int rc = 0;
    for (int k = 0; k < a->n_slabs && !rc; k++) {
        struct piece *pc = &a->pieces[k];
        for (int l = 1; l <= ISO_MAX_LEVELS; l++)
            st->cells[l] += pc->cells[l];
        st->max_estimate = fmax(st->max_estimate, a->slab_max[k]);
        if (pc->nomem) {
            rc = -1;
            break;
        }
        /* the slab's vertices into the mesh, each key once (the slabs' order: the same mesh on any
         * number of threads), its triangles renumbered */
        uint32_t *id = malloc((pc->m.n_vert ? pc->m.n_vert : 1) * sizeof *id);
        if (!id) {
            rc = -1;
            break;
        }
        for (size_t v = 0; v < pc->m.n_vert && !all.nomem; v++) {
            bool found = false;
            size_t h = 0;
            if (pc->vkey[v] != UINT64_MAX && !slot_of(&all, pc->vkey[v], &found, &h))
                break;
            if (found) {
                id[v] = all.slot[h];
                continue;
            }
            double pos[3] = {pc->m.pos[3 * v], pc->m.pos[3 * v + 1], pc->m.pos[3 * v + 2]};
            double nrm[3] = {pc->m.nrm[3 * v], pc->m.nrm[3 * v + 1], pc->m.nrm[3 * v + 2]};
            long g = new_vertex(&all, pos, nrm, pc->vkey[v]);
            if (g < 0)
                break;
            if (pc->vkey[v] != UINT64_MAX)
                keep_slot(&all, h, pc->vkey[v], g);
            id[v] = (uint32_t)g;
        }
        for (size_t t = 0; t < pc->m.n_tri && !all.nomem; t++)
            add_triangle(&all, id[pc->m.tri[3 * t]], id[pc->m.tri[3 * t + 1]], id[pc->m.tri[3 * t + 2]]);
        free(id);
        piece_free(pc);
        memset(pc, 0, sizeof *pc);
        rc = all.nomem ? -1 : 0;
    }
    if (rc) {
        rc = sf_fail(err, all.m.n_vert >= ISO_MAX_VERTICES ? SF_ELIMIT : SF_ENOMEM, "",
                     "the mesh would take more memory than there is (or over %u vertices)", ISO_MAX_VERTICES);
    } else {
        *out = all.m;
        memset(&all.m, 0, sizeof all.m);
    }
    piece_free(&all);
    iso_adapt_free(a);
    return rc;
}

int iso_extract_adaptive(const struct iso_grid *g, const struct iso_opts *o, int levels, double max_error,
                         const struct sf_progress *pr, struct trimesh *out, struct iso_adapt_stats *st,
                         struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    struct iso_adapt *a;
    int rc = iso_adapt_begin(g, o, levels, max_error, &a, err);
    if (rc)
        return rc;
    int phases = iso_adapt_phases(a), n = iso_adapt_n_slabs(a);
    for (int p = 0; p < phases && !rc; p++) {
        for (int s = 0; s < n && !rc; s++) {
            iso_adapt_run(a, p, s);
            rc = sf_poll(pr, (p * n + s + 1.0) / (phases * n), err);
        }
        iso_adapt_between(a, p);
    }
    if (rc) {
        iso_adapt_free(a);
        return rc;
    }
    return iso_adapt_end(a, out, st, err);
}
