/* fuzz_journal.c - a model's mesh as a base and a journal of changes (api/mesh_journal.h, issue
 * 45), the bytes a store hands back: the input is records of a u32 length and its bytes, the first
 * a packed mesh (mesh_io.h, with or without ids; not one: a tetrahedron of version 1), the rest
 * changes. Their delta (after the base, and up to it: a whole change composed with the base as
 * the current mesh) and the base with them applied must end cleanly; what apply answers must
 * unpack again, of the version after the last change, without a vertex out of range; a delta's
 * counts must match its length. A disagreement aborts. */
#include "../../api/mesh_io.h"
#include "../../api/mesh_journal.h"
#include "fuzz.h"

#define MAX_CHANGES 8

static uint32_t rd32(const uint8_t *p) { return p[0] | p[1] << 8 | p[2] << 16 | (uint32_t)p[3] << 24; }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const uint8_t *rec[MAX_CHANGES + 1];
    size_t len[MAX_CHANGES + 1];
    int n = 0;
    for (size_t at = 0; n <= MAX_CHANGES && at + 4 <= size;) {
        size_t l = rd32(data + at);
        if (l > size - at - 4)
            l = size - at - 4;
        rec[n] = data + at + 4, len[n++] = l;
        at += 4 + l;
    }
    float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    uint32_t tri[] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    struct trimesh tet = {pos, NULL, tri, 4, 4};
    struct sf_err err = {0};
    char *base = NULL, *out = NULL;
    size_t base_len = 0, out_len = 0;
    if (n && mesh_is_packed((const char *)rec[0], len[0])) {
        base = malloc(len[0] ? len[0] : 1);
        if (!base)
            return 0;
        memcpy(base, rec[0], len[0]);
        base_len = len[0];
    } else if (mesh_pack(&tet, &base, &base_len, &err)) {
        return 0;
    }
    uint64_t version = 1;
    if (mesh_packed_version(base, base_len, &version))
        version = 1;
    struct mesh_change ch[MAX_CHANGES];
    size_t nc = 0;
    for (int k = 1; k < n; k++)
        ch[nc++] = (struct mesh_change){rec[k], len[k]};
    for (size_t k = 0; k < nc; k++)
        (void)mesh_change_version(ch[k].data, ch[k].len);
    /* the changes after the base; then the changes as the ones up to it (a whole change composed
     * with the base as the current mesh) */
    for (int as_current = 0; as_current < 2; as_current++) {
        uint64_t from = as_current ? version - nc : version;
        if (as_current && version < nc)
            break;
        if (mesh_changes_delta(ch, nc, (uint32_t)from, (uint32_t)(from + nc), base, base_len, &out, &out_len, &err))
            continue;
        const uint8_t *d = (const uint8_t *)out;
        if (out_len < 20 || memcmp(d, "SFMD", 4) || out_len != 20 + 4 * (size_t)rd32(d + 12) + 40 * (size_t)rd32(d + 16))
            abort();
        free(out);
    }
    if (mesh_changes_apply(base, base_len, ch, nc, &out, &out_len, &err) == 0) {
        struct trimesh m;
        uint32_t *ids;
        uint64_t v;
        int rc = mesh_unpack_ids(out, out_len, &m, &ids, &v, &err);
        if (rc == 0 && v != version + nc)
            abort();
        if (rc && rc != SF_ENOMEM)
            abort();
        if (!rc) {
            trimesh_free(&m);
            free(ids);
        }
        free(out);
    }
    free(base);
    return 0;
}
