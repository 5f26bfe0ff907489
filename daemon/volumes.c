/* volumes.c - what the kinds that read volumes share (volumes.h). */
#include "volumes.h"

#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../api/iso_json.h"
#include "../api/query.h"

int job_map_file(const char *path, void **map, size_t *len)
{
    int fd = open(path, O_RDONLY);
    struct stat st;
    if (fd < 0 || fstat(fd, &st)) {
        if (fd >= 0)
            close(fd);
        return SF_EIO;
    }
    *len = (size_t)st.st_size;
    *map = *len ? mmap(NULL, *len, PROT_READ, MAP_PRIVATE, fd, 0) : NULL;
    close(fd);
    if (*map == MAP_FAILED) {
        *map = NULL;
        return SF_EIO;
    }
    return 0;
}

struct iso_opts job_iso_opts(const struct service *svc, const struct volume *v)
{
    struct iso_opts o = volume_iso_opts(v);
    o.max_triangles = (size_t)svc->cfg.max_triangles;
    o.max_triangles_by = "this node's max-triangles";
    long long held = svc->cfg.job_memory / ISO_BYTES_PER_TRIANGLE;
    if (svc->cfg.job_memory && held < svc->cfg.max_triangles) {
        o.max_triangles = (size_t)held;
        o.max_triangles_by = "what this node's job-memory holds (some 80 bytes a triangle from extraction to the store)";
    }
    return o;
}

/* Block blk at lo written into grid g's samples (same type). */
static void write_samples(struct iso_grid *g, const int lo[3], const struct iso_grid *blk)
{
    size_t ts = g->type == ISO_U8 ? 1 : g->type == ISO_F32 ? 4 : 2;
    for (int z = 0; z < blk->nz; z++)
        for (int y = 0; y < blk->ny; y++)
            memcpy((char *)g->samples + ts * ((size_t)lo[0] + (size_t)g->nx * ((size_t)lo[1] + y + (size_t)g->ny * ((size_t)lo[2] + z))),
                   (const char *)blk->samples + ts * (size_t)blk->nx * ((size_t)y + (size_t)blk->ny * z),
                   ts * (size_t)blk->nx);
}

/* The least and greatest of n samples f. */
static void range_of(const float *f, size_t n, double *lo, double *hi)
{
    float a = INFINITY, b = -INFINITY;
    for (size_t i = 0; i < n; i++)
        a = f[i] < a ? f[i] : a, b = f[i] > b ? f[i] : b;
    *lo = a, *hi = b;
}

struct adapt_phase {
    struct iso_adapt *a;
    int phase;
};

static void adapt_slab(void *ctx, int s)
{
    const struct adapt_phase *p = ctx;
    iso_adapt_run(p->a, p->phase, s);
}

void volume_adapt_run(struct service *svc, struct iso_adapt *a)
{
    for (int p = 0; p < iso_adapt_phases(a); p++) {
        struct adapt_phase ph = {a, p};
        jobq_help(svc->q, iso_adapt_n_slabs(a), adapt_slab, &ph);
        iso_adapt_between(a, p);
    }
}

/* An iso change to value (options' "value") of vol's model: marching cubes kept drawn again at
 * that iso (iso_kept_iso), a new hierarchy at that iso, its triangles numbered after
 * the old one's (ch: all of the old ones out, all of the new in, by id, without corners), or, with
 * neither, vol's iso (its mesh then extracted again whole). */
