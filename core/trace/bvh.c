/* bvh.c - Embree 3 scenes for the exact tracer and the mesh reference.
 *
 * Exact: every patch is split (de Casteljau) until its control net is flat; each leaf is an
 * Embree user primitive with the control hull's box as bounds. The intersect callback seeds
 * Newton–Cramer (seed 000 eq. 10–13) from the ray's hit on the two triangles through the leaf's
 * corners and accepts a root only inside the leaf's parameter box (with SOLVE_BOX_EPS slack),
 * so each root is found by the leaf that owns it and none slips between leaves. Embree traces
 * in float; the double ray and the double hit ride along in the intersect context. The leaves'
 * normal cones and the chord bounds of patches and seams come from bvh_cone.c. */
#include "bvh.h"
#include "bvh_cone.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../base/mem.h"
#include "../geom/tess.h"

#define LEAF_FLAT_REL 0.05  /* leaf is flat when its net deviates < 5 % of its size ...       */
#define LEAF_FINE_REL 0.025 /* ... or 2.5 % where it deviates by more than bvh.fine (the teapot at
                             * 1024^2: 3.1 k -> 7.6 k leaves, shadow iterations 144 k -> 74 k, render
                             * 6 % faster, preparation 10 -> 20 ms; at 2.5 % everywhere the heart
                             * model's preparation 140 -> 230 ms for no faster render) */
