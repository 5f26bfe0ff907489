/* job_iso.c - the isosurface job kind: a sampled volume (raw, NRRD, MetaImage, NIfTI, a DICOM series
 * or multi-frame image)
 * and ?iso, or an FRep object, to a closed triangle mesh, stored as a model. Read back from the
 * store (so a job recovered after a crash, or claimed by another node, runs as submitted); an FRep
 * sampled on its grid in a first phase of bands; then core/iso's two passes as two phases of
 * bands, one band a slab of z, on whichever workers are idle (cancel between slabs); then the
 * mesh is measured and stored compactly with its model resource. A label map's ?label=N is its
 * mask's isosurface as above (the map not kept: no edits); ?labels=all is core/iso/labels.h's
 * surfaces, made on the worker that reads the map, and one model a label, stored as an RT
 * Structure Set's ROIs are (job_contours.c): the first the job's id, the others its id with k in
 * the last four hex digits; the result {"models": [...]}. */
#include <fcntl.h>
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../api/dicom_scan.h"
#include "../api/iso_json.h"
#include "../api/mesh_io.h"
#include "../api/multipart.h"
#include "../api/volume_io.h"
#include "../core/base/mem.h"
#include "../core/iso/labels.h"
#include "job_edit.h"
#include "kinds.h"
#include "log.h"
#include "volumes.h"

#define SLABS_PER_WORKER 4 /* a few bands a worker: the slabs' costs differ */

struct iso_work {
    struct job_work job;     /* first: job_start fills it */
    struct job *j;
    struct job_rec rec;      /* holds the request: the samples may lie in it */
    char file[1100];         /* or in the streamed body's file, mapped at map */
    void *map;
    size_t map_len;
    struct volume vol;
    struct iso_job *ij;
    enum { PH_SAMPLE, PH_COUNT, PH_EMIT, PH_ADAPT } phase;
    struct iso_adapt *ad;    /* volume_adaptive(): the adaptive hierarchy, its phases of bands */
    bool ad_keep;            /* begun to be kept for the model's edits */
    bool warm;               /* marching cubes to be kept for them, after the answer (edit_warm) */
    int ad_phase;
    struct iso_adapt_stats adapt_st;
    int n_slabs, n_sample, bands_total; /* bands_total: of every phase, for the progress */
    atomic_int bands_done;
    double t0, t_read, t_sampled;
    char *json;
    size_t len;
    char meta[128];
    size_t input_len;        /* bytes of the request (the volume's file, the FRep's JSON) */
    char tri_by[160];        /* what limits its triangles, when its size does */
    struct iso_labels lab;   /* ?labels=all: the labels' surfaces (made in prepare) */
    struct sf_err err;
};

/* Triangles any request may make, however small (max-triangles-per-byte): an FRep's fine grid,
 * a small label map. */
#define ISO_TRIANGLES_ANY_INPUT 4000000

static int begin_extract(struct iso_work *w, int *n_bands);
static int extract_labels(struct iso_work *w, struct job *j);

static int prepare(struct job *j, void *arg, int *n_bands)
{
    struct iso_work *w = arg;
    w->j = j;
    w->t0 = monotonic_s();
    if (store_get(w->job.svc->store, w->job.claim.id, true, false, &w->rec))
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store");
    const char *body = (const char *)w->rec.request;
    size_t len = w->rec.request_len;
    if (w->rec.request_file) { /* a streamed volume: mapped, read in place */
        if (store_request_file(w->job.svc->store, w->job.claim.id, w->file, sizeof w->file) ||
            job_map_file(w->file, &w->map, &w->map_len))
            return sf_fail(&w->err, SF_EIO, "", "the job's volume could not be read from the store");
        body = w->map ? w->map : "";
        len = w->map_len;
    }
    w->input_len = len;
    int rc = volume_read(body, len, w->rec.format, w->rec.options, &w->vol, &w->err);
    if (rc)
        return rc;
    w->t_read = w->t_sampled = monotonic_s();
    struct jobq_stats qs;
    jobq_stats(w->job.svc->q, &qs);
    w->n_slabs = (int)qs.workers * SLABS_PER_WORKER;
    if (w->vol.frep && (rc = frep_volumes(w->job.svc, w->vol.frep, &w->err)))
        return rc;
    if (w->vol.all_labels) { /* the labels' surfaces here, the models stored by finish */
        *n_bands = 0;
        return extract_labels(w, j);
    }
    if (w->vol.frep) { /* sampled first, in bands of planes */
        w->phase = PH_SAMPLE;
        *n_bands = w->n_sample = w->n_slabs < w->vol.g.nz ? w->n_slabs : w->vol.g.nz;
        w->bands_total = 3 * w->n_sample; /* till the extraction says its own */
        return 0;
    }
    return begin_extract(w, n_bands);
}

