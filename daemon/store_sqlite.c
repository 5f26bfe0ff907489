/* store_sqlite.c - the embedded store: SQLite (WAL) under the data directory, behind
 * store_backend.h. WAL journal and synchronous=NORMAL: a committed job survives a process crash
 * (kill -9); a power cut may lose the last transactions, which is what WAL NORMAL trades for
 * speed. One connection behind one mutex: one node uses it, and the store is not on any hot path.
 * Leases and fences are kept as PostgreSQL keeps them, so that the lifecycle is the same; with one
 * node a lease runs out only when the process has died (store_reap at the next start). */
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <sqlite3.h>
#include <sys/statvfs.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdatomic.h>
#include <sys/stat.h>
#include <unistd.h>
#include <time.h>

#include "store_backend.h"
#include "store_walmark.h"

/* Names of value files (lock held). */
struct names {
    char (*v)[64];
    size_t n, cap;
};

struct sqlite_store {
    struct store base;
    sqlite3 *db;
    pthread_mutex_t lock;
    char path[1024];         /* DIR/surfd.db */
    char uploads[1024];      /* DIR/uploads: streamed request bodies, one file a job */
    char values[1024];       /* DIR/values: values of VALUE_FILE bytes or more, one file each */
    struct names written, dropped; /* value files since the last commit: written, and whose rows went */
    struct walmark *mark;    /* what the WAL held at the last commit (store_walmark.h); NULL in
                                a process that does not serve the store while another does */
};

static sqlite3 *db_of(struct store *s) { return ((struct sqlite_store *)s)->db; }
static pthread_mutex_t *lock_of(struct store *s) { return &((struct sqlite_store *)s)->lock; }

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
    "CREATE TABLE IF NOT EXISTS model_volumes ("
    " model TEXT NOT NULL, seq INTEGER NOT NULL, format TEXT NOT NULL, options TEXT NOT NULL, data BLOB NOT NULL,"
    " sum TEXT NOT NULL, PRIMARY KEY (model, seq));"
    "CREATE TABLE IF NOT EXISTS meshes ("
    " model TEXT NOT NULL, key TEXT NOT NULL, type TEXT NOT NULL, meta TEXT NOT NULL, data BLOB NOT NULL,"
    " sum TEXT NOT NULL, used REAL NOT NULL, PRIMARY KEY (model, key));"
    "CREATE TABLE IF NOT EXISTS probe (x INTEGER);"
    "CREATE TABLE IF NOT EXISTS series ("
    " uid TEXT PRIMARY KEY, study_uid TEXT NOT NULL, modality TEXT NOT NULL, source TEXT NOT NULL, owner TEXT NOT NULL,"
    " instances INTEGER NOT NULL, bytes INTEGER NOT NULL, first REAL NOT NULL, last REAL NOT NULL,"
    " job TEXT NOT NULL DEFAULT '');"
    "CREATE INDEX IF NOT EXISTS series_last ON series(last);"
    "CREATE TABLE IF NOT EXISTS instances ("
    " sop_uid TEXT PRIMARY KEY, series_uid TEXT NOT NULL, received REAL NOT NULL, meta TEXT NOT NULL,"
    " data BLOB NOT NULL, sum TEXT NOT NULL);"
    "CREATE INDEX IF NOT EXISTS instances_series ON instances(series_uid, received);"
    "CREATE TABLE IF NOT EXISTS pieces (name TEXT NOT NULL, seq INTEGER NOT NULL, data BLOB NOT NULL,"
    " PRIMARY KEY (name, seq));"
    /* a row's pieces go with it, however it goes (REPLACE's deletes fire triggers when recursive) */
    "PRAGMA recursive_triggers=ON;"
    "CREATE TRIGGER IF NOT EXISTS models_pieces AFTER DELETE ON models WHEN typeof(old.source)='text'"
    " BEGIN DELETE FROM pieces WHERE name=old.source; END;"
    "CREATE TRIGGER IF NOT EXISTS models_pieces_update AFTER UPDATE OF source ON models"
    " WHEN typeof(old.source)='text' AND old.source IS NOT new.source BEGIN DELETE FROM pieces WHERE name=old.source; END;"
    "CREATE TRIGGER IF NOT EXISTS volumes_pieces AFTER DELETE ON model_volumes WHEN typeof(old.data)='text'"
    " BEGIN DELETE FROM pieces WHERE name=old.data; END;"
    "CREATE TRIGGER IF NOT EXISTS meshes_pieces AFTER DELETE ON meshes WHEN typeof(old.data)='text'"
    " BEGIN DELETE FROM pieces WHERE name=old.data; END;"
    "CREATE TRIGGER IF NOT EXISTS instances_pieces AFTER DELETE ON instances WHEN typeof(old.data)='text'"
    " BEGIN DELETE FROM pieces WHERE name=old.data; END;"
    "CREATE TRIGGER IF NOT EXISTS jobs_pieces AFTER DELETE ON jobs"
    " WHEN typeof(old.request)='text' OR typeof(old.result)='text'"
    " BEGIN DELETE FROM pieces WHERE name IN (old.request, old.result); END;";

/* Columns added after the first release, for databases made before them: added when missing. */
static const char *const MIGRATIONS[] = {
    "ALTER TABLE jobs ADD COLUMN attempts INTEGER NOT NULL DEFAULT 0",
    "ALTER TABLE jobs ADD COLUMN owner TEXT NOT NULL DEFAULT ''",
    "ALTER TABLE models ADD COLUMN owner TEXT NOT NULL DEFAULT ''",
    "ALTER TABLE jobs ADD COLUMN result_sum TEXT",
    "ALTER TABLE models ADD COLUMN sum TEXT",
    "ALTER TABLE jobs ADD COLUMN node TEXT NOT NULL DEFAULT ''",
    "ALTER TABLE jobs ADD COLUMN fence INTEGER NOT NULL DEFAULT 0",
    "ALTER TABLE jobs ADD COLUMN lease_until REAL NOT NULL DEFAULT 0",
    "ALTER TABLE jobs ADD COLUMN cancel_requested INTEGER NOT NULL DEFAULT 0",
    "ALTER TABLE jobs ADD COLUMN not_before REAL NOT NULL DEFAULT 0",
    "ALTER TABLE jobs ADD COLUMN request_file INTEGER NOT NULL DEFAULT 0",
    "ALTER TABLE models ADD COLUMN resource_sum TEXT",
    "ALTER TABLE jobs ADD COLUMN suspect INTEGER NOT NULL DEFAULT 0",
    /* the version a model's source is of (0: a row from before the journal of mesh changes, whose
     * sum covers its source and resource together; else its source alone) */
    "ALTER TABLE models ADD COLUMN base_version INTEGER NOT NULL DEFAULT 0",
};

/* The value files of rows that go (values kept as files, below): TEMP, so that the schema names no
 * function of surfd's (the sqlite3 shell can still change the file). */
static const char VALUE_TRIGGERS[] =
#define DROPS(table, col)                                                                                           \
    "CREATE TEMP TRIGGER IF NOT EXISTS " #table "_" #col "_file AFTER DELETE ON main." #table                      \
    " WHEN typeof(old." #col ")='text' BEGIN SELECT surfd_drop(old." #col "); END;"                                  \
    "CREATE TEMP TRIGGER IF NOT EXISTS " #table "_" #col "_file_update AFTER UPDATE OF " #col " ON main." #table     \
    " WHEN typeof(old." #col ")='text' AND old." #col " IS NOT new." #col " BEGIN SELECT surfd_drop(old." #col "); END;"
    DROPS(models, source) DROPS(model_volumes, data) DROPS(meshes, data) DROPS(instances, data) DROPS(jobs, request)
    DROPS(jobs, result);
#undef DROPS

static const struct store_ops SQLITE_OPS;
static void sq_close(struct store *base);
static void sweep_pieces(struct store *s);
static void sweep_uploads(struct store *s, bool all);
static void sweep_values(struct sqlite_store *s);
static void drop_fn(sqlite3_context *ctx, int argc, sqlite3_value **argv);

