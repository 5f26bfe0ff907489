/* adapt_feature.c - feature points (seed 002's second method): where a cell's loop turns sharply,
 * the vertex where the tangent planes of its crossings meet (an edge or a corner of the surface),
 * and on the cell's faces the points where the isoline's tangents meet or, with the field at hand,
 * where the isoline strays from a segment. Each is a keyed vertex of the piece, so that both cells
 * that share a face find the same one. */
#include "adapt_internal.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define FEATURE_COS 0.9   /* normals further apart than this (26 degrees) make a feature */
#define CORNER_COS 0.7    /* a third normal this far out of the other two's plane makes a corner */

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
void add_face_seg(struct cell *c, int f, const int sq[3], int h, int j, long from, int from_faces, long to)
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
bool feature_point(const struct iso_adapt *a, const struct cell *c, const long *loop, const int *faces, int n,
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

