/* solid.c - contour models closed into solids: tubes of bands (solid.h), their measures and
 * their triangle meshes (flat ends ear-clipped and joined where tubes meet in a plane: join.c). */
#include "solid.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../base/gauss.h"
#include "../base/mem.h"
#include "join.h"

/* ---- building ------------------------------------------------------------------------------ */

/* Appends a patch of degree (p, q) and returns its control points, valid until the next append
 * (the pool may move); NULL when out of memory. cw is kept as a pool offset until the end. */
static double (*new_patch(struct patch_set *set, int p, int q, bool rational, double u0, double u1))[4]
{
    size_t np = (size_t)(p + 1) * (size_t)(q + 1);
    if (mem_reserve((void **)&set->patches, &set->cap, set->n + 1, sizeof *set->patches) ||
        mem_reserve((void **)&set->pool, &set->cap_pool, set->n_pool + np, sizeof *set->pool))
        return NULL;
    set->patches[set->n++] = (struct patch){.p = p, .q = q, .rational = rational, .cw = (double(*)[4])(uintptr_t)set->n_pool, .u0 = u0, .u1 = u1, .v1 = 1};
    set->n_pool += np;
    return set->pool + set->n_pool - np;
}

/* Patch k with its control points resolved (while they are still pool offsets). */
static struct patch resolved(const struct patch_set *set, size_t k)
{
    struct patch pt = set->patches[k];
    pt.cw = set->pool + (uintptr_t)pt.cw;
    return pt;
}

/* Area enclosed by a band's row t (0 or 1): ∮ x dy, exact for the cubic rows of side bands. */
static double row_area(const struct patch_set *set, const struct band *b, double t)
{
    double a = 0.0;
    for (size_t k = b->first; k < b->first + b->n; k++) {
        struct patch pt = resolved(set, k);
        for (int g = 0; g < 5; g++) {
            vec3 P, Pu;
            bezier_eval(&pt, GL5_X[g], t, &P, &Pu, NULL);
            a += GL5_W[g] * P.x * Pu.y;
        }
    }
    return a;
}

/* The dome's profile (s, ρ), ρ² = q(s)/q(0), as a rational quadratic: from (0, 1) along the slope
 * q'(0)/(2 q(0)) to the apex (root, 0), where it arrives vertically; the middle weight puts the
 * curve through the profile's point at s = root/2 (a conic is fixed by two tangents and a point). */
static void dome_profile(const struct model_dome *d, double s[3], double rho[3], double w[3])
{
    double R = d->root, b = d->b / d->a0, c = d->c / d->a0;
    s[0] = 0, rho[0] = 1, w[0] = 1;
    s[1] = R, rho[1] = 1 + 0.5 * b * R, w[1] = 1;
    s[2] = R, rho[2] = 0, w[2] = 1;
    double sm = 0.5 * R, rm = sqrt(fmax(0.0, 1 + b * sm + c * sm * sm));
    /* M = α P0 + β P1 + γ P2: α = 1/2 from x; then w1 = β / (2 sqrt(α γ)) */
    double alpha = 0.5, beta = rho[1] > 1e-9 ? (rm - alpha) / rho[1] : 0.0, gamma = 1 - alpha - beta;
    if (beta > 0 && gamma > 0)
        w[1] = beta / (2 * sqrt(alpha * gamma));
    else /* a double root: the profile is a straight line to the apex (a cone) */
        s[1] = 0.5 * R, rho[1] = 0.5;
}

/* The end bands of one end (e = 0 bottom, 1 top) of a tube whose end side band is `side`:
 * a dome (when d is given), or a wall of ext (when ext > 0) and a cap. Appends them to out in the
 * tube's upward order for that end. */
static int end_bands(struct solid *s, const struct band *side, int e, double z, const double c[2], double area,
                     const struct model_dome *d, double ext, struct band *out, int *n_out)
{
    struct patch_set *set = &s->set;
    int n = 0;
    double sd[3], rho_d[3], w[3];
    if (d)
        dome_profile(d, sd, rho_d, w);
    enum band_kind kinds[2];
    if (d)
        kinds[n++] = BAND_DOME;
    else {
        if (ext > 0)
            kinds[n++] = BAND_WALL;
        kinds[n++] = BAND_CAP;
    }
    if (!e) /* bottom: outermost first */
        for (int a = 0, b = n - 1; a < b; a++, b--) {
            enum band_kind t = kinds[a];
            kinds[a] = kinds[b], kinds[b] = t;
        }
    double dir = e ? 1.0 : -1.0, zc = z + dir * ext; /* the cap's plane */
    for (int k = 0; k < n; k++) {
        struct band *b = &out[(*n_out)++];
        *b = (struct band){kinds[k], set->n, side->n, kinds[k] == BAND_CAP ? area : 0.0};
        for (size_t i = side->first; i < side->first + side->n; i++) {
            struct patch sp = resolved(set, i);
            double E[4][2]; /* the end row: bicubic side patches (v = 0 or 1) */
            for (int a = 0; a < 4; a++) {
                const double *P = sp.cw[a * (sp.q + 1) + (e ? sp.q : 0)];
                E[a][0] = P[0] / P[3], E[a][1] = P[1] / P[3];
            }
            /* row j of every band is c + ρ_j (E - c) at height h_j with weight w_j */
            double rho[4], h[4], wt[4] = {1, 1, 1, 1};
            int q;
            if (kinds[k] == BAND_DOME) { /* top: rim at t = 0; bottom: apex at t = 0 */
                q = 2;
                for (int j = 0; j < 3; j++) {
                    int r = e ? j : 2 - j;
                    rho[r] = rho_d[j], h[r] = z + dir * sd[j], wt[r] = w[j];
                }
            } else if (kinds[k] == BAND_WALL) { /* bicubic, z linear: the side's fast measures apply */
                q = 3;
                for (int j = 0; j < 4; j++)
                    rho[j] = 1.0, h[j] = e ? z + (zc - z) * j / 3.0 : zc + (z - zc) * j / 3.0;
            } else { /* cap: top from the rim to the centre, bottom back, so that Su × Sv faces out */
                q = 1;
                rho[0] = e ? 1.0 : 0.0, rho[1] = 1.0 - rho[0], h[0] = h[1] = zc;
            }
            double(*cw)[4] = new_patch(set, 3, q, kinds[k] == BAND_DOME, sp.u0, sp.u1);
            if (!cw)
                return SF_ENOMEM;
            for (int a = 0; a < 4; a++)
                for (int j = 0; j <= q; j++) {
                    double *P = cw[a * (q + 1) + j];
                    P[0] = wt[j] * (c[0] + rho[j] * (E[a][0] - c[0]));
                    P[1] = wt[j] * (c[1] + rho[j] * (E[a][1] - c[1]));
                    P[2] = wt[j] * h[j];
                    P[3] = wt[j];
                }
        }
    }
    return 0;
}

/* Reverses u in every patch of bands [b0, b1): the surface then faces the other way. */
static void flip_u(struct solid *s, int b0, int b1)
{
    for (int b = b0; b < b1; b++)
        for (size_t k = s->bands[b].first; k < s->bands[b].first + s->bands[b].n; k++) {
            struct patch pt = resolved(&s->set, k);
            int m = pt.q + 1;
            for (int i = 0; 2 * i < pt.p; i++)
                for (int j = 0; j < m; j++)
                    for (int c = 0; c < 4; c++) {
                        double t = pt.cw[i * m + j][c];
                        pt.cw[i * m + j][c] = pt.cw[(pt.p - i) * m + j][c];
                        pt.cw[(pt.p - i) * m + j][c] = t;
                    }
        }
}

