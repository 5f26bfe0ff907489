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
 * an edge or at a point only, trimesh_manifold parts them (midpoints: the computed vertices); the
 * fans noted as the mesh is made (struct fan) say whether there is such a place, so a mesh without
 * one is done when made. The cubes go a layer at a time (kept corners of three planes, corner masks
 * of three layers): beyond the voxels and the mesh, the memory is a few planes.
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
#include <stdatomic.h>
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

/* A triangle's corner: the cube's corner c, and the directions (dir_of) from it to the corners after
 * and before it in the triangle. */
struct corner {
    uint8_t c, next, prev;
};

struct fragment {
    bool solid;                          /* the hull has volume */
    uint8_t n_tri, n_face[6], faces;     /* faces: bit f where n_face[f] */
    struct corner tri[MAX_TRIS][3];      /* the facets inside the cube, outward */
    struct corner face[6][2][3];         /* the facet on face f (2 axis + side), outward */
};

/* The lattice direction from corner a of a cube to corner b (0..26, 13 itself). */
static int dir_of(int a, int b) { return 13 + (CX(b) - CX(a)) + 3 * (CY(b) - CY(a)) + 9 * (CZ(b) - CZ(a)); }

/* The dot product of integer lattice vectors (exact; vec.h's dot3 is of doubles). */
static int idot3(const int a[3], const int b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

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
                    int s = idot3(n, p[q]) - idot3(n, p[a]);
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
                key[3] = idot3(key, p[a]);
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
            if (idot3(n, p[i]) == n[3])
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
            if (f >= 0)
                fr->faces |= (uint8_t)(1 << f);
            struct corner *tr = f >= 0 ? fr->face[f][fr->n_face[f]++] : fr->tri[fr->n_tri++];
            int c[3] = {pts[on[0]], pts[on[t + 1]], pts[on[t + 2]]};
            for (int i = 0; i < 3; i++)
                tr[i] = (struct corner){(uint8_t)c[i], (uint8_t)dir_of(c[i], c[(i + 1) % 3]),
                                        (uint8_t)dir_of(c[i], c[(i + 2) % 3])};
        }
    }
}

/* The 256 fragments, made once a process (the first caller's table is kept, a racing one's freed:
 * an atomic pointer, no lock). NULL without memory. */
static const struct fragment *fragments(void)
{
    static _Atomic(struct fragment *) shared;
    struct fragment *tab = atomic_load_explicit(&shared, memory_order_acquire), *none = NULL;
    if (tab)
        return tab;
    if (!(tab = malloc(256 * sizeof *tab)))
        return NULL;
    for (int k = 0; k < 256; k++)
        fragment_of(k, &tab[k]);
    if (atomic_compare_exchange_strong_explicit(&shared, &none, tab, memory_order_acq_rel, memory_order_acquire))
        return tab;
    free(tab);
    return none;
}

/* Each corner's fan, noted as its triangles are emitted, so that a mesh whose fans all close needs no
 * trimesh_manifold (the usual case; the fragments close by construction, but solids that touch along
 * an edge or at a point give an edge of four triangles or a corner of two fans). A corner's
 * neighbours in the mesh are lattice neighbours, named by direction (dir_of): bit d of `next` is set
 * for the triangle whose corner after this one lies in direction d, and before[d] is then the
 * direction of its corner before this one; `prev` has those. An edge of more than two triangles shows
 * as a bit of next set twice. The fan closes when next == prev; it is one fan when the walk d ->
 * before[d] takes all of them in turn (two fans need 6 triangles). Kept for two planes of corners
 * (struct emit's slot): a plane's corners are complete when the layer of cubes above it is. */
struct fan {
    uint32_t id, at;           /* the vertex, its corner's index in the plane */
    uint32_t next, prev;
    uint8_t before[27], n;     /* n: triangles */
};

