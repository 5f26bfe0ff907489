/* contour.c - cleaning slice contours and the polygon baselines. Written by hand: a few hundred
 * points per contour, where the quadratic self-crossing test costs microseconds. */
#include "contour.h"

#include <math.h>
#include <stdio.h>
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

static int by_z(const void *a, const void *b)
{
    double za = ((const struct contour_slice *)a)->z, zb = ((const struct contour_slice *)b)->z;
    return za < zb ? -1 : za > zb;
}

/* Orientation of (a, b, c): >0 counter-clockwise. */
static double orient(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Proper or touching intersection of segments ab and cd. */
static int segments_meet(const double *a, const double *b, const double *c, const double *d)
{
    double o1 = orient(a, b, c), o2 = orient(a, b, d), o3 = orient(c, d, a), o4 = orient(c, d, b);
    if (((o1 > 0 && o2 < 0) || (o1 < 0 && o2 > 0)) && ((o3 > 0 && o4 < 0) || (o3 < 0 && o4 > 0)))
        return 1;
    return 0; /* collinear touching is left to the duplicate-point rule */
}

int contour_clean(struct contour_set *cs, struct sf_err *err)
{
    char ptr[64];
    for (int k = 0; k < cs->n_slices; k++) {
        struct contour_slice *s = &cs->s[k];
        snprintf(ptr, sizeof ptr, "/slices/%d/points", s->src);
        if (!isfinite(s->z)) {
            snprintf(ptr, sizeof ptr, "/slices/%d/z", s->src);
            return sf_fail(err, SF_EINVAL, ptr, "z must be a finite number");
        }
        int m = 0;
        for (int i = 0; i < s->n; i++) {
            if (!isfinite(s->p[i][0]) || !isfinite(s->p[i][1]))
                return sf_fail(err, SF_EINVAL, ptr, "point %d is not two finite numbers", i);
            if (m > 0 && fabs(s->p[i][0] - s->p[m - 1][0]) <= POINT_EPS && fabs(s->p[i][1] - s->p[m - 1][1]) <= POINT_EPS)
                continue; /* repeated point */
            s->p[m][0] = s->p[i][0];
            s->p[m][1] = s->p[i][1];
            m++;
        }
        while (m > 1 && fabs(s->p[m - 1][0] - s->p[0][0]) <= POINT_EPS && fabs(s->p[m - 1][1] - s->p[0][1]) <= POINT_EPS)
            m--; /* repeated closing point */
        s->n = m;
        if (m < 3)
            return sf_fail(err, SF_EINVAL, ptr, "a contour needs at least 3 distinct points, this one has %d", m);
        for (int i = 0; i < m; i++) /* a contour that crosses itself cannot bound a solid */
            for (int j = i + 2; j < m; j++) {
                if (i == 0 && j == m - 1)
                    continue; /* neighbours through the closing edge */
                if (segments_meet(s->p[i], s->p[(i + 1) % m], s->p[j], s->p[(j + 1) % m]))
                    return sf_fail(err, SF_EINVAL, ptr, "the contour crosses itself (edges %d and %d)", i, j);
            }
        double a = contour_area(s);
        if (!(fabs(a) > 0))
            return sf_fail(err, SF_EINVAL, ptr, "the contour encloses no area");
        if (a < 0) /* clockwise: reverse */
            for (int i = 0, j = m - 1; i < j; i++, j--) {
                double t0 = s->p[i][0], t1 = s->p[i][1];
                s->p[i][0] = s->p[j][0], s->p[i][1] = s->p[j][1];
                s->p[j][0] = t0, s->p[j][1] = t1;
            }
    }
    qsort(cs->s, (size_t)cs->n_slices, sizeof *cs->s, by_z);
    for (int k = 1; k < cs->n_slices; k++)
        if (cs->s[k].z == cs->s[k - 1].z) {
            snprintf(ptr, sizeof ptr, "/slices/%d/z", cs->s[k].src);
            return sf_fail(err, SF_EINVAL, ptr,
                           "two contours at z = %g: several contours per slice are not supported yet", cs->s[k].z);
        }
    if (cs->n_slices < 2)
        return sf_fail(err, SF_EINVAL, "/slices", "a model needs at least 2 slices, got %d", cs->n_slices);
    return 0;
}

void contour_baselines(const struct contour_set *cs, struct contour_baselines *b)
{
    memset(b, 0, sizeof *b);
    int n = cs->n_slices;
    for (int k = 0; k < n; k++) {
        double a = fabs(contour_area(&cs->s[k]));
        /* Cavalieri: the slab around each slice reaches half way to its neighbours (a full
         * spacing at the ends), which for even spacing is the usual A_k h */
        double lo = k > 0 ? 0.5 * (cs->s[k].z - cs->s[k - 1].z) : 0.5 * (cs->s[1].z - cs->s[0].z);
        double hi = k < n - 1 ? 0.5 * (cs->s[k + 1].z - cs->s[k].z) : 0.5 * (cs->s[n - 1].z - cs->s[n - 2].z);
        b->cavalieri += a * (lo + hi);
        if (k + 1 < n) {
            double a2 = fabs(contour_area(&cs->s[k + 1])), h = cs->s[k + 1].z - cs->s[k].z;
            b->trapezoid += h * 0.5 * (a + a2);
            b->frustum += h / 3.0 * (a + a2 + sqrt(a * a2));
        }
    }
}
