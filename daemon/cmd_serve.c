/* cmd_serve.c - `surfd serve`: settings, start-up checks (no unauthenticated non-loopback
 * listener), the store, recovery of jobs an earlier process left queued or running, the worker
 * pool and the HTTP server; then signals: SIGTERM/SIGINT drain and exit 0. */
#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/statvfs.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../api/image.h"
#include "frames.h"
#include "job_edit.h"
#include "keeper.h"
#include "../core/iso/mc.h"

#ifndef SURFD_VERSION
#define SURFD_VERSION "dev"
#endif
#include "cli.h"
#include "dicom_node.h"
#include "dicomweb.h"
#include "log.h"
#include "pacs.h"
#include "server.h"
#include "service.h"
#include "shares.h"
#include "tokens.h"

/* job-memory 0: three quarters of the memory the process may use (the machine's, or less under
 * RLIMIT_AS or its cgroup's memory.max), shared among the workers. */
static long long job_memory_share(long threads)
{
    long long total = (long long)sysconf(_SC_PHYS_PAGES) * sysconf(_SC_PAGESIZE);
    struct rlimit rl;
    if (!getrlimit(RLIMIT_AS, &rl) && rl.rlim_cur != RLIM_INFINITY && (long long)rl.rlim_cur < total)
        total = (long long)rl.rlim_cur;
    char line[512], path[600];
    FILE *f = fopen("/proc/self/cgroup", "r");
    while (f && fgets(line, sizeof line, f)) /* "0::/PATH": cgroup v2 */
        if (!strncmp(line, "0::", 3)) {
            line[strcspn(line, "\n")] = 0;
            snprintf(path, sizeof path, "/sys/fs/cgroup%s/memory.max", line + 3);
            FILE *m = fopen(path, "r");
            long long max;
            if (m && fscanf(m, "%lld", &max) == 1 && max > 0 && max < total) /* "max": none */
                total = max;
            if (m)
                fclose(m);
        }
    if (f)
        fclose(f);
    return total / 4 * 3 / (threads > 0 ? threads : 1);
}

/* upload-share 0: a quarter of the file system that holds the data dir. */
static long long upload_share(const char *data_dir)
{
    struct statvfs fs;
    return statvfs(data_dir, &fs) ? 1LL << 30 : (long long)(fs.f_blocks / 4) * (long long)fs.f_frsize;
}

/* The node's name in the store: --node-name, or host name and port. */
static void node_name(struct service *svc, unsigned port)
{
    if (svc->cfg.node_name[0]) {
        snprintf(svc->node, sizeof svc->node, "%s", svc->cfg.node_name);
        return;
    }
    char host[48] = "localhost";
    gethostname(host, sizeof host - 1);
    snprintf(svc->node, sizeof svc->node, "%s:%u", host, port);
}

static bool loopback(const char *listen)
{
    return !strncmp(listen, "127.", 4) || !strncmp(listen, "[::1]:", 6) || !strncmp(listen, "localhost:", 10);
}

/* A job this node held when it stopped: queued again for whichever node has room, or failed
 * once it has stopped the service max-attempts times (with Restart=on-failure, running it again
 * would keep the service down). */
static void recovered(const char *id, enum job_state state, void *arg)
{
    const struct service *svc = arg;
    if (state == JOB_FAILED)
        LOG(LOG_ERROR, "job %s stopped the service %ld times: failed, not recovered", id, svc->cfg.max_attempts);
    else if (state == JOB_CANCELLED)
        LOG(LOG_INFO, "job %s was cancelled before the service stopped: not run again", id);
    else
        LOG(LOG_INFO, "recovered job %s (to run alone)", id);
}

static void log_finding(const char *line, void *arg)
{
    (void)arg;
    LOG(LOG_ERROR, "store check: %s", line);
}

/* Seconds a running job has to stop once the drain timeout has passed and it has been cancelled. */
#define DRAIN_GRACE_S 5.0

/* A job that did not stop by the drain's end: queued again, its attempt not counted (it did not
 * stop the service; the service stopped it). */
static void abandon(const char *id, void *arg)
{
    service_release(arg, id);
}

void cmd_serve_usage(FILE *f) { config_usage(f); }

