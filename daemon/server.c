/* server.c - HTTP on libmicrohttpd: its own thread pool polls with epoll. Handlers never wait on
 * a job or parse a body: a request's body is read into a buffer capped at --max-body (413 is
 * decided from Content-Length before any of it is read; a volume's is streamed to a file), then
 * validated and stored as a job on the checks pool (its connection suspended meanwhile), and
 * answered. A synchronous request suspends its connection; the job's end (or --sync-wait /
 * Prefer: wait=N running out) resumes it, and the handler then answers with the result or 202 +
 * Location. What a handler does itself is a read of the store (one short transaction: a job's or
 * a model's record, a list, a cached mesh) and the answer.
 * Access log: one line per request, without tokens, query strings or bodies. */
#define _GNU_SOURCE /* strcasestr */
#include "server.h"
#include "assets.h"

#include <arpa/inet.h>
#include <ctype.h>
#include <limits.h>
#include <dirent.h>
#include <errno.h>
#include <microhttpd.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../api/iso_json.h"
#include "../api/model_json.h"
#include "../api/job_json.h"
#include "../api/mesh_io.h"
#include "../api/mesh_journal.h"
#include "../api/problem.h"
#include "frames.h"
#include "../api/dicom_instance.h"
#include "../api/query.h"
#include "dicom_node.h"
#include "guard.h"
#include "job_samples.h"
#include "kinds.h"
#include "log.h"
#include "metrics.h"
#include "shares.h"

#ifndef SURFD_VERSION
#define SURFD_VERSION "dev"
#endif

extern const char surfd_openapi_yaml[]; /* generated from api/openapi.yaml */

struct server {
    struct MHD_Daemon *mhd;
    struct service *svc;
    struct guard *guard;      /* header, body and idle deadlines; the connection reserve */
    struct jobq *checks;      /* validates and stores requests' bodies, off the HTTP threads */
};

/* Threads that validate bodies (DCMTK, IGES, JSON trees, volume headers) and store them as jobs:
 * an HTTP thread never parses untrusted bytes or waits on the store for a body (four hostile
 * DICOM parts at once held both HTTP threads, and /livez, for 30 s). */
#define CHECK_THREADS 2

/* Bytes of request bodies held by all connections together; capped at BODY_BUDGET_BODIES bodies
 * of max-body, so that many large uploads at once get 503 instead of exhausting memory. */
#define BODY_BUDGET_BODIES 4
static atomic_long body_bytes;

struct req {
    struct service *svc;
    struct guard *guard;
    struct jobq *checks;
    struct MHD_Connection *conn;
    double t0;
    char method[8];
    char path[256];
    char client[64];
    char *body;
    size_t len, cap;
    long reserved;            /* bytes of body_bytes this request holds */
    bool too_large;           /* over max-body: 413 */
    bool long_query;          /* over QUERY_MAX_ARGS options: 414 */
    int fd;                   /* a streamed body (a kind with .streamed): the file it is written to */
    char upload[1100];        /* its path, "" once the store has taken it */
    bool write_failed;        /* the file would not take the body (a full disk): 503 */
    long long shared;         /* bytes of its owner's upload share it holds while it arrives */
    bool over_share;          /* a body without a length that outgrew the share */
    int share_status;         /* 429, or 413 for a body larger than a whole share */
    char share_detail[256];
    void *map;                /* the file mapped, as body, when it has all arrived */
    bool over_budget;         /* over the shared body budget: 503 */
    bool woken;               /* resumed after a synchronous wait: answer with the job */
    atomic_bool finished;     /* set by the waiter callback before it resumes */
    /* a job's request on the checks pool (suspended meanwhile), and what it found */
    const struct job_kind *kind;
    char format[16];          /* as job_rec's */
    char options[512];
    bool checked;             /* resumed from the pool: answer with what it found */
    int check_rc;             /* validation's SF_E* code (check_err), or 0 */
    struct sf_err check_err;
    int check_status;         /* the store's refusal (503, 429), with check_detail; or 0 */
    const char *check_detail;
    char job[40];
    char owner[64];           /* the token's name ("" in open mode) */
    bool admin;               /* sees every owner's jobs and models */
    int status;
    size_t bytes;
};

/* The owner whose jobs and models a request may see: its own, or NULL for all (an admin token,
 * or open mode). */
static const char *scope(const struct req *r)
{
    return r->svc->n_tokens == 0 || r->admin ? NULL : r->owner;
}

/* Whether a stored job is the request's to see (others' are answered as unknown: 404). */
static bool visible(const struct req *r, const struct job_rec *rec)
{
    const char *o = scope(r);
    return !o || !strcmp(o, rec->owner);
}

struct reply {
    int status;
    const char *type;
    char *body;                /* malloc'd, handed to MHD */
    size_t len;
    const char *hdr[8][2];
};

/* ---- replies -------------------------------------------------------------------------- */

/* The request's Origin when the configuration lets it call (cors-origin), else NULL. */
static const char *cors_origin(const struct req *r)
{
    const char *list = r->svc->cfg.cors_origins;
    const char *o = list[0] ? MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, "Origin") : NULL;
    if (!o || !*o)
        return NULL;
    size_t n = strlen(o);
    for (const char *p = list; *p; p += strcspn(p, " "), p += *p == ' ') {
        size_t m = strcspn(p, " ");
        if ((m == 1 && *p == '*') || (m == n && !strncmp(p, o, n)))
            return o;
    }
    return NULL;
}

static void cors_headers(const struct req *r, struct MHD_Response *resp)
{
    const char *o = cors_origin(r);
    if (!o)
        return;
    MHD_add_response_header(resp, "Access-Control-Allow-Origin", o);
    MHD_add_response_header(resp, "Vary", "Origin");
    MHD_add_response_header(resp, "Access-Control-Expose-Headers",
                            "Location, X-Job-Id, X-Render-Ms, X-Rays, ETag, Content-Disposition, Retry-After");
}

static enum MHD_Result send_reply(struct req *r, struct reply *rp)
{
    struct MHD_Response *resp =
        MHD_create_response_from_buffer(rp->len, rp->body ? rp->body : (char *)"", rp->body ? MHD_RESPMEM_MUST_FREE
                                                                                              : MHD_RESPMEM_PERSISTENT);
    if (!resp) {
        free(rp->body);
        return MHD_NO;
    }
    if (rp->type)
        MHD_add_response_header(resp, MHD_HTTP_HEADER_CONTENT_TYPE, rp->type);
    MHD_add_response_header(resp, "X-Content-Type-Options", "nosniff"); /* every answer, API and page alike */
    for (int k = 0; k < 8 && rp->hdr[k][0]; k++)
        MHD_add_response_header(resp, rp->hdr[k][0], rp->hdr[k][1]);
    if (r->job[0])
        MHD_add_response_header(resp, "X-Job-Id", r->job);
    cors_headers(r, resp);
    r->status = rp->status;
    r->bytes = rp->len;
    enum MHD_Result ok = MHD_queue_response(r->conn, (unsigned)rp->status, resp);
    MHD_destroy_response(resp);
    return ok;
}

static enum MHD_Result problem(struct req *r, int status, const char *detail, const char *pointer)
{
    struct reply rp = {status, "application/problem+json", problem_json(status, detail, pointer), 0, {{0}}};
    rp.len = rp.body ? strlen(rp.body) : 0;
    if (status == 401)
        rp.hdr[0][0] = "WWW-Authenticate", rp.hdr[0][1] = "Bearer realm=\"surfd\"";
    if (status == 429 || status == 503)
        rp.hdr[0][0] = "Retry-After", rp.hdr[0][1] = status == 429 ? "2" : "5";
    return send_reply(r, &rp);
}

/* A store read that failed: damaged bytes (counted, never sent) or another failure. */
static enum MHD_Result damaged_or_failed(struct req *r, int found)
{
    if (found != SF_EDAMAGED)
        return problem(r, 500, "the store failed", NULL);
    metrics_store_damaged();
    LOG(LOG_ERROR, "%s: the store is damaged (bytes that do not match their checksum, or a page SQLite cannot read): not "
                  "served; /readyz is 503 until the operator has run surfd store check and restarted", r->path);
    return problem(r, 500, "the stored data is damaged (its checksum does not match); it is not served", NULL);
}

/* store_get for the request: another owner's job is not found (SF_ENOTFOUND), and *rec holds
 * nothing unless the answer is 0. */
static int get_job(struct req *r, const char *id, bool with_result, struct job_rec *rec)
{
    int found = store_get(r->svc->store, id, false, with_result, rec);
    if (!found && !visible(r, rec))
        found = SF_ENOTFOUND;
    if (found)
        store_rec_free(rec);
    return found;
}

/* The answer to a get_job that found nothing: 404, or the store's failure. */
static enum MHD_Result no_job(struct req *r, int found)
{
    return found == SF_ENOTFOUND ? problem(r, 404, "no such job", NULL) : damaged_or_failed(r, found);
}

static enum MHD_Result problem_err(struct req *r, const struct sf_err *e)
{
    return problem(r, problem_status(e->code), e->message, e->pointer);
}

static enum MHD_Result text(struct req *r, int status, const char *type, const char *s)
{
    struct reply rp = {status, type, strdup(s), strlen(s), {{0}}};
    return send_reply(r, &rp);
}

static enum MHD_Result json_reply(struct req *r, int status, char *json, const char *location)
{
    if (!json)
        return problem(r, 500, "out of memory", NULL);
    struct reply rp = {status, "application/json", json, strlen(json), {{0}}};
    if (location)
        rp.hdr[0][0] = "Location", rp.hdr[0][1] = location;
    return send_reply(r, &rp);
}

