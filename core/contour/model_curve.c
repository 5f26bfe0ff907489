/* model_curve.c - a contour's curve and a slice pair's nets, what every method of model.c reads.
 *
 * Each contour becomes a closed curve C(u), u in [0,1), through all its points, parameterised by
 * chord length from where the +x ray out of its centroid crosses it, so that u = 0 lines up from
 * slice to slice whatever the start points of the data (no twist), or, asked for (model_opts.polar),
 * by the polar angle round the centroid (seed 004 eq. 1–5) where the contour winds round it. Between
 * points i and i+1 the curve blends the parabolas through points i-1..i+1 and i..i+2 (eq. 32): a
 * cubic. Across slices the same blend runs at fixed u over the slices' z. A chain's curves are
 * lined up and redrawn on fewer knots here; on the merged breakpoints of the (up to) four curves a
 * slice pair depends on, every piece is bicubic, so it is converted exactly (pair_nets): sampled on
 * a 4x4 grid and solved against the Bernstein basis. */
#include "model_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

#define BREAK_EPS 1e-12 /* breakpoints closer than this in u are one */

void curve_free(struct curve *c)
{
    free(c->p);
    free(c->u);
    free(c->corner);
    free(c->t_in);
    free(c->t_out);
}

/* Seed 004 eq. 1–5: rays from the centroid give u = φ / 2π where the contour turns steadily about it
 * (eq. 1); where a stretch turns back (turning points, a sign change of Δφ: eq. 2–3) the polar angle's
 * running maximum stands still, and the arc length spreads u over the stretch (eq. 4–5). Here that is
 * one formula: u = (Φ + λ 2π a) / (2π (1 + λ)), Φ the running maximum of the unwrapped angle from the
 * start ray and a the arc-length fraction (the chord parameters c->u on entry), so u always
 * increases; λ (ours) weighs arc length in. A contour that does not wind once round its centroid
 * (a C shape whose centroid lies outside) keeps the arc-length parameters. */
#define POLAR_ARC_WEIGHT 0.25

static void polar_parameters(struct curve *c, double cx, double cy)
{
    double phi = 0.0, prev = 0.0, run = 0.0, *u = malloc(sizeof *u * (size_t)c->n);
    if (!u)
        return; /* arc length it is */
    for (int k = 0; k <= c->n; k++) {
        const double *p = c->p[k % c->n];
        double a = atan2(p[1] - cy, p[0] - cx), d = a - prev;
        d -= 2 * M_PI * floor((d + M_PI) / (2 * M_PI)); /* into [-π, π) */
        phi += d, prev = a;
        if (k == c->n) /* back at the start: once round, counter-clockwise? */
            break;
        run = fmax(run, fmin(phi, 2 * M_PI));
        u[k] = (run + POLAR_ARC_WEIGHT * 2 * M_PI * c->u[k]) / (2 * M_PI * (1 + POLAR_ARC_WEIGHT));
    }
    if (fabs(phi - 2 * M_PI) < 0.5)
        memcpy(c->u, u, sizeof *u * (size_t)c->n);
    free(u);
}

/* Parameter and point of index i, any integer (periodic: one turn adds 1 to u). */
static double cu(const struct curve *c, int i, double *x, double *y)
{
    int n = c->n, k = ((i % n) + n) % n, turns = (i - k) / n;
    *x = c->p[k][0];
    *y = c->p[k][1];
    return c->u[k] + turns;
}

/* ---- corners, straight runs and bulges (parabolic) ----
 * The curve through every point is right where the points sample a smooth outline densely. Where a
 * planning system draws a box, a couch or a hand-made structure with 4 to 6 points a slice, the
 * parabolas round its corners off and bulge between far-apart points: a 50 mm square of 4 points
 * modelled +36.7 %, an L of 6 +43 %. Ours (the seeds are silent; the local fits are seed 004's),
 * features counting where they are drawn at the contour's scale, FEATURE_REL of its extent or more
 * (so that a dense outline's pixel steps and spikes are not taken for them: the lung's slits, 2 mm
 * steps on a 100 mm contour, folded the surface between levels as corners):
 * - a run of edges in line (each turning less than STRAIGHT_TURN from the last), FEATURE_REL long or
 *   more, is straight: the tangents at its ends run along it, so it stays a line and the curve leaves
 *   it tangentially;
 * - a point where the contour turns by CORNER_TURN or more next to an edge or run FEATURE_REL long,
 *   or between two straight runs turning by RUN_CORNER_TURN or more, is a corner: the curve is C0
 *   there, each side's tangent from its own side alone (the parabola through that point and the
 *   next two, as at an open end; the edge itself where the next point is a corner or the edge is
 *   straight, so corners are joined straight). Dense outlines bend between runs by less (Eclipse's
 *   body: 2831 such bends, all under 10 degrees, which as corners cut it into 2.6 times the patches);
 * - no piece leaves its edge's line by more than BULGE_REL of the edge's length or BULGE_EXT of the
 *   contour's extent, whichever is more: the tangents at its ends are shortened until the bound
 *   4/27 (|a0| + |a1|) on the piece's offset from that line holds (a0, a1: the end tangents'
 *   components across the edge times the piece's span; the Hermite basis functions t(1-t)² and
 *   t²(1-t) peak at 4/27). A point's two tangents shorten together but at a corner, so the curve
 *   stays C1 where it was.
 * So a 4 to 6 point polygon is modelled as the polygon, an octagon as a curve within 0.1 of an edge
 * of it (the figures warn: model_departure), and dense organ contours as before: their volumes move
 * by 3e-4 (the tumour bed's two corners) down to 2e-8 (Eclipse's body). */
#define CORNER_TURN 60.0     /* degrees */
#define RUN_CORNER_TURN 10.0 /* degrees */
#define STRAIGHT_TURN 0.25   /* degrees */
#define FEATURE_REL 0.05
#define BULGE_REL 0.1
#define BULGE_EXT 0.005

