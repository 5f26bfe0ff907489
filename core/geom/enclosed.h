/* enclosed.h - the volume that any set of patches encloses (seed 000 eq. 21–22 over every patch,
 * Gauss–Legendre of enough nodes to be exact for polynomial patches), and whether the patches close:
 * edge to edge, every patch edge shared by exactly one other, traversed the other way. Collapsed
 * edges (a NURBS sphere's poles, the teapot lid's top) need no partner. */
#ifndef SURFD_ENCLOSED_H
#define SURFD_ENCLOSED_H

#include <stddef.h>

#include "nurbs.h"

struct enclosed {
    double volume;           /* signed: positive when the patches face outward */
    double area;
    double lo[3], hi[3];     /* bounds of the control points */
    size_t open_edges;       /* edges no other patch shares */
    size_t flipped_edges;    /* edges shared the same way round: neighbours facing opposite ways */
    int open_object;         /* an object (patch.surface) with an open edge, or else the one with the most
                              * flipped edges (the one turned the wrong way), or -1 */
};

/* ps must be resolved (nurbs_patches_fix). Patches with a trim (bezier.h) count only their trim
 * region; the edges of a set with any are not matched (open_edges and flipped_edges stay 0:
 * enclosed_shell checks such a set). Returns 0 or SF_ENOMEM. */
int enclosed_measure(const struct patch_set *ps, struct enclosed *e);
/* The same, and each object's own share of the volume and of the area (object_volume and object_area
 * [0..n_objects - 1]). */
int enclosed_measure_objects(const struct patch_set *ps, struct enclosed *e, double *object_volume, double *object_area,
                             int n_objects);

/* ---- trimmed surfaces: closure along the loops ---- */

struct shell_part {
    const struct surface *s;
    const struct trim *t;  /* NULL: the whole domain */
};

struct shell {
    size_t samples;        /* boundary points tested */
    size_t open_samples;   /* ... that lie on no other boundary */
    int open_object;       /* a part with one, or -1 */
    double open_at[3];     /* the first such point */
    size_t flipped;        /* matched points where the two parts face opposite ways */
    int conflicts;         /* parts whose facing no choice of signs makes agree with every neighbour */
    double tests;          /* point-segment tests the matching takes (about) */
};

/* The most point-segment tests enclosed_shell makes (some 25 s here): the real parts take tens a
 * boundary point; a 6.6 KB part whose loops crowd together took 1.7e10, seven minutes. */
#define SHELL_MAX_TESTS 1e9

/* Whether the parts close a solid: every point of every boundary (trim loops, or the domain's edges;
 * collapsed edges need no partner) within tol of another boundary (a part's own, across a seam, too),
 * and how each part must be turned (sign[k] = +1 or -1, caller's array of n) so that neighbours face
 * the same way. pr is polled as the boundary's segments are matched (a loop of millions of points
 * takes minutes). Returns 0, SF_ENOMEM, SF_ECANCEL, or SF_ELIMIT when the matching would take more
 * than SHELL_MAX_TESTS tests (out->tests says how many), decided before it starts. */
int enclosed_shell(const struct shell_part *parts, int n, double tol, const struct sf_progress *pr, struct shell *out,
                   signed char *sign);

#endif
