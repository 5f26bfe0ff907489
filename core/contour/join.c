/* join.c - one surface where a contour model's tubes end and begin in the same plane (join.h).
 *
 * At a branching (one contour below, two above) the chains end with flat caps half a spacing out,
 * so the caps of the chain below and of those above lie in one plane and overlap: each tube is
 * closed, but the model is several shells touching there. In that plane the solid's surface is
 * where the solid below and the solid above differ: d(x, y) = the sum over the plane's caps of +1
 * (facing up: a tube ends below) or -1 (facing down: one begins above) where the point is inside
 * the cap's ring; d = +1 is surface facing up, d = -1 facing down, d = 0 none. The rings are
 * overlaid (split where they cross; a crossing this near a vertex is that vertex), each piece of a
 * ring is kept where d differs across it, the pieces are linked into loops round each region
 * (at a vertex of several, the first clockwise from where the loop came in), holes are bridged to
 * their outer loop, and the polygons ear-clipped; the walls' triangles on a split ring edge become
 * a fan through the crossings. The volume is unchanged (the overlap's two caps cancelled), and the
 * tubes are one shell.
 *
 * Written here, with the ear clipping of every flat end, because no packaged C library does it on
 * our vertices: polygon clipping libraries (Clipper, in Debian as C++) round to their own
 * coordinates and return new vertices, where the join must keep the rings' vertex ids so that the
 * walls stay joined to the plane's triangles; and ear clipping is the one triangulation the
 * polygons here (a cleaned contour's curve, a region with its holes bridged) need. */
#include "join.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/err.h"
#include "../base/mem.h"

#define JOIN_EPS 1e-9 /* of an edge's parameter: a crossing this near an end is at that end */

struct split {
    double t;
    unsigned v;
};

struct edge { /* ring edge k of cap c, and where other rings cross it */
    int c, k;
    struct split *s;
    size_t n, cap;
};

struct piece { /* a piece of a region's boundary, the region on its left */
    unsigned a, b;
    bool used;
};

struct list {
    unsigned *v;
    size_t n, cap;
};

struct join {
    struct solid_mesh *m;
    unsigned *alias; /* vertex -> the vertex it coincides with (itself mostly) */
    size_t cap_alias;
    struct list undo; /* aliases set in this plane: undone if it fails */
};

static const double *xy(const struct join *j, unsigned v) { return j->m->v[v]; }

static unsigned root(const struct join *j, unsigned v)
{
    while (j->alias[v] != v)
        v = j->alias[v];
    return v;
}

static int push(struct list *l, unsigned v)
{
    if (mem_reserve((void **)&l->v, &l->cap, l->n + 1, sizeof *l->v))
        return SF_ENOMEM;
    l->v[l->n++] = v;
    return 0;
}

static int new_vertex(struct join *j, double x, double y, double z, unsigned *out)
{
    struct solid_mesh *m = j->m;
    if (m->n_v >= UINT32_MAX || mem_reserve((void **)&m->v, &m->cap_v, m->n_v + 1, sizeof *m->v) ||
        mem_reserve((void **)&j->alias, &j->cap_alias, m->n_v + 1, sizeof *j->alias))
        return SF_ENOMEM;
    m->v[m->n_v][0] = x, m->v[m->n_v][1] = y, m->v[m->n_v][2] = z;
    j->alias[m->n_v] = (unsigned)m->n_v;
    *out = (unsigned)m->n_v++;
    return 0;
}

static double cross3(const double *a, const double *b, const double *c)
{
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
}

/* Whether (x, y) is inside the polygon of vertices v (crossing number). */
static bool in_loop(const struct join *j, const unsigned *v, size_t n, double x, double y)
{
    bool in = false;
    for (size_t k = 0, l = n - 1; k < n; l = k++) {
        const double *a = xy(j, v[k]), *b = xy(j, v[l]);
        if ((a[1] > y) != (b[1] > y) && x < a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1]))
            in = !in;
    }
    return in;
}

