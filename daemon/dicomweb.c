/* dicomweb.c - the DICOMweb client (dicomweb.h): QIDO-RS, WADO-RS into files, STOW-RS from files,
 * hand-written on libcurl (Debian has no C DICOMweb library). One request at a time per call, on
 * its own easy handle; every request bounded by a connect, a stall and a whole-request timeout and
 * tried DICOMWEB_ATTEMPTS times while its answer has not begun (request()). The multipart bodies
 * are read by api/multipart.c's streaming reader, the same one that splits posted series. Never
 * logs; its messages name the PACS's root URL and HTTP statuses, never a query's values or a
 * response body (patient data). */
#include "dicomweb.h"

#include <curl/curl.h>
#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "../api/multipart.h"
#include "../core/base/clock.h"

struct dicomweb {
    char *root;        /* the URL without its final '/' */
    char *userpwd;     /* "user:password", or NULL */
    char *ca_file;     /* or NULL */
    long connect_s, stall_s, request_s;
    int attempts;
};

int dicomweb_global_init(void)
{
    return curl_global_init(CURL_GLOBAL_DEFAULT) == CURLE_OK ? 0 : SF_EBACKEND;
}

static char *dup_str(const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    return d ? memcpy(d, s, n) : NULL;
}

/* The first line of the credentials file: "user:password", the file private to its owner (and
 * group). */
static int read_credentials(const char *path, char **userpwd, struct sf_err *err)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return sf_fail(err, SF_EIO, "", "credentials file %.200s: %s", path, strerror(errno));
    int rc = 0;
    struct stat st;
    char buf[1024];
    ssize_t n = 0;
    if (fstat(fd, &st) || !S_ISREG(st.st_mode)) {
        rc = sf_fail(err, SF_EINVAL, "", "credentials file %.200s is not a regular file", path);
        goto out_close;
    }
    if (st.st_mode & 0027) {
        rc = sf_fail(err, SF_EINVAL, "", "credentials file %.200s is mode %04o: others may read it or the group may "
                     "write it; chmod 0600", path, (unsigned)(st.st_mode & 07777));
        goto out_close;
    }
    while ((n = read(fd, buf, sizeof buf - 1)) < 0 && errno == EINTR)
        ;
    if (n < 0) {
        rc = sf_fail(err, SF_EIO, "", "credentials file %.200s: %s", path, strerror(errno));
        goto out_close;
    }
    buf[n] = 0;
    buf[strcspn(buf, "\r\n")] = 0;
    char *colon = strchr(buf, ':');
    if (!colon || colon == buf || !colon[1]) {
        rc = sf_fail(err, SF_EINVAL, "", "credentials file %.200s: its first line is user:password", path);
        goto out_wipe;
    }
    if (!(*userpwd = dup_str(buf)))
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
out_wipe:
    explicit_bzero(buf, sizeof buf);
out_close:
    close(fd);
    return rc;
}

int dicomweb_open(const struct dicomweb_config *cfg, struct dicomweb **out, struct sf_err *err)
{
    *out = NULL;
    const char *u = cfg->url ? cfg->url : "";
    bool tls = !strncmp(u, "https://", 8);
    if (!tls && strncmp(u, "http://", 7))
        return sf_fail(err, SF_EINVAL, "", "a DICOMweb root is an http:// or https:// URL");
    const char *host = u + (tls ? 8 : 7), *host_end = host + strcspn(host, "/?#");
    if (host == host_end || memchr(host, '@', (size_t)(host_end - host)))
        return sf_fail(err, SF_EINVAL, "", "a DICOMweb root names its host and no user:password@ (credentials "
                       "come from a file)");
    if (strpbrk(u, "?# \t\r\n"))
        return sf_fail(err, SF_EINVAL, "", "a DICOMweb root has no query, fragment or blanks");
    struct dicomweb *dw = calloc(1, sizeof *dw);
    if (!dw)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    int rc = 0;
    if (!(dw->root = dup_str(u)) || (cfg->ca_file && !(dw->ca_file = dup_str(cfg->ca_file)))) {
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        goto out_fail;
    }
    for (size_t n = strlen(dw->root); n > 0 && dw->root[n - 1] == '/'; n--)
        dw->root[n - 1] = 0;
    if (cfg->credentials_file && (rc = read_credentials(cfg->credentials_file, &dw->userpwd, err)))
        goto out_fail;
    dw->connect_s = cfg->connect_timeout_s > 0 ? cfg->connect_timeout_s : DICOMWEB_CONNECT_TIMEOUT_S;
    dw->stall_s = cfg->stall_timeout_s > 0 ? cfg->stall_timeout_s : DICOMWEB_STALL_TIMEOUT_S;
    dw->request_s = cfg->request_timeout_s > 0 ? cfg->request_timeout_s : DICOMWEB_REQUEST_TIMEOUT_S;
    dw->attempts = cfg->attempts > 0 ? cfg->attempts : DICOMWEB_ATTEMPTS;
    *out = dw;
    return 0;
out_fail:
    dicomweb_free(dw);
    return rc;
}