/* ---- jobs ------------------------------------------------------------------------------ */

/* A job as the store has it, with this node's live progress when the job runs here (a job
 * whose result is still being encoded or stored reads as running). */
static struct job_view view_of(struct service *svc, const struct job_rec *rec)
{
    struct job_view v = {rec->id,       rec->kind,  job_state_name(rec->state), rec->progress, rec->created,
                         rec->started, rec->finished, rec->error,              rec->attempts, rec->node};
    enum job_state st;
    double progress;
    if (jobq_peek(svc->q, rec->id, &st, &progress) && !job_state_ended(rec->state)) {
        v.state = job_state_name(JOB_RUNNING);
        v.progress = progress > rec->progress ? progress : rec->progress;
    }
    return v;
}

static enum MHD_Result job_resource(struct req *r, int status, const char *id)
{
    struct job_rec rec;
    int found = get_job(r, id, false, &rec);
    if (found)
        return no_job(r, found);
    struct job_view v = view_of(r->svc, &rec);
    char location[80];
    snprintf(location, sizeof location, "/jobs/%s", id);
    if (id != r->job)
        snprintf(r->job, sizeof r->job, "%s", id);
    enum MHD_Result ok = json_reply(r, status, job_json(&v), status == 202 ? location : NULL);
    store_rec_free(&rec);
    return ok;
}

/* A stored result (a job's, or a cached mesh) as its route sends it: a strong ETag of its content
 * (sum; 304 when If-None-Match holds it) and the headers its meta names (a model job's status and
 * Location, a mesh's file name, a render's figures). body is taken. */
static enum MHD_Result send_result(struct req *r, char *body, size_t len, const char *type, const char *meta,
                                   const char *sum)
{
    char etag[48];
    snprintf(etag, sizeof etag, "\"%.32s\"", sum); /* content: strong */
    const char *inm = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_IF_NONE_MATCH);
    if (inm && (strstr(inm, etag) || !strcmp(inm, "*"))) {
        free(body);
        struct reply rp = {304, NULL, NULL, 0, {{"ETag", etag}}};
        return send_reply(r, &rp);
    }
    struct reply rp = {200, type, body, len, {{"ETag", etag}}};
    char ms[32] = "", rays[32] = "", location[80] = "", disposition[96] = "", tol[32] = "";
    const char *m = meta ? strstr(meta, "\"render_ms\":") : NULL;
    if (m)
        snprintf(ms, sizeof ms, "%.*s", (int)strcspn(m + 12, ",}"), m + 12);
    const char *y = meta ? strstr(meta, "\"rays\":") : NULL;
    if (y)
        snprintf(rays, sizeof rays, "%.*s", (int)strcspn(y + 7, ",}"), y + 7);
    const char *st = meta ? strstr(meta, "\"status\":") : NULL; /* a model job's 201 */
    const char *lo = meta ? strstr(meta, "\"location\":\"") : NULL;
    const char *fn = meta ? strstr(meta, "\"filename\":\"") : NULL; /* a mesh's download */
    const char *tl = meta ? strstr(meta, "\"tolerance_mm\":") : NULL; /* the mesh's chord tolerance */
    const char *sg = meta ? strstr(meta, "\"seg_grid\":\"") : NULL; /* a SEG's grid: series, model or spacing */
    char grid[16] = "";
    int h = 1;
    if (st)
        rp.status = atoi(st + 9);
    if (lo)
        snprintf(location, sizeof location, "%.*s", (int)strcspn(lo + 12, "\""), lo + 12);
    if (location[0])
        rp.hdr[h][0] = "Location", rp.hdr[h++][1] = location;
    if (fn) {
        snprintf(disposition, sizeof disposition, "attachment; filename=\"%.*s\"", (int)strcspn(fn + 12, "\""), fn + 12);
        rp.hdr[h][0] = "Content-Disposition", rp.hdr[h++][1] = disposition;
    }
    if (tl) {
        snprintf(tol, sizeof tol, "%.*s", (int)strcspn(tl + 15, ",}"), tl + 15);
        rp.hdr[h][0] = "X-Mesh-Tolerance-Mm", rp.hdr[h++][1] = tol;
    }
    if (sg)
        snprintf(grid, sizeof grid, "%.*s", (int)strcspn(sg + 12, "\""), sg + 12);
    if (grid[0])
        rp.hdr[h][0] = "X-Seg-Grid", rp.hdr[h++][1] = grid;
    if (ms[0])
        rp.hdr[h][0] = "X-Render-Ms", rp.hdr[h++][1] = ms;
    if (rays[0])
        rp.hdr[h][0] = "X-Rays", rp.hdr[h++][1] = rays;
    return send_reply(r, &rp);
}

/* The job's result as its route would have sent it: the image (200), or the job's problem. */
static enum MHD_Result job_result(struct req *r, const char *id, bool sync)
{
    struct job_rec rec;
    int found = get_job(r, id, true, &rec);
    if (found)
        return no_job(r, found);
    if (id != r->job)
        snprintf(r->job, sizeof r->job, "%s", id);
    enum MHD_Result ok;
    if (rec.state == JOB_SUCCEEDED && rec.result) {
        ok = send_result(r, (char *)rec.result, rec.result_len, rec.result_type, rec.meta,
                         rec.result_sum[0] ? rec.result_sum : id);
        rec.result = NULL; /* taken */
    } else if (rec.state == JOB_FAILED && rec.error) {
        int status = 500;
        const char *s = strstr(rec.error, "\"status\":");
        if (s)
            status = atoi(s + 9);
        struct reply rp = {status, "application/problem+json", strdup(rec.error), strlen(rec.error), {{0}}};
        ok = send_reply(r, &rp);
    } else if (rec.state == JOB_CANCELLED) {
        ok = problem(r, 409, "the job was cancelled", NULL);
    } else {
        store_rec_free(&rec);
        return sync ? job_resource(r, 202, id) : problem(r, 409, "the job has not finished; see its state", NULL);
    }
    store_rec_free(&rec);
    return ok;
}

struct list_ctx {
    struct service *svc;
    struct job_view *v;
    struct job_rec *recs;
    int n, cap;
};

static void collect(const struct job_rec *rec, void *arg)
{
    struct list_ctx *c = arg;
    if (c->n == c->cap)
        return;
    c->recs[c->n] = *rec;
    /* the store frees rec's strings after the call: keep copies */
    c->recs[c->n].error = rec->error ? strdup(rec->error) : NULL;
    c->recs[c->n].meta = NULL;
    c->n++;
}

static enum MHD_Result job_list(struct req *r)
{
    const char *name = MHD_lookup_connection_value(r->conn, MHD_GET_ARGUMENT_KIND, "state");
    enum job_state state;
    if (name && !job_state_parse(name, &state))
        return problem(r, 422, "state is queued, running, succeeded, failed or cancelled", "?state");
    enum { LIST_MAX = 1000 };
    struct list_ctx c = {r->svc, calloc(LIST_MAX, sizeof(struct job_view)), calloc(LIST_MAX, sizeof(struct job_rec)),
                         0, LIST_MAX};
    if (!c.v || !c.recs) {
        free(c.v);
        free(c.recs);
        return problem(r, 500, "out of memory", NULL);
    }
    int listed = store_list(r->svc->store, name ? &state : NULL, scope(r), LIST_MAX, collect, &c);
    for (int k = 0; k < c.n; k++)
        c.v[k] = view_of(r->svc, &c.recs[k]);
    enum MHD_Result ok = listed ? damaged_or_failed(r, listed) : json_reply(r, 200, job_list_json(c.v, c.n), NULL);
    for (int k = 0; k < c.n; k++)
        free(c.recs[k].error);
    free(c.v);
    free(c.recs);
    return ok;
}

/* ---- POST /render --------------------------------------------------------------------------- */

struct opts {
    char buf[512];
    size_t n;
    bool bad;
    const char *skip;        /* an option the route reads itself (not the job's), or NULL */
};

/* Appends one query option; a name or value with a NUL in it (%00) or '&' or '=' is refused. */
static enum MHD_Result add_opt(void *cls, enum MHD_ValueKind kind, const char *key, size_t key_size,
                               const char *value, size_t value_size)
{
    (void)kind;
    struct opts *o = cls;
    if (o->skip && !strcmp(key, o->skip))
        return MHD_YES;
    if (!value)
        value = "";
    if (strlen(key) != key_size || strlen(value) != value_size || strpbrk(key, "&=") || strpbrk(value, "&=") ||
        o->n + strlen(key) + strlen(value) + 2 >= sizeof o->buf) {
        o->bad = true;
        return MHD_NO;
    }
    o->n += (size_t)snprintf(o->buf + o->n, sizeof o->buf - o->n, "%s%s=%s", o->n ? "&" : "", key, value);
    return MHD_YES;
}

/* Reads the query's options into o; false (after answering 422) when one is malformed. */
static bool query_options(struct req *r, struct opts *o, enum MHD_Result *answer)
{
    MHD_get_connection_values_n(r->conn, MHD_GET_ARGUMENT_KIND, add_opt, o);
    if (o->bad)
        *answer = problem(r, 422, "query options must be short name=value pairs without '&', '=' or NUL", NULL);
    return !o->bad;
}

/* Prefer: respond-async, wait=N (RFC 7240). */
static void prefer(struct req *r, bool *async, double *wait)
{
    *async = false;
    *wait = (double)r->svc->cfg.sync_wait;
    const char *p = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, "Prefer");
    if (!p)
        return;
    if (strcasestr(p, "respond-async"))
        *async = true;
    const char *w = strcasestr(p, "wait=");
    if (w) {
        double v = atof(w + 5);
        if (v >= 0 && v < *wait)
            *wait = v;
    }
}

