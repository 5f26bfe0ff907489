/* test_store.c - the store conformance suite (issue 43, 8): each backend held to store.h's diagram
 * directly, not only through HTTP. Every transition of a job and who may make it (fences,
 * owners), reaps and suspects, cancels in each state, prune with the streamed bodies it removes,
 * values longer than a piece, models scoped by owner, their volumes and edits, cached meshes; every
 * answer in core's convention (store.h: 0 or an SF_E* code). The backend is STORE_TARGET (a data
 * directory or a postgresql:// URI; tests/api/store_conformance.sh runs it on PostgreSQL), else a new SQLite
 * store in a temporary directory. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "../../api/mesh_io.h"
#include "../../api/mesh_journal.h"
#include "../../daemon/store.h"
#include "../unit.h"

static struct store *S;
static char scratch[256];
static int serial;

/* A new job of owner, queued at created (its id unique in this run and across runs on one store). */
static void submit(const char *owner, double created, char id[40])
{
    struct job_rec r = {0};
    snprintf(id, 40, "%08x%08x%016d", (unsigned)getpid(), (unsigned)rand(), ++serial);
    snprintf(r.id, sizeof r.id, "%s", id);
    snprintf(r.kind, sizeof r.kind, "volume");
    snprintf(r.format, sizeof r.format, "json");
    snprintf(r.owner, sizeof r.owner, "%s", owner);
    r.created = created;
    r.request = (unsigned char *)"{}";
    r.request_len = 2;
    REQUIRE(store_submit(S, &r) == 0);
}

static enum job_state state_of(const char *id)
{
    struct job_rec r;
    int rc = store_get(S, id, false, false, &r);
    enum job_state st = rc == 0 ? r.state : (enum job_state)-1;
    store_rec_free(&r);
    return st;
}

/* Claims queued jobs until id's is claimed (others queued before it by earlier cases are finished):
 * store_claim's answer, SF_ENOTFOUND when id's was not among the first 1000. */
static int claim(const char *id, bool alone, struct job_claim *c)
{
    for (int k = 0; k < 1000; k++) {
        int got = store_claim(S, "node-a", 30, alone, c);
        if (got != 0 || !strcmp(c->id, id))
            return got;
        struct job_end end = {.outcome = JOB_CANCELLED};
        store_finish(S, c->id, c->fence, &end);
    }
    return SF_ENOTFOUND;
}

TEST(a_job_runs_through_its_states_under_its_fence)
{
    char id[40];
    submit("alice", 1000, id);
    CHECK(state_of(id) == JOB_QUEUED);
    struct job_claim c;
    REQUIRE(claim(id, true, &c) == 0);
    CHECK(state_of(id) == JOB_RUNNING);
    bool cancel = true;
    CHECK(store_heartbeat(S, id, c.fence, 30, 0.5, &cancel) == 0 && !cancel);
    struct job_end end = {.outcome = JOB_SUCCEEDED, .result = (const unsigned char *)"result", .len = 6,
                          .type = "text/plain", .meta = "{}", .finished = 2000};
    CHECK(store_finish(S, id, c.fence + 1, &end) == SF_ECONFLICT); /* another claim's fence: nothing written */
    CHECK(state_of(id) == JOB_RUNNING);
    CHECK(store_finish(S, id, c.fence, &end) == 0);
    struct job_rec r;
    REQUIRE(store_get(S, id, false, true, &r) == 0);
    CHECK(r.state == JOB_SUCCEEDED && r.result_len == 6 && !memcmp(r.result, "result", 6) && r.attempts == 1 &&
          !strcmp(r.result_type, "text/plain") && r.result_sum[0]);
    store_rec_free(&r);
    CHECK(store_heartbeat(S, id, c.fence, 30, 1, &cancel) == SF_ECONFLICT); /* ended: the claim is gone */
    CHECK(store_finish(S, id, c.fence, &end) == SF_ECONFLICT);              /* and ends once */
    CHECK(store_get(S, "0123456789abcdef0123456789abcdef", false, true, &r) == SF_ENOTFOUND);
    store_rec_free(&r); /* zeroed whatever the answer */
}

