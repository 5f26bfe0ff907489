/* store_backend.h - the seam between store.h and its backends (store_sqlite.c, store_pg.c):
 * one table of operations, each with the meaning (and the answers, core's SF_E* codes) its store_*
 * function has in store.h. A backend's handle starts with struct store, whose ops point at its
 * table. */
#ifndef SURFD_STORE_BACKEND_H
#define SURFD_STORE_BACKEND_H

#include <stdatomic.h>

#include "store.h"

struct store_ops {
    const char *name;
    void (*close)(struct store *);
    int (*submit)(struct store *, const struct job_rec *);
    int (*submit_file)(struct store *, const struct job_rec *, const char *path);
    int (*request_file)(struct store *, const char *id, char *path, size_t cap);
    void (*request_file_done)(struct store *, const char *path);
    int (*claim)(struct store *, const char *node, double lease_s, bool alone, struct job_claim *);
    int (*heartbeat)(struct store *, const char *id, long fence, double lease_s, double progress, bool *cancel);
    int (*finish)(struct store *, const char *id, long fence, const struct job_end *);
    int (*release)(struct store *, const char *id, long fence);
    int (*cancel)(struct store *, const char *id, const char *owner, double now, bool *asked); /* *asked false on entry */
    int (*reap)(struct store *, double now, const char *node, int max_attempts, const char *give_up,
                void (*fn)(const char *, enum job_state, void *), void *arg);
    int (*prune)(struct store *, double now, long ttl, long max_count);
    int (*get)(struct store *, const char *id, bool with_request, bool with_result, struct job_rec *);
    int (*list)(struct store *, const enum job_state *state, const char *owner, long limit,
                void (*fn)(const struct job_rec *, void *), void *arg);
    long (*queued)(struct store *);
    int (*model_put)(struct store *, const struct model_rec *);
    int (*model_get)(struct store *, const char *id, const char *owner, char **resource, char **source,
                     size_t *source_len);
    int (*model_list)(struct store *, const char *owner, long limit, void (*fn)(const char *, void *), void *arg);
    int (*model_delete)(struct store *, const char *id, const char *owner);
    int (*model_edit)(struct store *, const struct model_rec *, const struct volume_rec *edit,
                      const struct volume_rec *change);
    int (*volume_get)(struct store *, const char *id, int from, int to, struct volume_rec **parts, int *n); /* seqs from .. to-1 */
    int (*mesh_get)(struct store *, const char *model, const char *key, struct mesh_rec *); /* sum as stored */
    int (*mesh_put)(struct store *, const char *model, const char *key, const struct mesh_rec *, long max_bytes);
    long (*mesh_bytes)(struct store *);
    bool (*writable)(struct store *);
    void (*on_event)(struct store *, void (*fn)(enum store_event, const char *, void *), void *arg); /* may be NULL */
    /* store_check: NULL when the backend leaves it to its own tools (PostgreSQL's). */
    int (*check)(struct store *, bool deep, void (*report)(const char *line, void *), void *arg);
    int (*recover)(struct store *, const char *problem, void (*report)(const char *line, void *), void *arg); /* or NULL */
    int (*uploads_held)(struct store *, void (*fn)(const char *owner, long long bytes, void *), void *arg);
    int (*instance_put)(struct store *, const struct instance_rec *); /* sum: store_checksum of the data */
    int (*series_list)(struct store *, const char *uid, const char *owner, void (*fn)(const struct series_rec *, void *),
                       void *arg); /* uid NULL: every series */
    int (*series_instances)(struct store *, const char *uid, bool with_data,
                            void (*fn)(const char *, const char *, const void *, size_t, void *), void *arg);
    int (*series_delete)(struct store *, const char *uid, const char *owner);
    int (*series_mark)(struct store *, const char *uid, const char *job);
    int (*model_rebase)(struct store *, const struct model_rec *, long drop_through);
    int (*model_refresh)(struct store *, const char *id, long version, const char *resource, const char *sum);
};

/* A running job a reap found, with what decides its new state (store_reaped_state). */
struct reaped {
    char id[40];
    long fence;
    int attempts;            /* counting the claim it was running under */
    bool cancelled;          /* its user asked it to stop */
    int beside;              /* other jobs of its node reaped with it: it ran beside them when the node stopped */
};

/* A reaped job's new state: CANCELLED when its user asked it to stop; else a job that ran alone
 * when its node stopped is the cause, its attempt counted (FAILED at max_attempts); one that ran
 * beside others cannot be blamed, so its attempt is given back: QUEUED. Every job QUEUED by a reap
 * is a suspect, claimed only by a node that runs nothing else (store_claim's alone), so that the
 * next stop, if it comes, has one cause. The PostgreSQL backend says the same in SQL. */
enum job_state store_reaped_state(const struct reaped *r, int max_attempts);

/* Seconds a reaped job waits before it is claimed again, after its attempts so far: 1, 2, 4 ...
 * up to a minute, so that a job that takes nodes down does not take them all at once. */
#define STORE_BACKOFF_S(attempts) ((attempts) < 1 ? 0.0 : (attempts) > 6 ? 60.0 : (double)(1 << ((attempts) - 1)))

struct store {
    const struct store_ops *ops;
    atomic_bool damaged;     /* a read found damage (store.c's wrappers): not ready until restarted */
    atomic_bool full;        /* a write met a full disk: not ready until the backend's writable() finds room */
    size_t piece;            /* bytes of a value stored in one piece at most (store_set_piece) */
};

/* One more part for a backend's volume_get (format, options and data copied): 0 or SF_ENOMEM. */
int store_volume_add(struct volume_rec **parts, int *n, int seq, const char *format, const char *options,
                     const void *data, size_t len);

/* A new name for a value's pieces (store.h's STORE_PIECE): "pieces:" and 32 random hex digits. 0, or
 * SF_EIO (no randomness). */
int store_piece_name(char name[48]);

/* The answer of a statement that changes one row, from the n rows it changed (< 0: it failed): 0
 * when it did, none when no row was in the state it needs, SF_EIO when it failed. */
int store_one_row(int n, int none);

/* The backends' openers: 0 and *out, or SF_EIO with err's message (store_open). */
int store_sqlite_open(const char *dir, struct store **out, struct sf_err *err);
int store_pg_open(const char *uri, const char *scratch, struct store **out, struct sf_err *err);

#endif
