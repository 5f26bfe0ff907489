/* adapt.c - the adaptive hierarchy with crack-free joins (adapt.h). The grid is copied as floats
 * with its pad layer (closed=true), as mc.c sees it; nodes and cells are addressed by their
 * integer coordinates in that grid. */
#include "adapt.h"
#include "cube.h"

#include <math.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"
#include "../base/vec.h"

/* One slab's share of the mesh (the cells phase runs slab by slab, on any threads): vertices keyed
 * by the finest edge they lie on, merged across slabs at the end. */
struct piece {
    uint64_t *keys;
    uint32_t *slot;
    size_t cap, used;
    uint64_t *vkey;                    /* each vertex's key (UINT64_MAX: a fan's centre) */
    struct trimesh m;
    size_t vcap, tcap, kcap;
    uint32_t *owner;                   /* each triangle's level-2 block (the cell <-> triangle map) */
    size_t ocap;
    uint32_t block;                    /* the block whose cells are being drawn */
    atomic_size_t *tri_total;          /* the slabs' triangles together, by TRI_CHUNK (NULL: uncounted) */
    size_t tri_limit;                  /* ... the opts' max_triangles */
    bool over;                         /* stopped at tri_limit (with nomem) */
    bool nomem;
    long cells[ISO_MAX_LEVELS + 1];
    long feature_points;
};

#define HIDES 2 /* in mixed[2]: a fine edge of the block carries crossings its samples do not show */
#define ADAPT_SLABS 16 /* fixed, so that the mesh does not depend on the number of threads */

struct iso_adapt {
    int N[3], shift;
    float iso;
    double org[3], sp[3], max_err;
    int L, n_slabs;
    bool sharp;
    double (*field)(const void *ctx, const double p[3], double g[3]);
    const void *field_ctx;
    const char *tri_limit_by;          /* the opts' max_triangles_by */
    struct iso_grid g;                 /* the samples, copied into F by the first phase */
    float pad;
    float *F;                          /* the virtual grid, x fastest */
    int nb[ISO_MAX_LEVELS + 1][3];     /* blocks per axis at each level */
    uint8_t *M[ISO_MAX_LEVELS + 1];    /* [l][block]: covered by a cell of level >= l (l >= 2) */
    uint8_t *lev2;                     /* each level-2 block's cell level (1: cut into level-1 cells) */
    uint8_t *mixed[ISO_MAX_LEVELS + 1]; /* [l][block]: its samples are on both sides of iso (l >= 2;
                                         * level 2: or the grid's end cuts it, or HIDES) */
    double slab_max[ADAPT_SLABS];      /* the largest error a merge accepted, by slab */
    float slab_min[ADAPT_SLABS];       /* the least sample, by slab (the first phase's) */
    struct piece pieces[ADAPT_SLABS];
    atomic_size_t tri_total;           /* the pieces' triangles, counted as they grow */
    /* opts keep: what local rebuilds need (iso_adapt_keep, iso_adapt_edit) */
    double *berr[ISO_MAX_LEVELS + 1];  /* [l][block]: the error its merge accepted */
    uint8_t *bcells, *bfeat;           /* [level-2 block]: the cells it drew, their feature points */
    bool kept;
    struct piece all;                  /* the mesh, its vertices keyed as the pieces' */
    uint32_t *refs;                    /* each vertex's triangles */
    size_t rcap, dead;                 /* dead: vertices no triangle uses */
    long cells[ISO_MAX_LEVELS + 1], feature_points;
    double gmin, iso1;                 /* the samples' smallest and iso - 1: the pad is the lower */
    size_t n_min;                      /* samples at gmin */
};

static size_t at3(const struct iso_adapt *a, int x, int y, int z) { return (size_t)x + (size_t)a->N[0] * ((size_t)y + (size_t)a->N[1] * z); }
static float F(const struct iso_adapt *a, int x, int y, int z) { return a->F[at3(a, x, y, z)]; }

static size_t block(const struct iso_adapt *a, int l, int bx, int by, int bz)
{
    return (size_t)bx + (size_t)a->nb[l][0] * ((size_t)by + (size_t)a->nb[l][1] * bz);
}

static float Fp(const struct iso_adapt *a, const int p[3]) { return F(a, p[0], p[1], p[2]); }

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

static bool hides_crossings(const struct iso_adapt *a, const int o[3], int s);

/* A crossing's key: the finest edge it lies on. */
static uint64_t edge_key(const struct iso_adapt *a, const int n[3], int axis)
{
    return (uint64_t)at3(a, n[0], n[1], n[2]) * 3 + (uint64_t)axis;
}

/* The vertex a loop of n is fanned from: of those none of whose diagonals joins two vertices of
 * one cell face (faces: each vertex's face bits), the first, or with keys the one of least key
 * (merged cells: so that block_error and the mesh pick the same whichever vertex their loops
 * start from), or -1 (then from a centre). */
static int fan_apex(const int *faces, const uint64_t *keys, int n)
{
    int apex = -1;
    for (int p = 0; p < n && (keys || apex < 0); p++) {
        bool ok = true;
        for (int k = 2; k + 1 < n && ok; k++)
            ok = !(faces[p] & faces[(p + k) % n]);
        if (ok && (apex < 0 || keys[p] < keys[apex]))
            apex = p;
    }
    return apex;
}

/* The triangle of a loop of n fanned from its apex (-1: from a centre) that holds the loop's
 * edge from vertex k to k + 1: the fan's triangles numbered from the apex's next edge (from a
 * centre: one an edge); the apex's own two edges are those of the first and the last. */
static int fan_triangle(int k, int apex, int n)
{
    if (apex < 0)
        return k;
    int r = (k - apex + n) % n;
    return r == 0 ? 0 : r == n - 1 ? n - 3 : r - 1;
}

/* The centre of a loop without an apex in the cell of s nodes a side at o: the crossing of a fine
 * edge inside the cell (on none of its faces) nearest the loop's mean x, a vertex of the
 * full-resolution surface, so that the fan's centre lies on it: its edge's lower node into n and
 * axis, and the samples' crossing into x; false when the cell has none (level 1). */
static bool inner_crossing(const struct iso_adapt *a, const int o[3], int s, double x[3], int n[3], int *axis)
{
    double at[3];
    double best = INFINITY;
    for (int ax = 0; ax < 3; ax++) {
        int u = (ax + 1) % 3, w = (ax + 2) % 3, p[3];
        for (p[u] = o[u] + 1; p[u] < o[u] + s; p[u]++)
            for (p[w] = o[w] + 1; p[w] < o[w] + s; p[w]++)
                for (p[ax] = o[ax]; p[ax] < o[ax] + s; p[ax]++) {
                    int q[3] = {p[0], p[1], p[2]};
                    q[ax]++;
                    double f0 = Fp(a, p) - a->iso, f1 = Fp(a, q) - a->iso;
                    if ((f0 > 0) == (f1 > 0))
                        continue;
                    double t = f0 / (f0 - f1), d2 = 0, y[3];
                    for (int d = 0; d < 3; d++) {
                        y[d] = a->org[d] + a->sp[d] * (p[d] + (d == ax ? t : 0));
                        d2 += (y[d] - x[d]) * (y[d] - x[d]);
                    }
                    if (d2 < best)
                        best = d2, memcpy(n, p, sizeof p), *axis = ax, memcpy(at, y, sizeof y);
                }
    }
    if (best < INFINITY)
        memcpy(x, at, sizeof at);
    return best < INFINITY;
}

/* Whether 2-D segments p-q and r-s cross, or may touch. */
static bool segs_meet(const double p[2], const double q[2], const double r[2], const double s[2])
{
    double d1 = (s[0] - r[0]) * (p[1] - r[1]) - (s[1] - r[1]) * (p[0] - r[0]);
    double d2 = (s[0] - r[0]) * (q[1] - r[1]) - (s[1] - r[1]) * (q[0] - r[0]);
    double d3 = (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]);
    double d4 = (q[0] - p[0]) * (s[1] - p[1]) - (q[1] - p[1]) * (s[0] - p[0]);
    if (d1 == 0 || d2 == 0 || d3 == 0 || d4 == 0) /* (an end on the other's line: taken to meet) */
        return true;
    return (d1 > 0) != (d2 > 0) && (d3 > 0) != (d4 > 0);
}

/* Twice the signed area of the 2-D polygon p[0..n) when it is simple (no two of its edges meet
 * but neighbours at their shared end), else 0. */
static double simple_area(const double (*p)[2], int n)
{
    double area = 0;
    for (int k = 0; k < n; k++)
        area += p[k][0] * p[(k + 1) % n][1] - p[(k + 1) % n][0] * p[k][1];
    for (int i = 0; i < n && area != 0; i++)
        for (int j = i + 2; j < n; j++)
            if ((j + 1) % n != i && segs_meet(p[i], p[(i + 1) % n], p[j], p[(j + 1) % n]))
                return 0;
    return area;
}

/* ---- the hierarchy ---- */

/* The face square across axis of s nodes a side (s >= 2) from node sq, its inside corners
 * diagonal: whether they are joined across it as its nine nodes (corners, mid-edges, centre) join
 * them, 4 neighbours to a node (as the square cut in four draws it); -1 when a quarter is itself
 * ambiguous (then the corners' bilinear decides). Every square of 2 or more nodes a side is drawn
 * so, from both cells that share it, so that a merged cell's face joins its crossings as the same
 * face cut in four does where finer cells lie across. */
static int face_inside_joined(const struct iso_adapt *a, int axis, const int sq[3], int s)
{
    int u = axis == 0 ? 1 : 0, w = axis == 2 ? 1 : 2, h = s / 2;
    bool in[3][3];
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++) {
            int p[3] = {sq[0], sq[1], sq[2]};
            p[u] += i * h, p[w] += j * h;
            in[i][j] = Fp(a, p) > a->iso;
        }
    for (int b = 0; b < 2; b++)
        for (int q = 0; q < 2; q++)
            if (in[q][b] == in[q + 1][b + 1] && in[q + 1][b] == in[q][b + 1] && in[q][b] != in[q + 1][b])
                return -1;
    /* the inside corners, (0, 0) and (2, 2) or (2, 0) and (0, 2): flood the inside nodes from one */
    int c0 = in[0][0] ? 0 : 2, stack[9], top = 0;
    bool seen[3][3] = {{false}};
    seen[c0][0] = true, stack[top++] = c0;
    while (top > 0) {
        int at = stack[--top], i = at % 3, j = at / 3;
        static const int STEP[4][2] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
        for (int k = 0; k < 4; k++) {
            int ni = i + STEP[k][0], nj = j + STEP[k][1];
            if (ni >= 0 && ni < 3 && nj >= 0 && nj < 3 && in[ni][nj] && !seen[ni][nj])
                seen[ni][nj] = true, stack[top++] = ni + 3 * nj;
        }
    }
    return seen[2 - c0][2];
}

#define MAX_EAR 8 /* vertices of an ear: a chord's two ends and the crossings between them */

/* A crossing's fraction t of its finest edge, kept ISO_EDGE_MARGIN off the edge's ends. */
static inline double edge_fraction(double t)
{
    return t < ISO_EDGE_MARGIN ? ISO_EDGE_MARGIN : t > 1 - ISO_EDGE_MARGIN ? 1 - ISO_EDGE_MARGIN : t;
}

/* The place of a sample crossing at fraction t of the finest edge from node n along axis, as
 * place_vertex puts it. */
static inline void crossing_at(const struct iso_adapt *a, const int n[3], int axis, double t, double x[3])
{
    t = edge_fraction(t);
    for (int d = 0; d < 3; d++)
        x[d] = a->org[d] + a->sp[d] * (n[d] + (d == axis ? t : 0));
}

/* The first change of side on the edge of len samples from node n along axis: false when there is
 * none; else n is moved to the finest edge's lower node and v0, v1 get its two values. */
static bool first_change(const struct iso_adapt *a, int n[3], int axis, int len, float *v0, float *v1)
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

/* The place of the crossing of the edge of len samples from node n along axis that crossing()
 * finds there: false when there is none. */
static bool walk_crossing(const struct iso_adapt *a, const int n[3], int axis, int len, double x[3])
{
    int p[3] = {n[0], n[1], n[2]};
    float v0, v1;
    if (!first_change(a, p, axis, len, &v0, &v1))
        return false;
    crossing_at(a, p, axis, ((double)a->iso - v0) / ((double)v1 - v0), x);
    return true;
}

