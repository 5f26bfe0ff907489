/* job_pacs.c - the job kinds that talk to a PACS (pacs.h): pull (POST /series/pull: a study's
 * series, or one, retrieved by WADO-RS or C-GET into the store as the DICOM node keeps what it
 * receives) and query (GET /pacs/{name}/studies: a QIDO-RS search passed through, or a C-FIND made
 * of its keys and answered in the same DICOM JSON, on the checks pool and stored nowhere: its
 * answer names patients). Network work, never on the HTTP threads: a PACS may take seconds. The
 * request holds no body (a pull) or the PACS's name (a query); the options say the rest. Each
 * step is one call for either kind of PACS, chosen here by pacs->dimse. */
#include <errno.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../api/dicom_instance.h"
#include "../api/query.h"
#include "dicom_node.h"
#include "kinds.h"
#include "log.h"
#include "pacs.h"

/* Series one pull retrieves at most (a study has some tens). */
#define PULL_MAX_SERIES 1000

struct pacs_work {
    struct job_work job;     /* first: job_start fills it */
    struct job *j;
    char *json;
    size_t len;
    struct sf_err err;
    /* a pull's */
    const struct pacs *pacs;
    char dir[600];
    long kept, n_expected;
};

/* ---- pull ---- */

static const char *any_format(const char *content_type)
{
    (void)content_type;
    return "";
}

static int pull_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    char name[40], study[72], series[72];
    query_option(b->options, "pacs", name, sizeof name);
    query_option(b->options, "study", study, sizeof study);
    query_option(b->options, "series", series, sizeof series);
    const struct pacs *p;
    if (b->len)
        return sf_fail(err, SF_EINVAL, "", "POST /series/pull takes no body: ?pacs=NAME&study=UID[&series=UID]");
    int rc = pacs_named(svc, name, &p, err);
    if (rc)
        return rc;
    if (!dicom_uid_valid(study))
        return sf_fail(err, SF_EINVAL, "?study", "study is the study's Study Instance UID (digits and dots, 64 at most)");
    if (series[0] && !dicom_uid_valid(series))
        return sf_fail(err, SF_EINVAL, "?series", "series is a Series Instance UID (digits and dots, 64 at most)");
    return 0;
}

/* A retrieved instance's file into the store (then removed), as the node keeps a received one. */
static int pulled(void *ctx, int index, const char *path, uint64_t n_bytes, struct sf_err *err)
{
    (void)index, (void)n_bytes;
    struct pacs_work *w = ctx;
    struct service *svc = w->job.svc;
    size_t len;
    char *data = dicom_file_read(path, (size_t)svc->cfg.max_body, &len);
    char source[64];
    snprintf(source, sizeof source, "pulled from %s", w->pacs->name);
    int rc = data ? dicom_instance_keep(svc, data, len, source, NULL, err)
                  : sf_fail(err, SF_EIO, "", "a retrieved instance could not be read back");
    free(data);
    unlink(path);
    w->kept += rc == 0;
    return rc;
}

/* The pull's progress: instances kept of those the PACS said its series hold. */
static bool pull_poll(void *ctx, double done)
{
    struct pacs_work *w = ctx;
    (void)done;
    double f = w->n_expected > 0 ? (double)w->kept / (double)w->n_expected : 0;
    return jobq_cancelled(w->job.svc->q, w->j, f < 1 ? f : 1);
}

/* The series of a study (QIDO-RS, or C-FIND at the SERIES level: the same JSON) into uids (and their instances, expected): their count, or an
 * SF_E* code. */
