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

#include "tess.h"

#define MAP_ERR_PX 0.5   /* chord error allowed, in pixels at the patch's nearest depth */
#define MAP_PAD_PX 1.0   /* conservative dilation of every triangle, in pixels */
#define MAP_MAX_SIDE 96  /* grid cap per patch side; the pad grows where the cap binds */
#define NEAR_EPS 1e-9    /* relative depth below which a vertex counts as behind the eye */

void map_free(struct map *m)
{
    if (!m)
        return;
    free(m->cand);
    free(m->dropped);
    free(m);
}

struct sv { /* screen vertex */
    double x, y, iz;      /* pixel-centre coordinates, 1/depth */
    double uz, vz;        /* u/depth, v/depth */
};

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

/* Marks every pixel whose centre is within pad pixels of triangle abc. zlo bounds the depth
 * of the patch's surface near the triangle: its nearest vertex less the chord error. */
static void raster_tri(struct map *m, const struct sv *a, const struct sv *b, const struct sv *c, int patch,
                       double pad, double chord)
{
    float zlo = (float)(1.0 / fmax(a->iz, fmax(b->iz, c->iz)) - chord);
    double area = (b->x - a->x) * (c->y - a->y) - (b->y - a->y) * (c->x - a->x);
    if (fabs(area) < 1e-12) { /* degenerate on screen: still mark its pixels via a widened box */
        area = area < 0 ? -1e-12 : 1e-12;
    }
    int x0 = (int)floor(fmin(a->x, fmin(b->x, c->x)) - pad), x1 = (int)ceil(fmax(a->x, fmax(b->x, c->x)) + pad);
    int y0 = (int)floor(fmin(a->y, fmin(b->y, c->y)) - pad), y1 = (int)ceil(fmax(a->y, fmax(b->y, c->y)) + pad);
    if (x0 < 0) x0 = 0;
    if (y0 < 0) y0 = 0;
    if (x1 > m->W - 1) x1 = m->W - 1;
    if (y1 > m->H - 1) y1 = m->H - 1;
    const struct sv *v[3] = {a, b, c};
    double len[3];
    for (int k = 0; k < 3; k++) {
        const struct sv *p = v[(k + 1) % 3], *q = v[(k + 2) % 3];
        len[k] = hypot(q->x - p->x, q->y - p->y);
    }
    double sgn = area > 0 ? 1.0 : -1.0;
    for (int y = y0; y <= y1; y++)
        for (int x = x0; x <= x1; x++) {
            /* edge functions: w_k is the signed area opposite vertex k */
            double w[3];
            bool inside = true;
            for (int k = 0; k < 3; k++) {
                const struct sv *p = v[(k + 1) % 3], *q = v[(k + 2) % 3];
                w[k] = sgn * ((q->x - p->x) * (y - p->y) - (q->y - p->y) * (x - p->x));
                if (w[k] < -pad * len[k])
                    inside = false;
            }
            if (!inside)
                continue;
            double s = 0.0;
            for (int k = 0; k < 3; k++) {
                if (w[k] < 0)
                    w[k] = 0;
                s += w[k];
            }
            if (s <= 0)
                w[0] = w[1] = w[2] = 1.0, s = 3.0;
            double iz = 0, uz = 0, vz = 0;
            for (int k = 0; k < 3; k++) {
                iz += w[k] * v[k]->iz;
                uz += w[k] * v[k]->uz;
                vz += w[k] * v[k]->vz;
            }
            put(m, (size_t)y * m->W + x, patch, (float)(uz / iz), (float)(vz / iz), zlo);
        }
}

int map_build(const struct patch *patches, size_t n, const struct camera *cam, struct map **out, struct sf_err *err)
{
    *out = NULL;
    struct map *m = calloc(1, sizeof *m);
    size_t np = (size_t)cam->W * cam->H;
    if (!m || np > MAP_MAX_PIXELS || !(m->cand = malloc(sizeof *m->cand * np * MAP_CANDS)) ||
        !(m->dropped = malloc(sizeof *m->dropped * np))) {
        map_free(m);
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the preliminary-value map");
    }
    m->W = cam->W;
    m->H = cam->H;
    m->complete = true;
    for (size_t k = 0; k < np * MAP_CANDS; k++)
        m->cand[k] = (struct map_cand){-1, 0, 0, INFINITY};
    for (size_t k = 0; k < np; k++)
        m->dropped[k] = INFINITY;
    double px_per_unit = cam->H / (2.0 * cam->th); /* pixels per world unit at depth 1 */

    for (size_t k = 0; k < n; k++) {
        const struct patch *pt = &patches[k];
        /* nearest depth of the patch: control points bound it (convex hull) */
        double zmin = INFINITY, zmax = -INFINITY;
        for (int i = 0; i <= pt->p; i++)
            for (int j = 0; j <= pt->q; j++) {
                double z = v3_dot(v3_sub(bezier_point(pt, i, j), cam->eye), cam->f);
                zmin = fmin(zmin, z);
                zmax = fmax(zmax, z);
            }
        if (zmax <= 0)
            continue; /* wholly behind the eye */
        if (zmin <= NEAR_EPS * fmax(zmax, 1.0)) {
            m->complete = false;
            continue;
        }
        double pix = zmin / px_per_unit; /* world size of a pixel at the nearest depth */
        int gu, gv;
        tess_grid_size(pt, MAP_ERR_PX * pix, MAP_MAX_SIDE, &gu, &gv);
        double err_px = tess_grid_error(pt, gu, gv) / pix;
        double pad = MAP_PAD_PX + fmax(0.0, err_px - MAP_ERR_PX);
        double chord = 2.0 * tess_grid_error(pt, gu, gv); /* twice the bound: rational patches */
        struct sv *row = malloc(sizeof *row * (size_t)(gu + 1) * (gv + 1));
        if (!row) {
            map_free(m);
            return sf_fail(err, SF_ENOMEM, "", "out of memory for the preliminary-value map");
        }
        for (int i = 0; i <= gu; i++)
            for (int j = 0; j <= gv; j++) {
                double u = (double)i / gu, v = (double)j / gv;
                vec3 P;
                bezier_eval(pt, u, v, &P, NULL, NULL);
                vec3 d = v3_sub(P, cam->eye);
                double z = fmax(v3_dot(d, cam->f), NEAR_EPS);
                double sx = v3_dot(d, cam->r) / (z * cam->th * cam->aspect);
                double sy = v3_dot(d, cam->u) / (z * cam->th);
                struct sv *s = &row[i * (gv + 1) + j];
                s->x = (sx + 1.0) * 0.5 * cam->W - 0.5;
                s->y = (1.0 - sy) * 0.5 * cam->H - 0.5;
                s->iz = 1.0 / z;
                s->uz = u / z;
                s->vz = v / z;
            }
        for (int i = 0; i < gu; i++)
            for (int j = 0; j < gv; j++) {
                const struct sv *a = &row[i * (gv + 1) + j], *b = a + (gv + 1);
                raster_tri(m, a, b, b + 1, (int)k, pad, chord);
                raster_tri(m, a, b + 1, a + 1, (int)k, pad, chord);
                m->n_tris += 2;
            }
        free(row);
    }
    *out = m;
    return 0;
}
