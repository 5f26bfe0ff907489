/* matrix_json.h - matrix models as JSON (API.md §Matrix models, seed 003): the request of POST
 * /model, the model resource of its mesh, and the six matrices POST /matrix-model answers.
 *
 *   {"name": "part", "matrix_model": {"size": [N, M, K], "bounds": [[x0, y0, z0], [x1, y1, z1]],
 *    "M0": [[..M..], ..K rows..], "M1": K x N, "M2": M x N, "M3": K x M, "M4": K x N, "M5": M x N},
 *    "mesher": "fragments" (the default: seed 003's corner fragments) | "chamfer" (every voxel centre kept)}
 *
 * Errors are 422s whose pointer names the member, the matrix, or the element
 * ("/matrix_model/M0/7/12"); matrices that contradict each other name the element whose voxel the
 * others exclude. */
#ifndef SURFD_MATRIX_JSON_H
#define SURFD_MATRIX_JSON_H

#include <stdbool.h>
#include <stddef.h>

#include "../core/base/err.h"
#include "../core/matrix/matrix.h"

/* Voxels a matrix model of a request may have (the mask takes a byte a voxel). */
#define MATRIX_JSON_MAX_VOXELS (1u << 27)

struct matrix_request {
    char name[128];
    struct matrix_model mm;
    bool chamfer;            /* "mesher": "chamfer" (matrix_mesh); else "fragments", the seed's (matrix_fragments) */
};

/* Parses and checks a request (shapes, elements in [0, the line's length], the voxel cap): 0, or
 * SF_EFORMAT (not JSON), SF_EINVAL, SF_ELIMIT with the pointer. */
int matrix_parse(const char *buf, size_t len, struct matrix_request *r, struct sf_err *err);
void matrix_request_free(struct matrix_request *r);

/* The voxels, the mesh and their figures of a parsed request: 0, or SF_EINVAL (contradicting
 * matrices, at the element), SF_ENOMEM. *vox (the caller frees) may be NULL when not wanted. */
int matrix_build(const struct matrix_request *r, struct trimesh *m, struct matrix_stats *st, double *mesh_ms,
                 struct sf_err *err);

/* The model resource (caller frees): id, the mesh figures, the counts, timings (mesh: the mesher on
 * the voxels; build: from the body to the figures). */
char *matrix_model_json(const char *id, const struct matrix_request *r, const struct trimesh *m,
                        const struct trimesh_stats *ts, const struct matrix_stats *st, double mesh_ms, double build_ms,
                        double total_ms, struct sf_err *err);

/* A voxel set's six matrices as a request ({"name", "matrix_model": {...}, "exact"}; exact: the
 * matrices give the set back), caller frees. */
char *matrix_json_of_voxels(const char *name, const int n[3], const double lo[3], const double hi[3],
                            const uint8_t *vox, struct sf_err *err);

/* The matrices of a volume as volume_read gives it (samples >= iso are the body, each voxel centred
 * on its sample; an FRep's grid sampled), caller frees; NULL with err (SF_ELIMIT at ?dims). */
struct volume;
char *matrix_json_of_volume(const struct volume *v, struct sf_err *err);

#endif