int store_sqlite_open(const char *dir, struct store **out, struct sf_err *err)
{
    *out = NULL;
    /* patient data: the directory and every file SQLite makes in it (db, -wal, -shm) are the
     * service user's alone, whatever the umask and however an earlier version left them */
    mkdir(dir, 0700);
    chmod(dir, 0700);
    char path[1024];
    snprintf(path, sizeof path, "%s/surfd.db", dir);
    struct sqlite_store *s = calloc(1, sizeof *s);
    if (!s)
        return sf_fail(err, SF_EIO, NULL, "out of memory");
    s->base.ops = &SQLITE_OPS;
    snprintf(s->path, sizeof s->path, "%s", path);
    snprintf(s->uploads, sizeof s->uploads, "%s/uploads", dir);
    mkdir(s->uploads, 0700);
    snprintf(s->values, sizeof s->values, "%s/values", dir);
    mkdir(s->values, 0700);
    chmod(s->values, 0700);
    pthread_mutex_init(&s->lock, NULL);
    char *why = NULL;
    bool opened = sqlite3_open_v2(path, &s->db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX,
                                  NULL) == SQLITE_OK && sqlite3_busy_timeout(s->db, 5000) == SQLITE_OK;
    if (opened)
        s->mark = walmark_open(path, s->db); /* before the schema's first write can restart the WAL */
    if (!opened || sqlite3_exec(s->db, SCHEMA, NULL, NULL, &why) != SQLITE_OK) {
        sf_fail(err, SF_EIO, NULL, "%s: %s", path, why ? why : sqlite3_errmsg(s->db));
        sqlite3_free(why);
        sq_close(&s->base);
        return SF_EIO;
    }
    const char *const suffixes[] = {"", "-wal", "-shm", "-mark"};
    for (size_t k = 0; k < 4; k++) {
        char f[1100];
        snprintf(f, sizeof f, "%s%s", path, suffixes[k]);
        chmod(f, 0600);
    }
    for (size_t k = 0; k < sizeof MIGRATIONS / sizeof *MIGRATIONS; k++)
        if (sqlite3_exec(s->db, MIGRATIONS[k], NULL, NULL, &why) != SQLITE_OK) {
            bool had = why && strstr(why, "duplicate column");
            sqlite3_free(why);
            why = NULL;
            if (!had) {
                sf_fail(err, SF_EIO, NULL, "%s: cannot upgrade the schema: %s", path, sqlite3_errmsg(s->db));
                sq_close(&s->base);
                return SF_EIO;
            }
        }
    if (sqlite3_create_function(s->db, "surfd_drop", 1, SQLITE_UTF8, s, drop_fn, NULL, NULL) != SQLITE_OK ||
        sqlite3_exec(s->db, VALUE_TRIGGERS, NULL, NULL, &why) != SQLITE_OK) {
        sf_fail(err, SF_EIO, NULL, "%s: %s", path, why ? why : sqlite3_errmsg(s->db));
        sqlite3_free(why);
        sq_close(&s->base);
        return SF_EIO;
    }
    sweep_pieces(&s->base); /* written by a statement outside a transaction that a stop cut short */
    sweep_values(s);
    sweep_uploads(&s->base, true);
    *out = &s->base;
    return 0;
}

static void sq_close(struct store *base)
{
    struct sqlite_store *s = (struct sqlite_store *)base;
    walmark_closing(s->mark);
    sqlite3_close(s->db);
    walmark_free(s->mark);
    free(s->written.v);
    free(s->dropped.v);
    pthread_mutex_destroy(&s->lock);
    free(s);
}

static int run_held(struct store *s, const char *sql, const char *types, ...);

/* ---- values longer than a piece --------------------------------------------------------------
 * SQLite holds at most 1e9 bytes in one value (SQLITE_MAX_LENGTH), and a mesh, a volume kept for
 * edits or a result can be longer. A blob longer than the store's piece (store.h) is written as
 * rows of pieces(name, seq, data), and its column holds the pieces' name as TEXT
 * (store_piece_name): every value surfd writes is bound as a blob, so a column's type says which
 * it is. A row's pieces are deleted with it by the schema's triggers; sweep_pieces finds those no
 * row names (a finish whose claim was lost), at start and after such a finish. */

#define PIECES_PREFIX "pieces:"

/* 'P' in run's types: a blob of a row that is updated while the blob stays (a model's mesh, whose
 * resource each edit rewrites) goes to pieces from this length on, since SQLite writes a row
 * whole: kept in the row, a 10 MB mesh would be written again by each edit's resource. */
#define MOVED_OUT (64u << 10)

/* Writes n bytes at p as pieces under a new name (lock held): 0, or SF_EIO. */
static int pieces_put(struct store *s, const unsigned char *p, size_t n, char name[48])
{
    if (store_piece_name(name))
        return SF_EIO;
    for (size_t off = 0, seq = 0; off < n; off += s->piece, seq++) {
        size_t len = n - off < s->piece ? n - off : s->piece;
        if (run_held(s, "INSERT INTO pieces(name,seq,data) VALUES(?,?,?)", "tib", name, (long)seq, p + off, len) != 1)
            return SF_EIO;
    }
    return 0;
}

/* ---- values kept as files ------------------------------------------------------------------
 * A value of VALUE_FILE bytes or more ('B' and 'P' in run's types: a model's mesh, a job's result,
 * a cached mesh, a volume kept for edits) is a file of DIR/values, and its column holds
 * "file:" NAME ":" LENGTH as TEXT. SQLite writes a long blob page by page, each page a system
 * call into its WAL and another at the checkpoint, and deletes one by reading its chain of
 * overflow pages: on the CT head an iso change's 27 MB mesh cost 320 ms to store and its 30 MB
 * delta 200 ms as a job's result, where a file is written and synced in tens of ms. A file is
 * written (and fdatasync'd: a row never names bytes a power cut could lose) before the statement
 * that names it; removed after the commit that drops its row (the TEMP triggers of
 * VALUE_TRIGGERS call surfd_drop, the names kept until then), or after the rollback of the
 * statement that wrote it; one that no row names (a crash between the two) is swept at the next
 * start. The sums cover the bytes as before, so `store check` finds a damaged or missing file. */

/* Every name a column holds in place of its value (a file's or pieces'): what the sweeps keep. */
#define NAMED_VALUES                                                                                                \
    "SELECT source FROM models WHERE typeof(source)='text'"                                                         \
    " UNION ALL SELECT data FROM model_volumes WHERE typeof(data)='text'"                                           \
    " UNION ALL SELECT data FROM meshes WHERE typeof(data)='text'"                                                  \
    " UNION ALL SELECT data FROM instances WHERE typeof(data)='text'"                                               \
    " UNION ALL SELECT result FROM jobs WHERE typeof(result)='text'"                                                \
    " UNION ALL SELECT request FROM jobs WHERE typeof(request)='text'"

#define FILE_PREFIX "file:"
#define VALUE_FILE (1u << 20)
#define FILE_NAME_HEX 32

/* Whether name is one of ours: "file:", FILE_NAME_HEX hex digits, ":", a length (into *len). */
static bool file_name_ok(const char *name, size_t *len)
{
    size_t p = strlen(FILE_PREFIX);
    if (strncmp(name, FILE_PREFIX, p))
        return false;
    for (size_t k = 0; k < FILE_NAME_HEX; k++)
        if (!strchr("0123456789abcdef", name[p + k]) || !name[p + k])
            return false;
    const char *n = name + p + FILE_NAME_HEX;
    char *end;
    unsigned long long v = n[0] == ':' && n[1] >= '0' && n[1] <= '9' ? strtoull(n + 1, &end, 10) : 0;
    if (n[0] != ':' || !(n[1] >= '0' && n[1] <= '9') || *end)
        return false;
    *len = (size_t)v;
    return true;
}

/* The path of value file name (already file_name_ok) into out. */
static void file_path(const struct sqlite_store *s, const char *name, char *out, size_t cap)
{
    snprintf(out, cap, "%s/%.*s", s->values, FILE_NAME_HEX, name + strlen(FILE_PREFIX));
}

static bool names_add(struct names *l, const char *name)
{
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 8;
        char(*v)[64] = realloc(l->v, cap * sizeof *v);
        if (!v)
            return false;
        l->v = v, l->cap = cap;
    }
    snprintf(l->v[l->n++], 64, "%s", name);
    return true;
}

/* The files of list l removed, and l emptied. */
static void names_unlink(const struct sqlite_store *s, struct names *l)
{
    for (size_t k = 0; k < l->n; k++) {
        char path[1100];
        file_path(s, l->v[k], path, sizeof path);
        unlink(path);
    }
    l->n = 0;
}

/* After a commit: the files whose rows went are removed, those written are the rows' now. */
static void committed(struct store *base)
{
    struct sqlite_store *s = (struct sqlite_store *)base;
    names_unlink(s, &s->dropped);
    s->written.n = 0;
}

/* After a rollback: the rows that went are back, the files written for it are removed. */
static void rolled_back(struct store *base)
{
    struct sqlite_store *s = (struct sqlite_store *)base;
    s->dropped.n = 0;
    names_unlink(s, &s->written);
}

/* surfd_drop(name), called by VALUE_TRIGGERS when a row that names a value file goes (lock held). */
static void drop_fn(sqlite3_context *ctx, int argc, sqlite3_value **argv)
{
    struct sqlite_store *s = sqlite3_user_data(ctx);
    const char *name = argc == 1 ? (const char *)sqlite3_value_text(argv[0]) : NULL;
    size_t len;
    if (name && file_name_ok(name, &len) && !names_add(&s->dropped, name))
        sqlite3_result_error_nomem(ctx);
}

/* Writes n bytes at p as a value file (lock held), its name into name: 0, or SF_EIO (a full disk
 * noted as SQLite's is). */
static int file_put(struct store *base, const unsigned char *p, size_t n, char name[64])
{
    struct sqlite_store *s = (struct sqlite_store *)base;
    char piece[48], path[1100];
    if (store_piece_name(piece)) /* ("pieces:" and 32 random hex digits) */
        return SF_EIO;
    snprintf(name, 64, FILE_PREFIX "%s:%zu", piece + strlen("pieces:"), n);
    file_path(s, name, path, sizeof path);
    int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    bool ok = fd >= 0;
    for (size_t at = 0; ok && at < n;) {
        ssize_t w = write(fd, p + at, n - at);
        ok = w > 0;
        at += ok ? (size_t)w : 0;
    }
    ok = ok && fdatasync(fd) == 0;
    if (!ok && errno == ENOSPC)
        atomic_store(&base->full, true);
    if (fd >= 0 && close(fd) && ok)
        ok = false;
    if (ok && names_add(&s->written, name))
        return 0;
    unlink(path);
    return SF_EIO;
}

