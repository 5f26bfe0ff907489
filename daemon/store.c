/* store.c - SQLite behind store.h. WAL journal and synchronous=NORMAL: a committed job survives a
 * process crash (kill -9); a power cut may lose the last transactions, which is what WAL NORMAL
 * trades for speed. Statements are prepared per call: the store is not on any hot path. */
#include "store.h"

#include <gnutls/crypto.h>
#include <pthread.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

struct store {
    sqlite3 *db;
    pthread_mutex_t lock;
};

static const char SCHEMA[] =
    "PRAGMA journal_mode=WAL;"
    "PRAGMA synchronous=NORMAL;"
    "CREATE TABLE IF NOT EXISTS jobs ("
    " id TEXT PRIMARY KEY, kind TEXT NOT NULL, state TEXT NOT NULL, progress REAL NOT NULL DEFAULT 0,"
    " created REAL NOT NULL, started REAL NOT NULL DEFAULT 0, finished REAL NOT NULL DEFAULT 0,"
    " format TEXT NOT NULL, options TEXT NOT NULL, request BLOB NOT NULL,"
    " result BLOB, result_type TEXT, meta TEXT, error TEXT);"
    "CREATE INDEX IF NOT EXISTS jobs_state ON jobs(state, created);"
    "CREATE TABLE IF NOT EXISTS models ("
    " id TEXT PRIMARY KEY, job TEXT NOT NULL, name TEXT NOT NULL, created REAL NOT NULL,"
    " source BLOB NOT NULL, resource TEXT NOT NULL);"
    "CREATE INDEX IF NOT EXISTS models_created ON models(created);"
    "CREATE TABLE IF NOT EXISTS probe (x INTEGER);";

/* Columns added after the first release, for databases made before them: added when missing. */
static const char *const MIGRATIONS[] = {
    "ALTER TABLE jobs ADD COLUMN attempts INTEGER NOT NULL DEFAULT 0",
    "ALTER TABLE jobs ADD COLUMN owner TEXT NOT NULL DEFAULT ''",
    "ALTER TABLE models ADD COLUMN owner TEXT NOT NULL DEFAULT ''",
    "ALTER TABLE jobs ADD COLUMN result_sum TEXT",
    "ALTER TABLE models ADD COLUMN sum TEXT",
};

int store_open(const char *dir, struct store **out, char *msg, size_t msg_len)
{
    *out = NULL;
    /* patient data: the directory and every file SQLite makes in it (db, -wal, -shm) are the
     * service user's alone, whatever the umask and however an earlier version left them */
    mkdir(dir, 0700);
    chmod(dir, 0700);
    char path[1024];
    snprintf(path, sizeof path, "%s/surfd.db", dir);
    struct store *s = calloc(1, sizeof *s);
    if (!s) {
        snprintf(msg, msg_len, "out of memory");
        return -1;
    }
    pthread_mutex_init(&s->lock, NULL);
    char *err = NULL;
    if (sqlite3_open_v2(path, &s->db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, NULL) !=
            SQLITE_OK ||
        sqlite3_busy_timeout(s->db, 5000) != SQLITE_OK || sqlite3_exec(s->db, SCHEMA, NULL, NULL, &err) != SQLITE_OK) {
        snprintf(msg, msg_len, "%s: %s", path, err ? err : sqlite3_errmsg(s->db));
        sqlite3_free(err);
        store_close(s);
        return -1;
    }
    const char *const suffixes[] = {"", "-wal", "-shm"};
    for (size_t k = 0; k < 3; k++) {
        char f[1100];
        snprintf(f, sizeof f, "%s%s", path, suffixes[k]);
        chmod(f, 0600);
    }
    for (size_t k = 0; k < sizeof MIGRATIONS / sizeof *MIGRATIONS; k++)
        if (sqlite3_exec(s->db, MIGRATIONS[k], NULL, NULL, &err) != SQLITE_OK) {
            bool had = err && strstr(err, "duplicate column");
            sqlite3_free(err);
            err = NULL;
            if (!had) {
                snprintf(msg, msg_len, "%s: cannot upgrade the schema: %s", path, sqlite3_errmsg(s->db));
                store_close(s);
                return -1;
            }
        }
    *out = s;
    return 0;
}

void store_close(struct store *s)
{
    if (!s)
        return;
    sqlite3_close(s->db);
    pthread_mutex_destroy(&s->lock);
    free(s);
}

