/* matrix_json.c - matrix models as JSON with jansson (matrix_json.h). */
#include "matrix_json.h"
#include "json_in.h"
#include "volume_io.h"

#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/base/clock.h"
void matrix_request_free(struct matrix_request *r)
{
    for (int k = 0; k < 6; k++)
        free(r->mm.m[k]), r->mm.m[k] = NULL;
}

static int box(json_t *mm, struct matrix_request *r, struct sf_err *err)
{
    json_t *size = json_object_get(mm, "size"), *bounds = json_object_get(mm, "bounds");
    double total = 1;
    if (!json_is_array(size) || json_array_size(size) != 3)
        return sf_fail(err, SF_EINVAL, "/matrix_model/size", "size is [N, M, K]: voxels along x, y and z");
    for (int a = 0; a < 3; a++) {
        json_t *v = json_array_get(size, a);
        if (!json_is_integer(v) || json_integer_value(v) < 1 || json_integer_value(v) > MATRIX_MAX_SIDE)
            return sf_fail(err, SF_EINVAL, a == 0 ? "/matrix_model/size/0" : a == 1 ? "/matrix_model/size/1" : "/matrix_model/size/2",
                           "a size is a whole number from 1 to %d", MATRIX_MAX_SIDE);
        r->mm.n[a] = (int)json_integer_value(v);
        total *= r->mm.n[a];
    }
    if (total > MATRIX_JSON_MAX_VOXELS)
        return sf_fail(err, SF_ELIMIT, "/matrix_model/size", "%.0f voxels: at most %u", total, MATRIX_JSON_MAX_VOXELS);
    if (!json_is_array(bounds) || json_array_size(bounds) != 2)
        return sf_fail(err, SF_EINVAL, "/matrix_model/bounds", "bounds are [[x0, y0, z0], [x1, y1, z1]]");
    for (int c = 0; c < 2; c++) {
        json_t *corner = json_array_get(bounds, c);
        for (int a = 0; a < 3; a++) {
            json_t *v = json_array_get(corner, a);
            char p[48];
            snprintf(p, sizeof p, "/matrix_model/bounds/%d/%d", c, a);
            if (!json_is_array(corner) || json_array_size(corner) != 3 || !json_is_number(v) ||
                !isfinite(json_number_value(v)) || fabs(json_number_value(v)) > 1e9)
                return sf_fail(err, SF_EINVAL, p, "a corner is three finite numbers (mm)");
            (c ? r->mm.hi : r->mm.lo)[a] = json_number_value(v);
        }
    }
    for (int a = 0; a < 3; a++)
        if (!(r->mm.hi[a] > r->mm.lo[a])) {
            char p[48];
            snprintf(p, sizeof p, "/matrix_model/bounds/1/%d", a);
            return sf_fail(err, SF_EINVAL, p, "the second corner is above the first on every axis");
        }
    return 0;
}

