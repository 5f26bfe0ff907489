/* matrix.c - matrix models (matrix.h): elements and voxels, and the mesh of chamfered voxel
 * solids. A voxel's solid is clipped from its cube in half-voxel units (doubled coordinates:
 * corners 0 and 2, centres 1), where every vertex is a whole number, so vertices are merged by
 * exact keys and nothing is compared with a tolerance. */
#include "matrix.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"
#include "../iso/mc.h"

/* ---- elements and voxels ---- */

static int axis_of(int k) { return k == 0 || k == 3 ? 0 : k == 1 || k == 4 ? 1 : 2; }

void matrix_shape(const int n[3], int k, int *rows, int *cols)
{
    int a = axis_of(k);
    *rows = a == 2 ? n[1] : n[2];
    *cols = a == 0 ? n[1] : n[0];
}

void matrix_voxel(const int n[3], int k, int i, int j, int d, int v[3])
{
    const int N = n[0], M = n[1], K = n[2];
    switch (k) {
    case 0: v[0] = N - 1 - d, v[1] = j, v[2] = K - 1 - i; break;
    case 1: v[0] = N - 1 - j, v[1] = M - 1 - d, v[2] = K - 1 - i; break;
    case 2: v[0] = j, v[1] = M - 1 - i, v[2] = K - 1 - d; break;
    case 3: v[0] = d, v[1] = M - 1 - j, v[2] = K - 1 - i; break;
    case 4: v[0] = j, v[1] = d, v[2] = K - 1 - i; break;
    default: v[0] = N - 1 - j, v[1] = M - 1 - i, v[2] = d; break;
    }
}

static size_t at(const int n[3], const int v[3]) { return (size_t)v[0] + (size_t)n[0] * ((size_t)v[1] + (size_t)n[1] * v[2]); }

static bool in_set(const int n[3], const uint8_t *vox, const int v[3])
{
    for (int d = 0; d < 3; d++)
        if (v[d] < 0 || v[d] >= n[d])
            return false;
    return vox[at(n, v)] != 0;
}

/* The line of element [i][j] of matrix k: the index of its voxel at depth 0, and the step to the
 * next depth. */
static void line_of(const int n[3], int k, int i, int j, size_t *first, ptrdiff_t *step)
{
    int v0[3], v1[3];
    matrix_voxel(n, k, i, j, 0, v0);
    matrix_voxel(n, k, i, j, 1, v1);
    *first = at(n, v0);
    *step = (ptrdiff_t)at(n, v1) - (ptrdiff_t)*first; /* (v1 may lie outside: the index is only a difference) */
}

/* The depth of the first voxel of the set along the line, or its length. */
static int first_in(const uint8_t *vox, size_t first, ptrdiff_t step, int len)
{
    int d = 0;
    for (ptrdiff_t q = (ptrdiff_t)first; d < len && !vox[q]; d++, q += step)
        ;
    return d;
}

void matrix_of_voxels(const int n[3], const uint8_t *vox, int *const m[6])
{
    for (int k = 0; k < 6; k++) {
        int rows, cols, len = n[axis_of(k)];
        matrix_shape(n, k, &rows, &cols);
        for (int i = 0; i < rows; i++)
            for (int j = 0; j < cols; j++) {
                size_t first;
                ptrdiff_t step;
                line_of(n, k, i, j, &first, &step);
                m[k][(size_t)i * cols + j] = first_in(vox, first, step, len);
            }
    }
}

/* The element of matrix k that looks along the line through voxel v (its row and column). */
static void element_of(const int n[3], int k, const int v[3], int *i, int *j)
{
    const int N = n[0], M = n[1], K = n[2];
    switch (k) {
    case 0: *i = K - 1 - v[2], *j = v[1]; break;
    case 1: *i = K - 1 - v[2], *j = N - 1 - v[0]; break;
    case 2: *i = M - 1 - v[1], *j = v[0]; break;
    case 3: *i = K - 1 - v[2], *j = M - 1 - v[1]; break;
    case 4: *i = K - 1 - v[2], *j = v[0]; break;
    default: *i = M - 1 - v[1], *j = N - 1 - v[0]; break;
    }
}

