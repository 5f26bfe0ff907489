/* mc.c - marching cubes over an indexed mesh (mc.h), in two passes over slabs of z as VTK's Flying
 * Edges does: pass 1 counts each row's edge crossings and triangles, a prefix sum places every
 * row's output, pass 2 writes it. The grid seen here is "virtual": with closed=true it has one
 * layer of pad samples (below iso) round the real ones. Rows: x-edge row (J, K) holds the
 * crossings of the edges from (I, J, K) to (I+1, J, K), and so on for y and z; cell row (J, K)
 * the cells (I, J, K). Vertices are numbered level by level (x rows, y rows, z rows of level K),
 * triangles cell row by cell row, so the mesh does not depend on the slabs. Each slice's states
 * (sample > iso) are kept as bits, so that crossings are counted and cells of one state passed over
 * 64 at a time: pass 1 compares the samples in their own type into them (sample_bits), and keeps
 * them, with each crossed cell's case, for pass 2, which alone makes floats (for positions and
 * gradients). A box of cells (iso_box_extract, for kept.c's local rebuilds) is drawn in one pass by
 * the same case and vertex code; the whole grid for kept.c by the two passes (iso_box_whole). */
#include "mc.h"
#include "cube.h"

#include <math.h>
#include <stdint.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif
#include <stdlib.h>
#include <string.h>

/* ---- the cell tables ---- */

/* corners c = x + 2y + 4z; edges 0-3 along x (index y + 2z), 4-7 along y (x + 2z), 8-11 along z
 * (x + 2y) */
static int edge_of(int a, int b)
{
    int d = a ^ b, lo = a < b ? a : b;
    int x = lo & 1, y = lo >> 1 & 1, z = lo >> 2 & 1;
    return d == 1 ? y + 2 * z : d == 2 ? 4 + x + 2 * z : 8 + x + 2 * y;
}

