/* store.c - store.h over its backends: picks one by the target's form and forwards each call. */
#include "store.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "store_backend.h"
#include "../api/mesh_io.h"
#include "../api/mesh_journal.h"

int store_open(const char *target, const char *scratch, struct store **out, struct sf_err *err)
{
    int rc = !strncmp(target, "postgresql://", 13) || !strncmp(target, "postgres://", 11)
                 ? store_pg_open(target, scratch, out, err)
                 : store_sqlite_open(target, out, err);
    if (!rc)
        (*out)->piece = STORE_PIECE;
    return rc;
}

void store_set_piece(struct store *s, size_t bytes) { s->piece = bytes; }

void store_close(struct store *s)
{
    if (s)
        s->ops->close(s);
}

const char *store_backend(const struct store *s) { return s->ops->name; }

int store_submit(struct store *s, const struct job_rec *r) { return s->ops->submit(s, r); }

int store_submit_file(struct store *s, const struct job_rec *r, const char *path)
{
    return s->ops->submit_file(s, r, path);
}

int store_request_file(struct store *s, const char *id, char *path, size_t cap)
{
    return s->ops->request_file(s, id, path, cap);
}

void store_request_file_done(struct store *s, const char *path) { s->ops->request_file_done(s, path); }

int store_claim(struct store *s, const char *node, double lease_s, bool alone, struct job_claim *out)
{
    memset(out, 0, sizeof *out);
    return s->ops->claim(s, node, lease_s, alone, out);
}

int store_heartbeat(struct store *s, const char *id, long fence, double lease_s, double progress, bool *cancel)
{
    *cancel = false;
    return s->ops->heartbeat(s, id, fence, lease_s, progress, cancel);
}

int store_finish(struct store *s, const char *id, long fence, const struct job_end *end)
{
    return s->ops->finish(s, id, fence, end);
}

int store_release(struct store *s, const char *id, long fence) { return s->ops->release(s, id, fence); }

int store_cancel(struct store *s, const char *id, const char *owner, double now, bool *asked)
{
    *asked = false;
    return s->ops->cancel(s, id, owner, now, asked);
}

int store_reap(struct store *s, double now, const char *node, int max_attempts, const char *give_up,
               void (*fn)(const char *, enum job_state, void *), void *arg)
{
    return s->ops->reap(s, now, node, max_attempts, give_up, fn, arg);
}

int store_prune(struct store *s, double now, long ttl, long max_count)
{
    return s->ops->prune(s, now, ttl, max_count);
}

/* A read's answer, noted: damage makes the store not ready (store_writable) until the operator
 * has looked (store_check) and restarted. */
static int noted(struct store *s, int rc)
{
    if (rc == SF_EDAMAGED)
        atomic_store(&s->damaged, true);
    return rc;
}

int store_get(struct store *s, const char *id, bool with_request, bool with_result, struct job_rec *out)
{
    memset(out, 0, sizeof *out);
    return noted(s, s->ops->get(s, id, with_request, with_result, out));
}

int store_list(struct store *s, const enum job_state *state, const char *owner, long limit,
               void (*fn)(const struct job_rec *, void *), void *arg)
{
    return noted(s, s->ops->list(s, state, owner, limit, fn, arg));
}

long store_queued(struct store *s) { return s->ops->queued(s); }

int store_model_put(struct store *s, const struct model_rec *m) { return s->ops->model_put(s, m); }

/* A mesh model's source with its changes after the base applied (the store header): *source
 * replaced. 0, or the store's or the journal's error. */
static int with_changes(struct store *s, const char *id, char **source, size_t *len)
{
    uint64_t base = 1;
    if (!mesh_is_packed(*source, *len))
        return 0;
    if (mesh_packed_version(*source, *len, &base))
        return SF_EDAMAGED;
    struct volume_rec *parts;
    int n, rc = store_changes_get(s, id, (long)base, &parts, &n);
    if (rc || n == 0)
        return rc;
    struct mesh_change *ch = malloc((size_t)n * sizeof *ch);
    char *out = NULL;
    size_t out_len = 0;
    struct sf_err err = {0};
    if (!ch)
        rc = SF_EIO;
    for (int k = 0; k < n && ch; k++)
        ch[k] = (struct mesh_change){parts[k].data, parts[k].len};
    if (ch && mesh_changes_apply(*source, *len, ch, (size_t)n, &out, &out_len, &err))
        rc = err.code == SF_ENOMEM ? SF_EIO : SF_EDAMAGED;
    if (!rc) {
        free(*source);
        *source = out, *len = out_len;
    }
    free(ch);
    store_volume_free(parts, n);
    return rc;
}

