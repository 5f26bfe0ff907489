/* tess.c - uniform grids sized by the second-difference chord bound, the same size for every
 * patch so that shared edges match (no cracks where patches meet edge to edge). */
#include "tess.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

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

/* The growing arrays of a tessellation. */
struct tess_caps {
    size_t v, t;
};

static int add_vertex(struct tess *out, struct tess_caps *cap, const struct patch *pt, int k, double u, double w)
{
    size_t v = out->n_verts;
    if (v == cap->v) { /* the four per-vertex arrays grow together */
        size_t c = cap->v ? 2 * cap->v : 1024;
        double(*pos)[3] = realloc(out->pos, sizeof *pos * c);
        if (pos)
            out->pos = pos;
        float(*nrm)[3] = realloc(out->nrm, sizeof *nrm * c);
        if (nrm)
            out->nrm = nrm;
        float(*uv)[2] = realloc(out->uv, sizeof *uv * c);
        if (uv)
            out->uv = uv;
        int *patch = realloc(out->patch, sizeof *patch * c);
        if (patch)
            out->patch = patch;
        if (!pos || !nrm || !uv || !patch)
            return SF_ENOMEM;
        cap->v = c;
    }
    vec3 P, N = v3(0, 0, 1);
    bezier_eval(pt, u, w, &P, NULL, NULL);
    bezier_normal(pt, u, w, &N);
    memcpy(out->pos[v], &P, sizeof out->pos[v]);
    out->nrm[v][0] = (float)N.x, out->nrm[v][1] = (float)N.y, out->nrm[v][2] = (float)N.z;
    out->uv[v][0] = (float)u, out->uv[v][1] = (float)w;
    out->patch[v] = k;
    out->n_verts++;
    return 0;
}

static int add_tri(struct tess *out, struct tess_caps *cap, unsigned a, unsigned b, unsigned c)
{
    if (mem_reserve((void **)&out->tri, &cap->t, out->n_tris + 1, sizeof *out->tri))
        return SF_ENOMEM;
    out->tri[out->n_tris][0] = a, out->tri[out->n_tris][1] = b, out->tri[out->n_tris][2] = c;
    out->n_tris++;
    return 0;
}

/* A grid triangle that a trim loop crosses, split into four by its edges' midpoints down to
 * TESS_TRIM_DEPTH levels; the smallest parts whose centres the region holds are kept (so the
 * mesh follows the loop to within a sixteenth of a grid cell). uv: the corners' patch parameters. */
