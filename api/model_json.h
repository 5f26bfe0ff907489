/* model_json.h - contours in, models out: the figures of API.md's model resource (name, method,
 * caps, slices, patches, volume_mm3, area_mm2, volume {exact, quadrature, trapezoid, cavalieri,
 * frustum}, bounds, timings_ms, ...), stored models' sources, and what is made from a stored model:
 * meshes, patch lists, scene objects. The CLI, the volume and model jobs and the model routes share
 * these. Requests are "json" (contour JSON) or "dicom" (an RT Structure Set; options
 * "roi=NAME&caps=flat|slab|dome"). */
#ifndef SURFD_MODEL_JSON_H
#define SURFD_MODEL_JSON_H

#include <stdbool.h>
#include <stddef.h>

#include "../core/base/err.h"
#include "../core/trace/scene.h"
#include "contour_json.h"
#include "seg.h"

/* Reads contours, builds the model and measures it; *json receives the figures (caller frees): one
 * object for JSON or for a DICOM ?roi=NAME, else {"models": [...]} with one object per ROI. Errors
 * as contour_parse_json and rtstruct_read. A scene (format bpt or nurbs, or JSON with "objects" or
 * "patches" and no "slices") is measured as it is: the volume its patches enclose, refused (with the
 * object's pointer) when they do not close edge to edge or face both ways. */
int model_figures(const char *buf, size_t len, const char *format, const char *options,
                  const struct sf_progress *pr, char **json, struct sf_err *err);
/* Whether a body is a scene (format bpt or nurbs, or JSON with "objects" or "patches" and no
 * "slices") rather than contours (JSON, DICOM). */
bool model_body_is_scene(const char *buf, size_t len, const char *format);
/* What model_figures would refuse, without modelling anything (for request handlers). */
int model_validate(const char *buf, size_t len, const char *format, const char *options, struct sf_err *err);

/* Where model_create keeps the models it makes. id(k) names the k-th model of the request (the same
 * request must get the same ids, so that a job run again after a crash replaces what it stored);
 * put stores one: its source (contour JSON, model_source) and its resource JSON. -1: the store failed.
 * Without id (NULL), models get no id or links and put sees id "" (offline, the CLI). */
struct model_sink {
    void (*id)(void *ctx, int k, char id[40]);
    int (*put)(void *ctx, const char *id, const char *name, const char *source, size_t source_len, const char *resource);
    void *ctx;
};
/* As model_figures, and each model gets an id and links and is put in the sink; location receives
 * /models/{id} of the first. pr (may be NULL) is polled while modelling (err.h). */
int model_create(const char *buf, size_t len, const char *format, const char *options, const struct model_sink *sink,
                 const struct sf_progress *pr, char **json, char location[64], struct sf_err *err);

/* A stored model's mesh; options "format=stl|ply|obj|vtp|vtk|dicom-stl|delta&tolerance=MM": binary STL
 * (the default), binary little-endian PLY, OBJ, VTK, the STL as a DICOM Encapsulated STL
 * (referencing the study and frame of reference resource names, when it does; resource may be
 * NULL), or the whole mesh as a delta from version 0 to the model's (mesh_io.h: every triangle
 * added, its id its place), within the tolerance (absent or 0: the coarsest that holds the model's volume within
 * 0.05 %, solid_mesh_default). *out (caller frees), *out_len and *mime receive the file, *tol_used
 * the tolerance (0 for an isosurface: its own mesh). */
/* A model's version (its resource's "version"; 1 + its edits for a resource written before it). */
long model_version(const char *resource);
int model_mesh(const char *src, size_t len, const char *resource, const char *options, const struct sf_progress *pr,
               char **out, size_t *out_len, const char **mime, double *tol_used, struct sf_err *err);
/* A stored model (resource: its resource JSON) as a DICOM RT Structure Set of one ROI: the mesh at
 * the default tolerance cut by planes - a contour model's own slices, or ?spacing=MM apart (an
 * isosurface: its grid's slices by default) - into CLOSED_PLANAR contours in patient coordinates,
 * referencing the source's study and frame of reference where it came from one (else fresh UIDs).
 * *out (caller frees) receives the DICOM Part 10 object. */
int model_rtstruct(const char *src, size_t len, const char *resource, const char *options,
                   const struct sf_progress *pr, unsigned char **out, size_t *out_len, struct sf_err *err);
