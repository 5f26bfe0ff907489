/* store_pg.c - PostgreSQL behind store_backend.h: several nodes share one database, and every
 * node sees every job.
 *
 * - Claims: one autocommit UPDATE whose subquery takes the oldest queued row FOR UPDATE SKIP
 *   LOCKED, so nodes claiming at once never wait on each other nor take the same job. The claim
 *   sets a lease (lease_until, renewed by heartbeats) and a new fence token; every later write of
 *   the job names its fence, so a node that lost its lease (stopped, partitioned) changes nothing.
 * - Reaping: running jobs whose lease ran out go back to the queue (with a backoff) or fail at
 *   max-attempts; one node at a time reaps, under a transaction-level advisory lock.
 * - Times that decide leases are the database's clock (clock_timestamp()), so nodes need not agree
 *   on the time.
 * - No transaction spans a job's run: each call is one statement, or one short transaction
 *   (finish: the guarded update and the result's chunks).
 * - Results are stored as 1 MiB chunks of a side table, written and read as binary parameters
 *   and rows one chunk at a time (single-row mode): a 300 MB mesh is never escaped as text nor
 *   held whole in a libpq result next to our copy.
 * - Events: NOTIFY surfd 'queued|ended|cancel:ID' in the statements that change jobs; a listener
 *   thread with its own connection hands them to the service (store_on_event).
 * - Connections: a small pool; a broken connection is reset and the statement tried again once,
 *   so a node survives a database restart (calls fail while it is away: /readyz says 503). */
#include <errno.h>
#include <libpq-fe.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "store_backend.h"

#define POOL_SIZE 6          /* HTTP threads, keeper, workers' reads: few at once, each short */
#define CHUNK (1u << 20)     /* bytes of a result per row of results */
#define REAP_LOCK "72656170" /* the advisory lock of the reaper ("reap") */
#define SCHEMA_LOCK "72656171"

struct pg_store {
    struct store base;
    char *uri;
    char scratch[1024];      /* the node's directory for streamed bodies fetched to run */
    PGconn *pool[POOL_SIZE];
    bool busy[POOL_SIZE];
    pthread_mutex_t lock;
    pthread_cond_t freed;
    /* the listener */
    pthread_t listener;
    bool listening, stop;
    void (*event)(enum store_event, const char *, void *);
    void *event_arg;
};

static const char SCHEMA[] =
    "CREATE TABLE IF NOT EXISTS jobs ("
    " id text PRIMARY KEY, kind text NOT NULL, state text NOT NULL, progress double precision NOT NULL DEFAULT 0,"
    " created double precision NOT NULL, started double precision NOT NULL DEFAULT 0,"
    " finished double precision NOT NULL DEFAULT 0, format text NOT NULL, options text NOT NULL,"
    " request bytea NOT NULL, result_len bigint, result_type text, meta text, error text,"
    " attempts integer NOT NULL DEFAULT 0, owner text NOT NULL DEFAULT '', result_sum text,"
    " node text NOT NULL DEFAULT '', fence bigint NOT NULL DEFAULT 0,"
    " lease_until double precision NOT NULL DEFAULT 0, cancel_requested boolean NOT NULL DEFAULT false,"
    " not_before double precision NOT NULL DEFAULT 0, request_file boolean NOT NULL DEFAULT false);"
    "ALTER TABLE jobs ADD COLUMN IF NOT EXISTS request_file boolean NOT NULL DEFAULT false;"
    "ALTER TABLE jobs ADD COLUMN IF NOT EXISTS suspect boolean NOT NULL DEFAULT false;"
    "CREATE TABLE IF NOT EXISTS uploads (job text NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,"
    " seq integer NOT NULL, data bytea NOT NULL, PRIMARY KEY (job, seq));"
    "CREATE INDEX IF NOT EXISTS jobs_queued ON jobs(created, id) WHERE state='queued';"
    "CREATE INDEX IF NOT EXISTS jobs_running ON jobs(lease_until) WHERE state='running';"
    "CREATE INDEX IF NOT EXISTS jobs_created ON jobs(created);"
    "CREATE TABLE IF NOT EXISTS results (job text NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,"
    " seq integer NOT NULL, data bytea NOT NULL, PRIMARY KEY (job, seq));"
    "CREATE TABLE IF NOT EXISTS models ("
    " id text PRIMARY KEY, job text NOT NULL, name text NOT NULL, created double precision NOT NULL,"
    " source bytea NOT NULL, resource text NOT NULL, owner text NOT NULL DEFAULT '', sum text);"
    "ALTER TABLE models ADD COLUMN IF NOT EXISTS resource_sum text;"
    /* the version a model's source is of (0: a row from before the journal of mesh changes, whose
     * sum covers its source and resource together; else its source alone) */
    "ALTER TABLE models ADD COLUMN IF NOT EXISTS base_version bigint NOT NULL DEFAULT 0;"
    "CREATE INDEX IF NOT EXISTS models_created ON models(created);"
    "CREATE TABLE IF NOT EXISTS model_volumes (model text NOT NULL REFERENCES models(id) ON DELETE CASCADE,"
    " seq integer NOT NULL, format text NOT NULL, options text NOT NULL, data bytea NOT NULL, sum text NOT NULL,"
    " PRIMARY KEY (model, seq));"
    "CREATE TABLE IF NOT EXISTS meshes (model text NOT NULL REFERENCES models(id) ON DELETE CASCADE,"
    " key text NOT NULL, type text NOT NULL, meta text NOT NULL, data bytea NOT NULL, sum text NOT NULL,"
    " used double precision NOT NULL, PRIMARY KEY (model, key));"
    /* values longer than a piece (store.h): the column empty, its rows in pieces, named by *_pieces */
    "CREATE TABLE IF NOT EXISTS pieces (name text NOT NULL, seq integer NOT NULL, data bytea NOT NULL,"
    " PRIMARY KEY (name, seq));"
    "ALTER TABLE models ADD COLUMN IF NOT EXISTS source_pieces text;"
    "ALTER TABLE model_volumes ADD COLUMN IF NOT EXISTS data_pieces text;"
    "ALTER TABLE meshes ADD COLUMN IF NOT EXISTS data_pieces text;"
    /* a row's pieces go with it, however it goes (a delete, a cascade, an update naming others) */
    "CREATE OR REPLACE FUNCTION surfd_drop_pieces() RETURNS trigger LANGUAGE plpgsql AS $$"
    " DECLARE n text; m text; BEGIN"
    " IF TG_TABLE_NAME = 'models' THEN n := OLD.source_pieces; IF TG_OP = 'UPDATE' THEN m := NEW.source_pieces; END IF;"
    " ELSE n := OLD.data_pieces; IF TG_OP = 'UPDATE' THEN m := NEW.data_pieces; END IF; END IF;"
    " IF n IS NOT NULL AND n IS DISTINCT FROM m THEN DELETE FROM pieces WHERE name = n; END IF;"
    " RETURN NULL; END $$;"
    "CREATE OR REPLACE TRIGGER models_pieces AFTER DELETE OR UPDATE OF source_pieces ON models"
    " FOR EACH ROW EXECUTE FUNCTION surfd_drop_pieces();"
    "CREATE OR REPLACE TRIGGER volumes_pieces AFTER DELETE ON model_volumes FOR EACH ROW EXECUTE FUNCTION surfd_drop_pieces();"
    "CREATE OR REPLACE TRIGGER meshes_pieces AFTER DELETE OR UPDATE OF data_pieces ON meshes"
    " FOR EACH ROW EXECUTE FUNCTION surfd_drop_pieces();";
/* DICOM series (store.h): an instance's pieces go with it, its series' delete takes them all (a
 * string of its own: C99 compilers need take no longer one) */
static const char SCHEMA_SERIES[] =
    "CREATE TABLE IF NOT EXISTS series ("
    " uid text PRIMARY KEY, study_uid text NOT NULL, modality text NOT NULL, source text NOT NULL, owner text NOT NULL,"
    " instances bigint NOT NULL, bytes bigint NOT NULL, first double precision NOT NULL, last double precision NOT NULL,"
    " job text NOT NULL DEFAULT '');"
    "CREATE TABLE IF NOT EXISTS instances ("
    " sop_uid text PRIMARY KEY, series_uid text NOT NULL REFERENCES series(uid) ON DELETE CASCADE,"
    " received double precision NOT NULL, meta text NOT NULL, data bytea NOT NULL, sum text NOT NULL, data_pieces text);"
    "CREATE INDEX IF NOT EXISTS instances_series ON instances(series_uid, received);"
    "CREATE OR REPLACE TRIGGER instances_pieces AFTER DELETE ON instances FOR EACH ROW EXECUTE FUNCTION surfd_drop_pieces();";

