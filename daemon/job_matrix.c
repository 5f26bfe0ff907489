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
    const struct iso_grid *g = &v.g;
    size_t n = rc ? 0 : (size_t)g->nx * g->ny * g->nz;
    uint8_t *vox = rc ? NULL : malloc(n ? n : 1);
    float *row = rc ? NULL : malloc(sizeof *row * (size_t)g->nx);
    if (!rc && (!vox || !row))
        rc = sf_fail(&w->err, SF_ENOMEM, "", "out of memory for the voxels");
    if (!rc && (g->nx > MATRIX_MAX_SIDE || g->ny > MATRIX_MAX_SIDE || g->nz > MATRIX_MAX_SIDE || n > MATRIX_JSON_MAX_VOXELS))
        rc = sf_fail(&w->err, SF_ELIMIT, "?dims", "a matrix model has at most %d voxels a side and %u in all",
                     MATRIX_MAX_SIDE, MATRIX_JSON_MAX_VOXELS);
    if (!rc) {
        if (v.frep)
            volume_sample(&v, 0, g->nz);
        for (int z = 0; z < g->nz; z++)
            for (int y = 0; y < g->ny; y++) {
                iso_grid_row(g, y, z, row);
                for (int x = 0; x < g->nx; x++) /* samples >= iso are the body */
                    vox[(size_t)x + (size_t)g->nx * ((size_t)y + (size_t)g->ny * z)] = row[x] >= v.iso;
            }
        int dims[3] = {g->nx, g->ny, g->nz};
        double lo[3], hi[3];
        for (int a = 0; a < 3; a++) /* each voxel centred on its sample */
            lo[a] = g->origin[a] - g->spacing[a] / 2, hi[a] = lo[a] + g->spacing[a] * dims[a];
        if (!(w->json = matrix_json_of_voxels(v.name, dims, lo, hi, vox, &w->err)))
            rc = w->err.code;
    }
    free(vox);
    free(row);
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
