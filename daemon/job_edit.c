/* job_edit.c - the edit job kind (POST /models/{id}/edit?region=x0,y0,z0,nx,ny,nz, the body the
 * block's raw samples in the model's sample type): the model's stored volume changes and only the
 * cells the new samples reach are drawn again (seed 002's local rebuild, core/iso/adapt.h), so
 * that the mesh equals what a fresh POST /isosurface of the edited volume gives.
 *
 * The store keeps each isosurface model's volume as it was posted (seq 0) and every edit after it
 * (seq 1, 2 ...), so any node can rebuild a model's hierarchy: from the volume and its edits in
 * order, after a restart or on a node that has not seen the model. The hierarchies of the models
 * edited last are kept in memory here (the cell <-> triangle map with them), within edit-memory
 * bytes, the least recently used let go first; an isosurface job leaves its own here when it
 * fits. Before an edit the parts another node stored since are applied (a shared store), and the
 * edit is stored under the next seq in one transaction with the new mesh: if another node took
 * that seq first, the hierarchy is let go and the edit answered 409 (sent again, it is applied
 * after the other). Models of levels 1 without features are kept as marching cubes (core/iso/kept.h:
 * the samples, a min/max index of blocks, each block's triangles), so that their edits too draw
 * only the cells they reach and an iso change draws without a rebuild (the warm-up makes the
 * lists an edit needs after the model's answer: iso_kept_index); a volume too large
 * for edit-memory keeps its samples alone, and every edit of it draws every cell again (whole).
 * Every kept extraction's change goes to the model's journal (store.h) once its triangle ids are
 * found to be the stored mesh's (ids_agree). An FRep model is edited by an object ({op, object, alpha}): its latest tree (the last part) is
 * combined with it and extracted again, every cell (an R-function of alpha < 1 moves every
 * sample); the new request is stored as the next part.
 *
 * An edit is applied once: its part carries its job's id (job=ID among the part's options), and a
 * job run again after a crash that came between its part's store and its end finds its part and
 * answers with the model as it is, so that it does not undo edits answered after it. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>

#include "../api/frep_json.h"
#include "../api/iso_json.h"
#include "../api/mesh_io.h"
#include "../api/mesh_journal.h"
#include "../api/model_json.h"
#include "../core/base/mem.h"
#include "../api/query.h"
#include "log.h"
#include "../api/volume_io.h"
#include "job_edit.h"
#include "kinds.h"

/* ---- the hierarchies kept ---- */

struct live {
    char id[40];
    int next_seq;            /* the volume's parts applied: 0 .. next_seq - 1 */
    struct volume vol;       /* its settings; its samples only when x keeps none */
    struct kept_ext x;       /* the kept extraction: a hierarchy or marching cubes (volumes.h) */
    bool checked;            /* x's triangle ids found to be the stored mesh's (agree) */
    double (*fig)[2];        /* x: each triangle's signed volume and area, by id - fig_base (an edit's
                              * figures move by what it takes out and puts in) */
    size_t figcap;
    uint32_t fig_base;       /* the first id of the hierarchy's mesh (a new iso numbers after the old) */
    size_t bytes;
    double used;
    int users;
    bool dropped;            /* out of the list: freed when its last user lets go */
    pthread_mutex_t lock;    /* one edit of a model at a time */
    struct live *next;
};

static struct {
    pthread_mutex_t lock;
    struct live *head;
    size_t bytes;
} kept = {PTHREAD_MUTEX_INITIALIZER, NULL, 0};

static void live_free(struct live *e)
{
    free(e->fig);
    iso_adapt_free(e->x.a);
    iso_kept_free(e->x.k);
    volume_free(&e->vol);
    pthread_mutex_destroy(&e->lock);
    free(e);
}

static size_t live_bytes(const struct live *e)
{
    size_t n = (e->x.a ? iso_adapt_bytes(e->x.a) : 0) + (e->x.k ? iso_kept_bytes(e->x.k) : 0) + e->figcap * sizeof *e->fig;
    if (e->vol.owned)
        n += (size_t)e->vol.g.nx * e->vol.g.ny * e->vol.g.nz * (e->vol.g.type == ISO_U8 ? 1 : e->vol.g.type == ISO_F32 ? 4 : 2);
    return n;
}

/* Out of the list (cache lock held). */
static void unlink_live(struct live *e)
{
    for (struct live **p = &kept.head; *p; p = &(*p)->next)
        if (*p == e) {
            *p = e->next;
            kept.bytes -= e->bytes;
            e->dropped = true;
            break;
        }
}

/* The least recently used ones nobody holds let go until the rest fit in budget (lock held). */
static void trim(size_t budget)
{
    while (kept.bytes > budget) {
        struct live *old = NULL;
        for (struct live *e = kept.head; e; e = e->next)
            if (!e->users && (!old || e->used < old->used))
                old = e;
        if (!old)
            return;
        unlink_live(old);
        live_free(old);
    }
}

/* Model id's kept hierarchy, held and locked (NULL: none kept). */
static struct live *live_take(const char *id)
{
    pthread_mutex_lock(&kept.lock);
    struct live *e = kept.head;
    while (e && strcmp(e->id, id))
        e = e->next;
    if (e)
        e->users++;
    pthread_mutex_unlock(&kept.lock);
    if (e)
        pthread_mutex_lock(&e->lock);
    return e;
}

/* Lets go of e (drop: it no longer matches the store, or is of no further use). */
static void live_give(struct live *e, bool drop, size_t budget)
{
    pthread_mutex_unlock(&e->lock);
    pthread_mutex_lock(&kept.lock);
    if (drop && !e->dropped)
        unlink_live(e);
    if (!e->dropped) {
        kept.bytes -= e->bytes;
        e->bytes = live_bytes(e);
        kept.bytes += e->bytes;
        e->used = monotonic_s();
    }
    bool gone = --e->users == 0 && e->dropped;
    trim(budget);
    pthread_mutex_unlock(&kept.lock);
    if (gone)
        live_free(e);
}