#define LEAF_MAX_DEPTH 14   /* ... or after this many splits; trades leaves for Newton starts */
#define LEAF_TRIM_DEPTH 10  /* ... but a leaf a trim loop crosses splits to this depth at least */
#define LEAF_MAX_ASPECT 8.0 /* ... and an untrimmed one longer than this many times its width splits
                             * across (the heart of 19 k sliver patches at 1024^2: shadow rays 94 -> 79
                             * ms at 4. Its model of 7.6 k patches since the curves were redrawn on
                             * fewer knots: auto's render the same at 4, 8 and 16, 168 ms without
                             * the split; preparation 139 ms at 4, 122 at 8 (the teacup 10 -> 4.6
                             * ms, the teapot 12 -> 8); the bvh method's render 5 % slower at 8) */
#define LEAF_GRAZING 0.25   /* |cos| of a ray's angle to a leaf's normal below which it grazes the leaf */
#define LEAF_SPLIT_DEPTH 4  /* ... and intersection queries search its quarters, this many levels deep */
#define REGION_GROW 0.25    /* a leaf's neighbourhood: its box grown by this much of its size each way
                             * (shadow rays leaving within it are tested by chords; a larger one
                             * catches more origins but bounds its chords more loosely: 1.0 measured
                             * 219 k shadow iterations on the teapot, 0.25 178 k) */

struct bvh_device {
    RTCDevice dev;
};

struct leaf {
    int patch;
    double u0, u1, v0, v1;  /* parameter box in the patch */
    vec3 lo, hi;            /* control hull box */
    vec3 c00, c10, c01, c11; /* corner points: the Newton seed comes from them */
    vec3 n;                  /* unit normal of the corner quad (zero where the corners are degenerate) */
    bool has_axes;           /* n is a unit vector, and e, d0, d1, e0, e1 are set */
    bool trim_cut;           /* its patch's trim loops cross it: each root is tested against them */
    double slack;            /* how far off the corner quad a root may lie (world units): the net's
                              * deviation from the bilinear plus the bilinear's twist */
    double alt[2][3];        /* altitudes of the corner triangles (c00 c10 c11) and (c00 c11 c01) */
    double d0, d1;           /* the control points' extent along n: the leaf lies in this slab */
    vec3 e[2];               /* two unit directions across n (along the quad's u edges, and n × that) */
    double e0[2], e1[2];     /* ... and the control points' extents along them: with n, a box that
                              * hugs a leaf lying diagonally, as a sliver does, where the axes' does not */
    vec3 cone_axis;          /* every normal Pu × Pv of the leaf is within the cone of this axis ... */
    double cone_sin;         /* ... and half-angle asin(cone_sin); > 1: no cone (rational, or too wide) */
    /* the leaf's neighbourhood in its patch (its parameter box grown by REGION_GROW each way): no
     * chord of that part of the surface is within asin(chord_sin) of the plane across chord_n */
    double ru0, ru1, rv0, rv1;
    vec3 chord_n;
    double chord_sin;        /* > 1: no such bound */
};

/* A patch's chord bounds (chord_bound): its own, and with each neighbour that shares a whole
 * edge with it the same way round (the seam's other patch continues its u or v parameter: the
 * two are one surface over a longer rectangle, and the bound holds for its chords as for one
 * patch's). A ray steeper than a bound meets that surface once at most. */
struct chords {
    vec3 n;
    double sin;            /* > 1: no bound */
    struct seam {
        int other;         /* -1: none */
        vec3 n;
        double sin;
    } seam[4];             /* across u = 0, u = 1, v = 0, v = 1 */
};

struct bvh {
    RTCScene scene;
    const struct patch *patches;
    struct chords *chords; /* per patch; NULL for the mesh */
    double tol2;
    double fine;           /* LEAF_FINE_REL's deviation (bvh_build_scene) */
    struct rat_polys *rat; /* while building: the rational patch being split's numerators */
    /* exact */
    struct leaf *leaves;
    size_t n_leaves, cap_leaves;
    /* the leaves along each patch edge that has a seam (edge e of patch k: border[border_at[4k + e]]
     * up to border[border_at[4k + e + 1]]), in order along it; NULL: none known */
    uint32_t *border;
    size_t *border_at;
    /* mesh */
    struct tess mesh;
    /* triangle meshes beside the patches: mesh k is geometry mesh_geom + k */
    const struct trimesh *const *meshes;
    int n_meshes;
    unsigned mesh_geom;
};

/* Rides along with every Embree query. ctx must stay first. */
struct query {
    struct RTCIntersectContext ctx;
    const struct bvh *b;
    const struct dray *r;
    struct bvh_shadow *shadows;    /* occlusion queries: the rays, by Embree ray id */
    double tnear;
    struct bvh_hit *hit;   /* NULL for occlusion queries */
    const int *among;      /* intersection queries: only these patches (NULL: all) */
    int n_among;
    double best_t;
    long iters;
    bool found;
};

struct bvh_device *bvh_device_new(int n_threads, struct sf_err *err)
{
    struct bvh_device *d = calloc(1, sizeof *d);
    if (!d) {
        sf_fail(err, SF_ENOMEM, "", "out of memory");
        return NULL;
    }
    char cfg[64];
    snprintf(cfg, sizeof cfg, "threads=%d,set_affinity=0", n_threads > 0 ? n_threads : 0);
    d->dev = rtcNewDevice(cfg);
    if (!d->dev) {
        free(d);
        sf_fail(err, SF_EBACKEND, "", "Embree device: error %d", (int)rtcGetDeviceError(NULL));
        return NULL;
    }
    return d;
}

void bvh_device_free(struct bvh_device *d)
{
    if (!d)
        return;
    rtcReleaseDevice(d->dev);
    free(d);
}

size_t bvh_n_leaves(const struct bvh *b) { return b->n_leaves; }

size_t bvh_bytes(const struct bvh *b, size_t n_patches)
{
    if (!b)
        return 0;
    size_t n = sizeof *b + b->cap_leaves * sizeof *b->leaves + (b->chords ? n_patches * sizeof *b->chords : 0);
    if (b->border_at)
        n += (4 * n_patches + 1) * sizeof *b->border_at + b->border_at[4 * n_patches] * sizeof *b->border;
    n += b->mesh.n_tris * sizeof *b->mesh.tri +
         b->mesh.n_verts * (sizeof *b->mesh.pos + sizeof *b->mesh.nrm + sizeof *b->mesh.uv + sizeof *b->mesh.patch);
    return n + b->n_leaves * 64 + b->mesh.n_tris * 96; /* Embree's nodes over them, about (measured: the
                                                        * heart's 41.0 MB exact and 95.6 MB mesh hierarchies) */
}

void bvh_free(struct bvh *b)
{
    if (!b)
        return;
    if (b->scene)
        rtcReleaseScene(b->scene);
    free(b->leaves);
    free(b->border);
    free(b->border_at);
    free(b->chords);
    tess_free(&b->mesh);
    free(b);
}

/* ---- exact: leaves -------------------------------------------------------------------- */

/* The extents of sub's control points along l->n, l->e[0] and l->e[1] (l->d0 .. l->e1), widened by
 * their rounding (size: about sub's size). */
static void axes_extents(struct leaf *l, const struct patch *sub, double size)
{
    l->d0 = INFINITY, l->d1 = -INFINITY;
    l->e0[0] = l->e0[1] = INFINITY, l->e1[0] = l->e1[1] = -INFINITY;
    for (int i = 0; i <= sub->p; i++)
        for (int j = 0; j <= sub->q; j++) {
            vec3 c = bezier_point(sub, i, j);
            double d = v3_dot(l->n, c);
            l->d0 = dmin(l->d0, d);
            l->d1 = dmax(l->d1, d);
            for (int k = 0; k < 2; k++) {
                double a = v3_dot(l->e[k], c);
                l->e0[k] = dmin(l->e0[k], a);
                l->e1[k] = dmax(l->e1[k], a);
            }
        }
    double pad = 1e-9 * (size + fabs(l->d0) + fabs(l->d1)); /* rounding of the dot products */
    l->d0 -= pad, l->d1 += pad;
    for (int k = 0; k < 2; k++) {
        double pk = 1e-9 * (size + fabs(l->e0[k]) + fabs(l->e1[k]));
        l->e0[k] -= pk, l->e1[k] += pk;
    }
}

/* The bounds of sub-patch sub (the part [u0, u1] x [v0, v1] of patch `patch`, its net deviating
 * dev from the bilinear through its corners) that a ray query needs, besides its box l->lo,
 * l->hi (bezier_bounds), which the caller has set already. */
static void leaf_fill(struct leaf *l, const struct patch *sub, int patch, double u0, double u1, double v0, double v1,
                      double dev)
{
    l->patch = patch;
    l->u0 = u0, l->u1 = u1, l->v0 = v0, l->v1 = v1;
    l->c00 = bezier_point(sub, 0, 0);
    l->c10 = bezier_point(sub, sub->p, 0);
    l->c01 = bezier_point(sub, 0, sub->q);
    l->c11 = bezier_point(sub, sub->p, sub->q);
    vec3 d1 = v3_sub(l->c11, l->c00), d2 = v3_sub(l->c01, l->c10);
    l->n = v3_norm(v3_cross(d1, d2));
    l->has_axes = v3_len(l->n) > 0.5;
    double size = dmax(v3_len(d1), v3_len(d2));
    vec3 twist = v3_sub(v3_add(l->c00, l->c11), v3_add(l->c10, l->c01));
    l->slack = l->has_axes ? dev + 0.25 * v3_len(twist) : INFINITY;
    const vec3 tri[2][3] = {{l->c00, l->c10, l->c11}, {l->c00, l->c11, l->c01}};
    for (int k = 0; k < 2; k++) { /* altitude of vertex i: twice the area over the opposite edge */
        double area2 = v3_len(v3_cross(v3_sub(tri[k][1], tri[k][0]), v3_sub(tri[k][2], tri[k][0])));
        for (int i = 0; i < 3; i++) {
            double opp = v3_len(v3_sub(tri[k][(i + 2) % 3], tri[k][(i + 1) % 3]));
            l->alt[k][i] = opp > 0 ? area2 / opp : 0.0;
        }
    }
    l->e[0] = v3_norm(v3_sub(v3_add(l->c10, l->c11), v3_add(l->c00, l->c01)));
    l->e[0] = v3_norm(v3_sub(l->e[0], v3_scale(l->n, v3_dot(l->e[0], l->n)))); /* across n */
    l->e[1] = v3_cross(l->n, l->e[0]);
    axes_extents(l, sub, size);
}

static int add_leaf(struct bvh *b, const struct patch *sub, const struct patch *nrm, int patch, double u0, double u1,
                    double v0, double v1, double dev, bool trim_cut)
{
    if (mem_reserve((void **)&b->leaves, &b->cap_leaves, b->n_leaves + 1, sizeof *b->leaves))
        return SF_ENOMEM;
    struct leaf *l = &b->leaves[b->n_leaves++];
    bezier_bounds(sub, &l->lo, &l->hi);
    leaf_fill(l, sub, patch, u0, u1, v0, v1, dev);
    l->trim_cut = trim_cut;
    /* the neighbourhood's chord bound */
    const struct patch *pt = &b->patches[patch];
    l->ru0 = fmax(0.0, u0 - REGION_GROW * (u1 - u0)), l->ru1 = fmin(1.0, u1 + REGION_GROW * (u1 - u0));
    l->rv0 = fmax(0.0, v0 - REGION_GROW * (v1 - v0)), l->rv1 = fmin(1.0, v1 + REGION_GROW * (v1 - v0));
    struct rat_polys *rp = b->rat;
    if (nrm) { /* a rational patch: its numerators (rp, made for it) over the parts */
        struct patch part;
        cone_of_net(nrm, &l->cone_axis, &l->cone_sin);
        vec3 g[2 * RAT_N * RAT_N];
        int n_g = 0, n_u;
        append_net(rat_part(rp, &rp->tu, l->ru0, l->ru1, l->rv0, l->rv1, &part), g, &n_g);
        n_u = n_g;
        append_net(rat_part(rp, &rp->tv, l->ru0, l->ru1, l->rv0, l->rv1, &part), g, &n_g);
        l->chord_sin = 2.0;
        chord_bound_of(g, n_g, n_u, &l->chord_n, &l->chord_sin);
        return 0;
    }
    normal_cone(sub, &l->cone_axis, &l->cone_sin);
    size_t n_pts = (size_t)(pt->p + 1) * (pt->q + 1);
    double(*net)[4] = malloc(sizeof *net * 2 * n_pts);
    if (!net)
        return SF_ENOMEM;
    struct patch region = *pt;
    region.cw = net;
    sub_net(pt, l->ru0, l->ru1, l->rv0, l->rv1, net, net + n_pts);
    chord_bound(&region, &l->chord_n, &l->chord_sin);
    free(net);
    return 0;
}

/* Splits sub-patch sub (the part [u0, u1] x [v0, v1] of patch `patch`) until its parts are flat,
 * leaving out the parts its trim region holds none of; trim_cut: the region's loops may cross it.
 * nrm: a rational patch's normals' numerator over the same part (b->rat), split alongside, or NULL. */
static int subdivide(struct bvh *b, const struct patch *sub, const struct patch *nrm, int patch, double u0, double u1,
                     double v0, double v1, int depth, bool trim_cut)
{
    const struct patch *pt = &b->patches[patch];
    if (trim_cut) {
        double su = pt->u1 - pt->u0, sv = pt->v1 - pt->v0;
        enum trim_class c = trim_classify(pt->trim, pt->u0 + u0 * su, pt->u0 + u1 * su, pt->v0 + v0 * sv, pt->v0 + v1 * sv);
        if (c == TRIM_OUT)
            return 0;
        trim_cut = c == TRIM_CUT;
    }
    double cu, cv;
    vec3 lo, hi;
    bezier_bounds(sub, &lo, &hi);
    double size = v3_len(v3_sub(hi, lo));
    double dev = net_deviation(sub, &cu, &cv);
    /* a flat leaf many times longer than wide (a contour model's strips) splits across too: a
     * box round a sliver that lies along no axis holds far more than the sliver, and every ray
     * through it calls the leaf's test (LEAF_MAX_ASPECT) */
    vec3 c00 = bezier_point(sub, 0, 0), c10 = bezier_point(sub, sub->p, 0), c01 = bezier_point(sub, 0, sub->q);
    vec3 c11 = bezier_point(sub, sub->p, sub->q);
    double lu = fmax(v3_len(v3_sub(c10, c00)), v3_len(v3_sub(c11, c01)));
    double lv = fmax(v3_len(v3_sub(c01, c00)), v3_len(v3_sub(c11, c10)));
    bool slim = !pt->trim && (lu > LEAF_MAX_ASPECT * lv || lv > LEAF_MAX_ASPECT * lu);
    /* a flat leaf a trim loop crosses is split on (to LEAF_TRIM_DEPTH): its parts the trims cut away
     * go, and the rest hug the region, so that rays through the cut-away part meet no leaf */
    bool flat = dev <= LEAF_FLAT_REL * size && (dev <= LEAF_FINE_REL * size || dev <= b->fine);
    if ((flat && !slim && !(trim_cut && depth < LEAF_TRIM_DEPTH)) || depth >= LEAF_MAX_DEPTH)
        return add_leaf(b, sub, nrm, patch, u0, u1, v0, v1, dev, trim_cut);
    if (flat) /* slim: its length halved */
        cu = lu, cv = lv;

    size_t n_pts = (size_t)(sub->p + 1) * (sub->q + 1), n_nrm = nrm ? (size_t)(nrm->p + 1) * (nrm->q + 1) : 0;
    double(*net)[4] = malloc(sizeof *net * 2 * (n_pts + n_nrm));
    if (!net)
        return SF_ENOMEM;
    struct patch lo_p = *sub, hi_p = *sub, lo_n, hi_n;
    lo_p.cw = net;
    hi_p.cw = net + n_pts;
    if (nrm)
        lo_n = *nrm, hi_n = *nrm, lo_n.cw = net + 2 * n_pts, hi_n.cw = net + 2 * n_pts + n_nrm;
    const struct patch *ln = nrm ? &lo_n : NULL, *hn = nrm ? &hi_n : NULL;
    int rc;
    if (cu > cv || (cu == cv && (u1 - u0) >= (v1 - v0))) { /* the more curved way; flat: the longer */
        bezier_split_u(sub, 0.5, lo_p.cw, hi_p.cw);
        if (nrm)
            bezier_split_u(nrm, 0.5, lo_n.cw, hi_n.cw);
        double um = 0.5 * (u0 + u1);
        rc = subdivide(b, &lo_p, ln, patch, u0, um, v0, v1, depth + 1, trim_cut);
        if (!rc)
            rc = subdivide(b, &hi_p, hn, patch, um, u1, v0, v1, depth + 1, trim_cut);
    } else {
        bezier_split_v(sub, 0.5, lo_p.cw, hi_p.cw);
        if (nrm)
            bezier_split_v(nrm, 0.5, lo_n.cw, hi_n.cw);
        double vm = 0.5 * (v0 + v1);
        rc = subdivide(b, &lo_p, ln, patch, u0, u1, v0, vm, depth + 1, trim_cut);
        if (!rc)
            rc = subdivide(b, &hi_p, hn, patch, u0, u1, vm, v1, depth + 1, trim_cut);
    }
    free(net);
    return rc;
}

/* ---- seams ---------------------------------------------------------------------------- */

/* Control point k of edge e of pt (0: u = 0, 1: u = 1, 2: v = 0, 3: v = 1), k along the edge. */
static const double *edge_point(const struct patch *pt, int e, int k)
{
    int i = e == 0 ? 0 : e == 1 ? pt->p : k, j = e == 2 ? 0 : e == 3 ? pt->q : k;
    return pt->cw[i * (pt->q + 1) + j];
}

static int edge_len(const struct patch *pt, int e) { return (e < 2 ? pt->q : pt->p) + 1; }

static uint64_t edge_hash(const struct patch *pt, int e)
{
    uint64_t h = 0xcbf29ce484222325ull ^ (uint64_t)(e >> 1); /* u edges meet u edges */
    for (int k = 0; k < edge_len(pt, e); k++) {
        const unsigned char *c = (const unsigned char *)edge_point(pt, e, k);
        for (size_t m = 0; m < 4 * sizeof(double); m++)
            h = (h ^ c[m]) * 0x100000001b3ull;
    }
    return h;
}

static bool same_edge(const struct patch *a, int ea, const struct patch *b, int eb)
{
    if (edge_len(a, ea) != edge_len(b, eb))
        return false;
    for (int k = 0; k < edge_len(a, ea); k++)
        if (memcmp(edge_point(a, ea, k), edge_point(b, eb, k), 4 * sizeof(double)))
            return false;
    return true;
}

#define SEAM_PROBES 64 /* slots an edge's search looks at, at most: many patches with one edge (copies
                        * of a patch, a cap's apex) cost no more than that each */

/* Every patch's own chord bound, and its seams: where edge u = 1 of one patch is edge u = 0 of
 * another point for point (or v = 1 of one v = 0 of another), the pair's bound over both nets'
 * differences. Found through a hash of the u = 0 and v = 0 edges; 0 or SF_ENOMEM. */
static int find_seams(struct bvh *b, size_t n)
{
    if (!(b->chords = malloc(sizeof *b->chords * (n ? n : 1))))
        return SF_ENOMEM;
    size_t cap = 16;
    while (cap < 4 * n)
        cap *= 2;
    int *slot = malloc(sizeof *slot * cap); /* patch * 4 + edge of a u = 0 or v = 0 edge, or -1 */
    if (!slot)
        return SF_ENOMEM;
    memset(slot, 0xff, sizeof *slot * cap);
    for (size_t k = 0; k < n; k++) {
        struct chords *c = &b->chords[k];
        chord_bound(&b->patches[k], &c->n, &c->sin);
        for (int e = 0; e < 4; e++)
            c->seam[e].other = -1;
        for (int e = 0; e < 4; e += 2) { /* (a run of SEAM_PROBES taken: the edge is left out, seamless) */
            size_t at = edge_hash(&b->patches[k], e) & (cap - 1);
            for (int probe = 0; slot[at] >= 0 && probe < SEAM_PROBES; probe++)
                at = (at + 1) & (cap - 1);
            if (slot[at] < 0)
                slot[at] = (int)k * 4 + e;
        }
    }
    for (size_t k = 0; k < n; k++)
        for (int e = 1; e < 4; e += 2) { /* edge u = 1 or v = 1 of k against u = 0 or v = 0 of another */
            const struct patch *a = &b->patches[k];
            if (!memcmp(edge_point(a, e, 0), edge_point(a, e, edge_len(a, e) - 1), 4 * sizeof(double)))
                continue; /* a collapsed edge (a cap's apex): a point many patches share */
            size_t at = edge_hash(a, e) & (cap - 1);
            for (int probe = 0; slot[at] >= 0 && probe <= SEAM_PROBES; probe++, at = (at + 1) & (cap - 1)) {
                int other = slot[at] / 4, eo = slot[at] % 4;
                if (eo != e - 1 || other == (int)k || b->chords[other].seam[eo].other >= 0 ||
                    !same_edge(a, e, &b->patches[other], eo))
                    continue;
                vec3 g[CHORD_MAX_GENS];
                int n_g = 0, n_u = 0;
                struct seam sm = {other, v3(0, 0, 0), 2.0};
                if (chord_generators(a, g, &n_g, &n_u) && chord_generators(&b->patches[other], g, &n_g, &n_u))
                    chord_bound_of(g, n_g, n_u, &sm.n, &sm.sin);
                b->chords[k].seam[e] = sm;
                sm.other = (int)k;
                b->chords[other].seam[eo] = sm;
                break;
            }
        }
    free(slot);
    return 0;
}

int bvh_seam(const struct bvh *b, int patch, int edge)
{
    return b->chords ? b->chords[patch].seam[edge].other : -1;
}

bool bvh_meets_once(const struct bvh *b, int pa, int pb, vec3 d)
{
    if (!b->chords || pa < 0 || pb < 0)
        return false;
    const struct chords *c = &b->chords[pa];
    if (pa == pb)
        return c->sin < 1.0 && fabs(v3_dot(d, c->n)) > c->sin;
    for (int e = 0; e < 4; e++)
        if (c->seam[e].other == pb)
            return c->seam[e].sin < 1.0 && fabs(v3_dot(d, c->seam[e].n)) > c->seam[e].sin;
    return false;
}

/* ---- exact: callbacks ----------------------------------------------------------------- */

static void leaf_bounds(const struct RTCBoundsFunctionArguments *args)
{
    const struct bvh *b = args->geometryUserPtr;
    const struct leaf *l = &b->leaves[args->primID];
    /* widen by a relative epsilon so float rounding never cuts the hull */
    double pad = 1e-6 * v3_len(v3_sub(l->hi, l->lo)) + 1e-9;
    args->bounds_o->lower_x = nextafterf((float)(l->lo.x - pad), -INFINITY);
    args->bounds_o->lower_y = nextafterf((float)(l->lo.y - pad), -INFINITY);
    args->bounds_o->lower_z = nextafterf((float)(l->lo.z - pad), -INFINITY);
    args->bounds_o->upper_x = nextafterf((float)(l->hi.x + pad), INFINITY);
    args->bounds_o->upper_y = nextafterf((float)(l->hi.y + pad), INFINITY);
    args->bounds_o->upper_z = nextafterf((float)(l->hi.z + pad), INFINITY);
}

/* Ray against triangle (a, b, c): barycentrics (b1, b2) of the ray's plane hit, unclamped.
 * Returns false when the ray is parallel to the triangle. */
static bool tri_bary(const struct dray *r, vec3 a, vec3 b, vec3 c, double *b1, double *b2)
{
    vec3 e1 = v3_sub(b, a), e2 = v3_sub(c, a);
    vec3 pv = v3_cross(r->d, e2);
    double det = v3_dot(e1, pv);
    if (fabs(det) < 1e-300)
        return false;
    vec3 tv = v3_sub(r->o, a);
    vec3 qv = v3_cross(tv, e1);
    *b1 = v3_dot(tv, pv) / det;
    *b2 = v3_dot(r->d, qv) / det;
    return isfinite(*b1) && isfinite(*b2);
}

static double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

/* How far outside triangle k of the leaf a plane hit with barycentrics (1 - b1 - b2, b1, b2) lies,
 * in world units (a lower bound: the largest distance past one of its edges). */
static double tri_out(const struct leaf *l, int k, double b1, double b2)
{
    double lam[3] = {1.0 - b1 - b2, b1, b2}, out = 0.0;
    for (int i = 0; i < 3; i++)
        out = dmax(out, -lam[i] * l->alt[k][i]);
    return out;
}

/* Newton seed in the leaf's local [0,1]²: the nearer-to-inside of the two corner triangles.
 * Returns how far outside the quad the ray passes, in world units (so that a sliver of a leaf,
 * a few hundredths of a millimetre wide and millimetres long, is measured as fairly as a square). */
static double leaf_seed(const struct leaf *l, const struct dray *r, double *s, double *t)
{
    double a1, a2, b1, b2;
    bool ok1 = tri_bary(r, l->c00, l->c10, l->c11, &a1, &a2); /* (s, t) = (a1 + a2, a2) */
    bool ok2 = tri_bary(r, l->c00, l->c11, l->c01, &b1, &b2); /* (s, t) = (b1, b1 + b2) */
    double out1 = ok1 ? tri_out(l, 0, a1, a2) : INFINITY;
    double out2 = ok2 ? tri_out(l, 1, b1, b2) : INFINITY;
    if (out1 <= out2 && ok1)
        *s = a1 + a2, *t = a2;
    else if (ok2)
        *s = b1, *t = b1 + b2;
    else
        *s = 0.5, *t = 0.5;
    *s = clamp01(*s);
    *t = clamp01(*t);
    return dmin(out1, out2);
}

/* Narrows [*t0, *t1] to where the ray is between the planes n·x = a and n·x = b, given n·d = den,
 * n·o = no and 1 / den = inv. */
static inline void clip_between(double den, double no, double inv, double a, double b, double *t0, double *t1)
{
    if (fabs(den) < 1e-300) {
        if (no < a || no > b)
            *t1 = -INFINITY;
        return;
    }
    double ta = (a - no) * inv, tb = (b - no) * inv;
    *t0 = dmax(*t0, dmin(ta, tb));
    *t1 = dmin(*t1, dmax(ta, tb));
}

/* The same for any n. */
static inline void clip_slab(vec3 n, double a, double b, const struct dray *r, double *t0, double *t1)
{
    double den = v3_dot(n, r->d);
    clip_between(den, v3_dot(n, r->o), 1.0 / den, a, b, t0, t1);
}

/* True when the ray's part in (tnear, tmax) meets the leaf's box and its normal slab: a
 * rigorous test (convex hull property), in double where Embree tested the box in float. */
static bool leaf_reachable(const struct leaf *l, const struct dray *r, double tnear, double tmax)
{
    double t0 = tnear, t1 = tmax;
    /* the control points' box along the leaf's own axes first: Embree hands over only rays that
     * meet the axes' box (in float), and most of them miss this one, which hugs the leaf; the
     * slack of a test is at most about 2e-9 of the larger end, so a gap wider than that is final */
    if (l->has_axes) {
        clip_slab(l->n, l->d0, l->d1, r, &t0, &t1);
        clip_slab(l->e[0], l->e0[0], l->e1[0], r, &t0, &t1);
        clip_slab(l->e[1], l->e0[1], l->e1[1], r, &t0, &t1);
        if (t0 - t1 > 3e-9 * (dmax(fabs(t0), fabs(t1)) + 1.0))
            return false;
    }
    clip_between(r->d.x, r->o.x, r->inv_d.x, l->lo.x, l->hi.x, &t0, &t1);
    clip_between(r->d.y, r->o.y, r->inv_d.y, l->lo.y, l->hi.y, &t0, &t1);
    clip_between(r->d.z, r->o.z, r->inv_d.z, l->lo.z, l->hi.z, &t0, &t1);
    double eps = 1e-9 * (fabs(t0) + fabs(t1) + 1.0);
    return t0 <= t1 + eps;
}

/* The root of the ray in leaf l with t in (tnear, tmax), or false. depth >= 0 (intersection
 * queries): where the ray grazes the leaf or may cross it twice, Newton may miss a root or find
 * the farther of two, so the leaf's quarters are searched instead, each bounded afresh, down to
 * LEAF_SPLIT_DEPTH levels. net: the leaf's own control net when the caller has it (a quarter),
 * else NULL. */
static bool leaf_search(const struct bvh *b, const struct leaf *l, double (*net)[4], const struct dray *r,
                        double tnear, double tmax, int depth, struct solve_hit *h, long *iters)
{
    if (!leaf_reachable(l, r, tnear, tmax))
        return false;
    const struct patch *pt = &b->patches[l->patch];
    const struct solve_box box = {l->u0, l->u1, l->v0, l->v1};
    double s, t;
    double out = leaf_seed(l, r, &s, &t);
    /* A root lies within the net's deviation (and the bilinear's twist) of the corner quad, which a
     * ray at angle θ to the quad's plane meets within that over |cos θ| of it: farther out (with a
     * factor 4 to spare, and a quarter of the narrowest altitude), no Newton start can succeed. */
    double cosang = fabs(v3_dot(r->d, l->n));
    double margin = 0.25 * dmin(dmin(l->alt[0][0], l->alt[0][1]), dmin(l->alt[1][1], l->alt[1][2]));
    if (out > margin + 4.0 * l->slack / dmax(cosang, 1e-6))
        return false;
    /* a ray that grazes the leaf, or may cross it twice (the leaf's normal cone does not
     * show it a height field along the ray; quarters have no cone), searches the quarters instead
     * (every root lies in one of them) */
    bool split = depth >= 0 && depth < LEAF_SPLIT_DEPTH;
    if (split && cosang >= LEAF_GRAZING)
        split = depth == 0 && !(l->cone_sin <= 1.0 && fabs(v3_dot(r->d, l->cone_axis)) > l->cone_sin);
    if (!split) {
        double u = l->u0 + s * (l->u1 - l->u0), v = l->v0 + t * (l->v1 - l->v0);
        /* from the corner quad's seed, giving up when the residual stops falling fast (no root near
         * it: most leaves a ray's box test lets through are missed so); then from the centre, which
         * finds what the seed's start did not (the heart model: iterations a primary ray 10.5 ->
         * 7.6), giving up as fast: the centre found 616 roots in 763 k retries at 8.6 M iterations
         * iterating on, 593 at 3.0 M giving up (the heart at 1024^2: render 1120 -> 840 ms, 2
         * pixels of 313 k shaded otherwise; the teapot, cup and mug the same) */
        bool ok = solve_newton_seeded(pt, r, u, v, &box, b->tol2, h);
        *iters += h->iters;
        if (!ok) { /* no root from the seed: retry from the centre */
            ok = solve_newton_seeded(pt, r, 0.5 * (l->u0 + l->u1), 0.5 * (l->v0 + l->v1), &box, b->tol2, h);
            *iters += h->iters;
        }
        return ok && h->t > tnear && h->t < tmax && (!l->trim_cut || bezier_kept(pt, h->u, h->v));
    }
    /* the quarters' nets from the leaf's by halving it in u, then each half in v */
    const size_t n_pts = (size_t)(pt->p + 1) * (pt->q + 1);
    double bicubic[7 * 16][4]; /* own net, two halves, four quarters: on the stack for the usual degrees */
    double(*buf)[4] = n_pts <= 16 ? bicubic : malloc(sizeof *buf * 7 * n_pts);
    if (!buf)
        return false;
    double(*half)[4] = buf + n_pts, (*quarters)[4] = buf + 3 * n_pts;
    struct patch whole = *pt;
    whole.cw = net;
    if (!net) {
        whole.cw = buf;
        sub_net(pt, l->u0, l->u1, l->v0, l->v1, buf, half);
    }
    bezier_split_u(&whole, 0.5, half, half + n_pts);
    for (int i = 0; i < 2; i++) {
        struct patch hp = *pt;
        hp.cw = half + i * n_pts;
        bezier_split_v(&hp, 0.5, quarters + 2 * i * n_pts, quarters + (2 * i + 1) * n_pts);
    }
    bool found = false;
    const double um = 0.5 * (l->u0 + l->u1), vm = 0.5 * (l->v0 + l->v1);
    for (int q = 0; q < 4; q++) { /* q = 2 (upper u half) + (upper v half) */
        double a0 = q & 2 ? um : l->u0, a1 = q & 2 ? l->u1 : um, b0 = q & 1 ? vm : l->v0, b1 = q & 1 ? l->v1 : vm;
        struct patch sub = *pt;
        sub.cw = quarters + q * n_pts;
        struct leaf quarter;
        bezier_bounds(&sub, &quarter.lo, &quarter.hi);
        quarter.has_axes = false; /* the box alone first: most quarters are missed */
        quarter.trim_cut = l->trim_cut;
        if (!leaf_reachable(&quarter, r, tnear, found ? h->t : tmax))
            continue;
        if (l->has_axes) { /* then the box along the leaf's axes, which fit a quarter nearly as well */
            quarter.has_axes = true, quarter.n = l->n, quarter.e[0] = l->e[0], quarter.e[1] = l->e[1];
            axes_extents(&quarter, &sub, v3_len(v3_sub(quarter.hi, quarter.lo)));
            if (!leaf_reachable(&quarter, r, tnear, found ? h->t : tmax))
                continue;
        }
        leaf_fill(&quarter, &sub, l->patch, a0, a1, b0, b1, net_deviation(&sub, NULL, NULL));
        struct solve_hit qh;
        if (leaf_search(b, &quarter, sub.cw, r, tnear, found ? h->t : tmax, depth + 1, &qh, iters)) {
            *h = qh;
            found = true;
        }
    }
    if (buf != bicubic)
        free(buf);
    return found;
}

static bool leaf_hit(const struct bvh *b, const struct leaf *l, const struct dray *r, double tnear, double tmax,
                     struct solve_hit *h, long *iters)
{
    return leaf_search(b, l, NULL, r, tnear, tmax, -1, h, iters);
}

static void leaf_intersect(const struct RTCIntersectFunctionNArguments *args)
{
    if (!args->valid[0])
        return;
    struct query *qy = (struct query *)args->context;
    const struct bvh *b = args->geometryUserPtr;
    const struct leaf *l = &b->leaves[args->primID];
    struct solve_hit h;
    int k = 0;
    while (k < qy->n_among && qy->among[k] != l->patch)
        k++;
    if ((qy->among && k == qy->n_among) || !leaf_search(b, l, NULL, qy->r, qy->tnear, qy->best_t, 0, &h, &qy->iters))
        return;
    struct RTCRayHit *rh = (struct RTCRayHit *)args->rayhit;
    qy->best_t = h.t;
    qy->found = true;
    qy->hit->patch = l->patch;
    qy->hit->u = h.u;
    qy->hit->v = h.v;
    qy->hit->t = h.t;
    qy->hit->has_normal = v3_dot(h.n, h.n) > 0;
    qy->hit->normal = h.n;
    /* float tfar must not cut off a double root that lies a rounding step beyond */
    rh->ray.tfar = nextafterf((float)h.t, INFINITY);
    rh->hit.geomID = args->geomID;
    rh->hit.primID = args->primID;
}

/* A shadow ray leaving a point of leaf l meets l nowhere else when every normal of l has the
 * same sign along the ray (then l is a height field along it): its normal cone decides. */
static bool leaves_only_its_origin(const struct leaf *l, const struct bvh_origin *o, const struct dray *r)
{
    if (!o || o->patch != l->patch || l->cone_sin > 1.0)
        return false;
    if (o->u < l->u0 - SOLVE_BOX_EPS || o->u > l->u1 + SOLVE_BOX_EPS || o->v < l->v0 - SOLVE_BOX_EPS ||
        o->v > l->v1 + SOLVE_BOX_EPS)
        return false;
    return fabs(v3_dot(r->d, l->cone_axis)) > l->cone_sin;
}

/* A shadow ray leaving a point of the neighbourhood of leaf l (same patch) meets l nowhere when
 * its direction is steeper than every chord of that neighbourhood (chord_bound): the ray from
 * the origin to any point of l would be such a chord. */
static bool leaves_its_neighbourhood(const struct leaf *l, const struct bvh_origin *o, const struct dray *r)
{
    return o && o->patch == l->patch && l->chord_sin < 1.0 && o->u >= l->ru0 && o->u <= l->ru1 &&
           o->v >= l->rv0 && o->v <= l->rv1 && fabs(v3_dot(r->d, l->chord_n)) > l->chord_sin;
}

/* Where leaf l's parameter box starts and ends along edge e of its patch (u = 0 or 1: along v),
 * and whether it touches that edge. */
static bool on_edge(const struct leaf *l, int e, double *lo, double *hi)
{
    *lo = e < 2 ? l->v0 : l->u0, *hi = e < 2 ? l->v1 : l->u1;
    return e == 0 ? l->u0 == 0.0 : e == 1 ? l->u1 == 1.0 : e == 2 ? l->v0 == 0.0 : l->v1 == 1.0;
}

struct border_key {
    double at;        /* where the leaf starts along the edge */
    uint32_t leaf;
};

static int border_cmp(const void *x, const void *y)
{
    const struct border_key *a = x, *c = y;
    return (a->at > c->at) - (a->at < c->at);
}

/* The border lists of b's n patches (bvh.border): each seam edge's leaves, in order along it. */
static int find_borders(struct bvh *b, size_t n)
{
    if (!(b->border_at = calloc(4 * n + 1, sizeof *b->border_at)))
        return SF_ENOMEM;
    double lo, hi;
    for (size_t k = 0; k < b->n_leaves; k++) /* counts, each after its list's start */
        for (int e = 0; e < 4; e++)
            if (b->chords[b->leaves[k].patch].seam[e].other >= 0 && on_edge(&b->leaves[k], e, &lo, &hi))
                b->border_at[4 * (size_t)b->leaves[k].patch + e + 1]++;
    for (size_t at = 1; at <= 4 * n; at++)
        b->border_at[at] += b->border_at[at - 1];
    size_t total = b->border_at[4 * n], *fill = malloc(sizeof *fill * 4 * n);
    struct border_key *keys = malloc(sizeof *keys * (total ? total : 1));
    b->border = malloc(sizeof *b->border * (total ? total : 1));
    if (!fill || !keys || !b->border) {
        free(fill), free(keys);
        return SF_ENOMEM;
    }
    memcpy(fill, b->border_at, sizeof *fill * 4 * n);
    for (size_t k = 0; k < b->n_leaves; k++)
        for (int e = 0; e < 4; e++)
            if (b->chords[b->leaves[k].patch].seam[e].other >= 0 && on_edge(&b->leaves[k], e, &lo, &hi))
                keys[fill[4 * (size_t)b->leaves[k].patch + e]++] = (struct border_key){lo, (uint32_t)k};
    for (size_t at = 0; at < 4 * n; at++)
        qsort(keys + b->border_at[at], b->border_at[at + 1] - b->border_at[at], sizeof *keys, border_cmp);
    for (size_t k = 0; k < total; k++)
        b->border[k] = keys[k].leaf;
    free(fill), free(keys);
    return 0;
}

/* A shadow ray leaving a point of a border leaf of its patch meets the neighbour's leaf l across
 * the seam nowhere when the two leaves touch along the seam and d lies on the same side of every
 * normal of both (their normal cones): the neighbour continues the patch's parameters, so the two
 * leaves are one surface, every normal of which has the same sign along the ray, a height field
 * along it (as in leaves_only_its_origin), which the ray leaves at its origin. Rays near seams
 * were most of the heart model's shadow iterations (Newton failing on the neighbour's leaves). */
static bool leaves_across_seam(const struct bvh *b, const struct leaf *l, const struct bvh_origin *o, const struct dray *r)
{
    if (!o || o->patch < 0 || !b->border || l->cone_sin > 1.0)
        return false;
    double sb = v3_dot(r->d, l->cone_axis);
    if (fabs(sb) <= l->cone_sin)
        return false;
    const struct chords *c = &b->chords[o->patch];
    for (int e = 0; e < 4; e++) {
        double lo, hi, alo, ahi;
        if (c->seam[e].other != l->patch || !on_edge(l, e ^ 1, &lo, &hi))
            continue;
        /* the origin's leaf: the last along the edge that starts at or before it */
        const uint32_t *list = b->border + b->border_at[4 * (size_t)o->patch + e];
        size_t n = b->border_at[4 * (size_t)o->patch + e + 1] - b->border_at[4 * (size_t)o->patch + e], k0 = 0;
        double t = e < 2 ? o->v : o->u;
        while (n > 1) {
            size_t half = n / 2;
            const struct leaf *m = &b->leaves[list[k0 + half]];
            if ((e < 2 ? m->v0 : m->u0) <= t)
                k0 += half, n -= half;
            else
                n = half;
        }
        if (n == 0)
            continue;
        const struct leaf *a = &b->leaves[list[k0]];
        on_edge(a, e, &alo, &ahi);
        if (o->u < a->u0 || o->u > a->u1 || o->v < a->v0 || o->v > a->v1 || fmin(ahi, hi) <= fmax(alo, lo) ||
            a->cone_sin > 1.0)
            continue;
        double sa = v3_dot(r->d, a->cone_axis);
        if (fabs(sa) > a->cone_sin && (sa > 0) == (sb > 0))
            return true;
    }
    return false;
}

/* Any-hit callback: Embree may hand over a packet of rays (N lanes); each lane's double ray is
 * the shadow request its id names. A packet is laid out field by field, N of each (as the
 * RTCRayN_* accessors of rtcore_ray.h, which are C++ only): tfar is field 8, id field 10. */
#define RAYN_TFAR(ray, N, i) (((float *)(ray))[8 * (N) + (i)])
#define RAYN_ID(ray, N, i) (((unsigned *)(ray))[10 * (N) + (i)])
static void leaf_occluded(const struct RTCOccludedFunctionNArguments *args)
{
    struct query *qy = (struct query *)args->context;
    const struct bvh *b = args->geometryUserPtr;
    const struct leaf *l = &b->leaves[args->primID];
    for (unsigned i = 0; i < args->N; i++) {
        if (!args->valid[i])
            continue;
        struct bvh_shadow *s = &qy->shadows[RAYN_ID(args->ray, args->N, i)];
        struct solve_hit h;
        if (s->blocked || leaves_only_its_origin(l, &s->from, &s->r) || leaves_its_neighbourhood(l, &s->from, &s->r) ||
            bvh_meets_once(b, s->from.patch, l->patch, s->r.d) || leaves_across_seam(b, l, &s->from, &s->r))
            continue;
        if (leaf_hit(b, l, &s->r, s->tnear, s->tfar, &h, &qy->iters)) {
            s->blocked = true;
            RAYN_TFAR(args->ray, args->N, i) = -INFINITY;
        }
    }
}

static struct bvh *bvh_alloc(const struct patch *patches, double tol2)
{
    struct bvh *b = calloc(1, sizeof *b);
    if (b) {
        b->patches = patches;
        b->tol2 = tol2;
    }
    return b;
}

/* One triangle geometry of mesh m, or NULL when Embree has no memory for its buffers. */
static RTCGeometry triangles(struct bvh_device *dev, const struct trimesh *m)
{
    RTCGeometry g = rtcNewGeometry(dev->dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m->n_vert);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m->n_tri);
    if (!vb || !ib) {
        rtcReleaseGeometry(g);
        return NULL;
    }
    memcpy(vb, m->pos, 3 * sizeof(float) * m->n_vert);
    memcpy(ib, m->tri, 3 * sizeof(unsigned) * m->n_tri);
    rtcCommitGeometry(g);
    return g;
}

