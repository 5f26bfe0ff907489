/* trimesh.h - an indexed triangle mesh and the figures a user checks it by: volume (divergence
 * theorem), area, boundary and non-manifold edges, connected components, Euler characteristic.
 * Made by the isosurface extraction (core/iso) and, later, the matrix models. */
#ifndef SURFD_TRIMESH_H
#define SURFD_TRIMESH_H

#include <stddef.h>
#include <stdint.h>

#include "../base/err.h"

struct trimesh {
    float *pos;              /* 3 per vertex */
    float *nrm;              /* 3 per vertex (unit, outward), or NULL */
    uint32_t *tri;           /* 3 per triangle, counter-clockwise seen from outside */
    size_t n_vert, n_tri;    /* vertex ids stay below 2^31 */
};

struct trimesh_stats {
    double volume, area;     /* in the mesh's units (mm^3, mm^2) */
    long boundary_edges;     /* edges of one triangle */
    long nonmanifold_edges;  /* edges of three or more, or two that run the same way (misoriented) */
    long components;         /* connected by shared edges */
    long euler;              /* V - E + F */
    long degenerate;         /* triangles of zero area */
    double bounds[2][3];
};

void trimesh_free(struct trimesh *m);
/* Turns m about o: a point o + (x, y, z) goes to o + x a[0] + y a[1] + z a[2] (the axes of an
 * oblique grid, orthonormal and right-handed, so orientation and volume are kept); normals turn
 * with it. */
void trimesh_turn(struct trimesh *m, const double o[3], const double a[3][3]);
/* Figures of m (O(F log F): edges are sorted). 0, or SF_ENOMEM. */
int trimesh_stats(const struct trimesh *m, struct trimesh_stats *out, struct sf_err *err);

/* The section of a closed, outward-oriented mesh by the plane z = const: closed loops, each
 * counter-clockwise seen from +z round the solid's inside (holes clockwise), as planning systems
 * store contours (issue 18: a model back to an RT Structure Set). */
struct trimesh_loops {
    double (*p)[2];          /* the loops' points, one loop after another */
    int *start;              /* loop k: points start[k] .. start[k + 1] - 1 */
    int n;                   /* loops */
};
/* A vertex on the plane counts as above it (so the loops close where the plane meets vertices);
 * consecutive equal points are merged and loops of under three points dropped. 0, or SF_ENOMEM. */
int trimesh_slice(const struct trimesh *m, double z, struct trimesh_loops *out, struct sf_err *err);
void trimesh_loops_free(struct trimesh_loops *l);

/* Makes a closed, outward-oriented mesh that bounds solids touching along edges or at points a
 * 2-manifold (each edge two triangles, each vertex one fan). An edge of 2k triangles is split at
 * its midpoint, one new vertex for each pair of triangles that bound one solid wedge round it
 * (paired by their angles about the edge); then a vertex whose triangles form several fans gets a
 * copy for each fan after the first. The solids stay as they were, touching without sharing.
 * *vcap and *tcap are the capacities of m->pos (floats) and m->tri (ids), which may grow;
 * *midpoints counts the new edge midpoints. 0, or SF_ENOMEM. */
int trimesh_manifold(struct trimesh *m, size_t *vcap, size_t *tcap, long *midpoints);

/* How many of a's triangles b does not hold, each compared as its three corners' positions and
 * normals (0 when the mesh has none) from its least corner on: the same triangle whatever the
 * vertex numbering and the order of the list (an edit's mesh against a fresh extraction's). Meshes
 * of different counts differ by the larger. 0 (*differ), or SF_ENOMEM. */
int trimesh_differ(const struct trimesh *a, const struct trimesh *b, size_t *differ);

/* Distance from point p to triangle abc (the closest point by Voronoi regions, Ericson's
 * Real-Time Collision Detection 5.1.5). */
double trimesh_point_dist(const double p[3], const double a[3], const double b[3], const double c[3]);

#endif
