/* service.c - small helpers every part of the daemon uses. */
#include "service.h"

#include <stdlib.h>

#include "../api/problem.h"
#include "log.h"
#include "metrics.h"

#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <sys/random.h>
#include <time.h>

double wall_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return ts.tv_sec + ts.tv_nsec / 1e9;
}

void service_new_id(char out[40])
{
    unsigned char b[16] = {0};
    if (getrandom(b, sizeof b, 0) != (ssize_t)sizeof b) { /* never on Linux >= 3.17; still unique enough */
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        for (size_t k = 0; k < sizeof b; k++)
            b[k] ^= (unsigned char)((ts.tv_nsec >> (k % 4 * 8)) + k * 131);
    }
    for (size_t k = 0; k < sizeof b; k++)
        snprintf(out + 2 * k, 3, "%02x", b[k]);
}

/* The job kinds: what a stored job's kind name runs as. */
static const struct {
    const char *name;
    int (*submit)(struct service *, const char *, bool);
} KINDS[] = {
    {"render", render_job_submit}, {"volume", volume_job_submit},   {"model", model_job_submit},
    {"mesh", mesh_job_submit},     {"patches", patches_job_submit},
};

int service_submit_kind(struct service *svc, const char *kind, const char *id, bool force)
{
    for (size_t k = 0; k < sizeof KINDS / sizeof *KINDS; k++)
        if (!strcmp(KINDS[k].name, kind))
            return KINDS[k].submit(svc, id, force);
    return -1;
}

#define STORE_TRIES 3          /* writes of a job's end before it is stranded */
#define STRANDED_FIRST_S 5.0   /* a stranded job's first delay; doubled each time, up to: */
#define STRANDED_LAST_S 300.0

/* The stranded entry of id, or NULL. Lock held. */
static struct stranded *stranded_find(struct service *svc, const char *id)
{
    for (int k = 0; k < svc->n_stranded; k++)
        if (!strcmp(svc->stranded[k].id, id))
            return &svc->stranded[k];
    return NULL;
}

/* Keeps job id for a later run (or counts one more try of a job kept already). */
static void strand(struct service *svc, const char *id)
{
    struct job_rec rec;
    int found = store_get(svc->store, id, false, false, &rec);
    store_requeue(svc->store, id); /* may fail as the end did; the list below is what counts */
    metrics_store_error();
    pthread_mutex_lock(&svc->stranded_lock);
    struct stranded *s = stranded_find(svc, id);
    if (!s && found == 1 && svc->n_stranded < STRANDED_MAX) {
        s = &svc->stranded[svc->n_stranded++];
        *s = (struct stranded){.tries = 0};
        snprintf(s->id, sizeof s->id, "%s", id);
        snprintf(s->kind, sizeof s->kind, "%s", rec.kind);
    }
    if (s) {
        s->tries++;
        double delay = STRANDED_FIRST_S * (double)(1 << (s->tries < 7 ? s->tries - 1 : 6));
        delay = delay < STRANDED_LAST_S ? delay : STRANDED_LAST_S;
        s->retry_at = monotonic_s() + delay;
        LOG(LOG_ERROR, "job %s: the store will not take its end (%d); run again in %.0f s", id, s->tries, delay);
    } else {
        LOG(LOG_ERROR, "job %s: the store will not take its end, and it cannot be kept for a retry; it runs again at "
                       "the next start", id);
    }
    pthread_mutex_unlock(&svc->stranded_lock);
    store_rec_free(&rec);
}

/* Writes a job's end, trying a few times a moment apart (a full disk may clear as pruning or a
 * checkpoint frees pages). 0 or -1. */
static int store_end(struct service *svc, const char *id, enum job_state outcome, const unsigned char *result,
                     size_t len, const char *type, const char *meta, const char *problem)
{
    int rc = -1;
    for (int k = 0; k < STORE_TRIES && rc; k++) {
        if (k) {
            struct timespec ts = {0, 200 * 1000000L};
            nanosleep(&ts, NULL);
        }
        rc = outcome == JOB_SUCCEEDED ? store_set_result(svc->store, id, result, len, type, meta, wall_s())
             : outcome == JOB_FAILED  ? store_set_state(svc->store, id, "failed", 0.0, 0, wall_s(), problem)
                                      : store_set_state(svc->store, id, "cancelled", 0.0, 0, wall_s(), NULL);
    }
    return rc;
}

void service_job_end(struct service *svc, const char *id, enum job_state outcome, bool requeue,
                     const unsigned char *result, size_t len, const char *type, const char *meta,
                     const struct sf_err *err)
{
    if (requeue) { /* shutdown: leave it to the next start */
        store_requeue(svc->store, id);
        return;
    }
    char *p = outcome == JOB_FAILED ? problem_from_err(err) : NULL;
    if (outcome == JOB_FAILED)
        LOG(LOG_WARN, "job %s failed: %s", id, err->message);
    if (store_end(svc, id, outcome, result, len, type, meta, p)) {
        strand(svc, id);
    } else {
        metrics_job_end(outcome);
        pthread_mutex_lock(&svc->stranded_lock);
        struct stranded *s = stranded_find(svc, id);
        if (s) {
            LOG(LOG_INFO, "job %s: the store took its end after %d refusals", id, s->tries);
            *s = svc->stranded[--svc->n_stranded];
        }
        pthread_mutex_unlock(&svc->stranded_lock);
    }
    free(p);
}

void service_retry_stranded(struct service *svc)
{
    double now = monotonic_s();
    pthread_mutex_lock(&svc->stranded_lock);
    for (int k = 0; k < svc->n_stranded; k++) {
        struct stranded *s = &svc->stranded[k];
        if (s->retry_at > now)
            continue;
        s->retry_at = INFINITY; /* running: its end sets the next */
        char id[40], kind[16];
        snprintf(id, sizeof id, "%s", s->id);
        snprintf(kind, sizeof kind, "%s", s->kind);
        pthread_mutex_unlock(&svc->stranded_lock);
        bool queued = service_submit_kind(svc, kind, id, true) == 0;
        LOG(queued ? LOG_INFO : LOG_WARN, "job %s: run again after the store refused its end%s", id,
            queued ? "" : ": could not queue it");
        pthread_mutex_lock(&svc->stranded_lock);
        if (!queued && (s = stranded_find(svc, id)))
            s->retry_at = now + STRANDED_FIRST_S;
    }
    pthread_mutex_unlock(&svc->stranded_lock);
}

int service_n_stranded(struct service *svc)
{
    pthread_mutex_lock(&svc->stranded_lock);
    int n = svc->n_stranded;
    pthread_mutex_unlock(&svc->stranded_lock);
    return n;
}

static int model_source(void *ctx, const char *id, char **src, size_t *len)
{
    const struct model_scope *ms = ctx;
    return store_model_get(ms->svc->store, id, ms->owner, NULL, src, len);
}

struct model_resolver service_models(struct model_scope *scope)
{
    return (struct model_resolver){model_source, scope};
}
