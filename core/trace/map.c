/* map.c - conservative raster of a screen-adaptive tessellation into the preliminary-value map.
 *
 * Each patch is tessellated so that its chord error, seen from its nearest point, stays under
 * half a pixel. Its triangles mark the pixel centres they cover (no padding: the triangles of a
 * patch tile its image, so only the outline of that image can be off the true one); the
 * outline - the grid's border and every fold, where two neighbouring triangles face opposite
 * ways on screen or either is too thin there for its turn to be the surface's (the chord bound's
 * second derivatives let the surface's tangents leave its edges by 4 chord errors: a sliver seen
 * edge-on may be pleated within a cell; tested only in cells where the surface may be seen
 * edge-on: where the Bernstein coefficients of (Pu x Pv).(P - eye) over the cell, or for a patch of
 * high degree its normal cone and the directions from the eye to it, do not keep one sign, as
 * elsewhere its image folds nowhere)
 * - is then widened by the chord error as the projection
 * may stretch it (capsules around those edges), so the true silhouette always has a seed. Seeds
 * take the perspective-correct attributes of the covering triangle, or of the nearest point of
 * the outline edge; a candidate near its patch's outline remembers the depth of the outline and of
 * any fold there (the tracer then trusts no root behind a fold, nor one seeded by the outline
 * alone). A seam - a whole edge two patches share, one's parameter going on into the other's
 * (bvh_seam) - is sampled at the same parameters on both sides and is no outline where the
 * triangles either side turn alike: the two tile their joint image as one patch's cells do, and a
 * pixel there may list one where the root is the other's (the tracer then searches all patches).
 * Primitives are rasterised nearest depth bound first, and a fragment behind
 * where a nearer triangle expects its patch's root is culled as from a full list. Written by
 * hand: no library rasterises with these guarantees, and the rows are filled by bands. */
#include "map.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"
#include "../geom/tess.h"
#include "bvh.h"
#include "bvh_cone.h"

#define MAP_ERR_PX 0.5   /* chord error allowed, in pixels at the patch's nearest depth */
#define MAP_PAD_SLACK 0.1 /* pixels the outline is widened by beyond the projected chord error */
#define MAP_MAX_SIDE 96  /* grid cap per patch side; the pad grows where the cap binds */
#define MAP_TRIM_SIDE 32 /* grid side at least, on a patch a trim loop crosses */
#define MAP_SEAM_GROW 4  /* a seam's count taken where it is at most this many times the patch's own:
                          * small patches chained to a large one keep their grids, and a scene's map
                          * at most MAP_SEAM_GROW^2 times the cells it had without seams (the heart's:
                          * 192.6 k triangles with the bound, 193.0 k without) */
#define NEAR_EPS 1e-9    /* relative depth below which a vertex counts as behind the eye */

struct map_vert { /* a tessellation vertex on screen */
    double x, y, iz;      /* pixel-centre coordinates, 1/depth */
    double uz, vz;        /* u/depth, v/depth */
};

struct map_tri {           /* a triangle, or (v[2] == EDGE) a padded outline edge v[0]-v[1] */
    unsigned v[3];
    int patch;
    float pad;            /* dilation, pixels: 0 for triangles */
    float zlo;            /* depth bound of the patch's surface near this primitive */
    bool fold;            /* an outline edge inside the grid (where the surface turns away), not its border */
    signed char turn;     /* a border edge: the turn on screen of the triangle inside it */
    short box[4];         /* its pixel centres x0, x1, y0, y1, padding in (x0 > x1 or y0 > y1: none) */
};

#define EDGE UINT_MAX
#define COVER_EPS 1e-7  /* pixels: a centre this near a triangle's edge counts as inside it */
#define PREFETCH_AHEAD 16 /* triangles of a tile's list fetched ahead of the raster */
#define SPAN_SLACK 1e-6 /* pixels: a row's span ends, widened past their rounding */

void map_free(struct map *m)
{
    if (!m)
        return;
    free(m->verts);
    free(m->tris);
    free(m->grid);
    free(m->pix);
    free(m->vfirst);
    free(m->first);
    free(m->end);
    free(m->part_first);
    free(m->part_failed);
    for (int p = 0; m->part_keys && p < m->n_parts; p++)
        free(m->part_keys[p]);
    free(m->part_keys);
    free(m->part_hist);
    free(m->border);
    free(m->segs);
    free(m->sfirst);
    free(m->pad);
    free(m->seamed);
    for (int y = 0; m->tile_list && y < m->n_tiles; y++)
        free(m->tile_list[y]);
    free(m->tile_list);
    free(m->tile_n);
    free(m);
}

/* Offers a fragment of `patch` to a pixel's candidate list: depth bound zlo, seed (u, v) and the
 * fragment's own depth zs there. A patch listed already keeps the least bound and the seed of
 * its nearest fragment (where a patch folds over a pixel, the seed on the near sheet). */
static void put(struct map_rows *rw, size_t idx, const struct map_tri *t, float u, float v, float zs)
{
    const int patch = t->patch;
    const float zlo = t->zlo;
    struct map_cand *c = &rw->cand[idx * MAP_CANDS];
    int n = rw->n[idx], at = 0;
    if (n == 0) /* the pixel's first fragment: its bounds start here */
        rw->dropped[idx] = rw->zcut[idx] = INFINITY;
    while (at < n && c[at].patch != patch)
        at++;
    const float zfold = t->fold ? zs : INFINITY, zoutline = t->v[2] == EDGE ? zs : INFINITY;
    if (at < n) {
        if (zs < c[at].zs)
            c[at].u = u, c[at].v = v, c[at].zs = zs;
        c[at].zfold = dmin(c[at].zfold, zfold);
        c[at].zoutline = dmin(c[at].zoutline, zoutline);
        if (!(zlo < c[at].zlo))
            return;
        struct map_cand keep = c[at];
        keep.zlo = zlo;
        for (; at > 0 && c[at - 1].zlo > zlo; at--)
            c[at] = c[at - 1];
        c[at] = keep;
        return;
    }
    /* a new patch: insert in order, pushing the last one out if the list is full */
    int pos = 0;
    while (pos < n && c[pos].zlo <= zlo)
        pos++;
    if (pos == MAP_CANDS) {
        rw->dropped[idx] = dmin(rw->dropped[idx], zlo);
        return;
    }
    if (n == MAP_CANDS) /* the last one goes */
        rw->dropped[idx] = dmin(rw->dropped[idx], c[--n].zlo);
    for (int k = n; k > pos; k--)
        c[k] = c[k - 1];
    c[pos] = (struct map_cand){patch, u, v, zlo, zs, zfold, zoutline};
    rw->n[idx] = (unsigned char)(n + 1);
}

/* True when a fragment with depth bound zlo at pixel idx lies behind where the nearest triangle
 * there expects its patch's root (zcut): it is dropped unlisted, as from a full list, and the
 * tracer searches everything should that root not be found in front of it. Triangles come
 * nearest bound first, so most hidden sheets never reach put(). */
static bool culled(struct map_rows *rw, size_t idx, float zlo)
{
    if (!rw->n[idx] || !(zlo > rw->zcut[idx]))
        return false;
    rw->dropped[idx] = dmin(rw->dropped[idx], zlo);
    return true;
}

/* floor(x) (ceil: up) clamped to [-1, n]: off the picture either side stays off it */
static inline int pixel_of(double x, int n, bool up)
{
    x = x >= -1.0 ? (x <= n ? x : n) : -1.0; /* (NaN: -1) */
    int i = (int)x;
    return up ? i + (i < x) : i - (i > x);
}

/* t's box of pixel centres, its padding in (x0 > x1 or y0 > y1: off the picture). */
static void tri_box(const struct map *m, struct map_tri *t)
{
    const struct map_vert *a = &m->verts[t->v[0]], *b = &m->verts[t->v[1]];
    const struct map_vert *c = t->v[2] == EDGE ? b : &m->verts[t->v[2]];
    int x0 = pixel_of(dmin(a->x, dmin(b->x, c->x)) - t->pad, m->W, false);
    int x1 = pixel_of(dmax(a->x, dmax(b->x, c->x)) + t->pad, m->W, true);
    int y0 = pixel_of(dmin(a->y, dmin(b->y, c->y)) - t->pad, m->H, false);
    int y1 = pixel_of(dmax(a->y, dmax(b->y, c->y)) + t->pad, m->H, true);
    t->box[0] = (short)(x0 < 0 ? 0 : x0), t->box[1] = (short)(x1 > m->W - 1 ? m->W - 1 : x1);
    t->box[2] = (short)(y0 < 0 ? 0 : y0), t->box[3] = (short)(y1 > m->H - 1 ? m->H - 1 : y1);
}

