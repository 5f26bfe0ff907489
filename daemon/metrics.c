/* metrics.c - process-wide counters and their Prometheus exposition. */
#include "metrics.h"

#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const int STATUSES[] = {200, 201, 202, 304, 400, 401, 404, 405, 409, 413, 415, 422, 429, 500, 501, 503};
#define N_STATUS (sizeof STATUSES / sizeof *STATUSES)
static atomic_long http_count[N_STATUS + 1]; /* the last: any other status */

static const double BUCKETS[] = {0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60};
#define N_BUCKETS (sizeof BUCKETS / sizeof *BUCKETS)
static atomic_long render_bucket[N_BUCKETS], render_count, rays_total;
static atomic_long render_us_total; /* microseconds, so that it stays an integer atomic */
static atomic_long jobs_ended[5];
static atomic_long http_aborted;
static atomic_long store_errors;

void metrics_store_error(void) { atomic_fetch_add(&store_errors, 1); }

static atomic_long connections_shut;
void metrics_connection_shut(void) { atomic_fetch_add(&connections_shut, 1); }

static atomic_long damaged_reads;
void metrics_store_damaged(void) { atomic_fetch_add(&damaged_reads, 1); }
static atomic_long mesh_lookups[2]; /* misses, hits */
void metrics_mesh_cache(bool hit) { atomic_fetch_add(&mesh_lookups[hit], 1); }
static atomic_long frame_lookups[2];
void metrics_frame_cache(bool hit) { atomic_fetch_add(&frame_lookups[hit], 1); }

void metrics_http(int status)
{
    if (status == 0) { /* the client left before an answer (e.g. during a synchronous wait) */
        atomic_fetch_add(&http_aborted, 1);
        return;
    }
    size_t k = 0;
    while (k < N_STATUS && STATUSES[k] != status)
        k++;
    atomic_fetch_add(&http_count[k], 1);
}

void metrics_render(double seconds, long rays)
{
    for (size_t k = 0; k < N_BUCKETS; k++)
        if (seconds <= BUCKETS[k])
            atomic_fetch_add(&render_bucket[k], 1);
    atomic_fetch_add(&render_count, 1);
    atomic_fetch_add(&render_us_total, (long)(seconds * 1e6));
    atomic_fetch_add(&rays_total, rays);
}

void metrics_job_end(enum job_state outcome) { atomic_fetch_add(&jobs_ended[outcome], 1); }

