/* mc.h - isosurfaces of sampled volumes (seed 002's base method, METHODS.md §4): marching cubes
 * over an indexed mesh, each edge crossing computed once and shared by the four cells round it.
 *
 * Inside is value > iso (a sample equal to iso is outside: ties are decided one way everywhere).
 * A cell's polygons come from its faces: on each face the isoline segments join the face's edge
 * crossings, an ambiguous face (two diagonal corners in, two out) joined by the asymptotic decider
 * of the bilinear interpolant, computed from the face's four samples in one global order so that
 * the two cells sharing the face agree. The segments of the six faces chain into closed loops,
 * oriented counter-clockwise seen from outside; each loop is fanned into triangles. So every
 * triangle edge on a cell face is shared, the other way round, by the neighbour's triangle:
 * with closed=true (the grid's border counts as outside) the mesh is a closed, consistently
 * oriented 2-manifold on any input. Where a cell has two loops whose sides could meet inside
 * it (MC33's interior ambiguity), the trilinear interpolant is sampled across the cell and, when
 * they meet, the loops are joined by a tube. A fan whose diagonal would join two crossings of one face (the
 * neighbour's fan might draw the same edge) starts from another vertex of the loop, or, when
 * every vertex has such a diagonal, from a vertex added at the loop's centre. The cells' tables
 * (256 corner states x the decisions of their ambiguous faces) are built by these rules at
 * start (iso_init), not typed in.
 * Vertices sit where the edge's linear interpolant crosses iso, kept ISO_EDGE_MARGIN of the edge
 * from its ends, so that a sample equal to iso never collapses triangles to zero area.
 *
 * Cells are addressed by integer coordinates and done in slabs of z: a caller runs iso_count and
 * then iso_emit on any slabs in any order, on as many threads as it likes (each slab writes only
 * its own rows); the mesh is the same whatever the order or the number of threads. */
#ifndef SURFD_MC_H
#define SURFD_MC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../base/err.h"
#include "../geom/trimesh.h"

#define ISO_EDGE_MARGIN 1e-3 /* of an edge: the nearest a vertex comes to a sample */
#define ISO_MAX_VERTICES 2000000000u

enum iso_type { ISO_U8, ISO_I16, ISO_U16, ISO_F32 };

/* Samples x fastest, then y, then z, in the host's byte order. */
struct iso_grid {
    int nx, ny, nz;
    enum iso_type type;
    const void *samples;
    double spacing[3], origin[3];
};

struct iso_opts {
    double iso;
    bool closed;             /* the border counts as outside: pads the grid with one layer below iso */
    bool normals;            /* vertex normals from the field's gradient (central differences) */
    bool sharp;              /* seed 002's feature points (adapt.h; iso_begin refuses it) */
    /* The field as a function of position, when there is one (an FRep object's): its value at p
     * (the samples' quantity) and its gradient into g. adapt.c puts the crossings on it and takes
     * their normals from its gradient; NULL for sampled volumes. */
    double (*field)(const void *ctx, const double p[3], double g[3]);
    const void *field_ctx;
    bool keep;               /* adapt.c keeps what local rebuilds need (iso_adapt_keep) */
    size_t max_triangles;    /* 0: none; a surface of more is SF_ELIMIT, found before its mesh is allocated
                              * (iso_layout) or while its pieces grow (adapt.c), never after */
    const char *max_triangles_by; /* what sets it, for the message ("this node's max-triangles") */
    bool pieces;             /* adapt.c, levels over 1: a vertex per piece of surface in a merged cell
                              * (adapt_pieces.c; not with sharp); mc.c ignores it */
};

struct iso_job;

/* Builds the cells' tables; call once, before any thread extracts (the daemon at start). */
void iso_init(void);

/* Prepares an extraction in n_slabs slabs (fewer when the grid is thinner). 0, or SF_EINVAL
 * (a grid under 2 samples on an axis, NaN iso), SF_ENOMEM. */
int iso_begin(const struct iso_grid *g, const struct iso_opts *o, int n_slabs, struct iso_job **out,
              struct sf_err *err);
int iso_n_slabs(const struct iso_job *j);
/* Pass 1: counts slab s's vertices and triangles. */
void iso_count(struct iso_job *j, int s);
/* Between the passes, on one thread: places every row's output. 0, or SF_ELIMIT (over
 * ISO_MAX_VERTICES or the options' max_triangles: nothing of the mesh allocated), SF_ENOMEM. */
