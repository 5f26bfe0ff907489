/* kinds.h - the one table of job kinds. A kind is named in the store (jobs.kind), so a job
 * claimed on any node, or recovered after a crash, runs as it was submitted: every kind runs
 * again from its stored request (a model job gives its models the same ids, replacing what an
 * earlier run stored). Adding a kind is one entry here (kinds.c) and its own job_*.c file.
 * The routes that submit kinds are server.c's route table. */
#ifndef SURFD_KINDS_H
#define SURFD_KINDS_H

#include <stdbool.h>
#include <stddef.h>

#include "service.h"

/* A request body as a kind's validate sees it: it may replace body (keeping only what the job
 * reads, e.g. an RT Structure Set without the patient), freeing the old one. */
struct job_body {
    char *body;
    size_t len;
    const char *format;      /* the body's format (json, bpt, nurbs, dicom); "" for a model id */
    const char *options;     /* the query as name=value&... */
    const char *owner;       /* the token's name: whose models a scene may use */
};

struct job_kind {
    const char *name;
    /* The body format a Content-Type names for this kind (NULL: the kind does not read it: 415),
     * and the types it reads, as a 415 says them. NULL format: the body is a stored model's id,
     * made by a GET route. */
    const char *(*format)(const char *content_type);
    const char *media;
    bool format_in_query;    /* ?format= overrides the Content-Type */
    /* Checks a request before it is stored: 0, or an error for a 4xx (pointer into the request). */
    int (*validate)(struct service *svc, struct job_body *b, struct sf_err *err);
    /* Puts a claimed job on the pool: 0, or -1 (the claim is then handed back). */
    int (*start)(struct service *svc, const struct job_claim *c);
    const char *result;      /* media type(s) of its result, as the contract says them */
    bool streamed;           /* the body is streamed to a file as it arrives (max-volume), not buffered */
};

/* The kind of that name, or NULL. */
const struct job_kind *job_kind(const char *name);

/* The kinds' own files (job_render.c, job_contours.c). */
const char *render_format(const char *content_type);
const char *contour_format(const char *content_type);
const char *volume_format(const char *content_type);
int render_validate(struct service *svc, struct job_body *b, struct sf_err *err);
int volume_validate(struct service *svc, struct job_body *b, struct sf_err *err);
int model_validate_body(struct service *svc, struct job_body *b, struct sf_err *err);
int mesh_validate(struct service *svc, struct job_body *b, struct sf_err *err);
int patches_validate(struct service *svc, struct job_body *b, struct sf_err *err);
int render_start(struct service *svc, const struct job_claim *c);
int volume_start(struct service *svc, const struct job_claim *c);
int model_start(struct service *svc, const struct job_claim *c);
int mesh_start(struct service *svc, const struct job_claim *c);
int patches_start(struct service *svc, const struct job_claim *c);
int rtstruct_validate(struct service *svc, struct job_body *b, struct sf_err *err);
int rtstruct_start(struct service *svc, const struct job_claim *c);
const char *iso_format(const char *content_type);
int iso_validate(struct service *svc, struct job_body *b, struct sf_err *err);
int iso_start(struct service *svc, const struct job_claim *c);
/* What a triangle of an isosurface costs from its extraction to the store (the mesh, its packing
 * and its measures; 78 bytes measured on a striped field of 39 M triangles, tests/bench/RESULTS.md). */
#define ISO_BYTES_PER_TRIANGLE 80
/* A volume's extraction options with this node's limits on the output: max-triangles, and what
 * job-memory holds (job_iso.c). */
struct volume;
struct iso_opts job_iso_opts(const struct service *svc, const struct volume *v);
/* The whole file at path, mapped read-only (*map NULL for an empty one): 0 or -1 (job_iso.c). */
int job_map_file(const char *path, void **map, size_t *len);
int matrix_validate(struct service *svc, struct job_body *b, struct sf_err *err);
int matrix_start(struct service *svc, const struct job_claim *c);
const char *edit_format(const char *content_type);
int edit_validate(struct service *svc, struct job_body *b, struct sf_err *err);
int edit_start(struct service *svc, const struct job_claim *c);
/* job_edit.c: an isosurface job's kept hierarchy a (iso_adapt_keep; NULL: none) for the model's
 * edits, with its volume's settings (not its samples); a is taken (freed when it does not fit). */
struct volume;
struct iso_adapt;
void edit_keep(struct service *svc, const char *id, const struct volume *vol, struct iso_adapt *a);
/* Model id's volume as the store keeps it, its edits applied (its samples in vol->owned; free with
 * volume_free), *next the seq after its last edit: 0, or SF_ECONFLICT (the model keeps no volume
 * of samples), SF_EIO, SF_ENOMEM. */
int edit_volume(struct service *svc, const char *id, struct volume *vol, int *next, struct sf_err *err);
/* The stored models an FRep request's volume primitives read, as float samples into r (their
 * iso into its nodes): 0, or SF_EINVAL at the primitive's pointer, SF_EIO, SF_ENOMEM. */
struct frep_request;
int frep_volumes(struct service *svc, struct frep_request *r, struct sf_err *err);
/* The one owner check of an FRep request's volume primitives (job_iso.c), for every route that
 * reads one: each a stored isosurface model of samples that owner (NULL: anyone's) may see. 0, or
 * SF_EINVAL at the primitive's pointer (or at pointer, when not NULL), SF_EIO. */
int frep_refs_check(struct service *svc, const struct frep_request *r, const char *owner, const char *pointer,
                    struct sf_err *err);

#endif
