/* jobq.c - queue, workers and waiters.
 *
 * Threading contract
 *   Lock: one mutex, q->lock, guards every field of struct jobq and the fields of struct job marked
 *   [q]. Nothing else is taken while it is held: ops, the store and waiter callbacks all run with it
 *   released. There is no lock order to get wrong because there is one lock.
 *   Ownership of a job by state:
 *     QUEUED     the queue (linked in q->queue and q->live); only lock holders touch it.
 *     preparing  the worker that dequeued it, alone, for ops->prepare (j->work is its own).
 *     banded     shared: any worker may claim the next band under the lock and run ops->band
 *                unlocked; bands write disjoint data, prepared data is read-only.
 *     finishing  the worker that saw the last band end (or the preparer, for a job without bands)
 *                runs ops->finish unlocked, then unlinks the job and wakes its waiters
 *                (then ops->after, when the kind has one).
 *     helped     a job's ops may hand a loop of their own to idle workers (jobq_help): the loop's
 *                tasks are handed out under the lock like bands, run unlocked with the job's
 *                account entered, on disjoint data; the caller takes tasks too and returns when
 *                every task has ended.
 *   What a worker may call: its job's ops (which call core/ and the store), never the HTTP layer;
 *   waiter callbacks are the only path back to connections, and they only resume them.
 *   Memory bound: at most n_workers jobs are prepared at once; others wait queued. Each job's ops
 *   run with its memory account entered (core/base/mem.h), so what they allocate is charged to it
 *   and refused past the queue's job budget. */
#include "jobq.h"

#include "../core/base/clock.h"
#include "../core/base/err.h"
#include "../core/base/mem.h"

#include <assert.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct waiter {
    char id[40];                 /* the job waited for: queued here, running elsewhere, or not yet claimed */
    void (*fn)(void *, bool);
    void *arg;
    double deadline;
    struct waiter *next;
};

struct job {
    char id[40];
    const struct job_ops *ops;
    void *work;
    enum job_state state;        /* [q] */
    bool preparing;              /* [q] */
    bool cancel;                 /* [q] set by jobq_cancel or shutdown */
    bool requeue;                /* [q] cancelled by shutdown: run again after restart */
    int n_bands, next_band;      /* [q] */
    int bands_done, bands_out;   /* [q] finished / being rendered */
    double progress;             /* [q] as the job reported it (jobq_cancelled), never decreasing */
    struct mem_account mem;      /* charged by the thread running its ops, whatever the lock */
    struct job *next_queued;     /* [q] FIFO link */
    struct job *next_live;       /* [q] all queued and running jobs */
};

/* A loop a job's ops hand to idle workers (jobq_help): on the caller's stack until it returns. */
struct help {
    void (*fn)(void *ctx, int k);
    void *ctx;
    struct job *job;
    int n, next, done;           /* [q] tasks: handed out, ended */
    struct help *next_help;      /* [q] */
};

struct jobq {
    pthread_mutex_t lock;
    pthread_t holder;            /* [q] who holds the lock, while held (the asserts' HELD) */
    bool held;                   /* [q] */
    pthread_cond_t work;         /* a queued job or a band is available, or stop */
    pthread_cond_t timer_cond;   /* a waiter with a deadline was added, or stop */
    struct job *queue_head, *queue_tail;
    struct job *live;
    long n_queued, queue_max;
    int n_workers, n_active;     /* n_active: jobs taken off the queue and not finished */
    long long job_memory;        /* each job's memory budget (0: none) */
    bool stop_taking, stop;
    pthread_t *threads, timer;
    struct waiter *waiters;      /* every waiter, by job id */
    struct help *helps;          /* [q] loops with tasks left to hand out */
    void (*room)(void *);        /* told when a job ends (jobq_on_room) */
    void *room_arg;
};

double monotonic_s(void) { return sf_now_ms() / 1e3; }

const char *job_id(const struct job *j) { return j->id; }

/* The one lock, and who holds it: the contract's "lock held" and its state rules are asserted
 * where they are relied on (assert: the test and sanitizer builds; the release build has NDEBUG). */
static void q_lock(struct jobq *q)
{
    pthread_mutex_lock(&q->lock);
    q->holder = pthread_self();
    q->held = true;
}

