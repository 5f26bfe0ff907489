/* nurbs.c - B-spline and NURBS surfaces: validation, Cox–de Boor evaluation (Piegl & Tiller
 * A2.1/A2.3, first derivatives), Boehm knot insertion and Bézier extraction.
 * Written by hand: the surfaces are small, and the tracer needs them as homogeneous Bézier
 * patches in its own layout, which no Debian library produces. */
#include "nurbs.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

#define KNOT_EPS 1e-12 /* knot values closer than this (relative to the domain) are one knot */

int nurbs_surface_alloc(struct surface *s, enum surf_kind kind, int deg_u, int deg_v, int n_u, int n_v,
                        struct sf_err *err)
{
    memset(s, 0, sizeof *s);
    s->kind = kind;
    s->deg_u = deg_u;
    s->deg_v = deg_v;
    s->n_u = n_u;
    s->n_v = n_v;
    if (deg_u < 1 || deg_v < 1 || deg_u > PATCH_MAX_DEGREE || deg_v > PATCH_MAX_DEGREE)
        return sf_fail(err, SF_EINVAL, "degree", "degrees must be between 1 and %d, not [%d, %d]",
                       PATCH_MAX_DEGREE, deg_u, deg_v);
    if (n_u <= deg_u || n_v <= deg_v)
        return sf_fail(err, SF_EINVAL, "size", "size [%d, %d] needs at least degree+1 points each way", n_u, n_v);
    if ((long long)n_u * n_v > SURF_MAX_POINTS)
        return sf_fail(err, SF_ELIMIT, "size", "%d x %d control points exceed the limit of %d", n_u, n_v,
                       SURF_MAX_POINTS);
    size_t np = (size_t)n_u * n_v;
    s->knots_u = malloc(sizeof(double) * (size_t)(n_u + deg_u + 1));
    s->knots_v = malloc(sizeof(double) * (size_t)(n_v + deg_v + 1));
    s->points = malloc(sizeof(double) * 3 * np);
    if (kind == SURF_NURBS)
        s->weights = malloc(sizeof(double) * np);
    if (!s->knots_u || !s->knots_v || !s->points || (kind == SURF_NURBS && !s->weights)) {
        nurbs_surface_free(s);
        return sf_fail(err, SF_ENOMEM, "", "out of memory for a %d x %d surface", n_u, n_v);
    }
    if (kind == SURF_BEZIER) {
        for (int k = 0; k < n_u + deg_u + 1; k++)
            s->knots_u[k] = k < n_u ? 0.0 : 1.0;
        for (int k = 0; k < n_v + deg_v + 1; k++)
            s->knots_v[k] = k < n_v ? 0.0 : 1.0;
    }
    return 0;
}

void nurbs_surface_free(struct surface *s)
{
    if (!s)
        return;
    free(s->knots_u);
    free(s->knots_v);
    free(s->points);
    free(s->weights);
    s->knots_u = s->knots_v = s->points = s->weights = NULL;
}

static int check_knots(const double *U, int n, int p, const char *where, const char *name, struct sf_err *err)
{
    int m = n + p + 1;
    char ptr[160];
    for (int k = 0; k < m; k++) {
        if (!isfinite(U[k])) {
            snprintf(ptr, sizeof ptr, "%s/%s/%d", where, name, k);
            return sf_fail(err, SF_EINVAL, ptr, "knot %d is not a finite number", k);
        }
        if (k > 0 && U[k] < U[k - 1]) {
            snprintf(ptr, sizeof ptr, "%s/%s/%d", where, name, k);
            return sf_fail(err, SF_EINVAL, ptr, "knots must be non-decreasing: knot %d (%g) < knot %d (%g)", k,
                           U[k], k - 1, U[k - 1]);
        }
    }
    snprintf(ptr, sizeof ptr, "%s/%s", where, name);
    if (!(U[n] > U[p]))
        return sf_fail(err, SF_EINVAL, ptr, "the domain [knot %d, knot %d] = [%g, %g] is empty", p, n, U[p], U[n]);
    /* an interior knot repeated more than degree times breaks the surface apart */
    for (int k = p + 1; k < n;) {
        int r = k;
        while (r + 1 < n && U[r + 1] == U[k])
            r++;
        if (r - k + 1 > p) {
            snprintf(ptr, sizeof ptr, "%s/%s/%d", where, name, k);
            return sf_fail(err, SF_EINVAL, ptr, "interior knot %g repeats %d times, more than the degree %d", U[k],
                           r - k + 1, p);
        }
        k = r + 1;
    }
    return 0;
}

