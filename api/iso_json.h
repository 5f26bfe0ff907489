/* iso_json.h - the model resource of an isosurface (API.md: a triangle mesh's model resource). */
#ifndef SURFD_ISO_JSON_H
#define SURFD_ISO_JSON_H

#include <stddef.h>

#include "../core/base/err.h"
#include "../core/geom/trimesh.h"
#include "volume_io.h"

struct iso_model {
    const char *id, *name;
    const struct volume *vol;
    const struct trimesh_stats *st;
    const struct iso_adapt_stats *adapt; /* levels > 1, else NULL */
    size_t vertices, triangles;
    double ms[5];            /* read, sample (an FRep's), extract, measure, total */
};

/* The resource as JSON (caller frees), or NULL with err. */
char *iso_model_json(const struct iso_model *m, struct sf_err *err);

#endif
