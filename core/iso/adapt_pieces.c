/* adapt_pieces.c - the adaptive hierarchy's merge=pieces mode (issue 45; adapt.h has the method):
 * each super-cell of the hierarchy gives one vertex per connected piece of the full-resolution
 * surface inside it (Manifold Dual Contouring's idea), placed by a least-squares fit to the fine
 * tangent planes (a QEF), where the piece is a disk, its merge keeps the mesh a 2-manifold of the
 * same topology and the two-way distance to the full-resolution mesh stays within max_error.
 * It starts from marching cubes' mesh (mc.c) and merges its vertices, so it draws no cell itself
 * and never cracks; it must not write what mc.c or the cell-drawing modes own. */
#include "adapt_internal.h"
#include "kept.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"

#define COLOURS 27          /* blocks 3 apart on every axis never touch each other's triangles */
#define CELL_EPS 1e-4       /* a vertex's cell from its place: below ISO_EDGE_MARGIN, above float's error */
#define QEF_TRUNCATE 0.1    /* the fit's directions whose eigenvalue is under this part of the largest are
                             * left at the mass point (the planes do not fix them: a flat piece slides) */
#define QEF_REACH 0.5       /* a fit further than this many samples outside its block takes the mass point */
#define FLIP_COS 0.2        /* a triangle the merge turns by more than acos(this) (78 deg) refuses it: folds */
#define MAX_LOCAL 4096      /* triangles round one piece: a piece with more stays finer */
#define LATTICE 4           /* a fine triangle no one triangle covers: its points at 1/LATTICE steps of
                             * barycentric coordinates each within e of the mesh (the bench's k = 2) */
#define NO_WITNESS UINT32_MAX
#define STAR_CHUNK 65536    /* the stars' store grows by this many entries, never moved (> MAX_LOCAL) */

struct ltri {               /* a triangle round the piece being merged, as the merge would leave it */
    uint32_t t, c[3], o[3]; /* its id, corners after and before */
    uint8_t alive;
};

struct qtri {               /* a triangle round the piece as the merge leaves it */
    uint32_t t, c[3];       /* its id, corners */
    double T[3][3];         /* their places */
    double lo[3], hi[3];    /* its box grown by e */
    double n[3], u[3], v[3]; /* its unit normal, edges from corner 0 */
    double uu, uv, vv, inv; /* their products, 1 / the Gram determinant (0: a sliver: the exact test) */
    bool ready;             /* the fields after T set (qtri_prepare: when first tested) */
};

struct cand {               /* a full-resolution triangle near the piece */
    double T[3][3];
    float lo[3], hi[3];
};

struct wup {
    uint32_t sample, tri, tri2;
};

struct pscratch {           /* one slab's working memory (each list with its capacity) */
    uint32_t *comp;         /* the piece's representatives, breadth first from the least */
    size_t ccap;
    struct ltri *lt;        /* the triangles round the piece */
    size_t lcap;
    int n_lt;
    uint32_t *link;         /* the merged vertex's neighbours */
    size_t kcap;
    struct cand *cand;      /* full-resolution triangles round the piece (and neighbours) */
    size_t dcap;
    struct wup *wu;         /* the witnesses the merge would set */
    size_t wcap;
    struct qtri *qt;        /* the mesh's triangles round the piece and its neighbours, after the merge */
    size_t qcap;
    int *use;               /* S->qt's entries round one fine triangle's corners */
    size_t ucap;
    int *lstart, *lqt;      /* S->qt's triangles round each local representative (p, then link's) */
    size_t lscap, lqcap;
    uint32_t *stamp;        /* per S->qt entry: the fine triangle that took it last */
    size_t stcap;
    uint8_t *added;         /* per link entry: its fine triangles among the candidates */
    size_t acap;
    uint32_t **chunk;       /* the stars this slab wrote (STAR_CHUNK entries each, never moved) */
    size_t nchunk, chcap, chused;
    bool nomem;
};

struct pieces {
    struct iso_grid g;      /* the samples (borrowed from iso_adapt_begin's caller, or own: own) */
    float *own;
    struct iso_opts o;
    int L;
    double e;               /* max_error */
    double org[3], sp[3];   /* the virtual grid's (with the pad layer: closed) */
    int NV[3];              /* its nodes */
    int phase;
    struct iso_job *mc;
    int n_mc;
    int rc;
    struct sf_err err;
    /* the full-resolution mesh and what the merges keep of it */
    struct trimesh fine;
    uint32_t nv, nt;
    uint64_t *cellk;        /* each fine vertex's cell in the virtual grid, x | y << 21 | z << 42 */
    uint32_t *inc_at, *inc; /* each fine vertex's triangles (CSR) */
    uint32_t **star, *nstar, *sl; /* each representative's live triangles in the order of its fine vertices'
                             * (the walk of inc from each in turn), first in sl (inc's copy), then
                             * where the merge that made it wrote them (pscratch's chunks) */
    uint64_t *lkey;         /* the local index of a representative round the merge being tried (lidx) */
    uint32_t *lidx;         /* when its lkey is that merge's id: 0 the merged vertex, 1 + j link[j] */
    uint32_t *cur;          /* each triangle's corners now (representatives) */
    uint8_t *dead;
    float *cp, *cn;         /* each representative's place and normal */
    uint32_t *mnext, *mtail; /* the fine vertices a representative stands for (a list from it) */
    uint32_t *rep;          /* each fine vertex's representative */
    uint8_t *lvl;           /* the level that made each representative (1: a fine vertex), 0 when merged away */
    uint32_t *wit, *wit2;   /* each fine triangle's witness: a triangle of the mesh within e of its three
                             * corners, so of all of it (the distance to a triangle is convex; wit2
                             * NO_WITNESS), or two such that each of its lattice points is within e
                             * of one of them; else NO_WITNESS: its lattice points are each within e
                             * of some triangle round its corners' representatives */
    uint64_t *mark;         /* each representative's piece being merged (its least vertex, its level) */
    uint64_t *tmark;        /* each triangle's: the piece being merged when it has a corner in it */
    /* the level's blocks and the representatives in each */
    int nb[3];
    uint32_t *bstart, *brep;
    size_t bcap;
    struct pscratch sc[ADAPT_SLABS];
    /* the result */
    struct trimesh out;
    long cells[ISO_MAX_LEVELS + 1];
    /* kept (opts keep): what edits need */
    bool keep, kept;
    float *samples;
    uint32_t *ids;
    uint32_t next_id;
};

/* ---- small numerics ---- */

static void sub3(const double a[3], const double b[3], double o[3]) { o[0] = a[0] - b[0], o[1] = a[1] - b[1], o[2] = a[2] - b[2]; }
static void cross3(const double a[3], const double b[3], double o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1], o[1] = a[2] * b[0] - a[0] * b[2], o[2] = a[0] * b[1] - a[1] * b[0];
}

/* The eigenvectors (columns of V) and eigenvalues w of the symmetric 3x3 A, by Jacobi rotations. */
static void eigen3(double A[3][3], double V[3][3], double w[3])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            V[i][j] = i == j;
    for (int sweep = 0; sweep < 12; sweep++) {
        double off = A[0][1] * A[0][1] + A[0][2] * A[0][2] + A[1][2] * A[1][2];
        if (off < 1e-24)
            break;
        for (int p = 0; p < 2; p++)
            for (int q = p + 1; q < 3; q++) {
                if (fabs(A[p][q]) < 1e-30)
                    continue;
                double th = (A[q][q] - A[p][p]) / (2 * A[p][q]);
                double t = (th >= 0 ? 1 : -1) / (fabs(th) + sqrt(th * th + 1)), c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < 3; k++) { /* A = J^T A J */
                    double akp = A[k][p], akq = A[k][q];
                    A[k][p] = c * akp - s * akq, A[k][q] = s * akp + c * akq;
                }
                for (int k = 0; k < 3; k++) {
                    double apk = A[p][k], aqk = A[q][k];
                    A[p][k] = c * apk - s * aqk, A[q][k] = s * apk + c * aqk;
                }
                for (int k = 0; k < 3; k++) {
                    double vkp = V[k][p], vkq = V[k][q];
                    V[k][p] = c * vkp - s * vkq, V[k][q] = s * vkp + c * vkq;
                }
            }
    }
    for (int i = 0; i < 3; i++)
        w[i] = A[i][i];
}

