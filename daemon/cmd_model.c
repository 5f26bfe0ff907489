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
    char options[256] = "";
    for (int k = 2; k + 1 < argc; k += 2) {
        size_t n = strlen(options);
        if (!strcmp(argv[k], "--repeat"))
            repeat = atoi(argv[k + 1]);
        else if (!strcmp(argv[k], "--roi") || !strcmp(argv[k], "--caps"))
            snprintf(options + n, sizeof options - n, "%s%s=%s", n ? "&" : "", argv[k] + 2, argv[k + 1]);
        else
            repeat = 0;
    }
    if (argc < 2 || argc % 2 || repeat < 1) {
        fprintf(stderr, "usage: surfd volume CONTOURS.json|RTSTRUCT.dcm [--roi NAME] [--caps flat|slab] [--repeat N]\n"
                        "       (also: surfd model ...); --repeat runs it N times in one process and reports the\n"
                        "       last (warm) timings\n");
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
        /* DICOM Part 10 files carry "DICM" after a 128-byte preamble */
        const char *format = len > 132 && !memcmp(buf + 128, "DICM", 4) ? "dicom" : "json";
        rc = model_figures(buf, (size_t)len, format, options, &json, &err);
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