/* Whether face f of the merged cell of s nodes a side at o, drawn cut in four (where a finer cell
 * lies across it), joins its corner-edge crossings as the whole face does (pairs: from -> to,
 * as corner-edge ids i * 8 + j, their places in ep), with no other path on it and no ambiguous
 * quarter; dev[k]: -1 where pair k's path and its chord bound a simple polygon (coarse_fan closes
 * it with triangles in the face), else how far the path strays from the chord (the chord's
 * triangle is then fanned over the path). */
static bool face_cut_ok(const struct iso_adapt *a, const int o[3], int s, int f, const bool (*half)[3][3],
                        const int (*pairs)[2], int n_pairs, double (*ep)[8][3], double dev[2])
{
    int axis = f >> 1, side = f & 1, u = axis == 0 ? 1 : 0, w = axis == 2 ? 1 : 2, h = s / 2;
    /* the 3 x 3 nodes (i along u, j along w), from the cell's nodes half a side apart (half[z][y][x]);
     * edges: e < 6 along u from (e % 2, e / 2), else along w from ((e - 6) / 2, (e - 6) % 2) */
    bool in[3][3];
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++) {
            int c[3];
            c[axis] = 2 * side, c[u] = i, c[w] = j;
            in[i][j] = half[c[2]][c[1]][c[0]];
        }
    if (n_pairs == 0) /* no corner-edge crossing: no path on the face unless a node inside it differs */
        return in[1][0] == in[0][0] && in[0][1] == in[0][0] && in[1][1] == in[0][0] && in[2][1] == in[0][0] &&
               in[1][2] == in[0][0];
    bool centre = in[1][1];
    int inner = (in[1][0] != centre) + (in[0][1] != centre) + (in[2][1] != centre) + (in[1][2] != centre);
    if (n_pairs == 1 && inner <= 1) {
        /* no inner edge cut: the path is one quarter's segment, the chord itself; one: it runs
         * through the two quarters by that edge, a triangle with its chord (simple; its points all
         * on the chord at worst, when the fan over the path is the chord's triangle) */
        dev[0] = -1;
        return true;
    }
    bool cut[12];
    for (int e = 0; e < 12; e++) {
        int i = e < 6 ? e % 2 : (e - 6) / 2, j = e < 6 ? e / 2 : (e - 6) % 2;
        cut[e] = in[i][j] != (e < 6 ? in[i + 1][j] : in[i][j + 1]);
    }
    /* each quarter's segment: its two cut edges (of bottom, top, left, right) */
    int seg[2][2][2];
    for (int b = 0; b < 2; b++)
        for (int q = 0; q < 2; q++) {
            int edges[4] = {q + 2 * b, q + 2 * (b + 1), 6 + b + 2 * q, 6 + b + 2 * (q + 1)}, k = 0;
            seg[q][b][0] = seg[q][b][1] = -1;
            for (int r = 0; r < 4; r++)
                if (cut[edges[r]]) {
                    if (k == 2)
                        return false; /* ambiguous */
                    seg[q][b][k++] = edges[r];
                }
        }
    int visited = 0;
    for (int k = 0; k < n_pairs; k++) {
        double poly[MAX_EAR][2], *A = ep[pairs[k][0] / 8][pairs[k][0] % 8], *B = ep[pairs[k][1] / 8][pairs[k][1] % 8];
        int m = 0, ends[2];
        dev[k] = -1;
        for (int r = 0; r < 2; r++) { /* the cut half of each corner edge */
            int i0 = pairs[k][r] / 8, j0 = pairs[k][r] % 8, along = __builtin_ctz((unsigned)(i0 ^ j0));
            int bu = i0 >> u & 1, bw = i0 >> w & 1;
            int e0 = along == u ? 2 * (2 * bw) : 6 + 2 * (2 * bu), e1 = e0 + 1;
            ends[r] = cut[e0] ? e0 : e1;
        }
        poly[m][0] = A[u], poly[m][1] = A[w], m++;
        double path[MAX_EAR][3];
        int e = ends[0], q = -1, b = -1;
        for (int steps = 0; steps < 8; steps++) {
            /* the quarter e leads into (not the one it came from) */
            int i = e < 6 ? e % 2 : (e - 6) / 2, j = e < 6 ? e / 2 : (e - 6) % 2, nq = -1, nb = -1;
            for (int c = 0; c < 4 && nq < 0; c++) {
                int cq = e < 6 ? i : i - (c & 1), cb = e < 6 ? j - (c & 1) : j;
                if (cq < 0 || cq > 1 || cb < 0 || cb > 1 || (cq == q && cb == b))
                    continue;
                if (seg[cq][cb][0] == e || seg[cq][cb][1] == e)
                    nq = cq, nb = cb;
            }
            if (nq < 0)
                return false;
            q = nq, b = nb;
            e = seg[q][b][0] == e ? seg[q][b][1] : seg[q][b][0];
            bool border = e < 6 ? e / 2 != 1 : (e - 6) / 2 != 1;
            if (border)
                break;
            int ei = e < 6 ? e % 2 : (e - 6) / 2, ej = e < 6 ? e / 2 : (e - 6) % 2, n0[3];
            n0[axis] = o[axis] + side * s, n0[u] = o[u] + ei * h, n0[w] = o[w] + ej * h;
            double x[3];
            if (m + 1 >= MAX_EAR || !walk_crossing(a, n0, e < 6 ? u : w, h, x))
                return false;
            memcpy(path[m], x, sizeof x);
            poly[m][0] = x[u], poly[m][1] = x[w], m++;
            visited++;
        }
        if (e != ends[1])
            return false;
        poly[m][0] = B[u], poly[m][1] = B[w], m++;
        if (m >= 3 && simple_area((const double (*)[2])poly, m) == 0) {
            dev[k] = 0;
            for (int j = 1; j + 1 < m; j++)
                dev[k] = fmax(dev[k], v3_seg_dist(v3(A[0], A[1], A[2]), v3(B[0], B[1], B[2]),
                                                  v3(path[j][0], path[j][1], path[j][2]), NULL));
        }
    }
    return visited == inner;
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
    if (l == 2 && a->mixed[2][block(a, 2, b[0], b[1], b[2])] & HIDES) /* (a coarser block's children said it) */
        return INFINITY;
    /* the block's samples, read once */
    enum { SIDE = (1 << (ISO_MAX_LEVELS - 1)) + 1 };
    double val[SIDE * SIDE * SIDE];
    const int n1 = s + 1, step[3] = {1, n1, n1 * n1};
    for (int z = 0, k = 0; z <= s; z++)
        for (int y = 0; y <= s; y++)
            for (int x = 0; x <= s; x++)
                val[k++] = F(a, o[0] + x, o[1] + y, o[2] + z) - (double)a->iso;
    double c[8], ep[8][8][3]; /* the crossing on the edge between corners i < j, in mm */
    uint64_t ek[8][8];        /* and its vertex's key */
    int at[8];                /* each corner in val */
    bool st[8];
    for (int k = 0; k < 8; k++) {
        at[k] = s * ((k & 1) * step[0] + (k >> 1 & 1) * step[1] + (k >> 2 & 1) * step[2]);
        c[k] = val[at[k]];
        st[k] = c[k] > 0;
    }
    for (int i = 0; i < 8; i++)
        for (int axis = 0; axis < 3; axis++) {
            int j = i | 1 << axis;
            if (j == i)
                continue;
            int changes = 0;
            double prev = c[i];
            for (int t = 1; t <= s; t++) {
                double cur = val[at[i] + t * step[axis]];
                if ((prev > 0) != (cur > 0)) {
                    if (++changes > 1)
                        return INFINITY;
                    int q[3] = {o[0] + (i & 1) * s, o[1] + (i >> 1 & 1) * s, o[2] + (i >> 2 & 1) * s};
                    q[axis] += t - 1;
                    crossing_at(a, q, axis, prev / (prev - cur), ep[i][j]);
                    ek[i][j] = edge_key(a, q, axis);
                }
                prev = cur;
            }
        }
    /* the merged cell's polygon: faces' segments between corner-edge crossings, chained, fanned */
    int next[8][8], tri_n = 0, pairs[6][2][2], n_pairs[6] = {0};
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
            pairs[f][n_pairs[f]][0] = cross[e], pairs[f][n_pairs[f]++][1] = cross[1 - e];
        } else if (n == 4) {
            int r = entry[0] ? 0 : 1, e1 = cross[r], x1 = cross[(r + 1) % 4], e2 = cross[(r + 2) % 4], x2 = cross[(r + 3) % 4];
            double det = g[0] * g[3] - g[1] * g[2];
            int sq[3] = {o[0], o[1], o[2]};
            sq[axis] += (f & 1) * s;
            int nine = face_inside_joined(a, axis, sq, s);
            bool joined = nine >= 0 ? nine : g[0] > 0 ? det > 0 : det < 0;
            next[(joined ? e2 : e1) / 8][(joined ? e2 : e1) % 8] = x1;
            next[(joined ? e1 : e2) / 8][(joined ? e1 : e2) % 8] = x2;
            pairs[f][n_pairs[f]][0] = joined ? e2 : e1, pairs[f][n_pairs[f]++][1] = x1;
            pairs[f][n_pairs[f]][0] = joined ? e1 : e2, pairs[f][n_pairs[f]++][1] = x2;
        }
    }
    for (int i = 0; i < 8; i++)
        for (int j = i + 1; j < 8; j++) {
            if (next[i][j] < 0)
                continue;
            int loop[12], faces[12], n = 0;
            uint64_t keys[12];
            for (int e = i * 8 + j; e >= 0 && n < 12 && (n == 0 || e != i * 8 + j);) {
                int lo = e / 8, axis = __builtin_ctz((unsigned)(e % 8 ^ lo));
                faces[n] = 0;
                for (int d = 0; d < 3; d++)
                    if (d != axis)
                        faces[n] |= 1 << (2 * d + (lo >> d & 1));
                keys[n] = ek[lo][e % 8];
                loop[n++] = e;
                int nx = next[e / 8][e % 8];
                next[e / 8][e % 8] = -1;
                e = nx;
            }
            /* fanned as fan_loops will: from its apex, else from the inner crossing nearest its mean */
            int apex = fan_apex(faces, keys, n);
            double centre[3] = {0, 0, 0};
            if (apex < 0) {
                int cn[3], axis;
                for (int k = 0; k < n; k++)
                    for (int d = 0; d < 3; d++)
                        centre[d] += ep[loop[k] / 8][loop[k] % 8][d] / n;
                if (!inner_crossing(a, o, s, centre, cn, &axis))
                    return INFINITY;
            }
            int from = apex < 0 ? 0 : 1, base = apex < 0 ? 0 : apex;
            for (int k = from; k + from < n && tri_n < 16; k++, tri_n++) {
                int p = (base + k) % n, q = (base + k + 1) % n;
                for (int d = 0; d < 3; d++) {
                    tris[tri_n][0][d] = apex < 0 ? centre[d] : ep[loop[apex] / 8][loop[apex] % 8][d];
                    tris[tri_n][1][d] = ep[loop[p] / 8][loop[p] % 8][d];
                    tris[tri_n][2][d] = ep[loop[q] / 8][loop[q] % 8][d];
                }
            }
        }
    /* every full-resolution vertex of the block (the crossings of its fine edges) against it */
    double worst = 0;
    int last = 0; /* the triangle that settled the last vertex: the next one's is often the same */
    for (int z = 0, k = 0; z <= s; z++)
        for (int y = 0; y <= s; y++)
            for (int x = 0; x <= s; x++, k++) {
                const int r[3] = {x, y, z};
                for (int axis = 0; axis < 3; axis++) {
                    /* (an edge along one of the cell's own holds one of the polygon's vertices, or none) */
                    if (r[axis] == s || (!(r[(axis + 1) % 3] & (s - 1)) && !(r[(axis + 2) % 3] & (s - 1))))
                        continue;
                    double f0 = val[k], f1 = val[k + step[axis]];
                    if ((f0 > 0) == (f1 > 0))
                        continue;
                    double v[3], e = INFINITY;
                    crossing_at(a, (int[3]){o[0] + x, o[1] + y, o[2] + z}, axis, f0 / (f0 - f1), v);
                    /* (a triangle within the worst so far settles this vertex: it cannot raise it) */
                    for (int j = 0; j < tri_n && e > worst; j++) {
                        int t = j == 0 ? last : j == last ? 0 : j;
                        e = fmin(e, trimesh_point_dist(v, tris[t][0], tris[t][1], tris[t][2]));
                        if (e <= worst)
                            last = t;
                    }
                    worst = fmax(worst, e);
                    if (worst > a->max_err)
                        return worst;
                }
            }
    /* the faces as the mesh draws them where finer cells lie across (last: most blocks that fail,
     * fail the distances): a path that strays to the far side of its chord is fanned over in place
     * of the chord's triangle (coarse_fan), which moves that triangle's points by at most the
     * path's stray */
    double stray = 0;
    bool half[3][3][3]; /* the cell's nodes half a side apart: in or not */
    for (int z = 0; z < 3; z++)
        for (int y = 0; y < 3; y++)
            for (int x = 0; x < 3; x++)
                half[z][y][x] = val[(x * step[0] + y * step[1] + z * step[2]) * s / 2] > 0;
    for (int f = 0; f < 6; f++) {
        double dev[2];
        if (!face_cut_ok(a, o, s, f, (const bool (*)[3][3])half, (const int (*)[2])pairs[f], n_pairs[f], ep, dev))
            return INFINITY;
        for (int k = 0; k < n_pairs[f]; k++)
            stray = fmax(stray, dev[k]);
    }
    return worst + stray;
}

