/* contour.c - cleaning slice contours and the polygon baselines. Written by hand: a few hundred
 * points per contour, where the quadratic self-crossing test costs microseconds. */
#include "contour.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define POINT_EPS 1e-9 /* mm: points closer than this are one point */

void contour_set_free(struct contour_set *cs)
{
    if (!cs)
        return;
    for (int k = 0; k < cs->n_slices; k++)
        free(cs->s[k].p);
    free(cs->s);
    cs->s = NULL;
    cs->n_slices = 0;
}

double contour_area(const struct contour_slice *s)
{
    double a = 0;
    for (int i = 0; i < s->n; i++) {
        const double *p = s->p[i], *q = s->p[(i + 1) % s->n];
        a += p[0] * q[1] - q[0] * p[1];
    }
    return 0.5 * a;
}

void contour_centroid(const struct contour_slice *s, double *x, double *y)
{
    double cx = 0, cy = 0, a2 = 0;
    for (int i = 0; i < s->n; i++) {
        const double *p = s->p[i], *q = s->p[(i + 1) % s->n];
        double w = p[0] * q[1] - q[0] * p[1];
        a2 += w;
        cx += (p[0] + q[0]) * w;
        cy += (p[1] + q[1]) * w;
    }
    *x = cx / (3 * a2);
    *y = cy / (3 * a2);
}

static int by_z(const void *a, const void *b)
{
    const struct contour_slice *p = a, *q = b;
    if (p->z != q->z)
        return p->z < q->z ? -1 : 1;
    return p->src != q->src ? p->src - q->src : p->src_contour - q->src_contour; /* stable */
}

bool contour_inside(const struct contour_slice *s, double x, double y)
{
    bool in = false;
    for (int i = 0, j = s->n - 1; i < s->n; j = i++) {
        const double *a = s->p[i], *b = s->p[j];
        if ((a[1] > y) != (b[1] > y) && x < (b[0] - a[0]) * (y - a[1]) / (b[1] - a[1]) + a[0])
            in = !in;
    }
    return in;
}

/* Orientation of (a, b, c): >0 counter-clockwise. */
static double orient(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

bool contour_segments_cross(const double *a, const double *b, const double *c, const double *d)
{
    double o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a), o4 = orient(c, d, b);
    /* (collinear touching is left to the duplicate-point rule) */
    return ((o1 > 0 && o2 < 0) || (o1 < 0 && o2 > 0)) && ((o3 > 0 && o4 < 0) || (o3 < 0 && o4 > 0));
}

struct edge_span {
    double x0, x1;
    int i;
};

static int by_x0(const void *a, const void *b)
{
    double x = ((const struct edge_span *)a)->x0, y = ((const struct edge_span *)b)->x0;
    return x < y ? -1 : x > y;
}

/* Edge pairs a sweep may compare at most: a contour of many long edges that overlap in x (a comb,
 * a spiral) would otherwise be checked for minutes. Real outlines compare a handful per edge. */
#define CROSS_MAX_PAIRS 50000000L
#define CROSS_TOO_COMPLEX -2

/* An edge of a that crosses another edge of a (b == a) or an edge of b: its index in a, -1 for none,
 * or CROSS_TOO_COMPLEX past CROSS_MAX_PAIRS. A sweep in x: edges are compared only with those whose
 * x-extent overlaps theirs. Neighbouring edges of one contour (they share a point) are not compared. */
/* Edge i of the sweep's numbering (a's edges, then b's): its two end points. */
static void sweep_edge(const struct contour_slice *a, const struct contour_slice *b, int na, int i, const double **p,
                       const double **q)
{
    const struct contour_slice *c = i < na ? a : b;
    int k = i < na ? i : i - na;
    *p = c->p[k];
    *q = c->p[(k + 1) % c->n];
}