static int iso_apply(struct service *svc, struct volume *vol, struct kept_ext *x, const char *value,
                     struct iso_edit *ed, struct iso_change *ch, struct sf_err *err)
{
    char *end = NULL;
    double v = strtod(value, &end), lo, hi;
    size_t n = (size_t)vol->g.nx * vol->g.ny * vol->g.nz;
    float *f = NULL, *row = NULL;
    struct iso_adapt **a = &x->a;
    if (*end || !isfinite(v))
        return sf_fail(err, SF_EINVAL, "?value", "value is the new iso, a finite number");
    if (x->k) {
        struct iso_change none = {0};
        int rc = iso_kept_iso(x->k, v, false, ed, ch ? ch : &none, err); /* (read back whole: job_edit.c) */
        iso_change_free(&none);
        if (!rc)
            vol->iso = v;
        return rc;
    }
    if (*a && iso_adapt_samples(*a, &f, err))
        return err->code;
    if (f) {
        range_of(f, n, &lo, &hi);
    } else { /* (the samples in their own type, a row at a time) */
        if (!(row = malloc((size_t)vol->g.nx * sizeof *row)))
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        lo = INFINITY, hi = -INFINITY;
        for (int z = 0; z < vol->g.nz; z++)
            for (int y = 0; y < vol->g.ny; y++) {
                double rl, rh;
                iso_grid_row(&vol->g, y, z, row);
                range_of(row, (size_t)vol->g.nx, &rl, &rh);
                lo = fmin(lo, rl), hi = fmax(hi, rh);
            }
        free(row);
    }
    if (!(v >= lo && v < hi)) { /* (samples over the iso are inside: at the greatest, none) */
        free(f);
        return sf_fail(err, SF_EINVAL, "?value", "the samples run from %g to %g: an iso of %g has no surface", lo, hi, v);
    }
    memset(ed, 0, sizeof *ed);
    ed->whole = true;
    vol->iso = v;
    if (!*a)
        return 0;
    struct iso_grid g = vol->g;
    g.type = ISO_F32, g.samples = f;
    struct iso_opts o = job_iso_opts(svc, vol);
    o.keep = true;
    struct iso_adapt *na = NULL;
    struct iso_adapt_stats st;
    struct trimesh m = {0};
    uint32_t *old = NULL, *ids = NULL;
    int rc = iso_adapt_begin(&g, &o, vol->levels, vol->max_error, &na, err);
    if (!rc) {
        volume_adapt_run(svc, na);
        iso_adapt_number_from(na, iso_adapt_next_id(*a));
        rc = iso_adapt_keep(na, &st, err);
    }
    if (!rc && ch && !(rc = iso_adapt_mesh(*a, &m, &st, err)) && !(rc = iso_adapt_ids(*a, &old, err))) {
        ch->removed = old, ch->n_removed = m.n_tri;
        ed->triangles_removed = (long)m.n_tri;
        trimesh_free(&m);
        if (!(rc = iso_adapt_mesh(na, &m, &st, err)) && !(rc = iso_adapt_ids(na, &ids, err)))
            ch->added = ids, ch->n_added = m.n_tri; /* (no corners: the new mesh is read back whole) */
        ed->triangles_added = (long)m.n_tri;
        ch->next_id = iso_adapt_next_id(na);
    }
    trimesh_free(&m);
    free(f);
    if (rc) {
        iso_adapt_free(na);
        return rc;
    }
    for (int l = 1; l <= ISO_MAX_LEVELS; l++)
        ed->cells_rebuilt += st.cells[l];
    iso_adapt_free(*a);
    *a = na;
    return 0;
}

int part_apply(struct service *svc, struct volume *vol, struct kept_ext *x, const char *options, const void *data,
               size_t len, struct iso_edit *ed, struct iso_change *ch, struct sf_err *err)
{
    int lo[3], n[3];
    char value[64] = "";
    query_option(options, "value", value, sizeof value);
    if (value[0])
        return iso_apply(svc, vol, x, value, ed, ch, err);
    if (volume_region(options, &vol->g, len, lo, n, err))
        return err->code;
    struct iso_grid blk = {n[0], n[1], n[2], vol->g.type, data, {1, 1, 1}, {0, 0, 0}};
    memset(ed, 0, sizeof *ed);
    if (x->a)
        return iso_adapt_edit_ids(x->a, lo, &blk, ed, ch, err);
    if (x->k) {
        struct iso_change none = {0};
        int rc = iso_kept_edit(x->k, lo, &blk, ed, ch ? ch : &none, err);
        iso_change_free(&none);
        return rc;
    }
    write_samples(&vol->g, lo, &blk);
    ed->whole = true;
    return 0;
}

