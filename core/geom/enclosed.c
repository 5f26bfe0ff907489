/* enclosed.c - volume and closure of a patch set (enclosed.h). */
#include "enclosed.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <stdint.h>
#include <string.h>

#include "../base/gauss.h"
#include "../base/mem.h"
#include "trim.h"

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

/* Eq. 21–22 and the area over the box [a0, a1] x [b0, b1] of patch pt by nu x nv Gauss nodes;
 * all: every node counts, else only those the trim region holds. */
static void box_measure(const struct patch *pt, double a0, double a1, double b0, double b1, int nu, int nv,
                        bool all, double *volume, double *area)
{
    double X[GL_MAX], W[GL_MAX], Y[GL_MAX], V[GL_MAX];
    gauss_legendre(nu, X, W);
    gauss_legendre(nv, Y, V);
    const double ju = a1 - a0, jv = b1 - b0;
    for (int a = 0; a < nu; a++)
        for (int b = 0; b < nv; b++) {
            double u = a0 + ju * X[a], v = b0 + jv * Y[b];
            if (!all && !bezier_kept(pt, u, v))
                continue;
            vec3 P, Pu, Pv;
            bezier_eval(pt, u, v, &P, &Pu, &Pv);
            double A = Pu.y * Pv.z - Pu.z * Pv.y, B = Pu.z * Pv.x - Pu.x * Pv.z, w = W[a] * V[b] * ju * jv;
            *volume += 0.5 * w * (A * P.x + B * P.y); /* seed 000 eq. 21–22 */
            *area += w * v3_len(v3_cross(Pu, Pv));
        }
}

/* The same over the part of the box its patch's trim region holds: boxes wholly inside by the
 * full rule, those a loop cuts split down to TRIM_DEPTH levels, then each smallest box's part in
 * the region taken exactly in (u, v) (trim_box_moments) with the integrand at its centroid: the
 * error is the integrand's curvature over a box 2^-TRIM_DEPTH of the patch across. (Counting the
 * Gauss nodes inside instead was 0.07 % off on a square trim along the (u, v) lines: the nodes
 * fall at the same place in every box along such a loop.) */
#define TRIM_DEPTH 8
static void trimmed_measure(const struct patch *pt, double a0, double a1, double b0, double b1, int nu, int nv,
                            int depth, double *volume, double *area)
{
    double su = pt->u1 - pt->u0, sv = pt->v1 - pt->v0;
    enum trim_class c = trim_classify(pt->trim, pt->u0 + a0 * su, pt->u0 + a1 * su, pt->v0 + b0 * sv, pt->v0 + b1 * sv);
    if (c == TRIM_OUT)
        return;
    if (c == TRIM_IN) {
        box_measure(pt, a0, a1, b0, b1, nu, nv, true, volume, area);
        return;
    }
    double at[2], uv_area = -1.0;
    if (depth >= TRIM_DEPTH &&
        (uv_area = trim_box_moments(pt->trim, pt->u0 + a0 * su, pt->u0 + a1 * su, pt->v0 + b0 * sv, pt->v0 + b1 * sv,
                                    at)) >= 0.0) {
        vec3 P, Pu, Pv;
        double u = (at[0] - pt->u0) / su, v = (at[1] - pt->v0) / sv, w = uv_area / (su * sv);
        bezier_eval(pt, u, v, &P, &Pu, &Pv);
        double A = Pu.y * Pv.z - Pu.z * Pv.y, B = Pu.z * Pv.x - Pu.x * Pv.z;
        *volume += 0.5 * w * (A * P.x + B * P.y); /* seed 000 eq. 21–22 */
        *area += w * v3_len(v3_cross(Pu, Pv));
        return;
    }
    if (depth >= 2 * TRIM_DEPTH) { /* more loop segments in one box than trim_box_moments takes */
        box_measure(pt, a0, a1, b0, b1, 6, 6, false, volume, area);
        return;
    }
    double am = 0.5 * (a0 + a1), bm = 0.5 * (b0 + b1);
    trimmed_measure(pt, a0, am, b0, bm, nu, nv, depth + 1, volume, area);
    trimmed_measure(pt, am, a1, b0, bm, nu, nv, depth + 1, volume, area);
    trimmed_measure(pt, a0, am, bm, b1, nu, nv, depth + 1, volume, area);
    trimmed_measure(pt, am, a1, bm, b1, nu, nv, depth + 1, volume, area);
}