/* ---- the state ---- */

static void scratch_free(struct pscratch *s)
{
    for (size_t i = 0; i < s->nchunk; i++)
        free(s->chunk[i]);
    free(s->chunk);
    free(s->comp), free(s->lt), free(s->link), free(s->cand), free(s->wu), free(s->qt), free(s->use), free(s->lstart), free(s->lqt), free(s->stamp), free(s->added);
    memset(s, 0, sizeof *s);
}

static void work_free(struct pieces *P)
{
    free(P->cellk), free(P->inc_at), free(P->inc), free(P->cur), free(P->dead), free(P->cp), free(P->cn);
    free(P->mnext), free(P->mtail), free(P->rep), free(P->lvl), free(P->wit), free(P->wit2), free(P->mark), free(P->tmark), free(P->bstart), free(P->brep);
    free(P->star), free(P->nstar), free(P->sl), free(P->lkey), free(P->lidx);
    P->cellk = NULL, P->inc_at = P->inc = P->cur = P->mnext = P->mtail = P->rep = P->wit = P->wit2 = P->bstart = P->brep = NULL;
    P->dead = P->lvl = NULL, P->cp = P->cn = NULL, P->mark = P->tmark = P->lkey = NULL;
    P->star = NULL, P->nstar = P->sl = P->lidx = NULL;
    for (int k = 0; k < ADAPT_SLABS; k++)
        scratch_free(&P->sc[k]);
    trimesh_free(&P->fine);
    iso_free(P->mc);
    P->mc = NULL;
}

void pieces_free(struct pieces *P)
{
    if (!P)
        return;
    work_free(P);
    trimesh_free(&P->out);
    free(P->own), free(P->samples), free(P->ids);
    free(P);
}

static int fail(struct pieces *P, int code, const char *msg)
{
    if (!P->rc)
        P->rc = sf_fail(&P->err, code, "", "%s", msg);
    return P->rc;
}

int pieces_begin(const struct iso_grid *g, const struct iso_opts *o, int levels, double max_error, struct pieces **out,
                 struct sf_err *err)
{
    struct pieces *P = calloc(1, sizeof *P);
    if (!P)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    P->g = *g;
    P->o = *o;
    P->o.keep = false;
    P->keep = o->keep;
    P->L = levels;
    P->e = max_error;
    int shift = o->closed ? 1 : 0, n[3] = {g->nx, g->ny, g->nz};
    for (int d = 0; d < 3; d++) {
        P->sp[d] = g->spacing[d];
        P->org[d] = g->origin[d] - shift * g->spacing[d];
        P->NV[d] = n[d] + 2 * shift;
        if (P->NV[d] >= 1 << 21) {
            free(P);
            return sf_fail(err, SF_ELIMIT, "?dims", "merge=pieces takes at most %d samples an axis", (1 << 21) - 3);
        }
    }
    int rc = iso_begin(&P->g, &P->o, ADAPT_SLABS, &P->mc, err);
    if (rc) {
        free(P);
        return rc;
    }
    P->n_mc = iso_n_slabs(P->mc);
    *out = P;
    return 0;
}

int pieces_phases(const struct pieces *P) { return 2 + (P->L - 1) * COLOURS; }

/* Block planes of colour cz at the level of phase (>= 2). */
static int colour_planes(const struct pieces *P, int cz) { return P->nb[2] > cz ? (P->nb[2] - cz + 2) / 3 : 0; }

int pieces_n_slabs(const struct pieces *P)
{
    if (P->phase < 2)
        return P->n_mc;
    int c = (P->phase - 2) % COLOURS, n = colour_planes(P, c / 9);
    return n < 1 ? 1 : n < ADAPT_SLABS ? n : ADAPT_SLABS;
}

/* ---- the representatives' pieces ---- */

static void cell_of(const struct pieces *P, uint32_t v, int c[3])
{
    uint64_t k = P->cellk[v];
    c[0] = (int)(k & 0x1fffff), c[1] = (int)(k >> 21 & 0x1fffff), c[2] = (int)(k >> 42);
}

static size_t block_of(const struct pieces *P, uint32_t v, int l)
{
    int c[3];
    cell_of(P, v, c);
    return (size_t)(c[0] >> (l - 1)) + (size_t)P->nb[0] * ((size_t)(c[1] >> (l - 1)) + (size_t)P->nb[1] * (size_t)(c[2] >> (l - 1)));
}

/* The level's blocks (P->nb) and its representatives sorted by block (counting sort). 0 or -1. */
static int bucket(struct pieces *P, int l)
{
    size_t nb = 1;
    for (int d = 0; d < 3; d++) {
        P->nb[d] = ((P->NV[d] - 1) >> (l - 1)) + 1;
        nb *= (size_t)P->nb[d];
    }
    if (nb + 1 > UINT32_MAX)
        return -1;
    free(P->bstart);
    if (!(P->bstart = calloc(nb + 1, sizeof *P->bstart)))
        return -1;
    if (!P->brep && !(P->brep = malloc(((size_t)P->nv + 1) * sizeof *P->brep)))
        return -1;
    for (uint32_t v = 0; v < P->nv; v++)
        if (P->lvl[v])
            P->bstart[block_of(P, v, l) + 1]++;
    for (size_t b = 0; b < nb; b++)
        P->bstart[b + 1] += P->bstart[b];
    uint32_t *fill = malloc((nb + 1) * sizeof *fill);
    if (!fill)
        return -1;
    memcpy(fill, P->bstart, (nb + 1) * sizeof *fill);
    for (uint32_t v = 0; v < P->nv; v++)
        if (P->lvl[v])
            P->brep[fill[block_of(P, v, l)]++] = v;
    free(fill);
    return 0;
}

/* The full-resolution mesh into the merge's lists: cells, incidences, every vertex its own
 * representative. 0 or -1. */
static int prepare(struct pieces *P)
{
    struct trimesh *m = &P->fine;
    if (m->n_vert >= UINT32_MAX / 2 || m->n_tri >= UINT32_MAX / 2)
        return -1;
    uint32_t nv = P->nv = (uint32_t)m->n_vert, nt = P->nt = (uint32_t)m->n_tri;
    size_t V = (size_t)nv + 1, T = (size_t)nt + 1;
    P->cellk = malloc(V * sizeof *P->cellk);
    P->inc_at = calloc(V + 1, sizeof *P->inc_at);
    P->inc = malloc(3 * T * sizeof *P->inc);
    P->cur = malloc(3 * T * sizeof *P->cur);
    P->dead = calloc(T, 1);
    P->cp = malloc(3 * V * sizeof *P->cp);
    P->cn = malloc(3 * V * sizeof *P->cn);
    P->mnext = malloc(V * sizeof *P->mnext);
    P->mtail = malloc(V * sizeof *P->mtail);
    P->rep = malloc(V * sizeof *P->rep);
    P->lvl = malloc(V);
    P->wit = malloc(T * sizeof *P->wit);
    P->wit2 = malloc(T * sizeof *P->wit2);
    P->mark = calloc(V, sizeof *P->mark);
    P->tmark = calloc(T, sizeof *P->tmark);
    P->star = malloc(V * sizeof *P->star);
    P->nstar = malloc(V * sizeof *P->nstar);
    P->sl = malloc(3 * T * sizeof *P->sl);
    P->lkey = calloc(V, sizeof *P->lkey);
    P->lidx = malloc(V * sizeof *P->lidx);
    if (!P->cellk || !P->inc_at || !P->inc || !P->cur || !P->dead || !P->cp || !P->cn || !P->mnext || !P->mtail || !P->rep ||
        !P->lvl || !P->wit || !P->wit2 || !P->mark || !P->tmark || !P->star || !P->nstar || !P->sl || !P->lkey || !P->lidx)
        return -1;
    for (uint32_t v = 0; v < nv; v++) {
        uint64_t k = 0;
        for (int d = 0; d < 3; d++) {
            double u = floor((m->pos[3 * v + d] - P->org[d]) / P->sp[d] + CELL_EPS);
            long c = u < 0 ? 0 : u > P->NV[d] - 2 ? P->NV[d] - 2 : (long)u;
            k |= (uint64_t)c << (21 * d);
        }
        P->cellk[v] = k;
        P->mnext[v] = UINT32_MAX, P->mtail[v] = v, P->rep[v] = v;
        P->lvl[v] = 1;
    }
    if (!m->nrm) { /* (opts without normals: the triangles' own, area-weighted) */
        if (!(m->nrm = calloc(3 * V, sizeof *m->nrm)))
            return -1;
        for (uint32_t t = 0; t < nt; t++) {
            double q[3][3], u[3], w[3], n[3];
            for (int k = 0; k < 3; k++)
                for (int d = 0; d < 3; d++)
                    q[k][d] = m->pos[3 * m->tri[3 * t + k] + d];
            sub3(q[1], q[0], u), sub3(q[2], q[0], w), cross3(u, w, n);
            for (int k = 0; k < 3; k++)
                for (int d = 0; d < 3; d++)
                    m->nrm[3 * m->tri[3 * t + k] + d] += (float)n[d];
        }
        for (uint32_t v = 0; v < nv; v++) {
            float *n = m->nrm + 3 * (size_t)v, len = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            for (int d = 0; d < 3 && len > 0; d++)
                n[d] /= len;
        }
    }
    memcpy(P->cp, m->pos, 3 * (size_t)nv * sizeof *P->cp);
    memcpy(P->cn, m->nrm, 3 * (size_t)nv * sizeof *P->cn);
    memcpy(P->cur, m->tri, 3 * (size_t)nt * sizeof *P->cur);
    for (size_t i = 0; i < 3 * (size_t)nt; i++)
        P->inc_at[m->tri[i] + 1]++;
    for (uint32_t v = 0; v < nv; v++)
        P->inc_at[v + 1] += P->inc_at[v];
    uint32_t *fill = malloc(V * sizeof *fill);
    if (!fill)
        return -1;
    memcpy(fill, P->inc_at, V * sizeof *fill);
    for (uint32_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->tri[3 * t + k];
            P->inc[fill[v]++] = t;
        }
    free(fill);
    memcpy(P->sl, P->inc, 3 * (size_t)nt * sizeof *P->sl);
    for (uint32_t v = 0; v < nv; v++)
        P->star[v] = P->sl + P->inc_at[v], P->nstar[v] = P->inc_at[v + 1] - P->inc_at[v];
    for (uint32_t t = 0; t < nt; t++)
        P->wit[t] = t, P->wit2[t] = NO_WITNESS;
    return bucket(P, 2);
}