int matrix_voxels(const struct matrix_model *mm, uint8_t *vox, int *bad_k, int *bad_i, int *bad_j, struct sf_err *err)
{
    const int *n = mm->n;
    /* each line seen from both ends: both miss, or the first from the low end lies before the
     * first from the high end (eq. 5); the voxels between them kept, along all three axes */
    memset(vox, 1, (size_t)n[0] * n[1] * n[2]);
    for (int k = 3; k < 6; k++) {
        int rows, cols, len = n[axis_of(k)];
        matrix_shape(n, k, &rows, &cols);
        for (int i = 0; i < rows; i++)
            for (int j = 0; j < cols; j++) {
                int lo = mm->m[k][(size_t)i * cols + j], v[3], oi, oj;
                matrix_voxel(n, k, i, j, 0, v);
                element_of(n, k - 3, v, &oi, &oj);
                int hi_depth = mm->m[k - 3][(size_t)oi * cols + oj], hi = len - 1 - hi_depth;
                if ((lo == len) != (hi_depth == len) || (lo < len && lo > hi)) {
                    *bad_k = k, *bad_i = i, *bad_j = j;
                    return sf_fail(err, SF_EINVAL, "", "M%d[%d][%d] = %d and M%d[%d][%d] = %d see one line: the first voxel "
                                   "from one end lies beyond the first from the other", k, i, j, lo, k - 3, oi, oj, hi_depth);
                }
                size_t first;
                ptrdiff_t step;
                line_of(n, k, i, j, &first, &step);
                ptrdiff_t q = (ptrdiff_t)first;
                for (int d = 0; d < len; d++, q += step)
                    if (d < lo || d > hi)
                        vox[q] = 0;
            }
    }
    /* and every element names a voxel the others keep: the set's own matrices are the model's */
    for (int k = 0; k < 6; k++) {
        int rows, cols, len = n[axis_of(k)];
        matrix_shape(n, k, &rows, &cols);
        for (int i = 0; i < rows; i++)
            for (int j = 0; j < cols; j++) {
                size_t first;
                ptrdiff_t step;
                line_of(n, k, i, j, &first, &step);
                int want = mm->m[k][(size_t)i * cols + j], d = first_in(vox, first, step, len);
                if (d != want) {
                    *bad_k = k, *bad_i = i, *bad_j = j;
                    return sf_fail(err, SF_EINVAL, "", "M%d[%d][%d] = %d names a voxel the other matrices exclude (the "
                                   "body they hold is seen at depth %d there)", k, i, j, want, d);
                }
            }
    }
    return 0;
}

void matrix_counts(const struct matrix_model *mm, struct matrix_stats *st)
{
    const int *n = mm->n;
    size_t nv = (size_t)n[0] * n[1] * n[2];
    uint8_t *seen = calloc(nv ? nv : 1, 1);
    memset(st, 0, sizeof *st);
    if (!seen)
        return;
    long hits = 0;
    for (int k = 0; k < 6; k++) {
        int rows, cols, len = n[axis_of(k)];
        matrix_shape(n, k, &rows, &cols);
        const int *m = mm->m[k];
        for (int i = 0; i < rows; i++)
            for (int j = 0; j < cols; j++) {
                int d = m[(size_t)i * cols + j], v[3];
                if (d >= len)
                    continue;
                matrix_voxel(n, k, i, j, d, v);
                size_t a = at(n, v);
                hits++;
                bool base = (i == 0 || m[(size_t)(i - 1) * cols + j] <= d) && (i + 1 == rows || m[(size_t)(i + 1) * cols + j] <= d) &&
                            (j == 0 || m[(size_t)i * cols + j - 1] <= d) && (j + 1 == cols || m[(size_t)i * cols + j + 1] <= d);
                st->voxels += !(seen[a] & 1);
                st->base_voxels += base && !(seen[a] & 2);
                seen[a] |= (uint8_t)(1 | (base ? 2 : 0));
            }
    }
    st->redundant_voxels = hits - st->voxels;
    free(seen);
}

/* ---- one voxel's solid, in quarter-voxel units (corners 0 and 4) ---- */