static int depth(const struct join *j, struct solid_cap *const *caps, int n, double x, double y)
{
    int d = 0;
    for (int c = 0; c < n; c++)
        if (in_loop(j, caps[c]->ring, (size_t)caps[c]->n, x, y))
            d += caps[c]->up ? 1 : -1;
    return d;
}

static int add_split(struct edge *e, double t, unsigned v)
{
    if (mem_reserve((void **)&e->s, &e->cap, e->n + 1, sizeof *e->s))
        return SF_ENOMEM;
    e->s[e->n++] = (struct split){t, v};
    return 0;
}

static int by_t(const void *a, const void *b)
{
    double x = ((const struct split *)a)->t, y = ((const struct split *)b)->t;
    return (x > y) - (x < y);
}

static void box_of(const struct join *j, const struct solid_cap *r, double b[4])
{
    b[0] = b[1] = INFINITY, b[2] = b[3] = -INFINITY;
    for (int k = 0; k < r->n; k++) {
        const double *p = xy(j, r->ring[k]);
        b[0] = fmin(b[0], p[0]), b[1] = fmin(b[1], p[1]), b[2] = fmax(b[2], p[0]), b[3] = fmax(b[3], p[1]);
    }
}

static bool boxes_meet(const double a[4], const double b[4])
{
    return a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3];
}

/* Where edges e1 and e2 of two rings cross: splits, a new vertex, or an alias where two vertices
 * coincide. 1 when they overlap along a stretch (the plane is left as it is). */
static int cross_edges(struct join *j, struct solid_cap *const *caps, struct edge *e1, struct edge *e2)
{
    const struct solid_cap *r1 = caps[e1->c], *r2 = caps[e2->c];
    unsigned A = r1->ring[e1->k], B = r1->ring[(e1->k + 1) % r1->n];
    unsigned C = r2->ring[e2->k], D = r2->ring[(e2->k + 1) % r2->n];
    const double *a = xy(j, A), *b = xy(j, B), *c = xy(j, C), *d = xy(j, D);
    if (fmax(a[0], b[0]) < fmin(c[0], d[0]) || fmax(c[0], d[0]) < fmin(a[0], b[0]) ||
        fmax(a[1], b[1]) < fmin(c[1], d[1]) || fmax(c[1], d[1]) < fmin(a[1], b[1]))
        return 0;
    double rx = b[0] - a[0], ry = b[1] - a[1], sx = d[0] - c[0], sy = d[1] - c[1], qx = c[0] - a[0], qy = c[1] - a[1];
    double den = rx * sy - ry * sx, lr = hypot(rx, ry), ls = hypot(sx, sy);
    if (fabs(den) <= 1e-12 * lr * ls) /* parallel: apart, or overlapping along a stretch */
        return fabs(qx * ry - qy * rx) <= 1e-9 * lr * (lr + ls) ? 1 : 0;
    double t = (qx * sy - qy * sx) / den, u = (qx * ry - qy * rx) / den;
    if (t < -JOIN_EPS || t > 1 + JOIN_EPS || u < -JOIN_EPS || u > 1 + JOIN_EPS)
        return 0;
    int end1 = t <= JOIN_EPS ? 0 : t >= 1 - JOIN_EPS ? 1 : -1, end2 = u <= JOIN_EPS ? 0 : u >= 1 - JOIN_EPS ? 1 : -1;
    unsigned v1 = end1 == 0 ? A : B, v2 = end2 == 0 ? C : D;
    if (end1 >= 0 && end2 >= 0) { /* two vertices at one point: one vertex */
        unsigned x = root(j, v1), y = root(j, v2);
        if (x != y) {
            j->alias[y] = x;
            return push(&j->undo, y) ? -1 : 0;
        }
        return 0;
    }
    if (end1 >= 0)
        return add_split(e2, u, v1) ? -1 : 0;
    if (end2 >= 0)
        return add_split(e1, t, v2) ? -1 : 0;
    unsigned x;
    if (new_vertex(j, a[0] + t * rx, a[1] + t * ry, a[2], &x) || add_split(e1, t, x) || add_split(e2, u, x))
        return -1;
    return 0;
}

