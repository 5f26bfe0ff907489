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

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "mem.h"

#define BREAK_EPS 1e-12 /* breakpoints closer than this in u are one */

struct curve {
    int n;
    double (*p)[2];  /* points, rotated so that u increases from index 0 */
    double *u;       /* parameters in [0, 1), increasing */
};

static void curve_free(struct curve *c)
{
    free(c->p);
    free(c->u);
}

/* Builds the curve of slice s: chord-length parameters from the +x crossing of the centroid's ray. */
static int curve_build(const struct contour_slice *s, struct curve *c)
{
    int n = s->n;
    c->n = n;
    c->p = malloc(sizeof *c->p * (size_t)n);
    c->u = malloc(sizeof *c->u * (size_t)n);
    double *len = malloc(sizeof *len * (size_t)(n + 1));
    if (!c->p || !c->u || !len) {
        free(len);
        return SF_ENOMEM;
    }
    /* centroid of the polygon */
    double cx = 0, cy = 0, a2 = 0;
    for (int i = 0; i < n; i++) {
        const double *p = s->p[i], *q = s->p[(i + 1) % n];
        double w = p[0] * q[1] - q[0] * p[1];
        a2 += w;
        cx += (p[0] + q[0]) * w;
        cy += (p[1] + q[1]) * w;
    }
    cx /= 3 * a2;
    cy /= 3 * a2;
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

/* eq. 32: between t1 and t2, the blend of the parabolas through 0..2 and 1..3. */
static double blend(double t, const double ts[4], const double v[4])
{
    double L1 = parabola(t, ts[0], ts[1], ts[2], v[0], v[1], v[2]);
    double L2 = parabola(t, ts[1], ts[2], ts[3], v[1], v[2], v[3]);
    return (t - ts[2]) / (ts[1] - ts[2]) * L1 + (t - ts[1]) / (ts[2] - ts[1]) * L2;
}

/* The curve at u in [0, 1]. */
static void curve_eval(const struct curve *c, double u, double *x, double *y)
{
    /* segment i: u_i <= u < u_{i+1} (periodic; u below u_0 belongs to the segment from the last
     * point, i = -1); binary search over the increasing u */
    int i = -1;
    if (u >= c->u[0]) {
        int lo = 0, hi = c->n - 1;
        while (lo < hi) {
            int mid = (lo + hi + 1) / 2;
            if (c->u[mid] <= u)
                lo = mid;
            else
                hi = mid - 1;
        }
        i = lo;
    }
    double ts[4], xs[4], ys[4];
    for (int k = 0; k < 4; k++)
        ts[k] = cu(c, i - 1 + k, &xs[k], &ys[k]);
    *x = blend(u, ts, xs);
    *y = blend(u, ts, ys);
}

/* Inverse of the cubic Bernstein matrix at t = 0, 1/3, 2/3, 1 (rows: samples, columns: basis). */
static void bernstein_inverse(double inv[4][4])
{
    double m[4][8];
    for (int a = 0; a < 4; a++) {
        double t = a / 3.0, B[4];
        bezier_basis(3, t, B, NULL);
        for (int b = 0; b < 4; b++) {
            m[a][b] = B[b];
            m[a][4 + b] = a == b;
        }
    }
    for (int c = 0; c < 4; c++) { /* Gauss–Jordan with partial pivoting */
        int piv = c;
        for (int r = c + 1; r < 4; r++)
            if (fabs(m[r][c]) > fabs(m[piv][c]))
                piv = r;
        for (int k = 0; k < 8; k++) {
            double t = m[c][k];
            m[c][k] = m[piv][k];
            m[piv][k] = t;
        }
        double d = m[c][c];
        for (int k = 0; k < 8; k++)
            m[c][k] /= d;
        for (int r = 0; r < 4; r++)
            if (r != c) {
                double f = m[r][c];
                for (int k = 0; k < 8; k++)
                    m[r][k] -= f * m[c][k];
            }
    }
    for (int a = 0; a < 4; a++)
        for (int b = 0; b < 4; b++)
            inv[a][b] = m[a][4 + b];
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* x, y of the surface between slices k and k+1 at (u, z): the blend over the slices at hand. */
static void surface_xy(const struct curve *cv, const struct contour_set *cs, int k, double u, double z, double *x,
                       double *y)
{
    int n = cs->n_slices, j0 = k > 0 ? k - 1 : k, j1 = k + 2 < n ? k + 2 : k + 1;
    double zs[4], xs[4], ys[4];
    int m = 0;
    for (int j = j0; j <= j1; j++, m++) {
        zs[m] = cs->s[j].z;
        curve_eval(&cv[j], u, &xs[m], &ys[m]);
    }
    if (m == 4) {
        *x = blend(z, zs, xs);
        *y = blend(z, zs, ys);
    } else if (m == 3) { /* an end pair: the one parabola there is */
        *x = parabola(z, zs[0], zs[1], zs[2], xs[0], xs[1], xs[2]);
        *y = parabola(z, zs[0], zs[1], zs[2], ys[0], ys[1], ys[2]);
    } else { /* two slices in all */
        double f = (z - zs[0]) / (zs[1] - zs[0]);
        *x = xs[0] + f * (xs[1] - xs[0]);
        *y = ys[0] + f * (ys[1] - ys[0]);
    }
}

int model_parabolic(const struct contour_set *cs, struct patch_set *set, struct sf_err *err)
{
    int n = cs->n_slices, rc = 0;
    struct curve *cv = calloc((size_t)n, sizeof *cv);
    if (!cv)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (int j = 0; j < n && !rc; j++)
        rc = curve_build(&cs->s[j], &cv[j]);
    double inv[4][4];
    bernstein_inverse(inv);
    double *brk = NULL;
    size_t cap_brk = 0;
    for (int k = 0; k + 1 < n && !rc; k++) {
        /* breakpoints: every parameter of the curves this pair depends on */
        int j0 = k > 0 ? k - 1 : k, j1 = k + 2 < n ? k + 2 : k + 1;
        size_t nb = 0;
        for (int j = j0; j <= j1; j++)
            nb += (size_t)cv[j].n;
        if ((rc = mem_reserve((void **)&brk, &cap_brk, nb + 2, sizeof *brk)))
            break;
        nb = 0;
        brk[nb++] = 0.0;
        brk[nb++] = 1.0;
        for (int j = j0; j <= j1; j++)
            for (int i = 0; i < cv[j].n; i++)
                brk[nb++] = cv[j].u[i];
        qsort(brk, nb, sizeof *brk, cmp_double);
        double z0 = cs->s[k].z, z1 = cs->s[k + 1].z;
        for (size_t b = 0; b + 1 < nb && !rc; b++) {
            double ua = brk[b], ub = brk[b + 1];
            if (ub - ua <= BREAK_EPS)
                continue;
            double S[4][4][2]; /* samples at (u_a, z_c) */
            for (int a = 0; a < 4; a++)
                for (int c = 0; c < 4; c++)
                    surface_xy(cv, cs, k, ua + (ub - ua) * a / 3.0, z0 + (z1 - z0) * c / 3.0, &S[a][c][0], &S[a][c][1]);
            if ((rc = mem_reserve((void **)&set->patches, &set->cap, set->n + 1, sizeof *set->patches)) ||
                (rc = mem_reserve((void **)&set->pool, &set->cap_pool, set->n_pool + 16, sizeof *set->pool)))
                break;
            struct patch *pt = &set->patches[set->n++];
            *pt = (struct patch){3, 3, false, (double(*)[4])(uintptr_t)set->n_pool, 0, ua, ub, z0, z1};
            for (int i = 0; i < 4; i++)
                for (int j = 0; j < 4; j++) {
                    double *P = set->pool[set->n_pool + (size_t)(i * 4 + j)];
                    for (int d = 0; d < 2; d++) { /* P = M^-1 S M^-T */
                        double sum = 0;
                        for (int a = 0; a < 4; a++)
                            for (int c = 0; c < 4; c++)
                                sum += inv[i][a] * S[a][c][d] * inv[j][c];
                        P[d] = sum;
                    }
                    P[2] = z0 + (z1 - z0) * j / 3.0; /* z is linear in v */
                    P[3] = 1.0;
                }
            set->n_pool += 16;
        }
    }
    free(brk);
    for (int j = 0; j < n; j++)
        curve_free(&cv[j]);
    free(cv);
    return rc ? sf_fail(err, SF_ENOMEM, "", "out of memory building the model") : 0;
}

/* Gauss–Legendre nodes and weights on [0, 1]. */
static const double GL5_X[5] = {0.046910077030668, 0.230765344947158, 0.5, 0.769234655052842, 0.953089922969332};
static const double GL5_W[5] = {0.118463442528095, 0.239314335249683, 0.284444444444444, 0.239314335249683,
                                0.118463442528095};
static const double GL8_X[8] = {0.019855071751232, 0.101666761293187, 0.237233795041836, 0.408282678752175,
                                0.591717321247825, 0.762766204958164, 0.898333238706813, 0.980144928248768};
static const double GL8_W[8] = {0.050614268145188, 0.111190517226687, 0.156853322938944, 0.181341891689181,
                                0.181341891689181, 0.156853322938944, 0.111190517226687, 0.050614268145188};

void model_measure(const struct patch_set *set, enum model_caps caps, const double end_gap[2],
                   struct model_measures *m)
{
    memset(m, 0, sizeof *m);
    double zmin = INFINITY, zmax = -INFINITY;
    for (size_t k = 0; k < set->n; k++) {
        zmin = fmin(zmin, set->patches[k].v0);
        zmax = fmax(zmax, set->patches[k].v1);
    }
    for (int d = 0; d < 3; d++)
        m->lo[d] = INFINITY, m->hi[d] = -INFINITY;
    for (size_t k = 0; k < set->n; k++) {
        const struct patch *pt = &set->patches[k];
        vec3 lo, hi;
        bezier_bounds(pt, &lo, &hi);
        m->lo[0] = fmin(m->lo[0], lo.x), m->lo[1] = fmin(m->lo[1], lo.y), m->lo[2] = fmin(m->lo[2], lo.z);
        m->hi[0] = fmax(m->hi[0], hi.x), m->hi[1] = fmax(m->hi[1], hi.y), m->hi[2] = fmax(m->hi[2], hi.z);
        /* seed 000 eq. 21–22: V = ½ ∬ (A Sx + B Sy) du dv; the integrand of a bicubic is of degree
         * 8 in each parameter, which 5-point Gauss–Legendre integrates exactly */
        for (int a = 0; a < 5; a++)
            for (int b = 0; b < 5; b++) {
                vec3 P, Pu, Pv;
                bezier_eval(pt, GL5_X[a], GL5_X[b], &P, &Pu, &Pv);
                double A = Pu.y * Pv.z - Pu.z * Pv.y, B = Pu.z * Pv.x - Pu.x * Pv.z;
                m->volume_flat += 0.5 * GL5_W[a] * GL5_W[b] * (A * P.x + B * P.y);
            }
        /* end curves: area = ∮ x dy along the v = 0 edge at the first slice and v = 1 at the last
         * (counter-clockwise in u); the integrand is of degree 5, exact with 5 points */
        for (int e = 0; e < 2; e++) {
            if ((e == 0 && pt->v0 != zmin) || (e == 1 && pt->v1 != zmax))
                continue;
            for (int a = 0; a < 5; a++) {
                vec3 P, Pu;
                bezier_eval(pt, GL5_X[a], e, &P, &Pu, NULL);
                m->end_area[e] += GL5_W[a] * P.x * Pu.y;
            }
            for (int a = 0; a < 8; a++) {
                vec3 Pu;
                bezier_eval(pt, GL8_X[a], e, NULL, &Pu, NULL);
                m->end_perimeter[e] += GL8_W[a] * v3_len(Pu);
            }
        }
        for (int a = 0; a < 8; a++)
            for (int b = 0; b < 8; b++) {
                vec3 Pu, Pv;
                bezier_eval(pt, GL8_X[a], GL8_X[b], NULL, &Pu, &Pv);
                m->area += GL8_W[a] * GL8_W[b] * v3_len(v3_cross(Pu, Pv));
            }
    }
    m->volume = m->volume_flat;
    m->area += m->end_area[0] + m->end_area[1]; /* the caps */
    if (caps == CAPS_SLAB) {
        m->volume += 0.5 * (m->end_area[0] * end_gap[0] + m->end_area[1] * end_gap[1]);
        m->area += 0.5 * (m->end_perimeter[0] * end_gap[0] + m->end_perimeter[1] * end_gap[1]);
    }
}