static int tube_build(struct solid *s, const struct contour_set *cs, const struct model_chain *ch, struct model_opts o,
                      enum model_caps caps, struct contour_slice *storage, struct tube *tb, struct sf_err *err)
{
    struct contour_set v = model_chain_view(cs, ch, storage);
    double ext[2] = {ch->ext[0], ch->ext[1]}, island_h = 0.0;
    bool dome[2] = {caps == CAPS_DOME && ch->at_end[0], caps == CAPS_DOME && ch->at_end[1]};
    if (v.n_slices == 1) { /* an island on one level: a prism of its extensions */
        for (int e = 0; e < 2; e++)
            if (dome[e]) {
                ext[e] += 0.5 * ch->spacing[e];
                s->dome_fallbacks++;
                dome[e] = false;
            }
        storage[1] = storage[0];
        storage[0].z -= ext[0];
        storage[1].z += ext[1];
        v.n_slices = 2;
        island_h = ext[0] + ext[1];
        ext[0] = ext[1] = 0.0;
    }
    size_t p0 = s->set.n;
    int rc = model_side_closed(&v, o, &s->set, island_h > 0 || !o.closed ? NULL : &tb->side, err);
    if (rc)
        return rc;
    int n_side = 0, nb = 0; /* one side band per run of equal v0: a level pair, or a span */
    for (size_t k = p0; k < s->set.n; k++)
        n_side += k == p0 || s->set.patches[k].v0 != s->set.patches[k - 1].v0;
    struct band *side = malloc(sizeof *side * (size_t)n_side);
    if (!side)
        return sf_fail(err, SF_ENOMEM, "", "out of memory");
    for (size_t k = p0; k < s->set.n; k++) {
        if (k == p0 || s->set.patches[k].v0 != s->set.patches[k - 1].v0)
            side[nb++] = (struct band){BAND_SIDE, k, 0, 0.0};
        side[nb - 1].n++;
    }
    struct band ends[2][2];
    int n_end[2] = {0, 0};
    tb->hole = ch->hole;
    tb->volume_ends = island_h > 0 ? fabs(row_area(&s->set, &side[0], 0.0)) * island_h : 0.0;
    for (int e = 0; e < 2 && !rc; e++) {
        const struct band *sb = &side[e ? nb - 1 : 0];
        const struct contour_slice *cend = &v.s[e ? v.n_slices - 1 : 0];
        struct model_dome d;
        double area = fabs(row_area(&s->set, sb, e));
        if (dome[e]) { /* the section areas of the last three levels: the side's end row, then the curves */
            double z[3], A[3];
            int m = v.n_slices > 2 ? 3 : 2;
            for (int i = 0; i < m; i++) {
                const struct contour_slice *ci = &v.s[e ? v.n_slices - 1 - i : i];
                z[i] = ci->z;
                A[i] = i ? model_curve_area(ci) : area;
            }
            double vol = model_dome(z, A, m, &d);
            if (isnan(vol)) {
                ext[e] += 0.5 * ch->spacing[e];
                s->dome_fallbacks++;
                dome[e] = false;
            } else
                tb->volume_ends += vol;
        }
        if (!dome[e])
            tb->volume_ends += area * ext[e];
        double c[2];
        contour_centroid(cend, &c[0], &c[1]);
        rc = end_bands(s, sb, e, cend->z, c, area, dome[e] ? &d : NULL, ext[e], ends[e], &n_end[e]);
    }
    if (ch->hole)
        tb->volume_ends = -tb->volume_ends;
    int total = n_end[0] + nb + n_end[1];
    if (!rc && mem_reserve((void **)&s->bands, &s->cap_bands, (size_t)(s->n_bands + total), sizeof *s->bands))
        rc = SF_ENOMEM;
    if (!rc) {
        tb->first = s->n_bands;
        tb->n = total;
        struct band *out = s->bands + s->n_bands;
        memcpy(out, ends[0], sizeof *out * (size_t)n_end[0]);
        memcpy(out + n_end[0], side, sizeof *out * (size_t)nb);
        memcpy(out + n_end[0] + nb, ends[1], sizeof *out * (size_t)n_end[1]);
        s->n_bands += total;
        if (ch->hole)
            flip_u(s, tb->first, s->n_bands);
    }
    free(side);
    return rc == SF_ENOMEM ? sf_fail(err, rc, "", "out of memory building the solid") : rc;
}

/* ---- holes that would leave the body ------------------------------------------------------------
 * A hole's chain end extends flat by half a spacing (model_chains), a prism of its end contour. Where
 * the body's side surface moves in between two levels (the left lung's hole at z -74.44 lies outside
 * the lung's one contour at -77.44), that prism pokes out through the body: the mesh cuts itself and
 * the volume takes away what was never in the body. Ours (the seeds are silent): such an end stops at
 * the greatest tenth of its extension up to which the contour's points, and the midpoints between
 * them, lie inside the sections of the body's tubes at every tenth, by at least HOLE_MARGIN of the
 * spacing. The sections are those of side and wall bands (z linear in t), sampled HOLE_SAMPLES times
 * a patch. A hole cut by the body at its own level ends there, flat, unless it has no other level:
 * then it keeps its extensions (a contour of no volume is no hole). */
#define HOLE_MARGIN 0.02
#define HOLE_SAMPLES 2

/* The bin of height y among nb bins of height bh from y0 (clamped to them). */
static size_t bin_of(double y, double y0, double bh, size_t nb)
{
    return bh > 0 ? (size_t)fmin(fmax((y - y0) / bh, 0.0), (double)nb - 1) : 0;
}

/* Sets in[i] for the points p[i] inside the edges e (x0, y0, x1, y1: all those of a closed section
 * that reach the points' +x rays or come within margin of them) by even-odd and by at least
 * margin. The edges are binned by y, each into the bins its y-range (widened by margin) meets, so
 * that a point reads only those that may cross its line or come near; fewer bins while they would
 * fill more than RING_FILL entries an edge (a comb of long teeth). (trim.c indexes closed loops
 * alone; the section here is cut only where it can reach the hole, a few edges of thousands.) */
