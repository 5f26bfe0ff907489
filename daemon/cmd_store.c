/* cmd_store.c - `surfd store check`: the operator's look at a store the service refused to start
 * on (or whose /readyz says damaged): every page and every stored sum, one line a finding; and
 * `surfd store recover`: keeps the sound part of a damaged store (store_recover), the service
 * stopped. Both read the same settings as serve (--config, --data-dir, --store). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../api/problem.h"
#include "cli.h"
#include "config.h"
#include "store.h"

void cmd_store_usage(FILE *f)
{
    fprintf(f, "usage: surfd store check|recover [--config FILE] [--data-dir DIR] [--store URI]\n"
               "  check: the store's pages, its journal (commits lost from SQLite's WAL) and the sums of every\n"
               "    stored byte (jobs' results, models, volumes); prints each finding; exit 0 sound, 1 damaged,\n"
               "    2 usage, 3 not readable\n"
               "  recover (the service stopped): keeps a copy of the store, then keeps its sound part: a loss\n"
               "    from the WAL accepted, models whose bytes do not match removed, jobs whose results do not\n"
               "    failed; prints each step; exit 0 mended, 1 pages damaged (restore a backup), 3 error\n");
}

static void print_line(const char *line, void *arg)
{
    (void)arg;
    printf("%s\n", line);
}

int cmd_store(int argc, char **argv)
{
    bool recover = argc >= 2 && !strcmp(argv[1], "recover");
    if (argc < 2 || (strcmp(argv[1], "check") && !recover)) {
        cmd_store_usage(stderr);
        return 2;
    }
    struct config cfg;
    config_defaults(&cfg);
    struct sf_err err = {0};
    if (config_load(&cfg, argc - 1, argv + 1, &err)) {
        fprintf(stderr, "surfd store: %s\n", err.message);
        return 2;
    }
    const char *target = cfg.store[0] ? cfg.store : cfg.data_dir;
    struct store *s;
    if (store_open(target, cfg.data_dir, &s, &err)) {
        fprintf(stderr, "surfd store: %s\n", err.message);
        return 3;
    }
    if (recover) {
        sf_fail(&err, SF_EBACKEND, "", "the result was damaged in the store and removed by surfd store recover; "
                                       "send the job again");
        char *problem = problem_from_err(&err);
        int rc = problem ? store_recover(s, problem, print_line, NULL) : SF_EIO;
        free(problem);
        if (rc == 0) /* what is left, checked as check does */
            rc = store_check(s, true, print_line, NULL);
        store_close(s);
        printf(rc == 0 ? "the store in %s is mended: what is left is sound\n"
                       : rc == SF_EDAMAGED ? "the store in %s is not mended: restore it from a backup\n"
                                           : "the store in %s was not mended\n", target);
        return rc == 0 ? 0 : rc == SF_EDAMAGED ? 1 : 3;
    }
    int rc = store_check(s, true, print_line, NULL);
    store_close(s);
    if (rc == 0)
        printf("the store in %s is sound\n", target);
    else if (rc == SF_EDAMAGED)
        printf("the store in %s is damaged: restore it from a backup (its jobs can be sent again)\n", target);
    return rc == 0 ? 0 : rc == SF_EDAMAGED ? 1 : 3;
}