struct emit {
    struct trimesh m;
    size_t vcap, tcap;
    int32_t *slot[2];          /* two planes of corners (by z & 1): the fan of each made a vertex, else -1 */
    struct fan *fan[2];        /* those fans, in the order made */
    uint32_t n_fan[2];
    bool open;                 /* a fan seen not to close: trimesh_manifold decides */
    int nx, ny;                /* corners a plane: (n[0] + 1) x (n[1] + 1) */
    double lo[3], d[3];
    bool nomem;
};

/* Corner (x, y, z)'s vertex and fan, made on first use (room for the vertex reserved by emit_reserve). */
static struct fan *corner(struct emit *e, int x, int y, int z)
{
    uint32_t at = (uint32_t)x + (uint32_t)e->nx * (uint32_t)y;
    int32_t *slot = &e->slot[z & 1][at];
    if (*slot >= 0)
        return &e->fan[z & 1][*slot];
    size_t i = e->m.n_vert++;
    e->m.pos[3 * i] = (float)(e->lo[0] + e->d[0] * x);
    e->m.pos[3 * i + 1] = (float)(e->lo[1] + e->d[1] * y);
    e->m.pos[3 * i + 2] = (float)(e->lo[2] + e->d[2] * z);
    *slot = (int32_t)e->n_fan[z & 1]++;
    struct fan *f = &e->fan[z & 1][*slot];
    f->id = (uint32_t)i, f->at = at, f->next = f->prev = 0, f->n = 0;
    return f;
}

/* Triangles t of the cube at v (cf: the fans of its corners as far as known, else NULL). */
static void emit_tris(struct emit *e, struct fan *cf[8], const int v[3], const struct corner (*t)[3], int n)
{
    uint32_t *out = e->m.tri + 3 * e->m.n_tri;
    for (const struct corner *q = t[0], *end = t[n]; q < end; q++) {
        int c = q->c;
        if (!cf[c])
            cf[c] = corner(e, v[0] + CX(c), v[1] + CY(c), v[2] + CZ(c));
        struct fan *f = cf[c];
        uint32_t bit = 1u << q->next;
        e->open |= (f->next & bit) != 0;
        f->next |= bit, f->prev |= 1u << q->prev, f->before[q->next] = q->prev, f->n++;
        *out++ = f->id;
    }
    e->m.n_tri += (size_t)n;
}

/* Plane p's corners are complete: whether their fans close as one (see struct fan); the plane
 * cleared for reuse. */
