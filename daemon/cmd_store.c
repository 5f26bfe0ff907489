/* cmd_store.c - `surfd store check`: the operator's look at a store the service refused to start
 * on (or whose /readyz says damaged): every page and every stored sum, one line a finding. It
 * reads the same settings as serve (--config, --data-dir, --store) and changes nothing. */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "config.h"
#include "store.h"

void cmd_store_usage(FILE *f)
{
    fprintf(f, "usage: surfd store check [--config FILE] [--data-dir DIR] [--store URI]\n"
               "  checks the store's pages and the sums of every stored byte (jobs' results, models,\n"
               "  volumes); prints each finding; exit 0 sound, 1 damaged, 2 usage, 3 not readable\n");
}

static void print_line(const char *line, void *arg)
{
    (void)arg;
    printf("%s\n", line);
}

int cmd_store(int argc, char **argv)
{
    if (argc < 2 || strcmp(argv[1], "check")) {
        cmd_store_usage(stderr);
        return 2;
    }
    struct config cfg;
    char msg[600];
    config_defaults(&cfg);
    if (config_load(&cfg, argc - 1, argv + 1, msg, sizeof msg)) {
        fprintf(stderr, "surfd store: %s\n", msg);
        return 2;
    }
    const char *target = cfg.store[0] ? cfg.store : cfg.data_dir;
    struct store *s;
    if (store_open(target, cfg.data_dir, &s, msg, sizeof msg)) {
        fprintf(stderr, "surfd store: %s\n", msg);
        return 3;
    }
    int rc = store_check(s, true, print_line, NULL);
    store_close(s);
    if (rc == 0)
        printf("the store in %s is sound\n", target);
    else if (rc > 0)
        printf("the store in %s is damaged: restore it from a backup (its jobs can be sent again)\n", target);
    return rc == 0 ? 0 : rc > 0 ? 1 : 3;
}
