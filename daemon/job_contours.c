/* job_contours.c - the job kinds made of contours: volume (figures only), model (figures, and the
 * models kept in the store), and what is made from a stored model: mesh and patches (GET
 * /models/{id}/mesh and /patches, which can take seconds and hundreds of megabytes: a job, so that
 * the HTTP threads never build them). One step each (no bands). The request is read back from the
 * store, so that a job recovered after a crash computes exactly what was submitted; a model job run
 * again gives its models the same ids, replacing what the first run may have stored. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "../api/iso_json.h"
#include "../api/model_json.h"
#include "../api/render_request.h"
#include "../api/rtstruct.h"
#include "log.h"
#include "kinds.h"

enum contour_kind { KIND_VOLUME, KIND_MODEL, KIND_MESH, KIND_PATCHES, KIND_RTSTRUCT };

struct contour_work {
    struct service *svc;
    struct job_claim claim;
    enum contour_kind kind;
    char *json;              /* the result (JSON, or the mesh file) */
    size_t len;
    const char *type;
    char meta[128];
    char owner[64];          /* the job's: its models are the same owner's */
    char model[64], key[96]; /* a mesh's model and cache key (model_mesh_key) */
    double tol;              /* the mesh's tolerance */
    struct sf_err err;
};

/* Model k of job `job`: the job's own id for the first, the job's id with k in its last four hex
 * digits for the others (an RT Structure Set's ROIs). */
static void model_id(void *ctx, int k, char id[40])
{
    const struct contour_work *w = ctx;
    if (k == 0)
        snprintf(id, 40, "%s", w->claim.id);
    else
        snprintf(id, 40, "%.28s%04x", w->claim.id, (unsigned)k & 0xffff);
}

static int model_put(void *ctx, const char *id, const char *name, const char *source, size_t source_len,
                     const char *resource)
{
    const struct contour_work *w = ctx;
    struct model_rec m = {id, w->claim.id, name, w->owner, wall_s(), source, source_len, resource, NULL};
    return store_model_put(w->svc->store, &m);
}

static int prepare(struct job *j, void *arg, int *n_bands)
{
    struct contour_work *w = arg;
    struct job_poll pc = {w->svc->q, j};
    const struct sf_progress pr = {service_poll_job, &pc};
    *n_bands = 0;
    struct job_rec rec;
    if (store_get(w->svc->store, w->claim.id, true, false, &rec) != 1)
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store"), -1;
    snprintf(w->owner, sizeof w->owner, "%s", rec.owner);
    const char *body = (const char *)rec.request;
    int rc;
    w->type = "application/json";
    if (w->kind == KIND_MODEL) {
        struct model_sink sink = {model_id, model_put, w};
        char location[64];
        rc = model_create(body, rec.request_len, rec.format, rec.options, &sink, &pr, &w->json, location, &w->err);
        snprintf(w->meta, sizeof w->meta, "{\"status\":201,\"location\":\"%s\"}", location);
    } else if (w->kind == KIND_VOLUME) {
        rc = model_figures(body, rec.request_len, rec.format, rec.options, &pr, &w->json, &w->err);
    } else { /* the request is the model's id */
        char model[40], *src = NULL, *resource = NULL;
        size_t n = 0;
        snprintf(model, sizeof model, "%.*s", (int)rec.request_len, body);
        if (store_model_get(w->svc->store, model, NULL, &resource, &src, &n) != 1) /* the route checked the owner */
            rc = sf_fail(&w->err, SF_EINVAL, "", "the model is no longer stored");
        else if (w->kind == KIND_RTSTRUCT) {
            rc = model_rtstruct(src, n, resource, rec.options, &pr, (unsigned char **)&w->json, &w->len, &w->err);
            w->type = "application/dicom";
            snprintf(w->meta, sizeof w->meta, "{\"filename\":\"%s.dcm\"}", model);
        } else if (w->kind == KIND_MESH)
            rc = model_mesh(src, n, resource, rec.options, &pr, &w->json, &w->len, &w->type, &w->tol, &w->err);
        else
            rc = model_patches_json(src, n, &w->json, &w->err);
        if (!rc && w->kind == KIND_MESH) { /* the file's name for the download: the model's id, the format's extension */
            const char *format;
            double tol;
            model_mesh_options(rec.options, &format, &tol, &w->err);
            model_mesh_key(rec.options, iso_model_edits(resource), w->key, sizeof w->key, &w->err);
            snprintf(w->model, sizeof w->model, "%s", model);
            const char *ext = strcmp(format, "dicom-stl") ? format : "dcm";
            if (w->tol > 0)
                snprintf(w->meta, sizeof w->meta, "{\"filename\":\"%s.%s\",\"tolerance_mm\":%.6g}", model, ext, w->tol);
            else
                snprintf(w->meta, sizeof w->meta, "{\"filename\":\"%s.%s\"}", model, ext);
        }
        free(src);
        free(resource);
    }
    if (!rc && w->kind != KIND_MESH && w->kind != KIND_RTSTRUCT)
        w->len = strlen(w->json);
    store_rec_free(&rec);
    return rc ? -1 : 0;
}

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct contour_work *w = arg;
    if (outcome == JOB_SUCCEEDED && w->kind == KIND_MESH && w->key[0] && w->svc->cfg.mesh_cache > 0) {
        struct mesh_rec m = {(char *)w->type, w->meta, (unsigned char *)w->json, w->len, ""};
        if (store_mesh_put(w->svc->store, w->model, w->key, &m, w->svc->cfg.mesh_cache) < 0)
            LOG(LOG_WARN, "model %s: its mesh (%s) could not be cached", w->model, w->key); /* made again next time */
    }
    service_job_end(w->svc, &w->claim, outcome, requeue, (const unsigned char *)w->json, w->json ? w->len : 0,
                    w->type ? w->type : "application/json", w->meta[0] ? w->meta : NULL, &w->err);
    free(w->json);
    free(w);
}

