/* mesh_io.c - mesh writers and the packed form (mesh_io.h). x86 and arm64 are little-endian, as
 * STL, our PLY and the packed form are, so floats and indices are written as they lie. */
#include "mesh_io.h"

#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Growable output buffer. */
struct out {
    char *p;
    size_t n, cap;
    bool failed;
};

static void put(struct out *o, const void *data, size_t n)
{
    if (o->failed)
        return;
    if (o->n + n > o->cap) {
        size_t cap = o->cap ? o->cap : 1 << 16;
        while (cap < o->n + n)
            cap *= 2;
        char *p = realloc(o->p, cap);
        if (!p) {
            o->failed = true;
            return;
        }
        o->p = p, o->cap = cap;
    }
    memcpy(o->p + o->n, data, n);
    o->n += n;
}

static void putf(struct out *o, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void putf(struct out *o, const char *fmt, ...)
{
    char line[1024];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    if (n >= (int)sizeof line) /* (a writer's header is longer than any line: a bug, not a truncation) */
        o->failed = true;
    put(o, line, n > 0 ? (size_t)n : 0);
}

static int done(struct out *o, char **out, size_t *len, struct sf_err *err)
{
    if (o->failed) {
        free(o->p);
        return sf_fail(err, SF_ENOMEM, "", "out of memory writing the mesh");
    }
    *out = o->p;
    *len = o->n;
    return 0;
}

const char *mesh_mime(const char *format)
{
    return !strcmp(format, "stl") ? "model/stl" : !strcmp(format, "ply") ? "application/ply"
                                              : !strcmp(format, "obj") ? "model/obj"
                                              : !strcmp(format, "vtp") ? "model/vnd.vtk.vtp+xml"
                                              : !strcmp(format, "vtk") ? "model/vnd.vtk"
                                              : !strcmp(format, "dicom-stl") ? "application/dicom"
                                              : !strcmp(format, "delta") ? "application/vnd.surfd.mesh-delta"
                                                                       : NULL;
}

/* Little-endian, whatever the host: the layout API.md fixes. */
static void put_le32(unsigned char *p, uint32_t v)
{
    p[0] = (unsigned char)v, p[1] = (unsigned char)(v >> 8), p[2] = (unsigned char)(v >> 16), p[3] = (unsigned char)(v >> 24);
}

int mesh_delta_encode(const struct trimesh *m, uint32_t from, uint32_t to, const uint32_t *removed, size_t n_removed,
                      const uint32_t *ids, size_t n_added, const uint32_t *tris, char **out, size_t *len,
                      struct sf_err *err)
{
    size_t n = 20 + 4 * n_removed + 40 * n_added;
    unsigned char *b = malloc(n), *p = b;
    if (!b)
        return sf_fail(err, SF_ENOMEM, "", "out of memory writing the mesh delta");
    memcpy(p, "SFMD", 4);
    put_le32(p + 4, from), put_le32(p + 8, to), put_le32(p + 12, (uint32_t)n_removed), put_le32(p + 16, (uint32_t)n_added);
    p += 20;
    for (size_t k = 0; k < n_removed; k++, p += 4)
        put_le32(p, removed[k]);
    for (size_t k = 0; k < n_added; k++, p += 40) {
        const uint32_t *t = &m->tri[3 * (size_t)(tris ? tris[k] : k)];
        put_le32(p, ids ? ids[k] : (uint32_t)k);
        for (int c = 0; c < 9; c++) {
            uint32_t bits;
            memcpy(&bits, &m->pos[3 * (size_t)t[c / 3] + (size_t)(c % 3)], 4);
            put_le32(p + 4 + 4 * c, bits);
        }
    }
    *out = (char *)b, *len = n;
    return 0;
}

/* n values of 4 bytes each, big-endian (legacy VTK's binary). */
static void put_be32(struct out *o, const void *v, size_t n)
{
    const unsigned char *b = v;
    for (size_t k = 0; k < n && !o->failed; k++) {
        unsigned char w[4] = {b[4 * k + 3], b[4 * k + 2], b[4 * k + 1], b[4 * k]};
        put(o, w, 4);
    }
}

/* VTK XML PolyData: points, triangles and (when the mesh has them) point normals, appended raw
 * (each array after its 64-bit byte count), the classic cell layout (offsets: each cell's end). */
static void vtp(struct out *o, const struct trimesh *m)
{
    uint64_t np = 3 * sizeof(float) * m->n_vert, nc = 3 * sizeof(int32_t) * m->n_tri, no = sizeof(int32_t) * m->n_tri;
    uint64_t at_conn = 8 + np, at_off = at_conn + 8 + nc, at_nrm = at_off + 8 + no;
    putf(o, "<?xml version=\"1.0\"?>\n<!-- surfd model mesh: mm, in the model's coordinates (DICOM patient "
            "coordinates for DICOM input) -->\n<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" "
            "header_type=\"UInt64\">\n<PolyData>\n<Piece NumberOfPoints=\"%zu\" NumberOfVerts=\"0\" NumberOfLines=\"0\" "
            "NumberOfStrips=\"0\" NumberOfPolys=\"%zu\">\n", m->n_vert, m->n_tri);
    if (m->nrm)
        putf(o, "<PointData Normals=\"Normals\"><DataArray type=\"Float32\" Name=\"Normals\" NumberOfComponents=\"3\" "
                "format=\"appended\" offset=\"%llu\"/></PointData>\n", (unsigned long long)at_nrm);
    putf(o, "<Points><DataArray type=\"Float32\" Name=\"Points\" NumberOfComponents=\"3\" format=\"appended\" "
            "offset=\"0\"/></Points>\n<Polys><DataArray type=\"Int32\" Name=\"connectivity\" format=\"appended\" "
            "offset=\"%llu\"/>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"appended\" offset=\"%llu\"/></Polys>\n"
            "</Piece>\n</PolyData>\n<AppendedData encoding=\"raw\">\n_", (unsigned long long)at_conn,
         (unsigned long long)at_off);
    put(o, &np, 8);
    put(o, m->pos, np);
    put(o, &nc, 8);
    put(o, m->tri, nc);
    put(o, &no, 8);
    for (size_t k = 0; k < m->n_tri && !o->failed; k++) {
        int32_t end = (int32_t)(3 * (k + 1));
        put(o, &end, 4);
    }
    if (m->nrm) {
        put(o, &np, 8);
        put(o, m->nrm, np);
    }
    putf(o, "\n</AppendedData>\n</VTKFile>\n");
}

/* Legacy VTK (version 3.0), binary: big-endian points, triangles, and normals when the mesh has
 * them. */
static void vtk_legacy(struct out *o, const struct trimesh *m)
{
    putf(o, "# vtk DataFile Version 3.0\nsurfd model mesh: mm, in the model's coordinates (DICOM patient coordinates "
            "for DICOM input)\nBINARY\nDATASET POLYDATA\nPOINTS %zu float\n", m->n_vert);
    put_be32(o, m->pos, 3 * m->n_vert);
    putf(o, "\nPOLYGONS %zu %zu\n", m->n_tri, 4 * m->n_tri);
    for (size_t k = 0; k < m->n_tri && !o->failed; k++) {
        uint32_t cell[4] = {3, m->tri[3 * k], m->tri[3 * k + 1], m->tri[3 * k + 2]};
        put_be32(o, cell, 4);
    }
    if (m->nrm) {
        putf(o, "\nPOINT_DATA %zu\nNORMALS Normals float\n", m->n_vert);
        put_be32(o, m->nrm, 3 * m->n_vert);
    }
    putf(o, "\n");
}

int mesh_encode(const struct trimesh *m, const char *format, char **out, size_t *len, struct sf_err *err)
{
    struct out o = {0};
    *out = NULL;
    if (!strcmp(format, "stl")) {
        char head[80] = "surfd model mesh (binary STL), mm, model coords (DICOM input: patient coords)";
        uint32_t n = (uint32_t)m->n_tri;
        put(&o, head, 80);
        put(&o, &n, 4);
        for (size_t k = 0; k < m->n_tri; k++) {
            const float *p[3];
            for (int i = 0; i < 3; i++)
                p[i] = m->pos + 3 * (size_t)m->tri[3 * k + i];
            double u[3], w[3];
            for (int d = 0; d < 3; d++)
                u[d] = (double)p[1][d] - p[0][d], w[d] = (double)p[2][d] - p[0][d];
            double nr[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
            double l = sqrt(nr[0] * nr[0] + nr[1] * nr[1] + nr[2] * nr[2]);
            float f[12];
            for (int d = 0; d < 3; d++)
                f[d] = (float)(l > 0 ? nr[d] / l : 0);
            for (int i = 0; i < 3; i++)
                memcpy(f + 3 + 3 * i, p[i], 3 * sizeof *f);
            put(&o, f, sizeof f);
            put(&o, "\0\0", 2);
        }
    } else if (!strcmp(format, "ply")) {
        putf(&o, "ply\nformat binary_little_endian 1.0\ncomment surfd model mesh, mm, in the model's coordinates (DICOM patient coordinates for DICOM input)\nelement vertex %zu\n"
                 "property float x\nproperty float y\nproperty float z\nelement face %zu\n"
                 "property list uchar int vertex_indices\nend_header\n", m->n_vert, m->n_tri);
        put(&o, m->pos, 3 * sizeof *m->pos * m->n_vert);
        for (size_t k = 0; k < m->n_tri; k++) {
            put(&o, "\3", 1);
            put(&o, m->tri + 3 * k, 3 * sizeof *m->tri);
        }
    } else if (!strcmp(format, "vtp")) {
        vtp(&o, m);
    } else if (!strcmp(format, "vtk")) {
        vtk_legacy(&o, m);
    } else {
        putf(&o, "# surfd model mesh, mm, in the model's coordinates (DICOM patient coordinates for DICOM input)\n");
        for (size_t k = 0; k < m->n_vert; k++)
            putf(&o, "v %.9g %.9g %.9g\n", m->pos[3 * k], m->pos[3 * k + 1], m->pos[3 * k + 2]);
        for (size_t k = 0; k < m->n_tri; k++)
            putf(&o, "f %u %u %u\n", m->tri[3 * k] + 1, m->tri[3 * k + 1] + 1, m->tri[3 * k + 2] + 1);
    }
    return done(&o, out, len, err);
}

static const char MAGIC[8] = "SFMESH1\n";

bool mesh_is_packed(const char *src, size_t len) { return len >= 32 && !memcmp(src, MAGIC, 8); }

size_t mesh_packed_triangles(const char *src, size_t len)
{
    uint64_t nt;
    if (!mesh_is_packed(src, len))
        return 0;
    memcpy(&nt, src + 16, sizeof nt);
    return nt < SIZE_MAX ? (size_t)nt : SIZE_MAX;
}

/* head[2]'s bits: normals follow the positions; triangle ids (and the version they are of)
 * follow the triangles. */
#define PACKED_NORMALS 1u
#define PACKED_IDS 2u

int mesh_pack_ids(const struct trimesh *m, const uint32_t *ids, uint64_t version, char **out, size_t *len,
                  struct sf_err *err)
{
    struct out o = {0};
    uint64_t head[3] = {m->n_vert, m->n_tri, (m->nrm ? PACKED_NORMALS : 0) | (ids ? PACKED_IDS : 0)};
    put(&o, MAGIC, 8);
    put(&o, head, sizeof head);
    put(&o, m->pos, 3 * sizeof *m->pos * m->n_vert);
    if (m->nrm)
        put(&o, m->nrm, 3 * sizeof *m->nrm * m->n_vert);
    put(&o, m->tri, 3 * sizeof *m->tri * m->n_tri);
    if (ids) {
        put(&o, &version, sizeof version);
        put(&o, ids, sizeof *ids * m->n_tri);
    }
    return done(&o, out, len, err);
}

int mesh_pack(const struct trimesh *m, char **out, size_t *len, struct sf_err *err)
{
    return mesh_pack_ids(m, NULL, 1, out, len, err);
}

int mesh_packed_version(const char *src, size_t len, uint64_t *version)
{
    struct mesh_packed v;
    struct sf_err err;
    int rc = mesh_packed_view(src, len, &v, &err);
    *version = v.version;
    return rc ? -1 : 0;
}

int mesh_packed_view(const char *src, size_t len, struct mesh_packed *v, struct sf_err *err)
{
    memset(v, 0, sizeof *v);
    v->version = 1;
    uint64_t head[3];
    if (!mesh_is_packed(src, len))
        return sf_fail(err, SF_EFORMAT, "", "not a packed mesh");
    memcpy(head, src + 8, sizeof head);
    uint64_t nv = head[0], nt = head[1], with_normals = (head[2] & PACKED_NORMALS) != 0, with_ids = (head[2] & PACKED_IDS) != 0;
    if (nv >= (1ull << 31) || nt >= (1ull << 32) || head[2] > 3 ||
        len != 32 + 12 * nv * (1 + with_normals) + 12 * nt + with_ids * (8 + 4 * nt))
        return sf_fail(err, SF_EFORMAT, "", "a packed mesh whose counts do not match its length");
    const unsigned char *p = (const unsigned char *)src + 32;
    v->n_vert = nv, v->n_tri = nt;
    v->pos = p, p += 12 * nv;
    v->nrm = with_normals ? p : NULL, p += 12 * nv * with_normals;
    v->tri = p, p += 12 * nt;
    if (with_ids) {
        memcpy(&v->version, p, 8);
        v->ids = p + 8;
    }
    return 0;
}

int mesh_unpack_ids(const char *src, size_t len, struct trimesh *m, uint32_t **ids, uint64_t *version,
                    struct sf_err *err)
{
    memset(m, 0, sizeof *m);
    if (ids)
        *ids = NULL;
    if (version)
        *version = 1;
    struct mesh_packed v;
    int rc = mesh_packed_view(src, len, &v, err);
    if (rc)
        return rc;
    size_t nv = v.n_vert, nt = v.n_tri;
    m->n_vert = nv, m->n_tri = nt;
    m->pos = malloc(12 * (nv ? nv : 1));
    m->nrm = v.nrm ? malloc(12 * (nv ? nv : 1)) : NULL;
    m->tri = malloc(12 * (nt ? nt : 1));
    uint32_t *id = ids ? malloc(4 * (nt ? nt : 1)) : NULL;
    if (!m->pos || !m->tri || (v.nrm && !m->nrm) || (ids && !id)) {
        trimesh_free(m);
        free(id);
        return sf_fail(err, SF_ENOMEM, "", "out of memory reading a mesh");
    }
    memcpy(m->pos, v.pos, 12 * nv);
    if (v.nrm)
        memcpy(m->nrm, v.nrm, 12 * nv);
    memcpy(m->tri, v.tri, 12 * nt);
    for (size_t k = 0; k < 3 * nt; k++)
        if (m->tri[k] >= nv) {
            trimesh_free(m);
            free(id);
            return sf_fail(err, SF_EFORMAT, "", "a packed mesh with a vertex index out of range");
        }
    if (version)
        *version = v.version;
    for (size_t k = 0; id && k < nt; k++)
        id[k] = mesh_packed_id(&v, k);
    if (ids)
        *ids = id;
    return 0;
}

int mesh_unpack(const char *src, size_t len, struct trimesh *m, struct sf_err *err)
{
    return mesh_unpack_ids(src, len, m, NULL, NULL, err);
}
