/* store.h - where jobs, their results and models live, and the one owner of a job's lifecycle.
 * Every accepted request is written here before it is answered, so a crash loses no job.
 *
 * Backends (store_open picks one by its target): the embedded SQLite database under the data
 * directory (store_sqlite.c, the default: one node), or PostgreSQL (store_pg.c, a libpq URI:
 * several nodes share the jobs, each claiming them as it has room).
 *
 * The lifecycle of a job, and the function that makes each transition (nothing else writes a
 * job's state):
 *
 *                      store_submit
 *                           |
 *                           v
 *          +----------->  QUEUED  ---------- store_cancel ------------+
 *          |                |                                         |
 *   store_release           | store_claim: attempts + 1, a lease       |
 *   (drain: the attempt     |   (lease_until) held by one node, and    |
 *   not counted; CANCELLED  |   a new fence token                      |
 *   if its user asked)      |                                          v
 *   store_reap (the lease   v                                     CANCELLED
 *   ran out, or its node    RUNNING --- store_heartbeat: lease renewed, progress,
 *   restarted: counted)  |  |             the cancel request read (cancel on a
 *          +-------------+  |             running job only asks: the node stops it)
 *                           |
 *                           | store_finish (only with the claim's fence token: a node that lost
 *                           |   its lease, or whose job was claimed again, changes nothing)
 *                           v
 *              SUCCEEDED | FAILED | CANCELLED  ---- store_prune (ttl, count) ----> gone
 *
 *   store_reap also ends a job whose attempts reached the maximum as FAILED: the job that keeps
 *   stopping a node (a crash in its run) is not run a third time. Only a job that ran alone when
 *   its node stopped is charged; jobs that ran together get their attempt back and run again one
 *   at a time (suspects, store_claim), so that the next stop names its cause and innocents finish.
 *
 * Thread-safe: every call is one short transaction; none is held across a job's run.
 *
 * Answers are core's convention (core/base/err.h): 0, or a negative SF_E* code: SF_ENOTFOUND (no
 * such row), SF_ECONFLICT (the row is not in the state the call needs: a claim lost, a job ended,
 * an edit's seq taken), SF_EDAMAGED (stored bytes no longer match the checksum taken when they
 * were written: damage below the database, a flipped bit on disk; never the bytes), SF_EIO (the
 * database failed). Counts (store_reap, store_queued, store_mesh_bytes) are >= 0, or SF_EIO. */
#ifndef SURFD_STORE_H
#define SURFD_STORE_H

#include <stdbool.h>
#include <stddef.h>

#include "../core/base/err.h"
#include "job_state.h"

struct store;

struct job_rec {
    char id[40];
    char kind[16];           /* a job kind's name (kinds.h) */
    enum job_state state;
    double progress;         /* 0..1, as last stored (the running node's heartbeat) */
    double created, started, finished; /* Unix seconds; 0: not yet */
    char format[16];         /* request body format: json, bpt, nurbs, dicom */
    char options[512];       /* request options as a query string (output=exr&...) */
    unsigned char *request;  /* the body as received */
    size_t request_len;
    unsigned char *result;   /* NULL unless asked for and present */
    size_t result_len;
    char result_type[48];    /* Content-Type of the result */
    char *meta;              /* JSON object of result headers (render_ms, rays), or NULL */
    char *error;             /* problem JSON, or NULL */
    int attempts;            /* claims of it that were not handed back (store_release) */
    char owner[64];          /* name of the token that submitted it; "" in open mode */
    char result_sum[65];     /* SHA-256 of the result (hex), "" before it has one */
    char node[64];           /* the node that holds (or last held) its claim */
    bool cancel_requested;   /* store_cancel asked a running job to stop */
    bool request_file;       /* the body was streamed to a file (store_submit_file), not in request */
};

/* A claim: the job a node now runs, and the fence token its end must show. */
struct job_claim {
    char id[40];
    char kind[16];
    long fence;
    bool suspect;            /* queued again by a reap: run alone (store_claim) */
};