#define Q 4                  /* units a voxel side */
#define MAX_PV 16            /* vertices of a clipped polygon */
#define MAX_POLYS 24

struct poly {
    int n, face;             /* face: the cube face it lies on (0..5), or 6 + the chamfer (a cap) */
    int p[MAX_PV][3];
};

struct solid {
    int open;                /* bit f = 2 axis + side: no voxel beyond face f */
    int n_ch, ch[12][2];     /* chamfers: pairs of adjacent open faces */
    int n_polys;
    struct poly polys[MAX_POLYS];
};

/* t_f at u: Q on face f, 0 on its opposite. */
static int t_face(int f, const int u[3]) { return f & 1 ? u[f >> 1] : Q - u[f >> 1]; }

/* A chamfer keeps t_f + t_g <= 3/2 voxel: it cuts the prism of legs half a voxel along the edge. */
static int chamfer_h(const struct solid *s, int c, const int u[3]) { return t_face(s->ch[c][0], u) + t_face(s->ch[c][1], u) - 3 * Q / 2; }

static int open_faces(const int n[3], const uint8_t *vox, const int v[3])
{
    int open = 0;
    for (int f = 0; f < 6; f++) {
        int w[3] = {v[0], v[1], v[2]};
        w[f >> 1] += f & 1 ? 1 : -1;
        open |= in_set(n, vox, w) ? 0 : 1 << f;
    }
    return open;
}

static void chamfers(struct solid *s)
{
    s->n_ch = 0;
    for (int f = 0; f < 6; f++)
        for (int g = f + 1; g < 6; g++)
            if ((f >> 1) != (g >> 1) && (s->open >> f & 1) && (s->open >> g & 1))
                s->ch[s->n_ch][0] = f, s->ch[s->n_ch][1] = g, s->n_ch++;
}

/* The corners of face f, counter-clockwise seen from outside. */
static void face_corners(int f, int c[4][3])
{
    int a = f >> 1, p = (a + 1) % 3, q = (a + 2) % 3;
    static const int pq[4][2] = {{0, 0}, {Q, 0}, {Q, Q}, {0, Q}}; /* counter-clockwise seen from +a */
    for (int k = 0; k < 4; k++) {
        int kk = f & 1 ? k : 3 - k;
        c[k][a] = f & 1 ? Q : 0;
        c[k][p] = pq[kk][0];
        c[k][q] = pq[kk][1];
    }
}

/* The polygons of s's solid: its cube clipped by each chamfer, each cut adding its cap. Every
 * vertex lies on the quarter-voxel lattice (the planes' normals are sums of two axes and their
 * levels multiples of half a voxel, and each vertex lies on three of them or of the faces). */
