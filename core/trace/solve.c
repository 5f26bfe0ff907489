/* solve.c - ray/patch root finders: Newton–Cramer (seed 000 eq. 10–13), gradient descent
 * (eq. 4), steepest descent with a golden-ratio step cut (eq. 9), Monte-Carlo seeding (eq. 3).
 * The descent methods exist because the thesis uses them and so that their cost can be
 * measured against Newton; the renderer's auto method uses Newton–Cramer for every kind, since
 * a polynomial patch is a rational one with w = 1. */
#include "solve.h"

#include <math.h>
#include <stddef.h>

#define INV_GOLDEN 0.6180339887498949 /* step cut of eq. 9 */

void solve_ray_init(struct dray *r, vec3 o, vec3 d)
{
    r->o = o;
    r->d = v3_norm(d);
    /* an orthonormal pair across d without a square root or a branch on the axis (Duff et al.,
     * "Building an orthonormal basis, revisited", JCGT 2017) */
    const vec3 n = r->d;
    double sign = copysign(1.0, n.z), a = -1.0 / (sign + n.z), b = n.x * n.y * a;
    r->e1 = v3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    r->e2 = v3(b, sign + n.y * n.y * a, -n.y);
    r->e1o = v3_dot(r->e1, o);
    r->e2o = v3_dot(r->e2, o);
    r->inv_d = v3(1.0 / r->d.x, 1.0 / r->d.y, 1.0 / r->d.z);
}

void solve_ray_parallel(struct dray *r, vec3 o, const struct dray *like)
{
    *r = *like;
    r->o = o;
    r->e1o = v3_dot(r->e1, o);
    r->e2o = v3_dot(r->e2, o);
}

/* Projected homogeneous values: x* = e1·S - (e1·o) w and y* likewise, with derivatives. */
struct proj {
    double x, y, w;    /* x*, y*, w */
    double xu, yu, wu;
    double xv, yv, wv;
    double S[4];       /* homogeneous point and derivatives, for t and the normal */
    double Su[4], Sv[4];
};

static void project(const struct patch *pt, const struct dray *r, double u, double v, struct proj *p)
{
    bezier_eval_h(pt, u, v, p->S, p->Su, p->Sv);
    const double *S = p->S, *Su = p->Su, *Sv = p->Sv;
    p->x = r->e1.x * S[0] + r->e1.y * S[1] + r->e1.z * S[2] - r->e1o * S[3];
    p->y = r->e2.x * S[0] + r->e2.y * S[1] + r->e2.z * S[2] - r->e2o * S[3];
    p->w = S[3];
    p->xu = r->e1.x * Su[0] + r->e1.y * Su[1] + r->e1.z * Su[2] - r->e1o * Su[3];
    p->yu = r->e2.x * Su[0] + r->e2.y * Su[1] + r->e2.z * Su[2] - r->e2o * Su[3];
    p->wu = Su[3];
    p->xv = r->e1.x * Sv[0] + r->e1.y * Sv[1] + r->e1.z * Sv[2] - r->e1o * Sv[3];
    p->yv = r->e2.x * Sv[0] + r->e2.y * Sv[1] + r->e2.z * Sv[2] - r->e2o * Sv[3];
    p->wv = Sv[3];
}

static double det3(double a, double b, double c, double d, double e, double f, double g, double h, double i)
{
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
}

static double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

static bool accept(const struct dray *r, const struct solve_box *box, double u, double v, const struct proj *p,
                   struct solve_hit *hit)
{
    if (u < box->u0 - SOLVE_BOX_EPS || u > box->u1 + SOLVE_BOX_EPS || v < box->v0 - SOLVE_BOX_EPS ||
        v > box->v1 + SOLVE_BOX_EPS)
        return false;
    const double *S = p->S, *Su = p->Su, *Sv = p->Sv;
    vec3 P = v3(S[0], S[1], S[2]), Pu = v3(Su[0], Su[1], Su[2]), Pv = v3(Sv[0], Sv[1], Sv[2]);
    if (S[3] != 1.0 || Su[3] != 0.0 || Sv[3] != 0.0) { /* rational: the quotient rule, as bezier_eval */
        const double iw = 1.0 / S[3];
        P = v3_scale(P, iw);
        Pu = v3_scale(v3_sub(Pu, v3_scale(P, Su[3])), iw);
        Pv = v3_scale(v3_sub(Pv, v3_scale(P, Sv[3])), iw);
    }
    hit->u = u;
    hit->v = v;
    hit->t = v3_dot(r->d, v3_sub(P, r->o));
    vec3 n = v3_cross(Pu, Pv);
    double l = v3_len(n);
    hit->n = l > 1e-12 * v3_dot(Pu, Pu) + 1e-300 ? v3_scale(n, 1.0 / l) : v3(0, 0, 0);
    return true;
}

