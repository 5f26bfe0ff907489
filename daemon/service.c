/* service.c - the claims this node holds, the end of jobs, and small helpers every part of the
 * daemon uses. See service.h for how a job travels. */
#include "service.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <time.h>

#include "../api/mesh_io.h"
#include "../api/model_json.h"
#include "../api/problem.h"
#include "../core/base/mem.h"
#include "log.h"
#include "metrics.h"

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

#define STORE_TRIES 3          /* writes of a job's end before it is stranded */

/* ---- the claims this node holds ---- */

struct claim *claim_find(struct service *svc, const char *id, long fence)
{
    for (int k = 0; k < svc->n_claims; k++)
        if (!strcmp(svc->claims[k].c.id, id) && (fence < 0 || svc->claims[k].c.fence == fence))
            return &svc->claims[k];
    return NULL;
}

void claim_drop(struct service *svc, const struct job_claim *c)
{
    pthread_mutex_lock(&svc->lock);
    struct claim *h = claim_find(svc, c->id, c->fence);
    if (h)
        *h = svc->claims[--svc->n_claims];
    pthread_mutex_unlock(&svc->lock);
}

void service_wake(struct service *svc)
{
    pthread_mutex_lock(&svc->lock);
    svc->wake = true;
    pthread_cond_signal(&svc->wake_cond);
    pthread_mutex_unlock(&svc->lock);
}

char *service_give_up_problem(const struct service *svc)
{
    struct sf_err err = {0};
    sf_fail(&err, SF_EBACKEND, "", "this job stopped the service %ld times (a crash, or its node lost); it is not run again",
            svc->cfg.max_attempts);
    return problem_from_err(&err);
}

/* ---- a job's end ---- */

/* Keeps a claimed job for a later run (or counts one more try of a job kept already), saying why.
 * Its claim stays held, its lease renewed by the heartbeats. */
static void strand(struct service *svc, const struct job_claim *c, const char *why)
{
    metrics_store_error();
    pthread_mutex_lock(&svc->lock);
    struct claim *h = claim_find(svc, c->id, c->fence);
    if (h) {
        h->stranded = true;
        h->tries++;
        double delay = STRANDED_FIRST_S * (double)(1 << (h->tries < 7 ? h->tries - 1 : 6));
        delay = delay < STRANDED_LAST_S ? delay : STRANDED_LAST_S;
        h->retry_at = monotonic_s() + delay;
        LOG(LOG_ERROR, "job %s: %s (%d); run again in %.0f s", c->id, why, h->tries, delay);
    }
    pthread_mutex_unlock(&svc->lock);
}

/* Writes a job's end, trying a few times a moment apart (a full disk may clear as pruning or a
 * checkpoint frees pages): store_finish's answer, 0 written, SF_ECONFLICT the claim is lost,
 * SF_EIO the store refused. */
static int store_end(struct service *svc, const struct job_claim *c, const struct job_end *end)
{
    int rc = SF_EIO;
    for (int k = 0; k < STORE_TRIES && rc == SF_EIO; k++) {
        if (k) {
            struct timespec ts = {0, 200 * 1000000L};
            nanosleep(&ts, NULL);
        }
        rc = store_finish(svc->store, c->id, c->fence, end);
    }
    return rc;
}

int service_outgrown(struct sf_err *err)
{
    const struct mem_account *a = mem_account_current();
    long long refused = a ? atomic_load(&a->refused) : 0;
    /* what a refused allocation turns into: core's and the store's failures, never the input's own */
    if (!refused || (err->code != SF_ENOMEM && err->code != SF_EIO && err->code != SF_EBACKEND))
        return err->code;
    long long held = atomic_load(&a->held), mb = 1 << 20;
    held = held < 0 ? 0 : held; /* credited frees of what other accounts allocated */
    *err = (struct sf_err){0};
    return sf_fail(err, SF_ELIMIT, "", "the job needs more memory than this node gives one job (job-memory, %lld MB): "
                   "%lld MB more were refused with %lld MB in use", a->budget / mb, (refused + mb - 1) / mb, held / mb);
}

