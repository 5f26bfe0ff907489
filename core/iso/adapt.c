/* adapt.c - the adaptive hierarchy's driver (adapt.h): its state made and freed, the phases run
 * slab by slab (the samples, each level's blocks, the cells), the slabs' pieces merged into one
 * mesh, and local rebuilds after an edit. The grid is copied as floats with its pad layer
 * (closed=true), as mc.c sees it; nodes and cells are addressed by their integer coordinates in
 * that grid. Its parts: adapt_hierarchy.c, adapt_polygon.c, adapt_feature.c, adapt_mesh.c. */
#include "adapt_internal.h"
#include "kept.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

static void piece_free(struct piece *pc)
{
    free(pc->keys);
    free(pc->slot);
    free(pc->vkey);
    free(pc->owner);
    trimesh_free(&pc->m);
}

void iso_adapt_free(struct iso_adapt *a)
{
    if (!a)
        return;
    pieces_free(a->pz);
    free(a->F);
    for (int l = 0; l <= ISO_MAX_LEVELS; l++)
        free(a->M[l]), free(a->mixed[l]);
    free(a->lev2);
    for (int k = 0; k < ADAPT_SLABS; k++)
        piece_free(&a->pieces[k]);
    for (int l = 0; l <= ISO_MAX_LEVELS; l++)
        free(a->berr[l]);
    free(a->bcells), free(a->bfeat), free(a->refs), free(a->ids);
    piece_free(&a->all);
    free(a);
}