const int iso_face_ccw[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
/* The same corners in one global order, (u, v) = 00, 10, 01, 11 over the face's two axes in
 * x, y, z order: what the asymptotic decider reads, the same in both cells that share the face. */
static const int FACE_CANON[6][4] = {{0, 2, 4, 6}, {1, 3, 5, 7}, {0, 1, 4, 5}, {2, 3, 6, 7}, {0, 1, 2, 3}, {4, 5, 6, 7}};

#define MAX_CELL_TRIS 12
#define MAX_CENTRES 4
struct cell_case {
    uint8_t n;                       /* triangles */
    uint8_t n_centres;               /* vertices inside the cell: the centres of loops fanned from them */
    /* two loops whose sides could meet inside the cell (MC33's interior ambiguity): test whether
     * the corners of comp[0] reach those of comp[1] through the interpolant's inside (test 1) or
     * outside (test 2); the case after it, one entry on, joins the loops by a tube */
    uint8_t test, comp[2];
    uint8_t e[3 * MAX_CELL_TRIS];    /* the triangles' corners: cell edges 0-11, centres 12.. */
    uint16_t centre_of[MAX_CENTRES]; /* the edges (bit mask) of each centre's loop */
};

/* Faces of corner states c with two diagonal corners in and the other two out. */
static int ambiguous_faces(int c)
{
    int m = 0;
    for (int f = 0; f < 6; f++) {
        const int *q = FACE_CANON[f];
        int s00 = c >> q[0] & 1, s10 = c >> q[1] & 1, s01 = c >> q[2] & 1, s11 = c >> q[3] & 1;
        if (s00 == s11 && s10 == s01 && s00 != s10)
            m |= 1 << f;
    }
    return m;
}

/* The two faces edge e lies on, as a bit mask. */
static int edge_faces(int e)
{
    int p = e & 3, lo = p & 1, hi = p >> 1;
    if (e < 4) /* along x: (y, z) = (lo, hi) */
        return 1 << (2 + lo) | 1 << (4 + hi);
    if (e < 8) /* along y: (x, z) */
        return 1 << lo | 1 << (4 + hi);
    return 1 << lo | 1 << (2 + hi); /* along z: (x, y) */
}

/* A loop position to fan from whose diagonals all cross the cell's inside: a diagonal between
 * two crossings of one face would lie in that face, where the neighbour's fan may draw it too
 * (four triangles on one edge). -1 when there is none. */
static int fan_apex(const int *loop, int n)
{
    for (int a = 0; a < n; a++) {
        bool ok = true;
        for (int k = 2; k + 1 < n && ok; k++)
            ok = !(edge_faces(loop[a]) & edge_faces(loop[(a + k) % n]));
        if (ok)
            return a;
    }
    return -1;
}

/* The corners of state s (1 inside, 0 outside) of corner states c, in components: joined along the
 * cube's edges and, across an ambiguous face, along its diagonal where the face joins them (inside
 * corners where bit f of joined is set, outside corners where it is not). Masks into comp; the
 * number of components. */
static int components(int c, int joined, int s, uint8_t comp[8])
{
    int label[8], n = 0;
    for (int k = 0; k < 8; k++)
        label[k] = -1;
    for (int k = 0; k < 8; k++) {
        if ((c >> k & 1) != s || label[k] >= 0)
            continue;
        int stack[8], top = 0;
        stack[top++] = k;
        label[k] = n;
        comp[n] = 0;
        while (top) {
            int a = stack[--top];
            comp[n] |= (uint8_t)(1 << a);
            int next[9], m = 0;
            for (int axis = 0; axis < 3; axis++)
                next[m++] = a ^ 1 << axis;
            for (int f = 0; f < 6; f++) { /* the diagonal partner across an ambiguous face */
                const int *q = FACE_CANON[f];
                if (!(ambiguous_faces(c) >> f & 1) || ((joined >> f & 1) != s))
                    continue;
                for (int i = 0; i < 4; i++)
                    if (q[i] == a)
                        next[m++] = q[3 - i];
            }
            for (int i = 0; i < m; i++)
                if ((c >> next[i] & 1) == s && label[next[i]] < 0) {
                    label[next[i]] = n;
                    stack[top++] = next[i];
                }
        }
        n++;
    }
    return n;
}

/* The middle of cell edge e, in cell units. */
static void edge_middle(int e, double p[3])
{
    int k = e & 3, lo = k & 1, hi = k >> 1, axis = e >> 2;
    int other[2] = {axis == 0 ? 1 : 0, axis == 2 ? 1 : 2};
    p[axis] = 0.5;
    p[other[0]] = lo;
    p[other[1]] = hi;
}

/* Whether a rung between crossings e and f may be drawn: not when they lie on one face, where
 * the neighbour cell (its own tube) could draw the same edge. */
static bool rung_ok(int e, int f) { return !(edge_faces(e) & edge_faces(f)); }

/* One band from rung (a[0], b[start]): a walked forward and b backward, so that each loop edge
 * keeps the direction its neighbour cell's triangle reverses, advancing on the two loops in
 * proportion where the rung that makes may be drawn and no rung comes twice. Its triangles into
 * tris; their number, or 0 when this start has no band. */
static int band_from(const int *a, int na, const int *b, int nb, int start, uint8_t *tris)
{
    /* The rungs are the points (ia, jb) of a monotone path from (0, 0) to (na, nb), taken modulo
     * (na, nb): no rung may come twice, so the b steps taken before the first a step (j0 of them)
     * must not be met again after the last, nor the a steps before the first b step (i0). */
    int n = 0, cur = start, i0 = -1, j0 = -1;
    for (int ia = 0, jb = 0; ia < na || jb < nb;) {
        int prev = (cur + nb - 1) % nb;
        bool can_a = ia < na && rung_ok(a[(ia + 1) % na], b[cur]) && (ia + 1 < na || jb > j0);
        bool can_b = jb < nb && rung_ok(a[ia % na], b[prev]) && (jb + 1 < nb || (i0 >= 0 && ia > i0));
        if (!can_a && !can_b)
            return 0;
        uint8_t *t = tris + 3 * n++;
        if (can_a && (!can_b || ia * nb <= jb * na)) { /* (a[ia], a[ia+1], b[cur]) */
            t[0] = (uint8_t)a[ia], t[1] = (uint8_t)a[(ia + 1) % na], t[2] = (uint8_t)b[cur];
            if (j0 < 0)
                j0 = jb;
            ia++;
        } else { /* back along b: (b[cur-1], b[cur], a[ia]) */
            t[0] = (uint8_t)b[prev], t[1] = (uint8_t)b[cur], t[2] = (uint8_t)a[ia % na];
            if (i0 < 0)
                i0 = ia;
            cur = prev;
            jb++;
        }
    }
    return n;
}

/* The band of triangles between loops a and b (a tube), from the first rung of a[0] that has
 * one, nearest first. false (out unchanged) when there is none: the loops then stay two caps. */
static bool band(const int *a, int na, const int *b, int nb, struct cell_case *out)
{
    int order[12];
    double pa[3], d[12];
    edge_middle(a[0], pa);
    for (int k = 0; k < nb; k++) {
        double pb[3];
        edge_middle(b[k], pb);
        d[k] = (pa[0] - pb[0]) * (pa[0] - pb[0]) + (pa[1] - pb[1]) * (pa[1] - pb[1]) + (pa[2] - pb[2]) * (pa[2] - pb[2]);
        order[k] = k;
    }
    for (int k = 1; k < nb; k++) /* nearest first */
        for (int i = k; i > 0 && d[order[i]] < d[order[i - 1]]; i--) {
            int t = order[i];
            order[i] = order[i - 1], order[i - 1] = t;
        }
    uint8_t tris[3 * 24];
    for (int k = 0; k < nb; k++) {
        if (!rung_ok(a[0], b[order[k]]))
            continue;
        int n = band_from(a, na, b, nb, order[k], tris);
        if (n && out->n + n <= MAX_CELL_TRIS) {
            memcpy(out->e + 3 * out->n, tris, 3 * (size_t)n);
            out->n = (uint8_t)(out->n + n);
            return true;
        }
    }
    return false;
}

/* The triangles of corner states c, ambiguous face f's inside corners joined across it when bit
 * f of joined is set: each face's segments run from an entry crossing (walking the face
 * counter-clockwise, out -> in) to an exit; they chain into loops, each fanned into triangles, or,
 * with tube, two loops joined by a band. */
static void build_case(int c, int joined, bool tube, struct cell_case *out)
{
    int next[12];
    for (int e = 0; e < 12; e++)
        next[e] = -1;
    for (int f = 0; f < 6; f++) {
        int cross[4], entry[4], n = 0;
        for (int k = 0; k < 4; k++) {
            int a = iso_face_ccw[f][k], b = iso_face_ccw[f][(k + 1) % 4];
            int sa = c >> a & 1, sb = c >> b & 1;
            if (sa != sb) {
                cross[n] = edge_of(a, b);
                entry[n++] = sb; /* out -> in */
            }
        }
        if (n == 2) {
            int en = entry[0] ? 0 : 1;
            next[cross[en]] = cross[1 - en];
        } else if (n == 4) {
            int r = entry[0] ? 0 : 1; /* E1 X1 E2 X2 counter-clockwise from the first entry */
            int e1 = cross[r], x1 = cross[(r + 1) % 4], e2 = cross[(r + 2) % 4], x2 = cross[(r + 3) % 4];
            if (joined >> f & 1) { /* the segments cut off the outside corners */
                next[e2] = x1;
                next[e1] = x2;
            } else { /* they cut off the inside corners */
                next[e1] = x1;
                next[e2] = x2;
            }
        }
    }
    out->n = out->n_centres = out->test = 0;
    bool seen[12] = {false};
    int loops[4][12], sizes[4], n_loops = 0;
    for (int e = 0; e < 12; e++) {
        if (next[e] < 0 || seen[e])
            continue;
        int n = 0;
        for (int v = e; !seen[v]; v = next[v]) {
            seen[v] = true;
            loops[n_loops][n++] = v;
        }
        sizes[n_loops++] = n;
    }
    uint8_t in[8], outc[8];
    if (n_loops == 2) { /* two caps, or one tube: the interior decides */
        if (components(c, joined, 1, in) == 2)
            out->test = 1, out->comp[0] = in[0], out->comp[1] = in[1];
        else if (components(c, joined, 0, outc) == 2)
            out->test = 2, out->comp[0] = outc[0], out->comp[1] = outc[1];
    }
    if (out->test && !band(loops[0], sizes[0], loops[1], sizes[1], &(struct cell_case){0}))
        out->test = 0; /* no band without a rung in a face: two caps, as without the test */
    if (tube && out->test && band(loops[0], sizes[0], loops[1], sizes[1], out))
        return;
    for (int l = 0; l < n_loops; l++) {
        const int *loop = loops[l];
        int n = sizes[l];
        int apex = fan_apex(loop, n);
        if (apex < 0) { /* fanned from a vertex at the loop's centre instead */
            int centre = 12 + out->n_centres;
            uint16_t edges = 0;
            for (int k = 0; k < n; k++) {
                uint8_t *t = out->e + 3 * out->n++;
                t[0] = (uint8_t)centre;
                t[1] = (uint8_t)loop[k];
                t[2] = (uint8_t)loop[(k + 1) % n];
                edges |= (uint16_t)(1 << loop[k]);
            }
            out->centre_of[out->n_centres++] = edges;
            continue;
        }
        for (int k = 1; k + 1 < n; k++) {
            uint8_t *t = out->e + 3 * out->n++;
            t[0] = (uint8_t)loop[apex];
            t[1] = (uint8_t)loop[(apex + k) % n];
            t[2] = (uint8_t)loop[(apex + k + 1) % n];
        }
    }
}

/* ---- the job ---- */

/* A sample row's states: the first's, and the first and last column whose state differs from it
 * (lo > hi: the row is all one state). What no crossing can be outside of, as Flying Edges trims
 * its rows: most rows of a CT are all air or all tissue. */
struct trim {
    int lo, hi;
    bool s0;
};

/* The case (CASES' index) of each cell a slab's pass 1 visits, in the order it visits them: pass 2
 * visits the same cells in the same order (the same bits and trims) and reads them back, so a
 * cell's faces and interior are decided once. */
struct cases {
    uint16_t *at;
    size_t n, cap;
};

struct iso_job {
    struct iso_grid g;
    struct iso_opts o;
    int NX, NY, NZ, shift;           /* the virtual grid; shift: 1 when padded */
    float iso, pad;
    double org[3];                   /* of the virtual grid's sample (0, 0, 0) */
    float half_inv[3];               /* 1 / (2 spacing): central differences */
    int n_slabs, *k0;                /* slab s: cell layers k0[s] .. k0[s+1]-1 */
    uint32_t *xc, *yc, *zc, *tc, *cc; /* per row [J + NY*K]: crossings, triangles, centres */
    size_t *xb, *yb, *zb, *tb, *cb;  /* where each row's output starts */
    bool *slab_failed;               /* [s]: a pass of slab s found no memory (written by s alone) */
    float *slab_min;                 /* [s]: the least sample slab s's pass 1 read (the pad, iso_layout) */
    struct trim *trim;               /* per sample row [J + NY*K]: where its states change */
    uint64_t *bits;                  /* per slice K: its states as bits (pass 1's, read by pass 2) */
    void *rows;                      /* the per-row lists above, one block (calloc'd: over 2 MB for most
                                      * grids, so its pages come in huge and zeroed; the cold run's faults) */
    struct cases *cases;             /* [s]: the cases of slab s's cells, as pass 1 found them */
    struct trimesh m;                /* the lists of into when there is one (iso_box_whole) */
    struct iso_box *into;
    uint64_t *key;                   /* with into: its keys and cells (iso_box) */
    uint32_t *cell;
};

int iso_n_slabs(const struct iso_job *j) { return j->n_slabs; }

/* The words of a row of states as bits (below, "states as bits"). */
static int bit_words(int NX) { return (NX + 63) / 64 + 1; }

#define LEAST_OF(T)                                      \
    do {                                                 \
        const T *p = (const T *)g->samples + at;         \
        T lo = p[0];                                     \
        for (size_t i = 1; i < n; i++)                   \
            lo = p[i] < lo ? p[i] : lo;                  \
        return (double)lo;                               \
    } while (0)

/* The least of samples at .. at+n-1 (n > 0; a typed loop each, which the compiler vectorises). */
static double least_of(const struct iso_grid *g, size_t at, size_t n)
{
    switch (g->type) {
    case ISO_U8: LEAST_OF(uint8_t);
    case ISO_I16: LEAST_OF(int16_t);
    case ISO_U16: LEAST_OF(uint16_t);
    default: LEAST_OF(float);
    }
}

double iso_grid_min(const struct iso_grid *g) { return least_of(g, 0, (size_t)g->nx * (size_t)g->ny * (size_t)g->nz); }

/* Samples x0 .. x0+n-1 of row (y, z) as floats into out. */
static void grid_span(const struct iso_grid *g, int x0, int y, int z, int n, float *out)
{
    size_t at = (size_t)g->nx * ((size_t)y + (size_t)g->ny * (size_t)z) + (size_t)x0;
    switch (g->type) {
    case ISO_U8: {
        const uint8_t *p = (const uint8_t *)g->samples + at;
        for (int i = 0; i < n; i++)
            out[i] = p[i];
        break;
    }
    case ISO_I16: {
        const int16_t *p = (const int16_t *)g->samples + at;
        for (int i = 0; i < n; i++)
            out[i] = p[i];
        break;
    }
    case ISO_U16: {
        const uint16_t *p = (const uint16_t *)g->samples + at;
        for (int i = 0; i < n; i++)
            out[i] = p[i];
        break;
    }
    default:
        memcpy(out, (const float *)g->samples + at, (size_t)n * sizeof *out);
    }
}

void iso_grid_row(const struct iso_grid *g, int y, int z, float *out) { grid_span(g, 0, y, z, g->nx, out); }

/* Virtual slice K into out (NX * NY floats). */
static void load(const struct iso_job *j, int K, float *out)
{
    int s = j->shift;
    for (int J = 0; J < j->NY; J++) {
        float *row = out + (size_t)j->NX * (size_t)J;
        int y = J - s, z = K - s;
        if (y < 0 || y >= j->g.ny || z < 0 || z >= j->g.nz) {
            for (int I = 0; I < j->NX; I++)
                row[I] = j->pad;
            continue;
        }
        iso_grid_row(&j->g, y, z, row + s);
        if (s)
            row[0] = row[j->NX - 1] = j->pad;
    }
}

void iso_free(struct iso_job *j)
{
    if (!j)
        return;
    free(j->k0);
    free(j->rows);
    free(j->slab_failed);
    free(j->slab_min);
    for (int s = 0; j->cases && s < j->n_slabs; s++)
        free(j->cases[s].at);
    free(j->cases);
    if (j->into) /* (its lists are the box's) */
        memset(&j->m, 0, sizeof j->m);
    trimesh_free(&j->m);
    free(j);
}

/* The cells' tables: [(c * 64 + joined) * 2 + tube], and each corner state's ambiguous faces. */
static struct cell_case CASES[256 * 64 * 2];
static uint8_t AMBIGUOUS[256];
static uint16_t CROSSED[256]; /* each corner state's crossed edges */
static bool tables_built;

void iso_init(void)
{
    if (tables_built)
        return;
    for (int c = 0; c < 256; c++) {
        AMBIGUOUS[c] = (uint8_t)ambiguous_faces(c);
        CROSSED[c] = 0;
        for (int a = 0; a < 8; a++)
            for (int axis = 0; axis < 3; axis++)
                if (!(a >> axis & 1) && (c >> a & 1) != (c >> (a | 1 << axis) & 1))
                    CROSSED[c] |= (uint16_t)(1 << edge_of(a, a | 1 << axis));
        for (int m = 0; m < 64; m++)
            if ((m & ~AMBIGUOUS[c]) == 0)
                for (int tube = 0; tube < 2; tube++)
                    build_case(c, m, tube, &CASES[(c * 64 + m) * 2 + tube]);
    }
    tables_built = true;
}

/* The job's view of g and o: the virtual grid, its origin, iso (the pad is the caller's). */
static void frame(struct iso_job *j, const struct iso_grid *g, const struct iso_opts *o)
{
    j->g = *g;
    j->o = *o;
    j->shift = o->closed ? 1 : 0;
    j->NX = g->nx + 2 * j->shift;
    j->NY = g->ny + 2 * j->shift;
    j->NZ = g->nz + 2 * j->shift;
    j->iso = (float)o->iso;
    for (int a = 0; a < 3; a++) {
        j->org[a] = g->origin[a] - j->shift * g->spacing[a];
        j->half_inv[a] = (float)(0.5 / g->spacing[a]);
    }
}

int iso_begin(const struct iso_grid *g, const struct iso_opts *o, int n_slabs, struct iso_job **out,
              struct sf_err *err)
{
    *out = NULL;
    if (!tables_built)
        return sf_fail(err, SF_EBACKEND, "", "iso_init() was not called");
    if (g->nx < 2 || g->ny < 2 || g->nz < 2)
        return sf_fail(err, SF_EINVAL, "?dims", "a volume has at least 2 samples on every axis");
    if (!isfinite(o->iso))
        return sf_fail(err, SF_EINVAL, "?iso", "iso is a finite number");
    if (o->sharp)
        return sf_fail(err, SF_EINVAL, "?features", "feature points are the adaptive extraction's (adapt.h)");
    struct iso_job *j = calloc(1, sizeof *j);
    if (!j)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    frame(j, g, o);
    /* The pad is below iso and every sample: the volume's least, as a CT's air, or iso - 1. Pass 1
     * finds the least as it reads the slabs (no pass of its own), so it counts with iso - 1 in the
     * pad: what it counts does not depend on the pad's value, as long as it is at most iso. The
     * states see it outside; no face with pad corners is ambiguous (they come two or more to a
     * face, side by side); and MC33's interior test of a cell with a face of pad corners reads
     * the inside of its other face alone (the interpolant's inside at each depth lies within the
     * inside there). iso_layout sets the pad pass 2 draws with. */
    if (o->closed)
        j->pad = (float)(o->iso - 1);
    int layers = j->NZ - 1;
    j->n_slabs = n_slabs < 1 ? 1 : n_slabs > layers ? layers : n_slabs;
    size_t rows = (size_t)j->NY * (size_t)j->NZ, W = (size_t)bit_words(j->NX);
    j->k0 = malloc(sizeof *j->k0 * (size_t)(j->n_slabs + 1));
    char *b = j->rows = calloc(rows, 5 * sizeof(size_t) + W * sizeof(uint64_t) + sizeof(struct trim) + 5 * sizeof(uint32_t));
    if (b) { /* (by alignment: 8-byte words first) */
        size_t **starts[5] = {&j->xb, &j->yb, &j->zb, &j->tb, &j->cb};
        uint32_t **counts[5] = {&j->xc, &j->yc, &j->zc, &j->tc, &j->cc};
        for (int k = 0; k < 5; k++, b += rows * sizeof(size_t))
            *starts[k] = (size_t *)(void *)b;
        j->bits = (uint64_t *)(void *)b, b += rows * W * sizeof(uint64_t);
        j->trim = (struct trim *)(void *)b, b += rows * sizeof(struct trim);
        for (int k = 0; k < 5; k++, b += rows * sizeof(uint32_t))
            *counts[k] = (uint32_t *)(void *)b;
    }
    j->slab_failed = calloc((size_t)j->n_slabs, sizeof *j->slab_failed);
    j->slab_min = malloc((size_t)j->n_slabs * sizeof *j->slab_min);
    j->cases = calloc((size_t)j->n_slabs, sizeof *j->cases);
    if (!j->k0 || !j->rows || !j->slab_failed || !j->slab_min || !j->cases) {
        iso_free(j);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    for (int s = 0; s <= j->n_slabs; s++)
        j->k0[s] = (int)((long)layers * s / j->n_slabs);
    for (int s = 0; s < j->n_slabs; s++)
        j->slab_min[s] = INFINITY;
    *out = j;
    return 0;
}

/* MC33's interior test, by sampling: whether the corners of mask a reach those of mask b through
 * samples of the trilinear interpolant of g (values less iso) that are inside (s = 1) or outside
 * (s = 0), on an (INTERIOR_STEPS+1)^3 lattice of the cell. Exact on the corners and faces the
 * lattice holds; a channel thinner than a lattice step is missed (the loops stay apart). */
#define INTERIOR_STEPS 4
static bool interior_joins(const double g[8], int s, int a, int b)
{
    enum { N = INTERIOR_STEPS + 1 };
    bool ok[N * N * N], seen[N * N * N] = {false};
    for (int z = 0; z < N; z++) { /* separably: along z, then y, then x */
        double w = (double)z / INTERIOR_STEPS, e[4];
        for (int k = 0; k < 4; k++)
            e[k] = g[k] + w * (g[k + 4] - g[k]);
        for (int y = 0; y < N; y++) {
            double v = (double)y / INTERIOR_STEPS, l0 = e[0] + v * (e[2] - e[0]), l1 = e[1] + v * (e[3] - e[1]);
            for (int x = 0; x < N; x++) {
                double f = l0 + (double)x / INTERIOR_STEPS * (l1 - l0);
                ok[x + N * (y + N * z)] = s ? f > 0 : f <= 0;
            }
        }
    }
    int stack[N * N * N], top = 0;
    for (int k = 0; k < 8; k++)
        if (a >> k & 1) {
            int at = (k & 1 ? N - 1 : 0) + N * ((k & 2 ? N - 1 : 0) + N * (k & 4 ? N - 1 : 0));
            seen[at] = true;
            stack[top++] = at;
        }
    while (top) {
        int at = stack[--top], x = at % N, y = at / N % N, z = at / (N * N);
        for (int k = 0; k < 8; k++) /* a corner of b reached */
            if ((b >> k & 1) && x == (k & 1 ? N - 1 : 0) && y == (k & 2 ? N - 1 : 0) && z == (k & 4 ? N - 1 : 0))
                return true;
        const int d[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (int k = 0; k < 6; k++) {
            int X = x + d[k][0], Y = y + d[k][1], Z = z + d[k][2];
            if (X < 0 || Y < 0 || Z < 0 || X >= N || Y >= N || Z >= N)
                continue;
            int to = X + N * (Y + N * Z);
            if (ok[to] && !seen[to]) {
                seen[to] = true;
                stack[top++] = to;
            }
        }
    }
    return false;
}

/* Whether the case of corner states c is decided by them alone (no ambiguous face, no interior
 * test): then it is CASES[c * 64 * 2], and cell_case need not read the samples. */
static inline bool states_decide(int c) { return !AMBIGUOUS[c] && !CASES[c * 64 * 2].test; }

/* The case of a cell of corner states c (not states_decide) and corner values v (bit x + 2y + 4z):
 * its ambiguous faces decided from the samples, and its interior where two loops could be one tube. */
static int cell_case(const struct iso_job *j, int c, const float v[8])
{
    int amb = AMBIGUOUS[c], joined = 0;
    float iso = j->iso;
    for (int f = 0; amb; f++, amb >>= 1) {
        if (!(amb & 1))
            continue;
        const int *q = FACE_CANON[f];
        double g00 = (double)v[q[0]] - iso, g10 = (double)v[q[1]] - iso, g01 = (double)v[q[2]] - iso,
               g11 = (double)v[q[3]] - iso;
        double det = g00 * g11 - g10 * g01; /* the bilinear saddle's side of iso, times the denominator's sign */
        if (g00 > 0 ? det > 0 : det < 0)
            joined |= 1 << f;
    }
    int idx = (c * 64 + joined) * 2;
    const struct cell_case *cc = &CASES[idx];
    if (cc->test) {
        double g[8];
        for (int k = 0; k < 8; k++)
            g[k] = (double)v[k] - iso;
        idx += interior_joins(g, cc->test == 1, cc->comp[0], cc->comp[1]);
    }
    return idx;
}

/* The columns [*lo, *hi] outside of which the n rows t can hold no crossing: of x edges and
 * cells (shift 1: an edge or cell starting one column before a change) or of y and z edges
 * between the rows (shift 0). last: the last column there is. Empty when *lo > *hi. */
static void span(const struct trim *const *t, int n, int shift, int last, int *lo, int *hi)
{
    int l = INT32_MAX, h = -1;
    bool same = true;
    for (int k = 0; k < n; k++) {
        same = same && t[k]->s0 == t[0]->s0;
        l = t[k]->lo < l ? t[k]->lo : l;
        h = t[k]->hi > h ? t[k]->hi : h;
    }
    if (!same) { /* rows of different states: crossings anywhere */
        *lo = 0, *hi = last;
        return;
    }
    *lo = l - shift < 0 ? 0 : l - shift;
    *hi = h > last ? last : h;
}

/* ---- states as bits ----
 * A slice's states (value > iso) as bits, word w of row J holding columns 64w .. 64w+63, with a word
 * of 0 more a row so that a cell's right column reads past the last: a row's crossings are then
 * counted 64 at a time and the cells whose corners all lie on one side (most of a CT's) passed over
 * 64 at a time, not compared sample by sample in each pass. The same states as the comparisons (NaN
 * none: the volumes are finite), so the same mesh. */

#ifdef __SSE2__
/* Whether each of the sixteen floats at p is over v's: bit k for p[k] (the compares' masks packed to
 * bytes, one movemask). */
static inline uint64_t over16(const float *p, __m128 v)
{
    __m128i m0 = _mm_castps_si128(_mm_cmpgt_ps(_mm_loadu_ps(p), v));
    __m128i m1 = _mm_castps_si128(_mm_cmpgt_ps(_mm_loadu_ps(p + 4), v));
    __m128i m2 = _mm_castps_si128(_mm_cmpgt_ps(_mm_loadu_ps(p + 8), v));
    __m128i m3 = _mm_castps_si128(_mm_cmpgt_ps(_mm_loadu_ps(p + 12), v));
    return (uint32_t)_mm_movemask_epi8(_mm_packs_epi16(_mm_packs_epi32(m0, m1), _mm_packs_epi32(m2, m3)));
}
#endif

/* Rows rect[2] .. rect[3] of slice a, columns rect[0] .. rect[1] (the others 0), into out. */
static void rect_bits(const float *a, int NX, const int rect[4], float iso, uint64_t *out)
{
    int W = bit_words(NX);
    memset(out + (size_t)W * rect[2], 0, (size_t)W * (size_t)(rect[3] - rect[2] + 1) * sizeof *out);
    for (int J = rect[2]; J <= rect[3]; J++) {
        const float *r = a + (size_t)NX * J;
        uint64_t *o = out + (size_t)W * J;
        int I = rect[0], end = rect[1] + 1;
#ifdef __SSE2__
        for (; I < end && (I & 15); I++)
            o[I >> 6] |= (uint64_t)(r[I] > iso) << (I & 63);
        __m128 v = _mm_set1_ps(iso);
        for (; I + 16 <= end; I += 16) /* (sixteen columns from a multiple of 16: within one word) */
            o[I >> 6] |= over16(r + I, v) << (I & 63);
#endif
        for (; I < end; I++)
            o[I >> 6] |= (uint64_t)(r[I] > iso) << (I & 63);
    }
}

/* n (at most 16) bits m into row o from column c on. */
static inline void put_bits(uint64_t *o, int c, uint64_t m, int n)
{
    int w = c >> 6, sh = c & 63;
    o[w] |= m << sh;
    if (sh + n > 64)
        o[w + 1] |= m >> (64 - sh);
}

/* Virtual slice K's states as bits (as rect_bits of the slice as floats), the least of its real samples
 * folded into *least: pass 1's, compared in the samples' own type, so that pass 1 makes no floats
 * (a whole number is over iso when it is over floor(iso); 16 at a time where SSE2 is). */
static void sample_bits(const struct iso_job *j, int K, uint64_t *out, float *least)
{
    const struct iso_grid *g = &j->g;
    int W = bit_words(j->NX), s = j->shift, z = K - s, n = g->nx;
    memset(out, 0, (size_t)W * (size_t)j->NY * sizeof *out);
    if (z < 0 || z >= g->nz)
        return; /* (a slice of pad: below iso) */
    float iso = j->iso;
    double lowest = g->type == ISO_I16 ? -32768 : 0, highest = g->type == ISO_U8 ? 255 : g->type == ISO_I16 ? 32767 : 65535;
    bool all = g->type != ISO_F32 && iso < lowest, none = g->type != ISO_F32 && iso >= highest;
    int T = all || none || g->type == ISO_F32 ? 0 : (int)floorf(iso);
    for (int y = 0; y < g->ny; y++) {
        size_t at = (size_t)n * ((size_t)y + (size_t)g->ny * (size_t)z);
        uint64_t *o = out + (size_t)W * (size_t)(y + s);
        float least_row = (float)least_of(g, at, (size_t)n);
        *least = least_row < *least ? least_row : *least;
        if (none)
            continue;
        int i = 0;
        if (all) {
            for (; i < n; i += 16)
                put_bits(o, s + i, n - i >= 16 ? 0xffff : ((uint64_t)1 << (n - i)) - 1, n - i >= 16 ? 16 : n - i);
            continue;
        }
#ifdef __SSE2__
        switch (g->type) {
        case ISO_U8: {
            const uint8_t *p = (const uint8_t *)g->samples + at;
            __m128i b = _mm_set1_epi8((char)0x80), t = _mm_set1_epi8((char)(T ^ 0x80));
            for (; i + 16 <= n; i += 16)
                put_bits(o, s + i,
                         (uint32_t)_mm_movemask_epi8(
                             _mm_cmpgt_epi8(_mm_xor_si128(_mm_loadu_si128((const __m128i *)(p + i)), b), t)),
                         16);
            break;
        }
        case ISO_I16:
        case ISO_U16: {
            const uint16_t *p = (const uint16_t *)g->samples + at;
            short bias = g->type == ISO_U16 ? (short)0x8000 : 0;
            __m128i b = _mm_set1_epi16(bias), t = _mm_set1_epi16((short)(T ^ bias));
            for (; i + 16 <= n; i += 16) {
                __m128i v0 = _mm_xor_si128(_mm_loadu_si128((const __m128i *)(p + i)), b);
                __m128i v1 = _mm_xor_si128(_mm_loadu_si128((const __m128i *)(p + i + 8)), b);
                __m128i m = _mm_packs_epi16(_mm_cmpgt_epi16(v0, t), _mm_cmpgt_epi16(v1, t));
                put_bits(o, s + i, (uint32_t)_mm_movemask_epi8(m), 16);
            }
            break;
        }
        default: {
            const float *p = (const float *)g->samples + at;
            __m128 v = _mm_set1_ps(iso);
            for (; i + 16 <= n; i += 16)
                put_bits(o, s + i, over16(p + i, v), 16);
        }
        }
#endif
        for (; i < n; i++) /* (the definition: the sample as a float over iso) */
            switch (g->type) {
            case ISO_U8: put_bits(o, s + i, (float)((const uint8_t *)g->samples)[at + i] > iso, 1); break;
            case ISO_I16: put_bits(o, s + i, (float)((const int16_t *)g->samples)[at + i] > iso, 1); break;
            case ISO_U16: put_bits(o, s + i, (float)((const uint16_t *)g->samples)[at + i] > iso, 1); break;
            default: put_bits(o, s + i, ((const float *)g->samples)[at + i] > iso, 1);
            }
    }
}

/* Word w of row x shifted down one column: bit i says column 64w+i+1. */
static inline uint64_t next_col(const uint64_t *x, int w) { return x[w] >> 1 | x[w + 1] << 63; }

/* Bits lo .. hi of word w (columns in its span). */
static inline uint64_t span_mask(int w, int lo, int hi)
{
    uint64_t m = ~(uint64_t)0;
    if (w == lo >> 6)
        m &= ~(uint64_t)0 << (lo & 63);
    if (w == hi >> 6)
        m &= ~(uint64_t)0 >> (63 - (hi & 63));
    return m;
}

/* The columns lo .. hi where rows x and y differ (y NULL: where x differs from its next column):
 * their number, or (walk) each in turn. */
struct diffs {
    const uint64_t *x, *y;
    uint64_t m;
    int w, lo, hi;
};

static inline uint64_t diff_word(const struct diffs *d, int w)
{
    return (d->x[w] ^ (d->y ? d->y[w] : next_col(d->x, w))) & span_mask(w, d->lo, d->hi);
}

static inline void diffs_begin(struct diffs *d, const uint64_t *x, const uint64_t *y, int lo, int hi)
{
    *d = (struct diffs){x, y, 0, lo >> 6, lo, hi};
    if (lo <= hi)
        d->m = diff_word(d, d->w);
    else
        d->w = hi >> 6;
}

static inline int diffs_next(struct diffs *d)
{
    while (!d->m) {
        if (++d->w > d->hi >> 6)
            return -1;
        d->m = diff_word(d, d->w);
    }
    int I = 64 * d->w + __builtin_ctzll(d->m);
    d->m &= d->m - 1;
    return I;
}

static uint32_t count_diffs(const uint64_t *x, const uint64_t *y, int lo, int hi)
{
    struct diffs d;
    uint32_t n = 0;
    diffs_begin(&d, x, y, lo, hi);
    if (lo > hi)
        return 0;
    for (int w = lo >> 6; w <= hi >> 6; w++)
        n += (uint32_t)__builtin_popcountll(diff_word(&d, w));
    return n;
}

/* The cells lo .. hi of a row whose eight corners do not all lie on one side, from the states of
 * its four sample rows (r: (y, z) = 00 10 01 11), in increasing column. */
struct cells {
    const uint64_t *r[4];
    uint64_t m;
    int w, hi;
};

static inline uint64_t cells_word(const struct cells *c, int w)
{
    const uint64_t *const *r = c->r;
    uint64_t in = r[0][w] & r[1][w] & r[2][w] & r[3][w], any = r[0][w] | r[1][w] | r[2][w] | r[3][w];
    uint64_t in1 = next_col(r[0], w) & next_col(r[1], w) & next_col(r[2], w) & next_col(r[3], w);
    uint64_t any1 = next_col(r[0], w) | next_col(r[1], w) | next_col(r[2], w) | next_col(r[3], w);
    return ~(in & in1) & (any | any1);
}

static inline void cells_begin(struct cells *c, const uint64_t *r0, const uint64_t *r1, const uint64_t *r2,
                               const uint64_t *r3, int lo, int hi)
{
    *c = (struct cells){{r0, r1, r2, r3}, 0, lo >> 6, hi};
    if (lo <= hi)
        c->m = cells_word(c, c->w) & ~(uint64_t)0 << (lo & 63);
    else
        c->w = hi >> 6;
}

static inline int cells_next(struct cells *c)
{
    while (!c->m) {
        if (++c->w > c->hi >> 6)
            return -1;
        c->m = cells_word(c, c->w);
    }
    int I = 64 * c->w + __builtin_ctzll(c->m);
    c->m &= c->m - 1;
    return I <= c->hi ? I : -1;
}

/* The corner states of cell I of the cells c walks (its rows' bits): bit x + 2y + 4z. */
static inline int states_at(const struct cells *c, int I)
{
    int w = I >> 6, s = I & 63, st = 0;
    for (int k = 0; k < 4; k++) { /* columns I and I+1 of row k: (y, z) = k's */
        uint64_t b = c->r[k][w] >> s | (s == 63 ? c->r[k][w + 1] << 1 : 0);
        st |= (int)(b & 3) << (2 * k);
    }
    return st;
}

/* The x and y rows of level K (its rows' trims t, states bits). */
static void count_level(struct iso_job *j, int K, const struct trim *t, const uint64_t *bits)
{
    int NX = j->NX, NY = j->NY, W = bit_words(NX), lo, hi;
    for (int J = 0; J < NY; J++) {
        const uint64_t *r = bits + (size_t)W * J;
        const struct trim *x[1] = {&t[J]}, *y[2] = {&t[J], &t[J + 1 < NY ? J + 1 : J]};
        j->trim[J + (size_t)NY * K] = t[J];
        span(x, 1, 1, NX - 2, &lo, &hi);
        j->xc[J + (size_t)NY * K] = count_diffs(r, NULL, lo, hi);
        if (J + 1 == NY)
            continue;
        span(y, 2, 0, NX - 1, &lo, &hi);
        j->yc[J + (size_t)NY * K] = count_diffs(r, r + W, lo, hi);
    }
}

/* The rows' trims (struct trim) from a slice's states as bits. */
static void trim_slice(const struct iso_job *j, const uint64_t *bits, struct trim *t)
{
    int NX = j->NX, W = bit_words(NX), last = (NX - 1) >> 6;
    uint64_t tail = ~(uint64_t)0 >> (63 - ((NX - 1) & 63));
    for (int J = 0; J < j->NY; J++) {
        const uint64_t *o = bits + (size_t)W * J;
        bool s0 = o[0] & 1;
        uint64_t flip = s0 ? ~(uint64_t)0 : 0;
        int lo = -1, hi = -1;
        for (int w = 0; w <= last; w++) {
            uint64_t x = (o[w] ^ flip) & (w == last ? tail : ~(uint64_t)0);
            if (!x)
                continue;
            if (lo < 0)
                lo = 64 * w + __builtin_ctzll(x);
            hi = 64 * w + 63 - __builtin_clzll(x);
        }
        t[J] = lo < 0 ? (struct trim){NX, -1, s0} : (struct trim){lo, hi, s0};
    }
}

/* The value of virtual sample (I, J, K) (the pad outside the real ones). */
static float sample_at(const struct iso_job *j, int I, int J, int K)
{
    const struct iso_grid *g = &j->g;
    int x = I - j->shift, y = J - j->shift, z = K - j->shift;
    if (x < 0 || y < 0 || z < 0 || x >= g->nx || y >= g->ny || z >= g->nz)
        return j->pad;
    size_t at = (size_t)x + (size_t)g->nx * ((size_t)y + (size_t)g->ny * (size_t)z);
    switch (g->type) {
    case ISO_U8: return ((const uint8_t *)g->samples)[at];
    case ISO_I16: return ((const int16_t *)g->samples)[at];
    case ISO_U16: return ((const uint16_t *)g->samples)[at];
    default: return ((const float *)g->samples)[at];
    }
}

/* The eight corner values of cell (I, J, K), bit x + 2y + 4z. */
static void corner_values(const struct iso_job *j, int I, int J, int K, float v[8])
{
    for (int c = 0; c < 8; c++)
        v[c] = sample_at(j, I + (c & 1), J + (c >> 1 & 1), K + (c >> 2));
}

static bool cases_grow(struct cases *c)
{
    size_t cap = c->cap ? 2 * c->cap : 16384;
    uint16_t *at = realloc(c->at, cap * sizeof *at);
    if (!at)
        return false;
    c->at = at, c->cap = cap;
    return true;
}

void iso_count(struct iso_job *j, int s)
{
    int NX = j->NX, NY = j->NY, W = bit_words(NX);
    size_t bplane = (size_t)W * NY;
    struct trim *ta = malloc(2 * (size_t)NY * sizeof *ta);
    uint64_t *last = malloc(bplane * sizeof *last); /* the next slab's first slice: its own to keep */
    if (!ta || !last) {
        free(ta);
        free(last);
        j->slab_failed[s] = true;
        return;
    }
    struct trim *tb = ta + NY, *tbuf = ta;
    uint64_t *ba, *bb = j->bits + bplane * (size_t)j->k0[s];
    float *least = &j->slab_min[s];
    struct cases *cs = &j->cases[s];
    cs->n = 0;
    sample_bits(j, j->k0[s], bb, least);
    trim_slice(j, bb, tb);
    for (int K = j->k0[s]; K < j->k0[s + 1]; K++) {
        struct trim *u = ta;
        ta = tb, tb = u;
        ba = bb;
        bb = K + 1 < j->k0[s + 1] || s == j->n_slabs - 1 ? j->bits + bplane * (size_t)(K + 1) : last;
        sample_bits(j, K + 1, bb, least);
        trim_slice(j, bb, tb);
        count_level(j, K, ta, ba);
        for (int J = 0; J < NY; J++) {
            const uint64_t *p0 = ba + (size_t)W * J, *q0 = bb + (size_t)W * J;
            const struct trim *z[2] = {&ta[J], &tb[J]};
            int lo, hi;
            span(z, 2, 0, NX - 1, &lo, &hi);
            j->zc[J + (size_t)NY * K] = count_diffs(p0, q0, lo, hi);
            if (J + 1 == NY)
                continue;
            const struct trim *c[4] = {&ta[J], &ta[J + 1], &tb[J], &tb[J + 1]};
            span(c, 4, 1, NX - 2, &lo, &hi);
            uint32_t n = 0, centres = 0;
            struct cells cl;
            cells_begin(&cl, p0, p0 + W, q0, q0 + W, lo, hi);
            for (int I; (I = cells_next(&cl)) >= 0;) {
                int st = states_at(&cl, I), idx = st * 64 * 2;
                if (!states_decide(st)) {
                    float v[8];
                    corner_values(j, I, J, K, v);
                    idx = cell_case(j, st, v);
                }
                if (cs->n == cs->cap && !cases_grow(cs)) {
                    j->slab_failed[s] = true;
                    goto done;
                }
                cs->at[cs->n++] = (uint16_t)idx;
                n += CASES[idx].n;
                centres += CASES[idx].n_centres;
            }
            j->tc[J + (size_t)NY * K] = n;
            j->cc[J + (size_t)NY * K] = centres;
        }
    }
    if (s == j->n_slabs - 1)
        count_level(j, j->NZ - 1, tb, bb);
done:
    free(tbuf);
    free(last);
}

/* Whether a slab's pass ran out of memory (it wrote nothing). */
static int slabs_ok(const struct iso_job *j, struct sf_err *err)
{
    for (int s = 0; s < j->n_slabs; s++)
        if (j->slab_failed[s])
            return sf_fail(err, SF_ENOMEM, "", "out of memory for a slab of the volume");
    return 0;
}

static bool box_grow(struct iso_box *b, size_t verts, size_t tris, bool normals);

int iso_layout(struct iso_job *j, struct sf_err *err)
{
    int rc = slabs_ok(j, err);
    if (rc)
        return rc;
    if (j->o.closed) { /* below iso and every sample: the volume's least, as a CT's air (as pass 1 found it) */
        float least = INFINITY;
        for (int s = 0; s < j->n_slabs; s++)
            least = j->slab_min[s] < least ? j->slab_min[s] : least;
        j->pad = (float)fmin(j->o.iso - 1, least);
    }
    size_t v = 0, t = 0;
    for (int K = 0; K < j->NZ; K++) {
        size_t base = (size_t)j->NY * K;
        for (int J = 0; J < j->NY; J++)
            j->xb[base + J] = v, v += j->xc[base + J];
        for (int J = 0; J < j->NY; J++)
            j->yb[base + J] = v, v += j->yc[base + J];
        for (int J = 0; J < j->NY; J++)
            j->zb[base + J] = v, v += j->zc[base + J];
        for (int J = 0; J < j->NY; J++)
            j->cb[base + J] = v, v += j->cc[base + J];
        for (int J = 0; J < j->NY; J++)
            j->tb[base + J] = t, t += j->tc[base + J];
    }
    if (v > ISO_MAX_VERTICES)
        return sf_fail(err, SF_ELIMIT, "", "the isosurface would have %zu vertices, over the limit of %u", v,
                       ISO_MAX_VERTICES);
    if (j->o.max_triangles && t > j->o.max_triangles)
        return sf_fail(err, SF_ELIMIT, "", "the isosurface would have %zu triangles, over the %zu of %s", t,
                       j->o.max_triangles, j->o.max_triangles_by ? j->o.max_triangles_by : "the limit");
    j->m.n_vert = v;
    j->m.n_tri = t;
    if (j->into) {
        struct iso_box *b = j->into;
        b->n_vert = b->n_tri = 0;
        if (!box_grow(b, v, t, j->o.normals))
            return sf_fail(err, SF_ENOMEM, "", "out of memory for a mesh of %zu triangles", t);
        j->m.pos = b->pos, j->m.nrm = j->o.normals ? b->nrm : NULL, j->m.tri = b->tri;
        j->key = b->key, j->cell = b->cell;
        return 0;
    }
    j->m.pos = malloc((v ? v : 1) * 3 * sizeof *j->m.pos);
    j->m.tri = malloc((t ? t : 1) * 3 * sizeof *j->m.tri);
    if (j->o.normals)
        j->m.nrm = malloc((v ? v : 1) * 3 * sizeof *j->m.nrm);
    if (!j->m.pos || !j->m.tri || (j->o.normals && !j->m.nrm))
        return sf_fail(err, SF_ENOMEM, "", "out of memory for a mesh of %zu triangles", t);
    return 0;
}

/* ---- pass 2 ---- */

/* Slices K-1 .. K+2 of the virtual grid, kept as K advances. */
struct window {
    float *s[4];
    int k;                           /* s[1] is slice k */
    uint64_t *b[4];                  /* their states as bits (pass 1's for the slabs, a box's own) */
};

static const float *slice(const struct window *w, int K) { return w->s[K - w->k + 1]; }
static const uint64_t *slice_bits(const struct window *w, int K) { return w->b[K - w->k + 1]; }

static void window_at(const struct iso_job *j, struct window *w, int K)
{
    size_t bplane = (size_t)bit_words(j->NX) * (size_t)j->NY;
    for (int d = -1; d <= 2; d++) /* pass 1's */
        w->b[d + 1] = K + d >= 0 && K + d < j->NZ ? j->bits + bplane * (size_t)(K + d) : NULL;
    if (K == w->k + 1) { /* slide by one */
        float *t = w->s[0];
        w->s[0] = w->s[1], w->s[1] = w->s[2], w->s[2] = w->s[3], w->s[3] = t;
        w->k = K;
        if (K + 2 < j->NZ)
            load(j, K + 2, w->s[3]);
        return;
    }
    w->k = K;
    for (int d = -1; d <= 2; d++)
        if (K + d >= 0 && K + d < j->NZ)
            load(j, K + d, w->s[d + 1]);
}

/* The field's gradient at virtual sample (I, J, K), by central differences (one-sided at the
 * border), in grid units. */
static void gradient(const struct iso_job *j, const struct window *w, int I, int J, int K, float g[3])
{
    int NX = j->NX, NY = j->NY, NZ = j->NZ;
    const float *c = slice(w, K) + (size_t)I + (size_t)NX * J;
    if (I > 0 && I + 1 < NX && J > 0 && J + 1 < NY && K > 0 && K + 1 < NZ) { /* the common case */
        g[0] = (c[1] - c[-1]) * j->half_inv[0];
        g[1] = (c[NX] - c[-NX]) * j->half_inv[1];
        g[2] = (slice(w, K + 1)[c - slice(w, K)] - slice(w, K - 1)[c - slice(w, K)]) * j->half_inv[2];
        return;
    }
    size_t at = (size_t)(c - slice(w, K));
    int i0 = I > 0 ? -1 : 0, i1 = I + 1 < NX ? 1 : 0;
    int j0 = J > 0 ? -NX : 0, j1 = J + 1 < NY ? NX : 0;
    int k0 = K > 0 ? K - 1 : K, k1 = K + 1 < NZ ? K + 1 : K;
    g[0] = (c[i1] - c[i0]) * j->half_inv[0] * (i1 - i0 == 2 ? 1.0f : 2.0f);
    g[1] = (c[j1] - c[j0]) * j->half_inv[1] * (j1 - j0 == 2 * NX ? 1.0f : 2.0f);
    g[2] = (slice(w, k1)[at] - slice(w, k0)[at]) * j->half_inv[2] * (k1 - k0 == 2 ? 1.0f : 2.0f);
}

/* Normal n scaled to unit length (0 when it is 0). */
static inline void unit_normal(float *n)
{
    float len2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2], inv = len2 > 0 ? 1.0f / sqrtf(len2) : 0.0f;
    for (int d = 0; d < 3; d++)
        n[d] *= inv;
}

/* unit_normal of each of the count normals at n, the square roots and divisions four at a time
 * where SSE is: the same bits (both are rounded exactly, one at a time or four), at a quarter of
 * the latency that held up the vertices one by one. */
static void unit_normals(float *n, size_t count)
{
    size_t i = 0;
#ifdef __SSE2__
    for (; i + 4 <= count; i += 4, n += 12) {
        float l[4];
        for (int k = 0; k < 4; k++)
            l[k] = n[3 * k] * n[3 * k] + n[3 * k + 1] * n[3 * k + 1] + n[3 * k + 2] * n[3 * k + 2];
        __m128 len2 = _mm_loadu_ps(l);
        __m128 inv = _mm_and_ps(_mm_div_ps(_mm_set1_ps(1.0f), _mm_sqrt_ps(len2)), _mm_cmpgt_ps(len2, _mm_setzero_ps()));
        _mm_storeu_ps(l, inv);
        for (int k = 0; k < 12; k++)
            n[k] *= l[k / 3];
    }
#endif
    for (; i < count; i++, n += 3)
        unit_normal(n);
}

/* The vertex on the edge from virtual sample (I, J, K) (value a) to its neighbour along axis
 * (value b): its position into pos, its normal into nrm (when not NULL), not yet of unit length
 * (unit_normal). The one computation of both extractions (the slabs' and a box's), so that they
 * agree bit for bit. */
static inline __attribute__((always_inline)) void vertex_at(const struct iso_job *j, const struct window *w, int I,
                                                        int J, int K, int axis, float a, float b, float *pos,
                                                        float *nrm)
{
    double t = ((double)j->iso - a) / ((double)b - a);
    t = t < ISO_EDGE_MARGIN ? ISO_EDGE_MARGIN : t > 1 - ISO_EDGE_MARGIN ? 1 - ISO_EDGE_MARGIN : t;
    int p[3] = {I, J, K};
    for (int d = 0; d < 3; d++)
        pos[d] = (float)(j->org[d] + j->g.spacing[d] * (p[d] + (d == axis ? t : 0)));
    if (!nrm)
        return;
    float g0[3], g1[3], ft = (float)t;
    int NX = j->NX, dx = axis == 0, dy = axis == 1, dz = axis == 2;
    if (I > 0 && J > 0 && K > 0 && I + 1 + dx < NX && J + 1 + dy < j->NY && K + 1 + dz < j->NZ) {
        /* both ends' neighbours inside: gradient's common case, its sums as there */
        size_t at = (size_t)I + (size_t)NX * J, at1 = at + (size_t)dx + (size_t)NX * dy;
        const float *below = slice(w, K - 1), *mid = slice(w, K), *above = slice(w, K + 1), *c = mid + at;
        const float *m1 = dz ? above : mid, *b1 = dz ? mid : below, *a1 = dz ? slice(w, K + 2) : above, *c1 = m1 + at1;
        g0[0] = (c[1] - c[-1]) * j->half_inv[0];
        g0[1] = (c[NX] - c[-NX]) * j->half_inv[1];
        g0[2] = (above[at] - below[at]) * j->half_inv[2];
        g1[0] = (c1[1] - c1[-1]) * j->half_inv[0];
        g1[1] = (c1[NX] - c1[-NX]) * j->half_inv[1];
        g1[2] = (a1[at1] - b1[at1]) * j->half_inv[2];
    } else {
        gradient(j, w, I, J, K, g0);
        gradient(j, w, I + dx, J + dy, K + dz, g1);
    }
    for (int d = 0; d < 3; d++)
        nrm[d] = (ft - 1) * g0[d] - ft * g1[d]; /* outward: down the gradient */
}

/* Vertex v on the edge from virtual sample p to its neighbour along axis (its normal made unit by
 * the caller, unit_normals). */
static void put_vertex(struct iso_job *j, const struct window *w, size_t v, int I, int J, int K, int axis, float a,
                       float b)
{
    vertex_at(j, w, I, J, K, axis, a, b, j->m.pos + 3 * v, j->m.nrm ? j->m.nrm + 3 * v : NULL);
    if (j->key)
        j->key[v] = iso_vertex_key(j->NX, j->NY, I, J, K, axis, 0);
}

/* The vertex at the centre of a loop of cell (I, J, K) (rows r[z][y]): the mean of the loop's
 * edge crossings, its normal down the trilinear interpolant's gradient there. */
static void centre_at(const struct iso_job *j, int I, int J, int K, const float *r[2][2], unsigned edges, float *pos,
                      float *nrm)
{
    double f[8], p[3] = {0, 0, 0};
    for (int c = 0; c < 8; c++)
        f[c] = r[c >> 2][c >> 1 & 1][I + (c & 1)];
    int n = 0;
    for (int a = 0; a < 8; a++)
        for (int axis = 0; axis < 3; axis++) {
            int b = a | 1 << axis;
            if (b == a || !(edges >> edge_of(a, b) & 1))
                continue;
            double t = ((double)j->iso - f[a]) / (f[b] - f[a]);
            t = t < ISO_EDGE_MARGIN ? ISO_EDGE_MARGIN : t > 1 - ISO_EDGE_MARGIN ? 1 - ISO_EDGE_MARGIN : t;
            for (int d = 0; d < 3; d++)
                p[d] += (a >> d & 1) + (d == axis ? t : 0);
            n++;
        }
    for (int d = 0; d < 3; d++)
        p[d] /= n;
    int at[3] = {I, J, K};
    for (int d = 0; d < 3; d++)
        pos[d] = (float)(j->org[d] + j->g.spacing[d] * (at[d] + p[d]));
    if (!nrm)
        return;
    double g[3] = {0, 0, 0}, len = 0;
    for (int c = 0; c < 8; c++) { /* d/dp_d of the trilinear weights */
        double w[3] = {c & 1 ? p[0] : 1 - p[0], c >> 1 & 1 ? p[1] : 1 - p[1], c >> 2 & 1 ? p[2] : 1 - p[2]};
        for (int d = 0; d < 3; d++)
            g[d] += f[c] * (c >> d & 1 ? 1 : -1) * w[(d + 1) % 3] * w[(d + 2) % 3] / j->g.spacing[d];
    }
    for (int d = 0; d < 3; d++)
        len += g[d] * g[d];
    len = sqrt(len);
    for (int d = 0; d < 3; d++)
        nrm[d] = len > 0 ? (float)(-g[d] / len) : 0.0f;
}

/* Vertex v at the centre of loop c of cell (I, J, K), of the edges edges. */
static void put_centre(struct iso_job *j, size_t v, int I, int J, int K, const float *r[2][2], int c, unsigned edges)
{
    centre_at(j, I, J, K, r, edges, j->m.pos + 3 * v, j->m.nrm ? j->m.nrm + 3 * v : NULL);
    if (j->key)
        j->key[v] = iso_vertex_key(j->NX, j->NY, I, J, K, 3, c);
}

/* The x and y vertices of level K. */
static void emit_level(struct iso_job *j, const struct window *w, int K)
{
    int NX = j->NX, NY = j->NY, W = bit_words(NX), lo, hi;
    const float *a = slice(w, K);
    const uint64_t *bits = slice_bits(w, K);
    const struct trim *t = j->trim + (size_t)NY * K;
    for (int J = 0; J < NY; J++) {
        const float *r = a + (size_t)NX * J;
        const uint64_t *rb = bits + (size_t)W * J;
        const struct trim *x[1] = {&t[J]}, *y[2] = {&t[J], &t[J + 1 < NY ? J + 1 : J]};
        size_t v = j->xb[J + (size_t)NY * K];
        struct diffs d;
        span(x, 1, 1, NX - 2, &lo, &hi);
        diffs_begin(&d, rb, NULL, lo, hi);
        for (int I; (I = diffs_next(&d)) >= 0;)
            put_vertex(j, w, v++, I, J, K, 0, r[I], r[I + 1]);
        if (J + 1 == NY)
            continue;
        v = j->yb[J + (size_t)NY * K];
        span(y, 2, 0, NX - 1, &lo, &hi);
        diffs_begin(&d, rb, rb + W, lo, hi);
        for (int I; (I = diffs_next(&d)) >= 0;)
            put_vertex(j, w, v++, I, J, K, 1, r[I], r[I + NX]);
    }
}

/* The z vertices between levels K and K+1, and the triangles of cell layer K (their cases from
 * *cases on, as pass 1 left them). */
static void emit_layer(struct iso_job *j, const struct window *w, int K, const uint16_t **cases)
{
    int NX = j->NX, NY = j->NY, W = bit_words(NX);
    const float *a = slice(w, K), *b = slice(w, K + 1);
    const uint64_t *ab = slice_bits(w, K), *bb = slice_bits(w, K + 1);
    const struct trim *ta = j->trim + (size_t)NY * K, *tb = ta + NY;
    int lo, hi;
    for (int J = 0; J < NY; J++) {
        size_t v = j->zb[J + (size_t)NY * K];
        const float *a0 = a + (size_t)NX * J, *b0 = b + (size_t)NX * J;
        const struct trim *z[2] = {&ta[J], &tb[J]};
        struct diffs d;
        span(z, 2, 0, NX - 1, &lo, &hi);
        diffs_begin(&d, ab + (size_t)W * J, bb + (size_t)W * J, lo, hi);
        for (int I; (I = diffs_next(&d)) >= 0;)
            put_vertex(j, w, v++, I, J, K, 2, a0[I], b0[I]);
    }
    for (int J = 0; J + 1 < NY; J++) {
        const float *r[2][2] = {{a + (size_t)NX * J, a + (size_t)NX * (J + 1)}, {b + (size_t)NX * J, b + (size_t)NX * (J + 1)}};
        size_t row = J + (size_t)NY * K, up = row + NY; /* level K+1's row J */
        /* running ids: crossings before column I in each row a cell of this row touches */
        /* (ids under ISO_MAX_VERTICES: 32 bits) */
        uint32_t cx[4] = {(uint32_t)j->xb[row], (uint32_t)j->xb[row + 1], (uint32_t)j->xb[up],
                          (uint32_t)j->xb[up + 1]};                           /* (y, z) = 00 10 01 11 */
        uint32_t cy[2] = {(uint32_t)j->yb[row], (uint32_t)j->yb[up]};         /* z = 0, 1 */
        uint32_t cz[2] = {(uint32_t)j->zb[row], (uint32_t)j->zb[row + 1]};    /* y = 0, 1 */
        uint32_t *tri = j->m.tri + 3 * j->tb[row], *cell = j->cell ? j->cell + j->tb[row] : NULL;
        uint32_t cell_row = (uint32_t)(NX - 1) * ((uint32_t)J + (uint32_t)(NY - 1) * (uint32_t)K);
        size_t centre = j->cb[row];
        const struct trim *rows[4] = {&ta[J], &ta[J + 1], &tb[J], &tb[J + 1]};
        span(rows, 4, 1, NX - 2, &lo, &hi); /* no crossing of any row the cells touch lies before lo */
        const uint64_t *p0 = ab + (size_t)W * J, *q0 = bb + (size_t)W * J;
        struct cells cl; /* (the cells passed over cross no edge: every running id stays) */
        cells_begin(&cl, p0, p0 + W, q0, q0 + W, lo, hi);
        for (int I; (I = cells_next(&cl)) >= 0;) {
            const struct cell_case *cc = &CASES[**cases];
            /* the cell's crossed edges from its corner states (the case index's): the x edges 0-3,
             * the y and z edges at x = 0 (4, 6; 8, 10), whose x = 1 ones (5, 7; 9, 11) are the next
             * crossings of their rows */
            unsigned e = CROSSED[*(*cases)++ / (64 * 2)];
            uint32_t xs[4] = {e & 1, e >> 1 & 1, e >> 2 & 1, e >> 3 & 1}, ys[2] = {e >> 4 & 1, e >> 6 & 1},
                     zs[2] = {e >> 8 & 1, e >> 10 & 1};
            uint32_t ids[12 + MAX_CENTRES] = {cx[0], cx[1], cx[2], cx[3], cy[0], cy[0] + ys[0], cy[1], cy[1] + ys[1],
                                              cz[0], cz[0] + zs[0], cz[1], cz[1] + zs[1]};
            int n = cc->n;
            for (int c = 0; c < cc->n_centres; c++) {
                ids[12 + c] = (uint32_t)centre;
                put_centre(j, centre++, I, J, K, r, c, cc->centre_of[c]);
            }
            if (cell)
                for (int k = 0; k < n; k++)
                    *cell++ = cell_row + (uint32_t)I;
            const uint8_t *ce = cc->e;
            for (int k = 0; k < 3 * n; k++)
                tri[k] = ids[ce[k]];
            tri += 3 * n;
            for (int k = 0; k < 4; k++)
                cx[k] += xs[k];
            cy[0] += ys[0], cy[1] += ys[1];
            cz[0] += zs[0], cz[1] += zs[1];
        }
    }
}

/* The normals of level K's edge vertices (its x, y and z rows': the centres' are unit) made unit. */
static void unit_level(struct iso_job *j, int K)
{
    size_t row = (size_t)j->NY * K;
    if (j->m.nrm)
        unit_normals(j->m.nrm + 3 * j->xb[row], j->cb[row] - j->xb[row]);
}

void iso_emit(struct iso_job *j, int s)
{
    size_t plane = (size_t)j->NX * (size_t)j->NY;
    float *buf = malloc(4 * plane * sizeof *buf);
    if (!buf) {
        j->slab_failed[s] = true;
        return;
    }
    struct window w = {{buf, buf + plane, buf + 2 * plane, buf + 3 * plane}, -10, {NULL}};
    const uint16_t *cases = j->cases[s].at;
    for (int K = j->k0[s]; K < j->k0[s + 1]; K++) {
        window_at(j, &w, K);
        emit_level(j, &w, K);
        emit_layer(j, &w, K, &cases);
        unit_level(j, K);
    }
    if (s == j->n_slabs - 1) {
        window_at(j, &w, j->NZ - 1);
        emit_level(j, &w, j->NZ - 1);
        unit_level(j, j->NZ - 1);
    }
    free(buf);
}

int iso_end(struct iso_job *j, struct trimesh *out, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    int rc = slabs_ok(j, err);
    if (!rc) {
        *out = j->m;
        memset(&j->m, 0, sizeof j->m);
    }
    iso_free(j);
    return rc;
}

int iso_extract(const struct iso_grid *g, const struct iso_opts *o, const struct sf_progress *pr, struct trimesh *out,
                struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    struct iso_job *j;
    int n = g->nz / 8 + 1, rc = iso_begin(g, o, n, &j, err);
    if (rc)
        return rc;
    n = iso_n_slabs(j);
    for (int s = 0; s < n && !rc; s++) {
        iso_count(j, s);
        rc = sf_poll(pr, 0.5 * (s + 1) / n, err);
    }
    if (!rc)
        rc = iso_layout(j, err);
    for (int s = 0; s < n && !rc; s++) {
        iso_emit(j, s);
        rc = sf_poll(pr, 0.5 + 0.5 * (s + 1) / n, err);
    }
    if (rc) {
        iso_free(j);
        return rc;
    }
    return iso_end(j, out, err);
}

/* ---- boxes of cells (mc.h: iso_box_extract) ---- */

/* Rows Y0 .. Y1, columns X0 .. X1 of virtual slice K into out (laid out as a whole slice). */
static void load_rect(const struct iso_job *j, int K, float *out, const int rect[4])
{
    int s = j->shift, z = K - s;
    for (int J = rect[2]; J <= rect[3]; J++) {
        float *row = out + (size_t)j->NX * J;
        int y = J - s, a = rect[0], b = rect[1];
        if (y < 0 || y >= j->g.ny || z < 0 || z >= j->g.nz) {
            for (int I = a; I <= b; I++)
                row[I] = j->pad;
            continue;
        }
        if (a - s < 0)
            row[a++] = j->pad;
        if (b - s >= j->g.nx)
            row[b--] = j->pad;
        if (a <= b)
            grid_span(&j->g, a - s, y, z, b - a + 1, row + a);
    }
}

static void rect_window_at(const struct iso_job *j, struct window *w, int K, const int rect[4])
{
    if (K == w->k + 1) {
        float *t = w->s[0];
        w->s[0] = w->s[1], w->s[1] = w->s[2], w->s[2] = w->s[3], w->s[3] = t;
        uint64_t *u = w->b[0];
        w->b[0] = w->b[1], w->b[1] = w->b[2], w->b[2] = w->b[3], w->b[3] = u;
        w->k = K;
        if (K + 2 < j->NZ) {
            load_rect(j, K + 2, w->s[3], rect);
            rect_bits(w->s[3], j->NX, rect, j->iso, w->b[3]);
        }
        return;
    }
    w->k = K;
    for (int d = -1; d <= 2; d++)
        if (K + d >= 0 && K + d < j->NZ) {
            load_rect(j, K + d, w->s[d + 1], rect);
            rect_bits(w->s[d + 1], j->NX, rect, j->iso, w->b[d + 1]);
        }
}

static bool box_grow(struct iso_box *b, size_t verts, size_t tris, bool normals)
{
    if (b->n_vert + verts > b->cap_vert) {
        size_t cap = b->cap_vert ? 2 * b->cap_vert : 4096;
        while (cap < b->n_vert + verts)
            cap *= 2;
        float *p = realloc(b->pos, cap * 3 * sizeof *p);
        if (p)
            b->pos = p;
        float *n = normals ? realloc(b->nrm, cap * 3 * sizeof *n) : b->nrm;
        if (n)
            b->nrm = n;
        uint64_t *k = realloc(b->key, cap * sizeof *k);
        if (k)
            b->key = k;
        if (!p || (normals && !n) || !k)
            return false;
        b->cap_vert = cap;
    }
    if (b->n_tri + tris > b->cap_tri) {
        size_t cap = b->cap_tri ? 2 * b->cap_tri : 4096;
        while (cap < b->n_tri + tris)
            cap *= 2;
        uint32_t *t = realloc(b->tri, cap * 3 * sizeof *t);
        if (t)
            b->tri = t;
        uint32_t *c = realloc(b->cell, cap * sizeof *c);
        if (c)
            b->cell = c;
        if (!t || !c)
            return false;
        b->cap_tri = cap;
    }
    return true;
}

/* The box's pass: the edges' vertex ids live in tagged slots (tag << 32 | id; tag = the level
 * plus one, for x and y edges, the layer plus one for z edges), two levels of x and y edges and a
 * layer of z edges, so that no slot is cleared as the pass moves on. */
struct box_pass {
    struct iso_job j;
    struct window w;
    struct iso_box *out;
    int lo[3], W;                    /* W: samples a row of the box */
    uint64_t *ex[2], *ey[2], *ez;
};

static uint32_t edge_vertex(struct box_pass *p, int e, int I, int J, int K)
{
    static const int8_t OFF[12][3] = {{0, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 1, 1}, {0, 0, 0}, {1, 0, 0},
                                      {0, 0, 1}, {1, 0, 1}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
    int x = OFF[e][0], y = OFF[e][1], z = OFF[e][2], axis = e >> 2;
    uint64_t *slot;
    size_t at = (size_t)(I + x - p->lo[0]) + (size_t)p->W * (size_t)(J + y - p->lo[1]);
    uint64_t tag = (uint64_t)(K + z + 1) << 32;
    slot = axis == 0 ? p->ex[(K + z) & 1] + at : axis == 1 ? p->ey[(K + z) & 1] + at : p->ez + at;
    if ((*slot & 0xffffffff00000000u) == tag)
        return (uint32_t)*slot;
    struct iso_box *b = p->out;
    size_t v = b->n_vert++;
    const struct iso_job *j = &p->j;
    int I0 = I + x, J0 = J + y, K0 = K + z;
    const float *s = slice(&p->w, K0) + (size_t)I0 + (size_t)j->NX * J0;
    float va = s[0], vb = axis == 0 ? s[1] : axis == 1 ? s[j->NX] : slice(&p->w, K0 + 1)[s - slice(&p->w, K0)];
    vertex_at(j, &p->w, I0, J0, K0, axis, va, vb, b->pos + 3 * v, b->nrm ? b->nrm + 3 * v : NULL);
    if (b->nrm)
        unit_normal(b->nrm + 3 * v);
    b->key[v] = iso_vertex_key(j->NX, j->NY, I0, J0, K0, axis, 0);
    *slot = tag | v;
    return (uint32_t)v;
}

/* Cells I0 .. I1 of row (J, K). */
static void box_run(struct box_pass *p, int I0, int I1, int J, int K)
{
    const struct iso_job *j = &p->j;
    struct iso_box *b = p->out;
    int NX = j->NX;
    const float *a = slice(&p->w, K), *c = slice(&p->w, K + 1);
    const float *r[2][2] = {{a + (size_t)NX * J, a + (size_t)NX * (J + 1)}, {c + (size_t)NX * J, c + (size_t)NX * (J + 1)}};
    const float *a0 = r[0][0], *a1 = r[0][1], *b0 = r[1][0], *b1 = r[1][1];
    uint32_t row = (uint32_t)(NX - 1) * ((uint32_t)J + (uint32_t)(j->NY - 1) * (uint32_t)K);
    int W = bit_words(NX);
    const uint64_t *p0 = slice_bits(&p->w, K) + (size_t)W * J, *q0 = slice_bits(&p->w, K + 1) + (size_t)W * J;
    struct cells cl;
    cells_begin(&cl, p0, p0 + W, q0, q0 + W, I0, I1);
    for (int I; (I = cells_next(&cl)) >= 0;) {
        int st = states_at(&cl, I), idx = st * 64 * 2;
        if (!states_decide(st))
            idx = cell_case(j, st, (const float[8]){a0[I], a0[I + 1], a1[I], a1[I + 1], b0[I], b0[I + 1], b1[I], b1[I + 1]});
        const struct cell_case *cc = &CASES[idx];
        uint32_t ids[12 + MAX_CENTRES];
        for (unsigned m = CROSSED[st]; m; m &= m - 1)
            ids[__builtin_ctz(m)] = edge_vertex(p, __builtin_ctz(m), I, J, K);
        for (int k = 0; k < cc->n_centres; k++) {
            size_t v = b->n_vert++;
            centre_at(j, I, J, K, r, cc->centre_of[k], b->pos + 3 * v, b->nrm ? b->nrm + 3 * v : NULL);
            b->key[v] = iso_vertex_key(NX, j->NY, I, J, K, 3, k);
            ids[12 + k] = (uint32_t)v;
        }
        uint32_t *tri = b->tri + 3 * b->n_tri;
        b->n_cells++;
        for (int k = 0; k < 3 * cc->n; k++)
            tri[k] = ids[cc->e[k]];
        for (int k = 0; k < cc->n; k++)
            b->cell[b->n_tri + k] = row + (uint32_t)I;
        b->n_tri += cc->n;
    }
}

int iso_box_extract(const struct iso_grid *g, const struct iso_opts *o, float pad, const int lo[3], const int hi[3],
                    struct iso_box *out, struct sf_err *err)
{
    if (!tables_built)
        return sf_fail(err, SF_EBACKEND, "", "iso_init() was not called");
    struct box_pass p = {.out = out};
    struct iso_job *j = &p.j;
    frame(j, g, o);
    j->pad = o->closed ? pad : 0;
    out->n_vert = out->n_tri = out->n_cells = 0;
    int C[3] = {j->NX - 1, j->NY - 1, j->NZ - 1}, rect[4];
    for (int d = 0; d < 3; d++)
        if (lo[d] < 0 || hi[d] >= C[d] || lo[d] > hi[d])
            return 0; /* (an empty box) */
    /* the samples the cells and their vertices' normals read: one further each way */
    rect[0] = lo[0] > 0 ? lo[0] - 1 : 0;
    rect[1] = hi[0] + 2 < j->NX ? hi[0] + 2 : j->NX - 1;
    rect[2] = lo[1] > 0 ? lo[1] - 1 : 0;
    rect[3] = hi[1] + 2 < j->NY ? hi[1] + 2 : j->NY - 1;
    p.W = hi[0] - lo[0] + 2;
    size_t plane = (size_t)j->NX * (size_t)j->NY, slots = (size_t)p.W * (size_t)(hi[1] - lo[1] + 2);
    size_t bplane = (size_t)bit_words(j->NX) * (size_t)j->NY;
    size_t need = 4 * plane * sizeof(float) + (5 * slots + 4 * bplane) * sizeof(uint64_t);
    if (need > out->scratch_bytes) {
        void *s = realloc(out->scratch, need);
        if (!s)
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        out->scratch = s, out->scratch_bytes = need;
    }
    float *f = out->scratch;
    uint64_t *t = (uint64_t *)(f + 4 * plane), *bits = t + 5 * slots;
    p.w = (struct window){{f, f + plane, f + 2 * plane, f + 3 * plane}, -10,
                          {bits, bits + bplane, bits + 2 * bplane, bits + 3 * bplane}};
    memset(t, 0, 5 * slots * sizeof *t);
    p.ex[0] = t, p.ex[1] = t + slots, p.ey[0] = t + 2 * slots, p.ey[1] = t + 3 * slots, p.ez = t + 4 * slots;
    memcpy(p.lo, lo, sizeof p.lo);
    for (int K = lo[2]; K <= hi[2]; K++) {
        rect_window_at(j, &p.w, K, rect);
        for (int J = lo[1]; J <= hi[1]; J++) {
            /* room for the row's worst case: 12 triangles, 3 new edges and the centres a cell */
            size_t cells = (size_t)(hi[0] - lo[0] + 1);
            if (!box_grow(out, cells * (3 + MAX_CENTRES) + 16, cells * MAX_CELL_TRIS, o->normals))
                return sf_fail(err, SF_ENOMEM, "", "out of memory");
            box_run(&p, lo[0], hi[0], J, K);
            if (out->n_vert > ISO_MAX_VERTICES)
                return sf_fail(err, SF_ELIMIT, "", "the isosurface would have %zu vertices, over the limit of %u",
                               out->n_vert, ISO_MAX_VERTICES);
        }
    }
    return 0;
}

int iso_box_whole(const struct iso_grid *g, const struct iso_opts *o, struct iso_box *out, struct sf_err *err)
{
    struct iso_job *j;
    int rc = iso_begin(g, o, 1, &j, err);
    if (rc)
        return rc;
    j->into = out;
    iso_count(j, 0);
    if (!(rc = iso_layout(j, err))) {
        iso_emit(j, 0);
        rc = slabs_ok(j, err);
    }
    if (!rc) {
        out->n_vert = j->m.n_vert, out->n_tri = j->m.n_tri, out->n_cells = j->cases[0].n;
    }
    iso_free(j);
    return rc;
}

int iso_box_reserve(struct iso_box *b, size_t verts, bool normals)
{
    size_t n = b->n_vert;
    b->n_vert = 0; /* (room for verts from the start) */
    bool ok = box_grow(b, verts, 0, normals);
    b->n_vert = n;
    if (!ok)
        return -1;
    memset(b->pos, 0, b->cap_vert * 3 * sizeof *b->pos);
    if (normals)
        memset(b->nrm, 0, b->cap_vert * 3 * sizeof *b->nrm);
    memset(b->key, 0, b->cap_vert * sizeof *b->key);
    return 0;
}

size_t iso_box_bytes(const struct iso_box *b)
{
    return b->cap_vert * ((b->nrm ? 6 : 3) * sizeof(float) + sizeof(uint64_t)) + b->cap_tri * 4 * sizeof(uint32_t) +
           b->scratch_bytes;
}

void iso_box_free(struct iso_box *b)
{
    free(b->pos);
    free(b->nrm);
    free(b->key);
    free(b->tri);
    free(b->cell);
    free(b->scratch);
    memset(b, 0, sizeof *b);
}