/* A job's end for store_finish: outcome SUCCEEDED (with result, type, meta), FAILED (error: the
 * problem JSON) or CANCELLED. */
struct job_end {
    enum job_state outcome;
    const unsigned char *result;
    size_t len;
    const char *type, *meta, *error;
    double finished;
};

/* Opens (creating) the store: target is a data directory (SQLite: DIR/surfd.db) or a
 * postgresql:// or postgres:// URI; scratch is the node's own directory (the data directory)
 * for files fetched from a shared store. 0, or SF_EIO with err's message. */
int store_open(const char *target, const char *scratch, struct store **out, struct sf_err *err);
void store_close(struct store *s);
/* A value (a model's mesh, a volume kept for edits, a cached mesh, a job's request or result)
 * longer than a piece is kept as several rows of one piece each: SQLite holds at most 1e9 bytes
 * in one value and PostgreSQL 1 GB. STORE_PIECE by default; store-piece sets it (tests make it
 * small). */
#define STORE_PIECE (256u << 20)
void store_set_piece(struct store *s, size_t bytes);
/* "sqlite" or "postgresql". */
const char *store_backend(const struct store *s);

/* ---- the lifecycle (see the diagram above) ---- */

/* A new job, QUEUED (r->state is ignored). 0, or SF_EIO. */
int store_submit(struct store *s, const struct job_rec *r);
/* The same for a job whose body was streamed to the file at path as it arrived (a volume of
 * hundreds of megabytes, never held in memory): the store takes the file (SQLite: moves it into
 * DIR/uploads; PostgreSQL: copies it into the database a chunk at a time and removes it);
 * r->request is ignored. 0, or SF_EIO (the file is removed either way). */
int store_submit_file(struct store *s, const struct job_rec *r, const char *path);
/* A local path of job id's streamed body (PostgreSQL: fetched a chunk at a time into the scratch
 * directory; give it back with store_request_file_done). 0, SF_ENOTFOUND (none), SF_EIO. */
int store_request_file(struct store *s, const char *id, char *path, size_t cap);
void store_request_file_done(struct store *s, const char *path);
/* Claims the oldest queued job for node, its lease lasting lease_s: 0 (and *out), SF_ENOTFOUND
 * when none is queued or the oldest is a suspect (out->suspect: a reap queued it again) and the
 * node is not alone (runs other jobs), SF_EIO. A node runs a suspect alone: it claims nothing else
 * meanwhile. */
int store_claim(struct store *s, const char *node, double lease_s, bool alone, struct job_claim *out);
/* Renews a running job's lease and stores its progress: 0 still held (*cancel: a cancel was
 * asked), SF_ECONFLICT the claim is lost (the lease ran out and the job was reaped, or it ended),
 * SF_EIO. */
int store_heartbeat(struct store *s, const char *id, long fence, double lease_s, double progress, bool *cancel);
/* Records a running job's end: 0, SF_ECONFLICT when the claim is no longer held (nothing
 * written), SF_EIO. */
int store_finish(struct store *s, const char *id, long fence, const struct job_end *end);
/* Hands a running job back unfinished (a draining node): QUEUED, the attempt not counted, or
 * CANCELLED when its user asked it to stop. 0, SF_ECONFLICT (the claim is not held), SF_EIO. */
int store_release(struct store *s, const char *id, long fence);
/* A queued job is cancelled at once (0, *asked false); a running one is asked to stop (0, *asked
 * true: its node's heartbeat sees it); an ended one stays as it is (SF_ECONFLICT). Jobs of other
 * owners are not found (SF_ENOTFOUND) unless owner is NULL. SF_EIO. */
int store_cancel(struct store *s, const char *id, const char *owner, double now, bool *asked);
/* Running jobs whose lease ran out before now, or (node not NULL) claimed by node (a node that
 * restarted holds nothing): QUEUED again as suspects, FAILED with the problem JSON give_up once the
 * attempts of a job that ran alone reached max_attempts, or CANCELLED when their user asked
 * (store_reaped_state says which). fn (may be NULL) is told each (id, the new state). The number
 * reaped, or SF_EIO. */
