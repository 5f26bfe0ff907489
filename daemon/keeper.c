/* keeper.c - the node's keeper (service.h says how a job travels): the thread that claims queued
 * jobs from the store while the pool has room and starts each as its kind runs it, renews the
 * leases of the claims held, passes on cancels asked on any node, and reaps the claims of nodes that
 * died; and the runs again of stranded jobs. The top of the job machinery: it sees the kinds
 * (kinds.h), which see only the service below it. */
#include "keeper.h"

#include <math.h>
#include <stdlib.h>
#include <time.h>

#include "kinds.h"
#include "log.h"

/* Takes one queued job from the store and starts it: true when one was started. A suspect (a
 * job queued again after a node stopped while it ran beside others) is claimed only when no other
 * job runs here, and nothing else is claimed while it runs: if it stops the node, the reap then
 * finds it alone and charges it, and no innocent job is charged with it. */
static bool claim_one(struct service *svc)
{
    pthread_mutex_lock(&svc->lock);
    bool full = svc->n_claims >= CLAIMS_MAX, alone = svc->n_claims == 0, isolated = false;
    for (int k = 0; k < svc->n_claims; k++)
        isolated = isolated || svc->claims[k].c.suspect;
    pthread_mutex_unlock(&svc->lock);
    if (full || isolated || atomic_load(&svc->draining) || jobq_room(svc->q) == 0)
        return false;
    struct job_claim c;
    if (store_claim(svc->store, svc->node, (double)svc->cfg.lease, alone, &c))
        return false;
    if (c.suspect)
        LOG(LOG_INFO, "job %s runs alone: it was running when the service last stopped", c.id);
    pthread_mutex_lock(&svc->lock);
    svc->claims[svc->n_claims++] = (struct claim){.c = c};
    pthread_mutex_unlock(&svc->lock);
    if (job_start(svc, &c)) {
        LOG(LOG_ERROR, "job %s of kind \"%s\" could not be started here; handed back", c.id, c.kind);
        store_release(svc->store, c.id, c.fence);
        claim_drop(svc, &c);
        return false;
    }
    LOG(LOG_DEBUG, "job %s (%s) claimed, fence %ld", c.id, c.kind, c.fence);
    return true;
}

/* Renews the lease of every claim held, stores progress, and passes a cancel asked anywhere to
 * the pool. A claim the store says is lost is cancelled here (its end would change nothing). */
static void heartbeat(struct service *svc)
{
    pthread_mutex_lock(&svc->lock);
    int n = svc->n_claims;
    struct job_claim *held = malloc(sizeof *held * (size_t)(n ? n : 1));
    for (int k = 0; held && k < n; k++)
        held[k] = svc->claims[k].c;
    pthread_mutex_unlock(&svc->lock);
    for (int k = 0; held && k < n; k++) {
        enum job_state st;
        double progress = 0;
        jobq_peek(svc->q, held[k].id, &st, &progress);
        bool cancel = false;
        int rc = store_heartbeat(svc->store, held[k].id, held[k].fence, (double)svc->cfg.lease, progress, &cancel);
        if (rc == SF_ECONFLICT)
            LOG(LOG_WARN, "job %s: this node's claim was lost (its lease ran out); stopping it here", held[k].id);
        if (rc == SF_ECONFLICT || (rc == 0 && cancel))
            jobq_cancel(svc->q, held[k].id);
    }
    free(held);
}

static void reaped(const char *id, enum job_state state, void *arg)
{
    struct service *svc = arg;
    if (state == JOB_FAILED) {
        LOG(LOG_ERROR, "job %s stopped the service %ld times: failed, not run again", id, svc->cfg.max_attempts);
        jobq_notify(svc->q, id); /* a waiter on any node learns it ended */
    } else {
        LOG(LOG_WARN, "job %s: its node's lease ran out; queued again", id);
    }
}

/* The keeper: claims while the pool has room, heartbeats a third of a lease apart, reaps expired
 * leases as often. It sleeps until woken (a submit, a job's end) or a second has passed: a second
 * is how long a job queued by another node can wait for this one's idle workers. */
static void *keeper(void *arg)
{
    struct service *svc = arg;
    double beat = monotonic_s(), reap = beat;
    char *give_up = service_give_up_problem(svc);
    pthread_mutex_lock(&svc->lock);
    while (!svc->stop) {
        if (!svc->wake) {
            struct timespec ts;
            clock_gettime(CLOCK_MONOTONIC, &ts);
            ts.tv_sec += 1;
            pthread_cond_timedwait(&svc->wake_cond, &svc->lock, &ts);
        }
        svc->wake = false;
        if (svc->stop)
            break;
        pthread_mutex_unlock(&svc->lock);
        while (claim_one(svc))
            ;
        double now = monotonic_s(), every = (double)svc->cfg.lease / 3;
        if (now - beat >= every) {
            heartbeat(svc);
            beat = now;
        }
        if (now - reap >= every) {
            store_reap(svc->store, wall_s(), NULL, (int)svc->cfg.max_attempts, give_up, reaped, svc);
            reap = now;
        }
        pthread_mutex_lock(&svc->lock);
    }
    pthread_mutex_unlock(&svc->lock);
    free(give_up);
    return NULL;
}

static void wake_on_room(void *arg) { service_wake(arg); }

/* What other nodes did (a shared store): claim what they queued, answer waiters of what they
 * ended, stop what they were asked to cancel. */
static void on_store_event(enum store_event ev, const char *id, void *arg)
{
    struct service *svc = arg;
    if (ev == STORE_QUEUED)
        service_wake(svc);
    else if (ev == STORE_ENDED)
        jobq_notify(svc->q, id);
    else
        jobq_cancel(svc->q, id);
}

int keeper_start(struct service *svc)
{
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&svc->wake_cond, &ca);
    pthread_condattr_destroy(&ca);
    jobq_on_room(svc->q, wake_on_room, svc);
    store_on_event(svc->store, on_store_event, svc);
    svc->wake = true;
    if (pthread_create(&svc->keeper, NULL, keeper, svc))
        return SF_ENOMEM;
    svc->keeper_started = true;
    return 0;
}

void keeper_stop(struct service *svc)
{
    if (!svc->keeper_started)
        return;
    pthread_mutex_lock(&svc->lock);
    svc->stop = true;
    pthread_cond_signal(&svc->wake_cond);
    pthread_mutex_unlock(&svc->lock);
    pthread_join(svc->keeper, NULL);
    store_on_event(svc->store, NULL, NULL); /* no more calls into the queue from the store */
    svc->keeper_started = false;
}

void keeper_retry_stranded(struct service *svc)
{
    if (store_full(svc->store) && !store_writable(svc->store))
        return; /* no room yet: running them again would only fill it */
    double now = monotonic_s();
    pthread_mutex_lock(&svc->lock);
    for (int k = 0; k < svc->n_claims; k++) {
        struct claim *h = &svc->claims[k];
        if (!h->stranded || h->retry_at > now)
            continue;
        h->retry_at = INFINITY; /* running: its end sets the next */
        struct job_claim c = h->c;
        pthread_mutex_unlock(&svc->lock);
        bool started = job_start(svc, &c) == 0;
        LOG(started ? LOG_INFO : LOG_WARN, "job %s: run again after the store refused its end%s", c.id,
            started ? "" : ": could not start it");
        pthread_mutex_lock(&svc->lock);
        if (!started && (h = claim_find(svc, c.id, c.fence)))
            h->retry_at = now + STRANDED_FIRST_S;
    }
    pthread_mutex_unlock(&svc->lock);
}
