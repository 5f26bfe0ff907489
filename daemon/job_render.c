/* job_render.c - the render job kind: rebuilds the scene from the stored request (so a job
 * recovered after a crash runs exactly as submitted), prepares one frame, renders it in
 * MAP_TILE_ROWS-row bands on whichever workers are idle, encodes the image and stores it. A
 * stored model's view (GET /models/{id}/render) takes the model's parsed objects and hierarchy
 * from the frame cache (frames.h) and prepares only the camera's part. */
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../api/image.h"
#include "../api/png.h"
#include "../api/render_request.h"
#include "../core/trace/map.h"
#include "../core/trace/render.h"
#include "../api/iso_json.h"
#include "frames.h"
#include "kinds.h"
#include "log.h"
#include "metrics.h"

#define JOB_BAND_ROWS MAP_TILE_ROWS /* a band is one map tile: no tile is rasterised twice */

struct render_work {
    struct job_work job;     /* first: job_start fills it */
    struct scene sc;
    bool have_scene;
    enum image_format fmt;
    struct frame *fr;
    struct frame_entry *cached; /* a model's view: its objects and hierarchy, the cache's */
    enum { PREPARE, RENDER, DEFLATE } phase; /* the map's parts, the frame's bands, a PNG's bands */
    int step;                                /* of the frame's preparation (frame_part) */
    int n_bands;
    atomic_int bands_done;
    struct png_bands *png;
    struct render_stats *band_stats; /* one per band: bands never share a counter */
    double at[5]; /* monotonic s: prepare begun, frame begun, bands begun, bands done, PNG done */
    struct sf_err err;
};

/* The model a request's scene is alone, when it is exactly what GET /models/{id}/render makes. */
static bool model_view(const char *format, const char *request, size_t len, char id[40])
{
    static const char HEAD[] = "{\"objects\":[{\"type\":\"model\",\"id\":\"";
    char want[128];
    snprintf(id, 40, "%.32s", len > sizeof HEAD - 1 ? request + sizeof HEAD - 1 : "");
    snprintf(want, sizeof want, "%s%s\"}]}", HEAD, id);
    return !strcmp(format, "json") && len == strlen(want) && !memcmp(request, want, len);
}

/* The frame cache's key of model id (owner's; NULL: anyone's) for the hierarchy the method needs:
 * 0, or the store's answer when it does not give the model. */
static int view_key(struct service *svc, const char *id, const char *owner, bool mesh, char key[96])
{
    char *resource = NULL;
    int found = store_model_get(svc->store, id, owner, &resource, NULL, NULL);
    if (found)
        return found;
    snprintf(key, 96, "%s.%ld.%s", id, iso_model_edits(resource), mesh ? "mesh" : "exact");
    free(resource);
    return 0;
}

struct model_build {
    struct service *svc;
    const struct job_rec *rec;
    bool mesh; /* the mesh method's hierarchy */
};

/* A model's objects and their hierarchy for the cache: the scene as the request has it, without
 * its options, prepared at one pixel (the picture is each view's). */
static int build_model(void *ctx, struct scene *sc, struct frame **base, struct sf_err *err)
{
    const struct model_build *b = ctx;
    struct model_scope scope = {b->svc, NULL}; /* the route checked the owner's models */
    struct model_resolver models = service_models(&scope);
    enum image_format img;
    int rc = render_request_parse((const char *)b->rec->request, b->rec->request_len, b->rec->format, "", &models, sc,
                                  &img, err);
    if (rc)
        return rc;
    sc->width = sc->height = 1;
    sc->srgb8_only = true;
    sc->method = b->mesh ? METHOD_MESH : METHOD_BVH;
    return frame_prepare(sc, b->svc->dev, base, err);
}

/* A model's view on its cached hierarchy (*viewed), or nothing done when the cache cannot serve it
 * (*viewed false): 0, or an error in w->err. */