#define RING_FILL 16
static int edges_inside(const double (*e)[4], size_t m, const double (*p)[2], int n, double margin, bool *in)
{
    double y0 = INFINITY, y1 = -INFINITY;
    for (size_t a = 0; a < m; a++)
        y0 = fmin(y0, fmin(e[a][1], e[a][3])), y1 = fmax(y1, fmax(e[a][1], e[a][3]));
    y0 -= margin, y1 += margin;
    size_t nb = m / 8 + 1, total = 0;
    double bh = 0.0;
    for (; m; nb = nb / 2 + (nb == 1)) {
        bh = (y1 - y0) / (double)nb;
        total = 0;
        for (size_t a = 0; a < m; a++)
            total += bin_of(fmax(e[a][1], e[a][3]) + margin, y0, bh, nb) - bin_of(fmin(e[a][1], e[a][3]) - margin, y0, bh, nb) + 1;
        if (total <= RING_FILL * m || nb == 1 || !(bh > 0))
            break;
    }
    size_t *start = calloc(nb + 1, sizeof *start), *edge = malloc(sizeof *edge * (total ? total : 1));
    if (!start || !edge) {
        free(start), free(edge);
        return SF_ENOMEM;
    }
    for (int pass = 0; pass < 2; pass++) { /* counts, then the edges */
        for (size_t a = 0; a < m; a++) {
            size_t b1 = bin_of(fmax(e[a][1], e[a][3]) + margin, y0, bh, nb);
            for (size_t b = bin_of(fmin(e[a][1], e[a][3]) - margin, y0, bh, nb); b <= b1; b++)
                if (pass)
                    edge[start[b]++] = a;
                else
                    start[b + 1]++;
        }
        for (size_t b = 0; b < nb && !pass; b++)
            start[b + 1] += start[b];
    }
    for (size_t b = nb; b > 0; b--) /* (filling moved each start to the next's) */
        start[b] = start[b - 1];
    start[0] = 0;
    for (int i = 0; i < n && m; i++) {
        if (in[i] || !(p[i][1] >= y0 && p[i][1] <= y1))
            continue;
        size_t b = bin_of(p[i][1], y0, bh, nb);
        bool odd = false, near = false;
        for (size_t k = start[b]; k < start[b + 1] && !near; k++) {
            const double *A = e[edge[k]], *C = e[edge[k]] + 2;
            if ((A[1] > p[i][1]) != (C[1] > p[i][1]) && p[i][0] < A[0] + (C[0] - A[0]) * (p[i][1] - A[1]) / (C[1] - A[1]))
                odd = !odd;
            double ex = C[0] - A[0], ey = C[1] - A[1], l2 = ex * ex + ey * ey;
            double f = l2 > 0 ? fmin(fmax(((p[i][0] - A[0]) * ex + (p[i][1] - A[1]) * ey) / l2, 0.0), 1.0) : 0.0;
            double dx = A[0] + f * ex - p[i][0], dy = A[1] + f * ey - p[i][1];
            near = dx * dx + dy * dy < margin * margin;
        }
        in[i] = odd && !near;
    }
    free(start), free(edge);
    return 0;
}

/* The x-y bounds (x0, y0, x1, y1) of every patch's control points: its surface lies inside. */
static double (*patch_boxes(const struct solid *s))[4]
{
    double(*box)[4] = malloc(sizeof *box * (s->set.n ? s->set.n : 1));
    for (size_t q = 0; box && q < s->set.n; q++) {
        struct patch pt = resolved(&s->set, q);
        vec3 lo, hi;
        bezier_bounds(&pt, &lo, &hi);
        box[q][0] = lo.x, box[q][1] = lo.y, box[q][2] = hi.x, box[q][3] = hi.y;
    }
    return box;
}

/* Sets in[i] for the points p[i] (within bounds pb) at height z inside the section of the tubes
 * built so far that are not holes, by at least margin: each side or wall band at z, cut at z into
 * HOLE_SAMPLES edges a patch, of the patches (box: patch_boxes) that reach the points' +x rays. */
static int mark_inside(const struct solid *s, const double (*box)[4], const double (*p)[2], int n, const double pb[4],
                       double z, double margin, bool *in)
{
    for (int k = 0; k < s->n_tubes; k++) {
        const struct tube *tb = &s->tubes[k];
        if (tb->hole || !tb->n)
            continue;
        for (int b = tb->first; b < tb->first + tb->n; b++) {
            const struct band *bd = &s->bands[b];
            if (bd->kind != BAND_SIDE && bd->kind != BAND_WALL)
                continue;
            struct patch p0 = resolved(&s->set, bd->first);
            vec3 lo, hi;
            bezier_eval(&p0, 0.0, 0.0, &lo, NULL, NULL);
            bezier_eval(&p0, 0.0, 1.0, &hi, NULL, NULL);
            if (!(z >= fmin(lo.z, hi.z) && z <= fmax(lo.z, hi.z)) || lo.z == hi.z)
                continue;
            double t = (z - lo.z) / (hi.z - lo.z), (*e)[4] = malloc(sizeof *e * HOLE_SAMPLES * bd->n);
            size_t m = 0;
            if (!e)
                return SF_ENOMEM;
            for (size_t q = bd->first; q < bd->first + bd->n; q++) {
                const double *bx = box[q];
                if (bx[1] > pb[3] + margin || bx[3] < pb[1] - margin || bx[2] < pb[0] - margin)
                    continue;
                struct patch pt = resolved(&s->set, q);
                vec3 P;
                bezier_eval(&pt, 0.0, t, &P, NULL, NULL);
                for (int i = 1; i <= HOLE_SAMPLES; i++, m++) {
                    e[m][0] = P.x, e[m][1] = P.y;
                    bezier_eval(&pt, (double)i / HOLE_SAMPLES, t, &P, NULL, NULL);
                    e[m][2] = P.x, e[m][3] = P.y;
                }
            }
            int rc = edges_inside((const double(*)[4])e, m, p, n, margin, in);
            free(e);
            if (rc)
                return rc;
        }
    }
    return 0;
}

/* The extensions of the hole chain's ends shortened where the prism would leave the body. */
static int hole_reach(const struct solid *s, const double (*box)[4], const struct contour_set *cs,
                      struct model_chain *ch)
{
    double was[2] = {ch->ext[0], ch->ext[1]};
    for (int e = 0; e < 2; e++) {
        const struct contour_slice *c = &cs->s[ch->idx[e ? ch->n - 1 : 0]];
        if (ch->ext[e] <= 0 || ch->at_end[e])
            continue;
        int n = 2 * c->n, ok = 0;
        double(*p)[2] = malloc(sizeof *p * (size_t)n);
        bool *in = malloc((size_t)n);
        if (!p || !in) {
            free(p), free(in);
            return SF_ENOMEM;
        }
        double pb[4] = {INFINITY, INFINITY, -INFINITY, -INFINITY};
        for (int i = 0; i < c->n; i++) {
            const double *a = c->p[i], *b = c->p[(i + 1) % c->n];
            p[2 * i][0] = a[0], p[2 * i][1] = a[1];
            p[2 * i + 1][0] = 0.5 * (a[0] + b[0]), p[2 * i + 1][1] = 0.5 * (a[1] + b[1]);
            pb[0] = fmin(pb[0], a[0]), pb[1] = fmin(pb[1], a[1]), pb[2] = fmax(pb[2], a[0]), pb[3] = fmax(pb[3], a[1]);
        }
        int rc = 0;
        for (int k = 1; k <= 10 && !rc; k++) {
            memset(in, 0, (size_t)n);
            double z = c->z + (e ? 1 : -1) * ch->ext[e] * k / 10;
            rc = mark_inside(s, box, (const double(*)[2])p, n, pb, z, HOLE_MARGIN * ch->spacing[e], in);
            bool all = true;
            for (int i = 0; i < n && all; i++)
                all = in[i];
            if (!all)
                break;
            ok = k;
        }
        free(p), free(in);
        if (rc)
            return rc;
        ch->ext[e] *= ok / 10.0;
    }
    if (ch->n == 1 && ch->ext[0] + ch->ext[1] <= 0) /* (a hole of one level keeps some height) */
        ch->ext[0] = was[0], ch->ext[1] = was[1];
    return 0;
}

