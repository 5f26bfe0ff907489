/* bezier.c - evaluation, subdivision and bounds of homogeneous Bézier patches.
 * Evaluation uses the Bernstein basis computed by the de Casteljau triangle, which is
 * stable for every degree up to PATCH_MAX_DEGREE; derivatives come from the degree-(n-1)
 * basis (B'_i = n (B^{n-1}_{i-1} - B^{n-1}_i)). */
#include "bezier.h"

#include <math.h>
#include <string.h>

/* Bernstein basis of degree n at t into B[0..n] (triangular recurrence). */
static void basis_only(int n, double t, double *B)
{
    double s = 1.0 - t;
    B[0] = 1.0;
    for (int k = 1; k <= n; k++) {
        double saved = 0.0;
        for (int i = 0; i < k; i++) {
            double tmp = B[i];
            B[i] = saved + s * tmp;
            saved = t * tmp;
        }
        B[k] = saved;
    }
}

void bezier_basis(int n, double t, double *B, double *dB)
{
    if (!dB) {
        basis_only(n, t, B);
        return;
    }
    if (n == 0) {
        B[0] = 1.0;
        dB[0] = 0.0;
        return;
    }
    double Bm[PATCH_MAX_DEGREE + 1];
    basis_only(n - 1, t, Bm);
    /* degree n from degree n-1 by one more recurrence step */
    double s = 1.0 - t, saved = 0.0;
    for (int i = 0; i < n; i++) {
        B[i] = saved + s * Bm[i];
        saved = t * Bm[i];
    }
    B[n] = saved;
    dB[0] = -n * Bm[0];
    for (int i = 1; i < n; i++)
        dB[i] = n * (Bm[i - 1] - Bm[i]);
    dB[n] = n * Bm[n - 1];
}

/* The bicubic case, which nearly every real scene is: the four homogeneous coordinates of a
 * control point are one vector of four doubles (GCC's vector extension), so each Bernstein
 * term is one vector multiply-add. On x86-64 an AVX2 clone of bezier_eval_h (this inlined) is
 * chosen at load time where the CPU has it (about 2.5x faster than the scalar loops this
 * replaced, 28 vs 70 ns with both derivatives); both clones do the same operations in the same
 * order (no contraction under -std=c11), so they return the same bits. */
typedef double v4d __attribute__((vector_size(4 * sizeof(double))));
typedef double v4du __attribute__((vector_size(4 * sizeof(double)), aligned(sizeof(double)), may_alias));

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__SANITIZE_THREAD__)
/* (not under the thread sanitizer: a clone's resolver runs at relocation, before its runtime) */
#define SIMD_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SIMD_CLONES
#endif

static inline __attribute__((always_inline)) void eval_bicubic(double (*cw)[4], double u, double v, double S[4],
                                                               double Su[4], double Sv[4])
{
    double su = 1.0 - u, sv = 1.0 - v;
    const double Bu[4] = {su * su * su, 3 * u * su * su, 3 * u * u * su, u * u * u};
    const double Bv[4] = {sv * sv * sv, 3 * v * sv * sv, 3 * v * v * sv, v * v * v};
    const double dBu[4] = {-3 * su * su, 3 * su * (su - 2 * u), 3 * u * (2 * su - u), 3 * u * u};
    const double dBv[4] = {-3 * sv * sv, 3 * sv * (sv - 2 * v), 3 * v * (2 * sv - v), 3 * v * v};
    v4d c[4], cv[4];
    for (int i = 0; i < 4; i++) { /* row i contracted with the v basis and its derivative */
        const v4du *r = (const v4du *)cw[4 * i]; /* read in place: a copy of the net cost a fifth */
        c[i] = (Bv[0] * r[0] + Bv[1] * r[1]) + (Bv[2] * r[2] + Bv[3] * r[3]);
        cv[i] = (dBv[0] * r[0] + dBv[1] * r[1]) + (dBv[2] * r[2] + dBv[3] * r[3]);
    }
    v4d s = (Bu[0] * c[0] + Bu[1] * c[1]) + (Bu[2] * c[2] + Bu[3] * c[3]);
    v4d a = (dBu[0] * c[0] + dBu[1] * c[1]) + (dBu[2] * c[2] + dBu[3] * c[3]);
    v4d b = (Bu[0] * cv[0] + Bu[1] * cv[1]) + (Bu[2] * cv[2] + Bu[3] * cv[3]);
    memcpy(S, &s, sizeof s);
    if (Su)
        memcpy(Su, &a, sizeof a);
    if (Sv)
        memcpy(Sv, &b, sizeof b);
}

