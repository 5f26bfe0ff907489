/* render.h - a prepared frame and the rendering of its scanline bands.
 *
 *   frame_prepare()  extract patches, place the camera, build what the method needs (hierarchy,
 *                    mesh, preliminary-value map); shared, read-only, by every band
 *   frame_band()     trace and shade rows [y0, y1); bands never overlap, so any number of
 *                    threads may render different bands of one frame at once
 *   frame_free()
 *
 * The frame borrows the scene until frame_free(). core/ starts no threads: the caller decides
 * who renders which band (the CLI's threads, the daemon's pool). */
#ifndef SURFD_RENDER_H
#define SURFD_RENDER_H

#include <stddef.h>

#include "bvh.h"
#include "../base/err.h"
#include "scene.h"

struct frame;

struct render_stats {
    long rays;          /* primary + shadow rays */
    long primary;       /* primary rays */
    long hits;          /* primary rays that hit */
    long refinements;   /* root searches for primary rays (map seeds, Monte-Carlo patches) */
    long iterations;    /* solver iterations for primary rays */
    long shadow;        /* shadow rays */
    long shadow_iterations; /* solver iterations for shadow rays */
    long misses;        /* pixels where map refinement failed and the fallback ran */
    long fallback_hits; /* ... of which the fallback found a surface */
};

/* What a finished frame holds, borrowed until frame_free(). rgba is linear, premultiplied
 * by nothing (A = 1 on hits, 0 elsewhere); depth is the distance along the ray (INFINITY on
 * a miss); normal/uv/id are NULL unless asked for by scene.aovs. */
struct frame_image {
    int width, height;
    const float *rgba;    /* 4 per pixel (NULL with srgb8_only) */
    const float *depth;   /* 1 per pixel (NULL with srgb8_only) */
    const float *normal;  /* 3 per pixel */
    const float *uv;      /* 2 per pixel: the object's own parameters */
    const float *id;      /* 1 per pixel: object index, -1 on a miss */
    const unsigned char *srgb8; /* 3 per pixel: rgb as 8-bit sRGB (srgb8_only), or NULL */
};

/* Returns 0 or an SF_E* code with err filled. dev is borrowed until frame_free(). */
int frame_prepare(const struct scene *sc, struct bvh_device *dev, struct frame **out, struct sf_err *err);
/* A frame of scene sc on base's patches and hierarchies (built by frame_prepare for the same
 * objects, tolerance and method; borrowed, read-only, until this frame is freed): only the view's
 * part is made - camera, lights, buffers, the map - so a second view of the same objects skips
 * the hierarchy (issue 17). SF_EINVAL when base was built for other objects or tolerances. */
int frame_prepare_from(const struct scene *sc, const struct frame *base, struct frame **out, struct sf_err *err);
/* Either preparation in parts, for a caller with threads: frame_begin() and frame_begin_from() do
 * all but the map's, which frame_part(fr, step, p) does for each step in [0, frame_steps(fr)), in
 * order, and each p in [0, frame_parts(fr)), the parts of a step on any threads at once;
 * frame_end() then finishes (0, or an SF_E* code: frame_free the frame). frame_prepare() is
 * frame_begin() and frame_finish(). */
int frame_begin(const struct scene *sc, struct bvh_device *dev, struct frame **out, struct sf_err *err);
int frame_begin_from(const struct scene *sc, const struct frame *base, struct frame **out, struct sf_err *err);
int frame_steps(const struct frame *fr);
int frame_parts(const struct frame *fr);
void frame_part(struct frame *fr, int step, int p);
int frame_end(struct frame *fr, struct sf_err *err);
/* Every part of every step left on this thread, then frame_end (a map too small to share out). */
int frame_finish(struct frame *fr, struct sf_err *err);
/* About the bytes a frame's patches and hierarchies take (a cache's budget). */
size_t frame_hierarchy_bytes(const struct frame *fr);
/* Renders rows [y0, y1), adding to *stats. */
void frame_band(struct frame *fr, int y0, int y1, struct render_stats *stats);
void frame_image(const struct frame *fr, struct frame_image *img);
/* Milliseconds the preparation took, and what it built (for --stats). */
double frame_prepare_ms(const struct frame *fr);
size_t frame_n_patches(const struct frame *fr);
/* The exact hierarchy over the frame's patches and meshes (NULL with the mesh method), and the
 * objects' bounds: rays other than the camera's (a model's matrices, core/matrix/rays.h). */
const struct bvh *frame_hierarchy(const struct frame *fr);
void frame_bounds(const struct frame *fr, double lo[3], double hi[3]);
void frame_free(struct frame *fr);

void render_stats_add(struct render_stats *into, const struct render_stats *s);

#endif
