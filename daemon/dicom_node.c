/* dicom_node.c - the DICOM node (dicom_node.h): the peers, the SCP's store function (an instance
 * read, blanked and stored on the node's workers while the association waits), and series
 * resources. */
#include "dicom_node.h"

#include <arpa/inet.h>
#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "../api/dicom_instance.h"
#include "../api/dicom_scan.h"
#include "../api/series_json.h"
#include "jobq.h"
#include "kinds.h"
#include "log.h"

/* Instances read at once (each a worker of the node's own pool: the HTTP checks and the jobs
 * are not held up by a PACS sending a study), and associations at once. */
#define NODE_WORKERS 2
#define NODE_ASSOCIATIONS 8
#define NODE_REFUSED_KEPT 1024 /* series whose structure set made no model, remembered (then retried) */

struct dicom_node {
    struct service *svc;
    struct dimse_scp *scp;
    struct jobq *q;
    struct dimse_peer *peers;
    int n_peers;
    char spool[600];
    /* the watcher: received RT Structure Sets modelled once their series is complete */
    pthread_t watcher;
    bool watching, stop;
    pthread_mutex_t lock;
    pthread_cond_t wake;
    char (*refused)[65];     /* structure sets that made no model (auto_model): not tried again */
    int n_refused;
};

int dicom_peers_read(const char *path, struct dimse_peer **peers, int *n, struct sf_err *err)
{
    *peers = NULL, *n = 0;
    FILE *f = fopen(path, "r");
    if (!f)
        return sf_fail(err, SF_EIO, NULL, "dicom-peers %s: %s", path, strerror(errno));
    char line[512];
    int rc = 0, at = 0;
    while (!rc && fgets(line, sizeof line, f)) {
        at++;
        char *hash = strchr(line, '#');
        if (hash)
            *hash = 0;
        char ae[64], host[256], extra[8];
        int port, got = sscanf(line, "%63s %255s %d %7s", ae, host, &port, extra);
        if (got <= 0)
            continue;
        if (got != 3 || strlen(ae) > 16 || port < 1 || port > 65535) {
            rc = sf_fail(err, SF_EINVAL, NULL, "dicom-peers %s line %d: a peer is AE_TITLE (16 characters at most) "
                         "HOST PORT", path, at);
            break;
        }
        struct addrinfo hints = {.ai_flags = AI_ADDRCONFIG, .ai_socktype = SOCK_STREAM}, *ai = NULL;
        char ip[64];
        if (getaddrinfo(host, NULL, &hints, &ai) || !ai ||
            getnameinfo(ai->ai_addr, ai->ai_addrlen, ip, sizeof ip, NULL, 0, NI_NUMERICHOST)) {
            rc = sf_fail(err, SF_EINVAL, NULL, "dicom-peers %s line %d: host %s is not found", path, at, host);
            if (ai)
                freeaddrinfo(ai);
            break;
        }
        freeaddrinfo(ai);
        struct dimse_peer *p = realloc(*peers, sizeof *p * (size_t)(*n + 1));
        if (!p) {
            rc = sf_fail(err, SF_ENOMEM, NULL, "out of memory for the peers");
            break;
        }
        *peers = p;
        p += (*n)++;
        snprintf(p->ae, sizeof p->ae, "%s", ae);
        snprintf(p->ip, sizeof p->ip, "%s", ip);
        p->port = port;
    }
    fclose(f);
    if (rc) {
        free(*peers);
        *peers = NULL, *n = 0;
    }
    return rc;
}

/* ---- what a stop leaves ---- */

void dicom_dir_empty(const char *dir)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    char path[1024];
    while (d && (e = readdir(d)))
        if (e->d_name[0] != '.') {
            snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
            unlink(path);
        }
    if (d)
        closedir(d);
    rmdir(dir);
}

void dicom_leftovers_remove(const char *data_dir)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/spool", data_dir);
    dicom_dir_empty(path);
    DIR *d = opendir(data_dir);
    struct dirent *e;
    while (d && (e = readdir(d))) {
        snprintf(path, sizeof path, "%s/%s", data_dir, e->d_name);
        if (!strncmp(e->d_name, "pull-", 5))
            dicom_dir_empty(path);
        else if (!strncmp(e->d_name, "send-", 5))
            unlink(path);
    }
    if (d)
        closedir(d);
}

