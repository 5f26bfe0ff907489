/* service.h - what the running daemon shares between its HTTP front end and its jobs: settings,
 * store, queue, Embree device, tokens, the draining flag. Created by cmd_serve.c. */
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

/* A job whose end the store would not take (a full disk, a failing device): its outcome is lost,
 * the job is not. It is run again, after a growing delay, until the store takes its end. */
#define STRANDED_MAX 1024
struct stranded {
    char id[40];
    char kind[16];
    double retry_at;         /* monotonic seconds */
    int tries;
};

struct service {
    struct config cfg;
    struct store *store;
    struct jobq *q;
    struct bvh_device *dev;
    struct token *tokens;    /* bearer tokens; none: open (loopback, or --insecure-no-auth) */
    size_t n_tokens;
    atomic_bool draining;
    double started_wall;     /* Unix seconds */
    double started_mono;
    pthread_mutex_t stranded_lock; /* guards the two fields below */
    struct stranded stranded[STRANDED_MAX];
    int n_stranded;
};

double wall_s(void);
/* A new random job id (32 hex digits). */
void service_new_id(char out[40]);

/* Records a job's end in the store and the metrics: succeeded (result) or failed (problem from
 * err) or cancelled, or, with requeue, back to queued for the next start. result may be NULL for
 * outcomes other than JOB_SUCCEEDED. When the store will not take the end (after a few tries),
 * the job is stranded: counted nowhere as ended, run again by service_retry_stranded(). */
void service_job_end(struct service *svc, const char *id, enum job_state outcome, bool requeue,
                     const unsigned char *result, size_t len, const char *type, const char *meta,
                     const struct sf_err *err);

/* Runs the stranded jobs whose delay has passed (the daemon's main loop calls it). */
void service_retry_stranded(struct service *svc);
/* Jobs stranded now (for /metrics). */
int service_n_stranded(struct service *svc);

/* Queues stored job id of the named kind (force as in jobq_submit): 0, or -1 (the queue is full
 * or stopping, or no kind has that name). */
int service_submit_kind(struct service *svc, const char *kind, const char *id, bool force);

/* Stored models for scenes' model objects, those of owner only (NULL: every owner's). The resolver
 * borrows *scope, which the caller fills and keeps while it is used. */
struct model_scope {
    struct service *svc;
    const char *owner;
};
struct model_resolver service_models(struct model_scope *scope);

/* The job kinds: each queues job `id` (already in the store). force as in jobq_submit. */
int render_job_submit(struct service *svc, const char *id, bool force);
int volume_job_submit(struct service *svc, const char *id, bool force);
int model_job_submit(struct service *svc, const char *id, bool force);
int mesh_job_submit(struct service *svc, const char *id, bool force);
int patches_job_submit(struct service *svc, const char *id, bool force);

#endif
