/* frames.h - prepared hierarchies of stored models, kept between their renders (issue 17: a repeat
 * view of a model prepares only what the camera changes). An entry holds a model's scene objects
 * (parsed from its source once) and a frame whose patches and hierarchy every later frame of that
 * model borrows (frame_prepare_from). Keyed by model, edit count and hierarchy kind; bounded by
 * frame-cache bytes, the least recently used idle entries dropped first. Thread-safe: the cache
 * has its own lock, held only to look up, link and unlink entries (never while one is built). */
#ifndef SURFD_FRAMES_H
#define SURFD_FRAMES_H

#include <stdbool.h>
#include <stddef.h>

#include "../core/trace/render.h"

struct frame_entry {
    char key[96];
    struct scene sc;         /* the model's objects (a frame's scene borrows them) */
    struct frame *base;      /* their patches and hierarchy */
    size_t bytes;
    long refs;               /* jobs using it */
    double used;             /* sf_now_ms of its last take */
    struct frame_entry *next;
};

/* A cache of at most budget bytes of hierarchies (0: none kept, every entry built for its job
 * alone); NULL when out of memory. */
struct frames *frames_open(size_t budget);
/* Frees the cache and every entry (at shutdown, no job running). */
void frames_close(struct frames *fc);

/* The entry of key, built by build(ctx, &sc, &base, err) when there is none (not kept when it
 * alone is over the budget: then it is the caller's to give back all the same). NULL with err
 * when the build fails. */
struct frame_entry *frames_take(struct frames *fc, const char *key,
                                int (*build)(void *ctx, struct scene *sc, struct frame **base, struct sf_err *err),
                                void *ctx, struct sf_err *err);
/* Whether the cache holds key; then its scene's object and mesh counts. */
bool frames_counts(struct frames *fc, const char *key, int *n_objects, int *n_meshes);
/* Gives an entry back (frames_take's); one no longer kept is freed with its last user. */
void frames_give(struct frames *fc, struct frame_entry *e);
/* The bytes of the hierarchies kept (frame_hierarchy_bytes of each), for /metrics. */
size_t frames_bytes(struct frames *fc);

#endif