/* ---- an instance arrives ---- */

struct arrival {
    struct dicom_node *node;
    const char *path, *calling, *sop;
    unsigned status;
    bool done;
    pthread_mutex_t lock;
    pthread_cond_t cond;
};

char *dicom_file_read(const char *path, size_t max, size_t *len)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat st;
    char *b = NULL;
    if (fd >= 0 && !fstat(fd, &st) && st.st_size > 0 && (size_t)st.st_size <= max && (b = malloc((size_t)st.st_size))) {
        size_t at = 0;
        while (at < (size_t)st.st_size) {
            ssize_t r = read(fd, b + at, (size_t)st.st_size - at);
            if (r <= 0)
                break;
            at += (size_t)r;
        }
        if (at != (size_t)st.st_size)
            free(b), b = NULL;
        *len = at;
    }
    if (fd >= 0)
        close(fd);
    return b;
}

int dicom_instance_keep(struct service *svc, char *data, size_t len, const char *source, const char *sop,
                        struct sf_err *err)
{
    struct dicom_instance in;
    size_t blanked = 0;
    int rc = dicom_instance_read(data, len, "", &in, err);
    if (!rc && !svc->cfg.keep_phi)
        rc = dicom_blank_identity(data, len, "", &blanked, err);
    if (!rc && sop && strcmp(in.sop_uid, sop))
        rc = sf_fail(err, SF_EINVAL, "", "the instance is not the one its request names");
    if (rc)
        return rc;
    char *meta = instance_meta(&in);
    if (!meta)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the instance");
    struct instance_rec r = {in.sop_uid, in.series_uid, in.study_uid, in.modality, source, "", wall_s(), meta, data, len};
    rc = store_instance_put(svc->store, &r);
    free(meta);
    if (rc == SF_ECONFLICT) /* a second of one SOP Instance UID is kept as the first was */
        return 0;
    return rc ? sf_fail(err, rc, "", "the store would not take the instance") : 0;
}

/* Reads, blanks and stores the instance: the C-STORE status its sender hears. */
static unsigned take(struct arrival *a)
{
    struct service *svc = a->node->svc;
    size_t len = 0;
    char *data = dicom_file_read(a->path, (size_t)svc->cfg.max_body, &len);
    if (!data) {
        LOG(LOG_WARN, "DICOM node: an instance from %s is over max-body or unreadable: refused", a->calling);
        return DIMSE_OUT_OF_RESOURCES;
    }
    char source[80];
    snprintf(source, sizeof source, "received from %s", a->calling);
    struct sf_err err = {0};
    int rc = dicom_instance_keep(svc, data, len, source, a->sop, &err);
    free(data);
    if (rc)
        LOG(LOG_WARN, "DICOM node: an instance from %s is not kept: %s", a->calling, err.message);
    return rc == 0 ? DIMSE_SUCCESS
           : rc == SF_EINVAL || rc == SF_EFORMAT || rc == SF_ELIMIT ? DIMSE_CANNOT_UNDERSTAND
                                                                     : DIMSE_OUT_OF_RESOURCES;
}

static int arrive(struct job *j, void *work, int *n_bands)
{
    (void)j;
    struct arrival *a = work;
    *n_bands = 0;
    a->status = take(a);
    return 0;
}

static void arrived(struct job *j, void *work, enum job_state outcome, bool requeue)
{
    (void)j, (void)requeue;
    struct arrival *a = work;
    pthread_mutex_lock(&a->lock);
    if (outcome != JOB_SUCCEEDED)
        a->status = DIMSE_OUT_OF_RESOURCES; /* (the node stopping) */
    a->done = true;
    pthread_cond_signal(&a->cond);
    pthread_mutex_unlock(&a->lock);
}

static const struct job_ops ARRIVAL_OPS = {.prepare = arrive, .finish = arrived};

/* The SCP's store function, on an association's thread: the instance goes to a worker, and the
 * thread waits for its status. */
