/* frames.c - prepared hierarchies of stored models between renders (frames.h). A list under the
 * service's lock: a few dozen models at most fit any sensible budget. */
#include "frames.h"

#include "metrics.h"

#include <stdlib.h>
#include <string.h>

static void entry_free(struct frame_entry *e)
{
    frame_free(e->base);
    scene_free(&e->sc);
    free(e);
}

/* Drops idle entries, least recently used first, while the kept ones are over budget (lock held). */
static void evict(struct service *svc)
{
    for (;;) {
        size_t total = 0;
        struct frame_entry **oldest = NULL;
        for (struct frame_entry **p = &svc->frames; *p; p = &(*p)->next) {
            total += (*p)->bytes;
            if ((*p)->refs == 0 && (!oldest || (*p)->used < (*oldest)->used))
                oldest = p;
        }
        if (total <= (size_t)svc->cfg.frame_cache || !oldest)
            return;
        struct frame_entry *e = *oldest;
        *oldest = e->next;
        entry_free(e);
    }
}

struct frame_entry *frames_take(struct service *svc, const char *key,
                                int (*build)(void *ctx, struct scene *sc, struct frame **base, struct sf_err *err),
                                void *ctx, struct sf_err *err)
{
    pthread_mutex_lock(&svc->lock);
    for (struct frame_entry *e = svc->frames; e; e = e->next)
        if (!strcmp(e->key, key)) {
            e->refs++;
            e->used = monotonic_s();
            pthread_mutex_unlock(&svc->lock);
            metrics_frame_cache(true);
            return e;
        }
    pthread_mutex_unlock(&svc->lock);
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
    e->used = monotonic_s();
    pthread_mutex_lock(&svc->lock);
    for (struct frame_entry *o = svc->frames; o; o = o->next)
        if (!strcmp(o->key, key)) { /* another job built it meanwhile: that one is kept */
            o->refs++;
            pthread_mutex_unlock(&svc->lock);
            entry_free(e);
            return o;
        }
    if (svc->cfg.frame_cache > 0 && e->bytes <= (size_t)svc->cfg.frame_cache) {
        e->next = svc->frames;
        svc->frames = e;
        evict(svc);
    } else {
        e->refs = -1; /* not kept: freed when given back */
    }
    pthread_mutex_unlock(&svc->lock);
    return e;
}

bool frames_counts(struct service *svc, const char *key, int *n_objects, int *n_meshes)
{
    pthread_mutex_lock(&svc->lock);
    struct frame_entry *e = svc->frames;
    while (e && strcmp(e->key, key))
        e = e->next;
    if (e)
        *n_objects = e->sc.n_objects, *n_meshes = e->sc.n_meshes;
    pthread_mutex_unlock(&svc->lock);
    return e != NULL;
}

void frames_give(struct service *svc, struct frame_entry *e)
{
    if (!e)
        return;
    if (e->refs < 0) {
        entry_free(e);
        return;
    }
    pthread_mutex_lock(&svc->lock);
    e->refs--;
    evict(svc);
    pthread_mutex_unlock(&svc->lock);
}

size_t frames_bytes(struct service *svc)
{
    size_t total = 0;
    pthread_mutex_lock(&svc->lock);
    for (struct frame_entry *e = svc->frames; e; e = e->next)
        total += e->bytes;
    pthread_mutex_unlock(&svc->lock);
    return total;
}

void frames_free_all(struct service *svc)
{
    pthread_mutex_lock(&svc->lock);
    while (svc->frames) {
        struct frame_entry *e = svc->frames;
        svc->frames = e->next;
        entry_free(e);
    }
    pthread_mutex_unlock(&svc->lock);
}
