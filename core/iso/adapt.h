/* adapt.h - seed 002's adaptive hierarchy (METHODS.md §4): cells of 2x2x2 merged level by level
 * where the coarser surface stays within max_error of the full-resolution one, joined without
 * cracks where cell sizes differ.
 *
 * Level l's cells are 2^(l-1) samples a side, aligned to multiples of it. One byte mask per level
 * marks the blocks covered by a cell of that level or a coarser one (the seed keeps bit masks:
 * which cell a sample lies in is a look-up, not an octree walk). A block merges at level l when
 * its eight children merged at l-1, every block of level l-1 that shares a face with it merged
 * too, so that cells that share a face differ by one level at most (cells that share only an edge
 * or a corner may differ more: an edge's crossing is one vertex, keyed by the finest edge it lies
 * on, whatever the levels that read it), and its error holds. The merged cell's surface is a polygon through the samples' own crossings on its twelve
 * edges (an edge the samples cross twice or more carries a feature finer than the cell: no
 * merge), so its vertices lie on the full-resolution surface; the error is the distance from
 * every full-resolution vertex in the block (the crossings of its fine edges) to that polygon,
 * the bench's measure (vertex distances both ways; the other way is 0 by construction), with the
 * polygon fanned as the mesh will fan it. Where a merged cell's neighbour stays finer, the cell
 * draws that face at the neighbour's resolution (below): its loop gains the crossings of the
 * face's inner edges. The mesh still fans the loop's corner-edge crossings as the estimate did,
 * and closes each stretch of finer path against its chord with triangles in the face (which only
 * add surface); where a path crosses its chord, the chord's triangle is fanned over the path
 * instead, which moves its points by at most the path's stray from the chord, and the estimate
 * adds that stray. So that the face cut in four joins the crossings as the whole face does, a
 * face square of two or more samples a side with diagonal inside corners is decided by its nine
 * nodes (corners, mid-edges, centre: the inside ones linked or not), from both cells that share
 * it; a block whose face, cut, would join them otherwise (an ambiguous quarter) or hold a path of
 * its own does not merge. Then every full-resolution vertex lies within max_error of the mesh,
 * whichever neighbours stay finer (tests/core/iso/test_adapt.c measures it; RESULTS.md).
 *
 * Crack-free joins. The seed makes the finer side of a shared face read the coarser cell's
 * interpolant there (its node values modified, the coarser side unchanged). Built that way first,
 * it costs accuracy (the finer cells' vertices move off the full-resolution surface with it:
 * 1.09x fewer triangles at max_error 0.5 on the shared CT, against 2.5x now) and it cannot be
 * combined with coarse edges that carry the samples' crossings (an edge read at two resolutions
 * by a cell's two faces can then disagree). So the other way round: the coarser cell draws a
 * face it shares with finer cells at their resolution, from the same samples, and nothing is
 * modified; its edges cross at most once, so reading an edge whole or in halves finds the same
 * crossing. Each crossing is keyed by the finest edge it lies on; each cell chains its faces'
 * segments into loops (an ambiguous face square of one sample a side by the asymptotic decider,
 * as mc.c; larger ones by their nine nodes, above) and fans
 * them from a vertex none of whose diagonals lies in a face (in a merged cell the one of least
 * key), else from a centre: in a merged cell the crossing of a fine edge inside it nearest the
 * loop's mean (a full-resolution vertex), in a level-1 cell the mean. So with
 * closed=true the mesh is a closed, consistently oriented 2-manifold at every mix of levels.
 * Unlike mc.c, a cell's two loops are always two caps (no interior tube test).
 *
 * merge=pieces (opts pieces, levels 2 and over; adapt_pieces.c, issue 45): a merged cell gives one
 * vertex per connected piece of surface inside it (Manifold Dual Contouring's idea), starting from
 * marching cubes' mesh (mc.c). Level by level, the vertices of the current mesh are grouped by the
 * level's block their first fine vertex lies in, and each group's pieces (vertices joined by mesh
 * edges inside the block) are merged into the piece's least vertex by edge collapses in breadth-
 * first order, each passing the link condition (which keeps a closed 2-manifold's topology: the
 * mesh stays closed, manifold, of the same components and Euler characteristic; a vertex refused
 * stays finer, with those reached through it only). The merged vertex minimises the QEF of the fine
 * tangent planes (truncated at a tenth of the largest eigenvalue, about the mass point; the mass
 * point when that leaves the block by over half a sample). The merge is refused when a changed
 * triangle turns by over acos(0.2), or when the distance either way would pass max_error: every
 * fine triangle keeps a witness (a triangle within max_error of its three corners, so of all of
 * it, or two that cover its points at quarters, or none: each such point within max_error of a
 * triangle round its corners' vertices), rechecked when a merge changes it; the new triangles'
 * vertex, points at quarters of their new edges and five inside points must lie within max_error
 * of a fine triangle round the piece or the triangle's corners. Blocks of one colour of 27 (3
 * apart on every axis) touch no triangle in common: each colour's blocks run in slabs on any
 * threads, the same mesh whatever their number. Edits draw the whole mesh again. No features.
 *
 * Sharp features (opts sharp; seed 002's second method: the feature points where the tangent
 * planes at a cell's crossings, from the gradient, meet). On a face, a segment between two
 * crossings whose normals are more than 26 degrees apart gets the point where their tangent lines
 * in the face meet, when it lies in the face: one vertex of both cells that share it (keyed by the
 * face square and the segment), so the joins stay closed. Inside, a loop whose normals differ that
 * much gets one point, found without SVD: the two most different normals seed two groups of
 * planes (each crossing to the nearer seed; each group one plane through its crossings' mean), a
 * third normal far out of their plane a third (a corner); a corner is where the three planes meet,
 * an edge the point of the two planes' line in the cell nearest the loop's centre. The loop is
 * fanned from it, so the mesh's edges run from face point to feature point to face point along
 * the feature. A corner that lies just outside the cell (less than half a cell) is pulled into
 * it, or kept where it is when the cell it lies in holds no surface; further out, the one of its
 * edges that passes nearest the loop's face points is taken.
 * With a field (opts field: an FRep object's own function), beyond the seed: crossings are put on
 * the function by regula falsi and their normals taken from its gradient; an ambiguous face is
 * decided by the function at the mean of its crossings; a cell edge that a feature pokes through
 * between two samples of one side gets the function's two crossings (the samples alone show
 * nothing there, and Extended Marching Cubes and Dual Contouring cut the feature off by up to half
 * a cell); a face segment whose isoline strays from it by more than a tenth of a cell (a curved
 * feature grazing the face) gets the isoline's point between; and an edge whose line leaves the
 * function's zero inside the cell ends there, at its corner. Blocks whose fine edges carry such
 * crossings are not merged. Without a field (sampled volumes) the normals are the samples'
 * central differences, which blur across an edge: features are kept, less exactly. */