static int sweep_crossing(const struct contour_slice *a, const struct contour_slice *b)
{
    int na = a->n, nb = b == a ? 0 : b->n, n = na + nb, found = -1;
    struct edge_span *e = malloc(sizeof *e * (size_t)n);
    if (!e)
        return -1; /* out of memory: leave the check to the modelling, which copes */
    for (int i = 0; i < n; i++) {
        const double *p, *q;
        sweep_edge(a, b, na, i, &p, &q);
        e[i] = (struct edge_span){fmin(p[0], q[0]), fmax(p[0], q[0]), i};
    }
    qsort(e, (size_t)n, sizeof *e, by_x0);
    long pairs = 0;
    for (int x = 0; x < n && found == -1; x++)
        for (int y = x + 1; y < n && e[y].x0 <= e[x].x1 && found == -1; y++) {
            if (++pairs > CROSS_MAX_PAIRS) {
                found = CROSS_TOO_COMPLEX;
                break;
            }
            int i = e[x].i, j = e[y].i;
            if (b == a) {
                int d = abs(i - j);
                if (d == 1 || d == n - 1)
                    continue; /* neighbours share a point */
            } else if ((i < na) == (j < na)) {
                continue;
            }
            const double *pi, *qi, *pj, *qj;
            sweep_edge(a, b, na, i, &pi, &qi);
            sweep_edge(a, b, na, j, &pj, &qj);
            if (contour_segments_cross(pi, qi, pj, qj))
                found = b == a ? (i < j ? i : j) : (i < na ? i : j);
        }
    free(e);
    return found;
}

static void bbox(const struct contour_slice *s, double b[4])
{
    b[0] = b[2] = s->p[0][0];
    b[1] = b[3] = s->p[0][1];
    for (int i = 1; i < s->n; i++) {
        b[0] = fmin(b[0], s->p[i][0]), b[2] = fmax(b[2], s->p[i][0]);
        b[1] = fmin(b[1], s->p[i][1]), b[3] = fmax(b[3], s->p[i][1]);
    }
}

/* The boxes of a and b are disjoint: nothing of one can touch the other. */
static bool apart(const struct contour_slice *a, const struct contour_slice *b)
{
    double p[4], q[4];
    bbox(a, p);
    bbox(b, q);
    return p[2] < q[0] || q[2] < p[0] || p[3] < q[1] || q[3] < p[1];
}

/* Whether an edge of a crosses one of b: 1, 0, or CROSS_TOO_COMPLEX. */
static int edges_cross(const struct contour_slice *a, const struct contour_slice *b)
{
    if (apart(a, b))
        return 0;
    int at = sweep_crossing(a, b);
    return at == CROSS_TOO_COMPLEX ? at : at >= 0;
}

bool contour_overlap(const struct contour_slice *a, const struct contour_slice *b)
{
    if (apart(a, b))
        return false;
    /* every vertex against the other region (contours that touch at vertices count when one lies
     * inside) while that is affordable; past it, crossing edges or one vertex of each: without a
     * crossing, either region holds the other whole or they are apart (too complex to sweep:
     * taken as overlapping, which links the two) */
    if ((long)a->n * b->n > CROSS_MAX_PAIRS)
        return edges_cross(a, b) || contour_inside(b, a->p[0][0], a->p[0][1]) ||
               contour_inside(a, b->p[0][0], b->p[0][1]);
    for (int i = 0; i < a->n; i++)
        if (contour_inside(b, a->p[i][0], a->p[i][1]))
            return true;
    for (int i = 0; i < b->n; i++)
        if (contour_inside(a, b->p[i][0], b->p[i][1]))
            return true;
    return edges_cross(a, b) != 0;
}

static bool same_point(const double *a, const double *b)
{
    return a[0] == b[0] && a[1] == b[1];
}

static void remove_at(double (*p)[2], int *n, int k)
{
    memmove(p + k, p + k + 1, sizeof *p * (size_t)(*n - k - 1));
    (*n)--;
}

/* Drops repeated neighbours and spikes (a -> k -> a collapses to a) until none is left. */
static int unspike(double (*p)[2], int n)
{
    for (bool changed = true; changed && n >= 3;) {
        changed = false;
        for (int k = 0; k < n && !changed; k++) {
            int a = (k + n - 1) % n, b = (k + 1) % n;
            if (same_point(p[k], p[b])) {
                remove_at(p, &n, k);
                changed = true;
            } else if (same_point(p[a], p[b])) { /* drop k and b, the higher index first */
                remove_at(p, &n, k > b ? k : b);
                remove_at(p, &n, k > b ? b : k);
                changed = true;
            }
        }
    }
    return n;
}

struct indexed_point {
    double x, y;
    int i;
};

static int by_xy(const void *a, const void *b)
{
    const struct indexed_point *p = a, *q = b;
    return p->x != q->x ? (p->x > q->x) - (p->x < q->x) : (p->y > q->y) - (p->y < q->y);
}

/* Keyholes: a contour that passes through one point twice (planning systems reach an inner hole
 * along a cut, in and back out the same way) is split there into two loops, each freed of the cut's
 * spikes; the loop with the hole becomes a contour of its own at the same z (appended to the set),
 * and nesting makes it a hole. Returns 1 when contour k was split, 0 when it has no such point,
 * SF_ENOMEM. Loops left without area (a bare cut) are dropped. */
