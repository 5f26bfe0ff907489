/* trim.c - the trimmed region's index and its point and box tests (trim.h). */
#include "trim.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Twice the signed area of (a, b, c): > 0 when c lies left of a -> b. */
static double orient(const double a[2], const double b[2], const double c[2])
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Segment s runs from pt[s] to pt[s + 1]: each loop is stored closed, its first point repeated. */
static void seg_ends(const struct trim *t, uint32_t s, const double **a, const double **b)
{
    *a = t->pt[s];
    *b = t->pt[s + 1];
}

static int cell_col(const struct trim *t, double u)
{
    double f = floor((u - t->u0) / t->du);
    return f < 0 ? 0 : f >= t->gu ? t->gu - 1 : (int)f;
}

static int cell_row(const struct trim *t, double v)
{
    double f = floor((v - t->v0) / t->dv);
    return f < 0 ? 0 : f >= t->gv ? t->gv - 1 : (int)f;
}

/* Bins every segment into the cells its bounding box meets (count when fill is false); SIZE_MAX
 * when pr asks to stop (polled every TRIM_POLL segments). */
#define TRIM_POLL 65536
static size_t bin(struct trim *t, bool fill, uint32_t *at, const struct sf_progress *pr)
{
    size_t total = 0;
    for (int l = 0; l < t->n_loops; l++)
        for (size_t k = t->start[l]; k + 1 < t->start[l + 1]; k++) {
            if (k % TRIM_POLL == 0 && sf_poll(pr, 0, NULL))
                return SIZE_MAX;
            const double *a = t->pt[k], *b = t->pt[k + 1];
            int i0 = cell_col(t, fmin(a[0], b[0])), i1 = cell_col(t, fmax(a[0], b[0]));
            int j0 = cell_row(t, fmin(a[1], b[1])), j1 = cell_row(t, fmax(a[1], b[1]));
            total += (size_t)(i1 - i0 + 1) * (size_t)(j1 - j0 + 1);
            if (!fill) {
                if (total > TRIM_MAX_ENTRIES)
                    return total;
                for (int j = j0; j <= j1; j++)
                    for (int i = i0; i <= i1; i++)
                        t->cell_first[(size_t)j * t->gu + i + 1]++;
                continue;
            }
            for (int j = j0; j <= j1; j++)
                for (int i = i0; i <= i1; i++)
                    t->cell_seg[at[(size_t)j * t->gu + i]++] = (uint32_t)k;
        }
    return total;
}

/* Whether each cell's centre is inside: along each row's centre line, the crossings left of a
 * centre (even-odd, half-open in v so a vertex on the line counts once). A crossing is counted in
 * the one cell whose columns hold it, though its segment is binned in every cell of its box. */