/* Whether every block of level l that shares a face with block b of level l+1 is covered at l,
 * so that cells that share a face differ by one level at most (a face drawn by the coarser cell
 * at the finer one's resolution is cut in four). Cells that share only an edge or a corner may
 * differ by more: an edge's crossing is keyed by the finest edge it lies on, one vertex whatever
 * the levels that read it (the CT head at levels=3: 3.69x -> 3.76x fewer triangles than with
 * every touching block required). */
static bool ring_covered(const struct iso_adapt *a, int l, const int b[3])
{
    for (int z = 2 * b[2] - 1; z <= 2 * b[2] + 2; z++)
        for (int y = 2 * b[1] - 1; y <= 2 * b[1] + 2; y++)
            for (int x = 2 * b[0] - 1; x <= 2 * b[0] + 2; x++) {
                if (x < 0 || y < 0 || z < 0 || x >= a->nb[l][0] || y >= a->nb[l][1] || z >= a->nb[l][2])
                    continue;
                int out = (x < 2 * b[0] || x > 2 * b[0] + 1) + (y < 2 * b[1] || y > 2 * b[1] + 1) +
                          (z < 2 * b[2] || z > 2 * b[2] + 1);
                if (out >= 2) /* (across an edge or a corner) */
                    continue;
                if (!a->M[l][block(a, l, x, y, z)])
                    return false;
            }
    return true;
}

/* Level-2 block b's 27 samples (fewer where the grid ends): whether they lie on both sides of iso. */
static bool samples_mixed(const struct iso_adapt *a, const int b[3])
{
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
    return in && out;
}

/* Block b of level l: mixed, merged or not (level l-1 done, M[l] at b clear): the error its merge
 * accepted, or -1 when it does not merge. split: at level 2, whether its samples lie on both sides
 * of iso (samples_mixed, or as mask_slab found it). */
static double mask_block(struct iso_adapt *a, int l, const int b[3], bool split)
{
    int s = 1 << (l - 1);
    bool inside = true, ok = true, mixed = false, hides = false;
    for (int d = 0; d < 3; d++)
        inside = inside && (b[d] + 1) * s <= a->N[d] - 1;
    if (l > 2) { /* its children merged, and every block of l-1 round it */
        for (int k = 0; k < 8 && ok && inside; k++)
            ok = a->M[l - 1][block(a, l - 1, 2 * b[0] + (k & 1), 2 * b[1] + (k >> 1 & 1), 2 * b[2] + (k >> 2 & 1))];
        ok = ok && inside && ring_covered(a, l - 1, b);
    }
    if (l == 2) {
        mixed = !inside || split; /* a block the grid's end cuts: level-1 cells */
        if (hides_crossings(a, (int[3]){2 * b[0], 2 * b[1], 2 * b[2]}, 2))
            mixed = true, hides = true;
    } else { /* any child's */
        for (int k = 0; k < 8 && !mixed; k++) {
            int c[3] = {2 * b[0] + (k & 1), 2 * b[1] + (k >> 1 & 1), 2 * b[2] + (k >> 2 & 1)};
            if (c[0] < a->nb[l - 1][0] && c[1] < a->nb[l - 1][1] && c[2] < a->nb[l - 1][2])
                mixed = a->mixed[l - 1][block(a, l - 1, c[0], c[1], c[2])];
        }
    }
    size_t at = block(a, l, b[0], b[1], b[2]);
    a->mixed[l][at] = (uint8_t)(mixed | hides << 1);
    double e = ok && inside ? block_error(a, l, b, mixed) : INFINITY;
    if (!(e <= a->max_err))
        return -1;
    a->M[l][at] = 1;
    if (a->berr[l])
        a->berr[l][at] = e;
    return e;
}

/* Which samples of a row are in, into the columns' any and all: sixteen at a time (a loop of a
 * fixed count, which -O2 vectorises), then the rest. */
static void columns_in(const float *restrict row, int n, float iso, uint8_t *restrict any, uint8_t *restrict all)
{
    int x = 0;
    for (; x + 16 <= n; x += 16)
        for (int k = 0; k < 16; k++) {
            uint8_t v = row[x + k] > iso;
            any[x + k] |= v, all[x + k] &= v;
        }
    for (; x < n; x++) {
        uint8_t v = row[x] > iso;
        any[x] |= v, all[x] &= v;
    }
}

/* Blocks of level l in layers [z0, z1) of slab s. At level 2 a row of blocks reads its nine rows
 * of samples a column at a time (whether any sample of a column is in, whether all are), which
 * the compiler does many columns at once: most blocks hold no surface, and their 27 samples one
 * by one were a sixth of an extraction. */
static void mask_slab(struct iso_adapt *a, int l, int z0, int z1, int slab)
{
    int b[3], n0 = a->N[0];
    uint8_t *any = l == 2 ? malloc(2 * (size_t)n0) : NULL, *all = any ? any + n0 : NULL;
    for (b[2] = z0; b[2] < z1; b[2]++)
        for (b[1] = 0; b[1] < a->nb[l][1]; b[1]++) {
            if (any) {
                memset(any, 0, (size_t)n0);
                memset(all, 1, (size_t)n0);
                for (int z = 2 * b[2]; z <= 2 * b[2] + 2 && z < a->N[2]; z++)
                    for (int y = 2 * b[1]; y <= 2 * b[1] + 2 && y < a->N[1]; y++) {
                        columns_in(a->F + at3(a, 0, y, z), n0, a->iso, any, all);
                    }
            }
            for (b[0] = 0; b[0] < a->nb[l][0]; b[0]++) {
                bool split = false;
                if (l == 2 && any) {
                    uint8_t in = 0, full = 1;
                    for (int x = 2 * b[0]; x <= 2 * b[0] + 2 && x < n0; x++)
                        in |= any[x], full &= all[x];
                    split = in && !full;
                } else if (l == 2) { /* (no memory for the columns) */
                    split = samples_mixed(a, b);
                }
                a->slab_max[slab] = fmax(a->slab_max[slab], mask_block(a, l, b, split));
            }
        }
    free(any);
}

/* Level-2 block b's cell level, once every level's blocks are known. */
static void cell_level(struct iso_adapt *a, const int b[3])
{
    int lev = 1;
    for (int l = a->L; l >= 2 && lev == 1; l--)
        if (a->M[l][block(a, l, b[0] >> (l - 2), b[1] >> (l - 2), b[2] >> (l - 2))])
            lev = l;
    a->lev2[block(a, 2, b[0], b[1], b[2])] = (uint8_t)lev;
}

static void cell_levels(struct iso_adapt *a)
{
    int b[3];
    for (b[2] = 0; b[2] < a->nb[2][2]; b[2]++)
        for (b[1] = 0; b[1] < a->nb[2][1]; b[1]++)
            for (b[0] = 0; b[0] < a->nb[2][0]; b[0]++)
                cell_level(a, b);
}

/* ---- the mesh ---- */

static uint64_t hash64(uint64_t k)
{
    k ^= k >> 33, k *= 0xff51afd7ed558ccdull, k ^= k >> 33, k *= 0xc4ceb9fe1a85ec53ull, k ^= k >> 33;
    return k;
}

/* Vertex v of pc at pos, its normal nrm made unit. */
static void set_vertex(struct piece *pc, size_t v, const double pos[3], const double nrm[3])
{
    double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    for (int d = 0; d < 3; d++) {
        pc->m.pos[3 * v + d] = (float)pos[d];
        pc->m.nrm[3 * v + d] = len > 0 ? (float)(nrm[d] / len) : 0.0f;
    }
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
    set_vertex(pc, v, pos, nrm);
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

#define UNKNOWN (-2)
/* pc's vertex keyed key: its id, or UNKNOWN with *slot where it will go (-1: no memory). */
static long known_vertex(struct piece *pc, uint64_t key, size_t *slot)
{
    bool found;
    if (!slot_of(pc, key, &found, slot))
        return -1;
    return found ? (long)pc->slot[*slot] : UNKNOWN;
}

/* A new vertex of pc keyed key (its slot from known_vertex). */
static long keyed_vertex(struct piece *pc, uint64_t key, size_t slot, const double pos[3], const double nrm[3])
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
static long edge_vertex(const struct iso_adapt *a, struct piece *pc, const int n[3], int axis, float v0, float v1)
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
#define HIDDEN_KEY(k) (1ull << (60 + (k))) /* the first (k = 0, nearer node n) and second crossing */

static bool hidden_pair(const struct iso_adapt *a, const int n[3], int axis, double t[2])
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
static long hidden_vertex(const struct iso_adapt *a, struct piece *pc, const int n[3], int axis, int k, double t)
{
    uint64_t key = edge_key(a, n, axis) | HIDDEN_KEY(k);
    size_t h;
    long v = known_vertex(pc, key, &h);
    return v != UNKNOWN ? v : place_vertex(a, pc, n, axis, t, true, key, h);
}

/* Whether any of the cell of s nodes a side at o's finest edges carries a hidden pair (only
 * when there is a field). */
static bool hides_crossings(const struct iso_adapt *a, const int o[3], int s)
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

static void add_triangle(struct piece *pc, long p, long q, long r)
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

#define MAX_SEGS 96

struct cell {
    const struct iso_adapt *a;
    bool hides;              /* a level-1 cell in a block with hidden crossings (HIDES) */
    struct piece *pc;        /* where its triangles go */
    int o[3], s;
    int n;                   /* segments */
    long from[MAX_SEGS], to[MAX_SEGS];
    int faces[MAX_SEGS];     /* of from[]: the cell faces its edge lies on (bits) */
};

/* The faces of cell c that the edge from node lo along axis lies on (bits). */
static int cell_edge_faces(const struct cell *c, const int lo[3], int axis)
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
static long crossing(const struct iso_adapt *a, const struct cell *c, const int p[3], const int q[3], int *faces)
{
    int axis = p[0] != q[0] ? 0 : p[1] != q[1] ? 1 : 2;
    const int *lo = p[axis] < q[axis] ? p : q;
    int n[3] = {lo[0], lo[1], lo[2]};
    float v0, v1;
    *faces = cell_edge_faces(c, lo, axis);
    return first_change(a, n, axis, abs(q[axis] - p[axis]), &v0, &v1) ? edge_vertex(a, c->pc, n, axis, v0, v1) : -1;
}

static void add_seg(struct cell *c, long from, int from_faces, long to)
{
    if (c->n < MAX_SEGS) {
        c->from[c->n] = from, c->to[c->n] = to, c->faces[c->n] = from_faces;
        c->n++;
    }
}

/* ---- feature points (seed 002's second method) ---- */

#define FEATURE_COS 0.9   /* normals further apart than this (26 degrees) make a feature */
#define CORNER_COS 0.7    /* a third normal this far out of the other two's plane makes a corner */
#define FACE_POINT (1 << 6) /* in a segment's faces: its start is a face point */
#define ON_FACE (1 << 7)    /* its start is an isoline point of a face (isoline_point) */
#define FACE_KEY (1ull << 62)

static double dot3(const double u[3], const double v[3]) { return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]; }

static void vertex_of(const struct piece *pc, long v, double pos[3], double nrm[3])
{
    for (int d = 0; d < 3; d++)
        pos[d] = pc->m.pos[3 * v + d], nrm[d] = pc->m.nrm[3 * v + d];
}

/* The feature point of segment A -> B of the face square with lowest node sq, h nodes a side,
 * across axis: where the isoline's tangents at A and B (their tangent planes cut by the face's
 * plane) meet, when the normals are more than the feature angle apart and the point lies in the
 * square. Both cells that share the square find it from the same crossings:
 * one vertex, keyed by the square, the segment (j: its number in the square, 0..7) and which part
 * of it (sub: 0 the whole, 2 and 3 its halves round an isoline point). -1 for none. */
