/* kinds.h - the job kinds. A kind is named in the store (jobs.kind), so a job claimed on any node,
 * or recovered after a crash, runs as it was submitted: every kind runs again from its stored
 * request (a model job gives its models the same ids, replacing what an earlier run stored).
 *
 * Each kind's own file (job_*.c) defines its `const struct job_kind`: how its requests are read
 * and checked, and the ops the pool runs it with; the routes (server.c's table) point at them, and
 * kinds.c lists them for the jobs the store hands back by name. Adding a kind is its file, a line
 * in kinds.c and its route. What the kinds that read volumes share is volumes.h. */
#ifndef SURFD_KINDS_H
#define SURFD_KINDS_H

#include <stdbool.h>
#include <stddef.h>

#include "../api/formats.h"
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

/* What every kind's work begins with: job_start fills it, the kind's ops take the rest from the
 * store (the request) and free the whole in their finish. */
struct job_work {
    struct service *svc;
    struct job_claim claim;
};

struct job_kind {
    const char *name;
    /* The body format a Content-Type names for this kind (NULL: the kind does not read it: 415),
     * and the route whose formats it reads (api/formats.h: its ?format= names, the types a 415
     * lists). NULL format: the body is made by a route (a stored model's id, or a scene naming it). */
    const char *(*format)(const char *content_type);
    unsigned route;
    bool format_in_query;    /* ?format= overrides the Content-Type, by any name formats.h gives it */
    /* Checks a request before it is stored, on the checks pool: 0, or an error for a 4xx (its
     * pointer into the request). */
    int (*validate)(struct service *svc, struct job_body *b, struct sf_err *err);
    /* How the pool runs it (jobq.h), on a work of work_size bytes that begins with struct job_work. */
    const struct job_ops *ops;
    size_t work_size;
    const char *result;      /* media type(s) of its result, as the contract says them */
    bool streamed;           /* the body is streamed to a file as it arrives (max-volume), not buffered */
    /* The request is answered by its validate alone, on the checks pool (its body then the answer,
     * of type result), and never stored: a PACS search, whose answer names patients (ops NULL). */
    bool transient;
};

/* The kinds, each defined in its own file. */
extern const struct job_kind render_kind;                 /* job_render.c */
extern const struct job_kind volume_kind, model_kind;     /* job_contours.c: contours (and scenes' volumes) */
extern const struct job_kind mesh_kind, patches_kind, rtstruct_kind; /* job_contours.c: a stored model's outputs */
extern const struct job_kind delta_kind;                 /* job_contours.c: a delta across a whole change */
extern const struct job_kind isosurface_kind;             /* job_iso.c */
extern const struct job_kind matrix_kind;                 /* job_matrix.c */
extern const struct job_kind edit_kind, iso_kind;         /* job_edit.c: an edit of a model's samples or FRep
                                                          * object, and of its iso (a job of the edit kind) */
extern const struct job_kind pull_kind, query_kind;       /* job_pacs.c: a PACS's series pulled, its studies searched */
extern const struct job_kind send_kind;                   /* job_contours.c: a model sent to a PACS */

/* The kind of that name (a stored job's), or NULL. */
const struct job_kind *job_kind(const char *name);
/* Puts a claimed job on the pool as its kind runs it: 0, or SF_ENOTFOUND (no kind of its name),
 * SF_ENOMEM, SF_ELIMIT (the pool takes no more: shutting down); the claim is then the caller's to
 * hand back. */
int job_start(struct service *svc, const struct job_claim *c);

#endif