#define HELD(q) assert((q)->held && pthread_equal((q)->holder, pthread_self()))

static void q_unlock(struct jobq *q)
{
    HELD(q);
    q->held = false;
    pthread_mutex_unlock(&q->lock);
}

/* Waits on c (until the monotonic time until, when not NULL), the lock let go meanwhile. */
static void q_wait(struct jobq *q, pthread_cond_t *c, const struct timespec *until)
{
    HELD(q);
    q->held = false;
    if (until)
        pthread_cond_timedwait(c, &q->lock, until);
    else
        pthread_cond_wait(c, &q->lock);
    q->holder = pthread_self();
    q->held = true;
}


static struct job *find_live(struct jobq *q, const char *id)
{
    HELD(q);
    for (struct job *j = q->live; j; j = j->next_live)
        if (!strcmp(j->id, id))
            return j;
    return NULL;
}

static void unlink_live(struct jobq *q, struct job *j)
{
    HELD(q);
    for (struct job **p = &q->live; *p; p = &(*p)->next_live)
        if (*p == j) {
            *p = j->next_live;
            return;
        }
}

/* The job whose ops the calling worker runs (jobq_help's), or NULL. */
static _Thread_local struct {
    struct jobq *q;
    struct job *j;
} running;

/* j's op call, as the worker runs it: its memory account entered, the job known to jobq_help. */
#define RUN_OP(Q, J, CALL)                                                                         \
    do {                                                                                           \
        mem_account_enter(&(J)->mem);                                                              \
        running.q = (Q), running.j = (J);                                                          \
        CALL;                                                                                      \
        running.q = NULL, running.j = NULL;                                                        \
        mem_account_enter(NULL);                                                                   \
    } while (0)

/* Runs one task of h (lock held on entry and return). */
static void help_one(struct jobq *q, struct help *h)
{
    HELD(q);
    int k = h->next++;
    if (h->next == h->n) /* (every task handed out: nobody else takes one) */
        for (struct help **p = &q->helps; *p; p = &(*p)->next_help)
            if (*p == h) {
                *p = h->next_help;
                break;
            }
    q_unlock(q);
    RUN_OP(q, h->job, h->fn(h->ctx, k));
    q_lock(q);
    if (++h->done == h->n)
        pthread_cond_broadcast(&q->work); /* (its caller waits there) */
}

void jobq_help(struct jobq *q, int n, void (*fn)(void *ctx, int k), void *ctx)
{
    if (running.q != q || !running.j) { /* (not a job's op on a worker of q: all here) */
        for (int k = 0; k < n; k++)
            fn(ctx, k);
        return;
    }
    struct job *j = running.j;
    struct help h = {fn, ctx, j, n, 0, 0, NULL};
    if (n <= 0)
        return;
    q_lock(q);
    h.next_help = q->helps;
    q->helps = &h;
    pthread_cond_broadcast(&q->work);
    while (h.next < h.n)
        help_one(q, &h);
    while (h.done < h.n)
        q_wait(q, &q->work, NULL);
    q_unlock(q);
    running.q = q, running.j = j; /* (help_one's RUN_OP left it) */
    mem_account_enter(&j->mem);
}

/* A banded job with a band left to hand out. */
static struct job *band_job(struct jobq *q)
{
    HELD(q);
    for (struct job *j = q->live; j; j = j->next_live)
        if (j->state == JOB_RUNNING && !j->preparing && !j->cancel && j->next_band < j->n_bands)
            return j;
    return NULL;
}

/* A banded job cancelled between bands: nobody holds a band of it, so nobody else will end it. */
static struct job *stranded_job(struct jobq *q)
{
    HELD(q);
    for (struct job *j = q->live; j; j = j->next_live)
        if (j->state == JOB_RUNNING && !j->preparing && j->cancel && j->bands_out == 0 && j->n_bands > 0)
            return j;
    return NULL;
}

/* Unlinks the waiters of job id (all, with id NULL) into a list. Lock held. */
static struct waiter *take_waiters(struct jobq *q, const char *id)
{
    HELD(q);
    struct waiter *taken = NULL;
    for (struct waiter **p = &q->waiters; *p;) {
        struct waiter *w = *p;
        if (!id || !strcmp(w->id, id)) {
            *p = w->next;
            w->next = taken;
            taken = w;
        } else {
            p = &w->next;
        }
    }
    return taken;
}

