/* bvh_cone.c - the directions a Bézier patch's normals and chords take, bounded from its net: the
 * normal cone of a leaf (its normals' Bernstein coefficients), the chord bound of a patch or of two
 * that share a seam (its differences), a rational patch's numerators for both, and the flatness of
 * a net (net_deviation). Geometry only: bvh.c builds the hierarchy and answers the rays with them. */
#include "bvh_cone.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The differences of the net's Euclidean points along u (du[i][j] = P[i+1][j] - P[i][j]) and
 * along v (dv[i][j] = P[i][j+1] - P[i][j]): Pu and Pv are their Bernstein combinations, times
 * the degrees. */
static void net_differences(const struct patch *pt, vec3 du[][PATCH_MAX_DEGREE + 1], vec3 dv[][PATCH_MAX_DEGREE])
{
    for (int i = 0; i <= pt->p; i++)
        for (int j = 0; j <= pt->q; j++) {
            vec3 c = bezier_point(pt, i, j);
            if (i < pt->p)
                du[i][j] = v3_sub(bezier_point(pt, i + 1, j), c);
            if (j < pt->q)
                dv[i][j] = v3_sub(bezier_point(pt, i, j + 1), c);
        }
}

/* The cone of directions holding every coefficient c[m * stride + n] (m <= M, n <= N) that is not
 * zero: *axis and the sine of its half-angle, *sin_half (> 1: none narrower than a hemisphere). */
static void cone_of(const vec3 *c, int stride, int M, int N, vec3 *axis, double *sin_half)
{
    *sin_half = 2.0;
    vec3 sum = v3(0, 0, 0);
    for (int m = 0; m <= M; m++)
        for (int n = 0; n <= N; n++)
            sum = v3_add(sum, v3_norm(c[m * stride + n]));
    if (v3_len(sum) == 0.0)
        return;
    vec3 ax = v3_norm(sum);
    double cos_min = 1.0;
    for (int m = 0; m <= M; m++)
        for (int n = 0; n <= N; n++) {
            double l = v3_len(c[m * stride + n]);
            if (l > 0)
                cos_min = fmin(cos_min, v3_dot(ax, c[m * stride + n]) / l);
        }
    if (cos_min <= 0.0)
        return; /* wider than a hemisphere: no use */
    *axis = ax;
    *sin_half = sqrt(fmax(0.0, 1.0 - cos_min * cos_min)) + 1e-9;
}

/* The net of pt's part over [u0, u1] x [v0, v1] (de Casteljau twice each way) into out; tmp holds
 * as many points as out. */
void sub_net(const struct patch *pt, double u0, double u1, double v0, double v1, double (*out)[4],
             double (*tmp)[4])
{
    struct patch a = *pt, b = *pt;
    a.cw = tmp, b.cw = out;
    bezier_split_u(pt, u1, tmp, out);             /* tmp: [0, u1] */
    bezier_split_u(&a, u0 / u1, out, tmp);        /* tmp: [u0, u1] (u1 > 0: it holds a leaf) */
    bezier_split_v(&a, v1, out, tmp);             /* out: [u0, u1] x [0, v1] */
    bezier_split_v(&b, v0 / v1, tmp, out);        /* out: [u0, u1] x [v0, v1] */
}

/* ---- rational patches: their derivatives' directions as Bernstein polynomials --------------- */

/* A rational patch P = s / w (s the net's x·w, y·w, z·w) has Pu = (su w - s wu) / w², and
 * Pu × Pv = (w su × sv + wv s × su + wu sv × s) / w³. With every weight positive the numerators
 * are polynomials whose Bernstein coefficients hold the directions of every tangent along u
 * (degree (2p-1, 2q)), along v, and every normal (degree (3p-1, 3q-1)), as a polynomial patch's
 * differences and cross products do: a product of two Bernstein polynomials of degrees a and b
 * has degree a + b, the term (i, k) weighted C(a,i) C(b,k) / C(a+b,i+k) each way. (The degrees'
 * factors p and q, common to every term, are left out.) */

struct vpoly { /* a polynomial with vector or scalar coefficients, degree (m, n) */
    int m, n;
    vec3 c[RAT_N][RAT_N];
};
struct spoly {
    int m, n;
    double c[RAT_N][RAT_N];
};

struct rnet { /* a rational net split up: s and w, and their differences along u and v */
    struct vpoly s, su, sv;
    struct spoly w, wu, wv;
    double bin[RAT_N][RAT_N]; /* binomials up to the normals' degree */
};