#define NOW "extract(epoch from clock_timestamp())"

static struct pg_store *pg(struct store *s) { return (struct pg_store *)s; }

/* ---- connections ---- */

/* A connection, giving up after 5 s unless the URI says otherwise (libpq waits for ever by
 * default, and an HTTP thread must not). */
static PGconn *connect_db(const char *uri)
{
    const char *const keys[] = {"connect_timeout", "dbname", NULL}, *const values[] = {"5", uri, NULL};
    PGconn *c = PQconnectdbParams(keys, values, 1);
    if (PQstatus(c) != CONNECTION_OK)
        return c; /* the caller reads the message, and a later take() resets it */
    PQclear(PQexec(c, "SET client_min_messages = warning"));
    return c;
}

static int take(struct pg_store *p)
{
    pthread_mutex_lock(&p->lock);
    for (;;) {
        for (int k = 0; k < POOL_SIZE; k++)
            if (!p->busy[k]) {
                p->busy[k] = true;
                pthread_mutex_unlock(&p->lock);
                if (PQstatus(p->pool[k]) != CONNECTION_OK)
                    PQreset(p->pool[k]);
                return k;
            }
        pthread_cond_wait(&p->freed, &p->lock);
    }
}

static void give(struct pg_store *p, int k)
{
    pthread_mutex_lock(&p->lock);
    p->busy[k] = false;
    pthread_cond_signal(&p->freed);
    pthread_mutex_unlock(&p->lock);
}

/* Parameters as execute() takes them: text, or binary (bytea) with its length. */
struct param {
    const char *v;
    int len;
    bool binary;
};
#define T(s) ((struct param){(s), 0, false})
#define BIN(p, n) ((struct param){(const char *)(p), (int)(n), true})

/* Runs sql with n parameters on connection c: the result, or NULL (a broken connection is reset
 * and the statement tried again once, when retry). */
static PGresult *execute(struct pg_store *p, int c, const char *sql, int n, const struct param *prm, bool retry)
{
    const char *values[16];
    int lengths[16], formats[16];
    for (int k = 0; k < n && k < 16; k++) {
        values[k] = prm[k].v;
        lengths[k] = prm[k].len;
        formats[k] = prm[k].binary;
    }
    for (int attempt = 0; attempt < (retry ? 2 : 1); attempt++) {
        PGresult *res = PQexecParams(p->pool[c], sql, n, NULL, values, lengths, formats, 1);
        ExecStatusType st = PQresultStatus(res);
        if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK)
            return res;
        const char *state = PQresultErrorField(res, PG_DIAG_SQLSTATE);
        if (state && !strcmp(state, "53100")) /* disk_full: cleared by the next probe that writes */
            atomic_store(&p->base.full, true);
        PQclear(res);
        if (PQstatus(p->pool[c]) == CONNECTION_OK)
            return NULL; /* the statement failed, not the connection */
        PQreset(p->pool[c]);
    }
    return NULL;
}

/* One statement on a pooled connection: the rows it changed (or returned), or SF_EIO. *out, when
 * given, receives the result (caller PQclear()s). */
static int exec1(struct store *s, PGresult **out, const char *sql, int n, const struct param *prm)
{
    struct pg_store *p = pg(s);
    int c = take(p);
    PGresult *res = execute(p, c, sql, n, prm, true);
    give(p, c);
    if (!res)
        return SF_EIO;
    int rows = PQresultStatus(res) == PGRES_TUPLES_OK ? PQntuples(res) : atoi(PQcmdTuples(res));
    if (out)
        *out = res;
    else
        PQclear(res);
    return rows;
}

/* Binary result values, in network byte order. */
static long long get_i64(const PGresult *r, int row, int col)
{
    const unsigned char *b = (const unsigned char *)PQgetvalue(r, row, col);
    unsigned long long v = 0;
    int n = PQgetlength(r, row, col);
    for (int k = 0; k < n; k++)
        v = v << 8 | b[k];
    if (n == 4)
        return (int32_t)(uint32_t)v;
    return (long long)v;
}

static double get_f64(const PGresult *r, int row, int col)
{
    long long bits = get_i64(r, row, col);
    double d;
    memcpy(&d, &bits, sizeof d);
    return d;
}

static void get_text(char *dst, size_t cap, const PGresult *r, int row, int col)
{
    snprintf(dst, cap, "%.*s", PQgetlength(r, row, col), PQgetisnull(r, row, col) ? "" : PQgetvalue(r, row, col));
}

static char *dup_text(const PGresult *r, int row, int col)
{
    if (PQgetisnull(r, row, col))
        return NULL;
    int n = PQgetlength(r, row, col);
    char *t = malloc((size_t)n + 1);
    if (t) {
        memcpy(t, PQgetvalue(r, row, col), (size_t)n);
        t[n] = 0;
    }
    return t;
}

static void num(char *buf, size_t cap, double v) { snprintf(buf, cap, "%.17g", v); }


/* ---- the lifecycle ---- */

static int pg_submit(struct store *s, const struct job_rec *r)
{
    char created[32];
    num(created, sizeof created, r->created);
    struct param prm[] = {T(r->id), T(r->kind), T(created), T(r->format), T(r->options),
                          BIN(r->request_len ? (const void *)r->request : "", r->request_len), T(r->owner)};
    return exec1(s, NULL,
                 "WITH j AS (INSERT INTO jobs(id,kind,state,created,format,options,request,owner)"
                 " VALUES($1,$2,'queued',$3,$4,$5,$6,$7) RETURNING id)"
                 " SELECT pg_notify('surfd', 'queued:' || id) FROM j",
                 7, prm) == 1 ? 0 : SF_EIO;
}

/* The job and its file's chunks in one transaction; the file is removed either way. */
static int pg_submit_file(struct store *s, const struct job_rec *r, const char *path)
{
    struct pg_store *p = pg(s);
    FILE *f = fopen(path, "rb");
    unsigned char *chunk = malloc(CHUNK);
    int c = take(p), rc = SF_EIO;
    PGresult *res = f && chunk ? execute(p, c, "BEGIN", 0, NULL, true) : NULL;
    if (res) {
        PQclear(res);
        char created[32];
        num(created, sizeof created, r->created);
        struct param prm[] = {T(r->id), T(r->kind), T(created), T(r->format), T(r->options), T(r->owner)};
        res = execute(p, c,
                      "INSERT INTO jobs(id,kind,state,created,format,options,request,owner,request_file)"
                      " VALUES($1,$2,'queued',$3,$4,$5,'',$6,true)",
                      6, prm, false);
        bool ok = res != NULL;
        PQclear(res);
        for (size_t seq = 0, n; ok && (n = fread(chunk, 1, CHUNK, f)) > 0; seq++) {
            char sq[24];
            snprintf(sq, sizeof sq, "%zu", seq);
            struct param cp[] = {T(r->id), T(sq), BIN(chunk, n)};
            ok = (res = execute(p, c, "INSERT INTO uploads(job,seq,data) VALUES($1,$2,$3)", 3, cp, false)) != NULL;
            PQclear(res);
        }
        ok = ok && !ferror(f);
        if (ok) {
            struct param n1[] = {T(r->id)};
            ok = (res = execute(p, c, "SELECT pg_notify('surfd', 'queued:' || $1::text)", 1, n1, false)) != NULL;
            PQclear(res);
        }
        res = execute(p, c, ok ? "COMMIT" : "ROLLBACK", 0, NULL, false);
        rc = res && ok ? 0 : SF_EIO;
        PQclear(res);
    }
    give(p, c);
    free(chunk);
    if (f)
        fclose(f);
    unlink(path);
    return rc;
}

/* Fetches job id's streamed body, chunk by chunk (single-row mode), into a scratch file. */
static int pg_request_file(struct store *s, const char *id, char *path, size_t cap)
{
    struct pg_store *p = pg(s);
    snprintf(path, cap, "%s/fetch-XXXXXX", p->scratch);
    int fd = mkstemp(path);
    if (fd < 0)
        return SF_EIO;
    FILE *f = fdopen(fd, "wb");
    int c = take(p);
    PGconn *conn = p->pool[c];
    const char *values[] = {id};
    bool ok = f && PQsendQueryParams(conn, "SELECT data FROM uploads WHERE job=$1 ORDER BY seq", 1, NULL, values, NULL,
                                     NULL, 1) &&
              PQsetSingleRowMode(conn);
    long rows = 0;
    PGresult *res;
    while ((res = PQgetResult(conn))) {
        ExecStatusType st = PQresultStatus(res);
        if (st == PGRES_SINGLE_TUPLE) {
            size_t n = (size_t)PQgetlength(res, 0, 0);
            ok = ok && fwrite(PQgetvalue(res, 0, 0), 1, n, f) == n;
            rows++;
        } else if (st != PGRES_TUPLES_OK) {
            ok = false;
        }
        PQclear(res);
    }
    give(p, c);
    if (f ? fclose(f) != 0 : (close(fd), true))
        ok = false;
    if (!ok || rows == 0) {
        unlink(path);
        return ok ? SF_ENOTFOUND : SF_EIO;
    }
    return 0;
}

