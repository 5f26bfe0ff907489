/* frep.c - FRep evaluation with gradients (frep.h). The tree's depth is capped by whoever built
 * it (FREP_MAX_DEPTH), so the recursion is bounded. */
#include "frep.h"

#include <math.h>
#include <string.h>

#include "../base/vec.h"

static void set3(double g[3], double x, double y, double z)
{
    if (g)
        g[0] = x, g[1] = y, g[2] = z;
}

/* A point relative to an axis through base: its height h along the axis and its radial vector w
 * (length rho). */
static double radial(const double x[3], const double base[3], const double axis[3], double w[3], double *rho)
{
    double v[3] = {x[0] - base[0], x[1] - base[1], x[2] - base[2]};
    double h = dot3(v, axis);
    for (int i = 0; i < 3; i++)
        w[i] = v[i] - h * axis[i];
    *rho = sqrt(dot3(w, w));
    return h;
}

/* Distance from (px, py) to the segment a-b, the unit direction from the nearest point in *dx, *dy.
 * Where the nearest point is inside the segment that direction is the segment's normal, one way
 * or the other (outward: the profile runs counter-clockwise), taken from the segment, not from
 * the point's offset (which a point on the surface, at a distance of rounding error, does not
 * give). */
static double seg_dist(double px, double py, double ax, double ay, double bx, double by, double *dx, double *dy)
{
    double ex = bx - ax, ey = by - ay, el = sqrt(ex * ex + ey * ey), t = ((px - ax) * ex + (py - ay) * ey) / (el * el);
    double nx = ey / el, ny = -ex / el;
    if (t > 0 && t < 1) {
        double side = (px - ax) * nx + (py - ay) * ny;
        *dx = side < 0 ? -nx : nx;
        *dy = side < 0 ? -ny : ny;
        return fabs(side);
    }
    t = t < 0 ? 0 : 1;
    double rx = px - (ax + t * ex), ry = py - (ay + t * ey), d = sqrt(rx * rx + ry * ry);
    *dx = d > 0 ? rx / d : nx;
    *dy = d > 0 ? ry / d : ny;
    return d;
}

/* A solid of revolution from its profile in the (rho, h) half-plane: a polyline from the axis
 * round to the axis (the axis itself is not surface), inside or not. f = -signed distance. */
static double revolve(const double (*pr)[2], int n, int inside, const double x[3], const double base[3],
                      const double axis[3], double g[3])
{
    double w[3], rho, h = radial(x, base, axis, w, &rho);
    double best = INFINITY, gr = 0, gh = 0;
    for (int k = 0; k + 1 < n; k++) {
        double dx, dy, d = seg_dist(rho, h, pr[k][0], pr[k][1], pr[k + 1][0], pr[k + 1][1], &dx, &dy);
        if (d < best)
            best = d, gr = dx, gh = dy;
    }
    double s = inside ? 1 : -1; /* f = -signed distance: +d inside, -d outside */
    if (g)
        for (int i = 0; i < 3; i++)
            g[i] = s * (gr * (rho > 0 ? w[i] / rho : 0) + gh * axis[i]);
    return s * best;
}