/* The turn of the contour at point i, in degrees (0 straight on, 180 back). */
static double turn_at(const struct curve *c, int i)
{
    double a[2], b[2], d[2];
    cu(c, i - 1, &a[0], &a[1]), cu(c, i, &b[0], &b[1]), cu(c, i + 1, &d[0], &d[1]);
    double e[2] = {b[0] - a[0], b[1] - a[1]}, f[2] = {d[0] - b[0], d[1] - b[1]};
    return fabs(atan2(e[0] * f[1] - e[1] * f[0], e[0] * f[0] + e[1] * f[1])) * (180.0 / M_PI);
}

/* The u-derivative at point at of the parabola through points i, i+1, i+2 (at one of them). */
static void parabola_slope(const struct curve *c, int i, int at, double out[2])
{
    double ts[3], v[3][2], t = 0.0;
    for (int a = 0; a < 3; a++) {
        ts[a] = cu(c, i + a, &v[a][0], &v[a][1]);
        if (i + a == at)
            t = ts[a];
    }
    out[0] = out[1] = 0.0;
    for (int a = 0; a < 3; a++) { /* d/dt of v_a's Lagrange basis (t - t_b)(t - t_d) / ... */
        int b = (a + 1) % 3, d = (a + 2) % 3;
        double w = ((t - ts[b]) + (t - ts[d])) / ((ts[a] - ts[b]) * (ts[a] - ts[d]));
        out[0] += w * v[a][0], out[1] += w * v[a][1];
    }
}

/* The edge from point i to i+1 as a u-derivative (its chord over its span). */
static void edge_slope(const struct curve *c, int i, double out[2])
{
    double a[2], b[2], h = cu(c, i + 1, &b[0], &b[1]) - cu(c, i, &a[0], &a[1]);
    out[0] = (b[0] - a[0]) / h, out[1] = (b[1] - a[1]) / h;
}

/* Corners and tangents of a parabolic curve (above). */
static void curve_shape(struct curve *c)
{
    int n = c->n;
    double *turn = malloc(sizeof *turn * (size_t)n), *s = malloc(sizeof *s * (size_t)n);
    bool *straight = malloc(sizeof *straight * (size_t)n); /* edge i, i+1 */
    if (!turn || !s || !straight) { /* (seed 004's curve as it was: no corners, the parabolas' tangents) */
        for (int i = 0; i < n; i++)
            parabola_slope(c, i - 1, i, c->t_in[i]), memcpy(c->t_out[i], c->t_in[i], sizeof c->t_in[i]);
        free(turn), free(s), free(straight);
        return;
    }
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (int i = 0; i < n; i++) {
        turn[i] = turn_at(c, i);
        for (int d = 0; d < 2; d++)
            lo[d] = fmin(lo[d], c->p[i][d]), hi[d] = fmax(hi[d], c->p[i][d]);
    }
    /* s[i]: the length of the run of edges in line that edge i is part of (itself alone if none) */
    double feature = FEATURE_REL * fmax(hi[0] - lo[0], hi[1] - lo[1]);
    int first = 0; /* an edge that begins a run (some turn is not straight on: they sum to a whole turn) */
    while (first < n - 1 && turn[first] < STRAIGHT_TURN)
        first++;
    for (int k = 0; k < n;) {
        int end = k + 1; /* edges first + k .. first + end - 1 */
        double len = 0.0;
        while (end < n && turn[(first + end) % n] < STRAIGHT_TURN)
            end++;
        for (int e = k; e < end; e++) {
            double a[2], b[2];
            cu(c, first + e, &a[0], &a[1]), cu(c, first + e + 1, &b[0], &b[1]);
            len += hypot(b[0] - a[0], b[1] - a[1]);
        }
        for (int e = k; e < end; e++)
            s[(first + e) % n] = len;
        k = end;
    }
    for (int i = 0; i < n; i++)
        straight[i] = (turn[i] < STRAIGHT_TURN || turn[(i + 1) % n] < STRAIGHT_TURN) && s[i] >= feature;
    for (int i = 0; i < n; i++) {
        int prev = (i + n - 1) % n;
        c->corner[i] = (turn[i] >= CORNER_TURN && (s[prev] >= feature || s[i] >= feature)) ||
                       (straight[prev] && straight[i] && turn[i] >= RUN_CORNER_TURN);
    }
    for (int i = 0; i < n; i++) {
        int prev = (i + n - 1) % n, next = (i + 1) % n;
        double *in = c->t_in[i], *out = c->t_out[i];
        if (c->corner[i]) {
            if (straight[prev] || c->corner[prev])
                edge_slope(c, i - 1, in);
            else
                parabola_slope(c, i - 2, i, in);
            if (straight[i] || c->corner[next])
                edge_slope(c, i, out);
            else
                parabola_slope(c, i, i, out);
            continue;
        }
        if (straight[i] && !straight[prev])
            edge_slope(c, i, in);
        else if (straight[prev] && !straight[i])
            edge_slope(c, i - 1, in);
        else /* (within a straight run, the parabola through three points in line is the line) */
            parabola_slope(c, i - 1, i, in);
        memcpy(out, in, sizeof c->t_in[i]);
    }
    for (int i = 0; i < n; i++) { /* each piece's shortening, s[i] for the piece from point i */
        double a[2], b[2], h = cu(c, i + 1, &b[0], &b[1]) - cu(c, i, &a[0], &a[1]);
        double e[2] = {b[0] - a[0], b[1] - a[1]}, len = hypot(e[0], e[1]);
        const double *m0 = c->t_out[i], *m1 = c->t_in[(i + 1) % n];
        double bound = 4.0 / 27.0 * h * (fabs(e[0] * m0[1] - e[1] * m0[0]) + fabs(e[0] * m1[1] - e[1] * m1[0])) / len;
        double tol = fmax(BULGE_REL * len, BULGE_EXT * feature / FEATURE_REL);
        s[i] = bound > tol ? tol / bound : 1.0;
    }
    for (int i = 0; i < n; i++) {
        double before = s[(i + n - 1) % n], after = s[i];
        if (!c->corner[i])
            before = after = fmin(before, after);
        for (int d = 0; d < 2; d++)
            c->t_in[i][d] *= before, c->t_out[i][d] *= after;
    }
    free(turn), free(s), free(straight);
}