static void pg_request_file_done(struct store *s, const char *path)
{
    (void)s;
    unlink(path); /* the copy: the database keeps the body until the job is pruned */
}

static int pg_claim(struct store *s, const char *node, double lease_s, bool alone, struct job_claim *out)
{
    char lease[32];
    num(lease, sizeof lease, lease_s);
    struct param prm[] = {T(node), T(lease), T(alone ? "true" : "false")};
    PGresult *res;
    int n = exec1(s, &res,
                  "UPDATE jobs SET state='running', progress=0, started=" NOW ", attempts=attempts+1, fence=fence+1,"
                  " node=$1, lease_until=" NOW "+$2::float8, cancel_requested=false"
                  " WHERE id=(SELECT id FROM jobs WHERE state='queued' AND not_before<=" NOW
                  " ORDER BY created, id LIMIT 1 FOR UPDATE SKIP LOCKED) AND (NOT suspect OR $3::boolean)"
                  " RETURNING id, kind, fence, suspect",
                  3, prm);
    if (n == 1) {
        get_text(out->id, sizeof out->id, res, 0, 0);
        get_text(out->kind, sizeof out->kind, res, 0, 1);
        out->fence = (long)get_i64(res, 0, 2);
        out->suspect = PQgetvalue(res, 0, 3)[0] != 0; /* results are binary: a boolean is 0 or 1 */
    }
    if (n >= 0)
        PQclear(res);
    return store_one_row(n, SF_ENOTFOUND); /* none queued that this node may take */
}

static int pg_heartbeat(struct store *s, const char *id, long fence, double lease_s, double progress, bool *cancel)
{
    char lease[32], prog[32], f[24];
    num(lease, sizeof lease, lease_s);
    num(prog, sizeof prog, progress);
    snprintf(f, sizeof f, "%ld", fence);
    struct param prm[] = {T(lease), T(prog), T(id), T(f)};
    PGresult *res;
    int n = exec1(s, &res,
                  "UPDATE jobs SET lease_until=" NOW "+$1::float8, progress=GREATEST(progress,$2::float8)"
                  " WHERE id=$3 AND fence=$4 AND state='running' RETURNING cancel_requested",
                  4, prm);
    if (n == 1)
        *cancel = PQgetvalue(res, 0, 0)[0] != 0;
    if (n >= 0)
        PQclear(res);
    return store_one_row(n, SF_ECONFLICT); /* no running row under that fence: the claim is lost */
}

/* Writes len bytes as rows of size bytes (insert: "INSERT INTO T(key,seq,data) VALUES($1,$2,$3)")
 * on connection c, inside the caller's transaction: a result's chunks, a value's pieces. 0 or SF_EIO. */
static int put_rows(struct pg_store *p, int c, const char *insert, const char *key, const unsigned char *data,
                    size_t len, size_t size)
{
    for (size_t off = 0, seq = 0; off < len || seq == 0; off += size, seq++) {
        size_t n = len - off < size ? len - off : size;
        char sq[24];
        snprintf(sq, sizeof sq, "%zu", seq);
        struct param prm[] = {T(key), T(sq), BIN(len ? (const void *)(data + off) : "", n)};
        PGresult *res = execute(p, c, insert, 3, prm, false);
        if (!res)
            return SF_EIO;
        PQclear(res);
        if (len == 0)
            break;
    }
    return 0;
}

static int pg_finish(struct store *s, const char *id, long fence, const struct job_end *e)
{
    struct pg_store *p = pg(s);
    char f[24], fin[32], len[24], sum[65] = "";
    snprintf(f, sizeof f, "%ld", fence);
    num(fin, sizeof fin, e->finished);
    snprintf(len, sizeof len, "%zu", e->len);
    if (e->outcome == JOB_SUCCEEDED)
        store_checksum(e->result, e->len, "", 0, sum);
    struct param prm[] = {T(job_state_name(e->outcome)), T(fin), T(e->error), T(e->type), T(e->meta),
                          T(e->outcome == JOB_SUCCEEDED ? sum : NULL), T(e->outcome == JOB_SUCCEEDED ? len : NULL),
                          T(id), T(f)};
    int c = take(p);
    int rc = SF_EIO;
    PGresult *res = execute(p, c, "BEGIN", 0, NULL, true);
    if (res) {
        PQclear(res);
        res = execute(p, c,
                      "UPDATE jobs SET state=$1, finished=$2, error=$3, result_type=$4, meta=$5, result_sum=$6,"
                      " result_len=$7, progress=CASE WHEN $1::text='succeeded' THEN 1 ELSE progress END, lease_until=0"
                      " WHERE id=$8 AND fence=$9 AND state='running'",
                      9, prm, false);
        int changed = res ? atoi(PQcmdTuples(res)) : SF_EIO;
        PQclear(res);
        if (changed == 1 && e->outcome == JOB_SUCCEEDED &&
            put_rows(p, c, "INSERT INTO results(job,seq,data) VALUES($1,$2,$3)", id, e->result, e->len, CHUNK))
            changed = SF_EIO;
        if (changed == 1) {
            struct param n1[] = {T(id)};
            res = execute(p, c, "SELECT pg_notify('surfd', 'ended:' || $1::text)", 1, n1, false);
            changed = res ? 1 : SF_EIO;
            PQclear(res);
        }
        res = execute(p, c, changed == 1 ? "COMMIT" : "ROLLBACK", 0, NULL, false);
        if (res && changed >= 0)
            rc = store_one_row(changed, SF_ECONFLICT);
        PQclear(res);
    }
    give(p, c);
    return rc;
}

static int pg_release(struct store *s, const char *id, long fence)
{
    char f[24];
    snprintf(f, sizeof f, "%ld", fence);
    struct param prm[] = {T(id), T(f)};
    return store_one_row(exec1(s, NULL,
                         "WITH j AS (UPDATE jobs SET state=CASE WHEN cancel_requested THEN 'cancelled' ELSE 'queued' END,"
                         " finished=CASE WHEN cancel_requested THEN " NOW " ELSE finished END, progress=0,"
                         " attempts=GREATEST(attempts-1,0), lease_until=0 WHERE id=$1 AND fence=$2 AND state='running'"
                         " RETURNING id, state)"
                         " SELECT pg_notify('surfd', CASE WHEN state='queued' THEN 'queued:' ELSE 'ended:' END || id)"
                         " FROM j",
                         2, prm),
                   SF_ECONFLICT);
}

static int pg_cancel(struct store *s, const char *id, const char *owner, double now, bool *asked)
{
    char t[32];
    num(t, sizeof t, now);
    struct param prm[] = {T(id), T(owner), T(t)};
    int n = exec1(s, NULL,
                  "WITH j AS (UPDATE jobs SET state='cancelled', finished=$3 WHERE id=$1 AND state='queued' AND"
                  " ($2::text IS NULL OR owner=$2) RETURNING id) SELECT pg_notify('surfd', 'ended:' || id) FROM j",
                  3, prm);
    if (n)
        return n > 0 ? 0 : SF_EIO;
    n = exec1(s, NULL,
              "WITH j AS (UPDATE jobs SET cancel_requested=true WHERE id=$1 AND state='running' AND"
              " ($2::text IS NULL OR owner=$2) RETURNING id) SELECT pg_notify('surfd', 'cancel:' || id) FROM j",
              2, prm);
    if (n > 0)
        *asked = true;
    if (n)
        return n > 0 ? 0 : SF_EIO;
    n = exec1(s, NULL, "SELECT 1 FROM jobs WHERE id=$1 AND ($2::text IS NULL OR owner=$2)", 2, prm);
    return n < 0 ? SF_EIO : n ? SF_ECONFLICT : SF_ENOTFOUND; /* ended, or not this owner's */
}

