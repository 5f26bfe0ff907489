/* job_matrix.c - the matrix job kind (POST /matrix-model): a volume in any form /isosurface takes
 * (samples >= ?iso are the body; an FRep object: f >= 0) to its six relief matrices (seed 003),
 * with exact: whether the matrices give the voxels back (a body with cavities or hidden
 * concavities is answered anyway, exact false). One step: reading the volume and scanning its
 * lines are both a pass over the samples. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "../api/matrix_json.h"
#include "../api/volume_io.h"
#include "kinds.h"

struct matrix_work {
    struct service *svc;
    struct job_claim claim;
    char *json;
    struct sf_err err;
};

static int prepare(struct job *j, void *arg, int *n_bands)
{
    (void)j;
    struct matrix_work *w = arg;
    *n_bands = 0;
    struct job_rec rec;
    char file[1100] = "";
    void *map = NULL;
    size_t map_len = 0;
    if (store_get(w->svc->store, w->claim.id, true, false, &rec) != 1)
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store"), -1;
    const char *body = (const char *)rec.request;
    size_t len = rec.request_len;
    int rc = 0;
    if (rec.request_file) {
        if (store_request_file(w->svc->store, w->claim.id, file, sizeof file) != 1 || job_map_file(file, &map, &map_len))
            rc = sf_fail(&w->err, SF_EIO, "", "the job's volume could not be read from the store");
        body = map ? map : "", len = map_len;
    }
    struct volume v = {0};
    if (!rc)
        rc = volume_read(body, len, rec.format, rec.options, &v, &w->err);
    if (!rc && v.frep)
        rc = frep_volumes(w->svc, v.frep, &w->err);
    if (!rc && v.frep)
        volume_sample(&v, 0, v.g.nz);
    if (!rc && !(w->json = matrix_json_of_volume(&v, &w->err)))
        rc = w->err.code;
    volume_free(&v);
    if (map)
        munmap(map, map_len);
    if (file[0])
        store_request_file_done(w->svc->store, file);
    store_rec_free(&rec);
    return rc ? -1 : 0;
}

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct matrix_work *w = arg;
    service_job_end(w->svc, &w->claim, outcome, requeue, (const unsigned char *)w->json, w->json ? strlen(w->json) : 0,
                    "application/json", NULL, &w->err);
    free(w->json);
    free(w);
}

static const struct job_ops MATRIX_OPS = {.prepare = prepare, .finish = finish};

int matrix_start(struct service *svc, const struct job_claim *c)
{
    struct matrix_work *w = calloc(1, sizeof *w);
    if (!w)
        return -1;
    w->svc = svc;
    w->claim = *c;
    if (jobq_submit(svc->q, c->id, &MATRIX_OPS, w, true)) {
        free(w);
        return -1;
    }
    return 0;
}

int matrix_validate(struct service *svc, struct job_body *b, struct sf_err *err) { return iso_validate(svc, b, err); }