TEST(a_released_job_is_queued_again_its_attempt_given_back)
{
    char id[40];
    submit("alice", 1001, id);
    struct job_claim c;
    REQUIRE(claim(id, true, &c) == 0);
    CHECK(store_release(S, id, c.fence) == 0 && state_of(id) == JOB_QUEUED);
    CHECK(store_release(S, id, c.fence) == SF_ECONFLICT); /* no longer running under that claim */
    struct job_claim again;
    REQUIRE(claim(id, true, &again) == 0);
    CHECK(again.fence != c.fence);
    CHECK(store_finish(S, id, c.fence, &(struct job_end){.outcome = JOB_CANCELLED}) == SF_ECONFLICT); /* the old claim */
    struct job_rec r;
    REQUIRE(store_get(S, id, false, false, &r) == 0);
    CHECK(r.attempts == 1);
    store_rec_free(&r);
    CHECK(store_finish(S, id, again.fence, &(struct job_end){.outcome = JOB_CANCELLED}) == 0);
}

TEST(cancel_in_each_state_and_only_by_its_owner)
{
    char queued[40], running[40];
    submit("alice", 1002, queued);
    bool asked = true;
    CHECK(store_cancel(S, queued, "bob", 1003, &asked) == SF_ENOTFOUND && !asked);
    asked = true;
    CHECK(store_cancel(S, queued, "alice", 1003, &asked) == 0 && !asked && state_of(queued) == JOB_CANCELLED);
    asked = true;
    CHECK(store_cancel(S, queued, NULL, 1004, &asked) == SF_ECONFLICT && !asked);
    submit("alice", 1005, running);
    struct job_claim c;
    REQUIRE(claim(running, true, &c) == 0);
    CHECK(store_cancel(S, running, "bob", 1006, &asked) == SF_ENOTFOUND && !asked);
    CHECK(store_cancel(S, running, "alice", 1006, &asked) == 0 && asked && state_of(running) == JOB_RUNNING);
    bool cancel = false;
    CHECK(store_heartbeat(S, running, c.fence, 30, 0.1, &cancel) == 0 && cancel); /* its node hears it */
    CHECK(store_release(S, running, c.fence) == 0 && state_of(running) == JOB_CANCELLED); /* not queued again */
    asked = true;
    CHECK(store_cancel(S, "0123456789abcdef0123456789abcdef", NULL, 1007, &asked) == SF_ENOTFOUND && !asked);
}

static void reaped(const char *id, enum job_state st, void *arg)
{
    (void)id, (void)st;
    ++*(int *)arg;
}

TEST(a_job_whose_lease_ran_out_is_a_suspect_run_alone)
{
    char id[40];
    submit("alice", 1008, id);
    struct job_claim c;
    REQUIRE(claim(id, true, &c) == 0);
    REQUIRE(store_release(S, id, c.fence) == 0); /* claimed again under a lease that runs out at once */
    for (int k = 0; k < 1000 && store_claim(S, "node-a", 0.001, true, &c) == 0 && strcmp(c.id, id); k++)
        store_finish(S, c.id, c.fence, &(struct job_end){.outcome = JOB_CANCELLED});
    REQUIRE(!strcmp(c.id, id));
    usleep(100000);
    int n = 0;
    CHECK(store_reap(S, (double)time(NULL) + 1, NULL, 3, "{\"status\":500}", reaped, &n) >= 1 && n >= 1);
    CHECK(state_of(id) == JOB_QUEUED);
    usleep(2100000); /* its backoff: 1 s after one attempt */
    CHECK(store_heartbeat(S, id, c.fence, 30, 0.5, &(bool){false}) == SF_ECONFLICT); /* its old claim is lost */
    struct job_claim s;
    CHECK(store_claim(S, "node-b", 30, false, &s) == SF_ENOTFOUND); /* a node running others does not take it */
    REQUIRE(store_claim(S, "node-b", 30, true, &s) == 0);
    CHECK(!strcmp(s.id, id) && s.suspect);
    CHECK(store_finish(S, id, s.fence, &(struct job_end){.outcome = JOB_CANCELLED}) == 0);
}

