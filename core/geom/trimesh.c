/* trimesh.c - figures of an indexed triangle mesh (trimesh.h). Edges are found by sorting the
 * 3F directed half-edges by their undirected key: a manifold, consistently oriented edge is two
 * half-edges running opposite ways; anything else is counted as boundary or non-manifold.
 * Components by union-find over vertices joined by edges (isolated vertices do not count). */
#include "trimesh.h"

#include "../base/mem.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

void trimesh_free(struct trimesh *m)
{
    free(m->pos);
    free(m->nrm);
    free(m->tri);
    memset(m, 0, sizeof *m);
}

void trimesh_turn(struct trimesh *m, const double o[3], const double a[3][3])
{
    for (size_t v = 0; v < m->n_vert; v++) {
        double p[3], q[3] = {0, 0, 0};
        for (int d = 0; d < 3; d++)
            p[d] = m->pos[3 * v + d] - o[d];
        for (int d = 0; d < 3; d++)
            for (int k = 0; k < 3; k++)
                q[d] += p[k] * a[k][d];
        for (int d = 0; d < 3; d++)
            m->pos[3 * v + d] = (float)(o[d] + q[d]);
        if (!m->nrm)
            continue;
        double n[3] = {0, 0, 0};
        for (int d = 0; d < 3; d++)
            for (int k = 0; k < 3; k++)
                n[d] += m->nrm[3 * v + k] * a[k][d];
        for (int d = 0; d < 3; d++)
            m->nrm[3 * v + d] = (float)n[d];
    }
}

static uint32_t find(uint32_t *parent, uint32_t v)
{
    while (parent[v] != v) {
        parent[v] = parent[parent[v]];
        v = parent[v];
    }
    return v;
}

int trimesh_stats(const struct trimesh *m, struct trimesh_stats *out, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    for (int a = 0; a < 3; a++)
        out->bounds[0][a] = INFINITY, out->bounds[1][a] = -INFINITY;
    for (size_t v = 0; v < m->n_vert; v++)
        for (int a = 0; a < 3; a++) {
            double x = m->pos[3 * v + a];
            out->bounds[0][a] = fmin(out->bounds[0][a], x);
            out->bounds[1][a] = fmax(out->bounds[1][a], x);
        }
    /* volume and area in double, about the bounds' centre (fewer digits lost far from the origin) */
    double c[3];
    for (int a = 0; a < 3; a++)
        c[a] = m->n_vert ? 0.5 * (out->bounds[0][a] + out->bounds[1][a]) : 0;
    double vol = 0, area = 0;
    for (size_t t = 0; t < m->n_tri; t++) {
        double p[3][3];
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++)
                p[k][a] = m->pos[3 * (size_t)m->tri[3 * t + k] + a] - c[a];
        double u[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
        double w[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
        double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        double a2 = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        area += 0.5 * a2;
        out->degenerate += a2 == 0;
        vol += (p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1]) - p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0]) +
                p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0])) / 6;
    }
    out->volume = vol;
    out->area = area;
    if (m->n_tri == 0)
        return 0;
    /* each edge once, from its least vertex: the half-edges counted out by that vertex (CSR: each
     * a word of the other end and which way it runs), each vertex's few then sorted in place. 4
     * bytes a half-edge, where a sort of 8-byte keys and its buffer took 16 (on the CT head's 2 M
     * half-edges their first touch was two thirds of the time: 150 -> 43 ms), and no count
     * of 2^16 buckets that meshes of a few triangles paid for (label maps measure them by the
     * thousand) */
    size_t nh = 3 * m->n_tri, nv = m->n_vert;
    uint32_t *start = calloc(nv + 1, sizeof *start), *half = malloc(nh * sizeof *half);
    uint32_t *parent = malloc((nv ? nv : 1) * sizeof *parent);
    if (!start || !half || !parent) {
        free(start);
        free(half);
        free(parent);
        return sf_fail(err, SF_ENOMEM, "", "out of memory measuring a mesh of %zu triangles", m->n_tri);
    }
    for (size_t v = 0; v < nv; v++)
        parent[v] = (uint32_t)v;
    for (size_t t = 0; t < 3 * m->n_tri; t++) {
        uint32_t a = m->tri[t], b = m->tri[t % 3 == 2 ? t - 2 : t + 1];
        start[(a < b ? a : b) + 1]++;
        uint32_t ra = find(parent, a), rb = find(parent, b);
        if (ra != rb)
            parent[ra] = rb;
    }
    for (size_t v = 0; v < nv; v++)
        start[v + 1] += start[v];
    for (size_t t = 0; t < 3 * m->n_tri; t++) {
        uint32_t a = m->tri[t], b = m->tri[t % 3 == 2 ? t - 2 : t + 1];
        half[start[a < b ? a : b]++] = (a < b ? b : a) << 1 | (a > b);
    }
    long edges = 0;
    for (size_t v = 0, from = 0; v < nv; from = start[v++]) { /* (start[v] is now v's end) */
        uint32_t *h = half + from;
        size_t n = start[v] - from;
        for (size_t i = 1; i < n; i++) {
            uint32_t k = h[i];
            size_t j = i;
            for (; j > 0 && h[j - 1] > k; j--)
                h[j] = h[j - 1];
            h[j] = k;
        }
        for (size_t i = 0; i < n;) {
            size_t j = i;
            while (j < n && h[j] >> 1 == h[i] >> 1)
                j++;
            edges++;
            if (j - i == 1)
                out->boundary_edges++;
            else if (j - i > 2 || (h[i] & 1) == (h[i + 1] & 1))
                out->nonmanifold_edges++;
            i = j;
        }
    }
    free(start);
    free(half);
    bool *used = calloc(m->n_vert ? m->n_vert : 1, sizeof *used);
    if (!used) {
        free(parent);
        return sf_fail(err, SF_ENOMEM, "", "out of memory measuring a mesh");
    }
    for (size_t t = 0; t < 3 * m->n_tri; t++)
        used[m->tri[t]] = true;
    long verts = 0;
    for (size_t v = 0; v < m->n_vert; v++)
        if (used[v]) {
            verts++;
            out->components += find(parent, (uint32_t)v) == v;
        }
    out->euler = verts - edges + (long)m->n_tri;
    free(used);
    free(parent);
    return 0;
}

