/* job_contours.c - the job kinds made of contours: volume (figures only) and model (figures, and the
 * models kept in the store). One step each (no bands). The request is read back from the store, so
 * that a job recovered after a crash computes exactly what was submitted; a model job run again
 * gives its models the same ids, replacing what the first run may have stored. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../api/model_json.h"
#include "service.h"

struct contour_work {
    struct service *svc;
    char id[40];
    bool model;
    char *json;
    char meta[128];
    struct sf_err err;
};

/* Model k of job `job`: the job's own id for the first, the job's id with k in its last four hex
 * digits for the others (an RT Structure Set's ROIs). */
static void model_id(void *ctx, int k, char id[40])
{
    const struct contour_work *w = ctx;
    if (k == 0)
        snprintf(id, 40, "%s", w->id);
    else
        snprintf(id, 40, "%.28s%04x", w->id, (unsigned)k & 0xffff);
}

static int model_put(void *ctx, const char *id, const char *name, const char *source, const char *resource)
{
    const struct contour_work *w = ctx;
    struct model_rec m = {id, w->id, name, wall_s(), source, strlen(source), resource};
    return store_model_put(w->svc->store, &m);
}

static int prepare(struct job *j, void *arg, int *n_bands)
{
    (void)j;
    struct contour_work *w = arg;
    *n_bands = 0;
    struct job_rec rec;
    if (store_get(w->svc->store, w->id, true, false, &rec) != 1)
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store"), -1;
    store_set_state(w->svc->store, w->id, "running", 0.0, wall_s(), 0, NULL);
    const char *body = (const char *)rec.request;
    int rc;
    if (w->model) {
        struct model_sink sink = {model_id, model_put, w};
        char location[64];
        rc = model_create(body, rec.request_len, rec.format, rec.options, &sink, &w->json, location, &w->err);
        snprintf(w->meta, sizeof w->meta, "{\"status\":201,\"location\":\"%s\"}", location);
    } else
        rc = model_figures(body, rec.request_len, rec.format, rec.options, &w->json, &w->err);
    store_rec_free(&rec);
    return rc ? -1 : 0;
}

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct contour_work *w = arg;
    service_job_end(w->svc, w->id, outcome, requeue, (const unsigned char *)w->json, w->json ? strlen(w->json) : 0,
                    "application/json", w->meta[0] ? w->meta : NULL, &w->err);
    free(w->json);
    free(w);
}

static const struct job_ops CONTOUR_OPS = {prepare, NULL, finish};

static int submit(struct service *svc, const char *id, bool force, bool model)
{
    struct contour_work *w = calloc(1, sizeof *w);
    if (!w)
        return -1;
    w->svc = svc;
    w->model = model;
    snprintf(w->id, sizeof w->id, "%s", id);
    if (jobq_submit(svc->q, id, &CONTOUR_OPS, w, force)) {
        free(w);
        return -1;
    }
    return 0;
}

int volume_job_submit(struct service *svc, const char *id, bool force)
{
    return submit(svc, id, force, false);
}

int model_job_submit(struct service *svc, const char *id, bool force)
{
    return submit(svc, id, force, true);
}