static int pg_reap(struct store *s, double now, const char *node, int max_attempts, const char *give_up,
                   void (*fn)(const char *, enum job_state, void *), void *arg)
{
    (void)now; /* the database's clock decides leases */
    struct pg_store *p = pg(s);
    char max[16];
    snprintf(max, sizeof max, "%d", max_attempts);
    struct param prm[] = {T(node), T(max), T(give_up)};
    int c = take(p);
    int reaped = SF_EIO;
    PGresult *res = execute(p, c, "BEGIN", 0, NULL, true), *rows = NULL;
    if (res) {
        PQclear(res);
        res = execute(p, c, "SELECT pg_try_advisory_xact_lock(" REAP_LOCK ")", 0, NULL, false);
        bool mine = res && PQgetvalue(res, 0, 0)[0];
        PQclear(res);
        reaped = 0;
        if (mine) /* one statement, store_reaped_state's rule: cancel those asked, fail the lone ones at the
                   * maximum, queue the others as suspects after their backoff (those that ran beside
                   * others with their attempt given back) */
            rows = execute(p, c,
                           "WITH r AS (SELECT id FROM jobs WHERE state='running' AND (lease_until<" NOW
                           " OR node=$1) FOR UPDATE SKIP LOCKED),"
                           " c AS (SELECT j.id, j.cancel_requested AS cx, j.attempts>=$2::int AND count(*) OVER"
                           "  (PARTITION BY j.node)=1 AS fail, count(*) OVER (PARTITION BY j.node)>1 AS beside"
                           "  FROM jobs j JOIN r ON j.id=r.id),"
                           " u AS (UPDATE jobs j SET"
                           "  state=CASE WHEN c.cx THEN 'cancelled' WHEN c.fail THEN 'failed' ELSE 'queued' END,"
                           "  error=CASE WHEN NOT c.cx AND c.fail THEN $3::text ELSE j.error END,"
                           "  finished=CASE WHEN c.cx OR c.fail THEN " NOW " ELSE j.finished END,"
                           "  attempts=CASE WHEN c.beside AND NOT c.cx THEN GREATEST(j.attempts-1, 0) ELSE j.attempts END,"
                           "  suspect=true, progress=0, lease_until=0,"
                           "  not_before=" NOW "+LEAST(60, power(2, GREATEST(j.attempts-1, 0)))"
                           "  FROM c WHERE j.id=c.id RETURNING j.id, j.state)"
                           " SELECT id, state, pg_notify('surfd', CASE WHEN state='queued' THEN 'queued:' ELSE"
                           " 'ended:' END || id) FROM u",
                           3, prm, false);
        res = execute(p, c, rows ? "COMMIT" : "ROLLBACK", 0, NULL, false);
        if (!res || (mine && !rows))
            reaped = SF_EIO;
        PQclear(res);
    }
    give(p, c);
    if (rows && reaped == 0) {
        reaped = PQntuples(rows);
        for (int k = 0; fn && k < reaped; k++) {
            char id[40], state[16];
            get_text(id, sizeof id, rows, k, 0);
            get_text(state, sizeof state, rows, k, 1);
            enum job_state st = JOB_QUEUED;
            job_state_parse(state, &st);
            fn(id, st, arg);
        }
    }
    PQclear(rows);
    return reaped;
}

static int pg_prune(struct store *s, double now, long ttl, long max_count)
{
    char before[32], max[24];
    num(before, sizeof before, now - (double)ttl);
    snprintf(max, sizeof max, "%ld", max_count);
    struct param prm[] = {T(before), T(max)};
    /* the streamed bodies of ended jobs: their runs are over, the space is the owner's share again */
    if (exec1(s, NULL, "DELETE FROM uploads WHERE job IN (SELECT id FROM jobs WHERE state NOT IN ('queued','running'))",
              0, NULL) < 0)
        return SF_EIO;
    return exec1(s, NULL,
                 "DELETE FROM jobs WHERE state IN ('succeeded','failed','cancelled') AND (finished < $1::float8 OR id NOT IN"
                 " (SELECT id FROM jobs WHERE state IN ('succeeded','failed','cancelled') ORDER BY finished DESC"
                 " LIMIT $2::bigint))",
                 2, prm) < 0 ? SF_EIO : 0;
}

/* ---- reading ---- */

#define REC_COLUMNS                                                                                         \
    "id,kind,state,progress,created,started,finished,format,options,result_type,meta,error,attempts,owner,"        \
    "result_sum,node,cancel_requested,request_file"
#define REC_N_COLUMNS 18

static void read_rec(const PGresult *r, int row, struct job_rec *out)
{
    memset(out, 0, sizeof *out);
    char state[16];
    get_text(out->id, sizeof out->id, r, row, 0);
    get_text(out->kind, sizeof out->kind, r, row, 1);
    get_text(state, sizeof state, r, row, 2);
    if (!job_state_parse(state, &out->state))
        out->state = JOB_FAILED;
    out->progress = get_f64(r, row, 3);
    out->created = get_f64(r, row, 4);
    out->started = get_f64(r, row, 5);
    out->finished = get_f64(r, row, 6);
    get_text(out->format, sizeof out->format, r, row, 7);
    get_text(out->options, sizeof out->options, r, row, 8);
    get_text(out->result_type, sizeof out->result_type, r, row, 9);
    out->meta = dup_text(r, row, 10);
    out->error = dup_text(r, row, 11);
    out->attempts = (int)get_i64(r, row, 12);
    get_text(out->owner, sizeof out->owner, r, row, 13);
    get_text(out->result_sum, sizeof out->result_sum, r, row, 14);
    get_text(out->node, sizeof out->node, r, row, 15);
    out->cancel_requested = PQgetvalue(r, row, 16)[0] != 0;
    out->request_file = PQgetvalue(r, row, 17)[0] != 0;
}

/* Reads the rows select (of key, "SELECT data ... ORDER BY seq") one at a time (single-row mode)
 * into one buffer of len bytes, their sum: a result's chunks, a value's pieces. 0 (*out: the caller
 * frees it), or SF_EIO. */
static int get_rows(struct pg_store *p, const char *select, const char *key, size_t len, unsigned char **out)
{
    int c = take(p);
    PGconn *conn = p->pool[c];
    const char *values[] = {key};
    unsigned char *buf = malloc(len ? len : 1);
    size_t at = 0;
    bool ok = buf && PQsendQueryParams(conn, select, 1, NULL, values, NULL, NULL, 1) && PQsetSingleRowMode(conn);
    PGresult *res;
    while ((res = PQgetResult(conn))) {
        ExecStatusType st = PQresultStatus(res);
        if (st == PGRES_SINGLE_TUPLE) {
            size_t n = (size_t)PQgetlength(res, 0, 0);
            if (ok && at + n <= len)
                memcpy(buf + at, PQgetvalue(res, 0, 0), n);
            ok = ok && at + n <= len;
            at += n;
        } else if (st != PGRES_TUPLES_OK) {
            ok = false;
        }
        PQclear(res);
    }
    give(p, c);
    if (!ok || at != len) {
        free(buf);
        return SF_EIO;
    }
    *out = buf;
    return 0;
}

static int pg_get(struct store *s, const char *id, bool with_request, bool with_result, struct job_rec *out)
{
    struct param prm[] = {T(id)};
    PGresult *res;
    int n = exec1(s, &res, "SELECT " REC_COLUMNS ",request,result_len FROM jobs WHERE id=$1", 1, prm); /* out zeroed by store_get */
    if (n < 0)
        return SF_EIO;
    if (n == 0) {
        PQclear(res);
        return SF_ENOTFOUND;
    }
    read_rec(res, 0, out);
    int rc = 0;
    if (with_request) {
        out->request_len = (size_t)PQgetlength(res, 0, REC_N_COLUMNS);
        out->request = malloc(out->request_len ? out->request_len : 1);
        if (out->request)
            memcpy(out->request, PQgetvalue(res, 0, REC_N_COLUMNS), out->request_len);
        else
            rc = SF_EIO;
    }
    bool has_result = !PQgetisnull(res, 0, REC_N_COLUMNS + 1);
    size_t len = has_result ? (size_t)get_i64(res, 0, REC_N_COLUMNS + 1) : 0;
    PQclear(res);
    if (rc == 0 && with_result && has_result) {
        if (get_rows(pg(s), "SELECT data FROM results WHERE job=$1 ORDER BY seq", id, len, &out->result)) {
            rc = SF_EIO;
        } else {
            out->result_len = len;
            char sum[65];
            store_checksum(out->result, len, "", 0, sum);
            if (out->result_sum[0] && strcmp(sum, out->result_sum))
                rc = SF_EDAMAGED;
        }
    }
    if (rc)
        store_rec_free(out);
    return rc;
}

