/* cmd_model.c - `surfd volume FILE` and `surfd model FILE`: contours in, the model's figures out
 * as JSON, offline; the same figures POST /volume and POST /model answer. `model` also writes the
 * model's mesh (--mesh OUT.stl|.ply|.obj) and patches (--patches OUT.json) as GET
 * /models/{id}/mesh and /patches would. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../api/model_json.h"
#include "cli.h"

/* The sink of offline models: keeps the sources, counts them. */
struct keep {
    char *source;
    size_t len;
    int n;
};

static int keep_put(void *ctx, const char *id, const char *name, const char *source, size_t source_len,
                    const char *resource)
{
    (void)id, (void)name, (void)resource;
    struct keep *k = ctx;
    if (k->n++ == 0 && (k->source = malloc(source_len + 1))) {
        memcpy(k->source, source, source_len);
        k->source[source_len] = 0;
        k->len = source_len;
    }
    return k->source ? 0 : -1;
}

void cmd_volume_usage(FILE *f)
{
    fprintf(f, "usage: surfd volume CONTOURS.json|RTSTRUCT.dcm [--roi NAME] [--caps flat|slab|dome]\n"
               "                    [--method parabolic|linear-parabolic|coons|bspline]\n"
               "                    [--parameterisation arc-length|polar] [--repeat N]\n"
               "       surfd model  CONTOURS.json|RTSTRUCT.dcm [--roi NAME] [--caps ...] [--method ...]\n"
               "                    [--mesh OUT.stl|OUT.ply|OUT.obj [--tolerance MM]] [--patches OUT.json]\n"
               "       --repeat runs it N times in one process and reports the last (warm) timings\n");
}

int cmd_volume(int argc, char **argv)
{
    bool model = !strcmp(argv[0], "model");
    int repeat = 1;
    char options[256] = "";
    const char *mesh = NULL, *patches = NULL;
    double tol = 0.0;
    for (int k = 2; k + 1 < argc; k += 2) {
        size_t n = strlen(options);
        if (!strcmp(argv[k], "--repeat"))
            repeat = atoi(argv[k + 1]);
        else if (!strcmp(argv[k], "--roi") || !strcmp(argv[k], "--caps") || !strcmp(argv[k], "--method") ||
                 !strcmp(argv[k], "--parameterisation"))
            snprintf(options + n, sizeof options - n, "%s%s=%s", n ? "&" : "", argv[k] + 2, argv[k + 1]);
        else if (model && !strcmp(argv[k], "--mesh"))
            mesh = argv[k + 1];
        else if (model && !strcmp(argv[k], "--patches"))
            patches = argv[k + 1];
        else if (model && !strcmp(argv[k], "--tolerance"))
            tol = atof(argv[k + 1]);
        else
            repeat = 0;
    }
    if (argc < 2 || argc % 2 || repeat < 1) {
        cmd_volume_usage(stderr);
        return 2;
    }
    size_t len;
    char *buf = cli_read_all(argv[1], &len, 1u << 30);
    if (!buf)
        return 1;
    char *json = NULL;
    struct sf_err err = {0};
    struct keep kept = {0};
    struct model_sink sink = {NULL, keep_put, &kept};
    int rc = 0;
    for (int k = 0; k < repeat && !rc; k++) {
        free(json);
        json = NULL;
        /* DICOM Part 10 files carry "DICM" after a 128-byte preamble */
        const char *format = len > 132 && !memcmp(buf + 128, "DICM", 4) ? "dicom" : "json";
        char location[64];
        rc = model ? model_create(buf, len, format, options, &sink, NULL, &json, location, &err)
                   : model_figures(buf, len, format, options, NULL, &json, &err);
    }
    free(buf);
    if (!rc && (mesh || patches) && kept.n != 1)
        rc = sf_fail(&err, SF_EINVAL, "--roi", "%d models: choose one with --roi for --mesh or --patches", kept.n);
    char *out = NULL;
    size_t out_len = 0;
    const char *ext = mesh ? strrchr(mesh, '.') : NULL, *mime;
    double tol_used = 0.0;
    char mesh_opts[96];
    snprintf(mesh_opts, sizeof mesh_opts, "format=%.8s&tolerance=%.17g", ext ? ext + 1 : "none", tol);
    if (!rc && mesh && !(rc = model_mesh(kept.source, kept.len, mesh_opts, NULL, &out, &out_len, &mime, &tol_used, &err)))
        rc = cli_write_all(mesh, out, out_len) ? SF_EIO : 0;
    if (!rc && mesh && tol_used > 0)
        fprintf(stderr, "surfd: %s: the surface within %.3g mm\n", mesh, tol_used);
    free(out);
    out = NULL;
    if (!rc && patches && !(rc = model_patches_json(kept.source, kept.len, &out, &err)))
        rc = cli_write_all(patches, out, strlen(out)) ? SF_EIO : 0;
    free(out);
    free(kept.source);
    if (rc) {
        if (rc != SF_EIO)
            fprintf(stderr, "surfd: %s: %s%s%s\n", argv[1], err.message, err.pointer[0] ? " at " : "", err.pointer);
        free(json);
        return 1;
    }
    printf("%s\n", json);
    free(json);
    return 0;
}