int nurbs_validate(const struct surface *s, const char *where, struct sf_err *err)
{
    char ptr[160];
    int rc = check_knots(s->knots_u, s->n_u, s->deg_u, where, "knots_u", err);
    if (rc)
        return rc;
    rc = check_knots(s->knots_v, s->n_v, s->deg_v, where, "knots_v", err);
    if (rc)
        return rc;
    size_t np = (size_t)s->n_u * s->n_v;
    for (size_t k = 0; k < np; k++) {
        for (int c = 0; c < 3; c++)
            if (!(fabs(s->points[3 * k + c]) <= SURF_MAX_COORD)) {
                snprintf(ptr, sizeof ptr, "%s/points/%zu/%d", where, k, c);
                return sf_fail(err, SF_EINVAL, ptr, "coordinate %d of point %zu is %g; coordinates are finite and within ±%g", c,
                               k, s->points[3 * k + c], SURF_MAX_COORD);
            }
        if (s->weights && !(s->weights[k] > 0.0 && isfinite(s->weights[k]))) {
            snprintf(ptr, sizeof ptr, "%s/weights/%zu", where, k);
            return sf_fail(err, SF_EINVAL, ptr, "weight %zu is %g; weights must be positive and finite", k,
                           s->weights[k]);
        }
    }
    return 0;
}

void nurbs_domain(const struct surface *s, double *u0, double *u1, double *v0, double *v1)
{
    *u0 = s->knots_u[s->deg_u];
    *u1 = s->knots_u[s->n_u];
    *v0 = s->knots_v[s->deg_v];
    *v1 = s->knots_v[s->n_v];
}

/* The span s in [p, n-1] with U[s] <= t < U[s+1] (t >= U[n]: n-1), as Piegl & Tiller's FindSpan. */
static int span_of(const double *U, int n, int p, double t)
{
    if (t >= U[n])
        return n - 1;
    int lo = p, hi = n;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (t < U[mid])
            hi = mid;
        else
            lo = mid;
    }
    return lo;
}

/* Knot span index r with U[r] <= t < U[r+1], clamped into [p, n-1] (Piegl & Tiller A2.1). */
static int find_span(const double *U, int n, int p, double t)
{
    if (t >= U[n]) { /* the last non-empty span, so the domain's end point evaluates */
        int r = n - 1;
        while (r > p && !(U[r + 1] > U[r]))
            r--;
        return r;
    }
    if (t <= U[p])
        return p;
    return span_of(U, n, p, t);
}

/* Non-zero basis functions N[0..p] and first derivatives dN[0..p] at t in span r (A2.3). */
static void basis_funs(const double *U, int r, int p, double t, double *N, double *dN)
{
    double left[PATCH_MAX_DEGREE + 1], right[PATCH_MAX_DEGREE + 1];
    double ndu[PATCH_MAX_DEGREE + 1][PATCH_MAX_DEGREE + 1];
    ndu[0][0] = 1.0;
    for (int j = 1; j <= p; j++) {
        left[j] = t - U[r + 1 - j];
        right[j] = U[r + j] - t;
        double saved = 0.0;
        for (int k = 0; k < j; k++) {
            ndu[j][k] = right[k + 1] + left[j - k]; /* lower triangle: knot differences */
            double tmp = ndu[k][j - 1] / ndu[j][k];
            ndu[k][j] = saved + right[k + 1] * tmp;
            saved = left[j - k] * tmp;
        }
        ndu[j][j] = saved;
    }
    for (int j = 0; j <= p; j++)
        N[j] = ndu[j][p];
    /* first derivative: N'_{k,p} = p (N_{k,p-1}/(U[k+p]-U[k]) - N_{k+1,p-1}/(U[k+p+1]-U[k+1])) */
    for (int k = 0; k <= p; k++) {
        double d = 0.0;
        if (k >= 1)
            d += ndu[k - 1][p - 1] / ndu[p][k - 1];
        if (k <= p - 1)
            d -= ndu[k][p - 1] / ndu[p][k];
        dN[k] = p * d;
    }
}

int nurbs_basis(const double *U, int n, int p, double t, double *N)
{
    double dN[PATCH_MAX_DEGREE + 1];
    int r = find_span(U, n, p, t);
    basis_funs(U, r, p, t, N, dN);
    return r;
}

