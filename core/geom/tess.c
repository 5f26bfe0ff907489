/* tess.c - uniform grids sized by the second-difference chord bound, the same size for every
 * patch so that shared edges match (no cracks where patches meet edge to edge). */
#include "tess.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* max |Δ²P| along u (dir 0) or v (dir 1) of the Euclidean control net, times p(p-1) */
static double second_diff(const struct patch *pt, int dir)
{
    int p = pt->p, q = pt->q, n = dir ? q : p;
    if (n < 2)
        return 0.0;
    double m = 0.0;
    for (int i = 0; i <= p; i++)
        for (int j = 0; j <= q; j++) {
            if ((dir == 0 && i + 2 > p) || (dir == 1 && j + 2 > q))
                continue;
            vec3 a = bezier_point(pt, i, j);
            vec3 b = dir ? bezier_point(pt, i, j + 1) : bezier_point(pt, i + 1, j);
            vec3 c = dir ? bezier_point(pt, i, j + 2) : bezier_point(pt, i + 2, j);
            m = fmax(m, v3_len(v3_add(v3_sub(a, v3_scale(b, 2.0)), c)));
        }
    /* rational patches: the Euclidean net is only a guide, so take a safety factor of 2 */
    return m * n * (n - 1) * (pt->rational ? 2.0 : 1.0);
}

void tess_grid_size(const struct patch *pt, double tol, int max_side, int *n_u, int *n_v)
{
    /* split the budget between the two directions: each gets tol/2 */
    double cu = second_diff(pt, 0), cv = second_diff(pt, 1);
    int nu = (int)ceil(sqrt(cu / (4.0 * tol))), nv = (int)ceil(sqrt(cv / (4.0 * tol)));
    *n_u = nu < 1 ? 1 : (nu > max_side ? max_side : nu);
    *n_v = nv < 1 ? 1 : (nv > max_side ? max_side : nv);
}

double tess_grid_error(const struct patch *pt, int n_u, int n_v)
{
    return second_diff(pt, 0) / (8.0 * n_u * n_u) + second_diff(pt, 1) / (8.0 * n_v * n_v);
}

int tess_build(const struct patch *patches, size_t n, double tol, int max_side, struct tess *out)
{
    memset(out, 0, sizeof *out);
    int(*sizes)[2] = malloc(sizeof *sizes * (n ? n : 1));
    if (!sizes)
        return SF_ENOMEM;
    /* One grid size for every patch and both directions: patches that share an edge curve then
     * share its vertices exactly, so the mesh has no cracks between them. */
    int side = 1;
    for (size_t k = 0; k < n; k++) {
        int gu, gv;
        tess_grid_size(&patches[k], tol, max_side, &gu, &gv);
        side = gu > side ? gu : side;
        side = gv > side ? gv : side;
    }
    size_t nv = 0, nt = 0;
    for (size_t k = 0; k < n; k++) {
        sizes[k][0] = sizes[k][1] = side;
        nv += (size_t)(side + 1) * (side + 1);
        nt += 2 * (size_t)side * side;
    }
    out->pos = malloc(sizeof *out->pos * nv);
    out->nrm = malloc(sizeof *out->nrm * nv);
    out->uv = malloc(sizeof *out->uv * nv);
    out->patch = malloc(sizeof *out->patch * nv);
    out->tri = malloc(sizeof *out->tri * nt);
    if (!out->pos || !out->nrm || !out->uv || !out->patch || !out->tri) {
        free(sizes);
        tess_free(out);
        return SF_ENOMEM;
    }
    size_t v = 0, t = 0;
    for (size_t k = 0; k < n; k++) {
        int gu = sizes[k][0], gv = sizes[k][1];
        size_t base = v;
        for (int i = 0; i <= gu; i++)
            for (int j = 0; j <= gv; j++, v++) {
                double u = (double)i / gu, w = (double)j / gv;
                vec3 P, N = v3(0, 0, 1);
                bezier_eval(&patches[k], u, w, &P, NULL, NULL);
                bezier_normal(&patches[k], u, w, &N);
                memcpy(out->pos[v], &P, sizeof out->pos[v]);
                out->nrm[v][0] = (float)N.x, out->nrm[v][1] = (float)N.y, out->nrm[v][2] = (float)N.z;
                out->uv[v][0] = (float)u, out->uv[v][1] = (float)w;
                out->patch[v] = (int)k;
            }
        for (int i = 0; i < gu; i++)
            for (int j = 0; j < gv; j++) {
                unsigned a = (unsigned)(base + (size_t)i * (gv + 1) + j), b = a + (unsigned)(gv + 1);
                out->tri[t][0] = a, out->tri[t][1] = b, out->tri[t][2] = b + 1, t++;
                out->tri[t][0] = a, out->tri[t][1] = b + 1, out->tri[t][2] = a + 1, t++;
            }
    }
    out->n_verts = v;
    out->n_tris = t;
    free(sizes);
    return 0;
}

void tess_free(struct tess *t)
{
    if (!t)
        return;
    free(t->pos);
    free(t->nrm);
    free(t->uv);
    free(t->patch);
    free(t->tri);
    memset(t, 0, sizeof *t);
}