int store_reap(struct store *s, double now, const char *node, int max_attempts, const char *give_up,
               void (*fn)(const char *id, enum job_state state, void *arg), void *arg);
/* Removes ended jobs older than ttl seconds and all but the newest max_count ended ones, and the
 * streamed bodies of every ended job (kept only for a run after a crash). 0, or SF_EIO. */
int store_prune(struct store *s, double now, long ttl, long max_count);

/* ---- reading ---- */

/* Reads one record (with the request and, if with_result, the result): 0, SF_ENOTFOUND, SF_EIO,
 * SF_EDAMAGED (the result is damaged). *out is zeroed first, so store_rec_free() is safe whatever
 * the answer. */
int store_get(struct store *s, const char *id, bool with_request, bool with_result, struct job_rec *out);
void store_rec_free(struct job_rec *r);
/* Calls fn for each record (no blobs), newest first; state NULL for all, owner NULL for every
 * owner's, limit <= 0 for no limit. 0, SF_EIO, SF_EDAMAGED. */
int store_list(struct store *s, const enum job_state *state, const char *owner, long limit,
               void (*fn)(const struct job_rec *, void *), void *arg);
/* Jobs queued (all nodes'), or SF_EIO. */
long store_queued(struct store *s);

/* ---- models: made by model jobs, kept until deleted (job pruning leaves them) ---- */

/* A part of a model's volume, kept for edits (POST /models/{id}/edit): seq 0 the volume as it was
 * posted (its format, options and body), then each edit in order (seq 1, 2 ...: options the
 * edit's region, data its samples). */
struct volume_rec {
    int seq;
    const char *format, *options;
    const void *data;
    size_t len;
};

/* source is the contour JSON a model is rebuilt from (an isosurface's mesh, packed), resource the
 * JSON of GET /models/{id}, volume (NULL: none) the volume an isosurface came from (seq 0),
 * version the model's version its source is of (0: 1).
 *
 * A mesh model's mesh is kept as a base (its source, of some version) and a journal of changes
 * (api/mesh_journal.h), one a version after it: rows of the volume's table with seq -version and
 * format "mesh-change", so that they go with the model. store_model_get answers the base with the
 * changes after it applied; store_model_rebase writes a newer base (compaction). */
struct model_rec {
    const char *id, *job, *name, *owner;
    double created;
    const char *source;
    size_t source_len;
    const char *resource;
    const struct volume_rec *volume;
    long version;
};
/* Inserts, or replaces a model of the same id (a job run again after a crash), with its volume
 * (and no edits). 0 or SF_EIO. */
int store_model_put(struct store *s, const struct model_rec *m);
/* An edit of model m->id in one transaction: the volume part edit (its seq the next one; NULL:
 * none), the model's new resource, its new source (of version m->version; NULL: the base stays)
 * and the mesh change to m->version (change: its bytes, seq and format set here; NULL: none; with
 * a source, a whole change, mesh_journal.h). 0
 * stored, SF_ECONFLICT when that seq is taken (another edit came first), the model is gone, or
 * (m->source NULL) its row keeps no base version (written before the journal: store a source),
 * SF_EIO. */
int store_model_edit(struct store *s, const struct model_rec *m, const struct volume_rec *edit,
                     const struct volume_rec *change);
/* The mesh changes of model id after version since, in order (as store_volume_get's parts:
 * data the change). 0, SF_EIO, SF_EDAMAGED. */
int store_changes_get(struct store *s, const char *id, long since, struct volume_rec **parts, int *n);
/* The mesh delta of model id since version since (mesh_journal.h), its changes composed up to the
 * last stored (*to); across a whole change with the current mesh, mesh (packed, as store_model_get
 * gives it; then up to its version). 0, SF_ELIMIT (a whole change is among them and mesh is NULL:
 * the work of a job), SF_ENOTFOUND (the journal does not reach back to since), SF_EIO,
 * SF_EDAMAGED, SF_ENOMEM. */