static void woken(void *arg, bool finished)
{
    struct req *r = arg;
    atomic_store(&r->finished, finished);
    r->woken = true;
    MHD_resume_connection(r->conn);
}

/* The routes ?series=UID reads a stored series on, instead of a body (dicom_node.h). */
#define SERIES_ROUTES (IN_ISOSURFACE | IN_MODEL | IN_MATRIX)

/* On the checks pool: validates the request's body as its kind reads it, and stores it as a job
 * (r->job), or says why not (check_rc, check_status). */
static int check_and_store(struct job *j, void *arg, int *n_bands)
{
    (void)j;
    struct req *r = arg;
    struct service *svc = r->svc;
    *n_bands = 0;
    char uid[72];
    query_option(r->options, "series", uid, sizeof uid);
    if (uid[0] && (r->kind->route & SERIES_ROUTES)) { /* a stored series: the body it makes, as if posted */
        char *made;
        size_t n;
        size_t most = r->kind->streamed ? (size_t)svc->cfg.max_volume : (size_t)svc->cfg.max_body;
        r->check_rc = series_request(svc, uid, r->kind->route == IN_MODEL, most, &made, &n, &r->check_err);
        if (r->check_rc)
            return 0;
        free(r->body); /* (none: ?series takes no body) */
        r->body = made, r->len = n;
        if (r->upload[0]) { /* the streamed body's empty file: the job keeps the series' bytes instead */
            unlink(r->upload);
            r->upload[0] = 0;
        }
    }
    struct job_body b = {r->body, r->len, r->format, r->options, scope(r)};
    r->check_rc = r->kind->validate(svc, &b, &r->check_err);
    if (r->check_rc) /* (a refused allocation: the job-memory budget's 422, not a 500) */
        r->check_rc = service_outgrown(&r->check_err);
    if (r->kind->transient) { /* answered now, kept nowhere */
        r->body = b.body, r->len = b.len;
        return 0;
    }
    r->body = b.body; /* validate may have replaced it */
    r->len = b.len;
    if (r->check_rc)
        return 0;
    bool draining = atomic_load(&svc->draining);
    long queued = draining ? 0 : store_queued(svc->store);
    if (draining || queued < 0 || queued >= svc->cfg.queue_max) {
        r->check_status = draining || queued < 0 ? 503 : 429;
        r->check_detail = draining     ? "the service is shutting down"
                          : queued < 0 ? "the store cannot take the job now"
                                       : "the job queue is full; try again shortly";
        return 0;
    }
    struct job_rec rec = {0};
    service_new_id(rec.id);
    snprintf(rec.kind, sizeof rec.kind, "%s", r->kind->name);
    snprintf(rec.format, sizeof rec.format, "%s", r->format);
    snprintf(rec.options, sizeof rec.options, "%s", r->options);
    snprintf(rec.owner, sizeof rec.owner, "%s", r->owner);
    rec.created = wall_s();
    rec.request = (unsigned char *)(r->body ? r->body : "");
    rec.request_len = r->len;
    struct stat sb;
    bool upload = r->upload[0] && !fstat(r->fd, &sb);
    int stored = r->upload[0] ? store_submit_file(svc->store, &rec, r->upload) : store_submit(svc->store, &rec);
    r->upload[0] = 0; /* the store has it, or removed it */
    if (!stored && upload)
        shares_stored(svc->shares, r->owner, (long long)sb.st_size);
    if (stored) {
        r->check_status = 503;
        r->check_detail = "the store cannot take the job now";
    } else {
        snprintf(r->job, sizeof r->job, "%s", rec.id);
        service_wake(svc);
    }
    return 0;
}

static void checked(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j, (void)requeue;
    struct req *r = arg;
    if (outcome != JOB_SUCCEEDED && !r->check_rc && !r->job[0]) { /* never run: the service stopped */
        r->check_status = 503;
        r->check_detail = "the service is shutting down";
    }
    r->checked = true;
    MHD_resume_connection(r->conn); /* the last touch of r here: the handler answers */
}

static const struct job_ops CHECK_OPS = {.prepare = check_and_store, .finish = checked};

/* A job's request: validated and stored on the checks pool while the connection is suspended;
 * the handler, called again, answers (answer_job). */
static enum MHD_Result submit(struct req *r, const struct job_kind *kind, const char *format, const char *options)
{
    static atomic_ulong n_checks;
    char id[32];
    r->kind = kind;
    snprintf(r->format, sizeof r->format, "%s", format);
    snprintf(r->options, sizeof r->options, "%s", options);
    snprintf(id, sizeof id, "check-%lu", atomic_fetch_add(&n_checks, 1));
    MHD_suspend_connection(r->conn);
    if (jobq_submit(r->checks, id, &CHECK_OPS, r, false)) {
        MHD_resume_connection(r->conn);
        return problem(r, 503, "too many requests are being read; try again shortly", NULL);
    }
    return MHD_YES;
}

/* Answers a request the checks pool has seen: its problem, or its job at once (async, 202), or
 * after the job ends (on this node or another) or the wait runs out. */
static enum MHD_Result answer_job(struct req *r)
{
    struct service *svc = r->svc;
    r->checked = false;
    if (r->check_rc)
        return problem_err(r, &r->check_err);
    if (r->check_status)
        return problem(r, r->check_status, r->check_detail, NULL);
    if (r->kind->transient) {
        struct reply rp = {200, r->kind->result, r->body, r->body ? r->len : 0, {{0}}};
        r->body = NULL; /* handed to MHD (a transient kind's request is never mapped) */
        return send_reply(r, &rp);
    }
    bool async;
    double wait;
    prefer(r, &async, &wait);
    if (async || wait <= 0)
        return job_resource(r, 202, r->job);
    MHD_suspend_connection(r->conn);
    jobq_wait(svc->q, r->job, monotonic_s() + wait, woken, r);
    /* an end stored before the wait began would wake nobody */
    struct job_rec now;
    if (store_get(svc->store, r->job, false, false, &now) || job_state_ended(now.state))
        jobq_notify(svc->q, r->job);
    store_rec_free(&now);
    return MHD_YES;
}

/* POST of a kind's request: its body format from Content-Type (or ?format=), its validation, and
 * the job; model (NULL: none) the stored model it is about, as ?model (a route's {id}). */
static enum MHD_Result post_job_on(struct req *r, const struct job_kind *kind, const char *model)
{
    const char *ct = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_TYPE);
    const char *format = kind->format(ct);
    const char *qf = kind->format_in_query ? MHD_lookup_connection_value(r->conn, MHD_GET_ARGUMENT_KIND, "format")
                                           : NULL;
    char d[1024];
    if (qf && *qf) { /* by any of its names: the job carries the table's (an empty one: none) */
        const struct input_format *f = input_format_named(qf, kind->route);
        if (!f) {
            char names[256];
            input_format_names(kind->route, names, sizeof names);
            snprintf(d, sizeof d, "POST %.60s reads %s (or their other names: GET /formats), not \"%.40s\"", r->path,
                     names, qf);
            return problem(r, 400, d, "?format");
        }
        format = f->name;
    }
    if (kind->route && MHD_lookup_connection_value(r->conn, MHD_GET_ARGUMENT_KIND, "series")) { /* a stored series */
        if (!(kind->route & SERIES_ROUTES))
            return problem(r, 400, "series= is read by POST /isosurface, /model and /matrix-model", "?series");
        if (r->len)
            return problem(r, 400, "series= reads a stored series: send the request without a body", "?series");
        format = "dicom";
    }
    if (!format) {
        char said[768];
        input_formats_said(kind->route, said, sizeof said);
        snprintf(d, sizeof d, "POST %.60s reads %s; not %.80s", r->path, said, ct ? ct : "a body without a type");
        return problem(r, 415, d, NULL);
    }
    struct opts o = {.n = 0};
    enum MHD_Result answer;
    if (!query_options(r, &o, &answer))
        return answer;
    if (model) /* (the last of a repeated option counts: a ?model in the query changes nothing) */
        o.n += (size_t)snprintf(o.buf + o.n, sizeof o.buf - o.n, "%smodel=%s", o.n ? "&" : "", model);
    if (o.n >= sizeof o.buf)
        return problem(r, 422, "query options must be short name=value pairs without '&', '=' or NUL", NULL);
    return submit(r, kind, format, o.buf);
}

static enum MHD_Result post_job(struct req *r, const struct job_kind *kind) { return post_job_on(r, kind, NULL); }

/* ---- models ------------------------------------------------------------------------------- */

struct model_list {
    char *buf;
    size_t n, cap;
    int count;
    bool failed;
};

/* Appends s to the list's buffer (keeping room for the closing "]}"). */
static void list_put(struct model_list *l, const char *s)
{
    size_t m = strlen(s);
    if (!l->failed && l->n + m + 3 > l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 4096;
        while (cap < l->n + m + 3)
            cap *= 2;
        char *b = realloc(l->buf, cap);
        l->failed = !b;
        if (b)
            l->buf = b, l->cap = cap;
    }
    if (!l->failed) {
        memcpy(l->buf + l->n, s, m + 1);
        l->n += m;
    }
}

static void add_resource(const char *resource, void *arg)
{
    struct model_list *l = arg;
    if (l->count++)
        list_put(l, ",");
    list_put(l, resource);
}

static enum MHD_Result model_list(struct req *r)
{
    struct model_list l = {0};
    list_put(&l, "{\"models\":[");
    int listed = store_model_list(r->svc->store, scope(r), 1000, add_resource, &l);
    if (listed || l.failed) {
        free(l.buf);
        return listed ? damaged_or_failed(r, listed) : problem(r, 500, "out of memory", NULL);
    }
    list_put(&l, "]}");
    return json_reply(r, 200, l.buf, NULL);
}

