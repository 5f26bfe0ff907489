/* bvh_cone.h - cones of normals and bounds of chords of Bézier patches (bvh_cone.c), for the
 * exact hierarchy's leaves and seams (bvh.c). Private to core/trace: the hierarchy, and the map
 * (normal_cone, sub_net: where a patch may be seen edge-on). Every bound is a sine of a half-angle, > 1 where there is none. */
#ifndef SURFD_BVH_CONE_H
#define SURFD_BVH_CONE_H

#include <stdbool.h>

#include "../base/vec.h"
#include "../geom/bezier.h"

#define RATIONAL_MAX_DEGREE 8 /* a rational patch up to this degree gets cones and chord bounds */
#define RAT_N (3 * RATIONAL_MAX_DEGREE + 1)

/* A rational patch's three numerators as Bézier nets (x, y, z; w unused), made once per patch: a
 * leaf's cone and its neighbourhood's chord generators are their coefficients over its part of the
 * domain (sub_net; the sub-patch's own numerators differ from these by positive factors), less work
 * than forming the products for every leaf; the normals' one is split alongside the net down the
 * hierarchy (subdivide). The ducks' preparation: 55 ms forming them per leaf, 31 so (12 without
 * rational cones, for a render 53 -> 38 ms). */
struct rat_polys {
    bool ok;                   /* rnet_of held */
    struct patch n, tu, tv;    /* degrees (3p-1, 3q-1), (2p-1, 2q), (2p, 2q-1) */
    double net[5][RAT_N * RAT_N][4]; /* their nets, and two to work in */
};

#define CHORD_MAX_GENS (4 * PATCH_MAX_DEGREE * (PATCH_MAX_DEGREE + 1)) /* two patches' differences */

/* The net of pt's part over [u0, u1] x [v0, v1] into out (tmp: as many points, to work in). */
void sub_net(const struct patch *pt, double u0, double u1, double v0, double v1, double (*out)[4],
             double (*tmp)[4]);
/* A rational patch's numerators (rp->ok false where it has none: polynomial, too high a degree, a
 * weight not positive), and their coefficients over a part of its domain (into rp's work net). */
void rat_polys_make(struct rat_polys *rp, const struct patch *pt);
const struct patch *rat_part(struct rat_polys *rp, const struct patch *poly, double u0, double u1, double v0,
                             double v1, struct patch *part);
/* Normal cones: of a numerator's part (rat_part), of a polynomial patch. */
void cone_of_net(const struct patch *part, vec3 *axis, double *sin_half);
void normal_cone(const struct patch *pt, vec3 *axis, double *sin_half);
/* A net's largest distance from the bilinear through its corners (and its second differences). */
double net_deviation(const struct patch *pt, double *curv_u, double *curv_v);
/* Chord bounds: generators appended (a part's net, a patch's differences), the bound of a set of
 * them, and a patch's own. */
void append_net(const struct patch *part, vec3 *g, int *n);
bool chord_generators(const struct patch *pt, vec3 *g, int *n_g, int *n_u);
void chord_bound_of(const vec3 *g, int n_g, int n_u, vec3 *n, double *sin_max);
void chord_bound(const struct patch *pt, vec3 *n, double *sin_max);

#endif
