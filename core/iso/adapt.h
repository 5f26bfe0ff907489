/* adapt.h - seed 002's adaptive hierarchy (METHODS.md §4): cells of 2x2x2 merged level by level
 * where the coarser surface stays within max_error of the full-resolution one, joined without
 * cracks where cell sizes differ.
 *
 * Level l's cells are 2^(l-1) samples a side, aligned to multiples of it. One byte mask per level
 * marks the blocks covered by a cell of that level or a coarser one (the seed keeps bit masks:
 * which cell a sample lies in is a look-up, not an octree walk). A block merges at level l when
 * its eight children merged at l-1, every block of level l-1 that touches it (by a face, an edge
 * or a corner) merged too, so that cells that touch differ by one level at most, and the error
 * test holds: at every sample of the block where the fine or the coarse surface passes within
 * a cell, |f - c| / |grad f| <= max_error, with f the samples, c the coarse cell's trilinear
 * interpolant of its corners and grad f by central differences: the distance between the two
 * surfaces along the normal, to first order (the bench measures the real distances both ways).
 *
 * Crack-free joins, by the seed's rule: where a finer cell meets a coarser one, the finer side's
 * values are the coarser cell's interpolant (bilinear on the shared face, linear on a shared
 * edge), so the isolines on the face coincide; the coarser cell draws its face at the finer
 * side's resolution (its own interpolant sampled there), so both sides have the same polyline,
 * vertex for vertex. Every value a cell reads comes from one function of the sample (the
 * coarsest cell that touches it interpolates it, or it is the sample itself), so neighbours read
 * the same numbers; each crossing is keyed by the finest edge it lies on. Each cell chains its
 * faces' segments into loops and fans them (from a vertex none of whose diagonals lies in a face,
 * else from the loop's centre), so with closed=true the mesh is a closed, consistently oriented
 * 2-manifold at every mix of levels. Unlike mc.c, a cell's two loops are always two caps (no
 * interior tube test). */
#ifndef SURFD_ADAPT_H
#define SURFD_ADAPT_H

#include "mc.h"

#define ISO_MAX_LEVELS 4

struct iso_adapt_stats {
    long cells[ISO_MAX_LEVELS + 1];   /* cells holding the surface, by level (1..levels) */
    double max_estimate;              /* the largest |f - c| / |grad f| the merges accepted */
};

/* The isosurface of g with levels (1..ISO_MAX_LEVELS) and max_error (in the grid's units), on
 * the calling thread, polling pr. 0, or SF_EINVAL, SF_ENOMEM, SF_ELIMIT, SF_ECANCEL. */
int iso_extract_adaptive(const struct iso_grid *g, const struct iso_opts *o, int levels, double max_error,
                         const struct sf_progress *pr, struct trimesh *out, struct iso_adapt_stats *st,
                         struct sf_err *err);

#endif
