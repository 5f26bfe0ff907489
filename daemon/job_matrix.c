/* job_matrix.c - the matrix job kind (POST /matrix-model): a volume in any form /isosurface takes
 * (samples >= ?iso are the body; an FRep object: f >= 0) to its six relief matrices (seed 003),
 * with exact: whether the matrices give the voxels back (a body with cavities or hidden
 * concavities is answered anyway, exact false). A volume is one step: reading it and scanning its
 * lines are both a pass over the samples. A stored model (?model=ID&size=N,M,K, no body) is
 * traced: its frame's hierarchy (the exact tracer for patches, Embree for meshes) along the
 * lines of voxel centres, a band of z rows each (core/matrix/rays.h), the matrices of those
 * voxels at the end. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include "../api/matrix_json.h"
#include "../api/query.h"
#include "../api/scene_io.h"
#include "../api/volume_io.h"
#include "../core/matrix/rays.h"
#include "../core/trace/render.h"
#include "kinds.h"
#include "volumes.h"

/* Voxels along the longest side of a model's box when ?size is not given (cubic voxels). */
#define MATRIX_RAYS_DEFAULT_SIDE 128
#define MATRIX_RAYS_BANDS 64

struct matrix_work {
    struct job_work job;     /* first: job_start fills it */
    char *json;
    struct sf_err err;
    /* a stored model's: */
    char model[64];
    struct scene sc;
    bool have_scene;
    struct frame *fr;
    int n[3], n_bands;
    double lo[3], hi[3];
    uint8_t *vox;
};

/* ?size=N,M,K into n: 0, or SF_EINVAL / SF_ELIMIT at ?size; all zero when absent. */
static int size_option(const char *options, int n[3], struct sf_err *err)
{
    char v[64];
    query_option(options, "size", v, sizeof v);
    n[0] = n[1] = n[2] = 0;
    if (!v[0])
        return 0;
    char *p = v, *end;
    for (int k = 0; k < 3; k++, p = end + 1) {
        long x = strtol(p, &end, 10);
        if (end == p || *end != (k < 2 ? ',' : '\0') || x < 1 || x > MATRIX_MAX_SIDE)
            return sf_fail(err, SF_EINVAL, "?size", "size is N,M,K: voxels along x, y, z, each 1..%d", MATRIX_MAX_SIDE);
        n[k] = (int)x;
    }
    if ((double)n[0] * n[1] * n[2] > MATRIX_JSON_MAX_VOXELS)
        return sf_fail(err, SF_ELIMIT, "?size", "%d x %d x %d voxels is over the cap of %u", n[0], n[1], n[2],
                       MATRIX_JSON_MAX_VOXELS);
    return 0;
}

/* The scene of stored model id alone (the route or validate checked the owner's models). */
static int model_scene(struct service *svc, const char *owner, const char *id, struct scene *sc, struct sf_err *err)
{
    char body[160];
    snprintf(body, sizeof body, "{\"objects\":[{\"type\":\"model\",\"id\":\"%s\"}]}", id);
    struct model_scope scope = {svc, owner};
    struct model_resolver models = service_models(&scope);
    enum image_format img;
    int rc = scene_parse_models(body, strlen(body), SCENE_JSON, &models, sc, &img, err);
    if (rc && !strcmp(err->pointer, "/objects/0/id")) /* the query's, not a scene's */
        snprintf(err->pointer, sizeof err->pointer, "?model");
    return rc;
}

static int prepare_model(struct matrix_work *w, const char *options, int *n_bands)
{
    query_option(options, "model", w->model, sizeof w->model);
    int rc;
    if ((rc = size_option(options, w->n, &w->err)) || (rc = model_scene(w->job.svc, NULL, w->model, &w->sc, &w->err)))
        return rc;
    w->have_scene = true;
    w->sc.width = w->sc.height = 1; /* no picture: the hierarchy alone */
    w->sc.srgb8_only = true;
    if ((rc = frame_prepare(&w->sc, w->job.svc->dev, &w->fr, &w->err)))
        return rc;
    frame_bounds(w->fr, w->lo, w->hi);
    if (!w->n[0]) { /* cubic voxels, the longest side MATRIX_RAYS_DEFAULT_SIDE */
        double side = fmax(w->hi[0] - w->lo[0], fmax(w->hi[1] - w->lo[1], w->hi[2] - w->lo[2]));
        for (int k = 0; k < 3; k++)
            w->n[k] = (int)fmax(1.0, ceil(MATRIX_RAYS_DEFAULT_SIDE * (w->hi[k] - w->lo[k]) / side - 1e-9));
    }
    if (!(w->vox = malloc((size_t)w->n[0] * w->n[1] * w->n[2])))
        return sf_fail(&w->err, SF_ENOMEM, "", "out of memory for %d x %d x %d voxels", w->n[0], w->n[1], w->n[2]);
    *n_bands = w->n_bands = w->n[2] < MATRIX_RAYS_BANDS ? w->n[2] : MATRIX_RAYS_BANDS;
    return 0;
}