static long long held_alice, held_bob;

static void held(const char *owner, long long bytes, void *arg)
{
    (void)arg;
    if (!strcmp(owner, "alice"))
        held_alice += bytes;
    else if (!strcmp(owner, "bob"))
        held_bob += bytes;
}

TEST(streamed_bodies_are_counted_by_owner_and_go_when_their_job_ends)
{
    char path[300], id[40];
    snprintf(path, sizeof path, "%s/body-XXXXXX", scratch);
    int fd = mkstemp(path);
    REQUIRE(fd >= 0);
    static char body[100000];
    memset(body, 7, sizeof body);
    REQUIRE(write(fd, body, sizeof body) == (ssize_t)sizeof body);
    close(fd);
    struct job_rec r = {0};
    snprintf(id, sizeof id, "%08x%08xf%015d", (unsigned)getpid(), (unsigned)rand(), ++serial);
    snprintf(r.id, sizeof r.id, "%s", id);
    snprintf(r.kind, sizeof r.kind, "isosurface");
    snprintf(r.owner, sizeof r.owner, "bob");
    r.created = 1009;
    REQUIRE(store_submit_file(S, &r, path) == 0);
    CHECK(access(path, F_OK) != 0); /* the store took the file */
    held_alice = held_bob = 0;
    CHECK(store_uploads_held(S, held, NULL) == 0 && held_bob == (long long)sizeof body && held_alice == 0);
    char local[1100];
    REQUIRE(store_request_file(S, id, local, sizeof local) == 0);
    FILE *f = fopen(local, "rb");
    static char back[sizeof body + 1];
    size_t n = f ? fread(back, 1, sizeof back, f) : 0;
    if (f)
        fclose(f);
    CHECK(n == sizeof body && !memcmp(back, body, n));
    store_request_file_done(S, local);
    struct job_claim c;
    REQUIRE(claim(id, true, &c) == 0);
    CHECK(store_finish(S, id, c.fence, &(struct job_end){.outcome = JOB_FAILED, .error = "{\"status\":422}",
                                                          .finished = (double)time(NULL)}) == 0);
    held_bob = 0;
    CHECK(store_uploads_held(S, held, NULL) == 0 && held_bob == 0); /* ended: no longer held */
    CHECK(store_prune(S, (double)time(NULL), 365L * 86400, 1000000) == 0); /* its body removed, the job kept */
    int rc = store_request_file(S, id, local, sizeof local);
    CHECK(state_of(id) == JOB_FAILED && (rc == SF_ENOTFOUND || (rc == 0 && access(local, F_OK) != 0)));
    CHECK(store_request_file(S, "0123456789abcdef0123456789abcdef", local, sizeof local) == SF_ENOTFOUND);
}

TEST(prune_removes_ended_jobs_by_age_and_count)
{
    char old[40], young[40], waiting[40];
    submit("alice", 1010, old);
    submit("alice", 1011, young);
    submit("alice", 1012, waiting);
    struct job_claim c;
    REQUIRE(claim(old, true, &c) == 0);
    CHECK(store_finish(S, old, c.fence, &(struct job_end){.outcome = JOB_CANCELLED, .finished = 100}) == 0);
    REQUIRE(claim(young, true, &c) == 0);
    double now = (double)time(NULL);
    CHECK(store_finish(S, young, c.fence, &(struct job_end){.outcome = JOB_CANCELLED, .finished = now}) == 0);
    CHECK(store_prune(S, now, 3600, 1000000) == 0);
    CHECK(state_of(old) == (enum job_state)-1 && state_of(young) == JOB_CANCELLED);
    CHECK(state_of(waiting) == JOB_QUEUED); /* never a job not ended */
    bool asked = true;
    CHECK(store_cancel(S, waiting, NULL, now, &asked) == 0 && !asked);
}