void dicomweb_free(struct dicomweb *dw)
{
    if (!dw)
        return;
    if (dw->userpwd) {
        explicit_bzero(dw->userpwd, strlen(dw->userpwd));
        free(dw->userpwd);
    }
    free(dw->root);
    free(dw->ca_file);
    free(dw);
}

/* A UID as PS3.5 9.1 has it: digits and dots, at most 64. Checked before it goes into a path. */
static int check_uid(const char *uid, const char *what, struct sf_err *err)
{
    size_t n = strlen(uid);
    if (n == 0 || n > 64 || strspn(uid, "0123456789.") != n)
        return sf_fail(err, SF_EINVAL, "", "the %s is not a DICOM UID (digits and dots, at most 64)", what);
    return 0;
}

/* One request as request() runs it: the parts that differ between QIDO, WADO and STOW. */
struct req {
    CURL *c;
    const char *url;
    const char *accept;
    const char *content_type;        /* a body's (STOW), or NULL: GET */
    curl_off_t body_len;
    curl_read_callback read;         /* the body, from the start at each attempt (rewind) */
    int (*rewind)(void *ctx);
    size_t (*write)(char *p, size_t size, size_t n, void *ctx);
    void *ctx;                       /* of read, rewind and write */
    bool (*may_retry)(void *ctx);    /* NULL: always, while the answer has not begun */
    void (*reset)(void *ctx);        /* before each attempt: what the last one received is dropped */
    const struct sf_progress *progress;
    double (*done)(void *ctx);       /* the fraction for progress */
    int *cb_code;                    /* set by write/read when they stop the transfer (err filled) */
};

static int xferinfo(void *ctx, curl_off_t dlt, curl_off_t dln, curl_off_t ult, curl_off_t uln)
{
    (void)dlt, (void)dln, (void)ult, (void)uln;
    const struct req *rq = ctx;
    return rq->progress && sf_poll(rq->progress, rq->done ? rq->done(rq->ctx) : 0, NULL) ? 1 : 0;
}

static int seek_body(void *ctx, curl_off_t offset, int origin)
{
    const struct req *rq = ctx;
    if (offset != 0 || origin != SEEK_SET || !rq->rewind)
        return CURL_SEEKFUNC_CANTSEEK;
    return rq->rewind(rq->ctx) ? CURL_SEEKFUNC_FAIL : CURL_SEEKFUNC_OK;
}

static bool retryable_status(long status)
{
    return status == 429 || status == 502 || status == 503 || status == 504;
}

static bool retryable_curl(CURLcode rc)
{
    return rc == CURLE_COULDNT_CONNECT || rc == CURLE_COULDNT_RESOLVE_HOST || rc == CURLE_OPERATION_TIMEDOUT ||
           rc == CURLE_GOT_NOTHING || rc == CURLE_SEND_ERROR || rc == CURLE_RECV_ERROR;
}

static void sleep_ms(long ms)
{
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    while (nanosleep(&ts, &ts) && errno == EINTR)
        ;
}

/* Runs rq: the options every request shares, then up to dw->attempts tries, DICOMWEB_RETRY_DELAY_MS
 * apart and doubling, of a request that could not connect, timed out, or was answered 429/502/503/
 * 504, while rq->may_retry agrees. 0 with *status the HTTP status (any: the caller judges it), or
 * the error. */
