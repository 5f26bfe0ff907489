/* adapt_internal.h - what the files of the adaptive hierarchy share (adapt.c, adapt_hierarchy.c,
 * adapt_polygon.c, adapt_feature.c, adapt_mesh.c): its state, a slab's piece of the mesh, a cell
 * being drawn, and the functions one file calls in another. Private to those files; the rest of
 * surfd sees adapt.h. Calls go one way: adapt.c -> hierarchy -> polygon -> feature -> mesh. */
#ifndef SURFD_ADAPT_INTERNAL_H
#define SURFD_ADAPT_INTERNAL_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../base/vec.h"
#include "adapt.h"

/* One slab's share of the mesh (the cells phase runs slab by slab, on any threads): vertices keyed
 * by the finest edge they lie on, merged across slabs at the end. */
struct piece {
    uint64_t *keys;
    uint32_t *slot;
    size_t cap, used;
    uint64_t *vkey;                    /* each vertex's key (UINT64_MAX: a fan's centre) */
    struct trimesh m;
    size_t vcap, tcap, kcap;
    uint32_t *owner;                   /* each triangle's level-2 block (the cell <-> triangle map) */
    size_t ocap;
    uint32_t block;                    /* the block whose cells are being drawn */
    atomic_size_t *tri_total;          /* the slabs' triangles together, by TRI_CHUNK (NULL: uncounted) */
    size_t tri_limit;                  /* ... the opts' max_triangles */
    bool over;                         /* stopped at tri_limit (with nomem) */
    bool nomem;
    long cells[ISO_MAX_LEVELS + 1];
    long feature_points;
};

#define HIDES 2 /* in mixed[2]: a fine edge of the block carries crossings its samples do not show */
#define ADAPT_SLABS 16 /* fixed, so that the mesh does not depend on the number of threads */

struct iso_adapt {
    int N[3], shift;
    float iso;
    double org[3], sp[3], max_err;
    int L, n_slabs;
    bool sharp;
    double (*field)(const void *ctx, const double p[3], double g[3]);
    const void *field_ctx;
    const char *tri_limit_by;          /* the opts' max_triangles_by */
    struct iso_grid g;                 /* the samples, copied into F by the first phase */
    float pad;
    float *F;                          /* the virtual grid, x fastest */
    int nb[ISO_MAX_LEVELS + 1][3];     /* blocks per axis at each level */
    uint8_t *M[ISO_MAX_LEVELS + 1];    /* [l][block]: covered by a cell of level >= l (l >= 2) */
    uint8_t *lev2;                     /* each level-2 block's cell level (1: cut into level-1 cells) */
    uint8_t *mixed[ISO_MAX_LEVELS + 1]; /* [l][block]: its samples are on both sides of iso (l >= 2;
                                         * level 2: or the grid's end cuts it, or HIDES) */
    double slab_max[ADAPT_SLABS];      /* the largest error a merge accepted, by slab */
    float slab_min[ADAPT_SLABS];       /* the least sample, by slab (the first phase's) */
    struct piece pieces[ADAPT_SLABS];
    atomic_size_t tri_total;           /* the pieces' triangles, counted as they grow */
    /* opts keep: what local rebuilds need (iso_adapt_keep, iso_adapt_edit) */
    double *berr[ISO_MAX_LEVELS + 1];  /* [l][block]: the error its merge accepted */
    uint8_t *bcells, *bfeat;           /* [level-2 block]: the cells it drew, their feature points */
    bool kept;
    struct piece all;                  /* the mesh, its vertices keyed as the pieces' */
    uint32_t *ids;                     /* each kept triangle's id (kept.h), beside all's owner */
    size_t idcap;
    uint32_t next_id;
    uint32_t *refs;                    /* each vertex's triangles */
    size_t rcap, dead;                 /* dead: vertices no triangle uses */
    long cells[ISO_MAX_LEVELS + 1], feature_points;
    double gmin, iso1;                 /* the samples' smallest and iso - 1: the pad is the lower */
    size_t n_min;                      /* samples at gmin */
    struct pieces *pz;                 /* opts pieces (adapt_pieces.c): the rest above is unused */
};

static inline size_t at3(const struct iso_adapt *a, int x, int y, int z) { return (size_t)x + (size_t)a->N[0] * ((size_t)y + (size_t)a->N[1] * z); }
static inline float F(const struct iso_adapt *a, int x, int y, int z) { return a->F[at3(a, x, y, z)]; }

static inline size_t block(const struct iso_adapt *a, int l, int bx, int by, int bz)
{
    return (size_t)bx + (size_t)a->nb[l][0] * ((size_t)by + (size_t)a->nb[l][1] * bz);
}

static inline float Fp(const struct iso_adapt *a, const int p[3]) { return F(a, p[0], p[1], p[2]); }

#define MAX_EAR 8 /* vertices of an ear: a chord's two ends and the crossings between them */

/* A crossing's fraction t of its finest edge, kept ISO_EDGE_MARGIN off the edge's ends. */
static inline double edge_fraction(double t)
{
    return t < ISO_EDGE_MARGIN ? ISO_EDGE_MARGIN : t > 1 - ISO_EDGE_MARGIN ? 1 - ISO_EDGE_MARGIN : t;
}

