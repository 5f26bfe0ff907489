/* service.c - small helpers every part of the daemon uses. */
#include "service.h"

#include <stdlib.h>

#include "../api/problem.h"
#include "log.h"
#include "metrics.h"

#include <fcntl.h>
#include <stdio.h>
#include <sys/random.h>
#include <time.h>

double wall_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return ts.tv_sec + ts.tv_nsec / 1e9;
}

void service_new_id(char out[40])
{
    unsigned char b[16] = {0};
    if (getrandom(b, sizeof b, 0) != (ssize_t)sizeof b) { /* never on Linux >= 3.17; still unique enough */
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        for (size_t k = 0; k < sizeof b; k++)
            b[k] ^= (unsigned char)((ts.tv_nsec >> (k % 4 * 8)) + k * 131);
    }
    for (size_t k = 0; k < sizeof b; k++)
        snprintf(out + 2 * k, 3, "%02x", b[k]);
}

void service_job_end(struct service *svc, const char *id, enum job_state outcome, bool requeue,
                     const unsigned char *result, size_t len, const char *type, const char *meta,
                     const struct sf_err *err)
{
    if (outcome == JOB_SUCCEEDED) {
        if (store_set_result(svc->store, id, result, len, type, meta, wall_s()))
            LOG(LOG_ERROR, "job %s: could not store its result", id);
    } else if (outcome == JOB_FAILED) {
        char *p = problem_from_err(err);
        store_set_state(svc->store, id, "failed", 0.0, 0, wall_s(), p);
        LOG(LOG_WARN, "job %s failed: %s", id, err->message);
        free(p);
    } else if (requeue) { /* shutdown: leave it to the next start */
        store_requeue(svc->store, id);
    } else {
        store_set_state(svc->store, id, "cancelled", 0.0, 0, wall_s(), NULL);
    }
    if (!requeue)
        metrics_job_end(outcome);
}

static int model_source(void *ctx, const char *id, char **src, size_t *len)
{
    struct service *svc = ctx;
    return store_model_get(svc->store, id, NULL, src, len);
}

struct model_resolver service_models(struct service *svc)
{
    return (struct model_resolver){model_source, svc};
}
