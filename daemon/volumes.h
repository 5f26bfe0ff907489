/* volumes.h - what the kinds that read volumes share (isosurface, matrix, edit): a stored model's
 * volume read back with its edits, the samples of FRep volume primitives and their owner check,
 * the extraction's limits on this node, and a streamed request's file mapped. */
#ifndef SURFD_VOLUMES_H
#define SURFD_VOLUMES_H

#include "../api/frep_json.h"
#include "../api/volume_io.h"
#include "../core/iso/kept.h"
#include "service.h"

/* What a triangle of an isosurface costs from its extraction to the store (the mesh, its packing
 * and its measures; 78 bytes measured on a striped field of 39 M triangles, tests/bench/RESULTS.md). */
#define ISO_BYTES_PER_TRIANGLE 80

/* A volume's extraction options with this node's limits on the output: max-triangles, and what
 * job-memory holds. */
struct iso_opts job_iso_opts(const struct service *svc, const struct volume *v);
/* The whole file at path, mapped read-only (*map NULL for an empty one): 0 or SF_EIO. */
int job_map_file(const char *path, void **map, size_t *len);

/* A model's extraction kept for its edits (core/iso/kept.h): the hierarchy (levels over 1, or
 * features) or marching cubes kept (levels 1), each holding the samples; neither: vol's samples. */
struct kept_ext {
    struct iso_adapt *a;
    struct iso_kept *k;
};

/* A part of a model's stored volume after the first applied to vol: an edit (options its region,
 * data and len its samples) into x's extraction (ed: what it redrew) or, with none, into vol's
 * samples; an iso change (options' value) x's extraction at that iso (a hierarchy: a new one), or
 * vol's iso alone. ch (NULL: not wanted): what it did by triangle id (an iso change's without
 * corners: its new mesh is read back whole). 0, or the region's or the
 * value's error (SF_EINVAL with its pointer: ?value outside the samples' range). */
int part_apply(struct service *svc, struct volume *vol, struct kept_ext *x, const char *options, const void *data,
               size_t len, struct iso_edit *ed, struct iso_change *ch, struct sf_err *err);
/* Every phase of hierarchy a's extraction, each phase's slabs on the pool's idle workers too
 * (jobq_help: an edit job's hierarchy at a new iso, or rebuilt from the store). */
void volume_adapt_run(struct service *svc, struct iso_adapt *a);
/* Model id's volume as the store keeps it, its edits applied unless edits is false (its samples in
 * vol->owned; free with volume_free), *next the seq after the last part applied: 0, or SF_ECONFLICT (the model keeps no volume
 * of samples), SF_EIO, SF_ENOMEM. */
int stored_volume(struct service *svc, const char *id, struct volume *vol, bool edits, int *next, struct sf_err *err);

/* The stored models an FRep request's volume primitives read, as float samples into r (their
 * iso into its nodes): 0, or SF_EINVAL at the primitive's pointer, SF_EIO, SF_ENOMEM. */
int frep_volumes(struct service *svc, struct frep_request *r, struct sf_err *err);
/* The one owner check of an FRep request's volume primitives, for every route that reads one:
 * each a stored isosurface model of samples that owner (NULL: anyone's) may see. 0, or SF_EINVAL
 * at the primitive's pointer (or at pointer, when not NULL), SF_EIO. */
int frep_refs_check(struct service *svc, const struct frep_request *r, const char *owner, const char *pointer,
                    struct sf_err *err);

#endif