static int pg_list(struct store *s, const enum job_state *state, const char *owner, long limit,
                   void (*fn)(const struct job_rec *, void *), void *arg)
{
    char lim[24];
    snprintf(lim, sizeof lim, "%ld", limit > 0 ? limit : 1000000000L);
    struct param prm[] = {T(state ? job_state_name(*state) : NULL), T(owner), T(lim)};
    PGresult *res;
    int n = exec1(s, &res,
                  "SELECT " REC_COLUMNS " FROM jobs WHERE ($1::text IS NULL OR state=$1) AND ($2::text IS NULL OR"
                  " owner=$2) ORDER BY created DESC LIMIT $3::bigint",
                  3, prm);
    for (int k = 0; k < n; k++) {
        struct job_rec r;
        read_rec(res, k, &r);
        fn(&r, arg);
        store_rec_free(&r);
    }
    if (n >= 0)
        PQclear(res);
    return n < 0 ? SF_EIO : 0;
}

/* The one bigint a query answers, or SF_EIO. */
static long query_count(struct store *s, const char *sql)
{
    PGresult *res;
    int rows = exec1(s, &res, sql, 0, NULL);
    if (rows != 1) {
        if (rows >= 0)
            PQclear(res);
        return SF_EIO;
    }
    long n = (long)get_i64(res, 0, 0);
    PQclear(res);
    return n;
}

static long pg_queued(struct store *s) { return query_count(s, "SELECT count(*) FROM jobs WHERE state='queued'"); }

/* ---- models ---- */

/* One statement of a transaction on connection c: the rows it changed, or SF_EIO. */
static int exec_in(struct pg_store *p, int c, const char *sql, int n, const struct param *prm)
{
    PGresult *res = execute(p, c, sql, n, prm, false);
    int rows = res ? atoi(PQcmdTuples(res)) : SF_EIO;
    PQclear(res);
    return rows;
}

/* Values longer than a piece (store.h): PostgreSQL holds at most 1 GB in one bytea. Such a value
 * is written as rows of pieces(name, seq, data) on the writer's connection, in its transaction;
 * its column is left empty and the column *_pieces names them (NULL for a value in its column).
 * A row's pieces are deleted with it by the schema's trigger (surfd_drop_pieces); pieces written
 * in a transaction that rolled back are gone with it. */

/* The parameters for a value of len bytes written on connection c: *v the bytes, or (the pieces
 * written first, named in name) empty, with *pieces the name or NULL. 0, or SF_EIO. */
static int value_params(struct pg_store *p, int c, const void *data, size_t len, char name[48], struct param *v,
                        struct param *pieces)
{
    *v = BIN(len ? data : "", len), *pieces = T(NULL);
    if (len <= p->base.piece)
        return 0;
    if (store_piece_name(name) ||
        put_rows(p, c, "INSERT INTO pieces(name,seq,data) VALUES($1,$2,$3)", name, data, len, p->base.piece))
        return SF_EIO;
    *v = BIN("", 0), *pieces = T(name);
    return 0;
}

/* Row row's value: column col, or the pieces column pieces_col names. A copy (*len bytes; the
 * caller frees it), or NULL without memory or when the pieces cannot be read. */
static unsigned char *value_copy(struct pg_store *p, const PGresult *res, int row, int col, int pieces_col, size_t *len)
{
    if (PQgetisnull(res, row, pieces_col)) {
        *len = (size_t)PQgetlength(res, row, col);
        unsigned char *b = malloc(*len + 1);
        if (b) {
            memcpy(b, PQgetvalue(res, row, col), *len);
            b[*len] = 0;
        }
        return b;
    }
    const char *name = PQgetvalue(res, row, pieces_col);
    struct param prm[] = {T(name)};
    PGresult *r;
    if (exec1(&p->base, &r, "SELECT COALESCE(sum(octet_length(data)), 0)::bigint FROM pieces WHERE name=$1", 1, prm) != 1)
        return NULL;
    *len = (size_t)get_i64(r, 0, 0);
    PQclear(r);
    unsigned char *b = NULL;
    return get_rows(p, "SELECT data FROM pieces WHERE name=$1 ORDER BY seq", name, *len, &b) ? NULL : b;
}

/* Volume part v of model id on connection c: 0, SF_ECONFLICT when its seq is taken, SF_EIO. */
static int volume_put(struct pg_store *p, int c, const char *id, const struct volume_rec *v)
{
    char seq[16], sum[65];
    snprintf(seq, sizeof seq, "%d", v->seq);
    store_checksum(v->options, strlen(v->options), v->data, v->len, sum);
    char name[48];
    struct param prm[] = {T(id), T(seq), T(v->format), T(v->options), T(NULL), T(sum), T(NULL)};
    if (value_params(p, c, v->data, v->len, name, &prm[4], &prm[6]))
        return SF_EIO;
    return store_one_row(exec_in(p, c,
                           "INSERT INTO model_volumes(model,seq,format,options,data,sum,data_pieces)"
                           " VALUES($1,$2,$3,$4,$5,$6,$7) ON CONFLICT DO NOTHING",
                           7, prm),
                   SF_ECONFLICT);
}

/* The model's row (update: only its source and resource, of an existing row) on connection c: the
 * rows written (0: no such row to update), or SF_EIO. */
static int model_row(struct pg_store *p, int c, const struct model_rec *m, bool update)
{
    char created[32], sum[65], rsum[65], base[24];
    num(created, sizeof created, m->created);
    snprintf(base, sizeof base, "%ld", m->version > 0 ? m->version : 1);
    store_checksum(m->resource, strlen(m->resource), "", 0, rsum);
    if (!m->source) { /* the resource alone: the source (the mesh's base) stays, with its own sum */
        struct param up[] = {T(m->id), T(m->resource), T(rsum)};
        return exec_in(p, c, "UPDATE models SET resource=$2, resource_sum=$3 WHERE id=$1 AND base_version>0", 3, up);
    }
    store_checksum(m->source, m->source_len, "", 0, sum);
    char name[48];
    struct param prm[] = {T(m->id), T(m->job), T(m->name ? m->name : ""), T(created), T(NULL),
                          T(m->resource), T(m->owner ? m->owner : ""), T(sum), T(rsum), T(NULL), T(base)};
    if (value_params(p, c, m->source, m->source_len, name, &prm[4], &prm[9]))
        return SF_EIO;
    if (update) {
        struct param up[] = {prm[0], prm[4], prm[5], prm[7], prm[8], prm[9], prm[10]};
        return exec_in(p, c, "UPDATE models SET source=$2, resource=$3, sum=$4, resource_sum=$5, source_pieces=$6,"
                       " base_version=$7 WHERE id=$1", 7, up);
    }
    return exec_in(p, c,
                   "INSERT INTO models(id,job,name,created,source,resource,owner,sum,resource_sum,source_pieces,"
                   "base_version) VALUES($1,$2,$3,$4,$5,$6,$7,$8,$9,$10,$11)"
                   " ON CONFLICT (id) DO UPDATE SET job=EXCLUDED.job, name=EXCLUDED.name, created=EXCLUDED.created,"
                   " source=EXCLUDED.source, resource=EXCLUDED.resource, owner=EXCLUDED.owner, sum=EXCLUDED.sum,"
                   " resource_sum=EXCLUDED.resource_sum, source_pieces=EXCLUDED.source_pieces,"
                   " base_version=EXCLUDED.base_version",
                   11, prm);
}

/* step(p, c, arg) as one transaction on a connection of its own: its answer (0 commits, anything
 * else rolls back), or SF_EIO. */
static int in_transaction(struct pg_store *p, int (*step)(struct pg_store *, int, const void *), const void *arg)
{
    int c = take(p), rc = SF_EIO;
    PGresult *res = execute(p, c, "BEGIN", 0, NULL, true);
    if (res) {
        PQclear(res);
        rc = step(p, c, arg);
        res = execute(p, c, rc == 0 ? "COMMIT" : "ROLLBACK", 0, NULL, false);
        if (!res)
            rc = SF_EIO;
        PQclear(res);
    }
    give(p, c);
    return rc;
}

struct model_write {
    const struct model_rec *m;
    const struct volume_rec *v, *change;
    bool update;
    long drop_through;       /* model_rebase's */
};

/* A model's row and its volume parts (v, change: NULL for none): 0, SF_ECONFLICT (the part's seq
 * was taken, or no such model to update), SF_EIO. */