/* The extraction's options with this node's limits on its triangles, and what the request's size
 * lets it make: real scans make under 1 triangle a byte (the CT head's gzip NRRD 0.17, the MRI's
 * 0.43), gzip label maps 3 to 5; a 43 KB gzip NRRD of a striped field (surface in every cell) would
 * make 916, 39 M triangles and 3 GB. */
static struct iso_opts limited_opts(struct iso_work *w)
{
    struct iso_opts o = job_iso_opts(w->job.svc, &w->vol);
    double by_size = fmax((double)w->job.svc->cfg.max_triangles_per_byte * (double)w->input_len, ISO_TRIANGLES_ANY_INPUT);
    if (w->job.svc->cfg.max_triangles_per_byte && by_size < (double)o.max_triangles) {
        o.max_triangles = (size_t)by_size;
        snprintf(w->tri_by, sizeof w->tri_by, "what a request of %zu bytes may make (max-triangles-per-byte, %ld a byte,"
                 " %d M at least)", w->input_len, w->job.svc->cfg.max_triangles_per_byte, ISO_TRIANGLES_ANY_INPUT / 1000000);
        o.max_triangles_by = w->tri_by;
    }
    return o;
}

/* ?labels=all: the map's labels' surfaces, every triangle once (each label's model holds its
 * own): limited as one isosurface is (job_iso_opts: some 80 bytes a triangle of the meshes it
 * stores, the shared surfaces half that). */
static int extract_labels(struct iso_work *w, struct job *j)
{
    long cap = w->job.svc->cfg.max_labels;
    if (w->vol.n_labels > cap)
        return sf_fail(&w->err, SF_ELIMIT, "?labels", "the map has %d labels; labels=all makes %ld models a request at "
                       "most on this node (max-labels)", w->vol.n_labels, cap);
    struct iso_opts o = limited_opts(w);
    char by[256];
    snprintf(by, sizeof by, "%s, a triangle between two labels counted in both their models", o.max_triangles_by);
    struct job_poll pc = {w->job.svc->q, j};
    const struct sf_progress pr = {service_poll_job, &pc};
    int rc = iso_labels_extract(&w->vol.g, w->vol.n_labels, w->vol.closed, o.max_triangles / 2, by, &pr, &w->lab,
                                &w->err);
    w->t_sampled = monotonic_s();
    return rc;
}

static int begin_extract(struct iso_work *w, int *n_bands)
{
    struct iso_opts o = limited_opts(w);
    /* a hierarchy of samples is kept for the model's edits when it fits their memory (about 5
     * bytes a sample) */
    o.keep = !w->vol.frep && !w->vol.has_label && (double)w->vol.g.nx * w->vol.g.ny * w->vol.g.nz * 5 <= (double)w->job.svc->cfg.edit_memory;
    int rc;
    if (volume_adaptive(&w->vol)) {
        if ((rc = iso_adapt_begin(&w->vol.g, &o, w->vol.levels, w->vol.max_error, &w->ad, &w->err)))
            return rc;
        w->ad_keep = o.keep;
        w->phase = PH_ADAPT;
        *n_bands = iso_adapt_n_slabs(w->ad);
        w->bands_total = w->n_sample + iso_adapt_phases(w->ad) * *n_bands;
        return 0;
    }
    if ((rc = iso_begin(&w->vol.g, &o, w->n_slabs, &w->ij, &w->err)))
        return rc;
    w->phase = PH_COUNT;
    w->n_slabs = iso_n_slabs(w->ij);
    *n_bands = w->n_slabs;
    w->bands_total = w->n_sample + 2 * w->n_slabs;
    return 0;
}