static int request(const struct dicomweb *dw, struct req *rq, long *status, struct sf_err *err)
{
    char errbuf[CURL_ERROR_SIZE];
    struct curl_slist *headers = NULL;
    char line[256];
    int rc = 0;
    *status = 0;
    snprintf(line, sizeof line, "Accept: %s", rq->accept);
    struct curl_slist *h1 = curl_slist_append(headers, line);
    if (h1)
        headers = h1;
    if (h1 && rq->content_type) {
        snprintf(line, sizeof line, "Content-Type: %s", rq->content_type);
        h1 = curl_slist_append(headers, line);
        if (h1 && !(h1 = curl_slist_append(headers, "Expect:"))) /* no 100-continue round trip */
            h1 = NULL;
    }
    if (!h1) {
        curl_slist_free_all(headers);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    CURL *c = rq->c;
    curl_easy_setopt(c, CURLOPT_URL, rq->url);
    curl_easy_setopt(c, CURLOPT_PROTOCOLS_STR, "http,https");
    curl_easy_setopt(c, CURLOPT_FOLLOWLOCATION, 0L); /* credentials go to the PACS configured, nowhere else */
    curl_easy_setopt(c, CURLOPT_NOSIGNAL, 1L);       /* called on worker threads */
    curl_easy_setopt(c, CURLOPT_ERRORBUFFER, errbuf);
    curl_easy_setopt(c, CURLOPT_HTTPHEADER, headers);
    curl_easy_setopt(c, CURLOPT_CONNECTTIMEOUT, dw->connect_s);
    curl_easy_setopt(c, CURLOPT_LOW_SPEED_LIMIT, 1L);
    curl_easy_setopt(c, CURLOPT_LOW_SPEED_TIME, dw->stall_s);
    curl_easy_setopt(c, CURLOPT_TIMEOUT, dw->request_s);
    curl_easy_setopt(c, CURLOPT_WRITEFUNCTION, rq->write);
    curl_easy_setopt(c, CURLOPT_WRITEDATA, rq->ctx);
    curl_easy_setopt(c, CURLOPT_NOPROGRESS, 0L);
    curl_easy_setopt(c, CURLOPT_XFERINFOFUNCTION, xferinfo);
    curl_easy_setopt(c, CURLOPT_XFERINFODATA, rq);
    curl_easy_setopt(c, CURLOPT_USERAGENT, "surfd/" SURFD_VERSION);
    if (dw->userpwd) {
        curl_easy_setopt(c, CURLOPT_HTTPAUTH, (long)CURLAUTH_BASIC);
        curl_easy_setopt(c, CURLOPT_USERPWD, dw->userpwd);
    }
    if (dw->ca_file)
        curl_easy_setopt(c, CURLOPT_CAINFO, dw->ca_file);
    if (rq->content_type) {
        curl_easy_setopt(c, CURLOPT_POST, 1L);
        curl_easy_setopt(c, CURLOPT_READFUNCTION, rq->read);
        curl_easy_setopt(c, CURLOPT_READDATA, rq->ctx);
        curl_easy_setopt(c, CURLOPT_SEEKFUNCTION, seek_body);
        curl_easy_setopt(c, CURLOPT_SEEKDATA, rq);
        curl_easy_setopt(c, CURLOPT_POSTFIELDSIZE_LARGE, rq->body_len);
    }
    double t0 = sf_now_ms();
    long delay = DICOMWEB_RETRY_DELAY_MS;
    CURLcode cc = CURLE_OK;
    int attempt;
    for (attempt = 1;; attempt++) {
        errbuf[0] = 0;
        *rq->cb_code = 0;
        if (rq->reset)
            rq->reset(rq->ctx);
        if (rq->rewind && rq->rewind(rq->ctx)) {
            cc = CURLE_READ_ERROR;
            break;
        }
        cc = curl_easy_perform(c);
        *status = 0;
        curl_easy_getinfo(c, CURLINFO_RESPONSE_CODE, status);
        bool again = cc == CURLE_OK ? retryable_status(*status) : retryable_curl(cc) && !*rq->cb_code;
        if (!again || attempt >= dw->attempts || (rq->may_retry && !rq->may_retry(rq->ctx)))
            break;
        if (rq->progress && sf_poll(rq->progress, rq->done ? rq->done(rq->ctx) : 0, NULL)) {
            cc = CURLE_ABORTED_BY_CALLBACK;
            break;
        }
        sleep_ms(delay);
        delay = delay * 2 > 4000 ? 4000 : delay * 2;
    }
    double secs = (sf_now_ms() - t0) / 1000;
    if (*rq->cb_code) /* the write or read callback stopped it, err filled */
        rc = *rq->cb_code;
    else if (cc == CURLE_ABORTED_BY_CALLBACK)
        rc = sf_fail(err, SF_ECANCEL, "", "cancelled");
    else if (cc == CURLE_COULDNT_CONNECT || cc == CURLE_COULDNT_RESOLVE_HOST)
        rc = sf_fail(err, SF_EIO, "", "the PACS at %.200s cannot be reached: %s (%d attempts in %.1f s)", dw->root,
                     errbuf[0] ? errbuf : curl_easy_strerror(cc), attempt, secs);
    else if (cc == CURLE_OPERATION_TIMEDOUT)
        rc = sf_fail(err, SF_EIO, "", "the PACS at %.200s did not answer in time: %s (%d attempts in %.1f s)",
                     dw->root, errbuf[0] ? errbuf : curl_easy_strerror(cc), attempt, secs);
    else if (cc != CURLE_OK)
        rc = sf_fail(err, SF_EIO, "", "the PACS at %.200s: %s (%d attempts in %.1f s)", dw->root,
                     errbuf[0] ? errbuf : curl_easy_strerror(cc), attempt, secs);
    else if (retryable_status(*status))
        rc = sf_fail(err, SF_EIO, "", "the PACS at %.200s is unavailable: HTTP %ld (%d attempts in %.1f s)",
                     dw->root, *status, attempt, secs);
    curl_easy_setopt(c, CURLOPT_HTTPHEADER, NULL);
    curl_easy_setopt(c, CURLOPT_ERRORBUFFER, NULL);
    curl_slist_free_all(headers);
    return rc;
}

/* The error of an HTTP status a request's caller does not take (the body is not read: it may
 * echo the query). */
static int status_error(const struct dicomweb *dw, long status, const char *what, struct sf_err *err)
{
    switch (status) {
    case 400:
        return sf_fail(err, SF_EINVAL, "", "the PACS at %.200s refused the %s as invalid (HTTP 400)", dw->root, what);
    case 401:
    case 403:
        return sf_fail(err, SF_EIO, "", "the PACS at %.200s refused surfd's credentials (HTTP %ld)", dw->root, status);
    case 404:
        return sf_fail(err, SF_ENOTFOUND, "", "the PACS at %.200s has no such %s (HTTP 404)", dw->root, what);
    case 413:
        return sf_fail(err, SF_ELIMIT, "", "the PACS at %.200s refused the %s as too large (HTTP 413)", dw->root, what);
    default:
        return sf_fail(err, SF_EIO, "", "the PACS at %.200s answered the %s with HTTP %ld", dw->root, what, status);
    }
}

/* A response body kept in memory, capped (QIDO, STOW) */
struct answer {
    CURL *c;
    char *data;
    size_t len, cap;
    int code;
    struct sf_err *err;
};

static size_t answer_write(char *p, size_t size, size_t n, void *ctx)
{
    struct answer *a = ctx;
    size_t len = size * n;
    if (a->len + len > DICOMWEB_MAX_ANSWER) {
        a->code = sf_fail(a->err, SF_ELIMIT, "", "the PACS's answer is over %u MB", DICOMWEB_MAX_ANSWER >> 20);
        return 0;
    }
    if (a->len + len + 1 > a->cap) {
        size_t cap = a->cap ? a->cap : 16384;
        while (cap < a->len + len + 1)
            cap *= 2;
        char *more = realloc(a->data, cap);
        if (!more) {
            a->code = sf_fail(a->err, SF_ENOMEM, "", "out of memory");
            return 0;
        }
        a->data = more, a->cap = cap;
    }
    memcpy(a->data + a->len, p, len);
    a->len += len;
    a->data[a->len] = 0;
    return len;
}

static void answer_reset(void *ctx)
{
    struct answer *a = ctx;
    a->len = 0;
}

/* The path of a search or a retrieve: {root}/studies[/{study}]/series[/{series}]... */
static int level_path(const struct dicomweb *dw, enum dicomweb_level level, const char *study, const char *series,
                      char *out, size_t cap, struct sf_err *err)
{
    int rc;
    if ((study && (rc = check_uid(study, "study UID", err))) || (series && (rc = check_uid(series, "series UID", err))))
        return rc;
    int n;
    if (level == DICOMWEB_STUDIES)
        n = snprintf(out, cap, "%s/studies", dw->root);
    else if (level == DICOMWEB_SERIES)
        n = study ? snprintf(out, cap, "%s/studies/%s/series", dw->root, study) : snprintf(out, cap, "%s/series", dw->root);
    else if (study && series)
        n = snprintf(out, cap, "%s/studies/%s/series/%s/instances", dw->root, study, series);
    else if (study)
        n = snprintf(out, cap, "%s/studies/%s/instances", dw->root, study);
    else
        n = snprintf(out, cap, "%s/instances", dw->root);
    if (n < 0 || (size_t)n >= cap)
        return sf_fail(err, SF_EINVAL, "", "the DICOMweb root is too long");
    return 0;
}

int dicomweb_search(const struct dicomweb *dw, enum dicomweb_level level, const char *study_uid, const char *series_uid,
                    const struct dicomweb_param *params, int n_params, char **json, size_t *len, struct sf_err *err)
{
    *json = NULL;
    *len = 0;
    char path[2048];
    int rc = level_path(dw, level, level == DICOMWEB_STUDIES ? NULL : study_uid,
                        level == DICOMWEB_INSTANCES ? series_uid : NULL, path, sizeof path, err);
    if (rc)
        return rc;
    CURL *c = curl_easy_init();
    if (!c)
        return sf_fail(err, SF_EBACKEND, "", "libcurl could not start a request");
    struct answer a = {c, NULL, 0, 0, 0, err};
    size_t cap = strlen(path) + 1, used = strlen(path);
    char *url = malloc(cap);
    if (!url) {
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        goto out_cleanup;
    }
    memcpy(url, path, cap);
    for (int i = 0; i < n_params; i++) { /* each name and value percent-encoded: a query is the user's text */
        char *name = curl_easy_escape(c, params[i].name, 0), *value = curl_easy_escape(c, params[i].value, 0);
        size_t need = used + 2 + (name ? strlen(name) : 0) + (value ? strlen(value) : 0) + 1;
        char *more = name && value && need <= 65536 ? realloc(url, need) : NULL;
        if (more) {
            url = more;
            used += (size_t)sprintf(url + used, "%c%s=%s", i ? '&' : '?', name, value);
        }
        curl_free(name);
        curl_free(value);
        if (!more) {
            rc = need > 65536 ? sf_fail(err, SF_ELIMIT, "", "a query is at most 64 KB encoded")
                              : sf_fail(err, SF_ENOMEM, "", "out of memory");
            goto out_free_url;
        }
    }
    struct req rq = {.c = c, .url = url, .accept = "application/dicom+json", .write = answer_write, .ctx = &a,
                     .reset = answer_reset, .cb_code = &a.code};
    long status;
    if ((rc = request(dw, &rq, &status, err)))
        goto out_free_url;
    if (status == 204) {
        a.len = 0;
        if (!answer_write("[]", 1, 2, &a)) {
            rc = a.code;
            goto out_free_url;
        }
    } else if (status != 200) {
        rc = status_error(dw, status, "search", err);
        goto out_free_url;
    }
    json_error_t jerr;
    json_t *root = a.len ? json_loadb(a.data, a.len, 0, &jerr) : NULL;
    bool array = json_is_array(root);
    json_decref(root);
    if (!array) {
        rc = sf_fail(err, SF_EFORMAT, "", "the PACS at %.200s answered the search with something other than a "
                     "DICOM JSON array", dw->root);
        goto out_free_url;
    }
    *json = a.data, *len = a.len;
    a.data = NULL;
out_free_url:
    free(url);
out_cleanup:
    free(a.data);
    curl_easy_cleanup(c);
    return rc;
}

/* ---- WADO-RS: the answer's parts, each into its own file as it arrives ---- */

struct wado {
    const struct dicomweb *dw;
    const struct dicomweb_retrieve *rq;
    CURL *c;
    struct multipart_reader *reader; /* made at the answer's first bytes, from its Content-Type */
    bool discard;                    /* a status other than 200: its body is not read */
    int fd;                          /* the instance being written, or -1 */
    char path[4096];
    uint64_t bytes;
    int n_begun, n_done;
    int code;                        /* what stopped the transfer (err filled) */
    struct sf_err *err;
};

static double wado_done(void *ctx)
{
    const struct wado *w = ctx;
    return w->rq->n_expected > 0 ? (double)w->n_done / w->rq->n_expected : 0;
}

static void wado_drop_partial(struct wado *w)
{
    if (w->fd >= 0) {
        close(w->fd);
        unlink(w->path);
        w->fd = -1;
    }
}

/* A part's header lines: its Content-Type, when it gives one, is application/dicom. */
static int wado_begin(void *ctx, const char *head, size_t head_len, uint64_t head_at, uint64_t data_at,
                      struct sf_err *err)
{
    (void)head_len, (void)head_at, (void)data_at;
    struct wado *w = ctx;
    int k = ++w->n_begun;
    if (k > DICOMWEB_MAX_INSTANCES)
        return sf_fail(err, SF_ELIMIT, "", "the series has more than %d instances", DICOMWEB_MAX_INSTANCES);
    for (const char *l = head; *l; l += strcspn(l, "\n"), l += *l == '\n') {
        if (strncasecmp(l, "Content-Type:", 13))
            continue;
        char type[128];
        snprintf(type, sizeof type, "%.*s", (int)strcspn(l + 13, "\r\n"), l + 13);
        if (!multipart_is_type(type, "application/dicom"))
            return sf_fail(err, SF_EFORMAT, "", "instance %d of the PACS's answer is not application/dicom", k);
    }
    int n = snprintf(w->path, sizeof w->path, "%s/%06d.dcm", w->rq->dir, k);
    if (n < 0 || (size_t)n >= sizeof w->path)
        return sf_fail(err, SF_EINVAL, "", "the retrieve's directory name is too long");
    w->fd = open(w->path, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
    if (w->fd < 0)
        return sf_fail(err, SF_EIO, "", "cannot write instance %d: %s", k, strerror(errno));
    w->bytes = 0;
    return 0;
}

static int wado_data(void *ctx, const char *data, size_t len, struct sf_err *err)
{
    struct wado *w = ctx;
    if (len > w->rq->max_instance_bytes - w->bytes || w->bytes > w->rq->max_instance_bytes)
        return sf_fail(err, SF_ELIMIT, "", "instance %d of the series is over %llu bytes", w->n_begun,
                       (unsigned long long)w->rq->max_instance_bytes);
    w->bytes += len;
    while (len) {
        ssize_t n = write(w->fd, data, len);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            return sf_fail(err, SF_EIO, "", "cannot write instance %d: %s", w->n_begun, strerror(n < 0 ? errno : EIO));
        data += n, len -= (size_t)n;
    }
    return 0;
}

static int wado_end(void *ctx, struct sf_err *err)
{
    struct wado *w = ctx;
    int fd = w->fd;
    w->fd = -1;
    if (close(fd)) {
        unlink(w->path);
        return sf_fail(err, SF_EIO, "", "cannot write instance %d: %s", w->n_begun, strerror(errno));
    }
    if (w->bytes == 0) {
        unlink(w->path);
        return sf_fail(err, SF_EFORMAT, "", "instance %d of the PACS's answer is empty", w->n_begun);
    }
    int rc = w->rq->instance ? w->rq->instance(w->rq->ctx, w->n_begun, w->path, w->bytes, err) : 0;
    if (rc)
        return rc;
    w->n_done++;
    return sf_poll(w->rq->progress, wado_done(w), err);
}

/* The answer's first bytes: a 200 must be multipart/related of application/dicom, its boundary
 * read from its Content-Type. */
static int wado_start(struct wado *w)
{
    long status = 0;
    curl_easy_getinfo(w->c, CURLINFO_RESPONSE_CODE, &status);
    if (status != 200) {
        w->discard = true;
        return 0;
    }
    char *ct = NULL, boundary[MULTIPART_MAX_BOUNDARY + 1], type[128];
    curl_easy_getinfo(w->c, CURLINFO_CONTENT_TYPE, &ct);
    if (!multipart_is_type(ct, "multipart/related") || !multipart_param(ct, "boundary", boundary, sizeof boundary) ||
        (multipart_param(ct, "type", type, sizeof type) && !multipart_is_type(type, "application/dicom")))
        return sf_fail(w->err, SF_EFORMAT, "", "the PACS at %.200s did not answer the retrieve with "
                       "multipart/related of application/dicom", w->dw->root);
    struct multipart_events ev = {wado_begin, wado_data, wado_end, w};
    int rc = multipart_reader_new(boundary, strlen(boundary), &ev, &w->reader, NULL);
    if (rc == SF_ENOMEM)
        return sf_fail(w->err, SF_ENOMEM, "", "out of memory");
    return rc ? sf_fail(w->err, SF_EFORMAT, "", "the PACS's multipart boundary is not one (RFC 2046)") : 0;
}

static size_t wado_write(char *p, size_t size, size_t n, void *ctx)
{
    struct wado *w = ctx;
    size_t len = size * n;
    if (!w->reader && !w->discard && (w->code = wado_start(w)))
        return 0;
    if (w->discard)
        return len;
    if ((w->code = multipart_reader_feed(w->reader, p, len, w->err))) {
        wado_drop_partial(w);
        return 0;
    }
    return len;
}

static void wado_reset(void *ctx)
{
    struct wado *w = ctx;
    multipart_reader_free(w->reader);
    w->reader = NULL;
    w->discard = false;
}

static bool wado_may_retry(void *ctx)
{
    const struct wado *w = ctx;
    return w->n_begun == 0;
}

int dicomweb_retrieve_series(const struct dicomweb *dw, const char *study_uid, const char *series_uid,
                             const struct dicomweb_retrieve *rq, int *n_instances, struct sf_err *err)
{
    *n_instances = 0;
    bool had_error = err && err->code;
    char url[2048];
    int rc = level_path(dw, DICOMWEB_INSTANCES, study_uid, series_uid, url, sizeof url, err);
    if (rc)
        return rc;
    url[strlen(url) - strlen("/instances")] = 0; /* the series itself: every instance's bytes */
    CURL *c = curl_easy_init();
    if (!c)
        return sf_fail(err, SF_EBACKEND, "", "libcurl could not start a request");
    struct wado w = {.dw = dw, .rq = rq, .c = c, .fd = -1, .err = err};
    struct req r = {.c = c, .url = url, .accept = "multipart/related; type=\"application/dicom\"; transfer-syntax=*",
                    .write = wado_write, .ctx = &w, .may_retry = wado_may_retry, .reset = wado_reset,
                    .progress = rq->progress, .done = wado_done, .cb_code = &w.code};
    long status;
    if ((rc = request(dw, &r, &status, err)))
        goto out_drop;
    if (status != 200) {
        rc = status_error(dw, status, "series", err);
        goto out_drop;
    }
    if (!w.reader) {
        rc = sf_fail(err, SF_ENOTFOUND, "", "the PACS at %.200s answered the series without instances", dw->root);
        goto out_drop;
    }
    if ((rc = multipart_reader_finish(w.reader, err)))
        goto out_drop;
    if (w.n_done == 0)
        rc = sf_fail(err, SF_ENOTFOUND, "", "the PACS at %.200s answered the series without instances", dw->root);
out_drop:
    wado_drop_partial(&w);
    *n_instances = w.n_done;
    if (rc && err && !had_error)
        err->pointer[0] = 0; /* the reader's "/parts/K" points into the PACS's answer, not a request */
    multipart_reader_free(w.reader);
    curl_easy_cleanup(c);
    return rc;
}

/* ---- STOW-RS: the files as one multipart/related body, read as curl sends it ---- */

struct stow {
    const char *const *paths;
    const uint64_t *sizes;
    int n;
    char head[160];     /* "--boundary" CRLF "Content-Type: application/dicom" CRLF CRLF */
    size_t head_len;
    char tail[80];      /* "--boundary--" CRLF */
    size_t tail_len;
    int i;              /* the file being sent (n: the closing delimiter) */
    int phase;          /* of file i: 0 its head, 1 its bytes, 2 the CRLF after them */
    size_t off;         /* into the head, the CRLF or the tail */
    int fd;
    uint64_t sent;      /* of file i */
    struct answer a;    /* the PACS's answer; its code is also the read side's */
    struct sf_err *err;
};

static size_t stow_write(char *p, size_t size, size_t n, void *ctx)
{
    struct stow *s = ctx;
    return answer_write(p, size, n, &s->a);
}

static void stow_reset(void *ctx)
{
    struct stow *s = ctx;
    answer_reset(&s->a);
}

static int stow_rewind(void *ctx)
{
    struct stow *s = ctx;
    if (s->fd >= 0)
        close(s->fd);
    s->fd = -1;
    s->i = 0, s->phase = 0, s->off = 0, s->sent = 0;
    return 0;
}

static size_t copy_mem(char *dst, size_t cap, const char *src, size_t len, size_t *off)
{
    size_t n = len - *off < cap ? len - *off : cap;
    memcpy(dst, src + *off, n);
    *off += n;
    return n;
}

static size_t stow_read(char *buf, size_t size, size_t nitems, void *ctx)
{
    struct stow *s = ctx;
    size_t cap = size * nitems, out = 0;
    while (out < cap) {
        if (s->i == s->n) {
            out += copy_mem(buf + out, cap - out, s->tail, s->tail_len, &s->off);
            break;
        }
        if (s->phase == 0) {
            out += copy_mem(buf + out, cap - out, s->head, s->head_len, &s->off);
            if (s->off == s->head_len)
                s->phase = 1, s->off = 0, s->sent = 0;
        } else if (s->phase == 1) {
            if (s->fd < 0 && (s->fd = open(s->paths[s->i], O_RDONLY | O_CLOEXEC)) < 0) {
                s->a.code = sf_fail(s->err, SF_EIO, "", "file %d of the send: %s", s->i + 1, strerror(errno));
                return CURL_READFUNC_ABORT;
            }
            uint64_t left = s->sizes[s->i] - s->sent;
            ssize_t n = left ? read(s->fd, buf + out, cap - out < left ? cap - out : (size_t)left) : 0;
            if (n < 0 && errno == EINTR)
                continue;
            if (n < 0 || (n == 0 && left)) {
                s->a.code = sf_fail(s->err, SF_EIO, "", "file %d of the send %s", s->i + 1,
                                  n < 0 ? strerror(errno) : "became shorter while it was sent");
                return CURL_READFUNC_ABORT;
            }
            out += (size_t)n;
            s->sent += (uint64_t)n;
            if (s->sent == s->sizes[s->i]) {
                close(s->fd);
                s->fd = -1;
                s->phase = 2, s->off = 0;
            }
        } else {
            out += copy_mem(buf + out, cap - out, "\r\n", 2, &s->off);
            if (s->off == 2)
                s->i++, s->phase = 0, s->off = 0;
        }
    }
    return out;
}

static int uid_value(json_t *item, const char *tag, char *out, size_t cap)
{
    json_t *v = json_array_get(json_object_get(json_object_get(item, tag), "Value"), 0);
    snprintf(out, cap, "%s", json_is_string(v) ? json_string_value(v) : "");
    return 0;
}

static int int_value(json_t *item, const char *tag)
{
    json_t *v = json_array_get(json_object_get(json_object_get(item, tag), "Value"), 0);
    return json_is_integer(v) ? (int)json_integer_value(v) : 0;
}

/* The answer's ReferencedSOPSequence and FailedSOPSequence, one result an item. */
static int stow_results(const struct dicomweb *dw, const char *body, size_t len, struct dicomweb_stored **results,
                        int *n_results, struct sf_err *err)
{
    json_error_t jerr;
    json_t *root = json_loadb(body, len, 0, &jerr);
    json_t *ok = json_object_get(json_object_get(root, "00081199"), "Value");
    json_t *failed = json_object_get(json_object_get(root, "00081198"), "Value");
    int rc = 0;
    if (!json_is_object(root) || (!json_is_array(ok) && !json_is_array(failed))) {
        rc = sf_fail(err, SF_EFORMAT, "", "the PACS at %.200s answered the send without ReferencedSOPSequence or "
                     "FailedSOPSequence", dw->root);
        goto out_decref;
    }
    size_t n = json_array_size(ok) + json_array_size(failed);
    *results = calloc(n ? n : 1, sizeof **results);
    if (!*results) {
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        goto out_decref;
    }
    for (int pass = 0; pass < 2; pass++) {
        json_t *seq = pass ? failed : ok, *item;
        size_t k;
        json_array_foreach(seq, k, item) {
            struct dicomweb_stored *r = &(*results)[(*n_results)++];
            uid_value(item, "00081150", r->sop_class_uid, sizeof r->sop_class_uid);
            uid_value(item, "00081155", r->sop_instance_uid, sizeof r->sop_instance_uid);
            r->stored = !pass;
            r->reason = int_value(item, pass ? "00081197" : "00081196");
        }
    }
out_decref:
    json_decref(root);
    return rc;
}

int dicomweb_store(const struct dicomweb *dw, const char *study_uid, const char *const *paths, int n_paths,
                   uint64_t max_instance_bytes, struct dicomweb_stored **results, int *n_results, struct sf_err *err)
{
    *results = NULL;
    *n_results = 0;
    if (n_paths <= 0)
        return sf_fail(err, SF_EINVAL, "", "a send has at least one file");
    if (n_paths > DICOMWEB_MAX_INSTANCES)
        return sf_fail(err, SF_ELIMIT, "", "a send has at most %d files", DICOMWEB_MAX_INSTANCES);
    char url[2048];
    int rc = study_uid ? check_uid(study_uid, "study UID", err) : 0, n;
    if (rc)
        return rc;
    n = study_uid ? snprintf(url, sizeof url, "%s/studies/%s", dw->root, study_uid)
                  : snprintf(url, sizeof url, "%s/studies", dw->root);
    if (n < 0 || (size_t)n >= sizeof url)
        return sf_fail(err, SF_EINVAL, "", "the DICOMweb root is too long");
    uint64_t *sizes = malloc(sizeof *sizes * (size_t)n_paths);
    if (!sizes)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    unsigned char rnd[16];
    char boundary[48], content_type[128];
    if (getrandom(rnd, sizeof rnd, 0) != (ssize_t)sizeof rnd) { /* a boundary no instance's bytes hold */
        rc = sf_fail(err, SF_EBACKEND, "", "no random bytes for a multipart boundary: %s", strerror(errno));
        goto out_free_sizes;
    }
    n = snprintf(boundary, sizeof boundary, "surfd-");
    for (size_t i = 0; i < sizeof rnd; i++)
        n += snprintf(boundary + n, sizeof boundary - (size_t)n, "%02x", rnd[i]);
    snprintf(content_type, sizeof content_type, "multipart/related; type=\"application/dicom\"; boundary=%s", boundary);
    struct stow s = {.paths = paths, .sizes = sizes, .n = n_paths, .fd = -1, .err = err};
    s.head_len = (size_t)snprintf(s.head, sizeof s.head, "--%s\r\nContent-Type: application/dicom\r\n\r\n", boundary);
    s.tail_len = (size_t)snprintf(s.tail, sizeof s.tail, "--%s--\r\n", boundary);
    curl_off_t total = (curl_off_t)s.tail_len;
    for (int i = 0; i < n_paths; i++) { /* every file's size known (and capped) before a byte is sent */
        struct stat st;
        if (stat(paths[i], &st)) {
            rc = sf_fail(err, SF_EIO, "", "file %d of the send: %s", i + 1, strerror(errno));
            goto out_free_sizes;
        }
        if (!S_ISREG(st.st_mode)) {
            rc = sf_fail(err, SF_EINVAL, "", "file %d of the send is not a regular file", i + 1);
            goto out_free_sizes;
        }
        if (st.st_size == 0) {
            rc = sf_fail(err, SF_EINVAL, "", "file %d of the send is empty", i + 1);
            goto out_free_sizes;
        }
        if ((uint64_t)st.st_size > max_instance_bytes) {
            rc = sf_fail(err, SF_ELIMIT, "", "file %d of the send is over %llu bytes", i + 1,
                         (unsigned long long)max_instance_bytes);
            goto out_free_sizes;
        }
        sizes[i] = (uint64_t)st.st_size;
        total += (curl_off_t)(s.head_len + 2) + (curl_off_t)st.st_size;
    }
    CURL *c = curl_easy_init();
    if (!c) {
        rc = sf_fail(err, SF_EBACKEND, "", "libcurl could not start a request");
        goto out_free_sizes;
    }
    s.a = (struct answer){c, NULL, 0, 0, 0, err};
    struct req r = {.c = c, .url = url, .accept = "application/dicom+json", .content_type = content_type,
                    .body_len = total, .read = stow_read, .rewind = stow_rewind, .write = stow_write, .ctx = &s,
                    .reset = stow_reset, .cb_code = &s.a.code};
    long status;
    if ((rc = request(dw, &r, &status, err)))
        goto out_cleanup;
    if (status != 200 && status != 202 && status != 409) {
        rc = status_error(dw, status, "send", err);
        goto out_cleanup;
    }
    rc = stow_results(dw, s.a.data ? s.a.data : "", s.a.len, results, n_results, err);
out_cleanup:
    if (s.fd >= 0)
        close(s.fd);
    free(s.a.data);
    curl_easy_cleanup(c);
out_free_sizes:
    free(sizes);
    return rc;
}
