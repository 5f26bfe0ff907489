/* rays.h - the voxels of any traced model for its matrices (seed 003: a body to its six relief
 * matrices): a voxel is the body's when its centre lies inside the model's closed surface, found
 * along each line of voxel centres parallel to x by the exact tracer (patches) or Embree
 * (meshes), every crossing of the line in turn. Lines are independent: any slabs of them may be
 * traced at once. */
#ifndef SURFD_MATRIX_RAYS_H
#define SURFD_MATRIX_RAYS_H

#include <stdint.h>

#include "../trace/bvh.h"

/* Fills vox (n voxels of the box lo..hi, x fastest) for the lines of z rows [z0, z1): 1 where
 * the centre is inside, else 0. Inside is decided at each crossing by the surface's normal
 * (outward: entering where it faces the ray), so a line through a seam that two patches both
 * report crosses once; a crossing with no normal toggles. Returns the crossings found. */
long matrix_rays_slab(const struct bvh *b, const int n[3], const double lo[3], const double hi[3], int z0, int z1,
                      uint8_t *vox);

#endif