static void pos_of(const struct pieces *P, uint32_t v, double x[3])
{
    x[0] = P->cp[3 * v], x[1] = P->cp[3 * v + 1], x[2] = P->cp[3 * v + 2];
}

static bool has(const uint32_t c[3], uint32_t v) { return c[0] == v || c[1] == v || c[2] == v; }

/* Whether representative v belongs to the piece being merged (mark id). */
static inline bool in_piece(const struct pieces *P, uint32_t v, uint64_t id) { return P->mark[v] == id; }

/* Representative v's index round the merge being tried (lkey, lidx), or -1. */
static inline int local(const struct pieces *P, uint32_t v, uint64_t id) { return P->lkey[v] == id ? (int)P->lidx[v] : -1; }

static bool grow(struct pscratch *S, void **p, size_t *cap, size_t need, size_t elem)
{
    if (mem_reserve(p, cap, need, elem)) {
        S->nomem = true;
        return false;
    }
    return true;
}

/* The live triangles round the piece comp[0 .. n-1] (marked id) into S->lt, each once. false: too
 * many, or no memory. */
static bool gather(const struct pieces *P, struct pscratch *S, int n, uint64_t id)
{
    S->n_lt = 0;
    for (int i = 0; i < n; i++) {
        uint32_t r = S->comp[i];
        for (uint32_t k = 0; k < P->nstar[r]; k++) {
            uint32_t t = P->star[r][k];
            const uint32_t *c = P->cur + 3 * (size_t)t;
            uint32_t least = UINT32_MAX; /* each once: from the piece's least corner */
            for (int j = 0; j < 3; j++)
                if (in_piece(P, c[j], id) && c[j] < least)
                    least = c[j];
            if (least != r)
                continue;
            if (S->n_lt >= MAX_LOCAL || !grow(S, (void **)&S->lt, &S->lcap, (size_t)S->n_lt + 1, sizeof *S->lt))
                return false;
            struct ltri *L = &S->lt[S->n_lt++];
            L->t = t, L->alive = 1;
            memcpy(L->c, c, sizeof L->c);
            memcpy(L->o, c, sizeof L->o);
        }
    }
    return true;
}

/* Adds w to list (of *n) unless there. */
static void add_unique(uint32_t *list, int *n, uint32_t w)
{
    for (int i = 0; i < *n; i++)
        if (list[i] == w)
            return;
    list[(*n)++] = w;
}

/* Collapses edge p-s in S->lt when the link condition holds (Dey et al.: the links of p and s
 * share just the two vertices across the edge, and the two are not a tetrahedron's), which keeps
 * a closed 2-manifold's topology: false when it does not. */
static bool collapse(struct pscratch *S, uint32_t p, uint32_t s)
{
    enum { NB = 256 };
    uint32_t apex[2], np_[NB], ns_[NB];
    int na = 0, nnp = 0, nns = 0;
    for (int i = 0; i < S->n_lt; i++) {
        struct ltri *L = &S->lt[i];
        if (!L->alive)
            continue;
        bool hp = has(L->c, p), hs = has(L->c, s);
        if (hp && hs) {
            if (na == 2)
                return false;
            apex[na++] = L->c[0] != p && L->c[0] != s ? L->c[0] : L->c[1] != p && L->c[1] != s ? L->c[1] : L->c[2];
        }
        for (int k = 0; k < 3; k++) {
            if (hp && L->c[k] != p) {
                if (nnp >= NB)
                    return false;
                add_unique(np_, &nnp, L->c[k]);
            }
            if (hs && L->c[k] != s) {
                if (nns >= NB)
                    return false;
                add_unique(ns_, &nns, L->c[k]);
            }
        }
    }
    if (na != 2 || apex[0] == apex[1])
        return false;
    for (int i = 0; i < nnp; i++) {
        if (np_[i] == s || np_[i] == apex[0] || np_[i] == apex[1])
            continue;
        for (int j = 0; j < nns; j++)
            if (ns_[j] == np_[i])
                return false;
    }
    /* the tetrahedron: p a b and s a b both there */
    int tet = 0;
    for (int i = 0; i < S->n_lt; i++) {
        struct ltri *L = &S->lt[i];
        if (L->alive && has(L->c, apex[0]) && has(L->c, apex[1]) && (has(L->c, p) || has(L->c, s)))
            tet++;
    }
    if (tet >= 2) /* (p a b and s a b: the edge's triangles hold one apex each) */
        return false;
    for (int i = 0; i < S->n_lt; i++) {
        struct ltri *L = &S->lt[i];
        if (!L->alive)
            continue;
        if (has(L->c, p) && has(L->c, s)) {
            L->alive = 0;
            continue;
        }
        for (int k = 0; k < 3; k++)
            if (L->c[k] == s)
                L->c[k] = p;
    }
    return true;
}

/* Whether every edge from a vertex of the piece has two triangles (an open mesh's border stays). */
static bool interior(const struct pscratch *S, int n)
{
    for (int i = 0; i < n; i++) {
        uint32_t r = S->comp[i];
        for (int a = 0; a < S->n_lt; a++) {
            const struct ltri *L = &S->lt[a];
            if (!has(L->c, r))
                continue;
            for (int k = 0; k < 3; k++) {
                uint32_t w = L->c[k];
                if (w == r)
                    continue;
                int count = 0;
                for (int b = 0; b < S->n_lt; b++)
                    count += has(S->lt[b].c, r) && has(S->lt[b].c, w);
                if (count != 2)
                    return false;
            }
        }
    }
    return true;
}

/* The merged vertex: the QEF of the fine vertices' tangent planes, solved about their mass point
 * with small eigenvalues left out (Dual Contouring's truncated pseudo-inverse), kept near its block
 * (lo, side s in samples); its normal the fine normals' mean. */