/* The field minus iso at x + t dir. */
static double at_line(const struct iso_adapt *a, const double x[3], const double dir[3], double t)
{
    double p[3] = {x[0] + t * dir[0], x[1] + t * dir[1], x[2] + t * dir[2]};
    return a->field(a->field_ctx, p, NULL) - a->iso;
}

/* Whether point q of the face plane across axis lies in the square of h nodes a side from node
 * sq, ISO_EDGE_MARGIN of it in from its sides. */
static bool in_square(const struct iso_adapt *a, int axis, const int sq[3], int h, const double q[3])
{
    for (int d = 0; d < 3; d++) {
        double lo = a->org[d] + a->sp[d] * sq[d], m = ISO_EDGE_MARGIN * h * a->sp[d];
        if (d != axis && !(q[d] > lo + m && q[d] < lo + h * a->sp[d] - m))
            return false;
    }
    return true;
}

static uint64_t face_key(const struct iso_adapt *a, int axis, const int sq[3], int h, int j, int sub)
{
    return FACE_KEY | (((((uint64_t)at3(a, sq[0], sq[1], sq[2]) * 3 + (uint64_t)axis) * 4 +
                         (uint64_t)__builtin_ctz((unsigned)h)) * 8 + (uint64_t)j) * 4 + (uint64_t)sub);
}

/* The vertex of pc keyed key at q with normal nrm: found or made (-1: no memory). */
static long face_vertex(struct piece *pc, uint64_t key, const double q[3], const double nrm[3])
{
    size_t slot;
    long v = known_vertex(pc, key, &slot);
    return v != UNKNOWN ? v : keyed_vertex(pc, key, slot, q, nrm);
}

static long face_point(const struct iso_adapt *a, struct piece *pc, long A, long B, int axis, const int sq[3], int h,
                       int j, int sub)
{
    if (A < 0 || B < 0)
        return -1;
    double pa[3], na[3], pb[3], nb[3];
    vertex_of(pc, A, pa, na);
    vertex_of(pc, B, pb, nb);
    if (dot3(na, nb) > FEATURE_COS)
        return -1;
    int u = axis == 0 ? 1 : 0, w = axis == 2 ? 1 : 2;
    double det = na[u] * nb[w] - na[w] * nb[u];
    double la = hypot(na[u], na[w]), lb = hypot(nb[u], nb[w]);
    if (!(fabs(det) > 0.1 * la * lb)) /* tangents (nearly) parallel in the face */
        return -1;
    double ca = na[u] * pa[u] + na[w] * pa[w], cb = nb[u] * pb[u] + nb[w] * pb[w], q[3];
    q[axis] = pa[axis];
    q[u] = (ca * nb[w] - cb * na[w]) / det;
    q[w] = (na[u] * cb - nb[u] * ca) / det;
    if (!in_square(a, axis, sq, h, q))
        return -1;
    double mu = ISO_EDGE_MARGIN * h * a->sp[u], mw = ISO_EDGE_MARGIN * h * a->sp[w];
    double eu = pb[u] - pa[u], ew = pb[w] - pa[w], el = hypot(eu, ew);
    if (!(fabs((q[u] - pa[u]) * ew - (q[w] - pa[w]) * eu) > el * hypot(mu, mw))) /* (all but on the segment) */
        return -1;
    double nrm[3] = {na[0] + nb[0], na[1] + nb[1], na[2] + nb[2]};
    return face_vertex(pc, face_key(a, axis, sq, h, j, sub), q, nrm);
}

/* With the field at hand: where the face's isoline crosses the perpendicular bisector of segment
 * A -> B, when that is further than a tenth of a cell from the segment (a curved feature that
 * grazes the face dips into it between two crossings of one surface, and neither crossing's
 * tangent shows it; between a hidden pair the isoline can round a corner's third face). A vertex
 * of both cells that share the square, on the field, its normal the field's; -1 for none. */
static long isoline_point(const struct iso_adapt *a, struct piece *pc, long A, long B, int axis, const int sq[3],
                          int h, int j)
{
    if (A < 0 || B < 0)
        return -1;
    if (pc->vkey[B] < pc->vkey[A]) { /* the same search from both cells */
        long t = A;
        A = B, B = t;
    }
    double pa[3], pb[3], n[3], m[3], d[3] = {0, 0, 0}, step = h * fmin(a->sp[0], fmin(a->sp[1], a->sp[2]));
    vertex_of(pc, A, pa, n);
    vertex_of(pc, B, pb, n);
    int u = axis == 0 ? 1 : 0, w = axis == 2 ? 1 : 2;
    for (int k = 0; k < 3; k++)
        m[k] = 0.5 * (pa[k] + pb[k]);
    d[u] = pb[w] - pa[w], d[w] = pa[u] - pb[u];
    double len = hypot(d[u], d[w]);
    if (!(len > 0))
        return -1;
    d[u] /= len, d[w] /= len;
    /* a hidden pair (both ends on one edge of the square): the isoline between them bulges into
     * the square, however near the edge the function is at the middle */
    bool pair = (pc->vkey[A] & ~(HIDDEN_KEY(0) | HIDDEN_KEY(1))) == (pc->vkey[B] & ~(HIDDEN_KEY(0) | HIDDEN_KEY(1)));
    double cu = a->org[u] + a->sp[u] * (sq[u] + 0.5 * h) - m[u], cw = a->org[w] + a->sp[w] * (sq[w] + 0.5 * h) - m[w];
    if (pair && cu * d[u] + cw * d[w] < 0)
        d[u] = -d[u], d[w] = -d[w]; /* into the square */
    double g[3], f0 = a->field(a->field_ctx, m, g) - a->iso, t1 = 0, f1 = f0;
    if (!pair && !(fabs(f0) > 0.1 * step * sqrt(dot3(g, g)))) /* the isoline is nearer the middle than that */
        return -1;
    for (int k = 1; k <= 4 && (f1 > 0) == (f0 > 0); k++) /* out from the middle, both ways (a pair's: in) */
        for (int sgn = pair ? 1 : -1; sgn <= 1 && (f1 > 0) == (f0 > 0); sgn += 2)
            t1 = sgn * step * k / 4, f1 = at_line(a, m, d, t1);
    if ((f1 > 0) == (f0 > 0))
        return -1;
    double lo = fmin(0, t1), hi = fmax(0, t1), flo = t1 > 0 ? f0 : f1;
    for (int it = 0; it < 30; it++) { /* bisection: the root nearest the middle */
        double tm = 0.5 * (lo + hi), fm = at_line(a, m, d, tm);
        if ((fm > 0) == (flo > 0))
            lo = tm, flo = fm;
        else
            hi = tm;
    }
    double t = 0.5 * (lo + hi), q[3];
    if (pair) /* however near the edge: each square round it its own vertex, else two squares that
               * share the edge would draw one chord between the pair, an edge of four triangles */
        t = fmax(t, 2 * ISO_EDGE_MARGIN * step);
    else if (fabs(t) < 0.1 * step)
        return -1;
    for (int k = 0; k < 3; k++)
        q[k] = m[k] + t * d[k];
    if (!in_square(a, axis, sq, h, q))
        return -1;
    a->field(a->field_ctx, q, g);
    for (int k = 0; k < 3; k++)
        g[k] = -g[k];
    return face_vertex(pc, face_key(a, axis, sq, h, j, 1), q, g);
}

/* Segment from -> to on face f, through q when it is a vertex (a face point). */
static void seg_via(struct cell *c, int f, long from, int from_faces, long q, long to)
{
    if (q < 0) {
        add_seg(c, from, from_faces, to);
        return;
    }
    add_seg(c, from, from_faces, q);
    add_seg(c, q, 1 << f | FACE_POINT, to);
}

/* Segment from -> to of face f's square sq (h a side, j its number in the square), with features
 * kept: through its feature point when it has one, else (with the field) through the isoline's
 * point between them when the isoline strays from the segment, and the feature points of the two
 * halves. */
static void add_face_seg(struct cell *c, int f, const int sq[3], int h, int j, long from, int from_faces, long to)
{
    const struct iso_adapt *a = c->a;
    int axis = f >> 1;
    long q = a->sharp ? face_point(a, c->pc, from, to, axis, sq, h, j, 0) : -1, r = -1;
    if (q >= 0 || !a->sharp || !a->field || (r = isoline_point(a, c->pc, from, to, axis, sq, h, j)) < 0) {
        seg_via(c, f, from, from_faces, q, to);
        return;
    }
    int first = c->pc->vkey[from] < c->pc->vkey[to]; /* the halves' numbers: 2 for the one by the lesser key */
    seg_via(c, f, from, from_faces, face_point(a, c->pc, from, r, axis, sq, h, j, first ? 2 : 3), r);
    seg_via(c, f, r, 1 << f | ON_FACE, face_point(a, c->pc, r, to, axis, sq, h, j, first ? 3 : 2), to);
}

/* The planes of a loop's crossings, grouped round n seed normals (each crossing to the seed
 * nearest its normal): each group's mean normal, through its crossings' mean position. */
static void group_planes(const struct piece *pc, const long *v, int k, const int *seed, int n, double nrm[3][3],
                         double off[3])
{
    double sn[3][3], sum[3][3] = {{0}}, at[3][3] = {{0}};
    int cnt[3] = {0};
    for (int g = 0; g < n; g++) {
        double p[3];
        vertex_of(pc, v[seed[g]], p, sn[g]);
    }
    for (int i = 0; i < k; i++) {
        double p[3], m[3];
        vertex_of(pc, v[i], p, m);
        int best = 0;
        for (int g = 1; g < n; g++)
            if (dot3(m, sn[g]) > dot3(m, sn[best]))
                best = g;
        for (int d = 0; d < 3; d++)
            sum[best][d] += m[d], at[best][d] += p[d];
        cnt[best]++;
    }
    for (int g = 0; g < n; g++) { /* (each seed is in its own group: cnt > 0) */
        double len = sqrt(dot3(sum[g], sum[g]));
        for (int d = 0; d < 3; d++)
            nrm[g][d] = len > 0 ? sum[g][d] / len : sn[g][d], at[g][d] /= cnt[g] ? cnt[g] : 1;
        off[g] = dot3(nrm[g], at[g]);
    }
}

/* The cell's box, a margin of ISO_EDGE_MARGIN round it. */
static void cell_box(const struct iso_adapt *a, const struct cell *c, double lo[3], double hi[3])
{
    for (int d = 0; d < 3; d++) {
        double m = ISO_EDGE_MARGIN * c->s * a->sp[d];
        lo[d] = a->org[d] + a->sp[d] * c->o[d] - m;
        hi[d] = a->org[d] + a->sp[d] * (c->o[d] + c->s) + m;
    }
}

static bool in_cell(const struct iso_adapt *a, const struct cell *c, const double x[3])
{
    double lo[3], hi[3];
    cell_box(a, c, lo, hi);
    for (int d = 0; d < 3; d++)
        if (!(x[d] > lo[d] && x[d] < hi[d]))
            return false;
    return true;
}

/* Whether x lies past one face of level-1 cell c, in the cell across it, and that cell holds no
 * surface (its samples on one side, no hidden crossings): a corner whose tip pokes through the
 * face between samples, which only c's loop can carry. */
static bool in_empty_neighbour(const struct iso_adapt *a, const struct cell *c, const double x[3])
{
    if (c->s != 1)
        return false;
    int o[3] = {c->o[0], c->o[1], c->o[2]}, out = 0;
    for (int d = 0; d < 3; d++) {
        double g = (x[d] - a->org[d]) / a->sp[d] - c->o[d];
        if (g < 0 || g > 1)
            out++, o[d] += g < 0 ? -1 : 1;
        if (g < -1 || g > 2)
            return false;
    }
    if (out != 1)
        return false;
    for (int d = 0; d < 3; d++)
        if (o[d] < 0 || o[d] + 1 >= a->N[d])
            return false;
    int in = 0;
    for (int k = 0; k < 8; k++) {
        int p[3] = {o[0] + (k & 1), o[1] + (k >> 1 & 1), o[2] + (k >> 2 & 1)};
        in += Fp(a, p) > a->iso;
    }
    return (in == 0 || in == 8) && !hides_crossings(a, o, 1);
}