/* Calls and frees a list of waiters. Lock not held. */
static void fire(struct waiter *w, bool finished)
{
    while (w) {
        struct waiter *next = w->next;
        w->fn(w->arg, finished);
        free(w);
        w = next;
    }
}

/* Called with the lock held; returns with it held. Runs finish unlocked and wakes the waiters. */
static void finish_job(struct jobq *q, struct job *j, enum job_state outcome)
{
    HELD(q);
    /* a job ends once, with an end state, when nobody prepares it or holds a band of it */
    assert(!job_state_ended(j->state) && job_state_ended(outcome) && !j->preparing && j->bands_out == 0);
    j->state = outcome;
    bool requeue = j->requeue;
    q_unlock(q);
    mem_account_enter(&j->mem);
    j->ops->finish(j, j->work, outcome, requeue);
    mem_account_enter(NULL);
    q_lock(q);
    unlink_live(q, j);
    q->n_active--;
    struct waiter *w = take_waiters(q, j->id);
    pthread_cond_broadcast(&q->work); /* room for another prepared job */
    void (*room)(void *) = q->room;
    void *room_arg = q->room_arg;
    q_unlock(q);
    fire(w, true);
    if (room)
        room(room_arg);
    if (j->ops->after) {
        mem_account_enter(&j->mem);
        j->ops->after(j->work);
        mem_account_enter(NULL);
    }
    free(j);
    q_lock(q);
}

static void *worker(void *arg)
{
    struct jobq *q = arg;
    q_lock(q);
    for (;;) {
        struct job *j;
        if (!q->stop_taking && q->queue_head && q->n_active < q->n_workers) {
            j = q->queue_head;
            q->queue_head = j->next_queued;
            if (!q->queue_head)
                q->queue_tail = NULL;
            q->n_queued--;
            q->n_active++;
            if (j->cancel) { /* cancelled while queued */
                finish_job(q, j, JOB_CANCELLED);
                continue;
            }
            assert(j->state == JOB_QUEUED);
            j->state = JOB_RUNNING;
            j->preparing = true;
            q_unlock(q);
            int n_bands = 0, rc = 0;
            RUN_OP(q, j, rc = j->ops->prepare(j, j->work, &n_bands));
            q_lock(q);
            j->preparing = false;
            j->n_bands = rc ? 0 : n_bands;
            if (rc || n_bands == 0) /* a prepare that stopped on its cancel flag was cancelled, not failed */
                finish_job(q, j, rc && j->cancel ? JOB_CANCELLED : rc ? JOB_FAILED : JOB_SUCCEEDED);
            else
                pthread_cond_broadcast(&q->work); /* bands for the others */
        } else if (q->helps) {
            help_one(q, q->helps);
        } else if ((j = stranded_job(q))) {
            finish_job(q, j, JOB_CANCELLED);
        } else if ((j = band_job(q))) {
            assert(j->state == JOB_RUNNING && j->next_band < j->n_bands);
            int band = j->next_band++;
            j->bands_out++;
            q_unlock(q);
            RUN_OP(q, j, j->ops->band(j, j->work, band));
            q_lock(q);
            j->bands_out--;
            j->bands_done++;
            bool all = j->bands_done == j->n_bands || (j->cancel && j->bands_out == 0);
            if (all && !j->cancel && j->ops->next) { /* the next phase, prepared as the first was */
                j->preparing = true;
                q_unlock(q);
                int n_bands = 0, rc = 0;
                RUN_OP(q, j, rc = j->ops->next(j, j->work, &n_bands));
                q_lock(q);
                j->preparing = false;
                if (rc == 0 && n_bands > 0 && !j->cancel) {
                    j->n_bands = n_bands;
                    j->next_band = j->bands_done = 0;
                    pthread_cond_broadcast(&q->work);
                } else {
                    finish_job(q, j, j->cancel ? JOB_CANCELLED : rc ? JOB_FAILED : JOB_SUCCEEDED);
                }
            } else if (all) {
                finish_job(q, j, j->cancel ? JOB_CANCELLED : JOB_SUCCEEDED);
            }
        } else if (q->stop) {
            break;
        } else {
            q_wait(q, &q->work, NULL);
        }
    }
    q_unlock(q);
    return NULL;
}

