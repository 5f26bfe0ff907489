/* keeper.h - the node's keeper thread: claims, starts, heartbeats, reaps (keeper.c). */
#ifndef SURFD_KEEPER_H
#define SURFD_KEEPER_H

#include "service.h"

/* Starts the keeper (after the pool and the store are open). 0, or SF_ENOMEM (no thread). */
int keeper_start(struct service *svc);
/* Stops the keeper: no more claims, heartbeats or reaps. */
void keeper_stop(struct service *svc);
/* Runs the stranded jobs whose delay has passed (the daemon's main loop calls it). */
void keeper_retry_stranded(struct service *svc);

#endif