int enclosed_measure(const struct patch_set *ps, struct enclosed *e)
{
    return enclosed_measure_objects(ps, e, NULL, NULL, 0);
}

int enclosed_measure_objects(const struct patch_set *ps, struct enclosed *e, double *object_volume, double *object_area,
                             int n_objects)
{
    memset(e, 0, sizeof *e);
    e->open_object = -1;
    for (int d = 0; d < 3; d++)
        e->lo[d] = INFINITY, e->hi[d] = -INFINITY;
    bool trimmed = false;
    for (int k = 0; k < n_objects; k++)
        object_volume[k] = object_area[k] = 0.0;
    for (size_t k = 0; k < ps->n; k++) {
        const struct patch *pt = &ps->patches[k];
        vec3 lo, hi;
        bezier_bounds(pt, &lo, &hi);
        e->lo[0] = fmin(e->lo[0], lo.x), e->lo[1] = fmin(e->lo[1], lo.y), e->lo[2] = fmin(e->lo[2], lo.z);
        e->hi[0] = fmax(e->hi[0], hi.x), e->hi[1] = fmax(e->hi[1], hi.y), e->hi[2] = fmax(e->hi[2], hi.z);
        int nu = nodes_for(pt->p, pt->rational), nv = nodes_for(pt->q, pt->rational);
        double volume = 0.0, area = 0.0;
        if (pt->trim)
            trimmed_measure(pt, 0, 1, 0, 1, nu, nv, 0, &volume, &area);
        else
            box_measure(pt, 0, 1, 0, 1, nu, nv, true, &volume, &area);
        trimmed |= pt->trim != NULL;
        e->volume += volume;
        e->area += area;
        if (pt->surface < n_objects)
            object_volume[pt->surface] += volume, object_area[pt->surface] += area;
    }
    if (trimmed) /* trimmed patches close along their loops, not edge to edge: enclosed_shell() tells */
        return 0;
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

/* ---- trimmed surfaces: closure along the loops ------------------------------------------ */

#define SHELL_EDGE_POINTS 64 /* at most, along each edge of an untrimmed domain (then halved as add_seg needs) */
#define SHELL_EDGE_STEP 50.0   /* ... one every this many tol along it, at least 4 */
#define SHELL_MAX_ENTRIES (1u << 26)
#define SHELL_PARALLEL 0.9     /* chords whose directions' cosine is under this cross: no facing read */

struct bseg { /* one boundary segment, in (u, v) and its chord in space */
    double a[2], b[2];
    vec3 pa, pb;
    int part, loop;
    int side;        /* an untrimmed domain's edge (0-3), or -1 on a trim loop */
    size_t index;    /* within its loop */
    size_t loop_len;
};

/* Cells of side `cell` from lo, hashed into buckets (a power of two; cells that share a bucket
 * only add candidates, each tested by its distance). */
struct seg_grid {
    vec3 lo;
    double cell;
    size_t buckets;
    uint32_t *first, *seg;
};

static void cell_of(const struct seg_grid *g, vec3 p, int c[3])
{
    const double q[3] = {p.x - g->lo.x, p.y - g->lo.y, p.z - g->lo.z};
    for (int d = 0; d < 3; d++) {
        double f = floor(q[d] / g->cell);
        c[d] = f < 0 ? 0 : f > 1e6 ? 1000000 : (int)f;
    }
}

static size_t bucket_of(const struct seg_grid *g, const int c[3])
{
    uint64_t h = (uint64_t)c[0] * 0x9e3779b97f4a7c15ull ^ (uint64_t)c[1] * 0xc2b2ae3d27d4eb4full ^
                 (uint64_t)c[2] * 0x165667b19e3779f9ull;
    return (size_t)((h ^ h >> 29) & (g->buckets - 1));
}

/* Bins each segment into the cells its box grown by tol meets, a long one piece by piece (pieces of
 * a cell at most, so that its entries go as its length, not as its box's volume); counting when at
 * is NULL, and then only up to SHELL_MAX_ENTRIES (past it the count is all the caller needs). */
static size_t grid_bin(struct seg_grid *g, const struct bseg *segs, size_t n, double tol, uint32_t *at)
{
    size_t total = 0;
    const vec3 t = v3(tol, tol, tol);
    for (size_t k = 0; k < n; k++) {
        vec3 d = v3_sub(segs[k].pb, segs[k].pa);
        double pieces = ceil(v3_len(d) / g->cell);
        int np = pieces > 1 ? (int)fmin(pieces, 1e6) : 1;
        for (int i = 0; i < np; i++) {
            vec3 a = v3_add(segs[k].pa, v3_scale(d, (double)i / np)), b = v3_add(segs[k].pa, v3_scale(d, (i + 1.0) / np));
            int c0[3], c1[3];
            cell_of(g, v3_sub(v3_min(a, b), t), c0);
            cell_of(g, v3_add(v3_max(a, b), t), c1);
            for (int x = c0[0]; x <= c1[0]; x++)
                for (int y = c0[1]; y <= c1[1]; y++)
                    for (int z = c0[2]; z <= c1[2]; z++) {
                        size_t c = bucket_of(g, (int[3]){x, y, z});
                        if (at)
                            g->seg[at[c]++] = (uint32_t)k;
                        else if (++total > SHELL_MAX_ENTRIES)
                            return total;
                        else
                            g->first[c + 1]++;
                    }
        }
    }
    return total;
}

/* The (u, v) segment a-b as chords in space, halved until each is within tol / 4 of the surface's
 * curve over it (a straight line in (u, v) is an arc round a cylinder). */
static int add_seg(struct bseg **segs, size_t *n, size_t *cap, const struct surface *s, const double a[2],
                   const double b[2], vec3 pa, vec3 pb, double tol, int depth, int part, int loop)
{
    const double m[2] = {0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])};
    vec3 pm;
    nurbs_eval(s, m[0], m[1], &pm, NULL, NULL);
    if (depth < 12 && v3_len(v3_sub(pm, v3_scale(v3_add(pa, pb), 0.5))) > 0.25 * tol) {
        int rc = add_seg(segs, n, cap, s, a, m, pa, pm, tol, depth + 1, part, loop);
        return rc ? rc : add_seg(segs, n, cap, s, m, b, pm, pb, tol, depth + 1, part, loop);
    }
    if (mem_reserve((void **)segs, cap, *n + 1, sizeof **segs))
        return SF_ENOMEM;
    struct bseg *g = &(*segs)[(*n)++];
    memcpy(g->a, a, sizeof g->a);
    memcpy(g->b, b, sizeof g->b);
    g->pa = pa, g->pb = pb;
    g->part = part, g->loop = loop, g->side = -1;
    return 0;
}