/* Narrows [*lo, *hi] to the x where a <= k x + c <= b. */
static inline void span_between(double k, double c, double a, double b, double *lo, double *hi)
{
    if (k == 0.0) {
        if (c < a || c > b)
            *hi = -INFINITY;
        return;
    }
    double xa = (a - c) / k, xb = (b - c) / k;
    *lo = dmax(*lo, dmin(xa, xb)), *hi = dmin(*hi, dmax(xa, xb));
}

/* The x where row y meets the capsule of radius r round segment a-b (the two end discs and the
 * strip between them; convex, so one span), widened by SPAN_SLACK; false where it misses. A
 * superset only: raster_edge tests each pixel centre in it exactly. */
static bool capsule_span(const struct map_vert *a, const struct map_vert *b, double r, double y, double *lo,
                         double *hi)
{
    double dx = b->x - a->x, dy = b->y - a->y, len = sqrt(dx * dx + dy * dy), ey = y - a->y;
    *lo = INFINITY, *hi = -INFINITY;
    for (int k = 0; k < 2; k++) {
        const struct map_vert *c = k ? b : a;
        double h = r * r - (y - c->y) * (y - c->y);
        if (h >= 0.0)
            *lo = dmin(*lo, c->x - sqrt(h)), *hi = dmax(*hi, c->x + sqrt(h));
    }
    if (len > 0.0) { /* the strip: 0 <= (p - a)·(b - a) <= len², |(p - a) × (b - a)| <= r len */
        double slo = -INFINITY, shi = INFINITY;
        span_between(dx, ey * dy - a->x * dx, 0.0, len * len, &slo, &shi);
        span_between(dy, -ey * dx - a->x * dy, -r * len, r * len, &slo, &shi);
        if (slo <= shi)
            *lo = dmin(*lo, slo), *hi = dmax(*hi, shi);
    }
    if (*lo != *lo || *hi != *hi) /* (not finite: every pixel of the row, tested one by one) */
        *lo = -INFINITY, *hi = INFINITY;
    *lo -= SPAN_SLACK * (1.0 + fabs(*lo)), *hi += SPAN_SLACK * (1.0 + fabs(*hi));
    return *lo <= *hi;
}

/* Marks every pixel centre of rows [y0, y1] within t->pad of the edge t->v[0]-t->v[1]. */
static void raster_edge(const struct map *m, struct map_rows *rw, const struct map_tri *t, int x0, int x1, int y0,
                        int y1)
{
    const struct map_vert *v[2] = {&m->verts[t->v[0]], &m->verts[t->v[1]]};
    double dx = v[1]->x - v[0]->x, dy = v[1]->y - v[0]->y, l2 = dx * dx + dy * dy;
    double pad2 = (double)t->pad * t->pad;
    for (int y = y0; y <= y1; y++) {
        double lo, hi;
        if (!capsule_span(v[0], v[1], t->pad, y, &lo, &hi))
            continue;
        int xs = lo > x0 ? (lo > x1 ? x1 + 1 : (int)ceil(lo)) : x0, xe = hi < x1 ? (hi < x0 ? x0 - 1 : (int)floor(hi)) : x1;
        for (int x = xs; x <= xe; x++) {
            double s = l2 > 0 ? ((x - v[0]->x) * dx + (y - v[0]->y) * dy) / l2 : 0.0;
            s = s < 0 ? 0 : (s > 1 ? 1 : s);
            double ex = v[0]->x + s * dx - x, ey = v[0]->y + s * dy - y;
            if (ex * ex + ey * ey > pad2)
                continue;
            size_t idx = (size_t)(y - rw->y0) * rw->W + x;
            if (culled(rw, idx, t->zlo))
                continue;
            double iz = v[0]->iz + s * (v[1]->iz - v[0]->iz), z = 1.0 / iz;
            double uz = v[0]->uz + s * (v[1]->uz - v[0]->uz), vz = v[0]->vz + s * (v[1]->vz - v[0]->vz);
            put(rw, idx, t, (float)(uz * z), (float)(vz * z), (float)z);
        }
    }
}

/* Marks every pixel centre of rows [y0, y1] that triangle t covers, row by row over the span
 * its three edges leave. 1/depth, u/depth and v/depth are planes over the screen. */
static void raster_tri(const struct map *m, struct map_rows *rw, const struct map_tri *t, int x0, int x1, int y0,
                       int y1)
{
    const struct map_vert *v[3] = {&m->verts[t->v[0]], &m->verts[t->v[1]], &m->verts[t->v[2]]};
    double area = (v[1]->x - v[0]->x) * (v[2]->y - v[0]->y) - (v[1]->y - v[0]->y) * (v[2]->x - v[0]->x);
    if (area == 0.0)
        return; /* no interior; its edges are outline and padded */
    /* edge function k (opposite vertex k), positive inside: w_k = A_k x + B_k y + C_k; inside,
     * the w_k / |area| are the barycentrics */
    double A[3], B[3], C[3], eps[3], iA[3], sgn = area > 0 ? 1.0 : -1.0;
    for (int k = 0; k < 3; k++) {
        const struct map_vert *p = v[(k + 1) % 3], *q = v[(k + 2) % 3];
        A[k] = -sgn * (q->y - p->y);
        B[k] = sgn * (q->x - p->x);
        C[k] = -(A[k] * p->x + B[k] * p->y);
        eps[k] = COVER_EPS * (fabs(A[k]) + fabs(B[k])); /* at least COVER_EPS of distance */
        iA[k] = A[k] != 0.0 ? 1.0 / A[k] : 0.0;
    }
    /* iz, uz, vz: coefficients of x, y, 1; made at the first pixel centre covered (a tessellation
     * of small patches has many triangles that cover none) */
    double plane[3][3] = {{0}};
    bool have_plane = false;
    for (int y = y0; y <= y1; y++) {
        double lo = x0, hi = x1;
        for (int k = 0; k < 3; k++) {
            double c = B[k] * y + C[k] + eps[k]; /* w_k + eps >= 0  <=>  A_k x >= -c */
            if (A[k] > 0)
                lo = dmax(lo, -c * iA[k]);
            else if (A[k] < 0)
                hi = dmin(hi, -c * iA[k]);
            else if (c < 0)
                hi = -INFINITY;
        }
        /* the span's ends, widened by far more than their rounding (1e-6 pixels: a centre that
         * near an edge may as well count as covered) */
        lo -= SPAN_SLACK, hi += SPAN_SLACK;
        if (!(lo <= hi))
            continue;
        /* ceil and floor by truncation (lo >= x0 - SPAN_SLACK > -1): libm's are calls here */
        int xs = (int)lo, xe = (int)(hi + 1.0) - 1;
        xs += xs < lo;
        if (xs > xe)
            continue;
        if (!have_plane) {
            for (int k = 0; k < 3; k++) {
                const double at[3] = {v[k]->iz, v[k]->uz, v[k]->vz}, inv = 1.0 / fabs(area);
                for (int c = 0; c < 3; c++) {
                    plane[c][0] += A[k] * at[c] * inv;
                    plane[c][1] += B[k] * at[c] * inv;
                    plane[c][2] += C[k] * at[c] * inv;
                }
            }
            have_plane = true;
        }
        double iz_y = plane[0][1] * y + plane[0][2], uz_y = plane[1][1] * y + plane[1][2];
        double vz_y = plane[2][1] * y + plane[2][2];
        size_t row = (size_t)(y - rw->y0) * rw->W;
        for (int x = xs; x <= xe; x++) {
            if (culled(rw, row + x, t->zlo))
                continue;
            double z = 1.0 / (plane[0][0] * x + iz_y);
            put(rw, row + x, t, (float)((plane[1][0] * x + uz_y) * z), (float)((plane[2][0] * x + vz_y) * z), (float)z);
            /* the patch's root here is expected about as far behind the fragment as its bound is
             * in front: anything whose bound lies beyond that is most likely hidden */
            rw->zcut[row + x] = dmin(rw->zcut[row + x], 2.0 * z - t->zlo);
        }
    }
}