/* Fires waiters whose deadline passed. */
static void *timer(void *arg)
{
    struct jobq *q = arg;
    q_lock(q);
    while (!q->stop) {
        double now = monotonic_s(), next = now + 0.25;
        struct waiter *due = NULL;
        for (struct waiter **p = &q->waiters; *p;) {
            struct waiter *w = *p;
            if (w->deadline <= now) {
                *p = w->next;
                w->next = due;
                due = w;
            } else {
                next = w->deadline < next ? w->deadline : next;
                p = &w->next;
            }
        }
        if (due) {
            q_unlock(q);
            fire(due, false);
            q_lock(q);
            continue;
        }
        struct timespec ts;
        clock_gettime(CLOCK_MONOTONIC, &ts);
        double wait = next - now;
        ts.tv_sec += (time_t)wait;
        ts.tv_nsec += (long)((wait - (double)(time_t)wait) * 1e9);
        if (ts.tv_nsec >= 1000000000L)
            ts.tv_sec++, ts.tv_nsec -= 1000000000L;
        q_wait(q, &q->timer_cond, &ts);
    }
    q_unlock(q);
    return NULL;
}

struct jobq *jobq_new(int n_workers, long queue_max, long long job_memory)
{
    struct jobq *q = calloc(1, sizeof *q);
    if (!q)
        return NULL;
    pthread_mutex_init(&q->lock, NULL);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&q->timer_cond, &ca);
    pthread_condattr_destroy(&ca);
    pthread_cond_init(&q->work, NULL);
    q->n_workers = n_workers < 1 ? 1 : n_workers;
    q->queue_max = queue_max;
    q->job_memory = job_memory;
    q->threads = calloc((size_t)q->n_workers, sizeof *q->threads);
    if (!q->threads) {
        free(q);
        return NULL;
    }
    for (int k = 0; k < q->n_workers; k++)
        pthread_create(&q->threads[k], NULL, worker, q);
    pthread_create(&q->timer, NULL, timer, q);
    return q;
}

/* Sleeps in 50 ms steps, the lock released, until no job is active or the deadline. Lock held. */
static void wait_idle(struct jobq *q, double deadline)
{
    HELD(q);
    while (q->n_active > 0 && monotonic_s() < deadline) {
        q_unlock(q);
        struct timespec ts = {0, 50 * 1000000L};
        nanosleep(&ts, NULL);
        q_lock(q);
    }
}

int jobq_shutdown(struct jobq *q, double timeout_s, double grace_s, void (*abandoned)(const char *id, void *arg),
                  void *arg)
{
    q_lock(q);
    q->stop_taking = true;
    wait_idle(q, monotonic_s() + timeout_s);
    for (struct job *j = q->live; j; j = j->next_live)
        if (j->state == JOB_RUNNING) {
            j->requeue = !j->cancel; /* a job its user cancelled ends cancelled, not queued again */
            j->cancel = true;
        }
    wait_idle(q, monotonic_s() + grace_s); /* bands end, prepares poll their cancel flag */
    if (q->n_active > 0) { /* deaf to cancel: the process ends with them, the store keeps them */
        for (struct job *j = q->live; j; j = j->next_live)
            if (j->state == JOB_RUNNING && abandoned)
                abandoned(j->id, arg);
        /* all the active ones, those in their finish too (an end state set, the finish - an edit's
         * compaction after its answer - still running): 0 would tell the caller to free the queue
         * under them */
        int n = q->n_active;
        q_unlock(q);
        return n;
    }
    q->stop = true;
    pthread_cond_broadcast(&q->work);
    pthread_cond_broadcast(&q->timer_cond);
    q_unlock(q);
    for (int k = 0; k < q->n_workers; k++)
        pthread_join(q->threads[k], NULL);
    pthread_join(q->timer, NULL);
    /* queued jobs stay queued in the store; their in-memory records and waiters go (under the
     * lock: the HTTP threads may still ask for them until the server stops) */
    q_lock(q);
    struct waiter *w = take_waiters(q, NULL);
    struct job *live = q->live;
    q->live = NULL;
    q_unlock(q);
    fire(w, false);
    for (struct job *j = live, *n; j; j = n) {
        n = j->next_live;
        j->ops->finish(j, j->work, JOB_CANCELLED, true);
        if (j->ops->after) /* (what it does after a requeue: nothing but free work) */
            j->ops->after(j->work);
        free(j);
    }
    return 0;
}