static void place(const struct pieces *P, const struct pscratch *S, int n, const int lo[3], int s, double x[3],
                  double nrm[3])
{
    const float *fp = P->fine.pos, *fn = P->fine.nrm;
    double c[3] = {0, 0, 0}, A[3][3] = {{0}}, b[3] = {0, 0, 0};
    long k = 0;
    nrm[0] = nrm[1] = nrm[2] = 0;
    for (int i = 0; i < n; i++)
        for (uint32_t m = S->comp[i]; m != UINT32_MAX; m = P->mnext[m], k++)
            for (int d = 0; d < 3; d++)
                c[d] += fp[3 * m + d], nrm[d] += fn[3 * m + d];
    for (int d = 0; d < 3; d++)
        c[d] /= (double)k;
    for (int i = 0; i < n; i++)
        for (uint32_t m = S->comp[i]; m != UINT32_MAX; m = P->mnext[m]) {
            double nn[3] = {fn[3 * m], fn[3 * m + 1], fn[3 * m + 2]};
            double h = nn[0] * (fp[3 * m] - c[0]) + nn[1] * (fp[3 * m + 1] - c[1]) + nn[2] * (fp[3 * m + 2] - c[2]);
            for (int r = 0; r < 3; r++) {
                b[r] += nn[r] * h;
                for (int q = 0; q < 3; q++)
                    A[r][q] += nn[r] * nn[q];
            }
        }
    double V[3][3], w[3], wmax = 0;
    eigen3(A, V, w);
    for (int j = 0; j < 3; j++)
        wmax = fmax(wmax, w[j]);
    for (int d = 0; d < 3; d++)
        x[d] = c[d];
    for (int j = 0; j < 3 && wmax > 0; j++) {
        if (w[j] < QEF_TRUNCATE * wmax)
            continue;
        double f = (V[0][j] * b[0] + V[1][j] * b[1] + V[2][j] * b[2]) / w[j];
        for (int d = 0; d < 3; d++)
            x[d] += f * V[d][j];
    }
    for (int d = 0; d < 3; d++) {
        double u = (x[d] - P->org[d]) / P->sp[d];
        if (u < lo[d] - QEF_REACH || u > lo[d] + s + QEF_REACH) {
            memcpy(x, c, sizeof c);
            break;
        }
    }
}

/* A triangle's corners' places, p at x. */
static void corners(const struct pieces *P, const uint32_t c[3], uint32_t p, const double x[3], double q[3][3])
{
    for (int k = 0; k < 3; k++) {
        if (c[k] == p)
            memcpy(q[k], x, 3 * sizeof(double));
        else
            pos_of(P, c[k], q[k]);
    }
}

static bool note_witness(struct pscratch *S, int *n, uint32_t sample, uint32_t tri, uint32_t tri2)
{
    if (!grow(S, (void **)&S->wu, &S->wcap, (size_t)*n + 1, sizeof *S->wu))
        return false;
    S->wu[*n].sample = sample, S->wu[*n].tri = tri, S->wu[*n].tri2 = tri2;
    (*n)++;
    return true;
}


/* Q's box and plane from its corners Q->T. */
static void qtri_prepare(struct qtri *Q, double e)
{
    for (int d = 0; d < 3; d++) {
        Q->lo[d] = dmin(Q->T[0][d], dmin(Q->T[1][d], Q->T[2][d])) - e;
        Q->hi[d] = dmax(Q->T[0][d], dmax(Q->T[1][d], Q->T[2][d])) + e;
    }
    sub3(Q->T[1], Q->T[0], Q->u), sub3(Q->T[2], Q->T[0], Q->v), cross3(Q->u, Q->v, Q->n);
    double len = sqrt(dot3(Q->n, Q->n));
    Q->uu = dot3(Q->u, Q->u), Q->uv = dot3(Q->u, Q->v), Q->vv = dot3(Q->v, Q->v);
    double det = Q->uu * Q->vv - Q->uv * Q->uv;
    Q->inv = len > 1e-9 * (Q->uu + Q->vv) && det > 0 ? 1 / det : 0;
    for (int d = 0; d < 3 && len > 0; d++)
        Q->n[d] /= len;
    Q->ready = true;
}

/* Whether a point (w from Q's corner 0, h over its plane, a b c its barycentric coordinates) lies
 * outside one of Q's edges' lines by more than the plane leaves, surely: a coordinate times the
 * height over its edge, squared (a^2 det / |edge|^2), over e^2 - h^2 by more than rounding. */
static bool beyond_edge(const struct qtri *Q, const double w[3], double h, double a, double b, double c, double e)
{
    double room = (e * e - h * h) * (1 + 1e-6) + 1e-9 * (e * e + dot3(w, w)), det = 1 / Q->inv;
    return (a < 0 && a * a * det > room * Q->vv) || (b < 0 && b * b * det > room * Q->uu) ||
           (c < 0 && c * c * det > room * (Q->uu + Q->vv - 2 * Q->uv));
}

/* Whether y lies within e of Q: off its plane by more, no; over the triangle, yes; else exactly. */
static bool plane_near(const struct qtri *Q, const double y[3], double e)
{
    if (Q->inv > 0) {
        double w[3];
        sub3(y, Q->T[0], w);
        double h = dot3(w, Q->n);
        if (h > e || h < -e)
            return false;
        double wu = dot3(w, Q->u), wv = dot3(w, Q->v);
        double a = (Q->vv * wu - Q->uv * wv) * Q->inv, b = (Q->uu * wv - Q->uv * wu) * Q->inv, c = 1 - a - b;
        if (a >= 0 && b >= 0 && a + b <= 1)
            return true;
        if (beyond_edge(Q, w, h, a, b, c, e))
            return false;
    }
    return trimesh_point_dist(y, Q->T[0], Q->T[1], Q->T[2]) <= e;
}

static bool in_box(const struct qtri *Q, const double y[3])
{
    return y[0] >= Q->lo[0] && y[0] <= Q->hi[0] && y[1] >= Q->lo[1] && y[1] <= Q->hi[1] && y[2] >= Q->lo[2] &&
           y[2] <= Q->hi[2];
}

static bool qtri_near(const struct qtri *Q, const double y[3], double e) { return in_box(Q, y) && plane_near(Q, y, e); }

/* Adds triangle t (corners c, p at x) to S->qt as entry (*n)++: false for no memory. */
static bool add_qt(const struct pieces *P, struct pscratch *S, int *n, uint32_t t, const uint32_t c[3], uint32_t p,
                   const double x[3])
{
    if (!grow(S, (void **)&S->qt, &S->qcap, (size_t)*n + 1, sizeof *S->qt))
        return false;
    struct qtri *Q = &S->qt[(*n)++];
    Q->t = t;
    memcpy(Q->c, c, sizeof Q->c);
    corners(P, c, p, x, Q->T);
    Q->ready = false;
    return true;
}

/* The triangles round the piece as its merge would leave them, into S->qt with their places: the
 * new vertex's (S->lt), and those of its neighbours (link) that touch no vertex of the piece. Their
 * count, or -1 (no memory). */
static int local_triangles(const struct pieces *P, struct pscratch *S, uint32_t p, const double x[3], uint64_t id,
                           int n_link)
{
    int n = 0;
    P->lkey[p] = id, P->lidx[p] = 0;
    for (int j = 0; j < n_link; j++)
        P->lkey[S->link[j]] = id, P->lidx[S->link[j]] = (uint32_t)j + 1;
    for (int i = 0; i < S->n_lt; i++)
        if (S->lt[i].alive && !add_qt(P, S, &n, S->lt[i].t, S->lt[i].c, p, x))
            return -1;
    for (int j = 0; j < n_link; j++) {
        uint32_t w = S->link[j];
        for (uint32_t k = 0; k < P->nstar[w]; k++) {
            uint32_t t = P->star[w][k];
            const uint32_t *c = P->cur + 3 * (size_t)t;
            if (P->tmark[t] == id)
                continue; /* (in S->lt) */
            bool earlier = false; /* (each once: from its first neighbour in link) */
            for (int q = 0; q < 3 && !earlier; q++)
                earlier = local(P, c[q], id) >= 1 && local(P, c[q], id) <= j;
            if (!earlier && !add_qt(P, S, &n, t, c, p, x))
                return -1;
        }
    }
    /* the lists by local representative (0: p, 1 + j: link[j]) */
    if (!grow(S, (void **)&S->lstart, &S->lscap, (size_t)n_link + 2, sizeof *S->lstart) ||
        !grow(S, (void **)&S->lqt, &S->lqcap, 3 * (size_t)n + 1, sizeof *S->lqt) ||
        !grow(S, (void **)&S->stamp, &S->stcap, (size_t)n + 1, sizeof *S->stamp))
        return -1;
    memset(S->lstart, 0, ((size_t)n_link + 2) * sizeof *S->lstart);
    for (int pass = 0; pass < 2; pass++) {
        for (int i = 0; i < n; i++)
            for (int k = 0; k < 3; k++) {
                int li = local(P, S->qt[i].c[k], id);
                if (li < 0)
                    continue;
                if (pass == 0)
                    S->lstart[li + 1]++;
                else
                    S->lqt[S->lstart[li]++] = i;
            }
        if (pass == 0)
            for (int j = 0; j <= n_link; j++)
                S->lstart[j + 1] += S->lstart[j];
        else
            for (int j = n_link; j >= 0; j--) /* (filled from each start: shift back) */
                S->lstart[j + 1] = S->lstart[j];
    }
    S->lstart[0] = 0;
    for (int i = 0; i < n; i++)
        S->stamp[i] = UINT32_MAX;
    return n;
}