char *metrics_text(const struct metrics_gauges *g)
{
    size_t cap = 8192, n = 0;
    char *buf = malloc(cap);
    if (!buf)
        return NULL;
#define OUT(...) n += (size_t)snprintf(buf + n, n < cap ? cap - n : 0, __VA_ARGS__)
    OUT("# HELP surfd_uptime_seconds Seconds since the daemon started.\n# TYPE surfd_uptime_seconds gauge\n");
    OUT("surfd_uptime_seconds %.3f\n", g->uptime_s);
    OUT("# HELP surfd_jobs Jobs this node's pool holds now, by state.\n# TYPE surfd_jobs gauge\n");
    OUT("surfd_jobs{state=\"queued\"} %ld\nsurfd_jobs{state=\"running\"} %ld\n", g->queued, g->running);
    OUT("# HELP surfd_jobs_ended_total Jobs ended since start, by outcome.\n# TYPE surfd_jobs_ended_total counter\n");
    OUT("surfd_jobs_ended_total{state=\"succeeded\"} %ld\n", atomic_load(&jobs_ended[JOB_SUCCEEDED]));
    OUT("surfd_jobs_ended_total{state=\"failed\"} %ld\n", atomic_load(&jobs_ended[JOB_FAILED]));
    OUT("surfd_jobs_ended_total{state=\"cancelled\"} %ld\n", atomic_load(&jobs_ended[JOB_CANCELLED]));
    OUT("# HELP surfd_store_queued Jobs queued in the store, for every node that shares it.\n"
        "# TYPE surfd_store_queued gauge\nsurfd_store_queued %ld\n", g->store_queued);
    OUT("# HELP surfd_queue_depth Jobs waiting for a worker of this node.\n# TYPE surfd_queue_depth gauge\n");
    OUT("surfd_queue_depth %ld\n", g->queued);
    OUT("# HELP surfd_queue_capacity Jobs this node's queue holds at most before requests get 429.\n"
        "# TYPE surfd_queue_capacity gauge\nsurfd_queue_capacity %ld\n", g->queue_max);
    OUT("# HELP surfd_workers Worker threads of this node's pool.\n# TYPE surfd_workers gauge\nsurfd_workers %ld\n",
        g->workers);
    OUT("# HELP surfd_render_seconds Tracing and shading time of render jobs.\n# TYPE surfd_render_seconds histogram\n");
    for (size_t k = 0; k < N_BUCKETS; k++)
        OUT("surfd_render_seconds_bucket{le=\"%g\"} %ld\n", BUCKETS[k], atomic_load(&render_bucket[k]));
    OUT("surfd_render_seconds_bucket{le=\"+Inf\"} %ld\n", atomic_load(&render_count));
    OUT("surfd_render_seconds_sum %.6f\nsurfd_render_seconds_count %ld\n", atomic_load(&render_us_total) / 1e6,
        atomic_load(&render_count));
    OUT("# HELP surfd_rays_total Rays traced (primary and shadow).\n# TYPE surfd_rays_total counter\n");
    OUT("surfd_rays_total %ld\n", atomic_load(&rays_total));
    double secs = atomic_load(&render_us_total) / 1e6;
    OUT("# HELP surfd_rays_per_second Rays per second of render time, since start.\n# TYPE surfd_rays_per_second gauge\n");
    OUT("surfd_rays_per_second %.1f\n", secs > 0 ? atomic_load(&rays_total) / secs : 0.0);
    OUT("# HELP surfd_http_requests_total HTTP responses by status.\n# TYPE surfd_http_requests_total counter\n");
    for (size_t k = 0; k < N_STATUS; k++)
        OUT("surfd_http_requests_total{status=\"%d\"} %ld\n", STATUSES[k], atomic_load(&http_count[k]));
    OUT("surfd_http_requests_total{status=\"other\"} %ld\n", atomic_load(&http_count[N_STATUS]));
    OUT("# HELP surfd_http_aborted_total Requests whose client left before the answer.\n"
        "# TYPE surfd_http_aborted_total counter\nsurfd_http_aborted_total %ld\n", atomic_load(&http_aborted));
    OUT("# HELP surfd_store_errors_total Jobs whose end the store refused (each refusal).\n"
        "# TYPE surfd_store_errors_total counter\nsurfd_store_errors_total %ld\n", atomic_load(&store_errors));
    OUT("# HELP surfd_connections_shut_total Connections shut down past their header, body or idle deadline, or "
        "to make room for a new one.\n# TYPE surfd_connections_shut_total counter\nsurfd_connections_shut_total %ld\n",
        atomic_load(&connections_shut));
    OUT("# HELP surfd_mesh_cache_bytes Bytes of models' meshes the store keeps (mesh-cache bounds them).\n"
        "# TYPE surfd_mesh_cache_bytes gauge\nsurfd_mesh_cache_bytes %ld\n", g->mesh_cache_bytes);
    OUT("# HELP surfd_mesh_cache_lookups_total GETs of a model's mesh, by whether the cache had it.\n"
        "# TYPE surfd_mesh_cache_lookups_total counter\n");
    OUT("surfd_mesh_cache_lookups_total{result=\"hit\"} %ld\nsurfd_mesh_cache_lookups_total{result=\"miss\"} %ld\n",
        atomic_load(&mesh_lookups[1]), atomic_load(&mesh_lookups[0]));
    OUT("# HELP surfd_frame_cache_lookups_total Views of a stored model, by whether its prepared hierarchy was in memory.\n"
        "# TYPE surfd_frame_cache_lookups_total counter\n");
    OUT("surfd_frame_cache_lookups_total{result=\"hit\"} %ld\nsurfd_frame_cache_lookups_total{result=\"miss\"} %ld\n",
        atomic_load(&frame_lookups[1]), atomic_load(&frame_lookups[0]));
    OUT("# HELP surfd_frame_cache_bytes Bytes of stored models' prepared hierarchies kept in memory (frame-cache "
        "bounds them).\n# TYPE surfd_frame_cache_bytes gauge\nsurfd_frame_cache_bytes %zu\n", g->frame_cache_bytes);
    OUT("# HELP surfd_store_damaged_total Stored results or models refused: their checksum did not match.\n"
        "# TYPE surfd_store_damaged_total counter\nsurfd_store_damaged_total %ld\n", atomic_load(&damaged_reads));
    OUT("# HELP surfd_jobs_stranded Jobs whose end the store refused, kept to run again.\n"
        "# TYPE surfd_jobs_stranded gauge\nsurfd_jobs_stranded %d\n", g->stranded);
#undef OUT
    if (n >= cap) { /* grew past the buffer: the table is fixed, so this is a programming error */
        free(buf);
        return NULL;
    }
    return buf;
}