double trimesh_point_dist(const double p[3], const double a[3], const double b[3], const double c[3])
{
    double ab[3], ac[3], ap[3], q[3];
    for (int d = 0; d < 3; d++)
        ab[d] = b[d] - a[d], ac[d] = c[d] - a[d], ap[d] = p[d] - a[d];
#define DOT(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double d1 = DOT(ab, ap), d2 = DOT(ac, ap), v, w;
    double bp[3] = {p[0] - b[0], p[1] - b[1], p[2] - b[2]}, cp[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    double d3 = DOT(ab, bp), d4 = DOT(ac, bp), d5 = DOT(ab, cp), d6 = DOT(ac, cp);
    double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    if (d1 <= 0 && d2 <= 0)
        v = 0, w = 0;
    else if (d3 >= 0 && d4 <= d3)
        v = 1, w = 0;
    else if (vc <= 0 && d1 >= 0 && d3 <= 0)
        v = d1 / (d1 - d3), w = 0;
    else if (d6 >= 0 && d5 <= d6)
        v = 0, w = 1;
    else if (vb <= 0 && d2 >= 0 && d6 <= 0)
        v = 0, w = d2 / (d2 - d6);
    else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6)), v = 1 - w;
    else {
        double den = 1 / (va + vb + vc);
        v = vb * den, w = vc * den;
    }
    for (int d = 0; d < 3; d++)
        q[d] = a[d] + v * ab[d] + w * ac[d] - p[d];
    return sqrt(DOT(q, q));
#undef DOT
}

/* ---- sections by a plane z = const ------------------------------------------------------- */

/* Open addressing from a mesh edge (its two vertex ids, smaller first) to its crossing point. */
struct edge_map {
    uint64_t *key;           /* (a << 32 | b) + 1; 0: empty */
    int *point;
    size_t cap;
};

