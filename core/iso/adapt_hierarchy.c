/* adapt_hierarchy.c - which cells the adaptive hierarchy draws: a block merges at a level where
 * the polygon its merged cell would draw stays within max_error of every full-resolution vertex in
 * it (block_error, fanned as adapt_polygon.c fans it) and its neighbours allow, and each level-2
 * block gets the level of the cell that covers it. It draws nothing. */
#include "adapt_internal.h"
#include "cube.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

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
bool samples_mixed(const struct iso_adapt *a, const int b[3])
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
double mask_block(struct iso_adapt *a, int l, const int b[3], bool split)
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
void mask_slab(struct iso_adapt *a, int l, int z0, int z1, int slab)
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
void cell_level(struct iso_adapt *a, const int b[3])
{
    int lev = 1;
    for (int l = a->L; l >= 2 && lev == 1; l--)
        if (a->M[l][block(a, l, b[0] >> (l - 2), b[1] >> (l - 2), b[2] >> (l - 2))])
            lev = l;
    a->lev2[block(a, 2, b[0], b[1], b[2])] = (uint8_t)lev;
}

void cell_levels(struct iso_adapt *a)
{
    int b[3];
    for (b[2] = 0; b[2] < a->nb[2][2]; b[2]++)
        for (b[1] = 0; b[1] < a->nb[2][1]; b[1]++)
            for (b[0] = 0; b[0] < a->nb[2][0]; b[0]++)
                cell_level(a, b);
}

