/* fuzz_volume.c - the volumes of POST /isosurface: the first line is the query (iso, dims, type,
 * spacing...), the rest the body (raw, NRRD, MetaImage, a DICOM series or an FRep object, sniffed). A volume that reads and is
 * small is polygonised too (with ?levels or ?features=sharp, by the adaptive hierarchy), and its mesh must then be a
 * closed, consistently oriented 2-manifold (the guarantee of core/iso/mc.h and adapt.h): anything
 * else aborts, so the fuzzer reports it. With ?region (POST /models/{id}/edit's), a sampled volume's
 * hierarchy is kept and edited by a block of its own last samples, and the edited mesh must equal
 * a fresh extraction of the edited samples, triangle for triangle. The body is also searched for a
 * detached header's data file (volume_data_file, the offline CLI's), and one found is made whole
 * with a few bytes of data (volume_attach) and read. A label map read with ?labels=all (its names
 * from NRRD segments or a NIfTI label table) gets core/iso/labels.h's surfaces: each label's must be
 * closed, oriented, no triangle of zero area, and share each triangle with the label it faces. */
#include "../../api/query.h"
#include "../../api/volume_io.h"
#include "../../core/iso/labels.h"
#include "fuzz.h"

#define EXTRACT_MAX_SAMPLES 40000

static int cmp_tri(const void *p, const void *q) { return memcmp(p, q, 9 * sizeof(float)); }

/* m's triangles as 9 floats each, turned to start at their least corner, sorted. */
static float *tri_set(const struct trimesh *m)
{
    float *t = malloc((m->n_tri + 1) * 9 * sizeof *t);
    for (size_t i = 0; t && i < m->n_tri; i++) {
        const uint32_t *v = m->tri + 3 * i;
        int r = 0;
        for (int k = 1; k < 3; k++)
            if (memcmp(m->pos + 3 * v[k], m->pos + 3 * v[r], 3 * sizeof(float)) < 0)
                r = k;
        for (int k = 0; k < 3; k++)
            memcpy(t + 9 * i + 3 * k, m->pos + 3 * v[(r + k) % 3], 3 * sizeof(float));
    }
    if (t)
        qsort(t, m->n_tri, 9 * sizeof *t, cmp_tri);
    return t;
}

/* The edit of ?region on v's kept hierarchy against a fresh extraction of the edited samples. */
static void edit_check(struct volume *v, const char *query)
{
    size_t ts = v->g.type == ISO_U8 ? 1 : v->g.type == ISO_F32 ? 4 : 2, total = ts * v->g.nx * v->g.ny * v->g.nz;
    char region[8];
    query_option(query, "region", region, sizeof region);
    int lo[3], n[3];
    struct sf_err err = {0};
    if (!region[0] || volume_region(query, &v->g, 0, lo, n, &err) == 0 || strcmp(err.pointer, ""))
        return; /* (no region, or a bad one: only the length of an empty body is wrong) */
    size_t len = ts * n[0] * n[1] * n[2];
    if (volume_region(query, &v->g, len, lo, n, &err))
        abort(); /* the region's own length must do */
    char *samples = malloc(total), *edited = malloc(total);
    memcpy(samples, v->g.samples, total);
    const char *blk = samples + total - len; /* the volume's last samples */
    struct iso_opts o = volume_iso_opts(v);
    o.keep = true;
    struct iso_adapt *a;
    struct iso_adapt_stats st;
    struct iso_edit ed;
    struct iso_grid g = v->g, bg = {n[0], n[1], n[2], v->g.type, blk, {1, 1, 1}, {0, 0, 0}};
    if (iso_adapt_begin(&g, &o, v->levels, v->max_error, &a, &err) == 0) {
        for (int p = 0; p < iso_adapt_phases(a); p++) {
            for (int k = 0; k < iso_adapt_n_slabs(a); k++)
                iso_adapt_run(a, p, k);
            iso_adapt_between(a, p);
        }
        struct trimesh live, fresh;
        if (iso_adapt_keep(a, &st, &err) == 0 && iso_adapt_edit(a, lo, &bg, &ed, &err) == 0 &&
            iso_adapt_mesh(a, &live, &st, &err) == 0) {
            memcpy(edited, samples, total);
            for (int z = 0; z < n[2]; z++)
                for (int y = 0; y < n[1]; y++)
                    memcpy(edited + ts * (lo[0] + (size_t)g.nx * (lo[1] + y + (size_t)g.ny * (lo[2] + z))),
                           blk + ts * (size_t)n[0] * (y + (size_t)n[1] * z), ts * n[0]);
            g.samples = edited;
            o.keep = false;
            if (iso_extract_adaptive(&g, &o, v->levels, v->max_error, NULL, &fresh, &st, &err) == 0) {
                float *x = tri_set(&live), *y = tri_set(&fresh);
                if (live.n_tri != fresh.n_tri || memcmp(x, y, 9 * sizeof *x * live.n_tri))
                    abort(); /* the edit drew another mesh than a fresh extraction */
                free(x), free(y);
                trimesh_free(&fresh);
            }
            trimesh_free(&live);
        }
        iso_adapt_free(a);
    }
    free(samples), free(edited);
}

