/* solve.h - the roots of ray = patch (seed 000 §2.3–2.4, METHODS.md §1).
 *
 * The ray is written as two planes through it (the "projection plane" of eq. 10): e1, e2 are
 * orthonormal and perpendicular to the ray, so a hit is x(u,v) = y(u,v) = 0 in that frame.
 * Every solver works in the patch's own parameters [0,1]², returns true with the hit only when
 * it converged inside the accepted box, and counts its iterations for the statistics.
 * Pure functions: no allocation, no state, safe from any thread. */
#ifndef SURFD_SOLVE_H
#define SURFD_SOLVE_H

#include <stdbool.h>
#include <stdint.h>

#include "../geom/bezier.h"
#include "../base/vec.h"

struct dray {
    vec3 o, d;         /* origin and unit direction */
    vec3 e1, e2;       /* the two planes' normals: d, e1, e2 orthonormal */
    double e1o, e2o;   /* e1·o, e2·o */
    vec3 inv_d;        /* 1 / d per axis (infinite where d is across the axis): box slabs without a division */
};

struct solve_box {
    double u0, u1, v0, v1; /* where a root is accepted, in patch parameters */
};

struct solve_hit {
    double u, v;  /* patch parameters of the root */
    double t;     /* distance along the ray */
    int iters;    /* iterations spent, converged or not */
    vec3 n;       /* unit normal Pu × Pv at the root, from the last evaluation; zero where
                   * that vanishes (a collapsed edge: bezier_normal() then looks nearby) */
};

/* Stop rules, ours (the seed names "four"/"three" conditions without listing them). */
#define SOLVE_MAX_NEWTON 16     /* Newton–Cramer iteration cap (it converges in 3–5 from a seed) */
#define SOLVE_MAX_DESCENT 400   /* gradient / steepest descent cap (they converge linearly) */
#define SOLVE_STEP_EPS 1e-15    /* a parameter step below this has converged */
#define SOLVE_BOX_EPS 1e-9      /* slack of the accepted box, so no root slips between leaves */

void solve_ray_init(struct dray *r, vec3 o, vec3 d);
/* The ray from o along like's direction (and like's planes): for many parallel rays. */
void solve_ray_parallel(struct dray *r, vec3 o, const struct dray *like);

/* Newton's method on the projected homogeneous system, step by Cramer's rule (seed 000
 * eq. 10–13). tol2 is the squared residual accepted as a root (distance² from the ray). */
bool solve_newton_cramer(const struct patch *pt, const struct dray *r, double u, double v,
                         const struct solve_box *box, double tol2, struct solve_hit *hit);
/* The same from a seed that should be next to a root, for a caller with an exact fallback: gives
 * up as soon as the residual stops falling fast instead of iterating up to SOLVE_MAX_NEWTON. */
bool solve_newton_seeded(const struct patch *pt, const struct dray *r, double u, double v,
                         const struct solve_box *box, double tol2, struct solve_hit *hit);

/* Gradient descent on g = x² + y² (seed 000 eq. 2, 4), the seed's refinement for Bézier. */
bool solve_gradient(const struct patch *pt, const struct dray *r, double u, double v,
                    const struct solve_box *box, double tol2, struct solve_hit *hit);

/* Steepest descent keeping the direction while g falls, cutting the step by the inverse
 * golden ratio when it rises (seed 000 eq. 9), the seed's refinement for B-splines. */
bool solve_steepest(const struct patch *pt, const struct dray *r, double u, double v,
                    const struct solve_box *box, double tol2, struct solve_hit *hit);

/* The thesis's original preliminary search (eq. 3): n_samples random (u,v), keep the best and
 * every sample within eps0 of it, refine each by gradient descent; the nearest root wins.
 * rng is the caller's xorshift state. */
bool solve_montecarlo(const struct patch *pt, const struct dray *r, int n_samples, uint64_t *rng,
                      double tol2, struct solve_hit *hit);

#endif
