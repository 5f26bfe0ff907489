/* kept.h - extractions kept for seed 002's interactive loop: what a local rebuild did to the mesh,
 * by stable triangle id (struct iso_change, reported by iso_adapt_edit and by the kept marching
 * cubes below), and marching cubes (mc.c, levels=1) kept with its samples so that an edit draws
 * again only the cells it reaches and a new iso is drawn in place, without rebuilding what is
 * kept.
 *
 * Triangle ids. A kept extraction numbers its first mesh's triangles 0 .. n-1 in the order the
 * matching fresh extraction hands them out (iso_extract, iso_adapt_end), so that the mesh a job
 * stored is version 1 of the ids. A triangle a change does not touch keeps its id; each triangle a
 * change adds takes the next id of a counter (never one used before), in an order fixed by the
 * samples and the change alone, so that a hierarchy rebuilt from the volume and its changes in
 * order (another node, a restart) numbers its triangles as the first did. */
#ifndef SURFD_KEPT_H
#define SURFD_KEPT_H

#include <stdbool.h>
#include <stdint.h>

#include "adapt.h"

/* What a change did: the ids of the triangles taken out; those put in, with their corners (per
 * corner x y z nx ny nz, floats; normals 0 when the extraction makes none), in id order. */
struct iso_change {
    uint32_t *removed;
    size_t n_removed;
    uint32_t *added;
    float *corners;          /* 18 floats a triangle added */
    size_t n_added;
    uint32_t next_id;        /* the counter after the change */
};
void iso_change_free(struct iso_change *c);

/* ---- marching cubes kept (mc.c's mesh, levels=1) ---- */

struct iso_kept;
/* Extracts g as iso_extract(g, o) does, keeping a copy of the samples (their own type), a min/max
 * index of blocks of cells and each triangle's block, for the calls below. 0, or SF_EINVAL,
 * SF_ENOMEM, SF_ELIMIT (o's max_triangles). */
int iso_kept_begin(const struct iso_grid *g, const struct iso_opts *o, struct iso_kept **out, struct sf_err *err);
/* The kept mesh (unused vertices left out) and each triangle's id (*ids: caller frees). With no
 * change since iso_kept_begin it is iso_extract's mesh, triangle for triangle in its order, ids
 * 0 .. n-1. 0 or SF_ENOMEM. */
int iso_kept_mesh(const struct iso_kept *k, struct trimesh *out, uint32_t **ids, struct sf_err *err);
/* Writes a block of new samples (blk: its size, type and samples; lo: its first sample) and draws
 * again the cells they reach, so that the mesh is iso_extract's of the edited samples, triangle
 * for triangle (positions and normals; in another order). ed: its counts; ch: what it did.
 * 0, or SF_EINVAL (?region outside the samples, with its pointer), SF_ENOMEM, SF_ELIMIT (k is
 * then of no further use: free it). */
int iso_kept_edit(struct iso_kept *k, const int lo[3], const struct iso_grid *blk, struct iso_edit *ed,
                  struct iso_change *ch, struct sf_err *err);
/* The mesh at a new iso value, drawn by the slabs' passes into k's own lists (no rebuild of k, no
 * sort when it is read: iso_kept_mesh), the blocks' lists left to the next edit: then
 * iso_extract's at that iso (opts otherwise as begun). ch: every triangle out, the new ones in,
 * with their corners unless corners is false (ch->corners NULL: a caller that reads the new mesh
 * back whole, iso_kept_mesh, saves their 72 bytes a triangle). 0, or SF_EINVAL (?value: not
 * finite, or outside the samples' range from the least up to, not at, the greatest: there the
 * surface is empty), SF_ENOMEM, SF_ELIMIT. */
int iso_kept_iso(struct iso_kept *k, double iso, bool corners, struct iso_edit *ed, struct iso_change *ch,
                 struct sf_err *err);
/* The lists an edit works on made now, when the last change left none (iso_kept_begin and a new
 * iso leave the mesh as drawn: a slider's moves and the reads of their meshes need no more), so
 * that the next edit does not make them: for a caller with time to spare, after an answer. 0, or
 * SF_ENOMEM (k is then of no further use), SF_EINVAL (it already was). */
int iso_kept_index(struct iso_kept *k, struct sf_err *err);
/* The memory k holds, in bytes. */
size_t iso_kept_bytes(const struct iso_kept *k);
void iso_kept_free(struct iso_kept *k);

#endif