/* ?labels=all: every label's surface closed (with ?closed), oriented, no triangle of zero area,
 * its triangles as many as its neighbours add up to, and the triangles the other labels say face
 * it as many as it says face them. */
static void labels_check(const struct volume *v)
{
    struct iso_labels l;
    struct sf_err err = {0};
    if (iso_labels_extract(&v->g, v->n_labels, v->closed, 0, NULL, NULL, &l, &err))
        return;
    size_t n = (size_t)v->n_labels + 1, *touch = malloc(sizeof *touch * n), *facing = calloc(n, sizeof *facing),
           *to_labels = calloc(n, sizeof *to_labels);
    bool whole = touch && facing && to_labels; /* (memory refused: no verdict) */
    for (int k = 1; whole && k <= v->n_labels; k++) {
        struct trimesh m;
        struct trimesh_stats st;
        if (iso_labels_mesh(&l, k, touch, &m, &err)) {
            whole = false;
            break;
        }
        size_t sum = 0;
        for (size_t j = 0; j < n; j++)
            sum += touch[j], facing[j] += touch[j];
        to_labels[k] = sum - touch[0];
        if (trimesh_stats(&m, &st, &err) == 0 &&
            (sum != m.n_tri || touch[k] || st.nonmanifold_edges || st.degenerate || (v->closed && st.boundary_edges)))
            abort();
        trimesh_free(&m);
    }
    for (size_t k = 1; whole && k < n; k++)
        if (facing[k] != to_labels[k])
            abort();
    free(touch), free(facing), free(to_labels);
    iso_labels_free(&l);
}

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
    char file[64]; /* a detached header's data file, as `surfd isosurface` looks for it: a name that fits, or none */
    int line = volume_data_file(body, len, file, sizeof file);
    if (line < 0 || (line && (line < 2 || strlen(file) >= sizeof file)))
        abort();
    if (line) { /* made whole with a data file of 64 bytes, as the CLI does, and read */
        static const char samples[64];
        size_t n;
        char *whole = volume_attach(body, len, line, samples, sizeof samples, &n);
        if (whole && volume_read(whole, n, "", text, &v, &err) == 0)
            volume_free(&v);
        free(whole);
    }
    if (volume_read(body, len, "", text, &v, &err) == 0) {
        if ((size_t)v.g.nx * v.g.ny * v.g.nz <= EXTRACT_MAX_SAMPLES && v.all_labels) {
            labels_check(&v);
        } else if ((size_t)v.g.nx * v.g.ny * v.g.nz <= EXTRACT_MAX_SAMPLES) {
            volume_sample(&v, 0, v.g.nz, NULL, NULL);
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
            if (volume_adaptive(&v) && !v.frep)
                edit_check(&v, text);
        }
        volume_free(&v);
    }
    free(text);
    return 0;
}
