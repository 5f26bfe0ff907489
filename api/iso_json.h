/* iso_json.h - the model resource of an isosurface (API.md: a triangle mesh's model resource). */
#ifndef SURFD_ISO_JSON_H
#define SURFD_ISO_JSON_H

#include <stdbool.h>
#include <stddef.h>

#include "../core/base/err.h"
#include "../core/geom/trimesh.h"
#include "volume_io.h"

/* An edit's figures (POST /models/{id}/edit). */
struct iso_model_edit {
    const char *region;
    struct iso_edit e;       /* (whole: every cell drawn again) */
    double ms;               /* the samples written and the cells drawn again */
};

struct iso_model {
    const char *id, *name;
    const struct volume *vol;
    const struct trimesh_stats *st;
    const struct iso_adapt_stats *adapt; /* levels > 1, else NULL */
    size_t vertices, triangles;
    double ms[5];            /* read, sample (an FRep's), extract, measure, total */
    int edits;               /* edits so far */
    const struct iso_model_edit *edit; /* the last one's, or NULL */
    int label;               /* a label map's: the label's index in vol (1 .. vol->n_labels), else 0 */
    const size_t *touch;     /* ?labels=all: its triangles facing each label index (0: the background), else NULL */
};

/* The resource as JSON (caller frees), or NULL with err. */
char *iso_model_json(const struct iso_model *m, struct sf_err *err);

/* The resource prev after an edit that made version version without the whole mesh measured again
 * (issue 45: an edit answers in milliseconds), at iso: its triangles, volume and area moved by what the
 * change took out and put in, the edit's figures and timings (extract, measure, total ms); the
 * figures that need the whole mesh (vertices, boundary and non-manifold edges, components, Euler
 * characteristic, bounds) stay those of the version topology_version says. NULL with err. */
/* The resource prev (of version version) with the figures of its whole mesh measured (st, its
 * vertices), topology_version then version. NULL with err. */
char *iso_model_json_measured(const char *prev, const struct trimesh_stats *st, size_t vertices, long version,
                              struct sf_err *err);
char *iso_model_json_edited(const char *prev, const struct iso_model_edit *me, long version, double iso, long d_triangles,
                            double d_volume, double d_area, const double ms[3], struct sf_err *err);
/* The same after a change that drew the whole mesh again (a new iso), its mesh's own triangles,
 * volume and area given: the figures that need the O(F log F) measure stay topology_version's. */
char *iso_model_json_redrawn(const char *prev, const struct iso_model_edit *me, long version, double iso, long triangles,
                             double volume, double area, const double ms[3], struct sf_err *err);

/* The grid (dims, type) of an isosurface model from its resource, *frep whether it is an FRep
 * object's: 0, or SF_ECONFLICT for a model of another source (contours) or of a label map's
 * label (its map is not kept). */
int iso_model_grid(const char *resource, struct iso_grid *g, bool *frep, struct sf_err *err);

/* A model resource's count of edits (0 for a model never edited, or of another kind). */
long iso_model_edits(const char *resource);
/* A resource's topology_version (0: it has none, its figures are its version's). */
long iso_model_topology(const char *resource);

#endif
