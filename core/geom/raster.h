/* raster.h - the even-odd region of a plane's closed loops (a section: trimesh_loops) sampled at
 * the centres of a grid's pixels: a binary mask, as a DICOM Segmentation's frame holds one. Pure
 * geometry on doubles: the loops are in pixel units already (pixel (i, j)'s centre at x = i,
 * y = j); no reader, writer or grid's placement in space here. */
#ifndef SURFD_RASTER_H
#define SURFD_RASTER_H

#include <stddef.h>

#include "../base/err.h"
#include "trimesh.h"

/* Edge-row crossings one plane may hold (an edge spanning r rows crosses r of them; a section's
 * loops cross each row a few times): 2^24 crossings of 8 bytes is 128 MB, far past any real
 * section on a 512 x 512 grid (some 1e4), reached only by loops that zigzag across every row */
#define RASTER_MAX_CROSSINGS (1L << 24)

/* Sets mask[j * cols + i] to 1 where pixel (i, j)'s centre lies inside an odd number of l's loops,
 * 0 elsewhere (every pixel written). A centre on an edge is inside where the edge is the region's
 * left or lower side (half-open: two loops that share an edge set its pixels once). *n_set (may be
 * NULL) counts the pixels set. cols, rows >= 1. 0, SF_ELIMIT (over RASTER_MAX_CROSSINGS, counted
 * before anything is allocated) or SF_ENOMEM. */
int raster_loops(const struct trimesh_loops *l, int cols, int rows, unsigned char *mask, size_t *n_set,
                 struct sf_err *err);

#endif