/* Value file name's bytes, read whole into a buffer of its own: NULL when it cannot be read or is
 * not as long as its name says. */
static void *file_get(struct sqlite_store *s, const char *name, size_t *len)
{
    size_t want;
    char path[1100];
    if (!file_name_ok(name, &want))
        return NULL;
    file_path(s, name, path, sizeof path);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat st;
    unsigned char *b = fd >= 0 && fstat(fd, &st) == 0 && (size_t)st.st_size == want ? malloc(want ? want : 1) : NULL;
    size_t at = 0;
    while (b && at < want) {
        ssize_t r = read(fd, b + at, want - at);
        if (r <= 0)
            break;
        at += (size_t)r;
    }
    if (fd >= 0)
        close(fd);
    if (b && at != want) {
        free(b);
        b = NULL;
    }
    *len = b ? want : 0;
    return b;
}

static int cmp_name(const void *a, const void *b) { return strcmp(a, b); }

/* Removes the value files no row names that are older than a minute (a file is named by its row
 * within the second it is written; one another process is writing now is younger): at start. */
static void sweep_values(struct sqlite_store *s)
{
    struct names named = {0};
    sqlite3_stmt *st;
    bool ok = sqlite3_prepare_v2(s->db, NAMED_VALUES, -1, &st, NULL) == SQLITE_OK;
    int rc = ok ? SQLITE_ROW : SQLITE_ERROR;
    while (rc == SQLITE_ROW && (rc = sqlite3_step(st)) == SQLITE_ROW) {
        const char *name = (const char *)sqlite3_column_text(st, 0);
        size_t len;
        if (name && file_name_ok(name, &len) && !names_add(&named, name + strlen(FILE_PREFIX)))
            rc = SQLITE_NOMEM;
    }
    if (ok)
        sqlite3_finalize(st);
    DIR *d = rc == SQLITE_DONE ? opendir(s->values) : NULL;
    if (d) {
        for (size_t k = 0; k < named.n; k++)
            named.v[k][FILE_NAME_HEX] = 0;
        if (named.n)
            qsort(named.v, named.n, sizeof *named.v, cmp_name);
        struct dirent *e;
        while ((e = readdir(d))) {
            char path[1400];
            struct stat fs;
            if (e->d_name[0] == '.' ||
                (named.n && bsearch(e->d_name, named.v, named.n, sizeof *named.v, cmp_name)))
                continue;
            snprintf(path, sizeof path, "%s/%s", s->values, e->d_name);
            if (stat(path, &fs) == 0 && S_ISREG(fs.st_mode) && fs.st_mtime < time(NULL) - 60)
                unlink(path);
        }
        closedir(d);
    }
    free(named.v);
}

/* Column col of st's row: its blob, borrowed from st, or the file or pieces its TEXT names, read
 * into *owned (the caller frees it). NULL (*len 0) for NULL, or when the file or the pieces cannot
 * be read (none of them left included). The pieces' total comes from a query of its own: length()
 * reads no overflow page, where a window sum over the data made SQLite copy every piece into a
 * temporary table first (720 ms for a 27 MB mesh, against 29 ms). */
static const void *value_of(struct store *s, sqlite3_stmt *st, int col, size_t *len, void **owned)
{
    *owned = NULL;
    *len = 0;
    if (sqlite3_column_type(st, col) != SQLITE_TEXT) {
        *len = (size_t)sqlite3_column_bytes(st, col);
        const void *b = sqlite3_column_blob(st, col);
        return b ? b : *len ? NULL : "";
    }
    const char *name = (const char *)sqlite3_column_text(st, col);
    if (name && !strncmp(name, FILE_PREFIX, strlen(FILE_PREFIX)))
        return *owned = file_get((struct sqlite_store *)s, name, len);
    sqlite3_stmt *q;
    if (!name || strncmp(name, PIECES_PREFIX, strlen(PIECES_PREFIX)) ||
        sqlite3_prepare_v2(db_of(s), "SELECT sum(length(data)) FROM pieces WHERE name=?", -1, &q, NULL) != SQLITE_OK)
        return NULL;
    sqlite3_bind_text(q, 1, name, -1, SQLITE_STATIC);
    int rc = sqlite3_step(q);
    sqlite3_int64 total = rc == SQLITE_ROW && sqlite3_column_type(q, 0) != SQLITE_NULL ? sqlite3_column_int64(q, 0) : -1;
    sqlite3_finalize(q);
    unsigned char *b = total >= 0 ? malloc(total ? (size_t)total : 1) : NULL;
    if (!b || sqlite3_prepare_v2(db_of(s), "SELECT data FROM pieces WHERE name=? ORDER BY seq", -1, &q, NULL) != SQLITE_OK) {
        free(b);
        return NULL;
    }
    sqlite3_bind_text(q, 1, name, -1, SQLITE_STATIC);
    size_t at = 0;
    while ((rc = sqlite3_step(q)) == SQLITE_ROW) {
        size_t n = (size_t)sqlite3_column_bytes(q, 0);
        if (at + n > (size_t)total)
            break;
        memcpy(b + at, sqlite3_column_blob(q, 0), n);
        at += n;
    }
    sqlite3_finalize(q);
    if (rc != SQLITE_DONE || at != (size_t)total) {
        free(b);
        return NULL;
    }
    *len = at;
    return *owned = b;
}

/* Column col as a copy of its own (the caller frees it): NULL for NULL, or without memory. */
static unsigned char *dup_value(struct store *s, sqlite3_stmt *st, int col, size_t *len)
{
    void *owned;
    const void *v = value_of(s, st, col, len, &owned);
    if (!v || owned)
        return owned;
    unsigned char *p = malloc(*len ? *len : 1);
    if (p)
        memcpy(p, v, *len);
    return p;
}

/* Removes the pieces no column names any more (lock held): a scan of every table, for start and
 * the rare finish whose claim was lost, never a hot path (58 ms over 10 000 jobs and 500 models). */
static void sweep_pieces(struct store *s)
{
    run_held(s, "DELETE FROM pieces WHERE name NOT IN (" NAMED_VALUES ")"
                " AND EXISTS (SELECT 1 FROM pieces)", "");
}

/* Prepares sql and binds its parameters from types: 't' text (NULL binds NULL), 'd' double,
 * 'i' long, 'b' blob (pointer, size_t), 'B' a blob that may be longer than a piece (written as
 * pieces then, and its name bound), 'P' the same from MOVED_OUT bytes on. Lock held by the
 * caller. NULL on failure. */
static sqlite3_stmt *prepare(struct store *s, const char *sql, const char *types, va_list ap)
{
    sqlite3_stmt *st;
    if (sqlite3_prepare_v2(db_of(s), sql, -1, &st, NULL) != SQLITE_OK)
        return NULL;
    for (int k = 1; types[k - 1]; k++)
        switch (types[k - 1]) {
        case 't': {
            const char *t = va_arg(ap, const char *);
            t ? sqlite3_bind_text(st, k, t, -1, SQLITE_TRANSIENT) : sqlite3_bind_null(st, k);
            break;
        }
        case 'd': sqlite3_bind_double(st, k, va_arg(ap, double)); break;
        case 'i': sqlite3_bind_int64(st, k, va_arg(ap, long)); break;
        case 'b':
        case 'B':
        case 'P': {
            const void *p = va_arg(ap, const void *);
            size_t n = va_arg(ap, size_t);
            char name[64];
            if (types[k - 1] != 'b' && n >= VALUE_FILE) {
                if (file_put(s, p, n, name)) {
                    sqlite3_finalize(st);
                    return NULL;
                }
                sqlite3_bind_text(st, k, name, -1, SQLITE_TRANSIENT);
            } else if ((types[k - 1] == 'B' && n > s->piece) || (types[k - 1] == 'P' && n > MOVED_OUT)) {
                if (pieces_put(s, p, n, name)) {
                    sqlite3_finalize(st);
                    return NULL;
                }
                sqlite3_bind_text(st, k, name, -1, SQLITE_TRANSIENT);
            } else {
                sqlite3_bind_blob64(st, k, n ? p : "", n, SQLITE_STATIC);
            }
            break;
        }
        }
    return st;
}

static double wall_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (double)ts.tv_sec + ts.tv_nsec / 1e9;
}

static int sq_get(struct store *s, const char *id, bool with_request, bool with_result, struct job_rec *out);

/* Runs one statement to its end: the rows it changed (or, a query, returned), or SF_EIO. */
static int vrun(struct store *s, const char *sql, const char *types, va_list ap)
{
    struct names *written = &((struct sqlite_store *)s)->written;
    size_t before = written->n;
    sqlite3_stmt *st = prepare(s, sql, types, ap);
    int rc = st ? sqlite3_step(st) : SQLITE_ERROR, rows = 0;
    while (rc == SQLITE_ROW)
        rc = sqlite3_step(st), rows++;
    int n = rc != SQLITE_DONE ? SF_EIO : sqlite3_stmt_readonly(st) ? rows : sqlite3_changes(db_of(s));
    if ((rc & 0xff) == SQLITE_FULL) /* the unix VFS's ENOSPC */
        atomic_store(&s->full, true);
    sqlite3_finalize(st);
    if (n <= 0 && written->n > before) { /* value files no row names (a lost claim's result; a model gone) */
        struct names mine = {written->v + before, written->n - before, 0};
        names_unlink((struct sqlite_store *)s, &mine);
        written->n = before;
    }
    if (sqlite3_get_autocommit(db_of(s))) /* the statement's own transaction, or the one it ended, is over */
        n >= 0 && strncmp(sql, "ROLLBACK", 8) ? committed(s) : rolled_back(s);
    return n;
}