static int edge_point(struct edge_map *h, uint32_t a, uint32_t b, int fresh)
{
    uint64_t k = ((uint64_t)(a < b ? a : b) << 32 | (a < b ? b : a)) + 1;
    size_t i = (size_t)(k * 0x9E3779B97F4A7C15ull >> 17) & (h->cap - 1);
    while (h->key[i] && h->key[i] != k)
        i = (i + 1) & (h->cap - 1);
    if (!h->key[i])
        h->key[i] = k, h->point[i] = fresh;
    return h->point[i];
}

int trimesh_slice(const struct trimesh *m, double z, struct trimesh_loops *out, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    /* the crossing triangles: each gives one segment, from its edge that goes down through the
     * plane to its edge that goes up (counter-clockwise round the inside, seen from +z) */
    size_t n_seg = 0;
    for (size_t t = 0; t < m->n_tri; t++) {
        int above = 0;
        for (int c = 0; c < 3; c++)
            above += m->pos[3 * m->tri[3 * t + c] + 2] >= z;
        n_seg += above == 1 || above == 2;
    }
    struct edge_map h = {0};
    h.cap = 16;
    while (h.cap < 4 * n_seg + 16)
        h.cap *= 2;
    h.key = calloc(h.cap, sizeof *h.key);
    h.point = malloc(h.cap * sizeof *h.point);
    double(*pt)[2] = malloc((2 * n_seg + 1) * sizeof *pt);
    int *next = malloc((2 * n_seg + 1) * sizeof *next);
    bool *used = calloc(2 * n_seg + 1, sizeof *used);
    int n_pt = 0;
    if (!h.key || !h.point || !pt || !next || !used)
        goto fail;
    for (size_t k = 0; k < 2 * n_seg + 1; k++)
        next[k] = -1;
    for (size_t t = 0; t < m->n_tri; t++) {
        int down = -1, up = -1;
        for (int c = 0; c < 3; c++) {
            uint32_t a = m->tri[3 * t + c], b = m->tri[3 * t + (c + 1) % 3];
            double za = m->pos[3 * a + 2], zb = m->pos[3 * b + 2];
            bool aa = za >= z, ab = zb >= z;
            if (aa == ab)
                continue;
            int id = edge_point(&h, a, b, n_pt);
            if (id == n_pt) { /* a new crossing: the point on the edge */
                double f = (z - za) / (zb - za);
                pt[n_pt][0] = m->pos[3 * a] + f * (m->pos[3 * b] - m->pos[3 * a]);
                pt[n_pt][1] = m->pos[3 * a + 1] + f * (m->pos[3 * b + 1] - m->pos[3 * a + 1]);
                n_pt++;
            }
            if (aa)
                down = id;
            else
                up = id;
        }
        if (down >= 0 && up >= 0)
            next[down] = up;
    }
    /* the loops: follow next from each point not yet used */
    out->p = malloc((size_t)(n_pt + 1) * sizeof *out->p);
    out->start = malloc((size_t)(n_pt + 2) * sizeof *out->start);
    if (!out->p || !out->start)
        goto fail;
    int at = 0;
    for (int s = 0; s < n_pt; s++) {
        if (used[s])
            continue;
        int first = at;
        for (int q = s; q >= 0 && !used[q]; q = next[q]) {
            used[q] = true;
            if (at > first && pt[q][0] == out->p[at - 1][0] && pt[q][1] == out->p[at - 1][1])
                continue; /* the plane through a vertex: two edges, one point */
            out->p[at][0] = pt[q][0], out->p[at][1] = pt[q][1];
            at++;
        }
        while (at - first > 1 && out->p[at - 1][0] == out->p[first][0] && out->p[at - 1][1] == out->p[first][1])
            at--;
        if (at - first < 3) {
            at = first; /* a touch, not a section */
            continue;
        }
        out->start[out->n++] = first;
    }
    out->start[out->n] = at;
    free(h.key), free(h.point), free(pt), free(next), free(used);
    return 0;
fail:
    free(h.key), free(h.point), free(pt), free(next), free(used);
    trimesh_loops_free(out);
    return sf_fail(err, SF_ENOMEM, "", "out of memory slicing the mesh");
}