/* Attaches g (taking it over; NULL: none) and b's meshes to a new scene of b and builds it; on
 * failure frees b. */
static int bvh_commit(struct bvh *b, struct bvh_device *dev, RTCGeometry g, struct bvh **out, struct sf_err *err)
{
    b->scene = rtcNewScene(dev->dev);
    rtcSetSceneBuildQuality(b->scene, RTC_BUILD_QUALITY_HIGH);
    if (g) {
        rtcCommitGeometry(g);
        rtcAttachGeometry(b->scene, g);
        rtcReleaseGeometry(g);
    }
    for (int k = 0; k < b->n_meshes; k++) {
        RTCGeometry t = triangles(dev, b->meshes[k]);
        if (!t) {
            bvh_free(b);
            return sf_fail(err, SF_ENOMEM, "", "out of memory for the triangles of a mesh");
        }
        unsigned id = rtcAttachGeometry(b->scene, t);
        if (k == 0)
            b->mesh_geom = id;
        rtcReleaseGeometry(t);
    }
    rtcCommitScene(b->scene);
    enum RTCError e = rtcGetDeviceError(dev->dev);
    if (e != RTC_ERROR_NONE) {
        bvh_free(b);
        return sf_fail(err, e == RTC_ERROR_OUT_OF_MEMORY ? SF_ENOMEM : SF_EBACKEND, "", "Embree build failed (%d)",
                       (int)e);
    }
    *out = b;
    return 0;
}

