/* tess.c - grids sized by the second-difference chord bound, each patch its own (tess.h: shared
 * edges snapped to the coarser side, so no cracks where patches meet edge to edge). */
#include "tess.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

/* bezier_net_curvature, as bezier_second_bounds keeps it where it ran (wmin set) */
static double second_diff(const struct patch *pt, int dir)
{
    return pt->wmin > 0.0 ? pt->curv[dir] : bezier_net_curvature(pt, dir);
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

/* A grid triangle that a trim loop crosses, halved across its longest side (in space: a grid cell
 * may be a long strip) until its sides are within 8 chord tolerances tol (at most TESS_TRIM_DEPTH
 * halvings); the smallest parts whose centres the region holds are kept (at the default tolerance,
 * a pixel of a 1024-pixel view of the part: the mugs' outlines as Open CASCADE's). uv: the corners'
 * patch parameters; idx: their vertices, UINT_MAX where there is none yet. */
#define TESS_TRIM_DEPTH 24
static int trim_tri(struct tess *out, struct tess_caps *cap, const struct patch *pt, int k, const double uv[3][2],
                    const unsigned idx[3], double tol, int depth)
{
    double lo[2] = {fmin(fmin(uv[0][0], uv[1][0]), uv[2][0]), fmin(fmin(uv[0][1], uv[1][1]), uv[2][1])};
    double hi[2] = {fmax(fmax(uv[0][0], uv[1][0]), uv[2][0]), fmax(fmax(uv[0][1], uv[1][1]), uv[2][1])};
    double su = pt->u1 - pt->u0, sv = pt->v1 - pt->v0;
    enum trim_class c = trim_classify(pt->trim, pt->u0 + lo[0] * su, pt->u0 + hi[0] * su, pt->v0 + lo[1] * sv,
                                      pt->v0 + hi[1] * sv);
    int longest = 0; /* the side from corner longest to the next */
    if (c == TRIM_CUT) {
        vec3 P[3];
        double len[3];
        for (int e = 0; e < 3; e++)
            bezier_eval(pt, uv[e][0], uv[e][1], &P[e], NULL, NULL);
        for (int e = 0; e < 3; e++) {
            len[e] = v3_len(v3_sub(P[(e + 1) % 3], P[e]));
            longest = len[e] > len[longest] ? e : longest;
        }
        if (depth >= TESS_TRIM_DEPTH || len[longest] <= 8.0 * tol)
            c = bezier_kept(pt, (uv[0][0] + uv[1][0] + uv[2][0]) / 3, (uv[0][1] + uv[1][1] + uv[2][1]) / 3) ? TRIM_IN
                                                                                                             : TRIM_OUT;
    }
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
    /* corners a, b (the longest side) and c; m the middle of a-b: halves (a, m, c) and (m, b, c),
     * both turning as the triangle does */
    const int ia = longest, ib = (longest + 1) % 3, ic = (longest + 2) % 3;
    const double m[2] = {0.5 * (uv[ia][0] + uv[ib][0]), 0.5 * (uv[ia][1] + uv[ib][1])};
    const double half[2][3][2] = {{{uv[ia][0], uv[ia][1]}, {m[0], m[1]}, {uv[ic][0], uv[ic][1]}},
                                  {{m[0], m[1]}, {uv[ib][0], uv[ib][1]}, {uv[ic][0], uv[ic][1]}}};
    const unsigned corner[2][3] = {{at[ia], UINT_MAX, at[ic]}, {UINT_MAX, at[ib], at[ic]}};
    for (int q = 0; q < 2; q++)
        if (trim_tri(out, cap, pt, k, half[q], corner[q], tol, depth + 1))
            return SF_ENOMEM;
    return 0;
}

/* ---- edges shared between patches ----------------------------------------------------- */

/* A patch edge by its two end points and its middle, quantised (ends in order, so that both patches
 * along it give the same key whichever way they run it), and the segments its patch gives it. */
struct tedge {
    long long key[9];
    int n;
    size_t patch;
    int side; /* 0: v = 0, 1: u = 1, 2: v = 1, 3: u = 0 */
};

static vec3 edge_point(const struct patch *pt, int side, double t)
{
    double u = side == 0 || side == 2 ? t : side == 1 ? 1.0 : 0.0, v = side == 1 || side == 3 ? t : side == 2 ? 1.0 : 0.0;
    vec3 P;
    bezier_eval(pt, u, v, &P, NULL, NULL);
    return P;
}

static int by_key(const void *x, const void *y)
{
    const struct tedge *a = x, *b = y;
    for (int k = 0; k < 9; k++)
        if (a->key[k] != b->key[k])
            return a->key[k] < b->key[k] ? -1 : 1;
    return 0;
}

static void edge_key(struct tedge *e, const struct patch *pt, double quantum)
{
    vec3 p[3] = {edge_point(pt, e->side, 0.0), edge_point(pt, e->side, 1.0), edge_point(pt, e->side, 0.5)};
    if (p[1].x < p[0].x || (p[1].x == p[0].x && (p[1].y < p[0].y || (p[1].y == p[0].y && p[1].z < p[0].z)))) {
        vec3 t = p[0];
        p[0] = p[1];
        p[1] = t;
    }
    for (int k = 0; k < 3; k++) {
        e->key[3 * k] = llround(p[k].x / quantum);
        e->key[3 * k + 1] = llround(p[k].y / quantum);
        e->key[3 * k + 2] = llround(p[k].z / quantum);
    }
}

/* The grid sizes patches may take: top (the most any needs, rounded up to a multiple of 16, or to a
 * power of two below 16) and its halves while they are whole, so that every size divides every
 * larger one; a patch takes the least that holds its need. At most a sixteenth over the finest
 * patch's need at the top, and under twice each other patch's. */
static int chain_size(int need, int top)
{
    int n = top;
    while (n % 2 == 0 && n / 2 >= need)
        n /= 2;
    return n;
}

static int chain_top(int most, int cap)
{
    int top = 1;
    if (most <= 16)
        while (top < most)
            top <<= 1;
    else
        top = (most + 15) / 16 * 16;
    return top > cap ? cap : top;
}

/* Each patch side's segments as its neighbour across it has them (its own where it has none or a
 * finer one): edges[4 k + side]. */
static int neighbour_counts(const struct patch *patches, size_t n, const int (*sizes)[2], int *counts)
{
    vec3 lo = v3(INFINITY, INFINITY, INFINITY), hi = v3(-INFINITY, -INFINITY, -INFINITY);
    for (size_t k = 0; k < n; k++) {
        vec3 a, b;
        bezier_bounds(&patches[k], &a, &b);
        lo = v3_min(lo, a), hi = v3_max(hi, b);
    }
    double quantum = 1e-7 * fmax(v3_len(v3_sub(hi, lo)), 1e-300);
    struct tedge *e = malloc(sizeof *e * 4 * (n ? n : 1));
    if (!e)
        return SF_ENOMEM;
    for (size_t k = 0; k < n; k++)
        for (int s = 0; s < 4; s++) {
            struct tedge *x = &e[4 * k + s];
            x->patch = k, x->side = s, x->n = sizes[k][s % 2 == 0 ? 0 : 1];
            edge_key(x, &patches[k], quantum);
            counts[4 * k + s] = x->n;
        }
    qsort(e, 4 * n, sizeof *e, by_key);
    for (size_t a = 0; a < 4 * n;) {
        size_t b = a;
        int least = e[a].n;
        while (b < 4 * n && !by_key(&e[a], &e[b]))
            least = e[b].n < least ? e[b].n : least, b++;
        for (size_t k = a; k < b; k++)
            counts[4 * e[k].patch + e[k].side] = least;
        a = b;
    }
    free(e);
    return 0;
}

/* Moves the vertices of patch k's side s that its coarser neighbour does not have onto the
 * neighbour's chords there (grid sizes divide one another: the coarse vertices are among the fine),
 * so that the mesh has no cracks where patches of different sizes meet. */
static void snap_side(struct tess *out, size_t base, const struct patch *pt, int gu, int gv, int s, int coarse)
{
    int n = s % 2 == 0 ? gu : gv;
    if (coarse >= n)
        return;
    for (int j = 1; j < n; j++) {
        if ((long long)j * coarse % n == 0)
            continue;
        double t = (double)j / n * coarse, f = t - floor(t);
        int i = (int)floor(t);
        vec3 A = edge_point(pt, s, (double)i / coarse), B = edge_point(pt, s, (double)(i + 1) / coarse);
        vec3 P = v3_add(A, v3_scale(v3_sub(B, A), f));
        int gi = s == 0 || s == 2 ? j : s == 1 ? gu : 0, gj = s == 1 || s == 3 ? j : s == 2 ? gv : 0;
        memcpy(out->pos[base + (size_t)gi * (gv + 1) + gj], &P, sizeof out->pos[0]);
    }
}

int tess_build(const struct patch *patches, size_t n, double tol, int max_side, struct tess *out)
{
    memset(out, 0, sizeof *out);
    /* Each patch its own grid, sized for tol, from one chain of sizes; where a neighbour across a side is
     * coarser, that side's extra vertices go onto the neighbour's chords: no cracks, and a model of
     * many small patches is not tessellated everywhere as finely as its most curved patch needs. */
    int(*sizes)[2] = malloc(sizeof *sizes * (n ? n : 1));
    int *counts = malloc(sizeof *counts * 4 * (n ? n : 1));
    if (!sizes || !counts) {
        free(sizes);
        free(counts);
        return SF_ENOMEM;
    }
    size_t nt = 0;
    int most = 1;
    for (size_t k = 0; k < n; k++) {
        tess_grid_size(&patches[k], tol, max_side, &sizes[k][0], &sizes[k][1]);
        most = sizes[k][0] > most ? sizes[k][0] : most;
        most = sizes[k][1] > most ? sizes[k][1] : most;
    }
    const int top = chain_top(most, max_side & ~15);
    for (size_t k = 0; k < n; k++) {
        sizes[k][0] = chain_size(sizes[k][0], top), sizes[k][1] = chain_size(sizes[k][1], top);
        nt += 2 * (size_t)sizes[k][0] * sizes[k][1];
    }
    struct tess_caps cap = {0, 0};
    int rc = neighbour_counts(patches, n, (const int(*)[2])sizes, counts);
    if (!rc && mem_reserve((void **)&out->tri, &cap.t, nt ? nt : 1, sizeof *out->tri))
        rc = SF_ENOMEM;
    for (size_t k = 0; k < n && !rc; k++) {
        const struct patch *pt = &patches[k];
        const int gu = sizes[k][0], gv = sizes[k][1];
        size_t base = out->n_verts;
        for (int i = 0; i <= gu && !rc; i++)
            for (int j = 0; j <= gv && !rc; j++)
                rc = add_vertex(out, &cap, pt, (int)k, (double)i / gu, (double)j / gv);
        for (int s = 0; s < 4 && !rc; s++)
            snap_side(out, base, pt, gu, gv, s, counts[4 * k + s]);
        for (int i = 0; i < gu && !rc; i++)
            for (int j = 0; j < gv && !rc; j++) {
                unsigned a = (unsigned)(base + (size_t)i * (gv + 1) + j), b = a + (unsigned)(gv + 1);
                const unsigned tri[2][3] = {{a, b, b + 1}, {a, b + 1, a + 1}};
                for (int h = 0; h < 2 && !rc; h++) {
                    if (!pt->trim) {
                        rc = add_tri(out, &cap, tri[h][0], tri[h][1], tri[h][2]);
                        continue;
                    }
                    const double u0 = (double)i / gu, u1 = (double)(i + 1) / gu, w0 = (double)j / gv,
                                 w1 = (double)(j + 1) / gv;
                    const double uv[2][3][2] = {{{u0, w0}, {u1, w0}, {u1, w1}}, {{u0, w0}, {u1, w1}, {u0, w1}}};
                    rc = trim_tri(out, &cap, pt, (int)k, uv[h], tri[h], tol, 0);
                }
            }
    }
    free(sizes);
    free(counts);
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