/* Runs one prepared statement to completion; binds are done by the caller through bind(). */
static int run(struct store *s, const char *sql, void (*bind)(sqlite3_stmt *, const void *), const void *arg)
{
    sqlite3_stmt *st;
    pthread_mutex_lock(&s->lock);
    int rc = sqlite3_prepare_v2(s->db, sql, -1, &st, NULL);
    if (rc == SQLITE_OK) {
        if (bind)
            bind(st, arg);
        rc = sqlite3_step(st);
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(&s->lock);
    return rc == SQLITE_DONE || rc == SQLITE_ROW ? 0 : -1;
}

/* SHA-256 of a and then b (either may be empty) as 64 hex digits: what a stored result or model
 * is checked against when read back (SQLite's own checks cover its page structure, not the bytes
 * of a blob). */
static void checksum(const void *a, size_t na, const void *b, size_t nb, char out[65])
{
    unsigned char d[32] = {0};
    gnutls_hash_hd_t h;
    if (gnutls_hash_init(&h, GNUTLS_DIG_SHA256) == 0) {
        gnutls_hash(h, a, na);
        gnutls_hash(h, b, nb);
        gnutls_hash_deinit(h, d);
    }
    for (int k = 0; k < 32; k++)
        snprintf(out + 2 * k, 3, "%02x", d[k]);
}

/* Whether blob bytes match their stored sum (a row written before sums were kept has none). */
static bool sum_ok(sqlite3_stmt *st, int col_sum, const void *a, size_t na, const void *b, size_t nb)
{
    const unsigned char *want = sqlite3_column_text(st, col_sum);
    if (!want)
        return true;
    char got[65];
    checksum(a, na, b, nb, got);
    return !strcmp((const char *)want, got);
}

static void bind_id(sqlite3_stmt *st, const void *arg) { sqlite3_bind_text(st, 1, arg, -1, SQLITE_STATIC); }

/* Binds an owner scope (NULL: every owner's) to parameter k of "(?k IS NULL OR owner=?k)". */
static void bind_owner(sqlite3_stmt *st, int k, const char *owner)
{
    if (owner)
        sqlite3_bind_text(st, k, owner, -1, SQLITE_STATIC);
    else
        sqlite3_bind_null(st, k);
}

static void bind_insert(sqlite3_stmt *st, const void *arg)
{
    const struct job_rec *r = arg;
    sqlite3_bind_text(st, 1, r->id, -1, SQLITE_STATIC);
    sqlite3_bind_text(st, 2, r->kind, -1, SQLITE_STATIC);
    sqlite3_bind_text(st, 3, r->state, -1, SQLITE_STATIC);
    sqlite3_bind_double(st, 4, r->created);
    sqlite3_bind_text(st, 5, r->format, -1, SQLITE_STATIC);
    sqlite3_bind_text(st, 6, r->options, -1, SQLITE_STATIC);
    sqlite3_bind_blob64(st, 7, r->request_len ? (const void *)r->request : "", r->request_len, SQLITE_STATIC);
    sqlite3_bind_text(st, 8, r->owner, -1, SQLITE_STATIC);
}

int store_insert(struct store *s, const struct job_rec *r)
{
    return run(s, "INSERT INTO jobs(id,kind,state,created,format,options,request,owner) VALUES(?,?,?,?,?,?,?,?)", bind_insert, r);
}

struct state_args {
    const char *id, *state, *error;
    double progress, started, finished;
};

static void bind_state(sqlite3_stmt *st, const void *arg)
{
    const struct state_args *a = arg;
    sqlite3_bind_text(st, 1, a->state, -1, SQLITE_STATIC);
    sqlite3_bind_double(st, 2, a->progress);
    sqlite3_bind_double(st, 3, a->started);
    sqlite3_bind_double(st, 4, a->finished);
    if (a->error)
        sqlite3_bind_text(st, 5, a->error, -1, SQLITE_STATIC);
    else
        sqlite3_bind_null(st, 5);
    sqlite3_bind_text(st, 6, a->id, -1, SQLITE_STATIC);
}

int store_set_state(struct store *s, const char *id, const char *state, double progress, double started,
                    double finished, const char *error)
{
    struct state_args a = {id, state, error, progress, started, finished};
    return run(s,
               "UPDATE jobs SET state=?1, progress=?2, started=CASE WHEN ?3>0 THEN ?3 ELSE started END,"
               " finished=CASE WHEN ?4>0 THEN ?4 ELSE finished END, error=COALESCE(?5,error) WHERE id=?6",
               bind_state, &a);
}

struct claim_args {
    const char *id;
    double started;
};

static void bind_claim(sqlite3_stmt *st, const void *arg)
{
    const struct claim_args *a = arg;
    sqlite3_bind_double(st, 1, a->started);
    sqlite3_bind_text(st, 2, a->id, -1, SQLITE_STATIC);
}

int store_claim(struct store *s, const char *id, double started)
{
    struct claim_args a = {id, started};
    return run(s, "UPDATE jobs SET state='running', progress=0, started=?1, attempts=attempts+1 WHERE id=?2",
               bind_claim, &a);
}

int store_requeue(struct store *s, const char *id)
{
    return run(s, "UPDATE jobs SET state='queued', progress=0, attempts=MAX(attempts-1,0) WHERE id=?", bind_id,
               id);
}

struct result_args {
    const char *id, *type, *meta;
    const unsigned char *data;
    size_t len;
    double finished;
    char sum[65];
};

static void bind_result(sqlite3_stmt *st, const void *arg)
{
    const struct result_args *a = arg;
    sqlite3_bind_blob64(st, 1, a->len ? (const void *)a->data : "", a->len, SQLITE_STATIC);
    sqlite3_bind_text(st, 2, a->type, -1, SQLITE_STATIC);
    if (a->meta)
        sqlite3_bind_text(st, 3, a->meta, -1, SQLITE_STATIC);
    else
        sqlite3_bind_null(st, 3);
    sqlite3_bind_double(st, 4, a->finished);
    sqlite3_bind_text(st, 5, a->id, -1, SQLITE_STATIC);
    sqlite3_bind_text(st, 6, a->sum, -1, SQLITE_STATIC);
}

int store_set_result(struct store *s, const char *id, const unsigned char *data, size_t len, const char *type,
                     const char *meta, double finished)
{
    struct result_args a = {id, type, meta, data, len, finished, ""};
    checksum(data, len, "", 0, a.sum);
    return run(s,
               "UPDATE jobs SET result=?1, result_type=?2, meta=?3, state='succeeded', progress=1, finished=?4,"
               " result_sum=?6 WHERE id=?5",
               bind_result, &a);
}

static char *dup_text(sqlite3_stmt *st, int col)
{
    const unsigned char *t = sqlite3_column_text(st, col);
    return t ? strdup((const char *)t) : NULL;
}

static void copy_text(char *dst, size_t cap, sqlite3_stmt *st, int col)
{
    const unsigned char *t = sqlite3_column_text(st, col);
    snprintf(dst, cap, "%s", t ? (const char *)t : "");
}

static unsigned char *dup_blob(sqlite3_stmt *st, int col, size_t *len)
{
    *len = (size_t)sqlite3_column_bytes(st, col);
    const void *b = sqlite3_column_blob(st, col);
    if (!b)
        return NULL;
    unsigned char *p = malloc(*len ? *len : 1);
    if (p)
        memcpy(p, b, *len);
    return p;
}

#define REC_COLUMNS                                                                                         \
    "id,kind,state,progress,created,started,finished,format,options,result_type,meta,error,attempts,owner,"        \
    "result_sum"
#define REC_N_COLUMNS 15

static void read_rec(sqlite3_stmt *st, struct job_rec *r)
{
    memset(r, 0, sizeof *r);
    copy_text(r->id, sizeof r->id, st, 0);
    copy_text(r->kind, sizeof r->kind, st, 1);
    copy_text(r->state, sizeof r->state, st, 2);
    r->progress = sqlite3_column_double(st, 3);
    r->created = sqlite3_column_double(st, 4);
    r->started = sqlite3_column_double(st, 5);
    r->finished = sqlite3_column_double(st, 6);
    copy_text(r->format, sizeof r->format, st, 7);
    copy_text(r->options, sizeof r->options, st, 8);
    copy_text(r->result_type, sizeof r->result_type, st, 9);
    r->meta = dup_text(st, 10);
    r->error = dup_text(st, 11);
    r->attempts = sqlite3_column_int(st, 12);
    copy_text(r->owner, sizeof r->owner, st, 13);
    copy_text(r->result_sum, sizeof r->result_sum, st, 14);
}

int store_get(struct store *s, const char *id, bool with_request, bool with_result, struct job_rec *out)
{
    sqlite3_stmt *st;
    int found = -1;
    memset(out, 0, sizeof *out);
    pthread_mutex_lock(&s->lock);
    if (sqlite3_prepare_v2(s->db, "SELECT " REC_COLUMNS ",request,result FROM jobs WHERE id=?", -1, &st, NULL) ==
        SQLITE_OK) {
        sqlite3_bind_text(st, 1, id, -1, SQLITE_STATIC);
        int rc = sqlite3_step(st);
        found = rc == SQLITE_ROW ? 1 : rc == SQLITE_DONE ? 0 : -1;
        if (found == 1) {
            read_rec(st, out);
            if (with_request)
                out->request = dup_blob(st, REC_N_COLUMNS, &out->request_len);
            if (with_result) {
                out->result = dup_blob(st, REC_N_COLUMNS + 1, &out->result_len);
                if (out->result && !sum_ok(st, 14, out->result, out->result_len, "", 0)) {
                    store_rec_free(out);
                    found = STORE_DAMAGED;
                }
            }
        }
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(&s->lock);
    return found;
}

void store_rec_free(struct job_rec *r)
{
    if (!r)
        return;
    free(r->request);
    free(r->result);
    free(r->meta);
    free(r->error);
    r->request = r->result = NULL;
    r->meta = r->error = NULL;
}

int store_list(struct store *s, const char *state, const char *owner, long limit,
               void (*fn)(const struct job_rec *, void *), void *arg)
{
    sqlite3_stmt *st;
    int rc = -1;
    pthread_mutex_lock(&s->lock);
    if (sqlite3_prepare_v2(s->db,
                           "SELECT " REC_COLUMNS " FROM jobs WHERE (?1 IS NULL OR state=?1) AND (?3 IS NULL OR owner=?3)"
                           " ORDER BY created DESC LIMIT ?2",
                           -1, &st, NULL) == SQLITE_OK) {
        if (state)
            sqlite3_bind_text(st, 1, state, -1, SQLITE_STATIC);
        else
            sqlite3_bind_null(st, 1);
        sqlite3_bind_int64(st, 2, limit > 0 ? limit : -1);
        bind_owner(st, 3, owner);
        while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
            struct job_rec r;
            read_rec(st, &r);
            fn(&r, arg);
            store_rec_free(&r);
        }
        rc = rc == SQLITE_DONE ? 0 : -1;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(&s->lock);
    return rc;
}

int store_unfinished(struct store *s, void (*fn)(const char *id, void *), void *arg)
{
    sqlite3_stmt *st;
    int rc = -1;
    pthread_mutex_lock(&s->lock);
    if (sqlite3_prepare_v2(s->db, "SELECT id FROM jobs WHERE state IN ('queued','running') ORDER BY created", -1, &st,
                           NULL) == SQLITE_OK) {
        /* collect first: fn may call back into the store */
        size_t n = 0, cap = 16;
        char(*ids)[40] = malloc(sizeof *ids * cap);
        while (ids && (rc = sqlite3_step(st)) == SQLITE_ROW) {
            if (n == cap) {
                char(*more)[40] = realloc(ids, sizeof *ids * (cap *= 2));
                if (!more)
                    break;
                ids = more;
            }
            copy_text(ids[n++], sizeof *ids, st, 0);
        }
        sqlite3_finalize(st);
        pthread_mutex_unlock(&s->lock);
        for (size_t k = 0; k < n; k++)
            fn(ids[k], arg);
        free(ids);
        return rc == SQLITE_DONE ? 0 : -1;
    }
    pthread_mutex_unlock(&s->lock);
    return rc;
}

struct prune_args {
    double before;
    long max_count;
};

static void bind_prune(sqlite3_stmt *st, const void *arg)
{
    const struct prune_args *a = arg;
    sqlite3_bind_double(st, 1, a->before);
    sqlite3_bind_int64(st, 2, a->max_count);
}

int store_prune(struct store *s, double now, long ttl, long max_count)
{
    struct prune_args a = {now - (double)ttl, max_count};
    return run(s,
               "DELETE FROM jobs WHERE state IN ('succeeded','failed','cancelled') AND (finished < ?1 OR id NOT IN"
               " (SELECT id FROM jobs WHERE state IN ('succeeded','failed','cancelled') ORDER BY finished DESC LIMIT ?2))",
               bind_prune, &a);
}

int store_delete(struct store *s, const char *id)
{
    return run(s, "DELETE FROM jobs WHERE id=?", bind_id, id);
}

/* ---- models ---- */

static void bind_model(sqlite3_stmt *st, const void *arg)
{
    const struct model_rec *m = arg;
    sqlite3_bind_text(st, 1, m->id, -1, SQLITE_STATIC);
    sqlite3_bind_text(st, 2, m->job, -1, SQLITE_STATIC);
    sqlite3_bind_text(st, 3, m->name ? m->name : "", -1, SQLITE_STATIC);
    sqlite3_bind_double(st, 4, m->created);
    sqlite3_bind_blob64(st, 5, m->source, m->source_len, SQLITE_STATIC);
    sqlite3_bind_text(st, 6, m->resource, -1, SQLITE_STATIC);
    sqlite3_bind_text(st, 7, m->owner ? m->owner : "", -1, SQLITE_STATIC);
    char sum[65];
    checksum(m->source, m->source_len, m->resource, strlen(m->resource), sum);
    sqlite3_bind_text(st, 8, sum, -1, SQLITE_TRANSIENT);
}

int store_model_put(struct store *s, const struct model_rec *m)
{
    return run(s, "INSERT OR REPLACE INTO models(id,job,name,created,source,resource,owner,sum) VALUES(?,?,?,?,?,?,?,?)", bind_model,
               m);
}

int store_model_get(struct store *s, const char *id, const char *owner, char **resource, char **source,
                    size_t *source_len)
{
    sqlite3_stmt *st;
    int found = -1;
    pthread_mutex_lock(&s->lock);
    if (sqlite3_prepare_v2(s->db, "SELECT resource, source, sum FROM models WHERE id=?1 AND (?2 IS NULL OR owner=?2)", -1,
                           &st, NULL) == SQLITE_OK) {
        sqlite3_bind_text(st, 1, id, -1, SQLITE_STATIC);
        bind_owner(st, 2, owner);
        int rc = sqlite3_step(st);
        found = rc == SQLITE_ROW ? 1 : rc == SQLITE_DONE ? 0 : -1;
        if (found == 1 && !sum_ok(st, 2, sqlite3_column_blob(st, 1), (size_t)sqlite3_column_bytes(st, 1),
                                  sqlite3_column_text(st, 0), (size_t)sqlite3_column_bytes(st, 0)))
            found = STORE_DAMAGED;
        if (found == 1) {
            size_t n;
            if (resource)
                *resource = dup_text(st, 0);
            if (source)
                *source = (char *)dup_blob(st, 1, source_len ? source_len : &n);
        }
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(&s->lock);
    return found;
}

int store_model_list(struct store *s, const char *owner, long limit, void (*fn)(const char *resource, void *),
                     void *arg)
{
    sqlite3_stmt *st;
    int rc = -1;
    pthread_mutex_lock(&s->lock);
    if (sqlite3_prepare_v2(s->db,
                           "SELECT resource FROM models WHERE ?2 IS NULL OR owner=?2 ORDER BY created DESC, id LIMIT ?1",
                           -1, &st, NULL) == SQLITE_OK) {
        sqlite3_bind_int64(st, 1, limit > 0 ? limit : -1);
        bind_owner(st, 2, owner);
        while ((rc = sqlite3_step(st)) == SQLITE_ROW)
            fn((const char *)sqlite3_column_text(st, 0), arg);
        rc = rc == SQLITE_DONE ? 0 : -1;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(&s->lock);
    return rc;
}

int store_model_delete(struct store *s, const char *id, const char *owner)
{
    pthread_mutex_lock(&s->lock);
    sqlite3_stmt *st;
    int rc = -1;
    if (sqlite3_prepare_v2(s->db, "DELETE FROM models WHERE id=?1 AND (?2 IS NULL OR owner=?2)", -1, &st, NULL) ==
        SQLITE_OK) {
        sqlite3_bind_text(st, 1, id, -1, SQLITE_STATIC);
        bind_owner(st, 2, owner);
        rc = sqlite3_step(st) == SQLITE_DONE ? sqlite3_changes(s->db) > 0 : -1;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(&s->lock);
    return rc;
}

bool store_writable(struct store *s)
{
    return run(s, "INSERT INTO probe(x) VALUES(1)", NULL, NULL) == 0 && run(s, "DELETE FROM probe", NULL, NULL) == 0;
}