/* The settings, the tokens, and whether they may serve where they listen: 0, or 2 (said on stderr). */
static int settings(struct service *svc, int argc, char **argv)
{
    struct sf_err err = {0};
    config_defaults(&svc->cfg);
    if (config_load(&svc->cfg, argc, argv, &err) || log_set_level(svc->cfg.log_level)) {
        fprintf(stderr, "surfd serve: %s\n", err.code ? err.message : "log-level is error, warn, info or debug");
        return 2;
    }
    if (svc->cfg.token_file[0] && tokens_read(svc->cfg.token_file, &svc->tokens, &svc->n_tokens, &err)) {
        fprintf(stderr, "surfd serve: %s\n", err.message);
        return 2;
    }
    if (!loopback(svc->cfg.listen) && svc->n_tokens == 0 && !svc->cfg.insecure_no_auth) {
        fprintf(stderr,
                "surfd serve: refusing to listen on %s without authentication: give --token-file FILE, listen on "
                "127.0.0.1, or say --insecure-no-auth if a proxy in front authenticates\n",
                svc->cfg.listen);
        return 2;
    }
    return 0;
}

/* What the node serves with, but the pool: the store (a damaged one is not served: its pages and
 * every job's and model's JSON are checked first), the Embree device, the image library's place,
 * the upload ledger, the frame cache. 0, or -1 (said on stderr; close_parts frees what opened). */
static int open_parts(struct service *svc, long threads)
{
    struct sf_err err = {0};
    if (store_open(svc->cfg.store[0] ? svc->cfg.store : svc->cfg.data_dir, svc->cfg.data_dir, &svc->store, &err)) {
        fprintf(stderr, "surfd serve: store: %s\n", err.message);
        return -1;
    }
    store_set_piece(svc->store, (size_t)svc->cfg.store_piece);
    int checked = store_check(svc->store, false, log_finding, NULL);
    if (checked) {
        if (checked == SF_EDAMAGED)
            LOG(LOG_ERROR, "the store in %s is damaged: not starting (surfd store check lists what; restore a backup)",
                svc->cfg.store[0] ? "the database" : svc->cfg.data_dir);
        fprintf(stderr, "surfd serve: the store is %s\n",
                checked == SF_EDAMAGED ? "damaged (see the log)" : "not readable");
        return -1;
    }
    if (!(svc->dev = bvh_device_new((int)threads, &err)) ||
        image_locate(&err)) { /* loaded on the first image: a node that never renders is lighter */
        fprintf(stderr, "surfd serve: %s\n", err.message);
        return -1;
    }
    if (!svc->cfg.upload_share)
        svc->cfg.upload_share = upload_share(svc->cfg.data_dir);
    if (!(svc->shares = shares_new(svc->tokens, svc->n_tokens)) || shares_refresh(svc->shares, svc->store)) {
        fprintf(stderr, "surfd serve: cannot read what the store holds of each owner's uploads\n");
        return -1;
    }
    if (!(svc->frames = frames_open((size_t)svc->cfg.frame_cache))) {
        fprintf(stderr, "surfd serve: out of memory\n");
        return -1;
    }
    return 0;
}

static void close_parts(struct service *svc)
{
    frames_close(svc->frames); /* after the pool: no job holds one */
    shares_free(svc->shares);
    bvh_device_free(svc->dev);
    store_close(svc->store);
    tokens_free(svc->tokens, svc->n_tokens);
}

/* Until SIGTERM or SIGINT: every 5 s the stranded jobs and the upload ledger, every minute pruning. */
static void run_until_stopped(struct service *svc, sigset_t *sigs)
{
    for (double pruned = monotonic_s();;) {
        struct timespec every = {5, 0};
        int sig = sigtimedwait(sigs, NULL, &every);
        if (sig == SIGTERM || sig == SIGINT)
            return;
        keeper_retry_stranded(svc);
        shares_refresh(svc->shares, svc->store);
        if (monotonic_s() - pruned >= 60) {
            store_prune(svc->store, wall_s(), svc->cfg.result_ttl, svc->cfg.result_max);
            pruned = monotonic_s();
        }
    }
}

/* The drain: no new jobs, the running ones given drain-timeout; those still running after it and
 * the grace are left to the next start (the process ends under them). */
static void drain(struct service *svc, struct server *server)
{
    LOG(LOG_INFO, "draining: no new jobs; running ones get %lds", svc->cfg.drain_timeout);
    atomic_store(&svc->draining, true);
    server_quiesce(server);
    dicom_node_stop(svc->dicom); /* no new instance; those arriving are stored and answered first */
    svc->dicom = NULL;
    int left = jobq_shutdown(svc->q, (double)svc->cfg.drain_timeout, DRAIN_GRACE_S, abandon, svc);
    if (left) { /* their workers are still in core code: end the process under them */
        log_write(LOG_WARN, "%d job%s did not stop within %lds + %.0fs; exiting, %s queued for the next start", left,
                  left == 1 ? "" : "s", svc->cfg.drain_timeout, DRAIN_GRACE_S, left == 1 ? "it stays" : "they stay");
        _exit(0);
    }
    edit_stop(); /* (no job is left to ask it for more) */
    keeper_stop(svc); /* heartbeats went on while the drain ran; the draining flag stopped claims */
    server_stop(server);
    jobq_free(svc->q);
    LOG(LOG_INFO, "stopped");
}