int store_model_get(struct store *s, const char *id, const char *owner, char **resource, char **source,
                    size_t *source_len)
{
    if (resource)
        *resource = NULL;
    if (source)
        *source = NULL;
    size_t len = 0;
    int rc = noted(s, s->ops->model_get(s, id, owner, resource, source, &len));
    if (!rc && source && (rc = noted(s, with_changes(s, id, source, &len)))) {
        free(*source), *source = NULL;
        if (resource)
            free(*resource), *resource = NULL;
    }
    if (!rc && source_len)
        *source_len = len;
    return rc;
}

int store_model_list(struct store *s, const char *owner, long limit, void (*fn)(const char *, void *), void *arg)
{
    return noted(s, s->ops->model_list(s, owner, limit, fn, arg));
}

int store_model_delete(struct store *s, const char *id, const char *owner)
{
    return s->ops->model_delete(s, id, owner);
}

int store_model_edit(struct store *s, const struct model_rec *m, const struct volume_rec *edit,
                     const struct volume_rec *change)
{
    struct volume_rec c;
    if (change) /* (seq -version: the journal's rows sort before the volume's) */
        c = (struct volume_rec){(int)-m->version, "mesh-change", "", change->data, change->len};
    return s->ops->model_edit(s, m, edit, change ? &c : NULL);
}

int store_changes_get(struct store *s, const char *id, long since, struct volume_rec **parts, int *n)
{
    *parts = NULL;
    *n = 0;
    int rc = noted(s, s->ops->volume_get(s, id, INT_MIN + 1, (int)-since, parts, n));
    if (rc) {
        store_volume_free(*parts, *n);
        *parts = NULL, *n = 0;
        return rc;
    }
    for (int i = 0, j = *n - 1; i < j; i++, j--) { /* seq -version rising: versions falling */
        struct volume_rec t = (*parts)[i];
        (*parts)[i] = (*parts)[j], (*parts)[j] = t;
    }
    return 0;
}

int store_delta(struct store *s, const char *id, long since, const char *mesh, size_t mesh_len, char **out,
                size_t *len, long *to)
{
    struct volume_rec *parts;
    int n, rc = store_changes_get(s, id, since, &parts, &n);
    if (rc)
        return rc;
    uint64_t at = 0;
    for (int k = 0; k < n && !rc; k++)
        if (mesh_change_whole(parts[k].data, parts[k].len))
            rc = !mesh ? SF_ELIMIT : mesh_packed_version(mesh, mesh_len, &at) ? SF_EDAMAGED : 0;
    while (n && !rc && mesh && mesh_change_version(parts[n - 1].data, parts[n - 1].len) > at) {
        n--; /* (stored after the mesh was read) */
        free((void *)parts[n].format), free((void *)parts[n].options), free((void *)parts[n].data);
    }
    struct mesh_change *ch = malloc(((size_t)n + 1) * sizeof *ch);
    for (int k = 0; ch && k < n; k++)
        ch[k] = (struct mesh_change){parts[k].data, parts[k].len};
    struct sf_err err = {0};
    *to = n ? (long)mesh_change_version(parts[n - 1].data, parts[n - 1].len) : since;
    if (!rc && !ch)
        rc = SF_ENOMEM;
    else if (!rc && (*to - since != n || (at && (uint64_t)*to != at)))
        rc = SF_ENOTFOUND;
    else if (!rc && mesh_changes_delta(ch, (size_t)n, (uint32_t)since, (uint32_t)*to, at ? mesh : NULL, mesh_len, out,
                                       len, &err))
        rc = err.code == SF_ENOMEM ? SF_ENOMEM : SF_EDAMAGED;
    free(ch);
    store_volume_free(parts, n);
    return rc;
}