static int run(struct store *s, const char *sql, const char *types, ...)
{
    va_list ap;
    va_start(ap, types);
    pthread_mutex_lock(lock_of(s));
    int n = vrun(s, sql, types, ap);
    pthread_mutex_unlock(lock_of(s));
    va_end(ap);
    return n;
}

/* run() inside a transaction whose lock the caller holds. */
static int run_held(struct store *s, const char *sql, const char *types, ...)
{
    va_list ap;
    va_start(ap, types);
    int n = vrun(s, sql, types, ap);
    va_end(ap);
    return n;
}

/* A sqlite3_step()'s answer for a statement of one row: 0 a row, SF_ENOTFOUND none, SF_EIO. */
static int row_of(int step) { return step == SQLITE_ROW ? 0 : step == SQLITE_DONE ? SF_ENOTFOUND : SF_EIO; }

/* Whether blob bytes match their stored sum (a row written before sums were kept has none). */
static bool sum_ok(sqlite3_stmt *st, int col_sum, const void *a, size_t na, const void *b, size_t nb)
{
    const unsigned char *want = sqlite3_column_text(st, col_sum);
    if (!want)
        return true;
    char got[65];
    store_checksum(a, na, b, nb, got);
    return !strcmp((const char *)want, got);
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

static int sq_submit(struct store *s, const struct job_rec *r)
{
    return run(s, "INSERT INTO jobs(id,kind,state,created,format,options,request,owner) VALUES(?,?,'queued',?,?,?,?,?)",
               "ttdttBt", r->id, r->kind, r->created, r->format, r->options, (const void *)r->request,
               r->request_len, r->owner) == 1 ? 0 : SF_EIO;
}

static int sq_submit_file(struct store *s, const struct job_rec *r, const char *path)
{
    char kept[1100];
    snprintf(kept, sizeof kept, "%s/%s", ((struct sqlite_store *)s)->uploads, r->id);
    if (rename(path, kept)) {
        unlink(path);
        return SF_EIO;
    }
    if (run(s, "INSERT INTO jobs(id,kind,state,created,format,options,request,owner,request_file)"
               " VALUES(?,?,'queued',?,?,?,X'',?,1)",
            "ttdttt", r->id, r->kind, r->created, r->format, r->options, r->owner) != 1) {
        unlink(kept);
        return SF_EIO;
    }
    return 0;
}

static int sq_request_file(struct store *s, const char *id, char *path, size_t cap)
{
    struct job_rec r;
    int rc = sq_get(s, id, false, false, &r);
    store_rec_free(&r);
    if (rc == 0 && !r.request_file)
        rc = SF_ENOTFOUND; /* its body is in its row */
    if (rc)
        return rc == SF_ENOTFOUND ? rc : SF_EIO;
    snprintf(path, cap, "%s/%s", ((struct sqlite_store *)s)->uploads, id);
    return 0;
}

static void sq_request_file_done(struct store *s, const char *path)
{
    (void)s, (void)path; /* kept with the job, for a run after a crash, until the job ends */
}

/* Removes the streamed bodies of ended jobs (their runs are over: the disk is the owner's share
 * again, shares.h) and, at start (all), those of jobs no longer stored. A body without a row is
 * left alone otherwise: sq_submit_file moves it in before its row is written. */
static void sweep_uploads(struct store *s, bool all)
{
    DIR *d = opendir(((struct sqlite_store *)s)->uploads);
    if (!d)
        return;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.' || !strncmp(e->d_name, "tmp-", 4))
            continue; /* uploads still arriving belong to the HTTP layer */
        if (all ? run(s, "SELECT 1 FROM jobs WHERE id=? AND state IN ('queued','running')", "t", e->d_name) == 0
                : run(s, "SELECT 1 FROM jobs WHERE id=? AND state NOT IN ('queued','running')", "t", e->d_name) == 1) {
            char path[1400];
            snprintf(path, sizeof path, "%s/%s", ((struct sqlite_store *)s)->uploads, e->d_name);
            unlink(path);
        }
    }
    closedir(d);
}

