/* server.h - the HTTP front end on libmicrohttpd: routes of API.md over the service. */
#ifndef SURFD_SERVER_H
#define SURFD_SERVER_H

#include <stddef.h>

#include "service.h"

struct server;

/* Starts listening per svc->cfg (address, TLS, limits). NULL on failure, with err. */
struct server *server_start(struct service *svc, struct sf_err *err);
/* The port it listens on (the one the system chose, when asked for port 0). */
unsigned short server_port(struct server *s);
/* Stops accepting new connections (draining); requests in flight go on. */
void server_quiesce(struct server *s);
void server_stop(struct server *s);

#endif