static void plane_done(struct emit *e, int p)
{
    for (uint32_t i = 0; i < e->n_fan[p]; i++) {
        const struct fan *f = &e->fan[p][i];
        int k = f->n;
        e->open |= f->next != f->prev;
        if (k >= 6 && !e->open) {
            int d0 = __builtin_ctz(f->next), d = d0, steps = 0;
            do /* (bounded: before[] need not be one-to-one where an edge repeats) */
                d = f->before[d], steps++;
            while (d != d0 && steps <= k);
            e->open |= steps != k;
        }
        e->slot[p][f->at] = -1;
    }
    e->n_fan[p] = 0;
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

/* The cubes of one layer: their corner masks (mk), and those of the layers below and above (0 beyond
 * the set's box). */
struct cubes {
    const struct fragment *tab; /* by corner mask */
    bool solid[256];            /* tab[k].solid */
    const uint8_t *below, *mk, *above, *vox;
    size_t n[3];
    long dropped;
    struct fan *cf[8];          /* the corners of the last cube emitted, as far as known */
    size_t cf_next;             /* its index in the layer + 1 (SIZE_MAX: none in this row) */
};

/* Room for `cubes` more cubes' vertices and triangles. */
static void emit_reserve(struct emit *e, size_t cubes)
{
    if (mem_reserve((void **)&e->m.pos, &e->vcap, 3 * (e->m.n_vert + 8 * cubes), sizeof(float)) ||
        mem_reserve((void **)&e->m.tri, &e->tcap, 3 * (e->m.n_tri + (MAX_TRIS + 12) * cubes), sizeof(uint32_t)))
        e->nomem = true;
}

/* Cube (x, y, z)'s facets inside it, and those on its faces where the cube across has no volume
 * (room reserved by emit_reserve). at: its index in the layer. */
static void emit_cube(struct emit *e, struct cubes *c, size_t x, size_t y, size_t z, size_t at)
{
    const size_t N = c->n[0], M = c->n[1], K = c->n[2];
    const uint8_t *mk = c->mk, k = mk[at];
    const struct fragment *fr = &c->tab[k];
    if (!fr->solid) {
        c->dropped += c->vox[at + N * M * z] != 0;
        return;
    }
    bool inner = x > 0 && x + 1 < N && y > 0 && y + 1 < M && z > 0 && z + 1 < K;
    if (k == 255 && inner && (mk[at - 1] & mk[at + 1] & mk[at - N] & mk[at + N] & c->below[at] & c->above[at]) == 255)
        return; /* inside */
    if (e->m.n_vert + 8 > ISO_MAX_VERTICES) {
        e->nomem = true;
        return;
    }
    int v[3] = {(int)x, (int)y, (int)z};
    struct fan **cf = c->cf;
    if (c->cf_next == at) /* the cube before: its corners on +x are this one's on -x */
        cf[0] = cf[1], cf[2] = cf[3], cf[4] = cf[5], cf[6] = cf[7], cf[1] = cf[3] = cf[5] = cf[7] = NULL;
    else
        memset(cf, 0, sizeof c->cf);
    c->cf_next = at + 1;
    if (fr->n_tri)
        emit_tris(e, cf, v, fr->tri, fr->n_tri);
    const size_t pos[3] = {x, y, z};
    const ptrdiff_t step[4] = {-1, 1, -(ptrdiff_t)N, (ptrdiff_t)N};
    for (unsigned faces = fr->faces; faces; faces &= faces - 1) {
        int f = __builtin_ctz(faces);
        size_t a = pos[f >> 1];
        bool wall = f & 1 ? a + 1 == c->n[f >> 1] : a == 0;
        /* on the box's wall, else drawn from the solid side */
        if (wall || !c->solid[f < 4 ? mk[at + step[f]] : f == 4 ? c->below[at] : c->above[at]])
            emit_tris(e, cf, v, fr->face[f], fr->n_face[f]);
    }
}

/* Of the 8 cubes from (x, y, z) on (index `at` in the layer, vr: their voxels), those that may emit
 * or drop something, as the low bits of byte lanes: a solid hull not inside (whole, with whole
 * neighbours all round; tested away from the walls, emit_cube tests the rest), or a voxel in. */
static uint64_t busy8(const struct cubes *c, size_t x, size_t y, size_t z, size_t at, const uint8_t *vr)
{
    const size_t N = c->n[0];
    const uint8_t *mk = c->mk;
    uint64_t m = load8(mk + at), in = nonzero8(load8(vr)), solid = 0;
    if (!(m | in))
        return 0;
    for (int i = 0; i < 8; i++)
        solid |= (uint64_t)c->solid[m >> 8 * i & 0xff] << 8 * i;
    if (x > 0 && x + 8 < N && y > 0 && y + 1 < c->n[1] && z > 0 && z + 1 < c->n[2])
        return (solid | in) & nonzero8(~(m & load8(mk + at - 1) & load8(mk + at + 1) & load8(mk + at - N) &
                                         load8(mk + at + N) & load8(c->below + at) & load8(c->above + at)));
    return solid | in;
}

/* The set's box: lo..hi (exclusive) on each axis; no cube outside it holds a solid hull (its kept
 * corners lie in one face). Empty: lo > hi. */
static void set_box(const uint8_t *vox, const size_t n[3], size_t lo[3], size_t hi[3])
{
    const size_t N = n[0];
    lo[0] = n[0], lo[1] = n[1], lo[2] = n[2], hi[0] = hi[1] = hi[2] = 0;
    for (size_t z = 0; z < n[2]; z++)
        for (size_t y = 0; y < n[1]; y++) {
            const uint8_t *r = vox + N * (y + n[1] * z);
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
            lo[0] = x0 < lo[0] ? x0 : lo[0], hi[0] = x1 > hi[0] ? x1 : hi[0];
            lo[1] = y < lo[1] ? y : lo[1], hi[1] = y + 1 > hi[1] ? y + 1 : hi[1];
            lo[2] = z < lo[2] ? z : lo[2], hi[2] = z + 1;
        }
}

/* Plane z of kept corners in the box (x lo[0]..hi[0], y lo[1]..hi[1], both ends in): at least KEEP_AT
 * of their 8 voxels in (the sums of two layers, then of 2 x 2), or two on an edge of the set. col:
 * (N + 2) x (M + 2) bytes of room. */
static void kept_plane(const uint8_t *vox, const int n[3], const size_t lo[3], const size_t hi[3], size_t z,
                       uint8_t *col, uint8_t *kept)
{
    const size_t N = (size_t)n[0], M = (size_t)n[1], K = (size_t)n[2], cx = N + 1, x0 = lo[0], x1 = hi[0];
    memset(col, 0, (N + 2) * (M + 2));
    for (size_t y = lo[1]; y < hi[1]; y++) {
        const uint8_t *a = z > 0 ? vox + N * (y + M * (z - 1)) : NULL, *b = z < K ? vox + N * (y + M * z) : NULL;
        uint8_t *cr = col + (N + 2) * (y + 1) + 1;
        size_t x = x0;
        for (; x + 8 <= x1; x += 8)
            store8(cr + x, (a ? nonzero8(load8(a + x)) : 0) + (b ? nonzero8(load8(b + x)) : 0));
        for (; x < x1; x++)
            cr[x] = (uint8_t)((a && a[x]) + (b && b[x]));
    }
    for (size_t y = lo[1]; y <= hi[1]; y++) {
        const uint8_t *r0 = col + (N + 2) * y, *r1 = r0 + (N + 2);
        uint8_t *kr = kept + cx * y;
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

/* A layer of cube corner masks in the box from kept planes k0 (below) and k1 (above). */
static void mask_plane(const size_t n[3], const size_t lo[3], const size_t hi[3], const uint8_t *k0, const uint8_t *k1,
                       uint8_t *mask)
{
    const size_t N = n[0], cx = N + 1, x0 = lo[0], x1 = hi[0];
    for (size_t y = lo[1]; y < hi[1]; y++) {
        const uint8_t *k00 = k0 + cx * y, *k01 = k00 + cx, *k10 = k1 + cx * y, *k11 = k10 + cx;
        uint8_t *mr = mask + N * y;
        size_t x = x0;
        for (; x + 8 <= x1; x += 8)
            store8(mr + x, load8(k00 + x) | load8(k00 + x + 1) << 1 | load8(k01 + x) << 2 | load8(k01 + x + 1) << 3 |
                               load8(k10 + x) << 4 | load8(k10 + x + 1) << 5 | load8(k11 + x) << 6 |
                               load8(k11 + x + 1) << 7);
        for (; x < x1; x++)
            mr[x] = (uint8_t)(k00[x] | k00[x + 1] << 1 | k01[x] << 2 | k01[x + 1] << 3 | k10[x] << 4 |
                              k10[x + 1] << 5 | k11[x] << 6 | k11[x + 1] << 7);
    }
}

int matrix_fragments(const int n[3], const uint8_t *vox, const double lo[3], const double d[3], struct trimesh *out,
                     struct matrix_stats *st, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    const size_t N = (size_t)n[0], M = (size_t)n[1], K = (size_t)n[2];
    const size_t plane = (N + 1) * (M + 1), layer = N * M;
    struct emit e = {.nx = (int)N + 1, .ny = (int)M + 1};
    struct cubes cu = {.tab = fragments(), .vox = vox, .n = {N, M, K}};
    /* a layer of cubes at a time: kept corners of 3 planes and corner masks of 3 layers in turn,
     * plus a zero layer for the layers beyond the box */
    uint8_t *kept = malloc(3 * plane), *masks = calloc(4 * layer + 8, 1), *col = malloc((N + 2) * (M + 2));
    e.nomem = !cu.tab || !kept || !masks || !col;
    for (int p = 0; p < 2; p++) {
        e.slot[p] = malloc(plane * sizeof(int32_t)), e.fan[p] = malloc(plane * sizeof(struct fan));
        e.nomem |= !e.slot[p] || !e.fan[p];
        if (e.slot[p])
            memset(e.slot[p], 0xff, plane * sizeof(int32_t));
    }
    memcpy(e.lo, lo, sizeof e.lo);
    memcpy(e.d, d, sizeof e.d);
    size_t b0[3], b1[3];
    if (!e.nomem) {
        for (int k = 0; k < 256; k++)
            cu.solid[k] = cu.tab[k].solid;
        set_box(vox, cu.n, b0, b1);
    }
    if (!e.nomem && b0[2] < b1[2]) {
        const uint8_t *zero = masks + 3 * layer;
#define KEPT(z) (kept + plane * ((z) % 3))
#define MASK(z) (masks + layer * ((z) % 3))
        kept_plane(vox, n, b0, b1, b0[2], col, KEPT(b0[2]));
        kept_plane(vox, n, b0, b1, b0[2] + 1, col, KEPT(b0[2] + 1));
        mask_plane(cu.n, b0, b1, KEPT(b0[2]), KEPT(b0[2] + 1), MASK(b0[2]));
        /* the cubes, eight at a time, those that may emit something; plane z - 1 of corners complete
         * at layer z */
        for (size_t z = b0[2]; z < b1[2] && !e.nomem; z++) {
            if (z + 1 < b1[2]) {
                kept_plane(vox, n, b0, b1, z + 2, col, KEPT(z + 2));
                mask_plane(cu.n, b0, b1, KEPT(z + 1), KEPT(z + 2), MASK(z + 1));
            }
            cu.below = z > b0[2] ? MASK(z - 1) : zero, cu.mk = MASK(z), cu.above = z + 1 < b1[2] ? MASK(z + 1) : zero;
            plane_done(&e, (z + 1) & 1);
            for (size_t y = b0[1]; y < b1[1]; y++) {
                const size_t row = N * y;
                const uint8_t *vr = vox + layer * z + row;
                emit_reserve(&e, b1[0] - b0[0]);
                cu.cf_next = SIZE_MAX;
                size_t x = b0[0];
                /* (past the box no corner is kept and no voxel is in: a last group may run over it) */
                for (; x < b1[0] && x + 8 <= N && !e.nomem; x += 8)
                    for (uint64_t busy = busy8(&cu, x, y, z, row + x, vr + x); busy; busy &= busy - 1) {
                        size_t at = x + (size_t)(__builtin_ctzll(busy) >> 3);
                        emit_cube(&e, &cu, at, y, z, row + at);
                    }
                for (; x < b1[0] && !e.nomem; x++)
                    if (cu.solid[cu.mk[row + x]] || vr[x])
                        emit_cube(&e, &cu, x, y, z, row + x);
            }
        }
#undef KEPT
#undef MASK
        plane_done(&e, 0), plane_done(&e, 1);
    }
    free(kept), free(masks), free(col);
    for (int p = 0; p < 2; p++)
        free(e.slot[p]), free(e.fan[p]);
    long mid = 0;
    if (!e.nomem && e.open && trimesh_manifold(&e.m, &e.vcap, &e.tcap, &mid))
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