int iso_adapt_begin(const struct iso_grid *g, const struct iso_opts *o, int levels, double max_error,
                    struct iso_adapt **out, struct sf_err *err)
{
    *out = NULL;
    if (levels < 1 || levels > ISO_MAX_LEVELS)
        return sf_fail(err, SF_EINVAL, "?levels", "levels is 1 to %d", ISO_MAX_LEVELS);
    if (!(max_error >= 0) || !isfinite(max_error))
        return sf_fail(err, SF_EINVAL, "?max_error", "max_error is a finite length, 0 or more");
    if (g->nx < 2 || g->ny < 2 || g->nz < 2)
        return sf_fail(err, SF_EINVAL, "?dims", "a volume has at least 2 samples on every axis");
    if (!isfinite(o->iso))
        return sf_fail(err, SF_EINVAL, "?iso", "iso is a finite number");
    if ((double)g->nx * g->ny * g->nz > ISO_ADAPT_MAX_SAMPLES)
        return sf_fail(err, SF_ELIMIT, "?levels", "levels over 1 take volumes of at most %u samples",
                       ISO_ADAPT_MAX_SAMPLES);
    if (o->pieces && o->sharp)
        return sf_fail(err, SF_EINVAL, "?merge", "merge=pieces draws no feature points (features=none)");
    struct iso_adapt *a = calloc(1, sizeof *a);
    if (!a)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if (o->pieces && levels > 1) { /* a vertex per piece of surface: adapt_pieces.c does it all */
        int rc = pieces_begin(g, o, levels, max_error, &a->pz, err);
        if (rc) {
            free(a);
            return rc;
        }
        a->L = levels;
        *out = a;
        return 0;
    }
    a->shift = o->closed ? 1 : 0;
    a->iso = (float)o->iso;
    a->sharp = o->sharp;
    a->field = o->field, a->field_ctx = o->field_ctx;
    a->tri_limit_by = o->max_triangles_by ? o->max_triangles_by : "the limit";
    a->max_err = levels == 1 ? -1 : max_error; /* levels 1: nothing merges */
    for (int k = 0; o->max_triangles && k < ADAPT_SLABS; k++)
        a->pieces[k].tri_total = &a->tri_total, a->pieces[k].tri_limit = o->max_triangles;
    a->L = levels < 2 ? 2 : levels;
    int nn[3] = {g->nx, g->ny, g->nz};
    for (int d = 0; d < 3; d++) {
        a->N[d] = nn[d] + 2 * a->shift;
        a->sp[d] = g->spacing[d];
        a->org[d] = g->origin[d] - a->shift * g->spacing[d];
    }
    size_t n = (size_t)a->N[0] * a->N[1] * a->N[2];
    a->g = *g;
    a->iso1 = o->iso - 1; /* (the pad, below iso and the samples' least, is set when they are read) */
    if (!(a->F = malloc(n * sizeof *a->F))) {
        iso_adapt_free(a);
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the volume's %zu samples", n);
    }
    for (int l = 2; l <= a->L; l++) {
        int s = 1 << (l - 1);
        for (int d = 0; d < 3; d++)
            a->nb[l][d] = (a->N[d] - 1 + s - 1) / s;
        size_t nb = (size_t)a->nb[l][0] * a->nb[l][1] * a->nb[l][2];
        if (!(a->M[l] = calloc(nb ? nb : 1, 1)) || !(a->mixed[l] = calloc(nb ? nb : 1, 1)) ||
            (o->keep && !(a->berr[l] = calloc(nb ? nb : 1, sizeof(double))))) {
            iso_adapt_free(a);
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        }
    }
    size_t n2 = (size_t)a->nb[2][0] * a->nb[2][1] * a->nb[2][2];
    if (n2 > UINT32_MAX || !(a->lev2 = malloc(n2 ? n2 : 1)) ||
        (o->keep && (!(a->bcells = calloc(n2 ? n2 : 1, 1)) || !(a->bfeat = calloc(n2 ? n2 : 1, 1))))) {
        iso_adapt_free(a);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    a->n_slabs = a->nb[2][2] < ADAPT_SLABS ? a->nb[2][2] : ADAPT_SLABS;
    *out = a;
    return 0;
}

int iso_adapt_phases(const struct iso_adapt *a) { return a->pz ? pieces_phases(a->pz) : a->L + 1; }

static void set_pad(struct iso_adapt *a);

/* Phase 0: the samples of planes [z0, z1) of the virtual grid as floats, and their least into
 * slab_min[slab]; the pad layer round them is written after every slab's (iso_adapt_between),
 * when the least of all is known. */
static void load_slab(struct iso_adapt *a, int z0, int z1, int slab)
{
    float lo = INFINITY;
    for (int z = z0; z < z1; z++)
        for (int y = 0; y < a->N[1]; y++) {
            float *row = a->F + at3(a, 0, y, z) + a->shift;
            int ry = y - a->shift, rz = z - a->shift;
            if (ry < 0 || ry >= a->g.ny || rz < 0 || rz >= a->g.nz)
                continue;
            iso_grid_row(&a->g, ry, rz, row);
            for (int x = 0; x < a->g.nx; x++)
                lo = row[x] < lo ? row[x] : lo;
        }
    a->slab_min[slab] = lo;
}

int iso_adapt_n_slabs(const struct iso_adapt *a) { return a->pz ? pieces_n_slabs(a->pz) : a->n_slabs; }

void iso_adapt_run(struct iso_adapt *a, int phase, int slab)
{
    if (a->pz) {
        pieces_run(a->pz, phase, slab);
        return;
    }
    if (phase == 0) {
        load_slab(a, (int)((long)a->N[2] * slab / a->n_slabs), (int)((long)a->N[2] * (slab + 1) / a->n_slabs), slab);
        return;
    }
    phase--;
    int l = phase + 2 <= a->L ? phase + 2 : 2, nz = a->nb[l][2];
    int z0 = (int)((long)nz * slab / a->n_slabs), z1 = (int)((long)nz * (slab + 1) / a->n_slabs);
    if (phase + 2 <= a->L) {
        mask_slab(a, l, z0, z1, slab);
        return;
    }
    int b[3];
    for (b[2] = z0; b[2] < z1 && !a->pieces[slab].nomem; b[2]++)
        for (b[1] = 0; b[1] < a->nb[2][1]; b[1]++)
            for (b[0] = 0; b[0] < a->nb[2][0]; b[0]++)
                block_cells(a, &a->pieces[slab], b);
}

void iso_adapt_between(struct iso_adapt *a, int phase)
{
    if (a->pz) {
        pieces_between(a->pz, phase);
        return;
    }
    if (phase == 0) { /* the samples are read: the pad below them and iso */
        a->gmin = INFINITY;
        for (int s = 0; s < a->n_slabs; s++)
            a->gmin = fmin(a->gmin, a->slab_min[s]);
        a->pad = a->shift ? (float)fmin(a->iso1, a->gmin) : 0;
        if (a->shift)
            set_pad(a);
    }
    if (phase == a->L - 1) /* the last level's blocks are known */
        cell_levels(a);
}

/* The slabs' pieces into a->all, each key once (the slabs' order: the same mesh on any number of
 * threads), their triangles renumbered; the counts into st. 0, or -1 (no memory, or over the
 * vertex limit). */
static int merge_pieces(struct iso_adapt *a, struct iso_adapt_stats *st)
{
    struct piece *all = &a->all;
    for (int k = 0; k < a->n_slabs; k++) {
        struct piece *pc = &a->pieces[k];
        for (int l = 1; l <= ISO_MAX_LEVELS; l++)
            st->cells[l] += pc->cells[l];
        st->feature_points += pc->feature_points;
        st->max_estimate = fmax(st->max_estimate, a->slab_max[k]);
        if (pc->nomem)
            return -1;
        uint32_t *id = malloc((pc->m.n_vert ? pc->m.n_vert : 1) * sizeof *id);
        if (!id)
            return -1;
        for (size_t v = 0; v < pc->m.n_vert && !all->nomem; v++) {
            bool found = false;
            size_t h = 0;
            if (pc->vkey[v] != UINT64_MAX && !slot_of(all, pc->vkey[v], &found, &h))
                break;
            if (found) {
                id[v] = all->slot[h];
                continue;
            }
            double pos[3] = {pc->m.pos[3 * v], pc->m.pos[3 * v + 1], pc->m.pos[3 * v + 2]};
            double nrm[3] = {pc->m.nrm[3 * v], pc->m.nrm[3 * v + 1], pc->m.nrm[3 * v + 2]};
            long g = new_vertex(all, pos, nrm, pc->vkey[v]);
            if (g < 0)
                break;
            st->face_points += pc->vkey[v] != UINT64_MAX && pc->vkey[v] & FACE_KEY;
            if (pc->vkey[v] != UINT64_MAX)
                keep_slot(all, h, pc->vkey[v], g);
            id[v] = (uint32_t)g;
        }
        for (size_t t = 0; t < pc->m.n_tri && !all->nomem; t++) {
            all->block = pc->owner[t];
            add_triangle(all, id[pc->m.tri[3 * t]], id[pc->m.tri[3 * t + 1]], id[pc->m.tri[3 * t + 2]]);
        }
        free(id);
        piece_free(pc);
        memset(pc, 0, sizeof *pc);
        if (all->nomem)
            return -1;
    }
    return 0;
}

static int mesh_failed(const struct iso_adapt *a, struct sf_err *err)
{
    for (int k = 0; k < ADAPT_SLABS; k++)
        if (a->pieces[k].over)
            return sf_fail(err, SF_ELIMIT, "", "the isosurface would have over %zu triangles, %s",
                           a->pieces[k].tri_limit, a->tri_limit_by);
    return sf_fail(err, a->all.m.n_vert >= ISO_MAX_VERTICES ? SF_ELIMIT : SF_ENOMEM, "",
                   "the mesh would take more memory than there is (or over %u vertices)", ISO_MAX_VERTICES);
}

int iso_adapt_end(struct iso_adapt *a, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    int rc = a->pz ? pieces_end(a->pz, out, st, err) : merge_pieces(a, st) ? mesh_failed(a, err) : 0;
    if (!rc && !a->pz) {
        *out = a->all.m;
        memset(&a->all.m, 0, sizeof a->all.m);
    }
    iso_adapt_free(a);
    return rc;
}

int iso_extract_adaptive(const struct iso_grid *g, const struct iso_opts *o, int levels, double max_error,
                         const struct sf_progress *pr, struct trimesh *out, struct iso_adapt_stats *st,
                         struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    struct iso_adapt *a;
    int rc = iso_adapt_begin(g, o, levels, max_error, &a, err);
    if (rc)
        return rc;
    int phases = iso_adapt_phases(a);
    for (int p = 0; p < phases && !rc; p++) {
        int n = iso_adapt_n_slabs(a); /* (pieces: each phase its own) */
        for (int s = 0; s < n && !rc; s++) {
            iso_adapt_run(a, p, s);
            rc = sf_poll(pr, (p * n + s + 1.0) / (phases * n), err);
        }
        iso_adapt_between(a, p);
    }
    if (rc) {
        iso_adapt_free(a);
        return rc;
    }
    return iso_adapt_end(a, out, st, err);
}

/* ---- local rebuilds (iso_adapt_keep, iso_adapt_edit) ---- */

/* The smallest of the samples (not the pad) into a->gmin, and how many are it. */
static void samples_min(struct iso_adapt *a)
{
    float m = INFINITY;
    size_t n = 0;
    for (int z = a->shift; z < a->N[2] - a->shift; z++)
        for (int y = a->shift; y < a->N[1] - a->shift; y++) {
            const float *row = a->F + at3(a, 0, y, z);
            for (int x = a->shift; x < a->N[0] - a->shift; x++) {
                if (row[x] < m)
                    m = row[x], n = 0;
                n += row[x] == m;
            }
        }
    a->gmin = m;
    a->n_min = n;
}

int iso_adapt_keep(struct iso_adapt *a, struct iso_adapt_stats *st, struct sf_err *err)
{
    memset(st, 0, sizeof *st);
    if (a->pz)
        return pieces_keep(a->pz, st, err);
    if (!a->bcells)
        return sf_fail(err, SF_EINVAL, "", "the extraction was not begun to be kept");
    if (merge_pieces(a, st))
        return mesh_failed(a, err);
    const struct trimesh *m = &a->all.m;
    if (mem_reserve((void **)&a->refs, &a->rcap, m->n_vert + 1, sizeof *a->refs))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    memset(a->refs, 0, (m->n_vert + 1) * sizeof *a->refs);
    for (size_t i = 0; i < 3 * m->n_tri; i++)
        a->refs[m->tri[i]]++;
    if (m->n_tri >= UINT32_MAX || mem_reserve((void **)&a->ids, &a->idcap, m->n_tri + 1, sizeof *a->ids))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if ((uint64_t)a->next_id + m->n_tri >= UINT32_MAX)
        return sf_fail(err, SF_ELIMIT, "", "the model's triangle ids ran out (2^32 of them)");
    for (size_t t = 0; t < m->n_tri; t++)
        a->ids[t] = a->next_id + (uint32_t)t;
    a->next_id += (uint32_t)m->n_tri;
    for (size_t v = 0; v < m->n_vert; v++)
        a->dead += !a->refs[v];
    samples_min(a);
    memcpy(a->cells, st->cells, sizeof a->cells);
    a->feature_points = st->feature_points;
    a->kept = true;
    return 0;
}

int iso_adapt_mesh(const struct iso_adapt *a, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    if (a->pz)
        return pieces_mesh(a->pz, out, st, err);
    const struct piece *all = &a->all;
    size_t nv = all->m.n_vert, nt = all->m.n_tri, live = nv - a->dead;
    uint32_t *id = malloc((nv ? nv : 1) * sizeof *id);
    out->pos = malloc((3 * live + 1) * sizeof *out->pos);
    out->nrm = malloc((3 * live + 1) * sizeof *out->nrm);
    out->tri = malloc((3 * nt + 1) * sizeof *out->tri);
    if (!id || !out->pos || !out->nrm || !out->tri) {
        free(id);
        trimesh_free(out);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    for (size_t v = 0; v < nv; v++) {
        if (!a->refs[v])
            continue;
        id[v] = (uint32_t)out->n_vert;
        memcpy(out->pos + 3 * out->n_vert, all->m.pos + 3 * v, 3 * sizeof *out->pos);
        memcpy(out->nrm + 3 * out->n_vert, all->m.nrm + 3 * v, 3 * sizeof *out->nrm);
        out->n_vert++;
        st->face_points += all->vkey[v] != UINT64_MAX && all->vkey[v] & FACE_KEY;
    }
    for (size_t i = 0; i < 3 * nt; i++)
        out->tri[i] = id[all->m.tri[i]];
    out->n_tri = nt;
    free(id);
    memcpy(st->cells, a->cells, sizeof st->cells);
    st->feature_points = a->feature_points;
    for (int l = 2; l <= a->L; l++) {
        size_t nb = (size_t)a->nb[l][0] * a->nb[l][1] * a->nb[l][2];
        for (size_t b = 0; b < nb; b++)
            st->max_estimate = fmax(st->max_estimate, a->berr[l][b]);
    }
    return 0;
}

int iso_adapt_ids(const struct iso_adapt *a, uint32_t **ids, struct sf_err *err)
{
    if (a->pz)
        return pieces_ids(a->pz, ids, err);
    size_t n = a->all.m.n_tri;
    if (!(*ids = malloc((n ? n : 1) * sizeof **ids)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if (n)
        memcpy(*ids, a->ids, n * sizeof **ids);
    return 0;
}

void iso_adapt_number_from(struct iso_adapt *a, uint32_t first)
{
    if (a->pz)
        pieces_number_from(a->pz, first);
    a->next_id = first;
}

uint32_t iso_adapt_next_id(const struct iso_adapt *a) { return a->pz ? pieces_next_id(a->pz) : a->next_id; }

int iso_adapt_samples(const struct iso_adapt *a, float **out, struct sf_err *err)
{
    if (a->pz)
        return pieces_samples(a->pz, out, err);
    int nx = a->N[0] - 2 * a->shift, ny = a->N[1] - 2 * a->shift, nz = a->N[2] - 2 * a->shift;
    float *f = malloc((size_t)nx * ny * nz * sizeof *f + 1);
    if (!f)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (int z = 0; z < nz; z++)
        for (int y = 0; y < ny; y++)
            memcpy(f + (size_t)nx * (y + (size_t)ny * z), a->F + at3(a, a->shift, y + a->shift, z + a->shift),
                   (size_t)nx * sizeof *f);
    *out = f;
    return 0;
}

static int floordiv(int x, int m) { return x >= 0 ? x / m : -((-x + m - 1) / m); }

/* Writes the pad layer round the samples (closed: the border counts as outside). */
static void set_pad(struct iso_adapt *a)
{
    for (int z = 0; z < a->N[2]; z++)
        for (int y = 0; y < a->N[1]; y++) {
            bool rim = y == 0 || z == 0 || y == a->N[1] - 1 || z == a->N[2] - 1;
            for (int x = 0; x < a->N[0]; x += rim || x == a->N[0] - 1 ? 1 : a->N[0] - 1)
                a->F[at3(a, x, y, z)] = a->pad;
        }
}

/* pc's vertices and triangles into the kept mesh: a keyed vertex that kept triangles still use
 * is theirs (it lies outside what changed, so it is the same), any other takes pc's values. 0,
 * or -1 (no memory). */
static int merge_rebuilt(struct iso_adapt *a, const struct piece *pc)
{
    struct piece *all = &a->all;
    uint32_t *id = malloc((pc->m.n_vert ? pc->m.n_vert : 1) * sizeof *id);
    if (!id)
        return -1;
    for (size_t v = 0; v < pc->m.n_vert && !all->nomem; v++) {
        uint64_t key = pc->vkey[v];
        bool found = false;
        size_t h = 0;
        if (key != UINT64_MAX && !slot_of(all, key, &found, &h))
            break;
        long g = found ? (long)all->slot[h] : -1;
        double pos[3] = {pc->m.pos[3 * v], pc->m.pos[3 * v + 1], pc->m.pos[3 * v + 2]};
        double nrm[3] = {pc->m.nrm[3 * v], pc->m.nrm[3 * v + 1], pc->m.nrm[3 * v + 2]};
        if (g >= 0 && !a->refs[g]) { /* unused since: where it is now (as merge_pieces puts it) */
            set_vertex(all, (size_t)g, pos, nrm);
        } else if (g < 0) {
            if ((g = new_vertex(all, pos, nrm, key)) < 0 ||
                mem_reserve((void **)&a->refs, &a->rcap, all->m.n_vert, sizeof *a->refs)) {
                all->nomem = true;
                break;
            }
            a->refs[g] = 0;
            a->dead++;
            if (key != UINT64_MAX)
                keep_slot(all, h, key, g);
        }
        id[v] = (uint32_t)g;
    }
    if (mem_reserve((void **)&a->ids, &a->idcap, all->m.n_tri + pc->m.n_tri + 1, sizeof *a->ids))
        all->nomem = true;
    for (size_t t = 0; t < pc->m.n_tri && !all->nomem; t++) {
        all->block = pc->owner[t];
        size_t n = all->m.n_tri;
        add_triangle(all, id[pc->m.tri[3 * t]], id[pc->m.tri[3 * t + 1]], id[pc->m.tri[3 * t + 2]]);
        if (all->m.n_tri > n)
            a->ids[n] = a->next_id++;
        for (int k = 0; k < 3 && all->m.n_tri > n; k++)
            if (a->refs[all->m.tri[3 * n + k]]++ == 0)
                a->dead--;
    }
    free(id);
    return all->nomem ? -1 : 0;
}

/* The kept mesh without its unused vertices (when they outnumber the used ones). 0 or -1. */
static int compact(struct iso_adapt *a)
{
    struct piece *all = &a->all, n = {0};
    uint32_t *id = malloc((all->m.n_vert ? all->m.n_vert : 1) * sizeof *id);
    if (!id)
        return -1;
    for (size_t v = 0; v < all->m.n_vert && !n.nomem; v++) {
        if (!a->refs[v])
            continue;
        double pos[3] = {all->m.pos[3 * v], all->m.pos[3 * v + 1], all->m.pos[3 * v + 2]};
        double nrm[3] = {all->m.nrm[3 * v], all->m.nrm[3 * v + 1], all->m.nrm[3 * v + 2]};
        bool found;
        size_t h = 0;
        if (all->vkey[v] != UINT64_MAX && !slot_of(&n, all->vkey[v], &found, &h))
            break;
        long g = new_vertex(&n, pos, nrm, all->vkey[v]);
        if (g < 0)
            break;
        memcpy(n.m.nrm + 3 * g, all->m.nrm + 3 * v, 3 * sizeof *n.m.nrm); /* as it was, not made unit again */
        if (all->vkey[v] != UINT64_MAX)
            keep_slot(&n, h, all->vkey[v], g);
        id[v] = (uint32_t)g;
        a->refs[g] = a->refs[v]; /* g <= v */
    }
    for (size_t t = 0; t < all->m.n_tri && !n.nomem; t++) {
        n.block = all->owner[t];
        add_triangle(&n, id[all->m.tri[3 * t]], id[all->m.tri[3 * t + 1]], id[all->m.tri[3 * t + 2]]);
    }
    free(id);
    if (n.nomem) {
        piece_free(&n);
        return -1;
    }
    piece_free(all);
    *all = n;
    a->dead = 0;
    return 0;
}

/* Level-2 block index at -> its coordinates. */
static void block_at(const struct iso_adapt *a, size_t at, int b[3])
{
    b[0] = (int)(at % (size_t)a->nb[2][0]);
    at /= (size_t)a->nb[2][0];
    b[1] = (int)(at % (size_t)a->nb[2][1]);
    b[2] = (int)(at / (size_t)a->nb[2][1]);
}

static bool in_box(const int b[3], const int lo[3], const int hi[3])
{
    return b[0] >= lo[0] && b[0] <= hi[0] && b[1] >= lo[1] && b[1] <= hi[1] && b[2] >= lo[2] && b[2] <= hi[2];
}

/* The samples of block blk at lo into F, the samples' least value and its count kept. */
static void write_block(struct iso_adapt *a, const int lo[3], const struct iso_grid *blk)
{
    float m = (float)a->gmin, bmin = INFINITY;
    size_t gone = 0, come = 0, at_bmin = 0;
    for (int z = 0; z < blk->nz; z++)
        for (int y = 0; y < blk->ny; y++) {
            float *row = a->F + at3(a, lo[0] + a->shift, lo[1] + y + a->shift, lo[2] + z + a->shift);
            for (int x = 0; x < blk->nx; x++)
                gone += row[x] == m;
            iso_grid_row(blk, y, z, row);
            for (int x = 0; x < blk->nx; x++) {
                if (row[x] < bmin)
                    bmin = row[x], at_bmin = 0;
                at_bmin += row[x] == bmin;
                come += row[x] == m;
            }
        }
    if (bmin < m) /* (every other sample is at least the old least) */
        a->gmin = bmin, a->n_min = at_bmin;
    else if ((a->n_min += come - gone) == 0)
        samples_min(a);
}

int iso_adapt_edit(struct iso_adapt *a, const int lo[3], const struct iso_grid *blk, struct iso_edit *ed,
                   struct sf_err *err)
{
    return iso_adapt_edit_ids(a, lo, blk, ed, NULL, err);
}

/* The triangles from n0 on of the kept mesh into ch (their ids and corners). 0 or -1. */
static int report_added(const struct iso_adapt *a, size_t n0, struct iso_change *ch)
{
    const struct trimesh *m = &a->all.m;
    size_t n = m->n_tri - n0;
    ch->added = malloc((n ? n : 1) * sizeof *ch->added);
    ch->corners = malloc((n ? n : 1) * 18 * sizeof *ch->corners);
    if (!ch->added || !ch->corners)
        return -1;
    for (size_t t = 0; t < n; t++) {
        ch->added[t] = a->ids[n0 + t];
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->tri[3 * (n0 + t) + k];
            memcpy(ch->corners + 18 * t + 6 * k, m->pos + 3 * v, 3 * sizeof(float));
            if (m->nrm)
                memcpy(ch->corners + 18 * t + 6 * k + 3, m->nrm + 3 * v, 3 * sizeof(float));
            else
                memset(ch->corners + 18 * t + 6 * k + 3, 0, 3 * sizeof(float));
        }
    }
    ch->n_added = n;
    return 0;
}

int iso_adapt_edit_ids(struct iso_adapt *a, const int lo[3], const struct iso_grid *blk, struct iso_edit *ed,
                       struct iso_change *ch, struct sf_err *err)
{
    if (a->pz)
        return pieces_edit(a->pz, lo, blk, ed, ch, err);
    memset(ed, 0, sizeof *ed);
    if (ch)
        *ch = (struct iso_change){.next_id = a->next_id};
    int n[3] = {blk->nx, blk->ny, blk->nz}, e0[3], e1[3];
    if (!a->kept)
        return sf_fail(err, SF_EINVAL, "", "the extraction is not kept (or an edit of it failed)");
    for (int d = 0; d < 3; d++)
        if (lo[d] < 0 || n[d] < 1 || lo[d] + (long)n[d] > a->N[d] - 2 * a->shift)
            return sf_fail(err, SF_EINVAL, "?region", "the region lies outside the volume's %d x %d x %d samples",
                           a->N[0] - 2 * a->shift, a->N[1] - 2 * a->shift, a->N[2] - 2 * a->shift);
    write_block(a, lo, blk);
    float pad = a->shift ? (float)fmin(a->iso1, a->gmin) : 0;
    ed->whole = pad != a->pad; /* the pad follows the samples' least: every border cell changes */
    if (ed->whole) {
        a->pad = pad;
        set_pad(a);
    }
    for (int d = 0; d < 3; d++) { /* the samples that changed, in the virtual grid */
        e0[d] = ed->whole ? 0 : lo[d] + a->shift;
        e1[d] = ed->whole ? a->N[d] - 1 : lo[d] + n[d] - 1 + a->shift;
    }
    /* the blocks whose decision can change, level by level: those holding a changed sample, and
     * above them those whose children or ring (mask_block) hold one of those */
    int blo[ISO_MAX_LEVELS + 1][3], bhi[ISO_MAX_LEVELS + 1][3], ulo[3], uhi[3], rlo[3], rhi[3];
    int c = 1 << (a->L - 2); /* the coarsest cell, in level-2 blocks */
    for (int l = 2; l <= a->L; l++)
        for (int d = 0; d < 3; d++) {
            int lo_ = l == 2 ? floordiv(e0[d] - 1, 2) : floordiv(blo[l - 1][d] - 1, 2);
            int hi_ = l == 2 ? floordiv(e1[d], 2) : floordiv(bhi[l - 1][d] + 1, 2);
            blo[l][d] = lo_ < 0 ? 0 : lo_;
            bhi[l][d] = hi_ >= a->nb[l][d] ? a->nb[l][d] - 1 : hi_;
            int u0 = blo[l][d] << (l - 2), u1 = ((bhi[l][d] + 1) << (l - 2)) - 1;
            ulo[d] = l == 2 || u0 < ulo[d] ? u0 : ulo[d];
            uhi[d] = l == 2 || u1 > uhi[d] ? u1 : uhi[d];
        }
    /* the cells to draw again: those, one block further (normals and neighbours' levels reach
     * that far), out to whole coarsest cells */
    for (int d = 0; d < 3; d++) {
        uhi[d] = uhi[d] >= a->nb[2][d] ? a->nb[2][d] - 1 : uhi[d];
        rlo[d] = floordiv(ulo[d] - 1, c) * c;
        rlo[d] = rlo[d] < 0 ? 0 : rlo[d];
        rhi[d] = (floordiv(uhi[d] + 1, c) + 1) * c - 1;
        rhi[d] = rhi[d] >= a->nb[2][d] ? a->nb[2][d] - 1 : rhi[d];
    }
    int b[3];
    for (b[2] = rlo[2]; b[2] <= rhi[2]; b[2]++) /* their cells leave the counts */
        for (b[1] = rlo[1]; b[1] <= rhi[1]; b[1]++)
            for (b[0] = rlo[0]; b[0] <= rhi[0]; b[0]++) {
                size_t at = block(a, 2, b[0], b[1], b[2]);
                a->cells[a->lev2[at]] -= a->bcells[at];
                a->feature_points -= a->bfeat[at];
            }
    for (int l = 2; l <= a->L; l++)
        for (b[2] = blo[l][2]; b[2] <= bhi[l][2]; b[2]++)
            for (b[1] = blo[l][1]; b[1] <= bhi[l][1]; b[1]++)
                for (b[0] = blo[l][0]; b[0] <= bhi[l][0]; b[0]++) {
                    size_t at = block(a, l, b[0], b[1], b[2]);
                    a->M[l][at] = 0;
                    a->berr[l][at] = 0;
                    mask_block(a, l, b, l == 2 && samples_mixed(a, b));
                }
    for (b[2] = ulo[2]; b[2] <= uhi[2]; b[2]++)
        for (b[1] = ulo[1]; b[1] <= uhi[1]; b[1]++)
            for (b[0] = ulo[0]; b[0] <= uhi[0]; b[0]++)
                cell_level(a, b);
    /* the old triangles of those cells out */
    struct piece *all = &a->all;
    size_t rcap = 0;
    bool nomem = false;
    for (size_t t = 0; t < all->m.n_tri;) {
        int ob[3];
        block_at(a, all->owner[t], ob);
        if (!in_box(ob, rlo, rhi)) {
            t++;
            continue;
        }
        for (int k = 0; k < 3; k++)
            if (--a->refs[all->m.tri[3 * t + k]] == 0)
                a->dead++;
        if (ch && !nomem) {
            nomem = mem_reserve((void **)&ch->removed, &rcap, ch->n_removed + 1, sizeof *ch->removed);
            if (!nomem)
                ch->removed[ch->n_removed++] = a->ids[t];
        }
        size_t last = --all->m.n_tri;
        memcpy(all->m.tri + 3 * t, all->m.tri + 3 * last, 3 * sizeof *all->m.tri);
        all->owner[t] = all->owner[last];
        a->ids[t] = a->ids[last];
        ed->triangles_removed++;
    }
    size_t n0 = all->m.n_tri;
    /* and the new ones in */
    struct piece pc = {0};
    for (b[2] = rlo[2]; b[2] <= rhi[2] && !pc.nomem; b[2]++)
        for (b[1] = rlo[1]; b[1] <= rhi[1]; b[1]++)
            for (b[0] = rlo[0]; b[0] <= rhi[0]; b[0]++)
                block_cells(a, &pc, b);
    for (int l = 1; l <= ISO_MAX_LEVELS; l++)
        a->cells[l] += pc.cells[l], ed->cells_rebuilt += pc.cells[l];
    a->feature_points += pc.feature_points;
    ed->triangles_added = (long)pc.m.n_tri;
    int rc = nomem || pc.nomem || merge_rebuilt(a, &pc) ? -1 : 0;
    piece_free(&pc);
    if (!rc && ch) {
        rc = report_added(a, n0, ch);
        ch->next_id = a->next_id;
    }
    if (!rc && a->dead > 4096 && a->dead > all->m.n_vert / 2)
        rc = compact(a);
    if (rc) {
        a->kept = false; /* half rebuilt: of no further use */
        return mesh_failed(a, err);
    }
    return 0;
}

size_t iso_adapt_bytes(const struct iso_adapt *a)
{
    if (a->pz)
        return sizeof *a + pieces_bytes(a->pz);
    size_t n = (size_t)a->N[0] * a->N[1] * a->N[2] * sizeof *a->F, nb2 = (size_t)a->nb[2][0] * a->nb[2][1] * a->nb[2][2];
    for (int l = 2; l <= a->L; l++)
        n += (size_t)a->nb[l][0] * a->nb[l][1] * a->nb[l][2] * (2 + (a->berr[l] ? sizeof(double) : 0));
    n += nb2 * 3 + a->all.cap * (sizeof(uint64_t) + sizeof(uint32_t));
    n += a->all.vcap * 2 * sizeof(float) + a->all.kcap * sizeof(uint64_t) + a->rcap * sizeof(uint32_t);
    return n + a->all.tcap * sizeof(uint32_t) + a->all.ocap * sizeof(uint32_t);
}
