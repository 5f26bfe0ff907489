/* fuzz_config.c - surfd serve's settings: the input as a config file (--config), and its lines as
 * command-line arguments, both through config_load. */
#include "../../daemon/config.h"
#include "fuzz.h"

#define ARGS_MAX 64

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct config c;
    struct sf_err err = {0};
    char *path = fuzz_file(data, size, 0600);
    if (path) {
        char *argv[] = {"serve", "--config", path, NULL};
        config_defaults(&c);
        config_load(&c, 3, argv, &err);
    }
    char *text = fuzz_text(data, size), *argv[ARGS_MAX + 1] = {"serve"};
    int argc = 1;
    for (char *p = text, *line; p && argc < ARGS_MAX && (line = strsep(&p, "\n"));)
        if (strcmp(line, "--config")) /* a path from the input would be opened: not this target's */
            argv[argc++] = line;
    argv[argc] = NULL;
    config_defaults(&c);
    err = (struct sf_err){0};
    if (text)
        config_load(&c, argc, argv, &err);
    free(text);
    return 0;
}
