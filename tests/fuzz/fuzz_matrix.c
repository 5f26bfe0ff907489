/* fuzz_matrix.c - matrix models (api/matrix_json.h): parse and check; a model that reads and is
 * small is also meshed by both meshers (the model job's whole path), and each mesh must then be a closed,
 * consistently oriented mesh without degenerate triangles (the guarantee of core/matrix/matrix.h):
 * anything else aborts, so the fuzzer reports it. */
#include "../../api/matrix_json.h"
#include "fuzz.h"

#define MESH_MAX_VOXELS 20000

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct matrix_request r;
    struct sf_err err = {0};
    if (matrix_parse((const char *)data, size, &r, &err))
        return 0;
    if ((long)r.mm.n[0] * r.mm.n[1] * r.mm.n[2] <= MESH_MAX_VOXELS) {
        for (int chamfer = 0; chamfer < 2; chamfer++) { /* both meshers, whichever the body asked for */
            struct trimesh m;
            struct matrix_stats st;
            struct trimesh_stats ts;
            double ms;
            r.chamfer = chamfer;
            if (matrix_build(&r, &m, &st, &ms, &err) == 0) {
                if (trimesh_stats(&m, &ts, &err) == 0 && (ts.boundary_edges || ts.nonmanifold_edges || ts.degenerate))
                    abort();
                trimesh_free(&m);
            }
        }
    }
    matrix_request_free(&r);
    return 0;
}