static int split_keyhole(struct contour_set *cs, int k)
{
    struct contour_slice *s = &cs->s[k];
    int n = s->n, i = -1, j = -1;
    struct indexed_point *order = malloc(sizeof *order * (size_t)n);
    if (!order)
        return SF_ENOMEM;
    for (int q = 0; q < n; q++)
        order[q] = (struct indexed_point){s->p[q][0], s->p[q][1], q};
    qsort(order, (size_t)n, sizeof *order, by_xy);
    for (int q = 0; q + 1 < n && i < 0; q++)
        if (order[q].x == order[q + 1].x && order[q].y == order[q + 1].y) {
            i = order[q].i < order[q + 1].i ? order[q].i : order[q + 1].i;
            j = order[q].i < order[q + 1].i ? order[q + 1].i : order[q].i;
        }
    free(order);
    if (i < 0)
        return 0;
    /* loop 1: i..j-1; loop 2: 0..i-1 and j..n-1 (in place) */
    int n1 = j - i;
    double(*p1)[2] = malloc(sizeof *p1 * (size_t)n1);
    if (!p1)
        return SF_ENOMEM;
    memcpy(p1, s->p + i, sizeof *p1 * (size_t)n1);
    memmove(s->p + i, s->p + j, sizeof *s->p * (size_t)(n - j));
    s->n = unspike(s->p, n - n1);
    n1 = unspike(p1, n1);
    struct contour_slice loop = *s;
    loop.p = p1;
    loop.n = n1;
    if (n1 < 3 || !(fabs(contour_area(&loop)) > 0)) { /* a bare cut */
        free(p1);
        return 1;
    }
    if (s->n < 3 || !(fabs(contour_area(s)) > 0)) { /* the other side was the cut: keep this one */
        free(s->p);
        *s = loop;
        return 1;
    }
    struct contour_slice *grown = realloc(cs->s, sizeof *grown * (size_t)(cs->n_slices + 1));
    if (!grown) {
        free(p1);
        return SF_ENOMEM;
    }
    cs->s = grown;
    cs->s[cs->n_slices++] = loop;
    return 1;
}

/* Contour s's points (point -1: all of them) or its slice's z, as the request numbers them. */
static struct contour_fault fault_of(const struct contour_slice *s, int point, bool z)
{
    return (struct contour_fault){s->src, s->src_contour, point, z};
}

