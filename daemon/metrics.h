/* metrics.h - counters for GET /metrics (Prometheus text format 0.0.4). Lock-free: atomics only,
 * safe from the HTTP threads and the workers. A leaf: the parts it counts call it, and what is a
 * gauge of another part (the queue, the store, the caches) is handed to metrics_text by its caller. */
#ifndef SURFD_METRICS_H
#define SURFD_METRICS_H

#include <stdbool.h>
#include <stddef.h>

#include "job_state.h"

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
/* The gauges of the other parts at the moment of a scrape. */
struct metrics_gauges {
    double uptime_s;
    long queued, running;    /* this node's pool */
    long queue_max, workers;
    long store_queued;       /* every node's; -1 when the store failed (as mesh_cache_bytes) */
    long mesh_cache_bytes;
    size_t frame_cache_bytes;
    int stranded;
};
/* The exposition text; caller frees. */
char *metrics_text(const struct metrics_gauges *g);

#endif
