/* bezier.h - tensor-product (rational) Bézier patches in homogeneous form: the one shape the
 * tracer, the tessellator and the volume integrator work on. B-splines and NURBS reach it by
 * Bézier extraction (nurbs.h); polynomial patches carry w = 1 and are flagged so the hot
 * paths can skip the division.
 *
 * Control point (i, j), i along u, j along v, lives at cw[i*(q+1)+j] = (x·w, y·w, z·w, w). */
#ifndef SURFD_BEZIER_H
#define SURFD_BEZIER_H

#include <stdbool.h>

#include "../base/vec.h"
#include "trim.h"

#define PATCH_MAX_DEGREE 24 /* bounds every stack array below; higher degrees are refused */

struct patch {
    int p, q;            /* degrees along u and v */
    bool rational;       /* false: every w is 1 */
    double (*cw)[4];     /* (p+1)(q+1) homogeneous control points; owned by the patch set */
    int surface;         /* index of the scene object this patch came from */
    double u0, u1;       /* the patch's span in the object's own parameters (for uv output) */
    double v0, v1;
    const struct trim *trim; /* the object's trim region where it cuts the patch; NULL: the whole patch counts */
    /* bounds over the patch, set by bezier_second_bounds (scene_patches does, for the tracer; wmin
     * 0: not set): |second partial| along uu, uv and vv of the homogeneous x·w, y·w, z·w (d2) and
     * of w (d2w), and the least weight */
    double d2[3], d2w[3], wmin;
    double curv[2]; /* set with them: bezier_net_curvature along u and v (a tessellation's chord bound) */
};

/* Bernstein basis of degree n at t and its derivative: B[0..n], dB[0..n] (dB may be NULL). */
void bezier_basis(int n, double t, double *B, double *dB);

/* Point and first derivatives in homogeneous space (any argument after S may be NULL). */
void bezier_eval_h(const struct patch *pt, double u, double v, double S[4], double Su[4], double Sv[4]);

/* Euclidean point and first derivatives (rational quotient rule applied). */
void bezier_eval(const struct patch *pt, double u, double v, vec3 *P, vec3 *Pu, vec3 *Pv);

/* Unit normal Pu × Pv; where that vanishes (a collapsed edge, as at the teapot's lid) the
 * normal is taken a little way inside the patch. Returns false if none can be found. */
bool bezier_normal(const struct patch *pt, double u, double v, vec3 *n);

/* Splits the control net at u = t into lo (u in [0,t]) and hi (u in [t,1]), by de Casteljau.
 * lo and hi must hold (p+1)(q+1) points each; src may alias neither. */
void bezier_split_u(const struct patch *pt, double t, double (*lo)[4], double (*hi)[4]);
void bezier_split_v(const struct patch *pt, double t, double (*lo)[4], double (*hi)[4]);

/* Axis-aligned box of the Euclidean control points: contains the patch (convex hull
 * property, weights positive). */
void bezier_bounds(const struct patch *pt, vec3 *lo, vec3 *hi);

/* Fills pt->d2, d2w (uu, uv, vv), wmin from the control net's second differences (each partial of a
 * Bézier patch is a convex combination of them, times the degrees). They bound the Taylor
 * remainder of a Newton step, so a solver can accept a step without evaluating its end. */
void bezier_second_bounds(struct patch *pt);
/* The largest second difference of the Euclidean control net along u (dir 0) or v, times
 * n (n - 1) for degree n there (twice that for rational patches): the tessellation's bound on a
 * chord's distance from the surface (tess.h). */
double bezier_net_curvature(const struct patch *pt, int dir);

/* Whether the patch's point (u, v) lies in its object's trim region. */
static inline bool bezier_kept(const struct patch *pt, double u, double v)
{
    return !pt->trim || trim_contains(pt->trim, pt->u0 + u * (pt->u1 - pt->u0), pt->v0 + v * (pt->v1 - pt->v0));
}

/* Euclidean control point (i, j) (a polynomial patch's w is 1: no division). */
static inline vec3 bezier_point(const struct patch *pt, int i, int j)
{
    const double *c = pt->cw[i * (pt->q + 1) + j];
    return pt->rational ? v3(c[0] / c[3], c[1] / c[3], c[2] / c[3]) : v3(c[0], c[1], c[2]);
}

#endif