int stored_volume(struct service *svc, const char *id, struct volume *vol, bool edits, int *next, struct sf_err *err)
{
    memset(vol, 0, sizeof *vol);
    struct volume_rec *parts;
    int n, found = store_volume_get(svc->store, id, 0, &parts, &n);
    if (found || n == 0 || parts[0].seq != 0) {
        store_volume_free(parts, n);
        return sf_fail(err, !found ? SF_ECONFLICT : SF_EIO, "",
                       !found ? "this model keeps no volume of samples (made before volumes were kept, or not an "
                                "isosurface of samples)"
                       : found == SF_EDAMAGED ? "the model's stored volume is damaged (its bytes no longer match "
                                                "their checksum): it cannot be edited"
                                              : "the model's volume could not be read from the store");
    }
    int rc = volume_read(parts[0].data, parts[0].len, parts[0].format, parts[0].options, vol, err);
    if (!rc && vol->frep)
        rc = sf_fail(err, SF_ECONFLICT, "", "an FRep model has no samples (it is edited by {op, object}, and a volume "
                     "primitive reads isosurfaces of samples)");
    if (!rc && !vol->owned) { /* the samples in the part's bytes: copied, to be written */
        size_t bytes = (size_t)vol->g.nx * vol->g.ny * vol->g.nz * (vol->g.type == ISO_U8 ? 1 : vol->g.type == ISO_F32 ? 4 : 2);
        if (!(vol->owned = malloc(bytes)))
            rc = sf_fail(err, SF_ENOMEM, "", "out of memory for the model's volume");
        else
            vol->g.samples = memcpy(vol->owned, vol->g.samples, bytes);
    }
    for (int k = 1; k < n && !rc && edits; k++) {
        struct iso_edit ed;
        struct kept_ext none = {0};
        rc = part_apply(svc, vol, &none, parts[k].options, parts[k].data, parts[k].len, &ed, NULL, err);
    }
    *next = edits ? parts[n - 1].seq + 1 : 1;
    store_volume_free(parts, n);
    if (rc)
        volume_free(vol);
    return rc;
}

int frep_volumes(struct service *svc, struct frep_request *r, struct sf_err *err)
{
    r->f.volumes = r->vols;
    for (int k = 0; k < r->n_refs; k++) {
        struct volume mv;
        struct sf_err e = {0};
        int next;
        if (stored_volume(svc, r->refs[k].model, &mv, true, &next, &e))
            return sf_fail(err, e.code == SF_ECONFLICT ? SF_EINVAL : e.code, r->refs[k].pointer, "model %s: %s",
                           r->refs[k].model, e.message);
        size_t n = (size_t)mv.g.nx * mv.g.ny * mv.g.nz;
        float *f = mv.oblique ? NULL : malloc(n * sizeof *f);
        if (!f) {
            volume_free(&mv);
            return mv.oblique ? sf_fail(err, SF_EINVAL, r->refs[k].pointer, "model %s: an oblique series is not read "
                                                                            "into an FRep object", r->refs[k].model)
                              : sf_fail(err, SF_ENOMEM, "", "out of memory for a volume's samples");
        }
        for (int z = 0; z < mv.g.nz; z++)
            for (int y = 0; y < mv.g.ny; y++)
                iso_grid_row(&mv.g, y, z, f + (size_t)mv.g.nx * (y + (size_t)mv.g.ny * z));
        float lo = INFINITY, hi = -INFINITY;
        for (size_t i = 0; i < n; i++)
            lo = fminf(lo, f[i]), hi = fmaxf(hi, f[i]);
        struct frep_volume *fv = &r->vols[k];
        *fv = (struct frep_volume){{mv.g.nx, mv.g.ny, mv.g.nz}, {0}, {0}, f, lo, hi, (float)fmin(mv.iso - 1, lo)};
        memcpy(fv->origin, mv.g.origin, sizeof fv->origin);
        memcpy(fv->spacing, mv.g.spacing, sizeof fv->spacing);
        r->vol_samples[k] = f;
        frep_volume_iso(r, k, mv.iso);
        volume_free(&mv);
    }
    return 0;
}

int frep_refs_check(struct service *svc, const struct frep_request *r, const char *owner, const char *pointer,
                    struct sf_err *err)
{
    int rc = 0;
    for (int k = 0; k < r->n_refs && !rc; k++) {
        char *resource = NULL;
        struct iso_grid g;
        struct sf_err e = {0};
        bool frep;
        const char *at = pointer ? pointer : r->refs[k].pointer;
        int found = store_model_get(svc->store, r->refs[k].model, owner, &resource, NULL, NULL);
        if (found)
            rc = found == SF_ENOTFOUND ? sf_fail(err, SF_EINVAL, at, "no such model: %s", r->refs[k].model)
                            : sf_fail(err, SF_EIO, "", "the store failed");
        else if (iso_model_grid(resource, &g, &frep, &e) || frep)
            rc = sf_fail(err, SF_EINVAL, at, "a volume reads an isosurface model of samples%s%s",
                         e.message[0] ? ": " : "", e.message);
        free(resource);
    }
    return rc;
}
