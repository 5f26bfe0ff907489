/* labels.c - the surfaces of a label map (labels.h): cells visited plane by plane of z, each cell's
 * faces divided by the face rule, the graphs they make closed inside the cell; the vertices on
 * edges and faces, shared with the neighbour cells, found through ids kept for two planes.
 * Written here: the libraries that do this are VTK's (vtkSurfaceNets3D, whose label surfaces are
 * not manifold where a label's voxels touch along an edge, and vtkDiscreteFlyingEdges3D, whose
 * labels' triangles are not shared where three labels meet: README.md), and surfd links no VTK. */
#include "labels.h"
#include "cube.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

#define NONE UINT32_MAX
/* A cell's points: its 12 edges' middles (0-11; edges as mc.c numbers them) and its 6 faces'
 * centres (12-17, faces -x, +x, -y, +y, -z, +z). */
#define N_POINTS 18
#define MAX_SEGS 24              /* 4 a face */

/* corners c = x + 2y + 4z; edges 0-3 along x (index y + 2z), 4-7 along y (x + 2z), 8-11 along z (x + 2y) */
static int edge_of(int a, int b)
{
    int d = a ^ b, lo = a < b ? a : b;
    int x = lo & 1, y = lo >> 1 & 1, z = lo >> 2 & 1;
    return d == 1 ? y + 2 * z : d == 2 ? 4 + x + 2 * z : 8 + x + 2 * y;
}

/* The faces (bit mask) point p lies on. */
static int point_faces(int p)
{
    if (p >= 12)
        return 1 << (p - 12);
    int k = p & 3, lo = k & 1, hi = k >> 1;
    if (p < 4) /* along x: (y, z) = (lo, hi) */
        return 1 << (2 + lo) | 1 << (4 + hi);
    if (p < 8)
        return 1 << lo | 1 << (4 + hi);
    return 1 << lo | 1 << (2 + hi);
}

/* Point p in cell units. */
static void point_at(int p, double c[3])
{
    if (p >= 12) {
        int f = p - 12;
        c[0] = c[1] = c[2] = 0.5;
        c[f >> 1] = f & 1;
        return;
    }
    int k = p & 3, axis = p >> 2;
    int other[2] = {axis == 0 ? 1 : 0, axis == 2 ? 1 : 2};
    c[axis] = 0.5;
    c[other[0]] = k & 1;
    c[other[1]] = k >> 1;
}

/* A segment of a face's division, from point a to point b; r is the label (a slot of the cell's)
 * on its right seen from outside the cell, l on its left: the triangles drawn over it face out of
 * r, into l. */
struct seg {
    uint8_t a, b, r, l;
};

struct cell {
    uint16_t label[8];       /* the cell's labels, by slot */
    uint8_t slot[8];         /* each corner's label slot */
    int n_slots;
    struct seg seg[MAX_SEGS];
    int n_seg;
};

static void add_seg(struct cell *c, int a, int b, int r, int l)
{
    c->seg[c->n_seg++] = (struct seg){(uint8_t)a, (uint8_t)b, (uint8_t)r, (uint8_t)l};
}

/* Face f divided among its corners' labels (labels.h): with the corners q counter-clockwise seen
 * from outside and edge e_i from q_i to q_i+1, corner q_i's part is bounded by a path from e_i-1's
 * middle to e_i's (through the centre where three or four labels meet), the part on its right. */
