/* service.h - what the running daemon shares between its HTTP front end and its jobs: settings,
 * store, queue, Embree device, tokens, the draining flag, the claims this node holds; and what the
 * job kinds call: the end of a job, its polls, stored models for scenes. Created by cmd_serve.c;
 * the keeper (keeper.h) moves jobs between the store and the worker pool.
 *
 * How a job travels: the HTTP layer validates a request and store_submit()s it (QUEUED), then
 * wakes the keeper. The keeper claims queued jobs (store_claim: any node's, oldest first) while
 * the pool has room, and starts each by its kind (kinds.h) on the pool. While a job runs the
 * keeper renews its lease (store_heartbeat) and passes on a cancel asked on any node. The job's
 * kind ends it through service_job_end(), which store_finish()es it under the claim's fence. The
 * keeper also reaps claims whose lease ran out (a node that died) so that another node runs them. */
#ifndef SURFD_SERVICE_H
#define SURFD_SERVICE_H

#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>

#include "../api/scene_io.h"
#include "../core/trace/bvh.h"
#include "config.h"
#include "jobq.h"
#include "store.h"
#include "tokens.h"

/* The claims this node holds: jobs on its pool, and jobs whose end the store would not take (a
 * full disk, a failing device: stranded). A stranded job's outcome is lost, the job is not: it is
 * run again, after a growing delay, until the store takes its end; its lease is kept meanwhile. */
#define CLAIMS_MAX 1024
struct claim {
    struct job_claim c;
    bool stranded;
    double retry_at;         /* monotonic seconds, when stranded */
    int tries;
};
/* A stranded job's first delay before it runs again; doubled each time, up to STRANDED_LAST_S. */
#define STRANDED_FIRST_S 5.0
#define STRANDED_LAST_S 300.0

struct frames;

struct service {
    struct config cfg;
    struct store *store;
    struct jobq *q;
    struct bvh_device *dev;
    struct token *tokens;    /* bearer tokens; none: open (loopback, or --insecure-no-auth) */
    size_t n_tokens;
    struct shares *shares;   /* each owner's uploads held in the data dir (shares.h) */
    struct frames *frames;   /* models' prepared hierarchies (frames.h; its own lock) */
    char node[64];           /* this node's name in the store */
    atomic_bool draining;
    double started_wall;     /* Unix seconds */
    double started_mono;
    pthread_mutex_t lock;    /* guards the fields below */
    pthread_cond_t wake_cond;
    bool wake, stop;
    struct claim claims[CLAIMS_MAX];
    int n_claims;
    pthread_t keeper;
    bool keeper_started;
    struct dicom_node *dicom; /* the DICOM node (dicom_node.h), or NULL */
    struct pacs *pacs;       /* the PACS configured (pacs.h), n_pacs of them */
    int n_pacs;
};

double wall_s(void);
/* A new random job id (32 hex digits). */
void service_new_id(char out[40]);

/* The claim on job id under fence (any fence: fence < 0), or NULL. svc->lock held. */
struct claim *claim_find(struct service *svc, const char *id, long fence);
/* Drops the claim c (takes svc->lock). */
void claim_drop(struct service *svc, const struct job_claim *c);

/* Asks the keeper to look for queued jobs now (a job was submitted, or one ended). */
void service_wake(struct service *svc);

/* Records a job's end in the store (under its claim) and the metrics: succeeded (result) or
 * failed (problem from err) or cancelled, or, with requeue, handed back queued (a drain). result
 * may be NULL for outcomes other than JOB_SUCCEEDED. A claim this node no longer holds changes
 * nothing (the job was reaped and runs elsewhere). When the store will not take the end (after a
 * few tries), the job is stranded, and run again by keeper_retry_stranded(). */
void service_job_end(struct service *svc, const struct job_claim *c, enum job_state outcome, bool requeue,
                     const unsigned char *result, size_t len, const char *type, const char *meta,
                     const struct sf_err *err);
/* For a failed job's ops: when the failure came from an allocation its memory account refused
 * (core/base/mem.h: the job outgrew job-memory), err becomes the 422 that says so, with the
 * figures. Returns err's code. */
int service_outgrown(struct sf_err *err);
/* A job of this node's pool that a drain could not stop: handed back queued. */
void service_release(struct service *svc, const char *id);

/* Jobs stranded now (for /metrics). */
int service_n_stranded(struct service *svc);

/* The give-up problem JSON of a job that reached max-attempts (caller frees). */
char *service_give_up_problem(const struct service *svc);

/* Stored models for scenes' model objects, those of owner only (NULL: every owner's). The resolver
 * borrows *scope, which the caller fills and keeps while it is used. */
struct model_scope {
    struct service *svc;
    const char *owner;
};
struct model_resolver service_models(struct model_scope *scope);

/* The modelling's poll (core/base/err.h) for a job on the pool: its progress, and its cancel flag. */
struct job_poll {
    struct jobq *q;
    struct job *j;
};
bool service_poll_job(void *ctx, double done);
/* The same, for work that is one step of its job's progress: the fraction it is given is not the job's. */
bool service_poll_cancel(void *ctx, double done);

#endif
