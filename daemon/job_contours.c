/* job_contours.c - the job kinds made of contours: volume (figures only), model (figures, and the
 * models kept in the store), and what is made from a stored model: mesh, patches and rtstruct
 * (GET /models/{id}/mesh, /patches and /rtstruct, which can take seconds and hundreds of megabytes: a job, so that
 * the HTTP threads never build them). One step each (no bands). The request is read back from the
 * store, so that a job recovered after a crash computes exactly what was submitted; a model job run
 * again gives its models the same ids, replacing what the first run may have stored. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <jansson.h>
#include <unistd.h>

#include "../api/dicom_instance.h"
#include "../api/iso_json.h"
#include "../api/model_json.h"
#include "../api/render_request.h"
#include "../api/query.h"
#include "../api/rtstruct.h"
#include "kinds.h"
#include "log.h"
#include "pacs.h"

struct contour_work {
    struct job_work job;     /* first: job_start fills it */
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
        snprintf(id, 40, "%s", w->job.claim.id);
    else
        snprintf(id, 40, "%.28s%04x", w->job.claim.id, (unsigned)k & 0xffff);
}

static int model_put(void *ctx, const char *id, const char *name, const char *source, size_t source_len,
                     const char *resource)
{
    const struct contour_work *w = ctx;
    struct model_rec m = {id, w->job.claim.id, name, w->owner, wall_s(), source, source_len, resource, NULL, 1};
    return store_model_put(w->job.svc->store, &m);
}

/* What every kind here does first: read the job's request (its record, the owner kept) and make
 * the poll; then make its result (w->json, w->len) from the request. */
static int prepare_with(struct job *j, struct contour_work *w, int *n_bands,
                        int (*make)(struct contour_work *w, const struct job_rec *rec, const struct sf_progress *pr))
{
    struct job_poll pc = {w->job.svc->q, j};
    const struct sf_progress pr = {service_poll_job, &pc};
    *n_bands = 0;
    struct job_rec rec;
    if (store_get(w->job.svc->store, w->job.claim.id, true, false, &rec))
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store");
    snprintf(w->owner, sizeof w->owner, "%s", rec.owner);
    w->type = "application/json";
    int rc = make(w, &rec, &pr);
    store_rec_free(&rec);
    return rc;
}

static int make_model(struct contour_work *w, const struct job_rec *rec, const struct sf_progress *pr)
{
    struct model_sink sink = {model_id, model_put, w};
    char location[64] = "";
    int rc = model_create((const char *)rec->request, rec->request_len, rec->format, rec->options, &sink, pr, &w->json,
                          location, &w->err);
    snprintf(w->meta, sizeof w->meta, "{\"status\":201,\"location\":\"%s\"}", location);
    w->len = rc ? 0 : strlen(w->json);
    return rc;
}

static int make_figures(struct contour_work *w, const struct job_rec *rec, const struct sf_progress *pr)
{
    int rc = model_figures((const char *)rec->request, rec->request_len, rec->format, rec->options, pr, &w->json, &w->err);
    w->len = rc ? 0 : strlen(w->json);
    return rc;
}

/* The stored model a request names (its id: the route checked its owner): its source and
 * resource (the caller frees), and its id into w->model. 0 or SF_EINVAL. */
static int stored_model(struct contour_work *w, const struct job_rec *rec, char **src, size_t *n, char **resource)
{
    snprintf(w->model, sizeof w->model, "%.*s", (int)rec->request_len, (const char *)rec->request);
    *src = NULL, *resource = NULL, *n = 0;
    if (store_model_get(w->job.svc->store, w->model, NULL, resource, src, n))
        return sf_fail(&w->err, SF_EINVAL, "", "the model is no longer stored");
    return 0;
}

/* ---- DICOM SEG out (?format=seg on /rtstruct and /models/{id}/mesh, as=seg on send) ---- */

struct instances {
    char **sop, **meta;
    int n, cap;
    bool failed;
};