/* Whether witness w of a fine triangle stays as it is through the merge of the piece marked id
 * (its triangles marked so in tmark). */
static bool witness_holds(const struct pieces *P, uint32_t w, uint64_t id)
{
    return w != NO_WITNESS && !P->dead[w] && P->tmark[w] != id;
}

/* Whether fine triangle F (its corners' representatives R, the piece's as p) lies within e of the
 * triangles round R as the merge leaves them (S->qt, n_qt of them, and for a representative outside
 * the piece and its neighbours, its own): one triangle within e of its three corners (the witness),
 * else each of its lattice points within e of one. Its witness noted. */
static bool fine_ok(const struct pieces *P, struct pscratch *S, uint32_t F, const uint32_t R[3], int n_qt, uint64_t id,
                    int *n_wu)
{
    double f[3][3];
    for (int k = 0; k < 3; k++)
        for (int d = 0; d < 3; d++)
            f[k][d] = P->fine.pos[3 * (size_t)P->fine.tri[3 * (size_t)F + k] + d];
    /* the candidates: S->qt's round R, then the stars of R's outside representatives, after them */
    int n = n_qt, n_use = 0;
    if (!grow(S, (void **)&S->use, &S->ucap, (size_t)n_qt + 1, sizeof *S->use))
        return false;
    for (int k = 0; k < 3; k++) {
        uint32_t r = R[k];
        int li = local(P, r, id);
        if (li >= 0) {
            for (int j = S->lstart[li]; j < S->lstart[li + 1]; j++)
                if (S->stamp[S->lqt[j]] != F)
                    S->stamp[S->lqt[j]] = F, S->use[n_use++] = S->lqt[j];
            continue;
        }
        if ((k > 0 && R[0] == r) || (k > 1 && R[1] == r))
            continue;
        for (uint32_t j = 0; j < P->nstar[r]; j++) {
            uint32_t t = P->star[r][j];
            const uint32_t *c = P->cur + 3 * (size_t)t;
            if (P->tmark[t] == id)
                continue;
            if (!grow(S, (void **)&S->qt, &S->qcap, (size_t)n + 1, sizeof *S->qt))
                return false;
            struct qtri *Q = &S->qt[n++];
            Q->t = t;
            memcpy(Q->c, c, sizeof Q->c);
            corners(P, c, UINT32_MAX, NULL, Q->T);
            Q->ready = false;
        }
    }
    if (!grow(S, (void **)&S->use, &S->ucap, (size_t)n + 1, sizeof *S->use))
        return false;
    int *use = S->use;
    for (int i = n_qt; i < n; i++)
        use[n_use++] = i;
    /* the old witnesses first: most often one still is, and the search stops at it */
    for (int w = 0, at = 0; w < 2; w++) {
        uint32_t old = w ? P->wit2[F] : P->wit[F];
        for (int j = at; j < n_use && old != NO_WITNESS; j++)
            if (S->qt[use[j]].t == old) {
                int u = use[j];
                use[j] = use[at], use[at++] = u;
                break;
            }
    }
    for (int j = 0; j < n_use; j++) {
        struct qtri *Q = &S->qt[use[j]];
        if (!Q->ready)
            qtri_prepare(Q, P->e);
        if (in_box(Q, f[0]) && in_box(Q, f[1]) && in_box(Q, f[2]) && plane_near(Q, f[0], P->e) &&
            plane_near(Q, f[1], P->e) && plane_near(Q, f[2], P->e))
            return note_witness(S, n_wu, F, Q->t, NO_WITNESS);
    }
    /* no one triangle: each lattice point near one; two do it (both kept as witnesses), or more */
    int used[2] = {-1, -1}, n_used = 0;
    bool more = false;
    for (int a = 0; a <= LATTICE; a++)
        for (int b = 0; a + b <= LATTICE; b++) {
            double y[3];
            int c = LATTICE - a - b, hit = -1;
            for (int d = 0; d < 3; d++)
                y[d] = (a * f[0][d] + b * f[1][d] + c * f[2][d]) / LATTICE;
            for (int j = 0; j < n_used && hit < 0; j++)
                if (qtri_near(&S->qt[use[used[j]]], y, P->e))
                    hit = used[j];
            for (int j = 0; j < n_use && hit < 0; j++)
                if (j != used[0] && j != used[1] && qtri_near(&S->qt[use[j]], y, P->e))
                    hit = j;
            if (hit < 0)
                return false;
            if (hit != used[0] && hit != used[1]) {
                if (n_used < 2)
                    used[n_used++] = hit;
                else
                    more = true;
            }
        }
    if (more || n_used == 0)
        return note_witness(S, n_wu, F, NO_WITNESS, NO_WITNESS);
    return note_witness(S, n_wu, F, S->qt[use[used[0]]].t, n_used > 1 ? S->qt[use[used[1]]].t : S->qt[use[used[0]]].t);
}

/* Whether representative w's fine triangles are among the candidates: the piece's, and the link's
 * added (S->added) once a point needed them. */
static bool is_cand(const struct pieces *P, const struct pscratch *S, uint32_t w, uint64_t id)
{
    int li = local(P, w, id);
    return in_piece(P, w, id) || (li >= 1 && S->added[li - 1]);
}

/* The full-resolution triangles round the fine vertices of representative r (of the piece, or of
 * the link and not yet added) into S->cand, each once: from the first of its corners whose
 * representative is among the candidates' (r's for the link's). */
static bool add_cands(const struct pieces *P, struct pscratch *S, uint32_t r, uint64_t id, int *n)
{
    const float *fp = P->fine.pos;
    bool piece = in_piece(P, r, id);
    for (uint32_t m = r; m != UINT32_MAX; m = P->mnext[m])
        for (uint32_t k = P->inc_at[m]; k < P->inc_at[m + 1]; k++) {
            const uint32_t *t = P->fine.tri + 3 * (size_t)P->inc[k];
            uint32_t first = UINT32_MAX;
            bool before = false;
            for (int q = 0; q < 3; q++) {
                uint32_t w = P->rep[t[q]];
                if (first == UINT32_MAX && (piece ? in_piece(P, w, id) : w == r))
                    first = t[q];
                before = before || (!piece && is_cand(P, S, w, id));
            }
            if (first != m || before)
                continue;
            if (!grow(S, (void **)&S->cand, &S->dcap, (size_t)*n + 1, sizeof *S->cand))
                return false;
            struct cand *c = &S->cand[(*n)++];
            double(*T)[3] = c->T;
            for (int d = 0; d < 3; d++) {
                T[0][d] = fp[3 * t[0] + d], T[1][d] = fp[3 * t[1] + d], T[2][d] = fp[3 * t[2] + d];
                c->lo[d] = (float)dmin(T[0][d], dmin(T[1][d], T[2][d]));
                c->hi[d] = (float)dmax(T[0][d], dmax(T[1][d], T[2][d]));
            }
        }
    return true;
}

