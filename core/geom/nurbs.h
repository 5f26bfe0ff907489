/* nurbs.h - the free-form surfaces a scene is made of (Bézier, B-spline, NURBS), their
 * validation, direct evaluation by Cox–de Boor, knot insertion and Bézier extraction.
 *
 * A Bézier surface is stored as the B-spline with clamped knots [0..0, 1..1]; a B-spline as
 * a NURBS with no weights. Control points are row-major, index i*n_v + j, i along u. */
#ifndef SURFD_NURBS_H
#define SURFD_NURBS_H

#include <stddef.h>

#include "bezier.h"
#include "../base/err.h"
#include "../base/vec.h"

enum surf_kind { SURF_BEZIER, SURF_BSPLINE, SURF_NURBS };

#define SURF_MAX_POINTS 1000000 /* control points per surface: caps memory per request */
/* Largest coordinate magnitude a control point may have. The tracer hands Embree float boxes and
 * rays, and Embree asserts (aborting the process) on an origin or box past ~1.8e18; 1e15 keeps every
 * point, the framed eye and the float bounds of any patch well inside that. */
#define SURF_MAX_COORD 1e15

struct surface {
    enum surf_kind kind;
    int deg_u, deg_v;   /* degrees, >= 1 */
    int n_u, n_v;       /* control points along u and v */
    double *knots_u;    /* n_u + deg_u + 1 values, non-decreasing */
    double *knots_v;    /* n_v + deg_v + 1 values */
    double *points;     /* 3 * n_u * n_v coordinates */
    double *weights;    /* n_u * n_v positive weights, or NULL (all 1) */
};

/* Allocates the arrays of s for the given kind, degrees and counts (Bézier: n = deg + 1 and
 * its knots are filled in). Returns 0 or SF_ENOMEM / SF_ELIMIT / SF_EINVAL. The caller frees
 * with nurbs_surface_free(). */
int nurbs_surface_alloc(struct surface *s, enum surf_kind kind, int deg_u, int deg_v, int n_u, int n_v,
                        struct sf_err *err);
void nurbs_surface_free(struct surface *s);

/* Checks degrees, counts, knots (non-decreasing, non-empty domain, multiplicity <= degree+1
 * inside), weights (positive, finite) and coordinates (finite, within ±SURF_MAX_COORD). where is the JSON pointer
 * of the object ("/objects/3"); field names are appended to it in err->pointer. */
int nurbs_validate(const struct surface *s, const char *where, struct sf_err *err);

/* Parameter domain: [knots_u[deg_u], knots_u[n_u]] and likewise in v. */
void nurbs_domain(const struct surface *s, double *u0, double *u1, double *v0, double *v1);

/* The p+1 non-zero B-spline basis functions N[0..p] at t, knots U of n control points (the
 * functions of points r-p..r); returns the span r. */
int nurbs_basis(const double *U, int n, int p, double t, double *N);

/* Point and first derivatives at (u, v) by Cox–de Boor, rational where weighted. */
void nurbs_eval(const struct surface *s, double u, double v, vec3 *P, vec3 *Pu, vec3 *Pv);

/* Inserts knot t once in the u direction (Boehm); the surface is unchanged geometrically.
 * Returns 0 or SF_ENOMEM. */
int nurbs_insert_knot_u(struct surface *s, double t);
/* Swaps the roles of u and v in place (knots, degrees, point order). */
int nurbs_transpose(struct surface *s);

/* Bézier extraction: one patch per non-empty knot span pair. Appends to *patches (growing
 * it with realloc; *n_patches and *cap track it) and the homogeneous points to *pool the same
 * way; patch.cw is stored as an offset into the pool until nurbs_patches_fix() resolves it.
 * s is left unchanged. Returns 0 or SF_ENOMEM. */
struct patch_set {
    struct patch *patches;
    size_t n, cap;
    double (*pool)[4];
    size_t n_pool, cap_pool;
};
int nurbs_extract(const struct surface *s, int surface_index, struct patch_set *set);
/* Makes every patch's cw point into the pool (call after the last extraction). */
void nurbs_patches_fix(struct patch_set *set);
void nurbs_patch_set_free(struct patch_set *set);

#endif