static void add_instance(const char *sop_uid, const char *meta, const void *data, size_t len, void *arg)
{
    (void)data, (void)len;
    struct instances *in = arg;
    if (in->failed)
        return;
    if (in->n == in->cap) {
        int cap = in->cap ? 2 * in->cap : 64;
        char **s = realloc(in->sop, sizeof *s * (size_t)cap), **m = s ? realloc(in->meta, sizeof *m * (size_t)cap) : NULL;
        if (s)
            in->sop = s;
        if (m)
            in->meta = m;
        if (!s || !m) {
            in->failed = true;
            return;
        }
        in->cap = cap;
    }
    in->sop[in->n] = strdup(sop_uid);
    in->meta[in->n] = strdup(meta ? meta : "{}");
    in->failed = !in->sop[in->n] || !in->meta[in->n];
    in->n++;
}

/* The grid a SEG of these models is made on (model_seg_grid): the first stored series one of them
 * names (their CT, or the series an isosurface was made of) read from the store's instance rows,
 * their pixels never read. g: the caller frees with seg_grid_free. */
static int seg_grid_of(struct service *svc, const char *const *ids, const char *const *resources, int n,
                       const char *options, struct seg_grid *g, struct sf_err *err)
{
    struct seg_grid ct = {0};
    bool stored = false;
    int rc = 0;
    for (int k = 0; !rc && !stored && k < n; k++) {
        char uid[65];
        struct series_rec sr;
        if (!model_seg_series(resources[k], uid) || store_series_get(svc->store, uid, NULL, &sr))
            continue;
        struct instances in = {0};
        int got = store_series_instances(svc->store, uid, false, add_instance, &in);
        if (got || in.failed)
            rc = sf_fail(err, got ? got : SF_ENOMEM, "", got ? "the stored series %.64s could not be read" : "out of memory",
                         uid);
        else
            rc = model_seg_series_grid(uid, sr.study_uid, (const char *const *)in.sop, (const char *const *)in.meta,
                                       in.n, &ct, err);
        stored = !rc;
        for (int i = 0; i < in.n; i++)
            free(in.sop[i]), free(in.meta[i]);
        free(in.sop);
        free(in.meta);
    }
    if (!rc)
        rc = model_seg_grid(ids, resources, n, stored ? &ct : NULL, options, g, err);
    seg_grid_free(&ct);
    return rc;
}

/* The models of an export's request ("ID,ID,..."), each id into ids[k] and its source and
 * resource from the store (the caller frees m[k].src and .resource, then m and ids). */
static int export_models(struct contour_work *w, const char *list, size_t len, struct model_export **out,
                         char (**out_ids)[40], int *n_out)
{
    const char *end = list + len;
    int n = 1, rc = 0;
    for (const char *c = list; c < end; c++)
        n += *c == ',';
    struct model_export *m = calloc((size_t)n, sizeof *m);
    char(*ids)[40] = calloc((size_t)n, sizeof *ids);
    if (!m || !ids)
        rc = sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
    for (int k = 0; !rc && k < n; k++) {
        const char *comma = memchr(list, ',', (size_t)(end - list));
        size_t l = (size_t)((comma ? comma : end) - list);
        snprintf(ids[k], sizeof ids[k], "%.*s", (int)(l < 39 ? l : 39), list);
        list += l + (comma != NULL);
        m[k].id = ids[k];
        if (store_model_get(w->job.svc->store, ids[k], NULL, (char **)&m[k].resource, (char **)&m[k].src, &m[k].len))
            rc = sf_fail(&w->err, SF_EINVAL, n > 1 ? "?models" : "", "model %s is no longer stored", ids[k]);
    }
    *out = m, *out_ids = ids, *n_out = n;
    return rc;
}

static void export_models_free(struct model_export *m, char (*ids)[40], int n)
{
    for (int k = 0; m && k < n; k++) {
        free((char *)m[k].src);
        free((char *)m[k].resource);
    }
    free(m);
    free(ids);
}

/* The models a request lists as one DICOM Segmentation, a segment each, on the grid seg_grid_of
 * chooses; named after its one model or its job, the grid's source in the meta (X-Seg-Grid). */