int store_model_refresh(struct store *s, const char *id, long version, const char *resource)
{
    char sum[65];
    store_checksum(resource, strlen(resource), "", 0, sum);
    return s->ops->model_refresh(s, id, version, resource, sum);
}

int store_model_rebase(struct store *s, const struct model_rec *m, long drop_through)
{
    return s->ops->model_rebase(s, m, drop_through < m->version ? drop_through : m->version);
}

int store_mesh_get(struct store *s, const char *model, const char *key, struct mesh_rec *out)
{
    memset(out, 0, sizeof *out);
    int rc = s->ops->mesh_get(s, model, key, out);
    if (rc == 0) {
        char sum[65];
        store_checksum(out->data, out->len, "", 0, sum);
        if (strcmp(sum, out->sum))
            rc = SF_EDAMAGED;
    }
    if (rc)
        store_mesh_free(out);
    return rc;
}

int store_mesh_put(struct store *s, const char *model, const char *key, const struct mesh_rec *m, long max_bytes)
{
    if ((long)m->len > max_bytes)
        return SF_ECONFLICT;
    struct mesh_rec with = *m;
    store_checksum(m->data, m->len, "", 0, with.sum);
    return s->ops->mesh_put(s, model, key, &with, max_bytes);
}

long store_mesh_bytes(struct store *s) { return s->ops->mesh_bytes(s); }

int store_volume_get(struct store *s, const char *id, int from, struct volume_rec **parts, int *n)
{
    *parts = NULL;
    *n = 0;
    int rc = noted(s, s->ops->volume_get(s, id, from, INT_MAX, parts, n));
    if (rc) { /* the parts read before the failure */
        store_volume_free(*parts, *n);
        *parts = NULL;
        *n = 0;
    }
    return rc;
}

bool store_writable(struct store *s) { return !atomic_load(&s->damaged) && s->ops->writable(s); }

bool store_damaged(struct store *s) { return atomic_load(&s->damaged); }

bool store_full(struct store *s) { return atomic_load(&s->full); }

int store_check(struct store *s, bool deep, void (*report)(const char *line, void *), void *arg)
{
    if (!s->ops->check) {
        report("this store is checked by its own tools (PostgreSQL: pg_amcheck)", arg);
        return 0;
    }
    int rc = s->ops->check(s, deep, report, arg);
    if (rc == SF_EDAMAGED)
        atomic_store(&s->damaged, true);
    return rc;
}

int store_recover(struct store *s, const char *problem, void (*report)(const char *line, void *), void *arg)
{
    if (!s->ops->recover) {
        report("this store's own tools mend it (PostgreSQL: pg_amcheck, a backup)", arg);
        return SF_EIO;
    }
    return s->ops->recover(s, problem, report, arg);
}

int store_uploads_held(struct store *s, void (*fn)(const char *owner, long long bytes, void *arg), void *arg)
{
    return s->ops->uploads_held(s, fn, arg);
}

int store_instance_put(struct store *s, const struct instance_rec *r) { return s->ops->instance_put(s, r); }

int store_series_list(struct store *s, const char *owner, void (*fn)(const struct series_rec *, void *), void *arg)
{
    return s->ops->series_list(s, NULL, owner, fn, arg);
}

static void series_one(const struct series_rec *r, void *arg) { *(struct series_rec *)arg = *r; }

int store_series_get(struct store *s, const char *uid, const char *owner, struct series_rec *out)
{
    memset(out, 0, sizeof *out);
    int rc = s->ops->series_list(s, uid, owner, series_one, out);
    return rc ? rc : out->uid[0] ? 0 : SF_ENOTFOUND;
}

int store_series_instances(struct store *s, const char *uid, bool with_data,
                           void (*fn)(const char *, const char *, const void *, size_t, void *), void *arg)
{
    return noted(s, s->ops->series_instances(s, uid, with_data, fn, arg));
}

int store_series_mark(struct store *s, const char *uid, const char *job) { return s->ops->series_mark(s, uid, job); }

int store_series_delete(struct store *s, const char *uid, const char *owner)
{
    return s->ops->series_delete(s, uid, owner);
}

void store_on_event(struct store *s, void (*fn)(enum store_event, const char *, void *), void *arg)
{
    if (s->ops->on_event)
        s->ops->on_event(s, fn, arg);
}
