/* fragment.c - the mesh of a voxel set as seed 003 has it (matrix.h, matrix_fragments): a fixed
 * fragment of triangles a voxel, every vertex a voxel corner, chosen by a table.
 *
 * The seed's table is a missing figure (METHODS.md §5), and it chooses a voxel's fragment by the
 * voxel's open faces, re-choosing where a neighbour's fragment makes a face "partially open". We
 * choose by corners instead, which makes the re-choice unnecessary: a corner of the lattice is
 * kept when at least KEEP_AT = 4 of the 8 voxels round it are in the set, or two that share a face
 * (an edge of the set: a convex edge, a plate's rim, a rod a voxel across), and each voxel's cube
 * holds the convex hull of its kept corners (its fragment: 256 corner masks, the table made by
 * brute-force hulls on first use). The solid is the union of the hulls. A hull meets a face of
 * its cube in the hull of that face's kept corners, which depends on the face alone, so the two
 * cubes of a face always agree on it: the surface is the hulls' facets inside their cubes, and the
 * faces where a solid hull meets one of no volume, closed by construction. Where hulls touch along
 * an edge or at a point only, trimesh_manifold parts them (midpoints: the computed vertices).
 *
 * The seed's variants, for a voxel whose neighbours continue its closed faces (corners as xyz
 * bits, the open faces on the + sides): 1 open face (+z), nothing cut, the face square; 2 opposite
 * (a plate a voxel thick), both faces; 2 adjacent (+x +z), nothing cut, both faces (the edge kept
 * sharp); 3 at a corner, 111 cut, the triangle 110-101-011 (five sixths kept); 3 with two opposite
 * (a plate's rim) and 4 with the closed pair opposite (a rod a voxel across), nothing cut; 4 with
 * the closed pair adjacent (a plate's corner), 110 111 cut, the quad 100-010-011-101 (half kept);
 * 5 (a rod's end, a lone bump) and 6 keep no volume (counted as dropped_voxels, as are voxels that
 * meet the others only along an edge or at a point). Concave edges keep their corners too, so the
 * empty voxel at a concave edge whose face beyond is a voxel high (the inner edge of a terrace)
 * holds half a voxel: a 2:1 terrace gains half a voxel a step, a ball about nothing (its convex
 * and concave steps balance); matrix_mesh's half-depth chamfers lose a quarter voxel at edges. */
#include "matrix.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"
#include "../iso/mc.h"

/* Corner c of a cube: bit 0 x, bit 1 y, bit 2 z. */
#define CX(c) ((c) & 1)
#define CY(c) ((c) >> 1 & 1)
#define CZ(c) ((c) >> 2 & 1)
#define MAX_TRIS 12
/* A corner is kept when this many of its 8 voxels are in, or two that share a face (edge_corner).
 * Measured on a ball of radius 30 voxels: -0.2 % with 4, +1.4 % with 3; with 3 and no edge corners
 * -1.2 % (a box then loses half a voxel along every edge, thin parts vanish). */
#define KEEP_AT 4

struct fragment {
    bool solid;              /* the hull has volume */
    uint8_t n_tri, tri[MAX_TRIS][3];        /* the facets inside the cube, outward */
    uint8_t n_face[6], face[6][2][3];       /* the facet on face f (2 axis + side), outward */
};