/* The place of a sample crossing at fraction t of the finest edge from node n along axis, as
 * place_vertex puts it. */
static inline void crossing_at(const struct iso_adapt *a, const int n[3], int axis, double t, double x[3])
{
    t = edge_fraction(t);
    for (int d = 0; d < 3; d++)
        x[d] = a->org[d] + a->sp[d] * (n[d] + (d == axis ? t : 0));
}

/* crossings: known_vertex's answer for a key it has not seen, and a hidden pair's keys (adapt_mesh.c) */
#define UNKNOWN (-2)
#define HIDDEN_KEY(k) (1ull << (60 + (k))) /* the first (k = 0, nearer node n) and second crossing */

#define MAX_SEGS 96

struct cell {
    const struct iso_adapt *a;
    bool hides;              /* a level-1 cell in a block with hidden crossings (HIDES) */
    struct piece *pc;        /* where its triangles go */
    int o[3], s;
    int n;                   /* segments */
    long from[MAX_SEGS], to[MAX_SEGS];
    int faces[MAX_SEGS];     /* of from[]: the cell faces its edge lies on (bits) */
};

/* feature points (adapt_feature.c) */
#define FACE_POINT (1 << 6) /* in a segment's faces: its start is a face point */
#define ON_FACE (1 << 7)    /* its start is an isoline point of a face (isoline_point) */
#define FACE_KEY (1ull << 62)

/* ---- one file's functions that another calls (their comments at their definitions) ---- */

/* adapt_hierarchy.c */
bool samples_mixed(const struct iso_adapt *a, const int b[3]);
double mask_block(struct iso_adapt *a, int l, const int b[3], bool split);
void mask_slab(struct iso_adapt *a, int l, int z0, int z1, int slab);
void cell_level(struct iso_adapt *a, const int b[3]);
void cell_levels(struct iso_adapt *a);

/* adapt_polygon.c */
int fan_apex(const int *faces, const uint64_t *keys, int n);
bool inner_crossing(const struct iso_adapt *a, const int o[3], int s, double x[3], int n[3], int *axis);
double simple_area(const double (*p)[2], int n);
int face_inside_joined(const struct iso_adapt *a, int axis, const int sq[3], int s);
void block_cells(const struct iso_adapt *a, struct piece *pc, const int b[3]);

/* adapt_feature.c */
void add_face_seg(struct cell *c, int f, const int sq[3], int h, int j, long from, int from_faces, long to);
bool feature_point(const struct iso_adapt *a, const struct cell *c, const long *loop, const int *faces, int n,
                   double x[3], double nrm[3]);

/* adapt_pieces.c (opts pieces: iso_adapt's functions hand over to these) */
struct pieces;
struct iso_change;
int pieces_begin(const struct iso_grid *g, const struct iso_opts *o, int levels, double max_error, struct pieces **out,
                 struct sf_err *err);
void pieces_free(struct pieces *P);
int pieces_phases(const struct pieces *P);
int pieces_n_slabs(const struct pieces *P);
void pieces_run(struct pieces *P, int phase, int slab);
void pieces_between(struct pieces *P, int phase);
int pieces_end(struct pieces *P, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err);
int pieces_keep(struct pieces *P, struct iso_adapt_stats *st, struct sf_err *err);
int pieces_mesh(const struct pieces *P, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err);
int pieces_edit(struct pieces *P, const int lo[3], const struct iso_grid *blk, struct iso_edit *ed,
                struct iso_change *ch, struct sf_err *err);
int pieces_ids(const struct pieces *P, uint32_t **ids, struct sf_err *err);
void pieces_number_from(struct pieces *P, uint32_t first);
uint32_t pieces_next_id(const struct pieces *P);
int pieces_samples(const struct pieces *P, float **out, struct sf_err *err);
size_t pieces_bytes(const struct pieces *P);

/* adapt_mesh.c */
uint64_t edge_key(const struct iso_adapt *a, const int n[3], int axis);
bool first_change(const struct iso_adapt *a, int n[3], int axis, int len, float *v0, float *v1);
void set_vertex(struct piece *pc, size_t v, const double pos[3], const double nrm[3]);
long new_vertex(struct piece *pc, const double pos[3], const double nrm[3], uint64_t key);
bool slot_of(struct piece *pc, uint64_t key, bool *found, size_t *h_out);
void keep_slot(struct piece *pc, size_t h, uint64_t key, long v);
long known_vertex(struct piece *pc, uint64_t key, size_t *slot);
long keyed_vertex(struct piece *pc, uint64_t key, size_t slot, const double pos[3], const double nrm[3]);
long edge_vertex(const struct iso_adapt *a, struct piece *pc, const int n[3], int axis, float v0, float v1);
bool hidden_pair(const struct iso_adapt *a, const int n[3], int axis, double t[2]);
long hidden_vertex(const struct iso_adapt *a, struct piece *pc, const int n[3], int axis, int k, double t);
bool hides_crossings(const struct iso_adapt *a, const int o[3], int s);
void add_triangle(struct piece *pc, long p, long q, long r);
int cell_edge_faces(const struct cell *c, const int lo[3], int axis);
long crossing(const struct iso_adapt *a, const struct cell *c, const int p[3], const int q[3], int *faces);
void add_seg(struct cell *c, long from, int from_faces, long to);

#endif