void trimesh_loops_free(struct trimesh_loops *l)
{
    free(l->p);
    free(l->start);
    memset(l, 0, sizeof *l);
}

/* ---- trimesh_manifold ---- */

/* The corners (3 t + k) round each vertex, grouped by vertex (counting sort), with the vertices
 * after them in their triangles (nb[2 i]: the next, nb[2 i + 1]: the one after). */
struct corners {
    uint32_t *start, *corner, *nb;
};

static void corners_free(struct corners *c) { free(c->start), free(c->corner), free(c->nb); }

static int corners_build(const struct trimesh *m, struct corners *c)
{
    size_t nv = m->n_vert, nc = 3 * m->n_tri;
    uint32_t *fill = calloc(nv + 1, sizeof *fill);
    c->start = calloc(nv + 1, sizeof *c->start);
    c->corner = malloc((nc ? nc : 1) * sizeof *c->corner);
    c->nb = malloc((nc ? nc : 1) * 2 * sizeof *c->nb);
    if (!fill || !c->start || !c->corner || !c->nb) {
        free(fill), corners_free(c);
        return SF_ENOMEM;
    }
    for (size_t i = 0; i < nc; i++)
        c->start[m->tri[i] + 1]++;
    for (size_t v = 0; v < nv; v++)
        c->start[v + 1] += c->start[v];
    for (size_t t = 0; t < m->n_tri; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->tri[3 * t + k], at = c->start[v] + fill[v]++;
            c->corner[at] = (uint32_t)(3 * t + k);
            c->nb[2 * at] = m->tri[3 * t + (k + 1) % 3], c->nb[2 * at + 1] = m->tri[3 * t + (k + 2) % 3];
        }
    free(fill);
    return 0;
}

static int add_vertex(struct trimesh *m, size_t *vcap, const float *p)
{
    size_t i = m->n_vert;
    if (i >= 0x7fffffffu || mem_reserve((void **)&m->pos, vcap, 3 * (i + 1), sizeof(float)))
        return -1;
    memmove(m->pos + 3 * i, p, 3 * sizeof(float));
    m->n_vert++;
    return 0;
}

/* The triangles of edge p-q: (p, q, r) ones and (q, p, s) ones, in turn round the edge (sorted by
 * the angle of their third vertex); each (q, p, s) is paired with the next (p, q, r), the other side
 * of the solid wedge between them (the outside of (p, q, r) lies the way the angle grows), and the
 * edge of each pair is split at its own midpoint. */
