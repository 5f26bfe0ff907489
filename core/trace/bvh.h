/* bvh.h - ray queries through Embree 3: an exact hierarchy over flat sub-patches (Embree user
 * geometry, Newton–Cramer in each leaf, as Martin et al. 2000) and a triangle hierarchy over a
 * tessellation (the `mesh` reference). Queries are thread-safe on a committed bvh.
 * Embree's own build threads are the library's; core starts none. */
#ifndef SURFD_BVH_H
#define SURFD_BVH_H

#include <stdbool.h>
#include <stddef.h>

#include "../geom/bezier.h"
#include "../geom/trimesh.h"
#include "../base/err.h"
#include "solve.h"

struct bvh_device; /* one Embree device; caller frees with bvh_device_free() */
struct bvh;        /* caller frees with bvh_free(); borrows its patches until then */

struct bvh_device *bvh_device_new(int n_threads, struct sf_err *err);
void bvh_device_free(struct bvh_device *dev);

struct bvh_hit {
    int patch;       /* index into the patch array */
    double u, v, t;  /* patch parameters and distance */
    bool has_normal; /* the root finder's (or, for the mesh, the interpolated) normal is set */
    vec3 normal;
};

/* Exact hierarchy over the patches, split until flat (LEAF_FLAT_REL in bvh.c). tol2: the
 * squared root residual accepted, in world units. */
int bvh_build_patches(struct bvh_device *dev, const struct patch *patches, size_t n, double tol2,
                      struct bvh **out, struct sf_err *err);
/* The same with triangle meshes beside the patches (isosurface models; the array and the meshes
 * borrowed until bvh_free), and fine: a leaf flat by LEAF_FLAT_REL whose net still deviates by
 * more than this (world units; INFINITY: never) splits on to LEAF_FINE_REL - a renderer passes
 * about half a pixel of the scene's size, so that large leaves get near seeds and tight bounds and
 * a small picture's preparation stays short:
 * a hit on mesh k has patch BVH_MESH_HIT(k), its u, v the triangle's barycentric coordinates and
 * its normal the mesh's normals interpolated (the face's when it has none). */
#define BVH_MESH_HIT(k) (-2 - (k))
#define BVH_HIT_MESH(patch) (-2 - (patch))
int bvh_build_scene(struct bvh_device *dev, const struct patch *patches, size_t n, double tol2, double fine,
                    const struct trimesh *const *meshes, int n_meshes, struct bvh **out, struct sf_err *err);
/* Triangle hierarchy over a tessellation at chord tolerance chord_tol. */
int bvh_build_mesh(struct bvh_device *dev, const struct patch *patches, size_t n, double chord_tol,
                   struct bvh **out, struct sf_err *err);
void bvh_free(struct bvh *b);

size_t bvh_n_leaves(const struct bvh *b);
/* About the bytes b takes (its leaves, seams and triangles, and Embree's nodes over them); 0 for NULL. */
size_t bvh_bytes(const struct bvh *b, size_t n_patches);

/* Nearest hit with t in (tnear, tfar). *iters accumulates solver iterations. */
bool bvh_intersect(const struct bvh *b, const struct dray *r, double tnear, double tfar, struct bvh_hit *hit,
                   long *iters);
/* The same among the given patches only (n of them; the mesh ignores the list). */
bool bvh_intersect_among(const struct bvh *b, const struct dray *r, double tnear, double tfar, const int *patches,
                         int n, struct bvh_hit *hit, long *iters);
/* The patch that shares edge `edge` of `patch` whole (0: u = 0, 1: u = 1, 2: v = 0, 3: v = 1),
 * continuing its parameter (edge 1 of one is edge 0 of the other, or 3 is 2), or -1. */
int bvh_seam(const struct bvh *b, int patch, int edge);
/* True when a line along d meets patches pa and pb (pa == pb: the one patch) together in one
 * point at most: d is steeper than every chord of the surface they make (the patch's own
 * control net's differences bound its chords; two patches count together where they share a
 * whole edge, one's u or v parameter going on into the other's). False where no such bound
 * is known. */
bool bvh_meets_once(const struct bvh *b, int pa, int pb, vec3 d);

/* Where a shadow ray leaves the surface: its own point needs no root search. */
struct bvh_origin {
    int patch;
    double u, v;   /* patch parameters */
};

/* Any hit with t in (tnear, tfar). from (may be NULL) names the surface point the ray leaves. */
bool bvh_occluded(const struct bvh *b, const struct dray *r, const struct bvh_origin *from, double tnear, double tfar,
                  long *iters);

/* A shadow request: as bvh_occluded's arguments (from.patch -1: none), and its answer. */
struct bvh_shadow {
    struct dray r;
    struct bvh_origin from;
    double tnear, tfar;
    bool blocked;
};
/* bvh_occluded for n rays at once (a chunk of a row's pixels: one call into Embree a batch). */
void bvh_occluded_many(const struct bvh *b, struct bvh_shadow *rays, size_t n, long *iters);

#endif