static unsigned received(const char *path, const char *calling_ae, const char *sop_uid, void *arg)
{
    static atomic_ulong serial;
    struct arrival a = {arg, path, calling_ae, sop_uid, DIMSE_OUT_OF_RESOURCES, false, PTHREAD_MUTEX_INITIALIZER,
                        PTHREAD_COND_INITIALIZER};
    char id[40];
    snprintf(id, sizeof id, "dicom-%lu", atomic_fetch_add(&serial, 1));
    if (jobq_submit(a.node->q, id, &ARRIVAL_OPS, &a, true))
        return DIMSE_OUT_OF_RESOURCES;
    pthread_mutex_lock(&a.lock);
    while (!a.done)
        pthread_cond_wait(&a.cond, &a.lock);
    pthread_mutex_unlock(&a.lock);
    return a.status;
}

/* ---- received RT Structure Sets become models (auto-model) ---- */

/* Whether series uid's structure set was found not to make models (by this process: its log said
 * why once); with add, noted so. The watcher's alone. */
static bool refused_before(struct dicom_node *n, const char *uid, bool add)
{
    for (int k = 0; k < n->n_refused; k++)
        if (!strcmp(n->refused[k], uid))
            return true;
    if (add && n->n_refused < NODE_REFUSED_KEPT)
        snprintf(n->refused[n->n_refused++], sizeof n->refused[0], "%s", uid);
    return false;
}

/* Makes series uid's models as POST /model?series=UID would, once: the request is made and
 * checked first (a structure set that makes no model is said once in the log, not marked: its
 * series keeps no link to a job that never was), then the series is marked with the job's id
 * (another node, or a pass after a restart, then leaves it) and the job stored as a request's is,
 * owned by nobody (the site's, as the series). */
static void auto_model(struct dicom_node *n, const char *uid)
{
    struct service *svc = n->svc;
    if (refused_before(n, uid, false))
        return;
    struct job_rec rec = {0};
    service_new_id(rec.id);
    struct sf_err err = {0};
    snprintf(rec.kind, sizeof rec.kind, "%s", model_kind.name);
    snprintf(rec.format, sizeof rec.format, "dicom");
    snprintf(rec.options, sizeof rec.options, "series=%s", uid);
    struct job_body b = {NULL, 0, "dicom", rec.options, ""};
    int rc = series_request(svc, uid, true, (size_t)svc->cfg.max_body, &b.body, &b.len, &err);
    if (!rc)
        rc = model_kind.validate(svc, &b, &err);
    if (rc) {
        refused_before(n, uid, true);
        LOG(LOG_WARN, "DICOM node: the RT Structure Set of series %s makes no model: %s", uid, err.message);
        free(b.body);
        return;
    }
    if (store_series_mark(svc->store, uid, rec.id)) {
        free(b.body);
        return;
    }
    rec.created = wall_s();
    rec.request = (unsigned char *)b.body, rec.request_len = b.len;
    if ((rc = store_submit(svc->store, &rec))) { /* (marked: a store that fails here is a store down) */
        LOG(LOG_ERROR, "DICOM node: the store would not take the job of series %s's RT Structure Set", uid);
    } else {
        LOG(LOG_INFO, "DICOM node: the RT Structure Set of series %s is complete: modelled by job %s", uid, rec.id);
        service_wake(svc);
    }
    free(b.body);
}

struct due {
    char (*uid)[65];
    int n, cap;
    double before;
};

static void due_series(const struct series_rec *r, void *arg)
{
    struct due *d = arg;
    if (strcmp(r->modality, "RTSTRUCT") || r->job[0] || r->last > d->before || strncmp(r->source, "received", 8))
        return;
    if (d->n == d->cap) {
        int cap = d->cap ? 2 * d->cap : 16;
        char(*u)[65] = realloc(d->uid, sizeof *u * (size_t)cap);
        if (!u)
            return;
        d->uid = u, d->cap = cap;
    }
    snprintf(d->uid[d->n++], 65, "%s", r->uid);
}