int map_raster_rows(const struct map *m, int y0, int y1, struct map_rows *rw)
{
    size_t n = (size_t)(y1 - y0) * m->W;
    if (n > rw->cap) {
        map_rows_free(rw);
        rw->cand = malloc(sizeof *rw->cand * n * MAP_CANDS);
        rw->n = malloc(n);
        rw->dropped = malloc(sizeof *rw->dropped * n);
        rw->zcut = malloc(sizeof *rw->zcut * n);
        rw->cap = rw->cand && rw->n && rw->dropped && rw->zcut ? n : 0;
        if (!rw->cap)
            return SF_ENOMEM;
    }
    rw->y0 = y0, rw->y1 = y1, rw->W = m->W;
    memset(rw->n, 0, n); /* the rest is read only where a pixel has candidates, and put() starts it */
    for (int tile = y0 / MAP_TILE_ROWS; tile * MAP_TILE_ROWS < y1; tile++) {
        int lo = tile * MAP_TILE_ROWS > y0 ? tile * MAP_TILE_ROWS : y0;
        int hi = (tile + 1) * MAP_TILE_ROWS < y1 ? (tile + 1) * MAP_TILE_ROWS : y1;
        const unsigned *list = m->tile_list[tile], n_list = m->tile_n[tile];
        for (unsigned k = 0; k < n_list; k++) {
            /* the list goes by depth, so its triangles and their vertices lie anywhere in memory:
             * fetched a few triangles ahead */
            if (k + PREFETCH_AHEAD < n_list)
                __builtin_prefetch(&m->tris[list[k + PREFETCH_AHEAD]]);
            if (k + PREFETCH_AHEAD / 2 < n_list) {
                const struct map_tri *ahead = &m->tris[list[k + PREFETCH_AHEAD / 2]];
                for (int i = 0; i < 3 && ahead->v[i] != EDGE; i++)
                    __builtin_prefetch(&m->verts[ahead->v[i]]);
            }
            const struct map_tri *t = &m->tris[list[k]];
            int ya = t->box[2] < lo ? lo : t->box[2], yb = t->box[3] > hi - 1 ? hi - 1 : t->box[3];
            (t->v[2] == EDGE ? raster_edge : raster_tri)(m, rw, t, t->box[0], t->box[1], ya, yb);
        }
    }
    return 0;
}

void map_rows_free(struct map_rows *rw)
{
    free(rw->cand);
    free(rw->n);
    free(rw->dropped);
    free(rw->zcut);
    memset(rw, 0, sizeof *rw);
}

/* The grid patch pt is tessellated on for the camera: chord error under MAP_ERR_PX pixels at its
 * nearest depth. False where the patch is wholly behind the eye, or crosses the eye's plane (then
 * the map is not complete). *pix: a pixel's world size at its nearest depth. */
static bool patch_grid(struct map *m, const struct patch *pt, const struct camera *cam, int *gu, int *gv, double *pix)
{
    double px_per_unit = cam->H / (2.0 * cam->th); /* pixels per world unit at depth 1 */
    /* nearest depth of the patch: control points bound it (convex hull) */
    double zmin = INFINITY, zmax = -INFINITY;
    for (int i = 0; i <= pt->p; i++)
        for (int j = 0; j <= pt->q; j++) {
            double z = v3_dot(v3_sub(bezier_point(pt, i, j), cam->eye), cam->f);
            zmin = fmin(zmin, z);
            zmax = fmax(zmax, z);
        }
    if (zmax <= 0)
        return false; /* wholly behind the eye */
    if (zmin <= NEAR_EPS * fmax(zmax, 1.0)) {
        m->complete = false;
        return false;
    }
    *pix = zmin / px_per_unit; /* world size of a pixel at the nearest depth */
    tess_grid_size(pt, MAP_ERR_PX * *pix, MAP_MAX_SIDE, gu, gv);
    if (pt->trim) { /* a grid fine enough that its cells the trims cut away can be left out */
        *gu = *gu < MAP_TRIM_SIDE ? MAP_TRIM_SIDE : *gu;
        *gv = *gv < MAP_TRIM_SIDE ? MAP_TRIM_SIDE : *gv;
    }
    return true;
}

struct border_seg { /* a border segment: its cell's depth bound (INFINITY: left out), its triangle's turn */
    float zlo;
    signed char turn;
};

static size_t border_edges(struct map *m, size_t k, int e, const struct border_seg *seg,
                           const struct border_seg *other, size_t nt);

/* A part's scratch, sized for its largest grid. */
struct grid_scratch {
    float *zc;         /* 2 per cell: nearest vertex depth, then the cell's bound */
    signed char *sg;   /* 2 per cell: the triangles' turns on screen */
    bool *keep;        /* 1 per cell: the trim region holds some of it */
    double *bv;        /* (gv + 1) x (q + 1): the Bernstein values of the grid's rows */
    bool *edge_on;     /* 1 per cell: the patch may be seen edge-on over it (jacobian_cells, edge_on_cells) */
};

/* True when no view ray meets the polynomial patch `part` edge-on: its normals' cone (normal_cone)
 * and the cone of the directions from the eye to its net's points (which holds those to all its
 * points: a positive combination of them) are further than 90 degrees apart everywhere, so
 * n.(S - eye) - the sign of the Jacobian of its image on screen - keeps its sign over it and its
 * image folds nowhere. False where it cannot tell (a rational patch: no cone). */
static bool never_edge_on(const struct patch *part, const struct camera *cam)
{
    vec3 a, c = cam->f;
    double sin_a, cos_b = 1.0;
    normal_cone(part, &a, &sin_a);
    if (!(sin_a < 1.0))
        return false;
    if (!cam->ortho) {
        const int n = (part->p + 1) * (part->q + 1);
        vec3 sum = v3(0, 0, 0);
        for (int k = 0; k < n; k++) {
            vec3 d = v3_sub(v3(part->cw[k][0], part->cw[k][1], part->cw[k][2]), cam->eye);
            if (!(v3_len(d) > 0.0))
                return false;
            sum = v3_add(sum, v3_norm(d));
        }
        if (!(v3_len(sum) > 0.0))
            return false;
        c = v3_norm(sum);
        for (int k = 0; k < n; k++)
            cos_b = fmin(cos_b, v3_dot(c, v3_norm(v3_sub(v3(part->cw[k][0], part->cw[k][1], part->cw[k][2]), cam->eye))));
        if (!(cos_b > 0.0))
            return false;
    }
    const double theta = acos(fmax(-1.0, fmin(1.0, v3_dot(a, c)))), spread = asin(sin_a) + acos(fmin(1.0, cos_b));
    const double margin = 1e-6; /* radians: the cones' rounding */
    return theta + spread < 0.5 * M_PI - margin || theta - spread > 0.5 * M_PI + margin;
}

#define EDGE_ON_MIN_CELLS 4 /* a block of the grid this small is not split further */

/* edge_on[cell] over the cells [i0, i1) x [j0, j1) of a gu x gv grid of polynomial patch pt: false
 * where its part of the patch is never seen edge-on (never_edge_on), splitting the block in two
 * along its longer side while it may be and is larger than EDGE_ON_MIN_CELLS. */