static void band(struct job *j, void *arg, int k)
{
    struct iso_work *w = arg;
    if (w->phase == PH_ADAPT)
        iso_adapt_run(w->ad, w->ad_phase, k);
    else if (w->phase == PH_SAMPLE) { /* a cancel stops it mid-band: the job ends at the band's end */
        struct job_poll pc = {w->job.svc->q, j};
        const struct sf_progress pr = {service_poll_cancel, &pc};
        volume_sample(&w->vol, (int)((long)w->vol.g.nz * k / w->n_sample), (int)((long)w->vol.g.nz * (k + 1) / w->n_sample),
                      &pr, NULL);
    }
    else if (w->phase == PH_COUNT)
        iso_count(w->ij, k);
    else
        iso_emit(w->ij, k);
    /* every band of every phase alike (the last 5 %: measuring, storing) */
    int done = atomic_fetch_add(&w->bands_done, 1) + 1;
    jobq_cancelled(w->job.svc->q, j, fmin(0.95, 0.95 * done / w->bands_total));
}

static int next(struct job *j, void *arg, int *n_bands)
{
    (void)j;
    struct iso_work *w = arg;
    *n_bands = 0;
    if (w->phase == PH_SAMPLE) {
        w->t_sampled = monotonic_s();
        return begin_extract(w, n_bands);
    }
    if (w->phase == PH_EMIT)
        return 0;
    if (w->phase == PH_ADAPT) {
        iso_adapt_between(w->ad, w->ad_phase);
        if (++w->ad_phase < iso_adapt_phases(w->ad))
            *n_bands = iso_adapt_n_slabs(w->ad);
        return 0;
    }
    int rc = iso_layout(w->ij, &w->err);
    if (rc)
        return rc;
    w->phase = PH_EMIT;
    *n_bands = w->n_slabs;
    return 0;
}

/* Lets go of the request (the volume's mapping or its bytes), once stored with the model. */
static void drop_request(struct iso_work *w)
{
    if (w->map)
        munmap(w->map, w->map_len);
    w->map = NULL;
    free(w->rec.request);
    w->rec.request = NULL;
}

/* SF_ECANCEL when the job has been asked to stop: a cancel that comes before the mesh is stored
 * is honoured, whichever step it finds (measuring a mesh of millions of triangles takes seconds). */
static int stopped(struct iso_work *w, double progress)
{
    return jobq_cancelled(w->job.svc->q, w->j, progress) ? sf_fail(&w->err, SF_ECANCEL, "", "cancelled") : 0;
}

/* The mesh measured and stored as model (the job's id), its resource the job's result. */
static int store_model(struct iso_work *w)
{
    double t_extract = monotonic_s();
    struct trimesh m = {0}; /* (iso_adapt_keep may fail before iso_adapt_mesh sets it) */
    struct iso_adapt *kept = NULL; /* for the model's edits */
    int rc;
    if (w->ad && w->ad_keep) {
        if (!(rc = iso_adapt_keep(w->ad, &w->adapt_st, &w->err)) &&
            !(rc = iso_adapt_mesh(w->ad, &m, &w->adapt_st, &w->err)))
            kept = w->ad;
        else
            iso_adapt_free(w->ad);
    } else {
        rc = w->ad ? iso_adapt_end(w->ad, &m, &w->adapt_st, &w->err) : iso_end(w->ij, &m, &w->err);
    }
    w->ij = NULL;
    w->ad = NULL;
    if (!rc)
        rc = volume_mesh_empty(&w->vol, &m, &w->err);
    if (rc) {
        trimesh_free(&m);
        iso_adapt_free(kept);
        return rc;
    }
    if (w->vol.oblique)
        trimesh_turn(&m, w->vol.g.origin, (const double(*)[3])w->vol.axes);
    volume_drop_samples(&w->vol); /* the volume and the mesh together are the job's peak of memory */
    struct trimesh_stats st;
    char *packed = NULL;
    size_t packed_len = 0;
    if (!(rc = stopped(w, 0.95)) && !(rc = trimesh_stats(&m, &st, &w->err)) && !(rc = stopped(w, 0.98)))
        rc = mesh_pack(&m, &packed, &packed_len, &w->err);
    double t_measure = monotonic_s();
    struct iso_model im = {w->job.claim.id, w->vol.name, &w->vol, &st, volume_adaptive(&w->vol) ? &w->adapt_st : NULL, m.n_vert,
                           m.n_tri,
                           {(w->t_read - w->t0) * 1e3, (w->t_sampled - w->t_read) * 1e3,
                            (t_extract - w->t_sampled) * 1e3, (t_measure - t_extract) * 1e3, (t_measure - w->t0) * 1e3},
                           0, NULL, w->vol.has_label, NULL};
    trimesh_free(&m);
    if (!rc && !(w->json = iso_model_json(&im, &w->err)))
        rc = w->err.code;
    if (!rc) {
        /* the volume (samples or an FRep object) is kept with the model, as it was posted, for its edits */
        struct volume_rec vr = {0, w->rec.format, w->rec.options, w->map ? w->map : (const void *)w->rec.request,
                                w->map ? w->map_len : w->rec.request_len};
        struct model_rec mr = {w->job.claim.id, w->job.claim.id, w->vol.name, w->rec.owner, wall_s(), packed, packed_len, w->json,
                               w->vol.has_label ? NULL : &vr, 1}; /* (a label's map is not kept: no edits) */
        if (store_model_put(w->job.svc->store, &mr))
            rc = sf_fail(&w->err, SF_EIO, "", "the store would not take the mesh");
    }
    free(packed);
    drop_request(w);
    if (!rc)
        edit_keep(w->job.svc, w->job.claim.id, &w->vol, kept);
    else
        iso_adapt_free(kept);
    w->warm = !rc && !volume_adaptive(&w->vol) && !w->vol.frep && !w->vol.has_label &&
              (double)w->vol.g.nx * w->vol.g.ny * w->vol.g.nz * 5 <= (double)w->job.svc->cfg.edit_memory;
    if (!rc) {
        w->len = strlen(w->json);
        snprintf(w->meta, sizeof w->meta, "{\"status\":201,\"location\":\"/models/%s\"}", w->job.claim.id);
    }
    return rc;
}