int store_delta(struct store *s, const char *id, long since, const char *mesh, size_t mesh_len, char **out,
                size_t *len, long *to);
/* A newer base of model m->id: its source of version m->version, when the stored one is older;
 * the changes up to version drop_through (at most m->version) dropped. 0 or SF_EIO. */
int store_model_rebase(struct store *s, const struct model_rec *m, long drop_through);
/* Model id's resource, of its version version, written again (its figures measured whole after
 * edits that moved them): 0, or SF_ECONFLICT when the model is gone or has a newer version (a part
 * of its volume from seq version on), SF_EIO. */
int store_model_refresh(struct store *s, const char *id, long version, const char *resource);
/* The parts of model id's volume from seq from on, in order (*parts: caller frees with
 * store_volume_free; their bytes checked against the sums taken when written): 0 (*n of them, 0
 * when none), SF_EIO, SF_EDAMAGED. */
int store_volume_get(struct store *s, const char *id, int from, struct volume_rec **parts, int *n);
void store_volume_free(struct volume_rec *parts, int n);
/* Models of another owner are not found, unless owner is NULL (every owner's). 0 (*resource,
 * *source: caller frees; either pointer may be NULL), SF_ENOTFOUND, SF_EIO, SF_EDAMAGED. */
int store_model_get(struct store *s, const char *id, const char *owner, char **resource, char **source,
                    size_t *source_len);
/* Resources, newest first (limit <= 0: all). 0, SF_EIO, SF_EDAMAGED. */
int store_model_list(struct store *s, const char *owner, long limit, void (*fn)(const char *resource, void *),
                     void *arg);
/* 0 deleted, SF_ENOTFOUND, SF_EIO. */
int store_model_delete(struct store *s, const char *id, const char *owner);

/* ---- DICOM series: instances received (C-STORE) or pulled from a PACS, kept by series ---- */

/* One instance as it is stored: its UIDs, where it came from, its geometry for GET /series (meta,
 * a JSON object: rows, columns, spacing, position...) and its bytes (a DICOM file, identifying
 * elements blanked unless the operator keeps them). */
struct instance_rec {
    const char *sop_uid, *series_uid, *study_uid, *modality, *source, *owner;
    double received;
    const char *meta;
    const void *data;
    size_t len;
};
/* A series as the store counts it: its instances, their bytes, when the first and the last came. */
struct series_rec {
    char uid[65], study_uid[65], modality[17], source[80], owner[64];
    char job[40];            /* the job made of it when it was complete (an RT Structure Set's models), or "" */
    long instances;
    long long bytes;
    double first, last;
};
/* Stores an instance, and counts it in its series (made with the first), in one transaction: 0
 * stored, SF_ECONFLICT when an instance of that SOP Instance UID is stored already (kept as it is:
 * a PACS sends again what it is unsure of), SF_EIO. */
int store_instance_put(struct store *s, const struct instance_rec *r);
/* Series, the latest last (owner NULL: every owner's). 0, SF_EIO. */
int store_series_list(struct store *s, const char *owner, void (*fn)(const struct series_rec *, void *), void *arg);
/* 0 (*out), SF_ENOTFOUND, SF_EIO. */
int store_series_get(struct store *s, const char *uid, const char *owner, struct series_rec *out);
/* Calls fn with each instance of series uid in the order they came: its SOP Instance UID, meta,
 * and (with_data) its bytes, checked against the sum taken when written (else NULL, 0). 0,
 * SF_EIO, SF_EDAMAGED. */
int store_series_instances(struct store *s, const char *uid, bool with_data,
                           void (*fn)(const char *sop_uid, const char *meta, const void *data, size_t len, void *),
                           void *arg);