static int dot3(const int a[3], const int b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void corner_of(int c, int p[3]) { p[0] = CX(c), p[1] = CY(c), p[2] = CZ(c); }

/* The hull of the corners in mask k: its facets by brute force (every plane of three kept corners
 * with all the others on one side), each a triangle or a planar quad of corners. */
static void fragment_of(int k, struct fragment *fr)
{
    memset(fr, 0, sizeof *fr);
    int pts[8], np = 0, p[8][3];
    for (int c = 0; c < 8; c++)
        if (k >> c & 1)
            corner_of(c, p[np]), pts[np++] = c;
    int planes[24][4], n_planes = 0;
    for (int a = 0; a < np; a++)
        for (int b = a + 1; b < np; b++)
            for (int c = b + 1; c < np; c++) {
                int u[3], v[3], n[3], pos = 0, neg = 0;
                for (int d = 0; d < 3; d++)
                    u[d] = p[b][d] - p[a][d], v[d] = p[c][d] - p[a][d];
                n[0] = u[1] * v[2] - u[2] * v[1], n[1] = u[2] * v[0] - u[0] * v[2], n[2] = u[0] * v[1] - u[1] * v[0];
                if (!n[0] && !n[1] && !n[2])
                    continue;
                for (int q = 0; q < np; q++) {
                    int s = dot3(n, p[q]) - dot3(n, p[a]);
                    pos += s > 0, neg += s < 0;
                }
                if (pos && neg)
                    continue;
                if (!pos && !neg)
                    return; /* all in one plane: no volume */
                fr->solid = true;
                if (pos) /* outward: the others behind */
                    n[0] = -n[0], n[1] = -n[1], n[2] = -n[2];
                int g = abs(n[0]) | abs(n[1]) | abs(n[2]), key[4];
                for (int d = 0; d < 3; d++) /* (entries are -2..2 on a unit cube; halve while all are even) */
                    key[d] = n[d];
                while (!(g & 1))
                    g >>= 1, key[0] /= 2, key[1] /= 2, key[2] /= 2;
                key[3] = dot3(key, p[a]);
                bool seen = false;
                for (int q = 0; q < n_planes && !seen; q++)
                    seen = !memcmp(planes[q], key, sizeof key);
                if (!seen && n_planes < 24)
                    memcpy(planes[n_planes++], key, sizeof key);
            }
    for (int q = 0; q < n_planes; q++) {
        const int *n = planes[q];
        int on[4], m = 0;
        for (int i = 0; i < np && m < 4; i++)
            if (dot3(n, p[i]) == n[3])
                on[m++] = i;
        /* counter-clockwise about n: by angle round their centre */
        double o[3] = {0, 0, 0}, u[3], w[3], ang[4];
        for (int i = 0; i < m; i++)
            for (int d = 0; d < 3; d++)
                o[d] += p[on[i]][d] / (double)m;
        for (int d = 0; d < 3; d++)
            u[d] = p[on[0]][d] - o[d];
        w[0] = n[1] * u[2] - n[2] * u[1], w[1] = n[2] * u[0] - n[0] * u[2], w[2] = n[0] * u[1] - n[1] * u[0];
        for (int i = 0; i < m; i++) {
            double r[3] = {p[on[i]][0] - o[0], p[on[i]][1] - o[1], p[on[i]][2] - o[2]};
            ang[i] = atan2(r[0] * w[0] + r[1] * w[1] + r[2] * w[2], r[0] * u[0] + r[1] * u[1] + r[2] * u[2]);
        }
        for (int i = 1; i < m; i++)
            for (int j = i; j > 0 && ang[j] < ang[j - 1]; j--) {
                double ta = ang[j];
                int t = on[j];
                ang[j] = ang[j - 1], ang[j - 1] = ta, on[j] = on[j - 1], on[j - 1] = t;
            }
        int axis = n[0] ? (n[1] || n[2] ? -1 : 0) : n[1] ? (n[2] ? -1 : 1) : 2;
        int f = axis >= 0 ? 2 * axis + (n[axis] > 0) : -1; /* on a face of the cube, or inside */
        for (int t = 0; t + 2 < m; t++) {
            uint8_t *tr = f >= 0 ? fr->face[f][fr->n_face[f]++] : fr->tri[fr->n_tri++];
            tr[0] = (uint8_t)pts[on[0]], tr[1] = (uint8_t)pts[on[t + 1]], tr[2] = (uint8_t)pts[on[t + 2]];
        }
    }
}

struct emit {
    struct trimesh m;
    size_t vcap, tcap;
    int32_t *ids[2];         /* vertex ids of two planes of corners, by z & 1 */
    int nx, ny;              /* corners a plane: (n[0] + 1) x (n[1] + 1) */
    double lo[3], d[3];
    bool nomem;
};

/* The id of corner (x, y, z), made on first use (room for it reserved by emit_cube). */
static int32_t corner_id(struct emit *e, int x, int y, int z)
{
    int32_t *id = &e->ids[z & 1][x + (size_t)e->nx * y];
    if (*id >= 0)
        return *id;
    size_t i = e->m.n_vert++;
    e->m.pos[3 * i] = (float)(e->lo[0] + e->d[0] * x);
    e->m.pos[3 * i + 1] = (float)(e->lo[1] + e->d[1] * y);
    e->m.pos[3 * i + 2] = (float)(e->lo[2] + e->d[2] * z);
    return *id = (int32_t)i;
}

/* Triangles t of the cube at v (corners by number; cid: their ids as far as known, else -1). */
static void emit_tris(struct emit *e, int32_t cid[8], const int v[3], const uint8_t (*t)[3], int n)
{
    uint32_t *out = e->m.tri + 3 * e->m.n_tri;
    for (int k = 0; k < n; k++)
        for (int q = 0; q < 3; q++) {
            int c = t[k][q];
            if (cid[c] < 0)
                cid[c] = corner_id(e, v[0] + CX(c), v[1] + CY(c), v[2] + CZ(c));
            *out++ = (uint32_t)cid[c];
        }
    e->m.n_tri += (size_t)n;
}

/* Eight bytes at a time (byte lanes of a word, memcpy'd so alignment and byte order do not matter):
 * sums of 0/1 bytes and shifts of them by under 8 never carry into the next lane. */
#define ONES 0x0101010101010101ull

static uint64_t load8(const uint8_t *p)
{
    uint64_t v;
    memcpy(&v, p, sizeof v);
    return v;
}

static void store8(uint8_t *p, uint64_t v) { memcpy(p, &v, sizeof v); }

static uint64_t nonzero8(uint64_t v) { return ((((v & 0x7f * ONES) + 0x7f * ONES) | v) >> 7) & ONES; }

/* Whether corner (x, y, z), two of whose 8 voxels are in, stands on an edge of the set: the two share a
 * face (a convex edge, a voxel-thick plate's rim, a rod a voxel across), not only an edge or a point. */
static bool edge_corner(const uint8_t *vox, const int n[3], size_t x, size_t y, size_t z)
{
    int occ = 0;
    for (int c = 0; c < 8; c++) {
        size_t vx = x - 1 + (size_t)CX(c), vy = y - 1 + (size_t)CY(c), vz = z - 1 + (size_t)CZ(c);
        if (vx < (size_t)n[0] && vy < (size_t)n[1] && vz < (size_t)n[2] &&
            vox[vx + (size_t)n[0] * (vy + (size_t)n[1] * vz)])
            occ |= 1 << c;
    }
    int i = __builtin_ctz((unsigned)occ), j = 31 - __builtin_clz((unsigned)occ), d = i ^ j;
    return !(d & (d - 1));
}

struct cubes {
    struct fragment *tab;     /* by corner mask, made on first use (have) */
    bool have[256];
    const uint8_t *mask, *vox;
    size_t n[3];
    long dropped;
};

static const struct fragment *fragment(struct cubes *c, int k)
{
    if (!c->have[k])
        fragment_of(k, &c->tab[k]), c->have[k] = true;
    return &c->tab[k];
}

/* Cube (x, y, z)'s facets inside it, and those on its faces where the cube across has no volume. */
static void emit_cube(struct emit *e, struct cubes *c, size_t x, size_t y, size_t z)
{
    const size_t N = c->n[0], M = c->n[1], K = c->n[2], at = x + N * (y + M * z);
    uint8_t k = c->mask[at];
    const struct fragment *fr = fragment(c, k);
    if (!fr->solid) {
        c->dropped += c->vox[at] != 0;
        return;
    }
    bool inner = x > 0 && x + 1 < N && y > 0 && y + 1 < M && z > 0 && z + 1 < K;
    const uint8_t *mk = c->mask;
    if (k == 255 && inner && (mk[at - 1] & mk[at + 1] & mk[at - N] & mk[at + N] & mk[at - N * M] & mk[at + N * M]) == 255)
        return; /* inside */
    int v[3] = {(int)x, (int)y, (int)z};
    int32_t cid[8] = {-1, -1, -1, -1, -1, -1, -1, -1};
    if (e->m.n_vert + 8 > ISO_MAX_VERTICES ||
        mem_reserve((void **)&e->m.pos, &e->vcap, 3 * (e->m.n_vert + 8), sizeof(float)) ||
        mem_reserve((void **)&e->m.tri, &e->tcap, 3 * (e->m.n_tri + MAX_TRIS + 12), sizeof(uint32_t))) {
        e->nomem = true;
        return;
    }
    if (fr->n_tri)
        emit_tris(e, cid, v, (const uint8_t(*)[3])fr->tri, fr->n_tri);
    const size_t pos[3] = {x, y, z};
    const ptrdiff_t step[6] = {-1, 1, -(ptrdiff_t)N, (ptrdiff_t)N, -(ptrdiff_t)(N * M), (ptrdiff_t)(N * M)};
    for (int f = 0; f < 6; f++) {
        if (!fr->n_face[f])
            continue;
        size_t a = pos[f >> 1];
        bool edge = f & 1 ? a + 1 == c->n[f >> 1] : a == 0;
        if (edge || !fragment(c, mk[at + step[f]])->solid) /* drawn from the solid side */
            emit_tris(e, cid, v, (const uint8_t(*)[3])fr->face[f], fr->n_face[f]);
    }
}

/* Whether the 8 cubes from `at` on, all whole, are inside (whole neighbours all round). */
static bool inside8(const struct cubes *c, size_t x, size_t y, size_t z, size_t at)
{
    const size_t N = c->n[0], NM = N * c->n[1];
    const uint8_t *mk = c->mask;
    return x > 0 && x + 8 < N && y > 0 && y + 1 < c->n[1] && z > 0 && z + 1 < c->n[2] && mk[at - 1] == 255 &&
           mk[at + 8] == 255 && (load8(mk + at - N) & load8(mk + at + N) & load8(mk + at - NM) & load8(mk + at + NM)) == ~0ull;
}

int matrix_fragments(const int n[3], const uint8_t *vox, const double lo[3], const double d[3], struct trimesh *out,
                     struct matrix_stats *st, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    const size_t N = (size_t)n[0], M = (size_t)n[1], K = (size_t)n[2], nv = N * M * K;
    const size_t cx = N + 1, cy = M + 1, plane = cx * cy;
    struct fragment *tab = malloc(256 * sizeof *tab);
    uint8_t *kept = malloc(plane * (K + 1)), *mask = calloc(nv ? nv : 1, 1), *col = malloc((N + 2) * (M + 2));
    struct emit e = {.nx = (int)cx, .ny = (int)cy};
    struct cubes cu = {.tab = tab, .mask = mask, .vox = vox, .n = {N, M, K}};
    e.ids[0] = malloc(plane * sizeof(int32_t)), e.ids[1] = malloc(plane * sizeof(int32_t));
    memcpy(e.lo, lo, sizeof e.lo);
    memcpy(e.d, d, sizeof e.d);
    e.nomem = !tab || !kept || !mask || !col || !e.ids[0] || !e.ids[1];
    if (!e.nomem) {
        /* the set's box: no cube outside it holds a solid hull (its kept corners lie in one face) */
        size_t lo3[3] = {N, M, K}, hi3[3] = {0, 0, 0};
        for (size_t z = 0; z < K; z++)
            for (size_t y = 0; y < M; y++) {
                const uint8_t *r = vox + N * (y + M * z);
                size_t x0 = 0, x1 = N;
                while (x0 + 8 <= N && !load8(r + x0))
                    x0 += 8;
                while (x0 < N && !r[x0])
                    x0++;
                if (x0 == N)
                    continue;
                while (x1 >= x0 + 8 && !load8(r + x1 - 8))
                    x1 -= 8;
                while (!r[x1 - 1])
                    x1--;
                lo3[0] = x0 < lo3[0] ? x0 : lo3[0], hi3[0] = x1 > hi3[0] ? x1 : hi3[0];
                lo3[1] = y < lo3[1] ? y : lo3[1], hi3[1] = y + 1 > hi3[1] ? y + 1 : hi3[1];
                lo3[2] = z < lo3[2] ? z : lo3[2], hi3[2] = z + 1;
            }
        const size_t x0 = lo3[0], x1 = hi3[0];
        /* kept corners: at least KEEP_AT of their 8 voxels in (the sums of two layers, then of 2 x 2) */
        for (size_t z = lo3[2]; z <= hi3[2]; z++) {
            memset(col, 0, (N + 2) * (M + 2));
            for (size_t y = lo3[1]; y < hi3[1]; y++) {
                const uint8_t *a = z > 0 ? vox + N * (y + M * (z - 1)) : NULL, *b = z < K ? vox + N * (y + M * z) : NULL;
                uint8_t *cr = col + (N + 2) * (y + 1) + 1;
                size_t x = x0;
                for (; x + 8 <= x1; x += 8)
                    store8(cr + x, (a ? nonzero8(load8(a + x)) : 0) + (b ? nonzero8(load8(b + x)) : 0));
                for (; x < x1; x++)
                    cr[x] = (uint8_t)((a && a[x]) + (b && b[x]));
            }
            for (size_t y = lo3[1]; y <= hi3[1]; y++) {
                const uint8_t *r0 = col + (N + 2) * y, *r1 = r0 + (N + 2);
                uint8_t *kr = kept + plane * z + cx * y;
                size_t x = x0;
                for (; x + 8 <= x1 + 1; x += 8) {
                    uint64_t sum = load8(r0 + x) + load8(r0 + x + 1) + load8(r1 + x) + load8(r1 + x + 1);
                    store8(kr + x, ((sum + (128 - KEEP_AT) * ONES) >> 7) & ONES);
                    for (uint64_t two = ~nonzero8(sum ^ 2 * ONES) & ONES; two; two &= two - 1) {
                        size_t at = x + (size_t)(__builtin_ctzll(two) >> 3);
                        kr[at] = edge_corner(vox, n, at, y, z);
                    }
                }
                for (; x <= x1; x++)
                    kr[x] = r0[x] + r0[x + 1] + r1[x] + r1[x + 1] >= KEEP_AT ||
                            (r0[x] + r0[x + 1] + r1[x] + r1[x + 1] == 2 && edge_corner(vox, n, x, y, z));
            }
        }
        for (size_t z = lo3[2]; z < hi3[2]; z++)
            for (size_t y = lo3[1]; y < hi3[1]; y++) {
                const uint8_t *k00 = kept + plane * z + cx * y, *k01 = k00 + cx, *k10 = k00 + plane, *k11 = k10 + cx;
                uint8_t *mr = mask + N * (y + M * z);
                size_t x = x0;
                for (; x + 8 <= x1; x += 8)
                    store8(mr + x, load8(k00 + x) | load8(k00 + x + 1) << 1 | load8(k01 + x) << 2 |
                                       load8(k01 + x + 1) << 3 | load8(k10 + x) << 4 | load8(k10 + x + 1) << 5 |
                                       load8(k11 + x) << 6 | load8(k11 + x + 1) << 7);
                for (; x < x1; x++)
                    mr[x] = (uint8_t)(k00[x] | k00[x + 1] << 1 | k01[x] << 2 | k01[x + 1] << 3 | k10[x] << 4 |
                                      k10[x + 1] << 5 | k11[x] << 6 | k11[x + 1] << 7);
            }
        memset(e.ids[0], 0xff, plane * sizeof(int32_t));
        /* the cubes, eight at a time past empty runs and inside ones */
        for (size_t z = lo3[2]; z < hi3[2] && !e.nomem; z++) {
            memset(e.ids[(z + 1) & 1], 0xff, plane * sizeof(int32_t));
            for (size_t y = lo3[1]; y < hi3[1]; y++) {
                const size_t row = N * (y + M * z);
                for (size_t x = x0; x < x1;) {
                    if (x + 8 <= x1) {
                        uint64_t m8 = load8(mask + row + x);
                        if ((!m8 && !load8(vox + row + x)) || (m8 == ~0ull && inside8(&cu, x, y, z, row + x))) {
                            x += 8;
                            continue;
                        }
                    }
                    for (size_t end = x + 8 < x1 ? x + 8 : x1; x < end; x++)
                        emit_cube(&e, &cu, x, y, z);
                }
            }
        }
    }
    free(tab), free(kept), free(mask), free(col), free(e.ids[0]), free(e.ids[1]);
    long mid = 0;
    if (!e.nomem && trimesh_manifold(&e.m, &e.vcap, &e.tcap, &mid))
        e.nomem = true;
    if (e.nomem) {
        bool limit = e.m.n_vert + 8 > ISO_MAX_VERTICES;
        trimesh_free(&e.m);
        return sf_fail(err, limit ? SF_ELIMIT : SF_ENOMEM, "", "the mesh would take more memory than there is");
    }
    *out = e.m;
    if (st)
        st->computed_vertices = mid, st->dropped_voxels = cu.dropped;
    return 0;
}