static int make_seg(struct contour_work *w, const struct job_rec *rec, const struct sf_progress *pr)
{
    struct model_export *m = NULL;
    char(*ids)[40] = NULL;
    int n = 0;
    int rc = export_models(w, (const char *)rec->request, rec->request_len, &m, &ids, &n);
    struct seg_grid g = {0};
    const char **id_of = rc ? NULL : calloc((size_t)n, sizeof *id_of), **res = rc ? NULL : calloc((size_t)n, sizeof *res);
    if (!rc && (!id_of || !res))
        rc = sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
    for (int k = 0; !rc && k < n; k++)
        id_of[k] = ids[k], res[k] = m[k].resource;
    if (!rc)
        rc = seg_grid_of(w->job.svc, id_of, res, n, rec->options, &g, &w->err);
    if (!rc)
        rc = model_seg_set(m, n, &g, pr, (unsigned char **)&w->json, &w->len, &w->err);
    w->type = "application/dicom";
    snprintf(w->model, sizeof w->model, "%s", n == 1 && ids ? ids[0] : w->job.claim.id);
    snprintf(w->meta, sizeof w->meta, "{\"filename\":\"%s.dcm\",\"seg_grid\":\"%s\"}", w->model,
             g.source ? g.source : "");
    seg_grid_free(&g);
    free(id_of);
    free(res);
    export_models_free(m, ids, n);
    return rc;
}

/* Whether an export's options ask for a SEG: ?format=seg (rtstruct, the default, else refused) */
static bool export_is_seg(const char *options) { char f[16]; query_option(options, "format", f, sizeof f); return !strcmp(f, "seg"); }

/* What an export of the listed models (list, len: "ID,ID,...") would refuse before any work: its
 * format, and for a SEG its grid and the grid's cap (seg_grid_of, on the checks pool: the store's
 * rows alone). */
static int export_validate(struct service *svc, const char *list, size_t len, const char *options, struct sf_err *err)
{
    char f[16];
    query_option(options, "format", f, sizeof f);
    if (f[0] && strcmp(f, "rtstruct") && strcmp(f, "seg"))
        return sf_fail(err, SF_EINVAL, "?format", "format is rtstruct (an RT Structure Set, the default) or seg (a "
                       "DICOM Segmentation)");
    if (strcmp(f, "seg")) {
        double spacing;
        return model_rtstruct_options(options, &spacing, err);
    }
    struct contour_work w = {.job.svc = svc};
    struct model_export *m = NULL;
    char(*ids)[40] = NULL;
    int n = 0;
    int rc = export_models(&w, list, len, &m, &ids, &n);
    const char **id_of = rc ? NULL : calloc((size_t)n, sizeof *id_of), **res = rc ? NULL : calloc((size_t)n, sizeof *res);
    if (!rc && (!id_of || !res))
        rc = sf_fail(&w.err, SF_ENOMEM, "", "out of memory");
    for (int k = 0; !rc && k < n; k++)
        id_of[k] = ids[k], res[k] = m[k].resource;
    struct seg_grid g = {0};
    if (!rc)
        rc = seg_grid_of(svc, id_of, res, n, options, &g, &w.err);
    seg_grid_free(&g);
    free(id_of);
    free(res);
    export_models_free(m, ids, n);
    if (rc)
        *err = w.err;
    return rc;
}

/* The models a request lists ("ID,ID,...": GET /rtstruct; one id: GET /models/{id}/rtstruct; the
 * route checked their owner and count) as one structure set, named after its one model or its job. */
static int make_rtstruct(struct contour_work *w, const struct job_rec *rec, const struct sf_progress *pr)
{
    if (export_is_seg(rec->options))
        return make_seg(w, rec, pr);
    struct model_export *m = NULL;
    char(*ids)[40] = NULL;
    int n = 0;
    int rc = export_models(w, (const char *)rec->request, rec->request_len, &m, &ids, &n);
    if (!rc)
        rc = model_rtstruct_set(m, n, rec->options, pr, (unsigned char **)&w->json, &w->len, &w->err);
    w->type = "application/dicom";
    snprintf(w->model, sizeof w->model, "%s", n == 1 && ids ? ids[0] : w->job.claim.id);
    snprintf(w->meta, sizeof w->meta, "{\"filename\":\"%s.dcm\"}", w->model);
    export_models_free(m, ids, n);
    return rc;
}