int cmd_serve(int argc, char **argv)
{
    struct service svc = {0};
    pthread_mutex_init(&svc.lock, NULL);
    int rc = settings(&svc, argc, argv);
    if (rc)
        return rc;
    /* DCMTK leaves Nagle's algorithm on unless TCP_NODELAY is set in the environment, and its
     * small PDUs then wait on delayed ACKs: 50 instances took 2.9 s over loopback, 0.19 s with it
     * on both sides (tests/bench/RESULTS.md). Set before any thread reads the environment; an
     * operator's own value is kept. */
    setenv("TCP_NODELAY", "1", 0);
    /* signals are taken by sigtimedwait below; block them before any thread starts */
    sigset_t sigs;
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGTERM);
    sigaddset(&sigs, SIGINT);
    pthread_sigmask(SIG_BLOCK, &sigs, NULL);
    signal(SIGPIPE, SIG_IGN);
    umask(077); /* the store, its journals and anything else made here hold patient data */

    long threads = svc.cfg.threads ? svc.cfg.threads : sysconf(_SC_NPROCESSORS_ONLN);
    svc.started_wall = wall_s();
    svc.started_mono = monotonic_s();
    struct sf_err err = {0};
    struct server *server = NULL;
    rc = 1;
    if (open_parts(&svc, threads))
        goto out;
    /* libcurl's and DCMTK's global state before any thread; the PACS named (their URLs and
     * credentials checked now: a wrong one stops the start, not a pull an hour later) */
    dimse_global_init();
    dicom_leftovers_remove(svc.cfg.data_dir);
    if (dicomweb_global_init() || pacs_open_all(&svc, &err)) {
        fprintf(stderr, "surfd serve: %s\n", err.message[0] ? err.message : "libcurl would not start");
        goto out;
    }
    iso_init();
    if (!svc.cfg.job_memory)
        svc.cfg.job_memory = job_memory_share(threads);
    if (!(svc.q = jobq_new((int)threads, svc.cfg.queue_max, svc.cfg.job_memory))) {
        fprintf(stderr, "surfd serve: cannot start the worker pool\n");
        goto out;
    }
    if (!(server = server_start(&svc, &err))) {
        fprintf(stderr, "surfd serve: %s\n", err.message);
        goto out_stop_pool;
    }
    node_name(&svc, server_port(server));
    /* what this node held when it last stopped (the embedded store: every running job, since one
     * process uses it) is queued again, or failed after max-attempts */
    char *give_up = service_give_up_problem(&svc);
    bool shared = strcmp(store_backend(svc.store), "sqlite");
    store_reap(svc.store, shared ? wall_s() : INFINITY, svc.node, (int)svc.cfg.max_attempts, give_up, recovered, &svc);
    free(give_up);
    if (keeper_start(&svc)) {
        fprintf(stderr, "surfd serve: cannot start the keeper thread\n");
        server_stop(server);
        goto out_stop_pool;
    }
    if (dicom_node_start(&svc, &svc.dicom, &err)) {
        fprintf(stderr, "surfd serve: %s\n", err.message);
        keeper_stop(&svc);
        server_stop(server);
        goto out_stop_pool;
    }
    char host[128];
    snprintf(host, sizeof host, "%.*s", (int)(strrchr(svc.cfg.listen, ':') - svc.cfg.listen), svc.cfg.listen);
    /* the one line an operator always needs, whatever the level */
    log_write(LOG_INFO, "surfd %s listening on %s%s:%u, %ld workers of %ld MB, node %s, %s store%s%s%s", SURFD_VERSION,
        svc.cfg.tls_cert[0] ? "https://" : "http://", host, server_port(server), threads, svc.cfg.job_memory >> 20, svc.node,
        store_backend(svc.store), shared ? "" : " in ", shared ? "" : svc.cfg.data_dir,
        svc.n_tokens ? ", bearer tokens required" : "");
    run_until_stopped(&svc, &sigs);
    drain(&svc, server);
    rc = 0;
    goto out;
out_stop_pool:
    jobq_shutdown(svc.q, 0, DRAIN_GRACE_S, NULL, NULL);
    jobq_free(svc.q);
out:
    pacs_close_all(&svc);
    close_parts(&svc);
    return rc;
}
