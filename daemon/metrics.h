/* metrics.h - counters for GET /metrics (Prometheus text format 0.0.4). Lock-free: atomics only,
 * safe from the HTTP threads and the workers. */
#ifndef SURFD_METRICS_H
#define SURFD_METRICS_H

#include "service.h"

/* An answered request (status 0: the client left before the answer). */
void metrics_http(int status);
/* A render finished: its tracing time and rays. */
void metrics_render(double seconds, long rays);
void metrics_job_end(enum job_state outcome);
/* The connection guard shut a connection down (a deadline passed, or room for a new one). */
void metrics_connection_shut(void);
/* The store refused a job's end. */
void metrics_store_error(void);
/* A stored result or model whose bytes did not match their checksum. */
void metrics_store_damaged(void);
/* A GET of a model's mesh found it in the cache (hit) or not. */
void metrics_mesh_cache(bool hit);
/* A model's view found its prepared hierarchy in memory (hit) or built it. */
void metrics_frame_cache(bool hit);
/* The exposition text; caller frees. */
char *metrics_text(struct service *svc);

#endif