/* Builds the curve of slice s: parameters from the +x crossing of the centroid's ray, by arc length
 * (the default), or polar (seed 004) where the contour winds round its centroid. */
int curve_build(const struct contour_slice *s, bool lsq, bool polar, struct curve *c)
{
    int n = s->n;
    c->lsq = lsq;
    c->n = n;
    c->p = malloc(sizeof *c->p * (size_t)n);
    c->u = malloc(sizeof *c->u * (size_t)n);
    c->corner = calloc((size_t)n, sizeof *c->corner);
    c->t_in = malloc(sizeof *c->t_in * (size_t)n);
    c->t_out = malloc(sizeof *c->t_out * (size_t)n);
    double *len = malloc(sizeof *len * (size_t)(n + 1));
    if (!c->p || !c->u || !c->corner || !c->t_in || !c->t_out || !len) {
        free(len);
        return SF_ENOMEM;
    }
    double cx, cy;
    contour_centroid(s, &cx, &cy);
    len[0] = 0;
    for (int i = 0; i < n; i++)
        len[i + 1] = len[i] + hypot(s->p[(i + 1) % n][0] - s->p[i][0], s->p[(i + 1) % n][1] - s->p[i][1]);
    double total = len[n];
    /* start: the outermost upward crossing of y = cy right of the centroid */
    double s0 = 0, best_x = -INFINITY;
    for (int i = 0; i < n; i++) {
        const double *p = s->p[i], *q = s->p[(i + 1) % n];
        if (p[1] < cy && q[1] >= cy) {
            double f = (cy - p[1]) / (q[1] - p[1]), x = p[0] + f * (q[0] - p[0]);
            if (x > cx && x > best_x) {
                best_x = x;
                s0 = len[i] + f * (len[i + 1] - len[i]);
            }
        }
    }
    /* rotate so that index 0 is the first point at or after s0 */
    int first = 0;
    while (first < n && len[first] < s0)
        first++;
    for (int k = 0; k < n; k++) {
        int i = (first + k) % n;
        c->p[k][0] = s->p[i][0];
        c->p[k][1] = s->p[i][1];
        double d = len[i] - s0;
        if (d < 0)
            d += total;
        c->u[k] = d / total;
    }
    free(len);
    if (polar && isfinite(best_x))
        polar_parameters(c, cx, cy);
    if (!lsq)
        curve_shape(c);
    return 0;
}


/* Lagrange parabola through (t0,v0), (t1,v1), (t2,v2) at t. */
static double parabola(double t, double t0, double t1, double t2, double v0, double v1, double v2)
{
    return v0 * (t - t1) * (t - t2) / ((t0 - t1) * (t0 - t2)) + v1 * (t - t0) * (t - t2) / ((t1 - t0) * (t1 - t2)) +
           v2 * (t - t0) * (t - t1) / ((t2 - t0) * (t2 - t1));
}

/* Least-squares line through (t0,v0), (t1,v1), (t2,v2) at t (seed 000 eq. 33–35). */
static double lsq_line(double t, double t0, double t1, double t2, double v0, double v1, double v2)
{
    double tm = (t0 + t1 + t2) / 3, vm = (v0 + v1 + v2) / 3;
    double sxx = (t0 - tm) * (t0 - tm) + (t1 - tm) * (t1 - tm) + (t2 - tm) * (t2 - tm);
    double sxy = (t0 - tm) * (v0 - vm) + (t1 - tm) * (v1 - vm) + (t2 - tm) * (v2 - vm);
    return vm + sxy / sxx * (t - tm);
}

/* The local fit through three points: a parabola (parabolic, seed 004 eq. 6–12) or a
 * least-squares line (linear-parabolic, seed 000 eq. 33–35). */
static double local_fit(bool lsq, double t, const double ts[3], const double v[3])
{
    return lsq ? lsq_line(t, ts[0], ts[1], ts[2], v[0], v[1], v[2]) : parabola(t, ts[0], ts[1], ts[2], v[0], v[1], v[2]);
}

/* eq. 32: between t1 and t2, the blend of the local fits through 0..2 and 1..3. */
static double blend(bool lsq, double t, const double ts[4], const double v[4])
{
    double L1 = local_fit(lsq, t, ts, v), L2 = local_fit(lsq, t, ts + 1, v + 1);
    return (t - ts[2]) / (ts[1] - ts[2]) * L1 + (t - ts[1]) / (ts[2] - ts[1]) * L2;
}

