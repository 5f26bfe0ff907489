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

/* ps must be resolved (nurbs_patches_fix). Returns 0 or SF_ENOMEM. */
int enclosed_measure(const struct patch_set *ps, struct enclosed *e);

#endif