/* False where the patch is polynomial, of too high a degree, or a weight is not positive. */
static bool rnet_of(const struct patch *pt, struct rnet *r)
{
    int p = pt->p, q = pt->q;
    if (!pt->rational || p > RATIONAL_MAX_DEGREE || q > RATIONAL_MAX_DEGREE || p < 1 || q < 1)
        return false;
    for (int n = 0; n < RAT_N; n++)
        for (int k = 0; k <= n; k++)
            r->bin[n][k] = k == 0 || k == n ? 1.0 : r->bin[n - 1][k - 1] + r->bin[n - 1][k];
    r->s.m = r->w.m = r->sv.m = r->wv.m = p, r->s.n = r->w.n = r->su.n = r->wu.n = q;
    r->su.m = r->wu.m = p - 1, r->sv.n = r->wv.n = q - 1;
    for (int i = 0; i <= p; i++)
        for (int j = 0; j <= q; j++) {
            const double *c = pt->cw[i * (q + 1) + j];
            if (!(c[3] > 0.0))
                return false;
            r->s.c[i][j] = v3(c[0], c[1], c[2]), r->w.c[i][j] = c[3];
        }
    for (int i = 0; i <= p; i++)
        for (int j = 0; j <= q; j++) {
            if (i < p)
                r->su.c[i][j] = v3_sub(r->s.c[i + 1][j], r->s.c[i][j]), r->wu.c[i][j] = r->w.c[i + 1][j] - r->w.c[i][j];
            if (j < q)
                r->sv.c[i][j] = v3_sub(r->s.c[i][j + 1], r->s.c[i][j]), r->wv.c[i][j] = r->w.c[i][j + 1] - r->w.c[i][j];
        }
    return true;
}

static void vpoly_zero(struct vpoly *out, int m, int n)
{
    out->m = m, out->n = n;
    for (int i = 0; i <= m; i++)
        for (int j = 0; j <= n; j++)
            out->c[i][j] = v3(0, 0, 0);
}

/* The weights of a product of degrees a and b, one way: w[i][k] = C(a,i) C(b,k) / C(a+b,i+k). */
static void product_weights(int a, int b, const double (*bin)[RAT_N], double (*w)[RAT_N])
{
    for (int i = 0; i <= a; i++)
        for (int k = 0; k <= b; k++)
            w[i][k] = bin[a][i] * bin[b][k] / bin[a + b][i + k];
}

/* out += f a b (a scalar polynomial times a vector one; out of degree a's plus b's) */
static void vpoly_add_scaled(struct vpoly *out, double f, const struct spoly *a, const struct vpoly *b,
                             const double (*bin)[RAT_N])
{
    double wu[RAT_N][RAT_N], wv[RAT_N][RAT_N];
    product_weights(a->m, b->m, bin, wu);
    product_weights(a->n, b->n, bin, wv);
    for (int i = 0; i <= a->m; i++)
        for (int j = 0; j <= a->n; j++)
            for (int k = 0; k <= b->m; k++) {
                const double fa = f * a->c[i][j] * wu[i][k];
                for (int l = 0; l <= b->n; l++)
                    out->c[i + k][j + l] = v3_mad(out->c[i + k][j + l], b->c[k][l], fa * wv[j][l]);
            }
}

/* out = a × b */
static void vpoly_cross(struct vpoly *out, const struct vpoly *a, const struct vpoly *b, const double (*bin)[RAT_N])
{
    double wu[RAT_N][RAT_N], wv[RAT_N][RAT_N];
    product_weights(a->m, b->m, bin, wu);
    product_weights(a->n, b->n, bin, wv);
    vpoly_zero(out, a->m + b->m, a->n + b->n);
    for (int i = 0; i <= a->m; i++)
        for (int j = 0; j <= a->n; j++)
            for (int k = 0; k <= b->m; k++)
                for (int l = 0; l <= b->n; l++)
                    out->c[i + k][j + l] =
                        v3_mad(out->c[i + k][j + l], v3_cross(a->c[i][j], b->c[k][l]), wu[i][k] * wv[j][l]);
}

