/* map.c - conservative raster of a screen-adaptive tessellation into the preliminary-value map.
 *
 * Each patch is tessellated so that its chord error, seen from its nearest point, stays under
 * half a pixel; each triangle then marks every pixel whose centre lies within PAD pixels of it
 * (so that the true silhouette, at most half a pixel away, always has a seed). Seeds outside
 * the triangle take its nearest point's attributes (clamped barycentrics, perspective-correct). */
#include "map.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mem.h"
#include "tess.h"

#define MAP_ERR_PX 0.5   /* chord error allowed, in pixels at the patch's nearest depth */
#define MAP_PAD_PX 1.0   /* conservative dilation of every triangle, in pixels */
#define MAP_MAX_SIDE 96  /* grid cap per patch side; the pad grows where the cap binds */
#define NEAR_EPS 1e-9    /* relative depth below which a vertex counts as behind the eye */

struct map_vert { /* a tessellation vertex on screen */
    double x, y, iz;      /* pixel-centre coordinates, 1/depth */
    double uz, vz;        /* u/depth, v/depth */
};

struct map_tri {
    unsigned v[3];
    int patch;
    float pad;            /* conservative dilation, pixels */
    float zlo;            /* depth bound of the patch's surface near this triangle */
};

void map_free(struct map *m)
{
    if (!m)
        return;
    free(m->cand);
    free(m->dropped);
    free(m->verts);
    free(m->tris);
    free(m->tile_first);
    free(m->tile_tris);
    free(m);
}

/* Offers a fragment of `patch` with depth bound zlo to a pixel's candidate list. */
static void put(struct map *m, size_t idx, int patch, float u, float v, float zlo)
{
    struct map_cand *c = &m->cand[idx * MAP_CANDS];
    int at = 0;
    while (at < MAP_CANDS && c[at].patch >= 0 && c[at].patch != patch)
        at++;
    if (at < MAP_CANDS && c[at].patch == patch) { /* already listed: keep the better bound */
        if (!(zlo < c[at].zlo))
            return;
        for (; at > 0 && c[at - 1].zlo > zlo; at--)
            c[at] = c[at - 1];
        c[at] = (struct map_cand){patch, u, v, zlo};
        return;
    }
    /* a new patch: insert in order, pushing the last one out if the list is full */
    int pos = 0;
    while (pos < MAP_CANDS && c[pos].patch >= 0 && c[pos].zlo <= zlo)
        pos++;
    if (pos == MAP_CANDS) {
        m->dropped[idx] = fminf(m->dropped[idx], zlo);
        return;
    }
    int last = at < MAP_CANDS ? at : MAP_CANDS - 1; /* first free slot, or the evicted one */
    if (at == MAP_CANDS)
        m->dropped[idx] = fminf(m->dropped[idx], c[last].zlo);
    for (int k = last; k > pos; k--)
        c[k] = c[k - 1];
    c[pos] = (struct map_cand){patch, u, v, zlo};
}

static void tri_bbox(const struct map *m, const struct map_tri *t, int *x0, int *x1, int *y0, int *y1)
{
    const struct map_vert *a = &m->verts[t->v[0]], *b = &m->verts[t->v[1]], *c = &m->verts[t->v[2]];
    *x0 = (int)floor(fmin(a->x, fmin(b->x, c->x)) - t->pad);
    *x1 = (int)ceil(fmax(a->x, fmax(b->x, c->x)) + t->pad);
    *y0 = (int)floor(fmin(a->y, fmin(b->y, c->y)) - t->pad);
    *y1 = (int)ceil(fmax(a->y, fmax(b->y, c->y)) + t->pad);
    *x0 = *x0 < 0 ? 0 : *x0;
    *y0 = *y0 < 0 ? 0 : *y0;
    *x1 = *x1 > m->W - 1 ? m->W - 1 : *x1;
    *y1 = *y1 > m->H - 1 ? m->H - 1 : *y1;
}

/* Marks every pixel of rows [ylo, yhi) whose centre is within pad pixels of triangle t. */
static void raster_tri(struct map *m, const struct map_tri *t, int ylo, int yhi)
{
    const struct map_vert *v[3] = {&m->verts[t->v[0]], &m->verts[t->v[1]], &m->verts[t->v[2]]};
    double area = (v[1]->x - v[0]->x) * (v[2]->y - v[0]->y) - (v[1]->y - v[0]->y) * (v[2]->x - v[0]->x);
    int x0, x1, y0, y1;
    tri_bbox(m, t, &x0, &x1, &y0, &y1);
    y0 = y0 < ylo ? ylo : y0;
    y1 = y1 > yhi - 1 ? yhi - 1 : y1;
    double len[3];
    for (int k = 0; k < 3; k++) {
        const struct map_vert *p = v[(k + 1) % 3], *q = v[(k + 2) % 3];
        len[k] = hypot(q->x - p->x, q->y - p->y);
    }
    double sgn = area >= 0 ? 1.0 : -1.0, pad = t->pad;
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++) {
            /* edge functions: w_k is the signed area opposite vertex k */
            double w[3], s = 0.0;
            bool inside = true;
            for (int k = 0; k < 3; k++) {
                const struct map_vert *p = v[(k + 1) % 3], *q = v[(k + 2) % 3];
                w[k] = sgn * ((q->x - p->x) * (y - p->y) - (q->y - p->y) * (x - p->x));
                inside &= w[k] >= -pad * len[k];
                w[k] = w[k] < 0 ? 0 : w[k]; /* outside: the nearest point's attributes */
                s += w[k];
            }
            if (!inside)
                continue;
            if (s <= 0) /* degenerate on screen */
                w[0] = w[1] = w[2] = 1.0;
            double iz = 0, uz = 0, vz = 0;
            for (int k = 0; k < 3; k++) {
                iz += w[k] * v[k]->iz;
                uz += w[k] * v[k]->uz;
                vz += w[k] * v[k]->vz;
            }
            put(m, (size_t)y * m->W + x, t->patch, (float)(uz / iz), (float)(vz / iz), t->zlo);
        }
}