static bool newton_cramer(const struct patch *pt, const struct dray *r, double u, double v,
                          const struct solve_box *box, double tol2, bool fail_fast, struct solve_hit *hit)
{
    struct proj p;
    const double mu = 0.5 * (box->u1 - box->u0) + 1e-3, mv = 0.5 * (box->v1 - box->v0) + 1e-3;
    /* Taylor: after a step (du, dv) that zeroes the linear part, the ray's distance from the
     * surface is at most ru du² + ruv |du dv| + rv dv² (bezier_second_bounds, each partial its
     * own: a sliver's steps across it are long in its parameter and short in the world; the
     * homogeneous point less the origin times w, over the least weight) */
    const bool bounded = pt->wmin > 0; /* (bezier_second_bounds ran) */
    const double olen = pt->d2w[0] > 0 || pt->d2w[1] > 0 || pt->d2w[2] > 0 ? v3_len(r->o) : 0.0;
    const double half = bounded ? 0.5 / pt->wmin : 0.0;
    const double ru = (pt->d2[0] + olen * pt->d2w[0]) * half, ruv = 2.0 * (pt->d2[1] + olen * pt->d2w[1]) * half,
                 rv = (pt->d2[2] + olen * pt->d2w[2]) * half;
    hit->iters = 0;
    double prev2 = INFINITY;
    for (int it = 0; it < SOLVE_MAX_NEWTON; it++) {
        project(pt, r, u, v, &p);
        hit->iters++;
        double res2, M, Mu, Mv;
        if (pt->rational) {
            res2 = (p.x * p.x + p.y * p.y) / (p.w * p.w);
            /* eq. 12–13 with the ray's projection at the origin of the plane: (x_R, y_R) = (0, 0) */
            M = det3(p.x, p.xu, p.xv, p.y, p.yu, p.yv, p.w, p.wu, p.wv);
            Mu = det3(p.x, 0.0, p.xv, p.y, 0.0, p.yv, p.w, 1.0, p.wv);
            Mv = det3(p.x, p.xu, 0.0, p.y, p.yu, 0.0, p.w, p.wu, 1.0);
        } else { /* the same with w = 1, wu = wv = 0 */
            res2 = p.x * p.x + p.y * p.y;
            M = p.xu * p.yv - p.xv * p.yu;
            Mu = p.xv * p.y - p.x * p.yv;
            Mv = p.x * p.yu - p.xu * p.y;
        }
        if (M == 0.0 || !isfinite(M))
            return res2 <= tol2 && accept(r, box, u, v, &p, hit);
        double du = p.w / M * Mu, dv = p.w / M * Mv; /* eq. 11 */
        double nu = clamp01(u + du), nv = clamp01(v + dv);
        double rem = bounded ? ru * du * du + ruv * fabs(du * dv) + rv * dv * dv : INFINITY;
        if ((res2 <= tol2 || rem * rem <= tol2) && nu == u + du && nv == v + dv) {
            /* Within tolerance here, or provably so at the step's end: take the step without
             * evaluating again. The point there is the first-order expansion S + Su du + Sv dv,
             * on the ray and within the remainder bound of the surface. */
            for (int c = 0; c < 4; c++)
                p.S[c] += p.Su[c] * du + p.Sv[c] * dv;
            return accept(r, box, nu, nv, &p, hit);
        }
        double step = fabs(nu - u) + fabs(nv - v);
        if (step < SOLVE_STEP_EPS) /* stalled (at the domain's edge, or at a singular point) */
            return res2 <= tol2 && accept(r, box, u, v, &p, hit);
        /* Newton converges quadratically from a seed near a root; a residual that has not even
         * halved after the first steps means none nearby (typically a ray past the silhouette) */
        if (fail_fast && it >= 3 && res2 > 0.25 * prev2)
            return false;
        prev2 = res2;
        u = nu;
        v = nv;
        /* well outside the box after the first steps: this root belongs to another leaf */
        if (it >= 2 && (u < box->u0 - mu || u > box->u1 + mu || v < box->v0 - mv || v > box->v1 + mv))
            return false;
    }
    project(pt, r, u, v, &p);
    return (p.x * p.x + p.y * p.y) / (p.w * p.w) <= tol2 && accept(r, box, u, v, &p, hit);
}

bool solve_newton_cramer(const struct patch *pt, const struct dray *r, double u, double v,
                         const struct solve_box *box, double tol2, struct solve_hit *hit)
{
    return newton_cramer(pt, r, u, v, box, tol2, false, hit);
}

bool solve_newton_seeded(const struct patch *pt, const struct dray *r, double u, double v,
                         const struct solve_box *box, double tol2, struct solve_hit *hit)
{
    return newton_cramer(pt, r, u, v, box, tol2, true, hit);
}

/* g = x² + y² in Euclidean units (seed 000 eq. 2); with gu, also its gradient and in *h the
 * step of eq. 4 that minimises the linearised g along -grad (the seed leaves h to the user):
 * h = F·(J∇g) / |J∇g|². */
