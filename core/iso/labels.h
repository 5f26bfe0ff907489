/* labels.h - the surfaces of a label map (issue 47: 5, POST /isosurface?labels=all): one closed
 * surface for each label, every triangle between two labels made once and shared by both, facing
 * each way, so labels that touch share their boundary (no gap, no overlap) where two meet and
 * where three or more do. README.md ("Label maps") says why this method and not per-label marching
 * cubes or surface nets.
 *
 * The method, a multiple-material marching cubes (after Wu & Sullivan 2003) built so that each
 * label's surface is a closed, consistently oriented 2-manifold on any map (the derived
 * neighbourhood argument of README.md). Samples are voxels whose value is a label index, 0 the
 * background. A cell is the cube between 8 samples. Every face of a cell is divided among its
 * corners' labels by one rule that reads only that face's 4 samples, so the two cells that share
 * the face divide it alike: a cube edge between two labels has a vertex at its middle; two labels
 * on a face meet along a segment between two such middles; three or four labels round a face meet
 * at a vertex at the face's centre, one segment to each middle; a label on both diagonal corners
 * of a face is joined across it (when both diagonals are one label each, the smaller label joins:
 * the background always, as marching cubes of a label's mask at 0.5 joins its outside). The
 * segments on the cell's six faces form closed graphs on the cube; each connected one is closed
 * inside the cell: a loop between two labels by a fan of triangles (marching cubes' polygon, never
 * drawing a diagonal in a face, which the neighbour could draw too), a graph where three or more
 * labels meet by a cone from a vertex at its points' centre. Where one label borders such a graph
 * in two separate places, the two would touch at the cone's apex: that label gets the cell's
 * centre instead (a small body joining its two places through the cell), the others' cones stop
 * short of it, each capped, so no surface touches itself.
 *
 * Vertices sit at the middles and centres of their edges, faces and cells (a 0/1 mask's marching
 * cubes puts its vertices at the same middles: a cell with two labels has the loops of that label's
 * mask's marching cubes, but for the faces where it joins across and its interior tubes). Positions are
 * origin + index x spacing, as mc.h's. */
#ifndef SURFD_LABELS_H
#define SURFD_LABELS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../base/err.h"
#include "../geom/trimesh.h"
#include "mc.h"

/* Labels of one map at most (the index grid is uint16; 0 is the background). */
#define ISO_LABELS_MAX 65535

/* The surfaces between the labels: every triangle once, counter-clockwise seen from the label it
 * faces (side[2t + 1]), its back to the label it bounds (side[2t]). Labels are the grid's indices
 * 1 .. n_labels; 0, the background, has no surface of its own. */
struct iso_labels {
    float *pos;              /* 3 per vertex */
    uint32_t *tri;           /* 3 per triangle */
    uint16_t *side;          /* 2 per triangle: the label behind it, the label in front */
    size_t n_vert, n_tri;
    int n_labels;
    long centres;            /* cells' junctions where a label took the centre (none touches itself) */
    size_t *first;           /* n_labels + 2: label k's triangles are of[first[k] .. first[k + 1]) */
    uint32_t *of;
    uint32_t *remap;         /* iso_labels_mesh's scratch (n_vert each) */
    uint32_t *stamp, generation;
};

/* Extracts the surfaces of grid g (type ISO_U8 or ISO_U16, each sample a label index 0 ..
 * n_labels). closed: the grid's border counts as background, so every surface closes (else they
 * stop at the border). max_triangles (0: none) bounds the triangles, found while they grow
 * (SF_ELIMIT naming max_by, "" when NULL); pr is polled between planes. 0, or SF_EINVAL (a sample
 * over n_labels, a type without labels), SF_ELIMIT, SF_ENOMEM, SF_ECANCEL; out is then empty.
 * Caller frees out with iso_labels_free. */
int iso_labels_extract(const struct iso_grid *g, int n_labels, bool closed, size_t max_triangles, const char *max_by,
                       const struct sf_progress *pr, struct iso_labels *out, struct sf_err *err);
/* Label k's surface (1 .. n_labels) as a mesh of its own (area-weighted vertex normals); touch
 * (NULL, or n_labels + 1 counts) receives how many of its triangles face each other label (0: the
 * background). Uses l's scratch: one call at a time on one l. 0, or SF_ENOMEM. Caller frees out. */
int iso_labels_mesh(struct iso_labels *l, int k, size_t *touch, struct trimesh *out, struct sf_err *err);
void iso_labels_free(struct iso_labels *l);

#endif