static void edge_on_cells(const struct patch *pt, const struct camera *cam, int gu, int gv, int i0, int i1, int j0,
                          int j1, bool *edge_on)
{
    double net[(PATCH_MAX_DEGREE + 1) * (PATCH_MAX_DEGREE + 1)][4], tmp[(PATCH_MAX_DEGREE + 1) * (PATCH_MAX_DEGREE + 1)][4];
    struct patch part = *pt;
    part.cw = net;
    sub_net(pt, (double)i0 / gu, (double)i1 / gu, (double)j0 / gv, (double)j1 / gv, net, tmp);
    const bool free_ = never_edge_on(&part, cam);
    if (free_ || (i1 - i0) * (j1 - j0) <= EDGE_ON_MIN_CELLS) {
        for (int i = i0; i < i1; i++)
            for (int j = j0; j < j1; j++)
                edge_on[(size_t)i * gv + j] = !free_;
        return;
    }
    if (i1 - i0 >= j1 - j0) {
        edge_on_cells(pt, cam, gu, gv, i0, (i0 + i1) / 2, j0, j1, edge_on);
        edge_on_cells(pt, cam, gu, gv, (i0 + i1) / 2, i1, j0, j1, edge_on);
    } else {
        edge_on_cells(pt, cam, gu, gv, i0, i1, j0, (j0 + j1) / 2, edge_on);
        edge_on_cells(pt, cam, gu, gv, i0, i1, (j0 + j1) / 2, j1, edge_on);
    }
}

#define JAC_MAX_DEGREE 8 /* a patch of degree up to this gets the coefficients (g's degree 3 p - 1 < 24) */

/* Bernstein products' weights: w[i][k] = C(a, i) C(b, k) / C(a + b, i + k), so that
 * B_i^a B_k^b = w[i][k] B_{i+k}^{a+b} (bin: binomials up to a + b). */
static void product_weights(int a, int b, double bin[3 * JAC_MAX_DEGREE][3 * JAC_MAX_DEGREE],
                            double w[2 * JAC_MAX_DEGREE][JAC_MAX_DEGREE + 1])
{
    for (int i = 0; i <= a; i++)
        for (int k = 0; k <= b; k++)
            w[i][k] = bin[a][i] * bin[b][k] / bin[a + b][i + k];
}

/* The sign of the Jacobian of a polynomial patch's image on screen is that of
 * g = (Pu x Pv).(P - eye) (in parallel projection (Pu x Pv).f; the perspective divides it by the
 * cube of the depth, > 0): the image folds only where g changes sign, so a cell over which g keeps
 * its sign hides no pleat, and its triangles' turns need no thinness test (add_patch). g is a
 * polynomial of degree (*gp, *gq) = (3p - 1, 3q - 1): its Bernstein coefficients into
 * g[i * (*gq + 1) + j], those of the normals (as normal_cone's, degree (2p - 1, 2q - 1)) times the
 * net's offsets from the eye (degree (p, q)), each pair weighted C(a,i) C(b,k) / C(a+b,i+k) each
 * way. A coefficient's rounding stays far under *tol: each is a convex combination of products
 * bounded by p q |du| |dv| (|P| + |eye|). Tighter than the cones (edge_on_cells): the coefficients
 * over a cell are within O(h²) of g there, where the cones of a block of cells add their angles.
 * False where the degree is too high (JAC_MAX_DEGREE) or the patch rational: the cones then, or
 * the test everywhere. */
static bool jacobian_net(const struct patch *pt, const struct camera *cam, double *g, int *gp, int *gq, double *tol)
{
    const int p = pt->p, q = pt->q, M = 2 * p - 1, N = 2 * q - 1;
    if (pt->rational || p < 1 || q < 1 || p > JAC_MAX_DEGREE || q > JAC_MAX_DEGREE)
        return false;
    const int dp = cam->ortho ? 0 : p, dq = cam->ortho ? 0 : q, GP = M + dp, GQ = N + dq;
    double bin[3 * JAC_MAX_DEGREE][3 * JAC_MAX_DEGREE];
    for (int n = 0; n <= GP || n <= GQ; n++)
        for (int k = 0; k <= n; k++)
            bin[n][k] = k == 0 || k == n ? 1.0 : bin[n - 1][k - 1] + bin[n - 1][k];
    /* (the weights once per patch, the net's differences once each: a patch of the heart model's
     * 2 x 7 cells spent more on its divisions than on its grid) */
    double wu[2 * JAC_MAX_DEGREE][JAC_MAX_DEGREE + 1], wv[2 * JAC_MAX_DEGREE][JAC_MAX_DEGREE + 1];
    double gu_[2 * JAC_MAX_DEGREE][JAC_MAX_DEGREE + 1], gv_[2 * JAC_MAX_DEGREE][JAC_MAX_DEGREE + 1];
    product_weights(p - 1, p, bin, wu), product_weights(q, q - 1, bin, wv);
    product_weights(M, dp, bin, gu_), product_weights(N, dq, bin, gv_);
    vec3 C[2 * JAC_MAX_DEGREE][2 * JAC_MAX_DEGREE], D[JAC_MAX_DEGREE + 1][JAC_MAX_DEGREE + 1];
    vec3 du[JAC_MAX_DEGREE][JAC_MAX_DEGREE + 1], dv[JAC_MAX_DEGREE + 1][JAC_MAX_DEGREE];
    double maxdu = 0.0, maxdv = 0.0, maxd = 0.0;
    for (int m = 0; m <= M; m++)
        for (int n = 0; n <= N; n++)
            C[m][n] = v3(0, 0, 0);
    for (int i = 0; i <= p; i++)
        for (int j = 0; j <= q; j++) {
            vec3 c = bezier_point(pt, i, j);
            if (i < p)
                du[i][j] = v3_sub(bezier_point(pt, i + 1, j), c), maxdu = dmax(maxdu, v3_len(du[i][j]));
            if (j < q)
                dv[i][j] = v3_sub(bezier_point(pt, i, j + 1), c), maxdv = dmax(maxdv, v3_len(dv[i][j]));
            maxd = dmax(maxd, v3_len(c) + v3_len(cam->eye));
            if (!cam->ortho)
                D[i][j] = v3_sub(c, cam->eye);
        }
    if (cam->ortho)
        D[0][0] = cam->f, maxd = 1.0;
    for (int i = 0; i < p; i++)
        for (int j = 0; j <= q; j++)
            for (int k = 0; k <= p; k++)
                for (int l = 0; l < q; l++)
                    C[i + k][j + l] = v3_add(C[i + k][j + l], v3_scale(v3_cross(du[i][j], dv[k][l]),
                                                                       (double)p * q * wu[i][k] * wv[j][l]));
    for (int k = 0; k < (GP + 1) * (GQ + 1); k++)
        g[k] = 0.0;
    for (int a = 0; a <= M; a++)
        for (int b = 0; b <= N; b++)
            for (int c = 0; c <= dp; c++)
                for (int d = 0; d <= dq; d++)
                    g[(a + c) * (GQ + 1) + b + d] += v3_dot(C[a][b], D[c][d]) * gu_[a][c] * gv_[b][d];
    *gp = GP, *gq = GQ;
    *tol = 1e-10 * (double)p * q * maxdu * maxdv * maxd;
    return true;
}

/* The coefficients c of a scalar polynomial of degree (gp, gq) (c[i * (gq + 1) + j]) split at t
 * along u (dir 0) or v into lo ([0, t]) and hi ([t, 1]), by de Casteljau. */
static void split_scalar(const double *c, int gp, int gq, int dir, double t, double *lo, double *hi)
{
    const int n = dir ? gq : gp, lines = dir ? gp + 1 : gq + 1, stride = dir ? 1 : gq + 1, step = dir ? gq + 1 : 1;
    double w[3 * JAC_MAX_DEGREE];
    for (int l = 0; l < lines; l++) {
        const size_t o = (size_t)l * step;
        for (int k = 0; k <= n; k++)
            w[k] = c[o + (size_t)k * stride];
        for (int r = 0; r <= n; r++) {
            lo[o + (size_t)r * stride] = w[0];
            hi[o + (size_t)(n - r) * stride] = w[n - r];
            for (int k = 0; k < n - r; k++)
                w[k] += t * (w[k + 1] - w[k]);
        }
    }
}

/* edge_on[cell] over the cells [i0, i1) x [j0, j1) of a gu x gv grid, from c, the coefficients of
 * g (jacobian_net) over the block. In: true for the cells whose answer is wanted (a block with
 * none is left as it is). Out: false where every coefficient is beyond tol and all of one sign
 * (a coefficient exactly 0, as along an edge collapsed to a point, counts as either: g >= 0 or
 * <= 0 there too), so g keeps its sign over the block (Bernstein weights are non-negative: g lies
 * within its coefficients' range) and its image folds nowhere. A coefficient within tol of 0 (not
 * 0) leaves the block edge-on: a sign rounding may have flipped. Else the block is split in two
 * along its longer side, down to single cells (de Casteljau from the block's coefficients). */