static int add_uv_seg(struct bseg **segs, size_t *n, size_t *cap, const struct surface *s, const double a[2],
                      const double b[2], double tol, int part, int loop)
{
    vec3 pa, pb;
    nurbs_eval(s, a[0], a[1], &pa, NULL, NULL);
    nurbs_eval(s, b[0], b[1], &pb, NULL, NULL);
    return add_seg(segs, n, cap, s, a, b, pa, pb, tol, 0, part, loop);
}

/* Every part's boundary as segments: its trim loops, or its domain's four edges as one loop. 0,
 * SF_ENOMEM, or SF_ECANCEL when pr asks. */
static int boundary_segments(const struct shell_part *parts, int n, double tol, const struct sf_progress *pr,
                             struct bseg **segs, size_t *n_segs)
{
    size_t cap = 0;
    *segs = NULL;
    *n_segs = 0;
    int loop = 0;
    for (int k = 0; k < n; k++, loop++) {
        const struct trim *t = parts[k].t;
        size_t first = *n_segs;
        if (t) {
            for (int l = 0; l < t->n_loops; l++, loop++) {
                first = *n_segs;
                for (size_t i = t->start[l]; i + 1 < t->start[l + 1]; i++) {
                    if (i % 4096 == 0 && sf_poll(pr, 0, NULL))
                        return SF_ECANCEL;
                    if (add_uv_seg(segs, n_segs, &cap, parts[k].s, t->pt[i], t->pt[i + 1], tol, k, loop))
                        return SF_ENOMEM;
                }
                for (size_t i = first; i < *n_segs; i++)
                    (*segs)[i].index = i - first, (*segs)[i].loop_len = *n_segs - first;
            }
            continue;
        }
        double u0, u1, v0, v1;
        nurbs_domain(parts[k].s, &u0, &u1, &v0, &v1);
        const double corner[5][2] = {{u0, v0}, {u1, v0}, {u1, v1}, {u0, v1}, {u0, v0}};
        for (int e = 0; e < 4; e++) {
            double len = 0; /* the edge's length, roughly: 8 chords */
            vec3 q0, q1;
            nurbs_eval(parts[k].s, corner[e][0], corner[e][1], &q0, NULL, NULL);
            for (int i = 1; i <= 8; i++, q0 = q1) {
                nurbs_eval(parts[k].s, corner[e][0] + i / 8.0 * (corner[e + 1][0] - corner[e][0]),
                           corner[e][1] + i / 8.0 * (corner[e + 1][1] - corner[e][1]), &q1, NULL, NULL);
                len += v3_len(v3_sub(q1, q0));
            }
            int np = (int)fmin(SHELL_EDGE_POINTS, fmax(4.0, ceil(len / (SHELL_EDGE_STEP * tol))));
            size_t first_of_side = *n_segs;
            for (int i = 0; i < np; i++) {
                double f0 = (double)i / np, f1 = (double)(i + 1) / np;
                const double a[2] = {corner[e][0] + f0 * (corner[e + 1][0] - corner[e][0]),
                                     corner[e][1] + f0 * (corner[e + 1][1] - corner[e][1])};
                const double b[2] = {corner[e][0] + f1 * (corner[e + 1][0] - corner[e][0]),
                                     corner[e][1] + f1 * (corner[e + 1][1] - corner[e][1])};
                if (add_uv_seg(segs, n_segs, &cap, parts[k].s, a, b, tol, k, loop))
                    return SF_ENOMEM;
            }
            for (size_t i = first_of_side; i < *n_segs; i++)
                (*segs)[i].side = e;
        }
        for (size_t i = first; i < *n_segs; i++)
            (*segs)[i].index = i - first, (*segs)[i].loop_len = *n_segs - first;
    }
    return 0;
}

