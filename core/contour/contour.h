/* contour.h - planar slice contours (mm), cleaned for modelling: sorted by z, repeated and closing
 * points dropped, every contour counter-clockwise, several contours per slice allowed (a contour
 * inside an odd number of others at its z is a hole). The set owns its arrays;
 * contour_set_free() releases them. */
#ifndef SURFD_CONTOUR_H
#define SURFD_CONTOUR_H

#include <stdbool.h>
#include <stddef.h>

#include "../base/err.h"

#define CONTOUR_MAX_POINTS 100000 /* per contour */
#define CONTOUR_MAX_SLICES 10000
#define CONTOUR_MAX_COORD 1e6     /* mm (a kilometre): |x|, |y| and |z| at most; past it the sums overflow */
#define CONTOUR_MIN_SPACING 1e-6  /* mm: two levels of contours are at least this far apart */

struct contour_slice {   /* one contour (a slice may hold several, at the same z) */
    double z;
    int n;              /* points */
    double (*p)[2];     /* x, y, counter-clockwise */
    int src;            /* index of the slice in the request, for naming it in errors */
    int src_contour;    /* index in the slice's "contours", or -1 for the "points" form */
    bool hole;          /* inside an odd number of the other contours at its z */
};

struct contour_set {
    struct contour_slice *s;
    int n_slices;       /* contours, sorted by z */
};

/* Where contour_clean found a set wrong, as the request numbers it (a contour_slice's src and
 * src_contour), for api/ to name: the set as a whole (slice -1), a slice's z (z), a contour's
 * points (contour -1: its slice's "points" form), or one of them (point >= 0). */
struct contour_fault {
    int slice, contour, point;
    bool z;
};

/* Cleans in place: sorts by z; drops the repeated closing point and repeated points; turns
 * clockwise contours; marks holes; rejects (SF_EINVAL, *fault saying where; fault may be NULL)
 * fewer than 3 distinct points, values that are not finite or past CONTOUR_MAX_COORD, levels
 * closer than CONTOUR_MIN_SPACING, a contour that crosses itself, two contours at
 * one z whose edges cross, fewer than two distinct z. */
int contour_clean(struct contour_set *cs, struct contour_fault *fault, struct sf_err *err);
void contour_set_free(struct contour_set *cs);

/* Signed area (shoelace; positive counter-clockwise) of a contour's polygon. */
double contour_area(const struct contour_slice *s);
/* Centroid of a contour's polygon (area-weighted). */
void contour_centroid(const struct contour_slice *s, double *x, double *y);
/* Whether point (x, y) is inside the contour's polygon (even-odd). */
bool contour_inside(const struct contour_slice *s, double x, double y);
/* Whether segments ab and cd cross properly (each one's ends strictly either side of the other). */
bool contour_segments_cross(const double *a, const double *b, const double *c, const double *d);
/* Whether two contours' regions overlap: a vertex of one inside the other, or crossing edges. */
bool contour_overlap(const struct contour_slice *a, const struct contour_slice *b);

/* Volumes from the raw polygons, the baselines users compare with. */
struct contour_baselines {
    double trapezoid;   /* sum of h (A_k + A_k+1) / 2: nothing beyond the end slices */
    double cavalieri;   /* sum of A_k h_k: each contour a slab of its slice's thickness */
    double frustum;     /* sum of h/3 (A_k + A_k+1 + sqrt(A_k A_k+1)) */
};
void contour_baselines(const struct contour_set *cs, struct contour_baselines *b);

#endif