int solid_build(const struct contour_set *cs, struct model_opts o, enum model_caps caps, struct solid *s,
                struct sf_err *err)
{
    memset(s, 0, sizeof *s);
    int n_chains = 0, rc = model_chains(cs, caps, &s->chains, &n_chains, err);
    if (rc)
        return rc;
    s->tubes = calloc((size_t)n_chains, sizeof *s->tubes);
    struct contour_slice *storage = malloc(sizeof *storage * (size_t)(cs->n_slices + 1));
    if (!s->tubes || !storage)
        rc = sf_fail(err, SF_ENOMEM, "", "out of memory");
    s->n_tubes = n_chains;
    s->progress = o.progress;
    /* the body's tubes, then the holes' (hole_reach reads the body's patches, within their bounds) */
    double(*box)[4] = NULL;
    for (int pass = 0, done = 0; pass < 2 && !rc; pass++)
        for (int c = 0; c < n_chains && !rc; c++) {
            if (s->chains[c].hole != (pass == 1) || (rc = sf_poll(o.progress, (double)done++ / n_chains, err)))
                continue;
            if (pass == 1 && !box)
                box = patch_boxes(s); /* (once the body is built, and only for a model with holes) */
            if (pass == 1 && (!box || hole_reach(s, (const double(*)[4])box, cs, &s->chains[c])))
                rc = sf_fail(err, SF_ENOMEM, "", "out of memory building the solid");
            else
                rc = tube_build(s, cs, &s->chains[c], o, caps, storage, &s->tubes[c], err);
        }
    free(box);
    free(storage);
    nurbs_patches_fix(&s->set);
    if (rc)
        solid_free(s);
    return rc;
}

void solid_free(struct solid *s)
{
    nurbs_patch_set_free(&s->set);
    free(s->bands);
    model_chains_free(s->chains, s->n_tubes);
    free(s->tubes);
    memset(s, 0, sizeof *s);
}

/* ---- measures --------------------------------------------------------------------------------
 * seed 000 eq. 21–22: V = ½ ∬ (A Sx + B Sy) du dv over every patch. For a bicubic with z linear in v
 * (the curve methods' side patches), A = y_u Δz and B = -x_u Δz, so the integrand ½ Δz (x y_u - y x_u)
 * is of degree 5 in u and 6 in v: Gauss–Legendre of 3 x 4 nodes is exact, and the same 12 evaluations
 * give the area (smooth, and the patches are small). */

struct gl_table {
    double Bu[3][4], dBu[3][4]; /* cubic Bernstein values and derivatives at the 3 nodes in u */
    double Bv[4][4], dBv[4][4]; /* ... and the 4 in v */
};

static void gl_table_init(struct gl_table *t)
{
    for (int a = 0; a < 3; a++)
        bezier_basis(3, GL3_X[a], t->Bu[a], t->dBu[a]);
    for (int b = 0; b < 4; b++)
        bezier_basis(3, GL4_X[b], t->Bv[b], t->dBv[b]);
}

static void measure_bicubic(const struct patch *pt, const struct gl_table *t, double *volume, double *area)
{
    double dz = pt->cw[3][2] - pt->cw[0][2]; /* z of control point (0,3) less (0,0) */
    for (int a = 0; a < 3; a++) {
        /* contract the u direction first: rows c[j] = sum_i B_i(u) P_ij, cu[j] = sum_i B'_i(u) P_ij */
        double cx[4] = {0}, cy[4] = {0}, cux[4] = {0}, cuy[4] = {0};
        for (int i = 0; i < 4; i++)
            for (int j = 0; j < 4; j++) {
                const double *P = pt->cw[i * 4 + j];
                cx[j] += t->Bu[a][i] * P[0], cy[j] += t->Bu[a][i] * P[1];
                cux[j] += t->dBu[a][i] * P[0], cuy[j] += t->dBu[a][i] * P[1];
            }
        for (int b = 0; b < 4; b++) {
            double x = 0, y = 0, xu = 0, yu = 0, xv = 0, yv = 0;
            for (int j = 0; j < 4; j++) {
                x += t->Bv[b][j] * cx[j], y += t->Bv[b][j] * cy[j];
                xu += t->Bv[b][j] * cux[j], yu += t->Bv[b][j] * cuy[j];
                xv += t->dBv[b][j] * cx[j], yv += t->dBv[b][j] * cy[j];
            }
            double w = GL3_W[a] * GL4_W[b];
            *volume += 0.5 * w * dz * (x * yu - y * xu);
            double nx = yu * dz, ny = -xu * dz, nz = xu * yv - yu * xv; /* Su × Sv */
            *area += w * sqrt(nx * nx + ny * ny + nz * nz);
        }
    }
}

/* Any patch, n x n Gauss–Legendre nodes (exact for polynomial integrands up to degree 2n-1 per
 * direction; the domes' rational integrand is smooth, and 8 nodes leave it below 1e-9). */
static void measure_general(const struct patch *pt, int n, const double *X, const double *W, double *volume,
                            double *area)
{
    for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++) {
            vec3 P, Pu, Pv;
            bezier_eval(pt, X[a], X[b], &P, &Pu, &Pv);
            double A = Pu.y * Pv.z - Pu.z * Pv.y, B = Pu.z * Pv.x - Pu.x * Pv.z, w = W[a] * W[b];
            *volume += 0.5 * w * (A * P.x + B * P.y);
            *area += w * v3_len(v3_cross(Pu, Pv));
        }
}

/* seed 000 eq. 23: the n x n grid rule over every patch, nodes (i/n, j/n), i, j < n, each of weight
 * 1/n² (METHODS.md: as printed, eq. 24's nodes i/(n-1) are first order; Table 6's figures fit i/n,
 * which over a closed surface sums to the trapezoid rule across patch seams: second order). */
#define GRID_N 10

struct grid_table {
    /* the grid sums of Bernstein products: Gu[i][k] = Σ_a B_i B'_k (a/n) / n, Gv[j][l] = Σ_b B_j B_l (b/n) / n */
    double Gu[4][4], Gv[4][4];
};

static void grid_table_init(struct grid_table *g)
{
    memset(g, 0, sizeof *g);
    for (int a = 0; a < GRID_N; a++) {
        double B[4], dB[4];
        bezier_basis(3, (double)a / GRID_N, B, dB);
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 4; k++) {
                g->Gu[i][k] += B[i] * dB[k] / GRID_N;
                g->Gv[i][k] += B[i] * B[k] / GRID_N;
            }
    }
}

/* For a bicubic with z linear in v the integrand is ½ Δz (x y_u - y x_u), a bilinear form in the
 * control points: its grid sum is Σ X_ij Y_kl Gu_ik Gv_jl less the same with X and Y swapped. */
static double grid_bicubic(const struct patch *pt, const struct grid_table *g)
{
    double XG[4][4] = {{0}}, YG[4][4] = {{0}}, s = 0.0, dz = pt->cw[3][2] - pt->cw[0][2];
    for (int k = 0; k < 4; k++)
        for (int j = 0; j < 4; j++)
            for (int l = 0; l < 4; l++) {
                XG[k][j] += pt->cw[k * 4 + l][0] * g->Gv[j][l];
                YG[k][j] += pt->cw[k * 4 + l][1] * g->Gv[j][l];
            }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            double gy = 0.0, gx = 0.0;
            for (int k = 0; k < 4; k++)
                gy += g->Gu[i][k] * YG[k][j], gx += g->Gu[i][k] * XG[k][j];
            s += pt->cw[i * 4 + j][0] * gy - pt->cw[i * 4 + j][1] * gx;
        }
    return 0.5 * dz * s;
}