static int sq_uploads_held(struct store *s, void (*fn)(const char *owner, long long bytes, void *), void *arg)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s), "SELECT id, owner FROM jobs WHERE request_file=1 AND state IN ('queued','running')",
                           -1, &st, NULL) == SQLITE_OK) {
        int step;
        while ((step = sqlite3_step(st)) == SQLITE_ROW) {
            char path[1400];
            struct stat sb;
            const unsigned char *owner = sqlite3_column_text(st, 1);
            snprintf(path, sizeof path, "%s/%s", ((struct sqlite_store *)s)->uploads, sqlite3_column_text(st, 0));
            if (!stat(path, &sb))
                fn(owner ? (const char *)owner : "", (long long)sb.st_size, arg);
        }
        rc = step == SQLITE_DONE ? 0 : SF_EIO;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static int sq_claim(struct store *s, const char *node, double lease_s, bool alone, struct job_claim *out)
{
    pthread_mutex_lock(lock_of(s));
    sqlite3_stmt *st;
    int rc = SF_EIO;
    if (sqlite3_prepare_v2(db_of(s),
                           "UPDATE jobs SET state='running', progress=0, started=?1, attempts=attempts+1,"
                           " fence=fence+1, node=?2, lease_until=?1+?3, cancel_requested=0"
                           " WHERE id=(SELECT id FROM jobs WHERE state='queued' AND not_before<=?1 ORDER BY created, id LIMIT 1)"
                           " AND (suspect=0 OR ?4) RETURNING id, kind, fence, suspect",
                           -1, &st, NULL) == SQLITE_OK) {
        sqlite3_bind_double(st, 1, wall_now());
        sqlite3_bind_text(st, 2, node, -1, SQLITE_STATIC);
        sqlite3_bind_double(st, 3, lease_s);
        sqlite3_bind_int(st, 4, alone);
        rc = row_of(sqlite3_step(st));
        if (rc == 0) {
            copy_text(out->id, sizeof out->id, st, 0);
            copy_text(out->kind, sizeof out->kind, st, 1);
            out->fence = (long)sqlite3_column_int64(st, 2);
            out->suspect = sqlite3_column_int(st, 3) != 0;
            rc = sqlite3_step(st) == SQLITE_DONE ? 0 : SF_EIO;
        }
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static int sq_heartbeat(struct store *s, const char *id, long fence, double lease_s, double progress, bool *cancel)
{
    pthread_mutex_lock(lock_of(s));
    sqlite3_stmt *st;
    int rc = SF_EIO;
    if (sqlite3_prepare_v2(db_of(s),
                           "UPDATE jobs SET lease_until=?1, progress=MAX(progress,?2) WHERE id=?3 AND fence=?4 AND"
                           " state='running' RETURNING cancel_requested",
                           -1, &st, NULL) == SQLITE_OK) {
        sqlite3_bind_double(st, 1, wall_now() + lease_s);
        sqlite3_bind_double(st, 2, progress);
        sqlite3_bind_text(st, 3, id, -1, SQLITE_STATIC);
        sqlite3_bind_int64(st, 4, fence);
        rc = row_of(sqlite3_step(st));
        if (rc == 0) {
            *cancel = sqlite3_column_int(st, 0) != 0;
            rc = sqlite3_step(st) == SQLITE_DONE ? 0 : SF_EIO;
        }
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc == SF_ENOTFOUND ? SF_ECONFLICT : rc; /* no running row under that fence: the claim is lost */
}

static int sq_finish(struct store *s, const char *id, long fence, const struct job_end *e)
{
    if (e->outcome == JOB_SUCCEEDED) {
        char sum[65];
        store_checksum(e->result, e->len, "", 0, sum);
        pthread_mutex_lock(lock_of(s));
        int n = run_held(s,
                         "UPDATE jobs SET state='succeeded', progress=1, finished=?1, result=?2, result_type=?3, meta=?4,"
                         " result_sum=?5, lease_until=0 WHERE id=?6 AND fence=?7 AND state='running'",
                         "dBtttti", e->finished, (const void *)e->result, e->len, e->type, e->meta, sum, id, fence);
        if (n != 1 && e->len > s->piece) /* pieces written for a claim that was lost */
            sweep_pieces(s);
        pthread_mutex_unlock(lock_of(s));
        return store_one_row(n, SF_ECONFLICT);
    }
    return store_one_row(run(s,
                       "UPDATE jobs SET state=?1, finished=?2, error=?3, lease_until=0 WHERE id=?4 AND fence=?5 AND"
                       " state='running'",
                       "tdtti", job_state_name(e->outcome), e->finished, e->error, id, fence),
                   SF_ECONFLICT);
}

static int sq_release(struct store *s, const char *id, long fence)
{
    return store_one_row(run(s,
                       "UPDATE jobs SET state=IIF(cancel_requested, 'cancelled', 'queued'), finished=IIF(cancel_requested,"
                       " ?3, finished), progress=0, attempts=MAX(attempts-1,0), lease_until=0 WHERE id=?1 AND fence=?2"
                       " AND state='running'",
                       "tid", id, fence, wall_now()),
                   SF_ECONFLICT);
}

static int sq_cancel(struct store *s, const char *id, const char *owner, double now, bool *asked)
{
    int n = run(s, "UPDATE jobs SET state='cancelled', finished=?1 WHERE id=?2 AND state='queued' AND (?3 IS NULL OR"
                   " owner=?3)", "dtt", now, id, owner);
    if (n)
        return n > 0 ? 0 : SF_EIO;
    n = run(s, "UPDATE jobs SET cancel_requested=1 WHERE id=?1 AND state='running' AND (?2 IS NULL OR owner=?2)",
            "tt", id, owner);
    if (n > 0)
        *asked = true;
    if (n)
        return n > 0 ? 0 : SF_EIO;
    struct job_rec r;
    int rc = sq_get(s, id, false, false, &r);
    bool mine = rc == 0 && (!owner || !strcmp(owner, r.owner));
    store_rec_free(&r);
    return rc && rc != SF_ENOTFOUND ? SF_EIO : mine ? SF_ECONFLICT : SF_ENOTFOUND;
}

static int sq_reap(struct store *s, double now, const char *node, int max_attempts, const char *give_up,
                   void (*fn)(const char *, enum job_state, void *), void *arg)
{
    /* collect first, then end each with its own guarded update: fn may call back into the store */
    pthread_mutex_lock(lock_of(s));
    sqlite3_stmt *st;
    size_t n = 0, cap = 0;
    struct reaped *c = NULL;
    int rc = SQLITE_ERROR;
    if (sqlite3_prepare_v2(db_of(s),
                           "SELECT id, fence, attempts, cancel_requested, count(*) OVER (PARTITION BY node) FROM jobs"
                           " WHERE state='running' AND (lease_until<?1 OR node=?2) ORDER BY created", -1, &st,
                           NULL) == SQLITE_OK) {
        sqlite3_bind_double(st, 1, now);
        node ? sqlite3_bind_text(st, 2, node, -1, SQLITE_STATIC) : sqlite3_bind_null(st, 2);
        while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
            if (n == cap) {
                void *more = realloc(c, sizeof *c * (cap = cap ? 2 * cap : 16));
                if (!more) {
                    rc = SQLITE_NOMEM;
                    break;
                }
                c = more;
            }
            copy_text(c[n].id, sizeof c[n].id, st, 0);
            c[n].fence = (long)sqlite3_column_int64(st, 1);
            c[n].attempts = sqlite3_column_int(st, 2);
            c[n].cancelled = sqlite3_column_int(st, 3) != 0;
            c[n].beside = sqlite3_column_int(st, 4) - 1;
            n++;
        }
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    int reaped = rc == SQLITE_DONE ? 0 : SF_EIO;
    for (size_t k = 0; k < n; k++) {
        enum job_state to = store_reaped_state(&c[k], max_attempts);
        double t = wall_now();
        int done = to == JOB_QUEUED
                       ? run(s, "UPDATE jobs SET state='queued', progress=0, lease_until=0, not_before=?1,"
                                " attempts=attempts-?2, suspect=1 WHERE id=?3 AND fence=?4 AND state='running'",
                             "diti", t + STORE_BACKOFF_S(c[k].attempts), (long)(c[k].beside > 0), c[k].id, c[k].fence)
                       : run(s, "UPDATE jobs SET state=?1, finished=?2, error=?3, lease_until=0 WHERE id=?4 AND"
                                " fence=?5 AND state='running'",
                             "tdtti", job_state_name(to), t, to == JOB_FAILED ? give_up : NULL, c[k].id, c[k].fence);
        if (done == 1 && reaped >= 0)
            reaped++;
        if (done == 1 && fn)
            fn(c[k].id, to, arg);
    }
    free(c);
    return reaped;
}

static int sq_prune(struct store *s, double now, long ttl, long max_count)
{
    sweep_uploads(s, false); /* before their rows go */
    int rc = run(s,
               "DELETE FROM jobs WHERE state IN ('succeeded','failed','cancelled') AND (finished < ?1 OR id NOT IN"
               " (SELECT id FROM jobs WHERE state IN ('succeeded','failed','cancelled') ORDER BY finished DESC LIMIT ?2))",
               "di", now - (double)ttl, max_count) < 0 ? SF_EIO : 0;
    return rc;
}

#define REC_COLUMNS                                                                                         \
    "id,kind,state,progress,created,started,finished,format,options,result_type,meta,error,attempts,owner,"        \
    "result_sum,node,cancel_requested,request_file"
#define REC_N_COLUMNS 18

static void read_rec(sqlite3_stmt *st, struct job_rec *r)
{
    memset(r, 0, sizeof *r);
    copy_text(r->id, sizeof r->id, st, 0);
    copy_text(r->kind, sizeof r->kind, st, 1);
    const unsigned char *state = sqlite3_column_text(st, 2);
    if (!state || !job_state_parse((const char *)state, &r->state))
        r->state = JOB_FAILED;
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
    copy_text(r->node, sizeof r->node, st, 15);
    r->cancel_requested = sqlite3_column_int(st, 16) != 0;
    r->request_file = sqlite3_column_int(st, 17) != 0;
}

static int sq_get(struct store *s, const char *id, bool with_request, bool with_result, struct job_rec *out)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    memset(out, 0, sizeof *out); /* store_rec_free()-safe whatever the answer (sq_cancel, sq_request_file) */
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s), "SELECT " REC_COLUMNS ",request,result FROM jobs WHERE id=?", -1, &st, NULL) ==
        SQLITE_OK) {
        sqlite3_bind_text(st, 1, id, -1, SQLITE_STATIC);
        rc = row_of(sqlite3_step(st));
        if (rc == 0) {
            read_rec(st, out);
            if (with_request)
                out->request = dup_value(s, st, REC_N_COLUMNS, &out->request_len);
            if (with_result) {
                out->result = dup_value(s, st, REC_N_COLUMNS + 1, &out->result_len);
                if (out->result && !sum_ok(st, 14, out->result, out->result_len, "", 0)) {
                    store_rec_free(out);
                    rc = SF_EDAMAGED;
                }
            }
            /* a value that is there but could not be read (no memory, or its pieces gone) */
            if (rc == 0 && ((with_request && !out->request && sqlite3_column_type(st, REC_N_COLUMNS) != SQLITE_NULL) ||
                            (with_result && !out->result && sqlite3_column_type(st, REC_N_COLUMNS + 1) != SQLITE_NULL))) {
                store_rec_free(out);
                rc = SF_EIO;
            }
        }
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static int sq_list(struct store *s, const enum job_state *state, const char *owner, long limit,
                   void (*fn)(const struct job_rec *, void *), void *arg)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s),
                           "SELECT " REC_COLUMNS " FROM jobs WHERE (?1 IS NULL OR state=?1) AND (?3 IS NULL OR owner=?3)"
                           " ORDER BY created DESC LIMIT ?2",
                           -1, &st, NULL) == SQLITE_OK) {
        state ? sqlite3_bind_text(st, 1, job_state_name(*state), -1, SQLITE_STATIC) : sqlite3_bind_null(st, 1);
        sqlite3_bind_int64(st, 2, limit > 0 ? limit : -1);
        owner ? sqlite3_bind_text(st, 3, owner, -1, SQLITE_STATIC) : sqlite3_bind_null(st, 3);
        while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
            struct job_rec r;
            read_rec(st, &r);
            fn(&r, arg);
            store_rec_free(&r);
        }
        rc = rc == SQLITE_DONE ? 0 : rc == SQLITE_CORRUPT ? SF_EDAMAGED : SF_EIO;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static long sq_queued(struct store *s)
{
    sqlite3_stmt *st;
    long n = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s), "SELECT count(*) FROM jobs WHERE state='queued'", -1, &st, NULL) == SQLITE_OK) {
        if (sqlite3_step(st) == SQLITE_ROW)
            n = (long)sqlite3_column_int64(st, 0);
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return n;
}

/* ---- models ---- */

/* Volume part v of model id (lock held): 0, SF_ECONFLICT when its seq is taken, SF_EIO. */
static int volume_put(struct store *s, const char *id, const struct volume_rec *v)
{
    char sum[65];
    store_checksum(v->options, strlen(v->options), v->data, v->len, sum);
    int n = run_held(s, "INSERT OR IGNORE INTO model_volumes(model,seq,format,options,data,sum) VALUES(?,?,?,?,?,?)",
                     "tittBt", id, (long)v->seq, v->format, v->options, v->data, v->len, sum);
    return store_one_row(n, SF_ECONFLICT);
}

/* Runs the steps of a write as one transaction, under the lock: step's answer (0 commits,
 * SF_ECONFLICT rolls back), or SF_EIO. */