void map_raster_rows(struct map *m, int y0, int y1)
{
    for (size_t k = (size_t)y0 * m->W * MAP_CANDS; k < (size_t)y1 * m->W * MAP_CANDS; k++)
        m->cand[k] = (struct map_cand){-1, 0, 0, INFINITY};
    for (size_t k = (size_t)y0 * m->W; k < (size_t)y1 * m->W; k++)
        m->dropped[k] = INFINITY;
    for (int tile = y0 / MAP_TILE_ROWS; tile * MAP_TILE_ROWS < y1; tile++) {
        int lo = tile * MAP_TILE_ROWS > y0 ? tile * MAP_TILE_ROWS : y0;
        int hi = (tile + 1) * MAP_TILE_ROWS < y1 ? (tile + 1) * MAP_TILE_ROWS : y1;
        for (unsigned k = m->tile_first[tile]; k < m->tile_first[tile + 1]; k++)
            raster_tri(m, &m->tris[m->tile_tris[k]], lo, hi);
    }
}

/* Tessellates patch pt for the camera and appends its screen vertices and triangles. */
static int add_patch(struct map *m, const struct patch *pt, int index, const struct camera *cam, size_t *cap_v,
                     size_t *cap_t)
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
        return 0; /* wholly behind the eye */
    if (zmin <= NEAR_EPS * fmax(zmax, 1.0)) {
        m->complete = false;
        return 0;
    }
    double pix = zmin / px_per_unit; /* world size of a pixel at the nearest depth */
    int gu, gv;
    tess_grid_size(pt, MAP_ERR_PX * pix, MAP_MAX_SIDE, &gu, &gv);
    double err_px = tess_grid_error(pt, gu, gv) / pix;
    float pad = (float)(MAP_PAD_PX + fmax(0.0, err_px - MAP_ERR_PX));
    double chord = 2.0 * tess_grid_error(pt, gu, gv); /* twice the bound: rational patches */
    size_t base = m->n_verts, nv = (size_t)(gu + 1) * (gv + 1), nt = 2 * (size_t)gu * gv;
    if (mem_reserve((void **)&m->verts, cap_v, base + nv, sizeof *m->verts) ||
        mem_reserve((void **)&m->tris, cap_t, m->n_tris + nt, sizeof *m->tris))
        return SF_ENOMEM;
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
    for (int i = 0; i < gu; i++)
        for (int j = 0; j < gv; j++) {
            unsigned a = (unsigned)(base + (size_t)i * (gv + 1) + j), b = a + (unsigned)(gv + 1);
            const unsigned tri[2][3] = {{a, b, b + 1}, {a, b + 1, a + 1}};
            for (int k = 0; k < 2; k++) {
                struct map_tri *t = &m->tris[m->n_tris++];
                memcpy(t->v, tri[k], sizeof t->v);
                t->patch = index;
                t->pad = pad;
                /* its nearest vertex, less the chord error */
                double iz = fmax(m->verts[t->v[0]].iz, fmax(m->verts[t->v[1]].iz, m->verts[t->v[2]].iz));
                t->zlo = (float)(1.0 / iz - chord);
            }
        }
    return 0;
}

int map_build(const struct patch *patches, size_t n, const struct camera *cam, struct map **out, struct sf_err *err)
{
    *out = NULL;
    struct map *m = calloc(1, sizeof *m);
    size_t np = (size_t)cam->W * cam->H, cap_v = 0, cap_t = 0;
    int n_tiles = (cam->H + MAP_TILE_ROWS - 1) / MAP_TILE_ROWS;
    if (!m || np > MAP_MAX_PIXELS || !(m->cand = malloc(sizeof *m->cand * np * MAP_CANDS)) ||
        !(m->dropped = malloc(sizeof *m->dropped * np)) || !(m->tile_first = calloc((size_t)n_tiles + 2, sizeof(unsigned))))
        goto out_nomem;
    m->W = cam->W;
    m->H = cam->H;
    m->complete = true;
    for (size_t k = 0; k < n; k++)
        if (add_patch(m, &patches[k], (int)k, cam, &cap_v, &cap_t))
            goto out_nomem;
    /* bucket the triangles by the row tiles their padded boxes touch (counting sort) */
    size_t n_refs = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (size_t k = 0; k < m->n_tris; k++) {
            int x0, x1, y0, y1;
            tri_bbox(m, &m->tris[k], &x0, &x1, &y0, &y1);
            if (x0 > x1 || y0 > y1)
                continue;
            for (int t = y0 / MAP_TILE_ROWS; t <= y1 / MAP_TILE_ROWS; t++) {
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
            if (!(m->tile_tris = malloc(sizeof *m->tile_tris * (n_refs ? n_refs : 1))))
                goto out_nomem;
        }
    }
    *out = m;
    return 0;

out_nomem:
    map_free(m);
    return sf_fail(err, SF_ENOMEM, "", "out of memory for the preliminary-value map");
}