static void *watch(void *arg)
{
    struct dicom_node *n = arg;
    pthread_mutex_lock(&n->lock);
    while (!n->stop) {
        struct timespec t;
        clock_gettime(CLOCK_REALTIME, &t);
        t.tv_sec += 1;
        pthread_cond_timedwait(&n->wake, &n->lock, &t);
        if (n->stop)
            break;
        pthread_mutex_unlock(&n->lock);
        struct due d = {NULL, 0, 0, wall_s() - (double)n->svc->cfg.series_idle};
        if (!store_series_list(n->svc->store, NULL, due_series, &d))
            for (int k = 0; k < d.n && !atomic_load(&n->svc->draining); k++)
                auto_model(n, d.uid[k]);
        free(d.uid);
        pthread_mutex_lock(&n->lock);
    }
    pthread_mutex_unlock(&n->lock);
    return NULL;
}

int dicom_node_start(struct service *svc, struct dicom_node **out, struct sf_err *err)
{
    *out = NULL;
    if (!svc->cfg.dicom_listen)
        return 0;
    if (!svc->cfg.dicom_peers[0])
        return sf_fail(err, SF_EINVAL, NULL, "dicom-listen needs dicom-peers: the AE titles and hosts allowed to send");
    struct dicom_node *n = calloc(1, sizeof *n);
    if (!n)
        return sf_fail(err, SF_ENOMEM, NULL, "out of memory for the DICOM node");
    n->svc = svc;
    n->refused = calloc(NODE_REFUSED_KEPT, sizeof *n->refused);
    if (!n->refused) {
        free(n);
        return sf_fail(err, SF_ENOMEM, NULL, "out of memory for the DICOM node");
    }
    pthread_mutex_init(&n->lock, NULL);
    pthread_cond_init(&n->wake, NULL);
    int rc = dicom_peers_read(svc->cfg.dicom_peers, &n->peers, &n->n_peers, err);
    snprintf(n->spool, sizeof n->spool, "%s/spool", svc->cfg.data_dir);
    if (!rc && mkdir(n->spool, 0700) && errno != EEXIST)
        rc = sf_fail(err, SF_EIO, NULL, "%s: %s", n->spool, strerror(errno));
    if (!rc && !(n->q = jobq_new(NODE_WORKERS, NODE_ASSOCIATIONS * 2, svc->cfg.job_memory)))
        rc = sf_fail(err, SF_ENOMEM, NULL, "cannot start the DICOM node's workers");
    struct dimse_config c = {svc->cfg.ae_title, (int)svc->cfg.dicom_listen, n->peers, n->n_peers, n->spool,
                             (size_t)svc->cfg.max_body, NODE_ASSOCIATIONS, received, n};
    if (!rc)
        rc = dimse_scp_start(&c, &n->scp, err);
    if (!rc && svc->cfg.auto_model) {
        n->watching = !pthread_create(&n->watcher, NULL, watch, n);
        if (!n->watching)
            rc = sf_fail(err, SF_ENOMEM, NULL, "cannot start the DICOM node's watcher");
    }
    if (rc) {
        dicom_node_stop(n);
        return rc;
    }
    LOG(LOG_INFO, "DICOM node %s listening on port %ld, %d peer%s", svc->cfg.ae_title, svc->cfg.dicom_listen,
        n->n_peers, n->n_peers == 1 ? "" : "s");
    *out = n;
    return 0;
}

void dicom_node_stop(struct dicom_node *n)
{
    if (!n)
        return;
    if (n->watching) {
        pthread_mutex_lock(&n->lock);
        n->stop = true;
        pthread_cond_signal(&n->wake);
        pthread_mutex_unlock(&n->lock);
        pthread_join(n->watcher, NULL);
    }
    pthread_mutex_destroy(&n->lock);
    pthread_cond_destroy(&n->wake);
    dimse_scp_stop(n->scp); /* the associations end (their instances' workers answer them) before the pool stops */
    /* (jobs still active after the grace: left to the process's end, not freed under them) */
    if (n->q && jobq_shutdown(n->q, 0, 5, NULL, NULL) == 0)
        jobq_free(n->q);
    free(n->peers);
    free(n->refused);
    free(n);
}

/* ---- a stored series as a request ---- */

#define SERIES_BOUNDARY "surfd-stored-series-7d1c0e"

struct joined {
    char *buf;
    size_t n, cap;
    bool one, failed;
};

