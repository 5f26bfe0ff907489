/* join.h - the flat caps of a contour model's mesh made one surface where tubes end and begin in
 * the same plane (join.c; solid_mesh's last step). */
#ifndef SURFD_JOIN_H
#define SURFD_JOIN_H

#include <stdbool.h>
#include <stddef.h>

#include "solid.h"

/* A flat cap of a mesh being built: its ring (the tube's end ring, vertex ids, n of them), the
 * plane z, which way its triangles face, their range [t0, t1) in the mesh, and for each ring edge
 * k (ring[k], ring[k + 1 mod n]) the wall triangle beside it (SIZE_MAX: none). */
struct solid_cap {
    unsigned *ring;
    size_t *wall;
    int n;
    double z;
    bool up;
    size_t t0, t1;
    bool joined;   /* set by solid_mesh_join_caps: its plane joined (its triangles replaced) */
};

/* Where caps facing up (a tube ending below) and down (one beginning above) lie in one plane and
 * overlap, replaces them by the plane's part of the solid's surface: the region under solid below
 * and none above, facing up, and the reverse, facing down; the walls' ring edges split where the
 * rings cross. A plane whose rings overlap along a stretch (or that the join cannot settle) keeps
 * its caps as they were. Returns 0 or SF_ENOMEM (the mesh then unchanged but for unused vertices). */
int solid_mesh_join_caps(struct solid_mesh *m, struct solid_cap *caps, int n_caps);

/* Whether heights a and b are one cap plane (within 1e-6, relative above 1). */
bool join_same_plane(double a, double b);

/* Appends triangle (a, b, c) unless two of its vertices are one. 0, SF_ENOMEM or SF_ELIMIT. */
int solid_mesh_tri(struct solid_mesh *m, unsigned a, unsigned b, unsigned c);

/* Ear clipping of the polygon of ring (n vertex ids, counter-clockwise in x, y; a hole bridged in
 * may repeat a vertex, whose copies are no obstacle to an ear); up: the triangles face +z. Where no
 * ear is left (a curve that grazes itself) it clips anyway. Returns as solid_mesh_tri. */
int solid_mesh_clip(struct solid_mesh *m, const unsigned *ring, size_t n, bool up);

#endif