int matrix_parse(const char *buf, size_t len, struct matrix_request *r, struct sf_err *err)
{
    memset(r, 0, sizeof *r);
    json_t *root;
    int rc = json_read(buf, len, &root, err);
    if (rc)
        return rc;
    json_t *mm = json_object_get(root, "matrix_model"), *name = json_object_get(root, "name");
    const char *k_;
    json_t *v_;
    if (!json_is_object(root) || !json_is_object(mm)) {
        rc = sf_fail(err, SF_EINVAL, "/matrix_model", "a matrix model is {\"matrix_model\": {\"size\", \"bounds\", \"M0\" ... \"M5\"}}");
        goto out;
    }
    json_object_foreach(root, k_, v_) {
        if (strcmp(k_, "name") && strcmp(k_, "matrix_model") && strcmp(k_, "exact") && strcmp(k_, "mesher")) { /* (exact: as /matrix-model answers) */
            char p[64];
            snprintf(p, sizeof p, "/%.40s", k_);
            rc = sf_fail(err, SF_EINVAL, p, "unknown member \"%.40s\"", k_);
            goto out;
        }
    }
    json_object_foreach(mm, k_, v_) {
        static const char *const KEYS[] = {"size", "bounds", "M0", "M1", "M2", "M3", "M4", "M5"};
        bool known = false;
        for (int k = 0; k < 8 && !known; k++)
            known = !strcmp(k_, KEYS[k]);
        if (!known) {
            char p[80];
            snprintf(p, sizeof p, "/matrix_model/%.40s", k_);
            rc = sf_fail(err, SF_EINVAL, p, "unknown member \"%.40s\"", k_);
            goto out;
        }
    }
    if (name && !json_is_string(name)) {
        rc = sf_fail(err, SF_EINVAL, "/name", "name is a string");
        goto out;
    }
    snprintf(r->name, sizeof r->name, "%s", name ? json_string_value(name) : "");
    json_t *mesher = json_object_get(root, "mesher");
    const char *how = json_is_string(mesher) ? json_string_value(mesher) : "";
    if (mesher && strcmp(how, "fragments") && strcmp(how, "chamfer")) {
        rc = sf_fail(err, SF_EINVAL, "/mesher", "mesher is \"fragments\" (the seed's, vertices at voxel corners) or "
                     "\"chamfer\" (every voxel centre kept on its side)");
        goto out;
    }
    r->chamfer = !strcmp(how, "chamfer");
    if ((rc = box(mm, r, err)))
        goto out;
    for (int k = 0; k < 6 && !rc; k++) {
        char key[4] = {'M', (char)('0' + k), 0}, p[64];
        int rows, cols, line = r->mm.n[k % 3 == 0 ? 0 : k % 3 == 1 ? 1 : 2];
        matrix_shape(r->mm.n, k, &rows, &cols);
        json_t *mat = json_object_get(mm, key);
        snprintf(p, sizeof p, "/matrix_model/%s", key);
        if (!json_is_array(mat) || (int)json_array_size(mat) != rows) {
            rc = sf_fail(err, SF_EINVAL, p, "%s is %d rows of %d elements", key, rows, cols);
            break;
        }
        if (!(r->mm.m[k] = malloc(sizeof(int) * (size_t)rows * cols))) {
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
            break;
        }
        for (int i = 0; i < rows && !rc; i++) {
            json_t *row = json_array_get(mat, (size_t)i);
            if (!json_is_array(row) || (int)json_array_size(row) != cols) {
                snprintf(p, sizeof p, "/matrix_model/%s/%d", key, i);
                rc = sf_fail(err, SF_EINVAL, p, "a row of %s has %d elements", key, cols);
                break;
            }
            for (int j = 0; j < cols; j++) {
                json_t *e = json_array_get(row, (size_t)j);
                json_int_t d = json_is_integer(e) ? json_integer_value(e) : -1;
                if (d < 0 || d > line) {
                    snprintf(p, sizeof p, "/matrix_model/%s/%d/%d", key, i, j);
                    rc = sf_fail(err, SF_EINVAL, p, "an element of %s is a whole number from 0 to %d (the line's "
                                 "length: it misses the body)", key, line);
                    break;
                }
                r->mm.m[k][(size_t)i * cols + j] = (int)d;
            }
        }
    }
out:
    json_decref(root);
    if (rc)
        matrix_request_free(r);
    return rc;
}

