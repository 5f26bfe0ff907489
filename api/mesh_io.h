/* mesh_io.h - triangle meshes out: STL (binary), PLY (binary little-endian) and OBJ, for every
 * kind of model; and the compact form a mesh model (an isosurface) is stored in. */
#ifndef SURFD_MESH_IO_H
#define SURFD_MESH_IO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "../core/base/err.h"
#include "../core/geom/trimesh.h"

/* "stl", "ply" or "obj" to its media type; NULL for another. */
const char *mesh_mime(const char *format);
/* m in format into *out (caller frees). 0, or SF_ENOMEM. */
int mesh_encode(const struct trimesh *m, const char *format, char **out, size_t *len, struct sf_err *err);

/* A mesh delta (API.md, "Interactive isosurfaces": "SFMD", from and to versions, the ids removed,
 * then each triangle added: its id and its three corners, float32 little-endian): n_added of m's
 * triangles, tris[k] (NULL: k) with id ids[k] (NULL: k). 0, or SF_ENOMEM. */
int mesh_delta_encode(const struct trimesh *m, uint32_t from, uint32_t to, const uint32_t *removed, size_t n_removed,
                      const uint32_t *ids, size_t n_added, const uint32_t *tris, char **out, size_t *len,
                      struct sf_err *err);

/* The stored form: "SFMESH1\n", vertex and triangle counts (uint64), whether normals follow
 * (uint64), then float32 positions, float32 normals, uint32 triangles, little-endian. */
int mesh_pack(const struct trimesh *m, char **out, size_t *len, struct sf_err *err);
/* The same with each triangle's id (core/iso/kept.h) and the model's version they are of, after the
 * triangles (the fourth header word's bit 2; bit 1: normals). */
int mesh_pack_ids(const struct trimesh *m, const uint32_t *ids, uint64_t version, char **out, size_t *len,
                  struct sf_err *err);
bool mesh_is_packed(const char *src, size_t len);
/* The triangles a packed mesh declares (what unpacking it will cost; mesh_unpack checks them). */
size_t mesh_packed_triangles(const char *src, size_t len);
/* Reads a packed mesh (checking its counts against its length): 0, or SF_EFORMAT, SF_ENOMEM. */
int mesh_unpack(const char *src, size_t len, struct trimesh *m, struct sf_err *err);
/* The version a packed mesh is of (1 when packed without ids): 0, or -1 (not one). */
int mesh_packed_version(const char *src, size_t len, uint64_t *version);
/* With its ids (NULL: not wanted; a mesh packed without them: 0 .. n-1) and version (1 when
 * packed without ids): caller frees *ids. */
int mesh_unpack_ids(const char *src, size_t len, struct trimesh *m, uint32_t **ids, uint64_t *version,
                    struct sf_err *err);
/* A packed mesh's arrays where they lie in src, not copied (what reads it once needs no copy: a
 * delta of 30 MB made from it without 19 MB of copies first). ids NULL when packed without them (0
 * .. n-1), nrm without normals. Its counts are checked against its length; its vertex indices are
 * not (a reader checks each against n_vert). 0, or SF_EFORMAT. */
struct mesh_packed {
    const unsigned char *pos, *nrm, *tri, *ids; /* host order, as packed; each may be unaligned */
    uint64_t n_vert, n_tri, version;
};
int mesh_packed_view(const char *src, size_t len, struct mesh_packed *v, struct sf_err *err);
/* Triangle t's corner k's vertex and id in v. */
static inline uint32_t mesh_packed_corner(const struct mesh_packed *v, size_t t, int k)
{
    uint32_t i;
    memcpy(&i, v->tri + 12 * t + 4 * (size_t)k, 4);
    return i;
}
static inline uint32_t mesh_packed_id(const struct mesh_packed *v, size_t t)
{
    uint32_t id = (uint32_t)t;
    if (v->ids)
        memcpy(&id, v->ids + 4 * t, 4);
    return id;
}

#endif
