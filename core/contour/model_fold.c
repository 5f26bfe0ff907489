/* model_fold.c - folds in a chain's side surface found (pair_folds) and undone by warping the
 * curves above them (curves_unfold), and a chain's curves fitted for the methods, unfolded when
 * asked (curves_fit). It changes curves, never the contours. */
#include "model_internal.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

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
                               .cy = malloc(sizeof *out->cy * n), .n_corner = c->n_corner,
                               .corner = malloc(sizeof *out->corner * (size_t)(c->n_corner + 1))};
    if (!out->own_u || !out->cx || !out->cy || !out->corner)
        return SF_ENOMEM;
    memcpy(out->corner, c->corner, sizeof *out->corner * (size_t)c->n_corner);
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

void fitted_free(struct fitted *f)
{
    for (int j = 0; j < f->n && f->cv && f->cp; j++)
        curve_free(&f->cv[j]), curve_poly_free(&f->cp[j]);
    free(f->cv), free(f->cp), free(f->ruled);
}

/* f's curves; the caller frees them with fitted_free, whatever the answer. 0 or SF_ENOMEM. */
int curves_fit(const struct contour_set *cs, bool lsq, bool polar, bool unfold, struct fitted *f)
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