static double grid_general(const struct patch *pt)
{
    double v = 0.0;
    for (int a = 0; a < GRID_N; a++)
        for (int b = 0; b < GRID_N; b++) {
            vec3 P, Pu, Pv;
            bezier_eval(pt, (double)a / GRID_N, (double)b / GRID_N, &P, &Pu, &Pv);
            v += (Pu.y * Pv.z - Pu.z * Pv.y) * P.x + (Pu.z * Pv.x - Pu.x * Pv.z) * P.y;
        }
    return 0.5 * v / (GRID_N * GRID_N);
}

/* A polynomial bicubic whose z is the same linear function of v in every column. */
static bool z_linear_in_v(const struct patch *pt)
{
    if (pt->p != 3 || pt->q != 3 || pt->rational)
        return false;
    double z0 = pt->cw[0][2], dz = pt->cw[3][2] - z0, eps = 1e-12 * (fabs(z0) + fabs(dz) + 1.0);
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            if (fabs(pt->cw[i * 4 + j][2] - (z0 + dz * j / 3.0)) > eps)
                return false;
    return true;
}

void solid_measure(const struct solid *s, struct solid_measures *m)
{
    memset(m, 0, sizeof *m);
    for (int d = 0; d < 3; d++)
        m->lo[d] = INFINITY, m->hi[d] = -INFINITY;
    struct gl_table t;
    gl_table_init(&t);
    struct grid_table g;
    grid_table_init(&g);
    for (int b = 0; b < s->n_bands; b++) {
        const struct band *bd = &s->bands[b];
        m->area += bd->area; /* a cap: flat, nothing to eq. 21, its area known from its rim */
        for (size_t k = bd->first; k < bd->first + bd->n; k++) {
            const struct patch *pt = &s->set.patches[k];
            vec3 lo, hi;
            bezier_bounds(pt, &lo, &hi);
            m->lo[0] = fmin(m->lo[0], lo.x), m->lo[1] = fmin(m->lo[1], lo.y), m->lo[2] = fmin(m->lo[2], lo.z);
            m->hi[0] = fmax(m->hi[0], hi.x), m->hi[1] = fmax(m->hi[1], hi.y), m->hi[2] = fmax(m->hi[2], hi.z);
            if (bd->kind == BAND_CAP)
                continue;
            if (z_linear_in_v(pt)) {
                m->volume_grid += grid_bicubic(pt, &g);
                measure_bicubic(pt, &t, &m->volume, &m->area);
            } else {
                m->volume_grid += grid_general(pt);
                if (bd->kind == BAND_DOME)
                    measure_general(pt, 8, GL8_X, GL8_W, &m->volume, &m->area);
                else
                    measure_general(pt, 5, GL5_X, GL5_W, &m->volume, &m->area);
            }
        }
    }
}

/* ---- meshes ----------------------------------------------------------------------------------
 * Per tube, rings of nu points at u = k/nu (one u grid for the whole tube, so neighbouring bands
 * share their boundary rings' vertices) and, per band, as many rows in t as its bending needs;
 * a dome's apex is one vertex; caps are the end ring's polygon, ear-clipped. */

#define MESH_MAX_NU 16384
#define MESH_MAX_NT 1024

struct mesher {
    const struct solid *s;
    const struct tube *tb;
    struct solid_mesh *m;
    double tol;
    int nu;
};

/* The point of band b at global u in [0, 1) and t in [0, 1]. */
static vec3 band_point(const struct solid *s, const struct band *b, bool hole, double u, double t)
{
    const struct patch *ps = s->set.patches + b->first;
    size_t lo = 0, hi = b->n - 1;
    while (lo < hi) { /* the last patch with u0 <= u */
        size_t mid = (lo + hi + 1) / 2;
        if (ps[mid].u0 <= u)
            lo = mid;
        else
            hi = mid - 1;
    }
    const struct patch *pt = &ps[lo];
    double w = pt->u1 - pt->u0, local = w > 0 ? (u - pt->u0) / w : 0.0;
    local = fmin(fmax(local, 0.0), 1.0);
    vec3 P;
    bezier_eval(pt, hole ? 1.0 - local : local, t, &P, NULL, NULL);
    return P;
}

vec3 solid_point(const struct solid *s, int band, double u, double t)
{
    for (int k = 0; k < s->n_tubes; k++)
        if (band >= s->tubes[k].first && band < s->tubes[k].first + s->tubes[k].n)
            return band_point(s, &s->bands[band], s->tubes[k].hole, u, t);
    return v3(NAN, NAN, NAN);
}

static double dist_to_mid(vec3 a, vec3 b, vec3 p)
{
    return v3_len(v3_sub(p, v3_scale(v3_add(a, b), 0.5)));
}

/* Whether the row between u0 and u1 (chord a-c) strays more than tol from its chord: at the middle
 * (from the chord's middle) and at the quarters (from the chord), so that a row that bends one way
 * and back within a step, straight through the middle, is seen (a wall's rim of the dicompyler
 * BODY strayed 0.069 mm from a 6.8 mm chord so, and its patches' cap missed it). */
static bool strays(const struct solid *s, const struct band *bd, bool hole, double u0, double u1, double t, vec3 a,
                   vec3 c, double tol)
{
    if (dist_to_mid(a, c, band_point(s, bd, hole, 0.5 * (u0 + u1), t)) > tol)
        return true;
    for (int q = 1; q <= 3; q += 2)
        if (v3_seg_dist(a, c, band_point(s, bd, hole, u0 + (u1 - u0) * q / 4, t), NULL) > tol)
            return true;
    return false;
}

/* The ring positions along u: from 16 even steps, every step whose chord strays more than tol from
 * the side bands' boundary or middle rows (strays) is halved, until none does. One grid for the
 * whole tube keeps the bands' shared rings shared; it is dense only where some row bends. *nu
 * receives the count; NULL when out of memory. */
static double *choose_u(const struct solid *s, const struct tube *tb, double tol, int *nu)
{
    int n = 16;
    double *u = malloc(sizeof *u * (size_t)n);
    for (int k = 0; u && k < n; k++)
        u[k] = (double)k / n;
    for (bool split = true; u && split && n < MESH_MAX_NU;) {
        bool *mark = calloc((size_t)n, sizeof *mark);
        split = false;
        for (int b = tb->first; mark && b < tb->first + tb->n; b++) {
            const struct band *bd = &s->bands[b];
            for (int r = 0; r < 3 && bd->kind == BAND_SIDE; r++)
                for (int k = 0; k < n; k++) {
                    double t = r * 0.5, u1 = k + 1 < n ? u[k + 1] : 1.0;
                    if (mark[k])
                        continue;
                    vec3 a = band_point(s, bd, tb->hole, u[k], t), c = band_point(s, bd, tb->hole, u1, t);
                    mark[k] = strays(s, bd, tb->hole, u[k], u1, t, a, c, tol);
                    split |= mark[k];
                }
        }
        int m = n;
        for (int k = 0; k < n; k++)
            m += mark && mark[k];
        double *v = mark && m <= MESH_MAX_NU ? malloc(sizeof *v * (size_t)m) : NULL;
        for (int k = 0, o = 0; v && k < n; k++) {
            v[o++] = u[k];
            if (mark[k])
                v[o++] = 0.5 * (u[k] + (k + 1 < n ? u[k + 1] : 1.0));
        }
        free(mark);
        if (!v) /* out of memory, or the limit: keep what there is */
            break;
        free(u);
        u = v;
        n = m;
    }
    *nu = n;
    return u;
}

