/* cmd_model.c - `surfd volume FILE` and `surfd model FILE`: contours in, the model's figures out
 * as JSON, offline; the same figures POST /volume answers. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../api/model_json.h"
#include "cli.h"

int cmd_volume(int argc, char **argv)
{
    int repeat = 1;
    if (argc == 4 && !strcmp(argv[2], "--repeat"))
        repeat = atoi(argv[3]);
    if ((argc != 2 && argc != 4) || repeat < 1) {
        fprintf(stderr, "usage: surfd volume CONTOURS.json [--repeat N]   (also: surfd model ...)\n"
                        "       --repeat runs it N times in one process and reports the last (warm) timings\n");
        return 2;
    }
    FILE *f = fopen(argv[1], "rb");
    if (!f) {
        perror(argv[1]);
        return 1;
    }
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = len >= 0 && len < (1L << 30) ? malloc((size_t)len + 1) : NULL;
    size_t got = buf ? fread(buf, 1, (size_t)len, f) : 0;
    fclose(f);
    if (!buf || got != (size_t)len) {
        free(buf);
        fprintf(stderr, "surfd: %s: cannot read\n", argv[1]);
        return 1;
    }
    char *json = NULL;
    struct sf_err err = {0};
    int rc = 0;
    for (int k = 0; k < repeat && !rc; k++) {
        free(json);
        json = NULL;
        rc = model_figures(buf, (size_t)len, &json, &err);
    }
    free(buf);
    if (rc) {
        fprintf(stderr, "surfd: %s: %s%s%s\n", argv[1], err.message, err.pointer[0] ? " at " : "", err.pointer);
        return 1;
    }
    printf("%s\n", json);
    free(json);
    return 0;
}