static int make_patches(struct contour_work *w, const struct job_rec *rec, const struct sf_progress *pr)
{
    (void)pr;
    char *src, *resource;
    size_t n;
    int rc = stored_model(w, rec, &src, &n, &resource);
    if (!rc && !(rc = model_patches_json(src, n, &w->json, &w->err)))
        w->len = strlen(w->json);
    free(src);
    free(resource);
    return rc;
}

/* The delta of model id since version since > 0, composed with its mesh src (n bytes, as the store
 * keeps it) into *out. 0 or an error (SF_ECONFLICT: the changes are no longer kept). */
static int delta_of(struct service *svc, const char *id, long since, const char *src, size_t n, char **out,
                    size_t *len, struct sf_err *err)
{
    long to;
    int rc = store_delta(svc->store, id, since, src, n, out, len, &to);
    return rc == SF_ENOTFOUND ? sf_fail(err, SF_ECONFLICT, "?since", "the changes since version %ld are no longer kept: "
                                        "load since=0 (the whole mesh)", since)
           : rc               ? sf_fail(err, rc, "", "the model's changes could not be composed")
                              : 0;
}

/* GET /models/{id}/mesh?format=delta&since=V across a change of every triangle (server.c's
 * delta_request: the other deltas are the journal's few bytes, composed on the HTTP thread): the
 * changes with the current mesh, read whole, composed on the checks pool and answered, kept
 * nowhere (a transient kind). A delta is a function of what the store keeps, asked once by the
 * client that held version V: as a job it was stored (30 MB on the CT head, synced), read back
 * and sent, some 0.1-0.3 s of a slider's step for nothing. The body is the model's id. */
static int delta_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    char id[64], since[24], *src = NULL, *out = NULL;
    snprintf(id, sizeof id, "%.*s", (int)(b->len < 63 ? b->len : 63), b->body ? b->body : "");
    query_option(b->options, "since", since, sizeof since);
    size_t n = 0, len = 0;
    int found = store_model_get(svc->store, id, b->owner, NULL, &src, &n);
    if (found)
        return sf_fail(err, found == SF_ENOTFOUND ? SF_ENOTFOUND : SF_EIO, "",
                       found == SF_ENOTFOUND ? "no such model" : "the store could not read the model");
    int rc = delta_of(svc, id, atol(since), src, n, &out, &len, err);
    free(src);
    if (rc)
        return rc;
    free(b->body);
    b->body = out, b->len = len;
    return 0;
}

const struct job_kind delta_kind = {.name = "delta", .validate = delta_validate, .transient = true,
                                    .result = "application/vnd.surfd.mesh-delta"};

/* A mesh, and its file's name for the download: the model's id, the format's extension. */
static int make_mesh(struct contour_work *w, const struct job_rec *rec, const struct sf_progress *pr)
{
    if (export_is_seg(rec->options)) /* not cached (no key): its grid is a stored series' that may come or go */
        return make_seg(w, rec, pr);
    char *src, *resource, since[24];
    size_t n;
    int rc = stored_model(w, rec, &src, &n, &resource);
    query_option(rec->options, "since", since, sizeof since);
    if (!rc && atol(since) > 0) { /* (a job stored by a surfd before delta_kind) */
        rc = delta_of(w->job.svc, w->model, atol(since), src, n, &w->json, &w->len, &w->err);
        w->type = "application/vnd.surfd.mesh-delta";
    } else if (!rc) {
        rc = model_mesh(src, n, resource, rec->options, pr, &w->json, &w->len, &w->type, &w->tol, &w->err);
    }
    if (!rc) {
        const char *format;
        double tol;
        model_mesh_options(rec->options, &format, &tol, &w->err);
        /* (a delta since a version is not cached: the client that held that version asks it once,
         * and an iso change's is as large as the mesh: 30 MB written for nothing, 0.2-0.3 s) */
        if (atol(since) <= 0)
            model_mesh_key(rec->options, iso_model_edits(resource), w->key, sizeof w->key, &w->err);
        const char *ext = strcmp(format, "dicom-stl") ? format : "dcm";
        if (w->tol > 0)
            snprintf(w->meta, sizeof w->meta, "{\"filename\":\"%s.%s\",\"tolerance_mm\":%.6g}", w->model, ext, w->tol);
        else
            snprintf(w->meta, sizeof w->meta, "{\"filename\":\"%s.%s\"}", w->model, ext);
    }
    free(src);
    free(resource);
    return rc;
}