/* Volume v, trilinear, at x (its gradient into g): scale (value - iso). */
static double sampled(const struct frep_volume *v, double iso, double scale, const double x[3], double g[3])
{
    int c[3];
    double u[3];
    for (int d = 0; d < 3; d++) {
        double t = v->v ? (x[d] - v->origin[d]) / v->spacing[d] : -1;
        if (!(t >= 0 && t <= v->dims[d] - 1)) { /* beyond the grid (or no samples given): outside, flat */
            if (g)
                set3(g, 0, 0, 0);
            return scale * (v->outside - iso);
        }
        c[d] = t >= v->dims[d] - 1 ? v->dims[d] - 2 : (int)t;
        u[d] = t - c[d];
    }
    size_t sx = 1, sy = (size_t)v->dims[0], sz = sy * (size_t)v->dims[1];
    const float *q = v->v + c[0] + sy * c[1] + sz * c[2];
    double f[8];
    for (int k = 0; k < 8; k++)
        f[k] = q[(k & 1) * sx + (k >> 1 & 1) * sy + (k >> 2 & 1) * sz];
    /* along x, then y, then z */
    double x00 = f[0] + u[0] * (f[1] - f[0]), x10 = f[2] + u[0] * (f[3] - f[2]);
    double x01 = f[4] + u[0] * (f[5] - f[4]), x11 = f[6] + u[0] * (f[7] - f[6]);
    double y0 = x00 + u[1] * (x10 - x00), y1 = x01 + u[1] * (x11 - x01);
    if (g) {
        double dx0 = (f[1] - f[0]) + u[1] * ((f[3] - f[2]) - (f[1] - f[0]));
        double dx1 = (f[5] - f[4]) + u[1] * ((f[7] - f[6]) - (f[5] - f[4]));
        set3(g, scale * (dx0 + u[2] * (dx1 - dx0)) / v->spacing[0],
             scale * ((x10 - x00) + u[2] * ((x11 - x01) - (x10 - x00))) / v->spacing[1], scale * (y1 - y0) / v->spacing[2]);
    }
    return scale * (y0 + u[2] * (y1 - y0) - iso);
}

static double primitive(const struct frep *f, const struct frep_node *n, const double x[3], double g[3])
{
    const double *p = n->p;
    switch (n->kind) {
    case FREP_VOLUME:
        return sampled(&f->volumes[(int)p[0]], p[1], p[2], x, g);
    case FREP_SPHERE: {
        double v[3] = {x[0] - p[0], x[1] - p[1], x[2] - p[2]}, r = sqrt(dot3(v, v));
        if (g)
            for (int i = 0; i < 3; i++)
                g[i] = r > 0 ? -v[i] / r : 0;
        return p[3] - r;
    }
    case FREP_ELLIPSOID: {
        double u[3], rmin = fmin(p[3], fmin(p[4], p[5]));
        for (int i = 0; i < 3; i++)
            u[i] = (x[i] - p[i]) / p[3 + i];
        double k = sqrt(dot3(u, u));
        if (g)
            for (int i = 0; i < 3; i++)
                g[i] = k > 0 ? -rmin * u[i] / (p[3 + i] * k) : 0;
        return rmin * (1 - k);
    }
    case FREP_BOX: {
        double q[3], s[3], out = 0, qmax = -INFINITY;
        int imax = 0;
        for (int i = 0; i < 3; i++) {
            double c = 0.5 * (p[i] + p[3 + i]), h = 0.5 * (p[3 + i] - p[i]);
            s[i] = x[i] >= c ? 1 : -1;
            q[i] = fabs(x[i] - c) - h;
            out += q[i] > 0 ? q[i] * q[i] : 0;
            if (q[i] > qmax)
                qmax = q[i], imax = i;
        }
        if (qmax > 0) {
            double d = sqrt(out);
            set3(g, -s[0] * fmax(q[0], 0) / d, -s[1] * fmax(q[1], 0) / d, -s[2] * fmax(q[2], 0) / d);
            return -d;
        }
        if (g) {
            set3(g, 0, 0, 0);
            g[imax] = -s[imax];
        }
        return -qmax;
    }
    case FREP_CYLINDER: {
        double w[3], rho, h = radial(x, p, p + 3, w, &rho);
        const double pr[4][2] = {{0, 0}, {p[6], 0}, {p[6], p[7]}, {0, p[7]}};
        return revolve(pr, 4, rho < p[6] && h > 0 && h < p[7], x, p, p + 3, g);
    }
    case FREP_CONE: {
        double w[3], rho, h = radial(x, p, p + 3, w, &rho);
        const double pr[3][2] = {{0, 0}, {p[6], 0}, {0, p[7]}};
        return revolve(pr, 3, h > 0 && h < p[7] && rho < p[6] * (1 - h / p[7]), x, p, p + 3, g);
    }
    case FREP_TORUS: {
        double w[3], rho, h = radial(x, p, p + 3, w, &rho);
        double qr = rho - p[6], d = sqrt(qr * qr + h * h);
        if (g)
            for (int i = 0; i < 3; i++)
                g[i] = d > 0 ? -(qr * (rho > 0 ? w[i] / rho : 0) + h * p[3 + i]) / d : 0;
        return p[7] - d;
    }
    case FREP_SUPERELLIPSOID: {
        double u[3], e1 = p[6], e2 = p[7], rmin = fmin(p[3], fmin(p[4], p[5]));
        for (int i = 0; i < 3; i++)
            u[i] = fabs(x[i] - p[i]) / p[3 + i];
        double a0 = pow(u[0], 2 / e2), a1 = pow(u[1], 2 / e2), A = a0 + a1;
        double F = pow(A, e2 / e1) + pow(u[2], 2 / e1), G = pow(F, e1 / 2);
        if (g) {
            set3(g, 0, 0, 0);
            if (F > 0) {
                double fe = pow(F, e1 / 2 - 1), ae = A > 0 ? pow(A, e2 / e1 - 1) : 0;
                for (int i = 0; i < 3; i++) {
                    double sg = x[i] >= p[i] ? 1 : -1, d;
                    if (u[i] == 0)
                        continue;
                    d = i < 2 ? fe * ae * pow(u[i], 2 / e2 - 1) : fe * pow(u[2], 2 / e1 - 1);
                    g[i] = -rmin * sg * d / p[3 + i];
                }
            }
        }
        return rmin * (1 - G);
    }
    case FREP_HALFSPACE: {
        double v[3] = {x[0] - p[0], x[1] - p[1], x[2] - p[2]};
        set3(g, -p[3], -p[4], -p[5]);
        return -dot3(v, p + 3);
    }
    default:
        return 0; /* operations are evaluated by eval() */
    }
}