static double g_and_grad(const struct patch *pt, const struct dray *r, double u, double v, double *gu, double *gv,
                         double *h, struct proj *p)
{
    project(pt, r, u, v, p);
    double iw = 1.0 / p->w;
    double x = p->x * iw, y = p->y * iw;
    if (gu) {
        double xu = (p->xu - x * p->wu) * iw, yu = (p->yu - y * p->wu) * iw;
        double xv = (p->xv - x * p->wv) * iw, yv = (p->yv - y * p->wv) * iw;
        *gu = 2.0 * (x * xu + y * yu);
        *gv = 2.0 * (x * xv + y * yv);
        double a = xu * (*gu) + xv * (*gv), b = yu * (*gu) + yv * (*gv);
        double den = a * a + b * b;
        *h = den > 0.0 ? (x * a + y * b) / den : 0.0;
    }
    return x * x + y * y;
}

bool solve_gradient(const struct patch *pt, const struct dray *r, double u, double v,
                    const struct solve_box *box, double tol2, struct solve_hit *hit)
{
    struct proj p;
    double gu, gv, h0;
    double g = g_and_grad(pt, r, u, v, &gu, &gv, &h0, &p);
    hit->iters = 1;
    for (int it = 0; it < SOLVE_MAX_DESCENT && g > tol2; it++) {
        double h = h0, nu = u, nv = v, ng = g, nh = 0;
        struct proj q;
        double ngu = 0, ngv = 0;
        /* eq. 4; h halves while the step does not lower g */
        for (int cut = 0; cut < 40; cut++, h *= 0.5) {
            nu = clamp01(u - h * gu);
            nv = clamp01(v - h * gv);
            ng = g_and_grad(pt, r, nu, nv, &ngu, &ngv, &nh, &q);
            hit->iters++;
            if (ng < g)
                break;
        }
        if (!(ng < g) || fabs(nu - u) + fabs(nv - v) < SOLVE_STEP_EPS)
            break;
        u = nu, v = nv, g = ng, gu = ngu, gv = ngv, h0 = nh, p = q;
    }
    return g <= tol2 && accept(r, box, u, v, &p, hit);
}

bool solve_steepest(const struct patch *pt, const struct dray *r, double u, double v,
                    const struct solve_box *box, double tol2, struct solve_hit *hit)
{
    struct proj p;
    double du, dv, h;
    double g = g_and_grad(pt, r, u, v, &du, &dv, &h, &p);
    hit->iters = 1;
    while (hit->iters < SOLVE_MAX_DESCENT && g > tol2) {
        /* step 2: move along the kept direction (eq. 9) */
        double nu = clamp01(u - h * du), nv = clamp01(v - h * dv);
        struct proj q;
        double ng = g_and_grad(pt, r, nu, nv, NULL, NULL, NULL, &q);
        hit->iters++;
        if (ng < g) { /* step 3: keep direction and h */
            u = nu, v = nv, g = ng, p = q;
            continue;
        }
        /* step 4: new direction at the current point (step 1), step cut by the inverse golden
         * ratio. The cut applies to the new direction's own step: cutting the old h again and
         * again lets it collapse until the iteration cap (the seed leaves this open). */
        g = g_and_grad(pt, r, u, v, &du, &dv, &h, &p);
        hit->iters++;
        h *= INV_GOLDEN;
        if (h * (fabs(du) + fabs(dv)) < SOLVE_STEP_EPS)
            break;
    }
    return g <= tol2 && accept(r, box, u, v, &p, hit);
}

static double rand01(uint64_t *s)
{
    uint64_t x = *s;
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    *s = x;
    return (double)(x >> 11) * (1.0 / 9007199254740992.0);
}

bool solve_montecarlo(const struct patch *pt, const struct dray *r, int n_samples, uint64_t *rng,
                      double tol2, struct solve_hit *hit)
{
    enum { KEEP = 6 };
    double best_g[KEEP], best_u[KEEP], best_v[KEEP];
    int n_best = 0;
    struct proj p;
    for (int k = 0; k < n_samples; k++) {
        double u = rand01(rng), v = rand01(rng);
        double g = g_and_grad(pt, r, u, v, NULL, NULL, NULL, &p);
        /* keep the KEEP lowest g, sorted */
        int at = n_best < KEEP ? n_best++ : KEEP;
        if (at == KEEP && g >= best_g[KEEP - 1])
            continue;
        if (at == KEEP)
            at = KEEP - 1;
        while (at > 0 && best_g[at - 1] > g) {
            best_g[at] = best_g[at - 1], best_u[at] = best_u[at - 1], best_v[at] = best_v[at - 1];
            at--;
        }
        best_g[at] = g, best_u[at] = u, best_v[at] = v;
    }
    /* eq. 3: refine every kept point within eps0 of the best (eps0 ours: 4x the best g plus
     * a floor, since the seed leaves it to the user) */
    double eps0 = 3.0 * best_g[0] + tol2;
    const struct solve_box all = {0, 1, 0, 1};
    bool found = false;
    int iters = n_samples;
    for (int k = 0; k < n_best && best_g[k] - best_g[0] <= eps0; k++) {
        struct solve_hit h;
        bool ok = solve_gradient(pt, r, best_u[k], best_v[k], &all, tol2, &h);
        iters += h.iters;
        if (ok && h.t > 0.0 && (!found || h.t < hit->t)) {
            *hit = h;
            found = true;
        }
    }
    hit->iters = iters;
    return found;
}
