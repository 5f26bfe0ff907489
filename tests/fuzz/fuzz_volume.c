/* fuzz_volume.c - the volumes of POST /isosurface: the first line is the query (iso, dims, type,
 * spacing...), the rest the body (raw, NRRD, MetaImage, a DICOM series or an FRep object, sniffed). A volume that reads and is
 * small is polygonised too (with ?levels or ?features=sharp, by the adaptive hierarchy), and its mesh must then be a
 * closed, consistently oriented 2-manifold (the guarantee of core/iso/mc.h and adapt.h): anything
 * else aborts, so the fuzzer reports it. */
#include "../../api/volume_io.h"
#include "fuzz.h"

#define EXTRACT_MAX_SAMPLES 40000

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static bool tables;
    if (!tables) {
        iso_init();
        tables = true;
    }
    const char *body;
    size_t len;
    char *text = fuzz_request(data, size, &body, &len);
    if (!text)
        return 0;
    struct volume v;
    struct sf_err err = {0};
    if (volume_read(body, len, "", text, &v, &err) == 0) {
        if ((size_t)v.g.nx * v.g.ny * v.g.nz <= EXTRACT_MAX_SAMPLES) {
            volume_sample(&v, 0, v.g.nz);
            struct iso_opts o = volume_iso_opts(&v);
            struct trimesh m;
            struct trimesh_stats st;
            struct iso_adapt_stats as;
            int rc = volume_adaptive(&v) ? iso_extract_adaptive(&v.g, &o, v.levels, v.max_error, NULL, &m, &as, &err)
                                  : iso_extract(&v.g, &o, NULL, &m, &err);
            if (rc == 0 && trimesh_stats(&m, &st, &err) == 0 &&
                (st.boundary_edges || st.nonmanifold_edges || st.degenerate))
                abort();
            trimesh_free(&m);
        }
        volume_free(&v);
    }
    free(text);
    return 0;
}