static void band(struct job *j, void *arg, int k)
{
    (void)j;
    struct matrix_work *w = arg;
    int z0 = (int)((long)k * w->n[2] / w->n_bands), z1 = (int)((long)(k + 1) * w->n[2] / w->n_bands);
    matrix_rays_slab(frame_hierarchy(w->fr), w->n, w->lo, w->hi, z0, z1, w->vox);
}

static int prepare(struct job *j, void *arg, int *n_bands)
{
    struct matrix_work *w = arg;
    struct job_poll pc = {w->job.svc->q, j};
    const struct sf_progress pr = {service_poll_cancel, &pc};
    *n_bands = 0;
    struct job_rec rec;
    char file[1100] = "";
    void *map = NULL;
    size_t map_len = 0;
    if (store_get(w->job.svc->store, w->job.claim.id, true, false, &rec))
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store");
    const char *body = (const char *)rec.request;
    size_t len = rec.request_len;
    int rc = 0;
    char model[64];
    query_option(rec.options, "model", model, sizeof model);
    if (model[0]) {
        rc = prepare_model(w, rec.options, n_bands);
        store_rec_free(&rec);
        return rc;
    }
    if (rec.request_file) {
        if (store_request_file(w->job.svc->store, w->job.claim.id, file, sizeof file) || job_map_file(file, &map, &map_len))
            rc = sf_fail(&w->err, SF_EIO, "", "the job's volume could not be read from the store");
        body = map ? map : "", len = map_len;
    }
    struct volume v = {0};
    if (!rc)
        rc = volume_read(body, len, rec.format, rec.options, &v, &w->err);
    if (!rc && v.frep)
        rc = frep_volumes(w->job.svc, v.frep, &w->err);
    if (!rc && v.frep)
        rc = volume_sample(&v, 0, v.g.nz, &pr, &w->err);
    if (!rc && !(w->json = matrix_json_of_volume(&v, &w->err)))
        rc = w->err.code;
    volume_free(&v);
    if (map)
        munmap(map, map_len);
    if (file[0])
        store_request_file_done(w->job.svc->store, file);
    store_rec_free(&rec);
    return rc;
}

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct matrix_work *w = arg;
    if (outcome == JOB_SUCCEEDED && w->vox && !(w->json = matrix_json_of_voxels(w->model, w->n, w->lo, w->hi, w->vox, &w->err)))
        outcome = JOB_FAILED;
    service_job_end(w->job.svc, &w->job.claim, outcome, requeue, (const unsigned char *)w->json, w->json ? strlen(w->json) : 0,
                    "application/json", NULL, &w->err);
    free(w->json);
    free(w->vox);
    frame_free(w->fr);
    if (w->have_scene)
        scene_free(&w->sc);
    free(w);
}

static const struct job_ops MATRIX_OPS = {.prepare = prepare, .band = band, .finish = finish};


static int matrix_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    char id[64];
    query_option(b->options, "model", id, sizeof id);
    char labels[8];
    query_option(b->options, "labels", labels, sizeof labels);
    if (!id[0] && labels[0]) /* (?label=N: its mask's matrices) */
        return sf_fail(err, SF_EINVAL, "?labels", "a matrix model is of one body: labels=all is for POST /isosurface "
                       "(label=N gives one label's matrices)");
    if (!id[0])
        return isosurface_kind.validate(svc, b, err);
    if (b->len)
        return sf_fail(err, SF_EINVAL, "", "a stored model's matrices (?model) take no body");
    int n[3], rc;
    struct scene sc;
    if ((rc = size_option(b->options, n, err)) || (rc = model_scene(svc, b->owner, id, &sc, err)))
        return rc;
    scene_free(&sc);
    return 0;
}

/* The isosurface kind's requests (a volume, or an FRep object), or a stored model by ?model. */
const struct job_kind matrix_kind = {
    .name = "matrix", .format = volume_format_from_type, .route = IN_MATRIX, .format_in_query = true, .validate = matrix_validate,
    .ops = &MATRIX_OPS, .work_size = sizeof(struct matrix_work), .result = "application/json", .streamed = true};