/* The last i with u[i] <= x among n increasing parameters, or -1 when x < u[0]. */
static int segment_at(const double *u, int n, double x)
{
    if (x < u[0])
        return -1;
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if (u[mid] <= x)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

/* The Hermite cubic through the curve at knots k0 and k1 (values and derivatives), in power basis
 * in t = (u - u0) / (u1 - u0). */
static void hermite_piece(const struct knot *k0, const struct knot *k1, double hx[4], double hy[4])
{
    double h = k1->u - k0->u;
    const double v[2][4] = {{k0->x, h * k0->xu, k1->x, h * k1->xu}, {k0->y, h * k0->yu, k1->y, h * k1->yu}};
    double *out[2] = {hx, hy};
    for (int d = 0; d < 2; d++) {
        out[d][0] = v[d][0];
        out[d][1] = v[d][1];
        out[d][2] = 3 * (v[d][2] - v[d][0]) - 2 * v[d][1] - v[d][3];
        out[d][3] = 2 * (v[d][0] - v[d][2]) + v[d][1] + v[d][3];
    }
}

/* Segment i of the curve (from point i to i+1, any integer) as a cubic in power basis in
 * t = (u - u_i) / (u_{i+1} - u_i): parabolic, the Hermite cubic of its ends' points and tangents
 * (curve_shape; where no point is a corner or straight, eq. 32's blend of the parabolas through
 * i-1..i+1 and i..i+2, whose derivative at a point is its own parabola's); linear-parabolic, eq.
 * 32's blend of least-squares lines sampled at t = 0, 1/3, 2/3, 1 and solved. */
static void segment_poly(const struct curve *c, int i, double px[4], double py[4])
{
    int n = c->n, k = ((i % n) + n) % n, k1 = (k + 1) % n;
    if (!c->lsq) {
        struct knot a = {.xu = c->t_out[k][0], .yu = c->t_out[k][1]}, b = {.xu = c->t_in[k1][0], .yu = c->t_in[k1][1]};
        a.u = cu(c, i, &a.x, &a.y), b.u = cu(c, i + 1, &b.x, &b.y);
        hermite_piece(&a, &b, px, py);
        return;
    }
    /* the inverse Vandermonde of t = 0, 1/3, 2/3, 1 maps samples to coefficients */
    static const double VINV[4][4] = {{1, 0, 0, 0}, {-5.5, 9, -4.5, 1}, {9, -22.5, 18, -4.5}, {-4.5, 13.5, -13.5, 4.5}};
    double ts[4], xs[4], ys[4], sx[4], sy[4];
    for (int q = 0; q < 4; q++)
        ts[q] = cu(c, i - 1 + q, &xs[q], &ys[q]);
    for (int a = 0; a < 4; a++) {
        double u = ts[1] + (ts[2] - ts[1]) * a / 3.0;
        sx[a] = blend(true, u, ts, xs), sy[a] = blend(true, u, ts, ys);
    }
    for (int q = 0; q < 4; q++) {
        px[q] = py[q] = 0;
        for (int a = 0; a < 4; a++)
            px[q] += VINV[q][a] * sx[a], py[q] += VINV[q][a] * sy[a];
    }
}

/* The curve at u in [0, 1]. */
static void curve_eval(const struct curve *c, double u, double *x, double *y)
{
    /* segment i: u_i <= u < u_{i+1} (periodic; u below u_0 belongs to the segment from the last
     * point, i = -1) */
    int i = segment_at(c->u, c->n, u);
    double px[4], py[4], p[2], u0 = cu(c, i, &p[0], &p[1]), t = (u - u0) / (cu(c, i + 1, &p[0], &p[1]) - u0);
    segment_poly(c, i, px, py);
    *x = px[0] + t * (px[1] + t * (px[2] + t * px[3]));
    *y = py[0] + t * (py[1] + t * (py[2] + t * py[3]));
}

/* ---- lining up a chain's curves ----
 * The +x ray out of the centroid starts every curve at a like place while contours are alike, but
 * on a C-shaped contour it may cross another lobe from one level to the next (the left lung at z
 * -107.44 and -104.44: corresponding points 18 mm apart on average, 9 mm from the best start), and
 * the side surface between them folds through itself. Ours (the seeds are silent): each curve after
 * a chain's first may start elsewhere, where the mean squared distance to the curve below at equal
 * parameter steps is least (ALIGN_SHIFTS starts tried on ALIGN_SAMPLES points, the best refined by
 * golden section), when that start is nearer by ALIGN_GAIN in root mean square; otherwise the ray's
 * start stands, as it lines up unlike shapes better than least distance does (the lung at -77.44
 * and -74.44, where its section almost doubles: 48 pairs of cutting triangles with the ray, 105 with
 * least distance). Lung: 446 -> 36 cutting pairs with hole_reach (solid.c). A start only moves the
 * parameter along the curve, whose shape is its points' and their spacing's, so every method reads
 * the same curves and a model's volume and patches agree as before. */
#define ALIGN_SAMPLES 32
#define ALIGN_SHIFTS 128
#define ALIGN_GAIN 0.7

/* Turns a's n items of size sz so that item first comes first, through tmp (n items). */
static void rotate(void *a, int n, size_t sz, int first, char *tmp)
{
    memcpy(tmp, (char *)a + sz * (size_t)first, sz * (size_t)(n - first));
    memcpy(tmp + sz * (size_t)(n - first), a, sz * (size_t)first);
    memcpy(a, tmp, sz * (size_t)n);
}

/* The curve started at parameter d: u -> u - d (mod 1), the points rotated to keep u increasing. */
static void curve_shift(struct curve *c, double d)
{
    int n = c->n, first = 0;
    double best = 2.0;
    for (int k = 0; k < n; k++) {
        double w = c->u[k] - d;
        w -= floor(w);
        if (w < best)
            best = w, first = k;
    }
    char *tmp = malloc(sizeof *c->p * (size_t)n);
    if (!tmp) /* (left as it was) */
        return;
    for (int k = 0; k < n; k++)
        c->u[k] -= d, c->u[k] -= floor(c->u[k]);
    rotate(c->u, n, sizeof *c->u, first, tmp);
    rotate(c->p, n, sizeof *c->p, first, tmp);
    rotate(c->corner, n, sizeof *c->corner, first, tmp);
    rotate(c->t_in, n, sizeof *c->t_in, first, tmp);
    rotate(c->t_out, n, sizeof *c->t_out, first, tmp);
    free(tmp);
}

static void curve_at(const struct curve *c, double u, double *x, double *y) { curve_eval(c, u - floor(u), x, y); }

/* Mean squared distance of b at u + d from a's samples sa (at u = (m + 0.5) / ALIGN_SAMPLES). */
static double align_cost(double (*sa)[2], const struct curve *b, double d)
{
    double sum = 0.0;
    for (int m = 0; m < ALIGN_SAMPLES; m++) {
        double x, y;
        curve_at(b, (m + 0.5) / ALIGN_SAMPLES + d, &x, &y);
        sum += (x - sa[m][0]) * (x - sa[m][0]) + (y - sa[m][1]) * (y - sa[m][1]);
    }
    return sum / ALIGN_SAMPLES;
}

/* Starts b where it lines up with a (the curve below it), if that is worth it (ALIGN_GAIN). */
static void curve_align(const struct curve *a, struct curve *b)
{
    const int K = ALIGN_SHIFTS, M = ALIGN_SAMPLES, step = K / M;
    double sa[ALIGN_SAMPLES][2], sb[ALIGN_SHIFTS][2], best = INFINITY;
    for (int m = 0; m < M; m++)
        curve_at(a, (m + 0.5) / M, &sa[m][0], &sa[m][1]);
    for (int k = 0; k < K; k++)
        curve_at(b, (k + 0.5 * step) / K, &sb[k][0], &sb[k][1]);
    int at = 0;
    double here = 0.0;
    for (int s = 0; s < K; s++) { /* start s / K: b's samples s, s + step, ... against a's */
        double sum = 0.0;
        for (int m = 0; m < M; m++) {
            const double *q = sb[(m * step + s) % K];
            sum += (q[0] - sa[m][0]) * (q[0] - sa[m][0]) + (q[1] - sa[m][1]) * (q[1] - sa[m][1]);
        }
        if (!s)
            here = sum;
        if (sum < best)
            best = sum, at = s;
    }
    if (best >= ALIGN_GAIN * here) /* (refining gains far less than the rest of the way) */
        return;
    const double g = 0.5 * (sqrt(5.0) - 1.0); /* golden section between the neighbouring starts */
    double lo = (at - 1.0) / K, hi = (at + 1.0) / K, x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
    double f1 = align_cost(sa, b, x1), f2 = align_cost(sa, b, x2);
    for (int it = 0; it < 12; it++)
        if (f1 < f2)
            hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = align_cost(sa, b, x1);
        else
            lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = align_cost(sa, b, x2);
    double d = 0.5 * (lo + hi);
    if (align_cost(sa, b, d) < ALIGN_GAIN * ALIGN_GAIN * align_cost(sa, b, 0.0))
        curve_shift(b, d - floor(d));
}

/* The curves of a chain's contours (one a level, bottom up), each after the first lined up with the
 * one below unless the parameters are polar (the angle lines them up). */
int curves_build(const struct contour_set *cs, bool lsq, bool polar, struct curve *cv)
{
    for (int j = 0; j < cs->n_slices; j++) {
        int rc = curve_build(&cs->s[j], lsq, polar, &cv[j]);
        if (rc)
            return rc;
        if (j > 0 && !polar)
            curve_align(&cv[j - 1], &cv[j]);
    }
    return 0;
}

int curve_poly_build(const struct curve *c, struct curve_poly *cp)
{
    cp->n = c->n;
    cp->u = c->u;
    cp->cx = malloc(sizeof *cp->cx * (size_t)c->n);
    cp->cy = malloc(sizeof *cp->cy * (size_t)c->n);
    cp->corner = malloc(sizeof *cp->corner * (size_t)c->n);
    if (!cp->cx || !cp->cy || !cp->corner)
        return SF_ENOMEM;
    cp->n_corner = 0;
    for (int i = 0; i < c->n; i++) {
        segment_poly(c, i, cp->cx[i], cp->cy[i]);
        if (c->corner[i])
            cp->corner[cp->n_corner++] = c->u[i];
    }
    return 0;
}

void curve_poly_free(struct curve_poly *cp)
{
    free(cp->cx);
    free(cp->cy);
    free(cp->own_u);
    free(cp->corner);
}

/* Value and u-derivative of the curve at u in [0, 1], given its segment i (u in [u_i, u_{i+1}],
 * with the wrap segment n-1 also covering [0, u_0] one turn back). */
void curve_poly_at(const struct curve_poly *cp, int i, double u, double *x, double *y, double *xu, double *yu)
{
    double u0 = cp->u[i], u1 = i + 1 < cp->n ? cp->u[i + 1] : cp->u[0] + 1.0;
    if (u < u0)
        u += 1.0;
    double h = u1 - u0, t = (u - u0) / h;
    const double *a = cp->cx[i], *b = cp->cy[i];
    *x = a[0] + t * (a[1] + t * (a[2] + t * a[3]));
    *y = b[0] + t * (b[1] + t * (b[2] + t * b[3]));
    *xu = (a[1] + t * (2 * a[2] + t * 3 * a[3])) / h;
    *yu = (b[1] + t * (2 * b[2] + t * 3 * b[3])) / h;
}

/* The segment holding u (just after a breakpoint, so pieces never straddle one). */
int curve_poly_segment(const struct curve_poly *cp, double u)
{
    int i = segment_at(cp->u, cp->n, u);
    return i < 0 ? cp->n - 1 : i; /* below u_0: the wrap segment */
}

/* ---- fewer knots ----
 * A curve has a breakpoint at every point of its contour, and a slice pair's surface breaks at the
 * merged breakpoints of the four curves it reads: on the heart, 19 014 patches whose median is
 * 0.34 mm wide along the contour (a tenth under 0.06 mm, where the points of four contours fall
 * close) and 3.9 mm between slices, each a leaf or more for the tracer and a record for /patches.
 * Ours (the seeds are silent): each curve is redrawn on dyadic knots (FIT_START pieces, each
 * halved until it holds), cubic Hermite pieces through the curve's own points and derivatives at
 * the knots (so C1 as the curve is), within MODEL_FIT_REL of the contour's extent of the curve
 * (measured at its breakpoints in the piece and between them). Dyadic knots of four curves merge
 * into pieces no narrower than the finest of them: the heart's model has 7 838 patches, none a
 * sliver, and renders 2.9x as fast. A piece holding no breakpoint of the curve is one of its
 * cubics, which its Hermite piece equals, so halving ends there; a curve that would take more
 * than FIT_MAX_KNOTS (breakpoints a hair apart) keeps its own. Every method and the closed-form volume read the redrawn
 * curves, so a model's volume and its patches agree to rounding as before; the volumes move by
 * about 1e-6 of themselves (the heart +0.59 mm3 of 434 480). */
#define FIT_MIN_PIECE 1e-7 /* of a turn: no piece is halved below this */

/* The curve's knot at u; arriving: with the derivative of the piece ending there (at a corner, the
 * other side's). */
static struct knot knot_side(const struct curve_poly *c, double u, bool arriving)
{
    struct knot k = {.u = u};
    double w = u >= 1.0 ? u - 1.0 : u;
    int i = curve_poly_segment(c, w);
    curve_poly_at(c, arriving ? (i + c->n - 1) % c->n : i, w, &k.x, &k.y, &k.xu, &k.yu);
    return k;
}

struct knot knot_at(const struct curve_poly *c, double u) { return knot_side(c, u, false); }

static double warp_at(const struct warp *w, double u, double *slope)
{
    double s = u - w->w0;
    s -= floor(s);
    if (s >= w->len)
        return u;
    double x = s / w->len * (w->n - 1);
    int i = x >= w->n - 1 ? w->n - 2 : (int)x;
    double t = x - i, h = 1.0 / (w->n - 1), y0 = w->y[i], y1 = w->y[i + 1], m0 = w->d[i] * h, m1 = w->d[i + 1] * h;
    double t2 = t * t, t3 = t2 * t;
    double y = (2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * m0 + (-2 * t3 + 3 * t2) * y1 + (t3 - t2) * m1;
    *slope *= ((6 * t2 - 6 * t) * y0 + (3 * t2 - 4 * t + 1) * m0 + (-6 * t2 + 6 * t) * y1 + (3 * t2 - 2 * t) * m1) / h;
    return w->w0 + w->len * y;
}

/* Where warp w takes v from (warp_at's inverse, by bisection: it is monotone), in [0, 1). */
static double warp_from(const struct warp *w, double v)
{
    double s = v - w->w0, slope = 1.0;
    s -= floor(s);
    if (s >= w->len)
        return v - floor(v);
    double lo = 0.0, hi = w->len;
    for (int it = 0; it < 64; it++) {
        double mid = 0.5 * (lo + hi);
        if (warp_at(w, w->w0 + mid, &slope) - w->w0 < s)
            lo = mid;
        else
            hi = mid;
    }
    double u = w->w0 + 0.5 * (lo + hi);
    return u - floor(u);
}

/* The source's knot at u. At one of its curve's corners (at: the corner's u on that curve, else
 * NAN; the warps' rounding would miss it), the derivative leaving it, or arriving with arriving. */
static struct knot src_knot(const struct redraw_src *s, double u, double at, bool arriving)
{
    double slope = 1.0, v = u;
    for (int i = s->n_w - 1; i >= 0; i--)
        v = warp_at(&s->w[i], v, &slope);
    struct knot k = knot_side(s->c, isnan(at) ? v - floor(v) : at, arriving && !isnan(at));
    k.u = u, k.xu *= slope, k.yu *= slope;
    return k;
}


/* Whether the curve and its Hermite piece over [u0, u1] are within tol2 (squared): so when no
 * breakpoint of the curve lies inside (the piece is one of its cubics, which the Hermite piece
 * equals), else as measured at those breakpoints and at the quarters between them (stopping at
 * the first sample beyond). A warped curve is no cubic anywhere: measured at the piece's eighths. */
static bool piece_holds(const struct redraw_src *src, double u0, double u1, const double hx[4], const double hy[4],
                        double tol2)
{
    const struct curve_poly *c = src->c;
    double h = u1 - u0;
    if (src->n_w) {
        for (int q = 1; q < 8; q++) {
            struct knot k = src_knot(src, u0 + h * q / 8.0, NAN, false);
            double t = q / 8.0, ex = hx[0] + t * (hx[1] + t * (hx[2] + t * hx[3])) - k.x;
            double ey = hy[0] + t * (hy[1] + t * (hy[2] + t * hy[3])) - k.y;
            if (ex * ex + ey * ey > tol2)
                return false;
        }
        return true;
    }
    int i = segment_at(c->u, c->n, u0) + 1; /* the first breakpoint past u0 */
    if (i >= c->n || c->u[i] >= u1)
        return true;
    double prev = u0;
    for (;; i++) {
        double b = i < c->n && c->u[i] < u1 ? c->u[i] : u1;
        int seg = i > 0 ? i - 1 : c->n - 1; /* the segment [prev, b] lies in */
        for (int q = 1; q <= 4; q++) { /* its quarters, and b when it is a breakpoint */
            double u = q < 4 ? prev + (b - prev) * q / 4 : b, t = (u - u0) / h, x, y, xu, yu;
            if (q == 4 && b >= u1)
                break;
            curve_poly_at(c, q < 4 ? seg : i, u, &x, &y, &xu, &yu);
            double ex = hx[0] + t * (hx[1] + t * (hx[2] + t * hx[3])) - x;
            double ey = hy[0] + t * (hy[1] + t * (hy[2] + t * hy[3])) - y;
            if (ex * ex + ey * ey > tol2)
                return false;
        }
        if (b >= u1)
            return true;
        prev = b;
    }
}

/* MODEL_FIT_REL of the curve's extent. */
double curve_tol(const struct curve_poly *c)
{
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (int i = 0; i < c->n; i++) {
        lo[0] = fmin(lo[0], c->cx[i][0]), hi[0] = fmax(hi[0], c->cx[i][0]);
        lo[1] = fmin(lo[1], c->cy[i][0]), hi[1] = fmax(hi[1], c->cy[i][0]);
    }
    return MODEL_FIT_REL * fmax(hi[0] - lo[0], hi[1] - lo[1]);
}

/* The coarsest dyadic point inside (a, b): the midpoint of a piece cut evenly, the knot other
 * curves are most likely to share in one cut at a corner. */
static double dyadic_between(double a, double b)
{
    for (double scale = 2.0; scale < 0x1p52; scale *= 2.0) {
        double m = (floor(a * scale) + 1.0) / scale;
        if (m < b)
            return m;
    }
    return 0.5 * (a + b);
}

/* Draws src on dyadic knots (above) within tol into *out (zeroed; the caller frees it). 0, SF_ENOMEM,
 * or SF_ELIMIT when that takes more than cap knots. */
int curve_redraw(const struct redraw_src *src, double tol, size_t cap, struct curve_poly *out)
{
    /* depth first: a stack of pieces still to check (one more than the knots allowed: a split
     * adds one), the accepted ones in order with their Hermite pieces */
    struct knot(*stack)[2] = malloc(sizeof *stack * (cap + 1)); /* (each knot read once) */
    *out = (struct curve_poly){.own_u = malloc(sizeof *out->own_u * cap), .cx = malloc(sizeof *out->cx * cap),
                               .cy = malloc(sizeof *out->cy * cap)};
    if (!stack || !out->own_u || !out->cx || !out->cy) {
        free(stack);
        return SF_ENOMEM;
    }
    /* the first pieces: FIT_START even ones, cut at the curve's corners too (knots fall there, each
     * piece ending with the derivative arriving at its end) */
    const struct curve_poly *c = src->c;
    size_t nk = 0, ns = 0, n_cut = 0;
    double(*cut)[2] = malloc(sizeof *cut * (size_t)(FIT_START + 1 + c->n_corner)); /* u, the corner's on c */
    out->corner = malloc(sizeof *out->corner * (size_t)(c->n_corner + 1));
    if (!cut || !out->corner) {
        free(stack), free(cut);
        return SF_ENOMEM;
    }
    for (int k = 0; k <= FIT_START; k++)
        cut[n_cut][0] = (double)k / FIT_START, cut[n_cut++][1] = NAN;
    for (int k = 0; k < c->n_corner; k++) {
        double u = c->corner[k];
        for (int i = 0; i < src->n_w; i++)
            u = warp_from(&src->w[i], u);
        u = u > 1.0 - BREAK_EPS ? 0.0 : u; /* (the warps' rounding) */
        cut[n_cut][0] = u, cut[n_cut++][1] = c->corner[k];
        out->corner[out->n_corner++] = u;
    }
    qsort(cut, n_cut, sizeof *cut, cmp_double); /* (by u: the first of each pair) */
    qsort(out->corner, (size_t)out->n_corner, sizeof *out->corner, cmp_double);
    size_t kept = 0; /* one cut where a corner falls on an even one, keeping the corner */
    for (size_t k = 0; k < n_cut; k++)
        if (kept && cut[k][0] - cut[kept - 1][0] <= BREAK_EPS)
            cut[kept - 1][1] = isnan(cut[kept - 1][1]) ? cut[k][1] : cut[kept - 1][1];
        else
            cut[kept][0] = cut[k][0], cut[kept][1] = cut[k][1], kept++;
    n_cut = kept;
    cut[n_cut - 1][1] = cut[0][1]; /* (u 1 is u 0) */
    struct knot next = src_knot(src, 1.0, cut[n_cut - 1][1], true);
    for (size_t k = n_cut - 1; k-- > 0; ns++) {
        stack[ns][1] = next;
        stack[ns][0] = src_knot(src, cut[k][0], cut[k][1], false);
        next = isnan(cut[k][1]) ? stack[ns][0] : src_knot(src, cut[k][0], cut[k][1], true);
    }
    free(cut);
    while (ns && nk + ns <= cap) {
        struct knot a = stack[ns - 1][0], b = stack[ns - 1][1];
        double hx[4], hy[4];
        ns--;
        hermite_piece(&a, &b, hx, hy);
        if (b.u - a.u <= FIT_MIN_PIECE || piece_holds(src, a.u, b.u, hx, hy, tol * tol)) {
            out->own_u[nk] = a.u;
            memcpy(out->cx[nk], hx, sizeof hx), memcpy(out->cy[nk], hy, sizeof hy);
            nk++;
        } else {
            struct knot m = src_knot(src, dyadic_between(a.u, b.u), NAN, false);
            stack[ns][0] = m, stack[ns][1] = b, ns++;
            stack[ns][0] = a, stack[ns][1] = m, ns++;
        }
    }
    free(stack);
    out->n = (int)nk, out->u = out->own_u;
    return ns ? SF_ELIMIT : 0;
}

/* Redraws curve c on dyadic knots (above) within MODEL_FIT_REL of its extent, unless that takes
 * more than FIT_MAX_KNOTS, or a curve of fewer pieces than FIT_START would take no fewer (then c
 * stays). 0 or SF_ENOMEM. */
int curve_refit(struct curve_poly *c)
{
    struct curve_poly out;
    int rc = curve_redraw(&(struct redraw_src){c, NULL, 0}, curve_tol(c), FIT_MAX_KNOTS(c->n), &out);
    if (rc || (c->n < FIT_START && out.n >= c->n)) { /* (a sparse polygon's pieces stay as they are) */
        curve_poly_free(&out);
        return rc == SF_ELIMIT ? 0 : rc;
    }
    curve_poly_free(c);
    *c = out;
    return 0;
}

int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The slices pair (k, k+1) of n reads, first to last: k-1 to k+2 where they exist; a ruled pair
 * (curves_unfold) its own two alone. */
void pair_reads(int n, int k, bool ruled, int *first, int *last)
{
    *first = k > 0 && !ruled ? k - 1 : k;
    *last = k + 2 < n && !ruled ? k + 2 : k + 1;
}

/* Weights of the slices at hand at height z, for the pair (k, k+1): the surface point is the sum
 * of weight_j C_j(u), since every blend is linear in the values. m receives the slice count. A
 * ruled pair reads its own two slices, linearly. */
void slice_weights(const struct contour_set *cs, bool lsq, bool ruled, int k, double z, double w[4], int *j0,
                   int *m)
{
    int first, last;
    pair_reads(cs->n_slices, k, ruled, &first, &last);
    double zs[4];
    *j0 = first;
    *m = last - first + 1;
    for (int j = 0; j < *m; j++)
        zs[j] = cs->s[first + j].z;
    for (int j = 0; j < *m; j++) { /* the blend of unit data at slice j */
        double v[4] = {0, 0, 0, 0};
        v[j] = 1.0;
        if (*m == 4)
            w[j] = blend(lsq, z, zs, v);
        else if (*m == 3) /* an end pair: the one local fit there is */
            w[j] = local_fit(lsq, z, zs, v);
        else /* two slices in all */
            w[j] = j == 0 ? (zs[1] - z) / (zs[1] - zs[0]) : (z - zs[0]) / (zs[1] - zs[0]);
    }
}

void pair_nets_free(struct pair_nets *pn)
{
    free(pn->brk);
    free(pn->u);
    free(pn->net);
}

/* Pair k's nets (parabolic or linear-parabolic, eq. 32 in both directions): on a piece [ua, ub]
 * between the merged breakpoints of the curves pair k depends on, the surface is sum_j w_j(z) C_j(u)
 * with each C_j a cubic in u and each w_j a cubic in z, so its Bézier points are sum_j C_j[a] W_j[b]:
 * the curves' Bézier points on the piece (from their values and derivatives at the ends) times the
 * weights' Bernstein coefficients over the pair. 0 or SF_ENOMEM. */
int pair_nets(const struct contour_set *cs, bool lsq, bool ruled, const struct curve_poly *cp, int k,
              struct pair_nets *pn)
{
    /* a cubic's samples at t = 0, 1/3, 2/3, 1 to its Bernstein coefficients */
    static const double INV[4][4] = {
        {1, 0, 0, 0}, {-5.0 / 6, 3, -1.5, 1.0 / 3}, {1.0 / 3, -1.5, 3, -5.0 / 6}, {0, 0, 0, 1}};
    int j0, j1;
    pair_reads(cs->n_slices, k, ruled, &j0, &j1);
    size_t nb = 2;
    for (int j = j0; j <= j1; j++)
        nb += (size_t)cp[j].n;
    if (mem_reserve((void **)&pn->brk, &pn->cap_brk, nb, sizeof *pn->brk) ||
        mem_reserve((void **)&pn->u, &pn->cap_u, nb, sizeof *pn->u) ||
        mem_reserve((void **)&pn->net, &pn->cap_net, nb, sizeof *pn->net))
        return SF_ENOMEM;
    /* the curves' breakpoints merged (each list increasing), with 0 and 1 */
    int next[4] = {0, 0, 0, 0};
    nb = 0;
    pn->brk[nb++] = 0.0;
    for (;;) {
        int at = -1;
        for (int j = j0; j <= j1; j++)
            if (next[j - j0] < cp[j].n && (at < 0 || cp[j].u[next[j - j0]] < cp[at].u[next[at - j0]]))
                at = j;
        if (at < 0)
            break;
        pn->brk[nb++] = cp[at].u[next[at - j0]++];
    }
    pn->brk[nb++] = 1.0;
    double z0 = cs->s[k].z, z1 = cs->s[k + 1].z, wz[4][4], W[4][4] = {{0}};
    int m = 0;
    for (int c = 0; c < 4; c++) /* the slice weights at the four z samples ... */
        slice_weights(cs, lsq, ruled, k, z0 + (z1 - z0) * c / 3.0, wz[c], &j0, &m);
    for (int j = 0; j < m; j++) /* ... as Bernstein coefficients W[j][b] */
        for (int b = 0; b < 4; b++)
            for (int c = 0; c < 4; c++)
                W[j][b] += INV[b][c] * wz[c][j];
    int at[4] = {-1, -1, -1, -1}; /* each curve's last breakpoint at or before the piece (segment_at) */
    pn->n = 0;
    for (size_t q = 0; q + 1 < nb; q++) {
        double ua = pn->brk[q], ub = pn->brk[q + 1], h = ub - ua;
        if (h <= BREAK_EPS)
            continue;
        double C[4][4][2], mid = 0.5 * (ua + ub); /* curve j's Bézier points on the piece */
        for (int j = 0; j < m; j++) {
            const struct curve_poly *c = &cp[j0 + j];
            while (at[j] + 1 < c->n && c->u[at[j] + 1] <= mid)
                at[j]++;
            int seg = at[j] < 0 ? c->n - 1 : at[j]; /* (curve_poly_segment, walked) */
            double xa, ya, xua, yua, xb, yb, xub, yub;
            curve_poly_at(c, seg, ua, &xa, &ya, &xua, &yua);
            curve_poly_at(c, seg, ub, &xb, &yb, &xub, &yub);
            C[j][0][0] = xa, C[j][0][1] = ya;
            C[j][1][0] = xa + h * xua / 3, C[j][1][1] = ya + h * yua / 3;
            C[j][2][0] = xb - h * xub / 3, C[j][2][1] = yb - h * yub / 3;
            C[j][3][0] = xb, C[j][3][1] = yb;
        }
        double(*P)[4][2] = pn->net[pn->n];
        for (int a = 0; a < 4; a++)
            for (int b = 0; b < 4; b++) {
                P[a][b][0] = P[a][b][1] = 0.0;
                for (int j = 0; j < m; j++)
                    P[a][b][0] += C[j][a][0] * W[j][b], P[a][b][1] += C[j][a][1] * W[j][b];
            }
        pn->u[pn->n][0] = ua, pn->u[pn->n][1] = ub;
        pn->n++;
    }
    return 0;
}