/* Several stored models as one RT Structure Set (GET /rtstruct?models=), model k as ROI k + 1: named
 * by its name, coloured and typed as its source structure set said (else a palette by ROI number,
 * and a type by its name: api/README.md), in the one frame of reference and study its models share
 * (refused at ?models when two differ), referencing the first model's series and images. Each
 * mesh cut as model_rtstruct does, holes joined into their outer contours (keyhole.h). Errors
 * name the model; model_rtstruct is this for one. */
#define MODEL_RTSTRUCT_MAX_MODELS 256 /* ROIs of one export: a plan's structure set has tens */
struct model_export {
    const char *id, *src;    /* borrowed for the call */
    size_t len;
    const char *resource;
};
int model_rtstruct_set(const struct model_export *m, int n, const char *options, const struct sf_progress *pr,
                       unsigned char **out, size_t *out_len, struct sf_err *err);
/* Stored models as one DICOM Segmentation (?format=seg on GET /rtstruct and /models/{id}/mesh; seg.h),
 * model k as segment k + 1, labelled, coloured and typed as model_rtstruct_set names its ROIs: each
 * mesh cut at grid g's slices and its sections' pixels set by the even-odd rule (a voxel is the
 * model's when its centre is inside), a frame where a slice holds any. g (model_seg_grid's) is
 * borrowed. Errors name the model where several are listed. */
int model_seg_set(const struct model_export *m, int n, const struct seg_grid *g, const struct sf_progress *pr,
                  unsigned char **out, size_t *out_len, struct sf_err *err);
/* The series a model's resource names (referenced_series: the CT its structure set was drawn on,
 * or the series an isosurface was made of) into uid, or false. */
bool model_seg_series(const char *resource, char uid[65]);
/* A stored series' grid from its n instances (their SOP Instance UIDs and store metas:
 * series_json.h's instance_meta), laid out as planes.h lays out a posted series' slices; study and
 * frame the series'. 0, or SF_EINVAL at ?format saying why the series is not one grid. */
int model_seg_series_grid(const char *series_uid, const char *study_uid, const char *const *sop_uids,
                          const char *const *metas, int n, struct seg_grid *g, struct sf_err *err);
/* The grid an export of these models is made on (api/README.md, "DICOM SEG out"): ?spacing=MM
 * isotropic voxels over the models' bounds; else the stored series' (series: NULL when none of
 * the models' series is stored); else the first isosurface model's own grid; else SF_EINVAL at
 * ?format saying which series to store. Refused when it would hold over SEG_MAX_BITS bits with n
 * segments (SF_ELIMIT, before anything is made), or when the series' frame of reference is not
 * the models'. g (caller frees with seg_grid_free) receives it; a series' grid is copied. */
int model_seg_grid(const char *const *ids, const char *const *resources, int n, const struct seg_grid *series,
                   const char *options, struct seg_grid *g, struct sf_err *err);

/* What model_rtstruct_set would refuse of its models before cutting them (for the route): 1 to
 * MODEL_RTSTRUCT_MAX_MODELS, none listed twice, one frame of reference and one study (models
 * without, as contours in JSON, go with any). Errors point at ?models and name the models. */
int model_rtstruct_check(const char *const *ids, const char *const *resources, int n, struct sf_err *err);
/* What model_rtstruct would refuse in its options (?spacing). */
int model_rtstruct_options(const char *options, double *spacing, struct sf_err *err);
/* The cache key of a mesh request's options for a model after edits edits ("stl default e0",
 * "ply 0.05 e2": a mesh made before an edit never matches after it), or their error. */
int model_mesh_key(const char *options, long edits, char *key, size_t cap, struct sf_err *err);
/* What model_mesh would refuse in its options (errors point at ?format, ?tolerance). */
int model_mesh_options(const char *options, const char **format, double *tol, struct sf_err *err);
/* A stored model's patches as a scene: {"objects": [...]}: bicubic "bezier" objects, and the domes'
 * rational patches as single-span "nurbs" objects. */
int model_patches_json(const char *src, size_t len, char **json, struct sf_err *err);
/* Appends a stored model's patches to a scene as objects of material mat. */
int model_scene_objects(const char *src, size_t len, struct scene *sc, const struct material *mat, const char *where,
                        struct sf_err *err);

#endif
