/* keyhole.h - the loops of one plane (a section: trimesh_slice's, outer loops and holes by the
 * even-odd rule) as loops without holes: each hole cut into the loop round it along a zero-width
 * channel, so that a reader that fills every contour it meets (plastimatch, many planning systems)
 * gets the even-odd region. Pure geometry on doubles; no reader or writer here.
 *
 * Written here: no Debian C library bridges holes into their outer polygons (earcut and the
 * triangulators do it only inside a triangulation, and give triangles back, not the polygon). */
#ifndef SURFD_KEYHOLE_H
#define SURFD_KEYHOLE_H

#include "../base/err.h"
#include "trimesh.h"

/* Edge-against-segment and point-in-loop tests one plane may cost (nesting and bridges), the cap
 * callers pass: past it SF_ELIMIT. A lung's sections take under 1e6; 10 000 loops of 100 points
 * nested in one another would take 1e10 (about 20 s) */
#define KEYHOLE_MAX_TESTS 2000000000L

/* Joins the loops of in (each closed, its first point not repeated, at least three points; loops
 * do not cross, they may touch). A loop inside an even number of others (0, 2 ...) is an outer
 * loop, inside an odd number a hole of the innermost loop round it. out receives one loop per
 * outer loop, counter-clockwise, in in's order: its points, then at the vertex nearest each of its
 * holes that sees it, the hole clockwise from its rightmost point back to that point, and the
 * outer vertex again (each point of a channel appears twice). A hole no vertex sees (a degenerate
 * section) is kept as a loop of its own after its outer one, clockwise, counted in *n_apart (may
 * be NULL). The caller frees out with trimesh_loops_free(). 0, SF_ENOMEM or SF_ELIMIT (over
 * max_tests tests). */
int keyhole_join(const struct trimesh_loops *in, long max_tests, struct trimesh_loops *out, int *n_apart,
                 struct sf_err *err);

#endif