/* R_alpha of (f1, f2), sign +1 for union and -1 for intersection; the partial derivatives into
 * *d1, *d2. */
static double rfunc(double f1, double f2, double alpha, double sign, double *d1, double *d2)
{
    double s = sqrt(fmax(f1 * f1 + f2 * f2 - 2 * alpha * f1 * f2, 0)), k = 1 / (1 + alpha);
    *d1 = k * (1 + (s > 0 ? sign * (f1 - alpha * f2) / s : 0));
    *d2 = k * (1 + (s > 0 ? sign * (f2 - alpha * f1) / s : 0));
    return k * (f1 + f2 + sign * s);
}

static double eval(const struct frep *f, int at, const double x[3], double g[3])
{
    const struct frep_node *n = &f->nodes[at];
    if (n->kind < FREP_UNION)
        return primitive(f, n, x, g);
    double ga[3], gb[3], *pa = g ? ga : NULL, *pb = g ? gb : NULL;
    if (n->kind == FREP_OFFSET) {
        double v = eval(f, n->a, x, g);
        return v + n->p[0];
    }
    if (n->kind == FREP_TRANSFORM) {
        double d[3] = {x[0] - n->t[0], x[1] - n->t[1], x[2] - n->t[2]}, q[3];
        for (int i = 0; i < 3; i++)
            q[i] = dot3(n->m[i], d);
        double v = eval(f, n->a, q, pa);
        if (g)
            for (int j = 0; j < 3; j++)
                g[j] = n->lip * (n->m[0][j] * ga[0] + n->m[1][j] * ga[1] + n->m[2][j] * ga[2]);
        return n->lip * v;
    }
    double f1 = eval(f, n->a, x, pa), f2 = eval(f, n->b, x, pb), d1, d2, v;
    if (n->kind == FREP_SUBTRACT) {
        v = rfunc(f1, -f2, n->alpha, -1, &d1, &d2);
        d2 = -d2;
    } else {
        v = rfunc(f1, f2, n->alpha, n->kind == FREP_INTERSECT ? -1 : 1, &d1, &d2);
    }
    if (n->kind == FREP_BLEND) {
        double r1 = f1 / n->p[1], r2 = f2 / n->p[2], den = 1 + r1 * r1 + r2 * r2;
        v += n->p[0] / den;
        d1 -= n->p[0] * 2 * r1 / (n->p[1] * den * den);
        d2 -= n->p[0] * 2 * r2 / (n->p[2] * den * den);
    }
    if (g)
        for (int i = 0; i < 3; i++)
            g[i] = d1 * ga[i] + d2 * gb[i];
    return v;
}