static int model_step(struct pg_store *p, int c, const void *arg)
{
    const struct model_write *w = arg;
    const struct model_rec *m = w->m;
    struct param id[] = {T(m->id)};
    int rc = store_one_row(model_row(p, c, m, w->update), SF_ECONFLICT);
    if (rc == 0 && !w->update && exec_in(p, c, "DELETE FROM model_volumes WHERE model=$1", 1, id) < 0)
        rc = SF_EIO;
    if (rc == 0 && w->update && exec_in(p, c, "DELETE FROM meshes WHERE model=$1", 1, id) < 0) /* the edit's before */
        rc = SF_EIO;
    if (rc == 0 && w->v)
        rc = volume_put(p, c, m->id, w->v);
    if (rc == 0 && w->change)
        rc = volume_put(p, c, m->id, w->change);
    return rc;
}

static int pg_model_put(struct store *s, const struct model_rec *m)
{
    return in_transaction(pg(s), model_step, &(struct model_write){m, m->volume, NULL, false, 0}) ? SF_EIO : 0;
}

static int pg_model_edit(struct store *s, const struct model_rec *m, const struct volume_rec *edit,
                         const struct volume_rec *change)
{
    return in_transaction(pg(s), model_step, &(struct model_write){m, edit, change, true, 0});
}

/* A newer base of the model (when the one kept is older), the changes up to drop_through gone. */
static int rebase_step(struct pg_store *p, int c, const void *arg)
{
    const struct model_write *w = arg;
    char sum[65], base[24], drop[24], name[48];
    store_checksum(w->m->source, w->m->source_len, "", 0, sum);
    snprintf(base, sizeof base, "%ld", w->m->version);
    snprintf(drop, sizeof drop, "%ld", -w->drop_through);
    struct param prm[] = {T(w->m->id), T(NULL), T(sum), T(base), T(NULL)}, del[] = {T(w->m->id), T(drop)};
    return value_params(p, c, w->m->source, w->m->source_len, name, &prm[1], &prm[4]) ||
                   exec_in(p, c, "UPDATE models SET source=$2, sum=$3, base_version=$4, source_pieces=$5 WHERE id=$1"
                           " AND base_version>0 AND base_version<$4", 5, prm) < 0 ||
                   exec_in(p, c, "DELETE FROM model_volumes WHERE model=$1 AND seq<0 AND seq>=$2::integer", 2, del) < 0
               ? SF_EIO
               : 0;
}

static int pg_model_rebase(struct store *s, const struct model_rec *m, long drop_through)
{
    return in_transaction(pg(s), rebase_step, &(struct model_write){m, NULL, NULL, false, drop_through});
}

static int pg_model_refresh(struct store *s, const char *id, long version, const char *resource, const char *sum)
{
    char v[24];
    snprintf(v, sizeof v, "%ld", version);
    struct param prm[] = {T(id), T(resource), T(sum), T(v)};
    return store_one_row(exec1(s, NULL, "UPDATE models SET resource=$2, resource_sum=$3 WHERE id=$1 AND base_version>0 AND"
                               " NOT EXISTS (SELECT 1 FROM model_volumes WHERE model=$1 AND seq>=$4::integer)", 4, prm),
                         SF_ECONFLICT);
}

static int pg_volume_get(struct store *s, const char *id, int from, int to, struct volume_rec **parts, int *n)
{
    char f[16], t[16];
    snprintf(f, sizeof f, "%d", from);
    snprintf(t, sizeof t, "%d", to);
    struct param prm[] = {T(id), T(f), T(t)};
    PGresult *res;
    int rows = exec1(s, &res,
                     "SELECT seq, format, options, data, sum, data_pieces FROM model_volumes WHERE model=$1 AND"
                     " seq>=$2::integer AND seq<$3::integer ORDER BY seq",
                     3, prm);
    if (rows < 0)
        return SF_EIO;
    int rc = 0;
    for (int k = 0; k < rows && rc == 0; k++) {
        const char *opt = PQgetvalue(res, k, 2);
        size_t len;
        unsigned char *data = value_copy(pg(s), res, k, 3, 5, &len);
        char sum[65];
        if (data)
            store_checksum(opt, strlen(opt), data, len, sum);
        if (!data)
            rc = SF_EIO;
        else if (strcmp(sum, PQgetvalue(res, k, 4)))
            rc = SF_EDAMAGED;
        else if (store_volume_add(parts, n, (int)get_i64(res, k, 0), PQgetvalue(res, k, 1), opt, data, len))
            rc = SF_EIO;
        free(data);
    }
    PQclear(res);
    return rc;
}

/* The resource alone, checked against its own sum, without fetching the source: 0, SF_ENOTFOUND,
 * SF_EIO, SF_EDAMAGED. *summed false (0 answered, nothing read): a row written before resource sums
 * were kept, whose resource only the model's sum covers. */
static int pg_resource_get(struct store *s, const char *id, const char *owner, char **resource, bool *summed)
{
    struct param prm[] = {T(id), T(owner)};
    PGresult *res;
    *summed = true;
    int n = exec1(s, &res, "SELECT resource, resource_sum FROM models WHERE id=$1 AND ($2::text IS NULL OR owner=$2)", 2,
                  prm);
    if (n <= 0) {
        if (n == 0)
            PQclear(res);
        return n == 0 ? SF_ENOTFOUND : SF_EIO;
    }
    int rc = 0;
    if (PQgetisnull(res, 0, 1)) {
        *summed = false;
    } else {
        char sum[65];
        store_checksum(PQgetvalue(res, 0, 0), (size_t)PQgetlength(res, 0, 0), "", 0, sum);
        rc = strcmp(sum, PQgetvalue(res, 0, 1)) ? SF_EDAMAGED : 0;
    }
    if (rc == 0 && *summed && resource && !(*resource = dup_text(res, 0, 0)))
        rc = SF_EIO;
    PQclear(res);
    return rc;
}

static int pg_model_get(struct store *s, const char *id, const char *owner, char **resource, char **source,
                        size_t *source_len)
{
    if (!source) {
        bool summed;
        int rc = pg_resource_get(s, id, owner, resource, &summed);
        if (rc || summed)
            return rc;
    }
    struct param prm[] = {T(id), T(owner)};
    PGresult *res;
    int n = exec1(s, &res,
                  "SELECT resource, source, sum, source_pieces, base_version, resource_sum FROM models WHERE id=$1 AND"
                  " ($2::text IS NULL OR owner=$2)",
                  2, prm);
    if (n <= 0) {
        if (n == 0)
            PQclear(res);
        return n == 0 ? SF_ENOTFOUND : SF_EIO;
    }
    const char *rsc = PQgetvalue(res, 0, 0);
    size_t ns = 0, nr = (size_t)PQgetlength(res, 0, 0);
    unsigned char *src = value_copy(pg(s), res, 0, 1, 3, &ns);
    char sum[65], rsum[65] = "";
    bool apart = get_i64(res, 0, 4) > 0; /* (a row of a base version: its source and resource summed apart) */
    if (src)
        store_checksum(src, ns, apart ? "" : rsc, apart ? 0 : nr, sum);
    if (apart)
        store_checksum(rsc, nr, "", 0, rsum);
    int rc = !src ? SF_EIO
             : (PQgetisnull(res, 0, 2) || !strcmp(sum, PQgetvalue(res, 0, 2))) &&
                       (!apart || PQgetisnull(res, 0, 5) || !strcmp(rsum, PQgetvalue(res, 0, 5)))
                 ? 0
                 : SF_EDAMAGED;
    if (rc == 0 && resource && !(*resource = dup_text(res, 0, 0)))
        rc = SF_EIO;
    if (rc == 0 && source) {
        *source = (char *)src, src = NULL;
        if (source_len)
            *source_len = ns;
    }
    free(src);
    PQclear(res);
    return rc;
}

static int pg_model_list(struct store *s, const char *owner, long limit, void (*fn)(const char *, void *), void *arg)
{
    char lim[24];
    snprintf(lim, sizeof lim, "%ld", limit > 0 ? limit : 1000000000L);
    struct param prm[] = {T(owner), T(lim)};
    PGresult *res;
    int n = exec1(s, &res,
                  "SELECT resource, resource_sum FROM models WHERE $1::text IS NULL OR owner=$1 ORDER BY created DESC, id"
                  " LIMIT $2::bigint",
                  2, prm);
    bool damaged = false;
    for (int k = 0; k < n && !damaged; k++) {
        char sum[65];
        store_checksum(PQgetvalue(res, k, 0), (size_t)PQgetlength(res, k, 0), "", 0, sum);
        damaged = !PQgetisnull(res, k, 1) && strcmp(sum, PQgetvalue(res, k, 1));
        char *r = damaged ? NULL : dup_text(res, k, 0);
        if (r)
            fn(r, arg);
        free(r);
    }
    if (n >= 0)
        PQclear(res);
    return n < 0 ? SF_EIO : damaged ? SF_EDAMAGED : 0;
}