/* The tangents' numerators: su w - s wu (along u) and sv w - s wv (along v). */
static void rational_tangents(const struct rnet *r, struct vpoly *tu, struct vpoly *tv)
{
    vpoly_zero(tu, r->su.m + r->w.m, r->su.n + r->w.n);
    vpoly_add_scaled(tu, 1.0, &r->w, &r->su, r->bin);
    vpoly_add_scaled(tu, -1.0, &r->wu, &r->s, r->bin);
    vpoly_zero(tv, r->sv.m + r->w.m, r->sv.n + r->w.n);
    vpoly_add_scaled(tv, 1.0, &r->w, &r->sv, r->bin);
    vpoly_add_scaled(tv, -1.0, &r->wv, &r->s, r->bin);
}

/* The normals' numerator: w su × sv + wv s × su + wu sv × s. */
static void rational_normals(const struct rnet *r, struct vpoly *out)
{
    struct vpoly *x = malloc(sizeof *x);
    vpoly_zero(out, 3 * r->s.m - 1, 3 * r->s.n - 1);
    if (!x) { /* (no cone: every coefficient zero) */
        return;
    }
    vpoly_cross(x, &r->su, &r->sv, r->bin);
    vpoly_add_scaled(out, 1.0, &r->w, x, r->bin);
    vpoly_cross(x, &r->s, &r->su, r->bin);
    vpoly_add_scaled(out, 1.0, &r->wv, x, r->bin);
    vpoly_cross(x, &r->sv, &r->s, r->bin);
    vpoly_add_scaled(out, 1.0, &r->wu, x, r->bin);
    free(x);
}

static void rat_net(struct patch *pt, const struct vpoly *v, double (*net)[4])
{
    *pt = (struct patch){.p = v->m, .q = v->n, .cw = net};
    for (int i = 0; i <= v->m; i++)
        for (int j = 0; j <= v->n; j++) {
            double *c = net[i * (v->n + 1) + j];
            c[0] = v->c[i][j].x, c[1] = v->c[i][j].y, c[2] = v->c[i][j].z, c[3] = 0.0;
        }
}

void rat_polys_make(struct rat_polys *rp, const struct patch *pt)
{
    struct rnet *r = malloc(sizeof *r);
    struct vpoly *v = malloc(sizeof *v);
    rp->ok = r && v && rnet_of(pt, r);
    if (rp->ok) {
        rational_normals(r, v);
        rat_net(&rp->n, v, rp->net[0]);
        struct vpoly *tv = malloc(sizeof *tv);
        if ((rp->ok = tv != NULL)) {
            rational_tangents(r, v, tv);
            rat_net(&rp->tu, v, rp->net[1]);
            rat_net(&rp->tv, tv, rp->net[2]);
        }
        free(tv);
    }
    free(r), free(v);
}

/* The coefficients of numerator poly over [u0, u1] x [v0, v1] of the domain, into rp's work net. */
const struct patch *rat_part(struct rat_polys *rp, const struct patch *poly, double u0, double u1, double v0,
                             double v1, struct patch *part)
{
    *part = *poly;
    part->cw = rp->net[3];
    sub_net(poly, u0, u1, v0, v1, rp->net[3], rp->net[4]);
    return part;
}

/* The cone of a numerator's coefficients over a part (rat_part). */
void cone_of_net(const struct patch *part, vec3 *axis, double *sin_half)
{
    vec3 c[RAT_N * RAT_N];
    int n = (part->p + 1) * (part->q + 1);
    for (int k = 0; k < n; k++)
        c[k] = v3(part->cw[k][0], part->cw[k][1], part->cw[k][2]);
    cone_of(c, part->q + 1, part->p, part->q, axis, sin_half);
}

/* Appends the coefficients of part's net that are not zero to g (at most RAT_N^2). */
void append_net(const struct patch *part, vec3 *g, int *n)
{
    for (int k = 0; k < (part->p + 1) * (part->q + 1); k++) {
        vec3 c = v3(part->cw[k][0], part->cw[k][1], part->cw[k][2]);
        if (v3_len(c) > 0)
            g[(*n)++] = c;
    }
}

/* Normal cone of a polynomial patch. Pu × Pv is a polynomial of degree (2p-1, 2q-1) whose
 * Bernstein coefficients are sums of cross products of the derivative nets, weighted by
 * binomial ratios; a cone holding every coefficient holds every normal (Bernstein weights are
 * non-negative). A rational patch's leaves take theirs from its normals' numerator (rat_polys). */
