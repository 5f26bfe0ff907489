/* job_samples.c - a volume's samples for the page's slice views (issue 46): GET /models/{id}/volume
 * (an isosurface model's volume as the store keeps it, its edits applied) and GET
 * /series/{uid}/volume (a stored series read as POST /isosurface?series= reads it), answered as one
 * NRRD: the samples as the grid holds them (uint8, int16, uint16 or float; a CT series' after its
 * rescale), x fastest, with their space directions and origin in DICOM patient coordinates (LPS).
 * A transient kind (kinds.h): read on the checks pool, never on an HTTP thread, never stored.
 * Bounded by max-volume; a model is its owner's, a series the site's (as GET /series/{uid}). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../api/dicom_instance.h"
#include "dicom_node.h"
#include "job_samples.h"
#include "pacs.h"
#include "volumes.h"

static const char *nrrd_type(enum iso_type t)
{
    return t == ISO_U8 ? "uint8" : t == ISO_I16 ? "int16" : t == ISO_U16 ? "uint16" : "float";
}

/* v's grid as an attached NRRD (malloc'ed into *out): 0, SF_ELIMIT over max bytes, SF_ENOMEM. */
static int nrrd_of(const struct volume *v, const char *what, size_t max, char **out, size_t *len, struct sf_err *err)
{
    const struct iso_grid *g = &v->g;
    size_t ts = g->type == ISO_U8 ? 1 : g->type == ISO_F32 ? 4 : 2;
    size_t bytes = (size_t)g->nx * (size_t)g->ny * (size_t)g->nz * ts;
    if (bytes > max)
        return sf_fail(err, SF_ELIMIT, "", "the samples are %zu bytes: over this node's max-volume (%zu)", bytes, max);
    char head[1024];
    double d[3][3];
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++)
            d[a][b] = g->spacing[a] * v->axes[a][b];
    int n = snprintf(head, sizeof head,
                     "NRRD0004\n# surfd: %s\ntype: %s\ndimension: 3\nspace: left-posterior-superior\n"
                     "sizes: %d %d %d\nspace directions: (%.17g,%.17g,%.17g) (%.17g,%.17g,%.17g) (%.17g,%.17g,%.17g)\n"
                     "kinds: domain domain domain\nendian: %s\nencoding: raw\nspace origin: (%.17g,%.17g,%.17g)\n\n",
                     what, nrrd_type(g->type), g->nx, g->ny, g->nz, d[0][0], d[0][1], d[0][2], d[1][0], d[1][1],
                     d[1][2], d[2][0], d[2][1], d[2][2],
                     __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ ? "little" : "big", g->origin[0], g->origin[1],
                     g->origin[2]);
    char *buf = malloc((size_t)n + bytes);
    if (!buf)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the samples");
    memcpy(buf, head, (size_t)n);
    memcpy(buf + n, g->samples, bytes);
    *out = buf, *len = (size_t)n + bytes;
    return 0;
}

/* The body is the id (a model's, or a series' UID), the format "model" or "series". */
static int samples_validate(struct service *svc, struct job_body *b, struct sf_err *err)
{
    char id[72], what[160];
    snprintf(id, sizeof id, "%.*s", (int)(b->len < 71 ? b->len : 71), b->body ? b->body : "");
    size_t max = (size_t)svc->cfg.max_volume;
    struct volume v;
    int rc;
    char *series = NULL;
    if (!strcmp(b->format, "series")) {
        struct series_rec rec;
        int found = dicom_uid_valid(id) ? store_series_get(svc->store, id, NULL, &rec) : SF_ENOTFOUND;
        if (found)
            return sf_fail(err, found == SF_ENOTFOUND ? SF_ENOTFOUND : SF_EIO, "",
                           found == SF_ENOTFOUND ? "no such series" : "the store could not read the series");
        size_t len;
        if ((rc = series_request(svc, id, false, max, &series, &len, err))) {
            err->pointer[0] = 0;
            return rc;
        }
        memset(&v, 0, sizeof v);
        struct sf_err e = {0};
        rc = volume_read(series, len, "dicom", "iso=0", &v, &e); /* (iso: read, not used) */
        if (rc) { /* (a series that is no volume: a structure set, a series of one slice) */
            free(series);
            return sf_fail(err, rc == SF_ENOMEM ? rc : SF_ECONFLICT, "", "the series is not a volume of samples: %s",
                           e.message);
        }
        snprintf(what, sizeof what, "series %s", id);
    } else {
        char *resource = NULL;
        int found = store_model_get(svc->store, id, b->owner, &resource, NULL, NULL);
        free(resource);
        if (found)
            return sf_fail(err, found == SF_ENOTFOUND ? SF_ENOTFOUND : found, "",
                           found == SF_ENOTFOUND ? "no such model" : "the store could not read the model");
        int next;
        if ((rc = stored_volume(svc, id, &v, true, &next, err)))
            return rc;
        snprintf(what, sizeof what, "model %s, %d edit%s applied", id, next - 1, next == 2 ? "" : "s");
    }
    char *out = NULL;
    size_t len = 0;
    rc = nrrd_of(&v, what, max, &out, &len, err);
    volume_free(&v);
    free(series);
    if (rc)
        return rc;
    free(b->body);
    b->body = out, b->len = len;
    return 0;
}

const struct job_kind samples_kind = {.name = "samples", .validate = samples_validate, .transient = true,
                                      .result = "application/x-nrrd"};

/* GET /pacs: the PACS configured, by name and kind (their addresses and credentials are the
 * site's configuration, not said). */
char *pacs_list_json(const struct service *svc)
{
    size_t cap = 32 + (size_t)svc->n_pacs * 96, n = 0;
    char *s = malloc(cap);
    if (!s)
        return NULL;
    n += (size_t)snprintf(s + n, cap - n, "{\"pacs\":[");
    for (int k = 0; k < svc->n_pacs; k++)
        n += (size_t)snprintf(s + n, cap - n, "%s{\"name\":\"%s\",\"protocol\":\"%s\"}", k ? "," : "",
                              svc->pacs[k].name, svc->pacs[k].dimse ? "dimse" : "dicomweb");
    snprintf(s + n, cap - n, "]}");
    return s;
}