/* Cloned itself, the bicubic case inlined: one dispatch per evaluation. */
SIMD_CLONES void bezier_eval_h(const struct patch *pt, double u, double v, double S[4], double Su[4], double Sv[4])
{
    const int p = pt->p, q = pt->q;
    if (p == 3 && q == 3) {
        eval_bicubic(pt->cw, u, v, S, Su, Sv);
        if (!pt->rational) { /* w is 1 exactly, not a sum of Bernstein weights */
            S[3] = 1.0;
            if (Su)
                Su[3] = 0.0;
            if (Sv)
                Sv[3] = 0.0;
        }
        return;
    }
    double Bu[PATCH_MAX_DEGREE + 1], dBu[PATCH_MAX_DEGREE + 1];
    double Bv[PATCH_MAX_DEGREE + 1], dBv[PATCH_MAX_DEGREE + 1];
    bool deriv = Su || Sv;
    bezier_basis(p, u, Bu, deriv ? dBu : NULL);
    bezier_basis(q, v, Bv, deriv ? dBv : NULL);

    double s[4] = {0}, su[4] = {0}, sv[4] = {0};
    double(*cw)[4] = pt->cw;
    for (int i = 0; i <= p; i++) {
        /* row i contracted with the v basis: C = sum_j Bv_j P_ij, Cv = sum_j dBv_j P_ij */
        double c[4] = {0}, cv[4] = {0};
        for (int j = 0; j <= q; j++) {
            const double *P = cw[i * (q + 1) + j];
            for (int k = 0; k < 4; k++) {
                c[k] += Bv[j] * P[k];
                if (deriv)
                    cv[k] += dBv[j] * P[k];
            }
        }
        for (int k = 0; k < 4; k++) {
            s[k] += Bu[i] * c[k];
            if (deriv) {
                su[k] += dBu[i] * c[k];
                sv[k] += Bu[i] * cv[k];
            }
        }
    }
    memcpy(S, s, sizeof s);
    if (Su)
        memcpy(Su, su, sizeof su);
    if (Sv)
        memcpy(Sv, sv, sizeof sv);
}

void bezier_eval(const struct patch *pt, double u, double v, vec3 *P, vec3 *Pu, vec3 *Pv)
{
    double S[4], Su[4], Sv[4];
    bezier_eval_h(pt, u, v, S, (Pu || Pv) ? Su : NULL, (Pu || Pv) ? Sv : NULL);
    double iw = 1.0 / S[3];
    vec3 p = v3(S[0] * iw, S[1] * iw, S[2] * iw);
    if (P)
        *P = p;
    /* quotient rule: d(S/w) = (dS - p dw) / w */
    if (Pu)
        *Pu = v3((Su[0] - p.x * Su[3]) * iw, (Su[1] - p.y * Su[3]) * iw, (Su[2] - p.z * Su[3]) * iw);
    if (Pv)
        *Pv = v3((Sv[0] - p.x * Sv[3]) * iw, (Sv[1] - p.y * Sv[3]) * iw, (Sv[2] - p.z * Sv[3]) * iw);
}

bool bezier_normal(const struct patch *pt, double u, double v, vec3 *n)
{
    /* Steps toward the patch centre, growing until the cross product is no longer
     * degenerate; 1e-9 is far below any visible shading change. */
    static const double NORMAL_EPS = 1e-24; /* |Pu × Pv|² below this counts as collapsed */
    double du = u < 0.5 ? 1.0 : -1.0, dv = v < 0.5 ? 1.0 : -1.0;
    for (double h = 0.0; h < 0.5; h = h == 0.0 ? 1e-9 : h * 8.0) {
        vec3 Pu, Pv;
        bezier_eval(pt, u + du * h, v + dv * h, NULL, &Pu, &Pv);
        vec3 c = v3_cross(Pu, Pv);
        if (v3_dot(c, c) > NORMAL_EPS) {
            *n = v3_norm(c);
            return true;
        }
    }
    return false;
}

/* de Casteljau split of n+1 points spaced by stride; writes lo and hi with the same stride. A
 * point's four coordinates are one vector, as in eval_bicubic (the hierarchy's grazing search
 * splits nets by the thousand a frame). */
