/* map.c - conservative raster of a screen-adaptive tessellation into the preliminary-value map.
 *
 * Each patch is tessellated so that its chord error, seen from its nearest point, stays under
 * half a pixel. Its triangles mark the pixel centres they cover (no padding: the triangles of a
 * patch tile its image, so only the outline of that image can be off the true one); the
 * outline - the grid's border and every fold, where two neighbouring triangles face opposite
 * ways on screen - is then widened by the chord error as the projection may stretch it
 * (capsules around those edges), so the true silhouette always has a seed. Seeds take the
 * perspective-correct attributes of the covering triangle, or of the nearest point of the
 * outline edge; a candidate near its patch's outline remembers the depth of the outline and of
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
    bool gone;            /* a seam's border edge where both sides turn alike: no outline */
};

#define EDGE UINT_MAX
#define COVER_EPS 1e-7  /* pixels: a centre this near a triangle's edge counts as inside it */
#define SPAN_SLACK 1e-6 /* pixels: a row's span ends, widened past their rounding */

void map_free(struct map *m)
{
    if (!m)
        return;
    free(m->verts);
    free(m->tris);
    free(m->grid);
    free(m->border);
    free(m->seamed);
    free(m->tile_first);
    free(m->tile_tris);
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

static void tri_bbox(const struct map *m, const struct map_tri *t, int *x0, int *x1, int *y0, int *y1)
{
    const struct map_vert *a = &m->verts[t->v[0]], *b = &m->verts[t->v[1]];
    const struct map_vert *c = t->v[2] == EDGE ? b : &m->verts[t->v[2]];
    *x0 = (int)floor(dmin(a->x, dmin(b->x, c->x)) - t->pad);
    *x1 = (int)ceil(dmax(a->x, dmax(b->x, c->x)) + t->pad);
    *y0 = (int)floor(dmin(a->y, dmin(b->y, c->y)) - t->pad);
    *y1 = (int)ceil(dmax(a->y, dmax(b->y, c->y)) + t->pad);
    *x0 = *x0 < 0 ? 0 : *x0;
    *y0 = *y0 < 0 ? 0 : *y0;
    *x1 = *x1 > m->W - 1 ? m->W - 1 : *x1;
    *y1 = *y1 > m->H - 1 ? m->H - 1 : *y1;
}

/* Marks every pixel centre of rows [y0, y1] within t->pad of the edge t->v[0]-t->v[1]. */
static void raster_edge(const struct map *m, struct map_rows *rw, const struct map_tri *t, int x0, int x1, int y0,
                        int y1)
{
    const struct map_vert *v[2] = {&m->verts[t->v[0]], &m->verts[t->v[1]]};
    double dx = v[1]->x - v[0]->x, dy = v[1]->y - v[0]->y, l2 = dx * dx + dy * dy;
    double pad2 = (double)t->pad * t->pad;
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++) {
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
        for (unsigned k = m->tile_first[tile]; k < m->tile_first[tile + 1]; k++) {
            const struct map_tri *t = &m->tris[m->tile_tris[k]];
            int x0, x1, ya, yb;
            tri_bbox(m, t, &x0, &x1, &ya, &yb);
            ya = ya < lo ? lo : ya;
            yb = yb > hi - 1 ? hi - 1 : yb;
            (t->v[2] == EDGE ? raster_edge : raster_tri)(m, rw, t, x0, x1, ya, yb);
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

/* Tessellates patch pt on a gu x gv grid for the camera and appends its screen vertices and
 * triangles, its border's edges last, edge by edge (u = 0, u = 1, v = 0, v = 1: m->border). */
static int add_patch(struct map *m, const struct patch *pt, int index, const struct camera *cam, int gu, int gv,
                     double pix, size_t *cap_v, size_t *cap_t)
{
    double err_px = tess_grid_error(pt, gu, gv) / pix;
    /* on screen a world displacement at depth z spans at most sqrt(1 + x² + y²) / z of its size
     * on the axis (the projection's largest singular value; x, y the tangents of the frame's
     * corner): the outline is widened by the chord error so stretched */
    double stretch = sqrt(1.0 + cam->th * cam->th * (cam->aspect * cam->aspect + 1.0));
    double twice = pt->rational ? 2.0 : 1.0; /* the bound taken twice for rational patches */
    float pad = (float)(twice * err_px * stretch + MAP_PAD_SLACK);
    double chord = 2.0 * tess_grid_error(pt, gu, gv); /* twice the bound: rational patches */
    /* room for every triangle and, at worst, every edge of the grid */
    size_t base = m->n_verts, nv = (size_t)(gu + 1) * (gv + 1), nc = (size_t)gu * gv;
    size_t n_prims = 2 * nc + (size_t)gu * (gv + 1) + (size_t)gv * (gu + 1) + nc;
    float *zc = malloc(2 * nc * sizeof *zc);
    signed char *sg = malloc(2 * nc);
    bool *keep = malloc(nc * sizeof *keep); /* the cells the trim region holds some of */
    if (!zc || !sg || !keep || mem_reserve((void **)&m->verts, cap_v, base + nv, sizeof *m->verts) ||
        mem_reserve((void **)&m->tris, cap_t, m->n_tris + n_prims, sizeof *m->tris)) {
        free(zc);
        free(sg);
        free(keep);
        return SF_ENOMEM;
    }
    for (int i = 0; i <= gu; i++)
        for (int j = 0; j <= gv; j++) {
            double u = (double)i / gu, v = (double)j / gv;
            vec3 P;
            bezier_eval(pt, u, v, &P, NULL, NULL);
            vec3 d = v3_sub(P, cam->eye);
            double z = fmax(v3_dot(d, cam->f), NEAR_EPS);
            struct map_vert *s = &m->verts[base + (size_t)i * (gv + 1) + j];
            s->x = (v3_dot(d, cam->r) / (z * cam->th * cam->aspect) + 1.0) * 0.5 * cam->W - 0.5;
            s->y = (1.0 - v3_dot(d, cam->u) / (z * cam->th)) * 0.5 * cam->H - 0.5;
            s->iz = 1.0 / z;
            s->uz = u / z;
            s->vz = v / z;
        }
    m->n_verts += nv;
    /* cell (i, j) holds triangles {a, b, b+1} and {a, b+1, a+1}, a = vertex (i, j), b = (i+1, j):
     * both wind the same way in (u, v), so on screen they turn the same way unless the surface
     * folds there. sg: each triangle's turn (-1, 0, 1); zc: each cell's nearest vertex depth. */
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
                const struct map_vert *p = &m->verts[tri[k][0]], *q = &m->verts[tri[k][1]], *r = &m->verts[tri[k][2]];
                double area = (q->x - p->x) * (r->y - p->y) - (q->y - p->y) * (r->x - p->x);
                sg[2 * CELL(i, j) + k] = keep[CELL(i, j)] ? (signed char)((area > 0) - (area < 0)) : 0;
            }
            double iz = fmax(fmax(m->verts[a].iz, m->verts[a + 1].iz), fmax(m->verts[b].iz, m->verts[b + 1].iz));
            zc[CELL(i, j)] = (float)(1.0 / iz);
        }
    /* a root seen through one triangle may belong to a neighbouring cell's part of the patch:
     * each cell's bound is the least over its 3x3 neighbourhood, less the chord error */
    float *zlo = zc + nc;
    for (int i = 0; i < gu; i++)
        for (int j = 0; j < gv; j++) {
            double z = INFINITY;
            for (int a = i > 0 ? i - 1 : 0; a <= i + 1 && a < gu; a++)
                for (int b = j > 0 ? j - 1 : 0; b <= j + 1 && b < gv; b++)
                    z = fmin(z, zc[CELL(a, b)]);
            zlo[CELL(i, j)] = keep[CELL(i, j)] ? (float)(z - chord) : INFINITY; /* a dropped cell: no bound */
        }
    for (int i = 0; i < gu; i++)
        for (int j = 0; j < gv; j++) {
            unsigned a = VTX(i, j), b = VTX(i + 1, j);
            const unsigned tri[2][3] = {{a, b, b + 1}, {a, b + 1, a + 1}};
            for (int k = 0; k < 2 && keep[CELL(i, j)]; k++)
                m->tris[m->n_tris++] =
                    (struct map_tri){{tri[k][0], tri[k][1], tri[k][2]}, index, 0.0f, zlo[CELL(i, j)], false, 0, false};
        }
    /* the outline: the grid's border, and every edge whose two triangles turn different ways
     * (or either none) on screen; s0, s1 are the turns on either side (0 where there is none) */
#define OUTLINE(v0, v1, s0, s1, z, inside)                                                         \
    if (((s0) == 0 || (s0) != (s1)) && (z) < INFINITY)                                          \
        m->tris[m->n_tris++] = (struct map_tri){{(v0), (v1), EDGE}, index, pad, (z), (inside), 0, false};
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
     * inside it (a kept cell's: a trimmed patch's border has gaps, and no seams) */
    for (int e = 0; e < 4; e++) {
        const int n_seg = e < 2 ? gv : gu, i = e == 1 ? gu - 1 : 0, j = e == 3 ? gv - 1 : 0;
        m->border[index][e] = pt->trim ? SIZE_MAX : m->n_tris;
        for (int k = 0; k < n_seg; k++) {
            size_t c = e < 2 ? CELL(i, k) : CELL(k, j);
            int turn = sg[2 * c + (e == 0 || e == 3)]; /* u = 0 and v = 1 edges: the cell's second triangle */
            unsigned v0 = e < 2 ? VTX(i + (e == 1), k) : VTX(k, j + (e == 3));
            unsigned v1 = e < 2 ? VTX(i + (e == 1), k + 1) : VTX(k + 1, j + (e == 3));
            if (zlo[c] < INFINITY)
                m->tris[m->n_tris++] = (struct map_tri){{v0, v1, EDGE}, index, pad, zlo[c], false, (signed char)turn, false};
            else
                m->border[index][e] = SIZE_MAX; /* a segment left out: the edge's run is not whole */
        }
    }
#undef OUTLINE
#undef CELL
#undef VTX
    free(zc);
    free(sg);
    free(keep);
    return 0;
}

/* The triangles' indices by increasing depth bound: a radix sort of (bound, index) pairs, the
 * bound's bits flipped so that unsigned order is float order, each pass reading and writing in
 * order (sorting the indices by a key looked up through them missed the cache at every step:
 * 4x slower on the heart's 208 k triangles). NULL when out of memory. */
static unsigned *depth_order(const struct map *m)
{
    const size_t n = m->n_tris;
    uint64_t *a = malloc(sizeof *a * (n ? n : 1)), *b = malloc(sizeof *b * (n ? n : 1));
    unsigned *out = malloc(sizeof *out * (n ? n : 1));
    if (!a || !b || !out) {
        free(a), free(b), free(out);
        return NULL;
    }
    for (size_t k = 0; k < n; k++) {
        uint32_t bits;
        memcpy(&bits, &m->tris[k].zlo, sizeof bits);
        a[k] = (uint64_t)(bits & 0x80000000u ? ~bits : bits | 0x80000000u) << 32 | k;
    }
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
    for (size_t k = 0; k < n; k++)
        out[k] = (unsigned)(a[k] & 0xffffffffu);
    free(a), free(b);
    return out;
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

/* Each seam's border edges, segment by segment: where the triangles either side turn alike on
 * screen the two patches go on as one surface there, and the edges are no outline (gone); where
 * they do not, the surface folds there, and both are outline inside the pair's grid (fold). */
static void join_seams(struct map *m, size_t n, const struct bvh *seams)
{
    for (size_t k = 0; k < n; k++)
        for (int e = 1; e < 4; e += 2) {
            int o = bvh_seam(seams, (int)k, e);
            if (o < 0 || m->border[k][e] == SIZE_MAX || m->border[o][e - 1] == SIZE_MAX)
                continue;
            const int n_seg = m->grid[k][e < 2];
            if (n_seg != m->grid[o][e < 2])
                continue; /* counts MAP_SEAM_GROW kept apart: the seam stays an outline */
            struct map_tri *a = &m->tris[m->border[k][e]], *b = &m->tris[m->border[o][e - 1]];
            for (int s = 0; s < n_seg; s++) {
                bool alike = a[s].turn != 0 && a[s].turn == b[s].turn;
                a[s].gone = b[s].gone = alike;
                a[s].fold = b[s].fold = !alike;
                m->seamed[k] |= alike;
                m->seamed[o] |= alike;
            }
        }
}

int map_build(const struct patch *patches, size_t n, const struct bvh *seams, const struct camera *cam,
              struct map **out, struct sf_err *err)
{
    *out = NULL;
    struct map *m = calloc(1, sizeof *m);
    size_t cap_v = 0, cap_t = 0;
    int n_tiles = (cam->H + MAP_TILE_ROWS - 1) / MAP_TILE_ROWS;
    if (!m || !(m->tile_first = calloc((size_t)n_tiles + 2, sizeof(unsigned))))
        goto out_nomem;
    m->W = cam->W;
    m->H = cam->H;
    m->complete = true;
    int(*grid)[2] = m->grid = malloc(sizeof *grid * (n ? n : 1));
    double *pix = malloc(sizeof *pix * (n ? n : 1));
    m->border = malloc(sizeof *m->border * (n ? n : 1));
    m->seamed = calloc(n ? n : 1, 1);
    if (!grid || !pix || !m->border || !m->seamed) {
        free(pix);
        goto out_nomem;
    }
    for (size_t k = 0; k < n; k++)
        if (!patch_grid(m, &patches[k], cam, &grid[k][0], &grid[k][1], &pix[k]))
            grid[k][0] = 0;
    if (seams && seam_grids(patches, n, seams, grid)) {
        free(pix);
        goto out_nomem;
    }
    for (size_t k = 0; k < n; k++) {
        for (int e = 0; e < 4; e++)
            m->border[k][e] = SIZE_MAX;
        if (grid[k][0] &&
            add_patch(m, &patches[k], (int)k, cam, grid[k][0], grid[k][1], pix[k], &cap_v, &cap_t)) {
            free(pix);
            goto out_nomem;
        }
    }
    free(pix);
    if (seams)
        join_seams(m, n, seams);
    /* bucket the triangles, nearest depth bound first, by the row tiles their padded boxes touch
     * (counting sorts) */
    unsigned *order = depth_order(m);
    if (!order)
        goto out_nomem;
    /* each triangle's tiles, once and in storage order (the passes below read them in depth order) */
    int (*tiles)[2] = malloc(sizeof *tiles * (m->n_tris ? m->n_tris : 1));
    if (!tiles) {
        free(order);
        goto out_nomem;
    }
    for (size_t k = 0; k < m->n_tris; k++) {
        int x0, x1, y0, y1;
        tri_bbox(m, &m->tris[k], &x0, &x1, &y0, &y1);
        if (m->tris[k].gone)
            x0 = 1, x1 = 0;
        tiles[k][0] = x0 > x1 || y0 > y1 ? 1 : y0 / MAP_TILE_ROWS; /* (off the picture: none) */
        tiles[k][1] = x0 > x1 || y0 > y1 ? 0 : y1 / MAP_TILE_ROWS;
    }
    size_t n_refs = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (size_t o = 0; o < m->n_tris; o++) {
            size_t k = order[o];
            for (int t = tiles[k][0]; t <= tiles[k][1]; t++) {
                if (pass == 0)
                    m->tile_first[t + 2]++;
                else
                    m->tile_tris[m->tile_first[t + 1]++] = (unsigned)k;
            }
        }
        if (pass == 0) {
            for (int t = 0; t < n_tiles; t++)
                m->tile_first[t + 2] += m->tile_first[t + 1];
            n_refs = m->tile_first[n_tiles + 1];
            if (!(m->tile_tris = malloc(sizeof *m->tile_tris * (n_refs ? n_refs : 1)))) {
                free(order), free(tiles);
                goto out_nomem;
            }
        }
    }
    free(order), free(tiles);
    *out = m;
    return 0;

out_nomem:
    map_free(m);
    return sf_fail(err, SF_ENOMEM, "", "out of memory for the preliminary-value map");
}
