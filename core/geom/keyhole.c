/* keyhole.c - holes cut into their outer loops along zero-width channels (keyhole.h). Nesting by
 * even-odd from one probe point per loop; each hole, the rightmost first, bridged from its
 * rightmost vertex to the nearest vertex of the polygon so far that sees it: inside both corners
 * (the polygon's and the hole's) and touching no edge of the polygon or of the holes still to
 * come (Eberly, "Triangulation by Ear Clipping", 2002, section 3, with visibility tested
 * directly rather than by his ray and reflex-vertex rule, which assumes general position: a
 * section of an isosurface has vertices on grid lines, many on the ray). */
#include "keyhole.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

typedef double pt2[2];

/* twice the signed area of abc: > 0 counter-clockwise */
static double orient(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

static bool same(const double *a, const double *b) { return a[0] == b[0] && a[1] == b[1]; }

/* c on the closed segment ab, given abc collinear */
static bool on_segment(const double *a, const double *b, const double *c)
{
    return fmin(a[0], b[0]) <= c[0] && c[0] <= fmax(a[0], b[0]) && fmin(a[1], b[1]) <= c[1] && c[1] <= fmax(a[1], b[1]);
}

/* Whether segment pq (a bridge) meets edge ab anywhere but at an end they share by value: two
 * segments that are not in line and share an end meet only there. */
static bool blocks(const double *p, const double *q, const double *a, const double *b)
{
    double o1 = orient(p, q, a), o2 = orient(p, q, b), o3 = orient(a, b, p), o4 = orient(a, b, q);
    bool shared = same(a, p) || same(a, q) || same(b, p) || same(b, q);
    if (shared) /* only an overlap in line blocks */
        return o1 == 0 && o2 == 0 &&
               ((!same(a, p) && !same(a, q) && on_segment(p, q, a)) || (!same(b, p) && !same(b, q) && on_segment(p, q, b)) ||
                (!same(p, a) && !same(p, b) && on_segment(a, b, p)) || (!same(q, a) && !same(q, b) && on_segment(a, b, q)));
    if (((o1 > 0 && o2 < 0) || (o1 < 0 && o2 > 0)) && ((o3 > 0 && o4 < 0) || (o3 < 0 && o4 > 0)))
        return true;
    return (o1 == 0 && on_segment(p, q, a)) || (o2 == 0 && on_segment(p, q, b)) || (o3 == 0 && on_segment(a, b, p)) ||
           (o4 == 0 && on_segment(a, b, q));
}

/* Whether the direction from v to m enters the region at corner a -> v -> b, the region on the
 * left of the loop (counter-clockwise round an outer loop, clockwise round a hole). */
static bool in_corner(const double *a, const double *v, const double *b, const double *m)
{
    if (orient(a, v, b) >= 0) /* convex (or straight): left of both edges */
        return orient(a, v, m) > 0 && orient(v, b, m) > 0;
    return orient(a, v, m) > 0 || orient(v, b, m) > 0;
}

/* even-odd: point q inside the loop of n points p */
static bool inside(const pt2 *p, int n, const double *q)
{
    bool in = false;
    for (int i = 0, j = n - 1; i < n; j = i++)
        if ((p[i][1] > q[1]) != (p[j][1] > q[1]) &&
            q[0] < p[j][0] + (q[1] - p[j][1]) / (p[i][1] - p[j][1]) * (p[i][0] - p[j][0]))
            in = !in;
    return in;
}

static double area(const pt2 *p, int n)
{
    double a = 0;
    for (int i = 0, j = n - 1; i < n; j = i++)
        a += p[j][0] * p[i][1] - p[i][0] * p[j][1];
    return a / 2;
}

struct poly { /* the polygon being grown: an outer loop and the holes bridged into it */
    pt2 *p;
    int n, cap;
};

static int poly_push(struct poly *g, const double *q)
{
    if (g->n == g->cap) {
        int cap = g->cap ? 2 * g->cap : 64;
        pt2 *p = realloc(g->p, sizeof *p * (size_t)cap);
        if (!p)
            return SF_ENOMEM;
        g->p = p, g->cap = cap;
    }
    g->p[g->n][0] = q[0], g->p[g->n][1] = q[1];
    g->n++;
    return 0;
}

struct cand {
    double d;
    int i;
};

static int by_distance(const void *a, const void *b)
{
    const struct cand *x = a, *y = b;
    return x->d != y->d ? (x->d > y->d) - (x->d < y->d) : x->i - y->i;
}

struct plane { /* the input's loops, read-only, and what the nesting found */
    const struct trimesh_loops *in;
    int *depth, *parent;
    double *area;
    double (*box)[4];        /* each loop's x0, y0, x1, y1 */
    long tests, max_tests;   /* the tests made, and the cap */
};

static const pt2 *loop_at(const struct plane *pl, int k) { return (const pt2 *)pl->in->p + pl->in->start[k]; }
static int loop_n(const struct plane *pl, int k) { return pl->in->start[k + 1] - pl->in->start[k]; }

/* Loop k's point i as the polygon takes it: holes clockwise, outer loops counter-clockwise. */
static const double *loop_point(const struct plane *pl, int k, int i, bool ccw)
{
    int n = loop_n(pl, k);
    return loop_at(pl, k)[(pl->area[k] > 0) == ccw ? i : n - 1 - i];
}

/* The vertex of g that sees hole h's point m (index mi, the hole read clockwise), nearest first;
 * -1 when none does. holes[0..n_holes) are the holes not yet bridged (h among them). */
static int bridge_vertex(struct plane *pl, const struct poly *g, int h, int mi, const int *holes, int n_holes,
                         struct cand *c, int *rc)
{
    int hn = loop_n(pl, h);
    const double *m = loop_point(pl, h, mi, false), *ma = loop_point(pl, h, (mi + hn - 1) % hn, false),
                 *mb = loop_point(pl, h, (mi + 1) % hn, false);
    long edges = g->n;
    for (int k = 0; k < n_holes; k++)
        edges += loop_n(pl, holes[k]);
    for (int i = 0; i < g->n; i++)
        c[i] = (struct cand){hypot(g->p[i][0] - m[0], g->p[i][1] - m[1]), i};
    qsort(c, (size_t)g->n, sizeof *c, by_distance);
    for (int t = 0; t < g->n; t++) {
        int v = c[t].i;
        const double *pv = g->p[v], *a = g->p[(v + g->n - 1) % g->n], *b = g->p[(v + 1) % g->n];
        if (c[t].d == 0) /* the hole touches the polygon here: a channel of no length */
            return v;
        if (!in_corner(a, pv, b, m) || !in_corner(ma, m, mb, pv))
            continue;
        if ((pl->tests += edges) > pl->max_tests) {
            *rc = SF_ELIMIT;
            return -1;
        }
        bool seen = true;
        for (int i = 0; seen && i < g->n; i++)
            seen = !blocks(m, pv, g->p[i], g->p[(i + 1) % g->n]);
        for (int k = 0; seen && k < n_holes; k++) {
            const pt2 *q = loop_at(pl, holes[k]);
            int qn = loop_n(pl, holes[k]);
            for (int i = 0; seen && i < qn; i++)
                seen = !blocks(m, pv, q[i], q[(i + 1) % qn]);
        }
        if (seen)
            return v;
    }
    return -1;
}

static double max_x(const struct plane *pl, int k, int *at)
{
    const pt2 *p = loop_at(pl, k);
    int n = loop_n(pl, k), best = 0;
    for (int i = 1; i < n; i++)
        if (p[i][0] > p[best][0] || (p[i][0] == p[best][0] && p[i][1] > p[best][1]))
            best = i;
    if (at)
        *at = best;
    return p[best][0];
}

static int by_max_x(const void *a, const void *b)
{
    const struct cand *x = a, *y = b; /* d: the hole's rightmost x; i: the hole */
    return x->d != y->d ? (x->d < y->d) - (x->d > y->d) : x->i - y->i;
}

/* Depth and innermost container of every loop, from a probe point on its first edge. */
static int nest(struct plane *pl)
{
    int n = pl->in->n;
    for (int k = 0; k < n; k++) {
        const pt2 *p = loop_at(pl, k);
        double q[2] = {(p[0][0] + p[1][0]) / 2, (p[0][1] + p[1][1]) / 2}, best = INFINITY;
        pl->depth[k] = 0, pl->parent[k] = -1;
        for (int j = 0; j < n; j++) {
            const double *b = pl->box[j];
            if (j == k || q[0] < b[0] || q[0] > b[2] || q[1] < b[1] || q[1] > b[3])
                continue;
            if ((pl->tests += loop_n(pl, j)) > pl->max_tests)
                return SF_ELIMIT;
            if (inside(loop_at(pl, j), loop_n(pl, j), q)) {
                pl->depth[k]++;
                if (fabs(pl->area[j]) < best)
                    best = fabs(pl->area[j]), pl->parent[k] = j;
            }
        }
    }
    return 0;
}

static int out_push_loop(struct trimesh_loops *out, int *cap_p, int *cap_l, const pt2 *p, int n)
{
    int need = out->start[out->n] + n;
    if (need > *cap_p) {
        int cap = *cap_p;
        while (cap < need)
            cap = cap ? 2 * cap : 256;
        pt2 *q = realloc(out->p, sizeof *q * (size_t)cap);
        if (!q)
            return SF_ENOMEM;
        out->p = q, *cap_p = cap;
    }
    if (out->n + 2 > *cap_l) {
        int cap = 2 * *cap_l;
        int *s = realloc(out->start, sizeof *s * (size_t)cap);
        if (!s)
            return SF_ENOMEM;
        out->start = s, *cap_l = cap;
    }
    memcpy(out->p + out->start[out->n], p, sizeof *p * (size_t)n);
    out->start[out->n + 1] = need;
    out->n++;
    return 0;
}

int keyhole_join(const struct trimesh_loops *in, long max_tests, struct trimesh_loops *out, int *n_apart,
                 struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    if (n_apart)
        *n_apart = 0;
    int n = in->n, rc = 0, cap_p = 0, cap_l = 8, *holes = NULL;
    struct plane pl = {in, calloc((size_t)n + 1, sizeof(int)), calloc((size_t)n + 1, sizeof(int)),
                       calloc((size_t)n + 1, sizeof(double)), calloc((size_t)n + 1, sizeof(double[4])), 0, max_tests};
    struct poly g = {0};
    struct cand *c = NULL;
    out->start = calloc((size_t)cap_l, sizeof *out->start);
    holes = malloc(sizeof *holes * ((size_t)n + 1));
    if (!pl.depth || !pl.parent || !pl.area || !pl.box || !out->start || !holes) {
        rc = SF_ENOMEM;
        goto out_free;
    }
    for (int k = 0; k < n; k++) {
        const pt2 *p = loop_at(&pl, k);
        pl.area[k] = area(p, loop_n(&pl, k));
        double *b = pl.box[k];
        b[0] = b[2] = p[0][0], b[1] = b[3] = p[0][1];
        for (int i = 1; i < loop_n(&pl, k); i++)
            b[0] = fmin(b[0], p[i][0]), b[1] = fmin(b[1], p[i][1]), b[2] = fmax(b[2], p[i][0]), b[3] = fmax(b[3], p[i][1]);
    }
    if ((rc = nest(&pl)))
        goto out_free;
    for (int k = 0; k < n && !rc; k++) {
        if (pl.depth[k] % 2)
            continue;
        int n_holes = 0;
        for (int h = 0; h < n; h++)
            if (pl.depth[h] % 2 && pl.parent[h] == k)
                holes[n_holes++] = h;
        if (n_holes > 0) { /* the rightmost first (Eberly's order: the channels of those to its right are in place) */
            struct cand *order = malloc(sizeof *order * (size_t)n_holes);
            if (!order) {
                rc = SF_ENOMEM;
                break;
            }
            for (int t = 0; t < n_holes; t++)
                order[t] = (struct cand){max_x(&pl, holes[t], NULL), holes[t]};
            qsort(order, (size_t)n_holes, sizeof *order, by_max_x);
            for (int t = 0; t < n_holes; t++)
                holes[t] = order[t].i;
            free(order);
        }
        g.n = 0;
        for (int i = 0; i < loop_n(&pl, k) && !rc; i++)
            rc = poly_push(&g, loop_point(&pl, k, i, true));
        int apart0 = n_holes; /* holes[apart0..]: those no vertex saw, moved to the end */
        for (int t = 0; t < apart0 && !rc;) {
            int h = holes[t], hn = loop_n(&pl, h), mi, v;
            max_x(&pl, h, &mi); /* the rightmost point, read clockwise from where the loop starts */
            if (pl.area[h] > 0) /* read reversed: point mi of the loop is point hn - 1 - mi clockwise */
                mi = hn - 1 - mi;
            struct cand *grown = realloc(c, sizeof *c * (size_t)(g.n + 1));
            if (!grown) {
                rc = SF_ENOMEM;
                break;
            }
            c = grown;
            v = bridge_vertex(&pl, &g, h, mi, holes + t, apart0 - t, c, &rc);
            if (rc)
                break;
            if (v < 0) { /* kept apart: swap to the end of the holes still to bridge */
                holes[t] = holes[--apart0];
                holes[apart0] = h;
                continue;
            }
            /* g: ..., v, m, (the hole clockwise), m, v, ... */
            int extra = hn + 2, tail = g.n - v - 1;
            while (g.cap < g.n + extra && !rc) {
                pt2 *p = realloc(g.p, sizeof *p * (size_t)(g.cap = 2 * g.cap + extra));
                if (!p)
                    rc = SF_ENOMEM;
                else
                    g.p = p;
            }
            if (rc)
                break;
            memmove(g.p + v + 1 + extra, g.p + v + 1, sizeof *g.p * (size_t)tail);
            for (int i = 0; i <= hn; i++) {
                const double *q = loop_point(&pl, h, (mi + i) % hn, false);
                g.p[v + 1 + i][0] = q[0], g.p[v + 1 + i][1] = q[1];
            }
            g.p[v + hn + 2][0] = g.p[v][0], g.p[v + hn + 2][1] = g.p[v][1];
            g.n += extra;
            t++;
        }
        if (!rc)
            rc = out_push_loop(out, &cap_p, &cap_l, (const pt2 *)g.p, g.n);
        for (int t = apart0; t < n_holes && !rc; t++) {
            int h = holes[t], hn = loop_n(&pl, h);
            g.n = 0;
            for (int i = 0; i < hn && !rc; i++)
                rc = poly_push(&g, loop_point(&pl, h, i, false));
            if (!rc)
                rc = out_push_loop(out, &cap_p, &cap_l, (const pt2 *)g.p, g.n);
            if (n_apart)
                ++*n_apart;
        }
    }
out_free:
    free(c);
    free(g.p);
    free(holes);
    free(pl.depth);
    free(pl.parent);
    free(pl.area);
    free(pl.box);
    if (rc) {
        trimesh_loops_free(out);
        return rc == SF_ELIMIT ? sf_fail(err, SF_ELIMIT, "", "the section's loops would take over %ld tests to join "
                                         "their holes", max_tests)
                               : sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    return 0;
}