/* The stretch [*t0, *t1] of the line x + t dir in the cell's box: false when it misses it. */
static bool line_in_cell(const struct iso_adapt *a, const struct cell *c, const double x[3], const double dir[3],
                         double *t0, double *t1)
{
    double lo[3], hi[3];
    cell_box(a, c, lo, hi);
    *t0 = -INFINITY, *t1 = INFINITY;
    for (int d = 0; d < 3; d++) {
        if (fabs(dir[d]) < 1e-12) {
            if (!(x[d] > lo[d] && x[d] < hi[d]))
                return false;
            continue;
        }
        double ta = (lo[d] - x[d]) / dir[d], tb = (hi[d] - x[d]) / dir[d];
        *t0 = fmax(*t0, fmin(ta, tb)), *t1 = fmin(*t1, fmax(ta, tb));
    }
    return *t0 < *t1;
}

/* Moves x along dir to the nearest point of the line x + t dir inside the cell: false when the
 * line misses it. */
static bool clip_to_cell(const struct iso_adapt *a, const struct cell *c, double x[3], const double dir[3])
{
    double t0, t1;
    if (!line_in_cell(a, c, x, dir, &t0, &t1))
        return false;
    double t = 0 < t0 ? t0 + 1e-3 * (t1 - t0) : 0 > t1 ? t1 - 1e-3 * (t1 - t0) : 0;
    for (int d = 0; d < 3; d++)
        x[d] += t * dir[d];
    return true;
}

/* With the field at hand: where the edge through x along dir ends in the cell (a corner whose
 * third face crosses none of the cell's edges, so that no crossing gave its plane), x is moved
 * there. The field is zero along the edge and leaves zero past its end: the line is sampled
 * across the cell, and where it is on the edge at one sample and off it at the next, the end is
 * found between them by bisection. */
static void edge_end(const struct iso_adapt *a, const struct cell *c, double x[3], const double dir[3])
{
    double t0, t1, tol = 1e-3 * c->s * fmin(a->sp[0], fmin(a->sp[1], a->sp[2]));
    if (!line_in_cell(a, c, x, dir, &t0, &t1))
        return;
#define ON_EDGE(t) (fabs(at_line(a, x, dir, t)) <= tol)
    enum { K = 8 };
    bool on[K + 1];
    int changes = 0, where = -1;
    for (int k = 0; k <= K; k++) {
        on[k] = ON_EDGE(t0 + (t1 - t0) * k / K);
        if (k && on[k] != on[k - 1])
            changes++, where = k - 1;
    }
    if (changes != 1)
        return;
    double ta = t0 + (t1 - t0) * where / K, tb = t0 + (t1 - t0) * (where + 1) / K; /* on[where] at ta */
    for (int it = 0; it < 30; it++) {
        double tm = 0.5 * (ta + tb);
        if (ON_EDGE(tm) == on[where])
            ta = tm;
        else
            tb = tm;
    }
#undef ON_EDGE
    double t = on[where] ? ta : tb;
    for (int d = 0; d < 3; d++)
        x[d] += t * dir[d];
}

/* The point of the line where planes (n0, d0) and (n1, d1) meet that lies in the cell nearest
 * centre (moved along the line into the cell when the nearest is outside it: the line may cross
 * the cell near a corner of it), and with the field at hand moved to where the edge ends in the
 * cell (edge_end). false when the planes are parallel or the line misses the cell. */
static bool edge_point(const struct iso_adapt *a, const struct cell *c, const double n0[3], double d0, const double n1[3],
                       double d1, const double centre[3], double x[3])
{
    double g = dot3(n0, n1), det = 1 - g * g;
    if (det < 1e-6)
        return false;
    double r0 = d0 - dot3(n0, centre), r1 = d1 - dot3(n1, centre);
    double al = (r0 - g * r1) / det, be = (r1 - g * r0) / det;
    double dir[3] = {n0[1] * n1[2] - n0[2] * n1[1], n0[2] * n1[0] - n0[0] * n1[2], n0[0] * n1[1] - n0[1] * n1[0]};
    for (int d = 0; d < 3; d++)
        x[d] = centre[d] + al * n0[d] + be * n1[d];
    if (!clip_to_cell(a, c, x, dir))
        return false;
    if (a->field)
        edge_end(a, c, x, dir);
    return true;
}

/* Seed 002's interior feature point of a loop: where the tangent planes at its crossings meet,
 * without SVD. The two most different normals seed two groups of planes (an edge), a third far
 * out of their plane a third group (a corner); each group is one plane (group_planes). A corner
 * is where its three planes meet (in the cell, or in an empty one next to it: in_empty_neighbour);
 * an edge a point of its two planes' line (edge_point). A corner elsewhere falls back to the one
 * of its three edges that passes nearest the loop's face points.
 * false when the loop has none. */
static bool feature_point(const struct iso_adapt *a, const struct cell *c, const long *loop, const int *faces, int n,
                          double x[3], double nrm[3])
{
    const struct piece *pc = c->pc;
    long v[MAX_SEGS];
    int k = 0;
    double centre[3] = {0, 0, 0};
    for (int d = 0; d < 3; d++)
        nrm[d] = 0;
    for (int i = 0; i < n; i++)
        if (loop[i] < 0) /* (no memory) */
            return false;
    for (int i = 0; i < n; i++) {
        double p[3], m[3];
        vertex_of(pc, loop[i], p, m);
        for (int d = 0; d < 3; d++)
            centre[d] += p[d] / n;
        if (!(faces[i] & FACE_POINT) && dot3(m, m) > 0.5) {
            v[k++] = loop[i];
            for (int d = 0; d < 3; d++)
                nrm[d] += m[d];
        }
    }
    int seed[3] = {-1, -1, -1};
    double least = FEATURE_COS;
    for (int i = 0; i < k; i++)
        for (int j = i + 1; j < k; j++) {
            double p[3], mi[3], mj[3];
            vertex_of(pc, v[i], p, mi);
            vertex_of(pc, v[j], p, mj);
            if (dot3(mi, mj) < least)
                least = dot3(mi, mj), seed[0] = i, seed[1] = j;
        }
    if (seed[0] < 0)
        return false;
    double pl[3][3], off[3], p[3], m0[3], m1[3], e[3];
    vertex_of(pc, v[seed[0]], p, m0);
    vertex_of(pc, v[seed[1]], p, m1);
    e[0] = m0[1] * m1[2] - m0[2] * m1[1], e[1] = m0[2] * m1[0] - m0[0] * m1[2], e[2] = m0[0] * m1[1] - m0[1] * m1[0];
    double el = sqrt(dot3(e, e)), most = CORNER_COS;
    for (int i = 0; i < k; i++) {
        double m[3];
        vertex_of(pc, v[i], p, m);
        if (fabs(dot3(m, e)) / el > most)
            most = fabs(dot3(m, e)) / el, seed[2] = i;
    }
    if (seed[2] >= 0) { /* a corner: three planes, by Cramer's rule */
        group_planes(pc, v, k, seed, 3, pl, off);
        double c0[3], c1[3], c2[3]; /* the rows' cross products */
        c0[0] = pl[1][1] * pl[2][2] - pl[1][2] * pl[2][1], c0[1] = pl[1][2] * pl[2][0] - pl[1][0] * pl[2][2],
        c0[2] = pl[1][0] * pl[2][1] - pl[1][1] * pl[2][0];
        c1[0] = pl[2][1] * pl[0][2] - pl[2][2] * pl[0][1], c1[1] = pl[2][2] * pl[0][0] - pl[2][0] * pl[0][2],
        c1[2] = pl[2][0] * pl[0][1] - pl[2][1] * pl[0][0];
        c2[0] = pl[0][1] * pl[1][2] - pl[0][2] * pl[1][1], c2[1] = pl[0][2] * pl[1][0] - pl[0][0] * pl[1][2],
        c2[2] = pl[0][0] * pl[1][1] - pl[0][1] * pl[1][0];
        double det = dot3(pl[0], c0);
        if (fabs(det) > 1e-3) {
            for (int d = 0; d < 3; d++)
                x[d] = (off[0] * c0[d] + off[1] * c1[d] + off[2] * c2[d]) / det;
            if (in_cell(a, c, x) || in_empty_neighbour(a, c, x))
                return true;
            double lo[3], hi[3], far = 0; /* just outside: its edges run through the cell, from near it */
            cell_box(a, c, lo, hi);
            for (int d = 0; d < 3; d++)
                far = fmax(far, fmax(lo[d] - x[d], x[d] - hi[d]) / (c->s * a->sp[d]));
            if (far < 0.5) {
                for (int d = 0; d < 3; d++) {
                    double m = 2 * ISO_EDGE_MARGIN * c->s * a->sp[d];
                    x[d] = fmin(fmax(x[d], lo[d] + m), hi[d] - m);
                }
                return true;
            }
        }
    }
    int pairs = 1, pick = -1;
    if (seed[2] < 0)
        group_planes(pc, v, k, seed, 2, pl, off);
    else /* the corner lies outside the cell: one of its three edges runs through it */
        pairs = 3;
    double best = INFINITY, bx[3];
    for (int q = 0; q < pairs; q++) {
        int i = q == 2 ? 1 : 0, j = q == 0 ? 1 : 2;
        double y[3], miss = 0;
        if (!edge_point(a, c, pl[i], off[i], pl[j], off[j], centre, y))
            continue;
        for (int r = 0; r < n; r++) /* the face points lie on the edge: the one nearest them */
            if (faces[r] & FACE_POINT) {
                double fp[3], m[3], w[3];
                vertex_of(pc, loop[r], fp, m);
                for (int d = 0; d < 3; d++)
                    w[d] = fp[d] - y[d];
                miss += sqrt(dot3(w, w));
            }
        if (miss < best)
            best = miss, pick = q, memcpy(bx, y, sizeof bx);
    }
    if (pick < 0)
        return false;
    memcpy(x, bx, sizeof bx);
    return true;
}

/* Whether the field is inside at the mean of a face's four crossings: with the field at hand,
 * whether the face's two stretches of inside border are joined across it, in place of the
 * asymptotic decider's reading of the samples' bilinear interpolant (the same answer from both
 * cells that share the face: it does not depend on the order of the crossings). */
static bool inside_between(const struct iso_adapt *a, const struct piece *pc, const long cross[4])
{
    double m[3] = {0, 0, 0};
    for (int q = 0; q < 4; q++) {
        if (cross[q] < 0)
            return false;
        for (int d = 0; d < 3; d++)
            m[d] += pc->m.pos[3 * cross[q] + d] / 4;
    }
    return a->field(a->field_ctx, m, NULL) > a->iso;
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
            long cross[8];
            int faces[8], entry[8], n = 0, sq[3] = {p[0][0], p[0][1], p[0][2]}; /* corner 0: the lowest */
            for (int q = 0; q < 4; q++) {
                const int *pa = p[q], *pb = p[(q + 1) % 4];
                bool sa = v[q] > a->iso, sb = v[(q + 1) % 4] > a->iso;
                int ea = pa[0] != pb[0] ? 0 : pa[1] != pb[1] ? 1 : 2;
                double t[2];
                if (sa != sb) {
                    cross[n] = crossing(a, c, pa, pb, &faces[n]);
                    entry[n++] = sb;
                } else if (c->hides && hidden_pair(a, pa[ea] < pb[ea] ? pa : pb, ea, t)) { /* in, out: walked in order */
                    const int *lo = pa[ea] < pb[ea] ? pa : pb;
                    for (int r = 0; r < 2; r++) {
                        int which = lo == pa ? r : 1 - r;
                        cross[n] = hidden_vertex(a, c->pc, lo, ea, which, t[which]);
                        faces[n] = cell_edge_faces(c, lo, ea);
                        entry[n++] = r ? sa : !sa;
                    }
                }
            }
            /* each segment's number in the square (a face point's key): how many of its crossings'
             * keys are less than the least of the segment's */
            long rank[8];
            for (int q = 0; q < n; q++) {
                rank[q] = 0;
                for (int r = 0; r < n; r++)
                    rank[q] += cross[q] >= 0 && cross[r] >= 0 && c->pc->vkey[cross[r]] < c->pc->vkey[cross[q]];
            }
#define SEG(e, x) add_face_seg(c, f, sq, h, (int)(rank[e] < rank[x] ? rank[e] : rank[x]), cross[e], faces[e], cross[x])
            if (n == 4) {
                int r = entry[0] ? 0 : 1;
                int e1 = r, x1 = (r + 1) % 4, e2 = (r + 2) % 4, x2 = (r + 3) % 4;
                double det = g[0] * g[3] - g[1] * g[2];
                int nine = !a->field && h >= 2 ? face_inside_joined(a, axis, sq, h) : -1;
                if (a->field ? inside_between(a, c->pc, cross) : nine >= 0 ? nine : g[0] > 0 ? det > 0 : det < 0) {
                    /* inside corners joined: the segments cut off the outside ones */
                    SEG(e2, x1);
                    SEG(e1, x2);
                } else {
                    SEG(e1, x1);
                    SEG(e2, x2);
                }
            } else { /* each way in to the next way out (6 or 8 crossings: each tip its own) */
                for (int q = 0; q < n; q++)
                    if (entry[q])
                        SEG(q, (q + 1) % n);
            }
#undef SEG
        }
}