static void face_segments(struct cell *c, int f)
{
    const int *q = iso_face_ccw[f];
    int s[4], e[4], cross = 0;
    for (int i = 0; i < 4; i++)
        s[i] = c->slot[q[i]], e[i] = edge_of(q[i], q[(i + 1) & 3]);
    for (int i = 0; i < 4; i++)
        cross += s[i] != s[(i + 1) & 3];
    if (!cross)
        return;
    if (cross == 2) { /* two runs of corners: one segment, the run from q_i+1 to q_j on its right */
        int i = 0, j;
        while (s[i] == s[(i + 1) & 3])
            i++;
        for (j = i + 1; s[j & 3] == s[(j + 1) & 3]; j++)
            ;
        add_seg(c, e[i], e[j & 3], s[(i + 1) & 3], s[(j + 1) & 3]);
        return;
    }
    int join = -1;
    if (cross == 4 && s[0] == s[2] && s[1] == s[3])
        join = c->label[s[0]] < c->label[s[1]] ? s[0] : s[1]; /* the smaller label (the background) joins */
    else if (cross == 4 && s[0] == s[2])
        join = s[0];
    else if (cross == 4 && s[1] == s[3])
        join = s[1];
    if (join >= 0) { /* the other two corners cut off */
        for (int i = 0; i < 4; i++)
            if (s[i] != join)
                add_seg(c, e[(i + 3) & 3], e[i], s[i], join);
        return;
    }
    for (int i = 0; i < 4; i++) /* three or four labels: to the centre */
        if (s[i] != s[(i + 1) & 3])
            add_seg(c, 12 + f, e[i], s[i], s[(i + 1) & 3]);
}

static int find(int8_t *parent, int p)
{
    while (parent[p] != p)
        p = parent[p] = parent[parent[p]];
    return p;
}

/* ---- the extraction ---- */

struct ext {
    const struct iso_grid *g;
    int n_labels;
    int px, py, pz;          /* padded sample counts: the border's layer of background round the grid */
    uint16_t *plane[2];      /* the padded labels of planes Z and Z + 1 */
    uint32_t *xe[2], *ye[2], *zf[2]; /* vertex ids of planes Z and Z + 1: x and y edges, z faces */
    uint32_t *ze, *xf, *yf;  /* ... between them: z edges, x and y faces */
    int X, Y, Z;             /* the cell */
    struct iso_labels *out;
    size_t vcap, tcap, scap;
    size_t max_tri;
    const char *max_by;
    struct sf_err *err;
    int rc;
};

/* A new vertex at c (cell units of the current cell): its id, or NONE (ext's rc set). */
static uint32_t new_vertex(struct ext *x, const double c[3])
{
    struct iso_labels *o = x->out;
    if (o->n_vert >= ISO_MAX_VERTICES) {
        x->rc = sf_fail(x->err, SF_ELIMIT, "", "the surfaces have over %u vertices", ISO_MAX_VERTICES);
        return NONE;
    }
    if (mem_reserve((void **)&o->pos, &x->vcap, 3 * (o->n_vert + 1), sizeof *o->pos)) {
        x->rc = sf_fail(x->err, SF_ENOMEM, "", "out of memory for the surfaces' vertices");
        return NONE;
    }
    const int at[3] = {x->X, x->Y, x->Z};
    for (int a = 0; a < 3; a++) /* padded index at - 1 + c is the sample index */
        o->pos[3 * o->n_vert + (size_t)a] = (float)(x->g->origin[a] + x->g->spacing[a] * (at[a] - 1 + c[a]));
    return (uint32_t)o->n_vert++;
}

/* Where point p of the current cell keeps its vertex id (shared with the cells round it). */
static uint32_t *point_slot(struct ext *x, int p)
{
    size_t X = (size_t)x->X, Y = (size_t)x->Y, px = (size_t)x->px;
    if (p < 4)
        return &x->xe[p >> 1][X + px * (Y + (p & 1))];
    if (p < 8)
        return &x->ye[(p - 4) >> 1][X + ((p - 4) & 1) + px * Y];
    if (p < 12)
        return &x->ze[X + ((p - 8) & 1) + px * (Y + ((p - 8) >> 1))];
    switch (p - 12) {
    case 0: return &x->xf[X + px * Y];
    case 1: return &x->xf[X + 1 + px * Y];
    case 2: return &x->yf[X + px * Y];
    case 3: return &x->yf[X + px * (Y + 1)];
    case 4: return &x->zf[0][X + px * Y];
    default: return &x->zf[1][X + px * Y];
    }
}

static uint32_t point_id(struct ext *x, int p)
{
    uint32_t *id = point_slot(x, p);
    if (*id == NONE) {
        double c[3];
        point_at(p, c);
        *id = new_vertex(x, c);
    }
    return *id;
}