TEST(a_result_longer_than_a_piece_reads_back_whole)
{
    store_set_piece(S, 1000);
    char id[40];
    submit("alice", 1013, id);
    struct job_claim c;
    REQUIRE(claim(id, true, &c) == 0);
    static unsigned char big[10007];
    for (size_t k = 0; k < sizeof big; k++)
        big[k] = (unsigned char)(k * 31 + 7);
    CHECK(store_finish(S, id, c.fence, &(struct job_end){.outcome = JOB_SUCCEEDED, .result = big, .len = sizeof big,
                                                          .type = "application/octet-stream", .finished = 4000}) == 0);
    struct job_rec r;
    REQUIRE(store_get(S, id, false, true, &r) == 0);
    CHECK(r.result_len == sizeof big && !memcmp(r.result, big, sizeof big));
    store_rec_free(&r);
    store_set_piece(S, STORE_PIECE);
}

static int listed;
static void count(const char *resource, void *arg)
{
    (void)resource, (void)arg;
    listed++;
}

TEST(models_are_scoped_by_owner)
{
    char id[40], job[40];
    snprintf(id, sizeof id, "%08x%08xm%015d", (unsigned)getpid(), (unsigned)rand(), ++serial);
    submit("alice", 1014, job);
    const char *resource = "{\"id\":\"m\"}";
    struct model_rec m = {id, job, "skull", "alice", 1014, "{\"slices\":[]}", 13, resource, NULL, 1};
    REQUIRE(store_model_put(S, &m) == 0);
    char *res = NULL, *src = NULL;
    size_t n = 0;
    CHECK(store_model_get(S, id, "bob", &res, &src, &n) == SF_ENOTFOUND && !res);
    CHECK(store_model_get(S, id, "bob", &res, NULL, NULL) == SF_ENOTFOUND && !res); /* the resource alone */
    CHECK(store_model_get(S, id, "alice", &res, &src, &n) == 0 && res && !strcmp(res, resource) && n == 13 &&
          src && !memcmp(src, "{\"slices\":[]}", 13));
    free(res), free(src);
    res = NULL;
    CHECK(store_model_get(S, id, "alice", &res, NULL, NULL) == 0 && res && !strcmp(res, resource));
    free(res);
    listed = 0;
    CHECK(store_model_list(S, "bob", 0, count, NULL) == 0 && listed == 0);
    CHECK(store_model_list(S, "alice", 0, count, NULL) == 0 && listed >= 1);
    CHECK(store_model_delete(S, id, "bob") == SF_ENOTFOUND);
    CHECK(store_model_delete(S, id, "alice") == 0 && store_model_get(S, id, NULL, &res, &src, &n) == SF_ENOTFOUND);
    CHECK(store_model_delete(S, id, "alice") == SF_ENOTFOUND); /* once */
    bool asked = true;
    CHECK(store_cancel(S, job, NULL, 1015, &asked) == 0 && !asked);
}

