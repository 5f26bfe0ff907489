/* map.h - the preliminary-value map of seed 000 (eq. 5–6, Table 1), made exact-safe: integer
 * patch ids and float (u, v) seeds instead of 8-bit channels, rasterised conservatively from a
 * tessellation whose chord error is under half a pixel, so every pixel the true surface covers
 * has a candidate. Each candidate carries a lower bound on its patch's depth at the pixel, so the
 * tracer can visit candidates nearest-first and stop as soon as the next cannot be in front
 * (branch and bound); what did not fit is remembered, and such pixels fall back to the exact
 * hierarchy. Caller frees with map_free(). */
#ifndef SURFD_MAP_H
#define SURFD_MAP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../geom/bezier.h"
#include "camera.h"
#include "../base/err.h"

struct bvh;

#define MAP_CANDS 3 /* patches kept per pixel, nearest lower bound first */

struct map_cand {
    int patch;
    float u, v;   /* seed in patch parameters */
    float zlo;    /* camera depth no root of this patch at this pixel can be in front of */
    float zs;     /* depth of the seed's fragment: a root much behind it is on another sheet */
    float zfold;  /* least depth of a fold of the patch's outline near the pixel (INFINITY: none):
                   * a root behind it may have a nearer sheet in front */
    float zoutline; /* least depth of any edge of the outline, border or fold, near the pixel: a seed
                     * from there (zs == zoutline) lies off the patch's tessellated image */
};

struct map_vert;
struct map_tri;
struct border_seg;

struct map {
    int W, H;
    bool complete;           /* false: some patch crosses the eye plane; trust no pixel */
    struct camera cam;
    const struct patch *patches; /* borrowed from map_begin to map_end */
    /* the projected tessellation, bucketed by tiles of MAP_TILE_ROWS rows: patch k's vertices
     * from vfirst[k], its primitives in [first[k], end[k]) (slots up to first[k + 1]) */
    struct map_vert *verts;
    struct map_tri *tris;
    size_t n_tris;           /* primitive slots */
    size_t *vfirst, *first, *end;
    double *pix;             /* per patch: a pixel's world size at its nearest depth */
    int n_parts;             /* the tessellation's parts: patches [part_first[p], part_first[p + 1]) */
    size_t *part_first;
    unsigned char *part_failed; /* per part: out of memory (map_end answers so) */
    const struct bvh *seams;     /* borrowed from map_begin to map_end */
    uint64_t **part_keys;        /* per part: its primitives on the picture by tile, as depth keys */
    unsigned *part_hist;         /* per part and row tile: how many */
    int n_tiles;
    unsigned **tile_list;    /* per tile: its primitives, nearest depth bound first */
    unsigned *tile_n;
    /* per patch: its grid (u, v counts; 0, 0: left out); the index in segs of each border edge
     * along a seam (SIZE_MAX: none, or the edge drawn whole, as on a trimmed patch) and where
     * its segments start; its outline's padding; and whether a seam joins it to a neighbour
     * without an outline somewhere (a candidate of its may then be the neighbour's root) */
    int (*grid)[2];
    size_t (*border)[4];
    struct border_seg *segs;
    size_t *sfirst;
    float *pad;
    unsigned char *seamed;
};

#define MAP_TILE_ROWS 16

/* The candidates of rows [y0, y1): a band's own buffer, reused from band to band. */
struct map_rows {
    int y0, y1, W;
    struct map_cand *cand;   /* (y1-y0)*W*MAP_CANDS, the first n[pixel] sorted by zlo, distinct patches */
    unsigned char *n;        /* (y1-y0)*W: candidates listed */
    float *dropped;          /* (y1-y0)*W: least zlo of a candidate that did not fit, or was culled as
                              * most likely hidden (INFINITY: none); where n > 0 */
    float *zcut;             /* (y1-y0)*W: depth beyond which a fragment is culled; where n > 0 */
    size_t cap;              /* pixels allocated */
};

/* Tessellates and projects the patches and buckets the triangles by row tiles; no pixel is
 * written yet. seams (may be NULL: every border an outline): the hierarchy whose bvh_seam says
 * which patches share an edge. map_build() is the steps below on one thread:
 *   map_begin()  each patch's grid for the camera, and room for its tessellation
 *   map_part()   step 0: tessellates part p of map_parts(); step 1: joins its patches' seams to
 *                their neighbours' and groups its primitives on the picture by row tiles; step 2:
 *                sorts its share of the tiles' lists, nearest depth bound first. The parts of a
 *                step on any threads at once, each step after every part of the one before
 *   map_end()    checks that every part went well
 * The patches and seams are borrowed until map_end; map_free() at any step. */
int map_build(const struct patch *patches, size_t n, const struct bvh *seams, const struct camera *cam,
              struct map **out, struct sf_err *err);
int map_begin(const struct patch *patches, size_t n, const struct bvh *seams, const struct camera *cam,
              struct map **out, struct sf_err *err);
#define MAP_STEPS 3
int map_parts(const struct map *m);
/* 0 or SF_ENOMEM (map_end then fails). */
int map_part(struct map *m, int step, int p);
int map_end(struct map *m, struct sf_err *err);
/* Fills rw (growing its buffers as needed) with the candidates of rows [y0, y1). The map is
 * only read, so threads may fill their own rows from one map at once. 0 or SF_ENOMEM. */
int map_raster_rows(const struct map *m, int y0, int y1, struct map_rows *rw);
void map_rows_free(struct map_rows *rw);
void map_free(struct map *m);

#endif