static int prepare_view(struct render_work *w, const struct job_rec *rec, const char *id, bool *viewed)
{
    char key[96];
    *viewed = false;
    if (w->job.svc->cfg.frame_cache <= 0)
        return 0;
    scene_init(&w->sc); /* the request's options first: the hierarchy they need */
    w->sc.borrowed = true;
    w->have_scene = true;
    w->fmt = IMG_PNG;
    int rc = render_options_apply(rec->options, &w->sc, &w->fmt, &w->err);
    if (rc)
        return rc;
    bool mesh = w->sc.method == METHOD_MESH;
    if (view_key(w->job.svc, id, NULL, mesh, key))
        return 0;
    *viewed = true;
    struct model_build b = {w->job.svc, rec, mesh};
    if (!(w->cached = frames_take(w->job.svc->frames, key, build_model, &b, &w->err)))
        return w->err.code ? w->err.code : SF_ENOMEM; /* frames_take says why in err */
    w->sc.objects = w->cached->sc.objects, w->sc.n_objects = w->cached->sc.n_objects;
    w->sc.meshes = w->cached->sc.meshes, w->sc.n_meshes = w->cached->sc.n_meshes;
    if (w->fmt == IMG_PNG)
        w->sc.srgb8_only = true;
    return frame_begin_from(&w->sc, w->cached->base, &w->fr, &w->err);
}

/* The frame prepared: its bands next. */
static int begin_bands(struct render_work *w, int *n_bands)
{
    w->phase = RENDER;
    w->n_bands = (w->sc.height + JOB_BAND_ROWS - 1) / JOB_BAND_ROWS;
    w->band_stats = calloc((size_t)w->n_bands, sizeof *w->band_stats);
    if (!w->band_stats)
        return sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
    w->at[2] = monotonic_s();
    *n_bands = w->n_bands;
    return 0;
}

static int prepare(struct job *j, void *arg, int *n_bands)
{
    struct render_work *w = arg;
    w->at[0] = monotonic_s();
    struct job_rec rec;
    if (store_get(w->job.svc->store, w->job.claim.id, true, false, &rec))
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store");
    char id[40];
    bool viewed = false;
    int rc = 0;
    if (model_view(rec.format, (const char *)rec.request, rec.request_len, id))
        rc = prepare_view(w, &rec, id, &viewed);
    if (!rc && !viewed) { /* any other scene: parsed and prepared whole */
        struct model_scope scope = {w->job.svc, NULL}; /* the route checked the owner's models */
        struct model_resolver models = service_models(&scope);
        struct job_poll pc = {w->job.svc->q, j}; /* an IGES part's loops stop at a cancel */
        const struct sf_progress pr = {service_poll_cancel, &pc};
        models.progress = &pr;
        rc = render_request_parse((const char *)rec.request, rec.request_len, rec.format, rec.options, &models, &w->sc,
                                  &w->fmt, &w->err);
        w->have_scene = rc == 0;
        if (!rc && w->fmt == IMG_PNG)
            w->sc.srgb8_only = true; /* the bands convert to 8 bits, on every thread */
        if (!rc)
            rc = frame_begin(&w->sc, w->job.svc->dev, &w->fr, &w->err);
    }
    store_rec_free(&rec);
    if (rc)
        return rc;
    w->at[1] = monotonic_s();
    /* the map's parts by every idle worker (the heart's: 19 ms on one), then the bands; a map of
     * one part here (handing it over would cost more) */
    if (frame_parts(w->fr) > 1)
        return *n_bands = frame_parts(w->fr), w->phase = PREPARE, 0;
    return (rc = frame_finish(w->fr, &w->err)) ? rc : begin_bands(w, n_bands);
}

static void band(struct job *j, void *arg, int k)
{
    struct render_work *w = arg;
    if (w->phase != RENDER) {
        if (w->phase == PREPARE)
            frame_part(w->fr, w->step, k);
        else
            png_band(w->png, k);
        return;
    }
    int y0 = k * JOB_BAND_ROWS, y1 = y0 + JOB_BAND_ROWS < w->sc.height ? y0 + JOB_BAND_ROWS : w->sc.height;
    frame_band(w->fr, y0, y1, &w->band_stats[k]);
    jobq_cancelled(w->job.svc->q, j, 0.95 * (atomic_fetch_add(&w->bands_done, 1) + 1) / w->n_bands); /* then the PNG */
}