void nurbs_eval(const struct surface *s, double u, double v, vec3 *P, vec3 *Pu, vec3 *Pv)
{
    int p = s->deg_u, q = s->deg_v;
    int ru = find_span(s->knots_u, s->n_u, p, u), rv = find_span(s->knots_v, s->n_v, q, v);
    double Nu[PATCH_MAX_DEGREE + 1], dNu[PATCH_MAX_DEGREE + 1];
    double Nv[PATCH_MAX_DEGREE + 1], dNv[PATCH_MAX_DEGREE + 1];
    basis_funs(s->knots_u, ru, p, u, Nu, dNu);
    basis_funs(s->knots_v, rv, q, v, Nv, dNv);
    double S[4] = {0}, Su[4] = {0}, Sv[4] = {0};
    for (int a = 0; a <= p; a++)
        for (int b = 0; b <= q; b++) {
            size_t k = (size_t)(ru - p + a) * s->n_v + (size_t)(rv - q + b);
            double w = s->weights ? s->weights[k] : 1.0;
            double h[4] = {s->points[3 * k] * w, s->points[3 * k + 1] * w, s->points[3 * k + 2] * w, w};
            for (int c = 0; c < 4; c++) {
                S[c] += Nu[a] * Nv[b] * h[c];
                Su[c] += dNu[a] * Nv[b] * h[c];
                Sv[c] += Nu[a] * dNv[b] * h[c];
            }
        }
    vec3 pt = v3(S[0] / S[3], S[1] / S[3], S[2] / S[3]);
    if (P)
        *P = pt;
    if (Pu)
        *Pu = v3((Su[0] - pt.x * Su[3]) / S[3], (Su[1] - pt.y * Su[3]) / S[3], (Su[2] - pt.z * Su[3]) / S[3]);
    if (Pv)
        *Pv = v3((Sv[0] - pt.x * Sv[3]) / S[3], (Sv[1] - pt.y * Sv[3]) / S[3], (Sv[2] - pt.z * Sv[3]) / S[3]);
}

/* Homogeneous copy of the net: 4 doubles per point. */
static double (*to_homogeneous(const struct surface *s))[4]
{
    size_t np = (size_t)s->n_u * s->n_v;
    double(*h)[4] = malloc(sizeof *h * np);
    if (!h)
        return NULL;
    for (size_t k = 0; k < np; k++) {
        double w = s->weights ? s->weights[k] : 1.0;
        h[k][0] = s->points[3 * k] * w;
        h[k][1] = s->points[3 * k + 1] * w;
        h[k][2] = s->points[3 * k + 2] * w;
        h[k][3] = w;
    }
    return h;
}

/* Boehm insertion of t into a homogeneous net along u. Pw has n_u*n_v points; returns the new
 * net of (n_u+1)*n_v points and the new knot vector, or NULL on allocation failure. */
static double (*insert_u(double (*Pw)[4], double **U, int *n_u, int n_v, int p, double t))[4]
{
    int n = *n_u;
    int r = find_span(*U, n, p, t);
    double(*Q)[4] = malloc(sizeof *Q * (size_t)(n + 1) * n_v);
    double *V = malloc(sizeof *V * (size_t)(n + p + 2));
    if (!Q || !V) {
        free(Q);
        free(V);
        return NULL;
    }
    const double *K = *U;
    for (int k = 0; k <= r; k++)
        V[k] = K[k];
    V[r + 1] = t;
    for (int k = r + 1; k < n + p + 1; k++)
        V[k + 1] = K[k];
    for (int i = 0; i <= n; i++) {
        double a;
        if (i <= r - p)
            a = 1.0;
        else if (i > r)
            a = 0.0;
        else
            a = (t - K[i]) / (K[i + p] - K[i]);
        for (int j = 0; j < n_v; j++) {
            double *q = Q[(size_t)i * n_v + j];
            const double *pi = i < n ? Pw[(size_t)i * n_v + j] : Pw[(size_t)(n - 1) * n_v + j];
            const double *pm = i > 0 ? Pw[(size_t)(i - 1) * n_v + j] : pi;
            for (int c = 0; c < 4; c++)
                q[c] = a * pi[c] + (1.0 - a) * pm[c];
        }
    }
    free(*U);
    *U = V;
    *n_u = n + 1;
    return Q;
}

static void from_homogeneous(struct surface *s, double (*h)[4])
{
    size_t np = (size_t)s->n_u * s->n_v;
    for (size_t k = 0; k < np; k++) {
        s->points[3 * k] = h[k][0] / h[k][3];
        s->points[3 * k + 1] = h[k][1] / h[k][3];
        s->points[3 * k + 2] = h[k][2] / h[k][3];
        if (s->weights)
            s->weights[k] = h[k][3];
    }
}