/* Appends text to the answer w->json (w->len bytes, cap its room): 0 or SF_ENOMEM. */
static int answer_add(struct iso_work *w, size_t *cap, const char *text)
{
    size_t n = strlen(text);
    if (mem_reserve((void **)&w->json, cap, w->len + n + 1, 1))
        return sf_fail(&w->err, SF_ENOMEM, "", "out of memory for the answer");
    memcpy(w->json + w->len, text, n + 1);
    w->len += n;
    return 0;
}

/* ?labels=all: each label's surface measured and stored as a model of its own (its id: the job's
 * for the first, the job's with k in its last four hex digits for the others, as an RT Structure
 * Set's ROIs); the answer {"models": [...]}. */
static int store_label_models(struct iso_work *w)
{
    drop_request(w); /* the map and its indices are no longer read: the meshes are the peak */
    volume_drop_samples(&w->vol);
    int n = w->vol.n_labels, rc = 0;
    size_t cap = 0, *touch = malloc(sizeof *touch * ((size_t)n + 1));
    if (!touch)
        return sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
    w->len = 0;
    rc = answer_add(w, &cap, "{\"models\":[");
    for (int k = 1; k <= n && !rc; k++) {
        double t0 = monotonic_s();
        struct trimesh m;
        struct trimesh_stats st;
        char id[40], name[sizeof w->vol.name], *packed = NULL, *json = NULL;
        size_t packed_len = 0;
        if (k == 1)
            snprintf(id, sizeof id, "%s", w->job.claim.id);
        else
            snprintf(id, sizeof id, "%.28s%04x", w->job.claim.id, (unsigned)(k - 1) & 0xffff);
        volume_label_name(&w->vol, k, name, sizeof name);
        if ((rc = stopped(w, 0.95 + 0.05 * (k - 1) / n)) || (rc = iso_labels_mesh(&w->lab, k, touch, &m, &w->err)))
            break;
        if (w->vol.oblique)
            trimesh_turn(&m, w->vol.g.origin, (const double(*)[3])w->vol.axes);
        if (!(rc = trimesh_stats(&m, &st, &w->err)))
            rc = mesh_pack(&m, &packed, &packed_len, &w->err);
        double t1 = monotonic_s();
        struct iso_model im = {id, name, &w->vol, &st, NULL, m.n_vert, m.n_tri,
                               {(w->t_read - w->t0) * 1e3, 0, (w->t_sampled - w->t_read) * 1e3, (t1 - t0) * 1e3,
                                (t1 - w->t0) * 1e3},
                               0, NULL, k, touch};
        trimesh_free(&m);
        if (!rc && !(json = iso_model_json(&im, &w->err)))
            rc = w->err.code;
        if (!rc) {
            struct model_rec mr = {id, w->job.claim.id, name, w->rec.owner, wall_s(), packed, packed_len, json, NULL, 1};
            if (store_model_put(w->job.svc->store, &mr))
                rc = sf_fail(&w->err, SF_EIO, "", "the store would not take the mesh of label %lld",
                             w->vol.label_of[k - 1].value);
        }
        if (!rc && k > 1)
            rc = answer_add(w, &cap, ",");
        if (!rc)
            rc = answer_add(w, &cap, json);
        free(packed);
        free(json);
    }
    free(touch);
    iso_labels_free(&w->lab);
    if (!rc && !(rc = answer_add(w, &cap, "]}")))
        snprintf(w->meta, sizeof w->meta, "{\"status\":201,\"location\":\"/models/%s\"}", w->job.claim.id);
    if (rc) {
        free(w->json);
        w->json = NULL;
        w->len = 0;
    }
    return rc;
}

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct iso_work *w = arg;
    if (outcome == JOB_SUCCEEDED) {
        int rc = w->vol.all_labels ? store_label_models(w) : store_model(w);
        outcome = rc == SF_ECANCEL ? JOB_CANCELLED : rc ? JOB_FAILED : JOB_SUCCEEDED;
    }
    service_job_end(w->job.svc, &w->job.claim, outcome, requeue, (const unsigned char *)w->json, w->json ? w->len : 0,
                    "application/json", w->meta[0] ? w->meta : NULL, &w->err);
    w->warm = w->warm && outcome == JOB_SUCCEEDED;
    iso_free(w->ij);
    iso_adapt_free(w->ad);
    iso_labels_free(&w->lab);
    volume_free(&w->vol);
    drop_request(w);
    if (w->file[0])
        store_request_file_done(w->job.svc->store, w->file);
    store_rec_free(&w->rec);
    free(w->json);
    w->json = NULL;
}