/* A model sent to a PACS (POST /models/{id}/send?pacs=NAME&as=rtstruct|dicom-stl|seg, or several as
 * one structure set: POST /rtstruct/send?models=ID,...&pacs=NAME): the file made as
 * GET /models/{id}/rtstruct or /mesh?format=dicom-stl|seg makes it, written to the data dir (0600) and
 * sent by STOW-RS or C-STORE; the result is the PACS's status for it. A PACS down or refusing
 * fails the job (after dicomweb.h's or the association's bounded tries); a PACS that answers
 * says per instance whether it stored it. */
static int make_send(struct contour_work *w, const struct job_rec *rec, const struct sf_progress *pr)
{
    struct service *svc = w->job.svc;
    char name[40], as[16], spacing[32];
    query_option(rec->options, "pacs", name, sizeof name);
    query_option(rec->options, "as", as, sizeof as);
    query_option(rec->options, "spacing", spacing, sizeof spacing);
    const struct pacs *p;
    if (pacs_named(svc, name, &p, &w->err))
        return w->err.code;
    struct job_rec made = *rec; /* the export's request: the model's id, its own options */
    int rc;
    if (!strcmp(as, "dicom-stl")) {
        snprintf(made.options, sizeof made.options, "format=dicom-stl");
        rc = make_mesh(w, &made, pr);
    } else if (!strcmp(as, "seg")) {
        snprintf(made.options, sizeof made.options, "format=seg%s%s", spacing[0] ? "&spacing=" : "", spacing);
        rc = make_seg(w, &made, pr);
    } else {
        snprintf(made.options, sizeof made.options, "%s%s", spacing[0] ? "spacing=" : "", spacing);
        rc = make_rtstruct(w, &made, pr);
    }
    if (rc)
        return rc;
    char path[700];
    snprintf(path, sizeof path, "%s/send-%s.dcm", svc->cfg.data_dir, w->job.claim.id);
    FILE *f = fopen(path, "wb");
    bool written = f && fwrite(w->json, 1, w->len, f) == w->len;
    if (f && fclose(f))
        written = false;
    struct dicom_instance in;
    struct sf_err e = {0};
    if (!written || dicom_instance_read(w->json, w->len, "", &in, &e)) {
        unlink(path);
        return sf_fail(&w->err, written ? SF_EINVAL : SF_EIO, "", written ? "the export is not an instance: %s"
                       : "the export could not be written to the data dir", e.message);
    }
    free(w->json), w->json = NULL;
    const char *paths[1] = {path};
    json_t *list = json_array();
    if (p->dimse) {
        unsigned status;
        rc = pacs_failed(dimse_send(&p->peer, svc->cfg.ae_title, paths, 1, 30, &status, &w->err), &w->err);
        if (!rc)
            json_array_append_new(list, json_pack("{s:s, s:b, s:i}", "sop_instance_uid", in.sop_uid, "stored",
                                                  status < 0xA000 && status != DIMSE_NOT_SENT, "status", (int)status));
    } else {
        struct dicomweb_stored *res = NULL;
        int n = 0;
        rc = pacs_failed(dicomweb_store(p->dw, NULL, paths, 1, (uint64_t)svc->cfg.max_body, &res, &n, &w->err), &w->err);
        for (int k = 0; !rc && k < n; k++)
            json_array_append_new(list, json_pack("{s:s, s:b, s:i}", "sop_instance_uid", res[k].sop_instance_uid,
                                                  "stored", res[k].stored, "reason", res[k].reason));
        if (!rc && n == 0) /* an instance the PACS does not list was not stored */
            json_array_append_new(list, json_pack("{s:s, s:b}", "sop_instance_uid", in.sop_uid, "stored", 0));
        free(res);
    }
    unlink(path);
    json_t *models = json_array(); /* the request's ids, as listed */
    for (const char *c = (const char *)rec->request, *end = c + rec->request_len; c < end;) {
        const char *comma = memchr(c, ',', (size_t)(end - c));
        json_array_append_new(models, json_stringn(c, (size_t)((comma ? comma : end) - c)));
        c = comma ? comma + 1 : end;
    }
    json_t *o = rc ? NULL : json_pack("{s:s, s:s, s:o, s:o}", "pacs", p->name, "as", as[0] ? as : "rtstruct",
                                      "models", models, "instances", list);
    if (rc)
        json_decref(models);
    if (!o)
        json_decref(list);
    w->json = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    w->len = w->json ? strlen(w->json) : 0;
    w->type = "application/json";
    w->meta[0] = 0;
    if (!rc && !w->json)
        rc = sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
    if (!rc)
        LOG(LOG_INFO, "model %s sent to %s as %s", w->model, p->name, as[0] ? as : "rtstruct");
    return rc;
}

