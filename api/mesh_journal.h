/* mesh_journal.h - a model's mesh as the store keeps it once edited (issue 45): a base (a packed
 * mesh with its triangle ids and the version it is of, mesh_io.h) and a journal of changes, one a
 * version, each the ids a change took out and the triangles it put in (core/iso/kept.h). From them:
 * the current mesh (the base with the changes applied) and the delta of API.md ("SFMD") from any
 * version the journal still covers.
 *
 * A change as stored, little-endian: "SFMC", u32 version (the one it makes), u32 n_removed,
 * u32 n_added, n_removed x u32 id, n_added x (u32 id, 18 x f32: each corner's x y z nx ny nz).
 *
 * A whole change (every triangle taken out, the new ones numbered on: a new iso, or an edit that
 * moves the samples' least and with it the closed grid's pad) is stored with a new base of its
 * version, which holds its triangles: "SFMW", the same counts, n_removed x u32 id, n_added x u32
 * id. (Journaled with corners it would be some 76 bytes a triangle, twice the base's, and the
 * base compacted at once.) A delta across one is every triangle of the current mesh added. */
#ifndef SURFD_MESH_JOURNAL_H
#define SURFD_MESH_JOURNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "../core/base/err.h"
#include "../core/iso/kept.h"

/* One stored change: its bytes. */
struct mesh_change {
    const void *data;
    size_t len;
};

/* Change ch (what version makes) in the stored layout (*out: caller frees). 0 or SF_ENOMEM. */
int mesh_change_encode(const struct iso_change *ch, uint32_t version, char **out, size_t *len, struct sf_err *err);
/* Change ch as a whole change (ids only: its triangles are in the base of its version). */
int mesh_change_encode_whole(const struct iso_change *ch, uint32_t version, char **out, size_t *len,
                             struct sf_err *err);
/* The version a stored change makes (0: not a change). */
uint32_t mesh_change_version(const void *data, size_t len);
/* Whether a stored change is a whole change. */
bool mesh_change_whole(const void *data, size_t len);

/* The delta from version from to version to of changes ch[0 .. n-1] (versions from+1 .. to, in
 * order): a triangle added and taken out again between them is in neither list. With a whole
 * change among them the triangles added are the current mesh's, mesh (packed with its ids, of
 * version to; NULL when no change is whole). 0, or SF_EFORMAT (a change damaged or out of order,
 * a whole one without the mesh, or the mesh not what the changes leave), SF_ENOMEM. */
int mesh_changes_delta(const struct mesh_change *ch, size_t n, uint32_t from, uint32_t to, const char *mesh,
                       size_t mesh_len, char **out, size_t *len, struct sf_err *err);

/* The packed base (mesh_pack_ids; one packed without ids is version 1, ids 0 .. n-1) with
 * changes ch[0 .. n-1] (its version + 1 on, in order) applied: packed again with its ids and the
 * last change's version. The triangles added share the vertices of equal position and normal.
 * 0, or SF_EFORMAT (the changes do not follow the base, name a triangle it does not have, or one
 * is whole: a base follows it), SF_ENOMEM. */
int mesh_changes_apply(const char *base, size_t base_len, const struct mesh_change *ch, size_t n, char **out,
                       size_t *len, struct sf_err *err);

#endif