/* Whether point y lies within e of one of the candidates (from *last on). */
static bool near_fine(const struct pieces *P, const struct pscratch *S, int n, const double y[3], int *last)
{
    double e = P->e;
    for (int j = 0, i = *last; j < n; j++, i = i + 1 < n ? i + 1 : 0) {
        const struct cand *c = &S->cand[i];
        if (y[0] < c->lo[0] - e || y[0] > c->hi[0] + e || y[1] < c->lo[1] - e || y[1] > c->hi[1] + e ||
            y[2] < c->lo[2] - e || y[2] > c->hi[2] + e)
            continue;
        if (trimesh_point_dist(y, c->T[0], c->T[1], c->T[2]) <= e) {
            *last = i;
            return true;
        }
    }
    return false;
}

/* Room for n star entries in S's chunks (the caller adds what it used to chused), or NULL. */
static uint32_t *star_room(struct pscratch *S, uint32_t n)
{
    if (!S->nchunk || S->chused + n > STAR_CHUNK) {
        uint32_t *c = malloc(STAR_CHUNK * sizeof *c);
        if (!c || !grow(S, (void **)&S->chunk, &S->chcap, S->nchunk + 1, sizeof *S->chunk)) {
            free(c);
            S->nomem = true;
            return NULL;
        }
        S->chunk[S->nchunk++] = c;
        S->chused = 0;
    }
    return S->chunk[S->nchunk - 1] + S->chused;
}

/* Representative v's star without its dead triangles. */
static void star_prune(struct pieces *P, uint32_t v)
{
    uint32_t k = 0, *st = P->star[v];
    for (uint32_t j = 0; j < P->nstar[v]; j++)
        if (!P->dead[st[j]])
            st[k++] = st[j];
    P->nstar[v] = k;
}

/* Tries to merge the piece comp[0 .. n-1] (marked id) of the block at lo (side s samples) into its
 * least vertex. */
static bool merge_piece(struct pieces *P, struct pscratch *S, int n, uint64_t id, const int lo[3], int s)
{
    if (!gather(P, S, n, id))
        return false;
    if (!P->o.closed && !interior(S, n))
        return false;
    /* comp is in BFS order: each joins one merged before it. One whose edge the link condition
     * refuses (the piece is no disk there, or a neighbour would be pinched) stays out, its own
     * vertex, and so do those that reach the rest through it only; the piece is the rest. */
    uint32_t p = S->comp[0];
    int kept = 1;
    for (int i = 1; i < n; i++) {
        uint32_t r = S->comp[i];
        if (collapse(S, p, r))
            S->comp[kept++] = r;
        else
            P->mark[r] = (((uint64_t)r << 3) | ((id - 1) & 7)) + 1; /* (this level's, not the piece's) */
    }
    if (kept < 2)
        return false;
    if (kept < n) { /* the rest's triangles alone, collapsed again as before */
        n = kept;
        if (!gather(P, S, n, id))
            return false;
        for (int i = 1; i < n; i++)
            if (!collapse(S, p, S->comp[i]))
                return false;
    }
    double x[3], nrm[3];
    place(P, S, n, lo, s, x, nrm);
    /* no triangle turned over or squashed */
    int n_link = 0;
    for (int i = 0; i < S->n_lt; i++) {
        struct ltri *L = &S->lt[i];
        if (!L->alive)
            continue;
        double A[3][3], B[3][3], u[3], v[3], na[3], nb[3];
        corners(P, L->c, p, x, A);
        corners(P, L->o, UINT32_MAX, x, B);
        sub3(A[1], A[0], u), sub3(A[2], A[0], v), cross3(u, v, na);
        sub3(B[1], B[0], u), sub3(B[2], B[0], v), cross3(u, v, nb);
        double la = sqrt(dot3(na, na)), lb = sqrt(dot3(nb, nb));
        if (!(la > 1e-12 * P->sp[0] * P->sp[0]) || dot3(na, nb) < FLIP_COS * la * lb)
            return false;
        for (int k = 0; k < 3; k++)
            if (L->c[k] != p) {
                if (!grow(S, (void **)&S->link, &S->kcap, (size_t)n_link + 1, sizeof *S->link))
                    return false;
                add_unique(S->link, &n_link, L->c[k]);
            }
    }
    /* every fine triangle round the piece and its neighbours within e of the triangles round its
     * corners' representatives: those whose witness the merge changes, or that had none */
    for (int i = 0; i < S->n_lt; i++) /* (the triangles with a corner in the piece: those the merge changes) */
        P->tmark[S->lt[i].t] = id;
    int n_wu = 0, n_qt = local_triangles(P, S, p, x, id, n_link);
    if (n_qt < 0)
        return false;
    for (int i = 0; i < n + n_link; i++) {
        uint32_t r = i < n ? S->comp[i] : S->link[i - n];
        for (uint32_t m = r; m != UINT32_MAX; m = P->mnext[m])
            for (uint32_t k = P->inc_at[m]; k < P->inc_at[m + 1]; k++) {
                uint32_t F = P->inc[k], R[3];
                if (witness_holds(P, P->wit[F], id) && (P->wit2[F] == NO_WITNESS || witness_holds(P, P->wit2[F], id)))
                    continue;
                const uint32_t *fc = P->fine.tri + 3 * (size_t)F;
                bool earlier = false;
                for (int j = 0; j < 3; j++) {
                    R[j] = P->rep[fc[j]];
                    R[j] = in_piece(P, R[j], id) ? p : R[j];
                }
                for (int j = 0; j < 3 && fc[j] != m && !earlier; j++) /* (each once: from its first corner here) */
                    earlier = local(P, R[j], id) >= 0;
                if (earlier)
                    continue;
                if (!fine_ok(P, S, F, R, n_qt, id, &n_wu))
                    return false;
            }
    }
    /* the new triangles near the fine surface: sampled at p, along their new edges and inside,
     * against the fine triangles round the piece, and round a neighbour once a point needs them */
    int n_cand = 0, last = 0;
    if (!grow(S, (void **)&S->added, &S->acap, (size_t)n_link + 1, sizeof *S->added))
        return false;
    memset(S->added, 0, (size_t)n_link + 1);
    for (int i = 0; i < n; i++)
        if (!add_cands(P, S, S->comp[i], id, &n_cand))
            return false;
    if (!near_fine(P, S, n_cand, x, &last))
        return false;
    for (int j = 0; j < n_link; j++) {
        double q[3], y[3];
        pos_of(P, S->link[j], q);
        for (int f = 1; f <= 3; f++) {
            for (int d = 0; d < 3; d++)
                y[d] = x[d] + (q[d] - x[d]) * f / 4.0;
            if (near_fine(P, S, n_cand, y, &last))
                continue;
            if (S->added[j] || !add_cands(P, S, S->link[j], id, &n_cand))
                return false;
            S->added[j] = 1;
            if (!near_fine(P, S, n_cand, y, &last))
                return false;
        }
    }
    static const double W[5][3] = {{1 / 3.0, 1 / 3.0, 1 / 3.0}, {0.5, 0.25, 0.25}, {0.25, 0.5, 0.25}, {0.25, 0.25, 0.5},
                                   {0.2, 0.4, 0.4}};
    for (int i = 0; i < S->n_lt; i++) {
        const struct ltri *L = &S->lt[i];
        if (!L->alive || !has(L->c, p))
            continue;
        int r = L->c[0] == p ? 0 : L->c[1] == p ? 1 : 2;
        double T[3][3], y[3];
        corners(P, L->c, p, x, T);
        for (int w = 0; w < 5; w++) {
            for (int d = 0; d < 3; d++)
                y[d] = W[w][0] * T[r][d] + W[w][1] * T[(r + 1) % 3][d] + W[w][2] * T[(r + 2) % 3][d];
            if (near_fine(P, S, n_cand, y, &last))
                continue;
            bool more = false; /* (the fine triangles round the other two corners) */
            for (int j = 0; j < n_link; j++)
                if (!S->added[j] && has(L->c, S->link[j])) {
                    if (!add_cands(P, S, S->link[j], id, &n_cand))
                        return false;
                    S->added[j] = 1, more = true;
                }
            if (!more || !near_fine(P, S, n_cand, y, &last))
                return false;
        }
    }
    /* all well: the merge made */
    uint32_t total = 0;
    for (int i = 0; i < n; i++)
        total += P->nstar[S->comp[i]];
    uint32_t *ns = star_room(S, total);
    if (!ns)
        return false;
    for (int i = 0; i < S->n_lt; i++) {
        const struct ltri *L = &S->lt[i];
        memcpy(P->cur + 3 * (size_t)L->t, L->c, sizeof L->c);
        P->dead[L->t] = !L->alive;
    }
    /* the stars: p's its pieces' in their order, the link's without the triangles that died */
    uint32_t ks = 0;
    for (int i = 0; i < n; i++)
        for (uint32_t j = 0; j < P->nstar[S->comp[i]]; j++)
            if (!P->dead[P->star[S->comp[i]][j]])
                ns[ks++] = P->star[S->comp[i]][j];
    P->star[p] = ns, P->nstar[p] = ks;
    S->chused += ks;
    for (int i = 0; i < S->n_lt; i++)
        for (int c = 0; c < 3 && !S->lt[i].alive; c++)
            if (!in_piece(P, S->lt[i].o[c], id))
                star_prune(P, S->lt[i].o[c]);
    for (int i = 1; i < n; i++) {
        uint32_t r = S->comp[i];
        for (uint32_t m = r; m != UINT32_MAX; m = P->mnext[m])
            P->rep[m] = p;
        P->mnext[P->mtail[p]] = r;
        P->mtail[p] = P->mtail[r];
        P->lvl[r] = 0;
    }
    P->lvl[p] = (uint8_t)(s == 2 ? 2 : s == 4 ? 3 : 4);
    for (int d = 0; d < 3; d++) {
        P->cp[3 * p + d] = (float)x[d];
        P->cn[3 * p + d] = (float)nrm[d];
    }
    double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    for (int d = 0; d < 3 && len > 0; d++)
        P->cn[3 * p + d] = (float)(nrm[d] / len);
    for (int i = 0; i < n_wu; i++)
        P->wit[S->wu[i].sample] = S->wu[i].tri, P->wit2[S->wu[i].sample] = S->wu[i].tri2;
    return true;
}

