/* contour.h - planar slice contours (mm), cleaned for modelling: slices sorted by z, repeated and
 * closing points dropped, every contour counter-clockwise. One contour per slice for now (holes,
 * islands and branching come next). The set owns its arrays; contour_set_free() releases them. */
#ifndef SURFD_CONTOUR_H
#define SURFD_CONTOUR_H

#include <stddef.h>

#include "err.h"

#define CONTOUR_MAX_POINTS 100000 /* per contour */
#define CONTOUR_MAX_SLICES 10000

struct contour_slice {
    double z;
    int n;              /* points */
    double (*p)[2];     /* x, y */
    int src;            /* index of the slice in the request, for error pointers */
};

struct contour_set {
    struct contour_slice *s;
    int n_slices;
};

/* Cleans in place: sorts by z; drops the repeated closing point and repeated points; turns
 * clockwise contours; rejects (SF_EINVAL with a pointer "/slices/K/points") fewer than 3
 * distinct points, non-finite values, a contour that crosses itself, two slices at one z. */
int contour_clean(struct contour_set *cs, struct sf_err *err);
void contour_set_free(struct contour_set *cs);

/* Signed area (shoelace; positive counter-clockwise) and centroid of slice k's polygon. */
double contour_area(const struct contour_slice *s);

/* Volumes from the raw polygons, the baselines users compare with. */
struct contour_baselines {
    double trapezoid;   /* sum of h (A_k + A_k+1) / 2: nothing beyond the end slices */
    double cavalieri;   /* sum of A_k h_k: each contour a slab of its slice's thickness */
    double frustum;     /* sum of h/3 (A_k + A_k+1 + sqrt(A_k A_k+1)) */
};
void contour_baselines(const struct contour_set *cs, struct contour_baselines *b);

#endif