static int transaction(struct store *s, int (*step)(struct store *, const void *, const void *), const void *a,
                       const void *b)
{
    pthread_mutex_lock(lock_of(s));
    int rc = run_held(s, "BEGIN IMMEDIATE", "") < 0 ? SF_EIO : step(s, a, b);
    if ((rc == 0 || rc == SF_ECONFLICT) && run_held(s, rc == 0 ? "COMMIT" : "ROLLBACK", "") < 0)
        rc = SF_EIO;
    if (rc && rc != SF_ECONFLICT)
        run_held(s, "ROLLBACK", "");
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static int model_row(struct store *s, const struct model_rec *m, bool update)
{
    char sum[65], rsum[65];
    store_checksum(m->resource, strlen(m->resource), "", 0, rsum);
    if (!m->source) /* the resource alone: the source (the mesh's base) stays, with its own sum */
        return run_held(s, "UPDATE models SET resource=?2, resource_sum=?3 WHERE id=?1 AND base_version>0", "ttt", m->id,
                        m->resource, rsum);
    store_checksum(m->source, m->source_len, "", 0, sum);
    long base = m->version > 0 ? m->version : 1;
    if (update)
        return run_held(s, "UPDATE models SET source=?2, resource=?3, sum=?4, resource_sum=?5, base_version=?6 WHERE id=?1",
                        "tPttti", m->id, (const void *)m->source, m->source_len, m->resource, sum, rsum, base);
    return run_held(s, "INSERT OR REPLACE INTO models(id,job,name,created,source,resource,owner,sum,resource_sum,"
                    "base_version) VALUES(?,?,?,?,?,?,?,?,?,?)",
                    "tttdPtttti", m->id, m->job, m->name ? m->name : "", m->created, (const void *)m->source,
                    m->source_len, m->resource, m->owner ? m->owner : "", sum, rsum, base);
}

static int put_step(struct store *s, const void *a, const void *b)
{
    (void)b;
    const struct model_rec *m = a;
    if (model_row(s, m, false) != 1 || run_held(s, "DELETE FROM model_volumes WHERE model=?", "t", m->id) < 0)
        return SF_EIO;
    return m->volume && volume_put(s, m->id, m->volume) ? SF_EIO : 0;
}

static int sq_model_put(struct store *s, const struct model_rec *m) { return transaction(s, put_step, m, NULL) ? SF_EIO : 0; }

struct edit_parts {
    const struct volume_rec *edit, *change;
};

static int edit_step(struct store *s, const void *a, const void *b)
{
    const struct model_rec *m = a;
    const struct edit_parts *e = b;
    int rc = store_one_row(model_row(s, m, true), SF_ECONFLICT); /* the model is gone (or keeps no base) */
    if (rc == 0 && run_held(s, "DELETE FROM meshes WHERE model=?", "t", m->id) < 0) /* of the model before the edit */
        rc = SF_EIO;
    if (rc == 0 && e->edit)
        rc = volume_put(s, m->id, e->edit);
    return rc == 0 && e->change ? volume_put(s, m->id, e->change) : rc;
}

static int sq_model_edit(struct store *s, const struct model_rec *m, const struct volume_rec *edit,
                         const struct volume_rec *change)
{
    return transaction(s, edit_step, m, &(struct edit_parts){edit, change});
}

static int rebase_step(struct store *s, const void *a, const void *b)
{
    const struct model_rec *m = a;
    long drop = *(const long *)b;
    char sum[65];
    store_checksum(m->source, m->source_len, "", 0, sum);
    int n = run_held(s, "UPDATE models SET source=?2, sum=?3, base_version=?4 WHERE id=?1 AND base_version>0 AND"
                     " base_version<?4", "tPti", m->id, (const void *)m->source, m->source_len, sum, m->version);
    if (n < 0 || run_held(s, "DELETE FROM model_volumes WHERE model=?1 AND seq<0 AND seq>=?2", "ti", m->id, -drop) < 0)
        return SF_EIO;
    return 0;
}

static int sq_model_rebase(struct store *s, const struct model_rec *m, long drop_through)
{
    return transaction(s, rebase_step, m, &drop_through);
}

static int sq_model_refresh(struct store *s, const char *id, long version, const char *resource, const char *sum)
{
    return store_one_row(run(s, "UPDATE models SET resource=?2, resource_sum=?3 WHERE id=?1 AND base_version>0 AND NOT "
                             "EXISTS (SELECT 1 FROM model_volumes WHERE model=?1 AND seq>=?4)", "ttti", id, resource, sum,
                             version), SF_ECONFLICT);
}

static int sq_volume_get(struct store *s, const char *id, int from, int to, struct volume_rec **parts, int *n)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s),
                           "SELECT seq, format, options, data, sum FROM model_volumes WHERE model=?1 AND seq>=?2 AND seq<?3"
                           " ORDER BY seq",
                           -1, &st, NULL) == SQLITE_OK) {
        sqlite3_bind_text(st, 1, id, -1, SQLITE_STATIC);
        sqlite3_bind_int(st, 2, from);
        sqlite3_bind_int(st, 3, to);
        int step = SQLITE_DONE;
        rc = 0;
        while (rc == 0 && (step = sqlite3_step(st)) == SQLITE_ROW) {
            const char *opt = (const char *)sqlite3_column_text(st, 2);
            size_t len;
            void *owned;
            const void *data = value_of(s, st, 3, &len, &owned);
            if (!data)
                rc = SF_EIO;
            else if (!sum_ok(st, 4, opt, strlen(opt), data, len))
                rc = SF_EDAMAGED;
            else if (store_volume_add(parts, n, sqlite3_column_int(st, 0), (const char *)sqlite3_column_text(st, 1), opt,
                                      data, len))
                rc = SF_EIO;
            free(owned);
        }
        if (rc == 0 && step != SQLITE_DONE)
            rc = SF_EIO;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

/* The resource alone, checked against its own sum, without reading the source (a mesh of
 * hundreds of MB): 0, SF_ENOTFOUND, SF_EIO, SF_EDAMAGED. *summed false (0 answered, nothing read):
 * a row written before resource sums were kept, whose resource only the model's sum covers. */
static int sq_resource_get(struct store *s, const char *id, const char *owner, char **resource, bool *summed)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    *summed = true;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s), "SELECT resource, resource_sum FROM models WHERE id=?1 AND (?2 IS NULL OR owner=?2)",
                           -1, &st, NULL) == SQLITE_OK) {
        sqlite3_bind_text(st, 1, id, -1, SQLITE_STATIC);
        owner ? sqlite3_bind_text(st, 2, owner, -1, SQLITE_STATIC) : sqlite3_bind_null(st, 2);
        rc = row_of(sqlite3_step(st));
        if (rc == 0 && sqlite3_column_type(st, 1) == SQLITE_NULL)
            *summed = false;
        else if (rc == 0 && !sum_ok(st, 1, sqlite3_column_text(st, 0), (size_t)sqlite3_column_bytes(st, 0), "", 0))
            rc = SF_EDAMAGED;
        if (rc == 0 && *summed && resource && !(*resource = dup_text(st, 0)))
            rc = SF_EIO;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static int sq_model_get(struct store *s, const char *id, const char *owner, char **resource, char **source,
                        size_t *source_len)
{
    if (!source) {
        bool summed;
        int rc = sq_resource_get(s, id, owner, resource, &summed);
        if (rc || summed)
            return rc;
    }
    sqlite3_stmt *st;
    int rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s), "SELECT resource, source, sum, base_version, resource_sum FROM models WHERE id=?1 AND"
                           " (?2 IS NULL OR owner=?2)",
                           -1, &st, NULL) == SQLITE_OK) {
        sqlite3_bind_text(st, 1, id, -1, SQLITE_STATIC);
        owner ? sqlite3_bind_text(st, 2, owner, -1, SQLITE_STATIC) : sqlite3_bind_null(st, 2);
        rc = row_of(sqlite3_step(st));
        size_t n = 0;
        char *src = rc == 0 ? (char *)dup_value(s, st, 1, &n) : NULL;
        if (rc == 0 && !src)
            rc = SF_EIO;
        else if (rc == 0) { /* (a row of a base version: its source and resource summed apart) */
            const unsigned char *rsc = sqlite3_column_text(st, 0);
            size_t nr = (size_t)sqlite3_column_bytes(st, 0);
            if (sqlite3_column_int64(st, 3) > 0 ? !sum_ok(st, 2, src, n, "", 0) || !sum_ok(st, 4, rsc, nr, "", 0)
                                                : !sum_ok(st, 2, src, n, rsc, nr))
                rc = SF_EDAMAGED;
        }
        if (rc == 0) {
            if (resource)
                *resource = dup_text(st, 0);
            if (source) {
                *source = src, src = NULL;
                if (source_len)
                    *source_len = n;
            }
        }
        free(src);
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static int sq_model_list(struct store *s, const char *owner, long limit, void (*fn)(const char *resource, void *),
                         void *arg)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s),
                           "SELECT resource, resource_sum FROM models WHERE ?2 IS NULL OR owner=?2 ORDER BY created DESC,"
                           " id LIMIT ?1",
                           -1, &st, NULL) == SQLITE_OK) {
        sqlite3_bind_int64(st, 1, limit > 0 ? limit : -1);
        owner ? sqlite3_bind_text(st, 2, owner, -1, SQLITE_STATIC) : sqlite3_bind_null(st, 2);
        bool damaged = false;
        while (!damaged && (rc = sqlite3_step(st)) == SQLITE_ROW) {
            damaged = sqlite3_column_type(st, 1) != SQLITE_NULL &&
                      !sum_ok(st, 1, sqlite3_column_text(st, 0), (size_t)sqlite3_column_bytes(st, 0), "", 0);
            if (!damaged)
                fn((const char *)sqlite3_column_text(st, 0), arg);
        }
        rc = damaged || rc == SQLITE_CORRUPT ? SF_EDAMAGED : rc == SQLITE_DONE ? 0 : SF_EIO;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static int sq_model_delete(struct store *s, const char *id, const char *owner)
{
    int n = run(s, "DELETE FROM models WHERE id=?1 AND (?2 IS NULL OR owner=?2)", "tt", id, owner);
    if (n > 0 && (run(s, "DELETE FROM model_volumes WHERE model=?", "t", id) < 0 ||
                  run(s, "DELETE FROM meshes WHERE model=?", "t", id) < 0))
        return SF_EIO;
    return store_one_row(n, SF_ENOTFOUND);
}

static int sq_mesh_get(struct store *s, const char *model, const char *key, struct mesh_rec *out)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s), "SELECT type, meta, data, sum FROM meshes WHERE model=?1 AND key=?2", -1, &st,
                           NULL) == SQLITE_OK) {
        sqlite3_bind_text(st, 1, model, -1, SQLITE_STATIC);
        sqlite3_bind_text(st, 2, key, -1, SQLITE_STATIC);
        rc = row_of(sqlite3_step(st));
        if (rc == 0) {
            out->type = dup_text(st, 0);
            out->meta = dup_text(st, 1);
            out->data = dup_value(s, st, 2, &out->len);
            copy_text(out->sum, sizeof out->sum, st, 3);
            if (!out->type || !out->meta || !out->data)
                rc = SF_EIO;
        }
        sqlite3_finalize(st);
    }
    if (rc == 0)
        run_held(s, "UPDATE meshes SET used=?3 WHERE model=?1 AND key=?2", "ttd", model, key, wall_now());
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