TEST(a_models_volume_and_its_edits_in_order)
{
    char id[40], job[40];
    snprintf(id, sizeof id, "%08x%08xv%015d", (unsigned)getpid(), (unsigned)rand(), ++serial);
    submit("alice", 1016, job);
    struct volume_rec posted = {0, "json", "", "abc", 3};
    struct model_rec m = {id, job, "skull", "alice", 1016, "{}", 2, "{\"v\":0}", &posted, 1};
    REQUIRE(store_model_put(S, &m) == 0);
    struct volume_rec *parts = NULL;
    int n = -1;
    CHECK(store_volume_get(S, id, 0, &parts, &n) == 0 && n == 1 && parts[0].seq == 0 && parts[0].len == 3 &&
          !memcmp(parts[0].data, "abc", 3) && !strcmp(parts[0].format, "json"));
    store_volume_free(parts, n);
    CHECK(store_volume_get(S, id, 1, &parts, &n) == 0 && n == 0); /* no edits yet: none, not an error */
    store_volume_free(parts, n);
    struct volume_rec edit = {1, "json", "region=1", "de", 2};
    struct model_rec edited = {id, job, "skull", "alice", 1016, "{ }", 3, "{\"v\":1}", NULL, 2};
    CHECK(store_model_edit(S, &edited, &edit, NULL) == 0);
    CHECK(store_model_edit(S, &edited, &edit, NULL) == SF_ECONFLICT); /* its seq is taken: another edit came first */
    CHECK(store_volume_get(S, id, 0, &parts, &n) == 0 && n == 2 && parts[0].seq == 0 && parts[1].seq == 1 &&
          parts[1].len == 2 && !memcmp(parts[1].data, "de", 2) && !strcmp(parts[1].options, "region=1"));
    store_volume_free(parts, n);
    char *res = NULL;
    CHECK(store_model_get(S, id, NULL, &res, NULL, NULL) == 0 && res && !strcmp(res, "{\"v\":1}"));
    free(res);
    CHECK(store_model_delete(S, id, NULL) == 0);
    edit.seq = 2;
    CHECK(store_model_edit(S, &edited, &edit, NULL) == SF_ECONFLICT); /* the model is gone */
    CHECK(store_volume_get(S, id, 0, &parts, &n) == 0 && n == 0);
    store_volume_free(parts, n);
    bool asked = true;
    CHECK(store_cancel(S, job, NULL, 1017, &asked) == 0 && !asked);
}

TEST(meshes_are_cached_while_their_model_lasts)
{
    char id[40], job[40];
    snprintf(id, sizeof id, "%08x%08xc%015d", (unsigned)getpid(), (unsigned)rand(), ++serial);
    submit("alice", 1018, job);
    struct model_rec m = {id, job, "skull", "alice", 1018, "{}", 2, "{\"c\":0}", NULL, 1};
    REQUIRE(store_model_put(S, &m) == 0);
    struct mesh_rec got;
    CHECK(store_mesh_get(S, id, "stl", &got) == SF_ENOTFOUND && !got.data);
    static unsigned char mesh[5000];
    memset(mesh, 3, sizeof mesh);
    struct mesh_rec put = {"model/stl", "{}", mesh, sizeof mesh, ""};
    CHECK(store_mesh_put(S, id, "stl", &put, 1L << 30) == 0);
    REQUIRE(store_mesh_get(S, id, "stl", &got) == 0);
    CHECK(got.len == sizeof mesh && !memcmp(got.data, mesh, sizeof mesh) && !strcmp(got.type, "model/stl") &&
          strlen(got.sum) == 64);
    store_mesh_free(&got);
    CHECK(store_mesh_bytes(S) >= (long)sizeof mesh);
    CHECK(store_mesh_put(S, id, "small", &put, 100) == SF_ECONFLICT); /* alone over the budget */
    CHECK(store_mesh_get(S, id, "small", &got) == SF_ENOTFOUND);
    CHECK(store_mesh_put(S, "0123456789abcdef0123456789abcdef", "stl", &put, 1L << 30) == SF_ECONFLICT); /* no model */
    struct volume_rec edit = {1, "json", "", "x", 1};
    CHECK(store_model_edit(S, &m, &edit, NULL) == 0);
    CHECK(store_mesh_get(S, id, "stl", &got) == SF_ENOTFOUND); /* an edit drops the model's meshes */
    CHECK(store_model_delete(S, id, NULL) == 0);
    bool asked = true;
    CHECK(store_cancel(S, job, NULL, 1019, &asked) == 0 && !asked);
}

/* A mesh model edited by changes (store.h: a base and a journal): the mesh answered is the base
 * with the changes applied, each change's version, the journal read from any version, a newer base
 * taking the older changes with it (an older one left). */