#define TESS_TRIM_DEPTH 4
static int trim_tri(struct tess *out, struct tess_caps *cap, const struct patch *pt, int k, const double uv[3][2],
                    const unsigned idx[3], int depth)
{
    double lo[2] = {fmin(fmin(uv[0][0], uv[1][0]), uv[2][0]), fmin(fmin(uv[0][1], uv[1][1]), uv[2][1])};
    double hi[2] = {fmax(fmax(uv[0][0], uv[1][0]), uv[2][0]), fmax(fmax(uv[0][1], uv[1][1]), uv[2][1])};
    double su = pt->u1 - pt->u0, sv = pt->v1 - pt->v0;
    enum trim_class c = trim_classify(pt->trim, pt->u0 + lo[0] * su, pt->u0 + hi[0] * su, pt->v0 + lo[1] * sv,
                                      pt->v0 + hi[1] * sv);
    if (c == TRIM_CUT && depth >= TESS_TRIM_DEPTH)
        c = bezier_kept(pt, (uv[0][0] + uv[1][0] + uv[2][0]) / 3, (uv[0][1] + uv[1][1] + uv[2][1]) / 3) ? TRIM_IN
                                                                                                         : TRIM_OUT;
    if (c == TRIM_OUT)
        return 0;
    unsigned at[3];
    for (int e = 0; e < 3; e++)
        if (idx[e] != UINT_MAX)
            at[e] = idx[e];
        else if (add_vertex(out, cap, pt, k, uv[e][0], uv[e][1]))
            return SF_ENOMEM;
        else
            at[e] = (unsigned)(out->n_verts - 1);
    if (c == TRIM_IN)
        return add_tri(out, cap, at[0], at[1], at[2]);
    const double m[3][2] = {{0.5 * (uv[0][0] + uv[1][0]), 0.5 * (uv[0][1] + uv[1][1])},
                            {0.5 * (uv[1][0] + uv[2][0]), 0.5 * (uv[1][1] + uv[2][1])},
                            {0.5 * (uv[2][0] + uv[0][0]), 0.5 * (uv[2][1] + uv[0][1])}};
    const double part[4][3][2] = {{{uv[0][0], uv[0][1]}, {m[0][0], m[0][1]}, {m[2][0], m[2][1]}},
                                  {{m[0][0], m[0][1]}, {uv[1][0], uv[1][1]}, {m[1][0], m[1][1]}},
                                  {{m[2][0], m[2][1]}, {m[1][0], m[1][1]}, {uv[2][0], uv[2][1]}},
                                  {{m[0][0], m[0][1]}, {m[1][0], m[1][1]}, {m[2][0], m[2][1]}}};
    const unsigned corner[4][3] = {{at[0], UINT_MAX, UINT_MAX}, {UINT_MAX, at[1], UINT_MAX},
                                   {UINT_MAX, UINT_MAX, at[2]}, {UINT_MAX, UINT_MAX, UINT_MAX}};
    for (int q = 0; q < 4; q++)
        if (trim_tri(out, cap, pt, k, part[q], corner[q], depth + 1))
            return SF_ENOMEM;
    return 0;
}

int tess_build(const struct patch *patches, size_t n, double tol, int max_side, struct tess *out)
{
    memset(out, 0, sizeof *out);
    /* One grid size for every patch and both directions: patches that share an edge curve then
     * share its vertices exactly, so the mesh has no cracks between them. */
    int side = 1;
    for (size_t k = 0; k < n; k++) {
        int gu, gv;
        tess_grid_size(&patches[k], tol, max_side, &gu, &gv);
        side = gu > side ? gu : side;
        side = gv > side ? gv : side;
    }
    struct tess_caps cap = {0, 0};
    if (mem_reserve((void **)&out->tri, &cap.t, n ? 2 * (size_t)side * side * n : 1, sizeof *out->tri))
        return SF_ENOMEM;
    int rc = 0;
    for (size_t k = 0; k < n && !rc; k++) {
        const struct patch *pt = &patches[k];
        const int g = side;
        size_t base = out->n_verts;
        for (int i = 0; i <= g && !rc; i++)
            for (int j = 0; j <= g && !rc; j++)
                rc = add_vertex(out, &cap, pt, (int)k, (double)i / g, (double)j / g);
        for (int i = 0; i < g && !rc; i++)
            for (int j = 0; j < g && !rc; j++) {
                unsigned a = (unsigned)(base + (size_t)i * (g + 1) + j), b = a + (unsigned)(g + 1);
                const unsigned tri[2][3] = {{a, b, b + 1}, {a, b + 1, a + 1}};
                for (int h = 0; h < 2 && !rc; h++) {
                    if (!pt->trim) {
                        rc = add_tri(out, &cap, tri[h][0], tri[h][1], tri[h][2]);
                        continue;
                    }
                    const double u0 = (double)i / g, u1 = (double)(i + 1) / g, w0 = (double)j / g,
                                 w1 = (double)(j + 1) / g;
                    const double uv[2][3][2] = {{{u0, w0}, {u1, w0}, {u1, w1}}, {{u0, w0}, {u1, w1}, {u0, w1}}};
                    rc = trim_tri(out, &cap, pt, (int)k, uv[h], tri[h], 0);
                }
            }
    }
    if (rc)
        tess_free(out);
    return rc;
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