static const struct job_ops CONTOUR_OPS = {.prepare = prepare, .finish = finish};

static int start(struct service *svc, const struct job_claim *c, enum contour_kind kind)
{
    struct contour_work *w = calloc(1, sizeof *w);
    if (!w)
        return -1;
    w->svc = svc;
    w->kind = kind;
    w->claim = *c;
    if (jobq_submit(svc->q, c->id, &CONTOUR_OPS, w, true)) {
        free(w);
        return -1;
    }
    return 0;
}

int volume_start(struct service *svc, const struct job_claim *c) { return start(svc, c, KIND_VOLUME); }
int model_start(struct service *svc, const struct job_claim *c) { return start(svc, c, KIND_MODEL); }
int mesh_start(struct service *svc, const struct job_claim *c) { return start(svc, c, KIND_MESH); }
int patches_start(struct service *svc, const struct job_claim *c) { return start(svc, c, KIND_PATCHES); }
int rtstruct_start(struct service *svc, const struct job_claim *c) { return start(svc, c, KIND_RTSTRUCT); }

/* ---- the requests: contour JSON or an RT Structure Set (both kinds); /volume also measures a
 * scene (JSON, .bpt, VRML) whose patches bound a closed solid ---- */

const char *contour_format(const char *content_type)
{
    const char *f = volume_format(content_type);
    return f && (!strcmp(f, "json") || !strcmp(f, "dicom")) ? f : NULL;
}

const char *volume_format(const char *content_type)
{
    if (content_type && !strncasecmp(content_type, "application/dicom", 17))
        return "dicom";
    const char *f = render_format_from_type(content_type);
    return f && !*f ? "json" : f;
}

/* An RT Structure Set is stored without the patient: only what the job reads. */
static int validate(struct job_body *b, bool scenes, struct sf_err *err)
{
    const char *body = b->body ? b->body : "";
    if (!scenes && model_body_is_scene(body, b->len, b->format))
        return sf_fail(err, SF_EINVAL, "/slices", "a model is built from slice contours; POST /volume measures a scene");
    if (model_validate(body, b->len, b->format, b->options, err))
        return err->code;
    if (strcmp(b->format, "dicom"))
        return 0;
    unsigned char *kept;
    size_t n;
    if (rtstruct_strip(b->body, b->len, &kept, &n, err))
        return err->code;
    free(b->body);
    b->body = (char *)kept;
    b->len = n;
    return 0;
}

int volume_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    (void)svc;
    /* ?format= names it: an RT Structure Set, or a scene by any name /render takes (scene_text.c's table) */
    if (strcmp(b->format, "dicom") && scene_format_parse(b->format) == (enum scene_format)-1)
        return sf_fail(err, SF_EFORMAT, "?format", "format is json, dicom, bpt, nurbs (vrml, wrl) or iges (igs), not \"%s\"",
                       b->format);
    return validate(b, true, err);
}

int model_validate_body(struct service *svc, struct job_body *b, struct sf_err *err)
{
    (void)svc;
    return validate(b, false, err);
}

int mesh_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    (void)svc;
    const char *format;
    double tol;
    return model_mesh_options(b->options, &format, &tol, err);
}

int rtstruct_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    (void)svc;
    double spacing;
    return model_rtstruct_options(b->options, &spacing, err);
}

int patches_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    (void)svc;
    (void)b;
    (void)err;
    return 0;
}