#ifndef SURFD_ADAPT_H
#define SURFD_ADAPT_H

#include "mc.h"

#define ISO_MAX_LEVELS 4
/* Samples the hierarchy takes: it holds the grid as floats (4 bytes a sample, 1 GiB at most) */
#define ISO_ADAPT_MAX_SAMPLES (1u << 28)

struct iso_adapt_stats {
    long cells[ISO_MAX_LEVELS + 1];   /* cells holding the surface, by level (1..levels) */
    double max_estimate;              /* the largest |f - c| / |grad f| the merges accepted */
    long feature_points, face_points; /* features=sharp: loops fanned from their feature point, and
                                       * the points where features cross cell faces */
};

/* The extraction in phases of slabs: the samples copied as floats, each level's blocks (levels
 * 2..L), then the cells. The grid's samples must stay in place until iso_adapt_end. A caller
 * runs the slabs of each phase in any order on as many threads as it likes, calling
 * iso_adapt_between() on one thread after each phase; the mesh is the same whatever the order
 * or the number of threads (the slabs are fixed by the grid). */
struct iso_adapt;
/* 0, or SF_EINVAL (a bad levels, max_error, grid or iso, with its pointer), SF_ENOMEM. */
int iso_adapt_begin(const struct iso_grid *g, const struct iso_opts *o, int levels, double max_error,
                    struct iso_adapt **out, struct sf_err *err);
