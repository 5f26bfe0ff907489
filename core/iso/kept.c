/* kept.c - marching cubes kept for local rebuilds and iso changes (kept.h; seed 002's interactive
 * loop, issue 45), and the changes kept extractions report.
 *
 * What is kept: the samples (their own type); the cells in blocks of KB^3, each block with the
 * least and greatest of the samples its cells' corners read (so that the samples' least, which
 * sets the pad, and their range, which bounds an iso, follow edits without a pass over every
 * sample) and the list of its cells' triangles (id, vertices, cell within the block, in id order);
 * a pool of vertices, each with its key (mc.h: iso_vertex_key, the edge or cell centre it sits on)
 * and the number of triangles that use it. Every triangle is drawn by mc.c's code of iso_extract
 * (iso_box_extract, iso_box_whole), so a cell drawn again is drawn bit for bit as a fresh
 * extraction would.
 *
 * An edit of samples lo .. hi changes the corners of cells lo-1 .. hi and the normals of the
 * vertices on edges that end within one sample of them (central differences), i.e. of cells
 * lo-2 .. hi+1: those cells' triangles go, the box of them is drawn again, and its vertices on the
 * box's faces are matched by key to those the kept triangles round the box use (the same edge, the
 * same samples: the same vertex). When the least sample moves the closed grid's pad (iso - 1 or
 * the least, whichever is less), every border cell changes: the whole grid is drawn again. So is it
 * at a new iso, by the slabs' two passes (iso_box_whole), which pass over 64 cells of one state at a
 * time: on the CT head 0.42-0.48x Flying Edges' time where drawing the 8^3 blocks whose range
 * straddles the iso as boxes took 1.0-1.1x (tests/bench/RESULTS.md). A whole drawing is left flat,
 * as drawn (redraw_all): the blocks' lists and the pool are made when an edit first needs them
 * (iso_kept_index), so a slider's moves and the reads of their meshes never make them.
 * Written by hand: VTK and OpenVDB keep no mesh by cell. */
#include "kept.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void iso_change_free(struct iso_change *c)
{
    free(c->removed);
    free(c->added);
    free(c->corners);
    *c = (struct iso_change){.next_id = c->next_id};
}

#define KB 8 /* a block's cells a side (8: an edit of 16^3 samples reaches 3-4 blocks a side) */

struct ktri {
    uint32_t id, v[3];
    uint16_t cell;                   /* within its block: x + KB (y + KB z) */
};

struct kblock {
    struct ktri *t;                  /* in id order */
    uint32_t n, cap;
};

struct iso_kept {
    struct iso_grid g;               /* samples: k's own copy */
    struct iso_opts o;
    size_t esize;
    int shift, N[3], C[3], nb[3];    /* virtual samples, cells, blocks a side */
    size_t n_blocks;
    float *bmin, *bmax;              /* per block: of the real samples its cells' corners read */
    double least, most;              /* of the samples */
    float pad;
    struct kblock *blk;
    float *pos, *nrm;                /* the vertex pool: 3 each a slot */
    uint64_t *key;
    uint32_t *ref;                   /* triangles that use the slot (0: free) */
    uint32_t *free_v;                /* free slots */
    size_t n_vert, cap_vert, n_free, ref_cap;
    size_t n_tri;
    uint32_t next_id;
    struct iso_box box;              /* the extractor's lists and scratch, kept between calls */
    uint64_t *map_k;                 /* an edit's keys of the vertices round its box (key + 1; 0 empty) */
    uint32_t *map_v;
    size_t map_cap;
    uint32_t *vmap;                  /* an edit's box vertex -> slot */
    size_t vmap_cap;
    bool broken;
    bool flat;                       /* the mesh is box's as drawn (redraw_all), ids flat_first on in its
                                      * order; blk, the pool and its counts are not made (index_flat) */
    uint32_t flat_first;
};

/* ---- small helpers ---- */

static size_t sample_bytes(enum iso_type t) { return t == ISO_U8 ? 1 : t == ISO_F32 ? 4 : 2; }

struct pair {
    uint64_t key;
    uint32_t val;
};

/* Sorts n pairs by key (stable, 16 bits a pass, as many passes as the largest key needs). 0 or
 * SF_ENOMEM. */
