/* guard.h - deadlines for a request's headers and body and a reserve of connections, over
 * libmicrohttpd's connection notifications (guard.c has the phases and why). One per server. */
#ifndef SURFD_GUARD_H
#define SURFD_GUARD_H

#include <stdbool.h>
#include <sys/socket.h>
#include <microhttpd.h>

/* One connection in this many of max-connections is kept for new clients: past the rest, each new
 * connection shuts down the oldest that is waiting for a request. */
#define GUARD_RESERVE_DIVISOR 16

struct guard;

/* Starts the reaper thread. Seconds: headers (from the connection's start), body (from the end of
 * the headers), idle (a kept-alive connection until its next request's headers are in). NULL
 * when out of resources. guard_free(NULL) is a no-op. */
struct guard *guard_new(long max_connections, double header_timeout, double body_timeout, double idle_timeout);
void guard_free(struct guard *g);

/* libmicrohttpd's MHD_OPTION_NOTIFY_CONNECTION callback; cls is the guard. It owns the socket
 * context: nothing else may set it. */
void guard_notify(void *cls, struct MHD_Connection *connection, void **socket_context,
                  enum MHD_ConnectionNotificationCode code);
/* From the request handler: its headers are in (first call); its body is in and it is being
 * answered (the route runs); from the completion callback: answered. g may be NULL. */
void guard_request_started(struct guard *g, struct MHD_Connection *c);
void guard_request_handled(struct guard *g, struct MHD_Connection *c);
void guard_request_done(struct guard *g, struct MHD_Connection *c);

#endif
