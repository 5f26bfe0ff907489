/* model.c - the contour surface (model.h): each method's patches of a chain (the curve methods'
 * bicubic nets here, the grid methods' in model_grid.c, both from the curves of model_curve.c,
 * unfolded by model_fold.c), the volume in closed form from the same curves, the domes that close
 * a chain's ends, and a contour set's chains. */
#include "model_internal.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/clock.h"
#include "../base/gauss.h"
#include "../base/mem.h"

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

/* The area enclosed by s's curve (parabolic or linear-parabolic), redrawn as the methods read it or
 * as drawn through its points; NAN when out of memory. */
static double curve_area(const struct contour_slice *s, bool lsq, bool redrawn)
{
    struct curve c = {0};
    struct curve_poly cp = {0};
    double a = NAN;
    if (!curve_build(s, lsq, false, &c) && !curve_poly_build(&c, &cp) && (!redrawn || !curve_refit(&cp)))
        a = mixed_area(&cp, &cp, false);
    curve_poly_free(&cp);
    curve_free(&c);
    return a;
}

double model_curve_area(const struct contour_slice *s)
{
    double a = curve_area(s, false, true);
    return isnan(a) ? 0.0 : a;
}

int model_departure(const struct contour_set *cs, enum model_method m, struct model_departure *d)
{
    double curves = 0.0, polygons = 0.0;
    *d = (struct model_departure){0.0, -1, 0.0};
    for (int k = 0; k < cs->n_slices; k++) {
        double ap = fabs(contour_area(&cs->s[k])), ac = curve_area(&cs->s[k], m == MODEL_LINEAR_PARABOLIC, false);
        if (isnan(ac))
            return SF_ENOMEM;
        double sign = cs->s[k].hole ? -1.0 : 1.0, rel = ac / ap - 1.0;
        curves += sign * ac, polygons += sign * ap;
        if (d->worst < 0 || fabs(rel) > fabs(d->worst_rel))
            d->worst = k, d->worst_rel = rel;
    }
    d->rel = polygons > 0.0 ? curves / polygons - 1.0 : 0.0;
    return 0;
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