void normal_cone(const struct patch *pt, vec3 *axis, double *sin_half)
{
    *sin_half = 2.0;
    int p = pt->p, q = pt->q, M = 2 * p - 1, N = 2 * q - 1;
    if (pt->rational || M > PATCH_MAX_DEGREE || N > PATCH_MAX_DEGREE)
        return;
    double bin[2 * PATCH_MAX_DEGREE + 1][2 * PATCH_MAX_DEGREE + 1];
    for (int n = 0; n <= M || n <= N; n++)
        for (int k = 0; k <= n; k++)
            bin[n][k] = k == 0 || k == n ? 1.0 : bin[n - 1][k - 1] + bin[n - 1][k];
    vec3 C[2 * PATCH_MAX_DEGREE][2 * PATCH_MAX_DEGREE];
    for (int m = 0; m <= M; m++)
        for (int n = 0; n <= N; n++)
            C[m][n] = v3(0, 0, 0);
    /* Pu net: p du, degree (p-1, q); Pv net: q dv, degree (p, q-1) */
    vec3 du[PATCH_MAX_DEGREE][PATCH_MAX_DEGREE + 1], dv[PATCH_MAX_DEGREE + 1][PATCH_MAX_DEGREE];
    net_differences(pt, du, dv);
    for (int i = 0; i < p; i++)
        for (int j = 0; j <= q; j++)
            for (int k = 0; k <= p; k++)
                for (int l = 0; l < q; l++) {
                    double w = (double)p * q * bin[p - 1][i] * bin[p][k] / bin[M][i + k] * bin[q][j] * bin[q - 1][l] /
                               bin[N][j + l];
                    C[i + k][j + l] = v3_add(C[i + k][j + l], v3_scale(v3_cross(du[i][j], dv[k][l]), w));
                }
    cone_of(&C[0][0], 2 * PATCH_MAX_DEGREE, M, N, axis, sin_half);
}

/* Largest distance of a control point from the bilinear through the corners, and (when curv_u
 * is not NULL) the net's second differences along u and v, to choose the split direction. */
double net_deviation(const struct patch *pt, double *curv_u, double *curv_v)
{
    int p = pt->p, q = pt->q;
    vec3 c00 = bezier_point(pt, 0, 0), c10 = bezier_point(pt, p, 0);
    vec3 c01 = bezier_point(pt, 0, q), c11 = bezier_point(pt, p, q);
    double dev2 = 0.0, cu = 0.0, cv = 0.0;
    for (int i = 0; i <= p; i++)
        for (int j = 0; j <= q; j++) {
            double s = (double)i / p, t = (double)j / q;
            vec3 bl = v3_add(v3_add(v3_scale(c00, (1 - s) * (1 - t)), v3_scale(c10, s * (1 - t))),
                             v3_add(v3_scale(c01, (1 - s) * t), v3_scale(c11, s * t)));
            vec3 c = bezier_point(pt, i, j), d = v3_sub(c, bl);
            dev2 = dmax(dev2, v3_dot(d, d));
            if (!curv_u)
                continue;
            if (i + 2 <= p)
                cu = dmax(cu, v3_len(v3_add(v3_sub(c, v3_scale(bezier_point(pt, i + 1, j), 2)), bezier_point(pt, i + 2, j))));
            if (j + 2 <= q)
                cv = dmax(cv, v3_len(v3_add(v3_sub(c, v3_scale(bezier_point(pt, i, j + 1), 2)), bezier_point(pt, i, j + 2))));
        }
    if (curv_u)
        *curv_u = cu, *curv_v = cv;
    return sqrt(dev2);
}

/* Appends pt's net differences to g (a rational patch's: its tangents' numerators' coefficients):
 * the u ones at g[*n_u..] (moving the v ones already there up), the v ones after them; zero ones
 * (a collapsed edge's) add nothing to any chord. False where there is no such bound (rnet_of). */