static int next(struct job *j, void *arg, int *n_bands)
{
    (void)j;
    struct render_work *w = arg;
    *n_bands = 0;
    if (w->phase == PREPARE && ++w->step < frame_steps(w->fr))
        return *n_bands = frame_parts(w->fr), 0;
    int rc;
    if (w->phase == PREPARE)
        return (rc = frame_end(w->fr, &w->err)) ? rc : begin_bands(w, n_bands);
    if (w->phase == RENDER) {
        w->at[3] = monotonic_s();
        if (w->fmt == IMG_PNG) { /* deflated by bands on every idle worker (png.h) */
            struct frame_image img;
            frame_image(w->fr, &img);
            if (!(w->png = png_bands_new(img.srgb8, img.width, img.height, png_band_rows(img.width))))
                return sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
            w->phase = DEFLATE;
            if ((*n_bands = png_bands_n(w->png)) == 1) /* here: handing one band over costs more */
                png_band(w->png, 0), *n_bands = 0;
        }
    }
    return 0;
}

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct render_work *w = arg;
    unsigned char *bytes = NULL;
    size_t n = 0;
    char meta[160] = "";
    if (outcome == JOB_SUCCEEDED) {
        double render_s = w->at[3] - w->at[2];
        struct render_stats total = {0};
        for (int k = 0; k < w->n_bands; k++)
            render_stats_add(&total, &w->band_stats[k]);
        struct frame_image img;
        frame_image(w->fr, &img);
        if ((w->png ? png_join(w->png, &bytes, &n, &w->err) : image_encode(&img, w->fmt, &bytes, &n, &w->err)) == 0) {
            snprintf(meta, sizeof meta, "{\"render_ms\":%.1f,\"prepare_ms\":%.1f,\"rays\":%ld}",
                     render_s * 1e3, frame_prepare_ms(w->fr), total.rays);
            metrics_render(render_s, total.rays);
            w->at[4] = monotonic_s();
            LOG(LOG_DEBUG, "job %s: %.1f ms to read and begin the frame, %.1f to finish its map, %.1f to render, "
                "%.1f to encode", w->job.claim.id, 1e3 * (w->at[1] - w->at[0]), 1e3 * (w->at[2] - w->at[1]),
                1e3 * render_s, 1e3 * (w->at[4] - w->at[3]));
        } else {
            outcome = JOB_FAILED;
        }
    }
    service_job_end(w->job.svc, &w->job.claim, outcome, requeue, bytes, n, image_format_mime(w->fmt), meta, &w->err);
    free(bytes);
    png_bands_free(w->png);
    frame_free(w->fr);
    if (w->have_scene)
        scene_free(&w->sc);
    frames_give(w->job.svc->frames, w->cached); /* after the frame and the scene that borrowed from it */
    free(w->band_stats);
    free(w);
}

static const struct job_ops RENDER_OPS = {.prepare = prepare, .band = band, .next = next, .finish = finish};

static const char *render_format(const char *content_type) { return input_format_of_media(content_type, IN_RENDER); }

/* A view of a stored model whose objects the frame cache holds (parsed and checked when the model
 * was stored and again when they were cached): only the request's options are checked, against
 * them (parsing the heart's model took 11 ms of a 120 ms view); *checked false when the cache does not
 * hold it (nothing checked then). */
static int validate_view(struct service *svc, const struct job_body *b, const char *id, bool *checked,
                         struct sf_err *err)
{
    struct scene sc;
    enum image_format img = IMG_PNG;
    char key[96];
    scene_init(&sc);
    sc.borrowed = true;
    int rc = render_options_apply(b->options, &sc, &img, err);
    *checked = !rc && !view_key(svc, id, b->owner, sc.method == METHOD_MESH, key) &&
               frames_counts(svc->frames, key, &sc.n_objects, &sc.n_meshes);
    if (*checked)
        rc = scene_validate(&sc, err);
    scene_free(&sc);
    return rc;
}

static int render_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    struct scene sc;
    enum image_format img;
    char id[40];
    bool checked = false;
    int rc = model_view(b->format, b->body ? b->body : "", b->len, id) ? validate_view(svc, b, id, &checked, err) : 0;
    if (rc || checked)
        return rc;
    struct model_scope ms = {svc, b->owner};
    struct model_resolver models = service_models(&ms);
    if (render_request_parse(b->body ? b->body : "", b->len, b->format, b->options, &models, &sc, &img, err))
        return err->code;
    scene_free(&sc);
    return 0;
}

const struct job_kind render_kind = {
    .name = "render", .format = render_format, .route = IN_RENDER,
    .format_in_query = true, .validate = render_validate, .ops = &RENDER_OPS, .work_size = sizeof(struct render_work),
    .result = "image/png, image/x-exr or image/tiff"};
