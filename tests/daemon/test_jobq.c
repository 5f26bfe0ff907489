/* test_jobq.c - the queue and pool under the thread sanitizer: many banded jobs on 4 workers,
 * cancellations while queued and between bands, waiters that time out and waiters that see the
 * end, a full queue, and a shutdown that requeues what runs. Every band runs exactly once. */
#include "../../daemon/jobq.h"
#include "../unit.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <time.h>

struct work {
    int n_bands;
    atomic_int *ran;        /* per band */
    atomic_int finished;    /* times finish ran */
    enum job_state outcome;
    bool requeue;
    int spin_us;
};

static atomic_int total_finished;

static int prepare(struct job *j, void *arg, int *n)
{
    (void)j;
    struct work *w = arg;
    *n = w->n_bands;
    return w->n_bands < 0 ? -1 : 0;
}

static void band(struct job *j, void *arg, int k)
{
    (void)j;
    struct work *w = arg;
    atomic_fetch_add(&w->ran[k], 1);
    struct timespec ts = {0, w->spin_us * 1000L};
    nanosleep(&ts, NULL);
}

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct work *w = arg;
    w->outcome = outcome;
    w->requeue = requeue;
    atomic_fetch_add(&w->finished, 1);
    atomic_fetch_add(&total_finished, 1);
}

static const struct job_ops OPS = {.prepare = prepare, .band = band, .finish = finish};

struct waited {
    atomic_int calls;
    atomic_bool finished;
};

static void on_wait(void *arg, bool finished)
{
    struct waited *w = arg;
    atomic_store(&w->finished, finished);
    atomic_fetch_add(&w->calls, 1);
}

static struct work *make_work(int n_bands, int spin_us)
{
    struct work *w = calloc(1, sizeof *w);
    w->n_bands = n_bands;
    w->ran = calloc(n_bands > 0 ? (size_t)n_bands : 1, sizeof *w->ran);
    w->spin_us = spin_us;
    return w;
}

static void sleep_ms(int ms)
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

TEST(bands_run_once_and_jobs_end)
{
    enum { N = 40 };
    struct jobq *q = jobq_new(4, N, 0);
    struct work *w[N];
    struct waited wt[N] = {0};
    char id[N][40];
    for (int k = 0; k < N; k++) {
        w[k] = make_work(k % 5 == 0 ? 0 : (k % 7 == 0 ? -1 : 3 + k % 13), 50);
        snprintf(id[k], sizeof id[k], "job%02d", k);
        /* the waiter first: one registered after the job ended would wait for its deadline (the
         * daemon checks the store for that case) */
        jobq_wait(q, id[k], monotonic_s() + 30, on_wait, &wt[k]);
        CHECK(jobq_submit(q, id[k], &OPS, w[k], false) == 0);
    }
    for (int k = 3; k < N; k += 9)
        jobq_cancel(q, id[k]);
    /* a job's waiters are called after its finish returns: wait for both */
    for (int t = 0, waited = 0; t < 3000 && (atomic_load(&total_finished) < N || waited < N); t++) {
        sleep_ms(2);
        waited = 0;
        for (int k = 0; k < N; k++)
            waited += atomic_load(&wt[k].calls) > 0;
    }
    CHECK(atomic_load(&total_finished) == N);
    for (int k = 0; k < N; k++) {
        CHECK(atomic_load(&w[k]->finished) == 1);
        CHECK(atomic_load(&wt[k].calls) == 1 && atomic_load(&wt[k].finished));
        bool cancelled = (k - 3) % 9 == 0;
        if (w[k]->n_bands < 0) /* fails in prepare, unless cancelled while still queued */
            CHECK(w[k]->outcome == JOB_FAILED || (cancelled && w[k]->outcome == JOB_CANCELLED));
        else if (w[k]->outcome == JOB_SUCCEEDED)
            for (int b = 0; b < w[k]->n_bands; b++)
                CHECK(atomic_load(&w[k]->ran[b]) == 1);
        else
            CHECK(w[k]->outcome == JOB_CANCELLED && cancelled);
        for (int b = 0; b < w[k]->n_bands; b++)
            CHECK(atomic_load(&w[k]->ran[b]) <= 1);
    }
    jobq_shutdown(q, 1.0, 5.0, NULL, NULL);
    jobq_free(q);
    for (int k = 0; k < N; k++) {
        free(w[k]->ran);
        free(w[k]);
    }
}

