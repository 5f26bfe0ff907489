/* enclosed.c - volume and closure of a patch set (enclosed.h). */
#include "enclosed.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "../base/gauss.h"

#define GL_MAX 40
#define CLOSE_REL 1e-7 /* edge points closer than this times the bounds' diagonal are one */

/* Nodes enough for eq. 21's integrand, of degree 3d - 1 for a polynomial patch of degree d; more
 * for rational ones, whose integrand is smooth but not polynomial. */
static int nodes_for(int d, bool rational)
{
    int n = (3 * d + 1) / 2 + (rational ? 12 : 0);
    return n < 2 ? 2 : n > GL_MAX ? GL_MAX : n;
}

struct edge {
    const vec3 *pts;
    int n;
    double key;      /* x of the points' mean: a sort key that matching edges share */
    int object;
    bool matched;
};

static int by_key(const void *a, const void *b)
{
    double x = ((const struct edge *)a)->key, y = ((const struct edge *)b)->key;
    return (x > y) - (x < y);
}

/* Whether edge a runs along b (same) or against it (reversed), within tol. 0: neither. */
static int edge_match(const struct edge *a, const struct edge *b, double tol)
{
    if (a->n != b->n)
        return 0;
    bool rev = true, same = true;
    for (int i = 0; i < a->n && (rev || same); i++) {
        rev &= v3_len(v3_sub(a->pts[i], b->pts[b->n - 1 - i])) <= tol;
        same &= v3_len(v3_sub(a->pts[i], b->pts[i])) <= tol;
    }
    return rev ? -1 : same ? 1 : 0;
}

/* The patch's boundary as four edges round its (u, v) square: v = 0 forward, u = 1 forward, v = 1
 * back, u = 0 back; their points go to pts (at most 4 (d + 1)). */
static int patch_edges(const struct patch *pt, vec3 *pts, struct edge *out, double tol)
{
    int p = pt->p, q = pt->q, n = 0;
    vec3 *at = pts;
    for (int e = 0; e < 4; e++) {
        int m = e % 2 ? q + 1 : p + 1;
        for (int k = 0; k < m; k++) {
            int r = e >= 2 ? m - 1 - k : k; /* back along v = 1 and u = 0 */
            at[k] = e == 0 ? bezier_point(pt, r, 0) : e == 1 ? bezier_point(pt, p, r)
                  : e == 2 ? bezier_point(pt, r, q) : bezier_point(pt, 0, r);
        }
        bool collapsed = true;
        vec3 mean = v3(0, 0, 0);
        for (int k = 0; k < m; k++) {
            collapsed &= v3_len(v3_sub(at[k], at[0])) <= tol;
            mean = v3_add(mean, at[k]);
        }
        if (!collapsed)
            out[n++] = (struct edge){at, m, mean.x / m, pt->surface, false};
        at += m;
    }
    return n;
}

int enclosed_measure(const struct patch_set *ps, struct enclosed *e)
{
    memset(e, 0, sizeof *e);
    e->open_object = -1;
    for (int d = 0; d < 3; d++)
        e->lo[d] = INFINITY, e->hi[d] = -INFINITY;
    double X[GL_MAX], W[GL_MAX], Y[GL_MAX], V[GL_MAX];
    for (size_t k = 0; k < ps->n; k++) {
        const struct patch *pt = &ps->patches[k];
        vec3 lo, hi;
        bezier_bounds(pt, &lo, &hi);
        e->lo[0] = fmin(e->lo[0], lo.x), e->lo[1] = fmin(e->lo[1], lo.y), e->lo[2] = fmin(e->lo[2], lo.z);
        e->hi[0] = fmax(e->hi[0], hi.x), e->hi[1] = fmax(e->hi[1], hi.y), e->hi[2] = fmax(e->hi[2], hi.z);
        int nu = nodes_for(pt->p, pt->rational), nv = nodes_for(pt->q, pt->rational);
        gauss_legendre(nu, X, W);
        gauss_legendre(nv, Y, V);
        for (int a = 0; a < nu; a++)
            for (int b = 0; b < nv; b++) {
                vec3 P, Pu, Pv;
                bezier_eval(pt, X[a], Y[b], &P, &Pu, &Pv);
                double A = Pu.y * Pv.z - Pu.z * Pv.y, B = Pu.z * Pv.x - Pu.x * Pv.z, w = W[a] * V[b];
                e->volume += 0.5 * w * (A * P.x + B * P.y); /* seed 000 eq. 21–22 */
                e->area += w * v3_len(v3_cross(Pu, Pv));
            }
    }
    double tol = CLOSE_REL * v3_len(v3(e->hi[0] - e->lo[0], e->hi[1] - e->lo[1], e->hi[2] - e->lo[2]));
    size_t n_pts = 0;
    for (size_t k = 0; k < ps->n; k++)
        n_pts += 2 * (size_t)(ps->patches[k].p + ps->patches[k].q + 2);
    vec3 *pts = malloc(sizeof *pts * (n_pts ? n_pts : 1));
    struct edge *edges = malloc(sizeof *edges * (4 * ps->n + 1));
    if (!pts || !edges) {
        free(pts);
        free(edges);
        return SF_ENOMEM;
    }
    size_t n_edges = 0, used = 0;
    for (size_t k = 0; k < ps->n; k++) {
        const struct patch *pt = &ps->patches[k];
        n_edges += (size_t)patch_edges(pt, pts + used, edges + n_edges, tol);
        used += 2 * (size_t)(pt->p + pt->q + 2);
    }
    qsort(edges, n_edges, sizeof *edges, by_key);
    int n_obj = 0;
    for (size_t k = 0; k < ps->n; k++)
        n_obj = ps->patches[k].surface >= n_obj ? ps->patches[k].surface + 1 : n_obj;
    size_t *flips = calloc((size_t)n_obj + 1, sizeof *flips); /* per object: the one turned has most */
    for (size_t a = 0; a < n_edges; a++) {
        if (edges[a].matched)
            continue;
        for (size_t b = a + 1; b < n_edges && edges[b].key - edges[a].key <= tol; b++) {
            int m = edges[b].matched ? 0 : edge_match(&edges[a], &edges[b], tol);
            if (m) {
                edges[a].matched = edges[b].matched = true;
                if (m > 0) {
                    e->flipped_edges += 2;
                    if (flips) {
                        flips[edges[a].object]++;
                        flips[edges[b].object]++;
                    }
                }
                break;
            }
        }
        if (!edges[a].matched) {
            e->open_edges++;
            e->open_object = e->open_object < 0 ? edges[a].object : e->open_object;
        }
    }
    for (int k = 0; flips && k < n_obj && !e->open_edges; k++)
        if (flips[k] && (e->open_object < 0 || flips[k] > flips[e->open_object]))
            e->open_object = k;
    free(flips);
    free(pts);
    free(edges);
    return 0;
}
