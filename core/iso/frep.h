/* frep.h - FRep objects (seed 002 §hybrid modelling, METHODS.md §4): a body as a function of
 * space, f >= 0 inside and f < 0 outside (HyperFun's convention), built as a tree of primitives
 * and operations, evaluated with its gradient.
 *
 * The primitives are signed distances (exact, or exact on the surface to first order: the
 * ellipsoid and the superellipsoid), not HyperFun's polynomials (its sphere is r^2 - |x|^2): so
 * that an offset is a distance, and the extraction's max_error, a length, can be judged from the
 * field. The set operations are Rvachev's R-functions R_alpha (the seed names R0; the alpha family
 * is HyperFun's):
 *   union      (f1 + f2 + sqrt(f1^2 + f2^2 - 2 alpha f1 f2)) / (1 + alpha)
 *   intersect  (f1 + f2 - sqrt(f1^2 + f2^2 - 2 alpha f1 f2)) / (1 + alpha)
 *   subtract   intersect(f1, -f2)
 * alpha = 0 is R0, smooth except where f1 = f2 = 0 (the edges, which stay sharp); alpha = 1 is
 * max / min. Blended union (HyperFun's hfBlendUni): union + a0 / (1 + (f1/a1)^2 + (f2/a2)^2).
 * Offset: f + d. Transform: the object is scaled, then rotated about x, y and z in that order, then
 * translated; the field at x is the child's at the inverse image of x, times the smallest scale
 * (so that it stays a distance to first order under uniform scaling).
 *
 * Gradients are analytic, by the chain rule through the tree; where a function is not
 * differentiable (a box's edge, the axis of a cylinder, f1 = f2 = 0 in an R-function) the value
 * of one side is taken. */
#ifndef SURFD_FREP_H
#define SURFD_FREP_H

#include <stddef.h>

#include "../base/err.h"

#define FREP_MAX_NODES 4096
#define FREP_MAX_DEPTH 64

enum frep_kind {
    FREP_SPHERE,         /* p: center[3], radius */
    FREP_ELLIPSOID,      /* p: center[3], radii[3] */
    FREP_BOX,            /* p: min[3], max[3] */
    FREP_CYLINDER,       /* p: base[3], axis[3] (unit), radius, length */
    FREP_CONE,           /* p: base[3], axis[3] (unit), radius at the base, length (apex at base + length axis) */
    FREP_TORUS,          /* p: center[3], axis[3] (unit), major radius, minor radius */
    FREP_SUPERELLIPSOID, /* p: center[3], radii[3], e1 (north-south), e2 (east-west) */
    FREP_HALFSPACE,      /* p: point[3], normal[3] (unit, pointing out) */
    FREP_VOLUME,         /* p: volume index (struct frep's volumes), iso, scale: scale (trilinear - iso) */
    FREP_UNION,          /* a, b; alpha */
    FREP_INTERSECT,      /* a, b; alpha */
    FREP_SUBTRACT,       /* a minus b; alpha */
    FREP_BLEND,          /* a, b; alpha of the union, p: a0, a1, a2 */
    FREP_OFFSET,         /* a; p: distance */
    FREP_TRANSFORM,      /* a; m (x - t) is the child's point, times lip */
};

struct frep_node {
    enum frep_kind kind;
    int a, b;            /* children (node indices) of operations */
    double alpha;
    double p[8];
    double m[3][3], t[3], lip;
};

/* A sampled volume in a tree (seed 002's hybrid of voxels and functions): its samples, trilinear
 * between them; beyond the grid, outside (the value the extraction pads a closed volume with). */
struct frep_volume {
    int dims[3];
    double origin[3], spacing[3];
    const float *v;          /* dims[0] dims[1] dims[2] samples, x fastest (the caller's) */
    float lo, hi, outside;   /* the samples' least and greatest, the value beyond the grid */
};

struct frep {
    struct frep_node *nodes;
    int n, root;
    const struct frep_volume *volumes;
};

/* The field at x, and its gradient into g when g is not NULL. */
double frep_eval(const struct frep *f, const double x[3], double g[3]);

/* Bounds lo <= f <= hi over the ball of centre c and radius r (conservative, not tight). */
void frep_bound(const struct frep *f, const double c[3], double r, double *lo, double *hi);

/* Samples the field, as float32, on the grid origin + (i, j, k) cell for k in [z0, z1): out
 * holds nx ny nz floats, x fastest, of which those planes are written. Blocks of 8^3 samples
 * whose bounds (two samples round them included) keep one sign get that sign only (a value of
 * the bounds): no cell near them holds the surface, so the mesh and its normals are those of the
 * fully sampled field. */
int frep_sample(const struct frep *f, const double origin[3], double cell, int nx, int ny, int z0, int z1, float *out,
                const struct sf_progress *pr, struct sf_err *err);

/* Builds the rotation of a transform (degrees about x, then y, then z) and its inverse map: sets
 * n->m, n->t and n->lip from scale[3] (all > 0), rotate_deg[3] and translate[3]. */
void frep_transform(struct frep_node *n, const double scale[3], const double rotate_deg[3], const double translate[3]);

#endif