static void jacobian_cells(const double *c, int gp, int gq, double tol, int gu, int gv, int i0, int i1, int j0,
                           int j1, bool *edge_on)
{
    bool wanted = false, pos = false, neg = false, near = false;
    for (int i = i0; i < i1 && !wanted; i++)
        for (int j = j0; j < j1 && !wanted; j++)
            wanted = edge_on[(size_t)i * gv + j];
    if (!wanted)
        return;
    for (int k = 0; k < (gp + 1) * (gq + 1) && !(pos && neg) && !near; k++)
        pos |= c[k] > tol, neg |= c[k] < -tol, near |= c[k] != 0.0 && fabs(c[k]) <= tol;
    const bool free_ = pos != neg && !near;
    if (free_ || (i1 - i0) * (j1 - j0) <= 1) {
        for (int i = i0; i < i1; i++)
            for (int j = j0; j < j1; j++)
                edge_on[(size_t)i * gv + j] = !free_;
        return;
    }
    double lo[3 * JAC_MAX_DEGREE * 3 * JAC_MAX_DEGREE], hi[3 * JAC_MAX_DEGREE * 3 * JAC_MAX_DEGREE];
    if (i1 - i0 >= j1 - j0) {
        const int mid = (i0 + i1) / 2;
        split_scalar(c, gp, gq, 0, (double)(mid - i0) / (i1 - i0), lo, hi);
        jacobian_cells(lo, gp, gq, tol, gu, gv, i0, mid, j0, j1, edge_on);
        jacobian_cells(hi, gp, gq, tol, gu, gv, mid, i1, j0, j1, edge_on);
    } else {
        const int mid = (j0 + j1) / 2;
        split_scalar(c, gp, gq, 1, (double)(mid - j0) / (j1 - j0), lo, hi);
        jacobian_cells(lo, gp, gq, tol, gu, gv, i0, i1, j0, mid, edge_on);
        jacobian_cells(hi, gp, gq, tol, gu, gv, i0, i1, mid, j1, edge_on);
    }
}

/* Tessellates patch `index` on its grid for the camera into its slots of m->verts and m->tris
 * (map_begin's), its border's edges last, edge by edge (u = 0, u = 1, v = 0, v = 1: m->border).
 * The grid's points by the tensor product: the net's rows taken at each u first, those q + 1
 * points then at each v (16 multiply-adds a vertex on a bicubic; the two sides of a seam take the
 * same operations on the same points there, so their border vertices agree to the bit). */