/* A job of a kind made by a GET on a model: its request is body (made here), its options the
 * query's. */
static enum MHD_Result model_job(struct req *r, const struct job_kind *kind, char *body, const char *format)
{
    free(r->body);
    r->body = body;
    if (!body)
        return problem(r, 500, "out of memory", NULL);
    r->len = strlen(body);
    struct opts o = {.n = 0};
    enum MHD_Result answer;
    if (!query_options(r, &o, &answer))
        return answer;
    return submit(r, kind, format, o.buf);
}

/* GET /models/{id}/render: a render job of the scene {"objects": [{"type": "model", "id": ...}]},
 * with the query's render options. GET /models/{id}/mesh and /patches: a job of that kind (they
 * can take seconds and hundreds of megabytes, which no HTTP thread should spend), its request the
 * model's id. Each is answered as any job: the result when it ends within the wait, else 202. */
/* Whether model id is the request's to see; answers 404 (or the store's failure) when not. */
static bool model_found(struct req *r, const char *id, char **resource, enum MHD_Result *answer)
{
    int found = store_model_get(r->svc->store, id, scope(r), resource, NULL, NULL);
    if (found)
        *answer = found == SF_ENOTFOUND ? problem(r, 404, "no such model", NULL) : damaged_or_failed(r, found);
    return !found;
}

/* GET /models/{id}/mesh?format=delta&since=V (API.md, "Interactive isosurfaces"): since=0 is the
 * whole mesh (a mesh job, cached as any); a later version the changes after it, composed from the
 * model's journal (store.h) here, or across a change of every triangle with the mesh read whole
 * (delta_kind, on the checks pool), or 410 when the journal no longer reaches back to it
 * (compacted, or a model whose edits rewrite its whole mesh), so that a client loads since=0.
 * *answered false: the request goes on as a mesh job (since=0). */
static enum MHD_Result delta_request(struct req *r, const char *id, bool *answered)
{
    const char *f = MHD_lookup_connection_value(r->conn, MHD_GET_ARGUMENT_KIND, "format");
    const char *s = MHD_lookup_connection_value(r->conn, MHD_GET_ARGUMENT_KIND, "since");
    *answered = false;
    if (!f || strcmp(f, "delta"))
        return MHD_YES;
    *answered = true;
    char *end = NULL, *resource = NULL;
    long since = s && *s ? strtol(s, &end, 10) : 0;
    if (s && *s && (*end || since < 0 || since > INT_MAX))
        return problem(r, 422, "since is a version of the model (0: the whole mesh)", "?since");
    enum MHD_Result answer;
    if (!model_found(r, id, &resource, &answer))
        return answer;
    long version = model_version(resource);
    free(resource);
    char detail[160];
    if (since > version) {
        snprintf(detail, sizeof detail, "the model is at version %ld: since=%ld is after it", version, since);
        return problem(r, 422, detail, "?since");
    }
    if (since == 0) {
        *answered = false;
        return MHD_YES;
    }
    char *out = NULL;
    size_t len = 0;
    long to;
    int rc = store_delta(r->svc->store, id, since, NULL, 0, &out, &len, &to);
    if (rc == SF_ELIMIT) /* (across a whole change: the current mesh read whole, on the checks pool) */
        return model_job(r, &delta_kind, strdup(id), "");
    if (!rc && to < version) {
        free(out);
        rc = SF_ENOTFOUND;
    }
    if (rc == SF_ENOTFOUND) {
        snprintf(detail, sizeof detail, "the changes from version %ld to %ld are not kept: load since=0 (the whole mesh)",
                 since, version);
        return problem(r, 410, detail, "?since");
    }
    if (rc)
        return rc == SF_ENOMEM ? problem(r, 500, "out of memory", NULL) : damaged_or_failed(r, rc);
    struct reply rp = {200, "application/vnd.surfd.mesh-delta", out, len, {{0}}};
    return send_reply(r, &rp);
}

static enum MHD_Result model_output(struct req *r, const char *id, const struct job_kind *kind)
{
    if (kind == &mesh_kind) {
        bool answered;
        enum MHD_Result a = delta_request(r, id, &answered);
        if (answered)
            return a;
    }
    if (kind == &mesh_kind && r->svc->cfg.mesh_cache > 0) { /* computed once: from the cache when it has it */
        struct opts o = {.n = 0};
        enum MHD_Result answer;
        char key[96];
        struct sf_err err = {0};
        if (!query_options(r, &o, &answer))
            return answer;
        char *resource = NULL;
        bool stored = !store_model_get(r->svc->store, id, scope(r), &resource, NULL, NULL);
        long edits = stored ? iso_model_edits(resource) : 0;
        free(resource);
        if (model_mesh_key(o.buf, edits, key, sizeof key, &err))
            return problem_err(r, &err);
        struct mesh_rec m;
        int found = store_mesh_get(r->svc->store, id, key, &m);
        metrics_mesh_cache(found == 0);
        if (!found) {
            enum MHD_Result ok = send_result(r, (char *)m.data, m.len, m.type, m.meta, m.sum);
            m.data = NULL; /* taken */
            store_mesh_free(&m);
            return ok;
        }
        if (found == SF_EDAMAGED)
            LOG(LOG_WARN, "model %s: a cached mesh does not match its checksum; made again", id);
    }
    if (kind != &render_kind)
        return model_job(r, kind, strdup(id), "");
    char *scene = malloc(128);
    if (scene)
        snprintf(scene, 128, "{\"objects\":[{\"type\":\"model\",\"id\":\"%s\"}]}", id);
    return model_job(r, &render_kind, scene, "json");
}


static enum MHD_Result model_resource(struct req *r, const char *id)
{
    char *resource = NULL;
    enum MHD_Result ok;
    if (!model_found(r, id, &resource, &ok))
        return ok;
    if (!strcmp(r->method, "DELETE")) {
        int gone = store_model_delete(r->svc->store, id, scope(r));
        ok = gone && gone != SF_ENOTFOUND ? problem(r, 500, "the store failed", NULL) : text(r, 204, NULL, "");
    } else { /* a model changes only by its edits and by its figures measured after them (topology_version):
              * its id, their count and that version are a strong tag */
        char etag[80];
        long topo = iso_model_topology(resource);
        if (topo > 0)
            snprintf(etag, sizeof etag, "\"%s.%ld.t%ld\"", id, iso_model_edits(resource), topo);
        else
            snprintf(etag, sizeof etag, "\"%s.%ld\"", id, iso_model_edits(resource));
        const char *inm = MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_IF_NONE_MATCH);
        struct reply rp = {200, "application/json", resource, strlen(resource), {{"ETag", etag}}};
        if (inm && (strstr(inm, etag) || !strcmp(inm, "*")))
            rp = (struct reply){304, NULL, NULL, 0, {{"ETag", etag}}};
        else
            resource = NULL; /* handed to MHD */
        ok = send_reply(r, &rp);
    }
    free(resource);
    return ok;
}

static enum MHD_Result model_sub(struct req *r, const char *id, const struct job_kind *kind)
{
    enum MHD_Result ok;
    return model_found(r, id, NULL, &ok) ? model_output(r, id, kind) : ok;
}
static enum MHD_Result model_mesh_route(struct req *r, const char *id) { return model_sub(r, id, &mesh_kind); }
static enum MHD_Result model_patches_route(struct req *r, const char *id) { return model_sub(r, id, &patches_kind); }
static enum MHD_Result model_view_route(struct req *r, const char *id) { return model_sub(r, id, &render_kind); }
static enum MHD_Result model_rtstruct_route(struct req *r, const char *id) { return model_sub(r, id, &rtstruct_kind); }
static enum MHD_Result model_send_route(struct req *r, const char *id) { return model_sub(r, id, &send_kind); }

/* POST /models/{id}/iso?value=V: the same for a new iso. */
static enum MHD_Result model_iso_route(struct req *r, const char *id)
{
    enum MHD_Result ok;
    return model_found(r, id, NULL, &ok) ? post_job_on(r, &iso_kind, id) : ok;
}

/* POST /models/{id}/edit: an edit job of the model (the token's), its id in ?model. */
static enum MHD_Result model_edit_route(struct req *r, const char *id)
{
    enum MHD_Result ok;
    return model_found(r, id, NULL, &ok) ? post_job_on(r, &edit_kind, id) : ok;
}

/* ---- routing ---------------------------------------------------------------------------- */

/* Finds the request's bearer token; sets r->owner and r->admin from it. The whole header value is
 * compared (its length from libmicrohttpd, so "TOKEN\0junk" is not TOKEN), in time that depends on
 * the secrets' lengths only, every token compared. */
static bool authorised(struct req *r)
{
    struct service *svc = r->svc;
    if (svc->n_tokens == 0)
        return true;
    const char *h = NULL;
    size_t hn = 0;
    if (MHD_lookup_connection_value_n(r->conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_AUTHORIZATION,
                                      strlen(MHD_HTTP_HEADER_AUTHORIZATION), &h, &hn) != MHD_YES ||
        hn < 7 || strncasecmp(h, "Bearer ", 7))
        return false;
    const char *tok = h + 7;
    size_t n = hn - 7;
    const struct token *found = NULL;
    for (size_t k = 0; k < svc->n_tokens; k++) {
        const char *t = svc->tokens[k].secret;
        size_t m = strlen(t);
        unsigned diff = (unsigned)(m ^ n);
        for (size_t i = 0; i < m; i++)
            diff |= (unsigned char)t[i] ^ (unsigned char)(i < n ? tok[i] : 0);
        if (diff == 0)
            found = &svc->tokens[k];
    }
    if (found) {
        snprintf(r->owner, sizeof r->owner, "%s", found->name);
        r->admin = found->admin;
    }
    return found != NULL;
}