/* A new entry of model id (holding vol and x), held and locked, or NULL. */
static struct live *live_new(const char *id, struct volume *vol, struct kept_ext x, int next_seq)
{
    struct live *e = calloc(1, sizeof *e);
    if (!e)
        return NULL;
    snprintf(e->id, sizeof e->id, "%s", id);
    e->vol = *vol;
    e->x = x;
    e->next_seq = next_seq;
    e->users = 1;
    pthread_mutex_init(&e->lock, NULL);
    pthread_mutex_lock(&e->lock);
    pthread_mutex_lock(&kept.lock);
    struct live *old = kept.head;
    while (old && strcmp(old->id, id))
        old = old->next;
    if (old) { /* (another job rebuilt it meanwhile: this one is newer) */
        unlink_live(old);
        if (!old->users)
            live_free(old);
    }
    e->next = kept.head;
    kept.head = e;
    e->bytes = live_bytes(e);
    kept.bytes += e->bytes;
    pthread_mutex_unlock(&kept.lock);
    return e;
}

/* The signed volume (the divergence theorem's share) and area of the triangle of corners p, q, r. */
static void tri_figures(const float *p, const float *q, const float *r, double out[2])
{
    double u[3], v[3], c[3];
    for (int d = 0; d < 3; d++)
        u[d] = (double)q[d] - p[d], v[d] = (double)r[d] - p[d];
    c[0] = u[1] * v[2] - u[2] * v[1], c[1] = u[2] * v[0] - u[0] * v[2], c[2] = u[0] * v[1] - u[1] * v[0];
    double pq[3] = {(double)q[1] * r[2] - (double)q[2] * r[1], (double)q[2] * r[0] - (double)q[0] * r[2],
                    (double)q[0] * r[1] - (double)q[1] * r[0]};
    out[0] = (p[0] * pq[0] + p[1] * pq[1] + p[2] * pq[2]) / 6;
    out[1] = 0.5 * sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
}

/* The figures of triangle id into e->fig: 0 or -1 (no memory). */
static int fig_put(struct live *e, uint32_t id, const float *p, const float *q, const float *r)
{
    if (mem_reserve((void **)&e->fig, &e->figcap, (size_t)(id - e->fig_base) + 1, sizeof *e->fig))
        return -1;
    tri_figures(p, q, r, e->fig[id - e->fig_base]);
    return 0;
}

/* The kept extraction's mesh (its stats *st: a hierarchy's) and its triangles' ids (caller frees):
 * 0 or an error. */
static int live_mesh(const struct live *e, struct trimesh *m, uint32_t **ids, struct iso_adapt_stats *st,
                     struct sf_err *err)
{
    *ids = NULL;
    if (e->x.k)
        return iso_kept_mesh(e->x.k, m, ids, err);
    int rc = iso_adapt_mesh(e->x.a, m, st, err);
    if (!rc && (rc = iso_adapt_ids(e->x.a, ids, err)))
        trimesh_free(m);
    return rc;
}

/* Every triangle's figures of e's mesh m (ids: its triangles' ids), the table made anew: 0 or -1.
 * (Oblique grids: the figures are the same turned or not.) */
static int figures_of(struct live *e, const struct trimesh *m, const uint32_t *ids)
{
    free(e->fig);
    e->fig = NULL, e->figcap = 0, e->fig_base = m->n_tri ? UINT32_MAX : 0;
    for (size_t t = 0; t < m->n_tri; t++)
        e->fig_base = ids[t] < e->fig_base ? ids[t] : e->fig_base;
    int rc = 0;
    for (size_t t = 0; t < m->n_tri && !rc; t++)
        rc = fig_put(e, ids[t], m->pos + 3 * m->tri[3 * t], m->pos + 3 * m->tri[3 * t + 1], m->pos + 3 * m->tri[3 * t + 2]);
    return rc;
}

/* figures_of the kept extraction's mesh: 0 or -1. */
static int figures_all(struct live *e)
{
    struct trimesh m;
    struct iso_adapt_stats st;
    uint32_t *ids = NULL;
    struct sf_err err = {0};
    if (live_mesh(e, &m, &ids, &st, &err))
        return -1;
    int rc = figures_of(e, &m, ids);
    free(ids);
    trimesh_free(&m);
    return rc;
}

/* Whether a part of the volume (its options), applied as ed tells, took out every triangle and
 * numbered the new ones on from the counter: an iso change (POST /models/{id}/iso), or an edit
 * that drew every cell again (ed->whole: a pad move; any edit of a merge=pieces model). Its change
 * may come without corners: the figures are then those of the new mesh, read whole (figures_of). */
static bool whole_change(const char *options, const struct iso_edit *ed)
{
    char value[64];
    query_option(options, "value", value, sizeof value);
    return value[0] != 0 || ed->whole;
}

/* What change ch (not whole) did to the figures (*dv, *da added to), e->fig following it: 0 or -1. */
static int figures_move(struct live *e, const struct iso_change *ch, double *dv, double *da)
{
    for (size_t k = 0; k < ch->n_removed; k++)
        if (ch->removed[k] >= e->fig_base && ch->removed[k] - e->fig_base < e->figcap)
            *dv -= e->fig[ch->removed[k] - e->fig_base][0], *da -= e->fig[ch->removed[k] - e->fig_base][1];
    for (size_t k = 0; k < ch->n_added; k++) {
        const float *c = ch->corners + 18 * k;
        if (fig_put(e, ch->added[k], c, c + 6, c + 12))
            return -1;
        *dv += e->fig[ch->added[k] - e->fig_base][0], *da += e->fig[ch->added[k] - e->fig_base][1];
    }
    return 0;
}

