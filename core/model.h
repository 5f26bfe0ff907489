/* model.h - smooth surfaces through slice contours as bicubic Bézier patches, and their exact
 * volume (METHODS.md §2, §3). The patches are polynomial, oriented outward (Su × Sv), and close
 * with flat caps at the end slices, which add nothing to the volume integral. */
#ifndef SURFD_MODEL_H
#define SURFD_MODEL_H

#include "contour.h"
#include "err.h"
#include "nurbs.h"

/* Parabolic interpolation (seed 004 eq. 6–19; METHODS.md §2 eq. 32 and 36–38): through every
 * point of every contour; between slices the blend of the parabolas through slices k-1..k+1
 * and k..k+2 at their real z (uneven spacing is modelled as it is; the end pairs use the one
 * parabola they have). Appends to set as nurbs_extract() does: call nurbs_patches_fix() after
 * the last append; the caller frees the set. */
int model_parabolic(const struct contour_set *cs, struct patch_set *set, struct sf_err *err);

enum model_caps { CAPS_FLAT, CAPS_SLAB };

/* The volume with flat caps straight from the curves (closed form: mixed areas of curve pairs,
 * integrated over z exactly), without building patches; and the end curves' areas. */
int model_volume_closed(const struct contour_set *cs, double *volume, double end_area[2], struct sf_err *err);

struct model_measures {
    double volume;       /* with the caps asked for */
    double volume_flat;  /* divergence theorem, Gauss–Legendre exact for bicubics (seed 000 eq. 21–22) */
    double end_area[2];  /* areas enclosed by the first and last slice's curves (Green, exact) */
    double end_perimeter[2];
    double area;         /* of the closed solid: lateral (5x5 Gauss–Legendre per patch) and caps */
    double lo[3], hi[3]; /* bounds of the control points */
};
/* caps: CAPS_FLAT closes the solid at the end slices; CAPS_SLAB adds a prism of the end curve half
 * a slice spacing out at each end (end_gap[0], end_gap[1]: the first and last spacing), as most
 * planning systems count. */
void model_measure(const struct patch_set *set, enum model_caps caps, const double end_gap[2],
                   struct model_measures *m);

#endif