int bvh_build_patches(struct bvh_device *dev, const struct patch *patches, size_t n, double tol2,
                      struct bvh **out, struct sf_err *err)
{
    return bvh_build_scene(dev, patches, n, tol2, INFINITY, NULL, 0, out, err);
}

int bvh_build_scene(struct bvh_device *dev, const struct patch *patches, size_t n, double tol2, double fine,
                    const struct trimesh *const *meshes, int n_meshes, struct bvh **out, struct sf_err *err)
{
    *out = NULL;
    struct bvh *b = bvh_alloc(patches, tol2);
    if (!b)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    b->meshes = meshes;
    b->n_meshes = n_meshes;
    b->fine = fine;
    int rc = find_seams(b, n);
    for (size_t k = 0; k < n && !rc; k++) {
        if (patches[k].rational && !b->rat)
            b->rat = malloc(sizeof *b->rat);
        if (patches[k].rational && b->rat) /* (no memory: its leaves get no cones, their chords from their nets) */
            rat_polys_make(b->rat, &patches[k]);
        const struct patch *nrm = patches[k].rational && b->rat && b->rat->ok ? &b->rat->n : NULL;
        rc = subdivide(b, &patches[k], nrm, (int)k, 0.0, 1.0, 0.0, 1.0, 0, patches[k].trim != NULL);
    }
    free(b->rat);
    b->rat = NULL;
    if (!rc)
        rc = find_borders(b, n);
    if (rc) {
        bvh_free(b);
        return sf_fail(err, rc, "", "out of memory building the hierarchy");
    }
    if (n == 0) /* meshes alone */
        return bvh_commit(b, dev, NULL, out, err);
    RTCGeometry g = rtcNewGeometry(dev->dev, RTC_GEOMETRY_TYPE_USER);
    rtcSetGeometryUserPrimitiveCount(g, (unsigned)b->n_leaves);
    rtcSetGeometryUserData(g, b);
    rtcSetGeometryBoundsFunction(g, leaf_bounds, NULL);
    rtcSetGeometryIntersectFunction(g, leaf_intersect);
    rtcSetGeometryOccludedFunction(g, leaf_occluded);
    return bvh_commit(b, dev, g, out, err);
}