/* Row count of a band: chords along t at every fourth ring position within tol. */
static int choose_nt(const struct solid *s, const struct band *bd, bool hole, const double *us, int nu, double tol)
{
    int nt = 1;
    for (bool ok = false; !ok && nt < MESH_MAX_NT; nt *= ok ? 1 : 2) {
        ok = true;
        for (int k = 0; k < nu && ok; k += 4) {
            vec3 a = band_point(s, bd, hole, us[k], 0.0);
            for (int r = 0; r < nt && ok; r++) {
                vec3 c = band_point(s, bd, hole, us[k], (r + 1.0) / nt);
                ok = dist_to_mid(a, c, band_point(s, bd, hole, us[k], (r + 0.5) / nt)) <= tol;
                a = c;
            }
        }
    }
    return nt;
}

static int add_vertex(struct solid_mesh *m, vec3 p, unsigned *idx)
{
    if (m->n_v >= UINT32_MAX || mem_reserve((void **)&m->v, &m->cap_v, m->n_v + 1, sizeof *m->v))
        return SF_ENOMEM;
    m->v[m->n_v][0] = p.x, m->v[m->n_v][1] = p.y, m->v[m->n_v][2] = p.z;
    *idx = (unsigned)m->n_v++;
    return 0;
}

static int add_tri(struct solid_mesh *m, unsigned a, unsigned b, unsigned c, bool flip)
{
    return flip ? solid_mesh_tri(m, a, c, b) : solid_mesh_tri(m, a, b, c);
}

/* The caps a mesh's tubes end in (join.h), for solid_mesh to join where they share a plane. */
struct caps {
    struct solid_cap *c;
    int n;
    size_t cap;
};

/* Cap of ring (nu vertices), its triangles from t0 on, facing up or down; its walls unknown yet. */
static struct solid_cap *add_cap(struct caps *cs, const struct solid_mesh *m, const unsigned *ring, int nu, bool up, size_t t0)
{
    if (mem_reserve((void **)&cs->c, &cs->cap, (size_t)cs->n + 1, sizeof *cs->c))
        return NULL;
    struct solid_cap *c = &cs->c[cs->n];
    c->ring = malloc(sizeof *c->ring * (size_t)nu);
    c->wall = malloc(sizeof *c->wall * (size_t)nu);
    if (!c->ring || !c->wall) {
        free(c->ring), free(c->wall);
        return NULL;
    }
    memcpy(c->ring, ring, sizeof *ring * (size_t)nu);
    for (int k = 0; k < nu; k++)
        c->wall[k] = SIZE_MAX;
    c->n = nu, c->z = m->v[ring[0]][2], c->up = up, c->t0 = t0, c->t1 = m->n_t, c->joined = false;
    cs->n++;
    return c;
}

static void caps_free(struct caps *cs)
{
    for (int k = 0; k < cs->n; k++)
        free(cs->c[k].ring), free(cs->c[k].wall);
    free(cs->c);
}

static int mesh_tube(const struct solid *s, const struct tube *tb, double tol, struct solid_mesh *m, struct caps *cs)
{
    int nu, rc = 0;
    double *us = choose_u(s, tb, tol, &nu);
    unsigned *ring = malloc(sizeof *ring * (size_t)nu), *next = malloc(sizeof *next * (size_t)nu);
    size_t *top = malloc(sizeof *top * (size_t)nu); /* the last row's triangle on each edge of its top ring */
    int bottom = -1;                                 /* the bottom cap (index in cs) while its walls are made */
    bool have_ring = false;
    if (!us || !ring || !next || !top)
        rc = SF_ENOMEM;
    for (int b = tb->first; b < tb->first + tb->n && !rc && !(rc = sf_poll(s->progress, 0.0, NULL)); b++) {
        const struct band *bd = &s->bands[b];
        bool first = b == tb->first, last = b == tb->first + tb->n - 1;
        if (bd->kind == BAND_CAP) { /* the bottom cap comes before its ring exists: it is clipped below */
            if (last) {
                size_t t0 = m->n_t;
                struct solid_cap *c = (rc = solid_mesh_clip(m, ring, (size_t)nu, !tb->hole)) ? NULL : add_cap(cs, m, ring, nu, !tb->hole, t0);
                if (!rc && !c)
                    rc = SF_ENOMEM;
                else if (c)
                    memcpy(c->wall, top, sizeof *top * (size_t)nu);
            }
            continue;
        }
        int nt = choose_nt(s, bd, tb->hole, us, nu, tol);
        for (int r = have_ring ? 1 : 0; r <= nt && !rc; r++) {
            double t = (double)r / nt;
            bool apex = bd->kind == BAND_DOME && ((first && r == 0) || (last && r == nt));
            for (int k = 0; k < nu && !rc; k++) {
                if (apex && k > 0)
                    next[k] = next[0];
                else
                    rc = add_vertex(m, band_point(s, bd, tb->hole, apex ? 0.0 : us[k], t), &next[k]);
            }
            for (int k = 0; k < nu && have_ring && !rc; k++) {
                int k1 = (k + 1) % nu;
                size_t at = m->n_t;
                if (!(rc = add_tri(m, ring[k], ring[k1], next[k1], tb->hole)) && bottom >= 0)
                    cs->c[bottom].wall[k] = m->n_t > at ? at : SIZE_MAX;
                at = m->n_t;
                if (!rc && !(rc = add_tri(m, ring[k], next[k1], next[k], tb->hole)))
                    top[k] = m->n_t > at ? at : SIZE_MAX;
            }
            if (have_ring)
                bottom = -1;
            if (!have_ring && b > tb->first && s->bands[tb->first].kind == BAND_CAP && !rc) {
                size_t t0 = m->n_t;
                if (!(rc = solid_mesh_clip(m, next, (size_t)nu, tb->hole))) {
                    if (!add_cap(cs, m, next, nu, tb->hole, t0))
                        rc = SF_ENOMEM;
                    bottom = cs->n - 1;
                }
            }
            unsigned *sw = ring;
            ring = next, next = sw;
            have_ring = true;
        }
    }
    free(us);
    free(ring);
    free(next);
    free(top);
    return rc;
}

double solid_default_tolerance(const struct solid_measures *m)
{
    double dx = m->hi[0] - m->lo[0], dy = m->hi[1] - m->lo[1], dz = m->hi[2] - m->lo[2];
    return 1e-4 * sqrt(dx * dx + dy * dy + dz * dz);
}

/* The default's search (issue 18: meshes of a sensible size): the chords of a mesh within tol of
 * the surface cut off at most area x tol of volume, and on smooth surfaces a fraction of that, so
 * the first try is V / A times SOLID_MESH_START. A try whose volume misses by more than
 * SOLID_MESH_TARGET is made again finer, tol scaled by the miss (the chord error goes as tol), at
 * least halved; one that misses by less than an eighth of it is tried again twice as coarse (a lung
 * of many small sections: 0.1 mm held it within 0.003 %), the coarsest that holds kept; at most
 * SOLID_MESH_TRIES meshes, never finer than the old fixed default (1e-4 of the diagonal). */