int matrix_build(const struct matrix_request *r, struct trimesh *m, struct matrix_stats *st, double *mesh_ms,
                 struct sf_err *err)
{
    const int *n = r->mm.n;
    memset(m, 0, sizeof *m);
    uint8_t *vox = malloc((size_t)n[0] * n[1] * n[2]);
    if (!vox)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the voxels");
    int bk, bi, bj, rc = matrix_voxels(&r->mm, vox, &bk, &bi, &bj, err);
    if (rc)
        snprintf(err->pointer, sizeof err->pointer, "/matrix_model/M%d/%d/%d", bk, bi, bj);
    double d[3];
    for (int a = 0; a < 3; a++)
        d[a] = (r->mm.hi[a] - r->mm.lo[a]) / n[a];
    struct matrix_stats counts;
    double t0 = sf_now_ms();
    if (!rc && !(rc = (r->chamfer ? matrix_mesh : matrix_fragments)(n, vox, r->mm.lo, d, m, st, err))) {
        *mesh_ms = sf_now_ms() - t0;
        matrix_counts(&r->mm, &counts);
        st->voxels = counts.voxels, st->base_voxels = counts.base_voxels, st->redundant_voxels = counts.redundant_voxels;
        if (!m->n_tri && st->dropped_voxels)
            rc = sf_fail(err, SF_EINVAL, "/mesher", "the body's voxels meet only along edges or at points, or "
                         "stand alone: the fragments keep none of its %ld voxels (\"mesher\": \"chamfer\" keeps every voxel)", st->dropped_voxels);
        else if (!m->n_tri)
            rc = sf_fail(err, SF_EINVAL, "/matrix_model", "every line misses the body: the matrices hold no voxel");
    }
    free(vox);
    return rc;
}

char *matrix_model_json(const char *id, const struct matrix_request *r, const struct trimesh *m,
                        const struct trimesh_stats *s, const struct matrix_stats *st, double mesh_ms, double build_ms,
                        double total_ms, struct sf_err *err)
{
    char self[64], mesh[96], render[96];
    snprintf(self, sizeof self, "/models/%s", id);
    snprintf(mesh, sizeof mesh, "/models/%s/mesh?format=stl", id);
    snprintf(render, sizeof render, "/models/%s/render", id);
    const struct matrix_model *mm = &r->mm;
    json_t *o = json_pack(
        "{s:s, s:s, s:s, s:I, s:I, s:f, s:f, s:I, s:I, s:I, s:I, s:[[f,f,f],[f,f,f]], s:{s:[i,i,i], s:[[f,f,f],[f,f,f]]},"
        " s:s, s:I, s:I, s:I, s:I, s:I, s:{s:f, s:f, s:f}, s:{s:s, s:s, s:s}}",
        "id", id, "name", r->name, "source", "matrix", "triangles", (json_int_t)m->n_tri, "vertices",
        (json_int_t)m->n_vert, "volume_mm3", s->volume, "area_mm2", s->area, "boundary_edges",
        (json_int_t)s->boundary_edges, "nonmanifold_edges", (json_int_t)s->nonmanifold_edges, "components",
        (json_int_t)s->components, "euler_characteristic", (json_int_t)s->euler, "bounds", s->bounds[0][0],
        s->bounds[0][1], s->bounds[0][2], s->bounds[1][0], s->bounds[1][1], s->bounds[1][2], "matrix_model", "size",
        mm->n[0], mm->n[1], mm->n[2], "bounds", mm->lo[0], mm->lo[1], mm->lo[2], mm->hi[0], mm->hi[1], mm->hi[2], "mesher",
        r->chamfer ? "chamfer" : "fragments", "voxels",
        (json_int_t)st->voxels, "base_voxels", (json_int_t)st->base_voxels, "redundant_voxels",
        (json_int_t)st->redundant_voxels, "computed_vertices", (json_int_t)st->computed_vertices, "dropped_voxels",
        (json_int_t)st->dropped_voxels, "timings_ms", "mesh", mesh_ms, "build",
        build_ms, "total", total_ms, "links", "self", self, "mesh", mesh, "render", render);
    if (o)
        json_object_set_new(o, "version", json_integer(1)); /* a matrix model is not edited */
    char *text = o ? json_dumps(o, JSON_COMPACT | JSON_REAL_PRECISION(12)) : NULL;
    json_decref(o);
    if (!text)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return text;
}