/* Triangle (a, b, c), counter-clockwise seen from outside label in, facing label out. */
static void add_tri(struct ext *x, uint32_t a, uint32_t b, uint32_t c, int in, int out)
{
    struct iso_labels *o = x->out;
    if (x->rc || a == NONE || b == NONE || c == NONE)
        return;
    if (x->max_tri && o->n_tri >= x->max_tri) {
        x->rc = sf_fail(x->err, SF_ELIMIT, "", "the surfaces have over %zu triangles (%s)", x->max_tri,
                        x->max_by ? x->max_by : "the limit");
        return;
    }
    if (mem_reserve((void **)&o->tri, &x->tcap, 3 * (o->n_tri + 1), sizeof *o->tri) ||
        mem_reserve((void **)&o->side, &x->scap, 2 * (o->n_tri + 1), sizeof *o->side)) {
        x->rc = sf_fail(x->err, SF_ENOMEM, "", "out of memory for the surfaces' triangles");
        return;
    }
    uint32_t *t = o->tri + 3 * o->n_tri;
    t[0] = a, t[1] = b, t[2] = c;
    o->side[2 * o->n_tri] = (uint16_t)in;
    o->side[2 * o->n_tri + 1] = (uint16_t)out;
    o->n_tri++;
}

static void centroid(const double (*pts)[3], const int *which, int n, double c[3])
{
    c[0] = c[1] = c[2] = 0;
    for (int i = 0; i < n; i++)
        for (int a = 0; a < 3; a++)
            c[a] += pts[which[i]][a] / n;
}

/* A component of two labels, a loop: marching cubes' polygon, fanned from a point none of whose
 * diagonals lies in one face (the neighbour's fan could draw it too), else from its centre. */
static void close_loop(struct ext *x, const struct cell *c, const int *segs, int n)
{
    const struct seg *s0 = &c->seg[segs[0]];
    int r = s0->r, l = s0->l, next[N_POINTS], v[MAX_SEGS], nv = 0;
    for (int p = 0; p < N_POINTS; p++)
        next[p] = -1;
    for (int i = 0; i < n; i++) { /* each segment with r on its right */
        const struct seg *s = &c->seg[segs[i]];
        if (s->r == r)
            next[s->a] = s->b;
        else
            next[s->b] = s->a;
    }
    for (int p = s0->r == r ? s0->a : s0->b; p >= 0 && nv < n && (nv == 0 || p != v[0]); p = next[p])
        v[nv++] = p;
    int apex = -1;
    for (int i = 0; i < nv && apex < 0; i++) {
        bool ok = true;
        for (int k = 2; k + 1 < nv && ok; k++)
            ok = !(point_faces(v[i]) & point_faces(v[(i + k) % nv]));
        if (ok)
            apex = i;
    }
    int in = c->label[r], out = c->label[l];
    uint32_t id[MAX_SEGS];
    for (int i = 0; i < nv; i++)
        id[i] = point_id(x, v[i]);
    if (apex >= 0) {
        for (int k = 1; k + 1 < nv; k++)
            add_tri(x, id[apex], id[(apex + k) % nv], id[(apex + k + 1) % nv], in, out);
        return;
    }
    double pts[N_POINTS][3], m[3];
    for (int i = 0; i < nv; i++)
        point_at(v[i], pts[v[i]]);
    centroid((const double(*)[3])pts, v, nv, m);
    uint32_t centre = new_vertex(x, m);
    for (int i = 0; i < nv; i++)
        add_tri(x, centre, id[i], id[(i + 1) % nv], in, out);
}

/* A component where three or more labels meet: a cone from its points' centre over its segments.
 * The boundary of each label's part round it is a closed walk along the segments (the label on
 * the right of each); a label with two walks would touch itself at the apex, so it takes the
 * centre: every segment then draws a band from itself to a copy halfway to the apex, and each
 * other label's walk is capped by a fan from a point inside those copies. */