int contour_clean(struct contour_set *cs, struct contour_fault *fault, struct sf_err *err)
{
    struct contour_fault none, *f = fault ? fault : &none;
    for (int k = 0; k < cs->n_slices; k++) {
        struct contour_slice *s = &cs->s[k];
        *f = fault_of(s, -1, false);
        if (!(fabs(s->z) <= CONTOUR_MAX_COORD)) {
            *f = fault_of(s, -1, true);
            return sf_fail(err, SF_EINVAL, "", "z is %g; it must be a finite number within ±%g mm", s->z,
                           CONTOUR_MAX_COORD);
        }
        int m = 0;
        for (int i = 0; i < s->n; i++) {
            if (!(fabs(s->p[i][0]) <= CONTOUR_MAX_COORD && fabs(s->p[i][1]) <= CONTOUR_MAX_COORD)) {
                *f = fault_of(s, i, false);
                return sf_fail(err, SF_EINVAL, "", "point %d is not two finite numbers within ±%g mm", i,
                               CONTOUR_MAX_COORD);
            }
            if (m > 0 && fabs(s->p[i][0] - s->p[m - 1][0]) <= POINT_EPS && fabs(s->p[i][1] - s->p[m - 1][1]) <= POINT_EPS)
                continue; /* repeated point */
            s->p[m][0] = s->p[i][0];
            s->p[m][1] = s->p[i][1];
            m++;
        }
        while (m > 1 && fabs(s->p[m - 1][0] - s->p[0][0]) <= POINT_EPS && fabs(s->p[m - 1][1] - s->p[0][1]) <= POINT_EPS)
            m--; /* repeated closing point */
        s->n = m;
        int split;
        while (m >= 3 && (split = split_keyhole(cs, k)) == 1) {
            s = &cs->s[k]; /* the set may have moved */
            m = s->n;
        }
        if (m >= 3 && split)
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        if (m < 3)
            return sf_fail(err, SF_EINVAL, "", "a contour needs at least 3 distinct points, this one has %d", m);
        int at = sweep_crossing(s, s);
        if (at == CROSS_TOO_COMPLEX)
            return sf_fail(err, SF_ELIMIT, "", "the contour is too complex to check for crossings (over %ld edge pairs "
                           "overlap in x)", CROSS_MAX_PAIRS);
        if (at >= 0) /* a contour that crosses itself cannot bound a solid */
            return sf_fail(err, SF_EINVAL, "", "the contour crosses itself (at edge %d)", at);
        double a = contour_area(s);
        if (!(fabs(a) > 0))
            return sf_fail(err, SF_EINVAL, "", "the contour encloses no area");
        if (a < 0) /* clockwise: reverse */
            for (int i = 0, j = m - 1; i < j; i++, j--) {
                double t0 = s->p[i][0], t1 = s->p[i][1];
                s->p[i][0] = s->p[j][0], s->p[i][1] = s->p[j][1];
                s->p[j][0] = t0, s->p[j][1] = t1;
            }
    }
    qsort(cs->s, (size_t)cs->n_slices, sizeof *cs->s, by_z);
    int levels = 0;
    for (int a = 0; a < cs->n_slices;) {
        int b = a;
        while (b < cs->n_slices && cs->s[b].z == cs->s[a].z)
            b++;
        levels++;
        if (a > 0 && !(cs->s[a].z - cs->s[a - 1].z >= CONTOUR_MIN_SPACING)) {
            *f = fault_of(&cs->s[a], -1, true);
            return sf_fail(err, SF_EINVAL, "", "z = %g is within %g mm of the level below (z = %g)", cs->s[a].z,
                           CONTOUR_MIN_SPACING, cs->s[a - 1].z);
        }
        for (int i = a; i < b; i++) { /* contours of one slice: nesting, and no crossing edges */
            int depth = 0;
            for (int j = a; j < b; j++) {
                if (j == i)
                    continue;
                int cross = j > i ? edges_cross(&cs->s[i], &cs->s[j]) : 0;
                if (cross) {
                    *f = fault_of(&cs->s[j], -1, false);
                    return cross == CROSS_TOO_COMPLEX
                               ? sf_fail(err, SF_ELIMIT, "", "too complex to check against the other contours at z = %g",
                                         cs->s[i].z)
                               : sf_fail(err, SF_EINVAL, "", "this contour crosses another contour at z = %g", cs->s[i].z);
                }
                depth += contour_inside(&cs->s[j], cs->s[i].p[0][0], cs->s[i].p[0][1]);
            }
            cs->s[i].hole = depth % 2 == 1;
        }
        a = b;
    }
    *f = (struct contour_fault){-1, -1, -1, false};
    if (levels < 2)
        return sf_fail(err, SF_EINVAL, "", "a model needs contours on at least 2 distinct z, got %d", levels);
    return 0;
}

void contour_baselines(const struct contour_set *cs, struct contour_baselines *b)
{
    memset(b, 0, sizeof *b);
    /* per level: outer areas less holes (even-odd) */
    int n = 0;
    double *z = malloc(sizeof *z * (size_t)cs->n_slices), *A = malloc(sizeof *A * (size_t)cs->n_slices);
    if (!z || !A) {
        free(z);
        free(A);
        return;
    }
    for (int k = 0; k < cs->n_slices; k++) {
        if (k == 0 || cs->s[k].z != cs->s[k - 1].z) {
            z[n] = cs->s[k].z;
            A[n++] = 0.0;
        }
        double a = fabs(contour_area(&cs->s[k]));
        A[n - 1] += cs->s[k].hole ? -a : a;
    }
    for (int k = 0; k < n; k++) {
        /* Cavalieri: the slab around each slice reaches half way to its neighbours (a full
         * spacing at the ends), which for even spacing is the usual A_k h */
        double lo = k > 0 ? 0.5 * (z[k] - z[k - 1]) : 0.5 * (z[1] - z[0]);
        double hi = k < n - 1 ? 0.5 * (z[k + 1] - z[k]) : 0.5 * (z[n - 1] - z[n - 2]);
        b->cavalieri += A[k] * (lo + hi);
        if (k + 1 < n) {
            double h = z[k + 1] - z[k];
            b->trapezoid += h * 0.5 * (A[k] + A[k + 1]);
            b->frustum += h / 3.0 * (A[k] + A[k + 1] + sqrt(fmax(0.0, A[k] * A[k + 1])));
        }
    }
    free(z);
    free(A);
}
