/* dicomweb_tool.c - daemon/dicomweb.c from the command line, for tests/api/dicomweb.sh and the
 * WADO-RS bench: each command one call of dicomweb.h, its answer printed in lines a shell test
 * reads. Errors: "error CODE (NAME): message" on stderr, exit status 1 (2: usage).
 *
 *   dicomweb_tool [OPTIONS] URL search studies|series|instances [STUDY [SERIES]] [NAME=VALUE ...]
 *   dicomweb_tool [OPTIONS] URL retrieve STUDY SERIES DIR MAX_BYTES
 *   dicomweb_tool [OPTIONS] URL store STUDY|- MAX_BYTES FILE...
 *   OPTIONS: --credentials FILE  --ca FILE  --attempts N  --connect-timeout S  --stall-timeout S
 *            --timeout S  --expect N (retrieve: instances expected, for the progress lines) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../../core/base/clock.h"
#include "../../daemon/dicomweb.h"

static int usage(void)
{
    fprintf(stderr, "usage: dicomweb_tool [--credentials FILE] [--ca FILE] [--attempts N] [--connect-timeout S] "
                    "[--stall-timeout S] [--timeout S] [--expect N] URL search|retrieve|store ...\n");
    return 2;
}

static int fail(const struct sf_err *err, int rc)
{
    fprintf(stderr, "error %d (%s): %s\n", rc, sf_strerror(rc), err->message);
    return 1;
}

static int on_instance(void *ctx, int index, const char *path, uint64_t n_bytes, struct sf_err *err)
{
    (void)err;
    uint64_t *total = ctx;
    *total += n_bytes;
    printf("instance %d %s %llu\n", index, path, (unsigned long long)n_bytes);
    return 0;
}

static bool on_progress(void *ctx, double done)
{
    double *last = ctx;
    if (done > *last)
        *last = done;
    return false;
}

int main(int argc, char **argv)
{
    struct dicomweb_config cfg = {0};
    int i = 1, expect = 0;
    for (; i + 1 < argc && !strncmp(argv[i], "--", 2); i += 2) {
        if (!strcmp(argv[i], "--credentials"))
            cfg.credentials_file = argv[i + 1];
        else if (!strcmp(argv[i], "--ca"))
            cfg.ca_file = argv[i + 1];
        else if (!strcmp(argv[i], "--attempts"))
            cfg.attempts = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--connect-timeout"))
            cfg.connect_timeout_s = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--stall-timeout"))
            cfg.stall_timeout_s = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--timeout"))
            cfg.request_timeout_s = atoi(argv[i + 1]);
        else if (!strcmp(argv[i], "--expect"))
            expect = atoi(argv[i + 1]);
        else
            return usage();
    }
    if (argc - i < 2)
        return usage();
    cfg.url = argv[i++];
    const char *cmd = argv[i++];
    struct sf_err err = {0};
    struct dicomweb *dw;
    int rc, status = 0;
    if (dicomweb_global_init())
        return fail(&err, SF_EBACKEND);
    if ((rc = dicomweb_open(&cfg, &dw, &err)))
        return fail(&err, rc);
    double t0 = sf_now_ms();
    if (!strcmp(cmd, "search") && i < argc) {
        enum dicomweb_level level = !strcmp(argv[i], "studies") ? DICOMWEB_STUDIES
                                  : !strcmp(argv[i], "series")  ? DICOMWEB_SERIES
                                                                : DICOMWEB_INSTANCES;
        const char *uids[2] = {NULL, NULL};
        struct dicomweb_param params[32];
        int n_params = 0, n_uids = 0;
        for (i++; i < argc; i++) {
            char *eq = strchr(argv[i], '=');
            if (!eq && n_uids < 2)
                uids[n_uids++] = argv[i];
            else if (eq && n_params < 32) {
                *eq = 0;
                params[n_params++] = (struct dicomweb_param){argv[i], eq + 1};
            }
        }
        char *json;
        size_t len;
        if ((rc = dicomweb_search(dw, level, uids[0], uids[1], params, n_params, &json, &len, &err)))
            status = fail(&err, rc);
        else {
            fwrite(json, 1, len, stdout);
            putchar('\n');
            free(json);
        }
    } else if (!strcmp(cmd, "retrieve") && argc - i == 4) {
        uint64_t total = 0;
        double done = 0;
        struct sf_progress pr = {on_progress, &done};
        struct dicomweb_retrieve rq = {argv[i + 2], strtoull(argv[i + 3], NULL, 10), expect, on_instance, &total, &pr};
        int n = 0;
        rc = dicomweb_retrieve_series(dw, argv[i], argv[i + 1], &rq, &n, &err);
        double s = (sf_now_ms() - t0) / 1000;
        printf("retrieved %d instances, %llu bytes in %.3f s (%.1f instances/s), progress %.2f\n", n,
               (unsigned long long)total, s, s > 0 ? n / s : 0, done);
        if (rc)
            status = fail(&err, rc);
    } else if (!strcmp(cmd, "store") && argc - i >= 3) {
        struct dicomweb_stored *res;
        int n_res;
        const char *study = strcmp(argv[i], "-") ? argv[i] : NULL;
        if ((rc = dicomweb_store(dw, study, (const char *const *)argv + i + 2, argc - i - 2,
                                 strtoull(argv[i + 1], NULL, 10), &res, &n_res, &err)))
            status = fail(&err, rc);
        else {
            int n_ok = 0;
            for (int k = 0; k < n_res; k++) {
                printf("%s %s %s %d\n", res[k].stored ? "stored" : "failed", res[k].sop_instance_uid,
                       res[k].sop_class_uid, res[k].reason);
                n_ok += res[k].stored;
            }
            printf("%d stored, %d failed in %.3f s\n", n_ok, n_res - n_ok, (sf_now_ms() - t0) / 1000);
            free(res);
        }
    } else
        status = usage();
    dicomweb_free(dw);
    return status;
}