static void add_patch(struct map *m, const struct patch *pt, int index, const struct camera *cam,
                      struct grid_scratch *sc)
{
    const int gu = m->grid[index][0], gv = m->grid[index][1];
    double err_px = tess_grid_error(pt, gu, gv) / m->pix[index];
    /* on screen a world displacement at depth z spans at most sqrt(1 + x² + y²) / z of its size
     * on the axis (the projection's largest singular value; x, y the tangents of the frame's
     * corner): the outline is widened by the chord error so stretched */
    double stretch = sqrt(1.0 + cam->th * cam->th * (cam->aspect * cam->aspect + 1.0));
    double twice = pt->rational ? 2.0 : 1.0; /* the bound taken twice for rational patches */
    float pad = (float)(twice * err_px * stretch + MAP_PAD_SLACK);
    double chord = 2.0 * tess_grid_error(pt, gu, gv); /* twice the bound: rational patches */
    /* a triangle turns as the surface over it does only where it is thick enough. Along u the
     * surface's derivative times the cell's step leaves the chord of its cell by at most M h² / 2,
     * four times the chord error M h² / 8 of that direction (M the second-difference bound the
     * grid is sized on), on screen dev_u pixels; the same along v. The surface's Jacobian keeps
     * the sign of the triangle's u edge x v edge where that exceeds dev_u |v edge| + dev_v |u edge|
     * + dev_u dev_v; a thinner triangle may hide a fold (a sliver seen edge-on may be pleated
     * within its cells, its triangles all turning one way) and is drawn as turning neither way:
     * its edges are outline, folds inside the grid */
    const double px_err = twice * stretch / m->pix[index];
    const double dev_u = 4.0 * px_err * (pt->wmin > 0.0 ? pt->curv[0] : bezier_net_curvature(pt, 0)) / (8.0 * gu * gu);
    const double dev_v = 4.0 * px_err * (pt->wmin > 0.0 ? pt->curv[1] : bezier_net_curvature(pt, 1)) / (8.0 * gv * gv);
    const size_t base = m->vfirst[index], nc = (size_t)gu * gv;
    size_t nt = m->first[index];
    float *zc = sc->zc;
    signed char *sg = sc->sg;
    bool *keep = sc->keep, *edge_on = sc->edge_on;
    const int p = pt->p, q = pt->q;
    for (int j = 0; j <= gv; j++)
        bezier_basis(q, (double)j / gv, sc->bv + (size_t)j * (q + 1), NULL); /* exactly 0 and 1 at the ends */
    const double sx = 0.5 * cam->W / (cam->th * cam->aspect), sy = 0.5 * cam->H / cam->th;
    for (int i = 0; i <= gu; i++) {
        double bu[PATCH_MAX_DEGREE + 1], row[PATCH_MAX_DEGREE + 1][4] = {{0}};
        const double u = (double)i / gu;
        bezier_basis(p, u, bu, NULL);
        for (int a = 0; a <= p; a++)
            for (int b = 0; b <= q; b++)
                for (int c = 0; c < 4; c++)
                    row[b][c] += bu[a] * pt->cw[a * (q + 1) + b][c];
        for (int j = 0; j <= gv; j++) {
            const double *bv = sc->bv + (size_t)j * (q + 1);
            double S[4] = {0, 0, 0, 0};
            for (int b = 0; b <= q; b++)
                for (int c = 0; c < 4; c++)
                    S[c] += bv[b] * row[b][c];
            vec3 d = v3_sub(v3(S[0] / S[3], S[1] / S[3], S[2] / S[3]), cam->eye);
            double z = dmax(v3_dot(d, cam->f), NEAR_EPS), iz = 1.0 / z;
            struct map_vert *s = &m->verts[base + (size_t)i * (gv + 1) + j];
            s->x = v3_dot(d, cam->r) * iz * sx + 0.5 * cam->W - 0.5;
            s->y = 0.5 * cam->H - v3_dot(d, cam->u) * iz * sy - 0.5;
            s->iz = iz;
            s->uz = u * iz;
            s->vz = (double)j / gv * iz;
        }
    }
    /* cell (i, j) holds triangles {a, b, b+1} and {a, b+1, a+1}, a = vertex (i, j), b = (i+1, j):
     * both wind the same way in (u, v), so on screen they turn the same way unless the surface
     * folds there. sg: each triangle's turn (-1, 0, 1); zc: each cell's nearest vertex depth. A
     * triangle too thin for its turn to be sure is marked +-2 first: only a patch that has one
     * asks where it may be seen edge-on (on the heart model that costs more than its grid), and
     * its thin triangles then turn neither way where it may, their own way where it may not. */
    bool thin_any = false;
#define VTX(i, j) ((unsigned)(base + (size_t)(i) * (gv + 1) + (size_t)(j)))
#define CELL(i, j) ((size_t)(i) * gv + (size_t)(j))
    const double su = (pt->u1 - pt->u0) / gu, sv = (pt->v1 - pt->v0) / gv;
    for (int i = 0; i < gu; i++)
        for (int j = 0; j < gv; j++) {
            unsigned a = VTX(i, j), b = VTX(i + 1, j);
            const unsigned tri[2][3] = {{a, b, b + 1}, {a, b + 1, a + 1}};
            /* a cell the trims cut away whole draws nothing (its roots are no hits), and its edges
             * toward kept cells are their outline; the chord padding covers the loop's path */
            double cu = pt->u0 + i * su, cv = pt->v0 + j * sv;
            keep[CELL(i, j)] = !pt->trim || trim_classify(pt->trim, cu, cu + su, cv, cv + sv) != TRIM_OUT;
            for (int k = 0; k < 2; k++) {
                const struct map_vert *p0 = &m->verts[tri[k][0]], *p1 = &m->verts[tri[k][1]], *p2 = &m->verts[tri[k][2]];
                double area = (p1->x - p0->x) * (p2->y - p0->y) - (p1->y - p0->y) * (p2->x - p0->x);
                /* its u edge (b - a; b+1 - a+1) and v edge (b+1 - b; a+1 - a): too thin, no turn */
                const struct map_vert *ua = &m->verts[k ? a + 1 : a], *ub = &m->verts[k ? b + 1 : b];
                const struct map_vert *va = &m->verts[k ? a : b], *vb = &m->verts[k ? a + 1 : b + 1];
                double thick = dev_u * hypot(vb->x - va->x, vb->y - va->y) + dev_v * hypot(ub->x - ua->x, ub->y - ua->y) +
                               dev_u * dev_v;
                int turn = (area > 0) - (area < 0);
                bool thin = turn && !(area > thick || area < -thick);
                sg[2 * CELL(i, j) + k] = keep[CELL(i, j)] ? (signed char)(thin ? 2 * turn : turn) : 0;
                thin_any |= keep[CELL(i, j)] && thin;
            }
            double iz = dmax(dmax(m->verts[a].iz, m->verts[a + 1].iz), dmax(m->verts[b].iz, m->verts[b + 1].iz));
            zc[CELL(i, j)] = (float)(1.0 / iz);
        }
    if (thin_any) {
        double g[3 * JAC_MAX_DEGREE * 3 * JAC_MAX_DEGREE], gtol;
        int gp, gq;
        for (size_t c = 0; c < nc; c++) /* (the cells asked about: those with a thin triangle) */
            edge_on[c] = sg[2 * c] == 2 || sg[2 * c] == -2 || sg[2 * c + 1] == 2 || sg[2 * c + 1] == -2;
        if (jacobian_net(pt, cam, g, &gp, &gq, &gtol))
            jacobian_cells(g, gp, gq, gtol, gu, gv, 0, gu, 0, gv, edge_on);
        else if (pt->rational) /* no cones: the thinness test everywhere */
            memset(edge_on, 1, sizeof *edge_on * nc);
        else
            edge_on_cells(pt, cam, gu, gv, 0, gu, 0, gv, edge_on);
        for (size_t c = 0; c < 2 * nc; c++)
            if (sg[c] == 2 || sg[c] == -2)
                sg[c] = edge_on[c / 2] ? 0 : (signed char)(sg[c] / 2);
    }
    /* a root seen through one triangle may belong to a neighbouring cell's part of the patch:
     * each cell's bound is the least over its 3x3 neighbourhood, less the chord error */
    float *zlo = zc + nc;
    for (int i = 0; i < gu; i++)
        for (int j = 0; j < gv; j++) {
            float z = INFINITY;
            for (int a = i > 0 ? i - 1 : 0; a <= i + 1 && a < gu; a++)
                for (int b = j > 0 ? j - 1 : 0; b <= j + 1 && b < gv; b++)
                    z = zc[CELL(a, b)] < z ? zc[CELL(a, b)] : z;
            zlo[CELL(i, j)] = keep[CELL(i, j)] ? (float)(z - chord) : INFINITY; /* a dropped cell: no bound */
        }
    for (int i = 0; i < gu; i++)
        for (int j = 0; j < gv; j++) {
            unsigned a = VTX(i, j), b = VTX(i + 1, j);
            const unsigned tri[2][3] = {{a, b, b + 1}, {a, b + 1, a + 1}};
            for (int k = 0; k < 2 && keep[CELL(i, j)]; k++)
                m->tris[nt++] = (struct map_tri){{tri[k][0], tri[k][1], tri[k][2]}, index, 0.0f, zlo[CELL(i, j)], false, 0, {0}};
        }
    /* the outline: the grid's border, and every edge whose two triangles turn different ways
     * (or either none) on screen; s0, s1 are the turns on either side (0 where there is none) */
#define OUTLINE(v0, v1, s0, s1, z, inside)                                                         \
    if (((s0) == 0 || (s0) != (s1)) && (z) < INFINITY)                                          \
        m->tris[nt++] = (struct map_tri){{(v0), (v1), EDGE}, index, pad, (z), (inside), 0, {0}};
    for (int i = 0; i < gu; i++)
        for (int j = 0; j < gv; j++) /* the diagonal a-(b+1) between a cell's two triangles */
            OUTLINE(VTX(i, j), VTX(i + 1, j + 1), sg[2 * CELL(i, j)], sg[2 * CELL(i, j) + 1], zlo[CELL(i, j)], true);
    for (int i = 0; i < gu; i++)
        for (int j = 1; j < gv; j++) { /* (i, j)-(i+1, j): first triangle of cell (i, j), second of (i, j-1) */
            int s0 = sg[2 * CELL(i, j)], s1 = sg[2 * CELL(i, j - 1) + 1];
            OUTLINE(VTX(i, j), VTX(i + 1, j), s0, s1, fminf(zlo[CELL(i, j)], zlo[CELL(i, j - 1)]), true);
        }
    for (int i = 1; i < gu; i++)
        for (int j = 0; j < gv; j++) { /* (i, j)-(i, j+1): second triangle of cell (i, j), first of (i-1, j) */
            int s0 = sg[2 * CELL(i, j) + 1], s1 = sg[2 * CELL(i - 1, j)];
            OUTLINE(VTX(i, j), VTX(i, j + 1), s0, s1, fminf(zlo[CELL(i, j)], zlo[CELL(i - 1, j)]), true);
        }
    /* the border, edge by edge along its parameter; each segment with the turn of the triangle
     * inside it (a kept cell's: a trimmed patch's border has gaps, and no seams). An edge along a
     * seam is kept as segments (border_segs): step 1 draws what of it is outline. */
    m->pad[index] = pad;
    for (size_t t = m->first[index]; t < nt; t++) /* (border_edges boxes its own) */
        tri_box(m, &m->tris[t]);
    for (int e = 0; e < 4; e++) {
        const int n_seg = e < 2 ? gv : gu, i = e == 1 ? gu - 1 : 0, j = e == 3 ? gv - 1 : 0;
        struct border_seg *seg = m->segs + m->sfirst[index] + (e == 0 ? 0 : e == 1 ? gv : e == 2 ? 2 * gv : 2 * gv + gu);
        bool whole = !pt->trim && m->seams && bvh_seam(m->seams, index, e) >= 0;
        for (int k = 0; k < n_seg; k++) {
            size_t c = e < 2 ? CELL(i, k) : CELL(k, j);
            seg[k] = (struct border_seg){zlo[c], sg[2 * c + (e == 0 || e == 3)]}; /* u = 0, v = 1: a cell's second */
            whole &= zlo[c] < INFINITY; /* a segment left out: the edge's run is not whole */
        }
        m->border[index][e] = whole ? (size_t)(seg - m->segs) : SIZE_MAX;
        if (!whole)
            nt = border_edges(m, index, e, seg, NULL, nt);
    }
#undef OUTLINE
#undef CELL
#undef VTX
    m->end[index] = nt;
}

/* Sorts the n (depth bound, primitive) keys by the bound: a radix sort whose passes read and
 * write in order (sorting indices by a key looked up through them missed the cache at every step:
 * 4x slower on the heart's 208 k triangles). b: n keys of scratch. Returns the sorted array (a or b). */
static uint64_t *depth_sort(uint64_t *a, uint64_t *b, size_t n)
{
    for (int shift = 32; shift < 64; shift += 8) {
        size_t count[257] = {0};
        for (size_t k = 0; k < n; k++)
            count[((a[k] >> shift) & 0xff) + 1]++;
        for (int d = 0; d < 256; d++)
            count[d + 1] += count[d];
        for (size_t k = 0; k < n; k++)
            b[count[(a[k] >> shift) & 0xff]++] = a[k];
        uint64_t *t = a;
        a = b, b = t;
    }
    return a;
}