static int study_series(struct pacs_work *w, const char *study, char (**uids)[65], long **counts)
{
    char *json = NULL;
    size_t len;
    int rc = w->pacs->dimse ? dimse_find(&w->pacs->peer, w->job.svc->cfg.ae_title, DIMSE_SERIES, study, NULL, 0, &json,
                                         &len, &w->err)
                            : dicomweb_search(w->pacs->dw, DICOMWEB_SERIES, study, NULL, NULL, 0, &json, &len, &w->err);
    if (rc)
        return pacs_failed(rc, &w->err);
    json_t *a = json_loadb(json, len, 0, NULL);
    free(json);
    size_t n = json_is_array(a) ? json_array_size(a) : 0;
    if (n > PULL_MAX_SERIES) { /* refused, not pulled in part under a success */
        json_decref(a);
        return sf_fail(&w->err, SF_ELIMIT, "?study", "PACS %s lists %zu series of the study: a pull takes %d at most; pull "
                       "them one at a time (?series=)", w->pacs->name, n, PULL_MAX_SERIES);
    }
    *uids = calloc(n ? n : 1, sizeof **uids);
    *counts = calloc(n ? n : 1, sizeof **counts);
    int found = 0;
    for (size_t k = 0; *uids && *counts && k < n; k++) {
        json_t *o = json_array_get(a, k);
        const char *uid = json_string_value(json_array_get(json_object_get(json_object_get(o, "0020000E"), "Value"), 0));
        json_t *count = json_array_get(json_object_get(json_object_get(o, "00201209"), "Value"), 0);
        if (uid && dicom_uid_valid(uid)) {
            snprintf((*uids)[found], 65, "%s", uid);
            json_int_t c = json_is_integer(count) ? json_integer_value(count) : 0; /* (the PACS's word: bounded) */
            (*counts)[found++] = c < 0 ? 0 : c > DICOMWEB_MAX_INSTANCES ? DICOMWEB_MAX_INSTANCES : (long)c;
        }
    }
    json_decref(a);
    if (!*uids || !*counts)
        return sf_fail(&w->err, SF_ENOMEM, "", "out of memory for the study's series");
    if (!found)
        return sf_fail(&w->err, SF_ENOTFOUND, "?study", "PACS %s holds no series of that study", w->pacs->name);
    return found;
}

static int pull_prepare(struct job *j, void *arg, int *n_bands)
{
    struct pacs_work *w = arg;
    struct service *svc = w->job.svc;
    w->j = j;
    *n_bands = 0;
    struct job_rec rec;
    if (store_get(svc->store, w->job.claim.id, false, false, &rec))
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store");
    char name[40], study[72], one[65];
    query_option(rec.options, "pacs", name, sizeof name);
    query_option(rec.options, "study", study, sizeof study);
    query_option(rec.options, "series", one, sizeof one);
    store_rec_free(&rec);
    int rc = pacs_named(svc, name, &w->pacs, &w->err);
    if (rc)
        return rc;
    char(*uids)[65] = NULL;
    long *counts = NULL;
    int n = 1;
    if (one[0]) {
        uids = calloc(1, sizeof *uids), counts = calloc(1, sizeof *counts);
        if (!uids || !counts)
            rc = sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
        else
            snprintf(uids[0], 65, "%s", one);
    } else if ((n = study_series(w, study, &uids, &counts)) < 0) {
        rc = n;
    }
    for (int k = 0; !rc && k < n; k++)
        w->n_expected += counts[k];
    snprintf(w->dir, sizeof w->dir, "%s/pull-%s", svc->cfg.data_dir, w->job.claim.id);
    dicom_dir_empty(w->dir); /* a run killed mid-instance left its file: the retrieve writes none over one */
    if (!rc && mkdir(w->dir, 0700) && errno != EEXIST)
        rc = sf_fail(&w->err, SF_EIO, "", "the pull's directory could not be made");
    json_t *done = json_array();
    for (int k = 0; !rc && k < n; k++) {
        const struct sf_progress pr = {pull_poll, w};
        int got = 0;
        long before = w->kept;
        if (w->pacs->dimse) {
            struct dimse_retrieve rq = {w->dir, (uint64_t)svc->cfg.max_body, pulled, w, &pr};
            rc = dimse_get(&w->pacs->peer, svc->cfg.ae_title, study, uids[k], &rq, &got, &w->err);
        } else {
            struct dicomweb_retrieve rq = {w->dir, (uint64_t)svc->cfg.max_body, (int)counts[k], pulled, w, &pr};
            rc = dicomweb_retrieve_series(w->pacs->dw, study, uids[k], &rq, &got, &w->err);
        }
        rc = pacs_failed(rc, &w->err);
        json_array_append_new(done, json_pack("{s:s, s:I}", "uid", uids[k], "instances", (json_int_t)(w->kept - before)));
    }
    rmdir(w->dir); /* (each instance's file removed once kept; one failed half-way is removed by the client) */
    if (!rc) {
        json_t *o = json_pack("{s:s, s:s, s:o, s:I}", "pacs", w->pacs->name, "study", study, "series", done,
                              "instances", (json_int_t)w->kept);
        w->json = o ? json_dumps(o, JSON_COMPACT) : NULL;
        json_decref(o);
        w->len = w->json ? strlen(w->json) : 0;
        if (!w->json)
            rc = sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
        LOG(LOG_INFO, "pull from %s: %ld instances of %d series kept", w->pacs->name, w->kept, n);
    } else {
        json_decref(done);
    }
    free(uids);
    free(counts);
    return rc;
}