int nurbs_insert_knot_u(struct surface *s, double t)
{
    double(*h)[4] = to_homogeneous(s);
    if (!h)
        return SF_ENOMEM;
    int n_u = s->n_u;
    double(*q)[4] = insert_u(h, &s->knots_u, &n_u, s->n_v, s->deg_u, t);
    free(h);
    if (!q)
        return SF_ENOMEM;
    size_t np = (size_t)n_u * s->n_v;
    double *pts = realloc(s->points, sizeof(double) * 3 * np);
    if (pts)
        s->points = pts;
    double *w = s->weights ? realloc(s->weights, sizeof(double) * np) : NULL;
    if (w)
        s->weights = w;
    if (!pts || (s->weights && !w)) {
        free(q);
        return SF_ENOMEM;
    }
    s->n_u = n_u;
    from_homogeneous(s, q);
    free(q);
    return 0;
}

/* Transposes an nu x nv homogeneous net into nv x nu. */
static double (*transpose_h(double (*h)[4], int nu, int nv))[4]
{
    double(*t)[4] = malloc(sizeof *t * (size_t)nu * nv);
    if (!t)
        return NULL;
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++)
            memcpy(t[(size_t)j * nu + i], h[(size_t)i * nv + j], sizeof *t);
    return t;
}

int nurbs_transpose(struct surface *s)
{
    double(*h)[4] = to_homogeneous(s);
    if (!h)
        return SF_ENOMEM;
    double(*t)[4] = transpose_h(h, s->n_u, s->n_v);
    free(h);
    if (!t)
        return SF_ENOMEM;
    int tmp = s->n_u;
    s->n_u = s->n_v;
    s->n_v = tmp;
    tmp = s->deg_u;
    s->deg_u = s->deg_v;
    s->deg_v = tmp;
    double *k = s->knots_u;
    s->knots_u = s->knots_v;
    s->knots_v = k;
    from_homogeneous(s, t);
    free(t);
    return 0;
}

/* Inserts every distinct knot of the domain [U[p], U[n]] until its multiplicity is p, so that
 * each non-empty span's p+1 points are Bézier points. Knots within KNOT_EPS of their neighbour
 * count as one. All insertions at once (Piegl & Tiller A5.4, knot refinement): O((n + r) p n_v)
 * for r new knots, where inserting them one at a time copies the whole net r times. Works on the
 * homogeneous net h of n_u x n_v points; takes ownership of h and returns the refined net (NULL
 * when out of memory, h freed all the same). */
static double (*refine_to_bezier(double (*h)[4], double **U, int *n_u, int n_v, int p))[4]
{
    const int n = *n_u;
    const double *K = *U;
    const double a = K[p], b = K[n], eps = KNOT_EPS * (b - a);
    int cnt = 0;
    double *X = NULL;
    for (int pass = 0; pass < 2; pass++) { /* count, then fill */
        cnt = 0;
        for (int i0 = 0, i1; i0 < n + p + 1; i0 = i1) {
            for (i1 = i0 + 1; i1 < n + p + 1 && K[i1] - K[i1 - 1] <= eps; i1++)
                ;
            if (K[i0] < a - eps || K[i0] > b + eps)
                continue;
            for (int c = i1 - i0; c < p; c++, cnt++)
                if (pass)
                    X[cnt] = K[i0];
        }
        if (cnt == 0)
            return h;
        if (!pass && !(X = malloc(sizeof *X * (size_t)cnt))) {
            free(h);
            return NULL;
        }
    }
    double(*Q)[4] = malloc(sizeof *Q * (size_t)(n + cnt) * n_v);
    double *V = malloc(sizeof *V * (size_t)(n + cnt + p + 1));
    if (!Q || !V) {
        free(Q), free(V), free(X), free(h);
        return NULL;
    }
    const size_t row = sizeof *Q * (size_t)n_v;
#define ROW(net, i) ((net) + (size_t)(i) * n_v)
    int sa = span_of(K, n, p, X[0]), sb = span_of(K, n, p, X[cnt - 1]) + 1;
    for (int j = 0; j <= sa - p; j++)
        memcpy(ROW(Q, j), ROW(h, j), row);
    for (int j = sb - 1; j < n; j++)
        memcpy(ROW(Q, j + cnt), ROW(h, j), row);
    for (int j = 0; j <= sa; j++)
        V[j] = K[j];
    for (int j = sb + p; j <= n + p; j++)
        V[j + cnt] = K[j];
    int i = sb + p - 1, k = sb + p + cnt - 1;
    for (int j = cnt - 1; j >= 0; j--) {
        while (X[j] <= K[i] && i > sa) {
            memcpy(ROW(Q, k - p - 1), ROW(h, i - p - 1), row);
            V[k] = K[i];
            k--, i--;
        }
        memcpy(ROW(Q, k - p - 1), ROW(Q, k - p), row);
        for (int l = 1; l <= p; l++) {
            int ind = k - p + l;
            double alfa = V[k + l] - X[j];
            if (alfa == 0.0) {
                memcpy(ROW(Q, ind - 1), ROW(Q, ind), row);
                continue;
            }
            alfa /= V[k + l] - K[i - p + l];
            double(*lo)[4] = ROW(Q, ind - 1), (*hi)[4] = ROW(Q, ind);
            for (int c = 0; c < n_v; c++)
                for (int d = 0; d < 4; d++)
                    lo[c][d] = alfa * lo[c][d] + (1.0 - alfa) * hi[c][d];
        }
        V[k] = X[j];
        k--;
    }
#undef ROW
    free(X);
    free(h);
    free(*U);
    *U = V;
    *n_u = n + cnt;
    return Q;
}

