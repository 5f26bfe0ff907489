/* fuzz_kept.c - marching cubes kept (core/iso/kept.h, issue 45): a small volume of any type from
 * the input's bytes, then a run of edits and iso changes from the rest; after each the kept mesh
 * must equal a fresh extraction triangle for triangle (positions and normals) and be closed when
 * the grid is: anything else aborts, so the fuzzer reports it. Under the torture build every
 * allocation refused must end cleanly (a failed change leaves the extraction to be freed). */
#include "../../core/iso/kept.h"
#include "fuzz.h"

/* Aborts when k's mesh is not g's fresh one at o (nothing checked when memory runs out). */
static void check(const struct iso_kept *k, const struct iso_grid *g, const struct iso_opts *o)
{
    struct trimesh a, b;
    uint32_t *ids;
    struct sf_err err = {0};
    if (iso_extract(g, o, NULL, &a, &err))
        return;
    if (iso_kept_mesh(k, &b, &ids, &err)) {
        trimesh_free(&a);
        return;
    }
    size_t differ;
    struct trimesh_stats st;
    if (!trimesh_differ(&a, &b, &differ) && differ)
        abort();
    for (size_t i = 1; i < b.n_tri; i++)
        if (ids[i - 1] >= ids[i])
            abort();
    if (o->closed && trimesh_stats(&b, &st, &err) == 0 && (st.boundary_edges || st.nonmanifold_edges))
        abort();
    free(ids);
    trimesh_free(&a);
    trimesh_free(&b);
}

/* A sample of type t from byte b, into p[i]. */
static void put(void *p, enum iso_type t, size_t i, uint8_t b)
{
    switch (t) {
    case ISO_U8: ((uint8_t *)p)[i] = b; break;
    case ISO_I16: ((int16_t *)p)[i] = (int16_t)((b - 128) * 8); break;
    case ISO_U16: ((uint16_t *)p)[i] = (uint16_t)(b * 4); break;
    default: ((float *)p)[i] = (float)(b - 128) / 16.0f;
    }
}

static double iso_of(enum iso_type t, uint8_t b)
{
    return t == ISO_U8 ? b + 0.5 : t == ISO_I16 ? (b - 128) * 8 + 0.5 : t == ISO_U16 ? b * 4 + 0.5 : (b - 128) / 16.0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 5)
        return 0;
    int dims[3] = {2 + data[0] % 9, 2 + data[1] % 9, 2 + data[2] % 9};
    enum iso_type type = (enum iso_type)(data[3] & 3);
    size_t es = type == ISO_U8 ? 1 : type == ISO_F32 ? 4 : 2, n = (size_t)dims[0] * dims[1] * dims[2], at = 5;
    struct iso_opts o = {.iso = iso_of(type, data[4]), .closed = data[3] >> 2 & 1, .normals = data[3] >> 3 & 1};
    void *vol = calloc(n, es);
    if (!vol)
        return 0;
    for (size_t i = 0; i < n; i++)
        put(vol, type, i, at < size ? data[at++] : (uint8_t)(i * 37));
    struct iso_grid g = {dims[0], dims[1], dims[2], type, vol, {1, 0.5, 2}, {0, 1, -1}};
    struct iso_kept *k;
    struct sf_err err = {0};
    if (iso_kept_begin(&g, &o, &k, &err)) {
        free(vol);
        return 0;
    }
    check(k, &g, &o);
    for (int steps = 0; at + 1 < size && steps < 16; steps++) {
        uint8_t op = data[at++];
        struct iso_edit ed;
        struct iso_change ch;
        int rc;
        if (op & 1) { /* a new iso (refused outside the samples' range) */
            double iso = iso_of(type, data[at++]);
            err = (struct sf_err){0};
            rc = iso_kept_iso(k, iso, (op & 2) != 0, &ed, &ch, &err);
            if (rc == 0)
                o.iso = iso;
            else if (rc != SF_EINVAL)
                break; /* (no memory: k of no further use) */
        } else { /* an edit of a block from the bytes that follow */
            int lo[3], bn[3];
            for (int d = 0; d < 3; d++) {
                lo[d] = at < size ? data[at++] % dims[d] : 0;
                bn[d] = 1 + (at < size ? data[at++] : 0) % (dims[d] - lo[d]);
            }
            size_t m = (size_t)bn[0] * bn[1] * bn[2];
            void *blk = malloc(m * es);
            if (!blk)
                break;
            for (size_t i = 0; i < m; i++) {
                uint8_t b = at < size ? data[at++] : (uint8_t)(op + i);
                put(blk, type, i, b);
                int x = (int)(i % (size_t)bn[0]), y = (int)(i / (size_t)bn[0] % (size_t)bn[1]),
                    z = (int)(i / ((size_t)bn[0] * bn[1]));
                put(vol, type, (size_t)(lo[0] + x) + (size_t)dims[0] * ((size_t)(lo[1] + y) + (size_t)dims[1] * (lo[2] + z)), b);
            }
            struct iso_grid bg = {bn[0], bn[1], bn[2], type, blk, {1, 1, 1}, {0, 0, 0}};
            err = (struct sf_err){0};
            rc = iso_kept_edit(k, lo, &bg, &ed, &ch, &err);
            free(blk);
            if (rc)
                break; /* (no memory, or the samples were written and k is of no further use) */
        }
        if (rc == 0) {
            iso_change_free(&ch);
            check(k, &g, &o);
        }
    }
    iso_kept_free(k);
    free(vol);
    return 0;
}