/* The next piece of a loop that came into v from u: among the unused pieces out of v (and the
 * loop's first, `first`, when v is where it began), the first clockwise from the way back to u. */
static long next_piece(const struct join *j, const struct piece *p, size_t n, const size_t *order, unsigned u,
                       unsigned v, size_t first)
{
    size_t lo = 0, hi = n; /* order: pieces by a */
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (p[order[mid]].a < v)
            lo = mid + 1;
        else
            hi = mid;
    }
    const double *pv = xy(j, v), *pu = xy(j, u);
    double bx = pu[0] - pv[0], by = pu[1] - pv[1], best = INFINITY;
    long pick = -1;
    for (size_t i = lo; i <= n; i++) {
        size_t q = i < n ? order[i] : first;
        if (i < n && p[q].a != v)
            i = n - 1; /* past v's pieces: the first piece is the last candidate */
        if ((i < n && (p[q].a != v || p[q].used)) || (i == n && p[q].a != v))
            continue;
        const double *pw = xy(j, p[q].b);
        double wx = pw[0] - pv[0], wy = pw[1] - pv[1];
        double cw = -atan2(bx * wy - by * wx, bx * wx + by * wy); /* clockwise from the way back */
        if (cw <= 0)
            cw += 2 * M_PI;
        if (cw < best)
            best = cw, pick = (long)q;
    }
    return pick;
}

static double loop_area(const struct join *j, const unsigned *v, size_t n)
{
    double a = 0;
    for (size_t k = 0, l = n - 1; k < n; l = k++)
        a += xy(j, v[l])[0] * xy(j, v[k])[1] - xy(j, v[k])[0] * xy(j, v[l])[1];
    return a / 2;
}

/* Joins hole h (clockwise) into ring r (counter-clockwise) by a bridge from the hole's rightmost
 * vertex to a ring vertex it sees (to the right, the nearest edge the ray meets, or a vertex of
 * the ring inside the triangle that hides, the one at the least angle). */