/* A cached mesh's bytes, in its row, its file (the length its name ends with) or its pieces. */
#define MESH_BYTES                                                                                                  \
    "CASE WHEN typeof(data) != 'text' THEN length(data) WHEN data GLOB 'file:*' THEN CAST(substr(data, 39) AS INTEGER)" \
    " ELSE (SELECT sum(length(p.data)) FROM pieces p WHERE p.name = meshes.data) END"

static int sq_mesh_put(struct store *s, const char *model, const char *key, const struct mesh_rec *m, long max_bytes)
{
    pthread_mutex_lock(lock_of(s));
    int n = run_held(s, "INSERT OR REPLACE INTO meshes(model,key,type,meta,data,sum,used)"
                     " SELECT ?1,?2,?3,?4,?5,?6,?7 WHERE EXISTS (SELECT 1 FROM models WHERE id=?1)",
                     "ttttBtd", model, key, m->type, m->meta ? m->meta : "", (const void *)m->data, m->len, m->sum,
                     wall_now());
    if (n > 0 && run_held(s, "DELETE FROM meshes WHERE rowid IN (SELECT rowid FROM (SELECT rowid, SUM(" MESH_BYTES ")"
                             " OVER (ORDER BY used DESC, rowid) AS run FROM meshes) WHERE run > ?1)", /* the least used */
                          "i", max_bytes) < 0)
        n = SF_EIO;
    pthread_mutex_unlock(lock_of(s));
    return store_one_row(n, SF_ECONFLICT); /* no row: the model is gone */
}

static long sq_mesh_bytes(struct store *s)
{
    sqlite3_stmt *st;
    long n = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s), "SELECT COALESCE(SUM(" MESH_BYTES "), 0) FROM meshes", -1, &st, NULL) == SQLITE_OK) {
        if (sqlite3_step(st) == SQLITE_ROW)
            n = sqlite3_column_int64(st, 0);
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return n;
}

/* One check's query: each row's bytes (columns data..) against its sum (column sum_col, NULL for
 * rows written before sums were kept), a line reported for each that does not match or whose
 * pieces cannot be read and, with keys, its column 0 kept in *keys (the caller frees them). 0
 * sound, SF_EDAMAGED, SF_EIO. */
static int check_sums(struct store *s, const char *what, const char *sql, int sum_col, bool two, int piece_col,
                      void (*report)(const char *, void *), void *arg, char ***keys, size_t *n_keys)
{
    sqlite3_stmt *st;
    int bad = 0, rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s), sql, -1, &st, NULL) == SQLITE_OK) {
        while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
            size_t n[3] = {0};
            void *own[3] = {NULL};
            const void *v[3] = {NULL, "", ""};
            for (int c = 1; c <= (two ? 2 : 1); c++)
                if (c == piece_col)
                    v[c] = value_of(s, st, c, &n[c], &own[c]);
                else if (!(v[c] = sqlite3_column_blob(st, c)) || !(n[c] = (size_t)sqlite3_column_bytes(st, c)))
                    v[c] = "", n[c] = 0;
            const void *v1 = v[1], *v2 = v[2];
            size_t n1 = n[1], n2 = n[2];
            const char *why = !v1 || !v2 ? "its file or pieces could not be read"
                              : sqlite3_column_type(st, sum_col) != SQLITE_NULL && !sum_ok(st, sum_col, v1, n1, v2, n2)
                                  ? "its bytes do not match their sum" : NULL;
            if (why) {
                char line[160];
                snprintf(line, sizeof line, "%s %s: %s", what, (const char *)sqlite3_column_text(st, 0), why);
                report(line, arg);
                bad = SF_EDAMAGED;
                char **more = keys ? realloc(*keys, (*n_keys + 1) * sizeof **keys) : NULL;
                if (more && (more[*n_keys] = strdup((const char *)sqlite3_column_text(st, 0))))
                    *keys = more, ++*n_keys;
                else if (more)
                    *keys = more;
            }
            free(own[1]);
            free(own[2]);
        }
        if (rc == SQLITE_CORRUPT) {
            char line[200];
            snprintf(line, sizeof line, "%s: the database could not be read: %s", what, sqlite3_errmsg(db_of(s)));
            report(line, arg);
        }
        rc = rc == SQLITE_DONE ? bad : rc == SQLITE_CORRUPT ? SF_EDAMAGED : SF_EIO;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

