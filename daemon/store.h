/* store.h - the embedded store: job records and their results in SQLite (WAL) under the data
 * directory. Every accepted request is written here before it is answered, so a crash loses no
 * job: on start, jobs still queued or running are read back and run again.
 * Thread-safe: one connection behind one mutex; every call is one short transaction. */
#ifndef SURFD_STORE_H
#define SURFD_STORE_H

#include <stdbool.h>
#include <stddef.h>

struct store;

/* What a read answers when a stored result or model's bytes no longer match the checksum taken
 * when they were written (damage below SQLite: a flipped bit on disk): never the bytes. */
#define STORE_DAMAGED -2

struct job_rec {
    char id[40];
    char kind[16];           /* render, model, volume, isosurface */
    char state[16];          /* queued, running, succeeded, failed, cancelled */
    double progress;         /* 0..1 */
    double created, started, finished; /* Unix seconds; 0: not yet */
    char format[16];         /* request body format: json, bpt, nurbs */
    char options[512];       /* request options as a query string (output=exr&...) */
    unsigned char *request;  /* the body as received */
    size_t request_len;
    unsigned char *result;   /* NULL unless asked for and present */
    size_t result_len;
    char result_type[48];    /* Content-Type of the result */
    char *meta;              /* JSON object of result headers (render_ms, rays), or NULL */
    char *error;             /* problem JSON, or NULL */
    int attempts;            /* times a worker has started it (store_claim) and not handed it back */
    char owner[64];          /* name of the token that submitted it; "" in open mode */
    char result_sum[65];     /* SHA-256 of the result (hex), "" before it has one */
};

/* Opens (creating) DIR/surfd.db. On failure writes msg and returns -1. */
int store_open(const char *dir, struct store **out, char *msg, size_t msg_len);
void store_close(struct store *s);

int store_insert(struct store *s, const struct job_rec *r);
/* Sets state and progress; started/finished are set when non-zero. error may be NULL. */
int store_set_state(struct store *s, const char *id, const char *state, double progress, double started,
                    double finished, const char *error);
/* A worker starts the job: running, and one more attempt recorded before any of its work is done,
 * so that a job that takes the process down is known as such at the next start. */
int store_claim(struct store *s, const char *id, double started);
/* A running job handed back unfinished by a draining process: queued, the attempt not counted. */
int store_requeue(struct store *s, const char *id);
int store_set_result(struct store *s, const char *id, const unsigned char *data, size_t len, const char *type,
                     const char *meta, double finished);
/* Reads one record (with the request and, if with_result, the result). Returns 1 found, 0 not
 * found, -1 error, STORE_DAMAGED (the result is damaged). *out is zeroed first, so store_rec_free() is safe whatever the answer; caller
 * frees with store_rec_free(). */
int store_get(struct store *s, const char *id, bool with_request, bool with_result, struct job_rec *out);
void store_rec_free(struct job_rec *r);
/* Calls fn for each record (no blobs), newest first; state NULL for all, owner NULL for every
 * owner's, limit <= 0 for no limit. */
int store_list(struct store *s, const char *state, const char *owner, long limit,
               void (*fn)(const struct job_rec *, void *), void *arg);
/* Jobs left queued or running by an earlier process, oldest first (ids into fn). */
int store_unfinished(struct store *s, void (*fn)(const char *id, void *), void *arg);
/* Removes finished jobs older than ttl seconds and all but the newest max_count finished ones. */
int store_prune(struct store *s, double now, long ttl, long max_count);
int store_delete(struct store *s, const char *id);
/* Models: made by model jobs, kept until deleted (job pruning leaves them). source is the contour
 * JSON they are rebuilt from, resource the JSON of GET /models/{id}. */
struct model_rec {
    const char *id, *job, *name, *owner;
    double created;
    const char *source;
    size_t source_len;
    const char *resource;
};
/* Inserts, or replaces a model of the same id (a job run again after a crash). 0 or -1. */
int store_model_put(struct store *s, const struct model_rec *m);
/* Models of another owner are not found, unless owner is NULL (every owner's). */
/* 1 found (*resource, *source: caller frees; either pointer may be NULL), 0 not found, -1 error,
 * STORE_DAMAGED. */
int store_model_get(struct store *s, const char *id, const char *owner, char **resource, char **source,
                    size_t *source_len);
/* Resources, newest first (limit <= 0: all). 0 or -1. */
int store_model_list(struct store *s, const char *owner, long limit, void (*fn)(const char *resource, void *),
                     void *arg);
/* 1 deleted, 0 not found, -1 error. */
int store_model_delete(struct store *s, const char *id, const char *owner);
/* A write succeeds (for /readyz). */
bool store_writable(struct store *s);

#endif
