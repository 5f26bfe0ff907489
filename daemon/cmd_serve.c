/* cmd_serve.c - `surfd serve`: settings, start-up checks (no unauthenticated non-loopback
 * listener), the store, recovery of jobs an earlier process left queued or running, the worker
 * pool and the HTTP server; then signals: SIGTERM/SIGINT drain and exit 0. */
#include <arpa/inet.h>
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../api/image.h"

#ifndef SURFD_VERSION
#define SURFD_VERSION "dev"
#endif
#include "cli.h"
#include "log.h"
#include "server.h"
#include "service.h"
#include "tokens.h"

static bool loopback(const char *listen)
{
    return !strncmp(listen, "127.", 4) || !strncmp(listen, "[::1]:", 6) || !strncmp(listen, "localhost:", 10);
}

/* A job that was running when the process stopped this many times is not run again: it is what
 * stopped it (with Restart=on-failure, running it again would keep the service down). */
#define RECOVER_MAX_ATTEMPTS 2

static void recover(const char *id, void *arg)
{
    struct service *svc = arg;
    struct job_rec rec;
    if (store_get(svc->store, id, false, false, &rec) != 1)
        return;
    if (rec.attempts >= RECOVER_MAX_ATTEMPTS) {
        struct sf_err err = {0};
        sf_fail(&err, SF_EBACKEND, "", "this job stopped the service %d times; it is not run again",
                rec.attempts);
        service_job_end(svc, id, JOB_FAILED, false, NULL, 0, NULL, NULL, &err);
        LOG(LOG_ERROR, "job %s stopped the service %d times: failed, not recovered", id, rec.attempts);
    } else {
        store_set_state(svc->store, id, "queued", 0.0, 0, 0, NULL);
        if (service_submit_kind(svc, rec.kind, id, true) == 0)
            LOG(LOG_INFO, "recovered job %s", id);
        else
            LOG(LOG_ERROR, "job %s of kind \"%s\" could not be queued again", id, rec.kind);
    }
    store_rec_free(&rec);
}

/* Seconds a running job has to stop once the drain timeout has passed and it has been cancelled. */
#define DRAIN_GRACE_S 5.0

/* A job that did not stop by the drain's end: queued again, its attempt not counted (it did not
 * stop the service; the service stopped it). */
static void abandon(const char *id, void *arg)
{
    struct service *svc = arg;
    store_requeue(svc->store, id);
}

int cmd_serve(int argc, char **argv)
{
    struct service svc = {0};
    pthread_mutex_init(&svc.stranded_lock, NULL);
    char msg[600];
    config_defaults(&svc.cfg);
    for (int k = 1; k < argc; k++)
        if (!strcmp(argv[k], "--help") || !strcmp(argv[k], "-h")) {
            config_usage();
            return 0;
        }
    if (config_load(&svc.cfg, argc, argv, msg, sizeof msg) || log_set_level(svc.cfg.log_level)) {
        fprintf(stderr, "surfd serve: %s\n", msg[0] ? msg : "log-level is error, warn, info or debug");
        return 2;
    }
    if (svc.cfg.token_file[0] && tokens_read(svc.cfg.token_file, &svc.tokens, &svc.n_tokens, msg, sizeof msg)) {
        fprintf(stderr, "surfd serve: %s\n", msg);
        return 2;
    }
    if (!loopback(svc.cfg.listen) && svc.n_tokens == 0 && !svc.cfg.insecure_no_auth) {
        fprintf(stderr,
                "surfd serve: refusing to listen on %s without authentication: give --token-file FILE, listen on "
                "127.0.0.1, or say --insecure-no-auth if a proxy in front authenticates\n",
                svc.cfg.listen);
        return 2;
    }
    /* signals are taken by sigwait below; block them before any thread starts */
    sigset_t sigs;
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGTERM);
    sigaddset(&sigs, SIGINT);
    pthread_sigmask(SIG_BLOCK, &sigs, NULL);
    signal(SIGPIPE, SIG_IGN);
    umask(077); /* the store, its journals and anything else made here hold patient data */

    int rc = 1;
    long threads = svc.cfg.threads ? svc.cfg.threads : sysconf(_SC_NPROCESSORS_ONLN);
    svc.started_wall = wall_s();
    svc.started_mono = monotonic_s();
    struct sf_err err = {0};
    struct server *server = NULL;
    if (store_open(svc.cfg.data_dir, &svc.store, msg, sizeof msg)) {
        fprintf(stderr, "surfd serve: store: %s\n", msg);
        goto out_free_tokens;
    }
    if (!(svc.dev = bvh_device_new((int)threads, &err))) {
        fprintf(stderr, "surfd serve: %s\n", err.message);
        goto out_close_store;
    }
    image_init();
    if (!(svc.q = jobq_new((int)threads, svc.cfg.queue_max))) {
        fprintf(stderr, "surfd serve: cannot start the worker pool\n");
        goto out_free_device;
    }
    store_unfinished(svc.store, recover, &svc);
    if (!(server = server_start(&svc, msg, sizeof msg))) {
        fprintf(stderr, "surfd serve: %s\n", msg);
        jobq_shutdown(svc.q, 0, DRAIN_GRACE_S, NULL, NULL);
        goto out_free_device;
    }
    char host[128];
    snprintf(host, sizeof host, "%.*s", (int)(strrchr(svc.cfg.listen, ':') - svc.cfg.listen), svc.cfg.listen);
    /* the one line an operator always needs, whatever the level */
    log_write(LOG_INFO, "surfd %s listening on %s%s:%u, %ld workers, data in %s%s", SURFD_VERSION,
        svc.cfg.tls_cert[0] ? "https://" : "http://", host, server_port(server), threads, svc.cfg.data_dir,
        svc.n_tokens ? ", bearer tokens required" : "");

    for (double pruned = monotonic_s();;) { /* every 5 s stranded jobs, every minute pruning */
        struct timespec every = {5, 0};
        int sig = sigtimedwait(&sigs, NULL, &every);
        if (sig == SIGTERM || sig == SIGINT)
            break;
        service_retry_stranded(&svc);
        if (monotonic_s() - pruned >= 60) {
            store_prune(svc.store, wall_s(), svc.cfg.result_ttl, svc.cfg.result_max);
            pruned = monotonic_s();
        }
    }
    LOG(LOG_INFO, "draining: no new jobs; running ones get %lds", svc.cfg.drain_timeout);
    atomic_store(&svc.draining, true);
    server_quiesce(server);
    int left = jobq_shutdown(svc.q, (double)svc.cfg.drain_timeout, DRAIN_GRACE_S, abandon, &svc);
    if (left) { /* their workers are still in core code: end the process under them */
        log_write(LOG_WARN, "%d job%s did not stop within %lds + %.0fs; exiting, %s queued for the next start", left,
                  left == 1 ? "" : "s", svc.cfg.drain_timeout, DRAIN_GRACE_S, left == 1 ? "it stays" : "they stay");
        _exit(0);
    }
    server_stop(server);
    LOG(LOG_INFO, "stopped");
    rc = 0;
out_free_device:
    bvh_device_free(svc.dev);
out_close_store:
    store_close(svc.store);
out_free_tokens:
    tokens_free(svc.tokens, svc.n_tokens);
    return rc;
}