static void close_junction(struct ext *x, const struct cell *c, const int *segs, int n)
{
    /* half-edge 2i: segment i from a to b with its r on the right; 2i + 1: from b to a with l */
    int8_t from_of[N_POINTS][8];
    int walk[2 * MAX_SEGS], n_walks = 0, walk_slot[2 * MAX_SEGS], walks_of[8] = {0};
    memset(from_of, -1, sizeof from_of);
    int pts_used[N_POINTS], n_pts = 0;
    bool used[N_POINTS] = {false};
    for (int i = 0; i < n; i++) {
        const struct seg *s = &c->seg[segs[i]];
        from_of[s->a][s->r] = (int8_t)(2 * i);
        from_of[s->b][s->l] = (int8_t)(2 * i + 1);
        for (int e = 0; e < 2; e++) {
            int p = e ? s->b : s->a;
            if (!used[p])
                used[p] = true, pts_used[n_pts++] = p;
        }
    }
    for (int h = 0; h < 2 * n; h++)
        walk[h] = -1;
    for (int h0 = 0; h0 < 2 * n; h0++) {
        if (walk[h0] >= 0)
            continue;
        const struct seg *s0 = &c->seg[segs[h0 / 2]];
        int lab = h0 & 1 ? s0->l : s0->r;
        for (int h = h0, k = 0; h >= 0 && walk[h] < 0 && k < 2 * n; k++) {
            walk[h] = n_walks;
            const struct seg *s = &c->seg[segs[h / 2]];
            h = from_of[h & 1 ? s->a : s->b][lab];
        }
        walk_slot[n_walks++] = lab;
        walks_of[lab]++;
    }
    double pts[N_POINTS][3], apex[3];
    for (int i = 0; i < n_pts; i++)
        point_at(pts_used[i], pts[pts_used[i]]);
    centroid((const double(*)[3])pts, pts_used, n_pts, apex);
    int owner = -1; /* the label that takes the centre: the most walks, then the smallest */
    for (int k = 0; k < c->n_slots; k++)
        if (walks_of[k] >= 2 && (owner < 0 || walks_of[k] > walks_of[owner] ||
                                 (walks_of[k] == walks_of[owner] && c->label[k] < c->label[owner])))
            owner = k;
    if (owner < 0) {
        uint32_t centre = new_vertex(x, apex);
        for (int i = 0; i < n; i++) {
            const struct seg *s = &c->seg[segs[i]];
            add_tri(x, centre, point_id(x, s->a), point_id(x, s->b), c->label[s->r], c->label[s->l]);
        }
        return;
    }
    x->out->centres++;
    uint32_t inner[N_POINTS];
    double half[N_POINTS][3];
    for (int i = 0; i < n_pts; i++) {
        int p = pts_used[i];
        for (int a = 0; a < 3; a++)
            half[p][a] = apex[a] + 0.5 * (pts[p][a] - apex[a]);
        inner[p] = new_vertex(x, half[p]);
    }
    for (int i = 0; i < n; i++) {
        const struct seg *s = &c->seg[segs[i]];
        int in = c->label[s->r], out = c->label[s->l];
        uint32_t a = point_id(x, s->a), b = point_id(x, s->b);
        add_tri(x, inner[s->a], a, b, in, out);
        add_tri(x, inner[s->a], b, inner[s->b], in, out);
    }
    for (int w = 0; w < n_walks; w++) {
        if (walk_slot[w] == owner)
            continue;
        double m[3] = {0, 0, 0};
        int len = 0;
        for (int h = 0; h < 2 * n; h++)
            if (walk[h] == w) {
                const struct seg *s = &c->seg[segs[h / 2]];
                int p = h & 1 ? s->b : s->a;
                for (int a = 0; a < 3; a++)
                    m[a] += half[p][a];
                len++;
            }
        for (int a = 0; a < 3; a++) /* within the copies, so no cap triangle lies flat in their faces */
            m[a] = apex[a] + 0.5 * (m[a] / len - apex[a]);
        uint32_t cap = new_vertex(x, m);
        for (int h = 0; h < 2 * n; h++)
            if (walk[h] == w) {
                const struct seg *s = &c->seg[segs[h / 2]];
                int p = h & 1 ? s->b : s->a, q = h & 1 ? s->a : s->b;
                add_tri(x, cap, inner[p], inner[q], c->label[walk_slot[w]], c->label[owner]);
            }
    }
}

