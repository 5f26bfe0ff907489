/* tess.h - tessellation of Bézier patches into triangle grids at a chord tolerance: the
 * `mesh` render method, the preliminary-value map's raster, and (later) mesh downloads.
 * The caller frees with tess_free(). */
#ifndef SURFD_TESS_H
#define SURFD_TESS_H

#include <stddef.h>

#include "bezier.h"
#include "../base/err.h"

#define TESS_MAX_SIDE 256 /* grid segments per patch side; bounds memory per patch */

struct tess {
    size_t n_verts, n_tris;
    double (*pos)[3];   /* vertex positions */
    float (*nrm)[3];    /* unit normals from the exact patch */
    float (*uv)[2];     /* patch parameters */
    int *patch;         /* patch index per vertex */
    unsigned (*tri)[3]; /* vertex indices, counter-clockwise seen along -(Pu × Pv) */
};

/* Segments per side so that the chord error stays below tol (world units); never fewer than
 * 1 nor more than max_side. The bound is |S_uu| h²/8 with |S_uu| <= p(p-1) max|Δ²P|. */
void tess_grid_size(const struct patch *pt, double tol, int max_side, int *n_u, int *n_v);
/* The chord error bound of an n_u x n_v grid (the inverse of tess_grid_size). */
double tess_grid_error(const struct patch *pt, int n_u, int n_v);

/* Tessellates every patch with its own grid for tol (sizes that divide one another, at most max_side
 * a side); where
 * patches meet edge to edge (the same end points and middle) the finer side's extra vertices lie on
 * the coarser's chords, so the mesh has no cracks. Returns 0 or SF_ENOMEM. */
int tess_build(const struct patch *patches, size_t n, double tol, int max_side, struct tess *out);
void tess_free(struct tess *t);

#endif
