/* rays.c - a traced model's voxels along lines of voxel centres (rays.h). */
#include "rays.h"

#include <float.h>
#include <math.h>
#include <string.h>

/* Crossings one line may have at most: past them the line's rest keeps its last state. */
#define RAYS_MAX_CROSSINGS 65536
/* Each line runs this far (in voxels) off the centres in y and z: a mesh on the voxels' own
 * lattice (a matrix model's, whose vertices lie on quarter voxels) puts edges and vertices
 * exactly on the centre lines, where a ray may slip between two triangles or meet both. A
 * surface this near a centre may count it the other way, which no sampling can tell anyway. */
#define RAYS_OFF_Y 1.2345e-4
#define RAYS_OFF_Z 0.8765e-4

long matrix_rays_slab(const struct bvh *b, const int n[3], const double lo[3], const double hi[3], int z0, int z1,
                      uint8_t *vox)
{
    const double d[3] = {(hi[0] - lo[0]) / n[0], (hi[1] - lo[1]) / n[1], (hi[2] - lo[2]) / n[2]};
    const double span = hi[0] - lo[0], start = lo[0] - 0.01 * span; /* from outside the box */
    /* each crossing's search starts this far past the last (moved there: Embree's float ray and
     * its widened near bound find the last triangle again closer than that): nearer crossings
     * are one (a seam that two patches both report) */
    const double mag = fmax(fmax(fabs(lo[0]), fabs(hi[0])), fmax(fmax(fabs(lo[1]), fabs(hi[1])), fmax(fabs(lo[2]), fabs(hi[2]))));
    const double eps = 1e-6 * span + 8.0 * FLT_EPSILON * mag;
    long crossings = 0;
    for (int z = z0; z < z1; z++)
        for (int y = 0; y < n[1]; y++) {
            uint8_t *line = vox + (size_t)n[0] * ((size_t)y + (size_t)n[1] * z);
            const double py = lo[1] + (y + 0.5 + RAYS_OFF_Y) * d[1], pz = lo[2] + (z + 0.5 + RAYS_OFF_Z) * d[2];
            bool inside = false;
            double x = start; /* the search's origin */
            int m = 0;        /* the next voxel centre to settle */
            for (int k = 0; k < RAYS_MAX_CROSSINGS && m < n[0]; k++) {
                struct dray r;
                solve_ray_init(&r, v3(x, py, pz), v3(1, 0, 0));
                struct bvh_hit h;
                long iters = 0;
                if (!bvh_intersect(b, &r, k ? eps : 0.0, hi[0] - x, &h, &iters))
                    break;
                crossings++;
                x += h.t; /* centres before the crossing keep the state so far */
                for (; m < n[0] && lo[0] + (m + 0.5) * d[0] < x; m++)
                    line[m] = inside;
                inside = h.has_normal ? h.normal.x < 0.0 : !inside;
            }
            for (; m < n[0]; m++)
                line[m] = inside;
        }
    return crossings;
}
