/* model_matrix.c - a matrix model (matrix_json.h) made a model: its figures for POST /volume and
 * surfd volume, and the model stored for POST /models. */
#include "model_json_internal.h"

#include <jansson.h>
#include <stdlib.h>

#include "../core/base/clock.h"
#include "matrix_json.h"
#include "mesh_io.h"

/* A matrix model's mesh and resource (id "" when it is not stored: POST /volume), and with a sink
 * the model stored as its packed mesh. */
int matrix_model(const char *buf, size_t len, const struct model_sink *sink, char **json, char location[64],
                 struct sf_err *err)
{
    double t0 = sf_now_ms();
    struct matrix_request r;
    int rc = matrix_parse(buf, len, &r, err);
    if (rc)
        return rc;
    struct trimesh m;
    struct matrix_stats st;
    struct trimesh_stats ts;
    char id[40] = "", *packed = NULL;
    size_t packed_len = 0;
    double mesh_ms = 0;
    if (!(rc = matrix_build(&r, &m, &st, &mesh_ms, err)))
        rc = trimesh_stats(&m, &ts, err);
    double t1 = sf_now_ms();
    if (!rc && sink && sink->id)
        sink->id(sink->ctx, 0, id);
    if (!rc && !(*json = matrix_model_json(id, &r, &m, &ts, &st, mesh_ms, t1 - t0, sf_now_ms() - t0, err)))
        rc = err->code;
    if (!rc && sink && !(rc = mesh_pack(&m, &packed, &packed_len, err)) &&
        sink->put(sink->ctx, id, r.name, packed, packed_len, *json))
        rc = sf_fail(err, SF_EIO, "", "the store could not keep the model");
    if (location)
        snprintf(location, 64, "/models/%s", id);
    free(packed);
    trimesh_free(&m);
    matrix_request_free(&r);
    return rc;
}