static int pg_model_delete(struct store *s, const char *id, const char *owner)
{
    struct param prm[] = {T(id), T(owner)};
    return store_one_row(exec1(s, NULL, "DELETE FROM models WHERE id=$1 AND ($2::text IS NULL OR owner=$2)", 2, prm),
                   SF_ENOTFOUND);
}

static int pg_mesh_get(struct store *s, const char *model, const char *key, struct mesh_rec *out)
{
    struct param prm[] = {T(model), T(key)};
    PGresult *res;
    int rows = exec1(s, &res,
                     "UPDATE meshes SET used=" NOW " WHERE model=$1 AND key=$2 RETURNING type, meta, data, sum,"
                     " data_pieces", 2, prm);
    if (rows < 0)
        return SF_EIO;
    int rc = rows > 0 ? 0 : SF_ENOTFOUND;
    if (rc == 0) {
        out->type = strdup(PQgetvalue(res, 0, 0));
        out->meta = strdup(PQgetvalue(res, 0, 1));
        out->data = value_copy(pg(s), res, 0, 2, 4, &out->len);
        snprintf(out->sum, sizeof out->sum, "%s", PQgetvalue(res, 0, 3));
        if (!out->type || !out->meta || !out->data)
            rc = SF_EIO;
    }
    PQclear(res);
    return rc;
}

/* A cached mesh's bytes, in its row or its pieces. */
#define MESH_BYTES                                                                                                  \
    "CASE WHEN data_pieces IS NULL THEN octet_length(data)"                                                         \
    " ELSE (SELECT sum(octet_length(p.data)) FROM pieces p WHERE p.name = meshes.data_pieces) END"

static int pg_mesh_put(struct store *s, const char *model, const char *key, const struct mesh_rec *m, long max_bytes)
{
    char budget[32];
    snprintf(budget, sizeof budget, "%ld", max_bytes);
    struct pg_store *p = pg(s);
    char name[48];
    struct param prm[] = {T(model), T(key), T(m->type), T(m->meta ? m->meta : ""), T(NULL), T(m->sum), T(NULL)};
    int c = take(p), n = SF_EIO;
    PGresult *res = execute(p, c, "BEGIN", 0, NULL, true);
    if (res) {
        PQclear(res);
        if (!value_params(p, c, m->data, m->len, name, &prm[4], &prm[6]))
            n = exec_in(p, c,
                        "INSERT INTO meshes(model,key,type,meta,data,sum,used,data_pieces) SELECT $1,$2,$3,$4,$5,$6," NOW
                        ",$7 WHERE EXISTS (SELECT 1 FROM models WHERE id=$1) ON CONFLICT (model, key) DO UPDATE SET"
                        " type=EXCLUDED.type, meta=EXCLUDED.meta, data=EXCLUDED.data, sum=EXCLUDED.sum,"
                        " used=EXCLUDED.used, data_pieces=EXCLUDED.data_pieces",
                        7, prm);
        res = execute(p, c, n > 0 ? "COMMIT" : "ROLLBACK", 0, NULL, false);
        if (!res)
            n = SF_EIO;
        PQclear(res);
    }
    give(p, c);
    struct param cap[] = {T(budget)};
    if (n > 0 && exec1(s, NULL,
                       "DELETE FROM meshes WHERE (model, key) IN (SELECT model, key FROM (SELECT model, key,"
                       " SUM(" MESH_BYTES ") OVER (ORDER BY used DESC, model, key) AS run FROM meshes) t"
                       " WHERE run > $1::bigint)", /* the least used past the budget */
                       1, cap) < 0)
        n = SF_EIO;
    return store_one_row(n, SF_ECONFLICT); /* no row: the model is gone */
}

static long pg_mesh_bytes(struct store *s)
{
    return query_count(s, "SELECT COALESCE(SUM(" MESH_BYTES "), 0)::bigint FROM meshes");
}

static bool pg_writable(struct store *s)
{
    PGresult *res;
    if (exec1(s, &res, "SELECT NOT pg_is_in_recovery()", 0, NULL) != 1)
        return false;
    bool ok = PQgetvalue(res, 0, 0)[0] != 0;
    PQclear(res);
    /* after a full disk, room again is a 32 MB sort (past work_mem: written to the server's disk) */
    if (ok && atomic_load(&s->full) &&
        (ok = exec1(s, NULL, "SELECT count(*) FROM (SELECT repeat(g::text, 1 << 20) AS x FROM generate_series(1, 32) g"
                             " ORDER BY x) t", 0, NULL) >= 0))
        atomic_store(&s->full, false);
    return ok;
}

/* ---- events: LISTEN surfd on a connection of the listener's own ---- */

static void *listen_loop(void *arg)
{
    struct pg_store *p = arg;
    PGconn *c = NULL;
    for (;;) {
        pthread_mutex_lock(&p->lock);
        bool stop = p->stop;
        pthread_mutex_unlock(&p->lock);
        if (stop)
            break;
        if (!c || PQstatus(c) != CONNECTION_OK) { /* (re)connect: the database may be restarting */
            if (c)
                PQfinish(c);
            c = connect_db(p->uri);
            PGresult *r = PQstatus(c) == CONNECTION_OK ? PQexec(c, "LISTEN surfd") : NULL;
            bool ok = r && PQresultStatus(r) == PGRES_COMMAND_OK;
            PQclear(r);
            if (!ok) {
                struct timespec ts = {0, 500 * 1000000L};
                nanosleep(&ts, NULL);
                continue;
            }
            if (p->event) /* what happened while it was away: look again */
                p->event(STORE_QUEUED, "", p->event_arg);
        }
        struct pollfd pfd = {PQsocket(c), POLLIN, 0};
        if (poll(&pfd, 1, 250) > 0 && !PQconsumeInput(c))
            continue; /* broken: reconnect above */
        PGnotify *n;
        while ((n = PQnotifies(c))) {
            const char *colon = strchr(n->extra, ':');
            const char *id = colon ? colon + 1 : "";
            enum store_event ev = !strncmp(n->extra, "ended", 5)    ? STORE_ENDED
                                  : !strncmp(n->extra, "cancel", 6) ? STORE_CANCEL
                                                                    : STORE_QUEUED;
            if (p->event)
                p->event(ev, id, p->event_arg);
            PQfreemem(n);
        }
    }
    PQfinish(c);
    return NULL;
}

static void stop_listening(struct pg_store *p)
{
    if (!p->listening)
        return;
    pthread_mutex_lock(&p->lock);
    p->stop = true;
    pthread_mutex_unlock(&p->lock);
    pthread_join(p->listener, NULL);
    p->listening = p->stop = false;
}

/* fn NULL: stops the listener (it has returned when this does). */
static void pg_on_event(struct store *s, void (*fn)(enum store_event, const char *, void *), void *arg)
{
    struct pg_store *p = pg(s);
    stop_listening(p);
    p->event = fn;
    p->event_arg = arg;
    if (fn && pthread_create(&p->listener, NULL, listen_loop, p) == 0)
        p->listening = true;
}

static void pg_close(struct store *s)
{
    struct pg_store *p = pg(s);
    stop_listening(p);
    for (int k = 0; k < POOL_SIZE; k++)
        PQfinish(p->pool[k]);
    pthread_mutex_destroy(&p->lock);
    pthread_cond_destroy(&p->freed);
    free(p->uri);
    free(p);
}

static int pg_uploads_held(struct store *s, void (*fn)(const char *owner, long long bytes, void *), void *arg)
{
    PGresult *res;
    int n = exec1(s, &res,
                  "SELECT j.owner, sum(octet_length(u.data))::bigint FROM uploads u JOIN jobs j ON j.id = u.job"
                  " WHERE j.state IN ('queued','running') GROUP BY j.owner",
                  0, NULL);
    for (int k = 0; k < n; k++)
        fn(PQgetvalue(res, k, 0), get_i64(res, k, 1), arg);
    if (n >= 0)
        PQclear(res);
    return n < 0 ? SF_EIO : 0;
}

/* ---- DICOM series ---- */