TEST(full_queue_timeouts_and_shutdown)
{
    atomic_store(&total_finished, 0);
    struct jobq *q = jobq_new(1, 2, 0);
    struct work *slow = make_work(200, 2000), *a = make_work(2, 10), *b = make_work(2, 10), *c = make_work(2, 10);
    CHECK(jobq_submit(q, "slow", &OPS, slow, false) == 0);
    sleep_ms(20); /* slow is running now */
    CHECK(jobq_submit(q, "a", &OPS, a, false) == 0);
    CHECK(jobq_submit(q, "b", &OPS, b, false) == 0);
    CHECK(jobq_submit(q, "c", &OPS, c, false) == SF_ELIMIT); /* full: two queued */
    CHECK(jobq_submit(q, "c", &OPS, c, true) == 0);   /* recovery may overfill */
    CHECK(jobq_room(q) == 0);
    struct waited early = {0}, elsewhere = {0}, gone = {0};
    jobq_wait(q, "a", monotonic_s() + 0.05, on_wait, &early);
    /* a job this queue does not run (another node's) is waited for until it is said to end */
    jobq_wait(q, "elsewhere", monotonic_s() + 10, on_wait, &elsewhere);
    jobq_wait(q, "gone", monotonic_s() + 0.1, on_wait, &gone);
    CHECK(atomic_load(&elsewhere.calls) == 0);
    jobq_notify(q, "elsewhere");
    CHECK(atomic_load(&elsewhere.calls) == 1 && atomic_load(&elsewhere.finished));
    jobq_notify(q, "elsewhere"); /* once only */
    sleep_ms(300);
    CHECK(atomic_load(&elsewhere.calls) == 1);
    CHECK(atomic_load(&early.calls) == 1 && !atomic_load(&early.finished)); /* timed out */
    CHECK(atomic_load(&gone.calls) == 1 && !atomic_load(&gone.finished));
    enum job_state st;
    double progress;
    CHECK(jobq_peek(q, "slow", &st, &progress) && st == JOB_RUNNING && progress > 0 && progress < 1);
    jobq_shutdown(q, 0.05, 5.0, NULL, NULL); /* slow cannot finish: cancelled for requeue; a, b, c stay queued */
    jobq_free(q);
    CHECK(slow->outcome == JOB_CANCELLED && slow->requeue);
    CHECK(a->requeue && b->requeue && c->requeue);
    CHECK(atomic_load(&slow->finished) == 1 && atomic_load(&a->finished) == 1);
    struct work *all[] = {slow, a, b, c};
    for (int k = 0; k < 4; k++) {
        free(all[k]->ran);
        free(all[k]);
    }
}

/* A job of phases: bands of phase p run only after every band of phase p-1 (next() between). */
struct phased {
    atomic_int phase, nexts, in_phase[3], early; /* early: a band that ran before its phase */
    enum job_state outcome;
};

static int ph_prepare(struct job *j, void *arg, int *n)
{
    (void)j;
    (void)arg;
    *n = 8;
    return 0;
}

static void ph_band(struct job *j, void *arg, int k)
{
    (void)j;
    (void)k;
    struct phased *p = arg;
    int ph = atomic_load(&p->phase);
    atomic_fetch_add(&p->in_phase[ph], 1);
    struct timespec ts = {0, 200 * 1000L};
    nanosleep(&ts, NULL);
    if (atomic_load(&p->phase) != ph)
        atomic_fetch_add(&p->early, 1);
}

static int ph_next(struct job *j, void *arg, int *n)
{
    (void)j;
    struct phased *p = arg;
    atomic_fetch_add(&p->nexts, 1);
    int ph = atomic_fetch_add(&p->phase, 1) + 1;
    *n = ph < 3 ? 8 : 0;
    return 0;
}

static void ph_finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    (void)requeue;
    ((struct phased *)arg)->outcome = outcome;
}

static const struct job_ops PHASED = {.prepare = ph_prepare, .band = ph_band, .next = ph_next, .finish = ph_finish};

TEST(phases_of_bands)
{
    struct jobq *q = jobq_new(4, 8, 0);
    struct phased p = {0};
    struct waited w = {0};
    jobq_wait(q, "p", monotonic_s() + 30, on_wait, &w);
    CHECK(jobq_submit(q, "p", &PHASED, &p, false) == 0);
    for (int k = 0; k < 3000 && !atomic_load(&w.calls); k++)
        sleep_ms(1);
    CHECK(atomic_load(&w.calls) == 1 && atomic_load(&w.finished));
    CHECK(p.outcome == JOB_SUCCEEDED && atomic_load(&p.nexts) == 3);
    CHECK(atomic_load(&p.in_phase[0]) == 8 && atomic_load(&p.in_phase[1]) == 8 && atomic_load(&p.in_phase[2]) == 8);
    CHECK(atomic_load(&p.early) == 0);
    jobq_shutdown(q, 1, 1, NULL, NULL);
    jobq_free(q);
}