void edit_keep(struct service *svc, const char *id, const struct volume *vol, struct iso_adapt *a)
{
    struct volume v = *vol;
    v.g.samples = NULL, v.owned = NULL, v.frep = NULL;
    if (!a)
        return;
    if (svc->cfg.edit_memory <= 0 || iso_adapt_bytes(a) > (size_t)svc->cfg.edit_memory) {
        iso_adapt_free(a);
        return;
    }
    struct live *e = live_new(id, &v, (struct kept_ext){a, NULL}, 1);
    if (!e) {
        iso_adapt_free(a);
        return;
    }
    e->checked = true; /* (the mesh the job stored, ids 0 .. n-1) */
    live_give(e, figures_all(e) != 0, (size_t)svc->cfg.edit_memory);
}

/* ---- applying parts of the volume ---- */

/* Model id's extraction rebuilt from the store into e (held, empty): its volume as posted, its
 * edits left to catch_up to apply in order (so that its triangles are numbered as the first
 * extraction numbered them: the journal's ids, core/iso/kept.h). A hierarchy for levels over 1 or
 * features; marching cubes kept when its samples fit edit-memory as the isosurface job's rule has
 * it (some 5 bytes a sample), else the samples alone (every edit then draws every cell). 0 or an
 * error. */
static int build(struct service *svc, struct live *e, struct sf_err *err)
{
    struct volume *vol = &e->vol;
    struct kept_ext x = {0};
    int rc = stored_volume(svc, e->id, vol, false, &e->next_seq, err);
    if (rc)
        return rc;
    struct iso_opts o = job_iso_opts(svc, vol);
    if (volume_adaptive(vol)) {
        o.keep = true;
        if (!(rc = iso_adapt_begin(&vol->g, &o, vol->levels, vol->max_error, &x.a, err))) {
            volume_adapt_run(svc, x.a);
            struct iso_adapt_stats st;
            rc = iso_adapt_keep(x.a, &st, err);
        }
    } else if ((double)vol->g.nx * vol->g.ny * vol->g.nz * 5 <= (double)svc->cfg.edit_memory) {
        rc = iso_kept_begin(&vol->g, &o, &x.k, err);
    }
    if (rc) {
        iso_adapt_free(x.a);
        iso_kept_free(x.k);
        return rc;
    }
    e->x = x;
    if (x.a || x.k) { /* the extraction holds the samples now */
        free(vol->owned);
        vol->owned = NULL, vol->g.samples = NULL;
        if (figures_all(e))
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    return 0;
}

/* Whether e holds nothing to edit (a rebuild that failed while another job waited for it). */
static bool live_empty(const struct live *e) { return !e->x.a && !e->x.k && !e->vol.owned; }

/* Model id's extraction rebuilt from the store (build), held and locked, or NULL with err. Its
 * entry is listed first, empty and locked, so that another edit of the model waits for this
 * rebuild instead of making its own. */
static struct live *rebuild(struct service *svc, const char *id, struct sf_err *err)
{
    struct live *e = live_new(id, &(struct volume){0}, (struct kept_ext){0}, 0);
    if (!e) {
        sf_fail(err, SF_ENOMEM, "", "out of memory");
        return NULL;
    }
    if (build(svc, e, err)) {
        live_give(e, true, (size_t)svc->cfg.edit_memory);
        return NULL;
    }
    return e;
}

void edit_warm(struct service *svc, const char *id)
{
    struct sf_err err = {0};
    struct live *e = live_take(id);
    if (!e && (e = rebuild(svc, id, &err)))
        e->checked = true; /* (the job's mesh, ids 0 .. n-1: a part stored since is caught up, and checked, first) */
    if (e && e->x.k && iso_kept_index(e->x.k, &err)) { /* (what the first edit would make) */
        live_give(e, true, (size_t)svc->cfg.edit_memory);
        e = NULL;
    }
    if (e)
        live_give(e, false, (size_t)svc->cfg.edit_memory);
    else if (err.code)
        LOG(LOG_INFO, "model %s: its extraction was not kept for edits (%s); its first edit builds it", id, err.message);
}

/* The parts other nodes stored since e was built, applied. 0 or an error. */
static int catch_up(struct service *svc, struct live *e, struct sf_err *err)
{
    struct volume_rec *parts;
    int n, found = store_volume_get(svc->store, e->id, e->next_seq, &parts, &n), rc = 0;
    if (found < 0)
        rc = sf_fail(err, SF_EIO, "", "the model's volume could not be read from the store");
    for (int k = 0; k < n && !rc; k++) {
        struct iso_edit ed;
        struct iso_change ch = {0};
        double dv = 0, da = 0;
        if (parts[k].seq != e->next_seq)
            rc = sf_fail(err, SF_EIO, "", "the model's edits in the store skip from %d to %d", e->next_seq, parts[k].seq);
        else if (!(rc = part_apply(svc, &e->vol, &e->x, parts[k].options, parts[k].data, parts[k].len, &ed,
                                   e->x.a || e->x.k ? &ch : NULL, err)))
            e->next_seq++, e->checked = false; /* (another node's part: its ids are checked before they are used) */
        if (!rc && (e->x.a || e->x.k) &&
            (whole_change(parts[k].options, &ed) ? figures_all(e) : figures_move(e, &ch, &dv, &da)))
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        iso_change_free(&ch);
    }
    store_volume_free(parts, n);
    return rc;
}

/* ---- the job ---- */

struct edit_work {
    struct job_work job;     /* first: job_start fills it */
    char *json;
    size_t len;
    char model[40];
    long version;            /* the change stored (0: none), and its bytes: for compaction */
    size_t change_bytes;
    long measure;            /* the version whose whole mesh is to be measured once the edits rest (its answer
                              * gave the figures that need no O(F log F) pass), or 0 */
    char meta[128];
    struct sf_err err;
};

/* Whether the job's edit is among the model's stored parts (*was: a run before a crash stored it;
 * the model's resource then into w->json): 0, or SF_EIO with w->err. */
static int applied_before(struct edit_work *w, const char *model, bool *was)
{
    struct volume_rec *parts;
    int n, found = store_volume_get(w->job.svc->store, model, 1, &parts, &n);
    *was = false;
    if (found)
        return sf_fail(&w->err, SF_EIO, "", "the model's edits could not be read from the store");
    for (int k = 0; k < n && !*was; k++) {
        char job[40] = "";
        query_option(parts[k].options, "job", job, sizeof job);
        *was = !strcmp(job, w->job.claim.id);
    }
    store_volume_free(parts, n);
    if (*was && store_model_get(w->job.svc->store, model, NULL, &w->json, NULL, NULL))
        return sf_fail(&w->err, SF_EIO, "", "the model could not be read from the store");
    if (*was)
        LOG(LOG_INFO, "job %s: its edit was stored before the service stopped; not applied again", w->job.claim.id);
    return 0;
}

/* A part's options: the request's and the job's id (applied_before). */
static void part_options(const char *options, const char *job, char *out, size_t cap)
{
    snprintf(out, cap, "%s%sjob=%s", options, options[0] ? "&" : "", job);
}

/* The resource of model id (its stored one prev) after a change that drew its whole mesh m again
 * (v's, me), as version version: its triangles, volume and area m's own, the figures that need the
 * O(F log F) measure left to measure_later (on the CT head that measure is some 50 ms of an iso
 * slider's step). NULL with err. */
static char *redrawn_json(struct store *st, const char *id, const struct volume *v, const struct trimesh *m,
                          const struct iso_model_edit *me, long version, const double ms[3], struct sf_err *err)
{
    char *prev = NULL, *json = NULL;
    double volume = 0, area = 0;
    for (size_t t = 0; t < m->n_tri; t++) {
        double f[2];
        tri_figures(m->pos + 3 * m->tri[3 * t], m->pos + 3 * m->tri[3 * t + 1], m->pos + 3 * m->tri[3 * t + 2], f);
        volume += f[0], area += f[1];
    }
    if (store_model_get(st, id, NULL, &prev, NULL, NULL))
        sf_fail(err, SF_ECONFLICT, "", "the model could not be read from the store");
    else
        json = iso_model_json_redrawn(prev, me, version, v->iso, (long)m->n_tri, volume, area, ms, err);
    free(prev);
    return json;
}

/* The mesh m of model id's volume v (ids: its triangles' ids, NULL: 0 .. n-1) measured (later: only
 * what redrawn_json gives, the rest once the edits rest), packed and stored as the model's source of
 * the part's version with the part (seq: its format, options and data) and change (NULL: none; a
 * whole change, mesh_journal.h), the resource into w->json with edit me. */
static int store_edit(struct edit_work *w, const char *id, const struct volume *v, struct trimesh *m,
                      const uint32_t *ids, const struct iso_adapt_stats *ast, struct iso_model_edit *me,
                      const struct volume_rec *part, const struct volume_rec *change, bool later, double t0,
                      double t_mesh)
{
    struct trimesh_stats st;
    char *packed = NULL;
    size_t packed_len = 0;
    uint32_t *own = NULL;
    double t1 = monotonic_s();
    int rc = volume_mesh_empty(v, m, &w->err);
    if (!rc && v->oblique)
        trimesh_turn(m, v->g.origin, (const double(*)[3])v->axes);
    if (!rc && !later)
        rc = trimesh_stats(m, &st, &w->err);
    if (!rc && !ids && !(ids = own = malloc((m->n_tri ? m->n_tri : 1) * sizeof *own)))
        rc = sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
    for (size_t t = 0; own && t < m->n_tri; t++)
        own[t] = (uint32_t)t;
    if (!rc)
        rc = mesh_pack_ids(m, ids, (uint64_t)part->seq + 1, &packed, &packed_len, &w->err);
    if (!rc) {
        double t2 = monotonic_s(), ms[3] = {(t_mesh - t0) * 1e3, (t2 - t1) * 1e3, (t2 - t0) * 1e3};
        struct iso_model im = {id, v->name, v, &st, ast, m->n_vert, m->n_tri,
                               {0, 0, ms[0], ms[1], ms[2]}, part->seq, me, 0, NULL};
        free(w->json);
        if (!(w->json = later ? redrawn_json(w->job.svc->store, id, v, m, me, part->seq + 1, ms, &w->err)
                              : iso_model_json(&im, &w->err)))
            rc = w->err.code;
    }
    if (!rc) {
        struct model_rec mr = {id, id, NULL, NULL, 0, packed, packed_len, w->json, NULL, part->seq + 1};
        int stored = store_model_edit(w->job.svc->store, &mr, part, change);
        if (stored == SF_ECONFLICT)
            rc = sf_fail(&w->err, SF_ECONFLICT, "", "the model was edited by another request meanwhile (or deleted); "
                         "send the edit again");
        else if (stored)
            rc = sf_fail(&w->err, SF_EIO, "", "the store would not take the edit");
        else if (later)
            w->measure = part->seq + 1;
    }
    free(own);
    free(packed);
    return rc;
}

/* Change ch's corners turned as an oblique grid's mesh is (trimesh_turn). */
static void turn_corners(struct iso_change *ch, const struct volume *v)
{
    const double *o = v->g.origin;
    for (size_t k = 0; k < 3 * ch->n_added; k++) {
        float *c = ch->corners + 6 * k;
        double x[3] = {c[0] - o[0], c[1] - o[1], c[2] - o[2]}, n[3] = {c[3], c[4], c[5]};
        for (int d = 0; d < 3; d++) {
            c[d] = (float)(o[d] + x[0] * v->axes[0][d] + x[1] * v->axes[1][d] + x[2] * v->axes[2][d]);
            c[3 + d] = (float)(n[0] * v->axes[0][d] + n[1] * v->axes[1][d] + n[2] * v->axes[2][d]);
        }
    }
}

/* The edit's change ch of e's mesh stored with the part as the journal's next version (issue 45:
 * the mesh itself is not written again, nor measured whole: the resource's figures move by what
 * the change did), the resource into w->json. SF_ECONFLICT: another edit took the part's seq, the
 * model is gone, or its row keeps no base (written before the journal). */
static int store_change(struct edit_work *w, const char *id, struct live *e, const struct iso_model_edit *me,
                        struct iso_change *ch, const struct volume_rec *part, double t0)
{
    long version = part->seq + 1;
    double dv = 0, da = 0, t1 = monotonic_s();
    char *bytes = NULL, *prev = NULL;
    size_t len = 0;
    if (figures_move(e, ch, &dv, &da))
        return sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
    if (e->vol.oblique)
        turn_corners(ch, &e->vol);
    int rc = mesh_change_encode(ch, (uint32_t)version, &bytes, &len, &w->err);
    if (!rc && store_model_get(w->job.svc->store, id, NULL, &prev, NULL, NULL))
        rc = sf_fail(&w->err, SF_ECONFLICT, "", "the model could not be read from the store");
    if (!rc) {
        double t2 = monotonic_s(), ms[3] = {me->ms, (t2 - t1) * 1e3, (t2 - t0) * 1e3};
        if (!(w->json = iso_model_json_edited(prev, me, version, e->vol.iso, (long)ch->n_added - (long)ch->n_removed, dv,
                                              da, ms, &w->err)))
            rc = w->err.code;
    }
    if (!rc) {
        struct model_rec mr = {id, id, NULL, NULL, 0, NULL, 0, w->json, NULL, version};
        struct volume_rec change = {0, "", "", bytes, len};
        int stored = store_model_edit(w->job.svc->store, &mr, part, &change);
        if (!stored)
            w->version = version, w->change_bytes = len, w->measure = version;
        rc = stored == SF_ECONFLICT ? SF_ECONFLICT
             : stored             ? sf_fail(&w->err, SF_EIO, "", "the store would not take the edit")
                                  : 0;
    }
    free(prev);
    free(bytes);
    return rc;
}

/* The (id << 32 | index) of n triangles of ids, sorted (by id): caller frees; NULL, no memory. */
static int cmp_u64(const void *p, const void *q)
{
    uint64_t a = *(const uint64_t *)p, b = *(const uint64_t *)q;
    return a < b ? -1 : a > b;
}

static uint64_t *by_id(const uint32_t *ids, size_t n)
{
    uint64_t *o = malloc((n ? n : 1) * sizeof *o);
    for (size_t t = 0; o && t < n; t++)
        o[t] = (uint64_t)ids[t] << 32 | t;
    if (o)
        qsort(o, n, sizeof *o, cmp_u64);
    return o;
}

/* Whether triangle s of a and t of b have their corners' centre in one place (within rounding: an
 * oblique mesh is turned by its base's and its changes' own arithmetic). */
static bool same_place(const struct trimesh *a, size_t s, const struct trimesh *b, size_t t)
{
    for (int d = 0; d < 3; d++) {
        double p = 0, q = 0;
        for (int c = 0; c < 3; c++)
            p += a->pos[3 * a->tri[3 * s + c] + d], q += b->pos[3 * b->tri[3 * t + c] + d];
        if (fabs(p - q) > 3e-3 + 1e-6 * fabs(p))
            return false;
    }
    return true;
}

/* Whether e's triangle ids are the stored mesh's (its version e's, each id there naming the same
 * triangle), so that e's changes can go to the journal. A model edited before its extraction was
 * kept here (at levels 1 every cell was drawn again and numbered 0 .. n-1), or by a node that
 * kept none, is not: its next edit is stored whole, numbered as e numbers it. O(F log F), once a
 * rebuild or another node's parts. */
static bool ids_agree(struct service *svc, const struct live *e)
{
    char *src = NULL;
    size_t len = 0;
    struct trimesh a = {0}, b = {0};
    uint32_t *ia = NULL, *ib = NULL;
    uint64_t version = 0, *oa = NULL, *ob = NULL;
    struct iso_adapt_stats st;
    struct sf_err err = {0};
    bool same = !store_model_get(svc->store, e->id, NULL, NULL, &src, &len) &&
                !mesh_unpack_ids(src, len, &a, &ia, &version, &err) && version == (uint64_t)e->next_seq &&
                !live_mesh(e, &b, &ib, &st, &err) && a.n_tri == b.n_tri;
    free(src);
    if (same && e->vol.oblique)
        trimesh_turn(&b, e->vol.g.origin, (const double(*)[3])e->vol.axes);
    same = same && (oa = by_id(ia, a.n_tri)) && (ob = by_id(ib, b.n_tri));
    for (size_t i = 0; same && i < a.n_tri; i++)
        same = oa[i] >> 32 == ob[i] >> 32 && same_place(&a, (uint32_t)oa[i], &b, (uint32_t)ob[i]);
    free(oa);
    free(ob);
    free(ia);
    free(ib);
    trimesh_free(&a);
    trimesh_free(&b);
    return same;
}

/* The edit applied to e and stored: with a kept extraction whose ids are the store's, as a change
 * of its mesh (store_change), else (or when the model's row keeps no base) with the whole mesh.
 * The new resource into w->json. */
static int edit_model(struct edit_work *w, struct live *e, const struct job_rec *rec, const char *model, bool *drop)
{
    char region[128];
    query_option(rec->options, "region", region, sizeof region);
    double t0 = monotonic_s();
    struct iso_model_edit me = {region, {0}, 0};
    bool keeps = e->x.a || e->x.k;
    int rc = catch_up(w->job.svc, e, &w->err);
    if (rc)
        return rc;
    if (keeps && !e->checked && !(e->checked = ids_agree(w->job.svc, e)))
        LOG(LOG_INFO, "model %s: its stored mesh is not numbered as its kept extraction (edited before it was kept, "
                      "or by a node that keeps none): this edit is stored whole", model);
    *drop = true; /* from here the entry is ahead of the store until the edit is stored */
    double ta = monotonic_s();
    struct iso_change ch = {0};
    if ((rc = part_apply(w->job.svc, &e->vol, &e->x, rec->options, rec->request, rec->request_len, &me.e,
                         keeps ? &ch : NULL, &w->err))) {
        iso_change_free(&ch);
        return rc;
    }
    me.ms = (monotonic_s() - ta) * 1e3;
    char opts[sizeof rec->options + 48];
    part_options(rec->options, w->job.claim.id, opts, sizeof opts);
    struct volume_rec part = {e->next_seq, strcmp(rec->format, "iso") ? "edit" : "iso", opts, rec->request,
                              rec->request_len};
    bool whole = keeps && whole_change(part.options, &me.e);
    char *bytes = NULL;
    size_t len = 0;
    if (keeps && e->checked && !whole) {
        rc = store_change(w, model, e, &me, &ch, &part, t0);
        if (rc != SF_ECONFLICT) {
            iso_change_free(&ch);
            if (!rc)
                e->next_seq++, *drop = false;
            return rc;
        }
        LOG(LOG_INFO, "job %s: the edit is stored with the model's whole mesh (a conflict, or a model stored before "
                      "the journal of changes)", w->job.claim.id);
        rc = 0;
    } else if (keeps && !whole && figures_move(e, &ch, &(double){0}, &(double){0})) {
        rc = sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
    } else if (whole && e->checked) { /* (stored with its base: mesh_journal.h) */
        rc = mesh_change_encode_whole(&ch, (uint32_t)part.seq + 1, &bytes, &len, &w->err);
    }
    iso_change_free(&ch);
    struct trimesh m = {0};
    struct iso_adapt_stats ast = {0};
    uint32_t *ids = NULL;
    if (!rc && keeps) {
        if (!(rc = live_mesh(e, &m, &ids, &ast, &w->err)) && whole && figures_of(e, &m, ids))
            rc = sf_fail(&w->err, SF_ENOMEM, "", "out of memory");
    } else if (!rc) {
        struct iso_opts o = job_iso_opts(w->job.svc, &e->vol);
        rc = iso_extract(&e->vol.g, &o, NULL, &m, &w->err);
        me.e.cells_rebuilt = (long)(e->vol.g.nx + 1) * (e->vol.g.ny + 1) * (e->vol.g.nz + 1);
        me.e.triangles_added = (long)m.n_tri;
        me.ms = (monotonic_s() - ta) * 1e3; /* (every cell drawn again) */
    }
    double t_mesh = monotonic_s();
    struct volume_rec change = {0, "", "", bytes, len};
    /* (a hierarchy's resource has its levels' figures, which only a whole measure writes) */
    if (!rc && !(rc = store_edit(w, model, &e->vol, &m, ids, e->x.a ? &ast : NULL, &me, &part, bytes ? &change : NULL,
                                 !e->x.a, t0, t_mesh))) {
        e->next_seq++, e->checked = true, *drop = false;
        w->version = bytes ? part.seq + 1 : 0; /* (the journal's rows before it dropped on compact's turn) */
    }
    free(bytes);
    free(ids);
    trimesh_free(&m);
    return rc;
}

/* An FRep model's edit: its latest request's tree combined with the body's object, sampled and
 * extracted again whole (every cell: see the file's head), stored as the next part. */
static int edit_frep(struct edit_work *w, struct job *j, const struct job_rec *rec, const char *id)
{
    struct job_poll pc = {w->job.svc->q, j};
    const struct sf_progress pr = {service_poll_cancel, &pc};
    struct volume_rec *parts;
    int n, found = store_volume_get(w->job.svc->store, id, 0, &parts, &n), rc = 0;
    if (found || n == 0)
        return sf_fail(&w->err, found ? SF_EIO : SF_ECONFLICT, "",
                       found ? "the model's FRep request could not be read from the store"
                             : "this model keeps no FRep request (made before they were kept)");
    double t0 = monotonic_s();
    char *req = frep_combine(parts[n - 1].data, parts[n - 1].len, (const char *)rec->request, rec->request_len, &w->err);
    struct volume v = {0};
    struct iso_model_edit me = {"", {0}, 0};
    if (!req || volume_read(req, strlen(req), "frep", parts[0].options, &v, &w->err) ||
        frep_volumes(w->job.svc, v.frep, &w->err))
        rc = w->err.code ? w->err.code : SF_EINVAL;
    struct trimesh m = {0};
    struct iso_adapt_stats ast = {0};
    if (!rc && !(rc = volume_sample(&v, 0, v.g.nz, &pr, &w->err))) {
        struct iso_opts o = job_iso_opts(w->job.svc, &v);
        rc = volume_adaptive(&v) ? iso_extract_adaptive(&v.g, &o, v.levels, v.max_error, NULL, &m, &ast, &w->err)
                                 : iso_extract(&v.g, &o, NULL, &m, &w->err);
    }
    if (!rc) {
        double t_mesh = monotonic_s();
        me.e = (struct iso_edit){(long)(v.g.nx + 1) * (v.g.ny + 1) * (v.g.nz + 1), 0, (long)m.n_tri, true};
        me.ms = (t_mesh - t0) * 1e3;
        char opts[600];
        part_options(parts[0].options, w->job.claim.id, opts, sizeof opts);
        struct volume_rec part = {n, "frep", opts, req, strlen(req)};
        rc = store_edit(w, id, &v, &m, NULL, volume_adaptive(&v) ? &ast : NULL, &me, &part, NULL, false, t0, t_mesh);
    }
    trimesh_free(&m);
    volume_free(&v);
    free(req);
    store_volume_free(parts, n);
    return rc;
}

static int prepare(struct job *j, void *arg, int *n_bands)
{
    struct edit_work *w = arg;
    *n_bands = 0;
    struct job_rec rec;
    if (store_get(w->job.svc->store, w->job.claim.id, true, false, &rec))
        return sf_fail(&w->err, SF_EIO, "", "the job's record could not be read from the store");
    char model[40];
    query_option(rec.options, "model", model, sizeof model);
    snprintf(w->model, sizeof w->model, "%s", model);
    bool was;
    int rc = applied_before(w, model, &was);
    if (!rc && !was && !strcmp(rec.format, "json")) {
        rc = edit_frep(w, j, &rec, model);
    } else if (!rc && !was) {
        struct live *e = live_take(model);
        if (e && live_empty(e)) { /* (the rebuild it waited for failed) */
            live_give(e, true, (size_t)w->job.svc->cfg.edit_memory);
            e = NULL;
        }
        if (!e)
            e = rebuild(w->job.svc, model, &w->err);
        rc = e ? 0 : w->err.code;
        if (e) {
            bool drop = false;
            rc = edit_model(w, e, &rec, model, &drop);
            live_give(e, drop || live_empty(e), (size_t)w->job.svc->cfg.edit_memory);
        }
    }
    if (!rc) {
        w->len = strlen(w->json);
        snprintf(w->meta, sizeof w->meta, "{\"status\":200}");
    }
    store_rec_free(&rec);
    return rc;
}

/* The journal compacted (store.h), after the answer: every journal-kept / 2 versions, or after a
 * change of over COMPACT_BYTES (a new iso: every triangle), the model's mesh written as a new base
 * and the changes kept back to journal-kept versions before it (one after a large change). A
 * failure leaves the journal as it was (the next one tries again). */
#define COMPACT_BYTES (8u << 20)

static void compact(struct service *svc, const char *id, long version, size_t change_bytes)
{
    long every = svc->cfg.journal_kept / 2 > 0 ? svc->cfg.journal_kept / 2 : 1;
    if (!version || (version % every && change_bytes < COMPACT_BYTES))
        return;
    char *src = NULL;
    size_t len = 0;
    uint64_t at;
    if (store_model_get(svc->store, id, NULL, NULL, &src, &len) || mesh_packed_version(src, len, &at)) {
        free(src);
        return;
    }
    struct model_rec m = {id, id, NULL, NULL, 0, src, len, "", NULL, (long)at};
    long keep = change_bytes >= COMPACT_BYTES ? 1 : svc->cfg.journal_kept;
    if (store_model_rebase(svc->store, &m, (long)at - keep))
        LOG(LOG_WARN, "model %s: its journal of changes was not compacted (the store failed); kept as it is", id);
    free(src);
}

/* ---- the whole mesh measured again once edits rest ----
 * An edit's answer moves the figures its change moves (triangles, volume, area); those of the whole
 * mesh (vertices, edges, components, Euler characteristic, bounds) need an O(F log F) pass that an
 * edit's milliseconds cannot hold. One thread of the edit kind measures a model once its journaled
 * edits have rested MEASURE_QUIET seconds (a brush stroke after another would measure each in vain)
 * and writes the figures with topology_version, unless the model changed meanwhile. */
#define MEASURE_QUIET 1.0

struct pending {
    char id[40];
    long version;
    double due;              /* monotonic seconds */
    struct pending *next;
};

static struct {
    pthread_mutex_t lock;
    pthread_cond_t cond;     /* on CLOCK_MONOTONIC */
    pthread_t thread;
    bool started, stop;
    struct service *svc;
    struct pending *head;
} quiet = {.lock = PTHREAD_MUTEX_INITIALIZER};

/* Model id at version measured whole and its resource written again (when still of that version). */
static void measure(struct service *svc, const char *id, long version)
{
    char *resource = NULL, *src = NULL, *json = NULL;
    size_t len = 0;
    struct trimesh m = {0};
    struct trimesh_stats st;
    struct sf_err err = {0};
    double t0 = monotonic_s();
    int rc = store_model_get(svc->store, id, NULL, &resource, &src, &len);
    if (!rc && model_version(resource) == version && !mesh_unpack(src, len, &m, &err)) {
        free(src), src = NULL;
        if (!trimesh_stats(&m, &st, &err) && (json = iso_model_json_measured(resource, &st, m.n_vert, version, &err)) &&
            !(rc = store_model_refresh(svc->store, id, version, json)))
            LOG(LOG_DEBUG, "model %s: version %ld measured whole in %.0f ms", id, version, (monotonic_s() - t0) * 1e3);
    }
    free(json);
    trimesh_free(&m);
    free(src);
    free(resource);
}

static void *measurer(void *arg)
{
    (void)arg;
    pthread_mutex_lock(&quiet.lock);
    while (!quiet.stop) {
        struct pending **first = NULL;
        for (struct pending **p = &quiet.head; *p; p = &(*p)->next)
            if (!first || (*p)->due < (*first)->due)
                first = p;
        double now = monotonic_s();
        if (!first) {
            pthread_cond_wait(&quiet.cond, &quiet.lock);
        } else if ((*first)->due > now) {
            double at = (*first)->due;
            struct timespec ts = {(time_t)at, (long)((at - floor(at)) * 1e9)};
            pthread_cond_timedwait(&quiet.cond, &quiet.lock, &ts);
        } else {
            struct pending *p = *first;
            *first = p->next;
            pthread_mutex_unlock(&quiet.lock);
            measure(quiet.svc, p->id, p->version);
            free(p);
            pthread_mutex_lock(&quiet.lock);
        }
    }
    pthread_mutex_unlock(&quiet.lock);
    return NULL;
}

/* Model id at version to be measured once its edits rest (the thread started the first time). */
static void measure_later(struct service *svc, const char *id, long version)
{
    pthread_mutex_lock(&quiet.lock);
    if (!quiet.started && !quiet.stop) {
        pthread_condattr_t ca;
        pthread_condattr_init(&ca);
        pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
        pthread_cond_init(&quiet.cond, &ca);
        pthread_condattr_destroy(&ca);
        quiet.svc = svc;
        quiet.started = !pthread_create(&quiet.thread, NULL, measurer, NULL);
    }
    struct pending *p = quiet.head;
    while (p && strcmp(p->id, id))
        p = p->next;
    if (!p && quiet.started && (p = calloc(1, sizeof *p))) {
        snprintf(p->id, sizeof p->id, "%s", id);
        p->next = quiet.head;
        quiet.head = p;
    }
    if (p) {
        p->version = version > p->version ? version : p->version;
        p->due = monotonic_s() + MEASURE_QUIET;
        pthread_cond_signal(&quiet.cond);
    }
    pthread_mutex_unlock(&quiet.lock);
}

void edit_stop(void)
{
    pthread_mutex_lock(&quiet.lock);
    quiet.stop = true;
    bool started = quiet.started;
    if (started)
        pthread_cond_signal(&quiet.cond);
    pthread_mutex_unlock(&quiet.lock);
    if (started)
        pthread_join(quiet.thread, NULL);
    for (struct pending *p = quiet.head, *n; p; p = n) /* (not measured: the next edit schedules them) */
        n = p->next, free(p);
    quiet.head = NULL;
}

static void finish(struct job *j, void *arg, enum job_state outcome, bool requeue)
{
    (void)j;
    struct edit_work *w = arg;
    service_job_end(w->job.svc, &w->job.claim, outcome, requeue, (const unsigned char *)w->json, w->json ? w->len : 0,
                    "application/json", w->meta[0] ? w->meta : NULL, &w->err);
    if (outcome != JOB_SUCCEEDED)
        w->version = 0, w->measure = 0;
}

/* After the answer: the journal compacted on its turn, the mesh measured once the edits rest. */
static void after(void *arg)
{
    struct edit_work *w = arg;
    compact(w->job.svc, w->model, w->version, w->change_bytes);
    if (w->measure)
        measure_later(w->job.svc, w->model, w->measure);
    free(w->json);
    free(w);
}

static const struct job_ops EDIT_OPS = {.prepare = prepare, .finish = finish, .after = after};


static const char *edit_format(const char *content_type)
{
    return content_type && !strncasecmp(content_type, "application/json", 16) ? "json" : "raw";
}

/* The route checked the model (found, the token's) and put its id in ?model; here: it is an
 * isosurface of samples, and the region and the body fit its grid. */
static int edit_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    char model[40], *resource = NULL;
    query_option(b->options, "model", model, sizeof model);
    if (store_model_get(svc->store, model, NULL, &resource, NULL, NULL))
        return sf_fail(err, SF_EINVAL, "", "no such model");
    struct iso_grid g;
    bool frep, json = !strcmp(b->format, "json");
    int rc = iso_model_grid(resource, &g, &frep, err), lo[3], n[3];
    free(resource);
    if (!rc && frep != json)
        rc = sf_fail(err, SF_ECONFLICT, "", frep ? "an FRep model is edited by {\"op\", \"object\"} (application/json)"
                                                 : "an isosurface of samples is edited by the region's raw samples "
                                                   "(application/octet-stream)");
    if (rc || !frep)
        return rc ? rc : volume_region(b->options, &g, b->len, lo, n, err);
    /* the object combined with the model's latest tree, parsed (its pointers the edit's) */
    struct volume_rec *parts;
    int np, found = store_volume_get(svc->store, model, 0, &parts, &np);
    if (found || np == 0)
        return sf_fail(err, found ? SF_EIO : SF_ECONFLICT, "",
                       found ? "the store failed" : "this model keeps no FRep request (made before they were kept)");
    char *req = frep_combine(parts[np - 1].data, parts[np - 1].len, b->body ? b->body : "", b->len, err);
    store_volume_free(parts, np);
    rc = req ? 0 : err->code;
    /* the object's volume primitives are the token's models, as on POST /isosurface */
    struct frep_request r;
    if (!rc && !(rc = frep_parse(req, strlen(req), &r, err))) {
        rc = frep_refs_check(svc, &r, b->owner, "/object", err);
        frep_request_free(&r);
    }
    free(req);
    return rc;
}