bool chord_generators(const struct patch *pt, vec3 *g, int *n_g, int *n_u)
{
    vec3 v_ones[CHORD_MAX_GENS];
    int n_v = *n_g - *n_u;
    memcpy(v_ones, g + *n_u, sizeof *g * (size_t)n_v);
    if (pt->rational) { /* the tangents' numerators' coefficients (rational_tangents) */
        struct rnet *r = malloc(sizeof *r);
        struct vpoly *t = malloc(2 * sizeof *t);
        bool ok = r && t && rnet_of(pt, r);
        if (ok) {
            rational_tangents(r, &t[0], &t[1]);
            for (int i = 0; i <= t[0].m; i++)
                for (int j = 0; j <= t[0].n; j++)
                    if (v3_len(t[0].c[i][j]) > 0)
                        g[(*n_u)++] = t[0].c[i][j];
            memcpy(g + *n_u, v_ones, sizeof *g * (size_t)n_v);
            *n_g = *n_u + n_v;
            for (int i = 0; i <= t[1].m; i++)
                for (int j = 0; j <= t[1].n; j++)
                    if (v3_len(t[1].c[i][j]) > 0)
                        g[(*n_g)++] = t[1].c[i][j];
        }
        free(r), free(t);
        return ok;
    }
    vec3 du[PATCH_MAX_DEGREE][PATCH_MAX_DEGREE + 1], dv[PATCH_MAX_DEGREE + 1][PATCH_MAX_DEGREE];
    net_differences(pt, du, dv);
    for (int i = 0; i < pt->p; i++)
        for (int j = 0; j <= pt->q; j++)
            if (v3_len(du[i][j]) > 0)
                g[(*n_u)++] = du[i][j];
    memcpy(g + *n_u, v_ones, sizeof *g * (size_t)n_v);
    *n_g = *n_u + n_v;
    for (int i = 0; i <= pt->p; i++)
        for (int j = 0; j < pt->q; j++)
            if (v3_len(dv[i][j]) > 0)
                g[(*n_g)++] = dv[i][j];
    return true;
}

/* Bounds the directions of the chords of a patch. A chord S(u1, v1) - S(u2, v2) is the integral
 * of Pu along u, then of Pv along v, and each is a non-negative combination of the net's
 * differences g (Bernstein weights are non-negative; a rational patch's tangents' numerators'
 * coefficients, over w² > 0); so with the u differences taken with
 * one sign and the v differences with another, every chord c = sum l_g g, l >= 0. For a unit n
 * and a unit w with w·g >= k |g| for all of them (k > 0): |c·n| <= max(|g·n| / |g|) sum l|g| and
 * |c| >= w·c >= k sum l|g|, so |c·n| / |c| <= max(|g·n| / |g|) / k. Both sign pairings (the
 * other two are their negatives) give the bound *sin_max on |c·n| / |c| for every chord. The same
 * holds for two patches that share an edge, one's parameter going on into the other's (a seam): a
 * path between two of their points runs monotone in both parameters of the longer rectangle, and
 * its tangents are combinations of the one net's differences or the other's. Here from the
 * generators g, the u ones first (n_u of them). */
void chord_bound_of(const vec3 *g, int n_g, int n_u, vec3 *n, double *sin_max)
{
    *sin_max = 2.0;
    double inv[CHORD_MAX_GENS]; /* 1 / |g|: one square root each */
    vec3 au = v3(0, 0, 0), av = v3(0, 0, 0); /* their mean directions */
    for (int m = 0; m < n_g; m++) {
        inv[m] = 1.0 / v3_len(g[m]);
        if (m < n_u)
            au = v3_mad(au, g[m], inv[m]);
        else
            av = v3_mad(av, g[m], inv[m]);
    }
    vec3 axis = v3_cross(au, av);
    if (!(v3_len(axis) > 1e-9 * v3_len(au) * v3_len(av)))
        return;
    axis = v3_norm(axis);
    au = v3_norm(au), av = v3_norm(av);
    const vec3 w[2] = {v3_norm(v3_add(au, av)), v3_norm(v3_sub(au, av))}; /* v differences taken +, then - */
    double tilt = 0.0, k[2] = {1.0, 1.0};
    for (int m = 0; m < n_g; m++) {
        tilt = fmax(tilt, fabs(v3_dot(g[m], axis)) * inv[m]);
        k[0] = fmin(k[0], v3_dot(w[0], g[m]) * inv[m]);
        k[1] = fmin(k[1], (m >= n_u ? -1.0 : 1.0) * v3_dot(w[1], g[m]) * inv[m]);
    }
    if (k[0] <= 0 || k[1] <= 0)
        return;
    *n = axis;
    *sin_max = tilt / fmin(k[0], k[1]) + 1e-9;
}

void chord_bound(const struct patch *pt, vec3 *n, double *sin_max)
{
    vec3 g[CHORD_MAX_GENS];
    int n_g = 0, n_u = 0;
    *sin_max = 2.0;
    if (chord_generators(pt, g, &n_g, &n_u))
        chord_bound_of(g, n_g, n_u, n, sin_max);
}