static int sort_pairs(struct pair *a, size_t n, struct sf_err *err)
{
    uint64_t top = 0;
    for (size_t i = 0; i < n; i++)
        top |= a[i].key;
    if (n < 2 || !top)
        return 0;
    struct pair *b = malloc(n * sizeof *b);
    size_t *count = malloc(65536 * sizeof *count);
    if (!b || !count) {
        free(b);
        free(count);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    struct pair *from = a, *to = b;
    for (int shift = 0; shift < 64 && top >> shift; shift += 16) {
        memset(count, 0, 65536 * sizeof *count);
        for (size_t i = 0; i < n; i++)
            count[from[i].key >> shift & 0xffff]++;
        size_t sum = 0;
        for (size_t d = 0; d < 65536; d++) {
            size_t c = count[d];
            count[d] = sum;
            sum += c;
        }
        for (size_t i = 0; i < n; i++)
            to[count[from[i].key >> shift & 0xffff]++] = from[i];
        struct pair *t = from;
        from = to, to = t;
    }
    if (from != a)
        memcpy(a, from, n * sizeof *a);
    free(b);
    free(count);
    return 0;
}

static int cmp_u32(const void *p, const void *q)
{
    uint32_t a = *(const uint32_t *)p, b = *(const uint32_t *)q;
    return a < b ? -1 : a > b;
}

/* ---- the samples and their blocks ---- */

#define RANGE_OF(T)                                                                                    \
    do {                                                                                               \
        for (int z = r0[2]; z <= r1[2]; z++)                                                           \
            for (int y = r0[1]; y <= r1[1]; y++) {                                                     \
                const T *p = (const T *)k->g.samples + (size_t)nx * ((size_t)y + (size_t)ny * z);      \
                for (int x = r0[0]; x <= r1[0]; x++) {                                                 \
                    float v = (float)p[x];                                                             \
                    lo = v < lo ? v : lo;                                                              \
                    hi = v > hi ? v : hi;                                                              \
                }                                                                                      \
            }                                                                                          \
    } while (0)

/* Block b's sample range: of the real samples its cells' corners read. */
static void block_range(struct iso_kept *k, size_t b)
{
    int at[3] = {(int)(b % (size_t)k->nb[0]), (int)(b / (size_t)k->nb[0] % (size_t)k->nb[1]),
                 (int)(b / ((size_t)k->nb[0] * (size_t)k->nb[1]))};
    int r0[3], r1[3], n[3] = {k->g.nx, k->g.ny, k->g.nz}, nx = k->g.nx, ny = k->g.ny;
    float lo = INFINITY, hi = -INFINITY;
    for (int d = 0; d < 3; d++) {
        int v0 = at[d] * KB, v1 = at[d] * KB + KB < k->N[d] - 1 ? at[d] * KB + KB : k->N[d] - 1;
        r0[d] = v0 - k->shift < 0 ? 0 : v0 - k->shift;
        r1[d] = v1 - k->shift >= n[d] ? n[d] - 1 : v1 - k->shift;
        if (r0[d] > r1[d]) { /* (only pad samples) */
            k->bmin[b] = INFINITY, k->bmax[b] = -INFINITY;
            return;
        }
    }
    switch (k->g.type) {
    case ISO_U8: RANGE_OF(uint8_t); break;
    case ISO_I16: RANGE_OF(int16_t); break;
    case ISO_U16: RANGE_OF(uint16_t); break;
    default: RANGE_OF(float);
    }
    k->bmin[b] = lo, k->bmax[b] = hi;
}

static void samples_range(struct iso_kept *k)
{
    float lo = INFINITY, hi = -INFINITY;
    for (size_t b = 0; b < k->n_blocks; b++) {
        lo = k->bmin[b] < lo ? k->bmin[b] : lo;
        hi = k->bmax[b] > hi ? k->bmax[b] : hi;
    }
    k->least = lo, k->most = hi;
}

static float pad_of(const struct iso_kept *k)
{
    return k->shift ? (float)fmin(k->o.iso - 1, k->least) : 0.0f; /* as iso_begin */
}

/* ---- the vertex pool and the blocks' lists ---- */

static int pool_room(struct iso_kept *k, size_t n, struct sf_err *err)
{
    if (n <= k->cap_vert && n <= k->ref_cap)
        return 0;
    size_t cap = k->cap_vert > n ? k->cap_vert : n;
    if (cap > k->cap_vert) {
        cap = k->cap_vert * 2 > n ? k->cap_vert * 2 : n;
        float *p = realloc(k->pos, cap * 3 * sizeof *p);
        if (p)
            k->pos = p;
        float *q = k->o.normals ? realloc(k->nrm, cap * 3 * sizeof *q) : k->nrm;
        if (q)
            k->nrm = q;
        uint64_t *y = realloc(k->key, cap * sizeof *y);
        if (y)
            k->key = y;
        if (!p || (k->o.normals && !q) || !y)
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        k->cap_vert = cap;
    }
    uint32_t *r = realloc(k->ref, cap * sizeof *r);
    if (r)
        k->ref = r;
    uint32_t *f = realloc(k->free_v, cap * sizeof *f);
    if (f)
        k->free_v = f;
    if (!r || !f)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    k->ref_cap = cap;
    return 0;
}

static int block_room(struct kblock *b, size_t n, struct sf_err *err)
{
    if (n <= b->cap)
        return 0;
    size_t cap = b->cap * 2 > n ? b->cap * 2 : n < 8 ? 8 : n;
    struct ktri *t = realloc(b->t, cap * sizeof *t);
    if (!t)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    b->t = t, b->cap = (uint32_t)cap;
    return 0;
}

static void unref(struct iso_kept *k, uint32_t v)
{
    if (--k->ref[v] == 0)
        k->free_v[k->n_free++] = v;
}

/* The block of virtual cell c, and c within it. */
static size_t cell_block(const struct iso_kept *k, uint32_t c, uint16_t *local)
{
    int x = (int)(c % (uint32_t)k->C[0]), y = (int)(c / (uint32_t)k->C[0] % (uint32_t)k->C[1]),
        z = (int)(c / ((uint32_t)k->C[0] * (uint32_t)k->C[1]));
    *local = (uint16_t)(x % KB + KB * (y % KB + KB * (z % KB)));
    return (size_t)(x / KB) + (size_t)k->nb[0] * ((size_t)(y / KB) + (size_t)k->nb[1] * (size_t)(z / KB));
}

/* Vertex v of pos and nrm (NULL: none, 0s) as a change's corner: x y z nx ny nz into c. */
static void corner(float c[6], const float *pos, const float *nrm, uint32_t v)
{
    memcpy(c, pos + 3 * (size_t)v, 3 * sizeof *c);
    if (nrm)
        memcpy(c + 3, nrm + 3 * (size_t)v, 3 * sizeof *c);
    else
        memset(c + 3, 0, 3 * sizeof *c);
}

/* The box's triangles into the blocks, ids from the counter, each using slot vmap[v] of box vertex
 * v; what was added into ch (when not NULL). */
static int install(struct iso_kept *k, const uint32_t *vmap, bool corners, struct iso_change *ch, struct sf_err *err)
{
    const struct iso_box *x = &k->box;
    if (k->o.max_triangles && k->n_tri + x->n_tri > k->o.max_triangles)
        return sf_fail(err, SF_ELIMIT, "", "the isosurface would have %zu triangles, over the %zu of %s",
                       k->n_tri + x->n_tri, k->o.max_triangles,
                       k->o.max_triangles_by ? k->o.max_triangles_by : "the limit");
    if ((uint64_t)k->next_id + x->n_tri > UINT32_MAX)
        return sf_fail(err, SF_ELIMIT, "", "the model has run out of triangle ids");
    if (ch && !(ch->added = malloc((x->n_tri ? x->n_tri : 1) * sizeof *ch->added)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if (corners && !(ch->corners = malloc((x->n_tri ? x->n_tri : 1) * 18 * sizeof *ch->corners)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    struct kblock *b = NULL;
    uint16_t local = 0;
    uint32_t row = 1, yz = 0; /* the row of cells of the last triangle: its first cell (1: none yet), its block part */
    for (size_t i = 0; i < x->n_tri; i++) {
        uint32_t cl = x->cell[i];
        if (i == 0 || cl != x->cell[i - 1]) { /* (a cell's triangles come together, cells in rows) */
            if (row > cl || cl - row >= (uint32_t)k->C[0]) {
                b = &k->blk[cell_block(k, cl, &local)];
                row = cl - cl % (uint32_t)k->C[0];
                yz = (uint32_t)(b - k->blk) - (cl - row) / KB;
            } else {
                uint32_t cx = cl - row;
                b = &k->blk[yz + cx / KB];
                local = (uint16_t)(local - local % KB + cx % KB);
            }
        }
        int rc = block_room(b, (size_t)b->n + 1, err);
        if (rc)
            return rc;
        struct ktri *t = &b->t[b->n++];
        t->id = k->next_id++;
        t->cell = local;
        float *c = corners ? ch->corners + 18 * i : NULL;
        for (int q = 0; q < 3; q++) {
            uint32_t v = vmap ? vmap[x->tri[3 * i + q]] : x->tri[3 * i + q];
            t->v[q] = v;
            k->ref[v]++;
            if (c)
                corner(c + 6 * q, k->pos, k->nrm, v);
        }
        if (ch)
            ch->added[i] = t->id;
    }
    k->n_tri += x->n_tri;
    if (ch) {
        ch->n_added = x->n_tri;
        ch->next_id = k->next_id;
    }
    return 0;
}

/* Every id there is, in order, into ch's removed; the blocks emptied. */
static int all_ids(struct iso_kept *k, struct iso_change *ch, struct sf_err *err)
{
    ch->removed = malloc((k->n_tri ? k->n_tri : 1) * sizeof *ch->removed);
    if (!ch->removed)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    size_t n = 0;
    if (k->flat) { /* (no edit since: the ids run on from the first) */
        for (; n < k->n_tri; n++)
            ch->removed[n] = k->flat_first + (uint32_t)n;
    } else { /* marked in a map of the ids' range (sorted when that is sparse) */
        uint32_t first = k->next_id;
        for (size_t b = 0; b < k->n_blocks; b++)
            if (k->blk[b].n && k->blk[b].t[0].id < first)
                first = k->blk[b].t[0].id;
        size_t range = k->next_id - first;
        uint64_t *bits = range <= 64 * (size_t)k->n_tri + 64 ? calloc(range / 64 + 1, sizeof *bits) : NULL;
        for (size_t b = 0; b < k->n_blocks; b++) {
            for (uint32_t i = 0; i < k->blk[b].n; i++) {
                uint32_t id = k->blk[b].t[i].id - first;
                if (bits)
                    bits[id >> 6] |= (uint64_t)1 << (id & 63);
                else
                    ch->removed[n++] = id + first;
            }
            k->blk[b].n = 0;
        }
        if (bits) {
            for (size_t w = 0; w <= range / 64; w++)
                for (uint64_t m = bits[w]; m; m &= m - 1)
                    ch->removed[n++] = first + (uint32_t)(64 * w + (size_t)__builtin_ctzll(m));
            free(bits);
        } else if (n > 1) {
            struct pair *p = malloc(n * sizeof *p);
            if (!p)
                return sf_fail(err, SF_ENOMEM, "", "out of memory");
            for (size_t i = 0; i < n; i++)
                p[i] = (struct pair){ch->removed[i], 0};
            int rc = sort_pairs(p, n, err);
            for (size_t i = 0; i < n && !rc; i++)
                ch->removed[i] = (uint32_t)p[i].key;
            free(p);
            if (rc)
                return rc;
        }
    }
    ch->n_removed = n;
    k->n_tri = 0;
    return 0;
}

/* Every triangle out (their ids into ch), and the whole grid drawn again at k's iso and pad by the
 * slabs' two passes (iso_box_whole): the new mesh left flat in k->box as drawn, in iso_extract's
 * order, its ids the counter's next in that order. The blocks' lists and the pool are made from it
 * when an edit first needs them (index_flat): a slider's moves, one new iso after another, and
 * the reads of their meshes (iso_kept_mesh: the box's lists as they are) never make them. */
static int redraw_all(struct iso_kept *k, bool corners, struct iso_edit *ed, struct iso_change *ch, struct sf_err *err)
{
    ed->whole = true;
    int rc = all_ids(k, ch, err);
    if (rc)
        return rc;
    ed->triangles_removed = (long)ch->n_removed;
    k->flat = true; /* (the blocks are empty now, the pool stale) */
    if ((rc = iso_box_whole(&k->g, &k->o, &k->box, err)))
        return rc;
    const struct iso_box *x = &k->box;
    if ((uint64_t)k->next_id + x->n_tri > UINT32_MAX)
        return sf_fail(err, SF_ELIMIT, "", "the model has run out of triangle ids");
    ch->added = malloc((x->n_tri ? x->n_tri : 1) * sizeof *ch->added);
    ch->corners = corners ? malloc((x->n_tri ? x->n_tri : 1) * 18 * sizeof *ch->corners) : NULL;
    if (!ch->added || (corners && !ch->corners))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    k->flat_first = k->next_id;
    for (size_t i = 0; i < x->n_tri; i++) {
        ch->added[i] = k->next_id++;
        for (int q = 0; corners && q < 3; q++)
            corner(ch->corners + 18 * i + 6 * q, x->pos, k->o.normals ? x->nrm : NULL, x->tri[3 * i + q]);
    }
    k->n_tri = x->n_tri;
    ch->n_added = x->n_tri;
    ch->next_id = k->next_id;
    ed->cells_rebuilt = (long)x->n_cells;
    ed->triangles_added = (long)ch->n_added;
    return 0;
}

/* A flat mesh (redraw_all) made into the blocks' lists and the pool, its ids as they were. */
static int index_flat(struct iso_kept *k, struct sf_err *err)
{
    /* the box's vertices become the pool (its lists and the pool's swap) */
    struct iso_box *x = &k->box;
    float *p = k->pos, *q = k->nrm;
    uint64_t *y = k->key;
    size_t cap = k->cap_vert;
    k->pos = x->pos, k->nrm = x->nrm, k->key = x->key, k->cap_vert = x->cap_vert;
    x->pos = p, x->nrm = q, x->key = y, x->cap_vert = cap;
    k->n_vert = x->n_vert;
    k->n_free = 0;
    int rc = pool_room(k, k->n_vert, err);
    if (rc)
        return rc;
    /* the box's vertex lists (the pool's old ones: none the first time) as large as the pool's and
     * touched now, not in the next redraw of a box */
    if (x->cap_vert < k->cap_vert && iso_box_reserve(x, k->cap_vert, k->o.normals))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if (k->n_vert)
        memset(k->ref, 0, k->n_vert * sizeof *k->ref);
    /* each block's room at once: most blocks get their triangles in one piece */
    for (size_t i = 0, run = 0; i < x->n_tri; i += run) {
        uint16_t local;
        size_t b = cell_block(k, x->cell[i], &local);
        for (run = 1; i + run < x->n_tri && x->cell[i + run] == x->cell[i]; run++)
            ;
        if ((rc = block_room(&k->blk[b], k->blk[b].n + run, err)))
            return rc;
        k->blk[b].n += (uint32_t)run; /* (counted here, set back below) */
    }
    for (size_t b = 0; b < k->n_blocks; b++)
        k->blk[b].n = 0;
    uint32_t next = k->next_id;
    k->next_id = k->flat_first, k->n_tri = 0;
    rc = install(k, NULL, false, NULL, err);
    k->next_id = next;
    if (rc)
        return rc;
    for (size_t v = 0; v < k->n_vert; v++) /* (every vertex of a whole drawing is used) */
        if (!k->ref[v])
            k->free_v[k->n_free++] = (uint32_t)v;
    k->flat = false;
    return 0;
}

/* The keys' map of an edit: key -> slot, open addressing. */
static uint32_t *map_slot(struct iso_kept *k, uint64_t key)
{
    size_t mask = k->map_cap - 1, h = (size_t)((key * 0x9e3779b97f4a7c15u) >> 20) & mask;
    while (k->map_k[h] && k->map_k[h] != key + 1)
        h = (h + 1) & mask;
    return &k->map_v[h];
}

static void map_put(struct iso_kept *k, uint64_t key, uint32_t v)
{
    uint32_t *s = map_slot(k, key);
    k->map_k[s - k->map_v] = key + 1;
    *s = v;
}

static bool map_get(struct iso_kept *k, uint64_t key, uint32_t *v)
{
    uint32_t *s = map_slot(k, key);
    if (!k->map_k[s - k->map_v])
        return false;
    *v = *s;
    return true;
}

/* Cells lo .. hi drawn again: their triangles out, the box's in, its vertices on the box's faces
 * the kept ones. */
static int redraw_box(struct iso_kept *k, const int lo[3], const int hi[3], struct iso_edit *ed, struct iso_change *ch,
                      struct sf_err *err)
{
    int rc = iso_box_extract(&k->g, &k->o, k->pad, lo, hi, &k->box, err);
    if (rc)
        return rc;
    ed->cells_rebuilt = (long)(hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) * (hi[2] - lo[2] + 1);
    /* the blocks the box and the cells round it lie in */
    int b0[3], b1[3];
    size_t kept = 0, gone = 0;
    for (int d = 0; d < 3; d++) {
        b0[d] = (lo[d] > 0 ? lo[d] - 1 : 0) / KB;
        b1[d] = (hi[d] + 1 < k->C[d] ? hi[d] + 1 : k->C[d] - 1) / KB;
    }
    for (int z = b0[2]; z <= b1[2]; z++)
        for (int y = b0[1]; y <= b1[1]; y++)
            for (int x = b0[0]; x <= b1[0]; x++)
                kept += k->blk[x + (size_t)k->nb[0] * (y + (size_t)k->nb[1] * z)].n;
    size_t cap = 64;
    while (cap < 4 * kept + 64)
        cap *= 2;
    if (cap > k->map_cap) {
        free(k->map_k);
        free(k->map_v);
        k->map_k = malloc(cap * sizeof *k->map_k);
        k->map_v = malloc(cap * sizeof *k->map_v);
        k->map_cap = k->map_k && k->map_v ? cap : 0;
        if (!k->map_cap)
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    cap = k->map_cap;
    memset(k->map_k, 0, cap * sizeof *k->map_k);
    ch->removed = malloc((kept ? kept : 1) * sizeof *ch->removed);
    if (!ch->removed)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (int z = b0[2]; z <= b1[2]; z++)
        for (int y = b0[1]; y <= b1[1]; y++)
            for (int x = b0[0]; x <= b1[0]; x++) {
                struct kblock *b = &k->blk[x + (size_t)k->nb[0] * (y + (size_t)k->nb[1] * z)];
                uint32_t w = 0;
                for (uint32_t i = 0; i < b->n; i++) {
                    struct ktri t = b->t[i];
                    int c[3] = {x * KB + t.cell % KB, y * KB + t.cell / KB % KB, z * KB + t.cell / (KB * KB)};
                    bool in = c[0] >= lo[0] && c[0] <= hi[0] && c[1] >= lo[1] && c[1] <= hi[1] && c[2] >= lo[2] &&
                              c[2] <= hi[2];
                    if (in) {
                        ch->removed[gone++] = t.id;
                        for (int q = 0; q < 3; q++)
                            unref(k, t.v[q]);
                    } else {
                        for (int q = 0; q < 3; q++)
                            map_put(k, k->key[t.v[q]], t.v[q]);
                        b->t[w++] = t;
                    }
                }
                b->n = w;
            }
    qsort(ch->removed, gone, sizeof *ch->removed, cmp_u32);
    ch->n_removed = gone;
    k->n_tri -= gone;
    ed->triangles_removed = (long)gone;
    /* the box's vertices: those round it kept, the others into free slots */
    const struct iso_box *bx = &k->box;
    if (bx->n_vert > k->vmap_cap) {
        uint32_t *m = realloc(k->vmap, bx->n_vert * sizeof *m);
        if (!m)
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        k->vmap = m, k->vmap_cap = bx->n_vert;
    }
    size_t fresh = 0;
    for (size_t v = 0; v < bx->n_vert; v++) {
        uint32_t s;
        fresh += !map_get(k, bx->key[v], &s);
    }
    if (fresh > k->n_free && (rc = pool_room(k, k->n_vert + fresh - k->n_free, err)))
        return rc;
    for (size_t v = 0; v < bx->n_vert; v++) {
        uint32_t s;
        if (!map_get(k, bx->key[v], &s)) {
            s = k->n_free ? k->free_v[--k->n_free] : (uint32_t)k->n_vert++;
            memcpy(k->pos + 3 * (size_t)s, bx->pos + 3 * v, 3 * sizeof *k->pos);
            if (k->nrm)
                memcpy(k->nrm + 3 * (size_t)s, bx->nrm + 3 * v, 3 * sizeof *k->nrm);
            k->key[s] = bx->key[v];
            k->ref[s] = 0;
        }
        k->vmap[v] = s;
    }
    rc = install(k, k->vmap, true, ch, err);
    ed->triangles_added = (long)ch->n_added;
    return rc;
}

/* ---- the calls ---- */

int iso_kept_begin(const struct iso_grid *g, const struct iso_opts *o, struct iso_kept **out, struct sf_err *err)
{
    *out = NULL;
    if (g->nx < 2 || g->ny < 2 || g->nz < 2)
        return sf_fail(err, SF_EINVAL, "?dims", "a volume has at least 2 samples on every axis");
    if (!isfinite(o->iso))
        return sf_fail(err, SF_EINVAL, "?iso", "iso is a finite number");
    if (o->sharp)
        return sf_fail(err, SF_EINVAL, "?features", "feature points are the adaptive extraction's (adapt.h)");
    int s = o->closed ? 1 : 0;
    if ((double)(g->nx + 2 * s) * (g->ny + 2 * s) * (g->nz + 2 * s) * 16 >= 18446744073709551615.0 ||
        (double)(g->nx + 2 * s - 1) * (g->ny + 2 * s - 1) * (g->nz + 2 * s - 1) >= 4294967295.0)
        return sf_fail(err, SF_ELIMIT, "?dims", "a kept extraction has at most 2^32 cells");
    struct iso_kept *k = calloc(1, sizeof *k);
    if (!k)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    k->g = *g;
    k->o = *o;
    k->o.keep = false;
    k->shift = s;
    k->esize = sample_bytes(g->type);
    size_t n = (size_t)g->nx * (size_t)g->ny * (size_t)g->nz;
    k->g.samples = malloc(n * k->esize);
    int dims[3] = {g->nx, g->ny, g->nz};
    k->n_blocks = 1;
    for (int d = 0; d < 3; d++) {
        k->N[d] = dims[d] + 2 * s;
        k->C[d] = k->N[d] - 1;
        k->nb[d] = (k->C[d] + KB - 1) / KB;
        k->n_blocks *= (size_t)k->nb[d];
    }
    k->bmin = malloc(k->n_blocks * sizeof *k->bmin);
    k->bmax = malloc(k->n_blocks * sizeof *k->bmax);
    k->blk = calloc(k->n_blocks, sizeof *k->blk);
    if (!k->g.samples || !k->bmin || !k->bmax || !k->blk) {
        iso_kept_free(k);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    memcpy((void *)k->g.samples, g->samples, n * k->esize);
    for (size_t b = 0; b < k->n_blocks; b++)
        block_range(k, b);
    samples_range(k);
    k->pad = pad_of(k);
    struct iso_edit ed = {0};
    struct iso_change ch = {0};
    int rc = redraw_all(k, false, &ed, &ch, err); /* (the first mesh: no change to hand out) */
    iso_change_free(&ch);
    if (rc) {
        iso_kept_free(k);
        return rc;
    }
    *out = k;
    return 0;
}

/* iso_kept_mesh of a flat mesh: the box's lists as they are (every vertex used, in iso_extract's
 * order). */
static int flat_mesh(const struct iso_kept *k, struct trimesh *out, uint32_t **ids, struct sf_err *err)
{
    const struct iso_box *x = &k->box;
    size_t nv = x->n_vert, nt = x->n_tri;
    out->pos = malloc((nv ? nv : 1) * 3 * sizeof *out->pos);
    out->nrm = k->o.normals ? malloc((nv ? nv : 1) * 3 * sizeof *out->nrm) : NULL;
    out->tri = malloc((nt ? nt : 1) * 3 * sizeof *out->tri);
    *ids = malloc((nt ? nt : 1) * sizeof **ids);
    if (!out->pos || (k->o.normals && !out->nrm) || !out->tri || !*ids) {
        trimesh_free(out);
        free(*ids);
        *ids = NULL;
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    memcpy(out->pos, x->pos, nv * 3 * sizeof *out->pos);
    if (out->nrm)
        memcpy(out->nrm, x->nrm, nv * 3 * sizeof *out->nrm);
    memcpy(out->tri, x->tri, nt * 3 * sizeof *out->tri);
    for (size_t i = 0; i < nt; i++)
        (*ids)[i] = k->flat_first + (uint32_t)i;
    out->n_vert = nv, out->n_tri = nt;
    return 0;
}

int iso_kept_index(struct iso_kept *k, struct sf_err *err)
{
    if (k->broken)
        return sf_fail(err, SF_EINVAL, "", "an earlier change of this extraction failed: it is of no further use");
    int rc = k->flat ? index_flat(k, err) : 0;
    if (rc)
        k->broken = true;
    return rc;
}

int iso_kept_mesh(const struct iso_kept *k, struct trimesh *out, uint32_t **ids, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    *ids = NULL;
    if (k->flat)
        return flat_mesh(k, out, ids, err);
    size_t nt = k->n_tri, nv = 0;
    struct pair *tp = malloc((nt ? nt : 1) * sizeof *tp);
    uint32_t *where = malloc((nt ? nt : 1) * 3 * sizeof *where);
    struct pair *vp = malloc((k->n_vert ? k->n_vert : 1) * sizeof *vp);
    uint32_t *renum = malloc((k->n_vert ? k->n_vert : 1) * sizeof *renum);
    int rc = 0;
    if (!tp || !where || !vp || !renum) {
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        goto done;
    }
    size_t at = 0;
    for (size_t b = 0; b < k->n_blocks; b++)
        for (uint32_t i = 0; i < k->blk[b].n; i++, at++) {
            const struct ktri *t = &k->blk[b].t[i];
            tp[at] = (struct pair){t->id, (uint32_t)at};
            memcpy(where + 3 * at, t->v, sizeof t->v);
        }
    for (size_t v = 0; v < k->n_vert; v++)
        if (k->ref[v])
            vp[nv++] = (struct pair){k->key[v], (uint32_t)v};
    if ((rc = sort_pairs(tp, nt, err)) || (rc = sort_pairs(vp, nv, err)))
        goto done;
    out->pos = malloc((nv ? nv : 1) * 3 * sizeof *out->pos);
    out->nrm = k->nrm ? malloc((nv ? nv : 1) * 3 * sizeof *out->nrm) : NULL;
    out->tri = malloc((nt ? nt : 1) * 3 * sizeof *out->tri);
    *ids = malloc((nt ? nt : 1) * sizeof **ids);
    if (!out->pos || (k->nrm && !out->nrm) || !out->tri || !*ids) {
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
        goto done;
    }
    for (size_t i = 0; i < nv; i++) { /* numbered as iso_extract numbers them */
        uint32_t v = vp[i].val;
        renum[v] = (uint32_t)i;
        memcpy(out->pos + 3 * i, k->pos + 3 * (size_t)v, 3 * sizeof *out->pos);
        if (out->nrm)
            memcpy(out->nrm + 3 * i, k->nrm + 3 * (size_t)v, 3 * sizeof *out->nrm);
    }
    for (size_t i = 0; i < nt; i++) {
        (*ids)[i] = (uint32_t)tp[i].key;
        for (int q = 0; q < 3; q++)
            out->tri[3 * i + q] = renum[where[3 * (size_t)tp[i].val + q]];
    }
    out->n_vert = nv, out->n_tri = nt;
done:
    if (rc) {
        trimesh_free(out);
        free(*ids);
        *ids = NULL;
    }
    free(tp);
    free(where);
    free(vp);
    free(renum);
    return rc;
}

/* Samples lo .. lo + blk's size - 1 from blk (converted to k's type when blk's differs). */
static int write_samples(struct iso_kept *k, const int lo[3], const struct iso_grid *blk, struct sf_err *err)
{
    float *row = blk->type == k->g.type ? NULL : malloc((size_t)blk->nx * sizeof *row);
    if (blk->type != k->g.type && !row)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    size_t bs = sample_bytes(blk->type);
    for (int z = 0; z < blk->nz; z++)
        for (int y = 0; y < blk->ny; y++) {
            size_t at = (size_t)lo[0] + (size_t)k->g.nx * ((size_t)(lo[1] + y) + (size_t)k->g.ny * (size_t)(lo[2] + z));
            char *dst = (char *)k->g.samples + at * k->esize;
            if (!row) {
                memcpy(dst, (const char *)blk->samples + bs * (size_t)blk->nx * ((size_t)y + (size_t)blk->ny * z),
                       (size_t)blk->nx * bs);
                continue;
            }
            iso_grid_row(blk, y, z, row);
            for (int x = 0; x < blk->nx; x++) {
                float v = row[x];
                switch (k->g.type) {
                case ISO_U8: ((uint8_t *)dst)[x] = (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : lrintf(v)); break;
                case ISO_I16: ((int16_t *)dst)[x] = (int16_t)(v < -32768 ? -32768 : v > 32767 ? 32767 : lrintf(v)); break;
                case ISO_U16: ((uint16_t *)dst)[x] = (uint16_t)(v < 0 ? 0 : v > 65535 ? 65535 : lrintf(v)); break;
                default: ((float *)dst)[x] = v;
                }
            }
        }
    free(row);
    return 0;
}

int iso_kept_edit(struct iso_kept *k, const int lo[3], const struct iso_grid *blk, struct iso_edit *ed,
                  struct iso_change *ch, struct sf_err *err)
{
    memset(ed, 0, sizeof *ed);
    *ch = (struct iso_change){.next_id = k->next_id};
    int n[3] = {blk->nx, blk->ny, blk->nz}, dims[3] = {k->g.nx, k->g.ny, k->g.nz};
    if (k->broken)
        return sf_fail(err, SF_EINVAL, "", "an earlier change of this extraction failed: it is of no further use");
    for (int d = 0; d < 3; d++)
        if (lo[d] < 0 || n[d] < 1 || lo[d] + (long)n[d] > dims[d])
            return sf_fail(err, SF_EINVAL, "?region", "the region lies outside the volume's %d x %d x %d samples",
                           dims[0], dims[1], dims[2]);
    int rc = iso_kept_index(k, err);
    if (rc)
        return rc;
    if ((rc = write_samples(k, lo, blk, err)))
        return rc;
    int e0[3], e1[3], c0[3], c1[3];
    for (int d = 0; d < 3; d++) { /* the samples written, in the virtual grid, and their blocks */
        e0[d] = lo[d] + k->shift;
        e1[d] = lo[d] + n[d] - 1 + k->shift;
        int b0 = (e0[d] + KB - 1) / KB - 1, b1 = e1[d] / KB;
        c0[d] = b0 < 0 ? 0 : b0;
        c1[d] = b1 >= k->nb[d] ? k->nb[d] - 1 : b1;
    }
    for (int z = c0[2]; z <= c1[2]; z++)
        for (int y = c0[1]; y <= c1[1]; y++)
            for (int x = c0[0]; x <= c1[0]; x++)
                block_range(k, x + (size_t)k->nb[0] * (y + (size_t)k->nb[1] * z));
    samples_range(k);
    float pad = pad_of(k);
    if (pad != k->pad) { /* the pad follows the samples' least: every border cell changes */
        k->pad = pad;
        rc = redraw_all(k, true, ed, ch, err);
    } else {
        for (int d = 0; d < 3; d++) { /* the cells whose corners or vertices' normals read them */
            c0[d] = e0[d] - 2 < 0 ? 0 : e0[d] - 2;
            c1[d] = e1[d] + 1 >= k->C[d] ? k->C[d] - 1 : e1[d] + 1;
        }
        rc = redraw_box(k, c0, c1, ed, ch, err);
    }
    if (rc) {
        k->broken = true;
        iso_change_free(ch);
    }
    return rc;
}

int iso_kept_iso(struct iso_kept *k, double iso, bool corners, struct iso_edit *ed, struct iso_change *ch,
                 struct sf_err *err)
{
    memset(ed, 0, sizeof *ed);
    *ch = (struct iso_change){.next_id = k->next_id};
    if (k->broken)
        return sf_fail(err, SF_EINVAL, "", "an earlier change of this extraction failed: it is of no further use");
    if (!isfinite(iso))
        return sf_fail(err, SF_EINVAL, "?value", "value is the new iso, a finite number");
    if (!(iso >= k->least && iso < k->most)) /* (samples over the iso are inside: at the greatest, none) */
        return sf_fail(err, SF_EINVAL, "?value", "the samples run from %g to %g: an iso of %g has no surface", k->least,
                       k->most, iso);
    k->o.iso = iso;
    k->pad = pad_of(k);
    int rc = redraw_all(k, corners, ed, ch, err);
    if (rc) {
        k->broken = true;
        iso_change_free(ch);
    }
    return rc;
}

size_t iso_kept_bytes(const struct iso_kept *k)
{
    size_t n = sizeof *k + (size_t)k->g.nx * (size_t)k->g.ny * (size_t)k->g.nz * k->esize;
    n += k->n_blocks * (2 * sizeof(float) + sizeof(struct kblock));
    for (size_t b = 0; b < k->n_blocks; b++)
        n += k->blk[b].cap * sizeof(struct ktri);
    n += k->cap_vert * ((k->nrm ? 6 : 3) * sizeof(float) + sizeof(uint64_t)) + k->ref_cap * 2 * sizeof(uint32_t);
    n += k->map_cap * (sizeof(uint64_t) + sizeof(uint32_t)) + k->vmap_cap * sizeof(uint32_t);
    return n + iso_box_bytes(&k->box);
}

void iso_kept_free(struct iso_kept *k)
{
    if (!k)
        return;
    free((void *)k->g.samples);
    free(k->bmin);
    free(k->bmax);
    if (k->blk)
        for (size_t b = 0; b < k->n_blocks; b++)
            free(k->blk[b].t);
    free(k->blk);
    free(k->pos);
    free(k->nrm);
    free(k->key);
    free(k->ref);
    free(k->free_v);
    free(k->map_k);
    free(k->map_v);
    free(k->vmap);
    iso_box_free(&k->box);
    free(k);
}