/* Distance from p to the chord of g, and where along it (0..1). */
static double seg_dist(const struct bseg *g, vec3 p, double *at) { return v3_seg_dist(g->pa, g->pb, p, at); }

/* The sign of (N × e) · inward at (u, v) of part k, inward the way into its region across the
 * boundary direction t (in (u, v)): +1 or -1, 0 where undefined. */
static int facing(const struct shell_part *part, const double uv[2], const double t[2], vec3 e)
{
    vec3 P, Su, Sv;
    nurbs_eval(part->s, uv[0], uv[1], &P, &Su, &Sv);
    double u0, u1, v0, v1;
    nurbs_domain(part->s, &u0, &u1, &v0, &v1);
    double len = hypot(t[0], t[1]), step = 1e-5 * hypot(u1 - u0, v1 - v0);
    if (!(len > 0))
        return 0;
    double nl[2] = {-t[1] / len, t[0] / len}, q[2] = {uv[0] + step * nl[0], uv[1] + step * nl[1]};
    bool left_in = part->t ? trim_contains(part->t, q[0], q[1]) : q[0] >= u0 && q[0] <= u1 && q[1] >= v0 && q[1] <= v1;
    double s = left_in ? 1.0 : -1.0;
    vec3 inward = v3_add(v3_scale(Su, s * nl[0]), v3_scale(Sv, s * nl[1]));
    double f = v3_dot(v3_cross(v3_cross(Su, Sv), e), inward);
    return (f > 0) - (f < 0);
}

struct vote {
    int a, b;   /* parts, a < b */
    int same;   /* +1: they face alike here, -1: opposite */
};

static int by_pair(const void *x, const void *y)
{
    const struct vote *p = x, *q = y;
    return p->a != q->a ? (p->a > q->a) - (p->a < q->a) : (p->b > q->b) - (p->b < q->b);
}

/* Whether a and b are the same stretch of one loop: one edge of an untrimmed domain, or at most
 * two segments apart along a trim loop, running the same way (a loop that doubles back on itself,
 * a spike of a contour, has two stretches there). */
static bool along(const struct bseg *a, const struct bseg *b)
{
    if (a->loop != b->loop || v3_dot(v3_sub(a->pb, a->pa), v3_sub(b->pb, b->pa)) < 0)
        return false;
    if (a->side >= 0)
        return a->side == b->side;
    size_t di = a->index > b->index ? a->index - b->index : b->index - a->index;
    return di <= 2 || a->loop_len - di <= 2;
}