/* After the answer: a levels=1 model's marching cubes kept for its edits (edit_warm). */
static void after(void *arg)
{
    struct iso_work *w = arg;
    if (w->warm)
        edit_warm(w->job.svc, w->job.claim.id);
    free(w);
}

static const struct job_ops ISO_OPS = {.prepare = prepare, .band = band, .next = next, .finish = finish, .after = after};


/* A DICOM series' (or one DICOM file's) identifying elements blanked in place in the body, before it
 * is stored (each value keeps its length: the multipart body and the slices read the same), and the
 * parts' file names (exports name them by patient). */
static int blank_identity(struct job_body *b, struct sf_err *err)
{
    struct part one = {b->body, b->len, NULL, 0}, *parts = &one; /* one file as the body: its part 0 */
    int n = 1, rc = multipart_sniff(b->body, b->len) ? multipart_split(b->body, b->len, &parts, &n, err) : 0;
    if (rc)
        return rc;
    size_t blanked = 0;
    for (int k = 0; !rc && k < n; k++) {
        char where[32];
        size_t m = 0;
        snprintf(where, sizeof where, "/parts/%d", k);
        rc = dicom_blank_identity((char *)parts[k].data, parts[k].len, where, &m, err);
        blanked += m;
        if (parts[k].filename)
            memset((char *)parts[k].filename, '_', parts[k].filename_len);
    }
    if (parts != &one)
        free(parts);
    LOG(LOG_DEBUG, "a DICOM series of %d parts: %zu identifying values blanked", n, blanked);
    return rc;
}

static int iso_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    const char *body = b->body ? b->body : "";
    int rc = volume_check(body, b->len, b->format, b->options, (int)svc->cfg.max_labels, err);
    const char *format = rc ? "" : volume_format_of(body, b->len, b->format, b->options);
    if (!rc && !strcmp(format, "dicom") && !svc->cfg.keep_phi)
        return blank_identity(b, err);
    if (rc || strcmp(format, "frep"))
        return rc;
    struct frep_request r;
    if ((rc = frep_parse(body, b->len, &r, err)))
        return rc;
    rc = frep_refs_check(svc, &r, b->owner, NULL, err);
    frep_request_free(&r);
    return rc;
}

const struct job_kind isosurface_kind = {
    .name = "isosurface", .format = volume_format_from_type, .route = IN_ISOSURFACE,
    .format_in_query = true, .validate = iso_validate, .ops = &ISO_OPS, .work_size = sizeof(struct iso_work),
    .result = "application/json", .streamed = true};
