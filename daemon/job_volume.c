/* job_volume.c - the volume job kind: one step (no bands). Rebuilds the model from the stored
 * contours, so that a job recovered after a crash computes exactly what was submitted. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../api/model_json.h"
#include "service.h"

struct volume_work {
    struct service *svc;
    char id[40];
    char *json;
    struct sf_err err;
};

static int prepare(struct job *j, void *arg, int *n_bands)
{
    (void)j;
    struct volume_work *w = arg;
    *n_bands = 0;
    struct job_rec rec;
    if (store_get(w->svc->store, w->id, true, false, &rec) != 1)
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store"), -1;
    store_set_state(w->svc->store, w->id, "running", 0.0, wall_s(), 0, NULL);
    int rc = model_figures((const char *)rec.request, rec.request_len, rec.format, rec.options, &w->json, &w->err);
    store_rec_free(&rec);
    return rc ? -1 : 0;
}

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct volume_work *w = arg;
    service_job_end(w->svc, w->id, outcome, requeue, (const unsigned char *)w->json, w->json ? strlen(w->json) : 0,
                    "application/json", NULL, &w->err);
    free(w->json);
    free(w);
}

static const struct job_ops VOLUME_OPS = {prepare, NULL, finish};

int volume_job_submit(struct service *svc, const char *id, bool force)
{
    struct volume_work *w = calloc(1, sizeof *w);
    if (!w)
        return -1;
    w->svc = svc;
    snprintf(w->id, sizeof w->id, "%s", id);
    if (jobq_submit(svc->q, id, &VOLUME_OPS, w, force)) {
        free(w);
        return -1;
    }
    return 0;
}