static int pg_instance_put(struct store *s, const struct instance_rec *r)
{
    struct pg_store *p = pg(s);
    char received[32], len[24], sum[65], name[48];
    num(received, sizeof received, r->received);
    snprintf(len, sizeof len, "%zu", r->len);
    store_checksum(r->data, r->len, "", 0, sum);
    int c = take(p), rc = SF_EIO;
    PGresult *res = execute(p, c, "BEGIN", 0, NULL, true);
    if (res) {
        PQclear(res);
        /* the series first (its row is the instances' reference), counted only if the instance is new */
        struct param sr[] = {T(r->series_uid), T(r->study_uid), T(r->modality), T(r->source), T(r->owner ? r->owner : ""),
                             T(received)};
        struct param in[] = {T(r->sop_uid), T(r->series_uid), T(received), T(r->meta), T(NULL), T(sum), T(NULL)};
        rc = exec_in(p, c, "INSERT INTO series(uid,study_uid,modality,source,owner,instances,bytes,first,last)"
                     " VALUES($1,$2,$3,$4,$5,0,0,$6,$6) ON CONFLICT (uid) DO NOTHING", 6, sr) < 0 ||
                     value_params(p, c, r->data, r->len, name, &in[4], &in[6])
                 ? SF_EIO
                 : store_one_row(exec_in(p, c, "INSERT INTO instances(sop_uid,series_uid,received,meta,data,sum,data_pieces)"
                                         " VALUES($1,$2,$3,$4,$5,$6,$7) ON CONFLICT DO NOTHING", 7, in),
                                 SF_ECONFLICT);
        struct param up[] = {T(r->series_uid), T(len), T(received)};
        if (rc == 0 && exec_in(p, c, "UPDATE series SET instances=instances+1, bytes=bytes+$2::bigint,"
                               " last=greatest(last,$3::double precision) WHERE uid=$1", 3, up) != 1)
            rc = SF_EIO;
        res = execute(p, c, rc == 0 ? "COMMIT" : "ROLLBACK", 0, NULL, false);
        if (!res)
            rc = SF_EIO;
        PQclear(res);
    }
    give(p, c);
    return rc;
}

static int pg_series_list(struct store *s, const char *uid, const char *owner,
                          void (*fn)(const struct series_rec *, void *), void *arg)
{
    struct param prm[] = {T(uid), T(owner)};
    PGresult *res;
    int n = exec1(s, &res,
                  "SELECT uid, study_uid, modality, source, owner, instances, bytes, first, last, job FROM series"
                  " WHERE ($1::text IS NULL OR uid=$1) AND ($2::text IS NULL OR owner=$2) AND instances > 0"
                  " ORDER BY last DESC, uid", 2, prm);
    for (int k = 0; k < n; k++) {
        struct series_rec r = {0};
        get_text(r.uid, sizeof r.uid, res, k, 0);
        get_text(r.study_uid, sizeof r.study_uid, res, k, 1);
        get_text(r.modality, sizeof r.modality, res, k, 2);
        get_text(r.source, sizeof r.source, res, k, 3);
        get_text(r.owner, sizeof r.owner, res, k, 4);
        r.instances = (long)get_i64(res, k, 5);
        r.bytes = get_i64(res, k, 6);
        r.first = get_f64(res, k, 7);
        r.last = get_f64(res, k, 8);
        get_text(r.job, sizeof r.job, res, k, 9);
        fn(&r, arg);
    }
    if (n >= 0)
        PQclear(res);
    return n < 0 ? SF_EIO : 0;
}

static int pg_series_instances(struct store *s, const char *uid, bool with_data,
                               void (*fn)(const char *, const char *, const void *, size_t, void *), void *arg)
{
    /* the UIDs first, then each instance's bytes alone: a series of 300 slices is never one result */
    struct param prm[] = {T(uid)};
    PGresult *res;
    int n = exec1(s, &res, "SELECT sop_uid, meta FROM instances WHERE series_uid=$1 ORDER BY received, sop_uid", 1, prm);
    int rc = n < 0 ? SF_EIO : 0;
    for (int k = 0; rc == 0 && k < n; k++) {
        if (!with_data) {
            fn(PQgetvalue(res, k, 0), PQgetvalue(res, k, 1), NULL, 0, arg);
            continue;
        }
        struct param one[] = {T(PQgetvalue(res, k, 0))};
        PGresult *d;
        if (exec1(s, &d, "SELECT data, sum, data_pieces FROM instances WHERE sop_uid=$1", 1, one) != 1) {
            rc = SF_EIO; /* (deleted meanwhile, or the database failed) */
            break;
        }
        size_t len = 0;
        unsigned char *data = value_copy(pg(s), d, 0, 0, 2, &len);
        char sum[65];
        if (data)
            store_checksum(data, len, "", 0, sum);
        rc = !data ? SF_EIO : strcmp(sum, PQgetvalue(d, 0, 1)) ? SF_EDAMAGED : 0;
        if (rc == 0)
            fn(PQgetvalue(res, k, 0), PQgetvalue(res, k, 1), data, len, arg);
        free(data);
        PQclear(d);
    }
    if (n >= 0)
        PQclear(res);
    return rc;
}

static int pg_series_mark(struct store *s, const char *uid, const char *job)
{
    struct param prm[] = {T(uid), T(job)};
    int n = exec1(s, NULL, "UPDATE series SET job=$2 WHERE uid=$1 AND job=''", 2, prm);
    if (n == 0 && exec1(s, NULL, "SELECT 1 FROM series WHERE uid=$1", 1, prm) == 0)
        return SF_ENOTFOUND;
    return store_one_row(n, SF_ECONFLICT);
}

static int pg_series_delete(struct store *s, const char *uid, const char *owner)
{
    struct param prm[] = {T(uid), T(owner)};
    return store_one_row(exec1(s, NULL, "DELETE FROM series WHERE uid=$1 AND ($2::text IS NULL OR owner=$2)", 2, prm),
                         SF_ENOTFOUND);
}

static const struct store_ops PG_OPS = {
    "postgresql", pg_close,     pg_submit,    pg_submit_file, pg_request_file, pg_request_file_done, pg_claim,      pg_heartbeat,    pg_finish,
    pg_release,   pg_cancel,    pg_reap,      pg_prune,      pg_get,          pg_list,
    pg_queued,    pg_model_put, pg_model_get, pg_model_list, pg_model_delete, pg_model_edit, pg_volume_get,
    pg_mesh_get,  pg_mesh_put,  pg_mesh_bytes, pg_writable,  pg_on_event,  NULL,         NULL,         pg_uploads_held,
    pg_instance_put, pg_series_list, pg_series_instances, pg_series_delete, pg_series_mark, pg_model_rebase,
    pg_model_refresh,
};

int store_pg_open(const char *uri, const char *scratch, struct store **out, struct sf_err *err)
{
    *out = NULL;
    struct pg_store *p = calloc(1, sizeof *p);
    if (!p || !(p->uri = strdup(uri))) {
        free(p);
        return sf_fail(err, SF_EIO, NULL, "out of memory");
    }
    mkdir(scratch, 0700);
    snprintf(p->scratch, sizeof p->scratch, "%s/scratch", scratch);
    mkdir(p->scratch, 0700);
    p->base.ops = &PG_OPS;
    pthread_mutex_init(&p->lock, NULL);
    pthread_cond_init(&p->freed, NULL);
    for (int k = 0; k < POOL_SIZE; k++)
        p->pool[k] = connect_db(uri);
    if (PQstatus(p->pool[0]) != CONNECTION_OK) {
        const char *why = PQerrorMessage(p->pool[0]);
        size_t n = strlen(why);
        sf_fail(err, SF_EIO, NULL, "PostgreSQL: %.*s", (int)(n && why[n - 1] == '\n' ? n - 1 : n), why);
        pg_close(&p->base);
        return SF_EIO;
    }
    /* one node at a time creates the schema (two starting at once would race on CREATE) */
    PGresult *r = PQexec(p->pool[0], "SELECT pg_advisory_lock(" SCHEMA_LOCK ")");
    PQclear(r);
    r = PQexec(p->pool[0], SCHEMA);
    bool ok = PQresultStatus(r) == PGRES_COMMAND_OK;
    if (ok) {
        PQclear(r);
        r = PQexec(p->pool[0], SCHEMA_SERIES);
        ok = PQresultStatus(r) == PGRES_COMMAND_OK;
    }
    if (!ok)
        sf_fail(err, SF_EIO, NULL, "PostgreSQL: cannot create the schema: %s", PQerrorMessage(p->pool[0]));
    PQclear(r);
    PQclear(PQexec(p->pool[0], "SELECT pg_advisory_unlock(" SCHEMA_LOCK ")"));
    if (!ok) {
        pg_close(&p->base);
        return SF_EIO;
    }
    *out = &p->base;
    return 0;
}
