/* matrix.h - seed 003's matrix models (METHODS.md §5): a body in its box stored as six relief
 * matrices M0..M5, one a face of the box, each element the number of empty voxels between that
 * face and the body along its line (the line's length where it misses the body); the voxels they
 * hold, the matrices of a voxel set, and the mesh of the voxels.
 *
 * Layout (Table 1, two index typos corrected as METHODS.md says), for N x M x K voxels along
 * x, y, z, element [i][j] (row i, column j):
 *   M0 (from Xmax, K x M): voxel (N-1-m, j, K-1-i)      M3 (from Xmin, K x M): (m, M-1-j, K-1-i)
 *   M1 (from Ymax, K x N): voxel (N-1-j, M-1-m, K-1-i)  M4 (from Ymin, K x N): (j, m, K-1-i)
 *   M2 (from Zmax, M x N): voxel (j, M-1-i, K-1-m)      M5 (from Zmin, M x N): (N-1-j, M-1-i, m)
 *
 * The voxels of a matrix model are those every axis-parallel line through them holds between the
 * first voxel seen from one end and the first seen from the other (seed 003 eq. 5): the body as
 * the six views see it. They hold the body exactly when every axis-parallel line meets it once
 * (convex along the axes); cavities and hidden concavities are filled (the seed's stated limit).
 *
 * Two meshes (our design: the seed's fragment table is a missing figure). matrix_fragments, the
 * default, is the seed's: a fixed fragment a voxel from a table, every vertex a voxel corner
 * (fragment.c has the table and why it is made by corners). matrix_mesh keeps every voxel centre
 * on the body's side (so rays through the centres give the voxels back). Each voxel of the set is
 * a solid: its cube, cut at every edge whose two faces are both open (no voxel beyond either) by
 * the plane t_f + t_g = 3/2 (t_f the distance from the face opposite f, in voxels): a chamfer that
 * takes off the prism of legs half a voxel along the edge. The surface is the boundary of the
 * union of the solids: the chamfers' facets (caps), each open face as the chamfers leave it, and
 * on a face two voxels share the corner triangles (legs half a voxel) that one neighbour's cuts
 * take off and the other's keep. A face's part in any solid holds the face's central diamond, so
 * two neighbours' parts always overlap: the union is closed and every edge has two triangles,
 * by construction. Where two solids touch at a point only, that vertex is given a copy per fan
 * of triangles round it, so the mesh is a 2-manifold. Vertices lie on the quarter-voxel lattice
 * (merged by exact keys): voxel corners, edge midpoints, and (computed) the points where chamfers
 * meet. The seed's deeper cut by faces (through the open faces' far edges) lets two neighbours'
 * parts of a shared face meet along a diagonal only and loses more volume (a ball of radius 20
 * voxels: -4.2 %, against -1.3 %); matrix_fragments makes the deep cut by corners instead. The seed's eight variants of open faces (1; 2 opposite; 2 adjacent; 3 with two
 * opposite; 3 at a corner; 4 with the closed pair adjacent; 4 opposite; 5) are cases of the one
 * rule (1 or 2 opposite: the faces themselves; 2 adjacent: one chamfer; 3 at a corner: three
 * meeting; ...), and its "partially open" faces are the corner triangles a neighbour's cut leaves. */
#ifndef SURFD_MATRIX_H
#define SURFD_MATRIX_H

#include <stddef.h>
#include <stdint.h>

#include "../base/err.h"
#include "../geom/trimesh.h"

/* Voxels a matrix model may have along one axis, and in all. */
#define MATRIX_MAX_SIDE 4096
#define MATRIX_MAX_VOXELS (1u << 28)

struct matrix_model {
    int n[3];                /* N, M, K: voxels along x, y, z */
    double lo[3], hi[3];     /* the box */
    int *m[6];               /* M0..M5, row by row */
};

/* Rows and columns of matrix k of a model of n voxels. */
void matrix_shape(const int n[3], int k, int *rows, int *cols);

/* The voxel that element [i][j] = depth of matrix k names. */
void matrix_voxel(const int n[3], int k, int i, int j, int depth, int v[3]);

/* The six matrices of voxel set vox (n voxels, x fastest, nonzero: in the body) into m[k] (each
 * rows x cols ints, the caller's). */
void matrix_of_voxels(const int n[3], const uint8_t *vox, int *const m[6]);

/* The voxels of model mm into vox (the caller's, n[0] n[1] n[2] bytes). 0; or SF_EINVAL when
 * the matrices contradict each other (a line seen from both ends where the first voxel from one
 * lies beyond the first from the other, or a voxel an element names that the others exclude):
 * *bad_k, *bad_i, *bad_j name the element. */
int matrix_voxels(const struct matrix_model *mm, uint8_t *vox, int *bad_k, int *bad_i, int *bad_j, struct sf_err *err);

struct matrix_stats {
    long voxels;             /* surface voxels (named by some element) */
    long base_voxels;        /* named by an element that is a local maximum of depth among its four
                              * neighbours (eq. 4: the far side of a bump) */
    long redundant_voxels;   /* named again by another matrix (eq. 6: handled once) */
    long computed_vertices;  /* mesh vertices off the voxel corners */
    long dropped_voxels;     /* voxels of the set whose cube holds none of the solid (matrix_fragments:
                              * lone voxels, a rod's ends, voxels meeting the others only at
                              * an edge or a point) */
};

/* The mesh of voxel set vox in the box lo + (0..n) d: a closed, outward-oriented 2-manifold (see
 * the head). stats may be NULL. 0, or SF_ENOMEM, SF_ELIMIT (over ISO's vertex limit). */
int matrix_mesh(const int n[3], const uint8_t *vox, const double lo[3], const double d[3], struct trimesh *out,
                struct matrix_stats *st, struct sf_err *err);

/* The mesh of voxel set vox as seed 003 builds it: a fixed fragment of triangles a voxel from a
 * table, every vertex a voxel corner (fragment.c says how the table is made); closed, outward,
 * a 2-manifold; volume within a few per cent of the voxels', but its chamfers pass through the
 * centres of the voxels they cut (matrix_mesh keeps every centre on its side). Same contract as
 * matrix_mesh; computed_vertices counts the edge midpoints that part solids touching along an edge. */
int matrix_fragments(const int n[3], const uint8_t *vox, const double lo[3], const double d[3], struct trimesh *out,
                     struct matrix_stats *st, struct sf_err *err);

/* The figures of eq. 4-6 of model mm (voxels, base_voxels, redundant_voxels; the rest zeroed). */
void matrix_counts(const struct matrix_model *mm, struct matrix_stats *st);

#endif