const struct job_kind edit_kind = {
    .name = "edit", .format = edit_format,
    .validate = edit_validate, .ops = &EDIT_OPS, .work_size = sizeof(struct edit_work), .result = "application/json"};

/* POST /models/{id}/iso?value=V: an edit of the model's iso (stored as a part of its volume, format
 * "iso", so that a rebuilt hierarchy replays it in order), a job of the edit kind. */
static const char *iso_format(const char *content_type)
{
    (void)content_type;
    return "iso";
}

/* The route put the model's id in ?model: an isosurface of samples, no body, a finite value (its
 * range against the samples is the job's to check: they are read there). */
static int iso_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    char model[40], value[64], *resource = NULL, *end = NULL;
    query_option(b->options, "model", model, sizeof model);
    query_option(b->options, "value", value, sizeof value);
    if (b->len)
        return sf_fail(err, SF_EINVAL, "", "POST /models/{id}/iso takes no body: the new iso is ?value");
    if (!value[0] || !isfinite(strtod(value, &end)) || *end)
        return sf_fail(err, SF_EINVAL, "?value", "value is the new iso, a finite number");
    if (store_model_get(svc->store, model, NULL, &resource, NULL, NULL))
        return sf_fail(err, SF_EINVAL, "", "no such model");
    struct iso_grid g;
    bool frep;
    int rc = iso_model_grid(resource, &g, &frep, err);
    free(resource);
    if (!rc && frep)
        rc = sf_fail(err, SF_ECONFLICT, "", "an FRep model's surface is its object's zero: it changes by its edits");
    return rc;
}

const struct job_kind iso_kind = {
    .name = "edit", .format = iso_format,
    .validate = iso_validate, .ops = &EDIT_OPS, .work_size = sizeof(struct edit_work), .result = "application/json"};