static void centres(struct trim *t)
{
    for (int j = 0; j < t->gv; j++) {
        double vc = t->v0 + (j + 0.5) * t->dv;
        int parity = 0;
        for (int i = 0; i < t->gu; i++) {
            double uc = t->u0 + (i + 0.5) * t->du, left = t->u0 + i * t->du, right = left + t->du;
            int before = 0, after = 0;
            size_t c = (size_t)j * t->gu + i;
            for (uint32_t e = t->cell_first[c]; e < t->cell_first[c + 1]; e++) {
                const double *a, *b;
                seg_ends(t, t->cell_seg[e], &a, &b);
                if ((a[1] > vc) == (b[1] > vc))
                    continue;
                double u = a[0] + (vc - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
                if ((u < left && i > 0) || (u >= right && i < t->gu - 1))
                    continue; /* another cell's crossing */
                if (u < uc)
                    before++;
                else
                    after++;
            }
            t->cell_in[c] = (uint8_t)((parity + before) & 1);
            parity += before + after;
        }
    }
}

int trim_build(struct trim *t, const double (*pts)[2], const size_t *counts, int n_loops, const char *where,
               const struct sf_progress *pr, struct sf_err *err)
{
    memset(t, 0, sizeof *t);
    size_t n = 0;
    if (n_loops < 1)
        return sf_fail(err, SF_EINVAL, where, "a trimmed surface needs at least one loop");
    for (int l = 0; l < n_loops; l++) {
        if (counts[l] < 3)
            return sf_fail(err, SF_EINVAL, where, "trim loop %d has %zu points: at least 3 close a region", l,
                           counts[l]);
        n += counts[l];
        if (n > TRIM_MAX_POINTS)
            return sf_fail(err, SF_ELIMIT, where, "trim loops have more than %u points", TRIM_MAX_POINTS);
    }
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (size_t k = 0; k < n; k++)
        for (int d = 0; d < 2; d++) {
            if (!isfinite(pts[k][d]))
                return sf_fail(err, SF_EINVAL, where, "trim loop point %zu is not finite", k);
            lo[d] = fmin(lo[d], pts[k][d]);
            hi[d] = fmax(hi[d], pts[k][d]);
        }
    if (!(hi[0] > lo[0]) || !(hi[1] > lo[1]))
        return sf_fail(err, SF_EINVAL, where, "the trim loops enclose no area");
    t->n_pts = n + (size_t)n_loops;
    t->n_loops = n_loops;
    t->pt = malloc(sizeof *t->pt * t->n_pts);
    t->start = malloc(sizeof *t->start * (size_t)(n_loops + 1));
    int g = (int)ceil(2.0 * sqrt((double)n));
    g = g < 4 ? 4 : g > TRIM_GRID_MAX ? TRIM_GRID_MAX : g;
    t->gu = t->gv = g;
    t->cell_first = calloc((size_t)g * g + 1, sizeof *t->cell_first);
    t->cell_in = malloc((size_t)g * g);
    if (!t->pt || !t->start || !t->cell_first || !t->cell_in) {
        trim_free(t);
        return sf_fail(err, SF_ENOMEM, where, "out of memory");
    }
    t->start[0] = 0;
    const double(*from)[2] = pts;
    for (int l = 0; l < n_loops; from += counts[l], l++) {
        memcpy(t->pt[t->start[l]], from, sizeof *t->pt * counts[l]);
        memcpy(t->pt[t->start[l] + counts[l]], from, sizeof *t->pt);
        t->start[l + 1] = t->start[l] + counts[l] + 1;
    }
    /* a little margin: no loop point on the grid's outer edge */
    double mu = 1e-9 * (hi[0] - lo[0]), mv = 1e-9 * (hi[1] - lo[1]);
    t->u0 = lo[0] - mu, t->v0 = lo[1] - mv;
    t->du = (hi[0] - lo[0] + 2 * mu) / g, t->dv = (hi[1] - lo[1] + 2 * mv) / g;
    size_t cells = (size_t)g * g;
    size_t entries = bin(t, false, NULL, pr);
    if (entries > TRIM_MAX_ENTRIES) {
        trim_free(t);
        return entries == SIZE_MAX ? sf_fail(err, SF_ECANCEL, where, "cancelled")
                                   : sf_fail(err, SF_ELIMIT, where, "trim loops too long across their bounds to index");
    }
    for (size_t c = 0; c < cells; c++)
        t->cell_first[c + 1] += t->cell_first[c];
    t->cell_seg = malloc(sizeof *t->cell_seg * (t->cell_first[cells] ? t->cell_first[cells] : 1));
    uint32_t *at = malloc(sizeof *at * cells);
    if (!t->cell_seg || !at) {
        free(at);
        trim_free(t);
        return sf_fail(err, SF_ENOMEM, where, "out of memory");
    }
    memcpy(at, t->cell_first, sizeof *at * cells);
    size_t filled = bin(t, true, at, pr);
    free(at);
    if (filled == SIZE_MAX) {
        trim_free(t);
        return sf_fail(err, SF_ECANCEL, where, "cancelled");
    }
    centres(t);
    return 0;
}

void trim_free(struct trim *t)
{
    if (!t)
        return;
    free(t->pt);
    free(t->start);
    free(t->cell_first);
    free(t->cell_seg);
    free(t->cell_in);
    memset(t, 0, sizeof *t);
}

bool trim_contains(const struct trim *t, double u, double v)
{
    if (u < t->u0 || v < t->v0 || u > t->u0 + t->gu * t->du || v > t->v0 + t->gv * t->dv)
        return false; /* beyond every loop */
    int i = cell_col(t, u), j = cell_row(t, v);
    size_t c = (size_t)j * t->gu + i;
    const double p[2] = {u, v}, m[2] = {t->u0 + (i + 0.5) * t->du, t->v0 + (j + 0.5) * t->dv};
    int in = t->cell_in[c];
    /* every loop edge the stretch from p to the centre crosses lies in this cell */
    for (uint32_t e = t->cell_first[c]; e < t->cell_first[c + 1]; e++) {
        const double *a, *b;
        seg_ends(t, t->cell_seg[e], &a, &b);
        if ((orient(a, b, p) > 0) != (orient(a, b, m) > 0) && (orient(p, m, a) > 0) != (orient(p, m, b) > 0))
            in ^= 1;
    }
    return in;
}

static int by_u32(const void *x, const void *y)
{
    uint32_t a = *(const uint32_t *)x, b = *(const uint32_t *)y;
    return (a > b) - (a < b);
}

/* Whether segment a-b enters the box's interior. One that only runs along its edge or touches it
 * does not: a loop along a patch's own border (a trimmed cylinder's seam, a face trimmed to its
 * natural boundary) leaves the patch wholly inside, not cut all round. */
static bool seg_meets_box(const double *a, const double *b, double u0, double u1, double v0, double v1)
{
    if (fmax(a[0], b[0]) <= u0 || fmin(a[0], b[0]) >= u1 || fmax(a[1], b[1]) <= v0 || fmin(a[1], b[1]) >= v1)
        return false;
    const double corner[4][2] = {{u0, v0}, {u1, v0}, {u1, v1}, {u0, v1}};
    int pos = 0, neg = 0;
    for (int k = 0; k < 4; k++) {
        double o = orient(a, b, corner[k]);
        pos += o > 0, neg += o < 0;
    }
    return pos && neg; /* the line through a, b separates the corners */
}

/* The loop segments that meet the box, into out (at most cap; a segment binned in several cells the
 * box covers comes once for each): their count, or -1 when there are more than cap. */
static long box_segments(const struct trim *t, double u0, double u1, double v0, double v1, uint32_t *out, size_t cap)
{
    size_t n = 0;
    int i0 = cell_col(t, u0), i1 = cell_col(t, u1), j0 = cell_row(t, v0), j1 = cell_row(t, v1);
    for (int j = j0; j <= j1; j++)
        for (int i = i0; i <= i1; i++) {
            size_t c = (size_t)j * t->gu + i;
            for (uint32_t e = t->cell_first[c]; e < t->cell_first[c + 1]; e++) {
                const double *a, *b;
                seg_ends(t, t->cell_seg[e], &a, &b);
                if (!seg_meets_box(a, b, u0, u1, v0, v1))
                    continue;
                if (n == cap)
                    return -1;
                out[n++] = t->cell_seg[e];
            }
        }
    return (long)n;
}

enum trim_class trim_classify(const struct trim *t, double u0, double u1, double v0, double v1)
{
    double gu1 = t->u0 + t->gu * t->du, gv1 = t->v0 + t->gv * t->dv;
    if (u1 < t->u0 || v1 < t->v0 || u0 > gu1 || v0 > gv1)
        return TRIM_OUT;
    uint32_t any;
    if (box_segments(t, u0, u1, v0, v1, &any, 1) != 0)
        return TRIM_CUT;
    /* no loop crosses the box: a box reaching past the loops' bounds lies partly outside them all,
     * so wholly outside; else its centre decides */
    if (u0 < t->u0 || v0 < t->v0 || u1 > gu1 || v1 > gv1)
        return TRIM_OUT;
    return trim_contains(t, 0.5 * (u0 + u1), 0.5 * (v0 + v1)) ? TRIM_IN : TRIM_OUT;
}

/* ---- the region's area within a box (Green's theorem on its boundary there) -------------- */

/* Adds the edge a -> b to the area and first moments: the region lies on its left. */
static void green_add(const double a[2], const double b[2], double m[3])
{
    double c = a[0] * b[1] - b[0] * a[1];
    m[0] += 0.5 * c;
    m[1] += (a[0] + b[0]) * c / 6.0;
    m[2] += (a[1] + b[1]) * c / 6.0;
}

static int by_double(const void *x, const void *y)
{
    double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

#define BOX_MAX_SEGS 4096 /* loop segments one box may meet; more: the caller subdivides */

double trim_box_moments(const struct trim *t, double u0, double u1, double v0, double v1, double centroid[2])
{
    const double box[4][2] = {{u0, v0}, {u1, v0}, {u1, v1}, {u0, v1}};
    const double lo[2] = {u0, v0}, hi[2] = {u1, v1};
    const double eps_u = 1e-9 * (u1 - u0), eps_v = 1e-9 * (v1 - v0);
    uint32_t segs[BOX_MAX_SEGS];
    long found = box_segments(t, u0, u1, v0, v1, segs, BOX_MAX_SEGS);
    if (found < 0)
        return -1.0;
    size_t n = (size_t)found;
    /* each segment once, though binned in several cells */
    qsort(segs, n, sizeof *segs, by_u32);
    double m[3] = {0, 0, 0};
    double cuts[4][BOX_MAX_SEGS / 4 + 2];
    int n_cuts[4] = {0, 0, 0, 0};
    for (size_t k = 0; k < n; k++) {
        if (k && segs[k] == segs[k - 1])
            continue;
        const double *a, *b;
        seg_ends(t, segs[k], &a, &b);
        /* Liang–Barsky: the part of a -> b inside the box */
        double f0 = 0, f1 = 1, d[2] = {b[0] - a[0], b[1] - a[1]};
        for (int ax = 0; ax < 2; ax++) {
            if (d[ax] == 0) {
                if (a[ax] < lo[ax] || a[ax] > hi[ax])
                    f0 = 1, f1 = 0;
                continue;
            }
            double g0 = (lo[ax] - a[ax]) / d[ax], g1 = (hi[ax] - a[ax]) / d[ax];
            if (g0 > g1) {
                double x = g0;
                g0 = g1;
                g1 = x;
            }
            f0 = fmax(f0, g0), f1 = fmin(f1, g1);
        }
        if (!(f1 > f0))
            continue;
        double p[2] = {a[0] + f0 * d[0], a[1] + f0 * d[1]}, q[2] = {a[0] + f1 * d[0], a[1] + f1 * d[1]};
        /* a part along the box's own edge is the box edge's business (its inside test below) */
        bool on_edge = (fabs(p[0] - u0) <= eps_u && fabs(q[0] - u0) <= eps_u) ||
                       (fabs(p[0] - u1) <= eps_u && fabs(q[0] - u1) <= eps_u) ||
                       (fabs(p[1] - v0) <= eps_v && fabs(q[1] - v0) <= eps_v) ||
                       (fabs(p[1] - v1) <= eps_v && fabs(q[1] - v1) <= eps_v);
        if (!on_edge) {
            /* the region on its left, or the part runs the other way */
            double mid[2] = {0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])}, len = hypot(d[0], d[1]);
            double off = 1e-7 * fmax(u1 - u0, v1 - v0);
            bool left_in = trim_contains(t, mid[0] - d[1] / len * off, mid[1] + d[0] / len * off);
            if (left_in)
                green_add(p, q, m);
            else
                green_add(q, p, m);
        }
        /* where it crosses the box's edges: edge e runs from box[e] to box[e + 1] */
        for (int e = 0; e < 4; e++) {
            const double *c0 = box[e], *c1 = box[(e + 1) % 4];
            int ax = e % 2 ? 0 : 1; /* the edge's fixed coordinate: v for the bottom and top, u for the sides */
            double fixed = c0[ax];
            if (d[ax] == 0)
                continue;
            double f = (fixed - a[ax]) / d[ax];
            if (f < 0 || f > 1)
                continue;
            int along = 1 - ax;
            double x = a[along] + f * d[along], s = (x - c0[along]) / (c1[along] - c0[along]);
            if (s > 0 && s < 1 && n_cuts[e] < BOX_MAX_SEGS / 4)
                cuts[e][n_cuts[e]++] = s;
        }
    }
    /* the box's edges, counter-clockwise, where the region holds them (tested just inside the box) */
    const double in_off = 1e-7;
    for (int e = 0; e < 4; e++) {
        const double *c0 = box[e], *c1 = box[(e + 1) % 4];
        qsort(cuts[e], (size_t)n_cuts[e], sizeof(double), by_double);
        double prev = 0;
        for (int k = 0; k <= n_cuts[e]; k++) {
            double next = k < n_cuts[e] ? cuts[e][k] : 1.0;
            if (next <= prev)
                continue;
            double mid = 0.5 * (prev + next);
            double x = c0[0] + mid * (c1[0] - c0[0]), y = c0[1] + mid * (c1[1] - c0[1]);
            x += in_off * (0.5 * (u0 + u1) - x), y += in_off * (0.5 * (v0 + v1) - y);
            if (trim_contains(t, x, y)) {
                double p[2] = {c0[0] + prev * (c1[0] - c0[0]), c0[1] + prev * (c1[1] - c0[1])};
                double q[2] = {c0[0] + next * (c1[0] - c0[0]), c0[1] + next * (c1[1] - c0[1])};
                green_add(p, q, m);
            }
            prev = next;
        }
    }
    if (m[0] > 0) {
        centroid[0] = m[1] / m[0], centroid[1] = m[2] / m[0];
    } else {
        centroid[0] = 0.5 * (u0 + u1), centroid[1] = 0.5 * (v0 + v1);
    }
    return fmax(m[0], 0.0);
}