#define SOLID_MESH_START 1e-2
#define SOLID_MESH_TARGET 5e-4
#define SOLID_MESH_TRIES 6

int solid_mesh_default(const struct solid *s, const struct solid_measures *sm, struct solid_mesh *m, double *tol)
{
    double floor = solid_default_tolerance(sm);
    double t = sm->area > 0.0 ? fmax(floor, SOLID_MESH_START * fabs(sm->volume) / sm->area) : floor;
    struct solid_mesh best = {0};
    bool have = false;
    for (int k = 0; k < SOLID_MESH_TRIES; k++) {
        struct solid_mesh cur;
        int rc = solid_mesh(s, t, &cur);
        if (rc == SF_ELIMIT && have) /* coarser than the best never needs more triangles: finer only */
            break;
        if (rc) {
            solid_mesh_free(&best);
            return rc;
        }
        double miss = fabs(solid_mesh_volume(&cur) / sm->volume - 1.0);
        bool holds = !(miss > SOLID_MESH_TARGET) || t <= floor;
        if (holds) {
            solid_mesh_free(&best);
            best = cur, *tol = t, have = true;
            if (!(miss < SOLID_MESH_TARGET / 8) || t <= floor)
                break;
            t *= 2.0;
        } else {
            solid_mesh_free(&cur);
            if (have) /* the coarser try failed: the best so far stands */
                break;
            t = fmax(floor, t * fmin(0.5, 0.8 * SOLID_MESH_TARGET / miss));
        }
    }
    if (!have) { /* every try missed: the floor, which holds by the old default's tests */
        *tol = floor;
        return solid_mesh(s, floor, m);
    }
    *m = best;
    return 0;
}

int solid_mesh(const struct solid *s, double tol, struct solid_mesh *m)
{
    memset(m, 0, sizeof *m);
    int rc = 0;
    struct caps cs = {0};
    for (int k = 0; k < s->n_tubes && !rc; k++)
        rc = mesh_tube(s, &s->tubes[k], tol, m, &cs);
    if (!rc) /* one surface where tubes end and begin in one plane */
        rc = solid_mesh_join_caps(m, cs.c, cs.n);
    caps_free(&cs);
    if (rc)
        solid_mesh_free(m);
    return rc;
}

/* Whether end e (0 bottom, 1 top) of tube tb faces up: a tube's top does, a hole's bottom (it faces
 * into the hole). */
static bool end_up(const struct tube *tb, int e) { return e ? !tb->hole : tb->hole; }

/* Whether cap band b's fan folds: its end curve is not star-shaped about the centre it fans from
 * (seen from the rim, a fan patch P = (1 - v) C(u) + v c has the normal (1 - v) C'(u) x (c - C(u)),
 * whose z keeps its sign along v: its sign at v = 0 at the patches' ends and thirds, some of them
 * against the rest). */
static bool fan_folds(const struct solid *s, const struct band *bd)
{
    bool pos = false, neg = false;
    for (size_t k = bd->first; k < bd->first + bd->n; k++)
        for (int i = 0; i <= 3; i++) {
            vec3 P, Su, Sv;
            bezier_eval(&s->set.patches[k], i / 3.0, 0.0, &P, &Su, &Sv);
            double nz = Su.x * Sv.y - Su.y * Sv.x, scale = v3_len(Su) * v3_len(Sv);
            pos |= nz > 1e-9 * scale, neg |= nz < -1e-9 * scale;
        }
    return pos && neg;
}

/* The end rings of the tubes' flat caps, within tol, as mesh_tube makes them (their caps clipped,
 * each ring edge with a wall triangle to a point a little off the plane, so that join.c can split
 * it where rings cross), joined (join.c); the joined planes' triangles kept, every other one
 * dropped. A cap whose fan folds (a not star-shaped end, as the dicompyler Breast's: its fan's
 * patches overlap, and their edges are taken for each other's neighbours) is kept as a region of
 * its own plane, its ring ear-clipped, even where no other cap shares the plane. */
static int joined_caps(const struct solid *s, double tol, struct solid_mesh *m, bool *skip)
{
    memset(m, 0, sizeof *m);
    for (int b = 0; b < s->n_bands; b++)
        skip[b] = false;
    struct caps cs = {0};
    int *band_of = NULL, rc = 0; /* each cap's band */
    bool *lone = NULL;           /* ... and whether it is sampled for its fan alone */
    size_t cap_band = 0, cap_lone = 0;
    /* the plane of each tube end's flat cap (NAN: none), so that only those sharing theirs with a cap
     * facing the other way are sampled */
    double *zs = malloc(sizeof *zs * (size_t)(2 * s->n_tubes + 1));
    if (!zs)
        return SF_ENOMEM;
    for (int k = 0; k < s->n_tubes; k++)
        for (int end = 0; end < 2; end++) {
            const struct tube *tb = &s->tubes[k];
            int b = end ? tb->first + tb->n - 1 : tb->first;
            zs[2 * k + end] = tb->n > 1 && s->bands[b].kind == BAND_CAP
                                  ? band_point(s, &s->bands[end ? b - 1 : b + 1], tb->hole, 0.0, end ? 1.0 : 0.0).z
                                  : NAN;
        }
    for (int k = 0; k < s->n_tubes && !rc; k++) {
        const struct tube *tb = &s->tubes[k];
        bool shared[2] = {false, false}, folds[2]; /* (NAN shares nothing) */
        for (int end = 0; end < 2; end++) {
            for (int o = 0; o < 2 * s->n_tubes && !shared[end]; o++)
                shared[end] = end_up(tb, end) != end_up(&s->tubes[o / 2], o % 2) && join_same_plane(zs[2 * k + end], zs[o]);
            folds[end] = !isnan(zs[2 * k + end]) && fan_folds(s, &s->bands[end ? tb->first + tb->n - 1 : tb->first]);
        }
        if (!shared[0] && !shared[1] && !folds[0] && !folds[1])
            continue;
        int nu;
        double *us = choose_u(s, tb, tol, &nu);
        unsigned *ring = us ? malloc(sizeof *ring * (size_t)nu) : NULL, *off = ring ? malloc(sizeof *off * (size_t)nu) : NULL;
        rc = off ? 0 : SF_ENOMEM;
        for (int end = 0; end < 2 && !rc; end++) {
            int b = end ? tb->first + tb->n - 1 : tb->first, next = end ? b - 1 : b + 1;
            if (!shared[end] && !folds[end])
                continue;
            bool up = end_up(tb, end);
            for (int q = 0; q < nu && !rc; q++) {
                vec3 p = band_point(s, &s->bands[next], tb->hole, us[q], end ? 1.0 : 0.0);
                if (!(rc = add_vertex(m, p, &ring[q])))
                    rc = add_vertex(m, v3_add(p, v3(0, 0, end ? -tol : tol)), &off[q]);
            }
            size_t t0 = m->n_t;
            struct solid_cap *c = rc || (rc = solid_mesh_clip(m, ring, (size_t)nu, up)) ? NULL : add_cap(&cs, m, ring, nu, up, t0);
            if (!rc && (!c || mem_reserve((void **)&band_of, &cap_band, (size_t)cs.n, sizeof *band_of) ||
                        mem_reserve((void **)&lone, &cap_lone, (size_t)cs.n, sizeof *lone)))
                rc = SF_ENOMEM;
            for (int q = 0; q < nu && !rc; q++) { /* the walls as mesh_tube's last (first) row has them */
                int q1 = (q + 1) % nu;
                size_t at = m->n_t;
                rc = end ? add_tri(m, off[q], ring[q1], ring[q], tb->hole) : add_tri(m, ring[q], ring[q1], off[q1], tb->hole);
                cs.c[cs.n - 1].wall[q] = m->n_t > at ? at : SIZE_MAX;
            }
            if (!rc)
                band_of[cs.n - 1] = b, lone[cs.n - 1] = !shared[end];
        }
        free(us), free(ring), free(off);
    }
    free(zs);
    if (!rc)
        rc = solid_mesh_join_caps(m, cs.c, cs.n);
    for (int c = 0; !rc && c < cs.n; c++) /* (a folding fan's plane: its clipped ring stands) */
        cs.c[c].joined |= lone[c];
    size_t o = 0;
    for (size_t t = 0; !rc && t < m->n_t; t++) { /* the joined planes' triangles */
        double z = m->v[m->t[t][0]][2];
        bool keep = false;
        for (int c = 0; !keep && c < cs.n; c++)
            keep = cs.c[c].joined && join_same_plane(cs.c[c].z, z);
        for (int q = 1; keep && q < 3; q++)
            keep = join_same_plane(m->v[m->t[t][q]][2], z);
        if (keep)
            memmove(m->t[o++], m->t[t], sizeof *m->t);
    }
    m->n_t = o;
    for (int c = 0; !rc && c < cs.n; c++)
        skip[band_of[c]] = cs.c[c].joined;
    caps_free(&cs);
    free(band_of), free(lone);
    if (rc)
        solid_mesh_free(m);
    return rc;
}

