/* guard.c - deadlines for a request's headers and body, and a reserve of connections, so that
 * clients that trickle bytes (slowloris, from one address or many) cannot hold every connection
 * libmicrohttpd has. libmicrohttpd's own timeout is an idle timeout: a byte every few seconds
 * keeps a connection forever. Written here because MHD offers no header deadline; it offers the
 * hooks: a callback as each connection starts and closes (before its socket is closed), and the
 * socket itself.
 *
 * A connection's phases, and the call that moves it:
 *
 *   (STARTED) HEADERS --guard_request_started--> BODY --guard_request_handled--> HANDLED
 *                ^                                                                  |
 *              IDLE <---------------------- guard_request_done <--------------------+
 *                  \--(its first byte is not seen: IDLE's deadline covers the next headers too)
 *
 * HEADERS (from guard_notify's STARTED) must end within header_timeout; BODY within body_timeout;
 * IDLE, a kept-alive connection between requests, within idle_timeout (the next request's headers
 * included); HANDLED has no deadline (the answer is being worked out or sent: a synchronous wait,
 * a large download). The reaper thread shuts down
 * the socket of a connection past its deadline, and libmicrohttpd then closes it. When the
 * connections reach the limit less the reserve, each new one also shuts down the oldest
 * connection in HEADERS or IDLE, so a new client (a health check, a user) always finds a slot.
 *
 * Threading: one mutex guards the table; MHD's threads and the reaper take it briefly. An entry
 * leaves the table in the CLOSED notification, which MHD makes before it closes the socket, so
 * the reaper never shuts down a descriptor that has been reused. */
#include "guard.h"

#include <pthread.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <time.h>

#include "jobq.h" /* monotonic_s */
#include "metrics.h"

enum phase { PH_HEADERS, PH_BODY, PH_HANDLED, PH_IDLE };

struct conn {
    int fd;
    enum phase phase;
    double since;            /* monotonic seconds the phase began */
    bool shut;               /* shut down already: the close is on its way */
    struct conn *prev, *next;
};

struct guard {
    pthread_mutex_t lock;
    pthread_cond_t stop_cond;
    bool stop;
    pthread_t reaper;
    struct conn *head, *tail; /* oldest first: a connection moves to the tail when its phase begins */
    long n, evict_at;
    double timeout[4];       /* by phase; PH_HANDLED's unused */
};

static void unlink_conn(struct guard *g, struct conn *c)
{
    if (c->prev)
        c->prev->next = c->next;
    else
        g->head = c->next;
    if (c->next)
        c->next->prev = c->prev;
    else
        g->tail = c->prev;
    c->prev = c->next = NULL;
}

static void append(struct guard *g, struct conn *c)
{
    c->prev = g->tail;
    c->next = NULL;
    if (g->tail)
        g->tail->next = c;
    else
        g->head = c;
    g->tail = c;
}

/* Lock held. */
static void shut(struct conn *c)
{
    if (c->shut)
        return;
    c->shut = true;
    shutdown(c->fd, SHUT_RDWR);
    metrics_connection_shut();
}

/* Lock held: a phase of a connection in the table begins now; it becomes the newest. */
static void enter(struct guard *g, struct conn *c, enum phase p)
{
    c->phase = p;
    c->since = monotonic_s();
    unlink_conn(g, c);
    append(g, c);
}

static void *reaper(void *arg)
{
    struct guard *g = arg;
    pthread_mutex_lock(&g->lock);
    while (!g->stop) {
        double now = monotonic_s();
        for (struct conn *c = g->head; c; c = c->next)
            if (c->phase != PH_HANDLED && now - c->since > g->timeout[c->phase])
                shut(c);
        struct timespec ts;
        clock_gettime(CLOCK_MONOTONIC, &ts);
        ts.tv_nsec += 250 * 1000000L;
        if (ts.tv_nsec >= 1000000000L)
            ts.tv_sec++, ts.tv_nsec -= 1000000000L;
        pthread_cond_timedwait(&g->stop_cond, &g->lock, &ts);
    }
    pthread_mutex_unlock(&g->lock);
    return NULL;
}

struct guard *guard_new(long max_connections, double header_timeout, double body_timeout, double idle_timeout)
{
    struct guard *g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    pthread_mutex_init(&g->lock, NULL);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    pthread_cond_init(&g->stop_cond, &ca);
    pthread_condattr_destroy(&ca);
    long reserve = max_connections / GUARD_RESERVE_DIVISOR;
    g->evict_at = max_connections - (reserve < 2 ? 2 : reserve);
    g->timeout[PH_HEADERS] = header_timeout;
    g->timeout[PH_BODY] = body_timeout;
    g->timeout[PH_IDLE] = idle_timeout;
    if (pthread_create(&g->reaper, NULL, reaper, g)) {
        pthread_cond_destroy(&g->stop_cond);
        pthread_mutex_destroy(&g->lock);
        free(g);
        return NULL;
    }
    return g;
}

void guard_free(struct guard *g)
{
    if (!g)
        return;
    pthread_mutex_lock(&g->lock);
    g->stop = true;
    pthread_cond_signal(&g->stop_cond);
    pthread_mutex_unlock(&g->lock);
    pthread_join(g->reaper, NULL);
    for (struct conn *c = g->head, *n; c; c = n) {
        n = c->next;
        free(c);
    }
    pthread_cond_destroy(&g->stop_cond);
    pthread_mutex_destroy(&g->lock);
    free(g);
}

void guard_notify(void *cls, struct MHD_Connection *connection, void **socket_context,
                  enum MHD_ConnectionNotificationCode code)
{
    struct guard *g = cls;
    if (code == MHD_CONNECTION_NOTIFY_STARTED) {
        const union MHD_ConnectionInfo *ci = MHD_get_connection_info(connection, MHD_CONNECTION_INFO_CONNECTION_FD);
        struct conn *c = ci ? calloc(1, sizeof *c) : NULL;
        *socket_context = c;
        if (!c)
            return; /* unguarded: MHD's own limits still hold */
        c->fd = ci->connect_fd;
        pthread_mutex_lock(&g->lock);
        if (++g->n > g->evict_at) /* into the reserve: make room by the oldest that has sent no request */
            for (struct conn *o = g->head; o; o = o->next)
                if ((o->phase == PH_HEADERS || o->phase == PH_IDLE) && !o->shut) {
                    shut(o);
                    break;
                }
        c->phase = PH_HEADERS;
        c->since = monotonic_s();
        append(g, c);
        pthread_mutex_unlock(&g->lock);
    } else if (code == MHD_CONNECTION_NOTIFY_CLOSED && *socket_context) {
        struct conn *c = *socket_context;
        pthread_mutex_lock(&g->lock);
        unlink_conn(g, c);
        g->n--;
        pthread_mutex_unlock(&g->lock);
        free(c);
        *socket_context = NULL;
    }
}

/* Moves connection's entry (if it has one) to phase p. */
static void move(struct guard *g, struct MHD_Connection *connection, enum phase p)
{
    if (!g)
        return;
    const union MHD_ConnectionInfo *ci = MHD_get_connection_info(connection, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
    struct conn *c = ci ? ci->socket_context : NULL;
    if (!c)
        return;
    pthread_mutex_lock(&g->lock);
    enter(g, c, p);
    pthread_mutex_unlock(&g->lock);
}

void guard_request_started(struct guard *g, struct MHD_Connection *c) { move(g, c, PH_BODY); }
void guard_request_handled(struct guard *g, struct MHD_Connection *c) { move(g, c, PH_HANDLED); }
void guard_request_done(struct guard *g, struct MHD_Connection *c) { move(g, c, PH_IDLE); }