static int prepare_model(struct job *j, void *arg, int *n_bands) { return prepare_with(j, arg, n_bands, make_model); }
static int prepare_send(struct job *j, void *arg, int *n_bands) { return prepare_with(j, arg, n_bands, make_send); }
static int prepare_volume(struct job *j, void *arg, int *n_bands) { return prepare_with(j, arg, n_bands, make_figures); }
static int prepare_rtstruct(struct job *j, void *arg, int *n_bands) { return prepare_with(j, arg, n_bands, make_rtstruct); }
static int prepare_patches(struct job *j, void *arg, int *n_bands) { return prepare_with(j, arg, n_bands, make_patches); }
static int prepare_mesh(struct job *j, void *arg, int *n_bands) { return prepare_with(j, arg, n_bands, make_mesh); }

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct contour_work *w = arg;
    service_job_end(w->job.svc, &w->job.claim, outcome, requeue, (const unsigned char *)w->json, w->json ? w->len : 0,
                    w->type ? w->type : "application/json", w->meta[0] ? w->meta : NULL, &w->err);
    free(w->json);
    free(w);
}

/* A mesh is cached (mesh-cache) before its job ends: the next GET of it is answered from there. */
static void finish_mesh(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    struct contour_work *w = arg;
    struct service *svc = w->job.svc;
    if (outcome == JOB_SUCCEEDED && w->key[0] && svc->cfg.mesh_cache > 0) {
        struct mesh_rec m = {(char *)w->type, w->meta, (unsigned char *)w->json, w->len, ""};
        if (store_mesh_put(svc->store, w->model, w->key, &m, svc->cfg.mesh_cache) == SF_EIO)
            LOG(LOG_WARN, "model %s: its mesh (%s) could not be cached", w->model, w->key); /* made again next time */
    }
    finish(j, arg, outcome, requeue);
}

static const struct job_ops MODEL_OPS = {.prepare = prepare_model, .finish = finish};
static const struct job_ops VOLUME_OPS = {.prepare = prepare_volume, .finish = finish};
static const struct job_ops RTSTRUCT_OPS = {.prepare = prepare_rtstruct, .finish = finish};
static const struct job_ops PATCHES_OPS = {.prepare = prepare_patches, .finish = finish};
static const struct job_ops MESH_OPS = {.prepare = prepare_mesh, .finish = finish_mesh};
static const struct job_ops SEND_OPS = {.prepare = prepare_send, .finish = finish};

