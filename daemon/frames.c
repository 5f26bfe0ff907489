/* frames.c - prepared hierarchies of stored models between renders (frames.h). A list under the
 * cache's own lock: a few dozen models at most fit any sensible budget. */
#include "frames.h"

#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/base/clock.h"
#include "metrics.h"

struct frames {
    pthread_mutex_t lock;    /* guards the list and every entry's refs and used */
    size_t budget;
    struct frame_entry *list;
};

struct frames *frames_open(size_t budget)
{
    struct frames *fc = calloc(1, sizeof *fc);
    if (!fc)
        return NULL;
    pthread_mutex_init(&fc->lock, NULL);
    fc->budget = budget;
    return fc;
}

static void entry_free(struct frame_entry *e)
{
    frame_free(e->base);
    scene_free(&e->sc);
    free(e);
}

/* Drops idle entries, least recently used first, while the kept ones are over budget (lock held). */
static void evict(struct frames *fc)
{
    for (;;) {
        size_t total = 0;
        struct frame_entry **oldest = NULL;
        for (struct frame_entry **p = &fc->list; *p; p = &(*p)->next) {
            total += (*p)->bytes;
            if ((*p)->refs == 0 && (!oldest || (*p)->used < (*oldest)->used))
                oldest = p;
        }
        if (total <= fc->budget || !oldest)
            return;
        struct frame_entry *e = *oldest;
        *oldest = e->next;
        entry_free(e);
    }
}

struct frame_entry *frames_take(struct frames *fc, const char *key,
                                int (*build)(void *ctx, struct scene *sc, struct frame **base, struct sf_err *err),
                                void *ctx, struct sf_err *err)
{
    pthread_mutex_lock(&fc->lock);
    for (struct frame_entry *e = fc->list; e; e = e->next)
        if (!strcmp(e->key, key)) {
            e->refs++;
            e->used = sf_now_ms();
            pthread_mutex_unlock(&fc->lock);
            metrics_frame_cache(true);
            return e;
        }
    pthread_mutex_unlock(&fc->lock);
    metrics_frame_cache(false);
    struct frame_entry *e = calloc(1, sizeof *e); /* built outside the lock: it takes a while */
    if (!e)
        return sf_fail(err, SF_ENOMEM, "", "out of memory"), NULL;
    snprintf(e->key, sizeof e->key, "%s", key);
    if (build(ctx, &e->sc, &e->base, err)) {
        scene_free(&e->sc);
        free(e);
        return NULL;
    }
    e->bytes = frame_hierarchy_bytes(e->base);
    e->refs = 1;
    e->used = sf_now_ms();
    pthread_mutex_lock(&fc->lock);
    for (struct frame_entry *o = fc->list; o; o = o->next)
        if (!strcmp(o->key, key)) { /* another job built it meanwhile: that one is kept */
            o->refs++;
            pthread_mutex_unlock(&fc->lock);
            entry_free(e);
            return o;
        }
    if (fc->budget > 0 && e->bytes <= fc->budget) {
        e->next = fc->list;
        fc->list = e;
        evict(fc);
    } else {
        e->refs = -1; /* not kept: freed when given back */
    }
    pthread_mutex_unlock(&fc->lock);
    return e;
}

bool frames_counts(struct frames *fc, const char *key, int *n_objects, int *n_meshes)
{
    pthread_mutex_lock(&fc->lock);
    struct frame_entry *e = fc->list;
    while (e && strcmp(e->key, key))
        e = e->next;
    if (e)
        *n_objects = e->sc.n_objects, *n_meshes = e->sc.n_meshes;
    pthread_mutex_unlock(&fc->lock);
    return e != NULL;
}

void frames_give(struct frames *fc, struct frame_entry *e)
{
    if (!e)
        return;
    if (e->refs < 0) {
        entry_free(e);
        return;
    }
    pthread_mutex_lock(&fc->lock);
    e->refs--;
    evict(fc);
    pthread_mutex_unlock(&fc->lock);
}

size_t frames_bytes(struct frames *fc)
{
    size_t total = 0;
    pthread_mutex_lock(&fc->lock);
    for (struct frame_entry *e = fc->list; e; e = e->next)
        total += e->bytes;
    pthread_mutex_unlock(&fc->lock);
    return total;
}

void frames_close(struct frames *fc)
{
    if (!fc)
        return;
    while (fc->list) {
        struct frame_entry *e = fc->list;
        fc->list = e->next;
        entry_free(e);
    }
    pthread_mutex_destroy(&fc->lock);
    free(fc);
}