int bvh_build_mesh(struct bvh_device *dev, const struct patch *patches, size_t n, double chord_tol,
                   struct bvh **out, struct sf_err *err)
{
    *out = NULL;
    struct bvh *b = bvh_alloc(patches, 0.0);
    if (!b)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    if (tess_build(patches, n, chord_tol, TESS_MAX_SIDE, &b->mesh)) {
        bvh_free(b);
        return sf_fail(err, SF_ENOMEM, "", "out of memory tessellating");
    }
    RTCGeometry g = rtcNewGeometry(dev->dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                        b->mesh.n_verts);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                           b->mesh.n_tris);
    if (!vb || !ib) {
        rtcReleaseGeometry(g);
        bvh_free(b);
        return sf_fail(err, SF_ENOMEM, "", "out of memory for the triangle buffers");
    }
    for (size_t k = 0; k < b->mesh.n_verts; k++)
        for (int c = 0; c < 3; c++)
            vb[3 * k + c] = (float)b->mesh.pos[k][c];
    memcpy(ib, b->mesh.tri, sizeof(unsigned) * 3 * b->mesh.n_tris);
    return bvh_commit(b, dev, g, out, err);
}

static void set_ray(struct RTCRay *ray, const struct dray *r, double tnear, double tfar)
{
    ray->org_x = (float)r->o.x, ray->org_y = (float)r->o.y, ray->org_z = (float)r->o.z;
    ray->dir_x = (float)r->d.x, ray->dir_y = (float)r->d.y, ray->dir_z = (float)r->d.z;
    /* float bounds widened outward: the exact test happens in double in the callbacks */
    ray->tnear = (float)dmax(0.0, tnear * 0.999999);
    ray->tfar = isinf(tfar) ? INFINITY : nextafterf((float)tfar, INFINITY);
    ray->time = 0.0f;
    ray->mask = 0xFFFFFFFFu;
    ray->id = 0;
    ray->flags = 0;
}