/* An id a route's path holds: a job or model id, or a series' UID (64 at most). */
#define ROUTE_ID 72

static bool valid_id(const char *s, size_t n)
{
    if (n == 0 || n >= 40)
        return false;
    for (size_t k = 0; k < n; k++)
        if (!isxdigit((unsigned char)s[k]))
            return false;
    return true;
}

/* A PACS's name in a path (/pacs/{name}/studies): letters, digits, '-' and '_' (pacs.h). */
static bool valid_name(const char *s, size_t n)
{
    if (n == 0 || n > 31)
        return false;
    for (size_t k = 0; k < n; k++)
        if (!isalnum((unsigned char)s[k]) && s[k] != '-' && s[k] != '_')
            return false;
    return true;
}

/* A DICOM UID in a path (/series/{uid}): digits and dots, 64 at most (dicom_instance.h). */
static bool valid_uid(const char *s, size_t n)
{
    char uid[65];
    if (n == 0 || n > 64)
        return false;
    snprintf(uid, sizeof uid, "%.*s", (int)n, s);
    return dicom_uid_valid(uid);
}

/* "{id}" or "{id}/rest" after a collection's prefix: the id (hex, as issued) into id, *rest at the
 * '/' or NULL. false for anything else. */
static bool split_id(const char *s, char kind, char id[ROUTE_ID], const char **rest)
{
    *rest = strchr(s, '/');
    size_t n = *rest ? (size_t)(*rest - s) : strlen(s);
    if (!(kind == 'u' ? valid_uid(s, n) : kind == 'n' ? valid_name(s, n) : valid_id(s, n)))
        return false;
    snprintf(id, ROUTE_ID, "%.*s", (int)n, s);
    return true;
}

/* GET /rtstruct?models=ID,ID,...: one rtstruct job of every listed model (the token's), its request
 * the list; the cap, the ids, their owner, frame and study checked here, before any job. The
 * list is the route's, not the job's options (a long list would not fit them). */
/* GET /rtstruct?models=... (kind rtstruct) and POST /rtstruct/send?models=...&pacs= (kind send): the
 * models listed, each the request's to see, of one frame of reference, as the job's request. */
static enum MHD_Result rtstruct_set_of(struct req *r, const struct job_kind *kind)
{
    const char *list = MHD_lookup_connection_value(r->conn, MHD_GET_ARGUMENT_KIND, "models");
    if (!list || !*list)
        return problem(r, 422, "?models lists the models to export, comma-separated ids", "?models");
    int n = 1;
    for (const char *c = list; *c; c++)
        n += *c == ',';
    if (n > MODEL_RTSTRUCT_MAX_MODELS) {
        char detail[128];
        snprintf(detail, sizeof detail, "%d models listed: one structure set holds at most %d", n,
                 MODEL_RTSTRUCT_MAX_MODELS);
        return problem(r, 422, detail, "?models");
    }
    char(*ids)[40] = calloc((size_t)n, sizeof *ids), **resources = calloc((size_t)n, sizeof *resources);
    const char **id_of = calloc((size_t)n, sizeof *id_of);
    char *body = malloc(strlen(list) + 1);
    enum MHD_Result answer = MHD_NO;
    bool answered = false;
    if (!ids || !resources || !id_of || !body) {
        answer = problem(r, 500, "out of memory", NULL), answered = true;
        goto out_free;
    }
    const char *at = list;
    for (int k = 0; k < n; k++) {
        size_t len = strcspn(at, ",");
        char detail[128];
        if (!valid_id(at, len)) {
            snprintf(detail, sizeof detail, "no such model: \"%.*s\"", (int)(len < 40 ? len : 40), at);
            answer = problem(r, len ? 404 : 422, len ? detail : "?models has an empty entry", "?models"), answered = true;
            goto out_free;
        }
        snprintf(ids[k], sizeof ids[k], "%.*s", (int)len, at);
        id_of[k] = ids[k];
        int found = store_model_get(r->svc->store, ids[k], scope(r), &resources[k], NULL, NULL);
        if (found) {
            snprintf(detail, sizeof detail, "no such model: %s", ids[k]);
            answer = found == SF_ENOTFOUND ? problem(r, 404, detail, "?models") : damaged_or_failed(r, found);
            answered = true;
            goto out_free;
        }
        at += len + (at[len] == ',');
    }
    struct sf_err err = {0};
    if (model_rtstruct_check(id_of, (const char *const *)resources, n, &err)) {
        answer = problem_err(r, &err), answered = true;
        goto out_free;
    }
    size_t used = 0; /* the request: the ids as checked */
    for (int k = 0; k < n; k++)
        used += (size_t)sprintf(body + used, "%s%s", k ? "," : "", ids[k]);
    free(r->body);
    r->body = body;
    r->len = used;
    body = NULL;
    struct opts o = {.n = 0, .skip = "models"};
    if (query_options(r, &o, &answer))
        answer = submit(r, kind, "", o.buf);
    answered = true;
out_free:
    for (int k = 0; resources && k < n; k++)
        free(resources[k]);
    free(resources);
    free(id_of);
    free(ids);
    free(body);
    return answered ? answer : problem(r, 500, "out of memory", NULL);
}

static enum MHD_Result rtstruct_set_route(struct req *r, const char *unused)
{
    (void)unused;
    return rtstruct_set_of(r, &rtstruct_kind);
}

static enum MHD_Result rtstruct_send_route(struct req *r, const char *unused)
{
    (void)unused;
    return rtstruct_set_of(r, &send_kind);
}

/* ---- the route table ---- */

static enum MHD_Result livez(struct req *r, const char *id)
{
    (void)id;
    return text(r, 200, "text/plain", "ok\n");
}

static enum MHD_Result readyz(struct req *r, const char *id)
{
    (void)id;
    if (atomic_load(&r->svc->draining))
        return problem(r, 503, "draining", NULL);
    if (store_damaged(r->svc->store))
        return problem(r, 503, "the store is damaged (see the log, and surfd store check)", NULL);
    return store_writable(r->svc->store) ? text(r, 200, "text/plain", "ready\n")
                                          : problem(r, 503, "the store is not writable", NULL);
}

static enum MHD_Result version(struct req *r, const char *id)
{
    (void)id;
    return text(r, 200, "application/json", "{\"name\":\"surfd\",\"version\":\"" SURFD_VERSION "\"}");
}

/* The input formats (api/formats.h's table), as the page and the Python client choose a route by. */
static enum MHD_Result formats(struct req *r, const char *id)
{
    (void)id;
    char *t = input_formats_json();
    if (!t)
        return problem(r, 500, "out of memory", NULL);
    struct reply rp = {200, "application/json", t, strlen(t), {{0}}};
    return send_reply(r, &rp);
}

static enum MHD_Result metrics(struct req *r, const char *id)
{
    (void)id;
    struct service *svc = r->svc;
    struct jobq_stats qs;
    jobq_stats(svc->q, &qs);
    long queued = store_queued(svc->store), meshes = store_mesh_bytes(svc->store); /* -1: the store failed */
    struct metrics_gauges g = {monotonic_s() - svc->started_mono, qs.queued, qs.running, qs.queue_max, qs.workers,
                               queued < 0 ? -1 : queued, meshes < 0 ? -1 : meshes, frames_bytes(svc->frames),
                               service_n_stranded(svc)};
    char *t = metrics_text(&g);
    if (!t)
        return problem(r, 500, "metrics failed", NULL);
    struct reply rp = {200, "text/plain; version=0.0.4", t, strlen(t), {{0}}};
    return send_reply(r, &rp);
}

static enum MHD_Result openapi(struct req *r, const char *id)
{
    (void)id;
    return text(r, 200, "application/yaml", surfd_openapi_yaml);
}

/* The web page's files (assets.h): open to all, like the spec they hold no data; the page asks
 * for the token itself. Its script and styles come from here alone (the policy says so). */
static enum MHD_Result web_asset(struct req *r, const char *id)
{
    (void)id;
    for (const struct asset *a = surfd_assets; a->path; a++) {
        if (strcmp(a->path, r->path))
            continue;
        char *body = malloc(a->len + 1);
        if (!body)
            return problem(r, 500, "out of memory", NULL);
        memcpy(body, a->data, a->len + 1);
        struct reply rp = {200, a->type, body, a->len,
                           {{"Cache-Control", "no-cache"},
                            {"Content-Security-Policy", "default-src 'self'; img-src 'self' blob: data:; "
                                                        "frame-ancestors 'none'; base-uri 'none'; form-action 'none'"}}};
        return send_reply(r, &rp);
    }
    return problem(r, 404, "no such file", NULL);
}

static enum MHD_Result models(struct req *r, const char *id)
{
    (void)id;
    return model_list(r);
}

/* ---- DICOM series (dicom_node.h): the site's, received or pulled; any token sees them ---- */

/* GET /models/{id}/volume, /series/{uid}/volume: the samples as NRRD, read on the checks pool
 * (job_samples.c); GET /pacs: the PACS configured, by name. */
static enum MHD_Result model_volume_route(struct req *r, const char *id)
{
    return model_job(r, &samples_kind, strdup(id), "model");
}
static enum MHD_Result series_volume_route(struct req *r, const char *uid)
{
    return model_job(r, &samples_kind, strdup(uid), "series");
}
static enum MHD_Result pacs_list(struct req *r, const char *id)
{
    (void)id;
    return json_reply(r, 200, pacs_list_json(r->svc), NULL);
}

