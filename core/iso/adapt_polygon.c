/* adapt_polygon.c - the polygoniser of the adaptive hierarchy: a cell's faces cut into segments at
 * the resolution of the finer cells across them, chained into loops and fanned, from a vertex none
 * of whose diagonals lies in a face or from a centre on the full-resolution surface; a merged
 * cell's loop as block_error measured it (fan_apex, inner_crossing, face_inside_joined: the rules
 * adapt_hierarchy.c reads too). */
#include "adapt_internal.h"
#include "cube.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

/* The vertex a loop of n is fanned from: of those none of whose diagonals joins two vertices of
 * one cell face (faces: each vertex's face bits), the first, or with keys the one of least key
 * (merged cells: so that block_error and the mesh pick the same whichever vertex their loops
 * start from), or -1 (then from a centre). */
int fan_apex(const int *faces, const uint64_t *keys, int n)
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
bool inner_crossing(const struct iso_adapt *a, const int o[3], int s, double x[3], int n[3], int *axis)
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
double simple_area(const double (*p)[2], int n)
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

/* The face square across axis of s nodes a side (s >= 2) from node sq, its inside corners
 * diagonal: whether they are joined across it as its nine nodes (corners, mid-edges, centre) join
 * them, 4 neighbours to a node (as the square cut in four draws it); -1 when a quarter is itself
 * ambiguous (then the corners' bilinear decides). Every square of 2 or more nodes a side is drawn
 * so, from both cells that share it, so that a merged cell's face joins its crossings as the same
 * face cut in four does where finer cells lie across. */
int face_inside_joined(const struct iso_adapt *a, int axis, const int sq[3], int s)
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
void block_cells(const struct iso_adapt *a, struct piece *pc, const int b[3])
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