/* A job whose finish is slow (an edit's compaction after its answer): its state has ended, but
 * it is still active. A shutdown within that time must not call the queue stopped (the caller
 * would free it under the worker): it returns the job as left, and a later one stops the queue. */
static void slow_finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    finish(j, arg, outcome, requeue);
    sleep_ms(400);
}

static const struct job_ops SLOW_FINISH = {.prepare = prepare, .band = band, .finish = slow_finish};

TEST(shutdown_while_a_job_finishes)
{
    struct jobq *q = jobq_new(2, 4, 0);
    struct work *w = make_work(1, 10);
    CHECK(jobq_submit(q, "tail", &SLOW_FINISH, w, false) == 0);
    enum job_state st = JOB_QUEUED;
    double progress;
    for (int k = 0; k < 200 && !(atomic_load(&w->finished) == 1); k++)
        sleep_ms(5);
    CHECK(atomic_load(&w->finished) == 1 && jobq_peek(q, "tail", &st, &progress) && st == JOB_RUNNING); /* in its finish */
    CHECK(jobq_shutdown(q, 0.01, 0.05, NULL, NULL) == 1); /* left: not stopped, not to be freed */
    sleep_ms(500);
    CHECK(jobq_shutdown(q, 0.01, 0.05, NULL, NULL) == 0); /* its finish over: stopped */
    jobq_free(q);
    free(w->ran);
    free(w);
}

/* jobq_help: a prepare's own loop, its tasks on the preparer and on the idle worker, each once,
 * the call returning when every task has ended; called from elsewhere, all of it on the caller. */
struct helped {
    struct jobq *q;
    atomic_int ran[64];
    atomic_int on_other;    /* tasks a worker other than the preparer ran */
    atomic_int after;       /* tasks found unfinished once jobq_help returned */
    pthread_t preparer;
    enum job_state outcome;
};

static void help_task(void *ctx, int k)
{
    struct helped *h = ctx;
    if (!pthread_equal(pthread_self(), h->preparer))
        atomic_fetch_add(&h->on_other, 1);
    sleep_ms(2);
    atomic_fetch_add(&h->ran[k], 1);
}

static int help_prepare(struct job *j, void *arg, int *n)
{
    (void)j;
    struct helped *h = arg;
    h->preparer = pthread_self();
    jobq_help(h->q, 64, help_task, h);
    for (int k = 0; k < 64; k++)
        atomic_fetch_add(&h->after, atomic_load(&h->ran[k]) != 1);
    *n = 0;
    return 0;
}

static void help_finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    (void)requeue;
    ((struct helped *)arg)->outcome = outcome;
}

static const struct job_ops HELPED = {.prepare = help_prepare, .finish = help_finish};

TEST(help_with_a_prepares_loop)
{
    struct jobq *q = jobq_new(2, 8, 0);
    struct helped *h = calloc(1, sizeof *h);
    REQUIRE(h);
    h->q = q;
    struct waited w = {0};
    jobq_wait(q, "h", monotonic_s() + 30, on_wait, &w);
    CHECK(jobq_submit(q, "h", &HELPED, h, false) == 0);
    for (int k = 0; k < 3000 && !atomic_load(&w.calls); k++)
        sleep_ms(1);
    CHECK(atomic_load(&w.calls) == 1 && h->outcome == JOB_SUCCEEDED);
    int once = 0;
    for (int k = 0; k < 64; k++)
        once += atomic_load(&h->ran[k]) == 1;
    CHECK(once == 64 && atomic_load(&h->after) == 0);
    CHECK(atomic_load(&h->on_other) > 0); /* (the idle worker took some: 64 tasks of 2 ms) */
    jobq_shutdown(q, 1, 1, NULL, NULL);
    jobq_free(q);
    struct helped *o = calloc(1, sizeof *o); /* not on a worker: all on this thread */
    REQUIRE(o);
    struct jobq *other = jobq_new(1, 1, 0);
    o->q = other, o->preparer = pthread_self();
    jobq_help(other, 64, help_task, o);
    int all = 0;
    for (int k = 0; k < 64; k++)
        all += atomic_load(&o->ran[k]) == 1;
    CHECK(all == 64 && atomic_load(&o->on_other) == 0);
    jobq_shutdown(other, 1, 1, NULL, NULL);
    jobq_free(other);
    free(o);
    free(h);
}

int main(void)
{
    RUN(bands_run_once_and_jobs_end);
    RUN(full_queue_timeouts_and_shutdown);
    RUN(phases_of_bands);
    RUN(shutdown_while_a_job_finishes);
    RUN(help_with_a_prepares_loop);
    UNIT_END();
}