/* ---- the requests: contour JSON or an RT Structure Set (both kinds); /volume also measures a
 * scene (JSON, .bpt, VRML) whose patches bound a closed solid ---- */

/* Contours and scenes (formats.h); a body without a type, or text, read as JSON's (its members say
 * which: model_json.c), an IGES part found by its magic. */
static const char *figures_format(const char *content_type)
{
    const char *f = input_format_of_media(content_type, IN_VOLUME);
    return f && !*f ? "json" : f;
}

static const char *contour_format(const char *content_type)
{
    const char *f = input_format_of_media(content_type, IN_MODEL);
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

static int volume_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    (void)svc; /* (?format= was named by formats.h's table on the route: server.c) */
    return validate(b, true, err);
}

static int model_validate_body(struct service *svc, struct job_body *b, struct sf_err *err)
{
    (void)svc;
    return validate(b, false, err);
}

static int mesh_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    const char *format;
    double tol;
    int rc = model_mesh_options(b->options, &format, &tol, err);
    return rc || strcmp(format, "seg") ? rc : export_validate(svc, b->body ? b->body : "", b->len, b->options, err);
}

static int rtstruct_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    return export_validate(svc, b->body ? b->body : "", b->len, b->options, err);
}

static int send_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    char name[40], as[16];
    query_option(b->options, "pacs", name, sizeof name);
    query_option(b->options, "as", as, sizeof as);
    const struct pacs *p;
    if (pacs_named(svc, name, &p, err))
        return err->code;
    if (as[0] && strcmp(as, "rtstruct") && strcmp(as, "dicom-stl") && strcmp(as, "seg"))
        return sf_fail(err, SF_EINVAL, "?as", "as is rtstruct (the default), dicom-stl or seg");
    if (!strcmp(as, "dicom-stl") && b->body && memchr(b->body, ',', b->len))
        return sf_fail(err, SF_EINVAL, "?as", "dicom-stl sends one model's mesh: several models go as one rtstruct");
    if (!strcmp(as, "dicom-stl"))
        return 0;
    /* the models' export as GET /rtstruct?models= or ?format=seg would make it, refused as they would */
    char spacing[32], options[96];
    query_option(b->options, "spacing", spacing, sizeof spacing);
    snprintf(options, sizeof options, "format=%s%s%s", as[0] ? as : "rtstruct", spacing[0] ? "&spacing=" : "", spacing);
    return export_validate(svc, b->body ? b->body : "", b->len, options, err); /* (the body: the models' ids) */
}

static int patches_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    (void)svc;
    (void)b;
    (void)err;
    return 0;
}

const struct job_kind volume_kind = {
    .name = "volume", .format = figures_format, .route = IN_VOLUME, .format_in_query = true, .validate = volume_validate, .ops = &VOLUME_OPS, .work_size = sizeof(struct contour_work),
    .result = "application/json"};
const struct job_kind model_kind = {
    .name = "model", .format = contour_format, .route = IN_MODEL,
    .validate = model_validate_body, .ops = &MODEL_OPS, .work_size = sizeof(struct contour_work),
    .result = "application/json"};
const struct job_kind patches_kind = {.name = "patches", .validate = patches_validate, .ops = &PATCHES_OPS,
                                      .work_size = sizeof(struct contour_work), .result = "application/json"};
const struct job_kind mesh_kind = {
    .name = "mesh", .validate = mesh_validate, .ops = &MESH_OPS, .work_size = sizeof(struct contour_work),
    .result = "model/stl, application/ply, model/obj, model/vnd.vtk.vtp+xml, model/vnd.vtk or application/dicom"};
const struct job_kind send_kind = {.name = "send", .validate = send_validate, .ops = &SEND_OPS,
                                   .work_size = sizeof(struct contour_work), .result = "application/json"};
const struct job_kind rtstruct_kind = {.name = "rtstruct", .validate = rtstruct_validate, .ops = &RTSTRUCT_OPS,
                                       .work_size = sizeof(struct contour_work), .result = "application/dicom"};