static void pacs_finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct pacs_work *w = arg;
    service_job_end(w->job.svc, &w->job.claim, outcome, requeue, (const unsigned char *)w->json, w->json ? w->len : 0,
                    "application/json", NULL, &w->err);
    free(w->json);
    free(w);
}

static const struct job_ops PULL_OPS = {.prepare = pull_prepare, .finish = pacs_finish};

const struct job_kind pull_kind = {.name = "pull", .format = any_format, .validate = pull_validate, .ops = &PULL_OPS,
                                   .work_size = sizeof(struct pacs_work), .result = "application/json"};

/* ---- query ---- */

/* The options a query passes through: every one the user gave (the route reads none itself). */
#define QUERY_MAX_PARAMS 24

/* GET /pacs/{name}/studies: the search made as the request is checked, its answer (the PACS's
 * DICOM JSON, or the C-FIND's matches written so, which name patients) sent back and kept
 * nowhere: a transient kind, no job. */
static int query_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    char name[40];
    snprintf(name, sizeof name, "%.*s", (int)(b->len < 39 ? b->len : 39), b->body ? b->body : "");
    const struct pacs *p;
    int rc = pacs_named(svc, name, &p, err);
    if (rc) { /* (the name is the path's: an unknown one is a resource not found, its message kept) */
        err->code = SF_ENOTFOUND, err->pointer[0] = 0;
        return SF_ENOTFOUND;
    }
    struct dicomweb_param prm[QUERY_MAX_PARAMS];
    char copy[512];
    snprintf(copy, sizeof copy, "%s", b->options ? b->options : "");
    int n = 0;
    for (char *q = copy; *q && n < QUERY_MAX_PARAMS;) {
        char *amp = strchr(q, '&'), *eq;
        if (amp)
            *amp = 0;
        if ((eq = strchr(q, '='))) {
            *eq = 0;
            prm[n++] = (struct dicomweb_param){q, eq + 1};
        }
        q = amp ? amp + 1 : q + strlen(q);
    }
    char *json = NULL;
    size_t len = 0;
    if (p->dimse) {
        struct dimse_key keys[QUERY_MAX_PARAMS];
        for (int k = 0; k < n; k++)
            keys[k] = (struct dimse_key){prm[k].name, prm[k].value};
        rc = dimse_find(&p->peer, svc->cfg.ae_title, DIMSE_STUDIES, NULL, keys, n, &json, &len, err);
        /* DCMTK writes a value it could not convert to UTF-8 as the PACS sent it: not JSON */
        json_t *check = rc ? NULL : json_loadb(json, len, 0, NULL);
        if (!rc && !json_is_array(check))
            rc = sf_fail(err, SF_EFORMAT, "", "the PACS %s answered in a character set surfd cannot convert to UTF-8",
                         p->name);
        json_decref(check);
    } else {
        rc = dicomweb_search(p->search, DICOMWEB_STUDIES, NULL, NULL, prm, n, &json, &len, err);
    }
    if (rc) {
        free(json);
        return pacs_failed(rc, err);
    }
    free(b->body);
    b->body = json, b->len = len;
    return 0;
}

const struct job_kind query_kind = {.name = "query", .validate = query_validate, .transient = true,
                                    .result = "application/dicom+json"};