/* GET /pacs/{name}/studies?...: a QIDO-RS search of the PACS, its options passed through, by a job
 * (a PACS may take seconds; no HTTP thread waits on it). */
static enum MHD_Result pacs_studies(struct req *r, const char *name) { return model_job(r, &query_kind, strdup(name), ""); }

struct series_listing {
    struct service *svc;
    struct model_list l;
};

static void add_series(const struct series_rec *rec, void *arg)
{
    struct series_listing *s = arg;
    char *one = series_resource(s->svc, rec, false);
    if (!one)
        s->l.failed = true;
    else
        add_resource(one, &s->l);
    free(one);
}

static enum MHD_Result series_list(struct req *r, const char *id)
{
    (void)id;
    struct series_listing s = {r->svc, {0}};
    list_put(&s.l, "{\"series\":[");
    int listed = store_series_list(r->svc->store, NULL, add_series, &s);
    if (listed || s.l.failed) {
        free(s.l.buf);
        return listed ? damaged_or_failed(r, listed) : problem(r, 500, "out of memory", NULL);
    }
    list_put(&s.l, "]}");
    return json_reply(r, 200, s.l.buf, NULL);
}

static enum MHD_Result series_one(struct req *r, const char *uid)
{
    struct series_rec rec;
    int found = store_series_get(r->svc->store, uid, NULL, &rec);
    if (found)
        return found == SF_ENOTFOUND ? problem(r, 404, "no such series", NULL) : damaged_or_failed(r, found);
    if (!strcmp(r->method, "DELETE")) {
        int gone = store_series_delete(r->svc->store, uid, NULL);
        return gone && gone != SF_ENOTFOUND ? problem(r, 500, "the store failed", NULL) : text(r, 204, NULL, "");
    }
    char *one = series_resource(r->svc, &rec, true);
    return one ? json_reply(r, 200, one, NULL) : problem(r, 500, "the series could not be read", NULL);
}

static enum MHD_Result jobs(struct req *r, const char *id)
{
    (void)id;
    return job_list(r);
}

static enum MHD_Result job(struct req *r, const char *id) { return job_resource(r, 200, id); }
static enum MHD_Result result(struct req *r, const char *id) { return job_result(r, id, false); }

/* Cancel: a queued job ends at once, a running one is asked to stop (on whichever node runs it:
 * here at once, elsewhere at its next heartbeat). */
static enum MHD_Result cancel(struct req *r, const char *id)
{
    struct job_rec rec;
    int found = get_job(r, id, false, &rec);
    if (found)
        return no_job(r, found);
    store_rec_free(&rec);
    bool asked;
    switch (store_cancel(r->svc->store, id, scope(r), wall_s(), &asked)) {
    case 0:
        if (asked) {
            jobq_cancel(r->svc->q, id);
        } else {
            metrics_job_end(JOB_CANCELLED);
            jobq_notify(r->svc->q, id);
        }
        return job_resource(r, 202, id);
    case SF_ECONFLICT:
        return problem(r, 409, "the job has already ended", NULL);
    case SF_ENOTFOUND:
        return problem(r, 404, "no such job", NULL);
    default:
        return problem(r, 500, "the store failed", NULL);
    }
}

enum { GET = 1, POST = 2, DELETE = 4 }; /* HEAD is answered as GET */

/* Every route of API.md: a path ({id}: one job or model id, hex as issued), its methods, and
 * either a handler or the job kind a POST submits. open: answered without a token. */
static const struct route {
    const char *path;
    unsigned methods;
    bool open;
    enum MHD_Result (*fn)(struct req *r, const char *id);
    const struct job_kind *kind;
} ROUTES[] = {
    {"/", GET, true, web_asset, NULL},
    {"/app.js", GET, true, web_asset, NULL},
    {"/style.css", GET, true, web_asset, NULL},
    {"/view.js", GET, true, web_asset, NULL}, /* the 3D view, three.js bundled in (client/web/README.md) */
    {"/livez", GET, true, livez, NULL},
    {"/readyz", GET, true, readyz, NULL},
    {"/version", GET, false, version, NULL},
    {"/formats", GET, false, formats, NULL},
    {"/metrics", GET, false, metrics, NULL},
    {"/openapi.yaml", GET, false, openapi, NULL},
    {"/render", POST, false, NULL, &render_kind},
    {"/volume", POST, false, NULL, &volume_kind},
    {"/model", POST, false, NULL, &model_kind},
    {"/isosurface", POST, false, NULL, &isosurface_kind},
    {"/matrix-model", POST, false, NULL, &matrix_kind},
    {"/models", GET, false, models, NULL},
    {"/models/{id}", GET | DELETE, false, model_resource, NULL},
    {"/models/{id}/mesh", GET, false, model_mesh_route, NULL},
    {"/models/{id}/patches", GET, false, model_patches_route, NULL},
    {"/models/{id}/render", GET, false, model_view_route, NULL},
    {"/models/{id}/rtstruct", GET, false, model_rtstruct_route, NULL},
    {"/models/{id}/edit", POST, false, model_edit_route, NULL},
    {"/models/{id}/iso", POST, false, model_iso_route, NULL},
    {"/models/{id}/send", POST, false, model_send_route, NULL},
    {"/models/{id}/volume", GET, false, model_volume_route, NULL},
    {"/rtstruct", GET, false, rtstruct_set_route, NULL},
    {"/rtstruct/send", POST, false, rtstruct_send_route, NULL},
    {"/series", GET, false, series_list, NULL},
    {"/series/pull", POST, false, NULL, &pull_kind},
    {"/pacs/{name}/studies", GET, false, pacs_studies, NULL},
    {"/series/{uid}", GET | DELETE, false, series_one, NULL},
    {"/series/{uid}/volume", GET, false, series_volume_route, NULL},
    {"/pacs", GET, false, pacs_list, NULL},
    {"/jobs", GET, false, jobs, NULL},
    {"/jobs/{id}", GET, false, job, NULL},
    {"/jobs/{id}/result", GET, false, result, NULL},
    {"/jobs/{id}/cancel", POST, false, cancel, NULL},
};

/* Whether path matches pattern; the {id} segment, if any, into id. */
static bool match(const char *pattern, const char *path, char id[ROUTE_ID])
{
    const char *at = strchr(pattern, '{');
    if (!at)
        return !strcmp(pattern, path);
    char kind = at[1] == 'i' ? 'i' : at[1] == 'u' ? 'u' : 'n'; /* {id}, {uid} or {name} */
    size_t pre = (size_t)(at - pattern);
    if (strncmp(pattern, path, pre))
        return false;
    const char *rest;
    return split_id(path + pre, kind, id, &rest) && !strcmp(rest ? rest : "", strchr(at, '}') + 1);
}

/* A CORS preflight (OPTIONS with Origin): 204 with what a page of an allowed origin may send, no
 * token needed (browsers send none); 403 for any other origin. Without cors-origin OPTIONS is a
 * method no route allows (405). */
static enum MHD_Result preflight(struct req *r)
{
    if (!cors_origin(r))
        return problem(r, 403, "this origin may not call surfd (see the cors-origin setting)", NULL);
    struct reply rp = {204, NULL, NULL, 0,
                       {{"Access-Control-Allow-Methods", "GET, HEAD, POST, DELETE"},
                        {"Access-Control-Allow-Headers", "Authorization, Content-Type, Prefer, If-None-Match"},
                        {"Access-Control-Max-Age", "600"}}};
    return send_reply(r, &rp);
}

/* The route path matches (its {id} into id), or NULL. */
static const struct route *find_route(const char *path, char id[ROUTE_ID])
{
    for (size_t k = 0; k < sizeof ROUTES / sizeof *ROUTES; k++)
        if (match(ROUTES[k].path, path, id))
            return &ROUTES[k];
    return NULL;
}

/* Whether the request is a CORS preflight (answered without a token). */
static bool is_preflight(const struct req *r)
{
    return !strcmp(r->method, "OPTIONS") && r->svc->cfg.cors_origins[0] &&
           MHD_lookup_connection_value(r->conn, MHD_HEADER_KIND, "Access-Control-Request-Method");
}

/* Whether the request needs a token it lacks: decided from its headers alone, before a byte of
 * its body is read or written (an unknown route needs one too, so that it reveals nothing). */
static bool unauthorised(struct req *r)
{
    char id[ROUTE_ID];
    const struct route *rt = find_route(r->path, id);
    return !is_preflight(r) && !(rt && rt->open) && !authorised(r);
}

static enum MHD_Result route(struct req *r)
{
    const char *m = r->method;
    if (is_preflight(r))
        return preflight(r);
    unsigned method = !strcmp(m, "GET") || !strcmp(m, "HEAD") ? GET : !strcmp(m, "POST") ? POST
                      : !strcmp(m, "DELETE")                  ? DELETE
                                                              : 0;
    char id[ROUTE_ID] = "";
    const struct route *rt = find_route(r->path, id);
    if (rt) {
        if (!(rt->methods & method)) {
            char allow[32];
            snprintf(allow, sizeof allow, "%s%s%s", rt->methods & GET ? "GET, HEAD" : "",
                     rt->methods & POST ? (rt->methods & GET ? ", POST" : "POST") : "",
                     rt->methods & DELETE ? ", DELETE" : "");
            struct reply rp = {405, "application/problem+json", problem_json(405, "method not allowed here", NULL), 0,
                               {{"Allow", allow}}};
            rp.len = rp.body ? strlen(rp.body) : 0;
            return send_reply(r, &rp);
        }
        return rt->kind ? post_job(r, rt->kind) : rt->fn(r, id);
    }
    if (!strncmp(r->path, "/jobs/", 6))
        return problem(r, 404, "no such job", NULL);
    if (!strncmp(r->path, "/models/", 8))
        return problem(r, 404, "no such model", NULL);
    if (!strncmp(r->path, "/series/", 8))
        return problem(r, 404, "no such series (a series is named by its Series Instance UID)", NULL);
    return problem(r, 404, "no such route", NULL);
}