/* Union-find root of k, halving the path. */
static size_t find_root(size_t *up, size_t k)
{
    while (up[k] != k)
        k = up[k] = up[up[k]];
    return k;
}

/* The patches' grids (grid[k][0] == 0: left out) made the same along seams: a seam's two sides are
 * sampled at the same parameters (the largest count of the patches the seams chain together
 * along it: u seams chain the v counts, v seams the u counts; no more than MAP_SEAM_GROW times a
 * patch's own), so their border vertices meet. */
static int seam_grids(const struct patch *patches, size_t n, const struct bvh *seams, int (*grid)[2])
{
    size_t *up = malloc(sizeof *up * 2 * (n ? n : 1)); /* [0, n): by u seams; [n, 2n): by v seams */
    if (!up)
        return SF_ENOMEM;
    for (size_t k = 0; k < 2 * n; k++)
        up[k] = k;
    for (size_t k = 0; k < n; k++)
        for (int e = 1; e < 4; e += 2) {
            int o = bvh_seam(seams, (int)k, e);
            if (o < 0 || !grid[k][0] || !grid[o][0] || patches[k].trim || patches[o].trim)
                continue;
            size_t base = e == 1 ? 0 : n, a = find_root(up, base + k), b = find_root(up, base + (size_t)o);
            up[a] = b;
        }
    int *most = calloc(2 * (n ? n : 1), sizeof *most); /* per root: the largest count */
    if (!most) {
        free(up);
        return SF_ENOMEM;
    }
    for (size_t k = 0; k < n; k++) {
        size_t a = find_root(up, k), b = find_root(up, n + k);
        most[a] = most[a] > grid[k][1] ? most[a] : grid[k][1];
        most[b] = most[b] > grid[k][0] ? most[b] : grid[k][0];
    }
    for (size_t k = 0; k < n; k++) /* (a seam whose sides still differ stays an outline: join_seams) */
        if (grid[k][0]) {
            int gv = most[find_root(up, k)], gu = most[find_root(up, n + k)];
            grid[k][1] = gv <= MAP_SEAM_GROW * grid[k][1] ? gv : grid[k][1];
            grid[k][0] = gu <= MAP_SEAM_GROW * grid[k][0] ? gu : grid[k][0];
        }
    free(most);
    free(up);
    return 0;
}

/* Appends at tris[nt] the outline edges of edge e of patch k, its segments seg: each kept one
 * (zlo finite), or where other (the neighbour's across a seam) is given, those where the triangles
 * either side turn different ways (a fold). Returns the new nt. */
static size_t border_edges(struct map *m, size_t k, int e, const struct border_seg *seg,
                           const struct border_seg *other, size_t nt)
{
    const int gu = m->grid[k][0], gv = m->grid[k][1], n_seg = e < 2 ? gv : gu;
    const int i = e == 0 ? 0 : gu, j = e == 2 ? 0 : gv; /* the edge's fixed grid line */
    const unsigned base = (unsigned)m->vfirst[k];
    for (int s = 0; s < n_seg; s++) {
        if (!(seg[s].zlo < INFINITY) || (other && seg[s].turn != 0 && seg[s].turn == other[s].turn))
            continue;
        unsigned v0 = base + (unsigned)(e < 2 ? i * (gv + 1) + s : s * (gv + 1) + j);
        unsigned v1 = v0 + (e < 2 ? 1u : (unsigned)(gv + 1));
        m->tris[nt] = (struct map_tri){{v0, v1, EDGE}, (int)k, m->pad[k], seg[s].zlo, other != NULL, seg[s].turn, {0}};
        tri_box(m, &m->tris[nt++]);
    }
    return nt;
}

/* Patch k's edges along seams against its neighbours' (every patch tessellated), segment by
 * segment: where the triangles either side turn alike on screen the two patches go on as one
 * surface there, and k draws no outline (its candidates may then be the neighbour's roots:
 * seamed); where they do not, the surface folds there, and the segment is outline inside the
 * pair's grid (fold). Each side decides its own edges alike. */
static void join_seams(struct map *m, size_t k)
{
    for (int e = 0; e < 4; e++) {
        if (m->border[k][e] == SIZE_MAX)
            continue;
        const struct border_seg *seg = m->segs + m->border[k][e], *other = NULL;
        int o = bvh_seam(m->seams, (int)k, e);
        if (o >= 0 && m->border[o][e ^ 1] != SIZE_MAX && m->grid[k][e < 2] == m->grid[o][e < 2])
            other = m->segs + m->border[o][e ^ 1]; /* (counts MAP_SEAM_GROW kept apart: all outline) */
        for (int s = 0; other && s < m->grid[k][e < 2]; s++)
            m->seamed[k] |= seg[s].turn != 0 && seg[s].turn == other[s].turn;
        m->end[k] = border_edges(m, k, e, seg, other, m->end[k]);
    }
}

/* The bound's bits flipped so that unsigned order is float order, above primitive t's index. */
static uint64_t depth_key(const struct map_tri *tri, size_t t)
{
    uint32_t bits;
    memcpy(&bits, &tri->zlo, sizeof bits);
    return (uint64_t)(bits & 0x80000000u ? ~bits : bits | 0x80000000u) << 32 | t;
}

/* The row tiles [*y0, *y1] primitive t's box touches; false when it is off the picture. */
static bool tiles_of(const struct map_tri *t, int *y0, int *y1)
{
    *y0 = t->box[2] / MAP_TILE_ROWS, *y1 = t->box[3] / MAP_TILE_ROWS;
    return t->box[0] <= t->box[1] && t->box[2] <= t->box[3];
}

/* Step 1 of part p: its patches' seams joined, and its primitives on the picture (a seam's edges
 * that are no outline left out) as depth keys grouped by the row tiles they touch, with how many
 * each tile has (a primitive over several tiles is in each). */
static int part_keys(struct map *m, int p)
{
    const size_t k0 = m->part_first[p], k1 = m->part_first[p + 1];
    unsigned *hist = m->part_hist + (size_t)p * m->n_tiles;
    for (size_t k = k0; k < k1; k++) {
        if (m->grid[k][0])
            join_seams(m, k);
        for (size_t t = m->first[k]; t < m->end[k]; t++)
            for (int y, y1, on = tiles_of(&m->tris[t], &y, &y1); on && y <= y1; y++)
                hist[y]++;
    }
    size_t n = 0, *at = malloc(sizeof *at * (size_t)m->n_tiles);
    for (int y = 0; at && y < m->n_tiles; y++)
        at[y] = n, n += hist[y];
    uint64_t *keys = malloc(sizeof *keys * (n ? n : 1));
    if (!at || !keys) {
        free(at), free(keys);
        return SF_ENOMEM;
    }
    for (size_t k = k0; k < k1; k++)
        for (size_t t = m->first[k]; t < m->end[k]; t++)
            for (int y, y1, on = tiles_of(&m->tris[t], &y, &y1); on && y <= y1; y++)
                keys[at[y]++] = depth_key(&m->tris[t], t);
    free(at);
    m->part_keys[p] = keys;
    return 0;
}

/* Step 2 of part p: its share of the row tiles, each tile's primitives from every part sorted by
 * depth key into the tile's list. */