static int by_edge(const void *x, const void *y)
{
    const unsigned *a = x, *b = y;
    return a[0] != b[0] ? (a[0] > b[0]) - (a[0] < b[0]) : (a[1] > b[1]) - (a[1] < b[1]);
}

/* Region r's loops: the directed edges of its triangles (ids into m) that no triangle of it has the
 * other way (sorted, each looked up), followed from each unused one until they close (where several
 * leave one vertex, any: the even-odd region is the same). */
static int region_loops(const struct solid_mesh *m, const size_t *tris, size_t nt, struct cap_region *r)
{
    size_t ne = 3 * nt, n_out = 0, cap = 0, n_pt = 0;
    unsigned(*e)[2] = malloc(sizeof *e * (ne ? ne : 1)), (*out)[2] = malloc(sizeof *out * (ne ? ne : 1));
    bool *used = calloc(ne ? ne : 1, sizeof *used);
    int rc = !out || !e || !used ? SF_ENOMEM : 0;
    for (size_t k = 0; !rc && k < nt; k++)
        for (int q = 0; q < 3; q++)
            e[3 * k + (size_t)q][0] = m->t[tris[k]][q], e[3 * k + (size_t)q][1] = m->t[tris[k]][(q + 1) % 3];
    if (!rc)
        qsort(e, ne, sizeof *e, by_edge);
    for (size_t k = 0; !rc && k < ne; k++) {
        unsigned back[2] = {e[k][1], e[k][0]};
        if (!bsearch(back, e, ne, sizeof *e, by_edge))
            out[n_out][0] = e[k][0], out[n_out++][1] = e[k][1]; /* (sorted by start too) */
    }
    r->lo[0] = r->lo[1] = INFINITY, r->hi[0] = r->hi[1] = -INFINITY;
    for (size_t s0 = 0; !rc && s0 < n_out; s0++) {
        if (used[s0])
            continue;
        size_t count = 0;
        for (size_t cur = s0; !rc;) {
            used[cur] = true;
            const double *v = m->v[out[cur][0]];
            if (mem_reserve((void **)&r->pt, &cap, n_pt + 1, sizeof *r->pt)) {
                rc = SF_ENOMEM;
                break;
            }
            r->pt[n_pt][0] = v[0], r->pt[n_pt++][1] = v[1], count++;
            for (int d = 0; d < 2; d++)
                r->lo[d] = fmin(r->lo[d], v[d]), r->hi[d] = fmax(r->hi[d], v[d]);
            size_t lo = 0, hi = n_out; /* the first boundary edge from cur's end, then an unused one */
            while (lo < hi) {
                size_t mid = (lo + hi) / 2;
                if (out[mid][0] < out[cur][1])
                    lo = mid + 1;
                else
                    hi = mid;
            }
            while (lo < n_out && out[lo][0] == out[cur][1] && used[lo])
                lo++;
            if (lo == n_out || out[lo][0] != out[cur][1])
                break; /* back where it began (or, were the boundary not closed, stopped) */
            cur = lo;
        }
        size_t *grown = rc ? NULL : realloc(r->counts, sizeof *r->counts * (size_t)(r->n_loops + 1));
        if (!grown)
            rc = rc ? rc : SF_ENOMEM;
        else
            r->counts = grown, r->counts[r->n_loops++] = count;
    }
    free(out), free(e), free(used);
    return rc;
}

int solid_join_caps(const struct solid *s, double tol, struct cap_regions *out, bool *skip)
{
    memset(out, 0, sizeof *out);
    struct solid_mesh m;
    int rc = joined_caps(s, tol, &m, skip);
    size_t *tris = rc ? NULL : malloc(sizeof *tris * (m.n_t ? m.n_t : 1));
    bool *done = rc ? NULL : calloc(m.n_t ? m.n_t : 1, sizeof *done);
    if (!rc && (!tris || !done))
        rc = SF_ENOMEM;
    for (size_t t0 = 0; !rc && t0 < m.n_t; t0++) { /* the planes' triangles by plane and side */
        if (done[t0])
            continue;
        double z = m.v[m.t[t0][0]][2];
        size_t nt = 0;
        bool up = false;
        for (size_t t = t0; t < m.n_t; t++) {
            const double *a = m.v[m.t[t][0]], *b = m.v[m.t[t][1]], *c = m.v[m.t[t][2]];
            bool tup = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]) > 0;
            if (t == t0)
                up = tup;
            if (!done[t] && tup == up && join_same_plane(a[2], z))
                done[t] = true, tris[nt++] = t;
        }
        struct cap_region *grown = realloc(out->r, sizeof *out->r * (size_t)(out->n + 1));
        if (!grown) {
            rc = SF_ENOMEM;
            break;
        }
        out->r = grown;
        struct cap_region *r = &out->r[out->n++];
        *r = (struct cap_region){.z = z, .up = up};
        rc = region_loops(&m, tris, nt, r);
    }
    free(tris), free(done);
    solid_mesh_free(&m);
    if (rc)
        solid_cap_regions_free(out);
    return rc;
}

void solid_cap_regions_free(struct cap_regions *r)
{
    for (int k = 0; k < r->n; k++)
        free(r->r[k].counts), free(r->r[k].pt);
    free(r->r);
    memset(r, 0, sizeof *r);
}

void solid_mesh_free(struct solid_mesh *m)
{
    free(m->v);
    free(m->t);
    memset(m, 0, sizeof *m);
}

double solid_mesh_volume(const struct solid_mesh *m)
{
    double v = 0.0;
    for (size_t k = 0; k < m->n_t; k++) {
        const double *a = m->v[m->t[k][0]], *b = m->v[m->t[k][1]], *c = m->v[m->t[k][2]];
        v += a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    return v / 6.0;
}
