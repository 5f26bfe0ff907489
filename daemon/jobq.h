/* jobq.h - the bounded job queue and its worker pool.
 *
 * A job runs in up to three steps, given by its kind's ops: prepare() on the worker that takes it,
 * then band(k) for k in [0, n_bands) on any idle workers (a render's scanline bands; a job may
 * have several phases of bands, next() starting each after the last), then finish() on the
 * worker that completes the last band. A job with no bands is finished right after
 * prepare. Cancel takes effect between bands. See jobq.c for the threading contract. */
#ifndef SURFD_JOBQ_H
#define SURFD_JOBQ_H

#include <stdbool.h>
#include <stddef.h>

#include "../core/base/err.h"
#include "job_state.h"

struct jobq;
struct job;

struct job_ops {
    /* Sets *n_bands (0: all work done here). Returns 0, or a negative SF_E* code when the job
     * failed (the kind keeps its error for finish, which is then called with JOB_FAILED, or
     * JOB_CANCELLED when the job had been asked to stop). Runs without the queue lock. */
    int (*prepare)(struct job *j, void *work, int *n_bands);
    void (*band)(struct job *j, void *work, int band); /* NULL for kinds without bands */
    /* NULL, or called (without the lock) when every band of a phase is done: sets *n_bands for
     * the next phase (0: all done). Returns 0, or an SF_E* code when the job failed. A job reports its own
     * progress (jobq_cancelled) when it has phases. */
    int (*next)(struct job *j, void *work, int *n_bands);
    /* outcome: JOB_SUCCEEDED, JOB_FAILED (prepare failed) or JOB_CANCELLED (by the user; or, with
     * requeue, by shutdown: the job is to run again after restart). Frees work (but see after). */
    void (*finish)(struct job *j, void *work, enum job_state outcome, bool requeue);
    /* NULL, or called (without the lock, on the same worker) once the job's waiters are woken:
     * what the kind does after its answer (a compaction, a warm-up); finish then leaves work for
     * it to free. */
    void (*after)(void *work);
};

/* Creates the pool with n_workers threads and room for queue_max waiting jobs, each job's ops
 * charged to a memory account of job_memory bytes (0: unbounded; core/base/mem.h). */
struct jobq *jobq_new(int n_workers, long queue_max, long long job_memory);
/* From a job's ops on a worker of q: fn(ctx, k) for each k in [0, n), on this worker and any idle
 * one, with the job's memory account entered (fn's tasks write disjoint data); returns once every
 * task has ended. Called anywhere else, it runs them all on the calling thread. */
void jobq_help(struct jobq *q, int n, void (*fn)(void *ctx, int k), void *ctx);
/* Stops taking queued jobs, waits up to timeout_s for running ones, cancels (requeue) the rest
 * and gives them grace_s to stop; then joins the workers and returns 0 (jobq_free frees it). Queued
 * jobs stay in the store. A job still running after the grace (deaf to its cancel flag) is named
 * to abandoned(id, arg), with the queue's lock held (abandoned must not call the queue); the
 * queue is then left as it is and the number of jobs still active returned (those named, and any
 * still in its finish after its end state was set): the caller ends the process, or calls again. */
int jobq_shutdown(struct jobq *q, double timeout_s, double grace_s, void (*abandoned)(const char *id, void *arg),
                  void *arg);
/* Frees a queue that jobq_shutdown stopped (0). Its waiters and jobs are gone by then. */
void jobq_free(struct jobq *q);

/* Queues a job. work is handed over (ops->finish frees it). Returns 0, or SF_ELIMIT when the
 * queue is full or shutting down, SF_ENOMEM (work not taken). force: ignore queue_max (jobs
 * recovered at start). */
int jobq_submit(struct jobq *q, const char *id, const struct job_ops *ops, void *work, bool force);

/* Live state of a queued or running job (JOB_QUEUED or JOB_RUNNING: a job whose finish is still
 * encoding or storing its result is running) and its progress, which never goes back; false when
 * the queue no longer knows it (finished, or never seen: ask the store). */
bool jobq_peek(struct jobq *q, const char *id, enum job_state *state, double *progress);
/* Asks a queued or running job to stop (one whose finish is still running may honour it too,
 * polling jobq_cancelled). Returns false when the queue does not know it. */
bool jobq_cancel(struct jobq *q, const char *id);
/* For a job's own ops, between steps of long work: records progress (0..1; the job's progress
 * never goes back) and answers whether the job has been asked to stop. */
bool jobq_cancelled(struct jobq *q, struct job *j, double progress);

/* Calls fn(arg, finished) once: when job id ends here or jobq_notify(id) says it ended elsewhere
 * (finished = true), or at deadline (monotonic seconds; finished = false). The job need not be
 * in the queue yet: a caller that may have missed the end (it was stored before the wait began)
 * checks the store after jobq_wait and calls jobq_notify. fn runs on a worker, the timer thread
 * or jobq_notify's caller, without any lock held. */
void jobq_wait(struct jobq *q, const char *id, double deadline, void (*fn)(void *arg, bool finished), void *arg);
/* Wakes the waiters of job id: it has ended (here or on another node). */
void jobq_notify(struct jobq *q, const char *id);
/* fn(arg) is called, without the lock, each time a job ends and frees room for another. */
void jobq_on_room(struct jobq *q, void (*fn)(void *), void *arg);
/* Jobs the pool could start now: workers without a job, less jobs waiting in memory. */
int jobq_room(struct jobq *q);

const char *job_id(const struct job *j);
/* Counters for /metrics. */
struct jobq_stats {
    long queued, running, workers, queue_max;
};
void jobq_stats(struct jobq *q, struct jobq_stats *out);
/* The daemon's deadlines and durations, in seconds: core's one clock (core/base/clock.h), CLOCK_MONOTONIC
 * as the condition variables wait on. */
double monotonic_s(void);

#endif