TEST(a_mesh_models_changes_are_its_journal)
{
    char id[40], job[40];
    snprintf(id, sizeof id, "%08x%08xj%015d", (unsigned)getpid(), (unsigned)rand(), ++serial);
    submit("alice", 1020, job);
    float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    uint32_t tri[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    struct trimesh tm = {pos, NULL, tri, 4, 4};
    struct sf_err err = {0};
    char *base, *chg[3], *src = NULL, *res = NULL;
    size_t base_len, chg_len[3], n_src;
    REQUIRE(mesh_pack(&tm, &base, &base_len, &err) == 0); /* (version 1, ids 0 .. 3) */
    struct model_rec m = {id, job, "tet", "alice", 1020, base, base_len, "{\"version\":1}", NULL, 1};
    REQUIRE(store_model_put(S, &m) == 0);
    /* three changes: each takes one triangle out and puts a moved copy in under a new id */
    for (int k = 0; k < 3; k++) {
        uint32_t removed = (uint32_t)k, added = 4 + (uint32_t)k;
        float corners[18] = {0};
        for (int c = 0; c < 3; c++)
            for (int d = 0; d < 3; d++)
                corners[6 * c + d] = pos[3 * tri[3 * k + c] + d] + (float)(k + 1);
        struct iso_change ch = {&removed, 1, &added, corners, 1, 5 + (uint32_t)k};
        REQUIRE(mesh_change_encode(&ch, (uint32_t)k + 2, &chg[k], &chg_len[k], &err) == 0);
        char rsc[32];
        snprintf(rsc, sizeof rsc, "{\"version\":%d}", k + 2);
        struct model_rec e = {id, job, "tet", "alice", 1020, NULL, 0, rsc, NULL, k + 2};
        struct volume_rec part = {k + 1, "raw", "region=0,0,0,1,1,1", "x", 1}, change = {0, "", "", chg[k], chg_len[k]};
        CHECK(store_model_edit(S, &e, &part, &change) == 0);
        CHECK(store_model_edit(S, &e, &part, &change) == SF_ECONFLICT); /* taken */
    }
    struct volume_rec *parts;
    int n;
    CHECK(store_changes_get(S, id, 1, &parts, &n) == 0 && n == 3 &&
          mesh_change_version(parts[0].data, parts[0].len) == 2 && mesh_change_version(parts[2].data, parts[2].len) == 4);
    store_volume_free(parts, n);
    CHECK(store_changes_get(S, id, 3, &parts, &n) == 0 && n == 1 && mesh_change_version(parts[0].data, parts[0].len) == 4);
    store_volume_free(parts, n);
    CHECK(store_volume_get(S, id, 0, &parts, &n) == 0 && n == 3 && parts[0].seq == 1); /* (the volume's edits alone) */
    store_volume_free(parts, n);
    /* the mesh: the base with the three changes applied */
    struct trimesh got;
    uint32_t *ids;
    uint64_t version;
    REQUIRE(store_model_get(S, id, NULL, &res, &src, &n_src) == 0);
    CHECK(!strcmp(res, "{\"version\":4}"));
    CHECK(mesh_unpack_ids(src, n_src, &got, &ids, &version, &err) == 0 && version == 4 && got.n_tri == 4 && ids[0] == 3 &&
          ids[1] == 4 && ids[3] == 6 && got.pos[3 * got.tri[3 * 3]] == pos[3 * tri[6]] + 3);
    trimesh_free(&got);
    free(ids);
    /* a newer base (compaction): the same mesh, the changes up to it gone */
    struct model_rec nb = {id, job, "tet", "alice", 1020, src, n_src, res, NULL, 4};
    CHECK(store_model_rebase(S, &nb, 3) == 0);
    CHECK(store_changes_get(S, id, 0, &parts, &n) == 0 && n == 1 && mesh_change_version(parts[0].data, parts[0].len) == 4);
    store_volume_free(parts, n);
    char *src2 = NULL;
    size_t n2;
    CHECK(store_model_get(S, id, NULL, NULL, &src2, &n2) == 0 && n2 == n_src && !memcmp(src, src2, n2));
    free(src2);
    struct model_rec old = {id, job, "tet", "alice", 1020, base, base_len, res, NULL, 1};
    CHECK(store_model_rebase(S, &old, 1) == 0); /* an older base than the one kept: left */
    CHECK(store_model_get(S, id, NULL, NULL, &src2, &n2) == 0 && n2 == n_src && !memcmp(src, src2, n2));
    free(src2);
    /* the resource measured again: written at its version, refused at an older one (a newer part) */
    char *now = NULL;
    CHECK(store_model_refresh(S, id, 3, "{\"version\":3}") == SF_ECONFLICT);
    CHECK(store_model_refresh(S, id, 4, "{\"version\":4,\"components\":1}") == 0);
    CHECK(store_model_get(S, id, NULL, &now, NULL, NULL) == 0 && !strcmp(now, "{\"version\":4,\"components\":1}"));
    free(now);
    CHECK(store_model_refresh(S, "no-such-model", 4, "{}") == SF_ECONFLICT);
    CHECK(store_model_delete(S, id, NULL) == 0);
    CHECK(store_changes_get(S, id, 0, &parts, &n) == 0 && n == 0);
    store_volume_free(parts, n);
    for (int k = 0; k < 3; k++)
        free(chg[k]);
    free(base), free(src), free(res);
    bool asked = true;
    CHECK(store_cancel(S, job, NULL, 1021, &asked) == 0 && !asked);
}

struct seen {
    int n;
    char sop[4][65];
    size_t len[4];
    bool data_ok;
};
static void seen_instance(const char *sop, const char *meta, const void *data, size_t len, void *arg)
{
    struct seen *s = arg;
    if (s->n < 4) {
        snprintf(s->sop[s->n], sizeof s->sop[0], "%s", sop);
        s->len[s->n] = len;
    }
    s->data_ok = s->data_ok && (!data || (len && ((const char *)data)[0] == sop[strlen(sop) - 1])) && meta[0] == '{';
    s->n++;
}
static int n_series;
static void count_series(const struct series_rec *r, void *arg)
{
    (void)r, (void)arg;
    n_series++;
}

TEST(series_keep_their_instances_once_each_in_order)
{
    char series[48], sop[3][65];
    snprintf(series, sizeof series, "1.2.826.0.1.%u.%d", (unsigned)getpid(), ++serial);
    for (int k = 0; k < 3; k++)
        snprintf(sop[k], sizeof sop[k], "%s.%d", series, k + 1); /* each ends in its digit: the data's first byte */
    static unsigned char big[3000]; /* longer than a piece (set below): read back whole */
    memset(big, '3', sizeof big);
    store_set_piece(S, 1024);
    struct instance_rec r = {sop[0], series, "1.2.3", "CT", "received from ORTHANC", "alice", 2000, "{\"rows\":2}",
                             "1abc", 4};
    CHECK(store_instance_put(S, &r) == 0);
    CHECK(store_instance_put(S, &r) == SF_ECONFLICT); /* once: the same SOP Instance UID again is kept as it was */
    r.sop_uid = sop[1], r.received = 2001, r.data = "2defgh", r.len = 6;
    CHECK(store_instance_put(S, &r) == 0);
    r.sop_uid = sop[2], r.received = 2002, r.data = big, r.len = sizeof big;
    CHECK(store_instance_put(S, &r) == 0);
    store_set_piece(S, STORE_PIECE);
    struct series_rec got;
    CHECK(store_series_get(S, series, NULL, &got) == 0 && got.instances == 3 && got.bytes == 4 + 6 + (long long)sizeof big &&
          got.first == 2000 && got.last == 2002 && !strcmp(got.modality, "CT") && !strcmp(got.study_uid, "1.2.3") &&
          !strcmp(got.source, "received from ORTHANC"));
    CHECK(store_series_get(S, series, "bob", &got) == SF_ENOTFOUND);
    n_series = 0;
    CHECK(store_series_list(S, "alice", count_series, NULL) == 0 && n_series >= 1);
    n_series = 0;
    CHECK(store_series_list(S, "bob", count_series, NULL) == 0 && n_series == 0);
    struct seen s = {.data_ok = true};
    CHECK(store_series_instances(S, series, true, seen_instance, &s) == 0 && s.n == 3 && s.data_ok &&
          !strcmp(s.sop[0], sop[0]) && !strcmp(s.sop[2], sop[2]) && s.len[1] == 6 && s.len[2] == sizeof big);
    struct seen h = {.data_ok = true};
    CHECK(store_series_instances(S, series, false, seen_instance, &h) == 0 && h.n == 3 && h.len[2] == 0);
    CHECK(store_series_mark(S, series, "job-1") == 0 && store_series_mark(S, series, "job-2") == SF_ECONFLICT &&
          store_series_get(S, series, NULL, &got) == 0 && !strcmp(got.job, "job-1"));
    CHECK(store_series_mark(S, "9.9.9", "job-3") == SF_ENOTFOUND);
    CHECK(store_series_delete(S, series, "bob") == SF_ENOTFOUND);
    CHECK(store_series_delete(S, series, "alice") == 0 && store_series_get(S, series, NULL, &got) == SF_ENOTFOUND);
    struct seen none = {.data_ok = true};
    CHECK(store_series_instances(S, series, true, seen_instance, &none) == 0 && none.n == 0);
    CHECK(store_series_delete(S, series, NULL) == SF_ENOTFOUND);
    r.sop_uid = sop[0];
    CHECK(store_instance_put(S, &r) == 0); /* its instances went with it: received again, stored again */
    CHECK(store_series_delete(S, series, NULL) == 0);
}

TEST(an_unopenable_store_says_why)
{
    struct store *bad = (struct store *)1;
    struct sf_err err = {0};
    CHECK(store_open("/dev/null/nowhere", scratch, &bad, &err) == SF_EIO && !bad && err.code == SF_EIO &&
          strstr(err.message, "/dev/null/nowhere/surfd.db: "));
    CHECK(store_open("/dev/null/nowhere", scratch, &bad, NULL) == SF_EIO); /* err may be NULL */
}

int main(void)
{
    srand((unsigned)time(NULL));
    const char *target = getenv("STORE_TARGET");
    snprintf(scratch, sizeof scratch, "/tmp/test_store-XXXXXX");
    if (!mkdtemp(scratch)) {
        perror("mkdtemp");
        return 1;
    }
    struct sf_err err = {0};
    if (store_open(target && *target ? target : scratch, scratch, &S, &err)) {
        fprintf(stderr, "store_open: %s\n", err.message);
        return 1;
    }
    printf("store: %s\n", store_backend(S));
    RUN(a_job_runs_through_its_states_under_its_fence);
    RUN(a_released_job_is_queued_again_its_attempt_given_back);
    RUN(cancel_in_each_state_and_only_by_its_owner);
    RUN(a_job_whose_lease_ran_out_is_a_suspect_run_alone);
    RUN(streamed_bodies_are_counted_by_owner_and_go_when_their_job_ends);
    RUN(prune_removes_ended_jobs_by_age_and_count);
    RUN(a_result_longer_than_a_piece_reads_back_whole);
    RUN(models_are_scoped_by_owner);
    RUN(a_models_volume_and_its_edits_in_order);
    RUN(meshes_are_cached_while_their_model_lasts);
    RUN(a_mesh_models_changes_are_its_journal);
    RUN(series_keep_their_instances_once_each_in_order);
    RUN(an_unopenable_store_says_why);
    store_close(S);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", scratch);
    if (system(cmd)) {
        /* a temporary directory left behind is no failure of the store */
    }
    UNIT_END();
}