void service_job_end(struct service *svc, const struct job_claim *c, enum job_state outcome, bool requeue,
                     const unsigned char *result, size_t len, const char *type, const char *meta,
                     const struct sf_err *err)
{
    if (requeue) { /* a drain: leave it to a node that runs on */
        store_release(svc->store, c->id, c->fence);
        claim_drop(svc, c);
        return;
    }
    /* a result the store would not take for a full disk: the job waits for room and runs again */
    if (outcome == JOB_FAILED && err->code == SF_EIO && store_full(svc->store)) {
        strand(svc, c, "the disk is full: the store would not take its result");
        return;
    }
    struct sf_err outgrown = *err;
    if (outcome == JOB_FAILED && service_outgrown(&outgrown))
        err = &outgrown;
    const struct mem_account *a = mem_account_current();
    if (a) /* what job-memory must hold for jobs like it */
        LOG(LOG_DEBUG, "job %s: its own allocations peaked at %lld MB", c->id, atomic_load(&a->peak) >> 20);
    char *p = outcome == JOB_FAILED ? problem_from_err(err) : NULL;
    if (outcome == JOB_FAILED)
        LOG(LOG_WARN, "job %s failed: %s", c->id, err->message);
    struct job_end end = {outcome, result, len, type, meta, p, wall_s()};
    int rc = store_end(svc, c, &end);
    if (rc && rc != SF_ECONFLICT) {
        strand(svc, c, "the store will not take its end");
    } else {
        if (rc == 0)
            metrics_job_end(outcome);
        else
            LOG(LOG_WARN, "job %s: ended here after its claim was lost; its outcome is dropped", c->id);
        pthread_mutex_lock(&svc->lock);
        struct claim *h = claim_find(svc, c->id, c->fence);
        if (h && h->stranded)
            LOG(LOG_INFO, "job %s: the store took its end after %d refusals", c->id, h->tries);
        if (h)
            *h = svc->claims[--svc->n_claims];
        pthread_mutex_unlock(&svc->lock);
    }
    free(p);
}

void service_release(struct service *svc, const char *id)
{
    pthread_mutex_lock(&svc->lock);
    struct claim *h = claim_find(svc, id, -1);
    struct job_claim c = h ? h->c : (struct job_claim){.fence = -1};
    pthread_mutex_unlock(&svc->lock);
    if (h)
        store_release(svc->store, c.id, c.fence);
}

int service_n_stranded(struct service *svc)
{
    pthread_mutex_lock(&svc->lock);
    int n = 0;
    for (int k = 0; k < svc->n_claims; k++)
        n += svc->claims[k].stranded;
    pthread_mutex_unlock(&svc->lock);
    return n;
}

/* ---- helpers of the job kinds ---- */

/* The resolver's objects(): stored model id's patches (or mesh) appended to the scene, refused
 * when the meshes all of the scene's model objects name would come to over max-triangles (every
 * reference is a copy of its mesh). */
static int model_objects(void *ctx, const char *id, const struct material *mat, const char *where, struct scene *sc,
                         struct sf_err *err)
{
    const struct model_scope *ms = ctx;
    size_t max_triangles = (size_t)ms->svc->cfg.max_triangles;
    char p[400], *src = NULL;
    size_t len = 0;
    snprintf(p, sizeof p, "%s/id", where);
    int found = store_model_get(ms->svc->store, id, ms->owner, NULL, &src, &len), rc = 0;
    if (found)
        rc = found == SF_ENOTFOUND ? sf_fail(err, SF_EINVAL, p, "no stored model has this id")
                        : sf_fail(err, SF_EIO, p, "the store could not be read");
    size_t tris = rc ? 0 : mesh_packed_triangles(src, len);
    for (int k = 0; tris && k < sc->n_meshes; k++)
        tris += sc->meshes[k].m.n_tri;
    if (!rc && max_triangles && tris > max_triangles)
        rc = sf_fail(err, SF_ELIMIT, p, "the scene's stored meshes come to %zu triangles with this one: over this "
                     "node's %zu (max-triangles)", tris, max_triangles);
    if (!rc)
        rc = model_scene_objects(src, len, sc, mat, where, err);
    free(src);
    return rc;
}

struct model_resolver service_models(struct model_scope *scope)
{
    return (struct model_resolver){model_objects, scope, NULL};
}

bool service_poll_job(void *ctx, double done)
{
    const struct job_poll *p = ctx;
    return jobq_cancelled(p->q, p->j, done);
}

bool service_poll_cancel(void *ctx, double done)
{
    (void)done;
    const struct job_poll *p = ctx;
    return jobq_cancelled(p->q, p->j, 0);
}