/* libmicrohttpd 0.9.75 stores each query argument in the connection's memory pool, and a query
 * of thousands of arguments exhausts the pool: its error answer then finds no room either and the
 * client waits until the header timeout. This callback sees the request line before the
 * arguments are split and allocates the request; a query of more options than any route takes is
 * cut off at its '?' (the line sits in libmicrohttpd's writable read buffer, which it modifies
 * itself right after this call) and answered 414 by the handler. */
#define QUERY_MAX_ARGS 64

static void *uri_logged(void *cls, const char *uri, struct MHD_Connection *conn)
{
    (void)cls;
    (void)conn;
    struct req *r = calloc(1, sizeof *r);
    if (r)
        r->fd = -1;
    char *q = strchr(uri, '?');
    if (r && q) {
        size_t n = 1;
        for (const char *c = q; *c; c++)
            n += *c == '&';
        if (n > QUERY_MAX_ARGS) {
            q[1] = 0;
            r->long_query = true;
        }
    }
    return r;
}

/* Whether the request is a POST of a kind whose body is streamed to a file. */
static bool streamed(const char *path, const char *method)
{
    if (strcmp(method, "POST"))
        return false;
    char id[ROUTE_ID];
    const struct route *rt = find_route(path, id);
    return rt && rt->kind && rt->kind->streamed;
}

/* Removes the uploads/tmp-* files a process before this one left when it was stopped mid-upload (a
 * kill -9): nobody will take them. A data dir is one node's, so none of them is still arriving. */
static void sweep_cut_uploads(const char *data_dir)
{
    char path[1100];
    snprintf(path, sizeof path, "%s/uploads", data_dir);
    DIR *d = opendir(path);
    if (!d)
        return;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        if (!strncmp(e->d_name, "tmp-", 4)) {
            snprintf(path, sizeof path, "%s/uploads/%s", data_dir, e->d_name);
            n += unlink(path) == 0;
        }
    closedir(d);
    if (n)
        LOG(LOG_WARN, "removed %d upload%s cut off when the service last stopped", n, n == 1 ? "" : "s");
}

/* Takes bytes more of the owner's upload share for the request (r->shared): false when they would
 * not fit, with r->share_detail saying why. */
static bool take_share(struct req *r, long long bytes)
{
    long long held, share = r->svc->cfg.upload_share;
    if (shares_take(r->svc->shares, r->owner, bytes, share, &held)) {
        r->shared += bytes;
        return true;
    }
    long long whole = r->shared + bytes; /* the body's bytes, as far as they are known */
    if (whole > share)
        snprintf(r->share_detail, sizeof r->share_detail,
                 "the upload (%lld bytes or more) is larger than one owner's share of the data dir (upload-share, %lld"
                 " bytes)", whole, share);
    else
        snprintf(r->share_detail, sizeof r->share_detail,
                 "your uploads not yet run to their end hold %lld of your share of the data dir (upload-share, %lld"
                 " bytes); this one (%lld bytes) would go over it: try again when your jobs have run",
                 held - r->shared, share, whole);
    r->share_status = whole > share ? 413 : 429;
    return false;
}

static enum MHD_Result share_problem(struct req *r)
{
    return problem(r, r->share_status, r->share_detail, NULL);
}

/* Starts a streamed body's file in the data dir's uploads/ (the store takes it from there). */
static bool open_upload(struct req *r)
{
    snprintf(r->upload, sizeof r->upload, "%s/uploads", r->svc->cfg.data_dir);
    mkdir(r->upload, 0700);
    snprintf(r->upload, sizeof r->upload, "%s/uploads/tmp-XXXXXX", r->svc->cfg.data_dir);
    if ((r->fd = mkstemp(r->upload)) < 0) {
        LOG(LOG_ERROR, "cannot write an upload in %s/uploads: %s", r->svc->cfg.data_dir, strerror(errno));
        r->upload[0] = 0;
        return false;
    }
    return true;
}

static void write_upload(struct req *r, const char *data, size_t n)
{
    while (n && !r->write_failed) {
        ssize_t w = write(r->fd, data, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0) {
            LOG(LOG_ERROR, "an upload could not be written to %s: %s", r->upload, strerror(errno));
            r->write_failed = true;
            return;
        }
        data += w, n -= (size_t)w;
    }
}

/* The whole streamed body, mapped as r->body. */
static bool map_upload(struct req *r)
{
    if (r->len == 0)
        return true;
    /* shared and writable: what validation changes in place (a series' identifying elements
     * blanked) is what the store keeps */
    void *m = mmap(NULL, r->len, PROT_READ | PROT_WRITE, MAP_SHARED, r->fd, 0);
    if (m == MAP_FAILED)
        return false;
    r->map = m;
    r->body = m;
    return true;
}

static enum MHD_Result handler(void *cls, struct MHD_Connection *conn, const char *url, const char *method,
                               const char *version, const char *upload, size_t *upload_size, void **con_cls)
{
    (void)version;
    struct server *s = cls;
    struct req *r = *con_cls;
    if (!r || !r->conn) {
        if (!r && !(r = calloc(1, sizeof *r)))
            return MHD_NO;
        r->fd = -1;
        *con_cls = r;
        r->svc = s->svc;
        r->guard = s->guard;
        r->checks = s->checks;
        r->conn = conn;
        guard_request_started(r->guard, conn);
        r->t0 = monotonic_s();
        snprintf(r->method, sizeof r->method, "%s", method);
        snprintf(r->path, sizeof r->path, "%s", url);
        const union MHD_ConnectionInfo *ci = MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
        if (ci && ci->client_addr) {
            const struct sockaddr *sa = ci->client_addr;
            if (sa->sa_family == AF_INET)
                inet_ntop(AF_INET, &((const struct sockaddr_in *)(const void *)sa)->sin_addr, r->client, sizeof r->client);
            else if (sa->sa_family == AF_INET6)
                inet_ntop(AF_INET6, &((const struct sockaddr_in6 *)(const void *)sa)->sin6_addr, r->client,
                          sizeof r->client);
        }
        if (r->long_query) {
            char d[64];
            snprintf(d, sizeof d, "the query has over %d options", QUERY_MAX_ARGS);
            return problem(r, 414, d, NULL);
        }
        if (unauthorised(r)) /* from the headers: no body byte is read or written first */
            return problem(r, 401, "a valid bearer token is required", NULL);
        bool stream = streamed(r->path, r->method);
        long limit = stream ? r->svc->cfg.max_volume : r->svc->cfg.max_body;
        const char *cl = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_CONTENT_LENGTH);
        if (cl && strtoull(cl, NULL, 10) > (unsigned long long)limit) {
            char d[96];
            snprintf(d, sizeof d, "the body is over the limit of %ld bytes", limit);
            return problem(r, 413, d, NULL); /* before a byte of it is read */
        }
        if (stream && cl && !take_share(r, (long long)strtoull(cl, NULL, 10)))
            return share_problem(r);
        if (stream && !open_upload(r))
            return problem(r, 503, "the data dir cannot take an upload now", NULL);
        /* libmicrohttpd decodes "chunked" alone; any other coding (gzip, chunked) would leave it
         * waiting for a body it cannot frame */
        const char *te = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, MHD_HTTP_HEADER_TRANSFER_ENCODING);
        if (te && strcasecmp(te, "chunked"))
            return problem(r, 501, "the only Transfer-Encoding surfd reads is chunked", NULL);
        return MHD_YES;
    }
    if (r->checked) /* back from the checks pool */
        return answer_job(r);
    if (r->woken) /* back from a synchronous wait */
        return atomic_load(&r->finished) ? job_result(r, r->job, true) : job_resource(r, 202, r->job);
    if (*upload_size) {
        size_t n = *upload_size;
        *upload_size = 0;
        if (r->too_large || r->over_budget || r->over_share)
            return MHD_YES; /* draining a refused body */
        if (r->fd >= 0) { /* streamed to its file */
            if (r->len + n > (size_t)r->svc->cfg.max_volume)
                r->too_large = true;
            else if ((long long)(r->len + n) > r->shared && !take_share(r, (long long)(r->len + n) - r->shared))
                r->over_share = true; /* chunked: its share taken as it arrives */
            else
                write_upload(r, upload, n);
            r->len += n;
            return MHD_YES;
        }
        if (r->len + n > (size_t)r->svc->cfg.max_body) {
            r->too_large = true; /* chunked, without a length to decide by up front */
            return MHD_YES;
        }
        if (r->len + n + 1 > r->cap) {
            size_t cap = r->cap ? r->cap : 65536, most = (size_t)r->svc->cfg.max_body + 1;
            while (cap < r->len + n + 1)
                cap *= 2;
            cap = cap > most ? most : cap; /* (a small max-body: its budget holds its bodies too) */
            long more = (long)cap - r->reserved;
            if (atomic_fetch_add(&body_bytes, more) + more > BODY_BUDGET_BODIES * r->svc->cfg.max_body) {
                atomic_fetch_sub(&body_bytes, more);
                r->over_budget = true;
                return MHD_YES;
            }
            r->reserved += more;
            char *b = realloc(r->body, cap);
            if (!b)
                return MHD_NO;
            r->body = b;
            r->cap = cap;
        }
        memcpy(r->body + r->len, upload, n);
        r->len += n;
        r->body[r->len] = 0;
        return MHD_YES;
    }
    guard_request_handled(r->guard, conn);
    if (r->over_budget)
        return problem(r, 503, "too many large uploads at once; try again shortly", NULL);
    if (r->too_large)
        return problem(r, 413, "the body is over the limit", NULL);
    if (r->over_share)
        return share_problem(r);
    if (r->fd >= 0 && (r->write_failed || !map_upload(r)))
        return problem(r, 503, "the data dir would not take the upload (is it full?)", NULL);
    return route(r);
}