double frep_eval(const struct frep *f, const double x[3], double g[3]) { return eval(f, f->root, x, g); }

/* Every function of the tree is Lipschitz with a known constant (1 for the distances, sqrt 3
 * for a superellipsoid whose exponents are at most 2, none above: its bounds are then
 * unbounded) and the R-functions are non-decreasing in both arguments, so bounds propagate up
 * the tree as intervals. */
#define FREP_HUGE 1e30

static void bound(const struct frep *f, int at, const double c[3], double r, double *lo, double *hi)
{
    const struct frep_node *n = &f->nodes[at];
    if (n->kind == FREP_VOLUME) { /* (no Lipschitz constant: the samples' range) */
        const struct frep_volume *v = &f->volumes[(int)n->p[0]];
        *lo = n->p[2] * (fminf(v->lo, v->outside) - n->p[1]);
        *hi = n->p[2] * (fmaxf(v->hi, v->outside) - n->p[1]);
        return;
    }
    if (n->kind < FREP_UNION) {
        double v = primitive(f, n, c, NULL), lip = 1;
        if (n->kind == FREP_SUPERELLIPSOID)
            lip = n->p[6] <= 2 && n->p[7] <= 2 ? sqrt(3.0) : FREP_HUGE;
        *lo = v - lip * r, *hi = v + lip * r;
        *lo = fmax(*lo, -FREP_HUGE), *hi = fmin(*hi, FREP_HUGE);
        return;
    }
    double l1, h1, l2, h2, d1, d2;
    if (n->kind == FREP_OFFSET) {
        bound(f, n->a, c, r, &l1, &h1);
        *lo = l1 + n->p[0], *hi = h1 + n->p[0];
        return;
    }
    if (n->kind == FREP_TRANSFORM) {
        double d[3] = {c[0] - n->t[0], c[1] - n->t[1], c[2] - n->t[2]}, q[3];
        for (int i = 0; i < 3; i++)
            q[i] = dot3(n->m[i], d);
        bound(f, n->a, q, r / n->lip, &l1, &h1);
        *lo = n->lip * l1, *hi = n->lip * h1;
        return;
    }
    bound(f, n->a, c, r, &l1, &h1);
    bound(f, n->b, c, r, &l2, &h2);
    if (n->kind == FREP_SUBTRACT) {
        *lo = rfunc(l1, -h2, n->alpha, -1, &d1, &d2);
        *hi = rfunc(h1, -l2, n->alpha, -1, &d1, &d2);
        return;
    }
    double sign = n->kind == FREP_INTERSECT ? -1 : 1;
    *lo = rfunc(l1, l2, n->alpha, sign, &d1, &d2);
    *hi = rfunc(h1, h2, n->alpha, sign, &d1, &d2);
    if (n->kind == FREP_BLEND) /* the bump a0 / (1 + ...) lies between 0 and a0 */
        *lo += fmin(0, n->p[0]), *hi += fmax(0, n->p[0]);
}

void frep_bound(const struct frep *f, const double c[3], double r, double *lo, double *hi)
{
    bound(f, f->root, c, r, lo, hi);
}

#define BLOCK 8 /* samples a side of the blocks that bounds may skip */

