/* model.c - the parabolic contour surface and the volume integral.
 *
 * Each contour becomes a closed curve C(u), u in [0,1), through all its points, parameterised by
 * chord length from where the +x ray out of its centroid crosses it, so that u = 0 lines up from
 * slice to slice whatever the start points of the data (no twist). Between points i and i+1 the
 * curve blends the parabolas through points i-1..i+1 and i..i+2 (eq. 32): a cubic. Across slices
 * the same blend runs at fixed u over the slices' z. On the merged breakpoints of the (up to) four
 * curves a slice pair depends on, every piece is bicubic, so it is converted exactly: sampled on a
 * 4x4 grid and solved against the Bernstein basis. Polar parameterisation (seed 004 eq. 1–5) is
 * not used yet: chord length is robust but lines up less well on strongly non-convex shapes. */
#include "model.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/clock.h"
#include "../base/gauss.h"
#include "../base/mem.h"

#define BREAK_EPS 1e-12 /* breakpoints closer than this in u are one */

struct curve {
    bool lsq;        /* linear-parabolic: least-squares lines instead of parabolas */
    int n;
    double (*p)[2];  /* points, rotated so that u increases from index 0 */
    double *u;       /* parameters in [0, 1), increasing */
};

static void curve_free(struct curve *c)
{
    free(c->p);
    free(c->u);
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

/* Builds the curve of slice s: parameters from the +x crossing of the centroid's ray, by arc length
 * (the default), or polar (seed 004) where the contour winds round its centroid. */
static int curve_build(const struct contour_slice *s, bool lsq, bool polar, struct curve *c)
{
    int n = s->n;
    c->lsq = lsq;
    c->n = n;
    c->p = malloc(sizeof *c->p * (size_t)n);
    c->u = malloc(sizeof *c->u * (size_t)n);
    double *len = malloc(sizeof *len * (size_t)(n + 1));
    if (!c->p || !c->u || !len) {
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
    return 0;
}

/* Parameter and point of index i, any integer (periodic: one turn adds 1 to u). */
static double cu(const struct curve *c, int i, double *x, double *y)
{
    int n = c->n, k = ((i % n) + n) % n, turns = (i - k) / n;
    *x = c->p[k][0];
    *y = c->p[k][1];
    return c->u[k] + turns;
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

/* The curve at u in [0, 1]. */
static void curve_eval(const struct curve *c, double u, double *x, double *y)
{
    /* segment i: u_i <= u < u_{i+1} (periodic; u below u_0 belongs to the segment from the last
     * point, i = -1) */
    int i = segment_at(c->u, c->n, u);
    double ts[4], xs[4], ys[4];
    for (int k = 0; k < 4; k++)
        ts[k] = cu(c, i - 1 + k, &xs[k], &ys[k]);
    *x = blend(c->lsq, u, ts, xs);
    *y = blend(c->lsq, u, ts, ys);
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
    double(*p)[2] = malloc(sizeof *p * (size_t)n), *u = malloc(sizeof *u * (size_t)n);
    if (!p || !u) { /* (left as it was) */
        free(p), free(u);
        return;
    }
    for (int k = 0; k < n; k++) {
        int i = (first + k) % n;
        p[k][0] = c->p[i][0], p[k][1] = c->p[i][1];
        u[k] = c->u[i] - d;
        u[k] -= floor(u[k]);
    }
    free(c->p), free(c->u);
    c->p = p, c->u = u;
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
static int curves_build(const struct contour_set *cs, bool lsq, bool polar, struct curve *cv)
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

/* Power-basis cubic per segment i of a curve, in t = (u - u_i) / (u_{i+1} - u_i). */
struct curve_poly {
    int n;
    const double *u;     /* borrowed from the curve, or own_u; u_n = u_0 + 1 */
    double (*cx)[4], (*cy)[4];
    double *own_u;       /* its own knots, when redrawn (curve_refit) */
};

static int curve_poly_build(const struct curve *c, struct curve_poly *cp)
{
    /* the inverse Vandermonde of t = 0, 1/3, 2/3, 1 maps samples to coefficients */
    static const double VINV[4][4] = {{1, 0, 0, 0}, {-5.5, 9, -4.5, 1}, {9, -22.5, 18, -4.5}, {-4.5, 13.5, -13.5, 4.5}};
    cp->n = c->n;
    cp->u = c->u;
    cp->cx = malloc(sizeof *cp->cx * (size_t)c->n);
    cp->cy = malloc(sizeof *cp->cy * (size_t)c->n);
    if (!cp->cx || !cp->cy)
        return SF_ENOMEM;
    for (int i = 0; i < c->n; i++) {
        double ts[4], xs[4], ys[4], sx[4], sy[4]; /* (curve_eval on segment i, whose u may run past 1) */
        for (int k = 0; k < 4; k++)
            ts[k] = cu(c, i - 1 + k, &xs[k], &ys[k]);
        for (int a = 0; a < 4; a++) {
            double u = ts[1] + (ts[2] - ts[1]) * a / 3.0;
            sx[a] = blend(c->lsq, u, ts, xs), sy[a] = blend(c->lsq, u, ts, ys);
        }
        for (int k = 0; k < 4; k++) {
            cp->cx[i][k] = cp->cy[i][k] = 0;
            for (int a = 0; a < 4; a++)
                cp->cx[i][k] += VINV[k][a] * sx[a], cp->cy[i][k] += VINV[k][a] * sy[a];
        }
    }
    return 0;
}

static void curve_poly_free(struct curve_poly *cp)
{
    free(cp->cx);
    free(cp->cy);
    free(cp->own_u);
}

/* Value and u-derivative of the curve at u in [0, 1], given its segment i (u in [u_i, u_{i+1}],
 * with the wrap segment n-1 also covering [0, u_0] one turn back). */
static void curve_poly_at(const struct curve_poly *cp, int i, double u, double *x, double *y, double *xu, double *yu)
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
static int curve_poly_segment(const struct curve_poly *cp, double u)
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
 * into pieces no narrower than the finest of them: the heart's model has 7 726 patches, none a
 * sliver, and renders 2.9x as fast. A piece holding no breakpoint of the curve is one of its
 * cubics, which its Hermite piece equals, so halving ends there; a curve that would take more
 * than FIT_MAX_KNOTS (breakpoints a hair apart) keeps its own. Every method and the closed-form volume read the redrawn
 * curves, so a model's volume and its patches agree to rounding as before; the volumes move by
 * about 1e-6 of themselves (the heart +0.59 mm3 of 434 480). */
#define FIT_START 16       /* pieces to begin with */
#define FIT_MIN_PIECE 1e-7 /* of a turn: no piece is halved below this */
#define FIT_MAX_KNOTS(n) (2 * (size_t)(n) + FIT_START) /* (the heart's curves take 1.1 to 1.5 n) */
#define WARP_MAX_KNOTS(n) (2 * FIT_MAX_KNOTS(n)) /* a warped curve's (curves_unfold) */

/* A knot of the redrawn curve: the curve's value and u-derivative there (the turn's end, u = 1,
 * read at its start). */
struct knot {
    double u, x, y, xu, yu;
};

static struct knot knot_at(const struct curve_poly *c, double u)
{
    struct knot k = {.u = u};
    double w = u >= 1.0 ? u - 1.0 : u;
    curve_poly_at(c, curve_poly_segment(c, w), w, &k.x, &k.y, &k.xu, &k.yu);
    return k;
}

/* A warp of a curve's parameter (curves_unfold): u -> φ(u) over a window [w0, w0 + len] of the turn
 * (mod 1), the identity elsewhere; φ is the monotone cubic Hermite through n nodes at even steps s of
 * the window, y and d its value and slope there (in the window's own [0, 1]; d = 1 at both ends, so
 * it joins the identity C1). */
struct warp {
    double w0, len;
    int n;
    double *y, *d;
};

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

/* A curve to redraw: c read at Φ(u) = w[0](w[1](... w[n_w - 1](u))), or as it is (n_w 0). */
struct redraw_src {
    const struct curve_poly *c;
    const struct warp *w;
    int n_w;
};

static struct knot src_knot(const struct redraw_src *s, double u)
{
    if (!s->n_w)
        return knot_at(s->c, u);
    double slope = 1.0, v = u;
    for (int i = s->n_w - 1; i >= 0; i--)
        v = warp_at(&s->w[i], v, &slope);
    struct knot k = knot_at(s->c, v - floor(v));
    k.u = u, k.xu *= slope, k.yu *= slope;
    return k;
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
            struct knot k = src_knot(src, u0 + h * q / 8.0);
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
static double curve_tol(const struct curve_poly *c)
{
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (int i = 0; i < c->n; i++) {
        lo[0] = fmin(lo[0], c->cx[i][0]), hi[0] = fmax(hi[0], c->cx[i][0]);
        lo[1] = fmin(lo[1], c->cy[i][0]), hi[1] = fmax(hi[1], c->cy[i][0]);
    }
    return MODEL_FIT_REL * fmax(hi[0] - lo[0], hi[1] - lo[1]);
}

/* Draws src on dyadic knots (above) within tol into *out (zeroed; the caller frees it). 0, SF_ENOMEM,
 * or SF_ELIMIT when that takes more than cap knots. */
static int curve_redraw(const struct redraw_src *src, double tol, size_t cap, struct curve_poly *out)
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
    size_t nk = 0, ns = 0;
    struct knot next = src_knot(src, 1.0);
    for (int k = FIT_START - 1; k >= 0; k--, ns++)
        stack[ns][1] = next, stack[ns][0] = next = src_knot(src, (double)k / FIT_START);
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
            struct knot m = src_knot(src, 0.5 * (a.u + b.u));
            stack[ns][0] = m, stack[ns][1] = b, ns++;
            stack[ns][0] = a, stack[ns][1] = m, ns++;
        }
    }
    free(stack);
    out->n = (int)nk, out->u = out->own_u;
    return ns ? SF_ELIMIT : 0;
}

/* Redraws curve c on dyadic knots (above) within MODEL_FIT_REL of its extent, unless that takes
 * more than FIT_MAX_KNOTS (then c stays). 0 or SF_ENOMEM. */
static int curve_refit(struct curve_poly *c)
{
    struct curve_poly out;
    int rc = curve_redraw(&(struct redraw_src){c, NULL, 0}, curve_tol(c), FIT_MAX_KNOTS(c->n), &out);
    if (rc) {
        curve_poly_free(&out);
        return rc == SF_ELIMIT ? 0 : rc;
    }
    curve_poly_free(c);
    *c = out;
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The slices pair (k, k+1) of n reads, first to last: k-1 to k+2 where they exist; a ruled pair
 * (curves_unfold) its own two alone. */
static void pair_reads(int n, int k, bool ruled, int *first, int *last)
{
    *first = k > 0 && !ruled ? k - 1 : k;
    *last = k + 2 < n && !ruled ? k + 2 : k + 1;
}

/* Weights of the slices at hand at height z, for the pair (k, k+1): the surface point is the sum
 * of weight_j C_j(u), since every blend is linear in the values. m receives the slice count. A
 * ruled pair reads its own two slices, linearly. */
static void slice_weights(const struct contour_set *cs, bool lsq, bool ruled, int k, double z, double w[4], int *j0,
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

/* A slice pair's side surface as Bézier nets in (x, y), z being linear in v: one for each piece
 * between the merged breakpoints of the (up to) four curves the pair reads, in increasing u. */
struct pair_nets {
    size_t n, cap_u, cap_net, cap_brk;
    double *brk;            /* the merged breakpoints (scratch) */
    double (*u)[2];         /* each piece's [ua, ub] */
    double (*net)[4][4][2]; /* its points [a along u][b along z] */
};

static void pair_nets_free(struct pair_nets *pn)
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
static int pair_nets(const struct contour_set *cs, bool lsq, bool ruled, const struct curve_poly *cp, int k,
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

/* ---- folds ----
 * Where the contours of two levels are unlike (a slit in one that the other lacks, a bay that
 * becomes a hole), the side surface between them may pass through itself: two parts of one section
 * z = const cross. The seeds are silent; ours: each pair's surface is checked for it (pair_folds)
 * and where it folds, the parameters of every curve above are warped over a window round the fold
 * so that the upper curve's points pair with the nearest of the lower's (curves_unfold). The
 * surfaces above keep their shape, since all their curves move alike; the curves are redrawn on
 * dyadic knots as before, so the volume and the patches still read the same curves. Where no warp
 * folds the pair less, it is drawn ruled (its two curves blended linearly, no overshoot from the
 * neighbours' curves: the dicompyler BODY's neck to a skin marker), if that folds it less.
 *
 * The check: at a fixed z the section sum_j w_j C_j(u) is a curve; two pieces of it can only meet
 * where their nets' boxes (in x, y, over the pair's z) overlap. Pieces along a stretch whose
 * tangents all lie within 90 degrees of one direction (the nets' u-differences bound them) cannot
 * meet each other at any z: a section is monotone along that direction there. The rest whose boxes
 * overlap are cut at FOLD_HEIGHTS heights, each section drawn as FOLD_CHORDS chords, and their
 * chords that cross are counted: the measure of a fold; so are a piece's own chords, where its
 * tangents turn half a turn or more, and a piece's against the next one's, where the two make no
 * monotone stretch (a loop within neighbours). (Splitting the nets until their boxes part
 * proves more but costs without bound where two sheets run close for long, as a slit's sides do.) */
#define FOLD_HEIGHTS 32
#define FOLD_CHORDS 8
#define FOLD_NEAR 2e-3 /* of the chain's extent: sections this close count as folding, but for finding them */
#define FOLD_MAX_SECTIONS 4096 /* pieces a pair's check draws sections of (4.6 kB each) */
#define FOLD_MAX_TESTS 2000000 /* pairs of boxes it compares (a contour drawn along one line a thousand
                                 * times over would have every pair's boxes overlap): past it, no fold */
#define FOLD_SPOTS 64          /* where the folds are: the pieces' middles kept for the warp's window */

typedef double net_t[4][4][2];

struct by_x {
    double x0;
    size_t i;
};

static int cmp_by_x(const void *a, const void *b)
{
    double x = ((const struct by_x *)a)->x0, y = ((const struct by_x *)b)->x0;
    return (x > y) - (x < y);
}

typedef double section_t[FOLD_HEIGHTS][FOLD_CHORDS + 1][2]; /* a piece's sections (net_section) */

struct fold_scratch {
    size_t cap;                /* pieces the arrays hold */
    double (*box)[4];          /* each piece's box: x0 x1 y0 y1 */
    struct by_x *order;        /* pieces by x0 */
    double *ang, *half;        /* each piece's tangent direction (unwrapped) and cone half-angle */
    size_t *reach;             /* the last piece (unwrapped index) of a monotone stretch from each */
    size_t *dq;                /* (deques of the sliding extremes) */
    int *slot;                 /* each piece's sections in sec and sbox, or -1 (pieces_cross) */
    size_t n_slots, cap_sec, cap_sbox;
    section_t *sec;
    double (*sbox)[FOLD_HEIGHTS][4];
};

static void fold_scratch_free(struct fold_scratch *f)
{
    free(f->box), free(f->order), free(f->ang), free(f->half), free(f->reach), free(f->dq), free(f->slot), free(f->sec),
        free(f->sbox);
}

static void net_box(net_t N, double b[4])
{
    b[0] = b[2] = INFINITY, b[1] = b[3] = -INFINITY;
    for (int a = 0; a < 4; a++)
        for (int c = 0; c < 4; c++) {
            b[0] = dmin(b[0], N[a][c][0]), b[1] = dmax(b[1], N[a][c][0]);
            b[2] = dmin(b[2], N[a][c][1]), b[3] = dmax(b[3], N[a][c][1]);
        }
}

static bool boxes_apart(const double a[4], const double b[4])
{
    return a[0] > b[1] || b[0] > a[1] || a[2] > b[3] || b[2] > a[3];
}

/* The section of net N at t as FOLD_CHORDS chords (FOLD_CHORDS + 1 points), and their box. */
static void net_section(net_t N, double t, double (*pt)[2], double box[4])
{
    const double s = 1.0 - t, B[4] = {s * s * s, 3 * s * s * t, 3 * s * t * t, t * t * t};
    double Q[4][2];
    for (int a = 0; a < 4; a++)
        for (int d = 0; d < 2; d++)
            Q[a][d] = B[0] * N[a][0][d] + B[1] * N[a][1][d] + B[2] * N[a][2][d] + B[3] * N[a][3][d];
    box[0] = box[2] = INFINITY, box[1] = box[3] = -INFINITY;
    for (int c = 0; c <= FOLD_CHORDS; c++) {
        double u = (double)c / FOLD_CHORDS, v = 1.0 - u, C[4] = {v * v * v, 3 * v * v * u, 3 * v * u * u, u * u * u};
        for (int d = 0; d < 2; d++)
            pt[c][d] = C[0] * Q[0][d] + C[1] * Q[1][d] + C[2] * Q[2][d] + C[3] * Q[3][d];
        box[0] = dmin(box[0], pt[c][0]), box[1] = dmax(box[1], pt[c][0]);
        box[2] = dmin(box[2], pt[c][1]), box[3] = dmax(box[3], pt[c][1]);
    }
}

/* Squared distance from p to segment ab. */
static double point_segment2(const double p[2], const double a[2], const double b[2])
{
    double ex = b[0] - a[0], ey = b[1] - a[1], l2 = ex * ex + ey * ey;
    double t = l2 > 0 ? dmax(0.0, dmin(1.0, ((p[0] - a[0]) * ex + (p[1] - a[1]) * ey) / l2)) : 0.0;
    double dx = a[0] + t * ex - p[0], dy = a[1] + t * ey - p[1];
    return dx * dx + dy * dy;
}

/* Crossings of pieces i and j's sections at FOLD_HEIGHTS heights, their chords against each other's,
 * and with near2 > 0 chords whose ends come within sqrt(near2) of the other's; each piece's sections
 * drawn once, into a slot of f. Past FOLD_MAX_SECTIONS slots (a contour that winds back and forth
 * thousands of times) the rest are taken not to cross. With next, j follows i: the chords at the
 * point they share are not compared; i == j compares a piece's chords but neighbours. */
static long pieces_cross(net_t *net, struct fold_scratch *f, size_t i, size_t j, bool next, double near2)
{
    const bool self = i == j;
    const size_t p[2] = {i, j};
    for (int e = 0; e < 2; e++)
        if (f->slot[p[e]] < 0) {
            if (f->n_slots == FOLD_MAX_SECTIONS ||
                mem_reserve((void **)&f->sec, &f->cap_sec, f->n_slots + 1, sizeof *f->sec) ||
                mem_reserve((void **)&f->sbox, &f->cap_sbox, f->n_slots + 1, sizeof *f->sbox))
                return 0;
            for (int h = 0; h < FOLD_HEIGHTS; h++)
                net_section(net[p[e]], (h + 0.5) / FOLD_HEIGHTS, f->sec[f->n_slots][h], f->sbox[f->n_slots][h]);
            f->slot[p[e]] = (int)f->n_slots++;
        }
    const int si = f->slot[i], sj = f->slot[j];
    long n = 0;
    for (int h = 0; h < FOLD_HEIGHTS; h++) {
        if (boxes_apart(f->sbox[si][h], f->sbox[sj][h]))
            continue;
        double(*pa)[2] = f->sec[si][h], (*pb)[2] = f->sec[sj][h];
        for (int a = 0; a < FOLD_CHORDS; a++)
            for (int b = self ? a + 2 : next && a == FOLD_CHORDS - 1; b < FOLD_CHORDS; b++)
                n += contour_segments_cross(pa[a], pa[a + 1], pb[b], pb[b + 1]) ||
                     (near2 > 0 && (point_segment2(pa[a], pb[b], pb[b + 1]) < near2 ||
                                    point_segment2(pb[b], pa[a], pa[a + 1]) < near2));
    }
    return n;
}

/* For each piece i of n, the last piece (unwrapped: up to i + n - 1) of a stretch from i along
 * which the section is monotone: the pieces' tangent cones (from their nets' u-differences, every
 * stretch of z) spread over less than half a turn. */
static void monotone_reach(net_t *net, size_t n, struct fold_scratch *f)
{
    for (size_t i = 0; i < n; i++) {
        double sx = 0, sy = 0, d[12][2];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 4; b++) {
                double *v = d[a * 4 + b], l;
                v[0] = net[i][a + 1][b][0] - net[i][a][b][0], v[1] = net[i][a + 1][b][1] - net[i][a][b][1];
                if ((l = sqrt(v[0] * v[0] + v[1] * v[1])) > 0)
                    sx += v[0] / l, sy += v[1] / l;
            }
        double l = sqrt(sx * sx + sy * sy), cmin = 1.0;
        for (int q = 0; q < 12 && l > 0; q++) {
            double lv = sqrt(d[q][0] * d[q][0] + d[q][1] * d[q][1]);
            if (lv > 0)
                cmin = dmin(cmin, (d[q][0] * sx + d[q][1] * sy) / (lv * l));
        }
        /* (π/2 sqrt(1 - c) >= acos c on [0, 1]: a cone no narrower, without acos) */
        f->half[i] = l > 0 && cmin > 0 ? M_PI_2 * sqrt(1.0 - cmin) + 1e-9 : M_PI; /* M_PI: no cone */
        double a = l > 0 ? atan2(sy, sx) : 0.0;
        if (i > 0) /* unwrapped: within half a turn of the piece before */
            a += 2 * M_PI * round((f->ang[i - 1] - a) / (2 * M_PI));
        f->ang[i] = a;
    }
    /* the turn's second lap, to reach past its end: piece q + n is piece q turned by the winding */
    double shift = 2 * M_PI * round((f->ang[n - 1] - f->ang[0]) / (2 * M_PI));
    /* two pointers, with deques of the stretch's least and greatest cone edge */
    size_t *lo = f->dq, *hi = f->dq + 2 * n, lh = 0, lt = 0, hh = 0, ht = 0, j = 0;
#define ANG(q) ((q) < n ? f->ang[q] : f->ang[(q) - n] + shift)
#define HALF(q) f->half[(q) < n ? (q) : (q) - n]
    for (size_t i = 0; i < n; i++) {
        if (j < i)
            j = i, lh = lt = hh = ht = 0;
        while (lh < lt && lo[lh] < i)
            lh++;
        while (hh < ht && hi[hh] < i)
            hh++;
        for (; j < i + n; j++) { /* can piece j join? */
            if (HALF(j) >= M_PI)
                break;
            double l = ANG(j) - HALF(j), h = ANG(j) + HALF(j);
            double least = lh < lt ? fmin(l, ANG(lo[lh]) - HALF(lo[lh])) : l;
            double most = hh < ht ? fmax(h, ANG(hi[hh]) + HALF(hi[hh])) : h;
            if (most - least >= M_PI)
                break;
            while (lt > lh && ANG(lo[lt - 1]) - HALF(lo[lt - 1]) >= l)
                lt--;
            lo[lt++] = j;
            while (ht > hh && ANG(hi[ht - 1]) + HALF(hi[ht - 1]) <= h)
                ht--;
            hi[ht++] = j;
        }
        f->reach[i] = j > i ? j - 1 : i;
    }
#undef ANG
#undef HALF
}

/* How much pair pn folds: the chords that cross, and with near > 0 those within near (pieces_cross;
 * 0: none), counted until limit is reached. The middles of the pieces that count go to spots (up to
 * FOLD_SPOTS; *n_spots counts them all). SF_ENOMEM as a negative count. */
static long pair_folds(const struct pair_nets *pn, long limit, double near, struct fold_scratch *f, double *spots,
                       int *n_spots)
{
    size_t n = pn->n;
    *n_spots = 0;
    if (n < 3)
        return 0;
    if (n > f->cap) {
        fold_scratch_free(f);
        *f = (struct fold_scratch){.cap = n, .box = malloc(sizeof *f->box * n), .order = malloc(sizeof *f->order * n),
                                   .ang = malloc(sizeof *f->ang * n), .half = malloc(sizeof *f->half * n),
                                   .reach = malloc(sizeof *f->reach * n), .dq = malloc(sizeof *f->dq * 4 * n),
                                   .slot = malloc(sizeof *f->slot * n)};
        if (!f->box || !f->order || !f->ang || !f->half || !f->reach || !f->dq || !f->slot) {
            fold_scratch_free(f);
            *f = (struct fold_scratch){0};
            return SF_ENOMEM;
        }
    }
    monotone_reach(pn->net, n, f);
    for (size_t i = 0; i < n; i++)
        f->slot[i] = -1;
    f->n_slots = 0;
    struct by_x *ord = f->order;
    for (size_t i = 0; i < n; i++) {
        net_box(pn->net[i], f->box[i]);
        ord[i] = (struct by_x){f->box[i][0], i};
    }
    qsort(ord, n, sizeof *ord, cmp_by_x);
    long folds = 0, tests = FOLD_MAX_TESTS;
    /* a piece whose tangents spread over half a turn or more, against itself; one that makes no
     * monotone stretch with the next, against that (at their sections' chords alone: near sections
     * are what neighbouring chords are) */
    for (size_t i = 0; i < n; i++)
        for (int e = 0; e < 2; e++) {
            size_t j = e ? (i + 1) % n : i;
            if (e ? f->reach[i] > i : f->half[i] < M_PI_2)
                continue;
            long m = pieces_cross(pn->net, f, i, j, e, 0.0);
            if ((folds += m) >= limit)
                return folds;
        }
    for (size_t x = 0; x < n; x++)
        for (size_t y = x + 1; y < n && --tests > 0; y++) {
            size_t i = ord[x].i, j = ord[y].i;
            const double *bi = f->box[i], *bj = f->box[j];
            if (bj[0] > bi[1])
                break;
            if (i > j) {
                size_t t = i;
                i = j, j = t;
            }
            /* neighbours, and pieces of one monotone stretch, cannot cross */
            if (bi[2] > bj[3] || bj[2] > bi[3] || j - i <= 1 || i + n - j <= 1 || j <= f->reach[i] ||
                i + n <= f->reach[j])
                continue;
            long m = pieces_cross(pn->net, f, i, j, false, near * near);
            if (m > 0) {
                for (int e = 0; e < 2; e++, ++*n_spots)
                    if (*n_spots < FOLD_SPOTS)
                        spots[*n_spots] = 0.5 * (pn->u[e ? j : i][0] + pn->u[e ? j : i][1]);
                folds += m;
                if (folds >= limit)
                    return folds;
            }
        }
    return folds;
}

/* The warp: the lower curve a and the upper b sampled at UNFOLD_SAMPLES even steps over the window,
 * b's samples paired with a's by dynamic time warping (least total squared distance plus, weighed by
 * tangent_weight, h2 times the tangents' disagreement, the path monotone from the window's start to
 * its end), each of a's samples given the mean of its partners' parameters (map, in the window's
 * [0, 1]); that map smoothed over UNFOLD_SMOOTH samples, tapered into the identity at each end,
 * kept increasing, and drawn as a monotone cubic (the slopes harmonic means of the secants). */
#define UNFOLD_SAMPLES 400
#define UNFOLD_SMOOTH 3
#define UNFOLD_MIN_SLOPE 0.05

static int warp_pairing(const struct curve_poly *a, const struct curve_poly *b, double w0, double len,
                        double tangent_weight, double h2, double *map)
{
    const int N = UNFOLD_SAMPLES;
    double(*pa)[4] = malloc(sizeof *pa * N), (*pb)[4] = malloc(sizeof *pb * N), *D = malloc(sizeof *D * N * N);
    double *cnt = malloc(sizeof *cnt * N);
    if (!pa || !pb || !D || !cnt) {
        free(pa), free(pb), free(D), free(cnt);
        return SF_ENOMEM;
    }
    for (int i = 0; i < N; i++) {
        double u = w0 + len * i / (N - 1);
        struct knot ka = knot_at(a, u - floor(u)), kb = knot_at(b, u - floor(u));
        double la = hypot(ka.xu, ka.yu), lb = hypot(kb.xu, kb.yu);
        pa[i][0] = ka.x, pa[i][1] = ka.y, pa[i][2] = la > 0 ? ka.xu / la : 0, pa[i][3] = la > 0 ? ka.yu / la : 0;
        pb[i][0] = kb.x, pb[i][1] = kb.y, pb[i][2] = lb > 0 ? kb.xu / lb : 0, pb[i][3] = lb > 0 ? kb.yu / lb : 0;
    }
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            double dx = pa[i][0] - pb[j][0], dy = pa[i][1] - pb[j][1];
            double c = dx * dx + dy * dy + tangent_weight * h2 * (1.0 - pa[i][2] * pb[j][2] - pa[i][3] * pb[j][3]);
            double best = i == 0 && j == 0 ? 0.0 : INFINITY;
            if (i > 0)
                best = dmin(best, D[(i - 1) * N + j]);
            if (j > 0)
                best = dmin(best, D[i * N + j - 1]);
            if (i > 0 && j > 0)
                best = dmin(best, D[(i - 1) * N + j - 1]);
            D[i * N + j] = c + best;
        }
    for (int i = 0; i < N; i++)
        map[i] = cnt[i] = 0;
    for (int i = N - 1, j = N - 1;;) { /* back along the path */
        map[i] += j, cnt[i] += 1;
        if (i == 0 && j == 0)
            break;
        double up = i > 0 ? D[(i - 1) * N + j] : INFINITY, left = j > 0 ? D[i * N + j - 1] : INFINITY;
        double diag = i > 0 && j > 0 ? D[(i - 1) * N + j - 1] : INFINITY;
        if (diag <= up && diag <= left)
            i--, j--;
        else if (up <= left)
            i--;
        else
            j--;
    }
    for (int i = 0; i < N; i++)
        map[i] = map[i] / cnt[i] / (N - 1);
    free(pa), free(pb), free(D), free(cnt);
    return 0;
}

/* The warp over window [w0, w0 + len] from the pairing's map (warp_pairing), tapered over taper of
 * the window at each end. */
static int warp_shape(const double *map, double w0, double len, double taper, struct warp *w)
{
    const int N = UNFOLD_SAMPLES;
    *w = (struct warp){w0, len, N, malloc(sizeof *w->y * N), malloc(sizeof *w->d * N)};
    if (!w->y || !w->d)
        return SF_ENOMEM;
    for (int i = 0; i < N; i++) {
        double sum = 0.0;
        int k = 0;
        for (int q = i - UNFOLD_SMOOTH; q <= i + UNFOLD_SMOOTH; q++)
            if (q >= 0 && q < N)
                sum += map[q], k++;
        double x = (double)i / (N - 1), e = dmin(x, 1.0 - x) / taper;
        double ramp = e >= 1.0 ? 1.0 : e * e * (3 - 2 * e);
        w->y[i] = x + ramp * (sum / k - x);
    }
    const double step = UNFOLD_MIN_SLOPE / (N - 1);
    w->y[0] = 0.0, w->y[N - 1] = 1.0;
    for (int i = 1; i < N - 1; i++)
        w->y[i] = dmax(w->y[i], w->y[i - 1] + step);
    for (int i = N - 2; i > 0; i--)
        w->y[i] = dmin(w->y[i], w->y[i + 1] - step);
    w->d[0] = w->d[N - 1] = 1.0;
    for (int i = 1; i < N - 1; i++) {
        double s0 = (w->y[i] - w->y[i - 1]) * (N - 1), s1 = (w->y[i + 1] - w->y[i]) * (N - 1);
        w->d[i] = 2 * s0 * s1 / (s0 + s1);
    }
    return 0;
}

/* ---- unfolding a chain ---- */
#define UNFOLD_MAX 32   /* warps a chain may take */

struct unfold {
    const struct contour_set *cs;
    bool lsq;
    struct curve_poly *cp, *orig; /* the curves as warped, and as fitted (orig[j] set once warped) */
    int *applied;                  /* warps drawn into cp[j] */
    bool *ruled;                   /* pairs drawn ruled (the caller's, n - 1) */
    struct warp w[UNFOLD_MAX + 1];
    int w_band[UNFOLD_MAX + 1], n_w;
    double near;                   /* sections this close count as folding (pair_folds), but for finding them */
    struct pair_nets pn;
    struct fold_scratch fs;
    double spots[FOLD_SPOTS];
    int n_spots;
};

/* The warps below curve j (those of pairs under it). */
static int warps_below(const struct unfold *uf, int j)
{
    int c = 0;
    while (c < uf->n_w && uf->w_band[c] < j)
        c++;
    return c;
}

/* A copy of curve c with its own knots. */
static int curve_copy(const struct curve_poly *c, struct curve_poly *out)
{
    size_t n = (size_t)c->n;
    *out = (struct curve_poly){.n = c->n, .own_u = malloc(sizeof *out->own_u * n), .cx = malloc(sizeof *out->cx * n),
                               .cy = malloc(sizeof *out->cy * n)};
    if (!out->own_u || !out->cx || !out->cy)
        return SF_ENOMEM;
    memcpy(out->own_u, c->u, sizeof *out->own_u * n);
    memcpy(out->cx, c->cx, sizeof *out->cx * n);
    memcpy(out->cy, c->cy, sizeof *out->cy * n);
    out->u = out->own_u;
    return 0;
}

/* Curve j redrawn through the first count warps (SF_ELIMIT, the curve as it was, when that takes too
 * many knots). */
static int curve_warp(struct unfold *uf, int j, int count)
{
    if (uf->applied[j] == count)
        return 0;
    const struct curve_poly *src = uf->orig[j].cx ? &uf->orig[j] : &uf->cp[j];
    struct curve_poly out = {0};
    int rc = count ? curve_redraw(&(struct redraw_src){src, uf->w, count}, curve_tol(src),
                                  WARP_MAX_KNOTS(uf->cs->s[j].n), &out)
                   : curve_copy(src, &out);
    if (rc) {
        curve_poly_free(&out);
        return rc;
    }
    if (!uf->orig[j].cx) /* the fitted curve, kept */
        uf->orig[j] = uf->cp[j];
    else
        curve_poly_free(&uf->cp[j]);
    uf->cp[j] = out;
    uf->applied[j] = count;
    return 0;
}

/* Pair k's folds with the curves it reads drawn through the warps below each (negative: SF_*). */
static long unfold_count(struct unfold *uf, int k, bool near, long limit)
{
    int n = uf->cs->n_slices, rc = 0, j0, j1;
    if (k < 0 || k + 1 >= n)
        return 0;
    pair_reads(n, k, false, &j0, &j1); /* (warped as the blend would read them, ruled or not) */
    for (int j = j0; j <= j1 && !rc; j++)
        rc = curve_warp(uf, j, warps_below(uf, j));
    if (rc || (rc = pair_nets(uf->cs, uf->lsq, uf->ruled[k], uf->cp, k, &uf->pn)))
        return rc;
    return pair_folds(&uf->pn, limit, near ? uf->near : 0.0, &uf->fs, uf->spots, &uf->n_spots);
}

/* The window round pair k's fold spots: the shortest arc holding them all, grown by grow each way. */
static void fold_window(const struct unfold *uf, double grow, double *w0, double *len)
{
    int n = uf->n_spots < FOLD_SPOTS ? uf->n_spots : FOLD_SPOTS;
    double sp[FOLD_SPOTS];
    if (n == 0) { /* (none: the whole turn) */
        *w0 = 0.0, *len = 1.0;
        return;
    }
    memcpy(sp, uf->spots, sizeof *sp * (size_t)n);
    qsort(sp, (size_t)n, sizeof *sp, cmp_double);
    double gap = sp[0] + 1.0 - sp[n - 1];
    int at = 0; /* the arc starts after the widest gap */
    for (int i = 1; i < n; i++)
        if (sp[i] - sp[i - 1] > gap)
            gap = sp[i] - sp[i - 1], at = i;
    *len = 1.0 - gap + 2 * grow;
    *w0 = sp[at] - grow;
    if (*len >= 1.0)
        *len = 1.0;
    *w0 -= floor(*w0);
}

static void warp_free(struct warp *w)
{
    free(w->y), free(w->d);
    *w = (struct warp){0};
}

/* Pair k folds: the warp of the curves above it, among the windows and weights tried, under which
 * pairs k-1..k+1 fold least, if less than now (taken: appended to uf->w); then the pair drawn ruled
 * if that folds it less (uf->ruled[k]). */
static int unfold_pair(struct unfold *uf, int k)
{
    static const double GROW[] = {0.03, 0.06, 0.1, 0.25}, TANGENT[] = {0.0, 4.0}, TAPER[] = {0.2, 0.4};
    const int n = uf->cs->n_slices;
    long now = 0;
    for (int d = 0; d < 3; d++) { /* pairs k-1, k+1 and k, whose spots are kept */
        long c = unfold_count(uf, k + (d == 2 ? 0 : 2 * d - 1), true, LONG_MAX);
        if (c < 0)
            return (int)c;
        now += c;
    }
    double spots[FOLD_SPOTS];
    int n_spots = uf->n_spots;
    memcpy(spots, uf->spots, sizeof spots);
    double h = uf->cs->s[k + 1].z - uf->cs->s[k].z, map[UNFOLD_SAMPLES];
    struct warp best = {0};
    long least = now;
    for (size_t g = 0; g < sizeof GROW / sizeof *GROW; g++)
        for (size_t t = 0; t < sizeof TANGENT / sizeof *TANGENT; t++) {
            memcpy(uf->spots, spots, sizeof spots), uf->n_spots = n_spots;
            double w0, len;
            fold_window(uf, GROW[g], &w0, &len);
            int rc = warp_pairing(&uf->cp[k], &uf->cp[k + 1], w0, len, TANGENT[t], h * h, map);
            for (size_t tp = 0; tp < sizeof TAPER / sizeof *TAPER && !rc; tp++) {
                struct warp *w = &uf->w[uf->n_w];
                if ((rc = warp_shape(map, w0, len, TAPER[tp], w)))
                    break;
                uf->w_band[uf->n_w++] = k; /* tried: pairs k-1..k+1 under it */
                long sum = 0, c = 0;
                for (int d = 0; d < 3 && c >= 0 && sum < least; d++) /* k first: a try no better stops early */
                    if ((c = unfold_count(uf, k + (d == 2 ? -1 : d), true, least - sum)) >= 0)
                        sum += c;
                uf->n_w--;
                for (int j = k + 1; j <= k + 3 && j < n; j++) /* drawn through the try: not as the warps stand */
                    uf->applied[j] = -1;
                if (c < 0 && c != SF_ELIMIT)
                    rc = (int)c;
                else if (c >= 0 && sum < least)
                    warp_free(&best), best = *w, least = sum, *w = (struct warp){0};
                warp_free(w);
            }
            if (rc) {
                warp_free(&uf->w[uf->n_w]), warp_free(&best);
                return rc;
            }
        }
    if (best.y) {
        uf->w[uf->n_w] = best;
        uf->w_band[uf->n_w++] = k;
    }
    int rc = 0;
    for (int j = k > 0 ? k - 1 : k; j <= k + 3 && j < n && (!rc || rc == SF_ELIMIT); j++) /* as the warps now stand */
        rc = curve_warp(uf, j, warps_below(uf, j));
    if (rc && rc != SF_ELIMIT)
        return rc;
    /* the pair ruled, if that folds it less (its neighbours do not read it) */
    long blended = unfold_count(uf, k, true, LONG_MAX), ruled = 0;
    if (blended > 0) {
        uf->ruled[k] = true;
        ruled = unfold_count(uf, k, true, blended);
        uf->ruled[k] = ruled >= 0 && ruled < blended;
    }
    return blended < 0 ? (int)blended : ruled < 0 && ruled != SF_ELIMIT ? (int)ruled : 0;
}

/* Checks every pair of the chain's curves cp (n, fitted) for folds, and warps the curves above
 * those that fold where that folds them less. 0 or SF_ENOMEM. */
static int curves_unfold(const struct contour_set *cs, bool lsq, struct curve_poly *cp, bool *ruled)
{
    const int n = cs->n_slices;
    struct unfold uf = {.cs = cs, .lsq = lsq, .cp = cp, .ruled = ruled, .orig = calloc((size_t)n, sizeof *uf.orig),
                        .applied = calloc((size_t)n, sizeof *uf.applied)};
    int rc = uf.orig && uf.applied ? 0 : SF_ENOMEM;
    for (int j = 0; j < n; j++)
        uf.near = dmax(uf.near, FOLD_NEAR * curve_tol(&cp[j]) / MODEL_FIT_REL);
    for (int k = 0; k + 1 < n && !rc; k++) {
        long f = unfold_count(&uf, k, false, 1);
        if (f < 0)
            rc = (int)f;
        else if (f > 0 && uf.n_w < UNFOLD_MAX)
            rc = unfold_pair(&uf, k);
    }
    for (int j = 0; j < n && (!rc || rc == SF_ELIMIT); j++) /* (one too many knots to warp stays as it is) */
        rc = curve_warp(&uf, j, warps_below(&uf, j));
    for (int j = 0; j < n && uf.orig; j++)
        curve_poly_free(&uf.orig[j]);
    for (int i = 0; i < uf.n_w; i++)
        warp_free(&uf.w[i]);
    pair_nets_free(&uf.pn);
    fold_scratch_free(&uf.fs);
    free(uf.orig), free(uf.applied);
    return rc == SF_ELIMIT ? 0 : rc;
}

/* A chain's curves (curves_build) as the methods read them: redrawn on their knots, and unfolded
 * if asked, with the pairs to be drawn ruled (ruled[k]: pair k, k+1; NULL when not unfolded). */
struct fitted {
    int n;
    struct curve *cv;
    struct curve_poly *cp;
    bool *ruled;
};

static void fitted_free(struct fitted *f)
{
    for (int j = 0; j < f->n && f->cv && f->cp; j++)
        curve_free(&f->cv[j]), curve_poly_free(&f->cp[j]);
    free(f->cv), free(f->cp), free(f->ruled);
}

/* f's curves; the caller frees them with fitted_free, whatever the answer. 0 or SF_ENOMEM. */
static int curves_fit(const struct contour_set *cs, bool lsq, bool polar, bool unfold, struct fitted *f)
{
    int n = cs->n_slices;
    *f = (struct fitted){n, calloc((size_t)n, sizeof *f->cv), calloc((size_t)n, sizeof *f->cp),
                         unfold ? calloc((size_t)n, sizeof *f->ruled) : NULL};
    if (!f->cv || !f->cp || (unfold && !f->ruled))
        return SF_ENOMEM;
    int rc = curves_build(cs, lsq, polar, f->cv);
    for (int j = 0; j < n && !rc; j++)
        if (!(rc = curve_poly_build(&f->cv[j], &f->cp[j])))
            rc = curve_refit(&f->cp[j]);
    return rc || !unfold ? rc : curves_unfold(cs, lsq, f->cp, f->ruled);
}

static int closed_form(const struct contour_set *cs, bool lsq, const struct curve_poly *cp, const bool *ruled,
                       double *volume, double end_area[2]);

/* Parabolic or linear-parabolic (eq. 32 in both directions), exactly as bicubic patches: each pair's
 * nets (pair_nets), z linear in v; with cl, the closed form from the same curves. */
static int curve_surface(const struct contour_set *cs, bool lsq, struct model_opts o, struct patch_set *set,
                         struct model_closed *cl, struct sf_err *err)
{
    double t0 = sf_now_ms(), ends[2];
    int n = cs->n_slices;
    struct fitted f;
    struct pair_nets pn = {0};
    int rc = curves_fit(cs, lsq, o.polar, o.unfold, &f);
    if (!rc && cl && !(rc = closed_form(cs, lsq, f.cp, f.ruled, &cl->volume, ends)))
        cl->ms = sf_now_ms() - t0;
    for (int k = 0; k + 1 < n && !rc && !(rc = sf_poll(o.progress, (double)k / n, err)); k++) {
        if ((rc = pair_nets(cs, lsq, f.ruled && f.ruled[k], f.cp, k, &pn)))
            break;
        double z0 = cs->s[k].z, z1 = cs->s[k + 1].z;
        for (size_t q = 0; q < pn.n && !rc; q++) {
            if ((rc = mem_reserve((void **)&set->patches, &set->cap, set->n + 1, sizeof *set->patches)) ||
                (rc = mem_reserve((void **)&set->pool, &set->cap_pool, set->n_pool + 16, sizeof *set->pool)))
                break;
            set->patches[set->n++] = (struct patch){.p = 3, .q = 3, .cw = (double(*)[4])(uintptr_t)set->n_pool,
                                                    .u0 = pn.u[q][0], .u1 = pn.u[q][1], .v0 = z0, .v1 = z1};
            for (int a = 0; a < 4; a++)
                for (int b = 0; b < 4; b++) {
                    double *P = set->pool[set->n_pool + (size_t)(a * 4 + b)];
                    P[0] = pn.net[q][a][b][0], P[1] = pn.net[q][a][b][1];
                    P[2] = z0 + (z1 - z0) * b / 3.0; /* z is linear in v */
                    P[3] = 1.0;
                }
            set->n_pool += 16;
        }
    }
    pair_nets_free(&pn);
    fitted_free(&f);
    return rc == SF_ECANCEL ? rc : rc ? sf_fail(err, SF_ENOMEM, "", "out of memory building the model") : 0;
}

/* ---- grid methods: Coons and B-spline ------------------------------------------------------------
 * Both need the same point count on every slice (METHODS.md §2): each contour's curve is sampled at
 * N even steps of u, N the most points any contour has (at least 8). The curves' parameter starts
 * where the +x ray out of the centroid crosses them, so column k lines up from slice to slice. */

#define GRID_MIN 8

static int grid_count(const struct contour_set *cs)
{
    int N = GRID_MIN;
    for (int j = 0; j < cs->n_slices; j++)
        N = cs->s[j].n > N ? cs->s[j].n : N;
    return N;
}

/* Q[j*N + k] = (x, y, z) of slice j at u = k/N. NULL when out of memory. */
static double (*grid_sample(const struct contour_set *cs, int N, bool polar))[3]
{
    int n = cs->n_slices;
    double(*Q)[3] = malloc(sizeof *Q * (size_t)n * (size_t)N);
    struct fitted f;
    if (curves_fit(cs, false, polar, false, &f) || !Q) {
        free(Q);
        Q = NULL;
    }
    for (int j = 0; Q && j < n; j++)
        for (int k = 0; k < N; k++) {
            double *q = Q[(size_t)j * N + k], u = (double)k / N, xu, yu;
            curve_poly_at(&f.cp[j], curve_poly_segment(&f.cp[j], u), u, &q[0], &q[1], &xu, &yu);
            q[2] = cs->s[j].z;
        }
    fitted_free(&f);
    return Q;
}

/* Appends a bicubic with cw still a pool offset (as nurbs_extract does); NULL when out of memory. */
static double (*append_bicubic(struct patch_set *set, double u0, double u1, double v0, double v1))[4]
{
    if (mem_reserve((void **)&set->patches, &set->cap, set->n + 1, sizeof *set->patches) ||
        mem_reserve((void **)&set->pool, &set->cap_pool, set->n_pool + 16, sizeof *set->pool))
        return NULL;
    set->patches[set->n++] = (struct patch){.p = 3, .q = 3, .cw = (double(*)[4])(uintptr_t)set->n_pool, .u0 = u0, .u1 = u1, .v0 = v0, .v1 = v1};
    set->n_pool += 16;
    return set->pool + set->n_pool - 16;
}

/* Local interpolation by bicubic Coons patches (seeds 000/001 eq. 14–17, as METHODS.md corrects
 * them): per grid cell, corners, central-difference tangents (one-sided at the first and last slice:
 * ours, the seeds are silent), each in its own slot (the difference along the slices where the
 * matrix wants the derivative across them), and zero twist; P_B = H G Hᵀ puts the edge points at the
 * corners ± tangent/3 and the inner points at the corners ± both tangents/3. */
static int coons_surface(const struct contour_set *cs, bool polar, const struct sf_progress *pr, struct patch_set *set)
{
    int n = cs->n_slices, N = grid_count(cs);
    double(*Q)[3] = grid_sample(cs, N, polar);
    if (!Q)
        return SF_ENOMEM;
#define AT(j, k) Q[(size_t)(j) * N + (size_t)(((k) % N + N) % N)]
    for (int j = 0; j + 1 < n; j++) {
        if (sf_poll(pr, (double)j / n, NULL)) {
            free(Q);
            return SF_ECANCEL;
        }
        for (int k = 0; k < N; k++) {
            double(*cw)[4] = append_bicubic(set, (double)k / N, (double)(k + 1) / N, cs->s[j].z, cs->s[j + 1].z);
            if (!cw) {
                free(Q);
                return SF_ENOMEM;
            }
            for (int a = 0; a < 2; a++)     /* corner along u: k + a */
                for (int b = 0; b < 2; b++) { /* ... across slices: j + b */
                    int jj = j + b, kk = k + a, jm = jj > 0 ? jj - 1 : jj, jp = jj + 1 < n ? jj + 1 : jj;
                    double su = a ? -1.0 / 3 : 1.0 / 3, sv = b ? -1.0 / 3 : 1.0 / 3;
                    for (int c = 0; c < 3; c++) {
                        double P = AT(jj, kk)[c];
                        double Tu = 0.5 * (AT(jj, kk + 1)[c] - AT(jj, kk - 1)[c]);
                        double Tv = (AT(jp, kk)[c] - AT(jm, kk)[c]) / (jp - jm);
                        int i0 = a ? 3 : 0, j0 = b ? 3 : 0, i1 = a ? 2 : 1, j1 = b ? 2 : 1;
                        cw[i0 * 4 + j0][c] = P;
                        cw[i1 * 4 + j0][c] = P + su * Tu;
                        cw[i0 * 4 + j1][c] = P + sv * Tv;
                        cw[i1 * 4 + j1][c] = P + su * Tu + sv * Tv; /* zero twist */
                    }
                }
            for (int q = 0; q < 16; q++)
                cw[q][3] = 1.0;
        }
    }
#undef AT
    free(Q);
    return 0;
}

/* Solves the periodic system (x[k-1] + 4 x[k] + x[k+1]) / 6 = d[k], k = 0..N-1 (N >= 3), in place
 * on d (three columns): the cyclic tridiagonal system of uniform periodic cubic interpolation, by
 * the Thomas algorithm with a Sherman–Morrison correction for the two corner entries. */
static int solve_periodic(double (*d)[3], int N)
{
    double *c = malloc(sizeof *c * (size_t)N), (*y)[3] = malloc(sizeof *y * (size_t)N),
           *z = malloc(sizeof *z * (size_t)N);
    if (!c || !y || !z) {
        free(c), free(y), free(z);
        return SF_ENOMEM;
    }
    /* A = T + u vᵀ with u = (γ, 0, .., 0, 1/6), v = (1, 0, .., 0, (1/6)/γ), T tridiagonal */
    const double a = 1.0 / 6, b = 4.0 / 6, gamma = -b;
    double rhs_u[2] = {gamma, a};
    for (int pass = 0; pass < 2; pass++) { /* pass 0: T y = d (three columns); pass 1: T z = u */
        double prev_c = 0.0;
        for (int k = 0; k < N; k++) {
            double diag = b - (k == 0 ? gamma : 0.0) - (k == N - 1 ? a * a / gamma : 0.0);
            double m = k == 0 ? diag : diag - a * prev_c;
            c[k] = a / m;
            prev_c = c[k];
            if (pass == 0)
                for (int q = 0; q < 3; q++)
                    y[k][q] = ((k ? -a * y[k - 1][q] : 0.0) + d[k][q]) / m;
            else
                z[k] = ((k ? -a * z[k - 1] : 0.0) + (k == 0 ? rhs_u[0] : k == N - 1 ? rhs_u[1] : 0.0)) / m;
        }
        for (int k = N - 2; k >= 0; k--) {
            if (pass == 0)
                for (int q = 0; q < 3; q++)
                    y[k][q] -= c[k] * y[k + 1][q];
            else
                z[k] -= c[k] * z[k + 1];
        }
    }
    double vz = z[0] + a / gamma * z[N - 1];
    for (int q = 0; q < 3; q++) {
        double vy = y[0][q] + a / gamma * y[N - 1][q], f = vy / (1.0 + vz);
        for (int k = 0; k < N; k++)
            d[k][q] = y[k][q] - f * z[k];
    }
    free(c), free(y), free(z);
    return 0;
}

/* Solves A X = B in place on B (m right-hand sides of 3), A n x n dense, Gaussian elimination with
 * partial pivoting. A is destroyed. */
static void solve_dense(double *A, int n, double (*B)[3], int m)
{
    for (int c = 0; c < n; c++) {
        int piv = c;
        for (int r = c + 1; r < n; r++)
            if (fabs(A[(size_t)r * n + c]) > fabs(A[(size_t)piv * n + c]))
                piv = r;
        if (piv != c) {
            for (int k = 0; k < n; k++) {
                double t = A[(size_t)c * n + k];
                A[(size_t)c * n + k] = A[(size_t)piv * n + k], A[(size_t)piv * n + k] = t;
            }
            for (int k = 0; k < m; k++)
                for (int q = 0; q < 3; q++) {
                    double t = B[(size_t)c * m + k][q];
                    B[(size_t)c * m + k][q] = B[(size_t)piv * m + k][q], B[(size_t)piv * m + k][q] = t;
                }
        }
        for (int r = c + 1; r < n; r++) {
            double f = A[(size_t)r * n + c] / A[(size_t)c * n + c];
            if (f == 0.0)
                continue;
            for (int k = c; k < n; k++)
                A[(size_t)r * n + k] -= f * A[(size_t)c * n + k];
            for (int k = 0; k < m; k++)
                for (int q = 0; q < 3; q++)
                    B[(size_t)r * m + k][q] -= f * B[(size_t)c * m + k][q];
        }
    }
    for (int c = n - 1; c >= 0; c--)
        for (int k = 0; k < m; k++)
            for (int q = 0; q < 3; q++) {
                double sum = B[(size_t)c * m + k][q];
                for (int r = c + 1; r < n; r++)
                    sum -= A[(size_t)c * n + r] * B[(size_t)r * m + k][q];
                B[(size_t)c * m + k][q] = sum / A[(size_t)c * n + c];
            }
}

static int cmp_span(const void *a, const void *b)
{
    const struct patch *x = a, *y = b;
    return x->v0 != y->v0 ? (x->v0 > y->v0) - (x->v0 < y->v0) : (x->u0 > y->u0) - (x->u0 < y->u0);
}

/* Global interpolation by one B-spline surface (seed 000 eq. 28–31): cubic and periodic along the
 * contours (uniform knots, the first three control columns wrapped, eq. 29), cubic (or of degree
 * slices - 1) across them, clamped, at uniform parameters with averaged knots (Piegl & Tiller 9.8).
 * The two directions are solved one after the other, each with a proper solver: the cyclic
 * tridiagonal system along u, Gaussian elimination with pivoting across (the thesis used
 * Gauss–Jordan on the whole). Bézier extraction gives the patches. */
static int bspline_surface(const struct contour_set *cs, bool polar, const struct sf_progress *pr, struct patch_set *set)
{
    int n = cs->n_slices, N = grid_count(cs), q = n > 3 ? 3 : n - 1, rc = SF_ENOMEM;
    double(*Q)[3] = grid_sample(cs, N, polar), *A = malloc(sizeof *A * (size_t)n * n);
    struct surface s = {0};
    if (!Q || !A || nurbs_surface_alloc(&s, SURF_BSPLINE, 3, q, N + 3, n, NULL))
        goto out;
    for (int j = 0; j < n; j++) /* along u, slice by slice */
        if ((rc = sf_poll(pr, 0.3 * j / n, NULL)) || (rc = solve_periodic(Q + (size_t)j * N, N)))
            goto out;
    rc = SF_ENOMEM;
    for (int k = 0; k < n + q + 1; k++) { /* across: clamped, averaged knots */
        if (k <= q)
            s.knots_v[k] = 0.0;
        else if (k >= n)
            s.knots_v[k] = 1.0;
        else {
            double sum = 0.0;
            for (int i = k - q; i < k; i++)
                sum += (double)i / (n - 1);
            s.knots_v[k] = sum / q;
        }
    }
    memset(A, 0, sizeof *A * (size_t)n * n);
    for (int i = 0; i < n; i++) {
        double Nb[PATCH_MAX_DEGREE + 1];
        int r = nurbs_basis(s.knots_v, n, q, (double)i / (n - 1), Nb);
        for (int b = 0; b <= q; b++)
            A[(size_t)i * n + (size_t)(r - q + b)] = Nb[b];
    }
    solve_dense(A, n, Q, N); /* rows: slices; right-hand sides: the N columns */
    if ((rc = sf_poll(pr, 0.6, NULL)))
        goto out;
    rc = SF_ENOMEM;
    for (int k = 0; k < N + 3 + 4; k++)
        s.knots_u[k] = (double)(k - 3) / N;
    /* control column i along u, j across; the curve at u = k/N is (x[k-1] + 4 x[k] + x[k+1]) / 6 of
     * columns k..k+2, so column i holds x[i-1] and the first three are wrapped round (eq. 29) */
    for (int i = 0; i < N + 3; i++)
        for (int j = 0; j < n; j++)
            memcpy(&s.points[3 * ((size_t)i * n + j)], Q[(size_t)j * N + (size_t)((i + N - 1) % N)], sizeof(double) * 3);
    size_t first = set->n;
    if (!(rc = nurbs_extract(&s, 0, set))) /* span by span across, each in increasing u */
        qsort(set->patches + first, set->n - first, sizeof *set->patches, cmp_span);
out:
    nurbs_surface_free(&s);
    free(Q);
    free(A);
    return rc;
}

/* The patches a method makes of a chain, at most: the grid methods one per grid column and pair of
 * levels; the curve methods one per knot of the (up to) four curves a pair depends on. */
static double patches_bound(const struct contour_set *cs, enum model_method m)
{
    int n = cs->n_slices;
    if (m == MODEL_COONS || m == MODEL_BSPLINE)
        return (double)grid_count(cs) * (n - 1);
    double sum = 0.0;
    for (int k = 0, j0, j1; k + 1 < n; k++) {
        pair_reads(n, k, false, &j0, &j1);
        for (int j = j0; j <= j1; j++)
            sum += (double)WARP_MAX_KNOTS(cs->s[j].n) + 1;
    }
    return sum;
}

int model_side(const struct contour_set *cs, struct model_opts o, struct patch_set *set, struct sf_err *err)
{
    return model_side_closed(cs, o, set, NULL, err);
}

int model_side_closed(const struct contour_set *cs, struct model_opts o, struct patch_set *set,
                      struct model_closed *cl, struct sf_err *err)
{
    if (cl)
        *cl = (struct model_closed){NAN, 0.0};
    double bound = patches_bound(cs, o.method);
    if (bound > MODEL_MAX_PATCHES)
        return sf_fail(err, SF_ELIMIT, "/slices",
                       "the %s method would make about %.0f patches of these contours, over the limit of %d: fewer "
                       "points per contour (or fewer levels) would do", model_method_name(o.method), bound,
                       MODEL_MAX_PATCHES);
    int rc;
    switch (o.method) {
    case MODEL_COONS: rc = coons_surface(cs, o.polar, o.progress, set); break;
    case MODEL_BSPLINE: rc = bspline_surface(cs, o.polar, o.progress, set); break;
    default: return curve_surface(cs, o.method == MODEL_LINEAR_PARABOLIC, o, set, cl, err);
    }
    return rc == SF_ECANCEL ? sf_fail(err, rc, "", "cancelled")
           : rc            ? sf_fail(err, rc, "", "out of memory building the model")
                           : 0;
}

static const char *const METHOD_NAMES[] = {"parabolic", "linear-parabolic", "coons", "bspline"};

const char *model_method_name(enum model_method m)
{
    return METHOD_NAMES[m];
}

int model_method_parse(const char *name, enum model_method *m)
{
    for (int k = 0; k < 4; k++)
        if (!strcmp(name, METHOD_NAMES[k])) {
            *m = (enum model_method)k;
            return 0;
        }
    return SF_EINVAL;
}

/* ---- closed-form volume from the curves ------------------------------------------------------
 * At height z the surface's section is the curve sum_j w_j(z) C_j(u), so its area is
 * A(z) = sum_jl w_j w_l M_jl with the mixed areas M_jl = ½ ∮ (x_j y_l' - y_j x_l') du, and
 * V = ∫ A dz. Each M_jl is a sum of polynomial integrals over the merged breakpoints of two
 * curves (degree 5: 3 Gauss points exact), shared by every slice pair that uses both curves;
 * ∫ w_j w_l dz is of degree 6 (4 points exact). No patches needed: this is the fast, exact path,
 * and it must agree with the divergence theorem over the patches to rounding. */

/* M_jl = ½ ∮ (x_j y_l' - y_j x_l') du over u in [0, 1], piece by piece between both curves'
 * breakpoints; with sym, M_jl + M_lj in the same pass (all the quadratic form of the area needs). */
static double mixed_area(const struct curve_poly *a, const struct curve_poly *b, bool sym)
{
    double sum = 0.0, lo = 0.0;
    int ia = 0, ib = 0; /* next breakpoint index in each */
    while (lo < 1.0) {
        double na = ia < a->n ? a->u[ia] : 1.0, nb = ib < b->n ? b->u[ib] : 1.0, hi = fmin(fmin(na, nb), 1.0);
        if (hi > lo) { /* (in the segments that end at the next breakpoints: before the first, the wrap one) */
            int sa = ia ? ia - 1 : a->n - 1, sb = ib ? ib - 1 : b->n - 1;
            for (int g = 0; g < 3; g++) {
                double u = lo + (hi - lo) * GL3_X[g], xa, ya, xua, yua, xb, yb, xub, yub;
                curve_poly_at(a, sa, u, &xa, &ya, &xua, &yua);
                curve_poly_at(b, sb, u, &xb, &yb, &xub, &yub);
                double f = xa * yub - ya * xub;
                if (sym)
                    f += xb * yua - yb * xua;
                sum += GL3_W[g] * (hi - lo) * f;
            }
        }
        if (hi == na)
            ia++;
        if (hi == nb)
            ib++;
        if (hi == 1.0 && ia >= a->n && ib >= b->n)
            break;
        lo = hi;
    }
    return 0.5 * sum;
}

/* Section area of pair k's blend at any z (inside or beyond the pair). */
static double section_area(const struct contour_set *cs, bool lsq, bool ruled, const double *M, int k, double z)
{
    double w[4], area = 0.0;
    int j0, m;
    slice_weights(cs, lsq, ruled, k, z, w, &j0, &m);
    for (int a = 0; a < m; a++)
        for (int b = a; b < m; b++) /* b > a: the symmetric sum stands for both orders */
            area += w[a] * w[b] * M[(size_t)(j0 + a) * 7 + (size_t)(b - a + 3)];
    return area;
}

#define DOME_REACH 3.0  /* spacings the extrapolated section may take to close */

double model_dome(const double z[3], const double A[3], int n, struct model_dome *d)
{
    double dir = z[0] > z[1] ? 1.0 : -1.0, h = fabs(z[0] - z[1]);
    /* q(s) = A0 + b s + c s² in s = dir (z - z0) >= 0, through the slices at s1, s2 < 0 */
    double s1 = dir * (z[1] - z[0]), s2 = n > 2 ? dir * (z[2] - z[0]) : 0.0, b, cq;
    if (n > 2) {
        double d1 = (A[1] - A[0]) / s1, d2 = (A[2] - A[0]) / s2;
        cq = (d1 - d2) / (s1 - s2);
        b = d1 - cq * s1;
    } else {
        cq = 0.0;
        b = (A[1] - A[0]) / s1;
    }
    /* first positive root of A0 + b s + c s² */
    double root = NAN;
    if (fabs(cq) < 1e-300 * (fabs(b) + 1.0)) {
        if (b < 0)
            root = -A[0] / b;
    } else {
        double disc = b * b - 4 * cq * A[0];
        if (disc >= 0) {
            double r1 = (-b - sqrt(disc)) / (2 * cq), r2 = (-b + sqrt(disc)) / (2 * cq);
            double lo = fmin(r1, r2), hi = fmax(r1, r2);
            root = lo > 0 ? lo : (hi > 0 ? hi : NAN);
        }
    }
    if (!(root > 0) || root > DOME_REACH * h || !(A[0] > 0))
        root = NAN;
    if (d)
        *d = (struct model_dome){A[0], b, cq, root};
    return isnan(root) ? NAN : A[0] * root + b * root * root / 2 + cq * root * root * root / 3;
}

/* The closed form from a chain's fitted curves cp (ruled: curves_fit's flags, or NULL). 0 or
 * SF_ENOMEM. */
static int closed_form(const struct contour_set *cs, bool lsq, const struct curve_poly *cp, const bool *ruled,
                       double *volume, double end_area[2])
{
    int n = cs->n_slices;
    /* M[j*7 + 3] = M_jj (the curve's area); M[j*7 + (l - j + 3)] for l > j: M_jl + M_lj */
    double *M = calloc((size_t)n * 7, sizeof *M);
    if (!M)
        return SF_ENOMEM;
    for (int j = 0; j < n; j++)
        for (int l = j; l <= j + 3 && l < n; l++)
            M[(size_t)j * 7 + (size_t)(l - j + 3)] = mixed_area(&cp[j], &cp[l], l > j);
    double v = 0.0;
    for (int k = 0; k + 1 < n; k++) {
        double z0 = cs->s[k].z, z1 = cs->s[k + 1].z;
        for (int g = 0; g < 4; g++)
            v += GL4_W[g] * (z1 - z0) * section_area(cs, lsq, ruled && ruled[k], M, k, z0 + (z1 - z0) * GL4_X[g]);
    }
    *volume = v;
    end_area[0] = M[3];
    end_area[1] = M[(size_t)(n - 1) * 7 + 3];
    free(M);
    return 0;
}

int model_volume_closed(const struct contour_set *cs, struct model_opts o, double *volume, double end_area[2],
                        struct sf_err *err)
{
    if (o.method != MODEL_PARABOLIC && o.method != MODEL_LINEAR_PARABOLIC)
        return sf_fail(err, SF_EINVAL, "/method", "the closed form is for the curve-based methods");
    bool lsq = o.method == MODEL_LINEAR_PARABOLIC;
    struct fitted f;
    int rc = curves_fit(cs, lsq, o.polar, o.unfold, &f);
    if (!rc)
        rc = closed_form(cs, lsq, f.cp, f.ruled, volume, end_area);
    fitted_free(&f);
    return rc ? sf_fail(err, SF_ENOMEM, "", "out of memory") : 0;
}

double model_curve_area(const struct contour_slice *s)
{
    struct curve c = {0};
    struct curve_poly cp = {0};
    double a = 0.0;
    if (!curve_build(s, false, false, &c) && !curve_poly_build(&c, &cp) && !curve_refit(&cp))
        a = mixed_area(&cp, &cp, false);
    curve_poly_free(&cp);
    curve_free(&c);
    return a;
}

void model_chains_free(struct model_chain *c, int n)
{
    for (int k = 0; k < n && c; k++)
        free(c[k].idx);
    free(c);
}

struct contour_set model_chain_view(const struct contour_set *cs, const struct model_chain *c,
                                    struct contour_slice *storage)
{
    for (int k = 0; k < c->n; k++)
        storage[k] = cs->s[c->idx[k]];
    return (struct contour_set){storage, c->n};
}

int model_chains(const struct contour_set *cs, enum model_caps caps, struct model_chain **out, int *n_out,
                 struct sf_err *err)
{
    int n = cs->n_slices, rc = 0, n_chains = 0;
    int *level = malloc(sizeof *level * (size_t)n), *succ = calloc((size_t)n, sizeof *succ),
        *pred = calloc((size_t)n, sizeof *pred), *next = malloc(sizeof *next * (size_t)n),
        *start = malloc(sizeof *start * (size_t)(n + 1));
    bool *used = calloc((size_t)n, sizeof *used);
    struct model_chain *chains = calloc((size_t)n, sizeof *chains);
    *out = NULL;
    *n_out = 0;
    if (!level || !succ || !pred || !next || !start || !used || !chains) {
        rc = SF_ENOMEM;
        goto out_free;
    }
    int n_levels = 0; /* start[L]: first contour of level L */
    for (int k = 0; k < n; k++) {
        if (k == 0 || cs->s[k].z != cs->s[k - 1].z)
            start[n_levels++] = k;
        level[k] = n_levels - 1;
        next[k] = -1;
    }
    start[n_levels] = n;
    for (int L = 0; L + 1 < n_levels; L++)
        for (int a = start[L]; a < start[L + 1]; a++)
            for (int b = start[L + 1]; b < start[L + 2]; b++)
                if (cs->s[a].hole == cs->s[b].hole && contour_overlap(&cs->s[a], &cs->s[b])) {
                    succ[a]++;
                    pred[b]++;
                    next[a] = b;
                }
    for (int k = 0; k < n; k++) {
        if (used[k])
            continue;
        struct model_chain *c = &chains[n_chains++];
        c->idx = malloc(sizeof *c->idx * (size_t)n_levels);
        if (!c->idx) {
            rc = SF_ENOMEM;
            goto out_free;
        }
        c->hole = cs->s[k].hole;
        for (int j = k;;) {
            c->idx[c->n++] = j;
            used[j] = true;
            if (succ[j] != 1 || pred[next[j]] != 1 || used[next[j]])
                break;
            j = next[j];
        }
        int L0 = level[c->idx[0]], L1 = level[c->idx[c->n - 1]];
        double below = L0 > 0 ? cs->s[start[L0]].z - cs->s[start[L0 - 1]].z
                              : (caps == CAPS_SLAB ? cs->s[start[1]].z - cs->s[start[0]].z : 0.0);
        double above = L1 + 1 < n_levels ? cs->s[start[L1 + 1]].z - cs->s[start[L1]].z
                                         : (caps == CAPS_SLAB ? cs->s[start[L1]].z - cs->s[start[L1 - 1]].z : 0.0);
        c->ext[0] = 0.5 * below;
        c->ext[1] = 0.5 * above;
        c->at_end[0] = L0 == 0;
        c->at_end[1] = L1 + 1 == n_levels;
        c->spacing[0] = cs->s[start[L0 > 0 ? L0 : 1]].z - cs->s[start[L0 > 0 ? L0 - 1 : 0]].z;
        c->spacing[1] = L1 + 1 < n_levels ? cs->s[start[L1 + 1]].z - cs->s[start[L1]].z
                                          : cs->s[start[L1]].z - cs->s[start[L1 - 1]].z;
    }
    *out = chains;
    *n_out = n_chains;
    chains = NULL;
out_free:
    model_chains_free(chains, n_chains);
    free(level);
    free(succ);
    free(pred);
    free(next);
    free(start);
    free(used);
    return rc ? sf_fail(err, SF_ENOMEM, "", "out of memory") : 0;
}