/* Names job as the one made of series uid, if none is named yet: 0, SF_ECONFLICT (one is: another
 * node or an earlier pass made it), SF_ENOTFOUND, SF_EIO. */
int store_series_mark(struct store *s, const char *uid, const char *job);
/* The series and its instances: 0, SF_ENOTFOUND, SF_EIO. */
int store_series_delete(struct store *s, const char *uid, const char *owner);

/* Meshes of stored models, cached per (model, key) - the key the request's normalised format and
 * tolerance (issue 18: computed once): the file, its type and meta (the job's: filename,
 * tolerance), its SHA-256 (the ETag). Deleting or editing a model drops its meshes; the cache is
 * kept within max_bytes by dropping the least recently used. */
struct mesh_rec {
    char *type, *meta;
    unsigned char *data;
    size_t len;
    char sum[65];
};
/* 0 (*out: free with store_mesh_free; its last use now), SF_ENOTFOUND, SF_EIO, SF_EDAMAGED. */
int store_mesh_get(struct store *s, const char *model, const char *key, struct mesh_rec *out);
/* Stores a mesh (when the model still exists) and drops the least recently used beyond max_bytes:
 * 0 stored, SF_ECONFLICT the model is gone or the mesh alone is over max_bytes, SF_EIO. */
int store_mesh_put(struct store *s, const char *model, const char *key, const struct mesh_rec *m, long max_bytes);
/* Bytes the cached meshes take (for /metrics), or SF_EIO. */
long store_mesh_bytes(struct store *s);
void store_mesh_free(struct mesh_rec *m);

/* What other nodes did, as a shared store tells it (PostgreSQL's LISTEN/NOTIFY): a job was
 * queued (idle workers claim it), ended (its waiters here answer), or asked to stop (the node
 * that runs it cancels it). fn runs on the store's listener thread. The embedded store has one
 * node and tells nothing. */
enum store_event { STORE_QUEUED, STORE_ENDED, STORE_CANCEL };
void store_on_event(struct store *s, void (*fn)(enum store_event ev, const char *id, void *arg), void *arg);

/* A write succeeds and no read has found damage (for /readyz). */
bool store_writable(struct store *s);
/* Whether a read has found damage (bytes that do not match their sums, or the database's own). */
bool store_damaged(struct store *s);
/* Whether a write has met a full disk since store_writable last found room: a job whose result
 * the store would not take then waits and runs again (service_job_end), never fails for good. */
bool store_full(struct store *s);
/* Checks the database's pages and the sums of every job's and model's JSON (deep: of every stored
 * byte too: results, models' sources, volumes), reporting each finding as a line: 0 sound,
 * SF_EDAMAGED (the store is then not ready), SF_EIO (the check could not run). */
int store_check(struct store *s, bool deep, void (*report)(const char *line, void *), void *arg);

/* Mends what store_check finds, keeping every sound job and model: a copy of the store is kept
 * beside it first; a loss from the WAL is accepted; a model whose bytes do not match their sums
 * is removed, and a job whose result does not is failed with problem (JSON). Damaged pages are
 * not mended (a backup is the way). Each step is reported as a line: 0 mended (or sound),
 * SF_EDAMAGED not mendable, SF_EIO (the service holds the store; PostgreSQL's is its own tools'
 * work). */
int store_recover(struct store *s, const char *problem, void (*report)(const char *line, void *), void *arg);

/* Calls fn with each owner's bytes of streamed request bodies (store_submit_file) kept for jobs
 * not yet ended (an ended job's are removed by store_prune): 0, or SF_EIO. */
int store_uploads_held(struct store *s, void (*fn)(const char *owner, long long bytes, void *arg), void *arg);

/* SHA-256 of a then b (either may be empty) as 64 hex digits: what a stored result or model is
 * checked against when read back (the databases check their pages, not a blob's bytes). */
void store_checksum(const void *a, size_t na, const void *b, size_t nb, char out[65]);

#endif