/* The cell at (X, Y, Z) (padded) whose corners' labels are lab. */
static void do_cell(struct ext *x, const uint16_t lab[8])
{
    struct cell c;
    c.n_slots = 0;
    c.n_seg = 0;
    for (int k = 0; k < 8; k++) {
        int s = 0;
        while (s < c.n_slots && c.label[s] != lab[k])
            s++;
        if (s == c.n_slots)
            c.label[c.n_slots++] = lab[k];
        c.slot[k] = (uint8_t)s;
    }
    for (int f = 0; f < 6; f++)
        face_segments(&c, f);
    int8_t parent[N_POINTS];
    for (int p = 0; p < N_POINTS; p++)
        parent[p] = (int8_t)p;
    for (int i = 0; i < c.n_seg; i++)
        parent[find(parent, c.seg[i].a)] = (int8_t)find(parent, c.seg[i].b);
    bool done[MAX_SEGS] = {false};
    for (int i = 0; i < c.n_seg && !x->rc; i++) {
        if (done[i])
            continue;
        int root = find(parent, c.seg[i].a), segs[MAX_SEGS], n = 0;
        bool junction = false;
        for (int k = i; k < c.n_seg; k++)
            if (!done[k] && find(parent, c.seg[k].a) == root) {
                done[k] = true;
                segs[n++] = k;
                junction = junction || c.seg[k].a >= 12 || c.seg[k].b >= 12;
            }
        if (junction)
            close_junction(x, &c, segs, n);
        else
            close_loop(x, &c, segs, n);
    }
}

/* Padded plane Z of the labels into row (the background beyond the grid): 0, or SF_EINVAL. */
static int fill_plane(struct ext *x, int Z, uint16_t *row)
{
    const struct iso_grid *g = x->g;
    memset(row, 0, sizeof *row * (size_t)x->px * (size_t)x->py);
    if (Z < 1 || Z > g->nz)
        return 0;
    for (int y = 0; y < g->ny; y++) {
        size_t at = (size_t)g->nx * ((size_t)y + (size_t)g->ny * (size_t)(Z - 1));
        uint16_t *r = row + (size_t)x->px * (size_t)(y + 1) + 1;
        for (int i = 0; i < g->nx; i++) {
            unsigned v = g->type == ISO_U8 ? ((const uint8_t *)g->samples)[at + (size_t)i]
                                           : ((const uint16_t *)g->samples)[at + (size_t)i];
            if (v > (unsigned)x->n_labels)
                return sf_fail(x->err, SF_EINVAL, "", "sample (%d, %d, %d) is label %u of %d", i, y, Z - 1, v,
                               x->n_labels);
            r[i] = (uint16_t)v;
        }
    }
    return 0;
}

/* Each label's triangles listed together (of, first). */
static int bucket(struct iso_labels *o, struct sf_err *err)
{
    size_t n = (size_t)o->n_labels;
    o->first = calloc(n + 2, sizeof *o->first);
    o->of = malloc(sizeof *o->of * (2 * o->n_tri + 1));
    o->remap = malloc(sizeof *o->remap * (o->n_vert + 1));
    o->stamp = calloc(o->n_vert + 1, sizeof *o->stamp);
    if (!o->first || !o->of || !o->remap || !o->stamp)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the labels' triangle lists");
    for (size_t t = 0; t < o->n_tri; t++)
        for (int s = 0; s < 2; s++)
            o->first[o->side[2 * t + (size_t)s] + 1]++;
    for (size_t k = 1; k <= n + 1; k++)
        o->first[k] += o->first[k - 1];
    size_t *at = malloc(sizeof *at * (n + 1));
    if (!at)
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the labels' triangle lists");
    memcpy(at, o->first, sizeof *at * (n + 1));
    for (size_t t = 0; t < o->n_tri; t++)
        for (int s = 0; s < 2; s++)
            o->of[at[o->side[2 * t + (size_t)s]]++] = (uint32_t)t;
    free(at);
    return 0;
}