static void clip_solid(struct solid *s)
{
    s->n_polys = 6;
    for (int f = 0; f < 6; f++) {
        s->polys[f].n = 4, s->polys[f].face = f;
        face_corners(f, s->polys[f].p);
    }
    for (int c = 0; c < s->n_ch; c++) {
        int cut[2 * MAX_POLYS * 2][3], n_cut = 0, kept = 0;
        for (int k = 0; k < s->n_polys; k++) {
            struct poly *pl = &s->polys[k], out = {0, pl->face, {{0}}};
            for (int e = 0; e < pl->n; e++) {
                const int *a = pl->p[e], *b = pl->p[(e + 1) % pl->n];
                int ha = chamfer_h(s, c, a), hb = chamfer_h(s, c, b);
                if (ha <= 0 && out.n < MAX_PV)
                    memcpy(out.p[out.n++], a, sizeof out.p[0]);
                if (ha == 0 && n_cut < (int)(sizeof cut / sizeof *cut))
                    memcpy(cut[n_cut++], a, sizeof cut[0]);
                if ((ha < 0 && hb > 0) || (ha > 0 && hb < 0)) {
                    int x[3];
                    for (int d = 0; d < 3; d++) /* exact: (a h_b - b h_a) / (h_b - h_a) is whole on the lattice */
                        x[d] = (a[d] * hb - b[d] * ha) / (hb - ha);
                    if (out.n < MAX_PV)
                        memcpy(out.p[out.n++], x, sizeof x);
                    if (n_cut < (int)(sizeof cut / sizeof *cut))
                        memcpy(cut[n_cut++], x, sizeof x);
                }
            }
            if (out.n >= 3)
                s->polys[kept++] = out;
        }
        s->n_polys = kept;
        struct poly cap = {0, 6 + c, {{0}}};
        for (int k = 0; k < n_cut; k++) {
            bool dup = false;
            for (int q = 0; q < cap.n && !dup; q++)
                dup = !memcmp(cap.p[q], cut[k], sizeof cut[k]);
            if (!dup && cap.n < MAX_PV)
                memcpy(cap.p[cap.n++], cut[k], sizeof cut[k]);
        }
        if (cap.n < 3 || s->n_polys >= MAX_POLYS)
            continue;
        /* ordered round their centre, counter-clockwise seen from outside (where h grows) */
        double nrm[3] = {0, 0, 0}, o[3] = {0, 0, 0}, e1[3], e2[3], ang[MAX_PV];
        for (int g = 0; g < 2; g++)
            nrm[s->ch[c][g] >> 1] += s->ch[c][g] & 1 ? 1 : -1;
        for (int k = 0; k < cap.n; k++)
            for (int d = 0; d < 3; d++)
                o[d] += (double)cap.p[k][d] / cap.n;
        for (int d = 0; d < 3; d++)
            e1[d] = cap.p[0][d] - o[d];
        e2[0] = nrm[1] * e1[2] - nrm[2] * e1[1], e2[1] = nrm[2] * e1[0] - nrm[0] * e1[2], e2[2] = nrm[0] * e1[1] - nrm[1] * e1[0];
        for (int k = 0; k < cap.n; k++) {
            double r[3] = {cap.p[k][0] - o[0], cap.p[k][1] - o[1], cap.p[k][2] - o[2]};
            ang[k] = atan2(r[0] * e2[0] + r[1] * e2[1] + r[2] * e2[2], r[0] * e1[0] + r[1] * e1[1] + r[2] * e1[2]);
        }
        for (int k = 1; k < cap.n; k++)
            for (int q = k; q > 0 && ang[q] < ang[q - 1]; q--) {
                double t = ang[q];
                int tp[3];
                ang[q] = ang[q - 1], ang[q - 1] = t;
                memcpy(tp, cap.p[q], sizeof tp);
                memcpy(cap.p[q], cap.p[q - 1], sizeof tp);
                memcpy(cap.p[q - 1], tp, sizeof tp);
            }
        s->polys[s->n_polys++] = cap;
    }
}

/* The corners of face f (as face_corners orders them) that s's chamfers cut: bit k where both
 * faces meeting f at corner k's edge... at the corner, across the face, are open. */
static int cut_corners(int open, int f)
{
    int a = f >> 1, p = (a + 1) % 3, q = (a + 2) % 3, c[4][3], mask = 0;
    face_corners(f, c);
    for (int k = 0; k < 4; k++) {
        int fp = 2 * p + (c[k][p] == Q), fq = 2 * q + (c[k][q] == Q);
        mask |= (open >> fp & 1) && (open >> fq & 1) ? 1 << k : 0;
    }
    return mask;
}

/* Corner k of face f as the voxel across it (face f ^ 1) numbers it. */
static int corner_across(int k) { return 3 - k; }

/* A voxel's solid depends on its open faces alone: the 64 of them, clipped once a mesh. */
static void solids(struct solid table[64])
{
    for (int open = 0; open < 64; open++) {
        table[open].open = open;
        chamfers(&table[open]);
        clip_solid(&table[open]);
    }
}

/* ---- the mesh ---- */

struct mesher {
    const int *n;
    const uint8_t *vox;
    uint8_t *open;           /* each voxel's open faces (0 for voxels out of the set) */
    double lo[3], d[3];
    struct trimesh m;
    size_t vcap, tcap;
    uint64_t *keys;          /* vertex table: global quarter-voxel coordinates */
    uint32_t *ids;
    size_t cap, used;
    uint64_t *seen;          /* pass 1: every polygon vertex, so that pass 2 puts them on the edges through them */
    size_t scap, sused;
    long computed;
    bool nomem;
};