static void completed(void *cls, struct MHD_Connection *conn, void **con_cls, enum MHD_RequestTerminationCode toe)
{
    struct server *s = cls;
    struct req *r = *con_cls;
    guard_request_done(s->guard, conn);
    if (!r)
        return;
    metrics_http(r->status);
    LOG(LOG_INFO, "access %s %s %s %d %zu %.1fms%s%s%s", r->client[0] ? r->client : "-", r->method, r->path, r->status,
        r->bytes, (monotonic_s() - r->t0) * 1e3, r->job[0] ? " job=" : "", r->job,
        toe == MHD_REQUEST_TERMINATED_COMPLETED_OK ? "" : " (aborted)");
    atomic_fetch_sub(&body_bytes, r->reserved);
    if (r->shared)
        shares_give(r->svc->shares, r->owner, r->shared);
    if (r->map)
        munmap(r->map, r->len);
    else
        free(r->body);
    if (r->fd >= 0)
        close(r->fd);
    if (r->upload[0]) /* not taken by the store */
        unlink(r->upload);
    free(r);
    *con_cls = NULL;
}

static char *read_file(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    char *buf = malloc(1 << 20);
    size_t n = buf ? fread(buf, 1, (1 << 20) - 1, f) : 0;
    fclose(f);
    if (buf)
        buf[n] = 0;
    return buf;
}

/* HOST:PORT, [V6]:PORT: 0, or SF_EINVAL. */
static int parse_listen(const char *s, struct sockaddr_storage *ss, unsigned short *port, bool *v6)
{
    char host[128];
    const char *colon;
    if (s[0] == '[') {
        const char *end = strchr(s, ']');
        if (!end || end[1] != ':')
            return SF_EINVAL;
        snprintf(host, sizeof host, "%.*s", (int)(end - s - 1), s + 1);
        colon = end + 1;
    } else {
        colon = strrchr(s, ':');
        if (!colon)
            return SF_EINVAL;
        snprintf(host, sizeof host, "%.*s", (int)(colon - s), s);
    }
    long p = strtol(colon + 1, NULL, 10);
    if (p < 0 || p > 65535)
        return SF_EINVAL;
    *port = (unsigned short)p;
    memset(ss, 0, sizeof *ss);
    struct sockaddr_in *a4 = (struct sockaddr_in *)ss;
    struct sockaddr_in6 *a6 = (struct sockaddr_in6 *)ss;
    if (inet_pton(AF_INET, host, &a4->sin_addr) == 1) {
        a4->sin_family = AF_INET;
        a4->sin_port = htons(*port);
        *v6 = false;
        return 0;
    }
    if (inet_pton(AF_INET6, host, &a6->sin6_addr) == 1) {
        a6->sin6_family = AF_INET6;
        a6->sin6_port = htons(*port);
        *v6 = true;
        return 0;
    }
    return SF_EINVAL;
}

/* GnuTLS priorities: TLS 1.3 as GnuTLS has it; TLS 1.2 only with ephemeral elliptic-curve key
 * exchange (forward secrecy) and AEAD ciphers: no static RSA, no CBC, no SHA-1 MACs, and no SHA-1
 * (or SHA-224) signatures on the key exchange. */
#define TLS_PRIORITIES                                                                                    \
    "NORMAL:-VERS-ALL:+VERS-TLS1.3:+VERS-TLS1.2:-KX-ALL:+ECDHE-ECDSA:+ECDHE-RSA:-CIPHER-ALL:+AES-256-GCM:" \
    "+AES-128-GCM:+CHACHA20-POLY1305:-MAC-ALL:+AEAD:-SIGN-RSA-SHA1:-SIGN-DSA-SHA1:-SIGN-ECDSA-SHA1:"       \
    "-SIGN-RSA-SHA224:-SIGN-DSA-SHA224:-SIGN-ECDSA-SHA224"

struct server *server_start(struct service *svc, struct sf_err *err)
{
    struct sockaddr_storage ss;
    unsigned short port;
    bool v6;
    if (parse_listen(svc->cfg.listen, &ss, &port, &v6)) {
        sf_fail(err, SF_EINVAL, "", "listen: expected HOST:PORT with a numeric address, got \"%s\"", svc->cfg.listen);
        return NULL;
    }
    struct server *s = calloc(1, sizeof *s);
    if (!s)
        return sf_fail(err, SF_ENOMEM, "", "out of memory"), NULL;
    s->svc = svc;
    sweep_cut_uploads(svc->cfg.data_dir);
    if (!(s->checks = jobq_new(CHECK_THREADS, svc->cfg.max_connections, svc->cfg.job_memory))) {
        sf_fail(err, SF_EIO, "", "cannot start the threads that read requests");
        free(s);
        return NULL;
    }
    if (!(s->guard = guard_new(svc->cfg.max_connections, (double)svc->cfg.header_timeout,
                               (double)svc->cfg.body_timeout, (double)svc->cfg.connection_timeout))) {
        sf_fail(err, SF_EIO, "", "cannot start the connection guard");
        jobq_shutdown(s->checks, 0, 0, NULL, NULL);
        jobq_free(s->checks);
        free(s);
        return NULL;
    }
    unsigned flags = MHD_USE_INTERNAL_POLLING_THREAD | MHD_USE_EPOLL | MHD_ALLOW_SUSPEND_RESUME | MHD_USE_ERROR_LOG |
                     MHD_USE_ITC; /* ITC: quiesce and resume wake the polling threads */
    if (v6)
        flags |= MHD_USE_IPv6;
    char *cert = NULL, *key = NULL;
    if (svc->cfg.tls_cert[0] || svc->cfg.tls_key[0]) {
        cert = read_file(svc->cfg.tls_cert);
        key = read_file(svc->cfg.tls_key);
        if (!cert || !key || !MHD_is_feature_supported(MHD_FEATURE_TLS)) {
            sf_fail(err, SF_EINVAL, "", "TLS: cannot read %s or %s, or libmicrohttpd has no TLS", svc->cfg.tls_cert,
                    svc->cfg.tls_key);
            free(cert);
            free(key);
            guard_free(s->guard);
            jobq_shutdown(s->checks, 0, 0, NULL, NULL);
            jobq_free(s->checks);
            free(s);
            return NULL;
        }
        flags |= MHD_USE_TLS;
    }
    struct MHD_OptionItem tls_opts[] = {
        {MHD_OPTION_HTTPS_MEM_CERT, 0, cert},
        {MHD_OPTION_HTTPS_MEM_KEY, 0, key},
        {MHD_OPTION_HTTPS_PRIORITIES, 0, (void *)TLS_PRIORITIES},
        {MHD_OPTION_END, 0, NULL},
    };
    s->mhd = MHD_start_daemon(
        flags, port, NULL, NULL, handler, s, MHD_OPTION_SOCK_ADDR, (struct sockaddr *)&ss, MHD_OPTION_THREAD_POOL_SIZE,
        (unsigned)2, MHD_OPTION_CONNECTION_LIMIT, (unsigned)svc->cfg.max_connections,
        MHD_OPTION_PER_IP_CONNECTION_LIMIT, (unsigned)svc->cfg.per_ip_connections, MHD_OPTION_CONNECTION_TIMEOUT,
        (unsigned)svc->cfg.connection_timeout, MHD_OPTION_CONNECTION_MEMORY_LIMIT, (size_t)(256 * 1024),
        MHD_OPTION_NOTIFY_COMPLETED, completed, s, MHD_OPTION_NOTIFY_CONNECTION, guard_notify, s->guard,
        MHD_OPTION_URI_LOG_CALLBACK, uri_logged, NULL,
        MHD_OPTION_ARRAY, cert ? tls_opts : tls_opts + 3,
        MHD_OPTION_END);
    free(cert);
    free(key);
    if (!s->mhd) {
        sf_fail(err, SF_EIO, "", "cannot listen on %s (in use, or not an address of this host)", svc->cfg.listen);
        guard_free(s->guard);
        jobq_shutdown(s->checks, 0, 0, NULL, NULL);
        jobq_free(s->checks);
        free(s);
        return NULL;
    }
    return s;
}

unsigned short server_port(struct server *s)
{
    const union MHD_DaemonInfo *di = MHD_get_daemon_info(s->mhd, MHD_DAEMON_INFO_BIND_PORT);
    return di ? di->port : 0;
}

void server_quiesce(struct server *s)
{
    MHD_socket fd = MHD_quiesce_daemon(s->mhd);
    (void)fd; /* the listening socket stays open until server_stop: new connections wait, then fail */
}

void server_stop(struct server *s)
{
    if (!s)
        return;
    /* every request on the checks pool is answered (its connection resumed) before MHD stops; one
     * still there after 10 s (a PACS's search at its bounds) is not freed under: the process ends */
    if (jobq_shutdown(s->checks, 5.0, 5.0, NULL, NULL)) {
        log_write(LOG_WARN, "a request still being checked after 10 s: exiting under it");
        _exit(0);
    }
    jobq_free(s->checks);
    MHD_stop_daemon(s->mhd);
    guard_free(s->guard);
    free(s);
}
