/* cmd_model.c - `surfd volume FILE` and `surfd model FILE`: contours in, the model's figures out
 * as JSON, offline; the same figures POST /volume and POST /model answer (an RT Structure Set's
 * ROIs without contours listed as "skipped", with the reason). `model` also writes the model's
 * mesh (--mesh OUT.stl|.ply|.obj|.vtp|.vtk, or --mesh DIR/: every model's, DIR/NAME.stl) and
 * patches (--patches OUT.json) as GET /models/{id}/mesh and /patches would. */
#include <errno.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "../api/dicom_scan.h"
#include "../api/formats.h"
#include "../api/model_json.h"
#include "cli.h"

/* The sink of offline models: keeps their names and sources. */
struct keep {
    struct kept_model {
        char name[128];
        char *source;
        size_t len;
    } *m;
    int n;
};

static int keep_put(void *ctx, const char *id, const char *name, const char *source, size_t source_len,
                    const char *resource)
{
    (void)id, (void)resource;
    struct keep *k = ctx;
    struct kept_model *grown = realloc(k->m, sizeof *k->m * (size_t)(k->n + 1));
    if (!grown)
        return -1;
    k->m = grown;
    struct kept_model *m = &k->m[k->n];
    snprintf(m->name, sizeof m->name, "%s", name ? name : "");
    if (!(m->source = malloc(source_len + 1)))
        return -1;
    memcpy(m->source, source, source_len);
    m->source[source_len] = 0;
    m->len = source_len;
    k->n++;
    return 0;
}

static void keep_free(struct keep *k)
{
    for (int i = 0; i < k->n; i++)
        free(k->m[i].source);
    free(k->m);
    memset(k, 0, sizeof *k);
}

/* Model m's mesh to path (its format from the extension): 0, or an SF_E* code with err. */
static int write_mesh(const struct kept_model *m, const char *path, double tol, struct sf_err *err)
{
    const char *ext = strrchr(path, '.'), *mime;
    char opts[96], *out = NULL;
    size_t out_len = 0;
    double used = 0.0;
    snprintf(opts, sizeof opts, "format=%.10s&tolerance=%.17g", !ext ? "none" : strcmp(ext, ".dcm") ? ext + 1 : "dicom-stl",
             tol); /* .dcm: a DICOM Encapsulated STL */
    int rc = model_mesh(m->source, m->len, NULL, opts, NULL, &out, &out_len, &mime, &used, err);
    if (!rc)
        rc = cli_write_all(path, out, out_len) ? SF_EIO : 0;
    if (!rc && used > 0)
        fprintf(stderr, "surfd: %s: the surface within %.3g mm\n", path, used);
    free(out);
    return rc;
}

void cmd_volume_usage(FILE *f)
{
    fprintf(f, "usage: surfd volume CONTOURS.json|RTSTRUCT.dcm|MATRIX.json [--roi NAME] [--caps flat|slab|dome]\n"
               "                    [--method parabolic|linear-parabolic|coons|bspline]\n"
               "                    [--parameterisation arc-length|polar] [--repeat N]\n"
               "       surfd volume SCENE.igs|.iges|.bpt|.nurbs|.json (patches that close a solid: area and volume)\n"
               "       surfd model  CONTOURS.json|RTSTRUCT.dcm|MATRIX.json [--roi NAME] [--caps ...] [--method ...]\n"
               "                    [--mesh OUT.stl|.ply|.obj|.vtp|.vtk|.dcm (Encapsulated STL) | --mesh DIR/ (every model: DIR/NAME.stl; DIR made)]\n"
               "                    [--tolerance MM] [--patches OUT.json]\n"
               "       --repeat runs it N times in one process and reports the fastest run (by timings_ms.total);\n"
               "       an RT Structure Set's ROIs without contours are listed as \"skipped\" with the reason\n");
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
    double best = 0;
    for (int k = 0; k < repeat && !rc; k++) {
        char *run = NULL;
        /* by the file's extension (api/formats.h), else its magic, DICOM with its preamble or without */
        const struct input_format *f = input_format_of_path(argv[1], IN_VOLUME);
        if (!f)
            f = input_format_sniff(buf, len, IN_VOLUME);
        const char *format = f ? f->name : dicom_sniff(buf, len) ? "dicom" : "json";
        char location[64];
        rc = model ? model_create(buf, len, format, options, &sink, NULL, &run, location, &err)
                   : model_figures(buf, len, format, options, NULL, &run, &err);
        if (rc)
            break;
        json_t *doc = json_loads(run, 0, NULL);
        double ms = json_number_value(json_object_get(json_object_get(doc, "timings_ms"), "total"));
        json_decref(doc);
        if (!json || ms < best) {
            free(json);
            json = run, best = ms;
        } else {
            free(run);
        }
    }
    free(buf);
    bool to_dir = mesh && mesh[0] && mesh[strlen(mesh) - 1] == '/';
    if (!rc && ((mesh && !to_dir) || patches) && kept.n != 1)
        rc = sf_fail(&err, SF_EINVAL, "--roi", "%d models: choose one with --roi, or --mesh DIR/ for all", kept.n);
    if (!rc && to_dir && mkdir(mesh, 0777) && errno != EEXIST) { /* (the last level; its parent must be there) */
        fprintf(stderr, "surfd: cannot make %s: %s\n", mesh, strerror(errno));
        rc = SF_EIO;
    }
    for (int k = 0; !rc && mesh && k < kept.n; k++) {
        char path[1200];
        if (to_dir) { /* DIR/NAME.stl, the name's spaces and slashes as _ */
            char name[128];
            snprintf(name, sizeof name, "%s", kept.m[k].name[0] ? kept.m[k].name : "model");
            for (char *c = name; *c; c++)
                *c = *c == ' ' || *c == '/' || *c == '\\' ? '_' : *c;
            snprintf(path, sizeof path, "%s%s.stl", mesh, name);
        } else {
            snprintf(path, sizeof path, "%s", mesh);
        }
        rc = write_mesh(&kept.m[k], path, tol, &err);
    }
    char *out = NULL;
    if (!rc && patches && !(rc = model_patches_json(kept.m[0].source, kept.m[0].len, &out, &err)))
        rc = cli_write_all(patches, out, strlen(out)) ? SF_EIO : 0;
    free(out);
    keep_free(&kept);
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