static uint64_t mix(uint64_t k)
{
    k ^= k >> 33, k *= 0xff51afd7ed558ccdull, k ^= k >> 33, k *= 0xc4ceb9fe1a85ec53ull, k ^= k >> 33;
    return k;
}

static uint64_t key_of(const struct mesher *ms, const int v[3], const int u[3])
{
    uint64_t X = (uint64_t)(Q * v[0] + u[0]), Y = (uint64_t)(Q * v[1] + u[1]), Z = (uint64_t)(Q * v[2] + u[2]);
    return X + (uint64_t)(Q * ms->n[0] + 1) * (Y + (uint64_t)(Q * ms->n[1] + 1) * Z);
}

/* Open addressing, grown at half full (keys are never UINT64_MAX); *found whether key was there. */
static size_t slot(uint64_t **keys, uint32_t **ids, size_t *cap, size_t used, uint64_t key, bool *found, bool *nomem)
{
    if (used * 2 >= *cap) {
        size_t nc = *cap ? *cap * 2 : 4096;
        uint64_t *nk = malloc(nc * sizeof *nk);
        uint32_t *ni = ids ? malloc(nc * sizeof *ni) : NULL;
        if (!nk || (ids && !ni)) {
            free(nk), free(ni);
            *nomem = true;
            *found = false;
            return SIZE_MAX;
        }
        memset(nk, 0xff, nc * sizeof *nk);
        for (size_t i = 0; i < *cap; i++)
            if ((*keys)[i] != UINT64_MAX) {
                size_t h = mix((*keys)[i]) & (nc - 1);
                while (nk[h] != UINT64_MAX)
                    h = (h + 1) & (nc - 1);
                nk[h] = (*keys)[i];
                if (ids)
                    ni[h] = (*ids)[i];
            }
        free(*keys);
        *keys = nk;
        if (ids)
            free(*ids), *ids = ni;
        *cap = nc;
    }
    size_t h = mix(key) & (*cap - 1);
    while ((*keys)[h] != UINT64_MAX && (*keys)[h] != key)
        h = (h + 1) & (*cap - 1);
    *found = (*keys)[h] == key;
    return h;
}

static void mark(struct mesher *ms, uint64_t key)
{
    bool found;
    size_t h = slot(&ms->seen, NULL, &ms->scap, ms->sused, key, &found, &ms->nomem);
    if (h != SIZE_MAX && !found)
        ms->seen[h] = key, ms->sused++;
}

static bool marked(const struct mesher *ms, uint64_t key)
{
    if (!ms->scap)
        return false;
    size_t h = mix(key) & (ms->scap - 1);
    while (ms->seen[h] != UINT64_MAX && ms->seen[h] != key)
        h = (h + 1) & (ms->scap - 1);
    return ms->seen[h] == key;
}

/* The mesh vertex at point u (quarter units) of voxel v: its id, or -1. */
static long vertex(struct mesher *ms, const int v[3], const int u[3])
{
    uint64_t key = key_of(ms, v, u);
    bool found;
    size_t h = slot(&ms->keys, &ms->ids, &ms->cap, ms->used, key, &found, &ms->nomem);
    if (h == SIZE_MAX)
        return -1;
    if (found)
        return ms->ids[h];
    size_t i = ms->m.n_vert, cap = ms->vcap;
    if (i >= ISO_MAX_VERTICES || mem_reserve((void **)&ms->m.pos, &cap, 3 * (i + 1), sizeof(float))) {
        ms->nomem = true;
        return -1;
    }
    ms->vcap = cap;
    bool corner = true;
    for (int d = 0; d < 3; d++) {
        ms->m.pos[3 * i + d] = (float)(ms->lo[d] + ms->d[d] * (v[d] + (double)u[d] / Q));
        corner = corner && u[d] % Q == 0;
    }
    ms->computed += !corner;
    ms->keys[h] = key, ms->ids[h] = (uint32_t)i, ms->used++;
    return (long)ms->m.n_vert++;
}