char *matrix_json_of_voxels(const char *name, const int n[3], const double lo[3], const double hi[3],
                            const uint8_t *vox, struct sf_err *err)
{
    struct matrix_model mm = {{n[0], n[1], n[2]}, {lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}, {NULL}};
    size_t nv = (size_t)n[0] * n[1] * n[2];
    uint8_t *back = malloc(nv ? nv : 1);
    json_t *o = NULL, *mat = json_object();
    bool ok = back && mat;
    for (int k = 0; k < 6 && ok; k++) {
        int rows, cols;
        matrix_shape(n, k, &rows, &cols);
        ok = (mm.m[k] = malloc(sizeof(int) * ((size_t)rows * cols + 1))) != NULL;
    }
    if (ok) {
        matrix_of_voxels(n, vox, mm.m);
        struct sf_err e2 = {0};
        int bk, bi, bj;
        bool exact = matrix_voxels(&mm, back, &bk, &bi, &bj, &e2) == 0 && !memcmp(back, vox, nv);
        json_object_set_new(mat, "size", json_pack("[i,i,i]", n[0], n[1], n[2]));
        json_object_set_new(mat, "bounds", json_pack("[[f,f,f],[f,f,f]]", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]));
        for (int k = 0; k < 6; k++) {
            int rows, cols;
            matrix_shape(n, k, &rows, &cols);
            json_t *rowsj = json_array();
            for (int i = 0; i < rows; i++) {
                json_t *row = json_array();
                for (int j = 0; j < cols; j++)
                    json_array_append_new(row, json_integer(mm.m[k][(size_t)i * cols + j]));
                json_array_append_new(rowsj, row);
            }
            char key[4] = {'M', (char)('0' + k), 0};
            json_object_set_new(mat, key, rowsj);
        }
        o = json_pack("{s:s, s:O, s:b}", "name", name ? name : "", "matrix_model", mat, "exact", exact);
    }
    char *text = o ? json_dumps(o, JSON_COMPACT) : NULL;
    json_decref(o);
    json_decref(mat);
    for (int k = 0; k < 6; k++)
        free(mm.m[k]);
    free(back);
    if (!text)
        sf_fail(err, SF_ENOMEM, "", "out of memory");
    return text;
}

char *matrix_json_of_volume(const struct volume *v, struct sf_err *err)
{
    const struct iso_grid *g = &v->g;
    size_t n = (size_t)g->nx * g->ny * g->nz;
    if (g->nx > MATRIX_MAX_SIDE || g->ny > MATRIX_MAX_SIDE || g->nz > MATRIX_MAX_SIDE || n > MATRIX_JSON_MAX_VOXELS)
        return sf_fail(err, SF_ELIMIT, "?dims", "a matrix model has at most %d voxels a side and %u in all",
                       MATRIX_MAX_SIDE, MATRIX_JSON_MAX_VOXELS), NULL;
    uint8_t *vox = malloc(n ? n : 1);
    float *row = malloc(sizeof *row * (size_t)g->nx);
    char *json = NULL;
    if (!vox || !row) {
        sf_fail(err, SF_ENOMEM, "", "out of memory for the voxels");
    } else {
        for (int z = 0; z < g->nz; z++)
            for (int y = 0; y < g->ny; y++) {
                iso_grid_row(g, y, z, row);
                for (int x = 0; x < g->nx; x++) /* samples >= iso are the body */
                    vox[(size_t)x + (size_t)g->nx * ((size_t)y + (size_t)g->ny * z)] = row[x] >= v->iso;
            }
        int dims[3] = {g->nx, g->ny, g->nz};
        double lo[3], hi[3];
        for (int a = 0; a < 3; a++) /* each voxel centred on its sample */
            lo[a] = g->origin[a] - g->spacing[a] / 2, hi[a] = lo[a] + g->spacing[a] * dims[a];
        json = matrix_json_of_voxels(v->name, dims, lo, hi, vox, err);
    }
    free(vox);
    free(row);
    return json;
}