/* The pieces of block b (level l, its representatives in brep): each merged when it can be. */
static void block_pieces(struct pieces *P, struct pscratch *S, int l, const int b[3])
{
    size_t at = (size_t)b[0] + (size_t)P->nb[0] * ((size_t)b[1] + (size_t)P->nb[1] * (size_t)b[2]);
    uint32_t first = P->bstart[at], end = P->bstart[at + 1];
    int s = 1 << (l - 1), lo[3] = {b[0] * s, b[1] * s, b[2] * s};
    for (uint32_t k = first; k < end && !S->nomem; k++) {
        uint32_t r0 = P->brep[k];
        uint64_t id = ((uint64_t)r0 << 3 | (uint64_t)l) + 1;
        if (P->mark[r0] && ((P->mark[r0] - 1) & 7) == (uint64_t)l) /* in a piece of this level already */
            continue;
        /* the piece: r0's representatives in the block joined by edges (breadth first) */
        int n = 0;
        if (!grow(S, (void **)&S->comp, &S->ccap, 1, sizeof *S->comp))
            return;
        S->comp[n++] = r0;
        P->mark[r0] = id;
        for (int h = 0; h < n; h++) {
            uint32_t u = S->comp[h];
            for (uint32_t j = 0; j < P->nstar[u]; j++) {
                const uint32_t *c = P->cur + 3 * (size_t)P->star[u][j];
                for (int q = 0; q < 3; q++) {
                    uint32_t w = c[q];
                    if (w == u || P->mark[w] == id || block_of(P, w, l) != at)
                        continue;
                    if (!grow(S, (void **)&S->comp, &S->ccap, (size_t)n + 1, sizeof *S->comp))
                        return;
                    P->mark[w] = id;
                    S->comp[n++] = w;
                }
            }
        }
        if (n < 2)
            continue;
        merge_piece(P, S, n, id, lo, s);
    }
}

/* ---- the phases ---- */

void pieces_run(struct pieces *P, int phase, int slab)
{
    if (P->rc)
        return;
    if (phase == 0) {
        iso_count(P->mc, slab);
        return;
    }
    if (phase == 1) {
        iso_emit(P->mc, slab);
        return;
    }
    int l = 2 + (phase - 2) / COLOURS, c = (phase - 2) % COLOURS, cx = c % 3, cy = c / 3 % 3, cz = c / 9;
    int planes = colour_planes(P, cz), n = pieces_n_slabs(P);
    int z0 = (int)((long)planes * slab / n), z1 = (int)((long)planes * (slab + 1) / n);
    struct pscratch *S = &P->sc[slab];
    int b[3];
    for (int zi = z0; zi < z1; zi++) {
        b[2] = cz + 3 * zi;
        for (b[1] = cy; b[1] < P->nb[1]; b[1] += 3)
            for (b[0] = cx; b[0] < P->nb[0]; b[0] += 3)
                block_pieces(P, S, l, b);
    }
}

void pieces_between(struct pieces *P, int phase)
{
    P->phase = phase + 1;
    if (P->rc)
        return;
    if (phase == 0) {
        if (iso_layout(P->mc, &P->err))
            P->rc = P->err.code;
        return;
    }
    if (phase == 1) {
        int rc = iso_end(P->mc, &P->fine, &P->err);
        P->mc = NULL;
        if (rc)
            P->rc = rc;
        else if (prepare(P))
            fail(P, SF_ENOMEM, "out of memory for the pieces' merge");
        return;
    }
    for (int k = 0; k < ADAPT_SLABS; k++)
        if (P->sc[k].nomem)
            fail(P, SF_ENOMEM, "out of memory for the pieces' merge");
    int c = (phase - 2) % COLOURS, l = 2 + (phase - 2) / COLOURS;
    if (c == COLOURS - 1 && l < P->L && bucket(P, l + 1))
        fail(P, SF_ENOMEM, "out of memory for the pieces' merge");
}

/* The merged mesh into P->out (live triangles in their order, representatives in theirs) and
 * the counts by level; the working lists freed. 0 or the error. */
static int finish(struct pieces *P, struct sf_err *err)
{
    if (!P->rc && P->phase < pieces_phases(P))
        fail(P, SF_EINVAL, "the merge's phases were not all run");
    if (P->rc) {
        *err = P->err;
        return P->rc;
    }
    uint32_t *id = malloc(((size_t)P->nv + 1) * sizeof *id);
    size_t nt = 0, nv = 0;
    for (uint32_t t = 0; t < P->nt; t++)
        nt += !P->dead[t];
    if (!id)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (uint32_t v = 0; v < P->nv; v++)
        id[v] = UINT32_MAX;
    for (uint32_t t = 0; t < P->nt; t++)
        for (int k = 0; k < 3 && !P->dead[t]; k++)
            id[P->cur[3 * (size_t)t + k]] = 0;
    for (uint32_t v = 0; v < P->nv; v++)
        if (id[v] == 0)
            id[v] = (uint32_t)nv++;
    struct trimesh *o = &P->out;
    trimesh_free(o);
    o->pos = malloc((3 * nv + 1) * sizeof *o->pos);
    o->nrm = malloc((3 * nv + 1) * sizeof *o->nrm);
    o->tri = malloc((3 * nt + 1) * sizeof *o->tri);
    if (!o->pos || !o->nrm || !o->tri) {
        free(id);
        trimesh_free(o);
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    }
    memset(P->cells, 0, sizeof P->cells);
    for (uint32_t v = 0; v < P->nv; v++)
        if (id[v] != UINT32_MAX) {
            memcpy(o->pos + 3 * (size_t)id[v], P->cp + 3 * (size_t)v, 3 * sizeof *o->pos);
            memcpy(o->nrm + 3 * (size_t)id[v], P->cn + 3 * (size_t)v, 3 * sizeof *o->nrm);
            P->cells[P->lvl[v] <= ISO_MAX_LEVELS ? P->lvl[v] : 1]++;
        }
    for (uint32_t t = 0; t < P->nt; t++)
        if (!P->dead[t]) {
            for (int k = 0; k < 3; k++)
                o->tri[3 * o->n_tri + k] = id[P->cur[3 * (size_t)t + k]];
            o->n_tri++;
        }
    o->n_vert = nv;
    free(id);
    work_free(P);
    return 0;
}

static void stats_of(const struct pieces *P, struct iso_adapt_stats *st)
{
    memset(st, 0, sizeof *st);
    memcpy(st->cells, P->cells, sizeof st->cells);
    st->max_estimate = P->e;
}