void jobq_free(struct jobq *q)
{
    if (!q)
        return;
    free(q->threads);
    pthread_mutex_destroy(&q->lock);
    pthread_cond_destroy(&q->work);
    pthread_cond_destroy(&q->timer_cond);
    free(q);
}

int jobq_submit(struct jobq *q, const char *id, const struct job_ops *ops, void *work, bool force)
{
    struct job *j = calloc(1, sizeof *j);
    if (!j)
        return SF_ENOMEM;
    snprintf(j->id, sizeof j->id, "%s", id);
    j->ops = ops;
    j->work = work;
    j->state = JOB_QUEUED;
    q_lock(q);
    j->mem.budget = q->job_memory;
    if ((q->n_queued >= q->queue_max && !force) || q->stop_taking) {
        q_unlock(q);
        free(j);
        return SF_ELIMIT;
    }
    if (q->queue_tail)
        q->queue_tail->next_queued = j;
    else
        q->queue_head = j;
    q->queue_tail = j;
    q->n_queued++;
    j->next_live = q->live;
    q->live = j;
    pthread_cond_signal(&q->work);
    q_unlock(q);
    return 0;
}

bool jobq_peek(struct jobq *q, const char *id, enum job_state *state, double *progress)
{
    q_lock(q);
    struct job *j = find_live(q, id);
    if (j) {
        *state = j->state == JOB_QUEUED ? JOB_QUEUED : JOB_RUNNING; /* finishing is running until stored */
        double bands = j->n_bands && !j->ops->next ? (double)j->bands_done / j->n_bands : 0.0;
        *progress = bands > j->progress ? bands : j->progress;
    }
    q_unlock(q);
    return j != NULL;
}

bool jobq_cancel(struct jobq *q, const char *id)
{
    q_lock(q);
    struct job *j = find_live(q, id);
    if (j) { /* a job finishing sees it too, through jobq_cancelled, until its end is stored */
        j->cancel = true;
        pthread_cond_broadcast(&q->work); /* someone must end it if no band is out */
    }
    q_unlock(q);
    return j != NULL;
}

void jobq_wait(struct jobq *q, const char *id, double deadline, void (*fn)(void *arg, bool finished), void *arg)
{
    struct waiter *w = malloc(sizeof *w);
    if (!w) {
        fn(arg, false); /* the caller answers 202 */
        return;
    }
    *w = (struct waiter){.fn = fn, .arg = arg, .deadline = deadline};
    snprintf(w->id, sizeof w->id, "%s", id);
    q_lock(q);
    w->next = q->waiters;
    q->waiters = w;
    pthread_cond_signal(&q->timer_cond);
    q_unlock(q);
}

void jobq_notify(struct jobq *q, const char *id)
{
    q_lock(q);
    struct waiter *w = take_waiters(q, id);
    q_unlock(q);
    fire(w, true);
}

void jobq_on_room(struct jobq *q, void (*fn)(void *), void *arg)
{
    q_lock(q);
    q->room = fn;
    q->room_arg = arg;
    q_unlock(q);
}

int jobq_room(struct jobq *q)
{
    q_lock(q);
    int n = q->stop_taking ? 0 : q->n_workers - q->n_active - (int)q->n_queued;
    q_unlock(q);
    return n > 0 ? n : 0;
}

bool jobq_cancelled(struct jobq *q, struct job *j, double progress)
{
    q_lock(q);
    if (progress > j->progress)
        j->progress = progress;
    bool cancel = j->cancel;
    q_unlock(q);
    return cancel;
}

void jobq_stats(struct jobq *q, struct jobq_stats *out)
{
    q_lock(q);
    out->queued = q->n_queued;
    out->running = q->n_active;
    out->workers = q->n_workers;
    out->queue_max = q->queue_max;
    q_unlock(q);
}