static int bridge(const struct join *j, struct list *r, const unsigned *h, size_t nh)
{
    size_t mi = 0;
    for (size_t k = 1; k < nh; k++)
        if (xy(j, h[k])[0] > xy(j, h[mi])[0])
            mi = k;
    const double *M = xy(j, h[mi]);
    double best = INFINITY;
    size_t at = SIZE_MAX;
    for (size_t k = 0; k < r->n; k++) {
        const double *a = xy(j, r->v[k]), *b = xy(j, r->v[(k + 1) % r->n]);
        if ((a[1] > M[1]) == (b[1] > M[1]) || a[1] == b[1])
            continue;
        double x = a[0] + (M[1] - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
        if (x >= M[0] && x - M[0] < best)
            best = x - M[0], at = a[0] > b[0] ? k : (k + 1) % r->n;
    }
    if (at == SIZE_MAX)
        return 1;
    const double I[2] = {M[0] + best, M[1]}, *P = xy(j, r->v[at]);
    double least = INFINITY;
    size_t pick = at;
    for (size_t k = 0; k < r->n; k++) { /* ring vertices inside (M, I, P) hide P */
        const double *q = xy(j, r->v[k]);
        if (k == at || q[0] < M[0])
            continue;
        double s1 = cross3(M, I, q), s2 = cross3(I, P, q), s3 = cross3(P, M, q);
        bool in = (s1 >= 0 && s2 >= 0 && s3 >= 0) || (s1 <= 0 && s2 <= 0 && s3 <= 0);
        if (!in)
            continue;
        double ang = fabs(atan2(q[1] - M[1], q[0] - M[0]));
        if (ang < least)
            least = ang, pick = k;
    }
    struct list out = {0};
    int rc = 0;
    for (size_t k = 0; k <= pick && !rc; k++)
        rc = push(&out, r->v[k]);
    for (size_t k = 0; k <= nh && !rc; k++)
        rc = push(&out, h[(mi + k) % nh]);
    for (size_t k = pick; k < r->n && !rc; k++)
        rc = push(&out, r->v[k]);
    if (rc) {
        free(out.v);
        return -1;
    }
    free(r->v);
    *r = out;
    return 0;
}

int solid_mesh_tri(struct solid_mesh *m, unsigned a, unsigned b, unsigned c)
{
    if (a == b || b == c || a == c) /* a collapsed ring's triangles have no area */
        return 0;
    if (m->n_t >= SOLID_MESH_MAX_TRIANGLES)
        return SF_ELIMIT;
    if (mem_reserve((void **)&m->t, &m->cap_t, m->n_t + 1, sizeof *m->t))
        return SF_ENOMEM;
    m->t[m->n_t][0] = a, m->t[m->n_t][1] = b, m->t[m->n_t][2] = c;
    m->n_t++;
    return 0;
}

int solid_mesh_clip(struct solid_mesh *m, const unsigned *ring, size_t n, bool up)
{
    size_t *prev = malloc(sizeof *prev * (n ? n : 1)), *next = malloc(sizeof *next * (n ? n : 1));
    int rc = 0;
    if (!prev || !next) {
        free(prev), free(next);
        return SF_ENOMEM;
    }
    for (size_t i = 0; i < n; i++)
        prev[i] = (i + n - 1) % n, next[i] = (i + 1) % n;
    size_t left = n, i = 0, since = 0;
    while (left > 3 && !rc) {
        size_t a = prev[i], c = next[i];
        const double *A = m->v[ring[a]], *I = m->v[ring[i]], *C = m->v[ring[c]];
        bool ear = cross3(A, I, C) > 0;
        for (size_t k = next[c]; ear && k != a; k = next[k]) { /* no other vertex inside or on (a, i, c) */
            const double *q = m->v[ring[k]];
            if ((q[0] == A[0] && q[1] == A[1]) || (q[0] == I[0] && q[1] == I[1]) || (q[0] == C[0] && q[1] == C[1]))
                continue;
            ear = !(cross3(A, I, q) >= 0 && cross3(I, C, q) >= 0 && cross3(C, A, q) >= 0);
        }
        if (ear || since > left) { /* stuck (a curve that grazes itself): clip anyway */
            rc = up ? solid_mesh_tri(m, ring[a], ring[i], ring[c]) : solid_mesh_tri(m, ring[a], ring[c], ring[i]);
            next[a] = c, prev[c] = a;
            left--, since = 0;
            i = c;
        } else {
            i = c, since++;
        }
    }
    if (!rc && left == 3)
        rc = up ? solid_mesh_tri(m, ring[prev[i]], ring[i], ring[next[i]]) : solid_mesh_tri(m, ring[prev[i]], ring[next[i]], ring[i]);
    free(prev), free(next);
    return rc;
}

/* The loops of pieces p (the region on their left), each into loops[] (the caller frees). 1 when
 * a loop does not close. */
static int link(const struct join *j, struct piece *p, size_t n, struct list **loops, size_t *n_loops)
{
    size_t *order = malloc(sizeof *order * (n ? n : 1));
    if (!order)
        return SF_ENOMEM;
    for (size_t k = 0; k < n; k++)
        order[k] = k;
    for (size_t k = 1; k < n; k++) /* by start vertex (insertion: a plane's pieces are few) */
        for (size_t l = k; l > 0 && p[order[l]].a < p[order[l - 1]].a; l--) {
            size_t t = order[l];
            order[l] = order[l - 1], order[l - 1] = t;
        }
    int rc = 0;
    for (size_t s = 0; s < n && !rc; s++) {
        if (p[s].used)
            continue;
        struct list lp = {0};
        size_t cur = s;
        p[s].used = true;
        for (size_t steps = 0; !rc; steps++) {
            rc = push(&lp, p[cur].a);
            long nx = rc ? -1 : next_piece(j, p, n, order, p[cur].a, p[cur].b, s);
            if (rc || nx < 0 || steps > n) {
                rc = rc ? rc : 1;
                break;
            }
            if ((size_t)nx == s)
                break;
            cur = (size_t)nx;
            p[cur].used = true;
        }
        struct list *grown = rc ? NULL : realloc(*loops, sizeof **loops * (*n_loops + 1));
        if (!grown) {
            free(lp.v);
            rc = rc ? rc : SF_ENOMEM;
            break;
        }
        *loops = grown;
        (*loops)[(*n_loops)++] = lp;
    }
    free(order);
    return rc;
}

/* The region d = target of the plane as triangles: its loops, holes bridged, clipped. */
static int region(struct join *j, struct piece *p, size_t n, bool up)
{
    struct list *loops = NULL;
    size_t nl = 0;
    int rc = link(j, p, n, &loops, &nl);
    double *area = rc ? NULL : malloc(sizeof *area * (nl ? nl : 1));
    if (!rc && !area)
        rc = SF_ENOMEM;
    for (size_t k = 0; !rc && k < nl; k++)
        area[k] = loop_area(j, loops[k].v, loops[k].n);
    for (size_t o = 0; !rc && o < nl; o++) {
        if (!(area[o] > 0))
            continue;
        struct list ring = {0};
        for (size_t k = 0; k < loops[o].n && !rc; k++)
            rc = push(&ring, loops[o].v[k]);
        /* its holes, rightmost first: those whose first edge's inner side (the region's) it holds
         * and no smaller outer loop does */
        bool *mine = calloc(nl ? nl : 1, sizeof *mine);
        if (!mine)
            rc = SF_ENOMEM;
        for (size_t h = 0; !rc && h < nl; h++) {
            if (!(area[h] < 0))
                continue;
            const double *a = xy(j, loops[h].v[0]), *b = xy(j, loops[h].v[1 % loops[h].n]);
            double dx = b[0] - a[0], dy = b[1] - a[1], len = hypot(dx, dy), e = 1e-6;
            double x = 0.5 * (a[0] + b[0]) - e * dy / len, y = 0.5 * (a[1] + b[1]) + e * dx / len;
            size_t owner = SIZE_MAX;
            for (size_t q = 0; q < nl; q++)
                if (area[q] > 0 && in_loop(j, loops[q].v, loops[q].n, x, y) && (owner == SIZE_MAX || area[q] < area[owner]))
                    owner = q;
            mine[h] = owner == o;
            if (owner == SIZE_MAX)
                rc = 1;
        }
        for (;;) {
            size_t pick = SIZE_MAX;
            double most = -INFINITY;
            for (size_t h = 0; !rc && h < nl; h++)
                for (size_t k = 0; mine[h] && k < loops[h].n; k++)
                    if (xy(j, loops[h].v[k])[0] > most)
                        most = xy(j, loops[h].v[k])[0], pick = h;
            if (rc || pick == SIZE_MAX)
                break;
            mine[pick] = false;
            rc = bridge(j, &ring, loops[pick].v, loops[pick].n);
        }
        free(mine);
        if (!rc && ring.n >= 3)
            rc = solid_mesh_clip(j->m, ring.v, ring.n, up);
        free(ring.v);
    }
    for (size_t k = 0; k < nl; k++)
        free(loops[k].v);
    free(loops);
    free(area);
    return rc;
}

/* Where wall triangle t has the edge p-q (either way): its position (forward: p -> q), or -1. */
static int wall_edge(const struct join *j, size_t t, unsigned p, unsigned q, bool *forward)
{
    const unsigned *tr = j->m->t[t];
    for (int k = 0; k < 3; k++) {
        unsigned a = root(j, tr[k]), b = root(j, tr[(k + 1) % 3]);
        if ((a == p && b == q) || (a == q && b == p)) {
            *forward = a == p;
            return k;
        }
    }
    return -1;
}

/* Wall triangle t's edge v[0]-v[n-1] through the crossings v[1..n-2]: the triangle's fan from its
 * third vertex. */
static int split_wall(struct join *j, size_t t, const unsigned *v, size_t n)
{
    struct solid_mesh *m = j->m;
    bool forward;
    int at = wall_edge(j, t, v[0], v[n - 1], &forward);
    unsigned o = m->t[t][(at + 2) % 3];
    for (size_t k = 0; k + 1 < n; k++) {
        unsigned a = forward ? v[k] : v[n - 1 - k], b = forward ? v[k + 1] : v[n - 2 - k];
        if (k == 0) {
            m->t[t][0] = a, m->t[t][1] = b, m->t[t][2] = o;
        } else {
            int rc = solid_mesh_tri(m, a, b, o);
            if (rc)
                return rc;
        }
    }
    return 0;
}

/* Edge e's vertices from its start through its crossings to its end, into l. */
static int edge_run(const struct join *j, struct solid_cap *const *caps, const struct edge *e, struct list *l)
{
    const struct solid_cap *r = caps[e->c];
    l->n = 0;
    int rc = push(l, root(j, r->ring[e->k]));
    for (size_t s = 0; !rc && s < e->n; s++)
        if (root(j, e->s[s].v) != l->v[l->n - 1])
            rc = push(l, root(j, e->s[s].v));
    unsigned last = root(j, r->ring[(e->k + 1) % r->n]);
    if (!rc && last != l->v[l->n - 1])
        rc = push(l, last);
    return rc;
}

/* One plane's caps (n of them, facing both ways). 0 joined (their triangles to be dropped: drop),
 * 1 left as they were, or an SF_* code. */
static int join_plane(struct join *j, struct solid_cap *const *caps, int n, bool *drop)
{
    struct solid_mesh *m = j->m;
    size_t n_t0 = m->n_t, n_e = 0;
    j->undo.n = 0;
    for (int c = 0; c < n; c++)
        n_e += (size_t)caps[c]->n;
    struct edge *e = calloc(n_e ? n_e : 1, sizeof *e);
    size_t *base = malloc(sizeof *base * (size_t)n);
    double(*box)[4] = malloc(sizeof *box * (size_t)n);
    struct piece *pc[2] = {NULL, NULL};
    size_t np[2] = {0, 0}, cap_p[2] = {0, 0};
    int rc = !e || !base || !box ? SF_ENOMEM : 0;
    for (int c = 0, at = 0; !rc && c < n; c++) {
        base[c] = (size_t)at;
        box_of(j, caps[c], box[c]);
        for (int k = 0; k < caps[c]->n; k++, at++)
            e[at].c = c, e[at].k = k;
    }
    for (int c1 = 0; !rc && c1 < n; c1++)
        for (int c2 = c1 + 1; !rc && c2 < n; c2++) {
            if (!boxes_meet(box[c1], box[c2]))
                continue;
            for (int k1 = 0; !rc && k1 < caps[c1]->n; k1++)
                for (int k2 = 0; !rc && k2 < caps[c2]->n; k2++) {
                    int x = cross_edges(j, caps, &e[base[c1] + (size_t)k1], &e[base[c2] + (size_t)k2]);
                    rc = x < 0 ? SF_ENOMEM : x;
                }
        }
    /* the pieces between crossings, kept where d differs across them */
    struct list seq = {0};
    for (size_t i = 0; !rc && i < n_e; i++) {
        if (e[i].n > 1)
            qsort(e[i].s, e[i].n, sizeof *e[i].s, by_t);
        rc = edge_run(j, caps, &e[i], &seq);
        bool forward;
        if (!rc && seq.n > 2 && (caps[e[i].c]->wall[e[i].k] == SIZE_MAX ||
                                 wall_edge(j, caps[e[i].c]->wall[e[i].k], seq.v[0], seq.v[seq.n - 1], &forward) < 0))
            rc = 1; /* a crossing on an edge without its wall */
        for (size_t s = 0; !rc && s + 1 < seq.n; s++) {
            const double *a = xy(j, seq.v[s]), *b = xy(j, seq.v[s + 1]);
            double dx = b[0] - a[0], dy = b[1] - a[1], len = hypot(dx, dy), h = 1e-6 * len;
            if (!(len > 0))
                continue;
            double mx = 0.5 * (a[0] + b[0]), my = 0.5 * (a[1] + b[1]), nx = -dy / len * h, ny = dx / len * h;
            int dl = depth(j, caps, n, mx + nx, my + ny), dr = depth(j, caps, n, mx - nx, my - ny);
            if (dl == dr)
                continue;
            int d = dl ? dl : dr, side = d > 0 ? 0 : 1;
            if ((dl && dr) || (d != 1 && d != -1)) {
                rc = 1; /* surfaces over each other: not ours to settle */
                break;
            }
            if (mem_reserve((void **)&pc[side], &cap_p[side], np[side] + 1, sizeof *pc[side])) {
                rc = SF_ENOMEM;
                break;
            }
            pc[side][np[side]++] = dl ? (struct piece){seq.v[s], seq.v[s + 1], false}
                                      : (struct piece){seq.v[s + 1], seq.v[s], false};
        }
    }
    for (int side = 0; !rc && side < 2; side++)
        rc = region(j, pc[side], np[side], side == 0);
    for (size_t i = 0; !rc && i < n_e; i++) /* the walls through the crossings */
        if (e[i].n && !(rc = edge_run(j, caps, &e[i], &seq)) && seq.n > 2)
            rc = split_wall(j, caps[e[i].c]->wall[e[i].k], seq.v, seq.n);
    free(seq.v);
    for (size_t i = 0; e && i < n_e; i++)
        free(e[i].s);
    free(e), free(base), free(box), free(pc[0]), free(pc[1]);
    if (rc == 1) { /* as it was (no wall is split before every check has passed) */
        m->n_t = n_t0;
        for (size_t k = 0; k < j->undo.n; k++)
            j->alias[j->undo.v[k]] = j->undo.v[k];
        return rc;
    }
    for (int c = 0; !rc && c < n; c++)
        for (size_t t = caps[c]->t0; t < caps[c]->t1; t++)
            drop[t] = true;
    return rc;
}

static int by_z(const void *a, const void *b)
{
    double x = (*(struct solid_cap *const *)a)->z, y = (*(struct solid_cap *const *)b)->z;
    return (x > y) - (x < y);
}

bool join_same_plane(double a, double b) { return fabs(a - b) <= 1e-6 * (1 + fabs(b)); }

int solid_mesh_join_caps(struct solid_mesh *m, struct solid_cap *caps, int n_caps)
{
    struct join j = {.m = m};
    struct solid_cap **order = malloc(sizeof *order * (size_t)(n_caps ? n_caps : 1));
    bool *drop = calloc(m->n_t ? m->n_t : 1, sizeof *drop);
    int rc = !order || !drop || mem_reserve((void **)&j.alias, &j.cap_alias, m->n_v ? m->n_v : 1, sizeof *j.alias)
                 ? SF_ENOMEM
                 : 0;
    size_t n_t0 = m->n_t;
    for (size_t v = 0; !rc && v < m->n_v; v++)
        j.alias[v] = (unsigned)v;
    for (int k = 0; !rc && k < n_caps; k++)
        order[k] = &caps[k];
    if (!rc)
        qsort(order, (size_t)n_caps, sizeof *order, by_z);
    bool joined = false;
    for (int a = 0, b; !rc && a < n_caps; a = b) {
        bool up = false, down = false;
        for (b = a; b < n_caps && join_same_plane(order[b]->z, order[a]->z); b++)
            up |= order[b]->up, down |= !order[b]->up;
        if (!up || !down)
            continue;
        int x = join_plane(&j, order + a, b - a, drop);
        joined |= x == 0;
        for (int c = a; c < b; c++)
            order[c]->joined = x == 0;
        rc = x == 1 ? 0 : x;
    }
    if (!rc && joined) { /* the joined planes' caps out, coinciding vertices as one */
        size_t o = 0;
        for (size_t t = 0; t < m->n_t; t++) {
            if (t < n_t0 && drop[t])
                continue;
            unsigned a = root(&j, m->t[t][0]), b = root(&j, m->t[t][1]), c = root(&j, m->t[t][2]);
            if (a == b || b == c || a == c)
                continue;
            m->t[o][0] = a, m->t[o][1] = b, m->t[o][2] = c;
            o++;
        }
        m->n_t = o;
    }
    free(order), free(drop), free(j.alias), free(j.undo.v);
    return rc;
}