int iso_layout(struct iso_job *j, struct sf_err *err);
/* Pass 2: writes slab s's vertices and triangles. */
void iso_emit(struct iso_job *j, int s);
/* Hands the mesh over (positions in the grid's units) and frees the job: 0, or SF_ENOMEM (a
 * slab's pass found no memory; nothing is handed over). */
int iso_end(struct iso_job *j, struct trimesh *out, struct sf_err *err);
void iso_free(struct iso_job *j);

/* The smallest sample; row (y, z) of the samples as floats into out[0 .. nx-1] (for the other
 * extractions of core/iso). */
double iso_grid_min(const struct iso_grid *g);
void iso_grid_row(const struct iso_grid *g, int y, int z, float *out);

/* All of it on the calling thread, polling pr between slabs (SF_ECANCEL when it says stop). */
int iso_extract(const struct iso_grid *g, const struct iso_opts *o, const struct sf_progress *pr, struct trimesh *out,
                struct sf_err *err);

/* ---- boxes of cells (kept.c: local rebuilds and iso changes of seed 002's interactive loop) ----
 *
 * The cells lo .. hi (inclusive, in the virtual grid's cells: with closed, cell (0, 0, 0) is the
 * pad's corner) drawn in one pass by the very code of the slabs' extraction (the same cases,
 * positions and normals, bit for bit), in its order: cell by cell, x fastest then y then z, each
 * cell's triangles in its case's order. So the whole grid as a box is iso_extract's list of
 * triangles (its vertices numbered otherwise). Each vertex has a key that names its place (below),
 * each triangle its cell. */
struct iso_box {
    float *pos, *nrm;        /* 3 per vertex; nrm with o->normals */
    uint64_t *key;           /* per vertex: iso_vertex_key */
    size_t n_vert, cap_vert;
    uint32_t *tri;           /* 3 per triangle, into the box's vertices */
    uint32_t *cell;          /* per triangle: its virtual cell, I + (NX-1) (J + (NY-1) K) */
    size_t n_tri, cap_tri;
    size_t n_cells;          /* the cells drawn (with a crossing) */
    void *scratch;           /* kept between calls (iso_box_free frees it all) */
    size_t scratch_bytes;
};
/* A vertex's key: ((K * 4 + kind) * NY + J) * NX + I) * 4 + c over the virtual grid (NX, NY),
 * kind 0, 1, 2 the edge from sample (I, J, K) along x, y, z (c = 0), kind 3 the c-th centre of cell
 * (I, J, K). Keys sort as iso_extract numbers its vertices. */
static inline uint64_t iso_vertex_key(int NX, int NY, int I, int J, int K, int kind, int c)
{
    return ((((uint64_t)K * 4 + (uint64_t)kind) * (uint64_t)NY + (uint64_t)J) * (uint64_t)NX + (uint64_t)I) * 4 +
           (uint64_t)c;
}
/* Draws cells lo .. hi of g at o (pad: the closed grid's pad sample, as iso_begin sets it) into
 * out (its lists emptied first; out zeroed before the first call). 0, or SF_EBACKEND (iso_init not
 * called), SF_ENOMEM (out's lists then half made), SF_ELIMIT (over ISO_MAX_VERTICES). */
int iso_box_extract(const struct iso_grid *g, const struct iso_opts *o, float pad, const int lo[3], const int hi[3],
                    struct iso_box *out, struct sf_err *err);
/* The whole grid drawn into out (its lists emptied first) by the slabs' two passes on the calling
 * thread: iso_extract's mesh, vertices and triangles in its order, with their keys and cells. Where
 * a new iso redraws every cell that straddles it, this is the faster way: the slabs' walk passes
 * over 64 cells of one state at a time and shares each vertex by its place in a row, where a box
 * finds its vertices again through slots. 0, or SF_EBACKEND, SF_ENOMEM, SF_ELIMIT. */
int iso_box_whole(const struct iso_grid *g, const struct iso_opts *o, struct iso_box *out, struct sf_err *err);
/* Room in out's vertex lists for verts vertices, their memory touched (so that a later pass
 * neither grows them cell by cell nor faults their pages in). 0, or -1: no memory. */
int iso_box_reserve(struct iso_box *out, size_t verts, bool normals);
/* The bytes out holds. */
size_t iso_box_bytes(const struct iso_box *out);
void iso_box_free(struct iso_box *out);

#endif
