/* model.h - smooth surfaces through slice contours as bicubic Bézier patches, and their exact
 * volume (METHODS.md §2, §3). The patches are polynomial, oriented outward (Su × Sv), and close
 * with flat caps at the end slices, which add nothing to the volume integral. */
#ifndef SURFD_MODEL_H
#define SURFD_MODEL_H

#include "contour.h"
#include "../base/err.h"
#include "../geom/nurbs.h"

enum model_caps { CAPS_FLAT, CAPS_SLAB, CAPS_DOME };

/* The four methods of METHODS.md §2:
 * - parabolic (seed 004 eq. 6–19, eq. 32 and 36–38): through every point of every contour (within
 *   MODEL_FIT_REL); between
 *   slices the blend of the parabolas through slices k-1..k+1 and k..k+2 at their real z (uneven
 *   spacing is modelled as it is; the end pairs use the one parabola they have);
 * - linear-parabolic (seed 000 eq. 32–38): the same blend of least-squares lines: smooths, does not
 *   pass through the points;
 * - coons (seeds 000/001 eq. 14–17): bicubic Coons patches on a grid resampled to one point count;
 * - bspline (seed 000 eq. 28–31): one interpolating B-spline surface, periodic along the contours.
 * Side patches run pair by pair of levels (grid methods: span by span), each in increasing u over
 * [0, 1]; the closed form (model_volume_closed) is for the first two. */
enum model_method { MODEL_PARABOLIC, MODEL_LINEAR_PARABOLIC, MODEL_COONS, MODEL_BSPLINE };
/* Every method reads each contour's curve redrawn on fewer knots (model_curve.c): within this
 * fraction of the contour's extent of the curve through its points (12 um on the heart), so that
 * patches are not slivers between the points of four contours. */
#define MODEL_FIT_REL 1e-4

/* How each contour's curve is parameterised from its start (where the +x ray out of its centroid
 * crosses it, so that u = 0 lines up from slice to slice): by arc length (the default: measured the
 * better on non-convex and branching sections), or polar (seed 004 eq. 1–5: u follows the angle round
 * the centroid, arc length where the contour turns back; better on star-shaped sections). */
struct model_opts {
    enum model_method method;
    bool polar;
    const struct sf_progress *progress; /* polled between steps (err.h); NULL: never stops */
    /* Folds between unlike contours undone (model_fold.c curves_unfold): for a model (its figures,
     * meshes, patches, renders, exports); POST /volume leaves it off, so that its closed form stays fast
     * (checking costs the heart 3 ms a path, a folding band's tries the lung 150 ms) - where a band
     * folds (the lung), the two surfaces' volumes differ by the pockets the fold holds (1.2e-4). */
    bool unfold;
    /* solid_build: each tube's side volume in closed form too (struct tube's side), from the curves
     * its patches are drawn from; for the figures (a mesh or a render needs none: 0.8 ms on the heart) */
    bool closed;
};
const char *model_method_name(enum model_method m);
int model_method_parse(const char *name, enum model_method *m);

/* Patches one side surface may have: about 600 bytes each (a bicubic net and its record), so a
 * few hundred thousand points of contour in one request cannot ask for tens of gigabytes. */
#define MODEL_MAX_PATCHES 2000000

/* The side surface of one chain of contours (one per level). Appends to set as nurbs_extract()
 * does: call nurbs_patches_fix() after the last append; the caller frees the set. SF_ELIMIT
 * (pointer /slices) when the method would make more than MODEL_MAX_PATCHES patches. */
int model_side(const struct contour_set *cs, struct model_opts o, struct patch_set *set, struct sf_err *err);
/* model_side, and with cl not NULL the closed form model_volume_closed gives, from the same curves,
 * fitted (and unfolded) once for both (volume NAN for the grid methods), and the time fitting them
 * and the closed form took (what the volume alone costs; the patches are the rest). */
struct model_closed {
    double volume, ms;
};
int model_side_closed(const struct contour_set *cs, struct model_opts o, struct patch_set *set,
                      struct model_closed *cl, struct sf_err *err);

/* The volume with flat caps straight from the curves (closed form: mixed areas of curve pairs,
 * integrated over z exactly), without building patches; and the end curves' areas. Parabolic and
 * linear-parabolic only. (The domes beyond the ends are model_dome's, built by solid.h.) */
int model_volume_closed(const struct contour_set *cs, struct model_opts o, double *volume, double end_area[2],
                        struct sf_err *err);

/* Chains: the tubes the surfaces run through. Contours on neighbouring levels (distinct z) link
 * when they are of one kind (hole or not) and overlap; a chain runs while links are one-to-one, so
 * a branching (one contour splitting into two, or two merging) ends chains and starts new ones.
 * Each chain end extends flat by ext[0] (below) and ext[1] (above): half the spacing to the next
 * level at a branching or an island's end; at the stack's ends, by the caps (flat and dome: 0, the
 * dome being added by the caller; slab: half a spacing). The seeds are silent on all of this: it is
 * ours. */
struct model_chain {
    int *idx;            /* contour indices, one per level, bottom up */
    int n;
    bool hole;           /* its volume counts negative */
    double ext[2];
    bool at_end[2];      /* this end is the stack's first (0) or last (1) level: the caps apply */
    double spacing[2];   /* the level spacing at each end */
};
int model_chains(const struct contour_set *cs, enum model_caps caps, struct model_chain **out, int *n_out,
                 struct sf_err *err);
void model_chains_free(struct model_chain *c, int n);
/* The chain's contours as a set of one contour per level (borrowing their points). */
struct contour_set model_chain_view(const struct contour_set *cs, const struct model_chain *c,
                                    struct contour_slice *storage);
/* The dome beyond an end: the quadratic q(s) = a0 + b s + c s² through the last three section
 * areas (two give a line; z[0] the end level, z[1], z[2] the next inward, s the distance outward),
 * extrapolated to its first zero, root. Returns its volume (the integral of q up to root), exact
 * where the end is a quadric (its section areas are quadratic in z); NAN, with root NAN, when it
 * does not close within three spacings (a shape still growing at its end). d may be NULL. */
struct model_dome {
    double a0, b, c, root;
};
double model_dome(const double z[3], const double A[3], int n, struct model_dome *d);
/* Area enclosed by the curve through one contour (exact, as the volume's end areas). */
double model_curve_area(const struct contour_slice *s);

/* How far the curves through the contours (the method's: the grid methods sample the parabolic
 * ones) enclose more or less than their polygons, what planning systems measure: rel, the sum of
 * the curves' areas over the polygons' less 1 (holes count negative), about what the volume departs
 * from the polygons' (volume.trapezoid); worst, the contour departing the most, by worst_rel. Dense
 * contours depart by 0.005 % (Eclipse's body) to 1.2 % (the synthetic bean, whose curve is right:
 * its polygons are short of the true shape); a sparse octagon by 9 %. 0 or SF_ENOMEM. */
struct model_departure {
    double rel;
    int worst;
    double worst_rel;
};
int model_departure(const struct contour_set *cs, enum model_method m, struct model_departure *d);
/* The departure past which a model's figures warn (api/model_json.c). */
#define MODEL_DEPART_WARN 0.02

#endif