static void triangle(struct mesher *ms, long a, long b, long c)
{
    if (a < 0 || b < 0 || c < 0 || a == b || b == c || a == c)
        return;
    size_t t = ms->m.n_tri;
    if (mem_reserve((void **)&ms->m.tri, &ms->tcap, 3 * (t + 1), sizeof(uint32_t))) {
        ms->nomem = true;
        return;
    }
    ms->m.tri[3 * t] = (uint32_t)a, ms->m.tri[3 * t + 1] = (uint32_t)b, ms->m.tri[3 * t + 2] = (uint32_t)c;
    ms->m.n_tri++;
}

static int gcd(int a, int b)
{
    a = abs(a), b = abs(b);
    while (b) {
        int t = a % b;
        a = b, b = t;
    }
    return a;
}

/* A convex polygon of voxel v (points u[0..n), counter-clockwise seen from outside): with pass
 * 1 (mark) its vertices noted; else triangulated, with every noted vertex that lies on one of its
 * sides put in (a neighbour's polygon ends there), fanned from a vertex none of whose sides'
 * neighbours is on a straight line with it, else from its centre. */
static void polygon(struct mesher *ms, const int v[3], const int (*u)[3], int n, bool pass1)
{
    if (pass1) {
        for (int k = 0; k < n; k++)
            mark(ms, key_of(ms, v, u[k]));
        return;
    }
    int p[4 * MAX_PV][3], m = 0;
    for (int k = 0; k < n; k++) {
        const int *a = u[k], *b = u[(k + 1) % n];
        int g = gcd(gcd(b[0] - a[0], b[1] - a[1]), b[2] - a[2]);
        memcpy(p[m++], a, sizeof p[0]);
        for (int s = 1; s < g && m < 4 * MAX_PV; s++) {
            int x[3];
            for (int d = 0; d < 3; d++)
                x[d] = a[d] + (b[d] - a[d]) / g * s;
            if (marked(ms, key_of(ms, v, x)))
                memcpy(p[m++], x, sizeof x);
        }
    }
    bool flat[4 * MAX_PV];
    for (int k = 0; k < m; k++) { /* on a line with its neighbours */
        const int *a = p[(k + m - 1) % m], *b = p[k], *c = p[(k + 1) % m];
        long cr[3] = {(long)(b[1] - a[1]) * (c[2] - b[2]) - (long)(b[2] - a[2]) * (c[1] - b[1]),
                      (long)(b[2] - a[2]) * (c[0] - b[0]) - (long)(b[0] - a[0]) * (c[2] - b[2]),
                      (long)(b[0] - a[0]) * (c[1] - b[1]) - (long)(b[1] - a[1]) * (c[0] - b[0])};
        flat[k] = !cr[0] && !cr[1] && !cr[2];
    }
    long id[4 * MAX_PV];
    for (int k = 0; k < m; k++)
        id[k] = vertex(ms, v, p[k]);
    int apex = -1;
    for (int k = 0; k < m && apex < 0; k++)
        if (!flat[k] && !flat[(k + 1) % m] && !flat[(k + m - 1) % m])
            apex = k;
    if (apex >= 0) {
        for (int k = 1; k + 1 < m; k++)
            triangle(ms, id[apex], id[(apex + k) % m], id[(apex + k + 1) % m]);
        return;
    }
    /* the centre: a vertex of this polygon alone (off the lattice: its own key) */
    size_t i = ms->m.n_vert, cap = ms->vcap;
    if (i >= ISO_MAX_VERTICES || mem_reserve((void **)&ms->m.pos, &cap, 3 * (i + 1), sizeof(float))) {
        ms->nomem = true;
        return;
    }
    ms->vcap = cap;
    for (int d = 0; d < 3; d++) {
        double o = 0;
        for (int k = 0; k < m; k++)
            o += (double)p[k][d] / m;
        ms->m.pos[3 * i + d] = (float)(ms->lo[d] + ms->d[d] * (v[d] + o / Q));
    }
    ms->computed++;
    long c = (long)ms->m.n_vert++;
    for (int k = 0; k < m; k++)
        triangle(ms, c, id[k], id[(k + 1) % m]);
}

/* Voxel v's part of the surface: its caps; its open faces as the chamfers left them; and on a
 * face it shares with a voxel (once, from the voxel below; an inner voxel draws nothing, so its
 * neighbours draw its faces), the corner triangles one of the two cuts and the other does not,
 * drawn outward from the one that keeps them. */