bool bvh_intersect(const struct bvh *b, const struct dray *r, double tnear, double tfar, struct bvh_hit *hit,
                   long *iters)
{
    return bvh_intersect_among(b, r, tnear, tfar, NULL, 0, hit, iters);
}

bool bvh_intersect_among(const struct bvh *b, const struct dray *r, double tnear, double tfar, const int *patches,
                         int n, struct bvh_hit *hit, long *iters)
{
    struct query qy = {.b = b, .r = r, .tnear = tnear, .hit = hit, .among = patches, .n_among = n, .best_t = tfar};
    rtcInitIntersectContext(&qy.ctx);
    struct RTCRayHit rh;
    set_ray(&rh.ray, r, tnear, tfar);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(b->scene, &qy.ctx, &rh);
    if (iters)
        *iters += qy.iters;
    if (b->n_meshes && rh.hit.geomID != RTC_INVALID_GEOMETRY_ID && rh.hit.geomID >= b->mesh_geom &&
        rh.hit.geomID < b->mesh_geom + (unsigned)b->n_meshes && rh.ray.tfar > tnear) {
        /* a mesh's triangle, nearer than any patch: its normals interpolated */
        int k = (int)(rh.hit.geomID - b->mesh_geom);
        const struct trimesh *m = b->meshes[k];
        const uint32_t *tri = m->tri + 3 * (size_t)rh.hit.primID;
        float w1 = rh.hit.u, w2 = rh.hit.v, w0 = 1.0f - w1 - w2;
        *hit = (struct bvh_hit){.patch = BVH_MESH_HIT(k), .u = w1, .v = w2, .t = rh.ray.tfar, .has_normal = true};
        if (m->nrm) {
            const float *n0 = m->nrm + 3 * (size_t)tri[0], *n1 = m->nrm + 3 * (size_t)tri[1], *n2 = m->nrm + 3 * (size_t)tri[2];
            hit->normal = v3(w0 * n0[0] + w1 * n1[0] + w2 * n2[0], w0 * n0[1] + w1 * n1[1] + w2 * n2[1],
                             w0 * n0[2] + w1 * n1[2] + w2 * n2[2]);
        } else {
            hit->normal = v3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
        }
        double len = v3_len(hit->normal);
        hit->has_normal = len > 0;
        if (len > 0)
            hit->normal = v3_scale(hit->normal, 1.0 / len);
        return true;
    }
    if (!b->mesh.tri)
        return qy.found;
    /* triangles: interpolate the patch parameters and the normal of the hit */
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID || !(rh.ray.tfar > tnear))
        return false;
    const unsigned *tri = b->mesh.tri[rh.hit.primID];
    float w1 = rh.hit.u, w2 = rh.hit.v, w0 = 1.0f - w1 - w2;
    const float *n0 = b->mesh.nrm[tri[0]], *n1 = b->mesh.nrm[tri[1]], *n2 = b->mesh.nrm[tri[2]];
    hit->patch = b->mesh.patch[tri[0]];
    hit->u = w0 * b->mesh.uv[tri[0]][0] + w1 * b->mesh.uv[tri[1]][0] + w2 * b->mesh.uv[tri[2]][0];
    hit->v = w0 * b->mesh.uv[tri[0]][1] + w1 * b->mesh.uv[tri[1]][1] + w2 * b->mesh.uv[tri[2]][1];
    hit->t = rh.ray.tfar;
    hit->has_normal = true;
    hit->normal = v3_norm(v3(w0 * n0[0] + w1 * n1[0] + w2 * n2[0], w0 * n0[1] + w1 * n1[1] + w2 * n2[1],
                             w0 * n0[2] + w1 * n1[2] + w2 * n2[2]));
    return true;
}