int iso_labels_extract(const struct iso_grid *g, int n_labels, bool closed, size_t max_triangles, const char *max_by,
                       const struct sf_progress *pr, struct iso_labels *out, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    out->n_labels = n_labels;
    if ((g->type != ISO_U8 && g->type != ISO_U16) || n_labels < 0 || n_labels > ISO_LABELS_MAX)
        return sf_fail(err, SF_EINVAL, "", "a label map's index grid is uint8 or uint16, of up to %d labels",
                       ISO_LABELS_MAX);
    if (g->nx < 2 || g->ny < 2 || g->nz < 2)
        return sf_fail(err, SF_EINVAL, "", "a label map has 2 samples or more along each axis");
    struct ext x = {.g = g, .n_labels = n_labels, .px = g->nx + 2, .py = g->ny + 2, .pz = g->nz + 2, .out = out,
                    .max_tri = max_triangles, .max_by = max_by, .err = err};
    size_t plane = (size_t)x.px * (size_t)x.py;
    bool ok = true;
    for (int k = 0; k < 2; k++) {
        ok = ok && (x.plane[k] = malloc(sizeof(uint16_t) * plane)) && (x.xe[k] = malloc(sizeof(uint32_t) * plane)) &&
             (x.ye[k] = malloc(sizeof(uint32_t) * plane)) && (x.zf[k] = malloc(sizeof(uint32_t) * plane));
    }
    ok = ok && (x.ze = malloc(sizeof(uint32_t) * plane)) && (x.xf = malloc(sizeof(uint32_t) * plane)) &&
         (x.yf = malloc(sizeof(uint32_t) * plane));
    if (!ok)
        x.rc = sf_fail(err, SF_ENOMEM, "", "out of memory for the labels' planes");
    /* closed: every cell that has a padding corner too; open: the grid's own cells */
    int lo = closed ? 0 : 1, hx = closed ? x.px - 2 : x.px - 3, hy = closed ? x.py - 2 : x.py - 3,
        hz = closed ? x.pz - 2 : x.pz - 3;
    if (!x.rc) {
        memset(x.xe[0], 0xff, sizeof(uint32_t) * plane);
        memset(x.ye[0], 0xff, sizeof(uint32_t) * plane);
        memset(x.zf[0], 0xff, sizeof(uint32_t) * plane);
        x.rc = fill_plane(&x, lo, x.plane[0]);
    }
    for (int Z = lo; Z <= hz && !x.rc; Z++) {
        if ((x.rc = fill_plane(&x, Z + 1, x.plane[1])) || (x.rc = sf_poll(pr, (double)(Z - lo) / (hz - lo + 1), err)))
            break;
        memset(x.xe[1], 0xff, sizeof(uint32_t) * plane);
        memset(x.ye[1], 0xff, sizeof(uint32_t) * plane);
        memset(x.zf[1], 0xff, sizeof(uint32_t) * plane);
        memset(x.ze, 0xff, sizeof(uint32_t) * plane);
        memset(x.xf, 0xff, sizeof(uint32_t) * plane);
        memset(x.yf, 0xff, sizeof(uint32_t) * plane);
        x.Z = Z;
        for (int Y = lo; Y <= hy && !x.rc; Y++) {
            const uint16_t *a0 = x.plane[0] + (size_t)x.px * (size_t)Y, *a1 = a0 + x.px;
            const uint16_t *b0 = x.plane[1] + (size_t)x.px * (size_t)Y, *b1 = b0 + x.px;
            x.Y = Y;
            for (int X = lo; X <= hx && !x.rc; X++) {
                uint16_t lab[8] = {a0[X], a0[X + 1], a1[X], a1[X + 1], b0[X], b0[X + 1], b1[X], b1[X + 1]};
                if (lab[0] == lab[1] && lab[0] == lab[2] && lab[0] == lab[3] && lab[0] == lab[4] && lab[0] == lab[5] &&
                    lab[0] == lab[6] && lab[0] == lab[7])
                    continue;
                x.X = X;
                do_cell(&x, lab);
            }
        }
        uint16_t *p = x.plane[0]; /* plane Z + 1 becomes the next cells' plane Z */
        x.plane[0] = x.plane[1], x.plane[1] = p;
        uint32_t *t = x.xe[0];
        x.xe[0] = x.xe[1], x.xe[1] = t;
        t = x.ye[0], x.ye[0] = x.ye[1], x.ye[1] = t;
        t = x.zf[0], x.zf[0] = x.zf[1], x.zf[1] = t;
    }
    for (int k = 0; k < 2; k++)
        free(x.plane[k]), free(x.xe[k]), free(x.ye[k]), free(x.zf[k]);
    free(x.ze), free(x.xf), free(x.yf);
    if (!x.rc)
        x.rc = bucket(out, err);
    if (x.rc) {
        iso_labels_free(out);
        out->n_labels = n_labels;
    }
    return x.rc;
}