int iso_adapt_phases(const struct iso_adapt *a);
int iso_adapt_n_slabs(const struct iso_adapt *a);
void iso_adapt_run(struct iso_adapt *a, int phase, int slab);
void iso_adapt_between(struct iso_adapt *a, int phase);
/* Hands the mesh over and frees a: 0, or SF_ENOMEM, SF_ELIMIT (nothing handed over). */
int iso_adapt_end(struct iso_adapt *a, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err);
void iso_adapt_free(struct iso_adapt *a);

/* Local rebuilds (seed 002: the data change, and only the cells they touch are drawn again).
 * An extraction begun with opts keep is ended by iso_adapt_keep instead of iso_adapt_end: the
 * hierarchy, its float samples and the mesh stay, each triangle with its cell (the cell <->
 * triangle map: the level-2 block that drew it). iso_adapt_edit writes a block of new samples
 * (blk: its size, type and samples; lo: its first sample) and draws again the cells they reach:
 * every block whose merge they can change (its samples, children or ring), the cells round those
 * (normals and the joins read one block further), out to whole cells of the coarsest level. The
 * mesh is then the one a fresh extraction of the edited samples gives, triangle for triangle
 * (in another order). When the samples' least value moves the pad layer (closed), every cell is
 * drawn again (whole: every triangle is then taken out, and the new ones numbered on from the
 * counter, as merge=pieces' edits and kept.h's iso changes do). The samples of the grid given to
 * iso_adapt_begin are no longer read. */
struct iso_edit {
    long cells_rebuilt, triangles_removed, triangles_added;
    bool whole;
};
/* 0, or SF_ENOMEM, SF_ELIMIT (nothing handed over: a must be freed). */
int iso_adapt_keep(struct iso_adapt *a, struct iso_adapt_stats *st, struct sf_err *err);
/* A copy of the kept mesh (unused vertices left out) and its counts. 0 or SF_ENOMEM. */
int iso_adapt_mesh(const struct iso_adapt *a, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err);
/* 0, or SF_EINVAL (?region outside the samples; a not kept), SF_ENOMEM, SF_ELIMIT (a is then
 * of no further use: free it). */
int iso_adapt_edit(struct iso_adapt *a, const int lo[3], const struct iso_grid *blk, struct iso_edit *ed,
                   struct sf_err *err);

/* The same, reporting what the edit did by triangle id (kept.h: ch, which may be NULL; freed by
 * iso_change_free). The kept mesh's triangles are numbered as kept.h says: 0 .. n-1 in the order
 * iso_adapt_keep found them (iso_adapt_end's), then each new one the next id in the order the
 * rebuilt blocks drew them. */
struct iso_change;
int iso_adapt_edit_ids(struct iso_adapt *a, const int lo[3], const struct iso_grid *blk, struct iso_edit *ed,
                       struct iso_change *ch, struct sf_err *err);
/* Before iso_adapt_keep: the kept mesh's ids start at first, not 0 (a hierarchy that replaces
 * another's mesh, at a new iso, numbers its triangles after the other's). */
void iso_adapt_number_from(struct iso_adapt *a, uint32_t first);
/* The id the next triangle drawn will take. */
uint32_t iso_adapt_next_id(const struct iso_adapt *a);
/* The samples as they are now (edits written), as floats, x fastest, without the pad (*out:
 * caller frees). 0 or SF_ENOMEM. */
int iso_adapt_samples(const struct iso_adapt *a, float **out, struct sf_err *err);
/* Each triangle's id, in iso_adapt_mesh's order (*ids: caller frees). 0 or SF_ENOMEM. */
int iso_adapt_ids(const struct iso_adapt *a, uint32_t **ids, struct sf_err *err);

/* The memory a holds, in bytes. */
size_t iso_adapt_bytes(const struct iso_adapt *a);

/* All of it on the calling thread, polling pr. 0, or SF_EINVAL, SF_ENOMEM, SF_ELIMIT, SF_ECANCEL. */
int iso_extract_adaptive(const struct iso_grid *g, const struct iso_opts *o, int levels, double max_error,
                         const struct sf_progress *pr, struct trimesh *out, struct iso_adapt_stats *st,
                         struct sf_err *err);

#endif