/* Whether the fan of a loop from x has no triangle of (all but) zero area, as the mesh will hold
 * it (in floats). */
static bool fan_ok(const struct cell *c, const double x[3], const long *loop, int n)
{
    const float *pos = c->pc->m.pos;
    double h = c->s * fmax(c->a->sp[0], fmax(c->a->sp[1], c->a->sp[2])), p[3];
    for (int d = 0; d < 3; d++)
        p[d] = (float)x[d];
    for (int k = 0; k < n; k++) {
        const float *q = pos + 3 * loop[k], *r = pos + 3 * loop[(k + 1) % n];
        double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, w[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
        double cr[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        if (!(dot3(cr, cr) > 1e-12 * h * h * h * h))
            return false;
    }
    return true;
}

/* The triangles (into tri, 3 per triangle, as indices of v) of the ear v[0..n) lying in the face
 * across axis: the polygon between a chord of a merged cell's face (v[n-1] -> v[0]) and the
 * finer path the face was cut into (v[0] -> ... -> v[n-1]), by clipping ears; false when it is
 * not a simple polygon of some area (then the chord's triangle is fanned over the path). */
static bool ear_triangles(const float *pos, const long *v, int n, int axis, int *tri)
{
    int u = axis == 0 ? 1 : 0, w = axis == 2 ? 1 : 2, idx[MAX_EAR], m = n, t = 0;
    double p[MAX_EAR][2];
    for (int k = 0; k < n; k++)
        p[k][0] = pos[3 * v[k] + u], p[k][1] = pos[3 * v[k] + w], idx[k] = k;
    double area = simple_area((const double (*)[2])p, n);
    if (area == 0)
        return false;
    while (m > 3) {
        int e = -1;
        for (int k = 0; k < m && e < 0; k++) {
            const double *a = p[idx[(k + m - 1) % m]], *b = p[idx[k]], *cc = p[idx[(k + 1) % m]];
            double cr = (b[0] - a[0]) * (cc[1] - a[1]) - (b[1] - a[1]) * (cc[0] - a[0]);
            if (!(cr * area > 0))
                continue;
            bool empty = true;
            for (int j = 0; j < m && empty; j++) {
                if (j == k || j == (k + 1) % m || j == (k + m - 1) % m)
                    continue;
                const double *q = p[idx[j]];
                double s1 = (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0]);
                double s2 = (cc[0] - b[0]) * (q[1] - b[1]) - (cc[1] - b[1]) * (q[0] - b[0]);
                double s3 = (a[0] - cc[0]) * (q[1] - cc[1]) - (a[1] - cc[1]) * (q[0] - cc[0]);
                empty = !(s1 * area >= 0 && s2 * area >= 0 && s3 * area >= 0);
            }
            if (empty)
                e = k;
        }
        if (e < 0)
            return false;
        tri[t++] = idx[(e + m - 1) % m], tri[t++] = idx[e], tri[t++] = idx[(e + 1) % m];
        for (int k = e; k + 1 < m; k++)
            idx[k] = idx[k + 1];
        m--;
    }
    tri[t++] = idx[0], tri[t++] = idx[1], tri[t++] = idx[2];
    return true;
}

/* A merged cell's loop that the faces it shares with finer cells cut (crossings on those faces'
 * inner edges between its corner-edge crossings): fanned as block_error measured it - its
 * corner-edge crossings alone, from the apex of least key or the inner crossing nearest their
 * mean - and each stretch of finer path closed against its chord by triangles in the face (the
 * ears), so that every full-resolution vertex lies within the accepted error of the fan and the
 * bound holds wherever the cell meets finer ones. False (nothing drawn) when the loop is not of
 * that form. */
static bool coarse_fan(struct cell *c, const long *loop, const int *faces, int n)
{
    int at[MAX_SEGS], nc = 0;
    for (int k = 0; k < n; k++) {
        if (loop[k] < 0 || faces[k] & (FACE_POINT | ON_FACE))
            return false;
        if (__builtin_popcount((unsigned)faces[k] & 63) == 2)
            at[nc++] = k;
    }
    if (nc < 3 || nc == n)
        return false;
    long cv[MAX_SEGS];
    int cf[MAX_SEGS], ears[MAX_SEGS][3 * (MAX_EAR - 2)], n_ear[MAX_SEGS];
    uint64_t keys[MAX_SEGS];
    long ev[MAX_SEGS][MAX_EAR];
    const float *pos = c->pc->m.pos;
    for (int i = 0; i < nc; i++) {
        int k0 = at[i], k1 = at[(i + 1) % nc], m = (k1 - k0 + n) % n + 1; /* the stretch k0 .. k1 */
        cv[i] = loop[k0], cf[i] = faces[k0], keys[i] = c->pc->vkey[loop[k0]], n_ear[i] = 0;
        if (m == 2)
            continue;
        int f = faces[k0] & faces[k1] & 63;
        if (m > MAX_EAR || __builtin_popcount((unsigned)f) != 1)
            return false;
        for (int j = 0; j < m; j++) {
            ev[i][j] = loop[(k0 + j) % n];
            if (j > 0 && j + 1 < m && (faces[(k0 + j) % n] & 63) != f)
                return false;
        }
        n_ear[i] = ear_triangles(pos, ev[i], m, __builtin_ctz((unsigned)f) >> 1, ears[i]) ? m - 2 : -m;
    }
    int apex = fan_apex(cf, keys, nc), nt = apex >= 0 ? nc - 2 : nc, over[MAX_SEGS], paths[MAX_SEGS] = {0};
    for (int i = 0; i < nc; i++) /* the triangle of each stretch whose path is fanned over */
        if (n_ear[i] < 0) {
            int t = fan_triangle(i, apex, nc);
            over[t] = i, paths[t]++;
        }
    long centre = -1;
    if (apex < 0) {
        double x[3] = {0, 0, 0};
        int cn[3], axis;
        for (int i = 0; i < nc; i++)
            for (int d = 0; d < 3; d++)
                x[d] += pos[3 * cv[i] + d] / nc;
        if (!inner_crossing(c->a, c->o, c->s, x, cn, &axis))
            return false;
        int cm[3] = {cn[0], cn[1], cn[2]};
        cm[axis]++;
        centre = edge_vertex(c->a, c->pc, cn, axis, Fp(c->a, cn), Fp(c->a, cm));
        pos = c->pc->m.pos; /* (a new vertex may have moved them) */
    }
    for (int t = 0; t < nt; t++) {
        /* triangle t as (x, p, q), the loop's edge p -> q */
        int p = apex >= 0 ? (apex + t + 1) % nc : t, q = (p + 1) % nc, i = paths[t] ? over[t] : -1;
        long x = apex >= 0 ? cv[apex] : centre;
        if (i < 0) {
            add_triangle(c->pc, x, cv[p], cv[q]);
        } else if (paths[t] == 1) { /* a path on both sides of its chord: the triangle fanned over it */
            if (apex >= 0 && i != p) /* (the apex's own edge: the triangle seen from its third corner) */
                x = cv[i == apex ? q : p];
            for (int j = 0; j + 1 < -n_ear[i]; j++)
                add_triangle(c->pc, x, ev[i][j], ev[i][j + 1]);
        } else { /* two or three: fanned from the triangle's centre over its sides x -> p -> q -> x */
            int side[3] = {apex >= 0 && t == 0 ? apex : -1, p, apex >= 0 && t == nt - 1 ? q : -1};
            long corner[3] = {x, cv[p], cv[q]}, mid;
            double m[3] = {0, 0, 0}, nrm[3] = {0, 0, 0};
            for (int k = 0; k < 3; k++)
                for (int d = 0; d < 3; d++)
                    m[d] += pos[3 * corner[k] + d] / 3, nrm[d] += c->pc->m.nrm[3 * corner[k] + d];
            if ((mid = new_vertex(c->pc, m, nrm, UINT64_MAX)) < 0)
                return true; /* (no memory: the piece says so) */
            pos = c->pc->m.pos; /* (the new vertex may have moved them) */
            for (int k = 0; k < 3; k++) {
                int st = side[k];
                if (st >= 0 && n_ear[st] < 0)
                    for (int j = 0; j + 1 < -n_ear[st]; j++)
                        add_triangle(c->pc, mid, ev[st][j], ev[st][j + 1]);
                else
                    add_triangle(c->pc, mid, corner[k], corner[(k + 1) % 3]);
            }
        }
    }
    for (int i = 0; i < nc; i++)
        for (int t = 0; t < n_ear[i]; t++)
            add_triangle(c->pc, ev[i][ears[i][3 * t]], ev[i][ears[i][3 * t + 1]], ev[i][ears[i][3 * t + 2]]);
    return true;
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
        double fx[3], fn[3];
        if (c->a->sharp && feature_point(c->a, c, loop, faces, n, fx, fn) && fan_ok(c, fx, loop, n)) { /* fanned from it */
            long centre = new_vertex(c->pc, fx, fn, UINT64_MAX);
            c->pc->feature_points++;
            for (int k = 0; k < n; k++)
                add_triangle(c->pc, centre, loop[k], loop[(k + 1) % n]);
            continue;
        }
        if (c->s > 1 && coarse_fan(c, loop, faces, n))
            continue;
        uint64_t keys[MAX_SEGS];
        for (int k = 0; k < n; k++)
            keys[k] = loop[k] < 0 ? UINT64_MAX : c->pc->vkey[loop[k]];
        int apex = fan_apex(faces, c->s > 1 ? keys : NULL, n); /* (a face point lies in a face too: its bit says) */
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
        int cn[3], axis;
        long centre;
        if (inner_crossing(c->a, c->o, c->s, pos, cn, &axis)) {
            int cm[3] = {cn[0], cn[1], cn[2]};
            cm[axis]++;
            centre = edge_vertex(c->a, c->pc, cn, axis, Fp(c->a, cn), Fp(c->a, cm));
        } else {
            centre = new_vertex(c->pc, pos, nrm, UINT64_MAX);
        }
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
    bool hides = l == 1 && a->mixed[2][block(a, 2, o[0] >> 1, o[1] >> 1, o[2] >> 1)] & HIDES;
    bool mixed = (in > 0 && in < 8) || (hides && hides_crossings(a, o, 1));
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
    c.a = a;
    c.hides = hides;
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
    long cells = pc->cells[lam], features = pc->feature_points;
    pc->block = (uint32_t)at;
    if (lam >= 2) {
        /* (a cell whose samples all lie on one side draws nothing, whichever neighbours it has:
         * most blocks, merged at every level as they hold no surface) */
        int m = (1 << (lam - 2)) - 1;
        if (!(b[0] & m) && !(b[1] & m) && !(b[2] & m) &&
            a->mixed[lam][block(a, lam, b[0] >> (lam - 2), b[1] >> (lam - 2), b[2] >> (lam - 2))])
            polygonise(a, pc, (int[3]){2 * b[0], 2 * b[1], 2 * b[2]}, lam);
    } else if (a->mixed[2][at]) { /* level-1 cells where the samples change side */
        bool hides = a->mixed[2][at] & HIDES, side[27];
        int n[3];
        for (int d = 0; d < 3; d++)
            n[d] = 2 * b[d] + 2 < a->N[d] ? 3 : a->N[d] - 2 * b[d];
        for (int z = 0; z < n[2]; z++) /* the block's samples once (a cell's corners lie planes apart) */
            for (int y = 0; y < n[1]; y++)
                for (int x = 0; x < n[0]; x++)
                    side[x + 3 * (y + 3 * z)] = F(a, 2 * b[0] + x, 2 * b[1] + y, 2 * b[2] + z) > a->iso;
        for (int k = 0; k < 8; k++) {
            int c[3] = {k & 1, k >> 1 & 1, k >> 2 & 1}, o[3] = {2 * b[0] + c[0], 2 * b[1] + c[1], 2 * b[2] + c[2]};
            if (o[0] + 1 >= a->N[0] || o[1] + 1 >= a->N[1] || o[2] + 1 >= a->N[2])
                continue;
            int in = 0;
            for (int q = 0; q < 8; q++)
                in += side[(c[0] + (q & 1)) + 3 * ((c[1] + (q >> 1 & 1)) + 3 * (c[2] + (q >> 2 & 1)))];
            if (hides || (in > 0 && in < 8)) /* (polygonise draws nothing in the others) */
                polygonise(a, pc, o, 1);
        }
    }
    if (a->bcells) {
        a->bcells[at] = (uint8_t)(pc->cells[lam] - cells);
        a->bfeat[at] = (uint8_t)(pc->feature_points - features);
    }
}

static void piece_free(struct piece *pc)
{
    free(pc->keys);
    free(pc->slot);
    free(pc->vkey);
    free(pc->owner);
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
    for (int l = 0; l <= ISO_MAX_LEVELS; l++)
        free(a->berr[l]);
    free(a->bcells), free(a->bfeat), free(a->refs);
    piece_free(&a->all);
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
    a->sharp = o->sharp;
    a->field = o->field, a->field_ctx = o->field_ctx;
    a->tri_limit_by = o->max_triangles_by ? o->max_triangles_by : "the limit";
    a->max_err = levels == 1 ? -1 : max_error; /* levels 1: nothing merges */
    for (int k = 0; o->max_triangles && k < ADAPT_SLABS; k++)
        a->pieces[k].tri_total = &a->tri_total, a->pieces[k].tri_limit = o->max_triangles;
    a->L = levels < 2 ? 2 : levels;
    int nn[3] = {g->nx, g->ny, g->nz};
    for (int d = 0; d < 3; d++) {
        a->N[d] = nn[d] + 2 * a->shift;
        a->sp[d] = g->spacing[d];
        a->org[d] = g->origin[d] - a->shift * g->spacing[d];
    }
    size_t n = (size_t)a->N[0] * a->N[1] * a->N[2];
    a->g = *g;
    a->iso1 = o->iso - 1; /* (the pad, below iso and the samples' least, is set when they are read) */
    if (!(a->F = malloc(n * sizeof *a->F))) {
        iso_adapt_free(a);
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the volume's %zu samples", n);
    }
    for (int l = 2; l <= a->L; l++) {
        int s = 1 << (l - 1);
        for (int d = 0; d < 3; d++)
            a->nb[l][d] = (a->N[d] - 1 + s - 1) / s;
        size_t nb = (size_t)a->nb[l][0] * a->nb[l][1] * a->nb[l][2];
        if (!(a->M[l] = calloc(nb ? nb : 1, 1)) || !(a->mixed[l] = calloc(nb ? nb : 1, 1)) ||
            (o->keep && !(a->berr[l] = calloc(nb ? nb : 1, sizeof(double))))) {
            iso_adapt_free(a);
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        }
    }
    size_t n2 = (size_t)a->nb[2][0] * a->nb[2][1] * a->nb[2][2];
    if (n2 > UINT32_MAX || !(a->lev2 = malloc(n2 ? n2 : 1)) ||
        (o->keep && (!(a->bcells = calloc(n2 ? n2 : 1, 1)) || !(a->bfeat = calloc(n2 ? n2 : 1, 1))))) {
        iso_adapt_free(a);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    a->n_slabs = a->nb[2][2] < ADAPT_SLABS ? a->nb[2][2] : ADAPT_SLABS;
    *out = a;
    return 0;
}

int iso_adapt_phases(const struct iso_adapt *a) { return a->L + 1; }

static void set_pad(struct iso_adapt *a);

/* Phase 0: the samples of planes [z0, z1) of the virtual grid as floats, and their least into
 * slab_min[slab]; the pad layer round them is written after every slab's (iso_adapt_between),
 * when the least of all is known. */
static void load_slab(struct iso_adapt *a, int z0, int z1, int slab)
{
    float lo = INFINITY;
    for (int z = z0; z < z1; z++)
        for (int y = 0; y < a->N[1]; y++) {
            float *row = a->F + at3(a, 0, y, z) + a->shift;
            int ry = y - a->shift, rz = z - a->shift;
            if (ry < 0 || ry >= a->g.ny || rz < 0 || rz >= a->g.nz)
                continue;
            iso_grid_row(&a->g, ry, rz, row);
            for (int x = 0; x < a->g.nx; x++)
                lo = row[x] < lo ? row[x] : lo;
        }
    a->slab_min[slab] = lo;
}

int iso_adapt_n_slabs(const struct iso_adapt *a) { return a->n_slabs; }

void iso_adapt_run(struct iso_adapt *a, int phase, int slab)
{
    if (phase == 0) {
        load_slab(a, (int)((long)a->N[2] * slab / a->n_slabs), (int)((long)a->N[2] * (slab + 1) / a->n_slabs), slab);
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
    if (phase == 0) { /* the samples are read: the pad below them and iso */
        a->gmin = INFINITY;
        for (int s = 0; s < a->n_slabs; s++)
            a->gmin = fmin(a->gmin, a->slab_min[s]);
        a->pad = a->shift ? (float)fmin(a->iso1, a->gmin) : 0;
        if (a->shift)
            set_pad(a);
    }
    if (phase == a->L - 1) /* the last level's blocks are known */
        cell_levels(a);
}

/* The slabs' pieces into a->all, each key once (the slabs' order: the same mesh on any number of
 * threads), their triangles renumbered; the counts into st. 0, or -1 (no memory, or over the
 * vertex limit). */
static int merge_pieces(struct iso_adapt *a, struct iso_adapt_stats *st)
{
    struct piece *all = &a->all;
    for (int k = 0; k < a->n_slabs; k++) {
        struct piece *pc = &a->pieces[k];
        for (int l = 1; l <= ISO_MAX_LEVELS; l++)
            st->cells[l] += pc->cells[l];
        st->feature_points += pc->feature_points;
        st->max_estimate = fmax(st->max_estimate, a->slab_max[k]);
        if (pc->nomem)
            return -1;
        uint32_t *id = malloc((pc->m.n_vert ? pc->m.n_vert : 1) * sizeof *id);
        if (!id)
            return -1;
        for (size_t v = 0; v < pc->m.n_vert && !all->nomem; v++) {
            bool found = false;
            size_t h = 0;
            if (pc->vkey[v] != UINT64_MAX && !slot_of(all, pc->vkey[v], &found, &h))
                break;
            if (found) {
                id[v] = all->slot[h];
                continue;
            }
            double pos[3] = {pc->m.pos[3 * v], pc->m.pos[3 * v + 1], pc->m.pos[3 * v + 2]};
            double nrm[3] = {pc->m.nrm[3 * v], pc->m.nrm[3 * v + 1], pc->m.nrm[3 * v + 2]};
            long g = new_vertex(all, pos, nrm, pc->vkey[v]);
            if (g < 0)
                break;
            st->face_points += pc->vkey[v] != UINT64_MAX && pc->vkey[v] & FACE_KEY;
            if (pc->vkey[v] != UINT64_MAX)
                keep_slot(all, h, pc->vkey[v], g);
            id[v] = (uint32_t)g;
        }
        for (size_t t = 0; t < pc->m.n_tri && !all->nomem; t++) {
            all->block = pc->owner[t];
            add_triangle(all, id[pc->m.tri[3 * t]], id[pc->m.tri[3 * t + 1]], id[pc->m.tri[3 * t + 2]]);
        }
        free(id);
        piece_free(pc);
        memset(pc, 0, sizeof *pc);
        if (all->nomem)
            return -1;
    }
    return 0;
}

static int mesh_failed(const struct iso_adapt *a, struct sf_err *err)
{
    for (int k = 0; k < ADAPT_SLABS; k++)
        if (a->pieces[k].over)
            return sf_fail(err, SF_ELIMIT, "", "the isosurface would have over %zu triangles, %s",
                           a->pieces[k].tri_limit, a->tri_limit_by);
    return sf_fail(err, a->all.m.n_vert >= ISO_MAX_VERTICES ? SF_ELIMIT : SF_ENOMEM, "",
                   "the mesh would take more memory than there is (or over %u vertices)", ISO_MAX_VERTICES);
}

int iso_adapt_end(struct iso_adapt *a, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    int rc = merge_pieces(a, st) ? mesh_failed(a, err) : 0;
    if (!rc) {
        *out = a->all.m;
        memset(&a->all.m, 0, sizeof a->all.m);
    }
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

/* ---- local rebuilds (iso_adapt_keep, iso_adapt_edit) ---- */

/* The smallest of the samples (not the pad) into a->gmin, and how many are it. */
static void samples_min(struct iso_adapt *a)
{
    float m = INFINITY;
    size_t n = 0;
    for (int z = a->shift; z < a->N[2] - a->shift; z++)
        for (int y = a->shift; y < a->N[1] - a->shift; y++) {
            const float *row = a->F + at3(a, 0, y, z);
            for (int x = a->shift; x < a->N[0] - a->shift; x++) {
                if (row[x] < m)
                    m = row[x], n = 0;
                n += row[x] == m;
            }
        }
    a->gmin = m;
    a->n_min = n;
}

int iso_adapt_keep(struct iso_adapt *a, struct iso_adapt_stats *st, struct sf_err *err)
{
    memset(st, 0, sizeof *st);
    if (!a->bcells)
        return sf_fail(err, SF_EINVAL, "", "the extraction was not begun to be kept");
    if (merge_pieces(a, st))
        return mesh_failed(a, err);
    const struct trimesh *m = &a->all.m;
    if (mem_reserve((void **)&a->refs, &a->rcap, m->n_vert + 1, sizeof *a->refs))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    memset(a->refs, 0, (m->n_vert + 1) * sizeof *a->refs);
    for (size_t i = 0; i < 3 * m->n_tri; i++)
        a->refs[m->tri[i]]++;
    for (size_t v = 0; v < m->n_vert; v++)
        a->dead += !a->refs[v];
    samples_min(a);
    memcpy(a->cells, st->cells, sizeof a->cells);
    a->feature_points = st->feature_points;
    a->kept = true;
    return 0;
}

int iso_adapt_mesh(const struct iso_adapt *a, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    const struct piece *all = &a->all;
    size_t nv = all->m.n_vert, nt = all->m.n_tri, live = nv - a->dead;
    uint32_t *id = malloc((nv ? nv : 1) * sizeof *id);
    out->pos = malloc((3 * live + 1) * sizeof *out->pos);
    out->nrm = malloc((3 * live + 1) * sizeof *out->nrm);
    out->tri = malloc((3 * nt + 1) * sizeof *out->tri);
    if (!id || !out->pos || !out->nrm || !out->tri) {
        free(id);
        trimesh_free(out);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    for (size_t v = 0; v < nv; v++) {
        if (!a->refs[v])
            continue;
        id[v] = (uint32_t)out->n_vert;
        memcpy(out->pos + 3 * out->n_vert, all->m.pos + 3 * v, 3 * sizeof *out->pos);
        memcpy(out->nrm + 3 * out->n_vert, all->m.nrm + 3 * v, 3 * sizeof *out->nrm);
        out->n_vert++;
        st->face_points += all->vkey[v] != UINT64_MAX && all->vkey[v] & FACE_KEY;
    }
    for (size_t i = 0; i < 3 * nt; i++)
        out->tri[i] = id[all->m.tri[i]];
    out->n_tri = nt;
    free(id);
    memcpy(st->cells, a->cells, sizeof st->cells);
    st->feature_points = a->feature_points;
    for (int l = 2; l <= a->L; l++) {
        size_t nb = (size_t)a->nb[l][0] * a->nb[l][1] * a->nb[l][2];
        for (size_t b = 0; b < nb; b++)
            st->max_estimate = fmax(st->max_estimate, a->berr[l][b]);
    }
    return 0;
}

static int floordiv(int x, int m) { return x >= 0 ? x / m : -((-x + m - 1) / m); }

/* Writes the pad layer round the samples (closed: the border counts as outside). */
static void set_pad(struct iso_adapt *a)
{
    for (int z = 0; z < a->N[2]; z++)
        for (int y = 0; y < a->N[1]; y++) {
            bool rim = y == 0 || z == 0 || y == a->N[1] - 1 || z == a->N[2] - 1;
            for (int x = 0; x < a->N[0]; x += rim || x == a->N[0] - 1 ? 1 : a->N[0] - 1)
                a->F[at3(a, x, y, z)] = a->pad;
        }
}

/* pc's vertices and triangles into the kept mesh: a keyed vertex that kept triangles still use
 * is theirs (it lies outside what changed, so it is the same), any other takes pc's values. 0,
 * or -1 (no memory). */
static int merge_rebuilt(struct iso_adapt *a, const struct piece *pc)
{
    struct piece *all = &a->all;
    uint32_t *id = malloc((pc->m.n_vert ? pc->m.n_vert : 1) * sizeof *id);
    if (!id)
        return -1;
    for (size_t v = 0; v < pc->m.n_vert && !all->nomem; v++) {
        uint64_t key = pc->vkey[v];
        bool found = false;
        size_t h = 0;
        if (key != UINT64_MAX && !slot_of(all, key, &found, &h))
            break;
        long g = found ? (long)all->slot[h] : -1;
        double pos[3] = {pc->m.pos[3 * v], pc->m.pos[3 * v + 1], pc->m.pos[3 * v + 2]};
        double nrm[3] = {pc->m.nrm[3 * v], pc->m.nrm[3 * v + 1], pc->m.nrm[3 * v + 2]};
        if (g >= 0 && !a->refs[g]) { /* unused since: where it is now (as merge_pieces puts it) */
            set_vertex(all, (size_t)g, pos, nrm);
        } else if (g < 0) {
            if ((g = new_vertex(all, pos, nrm, key)) < 0 ||
                mem_reserve((void **)&a->refs, &a->rcap, all->m.n_vert, sizeof *a->refs)) {
                all->nomem = true;
                break;
            }
            a->refs[g] = 0;
            a->dead++;
            if (key != UINT64_MAX)
                keep_slot(all, h, key, g);
        }
        id[v] = (uint32_t)g;
    }
    for (size_t t = 0; t < pc->m.n_tri && !all->nomem; t++) {
        all->block = pc->owner[t];
        size_t n = all->m.n_tri;
        add_triangle(all, id[pc->m.tri[3 * t]], id[pc->m.tri[3 * t + 1]], id[pc->m.tri[3 * t + 2]]);
        for (int k = 0; k < 3 && all->m.n_tri > n; k++)
            if (a->refs[all->m.tri[3 * n + k]]++ == 0)
                a->dead--;
    }
    free(id);
    return all->nomem ? -1 : 0;
}

/* The kept mesh without its unused vertices (when they outnumber the used ones). 0 or -1. */
static int compact(struct iso_adapt *a)
{
    struct piece *all = &a->all, n = {0};
    uint32_t *id = malloc((all->m.n_vert ? all->m.n_vert : 1) * sizeof *id);
    if (!id)
        return -1;
    for (size_t v = 0; v < all->m.n_vert && !n.nomem; v++) {
        if (!a->refs[v])
            continue;
        double pos[3] = {all->m.pos[3 * v], all->m.pos[3 * v + 1], all->m.pos[3 * v + 2]};
        double nrm[3] = {all->m.nrm[3 * v], all->m.nrm[3 * v + 1], all->m.nrm[3 * v + 2]};
        bool found;
        size_t h = 0;
        if (all->vkey[v] != UINT64_MAX && !slot_of(&n, all->vkey[v], &found, &h))
            break;
        long g = new_vertex(&n, pos, nrm, all->vkey[v]);
        if (g < 0)
            break;
        memcpy(n.m.nrm + 3 * g, all->m.nrm + 3 * v, 3 * sizeof *n.m.nrm); /* as it was, not made unit again */
        if (all->vkey[v] != UINT64_MAX)
            keep_slot(&n, h, all->vkey[v], g);
        id[v] = (uint32_t)g;
        a->refs[g] = a->refs[v]; /* g <= v */
    }
    for (size_t t = 0; t < all->m.n_tri && !n.nomem; t++) {
        n.block = all->owner[t];
        add_triangle(&n, id[all->m.tri[3 * t]], id[all->m.tri[3 * t + 1]], id[all->m.tri[3 * t + 2]]);
    }
    free(id);
    if (n.nomem) {
        piece_free(&n);
        return -1;
    }
    piece_free(all);
    *all = n;
    a->dead = 0;
    return 0;
}

/* Level-2 block index at -> its coordinates. */
static void block_at(const struct iso_adapt *a, size_t at, int b[3])
{
    b[0] = (int)(at % (size_t)a->nb[2][0]);
    at /= (size_t)a->nb[2][0];
    b[1] = (int)(at % (size_t)a->nb[2][1]);
    b[2] = (int)(at / (size_t)a->nb[2][1]);
}

static bool in_box(const int b[3], const int lo[3], const int hi[3])
{
    return b[0] >= lo[0] && b[0] <= hi[0] && b[1] >= lo[1] && b[1] <= hi[1] && b[2] >= lo[2] && b[2] <= hi[2];
}

/* The samples of block blk at lo into F, the samples' least value and its count kept. */
static void write_block(struct iso_adapt *a, const int lo[3], const struct iso_grid *blk)
{
    float m = (float)a->gmin, bmin = INFINITY;
    size_t gone = 0, come = 0, at_bmin = 0;
    for (int z = 0; z < blk->nz; z++)
        for (int y = 0; y < blk->ny; y++) {
            float *row = a->F + at3(a, lo[0] + a->shift, lo[1] + y + a->shift, lo[2] + z + a->shift);
            for (int x = 0; x < blk->nx; x++)
                gone += row[x] == m;
            iso_grid_row(blk, y, z, row);
            for (int x = 0; x < blk->nx; x++) {
                if (row[x] < bmin)
                    bmin = row[x], at_bmin = 0;
                at_bmin += row[x] == bmin;
                come += row[x] == m;
            }
        }
    if (bmin < m) /* (every other sample is at least the old least) */
        a->gmin = bmin, a->n_min = at_bmin;
    else if ((a->n_min += come - gone) == 0)
        samples_min(a);
}

int iso_adapt_edit(struct iso_adapt *a, const int lo[3], const struct iso_grid *blk, struct iso_edit *ed,
                   struct sf_err *err)
{
    memset(ed, 0, sizeof *ed);
    int n[3] = {blk->nx, blk->ny, blk->nz}, e0[3], e1[3];
    if (!a->kept)
        return sf_fail(err, SF_EINVAL, "", "the extraction is not kept (or an edit of it failed)");
    for (int d = 0; d < 3; d++)
        if (lo[d] < 0 || n[d] < 1 || lo[d] + (long)n[d] > a->N[d] - 2 * a->shift)
            return sf_fail(err, SF_EINVAL, "?region", "the region lies outside the volume's %d x %d x %d samples",
                           a->N[0] - 2 * a->shift, a->N[1] - 2 * a->shift, a->N[2] - 2 * a->shift);
    write_block(a, lo, blk);
    float pad = a->shift ? (float)fmin(a->iso1, a->gmin) : 0;
    ed->whole = pad != a->pad; /* the pad follows the samples' least: every border cell changes */
    if (ed->whole) {
        a->pad = pad;
        set_pad(a);
    }
    for (int d = 0; d < 3; d++) { /* the samples that changed, in the virtual grid */
        e0[d] = ed->whole ? 0 : lo[d] + a->shift;
        e1[d] = ed->whole ? a->N[d] - 1 : lo[d] + n[d] - 1 + a->shift;
    }
    /* the blocks whose decision can change, level by level: those holding a changed sample, and
     * above them those whose children or ring (mask_block) hold one of those */
    int blo[ISO_MAX_LEVELS + 1][3], bhi[ISO_MAX_LEVELS + 1][3], ulo[3], uhi[3], rlo[3], rhi[3];
    int c = 1 << (a->L - 2); /* the coarsest cell, in level-2 blocks */
    for (int l = 2; l <= a->L; l++)
        for (int d = 0; d < 3; d++) {
            int lo_ = l == 2 ? floordiv(e0[d] - 1, 2) : floordiv(blo[l - 1][d] - 1, 2);
            int hi_ = l == 2 ? floordiv(e1[d], 2) : floordiv(bhi[l - 1][d] + 1, 2);
            blo[l][d] = lo_ < 0 ? 0 : lo_;
            bhi[l][d] = hi_ >= a->nb[l][d] ? a->nb[l][d] - 1 : hi_;
            int u0 = blo[l][d] << (l - 2), u1 = ((bhi[l][d] + 1) << (l - 2)) - 1;
            ulo[d] = l == 2 || u0 < ulo[d] ? u0 : ulo[d];
            uhi[d] = l == 2 || u1 > uhi[d] ? u1 : uhi[d];
        }
    /* the cells to draw again: those, one block further (normals and neighbours' levels reach
     * that far), out to whole coarsest cells */
    for (int d = 0; d < 3; d++) {
        uhi[d] = uhi[d] >= a->nb[2][d] ? a->nb[2][d] - 1 : uhi[d];
        rlo[d] = floordiv(ulo[d] - 1, c) * c;
        rlo[d] = rlo[d] < 0 ? 0 : rlo[d];
        rhi[d] = (floordiv(uhi[d] + 1, c) + 1) * c - 1;
        rhi[d] = rhi[d] >= a->nb[2][d] ? a->nb[2][d] - 1 : rhi[d];
    }
    int b[3];
    for (b[2] = rlo[2]; b[2] <= rhi[2]; b[2]++) /* their cells leave the counts */
        for (b[1] = rlo[1]; b[1] <= rhi[1]; b[1]++)
            for (b[0] = rlo[0]; b[0] <= rhi[0]; b[0]++) {
                size_t at = block(a, 2, b[0], b[1], b[2]);
                a->cells[a->lev2[at]] -= a->bcells[at];
                a->feature_points -= a->bfeat[at];
            }
    for (int l = 2; l <= a->L; l++)
        for (b[2] = blo[l][2]; b[2] <= bhi[l][2]; b[2]++)
            for (b[1] = blo[l][1]; b[1] <= bhi[l][1]; b[1]++)
                for (b[0] = blo[l][0]; b[0] <= bhi[l][0]; b[0]++) {
                    size_t at = block(a, l, b[0], b[1], b[2]);
                    a->M[l][at] = 0;
                    a->berr[l][at] = 0;
                    mask_block(a, l, b, l == 2 && samples_mixed(a, b));
                }
    for (b[2] = ulo[2]; b[2] <= uhi[2]; b[2]++)
        for (b[1] = ulo[1]; b[1] <= uhi[1]; b[1]++)
            for (b[0] = ulo[0]; b[0] <= uhi[0]; b[0]++)
                cell_level(a, b);
    /* the old triangles of those cells out */
    struct piece *all = &a->all;
    for (size_t t = 0; t < all->m.n_tri;) {
        int ob[3];
        block_at(a, all->owner[t], ob);
        if (!in_box(ob, rlo, rhi)) {
            t++;
            continue;
        }
        for (int k = 0; k < 3; k++)
            if (--a->refs[all->m.tri[3 * t + k]] == 0)
                a->dead++;
        size_t last = --all->m.n_tri;
        memcpy(all->m.tri + 3 * t, all->m.tri + 3 * last, 3 * sizeof *all->m.tri);
        all->owner[t] = all->owner[last];
        ed->triangles_removed++;
    }
    /* and the new ones in */
    struct piece pc = {0};
    for (b[2] = rlo[2]; b[2] <= rhi[2] && !pc.nomem; b[2]++)
        for (b[1] = rlo[1]; b[1] <= rhi[1]; b[1]++)
            for (b[0] = rlo[0]; b[0] <= rhi[0]; b[0]++)
                block_cells(a, &pc, b);
    for (int l = 1; l <= ISO_MAX_LEVELS; l++)
        a->cells[l] += pc.cells[l], ed->cells_rebuilt += pc.cells[l];
    a->feature_points += pc.feature_points;
    ed->triangles_added = (long)pc.m.n_tri;
    int rc = pc.nomem || merge_rebuilt(a, &pc) ? -1 : 0;
    piece_free(&pc);
    if (!rc && a->dead > 4096 && a->dead > all->m.n_vert / 2)
        rc = compact(a);
    if (rc) {
        a->kept = false; /* half rebuilt: of no further use */
        return mesh_failed(a, err);
    }
    return 0;
}

size_t iso_adapt_bytes(const struct iso_adapt *a)
{
    size_t n = (size_t)a->N[0] * a->N[1] * a->N[2] * sizeof *a->F, nb2 = (size_t)a->nb[2][0] * a->nb[2][1] * a->nb[2][2];
    for (int l = 2; l <= a->L; l++)
        n += (size_t)a->nb[l][0] * a->nb[l][1] * a->nb[l][2] * (2 + (a->berr[l] ? sizeof(double) : 0));
    n += nb2 * 3 + a->all.cap * (sizeof(uint64_t) + sizeof(uint32_t));
    n += a->all.vcap * 2 * sizeof(float) + a->all.kcap * sizeof(uint64_t) + a->rcap * sizeof(uint32_t);
    return n + a->all.tcap * sizeof(uint32_t) + a->all.ocap * sizeof(uint32_t);
}