/* The pages (quick_check), each finding reported: 0 sound, SF_EDAMAGED, SF_EIO. */
static int check_pages(struct store *s, void (*report)(const char *, void *), void *arg)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s), "PRAGMA quick_check(20)", -1, &st, NULL) == SQLITE_OK) {
        rc = 0;
        int step;
        while ((step = sqlite3_step(st)) == SQLITE_ROW) {
            const char *line = (const char *)sqlite3_column_text(st, 0);
            if (line && strcmp(line, "ok")) {
                report(line, arg);
                rc = SF_EDAMAGED;
            }
        }
        if (step != SQLITE_DONE) {
            report(sqlite3_errmsg(db_of(s)), arg);
            rc = step == SQLITE_CORRUPT || step == SQLITE_NOTADB ? SF_EDAMAGED : SF_EIO;
        }
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

/* What the sums cover, and how recover mends a row of each (?1 its key, ?2 a failed job's problem). */
static const struct {
    const char *what, *sql;
    int sum_col;
    bool two, deep;
    int piece_col; /* the column that may name pieces */
    const char *mend, *mended;
} CHECKS[] = {
    {"model", "SELECT id, resource, resource_sum FROM models", 2, false, false, 0,
     "DELETE FROM models WHERE id=?1", "removed"},
    {"model", /* (a row of a base version sums its source alone) */
     "SELECT id, source, CASE WHEN base_version > 0 THEN X'' ELSE resource END, sum FROM models", 3, true, true, 1,
     "DELETE FROM models WHERE id=?1", "removed"},
    {"job result", "SELECT id, result, result_sum FROM jobs WHERE result IS NOT NULL", 2, false, true, 1,
     "UPDATE jobs SET state='failed', result=NULL, result_sum=NULL, result_type=NULL, error=?2 WHERE id=?1",
     "failed, its result removed"},
    {"model volume", "SELECT model || '/' || seq, options, data, sum FROM model_volumes", 3, true, true, 2,
     "DELETE FROM models WHERE id=substr(?1, 1, instr(?1, '/') - 1)", "removed with its model"},
};

/* Two findings as one: SF_EIO (a check that could not run) over SF_EDAMAGED over 0 (sound). */
static int worse(int a, int b) { return a == SF_EIO || b == SF_EIO ? SF_EIO : a ? a : b; }

/* check_sums over CHECKS; with a problem, each damaged row is mended as CHECKS says (reported):
 * 0 sound, SF_EDAMAGED (found, and mended with a problem), SF_EIO. */
static int check_all_sums(struct store *s, bool deep, const char *problem, void (*report)(const char *, void *),
                          void *arg)
{
    int rc = 0;
    for (size_t k = 0; rc != SF_EIO && k < sizeof CHECKS / sizeof *CHECKS; k++) {
        if (CHECKS[k].deep && !deep)
            continue;
        char **keys = NULL;
        size_t n = 0;
        int c = check_sums(s, CHECKS[k].what, CHECKS[k].sql, CHECKS[k].sum_col, CHECKS[k].two, CHECKS[k].piece_col,
                           report, arg, problem ? &keys : NULL, &n);
        rc = worse(rc, c);
        for (size_t j = 0; j < n; j++) {
            char line[200];
            bool done = run(s, CHECKS[k].mend, "tt", keys[j], problem) >= 0;
            snprintf(line, sizeof line, "%s %s: %s", CHECKS[k].what, keys[j], done ? CHECKS[k].mended : "NOT mended");
            report(line, arg);
            rc = done ? rc : SF_EIO;
            free(keys[j]);
        }
        free(keys);
    }
    if (problem && rc != SF_EIO && /* what a removed model leaves */
        (run(s, "DELETE FROM model_volumes WHERE model NOT IN (SELECT id FROM models)", "") < 0 ||
         run(s, "DELETE FROM meshes WHERE model NOT IN (SELECT id FROM models)", "") < 0))
        rc = SF_EIO;
    return rc;
}

static int sq_check(struct store *s, bool deep, void (*report)(const char *, void *), void *arg)
{
    const char *lost = walmark_finding(((struct sqlite_store *)s)->mark); /* commits lost from the WAL */
    if (lost)
        report(lost, arg);
    int rc = check_pages(s, report, arg);
    if (rc != SF_EIO)
        rc = worse(rc, check_all_sums(s, deep, NULL, report, arg));
    return worse(rc, lost ? SF_EDAMAGED : 0);
}

/* store_recover: pages are not mended (SF_EDAMAGED: a backup is the way); else a copy is kept beside
 * the database, a loss from the WAL accepted, and the rows whose bytes do not match mended. */
static int sq_recover(struct store *s, const char *problem, void (*report)(const char *, void *), void *arg)
{
    struct sqlite_store *q = (struct sqlite_store *)s;
    char line[1300];
    if (!q->mark) {
        report("the service holds this store: stop it first", arg);
        return SF_EIO;
    }
    int pages = check_pages(s, report, arg);
    if (pages) {
        if (pages == SF_EDAMAGED)
            report("its pages are damaged, which recover does not mend: restore a backup", arg);
        return pages;
    }
    snprintf(line, sizeof line, "%s.before-recover-%ld", q->path, (long)time(NULL));
    sqlite3 *copy = NULL;
    pthread_mutex_lock(lock_of(s));
    sqlite3_backup *b = sqlite3_open(line, &copy) == SQLITE_OK ? sqlite3_backup_init(copy, "main", q->db, "main") : NULL;
    bool kept = b && sqlite3_backup_step(b, -1) == SQLITE_DONE;
    sqlite3_backup_finish(b);
    pthread_mutex_unlock(lock_of(s));
    sqlite3_close(copy);
    chmod(line, 0600);
    if (!kept) {
        report("a copy of the store could not be kept beside it (is the disk full?): nothing changed", arg);
        return SF_EIO;
    }
    char copied[1400];
    snprintf(copied, sizeof copied, "kept the store as it was in %s", line);
    report(copied, arg);
    const char *lost = walmark_finding(q->mark);
    if (lost) {
        snprintf(line, sizeof line, "accepted: %s", lost);
        report(line, arg);
        walmark_accept(q->mark);
    }
    return check_all_sums(s, true, problem, report, arg) == SF_EIO ? SF_EIO : 0; /* damage found is mended */
}

/* ---- DICOM series ---- */

static int instance_step(struct store *s, const void *a, const void *b)
{
    (void)b;
    const struct instance_rec *r = a;
    char sum[65];
    store_checksum(r->data, r->len, "", 0, sum);
    int n = run_held(s, "INSERT OR IGNORE INTO instances(sop_uid,series_uid,received,meta,data,sum) VALUES(?,?,?,?,?,?)",
                     "ttdtBt", r->sop_uid, r->series_uid, r->received, r->meta, r->data, r->len, sum);
    if (n == 0)
        return SF_ECONFLICT;
    if (n < 0 || run_held(s, "INSERT INTO series(uid,study_uid,modality,source,owner,instances,bytes,first,last)"
                             " VALUES(?1,?2,?3,?4,?5,1,?6,?7,?7) ON CONFLICT(uid) DO UPDATE SET"
                             " instances=instances+1, bytes=bytes+?6, last=max(last,?7)",
                          "tttttid", r->series_uid, r->study_uid, r->modality, r->source, r->owner ? r->owner : "",
                          (long)r->len, r->received) != 1)
        return SF_EIO;
    return 0;
}

static int sq_instance_put(struct store *s, const struct instance_rec *r) { return transaction(s, instance_step, r, NULL); }

static int sq_series_list(struct store *s, const char *uid, const char *owner,
                          void (*fn)(const struct series_rec *, void *), void *arg)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s),
                           "SELECT uid, study_uid, modality, source, owner, instances, bytes, first, last, job FROM series"
                           " WHERE (?1 IS NULL OR uid=?1) AND (?2 IS NULL OR owner=?2) ORDER BY last DESC, uid",
                           -1, &st, NULL) == SQLITE_OK) {
        uid ? sqlite3_bind_text(st, 1, uid, -1, SQLITE_STATIC) : sqlite3_bind_null(st, 1);
        owner ? sqlite3_bind_text(st, 2, owner, -1, SQLITE_STATIC) : sqlite3_bind_null(st, 2);
        while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
            struct series_rec r = {0};
            copy_text(r.uid, sizeof r.uid, st, 0);
            copy_text(r.study_uid, sizeof r.study_uid, st, 1);
            copy_text(r.modality, sizeof r.modality, st, 2);
            copy_text(r.source, sizeof r.source, st, 3);
            copy_text(r.owner, sizeof r.owner, st, 4);
            r.instances = (long)sqlite3_column_int64(st, 5);
            r.bytes = sqlite3_column_int64(st, 6);
            r.first = sqlite3_column_double(st, 7);
            r.last = sqlite3_column_double(st, 8);
            copy_text(r.job, sizeof r.job, st, 9);
            fn(&r, arg);
        }
        rc = rc == SQLITE_DONE ? 0 : SF_EIO;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static int sq_series_instances(struct store *s, const char *uid, bool with_data,
                               void (*fn)(const char *, const char *, const void *, size_t, void *), void *arg)
{
    sqlite3_stmt *st;
    int rc = SF_EIO;
    pthread_mutex_lock(lock_of(s));
    if (sqlite3_prepare_v2(db_of(s),
                           with_data ? "SELECT sop_uid, meta, data, sum FROM instances WHERE series_uid=? ORDER BY received, sop_uid"
                                     : "SELECT sop_uid, meta FROM instances WHERE series_uid=? ORDER BY received, sop_uid",
                           -1, &st, NULL) == SQLITE_OK) {
        sqlite3_bind_text(st, 1, uid, -1, SQLITE_STATIC);
        int step = SQLITE_DONE;
        rc = 0;
        while (rc == 0 && (step = sqlite3_step(st)) == SQLITE_ROW) {
            size_t len = 0;
            void *owned = NULL;
            const void *data = with_data ? value_of(s, st, 2, &len, &owned) : NULL;
            if (with_data && !data)
                rc = SF_EIO;
            else if (with_data && !sum_ok(st, 3, data, len, "", 0))
                rc = SF_EDAMAGED;
            else
                fn((const char *)sqlite3_column_text(st, 0), (const char *)sqlite3_column_text(st, 1), data, len, arg);
            free(owned);
        }
        if (rc == 0 && step != SQLITE_DONE)
            rc = step == SQLITE_CORRUPT ? SF_EDAMAGED : SF_EIO;
        sqlite3_finalize(st);
    }
    pthread_mutex_unlock(lock_of(s));
    return rc;
}

static int series_delete_step(struct store *s, const void *a, const void *b)
{
    const char *uid = a, *owner = b;
    int n = run_held(s, "DELETE FROM series WHERE uid=?1 AND (?2 IS NULL OR owner=?2)", "tt", uid, owner);
    if (n > 0 && run_held(s, "DELETE FROM instances WHERE series_uid=?", "t", uid) < 0)
        return SF_EIO;
    return n < 0 ? SF_EIO : n == 0 ? SF_ECONFLICT : 0;
}

static int sq_series_mark(struct store *s, const char *uid, const char *job)
{
    int n = run(s, "UPDATE series SET job=?2 WHERE uid=?1 AND job=''", "tt", uid, job);
    if (n == 0 && run(s, "SELECT 1 FROM series WHERE uid=?", "t", uid) == 0)
        return SF_ENOTFOUND;
    return store_one_row(n, SF_ECONFLICT);
}

static int sq_series_delete(struct store *s, const char *uid, const char *owner)
{
    int rc = transaction(s, series_delete_step, uid, owner);
    return rc == SF_ECONFLICT ? SF_ENOTFOUND : rc;
}

/* Room the data dir must have again before a store that met a full disk takes work (64 MB, or an
 * eighth of a smaller file system): a probe's row fits in a page the WAL has, so it alone would
 * say ready while every mesh is refused. */
#define ROOM_BYTES (64.0 * (1 << 20))

static bool sq_writable(struct store *s)
{
    struct statvfs fs;
    if (atomic_load(&s->full)) {
        if (statvfs(((struct sqlite_store *)s)->uploads, &fs) ||
            (double)fs.f_bavail * fs.f_frsize < fmin(ROOM_BYTES, (double)fs.f_blocks * fs.f_frsize / 8))
            return false;
        atomic_store(&s->full, false);
    }
    return run(s, "INSERT INTO probe(x) VALUES(1)", "") == 1 && run(s, "DELETE FROM probe", "") >= 0;
}

static const struct store_ops SQLITE_OPS = {
    "sqlite",     sq_close,      sq_submit,    sq_submit_file, sq_request_file, sq_request_file_done, sq_claim,     sq_heartbeat,    sq_finish,
    sq_release,   sq_cancel,     sq_reap,      sq_prune,     sq_get,          sq_list,
    sq_queued,    sq_model_put,  sq_model_get, sq_model_list, sq_model_delete, sq_model_edit, sq_volume_get,
    sq_mesh_get,  sq_mesh_put,   sq_mesh_bytes, sq_writable,  NULL,         sq_check,     sq_recover,  sq_uploads_held,
    sq_instance_put, sq_series_list, sq_series_instances, sq_series_delete, sq_series_mark, sq_model_rebase,
    sq_model_refresh,
};