static void join_instance(const char *sop, const char *meta, const void *data, size_t len, void *arg)
{
    (void)sop, (void)meta;
    struct joined *j = arg;
    static const char HEAD[] = "--" SERIES_BOUNDARY "\r\nContent-Disposition: form-data; name=\"slice\"\r\n"
                               "Content-Type: application/dicom\r\n\r\n";
    size_t need = j->n + (j->one ? 0 : sizeof HEAD + 2) + len;
    if (j->failed || need > j->cap) {
        j->failed = true; /* (the room was counted from the series' bytes before) */
        return;
    }
    if (!j->one)
        memcpy(j->buf + j->n, HEAD, sizeof HEAD - 1), j->n += sizeof HEAD - 1;
    memcpy(j->buf + j->n, data, len), j->n += len;
    if (!j->one)
        memcpy(j->buf + j->n, "\r\n", 2), j->n += 2;
}

int series_request(struct service *svc, const char *uid, bool one, size_t max_bytes, char **body, size_t *len,
                   struct sf_err *err)
{
    *body = NULL, *len = 0;
    struct series_rec r;
    int rc = dicom_uid_valid(uid) ? store_series_get(svc->store, uid, NULL, &r) : SF_ENOTFOUND;
    if (rc == SF_ENOTFOUND)
        return sf_fail(err, SF_EINVAL, "?series", "no stored series %.64s (GET /series lists them)", uid);
    if (rc)
        return sf_fail(err, rc, "?series", "the store could not read the series");
    if (one && r.instances != 1)
        return sf_fail(err, SF_EINVAL, "?series", "the series holds %ld instances: POST /model reads a series of one RT "
                       "Structure Set", r.instances);
    size_t cap = (size_t)r.bytes + (size_t)r.instances * 160 + 64;
    if ((size_t)r.bytes > max_bytes)
        return sf_fail(err, SF_ELIMIT, "?series", "the series is %lld bytes: over the %zu this route reads", r.bytes,
                       max_bytes);
    struct joined j = {malloc(cap), 0, cap, one, false};
    if (!j.buf)
        return sf_fail(err, SF_ENOMEM, "?series", "out of memory for the series");
    rc = store_series_instances(svc->store, uid, true, join_instance, &j);
    if (!rc && !j.failed && !one) {
        static const char END[] = "--" SERIES_BOUNDARY "--\r\n";
        if (j.n + sizeof END - 1 <= j.cap)
            memcpy(j.buf + j.n, END, sizeof END - 1), j.n += sizeof END - 1;
        else
            j.failed = true;
    }
    if (rc || j.failed) {
        free(j.buf);
        return sf_fail(err, rc ? rc : SF_ECONFLICT, "?series", rc == SF_EDAMAGED ? "a stored instance is damaged"
                       : rc ? "the store could not read the series" : "the series changed while it was read: try again");
    }
    *body = j.buf, *len = j.n;
    return 0;
}

/* ---- series resources ---- */

struct metas {
    char **v;
    int n, cap;
    bool failed;
};

static void add_meta(const char *sop, const char *meta, const void *data, size_t len, void *arg)
{
    (void)sop, (void)data, (void)len;
    struct metas *m = arg;
    if (m->failed)
        return;
    if (m->n == m->cap) {
        int cap = m->cap ? 2 * m->cap : 64;
        char **v = realloc(m->v, sizeof *v * (size_t)cap);
        if (!v) {
            m->failed = true;
            return;
        }
        m->v = v, m->cap = cap;
    }
    if (!(m->v[m->n] = strdup(meta)))
        m->failed = true;
    else
        m->n++;
}

char *series_resource(struct service *svc, const struct series_rec *r, bool detail)
{
    struct series_view v = {r->uid, r->study_uid, r->modality, r->source, r->instances, r->bytes, r->first, r->last,
                            wall_s() - r->last >= (double)svc->cfg.series_idle, r->job, NULL, 0};
    struct metas m = {0};
    if (detail && (store_series_instances(svc->store, r->uid, false, add_meta, &m) || m.failed)) {
        for (int k = 0; k < m.n; k++)
            free(m.v[k]);
        free(m.v);
        return NULL;
    }
    v.metas = detail ? (const char *const *)m.v : NULL;
    v.n_metas = m.n;
    char *s = series_json(&v);
    for (int k = 0; k < m.n; k++)
        free(m.v[k]);
    free(m.v);
    return s;
}