int enclosed_shell(const struct shell_part *parts, int n, double tol, const struct sf_progress *pr, struct shell *out,
                   signed char *sign)
{
    memset(out, 0, sizeof *out);
    out->open_object = -1;
    struct bseg *segs;
    size_t n_segs;
    int rc = boundary_segments(parts, n, tol, pr, &segs, &n_segs);
    struct seg_grid g = {0};
    struct vote *votes = NULL;
    size_t n_votes = 0, cap_votes = 0;
    uint32_t *at = NULL;
    if (rc || n_segs == 0)
        goto done;
    vec3 lo = v3(INFINITY, INFINITY, INFINITY), hi = v3(-INFINITY, -INFINITY, -INFINITY);
    for (size_t k = 0; k < n_segs; k++)
        lo = v3_min(lo, v3_min(segs[k].pa, segs[k].pb)), hi = v3_max(hi, v3_max(segs[k].pa, segs[k].pb));
    /* cells twice the mean chord (4 tol at least): a few cells a chord, a few chords a cell */
    double mean = 0;
    for (size_t k = 0; k < n_segs; k++)
        mean += v3_len(v3_sub(segs[k].pb, segs[k].pa)) / (double)n_segs;
    vec3 size = v3_sub(hi, lo);
    g.lo = lo;
    g.cell = fmax(fmax(2 * mean, 4.0 * tol), fmax(size.x, fmax(size.y, size.z)) / 1e6);
    for (g.buckets = 1024; g.buckets < 2 * n_segs && g.buckets < SHELL_MAX_ENTRIES; g.buckets *= 2)
        ;
    size_t cells = g.buckets;
    g.first = calloc(cells + 1, sizeof *g.first);
    if (!g.first || grid_bin(&g, segs, n_segs, tol, NULL) > SHELL_MAX_ENTRIES) {
        rc = SF_ENOMEM;
        goto done;
    }
    for (size_t c = 0; c < cells; c++)
        g.first[c + 1] += g.first[c];
    g.seg = malloc(sizeof *g.seg * (g.first[cells] + 1));
    at = malloc(sizeof *at * cells);
    if (!g.seg || !at) {
        rc = SF_ENOMEM;
        goto done;
    }
    memcpy(at, g.first, sizeof *at * cells);
    /* what matching will cost, decided before it: a point is tested against every segment of its
     * cell, so about the sum over cells of their segments squared (a few tens a segment for real
     * parts, thousands where a hostile part crowds its loops together) */
    for (size_t c = 0; c < cells; c++)
        out->tests += (double)(g.first[c + 1] - g.first[c]) * (double)(g.first[c + 1] - g.first[c]);
    if (out->tests > SHELL_MAX_TESTS) {
        rc = SF_ELIMIT;
        goto done;
    }
    grid_bin(&g, segs, n_segs, tol, at);
    const double collapsed = 1e-3 * tol;
    for (size_t k = 0; k < n_segs; k++) {
        const struct bseg *s = &segs[k];
        if (k % 64 == 0 && (rc = sf_poll(pr, (double)k / (double)n_segs, NULL)))
            goto done;
        if (v3_len(v3_sub(s->pb, s->pa)) <= collapsed)
            continue; /* a pole: no partner needed */
        double mid[2] = {0.5 * (s->a[0] + s->b[0]), 0.5 * (s->a[1] + s->b[1])};
        vec3 p;
        nurbs_eval(parts[s->part].s, mid[0], mid[1], &p, NULL, NULL);
        out->samples++;
        int c[3];
        cell_of(&g, p, c);
        size_t cell = bucket_of(&g, c);
        const struct bseg *best = NULL;
        double best_d = tol, best_f = 0;
        bool own = false; /* another stretch of one surface's boundary within tol too */
        for (uint32_t e = g.first[cell]; e < g.first[cell + 1]; e++) {
            const struct bseg *o = &segs[g.seg[e]];
            if (along(o, s)) /* its own loop: only far along it (a seam run up and back) */
                continue;
            if (v3_len(v3_sub(o->pb, o->pa)) <= collapsed)
                continue;
            double f, d = seg_dist(o, p, &f);
            own |= o->part == s->part && d <= tol;
            if (d <= best_d)
                best = o, best_d = d, best_f = f;
        }
        if (!best) {
            if (!out->open_samples++) {
                out->open_object = s->part;
                out->open_at[0] = p.x, out->open_at[1] = p.y, out->open_at[2] = p.z;
            }
            continue;
        }
        for (uint32_t e = g.first[cell]; e < g.first[cell + 1] && !own; e++) {
            const struct bseg *o = &segs[g.seg[e]];
            own = o->part == best->part && !along(o, best) && v3_len(v3_sub(o->pb, o->pa)) > collapsed &&
                  seg_dist(o, p, &(double){0}) <= tol;
        }
        if (own)
            continue; /* matched, but which way the two face is not to be read here: a surface
                       * whose opposite edges come within tol of each other (a sliver between two
                       * slices, a seam) has both on its neighbour */
        vec3 e = v3_sub(s->pb, s->pa), eb = v3_sub(best->pb, best->pa);
        if (fabs(v3_dot(e, eb)) < SHELL_PARALLEL * v3_len(e) * v3_len(eb))
            continue; /* boundaries that cross (where two rings do, in a plane of branchings) meet at a
                       * point: which way the two face is not to be read there either */
        const double ts[2] = {s->b[0] - s->a[0], s->b[1] - s->a[1]}, tb[2] = {best->b[0] - best->a[0], best->b[1] - best->a[1]};
        const double ub[2] = {best->a[0] + best_f * tb[0], best->a[1] + best_f * tb[1]};
        int fa = facing(&parts[s->part], mid, ts, e), fb = facing(&parts[best->part], ub, tb, e);
        if (!fa || !fb)
            continue;
        if (mem_reserve((void **)&votes, &cap_votes, n_votes + 1, sizeof *votes)) {
            rc = SF_ENOMEM;
            goto done;
        }
        int a = s->part < best->part ? s->part : best->part, b = s->part ^ best->part ^ a;
        votes[n_votes++] = (struct vote){a, b, fa == fb ? -1 : 1};
        out->flipped += fa == fb;
    }
    /* each pair's verdict by majority, then signs spread from part 0 over the pairs */
    if (n_votes)
        qsort(votes, n_votes, sizeof *votes, by_pair);
    size_t n_pairs = 0;
    for (size_t k = 0; k < n_votes;) {
        size_t j = k;
        int sum = 0;
        while (j < n_votes && votes[j].a == votes[k].a && votes[j].b == votes[k].b)
            sum += votes[j++].same;
        votes[n_pairs++] = (struct vote){votes[k].a, votes[k].b, sum >= 0 ? 1 : -1};
        k = j;
    }
    /* breadth first over the pairs of each part (both ways, counting sort) */
    size_t *first = calloc((size_t)n + 1, sizeof *first), *adj = malloc(sizeof *adj * (2 * n_pairs + 1));
    int *queue = malloc(sizeof *queue * ((size_t)n + 1));
    if (!first || !adj || !queue) {
        free(first), free(adj), free(queue);
        rc = SF_ENOMEM;
        goto done;
    }
    for (size_t k = 0; k < n_pairs; k++)
        first[votes[k].a + 1]++, first[votes[k].b + 1]++;
    for (int k = 0; k < n; k++)
        first[k + 1] += first[k];
    for (size_t k = 0; k < n_pairs; k++)
        adj[first[votes[k].a]++] = k, adj[first[votes[k].b]++] = k;
    for (int k = n; k > 0; k--) /* (the fill moved each start to the next part's) */
        first[k] = first[k - 1];
    first[0] = 0;
    for (int k = 0; k < n; k++)
        sign[k] = 0;
    for (int root = 0; root < n; root++) {
        if (sign[root])
            continue;
        sign[root] = 1;
        size_t head = 0, tail = 0;
        queue[tail++] = root;
        while (head < tail) {
            int a = queue[head++];
            for (size_t i = first[a]; i < first[a + 1]; i++) {
                const struct vote *v = &votes[adj[i]];
                int b = v->a == a ? v->b : v->a;
                if (!sign[b])
                    sign[b] = (signed char)(sign[a] * v->same), queue[tail++] = b;
            }
        }
    }
    free(first), free(adj), free(queue);
    for (size_t k = 0; k < n_pairs; k++)
        out->conflicts += sign[votes[k].a] * sign[votes[k].b] != votes[k].same;
done:
    free(segs);
    free(g.first);
    free(g.seg);
    free(at);
    free(votes);
    return rc;
}