int nurbs_extract(const struct surface *s, int surface_index, struct patch_set *set)
{
    int rc = SF_ENOMEM;
    int p = s->deg_u, q = s->deg_v, n_u = s->n_u, n_v = s->n_v;
    double *U = malloc(sizeof *U * (size_t)(n_u + p + 1));
    double *V = malloc(sizeof *V * (size_t)(n_v + q + 1));
    double(*h)[4] = to_homogeneous(s), (*t)[4] = NULL;
    if (!U || !V || !h)
        goto out_free;
    memcpy(U, s->knots_u, sizeof *U * (size_t)(n_u + p + 1));
    memcpy(V, s->knots_v, sizeof *V * (size_t)(n_v + q + 1));
    if (!(h = refine_to_bezier(h, &U, &n_u, n_v, p)))
        goto out_free;
    if (!(t = transpose_h(h, n_u, n_v)))
        goto out_free;
    free(h);
    h = NULL;
    if (!(t = refine_to_bezier(t, &V, &n_v, n_u, q))) /* t is now n_v x n_u */
        goto out_free;

    bool rational = false;
    if (s->weights)
        for (size_t k = 0; k < (size_t)s->n_u * s->n_v; k++)
            rational |= s->weights[k] != s->weights[0];
    for (int ru = p; ru < n_u; ru++) {
        if (!(U[ru + 1] > U[ru]))
            continue;
        for (int rv = q; rv < n_v; rv++) {
            if (!(V[rv + 1] > V[rv]))
                continue;
            if (mem_reserve((void **)&set->patches, &set->cap, set->n + 1, sizeof *set->patches) ||
                mem_reserve((void **)&set->pool, &set->cap_pool, set->n_pool + (size_t)(p + 1) * (q + 1), sizeof *set->pool))
                goto out_free;
            /* every field set: the second-difference bounds zero (wmin 0: not set), as the other
             * patch makers leave them, where a stale heap value sent the solver's steps astray */
            set->patches[set->n++] = (struct patch){.p = p, .q = q, .rational = rational, .surface = surface_index,
                                                    .u0 = U[ru], .u1 = U[ru + 1], .v0 = V[rv], .v1 = V[rv + 1],
                                                    /* an offset until nurbs_patches_fix() */
                                                    .cw = (double(*)[4])(uintptr_t)set->n_pool};
            for (int i = 0; i <= p; i++)
                for (int j = 0; j <= q; j++) {
                    const double *src = t[(size_t)(rv - q + j) * n_u + (size_t)(ru - p + i)];
                    double *dst = set->pool[set->n_pool++];
                    memcpy(dst, src, sizeof(double) * 4);
                    if (!rational) { /* constant weight: divide it out so w = 1 exactly */
                        for (int c = 0; c < 3; c++)
                            dst[c] /= dst[3];
                        dst[3] = 1.0;
                    }
                }
        }
    }
    rc = 0;
out_free:
    free(t);
    free(h);
    free(U);
    free(V);
    return rc;
}

void nurbs_patches_fix(struct patch_set *set)
{
    for (size_t k = 0; k < set->n; k++)
        set->patches[k].cw = set->pool + (uintptr_t)set->patches[k].cw;
}

void nurbs_patch_set_free(struct patch_set *set)
{
    if (!set)
        return;
    free(set->patches);
    free(set->pool);
    memset(set, 0, sizeof *set);
}