static void voxel_surface(struct mesher *ms, const int v[3], const struct solid *s, bool pass1)
{
    for (int k = 0; k < s->n_polys; k++) {
        const struct poly *pl = &s->polys[k];
        if (pl->face >= 6 || (s->open >> pl->face & 1))
            polygon(ms, v, (const int(*)[3])pl->p, pl->n, pass1);
    }
    for (int f = 0; f < 6; f++) {
        int w[3] = {v[0], v[1], v[2]};
        w[f >> 1] += f & 1 ? 1 : -1;
        if (s->open >> f & 1)
            continue;
        int wopen = ms->open[at(ms->n, w)]; /* (w is in the set: f is closed) */
        if (!(f & 1) && wopen)
            continue; /* (drawn from w) */
        int mv = cut_corners(s->open, f), mw0 = cut_corners(wopen, f ^ 1), mw = 0;
        for (int k = 0; k < 4; k++)
            mw |= (mw0 >> corner_across(k) & 1) << k;
        int c[4][3];
        face_corners(f, c);
        for (int k = 0; k < 4; k++) {
            if (!((mv ^ mw) >> k & 1))
                continue;
            int t[3][3], prev = (k + 3) % 4, next = (k + 1) % 4;
            memcpy(t[0], c[k], sizeof t[0]);
            for (int d = 0; d < 3; d++) {
                t[1][d] = (c[k][d] + c[next][d]) / 2;
                t[2][d] = (c[k][d] + c[prev][d]) / 2;
            }
            if (mv >> k & 1) { /* w keeps it: outward from w, toward v */
                int r[3][3];
                memcpy(r[0], t[0], sizeof r[0]), memcpy(r[1], t[2], sizeof r[1]), memcpy(r[2], t[1], sizeof r[2]);
                polygon(ms, v, (const int(*)[3])r, 3, pass1);
            } else {
                polygon(ms, v, (const int(*)[3])t, 3, pass1);
            }
        }
    }
}

int matrix_mesh(const int n[3], const uint8_t *vox, const double lo[3], const double d[3], struct trimesh *out,
                struct matrix_stats *st, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    struct mesher ms = {.n = n, .vox = vox};
    memcpy(ms.lo, lo, sizeof ms.lo);
    memcpy(ms.d, d, sizeof ms.d);
    struct solid *table = malloc(64 * sizeof *table);
    if (!table)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    solids(table);
    size_t nv = (size_t)n[0] * n[1] * n[2];
    if (!(ms.open = malloc(nv ? nv : 1))) {
        free(table);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    int v[3];
    for (v[2] = 0; v[2] < n[2]; v[2]++)
        for (v[1] = 0; v[1] < n[1]; v[1]++)
            for (v[0] = 0; v[0] < n[0]; v[0]++)
                ms.open[at(n, v)] = vox[at(n, v)] ? (uint8_t)open_faces(n, vox, v) : 0;
    for (int pass = 0; pass < 2 && !ms.nomem; pass++)
        for (v[2] = 0; v[2] < n[2]; v[2]++)
            for (v[1] = 0; v[1] < n[1]; v[1]++)
                for (v[0] = 0; v[0] < n[0] && !ms.nomem; v[0]++) {
                    int open = ms.open[at(n, v)];
                    if (open)
                        voxel_surface(&ms, v, &table[open], pass == 0);
                }
    free(table);
    free(ms.open);
    free(ms.keys), free(ms.ids), free(ms.seen);
    long mid = 0; /* (where solids touch at a point: a voxel corner both keep, their other corners apart) */
    if (!ms.nomem && trimesh_manifold(&ms.m, &ms.vcap, &ms.tcap, &mid))
        ms.nomem = true;
    if (ms.nomem) {
        bool limit = ms.m.n_vert >= ISO_MAX_VERTICES;
        trimesh_free(&ms.m);
        return sf_fail(err, limit ? SF_ELIMIT : SF_ENOMEM, "", "the mesh would take more memory than there is");
    }
    *out = ms.m;
    if (st)
        st->computed_vertices = ms.computed + mid, st->dropped_voxels = 0;
    return 0;
}