int iso_labels_mesh(struct iso_labels *l, int k, size_t *touch, struct trimesh *out, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    if (touch)
        memset(touch, 0, sizeof *touch * ((size_t)l->n_labels + 1));
    if (k < 1 || k > l->n_labels)
        return sf_fail(err, SF_EINVAL, "", "label %d of %d", k, l->n_labels);
    size_t nt = l->first[k + 1] - l->first[k], nv = 0;
    const uint32_t *of = l->of + l->first[k];
    uint32_t gen = ++l->generation;
    for (size_t i = 0; i < nt; i++)
        for (int c = 0; c < 3; c++) {
            uint32_t v = l->tri[3 * (size_t)of[i] + (size_t)c];
            if (l->stamp[v] != gen)
                l->stamp[v] = gen, l->remap[v] = (uint32_t)nv++;
        }
    out->tri = malloc(sizeof *out->tri * (3 * nt + 1));
    out->pos = malloc(sizeof *out->pos * (3 * nv + 1));
    out->nrm = calloc(3 * nv + 1, sizeof *out->nrm);
    if (!out->tri || !out->pos || !out->nrm) {
        trimesh_free(out);
        return sf_fail(err, SF_ENOMEM, "", "out of memory for a label's mesh");
    }
    out->n_tri = nt, out->n_vert = nv;
    for (size_t i = 0; i < nt; i++) {
        size_t t = of[i];
        bool behind = l->side[2 * t] == k; /* it faces away from k: kept as it is; else turned round */
        uint32_t v[3] = {l->tri[3 * t], l->tri[3 * t + (behind ? 1 : 2)], l->tri[3 * t + (behind ? 2 : 1)]};
        if (touch)
            touch[l->side[2 * t + (behind ? 1 : 0)]]++;
        double p[3][3];
        for (int c = 0; c < 3; c++) {
            out->tri[3 * i + (size_t)c] = l->remap[v[c]];
            for (int a = 0; a < 3; a++)
                p[c][a] = out->pos[3 * (size_t)l->remap[v[c]] + (size_t)a] = l->pos[3 * (size_t)v[c] + (size_t)a];
        }
        double u[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
        double w[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
        double nrm[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        for (int c = 0; c < 3; c++) /* area-weighted */
            for (int a = 0; a < 3; a++)
                out->nrm[3 * (size_t)out->tri[3 * i + (size_t)c] + (size_t)a] += (float)nrm[a];
    }
    for (size_t v = 0; v < nv; v++) {
        float *n = out->nrm + 3 * v;
        float len = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (len > 0)
            n[0] /= len, n[1] /= len, n[2] /= len;
        else
            n[2] = 1;
    }
    return 0;
}

void iso_labels_free(struct iso_labels *l)
{
    free(l->pos);
    free(l->tri);
    free(l->side);
    free(l->first);
    free(l->of);
    free(l->remap);
    free(l->stamp);
    memset(l, 0, sizeof *l);
}