SIMD_CLONES static void split_line(double (*src)[4], int n, int stride, double t, double (*lo)[4], double (*hi)[4])
{
    v4d tmp[PATCH_MAX_DEGREE + 1];
    const double s = 1.0 - t;
    if (n == 3) { /* cubic, unrolled: the same operations in the same order */
        v4d p0, p1, p2, p3;
        memcpy(&p0, src[0], sizeof p0), memcpy(&p1, src[stride], sizeof p1);
        memcpy(&p2, src[2 * stride], sizeof p2), memcpy(&p3, src[3 * stride], sizeof p3);
        v4d a = s * p0 + t * p1, b = s * p1 + t * p2, c = s * p2 + t * p3;
        v4d ab = s * a + t * b, bc = s * b + t * c, m = s * ab + t * bc;
        memcpy(lo[0], &p0, sizeof p0), memcpy(lo[stride], &a, sizeof a);
        memcpy(lo[2 * stride], &ab, sizeof ab), memcpy(lo[3 * stride], &m, sizeof m);
        memcpy(hi[0], &m, sizeof m), memcpy(hi[stride], &bc, sizeof bc);
        memcpy(hi[2 * stride], &c, sizeof c), memcpy(hi[3 * stride], &p3, sizeof p3);
        return;
    }
    for (int i = 0; i <= n; i++)
        memcpy(&tmp[i], src[i * stride], sizeof tmp[i]);
    for (int r = 0; r <= n; r++) {
        memcpy(lo[r * stride], &tmp[0], sizeof tmp[0]);
        memcpy(hi[(n - r) * stride], &tmp[n - r], sizeof tmp[0]);
        for (int i = 0; i < n - r; i++)
            tmp[i] = s * tmp[i] + t * tmp[i + 1];
    }
}

void bezier_split_u(const struct patch *pt, double t, double (*lo)[4], double (*hi)[4])
{
    for (int j = 0; j <= pt->q; j++)
        split_line(pt->cw + j, pt->p, pt->q + 1, t, lo + j, hi + j);
}

void bezier_split_v(const struct patch *pt, double t, double (*lo)[4], double (*hi)[4])
{
    for (int i = 0; i <= pt->p; i++) {
        int o = i * (pt->q + 1);
        split_line(pt->cw + o, pt->q, 1, t, lo + o, hi + o);
    }
}

double bezier_net_curvature(const struct patch *pt, int dir)
{
    int p = pt->p, q = pt->q, n = dir ? q : p;
    if (n < 2)
        return 0.0;
    double m = 0.0;
    for (int i = 0; i <= p; i++)
        for (int j = 0; j <= q; j++) {
            if ((dir == 0 && i + 2 > p) || (dir == 1 && j + 2 > q))
                continue;
            vec3 a = bezier_point(pt, i, j);
            vec3 b = dir ? bezier_point(pt, i, j + 1) : bezier_point(pt, i + 1, j);
            vec3 c = dir ? bezier_point(pt, i, j + 2) : bezier_point(pt, i + 2, j);
            m = fmax(m, v3_len(v3_add(v3_sub(a, v3_scale(b, 2.0)), c)));
        }
    /* rational patches: the Euclidean net is only a guide, so take a safety factor of 2 */
    return m * n * (n - 1) * (pt->rational ? 2.0 : 1.0);
}

void bezier_second_bounds(struct patch *pt)
{
    static const double DIFF[3][3] = {{1, 0, 0}, {-1, 1, 0}, {1, -2, 1}}; /* forward differences */
    static const int ORDER[3][2] = {{2, 0}, {1, 1}, {0, 2}};               /* uu, uv, vv */
    const int p = pt->p, q = pt->q, m = q + 1;
    double(*cw)[4] = pt->cw, wmin = INFINITY;
    for (int k = 0; k < (p + 1) * m; k++)
        wmin = fmin(wmin, cw[k][3]);
    for (int o = 0; o < 3; o++) {
        const int di = ORDER[o][0], dj = ORDER[o][1];
        double d2 = 0.0, d2w = 0.0;
        /* d^(di+dj) S / du^di dv^dj = p!/(p-di)! q!/(q-dj)! sum B B (Delta_u^di Delta_v^dj cw) */
        const double f = (di == 2 ? p * (p - 1.0) : di == 1 ? p : 1.0) * (dj == 2 ? q * (q - 1.0) : dj == 1 ? q : 1.0);
        for (int i = 0; i + di <= p; i++)
            for (int j = 0; j + dj <= q; j++) {
                double d[4] = {0};
                for (int a = 0; a <= di; a++)
                    for (int b = 0; b <= dj; b++)
                        for (int c = 0; c < 4; c++)
                            d[c] += DIFF[di][a] * DIFF[dj][b] * cw[(i + a) * m + j + b][c];
                d2 = fmax(d2, f * sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]));
                d2w = fmax(d2w, f * fabs(d[3]));
            }
        pt->d2[o] = d2, pt->d2w[o] = d2w;
    }
    pt->wmin = wmin;
    pt->curv[0] = bezier_net_curvature(pt, 0);
    pt->curv[1] = bezier_net_curvature(pt, 1);
}

void bezier_bounds(const struct patch *pt, vec3 *lo, vec3 *hi)
{
    vec3 a = bezier_point(pt, 0, 0), b = a;
    for (int i = 0; i <= pt->p; i++)
        for (int j = 0; j <= pt->q; j++) {
            vec3 e = bezier_point(pt, i, j);
            a = v3_min(a, e);
            b = v3_max(b, e);
        }
    *lo = a;
    *hi = b;
}