static int split_edge(struct trimesh *m, size_t *vcap, size_t *tcap, uint32_t p, uint32_t q, const uint32_t *tris, int n)
{
    double e[3], u[3] = {0, 0, 0}, w[3] = {0, 0, 0}, ang[16];
    const float *P = m->pos + 3 * p, *Q = m->pos + 3 * q;
    for (int d = 0; d < 3; d++)
        e[d] = Q[d] - P[d];
    int dir[16], order[16];
    for (int k = 0; k < n; k++) {
        const uint32_t *t = m->tri + 3 * tris[k];
        uint32_t r = t[0] != p && t[0] != q ? t[0] : t[1] != p && t[1] != q ? t[1] : t[2];
        int at = t[0] == p ? 0 : t[1] == p ? 1 : 2;
        dir[k] = t[(at + 1) % 3] == q; /* (p, q, r) */
        double x[3], ee = e[0] * e[0] + e[1] * e[1] + e[2] * e[2], xe;
        for (int d = 0; d < 3; d++)
            x[d] = m->pos[3 * r + d] - P[d];
        xe = (x[0] * e[0] + x[1] * e[1] + x[2] * e[2]) / ee;
        for (int d = 0; d < 3; d++)
            x[d] -= xe * e[d];
        if (!k) {
            memcpy(u, x, sizeof u);
            w[0] = e[1] * u[2] - e[2] * u[1], w[1] = e[2] * u[0] - e[0] * u[2], w[2] = e[0] * u[1] - e[1] * u[0];
        }
        ang[k] = atan2(x[0] * w[0] + x[1] * w[1] + x[2] * w[2], x[0] * u[0] + x[1] * u[1] + x[2] * u[2]);
        order[k] = k;
    }
    for (int k = 1; k < n; k++)
        for (int j = k; j > 0 && ang[order[j]] < ang[order[j - 1]]; j--) {
            int t = order[j];
            order[j] = order[j - 1], order[j - 1] = t;
        }
    for (int k = 0; k < n; k++) {
        int a = order[k], b = order[(k + 1) % n];
        if (dir[a] || !dir[b])
            continue; /* a: (q, p, s); b: (p, q, r) */
        float mid[3];
        for (int d = 0; d < 3; d++)
            mid[d] = (P[d] + Q[d]) / 2;
        if (add_vertex(m, vcap, mid) || mem_reserve((void **)&m->tri, tcap, 3 * (m->n_tri + 2), sizeof(uint32_t)))
            return SF_ENOMEM;
        P = m->pos + 3 * p; /* (pos may have moved) */
        Q = m->pos + 3 * q;
        uint32_t mv = (uint32_t)(m->n_vert - 1);
        for (int s = 0; s < 2; s++) { /* (x, y, z) with edge x -> y: (x, m, z) and (m, y, z) */
            uint32_t *t = m->tri + 3 * tris[s ? a : b];
            int at = 0;
            while (!((t[at] == p || t[at] == q) && (t[(at + 1) % 3] == p || t[(at + 1) % 3] == q)))
                at++;
            uint32_t y = t[(at + 1) % 3], z = t[(at + 2) % 3], *nt = m->tri + 3 * m->n_tri++;
            t[(at + 1) % 3] = mv;
            nt[0] = mv, nt[1] = y, nt[2] = z;
        }
    }
    return 0;
}

/* Whether a vertex after v in one of v's triangles, or one before it, repeats: what an edge at v
 * of more than two triangles implies. mark (zeroed, 2 a vertex) remembers what was seen at which
 * vertex. */
static bool repeats(const struct corners *c, uint32_t v, uint32_t *mark)
{
    for (uint32_t i = c->start[v]; i < c->start[v + 1]; i++)
        for (int side = 0; side < 2; side++) {
            uint32_t *seen = &mark[2 * c->nb[2 * i + side] + side];
            if (*seen == v + 1)
                return true;
            *seen = v + 1;
        }
    return false;
}