#define SHADOW_BATCH 64 /* rays handed to Embree at once */

void bvh_occluded_many(const struct bvh *b, struct bvh_shadow *rays, size_t n, long *iters)
{
    struct query qy = {.b = b, .shadows = rays};
    rtcInitIntersectContext(&qy.ctx);
    /* incoherent (Embree's default): traced one by one, they are faster than as packets, whose
     * rays leave a surface of small leaves each among its own (the heart's shadow rays at
     * 1024^2: 113 -> 97 ms; the teapot's the same) */
    for (size_t at = 0; at < n; at += SHADOW_BATCH) {
        struct RTCRay batch[SHADOW_BATCH];
        size_t m = n - at < SHADOW_BATCH ? n - at : SHADOW_BATCH;
        for (size_t k = 0; k < m; k++) {
            struct bvh_shadow *s = &rays[at + k];
            s->blocked = false;
            set_ray(&batch[k], &s->r, s->tnear, s->tfar);
            batch[k].id = (unsigned)(at + k);
        }
        rtcOccluded1M(b->scene, &qy.ctx, batch, (unsigned)m, sizeof *batch);
        if (b->mesh.tri || b->n_meshes) /* triangles block without a callback */
            for (size_t k = 0; k < m; k++)
                rays[at + k].blocked = rays[at + k].blocked || batch[k].tfar < 0.0f;
    }
    if (iters)
        *iters += qy.iters;
}

bool bvh_occluded(const struct bvh *b, const struct dray *r, const struct bvh_origin *from, double tnear, double tfar,
                  long *iters)
{
    struct bvh_shadow s = {.r = *r, .from = from ? *from : (struct bvh_origin){-1, 0, 0}, .tnear = tnear, .tfar = tfar};
    bvh_occluded_many(b, &s, 1, iters);
    return s.blocked;
}