int frep_sample(const struct frep *f, const double origin[3], double cell, int nx, int ny, int z0, int z1, float *out,
                const struct sf_progress *pr, struct sf_err *err)
{
    /* polled a block at a time: a block of a 2 048-primitive union is some milliseconds, so a
     * cancel is heard at once, where a slab of it was hours */
    double blocks = ceil((z1 - z0) / (double)BLOCK) * ceil(ny / (double)BLOCK) * ceil(nx / (double)BLOCK), done = 0;
    for (int k0 = z0; k0 < z1; k0 += BLOCK)
        for (int j0 = 0; j0 < ny; j0 += BLOCK)
            for (int i0 = 0; i0 < nx; i0 += BLOCK, done++) {
                if (sf_poll(pr, done / blocks, err))
                    return SF_ECANCEL;
                int i1 = i0 + BLOCK < nx ? i0 + BLOCK : nx, j1 = j0 + BLOCK < ny ? j0 + BLOCK : ny,
                    k1 = k0 + BLOCK < z1 ? k0 + BLOCK : z1;
                /* the block and two samples round it: when the field keeps one sign there, no
                 * cell with a corner within a sample of the block holds the surface, so neither
                 * the vertices nor their gradients (central differences) read the block's values,
                 * and the sign is all that is needed of them */
                double c[3] = {origin[0] + 0.5 * (i0 + i1 - 1) * cell, origin[1] + 0.5 * (j0 + j1 - 1) * cell,
                               origin[2] + 0.5 * (k0 + k1 - 1) * cell};
                double h[3] = {0.5 * (i1 - i0 - 1) + 2, 0.5 * (j1 - j0 - 1) + 2, 0.5 * (k1 - k0 - 1) + 2};
                double lo, hi, r = cell * sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
                frep_bound(f, c, r, &lo, &hi);
                if (lo > 0 || hi < 0) {
                    float v = lo > 0 ? (float)fmax(lo, 1e-6) : (float)fmin(hi, -1e-6);
                    for (int k = k0; k < k1; k++)
                        for (int j = j0; j < j1; j++)
                            for (int i = i0; i < i1; i++)
                                out[((size_t)k * ny + j) * nx + i] = v;
                    continue;
                }
                for (int k = k0; k < k1; k++)
                    for (int j = j0; j < j1; j++) {
                        float *row = out + ((size_t)k * ny + j) * nx;
                        double x[3] = {0, origin[1] + j * cell, origin[2] + k * cell};
                        for (int i = i0; i < i1; i++) {
                            x[0] = origin[0] + i * cell;
                            row[i] = (float)eval(f, f->root, x, NULL);
                        }
                    }
            }
    return 0;
}

void frep_transform(struct frep_node *n, const double scale[3], const double rotate_deg[3], const double translate[3])
{
    double c[3], s[3], r[3][3];
    for (int i = 0; i < 3; i++) {
        double a = rotate_deg[i] * M_PI / 180;
        c[i] = cos(a), s[i] = sin(a);
    }
    /* R = Rz Ry Rx */
    const double rx[3][3] = {{1, 0, 0}, {0, c[0], -s[0]}, {0, s[0], c[0]}};
    const double ry[3][3] = {{c[1], 0, s[1]}, {0, 1, 0}, {-s[1], 0, c[1]}};
    const double rz[3][3] = {{c[2], -s[2], 0}, {s[2], c[2], 0}, {0, 0, 1}};
    double ryx[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            ryx[i][j] = 0;
            for (int k = 0; k < 3; k++)
                ryx[i][j] += ry[i][k] * rx[k][j];
        }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            r[i][j] = 0;
            for (int k = 0; k < 3; k++)
                r[i][j] += rz[i][k] * ryx[k][j];
        }
    /* x = R S q + t, so q = S^-1 R^T (x - t) */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            n->m[i][j] = r[j][i] / scale[i];
    memcpy(n->t, translate, sizeof n->t);
    n->lip = fmin(scale[0], fmin(scale[1], scale[2]));
}