int trimesh_manifold(struct trimesh *m, size_t *vcap, size_t *tcap, long *midpoints)
{
    struct corners c;
    size_t nv0 = m->n_vert;
    int rc = 0;
    /* edges of more than two triangles (a next vertex seen twice among a vertex's corners), split
     * in passes: a split leaves the corner lists of its vertices stale, so an edge at a vertex of a
     * triangle split in this pass waits for the next */
    for (;;) {
        size_t nv = m->n_vert;
        uint8_t *stale = calloc(nv + 1, 1);
        uint32_t *mark = calloc(2 * nv + 1, sizeof *mark);
        if (!stale || !mark || corners_build(m, &c)) {
            free(stale), free(mark);
            return SF_ENOMEM;
        }
        bool split = false;
        for (uint32_t v = 0; v < nv && !rc; v++) {
            if (!repeats(&c, v, mark))
                continue;
            for (uint32_t i = c.start[v]; i < c.start[v + 1] && !rc; i++) {
                uint32_t a = c.nb[2 * i], tris[16];
                int n = 0, same = 0;
                if (a < v || stale[v] || stale[a])
                    continue;
                for (uint32_t j = c.start[v]; j < c.start[v + 1]; j++) {
                    bool out = c.nb[2 * j] == a, in = c.nb[2 * j + 1] == a;
                    same += out && j < i;
                    n += out || in;
                    if ((out || in) && n <= 16)
                        tris[n - 1] = c.corner[j] / 3;
                }
                if (n <= 2 || n > 16 || same) /* (an edge once: at its first corner) */
                    continue;
                for (int k = 0; k < n; k++)
                    for (int d = 0; d < 3; d++)
                        stale[m->tri[3 * tris[k] + d]] = 1;
                rc = split_edge(m, vcap, tcap, v, a, tris, n);
                split = true;
            }
        }
        free(stale), free(mark);
        if (rc || !split)
            break;
        corners_free(&c);
    }
    *midpoints += (long)(m->n_vert - nv0);
    size_t nv = m->n_vert;
    /* vertices of several fans: walked from triangle (v, a, b) to the one (v, b, ...), found by
     * b's corner at v (mark: v + 1 where it is known) */
    uint8_t *done = calloc(3 * m->n_tri + 1, 1);
    uint32_t *mark = calloc(nv + 1, sizeof *mark), *slot = malloc((nv + 1) * sizeof *slot);
    if (!done || !mark || !slot)
        rc = SF_ENOMEM;
    for (uint32_t v = 0; v < nv && !rc; v++) {
        int fans = 0;
        for (uint32_t q = c.start[v]; q < c.start[v + 1]; q++)
            mark[c.nb[2 * q]] = v + 1, slot[c.nb[2 * q]] = q;
        for (uint32_t c0 = c.start[v]; c0 < c.start[v + 1] && !rc; c0++) {
            if (done[c0])
                continue;
            uint32_t id = v;
            if (fans++) {
                float p[3];
                memcpy(p, m->pos + 3 * v, sizeof p);
                if (add_vertex(m, vcap, p)) {
                    rc = SF_ENOMEM;
                    break;
                }
                id = (uint32_t)(m->n_vert - 1);
            }
            for (uint32_t k = c0; !done[k];) { /* (k: v's corners in turn; ids as they were) */
                done[k] = 1;
                uint32_t b = c.nb[2 * k + 1];
                m->tri[c.corner[k]] = id;
                if (mark[b] == v + 1)
                    k = slot[b];
            }
        }
    }
    free(done), free(mark), free(slot);
    corners_free(&c);
    return rc;
}

/* ---- comparing meshes by their triangles ---- */

static int cmp18(const void *p, const void *q) { return memcmp(p, q, 18 * sizeof(float)); }

/* m's triangles as 18 floats each (position and normal of each corner, from the least corner on),
 * sorted; NULL when memory runs out. */
static float *sorted18(const struct trimesh *m)
{
    float *t = malloc((m->n_tri ? m->n_tri : 1) * 18 * sizeof *t);
    if (!t)
        return NULL;
    for (size_t i = 0; i < m->n_tri; i++) {
        const uint32_t *v = m->tri + 3 * i;
        int r = 0;
        for (int q = 1; q < 3; q++)
            if (memcmp(m->pos + 3 * v[q], m->pos + 3 * v[r], 3 * sizeof(float)) < 0)
                r = q;
        for (int q = 0; q < 3; q++) {
            memcpy(t + 18 * i + 6 * q, m->pos + 3 * v[(r + q) % 3], 3 * sizeof(float));
            if (m->nrm)
                memcpy(t + 18 * i + 6 * q + 3, m->nrm + 3 * v[(r + q) % 3], 3 * sizeof(float));
            else
                memset(t + 18 * i + 6 * q + 3, 0, 3 * sizeof(float));
        }
    }
    qsort(t, m->n_tri, 18 * sizeof *t, cmp18);
    return t;
}

int trimesh_differ(const struct trimesh *a, const struct trimesh *b, size_t *differ)
{
    *differ = a->n_tri > b->n_tri ? a->n_tri : b->n_tri;
    if (a->n_tri != b->n_tri)
        return 0;
    float *x = sorted18(a), *y = sorted18(b);
    int rc = x && y ? 0 : SF_ENOMEM;
    if (!rc)
        for (size_t i = *differ = 0; i < a->n_tri; i++)
            *differ += memcmp(x + 18 * i, y + 18 * i, 18 * sizeof *x) != 0;
    free(x);
    free(y);
    return rc;
}
