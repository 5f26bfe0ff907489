/* test_model_json.c - the model routes' reading and writing of stored models (model_json.c): an
 * RT Structure Set cut from a mesh at its grid's slices, however far the grid lies from 0. */
#include "../../api/mesh_io.h"
#include "../../api/model_json.h"

#include "../unit.h"

/* A tetrahedron, outward, 4 x 4 x 3 mm from (0, 0, z0) (in float32, as an isosurface's vertices). */
static char *tetra(double z0, size_t *len)
{
    float pos[12] = {0, 0, (float)z0, 4, 0, (float)z0, 0, 4, (float)z0, 0, 0, (float)(z0 + 3)};
    uint32_t tri[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    struct trimesh m = {pos, NULL, tri, 4, 4};
    char *src = NULL;
    struct sf_err err = {0};
    if (mesh_pack(&m, &src, len, &err))
        fprintf(stderr, "  mesh_pack: %s\n", err.message);
    return src;
}

static int rtstruct(const char *src, size_t len, const char *resource, size_t *out_len, struct sf_err *err)
{
    unsigned char *out = NULL;
    memset(err, 0, sizeof *err);
    *out_len = 0;
    int rc = model_rtstruct(src, len, resource, "", NULL, &out, out_len, err);
    free(out);
    return rc;
}

/* The planes at the grid's slices are counted by an integer: a grid 1e24 mm from its mesh's
 * vertices (which float32 flattened to one plane) made a double plane counter stop advancing
 * past 2^53 and write past its buffer (issue 48: 1). */
TEST(rtstruct_planes_far_from_the_grid)
{
    size_t len, out_len;
    struct sf_err err;
    char *src = tetra(0, &len);
    REQUIRE(src);
    CHECK(rtstruct(src, len, "{\"name\": \"t\", \"grid\": {\"spacing\": [1, 1, 1], \"origin\": [0, 0, 0]}}", &out_len, &err) == 0);
    CHECK(out_len > 0);
    free(src);
    src = tetra(1e24, &len);
    REQUIRE(src);
    int rc = rtstruct(src, len, "{\"name\": \"t\", \"grid\": {\"spacing\": [1, 1, 1], \"origin\": [0, 0, 0]}}", &out_len,
                      &err);
    CHECK(rc == 0 || rc == SF_EINVAL || rc == SF_ELIMIT);
    free(src);
}

int main(void)
{
    RUN(rtstruct_planes_far_from_the_grid);
    UNIT_END();
}