int pieces_end(struct pieces *P, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err)
{
    memset(out, 0, sizeof *out);
    memset(st, 0, sizeof *st);
    int rc = finish(P, err);
    if (!rc) {
        *out = P->out;
        memset(&P->out, 0, sizeof P->out);
        stats_of(P, st);
    }
    return rc;
}

/* ---- kept: edits draw the whole mesh again (merges reach across blocks: not local yet) ---- */

static size_t n_samples(const struct pieces *P) { return (size_t)P->g.nx * P->g.ny * P->g.nz; }

int pieces_keep(struct pieces *P, struct iso_adapt_stats *st, struct sf_err *err)
{
    memset(st, 0, sizeof *st);
    if (!P->keep)
        return sf_fail(err, SF_EINVAL, "", "the extraction was not begun to be kept");
    int rc = finish(P, err);
    if (rc)
        return rc;
    size_t n = n_samples(P);
    if (!P->samples && !(P->samples = malloc(n * sizeof *P->samples + 1)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if (P->g.samples != P->samples)
        for (int z = 0; z < P->g.nz; z++)
            for (int y = 0; y < P->g.ny; y++)
                iso_grid_row(&P->g, y, z, P->samples + (size_t)P->g.nx * (y + (size_t)P->g.ny * z));
    P->g.type = ISO_F32;
    P->g.samples = P->samples;
    free(P->ids);
    if (!(P->ids = malloc((P->out.n_tri + 1) * sizeof *P->ids)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if ((uint64_t)P->next_id + P->out.n_tri >= UINT32_MAX)
        return sf_fail(err, SF_ELIMIT, "", "the model's triangle ids ran out (2^32 of them)");
    for (size_t t = 0; t < P->out.n_tri; t++)
        P->ids[t] = P->next_id + (uint32_t)t;
    P->next_id += (uint32_t)P->out.n_tri;
    P->kept = true;
    stats_of(P, st);
    return 0;
}

static int copy_mesh(const struct trimesh *m, struct trimesh *out)
{
    memset(out, 0, sizeof *out);
    out->pos = malloc((3 * m->n_vert + 1) * sizeof *out->pos);
    out->nrm = malloc((3 * m->n_vert + 1) * sizeof *out->nrm);
    out->tri = malloc((3 * m->n_tri + 1) * sizeof *out->tri);
    if (!out->pos || !out->nrm || !out->tri) {
        trimesh_free(out);
        return -1;
    }
    memcpy(out->pos, m->pos, 3 * m->n_vert * sizeof *out->pos);
    memcpy(out->nrm, m->nrm, 3 * m->n_vert * sizeof *out->nrm);
    memcpy(out->tri, m->tri, 3 * m->n_tri * sizeof *out->tri);
    out->n_vert = m->n_vert, out->n_tri = m->n_tri;
    return 0;
}

int pieces_mesh(const struct pieces *P, struct trimesh *out, struct iso_adapt_stats *st, struct sf_err *err)
{
    stats_of(P, st);
    if (copy_mesh(&P->out, out))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    return 0;
}

int pieces_ids(const struct pieces *P, uint32_t **ids, struct sf_err *err)
{
    size_t n = P->out.n_tri;
    if (!(*ids = malloc((n ? n : 1) * sizeof **ids)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if (n)
        memcpy(*ids, P->ids, n * sizeof **ids);
    return 0;
}

void pieces_number_from(struct pieces *P, uint32_t first) { P->next_id = first; }

uint32_t pieces_next_id(const struct pieces *P) { return P->next_id; }

int pieces_samples(const struct pieces *P, float **out, struct sf_err *err)
{
    size_t n = n_samples(P);
    if (!(*out = malloc(n * sizeof **out + 1)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (int z = 0; z < P->g.nz; z++)
        for (int y = 0; y < P->g.ny; y++)
            iso_grid_row(&P->g, y, z, *out + (size_t)P->g.nx * (y + (size_t)P->g.ny * z));
    return 0;
}

size_t pieces_bytes(const struct pieces *P)
{
    return n_samples(P) * sizeof(float) + P->out.n_vert * 6 * sizeof(float) + P->out.n_tri * 4 * sizeof(uint32_t);
}

/* The whole extraction again on the kept samples, on this thread. 0 or the error. */
static int extract_again(struct pieces *P, struct sf_err *err)
{
    struct pieces *Q;
    struct iso_opts o = P->o;
    int rc = pieces_begin(&P->g, &o, P->L, P->e, &Q, err);
    if (rc)
        return rc;
    for (int ph = 0; ph < pieces_phases(Q); ph++) {
        int n = pieces_n_slabs(Q);
        for (int s = 0; s < n; s++)
            pieces_run(Q, ph, s);
        pieces_between(Q, ph);
    }
    rc = finish(Q, err);
    if (!rc) {
        trimesh_free(&P->out);
        P->out = Q->out;
        memset(&Q->out, 0, sizeof Q->out);
        memcpy(P->cells, Q->cells, sizeof P->cells);
    }
    pieces_free(Q);
    return rc;
}

int pieces_edit(struct pieces *P, const int lo[3], const struct iso_grid *blk, struct iso_edit *ed,
                struct iso_change *ch, struct sf_err *err)
{
    memset(ed, 0, sizeof *ed);
    if (ch)
        *ch = (struct iso_change){.next_id = P->next_id};
    if (!P->kept)
        return sf_fail(err, SF_EINVAL, "", "the extraction is not kept (or an edit of it failed)");
    int n[3] = {blk->nx, blk->ny, blk->nz}, N[3] = {P->g.nx, P->g.ny, P->g.nz};
    for (int d = 0; d < 3; d++)
        if (lo[d] < 0 || n[d] < 1 || lo[d] + (long)n[d] > N[d])
            return sf_fail(err, SF_EINVAL, "?region", "the region lies outside the volume's %d x %d x %d samples", N[0],
                           N[1], N[2]);
    for (int z = 0; z < blk->nz; z++)
        for (int y = 0; y < blk->ny; y++)
            iso_grid_row(blk, y, z, P->samples + (size_t)lo[0] + (size_t)N[0] * ((size_t)(lo[1] + y) + (size_t)N[1] * (size_t)(lo[2] + z)));
    size_t old = P->out.n_tri;
    if (ch) {
        ch->removed = malloc((old ? old : 1) * sizeof *ch->removed);
        if (!ch->removed)
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        memcpy(ch->removed, P->ids, old * sizeof *ch->removed);
        ch->n_removed = old;
    }
    P->kept = false; /* (until the mesh is whole again) */
    int rc = extract_again(P, err);
    if (rc)
        return rc;
    size_t nt = P->out.n_tri;
    free(P->ids);
    if (!(P->ids = malloc((nt + 1) * sizeof *P->ids)))
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if ((uint64_t)P->next_id + nt >= UINT32_MAX)
        return sf_fail(err, SF_ELIMIT, "", "the model's triangle ids ran out (2^32 of them)");
    for (size_t t = 0; t < nt; t++)
        P->ids[t] = P->next_id++;
    ed->whole = true;
    ed->triangles_removed = (long)old;
    ed->triangles_added = (long)nt;
    for (int l = 1; l <= ISO_MAX_LEVELS; l++)
        ed->cells_rebuilt += P->cells[l];
    if (ch) {
        ch->added = malloc((nt ? nt : 1) * sizeof *ch->added);
        ch->corners = malloc((nt ? nt : 1) * 18 * sizeof *ch->corners);
        if (!ch->added || !ch->corners)
            return sf_fail(err, SF_ENOMEM, "", "out of memory");
        const struct trimesh *m = &P->out;
        for (size_t t = 0; t < nt; t++) {
            ch->added[t] = P->ids[t];
            for (int k = 0; k < 3; k++) {
                uint32_t v = m->tri[3 * t + k];
                memcpy(ch->corners + 18 * t + 6 * k, m->pos + 3 * v, 3 * sizeof(float));
                memcpy(ch->corners + 18 * t + 6 * k + 3, m->nrm + 3 * v, 3 * sizeof(float));
            }
        }
        ch->n_added = nt;
        ch->next_id = P->next_id;
    }
    P->kept = true;
    return 0;
}