static int tile_lists(struct map *m, int p)
{
    for (int q = 0; q < m->n_parts; q++)
        if (!m->part_keys[q]) /* its step 1 found no memory (set before this step began) */
            return SF_ENOMEM;
    const int y0 = (int)((long)m->n_tiles * p / m->n_parts), y1 = (int)((long)m->n_tiles * (p + 1) / m->n_parts);
    size_t most = 0;
    for (int y = y0; y < y1; y++) {
        size_t n = 0;
        for (int q = 0; q < m->n_parts; q++)
            n += m->part_hist[(size_t)q * m->n_tiles + y];
        most = n > most ? n : most;
    }
    uint64_t *a = malloc(sizeof *a * (most ? most : 1)), *b = malloc(sizeof *b * (most ? most : 1));
    size_t *from = calloc((size_t)m->n_parts, sizeof *from); /* where each part's keys of tile y start */
    int rc = a && b && from ? 0 : SF_ENOMEM;
    for (int q = 0; q < m->n_parts && !rc; q++) /* (a part's keys of a tile follow those of the tiles above) */
        for (int z = 0; z < y0; z++)
            from[q] += m->part_hist[(size_t)q * m->n_tiles + z];
    for (int y = y0; y < y1 && !rc; y++) {
        size_t n = 0;
        for (int q = 0; q < m->n_parts; q++) {
            unsigned h = m->part_hist[(size_t)q * m->n_tiles + y];
            memcpy(a + n, m->part_keys[q] + from[q], sizeof *a * h);
            n += h, from[q] += h;
        }
        const uint64_t *order = depth_sort(a, b, n);
        if (!(m->tile_list[y] = malloc(sizeof *m->tile_list[y] * (n ? n : 1)))) {
            rc = SF_ENOMEM;
            break;
        }
        for (size_t k = 0; k < n; k++)
            m->tile_list[y][k] = (unsigned)(order[k] & 0xffffffffu);
        m->tile_n[y] = (unsigned)n;
    }
    free(a), free(b), free(from);
    return rc;
}

/* Parts of the tessellation, at most: whole patches of about equal work, MAP_PART_SLOTS primitive
 * slots each at least (a small map is one part: a step of parts costs its threads a hand-over) */
#define MAP_PARTS 32
#define MAP_PART_SLOTS 16384

int map_begin(const struct patch *patches, size_t n, const struct bvh *seams, const struct camera *cam,
              struct map **out, struct sf_err *err)
{
    *out = NULL;
    struct map *m = calloc(1, sizeof *m);
    int n_tiles = (cam->H + MAP_TILE_ROWS - 1) / MAP_TILE_ROWS;
    const size_t n1 = n ? n : 1;
    if (!m)
        goto out_nomem;
    m->W = cam->W;
    m->H = cam->H;
    m->complete = true;
    m->cam = *cam;
    m->patches = patches;
    m->grid = malloc(sizeof *m->grid * n1);
    m->pix = malloc(sizeof *m->pix * n1);
    m->border = malloc(sizeof *m->border * n1);
    m->sfirst = malloc(sizeof *m->sfirst * n1);
    m->pad = malloc(sizeof *m->pad * n1);
    m->seamed = calloc(n1, 1);
    m->vfirst = malloc(sizeof *m->vfirst * n1);
    m->first = malloc(sizeof *m->first * n1);
    m->end = calloc(n1, sizeof *m->end);
    m->seams = seams;
    m->part_first = calloc(MAP_PARTS + 1, sizeof *m->part_first);
    m->part_failed = calloc(MAP_PARTS, 1);
    m->part_keys = calloc(MAP_PARTS, sizeof *m->part_keys);
    m->part_hist = calloc((size_t)MAP_PARTS * n_tiles, sizeof *m->part_hist);
    m->n_tiles = n_tiles;
    m->tile_list = calloc((size_t)n_tiles, sizeof *m->tile_list);
    m->tile_n = calloc((size_t)n_tiles, sizeof *m->tile_n);
    if (!m->tile_list || !m->tile_n || !m->part_failed || !m->part_keys || !m->part_hist || !m->grid || !m->pix ||
        !m->border || !m->sfirst || !m->pad || !m->seamed || !m->vfirst || !m->first || !m->end || !m->part_first)
        goto out_nomem;
    for (size_t k = 0; k < n; k++) {
        if (!patch_grid(m, &patches[k], cam, &m->grid[k][0], &m->grid[k][1], &m->pix[k]))
            m->grid[k][0] = m->grid[k][1] = 0;
        for (int e = 0; e < 4; e++)
            m->border[k][e] = SIZE_MAX;
    }
    if (seams && seam_grids(patches, n, seams, m->grid))
        goto out_nomem;
    /* each patch's slots: its vertices, and room for every triangle and, at worst, every edge of
     * its grid (what is not used stays untouched) */
    size_t nv = 0, nt = 0, ns = 0;
    for (size_t k = 0; k < n; k++) {
        size_t gu = (size_t)m->grid[k][0], gv = (size_t)m->grid[k][1], nc = gu * gv;
        m->vfirst[k] = nv, m->first[k] = m->end[k] = nt, m->sfirst[k] = ns;
        if (gu) {
            nv += (gu + 1) * (gv + 1);
            nt += 3 * nc + gu * (gv + 1) + gv * (gu + 1);
            ns += 2 * (gu + gv);
        }
    }
    if (!(m->segs = malloc(sizeof *m->segs * (ns ? ns : 1))))
        goto out_nomem;
    if (nv >= UINT_MAX || nt >= UINT_MAX || !(m->verts = malloc(sizeof *m->verts * (nv ? nv : 1))) ||
        !(m->tris = malloc(sizeof *m->tris * (nt ? nt : 1))))
        goto out_nomem;
    m->n_tris = nt;
    /* parts of about nt / parts slots each */
    const size_t parts = nt / MAP_PART_SLOTS < 1 ? 1 : nt / MAP_PART_SLOTS > MAP_PARTS ? MAP_PARTS : nt / MAP_PART_SLOTS;
    size_t k = 0;
    for (size_t p = 0; p < parts && k < n; p++) {
        m->part_first[p] = k;
        size_t goal = (size_t)((double)nt * (p + 1) / parts);
        while (k < n && (m->first[k] < goal || p == parts - 1))
            k++;
        m->n_parts = (int)p + 1;
    }
    m->part_first[m->n_parts] = n;
    *out = m;
    return 0;

out_nomem:
    map_free(m);
    return sf_fail(err, SF_ENOMEM, "", "out of memory for the preliminary-value map");
}

int map_parts(const struct map *m) { return m->n_parts; }

int map_part(struct map *m, int step, int part)
{
    size_t k0 = m->part_first[part], k1 = m->part_first[part + 1], most_c = 0, most_v = 0;
    if (step > 0) {
        int rc = step == 1 ? part_keys(m, part) : tile_lists(m, part);
        m->part_failed[part] |= rc != 0;
        return rc;
    }
    for (size_t k = k0; k < k1; k++) {
        size_t nc = (size_t)m->grid[k][0] * m->grid[k][1], nv = (size_t)(m->grid[k][1] + 1) * (m->patches[k].q + 1);
        most_c = nc > most_c ? nc : most_c;
        most_v = nv > most_v ? nv : most_v;
    }
    struct grid_scratch sc = {malloc(2 * sizeof *sc.zc * (most_c + 1)), malloc(2 * most_c + 2),
                              malloc(sizeof *sc.keep * (most_c + 1)), malloc(sizeof *sc.bv * (most_v + 1)),
                              malloc(sizeof *sc.edge_on * (most_c + 1))};
    int rc = sc.zc && sc.sg && sc.keep && sc.bv && sc.edge_on ? 0 : SF_ENOMEM;
    for (size_t k = k0; k < k1 && !rc; k++)
        if (m->grid[k][0])
            add_patch(m, &m->patches[k], (int)k, &m->cam, &sc);
    free(sc.zc), free(sc.sg), free(sc.keep), free(sc.bv), free(sc.edge_on);
    m->part_failed[part] |= rc != 0;
    return rc;
}

int map_end(struct map *m, struct sf_err *err)
{
    for (int p = 0; p < m->n_parts; p++)
        if (m->part_failed[p])
            return sf_fail(err, SF_ENOMEM, "", "out of memory for the preliminary-value map");
    for (int p = 0; p < m->n_parts; p++) { /* in the tiles' lists now */
        free(m->part_keys[p]);
        m->part_keys[p] = NULL;
    }
    return 0;
}

int map_build(const struct patch *patches, size_t n, const struct bvh *seams, const struct camera *cam,
              struct map **out, struct sf_err *err)
{
    int rc = map_begin(patches, n, seams, cam, out, err);
    for (int step = 0; !rc && step < MAP_STEPS; step++)
        for (int p = 0; p < (*out)->n_parts; p++)
            map_part(*out, step, p);
    if (!rc)
        rc = map_end(*out, err);
    if (rc) {
        map_free(*out);
        *out = NULL;
    }
    return rc;
}
